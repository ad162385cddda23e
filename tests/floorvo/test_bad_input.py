"""Issue 16: bad input and faults give one line naming the thing and the rule (exit code 1),
never a traceback, and impossible values are refused instead of giving wrong output."""

from __future__ import annotations

import errno
import io
import json
import os

import numpy as np
import pytest

from floorsim.cli import main as floorsim_main
from floorvo.camera import CameraModel
from floorvo.cli import main as floorvo_main
from floorvo.synthetic import line_poses, write_synthetic_sequence


@pytest.fixture(scope="module")
def small_seq(tmp_path_factory):
    """A 3-frame synthetic sequence at quarter size (with ground truth)."""
    cam = CameraModel.from_sensor().scaled(0.25)
    return write_synthetic_sequence(tmp_path_factory.mktemp("seq") / "seq", cam, line_poses(8.0, 4.0), seed=0)


def _one_line(capsys, prog: str) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"{prog}: error: ") and "Traceback" not in err, err
    return err.strip()


def test_a_full_disk_is_one_line_naming_the_file_and_leaves_no_temporary(small_seq, tmp_path, monkeypatch, capsys):
    def full(fd):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "fsync", full)
    run = tmp_path / "run"
    assert floorvo_main(["run", str(small_seq), "-e", "phase-corr", "-o", str(run)]) == 1
    err = _one_line(capsys, "floorvo")
    assert f"{run}/" in err and "No space left on device (errno 28)" in err
    assert not [p for p in run.iterdir() if p.name.endswith(".tmp")]
    # the same through floorsim (a scene render writes sequence.json first)
    assert floorsim_main(["render", "demo", "--frames", "1", "-o", str(tmp_path / "seq")]) == 1
    err = _one_line(capsys, "floorsim")
    assert f"{tmp_path / 'seq' / 'sequence.json'}: No space left on device (errno 28)" in err


def test_a_run_that_cannot_finish_leaves_no_half_run(small_seq, tmp_path, monkeypatch, capsys):
    """Issue 16: a full disk left trajectory.txt without result.json (or beside an older run's)."""
    import floorvo.runfolder
    from floorvo.runfolder import RunFolder

    run = tmp_path / "run"
    assert floorvo_main(["run", str(small_seq), "-e", "phase-corr", "-o", str(run)]) == 0
    assert RunFolder.read(run).result["estimator"] == "phase-corr"

    def full(path, obj):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))

    monkeypatch.setattr(floorvo.runfolder, "atomic_write_json", full)
    assert floorvo_main(["run", str(small_seq), "-e", "akaze-guided", "-o", str(run)]) == 1
    assert f"{run / 'result.json'}: No space left on device (errno 28)" in _one_line(capsys, "floorvo")
    assert sorted(p.name for p in run.iterdir()) == []  # neither the new trajectory nor the old summary


def test_a_new_run_into_a_folder_removes_the_old_runs_score_and_match_samples(small_seq, tmp_path, capsys):
    """`floorvo run -e akaze-guided -o R` into a folder that phase-corr's run was scored in kept
    phase-corr's R/score.json beside akaze-guided's trajectory (and the bench's match samples of
    the old run); a program's run that fails kept the old score beside no run at all."""
    from floorvo.errors import ExternalEstimatorError
    from floorvo.external import ExternalEstimator, run_external
    from floorvo.runfolder import write_match_sample

    run = tmp_path / "run"
    assert floorvo_main(["run", str(small_seq), "-e", "phase-corr", "-o", str(run)]) == 0
    assert floorvo_main(["score", str(run), "--gt", str(small_seq)]) == 0
    write_match_sample(run, 1, np.array([[1.0, 2.0, 3.0, 4.0]]))
    assert json.loads((run / "score.json").read_text())["estimator"] == "phase-corr"
    assert floorvo_main(["run", str(small_seq), "-e", "phase-corr-fast", "-o", str(run)]) == 0
    assert sorted(p.name for p in run.iterdir()) == ["result.json", "timing.csv", "trajectory.txt"]
    assert floorvo_main(["score", str(run), "--gt", str(small_seq)]) == 0
    assert json.loads((run / "score.json").read_text())["estimator"] == "phase-corr-fast"
    crash = ExternalEstimator(name="crash", command=("sh", "-c", "exit 3"))
    with pytest.raises(ExternalEstimatorError, match="exit code 3"):
        run_external(small_seq, crash, run)
    assert not (run / "score.json").exists() and not (run / "result.json").exists()


def _cut(path, lines: int) -> None:
    """Keep the first ``lines`` lines of ``path``: a file cut short at a line boundary."""
    path.write_text("".join(path.read_text().splitlines(keepends=True)[:lines]))


@pytest.mark.parametrize(
    "damage, words",
    [
        (
            lambda r: _cut(r / "trajectory.txt", 3),
            "trajectory.txt holds 2 pose(s), and timing.csv marks 3 frame(s) init or ok",
        ),
        (lambda r: _cut(r / "trajectory.txt", 0), "trajectory.txt holds 0 pose(s), and timing.csv marks 3 frame(s)"),
        (
            lambda r: (_cut(r / "trajectory.txt", 3), (r / "timing.csv").unlink()),
            "trajectory.txt holds 2 pose(s), and result.json counts 3 frame(s) init or ok ('status_counts')",
        ),
        (lambda r: _cut(r / "timing.csv", 3), "trajectory.txt holds 3 pose(s), and timing.csv marks 2 frame(s)"),
        (
            lambda r: (_cut(r / "trajectory.txt", 3), _cut(r / "timing.csv", 3)),
            "result.json says the run saw 3 frame(s) ('frames'), and timing.csv lists 2",
        ),
        (lambda r: (r / "timing.csv").write_text("garbage\n"), "timing.csv: holds no row"),
        (lambda r: _cut(r / "timing.csv", 0), "timing.csv: holds no row"),
        (lambda r: (r / "timing.csv").write_text("garbage\n1\n"), "timing.csv: has no 'frame' column"),
        # a malformed line: floorvo plot said only "not a run folder with poses"
        (lambda r: (r / "trajectory.txt").write_text("# h\n0.1 1 2\n"), "trajectory.txt:2: a TUM line has 8 numbers"),
    ],
    ids=[
        "trajectory-cut",
        "trajectory-empty",
        "no-timing",
        "timing-cut",
        "both-cut",
        "garbage",
        "empty",
        "no-frame",
        "bad-line",
    ],
)
def test_a_run_folder_cut_short_or_whose_files_disagree_is_refused_by_every_reader(
    small_seq, tmp_path, capsys, damage, words
):
    """A trajectory.txt cut at a line boundary was scored over the poses it still held ("tracked
    100.0 %", exit 0) beside a result.json and timing.csv of every frame; an empty one as "poses: 0,
    tracked 100.0 %"; floorvo calibrate fitted a scale from it; a timing.csv cut short gave the
    timing of the frames it still held, one of `garbage` or empty was ignored without a word."""
    run = tmp_path / "run"
    assert floorvo_main(["run", str(small_seq), "-e", "phase-corr", "-o", str(run)]) == 0
    damage(run)
    for argv in (
        ["score", str(run), "--gt", str(small_seq)],
        ["calibrate", str(run), "--gt", str(small_seq), "-o", str(tmp_path / "scale.json")],
        ["plot", str(run), "--gt", str(small_seq), "-o", str(tmp_path / "plot.png")],
    ):
        capsys.readouterr()
        assert floorvo_main(argv) == 1, argv
        assert words in _one_line(capsys, "floorvo"), argv
    assert not {"score.json", "scale.json", "plot.png"} & {p.name for p in [*run.iterdir(), *tmp_path.iterdir()]}


def test_a_run_over_a_range_of_frames_is_read_and_refused_when_cut_short(small_seq, tmp_path):
    """A run whose result.json records a sub-range of the sequence (frames 1-2 of 0-2) agrees with its
    files; cut short, it is refused as a whole run is."""
    from floorvo.errors import SequenceError
    from floorvo.run import run_estimator
    from floorvo.runfolder import RunFolder
    from floorvo.scoring import score_run

    run = tmp_path / "run"
    run_estimator(small_seq, "phase-corr", run, frames=[1, 2])
    back = RunFolder.read(run)
    assert back.result["frames"] == 2 and back.result["first_frame"] == 1 and len(back.timestamps_s) == 2
    assert score_run(run, small_seq).n_est == 2
    _cut(run / "trajectory.txt", 2)
    with pytest.raises(SequenceError, match=r"trajectory.txt holds 1 pose\(s\), and timing.csv marks 2 frame"):
        score_run(run, small_seq)


def test_a_rendered_sequences_ground_truth_cut_short_is_refused(small_seq, tmp_path, capsys):
    """A rendered sequence's groundtruth.txt cut to its first poses was scored over them ("10 matched
    of 10 ground truth", exit 0), calibrated on and benched. floorsim and floorvo.synthetic write a
    pose per frame; an imported recording's ground truth may be at another rate and is kept."""
    import shutil

    from floorvo.errors import SequenceError
    from floorvo.sequence import Sequence

    seq = shutil.copytree(small_seq, tmp_path / "seq")
    run = tmp_path / "run"
    assert floorvo_main(["run", str(seq), "-e", "phase-corr", "-o", str(run)]) == 0
    _cut(seq / "groundtruth.txt", 2)
    words = "groundtruth.txt: 2 pose(s) for 3 frame(s) (frame_count in sequence.json): the ground truth of a sequence"
    for argv in (
        ["score", str(run), "--gt", str(seq)],
        ["calibrate", str(run), "--gt", str(seq), "-o", str(tmp_path / "scale.json")],
        ["plot", str(run), "--gt", str(seq), "-o", str(tmp_path / "plot.png")],
        ["run", str(seq), "-e", "phase-corr", "-o", str(tmp_path / "run2")],
    ):
        capsys.readouterr()
        assert floorvo_main(argv) == 1, argv
        assert words + " drawn by floorvo.synthetic holds one pose per frame" in _one_line(capsys, "floorvo"), argv
    assert floorsim_main(["bench", str(seq), "--estimators", "phase-corr", "-o", str(tmp_path / "bench")]) == 1
    assert words in _one_line(capsys, "floorsim") and not (tmp_path / "bench").exists()
    # as floorsim renders it (sequence.json's versions name floorsim), and as an import (no such mark)
    meta = json.loads((seq / "sequence.json").read_text())
    del meta["synthetic"]
    (seq / "sequence.json").write_text(json.dumps({**meta, "versions": {"floorsim": "0.1.0"}}))
    with pytest.raises(SequenceError, match="a sequence rendered by floorsim holds one pose per frame"):
        Sequence.open(seq).groundtruth()
    (seq / "sequence.json").write_text(json.dumps({**meta, "source": {"format": "tum"}}))
    assert len(Sequence.open(seq).groundtruth()[0]) == 2


def test_an_unreadable_output_folder_is_one_line(small_seq, tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    assert floorvo_main(["run", str(small_seq), "-e", "phase-corr", "-o", str(blocker / "run")]) == 1
    assert str(blocker) in _one_line(capsys, "floorvo")


def test_opencv_5_is_refused_in_one_line_before_a_built_in_estimator_is_built(small_seq, tmp_path, monkeypatch, capsys):
    """OpenCV 5 moved AKAZE out of the main package: akaze-guided raised an AttributeError from its __init__."""
    import cv2

    monkeypatch.setattr(cv2, "__version__", "5.0.0")
    run = tmp_path / "run"
    assert floorvo_main(["run", str(small_seq), "-e", "akaze-guided", "-o", str(run)]) == 1
    err = _one_line(capsys, "floorvo")
    assert "'akaze-guided' needs OpenCV 4" in err and "OpenCV 5.0.0" in err and "opencv-python-headless>=4.10,<5" in err
    assert not (run / "result.json").exists()


# --------------------------------------------------------------------------- maps
def _tiny_map(root):
    """A 2-keyframe map of a 40 x 30 px camera with random arrays, saved to ``root``."""
    from floorvo.geometry import T_world_cam_down
    from floorvo.mapping.map import GlobalMap, MapConfig, save_map
    from floorvo.mapping.retrieval import BinaryVocabulary
    from floorvo.mapping.similarity import Features, downscale

    rng = np.random.default_rng(0)
    cam = CameraModel.from_sensor(40, 30, 7.4, 6.0)
    cfg = MapConfig()
    h, w = downscale(np.zeros((30, 40), np.uint8), cfg.similarity.sim_scale).shape
    feats = [
        Features(rng.uniform(0, 30, (n, 2)).astype(np.float32), rng.integers(0, 256, (n, 32), dtype=np.uint8))
        for n in (5, 7)
    ]
    m = GlobalMap(
        cam,
        100.0,
        cfg,
        [0, 3],
        np.array([0.0, 0.1]),
        np.stack([T_world_cam_down(0, 0, 100.0), T_world_cam_down(2.0, 0, 100.0)]),
        rng.integers(0, 256, (2, h, w), dtype=np.uint8),
        feats,
        BinaryVocabulary(rng.integers(0, 256, (4, 32), dtype=np.uint8), np.ones(4, np.float32)),
        n_mapping_frames=4,
    )
    return save_map(m, root)


def _resign(root, meta: dict | None = None, arrays: dict | None = None, npz_bytes: bytes | None = None) -> None:
    """Rewrite a map's files as a buggy or foreign writer would, with checksums that match."""
    import hashlib

    from floorvo.io import json_sha256

    mj, npz = root / "map.json", root / "keyframes.npz"
    meta = json.loads(mj.read_text()) if meta is None else meta
    if arrays is not None:
        buf = io.BytesIO()
        np.savez(buf, **arrays)
        npz_bytes = buf.getvalue()
    if npz_bytes is not None:
        npz.write_bytes(npz_bytes)
        meta["arrays"]["sha256"] = hashlib.sha256(npz_bytes).hexdigest()
    if isinstance(meta, dict):
        meta.pop("content_sha256", None)
        meta["content_sha256"] = json_sha256(meta)
    mj.write_text(json.dumps(meta))


def _map_refused(root, *words):
    from floorvo.errors import FloorbenchError
    from floorvo.mapping.map import load_map

    with pytest.raises(FloorbenchError) as info:
        load_map(root)
    msg = str(info.value)
    assert "\n" not in msg and len(msg) < 400, msg
    for w in words:
        assert w in msg, msg
    return msg


def test_an_edited_map_json_is_refused(tmp_path):
    """Issue 16: fx scaled by 1.1 in map.json was accepted (localisation error 0.02 -> 0.43 mm)."""
    from floorvo.mapping.map import load_map

    root = _tiny_map(tmp_path / "map")
    assert load_map(root).camera.fx_px == pytest.approx(6000 / 7.4)
    meta = json.loads((root / "map.json").read_text())
    meta["camera"]["K"][0][0] *= 1.1
    (root / "map.json").write_text(json.dumps(meta, indent=2))
    _map_refused(root, "map.json: content differs from its content_sha256")
    del meta["content_sha256"]
    (root / "map.json").write_text(json.dumps(meta, indent=2))
    _map_refused(root, "has no content_sha256")


def _npz_arrays(root) -> dict:
    with np.load(root / "keyframes.npz") as z:
        return {k: z[k] for k in z.files}


@pytest.mark.parametrize(
    "variant, words",
    [
        # map.json variants (AttributeError, KeyError and TypeError before)
        (lambda m, a: ([1], None), ("not a floorbench map",)),
        (lambda m, a: ({**m, "keyframes": 5}, None), ("keyframes = 5: must be a list",)),
        (lambda m, a: ({k: v for k, v in m.items() if k != "camera"}, None), ("camera", "missing")),
        (lambda m, a: ({**m, "camera": "none"}, None), ("camera = 'none': must be a table",)),
        (lambda m, a: ({**m, "arrays": []}, None), ("arrays = []: must be a table",)),
        (lambda m, a: ({**m, "height_mm": "80mm"}, None), ("height_mm = '80mm': must be a number",)),
        (lambda m, a: ({**m, "height_mm": float("nan")}, None), ("height_mm = nan mm: must be a finite number",)),
        (
            lambda m, a: ({**m, "keyframes": [{**m["keyframes"][0], "T_world_kf": [[1, 0]]}, m["keyframes"][1]]}, None),
            ("keyframes[0].T_world_kf = [[1.0, 0.0]]: must be a 4x4 matrix",),
        ),
        (lambda m, a: ({**m, "n_keyframes": 3}, None), ("n_keyframes = 3, but 2 keyframes",)),
        (
            lambda m, a: ({**m, "arrays": {**m["arrays"], "file": "../map.json"}}, None),
            ("arrays.file = '../map.json'",),
        ),
        (lambda m, a: ({**m, "parameters": {"vocab_words": "many"}}, None), ("map.vocab_words = 'many'",)),
        # keyframes.npz variants (BadZipFile, KeyError before)
        (lambda m, a: (m, b"PK\x03\x04 not a zip at all"), ("not a readable .npz archive",)),
        (lambda m, a: (m, {k: v for k, v in a.items() if k != "kp_offsets"}), ("array 'kp_offsets' is missing",)),
        (
            lambda m, a: (m, {**a, "images": a["images"].astype(np.float32)}),
            ("array 'images' has shape (2, 15, 20) and dtype float32: must be 3-dimensional",),
        ),
        (lambda m, a: (m, {**a, "images": a["images"][:, :-1]}), ("inconsistent map: images uint8",)),
        (lambda m, a: (m, {**a, "kp_offsets": a["kp_offsets"][::-1].copy()}), ("keypoint offsets",)),
        (lambda m, a: (m, {**a, "kp_xy_px": a["kp_xy_px"] * np.nan}), ("kp_xy_px", "finite")),
        (lambda m, a: (m, {**a, "vocab_idf": a["vocab_idf"][:2]}), ("vocab_idf (2,)",)),
        (lambda m, a: (m, {**a, "T_world_kf": a["T_world_kf"] + 1.0}), ("poses in map.json differ",)),
    ],
)
def test_malformed_maps_are_refused_in_one_line(tmp_path, variant, words):
    root = _tiny_map(tmp_path / "map")
    meta, arrays = variant(json.loads((root / "map.json").read_text()), _npz_arrays(root))
    if isinstance(arrays, bytes):
        _resign(root, meta, npz_bytes=arrays)
    else:
        _resign(root, meta, arrays=arrays)
    _map_refused(root, *words)


# --------------------------------------------------------------------------- text files that are not text
@pytest.mark.parametrize(
    "row, words",
    [
        ("1,nan,0,0,nan,ok,1,1,1", "column 'detect_ms' holds 'nan'; must hold finite milliseconds >= 0"),
        ("1,0,0,0,-1,ok,1,1,1", "column 'total_ms' holds '-1'"),
        ("1,0,0,0,1,ok,1.5,1,1", "column 'n_keypoints' holds '1.5'; must hold whole numbers >= 0"),
        ("0,0,0,0,1,ok,1,1,1", "frame 0 (row 2) follows frame 0"),  # a frame twice: one would be dropped
        ("1e10,0,0,0,1,ok,1,1,1", "column 'frame' must hold frame indices"),
    ],
)
def test_timing_rows_that_would_be_dropped_or_misread_are_refused(small_seq, tmp_path, capsys, row, words):
    run = tmp_path / "run"
    assert floorvo_main(["run", str(small_seq), "-e", "phase-corr", "-o", str(run)]) == 0
    lines = (run / "timing.csv").read_text().splitlines()
    # The row as the run wrote it: its leading columns, then empty cells for any text
    # columns the run adds (a run's timing.csv has a trailing `reason` column).
    lines[2] = row + "," * (lines[0].count(",") - row.count(","))
    (run / "timing.csv").write_text("\n".join(lines) + "\n")
    capsys.readouterr()
    assert floorvo_main(["score", str(run), "--gt", str(small_seq)]) == 1
    assert words in _one_line(capsys, "floorvo")


def test_binary_or_absurd_trajectory_and_json_files_are_one_line(tmp_path, small_seq, capsys):
    from floorvo.errors import SequenceError
    from floorvo.io import read_json
    from floorvo.tum import read_tum

    p = tmp_path / "trajectory.txt"
    p.write_bytes(b"\x89PNG\r\n\x1a\n\x00\xff\xfe")
    with pytest.raises(SequenceError, match=r"trajectory.txt: not a TUM text file \(byte 0 is not UTF-8 text\)"):
        read_tum(p)
    p.write_text("0 1e306 0 0 0 0 0 1\n")  # metres that overflow to inf in mm
    with pytest.raises(SequenceError, match="non-finite value"):
        read_tum(p)
    j = tmp_path / "x.json"
    for content, words in (
        (b"\xff\xfe{}", "byte 0 is not UTF-8"),
        (b"[" * 100_000 + b"]" * 100_000, "not valid JSON"),
        (b"1" * 5000, "not valid JSON"),
    ):
        j.write_bytes(content)
        with pytest.raises(SequenceError, match=words) as info:
            read_json(j)
        assert len(str(info.value)) < 300
    # through the CLI: a binary ground truth is one line
    run = tmp_path / "run"
    assert floorvo_main(["run", str(small_seq), "-e", "phase-corr", "-o", str(run)]) == 0
    (run / "trajectory.txt").write_bytes(b"\x00\xff" * 100)
    capsys.readouterr()
    assert floorvo_main(["score", str(run), "--gt", str(small_seq)]) == 1
    assert "not a TUM text file" in _one_line(capsys, "floorvo")


@pytest.mark.parametrize(
    "order, line, words", [((1, 0, 2), 3, "0.000000000 s follows 0.033333000 s"), ((0, 1, 1, 2), 4, "")]
)
def test_a_trajectory_whose_timestamps_do_not_increase_is_one_line(small_seq, tmp_path, capsys, order, line, words):
    """Poses out of time order or a time given twice were scored as they stood, exit 0 (the
    path length of a trajectory walked back and forth: 'end error 0 mm over 16 mm; measured
    12 mm of 12 mm'); read_tum, the one TUM reader, now refuses them for every caller."""
    from floorvo.errors import SequenceError
    from floorvo.tum import read_tum

    run = tmp_path / "run"
    assert floorvo_main(["run", str(small_seq), "-e", "phase-corr", "-o", str(run)]) == 0
    lines = [x for x in (run / "trajectory.txt").read_text().splitlines() if not x.startswith("#")]
    (run / "trajectory.txt").write_text("# header\n" + "".join(lines[i] + "\n" for i in order))
    with pytest.raises(SequenceError, match=rf"trajectory.txt:{line}: timestamp .*{words}.*must increase"):
        read_tum(run / "trajectory.txt")
    capsys.readouterr()
    assert floorvo_main(["score", str(run), "--gt", str(small_seq)]) == 1
    assert "the poses' timestamps must increase" in _one_line(capsys, "floorvo")


# --------------------------------------------------------------------------- sequence.json
@pytest.mark.parametrize(
    "content, words",
    [
        ("[1]", "holds a list; sequence.json must be a table of keys"),  # was "schema_version None"
        ("3.5", "holds float 3.5; sequence.json must be a table"),
        ('"x"', "holds str 'x'"),
    ],
)
def test_sequence_json_that_is_not_a_table_says_so(tmp_path, capsys, content, words):
    cam = CameraModel.from_sensor().scaled(0.1)
    seq = write_synthetic_sequence(tmp_path / "seq", cam, line_poses(4.0, 4.0), seed=0)
    (seq / "sequence.json").write_text(content)
    assert floorvo_main(["run", str(seq), "-e", "phase-corr", "-o", str(tmp_path / "run")]) == 1
    assert words in _one_line(capsys, "floorvo")


def test_a_key_given_twice_in_a_json_object_is_refused(tmp_path, capsys):
    """sequence.json with "fps": 30.0, "fps": 7.0 was read as 7 fps (JSON keeps the last key
    silently); a sequence without ground truth ran at the wrong frame times, exit 0."""
    cam = CameraModel.from_sensor().scaled(0.1)
    seq = write_synthetic_sequence(tmp_path / "seq", cam, line_poses(4.0, 4.0), seed=0)
    (seq / "groundtruth.txt").unlink()
    text = (seq / "sequence.json").read_text()
    (seq / "sequence.json").write_text(text.replace('"fps": 30.0,', '"fps": 30.0, "fps": 7.0,', 1))
    assert floorvo_main(["run", str(seq), "-e", "phase-corr", "-o", str(tmp_path / "run")]) == 1
    assert "sequence.json: key 'fps' is given twice in one object" in _one_line(capsys, "floorvo")


def test_a_frame_count_too_large_to_hold_is_refused(tmp_path):
    from floorvo.errors import SequenceError
    from floorvo.sequence import Sequence

    cam = CameraModel.from_sensor().scaled(0.1)
    seq = write_synthetic_sequence(tmp_path / "seq", cam, line_poses(4.0, 4.0), seed=0)
    meta = json.loads((seq / "sequence.json").read_text())
    (seq / "sequence.json").write_text(json.dumps({**meta, "frame_count": 1e308}))  # an integer-valued float
    with pytest.raises(SequenceError, match=r"frame_count = .*: must be <= 10000000"):
        Sequence.open(seq)


def test_localize_errors_name_the_options_not_the_estimator_config(tmp_path, small_seq, capsys):
    """Issue 16 item 10: `floorvo localize` errors were labelled `map-fused.map:`."""
    root = _tiny_map(tmp_path / "map")  # a 40 x 30 px camera; the sequence's is 162 x 124
    rc = floorvo_main(["localize", str(small_seq), "--map", str(root), "-o", str(tmp_path / "run")])
    err = _one_line(capsys, "floorvo")
    assert rc == 1 and f"--map {root}: the map's camera is (40, 30), the sequence's (162, 124)" in err
    assert "map-fused" not in err
    # the estimator itself (floorvo run -e map-fused) still names its config key
    rc = floorvo_main(["run", str(small_seq), "-e", "map-fused", "--set", f"map={root}", "-o", str(tmp_path / "r2")])
    assert rc == 1 and f"map-fused.map {root}: the map's camera is (40, 30)" in _one_line(capsys, "floorvo")


def test_sequence_fps_that_disagrees_with_its_ground_truth_is_refused(tmp_path, capsys):
    """Issue 16 item 4: with fps 60 in sequence.json and ground truth at 30 Hz, floorvo score
    scored 11 of 21 poses with exit code 0."""
    cam = CameraModel.from_sensor().scaled(0.1)
    seq = write_synthetic_sequence(tmp_path / "seq", cam, line_poses(8.0, 4.0), seed=0)  # 30 fps, 3 frames
    meta = json.loads((seq / "sequence.json").read_text())
    (seq / "sequence.json").write_text(json.dumps({**meta, "fps": 60.0}))
    assert floorvo_main(["run", str(seq), "-e", "phase-corr", "-o", str(tmp_path / "run")]) == 1
    err = _one_line(capsys, "floorvo")
    assert "groundtruth.txt: one pose per frame, but pose 1 is at 0.033333 s and frame 1 at 0.016667 s" in err
    assert "fps = 60 Hz" in err


def test_a_refused_render_writes_nothing(tmp_path, capsys):
    """Issue 16 item 5: --set floor.seed=abc left sequence.json and groundtruth.txt behind."""
    for bad in ("floor.seed=abc", "camera.pixel_pitch_um=8193", 'trajectory.type=["uniform"]', "fps=nan"):
        out = tmp_path / "seq"
        assert floorsim_main(["render", "demo", "--frames", "1", "--set", bad, "-o", str(out)]) == 1
        assert bad.split("=")[0].split(".")[0] in _one_line(capsys, "floorsim")
        assert not out.exists()


def test_an_error_line_is_one_line_whatever_it_quotes(tmp_path, capsys):
    p = tmp_path / ("x" * 200 + "\nline")
    p.mkdir()
    assert floorvo_main(["run", str(p), "-e", "phase-corr", "-o", str(tmp_path / "run")]) == 1
    assert "\\nline" in _one_line(capsys, "floorvo")


@pytest.mark.parametrize("which", ["frame", "flatfield"])
def test_an_image_of_another_bit_depth_than_sequence_json_states_is_refused(tmp_path, capsys, which):
    """A 16-bit frame in a sequence whose sequence.json says bit_depth = 8 was read as it was, 256
    times too bright, and phase-corr ran on with exit code 0; so was a flat field of another
    depth than calib.flatfield_bit_depth."""
    from floorvo.io import read_png, write_png

    cam = CameraModel.from_sensor().scaled(0.1)
    seq = write_synthetic_sequence(tmp_path / "seq", cam, line_poses(8.0, 4.0), seed=0)
    meta = json.loads((seq / "sequence.json").read_text())
    path = seq / "cam0" / "000001.png" if which == "frame" else seq / "calib" / "cam0_flatfield.png"
    bits = 8 * read_png(path).dtype.itemsize
    if which == "frame":
        meta["bit_depth"] = bits
    else:
        meta["calib"] = {"flatfield": "calib/cam0_flatfield.png", "flatfield_bit_depth": bits}
    (seq / "sequence.json").write_text(json.dumps(meta))
    run = ["run", str(seq), "-e", "phase-corr", "-o", str(tmp_path / "run0")]
    assert floorvo_main(run) == 0  # as written: the stated depth is the file's
    capsys.readouterr()
    image = read_png(path).astype(np.float64)
    write_png(path, (image * 257).astype(np.uint16) if bits == 8 else (image / 257).astype(np.uint8))
    assert floorvo_main(run[:-1] + [str(tmp_path / "run1")]) == 1
    key = "bit_depth" if which == "frame" else "calib.flatfield_bit_depth"
    other = 16 if bits == 8 else 8
    assert f"{path}: image is {other}-bit, sequence.json says {key} = {bits}" in _one_line(capsys, "floorvo")


def test_a_frame_of_another_bit_depth_than_frame_0_is_refused_where_none_is_stated(tmp_path, capsys):
    """sequence.json may state no bit_depth (the least sequence.json of the README, a synthetic
    sequence): a 16-bit frame among 8-bit ones was then read as it was, 256 times too bright,
    with exit code 0; frame 0's depth is the sequence's."""
    from floorvo.io import read_png, write_png

    cam = CameraModel.from_sensor().scaled(0.1)
    seq = write_synthetic_sequence(tmp_path / "seq", cam, line_poses(8.0, 4.0), seed=0)
    assert "bit_depth" not in json.loads((seq / "sequence.json").read_text())
    path = seq / "cam0" / "000001.png"
    write_png(path, read_png(path).astype(np.uint16) * 257)
    assert floorvo_main(["run", str(seq), "-e", "phase-corr", "-o", str(tmp_path / "run")]) == 1
    err = _one_line(capsys, "floorvo")
    assert f"{path}: image is 16-bit, frame 0 is 8-bit (sequence.json states no bit_depth" in err


def test_a_colour_frame_in_a_sequence_is_refused_not_turned_grey(tmp_path, capsys):
    """A 3-channel frame in a sequence folder was silently converted to grey, although a frame of
    another channel count than the camera's is refused (README); floorvo import converts colour."""
    from floorvo.io import read_png, write_png

    cam = CameraModel.from_sensor().scaled(0.1)
    seq = write_synthetic_sequence(tmp_path / "seq", cam, line_poses(8.0, 4.0), seed=0)
    path = seq / "cam0" / "000001.png"
    write_png(path, np.dstack([read_png(path)] * 3))
    assert floorvo_main(["run", str(seq), "-e", "phase-corr", "-o", str(tmp_path / "run")]) == 1
    err = _one_line(capsys, "floorvo")
    assert f"{path}: image is {cam.width_px}x{cam.height_px} with 3 channels, sequence.json says a mono" in err


@pytest.mark.parametrize("name", ["", "..", " "])
def test_an_output_file_path_that_names_no_file_is_one_line(small_seq, tmp_path, monkeypatch, capsys, name):
    """floorvo score/plot/calibrate -o "" said '.: Device or resource busy (errno 16)'."""
    run = tmp_path / "run"
    assert floorvo_main(["run", str(small_seq), "-e", "phase-corr", "-o", str(run)]) == 0
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    for command in ("score", "plot", "calibrate"):
        capsys.readouterr()
        assert floorvo_main([command, str(run), "--gt", str(small_seq), "-o", name]) == 1
        assert ": names no file; give a file name" in _one_line(capsys, "floorvo")  # ("" reaches it as ".")
    assert list(work.iterdir()) == []


def test_an_output_path_under_a_file_says_not_a_directory(small_seq, tmp_path, capsys):
    """-o FILE/x.json said 'FILE/x.json: File exists (errno 17)'; floorvo run FILE said the
    sequence folder did not exist; floorsim export -o FILE/out said 'FILE: File exists'."""
    run = tmp_path / "run"
    assert floorvo_main(["run", str(small_seq), "-e", "phase-corr", "-o", str(run)]) == 0
    afile = tmp_path / "afile"
    afile.write_text("x")
    for command in ("score", "plot", "calibrate"):
        capsys.readouterr()
        out = afile / "sub" / "x.png" if command == "plot" else afile / "x.json"
        assert floorvo_main([command, str(run), "--gt", str(small_seq), "-o", str(out)]) == 1
        assert f"{out}: not a directory ({afile} is a file)" in _one_line(capsys, "floorvo")  # before any work
    assert floorsim_main(["export", str(small_seq), "--format", "euroc", "-o", str(afile / "e")]) == 1
    assert f"{afile / 'e'}: not a directory ({afile} is a file)" in _one_line(capsys, "floorsim")
    assert floorvo_main(["run", str(afile), "-e", "phase-corr", "-o", str(tmp_path / "r")]) == 1
    assert f"{afile}: is a file, not a sequence folder" in _one_line(capsys, "floorvo")
    assert floorvo_main(["run", str(afile / "s"), "-e", "phase-corr", "-o", str(tmp_path / "r")]) == 1
    assert f"{afile / 's'}: sequence folder does not exist ({afile} is a file)" in _one_line(capsys, "floorvo")
    assert afile.read_text() == "x" and not (tmp_path / "r").exists()


def test_a_depth_map_of_another_size_is_refused_like_a_frame(tmp_path, capsys):
    """A depth map of 80x60 in a 160x120 sequence was taken as a lost frame ('depth image is 80x60
    px') and orb-icp ran on with exit code 0; a frame of another size is refused in one line."""
    cam = CameraModel.from_sensor(160, 120, 29.97, 6.0)
    seq = write_synthetic_sequence(tmp_path / "seq", cam, line_poses(8.0, 4.0), seed=0, depth=True)
    path = seq / "depth" / "000001.npy"
    np.save(path, np.full((60, 80), 100.0, np.float32))
    assert floorvo_main(["run", str(seq), "-e", "orb-icp", "-o", str(tmp_path / "run")]) == 1
    err = _one_line(capsys, "floorvo")
    assert f"{path}: depth map has shape (60, 80) and dtype float32: sequence.json says 160x120" in err


@pytest.mark.parametrize("kind", ["8-bit", "16-bit with 3 channels"])
def test_a_png16_depth_map_of_another_bit_depth_is_refused_like_a_frame(tmp_path, capsys, kind):
    """An 8-bit PNG in a png16 depth folder was read as 1/100 mm (depths of 0-2.55 mm): orb-icp lost
    its frames and exited 0. A frame of another bit depth is refused in one line, and so is it."""
    from floorvo.io import write_png
    from floorvo.sequence import DEPTH_PNG_SCALE_PER_MM

    cam = CameraModel.from_sensor(160, 120, 29.97, 6.0)
    seq = write_synthetic_sequence(tmp_path / "seq", cam, line_poses(8.0, 4.0), seed=0, depth=True)
    meta = json.loads((seq / "sequence.json").read_text())
    meta["depth"]["format"] = "png16"
    (seq / "sequence.json").write_text(json.dumps(meta))
    for npy in sorted((seq / "depth").glob("*.npy")):  # the same depths as 16-bit PNGs in 1/100 mm
        write_png(npy.with_suffix(".png"), np.round(np.load(npy) * DEPTH_PNG_SCALE_PER_MM).astype(np.uint16))
        npy.unlink()
    run = ["run", str(seq), "-e", "orb-icp", "-o", str(tmp_path / "run0")]
    assert floorvo_main(run) == 0
    capsys.readouterr()
    path = seq / "depth" / "000001.png"
    depth = np.full((120, 160), 100, np.uint8)
    write_png(path, depth if kind == "8-bit" else np.dstack([depth.astype(np.uint16) * 100] * 3))
    assert floorvo_main(run[:-1] + [str(tmp_path / "run1")]) == 1
    err = _one_line(capsys, "floorvo")
    assert f"{path}: depth map is {kind}, sequence.json says depth format png16 (one channel of 16 bits" in err


def _npy_header(shape: tuple[int, ...], descr: str = "<f4") -> bytes:
    """The header of a .npy file stating ``shape``, followed by a few bytes of data only."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": descr, "fortran_order": False, "shape": shape})
    return buf.getvalue() + bytes(16)


@pytest.mark.parametrize(
    "content, words",
    [
        (_npy_header((10**6, 10**6)), "has shape (1000000, 1000000) and dtype float32: sequence.json says 16x12"),
        (_npy_header((12, 16)), "states shape (12, 16) of float32 (768 bytes) in its header; the file holds 16 bytes"),
        (_npy_header((12, 16), "<f8"), "dtype float64: a depth map is float32 mm"),
        (_npy_header((12, 16), "|O"), "holds Python objects"),
    ],
)
def test_a_npy_depth_map_header_is_checked_before_its_data_is_read(tmp_path, capsys, monkeypatch, content, words):
    """np.load allocated the shape a crafted header stated (a 100-byte file can state terabytes),
    and read a float64 or another size's map as if it were the camera's."""
    cam = CameraModel.from_sensor().scaled(0.025)  # 16x12
    seq = write_synthetic_sequence(tmp_path / "seq", cam, line_poses(8.0, 4.0), seed=0, depth=True)
    path = seq / "depth" / "000001.npy"
    path.write_bytes(content)
    monkeypatch.setattr(np, "load", lambda *a, **k: pytest.fail("np.load reads the data before its header is checked"))
    assert floorvo_main(["run", str(seq), "-e", "orb-icp", "-o", str(tmp_path / "run")]) == 1
    err = _one_line(capsys, "floorvo")
    assert f"{path}: " in err and words in err, err


def test_npz_headers_of_maps_and_match_samples_are_checked_before_their_data_is_read(tmp_path):
    """The map's keyframes.npz and a run folder's matches/*.npz were read with np.load, which
    allocates the shape a member's header states before reading it."""
    import zipfile

    from floorvo.errors import SequenceError
    from floorvo.runfolder import read_match_samples, write_match_sample

    def crafted(names: dict[str, bytes]) -> bytes:
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w") as zf:
            for name, data in names.items():
                zf.writestr(f"{name}.npy", data)
        return buf.getvalue()

    root = _tiny_map(tmp_path / "map")
    arrays = _npz_arrays(root)
    members = {}
    for k, a in arrays.items():
        b = io.BytesIO()
        np.save(b, a)
        members[k] = b.getvalue()
    members["images"] = _npy_header((10**5, 10**5, 10**5), "|u1")
    _resign(root, npz_bytes=crafted(members))
    _map_refused(root, "keyframes.npz: array 'images' states shape (100000, 100000, 100000) of uint8")

    write_match_sample(tmp_path / "run", 1, np.zeros((3, 4)))
    path = tmp_path / "run" / "matches" / "000002.npz"
    path.write_bytes(crafted({"xy_prev_px": _npy_header((10**9, 2), "<f8"), "xy_cur_px": _npy_header((3, 2), "<f8")}))
    with pytest.raises(SequenceError, match=r"000002.npz: array 'xy_prev_px' states shape \(1000000000, 2\)"):
        read_match_samples(tmp_path / "run")
    path.write_bytes(crafted({"xy_prev_px": _npy_header((3, 5), "<f8"), "xy_cur_px": _npy_header((3, 2), "<f8")}))
    with pytest.raises(SequenceError, match=r"array 'xy_prev_px' has shape \(3, 5\) .*: must be \(N, 2\)"):
        read_match_samples(tmp_path / "run")


@pytest.mark.parametrize("shape", [(6, 8), (12, 16, 3)])
def test_a_flat_field_of_another_size_is_refused_in_one_line(tmp_path, capsys, shape):
    """A flat field of another size (or a colour one) ended in a ValueError from inside the
    estimator ('flatfield shape (60, 80) differs from the camera's 120x160')."""
    from floorvo.io import write_png

    cam = CameraModel.from_sensor().scaled(0.025)  # 16x12
    seq = write_synthetic_sequence(tmp_path / "seq", cam, line_poses(8.0, 4.0), seed=0)
    write_png(seq / "calib" / "cam0_flatfield.png", np.full(shape, 30000, np.uint16))
    assert floorvo_main(["run", str(seq), "-e", "phase-corr", "-o", str(tmp_path / "run")]) == 1
    err = _one_line(capsys, "floorvo")
    assert "cam0_flatfield.png: image is" in err and "sequence.json says a mono 16x12" in err


@pytest.mark.parametrize(
    "argv, words",
    [
        # OpenCV's RNG takes a C int: a larger seed ended in a ValueError or OverflowError traceback
        (["run", "SEQ", "-e", "homography-6dof", "--set", "seed=2147483648", "-o", "OUT"], "seed = 2147483648"),
        (["run", "SEQ", "-e", "orb-icp", "--set", "seed=99999999999999999999", "-o", "OUT"], "seed = 9999999999"),
        (["map", "SEQ", "--set", "seed=4294967296", "-o", "OUT"], "map.seed = 4294967296"),
    ],
)
def test_a_seed_beyond_31_bits_is_refused_in_one_line(small_seq, tmp_path, capsys, argv, words):
    argv = [str(small_seq) if a == "SEQ" else str(tmp_path / "out") if a == "OUT" else a for a in argv]
    assert floorvo_main(argv) == 1
    err = _one_line(capsys, "floorvo")
    assert words in err and "must be <= 2147483647" in err
    assert not (tmp_path / "out").exists()


def test_a_scene_or_study_seed_beyond_31_bits_is_refused(tmp_path, capsys):
    """Mitsuba's sampler took the seed's low 32 bits: seeds 2^32 apart rendered the same pixel jitter."""
    assert floorsim_main(["render", "demo", "--seed", str(2**32), "-o", str(tmp_path / "out")]) == 1
    assert "seed = 4294967296: must be <= 2147483647" in _one_line(capsys, "floorsim")
    from floorsim.bench.study import StudyFile
    from floorvo.errors import ConfigError

    with pytest.raises(ConfigError, match=r"seeds = \[1, 4294967297\]: must be distinct integers from 0 to 2147483647"):
        StudyFile(base="b.toml", seeds=(1, 2**32 + 1), vary={"lights.height_mm": [1.0]})


@pytest.mark.parametrize(
    "main, prog, argv, words",
    [
        (floorsim_main, "floorsim", ["render", "demo", "--frames", "abc", "-o", "x"], "argument --frames: invalid int"),
        (floorsim_main, "floorsim", ["rendr"], "argument COMMAND: invalid choice: 'rendr'"),
        (floorvo_main, "floorvo", ["run"], "the following arguments are required: sequence"),
    ],
)
def test_a_command_line_argparse_refuses_is_one_line_and_exit_code_1(tmp_path, capsys, main, prog, argv, words):
    """argparse printed its usage block and exited 2 (SystemExit out of main()); it is one line,
    naming the argument and where the help is, exit code 1, as every other refusal."""
    assert main(argv) == 1
    err = _one_line(capsys, prog)
    assert words in err and "--help)" in err


def test_a_scale_that_leaves_a_side_under_8_px_is_refused_not_raised_to_8(tmp_path, capsys):
    """--scale 1e-9 rendered the 324x247 demo camera as 8x8 px (each side raised to 8: another
    aspect and field of view than the scene's), exit code 0."""
    assert floorsim_main(["render", "demo", "--scale", "1e-9", "-o", str(tmp_path / "out")]) == 1
    err = _one_line(capsys, "floorsim")
    assert "--scale = 1e-09: makes the 324x247 px camera 0x0 px; a side must keep at least 8 px" in err
    assert "(--scale >= 0.0324)" in err and not (tmp_path / "out").exists()


@pytest.mark.parametrize("which", ["frame", "flatfield", "depth"])
def test_a_png_stating_another_size_is_refused_before_it_is_decoded(tmp_path, capsys, monkeypatch, which):
    """A PNG's header states its size: a frame, flat field or depth map of 60000x60000 px (a few
    kilobytes of file, 3.6 GB of pixels) was decoded in full before its size was compared."""
    import struct
    import zlib

    import cv2

    from floorvo.sequence import Sequence

    cam = CameraModel.from_sensor().scaled(0.025)  # 16x12
    seq = write_synthetic_sequence(tmp_path / "seq", cam, line_poses(8.0, 4.0), seed=0, depth=True)
    if which == "depth":  # png16 depth maps
        meta = json.loads((seq / "sequence.json").read_text())
        meta["depth"]["format"] = "png16"
        (seq / "sequence.json").write_text(json.dumps(meta))
        for p in (seq / "depth").glob("*.npy"):
            p.unlink()
    ihdr = struct.pack(">IIBBBBB", 60000, 60000, 8, 0, 0, 0, 0)
    chunk = struct.pack(">I", len(ihdr)) + b"IHDR" + ihdr + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr))
    bomb = b"\x89PNG\r\n\x1a\n" + chunk
    path = {
        "frame": seq / "cam0" / "000001.png",
        "flatfield": seq / "calib" / "cam0_flatfield.png",
        "depth": seq / "depth" / "000001.png",
    }[which]
    path.write_bytes(bomb)

    def no_decoding(*args, **kwargs):
        raise AssertionError("the PNG was decoded")

    monkeypatch.setattr(cv2, "imdecode", no_decoding)
    s = Sequence.open(seq)
    read = {"frame": lambda: s.image(1), "flatfield": lambda: s.flatfield(), "depth": lambda: s.depth_mm(1)}[which]
    from floorvo.errors import SequenceError

    noun = "depth map" if which == "depth" else "image"
    with pytest.raises(SequenceError, match=f"{noun} is 60000x60000, sequence.json says (a mono )?16x12"):
        read()


def test_a_shipped_scenes_folder_that_is_not_one_is_named(tmp_path, monkeypatch, capsys):
    """FLOORSIM_SCENES naming no folder made every shipped scene 'no such scene file or shipped
    scene', the variable unnamed, and floorsim list showed none."""
    monkeypatch.setenv("FLOORSIM_SCENES", str(tmp_path / "nope"))
    assert floorsim_main(["render", "demo", "-o", str(tmp_path / "out")]) == 1
    assert f"FLOORSIM_SCENES = '{tmp_path / 'nope'}': not a folder" in _one_line(capsys, "floorsim")
    assert floorsim_main(["list"]) == 1


def test_a_reader_that_closes_the_pipe_ends_the_command_quietly(tmp_path):
    """`floorsim list | head -1` printed 'floorsim: error: Broken pipe (errno 32)' and exited 1."""
    import subprocess
    import sys

    from _procs import child_env

    code = "import sys; from floorsim.cli import main; sys.exit(main(['list']))"
    p = subprocess.Popen(
        [sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=child_env(), cwd=tmp_path
    )
    assert p.stdout is not None and p.stderr is not None
    p.stdout.close()  # before the child has written a line: it is still importing
    err = p.stderr.read().decode()
    assert p.wait(timeout=120) == 141 and "error" not in err and "Traceback" not in err, err


def _editable_copy(small_seq, seq):
    """A copy of the sequence folder ``small_seq`` at ``seq`` whose files may be edited (its
    camera folder linked), and its ``sequence.json`` content."""
    seq.mkdir()
    for p in small_seq.iterdir():
        if p.is_file():
            (seq / p.name).write_bytes(p.read_bytes())
    (seq / "cam0").symlink_to(small_seq / "cam0")
    return seq, json.loads((small_seq / "sequence.json").read_text())


def test_a_huge_number_in_an_error_message_is_shown_short(tmp_path, small_seq, capsys):
    """1e308 formatted with ':.0f' is 309 digits, and an integer read from a file (frame_count =
    1e308, made an int) as many: errors of every kind of input show such a number in exponent
    form (floorvo.errors.shown_number), each line under 200 characters."""
    from floorvo.errors import SequenceError, shown, shown_number
    from floorvo.sequence import check_groundtruth_times

    assert shown_number(1e308, ".0f") == "1e+308" and shown_number(-1e20, ".1f") == "-1e+20"
    assert shown_number(10**400) == "1e+400" and shown(int(1e308)) == "1e+308"
    assert shown_number(0.2, ".6f") == "0.200000" and shown_number(float("inf"), ".0f") == "inf"
    lines = []
    # a sequence folder: sequence.json, a run of it
    seq, meta = _editable_copy(small_seq, tmp_path / "seq")
    for key, value in [("frame_count", 1e308), ("fps", 1e308), ("frame_count", 10**300)]:
        (seq / "sequence.json").write_text(json.dumps({**meta, key: value}))
        assert floorvo_main(["run", str(seq), "-e", "phase-corr", "-o", str(tmp_path / "run")]) == 1
        lines.append(_one_line(capsys, "floorvo"))
    # an estimator's config
    assert (
        floorvo_main(["run", str(small_seq), "-e", "phase-corr", "--set", "min_peak=1e308", "-o", str(tmp_path / "r")])
        == 1
    )
    lines.append(_one_line(capsys, "floorvo"))
    # ground truth at other times than the frames
    with pytest.raises(SequenceError) as exc:
        check_groundtruth_times(np.array([0.0, 1e308]), np.array([0.0, 0.1]), "groundtruth.txt", "fps")
    lines.append(str(exc.value))
    # a scene: a footprint of 5e300 mm of floor
    rc = floorsim_main(["render", "demo", "--set", "camera.pixel_pitch_um=1e300", "-o", str(tmp_path / "r")])
    assert rc == 1
    lines.append(_one_line(capsys, "floorsim"))
    assert "camera.pixel_pitch_um = 1e+300 um: must be <= 100000.0 um" in lines[-1]
    for line in lines:
        assert len(line) < 200 and ("e+308" in line or "e+300" in line), line


def test_an_output_path_in_a_loop_of_symbolic_links_is_one_line(small_seq, tmp_path, capsys):
    """-o LINK where LINK -> l2 -> LINK was a RuntimeError traceback ('Symlink loop')."""
    (tmp_path / "l1").symlink_to(tmp_path / "l2")
    (tmp_path / "l2").symlink_to(tmp_path / "l1")
    assert floorvo_main(["run", str(small_seq), "-e", "phase-corr", "-o", str(tmp_path / "l1")]) == 1
    assert f"{tmp_path / 'l1'}: cannot be resolved (" in _one_line(capsys, "floorvo")
    assert floorsim_main(["export", str(small_seq), "--format", "euroc", "-o", str(tmp_path / "l1")]) == 1
    assert "cannot be resolved" in _one_line(capsys, "floorsim")


def test_a_missing_float_depth_map_is_named_as_the_format_says(tmp_path, capsys):
    """With depth.format = npy_float32_mm and depth/000001.npy gone, the error named a .png."""
    cam = CameraModel.from_sensor().scaled(0.25)
    seq = write_synthetic_sequence(tmp_path / "seq", cam, line_poses(8.0, 4.0), depth=True, seed=0)
    (seq / "depth" / "000001.npy").unlink()
    assert floorvo_main(["run", str(seq), "-e", "orb-icp", "-o", str(tmp_path / "run")]) == 1
    assert f"{seq / 'depth' / '000001.npy'}: " in _one_line(capsys, "floorvo")


def test_a_ground_truth_that_is_a_folder_is_not_scored_as_none(small_seq, tmp_path, capsys):
    """A folder named groundtruth.txt was read as no ground truth: a score of tracking alone, exit 0."""
    import shutil

    seq = tmp_path / "seq"
    shutil.copytree(small_seq, seq)
    run = tmp_path / "run"
    assert floorvo_main(["run", str(seq), "-e", "phase-corr", "-o", str(run)]) == 0
    (seq / "groundtruth.txt").unlink()
    (seq / "groundtruth.txt").mkdir()
    capsys.readouterr()
    assert floorvo_main(["score", str(run), "--gt", str(seq)]) == 1
    assert f"{seq / 'groundtruth.txt'}: is not a file (the ground truth to score against" in _one_line(
        capsys, "floorvo"
    )


@pytest.mark.parametrize("key, value", [("estimator", 5), ("estimator", None), ("sequence", [1])])
def test_a_run_summary_naming_things_with_no_text_is_refused(small_seq, tmp_path, capsys, key, value):
    """result.json's estimator 5 (or null) was printed in the score and written into a calibration."""
    import json

    run = tmp_path / "run"
    assert floorvo_main(["run", str(small_seq), "-e", "phase-corr", "-o", str(run)]) == 0
    result = json.loads((run / "result.json").read_text())
    (run / "result.json").write_text(json.dumps({**result, key: value}))
    capsys.readouterr()
    assert floorvo_main(["score", str(run), "--gt", str(small_seq)]) == 1
    assert f"result.json: {key} = " in _one_line(capsys, "floorvo")


@pytest.mark.parametrize(
    ("key", "value", "spelled"), [("fps", None, "null"), ("fps", True, "true"), ("frame_count", False, "false")]
)
def test_a_json_value_in_an_error_message_is_spelled_as_json_writes_it(
    tmp_path, small_seq, capsys, key, value, spelled
):
    """A sequence.json value of null, true or false is named in the file's words: the message
    read 'None' and 'True', which a user finds in no file."""
    seq, meta = _editable_copy(small_seq, tmp_path / "seq")
    (seq / "sequence.json").write_text(json.dumps({**meta, key: value}))
    assert floorvo_main(["run", str(seq), "-e", "phase-corr", "-o", str(tmp_path / "run")]) == 1
    line = _one_line(capsys, "floorvo")
    assert spelled in line and key in line, line
    assert "None" not in line and "True" not in line and "False" not in line, line

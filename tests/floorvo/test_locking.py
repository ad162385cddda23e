"""Issue 16 item 1: every writer of a sequence, run or map folder locks it; a second writer is
refused in one line naming the folder and the holder's pid; the lock dies with its process;
readers never lock. The holder is a real second process (``_holder``)."""

from __future__ import annotations

import os
import signal
import threading
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from _procs import assert_refused, held_by_another_process
from floorvo.camera import CameraModel
from floorvo.cli import main as floorvo_main
from floorvo.errors import FloorbenchError, FolderLockedError
from floorvo.locking import LOCK_FILE, lock_folder, lock_holder, locks_folder
from floorvo.runfolder import RunFolder, write_match_sample
from floorvo.scoring import score_run
from floorvo.sequence import Sequence, SequenceWriter
from floorvo.synthetic import line_poses, write_synthetic_sequence

_holder = held_by_another_process
_refusal = assert_refused


@pytest.fixture(scope="module")
def seq(tmp_path_factory):
    """A 3-frame synthetic sequence at quarter size (with ground truth)."""
    cam = CameraModel.from_sensor().scaled(0.25)
    return write_synthetic_sequence(tmp_path_factory.mktemp("seq") / "seq", cam, line_poses(8.0, 4.0), seed=0)


# ----------------------------------------------------------------------------- the lock itself
def test_a_second_writer_is_refused_naming_the_folder_and_the_holders_pid(tmp_path):
    out = tmp_path / "out"
    with _holder(out) as p:
        assert lock_holder(out) is not None and lock_holder(out).split()[0] == str(p.pid)
        with pytest.raises(FolderLockedError) as exc:
            lock_folder(out, "run folder")
        assert exc.value.pid == p.pid and exc.value.folder == str(out)
        _refusal(str(exc.value), out, p.pid, "run folder")
    # the holder ended normally: its lock file is gone, the folder is free
    assert lock_holder(out) is None and not (out / LOCK_FILE).exists()
    with lock_folder(out, "run folder"):
        assert lock_holder(out).split()[0] == str(os.getpid())


def test_the_lock_dies_with_its_process_even_by_sigkill(tmp_path):
    out = tmp_path / "out"
    with _holder(out) as p:
        os.kill(p.pid, signal.SIGKILL)
        p.wait(timeout=20)
        assert (out / LOCK_FILE).read_text().split()[0] == str(p.pid)  # the file stays behind ...
        assert lock_holder(out) is None  # ... but nobody holds it
        with lock_folder(out, "run folder"):  # the next writer takes it over at once
            assert (out / LOCK_FILE).read_text().split()[0] == str(os.getpid())
        assert not (out / LOCK_FILE).exists()


def test_reentrant_in_one_thread_exclusive_between_threads(tmp_path):
    out = tmp_path / "out"
    errors: list[str] = []

    def other_thread():
        try:
            lock_folder(out, "run folder").release()
        except FolderLockedError as exc:
            errors.append(str(exc))

    with lock_folder(out, "run folder") as outer:
        with lock_folder(out, "run folder") as inner:  # a writer calling another writer of the folder
            assert inner.held and not inner.outer
        assert (out / LOCK_FILE).is_file()  # the inner release kept the outer's lock
        t = threading.Thread(target=other_thread)
        t.start()
        t.join()
        assert outer.outer
    assert errors == [f"{out}: another thread of this process (pid {os.getpid()}) is writing this run folder; "
                      "wait for it to finish or choose another output folder"]  # fmt: skip
    t = threading.Thread(target=other_thread)
    t.start()
    t.join()
    assert len(errors) == 1  # free again: the other thread took it


def test_wait_takes_the_lock_when_the_holder_ends(tmp_path):
    out = tmp_path / "out"
    with _holder(out) as p:
        threading.Timer(1.0, p.stdin.close).start()
        t0 = time.monotonic()
        with lock_folder(out, "sequence folder", wait=True):
            waited = time.monotonic() - t0
            assert p.wait(timeout=20) == 0
    assert waited >= 0.9


def test_a_refused_writer_leaves_no_folder_it_made_a_failed_one_keeps_its_folder(tmp_path):
    @locks_folder("out", "run folder")
    def refusing(out):
        raise FloorbenchError("bad input")

    @locks_folder("out", "run folder")
    def disk_full(out):
        raise OSError(28, "No space left on device")

    with pytest.raises(FloorbenchError):
        refusing(tmp_path / "a" / "b" / "c")
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(OSError):
        disk_full(tmp_path / "d")
    assert [p.name for p in tmp_path.iterdir()] == ["d"] and list((tmp_path / "d").iterdir()) == []


@pytest.mark.parametrize("bad", ["", "/"])
def test_no_lock_in_the_current_folder_or_the_root(bad, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(FloorbenchError, match="empty|root"):
        lock_folder(bad)
    assert list(tmp_path.iterdir()) == []


def test_a_file_where_the_folder_goes_is_one_line(tmp_path):
    (tmp_path / "f").write_text("x")
    with pytest.raises(FloorbenchError, match="exists and is not a folder"):
        lock_folder(tmp_path / "f")
    with pytest.raises(FloorbenchError, match=r"run: not a directory \(.*/f is a file\)"):
        lock_folder(tmp_path / "f" / "run")


def test_a_run_or_map_into_a_sequence_folder_is_refused(tmp_path, capsys):
    """floorvo run SEQ -o SEQ wrote trajectory.txt, timing.csv and result.json into the sequence
    (and floorvo map its map, floorsim bench its bench) with exit code 0."""
    cam = CameraModel.from_sensor().scaled(0.25)
    seq = write_synthetic_sequence(tmp_path / "seq", cam, line_poses(8.0, 4.0), seed=0)
    before = sorted(p.name for p in seq.iterdir())
    for argv, what in (
        (["run", str(seq), "-e", "phase-corr", "-o", str(seq)], "run folder"),
        (["map", str(seq), "-o", str(seq)], "map folder"),
    ):
        capsys.readouterr()
        assert floorvo_main(argv) == 1
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"is a sequence folder (sequence.json); a {what} goes in a folder" in err
    assert sorted(p.name for p in seq.iterdir()) == before
    with lock_folder(seq, "sequence folder"):  # its own writer still takes it
        pass


def _tree(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_outputs_over_what_a_command_reads_are_refused(tmp_path, capsys):
    """Each wrote with exit code 0 into what it read or another command's folder: a run among the
    frames (-o SEQ/cam0), a map among a run's files, a localisation among a map's, a score over
    the run's trajectory, a calibration over sequence.json, a plot over a frame, and an import
    of SEQ/cam0 into SEQ with --overwrite cleared the frames it was to read."""
    cam = CameraModel.from_sensor().scaled(0.25)
    seq = write_synthetic_sequence(tmp_path / "seq", cam, line_poses(12.0, 4.0), seed=0)
    run, mp = tmp_path / "run", tmp_path / "map"
    assert floorvo_main(["run", str(seq), "-e", "phase-corr", "-o", str(run)]) == 0
    assert floorvo_main(["map", str(seq), "-o", str(mp)]) == 0
    before = {d: _tree(d) for d in (seq, run, mp)}
    frame = seq / "cam0" / "000001.png"
    for argv, words in (
        (["run", str(seq), "-e", "phase-corr", "-o", str(seq / "cam0")], f"inside the sequence folder {seq}"),
        (["map", str(seq), "-o", str(run)], "is a run folder (result.json); a map folder goes in a folder of its own"),
        (["localize", str(seq), "--map", str(mp), "-o", str(mp)], "is a map folder (map.json); a run folder goes"),
        (["run", str(seq), "-e", "phase-corr", "-o", str(mp)], "is a map folder (map.json); a run folder goes"),
        (["score", str(run), "--gt", str(seq), "-o", str(run / "trajectory.txt")], "this command reads that file"),
        (["score", str(run), "--gt", str(seq / "groundtruth.txt"), "-o", str(seq / "groundtruth.txt")], "reads"),
        (["calibrate", str(run), "--gt", str(seq), "-o", str(seq / "sequence.json")], "inside the sequence folder"),
        (["calibrate", str(run), "--gt", str(seq), "-o", str(run / "result.json")], "this command reads that file"),
        (["plot", str(run), "--gt", str(seq), "-o", str(frame)], f"inside the sequence folder {seq}"),
        (
            ["import", str(seq / "cam0"), "-o", str(seq), "--overwrite", "--fps", "30", "--height-mm", "100"]
            + ["--fx", "200", "--fy", "200", "--cx", "80", "--cy", "60"],
            f"lies inside the output folder {seq}, which the import writes over",
        ),
    ):
        capsys.readouterr()
        assert floorvo_main(argv) == 1, argv
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and words in err, (argv, err)
    assert {d: _tree(d) for d in (seq, run, mp)} == before


# ----------------------------------------------------------------------------- every floorvo writer
def _writers(seq: Path, out: Path) -> dict:
    """Each writer of a folder at ``out`` (a callable; the CLIs return their exit code); the
    import reads the images of ``out/../images`` (:func:`_images`). Nothing is written here."""
    frames = out.parent / "images"
    run = RunFolder(np.zeros(1), np.eye(4)[None], None, {"estimator": "x"})
    cam = CameraModel.from_sensor().scaled(0.25)
    return {
        "floorvo run": lambda: floorvo_main(["run", str(seq), "-e", "phase-corr", "-o", str(out)]),
        "floorvo map": lambda: floorvo_main(["map", str(seq), "-o", str(out)]),
        "floorvo import": lambda: floorvo_main(
            [
                "import",
                str(frames),
                "--fps",
                "30",
                "--fx",
                "30",
                "--fy",
                "30",
                "--cx",
                "15",
                "--cy",
                "10",
                "-o",
                str(out),
            ]
        ),
        "floorvo localize": lambda: floorvo_main(["localize", str(seq), "--map", str(seq), "-o", str(out)]),
        "floorvo score": lambda: floorvo_main(["score", str(out), "--gt", str(seq)]),
        "RunFolder.write": lambda: run.write(out),
        "write_match_sample": lambda: write_match_sample(out, 1, np.zeros((2, 4))),
        "write_synthetic_sequence": lambda: write_synthetic_sequence(out, cam, line_poses(8.0, 4.0)),
        "SequenceWriter": lambda: SequenceWriter(out, {"camera": cam.to_dict(), "fps": 30.0, "frame_count": 1}),
        "save_map": lambda: __import__("floorvo.mapping.map", fromlist=["save_map"]).save_map(None, out),
    }


def _images(folder: Path) -> None:
    folder.mkdir()
    for i in range(3):
        cv2.imwrite(str(folder / f"{i}.png"), np.full((20, 30), 40 * i, np.uint8))


WRITERS = list(_writers(Path("s"), Path("o")))
WHAT = {"floorvo map": "map folder", "save_map": "map folder", "floorvo import": "sequence folder"}
WHAT |= {"write_synthetic_sequence": "sequence folder", "SequenceWriter": "sequence folder"}


@pytest.mark.parametrize("writer", WRITERS)
def test_every_writer_is_refused_while_another_process_writes_its_folder(writer, seq, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    _images(tmp_path / "images")
    if writer == "floorvo score":  # it writes score.json into the run folder it scores
        assert floorvo_main(["run", str(seq), "-e", "phase-corr", "-o", str(out)]) == 0
    before = sorted(p.name for p in out.iterdir())
    call = _writers(seq, out)[writer]
    what = WHAT.get(writer, "run folder")
    with _holder(out) as p:
        if writer.startswith("floorvo "):
            assert call() == 1
            _refusal(capsys.readouterr().err, out, p.pid, what)
        else:
            with pytest.raises(FolderLockedError) as exc:
                call()
            _refusal(str(exc.value), out, p.pid, what)
        assert sorted(p.name for p in out.iterdir()) == sorted([*before, LOCK_FILE])  # nothing written


def test_readers_never_lock(seq, tmp_path):
    run = tmp_path / "run"
    assert floorvo_main(["run", str(seq), "-e", "phase-corr", "-o", str(run)]) == 0
    with _holder(seq), _holder(run):
        assert Sequence.open(seq).frame_count == 3
        assert RunFolder.read(run).result["estimator"] == "phase-corr"
        assert score_run(run, seq).ground_truth
        assert floorvo_main(["score", str(run), "--gt", str(seq), "-o", str(tmp_path / "score.json")]) == 0


def test_a_lock_file_left_by_a_killed_writer_is_no_file_of_the_sequence(tmp_path):
    """A writer killed before its first file leaves only ``.floorbench.lock``: the folder still
    counts as empty, and --overwrite and the sequence reader ignore the file."""
    cam = CameraModel.from_sensor().scaled(0.1)
    out = tmp_path / "seq"
    out.mkdir()
    (out / LOCK_FILE).write_text("999999 elsewhere\n")
    write_synthetic_sequence(out, cam, line_poses(8.0, 4.0), seed=0, overwrite=False)
    assert sorted(p.name for p in out.iterdir()) == ["calib", "cam0", "groundtruth.txt", "sequence.json"]
    (out / LOCK_FILE).write_text("999999 elsewhere\n")
    assert Sequence.open(out).frame_count == 3
    write_synthetic_sequence(out, cam, line_poses(8.0, 4.0), seed=1, overwrite=True)  # another sequence
    assert Sequence.open(out).meta["seeds"] == {"texture": 1}
    assert not (out / LOCK_FILE).exists()  # taken over, then removed by the writer that ended


def test_the_next_writer_removes_what_a_killed_writer_left_in_the_folder(seq, tmp_path):
    """A run killed while writing left its lock file and a temporary: the next run takes the
    lock over and removes the temporary (only a holder of the lock writes there)."""
    run = tmp_path / "run"
    run.mkdir()
    (run / LOCK_FILE).write_text("999999 elsewhere\n")
    stale = run / ".trajectory.txt.0123abcd.tmp"
    stale.write_text("# half a traj")
    assert floorvo_main(["run", str(seq), "-e", "phase-corr", "-o", str(run)]) == 0
    assert sorted(p.name for p in run.iterdir()) == ["result.json", "timing.csv", "trajectory.txt"]


def test_a_ctrl_c_while_a_lock_is_taken_leaves_no_lock_file(tmp_path, monkeypatch):
    """A SIGINT between creating the lock file and recording the lock left a ``.floorbench.lock``
    that nothing removed (seen when ``floorsim bench`` was interrupted as a run folder appeared):
    the signal is now held back until the lock is recorded, and the exit clean-up removes it."""
    import floorvo.locking as locking

    real = locking._try_lock

    def interrupted(lock_path):
        taken = real(lock_path)
        os.kill(os.getpid(), signal.SIGINT)
        return taken

    monkeypatch.setattr(locking, "_try_lock", interrupted)
    with pytest.raises(KeyboardInterrupt):
        lock_folder(tmp_path / "run", "run folder")
    locking._release_all_at_exit()  # what the interpreter's exit does
    assert not (tmp_path / "run" / LOCK_FILE).exists()

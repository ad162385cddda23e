"""Property-based tests (issue 16): every floorvo reader and config, given any input, gives
a valid object or one FloorbenchError line, never another exception.

Inputs are edits of a valid document (a value replaced by a nearby or a random one, a key
dropped or added, the whole document swapped) and random bytes; see ``tests/_fuzz.py``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from _fuzz import edited, one_line_or_valid, values
from floorvo.camera import CameraModel
from floorvo.config import from_overrides, parse_set_args
from floorvo.estimators import get_estimator, list_estimators, make_config
from floorvo.io import json_sha256, read_json
from floorvo.mapping.map import MapConfig, load_map
from floorvo.sequence import Sequence
from floorvo.synthetic import line_poses, write_synthetic_sequence
from floorvo.tum import read_tum

CAMERA = CameraModel.from_sensor().scaled(0.1)


@pytest.fixture(scope="module")
def workdir():
    with tempfile.TemporaryDirectory(prefix="floorbench-props-") as d:
        yield Path(d)


# --------------------------------------------------------------------------- camera blocks
@given(edited(CAMERA.to_dict()))
def test_camera_block(block):
    cam = one_line_or_valid(lambda: CameraModel.from_dict(block))
    if isinstance(cam, CameraModel):
        assert cam.width_px >= 1 and cam.fx_px > 0 and np.isfinite(cam.K).all()


# --------------------------------------------------------------------------- TUM files
TUM_LINE = st.lists(
    st.one_of(st.floats(), st.integers(-(10**30), 10**30), st.sampled_from(["x", "1,2", "nan", "#", "0x10"])),
    min_size=0,
    max_size=9,
).map(lambda xs: " ".join(map(str, xs)))


@given(st.one_of(st.binary(max_size=200), st.lists(TUM_LINE, max_size=6).map(lambda ls: "\n".join(ls).encode())))
def test_tum_file(workdir, data):
    p = workdir / "trajectory.txt"
    p.write_bytes(data)
    got = one_line_or_valid(lambda: read_tum(p))
    if isinstance(got, tuple):
        ts, T = got
        assert len(ts) == len(T) >= 1 and np.isfinite(ts).all() and np.isfinite(T).all()
        np.testing.assert_allclose(
            T[:, :3, :3] @ T[:, :3, :3].transpose(0, 2, 1), np.broadcast_to(np.eye(3), T[:, :3, :3].shape), atol=1e-9
        )


# --------------------------------------------------------------------------- JSON files
@given(st.one_of(st.binary(max_size=100), values.map(lambda v: json.dumps(v).encode())))
def test_json_file(workdir, data):
    p = workdir / "any.json"
    p.write_bytes(data)
    one_line_or_valid(lambda: read_json(p))


# --------------------------------------------------------------------------- configs and --set
CONFIGS = {name: get_estimator(name).Config for name in list_estimators()} | {"map": MapConfig}


@given(
    st.sampled_from(sorted(CONFIGS)),
    st.dictionaries(st.text(max_size=10), st.text(max_size=12), max_size=2),
    st.data(),
)
def test_config_overrides(name, extra, data):
    cls = CONFIGS[name]
    keys = [f.name for f in dataclasses.fields(cls)]
    texts = data.draw(
        st.dictionaries(st.sampled_from(keys), st.one_of(st.text(max_size=12), values.map(str)), max_size=3)
    )
    cfg = one_line_or_valid(lambda: from_overrides(cls, {**texts, **extra}, name))
    if name in list_estimators():
        one_line_or_valid(lambda: make_config(name, {**texts, **extra}))
    if isinstance(cfg, cls):
        assert from_overrides(cls, {}, name).__class__ is cfg.__class__


@given(st.lists(st.text(max_size=20), max_size=4))
def test_set_arguments(items):
    one_line_or_valid(lambda: parse_set_args(items))


# --------------------------------------------------------------------------- sequence.json
@pytest.fixture(scope="module")
def sequence(workdir):
    """A 2-frame synthetic sequence and its sequence.json."""
    root = write_synthetic_sequence(workdir / "seq", CAMERA, line_poses(4.0, 4.0), seed=0)
    return root, json.loads((root / "sequence.json").read_text())


@given(st.data())
def test_sequence_json_edits(sequence, data):
    root, meta = sequence
    doc = data.draw(edited(meta))
    (root / "sequence.json").write_text(json.dumps(doc))
    try:
        seq = one_line_or_valid(lambda: Sequence.open(root))
        if isinstance(seq, Sequence):
            assert seq.frame_count >= 1 and seq.fps > 0 and np.isfinite(seq.timestamps_s).all()
            assert seq.height_mm is None or seq.height_mm > 0
            assert seq.camera.fx_px > 0
            one_line_or_valid(lambda: seq.image(0))
    finally:
        (root / "sequence.json").write_text(json.dumps(meta))


# --------------------------------------------------------------------------- maps
@pytest.fixture(scope="module")
def map_dir(workdir):
    from test_bad_input import _tiny_map

    root = _tiny_map(workdir / "map")
    return root, (root / "map.json").read_text(), (root / "keyframes.npz").read_bytes()


ARRAY_EDITS = st.sampled_from(["drop", "dtype", "shape", "nan", "empty", "transpose"])


@given(st.data(), st.booleans(), st.lists(st.tuples(st.integers(0, 6), ARRAY_EDITS), max_size=2))
def test_map_folder(map_dir, data, resign, array_edits):
    """map.json edited (with checksums made to match, as a buggy writer would, or not) and
    keyframes.npz arrays dropped, retyped, reshaped, emptied or filled with NaN."""
    root, meta_text, npz_bytes = map_dir
    meta = data.draw(edited(json.loads(meta_text)))
    with np.load(io.BytesIO(npz_bytes)) as z:
        arrays = {k: z[k] for k in z.files}
    names = sorted(arrays)
    for i, how in array_edits:
        k = names[i % len(names)]
        if k not in arrays:
            continue
        a = arrays[k]
        if how == "drop":
            del arrays[k]
        elif how == "dtype":
            arrays[k] = a.astype(np.float16 if a.dtype.kind != "f" else np.int8)
        elif how == "shape":
            arrays[k] = a.reshape(-1)
        elif how == "nan" and a.dtype.kind == "f":
            arrays[k] = np.full_like(a, np.nan)
        elif how == "empty":
            arrays[k] = a[:0]
        elif how == "transpose":
            arrays[k] = a.T.copy()
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    data_npz = buf.getvalue() if array_edits else npz_bytes
    (root / "keyframes.npz").write_bytes(data_npz)
    if resign and isinstance(meta, dict):
        if isinstance(meta.get("arrays"), dict):
            meta["arrays"]["sha256"] = hashlib.sha256(data_npz).hexdigest()
        meta.pop("content_sha256", None)
        meta["content_sha256"] = json_sha256(meta)
    (root / "map.json").write_text(json.dumps(meta))
    try:
        m = one_line_or_valid(lambda: load_map(root))
        if not isinstance(m, Exception):
            assert m.n_keyframes == len(m.T_world_kf) == len(m.images) == len(m.features) >= 1
            assert np.isfinite(m.T_world_kf).all() and m.height_mm > 0
    finally:
        (root / "map.json").write_text(meta_text)
        (root / "keyframes.npz").write_bytes(npz_bytes)


# --------------------------------------------------------------------------- run folders
@pytest.fixture(scope="module")
def run_dir(sequence, workdir):
    """A phase-corr run over the 2-frame sequence, and its files' contents."""
    from floorvo.run import run_estimator

    root, _ = sequence
    run = workdir / "run"
    run_estimator(root, "phase-corr", run)
    return run, {f: (run / f).read_bytes() for f in ("trajectory.txt", "timing.csv", "result.json")}


CELLS = st.one_of(
    st.sampled_from(["", "0", "1", "2", "-1", "nan", "inf", "1e10", "1.5", "ok", "lost", "init", "x", '"a,b"']),
    st.floats().map(str),
    st.integers(-5, 5).map(str),
)


@given(
    st.data(),
    st.sampled_from(["timing", "result", "both"]),
    st.one_of(st.none(), st.binary(max_size=60)),
)
def test_run_folder(sequence, run_dir, data, which, raw):
    """timing.csv rows of any cells (under its header, or a random one), result.json edited, or
    either file replaced by bytes: RunFolder.read and floorvo score give a run or one line."""
    from floorvo.runfolder import TIMING_COLUMNS, RunFolder
    from floorvo.scoring import score_run

    root, _ = sequence
    run, files = run_dir
    if which in ("timing", "both"):
        header = data.draw(st.just(",".join(TIMING_COLUMNS)) | st.lists(CELLS, max_size=4).map(",".join))
        rows = data.draw(st.lists(st.lists(CELLS, min_size=0, max_size=10).map(",".join), max_size=3))
        (run / "timing.csv").write_bytes(raw if raw is not None else "\n".join([header, *rows]).encode() + b"\n")
    if which in ("result", "both"):
        doc = data.draw(edited(json.loads(files["result.json"])))
        (run / "result.json").write_bytes(raw if raw is not None and which == "result" else json.dumps(doc).encode())
    try:
        got = one_line_or_valid(lambda: RunFolder.read(run))
        if isinstance(got, RunFolder) and got.timing and "frame" in got.timing:
            assert np.all(np.diff(got.timing["frame"]) > 0)
        one_line_or_valid(lambda: score_run(run, root))
    finally:
        for name, content in files.items():
            (run / name).write_bytes(content)


# --------------------------------------------------------------------------- other text files
def _readers():
    from floorsim.bench.results import read_results_csv
    from floorvo.calibration import load_scale_calibration
    from floorvo.external import load_estimator_file
    from floorvo.importers.camera_files import read_camera_file
    from floorvo.importers.images import list_images
    from floorvo.importers.times import read_groundtruth_file, read_timestamps_file
    from floorvo.sequence import _read_timestamps

    return {
        "timestamps.txt": _read_timestamps,
        "times.csv": read_timestamps_file,
        "gt.csv": read_groundtruth_file,
        "camera.yaml": read_camera_file,
        "scale.json": load_scale_calibration,
        "results.csv": read_results_csv,
        "estimator.toml": load_estimator_file,
        "images.txt": list_images,
    }


LINES = st.lists(st.lists(CELLS, max_size=9).map(lambda cs: ",".join(cs)), max_size=5).map("\n".join)
YAMLISH = st.sampled_from(
    [
        "%YAML:1.0\n",
        "camera_matrix: {rows: 3, cols: 3, data: [1, 0, 1, 0, 1, 1, 0, 0, 1]}\n",
        "image_width: 10\n",
        "cam0: {intrinsics: [1, 1, 1, 1], resolution: [4, 4]}\n",
        "K: [1, 2]\n",
        "- a\n",
        "a: !!opencv-matrix {}\n",
        "distortion_coefficients: {data: [nan]}\n",
        "image_height: x\n",
        "T_cn_cnm1: [[1]]\n",
    ]
)


@given(
    st.sampled_from(sorted(_readers())),
    st.one_of(
        st.binary(max_size=120),
        LINES.map(str.encode),
        st.lists(YAMLISH, max_size=4).map(lambda ls: "".join(ls).encode()),
        values.map(lambda v: json.dumps(v).encode()),
    ),
)
def test_text_file_readers(workdir, name, data):
    """Frame-time files, imported timestamps and ground truth, camera files, scale
    calibrations, results.csv, external estimator files and image lists."""
    p = workdir / name
    p.write_bytes(data)
    one_line_or_valid(lambda: _readers()[name](p))

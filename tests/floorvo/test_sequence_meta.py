"""sequence.json is checked as strictly as a scene file: one line naming the key, the value and the rule."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest

from floorvo.cli import main
from floorvo.errors import SequenceError
from floorvo.sequence import Sequence, SequenceWriter

GOOD = {
    "schema_version": 2,
    "camera": {
        "width_px": 32,
        "height_px": 24,
        "K": [[40.0, 0.0, 15.5], [0.0, 40.0, 11.5], [0.0, 0.0, 1.0]],
        "distortion": [0.0, 0.0, 0.0, 0.0, 0.0],
    },
    "fps": 30.0,
    "frame_count": 2,
    "rig": {"height_mm": 100.0},
}


def _folder(tmp_path, meta, text: str | None = None):
    root = tmp_path / "seq"
    (root / "cam0").mkdir(parents=True, exist_ok=True)
    (root / "sequence.json").write_text(text if text is not None else json.dumps(meta))
    return root


def _with(path: str, value):
    meta = copy.deepcopy(GOOD)
    node = meta
    *parents, last = path.split(".")
    for p in parents:
        node = node[p]
    if value is KeyError:
        del node[last]
    else:
        node[last] = value
    return meta


@pytest.mark.parametrize(
    "path, value, message",
    [
        ("rig.height_mm", "80mm", "rig.height_mm = '80mm': must be a number or none"),
        ("fps", "30fps", "fps = '30fps': must be a number"),
        ("rig.height_mm", float("nan"), "rig.height_mm = nan mm: must be a finite number"),
        ("rig.height_mm", -5.0, "rig.height_mm = -5.0 mm: must be >= 1.0 mm"),
        ("rig", "none", "rig = 'none': must be a table"),
        ("rig.height_noise_mm", -0.1, "rig.height_noise_mm = -0.1 mm: must be >= 0.0 mm"),
        ("fps", 0, "fps = 0.0 Hz: must be >= 0.01 Hz"),
        ("fps", 1e7, "fps = 10000000.0 Hz: must be <= 1000000.0 Hz"),
        ("frame_count", 0, "frame_count = 0: must be >= 1"),
        ("frame_count", 2.5, "frame_count = 2.5: must be integer"),
        ("frame_count", KeyError, "frame_count: missing (a required key)"),
        ("camera.K", KeyError, "camera.K: missing (a required key)"),
        ("height_mm", 100.0, "height_mm: unknown key (known: bit_depth, calib, camera"),
        ("rig.heigth_mm", 100.0, "rig.heigth_mm: unknown key (known: T_cam0_cam1, gsd_mm_per_px, height_mm"),
        ("camera.K", [[40.0, 0.0], [0.0, 40.0]], "camera.K = [[40.0, 0.0], [0.0, 40.0]]: must be a 3x3 matrix"),
        ("camera.K", [[40.0, 0, 15.5], [0, -40.0, 11.5], [0, 0, 1]], "camera.K = [[40.0, 0.0, 15.5], [0.0, -40.0"),
        ("camera.distortion", [0.1, 0.2], "camera.distortion = [0.1, 0.2]: must be 4 or 5 finite numbers"),
        # a principal point far outside the 32x24 image (cx in another unit, or of another resolution) was taken
        (
            "camera.K",
            [[40.0, 0.0, 1550.0], [0.0, 40.0, 11.5], [0.0, 0.0, 1.0]],
            "camera.K = [[40.0, 0.0, 1550.0], [0.0, 40.0, 11.5], [0.0, 0.0, 1.0]]: principal point (cx, cy) = "
            "(1550, 11.5) px must lie in the image: -0.5 <= cx <= width_px and -0.5 <= cy <= height_px (32x24 px)",
        ),
        ("camera.K", [[40.0, 0.0, 15.5], [0.0, 40.0, -3.0], [0.0, 0.0, 1.0]], "(cx, cy) = (15.5, -3) px must lie"),
        ("camera.width_px", "32", "camera.width_px = '32': must be integer"),
        ("stereo", True, "stereo = true: needs cameras.cam1 and rig.T_cam0_cam1"),
        ("stereo", "no", "stereo = 'no': must be true or false"),
        ("depth", {"format": "exr"}, "depth.format = 'exr': must be one of 'png16', 'npy_float32_mm'"),
        ("cameras", {"cam2": GOOD["camera"]}, "cameras.cam2: unknown camera (known: cam1)"),
        ("rig.T_cam0_cam1", np.diag([1.0, 1.0, 1.0, 2.0]).tolist(), "rig.T_cam0_cam1 = [[1.0, 0.0, 0.0, 0.0]"),
        # a mirrored right camera (det R = -1) passed the orthonormality test and was used as it was
        (
            "rig.T_cam0_cam1",
            np.diag([1.0, 1.0, -1.0, 1.0]).tolist(),
            "must be a rigid 4x4 transform (its 3x3 part is not a rotation (orthonormal, determinant +1))",
        ),
    ],
)
def test_bad_sequence_json_is_one_line(tmp_path, capsys, path, value, message):
    root = _folder(tmp_path, _with(path, value))
    with pytest.raises(SequenceError) as exc:
        Sequence.open(root)
    assert message in str(exc.value)
    assert str(exc.value).startswith(f"{root / 'sequence.json'}: ")
    rc = main(["run", str(root), "-e", "phase-corr", "-o", str(tmp_path / "run")])
    err = capsys.readouterr().err.strip()
    assert rc == 1 and len(err.splitlines()) == 1 and message in err


def test_not_an_object_and_nan_literal(tmp_path):
    root = _folder(tmp_path, None, "[1, 2]")
    # issue 16 item 10: a JSON list is not a schema-version problem
    with pytest.raises(SequenceError, match="holds a list; sequence.json must be a table of keys"):
        Sequence.open(root)
    text = json.dumps(GOOD).replace('"fps": 30.0', '"fps": NaN')
    root = _folder(tmp_path, None, text)
    with pytest.raises(SequenceError, match="fps = nan Hz: must be a finite number"):
        Sequence.open(root)


def test_good_sequence_loads_and_the_writer_refuses_what_would_not(tmp_path):
    root = _folder(tmp_path, GOOD)
    seq = Sequence.open(root)
    assert seq.height_mm == 100.0 and seq.fps == 30.0 and seq.camera.size == (32, 24)
    bad = {k: v for k, v in _with("fps", -1.0).items() if k != "schema_version"}
    with pytest.raises(SequenceError, match="fps = -1.0 Hz: must be >= 0.01 Hz"):
        SequenceWriter(tmp_path / "other", bad)
    assert not (tmp_path / "other" / "sequence.json").exists()


def test_list_config_sequence_prints_every_key(capsys):
    from floorvo.sequence_meta import SequenceMeta

    assert main(["list", "--config", "sequence"]) == 0
    out = capsys.readouterr().out
    rows = {line.split()[0]: line for line in out.splitlines()[2:]}
    assert set(rows) >= {f for f in SequenceMeta.__dataclass_fields__ if f not in ("camera", "rig")}
    assert "camera.K" in rows and "(required)" in rows["camera.K"]
    assert "mm" in rows["rig.height_mm"].split() and "[1.0, 20000.0]" in rows["rig.height_mm"]


def test_the_optional_sensor_block_states_the_row_times_and_is_checked(tmp_path):
    from floorvo.sequence_meta import check_sequence_meta

    # A sequence without it (every sequence written before it existed) reads as a global shutter.
    block = check_sequence_meta(copy.deepcopy(GOOD)).sensor_block
    assert block.shutter == "global" and block.exposure_mode == "fixed"
    np.testing.assert_array_equal(block.row_offsets_s(24), np.zeros(24))
    rolling = _with("sensor", {"shutter": "rolling", "readout_ms": 23.0, "groundtruth_row": 11.5})
    offsets = check_sequence_meta(rolling).sensor_block.row_offsets_s(24)
    # Row r at (r - 11.5) / 23 x 23 ms: the first row 11.5 ms early, the last 11.5 ms late, 1 ms apart.
    np.testing.assert_allclose(offsets, (np.arange(24) - 11.5) * 1e-3)
    assert Sequence.open(_folder(tmp_path, rolling)).frame_count == 2
    for value, message in (
        ({"shutter": "sideways"}, "sensor.shutter = 'sideways': must be one of"),
        ({"readout_ms": -1.0}, "sensor.readout_ms = -1.0 ms"),
        ({"exposure_mode": "auto", "lens": 1}, "sensor.lens"),
        ("rolling", "sensor = 'rolling': must be a table"),
    ):
        with pytest.raises(SequenceError) as info:
            Sequence.open(_folder(tmp_path, _with("sensor", value)))
        assert message in str(info.value) and "\n" not in str(info.value)

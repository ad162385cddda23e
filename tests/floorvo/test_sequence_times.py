"""Per-frame times in the sequence format (schema 2, ``timestamps.txt``), and how run and score use them."""

from __future__ import annotations

import json

import numpy as np
import pytest

from floorvo.camera import CameraModel
from floorvo.errors import SequenceError
from floorvo.geometry import T_world_cam_down
from floorvo.sequence import Sequence
from floorvo.synthetic import line_poses, write_synthetic_sequence
from floorvo.tum import read_tum, write_tum

CAM = CameraModel.from_sensor(162, 124, pixel_pitch_um=29.6, focal_length_mm=6.0)


def test_timestamps_file_drives_run_and_score(tmp_path):
    """Uneven frame times: the run is stamped with them, starts at the ground truth of the first frame
    run, and score cuts the reference to the frames the run saw, by time."""
    from floorvo.run import run_estimator
    from floorvo.scoring import score_run

    T = line_poses(24.0, 4.0, 100.0)
    root = write_synthetic_sequence(tmp_path / "s", CAM, T, seed=1)
    t = 5.0 + np.cumsum([0.0, 0.05, 0.02, 0.04, 0.03, 0.06, 0.02])
    write_tum(root / "groundtruth.txt", t, T)
    (root / "timestamps.txt").write_text("".join(f"{x:.9f}\n" for x in t))
    seq = Sequence.open(root)
    np.testing.assert_allclose(seq.timestamps_s, t)
    run_estimator(seq, "phase-corr", tmp_path / "run", frames=range(2, 7))
    t_run, T_run = read_tum(tmp_path / "run" / "trajectory.txt")
    np.testing.assert_allclose(t_run, t[2:], atol=1e-6)
    np.testing.assert_allclose(T_run[0], T[2], atol=1e-9)
    score = score_run(tmp_path / "run", root)
    assert score.n_ref == 5 and score.n_matched == 5
    assert score.ate["none"]["trans_mm"]["max"] < 0.2
    (root / "timestamps.txt").write_text("".join(f"{x:.9f}\n" for x in t[:5]))
    with pytest.raises(SequenceError, match=r"timestamps.txt: 5 timestamp\(s\) for 7 frame\(s\)"):
        Sequence.open(root)


def test_schema_version_1_loads_and_is_resumed(tmp_path):
    """A folder written before per-frame times (schema 1) loads with i / fps, and writing the same
    sequence into it again resumes it (its sequence.json is brought to the current version)."""
    from floorvo.sequence import SCHEMA_VERSION, SequenceWriter

    meta = {"camera": CAM.to_dict(), "fps": 20.0, "frame_count": 2, "rig": {"height_mm": 100.0}}
    w = SequenceWriter(tmp_path / "s", meta)
    for i in range(2):
        w.write_frame(i, np.zeros((124, 162), np.uint8))
    path = tmp_path / "s" / "sequence.json"
    old = json.loads(path.read_text())
    old["schema_version"] = 1
    path.write_text(json.dumps(old))
    seq = Sequence.open(tmp_path / "s")
    np.testing.assert_allclose(seq.timestamps_s, [0.0, 0.05])
    w2 = SequenceWriter(tmp_path / "s", meta)
    assert w2.resumed and w2.missing_frames() == []
    assert json.loads(path.read_text())["schema_version"] == SCHEMA_VERSION == 2
    old["schema_version"] = 3
    path.write_text(json.dumps(old))
    with pytest.raises(SequenceError, match="schema_version 3 is not supported"):
        Sequence.open(tmp_path / "s")


def test_groundtruth_at_nearest_within_tolerance(tmp_path):
    T = np.stack([T_world_cam_down(float(i), 0.0, 100.0) for i in range(4)])
    meta = {"camera": CAM.to_dict(), "fps": 10.0, "frame_count": 4, "rig": {"height_mm": 100.0}}
    from floorvo.sequence import SequenceWriter

    SequenceWriter(tmp_path / "s", meta).write_groundtruth(np.array([0.0, 0.1, 0.2, 0.3]), T)
    seq = Sequence.open(tmp_path / "s")
    Tq, found = seq.groundtruth_at(np.array([0.104, 0.25, 0.3]))
    assert found.tolist() == [True, False, True]
    np.testing.assert_allclose(Tq[0], T[1])
    np.testing.assert_allclose(Tq[1], np.eye(4))
    np.testing.assert_allclose(Tq[2], T[3])

"""Round trips: ``floorsim export`` (EuRoC, ROS 2 bag) then ``floorvo import`` give back the sequence.

The sequence is a small synthetic one (:mod:`floorvo.synthetic`: stereo, depth, exact ground
truth), not a render. The imported sequence must hold the same frames, camera, rig and ground
truth, and an estimator run over it must give the same trajectory (to 1e-6 m) as over the original.
"""

from __future__ import annotations

import numpy as np
import pytest

from floorsim.export import export_sequence
from floorvo.camera import CameraModel
from floorvo.cli import main
from floorvo.run import run_estimator
from floorvo.sequence import Sequence
from floorvo.synthetic import line_poses, write_synthetic_sequence
from floorvo.tum import read_tum

CAM = CameraModel.from_sensor(162, 124, pixel_pitch_um=29.6, focal_length_mm=6.0)


@pytest.fixture(scope="module")
def original(tmp_path_factory):
    """Synthetic stereo + depth sequence (8 frames, 4 mm steps, turning) and a phase-corr run over it."""
    tmp = tmp_path_factory.mktemp("orig")
    T = line_poses(28.0, 4.0, 100.0, yaw_step_rad=np.radians(0.5))
    root = write_synthetic_sequence(tmp / "seq", CAM, T, depth=True, stereo_baseline_mm=10.0, seed=5)
    run_estimator(root, "phase-corr", tmp / "run")
    return Sequence.open(root), read_tum(tmp / "run" / "trajectory.txt")


@pytest.mark.parametrize("fmt", ["euroc", "rosbag2"])
def test_export_then_import_gives_the_same_sequence_and_trajectory(tmp_path, original, fmt, capsys):
    seq, (t_orig, T_orig) = original
    exported = export_sequence(seq.root, fmt, tmp_path / "exported")
    out = tmp_path / "imported"
    argv = ["import", str(exported), "-o", str(out), "--height-mm", "100"]
    argv += ["--flatfield", str(seq.root / "calib" / "cam0_flatfield.png")]  # exports carry no flat field
    assert main(argv) == 0
    assert f"{fmt}: 8 frames 162x124 8-bit stereo" in capsys.readouterr().out
    imp = Sequence.open(out)
    assert imp.meta["source"]["format"] == fmt and imp.frame_count == seq.frame_count
    np.testing.assert_allclose(imp.camera.K, seq.camera.K)
    np.testing.assert_allclose(imp.camera_model("cam1").K, seq.camera_model("cam1").K)
    np.testing.assert_allclose(imp.T_cam0_cam1, seq.T_cam0_cam1, atol=1e-9)
    np.testing.assert_allclose(imp.timestamps_s, seq.timestamps_s, rtol=0, atol=1e-9)
    for i in range(seq.frame_count):
        np.testing.assert_array_equal(imp.image(i), seq.image(i))
        np.testing.assert_array_equal(imp.image(i, "cam1"), seq.image(i, "cam1"))
    if fmt == "rosbag2":
        assert imp.has_depth
        np.testing.assert_allclose(imp.depth_mm(3), seq.depth_mm(3), atol=1e-4)
    t_gt, T_gt = imp.groundtruth()
    t_ref, T_ref = seq.groundtruth()
    np.testing.assert_allclose(T_gt, T_ref, atol=1e-6)
    np.testing.assert_allclose(t_gt, t_ref, rtol=0, atol=1e-6)
    assert main(["run", str(out), "-e", "phase-corr", "-o", str(tmp_path / "run")]) == 0
    t_run, T_run = read_tum(tmp_path / "run" / "trajectory.txt")
    np.testing.assert_allclose(t_run, t_orig, rtol=0, atol=1e-6)
    np.testing.assert_allclose(T_run[:, :3, 3], T_orig[:, :3, 3], rtol=0, atol=1e-3)  # 1e-6 m, in mm
    np.testing.assert_allclose(T_run[:, :3, :3], T_orig[:, :3, :3], rtol=0, atol=1e-9)


@pytest.mark.parametrize("fmt, k3", [("euroc", 0.0), ("euroc", 0.004), ("rosbag2", 0.004)])
def test_distortion_survives_the_round_trip(tmp_path, fmt, k3):
    """k1, k2, p1, p2 and k3 (EuRoC's fifth coefficient when it is not 0, the bag's plumb_bob
    camera_info) come back as they were written."""
    from floorvo.sequence import SequenceWriter

    cam = CameraModel(40, 30, 50.0, 51.0, 19.5, 14.5, (-0.12, 0.03, 0.001, -0.002, k3))
    w = SequenceWriter(tmp_path / "seq", {"camera": cam.to_dict(), "fps": 10.0, "frame_count": 2})
    for i in range(2):
        w.write_frame(i, np.full((30, 40), 10 * i, np.uint8))
    exported = export_sequence(tmp_path / "seq", fmt, tmp_path / "exported")
    assert main(["import", str(exported), "-o", str(tmp_path / "imported")]) == 0
    got = Sequence.open(tmp_path / "imported").camera
    assert got.distortion == pytest.approx(cam.distortion, abs=1e-12)
    assert (got.fx_px, got.fy_px, got.cx_px, got.cy_px) == (50.0, 51.0, 19.5, 14.5)

"""floorvo.synthetic: exact views, a complete sequence folder, and estimators run over it."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.ndimage import spline_filter

from floorvo.camera import CameraModel
from floorvo.geometry import T_world_cam_down
from floorvo.sequence import Sequence
from floorvo.synthetic import floor_texture, line_poses, render_view, write_synthetic_sequence
from floorvo.tum import read_tum

CAM = CameraModel.from_sensor(162, 124, pixel_pitch_um=29.6, focal_length_mm=6.0)  # GSD 0.4933 mm at 100 mm


def test_view_moves_by_exact_pixels():
    """Moving the camera +x by 5 GSD shifts the content 5 px toward -u; +y (world) moves it toward +v."""
    gsd = 100.0 / CAM.fx_px
    coeffs = spline_filter(floor_texture(400, 400, 0), order=3, output=np.float32)
    a = render_view(coeffs, (200.0, 200.0), gsd, CAM, T_world_cam_down(0.0, 0.0, 100.0))
    b = render_view(coeffs, (200.0, 200.0), gsd, CAM, T_world_cam_down(5 * gsd, 0.0, 100.0))
    np.testing.assert_allclose(b[:, :-5], a[:, 5:], atol=1e-4)
    c = render_view(coeffs, (200.0, 200.0), gsd, CAM, T_world_cam_down(0.0, 3 * gsd, 100.0))
    np.testing.assert_allclose(c[3:, :], a[:-3, :], atol=1e-4)


def test_sequence_folder_complete(tmp_path):
    T = line_poses(8.0, 4.0, 100.0)
    root = write_synthetic_sequence(tmp_path / "s", CAM, T, depth=True, stereo_baseline_mm=10.0)
    seq = Sequence.open(root)
    assert seq.frame_count == 3 and seq.has_depth and seq.has_stereo
    assert seq.image(2).dtype == np.uint8 and seq.image(2, "cam1").shape == (124, 162)
    np.testing.assert_allclose(seq.depth_mm(1), 100.0)
    assert seq.flatfield() is not None and seq.flatfield("cam1") is not None
    np.testing.assert_allclose(seq.T_cam0_cam1[:3, 3], [10.0, 0, 0])
    _, G = seq.groundtruth()
    np.testing.assert_allclose(G[:, :3, 3], T[:, :3, 3], atol=1e-9)
    # The LED falloff: the middle column is darker than the edges.
    img = seq.image(0).astype(float)
    assert img[:, 75:87].mean() < 0.7 * img[:, :12].mean()


@pytest.mark.parametrize(
    "name, tol_pct", [("phase-corr", 0.2), ("akaze-guided", 0.5), ("orb-icp", 1.0), ("stereo-sift", 1.0)]
)
def test_estimators_track_a_synthetic_line(tmp_path, name, tol_pct):
    from floorvo.run import run_estimator

    cam = CameraModel.from_sensor(324, 247, pixel_pitch_um=14.8, focal_length_mm=6.0)
    T = line_poses(40.0, 4.0, 100.0, yaw_step_rad=np.radians(0.2))
    root = write_synthetic_sequence(tmp_path / "s", cam, T, depth=True, stereo_baseline_mm=20.0)
    res = run_estimator(root, name, tmp_path / "run")
    assert res.lost == 0 and res.ok == len(T) - 1
    _, Te = read_tum(tmp_path / "run" / "trajectory.txt")
    err = np.linalg.norm(Te[-1][:3, 3] - T[-1][:3, 3])
    assert 100 * err / 40.0 < tol_pct
    assert json.loads((tmp_path / "run" / "result.json").read_text())["status_counts"]["ok"] == len(T) - 1


def test_lost_frame_leaves_a_gap_in_the_trajectory(tmp_path):
    from floorvo.run import run_estimator
    from floorvo.sequence import SequenceWriter

    T = line_poses(16.0, 4.0, 100.0)
    root = write_synthetic_sequence(tmp_path / "s", CAM, T)
    meta = json.loads((root / "sequence.json").read_text())
    meta.pop("schema_version")
    SequenceWriter(root, meta).write_frame(2, np.zeros((124, 162), np.uint8))  # a black frame
    res = run_estimator(root, "phase-corr", tmp_path / "run")
    assert res.lost == 1 and res.lost_frames[0]["frame"] == 2 and res.lost_frames[0]["reason"]
    ts, Te = read_tum(tmp_path / "run" / "trajectory.txt")
    assert len(ts) == 4 and not np.any(np.isclose(ts, 2 / 30.0))
    # Frame 3 is matched against frame 1 (8 mm): the chain continues and ends near the truth.
    assert np.linalg.norm(Te[-1][:3, 3] - T[-1][:3, 3]) < 0.1


def test_frame_times_that_do_not_increase_are_refused_before_anything_is_written(tmp_path):
    """Repeated times (``timestamps_s``) were refused after the frames and sequence.json were
    written, and the half-made folder was benched as a sequence without ground truth."""
    from floorvo.errors import SequenceError

    cam = CameraModel.from_sensor(162, 124, pixel_pitch_um=29.6, focal_length_mm=6.0)
    poses = np.stack([T_world_cam_down(float(i), 0.0, 100.0) for i in range(3)])
    with pytest.raises(SequenceError, match="timestamps_s: timestamps must increase, frame 2"):
        write_synthetic_sequence(tmp_path / "seq", cam, poses, timestamps_s=[0.0, 0.1, 0.1])
    assert not (tmp_path / "seq").exists()

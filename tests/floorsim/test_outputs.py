"""Depth and stereo outputs against geometry (tiny renders)."""

import numpy as np
import pytest
from _tiny import tiny_scene
from skimage.registration import phase_cross_correlation

from floorsim.simulate import render_sequence
from floorvo.sequence import Sequence

pytestmark = pytest.mark.render


def test_depth_is_camera_to_floor_distance(tmp_path):
    scene = tiny_scene(**{"render.depth": True, "trajectory.distance_mm": 4.0, "camera.height_mm": 90.0})
    seq = Sequence.open(render_sequence(scene, tmp_path / "seq"))
    assert seq.has_depth
    d = seq.depth_mm(1)
    assert d.shape == (124, 162)
    # The floor relief is tens of micrometres: depth = 90 mm within that, quantised to 0.01 mm.
    assert np.all(np.abs(d - 90.0) < 0.1)
    assert 0.002 < float(d.std()) < 0.05


def test_stereo_disparity_is_baseline_times_focal_over_depth(tmp_path):
    scene = tiny_scene(**{"stereo.enabled": True, "stereo.baseline_mm": 10.0, "trajectory.distance_mm": 4.0})
    seq = Sequence.open(render_sequence(scene, tmp_path / "seq"))
    assert seq.has_stereo
    T01 = seq.T_cam0_cam1
    cam = seq.camera
    expect = T01[0, 3] * cam.fx_px / seq.height_mm  # px; the right camera sees the floor shifted to -u
    left = seq.image(0).astype(float) / np.maximum(seq.flatfield("cam0").astype(float), 1)
    right = seq.image(0, "cam1").astype(float) / np.maximum(seq.flatfield("cam1").astype(float), 1)
    sl = (slice(25, 99), slice(40, 122))
    win = np.outer(np.hanning(74), np.hanning(82))
    a, b = left[sl], right[sl]
    shift, _, _ = phase_cross_correlation((a - a.mean()) * win, (b - b.mean()) * win, upsample_factor=50)
    assert shift[1] == pytest.approx(expect, abs=0.15)  # right content displaced by -disparity
    assert shift[0] == pytest.approx(0.0, abs=0.15)


def test_range_sensor_writes_the_true_height_plus_its_seeded_noise(tmp_path):
    """Issue 14 item 4: a simulated range sensor (scene key range_sensor) writes height.csv,
    the ground truth's height (here bouncing) plus Gaussian noise from the scene seed."""
    from floorsim.scene import RangeSensorSpec
    from floorsim.simulate import range_sensor_heights

    scene = tiny_scene(
        **{
            "range_sensor.enabled": True,
            "range_sensor.noise_mm": 0.01,
            "trajectory.distance_mm": 8.0,
            "trajectory.disturbance": {"bounce_amp_mm": 2.0},
        }
    )
    seq = Sequence.open(render_sequence(scene, tmp_path / "seq"))
    gt = seq.groundtruth()[1][:, 2, 3]
    h = seq.height_signal_mm
    assert h is not None and np.ptp(gt) > 1.0
    assert np.all(np.abs(h - gt) < 0.05)
    T = np.tile(np.eye(4), (20000, 1, 1))
    T[:, 2, 3] = 100.0
    a = range_sensor_heights(T, RangeSensorSpec(enabled=True, noise_mm=0.3, dropout=0.25), seed=4)
    b = range_sensor_heights(T, RangeSensorSpec(enabled=True, noise_mm=0.3, dropout=0.25), seed=4)
    np.testing.assert_array_equal(a, b)
    assert np.isnan(a).mean() == pytest.approx(0.25, abs=0.02)
    assert np.nanstd(a) == pytest.approx(0.3, rel=0.05) and np.nanmean(a) == pytest.approx(100.0, abs=0.01)

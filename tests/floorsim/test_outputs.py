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
    the ground truth's height (here bouncing) plus Gaussian noise from the scene seed, and
    states that noise in sequence.json (rig.height_noise_mm)."""
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
    assert seq.height_noise_mm == 0.01  # stated in sequence.json, for the runner to hold the steps to
    T = np.tile(np.eye(4), (20000, 1, 1))
    T[:, 2, 3] = 100.0
    a = range_sensor_heights(T, RangeSensorSpec(enabled=True, noise_mm=0.3, dropout=0.25), seed=4)
    b = range_sensor_heights(T, RangeSensorSpec(enabled=True, noise_mm=0.3, dropout=0.25), seed=4)
    np.testing.assert_array_equal(a, b)
    # the first k frames' readings do not depend on the frame count (render --frames k): the
    # dropout was drawn after every frame's noise, and moved with it
    k = 137
    spec = RangeSensorSpec(enabled=True, noise_mm=0.3, dropout=0.25)
    np.testing.assert_array_equal(range_sensor_heights(T[:k], spec, seed=4), a[:k])
    assert np.isnan(a).mean() == pytest.approx(0.25, abs=0.02)
    assert np.nanstd(a) == pytest.approx(0.3, rel=0.05) and np.nanmean(a) == pytest.approx(100.0, abs=0.01)


def test_attitude_sensor_writes_the_true_roll_and_pitch_plus_its_seeded_noise(tmp_path):
    """Issue 14 (6-DoF where the sensors allow it): a simulated IMU (scene key attitude_sensor)
    writes attitude.csv, the ground truth's roll and pitch (here tilting) plus Gaussian noise
    from the scene seed on a stream of its own; two renders write the same file, bit for bit;
    the key off leaves the scene (and its render cache key) as it was."""
    from floorsim.bench.bench import scene_cache_key
    from floorsim.scene import AttitudeSensorSpec
    from floorsim.simulate import attitude_sensor_angles
    from floorvo.geometry import attitude_of_T

    keys = {"trajectory.distance_mm": 8.0, "trajectory.disturbance": {"tilt_amp_rad": 0.03}}
    scene = tiny_scene(**keys, **{"attitude_sensor.enabled": True, "attitude_sensor.noise_rad": 0.0005})
    a_seq = Sequence.open(render_sequence(scene, tmp_path / "a", spp=2))
    b_seq = Sequence.open(render_sequence(scene, tmp_path / "b", spp=2))
    assert (a_seq.root / "attitude.csv").read_bytes() == (b_seq.root / "attitude.csv").read_bytes()
    truth = attitude_of_T(a_seq.groundtruth()[1])
    att = a_seq.attitude_signal_rad
    assert att is not None and np.ptp(truth) > 0.01
    assert np.all(np.abs(att - truth) < 0.003) and np.any(att != truth)
    plain = tiny_scene(**keys)
    assert "attitude_sensor" not in plain.to_dict() and "attitude_sensor" in scene.to_dict()
    assert scene_cache_key(plain.to_dict(), seed=0, frames=None, scale=None, spp=None) != scene_cache_key(
        scene.to_dict(), seed=0, frames=None, scale=None, spp=None
    )
    T = np.tile(np.eye(4), (20000, 1, 1))
    T[:, :3, :3] = np.diag([1.0, -1.0, -1.0])  # looking straight down
    spec = AttitudeSensorSpec(enabled=True, noise_rad=0.002, dropout=0.25)
    a = attitude_sensor_angles(T, spec, seed=4)
    np.testing.assert_array_equal(a, attitude_sensor_angles(T, spec, seed=4))
    np.testing.assert_array_equal(attitude_sensor_angles(T[:137], spec, seed=4), a[:137])  # as --frames 137
    assert np.isnan(a[:, 0]).mean() == pytest.approx(0.25, abs=0.02)
    assert np.array_equal(np.isnan(a[:, 0]), np.isnan(a[:, 1]))  # a dropout loses both angles
    assert np.nanstd(a[:, 0]) == pytest.approx(0.002, rel=0.05) and abs(np.nanmean(a)) < 1e-4

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

"""Procedural floor materials: world-coordinate reproducibility, seeds, relief scale, registry."""

from dataclasses import dataclass

import numpy as np
import pytest

from floorsim.materials import MATERIALS, get_material, register_material, sample_material
from floorvo.config import Config, param
from floorvo.errors import ConfigError

SPACING = 0.0617


@pytest.mark.parametrize("name", ["vinyl", "concrete"])
def test_same_world_point_same_value_in_any_tile(name):
    """Two overlapping tiles sampled separately agree exactly on their shared grid points,
    also far from the origin (an unbounded floor)."""
    i = np.arange(0, 300)
    for x0 in (0, 3000.0 / SPACING):
        ia = np.round(x0) + i
        ib = np.round(x0) + i + 117  # second tile shifted by 117 grid steps
        ha, aa = sample_material(name, ia * SPACING, np.arange(40, 90) * SPACING, seed=4)
        hb, ab = sample_material(name, ib * SPACING, np.arange(40, 90) * SPACING, seed=4)
        np.testing.assert_array_equal(ha[:, 117:], hb[:, :-117])
        np.testing.assert_array_equal(aa[:, 117:], ab[:, :-117])
    # A tile of a different shape (scattered points) gives the same values too.
    hc, _ = sample_material(name, np.array([5.0, 17.25]), np.array([-3.0]), seed=4)
    hd, _ = sample_material(name, np.arange(0, 20, 0.25), np.array([-3.0, -2.0]), seed=4)
    assert hc[0, 0] == hd[0, 20] and hc[0, 1] == hd[0, 69]


@pytest.mark.parametrize("name", ["vinyl", "concrete"])
def test_relief_is_tens_of_micrometres_and_seeded(name):
    xs = np.arange(0, 600) * SPACING
    ys = np.arange(0, 400) * SPACING
    h, a = sample_material(name, xs, ys, seed=1)
    assert h.shape == a.shape == (400, 600)
    relief_um = (np.percentile(h, 99) - np.percentile(h, 1)) * 1000
    assert 10 < relief_um < 300
    assert 0 <= a.min() and a.max() <= 1 and a.std() > 0.01
    h2, _ = sample_material(name, xs, ys, seed=2)
    assert np.corrcoef(h.ravel(), h2.ravel())[0, 1] < 0.5  # another seed, another floor
    h3, _ = sample_material(name, xs, ys, seed=1, relief_scale=2.0)
    np.testing.assert_allclose(h3, 2 * h, rtol=1e-6)


def test_vinyl_has_scratches_and_veins():
    xs = np.arange(0, 800) * SPACING
    ys = np.arange(0, 800) * SPACING
    h, _ = sample_material("vinyl", xs, ys, seed=3)
    h0, _ = sample_material("vinyl", xs, ys, seed=3, params={"scratch_density": 0.0})
    groove = h0 - h
    assert groove.min() >= -1e-9 and (groove > 0.005).mean() > 0.001  # scratches only cut into the floor
    _, a0 = sample_material(
        "vinyl", xs, ys, seed=3, params={"vein_contrast": 0.0, "stain_contrast": 0.0, "scratch_density": 0.0}
    )
    _, a1 = sample_material("vinyl", xs, ys, seed=3, params={"stain_contrast": 0.0, "scratch_density": 0.0})
    assert np.all(a1 <= a0 + 1e-6) and (a0 - a1).max() > 0.05  # veins darken


def test_material_params_refused_by_name():
    with pytest.raises(ConfigError, match=r"bump_amplitude_mm = -1.0 mm: must be >= 0"):
        sample_material("vinyl", np.zeros(2), np.zeros(2), 0, {"bump_amplitude_mm": -1.0})
    with pytest.raises(ConfigError, match=r"unknown key"):
        sample_material("concrete", np.zeros(2), np.zeros(2), 0, {"vein_contrast": 0.1})
    with pytest.raises(ConfigError, match=r"floor.material = 'lava': unknown material"):
        get_material("lava")


def test_registering_a_new_material():
    @dataclass(frozen=True)
    class StripeParams(Config):
        period_mm: float = param(2.0, unit="mm", gt=0, doc="stripe period")

    @register_material("test_stripes", "test only: albedo stripes along x", StripeParams)
    def _stripes(X, Y, seed, p):
        return 0.0 * X + 0.0 * Y, 0.5 + 0.4 * np.sign(np.sin(2 * np.pi * X / p.period_mm)) + 0.0 * Y

    try:
        assert "test_stripes" in MATERIALS
        h, a = sample_material("test_stripes", np.array([0.5, 1.5]), np.array([0.0, 1.0, 2.0]), 0, {"period_mm": 2.0})
        assert h.shape == (3, 2) and np.all(h == 0)
        np.testing.assert_allclose(a[:, 0], 0.9)
        np.testing.assert_allclose(a[:, 1], 0.1)
    finally:
        MATERIALS.pop("test_stripes", None)


def test_scratch_fast_grid_path_matches_general_path():
    """Per-segment bounding boxes on a grid give the grooves of the all-points computation."""
    from floorsim.materials import _segments_distance

    xs = (np.round(3000.0 / SPACING) + np.arange(0, 400)) * SPACING
    ys = (np.arange(-200, 150)) * SPACING
    for per_cell in (1, 3):
        slow = _segments_distance(xs[None, :], ys[:, None], 5.0, 3, 5, per_cell, (1.0, 4.5), 4.9)
        fast = _segments_distance(xs[None, :], ys[:, None], 5.0, 3, 5, per_cell, (1.0, 4.5), 4.9, max_dist=0.04)
        near = slow < 0.04
        assert near.mean() > 0.002  # the region holds scratches
        np.testing.assert_array_equal(fast[near], slow[near])
        assert np.all(fast[~near] >= 0.04)

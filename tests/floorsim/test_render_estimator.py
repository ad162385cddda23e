"""The LED light estimator of the renderer against hand computation and against itself."""

import numpy as np
import pytest
from _tiny import tiny_scene

from floorsim.render import FloorRenderer, LedArray
from floorsim.simulate import _leds, _load_tile
from floorsim.trajectories import footprint_bounds_mm

pytestmark = pytest.mark.render


@pytest.fixture(scope="module")
def rig():
    scene = tiny_scene()
    T = scene.build_trajectory().T_world_cam[0]
    renderer = FloorRenderer(scene.camera_model())
    return scene, T, renderer


@pytest.mark.parametrize("distortion", [(), (-0.2, 0.05, 0.001, -0.002)])
def test_flat_floor_matches_hand_computed_irradiance(rig, distortion):
    """Over a flat floor L = albedo/pi * sum_k I_k cos_led^m cos_surf / r^2 (no shadows),
    with each pixel's ray from the camera model (lens distortion included)."""
    scene, T, r = rig
    if distortion:
        scene = tiny_scene(**{"camera.distortion": list(distortion)})
        r = FloorRenderer(scene.camera_model())
    cam = r.camera
    leds = _leds(scene, T)
    r.load_flat(*footprint_bounds_mm(T[None], cam, 5.0), albedo=0.5)
    img = r.render(T, leds, 16, seed=1)
    u, v = np.meshgrid(np.arange(cam.width_px, dtype=float), np.arange(cam.height_px, dtype=float))
    d = cam.unproject(np.stack([u.ravel(), v.ravel()], 1), 1.0) @ T[:3, :3].T
    p = T[:3, 3] + (-T[2, 3] / d[:, 2])[:, None] * d  # pixel centre rays on z = 0
    expect = np.zeros(len(p))
    for pos, aim, inten in zip(leds.positions_mm, leds.aim, leds.intensity):
        wl = pos - p
        r2 = (wl**2).sum(1)
        wl /= np.sqrt(r2)[:, None]
        expect += inten * np.maximum(-(wl @ aim), 0) ** leds.lobe_exponent * np.maximum(wl[:, 2], 0) / r2
    expect = (0.5 / np.pi * expect).reshape(img.shape)
    np.testing.assert_allclose(img, expect, rtol=2e-3)


def test_one_shadow_ray_per_bar_is_unbiased(rig):
    """Per-bar shadow sampling converges to the every-LED shadow sum on the bumpy floor."""
    scene, T, r = rig
    _load_tile(r, scene, footprint_bounds_mm(T[None], r.camera, 3.0), scene.floor_spacing_mm())
    leds = _leds(scene, T)
    every = r.render(T, leds, 32, seed=5, every_led=True)
    per_bar = r.render(T, leds, 32, seed=6)
    assert per_bar.mean() == pytest.approx(every.mean(), rel=2e-3)
    rel_rms = np.sqrt(np.mean((per_bar - every) ** 2)) / every.mean()
    assert rel_rms < 0.03
    # Bars are grouped by side; an explicit grouping with one LED per group is the every-LED sum.
    single = LedArray(
        leds.positions_mm, leds.aim, leds.intensity, leds.lobe_exponent, bar=np.arange(len(leds.intensity))
    )
    np.testing.assert_allclose(
        r.render(T, single, 4, seed=6), r.render(T, leds, 4, seed=6, every_led=True), rtol=1e-5, atol=1e-9
    )


def test_relief_casts_real_shadows(rig):
    """One grazing LED: the relief's shadows darken the bumpy floor; a flat floor has none."""
    scene, T, r = rig
    leds = _leds(tiny_scene(**{"lights.side": "left"}), T)
    _load_tile(r, scene, footprint_bounds_mm(T[None], r.camera, 3.0), scene.floor_spacing_mm())
    lit = r.render(T, leds, 4, seed=2, every_led=True)
    unshadowed = r.render(T, leds, 4, seed=2, shadows=False)
    assert np.all(lit <= unshadowed * (1 + 1e-6))
    # Cast shadows (beyond the faces turned away, which n . w already darkens) dim a
    # clear share of the pixels by more than 30 %.
    assert (lit < 0.7 * unshadowed).mean() > 0.03
    r.load_flat(*footprint_bounds_mm(T[None], r.camera, 5.0), albedo=0.5)
    np.testing.assert_array_equal(
        r.render(T, leds, 4, seed=2, every_led=True), r.render(T, leds, 4, seed=2, shadows=False)
    )

"""LEDs with an extent: penumbrae against similar triangles, size 0 = point LEDs, the bar emitter, scene keys."""

from __future__ import annotations

import numpy as np
import pytest
from _tiny import tiny_scene

from floorsim.render import FloorRenderer, LedArray
from floorsim.scene import scene_T_world_leds
from floorvo.errors import ConfigError

RIDGE_X_MM = -10.0  # the ridge's crest (its right-hand edge, 0.1 mm spacing) along the world y axis
RIDGE_H_MM = 1.0
EMITTER_X_MM = -30.0  # 20 mm to the left of the crest
EMITTER_Z_MM = 5.0


def _ridge_renderer(camera) -> FloorRenderer:
    """A flat floor with one straight ridge 1 mm tall at x = RIDGE_X_MM (crest 0.2 mm wide)."""
    s = 0.1
    xs, ys = np.arange(-450, 451) * s, np.arange(-350, 351) * s
    h = np.zeros((len(ys), len(xs)), np.float32)
    h[:, np.abs(xs - (RIDGE_X_MM - 0.1)) <= 0.1 + 1e-6] = RIDGE_H_MM
    r = FloorRenderer(camera)
    r.load_heightfield(xs[0], ys[0], s, h, np.full_like(h, 0.5))
    return r


def _T_down() -> np.ndarray:
    T = np.diag([1.0, -1.0, -1.0, 1.0])
    T[2, 3] = 100.0
    return T


def _emitter(size_mm: tuple[float, float], shape: str = "rectangle") -> LedArray:
    """One emitter left of the ridge, facing +x (its plane vertical: width along y, height along z)."""
    return LedArray(
        np.array([[EMITTER_X_MM, 0.0, EMITTER_Z_MM]]),
        np.array([[1.0, 0.0, 0.0]]),
        np.array([1000.0]),
        size_mm=size_mm,
        shape=shape,
        along=np.array([[0.0, 1.0, 0.0]]),
    )


def _predicted_visibility(x_mm: np.ndarray, size_mm: tuple[float, float], shape: str) -> np.ndarray:
    """Fraction of the emitter's light reaching floor points (x, 0, 0) past the ridge, by similar triangles:
    an emitter point at height z is seen from x when z > h (x - x_e) / (x - x_r); weighted by the light
    f = cos(emission) cos(incidence) / r^2 of each point, integrated on a fine grid over the emitter."""
    w, hgt = size_mm
    n = 201
    gb, gu = np.meshgrid((np.arange(n) + 0.5) / n - 0.5, (np.arange(n) + 0.5) / n - 0.5)
    if shape == "disc":
        keep = np.hypot(gb, gu) <= 0.5
        gb, gu, hgt = gb[keep], gu[keep], w
    ey, ez = gb.ravel() * w, EMITTER_Z_MM + gu.ravel() * hgt
    out = []
    for x in np.atleast_1d(x_mm):
        d = np.stack([EMITTER_X_MM - x + 0 * ey, ey, ez], 1)
        r = np.linalg.norm(d, axis=1)
        f = (-d[:, 0] / r) * (d[:, 2] / r) / r**2  # cos at the emitter (normal +x), cos at the floor (+z)
        f = np.maximum(f, 0)
        seen = ez > RIDGE_H_MM * (x - EMITTER_X_MM) / (x - RIDGE_X_MM)
        out.append(float((f * seen).sum() / f.sum()))
    return np.array(out)


@pytest.mark.render
@pytest.mark.parametrize("size_mm, shape", [((4.0, 2.0), "rectangle"), ((2.5, 2.5), "disc")])
def test_penumbra_of_a_ridge_matches_similar_triangles(size_mm, shape):
    scene = tiny_scene()
    cam = scene.camera_model()
    r = _ridge_renderer(cam)
    T = _T_down()
    leds = _emitter(size_mm, shape)
    lit = r.render(T, leds, 64, seed=1)
    unshadowed = r.render(T, leds, 64, seed=1, shadows=False)
    rows = slice(52, 72)
    vis = (lit[rows] / np.maximum(unshadowed[rows], 1e-12)).mean(axis=0)
    gsd = cam.gsd_mm_per_px(100.0)
    cols = np.arange(cam.width_px)
    x_col = (cols - cam.cx_px) * gsd  # camera x is world x; pixel j covers x_col[j] +- gsd / 2
    behind = (x_col > RIDGE_X_MM + 1.0) & (x_col < 25.0)
    sub = (np.arange(8) + 0.5) / 8 - 0.5  # the pixel's footprint
    pred = np.array([_predicted_visibility(x + sub * gsd, size_mm, shape).mean() for x in x_col[behind]])
    np.testing.assert_allclose(vis[behind], pred, atol=0.06)
    # The penumbra spans from where the top of the emitter is hidden to where its bottom shows:
    # L = h D / (z - h) behind the crest for z = the emitter's top and bottom (D = 20 mm).
    top = EMITTER_Z_MM + (size_mm[1] if shape == "rectangle" else size_mm[0]) / 2
    bottom = 2 * EMITTER_Z_MM - top
    d_mm = RIDGE_X_MM - EMITTER_X_MM
    umbra_end, penumbra_end = RIDGE_H_MM * d_mm / (top - RIDGE_H_MM), RIDGE_H_MM * d_mm / (bottom - RIDGE_H_MM)
    xs = x_col[behind] - RIDGE_X_MM
    assert np.all(vis[behind][xs < umbra_end - gsd] < 0.05)
    assert np.all(vis[behind][xs > penumbra_end + gsd] > 0.95)
    inside = (xs > umbra_end + gsd) & (xs < penumbra_end - gsd)
    assert inside.sum() >= 3 and np.all((vis[behind][inside] > 0.05) & (vis[behind][inside] < 0.95))


@pytest.mark.render
def test_a_point_led_casts_a_sharp_shadow_and_size_zero_is_the_point_led():
    scene = tiny_scene()
    cam = scene.camera_model()
    r = _ridge_renderer(cam)
    T = _T_down()
    point = LedArray(np.array([[EMITTER_X_MM, 0.0, EMITTER_Z_MM]]), np.array([[1.0, 0.0, 0.0]]), np.array([1000.0]))
    img = r.render(T, point, 16, seed=1)
    np.testing.assert_array_equal(r.render(T, _emitter((0.0, 0.0)), 16, seed=1), img)  # bit for bit
    vis = (img / np.maximum(r.render(T, point, 16, seed=1, shadows=False), 1e-12))[52:72].mean(axis=0)
    gsd = cam.gsd_mm_per_px(100.0)
    xs = (np.arange(cam.width_px) - cam.cx_px) * gsd - RIDGE_X_MM
    edge = RIDGE_H_MM * (RIDGE_X_MM - EMITTER_X_MM) / (EMITTER_Z_MM - RIDGE_H_MM)  # 5 mm
    assert np.all(vis[(xs > 1.0) & (xs < edge - gsd)] < 0.02)
    assert np.all(vis[(xs > edge + gsd) & (xs < 25.0)] > 0.98)
    # An emitter's mean light equals the point LED's where it is wholly visible (unbiased; far from the ridge).
    ext = r.render(T, _emitter((3.0, 2.0)), 64, seed=2, shadows=False)
    pt = r.render(T, point, 64, seed=2, shadows=False)
    far = (xs > 20.0) & (xs < 35.0)
    assert ext[52:72][:, far].mean() == pytest.approx(pt[52:72][:, far].mean(), rel=0.02)


def test_bar_emitter_tiles_its_window_and_faces_the_centre():
    s = tiny_scene(**{"lights.emitter": "bar", "lights.count": 4, "lights.bar_length_mm": 40.0})
    p_cam, side = s.led_positions_cam()
    np.testing.assert_allclose(p_cam[side == -1][:, 1], [-15.0, -5.0, 5.0, 15.0])
    assert s.lights.emitter_size_mm() == (10.0, 4.0, "rectangle")
    T = _T_down()
    _, aim = scene_T_world_leds(s, T)
    np.testing.assert_allclose(aim[side == -1], np.repeat(aim[side == -1][:1], 4, axis=0))  # one flat window
    assert tiny_scene(**{"lights.led_size_mm": 2.8, "lights.led_size_z_mm": 3.5}).lights.emitter_size_mm() == (
        2.8,
        3.5,
        "rectangle",
    )
    assert tiny_scene().lights.emitter_size_mm() == (0.0, 0.0, "rectangle")


@pytest.mark.parametrize(
    "over, message",
    [
        ({"lights.emitter": "bar", "lights.bar_window_mm": 15.0}, "lights.height_mm = 3.0 mm: an emitter 15 mm tall"),
        ({"lights.led_size_mm": 8.0}, "lights.height_mm = 3.0 mm: an emitter 8 mm tall"),
        ({"lights.led_shape": "disc", "lights.led_size_mm": 2.0, "lights.led_size_z_mm": 1.0}, "a disc LED has one"),
        ({"lights.emitter": "strip"}, "lights.emitter = 'strip': must be one of"),
        ({"lights.led_size_mm": -1.0}, "lights.led_size_mm = -1.0 mm"),
    ],
)
def test_impossible_emitters_are_refused_in_one_line(over, message):
    with pytest.raises(ConfigError) as info:
        tiny_scene(**over)
    assert message in str(info.value) and "\n" not in str(info.value)

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


def _flat_renderer(camera) -> FloorRenderer:
    """The plane z = 0 under the tiny camera, albedo 0.5 (as a 0.1 mm height grid)."""
    s = 0.1
    xs, ys = np.arange(-450, 451) * s, np.arange(-350, 351) * s
    h = np.zeros((len(ys), len(xs)), np.float32)
    r = FloorRenderer(camera)
    r.load_heightfield(xs[0], ys[0], s, h, np.full_like(h, 0.5))
    return r


def _quadrature(camera, leds: LedArray, n: int = 24) -> np.ndarray:
    """Unshadowed radiance (H, W) of the plane z = 0 at the pixel centres (camera 100 mm above it, looking
    down: image x along world x, image y along -y), by a midpoint rule with n x n points on every
    rectangular emitter: albedo / pi x I x the emitter's mean of max(0, cos emission) max(0, cos incidence) / r^2."""
    gsd = camera.gsd_mm_per_px(100.0)
    x = (np.arange(camera.width_px) - camera.cx_px) * gsd
    y = -(np.arange(camera.height_px) - camera.cy_px) * gsd
    b_axes, u_axes = leds.emitter_axes()
    grid = (np.arange(n) + 0.5) / n - 0.5
    gb, gu = (a.ravel() for a in np.meshgrid(grid, grid))
    out = np.zeros((camera.height_px, camera.width_px))
    w, h = leds.size_mm
    for c, a, b, u, inten in zip(leds.positions_mm, leds.aim, b_axes, u_axes, leds.intensity):
        pts = c + (gb * w)[:, None] * b + (gu * h)[:, None] * u  # (n^2, 3)
        for i, yi in enumerate(y):
            d = pts[None, :, :] - np.stack([x, np.full_like(x, yi), np.zeros_like(x)], 1)[:, None, :]  # p -> y
            r = np.linalg.norm(d, axis=2)
            cos_e = np.maximum(-(d @ a) / r, 0.0)
            cos_i = np.maximum(d[..., 2] / r, 0.0)
            out[i] += inten * 0.5 / np.pi * (cos_e * cos_i / r**2).mean(axis=1)
    return out


def _row(n: int, size_mm: tuple[float, float], z_mm: float, aimed_at_centre: bool) -> LedArray:
    """n emitters in a row along y at x = -40 mm, 10 mm apart (one bar): facing +x, or each aimed at the origin."""
    pos = np.stack([np.full(n, -40.0), 10.0 * (np.arange(n) - (n - 1) / 2), np.full(n, z_mm)], 1)
    aim = -pos if aimed_at_centre else np.tile([1.0, 0.0, 0.0], (n, 1))
    aim = aim / np.linalg.norm(aim, axis=1, keepdims=True)
    return LedArray(pos, aim, np.full(n, 1000.0), size_mm=size_mm, along=np.tile([0.0, 1.0, 0.0], (n, 1)))


@pytest.mark.render
@pytest.mark.parametrize(
    "leds",
    [
        _row(1, (3.0, 3.0), 3.0, False),  # one LED
        _row(3, (3.0, 3.0), 3.0, True),  # a row of LEDs aimed at the centre (each its own axes)
        _row(4, (10.0, 4.0), 3.0, False),  # a bar window in four pieces (shared axes)
    ],
)
def test_extended_leds_unshadowed_light_is_unbiased_and_nearly_exact_per_pixel(leds):
    """The one-sample estimator against a quadrature of the emitters: unbiased over the image, and within
    a few % per pixel at 4 spp (a point drawn uniformly on each emitter gave 7 % for one 3 mm LED)."""
    cam = tiny_scene().camera_model()
    r = _flat_renderer(cam)
    truth = _quadrature(cam, leds)
    rel = r.render(_T_down(), leds, 4, seed=3, shadows=False)[10:-10, 30:-10] / truth[10:-10, 30:-10] - 1.0
    assert abs(rel.mean()) < 0.003
    assert np.sqrt(np.mean(rel**2)) < 0.025


@pytest.mark.render
def test_an_emitter_cut_by_the_receivers_horizon_is_still_unbiased():
    """An emitter whose centre lies 0.5 mm below the floor plane and whose top 1 mm above it: every floor
    point sees only its upper part (the proxy of its light at its centre is below the horizon there and
    must not be 0); the render matches the quadrature of the part above the plane."""
    cam = tiny_scene().camera_model()
    r = _flat_renderer(cam)
    leds = _row(1, (3.0, 3.0), -0.5, False)
    truth = _quadrature(cam, leds, n=48)
    img = r.render(_T_down(), leds, 64, seed=4, shadows=False)
    sl = (slice(10, -10), slice(40, -10))
    assert truth[sl].min() > 0
    assert img[sl].mean() == pytest.approx(truth[sl].mean(), rel=0.01)
    assert np.sqrt(np.mean((img[sl] / truth[sl] - 1.0) ** 2)) < 0.05


@pytest.mark.render
def test_extended_leds_one_pose_per_row_matches_the_global_render():
    """Extended LEDs given per row (the rolling-shutter path, which gathers every LED's values per row)
    render what the same LEDs given once render, up to float rounding."""
    scene = tiny_scene()
    cam = scene.camera_model()
    r = _ridge_renderer(cam)
    T = _T_down()
    leds = _row(3, (3.0, 2.0), 5.0, True)
    h = cam.height_px
    rows = LedArray(
        np.repeat(leds.positions_mm[None], h, 0),
        np.repeat(leds.aim[None], h, 0),
        leds.intensity,
        size_mm=leds.size_mm,
        along=np.repeat(np.asarray(leds.along)[None], h, 0),
    )
    still = r.render(T, leds, 4, seed=5)
    per_row = r.render(np.repeat(T[None], h, 0), rows, 4, seed=5)
    close = np.isclose(per_row, still, rtol=1e-4, atol=1e-6 * still.max())
    assert close.mean() > 0.999  # a sample may pick another LED where two proxies' sums tie to rounding
    assert per_row.mean() == pytest.approx(still.mean(), rel=1e-4)

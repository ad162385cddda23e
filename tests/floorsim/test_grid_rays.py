"""Rays traced against the floor's height grid (no Embree) against Embree on the same mesh."""

from __future__ import annotations

import numpy as np
import pytest
from _tiny import tiny_scene

from floorsim.materials import sample_material
from floorsim.render import FloorRenderer
from floorsim.simulate import _leds
from floorvo.camera import CameraModel

pytestmark = pytest.mark.render

SPACING_MM = 0.0617


def _vinyl_renderer(width_px: int = 96, height_px: int = 72) -> tuple[FloorRenderer, np.ndarray]:
    """A 18 x 15 mm vinyl tile centred on the world origin, and a camera 100 mm above it looking down."""
    full = CameraModel.from_sensor()
    cam = CameraModel(width_px, height_px, full.fx_px, full.fy_px, (width_px - 1) / 2, (height_px - 1) / 2)
    xs = (np.arange(300) - 150) * SPACING_MM
    ys = (np.arange(240) - 120) * SPACING_MM
    height, albedo = sample_material("vinyl", xs, ys, 5)
    r = FloorRenderer(cam)
    r.load_heightfield(xs[0], ys[0], SPACING_MM, height, albedo)
    T = np.diag([1.0, -1.0, -1.0, 1.0])
    T[2, 3] = 100.0
    return r, T


def _rays_from_above(r: FloorRenderer, n: int, max_tilt_rad: float, seed: int):
    """``n`` unit rays from points 100 mm above the tile's inner part, tilted up to ``max_tilt_rad`` off the vertical."""
    mi = r.mi
    rng = np.random.default_rng(seed)
    target = np.stack([rng.uniform(-6, 6, n), rng.uniform(-5, 5, n), np.zeros(n)], 1)
    tilt, azimuth = rng.uniform(0, max_tilt_rad, n), rng.uniform(0, 2 * np.pi, n)
    d = np.stack([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), -np.cos(tilt)], 1)
    o = target - 100.0 * d / np.cos(tilt)[:, None]
    return mi.Ray3f(mi.Point3f(*o.T.astype(np.float32)), mi.Vector3f(*d.T.astype(np.float32)))


def test_primary_hits_on_the_grid_are_embrees_hits():
    """Distance, position, geometric and shading normal and albedo of the first hit, for rays up to 25 deg off
    the vertical (the camera's corners are 22 deg off), agree with Mitsuba's SurfaceInteraction."""
    r, _ = _vinyl_renderer()
    dr = r.dr
    ray = _rays_from_above(r, 20_000, np.radians(25.0), seed=1)
    assert r._grid is not None
    z_range = r._grid.z_max - r._grid.z_min
    cells = int(np.floor(np.tan(np.radians(25.0)) * z_range / SPACING_MM)) + 2
    valid, t, p, n_geo, n_shade, albedo = r._intersect_grid(ray.o, ray.d, cells)
    si = r.scene.ray_intersect(ray)
    albedo_embree = si.shape.eval_attribute_1("vertex_albedo", si, si.is_valid())
    assert np.all(valid.numpy()) and np.all(si.is_valid().numpy())
    assert np.abs(t.numpy() - si.t.numpy()).max() < 1e-4  # mm, along rays 100 mm long
    assert np.abs((p - si.p).numpy()).max() < 1e-4
    # A ray through the edge between two triangles meets both at the same point: either normal is right.
    assert np.mean(dr.dot(n_geo, si.n).numpy() < 0.99999) < 1e-3
    assert np.min(dr.dot(n_shade, si.sh_frame.n).numpy()) > 0.99999
    assert np.abs(albedo.numpy() - albedo_embree.numpy()).max() < 1e-4


def test_rays_through_a_triangle_edge_far_out_on_a_long_tile_hit_the_floor():
    """On a tile of the default 240 mm (3900 cells), a ray's cell coordinates near the far end are
    float32 numbers about 3000, rounded by 2.4e-4 of a cell: rays aimed at the diagonal edge between
    a cell's two triangles all hit, at the point they were aimed at (a fixed slack of 1e-5 of a cell
    let 0.5 % of them through the floor: depth pixels without a hit in full-size frames)."""
    xs = np.arange(3900) * SPACING_MM
    ys = np.arange(80) * SPACING_MM
    height, albedo = sample_material("concrete", xs, ys, 5)
    r = FloorRenderer(CameraModel.from_sensor())
    r.load_heightfield(xs[0], ys[0], SPACING_MM, height, albedo)
    mi = r.mi
    rng = np.random.default_rng(2)
    n = 100_000
    i, j, f = rng.integers(10, 70, n), rng.integers(3000, 3890, n), rng.uniform(0.05, 0.95, n)
    z = height[i, j] + f * (height[i + 1, j + 1] - height[i, j])  # on the diagonal (i, j)-(i+1, j+1)
    target = np.stack([xs[j] + f * SPACING_MM, ys[i] + f * SPACING_MM, z], 1) - r.origin_mm
    tilt, azimuth = rng.uniform(0.05, 0.35, n), rng.uniform(0, 2 * np.pi, n)
    d = np.stack([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), -np.cos(tilt)], 1)
    o = target - 100.0 * d
    ray = mi.Ray3f(mi.Point3f(*o.T.astype(np.float32)), mi.Vector3f(*d.T.astype(np.float32)))
    valid, t = (x.numpy() for x in r._intersect_grid(ray.o, ray.d, 8)[:2])
    assert np.all(valid)
    assert np.abs(t - 100.0).max() < 1e-4  # mm: where it was aimed


def test_shadow_rays_on_the_grid_are_occluded_where_embree_says():
    """Shadow rays from floor points to LEDs 3 mm up and 20-60 mm away (grazing, through the relief):
    the grid walk answers as Embree's ray_test on the same mesh, and the relief does shadow a good part."""
    r, _ = _vinyl_renderer()
    mi = r.mi
    ray = _rays_from_above(r, 20_000, np.radians(20.0), seed=2)
    _, _, p, n_geo, _, _ = r._intersect_grid(ray.o, ray.d, 3)
    rng = np.random.default_rng(3)
    n = 20_000
    azimuth, distance = rng.uniform(0, 2 * np.pi, n), rng.uniform(20.0, 60.0, n)
    p_np = p.numpy().T  # (n, 3)
    led = p_np + np.stack([distance * np.cos(azimuth), distance * np.sin(azimuth), np.full(n, 3.0)], 1)
    shadow = r._shadow_ray(p, n_geo, mi.Point3f(*led.T.astype(np.float32)))
    occluded_grid = r._occluded_grid(shadow, mi.Bool(True)).numpy()
    occluded_embree = r.scene.ray_test(shadow).numpy()
    assert 0.1 < occluded_embree.mean() < 0.9
    assert np.mean(occluded_grid != occluded_embree) <= 1e-3  # float rounding where a ray grazes a triangle's edge


def test_render_on_the_grid_matches_the_embree_render():
    """The whole picture (primary rays, shading, shadow rays) with and without the grid tracing."""
    r, T = _vinyl_renderer()
    leds = _leds(tiny_scene(), T)
    grid = r.render(T, leds, spp=4, seed=1).astype(np.float64)
    r.grid_rays = False
    embree = r.render(T, leds, spp=4, seed=1).astype(np.float64)
    assert np.mean(np.abs(grid - embree)) < 1e-3 * embree.mean()
    # Float rounding: every pixel to about 1e-5; a few more where it flips a shadow ray.
    assert np.mean(np.abs(grid - embree) > 1e-3 * embree.mean()) < 0.01


def test_the_mesh_bvh_is_built_only_when_a_ray_needs_it_and_of_the_tile_loaded_last():
    """A render that the grid answers builds no Mitsuba scene (its BVH is most of a tile's load, about
    15 s on CUDA); the first ray that needs Embree builds it, of the tile loaded last, not of one
    loaded before it; unloading the floor (``scene = None``) leaves nothing to render."""
    r, T = _vinyl_renderer(48, 36)
    leds = _leds(tiny_scene(), T)
    r.render(T, leds, spp=4, seed=1)
    assert r._scene is None
    r.scene.ray_test(r.mi.Ray3f(r.mi.Point3f(0, 0, 50), r.mi.Vector3f(0, 0, -1)))  # builds this tile's BVH
    xs = (np.arange(300) - 150) * SPACING_MM
    ys = (np.arange(240) - 120) * SPACING_MM
    raised = np.full((240, 300), 2.5, np.float32)  # a second, flat tile 2.5 mm up
    r.load_heightfield(xs[0], ys[0], SPACING_MM, raised, np.full_like(raised, 0.5))
    assert r._scene is None
    down = r.mi.Ray3f(r.mi.Point3f(1.0, -2.0, 50.0), r.mi.Vector3f(0.0, 0.0, -1.0))
    assert r.scene.ray_intersect(down).p.z.numpy() == pytest.approx([2.5], abs=1e-5)
    r.scene = None
    with pytest.raises(RuntimeError, match="no floor loaded"):
        r.render(T, leds, spp=4, seed=1)


def test_a_camera_turned_over_a_tall_relief_is_traced_on_the_grid():
    """Over asphalt (relief 0.38 mm) a camera of the rig's field of view turned by 45 degrees needs a
    block of 5 cells (its corner rays run furthest along one axis): traced on the grid, without
    building the tile's BVH, and the picture is Embree's up to float rounding."""
    full = CameraModel.from_sensor()
    k = 96 / full.width_px  # the rig's field of view on a small frame
    cam = CameraModel(96, 73, full.fx_px * k, full.fy_px * k, 47.5, 36.0)
    xs = (np.arange(300) - 150) * SPACING_MM
    ys = (np.arange(240) - 120) * SPACING_MM
    height, albedo = sample_material("asphalt", xs, ys, 5)
    r = FloorRenderer(cam)
    r.load_heightfield(xs[0], ys[0], SPACING_MM, height, albedo)
    c = np.cos(np.radians(45.0))
    T = np.array([[c, c, 0.0, 0.0], [c, -c, 0.0, 0.0], [0.0, 0.0, -1.0, 100.0], [0.0, 0.0, 0.0, 1.0]])
    corners = (
        (np.array([-0.5, 95.5, -0.5, 95.5]) - 47.5) / cam.fx_px,
        (np.array([-0.5, -0.5, 72.5, 72.5]) - 36.0) / cam.fy_px,
    )
    assert r._grid_cells(T[:3, :3], *corners) == 5
    assert r._grid_cells(np.diag([1.0, -1.0, -1.0]), *corners) == 4
    leds = _leds(tiny_scene(), T)
    grid = r.render(T, leds, spp=4, seed=1).astype(np.float64)
    assert r._scene is None  # no BVH was built
    r.grid_rays = False
    embree = r.render(T, leds, spp=4, seed=1).astype(np.float64)
    assert np.mean(np.abs(grid - embree)) < 1e-3 * embree.mean()
    assert np.mean(np.abs(grid - embree) > 1e-3 * embree.mean()) < 0.01


def test_depth_on_the_grid_is_embrees_depth_without_the_bvh():
    """The depth image is traced on the height grid (no BVH built) and equals the depth Embree
    gives on the same mesh to float rounding, for a level camera and for one pose per row."""
    r, T = _vinyl_renderer(48, 36)
    rows = np.repeat(T[None], 36, axis=0)
    rows[:, 0, 3] = np.linspace(0.0, 0.5, 36)  # a rolling shutter's rows along x
    grid = [r.depth(T), r.depth(rows)]
    assert r._scene is None
    r.grid_rays = False
    embree = [r.depth(T), r.depth(rows)]
    for g, e in zip(grid, embree, strict=True):
        assert np.all(np.isfinite(g)) and np.all(np.isfinite(e))
        assert np.abs(g - e).max() < 1e-4  # mm, about 100 mm away
        assert 99.5 < float(np.median(g)) < 100.5


def test_the_cell_bound_of_every_ray_and_a_pose_per_row_costs_no_memory():
    """A distorted frame passes every ray's coordinates and a rolling shutter a pose per row: the
    bound is that of the rays' bounding rectangle, computed from its four corners (the rays times
    the rows had been 14 GiB for a 648x494 frame at 4 spp; 5.0 GiB peak at half size)."""
    import tracemalloc

    r, _ = _vinyl_renderer()
    rng = np.random.default_rng(4)
    x, y = rng.uniform(-0.4, 0.4, 100_000), rng.uniform(-0.3, 0.3, 100_000)
    rows = np.repeat(np.diag([1.0, -1.0, -1.0])[None], 100, axis=0)
    box = np.array([x.min(), x.max(), x.min(), x.max()]), np.array([y.min(), y.min(), y.max(), y.max()])
    tracemalloc.start()
    cells = r._grid_cells(rows, x, y)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert cells == r._grid_cells(rows, *box) == r._grid_cells(rows[0], *box) is not None
    assert peak < 5e6  # bytes; the rays times the rows would be 240 MB


def test_rays_far_off_the_vertical_are_traced_by_embree():
    """A camera tilted 80 degrees sees the floor at grazing angles: the grid's few-cell bound does not hold."""
    r, _ = _vinyl_renderer()
    c, s = np.cos(np.radians(80.0)), np.sin(np.radians(80.0))
    R_world_cam = np.array([[1.0, 0.0, 0.0], [0.0, -c, s], [0.0, -s, -c]])
    corners = np.array([-0.2, 0.2, -0.2, 0.2]), np.array([-0.15, -0.15, 0.15, 0.15])
    assert r._grid_cells(np.diag([1.0, -1.0, -1.0]), *corners) == 2
    assert r._grid_cells(R_world_cam, *corners) is None


def test_an_interrupt_while_the_grid_walk_is_traced_stays_an_interrupt(monkeypatch):
    """Dr.Jit wraps an exception of a while loop's body in a RuntimeError: a Ctrl-C that came while
    the shadow rays' grid walk was traced ended ``floorsim bench`` with a traceback and exit code 1."""
    r, _ = _vinyl_renderer(24, 18)
    ray = _rays_from_above(r, 100, np.radians(20.0), seed=2)

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(r, "_cell_triangles", interrupted)
    with pytest.raises(KeyboardInterrupt):
        r._occluded_grid(ray, r.mi.Bool(True))

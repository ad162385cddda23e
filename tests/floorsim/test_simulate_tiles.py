"""Floor tiling of long trajectories (pure geometry, no rendering)."""

import copy

import pytest
from _tiny import TINY_SCENE

from floorsim.scene import scene_from_dict
from floorsim.simulate import plan_tiles
from floorsim.trajectories import footprint_bounds_mm


def test_three_metre_line_never_holds_a_long_mesh():
    scene = _line_scene()
    traj = scene.build_trajectory()
    cam = scene.camera_model()
    T = traj.T_world_cam
    assert traj.frame_count == 301
    tiles = plan_tiles(T, cam, scene.floor.tile_length_mm, 2.0)
    seen = [i for idx, _ in tiles for i in idx]
    assert seen == list(range(traj.frame_count))  # every frame once, in order
    spacing = scene.floor_spacing_mm()
    for idx, (x0, x1, y0, y1) in tiles:
        assert max(x1 - x0, y1 - y0) <= scene.floor.tile_length_mm
        # every frame's view (plus margin) lies inside its tile
        fx0, fx1, fy0, fy1 = footprint_bounds_mm(T[idx], cam, 2.0)
        assert x0 <= fx0 and fx1 <= x1 and y0 <= fy0 and fy1 <= y1
    n_vertices = max((x1 - x0) * (y1 - y0) for _, (x0, x1, y0, y1) in tiles) / spacing**2
    assert n_vertices < 0.2 * 3000 * 61 / spacing**2  # a small fraction of a 3 m mesh
    assert len(tiles) >= 3000 / scene.floor.tile_length_mm


def _line_scene():
    """The full-size paper-000 rig on paper 001's 3 m line at 0.3 m/s, 30 fps."""
    d = copy.deepcopy(TINY_SCENE)
    d["camera"].update(width_px=648, height_px=494, pixel_pitch_um=7.4)
    d["trajectory"] = {"type": "line", "length_mm": 3000.0, "speed_mm_s": 300.0}
    d["fps"] = 30.0
    return scene_from_dict(d)


def test_single_frame_always_gets_a_tile():
    scene = _line_scene()
    cam = scene.camera_model()
    T = scene.build_trajectory().T_world_cam[:2]
    tiles = plan_tiles(T, cam, 10.0, 2.0)  # tile shorter than one footprint
    assert [idx for idx, _ in tiles] == [[0], [1]]
    assert tiles[0][1] == pytest.approx(footprint_bounds_mm(T[:1], cam, 2.0))

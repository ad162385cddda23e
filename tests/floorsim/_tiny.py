"""Tiny scenes built in code, shared by the floorsim render tests."""

from __future__ import annotations

import copy

from floorsim.scene import apply_overrides, scene_from_dict

#: A quarter-size paper-000 rig (162x124, GSD 0.493 mm) with noise off: tests of geometry and physics.
TINY_SCENE = {
    "schema_version": 1,
    "name": "tiny",
    "seed": 3,
    "fps": 30.0,
    "camera": {"width_px": 162, "height_px": 124, "pixel_pitch_um": 29.6, "focal_length_mm": 6.0, "height_mm": 100.0},
    "floor": {"material": "vinyl"},
    "lights": {"height_mm": 3.0},
    "sensor": {"noise": False},
    "render": {"spp": 4},
    "trajectory": {"type": "uniform", "distance_mm": 4.0, "step_mm": 4.0},
}


def tiny_scene(**overrides):
    """TINY_SCENE with ``{"section.key": value}`` overrides (keys with dots)."""
    d = apply_overrides(copy.deepcopy(TINY_SCENE), {k.replace("__", "."): v for k, v in overrides.items()})
    return scene_from_dict(d)


#: The same rig as a scene file, with sensor noise on, 12 mm in 1 mm steps (13 frames; about 5 s
#: to render here): what the CLI tests give ``floorsim bench``/``render`` to interrupt and run again.
TINY_TOML = """schema_version = 1
name = "tiny"
seed = 3
fps = 30.0

[camera]
width_px = 162
height_px = 124
pixel_pitch_um = 29.6
focal_length_mm = 6.0
height_mm = 100.0

[floor]
material = "vinyl"

[lights]
height_mm = 3.0

[render]
spp = 4

[trajectory]
type = "uniform"
distance_mm = 12.0
step_mm = 1.0
"""

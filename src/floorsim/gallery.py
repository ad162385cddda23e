"""A labelled contact sheet: one frame per floor material and per lighting variant.

``floorsim gallery -o DIR`` renders (small, quick) the first frame of a base scene for
every registered material under the paper rig's lighting, and the vinyl floor under each
lighting and sensor variant, then lays them out as ``DIR/gallery.png`` with a label under each tile,
so a person can judge the realism at a glance. The frames are kept as sequences under
``DIR/frames/`` (re-running reuses them).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from floorsim.materials import MATERIALS
from floorsim.scene import Scene, load_scene
from floorsim.simulate import render_sequence
from floorvo.io import ensure_writable_dir, write_png
from floorvo.sequence import Sequence

__all__ = ["LIGHTING_VARIANTS", "render_gallery"]

#: Lighting variants on the vinyl floor: label -> scene overrides.
LIGHTING_VARIANTS: dict[str, dict[str, str]] = {
    "paper rig: both bars, LEDs 3 mm": {},
    "left bar only": {"lights.side": "left"},
    "LEDs 0.5 mm": {"lights.height_mm": "0.5"},
    "LEDs 30 mm": {"lights.height_mm": "30"},
    "ambient leak 0.3": {"lights.ambient_leak": "0.3"},
    "vignetting + blur 10 ms": {"camera.vignetting": "0.8", "sensor.exposure_ms": "10"},
    "dirt + dust": {"floor.dirt_density": "0.3", "floor.dust_density": "0.2"},
    "LEDs 2.8 x 3.5 mm (SMD 3528)": {"lights.led_size_mm": "2.8", "lights.led_size_z_mm": "3.5"},
    "bar emitter, window 4 mm": {"lights.emitter": '"bar"'},
    "rolling shutter 30 ms": {"sensor.readout_ms": "30"},
    "fixed pattern: PRNU 5 %, hot/dead": {
        "sensor.prnu": "0.05",
        "sensor.dsnu_e": "50",
        "sensor.hot_pixel_fraction": "0.003",
        "sensor.dead_pixel_fraction": "0.003",
    },
    "gamma 2.2": {"sensor.gamma": "2.2"},
}


def _label(tile: np.ndarray, text: str) -> np.ndarray:
    h, w = tile.shape
    band = np.full((22, w), 255, np.uint8)
    cv2.putText(band, text[: max(8, w // 7)], (4, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.42, 0, 1, cv2.LINE_AA)
    return np.vstack([tile, band])


def render_gallery(
    out_dir: str | os.PathLike,
    base: str | os.PathLike = "demo",
    scale: float = 1.0,
    columns: int = 4,
    on_tile: Callable[[int, int], None] | None = None,
) -> Path:
    """Render the gallery into ``out_dir`` and return the path of ``gallery.png``."""
    out = ensure_writable_dir(out_dir)
    jobs: list[tuple[str, dict[str, str]]] = []
    for name in sorted(MATERIALS):
        jobs.append((f"material: {name}", {"floor.material": f'"{name}"', "floor.params": "{}"}))
    for label, over in LIGHTING_VARIANTS.items():
        jobs.append((f"vinyl, {label}", {"floor.material": '"vinyl"', **over}))
    tiles = []
    for k, (label, over) in enumerate(jobs):
        scene: Scene = load_scene(
            base, {**over, "trajectory.type": '"uniform"', "trajectory.distance_mm": "4", "trajectory.step_mm": "4"}
        )
        slug = "".join(c if c.isalnum() else "_" for c in label).strip("_")
        seq = Sequence.open(render_sequence(scene, out / "frames" / slug, frames=1, scale=scale))
        img = seq.image(0)
        if img.dtype != np.uint8:
            img = (img >> 8).astype(np.uint8)
        tiles.append(_label(img, label))
        if on_tile:
            on_tile(k + 1, len(jobs))
    h, w = tiles[0].shape
    rows = -(-len(tiles) // columns)
    sheet = np.full((rows * (h + 6) + 6, columns * (w + 6) + 6), 255, np.uint8)
    for i, t in enumerate(tiles):
        r, c = divmod(i, columns)
        sheet[6 + r * (h + 6) : 6 + r * (h + 6) + h, 6 + c * (w + 6) : 6 + c * (w + 6) + w] = t
    path = out / "gallery.png"
    write_png(path, sheet)
    return path

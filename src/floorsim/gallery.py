"""A labelled contact sheet: one frame per floor material and per lighting variant.

``floorsim gallery -o DIR`` renders (small, quick) the first frame of a base scene for
every registered material under the paper rig's lighting, and the vinyl floor under each
lighting and sensor variant, then lays them out as ``DIR/gallery.png`` with a label under each tile,
so a person can judge the realism at a glance. The frames are kept as sequences under
``DIR/frames/`` (re-running reuses them).

Auto exposure shows only over several frames: its tile is a strip of :data:`AE_FRAMES`
frames of a run whose LEDs flicker, each frame contributing the next vertical slice
(left to right), with the per-frame exposure gain drawn over it as a line (top: highest).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from floorsim.materials import MATERIALS
from floorsim.scene import Scene, load_scene
from floorsim.simulate import EXPOSURE_FILE, read_exposure_log, render_sequence
from floorvo.io import ensure_writable_dir, write_png
from floorvo.locking import locks_folder
from floorvo.sequence import Sequence

__all__ = ["LIGHTING_VARIANTS", "AE_FRAMES", "AE_VARIANT", "render_gallery"]

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


#: Auto exposure (a tile over several frames): label, scene overrides.
AE_VARIANT: tuple[str, dict[str, str]] = (
    "auto exposure",
    {"sensor.exposure_mode": '"auto"', "lights.flicker": "0.3"},
)
#: Frames in the auto-exposure tile.
AE_FRAMES = 8


def _ae_strip(seq: Sequence, frames: int) -> np.ndarray:
    """(H, W) uint8: frame k's columns [k W / n, (k + 1) W / n) side by side, the per-frame gain
    (``calib/exposure.csv``) drawn as a black-on-white line, highest gain at the top quarter."""
    images = [_to_uint8(seq.image(k)) for k in range(frames)]
    h, w = images[0].shape
    edges = np.linspace(0, w, frames + 1).astype(int)
    strip = np.hstack([img[:, a:b] for img, a, b in zip(images, edges[:-1], edges[1:])])
    gains, _ = read_exposure_log(seq.root / EXPOSURE_FILE)
    g = np.log(np.asarray(gains[:frames], dtype=float))
    span = max(float(g.max() - g.min()), 1e-9)
    ys = (h * 0.05 + (g.max() - g) / span * h * 0.2).astype(np.int32)
    xs = ((edges[:-1] + edges[1:]) // 2).astype(np.int32)
    pts = np.stack([xs, ys], 1).reshape(-1, 1, 2)
    cv2.polylines(strip, [pts], False, 255, 3, cv2.LINE_AA)
    cv2.polylines(strip, [pts], False, 0, 1, cv2.LINE_AA)
    return strip


def _to_uint8(img: np.ndarray) -> np.ndarray:
    return img if img.dtype == np.uint8 else (img >> 8).astype(np.uint8)


def _label(tile: np.ndarray, text: str) -> np.ndarray:
    h, w = tile.shape
    band = np.full((22, w), 255, np.uint8)
    cv2.putText(band, text[: max(8, w // 7)], (4, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.42, 0, 1, cv2.LINE_AA)
    return np.vstack([tile, band])


@locks_folder("out_dir", "gallery folder")
def render_gallery(
    out_dir: str | os.PathLike,
    base: str | os.PathLike = "demo",
    scale: float = 1.0,
    columns: int = 4,
    on_tile: Callable[[int, int], None] | None = None,
) -> Path:
    """Render the gallery into ``out_dir`` and return the path of ``gallery.png``.

    ``out_dir`` is locked while the gallery renders (:func:`floorvo.locking.lock_folder`): the
    empty path, a file-system root and a folder another writer holds are refused in one line.
    """
    out = ensure_writable_dir(out_dir)
    jobs: list[tuple[str, dict[str, str]]] = []
    for name in sorted(MATERIALS):
        jobs.append((f"material: {name}", {"floor.material": f'"{name}"', "floor.params": "{}"}))
    for label, over in LIGHTING_VARIANTS.items():
        jobs.append((f"vinyl, {label}", {"floor.material": '"vinyl"', **over}))
    jobs.append((f"vinyl, {AE_VARIANT[0]}, {AE_FRAMES} frames", {"floor.material": '"vinyl"', **AE_VARIANT[1]}))
    tiles = []
    for k, (label, over) in enumerate(jobs):
        frames = AE_FRAMES if k == len(jobs) - 1 else 1
        scene: Scene = load_scene(
            base,
            {
                **over,
                "trajectory.type": '"uniform"',
                # One frame: a 4 mm step (as every sequence has two poses); auto exposure: 1 mm steps.
                "trajectory.distance_mm": "4" if frames == 1 else str(frames - 1),
                "trajectory.step_mm": "4" if frames == 1 else "1",
            },
        )
        slug = "".join(c if c.isalnum() else "_" for c in label).strip("_")
        seq = Sequence.open(render_sequence(scene, out / "frames" / slug, frames=frames, scale=scale))
        img = _ae_strip(seq, frames) if frames > 1 else _to_uint8(seq.image(0))
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

"""A labelled contact sheet: one frame per floor material and per lighting variant.

``floorsim gallery -o DIR`` renders (small, quick) the first frame of a base scene for
every registered material under the base's own lighting, and the vinyl floor under each
lighting and sensor variant, then lays them out as ``DIR/gallery.png`` with a label under each tile,
so a person can judge the realism at a glance. The frames are kept as sequences under
``DIR/frames/`` (re-running reuses them).

Auto exposure shows only over several frames: its tile is a strip of :data:`AE_FRAMES`
frames of a run whose LEDs flicker, each frame contributing the next vertical slice
(left to right), with the per-frame exposure gain drawn over it as a line (top: highest).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from floorsim.materials import MATERIALS
from floorsim.scene import Scene, resolve_scene_path, scene_from_dict
from floorsim.simulate import EXPOSURE_FILE, prepare_scene, read_exposure_log, render_sequence
from floorvo.config import apply_overrides
from floorvo.errors import ConfigError
from floorvo.io import checked_output_path, ensure_writable_dir, read_toml, write_png
from floorvo.locking import locks_folder
from floorvo.sequence import Sequence

__all__ = ["LIGHTING_VARIANTS", "AE_FRAMES", "AE_VARIANT", "gallery_scenes", "render_gallery"]

#: Lighting variants on the vinyl floor: label -> scene overrides. The first is the base scene's own
#: lighting, labelled with its bars and LED height (:func:`_base_label`; the paper rig's for demo).
LIGHTING_VARIANTS: dict[str, dict[str, str]] = {
    "base lighting": {},
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


_FONT = cv2.FONT_HERSHEY_SIMPLEX


def _text_width(text: str, font_scale: float) -> int:
    return int(cv2.getTextSize(text, _FONT, font_scale, 1)[0][0])


def _wrap(text: str, width: int, font_scale: float) -> list[str]:
    """``text`` in lines of at most ``width`` px, broken between words (inside a word longer than a line)."""
    lines: list[str] = []
    cur = ""
    for word in text.split(" "):
        cand = f"{cur} {word}" if cur else word
        if _text_width(cand, font_scale) <= width:
            cur = cand
            continue
        if cur:
            lines.append(cur)
        cur = word
        while len(cur) > 1 and _text_width(cur, font_scale) > width:
            n = max(k for k in range(1, len(cur) + 1) if k == 1 or _text_width(cur[:k], font_scale) <= width)
            lines.append(cur[:n])
            cur = cur[n:]
    if cur:
        lines.append(cur)
    return lines


def _labelled(tiles: list[tuple[np.ndarray, str]]) -> list[np.ndarray]:
    """Each tile with its whole label under it, wrapped onto as many lines as it needs (a smaller
    font on small tiles); every band as tall as the tallest, so the tiles stay one size."""
    w = tiles[0][0].shape[1]
    font_scale = 0.42 if w >= 160 else 0.32
    step = 15 if w >= 160 else 12
    wrapped = [_wrap(label, w - 6, font_scale) for _, label in tiles]
    band_h = 6 + step * max(len(lines) for lines in wrapped)
    out = []
    for (tile, _), lines in zip(tiles, wrapped):
        band = np.full((band_h, w), 255, np.uint8)
        for i, line in enumerate(lines):
            cv2.putText(band, line, (3, step * (i + 1)), _FONT, font_scale, 0, 1, cv2.LINE_AA)
        out.append(np.vstack([tile, band]))
    return out


def _base_label(base: Scene) -> str:
    """The label of the base's own lighting: its lit bars and LED height (the tile said "paper rig:
    both bars, LEDs 3 mm" whatever the base's lights were)."""
    lights = base.lights
    bars = "both bars" if lights.side == "both" else f"{lights.side} bar only"
    return f"base lighting: {bars}, LEDs {lights.height_mm:g} mm"


def _fitted(label: str, over: dict[str, str], base: Scene) -> tuple[str, dict[str, str]]:
    """The variant ``label: over`` with values the base scene cannot take brought within its rules:
    a rolling shutter's readout within the base's frame period, raised LEDs below its camera."""
    if "sensor.readout_ms" in over:
        period_ms = math.floor(10000.0 / base.fps) / 10  # 0.1 ms below or at 1000 / fps
        readout = min(float(over["sensor.readout_ms"]), period_ms)
        label, over = f"rolling shutter {readout:g} ms", {**over, "sensor.readout_ms": f"{readout:g}"}
    if "lights.height_mm" in over and float(over["lights.height_mm"]) >= base.camera.height_mm:
        height = math.floor(base.camera.height_mm * 6) / 10  # 60 % of the camera's height, to 0.1 mm
        label, over = f"LEDs {height:g} mm", {**over, "lights.height_mm": f"{height:g}"}
    return label, over


def gallery_scenes(base: str | os.PathLike = "demo", scale: float = 1.0) -> list[tuple[str, Scene, int]]:
    """The gallery's tiles of ``base``: (label, scene, frames) each, every scene built and validated.

    Each scene is the base with the tile's overrides and the gallery's own trajectory (a uniform
    one, replacing the base's whole ``[trajectory]`` table). Variant values the base cannot take are
    fitted to it (:func:`_fitted`); a tile still invalid is refused in one line naming the base
    file, the tile and the rule.
    """
    path = resolve_scene_path(base)
    raw = read_toml(path, ConfigError)

    def build(label: str, over: dict[str, str], frames: int) -> Scene:
        d = apply_overrides({k: v for k, v in raw.items() if k != "trajectory"}, over)
        # One frame: a 4 mm step (as every sequence has two poses); auto exposure: 1 mm steps.
        step = 4.0 if frames == 1 else 1.0
        d["trajectory"] = {"type": "uniform", "distance_mm": step * max(frames - 1, 1), "step_mm": step}
        try:
            scene = scene_from_dict(d, default_name=path.stem)
            prepare_scene(scene, frames=frames, scale=scale)
        except ConfigError as exc:
            where = f"gallery tile {label!r}: " if over else ""
            raise ConfigError(f"{path.name}: {where}{exc}") from None
        return scene

    plain = build("base", {}, 1)
    jobs: list[tuple[str, dict[str, str], int]] = []
    for name in sorted(MATERIALS):
        jobs.append((f"material: {name}", {"floor.material": f'"{name}"', "floor.params": "{}"}, 1))
    for label, over in LIGHTING_VARIANTS.items():
        label, over = _fitted(label if over else _base_label(plain), over, plain)
        jobs.append((f"vinyl, {label}", {"floor.material": '"vinyl"', **over}, 1))
    ae_label, ae_over = AE_VARIANT
    jobs.append((f"vinyl, {ae_label}, {AE_FRAMES} frames", {"floor.material": '"vinyl"', **ae_over}, AE_FRAMES))
    return [(label, build(label, over, frames), frames) for label, over, frames in jobs]


def render_gallery(
    out_dir: str | os.PathLike,
    base: str | os.PathLike = "demo",
    scale: float = 1.0,
    columns: int = 4,
    on_tile: Callable[[int, int], None] | None = None,
    overwrite: bool = False,
) -> Path:
    """Render the gallery into ``out_dir`` and return the path of ``gallery.png``.

    Every tile's scene is built and validated first (:func:`gallery_scenes`): a base a tile
    cannot use is refused in one line before anything is written. ``out_dir`` is then locked
    while the gallery renders (:func:`floorvo.locking.lock_folder`): the empty path, a
    file-system root and a folder another writer holds are refused in one line. ``overwrite``
    replaces the tiles' sequences rendered with other settings (another scale or base).
    """
    checked_output_path(out_dir)  # "" and "/" before the scenes are read
    jobs = gallery_scenes(base, scale)
    return _render(out_dir, jobs, scale, columns, on_tile, overwrite)


@locks_folder("out_dir", "gallery folder")
def _render(
    out_dir: str | os.PathLike,
    jobs: list[tuple[str, Scene, int]],
    scale: float,
    columns: int,
    on_tile: Callable[[int, int], None] | None,
    overwrite: bool,
) -> Path:
    out = ensure_writable_dir(out_dir)
    tiles = []
    for k, (label, scene, frames) in enumerate(jobs):
        slug = "".join(c if c.isalnum() else "_" for c in label).strip("_")
        root = render_sequence(scene, out / "frames" / slug, frames=frames, scale=scale, overwrite=overwrite)
        seq = Sequence.open(root)
        img = _ae_strip(seq, frames) if frames > 1 else _to_uint8(seq.image(0))
        tiles.append((img, label))
        if on_tile:
            on_tile(k + 1, len(jobs))
    labelled = _labelled(tiles)
    h, w = labelled[0].shape
    rows = -(-len(labelled) // columns)
    sheet = np.full((rows * (h + 6) + 6, columns * (w + 6) + 6), 255, np.uint8)
    for i, t in enumerate(labelled):
        r, c = divmod(i, columns)
        sheet[6 + r * (h + 6) : 6 + r * (h + 6) + h, 6 + c * (w + 6) : 6 + c * (w + 6) + w] = t
    path = out / "gallery.png"
    write_png(path, sheet)
    return path

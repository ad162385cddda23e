"""Procedural, seeded floor materials defined in world coordinates.

A material maps world coordinates (mm) to a height field ``height_mm`` (relief above the
mean floor plane, tens of micrometres) and an ``albedo`` in [0, 1]. Every value is a pure
function of ``(x_mm, y_mm, seed, params)``: noise comes from hashing integer lattice
coordinates, never from a random stream, so any tile of the unbounded floor is
reproducible and the same floor point looks the same from every pose and tile.

Registry: :data:`MATERIALS` (name -> :class:`Material`). A material declares a frozen
parameter dataclass (validated like scene sections) and a ``sample`` function::

    sample(x_mm: (W,) array, y_mm: (H,) array, seed: int, params) -> (height_mm (H, W), albedo (H, W))
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from floorvo.config import Config, build, param
from floorvo.errors import ConfigError, shown

__all__ = [
    "Material",
    "MATERIALS",
    "register_material",
    "get_material",
    "sample_material",
    "value_noise",
    "fbm",
    "hash01",
]

_M1 = np.uint64(0x9E3779B97F4A7C15)
_M2 = np.uint64(0xC2B2AE3D27D4EB4F)
_M3 = np.uint64(0x165667B19E3779F9)
_F1 = np.uint64(0xFF51AFD7ED558CCD)
_F2 = np.uint64(0xC4CEB9FE1A85EC53)


def hash01(ix: np.ndarray, iy: np.ndarray, seed: int, channel: int = 0) -> np.ndarray:
    """Uniform [0, 1) value per integer lattice point (ix, iy), a pure function of its inputs."""
    with np.errstate(over="ignore"):
        s = np.uint64((int(seed) * 0x2545F4914F6CDD1D + int(channel) * 0x632BE59BD9B4E019) & 0xFFFFFFFFFFFFFFFF)
        ix, iy = np.broadcast_arrays(np.asarray(ix, dtype=np.int64), np.asarray(iy, dtype=np.int64))
        h = ix.astype(np.uint64) * _M1
        h ^= iy.astype(np.uint64) * _M2
        h ^= s * _M3 + s
        h ^= h >> np.uint64(33)
        h *= _F1
        h ^= h >> np.uint64(33)
        h *= _F2
        h ^= h >> np.uint64(33)
    return (h >> np.uint64(11)).astype(np.float64) * (1.0 / 9007199254740992.0)


def _lattice(ix: np.ndarray, iy: np.ndarray, seed: int, channel: int):
    """A function (dx, dy) -> hash01(ix + dx, iy + dy), via a table over the lattice range.

    Hashing only the lattice nodes that the points touch (then gathering) is far cheaper
    than hashing every point when the cells are larger than the sample spacing.
    """
    x0, x1 = int(ix.min()), int(ix.max()) + 2
    y0, y1 = int(iy.min()), int(iy.max()) + 2
    n_points = np.broadcast(ix, iy).size
    if (x1 - x0) * (y1 - y0) > 2 * n_points:  # scattered points: hash directly
        return lambda dx, dy: hash01(ix + dx, iy + dy, seed, channel)
    table = hash01(np.arange(x0, x1)[None, :], np.arange(y0, y1)[:, None], seed, channel)
    jx, jy = ix - x0, iy - y0
    return lambda dx, dy: table[jy + dy, jx + dx]


def value_noise(x_mm: np.ndarray, y_mm: np.ndarray, cell_mm: float, seed: int, channel: int = 0) -> np.ndarray:
    """Smooth value noise in [-1, 1] with lattice spacing ``cell_mm``; x, y broadcast together."""
    gx = np.asarray(x_mm, dtype=np.float64) / cell_mm
    gy = np.asarray(y_mm, dtype=np.float64) / cell_mm
    ix, iy = np.floor(gx), np.floor(gy)
    fx, fy = gx - ix, gy - iy
    fx = fx * fx * fx * (fx * (fx * 6 - 15) + 10)  # quintic fade
    fy = fy * fy * fy * (fy * (fy * 6 - 15) + 10)
    lat = _lattice(ix.astype(np.int64), iy.astype(np.int64), seed, channel)
    v00, v10, v01, v11 = lat(0, 0), lat(1, 0), lat(0, 1), lat(1, 1)
    a = v00 + (v10 - v00) * fx
    b = v01 + (v11 - v01) * fx
    return 2.0 * (a + (b - a) * fy) - 1.0


def fbm(x_mm, y_mm, cell_mm: float, seed: int, octaves: int = 4, gain: float = 0.5, channel: int = 0) -> np.ndarray:
    """Fractal sum of value noise, roughly in [-1, 1]; finest cell = cell_mm / 2**(octaves-1)."""
    total: np.ndarray | float = 0.0
    amp, norm = 1.0, 0.0
    cell = cell_mm
    for o in range(octaves):
        total = total + amp * value_noise(x_mm, y_mm, cell, seed, channel * 97 + o)
        norm += amp
        amp *= gain
        cell *= 0.5
    return np.asarray(total / norm)


def _segments_distance(X, Y, cell_mm, seed, channel, per_cell, length_range, max_len, max_dist=np.inf):
    """Distance (mm) from each point to the nearest of a seeded set of line segments.

    Segments are hashed per ``cell_mm`` cell (``per_cell`` candidates, each present with
    probability 0.5) and shorter than ``cell_mm``, so the 3x3 neighbourhood of cells covers
    every segment that can reach a point: the result is tile-independent.

    With a finite ``max_dist``, distances of ``max_dist`` or more may come back as inf;
    on a grid (X (1, W) and Y (H, 1), increasing) each segment then only visits the grid
    points in its own bounding box, which is much faster and gives the same values below
    ``max_dist`` (the same element-wise arithmetic per point and segment).
    """
    X = np.asarray(X, dtype=np.float64)
    Y = np.asarray(Y, dtype=np.float64)
    if (
        np.isfinite(max_dist)
        and X.ndim == 2
        and Y.ndim == 2
        and X.shape[0] == 1
        and Y.shape[1] == 1
        and X.shape[1] > 1
        and Y.shape[0] > 1
        and np.all(np.diff(X[0]) > 0)
        and np.all(np.diff(Y[:, 0]) > 0)
    ):
        return _segments_distance_grid(X[0], Y[:, 0], cell_mm, seed, channel, per_cell, length_range, max_len, max_dist)
    cx0 = np.floor(X / cell_mm).astype(np.int64)
    cy0 = np.floor(Y / cell_mm).astype(np.int64)
    best = np.full(np.broadcast(X, Y).shape, np.inf)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            cx, cy = cx0 + dx, cy0 + dy
            for k in range(per_cell):
                ch = channel * 131 + k * 7
                hv = [_lattice(cx, cy, seed, ch + j)(0, 0) for j in range(5)]
                present = hv[0] < 0.5
                px = (cx + hv[1]) * cell_mm
                py = (cy + hv[2]) * cell_mm
                ang = hv[3] * np.pi
                ln = length_range[0] + (length_range[1] - length_range[0]) * hv[4]
                ln = np.minimum(ln, max_len)
                ux, uy = np.cos(ang), np.sin(ang)
                rx, ry = X - px, Y - py
                tproj = np.clip(rx * ux + ry * uy, -ln / 2, ln / 2)
                d = np.hypot(rx - tproj * ux, ry - tproj * uy)
                best = np.where(present, np.minimum(best, d), best)
    return best


def _segments_distance_grid(x, y, cell_mm, seed, channel, per_cell, length_range, max_len, max_dist):
    """:func:`_segments_distance` on the grid x (W,) by y (H,): per segment, its bounding box only."""
    best = np.full((len(y), len(x)), np.inf)
    cxs = np.arange(int(np.floor(x[0] / cell_mm)) - 1, int(np.floor(x[-1] / cell_mm)) + 2)
    cys = np.arange(int(np.floor(y[0] / cell_mm)) - 1, int(np.floor(y[-1] / cell_mm)) + 2)
    cx, cy = (a.ravel() for a in np.meshgrid(cxs, cys))
    for k in range(per_cell):
        ch = channel * 131 + k * 7
        hv = [hash01(cx, cy, seed, ch + j) for j in range(5)]
        px = (cx + hv[1]) * cell_mm
        py = (cy + hv[2]) * cell_mm
        ang = hv[3] * np.pi
        ln = np.minimum(length_range[0] + (length_range[1] - length_range[0]) * hv[4], max_len)
        ux, uy = np.cos(ang), np.sin(ang)
        for s in np.flatnonzero(hv[0] < 0.5):
            reach = ln[s] / 2 + max_dist
            j0, j1 = np.searchsorted(x, px[s] - reach), np.searchsorted(x, px[s] + reach, side="right")
            i0, i1 = np.searchsorted(y, py[s] - reach), np.searchsorted(y, py[s] + reach, side="right")
            if j0 >= j1 or i0 >= i1:
                continue
            rx = x[None, j0:j1] - px[s]
            ry = y[i0:i1, None] - py[s]
            tproj = np.clip(rx * ux[s] + ry * uy[s], -ln[s] / 2, ln[s] / 2)
            d = np.hypot(rx - tproj * ux[s], ry - tproj * uy[s])
            sub = best[i0:i1, j0:j1]
            np.minimum(sub, d, out=sub)
    return best


def _spots(X, Y, cell_mm, seed, channel, probability, radius_range):
    """(depth-profile in [0, 1], 1 inside a spot) of seeded round spots, one candidate per cell."""
    cx0 = np.floor(X / cell_mm).astype(np.int64)
    cy0 = np.floor(Y / cell_mm).astype(np.int64)
    out = np.zeros(np.broadcast(X, Y).shape)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            cx, cy = cx0 + dx, cy0 + dy
            hv = [_lattice(cx, cy, seed, channel + j)(0, 0) for j in range(4)]
            present = hv[0] < probability
            px = (cx + hv[1]) * cell_mm
            py = (cy + hv[2]) * cell_mm
            r = radius_range[0] + (radius_range[1] - radius_range[0]) * hv[3]
            d = np.hypot(X - px, Y - py) / r
            prof = np.clip(1.0 - d * d, 0.0, 1.0)
            out = np.maximum(out, np.where(present, prof, 0.0))
    return out


@dataclass(frozen=True)
class Material:
    """A registered floor material: ``Params`` (frozen dataclass) and ``sample``.

    ``specular``: (strength, Blinn-Phong exponent) of a glossy coat on top of the diffuse
    albedo, or None for a matte floor.
    """

    name: str
    description: str
    Params: type
    sample: Callable[[np.ndarray, np.ndarray, int, Any], tuple[np.ndarray, np.ndarray]]
    specular: tuple[float, float] | None = None


MATERIALS: dict[str, Material] = {}


def register_material(name: str, description: str, Params: type, specular: tuple[float, float] | None = None):
    """Decorator registering ``sample(x_mm, y_mm, seed, params)`` under ``name``."""

    def deco(fn):
        MATERIALS[name] = Material(name, description, Params, fn, specular)
        return fn

    return deco


def get_material(name: str) -> Material:
    if name not in MATERIALS:
        raise ConfigError(f"floor.material = {shown(name)}: unknown material (known: {', '.join(sorted(MATERIALS))})")
    return MATERIALS[name]


def overlay_dirt(X, Y, seed: int, dirt_density: float, dust_density: float) -> tuple[np.ndarray, np.ndarray]:
    """(height_mm, albedo factor) of dirt and dust lying on any floor.

    Dirt: dark flat specks 0.1-0.6 mm across, ``dirt_density`` = fraction of 1 mm cells
    holding one. Dust: fine bright grains 20-60 um high, ``dust_density`` = fraction of
    0.25 mm cells holding one.
    """
    h = np.zeros(np.broadcast(X, Y).shape)
    f = np.ones_like(h)
    if dirt_density > 0:
        spots = _spots(X, Y, 1.0, seed, 901, dirt_density, (0.05, 0.3))
        f = f * (1.0 - 0.6 * (spots > 0))
        h = h + 0.005 * spots
    if dust_density > 0:
        grains = _spots(X, Y, 0.25, seed, 911, dust_density, (0.02, 0.05))
        f = f * (1.0 + 0.4 * (grains > 0))
        h = h + 0.04 * grains
    return h, f


def sample_material(
    name: str,
    x_mm: np.ndarray,
    y_mm: np.ndarray,
    seed: int,
    params: Mapping[str, Any] | Any | None = None,
    relief_scale: float = 1.0,
    dirt_density: float = 0.0,
    dust_density: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Height (mm) and albedo grids (H, W) of material ``name`` at x (W,) and y (H,), with overlays."""
    mat = get_material(name)
    p = params if isinstance(params, mat.Params) else build(mat.Params, params, f"floor.{name}")
    X = np.asarray(x_mm, dtype=np.float64)[None, :]
    Y = np.asarray(y_mm, dtype=np.float64)[:, None]
    h, a = mat.sample(X, Y, int(seed), p)
    if dirt_density > 0 or dust_density > 0:
        dh, fa = overlay_dirt(X, Y, int(seed), dirt_density, dust_density)
        h, a = h + dh, a * fa
    h = np.broadcast_to(h, (len(y_mm), len(x_mm))) * relief_scale
    a = np.clip(np.broadcast_to(a, (len(y_mm), len(x_mm))), 0.0, 1.0)
    return h.astype(np.float32), a.astype(np.float32)


# ----------------------------------------------------------------------------- vinyl (paper 000)
@dataclass(frozen=True)
class VinylParams(Config):
    """Vinyl tile: micro-bumps, veins, scratches, stains and mottling."""

    base_albedo: float = param(0.55, min=0, max=1, doc="albedo of the vinyl before veins and stains")
    bump_amplitude_mm: float = param(0.03, unit="mm", min=0, max=1.0, doc="height scale of the fractal micro-bumps")
    bump_cell_mm: float = param(0.6, unit="mm", gt=0, doc="size of the largest micro-bumps")
    vein_contrast: float = param(0.25, min=0, max=1, doc="how much darker the veins are (fraction of the albedo)")
    vein_cell_mm: float = param(8.0, unit="mm", gt=0, doc="size of the vein pattern")
    scratch_density: float = param(1.0, min=0, max=4.0, doc="scratches per 5 mm cell")
    scratch_depth_mm: float = param(0.01, unit="mm", min=0, max=1.0, doc="depth of a scratch groove")
    stain_contrast: float = param(0.12, min=0, max=1, doc="albedo drop of the stains (fraction)")


@register_material("vinyl", "vinyl tile of paper 000: micro-bumps, veins, scratches, stains", VinylParams)
def _vinyl(X, Y, seed, p: VinylParams):
    # Micro-bumps: fractal relief from 0.6 mm down to ~0.08 mm.
    h = p.bump_amplitude_mm * fbm(X, Y, p.bump_cell_mm, seed, octaves=4, gain=0.6, channel=1)
    # Veins: ridged, domain-warped low-frequency noise; slightly raised and darker.
    wx = X + 2.0 * value_noise(X, Y, p.vein_cell_mm, seed, 21)
    wy = Y + 2.0 * value_noise(X, Y, p.vein_cell_mm, seed, 22)
    ridge = 1.0 - np.abs(fbm(wx, wy, p.vein_cell_mm, seed, octaves=3, channel=2))
    vein = ridge**12
    h = h + 0.004 * vein
    albedo = p.base_albedo * (1.0 - p.vein_contrast * vein)
    # Mottling and stains: albedo only.
    albedo = albedo * (1.0 + 0.06 * fbm(X, Y, 0.5, seed, octaves=3, channel=3))
    albedo = albedo * (1.0 - p.stain_contrast * np.clip(fbm(X, Y, 12.0, seed, octaves=2, channel=4), 0.0, 1.0))
    # Scratches: thin grooves with V profile, 5 mm cells.
    if p.scratch_density > 0 and p.scratch_depth_mm > 0:
        per_cell = max(1, int(np.ceil(p.scratch_density)))
        width = 0.04
        d = _segments_distance(X, Y, 5.0, seed, 5, per_cell, (1.0, 4.5), 4.9, max_dist=width)
        groove = np.clip(1.0 - d / width, 0.0, 1.0)
        h = h - p.scratch_depth_mm * groove
        albedo = albedo * (1.0 - 0.15 * groove)
    return h, albedo


# ----------------------------------------------------------------------------- concrete
@dataclass(frozen=True)
class ConcreteParams(Config):
    """Concrete: cement matrix, exposed aggregate, pores."""

    base_albedo: float = param(0.45, min=0, max=1, doc="albedo of the cement matrix")
    roughness_mm: float = param(0.02, unit="mm", min=0, max=1.0, doc="height scale of the fine surface roughness")
    aggregate_cell_mm: float = param(1.5, unit="mm", gt=0, doc="size of the exposed aggregate stones")
    aggregate_height_mm: float = param(0.03, unit="mm", min=0, max=1.0, doc="how far the aggregate stands out")
    pore_probability: float = param(0.25, min=0, max=1, doc="fraction of 0.8 mm cells holding a pore")
    pore_depth_mm: float = param(0.05, unit="mm", min=0, max=1.0, doc="depth of a pore")


@register_material("concrete", "concrete: rough cement, exposed aggregate, pores", ConcreteParams)
def _concrete(X, Y, seed, p: ConcreteParams):
    h = p.roughness_mm * fbm(X, Y, 0.8, seed, octaves=4, gain=0.55, channel=11)
    agg_field = value_noise(X, Y, p.aggregate_cell_mm, seed, 12) + 0.3 * value_noise(
        X, Y, p.aggregate_cell_mm / 3, seed, 13
    )
    stone = np.clip((agg_field - 0.35) * 4.0, 0.0, 1.0)
    h = h + p.aggregate_height_mm * stone
    tone = value_noise(X, Y, p.aggregate_cell_mm, seed, 14)
    albedo = p.base_albedo * (1.0 + 0.25 * stone * tone) * (1.0 + 0.08 * fbm(X, Y, 0.4, seed, octaves=3, channel=15))
    pores = _spots(X, Y, 0.8, seed, 16, p.pore_probability, (0.04, 0.15))
    h = h - p.pore_depth_mm * pores
    albedo = albedo * (1.0 - 0.35 * pores)
    return h, albedo


# ----------------------------------------------------------------------------- wood
@dataclass(frozen=True)
class WoodParams(Config):
    """Wood planks: growth-ring grain along x, grain grooves, plank joints, scratches."""

    base_albedo: float = param(0.4, min=0, max=1, doc="albedo of the earlywood")
    grain_period_mm: float = param(1.2, unit="mm", gt=0, doc="spacing of the growth rings across y")
    grain_contrast: float = param(0.3, min=0, max=1, doc="albedo drop of the latewood bands (fraction)")
    groove_depth_mm: float = param(0.012, unit="mm", min=0, max=1.0, doc="depth of the grain grooves")
    plank_width_mm: float = param(90.0, unit="mm", gt=0, doc="plank width (joints along x)")
    scratch_depth_mm: float = param(0.01, unit="mm", min=0, max=1.0, doc="depth of a scratch groove")


@register_material("wood", "wood planks: grain along x, grooves, plank joints, scratches", WoodParams)
def _wood(X, Y, seed, p: WoodParams):
    warp = 3.0 * fbm(X * 0.05, Y, 4.0, seed, octaves=3, channel=31)
    phase = (Y + warp) / p.grain_period_mm
    ring = 0.5 + 0.5 * np.sin(2 * np.pi * phase)
    late = ring**4  # dense latewood bands
    h = -p.groove_depth_mm * late + 0.004 * fbm(X, Y, 0.3, seed, octaves=3, channel=32)
    albedo = (
        p.base_albedo * (1.0 - p.grain_contrast * late) * (1.0 + 0.08 * fbm(X, Y, 6.0, seed, octaves=2, channel=33))
    )
    joint_d = np.abs(((Y / p.plank_width_mm) % 1.0) - 0.5) * p.plank_width_mm  # distance from the plank centre
    joint = np.clip(1.0 - (p.plank_width_mm / 2 - joint_d) / 0.3, 0.0, 1.0)
    h = h - 0.15 * joint
    albedo = albedo * (1.0 - 0.6 * joint)
    if p.scratch_depth_mm > 0:
        d = _segments_distance(X, Y, 6.0, seed, 34, 1, (1.5, 5.5), 5.9, max_dist=0.03)
        groove = np.clip(1.0 - d / 0.03, 0.0, 1.0)
        h = h - p.scratch_depth_mm * groove
    return h, albedo


# ----------------------------------------------------------------------------- asphalt
@dataclass(frozen=True)
class AsphaltParams(Config):
    """Asphalt: dark binder, coarse bright aggregate with high relief."""

    base_albedo: float = param(0.12, min=0, max=1, doc="albedo of the binder")
    stone_albedo: float = param(0.32, min=0, max=1, doc="mean albedo of the aggregate stones")
    stone_cell_mm: float = param(2.5, unit="mm", gt=0, doc="size of the coarse aggregate cells")
    relief_mm: float = param(0.25, unit="mm", min=0, max=3.0, doc="height of the stones above the binder")


@register_material("asphalt", "asphalt: coarse aggregate in dark binder, high relief", AsphaltParams)
def _asphalt(X, Y, seed, p: AsphaltParams):
    stones = _spots(X, Y, p.stone_cell_mm, seed, 41, 0.8, (0.4 * p.stone_cell_mm, 0.75 * p.stone_cell_mm))
    fine = _spots(X, Y, p.stone_cell_mm / 3, seed, 45, 0.6, (0.1, 0.35))
    h = p.relief_mm * (np.sqrt(stones) + 0.4 * np.sqrt(fine)) + 0.02 * fbm(X, Y, 0.5, seed, octaves=3, channel=42)
    tone = 0.5 + 0.5 * value_noise(X, Y, p.stone_cell_mm, seed, 43)
    is_stone = np.maximum(stones > 0, fine > 0)
    albedo = np.where(
        is_stone, p.stone_albedo * (0.7 + 0.6 * tone), p.base_albedo * (1.0 + 0.2 * fbm(X, Y, 0.4, seed, channel=44))
    )
    return h, albedo


# ----------------------------------------------------------------------------- ceramic tile
@dataclass(frozen=True)
class TileParams(Config):
    """Glazed ceramic tiles on a square grid with grout lines: repetitive, a hard case for matching."""

    # bounded: tile_mm + grout_mm (the period) of 1e308 each overflowed to inf and a NaN ended the render
    tile_mm: float = param(30.0, unit="mm", gt=0, max=100_000.0, doc="side of a tile")
    grout_mm: float = param(2.0, unit="mm", gt=0, max=100_000.0, doc="width of a grout line")
    grout_depth_mm: float = param(0.4, unit="mm", min=0, max=3.0, doc="depth of the grout below the glaze")
    tile_albedo: float = param(0.7, min=0, max=1, doc="albedo of the glaze")
    grout_albedo: float = param(0.35, min=0, max=1, doc="albedo of the grout")
    glaze_relief_mm: float = param(0.002, unit="mm", min=0, max=0.1, doc="height scale of the glaze's micro-relief")


@register_material("ceramic_tile", "glazed ceramic tiles with grout lines (repetitive texture)", TileParams)
def _tile(X, Y, seed, p: TileParams):
    period = p.tile_mm + p.grout_mm
    gx = np.abs(((X / period) % 1.0) * period - period / 2)
    gy = np.abs(((Y / period) % 1.0) * period - period / 2)
    edge = np.maximum(gx, gy) - p.tile_mm / 2  # > 0 inside the grout
    grout = np.clip(edge / (p.grout_mm / 2) + 0.5, 0.0, 1.0) * (edge > -0.2)
    h = -p.grout_depth_mm * grout + p.glaze_relief_mm * fbm(X, Y, 0.4, seed, octaves=3, channel=51)
    h = h - 0.02 * grout * (0.5 + 0.5 * value_noise(X, Y, 0.2, seed, 52))  # sandy grout
    albedo = p.tile_albedo * (1.0 + 0.02 * fbm(X, Y, 5.0, seed, channel=53)) * (1 - grout) + p.grout_albedo * grout
    return h, albedo


# ----------------------------------------------------------------------------- polished / wet
@dataclass(frozen=True)
class PolishedParams(Config):
    """Polished or wet floor: smooth micro-relief under a glossy coat (highlights at grazing light)."""

    base_albedo: float = param(0.35, min=0, max=1, doc="mean albedo")
    relief_mm: float = param(0.003, unit="mm", min=0, max=0.1, doc="height scale of the smooth micro-relief")
    mottle: float = param(0.1, min=0, max=1, doc="relative albedo variation")


@register_material(
    "polished", "polished or wet floor: smooth, glossy (specular highlights)", PolishedParams, specular=(0.6, 300.0)
)
def _polished(X, Y, seed, p: PolishedParams):
    h = p.relief_mm * fbm(X, Y, 1.5, seed, octaves=4, channel=61)
    albedo = p.base_albedo * (1.0 + p.mottle * fbm(X, Y, 3.0, seed, octaves=3, channel=62))
    return h, albedo


# ----------------------------------------------------------------------------- featureless
@dataclass(frozen=True)
class FeaturelessParams(Config):
    """A nearly featureless floor (the failure case): uniform albedo, sub-micrometre relief."""

    base_albedo: float = param(0.5, min=0, max=1, doc="the uniform albedo")
    relief_mm: float = param(0.0003, unit="mm", min=0, max=0.01, doc="height scale of the faint relief")


@register_material("featureless", "nearly featureless floor (the failure case)", FeaturelessParams)
def _featureless(X, Y, seed, p: FeaturelessParams):
    h = p.relief_mm * value_noise(X, Y, 2.0, seed, 71)
    return h, np.full(np.broadcast(X, Y).shape, p.base_albedo)

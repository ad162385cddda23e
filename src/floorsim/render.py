"""The Mitsuba 3 backend: the only module that imports mitsuba and drjit.

Physics model
-------------
The floor is a height-field triangle mesh (real geometry, vertex spacing at most half a
ground-sample distance) with a per-vertex albedo, built once per floor tile. The LEDs
are point sources attached to the rig; each has a cosine-power emission lobe aimed at
the floor point under the camera. The hood blocks all other light.

For every pixel we trace ``spp`` stratified primary rays through the pinhole (Mitsuba's
``ldsampler`` for 4^k spp, ``multijitter`` otherwise, which rounds some counts up:
:func:`stratified_spp`; the camera's lens distortion when it has one). The floor is Lambertian, shaded with the normal interpolated from the
vertex normals of the height field (the sampled surface is smooth; flat facets would add
sub-pixel shading noise), and lit by the LEDs only. For LED k at distance r_k::

    f_k = albedo / pi * I_k * max(0, -w_k . a_k)^m * max(0, n . w_k) / r_k^2
    L   = sum_k f_k V_k

(w_k: unit vector from the hit to LED k, a_k: LED aim, m: emission lobe exponent, V_k:
visibility, a shadow ray against the real relief). An LED with an extent (a rectangle or a
disc facing its aim, or a piece of a continuous bar window) spreads I_k evenly over its
area A_k, so its light is the area average (1/A_k) int f_k(y) V_k(y) dA(y). Per bar and
sample one LED is chosen in proportion to a proxy of its light from its centre, one point
y is drawn on it (a rectangle: in proportion to the receiver's cosine factor n . (y - p),
linear over the emitter; a disc: uniformly) and one shadow ray aims at y; the sample adds
f_k(y) V(y) over the probability of that choice (:meth:`FloorRenderer._emitter_light`):
unbiased, nearly exact where a bar is wholly visible, and a penumbra as wide as the
emitter's extent predicts (``every_led=True``: a point on every
emitter, uniformly, and a shadow ray to each). Size 0 is the point-LED renderer bit for
bit: the unshadowed ``f_k`` of every point LED is evaluated exactly at every sample; visibility is estimated with one shadow ray per
LED bar, to an LED picked with probability f_k / F_bar (F_bar = sum of the bar's f_k),
the sample adding F_bar V. This is unbiased, exact wherever a bar is wholly visible or
hidden, and noisy only in penumbrae; ``every_led=True`` traces a shadow ray to every LED
instead. Mitsuba's own ``direct`` integrator (one random light per sample, and images
scaled by ``emitter_samples`` with point lights) is not used.

Rays are cast against the floor's height grid inside the JIT kernel, not through Embree:
nine in ten of a frame's CPU seconds were Embree's descent of the tile's BVH (6 M
triangles), which a grid indexed by position does not need. A primary ray (near the
vertical) crosses the slab of the tile's heights within a few cells, and every triangle
of those cells is tested (:meth:`FloorRenderer._intersect_grid`); a shadow ray walks the
cells along its track, skipping runs of cells that lie below it
(:meth:`FloorRenderer._occluded_grid`). They meet the same triangles as Embree on the same
mesh and give its answers up to float rounding; Embree stays for what the grid does not
cover (a tile that is not a regular grid, rays far from the vertical; depth too only there)
and ``grid_rays = False`` uses it for every ray (for comparisons). The tile's Mitsuba scene,
and with it the BVH, is built the first time such a ray needs it (:attr:`FloorRenderer.scene`).

A rolling-shutter frame is traced with one camera pose (and one set of LED positions) per
image row, gathered per lane from arrays of the H row poses: each row is exactly the row a
global-shutter render from that row's pose gives, in one pass over the image.

The camera pose and the LED parameters enter the JIT kernel as opaque variables, so one
compiled kernel serves every frame; moving the camera and the LEDs touches no shape, so
the BVH is never rebuilt within a tile (DESIGN: a shape transform rebuilds it).

Units: mm; radiance in arbitrary linear units proportional to LED power.
"""

from __future__ import annotations

import glob
import logging
import math
import os
import re
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.ndimage import maximum_filter

from floorvo.camera import CameraModel
from floorvo.errors import FloorbenchError
from floorvo.locking import signals_deferred

__all__ = ["LedArray", "FloorRenderer", "heightfield_vertex_normals", "stratified_spp", "find_libllvm", "backend_info"]

log = logging.getLogger(__name__)

_MI = None  # the mitsuba module, once imported


def find_libllvm(min_major: int = 17) -> str | None:
    """Path of a libLLVM shared library with major version >= ``min_major``, or None."""
    candidates = []
    for pattern in (
        "/usr/lib/x86_64-linux-gnu/libLLVM*.so*",
        "/usr/lib/aarch64-linux-gnu/libLLVM*.so*",
        "/usr/lib/llvm-*/lib/libLLVM*.so*",
        "/usr/lib64/libLLVM*.so*",
        "/usr/local/lib/libLLVM*.so*",
        "/opt/homebrew/opt/llvm/lib/libLLVM*.dylib",
    ):
        candidates += glob.glob(pattern)
    best = None
    for path in candidates:
        m = re.search(r"libLLVM[-.]?(?:so\.)?(\d+)", os.path.basename(path))
        if not m:
            continue
        major = int(m.group(1))
        if major >= min_major and (best is None or major > best[0]):
            best = (major, path)
    return None if best is None else best[1]


def _while_loop(dr, state: tuple, cond, body) -> tuple:
    """``dr.while_loop(state, cond, body)``, with an interrupt raised while Dr.Jit runs ``body`` re-raised as itself.

    Dr.Jit wraps every exception of a loop's Python body in a ``RuntimeError`` ("dr.while_loop():
    encountered an exception (see above)", the original as its ``__cause__``). A Ctrl-C (or the
    CLIs' SIGTERM) that arrived while the body was traced so became a crash: exit code 1 and a
    traceback, not the interrupted command's one line and exit code 130. Exceptions proper stay wrapped.
    """
    try:
        return dr.while_loop(state, cond, body)
    except RuntimeError as exc:
        cause = exc.__cause__
        if isinstance(cause, BaseException) and not isinstance(cause, Exception):
            raise cause from None
        raise


def _has_cuda() -> bool:
    return any(os.path.exists(p) for p in ("/dev/nvidiactl", "/dev/nvidia0"))


def _import_mitsuba(variant: str | None = None):
    """Import mitsuba with a working variant; raise a one-line FloorbenchError if impossible.

    ``variant`` (or ``FLOORSIM_VARIANT``) asks for one: one that cannot be set up is refused in
    one line, a CUDA variant too (a render asked to run on the GPU must not run on the CPU
    unnoticed). Without one, ``cuda_ad_mono`` is chosen when an NVIDIA device node exists,
    falling back to ``llvm_ad_mono`` with a warning if CUDA cannot start; ``llvm_ad_mono``
    otherwise."""
    if _MI is not None:
        return _MI
    asked = variant or os.environ.get("FLOORSIM_VARIANT") or None
    want = asked or ("cuda_ad_mono" if _has_cuda() else "llvm_ad_mono")
    if want.startswith("llvm") and "DRJIT_LIBLLVM_PATH" not in os.environ:
        path = find_libllvm()
        if path is None:
            raise FloorbenchError(
                "Mitsuba's LLVM backend needs libLLVM >= 17: run scripts/setup, or 'apt-get install libllvm19', "
                "or set DRJIT_LIBLLVM_PATH to a libLLVM.so of version 17 or newer"
            )
        os.environ["DRJIT_LIBLLVM_PATH"] = path
    # Ctrl-C or SIGTERM held back until Mitsuba and its variant are loaded (half a second): inside
    # Dr.Jit's import an interrupt became an ordinary exception, sequence.json recorded the backend
    # as 'unavailable', and the process aborted or exited 0.
    with signals_deferred():
        return _load_mitsuba(want, asked)


def _load_mitsuba(want: str, asked: str | None):
    """:func:`_import_mitsuba`'s import and variant (``want``; ``asked``: whether the user named it)."""
    global _MI
    try:
        import mitsuba as mi
    except ImportError as exc:
        raise FloorbenchError(
            f"the renderer needs mitsuba ({exc}); run scripts/setup or 'pip install mitsuba==3.9.1'"
        ) from None
    try:
        mi.set_variant(want)
    except (ImportError, AttributeError, RuntimeError) as exc:
        reason = " ".join(str(exc).split())  # one line
        if not (want.startswith("cuda") and asked is None):
            raise FloorbenchError(f"mitsuba variant {want!r} is not available ({reason})") from None
        # Chosen by itself (an NVIDIA device node exists) and CUDA did not start: the CPU, said.
        path = os.environ.get("DRJIT_LIBLLVM_PATH") or find_libllvm()
        if not path:
            raise FloorbenchError(
                f"mitsuba variant {want!r} is not available ({reason}), and the fallback llvm_ad_mono needs "
                "libLLVM >= 17: run scripts/setup, or 'apt-get install libllvm19', or set DRJIT_LIBLLVM_PATH"
            ) from None
        log.warning("variant %s unavailable (%s); falling back to llvm_ad_mono", want, reason)
        os.environ["DRJIT_LIBLLVM_PATH"] = path
        try:
            mi.set_variant("llvm_ad_mono")
        except (ImportError, AttributeError, RuntimeError) as exc2:
            why = " ".join(str(exc2).split())
            raise FloorbenchError(
                f"mitsuba variant {want!r} is not available ({reason}), nor the fallback llvm_ad_mono ({why})"
            ) from None
    _MI = mi
    return mi


def backend_info() -> dict:
    """Versions and variant of the backend (for sequence.json)."""
    mi = _import_mitsuba()
    import drjit as dr

    return {"mitsuba": mi.__version__, "drjit": dr.__version__, "variant": mi.variant()}  # type: ignore[attr-defined]


@dataclass(frozen=True)
class LedArray:
    """LED point sources in world coordinates for one frame.

    ``positions_mm`` (N, 3), ``aim`` (N, 3) unit emission axes, ``intensity`` (N,)
    radiant intensity on the axis (arbitrary units), ``lobe_exponent`` m of the
    cos^m emission profile, ``bar`` (N,) optional bar index of each LED (LEDs of one bar
    share a shadow ray per sample); by default the side of the camera's x axis.
    For a rolling-shutter render (:meth:`FloorRenderer.render` with one pose per image
    row) ``positions_mm``, ``aim`` and ``along`` may be (H, N, 3): the LEDs where they are
    when row r is exposed.

    Extent: ``size_mm`` = (w, h) > 0 makes each LED an emitting area centred on its
    position and facing its aim: a w x h rectangle (w along ``along`` made perpendicular
    to the aim, h across) or, with ``shape = "disc"``, a disc of diameter w; the
    intensity is spread evenly over it. ``along`` (N, 3): default the horizontal direction
    perpendicular to the aim. (0, 0): point LEDs.
    """

    positions_mm: np.ndarray
    aim: np.ndarray
    intensity: np.ndarray
    lobe_exponent: float = 1.0
    bar: np.ndarray | None = None
    size_mm: tuple[float, float] = (0.0, 0.0)
    shape: str = "rectangle"
    along: np.ndarray | None = None

    def emitter_axes(self) -> tuple[np.ndarray, np.ndarray]:
        """Unit axes (b, u) of each emitter's plane, shaped as ``aim``: b = ``along`` made
        perpendicular to the aim (the width's direction), u = aim x b (the height's)."""
        a = np.asarray(self.aim, dtype=np.float64)
        if self.along is None:
            b = np.cross(np.array([0.0, 0.0, 1.0]), a)
        else:
            b = np.broadcast_to(np.asarray(self.along, dtype=np.float64), a.shape).copy()
        b = b - np.sum(b * a, axis=-1, keepdims=True) * a
        norm = np.linalg.norm(b, axis=-1, keepdims=True)
        if np.any(norm < 1e-9):
            raise ValueError("LedArray: 'along' (or, by default, the horizontal) is parallel to an LED's aim")
        b = b / norm
        return b, np.cross(a, b)


def _is_power_of_four(n: int) -> bool:
    return n >= 4 and (n & (n - 1)) == 0 and (n.bit_length() - 1) % 2 == 0


def stratified_spp(spp: int) -> int:
    """Samples per pixel the renderer takes when asked for ``spp``.

    4, 16, 64, ... (powers of 4) use Mitsuba's ``ldsampler`` and are exact. Every other
    count uses ``multijitter``, a jittered a x b grid with a = floor(sqrt(spp)) and
    b = ceil(spp / a), exact for 1, 2, 3, 6, 8, 9, 12, ... and rounded up otherwise
    (5 -> 6, 7 -> 8, 10 -> 12, 32 -> 35). (``ldsampler`` itself would take 4 for a request
    of 1, so 1 goes to ``multijitter``, which takes 1.)
    """
    spp = int(spp)
    if spp < 1:
        raise ValueError(f"spp = {spp}: must be >= 1")
    if _is_power_of_four(spp):
        return spp
    a = math.isqrt(spp)
    return a * (-(-spp // a))


def heightfield_vertex_normals(
    xs_mm: np.ndarray, ys_mm: np.ndarray, height_mm: np.ndarray, rows_per_block: int = 512
) -> np.ndarray:
    """Unit vertex normals (ny, nx, 3) float32 of the height field z = ``height_mm[i, j]`` at (xs[j], ys[i]).

    ``xs_mm`` (nx,) and ``ys_mm`` (ny,) increasing, ``height_mm`` (ny, nx). The grid is
    triangulated as :meth:`FloorRenderer._set_grid` does: cell (i, j) into
    (i,j)-(i,j+1)-(i+1,j+1) and (i,j)-(i+1,j+1)-(i+1,j). Each vertex gets the sum of the
    unit normals of its triangles weighted by the triangle's angle at the vertex,
    normalised: the weighting of Thuermer and Wuethrich, "Computing Vertex Normals from
    Polygonal Facets" (JGT 1998), which Mitsuba's ``recompute_vertex_normals`` uses; the
    normals agree with Mitsuba's to float32 rounding and point to +z.

    Computed in float64 in a fixed order, ``rows_per_block`` cell rows at a time (bounded
    memory), so they are the same bytes in every run whatever the threads. With
    dx = x[j+1] - x[j], dy = y[i+1] - y[i] and the height differences a = z01 - z00,
    b = z11 - z00, c = z10 - z00 of a cell, the lower triangle's normal is
    (-a dy, dx (a - b), dx dy) and the upper's (dy (c - b), -dx c, dx dy).
    """
    xs = np.asarray(xs_mm, dtype=np.float64)
    ys = np.asarray(ys_mm, dtype=np.float64)
    z = np.asarray(height_mm)
    ny, nx = z.shape
    if xs.shape != (nx,) or ys.shape != (ny,) or nx < 2 or ny < 2:
        raise ValueError(
            f"heightfield_vertex_normals: need xs (nx,), ys (ny,), height (ny, nx) with nx, ny >= 2, "
            f"got {xs.shape}, {ys.shape}, {z.shape}"
        )
    acc = np.zeros((3, ny, nx), dtype=np.float64)  # x, y, z planes
    dx = np.diff(xs)[None, :]  # (1, nx - 1)
    dx2 = dx * dx

    def angle(dot: np.ndarray, len_sq_u: np.ndarray, len_sq_v: np.ndarray) -> np.ndarray:
        return np.arccos(np.clip(dot / np.sqrt(len_sq_u * len_sq_v), -1.0, 1.0))

    def add(out: np.ndarray, rows: slice, cols: slice, n: tuple, weight: np.ndarray) -> None:
        for k in range(3):
            out[k, rows, cols] += n[k] * weight

    top, bottom, left, right = slice(None, -1), slice(1, None), slice(None, -1), slice(1, None)
    for r0 in range(0, ny - 1, rows_per_block):
        r1 = min(ny - 1, r0 + rows_per_block)
        zb = z[r0 : r1 + 1].astype(np.float64)
        dy = np.diff(ys[r0 : r1 + 1])[:, None]  # (rows, 1)
        dy2 = dy * dy
        z00 = zb[top, left]
        a, b, c = zb[top, right] - z00, zb[bottom, right] - z00, zb[bottom, left] - z00
        out = acc[:, r0 : r1 + 1]
        nz = dx * dy
        # Lower triangle v0 = (i, j), v1 = (i, j+1), v2 = (i+1, j+1): edges e01 = (dx, 0, a),
        # e02 = (dx, dy, b), e12 = (0, dy, b - a).
        n = (-a * dy, dx * (a - b), np.broadcast_to(nz, a.shape))
        inv = 1.0 / np.sqrt(n[0] ** 2 + n[1] ** 2 + n[2] ** 2)
        n = (n[0] * inv, n[1] * inv, n[2] * inv)
        l01, l02, l12 = dx2 + a * a, dx2 + dy2 + b * b, dy2 + (b - a) ** 2
        add(out, top, left, n, angle(dx2 + a * b, l01, l02))
        add(out, top, right, n, angle(-a * (b - a), l01, l12))
        add(out, bottom, right, n, angle(dy2 + b * (b - a), l02, l12))
        # Upper triangle v0 = (i, j), v1 = (i+1, j+1), v2 = (i+1, j): edges e01 = (dx, dy, b),
        # e02 = (0, dy, c), e12 = (-dx, 0, c - b).
        n = (dy * (c - b), -dx * c, np.broadcast_to(nz, a.shape))
        inv = 1.0 / np.sqrt(n[0] ** 2 + n[1] ** 2 + n[2] ** 2)
        n = (n[0] * inv, n[1] * inv, n[2] * inv)
        l01, l02, l12 = dx2 + dy2 + b * b, dy2 + c * c, dx2 + (c - b) ** 2
        add(out, top, left, n, angle(dy2 + b * c, l01, l02))
        add(out, bottom, right, n, angle(dx2 - b * (c - b), l01, l12))
        add(out, bottom, left, n, angle(c * (c - b), l02, l12))
    acc /= np.sqrt(acc[0] ** 2 + acc[1] ** 2 + acc[2] ** 2)[None]
    return np.ascontiguousarray(np.moveaxis(acc, 0, -1), dtype=np.float32)


@dataclass(frozen=True)
class _HeightGrid:
    """A floor tile as a regular grid for :meth:`FloorRenderer._intersect_grid` and
    :meth:`FloorRenderer._occluded_grid`: vertex (i, j) at tile-local (x0 + j sx, y0 + i sy, z[i, j])
    mm; ``z``, ``albedo`` (ny nx,) and ``normals`` (3, ny nx) as flat JIT arrays, ``z_min``/``z_max``
    the heights' range (mm). Per cell (i, j), cell index i (nx - 1) + j, packed so that one packet
    gather reads a cell's values: ``corners`` (4 (ny - 1) (nx - 1),) its vertex heights z00, z01,
    z10, z11 (z_rc: row i + r, column j + c); ``skip_max`` (2 (ny - 1) (nx - 1),) for each r in
    :attr:`SKIP_RADII` the highest vertex of the cells within r cells (Chebyshev) of it."""

    #: Radii (cells) of the dilated maxima a shadow ray uses to skip ahead, largest first.
    SKIP_RADII = (8, 2)

    nx: int
    ny: int
    x0: float
    y0: float
    sx: float
    sy: float
    z_min: float
    z_max: float
    z: Any
    albedo: Any
    normals: Any
    corners: Any
    skip_max: Any

    @property
    def edge_slack(self) -> float:
        """How far (in cells) outside a triangle a computed crossing still counts as on it.

        A ray's cell coordinates are float32 numbers up to the grid's size, rounded by a few units
        in their last place (1.2e-4 of a cell at 1600 cells): a ray through a triangle's edge
        could land outside both triangles beside it and go through the floor (3 depth pixels in a
        648x494 frame over a 3862 x 1815 tile had no hit at a fixed 1e-5). Eight such units of
        the largest coordinate, at least 1e-5 of a cell; at the rig's 0.0617 mm cells under
        0.5 um, and a crossing counted that far outside lies on the neighbouring plane within
        its slope times that."""
        return max(1e-5, 8.0 * float(np.finfo(np.float32).eps) * max(self.nx, self.ny))

    @staticmethod
    def of(mi, xs, ys, height_mm, albedo, normals) -> _HeightGrid | None:
        """The grid of a tile whose vertex columns ``xs`` and rows ``ys`` are evenly spaced (to 0.1 % of
        a cell: float32 coordinates round them by up to 1e-4 of a cell); None otherwise."""
        dxs, dys = np.diff(np.asarray(xs, np.float64)), np.diff(np.asarray(ys, np.float64))
        sx, sy = (float(xs[-1]) - float(xs[0])) / len(dxs), (float(ys[-1]) - float(ys[0])) / len(dys)
        if np.abs(dxs - sx).max() > 1e-3 * sx or np.abs(dys - sy).max() > 1e-3 * sy:
            return None
        z = np.asarray(height_mm, np.float32)
        nrm = np.asarray(normals, np.float32).reshape(-1, 3)
        cell_max = np.maximum(np.maximum(z[:-1, :-1], z[:-1, 1:]), np.maximum(z[1:, :-1], z[1:, 1:]))
        return _HeightGrid(
            int(z.shape[1]),
            int(z.shape[0]),
            float(xs[0]),
            float(ys[0]),
            sx,
            sy,
            float(z.min()),
            float(z.max()),
            mi.Float(z.ravel()),
            mi.Float(np.asarray(albedo, np.float32).ravel()),
            [mi.Float(np.ascontiguousarray(nrm[:, k])) for k in range(3)],
            mi.Float(np.stack([z[:-1, :-1], z[:-1, 1:], z[1:, :-1], z[1:, 1:]], -1).ravel()),
            mi.Float(
                np.stack(
                    [maximum_filter(cell_max, size=2 * r + 1, mode="nearest") for r in _HeightGrid.SKIP_RADII], -1
                ).ravel()
            ),
        )


class FloorRenderer:
    """Renders radiance images of a floor tile for a camera model.

    Usage: ``r = FloorRenderer(camera)``; ``r.load_heightfield(x0, y0, spacing, height, albedo)``
    (or ``r.load_flat(...)``); then ``r.render(T_world_cam, leds, spp, seed)`` per frame.
    """

    def __init__(self, camera: CameraModel, variant: str | None = None):
        self.mi = _import_mitsuba(variant)
        import drjit as dr

        self.dr = dr
        self.camera = camera
        self._scene: Any = None  # the loaded tile's mitsuba Scene, once built (see :attr:`scene`)
        #: (xs, ys, height_mm, albedo, normals) of the loaded tile while its Mitsuba scene is not built.
        self._mesh_source: tuple | None = None
        #: World position (mm) of the loaded tile's local origin: the mesh, the camera and the
        #: LEDs are traced in coordinates relative to it (see :meth:`_mesh_scene`).
        self.origin_mm = np.zeros(3)
        self.shadow_offset_mm = 0.0
        #: (k_s, Blinn-Phong exponent) of a glossy coat on the floor, or None (matte).
        self.specular: tuple[float, float] | None = None
        self._samplers: dict = {}
        self.smooth_normals = True
        #: The loaded tile as a regular height grid (rays traced against it without Embree), or None.
        self._grid: _HeightGrid | None = None
        #: Trace rays against :attr:`_grid` where it applies (False: Embree for every ray; for comparisons).
        self.grid_rays = True

    # --------------------------------------------------------------------- geometry
    def load_heightfield(
        self,
        x0_mm: float,
        y0_mm: float,
        spacing_mm: float,
        height_mm: np.ndarray,
        albedo: np.ndarray,
        normals: np.ndarray | None = None,
    ) -> np.ndarray:
        """Build the floor mesh: vertex (i, j) at (x0 + j s, y0 + i s, height[i, j]); returns its normals.

        ``height_mm`` and ``albedo`` are (H, W) grids. Replaces any previous floor.
        ``normals``: (H, W, 3) float32 vertex normals returned by an earlier call with the same
        spacing and heights (:mod:`floorsim.tilecache` keeps them); None computes them
        (:func:`heightfield_vertex_normals`). They depend only on the spacing and the heights,
        not on x0, y0 (the mesh is tile-local).
        """
        height_mm = np.asarray(height_mm, dtype=np.float32)
        albedo = np.asarray(albedo, dtype=np.float32)
        ny, nx = height_mm.shape
        if albedo.shape != height_mm.shape or nx < 2 or ny < 2:
            raise ValueError(
                f"load_heightfield: height {height_mm.shape} and albedo {albedo.shape} must be equal, >= 2x2"
            )
        # Tile-local coordinates about the central vertex (see _mesh_scene): two tiles of one
        # size hold bit-identical vertex x, y whatever their place in the world.
        cx, cy = (nx - 1) // 2, (ny - 1) // 2
        xs = (spacing_mm * (np.arange(nx) - cx)).astype(np.float32)
        ys = (spacing_mm * (np.arange(ny) - cy)).astype(np.float32)
        origin = (float(x0_mm) + spacing_mm * cx, float(y0_mm) + spacing_mm * cy)
        return self._set_grid(xs, ys, height_mm, albedo, origin, normals)

    def load_flat(self, xmin: float, xmax: float, ymin: float, ymax: float, albedo: float) -> None:
        """A perfectly flat floor of uniform ``albedo`` (for the flat-field frame)."""
        origin = (0.5 * (xmin + xmax), 0.5 * (ymin + ymax))
        hx, hy = 0.5 * (xmax - xmin), 0.5 * (ymax - ymin)
        xs = np.array([-hx, hx], dtype=np.float32)
        ys = np.array([-hy, hy], dtype=np.float32)
        self._set_grid(xs, ys, np.zeros((2, 2), np.float32), np.full((2, 2), albedo, np.float32), origin)

    def _set_grid(
        self,
        xs: np.ndarray,
        ys: np.ndarray,
        height_mm: np.ndarray,
        albedo: np.ndarray,
        origin_xy_mm,
        normals: np.ndarray | None = None,
    ) -> np.ndarray:
        """Load the grid of vertices (xs[j], ys[i], height[i, j]) (tile-local mm), the tile's origin at
        world ``origin_xy_mm``: as the height grid that rays are traced against, and as the source
        of its triangle mesh (:attr:`scene`, built on first use).

        ``xs`` (nx,), ``ys`` (ny,), ``height_mm`` and ``albedo`` (ny, nx), all float32.
        ``normals``: precomputed (ny, nx, 3) vertex normals, or None. Returns the normals.
        """
        ny, nx = height_mm.shape
        if normals is not None and np.asarray(normals).shape != (ny, nx, 3):
            raise ValueError(f"_set_grid: normals {np.asarray(normals).shape} must be {(ny, nx, 3)}")
        N = heightfield_vertex_normals(xs, ys, height_mm) if normals is None else np.asarray(normals, np.float32)
        self.scene = None
        self.origin_mm = np.array([origin_xy_mm[0], origin_xy_mm[1], 0.0], dtype=np.float64)
        extent = max(float(np.abs(a).max()) for a in (xs, ys, height_mm))  # the largest |coordinate| of a vertex
        #: Lift of a shadow ray's origin along the geometric normal (mm): constant over the tile.
        self.shadow_offset_mm = 64.0 * float(np.finfo(np.float32).eps) * (1.0 + extent)
        self._mesh_source = (xs, ys, height_mm, albedo, N)
        self._grid = _HeightGrid.of(self.mi, xs, ys, height_mm, albedo, N)
        return N

    @property
    def scene(self) -> Any:
        """The loaded tile's Mitsuba scene (its triangle mesh in Embree's or OptiX's BVH), or None
        when no floor is loaded.

        Built on first use: rays that the height grid answers (:meth:`_grid_cells`; every ray of
        the shipped rigs) never need it, and the BVH is most of a tile's load: 0.7-1.0 s of 1.0-1.7 s
        on LLVM (paper000_uniform, 648x494) and about 15 s on CUDA (an NVIDIA H200; BENCHMARKS.md,
        "On a GPU"). Setting it (None unloads the floor) replaces the tile's scene and grid.
        """
        if self._scene is None and self._mesh_source is not None:
            self._scene = self._mesh_scene(*self._mesh_source)
            self._mesh_source = None
        return self._scene

    @scene.setter
    def scene(self, value: Any) -> None:
        self._scene, self._mesh_source = value, None
        if value is None:
            self._grid = None

    @property
    def has_floor(self) -> bool:
        """Whether a floor is loaded (its Mitsuba scene built or not)."""
        return self._scene is not None or self._mesh_source is not None

    def _mesh_scene(self, xs, ys, height_mm, albedo, N) -> Any:
        """The Mitsuba scene of the grid's triangle mesh: vertex (i, j) at (xs[j], ys[i], height_mm[i, j])
        in tile-local mm, the tile's origin at world :attr:`origin_mm`; ``N`` (ny, nx, 3) float32
        unit vertex normals. Cell (i, j) with a = i nx + j is split along its diagonal into
        (a, a+1, a+1+nx) and (a, a+1+nx, a+nx).

        Why tile-local: a shadow ray must start a little off the surface so that it does not
        hit its own triangle, and Mitsuba's ``spawn_ray_to`` lifts it by
        ``(1 + max|p|) * 8.9e-5`` mm, which grows with the distance from the world origin
        (9 um at 100 mm, 27 um at 300 mm): as large as the relief (bumps of about 30 um), so
        grazing-light micro-shadows faded away from the origin and the same floor patch
        rendered differently at another place (13 % RMS at 200 mm). We lift shadow rays by a
        fixed :attr:`shadow_offset_mm` instead, 64 float32 ulps of the tile's largest
        coordinate, and hold coordinates small and alike in every tile.

        Why the normals come from numpy: Mitsuba's ``recompute_vertex_normals`` (which
        ``params.update()`` calls when only the positions change) adds the face normals into
        the vertices with atomic float adds, in an order that depends on the JIT threads, so
        the normals, and through them the frames and the exposure, changed in the last bits
        from run to run (see :func:`heightfield_vertex_normals`).
        """
        mi = self.mi
        ny, nx = height_mm.shape
        V = np.empty((ny, nx, 3), dtype=np.float32)
        V[..., 0] = xs[None, :]
        V[..., 1] = ys[:, None]
        V[..., 2] = height_mm
        a = (np.arange(ny - 1, dtype=np.uint32)[:, None] * nx + np.arange(nx - 1, dtype=np.uint32)[None, :]).ravel()
        F = np.empty((2 * a.size, 3), dtype=np.uint32)
        F[: a.size, 0], F[: a.size, 1], F[: a.size, 2] = a, a + 1, a + 1 + nx
        F[a.size :, 0], F[a.size :, 1], F[a.size :, 2] = a, a + 1 + nx, a + nx
        mesh = mi.Mesh("floor", nx * ny, len(F), has_vertex_normals=True, has_vertex_texcoords=False)
        params = mi.traverse(mesh)
        params["vertex_positions"] = mi.Float(V.reshape(-1))
        params["vertex_normals"] = mi.Float(np.asarray(N, np.float32).reshape(-1))
        params["faces"] = mi.UInt32(F.reshape(-1))
        params.update()  # "vertex_normals" among the changed keys: Mitsuba keeps ours
        mesh.add_attribute("vertex_albedo", 1, mi.Float(np.asarray(albedo, np.float32).reshape(-1)))
        return mi.load_dict({"type": "scene", "floor": mesh})

    # --------------------------------------------------------------------- rays
    def _sampler(self, spp: int):
        """A cached stratified Mitsuba sampler taking :func:`stratified_spp` (``spp``) samples per pixel:
        ``ldsampler`` for 4, 16, 64, ... spp, ``multijitter`` otherwise."""
        spp = int(spp)
        if spp < 1:
            raise ValueError(f"spp = {spp}: must be >= 1")
        s = self._samplers.get(spp)
        if s is None:
            kind = "ldsampler" if _is_power_of_four(spp) else "multijitter"
            s = self.mi.load_dict({"type": kind, "sample_count": stratified_spp(spp)})
            self._samplers[spp] = s
        return s

    def effective_spp(self, spp: int) -> int:
        """The number of samples per pixel a render with ``spp`` really takes."""
        return int(self._sampler(spp).sample_count())

    def _opaque(self, values) -> list:
        """Scalars as opaque 1-lane JIT variables: changing them between frames reuses the compiled kernel."""
        return [self.dr.opaque(self.mi.Float, float(v)) for v in values]

    def render(
        self,
        T_world_cam: np.ndarray,
        leds: LedArray,
        spp: int = 4,
        seed: int = 0,
        every_led: bool = False,
        shadows: bool = True,
        ambient: float = 0.0,
    ) -> np.ndarray:
        """Radiance image (H, W) float32 of the loaded floor from pose ``T_world_cam`` (mm).

        ``T_world_cam`` (4, 4), or (H, 4, 4) for a rolling shutter: one pose per image row,
        row r traced from pose r and lit by the LEDs of row r (``leds`` then (H, N, 3)
        positions and aims, or (N, 3) LEDs that are the same for every row). Row r of such a
        render equals row r of a render from pose r alone (LEDs with an extent: up to float
        rounding, as a global render sums a row of LEDs incrementally).

        ``spp`` stratified primary samples per pixel (``ldsampler`` when spp is a power of
        4, ``multijitter`` otherwise). Direct light of the LEDs, per primary sample:

        - ``every_led=False`` (default): the unshadowed contribution ``f_k`` of every LED is
          evaluated exactly; one shadow ray per bar goes to an LED chosen with probability
          ``f_k / F_bar`` (stratified across the pixel's samples) and the sample adds
          ``F_bar * V``. Unbiased (E[F_bar V_k*] = sum_k f_k V_k) and exact wherever the
          whole bar is visible or hidden; noise remains only in penumbrae. LEDs with an
          extent (``leds.size_mm``): one LED per bar chosen from a proxy of its light, one
          point on it and one shadow ray (:meth:`_emitter_light`).
        - ``every_led=True``: a shadow ray to every LED (the reference estimator; LEDs with an
          extent: to a point drawn uniformly on each).

        ``shadows=False`` drops the shadow rays (V = 1: shading of the relief only; for
        studies and tests). Deterministic for the same inputs (all samples derive from ``seed``).

        BRDF: Lambertian ``albedo / pi``, plus, when :attr:`specular` = (k_s, e) is set (a
        glossy or wet floor), a normalised Blinn-Phong coat ``k_s (e + 8) / (8 pi) (n.h)^e``.
        ``ambient``: irradiance of light leaking under the hood, uniform over the upper
        hemisphere and unshadowed (adds ``ambient * albedo / pi``).
        """
        if not self.has_floor:
            raise RuntimeError("FloorRenderer.render: no floor loaded")
        mi, dr = self.mi, self.dr
        cam = self.camera
        w, h = cam.width_px, cam.height_px
        sampler = self._sampler(spp)
        spp = sampler.sample_count()  # multijitter rounds up to an a x b grid
        n = w * h * spp
        sampler.set_samples_per_wavefront(spp)
        sampler.seed(int(seed) & 0xFFFFFFFF, n)
        pix = dr.arange(mi.UInt32, n) // spp  # pixel-major: the spp lanes of a pixel are adjacent
        pos = sampler.next_2d()
        u = mi.Float(pix % w) - 0.5 + pos.x
        v = mi.Float(pix // w) - 0.5 + pos.y
        T = np.asarray(T_world_cam, dtype=np.float64)
        per_row = T.ndim == 3
        if per_row and T.shape != (h, 4, 4):
            raise ValueError(f"render: T_world_cam must be (4, 4) or ({h}, 4, 4) (one pose per row), got {T.shape}")
        if cam.has_distortion:
            uv = np.stack([u.numpy(), v.numpy()], axis=1).astype(np.float64)
            d_np = cam.unproject(uv, 1.0)
            x, y = mi.Float(d_np[:, 0].astype(np.float32)), mi.Float(d_np[:, 1].astype(np.float32))
            x_bound, y_bound = d_np[:, 0], d_np[:, 1]
        else:
            x = (u - float(cam.cx_px)) * (1.0 / float(cam.fx_px))
            y = (v - float(cam.cy_px)) * (1.0 / float(cam.fy_px))
            x_bound = (np.array([-0.5, w - 0.5, -0.5, w - 0.5]) - cam.cx_px) / cam.fx_px
            y_bound = (np.array([-0.5, -0.5, h - 0.5, h - 0.5]) - cam.cy_px) / cam.fy_px
        cells = self._grid_cells(T[..., :3, :3], x_bound, y_bound)
        row = pix // w
        if per_row:
            R = self._per_row(T[:, :3, :3].reshape(h, 9), row)
            o = mi.Point3f(*self._per_row(T[:, :3, 3] - self.origin_mm, row))
            T = T[(h - 1) // 2]  # the centre row's pose: which bar an LED is on
        else:
            R = self._opaque(T[:3, :3].ravel())
            o = mi.Point3f(*self._opaque(T[:3, 3] - self.origin_mm))
        d = mi.Vector3f(R[0] * x + R[1] * y + R[2], R[3] * x + R[4] * y + R[5], R[6] * x + R[7] * y + R[8])
        ray = mi.Ray3f(o, dr.normalize(d))
        if cells is None:
            si = self.scene.ray_intersect(ray)
            valid, p_hit, n_geo = si.is_valid(), si.p, si.n
            albedo = si.shape.eval_attribute_1("vertex_albedo", si, valid)
            n_smooth = si.sh_frame.n
        else:
            valid, _, p_hit, n_geo, n_smooth, albedo = self._intersect_grid(ray.o, ray.d, cells)
        # Face normals may point down if the winding flips: orient them towards the camera.
        n_shade = n_smooth if self.smooth_normals else n_geo
        nrm = dr.select(dr.dot(n_shade, -ray.d) < 0, -n_shade, n_shade)
        m = float(leds.lobe_exponent)
        wo = -ray.d
        diffuse = albedo * (1.0 / np.pi)
        spec = self.specular

        led_terms = []  # (bar, position, unshadowed contribution f_k)
        led_pos = np.asarray(leds.positions_mm, dtype=np.float64)
        led_aim = np.asarray(leds.aim, dtype=np.float64)
        rows_of_leds = led_pos.ndim == 3
        if rows_of_leds and (not per_row or led_pos.shape[0] != h or led_aim.shape != led_pos.shape):
            raise ValueError(
                f"render: LEDs of shape {led_pos.shape} need one pose per row and aims alike (got {led_aim.shape})"
            )
        bars = self._bars(
            T,
            leds
            if not rows_of_leds
            else LedArray(led_pos[(h - 1) // 2], led_aim[(h - 1) // 2], leds.intensity, m, leds.bar),
        )
        size_w, size_h = (float(v) for v in leds.size_mm)
        extended = size_w > 0 or size_h > 0
        if extended:
            if leds.shape not in ("rectangle", "disc"):
                raise ValueError(f"render: LED shape {leds.shape!r} is not 'rectangle' or 'disc'")
        if extended and not every_led:
            # One emitter per bar and sample, importance-sampled (see _emitter_light).
            L = self._emitter_light(sampler, leds, bars, p_hit, n_geo, nrm, wo, diffuse, valid, row, shadows)
        else:
            if extended:
                axis_b, axis_u = leds.emitter_axes()
                if leds.shape == "disc":
                    size_h = size_w
                # One stratified 2-D sample per sample for all emitters, rotated per LED (Cranley-Patterson, by
                # multiples of the plastic-number constants): each LED's point stays uniform on it and stratified
                # across the pixel's samples, for one sampler draw instead of one per LED (16 draws cost 20 %).
                emitter_sample = sampler.next_2d()
            for k, inten in enumerate(leds.intensity):
                if inten <= 0:
                    continue
                if rows_of_leds:
                    px, py, pz, ax, ay, az = self._per_row(
                        np.concatenate([led_pos[:, k] - self.origin_mm, led_aim[:, k]], axis=1), row
                    )
                    (ik,) = self._opaque([inten])
                else:
                    px, py, pz, ax, ay, az, ik = self._opaque([*(led_pos[k] - self.origin_mm), *led_aim[k], inten])
                lp = mi.Point3f(px, py, pz)
                if extended:
                    # A point drawn uniformly on the emitter (stratified over the pixel's samples): f at that point
                    # is an unbiased estimate of the emitter's light (intensity spread evenly over its area), and
                    # the shadow ray below goes to the same point.
                    if rows_of_leds:
                        bx, by, bz, ux, uy, uz = self._per_row(
                            np.concatenate([axis_b[:, k], axis_u[:, k]], axis=1), row
                        )
                    else:
                        bx, by, bz, ux, uy, uz = self._opaque([*axis_b[k], *axis_u[k]])
                    shift = ((k * 0.7548776662466927) % 1.0, (k * 0.5698402909980532) % 1.0)
                    sq = emitter_sample + mi.Point2f(*shift)
                    sq = sq - dr.floor(sq)
                    if leds.shape == "disc":
                        disk = mi.warp.square_to_uniform_disk_concentric(sq)
                        s_b, s_u = disk.x * (0.5 * size_w), disk.y * (0.5 * size_w)
                    else:
                        s_b, s_u = (sq.x - 0.5) * size_w, (sq.y - 0.5) * size_h
                    lp = mi.Point3f(px + s_b * bx + s_u * ux, py + s_b * by + s_u * uy, pz + s_b * bz + s_u * uz)
                dl = lp - p_hit
                r2 = dr.squared_norm(dl)
                wl = dl * dr.rsqrt(r2)
                cos_surf = dr.maximum(dr.dot(nrm, wl), 0.0)
                cos_led = dr.maximum(-(wl.x * ax + wl.y * ay + wl.z * az), 0.0)  # emission profile cos^m
                lobe = cos_led if m == 1.0 else dr.power(cos_led, m)
                brdf = diffuse
                if spec is not None:
                    ks, e = float(spec[0]), float(spec[1])
                    hv = dr.normalize(wl + wo)
                    brdf = brdf + ks * (e + 8.0) / (8.0 * np.pi) * dr.power(dr.maximum(dr.dot(nrm, hv), 0.0), e)
                f = dr.select(valid, ik * lobe * cos_surf / r2 * brdf, 0.0)
                led_terms.append((int(bars[k]), lp, f))

            L = mi.Float(0.0)
            if not shadows:
                for _, _, f in led_terms:
                    L += f
            elif every_led:
                for _, lp, f in led_terms:
                    occluded = self._occluded(self._shadow_ray(p_hit, n_geo, lp), f > 0)
                    L += dr.select(occluded, 0.0, f)
            else:
                for bar in sorted({b for b, _, _ in led_terms}):
                    terms = [(lp, f) for b, lp, f in led_terms if b == bar]
                    F = mi.Float(0.0)
                    for _, f in terms:
                        F += f
                    target = sampler.next_1d() * F
                    acc = mi.Float(0.0)
                    chosen = mi.Point3f(terms[-1][0])
                    found = mi.Bool(False)
                    for lp, f in terms:
                        acc += f
                        pick = ~found & (acc > target)
                        chosen = dr.select(pick, lp, chosen)
                        found |= pick
                    occluded = self._occluded(self._shadow_ray(p_hit, n_geo, chosen), F > 0)
                    L += dr.select(occluded, 0.0, F)
        if ambient > 0:
            L += dr.select(valid, float(ambient) * diffuse, 0.0)
        # Evaluated mode: a reduction kernel with a fixed order. Dr.Jit's default switches to atomic
        # scatter-adds (order varies from run to run) when L would take over 1 GiB (about 1000 spp at full size).
        img = dr.block_sum(L, spp, mode="evaluated") * (1.0 / spp)
        # With every light off (power 0, no ambient) L is a literal: Dr.Jit holds it as one value.
        return np.broadcast_to(np.asarray(img.numpy(), dtype=np.float32).ravel(), (h * w,)).reshape(h, w).copy()

    @staticmethod
    def _linear_warp(dr, c, xi):
        """Sample t in [-1/2, 1/2] with density 1 + c t (|c| <= 2) from a uniform ``xi`` in [0, 1): the
        root of CDF(t) = t + 1/2 + c (t^2 - 1/4) / 2 = xi, written t = -2 q / (1 + sqrt(1 - 2 c q)) with
        q = 1/2 - c/8 - xi (stable as c -> 0, where it is xi - 1/2). Monotone in ``xi``, so stratified
        inputs stay stratified."""
        q = 0.5 - 0.125 * c - xi
        disc = dr.maximum(dr.square(1.0 - 0.5 * c) + 2.0 * c * xi, 0.0)
        return dr.clip(-2.0 * q / (1.0 + dr.sqrt(disc)), -0.5, 0.5)

    def _emitter_light(self, sampler, leds: LedArray, bars, p_hit, n_geo, nrm, wo, diffuse, valid, row, shadows: bool):
        """Light of LEDs with an extent at each sample: one point on one emitter per bar, one shadow ray.

        For LED k with centre c_k, aim a_k, in-plane unit axes b_k, u_k (:meth:`LedArray.emitter_axes`),
        size w x h and area A_k, the light at the hit p with shading normal n is the area average
        (1/A_k) int f_k(y) V(y) dA(y) of the point-LED formula at y, which reads, since (y - c_k) . a_k = 0::

            f_k(y) = I_k (a_k . (p - c_k))^m  max(0, n . (y - p)) brdf / |y - p|^(m + 3)

        Per bar and sample, a one-sample estimator: E[f_k(y) V(y) / (P_k pdf_k(y))] = sum_k (1/A_k)
        int f_k V dA, unbiased as long as P_k pdf_k(y) > 0 wherever f_k(y) > 0 (pdf_k per unit of the
        uniform density on the emitter):

        1. A proxy of each LED's light from its centre, g_k = I_k max(0, a_k . (p - c_k))^m h(x_k) /
           |c_k - p|^(m + 3), x_k = n . (c_k - p), with h(x) = x for x >= R, (x + R)^2 / (4 R) for
           |x| < R and 0 below -R (the mean of max(0, x + R s) over s uniform in [-1, 1]), R the
           emitter's half diagonal (a disc's radius) >= |y - c_k|. g_k > 0 wherever a point of the
           emitter can lie above the receiver's horizon (x_k + n . (y - c_k) > 0 needs x_k > -R) and
           in front of the emitter (a plane: all of it is in front of p or none is): wherever f_k can
           be > 0 (the brdf is left out: > 0 anyway). Where x_k >= R, g_k is f_k(c_k) / brdf.
           Collinear, evenly spaced centres (a row of LEDs, the pieces of a bar window) get x_k,
           |c_k - p|^2 and a_k . (p - c_k) from the first LED's by a multiply-add or two each.
        2. LED k of the bar chosen with P_k = g_k / G, G = sum of the bar's g_k (one 1-D sample per
           bar, stratified over the pixel's samples, as for point LEDs).
        3. A point y on LED k. A rectangle: the linear density pdf_k(y) = 1 + n . (y - c_k) / x' with
           x' = max(x_k, rho_k), rho_k = w/2 |n . b_k| + h/2 |n . u_k| the largest n . (y - c_k) on
           it: >= 0 on the emitter, mean 1 over it, and proportional to f_k's factor n . (y - p)
           wherever the whole emitter is above the horizon, so that f_k / pdf_k hardly varies over
           the emitter; drawn as the marginal along u_k, then b_k given u_k (:meth:`_linear_warp`),
           from one 2-D sample per sample rotated per bar. A disc: uniform (pdf 1; a linear density
           on a disc has no closed-form inverse).
        4. The sample adds f_k(y) V(y) / (P_k pdf_k(y)) = G f_k(y) V(y) / (g_k pdf_k(y)), V from one
           shadow ray to y (``shadows=False``: V = 1).

        Where a bar is wholly visible the sample is G f_k(y) / (g_k pdf_k(y)), which varies over a
        rectangle only through |y - p|^-(m + 3) (about 1 % RMS per pixel at 4 spp for one 3 mm LED
        50 mm away; uniform points: 7 %): the unshadowed term needs no estimate of its own. Per
        sample: the proxies (as cheap as the point-LED formula), then per bar one point, one f and
        one shadow ray, instead of a point and an f on every emitter.
        """
        mi, dr = self.mi, self.dr
        m = float(leds.lobe_exponent)
        size_w, size_h = (float(v) for v in leds.size_mm)
        disc = leds.shape == "disc"
        if disc:
            size_h = size_w
        half_w, half_h = 0.5 * size_w, 0.5 * size_h
        reach_max = math.hypot(half_w, half_h) if not disc else half_w  # R >= |y - c| on the emitter
        led_pos = np.asarray(leds.positions_mm, dtype=np.float64)
        led_aim = np.asarray(leds.aim, dtype=np.float64)
        rows_of_leds = led_pos.ndim == 3
        axis_b, axis_u = leds.emitter_axes()
        spec = self.specular
        emitter_sample = sampler.next_2d()  # one 2-D sample per sample for the bars' points

        def inv_r_pow(r2):  # |d|^-(m + 3) from |d|^2
            return dr.rcp(dr.square(r2)) if m == 1.0 else dr.power(r2, -0.5 * (m + 3.0))

        lit = [k for k, inten in enumerate(leds.intensity) if inten > 0]
        intensity = np.asarray(leds.intensity, dtype=np.float64)

        def proxy(x, lob_raw, r2, ik):  # (q_k, g_k) from x_k, a_k . (p - c_k), |c_k - p|^2, I_k
            lob = dr.maximum(lob_raw, 0.0)
            q = ik * (lob if m == 1.0 else dr.power(lob, m))
            hx = dr.select(
                x >= reach_max, x, dr.select(x > -reach_max, dr.square(x + reach_max) * (0.25 / reach_max), 0.0)
            )
            return q, q * hx * inv_r_pow(r2)

        picks = []
        for bar in sorted({int(bars[k]) for k in lit}):
            ks = [k for k in lit if int(bars[k]) == bar]

            def shared(values: np.ndarray, ks=ks) -> bool:  # the bar's LEDs share these values (in every row)
                return all(np.array_equal(values[..., ks[0], :], values[..., j, :]) for j in ks)

            same_axes = shared(axis_b) and shared(axis_u)  # one flat window: b, u need no choosing

            def axes_of(k: int) -> tuple:  # (b, u) of LED k as JIT values
                if rows_of_leds:
                    ax = self._per_row(np.concatenate([axis_b[:, k], axis_u[:, k]], axis=1), row)
                else:
                    ax = self._opaque(np.concatenate([axis_b[k], axis_u[k]]))
                return mi.Vector3f(*ax[0:3]), mi.Vector3f(*ax[3:6])

            # Collinear, evenly spaced centres c_j = c_0 + j delta (a row of LEDs, the pieces of a bar window):
            # then x_j, |c_j - p|^2 and a_j . (p - c_j) follow from c_0's by a multiply-add or two per LED.
            row_of = not rows_of_leds and len(ks) > 1
            if row_of:
                delta = led_pos[ks[1]] - led_pos[ks[0]]
                spread = led_pos[ks] - led_pos[ks[0]] - np.arange(len(ks))[:, None] * delta
                row_of = float(np.abs(spread).max()) <= 1e-6
            values = []  # per LED: (chosen-values tuple, g)
            if row_of:
                c0 = mi.Point3f(*self._opaque(led_pos[ks[0]] - self.origin_mm))
                dvec = mi.Vector3f(*self._opaque(delta))
                (dd,) = self._opaque([delta @ delta])
                dc0 = c0 - p_hit
                x0, nd = dr.dot(nrm, dc0), dr.dot(nrm, dvec)
                r0, two_dd = dr.squared_norm(dc0), 2.0 * dr.dot(dc0, dvec)
                same_aim = shared(led_aim)
                if same_aim:
                    a0 = mi.Vector3f(*self._opaque(led_aim[ks[0]]))
                    lob0 = -dr.dot(a0, dc0)
                for j, k in enumerate(ks):
                    ik, a_delta = self._opaque([intensity[k], led_aim[k] @ delta])
                    if same_aim:
                        lob_raw = lob0 - j * a_delta
                    else:
                        a = mi.Vector3f(*self._opaque(led_aim[k]))
                        lob_raw = -dr.dot(a, dc0) - j * a_delta
                    q, g = proxy(x0 + j * nd, lob_raw, r0 + (j * two_dd + (j * j) * dd), ik)
                    values.append(((mi.Float(j), q) + (() if same_axes else axes_of(k)), g))
            else:
                for k in ks:
                    per_led = [led_pos[..., k, :] - self.origin_mm, led_aim[..., k, :]]
                    if rows_of_leds:
                        v = self._per_row(np.concatenate(per_led, axis=1), row)
                    else:
                        v = self._opaque(np.concatenate(per_led))
                    (ik,) = self._opaque([intensity[k]])
                    dc = mi.Point3f(v[0], v[1], v[2]) - p_hit
                    q, g = proxy(dr.dot(nrm, dc), -(dc.x * v[3] + dc.y * v[4] + dc.z * v[5]), dr.squared_norm(dc), ik)
                    values.append(((dc, q) + (() if same_axes else axes_of(k)), g))
            G = mi.Float(0.0)
            for _, g in values:
                G += g
            target = sampler.next_1d() * G
            acc = mi.Float(0.0)
            found = mi.Bool(False)
            chosen, g = values[-1]
            for vals, gk in values:
                acc += gk
                pick = ~found & (acc > target)
                chosen = tuple(dr.select(pick, new, old) for new, old in zip(vals, chosen))
                g = dr.select(pick, gk, g)
                found |= pick
            dc = dc0 + chosen[0] * dvec if row_of else chosen[0]
            b, u = axes_of(ks[0]) if same_axes else chosen[2:4]
            picks.append((G, dc, b, u, chosen[1], g))

        L = mi.Float(0.0)
        for n_bar, (G, dc, b, u, q, g) in enumerate(picks):
            shift = ((n_bar * 0.7548776662466927) % 1.0, (n_bar * 0.5698402909980532) % 1.0)
            sq = emitter_sample + mi.Point2f(*shift)
            sq = sq - dr.floor(sq)
            if disc:
                dsk = mi.warp.square_to_uniform_disk_concentric(sq)
                s_b, s_u, pdf = dsk.x * half_w, dsk.y * half_w, mi.Float(1.0)
            else:
                nb, nu = dr.dot(nrm, b), dr.dot(nrm, u)
                reach = half_w * dr.abs(nb) + half_h * dr.abs(nu)
                inv_x = dr.rcp(dr.maximum(dr.maximum(dr.dot(nrm, dc), reach), 1e-9))
                # Slopes of f_k across the emitter, per unit of t = s / size: the cosine factor's (exact
                # where the emitter is above the horizon) and, to first order, |y - p|^-(m + 3)'s.
                fall = (m + 3.0) * dr.rcp(dr.squared_norm(dc))
                c_b = size_w * (nb * inv_x - fall * dr.dot(b, dc))
                c_u = size_h * (nu * inv_x - fall * dr.dot(u, dc))
                # Keep the density 1 + c_b t_b + c_u t_u >= 0 on the emitter: |c_b| + |c_u| <= 2.
                shrink = dr.minimum(2.0 * dr.rcp(dr.maximum(dr.abs(c_b) + dr.abs(c_u), 1e-9)), 1.0)
                c_b, c_u = c_b * shrink, c_u * shrink
                t_u = self._linear_warp(dr, c_u, sq.y)
                marginal = 1.0 + c_u * t_u
                c_cond = dr.clip(c_b / dr.maximum(marginal, 1e-9), -2.0, 2.0)  # b given u: 1 + c_cond t_b
                t_b = self._linear_warp(dr, c_cond, sq.x)
                s_b, s_u, pdf = t_b * size_w, t_u * size_h, marginal * (1.0 + c_cond * t_b)
            dy = dc + s_b * b + s_u * u
            r2 = dr.squared_norm(dy)
            brdf = diffuse
            if spec is not None:
                ks_, e = float(spec[0]), float(spec[1])
                hv = dr.normalize(dy * dr.rsqrt(r2) + wo)
                brdf = brdf + ks_ * (e + 8.0) / (8.0 * np.pi) * dr.power(dr.maximum(dr.dot(nrm, hv), 0.0), e)
            f = q * dr.maximum(dr.dot(nrm, dy), 0.0) * brdf * inv_r_pow(r2)
            weight = dr.select(valid & (g > 0) & (pdf > 0), f * G / (g * pdf), 0.0)
            if shadows:
                occluded = self._occluded(self._shadow_ray(p_hit, n_geo, p_hit + dy), weight > 0)
                weight = dr.select(occluded, 0.0, weight)
            L += weight
        return L

    #: The largest block of cells (per side) :meth:`_intersect_grid` tests for a primary ray. The
    #: tallest shipped reliefs (asphalt 0.38 mm, ceramic tile 0.42 mm, on 0.0617 mm cells) need 4 with
    #: the camera along the tile's axes and 5 turned by 45 degrees, where the image's corner rays run
    #: furthest along one axis; with 4 as the limit those frames went to Embree and built the tile's
    #: BVH (8.5 s for the arc over asphalt on the 2-core VM; on CUDA that scene took 90 s instead of
    #: about 5). The block's cost grows slowly (LLVM, arc over asphalt, a frame: 0.198 s at 4, 0.203 at
    #: 5, 0.220 at 6, 0.245 at 8) and each count is one kernel.
    MAX_GRID_CELLS = 8

    def _grid_cells(self, R_world_cam: np.ndarray, x_cam, y_cam) -> int | None:
        """How many grid cells along x and along y (one count for both) a primary ray can cross
        between the tile's highest and lowest points, or None when :meth:`_intersect_grid` should
        not be used (no regular grid, rays near the horizontal, or more than
        :attr:`MAX_GRID_CELLS` cells).

        ``R_world_cam`` (3, 3) or (H, 3, 3); ``x_cam``, ``y_cam``: numpy arrays of normalised image
        coordinates that bound the rays (the image's corners, or every ray). The ray's
        horizontal run per unit of height, d_x / d_z, is a ratio of linear functions of
        (x_cam, y_cam) and takes its extremes over a rectangle at its corners: the four corners
        of the rectangle that bounds the coordinates stand for them all (every ray of a
        distorted 648x494 frame at 4 spp with a pose per row would have made 494 x 1.3 M
        directions, 14 GiB).
        """
        g = self._grid
        if g is None or not self.grid_rays:
            return None
        R = np.asarray(R_world_cam, np.float64).reshape(-1, 3, 3)
        x, y = np.asarray(x_cam, np.float64), np.asarray(y_cam, np.float64)
        x0, x1, y0, y1 = x.min(), x.max(), y.min(), y.max()
        d_cam = np.array([[x0, x1, x0, x1], [y0, y0, y1, y1], [1.0, 1.0, 1.0, 1.0]])
        d = R @ d_cam  # (H or 1, 3, 4)
        if np.max(d[:, 2] / np.linalg.norm(d, axis=1)) > -0.2:  # rays more than 78 deg off the vertical
            return None
        run = (g.z_max - g.z_min) * np.max(np.abs(d[:, :2] / d[:, 2:3]), axis=(0, 2))  # (2,) mm
        cells = int(np.floor(1.01 * max(run[0] / g.sx, run[1] / g.sy))) + 2
        return cells if cells <= self.MAX_GRID_CELLS else None

    def _cell_triangles(self, cell, i, j, active, u0, w0, du, dw, oz, dz, eps) -> list:
        """The rays' crossings of the two triangles of grid cell (i, j) (``cell`` = i (nx - 1) + j):
        [(upper, t, on), ...] for the lower and the upper triangle, t the ray parameter where the ray
        meets the triangle's plane and ``on`` whether that point lies on the triangle (edges included,
        with ``eps`` of a cell to spare, :attr:`_HeightGrid.edge_slack`, so that no ray slips between
        two triangles).

        The ray in the grid's cell units: u = u0 + t du along x, w = w0 + t dw along y (u0, w0 the
        origin's, counted from vertex (0, 0)), z = oz + t dz (mm). On the cell, (u, w) - (j, i) in
        [0, 1]^2, the lower triangle (w <= u) lies in the plane z = z00 + A u + B w with
        A = z01 - z00, B = z11 - z01, the upper one (w >= u) in A = z11 - z10, B = z10 - z00.
        """
        mi, dr = self.mi, self.dr
        g = self._grid
        assert g is not None
        z00, z01, z10, z11 = dr.gather(mi.Array4f, g.corners, cell, active)  # one packet: the cell's corners
        uc, wc = u0 - mi.Float(j), w0 - mi.Float(i)  # the origin in this cell's (u, w)
        out = []
        for upper in (False, True):
            A, B = (z11 - z10, z10 - z00) if upper else (z01 - z00, z11 - z01)
            t = (z00 + A * uc + B * wc - oz) / (dz - A * du - B * dw)
            u, w = uc + t * du, wc + t * dw
            if upper:
                on = (u >= -eps) & (w <= 1.0 + eps) & (w >= u - eps)
            else:
                on = (w >= -eps) & (u <= 1.0 + eps) & (w <= u + eps)
            out.append((upper, t, on))
        return out

    def _occluded(self, ray, active):
        """Whether each shadow ray meets the floor before ``ray.maxt``: :meth:`_occluded_grid` when the
        tile is a regular grid, Embree's ``ray_test`` otherwise."""
        if self._grid is not None and self.grid_rays:
            return self._occluded_grid(ray, active)
        return self.scene.ray_test(ray, active)

    def _occluded_grid(self, ray, active):
        """Whether each ray ``o + t d``, 0 < t < ``maxt``, meets a triangle of the height grid: the answer
        of Embree's ``ray_test`` on the same mesh, without Embree.

        The ray walks along its horizontal track. Where its height exceeds the highest vertex
        within r cells of the current cell (``skip_max``) for the whole of its next r cells of
        horizontal travel (the lower of its heights at both ends; a rising ray's is the first),
        nothing within r cells can stop it and it skips r cells (r in :attr:`_HeightGrid.SKIP_RADII`
        = 8, 2: the largest that holds); if it is then also above the tile's highest point and
        rising, nothing can stop it and it is done. Otherwise it tests the two triangles of the
        cell it is in (:meth:`_cell_triangles`; a hit at any 0 < t < maxt occludes it) and
        steps to where it leaves that cell. It also stops when occluded, at ``maxt`` and on
        leaving the tile. Every cell the ray crosses is tested or lies within a radius shown
        clear, so the answer is Embree's up to float rounding: on a full-size vinyl frame it
        disagreed on 5 of 1.28 M shadow rays (rays through a triangle's edge). A grazing LED
        ray takes about 6 steps (3.6 when occluded, 7 when it reaches its LED), about half the
        time of Embree's descent of a 6 M-triangle BVH. (Radii 16, 4, 1 and 32, 8, 2 were
        slower: every step pays for every level in the vector lanes.)
        """
        mi, dr = self.mi, self.dr
        g = self._grid
        assert g is not None
        o, d, maxt = ray.o, ray.d, ray.maxt
        x0, y0, inv_sx, inv_sy, z_max, s_min, eps = self._opaque(
            [g.x0, g.y0, 1.0 / g.sx, 1.0 / g.sy, g.z_max, min(g.sx, g.sy), g.edge_slack]
        )
        nx = dr.opaque(mi.Int32, g.nx)
        ny = dr.opaque(mi.Int32, g.ny)
        u0, w0 = (o.x - x0) * inv_sx, (o.y - y0) * inv_sy
        du, dw = d.x * inv_sx, d.y * inv_sy
        # Ray parameter per cell of horizontal travel (the shorter cell side: a skip of r of them stays
        # within r cells of the start in both axes).
        t_per_cell = s_min / dr.sqrt(dr.maximum(d.x * d.x + d.y * d.y, 1e-30))
        rising = d.z >= 0
        inv_du, inv_dw = 1.0 / du, 1.0 / dw

        def body(t, occluded, walking):
            z = o.z + t * d.z
            u, w = u0 + t * du, w0 + t * dw
            j, i = mi.Int32(dr.floor(u)), mi.Int32(dr.floor(w))
            walking &= (i >= 0) & (j >= 0) & (i < ny - 1) & (j < nx - 1) & ~(rising & (z > z_max))
            cell = dr.select(walking, i * (nx - 1) + j, 0)
            step = mi.Float(0.0)
            maxima = dr.gather(mi.Array2f, g.skip_max, cell, walking)  # SKIP_RADII: two
            done = mi.Bool(False)
            for k, r in enumerate(g.SKIP_RADII):
                dt = r * t_per_cell
                clear = walking & (step == 0) & (dr.minimum(z, z + dt * d.z) > maxima[k])
                step = dr.select(clear, dt, step)
                # Clear for r cells and above the tile's highest point after them: clear for good.
                done |= clear & rising & (z + dt * d.z > z_max)
            walking &= ~done
            test = walking & (step == 0)
            for _, t_hit, on in self._cell_triangles(cell, i, j, test, u0, w0, du, dw, o.z, d.z, eps):
                occluded |= test & on & (t_hit > 0) & (t_hit < maxt)
            # Where the ray leaves the cell (plus a thousandth of a cell, so that it enters the next one).
            u_exit = mi.Float(j) + dr.select(du > 0, 1.0, 0.0)
            w_exit = mi.Float(i) + dr.select(dw > 0, 1.0, 0.0)
            t_u = dr.select(du != 0, (u_exit - u0) * inv_du, dr.inf)
            t_w = dr.select(dw != 0, (w_exit - w0) * inv_dw, dr.inf)
            t_next = dr.maximum(dr.minimum(t_u, t_w), t) + 1e-3 * t_per_cell
            t = dr.select(test, t_next, t + step)
            walking &= ~occluded & (t < maxt)
            return t, occluded, walking

        _, occluded, _ = _while_loop(
            dr, (mi.Float(0.0), mi.Bool(False), mi.Bool(active)), lambda t, occ, walking: walking, body
        )
        return occluded

    def _intersect_grid(self, o, d, cells: int):
        """First hit of the rays ``o + t d`` (tile-local mm, ``d`` unit, pointing down) with the
        height-grid floor, traced without Embree: the same triangles as the mesh (cell (i, j)
        split along its diagonal into the lower triangle (i,j)-(i,j+1)-(i+1,j+1) and the
        upper one (i,j)-(i+1,j+1)-(i+1,j)).

        A ray crosses the slab z_min <= z <= z_max of the tile's heights over a horizontal
        run of at most ``cells`` - 1 cells (:meth:`_grid_cells`), so its first hit lies in the
        ``cells`` x ``cells`` block of cells starting at the cell under its entry point; every
        triangle of the block is tested (a plane z = z00 + A u + B w in the cell's (u, w) in
        [0, 1]^2) and the nearest hit kept. Returns (valid, t, p, n_geo, n_shade, albedo):
        n_geo the triangle's normal, n_shade the normalised barycentric mix of the vertex
        normals and albedo the barycentric mix of the vertex albedos, as Mitsuba's
        ``SurfaceInteraction`` (``n``, ``sh_frame.n``, ``eval_attribute_1``) gives them.
        """
        mi, dr = self.mi, self.dr
        g = self._grid
        assert g is not None
        x0, y0, inv_sx, inv_sy, z_min, z_max, eps = self._opaque(
            [g.x0, g.y0, 1.0 / g.sx, 1.0 / g.sy, g.z_min, g.z_max, g.edge_slack]
        )
        nx = dr.opaque(mi.Int32, g.nx)
        ny = dr.opaque(mi.Int32, g.ny)
        # Cell coordinates (u along x, w along y) of the origin and their rates along the ray.
        u0, w0 = (o.x - x0) * inv_sx, (o.y - y0) * inv_sy
        du, dw = d.x * inv_sx, d.y * inv_sy
        inv_dz = dr.rcp(d.z)
        t_top = dr.maximum((z_max - o.z) * inv_dz, 0.0)
        t_bottom = (z_min - o.z) * inv_dz
        j_first = mi.Int32(dr.floor(dr.minimum(u0 + t_top * du, u0 + t_bottom * du)))
        i_first = mi.Int32(dr.floor(dr.minimum(w0 + t_top * dw, w0 + t_bottom * dw)))
        t_best = mi.Float(dr.inf)
        cell_best = mi.Int32(0)
        upper_best = mi.Bool(False)
        for di in range(cells):
            for dj in range(cells):
                i, j = i_first + di, j_first + dj
                inside = (i >= 0) & (j >= 0) & (i < ny - 1) & (j < nx - 1)
                a = dr.select(inside, i * nx + j, 0)
                cell = dr.select(inside, i * (nx - 1) + j, 0)
                for upper, t, on in self._cell_triangles(cell, i, j, inside, u0, w0, du, dw, o.z, d.z, eps):
                    hit = inside & on & (t > 0) & (t < t_best)
                    t_best = dr.select(hit, t, t_best)
                    cell_best = dr.select(hit, a, cell_best)
                    upper_best = dr.select(hit, mi.Bool(upper), upper_best)
        valid = dr.isfinite(t_best)
        t = dr.select(valid, t_best, 0.0)
        p = o + t * d
        a = cell_best
        u = dr.clip((o.x + t * d.x - x0) * inv_sx - mi.Float(a % nx), 0.0, 1.0)
        w = dr.clip((o.y + t * d.y - y0) * inv_sy - mi.Float(a // nx), 0.0, 1.0)
        # Vertices of the hit triangle: (0,0), (1,0) or (1,1) [lower], (1,1) or (0,1) [upper].
        v1 = dr.select(upper_best, a + nx + 1, a + 1)
        v2 = dr.select(upper_best, a + nx, a + nx + 1)
        b0 = dr.select(upper_best, 1.0 - w, 1.0 - u)
        b1 = dr.select(upper_best, u, u - w)
        b2 = dr.select(upper_best, w - u, w)

        def mix(values):
            return (
                b0 * dr.gather(mi.Float, values, a, valid)
                + b1 * dr.gather(mi.Float, values, v1, valid)
                + b2 * dr.gather(mi.Float, values, v2, valid)
            )

        z_a, z_1, z_2 = (dr.gather(mi.Float, g.z, k, valid) for k in (a, v1, v2))
        # The plane's slopes per cell: lower A = z(1,0) - z(0,0), B = z(1,1) - z(1,0); upper A = z(1,1) - z(0,1), B = z(0,1) - z(0,0).
        A = dr.select(upper_best, z_1 - z_2, z_1 - z_a)
        B = dr.select(upper_best, z_2 - z_a, z_2 - z_1)
        n_geo = dr.normalize(mi.Vector3f(-A * inv_sx, -B * inv_sy, 1.0))
        n_shade = dr.normalize(mi.Vector3f(mix(g.normals[0]), mix(g.normals[1]), mix(g.normals[2])))
        return valid, t, p, n_geo, n_shade, mix(g.albedo)

    def _per_row(self, values: np.ndarray, row) -> list:
        """Columns of ``values`` (H, K) as K per-lane arrays: lane l gets row ``row[l]``'s value.

        The same float32 rounding as :meth:`_opaque`, so a row traced from its own pose
        matches a render from that pose alone."""
        mi, dr = self.mi, self.dr
        v = np.asarray(values, dtype=np.float64)
        return [
            dr.gather(mi.Float, mi.Float(np.ascontiguousarray(v[:, k]).astype(np.float32)), row)
            for k in range(v.shape[1])
        ]

    def _shadow_ray(self, p, n_geo, target):
        """Shadow ray from the hit point ``p`` with geometric normal ``n_geo`` to the point ``target`` (tile-local mm).

        As ``Interaction.spawn_ray_to`` but with the fixed lift :attr:`shadow_offset_mm`
        along the geometric normal, on the side of the target (see :meth:`_mesh_scene`).
        """
        mi, dr = self.mi, self.dr
        # Opaque: the offset follows the tile's extent, and a literal would compile a new kernel per value.
        (offset,) = self._opaque([self.shadow_offset_mm])
        lift = dr.mulsign(offset, dr.dot(n_geo, target - p))
        o = p + lift * n_geo
        d = target - o
        dist = dr.norm(d)
        ray = mi.Ray3f(o, d / dist)
        ray.maxt = dist * (1.0 - float(mi.math.ShadowEpsilon))
        return ray

    @staticmethod
    def _bars(T_world_cam: np.ndarray, leds: LedArray) -> np.ndarray:
        """Bar index of each LED: the side of the camera's x axis it sits on (0 left, 1 right)."""
        if leds.bar is not None:
            return np.asarray(leds.bar, dtype=int)
        rel = np.asarray(leds.positions_mm, dtype=float) - T_world_cam[:3, 3]
        return (rel @ T_world_cam[:3, 0] > 0).astype(int)

    def depth(self, T_world_cam: np.ndarray) -> np.ndarray:
        """Depth (distance along the optical axis, mm) of the floor at each pixel centre; NaN where no hit.

        ``T_world_cam`` (4, 4), or (H, 4, 4): one pose per image row (rolling shutter). The rays are
        traced on the height grid where the primary rays are (:meth:`_grid_cells`), else by
        Embree: the same distances to float rounding (1e-4 mm), without building the tile's BVH
        (about 15 s a tile on CUDA)."""
        mi = self.mi
        cam = self.camera
        u, v = np.meshgrid(np.arange(cam.width_px, dtype=float), np.arange(cam.height_px, dtype=float))
        d_cam = cam.unproject(np.stack([u.ravel(), v.ravel()], 1), 1.0)  # z = 1
        norm = np.linalg.norm(d_cam, axis=1)
        T = np.asarray(T_world_cam, dtype=np.float64)
        if T.ndim == 3:
            rows = np.repeat(np.arange(cam.height_px), cam.width_px)
            d_world = np.einsum("nij,nj->ni", T[rows, :3, :3], d_cam / norm[:, None]).astype(np.float32)
            o_np = (T[rows, :3, 3] - self.origin_mm).astype(np.float32)
            origin = mi.Point3f(o_np[:, 0], o_np[:, 1], o_np[:, 2])
        else:
            d_world = ((d_cam / norm[:, None]) @ T[:3, :3].T).astype(np.float32)
            origin = mi.Point3f(*[float(x) for x in T[:3, 3] - self.origin_mm])
        ray = mi.Ray3f(origin, mi.Vector3f(d_world[:, 0], d_world[:, 1], d_world[:, 2]))
        cells = self._grid_cells(T[..., :3, :3], d_cam[:, 0], d_cam[:, 1])
        if cells is None:
            si = self.scene.ray_intersect(ray)
            t_jit, valid_jit = si.t, si.is_valid()
        else:
            valid_jit, t_jit, *_ = self._intersect_grid(ray.o, ray.d, cells)
        t = np.asarray(t_jit.numpy(), dtype=np.float64)  # distance along the unit ray
        t[~np.asarray(valid_jit.numpy(), dtype=bool)] = np.nan
        # The unit ray is d_cam / |d_cam| with d_cam.z = 1, so depth along the axis = t / |d_cam|.
        return (t / norm).reshape(cam.height_px, cam.width_px).astype(np.float32)

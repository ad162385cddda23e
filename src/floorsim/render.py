"""The Mitsuba 3 backend: the only module that imports mitsuba and drjit.

Physics model
-------------
The floor is a height-field triangle mesh (real geometry, vertex spacing at most half a
ground-sample distance) with a per-vertex albedo, built once per floor tile. The LEDs
are point sources attached to the rig; each has a cosine-power emission lobe aimed at
the floor point under the camera. The hood blocks all other light.

For every pixel we trace ``spp`` stratified, jittered primary rays through the pinhole
(with the camera's lens distortion when it has one) and, at each floor hit, evaluate the
direct light of **every** LED deterministically::

    L = albedo / pi * sum_k  I_k * max(0, -w_k . a_k)^m * max(0, n . w_k) / r_k^2 * V_k

(w_k: unit vector from the hit to LED k, a_k: LED aim, r_k: distance, V_k: shadow ray
visibility). This replaces Mitsuba's one-random-light-per-sample ``direct`` integrator
(noisier, and it scales point-light images by ``emitter_samples``); only the pixel
footprint is Monte Carlo integrated. Moving the camera and the LEDs touches no shape, so
the BVH is never rebuilt within a tile (DESIGN: a shape transform rebuilds it).

Units: mm; radiance in arbitrary linear units proportional to LED power.
"""

from __future__ import annotations

import glob
import logging
import os
import re
from dataclasses import dataclass

import numpy as np

from floorvo.camera import CameraModel
from floorvo.errors import FloorbenchError

__all__ = ["LedArray", "FloorRenderer", "find_libllvm", "backend_info"]

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


def _has_cuda() -> bool:
    return any(os.path.exists(p) for p in ("/dev/nvidiactl", "/dev/nvidia0"))


def _import_mitsuba(variant: str | None = None):
    """Import mitsuba with a working variant; raise a one-line FloorbenchError if impossible."""
    global _MI
    if _MI is not None:
        return _MI
    want = variant or os.environ.get("FLOORSIM_VARIANT") or ("cuda_ad_mono" if _has_cuda() else "llvm_ad_mono")
    if want.startswith("llvm") and "DRJIT_LIBLLVM_PATH" not in os.environ:
        path = find_libllvm()
        if path is None:
            raise FloorbenchError(
                "Mitsuba's LLVM backend needs libLLVM >= 17: run scripts/setup, or 'apt-get install libllvm19', "
                "or set DRJIT_LIBLLVM_PATH to a libLLVM.so of version 17 or newer"
            )
        os.environ["DRJIT_LIBLLVM_PATH"] = path
    try:
        import mitsuba as mi
    except ImportError as exc:
        raise FloorbenchError(f"the renderer needs mitsuba ({exc}); run scripts/setup or 'pip install mitsuba==3.9.1'") from None
    try:
        mi.set_variant(want)
    except (ImportError, AttributeError, RuntimeError) as exc:
        if want.startswith("cuda"):
            log.warning("variant %s unavailable (%s); falling back to llvm_ad_mono", want, exc)
            os.environ.setdefault("DRJIT_LIBLLVM_PATH", find_libllvm() or "")
            mi.set_variant("llvm_ad_mono")
        else:
            raise FloorbenchError(f"mitsuba variant {want!r} is not available ({exc})") from None
    _MI = mi
    return mi


def backend_info() -> dict:
    """Versions and variant of the backend (for sequence.json)."""
    mi = _import_mitsuba()
    import drjit as dr

    return {"mitsuba": mi.__version__, "drjit": dr.__version__, "variant": mi.variant()}


@dataclass(frozen=True)
class LedArray:
    """LED point sources in world coordinates for one frame.

    ``positions_mm`` (N, 3), ``aim`` (N, 3) unit emission axes, ``intensity`` (N,)
    radiant intensity on the axis (arbitrary units), ``lobe_exponent`` m of the
    cos^m emission profile.
    """

    positions_mm: np.ndarray
    aim: np.ndarray
    intensity: np.ndarray
    lobe_exponent: float = 1.0


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
        self.scene = None
        self._ray_cache: dict = {}

    # --------------------------------------------------------------------- geometry
    def load_heightfield(self, x0_mm: float, y0_mm: float, spacing_mm: float, height_mm: np.ndarray, albedo: np.ndarray) -> None:
        """Build the floor mesh: vertex (i, j) at (x0 + j s, y0 + i s, height[i, j]).

        ``height_mm`` and ``albedo`` are (H, W) grids. Replaces any previous floor.
        """
        mi = self.mi
        height_mm = np.asarray(height_mm, dtype=np.float32)
        albedo = np.asarray(albedo, dtype=np.float32)
        ny, nx = height_mm.shape
        if albedo.shape != height_mm.shape or nx < 2 or ny < 2:
            raise ValueError(f"load_heightfield: height {height_mm.shape} and albedo {albedo.shape} must be equal, >= 2x2")
        xs = (x0_mm + spacing_mm * np.arange(nx)).astype(np.float32)
        ys = (y0_mm + spacing_mm * np.arange(ny)).astype(np.float32)
        V = np.empty((ny, nx, 3), dtype=np.float32)
        V[..., 0] = xs[None, :]
        V[..., 1] = ys[:, None]
        V[..., 2] = height_mm
        a = (np.arange(ny - 1, dtype=np.uint32)[:, None] * nx + np.arange(nx - 1, dtype=np.uint32)[None, :]).ravel()
        F = np.empty((2 * a.size, 3), dtype=np.uint32)
        F[: a.size, 0], F[: a.size, 1], F[: a.size, 2] = a, a + 1, a + 1 + nx
        F[a.size :, 0], F[a.size :, 1], F[a.size :, 2] = a, a + 1 + nx, a + nx
        self._set_mesh(V.reshape(-1), F.reshape(-1), albedo.reshape(-1), nx * ny, len(F))

    def load_flat(self, xmin: float, xmax: float, ymin: float, ymax: float, albedo: float) -> None:
        """A perfectly flat floor of uniform ``albedo`` (for the flat-field frame)."""
        V = np.array([[xmin, ymin, 0], [xmax, ymin, 0], [xmax, ymax, 0], [xmin, ymax, 0]], dtype=np.float32)
        F = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32)
        self._set_mesh(V.reshape(-1), F.reshape(-1), np.full(4, albedo, dtype=np.float32), 4, 2)

    def _set_mesh(self, V, F, albedo, n_vertices, n_faces) -> None:
        mi = self.mi
        self.scene = None
        mesh = mi.Mesh("floor", n_vertices, n_faces, has_vertex_normals=False, has_vertex_texcoords=False)
        params = mi.traverse(mesh)
        params["vertex_positions"] = mi.Float(V)
        params["faces"] = mi.UInt32(F)
        params.update()
        mesh.add_attribute("vertex_albedo", 1, mi.Float(albedo))
        self.scene = mi.load_dict({"type": "scene", "floor": mesh})

    # --------------------------------------------------------------------- rays
    def _pixel_rays_cam(self, spp: int, rng: np.random.Generator) -> np.ndarray:
        """(spp * H * W, 3) unit ray directions in the camera frame, sample-major order.

        Stratified: the pixel is split into ceil(sqrt(spp))^2 strata; ``spp`` of them
        are used with a seeded jitter inside each.
        """
        cam = self.camera
        w, h = cam.width_px, cam.height_px
        s = int(np.ceil(np.sqrt(spp)))
        strata = [(i, j) for j in range(s) for i in range(s)]
        if spp < len(strata):
            idx = rng.permutation(len(strata))[:spp]
            strata = [strata[k] for k in sorted(idx)]
        u0 = np.arange(w, dtype=np.float64)[None, :]
        v0 = np.arange(h, dtype=np.float64)[:, None]
        uv = np.empty((len(strata), h, w, 2))
        for k, (i, j) in enumerate(strata):
            jit = rng.random((2, h, w))
            uv[k, :, :, 0] = u0 - 0.5 + (i + jit[0]) / s
            uv[k, :, :, 1] = v0 - 0.5 + (j + jit[1]) / s
        d = cam.unproject(uv.reshape(-1, 2), 1.0)
        return d / np.linalg.norm(d, axis=1, keepdims=True)

    def render(self, T_world_cam: np.ndarray, leds: LedArray, spp: int = 4, seed: int = 0) -> np.ndarray:
        """Radiance image (H, W) float32 of the loaded floor from pose ``T_world_cam`` (mm).

        Deterministic for the same inputs (the pixel jitter comes from ``seed``).
        """
        if self.scene is None:
            raise RuntimeError("FloorRenderer.render: no floor loaded")
        mi, dr = self.mi, self.dr
        cam = self.camera
        rng = np.random.default_rng([int(seed), 0x5EED])
        d_cam = self._pixel_rays_cam(int(spp), rng)
        T = np.asarray(T_world_cam, dtype=np.float64)
        d_world = (d_cam @ T[:3, :3].T).astype(np.float32)
        o = T[:3, 3]
        ray = mi.Ray3f(mi.Point3f(*[float(v) for v in o]), mi.Vector3f(d_world[:, 0], d_world[:, 1], d_world[:, 2]))
        si = self.scene.ray_intersect(ray)
        valid = si.is_valid()
        albedo = si.shape.eval_attribute_1("vertex_albedo", si)
        n = si.n
        # Face normals may point down if the winding flips: orient them towards the camera.
        n = dr.select(dr.dot(n, -ray.d) < 0, -n, n)
        L = mi.Float(0.0)
        m = float(leds.lobe_exponent)
        for p, a, inten in zip(leds.positions_mm, leds.aim, leds.intensity):
            if inten <= 0:
                continue
            lp = mi.Point3f(float(p[0]), float(p[1]), float(p[2]))
            dl = lp - si.p
            r2 = dr.squared_norm(dl)
            wl = dl * dr.rsqrt(r2)
            cos_surf = dr.maximum(dr.dot(n, wl), 0.0)
            cos_led = dr.maximum(-(wl.x * float(a[0]) + wl.y * float(a[1]) + wl.z * float(a[2])), 0.0)
            lobe = cos_led if m == 1.0 else dr.power(cos_led, m)
            lit = valid & (cos_surf > 0) & (cos_led > 0)
            occluded = self.scene.ray_test(si.spawn_ray_to(lp), lit)
            L += dr.select(lit & ~occluded, float(inten) * lobe * cos_surf / r2, 0.0)
        L = L * albedo * (1.0 / np.pi)
        img = np.asarray(L.numpy(), dtype=np.float64).reshape(-1, cam.height_px, cam.width_px).mean(axis=0)
        return img.astype(np.float32)

    def depth(self, T_world_cam: np.ndarray) -> np.ndarray:
        """Depth (distance along the optical axis, mm) of the floor at each pixel centre; NaN where no hit."""
        mi = self.mi
        cam = self.camera
        u, v = np.meshgrid(np.arange(cam.width_px, dtype=float), np.arange(cam.height_px, dtype=float))
        d_cam = cam.unproject(np.stack([u.ravel(), v.ravel()], 1), 1.0)  # z = 1
        norm = np.linalg.norm(d_cam, axis=1)
        T = np.asarray(T_world_cam, dtype=np.float64)
        d_world = ((d_cam / norm[:, None]) @ T[:3, :3].T).astype(np.float32)
        o = T[:3, 3]
        ray = mi.Ray3f(mi.Point3f(*[float(x) for x in o]), mi.Vector3f(d_world[:, 0], d_world[:, 1], d_world[:, 2]))
        si = self.scene.ray_intersect(ray)
        t = np.asarray(si.t.numpy(), dtype=np.float64)  # distance along the unit ray
        t[~np.asarray(si.is_valid().numpy(), dtype=bool)] = np.nan
        # The unit ray is d_cam / |d_cam| with d_cam.z = 1, so depth along the axis = t / |d_cam|.
        return (t / norm).reshape(cam.height_px, cam.width_px).astype(np.float32)

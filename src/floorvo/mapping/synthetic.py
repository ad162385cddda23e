"""A procedural floor texture and exact views of it at known camera poses (no renderer).

For tests and benchmarks of the map and the relocalisation: a large, deterministic
texture (bumps at several scales, veins, pores, noise) stands for the floor seen top-down
at the camera's ground sample distance, and :func:`view` crops the frame a downward
camera at ``T_world_cam`` would see by an exact affine warp (rotation about the principal
point and translation in px = mm / gsd).

Texture pixel ``(U, V)`` of floor point ``(X, Y)`` (mm): ``U = X / gsd + U0``,
``V = -Y / gsd + V0`` with ``(U0, V0)`` the texture centre (world y up, rows down).
"""

from __future__ import annotations

import cv2
import numpy as np

from floorvo.camera import CameraModel
from floorvo.geometry import se2_from_T

__all__ = ["floor_texture", "view", "texture_extent_mm"]


def floor_texture(size_px: int = 4000, seed: int = 0) -> np.ndarray:
    """A (size_px, size_px) float32 floor texture in [0, 1], deterministic from ``seed``."""
    rng = np.random.default_rng(seed)
    n = int(size_px)
    out = np.zeros((n, n), np.float32)
    for sigma, amp in ((1.2, 0.35), (3.0, 0.35), (8.0, 0.25), (25.0, 0.15)):
        layer = _smooth_noise(rng, n, sigma)
        out += amp * layer / (layer.std() + 1e-9)
    # Veins: thin dark lines where a smooth field crosses zero.
    field = _smooth_noise(rng, n, 40.0)
    field /= field.std() + 1e-9
    out -= 0.8 * np.exp(-((field / 0.06) ** 2))
    # Pores: sparse dark dots.
    pores = (rng.random((n, n)) < 0.002).astype(np.float32)
    out -= 1.5 * cv2.GaussianBlur(pores, (0, 0), 1.0) * 6.0
    out -= out.min()
    out /= out.max() + 1e-9
    return out


def _smooth_noise(rng: np.random.Generator, n: int, sigma: float) -> np.ndarray:
    """White noise blurred by ``sigma`` px; wide blurs are made on a coarser grid and upsampled."""
    f = max(1, int(sigma // 2))
    m = -(-n // f)
    layer = cv2.GaussianBlur(rng.standard_normal((m, m)).astype(np.float32), (0, 0), sigma / f)
    if f > 1:
        layer = cv2.resize(layer, (m * f, m * f), interpolation=cv2.INTER_CUBIC)[:n, :n]
    return layer


def texture_extent_mm(texture: np.ndarray, gsd_mm_per_px: float) -> tuple[float, float, float, float]:
    """(xmin, xmax, ymin, ymax) of the floor the texture covers, in mm."""
    h, w = texture.shape
    return (-(w / 2) * gsd_mm_per_px, (w / 2) * gsd_mm_per_px, -(h / 2) * gsd_mm_per_px, (h / 2) * gsd_mm_per_px)


def view(
    texture: np.ndarray,
    camera: CameraModel,
    T_world_cam: np.ndarray,
    height_mm: float,
    *,
    noise_std: float = 0.0,
    rng: np.random.Generator | None = None,
    centre_mm: tuple[float, float] = (0.0, 0.0),
) -> np.ndarray:
    """uint8 (H, W) frame of ``camera`` at ``T_world_cam`` (downward, yaw only) over ``texture``.

    A camera at (X0, Y0) with yaw psi sees floor point ``c + Rz(psi) [(u - cx) g, -(v - cy) g]``
    at pixel (u, v) (cam x = world x, cam y = world -y at yaw 0), so the image -> texture map
    is the rotation by psi about the principal point plus the translation (X0 / g, -Y0 / g).
    ``noise_std``: Gaussian sensor noise in grey levels (needs ``rng``); ``centre_mm``: the
    floor point (mm) at the texture's centre.
    """
    g = camera.gsd_mm_per_px(height_mm)
    x0, y0, psi = se2_from_T(T_world_cam)
    x0, y0 = x0 - centre_mm[0], y0 - centre_mm[1]
    th, tw = texture.shape
    Uc, Vc = x0 / g + tw / 2.0, -y0 / g + th / 2.0
    c, s = np.cos(psi), np.sin(psi)
    cx, cy = camera.cx_px, camera.cy_px
    M = np.array([[c, s, Uc - c * cx - s * cy], [-s, c, Vc + s * cx - c * cy]])
    img = cv2.warpAffine(
        texture, M, camera.size, flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_REFLECT
    )
    img = 30.0 + 200.0 * img
    if noise_std > 0:
        img = img + (rng or np.random.default_rng(0)).normal(0.0, noise_std, img.shape)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)

"""Structured-light depth noise: disparity quantisation, disparity noise and dropout.

An active-stereo / structured-light sensor measures the disparity ``d = f B / z`` between
its projector and its camera (focal length ``f`` in px, baseline ``B`` in mm) and
reports ``z = f B / d``. The model, per pixel:

* disparity noise: ``d' = d + N(0, sigma_px)``;
* quantisation to ``1 / subpixel`` px steps: ``d_q = round(d' * subpixel) / subpixel``;
* depth ``z_q = f B / d_q``, so the depth step and noise grow as ``z^2 / (f B)``;
* dropout: a pixel reports 0 (no measurement) with probability ``dropout``, and wherever
  the depth changes by more than ``edge_mm`` to a neighbour (occlusion edges).

Seeded: ``numpy.random.default_rng([seed, frame_index, 0xD3])``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from floorvo.config import Config, param

__all__ = ["DepthNoise", "apply_depth_noise"]


@dataclass(frozen=True)
class DepthNoise(Config):
    """Parameters of :func:`apply_depth_noise` (``model = "none"`` keeps the exact depth)."""

    model: str = param("none", choices=("none", "structured_light"), doc="none keeps the exact depth")
    baseline_mm: float = param(50.0, unit="mm", gt=0, max=1e5, doc="projector-camera baseline B")
    focal_px: float = param(580.0, unit="px", min=1.0, max=1e6, doc="focal length f of the depth camera")
    subpixel: float = param(8.0, unit="steps per px", gt=0, max=1e6, doc="disparity quantisation steps per pixel")
    sigma_px: float = param(0.05, unit="px", min=0, max=1e3, doc="standard deviation of the disparity noise")
    dropout: float = param(0.0, min=0, max=1, doc="probability of a pixel without measurement")
    edge_mm: float = param(5.0, unit="mm", gt=0, doc="depth jump to a neighbour that drops a pixel")


def apply_depth_noise(depth_mm: np.ndarray, p: DepthNoise, seed: int, frame_index: int) -> np.ndarray:
    """Noisy depth (H, W) float32 mm from exact ``depth_mm``; 0 = no measurement."""
    z = np.asarray(depth_mm, dtype=np.float64)
    if p.model == "none":
        return np.nan_to_num(z, nan=0.0).astype(np.float32)
    rng = np.random.default_rng([int(seed), int(frame_index), 0xD3])
    valid = np.isfinite(z) & (z > 0)
    fb = p.focal_px * p.baseline_mm
    d = np.where(valid, fb / np.where(valid, z, 1.0), 0.0)
    if p.sigma_px > 0:
        d = d + rng.normal(0.0, p.sigma_px, size=d.shape)
    dq = np.round(d * p.subpixel) / p.subpixel
    ok = valid & (dq > 0)
    out = np.where(ok, fb / np.where(ok, dq, 1.0), 0.0)
    if p.dropout > 0:
        out[rng.random(out.shape) < p.dropout] = 0.0
    zf = np.where(valid, z, np.nan)
    edge = np.zeros(z.shape, dtype=bool)
    with np.errstate(invalid="ignore"):
        edge[:, 1:] |= np.abs(np.diff(zf, axis=1)) > p.edge_mm
        edge[1:, :] |= np.abs(np.diff(zf, axis=0)) > p.edge_mm
    out[edge] = 0.0
    return out.astype(np.float32)

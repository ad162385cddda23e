"""``example-fft-shift``: translation between frames by phase correlation of the whole frame.

A plugin estimator implements floorvo's estimator protocol (:mod:`floorvo.estimators.base`):
class attributes ``name``, ``description``, ``Config`` (a frozen dataclass declared with
:func:`floorvo.config.param`, so ``--set`` and ``floorvo list --config`` work on it) and
``requires``; ``__init__(config, camera, *, height_mm, flatfield=None, **rig)``; ``start()``
for the per-sequence state; ``step(state, frame)`` returning a :class:`StepResult`.

Method (translation only, no yaw): the frame divided by the flat field, a Hann window, the
normalised cross-power spectrum ``F_prev conj(F_cur) / |...|`` and its inverse FFT, whose
peak sits at the image shift; a parabola through the peak and its neighbours gives the
sub-pixel part. The floor moved by ``d`` px in the image, so the camera moved by
``-d * gsd`` mm along its x and y axes (gsd = height / focal length, eq. 1 of paper 000).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from floorvo.config import Config as ConfigBase
from floorvo.config import param
from floorvo.estimators.base import Frame, StepResult
from floorvo.geometry import floor_rigid_to_T


@dataclass(frozen=True)
class FftShiftConfig(ConfigBase):
    """Settings of ``example-fft-shift``."""

    config_name = "example-fft-shift"
    min_peak: float = param(0.03, gt=0, lt=1, doc="a correlation peak below this (of 1) is reported lost")


def _peak_offset(c_minus: float, c0: float, c_plus: float) -> float:
    """Sub-pixel offset of a peak from three samples (vertex of the parabola through them)."""
    den = c_minus - 2.0 * c0 + c_plus
    return 0.0 if den == 0 else float(np.clip(0.5 * (c_minus - c_plus) / den, -0.5, 0.5))


class FftShift:
    name = "example-fft-shift"
    description = "example plugin: whole-frame FFT phase correlation, translation only"
    Config = FftShiftConfig
    requires: frozenset[str] = frozenset()

    def __init__(
        self, config: FftShiftConfig, camera: Any, *, height_mm: float, flatfield: np.ndarray | None = None, **rig: Any
    ):
        self.config, self.camera = config, camera
        self.gsd_mm_per_px = camera.gsd_mm_per_px(height_mm)  # eq. (1) of paper 000
        h, w = camera.height_px, camera.width_px
        self.window = np.outer(np.hanning(h), np.hanning(w))
        self.flat = None if flatfield is None else np.maximum(np.asarray(flatfield, float) / np.max(flatfield), 1e-3)

    def start(self) -> dict[str, Any]:
        return {"spectrum": None}

    def _spectrum(self, image: np.ndarray) -> np.ndarray:
        img = np.asarray(image, dtype=float)
        if self.flat is not None:
            img = img / self.flat
        return np.fft.fft2((img - img.mean()) * self.window)

    def step(self, state: dict[str, Any], frame: Frame) -> StepResult:
        t0 = time.perf_counter()
        spec = self._spectrum(frame.image)
        prev, state["spectrum"] = state["spectrum"], spec
        if prev is None:
            return StepResult("init", timing_ms={"total": (time.perf_counter() - t0) * 1e3})
        cross = prev * np.conj(spec)
        corr = np.fft.ifft2(cross / np.maximum(np.abs(cross), 1e-12)).real
        v, u = np.unravel_index(int(np.argmax(corr)), corr.shape)
        peak = float(corr[v, u])
        total_ms = (time.perf_counter() - t0) * 1e3
        if peak < self.config.min_peak:
            return StepResult(
                "lost", reason=f"correlation peak {peak:.3f} < {self.config.min_peak}", timing_ms={"total": total_ms}
            )
        h, w = corr.shape
        du = u + _peak_offset(corr[v, u - 1], peak, corr[v, (u + 1) % w])
        dv = v + _peak_offset(corr[v - 1, u], peak, corr[(v + 1) % h, u])
        # The peak sits at the shift of prev relative to cur: cur(x) = prev(x - d) peaks at -d.
        d_px = -np.array([(du + w / 2) % w - w / 2, (dv + h / 2) % h - h / 2])
        t2_mm = d_px * self.gsd_mm_per_px  # a floor point's camera x, y moved by this (mm)
        T = floor_rigid_to_T(np.eye(2), t2_mm)
        return StepResult("ok", T, timing_ms={"total": (time.perf_counter() - t0) * 1e3})

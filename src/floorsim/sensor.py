"""Camera sensor model: fixed exposure, photon shot noise, read noise, quantisation, saturation.

Radiance (linear, arbitrary units) becomes electrons through one exposure gain fixed per
sequence: ``electrons = radiance * gain_e_per_unit``. By default the gain puts the
``target_percentile`` of the first frame's radiance at ``target_level`` of the full well.
Then::

    e   ~ Poisson(electrons)            (shot noise, if enabled)
    e  += Normal(0, read_noise_e)        (read noise)
    DN  = round(clip(e / full_well_e, 0, 1) * (2^bits - 1))   (saturation, quantisation)

Every random draw comes from ``numpy.random.default_rng([seed, frame_index])``, so a
frame's noise does not depend on which frames were rendered before it (resume-safe).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["SensorModel", "exposure_gain"]


def exposure_gain(radiance: np.ndarray, full_well_e: float, target_percentile: float, target_level: float) -> float:
    """Electrons per radiance unit that put ``target_percentile`` of ``radiance`` at ``target_level`` x full well."""
    ref = float(np.percentile(np.asarray(radiance, dtype=np.float64), target_percentile))
    if not np.isfinite(ref) or ref <= 0:
        return 0.0
    return target_level * full_well_e / ref


@dataclass(frozen=True)
class SensorModel:
    """Sensor parameters (see module docstring). ``gain_e_per_unit`` is fixed per sequence."""

    gain_e_per_unit: float
    full_well_e: float = 10000.0
    read_noise_e: float = 5.0
    shot_noise: bool = True
    bit_depth: int = 8

    @property
    def max_dn(self) -> int:
        return (1 << self.bit_depth) - 1

    def capture(self, radiance: np.ndarray, seed: int, frame_index: int, noise: bool = True) -> np.ndarray:
        """Digitise a radiance image (H, W) to uint8/uint16 DN."""
        e = np.asarray(radiance, dtype=np.float64) * self.gain_e_per_unit
        e = np.maximum(e, 0.0)
        if noise:
            rng = np.random.default_rng([int(seed), int(frame_index), 0x5E50])
            if self.shot_noise:
                e = rng.poisson(e).astype(np.float64)
            if self.read_noise_e > 0:
                e = e + rng.normal(0.0, self.read_noise_e, size=e.shape)
        dn = np.round(np.clip(e / self.full_well_e, 0.0, 1.0) * self.max_dn)
        return dn.astype(np.uint8 if self.bit_depth <= 8 else np.uint16)

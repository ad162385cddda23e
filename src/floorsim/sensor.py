"""Camera sensor model: exposure, fixed-pattern noise, photon shot noise, read noise,
response curve, quantisation, saturation; rolling-shutter row timing; auto exposure.

Radiance (linear, arbitrary units) becomes electrons through an exposure gain
``gain_e_per_unit``: fixed per sequence (``sensor.exposure_mode = "fixed"``; by default the
gain puts the ``target_percentile`` of the first frame's radiance at ``target_level`` of
the full well), or chosen per frame by :class:`AutoExposure` (``"auto"``). Then, per pixel
(i, j)::

    e   = radiance * gain * (1 + prnu * P_ij) + dsnu_e * D_ij  (fixed pattern: PRNU, DSNU)
    e   ~ Poisson(max(e, 0))                                (shot noise, if enabled)
    e  += Normal(0, read_noise_e)                           (read noise)
    v   = clip(e / full_well_e, 0, 1) ** (1 / gamma)        (response curve; gamma = 1: linear)
    v   = 1 at hot pixels, 0 at dead pixels
    DN  = round(v * (2^bits - 1))                           (quantisation)

P and D are standard normal maps, and the hot and dead pixels a random set of
``hot_pixel_fraction`` and ``dead_pixel_fraction`` of the pixels: all drawn from
``numpy.random.default_rng([seed, 0xF1C5ED])`` and so fixed for the sensor (the same in
every frame; another seed is another sensor). With the defaults (0, 0, 0, 0, gamma 1)
the model is the linear one of the earlier versions, byte for byte. The fixed-pattern
model is the EMVA 1288 one (PRNU as a relative gain spread, DSNU as an offset spread in
electrons).

Every temporal random draw comes from ``numpy.random.default_rng([seed, frame_index])``,
so a frame's noise does not depend on which frames were rendered before it (resume-safe).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from floorvo.sequence_meta import rolling_row_offsets_s

__all__ = ["SensorModel", "FixedPattern", "AutoExposure", "exposure_gain", "image_level", "rolling_row_offsets_s"]

#: Seed tag of the fixed-pattern maps (P, D, hot, dead) of a sensor.
_FPN_TAG = 0xF1C5ED
#: The most electrons a pixel's expected count is taken as before shot noise is drawn: 1e8
#: times the largest full well a scene may state (sensor.full_well_e <= 1e7), so every pixel
#: above it is saturated either way.
_POISSON_MAX_E = 1e15


def exposure_gain(radiance: np.ndarray, full_well_e: float, target_percentile: float, target_level: float) -> float:
    """Electrons per radiance unit that put ``target_percentile`` of ``radiance`` at ``target_level`` x full well."""
    ref = float(np.percentile(np.asarray(radiance, dtype=np.float64), target_percentile))
    if not np.isfinite(ref) or ref <= 0:
        return 0.0
    return target_level * full_well_e / ref


def image_level(dn: np.ndarray, bit_depth: int, percentile: float) -> float:
    """Brightness of a captured frame as auto exposure meters it: the ``percentile`` of its DN
    as a fraction of full scale (0..1)."""
    return float(np.percentile(np.asarray(dn, dtype=np.float64), percentile)) / ((1 << int(bit_depth)) - 1)


@dataclass(frozen=True)
class FixedPattern:
    """Fixed-pattern noise of a sensor (see the module docstring); all zero: none.

    ``prnu``: relative standard deviation of the per-pixel gain; ``dsnu_e``: standard
    deviation of the per-pixel offset (electrons); ``hot_pixel_fraction`` and
    ``dead_pixel_fraction``: fractions of pixels stuck at full scale and at zero.
    """

    prnu: float = 0.0
    dsnu_e: float = 0.0
    hot_pixel_fraction: float = 0.0
    dead_pixel_fraction: float = 0.0

    @property
    def active(self) -> bool:
        return bool(self.prnu or self.dsnu_e or self.hot_pixel_fraction or self.dead_pixel_fraction)

    def maps(self, shape: tuple[int, int], seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(gain (H, W), offset_e (H, W), hot (H, W) bool, dead (H, W) bool) of the sensor ``seed``.

        Drawn in a fixed order from one generator, so each map is the same whatever the
        others' settings: raising ``prnu`` scales the same pattern.
        """
        rng = np.random.default_rng([int(seed), _FPN_TAG])
        p = rng.standard_normal(shape)
        d = rng.standard_normal(shape)
        u = rng.random(shape)
        gain = 1.0 + self.prnu * p
        offset = self.dsnu_e * d
        hot = u < self.hot_pixel_fraction
        dead = (u >= self.hot_pixel_fraction) & (u < self.hot_pixel_fraction + self.dead_pixel_fraction)
        return gain, offset, hot, dead


@dataclass(frozen=True)
class SensorModel:
    """Sensor parameters (see module docstring). ``gain_e_per_unit`` is the exposure of the frame."""

    gain_e_per_unit: float
    full_well_e: float = 10000.0
    read_noise_e: float = 5.0
    shot_noise: bool = True
    bit_depth: int = 8
    fixed_pattern: FixedPattern = FixedPattern()
    gamma: float = 1.0

    @property
    def max_dn(self) -> int:
        return (1 << self.bit_depth) - 1

    def capture(self, radiance: np.ndarray, seed: int, frame_index: int, noise: bool = True) -> np.ndarray:
        """Digitise a radiance image (H, W) to uint8/uint16 DN.

        ``noise=False`` drops the temporal noise (shot and read noise); the fixed pattern,
        a property of the sensor, stays. ``seed`` also selects the sensor's fixed pattern.
        """
        e = np.asarray(radiance, dtype=np.float64) * self.gain_e_per_unit
        hot = dead = None
        if self.fixed_pattern.active:
            gain_map, offset_e, hot, dead = self.fixed_pattern.maps(e.shape[-2:], seed)
            e = e * gain_map + offset_e
        e = np.maximum(e, 0.0)
        if noise:
            rng = np.random.default_rng([int(seed), int(frame_index), 0x5E50])
            if self.shot_noise:
                # above _POISSON_MAX_E a pixel saturates whatever its noise; numpy's Poisson refuses
                # lam > ~9e18 ('lam value too large' ended a render of exposure_gain = 1e308)
                e = rng.poisson(np.minimum(e, _POISSON_MAX_E)).astype(np.float64)
            if self.read_noise_e > 0:
                e = e + rng.normal(0.0, self.read_noise_e, size=e.shape)
        v = np.clip(e / self.full_well_e, 0.0, 1.0)
        if self.gamma != 1.0:
            v = v ** (1.0 / self.gamma)
        if hot is not None and dead is not None:
            v[hot] = 1.0
            v[dead] = 0.0
        dn = np.round(v * self.max_dn)
        return dn.astype(np.uint8 if self.bit_depth <= 8 else np.uint16)


@dataclass(frozen=True)
class AutoExposure:
    """Auto exposure: the exposure of frame i from the brightness of frame i - ``delay_frames``.

    With m_j the metered level of frame j (:func:`image_level`: its ``percentile`` as a
    fraction of full scale) and g_i the gain (electrons per radiance unit) of frame i::

        g_i = g_{i-1} * (target_level / max(m_{i-d}, floor)) ** k     for i >= d
        g_i = g_0                                                     for i < d

    (k = ``loop_gain`` in (0, 1], d = ``delay_frames``; the correction is proportional in
    the logarithm of the exposure, as camera AE loops step in EV; floor = half a DN, so a
    black frame raises the exposure by a bounded factor). k = 1 and d = 1 correct a
    constant scene in one frame; smaller k converge geometrically (the log error shrinks
    by 1 - k per frame); a delay d > 1 with a large k overshoots and hunts, as real AE does
    when the light flickers or the floor changes from dark to light.
    """

    initial_gain: float
    target_level: float = 0.8
    percentile: float = 99.0
    loop_gain: float = 0.5
    delay_frames: int = 1
    bit_depth: int = 8

    def next_gain(self, index: int, gains: list[float], levels: list[float]) -> float:
        """Gain of frame ``index`` given the gains and metered levels of frames 0 .. index - 1."""
        if index < self.delay_frames:
            return float(self.initial_gain)
        floor = 0.5 / ((1 << int(self.bit_depth)) - 1)
        m = max(float(levels[index - self.delay_frames]), floor)
        return float(gains[index - 1] * math.exp(self.loop_gain * math.log(self.target_level / m)))

"""Spectral weight of an LED's colour temperature for a mono silicon camera.

LEDs are specified by luminous power (what the eye sees). A mono CCD weighs the spectrum
by its quantum efficiency instead, so at equal luminous power a warmer (redder) source
gives a different signal. Both curves are modelled smoothly enough for a scalar weight:

* source: a white LED of correlated colour temperature T, modelled as Planck's law
  ``B(lambda, T)`` over the 380-780 nm a phosphor-converted LED emits (no infrared);
* eye: the CIE 1931 photopic curve V(lambda), as the sum of Gaussians of Wyman, Sloan and
  Shirley (2013) for y-bar;
* camera: a front-illuminated silicon CCD QE, an asymmetric Gaussian peaking at 620 nm
  (standard deviation 110 nm on the blue side, 170 nm on the red side; silicon is weak in
  the blue and reaches into the near infrared).

``mono_response(T) = [int B Q / int B V](T) / [int B Q / int B V](5000 K)``.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

__all__ = ["mono_response"]

_LAMBDA_NM = np.arange(380.0, 781.0, 1.0)


def _planck(lam_nm: np.ndarray, T_k: float) -> np.ndarray:
    h, c, k = 6.62607015e-34, 2.99792458e8, 1.380649e-23
    lam = lam_nm * 1e-9
    return (2 * h * c**2 / lam**5) / np.expm1(h * c / (lam * k * T_k))


def _photopic(lam_nm: np.ndarray) -> np.ndarray:
    x = lam_nm
    g = lambda mu, s1, s2: np.exp(-0.5 * ((x - mu) / np.where(x < mu, s1, s2)) ** 2)  # noqa: E731
    return 0.821 * g(568.8, 46.9, 40.5) + 0.286 * g(530.9, 16.3, 31.1)


def _silicon_qe(lam_nm: np.ndarray) -> np.ndarray:
    sigma = np.where(lam_nm < 620.0, 110.0, 170.0)
    return np.exp(-0.5 * ((lam_nm - 620.0) / sigma) ** 2)


@lru_cache(maxsize=256)
def _ratio(T_k: float) -> float:
    b = _planck(_LAMBDA_NM, T_k)
    return float(np.sum(b * _silicon_qe(_LAMBDA_NM)) / np.sum(b * _photopic(_LAMBDA_NM)))


def mono_response(colour_temperature_k: float) -> float:
    """Camera signal per luminous power at ``colour_temperature_k``, relative to 5000 K."""
    return _ratio(float(colour_temperature_k)) / _ratio(5000.0)

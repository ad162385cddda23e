"""Frame normalisation for grazing-LED floor images, shared by the estimators and the mapping.

Real frames are bright at the edges near the LEDs and dark in the middle; the pattern
moves with the camera, so it must be removed before matching (a plain correlation of
two raw frames is pulled toward zero shift). With a flat-field frame of the rig (same
LEDs over a flat uniform floor) the correction is exact: ``image / flatfield``. Without
one, the illumination is estimated by a wide Gaussian blur of the frame itself.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = [
    "flatfield_gain",
    "illumination_corrected",
    "impulses_replaced",
    "to_uint8_contrast",
    "local_contrast_uint8",
    "texture_orientation",
    "mean_orientation",
]


def flatfield_gain(flatfield: np.ndarray) -> np.ndarray:
    """float32 (H, W) gain that divides a rig's LED falloff out of its frames, computed once per run.

    ``flatfield``: (H, W) frame of the rig over a flat uniform floor (any bit depth). The gain is
    ``max / flatfield`` where the flat field is lit (above 0.5 % of its maximum) and 0 where it is
    not; :func:`illumination_corrected` multiplies a frame by it instead of dividing by the flat
    field each frame.
    """
    flat = np.asarray(flatfield, dtype=np.float32)
    flat = flat / (float(flat.max()) or 1.0)
    return np.where(flat > 0.005, 1.0 / np.maximum(flat, 1e-6), 0.0).astype(np.float32)


def illumination_corrected(
    image: np.ndarray,
    flatfield: np.ndarray | None = None,
    blur_sigma_px: float | None = None,
    *,
    blur_downscale: int | None = None,
    gain: np.ndarray | None = None,
) -> np.ndarray:
    """float32 (H, W) image with the LED falloff divided out, mean ~1 where lit.

    ``flatfield``: (H, W) frame of the rig over a flat uniform floor (any bit depth);
    pixels where it is below 0.5 % of its maximum are treated as unlit (value 0).
    ``gain``: :func:`flatfield_gain` of the flat field, computed once (an estimator's frames
    are corrected by one flat field: about 3 ms a 648x494 frame less than passing
    ``flatfield``); it replaces ``flatfield``.
    Without either, the illumination is a Gaussian blur of the frame of ``blur_sigma_px``
    (default: 1/16 of the image size), computed on a copy ``blur_downscale`` times smaller
    (default: sigma / 4; the blur is smooth, so it is scaled back up by linear interpolation).
    """
    img = np.asarray(image, dtype=np.float32)
    if gain is None and flatfield is not None:
        if np.shape(flatfield) != img.shape:
            raise ValueError(f"flatfield shape {np.shape(flatfield)} differs from image shape {img.shape}")
        gain = flatfield_gain(flatfield)
    if gain is not None:
        if gain.shape != img.shape:
            raise ValueError(f"flat-field gain shape {gain.shape} differs from image shape {img.shape}")
        out = img * gain
        n_lit = int(np.count_nonzero(gain))
        m = float(out.sum(dtype=np.float64)) / n_lit if n_lit else 0.0
        if m > 0:
            out *= np.float32(1.0 / m)
        return out
    sigma = blur_sigma_px or max(img.shape) / 16.0
    illum = _blur(img, sigma, int(sigma // 4) if blur_downscale is None else int(blur_downscale))
    out = np.zeros_like(img)
    np.divide(img, illum, out=out, where=illum > 1e-3 * max(float(illum.max()), 1e-12))
    return out


def impulses_replaced(image: np.ndarray, ratio: float = 2.0) -> np.ndarray:
    """float32 (H, W) ``image`` with each pixel brighter than ``ratio`` times its 3 x 3 median
    replaced by that median: a sensor's hot pixels (stuck near full scale) in a frame whose
    LED falloff was divided out (:func:`illumination_corrected`).

    Only bright outliers: under grazing light the floor's own shadows are black pixels beside
    lit ones (a fifth of an asphalt frame is 0), so a dark pixel is no defect by itself, and a
    median of the whole frame, which removes them all, is not shift-equivariant below a pixel
    (it biased phase-corr's steps by 0.25 % on a render whose picture moves rigidly with the
    floor). ``image``: (H, W), non-negative; ``ratio`` > 1."""
    img = np.ascontiguousarray(image, dtype=np.float32)
    med = cv2.medianBlur(img, 3)
    return np.where(img > ratio * med, med, img)


def _blur(img: np.ndarray, sigma_px: float, downscale: int = 1) -> np.ndarray:
    """Gaussian blur of ``sigma_px`` of the float32 (H, W) ``img``; with ``downscale`` f >= 2 computed on an
    f-times smaller copy (area averaging) and scaled back up by linear interpolation: a wide blur is smooth,
    and the copy costs about 1/f^2 of the work."""
    if downscale < 2:
        return cv2.GaussianBlur(img, (0, 0), sigma_px)
    h, w = img.shape
    small = cv2.resize(img, (max(1, w // downscale), max(1, h // downscale)), interpolation=cv2.INTER_AREA)
    return cv2.resize(cv2.GaussianBlur(small, (0, 0), sigma_px / downscale), (w, h), interpolation=cv2.INTER_LINEAR)


def to_uint8_contrast(corrected: np.ndarray, gain_sigma: float = 3.0) -> np.ndarray:
    """Map a corrected image to uint8 with mean 128 and ``gain_sigma`` std devs to the rails."""
    c = np.asarray(corrected, dtype=np.float32)
    mean, std = float(c.mean()), float(c.std())
    if std <= 0:
        return np.full(c.shape, 128, dtype=np.uint8)
    return np.clip(128.0 + (c - mean) * (127.0 / (gain_sigma * std)), 0, 255).astype(np.uint8)


def local_contrast_uint8(image: np.ndarray, sigma_px: float = 6.0, blur_downscale: int = 1) -> np.ndarray:
    """uint8 (H, W) image with the local mean removed and the local contrast equalised.

    ``(img - G(img)) / sqrt(G((img - G(img))^2))`` with ``G`` a Gaussian blur of ``sigma_px``,
    mapped to 128 +/- 40 per local standard deviation. What is left is the texture: a
    brightness that varies smoothly across the frame and differs between two views of the
    same floor (the LED falloff of two cameras of a stereo rig, a flat-field frame that no
    longer fits a tilted rig) cancels, so a Lucas-Kanade alignment of two such images is not
    biased by it (it was by 0.3-0.5 px on a rendered tilted stereo pair). ``blur_downscale``
    f >= 2: both blurs computed on f-times smaller copies (:func:`illumination_corrected`'s
    way; 9.6 -> 2.7 ms of CPU on a 648x494 frame with f = 2), and the median local deviation
    (the regulariser) taken on every f-th row and column.
    """
    f = np.asarray(image, dtype=np.float32)
    hp = f - _blur(f, sigma_px, blur_downscale)
    sd = np.sqrt(_blur(hp * hp, sigma_px, blur_downscale))
    step = max(1, int(blur_downscale))
    eps = 0.05 * float(np.median(sd[::step, ::step])) + 1e-6
    return np.clip(128.0 + 40.0 * hp / (sd + eps), 0, 255).astype(np.uint8)


def texture_orientation(image: np.ndarray, border_px: int = 8) -> tuple[float, float]:
    """The dominant gradient orientation of a floor frame's texture and how dominant it is.

    Returns ``(theta_rad, coherence)``: ``theta_rad`` in (-pi/2, pi/2], the direction of the
    texture's brightness gradients (an axis, not a vector: theta and theta + pi are one) measured
    in the image from its x axis (columns) toward its y axis (rows, downward); ``coherence`` in
    [0, 1]: 0 for a texture without a direction, 1 for parallel stripes. The structure tensor
    ``J = mean(grad grad^T)`` of the frame halved (area averaging) with its LED falloff divided
    out (:func:`illumination_corrected`, its own blur), over all but ``border_px`` px of the
    halved frame's edges: ``theta = atan2(2 Jxy, Jxx - Jyy) / 2``, ``coherence = sqrt((Jxx -
    Jyy)^2 + 4 Jxy^2) / (Jxx + Jyy)`` (Bigun and Granlund's), the gradients by Scharr's kernel. A grained floor (wood: 0.9) turns
    theta with the floor; under the rig's grazing light a floor without grain (concrete, vinyl,
    asphalt: 0.2-0.4) shows the light's own direction, which turns with the camera: theta stays
    put. ``image``: (H, W) mono, any bit depth. 0.9 ms of CPU on a 648x494 frame.
    """
    img = np.asarray(image, dtype=np.float32)
    h, w = img.shape
    half = cv2.resize(img, (max(1, w // 2), max(1, h // 2)), interpolation=cv2.INTER_AREA)
    a = illumination_corrected(half)
    gx = cv2.Scharr(a, cv2.CV_32F, 1, 0)  # Scharr's kernel: within 0.3 degrees of any direction (3x3 Sobel: 4)
    gy = cv2.Scharr(a, cv2.CV_32F, 0, 1)
    b = int(border_px)
    if min(a.shape) > 2 * b + 2:
        gx, gy = gx[b:-b, b:-b], gy[b:-b, b:-b]
    jxx, jyy, jxy = float(np.mean(gx * gx)), float(np.mean(gy * gy)), float(np.mean(gx * gy))
    trace = jxx + jyy
    if trace <= 0:
        return 0.0, 0.0
    return 0.5 * float(np.arctan2(2.0 * jxy, jxx - jyy)), float(np.hypot(jxx - jyy, 2.0 * jxy) / trace)


def mean_orientation(theta_a_rad: float | np.ndarray, theta_b_rad: float | np.ndarray) -> float | np.ndarray:
    """The mean of two axis orientations (rad; theta and theta + pi are one, :func:`texture_orientation`),
    taken on the doubled-angle circle: in (-pi/2, pi/2]; the mean of -89 and +89 degrees is 90, not 0."""
    z = np.exp(2j * np.asarray(theta_a_rad, float)) + np.exp(2j * np.asarray(theta_b_rad, float))
    out = 0.5 * np.angle(z)
    return float(out) if np.ndim(out) == 0 else out

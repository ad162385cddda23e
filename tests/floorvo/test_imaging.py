"""Frame normalisation (floorvo.imaging): the flat-field correction against a hand computation."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from floorvo.estimators.base import frame_is_blank
from floorvo.imaging import (
    flatfield_gain,
    illumination_corrected,
    impulses_replaced,
    local_contrast_uint8,
    mean_orientation,
    texture_orientation,
)


def test_flatfield_gain_corrects_as_dividing_by_the_flat_field():
    """``image / (flatfield / max)`` over its mean where the flat field is lit (above 0.5 % of its
    maximum), 0 where it is not, computed in double by hand: the same from the gain computed once
    (:func:`flatfield_gain`) as from the flat field passed each frame."""
    rng = np.random.default_rng(3)
    flat = rng.integers(2000, 60000, size=(40, 52)).astype(np.uint16)
    flat[:3, :] = 100  # unlit: under 0.5 % of the maximum
    image = rng.integers(0, 255, size=(40, 52)).astype(np.uint8)
    f = flat.astype(np.float64) / flat.max()
    lit = f > 0.005
    expected = np.where(lit, image / np.where(lit, f, 1.0), 0.0)
    expected /= expected[lit].mean()
    gain = flatfield_gain(flat)
    assert gain.dtype == np.float32 and np.all(gain[:3] == 0) and np.all(gain[3:] > 0)
    for out in (illumination_corrected(image, gain=gain), illumination_corrected(image, flat)):
        assert out.dtype == np.float32
        np.testing.assert_allclose(out, expected, rtol=2e-6, atol=1e-7)
    with pytest.raises(ValueError, match="gain shape"):
        illumination_corrected(image[:, :50], gain=gain)


def test_local_contrast_with_downscaled_blurs_is_the_exact_one_within_a_few_levels():
    """``blur_downscale=2`` (stereo-sift-fast's local-contrast images) computes the two wide blurs
    on half-size copies: the texture image stays the exact one's within a grey level or two, on a
    textured frame under a steep brightness ramp (which both remove)."""
    from _synth import floor_texture

    tex = floor_texture(300, 5)[:200, :260].astype(np.float32)
    ramp = np.linspace(0.3, 1.0, 260, dtype=np.float32)[None, :]
    img = tex * ramp
    exact = local_contrast_uint8(img).astype(float)
    fast = local_contrast_uint8(img, blur_downscale=2).astype(float)
    inner = (slice(20, -20), slice(20, -20))  # the blurs' borders are resampled differently
    diff = np.abs(fast - exact)[inner]
    # (a blur of sigma 4 or 9 px instead of 6, exact, is 1.5-2.3 levels off on average, 5-8 at the 99th percentile)
    assert np.mean(diff) < 0.3 and np.percentile(diff, 99) <= 2
    assert np.corrcoef(fast[inner].ravel(), exact[inner].ravel())[0, 1] > 0.9999


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
def test_frame_is_blank_as_a_zero_standard_deviation(dtype):
    rng = np.random.default_rng(0)
    flat = np.full((5, 7), 9, dtype=dtype)
    textured = rng.integers(0, 200, size=(5, 7)).astype(dtype)
    one_pixel = flat.copy()
    one_pixel[2, 3] = 10
    for img in (flat, textured, one_pixel):
        assert frame_is_blank(img) == (float(img.std()) == 0.0)


def test_impulses_replaced_changes_only_the_hot_pixels():
    """A smooth normalised frame (a ramp and a sine around 1) with one pixel stuck high (3.0)
    and one at zero: the bright one becomes its 3 x 3 median; the dark one is left (under
    grazing light the floor's own shadows are black pixels), and so is every other pixel, bit
    for bit (a plain median would change them all)."""
    v, u = np.mgrid[0:40, 0:50].astype(np.float32)
    img = (1.0 + 0.004 * u + 0.1 * np.sin(0.3 * v)).astype(np.float32)
    bad = img.copy()
    bad[10, 20], bad[30, 5] = 3.0, 0.0
    out = impulses_replaced(bad)
    assert out.dtype == np.float32
    assert np.argwhere(out != bad).tolist() == [[10, 20]]
    neighbours = np.sort(bad[9:12, 19:22].ravel())
    assert out[10, 20] == neighbours[4]  # the 3 x 3 median
    assert out[10, 20] == pytest.approx(img[10, 20], rel=0.02)
    np.testing.assert_array_equal(impulses_replaced(img), img)


def _grating(angle_rad: float, shape=(124, 162), period_px: float = 9.0, falloff: bool = True) -> np.ndarray:
    """uint8 stripes whose brightness varies along ``angle_rad`` (from the image x axis toward y, rows
    down), under an LED-like falloff that rises toward the left edge."""
    y, x = np.mgrid[: shape[0], : shape[1]].astype(float)
    s = np.sin(2 * np.pi * (x * np.cos(angle_rad) + y * np.sin(angle_rad)) / period_px)
    light = 1.5 - x / shape[1] if falloff else 1.0
    return np.clip(100 * light * (1 + 0.4 * s), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("angle_deg", [-80.0, -30.0, 0.0, 25.0, 60.0, 89.0])
def test_texture_orientation_of_stripes_is_their_gradient_direction(angle_deg):
    """Stripes whose brightness varies along a direction: that direction (mod 180 degrees),
    within a degree, the LED falloff divided out, and a coherence near 1."""
    theta, coherence = texture_orientation(_grating(np.radians(angle_deg)))
    err = (np.degrees(theta) - angle_deg + 90.0) % 180.0 - 90.0
    assert abs(err) < 1.0 and coherence > 0.9


def test_texture_orientation_turns_with_the_picture_and_has_no_direction_in_noise():
    """Turning a textured picture by 30 degrees about its centre turns the orientation by 30
    (rows down: a positive cv2 angle turns the content the other way); white noise has none."""
    rng = np.random.default_rng(0)
    base = _grating(np.radians(10.0), shape=(300, 300), falloff=False).astype(np.float32)
    base += rng.normal(0, 10, base.shape).astype(np.float32)
    R = cv2.getRotationMatrix2D((149.5, 149.5), 30.0, 1.0)
    turned = cv2.warpAffine(base, R, (300, 300), flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
    a, _ = texture_orientation(base[60:240, 60:240])
    b, _ = texture_orientation(turned[60:240, 60:240])
    assert np.degrees(a - b) == pytest.approx(30.0, abs=1.0)
    _, coherence = texture_orientation(rng.normal(128, 20, (124, 162)).clip(0, 255).astype(np.uint8))
    assert coherence < 0.1


def test_mean_orientation_is_taken_on_the_doubled_circle():
    """Axes, not vectors: -89 and +89 degrees average to 90 (not 0); 10 and 30 to 20."""
    assert np.degrees(mean_orientation(np.radians(-89.0), np.radians(89.0))) == pytest.approx(90.0)
    assert np.degrees(mean_orientation(np.radians(10.0), np.radians(30.0))) == pytest.approx(20.0)

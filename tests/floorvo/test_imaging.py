"""Frame normalisation (floorvo.imaging): the flat-field correction against a hand computation."""

from __future__ import annotations

import numpy as np
import pytest

from floorvo.imaging import flatfield_gain, illumination_corrected


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

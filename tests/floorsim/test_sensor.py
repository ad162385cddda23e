"""Sensor model: exposure from a percentile, shot and read noise, quantisation, saturation, seeds."""

import numpy as np
import pytest

from floorsim.sensor import SensorModel, exposure_gain


def test_exposure_puts_percentile_at_target_level():
    rng = np.random.default_rng(0)
    rad = rng.gamma(2.0, 1.0, size=(60, 80))
    gain = exposure_gain(rad, full_well_e=10000.0, target_percentile=99.0, target_level=0.8)
    dn = SensorModel(gain, 10000.0, 0.0, False, 8).capture(rad, 0, 0, noise=False)
    # Hand computation: the 99th percentile maps to 0.8 * 255 = 204 DN.
    assert np.percentile(dn, 99) == pytest.approx(204, abs=1)
    assert (dn == 255).mean() < 0.01  # only the top 1 % can exceed 204 and few reach 255
    assert exposure_gain(np.zeros((4, 4)), 10000.0, 99.0, 0.8) == 0.0  # a black frame gives no exposure


def test_noise_free_capture_is_linear_then_saturates():
    s = SensorModel(gain_e_per_unit=1000.0, full_well_e=10000.0, read_noise_e=0.0, shot_noise=False, bit_depth=8)
    rad = np.array([[0.0, 1.0, 5.0, 10.0, 20.0, -1.0]])
    dn = s.capture(rad, 0, 0, noise=False)
    assert dn.dtype == np.uint8
    np.testing.assert_array_equal(dn, [[0, 26, 128, 255, 255, 0]])  # round(e / 10000 * 255), clipped, no wrap-around


def test_sixteen_bit_quantisation():
    s = SensorModel(1000.0, 10000.0, 0.0, False, 16)
    dn = s.capture(np.array([[5.0, 10.0, 1e6]]), 0, 0, noise=False)
    assert dn.dtype == np.uint16
    np.testing.assert_array_equal(dn, [[round(0.5 * 65535), 65535, 65535]])


def test_shot_and_read_noise_statistics():
    # 2000 electrons: shot-noise sigma = sqrt(2000) = 44.7 e-; with 20 e- read noise: sqrt(2000 + 400).
    s = SensorModel(gain_e_per_unit=1.0, full_well_e=10000.0, read_noise_e=20.0, shot_noise=True, bit_depth=16)
    rad = np.full((200, 200), 2000.0)
    dn = s.capture(rad, 5, 0).astype(np.float64)
    e = dn / 65535 * 10000.0
    assert e.mean() == pytest.approx(2000.0, rel=0.005)
    assert e.std() == pytest.approx(np.sqrt(2000.0 + 400.0), rel=0.03)
    s_read = SensorModel(1.0, 10000.0, 20.0, False, 16)
    e_read = s_read.capture(rad, 5, 0).astype(np.float64) / 65535 * 10000.0
    assert e_read.std() == pytest.approx(20.0, rel=0.03)


def test_noise_seeded_per_frame():
    s = SensorModel(1.0, 10000.0, 5.0, True, 8)
    rad = np.full((50, 50), 3000.0)
    a = s.capture(rad, seed=1, frame_index=3)
    np.testing.assert_array_equal(a, s.capture(rad, seed=1, frame_index=3))  # independent of call history
    assert not np.array_equal(a, s.capture(rad, seed=2, frame_index=3))
    assert not np.array_equal(a, s.capture(rad, seed=1, frame_index=4))
    np.testing.assert_array_equal(s.capture(rad, 1, 3, noise=False), s.capture(rad, 9, 9, noise=False))

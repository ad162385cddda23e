"""Sensor model: exposure from a percentile, shot and read noise, quantisation, saturation, seeds."""

import numpy as np
import pytest

from floorsim.sensor import AutoExposure, FixedPattern, SensorModel, exposure_gain


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


def test_a_count_beyond_what_numpy_draws_saturates():
    """sensor.exposure_gain = 1e308 ended a render in numpy's 'lam value too large' traceback;
    a pixel far above the full well saturates whatever its shot noise."""
    s = SensorModel(gain_e_per_unit=1e20, full_well_e=10000.0, read_noise_e=5.0, shot_noise=True, bit_depth=8)
    dn = s.capture(np.array([[0.0, 1.0, 1e10, np.inf]]), 0, 0)
    np.testing.assert_array_equal(dn[0, 1:], [255, 255, 255])


def test_noise_seeded_per_frame():
    s = SensorModel(1.0, 10000.0, 5.0, True, 8)
    rad = np.full((50, 50), 3000.0)
    a = s.capture(rad, seed=1, frame_index=3)
    np.testing.assert_array_equal(a, s.capture(rad, seed=1, frame_index=3))  # independent of call history
    assert not np.array_equal(a, s.capture(rad, seed=2, frame_index=3))
    assert not np.array_equal(a, s.capture(rad, seed=1, frame_index=4))
    np.testing.assert_array_equal(s.capture(rad, 1, 3, noise=False), s.capture(rad, 9, 9, noise=False))


def test_default_model_is_the_linear_model_of_before():
    """With no fixed pattern and gamma 1 the capture is byte for byte the earlier linear model,
    written out here: Poisson, then read noise, from the same generator, then round(clip(e / fw) x max)."""
    rad = np.random.default_rng(4).gamma(2.0, 1.0, size=(30, 40))
    for bits in (8, 16):
        s = SensorModel(700.0, 10000.0, 5.0, True, bits)
        rng = np.random.default_rng([11, 2, 0x5E50])
        e = rng.poisson(np.maximum(rad * 700.0, 0.0)).astype(np.float64)
        e = e + rng.normal(0.0, 5.0, size=e.shape)
        old = np.round(np.clip(e / 10000.0, 0.0, 1.0) * ((1 << bits) - 1))
        np.testing.assert_array_equal(s.capture(rad, 11, 2), old)


def test_prnu_and_dsnu_have_their_spread_and_stay_fixed():
    fp = FixedPattern(prnu=0.02, dsnu_e=40.0)
    s = SensorModel(1.0, 10000.0, 0.0, False, 16, fp)
    flat = np.full((200, 200), 5000.0)
    e = s.capture(flat, seed=3, frame_index=0, noise=False) / 65535 * 10000.0
    # e = 5000 (1 + 0.02 P) + 40 D: spread sqrt(100^2 + 40^2) e- (P, D independent standard normals).
    assert e.std() == pytest.approx(np.hypot(100.0, 40.0), rel=0.03)
    assert e.mean() == pytest.approx(5000.0, abs=2.0)
    np.testing.assert_array_equal(e, s.capture(flat, seed=3, frame_index=9, noise=False) / 65535 * 10000.0)
    assert not np.array_equal(e, s.capture(flat, seed=4, frame_index=0, noise=False) / 65535 * 10000.0)
    dark = SensorModel(1.0, 10000.0, 0.0, False, 16, FixedPattern(dsnu_e=40.0)).capture(flat * 0 + 1000.0, 3, 0, False)
    assert (dark / 65535 * 10000.0).std() == pytest.approx(40.0, rel=0.03)  # DSNU alone: offsets of 40 e-
    # Raising the PRNU scales the same pattern (maps drawn in a fixed order).
    twice = SensorModel(1.0, 10000.0, 0.0, False, 16, FixedPattern(prnu=0.04, dsnu_e=40.0)).capture(flat, 3, 0, False)
    d1, d2 = e - 5000.0, twice / 65535 * 10000.0 - 5000.0
    assert np.corrcoef(d1.ravel(), d2.ravel())[0, 1] > 0.9


def test_hot_and_dead_pixels_are_stuck():
    fp = FixedPattern(hot_pixel_fraction=0.01, dead_pixel_fraction=0.02)
    s = SensorModel(1.0, 10000.0, 5.0, True, 8, fp)
    a = s.capture(np.full((300, 300), 5000.0), seed=1, frame_index=0)
    b = s.capture(np.full((300, 300), 100.0), seed=1, frame_index=5)
    assert (a == 255).mean() == pytest.approx(0.01, abs=0.002)
    assert (a == 0).mean() == pytest.approx(0.02, abs=0.003)
    np.testing.assert_array_equal(a == 255, b == 255)  # stuck wherever the light
    np.testing.assert_array_equal(a == 0, b == 0)


def test_gamma_response_by_hand():
    s = SensorModel(1000.0, 10000.0, 0.0, False, 8, gamma=2.0)
    # e / full well = 0.36, 0.04, 1: DN = round(sqrt(.) * 255) = 153, 51, 255.
    np.testing.assert_array_equal(s.capture(np.array([[3.6, 0.4, 10.0]]), 0, 0, noise=False), [[153, 51, 255]])


def test_auto_exposure_converges_and_reacts_after_its_delay():
    # A constant scene whose level is proportional to the gain: m = 0.2 at g = 1.
    for k in (1.0, 0.5):
        ae = AutoExposure(1.0, target_level=0.8, loop_gain=k, delay_frames=1)
        gains, levels = [], []
        for i in range(12):
            gains.append(ae.next_gain(i, gains, levels))
            levels.append(0.2 * gains[-1])
        if k == 1.0:
            assert gains[1] == pytest.approx(4.0)  # dead-beat: one frame
        # log error shrinks by (1 - k) per frame
        err = np.abs(np.log(np.array(levels) / 0.8))
        assert err[-1] < 1e-3 and (k == 1.0 or err[3] == pytest.approx(err[2] * 0.5, rel=1e-9))
    # A step in the light at frame 5 reaches the exposure at frame 5 + delay, not before.
    ae = AutoExposure(4.0, target_level=0.8, loop_gain=1.0, delay_frames=3)
    gains, levels = [], []
    for i in range(12):
        gains.append(ae.next_gain(i, gains, levels))
        levels.append(min(1.0, (0.2 if i < 5 else 0.1) * gains[-1]))  # the floor turns darker
    assert gains[:8] == [4.0] * 8 and gains[8] == pytest.approx(8.0)
    assert AutoExposure(1.0).next_gain(1, [1.0], [0.0]) == pytest.approx((0.8 / (0.5 / 255)) ** 0.5)  # black frame

"""Camera and lighting effects change the picture the way physics says (tiny renders)."""

import json

import numpy as np
import pytest
from _tiny import tiny_scene

from floorsim.depthnoise import DepthNoise, apply_depth_noise
from floorsim.simulate import render_sequence
from floorvo.sequence import Sequence
from floorvo.sequence_meta import check_sequence_meta

render = pytest.mark.render


def _gain(root) -> float:
    return json.loads((root / "calib" / "sensor.json").read_text())["gain_e_per_unit"]


@render
def test_vignetting_darkens_the_corners_by_cos4(tmp_path):
    base = render_sequence(tiny_scene(**{"trajectory.distance_mm": 4.0}), tmp_path / "a")
    g = _gain(base)
    vig = render_sequence(
        tiny_scene(**{"trajectory.distance_mm": 4.0, "camera.vignetting": 1.0, "sensor.exposure_gain": g}),
        tmp_path / "b",
    )
    fa = Sequence.open(base).flatfield().astype(float)
    fb = Sequence.open(vig).flatfield().astype(float)
    cam = Sequence.open(base).camera
    ratio = fb / np.maximum(fa, 1)
    theta_corner = np.arctan(np.hypot(cam.cx_px + 0.5, cam.cy_px + 0.5) / cam.fx_px)
    assert ratio[0, 0] == pytest.approx(np.cos(theta_corner) ** 4, abs=0.01)
    assert ratio[62, 81] == pytest.approx(1.0, abs=0.002)


@render
def test_flicker_varies_frame_brightness_only_when_asked(tmp_path):
    steady = render_sequence(tiny_scene(**{"trajectory.distance_mm": 8.0}), tmp_path / "s")
    g = _gain(steady)
    flick = render_sequence(
        tiny_scene(**{"trajectory.distance_mm": 8.0, "lights.flicker": 0.3, "sensor.exposure_gain": g}), tmp_path / "f"
    )
    ms = [Sequence.open(steady).image(i).astype(float).mean() for i in range(3)]
    mf = [Sequence.open(flick).image(i).astype(float).mean() for i in range(3)]
    assert np.ptp(ms) / np.mean(ms) < 0.02
    assert np.ptp(np.array(mf) / np.array(ms)) > 0.05


@render
def test_motion_blur_smears_along_the_motion_not_across(tmp_path):
    kw = {"trajectory.distance_mm": 8.0, "trajectory.step_mm": 4.0, "sensor.noise": False}
    sharp = Sequence.open(render_sequence(tiny_scene(**kw), tmp_path / "sharp"))
    # 4 mm/frame at 30 fps = 120 mm/s; 20 ms exposure smears 2.4 mm = ~5 px along x.
    blur = Sequence.open(
        render_sequence(
            tiny_scene(**kw, **{"sensor.exposure_ms": 20.0, "sensor.exposure_gain": _gain(sharp.root)}),
            tmp_path / "blur",
        )
    )

    def energy(seq, axis):
        c = seq.image(1).astype(float) / np.maximum(seq.flatfield().astype(float), 1)
        c = c[30:94, 40:122]
        return float(np.mean(np.diff(c, axis=axis) ** 2) / c.var())

    # Averaging along x damps every texture component with an x frequency, so the
    # gradient across the motion loses some energy too; along the motion it loses far more.
    along = energy(blur, 1) / energy(sharp, 1)
    across = energy(blur, 0) / energy(sharp, 0)
    assert along < 0.5
    assert along < 0.6 * across
    # sequence.json says so: the exposure time, centred on the frame time; an instantaneous
    # global shutter keeps the older metadata (no sensor block).
    block = check_sequence_meta(blur.meta).sensor_block
    assert block.exposure_ms == 20.0 and block.shutter == "global" and block.exposure_mode == "fixed"
    assert "sensor" not in sharp.meta and check_sequence_meta(sharp.meta).sensor_block.exposure_ms is None


def test_depth_noise_follows_its_formula():
    z = np.full((50, 60), 400.0)
    p = DepthNoise(model="structured_light", baseline_mm=50.0, focal_px=580.0, subpixel=8.0, sigma_px=0.0, dropout=0.0)
    out = apply_depth_noise(z, p, seed=1, frame_index=0)
    fb = 580.0 * 50.0
    assert np.all(out == np.float32(fb / (np.round(fb / 400.0 * 8) / 8)))
    noisy = apply_depth_noise(
        z, DepthNoise(model="structured_light", sigma_px=0.5, subpixel=64.0, dropout=0.1), seed=1, frame_index=0
    )
    valid = noisy > 0
    assert valid.mean() == pytest.approx(0.9, abs=0.03)
    # sigma_z = z^2 / (f B) sigma_d
    assert noisy[valid].std() == pytest.approx(400.0**2 / fb * 0.5, rel=0.1)
    again = apply_depth_noise(
        z, DepthNoise(model="structured_light", sigma_px=0.5, subpixel=64.0, dropout=0.1), seed=1, frame_index=0
    )
    np.testing.assert_array_equal(noisy, again)
    step = np.zeros((10, 10)) + 100.0
    step[:, 5:] = 150.0
    edged = apply_depth_noise(step, DepthNoise(model="structured_light", sigma_px=0.0), seed=0, frame_index=0)
    assert np.all(edged[:, 5] == 0) and np.all(edged[:, 2] > 0)


@render
def test_ambient_leak_raises_the_dark_level(tmp_path):
    kw = {"trajectory.distance_mm": 4.0, "sensor.noise": False}
    dark = render_sequence(tiny_scene(**kw), tmp_path / "dark")
    g = _gain(dark)
    leak = render_sequence(
        tiny_scene(**kw, **{"lights.ambient_leak": 0.5, "sensor.exposure_gain": g}), tmp_path / "leak"
    )
    a = Sequence.open(dark).image(0).astype(float)
    b = Sequence.open(leak).image(0).astype(float)
    lo = a < np.percentile(a, 10)  # the darkest pixels (shadows, image centre)
    assert (b[lo] - a[lo]).mean() > 3.0
    assert np.percentile(b, 1) > np.percentile(a, 1)


@render
def test_specular_floor_highlights_move_with_the_led(tmp_path):
    """A glossy floor lit by one bar shows a highlight on the far side of the image (mirror
    direction); switching to the other bar moves it to the other side. A matte floor does not."""
    peaks = {}
    for mat in ("polished", "featureless"):
        for side in ("left", "right"):
            kw = {"floor.material": mat, "lights.side": side, "trajectory.distance_mm": 4.0, "sensor.noise": False}
            seq = Sequence.open(render_sequence(tiny_scene(**kw), tmp_path / f"{mat}-{side}"))
            c = seq.image(0).astype(float) / np.maximum(seq.flatfield().astype(float), 1)
            cols = c[30:94].mean(axis=0)
            peaks[mat, side] = (int(np.argmax(cols[10:-10])) + 10, float(cols.max() / np.median(cols)))
    w = 162
    # Light from the left reflects towards the camera on the right half, and vice versa.
    assert peaks["polished", "left"][0] > w / 2 and peaks["polished", "right"][0] < w / 2
    # The mirror point of a 3 mm-high LED lies just beyond the image edge: inside the image
    # the glossy lobe's flank raises the far side, which the matte floor does not show.
    assert peaks["polished", "left"][1] > peaks["featureless", "left"][1] + 0.1
    assert peaks["polished", "right"][1] > peaks["featureless", "right"][1] + 0.1

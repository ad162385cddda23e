"""Rolling shutter, auto exposure and the fixed pattern on tiny renders (162x124)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from _tiny import tiny_scene
from skimage.registration import phase_cross_correlation

from floorsim.materials import sample_material
from floorsim.render import FloorRenderer, LedArray
from floorsim.sensor import image_level
from floorsim.simulate import render_sequence
from floorvo.imaging import illumination_corrected
from floorvo.sequence import Sequence
from floorvo.sequence_meta import check_sequence_meta, rolling_row_offsets_s

pytestmark = pytest.mark.render

#: 4 mm per frame at 30 fps: 120 mm/s along the world x axis.
STRAIGHT = {"trajectory.distance_mm": 8.0, "trajectory.step_mm": 4.0}


def _gain(root) -> float:
    return json.loads((root / "calib" / "sensor.json").read_text())["gain_e_per_unit"]


def _renderer(scene) -> FloorRenderer:
    """A renderer over a 100 x 80 mm vinyl tile about the origin (the tiny camera sees 80 x 61 mm)."""
    r = FloorRenderer(scene.camera_model())
    s = 0.25
    xs, ys = np.arange(-200, 201) * s, np.arange(-160, 161) * s
    h, a = sample_material("vinyl", xs, ys, 1, {}, 1.0)
    r.load_heightfield(xs[0], ys[0], s, h, a)
    return r


def _leds(T: np.ndarray) -> LedArray:
    p = T[:3, :3] @ np.array([[-70.0, 0, 97], [70.0, 0, 97]]).T + T[:3, 3:4]
    aim = np.array([T[0, 3], T[1, 3], 0.0]) - p.T
    return LedArray(p.T, aim / np.linalg.norm(aim, axis=1, keepdims=True), np.array([1000.0, 1000.0]))


def _T(x_mm: float) -> np.ndarray:
    T = np.diag([1.0, -1.0, -1.0, 1.0])  # looking straight down
    T[:3, 3] = (x_mm, 0.0, 100.0)
    return T


def test_one_pose_per_row_traces_each_row_from_its_pose():
    """Row r of a per-row render is row r of a render from pose r alone (the same float32 rays),
    and a per-row render whose rows share one pose is that pose's image bit for bit."""
    scene = tiny_scene()
    r = _renderer(scene)
    h = scene.camera.height_px
    T = _T(0.0)
    still = r.render(T, _leds(T), 4, seed=7)
    np.testing.assert_array_equal(r.render(np.repeat(T[None], h, 0), _leds(T), 4, seed=7), still)
    xs = np.linspace(-3.0, 3.0, h)
    Ts = np.stack([_T(x) for x in xs])
    leds_rows = [_leds(t) for t in Ts]
    rows = LedArray(
        np.stack([x.positions_mm for x in leds_rows]), np.stack([x.aim for x in leds_rows]), _leds(T).intensity
    )
    sheared = r.render(Ts, rows, 4, seed=7)
    for row in (0, 40, h - 1):
        alone = r.render(Ts[row], leds_rows[row], 4, seed=7)
        np.testing.assert_allclose(sheared[row], alone[row], rtol=1e-6, atol=1e-9)
    assert np.abs(sheared[0] - still[0]).max() > 0.05 * still.max()  # row 0 is elsewhere


def test_rolling_shutter_shears_a_straight_run_by_speed_times_readout(tmp_path):
    """Each row band of a rolling-shutter frame is displaced against the global-shutter frame of the
    same time by the floor motion during its row offset: v x readout x (r - (H-1)/2) / (H-1).
    Across the frame that is the shear v x readout (120 mm/s x 30 ms = 3.6 mm = 7.3 px here)."""
    kw = {**STRAIGHT, "render.spp": 16}
    gs = Sequence.open(render_sequence(tiny_scene(**kw), tmp_path / "gs"))
    rs_root = render_sequence(
        tiny_scene(**kw, **{"sensor.readout_ms": 30.0, "sensor.exposure_gain": _gain(gs.root)}), tmp_path / "rs"
    )
    rs = Sequence.open(rs_root)
    meta = json.loads((rs_root / "sequence.json").read_text())
    block = check_sequence_meta(meta).sensor_block
    assert block.shutter == "rolling" and block.groundtruth_row == 61.5 and block.readout_ms == 30.0
    assert check_sequence_meta(json.loads((gs.root / "sequence.json").read_text())).sensor_block.shutter == "global"
    # Ground truth is the centre row's pose: the same as the global-shutter sequence's.
    np.testing.assert_array_equal((rs_root / "groundtruth.txt").read_text(), (gs.root / "groundtruth.txt").read_text())
    cam = gs.camera
    gsd = cam.gsd_mm_per_px(100.0)
    speed_mm_s = 4.0 * 30.0
    a = illumination_corrected(gs.image(1), gs.flatfield())
    b = illumination_corrected(rs.image(1), rs.flatfield())
    # Bands of 8 rows (0.5 px of shear inside each): the shift of each against the global frame.
    centres, shifts = [], []
    for r0 in range(2, 116, 8):
        shift, _, _ = phase_cross_correlation(a[r0 : r0 + 8, 10:152], b[r0 : r0 + 8, 10:152], upsample_factor=50)
        assert abs(shift[0]) < 0.2  # no motion across the run
        centres.append(r0 + 3.5)
        shifts.append(shift[1])
    slope_px_per_row, at_row0 = np.polyfit(centres, shifts, 1)
    # The camera's x axis is the world's x (looking down, T_world_cam_down): a row exposed dt later
    # sees the floor v dt further on; registering it onto the global frame moves it by +v dt / gsd.
    offsets = rolling_row_offsets_s(cam.height_px, 30.0)
    np.testing.assert_allclose(
        shifts, speed_mm_s * np.interp(centres, np.arange(cam.height_px), offsets) / gsd, atol=0.25
    )
    assert slope_px_per_row * (cam.height_px - 1) * gsd == pytest.approx(speed_mm_s * 0.030, rel=0.02)  # the shear
    assert at_row0 + slope_px_per_row * 61.5 == pytest.approx(0.0, abs=0.1)  # the centre row is the frame time


def test_auto_exposure_follows_the_previous_frame_and_resumes(tmp_path):
    """Each frame's gain (calib/exposure.csv) is the last one corrected by the metered level of the frame
    before, recomputed here from the frames on disk; a resume renders on from the first missing frame."""
    kw = {"trajectory.distance_mm": 12.0, "lights.flicker": 0.5, "sensor.exposure_mode": "auto"}
    kw |= {"sensor.ae_loop_gain": 0.7}
    root = render_sequence(tiny_scene(**kw), tmp_path / "ae")
    seq = Sequence.open(root)
    rows = [line.split(",") for line in (root / "calib" / "exposure.csv").read_text().splitlines()[1:]]
    gains = [float(r[1]) for r in rows]
    assert [int(r[0]) for r in rows] == [0, 1, 2, 3]
    assert gains[0] == _gain(root)
    levels = [image_level(seq.image(i), 8, 99.0) for i in range(4)]
    assert [float(r[2]) for r in rows] == levels
    for i in range(1, 4):
        assert gains[i] == pytest.approx(gains[i - 1] * (0.8 / levels[i - 1]) ** 0.7, rel=1e-12)
    assert np.ptp(gains) > 0.05 * gains[0]  # the flicker made it move
    block = check_sequence_meta(json.loads((root / "sequence.json").read_text())).sensor_block
    assert block.exposure_mode == "auto" and block.exposure_file == "calib/exposure.csv"
    # The flat-field frame is at the first frame's exposure: the one a fixed-exposure render chooses.
    fixed = render_sequence(tiny_scene(**{**kw, "sensor.exposure_mode": "fixed"}), tmp_path / "fixed")
    assert _gain(fixed) == gains[0]
    np.testing.assert_array_equal(seq.flatfield(), Sequence.open(fixed).flatfield())
    before = [seq.image(i) for i in range(4)]
    (root / "cam0" / "000002.png").unlink()
    render_sequence(tiny_scene(**kw), root)
    for i in range(4):
        np.testing.assert_array_equal(Sequence.open(root).image(i), before[i])


def test_fixed_pattern_is_the_same_in_every_frame(tmp_path):
    kw = {"sensor.bit_depth": 16, "sensor.hot_pixel_fraction": 0.002, "sensor.dead_pixel_fraction": 0.002}
    plain = Sequence.open(render_sequence(tiny_scene(**{"sensor.bit_depth": 16}), tmp_path / "p"))
    fpn = Sequence.open(
        render_sequence(
            tiny_scene(**kw, **{"sensor.prnu": 0.05, "sensor.exposure_gain": _gain(plain.root)}), tmp_path / "f"
        )
    )
    # The pixels stuck at full scale or at zero in frame 0 (and not in the sequence without the pattern)
    # are stuck in frame 1 too.
    hot = (fpn.image(0) == 65535) & (plain.image(0) < 60000)
    dead = (fpn.image(0) == 0) & (plain.image(0) > 0)
    assert 0.001 < hot.mean() < 0.004 and 0.001 < dead.mean() < 0.004
    assert (fpn.image(1)[hot] == 65535).all() and (fpn.image(1)[dead] == 0).all()
    ok = ~(hot | dead)
    for i in range(2):  # lit and below saturation in both frames
        ok &= (plain.image(i) > 2000) & (plain.image(i) < 60000) & (fpn.image(i) < 65535)
    gain = [fpn.image(i)[ok] / plain.image(i)[ok].astype(float) for i in range(2)]  # the pixels' gains
    assert gain[0].std() == pytest.approx(0.05, rel=0.1)
    np.testing.assert_allclose(gain[0], gain[1], atol=2e-3)  # fixed: the same in the next frame


@pytest.mark.parametrize(
    "over, message",
    [
        ({"sensor.readout_ms": 40.0}, "sensor.readout_ms = 40.0 ms: a rolling shutter reads out within a frame period"),
        # a 1 s exposure at 30 fps rendered, exit 0
        ({"sensor.exposure_ms": 1000.0}, "sensor.exposure_ms = 1000.0 ms: an exposure fits within a frame period"),
        ({"sensor.exposure_mode": "auto", "sensor.target_level": 0.0}, "sensor.target_level = 0.0: auto exposure"),
        ({"sensor.exposure_mode": "manual"}, "sensor.exposure_mode = 'manual': must be one of"),
        ({"sensor.gamma": 0.0}, "sensor.gamma = 0.0"),
        ({"sensor.prnu": -0.1}, "sensor.prnu = -0.1"),
    ],
)
def test_impossible_sensor_settings_are_refused_in_one_line(over, message):
    from floorvo.errors import ConfigError

    with pytest.raises(ConfigError) as info:
        tiny_scene(**over)
    assert message in str(info.value) and "\n" not in str(info.value)

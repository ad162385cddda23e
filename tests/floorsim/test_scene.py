"""Scene files: loading, overrides, refusal of bad input by name."""

import subprocess
import sys
import tomllib

import numpy as np
import pytest
from _tiny import TINY_SCENE, tiny_scene

from floorsim.scene import load_scene, scene_from_dict, scenes_dir
from floorvo.errors import ConfigError


def test_shipped_scenes_load():
    for name in ("demo", "paper000_uniform", "paper000_sigmoid_g125", "paper000_sigmoid_g175"):
        s = load_scene(name)
        assert s.name == name
        assert s.build_trajectory().frame_count > 1
    s = load_scene("paper000_uniform")
    assert (s.camera.width_px, s.camera.height_px) == (648, 494)
    assert s.camera_model().gsd_mm_per_px(100.0) == pytest.approx(0.12333, abs=1e-5)
    assert s.build_trajectory().frame_count == 26


def test_set_overrides():
    s = load_scene("paper000_uniform", {"camera.height_mm": "80", "lights.side": "left", "trajectory.step_mm": "2"})
    assert s.camera.height_mm == 80.0 and s.lights.side == "left"
    assert s.build_trajectory().frame_count == 51


@pytest.mark.parametrize(
    "override, message",
    [
        ({"camera.heigth_mm": 80}, r"camera.heigth_mm: unknown key"),
        ({"camera.height_mm": "high"}, r"camera.height_mm = 'high': must be a number"),
        ({"camera.height_mm": -100.0}, r"camera.height_mm = -100.0 mm: must be > 0"),
        ({"lights.height_mm": -2.0}, r"lights.height_mm = -2.0 mm: must be > 0"),
        ({"lights.height_mm": 150.0}, r"LEDs must be below the camera"),
        ({"trajectory.distance_mm": 0.0}, r"trajectory.distance_mm = 0.0 mm: must be > 0"),
        ({"floor.material": "lava"}, r"floor.material = 'lava': unknown material"),
        ({"lights.side": "top"}, r"lights.side = 'top': must be one of"),
        ({"schema_version": 2}, r"schema_version = 2"),
        # issue 16: a negative floor seed (--seed -1 is refused), a list as the type, sizes that cannot be held
        ({"floor.seed": "-3"}, r"floor.seed = -3: must be >= 0"),
        ({"floor.seed": "1.5"}, r"floor.seed = '1.5': must be integer"),
        ({"trajectory.type": '["uniform"]'}, r"trajectory.type = \['uniform'\]: unknown type"),
        ({"camera.pixel_pitch_um": "5000"}, r"camera: .* see \d+ x \d+ mm of floor; at most 4000 mm"),
        ({"camera.pixel_pitch_um": "0.1"}, r"floor: a floor tile .* mesh vertices; at most 8e\+07"),
        # an infinite focal length in pixels ('intrinsics must be finite, got [inf, ...]', 'see inf x inf mm')
        ({"camera.focal_length_mm": "1e308"}, r"camera.focal_length_mm = 1e\+308 mm: must be <= 1000.0 mm"),
        ({"camera.pixel_pitch_um": "1e308"}, r"camera.pixel_pitch_um = 1e\+308 um: must be <= 100000.0 um"),
        ({"camera.focal_length_mm": "1e-308"}, r"camera.focal_length_mm = 1e-308 mm: must be >= 0.1 mm"),
        ({"floor.spacing_mm": "1e-6"}, r"floor: a floor tile .* at floor.spacing_mm = 1e-06 mm holds"),
        # its square underflowed to 0: a ZeroDivisionError traceback
        ({"floor.spacing_mm": "1e-300"}, r"floor: a floor tile .* at floor.spacing_mm = 1e-300 mm holds inf mesh"),
        ({"trajectory.step_mm": "1e-9"}, r"trajectory: these parameters give 4e\+09 frames; at most 1000000"),
        # a frame rate whose frame times the files cannot hold: 1e7 Hz wrote ground-truth poses that all had
        # one time (TUM holds microseconds) and its reader refused them; 1e-300 Hz made both exports overflow
        ({"fps": "1e7"}, r"fps = 10000000.0 Hz: must be <= 1000000.0 Hz"),
        ({"fps": "1e-300"}, r"fps = 1e-300 Hz: must be >= 0.01 Hz"),
        # a name the bench makes folders of: '../../x' wrote the sequence and runs outside the output folder
        ({"name": "../../x"}, r"name = '../../x': must be a file name: not \. or \.\., no / or \\"),
        ({"name": ".."}, r"name = '\.\.': must be a file name"),
        ({"name": ""}, r"name = '': must be a name \(not empty\)"),
        # 300 characters: refused after the render had started ('File name too long')
        ({"name": "a" * 300}, r"must be a file name of at most 200 bytes \(this one has 300\)"),
        # 1e308 (a TOML float) ended in an OverflowError or numpy ValueError traceback, or a wrong
        # 'the first frame is black' after overflow warnings
        ({"floor.spacing_mm": "1e308"}, r"floor.spacing_mm = 1e\+308 mm: must be <= 10.0 mm"),
        ({"floor.tile_length_mm": "1e308"}, r"floor.tile_length_mm = 1e\+308 mm: must be <= 100000.0 mm"),
        ({"lights.power": "1e308"}, r"lights.power = 1e\+308: must be <= 1000000.0"),
        ({"lights.bar_length_mm": "1e308"}, r"lights.bar_length_mm = 1e\+308 mm: must be <= 1000.0 mm"),
        ({"sensor.full_well_e": "1e308"}, r"sensor.full_well_e = 1e\+308 e-: must be <= 10000000.0 e-"),
        # rendered without a word: frames of noise alone (a read noise beyond any full well)
        ({"sensor.read_noise_e": "1e308"}, r"sensor.read_noise_e = 1e\+308 e-: must be <= 10000000.0 e-"),
        ({"sensor.dsnu_e": "1e308"}, r"sensor.dsnu_e = 1e\+308 e-: must be <= 10000000.0 e-"),
        # a disturbance frequency (or a ceramic tile's period) that overflowed: a NaN pose, a traceback
        (
            {"trajectory.disturbance.bounce_freq_hz": "1e308"},
            r"trajectory.disturbance.bounce_freq_hz = 1e\+308 Hz: must be <= 1000000.0 Hz",
        ),
        (
            {"trajectory.disturbance.tilt_freq_hz": "1e308"},
            r"trajectory.disturbance.tilt_freq_hz = 1e\+308 Hz: must be <= 1000000.0 Hz",
        ),
        (
            {"trajectory.disturbance.vibration_band_hz": "[20, inf]"},
            r"trajectory.disturbance.vibration_band_hz = \[20.0, inf\]: must be \[low, high\] with 0 < low < high <= 1e\+06 Hz",
        ),
        # a disturbance that took the LEDs or the camera under the floor rendered, exit 0
        (
            {"trajectory.disturbance.bounce_amp_mm": "7"},
            r"trajectory.disturbance: bounce_amp_mm = 7 mm, .* lower the LEDs \(lights.height_mm = 3 mm\) to -4 mm",
        ),
        ({"trajectory.disturbance.tilt_amp_rad": "0.3"}, r"trajectory.disturbance: .* lower the LEDs .* to -14.2 mm"),
        (
            {"trajectory.disturbance.vibration_rms_mm": "1"},
            r"4 x vibration_rms_mm = 4 mm, .* lower the LEDs .* to -1 mm",
        ),
        (
            {"camera.height_mm": "5", "lights.height_mm": "1", "trajectory.disturbance.bounce_amp_mm": "20"},
            r"trajectory.disturbance: bounce_amp_mm = 20 mm, .* lower the camera \(camera.height_mm = 5 mm\) to -15 mm",
        ),
        # a lens the renderer cannot invert rendered rays hundreds of pixels off, exit 0; one of kilometres
        # of floor ended in numpy's 'Maximum allowed size exceeded' traceback
        (
            {"camera.distortion": "[-1.0]"},
            r"camera.distortion = \[-1.0\]: the rays cast through the 162x124 image project back up to 180 px",
        ),
        ({"camera.distortion": "[0, 0, 5, 5]"}, r"camera.distortion = \[0.0, 0.0, 5.0, 5.0\]: the rays cast"),
        # a kidnap of one frame per segment: every frame a teleport and the path 0 mm long, exit 0
        (
            {"trajectory": {"type": "kidnap", "speed_mm_s": 1e6}},
            r"trajectory: segment_length_mm = 40 mm at speed_mm_s = 1e\+06 \(fps = 30\) gives 1 frame per segment",
        ),
        # png16 depth of a camera beyond 655.35 mm: 65535 at every pixel, exit 0
        (
            {"render.depth": "true", "camera.height_mm": "1000", "camera.focal_length_mm": "60"},
            r"render.depth_format = 'png16': holds depths up to 655.35 mm, but the camera .* sees the floor up to "
            r"1000.0 mm away; use depth_format = 'npy_float32_mm'",
        ),
        (
            {
                "render.depth": "true",
                "camera.height_mm": "650",
                "lights.height_mm": "12",
                "trajectory.disturbance.bounce_amp_mm": "10",
            },
            r"render.depth_format = 'png16': .* sees the floor up to 660.0 mm away",
        ),
        (
            {"floor.material": "ceramic_tile", "floor.params.tile_mm": "1e308"},
            r"floor.params.tile_mm = 1e\+308 mm: must be <= 100000.0 mm",
        ),
        # structured-light depth whose disparity rounds to 0 at the floor: depth maps of zeros, exit 0
        (
            {"render.depth": "true", "depth_noise.model": '"structured_light"', "depth_noise.baseline_mm": "1e-3"},
            r"depth_noise: focal_px x baseline_mm / depth = 0.0058 px at the farthest floor the camera sees "
            r"\(100.0 mm\), under one disparity step \(1 / subpixel = 0.125 px\)",
        ),
        (
            {"render.depth": "true", "depth_noise.model": '"structured_light"', "depth_noise.baseline_mm": "1e308"},
            r"depth_noise.baseline_mm = 1e\+308 mm: must be <= 100000.0 mm",
        ),
        # a beam of 1e308: "the first frame is black (lights off or power 0)"
        ({"lights.lobe_exponent": "1e308"}, r"lights.lobe_exponent = 1e\+308: must be <= 1000000.0"),
    ],
)
def test_bad_values_refused_by_name(override, message):
    with pytest.raises(ConfigError, match=message):
        tiny_scene(**override)


def test_a_disturbance_keeping_the_leds_above_the_floor_is_allowed():
    # the shipped disturbed scenes keep their LEDs 0.56-2.8 mm above the mean floor plane
    s = tiny_scene(**{"trajectory.disturbance.bounce_amp_mm": "2.9"})
    assert s.lowest_mm(s.disturbance()) == pytest.approx((0.1, 97.1))
    s = tiny_scene(**{"trajectory.disturbance.tilt_amp_rad": "0.03"})
    led_mm, cam_mm = s.lowest_mm(s.disturbance())
    assert 0.8 < led_mm < 0.9 and cam_mm == 100.0
    for p in sorted((scenes_dir() / "motion").glob("motion_*.toml")):
        s = load_scene(p)
        assert s.lowest_mm(s.disturbance())[0] > 0.5


def test_depth_beyond_png16_is_written_as_float():
    keys = {"render.depth": "true", "camera.height_mm": "1000", "camera.focal_length_mm": "60"}
    s = tiny_scene(**keys, **{"render.depth_format": "npy_float32_mm"})
    assert s.deepest_mm() == pytest.approx(1000.0)
    s = tiny_scene(**{"render.depth": "true", "camera.height_mm": "600", "trajectory.disturbance.tilt_amp_rad": "0.03"})
    assert 600.0 < s.deepest_mm() < 655.35  # the tilt sees the floor a little further away


def test_a_pincushion_lens_plans_its_floor_on_the_sides_of_the_image_too():
    # a pincushion lens sees further through the middle of a side than through a corner
    from floorsim.trajectories import footprint_bounds_mm

    s = tiny_scene(**{"camera.distortion": "[0.5]"})
    cam = s.camera_model()
    xmin, xmax, ymin, ymax = footprint_bounds_mm(s.build_trajectory().T_world_cam[:1], cam)
    mid = cam.unproject(np.array([[-0.5, 61.5], [161.5, 61.5], [80.5, -0.5], [80.5, 123.5]]), 100.0)
    corners = cam.unproject(np.array([[-0.5, -0.5], [161.5, 123.5]]), 100.0)
    assert np.abs(mid[:2, 0]).min() > np.abs(corners[:, 0]).max()  # the sides reach further
    assert xmax - xmin == pytest.approx(np.ptp(mid[:2, 0]), rel=1e-3)
    assert ymax - ymin == pytest.approx(np.ptp(mid[2:, 1]), rel=1e-3)


def test_bad_files_give_one_line_and_exit_1(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "bad"\n[camera]\nheight_mm = 100\nbogus = 1\n[trajectory]\ntype = "uniform"\n')
    r = subprocess.run(
        [sys.executable, "-m", "floorsim.cli", "render", str(bad), "-o", str(tmp_path / "o")],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 1
    assert (
        r.stderr.strip().splitlines()[-1]
        == "floorsim: error: bad.toml: camera.bogus: unknown key (known: distortion, focal_length_mm, height_mm, height_px, pixel_pitch_um, vignetting, width_px)"
    )
    assert "Traceback" not in r.stderr
    broken = tmp_path / "broken.toml"
    broken.write_text("name = \n")
    r = subprocess.run(
        [sys.executable, "-m", "floorsim.cli", "render", str(broken), "-o", str(tmp_path / "o")],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 1 and "not valid TOML" in r.stderr and "Traceback" not in r.stderr
    r = subprocess.run(
        [sys.executable, "-m", "floorsim.cli", "render", "demo", "--frames", "0", "-o", str(tmp_path / "o")],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 1 and "--frames = 0: must be >= 1" in r.stderr


def test_scene_dict_round_trip():
    s = tiny_scene()
    again = scene_from_dict(s.to_dict())
    assert again == s
    assert TINY_SCENE["camera"]["width_px"] == 162  # the template is not mutated


def test_set_text_lands_as_the_same_value_a_scene_file_holds():
    """--set text is read by the field's type in a section, as a TOML literal in a free-form table."""
    via_set = load_scene(
        "paper000_uniform",
        {
            "camera.height_mm": "80",
            "sensor.noise": "no",
            "floor.seed": "none",
            "camera.distortion": "[0.1, 0.0]",
            "trajectory.step_mm": "2",
            "floor.params.bump_amplitude_mm": "0.05",
        },
    )
    # The same values written into the file's tables as TOML would hold them.
    d = tomllib.loads((scenes_dir() / "paper000_uniform.toml").read_text())
    d["camera"] |= {"height_mm": 80, "distortion": [0.1, 0.0]}
    d.setdefault("sensor", {})["noise"] = False
    d["floor"] |= {"params": {"bump_amplitude_mm": 0.05}}  # seed: TOML has no none, a missing key is the default
    d["trajectory"]["step_mm"] = 2
    assert via_set.to_dict() == scene_from_dict(d, "paper000_uniform").to_dict()
    with pytest.raises(ConfigError, match=r"sensor.noise = 'maybe': must be true or false"):
        load_scene("paper000_uniform", {"sensor.noise": "maybe"})
    with pytest.raises(ConfigError, match=r"stereo.baseline_mm = 250.0 mm: must be <= 200.0 mm"):
        load_scene("paper000_uniform", {"stereo.baseline_mm": "250"})


def test_list_scene_keys_prints_every_section_type_and_material(capsys):
    from floorsim.cli import main
    from floorsim.materials import MATERIALS
    from floorsim.trajectories import TRAJECTORIES
    from floorvo.config import describe_fields

    assert main(["list", "--scene-keys"]) == 0
    out = capsys.readouterr().out
    lines = {ln.split()[0]: ln for ln in out.splitlines() if ln.startswith("  ") and ln.split()}
    for section in ("camera", "floor", "lights", "sensor", "render", "stereo", "depth_noise"):
        assert any(k.startswith(f"{section}.") for k in lines), section
    height = lines["camera.height_mm"].split()
    assert height[1:4] == ["float", "100.0", "mm"] and "[5.0, 2000.0]" in lines["camera.height_mm"]
    assert "one of 'both', 'left', 'right'" in lines["lights.side"]
    for name, t in TRAJECTORIES.items():
        assert f"  {name}: {t.description}" in out
    for name, m in MATERIALS.items():
        assert f"  {name}: {m.description}" in out
        for row in describe_fields(m.Params, "floor.params"):
            assert row.key in out


def test_a_scaled_down_render_of_large_pixels_keeps_its_camera():
    """camera.pixel_pitch_um's bound must leave room for --scale: the pixels of a scaled-down
    render grow as the resolution shrinks (the demo's 14.8 um at --scale 0.1 are 148 um)."""
    from floorsim.simulate import prepare_scene

    big = {"camera.pixel_pitch_um": "100", "camera.focal_length_mm": "100", "camera.width_px": "1000"}
    scene = tiny_scene(**big, **{"camera.height_px": "800"})
    scaled = prepare_scene(scene, scale=0.01)
    assert scaled.camera.width_px == 10 and scaled.camera.pixel_pitch_um == pytest.approx(10_000.0)
    assert scaled.camera.model().fx_px == pytest.approx(scene.camera.model().fx_px / 100)

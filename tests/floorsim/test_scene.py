"""Scene files: loading, overrides, refusal of bad input by name."""

import subprocess
import sys

import pytest
from _tiny import TINY_SCENE, tiny_scene

from floorsim.scene import load_scene, scene_from_dict
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
    ],
)
def test_bad_values_refused_by_name(override, message):
    with pytest.raises(ConfigError, match=message):
        tiny_scene(**override)


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

"""Rendered pictures against ground truth and physics (tiny 162x124 renders)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import cv2
import numpy as np
import pytest
from _tiny import tiny_scene
from skimage.registration import phase_cross_correlation

from floorsim import simulate
from floorsim.materials import sample_material
from floorsim.simulate import render_code_sha256, render_sequence
from floorvo.errors import SequenceError
from floorvo.geometry import invert_T, yaw_of_R
from floorvo.sequence import Sequence

pytestmark = pytest.mark.render


def _corrected(seq: Sequence, i: int) -> np.ndarray:
    """Frame i divided by the flat-field frame (LED falloff removed)."""
    img = seq.image(i).astype(np.float64)
    flat = seq.flatfield().astype(np.float64)
    return img / np.maximum(flat, 1.0)


def _interior(img: np.ndarray, frac: float = 0.7) -> np.ndarray:
    h, w = img.shape
    dh, dw = int(h * (1 - frac) / 2), int(w * (1 - frac) / 2)
    return img[dh : h - dh, dw : w - dw]


def _hann(img: np.ndarray) -> np.ndarray:
    win = np.outer(np.hanning(img.shape[0]), np.hanning(img.shape[1]))
    return (img - img.mean()) * win


@pytest.mark.parametrize(
    "k, direction_rad, tol_px",
    [
        (3, 0.0, 0.05),
        (7, 0.0, 0.05),
        # Oblique travel moves the rig along the LED bars too: the discrete LEDs' shadow
        # directions on each floor point change with the move, which the picture shows.
        (7, 0.6, 0.2),
    ],
)
def test_translation_of_k_gsd_shifts_image_by_k_pixels(tmp_path, k, direction_rad, tol_px):
    gsd = tiny_scene().camera_model().gsd_mm_per_px(100.0)
    scene = tiny_scene(
        **{"trajectory.distance_mm": k * gsd, "trajectory.step_mm": k * gsd, "trajectory.direction_rad": direction_rad}
    )
    seq = Sequence.open(render_sequence(scene, tmp_path / "seq"))
    # Expected motion from groundtruth.txt and the intrinsics in sequence.json alone.
    _, T = seq.groundtruth()
    T_0_1 = invert_T(T[0]) @ T[1]
    cam = seq.camera
    depth = T[0][2, 3]  # camera height above the mean floor plane (mm)
    expect_du = -T_0_1[0, 3] * cam.fx_px / depth  # floor content moves opposite to the camera
    expect_dv = -T_0_1[1, 3] * cam.fy_px / depth
    assert np.hypot(expect_du, expect_dv) == pytest.approx(k, rel=1e-3)
    a, b = _interior(_corrected(seq, 0)), _interior(_corrected(seq, 1))
    shift, _, _ = phase_cross_correlation(_hann(a), _hann(b), upsample_factor=100)
    # shift registers frame 1 onto frame 0: minus the content displacement.
    assert -shift[1] == pytest.approx(expect_du, abs=tol_px)
    assert -shift[0] == pytest.approx(expect_dv, abs=tol_px)


def test_yaw_rotates_image_about_principal_point(tmp_path):
    yaw = 0.08  # rad, spin in place
    scene = tiny_scene(**{"trajectory": {"type": "spin", "angle_rad": yaw, "rate_rad_s": yaw * 30.0}})
    seq = Sequence.open(render_sequence(scene, tmp_path / "seq"))
    _, T = seq.groundtruth()
    d_yaw = yaw_of_R(T[1][:3, :3]) - yaw_of_R(T[0][:3, :3])
    cam = seq.camera
    a, b = _corrected(seq, 0), _corrected(seq, 1)
    centre = (cam.cx_px, cam.cy_px)

    def ncc(angle_deg: float) -> float:
        M = cv2.getRotationMatrix2D(centre, angle_deg, 1.0)
        back = cv2.warpAffine(b, M, (cam.width_px, cam.height_px), flags=cv2.INTER_CUBIC)
        x, y = _interior(a, 0.6), _interior(back, 0.6)
        x, y = x - x.mean(), y - y.mean()
        return float((x * y).sum() / np.sqrt((x * x).sum() * (y * y).sum()))

    # Search the rotation that maps frame 1 back onto frame 0, about the principal point.
    angles = np.linspace(-8, 8, 161)
    scores = np.array([ncc(t) for t in angles])
    i = int(scores.argmax())
    y0, y1, y2 = scores[i - 1], scores[i], scores[i + 1]
    best = angles[i] + 0.1 * 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2)
    # The camera yaws counter-clockwise seen from above; with its y axis pointing to world -y
    # the image content turns by +yaw in OpenCV's (clockwise-positive on screen) angle convention.
    assert best == pytest.approx(np.degrees(d_yaw), abs=0.1)
    # The LEDs turn with the rig, so the shading of the relief changes too: a clear but imperfect match.
    assert scores.max() > 0.5 and scores.max() - np.median(scores) > 0.3
    # About the principal point: after de-rotation no translation remains.
    M = cv2.getRotationMatrix2D(centre, best, 1.0)
    back = cv2.warpAffine(b, M, (cam.width_px, cam.height_px), flags=cv2.INTER_CUBIC)
    shift, _, _ = phase_cross_correlation(_hann(_interior(a, 0.6)), _hann(_interior(back, 0.6)), upsample_factor=20)
    assert np.hypot(*shift) < 0.2


def _relief_gradient_x(seq: Sequence, i: int) -> np.ndarray:
    """dh/dx of the floor at each pixel centre of frame i (straight-down camera)."""
    scene = seq.meta["scene"]
    _, T = seq.groundtruth()
    cam = seq.camera
    gsd = cam.gsd_mm_per_px(T[i][2, 3])
    x = T[i][0, 3] + (np.arange(cam.width_px) - cam.cx_px) * gsd
    y = T[i][1, 3] - (np.arange(cam.height_px) - cam.cy_px) * gsd
    h, _ = sample_material(scene["floor"]["material"], x, y, seq.meta["seeds"]["floor"], scene["floor"]["params"])
    return np.gradient(h.astype(np.float64), gsd, axis=1)


@pytest.mark.parametrize("side, sign", [("left", 1.0), ("right", -1.0)])
def test_one_led_lights_faces_towards_it(tmp_path, side, sign):
    """Left LED only: faces rising towards +x (normals towards the left LED) are bright."""
    scene = tiny_scene(**{"lights.side": side, "trajectory.distance_mm": 4.0})
    seq = Sequence.open(render_sequence(scene, tmp_path / side))
    img = _interior(_corrected(seq, 0))
    gx = _interior(_relief_gradient_x(seq, 0))
    r = np.corrcoef(img.ravel(), gx.ravel())[0, 1]
    assert sign * r > 0.3, f"{side}: correlation of brightness with dh/dx is {r:.2f}"


def test_brightness_linear_in_led_power_until_saturation(tmp_path):
    base = {"trajectory.distance_mm": 4.0}
    first = render_sequence(tiny_scene(**base), tmp_path / "auto")
    # Fix the exposure at a quarter of the automatic one, then vary the power.
    base["sensor.exposure_gain"] = 0.25 * json.loads((first / "calib" / "sensor.json").read_text())["gain_e_per_unit"]
    imgs = {}
    for p in (1.0, 2.0, 200.0):
        seq = Sequence.open(render_sequence(tiny_scene(**base, **{"lights.power": p}), tmp_path / f"p{p}"))
        imgs[p] = seq.image(0).astype(np.float64)
    ok = (imgs[1.0] > 15) & (imgs[1.0] < 100)
    assert ok.sum() > 1000
    ratio = imgs[2.0][ok] / imgs[1.0][ok]
    assert np.median(ratio) == pytest.approx(2.0, abs=0.03)
    assert (imgs[200.0] == 255).mean() > 0.95  # saturated, and not wrapped around
    assert imgs[200.0].min() >= imgs[2.0].min()


def test_every_light_off_renders_black_or_says_to_fix_the_exposure(tmp_path, capsys):
    """lights.power = 0 (documented: off) with no ambient light ended in a traceback from inside the
    renderer ('cannot reshape array of size 1 into shape (124,162)'): with every light off Dr.Jit
    holds the image as one value. A fixed exposure renders black frames; automatic exposure asks
    for one in one line."""
    from floorsim.cli import main

    off = {"trajectory.distance_mm": 4.0, "lights.power": 0.0, "sensor.exposure_gain": 1000.0}
    seq = Sequence.open(render_sequence(tiny_scene(**off), tmp_path / "off"))
    assert seq.image(0).shape == (124, 162) and seq.image(0).max() == 0 and seq.image(1).max() == 0
    scene = tmp_path / "off.toml"
    scene.write_text(
        'name = "off"\n[lights]\npower = 0.0\n[trajectory]\ntype = "uniform"\ndistance_mm = 4.0\nstep_mm = 4.0\n'
    )
    assert main(["render", str(scene), "--scale", "0.05", "-o", str(tmp_path / "auto")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "the first frame is black (lights off or power 0); set sensor.exposure_gain" in err


def test_higher_leds_lower_relief_contrast(tmp_path):
    contrast = {}
    for h in (3.0, 30.0):
        seq = Sequence.open(
            render_sequence(tiny_scene(**{"lights.height_mm": h, "trajectory.distance_mm": 4.0}), tmp_path / f"h{h}")
        )
        c = _interior(_corrected(seq, 0))
        contrast[h] = c.std() / c.mean()
    assert contrast[3.0] > 1.5 * contrast[30.0]


def test_same_seed_same_bytes_other_seed_differs(tmp_path):
    scene = tiny_scene(**{"sensor.noise": True})
    a = render_sequence(scene, tmp_path / "a")
    b = render_sequence(scene, tmp_path / "b")
    c = render_sequence(scene, tmp_path / "c", seed=4)
    for i in (0, 1):
        name = f"cam0/{i:06d}.png"
        assert (a / name).read_bytes() == (b / name).read_bytes()
        assert (a / name).read_bytes() != (c / name).read_bytes()


def test_resume_keeps_written_frames(tmp_path):
    scene = tiny_scene(**{"sensor.noise": True, "trajectory.distance_mm": 8.0})
    root = render_sequence(scene, tmp_path / "seq")
    frames = sorted((root / "cam0").glob("*.png"))
    assert len(frames) == 3
    original = [f.read_bytes() for f in frames]
    stat_before = [f.stat().st_mtime_ns for f in frames]
    frames[1].unlink()  # an interrupted render lost frame 1
    render_sequence(scene, root)
    assert [f.read_bytes() for f in frames] == original
    assert frames[0].stat().st_mtime_ns == stat_before[0] and frames[2].stat().st_mtime_ns == stat_before[2]
    # A sensor.json cut short by the interruption: the exposure is chosen again, identically.
    (root / "calib" / "sensor.json").write_text('{"gain_e_per_unit": ')
    frames[1].unlink()
    render_sequence(scene, root)
    assert [f.read_bytes() for f in frames] == original


def test_a_render_by_other_renderer_code_is_neither_resumed_nor_reused(tmp_path, monkeypatch):
    """sequence.json records the renderer's code (``versions.render_code``): a render interrupted,
    the renderer edited and the command run again kept the old frames beside the new ones (a
    finished render came back as it was); now it is refused in one line naming the key."""
    scene = tiny_scene(**{"trajectory.distance_mm": 8.0})
    root = render_sequence(scene, tmp_path / "seq")
    assert json.loads((root / "sequence.json").read_text())["versions"]["render_code"] == render_code_sha256("vinyl")
    (root / "cam0" / "000001.png").unlink()  # an interrupted render
    monkeypatch.setattr(simulate, "render_code_sha256", lambda material=None: "0" * 64)
    for _ in range(2):  # interrupted, then finished
        with pytest.raises(SequenceError, match=r"differs in versions\.render_code\)"):
            render_sequence(scene, root)
        (root / "cam0" / "000001.png").write_bytes((root / "cam0" / "000000.png").read_bytes())


def test_resume_renders_damaged_files_again(tmp_path):
    """A frame and the flat field cut short, and a temporary a SIGKILL left: the resume
    renders the two again, byte for byte, and removes the temporary."""
    scene = tiny_scene(**{"sensor.noise": True, "trajectory.distance_mm": 8.0})
    root = render_sequence(scene, tmp_path / "seq")
    frame, flat = root / "cam0" / "000001.png", root / "calib" / "cam0_flatfield.png"
    original = {p: p.read_bytes() for p in (frame, flat)}
    for p, data in original.items():
        p.write_bytes(data[: len(data) // 2])
    stale = root / "cam0" / ".000002.png.a1b2c3d4.tmp"
    stale.write_bytes(b"half")
    render_sequence(scene, root)
    assert {p: p.read_bytes() for p in original} == original
    assert not stale.exists()


def test_cli_render_refuses_empty_root_and_foreign_folders(tmp_path, monkeypatch, capsys):
    from floorsim.cli import main

    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "thesis.tex").write_text("...")
    for out, rule in (("", "path is empty"), ("/", "root of a file system"), ("mine", "no sequence.json")):
        assert main(["render", "demo", "-o", out, "--frames", "1"]) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and rule in err[0], err
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["mine", "thesis.tex"]


@pytest.mark.parametrize(
    "env, override, rule",
    [
        ({"FLOORSIM_CACHE": "relative/dir"}, [], "FLOORSIM_CACHE = 'relative/dir': must be an absolute path"),
        ({"FLOORSIM_CACHE_MAX_MB": "abc"}, [], "FLOORSIM_CACHE_MAX_MB = 'abc': must be a number of megabytes"),
        ({"FLOORSIM_VARIANT": "bogus"}, [], "mitsuba variant 'bogus' is not available"),
        ({}, ["--set", "lights.power=0"], "the first frame is black"),
        # LEDs inside the relief: it said only "(lights off or power 0)"
        (
            {},
            ["--set", "floor.material=asphalt", "--set", "floor.relief_scale=100"],
            "the first frame is black (lights off, power 0, or the LEDs (3 mm up at their lowest) inside the "
            "asphalt relief, which rises 3",
        ),
        # a relief that reaches the camera: rendered, exit 0
        (
            {},
            ["--set", "floor.material=asphalt", "--set", "floor.params.relief_mm=3", "--set", "floor.relief_scale=100"]
            + ["--set", "sensor.exposure_gain=1000"],
            "and the camera comes down to 100 mm: it must stay above the floor",
        ),
    ],
)
def test_a_refused_render_leaves_no_half_made_sequence_folder(tmp_path, monkeypatch, capsys, env, override, rule):
    """A bad environment setting, or a first frame too black to choose the exposure from, left a
    folder holding sequence.json and groundtruth.txt but no frame. Refused before anything is written:
    the folder the command would have created is not left behind, an empty one given stays empty, and
    a sequence that --overwrite would have replaced is kept whole."""
    import floorsim.render as fr
    from floorsim.cli import main

    for key, value in env.items():
        monkeypatch.setenv(key, value)
    if "FLOORSIM_VARIANT" in env:
        monkeypatch.setattr(fr, "_MI", None)  # the backend this process already set up is asked for again
    tiny = ["--scale", "0.25", "--spp", "1"]
    empty, kept = tmp_path / "empty", tmp_path / "kept"
    empty.mkdir()
    with monkeypatch.context() as clean:  # the sequence to keep, rendered with the environment as it was
        for key in env:
            clean.delenv(key)
        clean.setattr(fr, "_MI", None)  # set up for this render, None again after it
        assert main(["-q", "render", "demo", "-o", str(kept), *tiny, "--frames", "2", "--seed", "7"]) == 0
    before = {p: p.read_bytes() for p in kept.rglob("*") if p.is_file()}
    capsys.readouterr()
    for out, more in ((tmp_path / "new" / "seq", []), (empty, []), (kept, ["--overwrite"])):
        assert main(["render", "demo", "-o", str(out), *tiny, "--frames", "1", *override, *more]) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and rule in err[0], err
    assert not (tmp_path / "new").exists()
    assert list(empty.iterdir()) == []
    assert {p: p.read_bytes() for p in kept.rglob("*") if p.is_file()} == before


def test_more_frames_asked_than_the_trajectory_has_says_so(tmp_path, caplog):
    """--frames 100000 on a 2-frame trajectory rendered its 2 frames without a word."""
    import logging

    with caplog.at_level(logging.WARNING, logger="floorsim.simulate"):
        seq = Sequence.open(render_sequence(tiny_scene(), tmp_path / "seq", frames=100000, scale=0.5, spp=1))
    assert seq.frame_count == 2
    said = [r.getMessage() for r in caplog.records if "--frames" in r.getMessage()]
    assert said == ["tiny: --frames = 100000, but the trajectory has only 2 frames; rendering those 2"], said


def test_cli_render_unwritable_and_summary(tmp_path):
    ro = tmp_path / "ro"
    ro.write_text("a file, not a folder")
    r = subprocess.run(
        [sys.executable, "-m", "floorsim.cli", "render", "demo", "-o", str(ro / "x"), "--frames", "1"],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert f"not a directory ({ro} is a file)" in r.stderr.strip().splitlines()[-1]
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "floorsim.cli",
            "-q",
            "render",
            "demo",
            "-o",
            str(tmp_path / "d"),
            "--frames",
            "2",
            "--scale",
            "0.5",
        ],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    assert "2 frames 162x124" in r.stdout
    seq = Sequence.open(tmp_path / "d")
    assert seq.camera.fx_px == pytest.approx(810.81 / 4, rel=1e-3)  # demo is half size; --scale 0.5 halves again


@pytest.mark.skipif(
    any(os.path.exists(p) for p in ("/dev/nvidia0", "/dev/nvidiactl")), reason="a CUDA device may start here"
)
def test_asking_for_the_cuda_variant_without_a_device_is_refused_in_one_line(tmp_path):
    """FLOORSIM_VARIANT=cuda_ad_mono on a machine without CUDA: exit code 1 and one line naming the variant
    (it fell back to LLVM with a warning, so a run meant for the GPU went to the CPU unnoticed)."""
    env = {**os.environ, "FLOORSIM_VARIANT": "cuda_ad_mono"}
    r = subprocess.run(
        [sys.executable, "-m", "floorsim.cli", "render", "demo", "-o", str(tmp_path / "d"), "--frames", "1"],
        capture_output=True,
        text=True,
        env=env,
    )
    err = r.stderr.strip().splitlines()
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr
    assert len(err) == 1 and "mitsuba variant 'cuda_ad_mono' is not available" in err[0], err


def test_cuda_chosen_by_itself_that_does_not_start_falls_back_to_llvm_or_says_why(monkeypatch, caplog):
    """An NVIDIA device node and no working CUDA: llvm_ad_mono with a warning; without a libLLVM >= 17
    either, one line naming both (the fallback raised Dr.Jit's own error from inside the renderer)."""
    import logging

    import mitsuba

    import floorsim.render as fr
    from floorvo.errors import FloorbenchError

    asked: list[str] = []

    def set_variant(variant):
        asked.append(variant)
        if variant.startswith("cuda"):
            raise ImportError("CUDA driver not found")

    monkeypatch.setattr(fr, "_MI", None)
    monkeypatch.setattr(fr, "_has_cuda", lambda: True)
    monkeypatch.setattr(mitsuba, "set_variant", set_variant)
    monkeypatch.delenv("FLOORSIM_VARIANT", raising=False)
    monkeypatch.delenv("DRJIT_LIBLLVM_PATH", raising=False)
    monkeypatch.setattr(fr, "find_libllvm", lambda min_major=17: None)
    with pytest.raises(FloorbenchError) as exc:
        fr._import_mitsuba()
    assert str(exc.value) == (
        "mitsuba variant 'cuda_ad_mono' is not available (CUDA driver not found), and the fallback llvm_ad_mono "
        "needs libLLVM >= 17: run scripts/setup, or 'apt-get install libllvm19', or set DRJIT_LIBLLVM_PATH"
    )
    monkeypatch.setattr(fr, "find_libllvm", lambda min_major=17: "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1")
    with caplog.at_level(logging.WARNING, logger="floorsim.render"):
        assert fr._import_mitsuba() is mitsuba
    assert asked == ["cuda_ad_mono", "cuda_ad_mono", "llvm_ad_mono"]
    assert os.environ["DRJIT_LIBLLVM_PATH"] == "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1"
    assert "falling back to llvm_ad_mono" in caplog.text


def _down_camera_at(x_mm: float) -> np.ndarray:
    """T_world_cam of a camera 100 mm above (x_mm, 0), looking straight down, image x along world x."""
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])
    T[0, 3], T[2, 3] = x_mm, 100.0
    return T


@pytest.mark.parametrize("x_world_mm", [0.0, 300.0, 2500.0])
def test_ridge_casts_shadow_of_hand_computed_length_anywhere(x_world_mm):
    """A 30 um ridge lit by one LED 3 mm high, 40 mm away, shadows the floor behind it to
    x_s = x_e + h (x_e - x_led) / (H - h) (similar triangles), at the world origin and far from it.

    (Shadow rays leave the surface at a fixed small lift: with a lift that grew with the
    distance from the world origin, a 30 um ridge cast almost no shadow 300 mm away.)
    """
    from floorsim.render import FloorRenderer, LedArray
    from floorvo.camera import CameraModel

    full = CameraModel.from_sensor()  # the paper rig's intrinsics, a 96x24 crop
    cam = CameraModel(96, 24, full.fx_px, full.fy_px, 47.5, 11.5)
    gsd = 100.0 / cam.fx_px
    spacing, h_mm, H_mm, d_mm = 0.02, 0.03, 3.0, 40.0
    xs = np.arange(-400, 401) * spacing  # tile-relative
    ys = np.arange(-110, 111) * spacing
    height = np.where(np.abs(xs) <= 0.1 + 1e-9, h_mm, 0.0)[None, :].repeat(len(ys), 0)
    r = FloorRenderer(cam)
    r.load_heightfield(x_world_mm + xs[0], ys[0], spacing, height, np.full(height.shape, 0.5))
    x_led = x_world_mm - d_mm
    aim = np.array([1.0, 0.0, -H_mm / d_mm]) / np.hypot(1.0, H_mm / d_mm)
    leds = LedArray(np.array([[x_led, 0.0, H_mm]]), aim[None, :], np.array([1.0]))
    T = _down_camera_at(x_world_mm)
    lit = r.render(T, leds, spp=16, seed=0).astype(np.float64)
    bare = r.render(T, leds, spp=16, seed=0, shadows=False).astype(np.float64)
    visible = (lit / bare).mean(axis=0)  # (W,) mean visibility per column; the ridge runs along y
    x_left = x_world_mm + (np.arange(cam.width_px) - 0.5 - cam.cx_px) * gsd  # left edge of each column
    # From the first column that lies wholly beyond the ridge's far wall (x_e + spacing).
    x_e = x_world_mm + 0.1
    c0 = int(np.argmax(x_left >= x_e + spacing))
    assert visible[c0] < 0.05, "the column just behind the ridge must lie in its shadow"
    x_shadow_end = x_left[c0] + gsd * np.sum(1.0 - visible[c0:])
    expect = x_e + h_mm * (x_e - x_led) / (H_mm - h_mm)
    assert x_shadow_end - x_world_mm == pytest.approx(expect - x_world_mm, abs=0.005)


def test_same_floor_patch_renders_alike_anywhere_in_the_world():
    """The vinyl relief at the world origin and 300 mm / 2.5 m away, seen from the same
    relative pose: the pictures agree (the renderer has no preferred place in the world)."""
    from floorsim.render import FloorRenderer
    from floorsim.simulate import _leds
    from floorvo.camera import CameraModel

    full = CameraModel.from_sensor()
    cam = CameraModel(96, 72, full.fx_px, full.fy_px, 47.5, 35.5)
    spacing = 0.0617
    xs = (np.arange(300) - 150) * spacing
    ys = (np.arange(240) - 120) * spacing
    height, albedo = sample_material("vinyl", xs, ys, 5)
    scene = tiny_scene()
    r = FloorRenderer(cam)
    imgs = []
    for x_world_mm in (0.0, 300.0, 2500.0):
        r.load_heightfield(x_world_mm + xs[0], ys[0], spacing, height, albedo)
        T = _down_camera_at(x_world_mm)
        imgs.append(r.render(T, _leds(scene, T), spp=4, seed=1).astype(np.float64))
        bare = r.render(T, _leds(scene, T), spp=4, seed=1, shadows=False)
        assert imgs[-1].mean() / bare.mean() < 0.97, "grazing LEDs must cast micro-shadows on the vinyl relief"
    for img in imgs[1:]:
        assert np.abs(img - imgs[0]).max() <= 1e-4 * imgs[0].mean()

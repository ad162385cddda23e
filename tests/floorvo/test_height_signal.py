"""A measured camera height per frame (issue 14 item 4): the sequence's ``height.csv``, the
height from a depth image, and the mono estimators correcting their scale with it on a
bouncing run, against ground truth."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from _synth import blank_meta, blank_sequence

from floorvo.camera import CameraModel
from floorvo.errors import SequenceError
from floorvo.estimators import Frame, get_estimator, make_config
from floorvo.geometry import T_world_cam_down, depth_floor_plane
from floorvo.metrics import reason_kind
from floorvo.run import run_estimator
from floorvo.runfolder import read_timing_csv
from floorvo.runner import sequence_frames
from floorvo.scoring import score_run
from floorvo.sequence import HEIGHT_FILE, Sequence, SequenceWriter, read_height_csv, sequence_files
from floorvo.synthetic import floor_depth, write_synthetic_sequence

CAM = CameraModel.from_sensor(324, 247, pixel_pitch_um=14.8, focal_length_mm=6.0)


def _meta(n: int) -> dict:
    return blank_meta(CAM, n)


def _write(tmp_path, n: int = 3):
    return blank_sequence(tmp_path, CAM, n)


def test_height_column_round_trip_and_a_folder_without_it_loads_as_before(tmp_path):
    root = _write(tmp_path)
    assert Sequence.open(root).height_signal_mm is None
    with SequenceWriter(root, _meta(3)) as w:
        w.write_heights(np.array([100.5, np.nan, 99.25]))
    text = (root / HEIGHT_FILE).read_text().splitlines()
    assert text[1:] == ["frame,height_mm", "0,100.500000", "1,", "2,99.250000"]
    h = Sequence.open(root).height_signal_mm
    np.testing.assert_array_equal(h, [100.5, np.nan, 99.25])
    assert root / HEIGHT_FILE in sequence_files(root)  # --overwrite removes it with the sequence
    frames = list(sequence_frames(Sequence.open(root), range(3)))
    assert [f.height_mm for f in frames] == [100.5, None, 99.25]


def test_frames_carry_the_depth_images_height_only_when_asked(tmp_path):
    poses = np.stack([T_world_cam_down(0.0, 0.0, h) for h in (100.0, 101.5)])
    seq = Sequence.open(write_synthetic_sequence(tmp_path / "d", CAM, poses, depth=True))
    assert [f.height_mm for f in sequence_frames(seq, range(2))] == [None, None]
    got = [f.height_mm for f in sequence_frames(seq, range(2), depth_height=True)]
    assert got == [pytest.approx(100.0, abs=1e-6), pytest.approx(101.5, abs=1e-6)]


@pytest.mark.parametrize(
    "body, message",
    [
        ("frame,height\n0,1\n1,1\n2,1\n", r"height.csv:1: header 'frame,height': must be 'frame,height_mm'"),
        (
            "frame,height_mm\n0,100\n2,100\n1,100\n",
            r"height.csv:3: frame '2': rows must be frames 0, 1, \.\.\. in order",
        ),
        (
            "frame,height_mm\n0,100\n1,-3\n2,100\n",
            r"height of frame 1 = -3 mm: must be a finite number from 1 to 20000 mm",
        ),
        # no floor camera is 1e9 or 1e-9 mm above the floor (both were taken)
        ("frame,height_mm\n0,100\n1,1e9\n2,100\n", r"height of frame 1 = 1e\+09 mm: must be a finite number from 1 to"),
        (
            "frame,height_mm\n0,1e-9\n1,100\n2,100\n",
            r"height of frame 0 = 1e-09 mm: must be .*\(a floor camera's height\)",
        ),
        ("frame,height_mm\n0,100\n1,100mm\n2,100\n", r"height.csv:3: height_mm '100mm' of frame 1: not a number"),
        ("frame,height_mm\n0,100\n1,100\n", r"2 height\(s\) for 3 frame\(s\); need one per frame"),
        ("frame,height_mm\n0,100\n1,100,3\n2,100\n", r"height.csv:3: '1,100,3': need two cells"),
        ("# nothing\n", r"no header line"),
    ],
)
def test_a_bad_height_column_is_refused_in_one_line(tmp_path, body, message):
    root = _write(tmp_path)
    (root / HEIGHT_FILE).write_text(body)
    with pytest.raises(SequenceError, match=message) as err:
        Sequence.open(root)
    assert "\n" not in str(err.value)
    with SequenceWriter(root, _meta(3)) as w, pytest.raises(SequenceError, match="need one per frame"):
        w.write_heights(np.array([100.0]))


def test_height_from_a_tilted_depth_image_is_the_height_above_the_floor():
    T = T_world_cam_down(3.0, 1.0, 97.3, 0.4, 0.03, -0.02)
    n, d = depth_floor_plane(floor_depth(CAM, T), CAM)
    assert d == pytest.approx(97.3, abs=1e-6)  # not the depth along the tilted axis (97.3 / cos(tilt))
    np.testing.assert_allclose(n, T[:3, :3].T @ [0.0, 0.0, -1.0], atol=1e-9)
    assert depth_floor_plane(np.zeros((CAM.height_px, CAM.width_px)), CAM) is None


def _bounce_poses(n: int = 34) -> np.ndarray:
    """4 mm/frame with a 2 mm bounce at 2 Hz (30 fps), ending 1.9 mm above the start height."""
    t = np.arange(n) / 30.0
    return np.stack([T_world_cam_down(4.0 * i, 0.0, 100.0 + 2.0 * np.sin(4 * np.pi * t[i])) for i in range(n)])


@pytest.fixture(scope="module")
def bounce_seqs(tmp_path_factory):
    root = tmp_path_factory.mktemp("bounce")
    poses = _bounce_poses()
    rng_seq = write_synthetic_sequence(root / "range", CAM, poses, height_noise_mm=0.02)
    depth_seq = write_synthetic_sequence(root / "depth", CAM, poses, depth=True)
    return rng_seq, depth_seq


@pytest.mark.parametrize("name", ["phase-corr", "akaze-guided"])
@pytest.mark.parametrize("source", ["range", "depth"])
def test_a_mono_estimator_corrects_its_scale_with_the_height_signal(bounce_seqs, tmp_path, name, source):
    """On a 2 mm bounce the rig height is up to 2 % off: with the measured height (a range
    sensor with 0.02 mm noise, or the depth image's floor plane) no step is wrong by the
    issue's bound and the drift and per-frame error against ground truth are lower; without
    it, at the rig's height (use_height_signal = false; phase-corr with fit_image_scale =
    false too: by default it follows the image scale, below; akaze with check_height_change =
    false: by default it loses the steps it cannot measure, below) most steps are wrong."""
    seq = bounce_seqs[0] if source == "range" else bounce_seqs[1]
    use = {} if source == "range" else {"height_from_depth": "true"}  # depth: asked for (a depth camera may be off)
    with_h = score_run(run_estimator(seq, name, tmp_path / "with", use).run_dir, seq).flat()
    rig = {"use_height_signal": "false", "fit_image_scale": "false"}
    if name == "akaze-guided":
        rig["check_height_change"] = "false"
    else:
        rig["precision_sigmas"] = "0"  # phase-corr's check of a kept height (below) off too
    without = score_run(run_estimator(seq, name, tmp_path / "without", rig).run_dir, seq).flat()
    assert with_h["wrong_ok_steps"] == 0
    assert without["wrong_ok_steps"] > 20
    assert with_h["end_drift_pct"] < 0.5 * without["end_drift_pct"]
    assert with_h["rpe_frame_trans_rmse_mm"] < 0.3 * without["rpe_frame_trans_rmse_mm"]


def test_an_estimator_step_uses_each_frames_height(tmp_path):
    """Two frames 2 mm apart in height, no motion in x/y: the step is the height change.

    (The frames are rendered at those heights: the pixel fit takes the image scale from the
    heights, so a picture that does not scale with them does not fit.)"""
    poses = np.stack([T_world_cam_down(0.0, 0.0, h) for h in (99.0, 101.0)])
    seq = Sequence.open(write_synthetic_sequence(tmp_path / "seq", CAM, poses))
    prev, cur = (f.image for f in sequence_frames(seq, range(2)))
    est = get_estimator("akaze-guided")(make_config("akaze-guided"), CAM, height_mm=100.0)
    st = est.start()
    est.step(st, Frame(0, 0.0, prev, height_mm=99.0))
    r = est.step(st, Frame(1, 0.1, cur, height_mm=101.0))
    assert r.ok
    assert r.T_prev_cur[2, 3] == pytest.approx(-2.0)  # the camera rose 2 mm: -2 mm along its down-pointing z


FULL = CameraModel.from_sensor(648, 494, pixel_pitch_um=7.4, focal_length_mm=6.0)


@pytest.fixture(scope="module")
def full_size_bounce(tmp_path_factory):
    """The rig's full-size camera rising and falling 0.8 mm a frame (0.8 % image scale, up to
    2.6 px at the corners) at 4 mm a frame, with an exact height signal."""
    heights_mm = [100.0, 100.8, 101.6, 100.8, 100.0, 99.2]
    poses = np.stack([T_world_cam_down(4.0 * i, 0.0, h) for i, h in enumerate(heights_mm)])
    return write_synthetic_sequence(tmp_path_factory.mktemp("full") / "seq", FULL, poses, height_noise_mm=0.0)


@pytest.mark.parametrize("name", ["akaze-guided", "akaze-bruteforce"])
def test_the_akaze_pixel_fit_takes_the_image_scale_from_the_height_signal(full_size_bounce, tmp_path, name):
    """With the frames' heights known the pixel fit scales the previous points by h_prev / h_cur
    before the rigid fit, so the residual check sees the true misfit: every step is ok and
    within the issue's bound of ground truth. A rigid fit (the old code) left 1.35-1.40 px RMS
    (limit 1.25) and lost every step; without the height signal the steps are still refused,
    never reported wrong."""
    seq = full_size_bounce
    with_h = score_run(run_estimator(seq, name, tmp_path / "with").run_dir, seq).flat()
    assert with_h["lost_frames"] == 0
    assert with_h["wrong_ok_steps"] == 0
    assert with_h["end_drift_pct"] < 0.1
    without = score_run(
        run_estimator(seq, name, tmp_path / "without", {"use_height_signal": "false"}).run_dir, seq
    ).flat()
    assert without["lost_frames"] == 5
    assert without["wrong_ok_steps"] == 0


@pytest.mark.parametrize("name", ["akaze-guided", "akaze-bruteforce", "phase-corr"])
def test_fits_the_image_scale_and_follows_the_height_without_a_signal(full_size_bounce, tmp_path, name):
    """``fit_image_scale``: with no height signal the camera height follows from the image
    scale (h_cur = h_prev / scale, from the rig's 100 mm): akaze's pixel fit is a similarity,
    phase-corr takes the scale of its blocks' shifts along y. On the full-size bounce (0.8 mm
    a frame) akaze's rigid fit lost all 5 steps and phase-corr reported them at the rig's
    height (0.8 mm off along z, wrong); with the fitted scale each step is within the issue's
    bound, height change included, and the track's height ends within 0.05 mm of the truth
    (99.2 mm). (phase-corr's default; akaze's option.)"""
    seq = full_size_bounce
    res = run_estimator(seq, name, tmp_path / "fit", {"use_height_signal": "false", "fit_image_scale": "true"})
    flat = score_run(res.run_dir, seq).flat()
    assert flat["lost_frames"] == 0
    assert flat["wrong_ok_steps"] == 0
    assert flat["end_drift_pct"] < 0.1
    T_true = Sequence.open(seq).groundtruth()[1]
    T_est = np.loadtxt(Path(res.run_dir) / "trajectory.txt")
    # TUM lines (t x y z qx qy qz qw, metres): the camera's z in the world, the start's height plus the rises
    z_est = 1000.0 * (T_est[:, 3] - T_est[0, 3]) + T_true[0, 2, 3]
    assert z_est[-1] == pytest.approx(T_true[-1, 2, 3], abs=0.05)


def test_phase_corr_without_the_image_scale_reports_the_bounce_wrong(full_size_bounce, tmp_path):
    """The control of the test above: phase-corr at the rig's height (``fit_image_scale =
    false``, its default until 2026-11-25) reported 5 of the bounce's steps ok with no height
    change, each 0.8 mm off along z: wrong against the camera's step (a planar estimator's steps
    are right only against the footprint). It now loses them: its blocks' image scale shows the
    change it keeps ("height change not measured"). Its default follows the bounce: none wrong,
    none lost."""
    seq = full_size_bounce
    res = run_estimator(
        seq, "phase-corr", tmp_path / "rigid", {"use_height_signal": "false", "fit_image_scale": "false"}
    )
    flat = score_run(res.run_dir, seq).flat()
    assert flat["wrong_ok_steps"] == 0
    assert flat["lost_frames"] == 5
    # each frame after a good one; the others, measured across the lost frame, see twice the
    # change, which the rigid warp's blocks do not agree on
    unmeasured = [r for r in res.reason if r.startswith("height change not measured: the blocks' image scale")]
    assert len(unmeasured) == 3, list(res.reason)
    default = score_run(
        run_estimator(seq, "phase-corr", tmp_path / "default", {"use_height_signal": "false"}).run_dir, seq
    )
    assert default.flat()["lost_frames"] == 0
    assert default.flat()["wrong_ok_steps"] == 0


@pytest.mark.parametrize("name", ["phase-corr", "akaze-guided"])
def test_keeps_the_height_where_the_image_scale_shows_no_change(tmp_path, name):
    """``fit_image_scale`` on a level run (100 mm throughout, straight then turning 2 degrees
    a frame, sensor noise of 4 DN): the image scale (phase-corr's four blocks', akaze's
    similarity fit's) differs from 1 by its noise only, within ``image_scale_min_sigmas`` (3)
    of its standard error on every step, so the height stays the rig's and the trajectory is
    the one at the rig's height, to the bit. Followed wherever it differs
    (``image_scale_min_sigmas = 0``), the noise walks the height away from 100 mm. (The
    bounce above is followed with the default: its 0.8 % scale steps stand far beyond their
    standard errors.)"""
    poses, x, y, yaw = [], 0.0, 0.0, 0.0
    for i in range(10):
        poses.append(T_world_cam_down(x, y, 100.0, yaw))
        yaw += np.radians(2.0) if i > 3 else 0.0
        x, y = x + 4.0 * np.cos(yaw), y + 4.0 * np.sin(yaw)
    seq = write_synthetic_sequence(tmp_path / "seq", FULL, np.stack(poses), noise_dn=4.0)

    def track(run: str, overrides: dict[str, str]) -> np.ndarray:
        res = run_estimator(seq, name, tmp_path / run, overrides)
        assert score_run(res.run_dir, seq).flat()["wrong_ok_steps"] == 0
        return np.loadtxt(Path(res.run_dir) / "trajectory.txt")[:, 1:]  # TUM: x y z, quaternion (m)

    rig = track("rig", {"fit_image_scale": "false"})
    np.testing.assert_array_equal(track("gated", {"fit_image_scale": "true"}), rig)
    followed = track("followed", {"fit_image_scale": "true", "image_scale_min_sigmas": "0"})
    assert np.abs(followed[:, 2] - rig[:, 2]).max() > 0.002e-3  # its camera's z moved by more than 2 um


def test_phase_corr_follows_a_bounce_too_small_for_one_frames_scale(tmp_path):
    """``image_scale_window``: a half-size run bouncing 0.6 mm (a sine of 12 frames, 0.08-0.3 mm
    a frame) under 4 DN of sensor noise, phase-corr-fast (binned blocks). One frame's scale shows
    too few of the height changes beyond its 9.2 standard errors: judged frame by frame
    (``image_scale_window = 1``) the camera's height ends more than 0.1 mm off the truth, and a
    step is reported ok and wrong. The last eight frames' scales together show the bounce (the
    F test), and each frame's scale is then the height change: every frame's height within
    0.05 mm of the truth, no step wrong."""
    heights_mm = 100.0 + 0.6 * np.sin(2 * np.pi * np.arange(16) / 12)
    poses = np.stack([T_world_cam_down(4.0 * i, 0.0, h) for i, h in enumerate(heights_mm)])
    seq = write_synthetic_sequence(tmp_path / "seq", CAM, poses, noise_dn=4.0)

    def heights(run: str, overrides: dict[str, str]) -> tuple[np.ndarray, float]:
        res = run_estimator(seq, "phase-corr-fast", tmp_path / run, overrides)
        flat = score_run(res.run_dir, seq).flat()
        assert flat["lost_frames"] == 0
        T_est = np.loadtxt(Path(res.run_dir) / "trajectory.txt")  # TUM: t x y z (m), quaternion
        return 1000.0 * (T_est[:, 3] - T_est[0, 3]) + heights_mm[0], flat["wrong_ok_steps"]

    z_window, wrong_window = heights("window", {})
    assert np.abs(z_window - heights_mm).max() < 0.05
    assert wrong_window == 0
    z_frame, wrong_frame = heights("frame", {"image_scale_window": "1"})
    assert np.abs(z_frame - heights_mm).max() > 0.1
    assert wrong_frame >= 1


def test_every_reader_of_a_camera_height_takes_the_one_range(tmp_path, capsys):
    """A camera height of 1e9 or 1e-9 mm in sequence.json's rig.height_mm (taken before, and
    every step came out scaled by it) is refused in one line naming the field and the rule;
    the scene's own (the renderer's) bounds lie inside the range."""
    import dataclasses
    import json

    from floorsim.scene import CameraSpec
    from floorvo.camera import CAMERA_HEIGHT_RANGE_MM, height_problem
    from floorvo.cli import main
    from floorvo.config import rule_of

    lo, hi = CAMERA_HEIGHT_RANGE_MM
    assert height_problem(100.0) is None and height_problem(lo) is None and height_problem(hi) is None
    for bad in (1e9, 1e-9, float("nan"), float("inf"), -100.0, "high"):
        assert height_problem(bad), bad
    scene = rule_of({f.name: f for f in dataclasses.fields(CameraSpec)}["height_mm"])
    assert scene.min is not None and scene.max is not None and lo <= scene.min and scene.max <= hi
    root = _write(tmp_path)
    meta = json.loads((root / "sequence.json").read_text())
    for height, rule in ((1e9, f"must be <= {hi}"), (1e-9, f"must be >= {lo}")):
        meta["rig"]["height_mm"] = height
        (root / "sequence.json").write_text(json.dumps(meta))
        rc = main(["run", str(root), "-e", "phase-corr", "-o", str(tmp_path / "run")])
        err = capsys.readouterr().err
        assert rc == 1 and err.count("\n") == 1 and "Traceback" not in err, err
        assert f"rig.height_mm = {height} mm: {rule} mm" in err, err


def _lost_for_height(run_dir: Path) -> set[int]:
    """The frames of a run lost because the rigid fit could not hold their height change."""
    timing = read_timing_csv(Path(run_dir) / "timing.csv")
    assert timing is not None
    return {int(f) for f, why in zip(timing["frame"], timing["reason"]) if "height change not measured" in str(why)}


@pytest.mark.parametrize("name", ["akaze-guided", "akaze-bruteforce"])
def test_the_papers_rigid_fit_loses_a_height_change_instead_of_reporting_it_wrong(bounce_seqs, tmp_path, name):
    """Paper 000's fit is rigid at the rig's height: on a 2 mm bounce (up to 0.84 mm of height
    change a frame) without a height signal, a step the rigid fit still holds was reported ok
    with no height change: wrong against the camera's step. ``check_height_change`` reads the
    change from the floor homography of the step's pairs: against ground truth, every step it
    loses changed the height by more than the bound a step reported ok may have (0.05 mm + 2 %
    of the step, from the frame it was measured from), and no step reported ok did. With the
    check off (the control) most steps are ok and wrong. (What wrong steps are left come from
    the height itself, not its change: a step measured across a lost frame, 8 mm at 98.2 mm,
    is 1.8 % long at the rig's 100 mm and changes the height by 0.17 mm, each within the bound
    and the two together 0.225 mm against 0.210: a rigid fit cannot see the absolute height.)"""
    seq = bounce_seqs[0]
    rig = {"use_height_signal": "false"}
    res = run_estimator(seq, name, tmp_path / "checked", rig)
    timing = read_timing_csv(Path(res.run_dir) / "timing.csv")
    assert timing is not None
    T_true = Sequence.open(seq).groundtruth()[1]
    ref, lost_for_height, ok = 0, 0, 0
    for frame, status, why in zip(timing["frame"][1:], timing["status"][1:], timing["reason"][1:]):
        k = int(frame)
        step_mm = float(np.linalg.norm(T_true[k, :2, 3] - T_true[ref, :2, 3]))
        dz_mm = abs(T_true[k, 2, 3] - T_true[ref, 2, 3])
        if "height change not measured" in str(why):
            lost_for_height += 1
            assert dz_mm > 0.05 + 0.02 * step_mm, f"frame {k}"
        if status == "ok":
            ok += 1
            assert dz_mm <= 0.05 + 0.02 * step_mm, f"frame {k}"
        if status == "ok" or "restarts" in str(why):
            ref = k  # the next step is measured from this frame
    assert lost_for_height >= 10 and ok >= 3
    # counted by its cause (a "; " inside the reason had counted it by its last clause)
    kinds = json.loads((Path(res.run_dir) / "result.json").read_text())["lost_reasons"]
    assert sum(n for k, n in kinds.items() if k.startswith("height change not measured")) == lost_for_height, kinds
    checked = score_run(res.run_dir, seq).flat()["wrong_ok_steps"]
    unchecked = run_estimator(seq, name, tmp_path / "unchecked", {**rig, "check_height_change": "false"})
    assert score_run(unchecked.run_dir, seq).flat()["wrong_ok_steps"] > 10 * max(1.0, checked)


def test_a_height_change_within_what_the_steps_tilt_makes_of_the_shading_is_not_lost(tmp_path):
    """Under grazing LEDs that ride with the camera a tilt moves the shading as a height change
    does, and a planar estimator is held to its footprint on a tilted step (issue 14): the
    check allows ``height_change_tilt_share`` x the camera height x the tilt change the
    homography reads beyond ``height_change_light_tilt_rad`` (2 mrad). The same 0.3 mm drop
    (beyond the 0.13 mm bound) is lost on a level step and kept on a step that also tilts the
    camera by 5 mrad (0.3 mm at the floor beyond the 2 mrad); with the share at 0 it is lost
    there too."""
    drop = [T_world_cam_down(0.0, 0.0, 100.0), T_world_cam_down(4.0, 0.0, 99.7)]
    tilted = [T_world_cam_down(0.0, 0.0, 100.0), T_world_cam_down(4.0, 0.0, 99.7, roll_rad=0.005)]
    level_seq = write_synthetic_sequence(tmp_path / "level", FULL, np.stack(drop))
    tilt_seq = write_synthetic_sequence(tmp_path / "tilt", FULL, np.stack(tilted))
    assert _lost_for_height(run_estimator(level_seq, "akaze-guided", tmp_path / "a").run_dir) == {1}
    assert _lost_for_height(run_estimator(tilt_seq, "akaze-guided", tmp_path / "b").run_dir) == set()
    no_share = run_estimator(tilt_seq, "akaze-guided", tmp_path / "c", {"height_change_tilt_share": "0"})
    assert _lost_for_height(no_share.run_dir) == {1}


def test_with_an_attitude_signal_the_tilt_allows_no_height_change(tmp_path):
    """Frames levelled with an IMU's attitude (``attitude.csv``) make the run's poses the
    camera's 6-DoF ones, and the score holds them to the camera's step. The step of the test
    above that tilts by 5 mrad and drops 0.3 mm, levelled: the check used to take the tilt
    change from the attitude and allow it (0.3 mm beyond the 2 mrad), so the step was kept
    with no height change, 0.3 mm off the camera's step against a 0.13 mm bound. Now a levelled
    run's check allows the tilt nothing, and the step is lost; without the signal (the test
    above) the tilt is allowed, the run being held to the footprint's step."""
    poses = np.stack([T_world_cam_down(0.0, 0.0, 100.0), T_world_cam_down(4.0, 0.0, 99.7, roll_rad=0.005)])
    seq = write_synthetic_sequence(tmp_path / "seq", FULL, poses, attitude_noise_rad=0.0)
    assert _lost_for_height(run_estimator(seq, "akaze-guided", tmp_path / "a").run_dir) == {1}


def test_pairs_on_a_line_give_the_height_check_no_evidence():
    """Pairs that fix no homography (all on one line; through the principal point OpenCV returns
    a singular matrix, which reads as the camera on the floor, 100 mm down) leave the step as the
    rigid fit has it; the same number of pairs spread over the frame, with a 0.5 mm drop in
    them, do not."""
    from floorvo.estimators.akaze import _Fit, _State
    from floorvo.geometry import floor_mm_to_pixels

    est = get_estimator("akaze-guided")(make_config("akaze-guided"), FULL, height_mm=100.0)
    M = np.eye(3)
    M[0, 2] = 32.0
    frame = Frame(1, 1 / 30.0, np.zeros((FULL.height_px, FULL.width_px), np.uint8))
    along = np.linspace(-150.0, 150.0, 12)[:, None]
    line = np.array([FULL.cx_px, FULL.cy_px]) + along * [2.0, 1.0] / np.sqrt(5.0)
    assert est._height_change_problem(_State(), _Fit(M, line, line + [32.0, 0.0], 12), frame, None) == ""
    rng = np.random.default_rng(1)
    floor_prev = rng.uniform([-30.0, -20.0], [30.0, 20.0], (12, 2))  # mm on the floor, camera-centred
    src = floor_mm_to_pixels(floor_prev, FULL, 100.0)
    dst = floor_mm_to_pixels(floor_prev - [4.0, 0.0], FULL, 99.5)
    assert "height change not measured" in est._height_change_problem(_State(), _Fit(M, src, dst, 12), frame, None)


def test_the_height_check_takes_its_read_as_a_share_of_the_change():
    """The rig's LEDs rise and fall with the camera, and their shading hides a part of a height
    change from the homography (it read 85-97 % of the true change on the motion suite's level
    runs): ``height_change_read_share`` (0.85) takes a read as that share of the change. By hand:
    noise-free pairs of a 4 mm step that drops the camera 0.12 mm read 0.120 mm with no spread;
    the bound is 0.05 mm + 2 % of 4 mm = 0.13 mm. At a read share of 1 the step stands; at 0.85
    the read stands for 0.141 mm, and the step is lost."""
    from floorvo.estimators.akaze import _Fit, _State
    from floorvo.geometry import floor_mm_to_pixels

    rng = np.random.default_rng(2)
    floor_prev = rng.uniform([-30.0, -20.0], [30.0, 20.0], (40, 2))  # mm on the floor, camera-centred
    src = floor_mm_to_pixels(floor_prev, FULL, 100.0)
    dst = floor_mm_to_pixels(floor_prev - [4.0, 0.0], FULL, 99.88)
    M = np.eye(3)
    M[0, 2] = 4.0 / FULL.gsd_mm_per_px(100.0)  # the rigid fit's step: 4 mm along x
    frame = Frame(1, 1 / 30.0, np.zeros((FULL.height_px, FULL.width_px), np.uint8))
    why = {}
    for share in ("1", "0.85"):
        est = get_estimator("akaze-guided")(
            make_config("akaze-guided", {"height_change_read_share": share}), FULL, height_mm=100.0
        )
        why[share] = est._height_change_problem(_State(), _Fit(M, src, dst, 40), frame, None)
    assert why["1"] == ""
    assert "reads -0.120 mm" in why["0.85"] and "standard error 0.000" in why["0.85"]
    assert "0.141 mm > bound 0.130" in why["0.85"]


@pytest.mark.parametrize("name", ["phase-corr", "phase-corr-fast"])
def test_phase_corr_loses_a_step_whose_height_reading_the_picture_contradicts(bounce_seqs, tmp_path, name):
    """A range reading of 300 mm in a run at 98-102 mm, or one creeping 3 mm a frame, was taken
    as it was: the steps reported ok 200 mm off (akaze's fits lost them). The honest readings of
    the same bounce (0.02 mm of noise) keep every step."""
    import shutil

    from floorvo.sequence import read_height_csv

    honest = score_run(run_estimator(bounce_seqs[0], name, tmp_path / "honest").run_dir, bounce_seqs[0]).flat()
    assert honest["lost_frames"] == 0 and honest["wrong_ok_steps"] == 0
    seq = tmp_path / "seq"
    shutil.copytree(bounce_seqs[0], seq)
    h = read_height_csv(seq / "height.csv")
    h[10] = 300.0
    h[20:] += 3.0 * np.arange(1, len(h) - 19)
    lines = ["frame,height_mm", *(f"{i},{v:.6f}" for i, v in enumerate(h))]
    (seq / "height.csv").write_text("\n".join(lines) + "\n")
    run = run_estimator(seq, name, tmp_path / "run")
    s = score_run(run.run_dir, seq).flat()
    assert s["wrong_ok_steps"] == 0
    lost = {int(i) for i, st in zip(run.frame_index, run.status) if st == "lost"}
    assert 10 in lost and set(range(21, len(h))) <= lost
    why = {int(i): r for i, r in zip(run.frame_index, run.reason)}
    assert why[10].startswith("height signal disagrees with the picture: it reads 300.000 mm")
    assert reason_kind(why[10]) == "height signal disagrees with the picture"


def test_homography_6dof_holds_its_floor_plane_to_the_height_signal(bounce_seqs, tmp_path):
    """homography-6dof reads only the ratio of the heights from the floor's homography, so the
    plane it starts from scales every step: a first reading of 300 mm in a run at 100 mm made
    every step 3x long, 38 of 40 reported ok. The readings after the first now hold the carried
    plane: the steps they contradict are lost, tracking restarts at a reading, and no step is
    wrong; a single wrong reading later in the run costs its own frame only. The honest readings
    (0.02 mm of noise) keep every step."""
    import shutil

    from floorvo.estimators.base import RESTART_NOTE
    from floorvo.sequence import read_height_csv

    name = "homography-6dof"
    honest = score_run(run_estimator(bounce_seqs[0], name, tmp_path / "honest").run_dir, bounce_seqs[0]).flat()
    assert honest["lost_frames"] == 0 and honest["wrong_ok_steps"] == 0
    for at in (0, 10):
        seq = tmp_path / f"seq{at}"
        shutil.copytree(bounce_seqs[0], seq)
        h = read_height_csv(seq / "height.csv")
        h[at] = 300.0
        (seq / "height.csv").write_text(
            "\n".join(["frame,height_mm", *(f"{i},{v:.6f}" for i, v in enumerate(h))]) + "\n"
        )
        run = run_estimator(seq, name, tmp_path / f"run{at}")
        s = score_run(run.run_dir, seq).flat()
        assert s["wrong_ok_steps"] == 0
        lost = [int(i) for i, st in zip(run.frame_index, run.status) if st == "lost"]
        why = {int(i): r for i, r in zip(run.frame_index, run.reason)}
        if at == 0:
            assert lost == [1, 2] and why[2].endswith(RESTART_NOTE)
            assert why[1].startswith("height signal disagrees with the floor plane: it reads 100.7")
        else:
            assert lost == [10]
            assert why[10].startswith("height signal disagrees with the floor plane: it reads 300.000 mm")
            assert reason_kind(why[10]) == "height signal disagrees with the floor plane"


@pytest.mark.parametrize("name", ["phase-corr", "akaze-guided"])
def test_a_height_signal_too_noisy_for_the_step_loses_it(tmp_path, name):
    """A range sensor of 0.1 mm noise on the 2 mm bounce: a step's height change, the difference
    of two readings, has 0.14 mm of noise against the 0.13 mm bound of a 4 mm step. Taken as
    exact (the sequence states no noise) steps are reported ok and wrong by it; with the noise
    stated (rig.height_noise_mm, as a render and `floorvo import --height-noise-mm` write it)
    those steps are lost with the reason and none is wrong; with the height signal off the
    estimator's own height change is not held to it."""
    import json

    seq = write_synthetic_sequence(tmp_path / "seq", CAM, _bounce_poses(), height_noise_mm=0.1)
    assert Sequence.open(seq).height_noise_mm == 0.1
    stated = run_estimator(seq, name, tmp_path / "stated")
    s = score_run(stated.run_dir, seq).flat()
    assert s["wrong_ok_steps"] == 0
    noisy = [r for r in stated.reason if r.startswith("height signal too noisy for the step: 2.5 x 1.414 x its stated")]
    assert len(noisy) > 20
    assert "0.100 mm = 0.354 mm > bound 0.13" in noisy[0]
    assert reason_kind(noisy[0]) == "height signal too noisy for the step"
    meta = json.loads((seq / "sequence.json").read_text())
    del meta["rig"]["height_noise_mm"]
    (seq / "sequence.json").write_text(json.dumps(meta))
    unstated = score_run(run_estimator(seq, name, tmp_path / "unstated").run_dir, seq).flat()
    assert unstated["wrong_ok_steps"] > 5
    meta["rig"]["height_noise_mm"] = 0.1
    (seq / "sequence.json").write_text(json.dumps(meta))
    off = {"use_height_signal": "false"}
    run_off = run_estimator(seq, name, tmp_path / "off", off)
    assert not any(r.startswith("height signal too noisy") for r in run_off.reason)


@pytest.mark.parametrize("name", ["phase-corr", "phase-corr-fast", "akaze-guided", "akaze-guided-fast"])
def test_a_height_reading_missing_at_the_first_frame_or_later_is_no_height_change(tmp_path, name):
    """A level run with the camera at 100.8 mm over a rig stated at 100 mm, a range sensor of
    0.01 mm: with the first frame's reading missing, the first step took the rig's height less
    the reading as its height change (0.77 mm off, reported ok). And phase-corr without the
    image scale converted a frame without a reading at the rig's height (every fifth reading
    missing, the camera at 102 mm: 8 steps ok and 2 mm off in height). Now a step's height
    change is the two readings' difference only where both frames have one; else the picture's
    (the image scale, where fitted) or none, and a frame without a reading keeps its reference's
    height. No step is wrong."""
    for h_mm, missing, over in ((100.8, [0], {}), (102.0, list(range(4, 34, 5)), {"fit_image_scale": "false"})):
        if over and not name.startswith("phase-corr"):
            continue
        poses = np.stack([T_world_cam_down(4.0 * i, 0.0, h_mm) for i in range(34)])
        seq = write_synthetic_sequence(tmp_path / f"seq{h_mm}", CAM, poses, height_noise_mm=0.01)
        h = read_height_csv(seq / HEIGHT_FILE)
        h[missing] = np.nan
        lines = ["frame,height_mm", *(f"{i},{'' if np.isnan(v) else f'{v:.6f}'}" for i, v in enumerate(h))]
        (seq / HEIGHT_FILE).write_text("\n".join(lines) + "\n")
        run = run_estimator(seq, name, tmp_path / f"run{h_mm}", over)
        s = score_run(run.run_dir, seq).flat()
        assert s["wrong_ok_steps"] == 0 and s["lost_frames"] == 0, (h_mm, [r for r in run.reason if r])


def test_homography_6dof_refines_its_plane_with_readings_of_a_stated_noise(tmp_path):
    """A range sensor of 1 mm noise, stated (rig.height_noise_mm), on an 8 mm/frame run with a
    1.5 mm bounce: held to its single readings within 1 % of the height, homography-6dof lost
    14 of 39 steps and restarted its plane at noisy readings (16 % end drift); allowed their
    noise, its plane started from one reading was up to 3 % off and 2 steps were ok and wrong.
    The readings now refine the plane's height (its variance from one reading's, shrinking with
    each), a step its uncertainty leaves beyond the bound is lost, and no step is: none is
    wrong, and the end drift is the run's without the signal or better."""
    poses = np.stack([T_world_cam_down(8.0 * i, 0.0, 100.0 + 1.5 * np.sin(2 * np.pi * i / 10)) for i in range(40)])
    seq = write_synthetic_sequence(tmp_path / "seq", CAM, poses, height_noise_mm=1.0)
    assert Sequence.open(seq).height_noise_mm == 1.0
    with_signal = score_run(run_estimator(seq, "homography-6dof", tmp_path / "with").run_dir, seq).flat()
    without = score_run(
        run_estimator(seq, "homography-6dof", tmp_path / "without", {"use_height_signal": "false"}).run_dir, seq
    ).flat()
    assert with_signal["wrong_ok_steps"] == 0 and with_signal["lost_frames"] == 0
    assert with_signal["end_drift_pct"] <= without["end_drift_pct"] + 0.01
    # 1.5 mm at 4 mm/frame: one reading leaves the plane too uncertain for a step; the steps so
    # lost refine the reference's plane with their readings, and tracking goes on (every step
    # had been lost, the plane never refined)
    slow = np.stack([T_world_cam_down(4.0 * i, 0.0, 100.0) for i in range(20)])
    seq = write_synthetic_sequence(tmp_path / "slow", CAM, slow, height_noise_mm=1.5, seed=5)
    run = run_estimator(seq, "homography-6dof", tmp_path / "slow_run")
    s = score_run(run.run_dir, seq).flat()
    assert s["wrong_ok_steps"] == 0 and s["lost_frames"] <= 4, list(run.reason)
    assert any(r.startswith("floor plane's height too uncertain for the step") for r in run.reason)


def test_a_height_signal_far_from_the_rig_height_is_said(tmp_path, caplog):
    """A range sensor mounted 5 mm off read 105 mm over a camera at 100 mm: every step was 5 %
    long without a word (the picture shows height changes, not the height). The run says so
    where the readings' median lies more than 2 % from rig.height_mm; within it, nothing."""
    poses = np.stack([T_world_cam_down(4.0 * i, 0.0, 100.0) for i in range(8)])
    seq = write_synthetic_sequence(tmp_path / "seq", CAM, poses, height_noise_mm=0.01)
    with caplog.at_level("WARNING", logger="floorvo"):
        run_estimator(seq, "phase-corr", tmp_path / "run")
    assert "rig.height_mm" not in caplog.text
    h = read_height_csv(seq / HEIGHT_FILE) + 5.0
    (seq / HEIGHT_FILE).write_text("\n".join(["frame,height_mm", *(f"{i},{v:.6f}" for i, v in enumerate(h))]) + "\n")
    with caplog.at_level("WARNING", logger="floorvo"):
        run_estimator(seq, "phase-corr", tmp_path / "run2")
        run_estimator(seq, "akaze-guided", tmp_path / "run3")  # once a sequence, not once a run
    assert caplog.text.count("lie 5.0 % from rig.height_mm (100.00 mm)") == 1


def test_runs_that_re_run_frames_of_a_run_already_said_do_not_warn_again(tmp_path, caplog):
    """A bench's match samples re-run pairs of frames of a run already scored: after the run's
    "19 step(s) lost" to a noisy height signal each pair warned "1 step(s) lost" again, which
    contradicted it. Without its summary warnings (``summary_warnings=False``) such a run says
    nothing; the run itself still does."""
    from floorvo.run import build_estimator
    from floorvo.runner import run_sequence

    poses = np.stack([T_world_cam_down(4.0 * i, 0.0, 100.0) for i in range(4)])
    seq = Sequence.open(write_synthetic_sequence(tmp_path / "seq", CAM, poses, height_noise_mm=0.1))
    est, _ = build_estimator(seq, "phase-corr")
    with caplog.at_level("WARNING", logger="floorvo"):
        run_sequence(seq, est, frames=[1, 2], summary_warnings=False)
    assert "step(s) lost" not in caplog.text
    est, _ = build_estimator(seq, "phase-corr")
    with caplog.at_level("WARNING", logger="floorvo"):
        run_sequence(seq, est)
    assert "3 step(s) lost: the height signal's stated noise" in caplog.text


@pytest.mark.parametrize(
    "name", ["phase-corr", "phase-corr-fast", "akaze-guided", "akaze-bruteforce", "homography-6dof"]
)
def test_a_height_signal_creeping_within_one_frames_check_is_lost(bounce_seqs, tmp_path, name):
    """A range reading creeping 0.8 mm a frame (a sensor drifting) passes the one-frame check
    against the picture, which allows 1 % of the height: every step after the creep began was
    reported ok and wrong (its height change 0.8 mm off against a 0.13 mm bound). Two of the
    last three steps disagreeing the same way now lose the step: at
    most the first two steps of the creep stay ok (the picture cannot tell a creep's first step
    from a misread frame), and the honest readings of the same bounce lose nothing so."""
    import shutil

    honest = run_estimator(bounce_seqs[0], name, tmp_path / "honest")
    assert not any("drifts from the picture" in r for r in honest.reason)
    seq = tmp_path / "seq"
    shutil.copytree(bounce_seqs[0], seq)
    h = read_height_csv(seq / "height.csv")
    h[10:] += 0.8 * np.arange(1, len(h) - 9)
    lines = ["frame,height_mm", *(f"{i},{v:.6f}" for i, v in enumerate(h))]
    (seq / "height.csv").write_text("\n".join(lines) + "\n")
    run = run_estimator(seq, name, tmp_path / "run")
    s = score_run(run.run_dir, seq).flat()
    assert s["wrong_ok_steps"] <= 2, s
    lost = [int(i) for i, st in zip(run.frame_index, run.status) if st == "lost"]
    drifted = [int(i) for i, r in zip(run.frame_index, run.reason) if "drifts from the picture" in r]
    # from the creep's third step on every frame is lost: by this check, or (a step across a lost
    # frame carries two frames' creep) by the one-frame check
    assert set(range(13, len(h))) <= set(lost), lost
    assert drifted and min(drifted) <= 13 and min(lost) >= 11, (lost, drifted)


def test_the_drift_check_passes_a_misread_frame_a_wrong_reading_and_a_bounce_read_short():
    """What a drifting height signal looks like, and what it does not (a unit check of
    floorvo.estimators.base.height_signal_drift_problem; bound 0.13 mm, picture's standard error
    0.02 mm, 2.5 of them, 0.2 mm that a picture may misread over several steps at 100 mm)."""
    from collections import deque

    from floorvo.estimators.base import HEIGHT_DRIFT_STEPS, height_signal_drift_problem

    def verdicts(steps):
        recent: deque = deque(maxlen=HEIGHT_DRIFT_STEPS)
        return [
            bool(height_signal_drift_problem(recent, sig, pic, 0.02, 0.13, 100.0, sigmas=2.5)) for sig, pic in steps
        ]

    level = [(0.0, 0.0)] * 3
    # one frame the picture misread by 0.6 mm, then agreement: never two of three
    assert not any(verdicts([*level, (0.0, 0.6), (0.0, 0.0), (0.0, 0.0)]))
    # a single reading 200 mm off: the one-frame checks judge it, and it stands for no drift after it
    assert not any(verdicts([*level, (200.0, 0.0), (-200.0, 0.0), (0.0, 0.0), (0.0, 0.6), (0.0, 0.0)]))
    # misreads every other frame, of either sign
    assert not any(verdicts([*level, (0.0, 0.6), (0.0, 0.0), (0.0, -0.6), (0.0, 0.0), (0.0, 0.6)]))
    # a bounce the picture reads at 85 % of each rise (0.8 mm a frame): the share is allowed
    assert not any(verdicts([(0.8, 0.68)] * 6))
    # the readings creep 0.5 mm a frame over a level floor: lost from the second step of the creep on
    assert verdicts([*level, (0.5, 0.0), (0.5, 0.0), (0.5, 0.0), (0.5, 0.0)]) == [False] * 4 + [True] * 3
    # and on a bounce the picture reads short (0.68 of 0.8 mm a frame)
    assert verdicts([*level, (1.3, 0.68), (1.3, 0.68), (1.3, 0.68)]) == [False] * 4 + [True] * 2
    # within the bound, 2.5 standard errors and the misread (0.13 + 0.05 + 0.2 mm) and the share: kept
    assert not any(verdicts([(0.4, 0.03)] * 6))
    # precision_sigmas = 0: no check
    recent: deque = deque(maxlen=HEIGHT_DRIFT_STEPS)
    assert not any(height_signal_drift_problem(recent, 0.5, 0.0, 0.02, 0.13, 100.0, sigmas=0.0) for _ in range(5))

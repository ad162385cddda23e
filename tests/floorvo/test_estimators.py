"""Estimators against known motion: synthetic warps made in code, and a tiny rendered sequence."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from _synth import frame_pair

from floorvo.camera import CameraModel
from floorvo.errors import ConfigError, FloorbenchError
from floorvo.estimators import Frame, get_estimator, list_estimators, make_config
from floorvo.estimators.akaze import mean_std_filter
from floorvo.geometry import T_world_cam_down, invert_T, rot_z, yaw_of_R

CAM = CameraModel.from_sensor(324, 247, pixel_pitch_um=14.8, focal_length_mm=6.0)  # GSD 0.2467 mm at 100 mm
MONO = ["phase-corr", "akaze-guided", "akaze-bruteforce"]
# Per-estimator tolerance on a synthetic pair: translation (mm), yaw (deg).
TOL = {"phase-corr": (0.01, 0.02), "akaze-guided": (0.03, 0.05), "akaze-bruteforce": (0.03, 0.05)}


def _motion(dx_mm: float, dy_mm: float, yaw_deg: float) -> np.ndarray:
    """T_prev_cur of a downward camera moving (dx, dy) in its own x-y plane and yawing."""
    T0 = T_world_cam_down(0.0, 0.0, 100.0)
    T1 = T_world_cam_down(dx_mm, -dy_mm, 100.0, np.radians(yaw_deg))
    return invert_T(T0) @ T1


def _run_pair(name: str, T_true: np.ndarray, seed: int = 0, flat: bool = True, frames: int = 2):
    prev, cur, flatfield = frame_pair(CAM, T_true, seed=seed)
    est = get_estimator(name)(make_config(name), CAM, height_mm=100.0, flatfield=flatfield if flat else None)
    st = est.start()
    r0 = est.step(st, Frame(0, 0.0, prev))
    r1 = est.step(st, Frame(1, 1 / 30, cur))
    return r0, r1


@pytest.mark.parametrize("name", MONO)
@pytest.mark.parametrize("dx, dy, yaw", [(4.0, 0.0, 0.0), (2.5, -1.2, 1.5)])
def test_recovers_known_translation_and_yaw(name, dx, dy, yaw):
    T_true = _motion(dx, dy, yaw)
    r0, r1 = _run_pair(name, T_true)
    assert r0.status == "init"
    assert r1.status == "ok", r1.reason
    t_tol, yaw_tol = TOL[name]
    np.testing.assert_allclose(r1.T_prev_cur[:2, 3], T_true[:2, 3], atol=t_tol)
    assert np.degrees(yaw_of_R(r1.T_prev_cur[:3, :3] @ T_true[:3, :3].T)) == pytest.approx(0.0, abs=yaw_tol)
    assert set(r1.timing_ms) >= {"detect", "match", "estimate", "total"}


@pytest.mark.parametrize("name", MONO)
def test_empty_frame_is_lost_not_an_exception(name):
    T_true = _motion(1.0, 0.0, 0.0)
    prev, cur, flat = frame_pair(CAM, T_true)
    est = get_estimator(name)(make_config(name), CAM, height_mm=100.0, flatfield=flat)
    st = est.start()
    est.step(st, Frame(0, 0.0, prev))
    r = est.step(st, Frame(1, 0.1, np.zeros_like(prev)))
    assert r.status == "lost" and r.reason and r.T_prev_cur is None
    # The run goes on: the next textured frame is tracked again, against the last frame kept
    # (frame 0, not the empty one), so its step is the motion from frame 0.
    r2 = est.step(st, Frame(2, 0.2, cur))
    assert r2.status == "ok", r2.reason
    np.testing.assert_allclose(r2.T_prev_cur[:2, 3], T_true[:2, 3], atol=TOL[name][0])


def test_one_instance_runs_two_sequences():
    name = "phase-corr"
    a = _motion(3.0, 0.0, 0.0)
    b = _motion(0.0, 2.0, 0.0)
    pa, ca, fa = frame_pair(CAM, a, seed=1)
    pb, cb, _ = frame_pair(CAM, b, seed=2)
    est = get_estimator(name)(make_config(name), CAM, height_mm=100.0, flatfield=fa)
    sa, sb = est.start(), est.start()
    est.step(sa, Frame(0, 0, pa))
    est.step(sb, Frame(0, 0, pb))
    ra, rb = est.step(sa, Frame(1, 0.1, ca)), est.step(sb, Frame(1, 0.1, cb))
    np.testing.assert_allclose(ra.T_prev_cur[:2, 3], a[:2, 3], atol=0.02)
    np.testing.assert_allclose(rb.T_prev_cur[:2, 3], b[:2, 3], atol=0.02)


def test_mean_std_filter_hand_computed():
    m = np.array([[1.0, 0.0], [1.1, 0.0], [0.9, 0.0], [1.0, 0.05], [5.0, 0.0]])
    keep = mean_std_filter(m, passes=1)
    # mean x = 1.8, std x = 1.6: keeps 0.2..3.4 -> drops 5.0; y: mean 0.01, std 0.02 -> drops 0.05
    assert keep.tolist() == [True, True, True, False, False]


def test_bad_config_refused_by_name():
    with pytest.raises(ConfigError, match=r"akaze-guided.hamming_threshold = 0: must be >= 1"):
        make_config("akaze-guided", {"hamming_threshold": "0"})
    with pytest.raises(ConfigError, match=r"phase-corr.grid = 'many': must be int"):
        make_config("phase-corr", {"grid": "many"})
    with pytest.raises(ConfigError, match=r"phase-corr.bogus: unknown config key"):
        make_config("phase-corr", {"bogus": "1"})
    # every key of akaze-guided made a line of about 510 characters: the closest ones, and where the rest are
    with pytest.raises(ConfigError) as info:
        make_config("akaze-guided", {"hamming_treshold": "3"})
    assert str(info.value) == (
        "akaze-guided.hamming_treshold: unknown config key (did you mean hamming_threshold, akaze_threshold or "
        "adapt_threshold? every key: floorvo list --config akaze-guided)"
    )
    with pytest.raises(ConfigError, match=r"^akaze-guided.zzz: unknown config key \(every key: floorvo list --config"):
        make_config("akaze-guided", {"zzz": "3"})
    with pytest.raises(ConfigError, match="unknown"):
        get_estimator("no-such-estimator")


def test_registry_lists_paper_estimators():
    assert set(MONO) <= set(list_estimators())


@pytest.fixture(scope="module")
def rendered_p0u(tmp_path_factory):
    """``render(overrides)``: paper000_uniform at half size (324x247) with ``--set`` overrides, rendered once per module."""
    from floorsim.scene import load_scene
    from floorsim.simulate import render_sequence

    cache = {}

    def render(**overrides):
        key = tuple(sorted(overrides.items()))
        if key not in cache:
            root = tmp_path_factory.mktemp("p0u")
            cache[key] = render_sequence(load_scene("paper000_uniform", overrides), root / "seq", scale=0.5)
        return cache[key]

    return render


def _end_error_pct(run, seq) -> float:
    """End-point error of a run as % of the distance travelled (from the two TUM files)."""
    from floorvo.tum import read_tum

    _, T_est = read_tum(run / "trajectory.txt")
    _, T_gt = read_tum(seq / "groundtruth.txt")
    end_err = np.linalg.norm(T_est[-1][:3, 3] - T_gt[-1][:3, 3])
    travelled = np.linalg.norm(T_gt[-1][:3, 3] - T_gt[0][:3, 3])
    assert travelled == pytest.approx(100.0)
    return 100 * end_err / travelled


@pytest.mark.render
@pytest.mark.parametrize(
    "shadows, limits",
    [
        # Shading only: the picture moves rigidly with the floor, so the estimators' own
        # errors remain.
        (False, {"phase-corr": 0.1, "akaze-guided": 0.1, "akaze-bruteforce": 0.2}),
        # With the relief's cast shadows the image moves about 0.25 % faster than the floor
        # along the LED-bar axis (x here): the shadows lengthen with the distance from
        # the bar they point away from (BENCHMARKS.md). Every estimator still ends within
        # 0.5 %, far under paper 001's 0.783 %; calibrated, within 0.2 % (next test).
        (True, {"phase-corr": 0.5, "akaze-guided": 0.5, "akaze-bruteforce": 1.0}),
    ],
)
def test_rendered_paper000_uniform_distance(tmp_path, rendered_p0u, shadows, limits):
    """Every mono estimator ends near the 100 mm travelled on the rendered paper-000 run."""
    from floorvo.run import run_estimator
    from floorvo.scoring import score_run

    seq = rendered_p0u(**{"render.shadows": str(shadows).lower()})
    for name in MONO:
        run = tmp_path / name
        res = run_estimator(seq, name, run)
        assert res.lost == 0
        err = _end_error_pct(run, seq)
        assert err < limits[name], f"{name}: end error {err:.3f} %"
        score = score_run(run, seq)
        assert json.loads(json.dumps(score.to_dict()))  # the score serialises


@pytest.mark.render
def test_rendered_paper000_uniform_calibrated(tmp_path, rendered_p0u):
    """The rig's scale fitted on one stretch of floor brings the paper-000 run within 0.2 %.

    Calibration run: the same rig 300 mm further along another stretch of the floor (other
    relief, other shadows); the scale is applied to the shipped paper000_uniform run.
    """
    from floorvo.calibration import calibrate_run
    from floorvo.run import run_estimator

    cal_seq = rendered_p0u(**{"render.shadows": "true", "trajectory.start_x_mm": 300.0, "trajectory.start_y_mm": 40.0})
    seq = rendered_p0u(**{"render.shadows": "true"})
    for name in ("phase-corr", "akaze-guided"):
        run_estimator(cal_seq, name, tmp_path / f"cal-{name}")
        cal = calibrate_run(tmp_path / f"cal-{name}", cal_seq)
        assert cal.observed_x and not cal.observed_y
        assert 1.0 < cal.scale_x < 1.01, cal  # the shadows read long along x
        run_estimator(seq, name, tmp_path / name)
        raw = _end_error_pct(tmp_path / name, seq)
        run_estimator(seq, name, tmp_path / f"{name}-cal", scale_calibration=cal)
        calibrated = _end_error_pct(tmp_path / f"{name}-cal", seq)
        assert calibrated < 0.2, f"{name}: end error {raw:.3f} % raw, {calibrated:.3f} % calibrated"
        assert calibrated < raw


def test_run_refuses_bad_sequence_before_any_frame(tmp_path):
    from floorvo.run import run_estimator
    from floorvo.sequence import SequenceWriter

    meta = {"camera": CAM.to_dict(), "fps": 30.0, "frame_count": 2, "rig": {"height_mm": 100.0}}
    w = SequenceWriter(tmp_path / "seq", meta)
    prev, cur, _ = frame_pair(CAM, _motion(1.0, 0, 0))
    w.write_frame(0, prev)  # frame 1 missing
    with pytest.raises(FloorbenchError, match="000001.png: frame file is missing"):
        run_estimator(tmp_path / "seq", "phase-corr", tmp_path / "run")
    # Frame 0 was processed before the missing frame was found; nothing half-written remains.
    assert not (tmp_path / "run" / "trajectory.txt").exists()


@pytest.mark.parametrize("yaw_deg", [1.5, 8.0])
def test_refined_pairs_land_on_the_true_motion_to_a_tenth_of_a_pixel(yaw_deg):
    """``refine_window_px`` (Lucas-Kanade from each previous keypoint's window): pairs whose current
    positions are off by 0.5 px RMS (what AKAZE's keypoints are off by on rendered floors) are
    moved onto where the true motion puts them, to under a twentieth of a pixel, and the motion
    fitted again on them is closer to the true one than the fit of the noisy pairs. On a turn of
    8 degrees too: the window is compared with the previous picture turned by the pairs' motion
    (Lucas-Kanade compared with the unturned picture left the pairs 0.24 px off, median, and
    read the turn 0.025 degrees short)."""
    from _synth import pixel_motion

    from floorvo.estimators.akaze import _Fit

    T_true = _motion(2.5, -1.2, yaw_deg)
    prev, cur, flat = frame_pair(CAM, T_true, seed=3)
    est = get_estimator("akaze-guided")(
        make_config("akaze-guided", {"refine_window_px": "21"}), CAM, height_mm=100.0, flatfield=flat
    )
    state = est.start()
    assert est.step(state, Frame(0, 0.0, prev)).status == "init"
    M = pixel_motion(T_true, CAM, 100.0)
    rng = np.random.default_rng(0)
    src = np.column_stack([rng.uniform(40, CAM.width_px - 40, 200), rng.uniform(40, CAM.height_px - 40, 200)])
    true_dst = est._predict(M, src)
    noisy = true_dst + rng.normal(0.0, 0.5, true_dst.shape)
    fit = _Fit(est._rigid_px(src, noisy), src, noisy, len(src))
    refined = est._refined(state, fit, est._detect(cur)[2], None)
    off_before = np.linalg.norm(fit.dst - est._predict(M, fit.src), axis=1)
    off_after = np.linalg.norm(refined.dst - est._predict(M, refined.src), axis=1)
    assert len(refined.src) >= 0.9 * len(src)
    assert np.median(off_after) < 0.05 < 0.5 < np.median(off_before) + 0.1
    yaw_err_deg = np.degrees(np.arctan2(refined.M[1, 0], refined.M[0, 0]) - np.arctan2(M[1, 0], M[0, 0]))
    assert abs(yaw_err_deg) < 0.005
    corner = np.array([[0.0, 0.0], [CAM.width_px - 1.0, CAM.height_px - 1.0]])
    err_before = np.abs(est._predict(fit.M, corner) - est._predict(M, corner)).max()
    err_after = np.abs(est._predict(refined.M, corner) - est._predict(M, corner)).max()
    assert err_after < 0.05 and err_after < err_before / 2
    # OpenCV's Lucas-Kanade asserts on a window under 3 px: refused in one line instead.
    with pytest.raises(ConfigError, match=r"refine_window_px = 2: must be 0 \(off\) or >= 3"):
        make_config("akaze-guided", {"refine_window_px": "2"})


@pytest.mark.parametrize("seed", [0, 1])
def test_subpixel_preset_tracks_a_turning_step_on_refined_pairs(seed):
    """``akaze-guided-subpixel`` is akaze-guided with ``refine_window_px = 21``: listed, and it
    measures a 6-degree turning step within 3 um and 0.005 degrees on a synthetic pair."""
    from floorvo.estimators.akaze import AkazeGuidedSubpixel

    assert "akaze-guided-subpixel" in list_estimators()
    assert get_estimator("akaze-guided-subpixel") is AkazeGuidedSubpixel
    assert make_config("akaze-guided-subpixel").refine_window_px == 21
    # Only refine_window_px differs from akaze-guided's defaults.
    sub_off = dataclasses.asdict(make_config("akaze-guided-subpixel", {"refine_window_px": "0"}))
    assert sub_off == dataclasses.asdict(make_config("akaze-guided"))
    T_true = _motion(2.5, -1.2, 6.0)
    _, r1 = _run_pair("akaze-guided-subpixel", T_true, seed=seed)
    assert r1.status == "ok", r1.reason
    np.testing.assert_allclose(r1.T_prev_cur[:2, 3], T_true[:2, 3], atol=0.003)
    assert np.degrees(yaw_of_R(r1.T_prev_cur[:3, :3] @ T_true[:3, :3].T)) == pytest.approx(0.0, abs=0.005)


@pytest.mark.parametrize("name", ["akaze-guided", "akaze-guided-fast"])
def test_a_turn_that_starts_between_two_frames_is_found_from_the_last_motion_turned(name, monkeypatch):
    """``turn_sweep_deg``: a straight step, then one that turns 8 degrees (a robot starting a turn
    between two frames) on a floor where brute force finds no motion (a repetitive floor; here
    brute force is made to find none). The eq. (2) prediction misses the keypoints by up to
    55 px; matched from the last motion turned by 2.5, 5, 7.5 ... degrees, the step is measured
    within akaze-guided's tolerance and says how. With the sweep off it is lost."""
    from _synth import frames_along

    from floorvo.estimators.akaze import _Fit

    poses = [T_world_cam_down(0.0, 0.0, 100.0), T_world_cam_down(4.0, 0.0, 100.0)]
    poses.append(poses[1] @ _motion(4.0, 0.0, 8.0))
    frames, flat = frames_along(CAM, poses)
    T_true = invert_T(poses[1]) @ poses[2]
    nothing = _Fit(None, np.zeros((0, 2)), np.zeros((0, 2)), 0, problem="(made to find nothing)", no_motion=True)
    for sweep, status in (("15", "ok"), ("0", "lost")):
        est = get_estimator(name)(make_config(name, {"turn_sweep_deg": sweep}), CAM, height_mm=100.0, flatfield=flat)
        st = est.start()
        assert [est.step(st, Frame(i, i / 30, frames[i])).status for i in (0, 1)] == ["init", "ok"]
        monkeypatch.setattr(est, "_bruteforce_fit", lambda *a, **k: (nothing, ""))
        r = est.step(st, Frame(2, 2 / 30, frames[2]))
        assert r.status == status, r.reason
        assert "guided prediction doubtful" in r.reason and "(made to find nothing)" in r.reason
        if status == "ok":
            assert "matched guided from the last motion turned by" in r.reason
            np.testing.assert_allclose(r.T_prev_cur[:2, 3], T_true[:2, 3], atol=TOL["akaze-guided"][0])
            yaw_err = np.degrees(yaw_of_R(r.T_prev_cur[:3, :3] @ T_true[:3, :3].T))
            assert yaw_err == pytest.approx(0.0, abs=TOL["akaze-guided"][1])


def test_turned_predictions_that_fit_two_motions_leave_the_step_lost(monkeypatch):
    """The decision of ``_turned_fit``, by hand: of the turns tried, a fit counts only with twice the
    evidence a fit needs (here 16 pairs and 40 % of the matches); the counted fits must agree within
    issue 14's bound with the one of most pairs. Two that are 3 degrees apart: lost, 'the turns
    disagree'; with the weaker one under the evidence, the stronger is taken."""
    from floorvo.estimators.akaze import _Fit, _State

    est = get_estimator("akaze-guided")(make_config("akaze-guided"), CAM, height_mm=100.0)
    st = _State()
    st.M_last = np.eye(3)
    st.M_last[0, 2] = 32.0

    def turned(deg: float) -> np.ndarray:
        return rot_z(np.radians(deg)) @ st.M_last

    def run(fits: dict[float, tuple[int, float]]):
        def fake_fit(src, dst, M, scale=1.0, ransac=False):
            deg = round(float(np.degrees(np.arctan2(M[1, 0], M[0, 0]))), 3)
            if deg not in fits:
                return _Fit(None, src, dst, 100, problem="no fit here", no_motion=True)
            n, consensus = fits[deg]
            return _Fit(turned(deg + 0.2), np.zeros((n, 2)), np.zeros((n, 2)), 100, consensus=consensus)

        monkeypatch.setattr(est, "_guided", lambda *a, **k: (np.zeros((0, 2)), np.zeros((0, 2))))
        monkeypatch.setattr(est, "_fit", fake_fit)
        monkeypatch.setattr(est, "_rematch_problem", lambda *a, **k: "")
        monkeypatch.setattr(est, "_prediction_doubt", lambda *a, **k: "")
        return est._turned_fit(st, np.zeros((0, 2)), np.zeros((0, 61), np.uint8), 1.0)

    fit, how = run({-7.5: (60, 0.5), -5.0: (30, 0.45)})
    assert fit is not None and fit.problem.endswith("the turns disagree") and how == ""
    fit, how = run({-7.5: (60, 0.5), -5.0: (30, 0.3)})  # 30 % of the matches: under the evidence
    assert fit is not None and not fit.problem and len(fit.src) == 60
    assert how == "matched guided from the last motion turned by -7.5 deg (1 of 12 turns fit, and agree)"
    fit, how = run({-5.0: (15, 0.9)})  # 15 pairs: under 2 x min_inliers
    assert fit is None and how == ""


def test_a_fit_the_filter_cannot_find_is_found_from_ransac_pairs_and_random_pairs_stay_lost():
    """Brute-force matches on a repetitive floor: 30 % follow the true motion (a 24 px shift and
    2 degrees), 70 % go to like keypoints elsewhere. The section II-C filter keeps the band about
    the mean movement of all of them, which holds no motion: the fit fails a check. Fitted on the
    pairs a RANSAC similarity finds in agreement (``ransac_retry``) it passes every check, keeps the
    true pairs, and is the true motion to 0.2 px at the frame's corners (the pairs' noise is 0.3 px).
    Pairs that are all random (a featureless floor) stay
    lost either way."""
    from _synth import pixel_motion

    est = get_estimator("akaze-guided")(make_config("akaze-guided"), CAM, height_mm=100.0)
    M = pixel_motion(_motion(24 * CAM.gsd_mm_per_px(100.0), 0.0, 2.0), CAM, 100.0)
    rng = np.random.default_rng(1)
    src = np.column_stack([rng.uniform(10, CAM.width_px - 10, 200), rng.uniform(10, CAM.height_px - 10, 200)])
    dst = est._predict(M, src) + rng.normal(0.0, 0.3, src.shape)
    wrong = rng.random(200) < 0.7
    dst[wrong] = np.column_stack(
        [rng.uniform(0, CAM.width_px, wrong.sum()), rng.uniform(0, CAM.height_px, wrong.sum())]
    )
    assert est._fit(src, dst, np.eye(3), 1.0).problem
    fit = est._fit(src, dst, np.eye(3), 1.0, ransac=True)
    assert fit.problem == "" and fit.M is not None
    corners = np.array([[0.0, 0.0], [CAM.width_px - 1.0, CAM.height_px - 1.0]])
    assert np.abs(est._predict(fit.M, corners) - est._predict(M, corners)).max() < 0.2
    assert len(fit.src) >= 0.8 * (~wrong).sum()
    noise = np.column_stack([rng.uniform(0, CAM.width_px, 200), rng.uniform(0, CAM.height_px, 200)])
    assert est._fit(src, noise, np.eye(3), 1.0).problem and est._fit(src, noise, np.eye(3), 1.0, ransac=True).problem


def test_a_step_given_no_state_or_another_estimators_state_is_one_typeerror(tmp_path):
    """A step before start() (state None) or with another estimator's state raised an
    AttributeError from deep inside the step ('NoneType' object has no attribute 'prev'); each
    built-in now names the rule first, and its own state still works."""
    from floorvo.run import build_estimator
    from floorvo.sequence import Sequence
    from floorvo.synthetic import line_poses, write_synthetic_sequence

    cam = CameraModel.from_sensor(162, 124, pixel_pitch_um=29.6, focal_length_mm=6.0)
    seq = Sequence.open(
        write_synthetic_sequence(tmp_path / "s", cam, line_poses(4.0, 4.0), depth=True, stereo_baseline_mm=20.0)
    )
    frame = Frame(0, 0.0, seq.image(0), image_right=seq.image(0, "cam1"), depth_mm=seq.depth_mm(0))
    other = build_estimator(seq, "phase-corr")[0].start()
    for name in ("phase-corr", "akaze-guided", "homography-6dof", "orb-icp", "stereo-sift"):
        est = build_estimator(seq, name)[0]
        for state in (None, {}, other if name != "phase-corr" else build_estimator(seq, "orb-icp")[0].start()):
            with pytest.raises(
                TypeError, match=rf"{name}: step\(\) takes the state this estimator's start\(\) returned"
            ):
                est.step(state, frame)
        assert est.step(est.start(), frame).status == "init"

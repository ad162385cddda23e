"""Estimators on motion that is not a constant-speed straight line, and on input they cannot track.

Issue 14: an estimator reports ``lost`` with a reason instead of a wrong step. A step
reported ok is held to the issue's bound: 0.05 mm + 2 % of the true step in translation,
0.3 degrees in yaw. Frames are code-made (:mod:`floorvo.synthetic`: an exact warp of a
procedural floor texture, LED falloff, 1 DN noise) at the paper-000 camera's full size,
where paper 000's steps are as many pixels as on the rig.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from floorvo.camera import CameraModel
from floorvo.estimators import Frame, get_estimator, make_config
from floorvo.estimators.akaze import _State
from floorvo.geometry import T_world_cam_down, invert_T, yaw_of_R
from floorvo.sequence import Sequence
from floorvo.synthetic import led_falloff, write_synthetic_sequence

CAM = CameraModel.from_sensor(648, 494, pixel_pitch_um=7.4, focal_length_mm=6.0)  # GSD 0.1233 mm at 100 mm
MONO = ["phase-corr", "phase-corr-fast", "akaze-guided", "akaze-bruteforce"]


def _step_error(T_est: np.ndarray, T_true: np.ndarray) -> tuple[float, float]:
    """Translation error (mm) and yaw error (deg) of one step."""
    e_t = float(np.linalg.norm(T_est[:2, 3] - T_true[:2, 3]))
    e_yaw = abs(float(np.degrees(yaw_of_R(T_est[:3, :3] @ T_true[:3, :3].T))))
    return e_t, e_yaw


def _within_bound(T_est: np.ndarray, T_true: np.ndarray) -> bool:
    e_t, e_yaw = _step_error(T_est, T_true)
    return e_t <= 0.05 + 0.02 * float(np.linalg.norm(T_true[:2, 3])) and e_yaw <= 0.3


def _step_frames(name: str, frames, overrides: dict | None = None, flatfield=None) -> list:
    """Estimator ``name`` (config ``overrides``) stepped over the frames (uint8 images of ``CAM``, 30 fps)."""
    est = get_estimator(name)(make_config(name, overrides), CAM, height_mm=100.0, flatfield=flatfield)
    state = est.start()
    return [est.step(state, Frame(i, i / 30.0, img)) for i, img in enumerate(frames)]


def _assert_every_step_ok_within_bound(name: str, seq: Sequence) -> list:
    """Run ``name`` over ``seq``: the first frame ``init``, every step ``ok`` and within issue 14's
    bound of the synthetic truth. Returns the step results."""
    results, truth = _run(name, seq)
    assert [r.status for r in results] == ["init"] + ["ok"] * (len(results) - 1), [r.reason for r in results]
    for r, T in zip(results[1:], truth):
        assert _within_bound(r.T_prev_cur, T), _step_error(r.T_prev_cur, T)
    return results[1:]


def _run(name: str, seq: Sequence, **overrides):
    """Step results of estimator ``name`` over every frame of ``seq``, and the true steps T_prev_cur."""
    est = get_estimator(name)(make_config(name, overrides), seq.camera, height_mm=100.0, flatfield=seq.flatfield())
    state = est.start()
    results = [est.step(state, Frame(i, i / 30.0, seq.image(i))) for i in range(seq.frame_count)]
    T = seq.groundtruth()[1]
    return results, [invert_T(T[i - 1]) @ T[i] for i in range(1, len(T))]


def _sequence(tmp_path, xy_yaw: list[tuple[float, float, float]], seed: int = 0) -> Sequence:
    poses = np.stack([T_world_cam_down(x, y, 100.0, np.radians(yaw)) for x, y, yaw in xy_yaw])
    return Sequence.open(write_synthetic_sequence(tmp_path / "seq", CAM, poses, seed=seed))


def test_guided_matching_follows_paper000_sigmoid_acceleration(tmp_path):
    """Paper 000's sigmoid model on the 1-mm strip: steps 1, 2, 4, 2, 1 mm (10 mm in all).

    The steepest step is 4 mm predicted from the previous 2 mm (eq. (2)): the true matches
    lie 16 px from the prediction. The guided search must reach them and take them over
    nearer keypoints of other floor points; before the fix it measured the 4 mm step as
    2 mm (the prediction) and the run as 8 mm.
    """
    seq = _sequence(tmp_path, [(x, 0.0, 0.0) for x in (0.0, 1.0, 3.0, 7.0, 9.0, 10.0)])
    results, truth = _run("akaze-guided", seq)
    assert results[0].status == "init"
    for k, (res, T_true) in enumerate(zip(results[1:], truth), start=1):
        assert res.status == "ok", f"step {k}: {res.reason}"
        assert _within_bound(res.T_prev_cur, T_true), f"step {k}: error {_step_error(res.T_prev_cur, T_true)}"
    # Steps 2 onwards are matched by the guided search itself, not by a brute-force fallback.
    assert all(r.reason == "" for r in results[2:]), [r.reason for r in results[2:]]
    total = sum(float(r.T_prev_cur[0, 3]) for r in results[1:])
    assert total == pytest.approx(10.0, abs=0.05)


def test_doubtful_prediction_falls_back_to_brute_force(tmp_path):
    """The rig reverses (+4 mm, then -4 mm): the eq. (2) prediction is 65 px off, beyond the
    guided search; the step is matched again by brute force, measured right and says so."""
    seq = _sequence(tmp_path, [(0.0, 0.0, 0.0), (4.0, 0.0, 0.0), (8.0, 0.0, 0.0), (4.0, 0.0, 0.0)])
    results, truth = _run("akaze-guided", seq)
    assert [r.status for r in results] == ["init", "ok", "ok", "ok"], [r.reason for r in results]
    for res, T_true in zip(results[1:], truth):
        assert _within_bound(res.T_prev_cur, T_true), _step_error(res.T_prev_cur, T_true)
    assert results[2].reason == ""
    assert "guided prediction doubtful" in results[3].reason and "brute force" in results[3].reason
    assert results[3].timing_ms["match"] > 0
    # A run writes the reason of every frame, the fallback's too, in timing.csv.
    from floorvo.run import run_estimator
    from floorvo.runfolder import RunFolder

    run_estimator(seq, "akaze-guided", tmp_path / "run")
    timing = RunFolder.read(tmp_path / "run").timing
    assert list(timing["status"]) == ["init", "ok", "ok", "ok"]
    assert timing["reason"][2] == "" and "brute force" in timing["reason"][3]


def test_guided_prediction_on_a_turn_whose_rate_changes(tmp_path):
    """Yaw rate 0, +4, -4 degrees per frame at 4 mm/frame (an S-bend): the prediction from the
    last turn is wrong by 8 degrees (up to 37 px at the frame's corners). Every step is
    right or refused; none is a wrong step reported ok."""
    seq = _sequence(tmp_path, [(0.0, 0.0, 0.0), (4.0, 0.0, 0.0), (8.0, 0.3, 4.0), (12.0, 0.3, 0.0)])
    results, truth = _run("akaze-guided", seq)
    assert results[0].status == "init"
    for k, (res, T_true) in enumerate(zip(results[1:], truth), start=1):
        assert res.status == "ok", f"step {k}: {res.reason}"
        assert _within_bound(res.T_prev_cur, T_true), f"step {k}: {_step_error(res.T_prev_cur, T_true)}"


def _featureless_frames(n: int, seed: int = 0) -> tuple[list[np.ndarray], np.ndarray]:
    """A flat, uniform floor under the LEDs: the LED falloff and 1 DN of sensor noise, nothing that moves."""
    rng = np.random.default_rng(seed)
    fall = led_falloff(CAM)
    base = fall / fall.max() * 200.0
    frames = [np.clip(np.round(base + rng.normal(0.0, 1.0, base.shape)), 0, 255).astype(np.uint8) for _ in range(n)]
    flat = np.clip(fall / fall.max() * 60000.0, 0, 65535).astype(np.uint16)
    return frames, flat


@pytest.mark.parametrize("name", MONO)
def test_featureless_floor_is_lost_not_a_wrong_motion(name):
    """Noise alone gives keypoints and matches, but no motion: every step is lost with a reason."""
    frames, flat = _featureless_frames(4)
    results = _step_frames(name, frames, flatfield=flat)
    assert results[0].status in ("init", "lost")
    for r in results[1:]:
        assert r.status == "lost" and r.T_prev_cur is None and r.reason, (r.status, r.reason)


@pytest.mark.parametrize("name", MONO)
@pytest.mark.parametrize(
    "shape, rule",
    [((240, 320), "320x240 px: the camera is 648x494"), ((494, 648, 3), "3 channels")],
)
def test_frame_of_the_wrong_size_or_channels_is_refused(tmp_path, name, shape, rule):
    """A wrong frame is lost with a reason naming the problem (no exception, no motion), and
    the next frame is measured against the last good one."""
    seq = _sequence(tmp_path, [(0.0, 0.0, 0.0), (2.0, 0.0, 0.0)])
    est = get_estimator(name)(make_config(name), CAM, height_mm=100.0, flatfield=seq.flatfield())
    state = est.start()
    assert est.step(state, Frame(0, 0.0, seq.image(0))).status == "init"
    bad = np.zeros(shape, np.uint8)
    bad[...] = seq.image(1)[: shape[0], : shape[1], None] if len(shape) == 3 else seq.image(1)[: shape[0], : shape[1]]
    r = est.step(state, Frame(1, 1 / 30.0, bad))
    assert r.status == "lost" and r.T_prev_cur is None
    assert rule in r.reason
    r2 = est.step(state, Frame(2, 2 / 30.0, seq.image(1)))
    assert r2.status == "ok", r2.reason
    T_true = invert_T(seq.groundtruth()[1][0]) @ seq.groundtruth()[1][1]
    assert _within_bound(r2.T_prev_cur, T_true), _step_error(r2.T_prev_cur, T_true)


@pytest.mark.parametrize("name", MONO)
@pytest.mark.parametrize("first", [True, False], ids=["first frame", "later frame"])
def test_a_float_frame_with_nan_or_inf_is_lost_with_a_reason(tmp_path, name, first):
    """A float frame holding NaN raised 'cannot convert float NaN to integer' from inside
    phase-corr; it is lost with a reason, and tracking goes on from the good frames."""
    seq = _sequence(tmp_path, [(0.0, 0.0, 0.0), (2.0, 0.0, 0.0)])
    est = get_estimator(name)(make_config(name), CAM, height_mm=100.0, flatfield=seq.flatfield())
    state = est.start()
    bad = seq.image(1).astype(np.float32)
    bad[100:110, 200:260] = np.nan
    bad[300, 300] = np.inf
    frames = [bad, seq.image(0), seq.image(1)] if first else [seq.image(0), bad, seq.image(1)]
    results = [est.step(state, Frame(i, i / 30.0, f)) for i, f in enumerate(frames)]
    k = 0 if first else 1
    assert results[k].status == "lost" and results[k].T_prev_cur is None
    assert "frame has 601 pixel(s) that are NaN or infinite: finite values are expected" in results[k].reason
    assert results[2].status == "ok", results[2].reason
    T_true = invert_T(seq.groundtruth()[1][0]) @ seq.groundtruth()[1][1]
    assert _within_bound(results[2].T_prev_cur, T_true), _step_error(results[2].T_prev_cur, T_true)


@pytest.mark.parametrize("name", MONO)
def test_tracking_restarts_after_lost_frames(tmp_path, name):
    """The rig is carried to unrelated floor (a kidnap): the frames there are lost against the
    last good one, then tracking restarts from the current frame (``restart_after_lost``) and
    the next step is measured again."""
    seq = _sequence(tmp_path, [(0.0, 0.0, 0.0), (2.0, 0.0, 0.0), (500.0, 0.0, 0.0), (502.0, 0.0, 0.0), (504.0, 0, 0)])
    results, truth = _run(name, seq)
    assert [r.status for r in results] == ["init", "ok", "lost", "lost", "ok"], [r.reason for r in results]
    assert "restarts" not in results[2].reason and "tracking restarts from this frame" in results[3].reason
    assert _within_bound(results[4].T_prev_cur, truth[3]), _step_error(results[4].T_prev_cur, truth[3])


DISTORTED = {
    # Issue 14's lens (k1 = -0.3, k2 = 0.1), the paper-000 camera otherwise.
    "distorted": CameraModel(648, 494, CAM.fx_px, CAM.fy_px, CAM.cx_px, CAM.cy_px, (-0.3, 0.1, 0.0, 0.0, 0.0)),
    # The same lens with 5 % taller pixels and the principal point 25 px right, 15 px up of the centre.
    "distorted_nonsquare_offset": CameraModel(
        648, 494, CAM.fx_px, 1.05 * CAM.fx_px, CAM.cx_px + 25.0, CAM.cy_px - 15.0, (-0.3, 0.1, 0.001, -0.001, 0.0)
    ),
}


@pytest.fixture(scope="module")
def distorted_sequences(tmp_path_factory):
    """A diagonal run of 3 mm steps turning 0.5 degrees a frame, seen by each camera of ``DISTORTED``."""
    d = 0.6
    poses = np.stack(
        [T_world_cam_down(3.0 * i * np.cos(d), 3.0 * i * np.sin(d), 100.0, np.radians(0.5 * i)) for i in range(5)]
    )
    root = tmp_path_factory.mktemp("distorted")
    return {k: Sequence.open(write_synthetic_sequence(root / k, cam, poses, seed=3)) for k, cam in DISTORTED.items()}


@pytest.mark.parametrize("camera", list(DISTORTED))
@pytest.mark.parametrize("name", MONO)
def test_every_mono_estimator_honours_the_whole_camera_model(distorted_sequences, name, camera):
    """Frames of a distorted camera (and one with non-square pixels and an offset principal
    point), made by inverting the camera model exactly (:mod:`floorvo.synthetic`): every
    step within 0.005 mm and 0.01 degrees of the truth (on an ideal camera phase-corr is
    0.0011-0.0013 mm off here). phase-corr ignored the distortion before: every step was
    0.054-0.057 mm (1.9 %) short."""
    seq = distorted_sequences[camera]
    assert seq.camera == DISTORTED[camera]
    results, truth = _run(name, seq)
    assert [r.status for r in results] == ["init"] + ["ok"] * 4, [r.reason for r in results]
    for r, T in zip(results[1:], truth):
        e_t, e_yaw = _step_error(r.T_prev_cur, T)
        assert e_t < 0.005 and e_yaw < 0.01, (e_t, e_yaw)


@pytest.mark.parametrize("name", ["akaze-guided", "akaze-guided-fast", "akaze-bruteforce-fast", "homography-6dof"])
def test_akaze_estimators_fit_a_wide_angle_lens_in_its_pinhole(tmp_path, name):
    """A wide-angle lens (k1 = -0.4, the paper-000 camera otherwise), frames made by inverting
    the camera model exactly: the AKAZE estimators fitted their pairs in the lens's own pixels,
    where the floor's motion is not rigid, so the pairs the fit left out agreed on a second
    motion and every step was lost ("two motions"; at k1 = -0.25 the presets' image scale read
    the distortion as a rising camera: steps 5.7 % short, 2 of 39 reported ok and wrong). They
    fit in the ideal pinhole's pixels now: every step ok, within issue 14's bound of the truth,
    and the fitted image scale (the presets' ``fit_image_scale``) reads no height change."""
    cam = CameraModel(648, 494, CAM.fx_px, CAM.fy_px, CAM.cx_px, CAM.cy_px, (-0.4, 0.0, 0.0, 0.0, 0.0))
    poses = np.stack([T_world_cam_down(4.0 * i, 0.3 * i, 100.0, np.radians(0.3 * i)) for i in range(5)])
    seq = Sequence.open(write_synthetic_sequence(tmp_path / "seq", cam, poses, seed=1))
    for r in _assert_every_step_ok_within_bound(name, seq):
        assert abs(r.T_prev_cur[2, 3]) < 0.02, r.T_prev_cur[2, 3]


@pytest.mark.parametrize("name", ["phase-corr", "phase-corr-fast"])
@pytest.mark.parametrize(
    "camera",
    [
        # The principal point 124 px left of and 107 px above the centre of the paper-000 frame.
        CameraModel(648, 494, CAM.fx_px, CAM.fy_px, 200.0, 140.0),
        # 320x240, the principal point 20 px above the centre: a 216 px crop fits centred only
        # within 12 px of the middle. With lens distortion, so the rectified region is cut too.
        CameraModel(320, 240, 400.0, 400.0, 165.0, 99.5, (-0.2, 0.05, 0.0, 0.0, 0.0)),
        # At the top-left pixel's centre: phase-corr-fast's grid binned 2 x 2 has it at (-0.25, -0.25),
        # in the image but refused by a rule that ended at the pixel centres (a ConfigError from inside).
        CameraModel(324, 247, CAM.fx_px / 2, CAM.fy_px / 2, 0.0, 0.0),
    ],
    ids=["648x494 off centre", "320x240 distorted off centre", "324x247 at the corner"],
)
def test_phase_corr_with_the_principal_point_far_from_the_centre(tmp_path, name, camera):
    """A real calibration's principal point can lie nearer an edge than half phase-corr's crop:
    the crop, centred on it, reached past the frame and the first step ended the run in a
    ValueError (a block reshape of an empty array). The crop is now moved inside the frame and
    the motion still measured about the principal point: a turning run's steps (3 mm, 1 degree
    a frame) are each within issue 14's bound of the synthetic truth."""
    poses = np.stack([T_world_cam_down(3.0 * i, 0.5 * i, 100.0, np.radians(1.0 * i)) for i in range(4)])
    seq = Sequence.open(write_synthetic_sequence(tmp_path / "seq", camera, poses, seed=2))
    assert len(_assert_every_step_ok_within_bound(name, seq)) == 3


@pytest.mark.parametrize("name", ["akaze-guided", "akaze-bruteforce"])
def test_imprecise_fit_is_lost_a_precise_one_kept(name):
    """The precision check of an AKAZE step: 60 matched pairs of a 4 mm step with 0.5 px of
    seeded noise. Spread over the frame they locate the yaw to 0.03 degrees: the step is
    ok. Crowded into a 40 px patch 250 px from the centre they pass every other check (RMS
    0.7 px, all agree, one motion) but leave the yaw and the camera's displacement (over the
    lever arm) uncertain beyond the bound: the step is lost, with the reason."""
    est = get_estimator(name)(make_config(name), CAM, height_mm=100.0)
    rng = np.random.default_rng(3)
    centre = np.array([CAM.cx_px, CAM.cy_px])
    M_true = np.array([[1.0, 0.0, -32.4], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])  # 4 mm along x
    for spread_px, offset_px, ok in [(400.0, 0.0, True), (40.0, 250.0, False)]:
        src = centre + np.array([offset_px, 0.0]) + rng.uniform(-spread_px / 2, spread_px / 2, (60, 2))
        dst = est._predict(M_true, src) + rng.normal(0.0, 0.5, src.shape)
        fit = est._fit(src, dst, M_true)
        if ok:
            assert fit.problem == "", fit.problem
        else:
            assert fit.problem.startswith("imprecise fit"), fit.problem
    # Without the check (precision_sigmas = 0) the crowded pairs were reported ok.
    est0 = get_estimator(name)(make_config(name, {"precision_sigmas": "0"}), CAM, height_mm=100.0)
    assert est0._fit(src, dst, M_true).problem == ""


def _image_motion(yaw_deg: float, tx_px: float) -> np.ndarray:
    """3x3 rigid image motion (prev-centred px -> cur-centred px): a rotation and a shift along x."""
    c, s = np.cos(np.radians(yaw_deg)), np.sin(np.radians(yaw_deg))
    return np.array([[c, -s, tx_px], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_guided_fit_pulled_by_its_prediction_is_doubted():
    """A tiled floor under a turn whose rate changes (the full-size ceramic corner: 6 degrees
    predicted at 7.65). Each of 80 keypoints lies on a grout line, half along x and half along
    y: along its line the nearest-first search takes a like keypoint at the predicted
    position, across it the true one (0.3 px of seeded noise). The fit lands between the
    prediction and the truth, 0.9 degrees off, and passes every other check (RMS, consensus,
    one motion, precision). Matched again around that fit the step turns by another 0.5
    degrees: the check reports the pull, so the step falls back to brute force. True matches
    come back unchanged (a fixed point); with ``check_rematch`` off the pulled fit passed."""
    name = "akaze-guided"
    est = get_estimator(name)(make_config(name), CAM, height_mm=100.0)
    rng = np.random.default_rng(0)
    centre = np.array([CAM.cx_px, CAM.cy_px])
    src = centre + rng.uniform(-100.0, 100.0, (80, 2))
    along_x = np.arange(len(src)) % 2 == 0
    noise = rng.normal(0.0, 0.3, src.shape)
    M_true = _image_motion(6.0, -32.4)  # 6 degrees and 4 mm along x

    def on_grout_lines(state, kps, packed, M_pred=None):
        pred = est._predict(state.M_last if M_pred is None else M_pred, src)
        dst = est._predict(M_true, src)
        dst[along_x, 0] = pred[along_x, 0]
        dst[~along_x, 1] = pred[~along_x, 1]
        return src, dst + noise

    def true_matches(state, kps, packed, M_pred=None):
        return src, est._predict(M_true, src) + noise

    state = _State(kps=src, packed=np.zeros((len(src), 1), dtype=np.uint64), M_last=_image_motion(7.65, -32.4))
    est._guided = on_grout_lines
    fit = est._fit(*est._guided(state, src, state.packed), state.M_last)
    assert fit.problem == "" and est._prediction_doubt(fit, state.M_last) == ""
    assert abs(np.degrees(yaw_of_R(fit.M[:2, :2])) - 6.0) > 0.3  # wrong beyond issue 14's bound
    problem = est._rematch_problem(state, src, state.packed, fit, 1.0)
    assert "the prediction pulled the matches" in problem, problem
    est._guided = true_matches
    fit = est._fit(*est._guided(state, src, state.packed), state.M_last)
    assert fit.problem == "" and abs(np.degrees(yaw_of_R(fit.M[:2, :2])) - 6.0) < 0.05
    assert est._rematch_problem(state, src, state.packed, fit, 1.0) == ""
    # Without the check the pulled fit was reported ok.
    est0 = get_estimator(name)(make_config(name, {"check_rematch": "false"}), CAM, height_mm=100.0)
    est0._guided = on_grout_lines
    fit = est0._fit(*est0._guided(state, src, state.packed), state.M_last)
    assert est0._rematch_problem(state, src, state.packed, fit, 1.0) == ""


def test_phase_corr_blocks_that_disagree_on_the_yaw_are_lost(tmp_path):
    """The four blocks of phase-corr's crop see the 4 mm step each shifted by 1.3 px more in
    x, in a pattern no rotation, scale or shift explains (+, -, -, + from the top left): the
    largest block residual (1.3 px) passes ``max_residual_px`` (1.5), so the step was
    reported ok with a yaw the blocks do not agree on. They disagree by 1.3 px RMS, beyond
    their own precision (``block_precision_px`` 0.5), and leave the yaw a standard error of
    0.28 degrees: the step is lost with the reason."""
    from tests.floorvo._synth import floor_texture, pixel_motion, view

    tex = floor_texture(int(2.2 * CAM.width_px), 0)
    T_prev_cur = invert_T(T_world_cam_down(0.0, 0.0, 100.0)) @ T_world_cam_down(4.0, 0.0, 100.0)
    M = pixel_motion(T_prev_cur, CAM, 100.0)
    prev = view(tex, CAM, np.eye(3))
    parts = {}
    for sx in (-1, 1):
        for sy in (-1, 1):
            extra = np.eye(3)
            extra[0, 2] = 1.3 * sx * sy  # + top left and bottom right, - the others
            parts[sx, sy] = view(tex, CAM, extra @ M)
    u, v = np.meshgrid(np.arange(CAM.width_px), np.arange(CAM.height_px))
    cur = np.where(
        v < CAM.cy_px,
        np.where(u < CAM.cx_px, parts[-1, -1], parts[1, -1]),
        np.where(u < CAM.cx_px, parts[-1, 1], parts[1, 1]),
    )
    frames = [np.clip(np.round(f / np.percentile(prev, 99.5) * 200.0), 0, 255).astype(np.uint8) for f in (prev, cur)]
    # Without the yaw check (and the translation's precision check, which these blocks fail too) it was ok.
    # Leaving out three of the finer 3 x 3 blocks, six agree on a motion that is not the floor's
    # (0.156 mm off): the three left out agree on another one, and the step is lost.
    relaxed = {"max_yaw_sigma_deg": "10", "precision_sigmas": "0"}
    for overrides, status in [({}, "lost"), (relaxed, "ok"), ({"robust_outlier_blocks": "3"}, "lost")]:
        res = _step_frames("phase-corr", frames, overrides)
        assert res[1].status == status, res[1].reason
        if status == "lost":
            assert res[1].reason.startswith("imprecise yaw"), res[1].reason


@pytest.mark.parametrize("name", ["phase-corr", "phase-corr-fast"])
def test_phase_corr_blocks_that_leave_the_step_imprecise_are_lost(name):
    """Three of the four blocks of the crop see the 4 mm step 1.9 px further in x (the top
    left, top right and bottom left), the fourth sees it as it is. No block is further than
    ``max_residual_px`` from the rigid fit, the yaw passes its check, and the step came out
    0.18 mm off (issue 14's bound here: 0.13 mm), reported ok. Four blocks that disagree so
    leave the translation a standard error of 0.058 mm: 2.5 of them (``precision_sigmas``)
    exceed the bound, and the step is lost with the reason."""
    from tests.floorvo._synth import floor_texture, pixel_motion, view

    tex = floor_texture(int(2.2 * CAM.width_px), 0)
    T_prev_cur = invert_T(T_world_cam_down(0.0, 0.0, 100.0)) @ T_world_cam_down(4.0, 0.0, 100.0)
    M = pixel_motion(T_prev_cur, CAM, 100.0)
    prev = view(tex, CAM, np.eye(3))
    extra = np.eye(3)
    extra[0, 2] = 1.9
    moved, kept = view(tex, CAM, extra @ M), view(tex, CAM, M)
    u, v = np.meshgrid(np.arange(CAM.width_px), np.arange(CAM.height_px))
    cur = np.where((u >= CAM.cx_px) & (v >= CAM.cy_px), kept, moved)  # the bottom right block sees the step
    frames = [np.clip(np.round(f / np.percentile(prev, 99.5) * 200.0), 0, 255).astype(np.uint8) for f in (prev, cur)]
    for overrides, status in [({}, "lost"), ({"precision_sigmas": "0"}, "ok")]:
        res = _step_frames(name, frames, overrides)
        assert res[1].status == status, res[1].reason
        if status == "lost":
            assert res[1].reason.startswith("imprecise step"), res[1].reason
        else:  # without the check: the wrong step the check is there for
            assert not _within_bound(res[1].T_prev_cur, T_prev_cur), _step_error(res[1].T_prev_cur, T_prev_cur)


def test_phase_corr_is_not_held_at_no_motion_by_hot_and_dead_pixels():
    """A sensor's hot and dead pixels (0.1 % each, stuck at full scale and at zero, the same in
    every frame: ``sensor.hot_pixel_fraction`` of the renderer) move with the camera, not the
    floor, and their flat spectrum weighs as much as the floor's in the whitened phase
    correlation: without replacing them by their 3 x 3 median phase-corr measured three 4 mm
    steps as no motion and reported them ok (on a full-size render of the concrete S-curve with
    that sensor, 10 of 11 steps). With it, every step is within issue 14's bound of the truth.
    (``impulse_ratio``: only the pixels brighter than twice their 3 x 3 median are replaced.)"""
    from tests.floorvo._synth import floor_texture, pixel_motion, view

    tex = floor_texture(int(2.2 * CAM.width_px), 3)
    rng = np.random.default_rng(7)
    n_px = CAM.width_px * CAM.height_px
    defects = rng.choice(n_px, size=int(0.002 * n_px), replace=False)
    hot, dead = (
        np.unravel_index(defects[::2], (CAM.height_px, CAM.width_px)),
        np.unravel_index(defects[1::2], (CAM.height_px, CAM.width_px)),
    )
    truth, frames = [], []
    for i in range(4):
        T = invert_T(T_world_cam_down(0.0, 0.0, 100.0)) @ T_world_cam_down(4.0 * i, 0.0, 100.0)
        truth.append(T)
        img = view(tex, CAM, pixel_motion(T, CAM, 100.0)) * led_falloff(CAM)
        if not frames:
            scale = 200.0 / float(np.percentile(img, 99.5))
        img = np.clip(np.round(img * scale), 0, 255).astype(np.uint8)
        img[hot], img[dead] = 255, 0
        frames.append(img)
    steps = [invert_T(a) @ b for a, b in zip(truth, truth[1:])]
    for ratio, held in [("0", True), ("2", False)]:
        res = _step_frames("phase-corr", frames, {"impulse_ratio": ratio})
        ok = [(r, T) for r, T in zip(res[1:], steps) if r.status == "ok"]
        if held:  # the defect the check is there for: steps of no motion reported ok
            assert any(not _within_bound(r.T_prev_cur, T) for r, T in ok)
        else:
            assert len(ok) == 3, [r.reason for r in res[1:]]
            assert all(_within_bound(r.T_prev_cur, T) for r, T in ok), [_step_error(r.T_prev_cur, T) for r, T in ok]


def test_phase_corr_refuses_an_impulse_ratio_that_would_replace_ordinary_pixels():
    """A ratio in (0, 1] would replace every pixel brighter than its median (a median filter,
    which biases the steps): refused in one line naming the key and the rule; 0 turns it off."""
    from floorvo.errors import ConfigError

    cls = get_estimator("phase-corr")
    with pytest.raises(ConfigError, match=r"^phase-corr\.impulse_ratio = 0\.5: must be 0 \(none\) or > 1"):
        cls(make_config("phase-corr", {"impulse_ratio": "0.5"}), CAM, height_mm=100.0)
    for ok in ("0", "1.5"):
        cls(make_config("phase-corr", {"impulse_ratio": ok}), CAM, height_mm=100.0)


def test_phase_corr_measures_a_step_larger_than_half_its_crop(tmp_path):
    """30 mm per frame (900 mm/s at 30 fps): 243 px at full size, more than half the 384 px
    crop, whose correlation wraps it to -141 px, and the crop moved by it leaves the frame.
    phase-corr takes a first guess from the whole normalised region and measures the blocks
    where both frames see them (the previous frame's crop moved back by half the step): every
    step is ok and within issue 14's bound (before: every step lost)."""
    seq = _sequence(tmp_path, [(30.0 * i, 0.0, 0.0) for i in range(4)])
    results, truth = _run("phase-corr", seq)
    assert results[0].status == "init"
    for k, (res, T_true) in enumerate(zip(results[1:], truth), start=1):
        assert res.status == "ok", f"step {k}: {res.reason}"
        assert _within_bound(res.T_prev_cur, T_true), f"step {k}: {_step_error(res.T_prev_cur, T_true)}"


def test_phase_corr_measures_the_first_frame_of_a_sharp_turn(tmp_path):
    """A straight run into a 90-degree corner on a 30 mm radius (issue 14's corner scenes:
    4 mm/frame, 7.64 degrees/frame), then a turn in place. The first turning frame, predicted
    straight, was reported ok and 0.148 mm off (the bound here: 0.13 mm): two warp rounds did
    not converge from a 7.6-degree error, and nothing checked that they had. A rotating warp
    now takes rounds until its estimate stops moving (else lost); on the rendered corner,
    where the blocks disagreed from the straight prediction (lost, 30 % drift), a rotation
    guess from the crops' log-polar magnitude spectra starts them. Each step is ok and
    within issue 14's bound."""
    yaw_step = np.degrees(4.0 / 30.0)  # 7.64 degrees per 4 mm on a 30 mm radius
    poses = [(0.0, 0.0, 0.0), (4.0, 0.0, 0.0), (8.0, 0.0, 0.0)]
    for _ in range(2):  # the arc: chord of the 4 mm arc, turning yaw_step each frame
        x, y, yaw = poses[-1]
        mid = np.radians(yaw + yaw_step / 2)
        poses.append((x + 4.0 * np.cos(mid), y + 4.0 * np.sin(mid), yaw + yaw_step))
    poses += [(poses[-1][0], poses[-1][1], poses[-1][2] - 8.0)]  # and back, in place
    seq = _sequence(tmp_path, poses)
    results, truth = _run("phase-corr", seq)
    for k, (res, T_true) in enumerate(zip(results[1:], truth), start=1):
        assert res.status == "ok", f"step {k}: {res.reason}"
        assert _within_bound(res.T_prev_cur, T_true), f"step {k}: {_step_error(res.T_prev_cur, T_true)}"


def test_phase_corr_block_shifts_of_a_stack_are_each_blocks_shift():
    """:func:`~floorvo.estimators.phase_corr.block_shifts` measures a stack of block pairs in one
    pass: each block's known sub-pixel shift (a texture moved by the Fourier shift theorem,
    exact; one of them by whole pixels too) within 0.02 px, and the same as measuring it alone;
    :func:`~floorvo.estimators.phase_corr.block_shifts_near`, given the whole pixels, the same,
    from the whole spectra or from their low frequencies alone."""
    from scipy.ndimage import fourier_shift
    from tests.floorvo._synth import floor_texture

    from floorvo.estimators.phase_corr import _Spectral, block_shift, block_shifts, block_shifts_near

    n = 64
    tex = floor_texture(4 * n, 2).astype(np.float64)
    sp = _Spectral(n, 0.3)
    truth = np.array([[0.25, -0.4], [1.7, 0.05], [-3.35, 2.6], [0.0, 0.0]])  # (dx, dy) px
    a_blocks, b_blocks = [], []
    for i, (dx, dy) in enumerate(truth):
        a = tex[(i // 2) * 2 * n : (i // 2) * 2 * n + 2 * n, (i % 2) * 2 * n : (i % 2) * 2 * n + 2 * n]
        b = np.fft.ifft2(fourier_shift(np.fft.fft2(a), (dy, dx))).real  # b(x) = a(x - d)
        a_blocks.append(a[n // 2 : n // 2 + n, n // 2 : n // 2 + n])
        b_blocks.append(b[n // 2 : n // 2 + n, n // 2 : n // 2 + n])
    Fa, Fb = sp.spectrum(np.array(a_blocks)), sp.spectrum(np.array(b_blocks))
    d, peaks, info = block_shifts(Fa, Fb, sp)
    assert d.shape == (4, 2) and peaks.shape == (4,) and info.shape == (4, 2, 2)
    np.testing.assert_allclose(d, truth, atol=0.02)
    for i in range(4):
        d_i, peak_i = block_shift(sp.spectrum(a_blocks[i]), sp.spectrum(b_blocks[i]), sp)
        np.testing.assert_allclose(d_i, d[i], atol=1e-9)
        assert peak_i == pytest.approx(peaks[i], abs=1e-6)
    # With the whole pixels known (block_shifts_near: no correlation, no peak search) the same shifts.
    d_near, info_near = block_shifts_near(Fa, Fb, sp, np.round(truth))
    np.testing.assert_allclose(d_near, truth, atol=0.02)
    np.testing.assert_allclose(info_near, info, rtol=1e-4)
    np.testing.assert_allclose(d_near, d, atol=1e-5)
    # The low frequencies alone (spectrum(..., low_only=True), phase-corr's warp-spread check):
    # those of the whole spectrum, and the same shifts from them.
    Fb_low = sp.spectrum(np.array(b_blocks), low_only=True)
    np.testing.assert_array_equal(Fb_low, Fb[:, sp.low_rows, : sp.low_cols])
    np.testing.assert_array_equal(block_shifts_near(Fa, Fb_low, sp, np.round(truth))[0], d_near)


def _grain(seed: int, shape: tuple[int, int]) -> np.ndarray:
    """Unit-variance noise smoothed 12 px along x and 0.8 px along y: a grain along x."""
    x = cv2.GaussianBlur(np.random.default_rng(seed).normal(size=shape).astype(np.float32), (0, 0), 12.0, sigmaY=0.8)
    return x / x.std()


def test_phase_corr_takes_the_yaw_from_what_its_blocks_see_on_a_grained_floor():
    """A floor grained along x, 4 mm along x, and in each frame its own faint grain that does not
    move with the floor (the grazing light's shading changing as the wood moves under it): each
    block's shift is poorly measured along the grain and well across it, and its information
    (the phase-slope fit's normal matrix) says so (along x under a tenth of across). Fitted with
    that (``weigh_blocks_by_texture``), six such steps' yaw is within 0.03 degrees of the truth
    and its RMS error under 0.4 of the equal-weight fit's (0.011 against 0.070 degrees when
    written)."""
    from tests.floorvo._synth import pixel_motion, view

    from floorvo.estimators.phase_corr import _Spectral, block_shifts

    size = int(2.2 * CAM.width_px)
    floor = _grain(3, (size, size))
    T_true = invert_T(T_world_cam_down(0.0, 0.0, 100.0)) @ T_world_cam_down(4.0, 0.0, 100.0)
    sp = _Spectral(128, 0.25)
    blocks = sp.spectrum(np.stack([floor[i : i + 128, i : i + 128] for i in (0, 300, 600)]))
    info = block_shifts(blocks, blocks, sp)[2]
    assert np.all(info[:, 0, 0] < 0.1 * info[:, 1, 1]), info
    yaw_err: dict[str, list[float]] = {"true": [], "false": []}
    for seed in range(6):
        shade = [0.3 * _grain(100 + 2 * seed + k, (CAM.height_px, CAM.width_px)) for k in (0, 1)]
        prev = view(floor, CAM, np.eye(3)) + shade[0]
        cur = view(floor, CAM, pixel_motion(T_true, CAM, 100.0)) + shade[1]
        lo, hi = np.percentile(prev, [0.5, 99.5])
        frames = [np.clip((f - lo) / (hi - lo) * 200.0 + 20.0, 0, 255).astype(np.uint8) for f in (prev, cur)]
        for weigh in yaw_err:
            res = _step_frames("phase-corr", frames, {"weigh_blocks_by_texture": weigh})[1]
            assert res.status == "ok", res.reason
            yaw_err[weigh].append(_step_error(res.T_prev_cur, T_true)[1])
    rms = {k: float(np.sqrt(np.mean(np.square(v)))) for k, v in yaw_err.items()}
    assert max(yaw_err["true"]) < 0.03 and rms["true"] < 0.4 * rms["false"], yaw_err


def test_phase_corr_measures_on_from_a_step_that_had_not_converged(monkeypatch):
    """A step that, measured again through the whole-pixel warp on its other side, the blocks still
    see further on (not bracketed: :meth:`PhaseCorr._warp_spread`) is measured once more from
    there, and reported if that measurement passes every check: here the first measurement of a
    4 mm step is reported not bracketed (the warp's pull along a grain, which a synthetic floor
    does not have), and the step is measured a second time, from the estimate through the other
    warp, and reported ok within issue 14's bound. Without the retry the same step is lost
    ("step not converged")."""
    from tests.floorvo._synth import frame_pair

    import floorvo.estimators.phase_corr as phase_corr

    T_true = invert_T(T_world_cam_down(0.0, 0.0, 100.0)) @ T_world_cam_down(4.0, 0.3, 100.0)
    prev, cur, _ = frame_pair(CAM, T_true, seed=4)
    real_spread = phase_corr.PhaseCorr._warp_spread
    starts: list[np.ndarray] = []
    real_measure = phase_corr.PhaseCorr._measure

    def measure(self, state, cur_img, M, layout=None):
        starts.append(M.copy())
        return real_measure(self, state, cur_img, M, layout)

    def first_not_bracketed(self, cur_img, m):
        spread_mm, spread_deg, _, M_beyond = real_spread(self, cur_img, m)
        return spread_mm, spread_deg, len(starts) > 1, M_beyond

    monkeypatch.setattr(phase_corr.PhaseCorr, "_measure", measure)
    monkeypatch.setattr(phase_corr.PhaseCorr, "_warp_spread", first_not_bracketed)
    res = _step_frames("phase-corr", [prev, cur])[1]
    assert res.status == "ok", res.reason
    assert _within_bound(res.T_prev_cur, T_true), _step_error(res.T_prev_cur, T_true)
    assert len(starts) == 2  # the first measurement, then once more from where the other warp put the step

    def never_bracketed(self, cur_img, m):
        return (*real_spread(self, cur_img, m)[:2], False, real_spread(self, cur_img, m)[3])

    monkeypatch.setattr(phase_corr.PhaseCorr, "_warp_spread", never_bracketed)
    starts.clear()
    res = _step_frames("phase-corr", [prev, cur])[1]
    assert res.status == "lost" and res.reason.startswith("step not converged"), res.reason
    assert len(starts) == 2  # one more measurement only


def _arc_poses(yaw_steps_deg: list[float], step_mm: float = 4.0) -> list[tuple[float, float, float]]:
    """Poses (x mm, y mm, yaw deg) from the origin, ``step_mm`` a frame along the chord of each
    frame's arc, turning ``yaw_steps_deg[i]`` in frame i."""
    poses = [(0.0, 0.0, 0.0)]
    for d_yaw in yaw_steps_deg:
        x, y, yaw = poses[-1]
        mid = np.radians(yaw + d_yaw / 2)
        poses.append((x + step_mm * np.cos(mid), y + step_mm * np.sin(mid), yaw + d_yaw))
    return poses


@pytest.mark.parametrize("name", ["phase-corr", "phase-corr-fast"])
def test_phase_corr_takes_one_round_on_a_steady_turn_and_two_when_its_rate_changes(tmp_path, monkeypatch, name):
    """A turn at 2 degrees/frame (4 mm/frame), then its rate changes to -1 degree/frame. On the
    steady turn the prediction (the last step) is right: the first round's rotating warp would
    not move a block centre by converged_px in a second, which is left out (one correlation
    round a step); where the rate changes the prediction is 3 degrees off and the rounds go on.
    Every step is ok and within issue 14's bound of the truth either way."""
    import floorvo.estimators.phase_corr as phase_corr

    rounds: list[int] = []
    counted = phase_corr.block_shifts

    def block_shifts(*args, **kwargs):  # a warp-and-measure round of _measure (the warp-spread check has its own)
        rounds[-1] += 1
        return counted(*args, **kwargs)

    monkeypatch.setattr(phase_corr, "block_shifts", block_shifts)
    seq = _sequence(tmp_path, _arc_poses([0.0, 2.0, 2.0, 2.0, 2.0, -1.0, -1.0]))
    est = get_estimator(name)(make_config(name, {}), seq.camera, height_mm=100.0, flatfield=seq.flatfield())
    state = est.start()
    results = []
    for i in range(seq.frame_count):
        rounds.append(0)
        results.append(est.step(state, Frame(i, i / 30.0, seq.image(i))))
    T = seq.groundtruth()[1]
    for k in range(1, seq.frame_count):
        res, T_true = results[k], invert_T(T[k - 1]) @ T[k]
        assert res.status == "ok", f"step {k}: {res.reason}"
        assert _within_bound(res.T_prev_cur, T_true), f"step {k}: {_step_error(res.T_prev_cur, T_true)}"
    # Steps 3-5 turn as the step before them: one round. Step 6 turns 3 degrees less than predicted.
    assert rounds[3:6] == [1, 1, 1], rounds
    assert rounds[6] >= 2, rounds


def _rounds_and_steps(monkeypatch, seq: Sequence, name: str, overrides: dict[str, str]) -> tuple[list[int], list]:
    """phase-corr's warp-and-measure rounds (``block_shifts`` calls in ``_measure``) and result of each frame."""
    import floorvo.estimators.phase_corr as phase_corr

    rounds: list[int] = []
    counted = phase_corr.block_shifts

    def block_shifts(*args, **kwargs):
        rounds[-1] += 1
        return counted(*args, **kwargs)

    monkeypatch.setattr(phase_corr, "block_shifts", block_shifts)
    est = get_estimator(name)(make_config(name, overrides), seq.camera, height_mm=100.0, flatfield=seq.flatfield())
    state = est.start()
    results = []
    for i in range(seq.frame_count):
        rounds.append(0)
        results.append(est.step(state, Frame(i, i / 30.0, seq.image(i))))
    monkeypatch.setattr(phase_corr, "block_shifts", counted)
    return rounds, results


@pytest.mark.parametrize("name", ["phase-corr", "phase-corr-fast"])
def test_phase_corr_predicts_a_steadily_changing_turn_rate_and_takes_one_round(tmp_path, monkeypatch, name):
    """A turn whose rate grows by 0.6 degrees a frame (an S-curve's change of rate): predicted at
    the last step's rate (``predict_turn_rate = false``), each step is 0.6 degrees off and takes
    a second round; predicted on at the change of rate of the last two steps (the default, once
    three steps agree on it), its first round's warp holds and the step takes one round. Every
    step is ok and within issue 14's bound of the truth both ways."""
    seq = _sequence(tmp_path, _arc_poses([0.6 * k for k in range(1, 9)]))
    T = seq.groundtruth()[1]
    per_setting = {}
    for setting in ("false", "true"):
        rounds, results = _rounds_and_steps(monkeypatch, seq, name, {"predict_turn_rate": setting})
        for k in range(1, seq.frame_count):
            res, T_true = results[k], invert_T(T[k - 1]) @ T[k]
            assert res.status == "ok", f"{setting}, step {k}: {res.reason}"
            assert _within_bound(res.T_prev_cur, T_true), f"{setting}, step {k}: {_step_error(res.T_prev_cur, T_true)}"
        per_setting[setting] = rounds
    # Steps 4 on are predicted from three steps whose rate grew alike; before, the rate is unknown.
    # (phase-corr-fast's binned blocks measure each step's yaw less precisely, and the change of
    # rate is the difference of two: one of its five steps takes a second round.)
    assert all(r >= 2 for r in per_setting["false"][4:]), per_setting
    n = seq.frame_count - 4
    assert per_setting["true"][4:].count(1) >= (n if name == "phase-corr" else n - 1), per_setting


@pytest.mark.parametrize(
    "yaws, predicted",
    [
        ([0.02], 0.02),
        ([0.01, 0.02], 0.02),  # two steps: no change of rate known yet
        ([0.01, 0.02, 0.03], 0.04),  # the rate grows steadily: on at its change
        ([0.01, 0.02, 0.035], 0.05),  # changes of 0.010 and 0.015 agree (within half the larger)
        ([0.0, 0.02, 0.02], 0.02),  # a turn's start: no change since, constant rate
        ([0.0, 0.01, 0.04], 0.04),  # changes of 0.01 and 0.03 do not agree
        ([0.03, 0.02, 0.03], 0.03),  # changes of opposite sign
    ],
)
def test_predicted_yaw_by_hand(yaws, predicted):
    from floorvo.estimators.phase_corr import _predicted_yaw

    assert _predicted_yaw(yaws) == pytest.approx(predicted)


def _with_rig_fixed_patch(width_px: int, step_mm: float = 4.0) -> tuple[list[np.ndarray], np.ndarray]:
    """Two frames of a 4 mm step along x whose top-left ``width_px`` x 128 px of phase-corr's crop
    (the first ``width_px / 128`` of its 3 x 3 blocks of the top row) show something fixed to the rig
    (a cable in view, dirt on the cover glass: the same picture in both frames), and the true step."""
    from tests.floorvo._synth import floor_texture, pixel_motion, view

    tex, other = floor_texture(int(2.2 * CAM.width_px), 0), floor_texture(int(2.2 * CAM.width_px), 5)
    T_prev_cur = invert_T(T_world_cam_down(0.0, 0.0, 100.0)) @ T_world_cam_down(step_mm, 0.0, 100.0)
    prev, cur = view(tex, CAM, np.eye(3)), view(tex, CAM, pixel_motion(T_prev_cur, CAM, 100.0))
    fixed = view(other, CAM, np.eye(3))
    x0, y0 = int(round(CAM.cx_px - 192 + 0.5)), int(round(CAM.cy_px - 192 + 0.5))  # the 384 px crop's corner
    for f in (prev, cur):
        f[y0 : y0 + 128, x0 : x0 + width_px] = fixed[y0 : y0 + 128, x0 : x0 + width_px]
    frames = [np.clip(np.round(f / np.percentile(prev, 99.5) * 200.0), 0, 255).astype(np.uint8) for f in (prev, cur)]
    return frames, T_prev_cur


@pytest.mark.parametrize("name", ["phase-corr", "phase-corr-fast"])
def test_phase_corr_measures_with_finer_blocks_when_a_block_sees_something_else(name):
    """Two of the crop's 3 x 3 blocks (the top left 256 x 128 px) show something fixed to the rig:
    it holds the top-left of the four default blocks at no motion, 20 px from the others, and the
    step is lost with the reason. Measured once more with 3 x 3 blocks (``robust_grid``), the two
    that disagree are left out and the other seven measure the step within issue 14's bound. Three
    such blocks are more than ``robust_outlier_blocks`` (2) leaves out: lost, not wrong."""
    frames, T_true = _with_rig_fixed_patch(256)
    lost = _step_frames(name, frames, {"robust_grid": "0"})[1]
    assert lost.status == "lost" and lost.reason.startswith("blocks disagree by"), lost.reason
    res = _step_frames(name, frames)[1]
    assert res.status == "ok", res.reason
    assert (res.n_matches, res.n_inliers) == (9, 7)
    assert _within_bound(res.T_prev_cur, T_true), _step_error(res.T_prev_cur, T_true)
    frames, _ = _with_rig_fixed_patch(384)
    res = _step_frames(name, frames)[1]
    assert res.status == "lost" and res.reason.startswith("blocks disagree by"), res.reason


def test_phase_corr_finer_blocks_leave_out_what_the_gross_check_would_not_pass():
    """The finer layout leaves out a block by the gross check's own measure of disagreement
    (the larger component of its residual from the blocks' rigid fit): of 3 x 3 blocks moved by
    (5, -2) px, the centre one off by (1.2, 1.2) px more leaves it a residual of 8/9 of that, by
    hand (the fit's translation takes the mean; the centre block adds no rotation): (1.07, 1.07)
    px, 1.51 px long but each component within ``max_residual_px`` (1.5): kept. Off by (2, 0) px,
    its residual is 1.78 px: left out. Three off by 5 px are more than ``robust_outlier_blocks``
    (2) leaves out: the two worst go and the step is left to the gross check."""
    est = get_estimator("phase-corr")(make_config("phase-corr"), CAM, height_mm=100.0)
    lay = est.robust_layout
    assert lay is not None and len(lay.centres) == 9 and lay.max_outliers == 2
    shifts = np.tile([5.0, -2.0], (9, 1))
    for off, kept in [((1.2, 1.2), None), ((2.0, 0.0), [0, 1, 2, 3, 5, 6, 7, 8])]:
        s = shifts.copy()
        s[4] += off
        keep = est._agreeing(lay.centres, s, lay.max_outliers)
        assert (keep if keep is None else keep.tolist()) == kept, off
    s = shifts.copy()
    s[[0, 4, 8]] += (5.0, 0.0)
    keep = est._agreeing(lay.centres, s, lay.max_outliers)
    assert keep is not None and len(keep) == 7


def test_phase_corr_blocks_left_out_that_agree_on_another_motion_are_a_second_motion():
    """:meth:`PhaseCorr._second_motion`, by hand: of 3 x 3 blocks moved by (5, -2) px, three
    left out that each read 2.55 px more along x agree on another motion (3, 2.55 px); two that
    do (something fixed to the rig) are left out as before; three that read 2.55, -4 and 6 px
    more (wrong peaks) do not agree; three that agree 1 px away are not distinct from the rest at
    a 4 mm step's tolerance of 1.5 px."""
    from floorvo.estimators.phase_corr import _rigid_residuals

    est = get_estimator("phase-corr")(make_config("phase-corr", {"robust_outlier_blocks": "3"}), CAM, height_mm=100.0)
    lay = est.robust_layout
    assert lay is not None and lay.max_outliers == 3
    kept = np.array([0, 1, 3, 4, 5, 6])
    for extra, dropped, expected in [
        ([(2.55, 0.0)] * 3, [2, 7, 8], (3, 2.55)),
        ([(2.55, 0.0)] * 2, [2, 7], None),
        ([(2.55, 0.0), (-4.0, 0.0), (6.0, 1.0)], [2, 7, 8], None),
        ([(1.0, 0.0)] * 3, [2, 7, 8], None),
    ]:
        shifts = np.tile([5.0, -2.0], (9, 1))
        for i, d in zip(dropped, extra, strict=True):
            shifts[i] += d
        keep = np.setdiff1d(np.arange(9), dropped) if len(dropped) == 2 else kept
        R, t, _ = _rigid_residuals(lay.centres[keep], shifts[keep])
        got = est._second_motion(lay.centres, shifts, keep, R, t, 4.0)  # a 4 mm step: tolerance 1.5 px
        if expected is None:
            assert got is None, (extra, got)
        else:
            assert got is not None and got[0] == expected[0] and got[1] == pytest.approx(expected[1]), got


def test_phase_corr_blocks_of_a_fast_step_may_disagree_by_part_of_its_bound():
    """The gross check's tolerance (``_max_residual_px``): ``max_residual_px`` (1.5 px) for a
    4 mm step, whose bound (0.05 mm + 2 %: 0.13 mm) is 1.05 px at this camera's 0.1233 mm per
    pixel; for a 30 mm step half its bound (0.65 mm / 2 = 2.64 px), by hand; at half size the
    same in the frame's pixels."""
    gsd = 7.4e-3 * 100.0 / 6.0  # mm per px at 100 mm
    for name in ("phase-corr", "phase-corr-fast"):
        est = get_estimator(name)(make_config(name), CAM, height_mm=100.0)
        assert est._max_residual_px(4.0) == pytest.approx(1.5)
        assert est._max_residual_px(30.0) == pytest.approx(0.5 * (0.05 + 0.02 * 30.0) / gsd, rel=1e-6)


def test_phase_corr_finer_blocks_only_where_they_are_large_enough_and_enough_remain():
    """``robust_grid`` at full size: 128 px blocks (phase-corr), 64 px (phase-corr-fast, binned
    2 x 2); at half size 72 px (the 220 px crop of a 247 px high frame), and binned 2 x 2 they
    would be 36 px, under ``robust_min_block_px``: none.
    Leaving out so many that fewer than four blocks remain is refused in one line."""
    from floorvo.errors import ConfigError

    half = CameraModel.from_sensor(324, 247, pixel_pitch_um=14.8, focal_length_mm=6.0)
    sizes = {}
    for name, cam in [("phase-corr", CAM), ("phase-corr-fast", CAM), ("phase-corr", half), ("phase-corr-fast", half)]:
        est = get_estimator(name)(make_config(name), cam, height_mm=100.0)
        sizes[name, cam.width_px] = None if est.robust_layout is None else est.robust_layout.block
    assert sizes == {
        ("phase-corr", 648): 128,
        ("phase-corr-fast", 648): 64,
        ("phase-corr", 324): 72,
        ("phase-corr-fast", 324): None,
    }
    with pytest.raises(
        ConfigError, match=r"^phase-corr\.robust_outlier_blocks = 6: leaves fewer than 4 of robust_grid 3's 9"
    ):
        get_estimator("phase-corr")(make_config("phase-corr", {"robust_outlier_blocks": "6"}), CAM, height_mm=100.0)


@pytest.mark.parametrize("name", ["phase-corr", "phase-corr-fast"])
def test_phase_corr_predicts_across_frames_the_camera_dropped_by_their_times(tmp_path, name):
    """A robot at 240 mm/s turning 60 degrees/s, filmed at 30 frames/s (8 mm and 2 degrees a
    frame) by a camera that dropped frames: gaps of 3 and 5 intervals in the frames' times. The
    prediction was made per frame, not per second: at each gap the blocks disagreed by 10-17 px
    from a prediction a third or a fifth of the step, and two frames were lost (the motion over
    the gap thrown away with the restart). Predicted over the time the frame is after the last
    one, every step is ok and within issue 14's bound of the truth."""
    from floorvo.run import run_estimator
    from floorvo.scoring import score_run

    cam = CameraModel.from_sensor(324, 247, pixel_pitch_um=14.8, focal_length_mm=6.0)
    keep = np.ones(30, bool)
    keep[[10, 11, 18, 19, 20, 21]] = False  # gaps of 3 and 5 intervals
    t_s = np.arange(30)[keep] / 30.0
    poses = np.stack([T_world_cam_down(_arc_x(t), _arc_y(t), 100.0, np.pi / 3 * t) for t in t_s])
    seq = write_synthetic_sequence(tmp_path / "seq", cam, poses, timestamps_s=t_s)
    assert np.allclose(Sequence.open(seq).timestamps_s, t_s)
    run = run_estimator(seq, name, tmp_path / "run")
    s = score_run(run.run_dir, seq).flat()
    assert s["lost_frames"] == 0, [r for r in run.reason if r]
    assert s["wrong_ok_steps"] == 0


def _arc_x(t: float) -> float:
    """x (mm) at time ``t`` (s) of a path at 240 mm/s turning at pi/3 rad/s from heading 0."""
    return 240.0 / (np.pi / 3) * np.sin(np.pi / 3 * t)


def _arc_y(t: float) -> float:
    return 240.0 / (np.pi / 3) * (1.0 - np.cos(np.pi / 3 * t))


@pytest.mark.parametrize("name", ["akaze-guided", "akaze-guided-subpixel"])
def test_akaze_guided_predicts_across_frames_the_camera_dropped_by_their_times(tmp_path, name):
    """The run of the phase-corr test above (240 mm/s, 60 degrees/s, gaps of 3 and 5 intervals):
    eq. (2)'s prediction one interval long was doubted at each gap and the frames matched by
    brute force (every step right all the same). Predicted over the frame's time after the last
    one, the guided matching holds across the gaps: no brute-force match, no step lost or wrong."""
    from floorvo.run import run_estimator
    from floorvo.scoring import score_run

    cam = CameraModel.from_sensor(324, 247, pixel_pitch_um=14.8, focal_length_mm=6.0)
    keep = np.ones(30, bool)
    keep[[10, 11, 18, 19, 20, 21]] = False
    t_s = np.arange(30)[keep] / 30.0
    poses = np.stack([T_world_cam_down(_arc_x(t), _arc_y(t), 100.0, np.pi / 3 * t) for t in t_s])
    seq = write_synthetic_sequence(tmp_path / "seq", cam, poses, timestamps_s=t_s)
    run = run_estimator(seq, name, tmp_path / "run")
    s = score_run(run.run_dir, seq).flat()
    assert s["lost_frames"] == 0 and s["wrong_ok_steps"] == 0
    assert not any("matched by brute force" in r for r in run.reason), [r for r in run.reason if r]

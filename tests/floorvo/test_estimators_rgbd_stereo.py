"""orb-icp (paper 001, depth) and stereo-sift (paper 002, stereo) against known motions made in code."""

from __future__ import annotations

import numpy as np
import pytest
from _synth import disturbed_poses, flat_floor_depth, frame_pair, stereo_pairs

from floorvo.camera import CameraModel
from floorvo.errors import ConfigError, FloorbenchError
from floorvo.estimators import Frame, get_estimator, make_config
from floorvo.estimators.orb_icp import homogenise_keypoints
from floorvo.geometry import T_world_cam_down, invert_T, yaw_of_R

CAM = CameraModel.from_sensor(324, 247, pixel_pitch_um=14.8, focal_length_mm=6.0)
# Per-estimator tolerance on a synthetic pair: translation (mm), yaw (deg). Measured worst
# cases over 4 motions x 3 seeds: orb-icp 0.012 mm / 0.005 deg, stereo-sift 0.026 mm /
# 0.003 deg. Most of it is the test warp itself: cubic resampling of a texture with
# content up to Nyquist shifts it by up to ~0.05 px less than asked at quarter-pixel
# fractions (none at whole and half pixels; see the whole-pixel test below).
TOL = {"orb-icp": (0.03, 0.05), "stereo-sift": (0.05, 0.05)}


def _motion(dx_mm, dy_mm, yaw_deg):
    return invert_T(T_world_cam_down(0.0, 0.0, 100.0)) @ T_world_cam_down(dx_mm, -dy_mm, 100.0, np.radians(yaw_deg))


def _check(r, T_true, name):
    assert r.status == "ok", r.reason
    t_tol, yaw_tol = TOL[name]
    np.testing.assert_allclose(r.T_prev_cur[:3, 3], T_true[:3, 3], atol=t_tol)
    assert np.degrees(yaw_of_R(r.T_prev_cur[:3, :3] @ T_true[:3, :3].T)) == pytest.approx(0.0, abs=yaw_tol)


@pytest.mark.parametrize("dx, dy, yaw", [(4.0, 0.0, 0.0), (2.5, -1.2, 1.5)])
def test_orb_icp_recovers_motion_from_depth(dx, dy, yaw):
    T_true = _motion(dx, dy, yaw)
    prev, cur, flat = frame_pair(CAM, T_true)
    depth = flat_floor_depth(CAM)
    est = get_estimator("orb-icp")(make_config("orb-icp"), CAM, height_mm=100.0, flatfield=flat)
    st = est.start()
    assert est.step(st, Frame(0, 0.0, prev, depth_mm=depth)).status == "init"
    _check(est.step(st, Frame(1, 0.1, cur, depth_mm=depth)), T_true, "orb-icp")


@pytest.mark.parametrize("shift_px", [16.0, 16.5])
def test_orb_icp_exact_where_the_test_warp_is_exact(shift_px):
    """At whole- and half-pixel shifts the cubic warp has no phase error: orb-icp (with its
    sub-pixel refinement) is then within 0.002 mm (0.008 px) of the truth."""
    dx_mm = shift_px * 100.0 / CAM.fx_px
    T_true = _motion(dx_mm, 0.0, 0.0)
    prev, cur, flat = frame_pair(CAM, T_true, seed=1)
    depth = flat_floor_depth(CAM)
    est = get_estimator("orb-icp")(make_config("orb-icp"), CAM, height_mm=100.0, flatfield=flat)
    st = est.start()
    est.step(st, Frame(0, 0.0, prev, depth_mm=depth))
    r = est.step(st, Frame(1, 0.1, cur, depth_mm=depth))
    assert r.ok, r.reason
    np.testing.assert_allclose(r.T_prev_cur[:3, 3], T_true[:3, 3], atol=0.002)


@pytest.mark.parametrize("dx, dy, yaw", [(4.0, 0.0, 0.0), (2.5, -1.2, 1.5)])
def test_stereo_sift_recovers_motion_from_triangulation(dx, dy, yaw):
    T_true = _motion(dx, dy, yaw)
    (L0, R0), (L1, R1), flat, T01 = stereo_pairs(CAM, T_true, baseline_mm=20.0)
    est = get_estimator("stereo-sift")(
        make_config("stereo-sift"),
        CAM,
        height_mm=100.0,
        flatfield=flat,
        camera_right=CAM,
        T_cam0_cam1=T01,
        flatfield_right=flat,
    )
    st = est.start()
    assert est.step(st, Frame(0, 0.0, L0, image_right=R0)).status == "init"
    _check(est.step(st, Frame(1, 0.1, L1, image_right=R1)), T_true, "stereo-sift")


def _stereo_sift_mean_step(T_true: np.ndarray):
    """The step stereo-sift with paper 002's update (``update = mean``) measures over the rendered
    stereo pair of the motion ``T_true``."""
    (L0, R0), (L1, R1), flat, T01 = stereo_pairs(CAM, T_true, baseline_mm=20.0, seed=3)
    est = get_estimator("stereo-sift")(
        make_config("stereo-sift", {"update": "mean"}),
        CAM,
        height_mm=100.0,
        flatfield=flat,
        camera_right=CAM,
        T_cam0_cam1=T01,
        flatfield_right=flat,
    )
    st = est.start()
    est.step(st, Frame(0, 0.0, L0, image_right=R0))
    return est.step(st, Frame(1, 0.1, L1, image_right=R1))


def test_stereo_sift_paper_mean_update_translation_only():
    """Algorithm 1's DP_L = P_3dL1 - P_3dL2 recovers a pure translation."""
    T_true = _motion(3.0, 1.0, 0.0)
    r = _stereo_sift_mean_step(T_true)
    assert r.ok, r.reason
    np.testing.assert_allclose(r.T_prev_cur[:3, 3], T_true[:3, 3], atol=0.05)
    np.testing.assert_allclose(r.T_prev_cur[:3, :3], np.eye(3))


def test_stereo_sift_paper_mean_update_loses_a_turn_it_cannot_measure():
    """DP_L is a translation: a step turning 1.5 degrees was reported ok with no rotation and its
    translation off by the turn of the points' centroid. It is lost, with the reason."""
    r = _stereo_sift_mean_step(_motion(2.5, -1.2, 1.5))
    assert r.status == "lost" and "turned 1.5" in r.reason and "update = mean" in r.reason, r.reason


def test_lost_frames_give_status_and_the_run_goes_on():
    T_true = _motion(2.0, 0.0, 0.0)
    prev, cur, flat = frame_pair(CAM, T_true)
    depth = flat_floor_depth(CAM)
    est = get_estimator("orb-icp")(make_config("orb-icp"), CAM, height_mm=100.0, flatfield=flat)
    st = est.start()
    est.step(st, Frame(0, 0.0, prev, depth_mm=depth))
    r = est.step(st, Frame(1, 0.1, np.zeros_like(prev), depth_mm=depth))
    assert r.status == "lost" and "empty" in r.reason and r.T_prev_cur is None
    r = est.step(st, Frame(2, 0.2, cur, depth_mm=np.zeros_like(depth)))  # no depth measured anywhere
    assert r.status == "lost" and "depth" in r.reason
    r = est.step(st, Frame(3, 0.3, cur, depth_mm=depth))  # matched against the last good frame
    _check(r, T_true, "orb-icp")
    # A frame with an unrelated texture: no consistent matches -> lost, with a reason.
    other, _, _ = frame_pair(CAM, T_true, seed=9)
    r = est.step(st, Frame(4, 0.4, other, depth_mm=depth))
    assert r.status == "lost" and r.reason and "restarts" not in r.reason
    # ... and the next frame is measured against the last good one (frame 3): the lost frame had
    # become the reference, unsaid, and the next step was chained as if from frame 3
    r = est.step(st, Frame(5, 0.5, cur, depth_mm=depth))
    assert r.status == "ok" and np.abs(r.T_prev_cur - np.eye(4)).max() < 0.02, r.reason
    # two unrelated frames in a row: tracking restarts from the second, and says so
    est.step(st, Frame(6, 0.6, other, depth_mm=depth))
    r = est.step(st, Frame(7, 0.7, frame_pair(CAM, T_true, seed=11)[0], depth_mm=depth))
    assert r.status == "lost" and r.reason.endswith("; tracking restarts from this frame"), r.reason
    # a NaN where the depth image has no measurement is no measurement, as 0 is
    holes = depth.copy()
    holes[:40] = np.nan
    r = est.step(st, Frame(8, 0.8, prev, depth_mm=holes))
    assert r.status in ("ok", "lost") and "NaN" not in r.reason

    (L0, R0), (L1, R1), flat2, T01 = stereo_pairs(CAM, T_true, baseline_mm=20.0)
    ss = get_estimator("stereo-sift")(
        make_config("stereo-sift"), CAM, height_mm=100.0, camera_right=CAM, T_cam0_cam1=T01
    )
    st = ss.start()
    ss.step(st, Frame(0, 0.0, L0, image_right=R0))
    r = ss.step(st, Frame(1, 0.1, L1, image_right=np.zeros_like(R1)))
    assert r.status == "lost" and "empty" in r.reason


def test_a_first_frame_with_nan_is_lost_not_taken_as_the_start():
    """orb-icp and stereo-sift took a NaN-laden float first frame as 'init', and lost the next
    good frame against it."""
    T_true = _motion(2.0, 0.0, 0.0)
    prev, cur, flat = frame_pair(CAM, T_true)
    depth = flat_floor_depth(CAM)
    bad = prev.astype(np.float32)
    bad[10, 10] = np.nan
    est = get_estimator("orb-icp")(make_config("orb-icp"), CAM, height_mm=100.0, flatfield=flat)
    st = est.start()
    r = est.step(st, Frame(0, 0.0, bad, depth_mm=depth))
    assert r.status == "lost" and "1 pixel(s) that are NaN or infinite" in r.reason
    assert est.step(st, Frame(1, 0.1, prev, depth_mm=depth)).status == "init"
    _check(est.step(st, Frame(2, 0.2, cur, depth_mm=depth)), T_true, "orb-icp")
    (L0, R0), (L1, R1), flat2, T01 = stereo_pairs(CAM, T_true, baseline_mm=20.0)
    ss = get_estimator("stereo-sift")(
        make_config("stereo-sift"), CAM, height_mm=100.0, camera_right=CAM, T_cam0_cam1=T01
    )
    st = ss.start()
    bad_right = R0.astype(np.float32)
    bad_right[5, 5] = np.inf
    r = ss.step(st, Frame(0, 0.0, L0, image_right=bad_right))
    assert r.status == "lost" and "right frame has 1 pixel(s) that are NaN or infinite" in r.reason
    assert ss.step(st, Frame(1, 0.1, L0, image_right=R0)).status == "init"


def test_frames_of_the_wrong_size_are_refused_with_a_reason():
    """A left, right or depth image of another size than the camera's: lost with a reason, no exception."""
    T_true = _motion(2.0, 0.0, 0.0)
    prev, cur, flat = frame_pair(CAM, T_true)
    depth = flat_floor_depth(CAM)
    est = get_estimator("orb-icp")(make_config("orb-icp"), CAM, height_mm=100.0, flatfield=flat)
    st = est.start()
    est.step(st, Frame(0, 0.0, prev, depth_mm=depth))
    r = est.step(st, Frame(1, 0.1, cur, depth_mm=depth[:200, :300]))
    assert r.status == "lost" and "depth image is 300x200 px: the camera is 324x247" in r.reason
    r = est.step(st, Frame(2, 0.2, cur[:, :200], depth_mm=depth))
    assert r.status == "lost" and "frame is 200x247 px" in r.reason
    _check(est.step(st, Frame(3, 0.3, cur, depth_mm=depth)), T_true, "orb-icp")  # against the last good frame

    (L0, R0), (L1, R1), flat2, T01 = stereo_pairs(CAM, T_true, baseline_mm=20.0)
    ss = get_estimator("stereo-sift")(
        make_config("stereo-sift"), CAM, height_mm=100.0, camera_right=CAM, T_cam0_cam1=T01
    )
    st = ss.start()
    ss.step(st, Frame(0, 0.0, L0, image_right=R0))
    r = ss.step(st, Frame(1, 0.1, L1, image_right=np.dstack([R1, R1, R1])))
    assert r.status == "lost" and "right frame has 3 channels" in r.reason


def test_homogenised_keypoints_capped_per_cell():
    import cv2

    kps = [
        cv2.KeyPoint(float(x), float(y), 7, -1, float(r)) for x, y, r in [(1, 1, 5), (2, 2, 9), (3, 3, 1), (90, 90, 2)]
    ]
    kept = homogenise_keypoints(kps, (100, 100), 2, 2, 2)
    assert sorted(k.response for k in kept) == [2, 5, 9]


def test_bad_config_refused():
    with pytest.raises(ConfigError, match=r"orb-icp.ratio = 1.5: must be <= 1.0"):
        make_config("orb-icp", {"ratio": "1.5"})
    with pytest.raises(ConfigError, match=r"stereo-sift.update = 'median': must be one of 'planar', 'rigid', 'mean'"):
        make_config("stereo-sift", {"update": "median"})
    with pytest.raises(ConfigError, match="stereo-sift: needs camera_right"):
        get_estimator("stereo-sift")(make_config("stereo-sift"), CAM, height_mm=100.0)


def _mono_sequence(root, n=2, depth=False):
    from floorvo.sequence import SequenceWriter

    meta = {"camera": CAM.to_dict(), "fps": 30.0, "frame_count": n, "rig": {"height_mm": 100.0}}
    if depth:
        meta["depth"] = {"format": "npy_float32_mm"}
    w = SequenceWriter(root, meta)
    prev, cur, _ = frame_pair(CAM, _motion(1.0, 0, 0))
    for i, im in enumerate([prev, cur][:n]):
        w.write_frame(i, im)
    return root


def test_missing_depth_or_stereo_refused_before_any_frame(tmp_path, monkeypatch):
    from floorvo.run import run_estimator

    seq = _mono_sequence(tmp_path / "seq")
    calls = []
    for name in ("orb-icp", "stereo-sift"):
        monkeypatch.setattr(get_estimator(name), "step", lambda self, st, fr: calls.append(fr) or None)
    with pytest.raises(FloorbenchError, match="orb-icp needs depth images"):
        run_estimator(seq, "orb-icp", tmp_path / "run1")
    with pytest.raises(FloorbenchError, match="stereo-sift needs a stereo sequence"):
        run_estimator(seq, "stereo-sift", tmp_path / "run2")
    assert calls == []
    assert not (tmp_path / "run1" / "result.json").exists()


@pytest.mark.render
@pytest.mark.parametrize("scene, name", [("paper002_stereo", "stereo-sift"), ("paper001_line3m_rgbd", "orb-icp")])
def test_rendered_stereo_and_depth_sequences(tmp_path, scene, name):
    """A few rendered frames (324x247) of the stereo and the RGB-D scene: within 1 % of the distance."""
    from floorsim.scene import load_scene
    from floorsim.simulate import render_sequence
    from floorvo.run import run_estimator
    from floorvo.tum import read_tum

    seq = render_sequence(load_scene(scene), tmp_path / "seq", scale=0.5, frames=6)
    # At 324x247 stereo-sift's floor planes leave its steps about 0.06 mm uncertain (one standard
    # error), too much to vouch for issue 14's bound: its precision check loses them (tested in
    # test_stereo_sift_never_reports_an_imprecise_step_ok). The accuracy over the distance is
    # what this test checks, so the check is off here.
    res = run_estimator(seq, name, tmp_path / "run", {"precision_sigmas": 0.0} if name == "stereo-sift" else None)
    assert res.lost == 0 and res.ok == 5
    _, T_est = read_tum(tmp_path / "run" / "trajectory.txt")
    _, T_gt = read_tum(seq / "groundtruth.txt")
    travelled = np.linalg.norm(T_gt[-1][:3, 3] - T_gt[0][:3, 3])
    assert travelled > 15.0
    assert 100 * np.linalg.norm(T_est[-1][:3, 3] - T_gt[-1][:3, 3]) / travelled < 1.0


def test_orb_icp_same_pair_same_result_whatever_ran_before():
    """FLANN-LSH draws its hash bits from OpenCV's RNG: orb-icp seeds it, so a frame pair
    gives bit-identical motion however much other random work ran in between."""
    import cv2

    T_true = _motion(2.5, -1.2, 1.5)
    prev, cur, flat = frame_pair(CAM, T_true, seed=2)
    depth = flat_floor_depth(CAM)
    results = []
    for disturb in (0, 7):
        cv2.setRNGSeed(12345 + disturb)
        cv2.randu(np.zeros(1000, np.uint8), 0, 255)  # other users of OpenCV's RNG
        est = get_estimator("orb-icp")(make_config("orb-icp"), CAM, height_mm=100.0, flatfield=flat)
        st = est.start()
        est.step(st, Frame(0, 0.0, prev, depth_mm=depth))
        r = est.step(st, Frame(1, 0.1, cur, depth_mm=depth))
        assert r.ok, r.reason
        results.append((r.T_prev_cur.copy(), r.n_matches, r.n_inliers))
    np.testing.assert_array_equal(results[0][0], results[1][0])
    assert results[0][1:] == results[1][1:]


@pytest.mark.parametrize("name", ["orb-icp", "stereo-sift", "akaze-guided", "akaze-bruteforce"])
def test_two_motions_in_one_frame_are_lost_not_measured(name):
    """The left 55 % of the new frame(s) is the old frame's (a static glare or dirt on the lens),
    the rest the floor moved by (3, 1) mm: the matches show two motions, the static one the
    larger. Each estimator must report the step lost with the reason, where before every one
    reported ok with the static motion, (0, 0) mm (issue 14: never silently wrong); the
    same frames without the static part stay ok."""
    T_true = _motion(3.0, 1.0, 0.0)
    w = int(0.55 * CAM.width_px)
    if name == "stereo-sift":
        (L0, R0), (L1, R1), _, T01 = stereo_pairs(CAM, T_true, baseline_mm=20.0)
        est = get_estimator(name)(make_config(name), CAM, height_mm=100.0, camera_right=CAM, T_cam0_cam1=T01)
        frames = [Frame(0, 0.0, L0, image_right=R0), Frame(1, 0.1, L1, image_right=R1)]
        static = [L0, R0]
    else:
        prev, cur, flat = frame_pair(CAM, T_true)
        depth = flat_floor_depth(CAM)
        est = get_estimator(name)(make_config(name), CAM, height_mm=100.0, flatfield=flat)
        frames = [Frame(0, 0.0, prev, depth_mm=depth), Frame(1, 0.1, cur, depth_mm=depth)]
        static = [prev]
    st = est.start()
    est.step(st, frames[0])
    _check(est.step(st, frames[1]), T_true, name if name in TOL else "stereo-sift")
    glared = []
    for img, old in zip([frames[1].image, frames[1].image_right], static + [None]):
        if old is None:
            glared.append(img)
            continue
        img = img.copy()
        img[:, :w] = old[:, :w]
        glared.append(img)
    f2 = Frame(2, 0.2, glared[0], image_right=glared[1] if name == "stereo-sift" else None, depth_mm=frames[1].depth_mm)
    st = est.start()
    est.step(st, frames[0])
    r = est.step(st, f2)
    assert r.status == "lost" and r.T_prev_cur is None and r.reason.startswith("two motions"), r.reason


def _stereo_run_errors(tmp_path, poses, name, noise_dn=1.0):
    """A synthetic stereo sequence (324x247, 20 mm baseline) of ``poses`` run by ``name``: the
    run and the error of every step it reported ok against the camera's true 6-DoF step from the
    frame it was measured from (:func:`floorvo.scoring.ok_step_errors`)."""
    from floorvo.run import run_estimator
    from floorvo.scoring import ok_step_errors
    from floorvo.synthetic import write_synthetic_sequence

    seq = write_synthetic_sequence(tmp_path / "seq", CAM, poses, stereo_baseline_mm=20.0, noise_dn=noise_dn)
    run = run_estimator(seq, name, tmp_path / "run")
    return run, ok_step_errors(list(run.status), list(run.reason), poses, run.T_world_cam[run.placed])


@pytest.mark.parametrize("name", ["stereo-sift", "stereo-sift-fast"])
def test_stereo_sift_says_when_it_restarts_its_track(tmp_path, name):
    """A frame over another stretch of floor (the rig lifted and set down 150 mm on: nothing in
    common with the previous frame) is lost; stereo-sift takes it as the next step's reference, and
    says so (RESTART_NOTE), so the next step is scored from it. Without the note the next step,
    4 mm measured, was held against the 154 mm from the last tracked frame: a wrong step reported ok."""
    from floorvo.estimators.base import RESTART_NOTE
    from floorvo.metrics import wrong_steps

    poses = np.stack([T_world_cam_down(x, 0.0, 100.0) for x in (0.0, 4.0, 154.0, 158.0)])
    run, e = _stereo_run_errors(tmp_path, poses, name)
    assert list(run.status) == ["init", "ok", "lost", "ok"], list(run.reason)
    assert RESTART_NOTE in run.reason[2]
    assert e is not None and len(e["trans_mm"]) == 2
    assert not wrong_steps(e).any(), e


def test_stereo_sift_never_reports_an_imprecise_step_ok(tmp_path):
    """stereo-sift-fast on small, noisy frames (324x247, 8 grey levels of noise; the preset is
    meant for 648x494) of a bouncing, tilting run: 8-11 SIFT pairs a step, and floor planes
    good to about 0.3 mrad, leave each 6-DoF step 0.05-0.07 mm uncertain (one standard error),
    against issue 14's bound of 0.13 mm. Without the precision check two of its steps were
    reported ok 0.13-0.15 mm off; with it, every step reported ok is within the bound of the
    true 6-DoF step, and the others are lost as imprecise."""
    from floorvo.metrics import wrong_steps

    run, e = _stereo_run_errors(tmp_path, disturbed_poses(), "stereo-sift-fast", noise_dn=8.0)
    assert e is None or not wrong_steps(e).any(), e
    assert any(str(r).startswith("imprecise step") for r in run.reason), list(run.reason)


@pytest.mark.parametrize("update", ["plane", "rigid"])
def test_stereo_sift_undoes_the_lens_distortion_before_triangulating(tmp_path, update):
    """A stereo rig whose lenses have a mild barrel distortion (k1 = -0.1, both cameras), frames
    made by inverting the camera model exactly (:mod:`floorvo.synthetic`): stereo-sift
    triangulated the distorted keypoints with P = K [R | t] (eqs. (1)-(3) of paper 002 hold for
    a pinhole), so the floor plane came out curved and every default step was lost as
    imprecise (0.5 mm at k1 = -0.05), and with update = rigid every step was reported ok
    31-62 % long. Each step is now reported ok within issue 14's bound of the true 6-DoF step."""
    from floorvo.metrics import wrong_steps
    from floorvo.run import run_estimator
    from floorvo.scoring import ok_step_errors
    from floorvo.synthetic import write_synthetic_sequence

    # Full size: at 324x247 the floor planes alone leave most steps imprecise (BENCHMARKS.md).
    cam = CameraModel.from_sensor(648, 494, pixel_pitch_um=7.4, focal_length_mm=6.0, distortion=(-0.1, 0, 0, 0, 0))
    poses = np.stack([T_world_cam_down(4.0 * i, 0.5 * i, 100.0, np.radians(0.3 * i)) for i in range(4)])
    seq = write_synthetic_sequence(tmp_path / "seq", cam, poses, stereo_baseline_mm=20.0)
    run = run_estimator(seq, "stereo-sift", tmp_path / "run", {"update": update})
    assert list(run.status) == ["init", "ok", "ok", "ok"], list(run.reason)
    e = ok_step_errors(list(run.status), list(run.reason), poses, run.T_world_cam[run.placed])
    assert e is not None and len(e["trans_mm"]) == 3 and not wrong_steps(e).any(), e


def _depth_run(tmp_path, name: str, poses: np.ndarray, seed: int = 0, overrides: dict | None = None) -> list:
    """Every step of ``name`` over a 160 x 120 synthetic depth sequence of ``poses`` (N, 4, 4)
    mm: ``(frame, status, reason, wrong)``, ``wrong`` whether an ok step is off its true step
    (from the frame it was measured from) beyond issue 14's bound (:func:`floorvo.metrics.wrong_steps`)."""
    from floorvo.metrics import step_errors, wrong_steps
    from floorvo.run import build_estimator
    from floorvo.runner import sequence_frames
    from floorvo.sequence import Sequence
    from floorvo.synthetic import write_synthetic_sequence

    cam = CameraModel(160, 120, 202.7027, 202.7027, 79.5, 59.5)
    root = tmp_path / f"seq-{seed}"
    if not root.exists():
        write_synthetic_sequence(root, cam, poses, depth=True, seed=seed)
    seq = Sequence.open(root)
    est, _ = build_estimator(seq, name, overrides)
    state, last, out = est.start(), None, []
    for f in sequence_frames(seq, range(seq.frame_count), ("depth",)):
        r = est.step(state, f)
        wrong = False
        if r.status == "ok" and last is not None:
            e = step_errors(np.stack([poses[last], poses[f.index]]), np.stack([np.eye(4), r.T_prev_cur]))
            wrong = bool(wrong_steps(e)[0])
        out.append((f.index, r.status, r.reason, wrong))
        if r.status in ("ok", "init") or "tracking restarts" in (r.reason or ""):
            last = f.index
    return out


@pytest.mark.parametrize("name", ["orb-icp", "orb-icp-fast"])
def test_orb_icp_loses_an_imprecise_turn_in_place_instead_of_reporting_it_wrong(tmp_path, name):
    """A turn of 90 degrees in place between two 160 x 120 frames (3 mm steps before and after)
    was reported ok 0.06-0.08 mm off against the 0.05 mm bound: orb-icp had no precision check
    (``precision_sigmas = 0`` is the code before, and shows the wrong steps)."""
    poses = np.stack(
        [T_world_cam_down(3.0 * min(k, 4), 3.0 * max(k - 5, 0), 100.0, np.pi / 2 if k >= 5 else 0.0) for k in range(8)]
    )
    wrong_before = 0
    for seed in (0, 1, 2):
        assert not any(s[3] for s in _depth_run(tmp_path, name, poses, seed))
        wrong_before += sum(s[3] for s in _depth_run(tmp_path, name, poses, seed, {"precision_sigmas": "0"}))
    assert wrong_before >= 2


@pytest.mark.parametrize("name", ["orb-icp", "orb-icp-fast"])
def test_orb_icp_after_a_jump_without_overlap_loses_frames_instead_of_raising(tmp_path, name):
    """A 150 mm jump between frames 4 and 5: frame 6 kept one pair after the sub-pixel refinement
    and the rigid fit raised ValueError (a traceback from floorvo run)."""
    xs = [0, 3, 6, 9, 12, 162, 165, 168, 171]
    steps = _depth_run(tmp_path, name, np.stack([T_world_cam_down(x, 0.0, 100.0, 0.0) for x in xs]))
    assert [s[1] for s in steps[:5]] == ["init", "ok", "ok", "ok", "ok"]
    assert steps[5][1] == "lost" and not any(s[3] for s in steps)


@pytest.mark.parametrize("name", ["stereo-sift", "stereo-sift-fast"])
def test_stereo_sift_keypoints_lie_on_their_points(name):
    """OpenCV's SIFT puts every keypoint 0.25 px right of and below its point (its first octave
    doubles the image); a frame turned 180 degrees shows it as twice that between the keypoints
    of the turned frame and the turned keypoints, and stereo-sift read a turn in place as a
    translation (0.18 mm at 320 x 240, -fast twice that). Its keypoints now lie on their points
    to 0.02 px (mean over the pairs)."""
    (L0, _), _, flat, T01 = stereo_pairs(CAM, _motion(0.0, 0.0, 0.0), baseline_mm=20.0, seed=3)
    est = get_estimator(name)(
        make_config(name), CAM, height_mm=100.0, flatfield=flat, camera_right=CAM, T_cam0_cam1=T01, flatfield_right=flat
    )
    img = np.ascontiguousarray(L0)
    uv, desc = est._detect(img)
    uv_r, desc_r = est._detect(np.ascontiguousarray(img[::-1, ::-1]))
    from floorvo.matching import match_ratio

    m = match_ratio(desc, desc_r, 0.7, unique="best")
    turned = np.column_stack([CAM.width_px - 1 - uv[m.i0, 0], CAM.height_px - 1 - uv[m.i0, 1]])
    d = uv_r[m.i1] - turned
    d = d[np.linalg.norm(d, axis=1) < 1.0]
    assert len(d) > 30
    np.testing.assert_allclose(d.mean(axis=0) / 2.0, [0.0, 0.0], atol=0.03)

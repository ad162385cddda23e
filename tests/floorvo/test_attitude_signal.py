"""A measured camera attitude per frame (issue 14, "6-DoF where the sensors allow it"): the
sequence's ``attitude.csv``, the inverse of the footprint, and a planar mono estimator's
poses made the tilted camera's with it, against ground truth."""

from __future__ import annotations

import numpy as np
import pytest
from _synth import blank_meta, blank_sequence

from floorvo.camera import CameraModel
from floorvo.errors import SequenceError
from floorvo.estimators import get_estimator
from floorvo.geometry import (
    T_world_cam_down,
    attitude_of_T,
    footprint_T,
    invert_T,
    rot_z,
    tilt_twist_rad,
    tilted_camera_T,
)
from floorvo.run import build_estimator, run_estimator
from floorvo.runner import NO_ATTITUDE, uses_attitude_signal
from floorvo.scoring import score_run
from floorvo.sequence import ATTITUDE_FILE, Sequence, SequenceWriter, sequence_files
from floorvo.synthetic import write_synthetic_sequence

CAM = CameraModel.from_sensor(324, 247, pixel_pitch_um=14.8, focal_length_mm=6.0)


def _meta(n: int) -> dict:
    return blank_meta(CAM, n)


def _write(tmp_path, n: int = 3):
    return blank_sequence(tmp_path, CAM, n)


def _random_poses(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.stack(
        [
            T_world_cam_down(
                *rng.uniform(-500, 500, 2),
                rng.uniform(60, 140),
                *rng.uniform(-np.pi, np.pi, 1),
                *rng.uniform(-0.3, 0.3, 2),
            )
            for _ in range(n)
        ]
    )


def test_tilted_camera_T_inverts_footprint_T_exactly():
    """Both ways round, for random poses: the footprint of the tilted camera is the footprint
    pose given, and the tilted camera of a pose's footprint, at its attitude and height, is the pose."""
    T = _random_poses(50)
    att = attitude_of_T(T)
    for Ti, (r, p) in zip(T, att):
        F = footprint_T(Ti, 80.0)[0]
        np.testing.assert_allclose(tilted_camera_T(F, r, p, Ti[2, 3]), Ti, rtol=0, atol=1e-9)
        G = T_world_cam_down(12.0, -3.0, 91.0, 0.7)  # any level footprint pose
        np.testing.assert_allclose(footprint_T(tilted_camera_T(G, r, p), 91.0)[0], G, rtol=0, atol=1e-9)
    # a level camera is its own footprint
    L = T_world_cam_down(5.0, 6.0, 100.0, 1.2)
    np.testing.assert_allclose(tilted_camera_T(L, 0.0, 0.0), L, rtol=0, atol=1e-12)


def test_attitude_is_the_direction_of_gravity_in_the_camera_frame():
    T = T_world_cam_down(1.0, 2.0, 100.0, 2.5, 0.04, -0.03)
    np.testing.assert_allclose(attitude_of_T(T), [0.04, -0.03], atol=1e-12)  # whatever the yaw
    g = T[:3, :3].T @ [0.0, 0.0, -1.0]
    r, p = 0.04, -0.03
    np.testing.assert_allclose(g, [np.sin(p), np.sin(r) * np.cos(p), np.cos(r) * np.cos(p)], atol=1e-12)
    # the turn about the optical axis between two tilts: the rotation between the two cameras
    a, b = T_world_cam_down(0, 0, 100, 0.0, 0.03, 0.0), T_world_cam_down(0, 0, 100, 0.0, 0.028, 0.009)
    rel = invert_T(a)[:3, :3] @ b[:3, :3]
    from scipy.spatial.transform import Rotation

    assert tilt_twist_rad((0.03, 0.0), (0.028, 0.009)) == pytest.approx(Rotation.from_matrix(rel).as_rotvec()[2])
    assert tilt_twist_rad((0.01, 0.02), (0.01, 0.02)) == 0.0
    np.testing.assert_allclose(rot_z(0.0), np.eye(3))


def test_attitude_file_round_trip_and_a_folder_without_it_loads_as_before(tmp_path):
    root = _write(tmp_path)
    assert Sequence.open(root).attitude_signal_rad is None
    with SequenceWriter(root, _meta(3)) as w:
        w.write_attitude(np.array([[0.01, -0.02], [np.nan, np.nan], [0.0, 0.5]]))
    text = (root / ATTITUDE_FILE).read_text().splitlines()
    assert text[1:] == ["frame,roll_rad,pitch_rad", "0,0.010000000,-0.020000000", "1,,", "2,0.000000000,0.500000000"]
    a = Sequence.open(root).attitude_signal_rad
    np.testing.assert_array_equal(a, [[0.01, -0.02], [np.nan, np.nan], [0.0, 0.5]])
    assert root / ATTITUDE_FILE in sequence_files(root)  # --overwrite removes it with the sequence
    from floorvo.runner import sequence_frames

    frames = list(sequence_frames(Sequence.open(root), range(3)))
    assert frames[0].attitude_rad == (0.01, -0.02) and frames[2].attitude_rad == (0.0, 0.5)
    assert np.isnan(frames[1].attitude_rad).all()


@pytest.mark.parametrize(
    "body, message",
    [
        (
            "frame,roll,pitch\n0,0,0\n1,0,0\n2,0,0\n",
            r"attitude.csv:1: header 'frame,roll,pitch': must be 'frame,roll_rad,pitch_rad'",
        ),
        (
            "frame,roll_rad,pitch_rad\n0,0,0\n2,0,0\n1,0,0\n",
            r"attitude.csv:3: frame '2': rows must be frames 0, 1, \.\.\. in order",
        ),
        (
            "frame,roll_rad,pitch_rad\n0,0,0\n1,0.7,0\n2,0,0\n",
            r"roll_rad of frame 1 = 0.7: must be a finite number of radians within \+-0.5",
        ),
        ("frame,roll_rad,pitch_rad\n0,0,0\n1,0,inf\n2,0,0\n", r"pitch_rad of frame 1 = inf: must be a finite number"),
        ("frame,roll_rad,pitch_rad\n0,0,0\n1,0.01,\n2,0,0\n", r"frame 1 has roll 0.01 and pitch nan: both or neither"),
        (
            "frame,roll_rad,pitch_rad\n0,0,0\n1,2deg,0\n2,0,0\n",
            r"attitude.csv:3: roll_rad '2deg' of frame 1: not a number",
        ),
        (
            "frame,roll_rad,pitch_rad\n0,0,0\n1,0,0\n",
            r"2 \(roll, pitch\) row\(s\) for 3 frame\(s\); need one per frame",
        ),
        ("frame,roll_rad,pitch_rad\n0,0,0\n1,0\n2,0,0\n", r"attitude.csv:3: '1,0': need three cells"),
        ("# nothing\n", r"no header line 'frame,roll_rad,pitch_rad'"),
    ],
)
def test_a_bad_attitude_file_is_refused_in_one_line(tmp_path, body, message):
    root = _write(tmp_path)
    (root / ATTITUDE_FILE).write_text(body)
    with pytest.raises(SequenceError, match=message) as err:
        Sequence.open(root)
    assert "\n" not in str(err.value) and "attitude.csv" in str(err.value)
    with SequenceWriter(root, _meta(3)) as w, pytest.raises(SequenceError, match="need one per frame"):
        w.write_attitude(np.zeros((1, 2)))


def _tilt_poses(n: int = 30, amp: float = 0.03) -> np.ndarray:
    """4 mm/frame along x with roll and pitch of ``amp`` rad at 1.5 Hz, a quarter period apart
    (the motion suite's tilt, ``floorsim.trajectories``), at 30 fps."""
    t = np.arange(n) / 30.0
    roll, pitch = amp * np.sin(3 * np.pi * t), amp * np.sin(3 * np.pi * t + np.pi / 2)
    return np.stack([T_world_cam_down(4.0 * i, 0.0, 100.0, 0.0, roll[i], pitch[i]) for i in range(n)])


def _with_dropout(seq_dir, tmp_path, frame: int):
    """A copy of the sequence ``seq_dir`` in ``tmp_path/seq`` whose ``attitude.csv`` has no
    reading for ``frame``."""
    import shutil

    root = tmp_path / "seq"
    shutil.copytree(seq_dir, root)
    a = Sequence.open(root).attitude_signal_rad
    a[frame] = np.nan
    with SequenceWriter(root, Sequence.open(root).meta) as w:
        w.write_attitude(a)
    return root


@pytest.fixture(scope="module")
def tilt_seq(tmp_path_factory):
    return write_synthetic_sequence(tmp_path_factory.mktemp("tilt") / "seq", CAM, _tilt_poses(), attitude_noise_rad=0.0)


@pytest.mark.parametrize("levelled, end_mm", [(True, 0.02), (False, 0.003 * 116.0)])
def test_phase_corr_with_the_attitude_reproduces_the_tilted_cameras_trajectory(
    tilt_seq, tmp_path, monkeypatch, levelled, end_mm
):
    """Without the signal a planar estimator's end is off by about height x tilt (the footprint
    under the tilted optical axis, 3-4 mm here) and every 6-DoF step is wrong; with it the run
    reports the tilted camera's poses, every step within issue 14's bound of the camera's 6-DoF
    step, and scoring holds it to that step. phase-corr levels each frame with its attitude
    (``levels_with_attitude``): the end within 0.02 mm of the truth (0.014 here, bilinear). An estimator that measures
    the footprint and does not level (a plugin; phase-corr with the flag off), whose footprint
    the runner turns back: within 0.3 % of the path (the rest: the picture of a tilted floor,
    whose perspective the planar fit reads as a little turn)."""
    from floorvo.estimators.phase_corr import PhaseCorr

    monkeypatch.setattr(PhaseCorr, "levels_with_attitude", levelled)
    T = _tilt_poses()
    seq = Sequence.open(tilt_seq)
    off = run_estimator(seq, "phase-corr", tmp_path / "off", {"use_attitude_signal": "false"})
    on = run_estimator(seq, "phase-corr", tmp_path / "on")
    assert not off.attitude_signal and on.attitude_signal
    assert off.lost == 0 and on.lost == 0
    end_off = np.linalg.norm(off.T_world_cam[-1][:3, 3] - T[-1][:3, 3])
    end_on = np.linalg.norm(on.T_world_cam[-1][:3, 3] - T[-1][:3, 3])
    assert end_off > 100.0 * 0.03  # height x tilt, and more
    assert end_on < end_mm
    np.testing.assert_allclose(attitude_of_T(on.T_world_cam), attitude_of_T(T), atol=1e-12)  # the tilt is the signal's
    s_on, s_off = score_run(tmp_path / "on", tilt_seq), score_run(tmp_path / "off", tilt_seq)
    assert s_on.tracking["wrong_ok_steps"] == 0 and s_on.tracking["attitude_signal"] is True
    assert "wrong_ok_steps_footprint" not in s_on.tracking  # held to the camera's step only
    assert s_off.tracking["wrong_ok_steps"] == 29 and s_off.tracking["wrong_ok_steps_footprint"] == 0


def test_a_signal_the_run_does_not_use_is_not_handed_to_the_estimator(tilt_seq, tmp_path):
    """A run that starts at the identity (no ground truth) does not use the attitude signal (its
    optical axis meets no floor; a warning says so), yet phase-corr still levelled its frames
    with it and lost the frame without a reading. It now runs as with the signal switched off."""
    root = _with_dropout(tilt_seq, tmp_path, 7)
    (root / "groundtruth.txt").unlink()
    unused = run_estimator(Sequence.open(root), "phase-corr", tmp_path / "unused")
    off = run_estimator(Sequence.open(root), "phase-corr", tmp_path / "off", {"use_attitude_signal": "false"})
    assert not unused.attitude_signal and unused.lost == 0
    np.testing.assert_array_equal(unused.T_world_cam, off.T_world_cam)


@pytest.mark.parametrize("levelled", [True, False])
def test_a_frame_without_an_attitude_reading_is_lost_and_the_next_one_right(tilt_seq, tmp_path, monkeypatch, levelled):
    """A dropout (NaN row) is no 6-DoF pose: the frame is reported lost with the reason. phase-corr,
    which levels its frames, cannot measure it (``NO_ATTITUDE_READING``) and measures the next
    frame from the last one it measured; an estimator that measures the footprint has its
    motion chained through it by the runner (``NO_ATTITUDE``; the turn of the two tilt changes
    about the optical axis taken out in one). Either way the frames after it are placed as
    without the dropout (to 10 um and 0.1 mrad)."""
    from floorvo.estimators.base import NO_ATTITUDE_READING
    from floorvo.estimators.phase_corr import PhaseCorr

    monkeypatch.setattr(PhaseCorr, "levels_with_attitude", levelled)
    root = _with_dropout(tilt_seq, tmp_path, 7)
    full = run_estimator(Sequence.open(tilt_seq), "phase-corr", tmp_path / "full")
    gap = run_estimator(Sequence.open(root), "phase-corr", tmp_path / "gap")
    assert gap.status[7] == "lost" and gap.lost == 1
    assert gap.reason[7] == (NO_ATTITUDE_READING if levelled else NO_ATTITUDE)
    np.testing.assert_allclose(gap.T_world_cam[8:, :3, 3], full.T_world_cam[8:, :3, 3], rtol=0, atol=0.01)
    np.testing.assert_allclose(gap.T_world_cam[8:, :3, :3], full.T_world_cam[8:, :3, :3], rtol=0, atol=1e-4)
    assert score_run(tmp_path / "gap", root).tracking["wrong_ok_steps"] == 0


def test_a_level_run_with_an_attitude_of_zero_keeps_its_steps(tmp_path):
    """Tilt 0: the signal changes nothing (to rounding) on a level run that turns."""
    n = 12
    T = np.stack([T_world_cam_down(3.0 * i, 0.2 * i * i, 100.0, 0.02 * i) for i in range(n)])
    with_sig = write_synthetic_sequence(tmp_path / "a", CAM, T, attitude_noise_rad=0.0)
    without = write_synthetic_sequence(tmp_path / "b", CAM, T)
    a = run_estimator(Sequence.open(with_sig), "phase-corr", tmp_path / "ra")
    b = run_estimator(Sequence.open(without), "phase-corr", tmp_path / "rb")
    assert a.attitude_signal and not b.attitude_signal
    np.testing.assert_allclose(a.T_world_cam, b.T_world_cam, rtol=0, atol=1e-9)


@pytest.mark.parametrize(
    "name, corrected",
    [
        ("phase-corr", True),
        ("phase-corr-fast", True),
        ("akaze-guided", True),
        ("akaze-bruteforce-fast", True),
        ("homography-6dof", False),
        ("orb-icp", False),
        ("stereo-sift", False),
    ],
)
def test_only_the_planar_estimators_are_turned_by_the_signal(tilt_seq, name, corrected):
    """Estimators that measure the tilt (depth, stereo, the homography) are not corrected twice."""
    cls = get_estimator(name)
    if cls.requires:
        assert not getattr(cls, "measures_footprint", False)
        return
    est, _ = build_estimator(Sequence.open(tilt_seq), name)
    assert uses_attitude_signal(est) is corrected
    est_off, _ = build_estimator(Sequence.open(tilt_seq), name, {"use_attitude_signal": "false"})
    assert not uses_attitude_signal(est_off)


def test_attitude_noise_is_estimated_from_the_signal_itself():
    """White noise of s rad on the motion suite's smooth tilt (0.03 rad at 1.5 Hz, 30 fps): the
    third differences give s back within 15 % for 1.5 and 0.5 mrad (the tilt's own third
    differences, 0.9 mrad at most, add little once the noise dominates); an exact signal reads
    about 0.2 mrad, the tilt's curvature (an upper bound, never 0); dropouts are skipped."""
    from floorvo.geometry import attitude_of_T
    from floorvo.runner import attitude_noise_rad

    truth = attitude_of_T(_tilt_poses(300))
    rng = np.random.default_rng(5)
    for s in (1.5e-3, 0.5e-3):
        noisy = truth + rng.normal(0.0, s, truth.shape)
        noisy[[10, 50, 51]] = np.nan
        assert attitude_noise_rad(noisy) == pytest.approx(s, rel=0.15)
    assert 0.05e-3 < attitude_noise_rad(truth) < 0.3e-3
    assert attitude_noise_rad(None) == 0.0 and attitude_noise_rad(truth[:1]) == 0.0
    # every other reading missing: no two consecutive (it read 0, the noise taken as nil); the
    # readings two frames apart give it back, an upper bound (the tilt's own differences grow
    # with the spacing: 1.83 mrad here)
    noisy = truth + rng.normal(0.0, 1.5e-3, truth.shape)
    noisy[1::2] = np.nan
    assert 1.5e-3 * 0.9 < attitude_noise_rad(noisy) < 1.5e-3 * 1.4


@pytest.mark.parametrize("noise_rad, lost", [(1.5e-3, True), (0.2e-3, False)])
def test_a_noisy_attitude_signal_loses_the_steps_it_leaves_uncertain(tmp_path, noise_rad, lost):
    """A reading's error moves the camera's pose by height x error: 1.5 mrad of white noise at
    100 mm makes each 6-DoF step uncertain by 0.21 mm, beyond issue 14's bound of a 4 mm step
    (0.13 mm), and those steps, reported ok before, were wrong; now each is lost with the
    reason, its motion chained. 0.2 mrad (an attitude filter's output) keeps every step, none
    wrong. Scored against the camera's 6-DoF step (ground truth)."""
    seq = write_synthetic_sequence(tmp_path / "seq", CAM, _tilt_poses(), attitude_noise_rad=noise_rad, seed=2)
    res = run_estimator(Sequence.open(seq), "phase-corr", tmp_path / "run")
    flat = score_run(tmp_path / "run", seq).tracking
    assert flat["wrong_ok_steps"] == 0
    if lost:
        assert res.lost == 29
        assert all(r.startswith("attitude signal too noisy for the step") for r in res.reason[1:])
        # unchecked (no precision check at all), the same steps are reported ok and most are wrong
        run_estimator(Sequence.open(seq), "phase-corr", tmp_path / "unchecked", {"precision_sigmas": "0"})
        assert score_run(tmp_path / "unchecked", seq).tracking["wrong_ok_steps"] >= 20
    else:
        assert res.lost == 0


def test_akaze_levels_its_keypoints_with_the_attitude(tilt_seq, tmp_path):
    """akaze-guided moves each frame's keypoints to where a camera at the same centre looking
    straight down sees them (``levels_with_attitude``): between two levelled frames only the
    floor's motion is left, so its steps are the camera's own and the runner tilts the chained
    pose about its centre. On the synthetic tilted run the end is within 0.01 mm of the truth
    (phase-corr, whose footprint the runner turns back, 0.25 mm), none wrong against the 6-DoF
    step; without the signal the end is 7 mm off and every step wrong but against the footprint."""
    T = _tilt_poses()
    seq = Sequence.open(tilt_seq)
    on = run_estimator(seq, "akaze-guided", tmp_path / "on")
    off = run_estimator(seq, "akaze-guided", tmp_path / "off", {"use_attitude_signal": "false"})
    assert on.attitude_signal and on.lost == 0
    assert np.linalg.norm(on.T_world_cam[-1][:3, 3] - T[-1][:3, 3]) < 0.01
    np.testing.assert_allclose(attitude_of_T(on.T_world_cam), attitude_of_T(T), atol=1e-12)
    assert score_run(tmp_path / "on", tilt_seq).tracking["wrong_ok_steps"] == 0
    assert np.linalg.norm(off.T_world_cam[-1][:3, 3] - T[-1][:3, 3]) > 100.0 * 0.03
    s_off = score_run(tmp_path / "off", tilt_seq).tracking
    assert s_off["wrong_ok_steps"] == 29 and s_off["wrong_ok_steps_footprint"] == 0


def test_akaze_without_an_attitude_reading_loses_the_frame_and_measures_the_next_from_the_last(tilt_seq, tmp_path):
    """A dropout: the frame's keypoints cannot be levelled, so akaze reports it lost with the
    reason and measures the next frame from the last one it measured, placed as without the gap."""
    from floorvo.estimators.base import NO_ATTITUDE_READING

    root = _with_dropout(tilt_seq, tmp_path, 7)
    full = run_estimator(Sequence.open(tilt_seq), "akaze-guided", tmp_path / "full")
    gap = run_estimator(Sequence.open(root), "akaze-guided", tmp_path / "gap")
    assert gap.status[7] == "lost" and gap.reason[7] == NO_ATTITUDE_READING and gap.lost == 1
    np.testing.assert_allclose(gap.T_world_cam[8:, :3, 3], full.T_world_cam[8:, :3, 3], rtol=0, atol=0.01)
    assert score_run(tmp_path / "gap", root).tracking["wrong_ok_steps"] == 0


def test_a_step_measured_from_a_restart_frame_is_scored_from_that_frames_attitude():
    """A levelled run that restarts its track on a lost frame r measured the next step from r,
    and holds r at the last placed pose's position and yaw tilted to r's attitude (the chain
    does not move over lost frames). Hand-built run: the truth tilts 0.03 rad between the last
    placed frame and r; the run measured the step from r exactly. Scored from the last placed
    pose the step is off by that tilt change (1.7 degrees); from r's pose (levelled_restart_poses)
    it is exact."""
    from floorvo.estimators.base import RESTART_NOTE
    from floorvo.metrics import step_errors
    from floorvo.scoring import levelled_restart_poses, ok_step_poses

    truth = np.stack(
        [
            T_world_cam_down(0.0, 0.0, 100.0, 0.0, 0.0, 0.0),
            T_world_cam_down(4.0, 0.0, 100.0, 0.0, 0.01, 0.0),
            T_world_cam_down(8.0, 0.0, 100.0, 0.0, 0.02, 0.0),  # lost
            T_world_cam_down(12.0, 0.0, 100.0, 0.0, 0.04, 0.0),  # lost, restart
            T_world_cam_down(16.0, 0.0, 100.0, 0.0, 0.03, 0.0),
        ]
    )
    statuses = ["init", "ok", "lost", "lost", "ok"]
    reasons = ["first frame", "", "blocks disagree", f"blocks disagree; {RESTART_NOTE}", ""]
    att = attitude_of_T(truth)
    # The run: frames 0, 1 placed at the truth; the chain stays at frame 1's (level: x 4, yaw 0)
    # over the gap; the step r -> 4 (4 mm along x, level) chained onto it, tilted by frame 4's attitude.
    placed = np.stack([truth[0], truth[1], T_world_cam_down(8.0, 0.0, 100.0, 0.0, *att[4])])
    A, A_from, B = ok_step_poses(statuses, reasons, truth, placed)
    from_last = step_errors(A, B, T_ref_from=A_from)
    B_from = levelled_restart_poses(statuses, reasons, placed, att)
    from_r = step_errors(A, B, T_ref_from=A_from, T_est_from=B_from)
    assert from_last["rot_deg"][1] == pytest.approx(np.degrees(0.03), abs=1e-6)
    np.testing.assert_allclose(from_r["rot_deg"], 0.0, atol=1e-6)
    np.testing.assert_allclose(from_r["trans_mm"], 0.0, atol=1e-9)


def test_akaze_reports_its_pairs_in_each_frames_own_pixels(tilt_seq):
    """Levelled, akaze fits keypoints moved to a level camera's view, but the pairs it reports
    (``StepResult.matches_px``, for reports and wrong_steps.py) are in each frame's own pixels:
    moved back, they are keypoints AKAZE detected in that frame (to 1e-6 px)."""
    from floorvo.runner import sequence_frames

    seq = Sequence.open(tilt_seq)
    est, _ = build_estimator(seq, "akaze-guided")
    state = est.start()
    frames = list(sequence_frames(seq, range(3)))
    results = [est.step(state, f) for f in frames]
    assert [r.status for r in results] == ["init", "ok", "ok"]
    detected = [est._detect(f.image)[0] for f in frames]
    for k in (1, 2):
        m = results[k].matches_px
        for pts, kps in ((m[:, :2], detected[k - 1]), (m[:, 2:], detected[k])):
            nearest = np.min(np.linalg.norm(pts[:, None, :] - kps[None, :, :], axis=2), axis=1)
            assert nearest.max() < 1e-6


def test_the_step_table_holds_the_steps_as_the_score_does(tmp_path):
    """``scoring.ok_step_table`` lists a run's ok steps as ``score_run`` scores them: for a run
    levelled with an attitude signal, its 6-DoF steps against the camera's (a diagnostic that
    compared the estimator's levelled steps with them had called nearly every step wrong): the
    same count of steps and of wrong ones, each step from the frame it was measured from."""
    from floorvo.scoring import ok_step_table

    seq = write_synthetic_sequence(tmp_path / "seq", CAM, _tilt_poses(), attitude_noise_rad=0.3e-3, seed=4)
    run = run_estimator(Sequence.open(seq), "phase-corr", tmp_path / "run")
    table = ok_step_table(tmp_path / "run", seq)
    flat = score_run(tmp_path / "run", seq).tracking
    assert len(table) == flat["ok_steps_scored"] and sum(s["wrong"] for s in table) == flat["wrong_ok_steps"]
    placed = [int(i) for i, st in zip(run.frame_index, run.status) if st in ("init", "ok")]
    assert [s["to_frame"] for s in table] == placed[1:]
    T = _tilt_poses()
    for s in table:  # the truth of each step, from the ground truth by hand
        np.testing.assert_allclose(s["true"], np.linalg.inv(T[s["from_frame"]]) @ T[s["to_frame"]], atol=1e-6)


@pytest.mark.parametrize("name", ["akaze-guided", "akaze-bruteforce"])
def test_the_rigid_fit_with_an_attitude_signal_loses_a_height_change_it_cannot_report(tmp_path, name):
    """Paper 000's rigid fit reports no height change. On a bouncing (1 mm at 2 Hz) and tilting
    (0.02 rad) run levelled with an IMU, its height check allowed the tilt's shading to be read
    as a height change (camera height x tilt change beyond 2 mrad, 0.7 mm a frame here), which
    let the bounce's changes through: 25 of 29 steps were ok and wrong against the camera's
    6-DoF step, which a levelled run's poses claim. Now such a step is lost, none is wrong."""
    t = np.arange(30) / 30.0
    poses = np.stack(
        [
            T_world_cam_down(
                4.0 * i,
                0.0,
                100.0 + np.sin(4 * np.pi * t[i]),
                0.0,
                0.02 * np.sin(3 * np.pi * t[i]),
                0.02 * np.cos(3 * np.pi * t[i]),
            )
            for i in range(30)
        ]
    )
    seq = write_synthetic_sequence(tmp_path / "seq", CAM, poses, attitude_noise_rad=0.0)
    run_estimator(Sequence.open(seq), name, tmp_path / "run")
    flat = score_run(tmp_path / "run", seq).tracking
    assert flat["wrong_ok_steps"] == 0 and flat["lost_frames"] > 10

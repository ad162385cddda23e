"""Trajectory metrics against hand-computed truth and against evo on the same TUM files."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from floorvo import metrics as M
from floorvo.geometry import T_world_cam_down, make_T, rot_z
from floorvo.tum import write_tum


def line_traj(n=26, step_mm=4.0, scale=1.0, yaw_rate=0.0, height_mm=100.0):
    """Poses along +x; the estimate variant scales every step and adds a yaw drift per frame."""
    xs = np.arange(n) * step_mm * scale
    return np.stack([T_world_cam_down(x, 0.0, height_mm, yaw_rate * i) for i, x in enumerate(xs)])


def wiggly_traj(n=60, seed=0):
    rng = np.random.default_rng(seed)
    x = np.cumsum(rng.uniform(1.0, 3.0, n))
    y = np.cumsum(rng.normal(0, 0.5, n))
    yaw = np.cumsum(rng.normal(0, 0.02, n))
    z = 100 + rng.normal(0, 0.2, n)
    return np.stack(
        [T_world_cam_down(x[i], y[i], z[i], yaw[i], rng.normal(0, 0.01), rng.normal(0, 0.01)) for i in range(n)]
    )


# ----------------------------------------------------------------------------- association
def test_associate_pairs_nearest_within_tolerance_and_uses_each_reference_once():
    t_ref = np.array([0.0, 0.1, 0.2, 0.3, 0.4])
    t_est = np.array([0.001, 0.099, 0.102, 0.25, 0.4])
    i_ref, i_est = M.associate(t_ref, t_est, max_diff_s=0.01)
    # 0.099 and 0.102 both want ref 0.1: the closer (0.099) wins; 0.25 is 0.05 away from both.
    assert i_ref.tolist() == [0, 1, 4]
    assert i_est.tolist() == [0, 1, 4]


# ----------------------------------------------------------------------------- alignment / ATE
def test_ate_alignments_remove_exactly_their_gauge_and_keep_inputs():
    ref = wiggly_traj()
    G = make_T(rot_z(0.4), [7.0, -2.0, 0.0])  # an SE(2) gauge change
    est = np.einsum("ij,njk->nik", G, ref)
    ref0, est0 = ref.copy(), est.copy()
    assert M.ate(ref, est, "se2")["trans_mm"]["rmse"] < 1e-9
    assert M.ate(ref, est, "se3")["trans_mm"]["rmse"] < 1e-9
    assert M.ate(ref, est, "origin")["trans_mm"]["rmse"] < 1e-9  # a rigid copy: its first pose fixes the gauge
    none = M.ate(ref, est, "none")
    expected = np.linalg.norm(ref[:, :3, 3] - est[:, :3, 3], axis=1)
    assert none["trans_mm"]["rmse"] == pytest.approx(np.sqrt(np.mean(expected**2)))
    assert none["trans_mm"]["max"] == pytest.approx(expected.max())
    assert none["alignment"] == "none"
    np.testing.assert_array_equal(ref, ref0)
    np.testing.assert_array_equal(est, est0)
    # A height offset is not an SE(2) gauge: se2 keeps it, se3 removes it.
    up = est.copy()
    up[:, 2, 3] += 0.5
    assert M.ate(ref, up, "se2")["trans_mm"]["rmse"] == pytest.approx(0.5, abs=1e-9)
    assert M.ate(ref, up, "se3")["trans_mm"]["rmse"] < 1e-9


def test_se3_alignment_of_a_straight_path_takes_the_least_rotation():
    """Points on one line leave the turn about it free: the SVD's pick gave an estimate off by a
    constant offset 0-180 degrees of rotation error (median 90; evo refuses such input). The least
    rotation that fits is taken: none for an offset, the turn itself for a turned copy, and a
    bent estimate is fitted as well as the SVD fits it."""
    ref = line_traj(n=31)
    rng = np.random.default_rng(0)
    for _ in range(20):
        est = ref.copy()
        est[:, :3, 3] += rng.normal(0.0, 5.0, 3)
        a = M.ate(ref, est, "se3")
        assert a["trans_mm"]["rmse"] < 1e-9 and a["rot_deg"]["max"] < 1e-9, a
    turned = np.einsum("ij,njk->nik", make_T(rot_z(np.radians(10.0)), [5.0, -3.0, 2.0]), ref)
    assert M.ate(ref, turned, "se3")["rot_deg"]["max"] < 1e-9
    bent = ref.copy()
    bent[:, 1, 3] += 0.01 * np.arange(31) ** 2
    aligned, _ = M.align(ref, bent, "se3")
    from floorvo.geometry import rigid_fit

    R, t = rigid_fit(bent[:, :3, 3], ref[:, :3, 3])
    svd = np.linalg.norm(bent[:, :3, 3] @ R.T + t - ref[:, :3, 3], axis=1)
    ours = np.linalg.norm(aligned[:, :3, 3] - ref[:, :3, 3], axis=1)
    assert np.sqrt(np.mean(ours**2)) == pytest.approx(np.sqrt(np.mean(svd**2)), rel=1e-9)


def test_origin_alignment_maps_first_pose_onto_reference():
    ref = wiggly_traj()
    est = np.einsum("ij,njk->nik", make_T(rot_z(-0.2), [1, 2, 3]), ref)
    a = M.ate(ref, est, "origin")
    assert a["trans_mm"]["rmse"] < 1e-9  # a rigid copy becomes the reference exactly


# ----------------------------------------------------------------------------- RPE, drift, segments
def test_wrong_steps_by_issue_14s_bound_hand_computed():
    """Steps of 4 mm: the bound is 0.05 + 0.08 = 0.13 mm and 0.3 degrees."""
    ref = line_traj(n=5, step_mm=4.0)
    est = ref.copy()
    est[2:, 0, 3] += 0.12  # step 2 is 0.12 mm long: within the bound
    est[3:, 0, 3] += 0.14  # step 3 is 0.14 mm long: over it
    est[4] = est[4] @ make_T(rot_z(np.radians(0.31)), [0, 0, 0])  # step 4 turns 0.31 degrees
    e = M.step_errors(ref, est)
    np.testing.assert_allclose(e["step_mm"], [4.0, 4.0, 4.0, 4.0])
    np.testing.assert_allclose(e["trans_mm"], [0.0, 0.12, 0.14, 0.0], atol=1e-9)
    np.testing.assert_allclose(e["rot_deg"], [0.0, 0.0, 0.0, 0.31], atol=1e-6)
    assert M.wrong_steps(e).tolist() == [False, False, True, True]
    assert M.wrong_steps(e, rot_deg=0.5).tolist() == [False, False, True, False]
    # Frame 2 lost and the track restarted on it: frame 3's 4 mm step was measured from frame 2.
    ref3, est3 = ref[[0, 1, 3]], ref[[0, 1, 3]].copy()
    est3[2] = est3[1] @ make_T(np.eye(3), [4.0, 0.0, 0.0])  # the chain continues from frame 1
    e3 = M.step_errors(ref3, est3, T_ref_from=ref[[0, 2]])
    np.testing.assert_allclose(e3["trans_mm"], [0.0, 0.0], atol=1e-9)
    assert M.step_errors(ref3, est3)["trans_mm"][1] == pytest.approx(4.0)  # against frame 1 it is 4 mm short


def test_lost_steps_are_counted_per_kind_of_reason():
    reasons = [
        "first frame",
        "weak correlation peak 0.012",
        "weak correlation peak 0.003; tracking restarts from this frame",
        "guided prediction doubtful (the motion differs from the prediction by 20.1 px (search radius 24.0)): "
        "matched by brute force; too few matches (3 < 6)",
        "only 12 % of 50 matches agree with the fit (within 2 px; needs 20 %)",
        "matched by brute force",
        "",
    ]
    statuses = ["init", "lost", "lost", "lost", "lost", "ok", "lost"]
    assert [M.reason_kind(r) for r in reasons[1:5]] == [
        "weak correlation peak #",
        "weak correlation peak #",
        "too few matches",
        "only # % of # matches agree with the fit",
    ]
    assert M.lost_reasons(statuses, reasons) == {
        "weak correlation peak #": 2,
        "(no reason)": 1,
        "only # % of # matches agree with the fit": 1,
        "too few matches": 1,
    }
    t = M.tracking_stats(statuses, 7, 2, reasons)
    assert t["lost_frames"] == 5 and sum(t["lost_reasons"].values()) == 5
    # a timing.csv without reasons (a program's): its lost frames counted as without one (they were left out)
    assert M.tracking_stats(statuses, 7, 2)["lost_reasons"] == {"(no reason)": 5}
    assert "lost_reasons" not in M.tracking_stats(["init", "ok"], 2, 2)
    # the runner's note that it chains the motion through a frame is no cause: every attitude
    # reason was counted as 'the motion is chained through this frame'
    from floorvo.runner import NO_ATTITUDE

    noisy = f"attitude signal too noisy for the step: 0.150 mm > bound 0.130 mm; {M.CHAINED_NOTE}"
    assert M.lost_reasons(["lost", "lost", "lost"], [NO_ATTITUDE, noisy, noisy]) == {
        "attitude signal too noisy for the step": 2,
        "no attitude reading": 1,
    }


def test_rpe_and_drift_of_a_scale_error_are_hand_computable():
    ref = line_traj(n=26, step_mm=4.0)
    est = line_traj(n=26, step_mm=4.0, scale=1.01)  # 1 % too long
    r = M.rpe(ref, est, delta_frames=1)
    assert r["trans_mm"]["rmse"] == pytest.approx(0.04, rel=1e-9)
    assert r["rot_deg"]["max"] < 1e-9
    rd = M.rpe(ref, est, delta_mm=20.0)
    assert rd["trans_mm"]["mean"] == pytest.approx(0.2, rel=1e-9)
    assert len(rd["pairs"]) == 26 - 5
    d = M.end_point_drift(ref, est)
    assert d["path_length_mm"] == pytest.approx(100.0)
    assert d["end_error_mm"] == pytest.approx(1.0)
    assert d["end_drift_pct"] == pytest.approx(1.0)
    assert d["measured_mm"] == pytest.approx(101.0)
    assert d["distance_error_pct"] == pytest.approx(1.0)
    segs = M.segment_errors(ref, est)
    assert [s["length_mm"] for s in segs] == [10.0, 25.0, 50.0, 100.0]
    # Segments end on the first pose at or past L: for L = 10 that is 12 mm of path, error 0.12 mm -> 1.2 % of L.
    s10 = segs[0]
    assert s10["t_err_pct"] == pytest.approx(1.2, rel=1e-9)
    assert segs[3]["t_err_pct"] == pytest.approx(1.0, rel=1e-9) and segs[3]["count"] == 1
    assert all(s["r_err_deg_per_m"] < 1e-6 for s in segs)


def test_segment_rotation_error_per_metre():
    ref = line_traj(n=26, step_mm=4.0)
    est = line_traj(n=26, step_mm=4.0, yaw_rate=np.radians(0.01))  # 0.01 deg of yaw per 4 mm frame
    seg100 = [s for s in M.segment_errors(ref, est) if s["length_mm"] == 100.0][0]
    assert seg100["r_err_deg_per_m"] == pytest.approx(0.25 * 1000 / 100, rel=1e-6)  # 25 frames x 0.01 deg over 0.1 m


def test_tracking_stats_count_events_and_frames():
    st = ["init", "ok", "lost", "lost", "ok", "lost", "ok"]
    t = M.tracking_stats(st, 7, 4)
    assert t["lost_frames"] == 3 and t["loss_events"] == 2
    assert t["tracked_fraction"] == pytest.approx(4 / 7)
    g = M.tracking_stats(None, 10, 7)
    assert g["lost_frames"] == 3 and g["source"] == "gaps"


def test_timing_stats():
    timing = {"total_ms": np.array([10.0, 20.0, 30.0, 40.0]), "status": np.array(["ok"] * 4, dtype=object)}
    s = M.timing_stats(timing)
    assert s["total_ms"]["mean"] == 25.0 and s["total_ms"]["max"] == 40.0
    assert s["fps"] == pytest.approx(40.0)


# ----------------------------------------------------------------------------- agreement with evo
def test_numbers_agree_with_evo_on_the_same_tum_files(tmp_path, monkeypatch):
    monkeypatch.setenv("HOME", str(tmp_path))  # evo writes its settings into the home folder
    # evo is a test dependency (pyproject's [test] extra): missing, this test fails instead of skipping.
    from evo.core import metrics as em
    from evo.core import sync
    from evo.tools import file_interface

    n = 80
    ts = np.arange(n) / 30.0
    ref = wiggly_traj(n, seed=3)
    rng = np.random.default_rng(4)
    noise = np.stack([T_world_cam_down(*rng.normal(0, 0.3, 2), 0.0, rng.normal(0, 0.01)) for _ in range(n)])
    noise[:, 2, 3] = rng.normal(0, 0.1, n)
    est = np.einsum("ij,njk->nik", make_T(rot_z(0.3), [4.0, 1.0, 0.5]), ref @ noise)
    write_tum(tmp_path / "gt.txt", ts, ref)
    write_tum(tmp_path / "est.txt", ts[::2] + 0.001, est[::2])  # every other frame, 1 ms late

    from floorvo.tum import read_tum

    t_ref, T_ref = read_tum(tmp_path / "gt.txt")
    t_est, T_est = read_tum(tmp_path / "est.txt")
    i_ref, i_est = M.associate(t_ref, t_est, 0.01)
    A, B = T_ref[i_ref], T_est[i_est]

    traj_ref = file_interface.read_tum_trajectory_file(str(tmp_path / "gt.txt"))
    traj_est = file_interface.read_tum_trajectory_file(str(tmp_path / "est.txt"))
    traj_ref, traj_est = sync.associate_trajectories(traj_ref, traj_est, max_diff=0.01)
    assert traj_ref.num_poses == len(A) == n // 2

    def evo_ape(align, align_origin=False):
        e = traj_est.__class__(poses_se3=traj_est.poses_se3, timestamps=traj_est.timestamps)  # evo aligns in place
        if align:
            e.align(traj_ref)
        if align_origin:
            e.align_origin(traj_ref)
        m = em.APE(em.PoseRelation.translation_part)
        m.process_data((traj_ref, e))
        return m.get_all_statistics()

    for ours, theirs in (
        (M.ate(A, B, "none"), evo_ape(False)),
        (M.ate(A, B, "se3"), evo_ape(True)),
        (M.ate(A, B, "origin"), evo_ape(False, True)),
    ):
        for k in ("rmse", "mean", "max", "median"):
            assert ours["trans_mm"][k] == pytest.approx(theirs[k] * 1000.0, rel=1e-6, abs=1e-6), (ours["alignment"], k)

    for relation, key, unit in (
        (em.PoseRelation.translation_part, "trans_mm", 1000.0),
        (em.PoseRelation.rotation_angle_deg, "rot_deg", 1.0),
    ):
        m = em.RPE(relation, delta=1, delta_unit=em.Unit.frames, all_pairs=False)
        m.process_data((traj_ref, traj_est))
        theirs = m.get_all_statistics()
        ours = M.rpe(A, B, delta_frames=1)[key]
        for k in ("rmse", "mean", "max"):
            assert ours[k] == pytest.approx(theirs[k] * unit, rel=1e-6, abs=1e-7), (key, k)

    # RPE per distance. evo_rpe --delta 0.01 --delta_unit m pairs consecutive segments from
    # pose 0 (each ends at the first pose >= 10 mm of path past the previous end); ours pairs
    # EVERY pose with the first pose >= 10 mm past it (overlapping). evo's pairs are a subset
    # of ours, on them our errors are evo's, and over all of ours the statistics differ by
    # the sampling alone (the difference README "Scoring" states).
    from evo.core import filters

    delta_mm = 10.0
    evo_pairs = filters.filter_pairs_by_path(traj_ref.poses_se3, delta_mm / 1000.0)
    ours_mm = M.rpe(A, B, delta_frames=None, delta_mm=delta_mm)
    row_of_start = {int(i): r for r, (i, _) in enumerate(ours_mm["pairs"])}
    assert len(evo_pairs) >= 5 and len(ours_mm["pairs"]) > 2 * len(evo_pairs)
    assert all(int(ours_mm["pairs"][row_of_start[i]][1]) == j for i, j in evo_pairs)
    rows = [row_of_start[i] for i, _ in evo_pairs]
    m = em.RPE(em.PoseRelation.translation_part, delta=delta_mm / 1000.0, delta_unit=em.Unit.meters, all_pairs=False)
    m.process_data((traj_ref, traj_est))
    theirs = m.get_all_statistics()
    on_evo_pairs = M.error_stats(ours_mm["trans_errors_mm"][rows])
    for k in ("rmse", "mean", "max"):
        assert on_evo_pairs[k] == pytest.approx(theirs[k] * 1000.0, rel=1e-6, abs=1e-7), k

    # And the evo_ape command line on the very same files, SE(3)-aligned.
    evo_ape_bin = Path(sys.executable).parent / "evo_ape"
    assert evo_ape_bin.exists(), f"{evo_ape_bin}: evo's command line is missing (install the [test] extra)"
    res = tmp_path / "ape.zip"
    out = subprocess.run(
        [
            str(evo_ape_bin),
            "tum",
            str(tmp_path / "gt.txt"),
            str(tmp_path / "est.txt"),
            "-a",
            "--save_results",
            str(res),
            "--no_warnings",
        ],
        capture_output=True,
        text=True,
        env={"HOME": str(tmp_path), "PATH": "/usr/bin:/bin", "MPLBACKEND": "Agg"},
    )
    assert out.returncode == 0, out.stderr
    from evo.tools import file_interface as fi

    stats = fi.load_res_file(str(res)).stats
    assert M.ate(A, B, "se3")["trans_mm"]["rmse"] == pytest.approx(stats["rmse"] * 1000.0, rel=1e-6)


def test_turn_error_is_the_yaw_scale_error_of_the_steps_hand_computed():
    """An S-curve's yaw steps, +0.02 rad for 20 frames then -0.02 rad for 20 (45.8 degrees of turn
    both ways counted, net none), measured 1 % too large: turn_error_pct = +1.0; measured exactly
    right but one step wrong by +0.005 rad: 100 * 0.2865 / 45.84 %. A straight run has no turn to
    scale: NaN, and a step measured from a restart frame (``T_ref_from``) counts its true turn."""
    yaw_steps = np.r_[np.full(20, 0.02), np.full(20, -0.02)]

    def traj(steps):
        yaw = np.r_[0.0, np.cumsum(steps)]
        return np.stack([T_world_cam_down(4.0 * i, 0.0, 100.0, yaw[i]) for i in range(len(yaw))])

    ref = traj(yaw_steps)
    t = M.turn_error(ref, traj(1.01 * yaw_steps))
    assert t["turn_deg"] == pytest.approx(np.degrees(0.8), rel=1e-9)
    assert t["turn_error_pct"] == pytest.approx(1.0, rel=1e-6)
    one_off = yaw_steps.copy()
    one_off[5] += 0.005
    t = M.turn_error(ref, traj(one_off))
    assert t["measured_turn_deg"] - t["turn_deg"] == pytest.approx(np.degrees(0.005), rel=1e-6)
    assert t["turn_error_pct"] == pytest.approx(100 * 0.005 / 0.8, rel=1e-6)
    assert np.isnan(M.turn_error(line_traj(), line_traj(yaw_rate=0.001))["turn_error_pct"])
    # Frame 1 lost: the run's poses at frames 0, 2, 3, its first step measured from frame 0 (0.04 rad),
    # its second from a restart on frame 1 (T_ref_from: the true step 1 -> 3, 0.04 rad, not 2 -> 3).
    est = traj(yaw_steps)[[0, 2, 3]]
    two = M.turn_error(ref[[0, 2, 3]], est, T_ref_from=ref[[0, 1]])
    assert two["turn_deg"] == pytest.approx(np.degrees(0.08), rel=1e-9)  # under MIN_TURN_DEG: no error
    assert two["measured_turn_deg"] == pytest.approx(np.degrees(0.06), rel=1e-9) and np.isnan(two["turn_error_pct"])


# ----------------------------------------------------------------------------- bad input
def _misuses(T):
    """Poses a user passes by mistake, each with the words its refusal must hold."""
    scaled, reflected, nan, inf = T.copy(), T.copy(), T.copy(), T.copy()
    scaled[2, :3, :3] *= 1.001  # a rotation that is not one
    reflected[2, :3, 0] *= -1.0  # a mirrored frame
    nan[2, 0, 3] = np.nan
    inf[2, 1, 3] = np.inf
    return [
        (np.swapaxes(T, 1, 2).copy(), "pose 0: bottom row"),  # row-major from another library: transposed
        (scaled, "pose 2: its 3x3 part is not a rotation"),
        (reflected, "pose 2: its 3x3 part is not a rotation"),
        (nan, "pose 2: holds a non-finite value"),
        (inf, "pose 2: holds a non-finite value"),
    ]


@pytest.mark.parametrize("k", range(5))
def test_every_metric_refuses_poses_that_are_not_rigid_naming_the_pose(k):
    """A transposed stack scored 0 mm everywhere, a scaled or mirrored rotation gave errors of a pose
    that does not exist, a NaN ended in 'SVD did not converge' (ate) or NaN statistics (rpe), and an
    infinite position an end drift of 0 %: each is refused in one line naming the pose and the rule."""
    A = line_traj(12)
    B = line_traj(12, scale=1.05)
    bad, words = _misuses(B)[k]
    calls = [
        lambda a, b: M.ate(a, b, "se3"),
        lambda a, b: M.align(a, b, "se2"),
        lambda a, b: M.rpe(a, b, delta_frames=1),
        lambda a, b: M.end_point_drift(a, b),
        lambda a, b: M.segment_errors(a, b),
        lambda a, b: M.translation_error_along_path(a, b),
    ]
    for call in calls:
        with pytest.raises(ValueError, match="T_est: " + words):
            call(A, bad)
        with pytest.raises(ValueError, match="T_ref: " + words):
            call(bad, A)
    t = np.arange(12) * 0.1
    with pytest.raises(ValueError, match="estimate: " + words):
        M.check_trajectory(t, bad, "estimate")


def test_step_metrics_take_a_nan_pose_as_unknown_but_refuse_other_bad_poses():
    """step_errors and turn_error leave out a step with no true pose (NaN, a frame without ground
    truth, as scoring passes them); an infinite or non-rigid pose is still refused."""
    A, B = line_traj(6), line_traj(6, scale=1.1)
    A_nan = A.copy()
    A_nan[3] = np.nan
    e = M.step_errors(A_nan, B)
    assert np.isnan(e["trans_mm"][[2, 3]]).all()
    np.testing.assert_allclose(e["trans_mm"][[0, 1, 4]], 0.4, atol=1e-9)  # 4 mm steps measured as 4.4 mm
    assert M.turn_error(A_nan, B)["turn_deg"] == 0.0
    for bad, words in _misuses(B)[:3] + _misuses(B)[4:]:
        with pytest.raises(ValueError, match="T_est: " + words):
            M.step_errors(A, bad)
        with pytest.raises(ValueError, match="T_est: " + words):
            M.turn_error(A, bad)
    with pytest.raises(ValueError, match=r"turn_error: T_ref_from has shape \(6, 4, 4\), expected \(5, 4, 4\)"):
        M.turn_error(A, B, T_ref_from=A)  # was a broadcasting error from inside numpy


@pytest.mark.parametrize(
    "t, words",
    [
        ([0.0, 0.1, np.nan, 0.3], r"pose 2: timestamp is not a finite number"),
        ([0.0, 0.2, 0.1, 0.3], r"pose 2: timestamp 0.100000000 s follows 0.200000000 s: .* must increase"),
        ([0.0, 0.1, 0.1, 0.3], r"pose 2: timestamp 0.100000000 s follows 0.100000000 s"),
        ([0.0, 0.1, 0.2, 3e18], r"pose 3: timestamp = 3e\+18 s is beyond"),
    ],
)
def test_a_trajectory_whose_times_are_not_finite_and_increasing_is_refused(t, words):
    """The rule of a TUM file's times (floorvo.tum.times_problem) holds for arrays too: an estimate
    with a repeated time was scored against the wrong poses (ATE 4.7 mm instead of 1.1 mm), one out
    of order had its path walked backwards, and a NaN time dropped its pose silently."""
    from floorvo.scoring import score_trajectories

    T = line_traj(4)
    with pytest.raises(ValueError, match="estimate: " + words):
        M.check_trajectory(np.array(t), T, "estimate")
    with pytest.raises(ValueError, match="estimate: " + words):
        score_trajectories(np.arange(4) * 0.1, T, np.array(t), T)


def test_metric_parameters_out_of_range_are_refused_not_replaced():
    """rpe took delta_frames=0 as 1 and 2.7 as 2, and delta_mm=NaN as no pair (all statistics NaN);
    a negative segment length gave negative errors; path_distances_mm and associate raised
    IndexError from inside on arrays of another shape, and associate left a NaN time unpaired."""
    A, B = line_traj(10), line_traj(10, scale=1.1)
    for kwargs in ({"delta_frames": 0}, {"delta_frames": 2.7}, {"delta_mm": float("nan")}, {"delta_mm": -1.0}):
        with pytest.raises(ValueError, match="rpe delta"):
            M.rpe(A, B, **kwargs)
    assert M.rpe(A, B, delta_frames=None)["delta"] == 1
    np.testing.assert_allclose(M.rpe(A, B, delta_frames=2)["trans_errors_mm"], 0.8, atol=1e-9)
    for L in (-10.0, 0.0, float("nan")):
        with pytest.raises(ValueError, match="segment length"):
            M.segment_errors(A, B, [L])
    for shape_bad in (A[0], A[:, :3, :3], A[:, :3, 3]):
        with pytest.raises(ValueError, match=r"path_distances_mm: need \(N, 4, 4\) poses"):
            M.path_distances_mm(shape_bad)
    with pytest.raises(ValueError, match="associate: t_ref_s must be an"):
        M.associate(np.array([0.0, np.nan, 0.2]), np.array([0.0, 0.1, 0.2]))
    with pytest.raises(ValueError, match="associate: t_est_s"):
        M.associate(np.array([0.0, 0.1]), np.zeros((2, 2)))

"""A rolling shutter's readout, undone in the steps (floorvo.geometry.rolling_shutter_undone).

Independent truth: points moved at a known image velocity and seen row by row (solved in
closed form), and frames whose every row is drawn from the pose at that row's time
(``_synth.rolling_frames_along``), scored against the poses at the frame times.
"""

from __future__ import annotations

import numpy as np
import pytest
from _synth import write_rolling_sequence

from floorvo.camera import CameraModel
from floorvo.geometry import T_world_cam_down, invert_T, rolling_shutter_undone, yaw_of_R
from floorvo.run import build_estimator
from floorvo.runner import run_sequence
from floorvo.sequence import Sequence

CAM = CameraModel.from_sensor(648, 494, pixel_pitch_um=7.4, focal_length_mm=6.0)  # GSD 0.1233 mm at 100 mm
READOUT_MS = 15.0
ROW_TIME_S = READOUT_MS / 1000.0 / (CAM.height_px - 1)
FPS = 30.0


def _seen_by_rows(q0: np.ndarray, v_px_s: np.ndarray, t_s: float, row_time_s: float, mid: float) -> np.ndarray:
    """Where a rolling shutter at frame time ``t_s`` sees points at ``q0 + v t`` (px): the row ``y``
    it sees a point on is exposed at ``t_s + (y - mid) row_time_s``, so
    ``y = q0_y + v_y (t_s + (y - mid) row_time_s)``, solved for ``y``."""
    y = (q0[:, 1] + v_px_s[1] * (t_s - mid * row_time_s)) / (1.0 - v_px_s[1] * row_time_s)
    t_row = t_s + (y - mid) * row_time_s
    return np.column_stack([q0[:, 0] + v_px_s[0] * t_row, y])


def test_rolling_shutter_undone_is_exact_for_a_translation():
    rng = np.random.default_rng(3)
    q0 = rng.uniform([0, 0], [648, 494], (50, 2))
    v = np.array([400.0, 975.0])  # px/s: 32.5 px a frame along the rows at 30 frames/s
    mid = 246.5
    src = _seen_by_rows(q0, v, 0.0, ROW_TIME_S, mid)
    dst = _seen_by_rows(q0, v, 1 / FPS, ROW_TIME_S, mid)
    # as seen, every pair moved by (1 + dy row_time / interval) of the step: 2.9 % long
    assert np.allclose((dst - src) / (v / FPS), 1.0 + (dst - src)[:, 1:] * ROW_TIME_S * FPS)
    assert np.mean(np.linalg.norm(dst - src, axis=1)) / np.linalg.norm(v / FPS) > 1.025
    a, b = rolling_shutter_undone(src, dst, interval_s=1 / FPS, row_time_s=ROW_TIME_S, mid_row_px=mid)
    np.testing.assert_allclose(a, q0, atol=1e-9)  # where global shutters at the frame times see them
    np.testing.assert_allclose(b, q0 + v / FPS, atol=1e-9)
    # a global shutter: the pairs as they are
    a, b = rolling_shutter_undone(src, dst, interval_s=1 / FPS, row_time_s=0.0, mid_row_px=mid)
    assert a is not None and np.array_equal(a, src) and np.array_equal(b, dst)


def _turning(p0: np.ndarray, centre: np.ndarray, rate_rad_s: float):
    """The picture of a floor under a camera at a constant planar twist (an arc): every point turns
    about one fixed point of the image at a constant rate. (N, 2) px at time t."""

    def at(t: float) -> np.ndarray:
        c, s = np.cos(rate_rad_s * t), np.sin(rate_rad_s * t)
        return (p0 - centre) @ np.array([[c, -s], [s, c]]).T + centre

    return at


def _seen_row_by_row(at, n: int, t_frame: float, mid: float) -> np.ndarray:
    """Where a rolling shutter at ``t_frame`` sees the ``n`` points ``at(t)``: each on the row ``y`` with
    ``y = at(t_frame + (y - mid) row_time)_y`` (a fixed point, iterated)."""
    y = at(t_frame)[:, 1]
    for _ in range(60):
        p = np.array([at(t_frame + (y[i] - mid) * ROW_TIME_S)[i] for i in range(n)])
        y = p[:, 1]
    return p


@pytest.mark.parametrize("rate_deg_frame", [3.0, -1.0, 1e-7])
def test_rolling_shutter_undone_on_an_arc(rate_deg_frame):
    """An arc whose floor moves about 32 px a frame along the rows: the pairs as global shutters see them."""
    rng = np.random.default_rng(4)
    p0 = rng.uniform([0, 0], [648, 494], (60, 2))
    rate = np.radians(rate_deg_frame) * FPS
    centre = np.array([324.0 + 32.5 / np.radians(rate_deg_frame), 247.0])  # 32.5 px a frame at the centre
    at = _turning(p0, centre, rate)
    src, dst = _seen_row_by_row(at, len(p0), 0.0, 246.5), _seen_row_by_row(at, len(p0), 1 / FPS, 246.5)
    err_seen = np.abs(dst - src - (at(1 / FPS) - at(0.0))).max()
    a, b = rolling_shutter_undone(src, dst, interval_s=1 / FPS, row_time_s=ROW_TIME_S, mid_row_px=246.5)
    assert err_seen > 0.8  # px
    np.testing.assert_allclose(a, at(0.0), atol=2e-3)
    np.testing.assert_allclose(b, at(1 / FPS), atol=2e-3)


def _rolling_sequence(tmp_path, direction_rad: float, yaw_rate_deg_frame: float = 0.0, n: int = 6, depth: bool = False):
    """A rolling-shutter sequence at 4 mm a frame along ``direction_rad`` from the camera's x axis
    (its rows run along its y axis, world -y at yaw 0), turning by ``yaw_rate_deg_frame`` a frame
    at a constant twist (an arc: the direction turns with the camera); its ground truth is the
    poses at the frame times. ``depth``: with the flat floor's depth image per frame (a global
    shutter's: level poses see the floor at one depth)."""
    speed = 4.0 * FPS
    w = np.radians(yaw_rate_deg_frame) * FPS
    v_world0 = speed * np.array([np.cos(direction_rad), -np.sin(direction_rad)])  # the camera's (x, y) in the world

    def pose_at(t):
        if w == 0.0:
            xy = v_world0 * t
        else:  # the integral of the velocity turned by w t
            c, s = np.cos(w * t), np.sin(w * t)
            xy = np.array([[s, c - 1.0], [1.0 - c, s]]) @ v_world0 / w
        return T_world_cam_down(xy[0], xy[1], 100.0, w * t)

    root = tmp_path / f"rs_{direction_rad:.2f}_{yaw_rate_deg_frame:.2f}"
    return write_rolling_sequence(root, CAM, pose_at, np.arange(n) / FPS, READOUT_MS, seed=5, depth=depth)


def _end_error(seq: Sequence, truth: np.ndarray, name: str, undo: bool) -> tuple[float, float, int]:
    """(the end's translation error over the distance travelled, its yaw error in degrees, steps ok)."""
    est, _ = build_estimator(seq, name, {"undo_rolling_shutter": str(undo).lower()})
    run = run_sequence(seq, est, summary_warnings=False)
    d = invert_T(truth[-1]) @ run.T_world_cam[-1]
    travelled = float(np.linalg.norm(truth[-1][:3, 3] - truth[0][:3, 3]))
    return (
        float(np.linalg.norm(d[:2, 3])) / travelled,
        float(np.degrees(abs(yaw_of_R(d[:3, :3])))),
        int(np.sum(run.status == "ok")),
    )


def test_a_sequence_states_its_row_time(tmp_path):
    seq, _ = _rolling_sequence(tmp_path, 0.0, n=2)
    assert seq.row_time_s == pytest.approx(0.015 / 493)


@pytest.mark.parametrize(
    "name", ["phase-corr", "phase-corr-fast", "akaze-guided", "akaze-bruteforce-fast", "homography-6dof"]
)
def test_a_step_along_the_rows_is_not_read_long(tmp_path, name):
    """4 mm a frame at 0.7 rad from the camera's x axis (20 px a frame along the rows): a 15 ms
    readout makes every step 1.9 % long, in both components, unless the estimator undoes it."""
    seq, truth = _rolling_sequence(tmp_path, 0.7)
    off, _, ok_off = _end_error(seq, truth, name, undo=False)
    on, _, ok_on = _end_error(seq, truth, name, undo=True)
    assert ok_on == ok_off == 5
    assert off > 0.015
    assert on < 0.003


@pytest.mark.parametrize("name", ["phase-corr", "akaze-guided"])
def test_a_turn_under_a_rolling_shutter(tmp_path, name):
    """Along the rows while turning 3 degrees a frame: the step's length and turn as a global
    shutter's."""
    seq, truth = _rolling_sequence(tmp_path, np.pi / 2, yaw_rate_deg_frame=3.0)
    off, _, _ = _end_error(seq, truth, name, undo=False)
    on, yaw_on, ok_on = _end_error(seq, truth, name, undo=True)
    assert ok_on == 5
    assert off > 0.02
    assert on < 0.004 and yaw_on < 0.05


@pytest.mark.parametrize("name", ["akaze-guided-fast", "phase-corr"])
def test_an_arc_along_the_rows_own_direction(tmp_path, name):
    """An arc along the camera's x axis (3 degrees a frame): the readout turns each row a little
    more than the last, which the frames' own pixels read as a turn 0.02 degrees off a step and
    (akaze-guided-fast, which follows the height from the image scale) as the camera rising 0.1 mm
    a frame. Undone: the heights and the turn as a global shutter's."""
    seq, truth = _rolling_sequence(tmp_path, 0.0, yaw_rate_deg_frame=3.0, n=8)
    _, yaw_off, _ = _end_error(seq, truth, name, undo=False)
    on, yaw_on, ok_on = _end_error(seq, truth, name, undo=True)
    assert ok_on == 7
    assert yaw_off > 0.01 and yaw_on < 0.005
    assert on < 0.0005
    heights = {}
    for undo in (False, True):
        est, _ = build_estimator(seq, name, {"undo_rolling_shutter": str(undo).lower()})
        run = run_sequence(seq, est, summary_warnings=False)
        heights[undo] = float(np.abs(run.T_world_cam[:, 2, 3] - truth[:, 2, 3]).max())
    assert heights[True] < 0.01
    if name == "akaze-guided-fast":
        assert heights[False] > 0.3


def _corner_sequence(tmp_path, n: int = 7):
    """A rolling-shutter run along the camera's x axis at 4 mm a frame that starts turning 7.6
    degrees a frame (a 30 mm radius) at frame 3's time: that frame's first rows see the straight
    run, its last rows the turn."""
    speed, t0 = 4.0 * FPS, 3 / FPS
    w = np.radians(7.64) * FPS

    def pose_at(t):
        if t <= t0:
            return T_world_cam_down(speed * t, 0.0, 100.0, 0.0)
        u = t - t0
        r = speed / w
        return T_world_cam_down(speed * t0 + r * np.sin(w * u), r * (1.0 - np.cos(w * u)), 100.0, w * u)

    return write_rolling_sequence(tmp_path / "corner", CAM, pose_at, np.arange(n) / FPS, READOUT_MS, seed=6)


@pytest.mark.parametrize("name", ["phase-corr", "phase-corr-fast"])
def test_a_turn_that_starts_during_the_readout_is_lost(tmp_path, name):
    """The frame whose rows straddle the turn's start is no motion at one velocity: undone at one,
    its step is more than 0.3 degrees off; it is lost, said, and every step reported ok is right."""
    seq, truth = _corner_sequence(tmp_path)
    errs = {}
    for check in (False, True):
        est, _ = build_estimator(seq, name, {"check_readout_motion": str(check).lower()})
        run = run_sequence(seq, est, summary_warnings=False)
        worst = 0.0
        for i in range(1, len(truth)):
            if run.status[i] != "ok":
                continue
            j = max(k for k in range(i) if run.status[k] in ("ok", "init") or "restarts" in str(run.reason[k]))
            d_true = invert_T(truth[j]) @ truth[i]
            d_run = invert_T(run.T_world_cam[j]) @ run.T_world_cam[i]
            worst = max(worst, abs(float(np.degrees(yaw_of_R(d_run[:3, :3]) - yaw_of_R(d_true[:3, :3])))))
        errs[check] = (worst, [str(r) for r in run.reason])
    assert errs[False][0] > 0.3  # reported ok, wrong
    assert errs[True][0] < 0.3
    assert any("motion changed during the readout" in r for r in errs[True][1])


def test_akaze_loses_pairs_whose_rows_move_apart(tmp_path):
    """The AKAZE check on pairs made by hand: the rows read first move straight on, those read last
    also turn 0.6 degrees about the principal point (a turn that began during the readout): lost,
    said; the same pairs moved as one motion: kept."""
    from dataclasses import replace

    from floorvo.estimators.akaze import _Fit

    seq, _ = _rolling_sequence(tmp_path, 0.0, n=2)
    est, _ = build_estimator(seq, "akaze-guided")
    rng = np.random.default_rng(7)
    src = rng.uniform([20, 20], [628, 474], (400, 2))
    c = np.array([CAM.cx_px, CAM.cy_px])
    a = np.radians(0.6)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    straight = src + [32.5, 0.0]
    turned = (src - c) @ R.T + c + [32.5, 0.0]
    late = src[:, 1] >= np.median(src[:, 1])
    M = np.eye(3)
    M[0, 2] = 32.5
    for dst, lost in ((np.where(late[:, None], turned, straight), True), (straight, False)):
        fit = _Fit(M, src, dst, len(src), src_gs=src, dst_gs=dst)
        why = est._readout_problem(fit)
        assert ("motion changed during the readout" in why) is lost, why
        assert est._readout_problem(replace(fit, src_gs=None, dst_gs=None)) == ""  # a global shutter: no check


@pytest.mark.parametrize("name", ["phase-corr", "akaze-guided-fast"])
def test_a_height_change_under_a_rolling_shutter_is_one_motion(tmp_path, name):
    """A half-size camera sinking 1 mm a frame while it moves along the rows (a bounce's steepest
    part): the picture grows 1 % a frame, which moves the upper and the lower blocks apart; at the
    step's image scale that is one motion, not a change during the readout, and every step is ok."""
    cam = CameraModel.from_sensor(324, 247, pixel_pitch_um=14.8, focal_length_mm=6.0)
    speed, sink = 4.0 * FPS, 1.0 * FPS

    def pose_at(t):
        return T_world_cam_down(0.0, -speed * t, 100.0 - sink * t)

    seq, _ = write_rolling_sequence(tmp_path / "sink", cam, pose_at, np.arange(6) / FPS, READOUT_MS, seed=8)
    est, _ = build_estimator(seq, name)
    run = run_sequence(seq, est, summary_warnings=False)
    assert not any("motion changed during the readout" in str(r) for r in run.reason), list(run.reason)
    assert int(np.sum(run.status == "ok")) == 5


@pytest.mark.parametrize("update", ["plane", "icp"])
def test_orb_icp_undoes_a_readout(tmp_path, update):
    """orb-icp on a rolling-shutter RGB-D run at 0.7 rad from the camera's x axis: its keypoints (and
    their 3-D points) undone, the end within 0.3 % of the distance; left in, 1.5 % or more off."""
    seq, truth = _rolling_sequence(tmp_path, 0.7, depth=True)
    errs = {}
    for undo in (False, True):
        est, _ = build_estimator(seq, "orb-icp", {"undo_rolling_shutter": str(undo).lower(), "update": update})
        run = run_sequence(seq, est, summary_warnings=False)
        assert int(np.sum(run.status == "ok")) == 5
        d = invert_T(truth[-1]) @ run.T_world_cam[-1]
        errs[undo] = float(np.linalg.norm(d[:2, 3])) / float(np.linalg.norm(truth[-1][:3, 3] - truth[0][:3, 3]))
    assert errs[False] > 0.015 and errs[True] < 0.003, errs


@pytest.mark.parametrize("update", ["plane", "planar"])
def test_stereo_sift_undoes_a_readout(tmp_path, update):
    """stereo-sift on a rolling-shutter stereo run (20 mm baseline, both cameras read out together)
    at 0.7 rad from the camera's x axis: undone, the end within 0.3 % of the distance; left in,
    1.5 % or more off."""
    speed, d = 4.0 * FPS, 0.7

    def pose_at(t):
        return T_world_cam_down(speed * t * np.cos(d), -speed * t * np.sin(d), 100.0)

    T01 = np.eye(4)
    T01[0, 3] = 20.0
    seq, truth = write_rolling_sequence(
        tmp_path / "stereo", CAM, pose_at, np.arange(6) / FPS, READOUT_MS, seed=9, T_cam0_cam1=T01
    )
    errs = {}
    for undo in (False, True):
        est, _ = build_estimator(seq, "stereo-sift", {"undo_rolling_shutter": str(undo).lower(), "update": update})
        run = run_sequence(seq, est, summary_warnings=False)
        assert int(np.sum(run.status == "ok")) == 5, list(run.reason)
        e = invert_T(truth[-1]) @ run.T_world_cam[-1]
        errs[undo] = float(np.linalg.norm(e[:2, 3])) / float(np.linalg.norm(truth[-1][:3, 3] - truth[0][:3, 3]))
    assert errs[False] > 0.015 and errs[True] < 0.003, errs


@pytest.mark.parametrize("name", ["akaze-guided", "phase-corr"])
def test_a_turn_rate_that_changes_is_undone(tmp_path, name):
    """Along the camera's x axis with the yaw swinging 0.5 rad at 0.75 Hz (an S-curve's turn: the
    rate changes 0.03 degrees a frame per frame at the swing's end). With one turn rate for both
    frames the two frames' rows turn by different amounts, and the steps read up to 0.5 % short;
    with the rate's change taken from the step before, as a global shutter's (from the second step
    on: the first has none before it)."""
    speed, swing, w = 4.0 * FPS, 0.5, 2 * np.pi * 0.75
    t_fine = np.linspace(-0.5, 1.0, 15001)
    yaw_fine = swing * np.sin(w * t_fine)
    step = t_fine[1] - t_fine[0]
    x_fine = np.cumsum(speed * np.cos(yaw_fine)) * step
    y_fine = np.cumsum(speed * np.sin(yaw_fine)) * step
    i0 = int(np.searchsorted(t_fine, 0.0))
    x_fine, y_fine = x_fine - x_fine[i0], y_fine - y_fine[i0]

    def pose_at(t):  # from 0.2 s on: around the swing's end (1/3 s), where the rate changes fastest
        t = t + 0.2
        return T_world_cam_down(
            float(np.interp(t, t_fine, x_fine)), float(np.interp(t, t_fine, y_fine)), 100.0, swing * np.sin(w * t)
        )

    times = np.arange(9) / FPS
    worst = {}
    for readout_ms, undo in ((READOUT_MS, False), (READOUT_MS, True)):
        seq, truth = write_rolling_sequence(tmp_path / f"s{undo}", CAM, pose_at, times, readout_ms, seed=3)
        est, _ = build_estimator(seq, name, {"undo_rolling_shutter": str(undo).lower()})
        run = run_sequence(seq, est, summary_warnings=False)
        assert int(np.sum(run.status == "ok")) == len(times) - 1
        errs = [
            np.linalg.norm((invert_T(run.T_world_cam[i - 1]) @ run.T_world_cam[i])[:2, 3])
            / np.linalg.norm((invert_T(truth[i - 1]) @ truth[i])[:2, 3])
            - 1.0
            for i in range(1, len(times))
        ]
        worst[undo] = float(np.max(np.abs(errs[1:])))  # the first step has no step before it
    assert worst[False] > 0.003 and worst[True] < 0.001, worst

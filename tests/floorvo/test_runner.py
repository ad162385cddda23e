"""The frame loop (:mod:`floorvo.runner`) and the run folder on disk (:mod:`floorvo.runfolder`).

The loop is checked against poses chained by hand from scripted steps, and on a
code-made sequence against its ground truth; the run folder by writing and reading it
back, and by damaging each of its files.
"""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from tests.floorvo._synth import Scripted

from floorvo.calibration import ScaleCalibration
from floorvo.camera import CameraModel
from floorvo.errors import ConfigError, FloorbenchError, SequenceError
from floorvo.estimators.base import Frame, StepResult
from floorvo.geometry import T_world_cam_down, make_T, rot_z
from floorvo.runfolder import RunFolder, read_match_samples, write_match_sample
from floorvo.runner import camera_height_mm, run_frames, run_sequence
from floorvo.sequence import Sequence
from floorvo.synthetic import line_poses, write_synthetic_sequence
from floorvo.tum import write_tum

CAM = CameraModel.from_sensor(162, 124, pixel_pitch_um=29.6, focal_length_mm=6.0)  # GSD 0.4933 mm at 100 mm


def _frames(n):
    return [Frame(i, i / 10.0, np.zeros((4, 4), np.uint8)) for i in range(n)]


START = T_world_cam_down(10.0, 5.0, 100.0, 0.3)
STEP = make_T(rot_z(0.1), [2.04, 1.0, 0.0])  # camera-frame motion, mm
FIX = T_world_cam_down(50.0, -3.0, 100.0, -0.2)


def _script():
    tm = {"detect": 1.0, "match": 2.25, "estimate": 0.5, "total": 3.75}
    return [
        StepResult("init", timing_ms=tm, n_keypoints=40),
        StepResult("ok", STEP, timing_ms=tm, n_keypoints=41, n_matches=30, n_inliers=25),
        StepResult("lost", reason="too few matches (3)", timing_ms={"total": 2.0}),
        StepResult("ok", STEP, timing_ms=tm),
        StepResult("ok", STEP, reason="map fix", T_world_cam=FIX, timing_ms=tm),
        StepResult("ok", STEP, timing_ms=tm),
    ]


# ----------------------------------------------------------------------------- the loop
def test_a_picture_repeating_the_last_frames_bit_for_bit_is_lost_and_not_measured():
    """A buffer delivered twice: every estimator measured no motion at the repeat (3 mm off) and
    both frames' motion at the next. The runner does not hand the repeat to the estimator; its
    next step is measured from the frame before (the script's second step is the next frame's).
    A blank picture repeated is the estimator's to refuse (all-zero pictures pass through)."""
    from floorvo.runner import REPEATED_FRAME

    rng = np.random.default_rng(0)
    pics = [rng.integers(0, 255, (6, 8), dtype=np.uint8) for _ in range(4)]
    pics[2] = pics[1].copy()
    frames = [Frame(i, i / 10.0, p) for i, p in enumerate(pics)]
    script = [StepResult("init"), StepResult("ok", STEP), StepResult("ok", STEP @ STEP)]
    res = run_frames(Scripted(script), frames, T_world_start=START)
    assert res.status.tolist() == ["init", "ok", "lost", "ok"]
    assert res.reason[2] == REPEATED_FRAME
    np.testing.assert_allclose(res.T_world_cam[3], START @ STEP @ STEP @ STEP, atol=1e-12)
    blank = [Frame(i, i / 10.0, np.zeros((6, 8), np.uint8)) for i in range(3)]
    res = run_frames(
        Scripted([StepResult("init"), StepResult("lost", reason="empty frame")] * 2), blank, T_world_start=START
    )
    assert res.reason[1] == "empty frame"


def test_run_frames_chains_steps_places_fixes_and_holds_the_pose_when_lost():
    calls = []
    res = run_frames(
        Scripted(_script()),
        _frames(6),
        T_world_start=START,
        on_step=lambda k, f, r: calls.append((k, f.index, r.status)),
    )
    # by hand: T_world_cur = T_world_prev @ T_prev_cur; a lost frame keeps the pose; a fix replaces it
    expected = [START, START @ STEP, START @ STEP, START @ STEP @ STEP, FIX, FIX @ STEP]
    np.testing.assert_allclose(res.T_world_cam, np.stack(expected), atol=1e-12)
    assert res.placed.tolist() == [True, True, False, True, True, True]
    assert res.fixed.tolist() == [False, False, False, False, True, False] and res.fixes == 1
    assert res.status_counts == {"init": 1, "ok": 4, "lost": 1} and (res.ok, res.lost, res.frames) == (4, 1, 6)
    assert res.lost_frames == [{"frame": 2, "reason": "too few matches (3)"}]
    ts, T = res.trajectory()
    np.testing.assert_allclose(ts, [0.0, 0.1, 0.3, 0.4, 0.5])
    np.testing.assert_allclose(T, np.stack(expected)[[0, 1, 3, 4, 5]], atol=1e-12)
    assert calls == [(k, k, s) for k, s in enumerate(["init", "ok", "lost", "ok", "ok", "ok"])]
    # a stage the estimator did not time is NaN in memory and 0 in timing.csv
    assert np.isnan(res.timing_ms[2, 1]) and res.timing_columns()["match_ms"][2] == 0.0
    assert res.counts[1].tolist() == [41, 30, 25]
    assert res.median_total_ms == 3.75


def test_scale_calibration_divides_the_steps_but_not_a_fix():
    cal = ScaleCalibration(scale_x=1.02, scale_y=1.0)
    res = run_frames(Scripted(_script()), _frames(6), T_world_start=START, scale_calibration=cal)
    true_step = make_T(rot_z(0.1), [2.0, 1.0, 0.0])  # 2.04 / 1.02
    np.testing.assert_allclose(res.T_world_cam[1], START @ true_step, atol=1e-12)
    np.testing.assert_allclose(res.T_world_cam[4], FIX, atol=1e-12)
    np.testing.assert_allclose(res.T_world_cam[5], FIX @ true_step, atol=1e-12)


@pytest.mark.parametrize(
    "bad, message",
    [
        (StepResult("ok"), "status 'ok' without T_prev_cur"),
        (StepResult("reset"), "status 'reset'"),
        (None, r"step returned a NoneType, not a StepResult"),
        # a motion that is not rigid was chained as it was: a scaled step ran with exit code 0,
        # a NaN ended in an SVD error and a 3x3 in a matmul error from deep inside
        (StepResult("ok", np.eye(3)), r"T_prev_cur is not a rigid transform \(shape \(3, 3\), not \(4, 4\)\)"),
        (StepResult("ok", np.diag([2.0, 1.0, 1.0, 1.0])), r"T_prev_cur is not a rigid transform \(its 3x3 part"),
        (StepResult("ok", np.diag([-1.0, 1.0, 1.0, 1.0])), r"T_prev_cur is not a rigid transform \(its 3x3 part"),
        (StepResult("ok", make_T(np.eye(3), [np.nan, 0.0, 0.0])), r"T_prev_cur .*non-finite"),
        (
            StepResult("ok", np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [1, 0, 0, 1.0]])),
            r"T_prev_cur is not a rigid transform \(bottom row",
        ),
        (StepResult("ok", "eye"), r"T_prev_cur is not a rigid transform \(a str"),
        (StepResult("init", T_world_cam=np.eye(4)[:3]), r"T_world_cam is not a rigid transform \(shape \(3, 4\)"),
    ],
)
def test_an_estimator_breaking_the_protocol_is_a_bug_not_a_user_error(bad, message):
    with pytest.raises(ValueError, match=f"scripted: frame 1: {message}") as exc:
        run_frames(Scripted([StepResult("init"), bad]), _frames(2), T_world_start=np.eye(4))
    assert not isinstance(exc.value, FloorbenchError)


def test_run_sequence_reads_frames_and_starts_at_the_ground_truth(tmp_path):
    from floorvo.run import build_estimator

    T = line_poses(24.0, 4.0, 100.0)
    seq = Sequence.open(write_synthetic_sequence(tmp_path / "s", CAM, T))
    est, _ = build_estimator(seq, "phase-corr")
    res = run_sequence(seq, est, frames=[2, 3, 4, 5])
    assert res.frame_index.tolist() == [2, 3, 4, 5] and res.estimator == "phase-corr"
    ts_gt, T_gt = seq.groundtruth()
    np.testing.assert_array_equal(res.timestamp_s, seq.timestamps_s[2:6])  # the sequence's frame times
    np.testing.assert_allclose(res.timestamp_s, ts_gt[2:6], atol=1e-6)
    np.testing.assert_allclose(res.T_world_cam[0], T_gt[2], atol=1e-9)
    assert np.linalg.norm(res.T_world_cam[-1][:3, 3] - T_gt[5][:3, 3]) < 0.05  # 12 mm travelled
    # the identity start of a localisation run
    res = run_sequence(seq, est, frames=[0, 1], T_world_start=np.eye(4))
    np.testing.assert_allclose(res.T_world_cam[0], np.eye(4))
    with pytest.raises(FloorbenchError, match="phase-corr: no frames to run on"):
        run_sequence(seq, est, frames=[])


@pytest.mark.parametrize("name", ["phase-corr", "akaze-guided"])
def test_a_run_whose_first_frames_are_lost_starts_at_the_first_tracked_frames_pose(tmp_path, name):
    """A real recording's first frames can be black (the exposure settling): the estimator
    loses them and starts on a later frame. The run placed that frame at the first frame's
    ground-truth pose, so every pose was off by the motion over the lost frames (8 mm here:
    the end 'drifted' 40 % of a 20 mm run whose steps were all right). It starts at the
    ground-truth pose of the frame the estimator starts on: every placed pose within
    0.05 mm of the truth."""
    from floorvo.run import build_estimator

    T = line_poses(28.0, 4.0, 100.0)
    seq_dir = write_synthetic_sequence(tmp_path / "s", CAM, T)
    for i in (0, 1):  # two black frames
        cv2.imwrite(str(seq_dir / "cam0" / f"{i:06d}.png"), np.zeros((CAM.height_px, CAM.width_px), np.uint8))
    seq = Sequence.open(seq_dir)
    est, _ = build_estimator(seq, name)
    res = run_sequence(seq, est)
    assert res.status.tolist() == ["lost", "lost", "init"] + ["ok"] * 5, res.reason.tolist()
    placed = res.placed
    err = np.linalg.norm(res.T_world_cam[placed][:, :3, 3] - T[placed][:, :3, 3], axis=1)
    assert err.max() < 0.05, err
    # A start the caller gives is kept: the first frame the estimator starts on is placed there.
    res = run_sequence(seq, est, T_world_start=np.eye(4))
    np.testing.assert_allclose(res.T_world_cam[2], np.eye(4))


def test_a_sequence_without_camera_height_is_refused(tmp_path):
    root = write_synthetic_sequence(tmp_path / "s", CAM, line_poses(8.0, 4.0, 100.0))
    meta = json.loads((root / "sequence.json").read_text())
    meta["rig"].pop("height_mm")
    (root / "sequence.json").write_text(json.dumps(meta))
    with pytest.raises(SequenceError, match="rig.height_mm is missing") as exc:
        camera_height_mm(Sequence.open(root))
    assert "\n" not in str(exc.value)


# ----------------------------------------------------------------------------- the run folder
def _written(tmp_path):
    res = run_frames(Scripted(_script()), _frames(6), T_world_start=START)
    result = {**res.summary(), "config": {"grid": 3}}
    res.run_folder(header="floorvo scripted: T_world_cam, metres", result=result, reasons=True).write(tmp_path / "run")
    return res, result, tmp_path / "run"


def test_run_folder_round_trip(tmp_path):
    res, result, run = _written(tmp_path)
    back = RunFolder.read(run)
    ts, T = res.trajectory()
    np.testing.assert_allclose(back.timestamps_s, ts, atol=1e-6)
    np.testing.assert_allclose(back.T_world_cam, T, atol=1e-5)  # TUM: micrometres, 12-digit quaternions
    assert back.statuses == ["init", "ok", "lost", "ok", "ok", "ok"]
    assert back.timing["frame"].tolist() == list(range(6))
    np.testing.assert_allclose(back.timing["match_ms"], [2.25, 2.25, 0.0, 2.25, 2.25, 2.25])
    np.testing.assert_allclose(back.timing["total_ms"], [3.75, 3.75, 2.0, 3.75, 3.75, 3.75])
    assert back.timing["n_inliers"].tolist() == [0, 25, 0, 0, 0, 0]
    assert list(back.timing["reason"]) == ["", "", "too few matches (3)", "", "map fix", ""]
    assert back.result == json.loads(json.dumps(result))
    assert back.result["map_fixes"] == 1 and back.result["lost_frames"] == [
        {"frame": 2, "reason": "too few matches (3)"}
    ]
    # the format other tools read
    assert (run / "trajectory.txt").read_text().splitlines()[0] == "# floorvo scripted: T_world_cam, metres"
    assert (run / "timing.csv").read_text().splitlines()[:2] == [
        "frame,detect_ms,match_ms,estimate_ms,total_ms,status,n_keypoints,n_matches,n_inliers,reason",
        "0,1.000,2.250,0.500,3.750,init,40,0,0,",
    ]


def test_a_run_that_placed_nothing_reads_back_empty(tmp_path):
    res = run_frames(Scripted([StepResult("lost", reason="dark")]), _frames(1), T_world_start=np.eye(4))
    res.run_folder(header="floorvo scripted: no frame tracked", result=res.summary()).write(tmp_path / "run")
    assert (tmp_path / "run" / "trajectory.txt").read_text() == "# floorvo scripted: no frame tracked\n"
    back = RunFolder.read(tmp_path / "run")
    assert back.T_world_cam.shape == (0, 4, 4) and back.statuses == ["lost"] and "reason" not in back.timing


@pytest.mark.parametrize(
    "name, damage, message",
    [
        ("timing.csv", lambda t: t.replace(",lost,", ",maybe,"), "status 'maybe' is not one of init, ok, lost"),
        ("timing.csv", lambda t: t.replace("0,1.000,", "0,fast,", 1), "column 'detect_ms' holds a value that is not a"),
        (
            "timing.csv",
            lambda t: t.replace(",init,40,0,0,", ",init,40,0,0,,7"),
            "another number of cells than the header",
        ),
        ("timing.csv", lambda t: t.replace("\n1,", "\n1.5,", 1), "column 'frame' must hold frame indices"),
        ("result.json", lambda t: t[:20], "not valid JSON"),
        ("result.json", lambda t: "[1, 2]", "must hold a JSON object"),
        ("trajectory.txt", lambda t: t + "0.6 1.0 2.0\n", "a TUM line has 8 numbers"),
        ("trajectory.txt", None, "trajectory file is missing"),
    ],
)
def test_a_damaged_run_folder_is_refused_in_one_line(tmp_path, capsys, name, damage, message):
    from floorvo.cli import main

    _, _, run = _written(tmp_path)
    path = run / name
    if damage is None:
        path.unlink()
    else:
        path.write_text(damage(path.read_text()))
    with pytest.raises(SequenceError, match=message) as exc:
        RunFolder.read(run)
    assert "\n" not in str(exc.value) and name in str(exc.value)
    ts = np.arange(6) / 10.0
    write_tum(tmp_path / "gt.txt", ts, np.stack([START] * 6))
    assert main(["score", str(run), "--gt", str(tmp_path / "gt.txt")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err


def test_match_samples_round_trip_and_a_damaged_one_is_refused(tmp_path):
    m = np.array([[10.0, 20.0, 8.0, 20.5], [30.0, 40.0, 28.0, 40.5]])
    write_match_sample(tmp_path, 7, m)
    write_match_sample(tmp_path, 3, m[:1])
    (frame3, a3, b3), (frame7, a7, b7) = read_match_samples(tmp_path)
    assert (frame3, frame7) == (3, 7)
    np.testing.assert_array_equal(a7, m[:, :2])
    np.testing.assert_array_equal(b7, m[:, 2:])
    np.testing.assert_array_equal(a3, m[:1, :2])
    assert read_match_samples(tmp_path / "elsewhere") == []
    (tmp_path / "matches" / "000009.npz").write_bytes(b"not a zip file")
    with pytest.raises(SequenceError, match="000009.npz: not a readable match sample"):
        read_match_samples(tmp_path)


@pytest.mark.parametrize(
    "start, words",
    [
        (np.full((4, 4), np.nan), "holds a non-finite value"),  # every pose of the run was NaN
        (np.diag([1000.0, 1000.0, 1000.0, 1.0]), "its 3x3 part is not a rotation"),  # every step x1000
        (START.T.copy(), r"bottom row \[10.0, 5.0, 100.0, 1.0\]"),  # transposed: the position was lost
        (START[None], r"shape \(1, 4, 4\), not \(4, 4\)"),
    ],
)
def test_a_start_pose_that_is_no_rigid_transform_is_refused_before_the_run(start, words):
    """T_world_start was checked for its shape alone: a NaN, scaled or transposed start pose was
    chained into every pose of the run (exit 0), and run_estimator refused the trajectory only
    when writing it, after the whole run."""
    est = Scripted(_script())
    with pytest.raises(ConfigError, match=r"scripted: T_world_start: " + words):
        run_frames(est, _frames(6), T_world_start=start)
    # the same pose, valid, chains as by hand
    np.testing.assert_allclose(
        run_frames(Scripted(_script()), _frames(2), T_world_start=START).T_world_cam[1], START @ STEP
    )


def test_frames_out_of_time_order_are_refused_in_one_line(tmp_path):
    """A run's trajectory is in time order (a TUM file's times increase): frames given in another
    order, repeated, with a NaN time, or indices outside the sequence (999: an IndexError from
    inside run_sequence) were run and then refused, or scored, as they stood."""
    frames = _frames(4)
    for bad, words in [
        ([frames[0], frames[2], frames[1]], r"frame 1: timestamp_s = 0.1 s follows the last frame's 0.2 s"),
        ([frames[0], frames[1], frames[1]], r"frame 1: timestamp_s = 0.1 s follows"),
        ([frames[0], Frame(1, float("nan"), frames[1].image)], r"frame 1: timestamp_s is not a finite number"),
        ([Frame(0, 2e18, frames[0].image)], r"frame 0: timestamp_s = 2e\+18 s is beyond"),
    ]:
        with pytest.raises(FloorbenchError, match="scripted: " + words):
            run_frames(Scripted(_script()), bad, T_world_start=START)
    from floorvo.run import build_estimator

    seq = Sequence.open(write_synthetic_sequence(tmp_path / "s", CAM, line_poses(12.0, 4.0, 100.0)))
    est, _ = build_estimator(seq, "phase-corr")
    for idx, words in [
        ([2, 1], "frame 1 follows frame 2: the frames of a run must increase"),
        ([0, 1, 1], "frame 1 follows frame 1"),
        ([0, 999], r"frame 999 is not a frame of .* \(0..3\)"),
        ([-1], r"frame -1 is not a frame of"),
    ]:
        with pytest.raises(FloorbenchError, match="phase-corr: " + words):
            run_sequence(seq, est, frames=idx)

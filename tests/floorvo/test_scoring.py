"""Scoring a run folder (floorvo.scoring) and the metric names it uses (floorvo.metric_defs)."""

import json

import numpy as np
import pytest
from test_metrics import line_traj

from floorvo import metric_defs as md
from floorvo import scoring as S
from floorvo.errors import SequenceError
from floorvo.estimators.base import RESTART_NOTE
from floorvo.geometry import T_world_cam_down
from floorvo.tum import write_tum


# ----------------------------------------------------------------------------- score_run and the CLI
def _fake_run(tmp_path, *, scale=1.01, lost=(7, 8), yaw_rate=0.0, yaw_scale=1.0):
    """A sequence folder (ground truth only) and a run folder with a scaled estimate and two lost frames
    (``yaw_rate`` rad a frame: a turning run, its yaw steps measured ``yaw_scale`` times)."""
    seq = tmp_path / "seq"
    run = tmp_path / "run"
    n = 26
    ts = np.arange(n) / 10.0
    ref = line_traj(n, yaw_rate=yaw_rate)
    est = line_traj(n, scale=scale, yaw_rate=yaw_rate * yaw_scale)
    seq.mkdir()
    write_tum(seq / "groundtruth.txt", ts, ref)
    camera = {"width_px": 64, "height_px": 48, "K": [[60.0, 0, 31.5], [0, 60.0, 23.5], [0, 0, 1]]}
    meta = {"schema_version": 2, "camera": camera, "fps": 10.0, "frame_count": n, "rig": {"height_mm": 100.0}}
    (seq / "sequence.json").write_text(json.dumps(meta))
    keep = np.array([i not in lost for i in range(n)])
    run.mkdir()
    write_tum(run / "trajectory.txt", ts[keep], est[keep])
    rows = ["frame,detect_ms,match_ms,estimate_ms,total_ms,status"]
    for i in range(n):
        st = "init" if i == 0 else ("lost" if i in lost else "ok")
        rows.append(f"{i},1.0,2.0,0.5,{3.5 + i % 2},{st}")
    (run / "timing.csv").write_text("\n".join(rows) + "\n")
    (run / "result.json").write_text(json.dumps({"estimator": "fake"}))
    return seq, run


def test_score_run_reads_run_folder(tmp_path):
    seq, run = _fake_run(tmp_path)
    s = S.score_run(run, seq)
    assert s.estimator == "fake"
    assert s.n_matched == 24 and s.tracking["lost_frames"] == 2 and s.tracking["loss_events"] == 1
    assert s.drift["end_drift_pct"] == pytest.approx(1.0, rel=1e-6)
    assert s.timing["total_ms"]["mean"] == pytest.approx(4.0)
    f = s.flat()
    assert f["lost_frames"] == 2 and f["end_drift_pct"] == pytest.approx(1.0, rel=1e-6)
    json.dumps(s.to_dict())  # serialisable


def test_the_turn_error_is_scored_over_the_steps_reported_ok(tmp_path, capsys):
    """A run turning 0.02 rad a frame (25 steps, 28.6 degrees), every yaw step measured 1 % too
    large, frames 7 and 8 lost: the step 6 -> 9 is measured from frame 6 (3 frames of turn), so
    the steps reported ok still cover the whole turn, and the turn error is +1 %. A straight run
    has none (left out: an empty results.csv cell)."""
    from floorvo.cli import main

    seq, run = _fake_run(tmp_path, scale=1.0, yaw_rate=0.02, yaw_scale=1.01)
    s = S.score_run(run, seq)
    assert s.drift["turn_deg"] == pytest.approx(np.degrees(0.5), rel=1e-6)
    assert s.drift["turn_error_pct"] == pytest.approx(1.0, rel=1e-6)
    assert s.flat()["turn_error_pct"] == pytest.approx(1.0, rel=1e-6)
    assert main(["score", str(run), "--gt", str(seq)]) == 0
    assert "turn_error_pct 1 %  (measured 28.93 deg of 28.65 deg turned" in capsys.readouterr().out
    (tmp_path / "straight").mkdir()
    straight_seq, straight_run = _fake_run(tmp_path / "straight")
    assert "turn_error_pct" not in S.score_run(straight_run, straight_seq).flat()


def test_floorvo_score_cli_prints_table_and_writes_score_json(tmp_path, capsys):
    from floorvo.cli import main

    seq, run = _fake_run(tmp_path)
    assert main(["score", str(run), "--gt", str(seq)]) == 0
    out = capsys.readouterr().out
    assert "ATE" in out and "end_drift_pct" in out and "score.json" in out
    data = json.loads((run / "score.json").read_text())
    assert data["drift"]["end_drift_pct"] == pytest.approx(1.0, rel=1e-6)
    assert data["ate"]["se3"]["alignment"] == "se3"
    assert main(["score", str(run), "--gt", str(tmp_path / "nope")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "groundtruth.txt" in err


def test_timing_csv_keeps_text_columns_and_refuses_text_times(tmp_path, capsys):
    from floorvo.cli import main

    seq, run = _fake_run(tmp_path)
    lines = (run / "timing.csv").read_text().splitlines()
    lines = [lines[0] + ",reason"] + [ln + (",map fix" if i % 2 else ",") for i, ln in enumerate(lines[1:])]
    (run / "timing.csv").write_text("\n".join(lines) + "\n")  # as `floorvo localize` writes it
    s = S.score_run(run, seq)
    assert s.tracking["lost_frames"] == 2 and s.timing["total_ms"]["mean"] == pytest.approx(4.0)
    (run / "timing.csv").write_text("\n".join([lines[0], lines[1].replace(",1.0,", ",fast,", 1)]) + "\n")
    assert main(["score", str(run), "--gt", str(seq)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "column 'detect_ms' holds a value that is not a number" in err


def _dir(path):
    path.mkdir()
    return path


def _with_reasons(run, reasons: dict[int, str]) -> None:
    """Add timing.csv's reason column (as ``floorvo run`` writes it): ``reasons[frame]``, else empty."""
    lines = (run / "timing.csv").read_text().splitlines()
    out = [lines[0] + ",reason"] + [ln + "," + reasons.get(i, "") for i, ln in enumerate(lines[1:])]
    (run / "timing.csv").write_text("\n".join(out) + "\n")


def test_wrong_ok_steps_are_scored_from_the_frame_each_was_measured_from(tmp_path):
    """Steps of 4 mm (issue 14's bound: 0.13 mm), frames 7 and 8 lost. The estimate is exact, so
    the chain's step from frame 6 to 9 is the true 12 mm: right when it was measured from 6,
    8 mm wrong when the track restarted on frame 8 (it then measured only 8 -> 9, 4 mm, so the
    run's 12 mm step is what it placed from a 4 mm measurement)."""
    seq, run = _fake_run(_dir(tmp_path / "a"), scale=1.0)
    _with_reasons(run, {0: "first frame", 7: "weak correlation peak 0.010", 8: "blocks disagree by 2.5 px"})
    s = S.score_run(run, seq)
    assert s.tracking["ok_steps_scored"] == 23 and s.tracking["wrong_ok_steps"] == 0
    assert s.tracking["lost_reasons"] == {"blocks disagree by # px": 1, "weak correlation peak #": 1}
    assert s.flat()["wrong_ok_steps"] == 0
    seq, run = _fake_run(_dir(tmp_path / "b"), scale=1.0)
    _with_reasons(run, {7: "weak correlation peak 0.010", 8: "weak correlation peak 0.012; " + RESTART_NOTE})
    s = S.score_run(run, seq)
    assert s.tracking["wrong_ok_steps"] == 1 and s.tracking["lost_reasons"] == {"weak correlation peak #": 2}
    errors = S.ok_step_errors(
        ["init", "ok", "lost", "lost", "ok"],
        ["", "", "x", "x; " + RESTART_NOTE, ""],
        line_traj(5),
        line_traj(5)[[0, 1, 4]],
    )
    np.testing.assert_allclose(errors["trans_mm"], [0.0, 8.0], atol=1e-9)  # the 12 mm step against 8 -> 9's 4 mm
    np.testing.assert_allclose(errors["step_mm"], [4.0, 4.0])
    # 1 % too long: within 0.05 mm + 2 % of every 4 mm step; 5 % too long: every ok step is wrong.
    seq, run = _fake_run(_dir(tmp_path / "c"), scale=1.01)
    assert S.score_run(run, seq).tracking["wrong_ok_steps"] == 0
    seq, run = _fake_run(_dir(tmp_path / "d"), scale=1.05)
    # 23 ok steps: 4 mm ones 0.2 mm off (bound 0.13), 6 -> 9 0.6 mm off in 12 mm (bound 0.29).
    assert S.score_run(run, seq).tracking["wrong_ok_steps"] == 23
    # A camera that tilts (pitch 0, 0.01, 0, 0.01, ... rad) seen by a planar estimator, which
    # measures its footprint's motion: each step is 100 tan(0.01) = 1.0 mm off the camera's
    # own step (bound 0.13 mm), and right against the footprint's.
    seq, run = _fake_run(_dir(tmp_path / "g"), scale=1.0)
    tilted = np.stack([T_world_cam_down(4.0 * i, 0.0, 100.0, 0.0, 0.0, 0.01 * (i % 2)) for i in range(26)])
    write_tum(seq / "groundtruth.txt", np.arange(26) / 10.0, tilted)
    level = np.stack([T_world_cam_down(4.0 * i - 100.0 * np.tan(0.01 * (i % 2)), 0, 100.0) for i in range(26)])
    keep = [i for i in range(26) if i not in (7, 8)]
    write_tum(run / "trajectory.txt", np.arange(26)[keep] / 10.0, level[keep])
    s = S.score_run(run, seq)
    assert s.tracking["wrong_ok_steps"] == 23 and s.tracking["wrong_ok_steps_footprint"] == 0
    # Every step lost (a featureless floor): scored all the same, without the pose metrics.
    seq, run = _fake_run(_dir(tmp_path / "f"), scale=1.0, lost=tuple(range(1, 26)))
    _with_reasons(run, {i: "weak correlation peak 0.003" for i in range(1, 26)})
    s = S.score_run(run, seq)
    assert s.ground_truth == S.NO_TRACK and not s.ate and not s.drift
    assert s.tracking["lost_frames"] == 25 and s.tracking["wrong_ok_steps"] == 0
    assert s.tracking["lost_reasons"] == {"weak correlation peak #": 25} and s.flat()["wrong_ok_steps"] == 0
    assert s.tracking["wrong_ok_steps_footprint"] == 0
    # A trajectory that does not fit its timing.csv (cut short at a line boundary): refused in one
    # line (it was scored over the poses it still held, its ok steps left unscored).
    seq, run = _fake_run(_dir(tmp_path / "e"), scale=1.0)
    lines = (run / "trajectory.txt").read_text().splitlines()
    (run / "trajectory.txt").write_text("\n".join(lines[:-1]) + "\n")
    with pytest.raises(SequenceError, match=r"trajectory.txt holds 23 pose\(s\), and timing.csv marks 24 frame"):
        S.score_run(run, seq)


def test_a_run_whose_poses_sit_at_other_frames_than_it_marks_is_refused(tmp_path, capsys):
    """Frames 7 and 8 lost: the run's 24 poses belong at the times of frames 0-6 and 9-25. A program
    that wrote them at its own consecutive times (frames 0-23) has the right counts; its steps were
    paired by frame with their truth and its trajectory by time with another frame's: refused in
    one line, by ``score`` (exit 1) as by the library, naming the first pose that is off."""
    from floorvo.cli import main

    seq, run = _fake_run(_dir(tmp_path / "a"), scale=1.0)
    assert S.score_run(run, seq).tracking["wrong_ok_steps"] == 0  # the run as written: its poses at its frames
    est = line_traj(26)[[i for i in range(26) if i not in (7, 8)]]
    write_tum(run / "trajectory.txt", np.arange(24) / 10.0, est)
    with pytest.raises(SequenceError, match=r"pose 8 is at 0.700000 s, nearest to frame 7 .* marks frame 9 "):
        S.score_run(run, seq)
    assert main(["score", str(run), "--gt", str(seq)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "a pose at the time of each frame marked init or ok" in err[0]
    # A run on another clock altogether (no pose at a frame's time) is not refused: it is scored for
    # tracking only, with the warning that it shares no timestamp with the ground truth.
    write_tum(run / "trajectory.txt", 1000.0 + np.arange(24) / 10.0, est)
    s = S.score_run(run, seq)
    assert s.ground_truth.startswith("the estimate shares no timestamp") and s.tracking["lost_frames"] == 2
    # A timing.csv listing a frame the sequence does not have (26 frames: 0-25).
    seq, run = _fake_run(_dir(tmp_path / "b"), scale=1.0)
    rows = (run / "timing.csv").read_text().replace("\n25,", "\n26,")
    (run / "timing.csv").write_text(rows)
    with pytest.raises(SequenceError, match=r"timing.csv: lists frame 26, and .* has frames 0-25"):
        S.score_run(run, seq)


def test_ok_steps_are_scored_against_a_bare_groundtruth_file_at_unix_times(tmp_path):
    """``floorvo score RUN --gt FILE`` with a recording's ground truth at Unix times: the frames have
    no times of their own there, so they are placed at their poses' times (the lost ones between);
    frame i had been put at i / rate from 0, paired with nothing, and the ok steps went unscored."""
    t0 = 1_700_000_000.0
    for scale, wrong in ((1.0, 0), (1.05, 23)):
        seq, run = _fake_run(_dir(tmp_path / f"s{scale}"), scale=scale)
        ts = t0 + np.arange(26) / 10.0
        write_tum(seq / "groundtruth.txt", ts, line_traj(26))
        keep = [i for i in range(26) if i not in (7, 8)]
        write_tum(run / "trajectory.txt", ts[keep], line_traj(26, scale=scale)[keep])
        s = S.score_run(run, seq / "groundtruth.txt")
        assert s.tracking["ok_steps_scored"] == 23 and s.tracking["wrong_ok_steps"] == wrong
        assert s.tracking["lost_frames"] == 2


# ----------------------------------------------------------------------------- metric names
def test_flat_names_are_the_declared_ones_and_the_results_csv_columns_of_before(tmp_path):
    """The column names results.csv has always had (written out by hand), now all from metric_defs."""
    seq, run = _fake_run(tmp_path)
    flat = S.score_run(run, seq).flat()
    by_hand = (
        [f"ate_{a}_{s}_mm" for a in ("none", "origin", "se2", "se3") for s in ("rmse", "mean", "max")]
        + ["ate_se3_rot_rmse_deg", "rpe_frame_trans_rmse_mm", "rpe_frame_rot_rmse_deg"]
        + ["rpe_10mm_trans_rmse_mm", "rpe_100mm_trans_rmse_mm"]
        + ["end_drift_pct", "distance_error_pct", "path_length_mm", "measured_mm", "turn_deg", "turn_error_pct"]
        + ["seg_10mm_t_err_pct", "seg_25mm_t_err_pct", "seg_50mm_t_err_pct", "seg_100mm_t_err_pct"]
        + ["seg_mean_t_err_pct", "seg_mean_r_err_deg_per_m", "lost_frames", "loss_events", "tracked_fraction"]
        + ["wrong_ok_steps", "wrong_ok_steps_footprint"]
        + ["time_total_ms_mean", "time_detect_ms_mean", "time_match_ms_mean", "time_estimate_ms_mean", "fps"]
    )
    assert list(flat) == [n for n in by_hand if n != "turn_error_pct"]  # a straight run: no turn to have an error
    declared = md.all_metrics(segment_lengths_mm=(10.0, 25.0, 50.0, 100.0))
    assert list(declared) == by_hand
    for name in by_hand:
        d = md.metric(name)
        assert d.name == name and d.label and d.description
        # The unit is the name's suffix where the name carries one.
        suffix = {"_mm": "mm", "_deg": "deg", "_pct": "%", "_deg_per_m": "deg/m", "_ms_mean": "ms"}
        assert all(d.unit == u for s, u in suffix.items() if name.endswith(s))
    assert md.END_DRIFT.unit == "%" and md.END_DRIFT.lower_is_better is True
    assert md.TRACKED_FRACTION.lower_is_better is False and md.FPS.lower_is_better is False
    assert md.DISTANCE_ERROR.lower_is_better is None  # signed: its magnitude counts
    assert md.ate_rmse("se2").unit == "mm" and md.time_mean("match_ms").name == "time_match_ms_mean"


def test_unknown_metric_names_and_parameters_are_refused_by_name():
    with pytest.raises(ValueError, match="metric 'ate_foo_rmse_mm': unknown"):
        md.metric("ate_foo_rmse_mm")
    with pytest.raises(ValueError, match="alignment 'sim3'"):
        md.ate_rmse("sim3")
    with pytest.raises(ValueError, match="timing stage 'io_ms'"):
        md.time_mean("io_ms")


def test_write_score_writes_json_atomically(tmp_path):
    seq, run = _fake_run(tmp_path)
    S.write_score(S.score_run(run, seq), tmp_path / "out" / "score.json")
    data = json.loads((tmp_path / "out" / "score.json").read_text())
    assert data["estimator"] == "fake" and data["tracking"]["lost_frames"] == 2
    assert [p.name for p in (tmp_path / "out").iterdir()] == ["score.json"]  # no temporary file left


def test_a_run_against_another_sequence_is_refused_by_score_plot_and_calibrate(tmp_path, capsys):
    """A run of one sequence scored, plotted or calibrated against another (another camera,
    another path) gave figures with exit code 0: now the run records the sequence it was run on
    (result.json sequence_sha256) and the three refuse another one in a line; a copy of the
    sequence folder is the same sequence, and a TUM file is not checked."""
    import shutil

    from floorvo.camera import CameraModel
    from floorvo.cli import main
    from floorvo.synthetic import line_poses, write_synthetic_sequence

    cam = CameraModel.from_sensor().scaled(0.25)
    seq = write_synthetic_sequence(tmp_path / "a", cam, line_poses(8.0, 2.0), seed=0)
    other = write_synthetic_sequence(tmp_path / "b", cam.scaled(1.25), line_poses(8.0, 2.0, yaw_step_rad=0.05), seed=0)
    run = tmp_path / "run"
    assert main(["run", str(seq), "-e", "phase-corr", "-o", str(run)]) == 0
    for argv in (
        ["score", str(run), "--gt", str(other)],
        ["plot", str(run), "--gt", str(other), "-o", str(tmp_path / "p.png")],
        ["calibrate", str(run), "--gt", str(other), "-o", str(tmp_path / "c.json")],
    ):
        capsys.readouterr()
        assert main(argv) == 1, argv
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"run: was run on another sequence ('{seq}'" in err, err
    assert not (tmp_path / "p.png").exists() and not (tmp_path / "c.json").exists()
    copy = shutil.copytree(seq, tmp_path / "copy")
    assert main(["score", str(run), "--gt", str(copy)]) == 0
    assert main(["score", str(run), "--gt", str(other / "groundtruth.txt")]) == 0
    # The same sequence rendered again differs in its render timings only: still the same.
    meta = json.loads((copy / "sequence.json").read_text())
    (copy / "sequence.json").write_text(json.dumps({**meta, "render_stats": {"seconds": 12.5}}))
    assert main(["score", str(run), "--gt", str(copy)]) == 0


@pytest.mark.parametrize("value, words", [("-1", "must be >= 0.0 s"), ("nan", "must be a finite number")])
def test_an_impossible_association_tolerance_is_refused(tmp_path, capsys, value, words):
    """floorvo score --max-diff -1 (or nan) paired nothing and reported 'the estimate shares no
    timestamp with the ground truth (within -1.0 s)' with exit code 0."""
    from floorvo.cli import main

    seq, run = _fake_run(tmp_path)
    assert main(["score", str(run), "--gt", str(seq), "--max-diff", value]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"timestamp association tolerance (--max-diff) = {float(value)} s: {words}" in err


def test_drift_divides_by_the_reference_path_across_lost_frames_not_its_chord():
    """A half circle of radius 100 mm (61 poses) tracked at frames 0, 59 and 60 only, exact but
    for a 5 mm error at the end: the path is 100 pi mm long up to frame 60 (60 chords of 3
    degrees), and the drift 5 mm of it (1.59 %). The chord between the matched poses (205 mm)
    gave 2.44 %, and no 250 mm segment at all."""
    a = np.linspace(0.0, np.pi, 61)
    T_ref = np.stack([T_world_cam_down(100.0 * np.sin(x), 100.0 * (1.0 - np.cos(x)), 100.0, x) for x in a])
    t = np.arange(61) / 30.0
    keep = [0, 59, 60]
    T_est = T_ref[keep].copy()
    T_est[-1, 0, 3] += 5.0
    sc = S.score_trajectories(t, T_ref, t[keep], T_est, rpe_deltas_mm=(250.0,), segment_lengths_mm=(250.0,))
    assert sc.drift["path_length_mm"] == pytest.approx(60 * 200.0 * np.sin(np.pi / 120), rel=1e-12)
    assert sc.drift["end_drift_pct"] == pytest.approx(100.0 * 5.0 / sc.drift["path_length_mm"], rel=1e-12)
    # 250 mm along the path from frame 0 is reached at frame 59 (its chord from frame 0: 200 mm)
    (seg,) = sc.segments
    assert seg["length_mm"] == 250.0 and seg["count"] == 1
    (r,) = sc.rpe_distance
    assert r["trans_mm"]["count"] == 1

"""floorvo.calibration: per-axis odometry scale fitted on one run and divided out of others."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from tests.floorvo._synth import chain_scaled, hand_run

from floorvo.calibration import (
    ScaleCalibration,
    _fit_steps,
    apply_scale,
    fit_scale_calibration,
    load_scale_calibration,
)
from floorvo.camera import CameraModel
from floorvo.cli import main as floorvo_main
from floorvo.errors import ConfigError
from floorvo.estimators.base import Frame, StepResult
from floorvo.geometry import T_world_cam_down, invert_T, make_T, rot_z
from floorvo.imaging import texture_orientation
from floorvo.synthetic import write_synthetic_sequence
from floorvo.tum import read_tum

CAM = CameraModel.from_sensor(162, 124, pixel_pitch_um=29.6, focal_length_mm=6.0)  # GSD 0.4933 mm at 100 mm


def test_fit_recovers_per_axis_scales_of_a_turning_path():
    k = np.arange(40)
    T_true = np.stack([T_world_cam_down(3.0 * i, 1.5 * i + 0.02 * i**2, 100.0, 0.03 * i) for i in k])
    T_est = chain_scaled(T_true, 1.0025, 0.9990)
    cal = fit_scale_calibration(T_true, T_est)
    assert cal.observed_x and cal.observed_y and cal.steps == 39
    assert cal.scale_x == pytest.approx(1.0025, abs=1e-9)
    assert cal.scale_y == pytest.approx(0.9990, abs=1e-9)
    # Dividing the scales out of the estimated steps gives back the true end pose.
    fixed = [T_est[0]]
    for i in range(len(T_est) - 1):
        fixed.append(fixed[-1] @ apply_scale(invert_T(T_est[i]) @ T_est[i + 1], cal))
    np.testing.assert_allclose(fixed[-1], T_true[-1], atol=1e-9)


def test_fit_recovers_the_yaw_scale_and_dividing_it_out_gives_back_the_path():
    """The same turning path (1.72 degrees a frame, 67 degrees in all) with every yaw step read
    0.4 % short and x 0.25 % long: scale_yaw 0.996 and scale_x 1.0025 by least squares, and the
    steps with both divided out chain to the true end pose; a straight run observes no yaw."""
    k = np.arange(40)
    T_true = np.stack([T_world_cam_down(3.0 * i, 1.5 * i + 0.02 * i**2, 100.0, 0.03 * i) for i in k])
    T_est = chain_scaled(T_true, 1.0025, 1.0, 0.996)
    cal = fit_scale_calibration(T_true, T_est)
    assert cal.observed_yaw and cal.turn_deg == pytest.approx(np.degrees(0.03 * 39), rel=1e-9)
    assert cal.scale_yaw == pytest.approx(0.996, abs=1e-9) and cal.scale_x == pytest.approx(1.0025, abs=1e-9)
    fixed = [T_est[0]]
    for i in range(len(T_est) - 1):
        fixed.append(fixed[-1] @ apply_scale(invert_T(T_est[i]) @ T_est[i + 1], cal))
    np.testing.assert_allclose(fixed[-1], T_true[-1], atol=1e-9)
    unfixed = [T_est[0]]
    for i in range(len(T_est) - 1):
        unfixed.append(unfixed[-1] @ apply_scale(invert_T(T_est[i]) @ T_est[i + 1], replace(cal, scale_yaw=1.0)))
    assert np.linalg.norm(unfixed[-1][:3, 3] - T_true[-1][:3, 3]) > 0.1  # mm: the yaw is what was left
    straight = np.stack([T_world_cam_down(4.0 * i, 0.0, 100.0) for i in range(26)])
    cal = fit_scale_calibration(straight, chain_scaled(straight, 1.0, 1.0, 0.9))
    assert not cal.observed_yaw and cal.scale_yaw == 1.0


def test_axis_without_travel_keeps_scale_one():
    T_true = np.stack([T_world_cam_down(4.0 * i, 0.0, 100.0) for i in range(26)])
    cal = fit_scale_calibration(T_true, chain_scaled(T_true, 1.01, 1.0))
    assert cal.observed_x and cal.scale_x == pytest.approx(1.01)
    assert not cal.observed_y and cal.scale_y == 1.0 and cal.travel_y_mm == pytest.approx(0.0, abs=1e-9)


def _diagonal_sequence(path, seed: int, dx: float, dy: float, n: int = 26):
    """A synthetic sequence rendered at 100 mm whose sequence.json says 102 mm (a mis-measured rig)."""
    T = np.stack([T_world_cam_down(dx * i, dy * i, 100.0) for i in range(n)])
    root = write_synthetic_sequence(path, CAM, T, height_mm=100.0, seed=seed)
    meta = json.loads((root / "sequence.json").read_text())
    meta["rig"]["height_mm"] = 102.0
    (root / "sequence.json").write_text(json.dumps(meta))
    return root


def _end_error_pct(run, seq) -> float:
    _, T_est = read_tum(run / "trajectory.txt")
    _, T_gt = read_tum(seq / "groundtruth.txt")
    return 100 * np.linalg.norm(T_est[-1][:3, 3] - T_gt[-1][:3, 3]) / np.linalg.norm(T_gt[-1][:3, 3] - T_gt[0][:3, 3])


def test_calibration_fitted_on_one_run_corrects_another(tmp_path, capsys):
    """A 2 % height error: calibrated on one run (floor seed 1), the next run (seed 2, another path) ends within 0.1 %."""
    cal_seq = _diagonal_sequence(tmp_path / "cal", 1, 3.0, 2.0)
    test_seq = _diagonal_sequence(tmp_path / "test", 2, 2.0, -3.0)
    assert floorvo_main(["run", str(cal_seq), "-e", "phase-corr", "-o", str(tmp_path / "run_cal")]) == 0
    assert (
        floorvo_main(["calibrate", str(tmp_path / "run_cal"), "--gt", str(cal_seq), "-o", str(tmp_path / "scale.json")])
        == 0
    )
    assert "scale x 1.0" in capsys.readouterr().out
    cal = load_scale_calibration(tmp_path / "scale.json")
    assert cal.estimator == "phase-corr"
    assert cal.scale_x == pytest.approx(1.02, abs=0.002) and cal.scale_y == pytest.approx(1.02, abs=0.002)
    assert floorvo_main(["run", str(test_seq), "-e", "phase-corr", "-o", str(tmp_path / "raw")]) == 0
    cmd = [
        "run",
        str(test_seq),
        "-e",
        "phase-corr",
        "-o",
        str(tmp_path / "fixed"),
        "--scale-calibration",
        str(tmp_path / "scale.json"),
    ]
    assert floorvo_main(cmd) == 0
    assert _end_error_pct(tmp_path / "raw", test_seq) == pytest.approx(2.0, abs=0.2)
    assert _end_error_pct(tmp_path / "fixed", test_seq) < 0.1
    result = json.loads((tmp_path / "fixed" / "result.json").read_text())
    assert result["scale_calibration"]["scale_x"] == cal.scale_x


def test_a_run_on_the_calibrations_own_sequence_or_with_another_config_says_so(tmp_path, caplog):
    """A calibration applied to the very sequence it was fitted on (a score that measures what was
    tuned on it) or to a run of another estimator config was applied without a word; now each is
    a warning and a line of result.json's ``scale_calibration_problems``; a separate run has none."""
    cal_seq = _diagonal_sequence(tmp_path / "cal", 1, 3.0, 2.0, n=8)
    test_seq = _diagonal_sequence(tmp_path / "test", 2, 2.0, -3.0, n=8)
    assert floorvo_main(["run", str(cal_seq), "-e", "phase-corr", "-o", str(tmp_path / "run_cal")]) == 0
    scale = tmp_path / "scale.json"
    assert floorvo_main(["calibrate", str(tmp_path / "run_cal"), "--gt", str(cal_seq), "-o", str(scale)]) == 0

    def problems(seq, out, *more) -> list[str]:
        cmd = ["run", str(seq), "-e", "phase-corr", "-o", str(tmp_path / out), "--scale-calibration", str(scale)]
        assert floorvo_main([*cmd, *more]) == 0
        return json.loads((tmp_path / out / "result.json").read_text()).get("scale_calibration_problems", [])

    with caplog.at_level("WARNING", logger="floorvo"):
        own = problems(cal_seq, "own")
    assert len(own) == 1 and "fitted on this sequence" in own[0] and "fitted on this sequence" in caplog.text
    assert problems(test_seq, "separate") == []
    other = problems(test_seq, "other-config", "--set", "iterations=3")
    assert len(other) == 1 and "another estimator config" in other[0] and "iterations = 2 there, 3 here" in other[0]
    # a boolean named as the config files spell it, not True/False
    other = problems(test_seq, "other-bool", "--set", "predict=false")
    assert len(other) == 1 and "predict = true there, false here" in other[0], other
    # A copy of the sequence it was fitted on is that sequence (its path was all that was compared);
    # a copy whose frames have changed since is another.
    import shutil

    shutil.copytree(cal_seq, tmp_path / "copy")
    copy = problems(tmp_path / "copy", "run_copy")
    assert len(copy) == 1 and "fitted on this sequence" in copy[0] and "or one holding the same files" in copy[0]
    frame = tmp_path / "copy" / "cam0" / "000003.png"
    frame.write_bytes(frame.read_bytes() + b"\0")  # a byte more after the PNG's end: other files, same picture
    assert problems(tmp_path / "copy", "run_copy2") == []
    # A config value JSON holds as a list (a plugin's tuple key) is the same config, not another.
    from floorvo.calibration import calibration_use_problems, load_scale_calibration

    result_path = tmp_path / "run_cal" / "result.json"
    result = json.loads(result_path.read_text())
    result["config"]["block_layout"] = [2, 2]
    result_path.write_text(json.dumps(result))
    same = {**result["config"], "block_layout": (2, 2)}
    assert calibration_use_problems(load_scale_calibration(scale), test_seq, same) == []


@pytest.mark.parametrize(
    "content, message",
    [
        ("{not json", "not valid JSON"),
        ('{"kind": "something else", "version": 1}', "not a scale calibration"),
        ('{"kind": "floorvo scale calibration", "version": 7, "scale_x": 1.0, "scale_y": 1.0}', "version 7"),
        (
            '{"kind": "floorvo scale calibration", "version": 1, "scale_x": 2.0, "scale_y": 1.0}',
            "scale_x = 2.0 must be a number in",
        ),
        (
            '{"kind": "floorvo scale calibration", "version": 1, "scale_x": 1.0, "scale_y": 1.0, "scale_z": 1}',
            "unknown key 'scale_z'",
        ),
        # fitted on another estimator's run: it was divided out of phase-corr's steps without a word
        (
            '{"kind": "floorvo scale calibration", "version": 1, "scale_x": 1.02, "scale_y": 1.0, '
            '"estimator": "akaze-guided"}',
            "fitted on a run of 'akaze-guided', not 'phase-corr'; fit one per estimator",
        ),
        # every other field held to its type and rule: a sequence that is no text was a traceback
        # where the run compared it with its own; a negative step count or a NaN travel was taken
        (
            '{"kind": "floorvo scale calibration", "version": 1, "scale_x": 1.0, "scale_y": 1.0, "sequence": 5}',
            "scale.json: sequence = 5: must be a string",
        ),
        (
            '{"kind": "floorvo scale calibration", "version": 1, "scale_x": 1.0, "scale_y": 1.0, "run": 7}',
            "scale.json: run = 7: must be a string",
        ),
        (
            '{"kind": "floorvo scale calibration", "version": 1, "scale_x": 1.0, "scale_y": 1.0, "steps": -1}',
            "scale.json: steps = -1: must be >= 0",
        ),
        (
            '{"kind": "floorvo scale calibration", "version": 1, "scale_x": 1.0, "scale_y": 1.0, "travel_x_mm": NaN}',
            "scale.json: travel_x_mm = nan mm: must be a finite number",
        ),
        (
            '{"kind": "floorvo scale calibration", "version": 1, "scale_x": 1.0, "scale_y": 1.0, "observed_x": "yes"}',
            "scale.json: observed_x = 'yes': must be true or false",
        ),
        (
            '{"kind": "floorvo scale calibration", "version": 3, "scale_x": 1.0, "scale_y": 1.0}',
            "scale.json: scale_yaw is missing",
        ),
    ],
)
def test_bad_calibration_file_is_one_line_error(tmp_path, capsys, content, message):
    path = tmp_path / "scale.json"
    path.write_text(content)
    with pytest.raises(ConfigError, match=message):
        load_scale_calibration(path, "phase-corr")
    seq = write_synthetic_sequence(tmp_path / "s", CAM, np.stack([T_world_cam_down(0.0, 0.0, 100.0)] * 2))
    assert (
        floorvo_main(
            ["run", str(seq), "-e", "phase-corr", "-o", str(tmp_path / "run"), "--scale-calibration", str(path)]
        )
        == 1
    )
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err
    assert not (tmp_path / "run" / "trajectory.txt").exists()


def test_calibration_round_trips_through_its_file(tmp_path):
    from floorvo.calibration import save_scale_calibration

    cal = ScaleCalibration(1.0025, 0.9993, True, True, 100.0, 20.0, 25, "akaze-guided", "r", "s", 0.9961, True, 115.0)
    save_scale_calibration(cal, tmp_path / "c.json")
    assert load_scale_calibration(tmp_path / "c.json") == cal
    # A version-1 file (before the yaw's scale) is read, its yaw kept at 1.
    v1 = {"kind": "floorvo scale calibration", "version": 1, "scale_x": 1.002, "scale_y": 0.999}
    (tmp_path / "v1.json").write_text(json.dumps(v1))
    old = load_scale_calibration(tmp_path / "v1.json")
    assert (old.scale_x, old.scale_yaw, old.observed_yaw) == (1.002, 1.0, False)
    bad = {**cal.to_dict(), "scale_yaw": 1.5}
    (tmp_path / "bad.json").write_text(json.dumps(bad))
    with pytest.raises(ConfigError, match=r"scale_yaw = 1.5 must be a number in \[0.9, 1.1\]"):
        load_scale_calibration(tmp_path / "bad.json")


def test_calibration_leaves_out_the_motion_a_restart_dropped(tmp_path):
    """A run 1 % long on every 4 mm step that lost frames 7 and 8 and restarted its track on
    frame 8: its step to frame 9 was measured from frame 8 (4.04 mm) and chained onto frame
    6's pose, so consecutive poses 6 -> 9 hold 4.04 mm where the truth moved 12 mm. Paired
    with frame 8 (the frame it was measured from, ``timing.csv``'s reason), every step gives
    1.01; paired with frame 6 (consecutive poses, as the fit did), the scale came out 0.81."""
    from floorvo.calibration import calibrate_run
    from floorvo.estimators.base import RESTART_NOTE
    from floorvo.tum import write_tum

    n, ts = 26, np.arange(26) / 10.0
    truth = np.stack([T_world_cam_down(4.0 * i, 0.0, 100.0) for i in range(n)])
    placed = [i for i in range(n) if i not in (7, 8)]
    est = [truth[0]]
    for a, b in zip(placed[:-1], placed[1:]):
        frm = 8 if b == 9 else a  # the restart on frame 8
        d = invert_T(truth[frm]) @ truth[b]
        d[:2, 3] *= 1.01
        est.append(est[-1] @ d)
    seq, run = tmp_path / "seq", tmp_path / "run"
    seq.mkdir()
    run.mkdir()
    write_tum(seq / "groundtruth.txt", ts, truth)
    write_tum(run / "trajectory.txt", ts[placed], np.stack(est))
    rows = ["frame,detect_ms,match_ms,estimate_ms,total_ms,status,reason"]
    for i in range(n):
        st, why = ("init", "first frame") if i == 0 else (("lost", "weak peak") if i in (7, 8) else ("ok", ""))
        rows.append(f"{i},1.0,2.0,0.5,3.5,{st},{why + ('; ' + RESTART_NOTE if i == 8 else '')}")
    (run / "timing.csv").write_text("\n".join(rows) + "\n")
    (run / "result.json").write_text(json.dumps({"estimator": "fake"}))
    assert calibrate_run(run, seq).scale_x == pytest.approx(1.01, abs=1e-9)
    # What the fit of consecutive poses gives (the old calibrate_run): (22 x 16 x 1.01 + 12 x 4.04) / (22 x 16 + 144)
    assert fit_scale_calibration(truth[placed], np.stack(est)).scale_x == pytest.approx(404.0 / 496.0, abs=1e-9)


def test_one_calibration_from_a_straight_run_and_a_spin(tmp_path, capsys):
    """x from a straight run (100 mm, read 0.3 % long), the yaw from a spin in place (115 degrees,
    read 0.35 % too far): `floorvo calibrate RUN1 RUN2 --gt SEQ1 --gt SEQ2` fits both into one file
    (neither run alone observes both); runs of two estimators are refused in one line."""
    straight = np.stack([T_world_cam_down(4.0 * i, 0.0, 100.0) for i in range(26)])
    spin = np.stack([T_world_cam_down(0.0, 0.0, 100.0, 0.1 * i) for i in range(21)])
    r1, s1 = hand_run(tmp_path / "a", straight, chain_scaled(straight, 1.003, 1.0), "phase-corr")
    r2, s2 = hand_run(tmp_path / "b", spin, chain_scaled(spin, 1.0, 1.0, 1.0035), "phase-corr")
    out = tmp_path / "cal.json"
    assert floorvo_main(["calibrate", str(r1), str(r2), "--gt", str(s1), "--gt", str(s2), "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "x 1.00300 (100 mm of travel)" in printed and "yaw 1.00350 (115 deg of turn)" in printed
    cal = load_scale_calibration(out)
    assert cal.scale_x == pytest.approx(1.003) and cal.scale_yaw == pytest.approx(1.0035) and cal.steps == 45
    assert not cal.observed_y and cal.estimator == "phase-corr" and cal.run == f"{r1}; {r2}"
    r3, s3 = hand_run(tmp_path / "c", spin, spin, "akaze-guided")
    assert floorvo_main(["calibrate", str(r1), str(r3), "--gt", str(s1), "--gt", str(s3), "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "the runs are of different estimators (akaze-guided, phase-corr)" in err
    assert floorvo_main(["calibrate", str(r1), str(r2), str(r3), "--gt", str(s1), "--gt", str(s2), "-o", str(out)]) == 1
    assert "--gt: given 2 times for 3 runs" in capsys.readouterr().err


def test_a_run_that_lost_every_frame_is_said_to_have_no_step(tmp_path, capsys):
    """It was refused as 'fewer than 2 poses match ... in time', which points at the timestamps."""
    straight = np.stack([T_world_cam_down(4.0 * i, 0.0, 100.0) for i in range(6)])
    run, seq = hand_run(tmp_path / "a", straight, straight, "phase-corr", lost_after=1)
    assert floorvo_main(["calibrate", str(run), "--gt", str(seq), "-o", str(tmp_path / "cal.json")]) == 1
    err = capsys.readouterr().err.splitlines()
    assert err == [f"floorvo: error: {run}/trajectory.txt: holds 1 pose(s): the run measured no step to calibrate with"]


@pytest.mark.parametrize("value, words", [("-1", "must be >= 0.0 mm"), ("nan", "must be a finite number")])
def test_an_impossible_min_travel_is_refused(tmp_path, capsys, value, words):
    """floorvo calibrate --min-travel-mm nan kept every axis 'not observed' at scale 1, exit 0."""
    seq = _diagonal_sequence(tmp_path / "cal", 1, 3.0, 2.0)
    assert floorvo_main(["run", str(seq), "-e", "phase-corr", "-o", str(tmp_path / "run")]) == 0
    capsys.readouterr()
    argv = ["calibrate", str(tmp_path / "run"), "--gt", str(seq), "-o", str(tmp_path / "c.json")]
    assert floorvo_main([*argv, "--min-travel-mm", value]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--min-travel-mm = {float(value)} mm: {words}" in err
    assert not (tmp_path / "c.json").exists()


# --- scales that depend on the floor texture's orientation (a grained floor under the rig's lights)

_TERMS = {"x": (1.0012, 0.0011, -0.0002), "yaw": (0.9971, 0.0047, -0.0008)}  # about what the wood floor shows


def _s(axis: str, theta: np.ndarray) -> np.ndarray:
    c, a, b = _TERMS[axis]
    return c + a * np.cos(2 * theta) + b * np.sin(2 * theta)


def _grained_steps(n: int = 60, noise: float = 0.0, seed: int = 0):
    """True and estimated steps (n, 4, 4) of a path turning 2 degrees a frame while moving 4 mm along
    x, its grain orientation theta turning with the floor (-yaw), each step's x and yaw scaled by
    the orientation's functions (_TERMS); ``noise``: Gaussian noise on the estimates (mm, rad)."""
    rng = np.random.default_rng(seed)
    theta = -np.radians(2.0) * np.arange(n) + 0.3
    G = np.stack([make_T(rot_z(np.radians(2.0)), [4.0, 0.0, 0.0]) for _ in range(n)])
    E = np.stack(
        [
            make_T(
                rot_z(np.radians(2.0) * _s("yaw", t) + noise * rng.normal()),
                [4.0 * _s("x", t) + noise * rng.normal(), 0.0, 0.0],
            )
            for t in theta
        ]
    )
    return G, E, theta


def test_fit_recovers_scales_that_depend_on_the_texture_orientation_and_undoes_them():
    """Steps whose x and yaw scales are functions of the step's texture orientation (120 degrees of
    it turned): the least squares gives back the constant and both terms of each, and dividing
    the scales at each step's orientation out gives back every true step."""
    G, E, theta = _grained_steps()
    cal = _fit_steps(G, E, 10.0, 10.0, theta, coherence=0.9)
    assert cal.uses_orientation and cal.orientation_coherence == 0.9
    for axis in ("x", "yaw"):
        got = (getattr(cal, f"scale_{axis}"), getattr(cal, f"{axis}_cos2"), getattr(cal, f"{axis}_sin2"))
        np.testing.assert_allclose(got, _TERMS[axis], atol=1e-6)
    assert (cal.y_cos2, cal.y_sin2) == (0.0, 0.0) and not cal.observed_y
    for g, e, t in zip(G, E, theta):
        np.testing.assert_allclose(apply_scale(e, cal, t), g, atol=1e-6)
    with pytest.raises(ValueError, match="give the step's theta_rad"):
        apply_scale(E[0], cal)


@pytest.mark.parametrize(
    "what",
    ["no direction", "orientation held", "turned too little", "no dependence", "no orientations"],
)
def test_orientation_terms_only_where_the_runs_observe_them(what):
    """Constants only (as a version-2 calibration) where the frames' texture has no direction
    (coherence 0.3: the light's own direction), where it did not turn (a straight run: one
    orientation) or turned through less than about 108 of its 180 degrees, where the scales do not depend on it (noise of the size the rendered runs
    show, no terms: not significant) or where no orientations are given."""
    G, E, theta = _grained_steps()
    coherence = 0.9
    if what == "no direction":
        coherence = 0.3
    elif what == "orientation held":
        theta = np.full_like(theta, 0.3)
    elif what == "turned too little":  # 80 of 180 degrees: the rest would be extrapolated
        G, E, theta = G[:40], E[:40], theta[:40]
    elif what == "no dependence":
        _TERMS_SAVED = dict(_TERMS)
        _TERMS.update({"x": (1.0012, 0.0, 0.0), "yaw": (0.9971, 0.0, 0.0)})
        try:
            G, E, theta = _grained_steps(noise=2e-4)
        finally:
            _TERMS.update(_TERMS_SAVED)
    cal = _fit_steps(G, E, 10.0, 10.0, None if what == "no orientations" else theta, coherence)
    assert not cal.uses_orientation
    assert cal.scale_x == pytest.approx(np.mean(E[:, 0, 3] / 4.0), rel=1e-3)


def test_an_orientation_calibration_round_trips_and_an_impossible_one_is_refused(tmp_path):
    from floorvo.calibration import save_scale_calibration

    G, E, theta = _grained_steps()
    cal = _fit_steps(G, E, 10.0, 10.0, theta, coherence=0.9)
    save_scale_calibration(cal, tmp_path / "c.json")
    back = load_scale_calibration(tmp_path / "c.json")
    assert back == cal and back.uses_orientation and json.loads((tmp_path / "c.json").read_text())["version"] == 3
    # A version-2 file (constants only) is read with no terms.
    v2 = {k: v for k, v in cal.to_dict().items() if not k.endswith(("cos2", "sin2")) and k != "orientation_coherence"}
    (tmp_path / "v2.json").write_text(json.dumps({**v2, "version": 2}))
    assert not load_scale_calibration(tmp_path / "v2.json").uses_orientation
    # Terms that take a scale out of [0.9, 1.1] at some orientation: refused in one line.
    (tmp_path / "bad.json").write_text(json.dumps({**cal.to_dict(), "yaw_cos2": 0.12}))
    with pytest.raises(ConfigError, match=r"scale_yaw with its orientation terms spans \[0\.87.*must stay in"):
        load_scale_calibration(tmp_path / "bad.json")
    (tmp_path / "nan.json").write_text(json.dumps({**cal.to_dict(), "x_sin2": "a"}))
    with pytest.raises(ConfigError, match=r"x_sin2 = 'a' must be a finite number"):
        load_scale_calibration(tmp_path / "nan.json")


def _stripes(theta_rad: float, shape=(124, 162), period_px: float = 12.0) -> np.ndarray:
    y, x = np.mgrid[: shape[0], : shape[1]].astype(float)
    s = np.sin(2 * np.pi * (x * np.cos(theta_rad) + y * np.sin(theta_rad)) / period_px)
    return np.clip(110 * (1 + 0.5 * s), 0, 255).astype(np.uint8)


def test_calibrate_reads_the_orientation_from_the_frames_and_a_run_applies_it(tmp_path, capsys):
    """End to end on a striped floor turning under the camera: ``floorvo calibrate`` on a run
    whose x and yaw scales depend on the stripes' orientation measures it in the sequence's
    frames and fits both terms; the runner, given that file, measures each frame's orientation
    and divides the scales at it out of the steps: the run's path is the true one."""
    from tests.floorvo._synth import Scripted, blank_meta

    from floorvo.runner import run_frames, sequence_frames
    from floorvo.sequence import Sequence, SequenceWriter
    from floorvo.tum import write_tum

    n = 60  # 120 degrees of the stripes' 180
    G, E, theta = _grained_steps(n=n)
    theta_frames = np.concatenate([[theta[0] + np.radians(1.0)], theta - np.radians(1.0)])  # steps: their means
    T_true = np.stack([np.eye(4)] * (n + 1))
    T_est = T_true.copy()
    for k in range(n):
        T_true[k + 1] = T_true[k] @ G[k]
        T_est[k + 1] = T_est[k] @ E[k]
    seq, run = tmp_path / "seq", tmp_path / "run"
    with SequenceWriter(seq, blank_meta(CAM, n + 1)) as w:
        for i, t in enumerate(theta_frames):
            w.write_frame(i, _stripes(t))
    ts = np.arange(n + 1) / 30.0
    write_tum(seq / "groundtruth.txt", ts, T_true)
    run.mkdir()
    write_tum(run / "trajectory.txt", ts, T_est)
    (run / "timing.csv").write_text(
        "frame,total_ms,status,reason\n" + "".join(f"{i},1.0,{'init' if i == 0 else 'ok'},\n" for i in range(n + 1))
    )
    (run / "result.json").write_text(json.dumps({"estimator": "phase-corr"}))
    assert floorvo_main(["calibrate", str(run), "--gt", str(seq), "-o", str(tmp_path / "c.json")]) == 0
    assert "cos 2theta" in capsys.readouterr().out
    cal = load_scale_calibration(tmp_path / "c.json")
    assert cal.uses_orientation and cal.orientation_coherence > 0.9
    np.testing.assert_allclose([cal.scale_yaw, cal.yaw_cos2, cal.yaw_sin2], _TERMS["yaw"], atol=2e-4)
    s = Sequence.open(seq)
    steps = [StepResult("init")] + [StepResult("ok", e) for e in E]
    res = run_frames(Scripted(steps), sequence_frames(s, range(n + 1)), T_world_start=np.eye(4), scale_calibration=cal)
    np.testing.assert_allclose(res.T_world_cam[-1][:3, 3], T_true[-1][:3, 3], atol=0.02)  # mm, after 240 mm
    plain = run_frames(Scripted(steps), sequence_frames(s, range(n + 1)), T_world_start=np.eye(4))
    assert np.linalg.norm(plain.T_world_cam[-1][:3, 3] - T_true[-1][:3, 3]) > 0.2
    # --no-orientation: constants only, no frame read.
    assert (
        floorvo_main(["calibrate", str(run), "--gt", str(seq), "-o", str(tmp_path / "k.json"), "--no-orientation"]) == 0
    )
    assert not load_scale_calibration(tmp_path / "k.json").uses_orientation


def test_a_frame_without_a_mono_image_gets_no_orientation_and_the_run_goes_on():
    """With an orientation calibration the runner measures each frame's texture orientation; a frame
    the estimator refuses (a colour frame, lost with its reason) is not measured, and the next ok
    step is scaled at the orientation of the frames it was measured between."""
    from tests.floorvo._synth import Scripted

    from floorvo.runner import run_frames

    G, E, theta = _grained_steps()
    cal = _fit_steps(G, E, 10.0, 10.0, theta, coherence=0.9)
    frames = [
        Frame(0, 0.0, _stripes(theta[0])),
        Frame(1, 0.1, np.zeros((124, 162, 3), np.uint8)),
        Frame(2, 0.2, _stripes(theta[0])),
    ]
    script = [StepResult("init"), StepResult("lost", reason="frame has 3 channels"), StepResult("ok", E[0])]
    res = run_frames(Scripted(script), frames, T_world_start=np.eye(4), scale_calibration=cal)
    assert list(res.status) == ["init", "lost", "ok"]
    np.testing.assert_allclose(res.T_world_cam[-1], apply_scale(E[0], cal, texture_orientation(frames[0].image)[0]))


def test_a_calibration_is_fitted_only_on_uncalibrated_runs_within_its_range_and_knows_its_paths(
    tmp_path, capsys, monkeypatch
):
    """Runs made with a calibration fitted scales of 1 (a file that then did nothing); a fit of 1.15
    wrote a file every later run refused; relative paths (and --gt SEQ/groundtruth.txt) kept the
    'fitted on this sequence' warning from runs made elsewhere; a file fitted on runs without
    result.json (no estimator) was applied to any estimator without a word."""
    from floorvo.calibration import calibrate_runs, calibration_use_problems

    seq = _diagonal_sequence(tmp_path / "cal", 1, 3.0, 2.0)
    assert floorvo_main(["run", str(seq), "-e", "phase-corr", "-o", str(tmp_path / "raw")]) == 0
    monkeypatch.chdir(tmp_path)
    assert floorvo_main(["calibrate", "raw", "--gt", "cal/groundtruth.txt", "-o", "scale.json"]) == 0
    cal = load_scale_calibration(tmp_path / "scale.json")
    assert cal.run == str((tmp_path / "raw").resolve()) and cal.sequence == str(seq.resolve())
    monkeypatch.chdir(tmp_path.parent)  # elsewhere: the fitted sequence is still told
    assert any("fitted on this sequence" in p for p in calibration_use_problems(cal, seq))
    argv = ["run", str(seq), "-e", "phase-corr", "-o", str(tmp_path / "corrected")]
    assert floorvo_main([*argv, "--scale-calibration", str(tmp_path / "scale.json")]) == 0
    capsys.readouterr()
    assert (
        floorvo_main(["calibrate", str(tmp_path / "corrected"), "--gt", str(seq), "-o", str(tmp_path / "c2.json")]) == 1
    )
    assert "was run with a scale calibration (result.json): fit on runs made without one" in capsys.readouterr().err
    # a height 15 % off: scales of 1.15 are no calibration
    meta = json.loads((seq / "sequence.json").read_text())
    meta["rig"]["height_mm"] = 115.0
    (seq / "sequence.json").write_text(json.dumps(meta))
    assert floorvo_main(["run", str(seq), "-e", "phase-corr", "-o", str(tmp_path / "far")]) == 0
    with pytest.raises(Exception, match=r"the runs give scale_x = 1\.1\d+, outside \[0\.9, 1\.1\]"):
        calibrate_runs([(tmp_path / "far", seq)])
    assert not (tmp_path / "c2.json").exists()
    nameless = replace(cal, estimator="")
    assert any("names no estimator" in p for p in calibration_use_problems(nameless, tmp_path / "other"))

"""External estimators: a program run once per sequence (the shipped example, and small inline
programs that crash, time out, or write nothing or garbage), its configuration refusals, and
``floorvo run --external`` / ``--estimator-file``."""

from __future__ import annotations

import json
import os
import shlex
import shutil
import signal
import sys
import threading
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from floorvo.camera import CameraModel
from floorvo.cli import main as floorvo_main
from floorvo.errors import ConfigError, ExternalEstimatorError
from floorvo.external import ExternalEstimator, command_hash, load_estimator_file, parse_external, run_external
from floorvo.runfolder import RunFolder
from floorvo.synthetic import line_poses, write_synthetic_sequence
from floorvo.tum import read_tum

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "external-estimator"
CAM = CameraModel.from_sensor(160, 120, 29.6, 6.0)
PY = shlex.quote(sys.executable)


@pytest.fixture(scope="module")
def line_sequence(tmp_path_factory):
    """A synthetic sequence: 20 mm along x in 1.5 mm steps, with ground truth."""
    return write_synthetic_sequence(tmp_path_factory.mktemp("seq") / "line", CAM, line_poses(20.0, 1.5), seed=3)


def test_example_program_runs_and_its_run_is_placed_in_the_world_frame(line_sequence, tmp_path):
    spec = load_estimator_file(EXAMPLE / "fft-vo.toml")
    assert spec.name == "fft-vo" and spec.here == str(EXAMPLE) and spec.env == {"OMP_NUM_THREADS": "1"}
    assert spec.source.kind == "external" and spec.source.command_sha256 == command_hash(spec.command)
    res = run_external(line_sequence, spec, tmp_path / "run")
    assert (res.frames, res.placed, res.returncode) == (14, 14, 0)
    assert res.wall_s > 0 and 10 < res.peak_rss_mb < 4096  # a Python child with numpy and OpenCV
    run = RunFolder.read(tmp_path / "run")
    t_gt, T_gt = read_tum(line_sequence / "groundtruth.txt")
    np.testing.assert_allclose(run.timestamps_s, t_gt)
    # the program starts at the identity; its run starts at the first ground-truth pose
    np.testing.assert_allclose(run.T_world_cam[0], T_gt[0], atol=1e-6)
    assert abs(run.T_world_cam[-1, 0, 3] - T_gt[-1, 0, 3]) < 0.3  # 19.5 mm travelled
    assert list(run.statuses) == ["init"] + ["ok"] * 13
    assert run.result["source"]["kind"] == "external" and run.result["external"]["returncode"] == 0
    # the camera file it read is OpenCV's YAML with the rig height
    fs = cv2.FileStorage(str(tmp_path / "run" / "camera.yaml"), cv2.FILE_STORAGE_READ)
    np.testing.assert_allclose(fs.getNode("camera_matrix").mat(), CAM.K)
    assert fs.getNode("camera_height_mm").real() == 100.0


def _failing(code: str, **kw) -> ExternalEstimator:
    return ExternalEstimator(name="bad", command=(sys.executable, "-c", code, "{output}"), **kw)


def test_poses_within_the_bound_that_the_start_pose_moves_beyond_it_are_a_failed_run(line_sequence, tmp_path):
    """Each pose within 1e8 m of the program's origin (-9e7 m, then +9e7 m), but moved with the run
    to the start pose the second lies 1.8e8 m out: the trajectory's writer raised a traceback."""
    code = (
        "import sys, pathlib; lines = ['%.6f %.1f 0 0 0 0 0 1' % (i / 30, -9e7 if i == 0 else 9e7) for i in range(14)]; "
        "pathlib.Path(sys.argv[1], 'trajectory.txt').write_text(chr(10).join(lines) + chr(10))"
    )
    with pytest.raises(ExternalEstimatorError) as info:
        run_external(line_sequence, _failing(code), tmp_path / "run")
    assert info.value.reason.startswith(
        "pose 1 (t = 0.033333 s), moved with the run to the start pose, lies at a position 1.8e+08 m"
    )


def test_a_programs_own_result_json_is_kept_as_strict_json(line_sequence, tmp_path):
    """A program's result.json holding NaN and Infinity (Python's json writes them) was copied into
    RUN/result.json as they were, which a strict JSON parser refuses; they are null there now."""
    code = (
        "import sys, json, pathlib; out = pathlib.Path(sys.argv[1]); "
        "(out / 'trajectory.txt').write_text(pathlib.Path(sys.argv[2], 'groundtruth.txt').read_text()); "
        "(out / 'result.json').write_text(json.dumps(dict(x=float('nan'), y=[float('inf'), 1.5], z='a')))"
    )
    spec = ExternalEstimator(name="nan-result", command=(sys.executable, "-c", code, "{output}", "{sequence}"))
    run_external(line_sequence, spec, tmp_path / "run")
    text = (tmp_path / "run" / "result.json").read_text()
    kept = json.loads(text, parse_constant=lambda c: pytest.fail(f"{c} in result.json"))
    assert kept["external"]["program_result"] == {"x": None, "y": [None, 1.5], "z": "a"}


@pytest.mark.parametrize(
    ("code", "reason", "tail"),
    [
        ("import sys; print('boom: no features', file=sys.stderr); sys.exit(3)", "exit code 3", "boom: no features"),
        ("import os, signal; os.kill(os.getpid(), signal.SIGSEGV)", "killed by signal SIGSEGV", ""),
        ("print('nothing written')", "wrote no trajectory.txt into {output}", ""),
        (
            "import sys, pathlib; pathlib.Path(sys.argv[1], 'trajectory.txt').write_text('0 1 2\\n')",
            "malformed output:",
            "",
        ),
    ],
)
def test_a_failing_program_is_an_error_with_reason_and_stderr_tail(line_sequence, tmp_path, code, reason, tail):
    with pytest.raises(ExternalEstimatorError) as info:
        run_external(line_sequence, _failing(code), tmp_path / "run")
    assert info.value.reason.startswith(reason)
    assert info.value.stderr_tail == tail
    assert len(str(info.value).splitlines()) == 1
    assert not (tmp_path / "run" / "result.json").exists()  # no finished run is claimed


# A program that writes the sequence's ground truth with its times moved by ``shift`` s, plus
# ``extra`` poses 1/30 s apart after the last one.
_GT_COPY = (
    "import sys, pathlib; seq, out, shift, extra = sys.argv[1], sys.argv[2], float(sys.argv[3]), int(sys.argv[4]); "
    "ls = [l.split() for l in pathlib.Path(seq, 'groundtruth.txt').read_text().splitlines() if l[:1] != '#']; "
    "ls += [[str(float(ls[-1][0]) + (k + 1) / 30)] + ls[-1][1:] for k in range(extra)]; "
    "pathlib.Path(out, 'trajectory.txt').write_text(''.join('%.6f ' % (float(l[0]) + shift) + ' '.join(l[1:]) "
    "+ chr(10) for l in ls))"
)


@pytest.mark.parametrize(
    ("shift", "extra", "words"),
    [
        (0.0, 0, ""),
        (100.0, 0, "pose 0 at 100.000000 s is at no frame time of the sequence (nearest: frame 13 at 0.433333 s"),
        (0.02, 0, "pose 0 at 0.020000 s is at no frame time of the sequence (nearest: frame 1 at 0.033333 s"),
        (0.0, 3, "pose 14 at 0.4666"),  # 0.466666 or 7: three poses past the last frame
    ],
)
def test_poses_at_other_times_than_the_frames_are_a_failed_run(line_sequence, tmp_path, shift, extra, words):
    """A program's poses stamped 100 s late, between the frames or past the last frame were
    placed and scored as if they were the frames' (13 poses for 8 frames, exit code 0)."""
    spec = ExternalEstimator(
        name="copy", command=(sys.executable, "-c", _GT_COPY, "{sequence}", "{output}", str(shift), str(extra))
    )
    if not words:
        assert run_external(line_sequence, spec, tmp_path / "run").placed == 14
        return
    with pytest.raises(ExternalEstimatorError) as info:
        run_external(line_sequence, spec, tmp_path / "run")
    assert words in info.value.reason and info.value.reason.endswith("stamp each pose with its frame's time")
    if extra:
        assert "(nearest: frame 13 at 0.433333 s; 3 of 17 poses are more than 0.01 s from a frame)" in info.value.reason
    assert not (tmp_path / "run" / "result.json").exists()


# The ground truth as the trajectory (less its pose at frame `drop`, -1: none), and a timing.csv of
# the given rows (frame,status).
_GT_AND_TIMING = (
    "import sys, pathlib; seq, out, rows, drop = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4]); "
    "gt = [l for l in pathlib.Path(seq, 'groundtruth.txt').read_text().splitlines() if not l.startswith('#')]; "
    "pathlib.Path(out, 'trajectory.txt').write_text(chr(10).join(l for i, l in enumerate(gt) if i != drop) + chr(10)); "
    "pathlib.Path(out, 'timing.csv').write_text('frame,status' + chr(10) + rows.replace(';', chr(10)) + chr(10))"
)


def _rows(statuses: dict[int, str], frames: range = range(14)) -> str:
    return ";".join(f"{i},{statuses.get(i, 'init' if i == 0 else 'ok')}" for i in frames)


@pytest.mark.parametrize(
    ("rows", "drop", "words"),
    [
        (_rows({}), -1, ""),
        (_rows({4: "lost"}), 4, ""),
        (
            _rows({i: "lost" for i in range(1, 14)}),
            -1,
            "timing.csv marks frame(s) 1-13 lost, and trajectory.txt has a pose",
        ),
        (_rows({}, range(13)) + ";99,ok", -1, "frame 99 is past the sequence's last"),
        # rows for the first 3 frames only: scored as 3 of 3 frames tracked, 100 %
        (_rows({}, range(3)), 2, "11 of the sequence's 14 frames have no row (3-13)"),
        # frame 4 marked lost, a pose at its time and none at frame 7's: poses paired with the wrong steps
        (
            _rows({4: "lost"}),
            7,
            "marks frame(s) 7 init or ok, and trajectory.txt has no pose at their time; it marks frame(s) 4",
        ),
    ],
)
def test_a_timing_csv_that_does_not_fit_is_a_failed_run(line_sequence, tmp_path, rows, drop, words):
    """A program's timing.csv saying 13 of 14 frames lost beside 14 poses was scored as tracking
    7 % of a perfect trajectory, and one naming frame 99 of a 14-frame sequence was taken, exit 0;
    one with rows for its first 3 frames was scored as tracking 100 % (the ground truth cut to
    them), and one whose lost frame held the pose of another had its steps scored against the
    wrong ones."""
    spec = ExternalEstimator(
        name="t", command=(sys.executable, "-c", _GT_AND_TIMING, "{sequence}", "{output}", rows, str(drop))
    )
    if not words:
        assert run_external(line_sequence, spec, tmp_path / "run").placed == 14 - (drop >= 0)
        return
    with pytest.raises(ExternalEstimatorError) as info:
        run_external(line_sequence, spec, tmp_path / "run")
    assert words in info.value.reason and not (tmp_path / "run" / "result.json").exists()


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie has ended)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(")")[-1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def _ends_within(pid: int, seconds: float) -> bool:
    """Whether process ``pid`` has ended within ``seconds`` (killed here if it has not)."""
    deadline = time.monotonic() + seconds
    while _alive(pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    if _alive(pid):
        os.kill(pid, signal.SIGKILL)
        return False
    return True


# A program that starts a child (a sleep of 60 s), writes both pids into {output}, then either
# writes its trajectory (the ground truth) or sleeps 60 s itself first (argument "slow").
_PARENT = (
    "import sys, os, time, pathlib, subprocess; seq, out = sys.argv[1], sys.argv[2]; "
    "p = subprocess.Popen(['sleep', '60']); pathlib.Path(out, 'child.pid').write_text(str(p.pid)); "
    "pathlib.Path(out, 'own.pid').write_text(str(os.getpid())); "
    "time.sleep(60 if sys.argv[3:] == ['slow'] else 0); "
    "pathlib.Path(out, 'trajectory.txt').write_text(pathlib.Path(seq, 'groundtruth.txt').read_text())"
)


def test_what_a_program_leaves_running_ends_with_it(line_sequence, tmp_path):
    """A child the program started (here a sleep of 60 s) kept running after the run had ended."""
    spec = ExternalEstimator(name="parent", command=(sys.executable, "-c", _PARENT, "{sequence}", "{output}"))
    run_external(line_sequence, spec, tmp_path / "run")
    assert _ends_within(int((tmp_path / "run" / "program" / "child.pid").read_text()), 5.0)


class _Interrupt(Exception):
    pass


def test_an_interrupted_run_ends_the_program_and_what_it_started(line_sequence, tmp_path):
    """Interrupted while the program runs (here by a signal whose handler raises, as Ctrl-C's
    does), the run kills the program's process group before the interrupt goes on: started in a
    session of its own the program saw no Ctrl-C, outlived the interrupted run and wrote into
    the run folder after a rerun had filled it."""

    def interrupt(signum, frame):
        raise _Interrupt

    spec = ExternalEstimator(
        name="parent", command=(sys.executable, "-c", _PARENT, "{sequence}", "{output}", "slow"), timeout_s=0
    )
    program = tmp_path / "run" / "program"
    before = signal.signal(signal.SIGUSR1, interrupt)
    timer = threading.Timer(60.0, lambda: None)
    try:

        def send_when_started() -> None:
            deadline = time.monotonic() + 30.0
            while not (program / "own.pid").is_file() and time.monotonic() < deadline:
                time.sleep(0.02)
            os.kill(os.getpid(), signal.SIGUSR1)

        timer = threading.Timer(0.0, send_when_started)
        timer.start()
        started = time.monotonic()
        with pytest.raises(_Interrupt):
            run_external(line_sequence, spec, tmp_path / "run")
        assert time.monotonic() - started < 30.0
    finally:
        timer.join()
        signal.signal(signal.SIGUSR1, before)
    own, child = (int((program / f"{who}.pid").read_text()) for who in ("own", "child"))
    assert not _alive(own)  # killed and reaped before the interrupt went on
    assert _ends_within(child, 5.0)
    assert not (program / "trajectory.txt").exists()


def test_a_program_past_its_timeout_is_killed(line_sequence, tmp_path):
    spec = _failing("import time; time.sleep(30)", timeout_s=0.5)
    program = Path(sys.executable).name
    with pytest.raises(ExternalEstimatorError, match=rf"{program} timed out after 0\.5 s \(its timeout_s;") as info:
        run_external(line_sequence, spec, tmp_path / "run")
    assert info.value.reason.endswith("and was killed")


def test_a_hanging_program_without_timeout_s_is_killed_at_the_default_limit(line_sequence, tmp_path, monkeypatch):
    """A program given no ``timeout_s`` that never ends blocked the run (and a bench) for ever; it
    gets a limit scaled by the frame count, named in the error, and its children die with it."""
    import floorvo.external as external

    monkeypatch.setattr(external, "DEFAULT_TIMEOUT_START_S", 0.5)
    monkeypatch.setattr(external, "DEFAULT_TIMEOUT_PER_FRAME_S", 0.05)
    assert external.default_timeout_s(14) == pytest.approx(1.2)
    code = (
        "import sys, pathlib, subprocess, time; out = pathlib.Path(sys.argv[1]); "
        "p = subprocess.Popen(['sleep', '60']); (out / 'child.pid').write_text(str(p.pid)); "
        "(out / 'trajectory.txt').write_text('0.0 0 0'); time.sleep(60)"
    )
    spec = _failing(code)
    assert spec.timeout_s is None and spec.timeout_for(14) == pytest.approx(1.2)
    t0 = time.monotonic()
    with pytest.raises(ExternalEstimatorError) as info:
        run_external(line_sequence, spec, tmp_path / "run")
    assert time.monotonic() - t0 < 20
    program = Path(sys.executable).name
    assert info.value.reason == (
        f"{program} timed out after 1.2 s (the default limit for this sequence; set timeout_s in an estimator file, "
        "0 for no limit) and was killed"
    )
    assert len(str(info.value).splitlines()) == 1
    run = tmp_path / "run"
    assert not (run / "trajectory.txt").exists() and not (run / "result.json").exists()  # no run is claimed
    pid = int((run / "program" / "child.pid").read_text())
    deadline = time.monotonic() + 5.0
    while Path(f"/proc/{pid}").exists() and time.monotonic() < deadline:
        with open(f"/proc/{pid}/stat") as f:
            if f.read().split(")")[-1].split()[0] == "Z":
                break
        time.sleep(0.05)
    else:
        if Path(f"/proc/{pid}").exists():
            os.kill(pid, signal.SIGKILL)
            pytest.fail("the program's child outlived its timeout")


def test_timeout_s_zero_is_no_limit_and_a_given_one_is_kept():
    assert _failing("pass", timeout_s=0).timeout_for(10_000) is None
    assert _failing("pass", timeout_s=7.5).timeout_for(10_000) == 7.5
    assert _failing("pass").timeout_for(100) == 120.0 + 2.0 * 100


def test_needs_are_checked_before_the_program_runs(line_sequence, tmp_path):
    spec = ExternalEstimator(name="rgbd", command=(sys.executable, "-c", "raise SystemExit(9)"), needs=("depth",))
    with pytest.raises(Exception, match=r"rgbd needs depth images"):
        run_external(line_sequence, spec, tmp_path / "run")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('name = "x"\ncommand = []\n', r"x\.toml\.command = \[\]: must name a program"),
        ('name = "x"\ncommand = ["vo", "{seq}"]\n', r"unknown placeholder \{seq\} \(known: sequence, output"),
        ('name = "x"\ncommand = ["vo"]\ntimeout_s = -1\n', r"x\.toml\.timeout_s = -1\.0 s: must be >= 0 s"),
        # 1e10 s killed the timer thread (OverflowError: beyond time_t), and the program ran without a limit
        (
            'name = "x"\ncommand = ["vo"]\ntimeout_s = 1e10\n',
            r"x\.toml\.timeout_s = 10000000000\.0 s: must be <= 2592000\.0 s",
        ),
        ('name = "x"\ncommand = ["vo"]\nneeds = ["lidar"]\n', r"'lidar' must be one of depth, stereo"),
        ('name = "x"\ncommand = ["vo"]\nwhen = 3\n', r"x\.toml\.when: unknown key \(known: command, env"),
        ('name = "a b"\ncommand = ["vo"]\n', r"x\.toml\.name = 'a b': must be a non-empty name"),
        ('command = ["vo"]\n', r"x\.toml: name: missing"),
        ('name = "x"\ncommand = ["vo"]\n[env]\nN = 1\n', r"x\.toml\.env\.N = 1: must be a string"),
        ("name = ", r"x\.toml: not valid TOML"),
    ],
)
def test_estimator_file_refusals_name_the_key_and_the_rule(tmp_path, text, message):
    (tmp_path / "x.toml").write_text(text)
    with pytest.raises(ConfigError, match=message) as info:
        load_estimator_file(tmp_path / "x.toml")
    assert len(str(info.value).splitlines()) == 1


def test_external_argument_is_split_like_a_shell_and_hashed_as_given():
    spec = parse_external("my_vo --cam '{camera}' {sequence} {output}", "my-vo")
    assert spec.name == "my-vo" and spec.command == ("my_vo", "--cam", "{camera}", "{sequence}", "{output}")
    assert spec.source.detail == "sha256:" + command_hash(spec.command)[:12]
    assert command_hash(spec.command) != command_hash(("my_vo", "{sequence}", "{output}"))
    assert parse_external("/opt/vo/bin/my_vo {sequence}").name == "my_vo"
    # the {python} placeholder runs a script: the script names it ('--external.name = {python}' was refused)
    assert parse_external("{python} /opt/vo/fft_vo.py {sequence} {output}").name == "fft_vo"
    assert parse_external("{python} -u -m my_vo {sequence} {output}").name == "my_vo"
    with pytest.raises(ConfigError, match=r"^--external\.command argument '\{sequence': a brace without a placeholder"):
        parse_external("my_vo {sequence")
    # an empty command: `floorvo run --external ""` took it for no --external and crashed on a None file
    with pytest.raises(ConfigError, match=r"^--external '': an empty command: give the program and its arguments$"):
        parse_external("")


def test_floorvo_run_with_an_empty_external_command_is_refused_in_one_line(line_sequence, tmp_path, capsys):
    assert floorvo_main(["run", str(line_sequence), "--external", "", "-o", str(tmp_path / "r")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--external '': an empty command" in err[0], err


def test_floorvo_run_external_and_estimator_file(line_sequence, tmp_path, capsys):
    cmd = f"{PY} {shlex.quote(str(EXAMPLE / 'fft_vo.py'))} {{sequence}} {{output}} {{camera}}"
    assert floorvo_main(["run", str(line_sequence), "--external", cmd, "-o", str(tmp_path / "a")]) == 0
    assert "14 placed" in capsys.readouterr().out
    f = str(EXAMPLE / "fft-vo.toml")
    assert floorvo_main(["run", str(line_sequence), "--estimator-file", f, "-o", str(tmp_path / "b")]) == 0
    a, b = RunFolder.read(tmp_path / "a"), RunFolder.read(tmp_path / "b")
    np.testing.assert_array_equal(a.T_world_cam, b.T_world_cam)
    # a crash is one line and exit code 1
    crash = f"{PY} -c 'import sys; sys.exit(4)'"
    assert floorvo_main(["run", str(line_sequence), "--external", crash, "-o", str(tmp_path / "c")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].endswith("exit code 4")


def test_floorvo_run_exits_1_when_nothing_after_the_first_frame_was_tracked(line_sequence, tmp_path, capsys):
    # blank frames: AKAZE finds no keypoint, so every frame after the first is lost
    blank = tmp_path / "blank"
    write_synthetic_sequence(blank, CAM, line_poses(3.0, 1.5), seed=1)
    for f in (blank / "cam0").glob("*.png"):
        cv2.imwrite(str(f), np.zeros((CAM.height_px, CAM.width_px), np.uint8))
    rc = floorvo_main(["run", str(blank), "-e", "akaze-guided", "-o", str(tmp_path / "r")])
    captured = capsys.readouterr()
    assert rc == 1
    assert "tracked no frame after the first" in captured.err and len(captured.err.strip().splitlines()) == 1
    assert json.loads((tmp_path / "r" / "result.json").read_text())["ok"] == 0


def test_floorvo_plot_draws_runs_against_ground_truth(line_sequence, tmp_path, capsys):
    spec = load_estimator_file(EXAMPLE / "fft-vo.toml")
    run_external(line_sequence, spec, tmp_path / "a")
    png = tmp_path / "plot.png"
    assert floorvo_main(["plot", str(tmp_path / "a"), "--gt", str(line_sequence), "-o", str(png)]) == 0
    img = cv2.imread(str(png))
    assert img is not None and img.shape[0] > img.shape[1]  # two panels, one above the other
    # a ground truth that shares no time with the run is refused in one line
    other = write_synthetic_sequence(tmp_path / "late", CAM, line_poses(3.0, 1.5), seed=2, fps=7.0)
    t, T = read_tum(other / "groundtruth.txt")
    (other / "groundtruth.txt").write_text(
        "".join(f"{ti + 1000.0:.6f} 0 0 0.1 1 0 0 0\n" for ti in t)  # the same poses' count, 1000 s later
    )
    capsys.readouterr()  # (its file: the folder is another sequence than the run's, refused before)
    assert floorvo_main(["plot", str(tmp_path / "a"), "--gt", str(other / "groundtruth.txt"), "-o", str(png)]) == 1
    assert "shares two timestamps" in capsys.readouterr().err


def test_floorvo_plot_takes_its_title_as_typed_tells_runs_apart_and_writes_the_format_asked(
    line_sequence, tmp_path, capsys, monkeypatch
):
    """A title with '$...$' was read as math and raised from inside matplotlib (a 61-line
    traceback); two runs of one estimator had one legend entry; '-o out.pdf' wrote PNG bytes."""
    from floorvo.plots import load_plot_run, run_styles

    spec = load_estimator_file(EXAMPLE / "fft-vo.toml")
    run_external(line_sequence, spec, tmp_path / "a")
    shutil.copytree(tmp_path / "a", tmp_path / "b")
    png = tmp_path / "plot.png"
    argv = ["plot", str(tmp_path / "a"), str(tmp_path / "b"), "--gt", str(line_sequence), "--title", "drift $x_$"]
    import floorvo.plots as plots

    drawn, draw = [], plots.draw_trajectories
    monkeypatch.setattr(plots, "draw_trajectories", lambda ax, runs, ref: drawn.extend(runs) or draw(ax, runs, ref))
    assert floorvo_main([*argv, "-o", str(png)]) == 0, capsys.readouterr().err
    assert [r.label for r in drawn] == [f"fft-vo ({tmp_path / 'a'})", f"fft-vo ({tmp_path / 'b'})"]
    assert cv2.imread(str(png)) is not None
    assert load_plot_run(tmp_path / "a").label == "fft-vo"
    pdf = tmp_path / "plot.pdf"
    assert floorvo_main([*argv, "-o", str(pdf)]) == 0 and pdf.read_bytes().startswith(b"%PDF")
    capsys.readouterr()
    assert floorvo_main([*argv, "-o", str(tmp_path / "plot.jpeg")]) == 1
    assert "plot.jpeg: the plot is written as png, pdf, svg, by the file's suffix" in capsys.readouterr().err
    styles = run_styles(25)  # beyond ten runs matplotlib's cycle drew two alike
    assert len({(tuple(c), ls) for c, ls in styles}) == 25


def test_score_warns_instead_of_scoring_a_run_outside_the_ground_truth_frame(line_sequence, tmp_path, capsys):
    from floorvo.scoring import score_run

    # a run started at --initial-pose 50 mm away: the unaligned figures are left out with a warning
    assert (
        floorvo_main(
            ["run", str(line_sequence), "-e", "phase-corr", "-o", str(tmp_path / "r"), "--initial-pose", "50,0,0"]
        )
        == 0
    )
    score = score_run(tmp_path / "r", line_sequence)
    assert score.warnings and "starts 50.0 mm from the ground truth" in score.warnings[0]
    flat = score.flat()
    assert "end_drift_pct" not in flat and "ate_none_rmse_mm" not in flat
    assert flat["ate_se2_rmse_mm"] < 0.2  # the aligned ATE still measures the estimator
    # a run whose times share nothing with the ground truth: tracking only, and it says why
    shifted = shutil.copytree(line_sequence, tmp_path / "shifted")
    t, T = read_tum(line_sequence / "groundtruth.txt")
    from floorvo.tum import write_tum

    write_tum(shifted / "groundtruth.txt", t + 1000.0, T)
    score = score_run(tmp_path / "r", shifted / "groundtruth.txt")
    assert score.ground_truth.startswith("the estimate shares no timestamp with the ground truth")
    assert "ate_se2_rmse_mm" not in score.flat() and score.flat()["tracked_fraction"] == 1.0
    gt_file = str(shifted / "groundtruth.txt")
    assert floorvo_main(["score", str(tmp_path / "r"), "--gt", gt_file, "-o", str(tmp_path / "s.json")]) == 0
    assert "accuracy (ATE, RPE, drift, segments): the estimate shares no timestamp" in capsys.readouterr().out
    # in its sequence folder that ground truth is refused (a pose per frame, not at the frames' times),
    # as `floorvo run` refuses it: scoring reads it through the sequence (Sequence.groundtruth)
    assert floorvo_main(["score", str(tmp_path / "r"), "--gt", str(shifted), "-o", str(tmp_path / "s.json")]) == 1
    assert "the frame times and the ground truth disagree" in capsys.readouterr().err
    # the same with a bare TUM file as the ground truth: it read sequence.json beside no folder and failed
    bare = tmp_path / "bare"
    bare.mkdir()
    write_tum(bare / "trajectory.txt", *read_tum(tmp_path / "r" / "trajectory.txt"))
    assert floorvo_main(["score", str(bare), "--gt", str(shifted / "groundtruth.txt")]) == 0
    score = score_run(bare, shifted / "groundtruth.txt")
    assert score.flat()["tracked_fraction"] == 1.0 and "of groundtruth.txt" in score.warnings[0]


def test_initial_pose_is_a_floor_pose_or_a_tum_line():
    from floorvo.geometry import T_from_se2
    from floorvo.run import InitialPose

    np.testing.assert_allclose(InitialPose.parse("12.5,-3,0.25").T_world_cam(80.0), T_from_se2(12.5, -3.0, 0.25, 80.0))
    assert InitialPose.parse("0 500000 5e6 0 0 0 0 1").T_full is not None  # UTM easting and northing, metres
    # a TUM line, with or without its timestamp (metres; qx qy qz qw): the downward camera at (0.1 m, 0, 0.08 m)
    for text in ("0.1 0 0.08 1 0 0 0", "42.0 0.1 0 0.08 1 0 0 0"):
        T = InitialPose.parse(text).T_world_cam(None)
        np.testing.assert_allclose(T, T_from_se2(100.0, 0.0, 0.0, 80.0), atol=1e-12)
    # "0 1e306 ...": metres that overflow to inf in mm (a run ended in 'SVD did not converge')
    # 1e308 mm / 1.1e8 m: finite, but every step vanished in rounding and the TUM lines held 300 digits
    for bad in ("1,2", "a,b,c", "0 0 0 0 0 0 0", "1,2,nan", "0 1e306 0 0 0 0 0 1", "1e308,0,0", "0 0 1.1e8 0 0 0 0 1"):
        with pytest.raises(ConfigError, match=r"^--initial-pose .*: expected x_mm,y_mm,yaw_rad"):
            InitialPose.parse(bad)


# The ground truth as the trajectory, after holding `mb` MiB for 0.3 s; run as `sh -c` with
# `wrap`, the shell starts it as a child of its own (a command after it: no exec).
_HOLDING = (
    "import sys, time, pathlib; import numpy as np; a = np.ones(int(sys.argv[3]) * 2**20, np.uint8); time.sleep(0.3); "
    "pathlib.Path(sys.argv[2], 'trajectory.txt').write_text(pathlib.Path(sys.argv[1], 'groundtruth.txt').read_text())"
)


@pytest.mark.skipif(not Path("/proc/self/status").is_file(), reason="reads /proc")
@pytest.mark.parametrize(("mb", "wrap"), [(0, False), (150, False), (150, True)])
def test_a_programs_peak_memory_is_its_own(line_sequence, tmp_path, mb, wrap):
    """A program's peak memory was the ru_maxrss of its wait4, which counts the memory of the
    process that started it (carried over the exec): a 2 MiB program read as the bench's 112-500
    MiB. Here the test process holds 250 MiB while it runs a program holding 0 or 150."""
    held = np.ones(250 * 2**20, np.uint8)  # this process's memory, which the program's must not show
    cmd = (sys.executable, "-c", _HOLDING, "{sequence}", "{output}", str(mb))
    if wrap:
        cmd = ("sh", "-c", shlex.join(cmd) + "; true")
    res = run_external(line_sequence, ExternalEstimator(name="m", command=cmd), tmp_path / "run")
    assert held.sum() == held.size and res.placed == 14
    assert mb + 5 < res.peak_rss_mb < mb + 150  # a Python child with numpy: some tens of MiB besides
    assert json.loads((tmp_path / "run" / "result.json").read_text())["peak_rss_mb"] == res.peak_rss_mb


def test_a_python_run_into_a_programs_run_folder_leaves_none_of_the_programs_files(line_sequence, tmp_path):
    """The program's folder, camera file and output streams stayed beside a result.json that
    named the Python estimator written there after it; what else the program wrote stays."""
    from floorvo.run import run_estimator

    code = (
        "import sys, pathlib; out = pathlib.Path(sys.argv[1]); (out / 'model.bin').write_bytes(b'x'); "
        "(out / 'trajectory.txt').write_text(pathlib.Path(sys.argv[2], 'groundtruth.txt').read_text())"
    )
    spec = ExternalEstimator(name="prog", command=(sys.executable, "-c", code, "{output}", "{sequence}"))
    run = tmp_path / "run"
    run_external(line_sequence, spec, run)
    assert {"camera.yaml", "stdout.txt", "stderr.txt", "program"} <= {p.name for p in run.iterdir()}
    run_estimator(line_sequence, "phase-corr", run)
    assert sorted(p.name for p in run.iterdir() if not p.name.startswith(".")) == [
        "program",
        "result.json",
        "timing.csv",
        "trajectory.txt",
    ]
    assert sorted(p.name for p in (run / "program").iterdir()) == ["model.bin"]  # the program's own, kept

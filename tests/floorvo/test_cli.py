"""Flags mean the same in every command of both CLIs: -o/--output (with --out accepted),
-v/-q before or after the subcommand (and -v gives debug logging), help without stray %%."""

import argparse
import logging

import pytest

from floorsim import __version__ as floorsim_version
from floorsim.cli import COMMANDS as FLOORSIM_COMMANDS
from floorsim.cli import main as floorsim_main
from floorvo import __version__ as floorvo_version
from floorvo.camera import CameraModel
from floorvo.cli import COMMANDS as FLOORVO_COMMANDS
from floorvo.cli import build_parser
from floorvo.cli import main as floorvo_main
from floorvo.synthetic import line_poses, write_synthetic_sequence

PARSERS = {
    "floorvo": lambda: build_parser("floorvo", "floorvo.cli", FLOORVO_COMMANDS, "", floorvo_version),
    "floorsim": lambda: build_parser("floorsim", "floorsim.commands", FLOORSIM_COMMANDS, "", floorsim_version),
}


def _commands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(sub.choices)


@pytest.mark.parametrize("prog", sorted(PARSERS))
def test_help_of_every_command_is_clean_and_names_output_the_same_way(prog):
    parser = PARSERS[prog]()
    texts = {"": parser.format_help()}
    texts.update({name: p.format_help() for name, p in _commands(parser).items()})
    with_output = set()
    for name, text in texts.items():
        assert "%%" not in text, (prog, name)
        assert "--out " not in text and "--out," not in text, (prog, name)  # the alias stays hidden
        if "--output" in text:
            with_output.add(name)
            assert "-o OUTPUT, --output OUTPUT" in text or "-o FILE, --output FILE" in text, (prog, name, text)
        if name:
            assert "-v, --verbose" in text and "-q, --quiet" in text, (prog, name)
    assert (
        with_output
        == {
            "floorvo": {"run", "score", "plot", "calibrate", "map", "localize", "import"},
            "floorsim": {"render", "bench", "sweep", "export", "gallery"},
        }[prog]
    )


@pytest.mark.parametrize("prog", sorted(PARSERS))
def test_out_is_an_alias_of_output_in_every_command_that_writes(prog):
    parser = PARSERS[prog]()
    positional = {
        "run": ["SEQ", "-e", "phase-corr"],
        "score": ["RUN", "--gt", "SEQ"],
        "calibrate": ["RUN", "--gt", "SEQ"],
        "plot": ["RUN", "--gt", "SEQ"],
    }
    positional |= {"map": ["SEQ"], "localize": ["SEQ", "--map", "MAP"], "render": ["demo"], "bench": ["s.toml"]}
    positional |= {"sweep": ["w.toml"], "export": ["SEQ", "--format", "euroc"], "gallery": [], "import": ["SRC"]}
    for name, sub in _commands(parser).items():
        if not any(a.dest == "output" for a in sub._actions):
            continue
        for flag in ("-o", "--output", "--out"):
            args = parser.parse_args([name, *positional[name], flag, "x/y"])
            assert str(args.output) == "x/y", (prog, name, flag)


def _debug_records(caplog):
    return [r for r in caplog.records if r.levelno == logging.DEBUG and r.name.startswith(("floorvo", "floorsim"))]


@pytest.mark.parametrize("main", [floorvo_main, floorsim_main])
def test_verbose_before_or_after_the_command_turns_on_debug_logging(main, caplog, capsys):
    caplog.set_level(logging.DEBUG)  # the handler takes all; the CLI sets its packages' levels
    for argv in (["-v", "list"], ["list", "-v"], ["list", "--verbose"]):
        caplog.clear()
        assert main(argv) == 0
        assert _debug_records(caplog), argv
    caplog.clear()
    assert main(["list"]) == 0
    assert not _debug_records(caplog)
    # the levels are the process's own again after the command
    assert logging.getLogger("floorvo").level == logging.NOTSET and logging.getLogger("floorsim").level == 0


def test_quiet_after_the_command_keeps_only_warnings(tmp_path, caplog, capsys):
    caplog.set_level(logging.DEBUG)
    cam = CameraModel.from_sensor().scaled(0.25)
    seq = write_synthetic_sequence(tmp_path / "seq", cam, line_poses(8.0, 4.0), seed=0)
    for argv, info in (([], True), (["-q"], False), (["--quiet"], False)):
        caplog.clear()
        assert floorvo_main(["run", str(seq), "-e", "phase-corr", "--out", str(tmp_path / "run"), *argv]) == 0
        logged = [r for r in caplog.records if r.name.startswith("floorvo") and r.levelno == logging.INFO]
        assert bool(logged) == info, argv


@pytest.mark.parametrize(
    "argv, words",
    [
        (["floorvo", "import", "SRC", "-o", "OUT", "--topic", "image=/a", "--topic", "image=/b"], "--topic 'image=/b'"),
        (["floorsim", "bench", "SRC", "-o", "OUT", "--external", "a=x {output}", "--external", "a=y {output}"], "'a'"),
        (
            [
                "floorsim",
                "bench",
                "SRC",
                "-o",
                "OUT",
                "--scale-calibration",
                "e=1.json",
                "--scale-calibration",
                "e=2.json",
            ],
            "--scale-calibration 'e=2.json'",
        ),
    ],
)
def test_a_name_given_twice_in_name_value_options_is_refused(tmp_path, monkeypatch, capsys, argv, words):
    """--external a=CMD1 --external a=CMD2 ran CMD2 alone, --topic image=A --topic image=B read B:
    the last one was taken silently."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "SRC").mkdir()
    main = {"floorvo": floorvo_main, "floorsim": floorsim_main}[argv[0]]
    assert main(argv[1:]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err and "is given twice" in err, err
    assert not (tmp_path / "OUT").exists()


def test_a_path_that_is_not_utf8_is_printed_escaped_by_run_and_score(tmp_path):
    """Under a C or C.UTF-8 locale Python's standard output lets a lone surrogate through as its raw
    byte (surrogateescape): floorvo run and score printed the byte 0xff of an output folder's name
    in their summaries, where the README promises the escape \\udcff."""
    import os
    import subprocess
    from pathlib import Path

    from _procs import child_env, cli

    cam = CameraModel.from_sensor().scaled(0.1)
    seq = write_synthetic_sequence(tmp_path / "seq", cam, line_poses(8.0, 4.0), seed=0)
    run = Path(os.fsdecode(bytes(tmp_path) + b"/\xff")) / "run"
    env = {**child_env(), "PYTHONIOENCODING": "utf-8:surrogateescape"}  # as a C locale sets it
    for argv in (["run", str(seq), "-e", "phase-corr", "-o", str(run)], ["score", str(run), "--gt", str(seq)]):
        r = subprocess.run([*cli("floorvo"), "-q", *argv], capture_output=True, env=env)
        assert r.returncode == 0, r.stderr
        assert b"\xff" not in r.stdout and b"/\\udcff/run" in r.stdout, r.stdout


def _truncated_png_sequence(tmp_path):
    """A synthetic sequence whose frame 1 is cut short (its PNG stops mid-stream)."""
    cam = CameraModel.from_sensor().scaled(0.1)
    seq = write_synthetic_sequence(tmp_path / "seq", cam, line_poses(8.0, 4.0), seed=0)
    frame = seq / "cam0" / "000001.png"
    frame.write_bytes(frame.read_bytes()[:300])
    return seq, frame


@pytest.mark.parametrize("prog", ["floorvo", "floorsim"])
def test_a_truncated_png_is_one_line_without_opencvs_warning(tmp_path, capfd, prog):
    """OpenCV printed '[ WARN:0@0.29] global grfmt_png.cpp:793 ... PNG input buffer is incomplete'
    on standard error before the CLI's one-line error. The CLIs silence OpenCV's own log while a
    command runs, and give its level back after (a library user keeps OpenCV's defaults)."""
    import cv2

    seq, frame = _truncated_png_sequence(tmp_path)
    level = cv2.utils.logging.getLogLevel()
    if prog == "floorvo":
        assert floorvo_main(["run", str(seq), "-e", "phase-corr", "-o", str(tmp_path / "run")]) == 1
    else:
        assert floorsim_main(["export", str(seq), "--format", "euroc", "-o", str(tmp_path / "euroc")]) == 1
    err = capfd.readouterr().err
    assert err.splitlines() == [f"{prog}: error: {frame}: not a readable PNG (corrupt or truncated)"], err
    assert cv2.utils.logging.getLogLevel() == level


def _video(path, n=5, codec="mp4v"):
    import cv2
    import numpy as np

    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*codec), 10, (64, 48), False)
    for i in range(n):
        writer.write(np.random.default_rng(i).integers(0, 255, (48, 64), np.uint8))
    writer.release()
    return path


def test_a_truncated_video_is_one_line_with_ffmpegs_reason_and_v_logs_it(tmp_path):
    """FFmpeg printed '[mov,mp4,m4a,3gp,3g2,mj2 @ 0x...] moov atom not found' before the one-line
    error; the reader takes FFmpeg's messages and gives the reason in its own line."""
    import subprocess

    from _procs import child_env, cli

    video = _video(tmp_path / "clip.mp4")
    video.write_bytes(video.read_bytes()[:2000])  # the index (moov) at the end is gone
    env = {k: v for k, v in child_env().items() if k != "OPENCV_FFMPEG_LOGLEVEL"}
    argv = ["import", str(video), "-o", str(tmp_path / "rec"), "--fx", "100", "--fy", "100", "--cx", "32", "--cy", "24"]
    r = subprocess.run([*cli("floorvo"), *argv], capture_output=True, text=True, env=env)
    assert r.returncode == 1 and r.stderr.splitlines() == [
        f"floorvo: error: {video}: not a video OpenCV can decode (FFmpeg: [mov,mp4,m4a,3gp,3g2,mj2] moov atom not found)"
    ], r.stderr
    r = subprocess.run([*cli("floorvo"), "-v", *argv], capture_output=True, text=True, env=env)
    assert r.returncode == 1 and "FFmpeg: [mov,mp4,m4a,3gp,3g2,mj2] moov atom not found" in r.stderr, r.stderr


def test_a_video_cut_inside_its_last_frame_is_refused_naming_the_frame(tmp_path, capfd):
    """An MJPEG video whose end was cut inside its last frame imported 5 frames with exit code 0,
    the last half decoded; FFmpeg's 'overread' on standard error was the only sign."""
    from floorvo.cli import main

    video = _video(tmp_path / "clip.avi", codec="MJPG")
    whole = video.read_bytes()
    argv = ["--fx", "100", "--fy", "100", "--cx", "32", "--cy", "24"]
    assert main(["import", str(video), "-o", str(tmp_path / "ok"), *argv]) == 0  # the whole file imports
    capfd.readouterr()
    video.write_bytes(whole[:-400])  # into the last frame's JPEG (the index after it is gone too)
    assert main(["import", str(video), "-o", str(tmp_path / "cut"), *argv]) == 1
    err = capfd.readouterr().err.splitlines()
    assert len(err) == 1 and f"{video}: frame 4 did not decode cleanly (FFmpeg: [mjpeg] " in err[0], err
    assert "1 of its 5 frames gave decoder errors: the file is damaged or truncated" in err[0]
    assert not (tmp_path / "cut").exists()


#: The console script (floorvo.launch / floorsim.launch) with a signal sent to itself the moment the
#: module ``argv[2]`` is imported, while the CLI loads.
_SIGNAL_WHILE_LOADING = """
import os, signal, sys
sig, target, prog = getattr(signal, sys.argv[1]), sys.argv[2], sys.argv[3]
class Hook:
    fired = False
    def find_spec(self, name, path=None, target_=None):
        if name == target and not Hook.fired:
            Hook.fired = True
            os.kill(os.getpid(), sig)
        return None
sys.meta_path.insert(0, Hook())
sys.argv = [prog, "list"]
if prog == "floorsim":
    from floorsim.launch import main
else:
    from floorvo.launch import floorvo_main as main
sys.exit(main())
"""


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
@pytest.mark.parametrize(("prog", "module"), [("floorvo", "floorvo.cli.score"), ("floorsim", "cv2")])
def test_an_interrupt_while_the_cli_loads_is_one_line(sig, prog, module):
    """A Ctrl-C in the 0.1-0.5 s a CLI takes to import its modules and build its parser was
    Python's KeyboardInterrupt traceback (exit code -2), a SIGTERM an end without a word."""
    import signal
    import subprocess
    import sys

    from _procs import child_env

    r = subprocess.run(
        [sys.executable, "-c", _SIGNAL_WHILE_LOADING, sig, module, prog],
        capture_output=True,
        text=True,
        env=child_env(),
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # as a terminal's foreground job
    )
    how = "interrupted (SIGTERM)" if sig == "SIGTERM" else "interrupted"
    assert r.returncode == 128 + getattr(signal, sig), r.stderr
    assert r.stderr.splitlines() == [f"{prog}: {how}; what was written is kept, run the same command again to resume"]

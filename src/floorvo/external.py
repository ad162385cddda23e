"""External estimators: a program, any language, run once per sequence folder.

An external estimator is a command line (an :class:`ExternalEstimator`, validated by the one
configuration mechanism, :mod:`floorvo.config`), given as ``--external NAME=CMD`` or in a
TOML file passed with ``--estimator-file FILE``::

    name = "my-vo"
    command = ["my_vo", "{sequence}", "{output}", "--camera", "{camera}"]
    timeout_s = 600            # optional: killed after this long (a failed run); 0: no limit
    needs = ["depth"]          # optional: what the sequence must have (depth, stereo)
    [env]                      # optional: added to the program's environment
    OMP_NUM_THREADS = "1"

:func:`run_external` fills the placeholders (:data:`PLACEHOLDERS`: the sequence folder, the
folder the program writes into, a camera file in OpenCV YAML, ...), runs the program in a
process group of its own (what it leaves running there is killed when it ends), and expects
``{output}/trajectory.txt`` (TUM: seconds and metres,
``T_world_cam``, one line per frame it placed, stamped with the sequence's frame times) and
optionally ``{output}/timing.csv`` (the run folder's columns, ``frame`` at least: a row for each
frame of the sequence, those it did not track with status ``lost``). It records
the wall time and the program's peak resident memory (:class:`floorvo.memory.PeakRss`).

The program's poses are taken relative to its first one and placed at the run's start pose:
the ground-truth pose at the time of its first pose when the sequence has ground truth,
else ``T_world_start`` (``--initial-pose``), else the identity; so a program may start at the
identity, as odometry does, and its run is in the ground truth's world frame like every run.
The run folder (``RUN/trajectory.txt``, ``timing.csv``, ``result.json``) is written through
:class:`floorvo.runfolder.RunFolder`; what the program wrote stays in ``RUN/program/``, its
standard output and error in ``RUN/stdout.txt`` and ``RUN/stderr.txt``.

A crash, a non-zero exit, a timeout, a missing or malformed trajectory (one whose times do
not increase, or a pose at no frame time of the sequence: not within
:data:`~floorvo.sequence.GROUNDTRUTH_MAX_DIFF_S` of one), a ``timing.csv`` that does not fit
the sequence or the trajectory (:func:`_timing_problem`) is an
:class:`~floorvo.errors.ExternalEstimatorError` whose ``reason`` and ``stderr_tail`` the bench
writes into a ``failed`` row.

A program without ``timeout_s`` gets a default limit (:func:`default_timeout_s`):
:data:`DEFAULT_TIMEOUT_START_S` for its start-up plus :data:`DEFAULT_TIMEOUT_PER_FRAME_S` per
frame of the sequence, generous for a compiled program (tens of milliseconds a frame) and for a
slow one with bundle adjustment (about a second a frame), so that a program that hangs fails its
run instead of blocking a bench for ever. ``timeout_s = 0`` runs it without a limit. At the limit
its process group gets SIGTERM, then SIGKILL 2 s later; the run folder gets no ``trajectory.txt``
or ``result.json`` (what the program had written stays in ``RUN/program/``).
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import shlex
import signal
import string
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from floorvo.config import Config, build, param
from floorvo.errors import (
    ConfigError,
    ConfigFieldError,
    ExternalEstimatorError,
    FloorbenchError,
    SequenceError,
    shown,
    shown_number,
)
from floorvo.estimators.base import NEEDS
from floorvo.estimators.registry import EstimatorSource
from floorvo.geometry import MAX_POSITION_MM, position_problem
from floorvo.io import atomic_write_text, ensure_writable_dir, read_toml, strict_json
from floorvo.locking import locks_folder
from floorvo.memory import PeakRss
from floorvo.metrics import associate
from floorvo.runfolder import (
    PROGRAM_CAMERA,
    PROGRAM_DIR,
    PROGRAM_STDERR,
    PROGRAM_STDOUT,
    SEQUENCE_SHA256,
    RunFolder,
    remove_run_files,
    sequence_sha256,
)
from floorvo.sequence import GROUNDTRUTH_MAX_DIFF_S, Sequence

__all__ = [
    "PLACEHOLDERS",
    "NEEDS",
    "ExternalEstimator",
    "ExternalRun",
    "command_hash",
    "default_timeout_s",
    "load_estimator_file",
    "parse_external",
    "run_external",
]

log = logging.getLogger(__name__)

#: What a command's ``{placeholder}`` is replaced with.
PLACEHOLDERS: dict[str, str] = {
    "sequence": "the sequence folder (sequence.json, cam0/, ...)",
    "output": "the folder the program writes trajectory.txt (and timing.csv) into: RUN/program",
    "camera": "the left (or only) camera in OpenCV calibration YAML, with camera_height_mm: RUN/camera.yaml",
    "images": "the folder of the left (or only) camera's frames: SEQUENCE/cam0",
    "height_mm": "the camera height above the floor, mm",
    "fps": "the sequence's frame rate, frames per second",
    "frames": "the number of frames",
    "here": "the folder of the --estimator-file (for --external: the folder the command was given in)",
    "python": "the Python interpreter floorbench runs in (sys.executable)",
}
#: The default time limit of a program without ``timeout_s``: this much for its start-up ...
DEFAULT_TIMEOUT_START_S = 120.0
#: ... plus this much per frame of the sequence (see the module doc).
DEFAULT_TIMEOUT_PER_FRAME_S = 2.0
#: The longest ``timeout_s``, s (30 days; 0 is no limit): 1e10 s killed the timer thread with an
#: OverflowError (beyond the platform's time_t), and the program then ran without a limit.
MAX_TIMEOUT_S = 30 * 86400.0
#: Lines of the program's standard error kept for a failed row.
STDERR_TAIL_LINES = 5
_NAME_CHARS = set(string.ascii_letters + string.digits + "-_.+")


def _placeholders(arg: str) -> list[str]:
    """The ``{name}`` fields of one argument (ValueError for a stray brace)."""
    return [f for _, f, _, _ in string.Formatter().parse(arg) if f is not None]


@dataclass(frozen=True)
class ExternalEstimator(Config):
    """An estimator that is a program (see the module doc); ``--estimator-file`` holds its fields."""

    config_name = "external"
    name: str = param("", doc="the estimator's name in results (letters, digits, - _ . +)")
    command: tuple[str, ...] = param(
        (), doc="program and arguments; placeholders: " + ", ".join("{" + k + "}" for k in PLACEHOLDERS)
    )
    timeout_s: float | None = param(
        None,
        unit="s",
        min=0,
        max=MAX_TIMEOUT_S,
        doc=f"kill the program after this long (a failed run); default {DEFAULT_TIMEOUT_START_S:g} s + "
        f"{DEFAULT_TIMEOUT_PER_FRAME_S:g} s per frame; 0: no limit",
    )
    env: dict[str, str] = param(default_factory=dict, doc="environment variables added for the program")
    needs: tuple[str, ...] = param((), doc="what the sequence must have besides mono frames: depth, stereo")
    here: str = param("", doc="the folder {here} stands for (default: the estimator file's folder)")

    def validate(self) -> None:
        if not self.name or not set(self.name) <= _NAME_CHARS:
            raise ConfigFieldError("name", f" = {self.name!r}: must be a non-empty name of letters, digits, - _ . +")
        if not self.command or not self.command[0].strip():
            raise ConfigFieldError("command", f" = {list(self.command)!r}: must name a program (a non-empty list)")
        for arg in self.command:
            try:
                fields = _placeholders(arg)
            except ValueError:
                raise ConfigFieldError(
                    "command", f" argument {arg!r}: a brace without a placeholder (write {{{{ for a brace)"
                ) from None
            for f in fields:
                if f not in PLACEHOLDERS:
                    raise ConfigFieldError(
                        "command", f" argument {arg!r}: unknown placeholder {{{f}}} (known: {', '.join(PLACEHOLDERS)})"
                    )
        for key, value in self.env.items():
            if not isinstance(value, str):
                raise ConfigFieldError(f"env.{key}", f" = {shown(value)}: must be a string")
        for n in self.needs:
            if n not in NEEDS:
                raise ConfigFieldError("needs", f" = {list(self.needs)!r}: {n!r} must be one of {', '.join(NEEDS)}")

    def timeout_for(self, frames: int) -> float | None:
        """The time limit of a run over ``frames`` frames, s: ``timeout_s``, else
        :func:`default_timeout_s`; None for ``timeout_s = 0`` (no limit)."""
        if self.timeout_s is None:
            return default_timeout_s(frames)
        return None if self.timeout_s == 0 else float(self.timeout_s)

    @property
    def requires(self) -> frozenset[str]:
        """What the sequence must have besides mono frames (as an estimator's ``requires``)."""
        return frozenset(self.needs)

    @property
    def source(self) -> EstimatorSource:
        """``external`` with the command line and its hash (:func:`command_hash`)."""
        return EstimatorSource("external", shlex.join(self.command), command_sha256=command_hash(self.command))


def default_timeout_s(frames: int) -> float:
    """The time limit of a program without ``timeout_s`` on a sequence of ``frames`` frames, s."""
    return DEFAULT_TIMEOUT_START_S + DEFAULT_TIMEOUT_PER_FRAME_S * max(int(frames), 0)


def command_hash(command: tuple[str, ...] | list[str]) -> str:
    """Hex SHA-256 of a command line as given (placeholders unfilled, so every sequence's run of one
    estimator has the same hash): of the JSON list of its arguments."""
    return hashlib.sha256(json.dumps(list(command)).encode()).hexdigest()


def load_estimator_file(path: str | os.PathLike) -> ExternalEstimator:
    """An external estimator from a TOML file (keys: the fields of :class:`ExternalEstimator`).

    Unknown keys, wrong types and broken rules are refused in one line naming the file and the key.
    """
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"--estimator-file {path}: no such file")
    data = read_toml(path, ConfigError)
    for key in ("name", "command"):
        if key not in data:
            raise ConfigError(f"{path}: {key}: missing (an external estimator needs name and command)")
    data.setdefault("here", str(path.resolve().parent))
    return build(ExternalEstimator, data, path.name)


def _program_name(argv: tuple[str, ...]) -> str:
    """The name of the program ``argv`` runs: its file name; for a script run by the interpreter
    (``{python} my_vo.py ...``, ``{python} -m my_vo ...``) the script's or module's name."""
    if not argv:
        return ""
    if argv[0] == "{python}":
        for arg in argv[1:]:
            if not arg.startswith("-"):
                return Path(arg).stem or Path(arg).name
    return Path(argv[0]).name


def parse_external(command: str, name: str = "") -> ExternalEstimator:
    """An :class:`ExternalEstimator` from a command line given as text (``--external``), split like a
    shell does; ``name`` defaults to the program's file name, or the script's for ``{python} SCRIPT``
    (``floorvo run --external CMD``)."""
    try:
        argv = tuple(shlex.split(command))
    except ValueError as exc:
        raise ConfigError(f"--external {command!r}: {exc}") from None
    if not argv:
        raise ConfigError(f"--external {command!r}: an empty command: give the program and its arguments")
    if not name:
        name = _program_name(argv)
    return build(ExternalEstimator, {"name": name, "command": argv, "here": os.getcwd()}, "--external")


@dataclass(frozen=True)
class ExternalRun:
    """What a successful run of a program gave: the run folder written, the program's figures."""

    estimator: str
    run_dir: str
    frames: int
    placed: int
    wall_s: float
    peak_rss_mb: float
    returncode: int
    command: list[str] = field(default_factory=list)

    @property
    def wall_ms_per_frame(self) -> float:
        """Wall time of the whole program (start-up included) per sequence frame, ms."""
        return 1000.0 * self.wall_s / self.frames if self.frames else float("nan")


def _tail(path: Path, lines: int = STDERR_TAIL_LINES) -> str:
    """The last ``lines`` non-blank lines of a text file, joined with `` | `` on one line (<= 500 chars)."""
    try:
        data = path.read_bytes()[-8192:].decode("utf-8", "replace")
    except OSError:
        return ""
    kept = [" ".join(line.split()) for line in data.splitlines() if line.strip()][-lines:]
    text = " | ".join(kept)
    return text if len(text) <= 500 else "..." + text[-497:]


def _wait(proc: subprocess.Popen, timeout_s: float | None) -> tuple[int | None, float, float]:
    """Wait for ``proc`` to end (``os.waitid`` without reaping it, then ``os.wait4``), sampling its
    peak resident memory meanwhile (:class:`floorvo.memory.PeakRss`: its own and its children's,
    not the ``ru_maxrss`` of ``wait4``, which counts this process's memory that the child carried
    over its ``exec``); after ``timeout_s`` a timer sends its process group SIGTERM, then SIGKILL
    2 s later. Once it has ended, whatever it left running in its process group is killed: a
    child it started kept running after the run (and through the next estimator's timing in a
    bench). Interrupted while it waits (Ctrl-C, SIGTERM), it kills the program's process group
    and reaps the program before the interrupt goes on. Returns ``(wait status, or None when it was killed for the timeout; wall s; peak
    RSS MiB, NaN where it cannot be read)``."""
    done, timed_out = threading.Event(), threading.Event()

    def kill() -> None:
        timed_out.set()
        for sig in (signal.SIGTERM, signal.SIGKILL):
            if done.is_set():
                return
            try:
                os.killpg(proc.pid, sig)
            except ProcessLookupError:
                return
            done.wait(2.0)

    timer = threading.Timer(timeout_s, kill) if timeout_s is not None else None
    t0 = time.perf_counter()
    if timer is not None:
        timer.daemon = True
        timer.start()
    try:
        with PeakRss(pid=proc.pid) as mem:
            # Ended, not yet reaped: the sampler stops while its pid still names the program.
            os.waitid(os.P_PID, proc.pid, os.WEXITED | os.WNOWAIT)
            wall = time.perf_counter() - t0
    except BaseException:
        # Interrupted here (Ctrl-C, SIGTERM, an error): the program's group is killed and reaped
        # before this unwinds. Started in a session of its own, it sees no Ctrl-C of the terminal,
        # and it went on past the interrupted run, writing into the run folder a rerun had filled.
        done.set()
        if timer is not None:
            timer.cancel()
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
        os.waitpid(proc.pid, 0)
        proc.returncode = -signal.SIGKILL  # reaped here: Popen must not wait again
        raise
    _, status, _ = os.wait4(proc.pid, 0)
    done.set()
    if timer is not None:
        timer.cancel()
    try:  # what the program left running in its group (a child it started) ends with it
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    proc.returncode = os.waitstatus_to_exitcode(status)  # reaped here: Popen must not wait again
    return (None if timed_out.is_set() else status), wall, mem.peak_mb


def _pose_at_no_frame(seq: Sequence, timestamps_s: np.ndarray) -> str:
    """Why the first pose of ``timestamps_s`` that is at no frame time of ``seq`` (none within
    :data:`~floorvo.sequence.GROUNDTRUTH_MAX_DIFF_S`, each frame taking one pose) is wrong; ""
    when every pose is at one. A program that stamps its poses with other times (its own
    clock, ``i / fps`` on a recording stamped otherwise, poses past the last frame) was placed
    and scored as if they were frames, exit code 0."""
    ts = np.asarray(timestamps_s, dtype=float)
    frame_ts = seq.timestamps_s
    _, paired = associate(frame_ts, ts, GROUNDTRUTH_MAX_DIFF_S)
    stray = np.setdiff1d(np.arange(len(ts)), paired)
    if not len(stray):
        return ""
    k = int(stray[0])
    j = int(np.argmin(np.abs(frame_ts - ts[k])))
    return (
        f"trajectory.txt: pose {k} at {shown_number(ts[k], '.6f')} s is at no frame time of the sequence (nearest: frame {j} at "
        f"{shown_number(frame_ts[j], '.6f')} s; {len(stray)} of {len(ts)} poses are more than {GROUNDTRUTH_MAX_DIFF_S:g} s from "
        "a frame): stamp each pose with its frame's time"
    )


def _timing_problem(seq: Sequence, written: RunFolder) -> str:
    """Why the program's ``timing.csv`` does not fit the sequence or its own trajectory; "" when it
    fits or there is none. It must hold a row for each frame of the sequence, once (the program was
    given them all: a frame it did not track is a row with status ``lost``; :meth:`RunFolder.read`
    has checked that they increase), and, with a
    ``status`` column, mark ``init`` or ``ok`` exactly the frames at whose times
    ``trajectory.txt`` holds a pose (every pose is at a frame's time: :func:`_pose_at_no_frame`).
    A program's 7 frames 'lost' beside 8 poses was scored as tracking 12.5 % of a perfect
    trajectory; frame 99 of an 8-frame sequence was taken, with exit code 0; a program that wrote
    rows for its first 3 frames of 12 was scored as tracking 100 % (the ground truth was cut to
    the frames it listed); and one that marked frame 4 lost while its trajectory held a pose at
    frame 4's time and none at frame 7's had its poses paired with the wrong steps."""
    timing = written.timing
    if timing is None:
        return ""
    # rows with a 'frame' column of whole numbers >= 0, increasing (RunFolder.read checked them)
    idx = np.asarray(timing["frame"]).astype(int)
    if len(idx) and int(idx.max()) >= seq.frame_count:
        return f"timing.csv: frame {int(idx.max())} is past the sequence's last frame ({seq.frame_count - 1})"
    missing = np.setdiff1d(np.arange(seq.frame_count), idx)
    if len(missing):
        return (
            f"timing.csv: {len(missing)} of the sequence's {seq.frame_count} frames have no row ({_frame_ranges(missing)}): "
            "a row for each frame, those not tracked with status lost"
        )
    statuses = written.statuses
    if statuses is not None:
        placed = sorted(int(f) for f, st in zip(idx, statuses, strict=True) if st in ("init", "ok"))
        i_frame, _ = associate(seq.timestamps_s, np.asarray(written.timestamps_s, dtype=float), GROUNDTRUTH_MAX_DIFF_S)
        posed = sorted(int(f) for f in i_frame)
        if placed != posed:
            unposed = sorted(set(placed) - set(posed))
            unmarked = sorted(set(posed) - set(placed))
            what = []
            if unposed:
                what.append(
                    f"marks frame(s) {_frame_ranges(np.array(unposed))} init or ok, and trajectory.txt has no pose at their time"
                )
            if unmarked:
                what.append(
                    f"marks frame(s) {_frame_ranges(np.array(unmarked))} lost, and trajectory.txt has a pose at their time"
                )
            return "timing.csv " + "; it ".join(what) + ": a pose at each frame tracked and at no other"
    return ""


def _frame_ranges(frames: np.ndarray) -> str:
    """Sorted frame indices as ranges, the first few: ``3-11``, ``4, 7``, ``2-5, 9, ... (14 in all)``."""
    runs: list[str] = []
    start = prev = int(frames[0])
    for f in [int(x) for x in frames[1:]] + [None]:
        if f is not None and f == prev + 1:
            prev = f
            continue
        runs.append(str(start) if start == prev else f"{start}-{prev}")
        if f is not None:
            start = prev = f
    return ", ".join(runs[:4]) + (f", ... ({len(frames)} in all)" if len(runs) > 4 else "")


def _start_pose(seq: Sequence, t_first_s: float, T_world_start: np.ndarray | None) -> np.ndarray:
    """Where the run starts (see the module doc): ground truth at ``t_first_s``
    (:meth:`Sequence.groundtruth_at`), else ``T_world_start``, else the identity."""
    T, found = seq.groundtruth_at(np.array([t_first_s]))
    if found[0]:
        return T[0]
    return np.eye(4) if T_world_start is None else np.asarray(T_world_start, dtype=float)


@locks_folder("run_dir", "run folder")
def run_external(
    seq: Sequence | str | os.PathLike,
    spec: ExternalEstimator,
    run_dir: str | os.PathLike,
    *,
    T_world_start: np.ndarray | None = None,
) -> ExternalRun:
    """Run program ``spec`` over ``seq`` into ``run_dir`` (see the module doc); returns its figures.

    ``T_world_start`` (4, 4) mm: the start pose of a run on a sequence without ground truth.
    Raises :class:`ExternalEstimatorError` (reason and stderr tail) when the program fails, and
    :class:`FloorbenchError` when the sequence lacks what it needs. ``run_dir`` is locked while
    the run lasts (:func:`floorvo.locking.lock_folder`; the program's own ``program/`` is not).
    """
    if not isinstance(seq, Sequence):
        seq = Sequence.open(seq)
    name = spec.name
    lacking = seq.lacks(spec.needs, name)
    if lacking:
        raise FloorbenchError(lacking)
    out = ensure_writable_dir(run_dir)
    program_dir = out / PROGRAM_DIR
    remove_run_files(out)  # a rerun must not read an older run's files, nor keep its score beside a failed one
    remove_run_files(program_dir)
    program_dir.mkdir(exist_ok=True)
    height = seq.height_mm
    camera_file = out / PROGRAM_CAMERA
    extra = {} if height is None else {"camera_height_mm": float(height)}
    atomic_write_text(camera_file, seq.camera.to_opencv_yaml(**extra))
    values = {
        "sequence": str(seq.root.resolve()),
        "output": str(program_dir.resolve()),
        "camera": str(camera_file.resolve()),
        "images": str((seq.root / "cam0").resolve()),
        "height_mm": "" if height is None else repr(float(height)),
        "fps": repr(float(seq.fps)),
        "frames": str(seq.frame_count),
        "here": spec.here or os.getcwd(),
        "python": sys.executable,
    }
    argv = [arg.format_map(values) for arg in spec.command]
    env = {**os.environ, **spec.env}
    log.info("%s: running %s", name, shlex.join(argv))

    def fail(reason: str) -> ExternalEstimatorError:
        tail = _tail(out / PROGRAM_STDERR)
        log.warning("%s on %s failed: %s%s", name, seq.root, reason, f" (stderr: {tail})" if tail else "")
        return ExternalEstimatorError(
            f"{name}: {reason}" + (f"; stderr: {tail}" if tail else ""), reason=reason, stderr_tail=tail
        )

    with open(out / PROGRAM_STDOUT, "wb") as so, open(out / PROGRAM_STDERR, "wb") as se:
        try:
            proc = subprocess.Popen(
                argv, stdin=subprocess.DEVNULL, stdout=so, stderr=se, env=env, start_new_session=True
            )
        except OSError as exc:  # not found, not executable
            raise fail(f"cannot start {argv[0]!r}: {exc.strerror or exc}") from None
        timeout_s = spec.timeout_for(seq.frame_count)
        status, wall_s, peak_mb = _wait(proc, timeout_s)
    if status is None:
        how = "its timeout_s" if spec.timeout_s is not None else "the default limit for this sequence"
        raise fail(
            f"{Path(argv[0]).name} timed out after {timeout_s:g} s ({how}; set timeout_s in an estimator file, "
            "0 for no limit) and was killed"
        )
    code = os.waitstatus_to_exitcode(status)
    if code < 0:
        raise fail(f"killed by signal {signal.Signals(-code).name}")
    if code != 0:
        raise fail(f"exit code {code}")
    if not (program_dir / "trajectory.txt").is_file():
        raise fail("wrote no trajectory.txt into {output}")
    try:
        written = RunFolder.read(program_dir, agree=False)  # its result.json is its own; timing: _timing_problem
    except SequenceError as exc:
        raise fail(f"malformed output: {' '.join(str(exc).split())}") from None
    if len(written.timestamps_s) == 0:
        raise fail("trajectory.txt holds no pose")
    stray = _pose_at_no_frame(seq, written.timestamps_s) or _timing_problem(seq, written)
    if stray:
        raise fail(stray)
    T_prog = written.T_world_cam
    T_start = _start_pose(seq, float(written.timestamps_s[0]), T_world_start)
    T_world_cam = T_start @ np.linalg.inv(T_prog[0]) @ T_prog
    far = np.abs(T_world_cam[:, :3, 3]).max(axis=1)
    if not (far <= MAX_POSITION_MM).all():  # each pose within the bound, but not moved to the start pose
        k = int(np.argmax(~(far <= MAX_POSITION_MM)))
        raise fail(
            f"pose {k} (t = {written.timestamps_s[k]:.6f} s), moved with the run to the start pose, lies at "
            f"{position_problem(T_world_cam[k, :3, 3])}"
        )
    src = spec.source
    run = ExternalRun(name, str(out), seq.frame_count, len(T_world_cam), wall_s, peak_mb, code, argv)
    statuses = written.statuses
    result: dict[str, Any] = {
        "estimator": name,
        "run_dir": str(out),
        "frames": seq.frame_count,
        "placed": run.placed,
        "fps": seq.frame_count / wall_s if wall_s > 0 else 0.0,
        "wall_s": wall_s,
        "wall_ms_per_frame": run.wall_ms_per_frame,
        "peak_rss_mb": None if np.isnan(peak_mb) else peak_mb,  # None: not measured (no /proc)
        "source": src.to_dict(),
        "external": {
            "command": argv,
            "returncode": code,
            "timeout_s": spec.timeout_for(seq.frame_count),
            "env": dict(spec.env),
            "program_result": strict_json(dict(written.result)),  # its NaN made strict JSON
        },
        "sequence": str(seq.root),
        SEQUENCE_SHA256: sequence_sha256(seq.meta),
    }
    if statuses is not None:
        result["status_counts"] = {s: statuses.count(s) for s in ("init", "ok", "lost")}
        result["ok"], result["lost"] = result["status_counts"]["ok"], result["status_counts"]["lost"]
    RunFolder(
        written.timestamps_s, T_world_cam, written.timing, result, f"floorvo external {name}: T_world_cam, metres"
    ).write(out)
    log.info("%s on %s: %d poses, %.2f s, peak %.0f MiB", name, seq.root, run.placed, wall_s, peak_mb)
    return run

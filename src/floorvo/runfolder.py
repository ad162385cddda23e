"""The run folder: one writer and one reader of ``RUN/trajectory.txt``, ``timing.csv``, ``result.json``.

Every estimator run of the project (``floorvo run``, ``floorvo localize``, the bench)
writes this layout through :meth:`RunFolder.write`, and every reader (scoring,
calibration, the bench report) reads it through :meth:`RunFolder.read`, as evo has one
trajectory type and one ``file_interface``. The format is the contract with other tools:

``trajectory.txt``
    TUM (``timestamp tx ty tz qx qy qz qw``, seconds and metres; readable by ``evo_ape
    tum``) of ``T_world_cam`` of every frame the run placed, after a ``#`` header line. A
    run that placed no frame holds the header only.
``timing.csv``
    One row per frame the estimator saw: ``frame`` (sequence index), ``detect_ms``,
    ``match_ms``, ``estimate_ms``, ``total_ms`` (three decimals), ``status`` (``init``,
    ``ok`` or ``lost``), ``n_keypoints``, ``n_matches``, ``n_inliers``; ``floorvo localize``
    adds a text column ``reason``. Runs written by other programs may have fewer columns;
    ``frame`` is the one every reader needs.
``result.json``
    The run's summary (estimator, frame counts, lost frames with reasons, config, ...); see
    :meth:`floorvo.runner.RunResult.summary`. Optional for a run written by another program.
``matches/NNNNNN.npz``
    Optional samples of matched keypoints for the report (:func:`write_match_sample`).
``score.json``
    The run's score (``floorvo score``, the bench: :func:`floorvo.scoring.write_score`).

Every file is written atomically (:mod:`floorvo.io`); ``result.json`` last, so its
presence marks a finished run. A new run written into a folder first removes the old
``result.json`` and what was derived from the old run (:data:`DERIVED`: ``score.json``,
``matches/``). Writers lock the folder (:func:`floorvo.locking.lock_folder`);
readers do not. A missing, malformed or inconsistent file is refused with a
one-line :class:`~floorvo.errors.SequenceError` naming the file and the rule; so are files
that disagree with each other (:meth:`RunFolder.read`): a trajectory or a ``timing.csv`` cut
short at a line boundary is whole on its own, and was scored as a shorter run.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from floorvo.errors import SequenceError, shorten, shown
from floorvo.io import (
    atomic_write_bytes,
    atomic_write_csv,
    atomic_write_json,
    atomic_write_text,
    ensure_writable_dir,
    json_sha256,
    read_json,
    read_npz,
    read_text,
)
from floorvo.locking import lock_folder
from floorvo.sequence_meta import MAX_FRAME_COUNT, stable_meta
from floorvo.tum import format_tum, read_tum

__all__ = [
    "STATUSES",
    "TIMING_MS_COLUMNS",
    "COUNT_COLUMNS",
    "TIMING_COLUMNS",
    "RunFolder",
    "timing_table",
    "read_timing_csv",
    "write_match_sample",
    "read_match_samples",
    "SEQUENCE_SHA256",
    "sequence_sha256",
    "BENCH_CACHE_MARKER",
    "sequence_content_sha256",
    "check_run_of_sequence",
    "SCORE",
    "DERIVED",
    "remove_derived_files",
    "remove_program_files",
    "remove_run_files",
    "PROGRAM_DIR",
    "PROGRAM_FILES",
    "PROGRAM_CAMERA",
    "PROGRAM_STDOUT",
    "PROGRAM_STDERR",
]

#: The ``result.json`` key holding the content hash of the ``sequence.json`` a run was made on.
SEQUENCE_SHA256 = "sequence_sha256"


def sequence_sha256(meta: Any) -> str:
    """The identity of a sequence a run records (:data:`SEQUENCE_SHA256`): the hash of its
    ``sequence.json`` content (:func:`floorvo.io.json_sha256`) without its render timings
    (:func:`floorvo.sequence_meta.stable_meta`): a copy of the folder, or the same scene rendered
    again, has the same."""
    return json_sha256(stable_meta(meta) if isinstance(meta, dict) else meta)


#: The bench's render cache marks a sequence folder it rendered with this file
#: (:func:`floorsim.bench.bench.render_cached`): the bench's, not the sequence's.
BENCH_CACHE_MARKER = "bench-cache.json"


def sequence_content_sha256(folder: str | os.PathLike) -> str:
    """What a recorded sequence folder holds (a study's record, a bench row's ``inputs``, the
    sequences a scale calibration was fitted on): its ``sequence.json`` (:func:`sequence_sha256`)
    and the bytes of every file in it (frames, depth, calibration, times, signals, ground truth)
    but hidden ones (a writer's lock) and the render cache's marker (:data:`BENCH_CACHE_MARKER`);
    ``"unreadable"`` where it cannot be read. Its frames were left out once: a gate blamed the
    estimators for a recording whose frames had been blurred since its baseline (12 metrics worse)."""
    root = Path(folder)
    files = hashlib.sha256()
    try:
        meta = json.loads((root / "sequence.json").read_text(encoding="utf-8"))
        for p in sorted(root.rglob("*")):
            rel = p.relative_to(root)
            if p.name == BENCH_CACHE_MARKER or any(part.startswith(".") for part in rel.parts) or not p.is_file():
                continue
            files.update(rel.as_posix().encode("utf-8", "surrogateescape") + b"\0")
            with open(p, "rb") as fh:
                files.update(hashlib.file_digest(fh, "sha256").digest())
    except (OSError, ValueError):
        return "unreadable"
    return json_sha256({"sequence": sequence_sha256(meta), "files": files.hexdigest()})


def check_run_of_sequence(run_dir: str | os.PathLike, result: Any, seq_dir: str | os.PathLike) -> None:
    """One-line :class:`SequenceError` when the run in ``run_dir`` (its ``result.json`` content
    ``result``) records that it was made on another sequence than the folder ``seq_dir``.

    Nothing is checked for a run that records no :data:`SEQUENCE_SHA256` (older runs, runs
    written by hand) or when ``seq_dir`` is not a sequence folder (a TUM file). A run scored,
    plotted or calibrated against a sequence it was not run on gave figures with exit code 0:
    ground truth of another trajectory and another camera paired by time with its poses.
    """
    recorded = result.get(SEQUENCE_SHA256) if isinstance(result, dict) else None
    meta_path = Path(seq_dir) / "sequence.json"
    if not isinstance(recorded, str) or not meta_path.is_file():
        return
    current = sequence_sha256(read_json(meta_path, SequenceError))
    if current != recorded:
        raise SequenceError(
            f"{run_dir}: was run on another sequence ({shown(str(result.get('sequence', '?')))}, sequence.json "
            f"sha256 {recorded[:12]}) than {seq_dir} (sha256 {current[:12]}); give the sequence it was run on"
        )


#: What an estimator says of a frame (:class:`floorvo.estimators.base.StepResult`).
STATUSES = ("init", "ok", "lost")
#: Per-stage milliseconds, in the order of ``timing.csv``.
TIMING_MS_COLUMNS = ("detect_ms", "match_ms", "estimate_ms", "total_ms")
#: Per-frame counts, in the order of ``timing.csv``.
COUNT_COLUMNS = ("n_keypoints", "n_matches", "n_inliers")
#: The columns ``timing.csv`` starts with; any others (``reason``) follow.
TIMING_COLUMNS = ("frame", *TIMING_MS_COLUMNS, "status", *COUNT_COLUMNS)

#: The largest frame index a run may list (a sequence holds at most MAX_FRAME_COUNT frames).
MAX_FRAME_INDEX = MAX_FRAME_COUNT - 1

TRAJECTORY = "trajectory.txt"
TIMING = "timing.csv"
RESULT = "result.json"
MATCHES = "matches"
SCORE = "score.json"
#: What is made from a finished run and kept in its folder: its score (``floorvo score``, the
#: bench) and the bench's match samples. A new run written into the folder removes them
#: (:func:`remove_derived_files`): a score of one run beside the trajectory of another was read
#: as the new run's (``floorvo run -e akaze-guided -o R`` kept phase-corr's ``R/score.json``).
DERIVED = (SCORE, MATCHES)


#: What a program's run (:mod:`floorvo.external`) writes into its run folder besides the run's
#: own files: the program's folder (``{output}``), the camera file it was given, its output streams.
PROGRAM_DIR = "program"
PROGRAM_CAMERA, PROGRAM_STDOUT, PROGRAM_STDERR = "camera.yaml", "stdout.txt", "stderr.txt"
PROGRAM_FILES = (PROGRAM_CAMERA, PROGRAM_STDOUT, PROGRAM_STDERR)


def remove_program_files(run_dir: str | os.PathLike) -> None:
    """Remove what a program's earlier run left in ``run_dir`` (:data:`PROGRAM_FILES`, and the run
    files of :data:`PROGRAM_DIR`, the folder too once empty): a Python estimator's run written
    into the folder kept them beside a ``result.json`` that named it. The caller holds the lock."""
    run_dir = Path(run_dir)
    for name in PROGRAM_FILES:
        (run_dir / name).unlink(missing_ok=True)
    pdir = run_dir / PROGRAM_DIR
    if pdir.is_dir():
        for name in (TRAJECTORY, TIMING, RESULT):
            (pdir / name).unlink(missing_ok=True)
        try:
            pdir.rmdir()
        except OSError:  # the program wrote more there: not ours to remove
            pass


def remove_run_files(run_dir: str | os.PathLike) -> None:
    """Remove an earlier run's ``trajectory.txt``, ``timing.csv`` and ``result.json`` from
    ``run_dir``, and what was made from them (:func:`remove_derived_files`): an external
    program's run, whose program writes them itself, must not read an older run's. The caller
    holds the folder's lock. (A Python run keeps the older run until it writes its own whole: an
    interrupted run loses nothing; the bench draws only the runs of its ``ok`` rows.)"""
    run_dir = Path(run_dir)
    for name in (TRAJECTORY, TIMING, RESULT):
        (run_dir / name).unlink(missing_ok=True)
    remove_derived_files(run_dir)


def remove_derived_files(run_dir: str | os.PathLike) -> None:
    """Remove :data:`DERIVED` from ``run_dir``: ``score.json`` and the match samples of
    ``matches/`` (the folder too, once empty). The caller holds the folder's lock."""
    run_dir = Path(run_dir)
    (run_dir / SCORE).unlink(missing_ok=True)
    mdir = run_dir / MATCHES
    if mdir.is_dir():
        for f in mdir.glob("*.npz"):
            f.unlink(missing_ok=True)
        try:
            mdir.rmdir()
        except OSError:  # something else is in it: not ours to remove
            pass


@dataclass(frozen=True)
class RunFolder:
    """The contents of a run folder in memory.

    ``timestamps_s`` (N,) and ``T_world_cam`` (N, 4, 4), mm: the frames the run placed.
    ``timing``: the columns of ``timing.csv``, each an (F,) array over the frames the
    estimator saw (numbers as float or int arrays, ``status`` and other text as object
    arrays), or None when the run has no ``timing.csv``. ``result``: ``result.json``
    (``{}`` when absent). ``header``: the comment line of ``trajectory.txt`` (written, not
    read back).
    """

    timestamps_s: np.ndarray
    T_world_cam: np.ndarray
    timing: Mapping[str, np.ndarray] | None = None
    result: Mapping[str, Any] = field(default_factory=dict)
    header: str = ""

    @property
    def statuses(self) -> list[str] | None:
        """``timing.csv``'s status per frame, or None when it has none."""
        if not self.timing or "status" not in self.timing:
            return None
        return [str(s) for s in self.timing["status"]]

    def write(self, run_dir: str | os.PathLike) -> Path:
        """Write the files into ``run_dir`` (created), each atomically; returns the folder.

        All or nothing: the folder's old ``result.json`` goes first, with what was derived from
        the old run (:data:`DERIVED`: its ``score.json``, the bench's match samples), and the new
        ``result.json`` is written last; when a write fails (a full disk) the files this call
        wrote are removed again before the error propagates, so a folder never holds the
        trajectory of one run beside the summary or the score of another, nor a trajectory
        without its summary. The
        folder is locked while it is written (:func:`floorvo.locking.lock_folder`; a writer
        that holds it already, such as :func:`floorvo.run.run_estimator`, keeps it).
        """
        with lock_folder(run_dir, "run folder"):
            return self._write(ensure_writable_dir(run_dir))

    def _write(self, out: Path) -> Path:
        ts = np.asarray(self.timestamps_s, dtype=float).reshape(-1)
        T = np.asarray(self.T_world_cam, dtype=float).reshape(-1, 4, 4)
        tum = format_tum(ts, T, self.header or None)
        table = timing_table(self.timing) if self.timing is not None else None
        (out / RESULT).unlink(missing_ok=True)
        remove_derived_files(out)
        written: list[Path] = []
        try:
            atomic_write_text(out / TRAJECTORY, tum)
            written.append(out / TRAJECTORY)
            if table is not None:
                atomic_write_csv(out / TIMING, *table)
                written.append(out / TIMING)
            atomic_write_json(out / RESULT, dict(self.result))
        except BaseException:
            for p in written:
                p.unlink(missing_ok=True)
            raise
        return out

    @classmethod
    def read(cls, run_dir: str | os.PathLike, *, agree: bool = True) -> RunFolder:
        """Read a run folder; ``trajectory.txt`` is required, ``timing.csv`` and ``result.json`` optional.

        A malformed file is a one-line :class:`SequenceError` naming it and the rule. So are
        files that disagree with each other (:func:`_disagreement`): a pose for each frame
        ``timing.csv`` marks ``init`` or ``ok``, and ``result.json``'s frame counts those of
        ``timing.csv`` (or of the trajectory). ``agree=False`` reads each file on its own: for
        a program's output (:mod:`floorvo.external`), whose ``result.json`` is the program's
        own and whose ``timing.csv`` is checked against the sequence and the trajectory there.
        """
        run_dir = Path(run_dir)
        if not run_dir.is_dir():
            raise SequenceError(f"{run_dir}: run folder is missing")
        ts, T = read_tum(run_dir / TRAJECTORY, allow_empty=True)
        timing = read_timing_csv(run_dir / TIMING)
        rp = run_dir / RESULT
        result = read_json(rp, SequenceError) if rp.is_file() else {}
        if not isinstance(result, dict):
            raise SequenceError(f"{rp}: must hold a JSON object (the run's summary), got {type(result).__name__}")
        for key in ("estimator", "sequence", "run_dir") if agree else ():  # a program's own result.json is its own
            if key in result and not isinstance(result[key], str):  # named in scores and calibrations (5 was)
                raise SequenceError(f"{rp}: {key} = {shown(result[key])}: must be a string")
        run = cls(ts, T, timing, result)
        problem = _disagreement(run_dir, run) if agree else ""
        if problem:
            raise SequenceError(
                f"{run_dir}: {problem}; a run's files must agree (one of them is cut short, or from another run)"
            )
        return run


_PLACED = ("init", "ok")


def _count(path: Path, result: Mapping[str, Any], key: str, where: str = "") -> int | None:
    """``result[key]`` (or ``result[where][key]``) of ``result.json`` at ``path`` as a whole number
    >= 0; None when absent (or null); a one-line :class:`SequenceError` when it is no count."""
    value = (result.get(where) if where else result) or {}
    v = value.get(key) if isinstance(value, Mapping) else None
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v >= 0 and v == int(v)):
        name = f"{where}.{key}" if where else key
        raise SequenceError(f"{path}: {name} = {shown(v)}: must be a whole number >= 0 (a count of frames)")
    return int(v)


def _disagreement(run_dir: Path, run: RunFolder) -> str:
    """Why the files of ``run`` (read from ``run_dir``) disagree with each other; "" when they agree.

    ``trajectory.txt`` holds a pose for each frame ``timing.csv`` marks ``init`` or ``ok`` (for a
    ``timing.csv`` without statuses: no more poses than it has rows); ``result.json``'s
    ``frames``, ``first_frame``, ``last_frame``, ``status_counts``, ``ok`` and ``lost`` (the
    summary of every run of this project, :meth:`floorvo.runner.RunResult.summary`) are those of
    ``timing.csv``, and its ``placed`` (an external program's run) and the placed frames of its
    ``status_counts`` the trajectory's poses. A run whose ``result.json`` records a sub-range of the
    sequence (``--frames``) agrees: its ``timing.csv`` lists that range. A value that is not a
    count is a :class:`SequenceError`.
    """
    n_poses = len(run.timestamps_s)
    poses = f"{TRAJECTORY} holds {n_poses} pose(s)"
    timing, result = run.timing, run.result
    statuses = run.statuses
    rp = run_dir / RESULT
    frames: np.ndarray | None = None
    if timing is not None:  # read_timing_csv refuses one without a frame column
        frames = np.asarray(timing["frame"]).astype(int)
        if statuses is not None:
            placed = sum(s in _PLACED for s in statuses)
            if placed != n_poses:
                return f"{poses}, and {TIMING} marks {placed} frame(s) init or ok: a pose for each frame tracked, and no other"
        elif len(frames) < n_poses:
            return f"{poses}, and {TIMING} lists {len(frames)} frame(s): a row for each frame the run saw"
    if not result:
        return ""
    n_frames = _count(rp, result, "frames")
    if frames is not None:
        if n_frames is not None and n_frames != len(frames):
            return f"{RESULT} says the run saw {n_frames} frame(s) ('frames'), and {TIMING} lists {len(frames)}: a row for each"
        for key, value in (("first_frame", frames[0]), ("last_frame", frames[-1])):
            recorded = _count(rp, result, key)
            if recorded is not None and recorded != int(value):
                return f"{RESULT} says the run's {key} was {recorded}, and {TIMING}'s is {int(value)}"
    elif n_frames is not None and n_poses > n_frames:
        return f"{poses}, and {RESULT} says the run saw {n_frames} frame(s) ('frames'): a pose for each frame tracked, and no other"
    counts = {s: _count(rp, result, s, "status_counts") for s in STATUSES}
    if statuses is not None:
        marked = {s: statuses.count(s) for s in STATUSES}
        for key, where in [(s, "status_counts") for s in STATUSES] + [("ok", ""), ("lost", "")]:
            recorded = counts[key] if where else _count(rp, result, key)
            if recorded is not None and recorded != marked[key]:
                name = f"{where}.{key}" if where else key
                return f"{RESULT} counts {recorded} frame(s) {key} ('{name}'), and {TIMING} marks {marked[key]}"
    elif counts["init"] is not None and counts["ok"] is not None and counts["init"] + counts["ok"] != n_poses:
        placed = counts["init"] + counts["ok"]
        return f"{poses}, and {RESULT} counts {placed} frame(s) init or ok ('status_counts'): a pose for each frame tracked, and no other"
    n_placed = _count(rp, result, "placed")
    if n_placed is not None and n_placed != n_poses:
        return f"{poses}, and {RESULT} says the run placed {n_placed} ('placed')"
    return ""


def _column_cells(column: str, values: Any) -> list[str]:
    values = np.asarray(values).tolist()
    if column.endswith("_ms"):
        return [f"{float(v):.3f}" for v in values]
    if column == "frame" or column in COUNT_COLUMNS:
        return [str(int(v)) for v in values]
    return [str(v) for v in values]


def timing_table(columns: Mapping[str, np.ndarray]) -> tuple[list[str], list[tuple[str, ...]]]:
    """``(header, rows)`` of ``timing.csv`` from its columns (each (F,)): :data:`TIMING_COLUMNS`
    first, in order, then the others; milliseconds with three decimals."""
    names = [c for c in TIMING_COLUMNS if c in columns] + [c for c in columns if c not in TIMING_COLUMNS]
    lengths = {len(columns[c]) for c in names}
    if len(lengths) > 1:
        raise ValueError(f"timing.csv: columns of different lengths {sorted(lengths)}")
    return names, list(zip(*[_column_cells(c, columns[c]) for c in names]))


def read_timing_csv(path: str | os.PathLike) -> dict[str, np.ndarray] | None:
    """Columns of ``timing.csv``, or None if the file is missing.

    A header line and a row for each frame: a file with no row (empty, a header alone, a
    line of anything else) or without a ``frame`` column is refused, as is a cell that
    breaks its column's rule. ``frame``, the ``*_ms`` and the ``n_*`` columns must be numbers
    (empty cells read as NaN; ``frame`` must be a whole number); ``status`` must be one of
    :data:`STATUSES`; any other column that is not all numbers (such as ``reason``) stays text.
    """
    path = Path(path)
    if not path.is_file():
        return None
    text = read_text(path, SequenceError, what="a CSV text file")
    try:
        rows = list(csv.DictReader(io.StringIO(text, newline="")))
    except csv.Error as exc:  # a NUL byte, a field beyond the csv module's limit
        raise SequenceError(f"{path}: not a readable CSV file ({shorten(str(exc))})") from None
    if not rows:
        raise SequenceError(f"{path}: holds no row; a header line, then a row for each frame the run saw")
    if "frame" not in rows[0]:
        raise SequenceError(
            f"{path}: has no 'frame' column (header {shown(','.join(str(k) for k in rows[0]))}); "
            f"a row for each frame, its index in 'frame' ({','.join(TIMING_COLUMNS)})"
        )
    if any(None in r or None in r.values() for r in rows):
        raise SequenceError(f"{path}: a row has another number of cells than the header")
    cols: dict[str, np.ndarray] = {}
    for key in rows[0]:
        vals = [r[key] for r in rows]
        if key == "status":
            bad = next((v for v in vals if v not in STATUSES), None)
            if bad is not None:
                raise SequenceError(f"{path}: status {shown(bad)} is not one of {', '.join(STATUSES)}")
            cols[key] = np.array(vals, dtype=object)
            continue
        try:
            cols[key] = np.array([float(v) if v not in ("", None) else np.nan for v in vals])
        except ValueError:
            if key == "frame" or key.endswith("_ms") or key in COUNT_COLUMNS:
                raise SequenceError(f"{path}: column {shown(key)} holds a value that is not a number") from None
            cols[key] = np.array(vals, dtype=object)
            continue
        _check_numbers(path, key, vals, cols[key])
    frame = cols["frame"]  # the column is there (refused above otherwise)
    if not all(math.isfinite(f) and f == int(f) and 0 <= f <= MAX_FRAME_INDEX for f in frame):
        raise SequenceError(f"{path}: column 'frame' must hold frame indices (whole numbers >= 0)")
    back = np.nonzero(np.diff(frame) <= 0)[0]
    if len(back):
        i = int(back[0]) + 1
        raise SequenceError(
            f"{path}: frame {int(frame[i])} (row {i + 1}) follows frame {int(frame[i - 1])}; "
            "a run sees each frame once, in increasing order"
        )
    return cols


def _check_numbers(path: Path, key: str, cells: list[str], values: np.ndarray) -> None:
    """Milliseconds and counts are finite and >= 0 (counts whole); an empty cell is a missing
    value (NaN), but a written ``nan`` or ``inf`` is a broken measurement."""
    if not (key.endswith("_ms") or key in COUNT_COLUMNS):
        return
    for cell, v in zip(cells, values):
        if cell in ("", None):
            continue
        if not (math.isfinite(v) and v >= 0 and (v == int(v) or key not in COUNT_COLUMNS)):
            rule = "whole numbers >= 0" if key in COUNT_COLUMNS else "finite milliseconds >= 0"
            raise SequenceError(f"{path}: column {shown(key)} holds {shown(cell)}; must hold {rule} (or be empty)")


def write_match_sample(run_dir: str | os.PathLike, frame: int, matches_px: np.ndarray) -> Path:
    """Save one frame pair's matched keypoints as ``RUN/matches/NNNNNN.npz`` (``frame``: the later frame).

    ``matches_px``: (N, 4) ``u_prev, v_prev, u_cur, v_cur`` (as in ``StepResult.matches_px``),
    stored as ``xy_prev_px`` and ``xy_cur_px`` (N, 2).
    """
    m = np.asarray(matches_px, dtype=float).reshape(-1, 4)
    buf = io.BytesIO()
    np.savez(buf, xy_prev_px=m[:, :2], xy_cur_px=m[:, 2:])
    path = Path(run_dir) / MATCHES / f"{int(frame):06d}.npz"
    with lock_folder(run_dir, "run folder"):
        atomic_write_bytes(path, buf.getvalue())
    return path


def _match_points_problem(shape: tuple[int, ...], dtype: np.dtype) -> str | None:
    """Why an array of a match sample is refused (checked on its header, before it is read), or None."""
    if len(shape) != 2 or shape[1] != 2 or dtype.kind not in "fiu":
        return "must be (N, 2) numbers (pixels)"
    return None


def read_match_samples(run_dir: str | os.PathLike) -> list[tuple[int, np.ndarray, np.ndarray]]:
    """``[(frame, xy_prev_px (N, 2), xy_cur_px (N, 2)), ...]`` of ``RUN/matches``, by frame; [] when none."""
    mdir = Path(run_dir) / MATCHES
    out = []
    for f in sorted(mdir.glob("*.npz")) if mdir.is_dir() else []:
        try:
            frame = int(f.stem)
        except ValueError:
            raise SequenceError(f"{f}: not a match sample (named by its frame: NNNNNN.npz)") from None
        rules = dict.fromkeys(("xy_prev_px", "xy_cur_px"), _match_points_problem)
        data = read_npz(f, rules, str(f), "match sample (an .npz with xy_prev_px and xy_cur_px)")
        a, b = np.asarray(data["xy_prev_px"], float), np.asarray(data["xy_cur_px"], float)
        if a.shape != b.shape or a.ndim != 2 or a.shape[1] != 2:
            raise SequenceError(f"{f}: xy_prev_px and xy_cur_px must both be (N, 2), got {a.shape} and {b.shape}")
        out.append((frame, a, b))
    return out

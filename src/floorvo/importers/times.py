"""Timestamps files and ground-truth files given beside a recording.

* ``--timestamps FILE``: one frame a line, in frame order; the first number of each line
  (whitespace- or comma-separated, so a TUM ``rgb.txt`` or a EuRoC ``data.csv`` works as
  it is) is the frame's time in ``unit`` (``s``, ``ms``, ``us`` or ``ns``); ``#`` lines
  and blank lines are skipped. Times that do not increase, or beyond
  :data:`floorvo.tum.MAX_TIME_S` (another unit), are refused naming the file and the line.
* ``--groundtruth FILE``: TUM (``t tx ty tz qx qy qz qw``, seconds and metres) or EuRoC
  CSV (``t_ns, px, py, pz, qw, qx, qy, qz, ...``, nanoseconds and metres; a ``.csv`` file
  or one whose header names ``[ns]``). The pose is ``T_world_cam0``.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import NamedTuple

import numpy as np

from floorvo.errors import ConfigError, SequenceError, shown
from floorvo.geometry import T_from_xyz_quat, position_problem
from floorvo.io import read_text
from floorvo.sequence import check_timestamps
from floorvo.tum import check_increasing, read_tum

__all__ = ["TIME_UNITS_S", "FrameTimes", "read_timestamps_file", "read_groundtruth_file", "read_euroc_groundtruth"]

#: Seconds per unit of a timestamps file.
TIME_UNITS_S = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}


def _rows(path: Path, what: str) -> list[tuple[int, list[str]]]:
    """``(line number, fields)`` of the data lines of a text file (``#`` and blank lines skipped)."""
    return _rows_and_header(path, what)[0]


def _rows_and_header(path: Path, what: str) -> tuple[list[tuple[int, list[str]]], tuple[int, list[str]] | None]:
    """:func:`_rows`, and the ``(line number, cells)`` of the CSV header: the last ``#`` line with a
    comma before the first data line (``#timestamp [ns], p_RS_R_x [m], ...``: its cells split at the
    commas alone, for a column's name holds spaces), or None."""
    text = read_text(path, SequenceError, label=f"{what} {path}", what="a text file")
    out: list[tuple[int, list[str]]] = []
    header = None
    for lineno, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        fields = line.replace(",", " ").split()
        if fields and not line.startswith("#"):  # a line of commas alone holds no field either
            out.append((lineno, fields))
        elif line.startswith("#") and "," in line and not out:
            header = (lineno, line[1:].split(","))
    return out, header


class FrameTimes(NamedTuple):
    """A timestamps file's frame times: ``seconds`` (N,), and for a file in ``ns`` the integers
    themselves (``ns``, else None), which the sequence writes exactly (a float of seconds holds a
    Unix time only to about 240 ns)."""

    seconds: np.ndarray
    ns: list[int] | None


def read_timestamps_file(path: str | os.PathLike, unit: str = "s") -> FrameTimes:
    """The frame times of ``path`` (format in the module docstring)."""
    path = Path(path)
    if unit not in TIME_UNITS_S:
        raise ConfigError(f"--time-unit {unit!r}: unknown (known: {', '.join(TIME_UNITS_S)})")
    if not path.is_file():
        raise SequenceError(f"timestamps file {path}: does not exist")
    vals, linenos, ns = [], [], []
    for lineno, fields in _rows(path, "timestamps file"):
        try:
            if unit == "ns":
                ns.append(int(fields[0]))
            v = float(fields[0]) if unit != "ns" else ns[-1] * 1e-9
        except ValueError:
            raise SequenceError(f"{path}:{lineno}: {shown(fields[0])} is not a timestamp in {unit}") from None
        if not np.isfinite(v):
            raise SequenceError(f"{path}:{lineno}: timestamp {shown(fields[0])} is not a finite number")
        vals.append(v if unit == "ns" else v * TIME_UNITS_S[unit])
        linenos.append(lineno)
    if not vals:
        raise SequenceError(f"timestamps file {path}: holds no timestamps")
    seconds = check_timestamps(np.array(vals, dtype=float), None, str(path), linenos)
    return FrameTimes(seconds, ns if unit == "ns" else None)


def read_euroc_groundtruth(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """EuRoC/ASL pose CSV: ``(timestamps_s (N,), T_world_body (N, 4, 4) mm)``.

    Columns: ``timestamp [ns], p_x, p_y, p_z [m], q_w, q_x, q_y, q_z``, then anything
    (velocities, biases). Every row has a cell for each column the header names (EuRoC's
    ``#timestamp, p_RS_R_x [m], ...``: 17), or without a header as many as the first row: a row
    cut short (a copy or a recording that stopped mid-line) is refused, naming it. Quaternions
    are normalised; a zero one is refused, and so are timestamps that do not increase
    (:func:`floorvo.tum.check_increasing`).
    """
    path = Path(path)
    if not path.is_file():
        raise SequenceError(f"ground-truth file {path}: does not exist")
    ts, Ts, linenos = [], [], []
    rows, header = _rows_and_header(path, "ground-truth file")
    if header is not None:
        cells, names = len(header[1]), f"the header (line {header[0]}) names"
    elif rows:
        cells, names = len(rows[0][1]), f"the first row (line {rows[0][0]}) has"
    for lineno, f in rows:
        if len(f) != cells:
            raise SequenceError(
                f"{path}:{lineno}: a row of {len(f)} cells, where {names} {cells}: every row has a cell "
                "for each column (a row cut short?)"
            )
        if len(f) < 8:
            raise SequenceError(f"{path}:{lineno}: a EuRoC pose row has >= 8 fields (t_ns px py pz qw qx qy qz)")
        try:
            t_ns = int(f[0])
            v = np.array([float(x) for x in f[1:8]])
        except ValueError:
            raise SequenceError(f"{path}:{lineno}: not a number in EuRoC pose row {shown(','.join(f[:8]))}") from None
        q = v[[4, 5, 6, 3]]  # (x, y, z, w)
        n = float(np.linalg.norm(q))
        if not np.isfinite(v).all() or n < 1e-9:
            raise SequenceError(f"{path}:{lineno}: non-finite value or zero quaternion")
        far = position_problem(v[:3] * 1000.0)
        if far:
            raise SequenceError(f"{path}:{lineno}: {far}")
        ts.append(t_ns * 1e-9)
        Ts.append(T_from_xyz_quat(v[:3] * 1000.0, q / n))
        linenos.append(lineno)
    check_increasing(path, ts, linenos)
    if not ts:
        raise SequenceError(f"ground-truth file {path}: holds no poses")
    return np.array(ts), np.stack(Ts)


def _is_euroc_csv(path: Path) -> bool:
    """Whether ``path`` is a EuRoC CSV: a ``.csv`` file, or one whose first line is a ``#`` header
    naming ``[ns]``. A byte-order mark before it (Windows editors write one) is not part of it: such a
    file was read as TUM, its ``t_ns px py pz qw qx qy qz`` rows as ``t tx ty tz qx qy qz qw``."""
    if path.suffix.lower() == ".csv":
        return True
    try:
        with open(path, encoding="utf-8-sig", errors="replace") as fh:
            head = fh.readline()
    except OSError:
        return False
    return head.startswith("#") and "[ns]" in head


def read_groundtruth_file(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """``(timestamps_s (N,), T_world_cam0 (N, 4, 4) mm)`` from a TUM or EuRoC CSV file."""
    path = Path(path)
    if not path.is_file():
        raise SequenceError(f"ground-truth file {path}: does not exist")
    return read_euroc_groundtruth(path) if _is_euroc_csv(path) else read_tum(path)

"""TUM trajectory files: ``timestamp tx ty tz qx qy qz qw`` per line, metres and seconds.

In memory a trajectory is ``(timestamps_s, T_world_cam)``: an (N,) float array and an
(N, 4, 4) array of poses with translations in **millimetres**. Conversion to metres
happens only here, so files are readable by ``evo_ape tum`` as they are.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from floorvo.errors import SequenceError, shown, shown_number
from floorvo.geometry import T_from_xyz_quat, position_problem, xyz_quat_from_T
from floorvo.io import atomic_write_text, read_text

__all__ = ["MAX_TIME_S", "write_tum", "read_tum", "format_tum", "check_increasing", "time_problem"]


def format_tum(timestamps_s: np.ndarray, T_world_cam: np.ndarray, header: str | None = None) -> str:
    """TUM text of poses (N, 4, 4) in mm at ``timestamps_s`` (N,)."""
    timestamps_s = np.asarray(timestamps_s, dtype=float)
    T_world_cam = np.asarray(T_world_cam, dtype=float)
    if T_world_cam.ndim != 3 or T_world_cam.shape[1:] != (4, 4) or len(T_world_cam) != len(timestamps_s):
        raise ValueError(
            f"format_tum: need (N,) timestamps and (N, 4, 4) poses, got {timestamps_s.shape} and {T_world_cam.shape}"
        )
    lines = []
    if header:
        lines += [f"# {h}" for h in header.splitlines()]
    for ts, T in zip(timestamps_s, T_world_cam):
        xyz_mm, q = xyz_quat_from_T(T)
        xyz = xyz_mm / 1000.0
        lines.append(f"{ts:.6f} {xyz[0]:.9f} {xyz[1]:.9f} {xyz[2]:.9f} {q[0]:.12f} {q[1]:.12f} {q[2]:.12f} {q[3]:.12f}")
    return "\n".join(lines) + "\n"


def write_tum(
    path: str | os.PathLike, timestamps_s: np.ndarray, T_world_cam: np.ndarray, header: str | None = None
) -> None:
    """Write a TUM file atomically (translations converted mm -> m)."""
    atomic_write_text(path, format_tum(timestamps_s, T_world_cam, header))


#: The largest time (s, either sign) a frame or a pose may have: a Unix time in seconds until the
#: year 2286. A larger one is a time in another unit (a recording's nanoseconds or milliseconds
#: given as seconds); 1e300 s was taken and printed as a 300-digit number.
MAX_TIME_S = 1e10


def time_problem(t_s: float) -> str | None:
    """Why ``t_s`` is no time a frame or a pose may have (:data:`MAX_TIME_S`), or None."""
    if not np.isfinite(t_s):
        return "is not a finite number"
    if abs(t_s) > MAX_TIME_S:
        return (
            f"= {t_s:.6g} s is beyond {MAX_TIME_S:g} s (a time in seconds; this one looks like another unit, ns or ms)"
        )
    return None


def check_increasing(path: str | os.PathLike, timestamps_s: list[float], linenos: list[int]) -> None:
    """One-line :class:`SequenceError` unless the pose times read from ``path`` (line ``linenos[i]``
    holds ``timestamps_s[i]``) strictly increase: a trajectory is in time order, one pose per
    time. Poses out of order or repeated were scored as they stood (a path length of poses
    visited back and forth, a drift against the wrong pose)."""
    t = np.asarray(timestamps_s, dtype=float)
    for k, tk in enumerate(t):
        problem = time_problem(float(tk))
        if problem:
            raise SequenceError(f"{path}:{linenos[k]}: timestamp {problem}")
    bad = np.nonzero(np.diff(t) <= 0)[0]
    if len(bad):
        k = int(bad[0]) + 1
        raise SequenceError(
            f"{path}:{linenos[k]}: timestamp {shown_number(t[k], '.9f')} s follows {shown_number(t[k - 1], '.9f')} s: the poses' timestamps must increase"
        )


def read_tum(path: str | os.PathLike, *, allow_empty: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Read a TUM file. Returns ``(timestamps_s (N,), T_world_cam (N, 4, 4) in mm)``.

    Lines starting with ``#`` and blank lines are skipped. A malformed line, timestamps that do
    not increase (:func:`check_increasing`), or a file without pose lines unless ``allow_empty``
    (then N = 0), raises :class:`SequenceError` naming the file and line.
    """
    path = Path(path)
    if not path.is_file():
        raise SequenceError(f"{path}: trajectory file is missing")
    text = read_text(path, SequenceError, what="a TUM text file")
    ts, Ts, linenos = [], [], []
    for lineno, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.replace(",", " ").split()
        if len(parts) != 8:
            raise SequenceError(f"{path}:{lineno}: a TUM line has 8 numbers (t tx ty tz qx qy qz qw), got {len(parts)}")
        try:
            vals = [float(p) for p in parts]
        except ValueError:
            raise SequenceError(f"{path}:{lineno}: not a number in TUM line {shown(line)}") from None
        q = np.array(vals[4:8])
        q_max = float(np.max(np.abs(q)))
        n = q_max * float(np.linalg.norm(q / q_max)) if 0 < q_max < np.inf else q_max  # no overflow in the squares
        with np.errstate(over="ignore"):  # metres beyond 1.8e305 overflow in mm: refused below
            xyz_mm = np.array(vals[1:4]) * 1000.0
        if not (np.isfinite(vals).all() and np.isfinite(xyz_mm).all() and np.isfinite(n)) or n < 1e-9:
            raise SequenceError(f"{path}:{lineno}: non-finite value or zero quaternion")
        far = position_problem(xyz_mm)
        if far:
            raise SequenceError(f"{path}:{lineno}: {far}")
        ts.append(vals[0])
        Ts.append(T_from_xyz_quat(xyz_mm, q / n))
        linenos.append(lineno)
    check_increasing(path, ts, linenos)
    if not ts and allow_empty:
        return np.zeros(0), np.zeros((0, 4, 4))
    if not ts:
        raise SequenceError(f"{path}: trajectory is empty (no pose lines)")
    return np.array(ts), np.stack(Ts)

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
from floorvo.geometry import MAX_POSITION_MM, T_from_xyz_quat, position_problem, rigid_problem, xyz_quat_from_T
from floorvo.io import atomic_write_text, read_text

__all__ = ["MAX_TIME_S", "write_tum", "read_tum", "format_tum", "check_increasing", "time_problem", "times_problem"]


def format_tum(timestamps_s: np.ndarray, T_world_cam: np.ndarray, header: str | None = None) -> str:
    """TUM text of poses ``T_world_cam`` (N, 4, 4), translations in mm (written in metres), at
    ``timestamps_s`` (N,) in seconds (written with 6 decimals).

    What :func:`read_tum` reads back, or a ``ValueError`` naming the pose or time: each pose a rigid
    transform of finite numbers (:func:`floorvo.geometry.rigid_problem`; a transposed pose, a
    scaled or reflected rotation were written as another pose) within
    :data:`~floorvo.geometry.MAX_POSITION_MM` of the origin, the times finite and increasing as
    written (:func:`times_problem`)."""
    timestamps_s = np.asarray(timestamps_s, dtype=float)
    T_world_cam = np.asarray(T_world_cam, dtype=float)
    if T_world_cam.ndim != 3 or T_world_cam.shape[1:] != (4, 4) or timestamps_s.shape != (len(T_world_cam),):
        raise ValueError(
            f"format_tum: need (N,) timestamps and (N, 4, 4) poses, got {timestamps_s.shape} and {T_world_cam.shape}"
        )
    problem = rigid_problem(T_world_cam, stack=True)
    if problem is None and len(T_world_cam):
        far = np.abs(T_world_cam[:, :3, 3]).max(axis=1)
        k = int(np.argmax(far))
        problem = None if far[k] <= MAX_POSITION_MM else f"pose {k}: {position_problem(T_world_cam[k, :3, 3])}"
    if problem is not None:
        raise ValueError(f"format_tum: {problem} (poses are T_world_cam (N, 4, 4), mm)")
    when = times_problem(timestamps_s, decimals=6)
    if when is not None:
        raise ValueError(f"format_tum: pose {when[0]}: {when[1]}")
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


def times_problem(timestamps_s: np.ndarray, *, decimals: int | None = None) -> tuple[int, str] | None:
    """``(k, why)`` for the first of the times ``timestamps_s`` (N,) s that breaks the rule of a
    trajectory's times, or None: each a time (:func:`time_problem`), strictly increasing (a
    trajectory is in time order, one pose per time). ``decimals``: compared as written with that
    many decimals (a TUM file's 6: poses closer in time than that are written as one time). The
    one rule of :func:`check_increasing`, :func:`format_tum` and :func:`floorvo.metrics.check_trajectory`."""
    t = np.asarray(timestamps_s, dtype=float).reshape(-1)
    ok = np.isfinite(t) & (np.abs(t) <= MAX_TIME_S)
    if not ok.all():
        k = int(np.argmin(ok))
        return k, f"timestamp {time_problem(float(t[k]))}"
    shown_t = t if decimals is None else np.array([float(f"{x:.{decimals}f}") for x in t])
    bad = np.nonzero(np.diff(shown_t) <= 0)[0]
    if len(bad):
        k = int(bad[0]) + 1
        fmt = ".9f" if decimals is None else f".{decimals}f"
        written = "" if decimals is None or t[k] <= t[k - 1] else f" (as written, with {decimals} decimals)"
        return k, (
            f"timestamp {shown_number(shown_t[k], fmt)} s follows {shown_number(shown_t[k - 1], fmt)} s{written}: "
            "the poses' timestamps must increase"
        )
    return None


def check_increasing(path: str | os.PathLike, timestamps_s: list[float], linenos: list[int]) -> None:
    """One-line :class:`SequenceError` unless the pose times read from ``path`` (line ``linenos[i]``
    holds ``timestamps_s[i]``) strictly increase (:func:`times_problem`): a trajectory is in time
    order, one pose per time. Poses out of order or repeated were scored as they stood (a path
    length of poses visited back and forth, a drift against the wrong pose)."""
    problem = times_problem(np.asarray(timestamps_s, dtype=float))
    if problem is not None:
        k, why = problem
        raise SequenceError(f"{path}:{linenos[k]}: {why}")


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

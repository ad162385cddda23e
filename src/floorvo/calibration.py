"""Odometry scale calibration: per-axis image-to-floor scale of a rig, fitted on a known run.

Why: under grazing LEDs that ride with the camera, the relief's cast shadows lengthen
with the distance from the bar they point away from, so the picture of a bumpy floor
moves a little faster than the floor along the LED-bar axis (0.25 % on the rendered
paper-000 vinyl floor with 3 mm LEDs, under 0.1 % across the bars; BENCHMARKS.md). A
real rig has the same effect. Like a rig calibrated once against a wire encoder, fit
the scale on one run with ground truth and divide it out of every later run on that
rig and floor.

Model: each estimated step ``T_prev_cur`` (camera frame of the previous frame, mm) has
translation ``t_est = S t_true`` with ``S = diag(scale_x, scale_y)`` on the camera's x
and y axes. Least squares over the steps gives, per axis ``a``,

    scale_a = sum_i t_est,a,i t_true,a,i / sum_i t_true,a,i^2

An axis along which the run travelled less than ``min_travel_mm`` (summed |steps|) is
not observed: its scale stays 1.

File (JSON): ``{"kind": "floorvo scale calibration", "version": 1, "scale_x": .., "scale_y": ..,
"observed_x": bool, "observed_y": bool, "travel_x_mm": .., "travel_y_mm": .., "steps": N,
"estimator": NAME, "run": PATH, "sequence": PATH}``.
"""

from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from floorvo.errors import ConfigError, SequenceError, shown
from floorvo.geometry import invert_T
from floorvo.io import atomic_write_json, read_json
from floorvo.metrics import associate
from floorvo.scoring import ok_step_poses_of_run, read_run_and_groundtruth

__all__ = [
    "ScaleCalibration",
    "fit_scale_calibration",
    "calibrate_run",
    "save_scale_calibration",
    "load_scale_calibration",
    "apply_scale",
]

KIND = "floorvo scale calibration"
VERSION = 1
#: Scales outside this range are refused when a file is read (a 10 % scale error is not a
#: calibration, it is a wrong camera height or a broken run).
SCALE_RANGE = (0.9, 1.1)


@dataclass(frozen=True)
class ScaleCalibration:
    """Per-axis scale of estimated over true step translations, camera x and y axes."""

    scale_x: float = 1.0
    scale_y: float = 1.0
    observed_x: bool = False
    observed_y: bool = False
    travel_x_mm: float = 0.0
    travel_y_mm: float = 0.0
    steps: int = 0
    estimator: str = ""
    run: str = ""
    sequence: str = ""

    def to_dict(self) -> dict:
        return {"kind": KIND, "version": VERSION, **asdict(self)}


def _steps(T: np.ndarray) -> np.ndarray:
    """(N-1, 3) translations of the relative steps inv(T_i) T_i+1 of (N, 4, 4) poses, mm."""
    return (invert_T(T[:-1]) @ T[1:])[:, :3, 3].reshape(-1, 3)


def fit_scale_calibration(T_true: np.ndarray, T_est: np.ndarray, min_travel_mm: float = 10.0) -> ScaleCalibration:
    """Fit per-axis scales from corresponding poses ``T_true``, ``T_est`` (N, 4, 4), mm.

    The poses must be paired (row i of both at the same time); steps are taken between
    consecutive rows, in the camera frame of the earlier one.
    """
    T_true, T_est = np.asarray(T_true, float), np.asarray(T_est, float)
    if T_true.shape != T_est.shape or T_true.ndim != 3 or len(T_true) < 2:
        raise SequenceError(
            f"scale calibration: needs at least 2 paired poses, got {len(T_true)} true and {len(T_est)} estimated"
        )
    return _fit_steps(_steps(T_true), _steps(T_est), min_travel_mm)


def _fit_steps(g: np.ndarray, e: np.ndarray, min_travel_mm: float) -> ScaleCalibration:
    """The per-axis least-squares scales of estimated over true step translations ``e``, ``g`` (K, 3), mm."""
    out: dict[str, Any] = {}
    for k, axis in enumerate("xy"):
        travel = float(np.abs(g[:, k]).sum())
        den = float(g[:, k] @ g[:, k])
        observed = travel >= min_travel_mm and den > 0
        scale = float(e[:, k] @ g[:, k]) / den if observed else 1.0
        out[f"scale_{axis}"], out[f"observed_{axis}"], out[f"travel_{axis}_mm"] = scale, observed, travel
    return ScaleCalibration(steps=len(g), **out)


def calibrate_run(
    run_dir: str | os.PathLike, seq_dir: str | os.PathLike, max_diff_s: float = 0.01, min_travel_mm: float = 10.0
) -> ScaleCalibration:
    """Fit the scales of ``RUN/trajectory.txt`` against ``SEQ/groundtruth.txt`` (or a TUM file).

    With the run's ``timing.csv`` (statuses and reasons), each step is compared with the true
    motion from the frame it was measured from (:func:`floorvo.scoring.ok_step_poses_of_run`):
    after an estimator restarted its track on a lost frame, the step between two consecutive
    poses of the trajectory lacks the motion over the gap, and paired with the true motion
    between those poses it pulled the scale down (0.17-0.49 fitted on a half-size ceramic
    floor that lost steps). Without ``timing.csv``, consecutive poses as they are.
    """
    run_dir, seq_dir = Path(run_dir), Path(seq_dir)
    gt, (t_ref, T_ref), run = read_run_and_groundtruth(run_dir, seq_dir, "calibrate")
    i_ref, i_est = associate(t_ref, run.timestamps_s, max_diff_s)
    if len(i_ref) < 2:
        raise SequenceError(f"{run_dir}/trajectory.txt: fewer than 2 poses match {gt} in time (within {max_diff_s} s)")
    poses = ok_step_poses_of_run(run, seq_dir, t_ref, T_ref, max_diff_s)
    if poses is None:
        cal = fit_scale_calibration(T_ref[i_ref], run.T_world_cam[i_est], min_travel_mm)
    else:
        A, A_from, B = poses
        g = (invert_T(A_from) @ A[1:])[:, :3, 3]
        e = (invert_T(B[:-1]) @ B[1:])[:, :3, 3]
        known = np.isfinite(g).all(axis=1)
        if known.sum() < 1:
            raise SequenceError(f"{run_dir}: no tracked step has a true pose at both ends in {gt}")
        cal = _fit_steps(g[known], e[known], min_travel_mm)
    return ScaleCalibration(
        **{
            **asdict(cal),
            "estimator": str(run.result.get("estimator", "")),
            "run": str(run_dir),
            "sequence": str(seq_dir),
        }
    )


def save_scale_calibration(cal: ScaleCalibration, path: str | os.PathLike) -> None:
    atomic_write_json(path, cal.to_dict())


def load_scale_calibration(path: str | os.PathLike) -> ScaleCalibration:
    """Read a calibration file; a wrong kind, version, key or value is a one-line ConfigError."""
    d = read_json(path, ConfigError)
    if not isinstance(d, dict) or d.get("kind") != KIND:
        raise ConfigError(
            f"{path}: not a scale calibration (\"kind\" must be {KIND!r}; write one with 'floorvo calibrate')"
        )
    if d.get("version") != VERSION:
        raise ConfigError(
            f"{path}: scale calibration version {d.get('version')!r}, this floorvo reads version {VERSION}"
        )
    fields = set(ScaleCalibration.__dataclass_fields__)
    unknown = sorted(set(d) - fields - {"kind", "version"})
    if unknown:
        raise ConfigError(f"{path}: unknown key {shown(unknown[0])} in a scale calibration")
    for axis in "xy":
        v = d.get(f"scale_{axis}")
        if (
            not isinstance(v, (int, float))
            or isinstance(v, bool)
            or not math.isfinite(v)
            or not SCALE_RANGE[0] <= v <= SCALE_RANGE[1]
        ):
            raise ConfigError(
                f"{path}: scale_{axis} = {shown(v)} must be a number in [{SCALE_RANGE[0]}, {SCALE_RANGE[1]}]"
            )
    return ScaleCalibration(**{k: v for k, v in d.items() if k in fields})


def apply_scale(T_prev_cur: np.ndarray, cal: ScaleCalibration) -> np.ndarray:
    """The step ``T_prev_cur`` (4, 4), mm, with its camera-frame x, y translation divided by the scales."""
    T = np.array(T_prev_cur, dtype=float, copy=True)
    T[0, 3] /= cal.scale_x
    T[1, 3] /= cal.scale_y
    return T

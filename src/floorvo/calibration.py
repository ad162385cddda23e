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
and y axes, and yaw (its rotation about the camera's z axis) ``yaw_est = scale_yaw
yaw_true``. Least squares over the steps gives, per axis ``a``,

    scale_a = sum_i t_est,a,i t_true,a,i / sum_i t_true,a,i^2

and ``scale_yaw`` likewise from the steps' yaw changes. An axis along which the runs
travelled less than ``min_travel_mm`` (summed |steps|) is not observed: its scale stays 1;
so is the yaw of runs that turned less than ``min_turn_deg`` (summed |yaw changes|): a
straight run calibrates the translation, a turning one (a spin in place) the yaw, and
``floorvo calibrate`` fits one file on several runs together. Why the yaw: the shading the
rig's lights cast turns with the rig, not with the floor, and the estimators measure a
floor-dependent share of each turn too much or too little (0.39 % too little on the rendered
wood floor, 0.3 % too much on concrete; BENCHMARKS.md, "The turn error"), which on a turning
run swings the rest of the path and which the translation's scales cannot take out.

File (JSON): ``{"kind": "floorvo scale calibration", "version": 2, "scale_x": .., "scale_y": ..,
"observed_x": bool, "observed_y": bool, "travel_x_mm": .., "travel_y_mm": .., "steps": N,
"estimator": NAME, "run": PATH, "sequence": PATH, "scale_yaw": .., "observed_yaw": bool,
"turn_deg": ..}``; version 1 (no yaw: ``scale_yaw`` 1) is read too. Several runs: ``run`` and
``sequence`` list them, separated by ``"; "``.
"""

from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from floorvo.config import Rule
from floorvo.errors import ConfigError, SequenceError, shown
from floorvo.geometry import invert_T, rot_z, yaw_of_R, yaws_of_T
from floorvo.io import atomic_write_json, read_json
from floorvo.metrics import associate
from floorvo.scoring import ok_step_poses_of_run, read_run_and_groundtruth

__all__ = [
    "ScaleCalibration",
    "fit_scale_calibration",
    "calibrate_run",
    "calibrate_runs",
    "save_scale_calibration",
    "load_scale_calibration",
    "apply_scale",
]

KIND = "floorvo scale calibration"
VERSION = 2
#: The file versions this floorvo reads (1: no yaw scale).
READABLE_VERSIONS = (1, 2)
#: Scales outside this range are refused when a file is read (a 10 % scale error is not a
#: calibration, it is a wrong camera height or a broken run).
SCALE_RANGE = (0.9, 1.1)


@dataclass(frozen=True)
class ScaleCalibration:
    """Per-axis scale of estimated over true step translations, camera x and y axes, and of
    the estimated over the true yaw changes (``scale_yaw``; ``turn_deg``: the summed |true yaw
    changes| it was fitted on)."""

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
    scale_yaw: float = 1.0
    observed_yaw: bool = False
    turn_deg: float = 0.0

    def to_dict(self) -> dict:
        return {"kind": KIND, "version": VERSION, **asdict(self)}


def _steps(T: np.ndarray) -> np.ndarray:
    """(N-1, 4, 4) relative steps inv(T_i) T_i+1 of (N, 4, 4) poses, mm."""
    return (invert_T(T[:-1]) @ T[1:]).reshape(-1, 4, 4)


def fit_scale_calibration(
    T_true: np.ndarray, T_est: np.ndarray, min_travel_mm: float = 10.0, min_turn_deg: float = 10.0
) -> ScaleCalibration:
    """Fit per-axis scales (and the yaw's) from corresponding poses ``T_true``, ``T_est`` (N, 4, 4), mm.

    The poses must be paired (row i of both at the same time); steps are taken between
    consecutive rows, in the camera frame of the earlier one.
    """
    T_true, T_est = np.asarray(T_true, float), np.asarray(T_est, float)
    if T_true.shape != T_est.shape or T_true.ndim != 3 or len(T_true) < 2:
        raise SequenceError(
            f"scale calibration: needs at least 2 paired poses, got {len(T_true)} true and {len(T_est)} estimated"
        )
    return _fit_steps(_steps(T_true), _steps(T_est), min_travel_mm, min_turn_deg)


def _fit_steps(G: np.ndarray, E: np.ndarray, min_travel_mm: float, min_turn_deg: float = 10.0) -> ScaleCalibration:
    """The least-squares scales of estimated over true steps ``E``, ``G`` (K, 4, 4), mm: per
    camera axis of their translations, and of their yaw changes."""
    for name, value, unit in (("--min-travel-mm", min_travel_mm, "mm"), ("--min-turn-deg", min_turn_deg, "deg")):
        problem = Rule(min=0.0, unit=unit).violation(float(value))
        if problem:  # NaN left every axis 'not observed' at scale 1, exit 0
            raise ConfigError(f"{name} = {value} {unit}: {problem}")
    g, e = G[:, :3, 3], E[:, :3, 3]
    out: dict[str, Any] = {}
    for k, axis in enumerate("xy"):
        travel = float(np.abs(g[:, k]).sum())
        den = float(g[:, k] @ g[:, k])
        observed = travel >= min_travel_mm and den > 0
        scale = float(e[:, k] @ g[:, k]) / den if observed else 1.0
        out[f"scale_{axis}"], out[f"observed_{axis}"], out[f"travel_{axis}_mm"] = scale, observed, travel
    yaw_g, yaw_e = np.degrees(yaws_of_T(G)), np.degrees(yaws_of_T(E))
    turn = float(np.abs(yaw_g).sum())
    den = float(yaw_g @ yaw_g)
    observed = turn >= min_turn_deg and den > 0
    out["scale_yaw"] = float(yaw_e @ yaw_g) / den if observed else 1.0
    out["observed_yaw"], out["turn_deg"] = observed, turn
    return ScaleCalibration(steps=len(G), **out)


def calibrate_run(
    run_dir: str | os.PathLike,
    seq_dir: str | os.PathLike,
    max_diff_s: float = 0.01,
    min_travel_mm: float = 10.0,
    min_turn_deg: float = 10.0,
) -> ScaleCalibration:
    """Fit the scales of ``RUN/trajectory.txt`` against ``SEQ/groundtruth.txt`` (or a TUM file).

    With the run's ``timing.csv`` (statuses and reasons), each step is compared with the true
    motion from the frame it was measured from (:func:`floorvo.scoring.ok_step_poses_of_run`):
    after an estimator restarted its track on a lost frame, the step between two consecutive
    poses of the trajectory lacks the motion over the gap, and paired with the true motion
    between those poses it pulled the scale down (0.17-0.49 fitted on a half-size ceramic
    floor that lost steps). Without ``timing.csv``, consecutive poses as they are.
    """
    return calibrate_runs([(run_dir, seq_dir)], max_diff_s, min_travel_mm, min_turn_deg)


def calibrate_runs(
    runs: list[tuple[str | os.PathLike, str | os.PathLike]],
    max_diff_s: float = 0.01,
    min_travel_mm: float = 10.0,
    min_turn_deg: float = 10.0,
) -> ScaleCalibration:
    """One calibration fitted on the steps of several ``(run folder, sequence)`` pairs together
    (each as :func:`calibrate_run`): a straight run for the translation's scales and a turning
    one for the yaw's, say. The runs must be of one estimator (``result.json``)."""
    if not runs:
        raise SequenceError("scale calibration: no run given")
    G, E, names = [], [], set()
    for run_dir, seq_dir in runs:
        g, e, estimator = _run_steps(Path(run_dir), Path(seq_dir), max_diff_s)
        G.append(g)
        E.append(e)
        names.add(estimator)
    if len(names) > 1:
        raise SequenceError(
            f"scale calibration: the runs are of different estimators ({', '.join(sorted(names))}); "
            "a calibration is of one estimator on one rig"
        )
    cal = _fit_steps(np.concatenate(G), np.concatenate(E), min_travel_mm, min_turn_deg)
    return ScaleCalibration(
        **{
            **asdict(cal),
            "estimator": names.pop(),
            "run": "; ".join(str(r) for r, _ in runs),
            "sequence": "; ".join(str(s) for _, s in runs),
        }
    )


def _run_steps(run_dir: Path, seq_dir: Path, max_diff_s: float) -> tuple[np.ndarray, np.ndarray, str]:
    """The true and estimated steps (K, 4, 4) of a run (:func:`calibrate_run`) and its estimator's name."""
    gt, (t_ref, T_ref), run = read_run_and_groundtruth(run_dir, seq_dir, "calibrate")
    i_ref, i_est = associate(t_ref, run.timestamps_s, max_diff_s)
    if len(i_ref) < 2:
        raise SequenceError(f"{run_dir}/trajectory.txt: fewer than 2 poses match {gt} in time (within {max_diff_s} s)")
    estimator = str(run.result.get("estimator", ""))
    poses = ok_step_poses_of_run(run, seq_dir, t_ref, T_ref, max_diff_s)
    if poses is None:
        return _steps(T_ref[i_ref]), _steps(run.T_world_cam[i_est]), estimator
    A, A_from, B = poses
    g = invert_T(A_from) @ A[1:]
    e = invert_T(B[:-1]) @ B[1:]
    known = np.isfinite(g).all(axis=(1, 2))
    if known.sum() < 1:
        raise SequenceError(f"{run_dir}: no tracked step has a true pose at both ends in {gt}")
    return g[known], e[known], estimator


def save_scale_calibration(cal: ScaleCalibration, path: str | os.PathLike) -> None:
    atomic_write_json(path, cal.to_dict())


def load_scale_calibration(path: str | os.PathLike, estimator: str | None = None) -> ScaleCalibration:
    """Read a calibration file; a wrong kind, version, key or value is a one-line ConfigError.

    ``estimator``: the estimator it is to be applied to; a file fitted on another estimator's
    run (its ``estimator``) is refused: a calibration is fitted per estimator, rig and floor,
    and akaze-guided's was divided out of phase-corr's steps without a word.
    """
    d = read_json(path, ConfigError)
    if not isinstance(d, dict) or d.get("kind") != KIND:
        raise ConfigError(
            f"{path}: not a scale calibration (\"kind\" must be {KIND!r}; write one with 'floorvo calibrate')"
        )
    if d.get("version") not in READABLE_VERSIONS:
        raise ConfigError(
            f"{path}: scale calibration version {d.get('version')!r}, this floorvo reads versions "
            f"{', '.join(map(str, READABLE_VERSIONS))}"
        )
    fields = set(ScaleCalibration.__dataclass_fields__)
    unknown = sorted(set(d) - fields - {"kind", "version"})
    if unknown:
        raise ConfigError(f"{path}: unknown key {shown(unknown[0])} in a scale calibration")
    for axis in ("x", "y", "yaw"):
        if axis == "yaw" and "scale_yaw" not in d:
            continue  # version 1: no yaw scale (1)
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
    cal = ScaleCalibration(**{k: v for k, v in d.items() if k in fields})
    if estimator is not None and cal.estimator and cal.estimator != estimator:
        raise ConfigError(
            f"{path}: fitted on a run of {shown(cal.estimator)}, not {shown(estimator)}; fit one per estimator "
            f"(floorvo calibrate on a run of {shown(estimator)})"
        )
    return cal


def apply_scale(T_prev_cur: np.ndarray, cal: ScaleCalibration) -> np.ndarray:
    """The step ``T_prev_cur`` (4, 4), mm, with its camera-frame x, y translation divided by the
    scales, and its yaw by ``scale_yaw`` (the rotation turned about the previous camera's z axis
    by yaw / scale_yaw - yaw; roll and pitch kept)."""
    T = np.array(T_prev_cur, dtype=float, copy=True)
    T[0, 3] /= cal.scale_x
    T[1, 3] /= cal.scale_y
    if cal.scale_yaw != 1.0:
        yaw = yaw_of_R(T[:3, :3])
        T[:3, :3] = rot_z(yaw / cal.scale_yaw - yaw) @ T[:3, :3]
    return T

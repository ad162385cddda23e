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

On a grained floor the scales depend on how the grain lies under the rig's lights. The
shading the grazing light casts in the grain's grooves depends on the angle between the grain
and the light, and the light turns with the camera: the rendered wood floor's picture reads
each turn 0.7 % short where its grain lies along the light (camera x) and 0.1 % long across
it, and each step along x 0.02 % long along the grain and 0.18 % across it (BENCHMARKS.md,
"Wood: the turn and the step depend on the grain's angle to the lights"). A spin over part
of a turn, or a straight run at one heading, gives one average of that; a path that turns
through other angles is measured otherwise. Where the calibration runs show it, each scale
is a function of the step's texture orientation ``theta`` (the floor's dominant gradient
direction in the image, :func:`floorvo.imaging.texture_orientation`, the mean of the step's
two frames)::

    scale_a(theta) = scale_a + a_cos2 cos(2 theta) + a_sin2 sin(2 theta)

(period 180 degrees: the grain is an axis), fitted by least squares like the constant
(regressors ``u``, ``u cos 2 theta``, ``u sin 2 theta`` for the true step component ``u``),
and only where the runs' frames have a direction (mean coherence at least
:data:`ORIENTATION_MIN_COHERENCE`: a grain, not the light's own direction), where ``theta``
turned over the axis's steps (their doubled-angle resultant, weighted by ``u^2``, at most
:data:`ORIENTATION_MAX_RESULTANT`: spread over about 108 of its 180 degrees) and where the two terms are
significant (their chi-square, from the fit's residual, at least :data:`ORIENTATION_MIN_CHI2`:
p < 0.001). Otherwise they are 0 and the scale is the constant, as before. A run applies them
with each step's ``theta`` (:func:`floorvo.runner.run_frames`). The runs of ``floorvo
calibrate`` for them: straight runs at three headings over the floor (0, 60 and 120
degrees) for the translation, a spin over more than half a turn for the yaw (a fit on the
115 degrees of a 2-rad spin read the other 65 0.1-0.2 % of the turn wrong).

File (JSON): ``{"kind": "floorvo scale calibration", "version": 3, "scale_x": .., "scale_y": ..,
"observed_x": bool, "observed_y": bool, "travel_x_mm": .., "travel_y_mm": .., "steps": N,
"estimator": NAME, "run": PATH, "sequence": PATH, "scale_yaw": .., "observed_yaw": bool,
"turn_deg": .., "x_cos2": .., "x_sin2": .., "y_cos2": .., "y_sin2": .., "yaw_cos2": ..,
"yaw_sin2": .., "orientation_coherence": ..}``; versions 1 (no yaw: ``scale_yaw`` 1) and 2 (no
orientation terms: 0) are read too. Several runs: ``run`` and ``sequence`` list them,
separated by ``"; "``.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from floorvo.config import Rule, build, param
from floorvo.errors import ConfigError, SequenceError, shorten, shown
from floorvo.geometry import invert_T, rot_z, yaw_of_R, yaws_of_T
from floorvo.imaging import mean_orientation, texture_orientation
from floorvo.io import atomic_write_json, read_json
from floorvo.metrics import associate
from floorvo.runfolder import sequence_content_sha256
from floorvo.scoring import ok_step_frames_of_run, ok_step_poses_of_run, read_run_and_groundtruth
from floorvo.sequence import Sequence

__all__ = [
    "ScaleCalibration",
    "fit_scale_calibration",
    "calibrate_run",
    "calibrate_runs",
    "scale_range_problem",
    "RunSteps",
    "run_steps",
    "save_scale_calibration",
    "load_scale_calibration",
    "apply_scale",
    "calibration_use_problems",
]

KIND = "floorvo scale calibration"
VERSION = 3
#: The file versions this floorvo reads (1: no yaw scale; 2: no texture-orientation terms).
READABLE_VERSIONS = (1, 2, 3)
#: Scales outside this range are refused when a file is read (a 10 % scale error is not a
#: calibration, it is a wrong camera height or a broken run).
SCALE_RANGE = (0.9, 1.1)
#: The texture-orientation terms (module docstring) are fitted only on frames whose texture has
#: a direction this coherent on average (:func:`floorvo.imaging.texture_orientation`: the rendered
#: wood floor 0.9; concrete, vinyl, asphalt 0.2-0.4, whose direction is the light's) ...
ORIENTATION_MIN_COHERENCE = 0.5
#: ... whose orientation turned over the axis's steps: the u^2-weighted resultant of exp(2i theta)
#: at most this (sin(d)/d for orientations spread evenly over d degrees of the 180: 0.5 is about
#: 108; a fit on less extrapolates the rest) ...
ORIENTATION_MAX_RESULTANT = 0.5
#: ... and where the two terms are significant: their chi-square (2 degrees of freedom) at least this (p < 0.001).
ORIENTATION_MIN_CHI2 = 13.8
_AXES = ("x", "y", "yaw")


@dataclass(frozen=True)
class ScaleCalibration:
    """Per-axis scale of estimated over true step translations, camera x and y axes, and of
    the estimated over the true yaw changes (``scale_yaw``; ``turn_deg``: the summed |true yaw
    changes| it was fitted on)."""

    scale_x: float = param(1.0, min=SCALE_RANGE[0], max=SCALE_RANGE[1])
    scale_y: float = param(1.0, min=SCALE_RANGE[0], max=SCALE_RANGE[1])
    observed_x: bool = False
    observed_y: bool = False
    travel_x_mm: float = param(0.0, unit="mm", min=0.0)
    travel_y_mm: float = param(0.0, unit="mm", min=0.0)
    steps: int = param(0, min=0)
    estimator: str = ""
    run: str = ""  # the run folders it was fitted on, joined by "; "
    sequence: str = ""  # their sequence folders, joined by "; "
    scale_yaw: float = param(1.0, min=SCALE_RANGE[0], max=SCALE_RANGE[1])
    observed_yaw: bool = False
    turn_deg: float = param(0.0, unit="deg", min=0.0)
    x_cos2: float = 0.0
    x_sin2: float = 0.0
    y_cos2: float = 0.0
    y_sin2: float = 0.0
    yaw_cos2: float = 0.0
    yaw_sin2: float = 0.0
    orientation_coherence: float = param(0.0, min=0.0, max=1.0)
    # what the ``sequence`` folders held (floorvo.runfolder.sequence_content_sha256; "" for a
    # ground-truth file), joined by "; ": a copy of one is recognised where its path is not
    sequence_sha256: str = ""

    def to_dict(self) -> dict:
        return {"kind": KIND, "version": VERSION, **asdict(self)}

    @property
    def uses_orientation(self) -> bool:
        """Whether a scale depends on the step's texture orientation (a term is not 0): the run must give each step's."""
        return any(getattr(self, f"{a}_{t}") != 0.0 for a in _AXES for t in ("cos2", "sin2"))

    def scales(self, theta_rad: float | None = None) -> tuple[float, float, float]:
        """``(scale_x, scale_y, scale_yaw)`` of a step whose texture orientation is ``theta_rad``
        (module docstring); None: the constants, allowed only without orientation terms."""
        if not self.uses_orientation:
            return self.scale_x, self.scale_y, self.scale_yaw
        if theta_rad is None:
            raise ValueError("this scale calibration depends on the texture orientation: give the step's theta_rad")
        c, s = math.cos(2.0 * theta_rad), math.sin(2.0 * theta_rad)
        return tuple(
            getattr(self, f"scale_{a}") + getattr(self, f"{a}_cos2") * c + getattr(self, f"{a}_sin2") * s for a in _AXES
        )


def _steps(T: np.ndarray) -> np.ndarray:
    """(N-1, 4, 4) relative steps inv(T_i) T_i+1 of (N, 4, 4) poses, mm."""
    return (invert_T(T[:-1]) @ T[1:]).reshape(-1, 4, 4)


def fit_scale_calibration(
    T_true: np.ndarray,
    T_est: np.ndarray,
    min_travel_mm: float = 10.0,
    min_turn_deg: float = 10.0,
    theta_rad: np.ndarray | None = None,
    coherence: float = 0.0,
) -> ScaleCalibration:
    """Fit per-axis scales (and the yaw's) from corresponding poses ``T_true``, ``T_est`` (N, 4, 4), mm.

    The poses must be paired (row i of both at the same time); steps are taken between
    consecutive rows, in the camera frame of the earlier one. ``theta_rad`` (N-1,): each step's
    texture orientation, with ``coherence`` the frames' mean coherence, for the orientation
    terms (module docstring); None: constants only.
    """
    T_true, T_est = np.asarray(T_true, float), np.asarray(T_est, float)
    if T_true.shape != T_est.shape or T_true.ndim != 3 or len(T_true) < 2:
        raise SequenceError(
            f"scale calibration: needs at least 2 paired poses, got {len(T_true)} true and {len(T_est)} estimated"
        )
    return _fit_steps(_steps(T_true), _steps(T_est), min_travel_mm, min_turn_deg, theta_rad, coherence)


def _fit_steps(
    G: np.ndarray,
    E: np.ndarray,
    min_travel_mm: float,
    min_turn_deg: float = 10.0,
    theta_rad: np.ndarray | None = None,
    coherence: float = 0.0,
) -> ScaleCalibration:
    """The least-squares scales of estimated over true steps ``E``, ``G`` (K, 4, 4), mm: per
    camera axis of their translations, and of their yaw changes; with the steps' texture
    orientations ``theta_rad`` (K,) and the frames' mean ``coherence``, the orientation terms
    where they are observed (module docstring)."""
    for name, value, unit in (("--min-travel-mm", min_travel_mm, "mm"), ("--min-turn-deg", min_turn_deg, "deg")):
        problem = Rule(min=0.0, unit=unit).violation(float(value))
        if problem:  # NaN left every axis 'not observed' at scale 1, exit 0
            raise ConfigError(f"{name} = {value} {unit}: {problem}")
    true_by_axis = {"x": G[:, 0, 3], "y": G[:, 1, 3], "yaw": np.degrees(yaws_of_T(G))}
    est_by_axis = {"x": E[:, 0, 3], "y": E[:, 1, 3], "yaw": np.degrees(yaws_of_T(E))}
    with_orientation = theta_rad is not None and coherence >= ORIENTATION_MIN_COHERENCE
    out: dict[str, Any] = {"orientation_coherence": float(coherence) if theta_rad is not None else 0.0}
    for axis in _AXES:
        u, v = true_by_axis[axis], est_by_axis[axis]
        amount = float(np.abs(u).sum())
        den = float(u @ u)
        observed = amount >= (min_turn_deg if axis == "yaw" else min_travel_mm) and den > 0
        out[f"scale_{axis}"] = float(v @ u) / den if observed else 1.0
        out[f"observed_{axis}"] = observed
        out["turn_deg" if axis == "yaw" else f"travel_{axis}_mm"] = amount
        if observed and with_orientation:
            terms = _orientation_terms(u, v, np.asarray(theta_rad, float))
            if terms is not None:
                out[f"scale_{axis}"], out[f"{axis}_cos2"], out[f"{axis}_sin2"] = terms
    return ScaleCalibration(steps=len(G), **out)


def _orientation_terms(u: np.ndarray, v: np.ndarray, theta_rad: np.ndarray) -> tuple[float, float, float] | None:
    """``(constant, cos2, sin2)`` of ``v = u (c + a cos 2 theta + b sin 2 theta)`` by least squares
    over the steps (K,), or None where the steps do not observe the terms: theta did not turn
    (resultant over :data:`ORIENTATION_MAX_RESULTANT`), too few steps, or the terms are not
    significant (chi-square under :data:`ORIENTATION_MIN_CHI2`)."""
    w = u * u
    if len(u) < 6 or float(w.sum()) <= 0:
        return None
    resultant = abs(complex(np.sum(w * np.exp(2j * theta_rad)))) / float(w.sum())
    if resultant > ORIENTATION_MAX_RESULTANT:
        return None
    X = np.column_stack([u, u * np.cos(2 * theta_rad), u * np.sin(2 * theta_rad)])
    coef, *_ = np.linalg.lstsq(X, v, rcond=None)
    r = v - X @ coef
    dof = len(u) - 3
    if dof <= 0:
        return None
    sigma2 = max(float(r @ r) / dof, 1e-30)  # an exact fit (code-made steps): its terms are certain
    XtX = X.T @ X
    if np.linalg.cond(XtX) > 1e12:
        return None
    cov = sigma2 * np.linalg.inv(XtX)
    chi2 = float(coef[1:] @ np.linalg.solve(cov[1:, 1:], coef[1:]))
    if chi2 < ORIENTATION_MIN_CHI2:
        return None
    return float(coef[0]), float(coef[1]), float(coef[2])


def calibrate_run(
    run_dir: str | os.PathLike,
    seq_dir: str | os.PathLike,
    max_diff_s: float = 0.01,
    min_travel_mm: float = 10.0,
    min_turn_deg: float = 10.0,
    orientation: bool = True,
    check_range: bool = True,
) -> ScaleCalibration:
    """Fit the scales of ``RUN/trajectory.txt`` against ``SEQ/groundtruth.txt`` (or a TUM file).

    With the run's ``timing.csv`` (statuses and reasons), each step is compared with the true
    motion from the frame it was measured from (:func:`floorvo.scoring.ok_step_poses_of_run`):
    after an estimator restarted its track on a lost frame, the step between two consecutive
    poses of the trajectory lacks the motion over the gap, and paired with the true motion
    between those poses it pulled the scale down (0.17-0.49 fitted on a half-size ceramic
    floor that lost steps). Without ``timing.csv``, consecutive poses as they are.
    """
    return calibrate_runs([(run_dir, seq_dir)], max_diff_s, min_travel_mm, min_turn_deg, orientation, check_range)


def scale_range_problem(cal: ScaleCalibration, axes: tuple[str, ...] = _AXES) -> str:
    """Why ``cal`` is no calibration a file may hold ('' when it is): a scale of ``axes``, with
    the amplitude of its texture-orientation terms, leaves :data:`SCALE_RANGE` (a 10 % scale
    error is a wrong camera height or a broken run). The one range rule of the fit, the file's
    reader and the motion suite's per-material fits."""
    for axis in axes:
        v = getattr(cal, f"scale_{axis}")
        amp = math.hypot(getattr(cal, f"{axis}_cos2"), getattr(cal, f"{axis}_sin2"))
        if not (SCALE_RANGE[0] <= v - amp and v + amp <= SCALE_RANGE[1]):
            terms = f" +/- {amp:.5f}" if amp else ""
            return f"scale_{axis} = {v:.5f}{terms}, outside [{SCALE_RANGE[0]}, {SCALE_RANGE[1]}]"
    return ""


def calibrate_runs(
    runs: list[tuple[str | os.PathLike, str | os.PathLike]],
    max_diff_s: float = 0.01,
    min_travel_mm: float = 10.0,
    min_turn_deg: float = 10.0,
    orientation: bool = True,
    check_range: bool = True,
) -> ScaleCalibration:
    """One calibration fitted on the steps of several ``(run folder, sequence)`` pairs together
    (each as :func:`calibrate_run`): a straight run for the translation's scales and a turning
    one for the yaw's, say. The runs must be of one estimator (``result.json``). The
    texture-orientation terms (``orientation``) need every run's step frames (``timing.csv``)
    and frames (a sequence folder, not a bare ground-truth file); without them, constants only.
    Refused: runs made with a scale calibration, and a fit outside :data:`SCALE_RANGE`
    (:func:`scale_range_problem`; ``check_range=False`` returns it, for a caller that says so itself)."""
    if not runs:
        raise SequenceError("scale calibration: no run given")
    got = [run_steps(run_dir, seq_dir, max_diff_s, orientation) for run_dir, seq_dir in runs]
    for (run_dir, _), r in zip(runs, got):
        if r.calibrated:  # fitted on runs a calibration had already corrected: scales of 1, applied for nothing
            raise SequenceError(
                f"{run_dir}: was run with a scale calibration (result.json): fit on runs made without one"
            )
    G, E = [r.true for r in got], [r.est for r in got]
    names = {r.estimator for r in got}
    if len(names) > 1:
        raise SequenceError(
            f"scale calibration: the runs are of different estimators ({', '.join(sorted(names))}); "
            "a calibration is of one estimator on one rig"
        )
    # A run whose steps' frames are unknown or not there: no orientation terms.
    with_theta = orientation and all(r.theta_rad is not None for r in got)
    theta = np.concatenate([r.theta_rad for r in got]) if with_theta else None
    coherence = float(np.average([r.coherence for r in got], weights=[len(g) for g in G])) if with_theta else 0.0
    cal = _fit_steps(np.concatenate(G), np.concatenate(E), min_travel_mm, min_turn_deg, theta, coherence)
    problem = scale_range_problem(cal) if check_range else ""
    if problem:  # what the file's reader refuses: said now, not at every later use of the file
        raise SequenceError(
            f"scale calibration: the runs give {problem}: not a calibration (a wrong camera height, or runs "
            "that lost their track)"
        )
    return ScaleCalibration(
        **{
            **asdict(cal),
            "estimator": names.pop(),
            # where they are, wherever the command ran: the use check compares them with the run's
            "run": "; ".join(str(Path(r).resolve()) for r, _ in runs),
            "sequence": "; ".join(str(_sequence_folder(Path(s)).resolve()) for _, s in runs),
            "sequence_sha256": "; ".join(_content_sha256(_sequence_folder(Path(s))) for _, s in runs),
        }
    )


def _content_sha256(path: Path) -> str:
    """What the sequence folder ``path`` holds (:func:`floorvo.runfolder.sequence_content_sha256`);
    "" for what is no sequence folder (a bare ground-truth file)."""
    return sequence_content_sha256(path) if (path / "sequence.json").is_file() else ""


def _sequence_folder(path: Path) -> Path:
    """The sequence folder of ``path``: the folder itself, or the folder of its ``groundtruth.txt``."""
    if path.name == "groundtruth.txt" and (path.parent / "sequence.json").is_file():
        return path.parent
    return path


@dataclass(frozen=True)
class RunSteps:
    """The steps of a run a calibration is fitted on (:func:`run_steps`): ``true``, ``est`` (K, 4, 4)
    mm, each step's true and estimated motion in the camera frame of the frame it was measured
    from; ``estimator``: the run's; ``theta_rad`` (K,): each step's texture orientation
    (:func:`floorvo.imaging.texture_orientation`, the mean of its two frames'), None where it
    was not asked for or cannot be measured; ``coherence``: the frames' mean (0 without)."""

    true: np.ndarray
    est: np.ndarray
    estimator: str
    theta_rad: np.ndarray | None = None
    coherence: float = 0.0
    calibrated: bool = False  # the run was made with a scale calibration (its result.json)


def run_steps(
    run_dir: str | os.PathLike, seq_dir: str | os.PathLike, max_diff_s: float = 0.01, orientation: bool = True
) -> RunSteps:
    """The steps of a run against its ground truth (:func:`calibrate_run`'s pairing) and, with
    ``orientation``, their texture orientations, read from the sequence's frames (none without
    ``timing.csv``, for a bare ground-truth file, or a sequence without frames)."""
    run_dir, seq_dir = Path(run_dir), Path(seq_dir)
    g, e, estimator, frames, calibrated = _run_steps(run_dir, seq_dir, max_diff_s)
    orient = _step_orientations(seq_dir, *frames) if orientation and frames is not None else None
    if orient is None:
        return RunSteps(g, e, estimator, calibrated=calibrated)
    return RunSteps(g, e, estimator, *orient, calibrated=calibrated)


def _run_steps(
    run_dir: Path, seq_dir: Path, max_diff_s: float
) -> tuple[np.ndarray, np.ndarray, str, tuple[np.ndarray, np.ndarray] | None, bool]:
    """The true and estimated steps (K, 4, 4) of a run (:func:`calibrate_run`), its estimator's
    name, each step's sequence frames ``(from (K,), to (K,))`` (None: unknown, a run without
    ``timing.csv``, or a bare ground-truth file), and whether it was made with a scale calibration."""
    gt, (t_ref, T_ref), run = read_run_and_groundtruth(run_dir, seq_dir, "calibrate")
    if len(run.timestamps_s) < 2:  # a run that lost every frame: said as such, not as a timing mismatch
        raise SequenceError(
            f"{run_dir}/trajectory.txt: holds {len(run.timestamps_s)} pose(s): the run measured no step to calibrate with"
        )
    i_ref, i_est = associate(t_ref, run.timestamps_s, max_diff_s)
    if len(i_ref) < 2:
        raise SequenceError(f"{run_dir}/trajectory.txt: fewer than 2 poses match {gt} in time (within {max_diff_s} s)")
    estimator = str(run.result.get("estimator", ""))
    calibrated = bool(run.result.get("scale_calibration"))
    poses = ok_step_poses_of_run(run, seq_dir, t_ref, T_ref, max_diff_s)
    if poses is None:
        return _steps(T_ref[i_ref]), _steps(run.T_world_cam[i_est]), estimator, None, calibrated
    A, A_from, B = poses
    g = invert_T(A_from) @ A[1:]
    e = invert_T(B[:-1]) @ B[1:]
    known = np.isfinite(g).all(axis=(1, 2))
    if known.sum() < 1:
        raise SequenceError(f"{run_dir}: no tracked step has a true pose at both ends in {gt}")
    frames = ok_step_frames_of_run(run) if (seq_dir / "sequence.json").is_file() else None
    if frames is not None:
        frames = (frames[0][known], frames[1][known])
    return g[known], e[known], estimator, frames, calibrated


def _step_orientations(seq_dir: Path, frm: np.ndarray, to: np.ndarray) -> tuple[np.ndarray, float] | None:
    """Each step's texture orientation (K,) rad (the mean of its two frames',
    :func:`floorvo.imaging.mean_orientation`) and the frames' mean coherence; None for a sequence
    that holds no frames (its ground truth only). A frame missing among others, or unreadable, is
    an error (:meth:`floorvo.sequence.Sequence.image`)."""
    seq = Sequence.open(seq_dir)
    if not any(seq.image_path(int(i)).is_file() for i in frm[:1]):
        return None
    per_frame = {int(i): texture_orientation(seq.image(int(i))) for i in np.unique(np.concatenate([frm, to]))}
    theta = np.array([mean_orientation(per_frame[int(a)][0], per_frame[int(b)][0]) for a, b in zip(frm, to)])
    return theta, float(np.mean([c for _, c in per_frame.values()]))


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
    for axis in _AXES:
        terms = [d.get(f"{axis}_{t}", 0.0) for t in ("cos2", "sin2")]
        for t, v in zip(("cos2", "sin2"), terms):
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
                raise ConfigError(f"{path}: {axis}_{t} = {shown(v)} must be a finite number")
    if d["version"] >= 2 and "scale_yaw" not in d:
        raise ConfigError(f"{path}: scale_yaw is missing (a version {d['version']} file has one)")
    try:  # every field's type and rule (a run or sequence that is no text was a traceback where used)
        cal = build(ScaleCalibration, {k: v for k, v in d.items() if k in fields})
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None
    for axis in _AXES:  # the range rule of the fit (scale_range_problem), said with the span the terms give
        if scale_range_problem(cal, (axis,)):
            v = getattr(cal, f"scale_{axis}")
            amp = math.hypot(getattr(cal, f"{axis}_cos2"), getattr(cal, f"{axis}_sin2"))
            raise ConfigError(
                f"{path}: scale_{axis} with its orientation terms spans [{v - amp:.4f}, {v + amp:.4f}]; it must "
                f"stay in [{SCALE_RANGE[0]}, {SCALE_RANGE[1]}]"
            )
    if estimator is not None and cal.estimator and cal.estimator != estimator:
        raise ConfigError(
            f"{path}: fitted on a run of {shown(cal.estimator)}, not {shown(estimator)}; fit one per estimator "
            f"(floorvo calibrate on a run of {shown(estimator)})"
        )
    return cal


def calibration_use_problems(
    cal: ScaleCalibration, seq_dir: str | os.PathLike, config: Mapping[str, Any] | None = None
) -> list[str]:
    """What is wrong with applying ``cal`` to a run over the sequence ``seq_dir`` with the estimator
    config ``config`` (its ``asdict``), one line each ([] where nothing is): the sequence is one
    the calibration was fitted on (its ``sequence``: a score of that run measures what was tuned on
    it), or the config differs from that of a run it was fitted on (its ``run`` folders'
    ``result.json``, where they are still there: a calibration is fitted per estimator config).
    """
    problems = []
    if not cal.estimator:  # fitted on runs without a result.json: the estimator check passed any
        problems.append(
            "the scale calibration names no estimator (its runs had no result.json): that it is this estimator's "
            "is not checked"
        )
    here = Path(seq_dir).resolve()
    fitted_on = [_sequence_folder(Path(s)) for s in cal.sequence.split("; ") if s]
    held = {h for h in cal.sequence_sha256.split("; ") if h and h != "unreadable"}
    same = any(s.resolve() == here for s in fitted_on)
    if not same and held and _content_sha256(here) in held:
        same = True  # a copy (or the same scene rendered again, bit for bit) of a sequence it was fitted on
    if same:
        problems.append(
            f"the scale calibration was fitted on this sequence ({shorten(str(seq_dir))}, or one holding the same "
            "files): a score of this run measures what the calibration was tuned on; fit it on a separate run"
        )
    if config is not None:
        # As result.json holds it (a tuple read back is a list): the same config compares equal.
        config = json.loads(json.dumps(dict(config), default=str))
        for run in (Path(r) for r in cal.run.split("; ") if r):
            try:
                fitted = read_json(run / "result.json", ConfigError).get("config")
            except (ConfigError, AttributeError):
                continue  # the run folder is gone or not a run's: nothing to compare with
            if not isinstance(fitted, dict):
                continue
            differ = sorted(k for k in set(fitted) | set(config) if fitted.get(k) != config.get(k))
            if differ:
                shown_keys = ", ".join(
                    f"{k} = {shown(fitted.get(k))} there, {shown(config.get(k))} here" for k in differ[:3]
                )
                more = f" and {len(differ) - 3} more" if len(differ) > 3 else ""
                problems.append(
                    f"the scale calibration was fitted on a run of another estimator config ({run}: {shown_keys}{more})"
                )
                break
    return problems


def apply_scale(T_prev_cur: np.ndarray, cal: ScaleCalibration, theta_rad: float | None = None) -> np.ndarray:
    """The step ``T_prev_cur`` (4, 4), mm, with its camera-frame x, y translation divided by the
    scales, and its yaw by the yaw's (the rotation turned about the previous camera's z axis
    by yaw / scale_yaw - yaw; roll and pitch kept). ``theta_rad``: the step's texture orientation
    (:meth:`ScaleCalibration.scales`), needed when the calibration has orientation terms."""
    scale_x, scale_y, scale_yaw = cal.scales(theta_rad)
    T = np.array(T_prev_cur, dtype=float, copy=True)
    T[0, 3] /= scale_x
    T[1, 3] /= scale_y
    if scale_yaw != 1.0:
        yaw = yaw_of_R(T[:3, :3])
        T[:3, :3] = rot_z(yaw / scale_yaw - yaw) @ T[:3, :3]
    return T

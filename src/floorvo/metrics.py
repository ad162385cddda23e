"""Trajectory metrics: ATE, RPE, drift, KITTI-style segment errors, tracking loss, timing.

Every function here is pure: it takes ``(timestamps_s (N,), T_world_cam (N, 4, 4) mm)``
arrays and returns new arrays or plain numbers; inputs are never modified (evo aligns in
place; this module never does), and no file is read or written: the scoring of a run
folder is :mod:`floorvo.scoring`, the names of the scored numbers :mod:`floorvo.metric_defs`.

Conventions
-----------
* Poses are 4x4 ``float64`` ``T_world_cam`` with translations in millimetres; angles are
  reported in degrees (the only place degrees appear), errors in millimetres.
* ``ref`` is the ground truth, ``est`` the estimate. After :func:`associate` both arrays
  have the same length and pair up index by index.
* Alignment (stated in every result under ``alignment``):

  - ``none``: the poses as they are (an estimator's trajectory starts at the first
    ground-truth pose, so this is what a robot would see);
  - ``origin``: ``est`` moved rigidly so its first pose equals the first ``ref`` pose
    (evo's ``--align_origin``);
  - ``se2``: the least-squares rotation about world z and translation in x, y
    (Umeyama in the floor plane, :func:`floorvo.geometry.rigid_fit`; z untouched): the
    natural gauge of floor odometry;
  - ``se3``: the least-squares rigid motion in 3D (Umeyama, no scale; evo's ``--align``).
    Positions on one straight line leave the turn about that line free (evo refuses them:
    "Degenerate covariance rank"; the SVD's pick was arbitrary, 0-180 degrees of rotation error
    for an estimate off by a constant offset): the least rotation that lays the estimate's line
    on the reference's is taken (:func:`_line_alignment`).

* RPE follows evo's definition: for index pairs (i, j), ``E = (ref_i^-1 ref_j)^-1
  (est_i^-1 est_j)``; the translation error is ``|t(E)|`` (mm), the rotation error is the
  angle of ``R(E)`` (degrees). Per frame: consecutive associated poses. Per distance:
  from every pose ``i`` to the first pose ``j`` at which the reference has travelled at
  least ``delta_mm`` further along its path.
* Drift: the end-point error ``|t_est(end) - t_ref(end)|`` in % of the reference path
  length, and the KITTI devkit's segment errors: for every start pose and every segment
  length L (floor lengths 10, 25, 50, 100 mm and up, those shorter than the path), the
  translation error of the relative motion over the segment in % of L and its rotation
  error in degrees per metre, averaged per length.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from collections.abc import Sequence as SequenceT
from typing import Any

import numpy as np

from floorvo.config import Rule
from floorvo.errors import ConfigError
from floorvo.geometry import invert_T, least_rotation, rigid_fit, rigid_problem, yaws_of_T
from floorvo.tum import times_problem

__all__ = [
    "ALIGNMENTS",
    "SEGMENT_LENGTHS_MM",
    "check_trajectory",
    "associate",
    "align",
    "path_distances_mm",
    "error_stats",
    "ate",
    "rpe_pairs_by_frames",
    "rpe_pairs_by_distance",
    "rpe",
    "step_errors",
    "wrong_steps",
    "turn_error",
    "MIN_TURN_DEG",
    "reason_kind",
    "lost_reasons",
    "end_point_drift",
    "segment_errors",
    "translation_error_along_path",
    "tracking_stats",
    "timing_stats",
]

ALIGNMENTS = ("none", "origin", "se2", "se3")
#: Default KITTI-style segment lengths for floors (mm): 10, 25, 50, 100 and up.
SEGMENT_LENGTHS_MM = (10.0, 25.0, 50.0, 100.0, 250.0, 500.0, 1000.0, 2000.0, 5000.0)


def check_trajectory(timestamps_s: np.ndarray, T: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray]:
    """``(timestamps_s (N,) s, T (N, 4, 4) mm)`` as float arrays, or a one-line ValueError naming
    ``what`` and the rule: other shapes; a pose that is no rigid transform of finite numbers
    (:func:`~floorvo.geometry.rigid_problem`: a transposed stack, a scaled or reflected rotation, NaN);
    times that are not finite, within :data:`~floorvo.tum.MAX_TIME_S`, and strictly increasing
    (:func:`~floorvo.tum.times_problem`, the rule of a TUM file's times). Units cannot be checked:
    translations are millimetres (metres give every error 1000 times too small)."""
    ts = np.asarray(timestamps_s, dtype=float)
    Ts = np.asarray(T, dtype=float)
    if Ts.ndim != 3 or Ts.shape[1:] != (4, 4) or ts.shape != (len(Ts),):
        raise ValueError(f"{what}: need (N,) timestamps and (N, 4, 4) poses, got {ts.shape} and {Ts.shape}")
    _check_poses(Ts, what)
    when = times_problem(ts)
    if when is not None:
        raise ValueError(f"{what}: pose {when[0]}: {when[1]}")
    return ts, Ts


def _check_poses(T: np.ndarray, what: str, *, unknown: bool = False) -> None:
    """ValueError naming ``what`` unless ``T`` (N, 4, 4) holds rigid poses (``unknown``: or NaN ones)."""
    problem = rigid_problem(T, stack=True, unknown=unknown)
    if problem is not None:
        raise ValueError(f"{what}: {problem} (poses are rigid (4, 4) transforms T_world_cam, mm)")


def _check_pair(T_ref: np.ndarray, T_est: np.ndarray, *, unknown: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """``(T_ref, T_est)`` as float (N, 4, 4) arrays of rigid poses (``unknown``: a pose holding a NaN
    is unknown and passes), N >= 1; else a one-line ValueError."""
    A = np.asarray(T_ref, dtype=float)
    B = np.asarray(T_est, dtype=float)
    if A.ndim != 3 or A.shape[1:] != (4, 4) or A.shape != B.shape:
        raise ValueError(f"need two associated (N, 4, 4) pose arrays of equal length, got {A.shape} and {B.shape}")
    if len(A) == 0:
        raise ValueError("need at least one associated pose pair, got 0")
    _check_poses(A, "T_ref", unknown=unknown)
    _check_poses(B, "T_est", unknown=unknown)
    return A, B


# ----------------------------------------------------------------------------- association
def associate(
    t_ref_s: np.ndarray, t_est_s: np.ndarray, max_diff_s: float = 0.01, offset_s: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Pair each estimated timestamp with the nearest reference timestamp.

    ``t_ref_s`` (N,), ``t_est_s`` (M,) in seconds; ``offset_s`` is added to the estimate's
    times. A pair is kept when the difference is at most ``max_diff_s``; each reference
    pose is used at most once (the closest estimate wins). Returns two int arrays
    ``(idx_ref, idx_est)`` of equal length, sorted by ``idx_est``. A ``max_diff_s`` that is not
    a finite number >= 0 is a one-line :class:`~floorvo.errors.ConfigError`; times that are not a
    1-D array of finite numbers a one-line ValueError (a NaN time was left unpaired, silently).
    """
    problem = Rule(min=0.0, unit="s").violation(float(max_diff_s))
    if problem:  # a negative or NaN tolerance paired nothing: 'shares no timestamp', exit 0
        raise ConfigError(f"timestamp association tolerance (--max-diff) = {max_diff_s} s: {problem}")
    t_ref = np.asarray(t_ref_s, dtype=float)
    t_est = np.asarray(t_est_s, dtype=float) + offset_s
    for what, t in (("t_ref_s", t_ref), ("t_est_s + offset_s", t_est)):
        if t.ndim != 1 or not np.isfinite(t).all():
            raise ValueError(f"associate: {what} must be an (N,) array of finite times (s), got shape {t.shape}")
    if len(t_ref) == 0 or len(t_est) == 0:
        return np.zeros(0, int), np.zeros(0, int)
    order = np.argsort(t_ref, kind="stable")
    sorted_ref = t_ref[order]
    pos = (
        np.clip(np.searchsorted(sorted_ref, t_est), 1, len(sorted_ref) - 1)
        if len(sorted_ref) > 1
        else np.zeros(len(t_est), int)
    )
    if len(sorted_ref) > 1:
        left = pos - 1
        pick = np.where(np.abs(sorted_ref[left] - t_est) <= np.abs(sorted_ref[pos] - t_est), left, pos)
    else:
        pick = pos
    diff = np.abs(sorted_ref[pick] - t_est)
    ok = diff <= max_diff_s
    best: dict[int, tuple[float, int]] = {}
    for j in np.nonzero(ok)[0]:
        r = int(order[pick[j]])
        if r not in best or diff[j] < best[r][0]:
            best[r] = (float(diff[j]), int(j))
    pairs = sorted((j, r) for r, (_, j) in best.items())
    idx_est = np.array([p[0] for p in pairs], dtype=int)
    idx_ref = np.array([p[1] for p in pairs], dtype=int)
    return idx_ref, idx_est


# ----------------------------------------------------------------------------- alignment
def align(T_ref: np.ndarray, T_est: np.ndarray, method: str) -> tuple[np.ndarray, np.ndarray]:
    """Align ``T_est`` (N, 4, 4) onto ``T_ref`` (N, 4, 4) by ``method`` (see module doc).

    Returns ``(T_est_aligned (N, 4, 4), T_align (4, 4))`` with ``T_est_aligned[i] =
    T_align @ T_est[i]``; the inputs are not modified. With fewer than two poses (three for
    ``se3``), or a reference that does not move, ``se2``/``se3`` fall back to ``origin``.
    """
    A, B = _check_pair(T_ref, T_est)
    if method not in ALIGNMENTS:
        raise ValueError(f"alignment {method!r}: must be one of {', '.join(ALIGNMENTS)}")
    T_align = np.eye(4)
    degenerate = len(A) < 2 or np.ptp(A[:, :3, 3], axis=0).max() < 1e-9 or np.ptp(B[:, :3, 3], axis=0).max() < 1e-9
    # A rotation in 3D needs three poses: two leave the turn about the line through them free.
    if method == "origin" or (method in ("se2", "se3") and degenerate) or (method == "se3" and len(A) < 3):
        T_align = A[0] @ invert_T(B[0])
    elif method == "se3":
        line = _line_alignment(B[:, :3, 3], A[:, :3, 3])
        R, t = line if line is not None else rigid_fit(B[:, :3, 3], A[:, :3, 3])
        T_align[:3, :3], T_align[:3, 3] = R, t
    elif method == "se2":
        R2, t2 = rigid_fit(B[:, :2, 3], A[:, :2, 3])
        T_align[:2, :2], T_align[:2, 3] = R2, t2
    return np.einsum("ij,njk->nik", T_align, B), T_align


# ----------------------------------------------------------------------------- helpers
#: Positions whose second principal extent is under this share of the first lie on one line.
LINE_EXTENT_RATIO = 1e-9


def _line_alignment(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The least-squares rigid motion ``dst ~ R src + t`` of positions (N, 3) mm of which one set
    lies on a straight line (None otherwise: :func:`~floorvo.geometry.rigid_fit` decides).

    The fit maximises ``trace(R W)``, ``W = sum_i c_i(src) c_i(dst)^T`` of the centred points; with
    one set on a line (direction ``v``) ``W`` has rank 1 and any ``R`` that turns the other set's
    ``m = sum_i c_i (c'_i . v)`` onto ``v`` is a best fit, whatever it turns about ``v``: of those,
    the least rotation (the shortest arc from ``m`` to ``v``; the identity for a straight estimate
    off by a constant offset). ``t`` lays the centroids on each other."""
    mu_s, mu_d = src.mean(axis=0), dst.mean(axis=0)
    cs, cd = src - mu_s, dst - mu_d

    def direction(c: np.ndarray) -> np.ndarray | None:
        _, sv, vt = np.linalg.svd(c, full_matrices=False)
        return vt[0] if sv[0] > 0 and sv[1] <= LINE_EXTENT_RATIO * sv[0] else None

    v, u = direction(cd), direction(cs)
    if v is None and u is None:
        return None
    if v is not None:  # the reference on a line: turn the estimate's m onto it
        a, b = cs.T @ (cd @ v), v
    else:  # the estimate on a line: turn it onto the reference's m
        assert u is not None
        a, b = u, cd.T @ (cs @ u)
    na, nb = float(np.linalg.norm(a)), float(np.linalg.norm(b))
    R = least_rotation(a / na, b / nb) if na > 0 and nb > 0 else np.eye(3)
    return R, mu_d - R @ mu_s


def path_distances_mm(T: np.ndarray) -> np.ndarray:
    """(N,) distance travelled along the path of poses ``T`` (N, 4, 4) up to each pose (mm)."""
    A = np.asarray(T, dtype=float)
    if A.ndim != 3 or A.shape[1:] != (4, 4):
        raise ValueError(f"path_distances_mm: need (N, 4, 4) poses, got shape {A.shape}")
    p = A[:, :3, 3]
    if len(p) == 0:
        return np.zeros(0)
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])


def _distances(A: np.ndarray, dist_mm: np.ndarray | None) -> np.ndarray:
    """The reference path's distance (N,) mm at each of the poses ``A`` (N, 4, 4): ``dist_mm`` as
    given (measured along the whole reference, where ``A`` are the poses of it that a run's poses
    matched: the path between two matched poses across lost frames is longer than their chord),
    else along ``A`` itself (:func:`path_distances_mm`)."""
    if dist_mm is None:
        return path_distances_mm(A)
    d = np.asarray(dist_mm, dtype=float)
    if d.shape != (len(A),) or not np.isfinite(d).all() or np.any(np.diff(d) < 0):
        raise ValueError(f"dist_mm: need ({len(A)},) finite, non-decreasing distances, got shape {d.shape}")
    return d - d[0] if len(d) else d


def _rotation_angle_deg(R: np.ndarray) -> np.ndarray:
    """Angle (deg) of rotations (..., 3, 3)."""
    tr = np.trace(R, axis1=-2, axis2=-1)
    return np.degrees(np.arccos(np.clip((tr - 1.0) / 2.0, -1.0, 1.0)))


def error_stats(errors: np.ndarray) -> dict[str, float]:
    """rmse, mean, median, std, min, max and count of a 1-D error array (NaN when empty)."""
    e = np.asarray(errors, dtype=float).ravel()
    if e.size == 0:
        nan = float("nan")
        return {"rmse": nan, "mean": nan, "median": nan, "std": nan, "min": nan, "max": nan, "count": 0}
    return {
        "rmse": float(np.sqrt(np.mean(e**2))),
        "mean": float(np.mean(e)),
        "median": float(np.median(e)),
        "std": float(np.std(e)),
        "min": float(np.min(e)),
        "max": float(np.max(e)),
        "count": int(e.size),
    }


# ----------------------------------------------------------------------------- ATE
def ate(T_ref: np.ndarray, T_est: np.ndarray, alignment: str = "se3") -> dict[str, Any]:
    """Absolute trajectory error of associated poses (N, 4, 4) after ``alignment``.

    Returns ``{"alignment", "trans_mm": stats, "rot_deg": stats, "errors_mm" (N,),
    "T_align" (4, 4)}``; the translation error is ``|t_ref - t_est_aligned|`` (evo's APE
    translation part), the rotation error the angle of ``R_ref^T R_est_aligned``.
    """
    A, B = _check_pair(T_ref, T_est)
    B2, T_align = align(A, B, alignment)
    e_t = np.linalg.norm(A[:, :3, 3] - B2[:, :3, 3], axis=1)
    e_r = _rotation_angle_deg(np.einsum("nji,njk->nik", A[:, :3, :3], B2[:, :3, :3]))
    return {
        "alignment": alignment,
        "trans_mm": error_stats(e_t),
        "rot_deg": error_stats(e_r),
        "errors_mm": e_t,
        "T_align": T_align,
    }


# ----------------------------------------------------------------------------- RPE
def rpe_pairs_by_frames(n: int, delta: int = 1) -> np.ndarray:
    """(K, 2) index pairs ``(i, i + delta)`` for every i (all pairs); ``delta``: a whole number >= 1."""
    if isinstance(delta, bool) or not float(delta).is_integer() or delta < 1:
        raise ValueError(f"rpe delta = {delta}: must be a whole number >= 1 of frames")
    delta = int(delta)
    i = np.arange(max(0, n - delta))
    return np.stack([i, i + delta], axis=1).astype(int)


def rpe_pairs_by_distance(T_ref: np.ndarray, delta_mm: float, dist_mm: np.ndarray | None = None) -> np.ndarray:
    """(K, 2) pairs ``(i, j)``: j is the first pose where the reference path is >= delta_mm past i.

    Every pose ``i`` that has such a ``j`` starts a pair, so the pairs overlap. evo's
    ``evo_rpe --delta D --delta_unit m --pairs_from_reference`` (``filters.filter_pairs_by_path``
    on the reference, ``all_pairs`` off) uses the same rule for the end of a pair but chains the
    pairs from pose 0, each starting where the previous one ended: its pairs are a subset of
    these, the errors on them are equal, and the statistics over all pairs differ by the
    sampling alone (a test checks both against evo's pair filter on the reference). Without
    ``--pairs_from_reference`` evo measures the distance along the estimate's path: other pairs
    wherever the estimate's steps are off in length. ``dist_mm``: the reference path's distance
    at each pose (:func:`_distances`; default: along ``T_ref``).
    """
    if not (0 < delta_mm < np.inf):  # NaN: no pair at all, silently
        raise ValueError(f"rpe delta_mm = {delta_mm}: must be a finite number > 0")
    dist = _distances(np.asarray(T_ref, dtype=float), dist_mm)
    j = np.searchsorted(dist, dist + delta_mm - 1e-9, side="left")
    i = np.arange(len(dist))
    ok = j < len(dist)
    return np.stack([i[ok], j[ok]], axis=1).astype(int)


def _relative_errors(A: np.ndarray, B: np.ndarray, pairs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(translation mm, rotation deg) of ``(A_i^-1 A_j)^-1 (B_i^-1 B_j)`` for each pair."""
    if len(pairs) == 0:
        return np.zeros(0), np.zeros(0)
    i, j = pairs[:, 0], pairs[:, 1]
    dA = invert_T(A[i]) @ A[j]
    dB = invert_T(B[i]) @ B[j]
    E = invert_T(dA) @ dB
    return np.linalg.norm(E[:, :3, 3], axis=1), _rotation_angle_deg(E[:, :3, :3])


def rpe(
    T_ref: np.ndarray,
    T_est: np.ndarray,
    *,
    delta_frames: int | None = 1,
    delta_mm: float | None = None,
    dist_mm: np.ndarray | None = None,
) -> dict[str, Any]:
    """Relative pose error per ``delta_frames`` frames or per ``delta_mm`` of reference path.

    ``delta_mm``, when given, is used (``delta_frames`` then ignored); else ``delta_frames``
    (None: 1), a whole number >= 1. Returns ``{"delta", "unit", "trans_mm": stats, "rot_deg":
    stats, "pairs" (K, 2)}``. RPE needs no alignment (it is invariant to it). ``dist_mm``: the
    reference path's distance at each pose (:func:`_distances`).
    """
    A, B = _check_pair(T_ref, T_est)
    if delta_mm is not None:
        pairs = rpe_pairs_by_distance(A, delta_mm, dist_mm)
        delta, unit = float(delta_mm), "mm"
    else:
        frames = 1 if delta_frames is None else delta_frames  # 0 was taken as 1, 2.7 as 2
        pairs = rpe_pairs_by_frames(len(A), frames)
        delta, unit = int(frames), "frames"
    e_t, e_r = _relative_errors(A, B, pairs)
    return {
        "delta": delta,
        "unit": unit,
        "trans_mm": error_stats(e_t),
        "rot_deg": error_stats(e_r),
        "pairs": pairs,
        "trans_errors_mm": e_t,
        "rot_errors_deg": e_r,
    }


# ----------------------------------------------------------------------------- steps
#: Issue 14's bound on a step reported ok: 0.05 mm + 2 % of the true step, 0.3 degrees.
WRONG_STEP_MM = 0.05
WRONG_STEP_FRACTION = 0.02
WRONG_STEP_DEG = 0.3


def step_errors(
    T_ref: np.ndarray,
    T_est: np.ndarray,
    *,
    T_ref_from: np.ndarray | None = None,
    T_est_from: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """Error of each step between consecutive associated poses (N, 4, 4), mm.

    An estimator measures each tracked frame from its last tracked one, so the poses of a
    run (lost frames left out) and the reference poses at the same frames give one
    measured step per tracked frame: ``B_i^-1 B_i+1`` against the truth ``A_i^-1 A_i+1``.
    When a step was measured from another frame (an estimator that restarted its track
    on a lost frame), ``T_ref_from`` (N-1, 4, 4) gives the true pose of the frame each
    step was measured from (default ``A_i``), and ``T_est_from`` (N-1, 4, 4) the run's pose of
    that frame where the run gives it one that is not ``B_i`` (default ``B_i``: the last pose
    placed; a run whose poses an attitude signal tilts holds the restart frame at the last
    pose's position and yaw, tilted to that frame's attitude). Returns ``trans_mm`` (N-1,) and
    ``rot_deg`` (N-1,), the translation and rotation of the error ``(true step)^-1 (measured
    step)``, and ``step_mm`` (N-1,), the true step's translation. A pose holding a NaN is unknown
    (a frame without ground truth): the steps from or to it are NaN.
    """
    A, B = _check_pair(T_ref, T_est, unknown=True)
    A_from = _check_from(A, T_ref_from, "step_errors: T_ref_from")
    B_from = _check_from(B, T_est_from, "step_errors: T_est_from")
    d_true = invert_T(A_from) @ A[1:]
    E = invert_T(d_true) @ (invert_T(B_from) @ B[1:])
    return {
        "trans_mm": np.linalg.norm(E[:, :3, 3], axis=1),
        "rot_deg": _rotation_angle_deg(E[:, :3, :3]),
        "step_mm": np.linalg.norm(d_true[:, :3, 3], axis=1),
    }


def _check_from(T: np.ndarray, T_from: np.ndarray | None, what: str) -> np.ndarray:
    """The poses (N-1, 4, 4) each step of the poses ``T`` (N, 4, 4) was measured from: ``T_from``
    (rigid, or NaN where unknown), by default ``T[:-1]``; a one-line ValueError naming ``what``."""
    if T_from is None:
        return T[:-1]
    F = np.asarray(T_from, dtype=float)
    if F.shape != (len(T) - 1, 4, 4):
        raise ValueError(f"{what} has shape {F.shape}, expected ({len(T) - 1}, 4, 4)")
    _check_poses(F, what, unknown=True)
    return F


def wrong_steps(
    errors: Mapping[str, np.ndarray],
    *,
    abs_mm: float = WRONG_STEP_MM,
    fraction: float = WRONG_STEP_FRACTION,
    rot_deg: float = WRONG_STEP_DEG,
) -> np.ndarray:
    """(K,) bool: the steps of :func:`step_errors` off by more than ``abs_mm + fraction * step``
    in translation or ``rot_deg`` in rotation (issue 14's bound by default)."""
    return (errors["trans_mm"] > abs_mm + fraction * errors["step_mm"]) | (errors["rot_deg"] > rot_deg)


#: Less true turn than this (degrees, summed over a run's steps) leaves the turn error unreported:
#: on a straight run it would be the ratio of two noises.
MIN_TURN_DEG = 10.0


def turn_error(T_ref: np.ndarray, T_est: np.ndarray, *, T_ref_from: np.ndarray | None = None) -> dict[str, float]:
    """How much of the true turn a run's steps measure: the yaw's scale error.

    Steps as in :func:`step_errors` (consecutive associated poses (N, 4, 4); ``T_ref_from``
    (N-1, 4, 4): the true pose each step was measured from). With d_k the true and e_k the
    measured yaw change of step k (degrees, about the camera's z axis: ``yaw_of_R`` of the
    step's rotation): ``turn_deg`` = sum |d_k| (the true turn, both directions counted, as on
    an S-curve), ``measured_turn_deg`` = sum e_k sign(d_k), and ``turn_error_pct`` = 100
    (measured - true) / true: the signed error of the turn, as ``distance_error_pct`` is of
    the distance; NaN below :data:`MIN_TURN_DEG` of true turn. A planar estimator that reads
    every rotation s times too large has turn_error_pct = 100 (s - 1); on a turning run that
    error, not the step's length, can dominate the end drift (it swings the rest of the path).
    Steps with no true pose at either end (NaN) are left out.
    """
    A, B = _check_pair(T_ref, T_est, unknown=True)
    A_from = _check_from(A, T_ref_from, "turn_error: T_ref_from")
    d_true = invert_T(A_from) @ A[1:]
    d_est = invert_T(B[:-1]) @ B[1:]
    yaw_true, yaw_est = np.degrees(yaws_of_T(d_true)), np.degrees(yaws_of_T(d_est))
    known = np.isfinite(yaw_true) & np.isfinite(yaw_est)
    turn = float(np.abs(yaw_true[known]).sum())
    measured = float((yaw_est[known] * np.sign(yaw_true[known])).sum())
    return {
        "turn_deg": turn,
        "measured_turn_deg": measured,
        "turn_error_pct": 100.0 * (measured - turn) / turn if turn >= MIN_TURN_DEG else float("nan"),
    }


# ----------------------------------------------------------------------------- drift
def end_point_drift(
    T_ref: np.ndarray, T_est: np.ndarray, alignment: str = "none", dist_mm: np.ndarray | None = None
) -> dict[str, Any]:
    """End-point error (mm) and its share of the reference path length (%).

    Also the measured against the true displacement from the first to the last pose
    (``measured_mm``, ``true_mm``, the paper-000 "measured distance") and their relative
    difference (``distance_error_pct``, the paper-001 "% error" of a straight line).
    ``dist_mm``: the reference path's distance at each pose (:func:`_distances`: along the whole
    reference, where the run lost frames; its chord across them was taken, and a half circle
    tracked at its ends alone was 205 mm long instead of 314).
    """
    A, B = _check_pair(T_ref, T_est)
    B2, _ = align(A, B, alignment)
    length = float(_distances(A, dist_mm)[-1])
    err = float(np.linalg.norm(A[-1, :3, 3] - B2[-1, :3, 3]))
    true_mm = float(np.linalg.norm(A[-1, :3, 3] - A[0, :3, 3]))
    measured_mm = float(np.linalg.norm(B2[-1, :3, 3] - B2[0, :3, 3]))
    nan = float("nan")
    return {
        "alignment": alignment,
        "path_length_mm": length,
        "end_error_mm": err,
        "end_drift_pct": 100.0 * err / length if length > 0 else nan,
        "true_mm": true_mm,
        "measured_mm": measured_mm,
        "distance_error_pct": 100.0 * (measured_mm - true_mm) / true_mm if true_mm > 0 else nan,
    }


def segment_errors(
    T_ref: np.ndarray,
    T_est: np.ndarray,
    lengths_mm: SequenceT[float] = SEGMENT_LENGTHS_MM,
    step: int = 1,
    dist_mm: np.ndarray | None = None,
) -> list[dict[str, float]]:
    """KITTI devkit segment errors (``calcSequenceErrors``), lengths in mm.

    For every ``step``-th start pose i and every length L, j is the first pose with
    ``dist[j] >= dist[i] + L`` on the reference path; the error of the relative motion
    ``E = (ref_i^-1 ref_j)^-1 (est_i^-1 est_j)`` gives ``t_err = |t(E)| / L`` and
    ``r_err = angle(E) / L``. Returns one dict per length that has at least one segment:
    ``{"length_mm", "count", "t_err_pct" (mean, % of L), "r_err_deg_per_m" (mean),
    "t_err_pct_max"}``. Each length must be a finite number > 0 (a negative one gave negative errors).
    ``dist_mm``: the reference path's distance at each pose (:func:`_distances`).
    """
    A, B = _check_pair(T_ref, T_est)
    for L in lengths_mm:
        if not (0 < float(L) < np.inf):
            raise ValueError(f"segment length {L} mm: must be a finite number > 0")
    dist = _distances(A, dist_mm)
    out = []
    starts = np.arange(0, len(A), max(1, int(step)))
    for L in lengths_mm:
        j = np.searchsorted(dist, dist[starts] + L - 1e-9, side="left")
        ok = j < len(A)
        if not ok.any():
            continue
        pairs = np.stack([starts[ok], j[ok]], axis=1)
        e_t, e_r = _relative_errors(A, B, pairs)
        out.append(
            {
                "length_mm": float(L),
                "count": int(len(pairs)),
                "t_err_pct": float(np.mean(e_t / L) * 100.0),
                "t_err_pct_max": float(np.max(e_t / L) * 100.0),
                "r_err_deg_per_m": float(np.mean(e_r / L) * 1000.0),
            }
        )
    return out


def translation_error_along_path(
    T_ref: np.ndarray, T_est: np.ndarray, alignment: str = "none"
) -> tuple[np.ndarray, np.ndarray]:
    """``(distance travelled (N,) mm, translation error (N,) mm)`` for an error-vs-distance plot."""
    A, B = _check_pair(T_ref, T_est)
    B2, _ = align(A, B, alignment)
    return path_distances_mm(A), np.linalg.norm(A[:, :3, 3] - B2[:, :3, 3], axis=1)


# ----------------------------------------------------------------------------- tracking and timing
#: The note a lost frame's reason ends with when the runner chains the motion through it (an
#: attitude signal that leaves the frame unplaced: :mod:`floorvo.runner`); a note, not a cause.
CHAINED_NOTE = "the motion is chained through this frame"


def reason_kind(reason: str) -> str:
    """The kind of a lost step's ``reason``, for counting reasons over a run.

    The last ``"; "``-separated clause that is no note (the restart note, :data:`CHAINED_NOTE`:
    every attitude reason was counted as 'the motion is chained through this frame'; the cause: an earlier
    clause says what was tried first, such as a brute-force fallback), without its
    parenthesised details, numbers replaced by ``#``: ``"weak correlation peak 0.012"``
    -> ``"weak correlation peak #"``; ``"guided prediction doubtful (...): matched by brute
    force; too few matches (3 < 6)"`` -> ``"too few matches"``. A clause that names its cause
    before a colon is counted by that name: ``"tilt not observable: the step tilts the camera
    9.1 mrad, ..."`` -> ``"tilt not observable"`` (the kinds had kept the whole formula, numbers
    as ``#``, 150 characters in a report's cell). Empty: ``"(no reason)"``.
    """
    text = str(reason)
    while True:  # innermost parentheses first, so nested ones go too
        cut = re.sub(r"\s*\([^()]*\)", "", text)
        if cut == text:
            break
        text = cut
    notes = ("tracking restarts", CHAINED_NOTE)
    clauses = [c.strip() for c in text.split("; ") if c.strip() and not c.strip().startswith(notes)]
    text = clauses[-1] if clauses else ""
    label, colon, _ = text.partition(": ")
    if colon and label.strip():
        text = label
    text = re.sub(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?", "#", text)
    text = re.sub(r"\s+", " ", text).strip(" :;,")
    return text or NO_REASON


#: The kind of a lost frame that gives no reason (an empty cell, or a timing.csv without the column).
NO_REASON = "(no reason)"


def lost_reasons(statuses: SequenceT[str], reasons: SequenceT[str]) -> dict[str, int]:
    """``{kind: count}`` of the lost steps of a run (:func:`reason_kind`), most frequent first."""
    counts: dict[str, int] = {}
    for st, why in zip(statuses, reasons):
        if st == "lost":
            k = reason_kind(why)
            counts[k] = counts.get(k, 0) + 1
    return dict(sorted(counts.items(), key=lambda kv: (-kv[1], kv[0])))


def tracking_stats(
    statuses: SequenceT[str] | None, n_ref: int, n_est: int, reasons: SequenceT[str] | None = None
) -> dict[str, Any]:
    """Tracking-loss statistics.

    ``statuses``: per-frame status strings (``init``/``ok``/``lost``) from ``timing.csv``,
    or None, in which case the frames without an estimated pose (``n_ref - n_est``) count
    as lost. Returns ``lost_frames``, ``loss_events`` (runs of consecutive lost frames),
    ``tracked_fraction`` and ``source``; with ``reasons`` (per frame, ``timing.csv``'s
    reason column) also ``lost_reasons``, the lost steps counted per kind of reason
    (:func:`lost_reasons`); without reasons, those lost steps as ``{NO_REASON: n}``.
    """
    if statuses is not None and len(statuses) > 0:
        lost = np.array([s == "lost" for s in statuses], dtype=bool)
        events = int(np.sum(lost[1:] & ~lost[:-1]) + (1 if lost[0] else 0))
        n = len(lost)
        out: dict[str, Any] = {
            "lost_frames": int(lost.sum()),
            "loss_events": events,
            "tracked_fraction": float(1 - lost.mean()),
            "frames": n,
            "source": "timing.csv",
        }
        if reasons is not None and len(reasons) == n:
            out["lost_reasons"] = lost_reasons(statuses, reasons)
        elif out[
            "lost_frames"
        ]:  # a timing.csv without reasons (a program's): its lost frames were left out of the count
            out["lost_reasons"] = {NO_REASON: out["lost_frames"]}
        return out
    lost_n = max(0, int(n_ref) - int(n_est))
    return {
        "lost_frames": lost_n,
        "loss_events": int(lost_n > 0),
        "tracked_fraction": float(n_est / n_ref) if n_ref else float("nan"),
        "frames": int(n_ref),
        "source": "gaps",
    }


def timing_stats(timing: dict[str, np.ndarray] | None) -> dict[str, dict[str, float]]:
    """Per ``*_ms`` column: mean, median, p95, max, std (ms); plus ``fps`` from total_ms."""
    out: dict[str, Any] = {}
    if not timing:
        return out
    for key, vals in timing.items():
        if not key.endswith("_ms"):
            continue
        v = np.asarray(vals, dtype=float)
        v = v[np.isfinite(v)]
        if v.size == 0:
            continue
        out[key] = {
            "mean": float(v.mean()),
            "median": float(np.median(v)),
            "p95": float(np.percentile(v, 95)),
            "max": float(v.max()),
            "std": float(v.std()),
        }
    if "total_ms" in out and out["total_ms"]["mean"] > 0:
        out["fps"] = 1000.0 / out["total_ms"]["mean"]
    return out

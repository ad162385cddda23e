"""Trajectory metrics: ATE, RPE, drift, KITTI-style segment errors, tracking loss, timing.

Every function here is pure: it takes ``(timestamps_s (N,), T_world_cam (N, 4, 4) mm)``
arrays and returns new arrays or plain numbers; inputs are never modified (evo aligns in
place; this module never does). Only :func:`score_run` reads files.

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

import logging
import math
import os
from collections.abc import Sequence as SequenceT
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from floorvo.errors import SequenceError
from floorvo.geometry import invert_T, rigid_fit
from floorvo.io import read_json
from floorvo.runfolder import RunFolder
from floorvo.tum import read_tum

log = logging.getLogger(__name__)

__all__ = [
    "ALIGNMENTS",
    "SEGMENT_LENGTHS_MM",
    "associate",
    "align",
    "path_distances_mm",
    "error_stats",
    "ate",
    "rpe_pairs_by_frames",
    "rpe_pairs_by_distance",
    "rpe",
    "end_point_drift",
    "segment_errors",
    "translation_error_along_path",
    "tracking_stats",
    "timing_stats",
    "Score",
    "score_trajectories",
    "read_run_and_groundtruth",
    "score_run",
]

ALIGNMENTS = ("none", "origin", "se2", "se3")
#: Default KITTI-style segment lengths for floors (mm): 10, 25, 50, 100 and up.
#: What a score without ground truth says in place of the metrics that need it.
NO_GROUND_TRUTH = "no ground truth"
#: An estimate whose first pose is farther than FAR_START_MM + FAR_START_FRACTION x path length
#: from the ground truth at the same time is not in the ground truth's frame (a warning).
FAR_START_MM = 10.0
FAR_START_FRACTION = 0.05
SEGMENT_LENGTHS_MM = (10.0, 25.0, 50.0, 100.0, 250.0, 500.0, 1000.0, 2000.0, 5000.0)


def _check_traj(timestamps_s: np.ndarray, T: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray]:
    ts = np.asarray(timestamps_s, dtype=float)
    Ts = np.asarray(T, dtype=float)
    if Ts.ndim != 3 or Ts.shape[1:] != (4, 4) or ts.shape != (len(Ts),):
        raise ValueError(f"{what}: need (N,) timestamps and (N, 4, 4) poses, got {ts.shape} and {Ts.shape}")
    return ts, Ts


def _check_pair(T_ref: np.ndarray, T_est: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    A = np.asarray(T_ref, dtype=float)
    B = np.asarray(T_est, dtype=float)
    if A.ndim != 3 or A.shape[1:] != (4, 4) or A.shape != B.shape:
        raise ValueError(f"need two associated (N, 4, 4) pose arrays of equal length, got {A.shape} and {B.shape}")
    if len(A) == 0:
        raise ValueError("need at least one associated pose pair, got 0")
    return A, B


# ----------------------------------------------------------------------------- association
def associate(
    t_ref_s: np.ndarray, t_est_s: np.ndarray, max_diff_s: float = 0.01, offset_s: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Pair each estimated timestamp with the nearest reference timestamp.

    ``t_ref_s`` (N,), ``t_est_s`` (M,) in seconds; ``offset_s`` is added to the estimate's
    times. A pair is kept when the difference is at most ``max_diff_s``; each reference
    pose is used at most once (the closest estimate wins). Returns two int arrays
    ``(idx_ref, idx_est)`` of equal length, sorted by ``idx_est``.
    """
    t_ref = np.asarray(t_ref_s, dtype=float)
    t_est = np.asarray(t_est_s, dtype=float) + offset_s
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
        R, t = rigid_fit(B[:, :3, 3], A[:, :3, 3])
        T_align[:3, :3], T_align[:3, 3] = R, t
    elif method == "se2":
        R2, t2 = rigid_fit(B[:, :2, 3], A[:, :2, 3])
        T_align[:2, :2], T_align[:2, 3] = R2, t2
    return np.einsum("ij,njk->nik", T_align, B), T_align


# ----------------------------------------------------------------------------- helpers
def path_distances_mm(T: np.ndarray) -> np.ndarray:
    """(N,) distance travelled along the path of poses ``T`` (N, 4, 4) up to each pose (mm)."""
    p = np.asarray(T, dtype=float)[:, :3, 3]
    if len(p) == 0:
        return np.zeros(0)
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])


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
    """(K, 2) index pairs ``(i, i + delta)`` for every i (all pairs)."""
    if delta < 1:
        raise ValueError(f"rpe delta = {delta}: must be >= 1 frame")
    i = np.arange(max(0, n - delta))
    return np.stack([i, i + delta], axis=1).astype(int)


def rpe_pairs_by_distance(T_ref: np.ndarray, delta_mm: float) -> np.ndarray:
    """(K, 2) pairs ``(i, j)``: j is the first pose where the reference path is >= delta_mm past i."""
    if delta_mm <= 0:
        raise ValueError(f"rpe delta_mm = {delta_mm}: must be > 0")
    dist = path_distances_mm(T_ref)
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
    T_ref: np.ndarray, T_est: np.ndarray, *, delta_frames: int | None = 1, delta_mm: float | None = None
) -> dict[str, Any]:
    """Relative pose error per ``delta_frames`` frames or per ``delta_mm`` of reference path.

    Give exactly one of the two. Returns ``{"delta", "unit", "trans_mm": stats,
    "rot_deg": stats, "pairs" (K, 2)}``. RPE needs no alignment (it is invariant to it).
    """
    A, B = _check_pair(T_ref, T_est)
    if delta_mm is not None:
        pairs = rpe_pairs_by_distance(A, delta_mm)
        delta, unit = float(delta_mm), "mm"
    else:
        pairs = rpe_pairs_by_frames(len(A), int(delta_frames or 1))
        delta, unit = int(delta_frames or 1), "frames"
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


# ----------------------------------------------------------------------------- drift
def end_point_drift(T_ref: np.ndarray, T_est: np.ndarray, alignment: str = "none") -> dict[str, float]:
    """End-point error (mm) and its share of the reference path length (%).

    Also the measured against the true displacement from the first to the last pose
    (``measured_mm``, ``true_mm``, the paper-000 "measured distance") and their relative
    difference (``distance_error_pct``, the paper-001 "% error" of a straight line).
    """
    A, B = _check_pair(T_ref, T_est)
    B2, _ = align(A, B, alignment)
    length = float(path_distances_mm(A)[-1])
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
    T_ref: np.ndarray, T_est: np.ndarray, lengths_mm: SequenceT[float] = SEGMENT_LENGTHS_MM, step: int = 1
) -> list[dict[str, float]]:
    """KITTI devkit segment errors (``calcSequenceErrors``), lengths in mm.

    For every ``step``-th start pose i and every length L, j is the first pose with
    ``dist[j] >= dist[i] + L`` on the reference path; the error of the relative motion
    ``E = (ref_i^-1 ref_j)^-1 (est_i^-1 est_j)`` gives ``t_err = |t(E)| / L`` and
    ``r_err = angle(E) / L``. Returns one dict per length that has at least one segment:
    ``{"length_mm", "count", "t_err_pct" (mean, % of L), "r_err_deg_per_m" (mean),
    "t_err_pct_max"}``.
    """
    A, B = _check_pair(T_ref, T_est)
    dist = path_distances_mm(A)
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
def tracking_stats(statuses: SequenceT[str] | None, n_ref: int, n_est: int) -> dict[str, Any]:
    """Tracking-loss statistics.

    ``statuses``: per-frame status strings (``init``/``ok``/``lost``) from ``timing.csv``,
    or None, in which case the frames without an estimated pose (``n_ref - n_est``) count
    as lost. Returns ``lost_frames``, ``loss_events`` (runs of consecutive lost frames),
    ``tracked_fraction`` and ``source``.
    """
    if statuses is not None and len(statuses) > 0:
        lost = np.array([s == "lost" for s in statuses], dtype=bool)
        events = int(np.sum(lost[1:] & ~lost[:-1]) + (1 if lost[0] else 0))
        n = len(lost)
        return {
            "lost_frames": int(lost.sum()),
            "loss_events": events,
            "tracked_fraction": float(1 - lost.mean()),
            "frames": n,
            "source": "timing.csv",
        }
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


# ----------------------------------------------------------------------------- score
@dataclass
class Score:
    """Every metric of one run against its ground truth (see :meth:`to_dict`, :meth:`flat`).

    Without ground truth (or when the estimate shares fewer than two timestamps with it),
    ``ate``, ``rpe_*``, ``drift`` and ``segments`` are empty, ``ground_truth`` says why
    (``"no ground truth"``), and only tracking and timing are scored. ``warnings``: what a
    reader of the figures must know (no shared timestamps; an estimate that starts far from
    the ground truth, whose unaligned metrics are then left out).
    """

    estimator: str
    run_dir: str
    seq_dir: str
    n_ref: int
    n_est: int
    n_matched: int
    ate: dict[str, dict]
    rpe_frame: dict
    rpe_distance: list[dict]
    drift: dict
    segments: list[dict]
    tracking: dict
    timing: dict
    extra: dict = field(default_factory=dict)
    ground_truth: str = "ok"
    warnings: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        """JSON-ready dict (per-pose arrays dropped)."""
        d = asdict(self)
        for a in d["ate"].values():
            a.pop("errors_mm", None)
            if "T_align" in a:
                a["T_align"] = np.asarray(a["T_align"]).tolist()
        for r in [d["rpe_frame"], *d["rpe_distance"]]:
            for k in ("pairs", "trans_errors_mm", "rot_errors_deg"):
                r.pop(k, None)
        return _jsonable(d)

    def flat(self) -> dict[str, float]:
        """One number per metric, named with unit and alignment (results.csv columns, gates)."""
        f: dict[str, float] = {}
        for name, a in self.ate.items():
            f[f"ate_{name}_rmse_mm"] = a["trans_mm"]["rmse"]
            f[f"ate_{name}_mean_mm"] = a["trans_mm"]["mean"]
            f[f"ate_{name}_max_mm"] = a["trans_mm"]["max"]
        f["ate_se3_rot_rmse_deg"] = self.ate["se3"]["rot_deg"]["rmse"] if "se3" in self.ate else float("nan")
        if self.rpe_frame:
            f["rpe_frame_trans_rmse_mm"] = self.rpe_frame["trans_mm"]["rmse"]
            f["rpe_frame_rot_rmse_deg"] = self.rpe_frame["rot_deg"]["rmse"]
        for r in self.rpe_distance:
            f[f"rpe_{r['delta']:g}mm_trans_rmse_mm"] = r["trans_mm"]["rmse"]
        for key in ("end_drift_pct", "distance_error_pct", "path_length_mm", "measured_mm"):
            if key in self.drift:
                f[key] = self.drift[key]
        for s in self.segments:
            f[f"seg_{s['length_mm']:g}mm_t_err_pct"] = s["t_err_pct"]
        f["seg_mean_t_err_pct"] = (
            float(np.mean([s["t_err_pct"] for s in self.segments])) if self.segments else float("nan")
        )
        f["seg_mean_r_err_deg_per_m"] = (
            float(np.mean([s["r_err_deg_per_m"] for s in self.segments])) if self.segments else float("nan")
        )
        f["lost_frames"] = float(self.tracking["lost_frames"])
        f["loss_events"] = float(self.tracking["loss_events"])
        f["tracked_fraction"] = float(self.tracking["tracked_fraction"])
        for key in ("total_ms", "detect_ms", "match_ms", "estimate_ms"):
            if key in self.timing:
                f[f"time_{key}_mean"] = self.timing[key]["mean"]
        if "fps" in self.timing:
            f["fps"] = self.timing["fps"]
        return f


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def score_trajectories(
    t_ref_s: np.ndarray,
    T_ref: np.ndarray,
    t_est_s: np.ndarray,
    T_est: np.ndarray,
    *,
    estimator: str = "",
    statuses: SequenceT[str] | None = None,
    timing: dict[str, np.ndarray] | None = None,
    max_diff_s: float = 0.01,
    rpe_deltas_mm: SequenceT[float] = (10.0, 100.0),
    segment_lengths_mm: SequenceT[float] = SEGMENT_LENGTHS_MM,
) -> Score:
    """Score an estimated trajectory against the reference (both ``(ts (N,), T (N, 4, 4) mm)``)."""
    t_ref_s, T_ref = _check_traj(t_ref_s, T_ref, "reference")
    t_est_s, T_est = _check_traj(t_est_s, T_est, "estimate")
    i_ref, i_est = associate(t_ref_s, t_est_s, max_diff_s)
    if len(i_ref) < 2:
        raise SequenceError(
            f"estimate has {len(i_ref)} pose(s) matching a ground-truth timestamp within {max_diff_s} s; need >= 2 to score"
        )
    A, B = T_ref[i_ref], T_est[i_est]
    ates = {m: ate(A, B, m) for m in ALIGNMENTS}
    rpe_d = [rpe(A, B, delta_mm=d) for d in rpe_deltas_mm if path_distances_mm(A)[-1] >= d]
    drift = end_point_drift(A, B, "none")
    warnings = []
    start_mm = float(np.linalg.norm(A[0, :3, 3] - B[0, :3, 3]))
    if start_mm > FAR_START_MM + FAR_START_FRACTION * path_distances_mm(A)[-1]:
        # Not in the ground truth's frame: the unaligned figures would measure the offset, not the estimator.
        warnings.append(
            f"the estimate starts {start_mm:.1f} mm from the ground truth at their first shared time: it is not in "
            "the ground truth's world frame, so the unaligned ATE and the end drift are left out (see the aligned ATE)"
        )
        for m in ("none", "origin"):
            ates.pop(m, None)
        drift = {k: v for k, v in drift.items() if k not in ("end_drift_pct", "end_error_mm")}
    return Score(
        estimator=estimator,
        run_dir="",
        seq_dir="",
        n_ref=len(T_ref),
        n_est=len(T_est),
        n_matched=len(i_ref),
        ate=ates,
        rpe_frame=rpe(A, B, delta_frames=1),
        rpe_distance=rpe_d,
        drift=drift,
        segments=segment_errors(A, B, segment_lengths_mm),
        tracking=tracking_stats(None if statuses is None else list(statuses), len(T_ref), len(i_est)),
        timing=timing_stats(timing),
        warnings=warnings,
    )


def score_without_groundtruth(
    n_frames: int,
    t_est_s: np.ndarray,
    *,
    estimator: str = "",
    statuses: SequenceT[str] | None = None,
    timing: dict[str, np.ndarray] | None = None,
    why: str = NO_GROUND_TRUTH,
) -> Score:
    """Tracking and timing of a run that has no ground truth to compare with (``why`` says so)."""
    return Score(
        estimator=estimator,
        run_dir="",
        seq_dir="",
        n_ref=0,
        n_est=len(t_est_s),
        n_matched=0,
        ate={},
        rpe_frame={},
        rpe_distance=[],
        drift={},
        segments=[],
        tracking=tracking_stats(None if statuses is None else list(statuses), n_frames, len(t_est_s)),
        timing=timing_stats(timing),
        ground_truth=why,
    )


def read_run_and_groundtruth(run_dir: str | os.PathLike, seq_dir: str | os.PathLike, purpose: str):
    """``(groundtruth path, (t_ref, T_ref), run)`` of a run; ``run`` is its :class:`~floorvo.runfolder.RunFolder`.

    ``seq_dir`` is a sequence folder (its ``groundtruth.txt``) or a TUM file; ``purpose``
    ("score", "calibrate") words the error when there is no ground truth.
    """
    run_dir, seq_dir = Path(run_dir), Path(seq_dir)
    gt_path = seq_dir / "groundtruth.txt" if seq_dir.is_dir() else seq_dir
    if not gt_path.is_file():
        raise SequenceError(f"{gt_path}: no ground truth to {purpose} against (groundtruth.txt is missing)")
    ref = read_tum(gt_path)
    return gt_path, ref, RunFolder.read(run_dir)


def score_run(run_dir: str | os.PathLike, seq_dir: str | os.PathLike, *, max_diff_s: float = 0.01) -> Score:
    """Score ``RUN/trajectory.txt`` (+ ``timing.csv``, ``result.json``) against ``SEQ/groundtruth.txt``.

    When the run covered a sub-range of the sequence (``result.json`` ``frames``), the
    reference is cut to the frames the estimator saw, so a lost tail still counts as lost.
    """
    run_dir, seq_dir = Path(run_dir), Path(seq_dir)
    if seq_dir.is_dir() and not (seq_dir / "groundtruth.txt").is_file() and (seq_dir / "sequence.json").is_file():
        score = _score_without_groundtruth(run_dir, seq_dir, NO_GROUND_TRUTH)
        log.info("%s: %s; scored tracking and timing only", seq_dir, NO_GROUND_TRUTH)
        return score
    _, (t_ref, T_ref), run = read_run_and_groundtruth(run_dir, seq_dir, "score")
    timing, result = run.timing, run.result
    if len(run.timestamps_s) >= 2 and len(associate(t_ref, run.timestamps_s, max_diff_s)[0]) == 0:
        why = f"the estimate shares no timestamp with the ground truth (within {max_diff_s} s)"
        log.warning("%s: %s; scored tracking and timing only", run_dir, why)
        score = _score_without_groundtruth(run_dir, seq_dir, why)
        score.warnings.append(why + ": check the frame times of the run and of groundtruth.txt")
        return score
    if timing and "frame" in timing and len(timing["frame"]):
        # The estimator saw only these frames: cut the reference to the poses taken at their times.
        frames = timing["frame"].astype(int)
        t_frames = _frame_times_of(seq_dir, t_ref, frames)
        i_ref, _ = associate(t_ref, t_frames, max_diff_s)
        if len(i_ref) >= 2:
            keep = np.sort(i_ref)
            t_ref, T_ref = t_ref[keep], T_ref[keep]
    score = score_trajectories(
        t_ref,
        T_ref,
        run.timestamps_s,
        run.T_world_cam,
        estimator=str(result.get("estimator", "")),
        statuses=run.statuses,
        timing=timing,
        max_diff_s=max_diff_s,
    )
    score.run_dir, score.seq_dir = str(run_dir), str(seq_dir)
    if result:
        score.extra["result"] = {
            k: result[k] for k in ("status_counts", "lost", "fps", "frames_per_second") if k in result
        }
    for w in score.warnings:
        log.warning("%s: %s", run_dir, w)
    return score


def _score_without_groundtruth(run_dir: Path, seq_dir: Path, why: str) -> Score:
    run = RunFolder.read(run_dir)
    n_frames = len(run.timing["frame"]) if run.timing and "frame" in run.timing else None
    if n_frames is None:  # a run without timing.csv (a program's): every frame of the sequence
        n_frames = int(run.result.get("frames") or read_json(seq_dir / "sequence.json").get("frame_count", 0))
    score = score_without_groundtruth(
        n_frames,
        run.timestamps_s,
        estimator=str(run.result.get("estimator", "")),
        statuses=run.statuses,
        timing=None if run.timing is None else dict(run.timing),
        why=why,
    )
    score.run_dir, score.seq_dir = str(run_dir), str(seq_dir)
    return score


def _frame_times_of(seq_dir: Path, t_ref: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """Times (s) of the sequence's ``frames``: from the sequence folder (``timestamps.txt`` or
    ``i / fps``), or, for a bare ground-truth file, frame i at i over its median rate."""
    if (seq_dir / "sequence.json").is_file():
        from floorvo.sequence import Sequence  # sequence.py uses associate(): scoring sits above it

        ts = Sequence.open(seq_dir).timestamps_s
        return ts[frames[(frames >= 0) & (frames < len(ts))]]
    d = np.diff(t_ref)
    fps = float(1.0 / np.median(d)) if len(d) else 1.0
    return frames / fps

"""Scoring of a run folder against its ground truth: the file side of the metrics.

:func:`score_run` reads a run folder (``RUN/trajectory.txt``, ``timing.csv``,
``result.json``, through :class:`floorvo.runfolder.RunFolder`) and the sequence's
``groundtruth.txt``, computes every metric of :mod:`floorvo.metrics`
(pure functions on arrays) into a :class:`Score`, and :func:`write_score` writes it as
``score.json``. :meth:`Score.flat` names each number as :mod:`floorvo.metric_defs`
declares it.
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Mapping
from collections.abc import Sequence as SequenceT
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from floorvo import metric_defs as md
from floorvo.errors import SequenceError, shown_number
from floorvo.estimators.base import RESTART_NOTE
from floorvo.geometry import T_world_cam_down, footprint_T, invert_T, yaw_of_R
from floorvo.io import atomic_write_json, read_json, strict_json
from floorvo.metrics import (
    ALIGNMENTS,
    SEGMENT_LENGTHS_MM,
    associate,
    ate,
    check_trajectory,
    end_point_drift,
    path_distances_mm,
    rpe,
    segment_errors,
    step_errors,
    timing_stats,
    tracking_stats,
    turn_error,
    wrong_steps,
)
from floorvo.runfolder import TIMING, TRAJECTORY, RunFolder, check_run_of_sequence
from floorvo.sequence import Sequence, no_groundtruth_reason, read_groundtruth
from floorvo.tum import read_tum

log = logging.getLogger(__name__)

__all__ = [
    "NO_GROUND_TRUTH",
    "NO_TRACK",
    "Score",
    "score_trajectories",
    "score_without_groundtruth",
    "read_run_and_groundtruth",
    "score_run",
    "ok_step_errors",
    "ok_step_poses",
    "levelled_restart_poses",
    "ok_step_poses_of_run",
    "ok_step_frames_of_run",
    "ok_step_table",
    "write_score",
]


#: What a score without ground truth says in place of the metrics that need it.
NO_GROUND_TRUTH = "no ground truth"
#: What a score of a run that placed fewer than two frames says in place of the pose metrics.
NO_TRACK = "fewer than two frames tracked"
#: An estimate whose first pose is farther than FAR_START_MM + FAR_START_FRACTION x path length
#: from the ground truth at the same time is not in the ground truth's frame (a warning).
FAR_START_MM = 10.0
FAR_START_FRACTION = 0.05


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
        return strict_json(d)

    def flat(self) -> dict[str, float]:
        """One number per metric, named by :mod:`floorvo.metric_defs` (results.csv columns, gates)."""
        f: dict[str, float] = {}
        for name, a in self.ate.items():
            f[md.ate_rmse(name).name] = a["trans_mm"]["rmse"]
            f[md.ate_mean(name).name] = a["trans_mm"]["mean"]
            f[md.ate_max(name).name] = a["trans_mm"]["max"]
        f[md.ATE_SE3_ROT_RMSE.name] = self.ate["se3"]["rot_deg"]["rmse"] if "se3" in self.ate else float("nan")
        if self.rpe_frame:
            f[md.RPE_FRAME_TRANS_RMSE.name] = self.rpe_frame["trans_mm"]["rmse"]
            f[md.RPE_FRAME_ROT_RMSE.name] = self.rpe_frame["rot_deg"]["rmse"]
        for r in self.rpe_distance:
            f[md.rpe_distance_trans_rmse(r["delta"]).name] = r["trans_mm"]["rmse"]
        for d in (md.END_DRIFT, md.DISTANCE_ERROR, md.PATH_LENGTH, md.MEASURED, md.TURN, md.TURN_ERROR):
            if d.name in self.drift:
                f[d.name] = self.drift[d.name]
        for s in self.segments:
            f[md.segment_t_err(s["length_mm"]).name] = s["t_err_pct"]
        f[md.SEG_MEAN_T_ERR.name] = (
            float(np.mean([s["t_err_pct"] for s in self.segments])) if self.segments else float("nan")
        )
        f[md.SEG_MEAN_R_ERR.name] = (
            float(np.mean([s["r_err_deg_per_m"] for s in self.segments])) if self.segments else float("nan")
        )
        f[md.LOST_FRAMES.name] = float(self.tracking["lost_frames"])
        f[md.LOSS_EVENTS.name] = float(self.tracking["loss_events"])
        f[md.TRACKED_FRACTION.name] = float(self.tracking["tracked_fraction"])
        if "wrong_ok_steps" in self.tracking:
            f[md.WRONG_OK_STEPS.name] = float(self.tracking["wrong_ok_steps"])
        if "wrong_ok_steps_footprint" in self.tracking:
            f[md.WRONG_OK_STEPS_FOOTPRINT.name] = float(self.tracking["wrong_ok_steps_footprint"])
        for stage in md.TIMING_STAGES:
            if stage in self.timing:
                f[md.time_mean(stage).name] = self.timing[stage]["mean"]
        if "fps" in self.timing:
            f[md.FPS.name] = self.timing["fps"]
        return f


def score_trajectories(
    t_ref_s: np.ndarray,
    T_ref: np.ndarray,
    t_est_s: np.ndarray,
    T_est: np.ndarray,
    *,
    estimator: str = "",
    statuses: SequenceT[str] | None = None,
    reasons: SequenceT[str] | None = None,
    timing: dict[str, np.ndarray] | None = None,
    max_diff_s: float = 0.01,
    rpe_deltas_mm: SequenceT[float] = (10.0, 100.0),
    segment_lengths_mm: SequenceT[float] = SEGMENT_LENGTHS_MM,
) -> Score:
    """Score an estimated trajectory against the reference (both ``(ts (N,), T (N, 4, 4) mm)``)."""
    t_ref_s, T_ref = check_trajectory(t_ref_s, T_ref, "reference")
    t_est_s, T_est = check_trajectory(t_est_s, T_est, "estimate")
    i_ref, i_est = associate(t_ref_s, t_est_s, max_diff_s)
    if len(i_ref) < 2:
        raise SequenceError(
            f"estimate has {len(i_ref)} pose(s) matching a ground-truth timestamp within {max_diff_s} s; need >= 2 to score"
        )
    A, B = T_ref[i_ref], T_est[i_est]
    # the reference path's length at each matched pose, along the whole reference: across the
    # frames a run lost, the chord between its matched poses is shorter than the path
    dist = path_distances_mm(T_ref)[i_ref]
    dist = dist - dist[0]
    ates = {m: ate(A, B, m) for m in ALIGNMENTS}
    rpe_d = [rpe(A, B, delta_mm=d, dist_mm=dist) for d in rpe_deltas_mm if dist[-1] >= d]
    drift = end_point_drift(A, B, "none", dist_mm=dist)
    warnings = []
    start_mm = float(np.linalg.norm(A[0, :3, 3] - B[0, :3, 3]))
    if start_mm > FAR_START_MM + FAR_START_FRACTION * dist[-1]:
        # Not in the ground truth's frame: the unaligned figures would measure the offset, not the estimator.
        warnings.append(
            f"the estimate starts {shown_number(start_mm, '.1f')} mm from the ground truth at their first shared time: it is not in "
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
        segments=segment_errors(A, B, segment_lengths_mm, dist_mm=dist),
        tracking=tracking_stats(None if statuses is None else list(statuses), len(T_ref), len(i_est), reasons),
        timing=timing_stats(timing),
        warnings=warnings,
    )


def score_without_groundtruth(
    n_frames: int,
    t_est_s: np.ndarray,
    *,
    estimator: str = "",
    statuses: SequenceT[str] | None = None,
    reasons: SequenceT[str] | None = None,
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
        tracking=tracking_stats(None if statuses is None else list(statuses), n_frames, len(t_est_s), reasons),
        timing=timing_stats(timing),
        ground_truth=why,
    )


def read_run_and_groundtruth(run_dir: str | os.PathLike, seq_dir: str | os.PathLike, purpose: str):
    """``(groundtruth path, (t_ref, T_ref), run)`` of a run; ``run`` is its :class:`~floorvo.runfolder.RunFolder`.

    ``seq_dir`` is a sequence folder (its ``groundtruth.txt``) or a TUM file; ``purpose``
    ("score", "calibrate") words the error when there is no ground truth. A run that records
    another sequence than ``seq_dir`` is refused (:func:`~floorvo.runfolder.check_run_of_sequence`),
    as are a run whose files disagree (:meth:`~floorvo.runfolder.RunFolder.read`) and a sequence's
    ground truth that does not fit its frames (:func:`~floorvo.sequence.read_groundtruth`), and a
    run whose poses do not sit at the frames it marks placed (:func:`check_poses_at_their_frames`).
    """
    run_dir, seq_dir = Path(run_dir), Path(seq_dir)
    gt_path = seq_dir / "groundtruth.txt" if seq_dir.is_dir() else seq_dir
    if not gt_path.is_file():
        raise SequenceError(no_groundtruth_reason(gt_path, purpose))
    run = RunFolder.read(run_dir)
    check_run_of_sequence(run_dir, run.result, seq_dir)
    check_poses_at_their_frames(run_dir, run, seq_dir)
    _, ref = read_groundtruth(seq_dir, purpose)
    return gt_path, ref, run


def check_poses_at_their_frames(
    run_dir: str | os.PathLike, run: RunFolder, seq_dir: str | os.PathLike, max_diff_s: float = 0.01
) -> None:
    """One-line :class:`SequenceError` when the run's k-th pose (``trajectory.txt``) is not at the
    time of the k-th frame its ``timing.csv`` marks ``init`` or ``ok``: the sequence frame nearest
    to the pose's time must be that frame. Or when ``timing.csv`` lists a frame the sequence does
    not have.

    The steps a run reported ok are scored by frame (:func:`ok_step_poses`: pose k against the
    true pose of the k-th placed frame), the trajectory by time: poses written at other times than
    their frames (a program's own clock, a run of another frame range) paired each step with
    another frame's truth and counted right steps wrong. Nothing is checked where ``seq_dir`` is
    not a sequence folder (a TUM file: no frame times), for a ``timing.csv`` without frames or
    statuses, when the counts differ (:meth:`RunFolder.read` refuses that where it applies), or
    when no pose lies within ``max_diff_s`` of a frame's time (a run on another clock, which
    :func:`score_run` scores for tracking only, with a warning).
    """
    seq_dir = Path(seq_dir)
    statuses = run.statuses
    if not (seq_dir / "sequence.json").is_file() or not statuses or not run.timing or "frame" not in run.timing:
        return
    frames = np.asarray(run.timing["frame"], dtype=int)
    t_seq = Sequence.open(seq_dir).timestamps_s
    beyond = frames[(frames < 0) | (frames >= len(t_seq))]
    if len(beyond):
        raise SequenceError(
            f"{Path(run_dir) / TIMING}: lists frame {int(beyond[0])}, and {seq_dir} has frames 0-{len(t_seq) - 1}; "
            "give the sequence the run was made on"
        )
    placed = frames[_measured_from(statuses, None)[0]]
    t_pose = np.asarray(run.timestamps_s, dtype=float)
    if len(placed) != len(t_pose) or not len(t_seq):
        return
    if len(t_seq) == 1:
        nearest = np.zeros(len(t_pose), dtype=int)
    else:
        after = np.clip(np.searchsorted(t_seq, t_pose), 1, len(t_seq) - 1)
        nearest = np.where(np.abs(t_seq[after - 1] - t_pose) <= np.abs(t_seq[after] - t_pose), after - 1, after)
    if not (np.abs(t_seq[nearest] - t_pose) <= max_diff_s).any():
        return  # no pose at a frame's time: another clock, which score_run warns of (tracking only)
    off = np.flatnonzero(nearest != placed)
    if len(off):
        k = int(off[0])
        raise SequenceError(
            f"{Path(run_dir) / TRAJECTORY}: pose {k + 1} is at {t_pose[k]:.6f} s, nearest to frame {int(nearest[k])} "
            f"of {seq_dir}, and {TIMING} marks frame {int(placed[k])} ({t_seq[placed[k]]:.6f} s) as the run's "
            f"placed frame {k + 1}: a pose at the time of each frame marked init or ok"
        )


def score_run(run_dir: str | os.PathLike, seq_dir: str | os.PathLike, *, max_diff_s: float = 0.01) -> Score:
    """Score ``RUN/trajectory.txt`` (+ ``timing.csv``, ``result.json``) against ``SEQ/groundtruth.txt``.

    When the run covered a sub-range of the sequence (``result.json`` ``frames``), the
    reference is cut to the frames the estimator saw, so a lost tail still counts as lost.

    Steps reported ok are scored against the camera's true 6-DoF step (``wrong_ok_steps``)
    and, for a planar estimator's poses, against the planar step of the camera's footprint
    (``wrong_ok_steps_footprint``, :func:`~floorvo.geometry.footprint_T`: what a planar mono
    estimator can see of a tilted camera). A run whose poses an attitude signal made 6-DoF
    (``result.json``'s ``attitude_signal``, :mod:`floorvo.runner`) has no footprint count:
    it is held to the camera's step.
    """
    run_dir, seq_dir = Path(run_dir), Path(seq_dir)
    if seq_dir.is_dir() and not (seq_dir / "groundtruth.txt").exists() and (seq_dir / "sequence.json").is_file():
        check_run_of_sequence(run_dir, RunFolder.read(run_dir).result, seq_dir)
        score = _score_without_groundtruth(run_dir, seq_dir, NO_GROUND_TRUTH)
        log.info("%s: %s; scored tracking and timing only", seq_dir, NO_GROUND_TRUTH)
        return score
    gt_path, (t_ref, T_ref), run = read_run_and_groundtruth(run_dir, seq_dir, "score")
    timing, result = run.timing, run.result
    if len(run.timestamps_s) < 2 and run.statuses:
        # Every step lost (a featureless floor): nothing to compare with the ground truth, but
        # the run is scored: its lost frames, their reasons and no ok step that is wrong.
        score = _score_without_groundtruth(run_dir, seq_dir, NO_TRACK)
        score.tracking["ok_steps_scored"], score.tracking["wrong_ok_steps"] = 0, 0
        score.tracking["wrong_ok_steps_footprint"] = 0
        log.info("%s: %s; scored tracking and timing only", run_dir, NO_TRACK)
        return score
    if len(run.timestamps_s) >= 2 and len(associate(t_ref, run.timestamps_s, max_diff_s)[0]) == 0:
        why = f"the estimate shares no timestamp with the ground truth (within {max_diff_s} s)"
        log.warning("%s: %s; scored tracking and timing only", run_dir, why)
        score = _score_without_groundtruth(run_dir, seq_dir, why)
        score.warnings.append(why + f": check the frame times of the run and of {gt_path.name}")
        return score
    if timing and "frame" in timing and len(timing["frame"]):
        # The estimator saw only these frames: cut the reference to the poses taken at their times.
        frames = timing["frame"].astype(int)
        t_frames = _frame_times_of(seq_dir, t_ref, frames, run)
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
        reasons=_reasons(run),
        timing=timing,
        max_diff_s=max_diff_s,
    )
    score.run_dir, score.seq_dir = str(run_dir), str(seq_dir)
    poses = ok_step_poses_of_run(run, seq_dir, t_ref, T_ref, max_diff_s)
    B_from = _levelled_restart_poses_of_run(run, seq_dir, result) if poses is not None else None
    steps = _step_errors_of(poses, B_from)
    if steps is not None:
        score.tracking["ok_steps_scored"] = len(steps["trans_mm"])
        score.tracking["wrong_ok_steps"] = int(wrong_steps(steps).sum())
        # The same against the footprint's planar step: issue 14's bound for a planar mono
        # estimator on a tilted (or bouncing) run, the footprint shift taken out. Not for a run
        # whose poses an attitude signal made 6-DoF (result.json's attitude_signal): it
        # claims the camera's tilted pose, and is held to the camera's 6-DoF step only.
        if (result or {}).get("attitude_signal"):
            score.tracking["attitude_signal"] = True
        else:
            height = float(np.median(T_ref[:, 2, 3]))
            planar = _ok_steps_of_run(run, seq_dir, t_ref, footprint_T(T_ref, height), max_diff_s, planar=True)
            if planar is not None:
                score.tracking["wrong_ok_steps_footprint"] = int(wrong_steps(planar).sum())
        if poses is not None:
            A, A_from, B = poses
            turn = turn_error(A, B, T_ref_from=A_from)
            # Under MIN_TURN_DEG the error is not reported: left out (an empty results.csv cell), not NaN.
            score.drift.update({k: v for k, v in turn.items() if math.isfinite(v)})
    if result:
        score.extra["result"] = {
            k: result[k]
            for k in ("status_counts", "lost", "fps", "frames_per_second", "scale_calibration_problems")
            if k in result
        }
    for w in score.warnings:
        log.warning("%s: %s", run_dir, w)
    return score


def ok_step_table(
    run_dir: str | os.PathLike, seq_dir: str | os.PathLike, *, max_diff_s: float = 0.01
) -> list[dict[str, Any]]:
    """Every step a run reported ok as :func:`score_run` holds it to the camera's 6-DoF step
    (``wrong_ok_steps``): one dict per step with ``from_frame`` and ``to_frame`` (the frame it
    was measured from and the one it placed), ``true`` and ``measured`` (4, 4) mm steps, and
    :func:`floorvo.metrics.step_errors`' ``step_mm``, ``trans_mm``, ``rot_deg`` and ``wrong``
    (:func:`floorvo.metrics.wrong_steps`). A run whose poses an attitude signal made 6-DoF is
    measured by its own 6-DoF poses, as scored: a diagnostic that compared the estimator's
    levelled steps with the camera's called nearly every step wrong. [] where the run places
    fewer than two frames, or its frames lack ``timing.csv``."""
    _, (t_ref, T_ref), run = read_run_and_groundtruth(run_dir, seq_dir, "score")
    poses = ok_step_poses_of_run(run, seq_dir, t_ref, T_ref, max_diff_s)
    frames = ok_step_frames_of_run(run)
    if poses is None or frames is None:
        return []
    A, A_from, B = poses
    B_from = _levelled_restart_poses_of_run(run, Path(seq_dir), run.result)
    B_from = B[:-1] if B_from is None else B_from
    e = step_errors(A, B, T_ref_from=A_from, T_est_from=B_from)
    wrong = wrong_steps(e)
    return [
        {
            "from_frame": int(frames[0][k]),
            "to_frame": int(frames[1][k]),
            "true": invert_T(A_from[k]) @ A[k + 1],
            "measured": invert_T(B_from[k]) @ B[k + 1],
            "step_mm": float(e["step_mm"][k]),
            "trans_mm": float(e["trans_mm"][k]),
            "rot_deg": float(e["rot_deg"][k]),
            "wrong": bool(wrong[k]),
        }
        for k in range(len(A) - 1)
    ]


def _reasons(run: RunFolder) -> list[str] | None:
    """``timing.csv``'s reason per frame, or None when it has no reason column."""
    if not run.timing or "reason" not in run.timing:
        return None
    return [str(r) for r in run.timing["reason"]]


def ok_step_poses(
    statuses: SequenceT[str],
    reasons: SequenceT[str] | None,
    T_ref_per_frame: np.ndarray,
    T_est_placed: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The poses behind every step a run reported ``ok``: ``(A (P, 4, 4), A_from (P-1, 4, 4), B (P, 4, 4))``.

    ``A``: the true pose of each placed (``init``/``ok``) frame; ``A_from``: the true pose of
    the frame each step was measured from: the last placed frame, or a lost frame on which
    the estimator restarted its track (its reason holds
    :data:`~floorvo.estimators.base.RESTART_NOTE`: the motion over that gap is unknown, and
    the lost frames show it); ``B``: the run's poses. Step k measured ``B_k^-1 B_k+1``; its
    truth is ``A_from_k^-1 A_k+1``. ``statuses``, ``reasons`` (F,): a run's frames
    (``timing.csv``); ``T_ref_per_frame`` (F, 4, 4): the true pose at each of those frames
    (NaN where there is none); ``T_est_placed`` (P, 4, 4): the run's poses, one per
    ``init``/``ok`` frame. None when the run does not fit its trajectory (P is not the number
    of placed frames, or fewer than 2 are placed).
    """
    placed, measured_from = _measured_from(statuses, reasons)
    if len(placed) < 2 or len(placed) != len(T_est_placed):
        return None
    A = np.asarray(T_ref_per_frame, dtype=float)
    return A[placed], A[measured_from], np.asarray(T_est_placed, dtype=float)


def _measured_from(statuses: SequenceT[str], reasons: SequenceT[str] | None) -> tuple[list[int], list[int]]:
    """The indices of a run's placed (``init``/``ok``) frames, and of the frame each step into the
    next placed one was measured from (:func:`ok_step_poses`)."""
    placed, measured_from, ref = [], [], None
    for i, st in enumerate(statuses):
        if st in ("init", "ok"):
            placed.append(i)
            if ref is not None:
                measured_from.append(ref)
            ref = i
        elif reasons is not None and RESTART_NOTE in str(reasons[i]):
            ref = i
    return placed, measured_from


def levelled_restart_poses(
    statuses: SequenceT[str], reasons: SequenceT[str] | None, T_est_placed: np.ndarray, attitude_rad: np.ndarray
) -> np.ndarray:
    """The run's pose of the frame each step was measured from (P-1, 4, 4), for a run whose
    poses are a levelled chain tilted by each frame's attitude (``result.json``'s
    ``attitude_levelled``, :mod:`floorvo.runner`): the last placed pose, but for a step measured
    from a restart frame that pose's position and yaw tilted to the restart frame's attitude
    (``attitude_rad`` (F, 2), the run's frames' readings): where the run holds that frame, the
    chain being unchanged over the lost frames. Against the last placed pose itself the step
    would carry the tilt change across the gap (3.4 degrees on the wood tilt's restarts).
    ``statuses``, ``reasons`` (F,) and ``T_est_placed`` (P, 4, 4): as for :func:`ok_step_poses`."""
    placed, measured_from = _measured_from(statuses, reasons)
    B = np.asarray(T_est_placed, dtype=float)
    B_from = B[:-1].copy()
    att = np.asarray(attitude_rad, dtype=float).reshape(-1, 2)
    for k, (p, r) in enumerate(zip(placed[:-1], measured_from)):
        if r != p and np.isfinite(att[r]).all():
            x, y, z = B[k, :3, 3]
            B_from[k] = T_world_cam_down(x, y, z, yaw_of_R(B[k, :3, :3]), float(att[r, 0]), float(att[r, 1]))
    return B_from


def ok_step_errors(
    statuses: SequenceT[str],
    reasons: SequenceT[str] | None,
    T_ref_per_frame: np.ndarray,
    T_est_placed: np.ndarray,
) -> dict[str, np.ndarray] | None:
    """:func:`floorvo.metrics.step_errors` of every step a run reported ``ok``, each against
    the true motion from the frame it was measured from (:func:`ok_step_poses`, whose
    arguments these are). Steps with no true pose at either end are left out. None when the
    run does not fit its trajectory.
    """
    return _step_errors_of(ok_step_poses(statuses, reasons, T_ref_per_frame, T_est_placed))


def _step_errors_of(
    poses: tuple[np.ndarray, np.ndarray, np.ndarray] | None, B_from: np.ndarray | None = None
) -> dict[str, np.ndarray] | None:
    """:func:`ok_step_errors` of the poses :func:`ok_step_poses` gave (None: None); ``B_from``:
    the run's pose of each step's first frame where it is not the last placed one
    (:func:`levelled_restart_poses`)."""
    if poses is None:
        return None
    A, A_from, B = poses
    errors = step_errors(A, B, T_ref_from=A_from, T_est_from=B_from)
    known = np.isfinite(errors["trans_mm"]) & np.isfinite(errors["rot_deg"])
    if not known.any():
        return None
    return {k: v[known] for k, v in errors.items()}


def _ok_steps_of_run(
    run: RunFolder, seq_dir: Path, t_ref: np.ndarray, T_ref: np.ndarray, max_diff_s: float, *, planar: bool = False
) -> dict[str, np.ndarray] | None:
    """:func:`ok_step_errors` of a run folder (None without ``timing.csv`` frames and statuses).

    ``planar``: the run's poses are compared by their planar part only (x, y, yaw at the
    reference's height), as ``T_ref`` is then (:func:`~floorvo.geometry.footprint_T`)."""
    args = _ok_step_args(run, seq_dir, t_ref, T_ref, max_diff_s)
    if args is None:
        return None
    statuses, reasons, T_per_frame, T_est = args
    if planar and len(T_est):
        T_est = footprint_T(T_est, float(np.nanmedian(T_ref[:, 2, 3])))
    return ok_step_errors(statuses, reasons, T_per_frame, T_est)


def _levelled_restart_poses_of_run(
    run: RunFolder, seq_dir: Path, result: Mapping[str, Any] | None
) -> np.ndarray | None:
    """:func:`levelled_restart_poses` of a run folder whose ``result.json`` says
    ``attitude_levelled``, from the sequence's ``attitude.csv`` at the run's frames; None otherwise."""
    statuses = run.statuses
    if not (result or {}).get("attitude_levelled") or not statuses or not run.timing or "frame" not in run.timing:
        return None
    attitude = Sequence.open(seq_dir).attitude_signal_rad
    frames = np.asarray(run.timing["frame"], dtype=int)
    if attitude is None or len(frames) == 0 or frames.max() >= len(attitude):
        return None
    return levelled_restart_poses(statuses, _reasons(run), run.T_world_cam, attitude[frames])


def ok_step_poses_of_run(
    run: RunFolder, seq_dir: str | os.PathLike, t_ref: np.ndarray, T_ref: np.ndarray, max_diff_s: float = 0.01
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """:func:`ok_step_poses` of a run folder against the reference ``(t_ref (N,), T_ref (N, 4, 4))``;
    None without ``timing.csv`` frames and statuses."""
    args = _ok_step_args(run, Path(seq_dir), t_ref, T_ref, max_diff_s)
    return None if args is None else ok_step_poses(*args)


def ok_step_frames_of_run(run: RunFolder) -> tuple[np.ndarray, np.ndarray] | None:
    """The sequence frame numbers ``(from (P-1,), to (P-1,))`` of the steps of :func:`ok_step_poses_of_run`:
    each step into a placed frame and the frame it was measured from; None without ``timing.csv``
    frames and statuses, or with fewer than 2 placed frames."""
    statuses = run.statuses
    if not statuses or not run.timing or "frame" not in run.timing:
        return None
    frames = np.asarray(run.timing["frame"], dtype=int)
    placed, measured_from = _measured_from(statuses, _reasons(run))
    if len(placed) < 2:
        return None
    return frames[measured_from], frames[placed[1:]]


def _ok_step_args(run: RunFolder, seq_dir: Path, t_ref: np.ndarray, T_ref: np.ndarray, max_diff_s: float):
    """``(statuses, reasons, T_ref_per_frame, T_est_placed)`` of a run folder, or None."""
    statuses = run.statuses
    if not statuses or not run.timing or "frame" not in run.timing:
        return None
    frames = np.asarray(run.timing["frame"], dtype=int)
    t_frames = _frame_times_of(seq_dir, t_ref, frames, run)
    if len(t_frames) != len(frames):
        return None
    T_per_frame = np.full((len(frames), 4, 4), np.nan)
    i_ref, i_frame = associate(t_ref, t_frames, max_diff_s)
    T_per_frame[i_frame] = T_ref[i_ref]
    return statuses, _reasons(run), T_per_frame, run.T_world_cam


def _score_without_groundtruth(run_dir: Path, seq_dir: Path, why: str) -> Score:
    run = RunFolder.read(run_dir)
    n_frames = len(run.timing["frame"]) if run.timing and "frame" in run.timing else None
    if n_frames is None and run.result.get("frames"):
        n_frames = int(run.result["frames"])
    if n_frames is None:  # a run without timing.csv (a program's): every frame of the sequence
        if seq_dir.is_dir():
            n_frames = int(read_json(seq_dir / "sequence.json").get("frame_count", 0))
        else:  # a bare TUM ground truth (floorvo score RUN --gt FILE): a frame at each of its poses
            n_frames = len(read_tum(seq_dir)[0])
    score = score_without_groundtruth(
        n_frames,
        run.timestamps_s,
        estimator=str(run.result.get("estimator", "")),
        statuses=run.statuses,
        reasons=_reasons(run),
        timing=None if run.timing is None else dict(run.timing),
        why=why,
    )
    score.run_dir, score.seq_dir = str(run_dir), str(seq_dir)
    return score


def _frame_times_of(seq_dir: Path, t_ref: np.ndarray, frames: np.ndarray, run: RunFolder) -> np.ndarray:
    """Times (s) of the sequence's ``frames`` (the run's ``timing.csv`` frames): from the sequence
    folder (``timestamps.txt`` or ``i / fps``). For a bare ground-truth file, which has no frame
    times: a placed frame at its pose's time (``trajectory.txt``), the others linear in the frame
    number between and beyond them; with fewer than two placed frames, frame i at i over the
    ground truth's median rate (a recording's ground truth at Unix times then pairs with nothing,
    as frame i at i / rate from 0 did for every run: its ok steps went unscored)."""
    if (seq_dir / "sequence.json").is_file():
        ts = Sequence.open(seq_dir).timestamps_s
        return ts[frames[(frames >= 0) & (frames < len(ts))]]
    statuses = run.statuses or []
    placed = frames[_measured_from(statuses, None)[0]].astype(float)
    t_pose = np.asarray(run.timestamps_s, dtype=float)
    if len(placed) >= 2 and len(placed) == len(t_pose):
        s_per_frame = (t_pose[-1] - t_pose[0]) / (placed[-1] - placed[0])
        inside = np.interp(frames, placed, t_pose)
        return np.where(
            frames < placed[0],
            t_pose[0] + (frames - placed[0]) * s_per_frame,
            np.where(frames > placed[-1], t_pose[-1] + (frames - placed[-1]) * s_per_frame, inside),
        )
    d = np.diff(t_ref)
    fps = float(1.0 / np.median(d)) if len(d) else 1.0
    return frames / fps


def write_score(score: Score, path: str | os.PathLike) -> None:
    """Write ``score`` as JSON (:meth:`Score.to_dict`) to ``path``, atomically (``RUN/score.json``)."""
    atomic_write_json(path, score.to_dict())

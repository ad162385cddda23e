"""The frame loop: run an estimator over frames and chain its steps into poses.

Every caller that runs an estimator over frames (``floorvo run``, ``floorvo localize``,
the paper-000 strip runs, the bench's match samples) goes through :func:`run_frames`, or
:func:`run_sequence` on top of it, and writes what it got with
:class:`floorvo.runfolder.RunFolder` (:meth:`RunResult.run_folder`)::

    est, cfg = floorvo.run.build_estimator(seq, "phase-corr")
    res = run_sequence(seq, est)               # RunResult: a pose and a status per frame
    ts, T_world_cam = res.trajectory()         # the frames it placed

Chaining (the motion convention of :mod:`floorvo.estimators.base`): the pose starts at
``T_world_start``; a step that reports an absolute pose (``StepResult.T_world_cam``, a map
fix) sets it, and counts as a fix; otherwise an ``ok`` step composes it with its motion,
``T_world_cur = T_world_prev @ T_prev_cur``, after dividing out the rig's scale
calibration when one is given (:func:`floorvo.calibration.apply_scale`). ``init`` places
the frame at the current pose; ``lost`` places nothing and keeps the pose, so the next
frame continues from the last good one.

With an attitude signal (``attitude.csv``: each frame's roll and pitch, ``Frame.attitude_rad``)
and a planar mono estimator (``measures_footprint``, ``use_attitude_signal``) the poses are
made the tilted camera's, in one of two ways:

* the estimator measures the motion of the camera's footprint (phase-corr): the chain is the
  footprint's (it starts at the footprint of the start pose turned to the first frame's
  attitude), each step loses the turn about the optical axis that the tilt change gives the
  picture (:func:`floorvo.geometry.tilt_twist_rad`), and each frame is placed at the tilted
  camera over that footprint (:func:`floorvo.geometry.tilted_camera_T`);
* the estimator levels its keypoints with the frame's attitude (``levels_with_attitude``: the
  AKAZE estimators): its steps are those of a camera at the camera's centre looking straight
  down, the chain is that levelled camera's, and each frame is placed at it tilted about its
  centre by the frame's roll and pitch.

A frame without a reading is not placed (lost, the motion chained through it where the
estimator measured it); a step that the signal's noise (:func:`attitude_noise_rad`) leaves
uncertain beyond the estimator's bound is lost too (:func:`_attitude_problem`).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from floorvo.calibration import ScaleCalibration, apply_scale
from floorvo.errors import ConfigError, FloorbenchError, SequenceError
from floorvo.estimators.base import RESTART_NOTE, Frame, StepResult, frame_height_mm, takes_height_change_from_signal
from floorvo.geometry import (
    MAX_POSITION_MM,
    T_world_cam_down,
    depth_floor_plane,
    footprint_T,
    make_T,
    position_problem,
    rigid_problem,
    rot_z,
    tilt_twist_rad,
    tilted_camera_T,
    yaw_of_R,
)
from floorvo.imaging import mean_orientation, texture_orientation
from floorvo.metrics import CHAINED_NOTE, WRONG_STEP_FRACTION, WRONG_STEP_MM, lost_reasons
from floorvo.runfolder import COUNT_COLUMNS, STATUSES, TIMING_MS_COLUMNS, RunFolder
from floorvo.sequence import GROUNDTRUTH_MAX_DIFF_S, Sequence
from floorvo.tum import MAX_TIME_S, time_problem

__all__ = [
    "RunResult",
    "OnStep",
    "run_frames",
    "run_sequence",
    "sequence_frames",
    "camera_height_mm",
    "uses_attitude_signal",
    "attitude_noise_rad",
    "NO_ATTITUDE",
]

log = logging.getLogger(__name__)

#: Called after every step with ``(k, frame, step_result)``; ``k`` counts from 0.
OnStep = Callable[[int, Frame, StepResult], None]

_STAGES = tuple(c[: -len("_ms")] for c in TIMING_MS_COLUMNS)  # detect, match, estimate, total
_PLACED = ("init", "ok")
#: The reason of a frame whose step was measured but that has no attitude reading (a dropout
#: of ``attitude.csv``) in a run whose poses the attitude signal makes 6-DoF.
NO_ATTITUDE = f"no attitude reading (attitude.csv): no 6-DoF pose; {CHAINED_NOTE}"
#: The reason of a frame whose picture repeats the previous frame's bit for bit (:func:`run_frames`):
#: a camera's noise never gives two such pictures, a re-delivered buffer does (every estimator
#: measured no motion there, and the motion of both frames at the next).
REPEATED_FRAME = "the picture repeats the previous frame's bit for bit (a buffer delivered twice?): not measured"


@dataclass(frozen=True)
class RunResult:
    """What a run gave, per frame the estimator saw (F frames).

    ``frame_index`` (F,) int: ``Frame.index``; ``timestamp_s`` (F,); ``status`` (F,)
    object array of ``init``/``ok``/``lost``; ``reason`` (F,) object array; ``timing_ms``
    (F, 4): detect, match, estimate, total (NaN where the estimator did not time a stage);
    ``counts`` (F, 3) int: keypoints, matches, inliers; ``T_world_cam`` (F, 4, 4) mm: the
    pose after each frame (a frame not placed holds the pose before it); ``fixed`` (F,)
    bool: the step reported an absolute pose (a map fix); ``wall_s``: wall-clock seconds
    of the loop, frame reading included. ``run_dir``: where it was written, "" if not.
    ``attitude_signal``: the poses are the tilted camera's, made 6-DoF with the frames'
    attitude (module docstring); a run folder records it (``result.json``) and scoring then
    holds its steps to the camera's 6-DoF step only. ``attitude_levelled``: and the estimator
    levelled its frames with it (``levels_with_attitude``: each pose is the levelled chain's,
    tilted about the camera's centre by that frame's attitude).
    """

    estimator: str
    frame_index: np.ndarray
    timestamp_s: np.ndarray
    status: np.ndarray
    reason: np.ndarray
    timing_ms: np.ndarray
    counts: np.ndarray
    T_world_cam: np.ndarray
    fixed: np.ndarray
    wall_s: float
    run_dir: str = ""
    attitude_signal: bool = False
    attitude_levelled: bool = False

    @property
    def frames(self) -> int:
        """How many frames the estimator saw."""
        return len(self.frame_index)

    @property
    def placed(self) -> np.ndarray:
        """(F,) bool: frames with a pose (status ``init`` or ``ok``)."""
        return (self.status == "init") | (self.status == "ok")

    @property
    def status_counts(self) -> dict[str, int]:
        return {s: int(np.count_nonzero(self.status == s)) for s in STATUSES}

    @property
    def ok(self) -> int:
        return self.status_counts["ok"]

    @property
    def lost(self) -> int:
        return self.status_counts["lost"]

    @property
    def fixes(self) -> int:
        """Frames placed by an absolute pose the estimator reported (map fixes)."""
        return int(np.count_nonzero(self.fixed))

    @property
    def lost_frames(self) -> list[dict[str, Any]]:
        """``[{"frame": index, "reason": why}, ...]`` of the frames not placed."""
        return [
            {"frame": int(i), "reason": str(r)}
            for i, r in zip(self.frame_index[~self.placed], self.reason[~self.placed])
        ]

    @property
    def fps(self) -> float:
        """Frames per second of the whole loop (wall clock)."""
        return self.frames / self.wall_s if self.wall_s > 0 else 0.0

    @property
    def median_total_ms(self) -> float:
        """Median of the estimator's ``total`` time per frame, ms (a frame it did not time counts 0)."""
        total = np.nan_to_num(self.timing_ms[:, 3], nan=0.0)
        return float(np.median(total)) if total.size else 0.0

    def trajectory(self) -> tuple[np.ndarray, np.ndarray]:
        """``(timestamps_s (N,), T_world_cam (N, 4, 4) mm)`` of the placed frames."""
        keep = self.placed
        return self.timestamp_s[keep], self.T_world_cam[keep]

    def timing_columns(self, *, reasons: bool = False) -> dict[str, np.ndarray]:
        """The columns of ``timing.csv``; ``reasons`` adds the ``reason`` column.

        A stage the estimator did not time is written as 0, as ``timing.csv`` always had it.
        """
        cols: dict[str, np.ndarray] = {"frame": self.frame_index}
        ms = np.nan_to_num(self.timing_ms, nan=0.0)
        cols.update({c: ms[:, j] for j, c in enumerate(TIMING_MS_COLUMNS)})
        cols["status"] = self.status
        cols.update({c: self.counts[:, j] for j, c in enumerate(COUNT_COLUMNS)})
        if reasons:
            cols["reason"] = self.reason
        return cols

    def summary(self) -> dict[str, Any]:
        """``result.json``'s part every run has (callers add config, sequence, ...)."""
        return {
            "estimator": self.estimator,
            "run_dir": self.run_dir,
            "frames": self.frames,
            "ok": self.ok,
            "lost": self.lost,
            "lost_frames": self.lost_frames,
            "lost_reasons": lost_reasons(list(self.status), [str(r) for r in self.reason]),
            "fps": self.fps,
            "median_total_ms": self.median_total_ms,
            "status_counts": self.status_counts,
            "map_fixes": self.fixes,
            "attitude_signal": self.attitude_signal,
            "attitude_levelled": self.attitude_levelled,
            "first_frame": int(self.frame_index[0]) if self.frames else None,
            "last_frame": int(self.frame_index[-1]) if self.frames else None,
        }

    def run_folder(self, *, header: str, result: Mapping[str, Any], reasons: bool = False) -> RunFolder:
        """The run folder of this run: its trajectory, ``timing.csv`` and ``result`` as ``result.json``."""
        ts, T = self.trajectory()
        return RunFolder(ts, T, self.timing_columns(reasons=reasons), dict(result), header)


def _check_rigid(T: Any, name: str, index: int, what: str) -> None:
    """A pose an estimator returned must be a rigid (4, 4) transform of finite numbers: chained
    as it is, a scaled, sheared or NaN matrix gives every later pose of the run that flaw."""
    problem = rigid_problem(T)
    if problem is not None:
        raise ValueError(f"{name}: frame {index}: {what} is not a rigid transform ({problem})")


def run_frames(
    estimator: Any,
    frames: Iterable[Frame],
    *,
    T_world_start: np.ndarray,
    scale_calibration: ScaleCalibration | None = None,
    on_step: OnStep | None = None,
    name: str | None = None,
    attitude_noise_rad: float = 0.0,
    height_noise_mm: float = 0.0,
    T_world_at: Callable[[Frame], np.ndarray | None] | None = None,
    lose_repeated_pictures: bool = True,
    summary_warnings: bool = True,
) -> RunResult:
    """Run ``estimator`` (an :class:`~floorvo.estimators.base.Estimator`) over ``frames`` from a fresh state.

    ``T_world_start`` (4, 4) mm: the pose the run starts at (see the module doc for the
    chaining). ``T_world_at``: the true pose (4, 4) mm of a frame, None where unknown (the
    ground truth, :func:`run_sequence`): where the estimator starts on a later frame than the
    first (the first ones lost: a black frame while a real camera's exposure settles), the run
    starts at that frame's pose instead of ``T_world_start``, the first frame's (the frame was
    placed there, and every pose of the run was off by the motion over the lost frames). ``scale_calibration`` is divided out of every motion step, never out of an
    absolute pose. ``on_step(k, frame, step_result)`` is called after each step (progress,
    match samples). ``name``: the run's estimator name (default ``estimator.name``).
    An estimator that breaks the protocol (an unknown status, ``ok`` without motion, a motion or
    pose that is not a rigid (4, 4) transform of finite numbers, steps that chain to a position
    beyond :data:`~floorvo.geometry.MAX_POSITION_MM`) is a bug: ``ValueError``.
    ``lose_repeated_pictures``: a frame whose picture repeats the last frame's bit for bit is
    reported lost (:data:`REPEATED_FRAME`) and not handed to the estimator; False for frames
    that repeat a picture by design (paper 000's protocol, whose runs repeat a strip frame
    where they stand still). ``summary_warnings``: warn at the end what the run lost to its
    signals (off for runs that re-run frames of a run already said: a bench's match samples).
    ``attitude_noise_rad``: the standard error of each reading of the frames' attitude signal
    (:func:`attitude_noise_rad`; :func:`run_sequence` estimates it from the sequence's): a step
    that the signal would leave uncertain beyond the estimator's bound is lost
    (:func:`_attitude_problem`). ``height_noise_mm``: the standard deviation of each reading
    of the frames' height signal (``Frame.height_mm``; :func:`run_sequence` takes the one the
    sequence states, :attr:`~floorvo.sequence.Sequence.height_noise_mm`): an ``ok`` step of an
    estimator that takes its height change from the readings
    (:func:`takes_height_change_from_signal`) that the signal leaves uncertain beyond the
    estimator's bound is lost (:func:`_height_noise_problem`).

    Refused in one line (:class:`~floorvo.errors.ConfigError`): a ``T_world_start`` that is no
    rigid transform of finite numbers (:func:`~floorvo.geometry.rigid_problem`; a NaN start gave
    a run of NaN poses, a scaled one every step scaled, a transposed one lost its position);
    (:class:`~floorvo.errors.FloorbenchError`) a frame whose ``timestamp_s`` is no time
    (:func:`floorvo.tum.time_problem`) or does not follow the last frame's: a run's frames are in
    time order, as its trajectory is (a TUM file's times increase).
    """
    name = getattr(estimator, "name", type(estimator).__name__) if name is None else name
    start_problem = rigid_problem(T_world_start)
    if start_problem is not None:
        raise ConfigError(f"{name}: T_world_start: {start_problem} (the run's start pose T_world_cam (4, 4), mm)")
    T_world = np.array(T_world_start, dtype=float)
    # The chained pose: the camera's; with an attitude signal, for an estimator that levels its
    # frames with it (levels_with_attitude) the levelled camera's, else its footprint's
    # (module docstring).
    T_chain = T_world
    attitude = False
    prev_image = None  # the last frame's picture (a repeat of it is not measured)
    unused_attitude = False  # the frames' attitude, set aside for the run (its start pose is not over the floor)
    levelled = bool(getattr(estimator, "levels_with_attitude", False))
    height_steps = takes_height_change_from_signal(estimator)
    height_noisy = 0  # steps lost to the height signal's noise
    measured_from: tuple[float, float] | None = None  # attitude of the frame the next step is measured from
    # A calibration whose scales depend on the texture orientation: each frame's, and that of the
    # frame the next step is measured from (floorvo.calibration).
    orient = scale_calibration is not None and scale_calibration.uses_orientation
    theta_from: float | None = None
    state = estimator.start()
    started = False  # whether the estimator has placed a frame (init or ok) yet
    index, stamp, status, reason, timing, counts, poses, fixed = [], [], [], [], [], [], [], []
    nan = float("nan")
    t0 = time.perf_counter()
    t_last = -math.inf
    for k, frame in enumerate(frames):
        t_frame = frame.timestamp_s
        if not t_last < t_frame <= MAX_TIME_S:  # one comparison a frame; NaN fails it too
            why = time_problem(float(t_frame)) or f"= {t_frame!r} s follows the last frame's {t_last!r} s"
            raise FloorbenchError(
                f"{name}: frame {frame.index}: timestamp_s {why}: a run's frames are in time order, one a time"
            )
        t_last = t_frame
        if k == 0 and frame.attitude_rad is not None and uses_attitude_signal(estimator):
            start = _start_footprint(T_world, frame.attitude_rad, levelled=levelled)
            if start is None:
                log.warning(
                    "%s: the run starts at a pose whose optical axis does not meet the floor (no ground truth?): "
                    "its attitude signal is not used (give a start pose over the floor, --initial-pose)",
                    name,
                )
                unused_attitude = True
            else:
                T_chain, attitude = start, True
        if unused_attitude and frame.attitude_rad is not None:
            # not used, so not handed on: the estimator levelled its frames with it and lost those
            # without a reading while the run chained its steps as a level camera's
            frame = replace(frame, attitude_rad=None)
        if lose_repeated_pictures and _same_picture(frame.image, prev_image):
            # not handed to the estimator: its next step is measured from the frame it last measured
            res = StepResult("lost", reason=REPEATED_FRAME)
        else:
            res = estimator.step(state, frame)
        prev_image = frame.image
        if not isinstance(res, StepResult):
            raise ValueError(f"{name}: frame {frame.index}: step returned a {type(res).__name__}, not a StepResult")
        # Measured only on a frame a step ends on or is measured from (a frame the estimator
        # refused, of no image or another shape, gives none).
        theta = None
        if orient and np.ndim(frame.image) == 2 and (res.status in _PLACED or RESTART_NOTE in res.reason):
            theta = texture_orientation(frame.image)[0]
        st = res.status
        why = res.reason
        fix = False
        if st == "init" and k > 0 and not started and T_world_at is not None:
            T_true = T_world_at(frame)  # the estimator starts on this frame: the run starts at its pose
            if T_true is not None:
                T_world = T_chain = np.array(T_true, dtype=float)
                if attitude and frame.attitude_rad is not None:
                    start = _start_footprint(T_world, frame.attitude_rad, levelled=levelled)
                    T_chain = T_chain if start is None else start
        started = started or st in _PLACED
        if st not in _PLACED:
            if st != "lost":
                raise ValueError(f"{name}: frame {frame.index}: status {st!r} (an estimator returns init, ok or lost)")
        elif res.T_world_cam is not None:
            _check_rigid(res.T_world_cam, name, frame.index, "T_world_cam")
            T_chain = np.array(res.T_world_cam, dtype=float)
            fix = True
        elif st == "ok":
            if res.T_prev_cur is None:
                raise ValueError(f"{name}: frame {frame.index}: status 'ok' without T_prev_cur")
            _check_rigid(res.T_prev_cur, name, frame.index, "T_prev_cur")
            if scale_calibration is None:
                step = res.T_prev_cur
            else:
                step_theta = None if theta is None or theta_from is None else float(mean_orientation(theta_from, theta))
                step = apply_scale(res.T_prev_cur, scale_calibration, theta if step_theta is None else step_theta)
            if attitude and not levelled:
                step = _untwisted(step, measured_from, frame.attitude_rad)
            T_chain = T_chain @ step
        if st in _PLACED or RESTART_NOTE in res.reason:
            theta_from = theta  # the next step is measured from this frame
        if (
            st == "ok"
            and height_steps
            and height_noise_mm > 0.0
            and res.T_world_cam is None  # a fix (map-fused's) places the frame: not the readings' difference
            and frame_height_mm(frame) is not None
        ):
            noisy = _height_noise_problem(estimator, res, height_noise_mm)
            if noisy:  # measured and chained, not placed: the signal leaves its height change uncertain
                st, why, fix = "lost", noisy, False
                height_noisy += 1
        if not attitude:
            if st in _PLACED:  # a frame lost after its step was chained keeps the last placed pose
                T_world = T_chain
        else:
            roll, pitch = frame.attitude_rad or (nan, nan)
            known = bool(np.isfinite(roll) and np.isfinite(pitch))
            if known and (st in _PLACED or RESTART_NOTE in res.reason):
                measured_from = (roll, pitch)  # the next step is measured from this frame
            noisy = _attitude_problem(estimator, res, attitude_noise_rad, float(T_chain[2, 3])) if st == "ok" else ""
            if st in _PLACED:
                if not known:  # a dropout: measured and chained, not placed
                    st, why, fix = "lost", NO_ATTITUDE, False
                elif noisy:  # measured and chained, not placed: the signal leaves it uncertain
                    st, why, fix = "lost", noisy, False
                elif levelled:  # the levelled camera tilted about its own centre
                    x, y, z = T_chain[:3, 3]
                    T_world = T_world_cam_down(x, y, z, yaw_of_R(T_chain[:3, :3]), roll, pitch)
                else:
                    T_world = tilted_camera_T(T_chain, roll, pitch)
        if st in _PLACED and not float(np.abs(T_world[:3, 3]).max()) <= MAX_POSITION_MM:
            # finite steps can chain to a place no pose file holds (1e11 mm steps): said here, with the
            # estimator named, not by the trajectory's writer after the run
            raise ValueError(
                f"{name}: frame {frame.index}: its steps place the camera at {position_problem(T_world[:3, 3])}"
            )
        index.append(frame.index)
        stamp.append(frame.timestamp_s)
        status.append(st)
        reason.append(why)
        tm = res.timing_ms
        timing.append([tm.get(s, nan) for s in _STAGES])
        counts.append((res.n_keypoints, res.n_matches, res.n_inliers))
        poses.append(T_world)
        fixed.append(fix)
        if on_step is not None:
            on_step(k, frame, res)
    wall = time.perf_counter() - t0
    if height_noisy and summary_warnings:
        log.warning(
            "%s: %d step(s) lost: the height signal's stated noise (%.3g mm) leaves their height change uncertain "
            "beyond the bound; with use_height_signal = false (and fit_image_scale = true where it is off) the "
            "estimator takes the height from the picture",
            name,
            height_noisy,
            height_noise_mm,
        )
    n = len(index)
    return RunResult(
        estimator=name,
        frame_index=np.array(index, dtype=int),
        timestamp_s=np.array(stamp, dtype=float),
        status=np.array(status, dtype=object),
        reason=np.array(reason, dtype=object),
        timing_ms=np.array(timing, dtype=float).reshape(n, len(_STAGES)),
        counts=np.array(counts, dtype=int).reshape(n, len(COUNT_COLUMNS)),
        T_world_cam=np.array(poses, dtype=float).reshape(n, 4, 4),
        fixed=np.array(fixed, dtype=bool),
        wall_s=wall,
        attitude_signal=attitude,
        attitude_levelled=attitude and levelled,
    )


def attitude_noise_rad(attitude_rad: np.ndarray | None) -> float:
    """The standard error (rad) of each reading of an attitude signal ``attitude_rad`` (N, 2)
    (roll, pitch; NaN where no reading), estimated from the signal itself: the k-th differences
    of white noise of standard error s have variance C(2k, k) s^2 (20 s^2 for k = 3), while those
    of a robot's tilt, smooth over a few frames, are small (0.03 rad at 1.5 Hz and 30 frames/s:
    0.9 mrad at k = 3); the median absolute third difference (the highest order the readings
    allow, up to 3) over both angles, as a normal standard error (x 1.4826), over sqrt(C(2k, k)).
    An upper bound where the tilt itself changes fast. Where no readings are consecutive (every
    other one missing: the estimate was 0, the noise taken as nil, and a 3 mrad IMU's steps were
    reported ok and wrong) the readings every 2nd, 3rd or 4th frame are differenced alike (white
    noise's differences do not depend on the spacing; the tilt's grow with it: still an upper
    bound). 0.0 where not even those are there (fewer than two readings 4 frames apart)."""
    if attitude_rad is None:
        return 0.0
    a = np.asarray(attitude_rad, dtype=float).reshape(-1, 2)
    for stride in (1, 2, 3, 4):
        for k in (3, 2, 1):
            d = np.concatenate(
                [np.diff(a[off::stride], k, axis=0).ravel() for off in range(stride) if len(a[off::stride]) > k]
                or [np.empty(0)]
            )
            d = d[np.isfinite(d)]
            if d.size:
                return float(1.4826 * np.median(np.abs(d)) / np.sqrt(math.comb(2 * k, k)))
    return 0.0


def _attitude_problem(estimator: Any, res: StepResult, noise_rad: float, height_mm: float) -> str:
    """Why an ``ok`` step made 6-DoF with an attitude signal whose readings each have the standard
    error ``noise_rad`` is too uncertain to report ('' when it is not): a reading's error moves
    the camera's pose by ``height_mm`` x the error, a step's by sqrt(2) of that, and at the
    estimator's ``precision_sigmas`` that must stay within its bound for the step
    (:func:`_step_uncertainty_problem`). A signal of 1.5 mrad at 100 mm: 0.53 mm against the
    0.13 mm of a 4 mm step; 0.2 mrad: 0.07 mm."""
    if noise_rad <= 0.0:
        return ""
    return _step_uncertainty_problem(
        estimator,
        res,
        np.sqrt(2.0) * height_mm * noise_rad,
        f"attitude signal too noisy for the step: {{sigmas:g}} x 1.414 x its noise {1e3 * noise_rad:.2f} mrad "
        f"x height {height_mm:.1f} mm",
    )


def _height_noise_problem(estimator: Any, res: StepResult, noise_mm: float) -> str:
    """Why an ``ok`` step whose height change is the difference of two height readings, each
    with the standard deviation ``noise_mm``, is too uncertain to report ('' when it is not): the
    change has sqrt(2) x that, and at the estimator's ``precision_sigmas`` it must stay within its
    bound for the step (:func:`_step_uncertainty_problem`). A range sensor of 0.1 mm: 0.35 mm
    against the 0.13 mm of a 4 mm step (taken as exact, 12 of 40 steps of a bounce were reported ok
    and wrong); 0.02 mm: 0.07 mm."""
    return _step_uncertainty_problem(
        estimator,
        res,
        np.sqrt(2.0) * noise_mm,
        f"height signal too noisy for the step: {{sigmas:g}} x 1.414 x its stated noise {noise_mm:.3f} mm",
    )


def _step_uncertainty_problem(estimator: Any, res: StepResult, sd_mm: float, said: str) -> str:
    """Why an ``ok`` step that a signal leaves uncertain by the standard deviation ``sd_mm`` (mm)
    cannot be reported ('' when it can): ``precision_sigmas`` of it must stay within the
    estimator's bound for the step (:class:`floorvo.estimators.base.StepBoundConfig`; an
    estimator without those keys: the scoring's bound, :data:`floorvo.metrics.WRONG_STEP_MM` and
    its siblings, at 2.5). ``said``: how the reason starts (``{sigmas}`` filled in)."""
    if res.T_prev_cur is None:
        return ""
    cfg = getattr(estimator, "config", None)
    sigmas = float(getattr(cfg, "precision_sigmas", 2.5))
    if sigmas <= 0.0:
        return ""
    step_mm = float(np.linalg.norm(np.asarray(res.T_prev_cur, dtype=float)[:3, 3]))
    bound = getattr(cfg, "bound_mm", None)
    bound_mm = float(bound(step_mm)) if callable(bound) else WRONG_STEP_MM + WRONG_STEP_FRACTION * step_mm
    err_mm = sigmas * sd_mm
    if err_mm <= bound_mm:
        return ""
    return f"{said.format(sigmas=sigmas)} = {err_mm:.3f} mm > bound {bound_mm:.3f} mm; {CHAINED_NOTE}"


def _same_picture(image: Any, prev: Any) -> bool:
    """Whether the frame picture ``image`` (an array) repeats ``prev`` bit for bit, and shows
    something (a blank picture, every pixel alike, is the estimator's to refuse: "empty
    frame"): a few rows first (two pictures of a camera differ there at once), then the whole."""
    if image is None or prev is None:
        return False
    a, b = np.asarray(image), np.asarray(prev)
    if a.shape != b.shape or a.dtype != b.dtype or a.ndim < 1 or a.size == 0:
        return False
    step = max(1, len(a) // 8)
    if not (np.array_equal(a[::step], b[::step]) and np.array_equal(a, b)):
        return False
    return bool(a.min() != a.max())


def uses_attitude_signal(estimator: Any) -> bool:
    """True when the runner turns ``estimator``'s poses into the tilted camera's with the frames'
    attitude: a planar mono estimator (its class's ``measures_footprint``) whose config's
    ``use_attitude_signal`` is on (module docstring)."""
    if not getattr(estimator, "measures_footprint", False):
        return False
    return bool(getattr(getattr(estimator, "config", None), "use_attitude_signal", True))


def _untwisted(
    step: np.ndarray, attitude_prev: tuple[float, float] | None, attitude_cur: tuple[float, float] | None
) -> np.ndarray:
    """A planar estimator's step ``T_prev_cur`` (4, 4) with the turn about the optical axis that
    the tilt change between the two frames gives the picture taken out
    (:func:`floorvo.geometry.tilt_twist_rad`): what is left is the footprint's yaw step.
    ``attitude_prev``: the attitude of the frame the step was measured from, or where that
    frame had no reading the last reading before it (the step into that frame kept its twist,
    so this takes out both); the step as it is when the current frame has no reading."""
    if attitude_prev is None or attitude_cur is None or not np.isfinite(attitude_cur).all():
        return step
    return step @ make_T(rot_z(-tilt_twist_rad(attitude_prev, attitude_cur)), np.zeros(3))


def _start_footprint(
    T_world_start: np.ndarray, attitude_rad: tuple[float, float], *, levelled: bool = False
) -> np.ndarray | None:
    """The pose (4, 4) an attitude chain starts at: the footprint of a camera at
    ``T_world_start``'s position and yaw with the first frame's measured attitude (its own
    tilt where the frame has no reading); with ``levelled`` (an estimator that levels its
    keypoints, ``levels_with_attitude``) that camera levelled about its own centre instead
    (looking straight down, the same yaw). None when the optical axis does not meet the floor
    (a start at the identity)."""
    T = np.asarray(T_world_start, dtype=float)
    roll, pitch = attitude_rad
    if np.isfinite(roll) and np.isfinite(pitch):
        T = T_world_cam_down(T[0, 3], T[1, 3], T[2, 3], yaw_of_R(T[:3, :3]), roll, pitch)
    F = footprint_T(T, float(T[2, 3]))[0]
    if not (np.isfinite(F).all() and T[2, 3] > 0):
        return None
    return T_world_cam_down(T[0, 3], T[1, 3], T[2, 3], yaw_of_R(T[:3, :3])) if levelled else F


def camera_height_mm(seq: Sequence) -> float:
    """The sequence's camera height above the floor (mm); refused when ``sequence.json`` does not state it."""
    height = seq.height_mm
    if height is None:
        raise SequenceError(
            f"{seq.root}/sequence.json: rig.height_mm is missing (the camera height above the floor, mm)"
        )
    return height


def sequence_frames(
    seq: Sequence, indices: Iterable[int], requires: Iterable[str] = (), *, depth_height: bool = False
) -> Iterator[Frame]:
    """Frames ``indices`` of ``seq`` at the sequence's frame times, read one at a time, with the
    right camera and depth when ``requires`` says.

    Each frame carries the camera's measured height (``Frame.height_mm``, issue 14 item 4):
    the sequence's ``height.csv`` (a range sensor) when it has one, else, with
    ``depth_height`` in a sequence with depth, the floor plane of the frame's depth image
    (:func:`floorvo.geometry.depth_floor_plane`); None otherwise. And its measured attitude
    (``Frame.attitude_rad``): the row of the sequence's ``attitude.csv`` (NaN where no
    reading), None without one.
    """
    req = set(requires)
    ts_all = seq.timestamps_s
    heights = seq.height_signal_mm
    attitudes = seq.attitude_signal_rad
    camera = seq.camera
    for i in indices:
        depth = seq.depth_mm(i) if "depth" in req or (depth_height and heights is None and seq.has_depth) else None
        height: float | None = None
        if heights is not None:
            height = None if np.isnan(heights[i]) else float(heights[i])
        elif depth is not None:
            plane = depth_floor_plane(depth, camera, 8)
            height = None if plane is None else plane[1]
        yield Frame(
            index=i,
            timestamp_s=float(ts_all[i]),
            image=seq.image(i),
            image_right=seq.image(i, "cam1") if "stereo" in req else None,
            depth_mm=depth if "depth" in req else None,
            height_mm=height,
            attitude_rad=None if attitudes is None else (float(attitudes[i, 0]), float(attitudes[i, 1])),
        )


def run_sequence(
    seq: Sequence,
    estimator: Any,
    *,
    frames: Iterable[int] | None = None,
    T_world_start: np.ndarray | None = None,
    scale_calibration: ScaleCalibration | None = None,
    on_step: OnStep | None = None,
    name: str | None = None,
    summary_warnings: bool = True,
) -> RunResult:
    """:func:`run_frames` over the frames ``frames`` (default: all) of ``seq``
    (``summary_warnings``: as there, and the warning of a height signal far from the rig's height).

    ``T_world_start`` defaults to the ground-truth pose of the first frame run (the nearest
    in time, within :data:`~floorvo.sequence.GROUNDTRUTH_MAX_DIFF_S`: :meth:`Sequence.groundtruth_at`)
    when there is one, the identity otherwise (so a trajectory is in the ground truth's world
    frame); that of the first frame the estimator starts on where it loses the first ones
    (``run_frames``' ``T_world_at``). An empty frame list is refused, and so are frames out of
    range or not increasing (a trajectory is in time order).
    """
    indices = [int(i) for i in (range(seq.frame_count) if frames is None else frames)]
    name = getattr(estimator, "name", type(estimator).__name__) if name is None else name
    if not indices:
        raise FloorbenchError(f"{name}: no frames to run on")
    outside = [i for i in indices if not 0 <= i < seq.frame_count]
    if outside:
        raise FloorbenchError(f"{name}: frame {outside[0]} is not a frame of {seq.root} (0..{seq.frame_count - 1})")
    back = next((k for k in range(1, len(indices)) if indices[k] <= indices[k - 1]), None)
    if back is not None:
        raise FloorbenchError(
            f"{name}: frame {indices[back]} follows frame {indices[back - 1]}: the frames of a run must increase"
        )
    if summary_warnings:
        _warn_height_signal_offset(seq, estimator)
    T_world_at: Callable[[Frame], np.ndarray | None] | None = None
    if T_world_start is None:
        T_world_at = _groundtruth_pose_of(seq)
        t0 = seq.timestamps_s[indices[0]]
        T_start, found = seq.groundtruth_at(np.array([t0]))
        T_world_start = T_start[0]
        if not found[0] and seq.groundtruth() is not None:
            log.warning(
                "%s: no ground-truth pose within %.3f s of frame %d (t = %.6f s); the trajectory starts at the identity",
                seq.root,
                GROUNDTRUTH_MAX_DIFF_S,
                indices[0],
                t0,
            )
    return run_frames(
        estimator,
        sequence_frames(
            seq,
            indices,
            getattr(estimator, "requires", ()),
            # A mono estimator asked to take its height from the depth image (height_from_depth).
            depth_height=bool(getattr(getattr(estimator, "config", None), "height_from_depth", False)),
        ),
        T_world_start=T_world_start,
        scale_calibration=scale_calibration,
        on_step=on_step,
        name=name,
        attitude_noise_rad=attitude_noise_rad(seq.attitude_signal_rad) if uses_attitude_signal(estimator) else 0.0,
        height_noise_mm=seq.height_noise_mm or 0.0,
        T_world_at=T_world_at,
        summary_warnings=summary_warnings,
    )


#: The share of the rig's height by which a height signal's median reading may differ from it
#: before a run says so (:func:`_warn_height_signal_offset`): issue 14's 2 % of a step.
HEIGHT_SIGNAL_OFFSET_WARN = 0.02
#: The (sequence, median reading, rig height) whose offset a run has said (:func:`_warn_height_signal_offset`).
_OFFSETS_SAID: set[tuple[str, float, float]] = set()


def _warn_height_signal_offset(seq: Sequence, estimator: Any) -> None:
    """A warning where ``seq``'s height readings (``height.csv``), which ``estimator`` converts its
    steps at (``use_height_signal``), lie by their median further from ``rig.height_mm`` than
    :data:`HEIGHT_SIGNAL_OFFSET_WARN` of it: a range sensor mounted 5 mm off (or the rig height
    stated wrong) made every step 5 % long without a word, and the picture cannot tell an
    absolute height (only its changes)."""
    cfg = getattr(estimator, "config", None)
    if not getattr(cfg, "use_height_signal", False) or seq.height_mm is None:
        return
    h = seq.height_signal_mm
    h = None if h is None else h[np.isfinite(h)]
    if h is None or not h.size:
        return
    median = float(np.median(h))
    said = (str(seq.root), median, seq.height_mm)
    if abs(median - seq.height_mm) > HEIGHT_SIGNAL_OFFSET_WARN * seq.height_mm and said not in _OFFSETS_SAID:
        _OFFSETS_SAID.add(said)  # once a sequence: a bench said it for every run of every estimator
        log.warning(
            "%s: height.csv's readings (median %.2f mm) lie %.1f %% from rig.height_mm (%.2f mm): the steps are "
            "converted at the readings; check the range sensor's mounting offset, or the rig height",
            seq.root,
            median,
            100.0 * (median - seq.height_mm) / seq.height_mm,
            seq.height_mm,
        )


def _groundtruth_pose_of(seq: Sequence) -> Callable[[Frame], np.ndarray | None] | None:
    """The ground-truth pose (4, 4) mm of a frame of ``seq`` (the nearest in time, within
    :data:`~floorvo.sequence.GROUNDTRUTH_MAX_DIFF_S`; None beyond), or None without ground truth."""
    if seq.groundtruth() is None:
        return None

    def pose(frame: Frame) -> np.ndarray | None:
        T, found = seq.groundtruth_at(np.array([frame.timestamp_s]))
        return T[0] if found[0] else None

    return pose

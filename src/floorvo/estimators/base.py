"""The estimator interface shared by every odometry method.

An estimator is built from a validated, frozen ``Config`` and the sequence's camera
model; per-sequence state lives in an explicit object returned by :meth:`start`, so one
instance can run several sequences::

    est = AkazeGuided(AkazeGuided.Config(), camera, height_mm=100.0)
    state = est.start()
    for frame in frames:
        res = est.step(state, frame)   # StepResult: motion since the previous frame, or "lost"

Motion convention: ``StepResult.T_prev_cur`` is the 4x4 pose (mm) of the current camera
in the previous camera's frame, so ``T_world_cur = T_world_prev @ T_prev_cur``. The first
frame returns status ``"init"`` and no motion; a frame that cannot be tracked returns
``"lost"`` with a reason (never an exception) and the next frame is matched against the
last good one.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol

import numpy as np

from floorvo.camera import CameraModel
from floorvo.config import Config, param
from floorvo.geometry import floor_plane_step_precision
from floorvo.metrics import WRONG_STEP_DEG, WRONG_STEP_FRACTION, WRONG_STEP_MM

__all__ = [
    "Frame",
    "StepResult",
    "Estimator",
    "frame_problem",
    "frame_height_mm",
    "HEIGHT_SIGNAL_MISREAD",
    "PICTURE_HEIGHT_READ_SHARE",
    "HEIGHT_DRIFT_STEPS",
    "HEIGHT_DRIFT_MISREAD",
    "height_signal_drift_problem",
    "takes_height_change_from_signal",
    "frame_is_blank",
    "RESTART_NOTE",
    "NO_ATTITUDE_READING",
    "frame_attitude_rad",
    "StepBoundConfig",
    "stage_timing_ms",
    "state_error",
    "NEEDS",
]

#: What an estimator (a class's ``requires``, a program's ``needs``) may need besides mono frames.
NEEDS = ("depth", "stereo")


@dataclass(frozen=True)
class StepBoundConfig(Config):
    """The keys of an estimator that checks each step's precision against issue 14's bound
    (a step reported ok within ``max_step_error_mm`` + ``max_step_error_fraction`` of the step
    and ``max_step_error_deg``; the defaults are :data:`floorvo.metrics.WRONG_STEP_MM` and its
    siblings, what scoring counts as wrong): a step whose standard errors, from the residuals
    of the estimator's own fits, leave it uncertain beyond that bound at ``precision_sigmas``
    of them is lost. Which standard errors: each estimator's docstring."""

    precision_sigmas: float = param(
        2.5,
        min=0.0,
        doc="a step left uncertain beyond the max_step_error_* bound at this many standard errors: lost "
        "(0: no precision check)",
    )
    max_step_error_mm: float = param(
        WRONG_STEP_MM,
        unit="mm",
        gt=0.0,
        doc="precision a step reported ok must have: this plus max_step_error_fraction",
    )
    max_step_error_fraction: float = param(
        WRONG_STEP_FRACTION,
        min=0.0,
        doc="precision a step reported ok must have, as a fraction of the step (issue 14's bound)",
    )
    max_step_error_deg: float = param(
        WRONG_STEP_DEG, unit="deg", gt=0.0, doc="precision of the rotation of a step reported ok"
    )

    def bound_mm(self, step_mm: float) -> float:
        """The translation error (mm) a step of ``step_mm`` reported ok may have:
        ``max_step_error_mm + max_step_error_fraction * step_mm``."""
        return self.max_step_error_mm + self.max_step_error_fraction * float(step_mm)


def plane_step_precision_problem(
    cfg: StepBoundConfig,
    T_prev_cur: np.ndarray,
    uv_prev: np.ndarray,
    uv_cur: np.ndarray,
    camera: CameraModel,
    plane_prev: tuple[np.ndarray, float],
    plane_cur: tuple[np.ndarray, float],
    sigma_prev: tuple[float, float],
    sigma_cur: tuple[float, float],
) -> str:
    """Why the 6-DoF step ``T_prev_cur`` (4, 4) mm from the pairs it kept ``uv_prev -> uv_cur``
    (K, 2) px and the two frames' floor planes ``(n, d_mm)`` with their standard errors
    ``(height mm, tilt rad)`` is too imprecise to report ('' if it is not): its standard errors
    (:func:`floorvo.geometry.floor_plane_step_precision`: the in-plane fit's and the planes'),
    ``precision_sigmas`` of them, must lie within issue 14's bound (``max_step_error_*``).
    stereo-sift's and orb-icp's check (``update = plane``)."""
    if cfg.precision_sigmas <= 0.0:
        return ""
    if len(uv_prev) < 3:
        return f"too few pairs to measure the step's precision ({len(uv_prev)})"
    sig_mm, sig_deg, sig_fit_mm = floor_plane_step_precision(
        uv_prev, uv_cur, camera, plane_prev, plane_cur, sigma_prev, sigma_cur
    )
    bound_mm = cfg.bound_mm(float(np.linalg.norm(T_prev_cur[:3, 3])))
    k = cfg.precision_sigmas
    if not (k * sig_mm <= bound_mm and k * sig_deg <= cfg.max_step_error_deg):
        return (
            f"imprecise step: {k:g} standard errors are {k * sig_mm:.3f} mm and {k * sig_deg:.2f} deg "
            f"(bound {bound_mm:.3f} mm, {cfg.max_step_error_deg:g} deg; in-plane fit of {len(uv_prev)} pairs "
            f"{sig_fit_mm:.3f} mm, planes' height {sigma_prev[0]:.3f}/{sigma_cur[0]:.3f} mm, "
            f"tilt {sigma_prev[1] * 1e3:.2f}/{sigma_cur[1] * 1e3:.2f} mrad)"
        )
    return ""


#: The note a lost step's reason ends with when the estimator restarts its track on that
#: frame (the next step is measured from it): scoring (:func:`floorvo.scoring.score_run`)
#: scores the next ok step from this frame.
RESTART_NOTE = "tracking restarts from this frame"

#: The reason of a frame that an estimator levelling its keypoints with the frames' attitude
#: (``levels_with_attitude``) cannot measure: the sequence has ``attitude.csv`` but no reading
#: for it. The next frame is measured from the last one measured.
NO_ATTITUDE_READING = "no attitude reading (attitude.csv): the frame cannot be levelled"


@dataclass(frozen=True)
class Frame:
    """One frame of a sequence. ``image``: (H, W) uint8/uint16 left (or only) camera;
    ``image_right``: the right camera of a stereo rig; ``depth_mm``: (H, W) float32, 0 = none;
    ``height_mm``: the camera's measured height above the floor at this frame (mm), from a
    range sensor (the sequence's ``height.csv``) or, when the estimator asks for it
    (``height_from_depth``), the floor plane of the depth image
    (:func:`floorvo.runner.sequence_frames`); None when the frame carries none (the
    estimators then take the rig's constant height). ``attitude_rad``: the camera's
    measured (roll, pitch) against gravity at this frame (rad, the sequence's
    ``attitude.csv``, :mod:`floorvo.sequence` defines them), (NaN, NaN) for a frame without
    a reading, None when the sequence has no attitude signal; the runner uses it
    (:func:`floorvo.runner.run_frames`), not the estimators."""

    index: int
    timestamp_s: float
    image: np.ndarray
    image_right: np.ndarray | None = None
    depth_mm: np.ndarray | None = None
    height_mm: float | None = None
    attitude_rad: tuple[float, float] | None = None


@dataclass(frozen=True)
class StepResult:
    """Outcome of one frame. ``T_prev_cur`` is None unless ``status == "ok"``.

    ``matches_px``: optional (N, 4) array of inlier matches (u_prev, v_prev, u_cur, v_cur)
    for reports; ``timing_ms``: detect, match, estimate, total.

    ``T_world_cam``: optional absolute pose (4, 4) mm of the current camera in the world
    frame, for an estimator that measures one (a map fix, :mod:`floorvo.mapping.fused`);
    None otherwise, and always None unless ``status`` is ``init`` or ``ok``. The runner
    (:mod:`floorvo.runner`) places the frame there instead of chaining ``T_prev_cur``, and
    counts it as a fix.
    """

    status: str
    T_prev_cur: np.ndarray | None = None
    reason: str = ""
    n_keypoints: int = 0
    n_matches: int = 0
    n_inliers: int = 0
    timing_ms: Mapping[str, float] = field(default_factory=dict)
    matches_px: np.ndarray | None = None
    T_world_cam: np.ndarray | None = None

    @property
    def ok(self) -> bool:
        return self.status == "ok"


def stage_timing_ms(t0_s: float, t1_s: float, t2_s: float, t3_s: float) -> dict[str, float]:
    """:attr:`StepResult.timing_ms` from four ``time.perf_counter()`` readings (s): the step's start,
    the end of detection, the end of matching and its end; each stage and the total in ms
    (a stage a step skipped is 0: pass the same reading twice)."""
    return {
        "detect": (t1_s - t0_s) * 1e3,
        "match": (t2_s - t1_s) * 1e3,
        "estimate": (t3_s - t2_s) * 1e3,
        "total": (t3_s - t0_s) * 1e3,
    }


def state_error(name: str, state: Any) -> TypeError:
    """The error of a ``step`` given a ``state`` its estimator's :meth:`Estimator.start` did not
    return (None before ``start()``, another estimator's): each built-in's ``step`` checks its
    state's type first (one ``isinstance`` a frame) and raises this, where an attribute error
    from deep inside the step was raised."""
    return TypeError(
        f"{name}: step() takes the state this estimator's start() returned, got {type(state).__name__} "
        "(call start() once per sequence and pass its state to every step)"
    )


class Estimator(Protocol):
    """What every estimator provides (see the module docstring)."""

    name: ClassVar[str]
    description: ClassVar[str]
    Config: ClassVar[type]
    requires: ClassVar[frozenset[str]]

    def __init__(
        self, config: Any, camera: CameraModel, *, height_mm: float, flatfield: np.ndarray | None = None, **rig: Any
    ): ...

    def start(self) -> Any: ...

    def step(self, state: Any, frame: Frame) -> StepResult: ...


def frame_problem(image: np.ndarray | None, camera: CameraModel, what: str = "frame", *, finite: bool = True) -> str:
    """Why ``image`` cannot be a frame of ``camera`` ('' when it can).

    A frame is a 2-D (H, W) mono image (integer or float) of the camera's size; an
    (H, W, C) array (colour, or a single channel kept as an axis), another size, an
    empty array or a float image with a NaN or infinite pixel is refused, so an estimator
    reports its step ``lost`` with this reason instead of measuring a wrong motion (a NaN
    frame raised from inside phase-corr, and orb-icp and stereo-sift took one as their first).
    ``finite=False`` lets NaN and infinite values pass (a depth image, where they mean no
    measurement, as 0 does).
    """
    if image is None:
        return f"{what} has no image"
    a = np.asarray(image)
    if a.ndim != 2:
        chans = f"{a.shape[2]} channels" if a.ndim == 3 else f"{a.ndim} dimensions"
        return f"{what} has {chans} (shape {a.shape}): a mono (H, W) image is expected"
    h, w = a.shape
    if (w, h) != (camera.width_px, camera.height_px):
        return f"{what} is {w}x{h} px: the camera is {camera.width_px}x{camera.height_px}"
    if a.dtype.kind not in "uif":
        return f"{what} has pixels of type {a.dtype}: numbers are expected"
    if finite and a.dtype.kind == "f" and not np.isfinite(a).all():
        bad = int(np.count_nonzero(~np.isfinite(a)))
        return f"{what} has {bad} pixel(s) that are NaN or infinite: finite values are expected"
    return ""


def frame_is_blank(image: np.ndarray) -> bool:
    """True when every pixel of ``image`` has one value (no texture to measure a motion from).

    The same answer as ``image.std() == 0`` without its float64 passes over the frame (0.6 ms
    of CPU on a 648x494 frame; a minimum and a maximum cost a tenth of it, and a textured
    frame's first row, where the two already differ, a third of that)."""
    a = np.asarray(image)
    if a.size == 0:
        return True
    if a.ndim >= 2 and a[0].min() != a[0].max():
        return False
    return bool(a.min() == a.max())


#: The least share of the camera height by which an estimator's picture may misread it, where a
#: measured height (``Frame.height_mm``) is held to the picture: phase-corr's blocks' image scale
#: (:meth:`floorvo.estimators.phase_corr.PhaseCorr._height_signal_problem`), homography-6dof's
#: carried floor plane (:meth:`floorvo.estimators.homography.HomographySixDof._height_signal_problem`).
#: 1 %, above the 0.6 % phase-corr's blocks misread on the suite's polished and ceramic vibrations
#: with a range sensor (BENCHMARKS.md, "phase-corr holds a height signal to the picture") and the
#: 0.24 % by which homography-6dof's carried plane strays from the range sensor on the suite's
#: full-size renders ("homography-6dof holds its floor plane to a height signal").
HEIGHT_SIGNAL_MISREAD = 0.01

#: The share of a true change of the camera height that the picture of a step reads under the rig's
#: grazing LEDs, which rise and fall with the camera: the shading their lower or higher light casts
#: moves against the image's change of scale. 0.85-0.97, the median per scene of the step's floor
#: homography on the full-size motion suite's bounces and vibrations (BENCHMARKS.md, "A height
#: change read as a share").
PICTURE_HEIGHT_READ_SHARE = 0.85

#: The steps :func:`height_signal_drift_problem` judges a height signal over: the step and the two
#: before it.
HEIGHT_DRIFT_STEPS = 3

#: The share of the camera height by which a picture may misread the height change of several steps
#: in a row, the same way (:func:`height_signal_drift_problem`): 0.2 %. A rolling shutter's stretch
#: changes as the path turns, and the AKAZE fits read it as a change of scale: on the half-size
#: S-curve with a 15 ms readout, an IMU and a range sensor, three steps in a row differed from the
#: readings by 0.18-0.34 mm at 0.02 mm standard errors, and without this share 4-10 of its right
#: steps were lost, the chain broken (0.33 -> 12 % end drift; BENCHMARKS.md, "A height signal that
#: drifts").
HEIGHT_DRIFT_MISREAD = 0.002


def height_signal_drift_problem(
    recent: deque[tuple[float, float]],
    signal_change_mm: float,
    picture_change_mm: float,
    picture_sigma_mm: float,
    bound_mm: float,
    height_mm: float,
    *,
    sigmas: float,
    read_share: float = PICTURE_HEIGHT_READ_SHARE,
    reading_sigma_mm: float = 0.0,
) -> str:
    """Why a step's height change, the difference of two readings of a height signal, is not to be
    reported ('' where it may be): the signal drifts from the picture (ours, issue 14).

    A step of an estimator that takes its height change from the signal
    (:func:`takes_height_change_from_signal`) carries that change and is converted at the reading;
    homography-6dof refines its floor plane with the readings. A picture can check one step's
    reading only to about 1 % of the height (:data:`HEIGHT_SIGNAL_MISREAD`: single frames misread
    it by up to 0.6 %), and a range sensor creeping 0.5 mm a frame passed that check on every step:
    every step after the creep began was reported ok and wrong (its height change 0.5 mm off against
    a bound of 0.13 mm), and the scale with it (11 % end drift after 30 frames).

    A drift goes one way on every frame, a misread frame does not. So the step is lost where the
    readings' change exceeds the picture's, the same way, on at least two of the last
    :data:`HEIGHT_DRIFT_STEPS` steps (this one among them: the median of their differences), by
    more than the bound ``bound_mm`` plus ``sigmas`` x the standard error (their median) plus what
    a picture may misread over several steps (:data:`HEIGHT_DRIFT_MISREAD` of the height
    ``height_mm``). Each difference is first reduced by what the picture may have read short of
    the change: it reads ``read_share`` of it (:data:`PICTURE_HEIGHT_READ_SHARE`), on a bounce the
    same way for several frames. A creep slower than about 0.4 mm a frame at 100 mm goes unseen. On
    the 12 renders with a range sensor of the motion suite (both sizes) and 20 more with dropouts,
    tilt, rolling shutter or auto exposure, no honest run loses a step it had kept
    (BENCHMARKS.md, "A height signal that drifts").

    A step whose readings lie further from the picture than one frame may misread
    (:data:`HEIGHT_SIGNAL_MISREAD` of the height plus the bound) is not recorded: the one-frame
    checks judge such a reading (a single reading of 300 mm in a run at 100 mm), and it would
    stand for a drift in the record of the steps after it.

    ``recent``: the state's record of the steps before (``maxlen`` :data:`HEIGHT_DRIFT_STEPS`),
    which this step joins; ``signal_change_mm``, ``picture_change_mm``: the camera's rise over the
    step (mm) from the two readings and from the picture's image scale; ``picture_sigma_mm``: the
    latter's standard error (mm); ``bound_mm``: issue 14's bound for the step; ``height_mm``: the
    camera height (mm); ``sigmas``: the estimator's ``precision_sigmas`` (0: no check);
    ``reading_sigma_mm``: the standard deviation of a reading, where the estimator knows it
    (``rig.height_noise_mm``; a step's change carries sqrt(2) of it).
    """
    diff_mm = signal_change_mm - picture_change_mm
    if abs(diff_mm) <= HEIGHT_SIGNAL_MISREAD * height_mm + bound_mm:
        # the picture reads read_share of a true change: the change may be up to |picture| / read_share
        beyond_mm = max(0.0, abs(diff_mm) - (1.0 / read_share - 1.0) * abs(picture_change_mm))
        sigma_mm = float(np.hypot(picture_sigma_mm, np.sqrt(2.0) * reading_sigma_mm))
        recent.append((float(np.copysign(beyond_mm, diff_mm)), sigma_mm))
    if sigmas <= 0.0 or len(recent) < (recent.maxlen or HEIGHT_DRIFT_STEPS):
        return ""
    diffs, sigmas_mm = (np.array(c) for c in zip(*recent))
    median_mm, sigma_mm = float(np.median(diffs)), float(np.median(sigmas_mm))
    misread_mm = HEIGHT_DRIFT_MISREAD * height_mm
    if abs(median_mm) > bound_mm + sigmas * sigma_mm + misread_mm:
        return (
            f"height signal drifts from the picture: over the last {len(recent)} steps its readings change the "
            f"height by a median {median_mm:+.3f} mm more than the picture shows, beyond the bound {bound_mm:.3f} + "
            f"{sigmas:g} x the standard error {sigma_mm:.3f} + what the picture may misread {misread_mm:.3f} mm "
            "(a range sensor drifting: use_height_signal = false)"
        )
    return ""


def frame_height_mm(frame: Frame, enabled: bool = True) -> float | None:
    """The camera height (mm) measured at ``frame`` (``Frame.height_mm``) when it has a usable
    one (finite, > 0) and ``enabled``; None otherwise, and the estimator takes the rig's
    constant height. The one rule by which the mono estimators use a height signal."""
    h = frame.height_mm
    if not enabled or h is None or not np.isfinite(h) or h <= 0:
        return None
    return float(h)


def takes_height_change_from_signal(estimator: Any) -> bool:
    """True when ``estimator``'s steps carry the difference of the frames' height readings as
    their height change: its ``height_change_from_signal`` (the planar mono estimators; map-fused
    with such an odometry), and its config's ``use_height_signal`` on. The runner holds such steps
    to the signal's noise (:func:`floorvo.runner.run_frames`)."""
    if not getattr(estimator, "height_change_from_signal", False):
        return False
    return bool(getattr(getattr(estimator, "config", None), "use_height_signal", True))


def frame_attitude_rad(frame: Frame, enabled: bool = True) -> tuple[float, float] | None | str:
    """The attitude (roll, pitch) rad measured at ``frame`` (``Frame.attitude_rad``) by which an
    estimator that levels its frames (``levels_with_attitude``) levels it; None when it is not
    levelled (no attitude signal, or not ``enabled``); :data:`NO_ATTITUDE_READING` when the
    sequence has a signal but no reading for this frame (the frame cannot be measured). The one
    rule by which the mono estimators use an attitude signal."""
    att = frame.attitude_rad
    if not enabled or att is None:
        return None
    if not np.isfinite(att).all():
        return NO_ATTITUDE_READING
    return float(att[0]), float(att[1])


def readout_change_problem(
    what: str,
    apart_mm: float,
    apart_deg: float,
    sigma_mm: float,
    sigma_deg: float,
    config: StepBoundConfig,
    bound_mm: float,
) -> str:
    """Why a step under a rolling shutter is not one motion over the readout ('' where it is): the
    motions fitted apart to ``what`` of the rows read first and of those read last lie
    ``apart_mm`` (their displacements at the principal point) and ``apart_deg`` (their yaws)
    apart; less ``config.precision_sigmas`` of the standard errors ``sigma_mm`` and ``sigma_deg``
    of that difference, beyond issue 14's bound (``bound_mm`` for the step,
    ``config.max_step_error_deg``), the motion changed during the readout (a turn that starts or
    ends within a frame), which undoing the readout at one motion cannot follow. The one rule of
    the AKAZE estimators' and phase-corr's ``check_readout_motion``."""
    k = config.precision_sigmas
    least_mm, least_deg = apart_mm - k * sigma_mm, apart_deg - k * sigma_deg
    if least_mm > bound_mm or least_deg > config.max_step_error_deg:
        return (
            f"motion changed during the readout: {what} of the rows read first and last move {apart_mm:.3f} mm and "
            f"{apart_deg:.2f} deg apart, less {k:g} standard errors {max(least_mm, 0.0):.3f} mm and "
            f"{max(least_deg, 0.0):.2f} deg (bound {bound_mm:.3f} mm, {config.max_step_error_deg:g} deg)"
        )
    return ""

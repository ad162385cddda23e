"""The names of the scored metrics, declared once: name, unit, direction, description.

A run's score flattens to one number per metric (:meth:`floorvo.scoring.Score.flat`):
the columns of the bench's ``results.csv``, the keys the regression gates compare, the
columns of the report and the curves of a sweep. Every such name comes from here; a
family of metrics with a parameter (the alignment of an ATE, the distance of an RPE,
the length of a KITTI segment, the stage of a timing) is a function that builds the
name, so no other module spells one with an f-string.

``lower_is_better``: True for errors, losses and times; False for tracking fraction and
frames per second; None where neither direction is better (path length, the signed
distance error, whose magnitude is what counts). ``low`` / ``high``: the range of values the
metric can take (errors, counts, lengths and times are never negative; the tracked fraction
is at most 1; a signed error has no bound), so a bound outside it (a study's criterion
``end_drift_pct = -1``, which every run would fail) is refused.
"""

from __future__ import annotations

from dataclasses import dataclass

from floorvo.metrics import ALIGNMENTS, SEGMENT_LENGTHS_MM

__all__ = [
    "MetricDef",
    "ate_rmse",
    "ate_mean",
    "ate_max",
    "ATE_SE3_ROT_RMSE",
    "RPE_FRAME_TRANS_RMSE",
    "RPE_FRAME_ROT_RMSE",
    "rpe_distance_trans_rmse",
    "END_DRIFT",
    "DISTANCE_ERROR",
    "PATH_LENGTH",
    "MEASURED",
    "TURN",
    "TURN_ERROR",
    "segment_t_err",
    "SEG_MEAN_T_ERR",
    "SEG_MEAN_R_ERR",
    "LOST_FRAMES",
    "LOSS_EVENTS",
    "TRACKED_FRACTION",
    "WRONG_OK_STEPS",
    "WRONG_OK_STEPS_FOOTPRINT",
    "TIMING_STAGES",
    "time_mean",
    "FPS",
    "all_metrics",
    "metric",
]


@dataclass(frozen=True)
class MetricDef:
    """One scored metric. ``name``: its key (results.csv column); ``unit``: mm, deg, %,
    deg/m, frames, ms, 1/s or "" (a fraction or a count); ``label``: a short table header;
    ``lower_is_better``: the direction of improvement (None: neither); ``description``;
    ``low`` / ``high``: the smallest and largest value it can take (None: unbounded)."""

    name: str
    unit: str
    label: str
    lower_is_better: bool | None
    description: str
    low: float | None = 0.0
    high: float | None = None

    def range_text(self) -> str:
        """The range in words (``>= 0``, ``from 0 to 1``, ``any number``)."""
        if self.low is not None and self.high is not None:
            return f"from {self.low:g} to {self.high:g}"
        if self.low is not None:
            return f">= {self.low:g}"
        return f"<= {self.high:g}" if self.high is not None else "any number"

    def __str__(self) -> str:
        return self.name


_ALIGN_LABEL = {"none": "no align", "origin": "origin", "se2": "SE2", "se3": "SE3"}


def _check_alignment(alignment: str) -> str:
    if alignment not in ALIGNMENTS:
        raise ValueError(f"alignment {alignment!r}: must be one of {', '.join(ALIGNMENTS)}")
    return alignment


def _ate(alignment: str, stat: str, label: str, what: str) -> MetricDef:
    a = _check_alignment(alignment)
    return MetricDef(
        f"ate_{a}_{stat}_mm", "mm", label.format(_ALIGN_LABEL[a]), True, f"ATE translation {what}, alignment {a}"
    )


def ate_rmse(alignment: str) -> MetricDef:
    """RMS absolute trajectory error (translation, mm) after ``alignment``."""
    return _ate(alignment, "rmse", "ATE mm ({})", "RMSE")


def ate_mean(alignment: str) -> MetricDef:
    """Mean absolute trajectory error (translation, mm) after ``alignment``."""
    return _ate(alignment, "mean", "ATE mean mm ({})", "mean")


def ate_max(alignment: str) -> MetricDef:
    """Largest absolute trajectory error (translation, mm) after ``alignment``."""
    return _ate(alignment, "max", "ATE max mm ({})", "maximum")


ATE_SE3_ROT_RMSE = MetricDef("ate_se3_rot_rmse_deg", "deg", "ATE deg (SE3)", True, "ATE rotation RMSE, SE(3) aligned")
RPE_FRAME_TRANS_RMSE = MetricDef(
    "rpe_frame_trans_rmse_mm", "mm", "RPE mm/frame", True, "relative pose error per frame, translation RMSE"
)
RPE_FRAME_ROT_RMSE = MetricDef(
    "rpe_frame_rot_rmse_deg", "deg", "RPE deg/frame", True, "relative pose error per frame, rotation RMSE"
)


def _per_length(name: str, unit: str, label: str, description: str, length_mm: float) -> MetricDef:
    """A metric of a path length: ``{}`` in name, label and description is the length (mm, ``%g``)."""
    g = f"{length_mm:g}"
    return MetricDef(name.format(g), unit, label.format(g), True, description.format(g))


def rpe_distance_trans_rmse(delta_mm: float) -> MetricDef:
    """Relative pose error over ``delta_mm`` of reference path, translation RMSE (mm)."""
    return _per_length(
        "rpe_{}mm_trans_rmse_mm",
        "mm",
        "RPE mm/{} mm",
        "relative pose error per {} mm of path, translation RMSE",
        delta_mm,
    )


END_DRIFT = MetricDef("end_drift_pct", "%", "end drift %", True, "end-point error in % of the path length")
DISTANCE_ERROR = MetricDef(
    "distance_error_pct",
    "%",
    "distance error %",
    None,
    "measured minus true start-to-end distance, in % of the true one (signed: its magnitude counts)",
    low=None,
)
PATH_LENGTH = MetricDef("path_length_mm", "mm", "path mm", None, "length of the reference path")
MEASURED = MetricDef("measured_mm", "mm", "measured mm", None, "estimated start-to-end distance")
TURN = MetricDef("turn_deg", "deg", "turn deg", None, "true turn over the steps reported ok (sum of |yaw change|)")
TURN_ERROR = MetricDef(
    "turn_error_pct",
    "%",
    "turn error %",
    None,
    "measured minus true turn over the steps reported ok, in % of the true turn (signed: the yaw's scale "
    "error); empty under 10 degrees of turn",
    low=None,
)


def segment_t_err(length_mm: float) -> MetricDef:
    """KITTI segment translation error over segments of ``length_mm`` (% of the length)."""
    return _per_length(
        "seg_{}mm_t_err_pct",
        "%",
        "segment {} mm err %",
        "KITTI segment translation error over {} mm, in % of the length",
        length_mm,
    )


SEG_MEAN_T_ERR = MetricDef(
    "seg_mean_t_err_pct", "%", "segment err %", True, "KITTI segment translation error, mean over lengths"
)
SEG_MEAN_R_ERR = MetricDef(
    "seg_mean_r_err_deg_per_m", "deg/m", "segment err deg/m", True, "KITTI segment rotation error, mean over lengths"
)
LOST_FRAMES = MetricDef("lost_frames", "frames", "lost", True, "frames the estimator reported lost")
LOSS_EVENTS = MetricDef("loss_events", "", "loss events", True, "runs of consecutive lost frames")
TRACKED_FRACTION = MetricDef("tracked_fraction", "", "tracked", False, "fraction of frames tracked", high=1.0)
WRONG_OK_STEPS = MetricDef(
    "wrong_ok_steps",
    "steps",
    "wrong ok",
    True,
    "steps reported ok that are off by more than 0.05 mm + 2 % of the true step or 0.3 degrees (issue 14)",
)
WRONG_OK_STEPS_FOOTPRINT = MetricDef(
    "wrong_ok_steps_footprint",
    "steps",
    "wrong ok (footprint)",
    True,
    "as wrong_ok_steps against the planar step of the camera's footprint: the bound for a planar mono estimator "
    "on a tilted or bouncing run (issue 14); none for a run whose poses an attitude signal made 6-DoF",
)

#: The stages an estimator times (timing.csv columns).
TIMING_STAGES = ("total_ms", "detect_ms", "match_ms", "estimate_ms")


def time_mean(stage: str) -> MetricDef:
    """Mean milliseconds per frame of one timing stage (``total_ms``, ``detect_ms``, ...)."""
    if stage not in TIMING_STAGES:
        raise ValueError(f"timing stage {stage!r}: must be one of {', '.join(TIMING_STAGES)}")
    label = "ms/frame" if stage == "total_ms" else f"{stage[:-3]} ms"
    return MetricDef(f"time_{stage}_mean", "ms", label, True, f"mean {stage[:-3]} time per frame")


FPS = MetricDef("fps", "1/s", "frames/s", False, "frames per second (from the mean total time)")


def all_metrics(
    rpe_deltas_mm: tuple[float, ...] = (10.0, 100.0), segment_lengths_mm: tuple[float, ...] = SEGMENT_LENGTHS_MM
) -> dict[str, MetricDef]:
    """Every metric a score can hold, by name, in the order of :meth:`floorvo.scoring.Score.flat`."""
    defs = [d for a in ALIGNMENTS for d in (ate_rmse(a), ate_mean(a), ate_max(a))]
    defs += [ATE_SE3_ROT_RMSE, RPE_FRAME_TRANS_RMSE, RPE_FRAME_ROT_RMSE]
    defs += [rpe_distance_trans_rmse(d) for d in rpe_deltas_mm]
    defs += [END_DRIFT, DISTANCE_ERROR, PATH_LENGTH, MEASURED, TURN, TURN_ERROR]
    defs += [segment_t_err(L) for L in segment_lengths_mm]
    defs += [SEG_MEAN_T_ERR, SEG_MEAN_R_ERR, LOST_FRAMES, LOSS_EVENTS, TRACKED_FRACTION, WRONG_OK_STEPS]
    defs += [WRONG_OK_STEPS_FOOTPRINT]
    defs += [time_mean(s) for s in TIMING_STAGES] + [FPS]
    return {d.name: d for d in defs}


def metric(name: str) -> MetricDef:
    """The declaration of metric ``name`` (ValueError naming the known ones if there is none)."""
    known = all_metrics()
    if name not in known:
        raise ValueError(f"metric {name!r}: unknown (known: {', '.join(known)})")
    return known[name]

"""Paper 000's experiment on a rendered strip (Nakashima et al., IEEE Access 2019, Sec. III).

The paper captured 200 floor images 1 mm apart along x and drew from them, from every
start frame, 100 runs of a uniform model (100 mm at 4 mm per frame) and 190 runs of each
sigmoid model (10 mm, gains 1.25 and 1.75) (:func:`floorsim.trajectories.paper000_subsequences`).
For each run this module feeds the strip frames of the run to an estimator, chains its
frame-to-frame motions from the first ground-truth pose and records the measured
distance per frame against the ground truth (the paper's Fig. 8) and the time of the
estimator's matching stage (``timing_ms["match"]``, for the paper's Fig. 9).

That stage is not the paper's measure alone. The paper timed "the processing time from the
start to the end of the matching process" (Sec. III-A); an estimator's ``match`` stage runs
from the end of detection to the end of the fit (:func:`floorvo.estimators.base.stage_timing_ms`),
so for the AKAZE estimators it also holds the section II-C filter, the rigid fit and the
self-checks, and for ``akaze-guided`` the second guided matching of its re-match check
(``check_rematch``, on by default; not in the paper) and any brute-force fallback. On a
synthetic 648x494 line (4 mm/frame) the matcher calls were about 70 % of akaze-guided's stage
(1.9 guided matchings a frame) and 85 % of akaze-bruteforce's, so the stage understates the
guided/brute-force ratio of matching alone.

Every estimator runs the same runs, so ``akaze-guided`` (the paper's guided matching)
and ``akaze-bruteforce`` (its brute-force baseline) are compared run for run. Outputs
under ``OUT/``: ``runs.csv`` (one row per estimator x model x start frame) and
``summary.csv``; the plots and the table go into the bench report.

In the bench this is the protocol ``paper000-strip`` (:class:`Paper000Strip`), the default
for a scene whose trajectory is the ``strip``.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
from collections.abc import Callable, Mapping
from collections.abc import Sequence as SequenceT
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from floorsim.bench.estimators import DEFAULT_RUNNER, EstimatorRunner
from floorsim.bench.protocols.base import BenchContext, BenchProtocol, ProtocolOutput, SceneRun
from floorsim.bench.report import Report, _plt
from floorsim.bench.results import write_results_csv
from floorsim.trajectories import paper000_subsequences
from floorvo.errors import FloorbenchError, SequenceError
from floorvo.estimators.base import Frame
from floorvo.runner import run_frames
from floorvo.sequence import Sequence

log = logging.getLogger(__name__)

__all__ = ["MODELS", "Paper000Result", "Paper000Strip", "run_subsequence", "run_paper000"]

#: The paper's three motion models, in its order (I, II, III).
MODELS = ("uniform", "sigmoid_g125", "sigmoid_g175")


def run_subsequence(
    seq,
    estimator: str,
    indices: SequenceT[int],
    overrides: Mapping[str, str] | None = None,
    images: dict[int, np.ndarray] | None = None,
    scale_calibration=None,
    runner: EstimatorRunner = DEFAULT_RUNNER,
) -> dict[str, Any]:
    """Run ``estimator`` over the strip frames ``indices`` (in order; repeats allowed).

    ``scale_calibration`` (:class:`floorvo.calibration.ScaleCalibration` or None) is
    divided out of every step, as ``floorvo run --scale-calibration`` does.

    Returns ``measured_mm`` (K,) (distance from the run's first pose, per frame),
    ``true_mm`` (K,), ``match_ms`` (K,) and ``lost`` (count). The run's frame k gets
    timestamp ``k / fps``; a lost step keeps the previous pose. ``runner`` builds the
    estimator (:class:`floorsim.bench.estimators.EstimatorRunner`; the camera height is the
    sequence's, refused when unknown); the loop is :func:`floorvo.runner.run_frames`.
    """
    est, _ = runner.build(seq, estimator, overrides)
    T_gt = seq.groundtruth()[1]
    frames = (
        Frame(
            index=k,
            timestamp_s=k / seq.fps,
            image=images[idx] if images is not None and idx in images else seq.image(int(idx)),
        )
        for k, idx in enumerate(indices)
    )
    run = run_frames(
        est,
        frames,
        T_world_start=T_gt[indices[0]],
        scale_calibration=scale_calibration,
        name=estimator,
        lose_repeated_pictures=False,  # a run that stands still repeats its strip frame: no motion, by design
    )
    p0 = T_gt[indices[0]][:3, 3]
    measured = np.linalg.norm(run.T_world_cam[:, :3, 3] - p0, axis=1)
    lost = int(np.count_nonzero(run.status[1:] != "ok"))
    true = [float(np.linalg.norm(T_gt[i][:3, 3] - p0)) for i in indices]
    return {"measured_mm": measured, "true_mm": np.array(true), "match_ms": run.timing_ms[:, 1], "lost": lost}


@dataclass
class Paper000Result:
    """Rows of runs.csv and summary.csv, and a report section (a callable ``f(report)``)."""

    runs: list[dict[str, Any]]
    summary: list[dict[str, Any]]
    curves: dict
    out_dir: Path
    skipped: list = dataclasses.field(default_factory=list)

    def report_section(self, rep) -> None:
        _report(self, rep)


def run_paper000(
    seq_dir: str | os.PathLike,
    estimators: SequenceT[str],
    out_dir: str | os.PathLike,
    *,
    max_runs: int | None = None,
    estimator_overrides: Mapping[str, Mapping[str, str]] | None = None,
    on_run: Callable[[int, int], None] | None = None,
    scale_calibrations: Mapping[str, Any] | None = None,
    runner: EstimatorRunner = DEFAULT_RUNNER,
) -> Paper000Result:
    """Run the paper-000 protocol on the strip sequence ``seq_dir`` (see the module doc).

    ``max_runs`` keeps at most that many runs per model, spread evenly over the start
    frames (None: 100 uniform and 190 per sigmoid model on a 200-frame strip).
    ``scale_calibrations``: ``{estimator: ScaleCalibration}`` divided out of its steps.
    ``runner``: builds the estimators (the bench's; a double in tests).
    """
    seq = Sequence.open(seq_dir)
    gt = seq.groundtruth()
    if gt is None:
        raise SequenceError(f"{seq_dir}: the paper-000 protocol needs ground truth (groundtruth.txt)")
    xs = gt[1][:, 0, 3]
    spacing = float(np.median(np.diff(xs))) if len(xs) > 1 else 1.0
    out_dir = Path(out_dir)
    images = {i: seq.image(i) for i in range(seq.frame_count)}
    runs: list[dict[str, Any]] = []
    curves: dict = {}
    plans = []
    for model in MODELS:
        subs = paper000_subsequences(model, seq.frame_count, spacing)
        if max_runs is not None and len(subs) > max_runs:
            pick = np.unique(np.linspace(0, len(subs) - 1, max_runs).round().astype(int))
            subs = [subs[i] for i in pick]
        if subs:
            plans.append((model, subs))
        else:
            log.warning("paper 000: the strip of %d frames is too short for any %s run", seq.frame_count, model)
    total = sum(len(s) for _, s in plans) * len(estimators)
    done = 0
    skipped: list[str] = []
    for name in estimators:
        over = dict((estimator_overrides or {}).get(name, {}))
        try:
            run_subsequence(seq, name, [0, 1], over, images, runner=runner)
        except FloorbenchError as exc:
            skipped.append(f"{name}: {exc}")
            log.warning("paper 000: %s skipped: %s", name, exc)
            continue
        for model, subs in plans:
            measured, true, times = [], [], []
            for sub in subs:
                r = run_subsequence(
                    seq, name, [int(i) for i in sub], over, images, (scale_calibrations or {}).get(name), runner
                )
                measured.append(r["measured_mm"])
                true.append(r["true_mm"])
                times.append(np.nanmean(r["match_ms"][1:]) if len(r["match_ms"]) > 1 else float("nan"))
                runs.append(
                    {
                        "scene": seq.root.name,
                        "estimator": name,
                        "model": model,
                        "start_frame": int(sub[0]),
                        "frames": len(sub),
                        "true_mm": r["true_mm"][-1],
                        "measured_mm": r["measured_mm"][-1],
                        "error_mm": r["measured_mm"][-1] - r["true_mm"][-1],
                        "match_ms_mean": times[-1],
                        "lost": r["lost"],
                    }
                )
                done += 1
                if on_run:
                    on_run(done, total)
            curves[(name, model)] = {
                "measured": np.array(measured),
                "true": np.array(true),
                "match_ms": np.array(times),
            }
    summary = []
    for (label, model), c in curves.items():
        err = c["measured"][:, -1] - c["true"][:, -1]
        true_end = float(np.mean(c["true"][:, -1]))
        summary.append(
            {
                "estimator": label,
                "model": model,
                "runs": len(err),
                "true_mm": true_end,
                "measured_mm_mean": float(np.mean(c["measured"][:, -1])),
                "measured_mm_std": float(np.std(c["measured"][:, -1])),
                "error_mm_mean": float(np.mean(err)),
                "error_mm_rmse": float(np.sqrt(np.mean(err**2))),
                "error_pct": 100.0 * float(np.mean(np.abs(err))) / true_end if true_end > 0 else float("nan"),
                "match_ms_mean": float(np.nanmean(c["match_ms"])) if np.isfinite(c["match_ms"]).any() else float("nan"),
                "match_ms_std": float(np.nanstd(c["match_ms"])) if np.isfinite(c["match_ms"]).any() else float("nan"),
            }
        )
    write_results_csv(out_dir / "runs.csv", runs, ())
    write_results_csv(out_dir / "summary.csv", summary, ())
    return Paper000Result(runs, summary, curves, out_dir, skipped)


class Paper000Strip(BenchProtocol):
    """``paper000-strip``: :func:`run_paper000` on repetition 0's strip, into ``DIR/paper000/SCENE``.

    Option ``max_runs`` (``floorsim bench --paper000-runs N``): at most N runs per model.
    """

    name: ClassVar[str] = "paper000-strip"
    description: ClassVar[str] = (
        "paper 000: 100 uniform and 2 x 190 sigmoid runs from every start frame of a 1 mm strip (Figs. 8 and 9)"
    )
    trajectory_types: ClassVar[tuple[str, ...]] = ("strip",)
    default_for: ClassVar[tuple[str, ...]] = ("strip",)

    def run_scene(self, ctx: BenchContext, scene: SceneRun) -> ProtocolOutput:
        res = run_paper000(
            scene.seq_dir,
            scene.estimators,
            ctx.out_dir / "paper000" / scene.label,
            max_runs=ctx.options_for(self.name).get("max_runs"),
            estimator_overrides=ctx.estimator_overrides,
            scale_calibrations=ctx.scale_calibrations,
            runner=ctx.runner,
        )
        return ProtocolOutput(sections=[res.report_section])


def _report(res: Paper000Result, rep: Report) -> None:
    plt = _plt()
    rep.heading("Paper 000 reproduction: the 200-frame strip")
    rep.text(
        "Nakashima et al. (IEEE Access 2019) ran 100 uniform runs (100 mm at 4 mm/frame) and 190 runs of each "
        "sigmoid model (10 mm, gains 1.25 and 1.75) from every start frame of a strip of 200 frames 1 mm apart. "
        "Fig. 8 there: measured distance against ground truth; Fig. 9: matching time of guided against "
        "brute-force matching. The same protocol on the rendered strip (match ms: each estimator's matching "
        "stage, which also holds its filter, fit and self-checks, akaze-guided's re-match check included):"
    )
    rep.table(
        res.summary,
        [
            ("estimator", "estimator"),
            ("model", "model"),
            ("runs", "runs"),
            ("true_mm", "true mm"),
            ("measured_mm_mean", "measured mm"),
            ("measured_mm_std", "std mm"),
            ("error_mm_rmse", "error rmse mm"),
            ("error_pct", "|error| %"),
            ("match_ms_mean", "match ms"),
            ("match_ms_std", "match std ms"),
        ],
    )
    for line in res.skipped:
        rep.text(f"skipped {line}")
    labels = sorted({k[0] for k in res.curves})
    models = [m for m in MODELS if any((l, m) in res.curves for l in labels)]
    if not models:
        return
    fig, axes = plt.subplots(1, len(models), figsize=(4.5 * len(models), 3.6))
    for ax, model in zip(np.atleast_1d(axes), models):
        first, n_runs = True, 0
        for label in labels:
            c = res.curves.get((label, model))
            if c is None:
                continue
            f = np.arange(c["measured"].shape[1])
            if first:
                ax.plot(f, c["true"].mean(0), "k-", lw=2.5, alpha=0.5, label="ground truth")
                first = False
            n_runs = c["measured"].shape[0]
            m, s = c["measured"].mean(0), c["measured"].std(0)
            ax.plot(f, m, ".-", ms=3, lw=1, label=label)
            ax.fill_between(f, m - s, m + s, alpha=0.2)
        ax.set_title(f"{model} ({n_runs} runs)", fontsize=10)
        ax.set_xlabel("frame of the run")
        ax.set_ylabel("distance [mm]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    rep.figure(fig, "paper 000 Fig. 8: measured distance (mean and +-1 std over the runs) against ground truth")
    timed = [r for r in res.summary if isinstance(r["match_ms_mean"], float) and math.isfinite(r["match_ms_mean"])]
    if timed:
        fig, ax = plt.subplots(figsize=(7, 3.6))
        width = 0.8 / max(1, len(labels))
        for j, label in enumerate(labels):
            vals = [next((r for r in timed if r["estimator"] == label and r["model"] == m), None) for m in models]
            x = np.arange(len(models)) + j * width
            ax.bar(
                x,
                [v["match_ms_mean"] if v else np.nan for v in vals],
                width,
                yerr=[v["match_ms_std"] if v else 0 for v in vals],
                capsize=3,
                label=label,
            )
        ax.set_xticks(np.arange(len(models)) + width * (len(labels) - 1) / 2, models)
        ax.set_ylabel("matching time per frame [ms]")
        ax.grid(alpha=0.3, axis="y")
        ax.legend(fontsize=7)
        rep.figure(fig, "paper 000 Fig. 9: mean matching time per frame (+-1 std over the runs)")
    else:
        rep.text("No estimator reported a matching time (timing_ms['match']); Fig. 9 is skipped.")

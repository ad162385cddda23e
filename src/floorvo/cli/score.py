"""``floorvo score RUN --gt SEQ``: score an estimator run against ground truth.

Prints a table and writes ``RUN/score.json`` (see :func:`floorvo.scoring.score_run`).
"""

from __future__ import annotations

import argparse
import contextlib
import math
from pathlib import Path

from floorvo.cli.common import add_output_argument, checked_output_beside_runs
from floorvo.locking import lock_folder
from floorvo.scoring import Score, score_run, write_score

__all__ = ["add_parser", "run", "format_score_table"]


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "score",
        help="score a run (trajectory.txt, timing.csv) against a sequence's ground truth",
        description="Score RUN/trajectory.txt against SEQ/groundtruth.txt: ATE (no/origin/SE(2)/SE(3) alignment), "
        "RPE per frame and per distance, drift in % of distance (end point and KITTI segments), tracking loss, "
        "timing. Prints a table and writes RUN/score.json.",
    )
    p.add_argument("run_dir", metavar="RUN", type=Path, help="run folder written by `floorvo run`")
    p.add_argument("--gt", metavar="SEQ", type=Path, required=True, help="sequence folder (or a TUM ground-truth file)")
    p.add_argument(
        "--max-diff", type=float, default=0.01, help="timestamp association tolerance in seconds (default 0.01)"
    )
    add_output_argument(
        p, "where to write score.json (default RUN/score.json)", type=Path, default=None, required=False
    )
    p.set_defaults(func=run)


def _fmt(v: float) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return f"{v:.4g}"


def _tracking_lines(score: Score) -> list[str]:
    """Tracking and timing lines (every score has them, with or without ground truth)."""
    lines: list[str] = []
    tr = score.tracking
    lines.append(
        f"tracking: {tr['lost_frames']} lost frame(s) in {tr['loss_events']} event(s), tracked {100 * tr['tracked_fraction']:.1f} %"
    )
    if "total_ms" in score.timing:
        t = score.timing["total_ms"]
        lines.append(
            f"timing: total {_fmt(t['mean'])} ms mean, {_fmt(t['p95'])} ms p95 ({_fmt(score.timing.get('fps', float('nan')))} frames/s)"
        )
    return lines


def format_score_table(score: Score) -> str:
    """A plain-text table of the main metrics of ``score``."""
    if score.ground_truth != "ok":
        lines = [f"estimator: {score.estimator or '?'}   poses: {score.n_est}; {score.ground_truth}"]
        lines.append(f"accuracy (ATE, RPE, drift, segments): {score.ground_truth}")
        lines += _tracking_lines(score)
        lines += [f"warning: {w}" for w in score.warnings]
        return "\n".join(lines)
    lines = [f"estimator: {score.estimator or '?'}   poses: {score.n_matched} matched of {score.n_ref} ground truth"]
    lines.append(f"{'metric':<34} {'rmse':>10} {'mean':>10} {'max':>10}")
    for name, a in score.ate.items():
        t = a["trans_mm"]
        lines.append(
            f"{'ATE [mm], alignment ' + name:<34} {_fmt(t['rmse']):>10} {_fmt(t['mean']):>10} {_fmt(t['max']):>10}"
        )
    for label, r in [("RPE per frame", score.rpe_frame)] + [
        (f"RPE per {d['delta']:g} mm", d) for d in score.rpe_distance
    ]:
        t, q = r["trans_mm"], r["rot_deg"]
        lines.append(f"{label + ' [mm]':<34} {_fmt(t['rmse']):>10} {_fmt(t['mean']):>10} {_fmt(t['max']):>10}")
        lines.append(f"{label + ' [deg]':<34} {_fmt(q['rmse']):>10} {_fmt(q['mean']):>10} {_fmt(q['max']):>10}")
    d = score.drift
    if "end_drift_pct" in d:
        lines.append(
            f"end_drift_pct {_fmt(d['end_drift_pct'])} %  (end error {_fmt(d['end_error_mm'])} mm over "
            f"{_fmt(d['path_length_mm'])} mm; measured {_fmt(d['measured_mm'])} mm of {_fmt(d['true_mm'])} mm)"
        )
    if "turn_error_pct" in d:
        lines.append(
            f"turn_error_pct {_fmt(d['turn_error_pct'])} %  (measured {_fmt(d['measured_turn_deg'])} deg of "
            f"{_fmt(d['turn_deg'])} deg turned over the steps reported ok)"
        )
    for s in score.segments:
        lines.append(
            f"segment {s['length_mm']:>6g} mm: t_err {_fmt(s['t_err_pct'])} %  r_err {_fmt(s['r_err_deg_per_m'])} deg/m  (n={s['count']})"
        )
    lines += _tracking_lines(score)
    lines += [f"warning: {w}" for w in score.warnings]
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    if args.output is not None:
        checked_output_beside_runs(args.output, [args.run_dir], [args.gt])
    out = args.output or (args.run_dir / "score.json")
    # score.json written into the run folder: its writer locks it (a run still being written there is refused)
    locked = args.output is None and Path(args.run_dir).is_dir()
    with lock_folder(args.run_dir, "run folder") if locked else contextlib.nullcontext():
        score = score_run(args.run_dir, args.gt, max_diff_s=args.max_diff)
        write_score(score, out)
    print(format_score_table(score))
    print(f"score written to {out}")
    return 0

"""``floorvo calibrate RUN [RUN ...] --gt SEQ [--gt SEQ ...] -o FILE``: fit a rig's per-axis odometry
scale (and its yaw's) on runs with ground truth."""

from __future__ import annotations

from pathlib import Path

from floorvo.cli.common import add_output_argument, checked_output_beside_runs

__all__ = ["add_parser", "run"]


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "calibrate",
        help="fit the camera-frame x, y scale (and the yaw's) of runs against ground truth "
        "(use it with 'floorvo run --scale-calibration')",
        description="Least-squares scale of the estimated step translations over the true ones, per camera axis, "
        "and of the estimated yaw changes over the true ones (floorvo.calibration). Fit it on runs of a rig over a "
        "floor (a straight run for x and y, a turning one such as a spin in place for the yaw; several runs are "
        "fitted together), apply it to later runs of that rig. On a grained floor (wood) each scale may depend on "
        "the grain's angle to the rig's lights: where the runs show it (their frames' texture has a direction that "
        "turns, and the terms are significant) the scales are fitted as functions of each step's texture "
        "orientation; straight runs at three headings (0, 60, 120 degrees over the floor) and a spin observe them.",
    )
    p.add_argument("run_dirs", metavar="RUN", type=Path, nargs="+", help="run folder(s) written by `floorvo run`")
    p.add_argument(
        "--gt",
        metavar="SEQ",
        type=Path,
        action="append",
        required=True,
        help="sequence folder (or a TUM ground-truth file) of each RUN, in their order (one for all: the same)",
    )
    add_output_argument(p, "calibration file to write (JSON)", metavar="FILE", type=Path)
    p.add_argument(
        "--min-travel-mm", type=float, default=10.0, help="an axis with less travel keeps scale 1 (default 10)"
    )
    p.add_argument(
        "--min-turn-deg", type=float, default=10.0, help="runs turning less keep the yaw's scale 1 (default 10)"
    )
    p.add_argument(
        "--no-orientation",
        action="store_true",
        help="constant scales only: no terms in the floor texture's orientation, and no frames read",
    )
    p.add_argument(
        "--max-diff", type=float, default=0.01, help="timestamp association tolerance in seconds (default 0.01)"
    )
    p.set_defaults(func=run)


def run(args) -> int:
    from floorvo.calibration import calibrate_runs, save_scale_calibration
    from floorvo.errors import ConfigError

    gts = args.gt * len(args.run_dirs) if len(args.gt) == 1 else args.gt
    if len(gts) != len(args.run_dirs):
        raise ConfigError(f"--gt: given {len(args.gt)} times for {len(args.run_dirs)} runs: give one, or one per run")
    checked_output_beside_runs(args.output, args.run_dirs, gts)
    cal = calibrate_runs(
        list(zip(args.run_dirs, gts)), args.max_diff, args.min_travel_mm, args.min_turn_deg, not args.no_orientation
    )
    save_scale_calibration(cal, args.output)
    parts = []
    for axis in "xy":
        travel = getattr(cal, f"travel_{axis}_mm")
        if getattr(cal, f"observed_{axis}"):
            parts.append(f"{axis} {getattr(cal, f'scale_{axis}'):.5f}{_terms(cal, axis)} ({travel:.0f} mm of travel)")
        else:
            parts.append(f"{axis} not observed ({travel:.1f} mm of travel), kept at 1")
    if cal.observed_yaw:
        parts.append(f"yaw {cal.scale_yaw:.5f}{_terms(cal, 'yaw')} ({cal.turn_deg:.0f} deg of turn)")
    else:
        parts.append(f"yaw not observed ({cal.turn_deg:.1f} deg of turn), kept at 1")
    if cal.uses_orientation:
        parts.append(f"theta: the step's texture orientation (coherence {cal.orientation_coherence:.2f})")
    print(f"scale {'; '.join(parts)}; {cal.steps} steps -> {args.output}")
    return 0


def _terms(cal, axis: str) -> str:
    """`` + a cos 2theta + b sin 2theta`` of an axis's texture-orientation terms ('' without)."""
    a, b = getattr(cal, f"{axis}_cos2"), getattr(cal, f"{axis}_sin2")
    return f" {a:+.5f} cos 2theta {b:+.5f} sin 2theta" if a or b else ""

"""``floorvo calibrate RUN --gt SEQ -o FILE``: fit a rig's per-axis odometry scale on a run with ground truth."""

from __future__ import annotations

from pathlib import Path

from floorvo.cli.common import add_output_argument

__all__ = ["add_parser", "run"]


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "calibrate",
        help="fit the camera-frame x, y scale of a run against ground truth (use it with 'floorvo run --scale-calibration')",
        description="Least-squares scale of the estimated step translations over the true ones, per camera axis "
        "(floorvo.calibration). Fit it on one run of a rig over a floor, apply it to later runs of that rig.",
    )
    p.add_argument("run_dir", metavar="RUN", type=Path, help="run folder written by `floorvo run`")
    p.add_argument("--gt", metavar="SEQ", type=Path, required=True, help="sequence folder (or a TUM ground-truth file)")
    add_output_argument(p, "calibration file to write (JSON)", metavar="FILE", type=Path)
    p.add_argument(
        "--min-travel-mm", type=float, default=10.0, help="an axis with less travel keeps scale 1 (default 10)"
    )
    p.add_argument(
        "--max-diff", type=float, default=0.01, help="timestamp association tolerance in seconds (default 0.01)"
    )
    p.set_defaults(func=run)


def run(args) -> int:
    from floorvo.calibration import calibrate_run, save_scale_calibration

    cal = calibrate_run(args.run_dir, args.gt, args.max_diff, args.min_travel_mm)
    save_scale_calibration(cal, args.output)
    parts = []
    for axis in "xy":
        travel = getattr(cal, f"travel_{axis}_mm")
        if getattr(cal, f"observed_{axis}"):
            parts.append(f"{axis} {getattr(cal, f'scale_{axis}'):.5f} ({travel:.0f} mm of travel)")
        else:
            parts.append(f"{axis} not observed ({travel:.1f} mm of travel), kept at 1")
    print(f"scale {'; '.join(parts)}; {cal.steps} steps -> {args.output}")
    return 0

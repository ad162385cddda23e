"""``floorvo run SEQ --estimator NAME -o RUN``: run one estimator over a sequence."""

from __future__ import annotations

from floorvo.cli.common import add_output_argument, parse_set_args, progress_callback


def add_parser(sub) -> None:
    p = sub.add_parser("run", help="run an estimator over a sequence folder")
    p.add_argument("sequence", help="sequence folder (sequence.json, cam0/...)")
    p.add_argument("--estimator", "-e", required=True, help="estimator name (floorvo list)")
    add_output_argument(p, "run folder for trajectory.txt, timing.csv, result.json")
    p.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        help="estimator config override, e.g. grid=3 (floorvo list --config NAME shows the keys)",
    )
    p.add_argument(
        "--scale-calibration",
        metavar="FILE",
        default=None,
        help="divide each step's camera-frame x, y translation by the scales in FILE (written by 'floorvo calibrate')",
    )
    p.set_defaults(func=run)


def run(args) -> int:
    from floorvo.calibration import load_scale_calibration
    from floorvo.run import run_estimator

    cal = None if args.scale_calibration is None else load_scale_calibration(args.scale_calibration)
    with progress_callback(args.estimator) as cb:
        res = run_estimator(
            args.sequence, args.estimator, args.output, parse_set_args(args.set), on_frame=cb, scale_calibration=cal
        )
    print(
        f"{res.estimator}: {res.frames} frames, {res.ok} tracked, {res.lost} lost, "
        f"{res.median_total_ms:.1f} ms/frame median -> {res.run_dir}"
    )
    return 0

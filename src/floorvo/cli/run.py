"""``floorvo run SEQ --estimator NAME -o RUN``: run one estimator over a sequence.

``--estimator`` takes a registered name (``floorvo list``: built-ins and installed plugins) or
a ``package.module:Class`` reference; ``--external CMD`` or ``--estimator-file FILE`` run a
program instead (:mod:`floorvo.external`). Exit code 1 when no frame after the first was tracked.
"""

from __future__ import annotations

import sys

from floorvo.cli.common import add_output_argument, parse_set_args, progress_callback


def add_parser(sub) -> None:
    p = sub.add_parser("run", help="run an estimator over a sequence folder")
    p.add_argument("sequence", help="sequence folder (sequence.json, cam0/...)")
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument(
        "--estimator", "-e", help="estimator name (floorvo list), or a class as package.module:Class (not installed)"
    )
    which.add_argument(
        "--external",
        metavar="CMD",
        help="a program as the estimator: CMD (split like a shell does) may use {sequence}, {output}, {camera}, "
        "{images}, {height_mm}, {fps}, {frames} and writes {output}/trajectory.txt (TUM), optionally timing.csv",
    )
    which.add_argument(
        "--estimator-file", metavar="FILE", help="a program as the estimator, from a TOML file (name, command, ...)"
    )
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
    p.add_argument(
        "--initial-pose",
        metavar="POSE",
        default=None,
        help="where the run starts: x_mm,y_mm,yaw_rad or a TUM line 't tx ty tz qx qy qz qw' (default: the first "
        "ground-truth pose, else the identity)",
    )
    p.set_defaults(func=run)


def _run_external(args, start) -> int:
    from floorvo.errors import ConfigError
    from floorvo.external import load_estimator_file, parse_external, run_external

    if args.set or args.scale_calibration:
        raise ConfigError("--set and --scale-calibration apply to Python estimators, not to a program")
    spec = parse_external(args.external) if args.external is not None else load_estimator_file(args.estimator_file)
    res = run_external(args.sequence, spec, args.output, T_world_start=start)
    peak = "not measured" if res.peak_rss_mb != res.peak_rss_mb else f"{res.peak_rss_mb:.0f} MiB"  # NaN: no /proc
    print(
        f"{res.estimator}: {res.frames} frames, {res.placed} placed, {res.wall_ms_per_frame:.1f} ms/frame (wall), "
        f"peak {peak} -> {res.run_dir}"
    )
    if res.placed < 2:
        print(f"floorvo: error: {res.estimator} placed no frame after the first (see {res.run_dir})", file=sys.stderr)
        return 1
    return 0


def run(args) -> int:
    from floorvo.calibration import load_scale_calibration
    from floorvo.run import InitialPose, run_estimator
    from floorvo.sequence import Sequence

    start = None
    if args.initial_pose is not None:
        pose = InitialPose.parse(args.initial_pose)
        start = pose.T_world_cam(Sequence.open(args.sequence).height_mm)
    if args.estimator is None:
        return _run_external(args, start)
    cal = None if args.scale_calibration is None else load_scale_calibration(args.scale_calibration, args.estimator)
    with progress_callback(args.estimator) as cb:
        res = run_estimator(
            args.sequence,
            args.estimator,
            args.output,
            parse_set_args(args.set),
            on_frame=cb,
            scale_calibration=cal,
            T_world_start=start,
        )
    print(
        f"{res.estimator}: {res.frames} frames, {res.ok} tracked, {res.lost} lost, "
        f"{res.median_total_ms:.1f} ms/frame median -> {res.run_dir}"
    )
    if res.frames > 1 and res.ok == 0:
        print(
            f"floorvo: error: {res.estimator} tracked no frame after the first (see {res.run_dir}/timing.csv)",
            file=sys.stderr,
        )
        return 1
    return 0

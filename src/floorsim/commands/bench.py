"""``floorsim bench [SCENES...] [--suite NAME] [--estimators A,B] [--external NAME=CMD] -o DIR``: render, run,
score, report, gate.

SCENES are scene files and sequence folders (recordings: run as they are, not rendered);
``--suite`` adds the scene files a suite lists (:mod:`floorsim.bench.suites`: a shipped
suite's name such as ``motion``, or a suite file).

Thin call to :func:`floorsim.bench.run_bench`; prints the score table and the report's
path. With ``--baseline FILE`` it prints what got worse and how many metrics it checked of how
many expected, and exits 1 if anything got worse or a scene/estimator has no baseline
entry (unless ``--allow-new``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from floorvo.cli.common import (
    add_external_arguments,
    add_output_argument,
    externals_from_args,
    parse_name_values,
    parse_set_args,
    progress_callback,
)
from floorvo.errors import ConfigError

__all__ = ["add_parser", "run", "parse_estimator_sets"]


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "bench",
        help="render scenes, run estimators, score them, write results.csv and a report; gate regressions",
        description="Render each scene (reusing a sequence already rendered with the same resolved scene, seed and "
        "settings; a sequence folder is used as it is), run each estimator (built-ins, installed plugins, "
        "package.module:Class references, external programs), score it, and write DIR/results.csv (one row per "
        "scene x estimator x repetition), DIR/report.html (self-contained) and DIR/report.md. A run that fails is "
        "a failed row; with --baseline, exit 1 when a metric got worse than the baseline's tolerance allows, or a "
        "scene/estimator has no baseline entry (unless --allow-new).",
    )
    p.add_argument(
        "scenes",
        metavar="SCENE",
        nargs="*",
        type=Path,
        help="scene TOML files and sequence folders (anything with a sequence.json, e.g. from floorvo import)",
    )
    p.add_argument(
        "--suite",
        action="append",
        metavar="NAME",
        help="run every scene of a suite as well: a shipped suite (motion: scenes/motion/suite.toml) or a suite "
        "file listing scene files (repeatable)",
    )
    add_output_argument(p, "output folder DIR", type=Path)
    p.add_argument(
        "--estimators",
        default=None,
        help="comma-separated estimator names or package.module:Class references (default: every registered "
        "estimator the sequence supports); the --external programs run in either case",
    )
    add_external_arguments(p)
    p.add_argument(
        "--initial-pose",
        metavar="POSE",
        default=None,
        help="where runs on a sequence without ground truth start: x_mm,y_mm,yaw_rad or a TUM line "
        "(default: the identity)",
    )
    p.add_argument("--repeat", type=int, default=1, help="repetitions per scene, seeds scene seed + k (default 1)")
    p.add_argument(
        "--set",
        dest="scene_set",
        action="append",
        metavar="KEY=VALUE",
        help="override a scene key of the scene files, e.g. lights.height_mm=5 (sequence folders run as recorded)",
    )
    p.add_argument("--est-set", action="append", metavar="NAME.KEY=VALUE", help="override an estimator config key")
    p.add_argument("--frames", type=int, default=None, help="render only the first N frames")
    p.add_argument("--scale", type=float, default=None, help="render at this fraction of the camera resolution")
    p.add_argument("--spp", type=int, default=None, help="samples per pixel")
    p.add_argument(
        "--cache", type=Path, default=None, help="folder of rendered sequences to reuse (default DIR/sequences)"
    )
    p.add_argument(
        "--baseline", type=Path, default=None, help="compare with this baseline; exit 1 if anything got worse"
    )
    p.add_argument(
        "--allow-new",
        action="store_true",
        help="a scene/estimator without a baseline entry does not fail the gate (default: it does)",
    )
    p.add_argument("--save-baseline", type=Path, default=None, metavar="FILE", help="write the results as a baseline")
    p.add_argument(
        "--paper000-runs",
        type=int,
        default=None,
        metavar="N",
        help="at most N runs per model of the paper000-strip protocol (default: all)",
    )
    p.add_argument("--no-report", action="store_true", help="skip the HTML/Markdown report")
    p.add_argument(
        "--scale-calibration",
        action="append",
        metavar="ESTIMATOR=FILE",
        help="divide the rig scale fitted by `floorvo calibrate` out of that estimator's steps (repeatable)",
    )
    p.set_defaults(func=run)


def parse_estimator_sets(items: list[str] | None) -> dict[str, dict[str, str]]:
    """``NAME.KEY=VALUE`` items into ``{NAME: {KEY: VALUE}}``; NAME may be a ``package.module:Class``
    reference, whose dots before the colon belong to it (``pkg.vo:MyVo.grid=3``)."""
    out: dict[str, dict[str, str]] = {}
    for key, value in parse_set_args(items, "--est-set").items():
        colon = key.find(":")
        dot = key.find(".", colon + 1 if colon >= 0 else 0)
        if dot <= 0:
            raise ConfigError(
                f"--est-set {key}={value}: expected NAME.KEY=VALUE (e.g. akaze-guided.akaze_threshold=0.001, map-fused.map=MAP)"
            )
        name, k = key[:dot], key[dot + 1 :]
        out.setdefault(name, {})[k] = value
    return out


def parse_scale_calibrations(items: list[str] | None) -> dict[str, str]:
    """``ESTIMATOR=FILE`` items into ``{ESTIMATOR: FILE}``."""
    return parse_name_values(items, "--scale-calibration", "ESTIMATOR=FILE (e.g. phase-corr=scale.json)")


def run(args: argparse.Namespace) -> int:
    # Imported when the command runs, as in every command module: `floorsim --help` stays quick.
    from floorsim.bench import run_bench
    from floorsim.bench.report import format_table
    from floorsim.bench.suites import suite_scenes
    from floorvo.run import InitialPose

    scenes = list(args.scenes)
    for suite in args.suite or []:
        scenes += suite_scenes(suite)
    if not scenes:
        raise ConfigError("bench: give scene files, sequence folders or --suite NAME")

    # --estimators ",," (or "") names no estimator: refused by run_bench, not taken for "every estimator"
    estimators = None if args.estimators is None else [e.strip() for e in args.estimators.split(",") if e.strip()]
    with progress_callback("render", "frame") as bar:
        res = run_bench(
            scenes,
            estimators,
            args.output,
            repetitions=args.repeat,
            scene_overrides=parse_set_args(args.scene_set),
            estimator_overrides=parse_estimator_sets(args.est_set),
            frames=args.frames,
            scale=args.scale,
            spp=args.spp,
            cache_dir=args.cache,
            baseline=args.baseline,
            save_baseline_to=args.save_baseline,
            allow_new=args.allow_new,
            report=not args.no_report,
            paper000_runs=args.paper000_runs,
            on_frame=lambda scene, done, n: bar(done, n, desc=f"render {scene}"),
            scale_calibrations=parse_scale_calibrations(args.scale_calibration),
            externals=externals_from_args(args),
            initial_pose=None if args.initial_pose is None else InitialPose.parse(args.initial_pose),
            **args.collaborators,
        )
    for note in res.notes:
        print(note)
    print(format_table(res.rows))
    print(f"results: {res.results_csv}")
    if res.report_html is not None:
        print(f"report: {res.report_html} (summary: {res.report_md})")
    if res.baseline_saved is not None:
        print(f"baseline written to {res.baseline_saved}")
    if res.gate is not None:
        print(res.gate.summary())
        if not res.gate.ok:
            return 1
    return 0

"""``floorsim sweep STUDY.toml -o DIR``: run a robustness study: a grid, a breaking-point search (locally or on Dask).

Thin call to :func:`floorsim.bench.sweep.run_sweep`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from floorvo.cli.common import add_external_arguments, add_output_argument, externals_from_args, progress_callback

__all__ = ["add_parser", "run"]


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "sweep",
        help="run a study: a grid of scene variations or a breaking-point search, x estimators; report",
        description="Run a study (sweep) file: every combination of its [vary] values, or a bisection of its "
        "[search] key for the value where each estimator starts to fail its [criterion]; each scene variation "
        "is rendered once and scored with every estimator. Rows stream into DIR/results.csv as jobs finish; "
        "running the same command again skips the jobs already there. A search prints, per estimator, the "
        "breaking point with its bracket and the renders it took (DIR/breaking_points.csv). Curves, envelopes "
        "and the search go to DIR/sweep.html and DIR/sweep.md; DIR/study.toml and DIR/study.json record the study.",
    )
    p.add_argument(
        "sweep", metavar="STUDY", type=Path, help="study or sweep TOML file (see scenes/studies/, scenes/sweeps/)"
    )
    add_output_argument(p, "output folder DIR", type=Path)
    where = p.add_mutually_exclusive_group()
    where.add_argument(
        "--scheduler", metavar="tcp://HOST:PORT", default=None, help="send the jobs to this Dask scheduler"
    )
    where.add_argument(
        "--workers", type=int, default=None, metavar="N", help="start a local Dask cluster of N workers (<= 4 per CPU)"
    )
    where.add_argument(
        "--jobs",
        type=int,
        default=None,  # not 1: argparse takes an explicit value equal to the default as not given (--jobs 1 --workers 1)
        metavar="N",
        help="local worker processes when not on Dask (default 1, <= 4 per CPU)",
    )
    p.add_argument(
        "--cache", type=Path, default=None, help="folder of rendered sequences to reuse (default DIR/sequences)"
    )
    add_external_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from floorsim.bench.sweep import run_sweep  # when the command runs: keeps `floorsim --help` quick

    with progress_callback("sweep", "job") as on_job:
        res = run_sweep(
            args.sweep,
            args.output,
            scheduler=args.scheduler,
            workers=args.workers,
            jobs=1 if args.jobs is None else args.jobs,
            cache_dir=args.cache,
            on_job=on_job,
            externals=externals_from_args(args),
            **args.collaborators,
        )
    print(f"sweep: {res.ran} job(s) run, {res.skipped} already done; {len(res.rows)} row(s) in {res.results_csv}")
    for line in res.summary_lines():
        print(line)
    if res.breaking_points_csv is not None:
        print(f"breaking points: {res.breaking_points_csv}")
    for e in res.errors:
        print(f"job failed: {e}")
    if res.report_html is not None:
        print(f"report: {res.report_html} (summary: {res.report_md})")
    return 1 if res.errors or (res.search is not None and res.search.errors) else 0

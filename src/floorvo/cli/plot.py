"""``floorvo plot RUN [RUN...] --gt SEQ -o PNG``: runs against ground truth in one PNG."""

from __future__ import annotations

from pathlib import Path

from floorvo.cli.common import add_output_argument, checked_output_beside_runs


def add_parser(sub) -> None:
    p = sub.add_parser(
        "plot",
        help="draw runs against ground truth (trajectory from above, error over distance) into a PNG",
    )
    p.add_argument("runs", metavar="RUN", nargs="+", type=Path, help="run folders (trajectory.txt)")
    p.add_argument("--gt", type=Path, default=None, help="sequence folder (its groundtruth.txt) or a TUM file")
    p.add_argument("--title", default="", help="title of the trajectory plot")
    add_output_argument(p, "image file to write: FILE.png (or .pdf, .svg)", metavar="FILE", type=Path)
    p.set_defaults(func=run)


def run(args) -> int:
    from floorvo.plots import plot_runs

    checked_output_beside_runs(args.output, args.runs, [args.gt])
    out = plot_runs(args.runs, args.gt, args.output, title=args.title)
    print(f"plot written to {out}")
    return 0

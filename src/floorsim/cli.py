"""``floorsim`` command line: one subcommand per module in :data:`COMMANDS`.

Each module under ``floorsim.commands`` defines ``add_parser(subparsers)`` and a
``run(args) -> int`` that is a thin call to a library function. Flags and logging as in
:mod:`floorvo.cli` (``-o/--output``, ``-v`` / ``-q`` before or after the subcommand).
"""

from __future__ import annotations

import sys
from collections.abc import Mapping
from typing import Any

from floorsim import __version__
from floorvo.cli import build_parser, run_cli

#: Command modules under ``floorsim.commands``, in the order ``--help`` lists them.
COMMANDS: list[str] = ["render", "list", "bench", "sweep", "export", "gallery", "cache"]


def main(argv: list[str] | None = None, *, collaborators: Mapping[str, Any] | None = None) -> int:
    """Run the CLI on ``argv``; ``collaborators`` (tests: doubles of the renderer, the scene
    loader and the estimator runner) go to ``bench`` and ``sweep``."""
    parser = build_parser(
        "floorsim",
        "floorsim.commands",
        COMMANDS,
        "Render the floor-camera rig and run the odometry bench.",
        __version__,
    )
    return run_cli(parser, argv, "floorsim", collaborators)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

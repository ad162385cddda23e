"""``floorvo`` command line: one subcommand per module in :data:`COMMANDS`.

Each command module defines ``add_parser(subparsers)`` (registering its arguments and
``set_defaults(func=run)``) and ``run(args) -> int``, a thin call to a library function.
A :class:`~floorvo.errors.FloorbenchError` becomes one line on stderr and exit code 1;
any other exception keeps its traceback.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

from floorvo import __version__
from floorvo.errors import FloorbenchError

#: Command modules under ``floorvo.cli``, in the order ``--help`` lists them.
COMMANDS: list[str] = ["run", "list", "score", "calibrate", "map", "localize"]


def build_parser(
    prog: str, package: str, commands: list[str], description: str, version: str
) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=prog, description=description)
    parser.add_argument("--version", action="version", version=f"%(prog)s {version}")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more logging (-vv for debug)")
    parser.add_argument("-q", "--quiet", action="store_true", help="only warnings and errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in commands:
        importlib.import_module(f"{package}.{name}").add_parser(sub)
    return parser


def run_cli(parser: argparse.ArgumentParser, argv: list[str] | None, prog: str) -> int:
    args = parser.parse_args(argv)
    level = logging.WARNING if args.quiet else (logging.INFO if args.verbose <= 1 else logging.DEBUG)
    if args.verbose == 0 and not args.quiet:
        level = logging.INFO
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    try:
        return int(args.func(args) or 0)
    except FloorbenchError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"{prog}: interrupted; what was written is kept, run the same command again to resume", file=sys.stderr)
        return 130


def main(argv: list[str] | None = None) -> int:
    parser = build_parser(
        "floorvo", "floorvo.cli", COMMANDS, "Odometry for downward-looking floor cameras.", __version__
    )
    return run_cli(parser, argv, "floorvo")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

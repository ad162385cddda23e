"""``floorvo`` command line: one subcommand per module in :data:`COMMANDS`.

Each command module defines ``add_parser(subparsers)`` (registering its arguments and
``set_defaults(func=run)``) and ``run(args) -> int``, a thin call to a library function.
A :class:`~floorvo.errors.FloorbenchError` becomes one line on stderr and exit code 1, and
so does an ``OSError`` (a full disk, a read-only folder: the line names the path); any
other exception keeps its traceback.

Flags that mean the same in every command of both CLIs (``floorvo``, ``floorsim``):
``-o/--output`` (the output file or folder; ``--out`` is accepted as a hidden alias, see
:func:`floorvo.cli.common.add_output_argument`), ``--set KEY=VALUE``, and ``-v/--verbose``
(debug logging of floorvo and floorsim) and ``-q/--quiet`` (warnings and errors only),
which work before or after the subcommand.

A command's ``run`` imports the library modules it needs when it runs: ``floorvo --help``
and a mistyped flag answer at once, without loading OpenCV, SciPy and the estimators.
These imports dodge no cycle (the command modules are leaves; each import works at module
level too).
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import importlib
import logging
import os
import signal
import sys
import threading
from collections.abc import Iterator, Mapping
from typing import Any, NoReturn

from floorvo import __version__
from floorvo.errors import ConfigError, FloorbenchError, shorten
from floorvo.interrupts import hand_back

__all__ = ["COMMANDS", "Terminated", "build_parser", "run_cli", "describe_os_error", "main"]

log = logging.getLogger(__name__)

#: Command modules under ``floorvo.cli``, in the order ``--help`` lists them.
COMMANDS: list[str] = ["run", "list", "score", "plot", "calibrate", "map", "localize", "import_"]

#: Loggers whose level ``-v`` / ``-q`` set.
PACKAGE_LOGGERS = ("floorvo", "floorsim")


class _HelpFormatter(argparse.HelpFormatter):
    """Leaves an option's ``hidden_aliases`` (e.g. ``--out`` of ``-o/--output``) out of the help."""

    def _format_action_invocation(self, action: argparse.Action) -> str:
        hidden = getattr(action, "hidden_aliases", ())
        if hidden:
            action = copy.copy(action)
            action.option_strings = [s for s in action.option_strings if s not in hidden]
        return super()._format_action_invocation(action)


class UsageError(ConfigError):
    """A command line argparse refuses (an unknown flag, ``--frames abc``): one line, exit code 1."""


class CommandParser(argparse.ArgumentParser):
    """The parser of both CLIs and of each subcommand (help without hidden aliases).

    A command line it refuses is a :class:`UsageError` (one line naming the argument and the
    rule, with where the help is; :func:`run_cli` prints it, exit code 1), as every other
    refusal is; argparse printed its usage block and exited 2."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", _HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        raise UsageError(f"{message} (see {self.prog} --help)")


def _add_verbosity(parser: argparse.ArgumentParser, suffix: str = "") -> None:
    parser.add_argument(
        "-v", "--verbose", dest=f"verbose{suffix}", action="count", default=0, help="debug logging of floorvo/floorsim"
    )
    parser.add_argument("-q", "--quiet", dest=f"quiet{suffix}", action="store_true", help="only warnings and errors")


def build_parser(
    prog: str, package: str, commands: list[str], description: str, version: str
) -> argparse.ArgumentParser:
    """The CLI ``prog``: a subcommand per module ``package.NAME`` of ``commands``; ``-v`` / ``-q``
    are accepted before and after the subcommand."""
    parser = CommandParser(prog=prog, description=description)
    parser.add_argument("--version", action="version", version=f"%(prog)s {version}")
    _add_verbosity(parser)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=CommandParser)
    sub.required = True
    for name in commands:
        importlib.import_module(f"{package}.{name}").add_parser(sub)
    for command_parser in sub.choices.values():
        _add_verbosity(command_parser, "_after")
    return parser


def _log_level(args: argparse.Namespace) -> int:
    if args.quiet or getattr(args, "quiet_after", False):
        return logging.WARNING
    if args.verbose + getattr(args, "verbose_after", 0) > 0:
        return logging.DEBUG
    return logging.INFO


def describe_os_error(exc: OSError) -> str:
    """An operating-system error as one line with the path: ``out/run/result.json: No space left
    on device (errno 28)``."""
    what = exc.strerror or str(exc) or type(exc).__name__
    if exc.errno is not None:
        what = f"{what} (errno {exc.errno})"
    paths = [str(p) for p in (exc.filename, exc.filename2) if p is not None]
    return shorten(f"{' -> '.join(paths)}: {what}" if paths else what, 400)


def _printable_streams() -> None:
    """Let standard output print a path that is not UTF-8 (a byte Python holds as a lone
    surrogate) as standard error does, escaped (``\\udcff``): ``floorvo import`` into such a
    folder imported it and then ended in a UnicodeEncodeError traceback printing its summary
    (``strict``), and under a C or C.UTF-8 locale (``surrogateescape``) ``floorvo run`` and
    ``score`` printed the raw byte in theirs, which is no text in the terminal's encoding."""
    for stream in (sys.stdout, sys.stderr):
        if getattr(stream, "errors", None) in ("strict", "surrogateescape") and hasattr(stream, "reconfigure"):
            try:
                stream.reconfigure(errors="backslashreplace")
            except (ValueError, OSError):  # a stream that cannot change now
                pass


class Terminated(KeyboardInterrupt):
    """SIGTERM (``kill PID``, ``timeout``, a batch system ending a job) while a command runs.

    Raised in the main thread as Ctrl-C's ``KeyboardInterrupt`` is, so it unwinds through the same
    clean-up: an atomic write removes its temporary, a folder lock is given back and its lock
    file removed, and the command ends with one line and exit code 143 (128 + SIGTERM). Before,
    SIGTERM ended the process at once, silently, leaving the temporary being written and the
    lock files of every folder it held (harmless to the next writer, which takes them over,
    but litter)."""


@contextlib.contextmanager
def _sigterm_interrupts() -> Iterator[None]:
    """While the block runs, SIGTERM raises :class:`Terminated` in this (the main) thread.

    Only where SIGTERM has its default action (a handler or an ignore set by whoever runs us
    stays), and only in the process that installed it: a ``fork()``ed child that kept the handler
    ends as SIGTERM ends it by default."""
    if threading.current_thread() is not threading.main_thread() or signal.getsignal(signal.SIGTERM) != signal.SIG_DFL:
        yield
        return
    pid = os.getpid()

    def terminated(signum: int, frame: Any) -> None:
        if os.getpid() != pid:
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
            os.kill(os.getpid(), signal.SIGTERM)
            return
        raise Terminated

    signal.signal(signal.SIGTERM, terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def run_cli(
    parser: argparse.ArgumentParser,
    argv: list[str] | None,
    prog: str,
    collaborators: Mapping[str, Any] | None = None,
) -> int:
    """Parse ``argv``, set the log level, run the command; returns the exit code.

    ``collaborators`` reach the commands that take them (``floorsim bench`` and ``sweep``
    pass them to their library function: a renderer, a scene loader, an estimator runner)
    as ``args.collaborators``; tests use it to run the CLI on doubles.
    """
    _printable_streams()
    try:
        args = parser.parse_args(argv)
    except UsageError as exc:
        print(f"{prog}: error: {shorten(str(exc), 2000)}", file=sys.stderr)
        return 1
    args.collaborators = dict(collaborators or {})
    level = _log_level(args)
    logging.basicConfig(level=max(level, logging.INFO), format="%(levelname)s %(name)s: %(message)s")
    previous = {name: logging.getLogger(name).level for name in PACKAGE_LOGGERS}
    for name in PACKAGE_LOGGERS:
        logging.getLogger(name).setLevel(level)
    log.debug("%s %s: debug logging on", prog, args.command)
    try:
        hand_back()  # the console script's answer while the CLI loaded (floorvo.interrupts): ours from here
        with _sigterm_interrupts():
            # OpenCV (and numpy) load here, after the parse (--help and a mistyped flag answer
            # without them), and where an interrupt is answered in one line.
            from floorvo.io import quiet_native_logs

            # OpenCV's own warnings (a truncated PNG) went to standard error before the one-line error
            # that says what is wrong; -v shows them. (FFmpeg's, a damaged video's, the video reader takes.)
            with contextlib.nullcontext() if level <= logging.DEBUG else quiet_native_logs():
                return int(args.func(args) or 0)
    except FloorbenchError as exc:
        # One line whatever the message holds (values are cut where they are formatted,
        # errors.shown; this keeps the contract for a path or a name read from a file too).
        print(f"{prog}: error: {shorten(str(exc), 2000)}", file=sys.stderr)
        return 1
    except BrokenPipeError as exc:
        if exc.filename is not None:  # a file's pipe, not ours: as any other OSError
            print(f"{prog}: error: {describe_os_error(exc)}", file=sys.stderr)
            return 1
        # our standard output was closed by its reader (`floorsim list | head`): end quietly, as
        # a command killed by SIGPIPE does ('Broken pipe (errno 32)' was printed as an error)
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # Python's flush at exit fails otherwise
        except (OSError, ValueError, AttributeError):  # no real file behind sys.stdout (a test's capture)
            pass
        return 141
    except OSError as exc:  # a full disk, a read-only folder, a file that vanished: one line with the path
        print(f"{prog}: error: {describe_os_error(exc)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM (Terminated)
        how = "interrupted (SIGTERM)" if isinstance(exc, Terminated) else "interrupted"
        print(f"{prog}: {how}; what was written is kept, run the same command again to resume", file=sys.stderr)
        return 128 + signal.SIGTERM if isinstance(exc, Terminated) else 130
    finally:
        for name, lvl in previous.items():  # a process that runs several commands (tests) starts each afresh
            logging.getLogger(name).setLevel(lvl)


def main(argv: list[str] | None = None, *, collaborators: Mapping[str, Any] | None = None) -> int:
    parser = build_parser(
        "floorvo", "floorvo.cli", COMMANDS, "Odometry for downward-looking floor cameras.", __version__
    )
    return run_cli(parser, argv, "floorvo", collaborators)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

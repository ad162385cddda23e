"""Helpers shared by the command modules of both CLIs."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from floorvo.config import parse_set_args  # the one --set parser, re-exported for the command modules
from floorvo.errors import ConfigError
from floorvo.io import checked_output_file
from floorvo.runfolder import RESULT, TIMING, TRAJECTORY

__all__ = [
    "add_output_argument",
    "add_external_arguments",
    "externals_from_args",
    "parse_name_values",
    "parse_set_args",
    "progress_callback",
]


def parse_name_values(items: list[str] | None, flag: str, form: str) -> dict[str, str]:
    """Repeated ``NAME=VALUE`` options (``--topic image=/cam0/image_raw``) into ``{NAME: VALUE}``.

    ``flag`` and ``form`` (``"ROLE=NAME (e.g. image=/cam0/image_raw)"``) word the one-line
    :class:`ConfigError` for an item without a name or a value, and for a name given twice
    (the last one was taken silently: ``--external a=CMD1 --external a=CMD2`` ran CMD2 alone).
    """
    out: dict[str, str] = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep or not name.strip() or not value.strip():
            raise ConfigError(f"{flag} {item!r}: expected {form}")
        if name.strip() in out:
            raise ConfigError(
                f"{flag} {item!r}: {name.strip()!r} is given twice (also {name.strip()}={out[name.strip()]}); give each once"
            )
        out[name.strip()] = value.strip()
    return out


def checked_output_beside_runs(output: Path, runs: Iterable[Path], ground_truths: Iterable[Path | None] = ()) -> Path:
    """The output file ``output`` of a command that reads the run folders ``runs`` and the ground
    truth ``ground_truths`` (sequence folders or TUM files), refused in one line
    (:class:`~floorvo.errors.ConfigError`) where it would overwrite what the command reads: a
    run's ``trajectory.txt``, ``timing.csv`` or ``result.json``, a ground-truth file, or anything
    inside a sequence folder (:func:`floorvo.io.checked_output_file`)."""
    reads = [Path(r) / f for r in runs for f in (TRAJECTORY, TIMING, RESULT)]
    reads += [g for g in ground_truths if g is not None and not Path(g).is_dir()]
    return checked_output_file(output, ConfigError, reads=reads)


def add_output_argument(parser: argparse.ArgumentParser, help: str, **kwargs: Any) -> argparse.Action:
    """``-o/--output`` (``args.output``), the one output flag of every command.

    ``--out``, the older spelling of four commands, is accepted as a hidden alias (left out
    of the help). ``kwargs`` go to ``add_argument`` (default ``required=True``).
    """
    kwargs.setdefault("required", True)
    action = parser.add_argument("-o", "--output", "--out", dest="output", help=help, **kwargs)
    action.hidden_aliases = ("--out",)  # type: ignore[attr-defined]  # read by the CLI's help formatter
    return action


def add_external_arguments(parser: argparse.ArgumentParser) -> None:
    """``--external NAME=CMD`` and ``--estimator-file FILE`` (both repeatable): estimators that are
    programs (:mod:`floorvo.external`), read by :func:`externals_from_args`."""
    parser.add_argument(
        "--external",
        action="append",
        metavar="NAME=CMD",
        help="an estimator that is a program, run once per sequence; CMD is split like a shell does and may use "
        "{sequence}, {output}, {camera}, {images}, {height_mm}, {fps}, {frames}; it writes {output}/trajectory.txt "
        "(TUM) and optionally timing.csv (repeatable)",
    )
    parser.add_argument(
        "--estimator-file",
        action="append",
        metavar="FILE",
        help="an external estimator in a TOML file: name, command = [...], optional timeout_s, env, needs (repeatable)",
    )


def externals_from_args(args: argparse.Namespace) -> list:
    """The :class:`floorvo.external.ExternalEstimator` of ``--external`` and ``--estimator-file``."""
    from floorvo.external import load_estimator_file, parse_external

    items = parse_name_values(
        getattr(args, "external", None), "--external", "NAME=COMMAND (e.g. my-vo='my_vo {sequence} {output}')"
    )
    specs = [parse_external(command, name) for name, command in items.items()]
    specs += [load_estimator_file(path) for path in getattr(args, "estimator_file", None) or []]
    return specs


class progress_callback:
    """Context manager giving an ``on_progress(done, total, desc=None)`` callback that drives a
    tqdm bar: the one progress bar of both CLIs.

    ``desc`` names what is counted; a call with another ``desc`` (the next scene of a bench)
    closes the bar and starts a new one. On a non-terminal stderr the callback does nothing
    (no progress bars in logs).
    """

    def __init__(self, desc: str = "", unit: str = "frame"):
        self.desc, self.unit = desc, unit
        self.bar: Any = None

    def update(self, done: int, total: int, desc: str | None = None) -> None:
        if not sys.stderr.isatty():
            return
        desc = self.desc if desc is None else desc
        if self.bar is not None and (self.bar.desc != desc or self.bar.total != total):
            self.bar.close()
            self.bar = None
        if self.bar is None:
            from tqdm import tqdm  # imported only when a bar is drawn: keeps the CLI's start quick

            self.bar = tqdm(total=total, desc=desc, unit=self.unit, leave=False)
        self.bar.n = done
        self.bar.refresh()

    def __enter__(self):
        return self.update

    def __exit__(self, *exc) -> None:
        if self.bar is not None:
            self.bar.close()

"""Helpers shared by the command modules of both CLIs."""

from __future__ import annotations

import sys

from floorvo.config import parse_set_args  # the one --set parser, re-exported for the command modules

__all__ = ["parse_set_args", "progress", "progress_callback"]


def progress(iterable, total: int | None = None, desc: str = "", unit: str = "frame"):
    """A tqdm progress bar on a terminal; the plain iterable otherwise."""
    if not sys.stderr.isatty():
        return iterable
    from tqdm import tqdm

    return tqdm(iterable, total=total, desc=desc, unit=unit, leave=False)


class progress_callback:
    """Context manager giving an ``on_progress(done, total)`` callback that drives a tqdm bar.

    On a non-terminal stderr the callback does nothing (no progress bar in logs).
    """

    def __init__(self, desc: str = "", unit: str = "frame"):
        self.desc, self.unit, self.bar = desc, unit, None

    def __enter__(self):
        def cb(done: int, total: int) -> None:
            if not sys.stderr.isatty():
                return
            if self.bar is None:
                from tqdm import tqdm

                self.bar = tqdm(total=total, desc=self.desc, unit=self.unit, leave=False)
            self.bar.n = done
            self.bar.refresh()

        return cb

    def __exit__(self, *exc) -> None:
        if self.bar is not None:
            self.bar.close()

"""Helpers shared by the command modules of both CLIs."""

from __future__ import annotations

import sys

from floorvo.errors import ConfigError

__all__ = ["parse_set_args", "progress", "progress_callback"]


def parse_set_args(items: list[str] | None) -> dict[str, str]:
    """Parse ``--set KEY=VALUE`` arguments into ``{KEY: VALUE}`` (values stay strings)."""
    out: dict[str, str] = {}
    for item in items or []:
        if "=" not in item:
            raise ConfigError(f"--set {item!r}: expected KEY=VALUE")
        key, value = item.split("=", 1)
        key = key.strip()
        if not key:
            raise ConfigError(f"--set {item!r}: empty key")
        out[key] = value.strip()
    return out


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

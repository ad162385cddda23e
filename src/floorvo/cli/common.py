"""Helpers shared by the command modules of both CLIs."""

from __future__ import annotations

import sys

from floorvo.errors import ConfigError

__all__ = ["parse_set_args", "progress"]


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

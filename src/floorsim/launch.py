"""The ``floorsim`` console script's start (:func:`floorvo.launch.launch`): Ctrl-C and SIGTERM
answered in one line while the CLI loads."""

from __future__ import annotations

from floorvo.launch import launch

__all__ = ["main"]


def main() -> int:
    """The ``floorsim`` console script."""
    return launch("floorsim", "floorsim.cli")

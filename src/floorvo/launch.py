"""The console scripts' start: Ctrl-C and SIGTERM answered in one line while the CLI loads.

``floorvo`` and ``floorsim`` import numpy, OpenCV and their own modules and build their parsers
before a command runs (0.1-0.5 s), and :func:`floorvo.cli.run_cli` takes over the interrupts only
then: a Ctrl-C in that time was Python's ``KeyboardInterrupt`` traceback (exit code -2), a SIGTERM
an end without a word. :func:`launch` answers them in the meantime
(:func:`floorvo.interrupts.answer_while_loading`) until ``run_cli`` hands them back as its command
starts, and only then imports the CLI: the console script is the top of the import graph, the CLI
module is named by its caller. Only numpy's import, before this module runs (about 0.05 s), is
left to Python's own handling.
"""

from __future__ import annotations

import importlib
import sys

from floorvo.interrupts import answer_while_loading, hand_back

__all__ = ["launch", "floorvo_main"]


def launch(prog: str, module: str) -> int:
    """Run ``module``'s ``main()`` (the CLI ``prog``), with the interrupts answered while it loads."""
    answer_while_loading(prog)
    try:
        return int(importlib.import_module(module).main() or 0)
    finally:
        hand_back()


def floorvo_main() -> int:
    """The ``floorvo`` console script."""
    return launch("floorvo", "floorvo.cli")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(floorvo_main())

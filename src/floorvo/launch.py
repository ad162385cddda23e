"""The console scripts' start: Ctrl-C and SIGTERM answered in one line while the CLI loads.

``floorvo`` and ``floorsim`` import numpy, OpenCV and their own modules and build their parsers
before a command runs (0.1-0.5 s), and :func:`floorvo.cli.run_cli` takes over the interrupts only
then: a Ctrl-C in that time was Python's ``KeyboardInterrupt`` traceback (exit code -2), a SIGTERM
an end without a word. :func:`launch` answers them in the meantime as ``run_cli`` does (one line,
exit code 130 or 143; nothing is written while the CLI loads) until ``run_cli`` calls
:func:`hand_back` as its command starts. Only numpy's import, before this module runs (about 0.05
s), is left to Python's own handling.
"""

from __future__ import annotations

import importlib
import os
import signal
import sys
from typing import Any

__all__ = ["launch", "hand_back"]

#: The handlers :func:`launch` replaced, to give back (empty when it replaced none).
_TAKEN: dict[int, Any] = {}


def _loading(prog: str):
    def answer(signum: int, frame: Any) -> None:
        how = "interrupted (SIGTERM)" if signum == signal.SIGTERM else "interrupted"
        os.write(2, f"{prog}: {how}; what was written is kept, run the same command again to resume\n".encode())
        os._exit(128 + signum)

    return answer


def hand_back() -> None:
    """Give back the handlers :func:`launch` replaced (``run_cli`` calls it as a command starts:
    from there Ctrl-C unwinds through the command's clean-up); nothing when it replaced none."""
    while _TAKEN:
        sig, handler = _TAKEN.popitem()
        signal.signal(sig, handler)


def launch(prog: str, module: str) -> int:
    """Run ``module``'s ``main()`` (the CLI ``prog``), with the interrupts answered while it loads.
    A signal some caller ignores or handles stays as it is."""
    defaults = {signal.SIGINT: signal.default_int_handler, signal.SIGTERM: signal.SIG_DFL}
    answer = _loading(prog)
    for sig, default in defaults.items():
        if signal.getsignal(sig) is default:  # as Python starts, not as a caller set it
            _TAKEN[sig] = default
            signal.signal(sig, answer)
    try:
        return int(importlib.import_module(module).main() or 0)
    finally:
        hand_back()


def floorvo_main() -> int:
    """The ``floorvo`` console script."""
    return launch("floorvo", "floorvo.cli")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(floorvo_main())

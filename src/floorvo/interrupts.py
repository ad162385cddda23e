"""Ctrl-C and SIGTERM answered in one line while a CLI loads (:mod:`floorvo.launch`), until the
command's own handling takes over (:func:`hand_back`, called by :func:`floorvo.cli.run_cli`).

The answer is :func:`floorvo.cli.run_cli`'s: ``PROG: interrupted; what was written is kept, run
the same command again to resume`` (``interrupted (SIGTERM)``), exit code 130 or 143. Nothing is
written while a CLI loads, so the process ends there and then.
"""

from __future__ import annotations

import os
import signal
from typing import Any

__all__ = ["answer_while_loading", "hand_back"]

#: The handlers :func:`answer_while_loading` replaced, to give back (empty when it replaced none).
_TAKEN: dict[int, Any] = {}


def answer_while_loading(prog: str) -> None:
    """From now on a Ctrl-C or SIGTERM ends the process in one line naming ``prog``, until
    :func:`hand_back`. A signal some caller ignores or handles stays as it is."""

    def answer(signum: int, frame: Any) -> None:
        how = "interrupted (SIGTERM)" if signum == signal.SIGTERM else "interrupted"
        os.write(2, f"{prog}: {how}; what was written is kept, run the same command again to resume\n".encode())
        os._exit(128 + signum)

    for sig, default in ((signal.SIGINT, signal.default_int_handler), (signal.SIGTERM, signal.SIG_DFL)):
        if signal.getsignal(sig) is default:  # as Python starts, not as a caller set it
            _TAKEN[sig] = default
            signal.signal(sig, answer)


def hand_back() -> None:
    """Give back the handlers :func:`answer_while_loading` replaced (``run_cli`` calls it as a
    command starts: from there Ctrl-C unwinds through the command's clean-up); nothing when it
    replaced none."""
    while _TAKEN:
        sig, handler = _TAKEN.popitem()
        signal.signal(sig, handler)

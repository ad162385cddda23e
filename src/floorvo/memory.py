"""Peak resident memory of a run: this process's, or a program's it started, sampled.

:class:`PeakRss` samples resident memory on a thread while its context is open. For this
process (an estimator run in the bench's own interpreter) it reads the current resident set
(``/proc/self/statm``), so its peak includes what the process held before the run (a Python
process with numpy and OpenCV loaded, about 150-250 MiB). For a program (``pid``: an external
estimator, :mod:`floorvo.external`) it reads the high-water mark the kernel keeps of the
program's resident set since it started (``VmHWM`` in ``/proc/PID/status``), and of each
process it started itself (``/proc/PID/task/*/children``, recursively), and keeps the largest:
a peak between two samples is still seen, and only what the program grows in the last interval
before it ends can be missed.

The kernel's own figure for a child, ``ru_maxrss`` from ``wait4``, cannot serve: a program
started by ``fork`` or ``vfork`` from this process (``subprocess`` does) carries this process's
resident set over its ``exec`` (Linux counts the memory it replaced), so a 2 MiB program read as
the 112-500 MiB of the bench that started it.

Where ``/proc`` does not exist (not Linux) the peak is NaN.
"""

from __future__ import annotations

import math
import os
import threading
from typing import Any

__all__ = ["PeakRss"]


def _self_rss_mb() -> float:
    """This process's resident set now, MiB (NaN without ``/proc/self/statm``)."""
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
    except (OSError, ValueError, IndexError):
        return math.nan


def _hwm_kib(pid: int) -> float:
    """``VmHWM`` of process ``pid``, KiB: the high-water mark of its resident set since it started
    (its last ``exec``); NaN when it cannot be read (the process has ended, or no ``/proc``)."""
    try:
        with open(f"/proc/{pid}/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return float(line.split()[1])
    except (OSError, ValueError, IndexError):
        pass
    return math.nan


def _children(pid: int) -> list[int]:
    """The processes ``pid`` started that are running now (every thread's children), [] if unknown."""
    out: list[int] = []
    try:
        tasks = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return out
    for tid in tasks:
        try:
            with open(f"/proc/{pid}/task/{tid}/children") as fh:
                out.extend(int(c) for c in fh.read().split())
        except (OSError, ValueError):
            continue
    return out


def tree_peak_mb(pid: int, max_processes: int = 256) -> float:
    """The largest ``VmHWM`` (MiB) of process ``pid`` and of the processes it started, recursively
    (at most ``max_processes``); NaN when none can be read."""
    peak, todo, seen = math.nan, [pid], 0
    while todo and seen < max_processes:
        p = todo.pop()
        seen += 1
        kib = _hwm_kib(p)
        if not math.isnan(kib):
            peak = kib / 1024.0 if math.isnan(peak) else max(peak, kib / 1024.0)
        todo.extend(_children(p))
    return peak


class PeakRss:
    """Context manager sampling resident memory every ``interval_s``; ``peak_mb`` is the largest
    sample (MiB), NaN where nothing could be read (not Linux).

    ``pid=None``: this process's current resident set, while the context is open. ``pid``: a
    program this process started, already running (past its ``exec``: ``subprocess.Popen`` returns
    after it): the high-water mark of its resident set and of its own children's
    (:func:`tree_peak_mb`); close the context before the program is reaped (``os.waitid`` with
    ``WNOWAIT``), so that its pid cannot name another process yet.
    """

    def __init__(self, interval_s: float = 0.02, pid: int | None = None):
        self.interval_s = interval_s
        self.pid = pid
        self.peak_mb = math.nan
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @staticmethod
    def current_mb() -> float:
        """This process's resident set now, MiB (NaN without ``/proc``)."""
        return _self_rss_mb()

    def _sample(self) -> None:
        mb = _self_rss_mb() if self.pid is None else tree_peak_mb(self.pid)
        if not math.isnan(mb):
            self.peak_mb = mb if math.isnan(self.peak_mb) else max(self.peak_mb, mb)

    def _loop(self) -> None:
        while not self._stop.wait(self.interval_s):
            self._sample()

    def __enter__(self) -> PeakRss:
        self._sample()
        self._thread = threading.Thread(target=self._loop, name="peak-rss", daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc: Any) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        self._sample()  # the last figure (a program that has ended reads as nothing: its peak stands)

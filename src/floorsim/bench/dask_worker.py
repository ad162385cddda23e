"""Set-up of each worker process of a sweep's local Dask cluster (:func:`floorsim.bench.sweep.job_pool`
passes this module as the workers' ``preload``).

A Ctrl-C reaches the whole process group, the workers with the sweep's main process; each worker
printed its own ``KeyboardInterrupt`` traceback (30-60 lines in all) while the main process stopped
in one line. The main process alone handles the interrupt: it closes the cluster, whose nannies
then end their workers, so a worker ignores SIGINT.
"""

from __future__ import annotations

import signal
from typing import Any


def dask_setup(worker: Any) -> None:
    """Dask's preload hook, run in the worker process as it starts: SIGINT ignored there."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:  # not the process's main thread: Python lets only that one set handlers
        pass

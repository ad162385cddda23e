"""A sweep killed with SIGKILL takes its local worker pool with it."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import _bench_doubles as D

#: A sweep of two jobs on two local workers whose render records the worker's pid and then
#: sleeps ten minutes: the workers are busy when the main process is killed.
_PROBE = """
import os, sys, time
from pathlib import Path
sys.path.insert(0, {tests!r})
import _bench_doubles as D
from floorsim.bench.sweep import run_sweep

def slow_render(scene, out, **kwargs):
    (Path({pids!r}) / str(os.getpid())).write_text("")
    time.sleep(600)

if __name__ == "__main__":
    run_sweep({sweep!r}, {out!r}, jobs=2, render=slow_render, load_scene=D.load_scene, runner=D.FakeRunner(),
              report=False)
"""


def _alive(pid: int) -> bool:
    """True while process ``pid`` exists and is not a zombie (an exited child nobody reaped yet)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except FileNotFoundError:
        return False
    except OSError:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        return True
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def test_workers_exit_when_the_sweep_is_killed(tmp_path):
    base = D.write_scene(tmp_path / "base.toml")
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(f'base = "{base.name}"\nestimators = ["scaled"]\n\n[vary]\n"lights.height_mm" = [1.0, 10.0]\n')
    pids = tmp_path / "pids"
    pids.mkdir()
    probe = tmp_path / "probe.py"
    probe.write_text(
        _PROBE.format(tests=str(Path(__file__).parent), pids=str(pids), sweep=str(sweep), out=str(tmp_path / "out"))
    )
    with open(tmp_path / "probe.log", "w") as log:
        main = subprocess.Popen([sys.executable, str(probe)], stdout=log, stderr=subprocess.STDOUT, cwd=tmp_path)
    workers: list[int] = []
    try:
        deadline = time.monotonic() + 180
        while len(workers) < 2:
            assert main.poll() is None, (tmp_path / "probe.log").read_text()
            assert time.monotonic() < deadline, "the two workers did not start their jobs"
            time.sleep(0.2)
            workers = [int(p.name) for p in pids.iterdir()]
        assert all(_alive(w) for w in workers) and main.pid not in workers
        main.kill()
        main.wait()
        deadline = time.monotonic() + 20
        while any(_alive(w) for w in workers) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert not any(_alive(w) for w in workers), "workers still running after their sweep was killed"
    finally:
        if main.poll() is None:
            main.kill()
        for w in workers:
            if _alive(w):
                os.kill(w, signal.SIGKILL)

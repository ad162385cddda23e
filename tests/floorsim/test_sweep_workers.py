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


#: The floorsim CLI's sweep on a local Dask cluster of one worker process, with the doubles; the
#: render double of the second job (LED height 10) marks that it started and then sleeps.
_DASK_CLI = """
import sys, time
from pathlib import Path
import _bench_doubles as D
from floorsim.cli import main

def render(scene, out, **kwargs):
    if scene.data["lights"]["height_mm"] == 10.0:
        Path({started!r}).write_text("")
        time.sleep(600)
    return D.render(scene, out, **kwargs)

if __name__ == "__main__":
    collaborators = dict(D.COLLABORATORS, render=render)
    sys.exit(main(["-q", "sweep", {sweep!r}, "-o", {out!r}, "--workers", "1", *sys.argv[1:]], collaborators=collaborators))
"""


def test_a_dask_sweep_is_quiet_under_q_and_stops_in_one_line_on_ctrl_c(tmp_path):
    """A sweep on a local Dask cluster printed 24 'INFO distributed.*' lines under -q, and a Ctrl-C
    to its process group 29-61 lines, with a KeyboardInterrupt traceback from each worker."""
    from _procs import child_env

    base = D.write_scene(tmp_path / "base.toml")
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(f'base = "{base.name}"\nestimators = ["scaled"]\n\n[vary]\n"lights.height_mm" = [1.0, 10.0]\n')
    started = tmp_path / "started"
    probe = tmp_path / "probe.py"
    probe.write_text(_DASK_CLI.format(started=str(started), sweep=str(sweep), out=str(tmp_path / "out")))
    env = child_env()
    env["PYTHONPATH"] = os.pathsep.join(
        [str(Path(__file__).parent), env["PYTHONPATH"]]
    )  # the doubles, in the workers too
    main = subprocess.Popen(
        [sys.executable, str(probe)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
        env=env,
        start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # as a terminal's foreground job
    )
    try:
        deadline = time.monotonic() + 180
        while not started.exists():
            assert main.poll() is None, main.communicate()
            assert time.monotonic() < deadline, "the second job did not start"
            time.sleep(0.1)
        os.killpg(main.pid, signal.SIGINT)  # Ctrl-C: the whole process group
        _, err = main.communicate(timeout=120)
    finally:
        if main.poll() is None:
            os.killpg(main.pid, signal.SIGKILL)
            main.wait()
    assert main.returncode == 130, err
    assert err.strip().splitlines() == [
        "floorsim: interrupted; what was written is kept, run the same command again to resume"
    ], err

"""``floorsim bench`` interrupted (Ctrl-C, SIGTERM) and run again with the same arguments.

The bench is started as a child in its own process group and the signal goes to the group,
as a terminal's Ctrl-C does, at moments chosen by its own progress: once the first sequence
frame is on disk (rendering), once the first run folder appears (running the estimators),
once the second run's folder appears (results.csv holds a row) and once the report's plots
folder appears (writing the report). Each time:

* it ends with one line on standard error, no traceback, and exit code 130 for SIGINT,
  143 for SIGTERM (as shells report a command so ended);
* every file under its final name is whole, and no temporary or lock file is left;
* the same command completes the bench, and its ``results.csv`` and ``report.md`` equal an
  uninterrupted bench's (clock and memory figures aside), as do its sequence frames,
  ground truth and trajectories, byte for byte.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import _bench_doubles as D
import cv2
import numpy as np
import pytest
from _tiny import TINY_TOML

from _procs import child_env
from floorsim.bench.results import read_results_csv
from floorsim.cli import main as floorsim_main
from floorvo.locking import LOCK_FILE
from floorvo.tum import read_tum

pytestmark = pytest.mark.render

ESTIMATORS = ("phase-corr-fast", "akaze-guided-fast")
#: Columns of results.csv (beside the ``time_*`` ones) that differ between identical runs (clocks,
#: memory) or name the output folder.
VOLATILE = ("wall_ms_per_frame", "peak_rss_mb", "fps", "run_dir", "sequence")
#: Columns of report.md's tables that differ between identical runs.
VOLATILE_MD = ("ms/frame", "wall ms/frame", "peak MiB", "wall ms/frame, mean", "peak MiB, max")


def _bench_cmd(scene: Path, out: Path) -> list[str]:
    code = "import sys; from floorsim.cli import main; sys.exit(main(sys.argv[1:]))"
    args = ["bench", str(scene), "--estimators", ",".join(ESTIMATORS), "--frames", "6", "-o", str(out)]
    return [sys.executable, "-c", code, "-q", *args]


def _first_frame(out: Path) -> bool:
    return any(out.glob("sequences/*/cam0/000000.png"))


def _run_folder(k: int):
    return lambda out: (out / "runs" / "tiny" / ESTIMATORS[k] / "rep0").is_dir()


def _plots(out: Path) -> bool:
    return (out / "plots").is_dir()


#: Where the bench is interrupted: (name, condition on the output folder, signal).
MOMENTS = [
    ("rendering", _first_frame, signal.SIGINT),
    ("first run", _run_folder(0), signal.SIGINT),
    ("second run", _run_folder(1), signal.SIGINT),
    ("report", _plots, signal.SIGINT),
    ("first run SIGTERM", _run_folder(0), signal.SIGTERM),
]


def _interrupt_when(cmd: list[str], out: Path, ready, sig: int, timeout: float = 300) -> subprocess.CompletedProcess:
    """Run ``cmd``; once ``ready(out)`` send ``sig`` to its process group; its exit code and output."""
    p = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=child_env(), start_new_session=True
    )
    deadline = time.monotonic() + timeout
    try:
        while not ready(out):
            if p.poll() is not None:
                out_text, err = p.communicate()
                pytest.fail(f"the bench ended (exit code {p.returncode}) before it could be interrupted: {err}")
            assert time.monotonic() < deadline, "the moment to interrupt never came"
            time.sleep(0.002)
        os.killpg(p.pid, sig)
        out_text, err = p.communicate(timeout=timeout)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
    return subprocess.CompletedProcess(cmd, p.returncode, out_text, err)


def _whole(root: Path) -> None:
    """Every file under ``root`` reads as its format, and no temporary or lock file is left."""
    for p in root.rglob("*"):
        assert not p.name.endswith(".tmp"), f"a temporary was left: {p}"
        assert p.name != LOCK_FILE, f"a lock file was left: {p}"
        if not p.is_file():
            continue
        if p.suffix == ".png":
            assert cv2.imdecode(np.fromfile(p, np.uint8), cv2.IMREAD_UNCHANGED) is not None, p
        elif p.suffix == ".json":
            json.loads(p.read_text())
        elif p.name in ("groundtruth.txt", "trajectory.txt"):
            read_tum(p, allow_empty=True)
        elif p.suffix == ".csv":
            list(csv.reader(p.open()))
        elif p.suffix == ".html":
            assert p.read_text().rstrip().endswith("</html>"), p
    for run in root.glob("runs/*/*/*"):  # a run folder is all or nothing: result.json marks a finished one
        if (run / "result.json").is_file():
            assert (run / "trajectory.txt").is_file() and (run / "timing.csv").is_file(), run


def _rows(out: Path) -> list[dict]:
    return [
        {k: ("nan" if v != v else v) for k, v in r.items() if k not in VOLATILE and not k.startswith("time_")}
        for r in read_results_csv(out / "results.csv")
    ]


def _report_md(out: Path) -> str:
    """report.md with the cells of its clock and memory columns blanked."""
    lines, header = [], None
    for line in (out / "report.md").read_text().splitlines():
        cells = line.split("|")
        if not line.startswith("|"):
            header = None
        elif header is None:
            header = [c.strip() for c in cells]
        elif not set(line) <= set("|-"):
            cells = ["" if i < len(header) and header[i] in VOLATILE_MD else c for i, c in enumerate(cells)]
        lines.append("|".join(cells))
    return "\n".join(lines)


def _kept(root: Path) -> dict[str, bytes]:
    """The files that must be the same bytes: frames, ground truth, trajectories."""
    return {
        str(p.relative_to(root)): p.read_bytes()
        for p in sorted(root.rglob("*"))
        if p.is_file() and p.name.endswith((".png", "groundtruth.txt", "trajectory.txt")) and "plots" not in p.parts
    }


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    p = tmp_path_factory.mktemp("scene") / "tiny.toml"
    p.write_text(TINY_TOML)
    return p


@pytest.fixture(scope="module")
def reference(scene, tmp_path_factory) -> Path:
    """An uninterrupted bench."""
    out = tmp_path_factory.mktemp("ref") / "bench"
    r = subprocess.run(_bench_cmd(scene, out), capture_output=True, text=True, timeout=300, env=child_env())
    assert r.returncode == 0, r.stderr
    return out


@pytest.mark.parametrize(
    "moment",
    [
        pytest.param(m, id=m[0].replace(" ", "-"), marks=() if m[0].startswith("first run") else pytest.mark.slow)
        for m in MOMENTS
    ],
)
def test_an_interrupted_bench_says_so_in_one_line_and_resumes_to_an_uninterrupted_ones_results(
    moment, scene, reference, tmp_path
):
    _, ready, sig = moment
    out = tmp_path / "bench"
    cmd = _bench_cmd(scene, out)
    r = _interrupt_when(cmd, out, ready, sig)
    assert r.returncode == 128 + sig, (r.returncode, r.stderr)
    err = r.stderr.strip()
    assert "Traceback" not in err and err.count("\n") == 0, err
    assert "interrupted" in err and "run the same command again" in err, err
    _whole(out)
    again = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=child_env())
    assert again.returncode == 0, again.stderr
    _whole(out)
    got, want = _rows(out), _rows(reference)
    diff = [
        (i, k, a.get(k), b.get(k)) for i, (a, b) in enumerate(zip(got, want)) for k in {*a, *b} if a.get(k) != b.get(k)
    ]
    assert len(got) == len(want) and not diff, diff
    assert _report_md(out) == _report_md(reference)
    assert _kept(out) == _kept(reference)


def test_sigterm_ends_a_command_in_one_line_and_gives_its_folders_back(tmp_path, capsys):
    """SIGTERM (kill PID, timeout, a batch system) ended the process at once: no message, exit code
    -15, and the lock files of the bench folder and the run folder it was writing left behind.
    It now unwinds as Ctrl-C does; outside a command SIGTERM keeps its default action."""
    D.reset()
    scene = D.write_scene(tmp_path / "s.toml")
    runner = D.FakeRunner()
    real_run = runner.run

    def run_then_sigterm(seq_dir, name, run_dir, *args, **kwargs):
        figures = real_run(seq_dir, name, run_dir, *args, **kwargs)
        os.kill(os.getpid(), signal.SIGTERM)
        return figures

    runner.run = run_then_sigterm  # type: ignore[method-assign]
    out = tmp_path / "out"
    args = ["-q", "bench", str(scene), "--estimators", "scaled", "--no-report", "-o", str(out)]
    assert floorsim_main(args, collaborators={**D.COLLABORATORS, "runner": runner}) == 143
    err = capsys.readouterr().err
    assert err == "floorsim: interrupted (SIGTERM); what was written is kept, run the same command again to resume\n"
    assert not list(out.rglob(LOCK_FILE)) and not list(out.rglob("*.tmp"))
    assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL
    assert floorsim_main(args, collaborators=D.COLLABORATORS) == 0
    assert [r["status"] for r in read_results_csv(out / "results.csv")] == ["ok"]


#: Runs the floorsim CLI with a SIGTERM or SIGINT (env INTERRUPT_SIGNAL) sent to itself the moment
#: Dr.Jit imports its LLVM backend: inside the renderer's import of Mitsuba.
_INTERRUPT_AT_DRJIT = """
import os, signal, sys
sig = getattr(signal, os.environ["INTERRUPT_SIGNAL"])
class Hook:
    fired = False
    def find_spec(self, name, path=None, target=None):
        if name == "drjit.llvm" and not Hook.fired:
            Hook.fired = True
            os.kill(os.getpid(), sig)
        return None
sys.meta_path.insert(0, Hook())
from floorsim.cli import main
code = main(sys.argv[1:])
print("fired" if Hook.fired else "not fired", file=sys.stderr)
sys.exit(code)
"""


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_an_interrupt_while_mitsuba_loads_ends_the_render_and_it_resumes(scene, tmp_path, sig):
    """An interrupt inside Dr.Jit's import became an ordinary exception: sequence.json recorded the
    backend as 'unavailable', then the process aborted (134) or went on and exited 0; the same
    command was then refused ('holds a different sequence'). Now the interrupt waits for the import
    to end and stops the render in one line; the same command renders the sequence."""
    out = tmp_path / "seq"
    cmd = [sys.executable, "-c", _INTERRUPT_AT_DRJIT, "-q", "render", str(scene), "-o", str(out), "--frames", "2"]
    r = subprocess.run(
        cmd, capture_output=True, text=True, timeout=300, env={**child_env(), "INTERRUPT_SIGNAL": sig.name}
    )
    lines = r.stderr.strip().splitlines()
    assert lines[-1] == "fired", r.stderr  # the hook ran: Dr.Jit's LLVM backend was imported
    assert r.returncode == 128 + sig, (r.returncode, r.stderr)
    assert len(lines) == 2 and "interrupted" in lines[0] and "Traceback" not in r.stderr, r.stderr
    again = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys; from floorsim.cli import main; sys.exit(main(sys.argv[1:]))",
            "-q",
            "render",
            str(scene),
            "-o",
            str(out),
            "--frames",
            "2",
        ],
        capture_output=True,
        text=True,
        timeout=300,
        env=child_env(),
    )
    assert again.returncode == 0, again.stderr
    versions = json.loads((out / "sequence.json").read_text())["versions"]
    assert "backend" not in versions and versions["variant"].startswith(("llvm", "cuda")), versions
    _whole(out)

"""Issue 16's fault injection: kill -9 at seeded random moments, two writers of one folder, a full disk.

* Two ``floorsim render`` of different seeds into one folder, and two ``floorsim sweep`` into
  one folder, mixed or lost data (issue 16 item 1): the second is now refused in one line
  naming the first's pid, and the folder ends as the first alone makes it. The first is
  paused (SIGSTOP) mid-work while the second runs, so the overlap is certain.
* A render, a run, a sweep and a bench killed with SIGKILL at seeded random moments and
  started again end with the bytes of an uninterrupted run (times and paths aside).
* A disk that fills up (``os.fsync`` patched to fail with ENOSPC after a seeded number of
  files) stops a render or a sweep with one line; every file already there reads, and the
  same command, run again, completes it.
"""

from __future__ import annotations

import csv
import errno
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import _bench_doubles as D
import cv2
import numpy as np
import pytest
from _tiny import TINY_TOML

from _procs import assert_refused, child_env, held_by_another_process
from floorsim.bench.bench import render_cached
from floorsim.bench.results import read_results_csv
from floorsim.bench.sweep import load_sweep, run_sweep_job
from floorsim.cli import main as floorsim_main
from floorvo.camera import CameraModel
from floorvo.locking import LOCK_FILE
from floorvo.runfolder import RunFolder
from floorvo.synthetic import line_poses, write_synthetic_sequence
from floorvo.tum import read_tum

FRAMES = 13
#: Columns of results.csv that differ between two identical runs (clocks, memory) or name the output folder.
VOLATILE = ("wall_ms_per_frame", "peak_rss_mb", "fps", "run_dir")


def _cli(prog: str, *args: str) -> list[str]:
    code = f"import sys; from {prog}.cli import main; sys.exit(main(sys.argv[1:]))"
    return [sys.executable, "-c", code, "-q", *map(str, args)]


def _run(cmd: list[str], timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=child_env())


def _start(cmd: list[str]) -> subprocess.Popen:
    """A child in its own process group (killed as a whole, as a crash would)."""
    return subprocess.Popen(
        cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=child_env(), start_new_session=True
    )


def _wait_for(path: Path, proc: subprocess.Popen, timeout: float = 180) -> None:
    deadline = time.monotonic() + timeout
    while not path.exists():
        assert proc.poll() is None, f"ended before {path} appeared: {proc.stderr.read() if proc.stderr else ''}"
        assert time.monotonic() < deadline, f"{path} did not appear"
        time.sleep(0.005)


def _kill_after(cmd: list[str], delay_s: float) -> bool:
    """Run ``cmd`` and SIGKILL its process group after ``delay_s``; True if it was killed (not done)."""
    p = _start(cmd)
    try:
        p.wait(delay_s)
        return False
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        p.wait()
        return True


def _kill_mid_render(cmd: list[str], out: Path, n_frames: int, frame_fraction: float) -> bool:
    """Run the render ``cmd`` into ``out``; once ``n_frames`` frames are on disk, wait ``frame_fraction``
    of the time the last frame took (when this process rendered two or more), then SIGKILL its process
    group. True if it was killed (not done).

    Killing on the render's own progress, not at a fraction of a reference run's wall time, keeps the
    kill inside the render whatever the machine's load or the tile cache's state (a warm cache makes
    a render seconds shorter than the reference that filled it)."""

    def on_disk() -> int:
        return len(list((out / "cam0").glob("*.png"))) if (out / "cam0").is_dir() else 0

    seen, stamps = on_disk(), list[float]()
    p = _start(cmd)
    try:
        while seen < n_frames:
            if p.poll() is not None:
                return False
            if (count := on_disk()) > seen:
                seen = count
                stamps.append(time.monotonic())
            time.sleep(0.002)
        p.wait(frame_fraction * (stamps[-1] - stamps[-2]) if len(stamps) > 1 else 0.0)
        return False
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        p.wait()
        return True


def _files(root: Path) -> dict[str, bytes]:
    """Every file under ``root`` (a lock file or a temporary left behind too) by relative path."""
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def _all_readable(root: Path, killed: bool = False) -> None:
    """Every file a killed or failed writer left under its name is whole: frames decode, JSON
    parses, TUM reads. A failed writer leaves no temporary; a killed one may (``killed``)."""
    for p in root.rglob("*"):
        if not p.is_file():
            continue
        if p.name.endswith(".tmp"):
            assert killed, p
            continue
        if p.suffix == ".png":
            assert cv2.imdecode(np.fromfile(p, np.uint8), cv2.IMREAD_UNCHANGED) is not None, p
        elif p.suffix == ".json":
            json.loads(p.read_text())
        elif p.name in ("groundtruth.txt", "trajectory.txt"):
            read_tum(p, allow_empty=True)
        elif p.suffix == ".csv":
            list(csv.reader(p.open()))


def _rows(results_csv: Path, out: Path) -> list[dict]:
    """results.csv's rows without the columns that differ between identical runs, paths relative to ``out``."""
    rows = []
    for r in read_results_csv(results_csv):
        rows.append(
            {
                k: (v.replace(str(out), "OUT") if isinstance(v, str) else "nan" if v != v else v)
                for k, v in r.items()
                if k not in VOLATILE and not k.startswith("time_")
            }
        )
    return rows


def _assert_same_rows(got: list[dict], want: list[dict]) -> None:
    """The same rows in the same order; the message lists the cells that differ."""
    diff = [
        (i, k, r.get(k), w.get(k)) for i, (r, w) in enumerate(zip(got, want)) for k in {*r, *w} if r.get(k) != w.get(k)
    ]
    assert len(got) == len(want) and not diff, (len(got), len(want), diff)


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("scene")
    (d / "tiny.toml").write_text(TINY_TOML)
    return d / "tiny.toml"


@pytest.fixture(scope="module")
def reference(tiny, tmp_path_factory):
    """An uninterrupted render of seed 1: (files, wall seconds)."""
    out = tmp_path_factory.mktemp("ref") / "seq"
    t0 = time.monotonic()
    r = _run(_cli("floorsim", "render", tiny, "--seed", 1, "-o", out))
    assert r.returncode == 0, r.stderr
    return _files(out), time.monotonic() - t0


@pytest.fixture(scope="module")
def sequences(tmp_path_factory) -> Path:
    """Four synthetic 11-frame sequences q0..q3 (quarter size) for sweeps of sequence folders."""
    d = tmp_path_factory.mktemp("seqs")
    cam = CameraModel.from_sensor().scaled(0.25)
    for k in range(4):
        write_synthetic_sequence(d / f"q{k}", cam, line_poses(20.0, 2.0), seed=k)
    return d


def _sweep_file(folder: Path, name: str, seqs: list[str]) -> Path:
    p = folder / f"{name}.toml"
    p.write_text(f'name = "{name}"\nestimators = ["phase-corr"]\nsequences = {json.dumps(seqs)}\n')
    return p


@pytest.fixture(scope="module")
def sweep_reference(sequences, tmp_path_factory):
    """An uninterrupted sweep of q0..q3 with phase-corr: (study file, output folder, wall seconds)."""
    study = _sweep_file(sequences, "all", ["q0", "q1", "q2", "q3"])
    ref = tmp_path_factory.mktemp("sweep") / "ref"
    t0 = time.monotonic()
    r = _run(_cli("floorsim", "sweep", study, "-o", ref))
    assert r.returncode == 0, r.stderr
    return study, ref, time.monotonic() - t0


# ----------------------------------------------------------------------------- two writers, one folder
@pytest.mark.render
def test_two_renders_into_one_folder_one_is_refused_and_nothing_is_mixed(tiny, reference, tmp_path):
    """Issue 16 item 1: a second render (another seed, --overwrite) while the first renders was
    accepted: it deleted the first's frames, and the first went on writing its seed's frames
    beside the second's sequence.json; both exited 0."""
    out = tmp_path / "seq"
    first = _start(_cli("floorsim", "render", tiny, "--seed", 1, "-o", out))
    try:
        _wait_for(out / "cam0" / "000000.png", first)
        os.kill(first.pid, signal.SIGSTOP)
        assert not (out / "cam0" / f"{FRAMES - 1:06d}.png").exists(), "the first render finished too soon"
        second = _run(_cli("floorsim", "render", tiny, "--seed", 2, "--overwrite", "-o", out))
    finally:
        os.kill(first.pid, signal.SIGCONT)
    assert first.wait(timeout=300) == 0, first.stderr.read() if first.stderr else ""
    assert second.returncode == 1
    assert_refused(second.stderr.strip().splitlines()[-1], out, first.pid, "sequence folder")
    assert _files(out) == reference[0]  # the first render's bytes, nothing of seed 2


def test_two_sweeps_into_one_folder_one_is_refused_and_the_rows_are_the_first_ones(
    sequences, sweep_reference, tmp_path
):
    """Issue 16 item 1: two sweeps into one folder both exited 0, and results.csv held only the
    second's rows."""
    first_file, ref, _ = sweep_reference
    second_file = _sweep_file(sequences, "second", ["q3"])
    out = tmp_path / "out"
    first = _start(_cli("floorsim", "sweep", first_file, "-o", out))
    try:
        _wait_for(out / "study.json", first)
        os.kill(first.pid, signal.SIGSTOP)
        second = _run(_cli("floorsim", "sweep", second_file, "-o", out))
    finally:
        os.kill(first.pid, signal.SIGCONT)
    assert first.wait(timeout=300) == 0, first.stderr.read() if first.stderr else ""
    assert second.returncode == 1
    assert_refused(second.stderr.strip().splitlines()[-1], out, first.pid, "sweep folder")
    _assert_same_rows(
        sorted(_rows(out / "results.csv", out), key=str), sorted(_rows(ref / "results.csv", ref), key=str)
    )
    assert 'name = "all"' in (out / "study.toml").read_text()


def test_every_floorsim_writer_is_refused_while_another_process_writes_its_folder(tmp_path, capsys):
    """floorsim render, bench and sweep (the bench and sweep on the test doubles) refuse a
    folder another process writes, before writing anything into it."""
    D.write_scene(tmp_path / "s.toml")
    (tmp_path / "sweep.toml").write_text(
        'base = "s.toml"\nestimators = ["scaled"]\n[vary]\n"lights.height_mm" = [1.0]\n'
    )
    commands = {
        "sequence folder": ["render", "demo", "--frames", "1", "--scale", "0.1"],
        "bench folder": ["bench", str(tmp_path / "s.toml"), "--estimators", "scaled", "--no-report"],
        "sweep folder": ["sweep", str(tmp_path / "sweep.toml"), "--workers", "1"],
    }
    for what, args in commands.items():
        out = tmp_path / what.replace(" ", "-")
        with held_by_another_process(out) as holder:
            assert floorsim_main([*args, "-o", str(out)], collaborators=D.COLLABORATORS) == 1
            assert_refused(capsys.readouterr().err.strip().splitlines()[-1], out, holder.pid, what)
            assert [p.name for p in out.iterdir()] == [LOCK_FILE]


def test_a_sweep_job_refused_a_run_folder_says_so_in_its_row(tmp_path):
    """A sweep worker locks each run folder it writes: one another process holds gives a failed
    row naming that process (the other estimators' rows are written)."""
    D.reset()
    D.write_scene(tmp_path / "s.toml")
    study = tmp_path / "sweep.toml"
    study.write_text('base = "s.toml"\nestimators = ["scaled", "lossy"]\n[vary]\n"lights.height_mm" = [1.0]\n')
    spec = load_sweep(study)
    job = {"job": "lights.height_mm=1.0;rep=0", "params": {"lights.height_mm": 1.0}, "repetition": 0}
    out = tmp_path / "out"
    with held_by_another_process(out / "runs" / "lights.height_mm=1.0_rep=0" / "lossy") as holder:
        rows = run_sweep_job(job, spec, str(out), str(out / "sequences"), D.render, D.load_scene, D.FakeRunner())
    by = {r["estimator"]: r for r in rows}
    assert by["scaled"]["status"] == "ok"
    assert by["lossy"]["status"].startswith("failed: ") and f"(pid {holder.pid})" in by["lossy"]["status"]


def test_the_render_cache_waits_for_another_process_rendering_the_same_sequence(tmp_path):
    """Benches and sweep jobs share the render cache: a process wanting a sequence that another
    process is rendering waits for it and reuses its render (neither refused nor rendering twice)."""
    D.reset()
    scene = D.load_scene(D.write_scene(tmp_path / "s.toml"))
    seq = render_cached(scene, tmp_path / "cache", render=D.render)
    marker = seq / "bench-cache.json"
    done = marker.read_bytes()
    marker.unlink()  # as if that render were still under way, in another process that ends in 1 s
    with held_by_another_process(seq) as holder:

        def finish() -> None:
            marker.write_bytes(done)
            assert holder.stdin is not None
            holder.stdin.close()

        threading.Timer(1.0, finish).start()
        t0 = time.monotonic()
        assert render_cached(scene, tmp_path / "cache", render=D.render) == seq
        assert time.monotonic() - t0 >= 0.9 and holder.wait(timeout=20) == 0
    assert D.RENDER_CALLS == [str(seq)]  # rendered once, by the first


# ----------------------------------------------------------------------------- kill -9 and resume
#: Seed of the moments at which the fault tests kill and of the file at which the disk fills up.
FAULT_SEED = 16


@pytest.mark.render
@pytest.mark.parametrize("kills", [1, pytest.param(4, marks=pytest.mark.slow)])
def test_a_render_killed_at_random_moments_resumes_to_the_bytes_of_an_uninterrupted_one(
    kills, tiny, reference, tmp_path
):
    files, _ = reference
    n_frames = sum(1 for name in files if name.startswith("cam0/") and name.endswith(".png"))
    out = tmp_path / "seq"
    cmd = _cli("floorsim", "render", tiny, "--seed", 1, "-o", out)
    rng = np.random.default_rng(FAULT_SEED)
    # Random moments of the render: after seeded numbers of frames on disk (increasing: a resumed render
    # skips the frames it finds, and at least two are left to render), a seeded part of a frame's time later.
    for at in sorted(rng.choice(np.arange(1, n_frames - 1), size=kills, replace=False)):
        assert _kill_mid_render(cmd, out, int(at), float(rng.uniform(0.0, 0.9))), (
            "the render ended before it was killed"
        )
        if out.exists():
            _all_readable(out, killed=True)
    r = _run(cmd)
    assert r.returncode == 0, r.stderr
    assert _files(out) == files


@pytest.fixture(scope="module")
def long_seq(tmp_path_factory) -> Path:
    """A 121-frame synthetic sequence (quarter size) and a completed phase-corr run of it: (seq, run, wall s)."""
    d = tmp_path_factory.mktemp("long")
    write_synthetic_sequence(d / "seq", CameraModel.from_sensor().scaled(0.25), line_poses(240.0, 2.0), seed=5)
    return d / "seq"


def _result(run: Path) -> dict:
    """result.json without what differs between identical runs (speed, the folder's name)."""
    res = json.loads((run / "result.json").read_text())
    return {k: v for k, v in res.items() if k not in ("fps", "median_total_ms", "run_dir")}


@pytest.mark.parametrize("kills", [1, pytest.param(6, marks=pytest.mark.slow)])
def test_a_run_killed_at_random_moments_leaves_one_whole_run_and_reruns_to_the_same_bytes(kills, long_seq, tmp_path):
    """The folder holds an older run (another config) when a new run is killed: at every moment it
    holds the old run or the new one, whole, or (killed while writing) no ``result.json``: never the
    trajectory of one run beside the summary of the other."""
    ref = tmp_path / "ref"
    t0 = time.monotonic()
    assert _run(_cli("floorvo", "run", long_seq, "-e", "phase-corr", "-o", ref)).returncode == 0
    wall_s = time.monotonic() - t0
    out = tmp_path / "run"
    older = ["run", long_seq, "-e", "phase-corr", "--set", "grid=3", "-o", out]
    assert _run(_cli("floorvo", *older)).returncode == 0
    old_traj = (out / "trajectory.txt").read_bytes()
    assert old_traj != (ref / "trajectory.txt").read_bytes()
    cmd = _cli("floorvo", "run", long_seq, "-e", "phase-corr", "-o", out)
    for frac in np.random.default_rng(FAULT_SEED).uniform(0.3, 1.0, size=kills):
        _kill_after(cmd, frac * wall_s)
        _all_readable(out, killed=True)
        run = RunFolder.read(out)
        if not run.result:  # killed while writing: no result.json, so no finished run is claimed
            continue
        grid = run.result["config"]["grid"]  # a summary, and the trajectory beside it is the same run's
        assert (out / "trajectory.txt").read_bytes() == (
            old_traj if grid == 3 else (ref / "trajectory.txt").read_bytes()
        )
    assert _run(cmd).returncode == 0
    assert (out / "trajectory.txt").read_bytes() == (ref / "trajectory.txt").read_bytes()
    assert _result(out) == _result(ref)


@pytest.mark.parametrize("kills", [1, pytest.param(3, marks=pytest.mark.slow)])
def test_a_sweep_killed_at_random_moments_resumes_to_the_rows_of_an_uninterrupted_one(kills, sweep_reference, tmp_path):
    """Its local workers, killed with it, leave lock files in the folders they wrote; the
    resumed sweep takes them over, skips the jobs in results.csv, and each job has one row."""
    study, ref, wall_s = sweep_reference
    out = tmp_path / "out"
    cmd = _cli("floorsim", "sweep", study, "-o", out)
    for frac in np.random.default_rng(FAULT_SEED).uniform(0.3, 0.9, size=kills):
        _kill_after(cmd, frac * wall_s)
        if out.exists():
            _all_readable(out, killed=True)
    r = _run(cmd)
    assert r.returncode == 0, r.stderr
    _assert_same_rows(
        sorted(_rows(out / "results.csv", out), key=str), sorted(_rows(ref / "results.csv", ref), key=str)
    )
    for k in range(4):
        run = Path("runs") / f"sequence=q{k}" / "phase-corr" / "trajectory.txt"
        assert (out / run).read_bytes() == (ref / run).read_bytes()
    assert not list(out.rglob(LOCK_FILE)) and not list(out.rglob("*.tmp"))


@pytest.mark.slow
@pytest.mark.render
def test_a_bench_killed_at_random_moments_resumes_to_the_results_of_an_uninterrupted_one(tiny, tmp_path):
    """Render, run and score, killed three times: the rows, sequences and trajectories of an uninterrupted bench."""
    ref = tmp_path / "ref"
    args = ["bench", tiny, "--estimators", "phase-corr,akaze-guided", "--frames", 8, "--no-report"]
    t0 = time.monotonic()
    assert _run(_cli("floorsim", *args, "-o", ref)).returncode == 0
    wall_s = time.monotonic() - t0
    out = tmp_path / "out"
    cmd = _cli("floorsim", *args, "-o", out)
    for frac in np.random.default_rng(FAULT_SEED).uniform(0.2, 0.95, size=3):
        _kill_after(cmd, frac * wall_s)
        if out.exists():
            _all_readable(out, killed=True)
    r = _run(cmd)
    assert r.returncode == 0, r.stderr
    _assert_same_rows(_rows(out / "results.csv", out), _rows(ref / "results.csv", ref))
    want = {k: v for k, v in _files(ref).items() if k.endswith((".png", "trajectory.txt", "groundtruth.txt"))}
    assert {k: v for k, v in _files(out).items() if k in want} == want


# ----------------------------------------------------------------------------- a full disk
def _disk_fills_after(monkeypatch, n_files: int) -> None:
    """``os.fsync`` (every atomic write's) fails with ENOSPC after ``n_files`` calls, as a full disk would."""
    real, calls = os.fsync, [0]

    def fsync(fd: int) -> None:
        calls[0] += 1
        if calls[0] > n_files:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        real(fd)

    monkeypatch.setattr(os, "fsync", fsync)


def _one_line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err.strip()


@pytest.mark.render
def test_a_full_disk_stops_a_render_in_one_line_and_the_same_command_completes_it(
    tiny, reference, tmp_path, monkeypatch, capsys
):
    out = tmp_path / "seq"
    n_files = int(np.random.default_rng(FAULT_SEED).integers(4, FRAMES))
    _disk_fills_after(monkeypatch, n_files)
    cmd = ["-q", "render", str(tiny), "--seed", "1", "-o", str(out)]
    assert floorsim_main(cmd) == 1
    # sequence.json, groundtruth.txt and calib/sensor.json, then the frames in order
    failed = out / "cam0" / f"{n_files - 3:06d}.png"
    assert _one_line(capsys) == f"floorsim: error: {failed}: No space left on device (errno 28)"
    _all_readable(out)
    assert len(list((out / "cam0").glob("*.png"))) == n_files - 3
    assert not (out / LOCK_FILE).exists()
    monkeypatch.undo()  # space again
    assert floorsim_main(cmd) == 0
    assert _files(out) == reference[0]


def test_a_full_disk_stops_a_sweep_in_one_line_and_the_same_command_completes_it(tmp_path, monkeypatch, capsys):
    """The sweep's main process writes results.csv after every job; when the disk fills up it
    stops with one line, results.csv keeps the rows of the jobs before, and the same command
    runs the others (each job once)."""
    D.reset()
    D.write_scene(tmp_path / "s.toml")
    study = tmp_path / "sweep.toml"
    study.write_text(
        'base = "s.toml"\nestimators = ["scaled", "lossy"]\n[vary]\n"lights.height_mm" = [1.0, 2.0, 3.0, 4.0]\n'
    )
    out = tmp_path / "out"
    n_files = 2 + int(np.random.default_rng(FAULT_SEED).integers(1, 4))  # study.toml, study.json, then results.csv
    _disk_fills_after(monkeypatch, n_files)
    cmd = ["-q", "sweep", str(study), "-o", str(out)]
    assert floorsim_main(cmd, collaborators=D.COLLABORATORS) == 1
    assert _one_line(capsys) == f"floorsim: error: {out / 'results.csv'}: No space left on device (errno 28)"
    _all_readable(out)
    before = read_results_csv(out / "results.csv")
    assert len(before) == 2 * (n_files - 2)  # the two rows of each job finished before the disk filled up
    monkeypatch.undo()
    assert floorsim_main(cmd, collaborators=D.COLLABORATORS) == 0
    rows = read_results_csv(out / "results.csv")
    assert rows[: len(before)] == before
    assert sorted((r["lights.height_mm"], r["estimator"], r["status"]) for r in rows) == [
        (h, e, "ok") for h in (1.0, 2.0, 3.0, 4.0) for e in ("lossy", "scaled")
    ]
    scaled = {r["lights.height_mm"]: r["end_drift_pct"] for r in rows if r["estimator"] == "scaled"}
    assert scaled == pytest.approx({h: 0.1 * h for h in (1.0, 2.0, 3.0, 4.0)}, rel=1e-4)  # 0.1 % per mm of LED height

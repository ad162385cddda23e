"""Estimators from outside the project: an installed entry-point plugin (the shipped example
package, built and installed by pip into a temporary folder), a broken plugin, and a
``module:Class`` reference imported without installing."""

from __future__ import annotations

import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from floorvo.camera import CameraModel
from floorvo.cli import main as floorvo_main
from floorvo.errors import EstimatorLoadError
from floorvo.estimators import (
    BUILTIN_ESTIMATORS,
    estimator_source,
    get_estimator,
    list_estimators,
    make_config,
    unavailable_estimators,
)
from floorvo.estimators.registry import refresh_plugins
from floorvo.external import command_hash
from floorvo.scoring import score_run
from floorvo.synthetic import line_poses, write_synthetic_sequence
from floorvo.tum import read_tum

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "plugin-estimator"
PLUGIN = "example-fft-shift"
CAM = CameraModel.from_sensor(160, 120, 29.6, 6.0)


def _install(source: Path, target: Path) -> None:
    """``pip install`` a package into ``target`` (offline, into a folder put on sys.path)."""
    r = subprocess.run(
        [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation", "--no-index"]
        + ["--target", str(target), str(source)],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr[-2000:]


@pytest.fixture(scope="module")
def installed_plugin(tmp_path_factory):
    """The example plugin package, pip-installed into a temporary folder on sys.path (a copy of
    the source is built, so the build leaves nothing in the repository)."""
    tmp = tmp_path_factory.mktemp("plugin")
    src = shutil.copytree(EXAMPLE, tmp / "src", ignore=shutil.ignore_patterns("build", "*.egg-info"))
    _install(src, tmp / "site")
    sys.path.insert(0, str(tmp / "site"))
    refresh_plugins()
    yield tmp / "site"
    sys.path.remove(str(tmp / "site"))
    for mod in [m for m in sys.modules if m.startswith("floorbench_example_plugin")]:
        del sys.modules[mod]
    refresh_plugins()


@pytest.fixture(scope="module")
def line_sequence(tmp_path_factory):
    """A synthetic sequence: 20 mm along x in 1.5 mm steps, with ground truth."""
    return write_synthetic_sequence(tmp_path_factory.mktemp("seq") / "line", CAM, line_poses(20.0, 1.5), seed=3)


def test_installed_plugin_is_listed_with_its_package_and_runs(installed_plugin, line_sequence, tmp_path, capsys):
    assert PLUGIN in list_estimators()
    src = estimator_source(PLUGIN)
    assert (src.kind, src.package, src.version) == ("plugin", "floorbench-example-plugin", "0.1.0")
    assert src.row() == {"source": "plugin", "source_detail": "floorbench-example-plugin 0.1.0"}
    cls = get_estimator(PLUGIN)
    assert cls.__module__ == "floorbench_example_plugin.fft_shift"
    assert Path(sys.modules[cls.__module__].__file__).is_relative_to(installed_plugin)
    # --set works on the plugin's config through the one config mechanism
    assert make_config(PLUGIN, {"min_peak": "0.1"}).min_peak == 0.1
    with pytest.raises(Exception, match=r"example-fft-shift\.min_peak = 2\.0: must be < 1"):
        make_config(PLUGIN, {"min_peak": "2"})

    assert floorvo_main(["list"]) == 0
    out = capsys.readouterr().out
    assert f"{PLUGIN} " in out and "(plugin floorbench-example-plugin 0.1.0)" in out

    run = tmp_path / "run"
    assert floorvo_main(["run", str(line_sequence), "-e", PLUGIN, "-o", str(run)]) == 0
    t, T = read_tum(run / "trajectory.txt")
    t_gt, T_gt = read_tum(line_sequence / "groundtruth.txt")
    assert len(t) == len(t_gt)
    # 20 mm travelled along x; the plugin's whole-frame correlation ends within 0.3 mm of the truth
    assert abs(T[-1, 0, 3] - T_gt[-1, 0, 3]) < 0.3
    assert score_run(run, line_sequence).flat()["ate_none_rmse_mm"] < 0.2


def test_a_broken_plugin_is_listed_unavailable_and_breaks_nothing(line_sequence, tmp_path, monkeypatch, capsys):
    site = tmp_path / "site"
    info = site / "broken_plugin-1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: broken-plugin\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text(
        "[floorvo.estimators]\n"
        "broken-est = no_such_module_for_floorvo_tests:Estimator\n"
        "not-an-estimator = json:JSONDecoder\n"
        "phase-corr = no_such_module_for_floorvo_tests:PhaseCorr\n"
        "exits = exits_on_import_for_floorvo_tests:Estimator\n"
    )
    # a module that ends the process on import (one that parses sys.argv when imported): it ended
    # `floorvo list` with its message and no list
    (site / "exits_on_import_for_floorvo_tests.py").write_text("import sys\nsys.exit('parses sys.argv on import')\n")
    monkeypatch.syspath_prepend(str(site))
    refresh_plugins()
    try:
        assert set(BUILTIN_ESTIMATORS) <= set(list_estimators())
        assert not {"broken-est", "not-an-estimator"} & set(list_estimators())
        reasons = unavailable_estimators()
        assert reasons["broken-est"] == "ModuleNotFoundError: No module named 'no_such_module_for_floorvo_tests'"
        assert reasons["not-an-estimator"] == "TypeError: estimator 'JSONDecoder' lacks 'name'"
        assert "named like a built-in" in reasons["phase-corr"]
        assert reasons["exits"] == "SystemExit: parses sys.argv on import"
        assert estimator_source("phase-corr").kind == "built-in"  # the built-in keeps its name
        with pytest.raises(
            EstimatorLoadError,
            match=r"^estimator 'broken-est' \(plugin no_such_module_for_floorvo_tests:Estimator\) is unavailable: Module",
        ):
            get_estimator("broken-est")
        assert floorvo_main(["list"]) == 0
        out = capsys.readouterr().out.splitlines()
        assert any(line.startswith("phase-corr ") and "unavailable" not in line for line in out)
        assert any(line.split()[:2] == ["broken-est", "unavailable:"] for line in out)
        # --config of such a plugin says why, not 'no such configuration'
        assert floorvo_main(["list", "--config", "broken-est"]) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert err == [
            "floorvo: error: --config 'broken-est': the plugin is unavailable: ModuleNotFoundError: "
            "No module named 'no_such_module_for_floorvo_tests'"
        ], err
        # a run with the broken plugin is one line and exit code 1, not a traceback
        assert floorvo_main(["run", str(line_sequence), "-e", "broken-est", "-o", str(tmp_path / "r")]) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "unavailable: ModuleNotFoundError" in err[0]
    finally:
        monkeypatch.undo()
        refresh_plugins()
    assert "broken-est" not in unavailable_estimators()


MODULE_SOURCE = '''
import numpy as np
from dataclasses import dataclass
from floorvo.estimators.base import StepResult

@dataclass(frozen=True)
class Config:
    step_mm: float = 1.5

class Dead:
    """Dead reckoning: every frame a fixed step along the camera's x axis."""
    name = "dead-reckoning"
    description = "a fixed step per frame"
    Config = Config
    requires = frozenset()
    def __init__(self, config, camera, *, height_mm, flatfield=None, **rig):
        self.config = config
    def start(self):
        return {"n": 0}
    def step(self, state, frame):
        state["n"] += 1
        if state["n"] == 1:
            return StepResult("init")
        T = np.eye(4)
        T[0, 3] = self.config.step_mm
        return StepResult("ok", T)
'''


def test_module_class_reference_runs_without_installing(line_sequence, tmp_path, monkeypatch, capsys):
    (tmp_path / "my_vo_for_tests.py").write_text(MODULE_SOURCE)
    monkeypatch.syspath_prepend(str(tmp_path))
    ref = "my_vo_for_tests:Dead"
    assert estimator_source(ref).row() == {"source": "module", "source_detail": ref}
    assert ref not in list_estimators()  # a reference is used, not listed
    run = tmp_path / "run"
    assert floorvo_main(["run", str(line_sequence), "-e", ref, "-o", str(run), "--set", "step_mm=1.5"]) == 0
    _, T = read_tum(run / "trajectory.txt")
    _, T_gt = read_tum(line_sequence / "groundtruth.txt")
    np.testing.assert_allclose(T[:, :3, 3], T_gt[:, :3, 3], atol=1e-6)  # the line's steps are 1.5 mm
    # the bench runs a reference too, --est-set reaching its config (the dots before the colon are the module's)
    from floorsim.bench import run_bench
    from floorsim.commands.bench import parse_estimator_sets

    over = parse_estimator_sets([f"{ref}.step_mm=3.0"])
    assert over == {ref: {"step_mm": "3.0"}}
    res = run_bench([line_sequence], [ref], tmp_path / "bench", estimator_overrides=over, report=False)
    (row,) = res.rows
    assert row["status"] == "ok" and (row["source"], row["source_detail"]) == ("module", ref)
    assert row["measured_mm"] == pytest.approx(2 * 19.5)  # 13 steps of 3 mm instead of 1.5 mm
    capsys.readouterr()
    assert floorvo_main(["run", str(line_sequence), "-e", "my_vo_for_tests:Nope", "-o", str(run)]) == 1
    err = capsys.readouterr().err
    assert "cannot be imported: AttributeError" in err and len(err.strip().splitlines()) == 1


FAULTY_SOURCE = (
    MODULE_SOURCE
    + """
class RaisesInInit(Dead):
    def __init__(self, *args, **kwargs):
        raise RuntimeError("no licence file")

class RaisesInStep(Dead):
    def step(self, state, frame):
        raise ZeroDivisionError("division by zero")

class Scales(Dead):
    def step(self, state, frame):
        res = super().step(state, frame)
        return StepResult("ok", np.diag([2.0, 2.0, 1.0, 1.0])) if res.ok else res

class Exits(Dead):
    def step(self, state, frame):
        import sys
        sys.exit(5)

class NoModelFile(Dead):
    def step(self, state, frame):
        return open("/nonexistent-floorbench-test/model.bin", "rb")

class FarAway(Dead):
    def step(self, state, frame):
        res = super().step(state, frame)
        if res.ok:
            res.T_prev_cur[0, 3] = 1e11  # 1e8 m a step: finite, each step within the bound, the chain not
        return res

class Complex(Dead):
    def step(self, state, frame):
        res = super().step(state, frame)
        return StepResult("ok", res.T_prev_cur + 1e-3j) if res.ok else res
"""
)


@pytest.mark.parametrize(
    "cls, message",
    [
        ("RaisesInInit", "__init__ raised RuntimeError: no licence file"),
        ("RaisesInStep", "the run raised ZeroDivisionError: division by zero"),
        ("Scales", "frame 1: T_prev_cur is not a rigid transform"),
        ("Exits", "the run raised SystemExit: 5"),
        (
            "NoModelFile",
            "the run raised FileNotFoundError: [Errno 2] No such file or directory: '/nonexistent-floorbench",
        ),
        ("FarAway", "frame 2: its steps place the camera at a position 2e+08 m from the origin (at most 1e+08 m"),
        ("Complex", "frame 1: T_prev_cur is not a rigid transform (complex numbers"),
    ],
)
def test_a_module_class_that_raises_is_one_line_and_a_failed_bench_row(
    cls, message, line_sequence, tmp_path, monkeypatch, capsys
):
    """A plugin's own exception (in __init__ or step, or a step breaking the protocol) was a
    traceback from inside the plugin and, in the bench, ended the whole bench; now it is one
    line naming the estimator, exit code 1, and a failed row as for a crashing program. So are
    its sys.exit (floorvo ended with the plugin's code and no word, the bench with it), an
    OSError of its own (told without the estimator's name, and the bench ended), steps that
    chain beyond the positions a pose file holds (a traceback from the trajectory's writer
    after the run) and a complex step (its imaginary part dropped with a warning)."""
    (tmp_path / "faulty_vo_for_tests.py").write_text(FAULTY_SOURCE)
    monkeypatch.syspath_prepend(str(tmp_path))
    ref = f"faulty_vo_for_tests:{cls}"
    assert floorvo_main(["run", str(line_sequence), "-e", ref, "-o", str(tmp_path / "run")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"estimator {ref!r} (module {ref})" in err[0] and message in err[0], err
    from floorsim.bench import run_bench

    res = run_bench([line_sequence], [ref, "phase-corr"], tmp_path / "bench", report=False)
    rows = {r["estimator"]: r for r in res.rows}
    assert rows[ref]["status"].startswith("failed: ") and message in rows[ref]["status"]
    assert rows["phase-corr"]["status"] == "ok"


@pytest.mark.parametrize("requires", ['frozenset({"depht"})', '"depth"'])
def test_a_requirement_not_understood_is_refused_not_ignored(line_sequence, tmp_path, monkeypatch, capsys, requires):
    """requires = {'depht'} (a typo), or "depth" as a string (its letters), was not understood and
    the estimator ran on a mono sequence without depth, exit 0."""
    (tmp_path / "needy_vo_for_tests.py").write_text(
        MODULE_SOURCE + f"\nclass Needy(Dead):\n    requires = {requires}\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    assert floorvo_main(["run", str(line_sequence), "-e", "needy_vo_for_tests:Needy", "-o", str(tmp_path / "r")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "requires = " in err[0] and "must be a set of depth, stereo" in err[0], err


def test_a_config_that_is_not_a_dataclass_is_refused_when_loaded(line_sequence, tmp_path, monkeypatch, capsys):
    """Config = dict ended in 'TypeError: must be called with a dataclass type or instance' from inside."""
    (tmp_path / "dict_vo_for_tests.py").write_text(MODULE_SOURCE + "\nclass DictConfig(Dead):\n    Config = dict\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    argv = ["run", str(line_sequence), "-e", "dict_vo_for_tests:DictConfig", "-o", str(tmp_path / "r")]
    assert floorvo_main(argv) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Config = <class 'dict'> must be a dataclass" in err[0], err


EXTERNAL = Path(__file__).resolve().parents[2] / "examples" / "external-estimator"


def test_bench_runs_a_plugin_an_external_program_and_a_built_in_on_recordings(
    installed_plugin, line_sequence, tmp_path
):
    """One bench over two sequence folders (one without ground truth): the plugin, the shipped
    external program, a built-in, and an external program that crashes; then the gate."""
    from floorsim.bench import run_bench
    from floorsim.bench.gates import compare, load_baseline
    from floorsim.bench.results import read_results_csv
    from floorvo.external import load_estimator_file, parse_external
    from floorvo.run import InitialPose

    # the recording: the frames as a folder of images with irregular frame times and the camera
    # in OpenCV YAML, imported with `floorvo import` (no ground truth)
    frames = tmp_path / "frames"
    frames.mkdir()
    for i, f in enumerate(sorted((line_sequence / "cam0").glob("*.png"))):
        shutil.copy(f, frames / f"img_{i + 1}.png")  # natural order: img_2 before img_10
    times = 100.0 + 0.05 * np.arange(14) + 0.01 * (np.arange(14) % 3)
    (tmp_path / "times.txt").write_text("".join(f"{t:.6f}\n" for t in times))
    (tmp_path / "camera.yaml").write_text(CAM.to_opencv_yaml())
    no_gt = tmp_path / "recording"
    argv = ["import", str(frames), "-o", str(no_gt), "--camera", str(tmp_path / "camera.yaml")]
    assert floorvo_main([*argv, "--height-mm", "100", "--timestamps", str(tmp_path / "times.txt")]) == 0
    crash = parse_external(f"{shlex.quote(sys.executable)} -c 'import sys; sys.exit(\"no features\")'", "crashes")
    externals = [load_estimator_file(EXTERNAL / "fft-vo.toml"), crash]
    out = tmp_path / "bench"
    res = run_bench(
        [line_sequence, no_gt],
        [PLUGIN, "phase-corr"],
        out,
        externals=externals,
        initial_pose=InitialPose.parse("5,0,0"),
        save_baseline_to=tmp_path / "baseline.json",
    )
    rows = {(r["scene"], r["estimator"]): r for r in read_results_csv(out / "results.csv")}
    names = {PLUGIN, "phase-corr", "fft-vo", "crashes"}
    assert set(rows) == {(s, n) for s in ("line", "recording") for n in names}
    for scene in ("line", "recording"):
        got = {n: (rows[scene, n]["source"], rows[scene, n]["source_detail"]) for n in names}
        assert got[PLUGIN] == ("plugin", "floorbench-example-plugin 0.1.0")
        assert got["phase-corr"][0] == "built-in" and got["phase-corr"][1].startswith("floorbench ")
        assert got["fft-vo"] == ("external", "sha256:" + command_hash(externals[0].command)[:12])
        # the crash is a failed row with its reason and stderr; the others complete
        bad = rows[scene, "crashes"]
        assert bad["status"] == "failed: exit code 1" and bad["stderr_tail"] == "no features"
        for n in names - {"crashes"}:
            r = rows[scene, n]
            assert r["status"] == "ok", r["status"]
            assert r["wall_ms_per_frame"] > 0 and r["peak_rss_mb"] > 10
            assert r["tracked_fraction"] == 1.0
    for n in names - {"crashes"}:
        # with ground truth: accurate to a fraction of a millimetre over the 19.5 mm line
        assert rows["line", n]["ground_truth"] == "ok" and rows["line", n]["ate_se2_rmse_mm"] < 0.2
        # without: tracking and timing only, and the run starts at --initial-pose
        assert rows["recording", n]["ground_truth"] == "no ground truth"
        assert rows["recording", n].get("ate_se2_rmse_mm") is None
        t, T = read_tum(Path(rows["recording", n]["run_dir"]) / "trajectory.txt")
        assert T[0, 0, 3] == pytest.approx(5.0) and T[0, 2, 3] == pytest.approx(100.0)
        np.testing.assert_allclose(t, times, atol=1e-6)  # stamped with the recording's own frame times
    page = res.report_html.read_text()
    assert "Estimators compared" in page and "no ground truth" in page and "Failed runs" in page
    assert "accuracy (ATE after SE(2) alignment) against wall time per frame" in page
    assert "recording: estimated (dots) trajectories (the sequence has no ground truth)" in page
    # the gate works on all three sources: the same rows pass, a tighter baseline fails each
    baseline = load_baseline(tmp_path / "baseline.json")
    assert compare(res.rows, baseline).ok
    for key in [f"line/{n}" for n in names - {"crashes"}]:
        baseline.entries[key]["ate_se2_rmse_mm"] = -1.0  # allowed: -1 + max(abs, rel * 1) < 0
    worse = {r.key for r in compare(res.rows, baseline).regressions}
    assert worse == {f"line/{n}" for n in names - {"crashes"}}


@pytest.mark.parametrize("where", ["process pool", "dask processes"])
def test_a_sweep_of_sequence_folders_runs_the_plugin_in_worker_processes(
    installed_plugin, line_sequence, tmp_path, where
):
    """A sweep file of sequence folders alone (no grid): each job runs in another process (a
    spawned local worker, or a Dask worker process), where the plugin is found by its entry point."""
    from floorsim.bench.results import read_results_csv
    from floorsim.bench.sweep import load_sweep, run_sweep, sweep_jobs

    sweep = tmp_path / "recordings.toml"
    sweep.write_text(f'estimators = ["{PLUGIN}"]\nsequences = ["{line_sequence}"]\n')
    spec = load_sweep(sweep)
    assert spec.base is None and [j["job"] for j in sweep_jobs(spec)] == ["sequence=line"]
    kwargs = {"jobs": 1} if where == "process pool" else {"workers": 1, "processes": True}
    res = run_sweep(sweep, tmp_path / "out", **kwargs)
    assert res.errors == [] and res.ran == 1
    (row,) = read_results_csv(tmp_path / "out" / "results.csv")
    assert row["estimator"] == PLUGIN and row["status"] == "ok", row["status"]
    assert (row["source"], row["source_detail"]) == ("plugin", "floorbench-example-plugin 0.1.0")
    assert row["ate_se2_rmse_mm"] < 0.2
    assert "Estimators compared" in (tmp_path / "out" / "sweep.html").read_text()


SAMPLES_SOURCE = (
    MODULE_SOURCE
    + """
from dataclasses import replace

class PairsOfTwo(Dead):
    def step(self, state, frame):
        res = super().step(state, frame)
        return replace(res, matches_px=np.zeros((3, 2))) if res.ok else res  # not (N, 4)

class OnlyFromFrameZero(Dead):
    def start(self):
        return {"n": 0, "first": None}
    def step(self, state, frame):
        if state["first"] is None:
            state["first"] = frame.index
        if state["first"] != 0:
            raise KeyError("prev")
        res = super().step(state, frame)
        return replace(res, matches_px=np.zeros((5, 4))) if res.ok else res
"""
)


@pytest.mark.parametrize(
    "cls, words, written",
    [
        ("PairsOfTwo", "frame 1: matches_px has shape (3, 2), not (N, 4)", 0),
        ("OnlyFromFrameZero", "the match sample of frames 6-7 raised KeyError: 'prev'", 1),  # the pair 0-1 is kept
    ],
)
def test_a_plugin_failing_on_the_reports_match_samples_keeps_its_scored_row(
    cls, words, written, line_sequence, tmp_path, monkeypatch, caplog
):
    """The report's match samples run the estimator again on a few frame pairs. A plugin that
    raised there (it cannot start on a later frame) or gave matches of another shape ended the
    whole bench with a traceback after its run had been scored; now the samples stop with a
    warning and the row stays ok."""
    from floorsim.bench import run_bench
    from floorsim.bench.bench import write_match_samples

    (tmp_path / "samples_vo_for_tests.py").write_text(SAMPLES_SOURCE)
    monkeypatch.syspath_prepend(str(tmp_path))
    ref = f"samples_vo_for_tests:{cls}"
    with caplog.at_level("WARNING"):
        assert write_match_samples(line_sequence, ref, tmp_path / "samples") == written
    assert any(words in r.getMessage() and "no more match samples" in r.getMessage() for r in caplog.records)
    res = run_bench([line_sequence], [ref], tmp_path / "bench", report=True)
    (row,) = res.rows
    assert row["status"] == "ok" and row["measured_mm"] == pytest.approx(19.5)

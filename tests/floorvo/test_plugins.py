"""Estimators from outside the project: an installed entry-point plugin (the shipped example
package, built and installed by pip into a temporary folder), a broken plugin, and a
``module:Class`` reference imported without installing."""

from __future__ import annotations

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
from floorvo.metrics import score_run
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
    )
    monkeypatch.syspath_prepend(str(site))
    refresh_plugins()
    try:
        assert set(BUILTIN_ESTIMATORS) <= set(list_estimators())
        assert not {"broken-est", "not-an-estimator"} & set(list_estimators())
        reasons = unavailable_estimators()
        assert reasons["broken-est"] == "ModuleNotFoundError: No module named 'no_such_module_for_floorvo_tests'"
        assert reasons["not-an-estimator"] == "TypeError: estimator 'JSONDecoder' lacks 'name'"
        assert "named like a built-in" in reasons["phase-corr"]
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
    capsys.readouterr()
    assert floorvo_main(["run", str(line_sequence), "-e", "my_vo_for_tests:Nope", "-o", str(run)]) == 1
    err = capsys.readouterr().err
    assert "cannot be imported: AttributeError" in err and len(err.strip().splitlines()) == 1

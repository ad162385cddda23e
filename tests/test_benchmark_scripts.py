"""The scripts of benchmarks/: the parts of their logic that a run over few or lost frames reaches."""

from __future__ import annotations

import importlib.util
import math
import os
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def _load(name: str) -> ModuleType:
    """benchmarks/NAME.py as a module, its environment defaults (OMP_NUM_THREADS) undone."""
    env = dict(os.environ)
    spec = importlib.util.spec_from_file_location(f"_bench_{name}", BENCHMARKS / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(BENCHMARKS))
    try:
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(BENCHMARKS))
        os.environ.clear()
        os.environ.update(env)
    return module


@pytest.fixture(scope="module")
def estimators() -> ModuleType:
    return _load("estimators")


def _row(sequence: str, estimator: str, fps: float | None, cpu_ms: float, drift: float | None, lost: int) -> dict:
    return {
        "sequence": sequence,
        "estimator": estimator,
        "frames_per_s": fps,
        "cpu_ms_per_frame": cpu_ms,
        "cpu_ms_mean_per_frame": cpu_ms,
        "end_drift_pct": drift,
        "lost": lost,
    }


def test_estimators_preset_rows_of_a_run_that_lost_every_step(estimators):
    """A preset or its default that lost every step (frames/s None, step times NaN: a featureless
    or tiny sequence) has no ratios: None, where the table crashed with a TypeError."""
    rows = [
        _row("p0", "akaze-guided", 50.0, 20.0, 0.18, 0),
        _row("p0", "akaze-guided-fast", 200.0, 5.0, 0.17, 0),
        _row("d", "akaze-guided", 100.0, 10.0, 0.2, 1),
        _row("d", "akaze-guided-fast", None, math.nan, None, 3),
    ]
    by = {r["sequence"]: r for r in estimators._preset_rows(rows)}
    assert by["p0"]["ratio_wall"] == 4.0
    assert by["p0"]["ratio_cpu"] == 4.0
    assert by["p0"]["cpu_fps_fast"] == 200.0
    assert by["d"]["ratio_wall"] is None
    assert by["d"]["ratio_cpu"] is None
    assert by["d"]["cpu_fps_fast"] is None
    assert by["d"]["cpu_fps_default"] == 100.0
    assert by["d"]["lost_fast"] == 3


def test_motion_suite_says_a_failed_calibrated_run_failed():
    """A calibrated run that failed (its row's status) showed "-" in the calibrated cells, as a
    figure it does not have, beside the uncalibrated row's "ok"; now "failed"."""
    suite = _load("motion_suite")
    failed = {"status": "failed: trajectory.txt: no pose", "scene": "s", "estimator": "phase-corr"}
    assert suite._cell(failed, "end_drift_pct") == "failed"
    assert suite._cell({"status": "ok", "end_drift_pct": 0.1234}, "end_drift_pct") == "0.123"
    assert suite._cell({}, "end_drift_pct") == "-"
    _, cells = suite._calibrated_cells(failed, {}, " (x, y only)", "1.0010")
    assert cells == ["1.0010", "failed", "failed", "failed"]


def test_motion_suite_says_when_a_cached_render_is_not_the_scene_files_render(tmp_path):
    """``--from-cache`` benched the newest ``NAME-*`` folder without a word, also one rendered from
    an earlier scene file or renderer. The folder's ``bench-cache.json`` key is now checked against
    the key of the scene as it is: the same scene passes, an edited one is named."""
    import json

    from floorsim.bench.bench import scene_cache_key
    from floorsim.scene import load_scene

    suite = _load("motion_suite")
    scene = load_scene("demo")
    folder = tmp_path / "demo-0123456789ab"
    folder.mkdir()
    key = scene_cache_key(scene.to_dict(), seed=0, frames=3, scale=0.5, spp=None)
    mark = {"key": key, "scene": "demo", "seed": 0, "frames": 3, "scale": 0.5, "spp": None}
    (folder / "bench-cache.json").write_text(json.dumps(mark))
    assert suite._stale_problem(scene, folder) == ""
    edited = load_scene("demo", {"lights.height_mm": "5"})
    assert "was rendered from another version of scene demo or of the renderer" in suite._stale_problem(edited, folder)


def test_drift_sources_chains_each_step_in_the_frame_before():
    """Four 10 mm steps each turning 90 degrees after it close a square; a yaw of 0.01 rad after
    the first of two straight 10 mm steps puts the second at that angle (hand computation)."""
    drift = _load("drift_sources")
    square = drift.chained_end_mm(np.full(4, np.pi / 2), np.tile([10.0, 0.0], (4, 1)))
    assert np.allclose(square, 0.0, atol=1e-12)
    bent = drift.chained_end_mm(np.array([0.01, 0.0]), np.array([[10.0, 0.0], [10.0, 0.0]]))
    assert np.allclose(bent, [10.0 + 10.0 * np.cos(0.01), 10.0 * np.sin(0.01)], atol=1e-12)
    # a sideways step in the turned frame: (0, 5) after a 90-degree turn points along -x
    side = drift.chained_end_mm(np.array([np.pi / 2, 0.0]), np.array([[10.0, 0.0], [0.0, 5.0]]))
    assert np.allclose(side, [5.0, 0.0], atol=1e-12)


def test_height_creep_copies_a_sequence_with_its_readings_creeping_from_a_frame(tmp_path):
    """benchmarks/height_creep.py's copy: frame ``from_frame`` reads ``rate`` more, the next twice
    that, the frames before and a missing reading as they were (hand computation); the copy is a
    sequence of the same frames, its camera folder linked."""
    from floorvo.camera import CameraModel
    from floorvo.geometry import T_world_cam_down
    from floorvo.sequence import Sequence, SequenceWriter, read_height_csv
    from floorvo.synthetic import write_synthetic_sequence

    creep = _load("height_creep")
    cam = CameraModel.from_sensor(64, 48, pixel_pitch_um=14.8, focal_length_mm=6.0)
    poses = np.stack([T_world_cam_down(2.0 * i, 0.0, 100.0) for i in range(6)])
    seq = write_synthetic_sequence(tmp_path / "seq", cam, poses, height_noise_mm=0.0)
    h = read_height_csv(seq / "height.csv")
    h[4] = np.nan
    meta = {k: v for k, v in Sequence.open(seq).meta.items() if k not in ("schema_version", "format")}
    with SequenceWriter(seq, meta) as w:
        w.write_heights(h)
    copy = creep.creeping_copy(seq, tmp_path / "copy", 0.5, 3)
    got = read_height_csv(copy / "height.csv")
    expected = h + np.array([0.0, 0.0, 0.0, 0.5, 1.0, 1.5])
    assert np.allclose(got[:4], expected[:4]) and np.isnan(got[4]) and got[5] == pytest.approx(expected[5])
    assert (copy / "cam0").is_symlink() and Sequence.open(copy).frame_count == 6


def test_rolling_shutter_table_runs_a_pair_three_ways(tmp_path, capsys):
    """benchmarks/rolling_shutter.py on a synthetic pair (4 mm a frame along the rows, 15 ms
    readout): the global shutter's and the undone run's end drift are small, the run with the
    readout left in reads the steps 3 % long (both from the ground truth, not from the script)."""
    from floorvo.camera import CameraModel
    from floorvo.geometry import T_world_cam_down

    sys.path.insert(0, str(Path(__file__).resolve().parent / "floorvo"))
    try:
        from _synth import write_rolling_sequence
    finally:
        sys.path.pop(0)
    rs = _load("rolling_shutter")
    cam = CameraModel.from_sensor(324, 247, pixel_pitch_um=14.8, focal_length_mm=6.0)

    def pose_at(t):
        return T_world_cam_down(0.0, -120.0 * t, 100.0)

    seqs = {}
    for name, readout_ms in (("global", 0.0), ("rolling", 15.0)):
        write_rolling_sequence(tmp_path / name, cam, pose_at, np.arange(5) / 30.0, readout_ms, seed=2)
        seqs[name] = tmp_path / name
    assert rs.main(["--pair", f"y4={seqs['global']},{seqs['rolling']}", "-o", str(tmp_path / "out"),
                    "--estimators", "phase-corr"]) == 0  # fmt: skip
    row = next(line for line in capsys.readouterr().out.splitlines() if line.startswith("| y4 | phase-corr |"))
    drifts = [float(cell.split(" / ")[2]) for cell in row.strip("| ").split(" | ")[2:]]
    assert drifts[0] < 0.5 and drifts[2] < 0.5 and drifts[1] > 2.5

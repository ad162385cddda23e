"""Property-based tests (issue 16): every floorsim reader, given any input, gives a valid
object or one FloorbenchError line, never another exception: scene files, baselines and
sweep files (edits of valid documents and random bytes; see ``tests/_fuzz.py``)."""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path

import pytest
from _tiny import TINY_SCENE
from hypothesis import given
from hypothesis import strategies as st

from _fuzz import edited, one_line_or_valid, toml_text, values
from floorsim.bench.gates import DEFAULT_TOLERANCES, Baseline, compare, load_baseline, make_baseline, parse_baseline
from floorsim.bench.sweep import SweepSpec, load_sweep, sweep_jobs
from floorsim.scene import Scene, load_scene, scene_from_dict


@pytest.fixture(scope="module")
def workdir():
    with tempfile.TemporaryDirectory(prefix="floorbench-props-") as d:
        yield Path(d)


# --------------------------------------------------------------------------- scenes
@given(edited(TINY_SCENE))
def test_scene_table(doc):
    scene = one_line_or_valid(lambda: scene_from_dict(doc) if isinstance(doc, dict) else scene_from_dict({}))
    if isinstance(scene, Scene):
        # a scene that loads is one the renderer can take: positive sizes, finite rates, frames
        assert scene.fps > 0 and math.isfinite(scene.fps) and scene.camera.height_mm > scene.lights.height_mm > 0
        assert scene.build_trajectory().frame_count >= 1 and scene.floor_spacing_mm() > 0


@given(st.one_of(st.binary(max_size=200), edited(TINY_SCENE).filter(lambda d: isinstance(d, dict)).map(toml_text)))
def test_scene_file(workdir, text):
    p = workdir / "scene.toml"
    p.write_bytes(text if isinstance(text, bytes) else text.encode())
    one_line_or_valid(lambda: load_scene(p))


@given(
    st.dictionaries(
        st.sampled_from(
            [
                "camera.height_mm",
                "floor.seed",
                "fps",
                "trajectory.type",
                "lights.side",
                "camera.pixel_pitch_um",
                "trajectory.step_mm",
                "x.y",
                "camera",
            ]
        ),
        st.one_of(st.text(max_size=12), values.map(str)),
        max_size=3,
    )
)
def test_scene_set_overrides(overrides):
    one_line_or_valid(lambda: load_scene("demo", overrides))


# --------------------------------------------------------------------------- baselines
ROWS = [
    {"scene": "s", "estimator": "e", **{m: 1.0 for m in DEFAULT_TOLERANCES}},
    {"scene": "s", "estimator": "f", **{m: 2.0 for m in DEFAULT_TOLERANCES}, "end_drift_pct": float("nan")},
]


@given(edited(make_baseline(ROWS)))
def test_baseline(doc):
    b = one_line_or_valid(lambda: parse_baseline(doc))
    if isinstance(b, Baseline):
        assert b.tolerances and b.entries
        assert all(
            math.isfinite(t.abs) and math.isfinite(t.rel) and t.abs >= 0 and t.rel >= 0 for t in b.tolerances.values()
        )
        r = compare(ROWS, b)
        # the gate passes only when it checked something and nothing got worse
        assert (not r.ok) or (r.checked > 0 and not r.regressions)
        assert r.checked <= r.expected


@given(st.one_of(st.binary(max_size=100), values.map(lambda v: json.dumps(v).encode())))
def test_baseline_file(workdir, data):
    p = workdir / "baseline.json"
    p.write_bytes(data)
    one_line_or_valid(lambda: load_baseline(p))


# --------------------------------------------------------------------------- sweep files
SWEEP = {
    "base": "scene.toml",
    "estimators": ["phase-corr"],
    "repetitions": 1,
    "render": {"frames": 3, "scale": 0.25},
    "set": {"sensor.read_noise_e": 2.0},
    "vary": {"lights.height_mm": [1, 3.0, 10]},
    "operating_point": {"lights.height_mm": 3.0},
}


@given(st.one_of(st.binary(max_size=100), edited(SWEEP).filter(lambda d: isinstance(d, dict)).map(toml_text)))
def test_sweep_file(workdir, text):
    (workdir / "scene.toml").write_text(toml_text(TINY_SCENE))
    p = workdir / "sweep.toml"
    p.write_bytes(text if isinstance(text, bytes) else text.encode())
    spec = one_line_or_valid(lambda: load_sweep(p))
    if isinstance(spec, SweepSpec):
        jobs = sweep_jobs(spec)
        grid = spec.repetitions * math.prod(len(v) for v in spec.vary.values()) if spec.base is not None else 0
        assert len(jobs) == grid + len(spec.sequences) >= 1
        assert len({j["job"] for j in jobs}) == len(jobs)


def test_sweep_paths_that_are_not_paths(workdir):
    (workdir / "scene.toml").write_text(toml_text(TINY_SCENE))
    p = workdir / "sweep.toml"
    p.write_text(toml_text({**SWEEP, "base": "scene\u0000.toml"}))
    assert "base = 'scene\\x00.toml': not a usable path" in str(one_line_or_valid(lambda: load_sweep(p)))
    p.write_text(toml_text({**SWEEP, "sequences": ["a\u0000"]}))
    assert "not a usable path" in str(one_line_or_valid(lambda: load_sweep(p)))

"""Test doubles for the bench's collaborators: a scene loader, a renderer and estimators.

The bench's own work (cache, results.csv, scoring, report, gates, sweeps) is tested with
these, passed in as ``run_bench(..., **D.COLLABORATORS)`` (``load_scene``, ``render``,
``runner``); the doubles have known errors so the scores can be checked against hand
values: estimator ``scaled`` measures every step ``1 + scale_error`` too long, where
``scale_error = 0.001 * lights.height_mm`` (so a sweep over the LED height gives a known
drift curve) unless ``--est-set scaled.scale=S`` fixes it; ``lossy`` loses two frames;
``needs_depth`` requires depth and must be skipped on mono sequences.
"""

from __future__ import annotations

import json
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from _bench_data import write_run, write_sequence

from floorsim.bench.estimators import EstimatorRunner
from floorvo.errors import ConfigError
from floorvo.estimators import EstimatorSource
from floorvo.estimators.base import StepResult

SCENE_TOML = """name = "{name}"
seed = {seed}
frames = {frames}

[lights]
height_mm = {height}
power = 1.0
"""


def write_scene(
    path: Path, name: str = "tiny", seed: int = 7, frames: int = 12, height: float = 3.0, extra: str = ""
) -> Path:
    """A scene file for :func:`load_scene`; ``extra``: more TOML tables (e.g. ``[bench]``)."""
    path.write_text(SCENE_TOML.format(name=name, seed=seed, frames=frames, height=height) + extra)
    return path


@dataclass(frozen=True)
class FakeScene:
    data: dict

    @property
    def name(self) -> str:
        return self.data["name"]

    @property
    def seed(self) -> int:
        return int(self.data["seed"])

    def to_dict(self) -> dict:
        return json.loads(json.dumps(self.data))


def load_scene(path, overrides=None) -> FakeScene:
    d = tomllib.loads(Path(path).read_text())
    for k, v in (overrides or {}).items():
        sec, key = k.split(".")
        d.setdefault(sec, {})[key] = float(v)
    return FakeScene(d)


RENDER_CALLS: list[str] = []


def render(scene, out, *, frames=None, scale=None, spp=None, seed=None, on_frame=None, overwrite=False):
    RENDER_CALLS.append(str(out))
    n = frames or int(scene.data["frames"])
    write_sequence(Path(out), n=n)
    meta_path = Path(out) / "sequence.json"
    meta = json.loads(meta_path.read_text())
    meta["scene"] = scene.to_dict()
    meta_path.write_text(json.dumps(meta))
    for i in range(n):
        if on_frame:
            on_frame(i, n)
    return Path(out)


#: What each double estimator needs besides mono frames.
REQUIRES = {"scaled": set(), "lossy": set(), "needs_depth": {"depth"}}

#: (estimator, ScaleCalibration or None) of every run.
CALIBRATIONS: list = []


class _Stepper:
    """What ``FakeRunner.build`` gives for the keypoint samples: ``scaled`` exposes 5 matches, 2 px apart."""

    requires: set = set()

    def __init__(self, name):
        self.name = name

    def start(self):
        return {"n": 0}

    def step(self, state, frame):
        state["n"] += 1
        if state["n"] == 1:
            return StepResult("init")
        m = np.array([[20.0 + 5 * k, 30.0, 18.0 + 5 * k, 30.0] for k in range(5)]) if self.name == "scaled" else None
        return StepResult("ok", np.eye(4), matches_px=m)


class FakeRunner(EstimatorRunner):
    """The double estimators: their runs write trajectories with known errors (see the module doc)."""

    def names(self):
        return list(REQUIRES) + list(self.externals)

    def python_names(self):
        return list(REQUIRES)

    def requires(self, name):
        return super().requires(name) if self.is_external(name) else set(REQUIRES[name])

    def source(self, name):
        return super().source(name) if self.is_external(name) else EstimatorSource("double", name)

    def check_config(self, name, overrides):
        for key in overrides:
            if name != "scaled" or key != "scale":
                raise ConfigError(f"{name}.{key}: unknown config key (known: {'scale' if name == 'scaled' else ''})")

    def build(self, seq, name, overrides=None):
        return _Stepper(name), None

    def run(self, seq_dir, name, run_dir, overrides=None, scale_calibration=None, **kwargs):
        if self.is_external(name):  # external programs given to the bench run for real
            return super().run(seq_dir, name, run_dir, overrides, scale_calibration, **kwargs)
        CALIBRATIONS.append((name, scale_calibration))
        meta = json.loads((Path(seq_dir) / "sequence.json").read_text())
        height = float(meta["scene"]["lights"]["height_mm"])
        if name == "scaled":
            scale = float((overrides or {}).get("scale", 1.0 + 0.001 * height))
            if scale_calibration is not None:  # the sequences travel along the camera's x axis
                scale /= scale_calibration.scale_x
            write_run(Path(run_dir), Path(seq_dir), scale=scale, estimator=name)
        elif name == "lossy":
            write_run(Path(run_dir), Path(seq_dir), scale=1.0, lost=(3, 4), estimator=name)
        else:
            raise AssertionError(f"{name} must not run on a mono sequence")


#: The collaborators ``run_bench`` / ``run_sweep`` / ``floorsim.cli.main`` take.
COLLABORATORS = {"load_scene": load_scene, "render": render, "runner": FakeRunner()}


def reset() -> None:
    """Forget the renders and runs of earlier tests."""
    RENDER_CALLS.clear()
    CALIBRATIONS.clear()

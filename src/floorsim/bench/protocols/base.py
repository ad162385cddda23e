"""What a paper protocol is to the bench: the interface, what it is given, what it gives back.

A protocol is an object with a ``name`` the scenes ask for (``[bench] protocols = [NAME]``
in a scene file) and up to three hooks, each optional (the base class does nothing):

* :meth:`BenchProtocol.row_columns`: extra columns for every estimator row of a scene
  that asks for it (paper 001: the paper's reference error);
* :meth:`BenchProtocol.run_scene`: after every repetition of such a scene has been run
  and scored, on repetition 0's sequence (paper 000: the strip runs);
* :meth:`BenchProtocol.run_bench`: once after every scene, with all the scenes of the
  bench that ask for it (paper 003: a map from one scene, another localised on it).

Each hook that produces something returns a :class:`ProtocolOutput`: rows for
``results.csv`` (scored like any run, so the gates cover them), run records for the
report's plots, report sections (callables ``f(report)``) and notes.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from collections.abc import Sequence as SequenceT
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

from floorsim.bench.estimators import DEFAULT_RUNNER, EstimatorRunner
from floorsim.bench.report import Report, RunRecord
from floorvo.calibration import ScaleCalibration

__all__ = ["BenchContext", "BenchProtocol", "ProtocolOutput", "SceneRun", "trajectory_type"]


def trajectory_type(scene: Any) -> str | None:
    """The ``trajectory.type`` of a scene (anything with ``to_dict()``), or None."""
    return (scene.to_dict().get("trajectory") or {}).get("type")


@dataclass(frozen=True)
class BenchContext:
    """What the bench passes every hook.

    ``out_dir``: the bench folder (``DIR``); ``estimator_overrides``: ``{estimator: {key:
    value}}`` from ``--est-set``; ``scale_calibrations``: ``{estimator: ScaleCalibration}``
    from ``--scale-calibration``; ``options``: settings of one protocol by its name (e.g.
    ``{"paper000-strip": {"max_runs": 5}}`` from ``--paper000-runs 5``); ``runner``: how
    estimators are built and run (the bench's, a double in tests).
    """

    out_dir: Path
    estimator_overrides: Mapping[str, Mapping[str, str]] = field(default_factory=dict)
    scale_calibrations: Mapping[str, ScaleCalibration] = field(default_factory=dict)
    options: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    runner: EstimatorRunner = DEFAULT_RUNNER

    def options_for(self, protocol: str) -> Mapping[str, Any]:
        return self.options.get(protocol, {})


@dataclass
class SceneRun:
    """One scene of the bench as the protocols see it.

    ``label``: the scene's name in results.csv (``NAME-2`` for a second scene of that
    name); ``seq_dir`` / ``seed``: repetition 0's rendered sequence and its seed (a
    sequence folder given to the bench: that folder, seed None, ``scene`` None);
    ``estimators``: the estimators run on it; ``rows``: its results.csv rows (every
    repetition).
    """

    label: str
    scene_file: Path
    scene: Any
    seq_dir: Path
    seed: int | None
    estimators: list[str]
    rows: list[dict[str, Any]]

    @property
    def trajectory_type(self) -> str | None:
        return trajectory_type(self.scene)


@dataclass
class ProtocolOutput:
    """What a hook adds to the bench: results.csv rows, run records, report sections, notes."""

    rows: list[dict[str, Any]] = field(default_factory=list)
    records: list[RunRecord] = field(default_factory=list)
    sections: list[Callable[[Report], None]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


class BenchProtocol:
    """A paper protocol (see the module doc). Subclasses set the class attributes and
    override the hooks they need.

    ``trajectory_types``: the trajectory types it runs on; a scene that asks for it with
    another type is refused before anything is rendered. A scene file without a
    ``[bench]`` table gets the protocols whose ``default_for`` holds its trajectory type.
    """

    name: ClassVar[str]
    description: ClassVar[str]
    trajectory_types: ClassVar[tuple[str, ...]] = ()
    default_for: ClassVar[tuple[str, ...]] = ()

    def row_columns(self, scene: SceneRun) -> dict[str, Any]:
        """Columns added to each estimator row of ``scene`` (``scene.rows`` is still being filled)."""
        return {}

    def run_scene(self, ctx: BenchContext, scene: SceneRun) -> ProtocolOutput:
        """Run on one scene after its estimators ran (every repetition)."""
        return ProtocolOutput()

    def run_bench(self, ctx: BenchContext, scenes: SequenceT[SceneRun]) -> ProtocolOutput:
        """Run once after every scene, with the scenes that ask for this protocol (in bench order)."""
        return ProtocolOutput()

"""How the bench finds, builds and runs estimators: one collaborator, replaceable in tests.

:class:`EstimatorRunner` wraps floorvo's registry and run loop (built-ins, entry-point
plugins, ``module:Class`` references: :mod:`floorvo.estimators.registry`) and the external
programs it was given (:mod:`floorvo.external`); the bench, its paper protocols (through
:class:`floorsim.bench.protocols.BenchContext`) and sweeps take one as ``runner`` (default
:data:`DEFAULT_RUNNER`), and tests pass a subclass whose estimators have known errors.

Every run gives the figures the bench compares estimators by besides accuracy
(:data:`RUN_FIGURES`): wall time per frame and peak resident memory
(:class:`floorvo.memory.PeakRss`). A program's peak is its own (the high-water mark of its
resident set, and of the processes it starts); an estimator run in the bench's process is
measured by sampling the process's resident memory during the run, so it includes the bench's
own (a Python process with numpy and OpenCV loaded, about 150-250 MiB).
"""

from __future__ import annotations

import copy
from collections.abc import Iterable, Mapping
from collections.abc import Sequence as SequenceT
from pathlib import Path
from typing import Any

import numpy as np

from floorvo.calibration import ScaleCalibration
from floorvo.errors import ConfigError, EstimatorLoadError, FloorbenchError, shown
from floorvo.estimators import EstimatorSource, estimator_source, get_estimator, list_estimators, make_config
from floorvo.external import ExternalEstimator, run_external
from floorvo.memory import PeakRss
from floorvo.run import build_estimator, run_estimator
from floorvo.sequence import Sequence

__all__ = ["DEFAULT_RUNNER", "EstimatorRunner", "RUN_FIGURES", "PeakRss", "check_estimator_choice"]

#: Columns every run adds to its row: wall-clock ms per sequence frame (the whole run, frame
#: reading or program start-up included) and peak resident memory (MiB).
RUN_FIGURES = ("wall_ms_per_frame", "peak_rss_mb")


class EstimatorRunner:
    """How the bench finds, builds and runs estimators: floorvo's registry and run loop, and
    the external programs ``externals`` (:class:`floorvo.external.ExternalEstimator`).

    The bench and sweeps take one as ``runner``; tests pass a subclass whose estimators
    have known errors. Picklable (sweeps send it to worker processes and Dask workers).
    """

    def __init__(self, externals: Iterable[ExternalEstimator] = ()):
        self.externals: dict[str, ExternalEstimator] = {}
        self.add_externals(externals)

    def add_externals(self, externals: Iterable[ExternalEstimator]) -> None:
        """Add external programs; a name that another estimator has is refused."""
        for spec in externals:
            if spec.name in self.externals or spec.name in self.python_names():
                raise ConfigError(f"external estimator {spec.name!r}: the name is taken (choose another NAME)")
            self.externals[spec.name] = spec

    def with_externals(self, externals: Iterable[ExternalEstimator]) -> EstimatorRunner:
        """A copy of this runner with ``externals`` added (this one is left as it is)."""
        externals = list(externals)
        if not externals:
            return self
        other = copy.copy(self)
        other.externals = dict(self.externals)
        other.add_externals(externals)
        return other

    def python_names(self) -> list[str]:
        """Every estimator of floorvo's registry (built-ins and plugins that load)."""
        return list(list_estimators())

    def names(self) -> list[str]:
        """Every estimator: the registry's, then the external programs."""
        return self.python_names() + [n for n in self.externals if n not in self.python_names()]

    def known(self, name: str) -> bool:
        """Whether ``name`` can be run: listed, or a ``package.module:Class`` reference."""
        return name in self.names() or ":" in name

    def is_external(self, name: str) -> bool:
        return name in self.externals

    def source(self, name: str) -> EstimatorSource:
        """Where estimator ``name`` comes from (recorded in every run row)."""
        if name in self.externals:
            return self.externals[name].source
        return estimator_source(name)

    def requires(self, name: str) -> set[str]:
        """What estimator ``name`` needs besides mono frames (``depth``, ``stereo``)."""
        if name in self.externals:
            return set(self.externals[name].needs)
        return set(getattr(get_estimator(name), "requires", ()) or ())

    def check_config(self, name: str, overrides: Mapping[str, Any]) -> None:
        """Refuse config keys or values that estimator ``name`` does not take (a one-line
        :class:`~floorvo.errors.ConfigError` naming ``name.key``), before any run."""
        if name in self.externals:
            if overrides:
                raise ConfigError(f"{name}: an external program takes no config keys (put options in its command)")
            return
        make_config(name, overrides)

    def build(self, seq: Sequence, name: str, overrides: Mapping[str, str] | None = None) -> tuple[Any, Any]:
        """``(estimator, config)`` for ``seq`` (:func:`floorvo.run.build_estimator`); an external
        program has no frame-by-frame object (:class:`FloorbenchError`)."""
        if name in self.externals:
            raise FloorbenchError(f"{name} is an external program: it runs over a whole sequence, not frame by frame")
        return build_estimator(seq, name, overrides)

    def check(self, seq: Sequence, name: str) -> None:
        """Refuse (:class:`FloorbenchError`) an estimator that cannot run on ``seq`` with its default
        configuration (e.g. one that needs a prebuilt map); a program is checked by running it."""
        if name not in self.externals:
            self.build(seq, name)

    def run(
        self,
        seq_dir: Path,
        name: str,
        run_dir: Path,
        overrides: Mapping[str, str] | None = None,
        scale_calibration: ScaleCalibration | None = None,
        T_world_start: np.ndarray | None = None,
    ) -> dict[str, float]:
        """Run ``name`` over the sequence into ``run_dir``; returns the run's :data:`RUN_FIGURES`.

        A Python estimator runs in this process (:func:`floorvo.run.run_estimator`), a program
        as a child (:func:`floorvo.external.run_external`, which takes no ``overrides`` or
        ``scale_calibration``). ``T_world_start``: the start pose on a sequence without ground truth.
        """
        if name in self.externals:
            if overrides:
                raise ConfigError(f"--est-set {name}.*: {name} is an external program (put options in its command)")
            if scale_calibration is not None:
                raise ConfigError(f"--scale-calibration {name}: {name} is an external program (calibrate its output)")
            ext = run_external(seq_dir, self.externals[name], run_dir, T_world_start=T_world_start)
            return {"wall_ms_per_frame": ext.wall_ms_per_frame, "peak_rss_mb": ext.peak_rss_mb}
        with PeakRss() as mem:
            res = run_estimator(
                seq_dir,
                name,
                run_dir,
                overrides=dict(overrides or {}),
                scale_calibration=scale_calibration,
                T_world_start=T_world_start,
            )
        return {"wall_ms_per_frame": 1000.0 / res.fps if res.fps > 0 else float("nan"), "peak_rss_mb": mem.peak_mb}


DEFAULT_RUNNER = EstimatorRunner()


def check_estimator_choice(
    runner: EstimatorRunner,
    estimators: SequenceT[str] | None,
    configs: Mapping[str, Mapping[str, Any]],
    *,
    names_label: str = "--estimators",
    config_label: str = "--est-set ",
) -> None:
    """Refuse, before any render or run, an estimator choice that would make runs fail or be
    ignored: the one check of the bench (``--estimators``, ``--est-set``) and of studies
    (``estimators``, ``[estimator_config.NAME]``).

    ``estimators``: the names asked for (None: every estimator a sequence supports); the
    runner's external programs run in either case. Refused, in one line
    (:class:`~floorvo.errors.ConfigError`): a list naming no estimator, an unknown or repeated
    name, a config for an unknown estimator or for one that does not run, and config keys or
    values the estimator does not take. ``names_label`` names the list in the refusal
    (``--estimators``, ``study.toml: estimators``); ``config_label`` is put before the
    estimator's ``NAME.KEY`` (``--est-set ``, ``study.toml: estimator_config.``).
    """
    known = ", ".join(sorted(runner.names()))
    if estimators is not None:
        if not estimators:
            raise ConfigError(
                f"{names_label}: names no estimator; name at least one (or leave it out for every estimator "
                "the sequence supports)"
            )
        for n in estimators:
            if not runner.known(n):
                raise ConfigError(f"{names_label}: {shown(n)}: unknown estimator (known: {known})")
            if n not in runner.names():  # a module:Class reference: imported here, not found out after the renders
                try:
                    get_estimator(n)
                except EstimatorLoadError as exc:
                    raise ConfigError(f"{names_label}: {exc}") from None
        twice = sorted({n for n in estimators if list(estimators).count(n) > 1})
        if twice:  # it ran twice into one run folder, two rows of one run
            raise ConfigError(f"{names_label}: {', '.join(map(repr, twice))} given twice; give each estimator once")
    for name, cfg in configs.items():
        if not runner.known(name):
            raise ConfigError(f"{config_label}{name}: unknown estimator (known: {known})")
        running = None if estimators is None else [*estimators, *(n for n in runner.externals if n not in estimators)]
        if running is not None and name not in running:  # its config was silently ignored
            raise ConfigError(
                f"{config_label}{name}: {shown(name)} is not among {names_label} ({', '.join(running)}), "
                "so its config would be ignored"
            )
        try:
            runner.check_config(name, cfg)
        except ConfigError as exc:
            raise ConfigError(f"{config_label}{exc}") from None

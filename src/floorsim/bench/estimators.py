"""How the bench finds, builds and runs estimators: one collaborator, replaceable in tests.

:class:`EstimatorRunner` wraps floorvo's registry and run loop; the bench, its paper
protocols (through :class:`floorsim.bench.protocols.BenchContext`) and sweeps take one as
``runner`` (default :data:`DEFAULT_RUNNER`), and tests pass a subclass whose estimators
have known errors.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from floorvo.calibration import ScaleCalibration
from floorvo.estimators import get_estimator, list_estimators
from floorvo.run import build_estimator, run_estimator
from floorvo.sequence import Sequence

__all__ = ["DEFAULT_RUNNER", "EstimatorRunner"]


class EstimatorRunner:
    """How the bench finds, builds and runs estimators: floorvo's registry and run loop.

    The bench and sweeps take one as ``runner``; tests pass a subclass whose estimators
    have known errors.
    """

    def names(self) -> list[str]:
        """Every registered estimator."""
        return list(list_estimators())

    def requires(self, name: str) -> set[str]:
        """What estimator ``name`` needs besides mono frames (``depth``, ``stereo``)."""
        return set(getattr(get_estimator(name), "requires", ()) or ())

    def build(self, seq: Sequence, name: str, overrides: Mapping[str, str] | None = None) -> tuple[Any, Any]:
        """``(estimator, config)`` for ``seq`` (:func:`floorvo.run.build_estimator`)."""
        return build_estimator(seq, name, overrides)

    def run(
        self,
        seq_dir: Path,
        name: str,
        run_dir: Path,
        overrides: Mapping[str, str] | None = None,
        scale_calibration: ScaleCalibration | None = None,
    ) -> None:
        """Run ``name`` over the sequence into ``run_dir`` (:func:`floorvo.run.run_estimator`)."""
        run_estimator(seq_dir, name, run_dir, overrides=dict(overrides or {}), scale_calibration=scale_calibration)


DEFAULT_RUNNER = EstimatorRunner()

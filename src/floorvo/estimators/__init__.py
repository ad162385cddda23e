"""Odometry estimators behind one interface (:mod:`floorvo.estimators.base`).

:func:`list_estimators` names them and :func:`get_estimator` returns a class by name
(:mod:`floorvo.estimators.registry`, where every built-in is declared and entry-point
plugins and ``module:Class`` references are found); :func:`make_config` builds an
estimator's configuration from ``--set`` style overrides.
"""

from floorvo.estimators.base import Estimator, Frame, StepResult
from floorvo.estimators.registry import (
    BUILTIN_ESTIMATORS,
    ENTRY_POINT_GROUP,
    EstimatorSource,
    estimator_source,
    get_estimator,
    list_estimators,
    make_config,
    register,
    unavailable_estimators,
)

__all__ = [
    "BUILTIN_ESTIMATORS",
    "ENTRY_POINT_GROUP",
    "Estimator",
    "EstimatorSource",
    "Frame",
    "StepResult",
    "estimator_source",
    "get_estimator",
    "list_estimators",
    "make_config",
    "register",
    "unavailable_estimators",
]

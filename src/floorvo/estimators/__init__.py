"""Odometry estimators behind one interface (:mod:`floorvo.estimators.base`).

:func:`list_estimators` names them and :func:`get_estimator` returns a class by name
(:mod:`floorvo.estimators.registry`, where every built-in is declared); :func:`make_config`
builds an estimator's configuration from ``--set`` style overrides.
"""

from floorvo.estimators.base import Estimator, Frame, StepResult
from floorvo.estimators.registry import BUILTIN_ESTIMATORS, get_estimator, list_estimators, make_config, register

__all__ = [
    "BUILTIN_ESTIMATORS",
    "Estimator",
    "Frame",
    "StepResult",
    "get_estimator",
    "list_estimators",
    "make_config",
    "register",
]

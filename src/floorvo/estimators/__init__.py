"""Odometry estimators behind one interface (:mod:`floorvo.estimators.base`).

Importing this package registers the built-in estimators; :func:`list_estimators` names
them and :func:`get_estimator` returns a class by name.
"""

from floorvo.estimators import akaze, orb_icp, phase_corr, stereo_sift  # noqa: F401  (registers them)
from floorvo.estimators.base import (
    REGISTRY,
    Estimator,
    Frame,
    StepResult,
    get_estimator,
    list_estimators,
    make_config,
    register,
)
from floorvo.mapping import fused as _map_fused  # noqa: F401,E402  (registers map-fused, paper 003)

__all__ = [
    "REGISTRY",
    "Estimator",
    "Frame",
    "StepResult",
    "get_estimator",
    "list_estimators",
    "make_config",
    "register",
]

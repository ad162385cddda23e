"""Estimators by name: the built-ins declared in one table, others added with :func:`register`.

:data:`BUILTIN_ESTIMATORS` names every built-in estimator as ``"module:Class"``, the way a
package names an entry-point plugin; a class is imported the first time it is looked up.
So this module imports no estimator, and ``map-fused`` (:mod:`floorvo.mapping.fused`),
which looks up its odometry estimator here and sits on the mapping modules, is a built-in
like the others without an import cycle between the estimators and the mapping layer.

:func:`make_config` builds an estimator's ``Config`` from ``--set`` style overrides through
the one configuration mechanism (:mod:`floorvo.config`).
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from typing import Any

from floorvo.config import from_overrides
from floorvo.errors import ConfigError
from floorvo.estimators.base import Estimator

__all__ = ["BUILTIN_ESTIMATORS", "register", "get_estimator", "list_estimators", "make_config"]

#: Every built-in estimator: name -> ``"module:Class"`` (the class's ``name`` is the key).
BUILTIN_ESTIMATORS: dict[str, str] = {
    "phase-corr": "floorvo.estimators.phase_corr:PhaseCorr",
    "akaze-guided": "floorvo.estimators.akaze:AkazeGuided",
    "akaze-bruteforce": "floorvo.estimators.akaze:AkazeBruteforce",
    "orb-icp": "floorvo.estimators.orb_icp:OrbIcp",
    "stereo-sift": "floorvo.estimators.stereo_sift:StereoSift",
    "map-fused": "floorvo.mapping.fused:MapFused",
}

_ATTRS = ("name", "description", "Config", "requires")
_LOADED: dict[str, type[Estimator]] = {}


def _checked(cls: Any, name: str | None = None) -> type[Estimator]:
    for attr in _ATTRS:
        if not hasattr(cls, attr):
            raise TypeError(f"estimator {cls.__name__} lacks {attr!r}")
    if name is not None and cls.name != name:
        raise TypeError(f"estimator {cls.__name__} is named {cls.name!r}, registered as {name!r}")
    return cls


def register(cls: Any) -> Any:
    """Class decorator adding an estimator from outside the built-ins under ``cls.name``."""
    _LOADED[cls.name] = _checked(cls)
    return cls


def get_estimator(name: str) -> type[Estimator]:
    """The estimator class registered as ``name`` (:class:`ConfigError` for an unknown name)."""
    if name not in _LOADED:
        if name not in BUILTIN_ESTIMATORS:
            raise ConfigError(f"estimator {name!r}: unknown (known: {', '.join(list_estimators())})")
        module, _, attr = BUILTIN_ESTIMATORS[name].partition(":")
        _LOADED[name] = _checked(getattr(importlib.import_module(module), attr), name)
    return _LOADED[name]


def list_estimators() -> list[str]:
    """Names of every registered estimator, sorted."""
    return sorted(set(BUILTIN_ESTIMATORS) | set(_LOADED))


def make_config(name: str, overrides: Mapping[str, Any] | None = None) -> Any:
    """Estimator ``name``'s Config with ``{"field": "value"}`` overrides applied and checked.

    String values are read by the field's type (``--set`` text); others are taken as they
    are. Errors name the estimator: ``akaze-guided.hamming_threshold = 0: must be >= 1``.
    """
    return from_overrides(get_estimator(name).Config, overrides, name, unknown="unknown config key")

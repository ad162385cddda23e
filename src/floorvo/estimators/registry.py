"""Estimators by name: the built-ins, entry-point plugins, ``module:Class`` references, :func:`register`.

Every estimator is named by a ``"module:Class"`` reference and imported the first time it
is looked up, whatever its source (:class:`EstimatorSource`):

* **built-in**: :data:`BUILTIN_ESTIMATORS`, one table. This module imports no estimator,
  so ``map-fused`` (:mod:`floorvo.mapping.fused`), which looks up its odometry estimator
  here and sits on the mapping modules, is a built-in without an import cycle.
* **plugin**: an installed distribution declaring an entry point in the group
  :data:`ENTRY_POINT_GROUP` (``floorvo.estimators``), ``NAME = "package.module:Class"``;
  after ``pip install`` it is listed and runs wherever a built-in does. A plugin that fails
  to import (or names a class that is not an estimator) is *unavailable*:
  :func:`unavailable_estimators` gives its one-line reason, :func:`list_estimators` leaves
  it out, and :func:`get_estimator` refuses it with :class:`~floorvo.errors.EstimatorLoadError`;
  it never breaks the listing or the built-ins. A plugin named like a built-in is refused.
* **module**: a name with a colon, ``package.module:Class``, is imported from ``sys.path``
  as it is (no install), for development: ``floorvo run --estimator mypkg.vo:MyVo``.
* :func:`register`, a class decorator, adds a class already imported.

Programs outside Python are estimators of another kind (:mod:`floorvo.external`): they run
as a process over a sequence folder, not frame by frame, so they are not looked up here.

:func:`make_config` builds an estimator's ``Config`` from ``--set`` style overrides through
the one configuration mechanism (:mod:`floorvo.config`).
"""

from __future__ import annotations

import dataclasses
import importlib
import importlib.metadata
import logging
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from floorvo import __version__
from floorvo.config import from_overrides
from floorvo.errors import ConfigError, EstimatorLoadError, shorten
from floorvo.estimators.base import NEEDS, Estimator

__all__ = [
    "BUILTIN_ESTIMATORS",
    "ENTRY_POINT_GROUP",
    "EstimatorSource",
    "register",
    "get_estimator",
    "estimator_source",
    "list_estimators",
    "unavailable_estimators",
    "refresh_plugins",
    "make_config",
]

log = logging.getLogger(__name__)

#: Every built-in estimator: name -> ``"module:Class"`` (the class's ``name`` is the key).
BUILTIN_ESTIMATORS: dict[str, str] = {
    "phase-corr": "floorvo.estimators.phase_corr:PhaseCorr",
    "akaze-guided": "floorvo.estimators.akaze:AkazeGuided",
    "akaze-bruteforce": "floorvo.estimators.akaze:AkazeBruteforce",
    "orb-icp": "floorvo.estimators.orb_icp:OrbIcp",
    "stereo-sift": "floorvo.estimators.stereo_sift:StereoSift",
    "map-fused": "floorvo.mapping.fused:MapFused",
    "homography-6dof": "floorvo.estimators.homography:HomographySixDof",
    # Real-time presets (issue 14 item 5): the same classes with other Config defaults.
    "akaze-guided-fast": "floorvo.estimators.akaze:AkazeGuidedFast",
    "akaze-bruteforce-fast": "floorvo.estimators.akaze:AkazeBruteforceFast",
    "orb-icp-fast": "floorvo.estimators.orb_icp:OrbIcpFast",
    "stereo-sift-fast": "floorvo.estimators.stereo_sift:StereoSiftFast",
    "phase-corr-fast": "floorvo.estimators.phase_corr:PhaseCorrFast",
    # Sub-pixel pairs (ours): akaze-guided with refine_window_px = 21.
    "akaze-guided-subpixel": "floorvo.estimators.akaze:AkazeGuidedSubpixel",
}

#: The entry-point group a plugin package declares its estimators in.
ENTRY_POINT_GROUP = "floorvo.estimators"

_ATTRS = ("name", "description", "Config", "requires")
_LOADED: dict[str, type[Estimator]] = {}
_REGISTERED: dict[str, str] = {}  # name -> "module:Class" of classes added with register()
_FAILED: dict[str, str] = {}  # plugin name -> why it cannot be loaded
_PLUGINS: dict[str, importlib.metadata.EntryPoint] | None = None


@dataclass(frozen=True)
class EstimatorSource:
    """Where an estimator comes from, as every run row records it.

    ``kind``: ``built-in``, ``plugin`` (an installed entry point), ``module`` (a
    ``module:Class`` reference imported as it is), ``registered`` (:func:`register`) or
    ``external`` (a program, :mod:`floorvo.external`). ``target``: the ``module:Class``
    reference, or the program's command line. ``package`` and ``version``: the
    distribution that provides it (``floorbench`` for the built-ins). ``command_sha256``:
    for an external program, the hash of its command line (:func:`floorvo.external.command_hash`).
    """

    kind: str
    target: str
    package: str = ""
    version: str = ""
    command_sha256: str = ""

    @property
    def detail(self) -> str:
        """``package version`` of a built-in or a plugin, ``sha256:HASH`` (12 hex digits) of a program,
        else the ``module:Class`` reference."""
        if self.command_sha256:
            return f"sha256:{self.command_sha256[:12]}"
        if self.package:
            return f"{self.package} {self.version}".strip()
        return self.target

    def describe(self) -> str:
        """One phrase: ``plugin floorbench-example-plugin 0.1.0``, ``external sha256:1a2b3c4d5e6f``."""
        return f"{self.kind} {self.detail}"

    def row(self) -> dict[str, str]:
        """The columns a results.csv row records: ``source`` (the kind) and ``source_detail``."""
        return {"source": self.kind, "source_detail": self.detail}

    def to_dict(self) -> dict[str, str]:
        """Every field, for ``result.json``."""
        return {
            "kind": self.kind,
            "target": self.target,
            "package": self.package,
            "version": self.version,
            "command_sha256": self.command_sha256,
        }


def _checked(cls: Any, name: str | None = None) -> type[Estimator]:
    for attr in _ATTRS:
        if not hasattr(cls, attr):
            raise TypeError(f"estimator {getattr(cls, '__name__', cls)!r} lacks {attr!r}")
    if name is not None and cls.name != name:
        raise TypeError(f"estimator {cls.__name__} is named {cls.name!r}, registered as {name!r}")
    if not (isinstance(cls.Config, type) and dataclasses.is_dataclass(cls.Config)):
        # Config = dict ended in 'TypeError: must be called with a dataclass type or instance' from inside
        raise TypeError(
            f"estimator {getattr(cls, '__name__', cls)!r}: Config = {cls.Config!r} must be a dataclass "
            "(declared with floorvo.config.param)"
        )
    req = cls.requires
    if isinstance(req, (str, bytes)) or not isinstance(req, (set, frozenset, tuple, list)) or set(req) - set(NEEDS):
        # 'depht', or "depth" as a string (its letters): a need not understood let it run without it
        raise TypeError(
            f"estimator {getattr(cls, '__name__', cls)!r}: requires = {req!r} must be a set of {', '.join(NEEDS)}"
        )
    return cls


def _one_line(exc: BaseException) -> str:
    """``Type: message`` on one line, cut to 200 characters (:func:`floorvo.errors.shorten`)."""
    return shorten(" ".join(f"{type(exc).__name__}: {exc}".split()), 200)


def _plugins() -> dict[str, importlib.metadata.EntryPoint]:
    """The entry points of :data:`ENTRY_POINT_GROUP` by name (read once; :func:`refresh_plugins`
    reads them again). A name declared twice is refused; one that a built-in has is refused."""
    global _PLUGINS
    if _PLUGINS is None:
        found: dict[str, importlib.metadata.EntryPoint] = {}
        for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
            if ep.name in BUILTIN_ESTIMATORS:
                _FAILED[ep.name] = f"plugin {ep.value} is named like a built-in estimator (rename its entry point)"
                log.warning("estimator plugin %s = %s: %s", ep.name, ep.value, _FAILED[ep.name])
                continue
            if ep.name in found and found[ep.name].value != ep.value:
                _FAILED[ep.name] = f"declared twice, as {found[ep.name].value} and {ep.value}"
                continue
            found[ep.name] = ep
        _PLUGINS = {n: ep for n, ep in found.items() if n not in _FAILED}
    return _PLUGINS


def refresh_plugins() -> None:
    """Read the installed entry points again (after a ``pip install`` in the same process) and
    forget the plugins loaded or refused so far."""
    global _PLUGINS
    for name in list(_PLUGINS or {}) + list(_FAILED):
        _LOADED.pop(name, None)
    _FAILED.clear()
    _PLUGINS = None
    importlib.invalidate_caches()


def _distribution(ep: importlib.metadata.EntryPoint) -> tuple[str, str]:
    dist = getattr(ep, "dist", None)
    if dist is None:
        return "", ""
    return str(dist.metadata["Name"] or dist.name), str(dist.version)


def estimator_source(name: str) -> EstimatorSource:
    """Where estimator ``name`` comes from (:class:`ConfigError` for an unknown name)."""
    if name in BUILTIN_ESTIMATORS:
        return EstimatorSource("built-in", BUILTIN_ESTIMATORS[name], "floorbench", __version__)
    if name in _REGISTERED:
        return EstimatorSource("registered", _REGISTERED[name])
    ep = _plugins().get(name)
    if ep is not None:
        package, version = _distribution(ep)
        return EstimatorSource("plugin", ep.value, package, version)
    if name in _FAILED:
        return EstimatorSource("plugin", "")
    if ":" in name:
        return EstimatorSource("module", name)
    raise _unknown(name)


def _unknown(name: str) -> ConfigError:
    return ConfigError(
        f"estimator {name!r}: unknown (known: {', '.join(list_estimators())}; or give a class as package.module:Class)"
    )


def register(cls: Any) -> Any:
    """Class decorator adding an estimator from outside the built-ins under ``cls.name``."""
    _LOADED[cls.name] = _checked(cls)
    _REGISTERED[cls.name] = f"{cls.__module__}:{cls.__qualname__}"
    return cls


def _import_reference(ref: str) -> Any:
    """The object ``module:attr.path`` names."""
    module, _, attr = ref.partition(":")
    if not module or not attr:
        raise ValueError(f"{ref!r} is not a reference of the form package.module:Class")
    obj: Any = importlib.import_module(module)
    for part in attr.split("."):
        obj = getattr(obj, part)
    return obj


def get_estimator(name: str) -> type[Estimator]:
    """The estimator class named ``name``: a built-in, a registered class, a plugin's entry point,
    or a ``package.module:Class`` reference.

    An unknown name is a :class:`ConfigError`; a plugin or a reference that cannot be
    imported, or that is not an estimator, an :class:`~floorvo.errors.EstimatorLoadError`
    with the one-line reason. A built-in's import errors propagate (they are bugs, or a
    missing optional dependency the caller reports).
    """
    if name in _LOADED:
        return _LOADED[name]
    if name in BUILTIN_ESTIMATORS:
        _LOADED[name] = _checked(_import_reference(BUILTIN_ESTIMATORS[name]), name)
        return _LOADED[name]
    ep = _plugins().get(name)
    if name in _FAILED:
        what = f"plugin {ep.value}" if ep is not None else "plugin"
        raise EstimatorLoadError(f"estimator {name!r} ({what}) is unavailable: {_FAILED[name]}")
    if ep is None and ":" not in name:
        raise _unknown(name)
    try:
        # Third-party code: any exception while importing it makes it unavailable, never a crash;
        # SystemExit too (a module that parses sys.argv on import ended `floorvo list`).
        cls = _checked(ep.load(), name) if ep is not None else _checked(_import_reference(name))
    except (Exception, SystemExit) as exc:
        if ep is None:
            raise EstimatorLoadError(f"estimator {name!r}: cannot be imported: {_one_line(exc)}") from None
        _FAILED[name] = _one_line(exc)
        log.warning("estimator plugin %s = %s is unavailable: %s", name, ep.value, _FAILED[name])
        raise EstimatorLoadError(f"estimator {name!r} (plugin {ep.value}) is unavailable: {_FAILED[name]}") from None
    _LOADED[name] = cls
    return cls


def list_estimators() -> list[str]:
    """Names of every estimator that can be looked up by name, sorted: the built-ins, the
    registered classes and the plugins that load (a plugin is imported here the first time)."""
    for name in list(_plugins()):
        if name not in _LOADED and name not in _FAILED:
            try:
                get_estimator(name)
            except EstimatorLoadError:
                pass
    usable = set(BUILTIN_ESTIMATORS) | set(_REGISTERED) | {n for n in _plugins() if n in _LOADED}
    return sorted(usable)


def unavailable_estimators() -> dict[str, str]:
    """``{name: one-line reason}`` of every installed plugin that cannot be loaded."""
    list_estimators()
    return dict(sorted(_FAILED.items()))


def make_config(name: str, overrides: Mapping[str, Any] | None = None) -> Any:
    """Estimator ``name``'s Config with ``{"field": "value"}`` overrides applied and checked.

    String values are read by the field's type (``--set`` text); others are taken as they
    are. Errors name the estimator: ``akaze-guided.hamming_threshold = 0: must be >= 1``.
    """
    return from_overrides(
        get_estimator(name).Config,
        overrides,
        name,
        unknown="unknown config key",
        listed_by=f"floorvo list --config {name}",
    )

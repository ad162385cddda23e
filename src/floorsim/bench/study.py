"""Study files: a sweep file grown into the whole record of a lighting-robustness study.

A study (or sweep) file is TOML, read through the one configuration mechanism
(:mod:`floorvo.config`: unknown keys, wrong types and broken rules refused in one line
naming the key)::

    name = "led_height_breaking"          # default: the file name
    description = "..."                   # one line for the report
    base = "../demo.toml"                 # scene file, relative to the study file
    estimators = ["phase-corr"]           # default: every estimator the sequence supports
    repetitions = 3                       # seeds: scene seed + k, or
    seeds = [7, 8, 9]                     # the seeds themselves (floor, noise, jitter)
    confidence = 0.95                     # of every interval the report states
    sequences = ["../recordings/hall"]    # sequence folders run beside (not rendered, not varied)

    [render]                              # every job: frames, scale, spp (as floorsim bench)
    frames = 8

    [set]                                 # fixed scene overrides
    "sensor.read_noise_e" = 2.0

    [estimator_config.phase-corr]         # an estimator's config (as --est-set NAME.KEY=VALUE)
    upsample = 50

    [vary]                                # a grid: every combination of these values
    "lights.side" = ["both", "left"]

    [search]                              # a breaking-point search (per [vary] combination)
    key = "lights.height_mm"
    low = 0.2
    high = 3.0
    fails = "below"                       # the criterion holds below the breaking point
    tolerance = 0.1                       # bracket width: key units (linear), relative (log)
    scale = "linear"                      # or "log"

    [criterion]                           # fails when any declared metric is worse than its bound
    end_drift_pct = 1.0                   # end drift above 1 %
    lost_frames = 0                       # more than 0 frames lost

    [operating_point]                     # the paper rig's value of a varied or searched key
    "lights.height_mm" = 3.0              # (default: the base scene's own value)

A file needs ``[vary]`` or ``[search]`` (or both) and their ``base``, or only ``sequences``;
``[search]`` needs ``[criterion]``.
Criterion keys are metric names declared in :mod:`floorvo.metric_defs` with a direction
(lower or higher is better). Scene keys are ``--set`` keys (``section.key``).

:func:`write_study_record` writes what makes a results folder the record of its study:
``study.toml`` (the file as it was) and ``study.json`` (the resolved study, the base
scene as resolved, the package versions).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import os
import platform
import sys
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

from floorsim.bench.bench import MAX_REPETITIONS, is_sequence_folder, sequence_content_sha256
from floorsim.bench.results import RESULTS_CSV, STUDY_RECORD
from floorsim.bench.search import Bound, Criterion
from floorsim.scene import Scene
from floorsim.simulate import package_versions as render_versions
from floorvo import metric_defs as md
from floorvo.config import MAX_SEED, Config, build, describe_fields, param, to_plain
from floorvo.errors import ConfigError, ConfigFieldError, FloorbenchError, shorten, shown
from floorvo.io import atomic_write_bytes, atomic_write_json, code_sha256, plain, read_toml

__all__ = [
    "MAX_SWEEP_JOBS",
    "MAX_SEARCH_VALUES",
    "StudyFile",
    "StudyRender",
    "SearchSpec",
    "SweepSpec",
    "as_override",
    "load_sweep",
    "parse_criterion",
    "scene_key_unit",
    "write_study_record",
    "study_record",
    "resume_problem",
    "RESULT_KEYS",
]

log = logging.getLogger(__name__)


#: The most jobs (grid points x repetitions, or a search's combinations x repetitions) a study may ask for.
MAX_SWEEP_JOBS = 10_000
#: The most values a search grid may hold ((high - low) / tolerance); bisection renders about log2 of it.
MAX_SEARCH_VALUES = 1_000_000


def as_override(value: Any) -> str:
    """A TOML value as a ``--set`` string (``true``, ``3.0``, ``"both"`` -> ``both``)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, dict)):
        return json.dumps(value)
    return str(value)


# ----------------------------------------------------------------------------- the file format
@dataclass(frozen=True)
class StudyRender(Config):
    """``[render]``: render settings of every job (``floorsim bench --frames/--scale/--spp``)."""

    frames: int | None = param(None, unit="frames", min=2, doc="frames per sequence, 2 at least (none: the scene's)")
    scale: float | None = param(None, gt=0, max=4.0, doc="image size factor (none: full size)")
    spp: int | None = param(None, min=1, doc="samples per pixel (none: the scene's)")


@dataclass(frozen=True)
class SearchSpec(Config):
    """``[search]``: a breaking-point search over one numeric scene key (see :mod:`floorsim.bench.search`)."""

    key: str = param(doc="the scene key searched (section.key)")
    low: float = param(doc="lowest value searched")
    high: float = param(doc="highest value searched")
    fails: str = param(choices=("below", "above"), doc="side of the breaking point where the criterion holds")
    tolerance: float = param(gt=0, doc="largest bracket at the end: key units (linear), a ratio - 1 (log)")
    scale: str = param("linear", choices=("linear", "log"), doc="bisect the value or its logarithm")

    def validate(self) -> None:
        if not self.high > self.low:
            raise ConfigFieldError("high", f" = {self.high}: must be > low ({self.low})")
        if self.scale == "log" and self.low <= 0:
            raise ConfigFieldError("low", f" = {self.low}: must be > 0 on a log scale")
        steps = (
            math.log(self.high / self.low) / math.log1p(self.tolerance)
            if self.scale == "log"
            else (self.high - self.low) / self.tolerance
        )
        if not steps < MAX_SEARCH_VALUES:
            raise ConfigFieldError(
                "tolerance", f" = {self.tolerance}: the grid would hold more than {MAX_SEARCH_VALUES} values"
            )

    @property
    def fails_below(self) -> bool:
        return self.fails == "below"


@dataclass(frozen=True)
class StudyFile(Config):
    """A study (sweep) file as written (see the module doc)."""

    base: str | None = param(None, doc="base scene file, relative to the study file (none: sequences alone)")
    name: str | None = param(None, doc="the study's name (none: the file name)")
    description: str = param("", doc="one line for the report")
    estimators: tuple[str, ...] | None = param(None, doc="estimator names (none: every one the sequence supports)")
    estimator_config: dict = param(default_factory=dict, doc="per estimator: a table of its config keys")
    repetitions: int = param(1, min=1, max=MAX_REPETITIONS, doc="renders per point, seeds scene seed + k")
    seeds: tuple[int, ...] | None = param(None, doc="the seeds of the repetitions (replaces repetitions)")
    confidence: float = param(0.95, gt=0, lt=1, doc="confidence of the stated intervals")
    render: StudyRender = param(default_factory=StudyRender)
    set: dict = param(default_factory=dict, doc="fixed scene overrides")
    vary: dict = param(default_factory=dict, doc="scene key -> list of values: the grid")
    search: SearchSpec | None = param(None, doc="a breaking-point search")
    criterion: dict = param(default_factory=dict, doc="declared metric -> bound: when a run fails")
    operating_point: dict = param(default_factory=dict, doc="the paper rig's value of a varied or searched key")
    sequences: tuple[str, ...] = param((), doc="sequence folders run beside, relative to the study file")

    def validate(self) -> None:
        if self.name is not None and not self.name:
            raise ConfigFieldError("name", " = '': must be a non-empty string")
        if self.base is not None and not self.vary and self.search is None:
            raise ConfigFieldError("vary", ": give [vary] (a grid) or [search] (a breaking point), or both")
        if self.base is None and (self.vary or self.search is not None):
            raise ConfigFieldError(
                "[vary]" if self.vary else "[search]", " needs base = the scene file whose keys it varies"
            )
        for k, v in self.vary.items():
            if not isinstance(v, list) or not v:
                raise ConfigFieldError(f"vary.{shorten(k)}", f" = {shown(v)}: must be a non-empty list of values")
            if len({as_override(x) for x in v}) != len(v):
                raise ConfigFieldError(f"vary.{shorten(k)}", f" = {shown(v)}: values must be distinct")
        if self.search is not None and self.search.key in self.vary:
            raise ConfigFieldError("search.key", f" = {shown(self.search.key)}: is varied in [vary] too")
        for k, v in self.set.items():  # a fixed value the grid or the search replaces would be ignored
            if k in self.vary:
                raise ConfigFieldError(f"set.{shorten(k)}", f" = {shown(v)}: is varied in [vary] too")
            if self.search is not None and k == self.search.key:
                raise ConfigFieldError(f"set.{shorten(k)}", f" = {shown(v)}: is searched in [search] too")
        if self.search is not None and not self.criterion:
            raise ConfigFieldError("criterion", ": a [search] needs a [criterion] (when does a run fail?)")
        if self.estimators is not None and not self.estimators:
            raise ConfigFieldError("estimators", " = []: must name at least one estimator (or be left out)")
        if self.estimators is not None and len(set(self.estimators)) != len(self.estimators):
            raise ConfigFieldError("estimators", f" = {list(self.estimators)!r}: must name each estimator once")
        if self.seeds is not None:
            if (
                not self.seeds
                or len(set(self.seeds)) != len(self.seeds)
                or min(self.seeds) < 0
                or max(self.seeds) > MAX_SEED
            ):
                raise ConfigFieldError(
                    "seeds", f" = {shorten(str(list(self.seeds)))}: must be distinct integers from 0 to {MAX_SEED}"
                )
        for name, cfg in self.estimator_config.items():
            if not isinstance(cfg, dict):
                raise ConfigFieldError(
                    f"estimator_config.{shorten(name)}", f" = {shown(cfg)}: must be a table of config keys"
                )
            if self.estimators is not None and name not in self.estimators:
                raise ConfigFieldError(
                    f"estimator_config.{shorten(name)}",
                    f": {shown(name)} is not among estimators ({', '.join(self.estimators)})",
                )
        jobs = self.repetitions if self.seeds is None else len(self.seeds)
        for v in self.vary.values():
            jobs *= len(v)
        if jobs > MAX_SWEEP_JOBS:
            what = "combinations x repetitions, each searched" if self.search is not None else "values x repetitions"
            raise ConfigFieldError("vary", f": the study holds {jobs} jobs ({what}); at most {MAX_SWEEP_JOBS}")
        keys = set(self.vary) | ({self.search.key} if self.search is not None else set())
        for k in self.operating_point:
            if k not in keys:
                raise ConfigFieldError(
                    f"operating_point.{shorten(k)}",
                    f": not a varied or searched key (those: {', '.join(sorted(keys))})",
                )
        parse_criterion(self.criterion)


def parse_criterion(table: dict[str, Any]) -> Criterion | None:
    """The ``[criterion]`` table as a :class:`Criterion` (None when empty).

    Every key must be a metric declared in :mod:`floorvo.metric_defs` with a direction;
    every bound a finite number within the metric's declared range (``low``, ``high``:
    ``end_drift_pct = -1`` failed every run). Refusals name ``criterion.KEY``.
    """
    bounds = []
    for name, limit in table.items():
        try:
            d = md.metric(name)
        except ValueError:
            raise ConfigFieldError(
                f"criterion.{shorten(name)}",
                ": not a declared metric (floorvo.metric_defs: e.g. end_drift_pct, lost_frames, ate_se2_rmse_mm)",
            ) from None
        if d.lower_is_better is None:
            raise ConfigFieldError(
                f"criterion.{shorten(name)}", f": {d.description} has no better direction, so no bound can fail it"
            )
        if (
            isinstance(limit, bool)
            or not isinstance(limit, (int, float))
            or limit != limit
            or abs(limit) == float("inf")
        ):
            raise ConfigFieldError(
                f"criterion.{shorten(name)}", f" = {shown(limit)}: must be a finite number ({d.unit or 'no unit'})"
            )
        if (d.low is not None and limit < d.low) or (d.high is not None and limit > d.high):
            # end_drift_pct = -1: a bound no run can meet (or, past the other end, that none can fail)
            raise ConfigFieldError(
                f"criterion.{shorten(name)}",
                f" = {shown(limit)}: must be {d.range_text()}, the range of {d.description} (a bound outside "
                "it fails every run, or none)",
            )
        bounds.append(Bound(name, float(limit), bool(d.lower_is_better), d.unit))
    return Criterion(tuple(bounds)) if bounds else None


def scene_key_unit(key: str) -> str:
    """The unit a scene key declares (``lights.height_mm`` -> ``mm``), or ``""``."""
    for f in describe_fields(Scene):
        if f.key == key:
            return f.unit
    return ""


# ----------------------------------------------------------------------------- the resolved study
@dataclass(frozen=True)
class SweepSpec:
    """A parsed study (sweep) file, paths resolved and overrides as ``--set`` text.

    ``vary``: the grid keys and their values; ``fixed``: the ``[set]`` overrides;
    ``render``: the set ``[render]`` keys; ``search`` / ``criterion``: None when absent;
    ``seeds``: the repetitions' seeds (None: scene seed + k); ``estimator_config``: per
    estimator, its config keys; ``path``: the study file.
    """

    name: str
    base: Path | None  # None: a study of sequence folders alone (no grid, no search)
    vary: dict[str, list[Any]]
    estimators: list[str] | None = None
    repetitions: int = 1
    render: dict[str, Any] = field(default_factory=dict)
    fixed: dict[str, str] = field(default_factory=dict)
    operating_point: dict[str, Any] = field(default_factory=dict)
    search: SearchSpec | None = None
    criterion: Criterion | None = None
    seeds: tuple[int, ...] | None = None
    confidence: float = 0.95
    estimator_config: dict[str, dict[str, Any]] = field(default_factory=dict)
    description: str = ""
    path: Path | None = None
    sequences: list[Path] = field(default_factory=list)

    def seed(self, scene_seed: int, repetition: int) -> int:
        """The render seed of ``repetition`` (the study's seeds, else scene seed + k)."""
        return self.seeds[repetition] if self.seeds is not None else scene_seed + repetition


def _beside(path: Path, name: str, key: str) -> Path:
    """``name`` (a path in the study file, relative to it) as an absolute path."""
    try:
        return (path.parent / name).resolve()
    except (ValueError, OSError) as exc:  # an embedded NUL byte, a loop of links
        raise ConfigError(f"{path}: {key} = {shown(name)}: not a usable path ({shorten(str(exc))})") from None


def load_sweep(path: str | os.PathLike) -> SweepSpec:
    """Read and check a study or sweep file (ConfigError naming the key, the value and the rule).

    A file of sequence folders alone (``sequences``) needs no base and no grid. A grid may
    hold at most :data:`MAX_SWEEP_JOBS` jobs, a search grid :data:`MAX_SEARCH_VALUES` values.
    """
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: study file does not exist")
    d = read_toml(path, ConfigError)
    known = [f.name for f in dataclasses.fields(StudyFile)]
    unknown = set(d) - set(known)
    if unknown:  # all of them at once, in the file's own words
        raise ConfigError(
            f"{path}: unknown key(s) {shorten(', '.join(sorted(unknown)))} (known: {', '.join(sorted(known))})"
        )
    seqs = d.get("sequences", [])
    if not isinstance(seqs, list) or not all(isinstance(q, str) for q in seqs):
        raise ConfigError(f"{path}: sequences = {shown(seqs)}: must be a list of sequence folders")
    sequences = [_beside(path, q, "sequences") for q in seqs]
    named: dict[str, Path] = {}
    for q, full in zip(seqs, sequences):
        if not is_sequence_folder(full):
            raise ConfigError(f"{path}: sequences: {shown(q)}: not a sequence folder (no {full / 'sequence.json'})")
        other = named.setdefault(full.name, full)  # a job and its run folders are named after the folder
        if other is not full:
            why = (
                "is listed twice" if other.resolve() == full.resolve() else f"has the name of {shorten(str(other))} too"
            )
            raise ConfigError(f"{path}: sequences: {shown(q)} {why}: each sequence folder once, with a name of its own")
    base: Path | None = None
    if "base" in d or not sequences:  # a study of sequence folders alone has no grid
        if not isinstance(d.get("base"), str) or not d["base"]:
            given = f"base = {shown(d['base'])}" if "base" in d else "base is missing"
            raise ConfigError(f"{path}: {given}: must name the base scene file")
        base = _beside(path, d["base"], "base")
        if not base.is_file():
            raise ConfigError(f"{path}: base = {shown(d['base'])}: scene file {shorten(str(base))} does not exist")
    try:
        f: StudyFile = build(StudyFile, d)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None
    reps = len(f.seeds) if f.seeds is not None else f.repetitions
    if f.seeds is not None and "repetitions" in d and d["repetitions"] != reps:
        raise ConfigError(f"{path}: repetitions = {f.repetitions}: {len(f.seeds)} seeds are given")
    return SweepSpec(
        name=f.name or path.stem,
        base=base,
        vary={k: list(v) for k, v in f.vary.items()},
        estimators=list(f.estimators) if f.estimators is not None else None,
        repetitions=reps,
        render={k: v for k, v in to_plain(f.render).items() if v is not None},
        fixed={k: as_override(v) for k, v in f.set.items()},
        operating_point=dict(f.operating_point),
        search=f.search,
        criterion=parse_criterion(f.criterion),
        seeds=f.seeds,
        confidence=f.confidence,
        estimator_config={k: dict(v) for k, v in f.estimator_config.items()},
        description=f.description,
        path=path.resolve(),
        sequences=sequences,
    )


# ----------------------------------------------------------------------------- the record
def package_versions() -> dict[str, str]:
    """Versions of what a study's numbers depend on (the renderer's, the estimators', Dask)."""
    v = dict(render_versions())
    for dist in ("scipy", "opencv-python-headless", "scikit-image", "dask", "distributed"):
        try:
            v[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            v[dist] = "not installed"
    v["platform"] = platform.platform()
    return v


#: The parts of a study's record (``study.json``) its rows depend on, beside the job itself: a
#: sweep resumes into a results folder only when these are the same (:func:`resume_problem`).
#: The grid and the search (``vary``, ``search``, ``repetitions``) may grow: they only add jobs.
RESULT_KEYS = ("base_scene", "set", "render", "estimators", "estimator_config", "seeds", "sequences", "externals")
#: What made a study's rows besides its file (:func:`made_by`, ``study.json``'s ``made_by``): the
#: code and library versions, the content of its sequence folders. A resume into a folder whose
#: rows other code made (an estimator edited, floorvo's version number unchanged) is refused too.
MADE_BY_KEYS = ("versions", "floorvo", "bench", "estimators", "sequences")
#: The library versions a study's numbers depend on (``made_by.versions``); the platform, Python and
#: Dask's are recorded in ``versions`` but a resume elsewhere is not refused for them.
MADE_BY_VERSIONS = (
    "floorsim",
    "floorvo",
    "render_code",
    "numpy",
    "mitsuba",
    "drjit",
    "scipy",
    "opencv-python-headless",
    "scikit-image",
)
#: The floorsim modules that make a study's rows from its renders (runs, scores, rows).
BENCH_CODE = ("floorsim.bench.bench", "floorsim.bench.estimators", "floorsim.bench.sweep", "floorsim.bench.search")


def _estimator_code(names: list[str] | None) -> dict[str, str]:
    """``{estimator: where it comes from and the fingerprint of its module}`` of the study's Python
    estimators (every registered one when ``names`` is None): a plugin's version and code."""
    from floorvo.estimators import estimator_source, list_estimators

    out = {}
    for name in list_estimators() if names is None else names:
        try:
            src = estimator_source(name)
            module = src.target.partition(":")[0]
            out[name] = f"{src.describe()} {code_sha256(module) if module else ''}".strip()
        except (FloorbenchError, ImportError, OSError):  # a double, or a plugin that does not load
            out[name] = "unknown"
    return out


def made_by(spec: SweepSpec, versions: dict[str, Any]) -> dict[str, Any]:
    """``study.json``'s ``made_by`` (:data:`MADE_BY_KEYS`): the library versions and renderer code
    of ``versions`` (:data:`MADE_BY_VERSIONS`), the fingerprints of floorvo's code (the built-in
    estimators, the runner, the scores: :func:`floorvo.io.code_sha256`) and of the bench's
    (:data:`BENCH_CODE`), each estimator's source and code, and each sequence folder's content."""
    return {
        "versions": {k: versions.get(k) for k in MADE_BY_VERSIONS},
        "floorvo": code_sha256("floorvo"),
        "bench": code_sha256(*BENCH_CODE),
        "estimators": _estimator_code(spec.estimators),
        "sequences": {str(q): sequence_content_sha256(q) for q in spec.sequences},
    }


def _result_parts(record: dict) -> dict:
    study = record.get("study") or {}
    parts = {k: study.get(k) for k in RESULT_KEYS if k != "base_scene"}
    parts["base_scene"] = record.get("base_scene")
    return json.loads(json.dumps(plain(parts), default=str))  # as it reads back from study.json


def _made_by_differs(old: Any, new: dict) -> list[str]:
    """The parts of ``made_by`` (with the estimators, versions or sequences named) that differ."""
    old = json.loads(json.dumps(plain(old), default=str)) if isinstance(old, dict) else {}
    new = json.loads(json.dumps(plain(new), default=str))
    out = []
    for k in MADE_BY_KEYS:
        a, b = old.get(k), new.get(k)
        if a == b:
            continue
        if isinstance(a, dict) and isinstance(b, dict):
            out += [f"{k}.{sub}" for sub in sorted(set(a) | set(b)) if a.get(sub) != b.get(sub)]
        else:
            out.append(k)
    return out


def resume_problem(spec: SweepSpec, out_dir: str | os.PathLike, base_scene: dict | None, externals: dict) -> str:
    """Why the results folder ``out_dir`` holds another study's rows (its ``study.json`` differs
    from this one in :data:`RESULT_KEYS`), or rows made by other code (its ``made_by`` differs:
    :func:`made_by`), "" when it holds none or this study's. A sweep into the folder of another
    study (another base scene, fixed keys, render settings, estimators) kept that study's rows
    for every job name the two shared, and reported them as its own; one resumed after an
    estimator's code was edited kept the old code's rows beside the new code's. A record written
    before ``made_by`` was is resumed with a warning."""
    path = Path(out_dir) / STUDY_RECORD
    if not path.is_file():
        return ""
    try:
        old = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        old = None
    if not isinstance(old, dict):
        return f"{path}: not a readable study record; a sweep resumes only a folder of its own study"
    record = study_record(spec, base_scene, externals)
    new = _result_parts(record)
    before = _result_parts(old)
    if "externals" not in (old.get("study") or {}):  # written before externals were recorded
        before["externals"] = new["externals"]
    differ = [k for k in RESULT_KEYS if before.get(k) != new.get(k)]
    if differ:
        return (
            f"{Path(out_dir)}: holds the results of another study (its study.json differs in {', '.join(differ)}); "
            "a sweep resumes only its own study: choose another output folder"
        )
    if "made_by" not in old:
        log.warning(
            "%s: its rows record no code (written before study.json had made_by): not checked that this code made them",
            path,
        )
        return ""
    changed = _made_by_differs(old["made_by"], record["made_by"])
    if changed and (Path(out_dir) / RESULTS_CSV).is_file():  # without rows nothing is reused
        return (
            f"{Path(out_dir)}: its rows were made by other code or inputs (study.json's made_by differs in "
            f"{shorten(', '.join(changed))}); a sweep resumes only rows this code would make: choose another "
            "output folder, or remove its results.csv to run the study again there"
        )
    return ""


def study_record(spec: SweepSpec, base_scene: dict | None = None, externals: dict | None = None) -> dict:
    """What ``study.json`` holds (see :func:`write_study_record`); ``externals``: the external
    programs run in every job, name -> SHA-256 of the command line."""
    versions = package_versions()
    return {
        "study": {
            "name": spec.name,
            "description": spec.description,
            "file": str(spec.path) if spec.path else None,
            "base": str(spec.base) if spec.base is not None else None,
            "estimators": spec.estimators,
            "estimator_config": spec.estimator_config,
            "repetitions": spec.repetitions,
            "seeds": list(spec.seeds) if spec.seeds is not None else None,
            "confidence": spec.confidence,
            "render": spec.render,
            "set": spec.fixed,
            "vary": spec.vary,
            "search": to_plain(spec.search) if spec.search is not None else None,
            "criterion": {b.metric: b.limit for b in spec.criterion.bounds} if spec.criterion else None,
            "operating_point": spec.operating_point,
            "sequences": [str(q) for q in spec.sequences],
            "externals": dict(sorted((externals or {}).items())),
        },
        "base_scene": base_scene,
        "versions": versions,
        "made_by": made_by(spec, versions),
        "command": [Path(sys.argv[0]).name, *sys.argv[1:]],
    }


def remove_study_record(out_dir: str | os.PathLike) -> None:
    """Remove ``DIR/study.toml`` and ``DIR/study.json`` (:func:`write_study_record`'s), where they are."""
    for name in ("study.toml", STUDY_RECORD):
        (Path(out_dir) / name).unlink(missing_ok=True)


def write_study_record(
    spec: SweepSpec, out_dir: str | os.PathLike, base_scene: dict | None = None, externals: dict | None = None
) -> Path:
    """Write ``DIR/study.toml`` (the study file as it was) and ``DIR/study.json`` (the
    resolved study, ``base_scene``: the base scene as resolved, the external programs, the
    package versions, the command line); returns the JSON's path. A re-run of the study
    overwrites both, so two results folders of one study can be diffed."""
    out = Path(out_dir)
    if spec.path is not None:
        atomic_write_bytes(out / "study.toml", spec.path.read_bytes())
    record = study_record(spec, base_scene, externals)
    path = out / STUDY_RECORD
    atomic_write_json(path, record)
    return path

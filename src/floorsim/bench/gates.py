"""Regression gates: compare a bench's metrics with a stored baseline.

A baseline file (JSON, written by :func:`save_baseline`, read by :func:`load_baseline`)::

    {"format": "floorbench-baseline", "version": 1,
     "tolerances": {"end_drift_pct": {"abs": 0.05, "rel": 0.05}, ...},
     "entries": {"SCENE/ESTIMATOR": {"end_drift_pct": 0.31, ...}, ...}}

``tolerances`` names the gated metrics with a finite, non-negative ``abs`` and ``rel``; ``entries`` holds, per ``scene/estimator``, the mean of
each gated metric over the repetitions: a finite number, or ``null`` when the baseline run
had no value for it (it failed or lost track). Anything else (an entry that is not a table,
a value that is text, a list or NaN, a missing metric, no tolerances or no entries) is
refused in one line by :func:`parse_baseline`, the one reader of the format, so a
malformed baseline can never pass by checking nothing.

A metric got worse when

    value > baseline + max(abs, rel * |baseline|)

for a metric whose declaration (:mod:`floorvo.metric_defs`) says lower is better (all the
default gates, and any metric that is not declared), or

    value < baseline - max(abs, rel * |baseline|)

for one declared higher-is-better (``tracked_fraction``, ``fps``); or when it was finite in the baseline and is missing or NaN now (the run lost track or
failed). Every ``scene/estimator`` of the current bench is expected in the baseline: one
without an entry fails the gate unless ``allow_new`` (``floorsim bench --allow-new``), and
a gate that checked no metric at all fails. The summary says how many metrics were checked
of how many expected (every gated metric of every ``scene/estimator`` of the bench).
Entries only in the baseline are listed but fail nothing (a bench may run fewer scenes).
Edit the tolerances in the file to tighten or loosen a gate.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from floorsim.bench.estimators import RUN_FIGURES
from floorvo import metric_defs as md
from floorvo.errors import ConfigError, shorten, shown
from floorvo.io import atomic_write_json, read_json

__all__ = [
    "DEFAULT_TOLERANCES",
    "Tolerance",
    "Baseline",
    "Regression",
    "GateResult",
    "aggregate",
    "make_baseline",
    "made_with",
    "save_baseline",
    "parse_baseline",
    "load_baseline",
    "compare",
]

BASELINE_FORMAT = "floorbench-baseline"
BASELINE_VERSION = 1

#: Gated metrics (all lower-is-better) and their default tolerances. Timing is machine
#: dependent, so its tolerance is wide (twice as slow plus 2 ms fails).
DEFAULT_TOLERANCES: dict[str, dict[str, float]] = {
    md.ate_rmse("none").name: {"abs": 0.01, "rel": 0.05},
    md.ate_rmse("se2").name: {"abs": 0.01, "rel": 0.05},
    md.RPE_FRAME_TRANS_RMSE.name: {"abs": 0.005, "rel": 0.05},
    md.RPE_FRAME_ROT_RMSE.name: {"abs": 0.005, "rel": 0.05},
    md.END_DRIFT.name: {"abs": 0.05, "rel": 0.05},
    md.SEG_MEAN_T_ERR.name: {"abs": 0.05, "rel": 0.05},
    md.LOST_FRAMES.name: {"abs": 0.0, "rel": 0.0},
    md.time_mean("total_ms").name: {"abs": 2.0, "rel": 1.0},
}


def _higher_is_better(metric: str) -> bool:
    """True for a metric declared higher-is-better; undeclared metrics count as lower-is-better."""
    try:
        return md.metric(metric).lower_is_better is False
    except ValueError:
        return False


def _by_size(metric: str) -> bool:
    """True for a signed error declared with no direction (``distance_error_pct``,
    ``turn_error_pct``: their magnitude counts): gated by its size. It was gated as lower-is-better,
    so -10.6 % passed against -0.65 % and +0.19 % failed."""
    try:
        d = md.metric(metric)
    except ValueError:
        return False
    return d.lower_is_better is None and d.low is None


def _gate_problem(metric: str) -> str:
    """Why ``metric`` cannot be gated ('' if it can): it is no metric of the score or figure of
    the run (:data:`floorsim.bench.estimators.RUN_FIGURES`; a misspelt ``lost_frame``, or the
    text column ``lost_reasons``, was stored and never checked, and the gate passed), or it is
    declared with no better direction and is no signed error (a path's length, a measured
    distance, a turn: what the run was, not how well it was measured)."""
    try:
        d = md.metric(metric)
    except ValueError as exc:
        if metric in RUN_FIGURES:
            return ""
        return f"{exc} or a figure of the run ({', '.join(RUN_FIGURES)})"
    if d.lower_is_better is None and d.low is not None:
        return f"{d.description} has no better direction: not a quality a gate can hold"
    return ""


def _key(row: Mapping[str, Any]) -> str:
    return f"{row['scene']}/{row['estimator']}"


def made_with(rows: Iterable[Mapping[str, Any]]) -> dict[str, dict[str, list]]:
    """Per ``scene/estimator``, what its runs were made with: the sorted ``inputs`` of its rows
    (:func:`floorsim.bench.bench.run_inputs`: the scene as resolved with ``--set``, the seed and
    ``--frames/--scale/--spp``, or a sequence folder's content), its seeds (the repetitions) and its
    ``--est-set`` configs (``est_config``: a change a gate may measure, noted but not refused), and
    its ``--scale-calibration`` files (``scale_calibration``: likewise; added or dropped, it had
    passed without a word).
    Rows without ``inputs`` (written before it was) give none."""
    out: dict[str, dict[str, list]] = {}
    for r in rows:
        if not r.get("inputs"):
            continue
        m = out.setdefault(_key(r), {"inputs": [], "seeds": [], "est_config": [], "scale_calibration": []})
        m["inputs"].append(str(r["inputs"]))
        m["seeds"].append(r.get("seed"))
        m["est_config"].append(str(r.get("est_config") or ""))
        m["scale_calibration"].append(str(r.get("scale_calibration") or ""))
    for m in out.values():
        m["inputs"].sort()
        m["est_config"] = sorted(set(m["est_config"]))
        m["scale_calibration"] = sorted(set(m["scale_calibration"]))
        m["seeds"].sort(key=lambda v: (v is None, v if v is not None else 0))
    return out


def _num(v: Any) -> float:
    try:
        f = float(v)
    except (TypeError, ValueError, OverflowError):
        return float("nan")
    return f


def aggregate(rows: Iterable[Mapping[str, Any]], metrics: Iterable[str]) -> dict[str, dict[str, float]]:
    """Mean of each metric over the repetitions of each ``scene/estimator`` (NaN if any is NaN)."""
    metrics = list(metrics)
    groups: dict[str, list[Mapping[str, Any]]] = {}
    for r in rows:
        groups.setdefault(_key(r), []).append(r)
    out: dict[str, dict[str, float]] = {}
    for key, rs in groups.items():
        out[key] = {}
        for m in metrics:
            vals = [_num(r.get(m)) for r in rs]
            out[key][m] = sum(vals) / len(vals) if vals and all(math.isfinite(v) for v in vals) else float("nan")
    return out


@dataclass(frozen=True)
class Tolerance:
    """How much worse a metric may get: ``max(abs, rel * |baseline|)`` (both finite, >= 0)."""

    abs: float = 0.0
    rel: float = 0.0

    def allowed(self, base: float, higher_is_better: bool = False) -> float:
        """The worst value that still passes against ``base``: the largest for a lower-is-better
        metric, the smallest for a higher-is-better one."""
        margin = max(self.abs, self.rel * abs(base))
        return base - margin if higher_is_better else base + margin


@dataclass(frozen=True)
class Baseline:
    """A checked baseline: gated metrics with their tolerances, and per ``scene/estimator``
    the baseline value of each (None: the baseline run had no value)."""

    tolerances: dict[str, Tolerance]
    entries: dict[str, dict[str, float | None]]
    #: per ``scene/estimator``, what its runs were made with (:func:`made_with`); empty in a
    #: baseline saved before it was recorded
    made_with: dict[str, dict[str, list]] = field(default_factory=dict)

    def to_dict(self) -> dict:
        """The file's content (format, version, tolerances, entries, made_with)."""
        out = {
            "format": BASELINE_FORMAT,
            "version": BASELINE_VERSION,
            "tolerances": {m: {"abs": t.abs, "rel": t.rel} for m, t in self.tolerances.items()},
            "entries": {k: dict(v) for k, v in self.entries.items()},
        }
        if self.made_with:
            out["made_with"] = {k: dict(v) for k, v in self.made_with.items()}
        return out


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


#: What :func:`_table` is given for a key the file lacks (a JSON null is a value, None).
_MISSING = object()


def _table(d: Any, where: str, what: str) -> Mapping[str, Any]:
    if d is _MISSING:
        raise ConfigError(f"{where}: missing: must be a table of {what}")
    if not isinstance(d, Mapping):
        raise ConfigError(f"{where} = {shown(d)}: must be a table of {what}")
    if not d:
        raise ConfigError(f"{where}: empty; a baseline that names no {what} would check nothing")
    return d


def parse_baseline(obj: Any, label: str = "baseline") -> Baseline:
    """The one reader of the baseline format: ``obj`` (parsed JSON) checked in full.

    Raises :class:`~floorvo.errors.ConfigError` with one line naming ``label``, the part of
    the file and the rule (see the module doc for the format).
    """
    if not isinstance(obj, Mapping) or obj.get("format") != BASELINE_FORMAT:
        raise ConfigError(f"{label}: not a floorbench baseline (format must be {BASELINE_FORMAT!r})")
    if obj.get("version") != BASELINE_VERSION:
        raise ConfigError(
            f"{label}: version {shown(obj.get('version'))} is not supported (expected {BASELINE_VERSION})"
        )
    unknown = sorted(set(obj) - {"format", "version", "tolerances", "entries", "made_with"})
    if unknown:
        raise ConfigError(
            f"{label}: unknown key {shown(unknown[0])} (known: entries, format, made_with, tolerances, version)"
        )
    tolerances: dict[str, Tolerance] = {}
    for metric, t in _table(obj.get("tolerances", _MISSING), f"{label}: tolerances", "gated metrics").items():
        where = f"{label}: tolerances.{shorten(metric)}"
        if not isinstance(t, Mapping) or set(t) - {"abs", "rel"} or not t:
            raise ConfigError(f'{where} = {shown(t)}: must be {{"abs": >= 0, "rel": >= 0}}')
        for k, v in t.items():
            if not _is_number(v) or v < 0:
                raise ConfigError(f"{where}.{k} = {shown(v)}: must be a finite number >= 0")
        problem = _gate_problem(str(metric))
        if problem:
            raise ConfigError(f"{where}: {problem}")
        tolerances[str(metric)] = Tolerance(float(t.get("abs", 0.0)), float(t.get("rel", 0.0)))
    entries: dict[str, dict[str, float | None]] = {}
    for key, entry in _table(obj.get("entries", _MISSING), f"{label}: entries", "scene/estimator entries").items():
        where = f"{label}: entries.{shorten(key)}"
        if not isinstance(key, str) or "/" not in key:
            raise ConfigError(f"{where}: an entry is named SCENE/ESTIMATOR")
        if not isinstance(entry, Mapping):
            raise ConfigError(f"{where} = {shown(entry)}: must be a table of metric values")
        for metric, v in entry.items():
            if metric not in tolerances:
                raise ConfigError(
                    f"{where}.{shorten(metric)}: not a gated metric (tolerances has: {', '.join(tolerances)})"
                )
            if v is not None and not _is_number(v):
                raise ConfigError(
                    f"{where}.{metric} = {shown(v)}: must be a finite number (or null: no value in the baseline run)"
                )
        missing = [m for m in tolerances if m not in entry]
        if missing:
            raise ConfigError(
                f"{where}: lacks {missing[0]} (every gated metric needs a value, null when the baseline run had none)"
            )
        entries[str(key)] = {m: (None if entry[m] is None else float(entry[m])) for m in tolerances}
    made: dict[str, dict[str, list]] = {}
    for key, m in (obj.get("made_with") or {}).items() if isinstance(obj.get("made_with"), Mapping) else ():
        if not isinstance(m, Mapping) or not all(isinstance(m.get(k), list) for k in ("inputs", "seeds")):
            raise ConfigError(
                f"{label}: made_with.{shorten(str(key))} = {shown(m)}: must be a table of lists inputs and seeds"
            )
        made[str(key)] = {
            "inputs": [str(v) for v in m["inputs"]],
            "seeds": list(m["seeds"]),
            "est_config": [str(v) for v in m.get("est_config") or []],
            **(
                {"scale_calibration": [str(v) for v in m["scale_calibration"]]}
                if isinstance(m.get("scale_calibration"), list)
                else {}
            ),
        }
    if "made_with" in obj and not isinstance(obj["made_with"], Mapping):
        raise ConfigError(f"{label}: made_with = {shown(obj['made_with'])}: must be a table of scene/estimator entries")
    return Baseline(tolerances, entries, made)


def make_baseline(
    rows: Iterable[Mapping[str, Any]], tolerances: Mapping[str, Mapping[str, float]] | None = None
) -> dict:
    """A baseline dict from bench rows (see the module doc for the format)."""
    tol = {k: dict(v) for k, v in (tolerances or DEFAULT_TOLERANCES).items()}
    rows = list(rows)
    agg = aggregate(rows, tol)
    entries = {k: {m: (v if math.isfinite(v) else None) for m, v in ms.items()} for k, ms in agg.items()}
    out = {"format": BASELINE_FORMAT, "version": BASELINE_VERSION, "tolerances": tol, "entries": entries}
    made = made_with(rows)
    if made:
        out["made_with"] = made
    return out


def save_baseline(path: str | os.PathLike, rows: Iterable[Mapping[str, Any]], tolerances=None) -> dict:
    """Write a baseline file atomically; returns its content.

    The content is checked by :func:`parse_baseline` before anything is written, so a
    baseline that could not be read back (no rows, bad tolerances) is refused.
    """
    b = make_baseline(rows, tolerances)
    parse_baseline(b, f"--save-baseline {path}")
    atomic_write_json(path, b)
    return b


def load_baseline(path: str | os.PathLike) -> Baseline:
    """Read and check a baseline file (ConfigError naming the file and the problem)."""
    path = Path(path)
    label = f"--baseline {path}"
    if path.is_dir():
        raise ConfigError(f"{label}: is a folder, not a baseline file (write one with --save-baseline)")
    if not path.is_file():
        raise ConfigError(f"{label}: file does not exist (write one with --save-baseline)")
    return parse_baseline(read_json(path, ConfigError, label=label), label)


@dataclass(frozen=True)
class Regression:
    """One metric of one ``scene/estimator`` that got worse than its baseline."""

    key: str
    metric: str
    baseline: float
    value: float
    allowed: float
    higher_is_better: bool = False
    by_size: bool = False  # a signed error, held by its magnitude (``allowed``: the largest size)

    def describe(self) -> str:
        if not math.isfinite(self.value):
            return f"{self.key}: {self.metric} is missing now (baseline {self.baseline:.6g})"
        if self.by_size:
            return (
                f"{self.key}: {self.metric} got worse: {self.value:.6g} against baseline {self.baseline:.6g} "
                f"(allowed up to {self.allowed:.6g} in size)"
            )
        # by the metric's direction: with no tolerance the limit is the baseline itself, and
        # comparing the two said 'up to' of a higher-is-better one's lower limit
        bound = "down to" if self.higher_is_better else "up to"
        return (
            f"{self.key}: {self.metric} got worse: {self.value:.6g} against baseline {self.baseline:.6g} "
            f"(allowed {bound} {self.allowed:.6g})"
        )


@dataclass
class GateResult:
    """Outcome of :func:`compare`.

    ``ok`` is False when a metric got worse, when a ``scene/estimator`` of the bench has no
    baseline entry (unless new ones were allowed), or when no metric was checked at all.
    ``checked`` of ``expected`` (every gated metric of every ``scene/estimator`` of the
    bench); ``no_baseline_value`` lists the ``(key, metric)`` pairs whose baseline is null.
    """

    regressions: list[Regression] = field(default_factory=list)
    improved: list[str] = field(default_factory=list)
    only_in_baseline: list[str] = field(default_factory=list)
    only_in_bench: list[str] = field(default_factory=list)
    no_baseline_value: list[tuple[str, str]] = field(default_factory=list)
    checked: int = 0
    expected: int = 0
    allow_new: bool = False
    #: ``scene/estimator: what differs`` of each entry whose baseline runs were made with other inputs
    made_otherwise: list[str] = field(default_factory=list)
    #: the baseline records no inputs (saved before they were): not checked
    inputs_unchecked: bool = False
    #: ``scene/estimator: ...`` of each entry run with another ``--est-set`` than its baseline (noted)
    config_changed: list[str] = field(default_factory=list)
    #: baseline entries whose scene ran in a bench of the default estimators but whose estimator did not
    missing_now: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return (
            not self.regressions
            and not self.made_otherwise
            and not self.missing_now
            and (self.allow_new or not self.only_in_bench)
            and self.checked > 0
        )

    def summary(self) -> str:
        lines = list(self.made_otherwise)
        lines += [r.describe() for r in self.regressions]
        for k in self.missing_now:
            lines.append(
                f"{k}: in the baseline, and its scene ran, but not this estimator (skipped or unavailable: see the "
                "bench's notes and warnings)"
            )
        for k in self.only_in_baseline:
            lines.append(f"{k}: in the baseline but not in this bench (not checked)")
        for k in self.only_in_bench:
            if self.allow_new:
                lines.append(f"{k}: new, no baseline (not checked; --allow-new)")
            else:
                lines.append(f"{k}: no baseline entry (add it with --save-baseline, or pass --allow-new)")
        by_key: dict[str, list[str]] = {}
        for k, m in self.no_baseline_value:
            by_key.setdefault(k, []).append(m)
        for k, ms in by_key.items():
            lines.append(f"{k}: {len(ms)} metric(s) not checked, the baseline run had no value ({', '.join(ms)})")
        lines += self.config_changed
        if self.inputs_unchecked:
            lines.append(
                "the baseline records no inputs (saved before they were): not checked that it was made with these "
                "scenes, --set, seeds, --frames/--scale/--spp and --est-set; save it again to have them checked"
            )
        if self.checked == 0:
            lines.append("no metric was checked: a gate that checks nothing passes nothing")
        verdict = "passed" if self.ok else "FAILED"
        lines.append(
            f"regression gate {verdict}: {len(self.regressions)} metric(s) worse; "
            f"checked {self.checked} of {self.expected} expected"
        )
        return "\n".join(lines)


def _configs(configs: list[str]) -> str:
    return " / ".join(c or "none" for c in configs) or "none"


def _made_otherwise(key: str, before: Mapping[str, list], now: Mapping[str, list]) -> str:
    """One line: the baseline's runs of ``key`` were made with other inputs than this bench's."""
    if before["seeds"] != now["seeds"]:
        what = f"seeds {before['seeds']}, now {now['seeds']} (scene seed or --repeat)"
    else:
        what = "another scene file, --set, --frames, --scale or --spp, or another sequence folder's content"
    return (
        f"{key}: not comparable, the baseline was made with other inputs ({what}); run the bench as the baseline "
        "was, or save a new baseline"
    )


def compare(
    rows: Iterable[Mapping[str, Any]],
    baseline: Baseline | Mapping[str, Any],
    *,
    allow_new: bool = False,
    estimators_chosen: bool = True,
) -> GateResult:
    """Compare bench rows with a baseline (see the module doc for the rule).

    ``baseline``: a :class:`Baseline`, or its file content (checked by :func:`parse_baseline`).
    ``allow_new``: a ``scene/estimator`` without a baseline entry does not fail the gate.
    ``estimators_chosen``: the bench ran the estimators it was given (``--estimators``); False
    when it ran those each sequence supports, and then a baseline entry whose scene ran but
    whose estimator did not (it broke on import, or its construction fails, and was skipped)
    fails the gate: it had passed, "not checked". An entry whose every value is null (its
    baseline runs failed) is no baseline entry where the runs have values now: it had exempted
    the estimator for good; where they still have none, its metrics are not checked, as before.
    """
    if not isinstance(baseline, Baseline):
        baseline = parse_baseline(baseline)
    tol = baseline.tolerances
    rows = list(rows)
    current = aggregate(rows, tol)
    # an entry with no value at all (its baseline runs failed) is no baseline entry for a run that has values now
    entries = {
        k: v
        for k, v in baseline.entries.items()
        if any(x is not None for x in v.values()) or not any(math.isfinite(x) for x in current.get(k, {}).values())
    }
    res = GateResult(allow_new=allow_new)
    res.only_in_baseline = sorted(set(entries) - set(current))
    res.only_in_bench = sorted(set(current) - set(entries))
    if not estimators_chosen:
        scenes_now = {str(r["scene"]) for r in rows}
        res.missing_now = [k for k in res.only_in_baseline if k.rsplit("/", 1)[0] in scenes_now]
        res.only_in_baseline = [k for k in res.only_in_baseline if k not in res.missing_now]
    res.expected = (len(current) + len(res.missing_now)) * len(tol)
    now = made_with(rows)
    res.inputs_unchecked = not baseline.made_with and bool(now)
    for key in sorted(set(entries) & set(current)):
        before = baseline.made_with.get(key)
        if before is not None and key in now:
            if (before["inputs"], before["seeds"]) != (now[key]["inputs"], now[key]["seeds"]):
                res.made_otherwise.append(_made_otherwise(key, before, now[key]))
                continue  # not comparable: its metrics are not checked
            if before.get("est_config", []) != now[key]["est_config"]:
                res.config_changed.append(
                    f"{key}: --est-set {_configs(now[key]['est_config'])}, the baseline's "
                    f"{_configs(before.get('est_config', []))}: the gate measures that change"
                )
            # (a baseline saved before the key was kept is not known to differ)
            if "scale_calibration" in before and before["scale_calibration"] != now[key]["scale_calibration"]:
                res.config_changed.append(
                    f"{key}: --scale-calibration {_configs(now[key]['scale_calibration'])}, the baseline's "
                    f"{_configs(before['scale_calibration'])}: the gate measures that change"
                )
        for metric, t in tol.items():
            base = entries[key][metric]
            if base is None:
                res.no_baseline_value.append((key, metric))
                continue
            value = current[key][metric]
            higher, size = _higher_is_better(metric), _by_size(metric)
            allowed = t.allowed(abs(base) if size else base, higher)
            res.checked += 1
            v = abs(value) if size else value
            if not math.isfinite(value) or (v < allowed if higher else v > allowed):
                res.regressions.append(Regression(key, metric, base, value, allowed, higher, size))
            elif (v > base) if higher else (v < (abs(base) if size else base)):
                res.improved.append(f"{key}: {metric} {value:.6g} (baseline {base:.6g})")
    return res

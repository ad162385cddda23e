"""Regression gates: compare a bench's metrics with a stored baseline.

A baseline file (JSON, written by :func:`save_baseline`) holds, per ``scene/estimator``,
the mean of each gated metric over the repetitions, and per metric a tolerance
``{"abs": a, "rel": r}``. A metric got worse when

    value > baseline + max(abs, rel * |baseline|)

(every gated metric is "lower is better"), or when it was finite in the baseline and is
missing or NaN now (the run lost track or failed). Entries only in the baseline or only
in the bench are listed but fail nothing. Edit the tolerances in the file to tighten or
loosen a gate.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from floorvo.errors import ConfigError
from floorvo.io import atomic_write_json, read_json

__all__ = [
    "DEFAULT_TOLERANCES",
    "Regression",
    "GateResult",
    "aggregate",
    "make_baseline",
    "save_baseline",
    "load_baseline",
    "compare",
]

BASELINE_FORMAT = "floorbench-baseline"
BASELINE_VERSION = 1

#: Gated metrics (all lower-is-better) and their default tolerances. Timing is machine
#: dependent, so its tolerance is wide (twice as slow plus 2 ms fails).
DEFAULT_TOLERANCES: dict[str, dict[str, float]] = {
    "ate_none_rmse_mm": {"abs": 0.01, "rel": 0.05},
    "ate_se2_rmse_mm": {"abs": 0.01, "rel": 0.05},
    "rpe_frame_trans_rmse_mm": {"abs": 0.005, "rel": 0.05},
    "rpe_frame_rot_rmse_deg": {"abs": 0.005, "rel": 0.05},
    "end_drift_pct": {"abs": 0.05, "rel": 0.05},
    "seg_mean_t_err_pct": {"abs": 0.05, "rel": 0.05},
    "lost_frames": {"abs": 0.0, "rel": 0.0},
    "time_total_ms_mean": {"abs": 2.0, "rel": 1.0},
}


def _key(row: Mapping[str, Any]) -> str:
    return f"{row['scene']}/{row['estimator']}"


def _num(v: Any) -> float:
    try:
        f = float(v)
    except (TypeError, ValueError):
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


def make_baseline(
    rows: Iterable[Mapping[str, Any]], tolerances: Mapping[str, Mapping[str, float]] | None = None
) -> dict:
    """A baseline dict from bench rows (see the module doc for the format)."""
    tol = {k: dict(v) for k, v in (tolerances or DEFAULT_TOLERANCES).items()}
    agg = aggregate(rows, tol)
    entries = {k: {m: (v if math.isfinite(v) else None) for m, v in ms.items()} for k, ms in agg.items()}
    return {"format": BASELINE_FORMAT, "version": BASELINE_VERSION, "tolerances": tol, "entries": entries}


def save_baseline(path: str | os.PathLike, rows: Iterable[Mapping[str, Any]], tolerances=None) -> dict:
    """Write a baseline file atomically; returns its content."""
    b = make_baseline(rows, tolerances)
    atomic_write_json(path, b)
    return b


def load_baseline(path: str | os.PathLike) -> dict:
    """Read and check a baseline file (ConfigError naming the file and the problem)."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"--baseline {path}: file does not exist (write one with --save-baseline)")
    b = read_json(path, ConfigError, label=f"--baseline {path}")
    if not isinstance(b, dict) or b.get("format") != BASELINE_FORMAT:
        raise ConfigError(f"--baseline {path}: not a floorbench baseline (format must be {BASELINE_FORMAT!r})")
    if b.get("version") != BASELINE_VERSION:
        raise ConfigError(
            f"--baseline {path}: version {b.get('version')!r} is not supported (expected {BASELINE_VERSION})"
        )
    for m, t in b.get("tolerances", {}).items():
        if not isinstance(t, dict) or any(
            not isinstance(t.get(k, 0), (int, float)) or t.get(k, 0) < 0 for k in ("abs", "rel")
        ):
            raise ConfigError(f'--baseline {path}: tolerance of {m} = {t!r}: must be {{"abs": >= 0, "rel": >= 0}}')
    return b


@dataclass(frozen=True)
class Regression:
    """One metric of one ``scene/estimator`` that got worse than its baseline."""

    key: str
    metric: str
    baseline: float
    value: float
    allowed: float

    def describe(self) -> str:
        if not math.isfinite(self.value):
            return f"{self.key}: {self.metric} is missing now (baseline {self.baseline:.6g})"
        return (
            f"{self.key}: {self.metric} got worse: {self.value:.6g} against baseline {self.baseline:.6g} "
            f"(allowed up to {self.allowed:.6g})"
        )


@dataclass
class GateResult:
    """Outcome of :func:`compare`: ``ok`` is False when anything got worse."""

    regressions: list[Regression] = field(default_factory=list)
    improved: list[str] = field(default_factory=list)
    only_in_baseline: list[str] = field(default_factory=list)
    only_in_bench: list[str] = field(default_factory=list)
    checked: int = 0

    @property
    def ok(self) -> bool:
        return not self.regressions

    def summary(self) -> str:
        lines = [r.describe() for r in self.regressions]
        for k in self.only_in_baseline:
            lines.append(f"{k}: in the baseline but not in this bench (not checked)")
        for k in self.only_in_bench:
            lines.append(f"{k}: new, no baseline (not checked)")
        verdict = "FAILED" if self.regressions else "passed"
        lines.append(f"regression gate {verdict}: {len(self.regressions)} metric(s) worse of {self.checked} checked")
        return "\n".join(lines)


def compare(rows: Iterable[Mapping[str, Any]], baseline: Mapping[str, Any]) -> GateResult:
    """Compare bench rows with a baseline (see the module doc for the rule)."""
    tol = baseline.get("tolerances", {})
    current = aggregate(rows, tol)
    entries = baseline.get("entries", {})
    res = GateResult()
    res.only_in_baseline = sorted(set(entries) - set(current))
    res.only_in_bench = sorted(set(current) - set(entries))
    for key in sorted(set(entries) & set(current)):
        for metric, t in tol.items():
            base = entries[key].get(metric)
            if base is None or not math.isfinite(_num(base)):
                continue
            base = float(base)
            value = current[key].get(metric, float("nan"))
            allowed = base + max(float(t.get("abs", 0.0)), float(t.get("rel", 0.0)) * abs(base))
            res.checked += 1
            if not math.isfinite(value) or value > allowed:
                res.regressions.append(Regression(key, metric, base, value, allowed))
            elif value < base:
                res.improved.append(f"{key}: {metric} {value:.6g} (baseline {base:.6g})")
    return res

"""The report of a study: robustness curves with their spread, the breaking-point search, envelopes.

``DIR/sweep.html`` (self-contained) and ``DIR/sweep.md`` (:class:`floorsim.bench.report.Report`):

* **Estimators compared**: every estimator's runs, failures, mean ATE and drift, time and
  memory, and where it comes from (:func:`floorsim.bench.report.compare_estimators`).
* **Breaking points** (a ``[search]``): per estimator the line ``floorsim sweep`` prints,
  a table (breaking value, confidence interval over the seeds, bracket, margin from the
  operating point, renders against a grid at the same tolerance) and a figure of the
  search: every value rendered, failing or working, per seed, the bracket shaded. With one
  ``[vary]`` key, the breaking point against that key (the envelope's edge) per estimator.
* **Curves**, per varied or searched key: end drift and lost frames against the value,
  one line per estimator: the mean over the seeds (of each seed's mean over the other
  keys), a band for its confidence interval when there are repetitions, the criterion's
  bounds, the operating point. The table gives each mean with its interval and, with a
  criterion, how many runs failed.
* **Envelope** (two ``[vary]`` keys and a criterion): each estimator's working region (the
  share of seeds that work in each cell) as a map with the operating point marked, every
  estimator's region edge on one figure, and per estimator and key the margin from the
  operating point to the nearest breaking point along that key (the other key held at
  its operating value).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from collections.abc import Sequence as SequenceT
from pathlib import Path
from typing import Any

import numpy as np

from floorsim.bench.report import COMPARE_COLUMNS, Report, _plt, compare_estimators
from floorsim.bench.search import SearchResult, mean_interval
from floorsim.bench.study import SweepSpec, as_override, scene_key_unit
from floorvo import metric_defs as md

__all__ = ["write_sweep_report", "margin_text"]

Row = Mapping[str, Any]


def _num(v: Any) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return float("nan")


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _match_key(v: Any) -> str:
    """The one text a varied value is matched by, however it was written: a number as a float
    (the study's ``100`` and a base scene's ``100.0``: the operating point's star and margin went
    missing), a boolean in lower case (a row read back from CSV holds ``True``, the study ``true``:
    a study run again emptied its tables and crashed), anything else as a ``--set`` text."""
    if isinstance(v, str) and v in ("True", "False"):
        return v.lower()
    if not isinstance(v, bool):
        f = _num(v)
        if math.isfinite(f):
            return repr(f)
    return as_override(v)


def _same(a: Any, b: Any) -> bool:
    """A row's value (read back from CSV: ``1.0``, ``True``) is the study's value (``1``, ``true``)?"""
    return _match_key(a) == _match_key(b)


def _values(rows: SequenceT[Row], key: str, declared: SequenceT[Any] | None = None) -> tuple[list[Any], bool]:
    """The values of ``key`` (the study's order, or those in the rows), sorted when numeric."""
    vals: list[Any] = list(declared) if declared is not None else []
    if declared is None:
        for r in rows:
            v = r.get(key)
            if v is not None and not any(_same(v, w) for w in vals):
                vals.append(v)
    numeric = bool(vals) and all(_is_number(v) for v in vals)
    return (sorted(vals, key=float) if numeric else vals), numeric


def _scored(rows: SequenceT[Row]) -> list[Row]:
    """Rows that are a verdict on an estimator: ok or failed runs (not skipped, not job failures)."""
    return [r for r in rows if r.get("estimator") and str(r.get("status", "")).split(":")[0] in ("ok", "failed")]


def _per_seed_means(sel: SequenceT[Row], metric: str) -> list[float]:
    """One value per repetition: its mean of ``metric`` over the other keys (ok runs)."""
    by_rep: dict[Any, list[float]] = {}
    for r in sel:
        if r.get("status") == "ok":
            by_rep.setdefault(r.get("repetition"), []).append(_num(r.get(metric)))
    out = []
    for vals in by_rep.values():
        v = np.asarray(vals, dtype=float)
        out.append(float(np.nanmean(v)) if np.isfinite(v).any() else float("nan"))
    return out


def _fmt_interval(lo: float, hi: float) -> str:
    return f"{lo:.4g} to {hi:.4g}" if math.isfinite(lo) and math.isfinite(hi) else "-"


# ----------------------------------------------------------------------------- margins
def margin_text(values: SequenceT[Any], failing: SequenceT[bool], op: Any, numeric: bool, unit: str = "") -> str:
    """The margin from operating value ``op`` to the nearest breaking point along one key.

    ``values``: the key's values in order (ascending when ``numeric``), ``failing``: the
    criterion holds there. A breaking point lies midway between a failing value and the
    working value next to it on the operating point's side. For a key that is not a
    number: the values it fails with.
    """
    u = f" {unit}" if unit else ""
    if not numeric:
        bad = [as_override(v) for v, f in zip(values, failing) if f]
        return f"fails with {', '.join(bad)}" if bad else "works with every value"
    if not _is_number(op):
        return "-"
    op = float(op)
    vals = [float(v) for v in values]
    if any(f and v == op for v, f in zip(vals, failing)):
        return "none: fails at the operating point"
    found = []
    below = [v for v, f in zip(vals, failing) if f and v < op]
    if below:
        vb = max(below)
        wb = min([v for v, f in zip(vals, failing) if not f and vb < v] + [op])
        found.append((op - 0.5 * (vb + wb), "below", vb, wb))
    above = [v for v, f in zip(vals, failing) if f and v > op]
    if above:
        va = min(above)
        wa = max([v for v, f in zip(vals, failing) if not f and v < va] + [op])
        found.append((0.5 * (va + wa) - op, "above", wa, va))
    if not found:
        return f"no breaking point in {min(vals):g}-{max(vals):g}{u}"
    m, side, a, b = min(found)
    return f"{m:.4g}{u} {side} (breaks between {a:g} and {b:g}{u})"


# ----------------------------------------------------------------------------- curves
def _curves(rep: Report, spec: SweepSpec, rows: SequenceT[Row], key: str, declared: list | None, op: Any) -> None:
    plt = _plt()
    scored = _scored(rows)
    values, numeric = _values(scored if declared is None else rows, key, declared)
    if not values:
        return
    pos = {_match_key(v): (float(v) if numeric else i) for i, v in enumerate(values)}
    estimators = sorted({r["estimator"] for r in scored})
    bounds = {b.metric: b for b in spec.criterion.bounds} if spec.criterion else {}
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    table = []
    banded = False
    for est in estimators:
        curves: dict[str, list[tuple[float, float, float]]] = {md.END_DRIFT.name: [], md.LOST_FRAMES.name: []}
        for v in values:
            sel = [r for r in scored if r["estimator"] == est and _same(r.get(key), v)]
            row: dict[str, Any] = {"estimator": est, "value": as_override(v), "n": len(sel)}
            for metric in curves:
                per_seed = _per_seed_means(sel, metric)
                m, lo, hi = mean_interval(per_seed, spec.confidence)
                lo = max(lo, 0.0) if np.isfinite(lo) else lo  # drift and lost frames are never negative
                curves[metric].append((m, lo, hi))
                row[metric] = m
                # an interval where two seeds have a value (one seed's was shown as zero wide)
                row[metric + ":ci"] = _fmt_interval(lo, hi) if np.isfinite(lo) else "-"
                banded |= bool(np.isfinite(lo))
            if spec.criterion is not None:
                row["fails"] = f"{sum(spec.criterion.failure(r) is not None for r in sel)}/{len(sel)}"
            table.append(row)
        x = [pos[_match_key(v)] for v in values]
        for ax, metric in zip(axes, curves):
            mean, lo, hi = np.array(curves[metric], dtype=float).T
            (line,) = ax.plot(x, mean, "o-", label=est)
            if np.isfinite(lo).any() and np.any(hi > lo):
                ax.fill_between(x, lo, hi, color=line.get_color(), alpha=0.2, lw=0)
    for ax, metric, ylabel in zip(
        axes, (md.END_DRIFT.name, md.LOST_FRAMES.name), ("end-point drift [% of distance]", "lost frames")
    ):
        if op is not None and _match_key(op) in pos:
            ax.axvline(pos[_match_key(op)], color="k", ls="--", lw=1, label="operating point")
        elif op is not None and numeric and _is_number(op):
            ax.axvline(float(op), color="k", ls="--", lw=1, label="operating point")
        if metric in bounds:
            ax.axhline(bounds[metric].limit, color="r", ls=":", lw=1, label="criterion bound")
        top = max(
            (abs(y) for ln in ax.get_lines() for y in np.asarray(ln.get_ydata(), dtype=float) if np.isfinite(y)),
            default=0.0,
        )
        if top > 20:  # a failing estimator's hundreds of % beside a working one's tenths
            ax.set_yscale("symlog", linthresh=1.0)
        ax.set_ylim(bottom=0.0)
        if (
            numeric
            and min(float(v) for v in values) > 0
            and max(float(v) for v in values) / min(float(v) for v in values) > 20
        ):
            ax.set_xscale("log")
        if not numeric:
            ax.set_xticks(range(len(values)), [str(v) for v in values])
        ax.set_xlabel(key)
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(f"robustness against {key}")
    fig.tight_layout()
    band = f"; bands: {round(100 * spec.confidence)} % interval over the seeds" if banded else ""
    rep.figure(fig, f"drift and tracking loss against {key} (operating point {op!r}){band}")
    cols = [
        ("estimator", "estimator"),
        ("value", key),
        (md.END_DRIFT.name, md.END_DRIFT.label),
        (md.END_DRIFT.name + ":ci", "interval"),
        (md.LOST_FRAMES.name, "lost frames"),
        (md.LOST_FRAMES.name + ":ci", "interval"),
        ("n", "runs"),
    ]
    if spec.criterion is not None:
        cols.append(("fails", "failed runs"))
    rep.table(table, cols)


# ----------------------------------------------------------------------------- the search
def _search_section(rep: Report, spec: SweepSpec, search: SearchResult, ops: Mapping[str, Any]) -> None:
    plt = _plt()
    s = search
    rep.heading(f"Breaking points: {s.key}")
    rep.text(
        f"Bisection over {s.key} from {s.grid[0]:g} to {s.grid[-1]:g} {s.unit} on a grid of {len(s.grid)} values "
        f"({s.scale} scale, tolerance {s.tolerance:g}{' relative' if s.scale == 'log' else ' ' + s.unit}); a run "
        f"fails when {s.criterion} or it could not run. Each seed's breaking point lies between the failing value "
        f"nearest the working end and the working value next to it; a grid at the same tolerance would have "
        f"rendered {s.grid_renders} sequences per combination."
    )
    for line in s.summary_lines()[1:]:
        rep.text(line.strip())
    op = s.operating_value
    table = []
    for p in s.points:
        bp = p.point
        table.append(
            {
                "context": s.context_label(p.context),
                "estimator": p.estimator,
                "state": bp.state,
                "value": bp.value,
                "interval": _fmt_interval(*bp.interval) if bp.noisy else ("seeds agree" if bp.seeds > 1 else "-"),
                "bracket": _fmt_interval(*bp.bracket),
                "margin": s.margin(p),
                "renders": s.renders.get(s.context_label(p.context)),
                "grid": s.grid_renders,
            }
        )
    cols = [("context", "combination")] if spec.vary else []
    cols += [
        ("estimator", "estimator"),
        ("state", "state"),
        ("value", f"breaking {s.unit}".strip()),
        ("interval", f"{round(100 * s.confidence)} % interval"),
        ("bracket", "bracket"),
        ("margin", f"margin {s.unit}".strip()),
        ("renders", "renders"),
        ("grid", "grid renders"),
    ]
    rep.table(table, cols)
    contexts: dict[str, list[Any]] = {}
    for p in s.points:
        contexts.setdefault(s.context_label(p.context), []).append(p)
    for label, ps in contexts.items():
        fig, ax = plt.subplots(figsize=(8, 0.6 + 0.55 * len(ps) * spec.repetitions + 0.8))
        yticks, ylabels = [], []
        y = 0
        for p in ps:
            for k in range(spec.repetitions):
                b = p.brackets[k]
                pts = sorted((i, why) for (i, rep_k), why in p.reasons.items() if rep_k == k)
                xs = [s.grid[i] for i, _ in pts]
                bad = [why is not None for _, why in pts]
                ax.scatter([x for x, f in zip(xs, bad) if f], [y] * sum(bad), marker="x", color="tab:red", zorder=3)
                ax.scatter(
                    [x for x, f in zip(xs, bad) if not f],
                    [y] * (len(xs) - sum(bad)),
                    marker="o",
                    color="tab:green",
                    zorder=3,
                )
                if b.state == "found" and b.fail_index is not None and b.work_index is not None:
                    lo, hi = sorted((s.grid[b.fail_index], s.grid[b.work_index]))
                    ax.fill_betweenx([y - 0.35, y + 0.35], lo, hi, color="tab:orange", alpha=0.3, lw=0)
                yticks.append(y)
                ylabels.append(f"{p.estimator}" + (f" seed {p.seeds[k]}" if spec.repetitions > 1 else ""))
                y += 1
            if math.isfinite(p.point.value):
                ax.plot([p.point.value] * 2, [y - spec.repetitions - 0.3, y - 0.7], color="k", lw=1)
        if _is_number(op):
            ax.axvline(float(op), color="k", ls="--", lw=1, label="operating point")
        ax.set_yticks(yticks, ylabels)
        ax.set_ylim(-0.7, y - 0.3)
        if s.scale == "log":
            ax.set_xscale("log")
        ax.set_xlabel(f"{s.key} [{s.unit}]" if s.unit else s.key)
        ax.scatter([], [], marker="x", color="tab:red", label="fails")
        ax.scatter([], [], marker="o", color="tab:green", label="works")
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
        ax.grid(alpha=0.3, axis="x")
        ax.set_title(f"search over {s.key}" + ("" if label == "all" else f" ({label})"))
        fig.tight_layout()
        rep.figure(
            fig,
            f"breaking-point search over {s.key}{'' if label == 'all' else ' at ' + label}: every value rendered "
            f"(x fails, o works), the final bracket shaded, the breaking point as a vertical tick",
        )
    if len(spec.vary) == 1:
        _search_envelope(rep, spec, s, ops)


def _search_envelope(rep: Report, spec: SweepSpec, s: SearchResult, ops: Mapping[str, Any]) -> None:
    """One [vary] key and a search: the breaking point against the varied key (the envelope's edge)."""
    plt = _plt()
    (vkey,) = spec.vary
    values, numeric = _values([], vkey, spec.vary[vkey])
    xpos = {_match_key(v): (float(v) if numeric else i) for i, v in enumerate(values)}
    fig, ax = plt.subplots(figsize=(7, 4))
    margins = []
    op_v, op_s = ops.get(vkey), s.operating_value
    for est in sorted({p.estimator for p in s.points}):
        ps = {_match_key(p.context[vkey]): p for p in s.points if p.estimator == est}
        xs, ys, lo, hi = [], [], [], []
        fails_at_op = []
        for v in values:
            p = ps.get(_match_key(v))
            if p is None:
                continue
            xs.append(xpos[_match_key(v)])
            ys.append(p.point.value)
            lo.append(p.point.interval[0])
            hi.append(p.point.interval[1])
            st = p.point.state
            if st == "fails_everywhere":
                fails_at_op.append(True)
            elif st == "works_everywhere" or not math.isfinite(p.point.value) or not _is_number(op_s):
                fails_at_op.append(False)
            else:
                fails_at_op.append(float(op_s) < p.point.value if s.fails == "below" else float(op_s) > p.point.value)
        y = np.array(ys, dtype=float)
        yerr = np.abs(np.array([lo, hi], dtype=float) - y)
        ax.errorbar(xs, y, yerr=np.nan_to_num(yerr), fmt="o-", capsize=3, label=est)
        at_op = ps.get(_match_key(op_v)) if op_v is not None else None
        m = s.margin(at_op) if at_op is not None else None
        search_margin = f"{m:.4g} {s.unit}".strip() if m is not None else (at_op.point.state if at_op else "-")
        vals_present = [v for v in values if _match_key(v) in ps]
        margins.append(
            {
                "estimator": est,
                "search": search_margin,
                "vary": margin_text(vals_present, fails_at_op, op_v, numeric),
            }
        )
    if op_v is not None and _is_number(op_s) and _match_key(op_v) in xpos:
        ax.plot([xpos[_match_key(op_v)]], [float(op_s)], "k*", ms=14, label="operating point")
    if not numeric:
        ax.set_xticks(range(len(values)), [str(v) for v in values])
    ax.set_xlabel(vkey)
    ax.set_ylabel(f"breaking {s.key}" + (f" [{s.unit}]" if s.unit else ""))
    ax.set_title(f"each estimator works {'above' if s.fails == 'below' else 'below'} its line")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    rep.figure(fig, f"envelope: breaking {s.key} against {vkey}, per estimator (bars: the interval over the seeds)")
    rep.text(f"Margins from the operating point ({vkey} = {op_v!r}, {s.key} = {op_s!r}) to the nearest breaking point:")
    rep.table(margins, [("estimator", "estimator"), ("search", f"along {s.key}"), ("vary", f"along {vkey}")])


# ----------------------------------------------------------------------------- envelopes
def _envelope_section(rep: Report, spec: SweepSpec, rows: SequenceT[Row], ops: Mapping[str, Any]) -> None:
    plt = _plt()
    assert spec.criterion is not None
    kx, ky = list(spec.vary)
    xs, xnum = _values([], kx, spec.vary[kx])
    ys, ynum = _values([], ky, spec.vary[ky])
    scored = _scored(rows)
    estimators = sorted({r["estimator"] for r in scored})
    if not estimators:
        return
    rep.heading(f"Envelope: {kx} x {ky}")
    rep.text(
        f"Each cell: the share of seeds whose run works (a run fails when {spec.criterion.describe()} or it could "
        f"not run). The star marks the paper rig's operating point."
    )

    def index_of(values: list, numeric: bool, v: Any) -> float | None:
        for i, w in enumerate(values):
            if _same(w, v):
                return float(i)
        if numeric and _is_number(v) and float(values[0]) <= float(v) <= float(values[-1]):
            return float(np.interp(float(v), [float(w) for w in values], np.arange(len(values))))
        return None

    ox, oy = index_of(xs, xnum, ops.get(kx)), index_of(ys, ynum, ops.get(ky))
    work: dict[str, np.ndarray] = {}
    for est in estimators:
        w = np.full((len(ys), len(xs)), np.nan)
        for i, x in enumerate(xs):
            for j, y in enumerate(ys):
                sel = [r for r in scored if r["estimator"] == est and _same(r.get(kx), x) and _same(r.get(ky), y)]
                if sel:
                    w[j, i] = sum(spec.criterion.failure(r) is None for r in sel) / len(sel)
        work[est] = w
    n = len(estimators)
    fig, axes = plt.subplots(1, n, figsize=(3.6 * n + 1, 3.4), squeeze=False)
    for ax, est in zip(axes[0], estimators):
        im = ax.imshow(work[est], origin="lower", cmap="RdYlGn", vmin=0, vmax=1, aspect="auto")
        if ox is not None and oy is not None:
            ax.plot([ox], [oy], "k*", ms=14)
        ax.set_xticks(range(len(xs)), [as_override(v) for v in xs], rotation=45 if not xnum else 0, fontsize=8)
        ax.set_yticks(range(len(ys)), [as_override(v) for v in ys], fontsize=8)
        ax.set_xlabel(kx)
        ax.set_ylabel(ky)
        ax.set_title(est, fontsize=10)
    fig.colorbar(im, ax=list(axes[0]), label="share of seeds that work")
    rep.figure(fig, f"working region of each estimator over {kx} x {ky} (green works, red fails; star: paper rig)")
    if len(xs) >= 2 and len(ys) >= 2:
        fig, ax = plt.subplots(figsize=(6, 4.2))
        colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
        for k, est in enumerate(estimators):
            c = colours[k % len(colours)]
            w = np.nan_to_num(work[est], nan=0.0)
            if w.min() < 0.5 <= w.max():
                ax.contour(np.arange(len(xs)), np.arange(len(ys)), w, levels=[0.5], colors=[c], linewidths=2)
            ax.plot([], [], color=c, lw=2, label=f"{est} ({int(np.sum(w >= 0.5))} of {w.size} cells work)")
        if ox is not None and oy is not None:
            ax.plot([ox], [oy], "k*", ms=14, label="operating point")
        ax.set_xticks(range(len(xs)), [as_override(v) for v in xs], rotation=45 if not xnum else 0, fontsize=8)
        ax.set_yticks(range(len(ys)), [as_override(v) for v in ys], fontsize=8)
        ax.set_xlim(-0.5, len(xs) - 0.5)
        ax.set_ylim(-0.5, len(ys) - 0.5)
        ax.set_xlabel(kx)
        ax.set_ylabel(ky)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        ax.set_title("estimators compared: the edge of each working region")
        fig.tight_layout()
        rep.figure(fig, "every estimator's working-region edge (half its seeds work) on one figure")
    margins = []
    for est in estimators:
        w = work[est]
        row: dict[str, Any] = {"estimator": est}
        for key, values, numeric, other_idx, axis in ((kx, xs, xnum, oy, 0), (ky, ys, ynum, ox, 1)):
            if other_idx is None or other_idx != round(other_idx):
                row[key] = "-"
                continue
            line = w[int(other_idx), :] if axis == 0 else w[:, int(other_idx)]
            keep = [i for i in range(len(values)) if np.isfinite(line[i])]
            row[key] = margin_text(
                [values[i] for i in keep],
                [bool(line[i] < 0.5) for i in keep],
                ops.get(key),
                numeric,
                scene_key_unit(key),
            )
        margins.append(row)
    rep.text(
        f"Margin from the operating point ({kx} = {ops.get(kx)!r}, {ky} = {ops.get(ky)!r}) to the nearest breaking "
        "point along each key, the other key held at its operating value:"
    )
    rep.table(margins, [("estimator", "estimator"), (kx, f"along {kx}"), (ky, f"along {ky}")])


# ----------------------------------------------------------------------------- the page
def write_sweep_report(
    spec: SweepSpec,
    rows: SequenceT[Row],
    out_dir: Path,
    ops: Mapping[str, Any],
    search: SearchResult | None = None,
) -> tuple[Path, Path]:
    """Write ``sweep.html`` / ``sweep.md`` for the study's rows (see the module doc).

    ``ops``: the operating value of every varied or searched key; ``search``: what the
    breaking-point search found, or None.
    """
    rep = Report(f"floorbench sweep: {spec.name}", Path(out_dir), stem="sweep")
    ok = [r for r in rows if r.get("status") == "ok"]
    seeds = (
        f"seeds {', '.join(map(str, spec.seeds))}"
        if spec.seeds
        else f"{spec.repetitions} repetition(s), seeds scene seed + k"
    )
    if spec.description:
        rep.text(spec.description)
    where = f"Base scene {spec.base.name}" if spec.base is not None else "Sequence folders only (no base scene)"
    rep.text(
        f"{where}; {len(rows)} rows, {len(ok)} scored; {seeds}. Each point is the mean over the "
        "other varied keys and the repetitions; the dashed line marks the paper rig's operating point. "
        "Failed or skipped jobs are listed in results.csv. The study file and the package versions are in "
        "study.toml and study.json."
    )
    rep.heading("Estimators compared")
    rep.table(compare_estimators(rows), COMPARE_COLUMNS)
    if search is not None:
        _search_section(rep, spec, search, ops)
    if spec.criterion is not None and len(spec.vary) == 2:
        _envelope_section(rep, spec, rows, ops)
    for key, values in spec.vary.items():
        rep.heading(key)
        _curves(rep, spec, rows, key, values, ops.get(key))
    if search is not None:
        rep.heading(f"{search.key} (values the search rendered)")
        _curves(rep, spec, rows, search.key, None, ops.get(search.key))
    return rep.write()

"""The pure core of lighting-robustness studies: failure criteria, breaking-point brackets, intervals.

No file I/O and no rendering here: :mod:`floorsim.bench.sweep` renders and scores, and
asks this module which values to render next and what the rows it has say.

**Failure criterion.** A study names bounds on declared metrics
(:mod:`floorvo.metric_defs`: name, unit, direction): ``end_drift_pct = 1.0`` (end drift
above 1 %), ``lost_frames = 0`` (more than 0 frames lost), any other declared metric with
a direction. A run *fails* when one metric is worse than its bound (above it for a
lower-is-better metric, below it for a higher-is-better one), when the metric is missing
or not a number (nothing was estimated), or when the run itself failed.

**Breaking-point search.** The searched key takes values on a grid from ``low`` to
``high`` whose neighbours are at most the tolerance apart (:func:`search_grid`): uniform
in the key for ``scale = "linear"`` (tolerance in the key's units), uniform in its
logarithm for ``"log"`` (tolerance relative: neighbours differ by a factor <= 1 + tol).
The dense-grid answer is the grid value where the criterion first holds, coming from the
working end (``fails = "below"``: the working end is ``high``). The search finds the same
bracket by bisection on the grid's indices (:func:`bracket`): it renders both ends, then
the middle of the bracket between the failing value nearest the working end and the
working value next to it, until they are neighbours. Every evaluated value narrows every
estimator's bracket, so estimators share renders (the first midpoints are the same for
all). On a criterion that holds on one side of a single crossing, the answer is the dense
grid's bracket exactly, with about ``2 + log2(N)`` renders instead of ``N + 1``.

**Uncertainty.** Each repetition (seed) has its own bracket; over seeds the breaking
point is stated as a mean with a Student-t confidence interval (:func:`mean_interval`),
and as the range of the seeds' brackets when they do not overlap (the criterion is noisy
there).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from collections.abc import Sequence as SequenceT
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = [
    "Bound",
    "Criterion",
    "Bracket",
    "search_grid",
    "bracket",
    "breaking_value",
    "dense_grid_bracket",
    "mean_interval",
    "BreakingPoint",
    "combine_brackets",
    "EstimatorBreakingPoint",
    "SearchResult",
]


# ----------------------------------------------------------------------------- the criterion
@dataclass(frozen=True)
class Bound:
    """One metric bound: the run fails when ``metric`` is worse than ``limit``.

    ``lower_is_better``: the metric's declared direction (True: fails above the limit).
    ``unit``: the metric's unit, for messages.
    """

    metric: str
    limit: float
    lower_is_better: bool
    unit: str = ""

    def broken(self, value: Any) -> str | None:
        """Why ``value`` breaks the bound (``"end_drift_pct 2.1 % > 1 %"``), or None."""
        unit = f" {self.unit}" if self.unit else ""
        try:
            v = float(value)
        except (TypeError, ValueError):
            v = float("nan")
        if not math.isfinite(v):
            return f"{self.metric} missing"
        if self.lower_is_better and v > self.limit:
            return f"{self.metric} {v:.4g}{unit} > {self.limit:g}{unit}"
        if not self.lower_is_better and v < self.limit:
            return f"{self.metric} {v:.4g}{unit} < {self.limit:g}{unit}"
        return None

    def describe(self) -> str:
        unit = f" {self.unit}" if self.unit else ""
        return f"{self.metric} {'>' if self.lower_is_better else '<'} {self.limit:g}{unit}"


@dataclass(frozen=True)
class Criterion:
    """A failure criterion: any of its bounds broken, or the run failed."""

    bounds: tuple[Bound, ...]

    def failure(self, row: Mapping[str, Any]) -> str | None:
        """Why the scored run ``row`` (a results.csv row) fails, or None when it works.

        A row whose ``status`` is ``failed: ...`` fails (the estimator could not run there);
        a ``skipped`` row is not a verdict and must not be passed in.
        """
        status = str(row.get("status", ""))
        if status.startswith("failed"):
            return status
        reasons = [r for b in self.bounds if (r := b.broken(row.get(b.metric))) is not None]
        return "; ".join(reasons) if reasons else None

    def describe(self) -> str:
        return " or ".join(b.describe() for b in self.bounds)


# ----------------------------------------------------------------------------- the search grid
def _round(v: float) -> float:
    """12 significant digits: grid values print and compare the same in every process."""
    return float(f"{v:.12g}")


def search_grid(low: float, high: float, tolerance: float, scale: str = "linear", integer: bool = False) -> list[float]:
    """The values a search may visit, ascending, from ``low`` to ``high`` (both included).

    ``scale="linear"``: ``low + k * tolerance`` for k = 0, 1, ... while below ``high``,
    then ``high``: N + 1 values, N = ceil((high - low) / tolerance), neighbours at most
    ``tolerance`` apart (key units). ``"log"``: ``low * (1 + tolerance)**k``, then ``high``
    (``low`` > 0): neighbours' ratio at most ``1 + tolerance``. ``integer``: whole numbers from
    ``round(low)`` to ``round(high)``, each as far from the one before as the tolerance allows and
    at least 1 (an integer key resolves no less), so
    neighbours are at most ``max(tolerance, 1)`` apart (log: their ratio at most ``1 + tolerance``
    or they are 1 apart).
    """
    if not (high > low) or tolerance <= 0:
        raise ValueError(f"search grid: need low < high and tolerance > 0 (got {low}, {high}, {tolerance})")
    if scale == "log" and low <= 0:
        raise ValueError(f"search grid: a log scale needs low > 0 (got {low})")
    if integer:
        # Whole numbers from low to high, each the furthest from the one before that the tolerance
        # allows (at least 1 on: the least an integer key resolves). The grid below rounded put
        # 0 .. 10 at 2.5 at 0, 2, 5, 8, 10: 3 apart, a bracket wider than the tolerance.
        lo_i, hi_i = float(round(low)), float(round(high))
        grid = [lo_i]
        while grid[-1] < hi_i:
            a = grid[-1]
            reach = a * (1.0 + tolerance) if scale == "log" else a + tolerance
            grid.append(min(hi_i, max(a + 1.0, float(math.floor(reach + 1e-9)))))
        return grid
    if scale == "log":
        n = max(1, math.ceil(math.log(high / low) / math.log1p(tolerance) - 1e-9))
        values = [low * (1.0 + tolerance) ** k for k in range(n)] + [high]
    else:
        n = max(1, math.ceil((high - low) / tolerance - 1e-9))
        values = [low + k * tolerance for k in range(n)] + [high]
    return [_round(v) for v in values]


@dataclass(frozen=True)
class Bracket:
    """Where one estimator's search (one seed) stands on the grid.

    ``state``: ``"found"`` (``fail_index`` and ``work_index`` are neighbours), ``"open"``
    (``next_index`` is the value to evaluate next), ``"works_everywhere"`` (the failing end
    works: the breaking point lies beyond it), ``"fails_everywhere"`` (the working end
    fails). Indices are grid indices (None when not known).
    """

    state: str
    fail_index: int | None = None
    work_index: int | None = None
    next_index: int | None = None


def bracket(outcomes: Mapping[int, bool], n_values: int, fails_below: bool) -> Bracket:
    """The bracket that the evaluated grid indices give, and what to evaluate next.

    ``outcomes``: grid index -> the criterion holds there (fails). ``fails_below``: the
    failing end is index 0 (else the last index). The failing value nearest the working
    end and the next evaluated value towards the working end bracket the breaking point
    (the dense-grid answer: the first failing value coming from the working end).
    """
    last = n_values - 1

    def t(i: int) -> int:  # steps from the failing end
        return i if fails_below else last - i

    def index(step: int) -> int:
        return step if fails_below else last - step

    steps = {t(i): bool(f) for i, f in outcomes.items() if 0 <= i <= last}
    if last not in steps:
        return Bracket("open", next_index=index(last))
    if steps[last]:
        return Bracket("fails_everywhere", fail_index=index(last))
    failing = [s for s, f in steps.items() if f]
    if not failing:
        if 0 not in steps:
            return Bracket("open", next_index=index(0))
        return Bracket("works_everywhere", work_index=index(0))
    f = max(failing)
    w = min(s for s in steps if s > f)
    if w - f == 1:
        return Bracket("found", fail_index=index(f), work_index=index(w))
    return Bracket("open", fail_index=index(f), work_index=index(w), next_index=index((f + w) // 2))


def dense_grid_bracket(fails: SequenceT[bool], fails_below: bool) -> Bracket:
    """The answer of a dense grid that evaluated every value: :func:`bracket` of all of them."""
    return bracket(dict(enumerate(fails)), len(fails), fails_below)


def breaking_value(grid: SequenceT[float], b: Bracket, scale: str = "linear") -> float:
    """The breaking point a found bracket states: the middle of its two values
    (the geometric middle on a log scale); NaN when the bracket is not found."""
    if b.state != "found" or b.fail_index is None or b.work_index is None:
        return float("nan")
    a, c = grid[b.fail_index], grid[b.work_index]
    return math.sqrt(a * c) if scale == "log" else 0.5 * (a + c)


# ----------------------------------------------------------------------------- uncertainty
def mean_interval(values: SequenceT[float], confidence: float = 0.95) -> tuple[float, float, float]:
    """``(mean, low, high)``: the mean of the finite ``values`` and its two-sided Student-t
    confidence interval at ``confidence`` (mean +- t_{(1+c)/2, n-1} s / sqrt(n)).

    One value gives no interval (NaNs: a Student-t interval needs two; it was shown as zero
    wide, '95 % interval 11-11' over one seed); none gives NaNs throughout.
    """
    from scipy import stats  # scipy.stats is slow to import; only studies need it

    v = np.asarray([x for x in values if x is not None], dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return float("nan"), float("nan"), float("nan")
    m = float(v.mean())
    if v.size == 1:
        return m, float("nan"), float("nan")
    half = float(stats.t.ppf(0.5 + confidence / 2, v.size - 1) * v.std(ddof=1) / math.sqrt(v.size))
    return m, m - half, m + half


@dataclass(frozen=True)
class BreakingPoint:
    """One estimator's breaking point over the seeds searched.

    ``state``: ``"found"`` (every seed found a bracket), ``"works_everywhere"`` /
    ``"fails_everywhere"`` (every seed), ``"mixed"`` (seeds disagree: some found one, some
    not), ``"open"`` (a search did not finish: a job failed). ``value``: mean of the seeds'
    breaking values; ``interval``: its confidence interval (NaNs for one seed: :func:`mean_interval`);
    ``bracket``: the lowest and highest value of the seeds' brackets (fail side to work
    side, ascending); ``noisy``: the seeds disagree (their brackets differ, or some found
    none), i.e. the criterion is noisy near the breaking point at the grid's resolution.
    """

    state: str
    value: float
    interval: tuple[float, float]
    bracket: tuple[float, float]
    seeds: int
    noisy: bool


def combine_brackets(
    grid: SequenceT[float], brackets: SequenceT[Bracket], scale: str = "linear", confidence: float = 0.95
) -> BreakingPoint:
    """The breaking point of one estimator from its per-seed brackets (see :class:`BreakingPoint`)."""
    nan = float("nan")
    states = {b.state for b in brackets}
    found = [b for b in brackets if b.state == "found"]
    if not brackets or "open" in states:
        return BreakingPoint("open", nan, (nan, nan), (nan, nan), len(brackets), False)
    if len(states) == 1 and states != {"found"}:
        return BreakingPoint(next(iter(states)), nan, (nan, nan), (nan, nan), len(brackets), False)
    if not found:  # some seeds work over the whole range, others fail over it
        return BreakingPoint("mixed", nan, (nan, nan), (nan, nan), len(brackets), True)
    values = [breaking_value(grid, b, scale) for b in found]
    m, lo, hi = mean_interval(values, confidence)
    ends = [sorted((grid[b.fail_index], grid[b.work_index])) for b in found]  # type: ignore[index]
    span = (min(e[0] for e in ends), max(e[1] for e in ends))
    noisy = len({tuple(e) for e in ends}) > 1
    state = "found" if len(found) == len(brackets) else "mixed"
    return BreakingPoint(state, m, (lo, hi), span, len(brackets), noisy or state == "mixed")


# ----------------------------------------------------------------------------- what a search found
def _text(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:g}"
    return str(v)


@dataclass(frozen=True)
class EstimatorBreakingPoint:
    """One estimator's breaking point in one combination of the ``[vary]`` values.

    ``context``: that combination (``{}`` without ``[vary]``); ``point``: the combined
    :class:`~floorsim.bench.search.BreakingPoint` over the seeds; ``brackets``: per seed,
    its :class:`~floorsim.bench.search.Bracket`; ``seeds``: the seeds, in repetition order;
    ``reasons``: per evaluated value (grid index) and seed, why it failed (None: it worked).
    """

    context: dict[str, Any]
    estimator: str
    point: BreakingPoint
    brackets: tuple[Bracket, ...]
    seeds: tuple[int | None, ...]
    reasons: dict[tuple[int, int], str | None]


@dataclass
class SearchResult:
    """What a breaking-point search found (see :mod:`floorsim.bench.search`).

    ``grid``: the values it could visit; ``renders``: per context label, the values x seeds
    it rendered; ``grid_renders``: what a grid at the same tolerance renders per context;
    ``jobs``: the ids of the jobs whose rows it used; ``errors``: contexts and seeds whose
    search stopped on a failed job.
    """

    key: str
    unit: str
    fails: str
    scale: str
    tolerance: float
    criterion: str
    grid: list[float]
    points: list[EstimatorBreakingPoint]
    renders: dict[str, int]
    grid_renders: int
    operating_value: Any = None
    errors: list[str] = field(default_factory=list)
    confidence: float = 0.95
    jobs: set[str] = field(default_factory=set)

    def margin(self, p: EstimatorBreakingPoint) -> float | None:
        """Distance from the operating value to ``p``'s breaking point, in the key's units:
        positive when the operating point is on the working side (None when either is unknown)."""
        op = self.operating_value
        if isinstance(op, bool) or not isinstance(op, (int, float)) or not math.isfinite(p.point.value):
            return None
        return float(op) - p.point.value if self.fails == "below" else p.point.value - float(op)

    def value_text(self, v: float) -> str:
        return f"{v:.4g} {self.unit}".rstrip() if math.isfinite(v) else "-"

    def describe(self, p: EstimatorBreakingPoint) -> str:
        """One line: where the estimator fails, its bracket and interval, or why there is none."""
        bp, side = p.point, self.fails
        lo, hi = self.grid[0], self.grid[-1]
        if bp.state == "works_everywhere":
            end = lo if side == "below" else hi
            return f"works over the whole range (works at {self.value_text(end)} too: the breaking point is beyond it)"
        if bp.state == "fails_everywhere":
            end = hi if side == "below" else lo
            return f"fails over the whole range (fails at {self.value_text(end)} already, the working end)"
        if bp.state == "open":
            return "search did not finish (a job failed; see results.csv)"
        if not math.isfinite(bp.value):
            return "no breaking point: some seeds work over the whole range, others fail over it"
        text = f"fails {side} {self.value_text(bp.value)} (bracket {bp.bracket[0]:.4g}-{bp.bracket[1]:.4g}"
        if bp.seeds > 1:
            found = sum(b.state == "found" for b in p.brackets)
            if bp.noisy and math.isfinite(bp.interval[0]):
                pct = round(100 * self.confidence)
                text += (
                    f"; {pct} % interval {bp.interval[0]:.4g} to {bp.interval[1]:.4g} over {found} of {bp.seeds} seeds"
                )
            elif bp.noisy:  # one seed found it: no interval
                text += f"; found by {found} of {bp.seeds} seeds"
            else:
                text += f"; every one of {bp.seeds} seeds in this bracket"
        text += ")"
        m = self.margin(p)
        if m is not None:  # m > 0: the operating point is on the working side
            where = "above" if (m > 0) == (side == "above") else "below"
            text += (
                f", {abs(m):.4g} {self.unit}".rstrip()
                + f" {where} the operating point ({self.value_text(float(self.operating_value))})"
                + (": the operating point is on the failing side" if m < 0 else "")
            )
        if bp.state == "mixed":
            n_fail = sum(b.state == "fails_everywhere" for b in p.brackets)
            n_work = sum(b.state == "works_everywhere" for b in p.brackets)
            if n_fail:  # beyond the working end: left out, they made the value and margin look safer
                end = hi if side == "below" else lo
                text += (
                    f"; {n_fail} of {bp.seeds} seeds fail over the whole range (at {self.value_text(end)}, the working "
                    "end, too): their breaking points lie beyond it, so this value and margin are optimistic"
                )
            if n_work:
                text += (
                    f"; {n_work} of {bp.seeds} seeds work over the whole range: their breaking points lie beyond "
                    "its failing end, so this value is pessimistic"
                )
        elif bp.noisy:
            text += "; noisy: the seeds disagree"
        return text

    @staticmethod
    def context_label(context: Mapping[str, Any]) -> str:
        """``key=value, ...`` of a [vary] combination (``all`` for none)."""
        return ", ".join(f"{k}={_text(v)}" for k, v in context.items()) or "all"

    def summary_lines(self) -> list[str]:
        """The lines ``floorsim sweep`` prints: per context and estimator, the breaking point."""
        lines = [
            f"breaking point of {self.key} (fails {self.fails} it when {self.criterion}; "
            f"tolerance {self.tolerance:g}{' ' + self.unit if self.unit and self.scale == 'linear' else ''}"
            f"{' relative' if self.scale == 'log' else ''}):"
        ]
        contexts: dict[str, list[EstimatorBreakingPoint]] = {}
        for p in self.points:
            contexts.setdefault(self.context_label(p.context), []).append(p)
        for label, ps in contexts.items():
            indent = "  "
            if len(contexts) > 1 or label != "all":
                lines.append(f"  {label}:")
                indent = "    "
            for p in ps:
                lines.append(f"{indent}{p.estimator}: {self.describe(p)}")
            lines.append(
                f"{indent}renders: {self.renders.get(label, 0)} (a grid at the same tolerance: {self.grid_renders})"
            )
        lines.extend(f"  search stopped: {e}" for e in self.errors)
        return lines

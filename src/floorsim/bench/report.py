"""The bench report: one self-contained HTML page and a Markdown summary.

The HTML embeds every plot as a base64 PNG (matplotlib, Agg backend), so the file opens
from disk with no server and no other file. The Markdown summary holds the same tables
and links the PNGs written next to it under ``plots/``.

Plots: estimated against true trajectory (per scene), translation error against distance
travelled (per scene), timing box plots (per estimator and stage), a few frames with the
estimator's matched keypoints when the run folder holds them (``RUN/matches/NNNNNN.npz``
with ``xy_prev_px`` and ``xy_cur_px`` (K, 2)); when no run does, the report says so.
"""

from __future__ import annotations

import base64
import html
import io
import math
import os
from collections.abc import Iterable, Mapping
from collections.abc import Sequence as SequenceT
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from floorsim.bench.results import TEXT_COLUMNS
from floorvo import metric_defs as md
from floorvo.io import atomic_write_bytes, atomic_write_text
from floorvo.plots import PlotRun, draw_errors, draw_trajectories, load_plot_run, pyplot, run_styles
from floorvo.runfolder import read_match_samples, read_timing_csv
from floorvo.sequence import Sequence
from floorvo.tum import read_tum

__all__ = ["Report", "RunRecord", "SUMMARY_COLUMNS", "build_bench_report", "format_table"]

#: (column, header) of the summary table, in order.
SUMMARY_COLUMNS: list[tuple[str, str]] = [
    ("scene", "scene"),
    ("estimator", "estimator"),
    ("source", "source"),
    ("repetition", "rep"),
    ("status", "status"),
    *(
        (m.name, m.label)
        for m in (
            md.ate_rmse("none"),
            md.ate_rmse("se2"),
            md.RPE_FRAME_TRANS_RMSE,
            md.END_DRIFT,
            md.SEG_MEAN_T_ERR,
            md.LOST_FRAMES,
            md.WRONG_OK_STEPS,
            md.time_mean("total_ms"),
        )
    ),
    ("wall_ms_per_frame", "wall ms/frame"),
    ("peak_rss_mb", "peak MiB"),
]

#: Columns that need ground truth: a row scored without it shows why in the first
#: (:data:`GROUND_TRUTH_REASON_COLUMN`) and ``-`` in the others.
GROUND_TRUTH_COLUMNS = frozenset(
    m.name for m in (md.ate_rmse("none"), md.ate_rmse("se2"), md.RPE_FRAME_TRANS_RMSE, md.END_DRIFT, md.SEG_MEAN_T_ERR)
)
#: The pose-metric cell that says why a row has no pose metrics (the leftmost of the tables).
GROUND_TRUTH_REASON_COLUMN = md.ate_rmse("none").name

#: (column, header) of the comparison of estimators across their sources.
COMPARE_COLUMNS: list[tuple[str, str]] = [
    ("estimator", "estimator"),
    ("source", "source"),
    ("source_detail", "version / command"),
    ("runs", "runs"),
    ("failed", "failed"),
    (md.ate_rmse("se2").name, f"{md.ate_rmse('se2').label}, mean"),
    (md.END_DRIFT.name, f"{md.END_DRIFT.label}, mean"),
    ("wall_ms_per_frame", "wall ms/frame, mean"),
    ("peak_rss_mb", "peak MiB, max"),
]


def display_rows(rows: SequenceT[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """``rows`` as tables show them: a run scored without the pose metrics (``ground_truth`` is
    not ``ok``) says why once, in :data:`GROUND_TRUTH_REASON_COLUMN` (the sequence has no
    ground truth, or the run tracked fewer than two frames: :data:`floorvo.scoring.NO_TRACK`),
    and shows ``-`` in the other cells of :data:`GROUND_TRUTH_COLUMNS` (the reason in all five
    made the console table five reasons wide)."""
    out = []
    for r in rows:
        d = dict(r)
        gt = d.get("ground_truth")
        if gt not in (None, "", "ok") and str(d.get("status", "")) == "ok":
            d.update({c: "-" for c in GROUND_TRUTH_COLUMNS})
            d[GROUND_TRUTH_REASON_COLUMN] = str(gt)
        out.append(d)
    return out


def _finite(values: Iterable[Any]) -> list[float]:
    out = []
    for v in values:
        try:
            f = float(v)
        except (TypeError, ValueError):
            continue
        if math.isfinite(f):
            out.append(f)
    return out


def compare_estimators(rows: SequenceT[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """One row per estimator of the bench (every source side by side): runs, failed runs, mean
    ATE (SE2) and end drift of the runs with ground truth, mean wall time per frame, peak memory."""
    by: dict[str, list[Mapping[str, Any]]] = {}
    for r in rows:
        if r.get("estimator") and "repetition" in r:
            by.setdefault(str(r["estimator"]), []).append(r)
    out = []
    for name, rs in by.items():
        first = next((r for r in rs if r.get("source")), rs[0])
        d: dict[str, Any] = {
            "estimator": name,
            "source": first.get("source"),
            "source_detail": first.get("source_detail"),
            "runs": len(rs),
            "failed": sum(1 for r in rs if str(r.get("status", "")).startswith("failed")),
        }
        for col, agg in (("ate_se2_rmse_mm", np.mean), ("end_drift_pct", np.mean), ("wall_ms_per_frame", np.mean)):
            vals = _finite(r.get(col) for r in rs)
            d[col] = float(agg(vals)) if vals else None
        peaks = _finite(r.get("peak_rss_mb") for r in rs)
        d["peak_rss_mb"] = max(peaks) if peaks else None
        out.append(d)
    return out


def _plt():
    """matplotlib's pyplot on the Agg backend (:func:`floorvo.plots.pyplot`); imported on the first plot."""
    return pyplot()


def _md(text: str) -> str:
    """``text`` as Markdown shows it literally, on one line: a table cell's ``|`` split its row
    (a program's stderr lines are joined by them), and ``*``, ``_``, ``[``, ``<`` in names and
    messages rendered as emphasis, links or HTML."""
    out = " ".join(str(text).split("\n"))
    for ch in "\\`*_[]<>|":
        out = out.replace(ch, "\\" + ch)
    return out


def _cell(r: Mapping[str, Any], column: str) -> str:
    """One table cell: a text column (the scene, the estimator, the status) as it is (a scene
    folder named 1.50 or nan was shown as 1.5 or -), any other as :func:`_fmt` formats it."""
    v = r.get(column)
    if column in TEXT_COLUMNS and isinstance(v, str):
        return v
    return _fmt(v)


def _fmt(v: Any) -> str:
    if v is None:
        return "-"
    if isinstance(v, (float, np.floating)):
        if not math.isfinite(v):
            return "-"
        return f"{v:.4g}"
    if isinstance(v, str):
        try:
            f = float(v)
        except ValueError:
            return v
        return _fmt(f) if ("." in v or "e" in v.lower() or v.lower() == "nan") else v
    return str(v)


def format_table(rows: SequenceT[Mapping[str, Any]], columns: SequenceT[tuple[str, str]] = SUMMARY_COLUMNS) -> str:
    """Plain-text table (fixed-width columns) of ``rows`` (:func:`display_rows`)."""
    cells = [[h for _, h in columns]] + [[_cell(r, c) for c, _ in columns] for r in display_rows(rows)]
    widths = [max(len(row[i]) for row in cells) for i in range(len(columns))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip() for row in cells]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


@dataclass
class RunRecord:
    """Where one scored run lives (for plots that read the trajectories)."""

    scene: str
    estimator: str
    repetition: int
    seq_dir: Path
    run_dir: Path


@dataclass
class Report:
    """Collects sections, then writes ``report.html`` (self-contained) and ``report.md``."""

    title: str
    out_dir: Path
    stem: str = "report"
    _html: list[str] = field(default_factory=list)
    _md: list[str] = field(default_factory=list)
    n_figures: int = 0

    def heading(self, text: str, level: int = 2) -> None:
        self._html.append(f"<h{level}>{html.escape(text)}</h{level}>")
        self._md.append(f"{'#' * level} {text}\n")

    def text(self, text: str) -> None:
        self._html.append(f"<p>{html.escape(text)}</p>")
        self._md.append(f"{text}\n")

    def lines(self, lines: SequenceT[str]) -> None:
        """Lines of text kept apart (a gate's summary: it ran together in one paragraph)."""
        self._html.append("<p>" + "<br>".join(html.escape(t) for t in lines) + "</p>")
        self._md.append("\n".join(f"- {_md(t)}" for t in lines) + "\n")

    def table(self, rows: SequenceT[Mapping[str, Any]], columns: SequenceT[tuple[str, str]]) -> None:
        head = "".join(f"<th>{html.escape(h)}</th>" for _, h in columns)
        body = "".join(
            "<tr>" + "".join(f"<td>{html.escape(_cell(r, c))}</td>" for c, _ in columns) + "</tr>" for r in rows
        )
        self._html.append(f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>")
        md = ["| " + " | ".join(_md(h) for _, h in columns) + " |", "|" + "---|" * len(columns)]
        md += ["| " + " | ".join(_md(_cell(r, c)) for c, _ in columns) + " |" for r in rows]
        self._md.append("\n".join(md) + "\n")

    def figure(self, fig, caption: str) -> None:
        """Embed a matplotlib figure (base64 PNG in the HTML, a file under plots/ for the Markdown)."""
        plt = _plt()
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
        plt.close(fig)
        png = buf.getvalue()
        self.n_figures += 1
        name = f"plots/{self.stem}-fig{self.n_figures:02d}.png"
        atomic_write_bytes(self.out_dir / name, png)
        b64 = base64.b64encode(png).decode("ascii")
        self._html.append(
            f'<figure><img class="plot" alt="{html.escape(caption)}" src="data:image/png;base64,{b64}">'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>"
        )
        self._md.append(f"![{caption}]({name})\n")

    def write(self) -> tuple[Path, Path]:
        """Write ``STEM.html`` and ``STEM.md`` (default ``report``) in ``out_dir``; returns both paths."""
        style = (
            "body{font-family:sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}"
            "table{border-collapse:collapse;font-size:13px;margin:1em 0}td,th{border:1px solid #ccc;padding:3px 6px;text-align:right}"
            "th{background:#eee}td:first-child,td:nth-child(2){text-align:left}img.plot{max-width:100%}"
            "figure{margin:1em 0}figcaption{font-size:13px;color:#555}"
        )
        page = (
            f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(self.title)}</title>"
            f"<style>{style}</style></head><body><h1>{html.escape(self.title)}</h1>"
            + "\n".join(self._html)
            + "</body></html>\n"
        )
        html_path = self.out_dir / f"{self.stem}.html"
        md_path = self.out_dir / f"{self.stem}.md"
        atomic_write_text(html_path, page)
        atomic_write_text(md_path, f"# {self.title}\n\n" + "\n".join(self._md))
        return html_path, md_path


# ----------------------------------------------------------------------------- plots
def _plot_runs(recs: list[RunRecord]) -> tuple[list[PlotRun], tuple[np.ndarray, np.ndarray] | None]:
    """The runs of ``recs`` that placed poses, and their sequence's ground truth (None without)."""
    runs = [r for r in (load_plot_run(rec.run_dir, rec.estimator) for rec in recs) if r is not None]
    gt = recs[0].seq_dir / "groundtruth.txt" if recs else None
    return runs, (read_tum(gt) if gt is not None and gt.is_file() else None)


def _trajectory_figure(scene: str, recs: list[RunRecord]):
    runs, ref = _plot_runs(recs)
    if not runs:
        return None
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4))
    draw_trajectories(ax, runs, ref)
    if ref is None:
        ax.set_title(f"{scene}: estimated trajectories (no ground truth)")
    else:
        ax.set_title(f"{scene}: estimated against true trajectory (no alignment)")
    return fig


def _error_figure(scene: str, recs: list[RunRecord]):
    runs, ref = _plot_runs(recs)
    if not runs or ref is None:
        return None
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 3.5))
    if not draw_errors(ax, runs, ref):
        plt.close(fig)
        return None
    ax.set_title(f"{scene}: error against distance (no alignment)")
    return fig


def _timing_figure(recs: list[RunRecord]):
    plt = _plt()
    stages = ("detect_ms", "match_ms", "estimate_ms", "total_ms")
    per_est: dict[str, dict[str, list[float]]] = {}
    for rec in recs:
        t = read_timing_csv(rec.run_dir / "timing.csv")
        if not t:
            continue
        d = per_est.setdefault(rec.estimator, {s: [] for s in stages})
        for s in stages:
            if s in t:
                v = np.asarray(t[s], dtype=float)
                d[s] += v[np.isfinite(v)].tolist()
    if not per_est:
        return None
    names = sorted(per_est)
    fig, axes = plt.subplots(1, len(stages), figsize=(3 * len(stages), 3.2), sharey=False)
    for ax, s in zip(axes, stages):
        data = [per_est[n][s] or [np.nan] for n in names]
        ax.boxplot(data, showfliers=True)
        ax.set_xticks(range(1, len(names) + 1), names, rotation=30, ha="right", fontsize=8)
        ax.set_title(s.replace("_ms", "") + " [ms]", fontsize=10)
        ax.grid(alpha=0.3, axis="y")
    fig.suptitle("time per frame")
    fig.tight_layout()
    return fig


def _keypoint_figure(recs: list[RunRecord], max_frames: int = 3):
    """Frames with matched keypoints from ``RUN/matches/*.npz``; None when no run has any."""
    plt = _plt()
    for rec in recs:
        samples = read_match_samples(rec.run_dir)
        if not samples:
            continue
        picks = [samples[int(i)] for i in np.linspace(0, len(samples) - 1, min(max_frames, len(samples)))]
        seq = Sequence.open(rec.seq_dir)
        fig, axes = plt.subplots(1, len(picks), figsize=(4 * len(picks), 3.4))
        for ax, (idx, a, b) in zip(np.atleast_1d(axes), picks):
            img = seq.image(idx)
            ax.imshow(img, cmap="gray")
            if len(a):
                ax.plot(b[:, 0], b[:, 1], "o", ms=3, mfc="none", mec="lime")
                for p, q in zip(a, b):
                    ax.plot([q[0], p[0]], [q[1], p[1]], "-", color="yellow", lw=0.8)
            ax.set_title(f"{rec.estimator}: frame {idx}, {len(a)} matches", fontsize=9)
            ax.axis("off")
        fig.tight_layout()
        return fig, rec
    return None


def _accuracy_time_figure(rows: SequenceT[Mapping[str, Any]]):
    """ATE (SE2) against wall time per frame, one marker per scene x estimator (mean over the
    repetitions): the multi-objective view; None when no run has both figures."""
    points: dict[str, list[tuple[float, float]]] = {}
    groups: dict[tuple[str, str], list[Mapping[str, Any]]] = {}
    for r in rows:
        if str(r.get("status", "")) == "ok" and r.get("estimator"):
            groups.setdefault((str(r.get("scene")), str(r["estimator"])), []).append(r)
    for (_, est), rs in groups.items():
        err = _finite(r.get("ate_se2_rmse_mm") for r in rs)
        ms = _finite(r.get("wall_ms_per_frame") for r in rs)
        if err and ms:
            points.setdefault(est, []).append((float(np.mean(ms)), float(np.mean(err))))
    if not points:
        return None
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.5, 4))
    # every estimator its own colour and marker (beyond ten the default cycle drew two alike)
    markers = {"-": "o", "--": "s", ":": "^"}
    for (est, pts), (colour, ls) in zip(sorted(points.items()), run_styles(len(points)), strict=True):
        xs, ys = zip(*pts)
        ax.plot(xs, ys, markers[ls], color=colour, ms=7, label=est)
    ax.set_xscale("log")
    ax.set_xlabel("wall time per frame [ms] (log)")
    ax.set_ylabel("ATE after SE(2) alignment [mm]")
    ax.set_title("accuracy against time per frame (lower left is better)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0))  # beside the axes, not over them
    return fig


def _compare_section(rows: SequenceT[Mapping[str, Any]], rep: Report) -> None:
    """Estimators of every source side by side, accuracy against time, and the failed runs."""
    table = compare_estimators(rows)
    if not table:
        return
    rep.heading("Estimators compared")
    rep.text(
        "Built-ins, plugins and external programs side by side. Wall time per frame covers the whole run (frame "
        "reading, a program's start-up); peak memory is a program's own, or the bench process's during an "
        "in-process run. Accuracy averages the runs that have ground truth."
    )
    rep.table(table, COMPARE_COLUMNS)
    fig = _accuracy_time_figure(rows)
    if fig is not None:
        rep.figure(fig, "accuracy (ATE after SE(2) alignment) against wall time per frame, per scene and estimator")
    failed = [r for r in rows if str(r.get("status", "")).startswith("failed")]
    if failed:
        rep.heading("Failed runs", level=3)
        rep.table(
            failed,
            [("scene", "scene"), ("estimator", "estimator"), ("status", "reason"), ("stderr_tail", "stderr (tail)")],
        )


# ----------------------------------------------------------------------------- the bench report
def _lost_reasons_section(rows: SequenceT[Mapping[str, Any]], rep: Report) -> None:
    """The lost steps of each run counted per kind of reason (results.csv's ``lost_reasons``), when any was lost."""
    lost = [r for r in rows if r.get("lost_reasons")]
    if not lost:
        return
    rep.heading("Lost frames by reason")
    rep.text(
        "Each estimator checks its own steps and reports a step lost, with the reason, instead of a wrong motion "
        "(counted by the cause a reason names before a colon; numbers in a reason without one are shown as #). "
        "Wrong ok: steps reported ok that are off by more than 0.05 mm + 2 % of the true step or 0.3 degrees."
    )
    cols = [("scene", "scene"), ("estimator", "estimator"), ("repetition", "rep")]
    cols += [(md.LOST_FRAMES.name, md.LOST_FRAMES.label), (md.WRONG_OK_STEPS.name, md.WRONG_OK_STEPS.label)]
    rep.table(lost, cols + [("lost_reasons", "lost frames by reason")])


def _notes_section(rows: SequenceT[Mapping[str, Any]], rep: Report) -> None:
    """What a run's score or its scale calibration warned of (results.csv's ``score_warnings``), when any did."""
    noted = [r for r in rows if r.get("score_warnings")]
    if not noted:
        return
    rep.heading("Notes")
    rep.text("What a run's score or its scale calibration warned of: read its figures with it.")
    cols = [("scene", "scene"), ("estimator", "estimator"), ("repetition", "rep"), ("score_warnings", "note")]
    rep.table(noted, cols)


def build_bench_report(
    out_dir: str | os.PathLike,
    rows: SequenceT[Mapping[str, Any]],
    records: SequenceT[RunRecord],
    *,
    title: str = "floorbench report",
    gate_summary: str | None = None,
    extra_sections: Iterable = (),
) -> tuple[Path, Path]:
    """Write the bench report; returns ``(report.html, report.md)``.

    ``extra_sections``: callables ``f(report)`` that add their own sections (the paper
    reproductions).
    """
    out_dir = Path(out_dir)
    rep = Report(title, out_dir)
    rep.heading("Scores")
    rep.text(
        "One row per scene x estimator x repetition. ATE in mm without alignment (the estimate starts at the "
        "first ground-truth pose) and after the best SE(2) fit; drift in % of the distance travelled."
    )
    rep.table(display_rows(rows), SUMMARY_COLUMNS)
    _compare_section(rows, rep)
    _lost_reasons_section(rows, rep)
    _notes_section(rows, rep)
    if gate_summary:
        rep.heading("Regression gate")
        rep.lines(gate_summary.splitlines())
    for section in extra_sections:
        section(rep)
    by_scene: dict[str, list[RunRecord]] = {}
    for r in records:
        if r.repetition == 0:
            by_scene.setdefault(r.scene, []).append(r)
    for scene, recs in by_scene.items():
        rep.heading(f"Scene {scene}")
        traj = _trajectory_figure(scene, recs)
        if traj is None:
            rep.text("No estimator produced a trajectory on this scene.")
            continue
        has_gt = (recs[0].seq_dir / "groundtruth.txt").is_file()
        what = "against true trajectory" if has_gt else "trajectories (the sequence has no ground truth)"
        rep.figure(traj, f"{scene}: estimated (dots) {what}, seen from above")
        fig = _error_figure(scene, recs)
        if fig is not None:
            rep.figure(fig, f"{scene}: translation error against distance travelled")
    rep.heading("Timing")
    fig = _timing_figure(list(records))
    if fig is not None:
        rep.figure(fig, "time per frame by stage, all runs")
    else:
        rep.text("No timing.csv found.")
    rep.heading("Matched keypoints")
    kp = _keypoint_figure([r for r in records if r.repetition == 0])
    if kp is None:
        rep.text("No run wrote matched keypoints (RUN/matches/*.npz), so this plot is skipped.")
    else:
        rep.figure(
            kp[0],
            f"{kp[1].scene} / {kp[1].estimator}: matched keypoints (circles: current frame, lines to the previous position)",
        )
    return rep.write()

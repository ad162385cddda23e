"""Plots of runs against ground truth: the estimated trajectory seen from above, and the
translation error against the distance travelled. Used by ``floorvo plot`` (runs outside the
bench, e.g. of a recording) and by the bench report (:mod:`floorsim.bench.report`).

matplotlib is imported on the first plot, on its Agg backend (files only, no display).
"""

from __future__ import annotations

import io
import os
from collections.abc import Sequence as SequenceT
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from floorvo.errors import FloorbenchError
from floorvo.io import atomic_write_bytes
from floorvo.metrics import associate, translation_error_along_path
from floorvo.runfolder import RunFolder, check_run_of_sequence
from floorvo.sequence import read_groundtruth

__all__ = ["PlotRun", "pyplot", "draw_trajectories", "draw_errors", "load_plot_run", "plot_runs", "run_styles"]


def pyplot():
    """matplotlib's pyplot on the Agg backend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


@dataclass(frozen=True)
class PlotRun:
    """One run to draw: its ``label`` and the poses it placed, ``t_s`` (N,) and ``T_world_cam`` (N, 4, 4) mm;
    ``result``: its ``result.json``."""

    label: str
    t_s: np.ndarray
    T_world_cam: np.ndarray
    result: dict = field(default_factory=dict, repr=False, compare=False)


def load_plot_run(run_dir: str | os.PathLike, label: str | None = None) -> PlotRun | None:
    """A run folder as a :class:`PlotRun` (label: ``result.json``'s estimator, else the folder name);
    None when it has no pose or cannot be read (a failed run in a bench report: nothing to draw;
    :func:`plot_runs` says why)."""
    try:
        return _plot_run(run_dir, label)
    except FloorbenchError:
        return None


def _plot_run(run_dir: str | os.PathLike, label: str | None = None) -> PlotRun | None:
    """:func:`load_plot_run`, a folder that cannot be read refused in one line
    (:meth:`~floorvo.runfolder.RunFolder.read`: the file, the line and the rule, as ``floorvo score``)."""
    run = RunFolder.read(run_dir)
    if len(run.timestamps_s) == 0:
        return None
    name = label or str(run.result.get("estimator") or Path(run_dir).name)
    return PlotRun(name, run.timestamps_s, run.T_world_cam, dict(run.result))


#: The formats :func:`plot_runs` writes, by the output file's suffix.
PLOT_FORMATS = ("png", "pdf", "svg")


def run_styles(n: int) -> list[tuple[Any, str]]:
    """(colour, line style) of each of ``n`` runs, all different: matplotlib's ten colours, then
    twenty, each with three line styles (beyond ten runs the default cycle drew two runs alike)."""
    import matplotlib

    if n <= 10:
        return [(matplotlib.colormaps["tab10"](i), "-") for i in range(n)]
    cmap = matplotlib.colormaps["tab20"]
    return [(cmap(i % 20), ("-", "--", ":")[(i // 20) % 3]) for i in range(n)]


def draw_trajectories(ax: Any, runs: SequenceT[PlotRun], reference: tuple[np.ndarray, np.ndarray] | None) -> bool:
    """x-y of each run (and of the ground truth ``reference = (t_s, T_world_cam)``) on ``ax``, in mm,
    no alignment; a nearly straight path keeps unequal axes so its lateral error stays visible.
    Returns whether anything was drawn."""
    if not runs:
        return False
    if reference is not None:
        T_ref = reference[1]
        ax.plot(T_ref[:, 0, 3], T_ref[:, 1, 3], "k-", lw=2.5, alpha=0.5, label="ground truth")
    for r, (colour, ls) in zip(runs, run_styles(len(runs)), strict=True):
        ax.plot(r.T_world_cam[:, 0, 3], r.T_world_cam[:, 1, 3], ".", ls=ls, color=colour, ms=3, lw=1, label=r.label)
    ax.set_xlabel("x [mm]")
    xy = (reference[1] if reference is not None else np.concatenate([r.T_world_cam for r in runs]))[:, :2, 3]
    ext = np.ptp(xy, axis=0)
    if ext.min() < 0.05 * max(ext.max(), 1e-9):
        # a straight path: equal axes would flatten the lateral error to nothing
        ax.set_ylabel("y [mm] (magnified)" if ext[1] <= ext[0] else "y [mm]")
    else:
        ax.set_ylabel("y [mm]")
        ax.axis("equal")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return True


def draw_errors(
    ax: Any, runs: SequenceT[PlotRun], reference: tuple[np.ndarray, np.ndarray], max_diff_s: float = 0.01
) -> bool:
    """Translation error (mm, no alignment) against the distance travelled on the ground truth, per
    run (poses associated by time within ``max_diff_s``). Returns whether anything was drawn."""
    drawn = False
    t_ref, T_ref = reference
    for r, (colour, ls) in zip(runs, run_styles(len(runs)), strict=True):
        i_ref, i_est = associate(t_ref, r.t_s, max_diff_s)
        if len(i_ref) < 2:
            continue
        d, e = translation_error_along_path(T_ref[i_ref], r.T_world_cam[i_est], "none")
        ax.plot(d, e, ".", ls=ls, color=colour, ms=3, lw=1, label=r.label)
        drawn = True
    ax.set_xlabel("distance travelled [mm]")
    ax.set_ylabel("translation error [mm]")
    ax.grid(alpha=0.3)
    if drawn:
        ax.legend(fontsize=8)
    return drawn


def plot_runs(
    run_dirs: SequenceT[str | os.PathLike],
    groundtruth: str | os.PathLike | None,
    out_png: str | os.PathLike,
    *,
    title: str = "",
) -> Path:
    """Draw runs against ground truth into one PNG (written atomically): the trajectories from
    above and, with ground truth, the error against distance travelled.

    ``groundtruth``: a sequence folder (its ``groundtruth.txt``) or a TUM file, or None. A run
    folder without poses is refused, and one that cannot be read with the reader's reason
    (:meth:`~floorvo.runfolder.RunFolder.read`, as ``floorvo score`` gives it), as is a ground truth
    that does not fit its sequence (:func:`~floorvo.sequence.read_groundtruth`) or shares no
    timestamp with any run.
    """
    fmt = Path(out_png).suffix.lower().lstrip(".")
    named = str(out_png).strip() and Path(out_png).name not in ("", ".", "..")  # else: the writer says why
    if named and fmt not in PLOT_FORMATS:  # '-o out.pdf' wrote PNG bytes under that name
        raise FloorbenchError(
            f"{out_png}: the plot is written as {', '.join(PLOT_FORMATS)}, by the file's suffix: name it FILE.png"
        )
    runs = []
    for d in run_dirs:
        r = _plot_run(d)  # a damaged run folder: the reader's one line, as floorvo score gives it
        if r is None:
            raise FloorbenchError(f"{Path(d) / 'trajectory.txt'}: holds no pose; the run placed no frame to draw")
        runs.append(r)
    if not runs:
        raise FloorbenchError("floorvo plot: give at least one run folder")
    # Runs of one estimator (a calibrated and an uncalibrated one) had the same legend entry.
    names = [r.label for r in runs]
    for k, (r, d) in enumerate(zip(runs, run_dirs, strict=True)):
        if names.count(r.label) > 1:
            runs[k] = replace(r, label=f"{r.label} ({d})")
    reference = None
    if groundtruth is not None:
        gt = Path(groundtruth)
        for d, r in zip(run_dirs, runs):
            check_run_of_sequence(d, r.result, gt)
        _, reference = read_groundtruth(gt, "plot")
    plt = pyplot()
    panels = 2 if reference is not None else 1
    fig, axes = plt.subplots(panels, 1, figsize=(7.5, 4 * panels), squeeze=False)
    draw_trajectories(axes[0, 0], runs, reference)
    # the title as it was typed: matplotlib reads '$...$' as math ('drift $x_$' raised from inside it)
    axes[0, 0].set_title(
        title.replace("$", r"\$") or "estimated against true trajectory, seen from above (no alignment)"
    )
    if reference is not None:
        if not draw_errors(axes[1, 0], runs, reference):
            plt.close(fig)
            raise FloorbenchError(
                f"{groundtruth}: no run shares two timestamps with this ground truth (within 0.01 s): "
                "wrong sequence, or the run's frame times differ"
            )
        axes[1, 0].set_title("translation error against distance travelled (no alignment)")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format=fmt if fmt in PLOT_FORMATS else "png", dpi=100)
    plt.close(fig)
    atomic_write_bytes(out_png, buf.getvalue())
    return Path(out_png)

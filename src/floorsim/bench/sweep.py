"""Lighting-robustness sweeps: a grid of scene variations, run locally or on Dask.

A sweep file (TOML)::

    base = "../demo.toml"                 # scene file, relative to the sweep file
    estimators = ["name_a", "name_b"]     # optional: default every estimator the sequence supports
    repetitions = 1                       # optional: seeds scene seed + k

    [render]                              # optional, for every job: frames, scale, spp
    frames = 12
    scale = 0.25

    [set]                                 # optional fixed scene overrides
    "sensor.read_noise_e" = 2.0

    [vary]                                # the grid: every combination of these values
    "lights.height_mm" = [0.5, 1, 3, 10, 50]

    [operating_point]                     # optional: the paper rig's value of a varied key
    "lights.height_mm" = 3.0              # (default: the base scene's own value)

    sequences = ["../recordings/hall"]    # optional: sequence folders run beside the grid
                                          # (relative to the sweep file; not rendered, not varied;
                                          # a file of sequences alone needs no base and no [vary])

Keys are scene keys in ``--set`` form (``section.key``), so a sweep can vary only what the
scene file format has. One job is one grid point and repetition: it renders the scene (the
render cache of :func:`floorsim.bench.bench.render_cached` reuses an identical sequence) and
runs and scores every estimator on it, giving one row per estimator (paper protocols are
the bench's, not the sweep's). Each sequence folder of ``sequences`` is one more job
(``sequence=NAME``), run and scored as it is. External programs (``externals=``, from
``--external`` and ``--estimator-file``) run in every job beside the registry's estimators.

Execution: local processes by default (``jobs`` of them); ``scheduler="tcp://HOST:PORT"``
sends the same jobs to a Dask distributed cluster; ``workers=N`` starts a local Dask
cluster of N workers. Local workers exit when the main process dies, even by SIGKILL
(:func:`_exit_with_parent`; Dask's own workers watch their nanny the same way). Rows stream
into ``DIR/results.csv`` (atomically rewritten) as jobs finish, so an interrupted sweep
started again skips the jobs already there.
Then ``DIR/sweep.html`` and ``DIR/sweep.md`` hold the robustness curves: drift and
tracking loss against each varied parameter, one line per estimator, the operating point
marked.
"""

from __future__ import annotations

import itertools
import json
import logging
import math
import os
from collections.abc import Callable, Mapping
from collections.abc import Sequence as SequenceT
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from floorsim.bench.bench import (
    RenderFn,
    SceneLoader,
    is_sequence_folder,
    render_cached,
    run_one,
    scene_seed,
    source_columns,
    supported_estimators,
)
from floorsim.bench.estimators import DEFAULT_RUNNER, EstimatorRunner
from floorsim.bench.report import COMPARE_COLUMNS, Report, _plt, compare_estimators
from floorsim.bench.results import read_results_csv, write_results_csv
from floorsim.scene import load_scene as load_scene_file
from floorvo import metric_defs as md
from floorvo.errors import ConfigError, ExternalEstimatorError, FloorbenchError, shorten, shown
from floorvo.external import ExternalEstimator
from floorvo.io import read_toml

log = logging.getLogger(__name__)

__all__ = ["SweepSpec", "load_sweep", "sweep_jobs", "run_sweep_job", "run_sweep", "SweepResult", "plot_sweep"]

_TOP_KEYS = {"base", "estimators", "repetitions", "render", "set", "vary", "operating_point", "name", "sequences"}
_RENDER_KEYS = {"frames": int, "scale": float, "spp": int}
#: The most jobs (grid points x repetitions) a sweep file may ask for.
MAX_SWEEP_JOBS = 10_000


def _as_override(value: Any) -> str:
    """A TOML value as a ``--set`` string."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, dict)):
        return json.dumps(value)
    return str(value)


@dataclass(frozen=True)
class SweepSpec:
    """A parsed sweep file."""

    name: str
    base: Path | None  # None: a sweep of sequence folders alone (no grid)
    vary: dict[str, list[Any]]
    estimators: list[str] | None = None
    repetitions: int = 1
    render: dict[str, Any] = field(default_factory=dict)
    fixed: dict[str, str] = field(default_factory=dict)
    operating_point: dict[str, Any] = field(default_factory=dict)
    sequences: list[Path] = field(default_factory=list)


def _table(path: Path, d: Mapping[str, Any], key: str) -> dict[str, Any]:
    value = d.get(key, {})
    if not isinstance(value, dict):
        raise ConfigError(f"{path}: {key} = {shown(value)}: must be a table")
    return value


def _beside(path: Path, name: str, key: str) -> Path:
    """``name`` (a path in the sweep file, relative to it) as an absolute path."""
    try:
        return (path.parent / name).resolve()
    except (ValueError, OSError) as exc:  # an embedded NUL byte, a loop of links
        raise ConfigError(f"{path}: {key} = {shown(name)}: not a usable path ({shorten(str(exc))})") from None


def load_sweep(path: str | os.PathLike) -> SweepSpec:
    """Read and check a sweep file (ConfigError naming the key, the value and the rule).

    The grid (values of every varied key, times the repetitions) may hold at most
    :data:`MAX_SWEEP_JOBS` jobs. The render settings follow the rules of ``floorsim render``'s
    ``--frames`` (an integer >= 1), ``--scale`` (0, 4] and ``--spp`` (an integer >= 1).
    """
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: sweep file does not exist")
    d = read_toml(path, ConfigError)
    unknown = set(d) - _TOP_KEYS
    if unknown:
        raise ConfigError(
            f"{path}: unknown key(s) {shorten(', '.join(sorted(unknown)))} (known: {', '.join(sorted(_TOP_KEYS))})"
        )
    seqs = d.get("sequences", [])
    if not isinstance(seqs, list) or not all(isinstance(q, str) for q in seqs):
        raise ConfigError(f"{path}: sequences = {shown(seqs)}: must be a list of sequence folders")
    sequences = [_beside(path, q, "sequences") for q in seqs]
    for q, full in zip(seqs, sequences):
        if not is_sequence_folder(full):
            raise ConfigError(f"{path}: sequences: {shown(q)}: not a sequence folder (no {full / 'sequence.json'})")
    base: Path | None = None
    if "base" in d or not sequences:  # a sweep of sequence folders alone has no grid
        if not isinstance(d.get("base"), str) or not d["base"]:
            raise ConfigError(f"{path}: base = {shown(d.get('base'))}: must name the base scene file")
        base = _beside(path, d["base"], "base")
        if not base.is_file():
            raise ConfigError(f"{path}: base = {shown(d['base'])}: scene file {shorten(str(base))} does not exist")
    vary = d.get("vary", {} if base is None else None)
    if base is None and (vary or not isinstance(vary, dict)):
        raise ConfigError(f"{path}: [vary] needs base = the scene file whose keys it varies")
    if base is not None and (not isinstance(vary, dict) or not vary):
        raise ConfigError(f"{path}: [vary] must name at least one scene key with a list of values")
    jobs = 1
    for k, v in vary.items():
        if not isinstance(v, list) or not v:
            raise ConfigError(f"{path}: vary.{shorten(k)} = {shown(v)}: must be a non-empty list of values")
        if len({_as_override(x) for x in v}) != len(v):
            raise ConfigError(f"{path}: vary.{shorten(k)} = {shown(v)}: values must be distinct")
        jobs *= len(v)
    est = d.get("estimators")
    if est is not None and (not isinstance(est, list) or not all(isinstance(e, str) for e in est) or not est):
        raise ConfigError(f"{path}: estimators = {shown(est)}: must be a non-empty list of names")
    reps = d.get("repetitions", 1)
    if not isinstance(reps, int) or isinstance(reps, bool) or reps < 1:
        raise ConfigError(f"{path}: repetitions = {shown(reps)}: must be an integer >= 1")
    if jobs * reps > MAX_SWEEP_JOBS:
        raise ConfigError(f"{path}: the grid holds {jobs * reps} jobs (values x repetitions); at most {MAX_SWEEP_JOBS}")
    render = _table(path, d, "render")
    for k, v in render.items():
        if k not in _RENDER_KEYS:
            raise ConfigError(f"{path}: render.{shorten(k)}: unknown key (known: {', '.join(_RENDER_KEYS)})")
        whole = _RENDER_KEYS[k] is int
        if isinstance(v, bool) or not isinstance(v, int if whole else (int, float)) or not 0 < v < math.inf:
            rule = "an integer >= 1" if whole else "a number > 0"
            raise ConfigError(f"{path}: render.{k} = {shown(v)}: must be {rule}")
        if k == "scale" and v > 4:
            raise ConfigError(f"{path}: render.scale = {shown(v)}: must be <= 4")
    render = {k: _RENDER_KEYS[k](v) for k, v in render.items()}
    op = _table(path, d, "operating_point")
    for k in op:
        if k not in vary:
            raise ConfigError(f"{path}: operating_point.{shorten(k)}: not a varied key (varied: {', '.join(vary)})")
    fixed = {k: _as_override(v) for k, v in _table(path, d, "set").items()}
    name = d.get("name", path.stem)
    if not isinstance(name, str) or not name:
        raise ConfigError(f"{path}: name = {shown(name)}: must be a non-empty string")
    return SweepSpec(name, base, {k: list(v) for k, v in vary.items()}, est, reps, render, fixed, dict(op), sequences)


def sweep_jobs(spec: SweepSpec) -> list[dict[str, Any]]:
    """Every job: the grid's ``{"job": id, "params": {key: value}, "repetition": k}``, then one
    ``{"job": "sequence=NAME", "params": {}, "repetition": 0, "sequence": folder}`` per sequence folder."""
    keys = list(spec.vary)
    jobs: list[dict[str, Any]] = []
    for combo in itertools.product(*(spec.vary[k] for k in keys)) if spec.base is not None else ():
        params = dict(zip(keys, combo))
        for rep in range(spec.repetitions):
            jid = ";".join(f"{k}={_as_override(v)}" for k, v in params.items()) + f";rep={rep}"
            jobs.append({"job": jid, "params": params, "repetition": rep})
    for q in spec.sequences:
        jobs.append({"job": f"sequence={q.name}", "params": {}, "repetition": 0, "sequence": str(q)})
    return jobs


def run_sweep_job(
    job: Mapping[str, Any],
    spec: SweepSpec,
    out_dir: str,
    cache_dir: str,
    render: RenderFn | None = None,
    load_scene: SceneLoader = load_scene_file,
    runner: EstimatorRunner | None = None,
) -> list[dict[str, Any]]:
    """Render one grid point and run and score every estimator on it; returns its rows.

    Runs in a worker (a local process or a Dask worker): takes and returns plain data (the
    collaborators ``render``, ``load_scene`` and ``runner`` are picklable: module-level
    functions and an :class:`~floorsim.bench.estimators.EstimatorRunner`).
    A user error (bad scene value, a failed run) becomes a row with ``status`` saying why.
    """
    out, cache = Path(out_dir), Path(cache_dir)
    base_row = {"job": job["job"], "repetition": job["repetition"], **{k: job["params"].get(k) for k in spec.vary}}
    overrides = {**spec.fixed, **{k: _as_override(v) for k, v in job["params"].items()}}
    runner = runner or DEFAULT_RUNNER
    estimators = spec.estimators
    if estimators is not None:
        estimators = list(estimators) + [n for n in runner.externals if n not in estimators]
    try:
        if job.get("sequence"):
            seq_dir, seed, scene_name = Path(job["sequence"]), None, Path(job["sequence"]).name
        else:
            assert spec.base is not None  # grid jobs exist only with a base scene
            scene = load_scene(spec.base, overrides)
            seed, scene_name = scene_seed(scene) + int(job["repetition"]), scene.name
            seq_dir = render_cached(scene, cache, seed=seed, render=render, **spec.render)
        names, skipped = supported_estimators(seq_dir, estimators, runner)
    except FloorbenchError as exc:
        return [{**base_row, "scene": spec.name, "estimator": "", "status": f"failed: {exc}"}]
    rows = []
    safe = "".join(c if c.isalnum() or c in "-_.=" else "_" for c in job["job"])
    for name in names:
        run_dir = out / "runs" / safe / name
        row = {
            **base_row,
            "scene": scene_name,
            "estimator": name,
            "seed": seed,
            "sequence": str(seq_dir),
            "run_dir": str(run_dir),
        }
        try:
            row.update(source_columns(runner, name))
            row.update(run_one(seq_dir, name, run_dir, runner=runner))
            row["status"] = "ok"
        except ExternalEstimatorError as exc:
            row["status"] = f"failed: {exc.reason}"
            row["stderr_tail"] = exc.stderr_tail
        except FloorbenchError as exc:
            row["status"] = f"failed: {exc}"
        rows.append(row)
    for name, why in skipped.items():
        rows.append({**base_row, "scene": scene_name, "estimator": name, "status": f"skipped: {why}"})
    return rows


@dataclass
class SweepResult:
    rows: list[dict[str, Any]]
    results_csv: Path
    ran: int
    skipped: int
    errors: list[str]
    report_html: Path | None = None
    report_md: Path | None = None


def run_sweep(
    sweep_path: str | os.PathLike,
    out_dir: str | os.PathLike,
    scheduler: str | None = None,
    workers: int | None = None,
    *,
    jobs: int = 1,
    cache_dir: str | os.PathLike | None = None,
    processes: bool = True,
    report: bool = True,
    on_job: Callable[[int, int], None] | None = None,
    externals: SequenceT[ExternalEstimator] = (),
    render: RenderFn | None = None,
    load_scene: SceneLoader = load_scene_file,
    runner: EstimatorRunner | None = None,
) -> SweepResult:
    """Run a sweep file's grid (see the module doc); returns the rows and where things are.

    ``scheduler``: a Dask scheduler address; ``workers``: start a local Dask cluster of
    that many workers (``processes=False`` makes them threads, for tests); neither: a local
    process pool of ``jobs`` workers. Collaborators of every job (defaults: the real ones,
    as in :func:`floorsim.bench.bench.run_bench`): ``render``, ``load_scene``, ``runner``.
    ``externals``: programs run in every job (:class:`floorvo.external.ExternalEstimator`).
    """
    runner = (runner or DEFAULT_RUNNER).with_externals(externals)
    if scheduler is not None and workers is not None:
        raise ConfigError("--scheduler and --workers: give one of them (a cluster to join, or a local one to start)")
    if workers is not None and workers < 1:
        raise ConfigError(f"--workers {workers}: must be >= 1")
    if jobs < 1:
        raise ConfigError(f"--jobs {jobs}: must be >= 1")
    spec = load_sweep(sweep_path)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    # Absolute paths: a Dask worker runs in another folder (on a cluster: a shared file system).
    cache = str((Path(cache_dir) if cache_dir is not None else out_dir / "sequences").resolve())
    results_csv = out_dir / "results.csv"
    rows = read_results_csv(results_csv)
    done = {r.get("job") for r in rows}
    all_jobs = sweep_jobs(spec)
    todo = [j for j in all_jobs if j["job"] not in done]
    log.info(
        "sweep %s: %d jobs, %d already done, %d to run", spec.name, len(all_jobs), len(all_jobs) - len(todo), len(todo)
    )
    errors: list[str] = []
    finished = 0

    def collect(job: Mapping[str, Any], result: list[dict[str, Any]] | None, exc: BaseException | None) -> None:
        nonlocal finished
        finished += 1
        if exc is not None:
            errors.append(f"{job['job']}: {type(exc).__name__}: {exc}")
            log.error("sweep job %s failed: %s", job["job"], exc, exc_info=exc)
        else:
            rows.extend(result or [])
            write_results_csv(results_csv, rows)
        if on_job:
            on_job(finished, len(todo))

    if todo:
        args = (spec, str(out_dir.resolve()), cache, render, load_scene, runner)
        if scheduler is not None or workers is not None:
            _run_dask(todo, args, collect, scheduler, workers, processes)
        else:
            _run_local(todo, args, collect, jobs)
    res = SweepResult(rows, results_csv, len(todo), len(all_jobs) - len(todo), errors)
    if report and rows:
        res.report_html, res.report_md = plot_sweep(spec, rows, out_dir, load_scene=load_scene)
    return res


def _exit_with_parent(parent_alive) -> None:
    """Worker initializer: exit at once when the sweep's main process dies (even by SIGKILL).

    ``parent_alive`` is the read end of a pipe whose write end only the main process holds;
    when that process is gone the pipe closes, the watching thread's ``recv`` ends and the
    worker exits, instead of computing for minutes results nobody collects (Dask's workers
    do the same with their nanny's pipe).
    """
    import threading

    def watch() -> None:
        try:
            parent_alive.recv()
        except (EOFError, OSError):
            pass
        os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


def _run_local(todo, args, collect, jobs: int) -> None:
    import concurrent.futures as cf
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    parent_alive, keep_alive = ctx.Pipe(duplex=False)  # keep_alive: never written, closed when this process ends
    try:
        with cf.ProcessPoolExecutor(
            max_workers=jobs, mp_context=ctx, initializer=_exit_with_parent, initargs=(parent_alive,)
        ) as pool:
            futs = {pool.submit(run_sweep_job, job, *args): job for job in todo}
            try:
                for fut in cf.as_completed(futs):
                    exc = fut.exception()
                    collect(futs[fut], None if exc else fut.result(), exc)
            except KeyboardInterrupt:
                for f in futs:
                    f.cancel()
                raise
    finally:
        keep_alive.close()
        parent_alive.close()


def _run_dask(todo, args, collect, scheduler: str | None, workers: int | None, processes: bool) -> None:
    from dask.distributed import Client, LocalCluster, as_completed  # heavy, and only for Dask runs

    cluster = None
    try:
        if scheduler is not None:
            try:
                client = Client(scheduler, timeout="10s")
            except (OSError, TimeoutError) as exc:
                raise FloorbenchError(
                    f"--scheduler {scheduler}: cannot connect to a Dask scheduler there ({exc})"
                ) from None
        else:
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=processes, dashboard_address=None)
            client = Client(cluster)
        with client:
            futs = {}
            for job in todo:
                f = client.submit(run_sweep_job, job, *args, key=f"floorsim-sweep-{job['job']}", pure=False)
                futs[f.key] = (f, job)
            for fut in as_completed([f for f, _ in futs.values()]):
                job = futs[fut.key][1]
                if fut.status == "error":
                    collect(job, None, fut.exception())
                else:
                    collect(job, fut.result(), None)
    finally:
        if cluster is not None:
            cluster.close()


# ----------------------------------------------------------------------------- robustness curves
def _operating_value(spec: SweepSpec, key: str, load_scene: SceneLoader) -> Any:
    if key in spec.operating_point:
        return spec.operating_point[key]
    try:
        if spec.base is None:
            return None
        d = load_scene(spec.base, dict(spec.fixed)).to_dict()
        for part in key.split("."):
            d = d[part]
        return d
    except (FloorbenchError, KeyError, TypeError, ImportError):
        return None


def _num(v: Any) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return float("nan")


def plot_sweep(
    spec: SweepSpec, rows: list[dict[str, Any]], out_dir: str | os.PathLike, load_scene: SceneLoader = load_scene_file
) -> tuple[Path, Path]:
    """Write ``sweep.html`` / ``sweep.md``: per varied key, drift and tracking loss against
    its values (mean over the other keys and repetitions), one line per estimator; the
    operating point is the sweep's, else the base scene's value (read with ``load_scene``)."""
    plt = _plt()
    rep = Report(f"floorbench sweep: {spec.name}", Path(out_dir), stem="sweep")
    ok = [r for r in rows if r.get("status") == "ok"]
    rep.text(
        f"Base scene {spec.base.name if spec.base else '(none: sequence folders only)'}; {len(rows)} rows, "
        f"{len(ok)} scored. Each point is the mean over the "
        "other varied keys and the repetitions; the dashed line marks the paper rig's operating point. "
        "Failed or skipped jobs are listed in results.csv."
    )
    estimators = sorted({r["estimator"] for r in ok})
    rep.heading("Estimators compared")
    rep.table(compare_estimators(rows), COMPARE_COLUMNS)
    for key, values in spec.vary.items():
        rep.heading(key)
        numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)
        xs_sorted = sorted(values) if numeric else list(values)
        pos = {(_as_override(v)): (float(v) if numeric else i) for i, v in enumerate(xs_sorted)}
        fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
        table = []
        for est in estimators:
            drift, lost = [], []
            for v in xs_sorted:
                sel = [r for r in ok if r["estimator"] == est and _as_override(r.get(key)) == _as_override(v)]
                sel = sel or [r for r in ok if r["estimator"] == est and _num(r.get(key)) == _num(v)]
                d = [_num(r.get(md.END_DRIFT.name)) for r in sel]
                lo = [_num(r.get(md.LOST_FRAMES.name)) for r in sel]
                drift.append(float(np.nanmean(d)) if d and np.isfinite(d).any() else np.nan)
                lost.append(float(np.nanmean(lo)) if lo and np.isfinite(lo).any() else np.nan)
                table.append(
                    {"estimator": est, "value": _as_override(v), "drift": drift[-1], "lost": lost[-1], "n": len(sel)}
                )
            x = [pos[_as_override(v)] for v in xs_sorted]
            axes[0].plot(x, drift, "o-", label=est)
            axes[1].plot(x, lost, "o-", label=est)
        op = _operating_value(spec, key, load_scene)
        for ax, ylabel in zip(axes, ("end-point drift [% of distance]", "lost frames")):
            if op is not None and _as_override(op) in pos:
                ax.axvline(pos[_as_override(op)], color="k", ls="--", lw=1, label="paper rig")
            elif op is not None and numeric and isinstance(op, (int, float)):
                ax.axvline(float(op), color="k", ls="--", lw=1, label="paper rig")
            if numeric and min(values) > 0 and max(values) / min(values) > 20:
                ax.set_xscale("log")
            if not numeric:
                ax.set_xticks(range(len(xs_sorted)), [str(v) for v in xs_sorted])
            ax.set_xlabel(key)
            ax.set_ylabel(ylabel)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8)
        fig.suptitle(f"robustness against {key}")
        fig.tight_layout()
        rep.figure(fig, f"drift and tracking loss against {key} (operating point {op!r})")
        rep.table(
            table,
            [
                ("estimator", "estimator"),
                ("value", key),
                ("drift", md.END_DRIFT.label),
                ("lost", "lost frames"),
                ("n", "runs"),
            ],
        )
    return rep.write()

"""Lighting-robustness studies: grids, breaking-point searches and envelopes, run locally or on Dask.

:func:`run_sweep` is the library function behind ``floorsim sweep STUDY.toml -o DIR``. The
study (or sweep) file format is :mod:`floorsim.bench.study`'s: a base scene, the scene keys
to vary (``[vary]``: a grid) or to search (``[search]``: a breaking point), a failure
``[criterion]``, repetitions with their seeds, estimators and their configs.

One job is one scene variation and repetition: it renders the scene (the render cache of
:func:`floorsim.bench.bench.render_cached` reuses an identical sequence) and runs and scores
every estimator on it, giving one row per estimator: one render serves every estimator.
Each folder of the file's ``sequences`` is one more job (``sequence=NAME``), run and scored
as it is (not rendered, not varied, not searched). External programs (``externals=``, from
``--external`` and ``--estimator-file``) run in every job beside the registry's estimators.

* **Grid**: every combination of the ``[vary]`` values, times the repetitions.
* **Search**: per combination of the ``[vary]`` values (none: one) and per repetition, each
  estimator's breaking point is bracketed by bisection on the search grid
  (:mod:`floorsim.bench.search`). Jobs run in rounds: the first renders both ends, each
  later one the midpoints the open brackets ask for (shared between estimators); every
  evaluated value narrows every estimator's bracket. The result states, per estimator, the
  breaking point, its bracket, its confidence interval over the seeds, the renders it took
  and the renders a grid at the same tolerance would have taken
  (``DIR/breaking_points.csv``, the report, :meth:`SweepResult.summary_lines`).

Execution: :func:`job_pool` (the one place workers are started and stopped): local
processes by default (``jobs`` of them); ``scheduler="tcp://HOST:PORT"`` sends the same
jobs to a Dask distributed cluster; ``workers=N`` starts a local Dask cluster of N workers.
A Dask worker lost mid-job (killed, out of memory) is replaced by its nanny and the
scheduler runs the job again elsewhere (up to ``distributed.scheduler.allowed-failures``
times); its rows come back once, from the run that finished. Rows stream into
``DIR/results.csv`` (atomically rewritten) as jobs finish, so an interrupted study started
again skips the jobs already there (a search replays its rounds from them).

``DIR/study.toml`` and ``DIR/study.json`` record the study (:func:`floorsim.bench.study.write_study_record`);
``DIR/sweep.html`` and ``DIR/sweep.md`` hold the report (:mod:`floorsim.bench.sweep_report`).
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator, Mapping
from collections.abc import Sequence as SequenceT
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from floorsim.bench.bench import (
    RenderFn,
    SceneLoader,
    check_cache_dir,
    check_sequence_folder,
    render_cached,
    run_one,
    scene_seed,
    source_columns,
    supported_estimators,
)
from floorsim.bench.estimators import DEFAULT_RUNNER, EstimatorRunner, check_estimator_choice
from floorsim.bench.results import (
    RESULTS_CSV,
    STUDY_RECORD,
    other_results_problem,
    read_results_csv,
    write_results_csv,
)
from floorsim.bench.search import (
    Bracket,
    EstimatorBreakingPoint,
    SearchResult,
    bracket,
    combine_brackets,
    search_grid,
)
from floorsim.bench.study import (
    SweepSpec,
    as_override,
    load_sweep,
    remove_study_record,
    resume_problem,
    scene_key_unit,
    write_study_record,
)
from floorsim.bench.sweep_report import write_sweep_report
from floorsim.scene import load_scene as load_scene_file
from floorvo.errors import ConfigError, ExternalEstimatorError, FloorbenchError, shown
from floorvo.external import ExternalEstimator
from floorvo.io import atomic_write_csv, path_text
from floorvo.locking import locks_folder

log = logging.getLogger(__name__)

__all__ = [
    "SweepSpec",
    "load_sweep",
    "sweep_jobs",
    "make_job",
    "run_sweep_job",
    "run_sweep",
    "job_pool",
    "SweepResult",
    "SearchResult",
    "EstimatorBreakingPoint",
    "plot_sweep",
    "scene_key_unit",
]

_as_override = as_override  # the name the sweep tests and older callers use

#: ``collect(job, rows or None, exception or None)``: what a pool calls as each job ends.
Collect = Callable[[Mapping[str, Any], "list[dict[str, Any]] | None", "BaseException | None"], None]
#: ``run_batch(jobs, collect)``: run jobs on the pool, calling ``collect`` as each ends; returns when all did.
RunBatch = Callable[[list[dict[str, Any]], Collect], None]


# ----------------------------------------------------------------------------- jobs
def make_job(params: Mapping[str, Any], repetition: int) -> dict[str, Any]:
    """One job: ``{"job": id, "params": {key: value}, "repetition": k}``; the id is
    ``key=value;...;rep=k`` (the ``job`` column of results.csv, how a restart finds it)."""
    jid = ";".join(f"{k}={as_override(v)}" for k, v in params.items()) + f";rep={repetition}"
    return {"job": jid, "params": dict(params), "repetition": int(repetition)}


def _combinations(vary: Mapping[str, list[Any]]) -> list[dict[str, Any]]:
    """Every combination of the ``[vary]`` values (one empty one when nothing varies)."""
    keys = list(vary)
    return [dict(zip(keys, combo)) for combo in itertools.product(*(vary[k] for k in keys))]


def sweep_jobs(spec: SweepSpec) -> list[dict[str, Any]]:
    """Every job of the ``[vary]`` grid and the repetitions (none for a search: its jobs come from
    its rounds), then one ``{"job": "sequence=NAME", "params": {}, "repetition": 0, "sequence":
    folder}`` per sequence folder of the file."""
    jobs = []
    if spec.vary and spec.search is None:
        jobs = [make_job(params, rep) for params in _combinations(spec.vary) for rep in range(spec.repetitions)]
    for q in spec.sequences:
        jobs.append({"job": f"sequence={path_text(q.name)}", "params": {}, "repetition": 0, "sequence": str(q)})
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
    """Render one job's scene and run and score every estimator on it; returns its rows.

    Runs in a worker (a local process or a Dask worker): takes and returns plain data (the
    collaborators ``render``, ``load_scene`` and ``runner`` are picklable: module-level
    functions and an :class:`~floorsim.bench.estimators.EstimatorRunner`).
    A user error (bad scene value, a failed run) becomes a row with ``status`` saying why.
    """
    out, cache = Path(out_dir), Path(cache_dir)
    base_row = {"job": job["job"], "repetition": job["repetition"], **job["params"]}
    overrides = {**spec.fixed, **{k: as_override(v) for k, v in job["params"].items()}}
    runner = runner or DEFAULT_RUNNER
    estimators = spec.estimators
    if estimators is not None:
        estimators = list(estimators) + [n for n in runner.externals if n not in estimators]
    seed: int | None
    try:
        if job.get("sequence"):
            seq_dir, seed, scene_name = Path(job["sequence"]), None, Path(job["sequence"]).name
        else:
            assert spec.base is not None  # grid and search jobs exist only with a base scene
            scene = load_scene(spec.base, overrides)
            seed, scene_name = spec.seed(scene_seed(scene), int(job["repetition"])), scene.name
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
            row.update(run_one(seq_dir, name, run_dir, spec.estimator_config.get(name), runner=runner))
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


# ----------------------------------------------------------------------------- the pool
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


#: How many local workers (``--jobs``, ``--workers``) a study may start per CPU this process may
#: use: each holds a scene of up to 1.8 GB and renders on every CPU it gets, so more than a few
#: per CPU only wait and fill the memory; ``--jobs 1000000`` tried to start a million processes.
MAX_WORKERS_PER_CPU = 4


def usable_cpus() -> int:
    """The CPUs this process may run on (its affinity where the system has one, else all)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - no sched_getaffinity (macOS, Windows)
        return max(1, os.cpu_count() or 1)


def local_workers_problem(n: int) -> str | None:
    """Why ``n`` local worker processes is no count a study may start (1 to
    :data:`MAX_WORKERS_PER_CPU` per usable CPU), or None."""
    most = MAX_WORKERS_PER_CPU * usable_cpus()
    if not 1 <= n <= most:
        return f"must be from 1 to {most} ({MAX_WORKERS_PER_CPU} per CPU of the {usable_cpus()} this process may use)"
    return None


def scheduler_problem(address: str) -> str | None:
    """Why ``address`` is not a Dask scheduler address (``tcp://HOST:PORT``, ``HOST:PORT``,
    ``tls://...``), or None: checked before anything is written (``notaurl`` was a 62-line
    traceback from inside Dask, after the study's record was written)."""
    from distributed.comm.addressing import parse_address, parse_host_port  # only for Dask runs

    try:
        scheme, location = parse_address(address)
        if scheme in ("tcp", "tls"):
            parse_host_port(location)
    except ValueError as exc:
        return f"not a Dask scheduler address, e.g. tcp://HOST:PORT ({exc})"
    return None


@contextlib.contextmanager
def job_pool(
    scheduler: str | None = None, workers: int | None = None, jobs: int = 1, processes: bool = True
) -> Iterator[Callable[..., None]]:
    """The one place a study starts and stops its workers; yields ``run_batch(fn, todo, args, collect)``.

    ``run_batch`` runs ``fn(job, *args)`` for every job of ``todo`` and calls
    ``collect(job, result, None)`` or ``collect(job, None, exception)`` in this process as
    each ends; it returns when all did, and may be called again (a search's rounds) on the
    same workers. ``scheduler``: a Dask scheduler address to join; ``workers``: start a
    local Dask cluster of that many single-threaded workers (``processes=False``: threads,
    for tests); neither: a local process pool of ``jobs`` workers (spawned: no state
    inherited from the parent). Workers are stopped when the ``with`` block ends; local
    workers also exit when this process dies, even by SIGKILL (:func:`_exit_with_parent`;
    Dask's own workers watch their nanny the same way).
    """
    if scheduler is None and workers is None:
        import concurrent.futures as cf
        import multiprocessing as mp

        ctx = mp.get_context("spawn")
        parent_alive, keep_alive = ctx.Pipe(duplex=False)  # keep_alive: never written, closed when this process ends
        try:
            with cf.ProcessPoolExecutor(
                max_workers=jobs, mp_context=ctx, initializer=_exit_with_parent, initargs=(parent_alive,)
            ) as pool:

                def run_local(fn: Callable[..., Any], todo: list, args: tuple, collect: Collect) -> None:
                    futs = {pool.submit(fn, job, *args): job for job in todo}
                    try:
                        for fut in cf.as_completed(futs):
                            exc = fut.exception()
                            collect(futs[fut], None if exc else fut.result(), exc)
                    except KeyboardInterrupt:  # Ctrl-C, or SIGTERM (floorvo.cli.Terminated)
                        for f in futs:
                            f.cancel()
                        # Stop the workers' jobs too: the pool's shutdown waits for them, and a SIGTERM
                        # reaches this process alone (Ctrl-C the whole process group), so the command
                        # waited for jobs whose rows it no longer collects. A job so stopped leaves what a
                        # killed one does (the next run takes its locks over, removes its temporaries).
                        for child in mp.active_children():
                            child.terminate()
                        raise

                yield run_local
        finally:
            keep_alive.close()
            parent_alive.close()
        return

    import dask  # heavy, and only for Dask runs
    from dask.distributed import Client, LocalCluster, as_completed

    # Dask's own loggers (their level set by its configuration on import) pass every record to the
    # CLI's handler: 24 'INFO distributed.*' lines a sweep, under -q too, and on a Ctrl-C its nanny's
    # warning that it killed a worker still in a job. Errors only, but with -v (its INFO then): what
    # a job met comes back as its future's exception, and is reported as the job's.
    debug = logging.getLogger("floorsim").getEffectiveLevel() <= logging.DEBUG
    logging.getLogger("distributed").setLevel(logging.INFO if debug else logging.ERROR)
    cluster = None
    # the local workers' scratch space and its config: Dask's default, $TMPDIR/dask-scratch-space, outlived the sweep
    scratch_space = contextlib.ExitStack()
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise FloorbenchError(
                f"--scheduler {scheduler}: cannot connect to a Dask scheduler there ({exc})"
            ) from None
    else:
        scratch = tempfile.mkdtemp(prefix="floorsim-dask-")
        scratch_space.callback(shutil.rmtree, scratch, ignore_errors=True)
        # its lock files too (dask-scratch-space/global.lock under $TMPDIR otherwise)
        scratch_space.enter_context(dask.config.set({"temporary-directory": scratch}))
        cluster = LocalCluster(
            n_workers=workers,
            local_directory=scratch,
            threads_per_worker=1,
            processes=processes,
            dashboard_address=None,
            # the scheduler's web server (it serves more than the dashboard) on a free port: on 8787, in
            # use, Dask warned in four lines
            scheduler_kwargs={"dashboard_address": ":0"},
            # The workers' own log records (a task cancelled by an interrupt warned in a line each) to
            # errors; a job's failure comes back as its future's exception. A worker ignores Ctrl-C,
            # which this process handles (:mod:`floorsim.bench.dask_worker`).
            silence_logs=logging.ERROR,
            preload=["floorsim.bench.dask_worker"],
        )
        client = Client(cluster)
    try:

        def run_dask(fn: Callable[..., Any], todo: list, args: tuple, collect: Collect) -> None:
            futs = {}
            for job in todo:
                # A key per job: a job that a lost worker held is rescheduled under the same key,
                # and its one result comes back here once.
                f = client.submit(fn, job, *args, key=f"floorsim-sweep-{job['job']}", pure=False)
                futs[f.key] = (f, job)
            for fut in as_completed([f for f, _ in futs.values()]):
                job = futs[fut.key][1]
                if fut.status == "error":
                    collect(job, None, fut.exception())
                else:
                    collect(job, fut.result(), None)

        yield run_dask
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
        scratch_space.close()


# ----------------------------------------------------------------------------- results
@dataclass
class SweepResult:
    rows: list[dict[str, Any]]
    results_csv: Path
    ran: int
    skipped: int
    errors: list[str]
    report_html: Path | None = None
    report_md: Path | None = None
    search: SearchResult | None = None
    breaking_points_csv: Path | None = None
    record: Path | None = None

    def summary_lines(self) -> list[str]:
        """What ``floorsim sweep`` prints about the study's answer (the search's breaking points)."""
        return self.search.summary_lines() if self.search is not None else []


# ----------------------------------------------------------------------------- checks before any job
def _scene_value(scene: Any, key: str) -> Any:
    d = scene.to_dict()
    for part in key.split("."):
        d = d[part]
    return d


def _check_study(spec: SweepSpec, load_scene: SceneLoader, runner: EstimatorRunner) -> Any:
    """Refuse, before any job, what would make every job fail: unknown estimators or config
    keys (:func:`floorsim.bench.estimators.check_estimator_choice`, the bench's check), a
    sequence folder that cannot be read (:func:`floorsim.bench.bench.check_sequence_folder`),
    scene keys or values the scene refuses, a search key that is not a number.
    Returns the base scene (the ``[set]`` overrides applied), None for sequence folders alone."""
    where = spec.path.name if spec.path is not None else spec.name
    check_estimator_choice(
        runner,
        spec.estimators,
        spec.estimator_config,
        names_label=f"{where}: estimators",
        config_label=f"{where}: estimator_config.",
    )
    for q in spec.sequences:
        try:
            check_sequence_folder(q)  # as the bench checks its sequence folders
        except FloorbenchError as exc:
            raise ConfigError(f"{where}: sequences: {exc}") from None
    if spec.base is None:
        return None
    base = load_scene(spec.base, dict(spec.fixed))
    tries = [(k, v) for k, vs in spec.vary.items() for v in vs]
    if spec.search is not None:
        tries += [(spec.search.key, spec.search.low), (spec.search.key, spec.search.high)]
    # the operating point's values are held to the scene's rules as the grid's are (a NaN or a
    # text was reported as "operating point nan", and a search's margins measured from it)
    tries += [(f"operating_point.{k}", v) for k, v in spec.operating_point.items()]
    for k, v in tries:
        key = k.removeprefix("operating_point.")
        try:
            load_scene(spec.base, {**spec.fixed, key: as_override(v)})
        except ConfigError as exc:
            raise ConfigError(f"{where}: {k} = {as_override(v)}: {exc}") from None
    if spec.search is not None:
        try:
            value = _scene_value(base, spec.search.key)
        except (KeyError, TypeError):
            raise ConfigError(f"{where}: search.key = {shown(spec.search.key)}: not a key of the scene") from None
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(
                f"{where}: search.key = {shown(spec.search.key)}: not a number in the scene ({shown(value)})"
            )
    return base


def _operating_value(spec: SweepSpec, key: str, base: Any) -> Any:
    """The operating point's value of ``key``: the study's ``[operating_point]``, else the base scene's."""
    if key in spec.operating_point:
        return spec.operating_point[key]
    try:
        return _scene_value(base, key)
    except (KeyError, TypeError, AttributeError):
        return None


# ----------------------------------------------------------------------------- the search
def _run_search(
    spec: SweepSpec, base: Any, rows: list[dict[str, Any]], run_round: Callable[[list[dict[str, Any]]], None]
) -> SearchResult:
    """Bisect every estimator's breaking point (per [vary] combination and seed), rendering in rounds.

    ``rows``: every row so far (a restart's included), grown by ``run_round(jobs)``, which
    runs the jobs it is given and appends their rows.
    """
    s, criterion = spec.search, spec.criterion
    assert s is not None and criterion is not None
    grid = search_grid(s.low, s.high, s.tolerance, s.scale, integer=isinstance(_scene_value(base, s.key), int))
    contexts = _combinations(spec.vary)
    pairs = [(c, rep) for c in range(len(contexts)) for rep in range(spec.repetitions)]

    def job(c: int, rep: int, i: int) -> dict[str, Any]:
        return make_job({**contexts[c], s.key: grid[i]}, rep)

    def evaluated(by_job: Mapping[str, list[dict[str, Any]]], c: int, rep: int) -> tuple[dict, int | None]:
        """``({grid index: {estimator: why it fails, or None}}, seed)`` of the values rendered
        so far; a failed job (scene, render) raises FloorbenchError with its status."""
        out: dict[int, dict[str, str | None]] = {}
        seed = None
        for i in range(len(grid)):
            rs = by_job.get(job(c, rep, i)["job"], [])
            for r in rs:
                if not r.get("estimator"):
                    raise FloorbenchError(f"{r['job']}: {r.get('status')}")
            if rs:
                used.add(rs[0]["job"])
                out[i] = {
                    r["estimator"]: criterion.failure(r) for r in rs if not str(r.get("status")).startswith("skipped")
                }
                seed = next((int(r["seed"]) for r in rs if r.get("seed") is not None), seed)
        return out, seed

    def rows_by_job() -> dict[str, list[dict[str, Any]]]:
        by: dict[str, list[dict[str, Any]]] = {}
        for r in rows:
            by.setdefault(str(r.get("job")), []).append(r)
        return by

    def brackets_of(ev: Mapping[int, Mapping[str, str | None]]) -> dict[str, Bracket]:
        names = sorted({e for v in ev.values() for e in v})
        return {
            e: bracket({i: v[e] is not None for i, v in ev.items() if e in v}, len(grid), s.fails_below) for e in names
        }

    used: set[str] = set()
    stopped: dict[tuple[int, int], str] = {}
    while True:
        by_job = rows_by_job()
        wanted: dict[str, dict[str, Any]] = {}
        for c, rep in pairs:
            if (c, rep) in stopped:
                continue
            try:
                ev, _ = evaluated(by_job, c, rep)
            except FloorbenchError as exc:
                stopped[(c, rep)] = str(exc)
                continue
            need = [i for i in (0, len(grid) - 1) if i not in ev]  # round one: both ends at once
            if not need:
                need = [
                    b.next_index for b in brackets_of(ev).values() if b.state == "open" and b.next_index is not None
                ]
            for i in need:
                j = job(c, rep, i)
                wanted[j["job"]] = j
        if not wanted:
            break
        log.info("search %s: rendering %d value(s): %s", s.key, len(wanted), ", ".join(sorted(wanted)))
        before = len(rows)
        run_round(list(wanted.values()))
        if len(rows) == before:  # every job of the round failed (see the errors): no progress possible
            for c, rep in pairs:
                stopped.setdefault((c, rep), "its jobs failed (see the job errors)")
            break

    res = SearchResult(
        s.key,
        scene_key_unit(s.key),
        s.fails,
        s.scale,
        s.tolerance,
        criterion.describe(),
        grid,
        [],
        {},
        len(grid) * spec.repetitions,
        _operating_value(spec, s.key, base),
        confidence=spec.confidence,
        jobs=used,
    )
    by_job = rows_by_job()
    for c, ctx in enumerate(contexts):
        label = res.context_label(ctx)
        per_seed, seeds = [], []
        for rep in range(spec.repetitions):
            if (c, rep) in stopped:
                res.errors.append(f"{label}, repetition {rep}: {stopped[(c, rep)]}")
            try:
                ev, seed = evaluated(by_job, c, rep)
            except FloorbenchError:
                ev, seed = {}, None
            per_seed.append(ev)
            seeds.append(seed)
        res.renders[label] = sum(len(ev) for ev in per_seed)
        per_est: dict[str, list[Bracket]] = {}
        for rep, ev in enumerate(per_seed):
            for e, b in brackets_of(ev).items():
                per_est.setdefault(e, [Bracket("open")] * spec.repetitions)[rep] = b
        for e, brackets in per_est.items():
            reasons = {(i, rep): v[e] for rep, ev in enumerate(per_seed) for i, v in ev.items() if e in v}
            bp = combine_brackets(grid, brackets, s.scale, spec.confidence)
            res.points.append(EstimatorBreakingPoint(dict(ctx), e, bp, tuple(brackets), tuple(seeds), reasons))
    return res


def _write_breaking_points(path: Path, res: SearchResult) -> None:
    """``breaking_points.csv``: one row per context and estimator (the CLI's lines as numbers)."""
    cols = [
        *{k: None for p in res.points for k in p.context},
        "estimator",
        "key",
        "unit",
        "fails",
        "state",
        "breaking_value",
        "interval_low",
        "interval_high",
        "bracket_low",
        "bracket_high",
        "seeds",
        "noisy",
        "margin",
        "renders",
        "grid_renders",
        "seed_brackets",
    ]
    table = []
    for p in res.points:
        bp = p.point
        seed_brackets = " ".join(
            "{:g}-{:g}".format(*sorted((res.grid[b.fail_index], res.grid[b.work_index])))
            if b.state == "found" and b.fail_index is not None and b.work_index is not None
            else b.state
            for b in p.brackets
        )
        row = {
            **p.context,
            "estimator": p.estimator,
            "key": res.key,
            "unit": res.unit,
            "fails": res.fails,
            "state": bp.state,
            "breaking_value": bp.value,
            "interval_low": bp.interval[0],
            "interval_high": bp.interval[1],
            "bracket_low": bp.bracket[0],
            "bracket_high": bp.bracket[1],
            "seeds": bp.seeds,
            "noisy": bp.noisy,
            "margin": res.margin(p),
            "renders": res.renders.get(res.context_label(p.context)),
            "grid_renders": res.grid_renders,
            "seed_brackets": seed_brackets,
        }
        table.append([row.get(c) for c in cols])
    atomic_write_csv(path, cols, table)


# ----------------------------------------------------------------------------- the study
@locks_folder("out_dir", "sweep folder")
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
    """Run a study (sweep) file: its grid, its search, its report (see the module doc).

    ``scheduler``: a Dask scheduler address; ``workers``: start a local Dask cluster of
    that many workers (``processes=False`` makes them threads, for tests); neither: a local
    process pool of ``jobs`` workers. Collaborators of every job (defaults: the real ones,
    as in :func:`floorsim.bench.bench.run_bench`): ``render``, ``load_scene``, ``runner``.
    ``externals``: programs run in every job (:class:`floorvo.external.ExternalEstimator`).

    Locks: this process holds ``out_dir`` (:func:`floorvo.locking.lock_folder`) while the study
    runs, so a second sweep into it is refused in one line naming this process's pid; each
    job, in whatever worker, locks the sequence folder it renders (waiting for another job
    that renders the same one) and each run folder it writes. A worker killed mid-job loses
    its locks with its process, so the job run again elsewhere takes them at once.
    """
    runner = (runner or DEFAULT_RUNNER).with_externals(externals)
    if scheduler is not None and workers is not None:
        raise ConfigError("--scheduler and --workers: give one of them (a cluster to join, or a local one to start)")
    for flag, n in (("--workers", workers), ("--jobs", jobs)):
        problem = None if n is None else local_workers_problem(n)
        if problem:
            raise ConfigError(f"{flag} {n}: {problem}")
    problem = None if scheduler is None else scheduler_problem(scheduler)
    if problem:
        raise ConfigError(f"--scheduler {scheduler!r}: {problem}")
    spec = load_sweep(sweep_path)
    base = _check_study(spec, load_scene, runner)
    if cache_dir is not None:
        cache_dir = check_cache_dir(cache_dir)  # as the bench checks it: every job failed there
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    base_scene = base.to_dict() if base is not None else None
    programs = {x.name: x.source.command_sha256 for x in externals}
    problem = other_results_problem(out_dir, "sweep") or resume_problem(spec, out_dir, base_scene, programs)
    if problem:
        raise ConfigError(problem)
    recorded_before = (out_dir / STUDY_RECORD).exists()
    record = write_study_record(spec, out_dir, base_scene, programs)
    # Absolute paths: a Dask worker runs in another folder (on a cluster: a shared file system).
    cache = str((Path(cache_dir) if cache_dir is not None else out_dir / "sequences").resolve())
    results_csv = out_dir / RESULTS_CSV
    rows = read_results_csv(results_csv)
    done_before = {r.get("job") for r in rows}
    errors: list[str] = []
    counts = {"ran": 0, "finished": 0, "submitted": 0}
    used: set[str] = set()  # every job the study asked for, done before or now

    def collect(job: Mapping[str, Any], result: list[dict[str, Any]] | None, exc: BaseException | None) -> None:
        counts["finished"] += 1
        if exc is not None:
            errors.append(f"{job['job']}: {type(exc).__name__}: {exc}")
            log.error("sweep job %s failed: %s", job["job"], exc, exc_info=exc)
        else:
            rows.extend(result or [])
            write_results_csv(results_csv, rows)
        if on_job:
            on_job(counts["finished"], counts["submitted"])

    args = (spec, str(out_dir.resolve()), cache, render, load_scene, runner)
    search_res: SearchResult | None = None
    with contextlib.ExitStack() as stack:
        pool: Callable[..., None] | None = None

        def run_round(todo: list[dict[str, Any]]) -> None:
            nonlocal pool
            used.update(j["job"] for j in todo)
            have = {r.get("job") for r in rows}
            todo = [j for j in todo if j["job"] not in have]
            if not todo:
                return
            if pool is None:  # workers start on the first job that is not already done
                try:
                    pool = stack.enter_context(job_pool(scheduler, workers, jobs, processes))
                except FloorbenchError:
                    # No workers (a scheduler that does not answer): a study that ran nothing leaves
                    # no record behind (the lock then removes the folder it created, if empty).
                    if not recorded_before and not rows:
                        remove_study_record(out_dir)
                    raise
            counts["ran"] += len(todo)
            counts["submitted"] += len(todo)
            pool(run_sweep_job, todo, args, collect)

        all_jobs = sweep_jobs(spec)  # the grid's, or none for a search; the sequence folders'
        log.info(
            "sweep %s: %d jobs%s, %d already done",
            spec.name,
            len(all_jobs),
            " besides the search" if spec.search is not None else "",
            sum(j["job"] in done_before for j in all_jobs),
        )
        run_round(all_jobs)
        if spec.search is not None:
            search_res = _run_search(spec, base, rows, run_round)
            used.update(search_res.jobs)
    skipped = len(used & done_before)
    res = SweepResult(rows, results_csv, counts["ran"], skipped, errors, search=search_res, record=record)
    if search_res is not None:
        res.breaking_points_csv = out_dir / "breaking_points.csv"
        _write_breaking_points(res.breaking_points_csv, search_res)
    if report and rows:
        res.report_html, res.report_md = plot_sweep(spec, rows, out_dir, base=base, search=search_res)
    return res


def plot_sweep(
    spec: SweepSpec,
    rows: SequenceT[Mapping[str, Any]],
    out_dir: str | os.PathLike,
    load_scene: SceneLoader = load_scene_file,
    base: Any = None,
    search: SearchResult | None = None,
) -> tuple[Path, Path]:
    """Write ``sweep.html`` / ``sweep.md`` (:func:`floorsim.bench.sweep_report.write_sweep_report`);
    the operating points default to the base scene's values (read with ``load_scene``)."""
    if base is None and spec.base is not None:
        try:
            base = load_scene(spec.base, dict(spec.fixed))
        except FloorbenchError:
            base = None
    ops = {k: _operating_value(spec, k, base) for k in [*spec.vary, *([spec.search.key] if spec.search else [])]}
    return write_sweep_report(spec, list(rows), Path(out_dir), ops, search)

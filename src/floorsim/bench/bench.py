"""The bench: render scenes (cached), run estimators, score them, run paper protocols, report, gate.

:func:`run_bench` is the library function behind ``floorsim bench``. It takes scene files and
sequence folders (anything with a ``sequence.json``: a recording made with ``floorvo import``,
a sequence rendered before); a sequence folder is used as it is (no render, no protocols, one
repetition) and gets the same runs, scores, report and gates.

Before anything renders, the inputs are checked, each refusal one line
(:class:`floorvo.errors.ConfigError` and kin): the estimators and their ``--est-set`` configs
(:func:`floorsim.bench.estimators.check_estimator_choice`), every sequence folder
(:func:`check_sequence_folder`), ``--cache`` (:func:`check_cache_dir`), the baseline and the
``--save-baseline`` path, ``--set`` given with sequence folders alone, and an output folder
holding a study's results (:func:`floorsim.bench.results.other_results_problem`); the sweep
uses the same checks. A bench in which no estimator ran on any scene is an error. For each
scene file:

1. load it (``floorsim.scene.load_scene`` with the ``--set`` overrides) and render it
   through :func:`render_cached`, which keys the sequence folder by a hash of the
   resolved scene, the seed, the render settings and the renderer's code
   (:func:`scene_cache_key`), so a sequence already rendered with the same inputs by the
   same code is reused (also across benches sharing a ``cache_dir``);
2. run every requested estimator (default: every registered estimator whose
   ``requires`` the sequence meets: mono estimators on mono sequences; built-ins, installed
   plugins, and every external program given) through the runner
   (:class:`floorsim.bench.estimators.EstimatorRunner`) into ``DIR/runs/SCENE/ESTIMATOR/repK``;
   each row records where the estimator came from (``source``, ``source_detail``: built-in,
   plugin with its version, external with the hash of its command line), its wall time per
   frame and peak memory; a run that fails (an external program that crashed, timed out or
   wrote no trajectory) is a ``failed`` row with the reason (and ``stderr_tail``), and the
   bench goes on;
3. score each run (:func:`floorvo.scoring.score_run`, written to ``RUN/score.json``) and
   append one row to ``DIR/results.csv`` (:mod:`floorsim.bench.results`, atomically
   rewritten after every row).

Repetition ``k`` renders the scene with seed ``scene seed + k``: another realisation of
the same scene (floor texture unless ``floor.seed`` fixes it, sensor noise, sampling).

Paper reproductions are protocol plugins (:mod:`floorsim.bench.protocols`) that a scene
asks for in its ``[bench]`` table (by default: those registered for its trajectory type).
They run after the scene's repetitions (``run_scene``: paper 000's strip runs, paper
001's table) or once after every scene (``run_bench``: paper 003's map and kidnap pair),
and add rows, report sections and notes. Then the report is written
(:mod:`floorsim.bench.report`) and, when asked, the rows are compared with a baseline
(:mod:`floorsim.bench.gates`) or saved as one.

Collaborators come in as parameters with the real ones as defaults (``load_scene``,
``render``, ``runner``: a :class:`floorsim.bench.estimators.EstimatorRunner`), so the bench's own work can be
tested with doubles.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
from collections.abc import Callable, Mapping
from collections.abc import Sequence as SequenceT
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from floorsim import __version__ as floorsim_version
from floorsim.bench.estimators import DEFAULT_RUNNER, EstimatorRunner, check_estimator_choice
from floorsim.bench.gates import Baseline, GateResult, compare, load_baseline, save_baseline
from floorsim.bench.protocols import (
    PROTOCOLS,
    BenchContext,
    BenchProtocol,
    ProtocolOutput,
    SceneRun,
    protocols_for_scene,
)
from floorsim.bench.report import Report, RunRecord, build_bench_report
from floorsim.bench.results import RESULTS_CSV, other_results_problem, write_results_csv
from floorsim.scene import load_scene as load_scene_file
from floorsim.simulate import render_code_sha256, render_sequence
from floorvo.calibration import ScaleCalibration, load_scale_calibration
from floorvo.errors import ConfigError, ExternalEstimatorError, FloorbenchError, SequenceError, shorten
from floorvo.external import ExternalEstimator
from floorvo.io import atomic_write_json, checked_output_file, checked_output_path, json_sha256, read_json
from floorvo.locking import lock_folder, locks_folder
from floorvo.run import InitialPose, estimator_faults
from floorvo.runfolder import BENCH_CACHE_MARKER as CACHE_MARKER
from floorvo.runfolder import sequence_content_sha256, write_match_sample
from floorvo.runner import run_sequence
from floorvo.scoring import score_run, write_score
from floorvo.sequence import Sequence

log = logging.getLogger(__name__)

__all__ = [
    "BenchResult",
    "check_cache_dir",
    "check_sequence_folder",
    "is_sequence_folder",
    "render_cached",
    "run_bench",
    "run_one",
    "scene_cache_key",
    "sequence_content_sha256",
    "run_inputs",
    "scene_seed",
    "MAX_REPETITIONS",
    "source_columns",
    "supported_estimators",
    "write_match_samples",
]

#: ``render(scene, out_dir, *, frames, scale, spp, seed, on_frame) -> sequence folder``
#: (the signature of :func:`floorsim.simulate.render_sequence`).
RenderFn = Callable[..., Path]
#: ``load_scene(path, overrides) -> scene`` (:func:`floorsim.scene.load_scene`).
SceneLoader = Callable[..., Any]


# ----------------------------------------------------------------------------- rendering with a cache
#: The most repetitions (renders of a scene, seeds scene seed + k) a bench or a study asks for:
#: ``--repeat 1000000000`` started on a billion renders.
MAX_REPETITIONS = 1000


def scene_seed(scene: Any) -> int:
    """The scene's seed (``scene.seed``, else ``seed`` of its dict, else 0)."""
    seed = getattr(scene, "seed", None)
    if seed is None:
        seed = scene.to_dict().get("seed", 0)
    return int(seed)


def scene_cache_key(
    resolved_scene: Mapping[str, Any], *, seed: int, frames: int | None, scale: float | None, spp: int | None
) -> str:
    """Hex SHA-256 of the resolved scene and everything else that changes the rendered sequence:
    the seed, the render settings and the renderer's code (:func:`floorsim.simulate.render_code_sha256`,
    with the scene's floor material: a plugin material's module too), so a sequence rendered by
    other code is rendered again, not reused (the package's version number stays the same through
    edits).

    The scene's ``bench`` table (which protocols run on it) does not change the render and
    is left out.
    """
    material = (resolved_scene.get("floor") or {}).get("material")
    payload = {
        **render_inputs(resolved_scene, seed=seed, frames=frames, scale=scale, spp=spp),
        "floorsim": floorsim_version,
        "render_code": render_code_sha256(material if isinstance(material, str) else None),
    }
    text = json.dumps(payload, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def render_inputs(
    resolved_scene: Mapping[str, Any], *, seed: int, frames: int | None, scale: float | None, spp: int | None
) -> dict[str, Any]:
    """What a rendered sequence is a function of besides code (the part of :func:`scene_cache_key`
    a baseline compares: :func:`floorsim.bench.gates.made_with`): the resolved scene without its
    ``bench`` table, the seed and the render settings."""
    return {
        "scene": {k: v for k, v in resolved_scene.items() if k != "bench"},
        "seed": seed,
        "frames": frames,
        "scale": scale,
        "spp": spp,
    }


def render_cached(
    scene: Any,
    cache_dir: str | os.PathLike,
    *,
    seed: int | None = None,
    frames: int | None = None,
    scale: float | None = None,
    spp: int | None = None,
    on_frame: Callable[[int, int], None] | None = None,
    render: RenderFn | None = None,
) -> Path:
    """Render ``scene`` into ``cache_dir/NAME-HASH`` unless an identical render is there already.

    The folder gets a ``bench-cache.json`` marker (the key) once the render finished; a
    folder without it (an interrupted render) is resumed by the renderer. ``render``:
    the renderer (default :func:`floorsim.simulate.render_sequence`).

    The cache may be shared (benches with one ``--cache-dir``, the jobs of a sweep): the
    folder is locked while it is checked and rendered, and a second process that wants the
    same sequence waits for the first's render and then reuses it.
    """
    render = render_sequence if render is None else render
    seed = scene_seed(scene) if seed is None else int(seed)
    key = scene_cache_key(scene.to_dict(), seed=seed, frames=frames, scale=scale, spp=spp)
    out = Path(cache_dir) / f"{scene.name}-{key[:12]}"
    with lock_folder(out, "sequence folder", wait=True):
        return _render_into_cache(scene, out, key, seed, frames, scale, spp, on_frame, render)


def _render_into_cache(
    scene: Any,
    out: Path,
    key: str,
    seed: int,
    frames: int | None,
    scale: float | None,
    spp: int | None,
    on_frame: Callable[[int, int], None] | None,
    render: RenderFn,
) -> Path:
    marker = out / CACHE_MARKER
    if marker.is_file():
        try:
            mark = read_json(marker, SequenceError)
        except SequenceError:  # a damaged marker: render again
            mark = None
        if isinstance(mark, dict) and mark.get("key") == key:
            log.info("scene %s: reusing the sequence rendered in %s", scene.name, out)
            return out
    log.info("scene %s: rendering into %s", scene.name, out)
    render(scene, out, frames=frames, scale=scale, spp=spp, seed=seed, on_frame=on_frame)
    material = (scene.to_dict().get("floor") or {}).get("material")
    atomic_write_json(
        marker,
        {
            "key": key,
            "scene": scene.name,
            "seed": seed,
            "frames": frames,
            "scale": scale,
            "spp": spp,
            "render_code": render_code_sha256(material if isinstance(material, str) else None),
        },
    )
    return out


def run_inputs(render: Mapping[str, Any] | str) -> str:
    """A run's ``inputs`` column (16 hex digits): what the sequence it ran on is a function of besides
    code (``render``: :func:`render_inputs` of a rendered one: the scene as resolved with ``--set``,
    the seed, ``--frames/--scale/--spp``; or :func:`sequence_content_sha256` of a sequence folder).
    A baseline records them (:func:`floorsim.bench.gates.made_with`) and a gate refuses to compare
    runs on other sequences; the estimator's config (``est_config``) and scale calibration are what
    a gate may measure a change of, and are not part of it."""
    return json_sha256({"sequence": render})[:16]


def check_cache_dir(cache_dir: str | os.PathLike) -> Path:
    """Refuse, before any render, a ``--cache`` that cannot hold sequence folders (a file, a path
    under a file, ``""``, ``/``): the bench's first render, and every job of a study, failed there.
    The one check of ``floorsim bench --cache`` and ``floorsim sweep --cache``."""
    path = Path(cache_dir)
    if path.exists() and not path.is_dir():
        raise ConfigError(f"--cache {path}: is a file, not a folder (of rendered sequences)")
    try:
        return checked_output_path(path, ConfigError)
    except ConfigError as exc:
        raise ConfigError(f"--cache {exc}") from None


def check_sequence_folder(path: str | os.PathLike) -> None:
    """Refuse, before any render or run, a sequence folder the runs cannot read (what
    :meth:`floorvo.sequence.Sequence.open` refuses: a ``sequence.json`` of an unknown schema
    version, bad timestamps; and its ground truth, :meth:`~floorvo.sequence.Sequence.groundtruth`:
    a rendered sequence's cut short), and one of fewer than 2 frames (no step to estimate: every
    run was an 'ok' row that "tracked" nothing, as a render of --frames 1 is refused): the one
    check of the bench's sequence folders and a study's."""
    seq = Sequence.open(path)
    if seq.frame_count < 2:
        raise ConfigError(
            f"{seq.root}: holds {seq.frame_count} frame(s): a bench needs at least 2 (a step to estimate)"
        )
    seq.groundtruth()


def is_sequence_folder(path: str | os.PathLike) -> bool:
    """True for a folder holding ``sequence.json`` (benched as it is, not rendered)."""
    return Path(path).is_dir() and (Path(path) / "sequence.json").is_file()


# ----------------------------------------------------------------------------- estimators
def supported_estimators(
    seq_dir: str | os.PathLike, names: SequenceT[str] | None = None, runner: EstimatorRunner | None = None
) -> tuple[list[str], dict[str, str]]:
    """Split estimator ``names`` (default: all registered) into those the sequence supports
    and ``{name: reason}`` for the others (e.g. ``needs depth``, or a plugin that is unavailable).

    A named estimator is kept unless the sequence lacks what it needs, so that one that cannot
    run fails visibly in its row."""
    runner = runner or DEFAULT_RUNNER
    seq = Sequence.open(seq_dir)
    have = set()
    if seq.has_depth:
        have.add("depth")
    if seq.has_stereo:
        have.add("stereo")
    ok, skipped = [], {}
    for n in names if names is not None else runner.names():
        try:
            missing = runner.requires(n) - have
        except FloorbenchError as exc:
            if names is None:
                skipped[n] = str(exc)
                continue
            missing = set()
        if missing:
            skipped[n] = "needs " + " and ".join(sorted(missing))
            continue
        if names is None:
            # Default selection: leave out estimators that cannot run with their default
            # configuration (e.g. one that needs a prebuilt map); named ones fail visibly.
            try:
                runner.check(seq, n)
            except FloorbenchError as exc:
                skipped[n] = f"not runnable with its default configuration: {exc}"
                continue
            except ImportError:  # an optional dependency is missing: the run says so in its row
                pass
        ok.append(n)
    return ok, skipped


# ----------------------------------------------------------------------------- the bench
@dataclass
class BenchResult:
    """What :func:`run_bench` did: rows of results.csv, where things are, the gate verdict."""

    rows: list[dict[str, Any]]
    records: list[RunRecord]
    results_csv: Path
    report_html: Path | None = None
    report_md: Path | None = None
    gate: GateResult | None = None
    baseline_saved: Path | None = None
    notes: list[str] = field(default_factory=list)


def source_columns(runner: EstimatorRunner, name: str) -> dict[str, str]:
    """``source`` and ``source_detail`` of estimator ``name`` for its row (none for a plugin that
    cannot be loaded: its run fails and says why)."""
    try:
        return runner.source(name).row()
    except FloorbenchError:
        return {}


@locks_folder("run_dir", "run folder")
def run_one(
    seq_dir: Path,
    estimator: str,
    run_dir: Path,
    overrides: Mapping[str, str] | None = None,
    scale_calibration: ScaleCalibration | None = None,
    runner: EstimatorRunner | None = None,
    T_world_start: np.ndarray | None = None,
) -> dict[str, Any]:
    """Run one estimator on one sequence and score it; returns the metric part of a row: the
    runner's figures (wall ms per frame, peak memory) and the score's metrics.

    ``scale_calibration``: a :class:`floorvo.calibration.ScaleCalibration` divided out of
    every step (``floorvo run --scale-calibration``), or None. ``T_world_start`` (4, 4) mm:
    where a run on a sequence without ground truth starts (``--initial-pose``). ``run_dir`` is
    locked while it is run and scored (:func:`floorvo.locking.lock_folder`).
    """
    kwargs = {} if T_world_start is None else {"T_world_start": T_world_start}
    figures = (runner or DEFAULT_RUNNER).run(seq_dir, estimator, run_dir, overrides, scale_calibration, **kwargs)
    score = score_run(run_dir, seq_dir)
    write_score(score, run_dir / "score.json")
    row: dict[str, Any] = {**dict(figures or {}), **score.flat(), "ground_truth": score.ground_truth}
    reasons = score.tracking.get("lost_reasons") or {}
    if reasons:  # the lost steps counted per kind of reason (floorvo.metrics.lost_reasons)
        row["lost_reasons"] = "; ".join(f"{kind}: {n}" for kind, n in reasons.items())
    # What the run said of its scale calibration (result.json: fitted on this sequence, or on a run
    # of another config) goes with the score's warnings: it had stayed in result.json, and the table
    # showed a calibrated drift tuned on the very sequence it scored.
    notes = list(score.warnings) + list(score.extra.get("result", {}).get("scale_calibration_problems") or [])
    if notes:
        row["score_warnings"] = "; ".join(str(n) for n in notes)
    return row


@locks_folder("run_dir", "run folder")
def write_match_samples(
    seq_dir: Path,
    estimator: str,
    run_dir: Path,
    overrides: Mapping[str, str] | None = None,
    count: int = 3,
    runner: EstimatorRunner | None = None,
) -> int:
    """Save the matched keypoints of ``count`` frame pairs as ``RUN/matches/NNNNNN.npz`` for the report.

    Runs the estimator afresh on each pair (previous, current) through
    :func:`floorvo.runner.run_sequence` and keeps the current frame's
    ``StepResult.matches_px`` ((N, 4): u_prev, v_prev, u_cur, v_cur), written by
    :func:`floorvo.runfolder.write_match_sample`. Returns how many pairs had matches (0 when
    the estimator does not expose them). The samples illustrate a run that is already scored:
    where a plugin's estimator fails on them (it raises on a pair its run did not start on, or
    gives ``matches_px`` of another shape) that is logged as a warning and the samples end
    there, where it had ended the whole bench with a traceback.
    """
    seq = Sequence.open(seq_dir)
    if seq.frame_count < 2:
        return 0
    est, _ = (runner or DEFAULT_RUNNER).build(seq, estimator, overrides)
    picks = sorted({int(i) for i in np.linspace(1, seq.frame_count - 1, min(count, seq.frame_count - 1)).round()})
    last: dict[str, Any] = {}

    def keep(k: int, frame: Any, res: Any) -> None:
        last["step"] = res

    written = 0
    for i in picks:
        try:
            with estimator_faults(estimator, f"the match sample of frames {i - 1}-{i}"):
                # the run it illustrates has said what it lost (a "1 step(s) lost" per pair contradicted it)
                run_sequence(seq, est, frames=[i - 1, i], on_step=keep, summary_warnings=False)
                m = last["step"].matches_px
                if m is None or len(m) == 0:
                    continue
                m = np.asarray(m, dtype=float)
                if m.ndim != 2 or m.shape[1] != 4:
                    raise FloorbenchError(
                        f"estimator {estimator!r}: frame {i}: matches_px has shape {m.shape}, not (N, 4) "
                        "(u_prev, v_prev, u_cur, v_cur px)"
                    )
        except FloorbenchError as exc:
            log.warning("%s on %s: no more match samples for the report: %s", estimator, seq_dir, exc)
            break
        write_match_sample(run_dir, i, m)
        written += 1
    return written


def _kept_tolerances(path: str | os.PathLike, compared: Baseline | None) -> dict[str, dict[str, float]] | None:
    """The tolerances a new baseline saved to ``path`` keeps: those of the baseline file already
    there (a refresh kept none of its edited tolerances), else those of the baseline the bench was
    compared with, else None (the defaults)."""
    source = compared
    if Path(path).is_file():
        try:
            source = load_baseline(path)
        except ConfigError:
            pass  # not a baseline: the defaults, or the compared one's
    if source is None:
        return None
    return {m: {"abs": t.abs, "rel": t.rel} for m, t in source.tolerances.items()}


def _notes_section(notes: list[str], rep: Report) -> None:
    rep.heading("Notes")
    for text in notes:
        rep.text(text)


def _load_scales(
    scale_calibrations: Mapping[str, str | os.PathLike] | None,
    estimators: SequenceT[str] | None,
    known: SequenceT[str],
) -> dict[str, tuple[str, ScaleCalibration]]:
    """``{estimator: (file, ScaleCalibration)}``; refuses an unknown or unselected estimator by name."""
    cals = {}
    for n, f in (scale_calibrations or {}).items():
        if n not in known and ":" not in n:  # a module:Class reference is taken as --estimators takes it
            raise ConfigError(f"--scale-calibration {n}={f}: unknown estimator (known: {', '.join(sorted(known))})")
        if estimators is not None and n not in estimators:
            raise ConfigError(
                f"--scale-calibration {n}={f}: estimator {n!r} is not among --estimators ({', '.join(estimators)})"
            )
        cals[n] = (str(f), load_scale_calibration(f, n))
    return cals


def _scene_protocols(path: Path, scene: Any) -> list[BenchProtocol]:
    try:
        return protocols_for_scene(scene)
    except ConfigError as exc:
        raise ConfigError(f"{path.name}: {exc}") from None


@locks_folder("out_dir", "bench folder")
def run_bench(
    scene_paths: SequenceT[str | os.PathLike],
    estimators: SequenceT[str] | None,
    out_dir: str | os.PathLike,
    *,
    repetitions: int = 1,
    scene_overrides: Mapping[str, str] | None = None,
    estimator_overrides: Mapping[str, Mapping[str, str]] | None = None,
    frames: int | None = None,
    scale: float | None = None,
    spp: int | None = None,
    cache_dir: str | os.PathLike | None = None,
    baseline: str | os.PathLike | None = None,
    save_baseline_to: str | os.PathLike | None = None,
    allow_new: bool = False,
    report: bool = True,
    paper000_runs: int | None = None,
    on_frame: Callable[[str, int, int], None] | None = None,
    scale_calibrations: Mapping[str, str | os.PathLike] | None = None,
    externals: SequenceT[ExternalEstimator] = (),
    initial_pose: InitialPose | None = None,
    render: RenderFn | None = None,
    load_scene: SceneLoader = load_scene_file,
    runner: EstimatorRunner | None = None,
) -> BenchResult:
    """Render, run, score, run the scenes' protocols, report and gate (see the module doc).

    ``scene_paths``: scene files and sequence folders (:func:`is_sequence_folder`).
    ``estimators``: names (built-ins, plugins, ``module:Class`` references), or None for
    every registered estimator each sequence supports; the ``externals`` (programs,
    :class:`floorvo.external.ExternalEstimator`) run on every sequence in either case.
    ``allow_new``: a scene/estimator without a ``baseline`` entry does not fail the gate.
    ``paper000_runs`` limits the number of runs per paper-000 model (None: all of them).
    ``on_frame(scene_name, done, n)`` reports render progress (frames done of n).
    ``scale_calibrations``: ``{estimator: calibration file}`` (``floorvo calibrate``); that
    estimator's runs, the paper-000 protocol's included, divide the rig's scale out of
    every step, and each row names the file in ``scale_calibration``.
    ``initial_pose``: where runs on a sequence without ground truth start (default: the
    identity); runs on a sequence with ground truth start at its first pose.
    Collaborators (defaults: the real ones): ``render`` (same signature as
    :func:`floorsim.simulate.render_sequence`), ``load_scene`` (as
    :func:`floorsim.scene.load_scene`), ``runner`` (:class:`EstimatorRunner`).

    ``out_dir`` is locked while the bench runs (:func:`floorvo.locking.lock_folder`: a second
    bench into it is refused in one line naming this process's pid), and so is each
    sequence and run folder while it is written.
    """
    runner = (runner or DEFAULT_RUNNER).with_externals(externals)
    if not 1 <= repetitions <= MAX_REPETITIONS:
        raise ConfigError(f"--repeat {repetitions}: must be from 1 to {MAX_REPETITIONS} (renders per scene)")
    if paper000_runs is not None and paper000_runs < 1:  # -1 failed after the renders, 0 wrote empty tables
        raise ConfigError(
            f"--paper000-runs {paper000_runs}: must be >= 1 (runs per model of the paper000-strip protocol)"
        )
    if frames is not None and frames < 2:  # one frame: no step to estimate, every row 'ok' and empty
        raise ConfigError(f"--frames {frames}: a bench needs at least 2 frames (a step to estimate)")
    if not scene_paths:
        raise ConfigError("bench: give at least one scene file or sequence folder")
    given: set[Path] = set()
    for p in scene_paths:  # the same file twice ran twice, as SCENE and SCENE-2, rows counted twice in the report
        if Path(p).resolve() in given:
            raise ConfigError(
                f"bench: {shorten(str(p))} is given twice (as an argument or in a suite); give each scene file or "
                "sequence folder once (--repeat N renders a scene N times with other seeds)"
            )
        given.add(Path(p).resolve())
    out_dir = Path(out_dir)
    problem = other_results_problem(out_dir, "bench")
    if problem:
        raise ConfigError(problem)
    cache_dir = check_cache_dir(cache_dir) if cache_dir is not None else out_dir / "sequences"
    est_over = {k: dict(v) for k, v in (estimator_overrides or {}).items()}
    known = runner.names()
    check_estimator_choice(runner, estimators, est_over)  # what a study checks of its estimators too
    estimators_chosen = estimators is not None
    if estimators is not None:
        estimators = list(estimators) + [n for n in runner.externals if n not in estimators]
    cals = _load_scales(scale_calibrations, estimators, known)
    baseline_data = load_baseline(baseline) if baseline is not None else None
    if save_baseline_to is not None:  # found out only after the whole bench had run
        try:
            checked_output_file(save_baseline_to, ConfigError)
        except ConfigError as exc:
            raise ConfigError(f"--save-baseline {exc}") from None
    scenes: list[tuple[Path, Any, list[BenchProtocol]]] = []
    notes: list[str] = []
    folders_given = [Path(p) for p in scene_paths if is_sequence_folder(p)]
    # What only a render uses: a sequence folder is run as recorded, and these were silently ignored.
    render_flags = [
        f"{flag} {value}"
        for flag, value in (("--frames", frames), ("--scale", scale), ("--spp", spp))
        if value is not None
    ]
    if scene_overrides:
        render_flags.insert(0, "--set " + " ".join(f"{k}={v}" for k, v in scene_overrides.items()))
    if render_flags and folders_given:
        sets = ", ".join(render_flags)
        folders = ", ".join(shorten(str(p)) for p in folders_given)
        if len(folders_given) == len(scene_paths):
            raise ConfigError(
                f"{shorten(sets)}: {'sets' if len(render_flags) == 1 else 'set'} how scene files are rendered, and "
                f"{folders} {'is a sequence folder' if len(folders_given) == 1 else 'are sequence folders'} (run as "
                "recorded, not rendered); leave them out"
            )
        notes.append(f"{shorten(sets)}: applies to the scene files only, not to the sequence folder(s) {folders}")
        log.warning("%s", notes[-1])
    for p in scene_paths:
        if is_sequence_folder(p):
            check_sequence_folder(p)  # before any scene renders
            scenes.append((Path(p), None, []))
            continue
        scene = load_scene(p, dict(scene_overrides or {}))
        scenes.append((Path(p), scene, _scene_protocols(Path(p), scene)))
    ctx = BenchContext(
        out_dir,
        est_over,
        {n: c for n, (_, c) in cals.items()},
        {"paper000-strip": {"max_runs": paper000_runs}},
        runner,
    )

    names_seen: dict[str, int] = {}
    rows: list[dict[str, Any]] = []
    records: list[RunRecord] = []
    sections: list[Callable[[Report], None]] = []
    results_csv = out_dir / RESULTS_CSV

    def add(out: ProtocolOutput) -> None:
        rows.extend(out.rows)
        records.extend(out.records)
        sections.extend(out.sections)
        notes.extend(out.notes)
        if out.rows:
            write_results_csv(results_csv, rows)

    scene_runs: list[tuple[SceneRun, list[BenchProtocol]]] = []
    skips: list[str] = []  # "SCENE: ESTIMATOR why" of each estimator skipped on a scene
    for path, scene, protocols in scenes:
        recorded = scene is None
        label = path.resolve().name if recorded else scene.name
        names_seen[label] = names_seen.get(label, 0) + 1
        if names_seen[label] > 1:
            label = f"{label}-{names_seen[label]}"
        cb = (lambda i, n, _s=label: on_frame(_s, i, n)) if on_frame else None
        first: SceneRun | None = None
        if recorded and repetitions > 1:
            notes.append(f"{label}: a sequence folder is run once (--repeat renders a scene again with other seeds)")
        for rep in range(1 if recorded else repetitions):
            if recorded:
                seq_dir, seed = path, None
            else:
                seed = scene_seed(scene) + rep
                seq_dir = render_cached(
                    scene, cache_dir, seed=seed, frames=frames, scale=scale, spp=spp, on_frame=cb, render=render
                )
            names, skipped = supported_estimators(seq_dir, estimators, runner)
            start = _start_pose(seq_dir, initial_pose)
            sequence_id: Mapping[str, Any] | str = (
                sequence_content_sha256(seq_dir)
                if recorded
                else render_inputs(scene.to_dict(), seed=scene_seed(scene) + rep, frames=frames, scale=scale, spp=spp)
            )
            if first is None:
                first = SceneRun(label, path, scene, seq_dir, seed, names, [])
                for n, why in skipped.items():
                    skips.append(f"{label}: {n} {why}")
                    notes.append(f"{label}: {n} skipped ({why})")
            for name in names:
                run_dir = out_dir / "runs" / label / name / f"rep{rep}"
                row: dict[str, Any] = {
                    "scene": label,
                    "scene_file": str(path),
                    "estimator": name,
                    "repetition": rep,
                    "seed": seed,
                    "sequence": str(seq_dir),
                    "run_dir": str(run_dir),
                }
                row.update(source_columns(runner, name))
                if name in cals:
                    row["scale_calibration"] = cals[name][0]
                row["est_config"] = json.dumps(est_over.get(name) or {}, sort_keys=True) if est_over.get(name) else ""
                row["inputs"] = run_inputs(sequence_id)
                try:
                    metrics = run_one(
                        seq_dir,
                        name,
                        run_dir,
                        est_over.get(name),
                        cals[name][1] if name in cals else None,
                        runner,
                        T_world_start=start,
                    )
                    row["status"] = "ok"
                    row.update(metrics)
                    if report and rep == 0 and not runner.is_external(name):
                        write_match_samples(seq_dir, name, run_dir, est_over.get(name), runner=runner)
                except ExternalEstimatorError as exc:
                    row["status"] = f"failed: {exc.reason}"
                    row["stderr_tail"] = exc.stderr_tail
                    log.warning("scene %s, estimator %s: %s", label, name, exc)
                except FloorbenchError as exc:
                    row["status"] = f"failed: {exc}"
                    log.warning("scene %s, estimator %s: %s", label, name, exc)
                for protocol in protocols:
                    row.update(protocol.row_columns(first))
                rows.append(row)
                first.rows.append(row)
                if row["status"] == "ok":  # a failed run's folder may hold an earlier run's files: not drawn
                    records.append(RunRecord(label, name, rep, seq_dir, run_dir))
                write_results_csv(results_csv, rows)
        assert first is not None  # repetitions >= 1
        for protocol in protocols:
            add(protocol.run_scene(ctx, first))
        scene_runs.append((first, protocols))
    for protocol in PROTOCOLS.values():
        asking = [sr for sr, ps in scene_runs if protocol in ps]
        if asking:
            add(protocol.run_bench(ctx, asking))

    if not rows:  # it exited 0 and named a results.csv it never wrote
        why = f"every estimator was skipped ({'; '.join(skips)})" if skips else "no estimator to run"
        raise FloorbenchError(f"bench: no estimator ran on any scene: {why}; nothing to score")
    for skip in skips:  # once something ran (else the error above names them, in its one line)
        log.warning("estimator skipped: %s", skip)
    res = BenchResult(rows, records, results_csv, notes=notes)
    gate_text = None
    if baseline_data is not None:
        res.gate = compare(rows, baseline_data, allow_new=allow_new, estimators_chosen=estimators_chosen)
        gate_text = res.gate.summary()
    if save_baseline_to is not None:
        if (
            res.gate is not None
            and not res.gate.ok
            and baseline is not None
            and Path(save_baseline_to).resolve() == Path(baseline).resolve()
        ):
            # the baseline it failed against, overwritten with the regressed numbers: the same
            # command then passed
            log.warning("--save-baseline %s: not saved, the gate against it failed", save_baseline_to)
            notes.append(f"--save-baseline {save_baseline_to}: not saved, the gate against it failed")
        else:
            saved = save_baseline(save_baseline_to, rows, _kept_tolerances(save_baseline_to, baseline_data))
            res.baseline_saved = Path(save_baseline_to)
            for key, entry in saved["entries"].items():
                if all(v is None for v in entry.values()):
                    log.warning(
                        "--save-baseline %s: %s has no value (its runs failed or lost every frame): a gate "
                        "will count it as having no baseline entry",
                        save_baseline_to,
                        key,
                    )
    if report:
        if notes:
            sections.insert(0, partial(_notes_section, list(notes)))
        res.report_html, res.report_md = build_bench_report(
            out_dir, rows, records, gate_summary=gate_text, extra_sections=sections
        )
    return res


def _start_pose(seq_dir: Path, initial_pose: InitialPose | None) -> np.ndarray | None:
    """``initial_pose`` at the sequence's camera height for a sequence without ground truth, else None
    (a run then starts at the first ground-truth pose, or at the identity)."""
    if initial_pose is None:
        return None
    seq = Sequence.open(seq_dir)
    if seq.groundtruth() is not None:
        return None
    return initial_pose.T_world_cam(seq.height_mm)

"""The bench: render scenes (cached), run estimators, score them, report, gate.

:func:`run_bench` is the library function behind ``floorsim bench``. For each scene file:

1. load it (``floorsim.scene.load_scene`` with the ``--set`` overrides) and render it
   through :func:`render_cached`, which keys the sequence folder by a hash of the
   resolved scene, the seed and the render settings, so a sequence already rendered with
   the same inputs is reused (also across benches sharing a ``cache_dir``);
2. run every requested estimator (default: every registered estimator whose
   ``requires`` the sequence meets: mono estimators on mono sequences) through
   ``floorvo.run.run_estimator`` into ``DIR/runs/SCENE/ESTIMATOR/repK``;
3. score each run (:func:`floorvo.metrics.score_run`, written to ``RUN/score.json``) and
   append one row to ``DIR/results.csv`` (atomically rewritten after every row).

Repetition ``k`` renders the scene with seed ``scene seed + k``: another realisation of
the same scene (floor texture unless ``floor.seed`` fixes it, sensor noise, sampling). Then the report is written
(:mod:`floorsim.bench.report`) and, when asked, the rows are compared with a baseline
(:mod:`floorsim.bench.gates`) or saved as one.

Paper reproductions: a scene whose trajectory is the paper-000 ``strip`` also runs that
paper's protocol (:mod:`floorsim.bench.paper000`); a scene named ``paper001*`` is
compared with paper 001's 0.783 % error over its 3 m line; a ``kidnap`` scene is localised
against the keyframe map built from a ``lawnmower`` scene over the same floor in the same
bench (:mod:`floorsim.bench.paper003`), as rows ``relocalise`` and ``map-fused``.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import logging
import math
import os
from collections.abc import Callable, Mapping
from collections.abc import Sequence as SequenceT
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from floorsim.bench.gates import GateResult, compare, load_baseline, save_baseline
from floorsim.bench.report import RunRecord, build_bench_report
from floorvo.errors import ConfigError, FloorbenchError
from floorvo.io import atomic_write_json, atomic_write_text

log = logging.getLogger(__name__)

__all__ = [
    "BenchResult",
    "PAPER001_ERROR_PCT",
    "render_cached",
    "scene_cache_key",
    "supported_estimators",
    "write_results_csv",
    "read_results_csv",
    "run_bench",
]

#: Paper 001's reported error over its 3 m straight line (abstract and Sec. 4).
PAPER001_ERROR_PCT = 0.783
#: Leading columns of results.csv; metric columns follow.
ID_COLUMNS = ["scene", "scene_file", "estimator", "repetition", "seed", "status", "sequence", "run_dir"]

RenderFn = Callable[..., Path]


# ----------------------------------------------------------------------------- rendering with a cache
def _scene_seed(scene) -> int:
    seed = getattr(scene, "seed", None)
    if seed is None:
        seed = scene.to_dict().get("seed", 0)
    return int(seed)


def scene_cache_key(
    resolved_scene: Mapping[str, Any], *, seed: int, frames: int | None, scale: float | None, spp: int | None
) -> str:
    """Hex SHA-256 of the resolved scene and everything else that changes the rendered sequence."""
    from floorsim import __version__

    payload = {
        "scene": resolved_scene,
        "seed": seed,
        "frames": frames,
        "scale": scale,
        "spp": spp,
        "floorsim": __version__,
    }
    text = json.dumps(payload, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def render_cached(
    scene,
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
    folder without it (an interrupted render) is resumed by the renderer.
    """
    if render is None:
        from floorsim.simulate import render_sequence as render
    seed = _scene_seed(scene) if seed is None else int(seed)
    key = scene_cache_key(scene.to_dict(), seed=seed, frames=frames, scale=scale, spp=spp)
    out = Path(cache_dir) / f"{scene.name}-{key[:12]}"
    marker = out / "bench-cache.json"
    if marker.is_file():
        try:
            if json.loads(marker.read_text()).get("key") == key:
                log.info("scene %s: reusing the sequence rendered in %s", scene.name, out)
                return out
        except json.JSONDecodeError:
            pass
    log.info("scene %s: rendering into %s", scene.name, out)
    render(scene, out, frames=frames, scale=scale, spp=spp, seed=seed, on_frame=on_frame)
    atomic_write_json(
        marker, {"key": key, "scene": scene.name, "seed": seed, "frames": frames, "scale": scale, "spp": spp}
    )
    return out


# ----------------------------------------------------------------------------- estimators
def _registry_names() -> list[str]:
    from floorvo.estimators import list_estimators

    names = list_estimators()
    return [n if isinstance(n, str) else n.name for n in names]


def _requires(name: str) -> set[str]:
    from floorvo.estimators import get_estimator

    return set(getattr(get_estimator(name), "requires", set()) or set())


def supported_estimators(
    seq_dir: str | os.PathLike, names: SequenceT[str] | None = None
) -> tuple[list[str], dict[str, str]]:
    """Split estimator ``names`` (default: all registered) into those the sequence supports
    and ``{name: reason}`` for the others (e.g. ``needs depth``)."""
    from floorvo.sequence import Sequence

    seq = Sequence.open(seq_dir)
    have = set()
    if seq.has_depth:
        have.add("depth")
    if seq.has_stereo:
        have.add("stereo")
    ok, skipped = [], {}
    for n in names if names is not None else _registry_names():
        missing = _requires(n) - have
        if missing:
            skipped[n] = "needs " + " and ".join(sorted(missing))
            continue
        if names is None:
            # Default selection: leave out estimators that cannot run with their default
            # configuration (e.g. one that needs a prebuilt map); named ones fail visibly.
            try:
                from floorvo.run import build_estimator

                build_estimator(seq, n)
            except FloorbenchError as exc:
                skipped[n] = f"not runnable with its default configuration: {exc}"
                continue
            except ImportError:
                pass
        ok.append(n)
    return ok, skipped


# ----------------------------------------------------------------------------- results.csv
def _columns(rows: SequenceT[Mapping[str, Any]], first: SequenceT[str] = ID_COLUMNS) -> list[str]:
    cols = list(first)
    for r in rows:
        for k in r:
            if k not in cols:
                cols.append(k)
    return cols


def _cell(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return "nan" if not math.isfinite(v) else repr(v)
    return str(v)


def write_results_csv(
    path: str | os.PathLike, rows: SequenceT[Mapping[str, Any]], first_columns: SequenceT[str] = ID_COLUMNS
) -> None:
    """Write rows (dicts) as CSV atomically; columns: ``first_columns``, then every other key seen."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    cols = _columns(rows, first_columns)
    w.writerow(cols)
    for r in rows:
        w.writerow([_cell(r.get(c)) for c in cols])
    atomic_write_text(path, buf.getvalue())


def read_results_csv(path: str | os.PathLike) -> list[dict[str, Any]]:
    """Rows of a results.csv; numeric cells become floats (empty cells None)."""
    path = Path(path)
    if not path.is_file():
        return []
    out = []
    with path.open(newline="") as fh:
        for r in csv.DictReader(fh):
            d: dict[str, Any] = {}
            for k, v in r.items():
                if k in ("scene", "scene_file", "estimator", "status", "sequence", "run_dir", "job"):
                    d[k] = v
                elif v == "":
                    d[k] = None
                else:
                    try:
                        d[k] = float(v)
                    except ValueError:
                        d[k] = v
            if d.get("repetition") is not None:
                d["repetition"] = int(d["repetition"])
            out.append(d)
    return out


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


def run_one(
    seq_dir: Path, estimator: str, run_dir: Path, overrides: Mapping[str, str] | None = None, scale_calibration=None
) -> dict[str, Any]:
    """Run one estimator on one sequence and score it; returns the metric part of a row.

    ``scale_calibration``: a :class:`floorvo.calibration.ScaleCalibration` divided out of
    every step (``floorvo run --scale-calibration``), or None.
    """
    from floorvo.metrics import score_run
    from floorvo.run import run_estimator

    run_estimator(seq_dir, estimator, run_dir, overrides=dict(overrides or {}), scale_calibration=scale_calibration)
    score = score_run(run_dir, seq_dir)
    atomic_write_json(run_dir / "score.json", score.to_dict())
    return score.flat()


def write_match_samples(
    seq_dir: Path, estimator: str, run_dir: Path, overrides: Mapping[str, str] | None = None, count: int = 3
) -> int:
    """Save the matched keypoints of ``count`` frame pairs as ``RUN/matches/NNNNNN.npz`` for the report.

    Runs the estimator afresh on each pair (previous, current) and keeps
    ``StepResult.matches_px`` ((N, 4): u_prev, v_prev, u_cur, v_cur) as ``xy_prev_px`` and
    ``xy_cur_px`` (N, 2). Returns how many pairs had matches (0 when the estimator does not
    expose them).
    """
    import io as _io

    import numpy as np

    from floorvo.estimators.base import Frame
    from floorvo.io import atomic_write_bytes
    from floorvo.run import build_estimator
    from floorvo.sequence import Sequence

    seq = Sequence.open(seq_dir)
    if seq.frame_count < 2:
        return 0
    est, _ = build_estimator(seq, estimator, overrides)
    picks = sorted({int(i) for i in np.linspace(1, seq.frame_count - 1, min(count, seq.frame_count - 1)).round()})
    written = 0
    for i in picks:
        state = est.start()
        res = None
        for j in (i - 1, i):
            res = est.step(
                state,
                Frame(
                    index=j,
                    timestamp_s=float(seq.timestamps_s[j]),
                    image=seq.image(j),
                    image_right=seq.image(j, "cam1") if "stereo" in est.requires else None,
                    depth_mm=seq.depth_mm(j) if "depth" in est.requires else None,
                ),
            )
        m = getattr(res, "matches_px", None)
        if m is None or len(m) == 0:
            continue
        m = np.asarray(m, dtype=float).reshape(-1, 4)
        buf = _io.BytesIO()
        np.savez(buf, xy_prev_px=m[:, :2], xy_cur_px=m[:, 2:])
        atomic_write_bytes(run_dir / "matches" / f"{i:06d}.npz", buf.getvalue())
        written += 1
    return written


def _trajectory_type(scene) -> str | None:
    traj = scene.to_dict().get("trajectory") or {}
    return traj.get("type")


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
    report: bool = True,
    paper000_runs: int | None = None,
    on_frame: Callable[[str, int, int], None] | None = None,
    render: RenderFn | None = None,
    scale_calibrations: Mapping[str, str | os.PathLike] | None = None,
) -> BenchResult:
    """Render, run, score, report and gate (see the module doc).

    ``estimators``: names, or None for every registered estimator each sequence supports.
    ``paper000_runs`` limits the number of runs per paper-000 model (None: all of them).
    ``on_frame(scene_name, done, n)`` reports render progress (frames done of n). ``render`` replaces the
    renderer (same signature as ``floorsim.simulate.render_sequence``).
    ``scale_calibrations``: ``{estimator: calibration file}`` (``floorvo calibrate``); that
    estimator's runs, the paper-000 protocol's included, divide the rig's scale out of
    every step, and each row names the file in ``scale_calibration``.
    """
    from floorsim.scene import load_scene

    if repetitions < 1:
        raise ConfigError(f"--repeat {repetitions}: must be >= 1")
    if not scene_paths:
        raise ConfigError("bench: give at least one scene file")
    out_dir = Path(out_dir)
    cache_dir = Path(cache_dir) if cache_dir is not None else out_dir / "sequences"
    est_over = {k: dict(v) for k, v in (estimator_overrides or {}).items()}
    if estimators is not None:
        known = set(_registry_names())
        for n in list(estimators) + list(est_over):
            if n not in known:
                raise ConfigError(f"--estimators {n!r}: unknown estimator (known: {', '.join(sorted(known))})")
    cals = {}
    for n, f in (scale_calibrations or {}).items():
        if n not in _registry_names():
            raise ConfigError(
                f"--scale-calibration {n}={f}: unknown estimator (known: {', '.join(sorted(_registry_names()))})"
            )
        if estimators is not None and n not in estimators:
            raise ConfigError(
                f"--scale-calibration {n}={f}: estimator {n!r} is not among --estimators ({', '.join(estimators)})"
            )
        from floorvo.calibration import load_scale_calibration

        cals[n] = (str(f), load_scale_calibration(f))
    baseline_data = load_baseline(baseline) if baseline is not None else None

    scenes = [(Path(p), load_scene(p, dict(scene_overrides or {}))) for p in scene_paths]
    names_seen: dict[str, int] = {}
    rows: list[dict[str, Any]] = []
    records: list[RunRecord] = []
    sections = []
    notes: list[str] = []
    results_csv = out_dir / "results.csv"
    first_rendered: dict[str, tuple[Path, Any, Path, int]] = {}  # label -> (scene file, scene, sequence, seed) of rep 0
    for path, scene in scenes:
        label = scene.name
        names_seen[label] = names_seen.get(label, 0) + 1
        if names_seen[label] > 1:
            label = f"{label}-{names_seen[label]}"
        for rep in range(repetitions):
            seed = _scene_seed(scene) + rep
            cb = (lambda i, n, _s=label: on_frame(_s, i, n)) if on_frame else None
            seq_dir = render_cached(
                scene, cache_dir, seed=seed, frames=frames, scale=scale, spp=spp, on_frame=cb, render=render
            )
            if rep == 0:
                first_rendered[label] = (path, scene, seq_dir, seed)
            names, skipped = supported_estimators(seq_dir, estimators)
            if rep == 0:
                for n, why in skipped.items():
                    notes.append(f"{label}: {n} skipped ({why})")
                    log.warning("scene %s: estimator %s skipped: %s", label, n, why)
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
                if name in cals:
                    row["scale_calibration"] = cals[name][0]
                try:
                    metrics = run_one(
                        seq_dir, name, run_dir, est_over.get(name), cals[name][1] if name in cals else None
                    )
                    row["status"] = "ok"
                    row.update(metrics)
                    if report and rep == 0:
                        write_match_samples(seq_dir, name, run_dir, est_over.get(name))
                except FloorbenchError as exc:
                    row["status"] = f"failed: {exc}"
                    log.warning("scene %s, estimator %s: %s", label, name, exc)
                if label.startswith("paper001"):
                    row["paper_ref_error_pct"] = PAPER001_ERROR_PCT
                rows.append(row)
                records.append(RunRecord(label, name, rep, seq_dir, run_dir))
                write_results_csv(results_csv, rows)
            if rep == 0 and _trajectory_type(scene) == "strip":
                from floorsim.bench.protocols.paper000 import run_paper000

                p0 = run_paper000(
                    seq_dir,
                    names,
                    out_dir / "paper000" / label,
                    max_runs=paper000_runs,
                    estimator_overrides=est_over,
                    scale_calibrations={n: c for n, (_, c) in cals.items()},
                )
                sections.append(p0.report_section)
        if label.startswith("paper001"):
            sections.append(_paper001_section([r for r in rows if r["scene"] == label]))

    # Paper 003: a map from each lawnmower scene, the kidnap scenes over its floor localised on it.
    from floorsim.bench.protocols.paper003 import pair_map_and_kidnap, run_paper003

    pairs, p3_notes = pair_map_and_kidnap([(lab, v[1]) for lab, v in first_rendered.items()])
    notes.extend(p3_notes)
    for map_label, kid_label in pairs:
        kpath, _, kseq, kseed = first_rendered[kid_label]
        base = {"scene_file": str(kpath), "seed": kseed}
        try:
            p3 = run_paper003(
                first_rendered[map_label][2],
                kseq,
                out_dir / "paper003",
                map_label=map_label,
                kidnap_label=kid_label,
                row_base=base,
            )
        except FloorbenchError as exc:
            notes.append(f"{kid_label}: relocalisation against the map of {map_label} failed: {exc}")
            log.warning("paper 003 (%s on %s): %s", kid_label, map_label, exc)
            continue
        rows.extend(p3.rows)
        records.extend(p3.records)
        write_results_csv(results_csv, rows)
        sections.append(p3.report_section)

    res = BenchResult(rows, records, results_csv, notes=notes)
    gate_text = None
    if baseline_data is not None:
        res.gate = compare(rows, baseline_data)
        gate_text = res.gate.summary()
    if save_baseline_to is not None:
        save_baseline(save_baseline_to, rows)
        res.baseline_saved = Path(save_baseline_to)
    if report:
        if notes:
            sections.insert(0, lambda rep, _n=list(notes): [rep.heading("Notes"), *[rep.text(t) for t in _n]])
        res.report_html, res.report_md = build_bench_report(
            out_dir, rows, records, gate_summary=gate_text, extra_sections=sections
        )
    return res


def _paper001_section(rows: list[dict[str, Any]]):
    def section(rep) -> None:
        rep.heading("Paper 001 reproduction: 3 m straight line")
        rep.text(
            f"Li et al. (JSER 2020) report an error of {PAPER001_ERROR_PCT} % over a 3 m line at 0.3 m/s. "
            "Here: the measured against the true distance (distance error) and the end-point error, each in % "
            "of the distance travelled; 'beats paper' compares the absolute distance error with the paper's."
        )
        table = []
        for r in rows:
            de = r.get("distance_error_pct")
            ok = isinstance(de, float) and math.isfinite(de)
            table.append(
                {
                    **r,
                    "paper": PAPER001_ERROR_PCT,
                    "beats": ("yes" if abs(de) <= PAPER001_ERROR_PCT else "no") if ok else "-",
                }
            )
        rep.table(
            table,
            [
                ("estimator", "estimator"),
                ("repetition", "rep"),
                ("path_length_mm", "path mm"),
                ("measured_mm", "measured mm"),
                ("distance_error_pct", "distance error %"),
                ("end_drift_pct", "end-point error %"),
                ("paper", "paper 001 %"),
                ("beats", "beats paper"),
            ],
        )

    return section

"""The motion suite (issue 14): every estimator on every scene of ``scenes/motion/suite.toml``, one table.

By default every registered estimator runs on every scene whose sequence it supports
(:func:`floorsim.bench.bench.supported_estimators`: orb-icp and stereo-sift only where the
sequence has depth or stereo, the mono estimators everywhere; one that needs a prebuilt map
is left out); ``--estimators a,b`` names some.

    .venv/bin/python benchmarks/motion_suite.py --scale 0.5 -o out/bench-motion-suite            # renders, runs
    .venv/bin/python benchmarks/motion_suite.py --from-cache out/bench-motion-suite/sequences -o out/again

Runs ``floorsim bench --suite motion`` as a library call (:func:`floorsim.bench.run_bench` on
:func:`floorsim.bench.suites.suite_scenes`, OpenCV on one thread), then prints one Markdown row
per scene x estimator from the bench's rows: steps, ok steps, **wrong ok steps**
(``wrong_ok_steps``: off by more than 0.05 mm + 2 % of the true step or 0.3 degrees, issue
14's bound), the same against the planar step of the camera's footprint
(``wrong_ok_steps_footprint``: the bound for a planar estimator on a tilted or bouncing run;
"-" for a run made 6-DoF by an attitude signal, held to the camera's step),
lost frames, end drift in % of the path, the turn error (``turn_error_pct``: measured minus
true turn over the steps reported ok, in % of the true turn; none under 10 degrees), frames
per second (from the mean total
time per frame of the run, one core) and the lost frames per kind of reason. With
``--from-cache DIR`` the suite's scenes are not rendered: the newest ``DIR/SCENE-*`` sequence
of each (a bench's render cache) is benched as it is, with a line on standard error where it was
rendered from another version of the scene file or of the renderer (its cache key differs).

``--est-set NAME.KEY=VALUE`` sets an estimator's config key in every run (as ``floorsim bench``).

``--calibrate`` (issue 14 item 1: the suite's drift after a per-material scale calibration):
for each floor material of the suite, the shipped straight run over it
(``scenes/material_MATERIAL.toml``: the paper-000 rig, 100 mm along x at 4 mm/frame) over
another floor than the suite's (``floor.seed`` one above the suite's highest, 1:
:func:`floorsim.bench.material_calibration.calibration_floor_seed`; from ``--from-cache`` when
it holds that render, else rendered at ``--scale``) is run by every estimator
and :func:`floorvo.calibration.calibrate_run` fits that estimator's scale on it
(``OUT/calibration/ESTIMATOR--MATERIAL.json``); the suite's scenes over that material are
then run again with it (:func:`floorsim.bench.run_bench`'s ``scale_calibrations``), and the
table gains the calibrated end drift, the scale fitted and the calibrated wrong-ok counts (against
the camera's 6-DoF step and against the footprint's; a run whose poses an attitude signal made
6-DoF, ``attitude.csv``, has no footprint count: "-"). A
straight run along x observes the x scale only (the y scale stays 1); an estimator that
loses its calibration run (the featureless floor) runs uncalibrated, and the table says so.

``--calibrate --spins DIR`` calibrates the yaw too: each estimator's calibration is fitted
per material on the straight run **and** a spin in place over the same floor together
(:func:`floorsim.bench.material_calibration.fit_material_calibration`, on
:func:`floorvo.calibration.calibrate_runs`): the suite's ``motion_turn_spin_concrete`` scene with
``floor.material`` set, over the calibration floor, rendered into ``DIR/MATERIAL-floorSEED-CODE``
(CODE: the renderer's code, :func:`floorsim.bench.material_calibration.calibration_render_dir`,
so a renderer edited since renders the calibration runs anew) at the straight run's frame size
when it is not there (:func:`floorsim.bench.material_calibration.render_spin`; a finished render
is reused). Never
the suite's own spin: its scored frames (until 2026-11-27 the concrete and polished spins were
calibrated on themselves; the straight runs were on the suite's floor, seed 0). Every
calibration run is checked against the scored sequences before a fit
(:func:`floorsim.bench.material_calibration.same_floor_problem`): one on a scored sequence's
floor stops the script. The material's scenes run a third time with it
(``OUT/calibration/ESTIMATOR--MATERIAL--yaw.json``), and the table gains the yaw's scale, the
end drift, turn error and wrong-ok count of that run. Where the spin cannot give the yaw (its
run lost, its ok steps turned less than 10 degrees, or a yaw scale out of range) the straight
run's calibration stands: the yaw-scale cell says why and the yaw-calibrated cells repeat the
x, y calibrated figures, marked "(x, y only)".

``--calibrate --spins DIR --orientation`` fits a third calibration per material and estimator:
on the straight run, the same run turned to 60 and 120 degrees over the floor
(:func:`floorsim.bench.material_calibration.render_turned_straight`, rendered into
``DIR/MATERIAL-floorSEED-heading60-CODE`` and ``-heading120-CODE`` when missing) and a spin over
3.5 rad (more than half a turn: ``DIR/MATERIAL-floorSEED-spin3.5rad-CODE``) together, all over the
calibration floor, with the
scales depending on each step's texture orientation where the runs observe it
(:mod:`floorvo.calibration`: a grained floor, wood). Where it has such terms the material's
scenes run a fourth time with it (``OUT/calibration/ESTIMATOR--MATERIAL--orientation.json``)
and the table gains its end drift, turn error and wrong-ok count; elsewhere the cell says why
there is none and the x, y, yaw figures stand, marked "(constant)".
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import sys
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import cv2  # noqa: E402

from floorsim.bench import run_bench  # noqa: E402
from floorsim.bench.bench import is_sequence_folder, scene_cache_key  # noqa: E402
from floorsim.bench.material_calibration import (  # noqa: E402
    FULL_SPIN_RAD,
    TURNED_HEADINGS_DEG,
    MaterialCalibration,
    calibration_floor_seed,
    calibration_render_dir,
    fit_material_calibration,
    floor_of,
    render_spin,
    render_turned_straight,
    same_floor_problem,
)
from floorsim.bench.suites import suite_scenes  # noqa: E402
from floorsim.commands.bench import parse_estimator_sets  # noqa: E402
from floorsim.scene import load_scene, resolve_scene_path  # noqa: E402
from floorvo.calibration import save_scale_calibration  # noqa: E402
from floorvo.errors import SequenceError  # noqa: E402
from floorvo.io import read_json  # noqa: E402


def _fmt(v, digits: int = 3) -> str:
    try:
        f = float(v)
    except (TypeError, ValueError):
        return "-"
    if f != f:  # NaN: no path (a spin in place) or nothing tracked
        return "-"
    text = f"{f:.{digits}f}".rstrip("0").rstrip(".") if digits else f"{f:.0f}"
    return "0" if text == "-0" else text  # -0.0003 rounded


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--suite", default="motion", help="suite name or file (default motion)")
    ap.add_argument("--scale", type=float, default=None, help="render at this fraction of 648x494")
    ap.add_argument(
        "--estimators", default="", help="comma-separated names (default: every registered one each sequence supports)"
    )
    ap.add_argument("--cache", type=Path, default=None, help="render cache (default OUT/sequences)")
    ap.add_argument("--from-cache", type=Path, default=None, help="bench the newest DIR/SCENE-* sequence of each scene")
    ap.add_argument(
        "--calibrate", action="store_true", help="also run each scene with a per-material scale calibration"
    )
    ap.add_argument(
        "--spins",
        type=Path,
        default=None,
        metavar="DIR",
        help="with --calibrate: fit the yaw too, on a spin in place per material (rendered into DIR/MATERIAL if missing)",
    )
    ap.add_argument(
        "--orientation",
        action="store_true",
        help="with --spins: also fit scales that depend on the floor texture's orientation, on straight runs "
        "turned to 60 and 120 degrees and a spin over 3.5 rad (rendered into DIR if missing)",
    )
    ap.add_argument(
        "--est-set", action="append", metavar="NAME.KEY=VALUE", help="override an estimator config key (repeatable)"
    )
    ap.add_argument("-o", "--output", type=Path, required=True)
    args = ap.parse_args()
    if args.spins is not None and not args.calibrate:
        ap.error("--spins goes with --calibrate (it calibrates the yaw too)")
    if args.orientation and args.spins is None:
        ap.error("--orientation goes with --calibrate --spins (it fits on the straight runs and the spin)")
    est_sets = parse_estimator_sets(args.est_set)
    cv2.setNumThreads(1)
    estimators: list[str] | None = [e.strip() for e in args.estimators.split(",") if e.strip()] or None
    scenes: list[Path] = suite_scenes(args.suite)
    loaded = [load_scene(p) for p in scenes]
    names = [sc.name for sc in loaded]
    material_of = {n: sc.floor.material for n, sc in zip(names, loaded)}
    if args.from_cache is not None:
        scenes = [_cached(args.from_cache, n) or _no_cache(args.from_cache, n) for n in names]
        for sc, folder in zip(loaded, scenes):
            if why := _stale_problem(sc, folder):
                print(f"--from-cache: {why}; benched as it is", file=sys.stderr)
    res = run_bench(
        scenes,
        estimators,
        args.output,
        scale=render_scale(scenes, args.scale),
        cache_dir=args.cache,
        report=True,
        estimator_overrides=est_sets,
    )
    calibrated: dict[tuple[str, str], dict] = {}
    with_yaw: dict[tuple[str, str], dict] = {}
    with_orient: dict[tuple[str, str], dict] = {}
    fits: dict[tuple[str, str], MaterialCalibration] = {}
    spins: dict[str, Path] = {}
    if args.calibrate:
        # Every calibration run over another floor than the suite's scenes: never fitted on what it scores.
        floor_seed = calibration_floor_seed(loaded)
        scored = sorted({r["sequence"] for r in res.rows})
        calibrated, with_yaw, with_orient, fits, spins = _calibrated_rows(
            args, scenes, names, material_of, estimators, est_sets, floor_seed, scored
        )
    cols = ["scene", "estimator", "steps", "ok", "wrong ok", "wrong ok, footprint", "lost", "end drift %"]
    cols += ["turn error %", "frames/s"]
    if args.calibrate:
        cols += [
            "scale x (material)",
            "calibrated end drift %",
            "calibrated wrong ok",
            "calibrated wrong ok, footprint",
        ]
    if args.spins is not None:
        cols += ["scale yaw (spin)", "x, y, yaw calibrated end drift %", "x, y, yaw calibrated turn error %"]
        cols += ["x, y, yaw calibrated wrong ok, footprint"]
    if args.orientation:
        cols += ["texture-orientation calibration", "orientation cal. end drift %", "orientation cal. turn error %"]
        cols += ["orientation cal. wrong ok, footprint"]
    cols.append("lost frames by reason")
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for r in res.rows:
        lost = int(float(r.get("lost_frames", 0) or 0))
        steps = _steps(r)
        scene = _scene_name(r)
        cells = [
            scene,
            r["estimator"],
            str(steps),
            str(steps - lost) if steps else "-",
            _fmt(r.get("wrong_ok_steps"), 0),
            _fmt(r.get("wrong_ok_steps_footprint"), 0),
            str(lost),
            _fmt(r.get("end_drift_pct")),
            _fmt(r.get("turn_error_pct")),
            _fmt(r.get("fps"), 1),
        ]
        if args.calibrate:
            c = calibrated.get((scene, r["estimator"]), {})
            fit = fits.get((material_of[scene], r["estimator"]))
            cells += [
                fit.scale_x_cell() if fit is not None else "-",
                _cell(c, "end_drift_pct"),
                _cell(c, "wrong_ok_steps", 0),
                _cell(c, "wrong_ok_steps_footprint", 0),
            ]
        if args.spins is not None:
            # The spin gave no yaw: the x, y calibrated run stands.
            y, more = _calibrated_cells(
                with_yaw.get((scene, r["estimator"])), c, " (x, y only)", fit.scale_yaw_cell() if fit else "-"
            )
            cells += more
        if args.orientation:
            # No texture-orientation terms: the constant calibration stands.
            _, more = _calibrated_cells(
                with_orient.get((scene, r["estimator"])), y, " (constant)", fit.orientation_cell() if fit else "-"
            )
            cells += more
        cells.append(str(r.get("lost_reasons") or "") if str(r.get("status")) == "ok" else str(r.get("status")))
        print("| " + " | ".join(cells) + " |")
    for m, seq in sorted(spins.items()):
        print(f"spin over {m}: {seq}")
    print(f"\nmachine: {platform.machine()}, {os.cpu_count()} cores; OpenCV {cv2.__version__} with 1 thread")
    print(f"results: {res.results_csv}; report: {res.report_html}")


def _calibrated_cells(row: dict | None, stands: dict, mark: str, calibration_cell: str) -> tuple[dict, list[str]]:
    """The row of a calibrated run (or, where it did not run, the ``stands`` row its cells repeat,
    marked ``mark``) and its cells: the calibration, end drift, turn error, wrong ok against the footprint."""
    if row is None and stands:
        row, shown = stands, mark
    else:
        row, shown = row or {}, ""
    return row, [
        calibration_cell,
        _cell(row, "end_drift_pct") + shown if row else "-",
        _cell(row, "turn_error_pct") + shown if row else "-",
        _cell(row, "wrong_ok_steps_footprint", 0),
    ]


def _cell(row: dict, key: str, digits: int = 3) -> str:
    """A calibrated run's figure, or "failed" where that run failed (its row's status): it read "-",
    as a figure the run does not have, while the uncalibrated row beside it said ok."""
    status = str(row.get("status", "ok")) if row else "ok"
    return _fmt(row.get(key), digits) if status == "ok" else "failed"


def render_scale(paths: list[Path], scale: float | None) -> float | None:
    """``--scale`` for a bench of ``paths``: None when every one is a sequence folder (``--from-cache``:
    rendered already; the bench refuses a render setting given with folders alone)."""
    return None if all(is_sequence_folder(p) for p in paths) else scale


def _cached(cache: Path, name: str, floor_seed: int | None = None) -> Path | None:
    """The newest finished ``CACHE/NAME-*`` sequence of a bench's render cache, or None;
    ``floor_seed``: only one rendered over that floor (:func:`floor_of`)."""
    cands = sorted(cache.glob(f"{name}-*"), key=lambda p: p.stat().st_mtime)
    cands = [c for c in cands if (c / "bench-cache.json").is_file()]
    if floor_seed is not None:
        cands = [c for c in cands if (floor_of(c) or ("", None))[1] == floor_seed]
    return cands[-1] if cands else None


def _stale_problem(scene, folder: Path) -> str:
    """Why the cached render ``folder`` is not what ``scene`` (the suite's scene file as it is now)
    renders today, or '': its ``bench-cache.json`` key is not the one the bench would key that
    scene by (:func:`floorsim.bench.bench.scene_cache_key`, at the render settings the folder
    records), so the scene file or the renderer's code changed since. It is still benched (a
    measurement of estimator code on earlier renders is legitimate), but said: the newest folder
    was taken without a word before."""
    mark = read_json(folder / "bench-cache.json", SequenceError)
    settings = {k: mark.get(k) for k in ("frames", "scale", "spp")}
    key = scene_cache_key(scene.to_dict(), seed=int(mark.get("seed", 0)), **settings)
    if key == mark.get("key"):
        return ""
    return f"{folder} was rendered from another version of scene {scene.name} or of the renderer (cache key differs)"


def _no_cache(cache: Path, name: str) -> Path:
    raise SystemExit(f"--from-cache {cache}: no finished sequence of scene {name}")


def _scene_name(row) -> str:
    return re.sub(r"-[0-9a-f]{12}$", "", str(row["scene"]))  # a cached sequence's folder: NAME-HASH


def _calibrated_rows(args, scenes, names, material_of, estimators, est_sets, floor_seed, scored):
    """Fit each estimator's scale per material on the material's straight run (with ``--spins``,
    and on the straight run with a spin over the material, :func:`render_spin` into ``--spins``),
    every calibration run over the floor of ``floor_seed``, and none on the floor of a ``scored``
    sequence (:func:`same_floor_problem`), then run the suite's scenes again with each. Returns ``({(scene, estimator): row}`` x, y calibrated, the same with
    the yaw, the same with the texture-orientation terms (``--orientation``), ``{(material, estimator):
    MaterialCalibration}``, ``{material: spin sequence})``."""
    out = args.output / "calibration"
    materials = sorted(set(material_of.values()))
    cal_scenes = []
    for m in materials:
        shipped = resolve_scene_path(f"material_{m}")
        cached = _cached(args.from_cache, f"material_{m}", floor_seed) if args.from_cache is not None else None
        cal_scenes.append(cached or shipped)
    rendered = not all(is_sequence_folder(p) for p in cal_scenes)
    cal = run_bench(
        cal_scenes,
        estimators,
        out / "runs",
        scale=args.scale if rendered else None,  # render_scale: --scale only for scenes still to render
        cache_dir=args.cache,
        report=False,
        estimator_overrides=est_sets,
        scene_overrides={"floor.seed": str(floor_seed)} if rendered else None,
    )
    _check_separate([r["sequence"] for r in cal.rows], scored)
    straight = {
        (_scene_name(r).removeprefix("material_"), r["estimator"]): (r["run_dir"], r["sequence"]) for r in cal.rows
    }
    fits = {key: fit_material_calibration(pair, None) for key, pair in straight.items()}
    straight_seq = {m: seq for (m, _), (_, seq) in straight.items()}  # each material's straight run
    spins: dict[str, Path] = {}
    if args.spins is not None:
        # A spin only for the floors some estimator could be calibrated on (not the featureless one).
        for m in sorted({m for (m, _), f in fits.items() if f.straight is not None}):
            spins[m] = render_spin(
                m,
                calibration_render_dir(args.spins, f"{m}-floor{floor_seed}", m),
                straight_seq[m],
                floor_seed=floor_seed,
            )
        _check_separate(spins.values(), scored)
        spin_runs: dict[tuple[str, str], tuple[str, str]] = {}
        if spins:
            material_of_spin = {str(seq): m for m, seq in spins.items()}
            ran = run_bench(
                list(spins.values()),
                sorted({e for (_, e), f in fits.items() if f.straight is not None}),
                out / "spin-runs",
                report=False,
                estimator_overrides=est_sets,
            )
            for r in ran.rows:
                spin_runs[(material_of_spin[str(r["sequence"])], r["estimator"])] = (r["run_dir"], r["sequence"])
        turned_runs: dict[tuple[str, str], list[tuple[str, str]]] = {}
        full_spin_runs: dict[tuple[str, str], tuple[str, str]] = {}
        if args.orientation and spins:
            turned = {
                (m, h): render_turned_straight(
                    m,
                    h,
                    calibration_render_dir(args.spins, f"{m}-floor{floor_seed}-heading{h:g}", m),
                    straight_seq[m],
                    floor_seed=floor_seed,
                )
                for m in spins
                for h in TURNED_HEADINGS_DEG
            }
            of_seq = {str(seq): m for (m, _), seq in turned.items()}
            full_spins = {
                m: render_spin(
                    m,
                    calibration_render_dir(args.spins, f"{m}-floor{floor_seed}-spin{FULL_SPIN_RAD:g}rad", m),
                    straight_seq[m],
                    FULL_SPIN_RAD,
                    floor_seed=floor_seed,
                )
                for m in spins
            }
            _check_separate([*turned.values(), *full_spins.values()], scored)
            of_seq.update({str(seq): m for m, seq in full_spins.items()})
            ran = run_bench(
                list(turned.values()) + list(full_spins.values()),
                sorted({e for (_, e), f in fits.items() if f.straight is not None}),
                out / "orientation-runs",
                report=False,
                estimator_overrides=est_sets,
            )
            full_of = {str(seq) for seq in full_spins.values()}
            for r in ran.rows:
                key = (of_seq[str(r["sequence"])], r["estimator"])
                if str(r["sequence"]) in full_of:
                    full_spin_runs[key] = (r["run_dir"], r["sequence"])
                else:
                    turned_runs.setdefault(key, []).append((r["run_dir"], r["sequence"]))
        fits = {
            key: fit_material_calibration(
                pair, spin_runs.get(key), turned=turned_runs.get(key, ()), full_spin=full_spin_runs.get(key)
            )
            for key, pair in straight.items()
        }
    files: dict[tuple[str, str], Path] = {}
    yaw_files: dict[tuple[str, str], Path] = {}
    orient_files: dict[tuple[str, str], Path] = {}
    for (m, e), fit in fits.items():
        if fit.straight is not None:
            files[(m, e)] = out / f"{e}--{m}.json"
            save_scale_calibration(fit.straight, files[(m, e)])
        if fit.with_yaw is not None:
            yaw_files[(m, e)] = out / f"{e}--{m}--yaw.json"
            save_scale_calibration(fit.with_yaw, yaw_files[(m, e)])
        if fit.with_orientation is not None:
            orient_files[(m, e)] = out / f"{e}--{m}--orientation.json"
            save_scale_calibration(fit.with_orientation, orient_files[(m, e)])
    rows: dict[tuple[str, str], dict] = {}
    rows_yaw: dict[tuple[str, str], dict] = {}
    rows_orient: dict[tuple[str, str], dict] = {}
    for m in materials:
        group = [p for p, n in zip(scenes, names) if material_of[n] == m]
        for tag, found, into in (
            ("", files, rows),
            ("yaw-", yaw_files, rows_yaw),
            ("orientation-", orient_files, rows_orient),
        ):
            with_cal = sorted(e for (mat, e) in found if mat == m)
            if not group or not with_cal:
                continue
            res = run_bench(
                group,
                with_cal,
                out / f"suite-{tag}{m}",
                scale=render_scale(group, args.scale),
                cache_dir=args.cache,
                report=False,
                scale_calibrations={e: found[(m, e)] for e in with_cal},
                estimator_overrides=est_sets,
            )
            for r in res.rows:
                into[(_scene_name(r), r["estimator"])] = r
    return rows, rows_yaw, rows_orient, fits, spins


def _check_separate(calibration, scored) -> None:
    """Stop where a calibration run is a scored sequence or on a scored sequence's floor."""
    problem = same_floor_problem(calibration, scored)
    if problem:
        raise SystemExit(f"--calibrate: {problem}")


def _steps(row) -> int:
    """Steps of a run: its frames less the first (``timing.csv`` of the run folder)."""
    timing = Path(row["run_dir"]) / "timing.csv"
    if not timing.is_file():
        return 0
    return max(0, len(timing.read_text().strip().splitlines()) - 2)


if __name__ == "__main__":
    main()

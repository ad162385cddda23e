"""The motion suite's fast straight runs with the scale calibrated at their own speed (issue 14).

The suite's calibration (``motion_suite.py --calibrate``) fits each estimator's scale per
material on the material's straight run, 4 mm/frame without motion blur. A run at 10-30
mm/frame with an exposure that blurs the picture is read at another scale by some estimators:
over the wood floor at 30 mm/frame phase-corr reads each step 0.38 % long, at 4-20 mm/frame
0.01-0.03 % (BENCHMARKS.md, "Fast runs: a scale calibrated at their own speed"). A rig that
drives fast is calibrated at its speed; this script measures what that gives.

For each straight (``uniform``) scene of the suite whose step or exposure differs from its
material's straight run (``scenes/material_MATERIAL.toml``), the calibration run at speed is the
same scene over another floor (``floor.seed`` = the scene's seed + 1: the same material, other
boards, other grain), rendered into the render cache. Each estimator's x, y scale is fitted on
it (:func:`floorsim.bench.material_calibration.fit_material_calibration`, as the suite's
calibration) and on the material's straight run (over that other floor too, as the suite's
calibration: until 2026-11-27 it was over the scene's own floor), and the scene
runs with each. One Markdown row per scene and estimator: ok steps, wrong ok steps (issue 14's
bound), end drift in % uncalibrated, with the material's 4 mm/frame scale and with the scale at
speed.

    .venv/bin/python benchmarks/speed_calibration.py --from-cache CACHE --cache RENDERS -o OUT \\
        --estimators akaze-bruteforce,akaze-guided,phase-corr,phase-corr-fast

``--from-cache CACHE``: the suite's scenes are the newest ``CACHE/SCENE-*`` sequences (a bench's
render cache, as ``motion_suite.py --from-cache``); ``--cache RENDERS``: where the calibration
runs are rendered or found (a bench render cache; the material runs a ``motion_suite.py
--calibrate`` rendered are in its ``OUT/calibration/runs/sequences``).
"""

from __future__ import annotations

import argparse
import os
import platform
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import cv2  # noqa: E402

from floorsim.bench import run_bench  # noqa: E402
from floorsim.bench.material_calibration import fit_material_calibration, same_floor_problem  # noqa: E402
from floorsim.bench.suites import suite_scenes  # noqa: E402
from floorsim.commands.bench import parse_estimator_sets  # noqa: E402
from floorsim.scene import Scene, load_scene, resolve_scene_path  # noqa: E402
from floorvo.calibration import save_scale_calibration  # noqa: E402

# The suite's cache lookup and cells (run as a script: this folder is on the path).
from motion_suite import _cached, _fmt, _no_cache, _scene_name, render_scale  # noqa: E402


def _fast_straight(scene: Scene, material_run: Scene) -> bool:
    """A straight run whose step or exposure differs from its material's straight run."""
    tr, tm = scene.to_dict()["trajectory"], material_run.to_dict()["trajectory"]
    if tr["type"] != "uniform":
        return False
    return tr.get("step_mm") != tm.get("step_mm") or scene.sensor.exposure_ms != material_run.sensor.exposure_ms


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--suite", default="motion", help="suite name or file (default motion)")
    ap.add_argument("--estimators", required=True, help="comma-separated mono estimator names")
    ap.add_argument("--from-cache", type=Path, default=None, help="bench the newest DIR/SCENE-* sequence of each scene")
    ap.add_argument("--cache", type=Path, required=True, help="render cache of the calibration runs")
    ap.add_argument("--scale", type=float, default=None, help="render at this fraction of 648x494")
    ap.add_argument("--est-set", action="append", metavar="NAME.KEY=VALUE", help="override an estimator config key")
    ap.add_argument("-o", "--output", type=Path, required=True)
    args = ap.parse_args()
    est_sets = parse_estimator_sets(args.est_set)
    cv2.setNumThreads(1)
    estimators = [e.strip() for e in args.estimators.split(",") if e.strip()]
    out: Path = args.output
    picked: list[tuple[Path, Scene]] = []
    for p in suite_scenes(args.suite):
        sc = load_scene(p)
        if _fast_straight(sc, load_scene(resolve_scene_path(f"material_{sc.floor.material}"))):
            picked.append((p, sc))
    if not picked:
        raise SystemExit(f"suite {args.suite}: no straight run faster or more blurred than its material's run")
    rows = []
    for path, sc in picked:
        seq = (_cached(args.from_cache, sc.name) or _no_cache(args.from_cache, sc.name)) if args.from_cache else path
        m = sc.floor.material
        floor_seed = (sc.seed if sc.floor.seed is None else sc.floor.seed) + 1
        kw = dict(scale=args.scale, cache_dir=args.cache, report=False, estimator_overrides=est_sets)
        other_floor = {"floor.seed": str(floor_seed)}
        material = run_bench(
            [resolve_scene_path(f"material_{m}")],
            estimators,
            out / f"{sc.name}/material-runs",
            scene_overrides=other_floor,
            **kw,
        )
        at_speed = run_bench([path], estimators, out / f"{sc.name}/at-speed-runs", scene_overrides=other_floor, **kw)
        fits: dict[str, dict[str, Path]] = {"material": {}, "speed": {}}
        scales: dict[tuple[str, str], str] = {}
        for kind, res in (("material", material), ("speed", at_speed)):
            for r in res.rows:
                e = r["estimator"]
                # x and y fitted on the straight run, or why not (lost, or a scale out of range)
                fit = fit_material_calibration((r["run_dir"], r["sequence"]), None)
                scales[kind, e] = fit.scale_x_cell()
                if fit.straight is not None:
                    fits[kind][e] = out / sc.name / f"{e}--{kind}.json"
                    save_scale_calibration(fit.straight, fits[kind][e])
        on_seq = {**kw, "scale": render_scale([seq], args.scale)}  # a cached sequence folder: rendered already
        plain = {r["estimator"]: r for r in run_bench([seq], estimators, out / f"{sc.name}/plain", **on_seq).rows}
        scored = [r["sequence"] for r in plain.values()]
        problem = same_floor_problem([r["sequence"] for r in (*material.rows, *at_speed.rows)], scored)
        if problem:  # a calibration is never fitted on the floor it is scored on
            raise SystemExit(problem)
        calibrated: dict[str, dict[str, dict]] = {}
        for kind, files in fits.items():
            if files:
                res = run_bench([seq], sorted(files), out / f"{sc.name}/{kind}", scale_calibrations=files, **on_seq)
                calibrated[kind] = {r["estimator"]: r for r in res.rows}
        for e in estimators:
            r = plain.get(e, {})
            cm, cs = calibrated.get("material", {}).get(e, {}), calibrated.get("speed", {}).get(e, {})
            lost = int(float(r.get("lost_frames", 0) or 0))
            rows.append(
                [
                    _scene_name(r) if r else sc.name,
                    e,
                    str(lost),
                    _fmt(r.get("wrong_ok_steps"), 0),
                    _fmt(r.get("end_drift_pct")),
                    scales.get(("material", e), "-"),
                    _fmt(cm.get("end_drift_pct")),
                    scales.get(("speed", e), "-"),
                    _fmt(cs.get("end_drift_pct")),
                    _fmt(cs.get("wrong_ok_steps"), 0),
                ]
            )
    cols = ["scene", "estimator", "lost", "wrong ok", "end drift %", "scale x (material, 4 mm/frame)"]
    cols += ["calibrated end drift %", "scale x (at speed, floor seed + 1)", "calibrated at speed end drift %"]
    cols += ["calibrated at speed wrong ok"]
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for cells in rows:
        print("| " + " | ".join(cells) + " |")
    print(f"\nmachine: {platform.machine()}, {os.cpu_count()} cores; OpenCV {cv2.__version__} with 1 thread")


if __name__ == "__main__":
    main()

"""Sweep scale-out: the same sweep on a local Dask cluster of 1 and of 2 workers, in one run.

    .venv/bin/python benchmarks/sweep_scaling.py --out out/bench-scaling [--workers 1,2] [--values 1,2,3,5,10,20]

Writes a sweep file (the demo scene, ``--key`` over ``--values``, ``--frames``/``--scale``/
``--spp``, ``--estimators``) and runs it with ``floorsim.bench.sweep.run_sweep(...,
workers=N)`` once per N, each into its own folder with its own render cache (so every run
renders everything), without the report. Prints per N the wall time (the local cluster's
start and stop included, as a user sees it), the jobs, the load average before and after,
and the ratio of the first N's wall time to each other's. Each Dask worker is one process
with one task thread; the renderer inside it uses every core (Dr.Jit's thread pool), so
on a machine of C cores, N workers share them.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

from floorsim.bench.sweep import run_sweep

DEMO = Path(__file__).resolve().parents[1] / "scenes" / "demo.toml"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, required=True, help="output folder (one sub-folder per worker count)")
    ap.add_argument("--workers", default="1,2", help="comma-separated worker counts (default 1,2)")
    ap.add_argument("--scene", type=Path, default=DEMO)
    ap.add_argument("--key", default="lights.height_mm")
    ap.add_argument("--values", default="1,2,3,5,10,20", help="comma-separated values of --key (one job each)")
    ap.add_argument("--estimators", default="phase-corr,akaze-guided")
    ap.add_argument("--frames", type=int, default=6)
    ap.add_argument("--scale", type=float, default=0.5)
    ap.add_argument("--spp", type=int, default=2)
    args = ap.parse_args()

    args.out.mkdir(parents=True, exist_ok=True)
    values = [float(v) for v in args.values.split(",")]
    names = [n.strip() for n in args.estimators.split(",")]
    study = args.out / "scaling.toml"
    study.write_text(
        f'base = "{args.scene.resolve()}"\nestimators = {json.dumps(names)}\n'
        f"[render]\nframes = {args.frames}\nscale = {args.scale}\nspp = {args.spp}\n"
        f'[vary]\n"{args.key}" = {json.dumps(values)}\n'
    )
    results = []
    for n in [int(w) for w in args.workers.split(",")]:
        out = args.out / f"workers{n}"
        if (out / "results.csv").exists():
            raise SystemExit(f"{out} holds a finished run: give an empty --out")
        load_before = os.getloadavg()
        t0 = time.perf_counter()
        res = run_sweep(study, out, workers=n, report=False)
        wall = time.perf_counter() - t0
        results.append(
            {
                "workers": n,
                "wall_s": round(wall, 1),
                "jobs": res.ran,
                "errors": len(res.errors),
                "load_before": [round(x, 2) for x in load_before],
                "load_after": [round(x, 2) for x in os.getloadavg()],
            }
        )
        print(
            f"{n} worker(s): {wall:.1f} s for {res.ran} jobs ({len(res.errors)} failed); load {load_before[0]:.2f} -> {os.getloadavg()[0]:.2f}"
        )
    base = results[0]["wall_s"]
    for r in results[1:]:
        r["ratio_to_first"] = round(base / r["wall_s"], 2)
        print(f"wall time {results[0]['workers']} worker(s) / {r['workers']} worker(s): {r['ratio_to_first']:.2f}")
    info = {"machine": platform.platform(), "cpus": os.cpu_count(), "study": study.read_text(), "runs": results}
    (args.out / "scaling.json").write_text(json.dumps(info, indent=2) + "\n")


if __name__ == "__main__":
    main()

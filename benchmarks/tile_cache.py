"""Time to the first frame with a cold and a warm floor-tile cache (floorsim.tilecache).

    .venv/bin/python benchmarks/tile_cache.py [--scene paper000_uniform] [--repeats 3] [--scale 1]

Each run is a fresh ``floorsim render SCENE --frames 1`` process (import, floor tile and
height grid, the first frame, the flat-field frame, PNG writing), timed from start to exit:
*cold* with an empty ``FLOORSIM_CACHE``, *warm* with the cache the cold run filled. Runs
alternate cold, warm, so both see the same machine load; Dr.Jit's own kernel cache is
warmed by one discarded run first. Prints the medians and their ratio.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def _run(scene: str, scale: float, cache: Path, out: Path, src: str | None = None) -> float:
    scenes = str(Path(__file__).resolve().parents[1] / "scenes")
    env = {"FLOORSIM_SCENES": scenes, **os.environ, "FLOORSIM_CACHE": str(cache)}
    if src:
        env["PYTHONPATH"] = src
    cmd = [sys.executable, "-m", "floorsim.cli", "-q", "render", scene, "-o", str(out), "--frames", "1"]
    if scale != 1.0:
        cmd += ["--scale", str(scale)]
    t = time.perf_counter()
    subprocess.run(cmd, env=env, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="paper000_uniform")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--json", help="also write the figures to this file")
    ap.add_argument(
        "--against",
        metavar="SRC",
        help="also time another source tree (its src/ folder, e.g. a git archive of an older commit), "
        "alternating with this one in the same run",
    )
    args = ap.parse_args()
    if args.against:
        against(args)
        return
    cold, warm = [], []
    with tempfile.TemporaryDirectory(prefix="tile-cache-bench-") as tmp:
        root = Path(tmp)
        _run(args.scene, args.scale, root / "jit-warmup-cache", root / "warmup")  # Dr.Jit's kernel cache
        for r in range(args.repeats):
            cache = root / f"cache{r}"
            cold.append(_run(args.scene, args.scale, cache, root / f"cold{r}"))
            warm.append(_run(args.scene, args.scale, cache, root / f"warm{r}"))
            print(f"repeat {r}: cold {cold[-1]:.2f} s, warm {warm[-1]:.2f} s", flush=True)
    res = {
        "scene": args.scene,
        "scale": args.scale,
        "cold_s": cold,
        "warm_s": warm,
        "cold_median_s": statistics.median(cold),
        "warm_median_s": statistics.median(warm),
        "machine": f"{platform.machine()}, {os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f}",
    }
    res["ratio"] = res["cold_median_s"] / res["warm_median_s"]
    print(
        f"{args.scene} x{args.scale}: time to first frame cold {res['cold_median_s']:.2f} s, "
        f"warm {res['warm_median_s']:.2f} s (x{res['ratio']:.2f}); {res['machine']}"
    )
    if args.json:
        Path(args.json).write_text(json.dumps(res, indent=2) + "\n")


def against(args) -> None:
    """Cold-cache time to the first frame of this tree and of ``--against``, alternating, in one run."""
    here = str(Path(__file__).resolve().parents[1] / "src")
    times: dict[str, list[float]] = {"this": [], "against": []}
    with tempfile.TemporaryDirectory(prefix="tile-cache-bench-") as tmp:
        root = Path(tmp)
        _run(args.scene, args.scale, root / "warmup-cache", root / "warmup", here)
        for r in range(args.repeats):
            for name, src in (("against", args.against), ("this", here)):
                times[name].append(_run(args.scene, args.scale, root / f"c-{name}{r}", root / f"{name}{r}", src))
            print(f"repeat {r}: this {times['this'][-1]:.2f} s, against {times['against'][-1]:.2f} s", flush=True)
    this, other = statistics.median(times["this"]), statistics.median(times["against"])
    print(
        f"{args.scene} x{args.scale}: time to first frame, empty cache: this {this:.2f} s, {args.against} "
        f"{other:.2f} s (x{other / this:.2f}); {platform.machine()}, {os.cpu_count()} CPUs, "
        f"load {os.getloadavg()[0]:.1f}"
    )


if __name__ == "__main__":
    main()

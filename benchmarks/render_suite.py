"""Wall time to render every scene of a suite, scene by scene, as a user renders them.

    .venv/bin/python benchmarks/render_suite.py [--suite motion] [--variant llvm_ad_mono] [--scale 1]
        [--frames N] [--passes 2] [--against SRC] [--json FILE]

Each scene is a fresh ``floorsim render SCENE -o OUT`` process (import, floor tiles, every frame,
PNG writing), timed from start to exit, into a new folder. The first pass starts from an empty
floor-tile cache (``FLOORSIM_CACHE``, a temporary folder of the run) and fills it; later passes
find it warm. ``--variant`` sets ``FLOORSIM_VARIANT`` (``cuda_ad_mono`` on a GPU machine);
``--against SRC`` also renders with another source tree (its ``src/`` folder, e.g. a ``git
archive`` of an older commit), alternating with this one scene by scene, with a tile cache of
its own. Prints a table of seconds per scene and pass, and the totals.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from floorsim.bench.suites import suite_scenes

HERE = Path(__file__).resolve().parents[1]


def _render(scene: Path, out: Path, cache: Path, args, src: Path) -> float:
    path = os.pathsep.join(p for p in (str(src), os.environ.get("PYTHONPATH", "")) if p)
    env = {**os.environ, "FLOORSIM_CACHE": str(cache), "PYTHONPATH": path}
    if args.variant:
        env["FLOORSIM_VARIANT"] = args.variant
    cmd = [sys.executable, "-m", "floorsim.cli", "-q", "render", str(scene), "-o", str(out)]
    if args.scale != 1.0:
        cmd += ["--scale", str(args.scale)]
    if args.frames:
        cmd += ["--frames", str(args.frames)]
    t = time.perf_counter()
    subprocess.run(cmd, env=env, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--suite", default="motion", help="a shipped suite's name or a suite file")
    ap.add_argument("--variant", help="FLOORSIM_VARIANT for the renders (default: the renderer's choice)")
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--frames", type=int, help="render only each scene's first N frames")
    ap.add_argument("--passes", type=int, default=1, help="passes over the suite (the first with an empty tile cache)")
    ap.add_argument("--against", metavar="SRC", type=Path, help="another source tree's src/ folder, alternating")
    ap.add_argument("--json", type=Path, help="also write the figures to this file")
    args = ap.parse_args()
    scenes = suite_scenes(args.suite)
    trees = {"this": HERE / "src"}
    if args.against:
        trees["against"] = args.against.resolve()
    seconds: dict[str, dict[str, list[float]]] = {name: {s.stem: [] for s in scenes} for name in trees}
    with tempfile.TemporaryDirectory(prefix="render-suite-") as tmp:
        root = Path(tmp)
        for p in range(args.passes):
            for scene in scenes:
                for name, src in trees.items():
                    out = root / f"{name}-pass{p}" / scene.stem
                    seconds[name][scene.stem].append(_render(scene, out, root / f"tiles-{name}", args, src))
                line = ", ".join(f"{name} {seconds[name][scene.stem][-1]:.1f} s" for name in trees)
                print(f"pass {p} {scene.stem}: {line}", flush=True)
    header = ["scene"] + [f"{name} pass {p} (s)" for name in trees for p in range(args.passes)]
    print("\n| " + " | ".join(header) + " |\n|" + "---|" * len(header))
    for scene in scenes:
        cells = [f"{t:.1f}" for name in trees for t in seconds[name][scene.stem]]
        print(f"| {scene.stem} | " + " | ".join(cells) + " |")
    totals = [f"{sum(s[p] for s in seconds[name].values()):.1f}" for name in trees for p in range(args.passes)]
    print("| **total** | " + " | ".join(totals) + " |")
    machine = f"{platform.machine()}, {os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f}"
    print(f"suite {args.suite}, variant {args.variant or 'automatic'}, scale {args.scale}; {machine}")
    if args.json:
        res = {"suite": args.suite, "variant": args.variant, "scale": args.scale, "frames": args.frames}
        args.json.write_text(json.dumps({**res, "seconds": seconds, "machine": machine}, indent=2) + "\n")


if __name__ == "__main__":
    main()

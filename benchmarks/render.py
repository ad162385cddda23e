"""Render benchmark: frames per second, PSNR against a high-spp reference, peak memory.

    .venv/bin/python benchmarks/render.py [--scene paper000_uniform] [--frames 10] [--spp 4,8,12] [--ref-spp 1024]
    .venv/bin/python benchmarks/render.py --profile [--frames 6] [--set lights.led_size_mm=3]
    .venv/bin/python benchmarks/render.py --against /tmp/old/src [--frames 6] [--repeats 3] [--ref-spp 1024]
    .venv/bin/python benchmarks/render.py --versus lights.led_size_mm=3.0 [--frames 6] [--repeats 3]

``--versus KEY=VALUE`` (repeatable) times the scene against the scene with these overrides
(lights, render settings: the floor must stay the same) in one process, alternating over
the same frames on the same floor tile; it prints the median CPU seconds per frame of each
and their ratio.

``--against SRC`` compares this tree with another source tree (its ``src/`` folder, e.g. a
``git archive`` of an older commit) in one run: one worker process per tree, each with
its floor tile loaded, rendering the same frames in turn (alternating, so both see the
same machine load), at each tree's default quality (``--this-set`` overrides apply to this
tree only); it prints the median CPU and wall seconds per frame of each and their ratio,
and the PSNR of each tree's frame 0 against a ``--ref-spp`` reference rendered by the
other tree (the old code's reference).

Renders ``--frames`` full-size frames of the scene at its default quality (or at each
``--spp`` given) and reports:

* frames/s of the steady per-frame render (camera and LEDs move, the floor tile stays),
  its CPU seconds per frame (all threads; on a shared machine the wall time depends on
  the other load), and the one-off cost of loading the floor tile (materials, or the tile
  cache, and the height grid; the BVH is built only for rays that need it);
* PSNR of the central 80 % of frame 0 (radiance before sensor noise, in the sequence's
  8-bit DN scale, peak 255) against a ``--ref-spp`` render of the same frame (accumulated
  in batches of 16 spp with independent jitter);
* peak resident memory of the process.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import resource
import tempfile
import time

import numpy as np

from floorsim.render import FloorRenderer, backend_info
from floorsim.scene import load_scene
from floorsim.sensor import SensorModel, exposure_gain
from floorsim.simulate import _frame_seed, _leds, _load_tile, _trajectory_of, plan_tiles
from floorvo.config import parse_set_args
from floorvo.io import write_png


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="paper000_uniform")
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--spp", default=None, help="comma-separated list; default: the scene's render.spp")
    ap.add_argument("--ref-spp", type=int, default=1024)
    ap.add_argument("--json", help="also write the figures to this file")
    ap.add_argument(
        "--profile",
        action="store_true",
        help="instead: where a frame's time goes (primary rays, shading, shadow rays, sensor, PNG, tracing)",
    )
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="scene override (repeatable)")
    ap.add_argument("--against", metavar="SRC", help="compare with another source tree, alternating (see above)")
    ap.add_argument(
        "--this-set", action="append", default=[], metavar="KEY=VALUE", help="with --against: this tree only"
    )
    ap.add_argument("--repeats", type=int, default=3, help="with --against: rounds of alternation")
    ap.add_argument("--versus", action="append", default=[], metavar="KEY=VALUE", help="see above (repeatable)")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker(args)
        return
    if args.against:
        against(args)
        return
    if args.profile:
        profile(args)
        return
    if args.versus:
        versus(args)
        return

    scene, cam, T, n, renderer, spacing, tiles = _prepare(args)
    spps = [int(s) for s in args.spp.split(",")] if args.spp else [scene.render.spp]
    t0 = time.perf_counter()
    _load_tile(renderer, scene, tiles[0][1], spacing)
    t_tile = time.perf_counter() - t0
    frames = tiles[0][0][:n]
    t = time.perf_counter()
    ref = _reference(renderer, scene, T[0], args.ref_spp)
    t_ref = time.perf_counter() - t
    # PSNR in the 8-bit DN scale of the sequence's automatic exposure (peak 255).
    gain = exposure_gain(ref, scene.sensor.full_well_e, scene.sensor.target_percentile, scene.sensor.target_level)
    to_dn = gain / scene.sensor.full_well_e * 255.0
    h, w = ref.shape
    sl = (slice(int(0.1 * h), int(0.9 * h)), slice(int(0.1 * w), int(0.9 * w)))
    rows = []
    for spp in spps:
        renderer.render(T[0], _leds(scene, T[0]), spp, seed=0)  # warm-up: JIT compilation
        times, cpu = [], []
        rad0 = None
        for i in frames:
            t, c = time.perf_counter(), time.process_time()
            rad = renderer.render(T[i], _leds(scene, T[i]), spp, seed=_frame_seed(scene.seed, i))
            times.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
            if rad0 is None:
                rad0 = rad
        assert rad0 is not None  # frames holds at least frame 0
        mse = float(np.mean(((rad0[sl] - ref[sl]) * to_dn) ** 2))
        psnr = 10 * np.log10(255.0**2 / mse)
        rows.append(
            {
                "spp": renderer.effective_spp(spp),
                "frame_s_median": round(float(np.median(times)), 3),
                "frames_per_s": round(1.0 / float(np.median(times)), 2),
                # CPU seconds of all render threads: wall time on an otherwise idle machine
                # is about this divided by the number of cores.
                "cpu_s_per_frame_median": round(float(np.median(cpu)), 3),
                "psnr_db_central80": round(float(psnr), 2),
            }
        )
        print(json.dumps(rows[-1]), flush=True)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    out = {
        "scene": scene.name,
        "size": f"{cam.width_px}x{cam.height_px}",
        "frames_timed": len(frames),
        "leds": int(len(_leds(scene, T[0]).positions_mm)),
        "floor_tile_build_s": round(t_tile, 2),
        "tile_vertices_mm_spacing": spacing,
        "results": rows,
        "ref_spp": args.ref_spp,
        "ref_render_s": round(t_ref, 1),
        "peak_rss_mb": round(peak_mb),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores",
        "load_average_1min_at_end": round(os.getloadavg()[0], 2),
        "backend": backend_info(),
    }
    print(json.dumps(out, indent=2))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=2)


def versus(args) -> None:
    """The scene against the scene with ``--versus`` overrides, alternating in one process (see the module doc)."""
    scene, cam, T, n, renderer, spacing, tiles = _prepare(args)
    other = load_scene(args.scene, parse_set_args(args.set + args.versus))
    if other.floor != scene.floor:
        raise SystemExit(f"--versus {' '.join(args.versus)}: changes the floor; only lights and render settings")
    _load_tile(renderer, scene, tiles[0][1], spacing)
    frames = tiles[0][0][1:n]
    cpu: dict[str, list[float]] = {"base": [], "versus": []}
    for r in range(args.repeats):
        for name, sc in (("base", scene), ("versus", other)):
            renderer.render(T[0], _leds(sc, T[0]), sc.render.spp, seed=0)  # JIT compilation (a kernel per scene)
            for i in frames:
                c = time.process_time()
                renderer.render(T[i], _leds(sc, T[i]), sc.render.spp, seed=_frame_seed(sc.seed, i))
                cpu[name].append(time.process_time() - c)
        print(f"round {r}: " + ", ".join(f"{k} {np.median(v[-len(frames) :]):.3f} CPU s" for k, v in cpu.items()))
    base, vs = float(np.median(cpu["base"])), float(np.median(cpu["versus"]))
    print(
        f"{scene.name} {cam.width_px}x{cam.height_px}, {renderer.effective_spp(scene.render.spp)} spp: "
        f"{base:.3f} CPU s per frame; with {' '.join(args.versus)}: {vs:.3f} ({vs / base - 1:+.1%}); "
        f"{len(frames)} frames x {args.repeats} rounds each, load {os.getloadavg()[0]:.1f}, "
        f"{platform.machine()}, {os.cpu_count()} cores"
    )


def _reference(renderer, scene, T_world_cam: np.ndarray, ref_spp: int) -> np.ndarray:
    """Radiance (H, W) of pose ``T_world_cam`` averaged over ``ref_spp`` samples: batches of 16 spp
    with independent sample patterns (seeds 10000, 10001, ...)."""
    batch, n_batches = 16, max(1, ref_spp // 16)
    acc = np.zeros((renderer.camera.height_px, renderer.camera.width_px), dtype=np.float64)
    for b in range(n_batches):
        acc += renderer.render(T_world_cam, _leds(scene, T_world_cam), batch, seed=10_000 + b)
    return acc / n_batches


def worker(args) -> None:
    """One tree's side of ``--against``: load the scene's first tile, then answer JSON commands on stdin
    (``{"frames": [...]}``: render them, reply CPU and wall seconds; ``{"save": PATH}``: frame 0 to
    PATH.npy; ``{"ref": PATH, "spp": N}``: an N-spp reference of frame 0 to PATH.npy)."""
    import sys

    scene, cam, T, n, renderer, spacing, tiles = _prepare(args)
    t = time.perf_counter()
    _load_tile(renderer, scene, tiles[0][1], spacing)
    spp = scene.render.spp
    renderer.render(T[0], _leds(scene, T[0]), spp, seed=0)  # JIT compilation
    print(json.dumps({"tile_s": time.perf_counter() - t, "spp": renderer.effective_spp(spp)}), flush=True)
    for line in sys.stdin:
        cmd = json.loads(line)
        if "frames" in cmd:
            wall, cpu = [], []
            for i in cmd["frames"]:
                t, c = time.perf_counter(), time.process_time()
                renderer.render(T[i], _leds(scene, T[i]), spp, seed=_frame_seed(scene.seed, i))
                wall.append(time.perf_counter() - t)
                cpu.append(time.process_time() - c)
            reply: dict = {"wall": wall, "cpu": cpu}
        elif "save" in cmd:
            np.save(cmd["save"], renderer.render(T[0], _leds(scene, T[0]), spp, seed=_frame_seed(scene.seed, 0)))
            reply = {}
        else:
            t = time.perf_counter()
            np.save(cmd["ref"], _reference(renderer, scene, T[0], int(cmd["spp"])))
            reply = {"ref_s": time.perf_counter() - t}
        print(json.dumps(reply), flush=True)


def against(args) -> None:
    """This tree against ``args.against``, alternating over the same frames in one run (see the module doc)."""
    import subprocess
    import sys
    from pathlib import Path

    here = str(Path(__file__).resolve().parents[1] / "src")
    common = [sys.executable, __file__, "--worker", "--scene", args.scene, "--frames", str(args.frames)]
    common += [f"--set={s}" for s in args.set]
    procs = {}
    for name, src, extra in (("against", args.against, []), ("this", here, [f"--set={s}" for s in args.this_set])):
        env = {"FLOORSIM_SCENES": str(Path(here).parent / "scenes"), **os.environ, "PYTHONPATH": src}
        procs[name] = subprocess.Popen(
            common + extra, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
        )
    info = {name: json.loads(p.stdout.readline()) for name, p in procs.items()}  # type: ignore[union-attr]

    def ask(name: str, cmd: dict) -> dict:
        p = procs[name]
        p.stdin.write(json.dumps(cmd) + "\n")  # type: ignore[union-attr]
        p.stdin.flush()  # type: ignore[union-attr]
        return json.loads(p.stdout.readline())  # type: ignore[union-attr]

    frames = list(range(1, max(2, args.frames)))
    times: dict[str, dict[str, list[float]]] = {name: {"cpu": [], "wall": []} for name in procs}
    for r in range(args.repeats):
        for name in procs:
            got = ask(name, {"frames": frames})
            times[name]["cpu"] += got["cpu"]
            times[name]["wall"] += got["wall"]
        print(
            f"round {r}: " + ", ".join(f"{k} {np.median(v['cpu'][-len(frames) :]):.3f} CPU s" for k, v in times.items())
        )
    with tempfile.TemporaryDirectory(prefix="render-bench-") as tmp:
        for name in procs:
            ask(name, {"save": f"{tmp}/{name}.npy"})
        ref_s = ask("against", {"ref": f"{tmp}/ref.npy", "spp": args.ref_spp})["ref_s"]
        ref = np.load(f"{tmp}/ref.npy")
        images = {name: np.load(f"{tmp}/{name}.npy") for name in procs}
    for p in procs.values():
        p.stdin.close()  # type: ignore[union-attr]
        p.wait()
    scene = load_scene(args.scene, parse_set_args(args.set))
    gain = exposure_gain(ref, scene.sensor.full_well_e, scene.sensor.target_percentile, scene.sensor.target_level)
    to_dn = gain / scene.sensor.full_well_e * 255.0
    h, w = ref.shape
    sl = (slice(int(0.1 * h), int(0.9 * h)), slice(int(0.1 * w), int(0.9 * w)))
    out: dict = {"scene": scene.name, "size": f"{w}x{h}", "frames_per_round": len(frames), "rounds": args.repeats}
    for name in procs:
        mse = float(np.mean(((images[name][sl] - ref[sl]) * to_dn) ** 2))
        out[name] = {
            "src": args.against if name == "against" else here,
            "set": args.set + (args.this_set if name == "this" else []),
            "spp": info[name]["spp"],
            "cpu_s_per_frame_median": round(float(np.median(times[name]["cpu"])), 3),
            "wall_s_per_frame_median": round(float(np.median(times[name]["wall"])), 3),
            "psnr_db_central80": round(10 * float(np.log10(255.0**2 / mse)), 2),
        }
    out["ratio_cpu"] = round(out["against"]["cpu_s_per_frame_median"] / out["this"]["cpu_s_per_frame_median"], 2)
    out["ratio_wall"] = round(out["against"]["wall_s_per_frame_median"] / out["this"]["wall_s_per_frame_median"], 2)
    out.update(
        ref_spp=args.ref_spp,
        ref_render_s=round(ref_s, 1),
        machine=f"{platform.machine()}, {os.cpu_count()} cores",
        load_average_1min_at_end=round(os.getloadavg()[0], 2),
    )
    print(json.dumps(out, indent=2))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=2)


def _prepare(args):
    """The scene (``--set`` overrides through the one parser), its camera, the poses ``T``
    (F, 4, 4) mm, the frame count ``n`` used, a renderer, the floor spacing and the plan's tiles."""
    scene = load_scene(args.scene, parse_set_args(args.set))
    traj = _trajectory_of(scene)
    cam = scene.camera_model()
    T = traj.T_world_cam
    n = min(args.frames, traj.frame_count)
    spacing = scene.floor_spacing_mm()
    tiles = plan_tiles(T[:n], cam, scene.floor.tile_length_mm, 2.0 + 2 * spacing)
    return scene, cam, T, n, FloorRenderer(cam), spacing, tiles


def profile(args) -> None:
    """Median wall and CPU seconds per frame of each stage of a frame, at the scene's spp.

    primary: primary rays and the albedo lookup (every LED off); shading: the LED sums
    (shadows off) less primary; shadow rays: the full render less shading; sensor: the
    capture of a frame (shot and read noise, quantisation); png: encoding and writing it;
    tracing: a full render of an 8 x 8 camera (the Python and JIT-tracing cost of a frame,
    which does not grow with the image).
    """
    scene, cam, T, n, renderer, spacing, tiles = _prepare(args)
    spp = int(args.spp.split(",")[0]) if args.spp else scene.render.spp
    _load_tile(renderer, scene, tiles[0][1], spacing)

    def timed(fn) -> tuple[float, float]:
        fn(0)  # warm-up: JIT compilation
        wall, cpu = [], []
        for i in range(1, n):
            t, c = time.perf_counter(), time.process_time()
            fn(i)
            wall.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
        return float(np.median(wall)), float(np.median(cpu))

    def dark(i):
        leds = _leds(scene, T[i])
        return dataclasses.replace(leds, intensity=np.zeros_like(leds.intensity))

    stages = {
        "primary": timed(lambda i: renderer.render(T[i], dark(i), spp, seed=i, ambient=1.0)),
        "no_shadows": timed(lambda i: renderer.render(T[i], _leds(scene, T[i]), spp, seed=i, shadows=False)),
        "full": timed(lambda i: renderer.render(T[i], _leds(scene, T[i]), spp, seed=i)),
    }
    rad = renderer.render(T[0], _leds(scene, T[0]), spp, seed=0)
    sensor = SensorModel(
        exposure_gain(rad, scene.sensor.full_well_e, 99.0, 0.8), scene.sensor.full_well_e, 5.0, True, 8
    )
    stages["sensor"] = timed(lambda i: sensor.capture(rad, 0, i))
    dn = sensor.capture(rad, 0, 0)
    with tempfile.TemporaryDirectory() as tmp:
        stages["png"] = timed(lambda i: write_png(f"{tmp}/{i:06d}.png", dn))
    small = FloorRenderer(type(cam).from_sensor(8, 8, 7.4 * cam.width_px / 8, scene.camera.focal_length_mm))
    small.scene, small.origin_mm, small.shadow_offset_mm = renderer.scene, renderer.origin_mm, renderer.shadow_offset_mm
    small._grid = renderer._grid
    stages["tracing"] = timed(lambda i: small.render(T[i], _leds(scene, T[i]), spp, seed=i))
    rows = {
        "primary rays + albedo": stages["primary"],
        "LED shading": tuple(a - b for a, b in zip(stages["no_shadows"], stages["primary"])),
        "shadow rays": tuple(a - b for a, b in zip(stages["full"], stages["no_shadows"])),
        "sensor model": stages["sensor"],
        "PNG writing": stages["png"],
        "Python + JIT tracing (8x8 render)": stages["tracing"],
        "render total": stages["full"],
    }
    print(f"{scene.name} {cam.width_px}x{cam.height_px}, {renderer.effective_spp(spp)} spp, {n - 1} frames timed")
    for name, (wall, cpu) in rows.items():
        print(f"  {name:36s} {wall:7.3f} s wall  {cpu:7.3f} s CPU")
    print(f"  load average {os.getloadavg()[0]:.1f}; {platform.machine()}, {os.cpu_count()} cores")


if __name__ == "__main__":
    main()

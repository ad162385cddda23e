"""``floorsim render SCENE -o OUT``: render a scene into a sequence folder."""

from __future__ import annotations

import time

from floorvo.cli.common import add_output_argument, parse_set_args, progress_callback


def add_parser(sub) -> None:
    p = sub.add_parser("render", help="render a scene into a sequence folder (resumable)")
    p.add_argument("scene", help="scene file, or the name of a shipped scene (floorsim list)")
    add_output_argument(p, "output sequence folder")
    p.add_argument("--frames", type=int, help="render only the first N frames")
    p.add_argument("--scale", type=float, help="resolution scale (0.25 = quarter size; intrinsics scaled to match)")
    p.add_argument("--spp", type=int, help="samples per pixel")
    p.add_argument("--seed", type=int, help="scene seed (floor, pixel jitter, sensor noise)")
    p.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        help="override a scene key, e.g. camera.height_mm=80 (floorsim list --scene-keys)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace a different sequence already in the output folder")
    p.set_defaults(func=run)


def run(args) -> int:
    # Imported when the command runs, as in every command module: `floorsim --help` stays
    # quick (these pull in numpy, OpenCV and the scene model).
    from floorsim.scene import load_scene
    from floorsim.simulate import render_sequence
    from floorvo.sequence import Sequence

    scene = load_scene(args.scene, parse_set_args(args.set))
    t0 = time.perf_counter()
    with progress_callback("render", "frame") as cb:
        root = render_sequence(
            scene,
            args.output,
            frames=args.frames,
            scale=args.scale,
            spp=args.spp,
            seed=args.seed,
            overwrite=args.overwrite,
            on_frame=cb,
        )
    seq = Sequence.open(root)
    dt = time.perf_counter() - t0
    print(
        f"{scene.name}: {seq.frame_count} frames {seq.camera.width_px}x{seq.camera.height_px} "
        f"({seq.meta['bit_depth']}-bit) in {dt:.1f} s -> {root}"
    )
    return 0

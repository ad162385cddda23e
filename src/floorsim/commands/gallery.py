"""``floorsim gallery -o DIR``: a labelled contact sheet of every material and lighting variant."""

from __future__ import annotations

from floorvo.cli.common import add_output_argument, progress_callback


def add_parser(sub) -> None:
    p = sub.add_parser("gallery", help="render one frame per material and lighting variant as a contact sheet PNG")
    add_output_argument(p, "output folder (gallery.png, frames/)")
    p.add_argument("--base", default="demo", help="base scene (default: demo)")
    p.add_argument("--scale", type=float, default=1.0, help="resolution scale of the base scene camera")
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace tiles rendered with other settings (another --scale or --base) in the output folder",
    )
    p.set_defaults(func=run)


def run(args) -> int:
    from floorsim.gallery import render_gallery  # when the command runs: keeps `floorsim --help` quick

    with progress_callback("gallery", "tile") as cb:
        path = render_gallery(args.output, args.base, args.scale, on_tile=cb, overwrite=args.overwrite)
    print(f"gallery: {path}")
    return 0

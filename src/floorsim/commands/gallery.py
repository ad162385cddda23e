"""``floorsim gallery -o DIR``: a labelled contact sheet of every material and lighting variant."""

from __future__ import annotations


def add_parser(sub) -> None:
    p = sub.add_parser("gallery", help="render one frame per material and lighting variant as a contact sheet PNG")
    p.add_argument("-o", "--out", required=True, help="output folder (gallery.png, frames/)")
    p.add_argument("--base", default="demo", help="base scene (default: demo)")
    p.add_argument("--scale", type=float, default=1.0, help="resolution scale of the base scene camera")
    p.set_defaults(func=run)


def run(args) -> int:
    from floorsim.gallery import render_gallery
    from floorvo.cli.common import progress_callback

    with progress_callback("gallery", "tile") as cb:
        path = render_gallery(args.out, args.base, args.scale, on_tile=cb)
    print(f"gallery: {path}")
    return 0

"""``floorsim export SEQ --format rosbag2|euroc -o OUT``: a sequence for other tools."""

from __future__ import annotations

from floorvo.cli.common import add_output_argument


def add_parser(sub) -> None:
    p = sub.add_parser("export", help="export a sequence to a ROS 2 bag or the EuRoC/ASL layout")
    p.add_argument("sequence", help="sequence folder")
    p.add_argument("--format", required=True, choices=["rosbag2", "euroc"])
    add_output_argument(p, "output path (must not exist yet)")
    p.set_defaults(func=run)


def run(args) -> int:
    from floorsim.export import export_sequence  # when the command runs: keeps `floorsim --help` quick

    out = export_sequence(args.sequence, args.format, args.output)
    print(f"exported {args.sequence} as {args.format} -> {out}")
    return 0

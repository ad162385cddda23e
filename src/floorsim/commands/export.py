"""``floorsim export SEQ --format rosbag2|euroc -o OUT``: a sequence for other tools."""

from __future__ import annotations


def add_parser(sub) -> None:
    p = sub.add_parser("export", help="export a sequence to a ROS 2 bag or the EuRoC/ASL layout")
    p.add_argument("sequence", help="sequence folder")
    p.add_argument("--format", required=True, choices=["rosbag2", "euroc"])
    p.add_argument("-o", "--out", required=True, help="output path (must not exist yet)")
    p.set_defaults(func=run)


def run(args) -> int:
    from floorsim.export import export_sequence

    out = export_sequence(args.sequence, args.format, args.out)
    print(f"exported {args.sequence} as {args.format} -> {out}")
    return 0

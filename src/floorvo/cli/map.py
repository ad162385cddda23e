"""``floorvo map SEQ -o MAP``: build a keyframe global map from a sequence (paper 003)."""

from __future__ import annotations

from floorvo.cli.common import add_output_argument, parse_set_args, progress_callback
from floorvo.locking import lock_folder


def add_parser(sub) -> None:
    p = sub.add_parser(
        "map",
        help="build a keyframe global map of the floor from a sequence (paper 003)",
        description="Extract keyframes by content-based similarity (50 % of the maximum over the next 50 frames), "
        "chain their poses (eq. 24 of paper 003) and write MAP/map.json and MAP/keyframes.npz. The map's world frame "
        "is the sequence's: with ground truth (a surveyed mapping run) the keyframes take their ground-truth poses "
        "and the chain's disagreement is recorded (--set poses=chain keeps the chained poses, anchored at the first "
        "ground-truth pose).",
    )
    p.add_argument("sequence", help="mapping sequence folder")
    add_output_argument(p, "map folder to write")
    p.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        help="parameter, e.g. keyframes.window=50, poses=chain (floorvo list --config map shows them all)",
    )
    p.set_defaults(func=run)


def run(args) -> int:
    from floorvo.mapping.map import MapConfig, build_map, save_map

    cfg = MapConfig.from_overrides(parse_set_args(args.set))
    with lock_folder(args.output, "map folder"):  # a second `floorvo map` into it is refused before it builds
        with progress_callback("map") as cb:
            m = build_map(args.sequence, cfg, on_progress=cb)
        out = save_map(m, args.output)
    print(
        f"map: {m.n_keyframes} keyframes of {m.n_mapping_frames} frames ({100 * m.keyframe_fraction:.1f} %), poses: {m.pose_source} -> {out}"
    )
    if m.chain_vs_groundtruth:
        c = m.chain_vs_groundtruth
        print(
            f"map: eq. (24) chain against ground truth: max {c['max_mm']:.3f} mm, rms {c['rms_mm']:.3f} mm, "
            f"max yaw {c['max_yaw_rad']:.2e} rad"
        )
    return 0

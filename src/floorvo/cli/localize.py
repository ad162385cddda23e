"""``floorvo localize SEQ --map MAP -o RUN``: place every frame of a sequence on a map (paper 003)."""

from __future__ import annotations

import sys

from floorvo.cli.common import add_output_argument, parse_set_args, progress_callback


def add_parser(sub) -> None:
    p = sub.add_parser(
        "localize",
        help="localise each frame of a sequence against a keyframe map (relocalisation, paper 003)",
        description="Each frame is localised against the map on its own (no earlier pose is used, so kidnapping is "
        "recovered on the first frame after landing); with --odometry NAME, that estimator bridges frames the map "
        "does not place. Writes RUN/trajectory.txt (TUM, metres, map poses), timing.csv and result.json, as "
        "`floorvo run`; frames not localised are left out and listed with reasons in result.json.",
    )
    p.add_argument("sequence", help="sequence folder")
    p.add_argument("--map", required=True, help="map folder written by `floorvo map`")
    add_output_argument(p, "run folder")
    p.add_argument("--odometry", default="none", help="estimator between map fixes (floorvo list), default none")
    p.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        help="localiser setting, e.g. fix_every=4, retrieval=bow (floorvo list --config localize shows them all)",
    )
    p.set_defaults(func=run)


def run(args) -> int:
    from floorvo.mapping.localize_run import localize_sequence

    with progress_callback("localize") as cb:
        res = localize_sequence(
            args.sequence,
            args.map,
            args.output,
            odometry=args.odometry,
            overrides=parse_set_args(args.set),
            on_frame=cb,
        )
    placed = res["ok"] + res["status_counts"]["init"]
    print(
        f"localize: {placed} of {res['frames']} frames placed ({res['map_fixes']} map fixes), "
        f"{res['median_total_ms']:.1f} ms/frame median -> {res['run_dir']}"
    )
    if placed == 0:  # as `floorvo run` when no frame is tracked: the run folder says why per frame
        print(f"floorvo: error: localize placed no frame on the map (see {res['run_dir']}/timing.csv)", file=sys.stderr)
        return 1
    return 0

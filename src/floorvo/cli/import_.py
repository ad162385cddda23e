"""``floorvo import SOURCE -o SEQ``: a recording (images, video, EuRoC, ROS 2 bag) as a sequence folder."""

from __future__ import annotations

import argparse

from floorvo.cli.common import add_output_argument, parse_name_values
from floorvo.errors import ConfigError

__all__ = ["add_parser", "run", "parse_floats", "parse_topics"]


def add_parser(sub) -> None:
    from floorvo.importers import READERS
    from floorvo.importers.rosbag2 import ROLES
    from floorvo.importers.times import TIME_UNITS_S

    p = sub.add_parser(
        "import",
        help="turn a recording (image folder, video, EuRoC folder, ROS 2 bag) into a sequence folder",
        description="Write SOURCE as a sequence folder (sequence.json, cam0/, timestamps.txt, groundtruth.txt) "
        "that `floorvo run` and `floorvo score` read. The format is detected from SOURCE unless --format is given; "
        "the camera comes from the source (EuRoC sensor.yaml, ROS camera_info) unless --camera or --fx/--fy/--cx/--cy "
        "give it.",
    )
    p.add_argument("source", help="image folder or list file, video file, EuRoC folder (with mav0/), ROS 2 bag folder")
    add_output_argument(p, "sequence folder to write")
    p.add_argument("--format", choices=sorted(READERS), default=None, help="source format (default: detected)")
    cam = p.add_argument_group("camera (default: the source's calibration)")
    cam.add_argument(
        "--camera", metavar="FILE", default=None, help="ROS camera_info, OpenCV calibration or Kalibr camchain YAML"
    )
    for name in ("fx", "fy", "cx", "cy"):
        cam.add_argument(f"--{name}", type=float, default=None, metavar="PX", help=f"{name} in pixels")
    cam.add_argument("--distortion", metavar="K1,K2,P1,P2[,K3]", default=None, help="OpenCV distortion coefficients")
    p.add_argument("--height-mm", type=float, default=None, help="camera height above the floor, mm (rig.height_mm)")
    p.add_argument(
        "--timestamps",
        metavar="FILE",
        default=None,
        help="frame times, one line per frame (first number of each line); overrides the source's",
    )
    p.add_argument("--time-unit", choices=list(TIME_UNITS_S), default="s", help="unit of --timestamps (default s)")
    p.add_argument(
        "--fps",
        type=float,
        default=None,
        help="frame rate (Hz) of a source without frame times, or of a video whose times do not increase (i / FPS)",
    )
    p.add_argument(
        "--groundtruth", metavar="FILE", default=None, help="T_world_cam0 as TUM (s, m) or EuRoC CSV (ns, m)"
    )
    p.add_argument("--flatfield", metavar="FILE", default=None, help="flat-field image of cam0, copied to calib/")
    p.add_argument(
        "--height-file",
        metavar="FILE",
        default=None,
        help="per-frame camera height (mm) from a range sensor: CSV frame,height_mm (written to height.csv)",
    )
    p.add_argument(
        "--height-noise-mm",
        type=float,
        default=None,
        metavar="MM",
        help="standard deviation of each reading of the height signal, mm (the range sensor's datasheet; "
        "rig.height_noise_mm): steps it leaves uncertain are lost",
    )
    p.add_argument(
        "--readout-ms",
        type=float,
        default=None,
        metavar="MS",
        help="a rolling shutter's readout, first row to last, ms (sequence.json's sensor.readout_ms; the frame "
        "times are taken as the centre row's): the estimators undo it in each step",
    )
    p.add_argument(
        "--attitude-file",
        metavar="FILE",
        default=None,
        help="per-frame camera roll and pitch against gravity (rad) from an IMU: CSV frame,roll_rad,pitch_rad "
        "(written to attitude.csv; README, 'A measured attitude')",
    )
    p.add_argument(
        "--topic",
        action="append",
        metavar="ROLE=NAME",
        default=None,
        help=f"ROS 2 bag topic of a role ({', '.join(ROLES)}); repeatable",
    )
    p.add_argument(
        "--left-only",
        action="store_true",
        help="import the left camera alone, leaving out a right one (EuRoC cam1, a bag's right topic)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace a different sequence already at --output")
    p.set_defaults(func=run)


def parse_floats(text: str | None, what: str) -> tuple[float, ...] | None:
    """``"a,b,c"`` -> floats; one-line :class:`ConfigError` naming ``what`` otherwise."""
    if text is None:
        return None
    try:
        return tuple(float(v) for v in text.split(","))
    except ValueError:
        raise ConfigError(f"{what} {text!r}: expected numbers separated by commas") from None


def parse_topics(items: list[str] | None) -> dict[str, str]:
    """``["image=/cam0/image_raw", ...]`` -> ``{"image": "/cam0/image_raw"}``."""
    return parse_name_values(items, "--topic", "ROLE=NAME, e.g. image=/cam0/image_raw")


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from floorvo.importers import ImportOptions, import_sequence
    from floorvo.importers.camera_files import read_camera_file
    from floorvo.importers.times import read_groundtruth_file, read_timestamps_file
    from floorvo.sequence import read_attitude_csv, read_height_csv

    flags = (args.fx, args.fy, args.cx, args.cy)
    times = None if args.timestamps is None else read_timestamps_file(args.timestamps, args.time_unit)
    options = ImportOptions(
        calibration=None if args.camera is None else read_camera_file(args.camera),
        intrinsics=None if all(v is None for v in flags) else flags,
        distortion=parse_floats(args.distortion, "--distortion"),
        height_mm=args.height_mm,
        timestamps_s=None if times is None else times.seconds,
        timestamps_ns=None if times is None else times.ns,
        groundtruth=None if args.groundtruth is None else read_groundtruth_file(args.groundtruth),
        fps=args.fps,
        flatfield=None if args.flatfield is None else Path(args.flatfield),
        height_signal_mm=None if args.height_file is None else read_height_csv(args.height_file),
        height_noise_mm=args.height_noise_mm,
        readout_ms=args.readout_ms,
        attitude_signal_rad=None if args.attitude_file is None else read_attitude_csv(args.attitude_file),
        topics=parse_topics(args.topic),
        left_only=args.left_only,
        overwrite=args.overwrite,
    )
    res = import_sequence(args.source, args.output, args.format, options)
    extras = [x for x, on in (("stereo", res.stereo), ("depth", res.depth)) if on]
    gt = f"{res.groundtruth_poses} ground-truth poses" if res.groundtruth_poses else "no ground truth"
    print(
        f"{res.format}: {res.frames} frames {res.width_px}x{res.height_px} {res.bit_depth}-bit"
        f"{' ' + ' '.join(extras) if extras else ''}, {res.duration_s:.3f} s at {res.fps:.4g} fps, {gt} -> {res.sequence}"
    )
    if res.height_mm is None:
        print("note: no --height-mm given; set rig.height_mm in sequence.json before `floorvo run`")
    return 0

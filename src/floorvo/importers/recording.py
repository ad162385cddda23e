"""What an importer reads from a recording, and the one place it becomes a sequence folder.

Every format reader (:mod:`.images`, :mod:`.video`, :mod:`.euroc`, :mod:`.rosbag2`) returns
a :class:`Recording`: the frames (read lazily, so a long video is never held in memory),
their timestamps as the source states them, and whatever calibration and ground truth the
source carries. :func:`write_recording` resolves what the user gave on the command line
against it (their camera, height, timestamps and ground truth win) and writes the
sequence through :class:`floorvo.sequence.SequenceWriter`, the writer floorsim's renders
use, so every file is written atomically and an interrupted import resumes.
"""

from __future__ import annotations

import logging
import os
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from floorvo import __version__
from floorvo.camera import CAMERA_HEIGHT_RANGE_MM, height_problem
from floorvo.errors import ConfigError, SequenceError, shown, shown_number
from floorvo.importers.camera_files import CameraCalibration, camera_from_flags
from floorvo.io import IMAGE_FORMATS, read_image
from floorvo.metrics import associate
from floorvo.sequence import (
    GROUNDTRUTH_MAX_DIFF_S,
    SequenceWriter,
    check_attitude,
    check_groundtruth_times,
    check_heights,
    check_timestamps,
)
from floorvo.sequence_meta import MAX_FPS_HZ, MIN_FPS_HZ, ROW_TIME_CONVENTION

__all__ = [
    "FrameImages",
    "Recording",
    "ImportOptions",
    "ImportResult",
    "to_mono",
    "read_image_file",
    "size_of",
    "natural_key",
    "median_rate_hz",
    "write_recording",
]

log = logging.getLogger(__name__)


@dataclass
class FrameImages:
    """One frame of a recording: ``image`` (H, W) uint8/uint16 mono, optional right image and depth (mm)."""

    image: np.ndarray
    image_right: np.ndarray | None = None
    depth_mm: np.ndarray | None = None


@dataclass
class Recording:
    """A source as a reader found it.

    Attributes
    ----------
    format:
        Reader name (``images``, ``video``, ``euroc``, ``rosbag2``).
    source:
        What was read.
    frame_count:
        Number of frames ``frames()`` yields.
    size_px:
        ``(width_px, height_px)`` of every frame.
    bit_depth:
        8 or 16: the pixel depth of every frame.
    frames:
        Called once, yields ``frame_count`` :class:`FrameImages` in time order.
    timestamps_s:
        (frame_count,) times the source states (s), or None when it states none.
    timestamps_ns:
        The same times in integer nanoseconds where the source stamps so (EuRoC, a ROS bag), or
        None: ``timestamps.txt`` gets them exactly (a float of seconds holds a Unix time only to
        about 240 ns), and an export gives back the source's stamps.
    fps:
        Nominal frame rate the source states (Hz), or None.
    calibration:
        Camera calibration the source carries, or None.
    has_right, has_depth:
        Whether ``frames()`` fills ``image_right`` / ``depth_mm``.
    groundtruth:
        ``(timestamps_s (M,), T_world_cam0 (M, 4, 4) mm)`` the source carries, or None.
    details:
        Provenance written under ``source`` in ``sequence.json`` (topics, files).
    height_mm:
        The camera height above the floor (mm) the source states, or None.
    flatfields:
        Flat-field frames the source carries, by camera (``cam0``, ``cam1``).
    height_signal_mm:
        (frame_count,) measured camera heights (mm, NaN where none) the source carries, or None.
        ``height_noise_mm``: the standard deviation of each reading, where the source states it.
    attitude_signal_rad:
        (frame_count, 2) measured camera roll and pitch (rad, NaN where none) the source
        carries, or None.
    readout_ms:
        A rolling shutter's readout (ms) the source states (a ``floorsim export``'s sidecar), or None.
    """

    format: str
    source: Path
    frame_count: int
    size_px: tuple[int, int]
    bit_depth: int
    frames: Callable[[], Iterator[FrameImages]]
    timestamps_s: np.ndarray | None = None
    timestamps_ns: np.ndarray | None = None
    fps: float | None = None
    calibration: CameraCalibration | None = None
    has_right: bool = False
    has_depth: bool = False
    groundtruth: tuple[np.ndarray, np.ndarray] | None = None
    details: dict = field(default_factory=dict)
    height_mm: float | None = None
    flatfields: dict[str, np.ndarray] = field(default_factory=dict)
    height_signal_mm: np.ndarray | None = None
    height_noise_mm: float | None = None
    attitude_signal_rad: np.ndarray | None = None
    readout_ms: float | None = None


@dataclass(frozen=True)
class ImportOptions:
    """What the user gives beside the source (the flags of ``floorvo import``).

    Attributes
    ----------
    calibration:
        The camera from ``--camera FILE``; overrides the source's.
    intrinsics:
        ``(fx, fy, cx, cy)`` px from ``--fx --fy --cx --cy`` (the image size is the frames');
        overrides the source's camera. ``distortion``: its k1, k2, p1, p2[, k3].
    height_mm:
        Camera height above the floor (mm); written as ``rig.height_mm``.
    timestamps_s:
        Per-frame times (s) from a timestamps file; override the source's. ``timestamps_ns``:
        the same in integer nanoseconds where the file holds them so (written exactly).
    groundtruth:
        ``(timestamps_s, T_world_cam0 mm)`` from a ground-truth file; overrides the source's.
    fps:
        Frame rate (Hz) for sources without times (an image folder); nominal otherwise.
    flatfield:
        A flat-field image of cam0 (same rig over a flat uniform floor), copied to ``calib/``.
    height_signal_mm:
        Per-frame camera height above the floor (mm, NaN where none) from a range sensor,
        written to ``height.csv`` (one per frame). ``height_noise_mm``: the standard deviation of
        each of its readings (a range sensor's datasheet figure), written as
        ``rig.height_noise_mm``; the runner loses the steps it leaves uncertain.
    readout_ms:
        A rolling shutter's readout time, first row to last (ms), written as ``sensor.readout_ms``
        (:class:`floorvo.sequence_meta.SensorBlock`: the frame's time is its centre row's); at
        most the shortest frame interval. None: a global shutter.
    attitude_signal_rad:
        Per-frame camera roll and pitch against gravity (rad, a row of NaN where none) from an
        IMU, (frame_count, 2), written to ``attitude.csv`` (:mod:`floorvo.sequence` defines the angles).
    topics:
        ROS 2 bag topics by role (``image``, ``right``, ``depth``, ``camera_info``,
        ``right_camera_info``, ``groundtruth``); roles not given are found by type and name.
    left_only:
        Import the left camera alone: leave out a right camera the source has (EuRoC ``cam1``,
        a bag's ``right`` topic). Without it a right camera whose frames do not pair with the
        left's is refused.
    overwrite:
        Replace an existing, different sequence at the output path.
    """

    calibration: CameraCalibration | None = None
    intrinsics: tuple[float | None, float | None, float | None, float | None] | None = None
    distortion: tuple[float, ...] | None = None
    height_mm: float | None = None
    timestamps_s: np.ndarray | None = None
    timestamps_ns: list[int] | None = None
    groundtruth: tuple[np.ndarray, np.ndarray] | None = None
    fps: float | None = None
    flatfield: Path | None = None
    height_signal_mm: np.ndarray | None = None
    height_noise_mm: float | None = None
    readout_ms: float | None = None
    attitude_signal_rad: np.ndarray | None = None
    topics: dict[str, str] = field(default_factory=dict)
    left_only: bool = False
    overwrite: bool = False


@dataclass(frozen=True)
class ImportResult:
    """Summary of an import: the sequence folder and what it holds."""

    sequence: Path
    format: str
    frames: int
    width_px: int
    height_px: int
    bit_depth: int
    fps: float
    duration_s: float
    stereo: bool
    depth: bool
    groundtruth_poses: int
    height_mm: float | None


def natural_key(name: str) -> list:
    """Sort key that orders ``img_2`` before ``img_10`` (digit runs compared as numbers)."""
    return [(0, int(t), "") if t.isdigit() else (1, 0, t.lower()) for t in re.split(r"(\d+)", name) if t]


def to_mono(image: np.ndarray, what: str) -> np.ndarray:
    """(H, W) uint8/uint16 of a mono, BGR or BGRA image as OpenCV decodes it (colour: luma, BT.601)."""
    img = np.asarray(image)
    if img.dtype not in (np.uint8, np.uint16):
        raise SequenceError(f"{what}: {img.dtype} pixels are not supported (need 8- or 16-bit integers)")
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    elif img.ndim == 3 and img.shape[2] == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    elif img.ndim == 3 and img.shape[2] == 4:
        img = cv2.cvtColor(img, cv2.COLOR_BGRA2GRAY)
    elif img.ndim != 2:
        raise SequenceError(f"{what}: image of shape {img.shape} is neither mono nor colour")
    return np.ascontiguousarray(img)


def read_image_file(
    path: str | os.PathLike, size_px: tuple[int, int] | None = None, size_source: str = ""
) -> np.ndarray:
    """Read a PNG/JPEG/TIFF/BMP file unchanged (8- or 16-bit) and make it mono; one-line error if
    unreadable. A file whose header states another size than ``size_px`` (``size_source``: where
    that size comes from) or too many pixels is refused before it is decoded, and so is another
    format, whose header is not read (:func:`floorvo.io.read_image`)."""
    return to_mono(read_image(path, "image file", f"image ({IMAGE_FORMATS})", size_px, size_source), str(path))


def size_of(image: np.ndarray) -> tuple[int, int]:
    """``(width_px, height_px)`` of an image array."""
    return image.shape[1], image.shape[0]


def median_rate_hz(timestamps_s: np.ndarray) -> float | None:
    """Frame rate (Hz) from the median spacing of increasing times (6 significant digits), or None for fewer than two."""
    d = np.diff(np.asarray(timestamps_s, dtype=float))
    return float(f"{1.0 / np.median(d):.6g}") if len(d) and np.median(d) > 0 else None


def _fps(value: float | None, what: str) -> float | None:
    """A frame rate given by the user (``--fps``): finite, from :data:`MIN_FPS_HZ` to :data:`MAX_FPS_HZ`, as
    ``sequence.json``'s ``fps`` (1e308 gave every frame the time 0 and a 'must increase' error)."""
    if value is None:
        return None
    v = float(value)
    if not np.isfinite(v) or v < MIN_FPS_HZ or v > MAX_FPS_HZ:  # 0.001 passed here, then sequence.json refused it
        raise ConfigError(f"{what} {shown(value)}: must be a finite number from {MIN_FPS_HZ:g} to {MAX_FPS_HZ:g} Hz")
    return v


def _height(value: float | None, what: str) -> float | None:
    """``value`` (mm) when it is a camera height (:func:`floorvo.camera.height_problem`); None stays None."""
    if value is None:
        return None
    problem = height_problem(value)
    if problem:
        raise ConfigError(f"{what} {shown(value)} mm: {problem}")
    return float(value)


def _camera_for(cal: CameraCalibration | None, size_px: tuple[int, int], what: str) -> CameraCalibration:
    if cal is None:
        raise ConfigError(
            f"{what}: holds no camera calibration; give --camera FILE (ROS camera_info, OpenCV or Kalibr YAML) "
            "or --fx --fy --cx --cy"
        )
    for name, cam in (("cam0", cal.cam0), ("cam1", cal.cam1)):
        if cam is not None and cam.size != tuple(size_px):
            raise ConfigError(
                f"camera {name}: calibrated for {cam.width_px}x{cam.height_px} px, "
                f"the frames of {what} are {size_px[0]}x{size_px[1]} px"
            )
    return cal


def write_recording(rec: Recording, out: str | os.PathLike, options: ImportOptions | None = None) -> ImportResult:
    """Write ``rec`` as a sequence folder at ``out`` (``sequence.json``, frames, ``timestamps.txt``, ground truth).

    The user's ``options`` override what the source states: calibration, timestamps,
    ground truth, camera height, cam0's flat field, measured heights; ``options.fps`` is the
    rate of a source without times. Frame times come from ``options.timestamps_s``, else the
    source, else ``i / fps``.
    """
    opts = options or ImportOptions()
    what = str(rec.source)
    src_real, out_real = Path(os.path.realpath(rec.source)), Path(os.path.realpath(out))
    if src_real == out_real or out_real in src_real.parents:
        # `floorvo import SEQ/cam0 -o SEQ --overwrite` cleared the frames it was to read, then failed
        raise ConfigError(
            f"{what}: lies inside the output folder {out}, which the import writes over; give -o another folder"
        )
    if opts.intrinsics is not None and opts.calibration is not None:
        raise ConfigError("camera: give --camera FILE or --fx --fy --cx --cy, not both")
    if opts.distortion is not None and opts.intrinsics is None:
        raise ConfigError("--distortion: goes with --fx --fy --cx --cy (a camera file has its own)")
    given = opts.calibration
    if opts.intrinsics is not None:
        given = CameraCalibration(camera_from_flags(rec.size_px, *opts.intrinsics, opts.distortion))
    cal = _camera_for(given or rec.calibration, rec.size_px, what)
    height_mm = _height(opts.height_mm, "--height-mm")
    if height_mm is None:
        height_mm = _height(rec.height_mm, f"{what}: camera height")
    fps_given = _fps(opts.fps, "--fps")
    n = rec.frame_count
    if n < 1:
        raise SequenceError(f"{what}: no frames found")
    if opts.timestamps_s is not None:
        ts = np.asarray(opts.timestamps_s, dtype=float)
        if len(ts) != n:
            raise SequenceError(f"timestamps file: {len(ts)} timestamp(s) for the {n} frame(s) of {what}")
        time_source = "timestamps file"
    elif rec.timestamps_s is not None:
        ts, time_source = np.asarray(rec.timestamps_s, dtype=float), rec.format
    elif fps_given is not None:
        ts, time_source = np.arange(n) / fps_given, "--fps"
    else:
        raise ConfigError(f"{what}: the source states no frame times; give --timestamps FILE or --fps HZ")
    if fps_given is not None and time_source != "--fps":
        # It was written into sequence.json beside times at another rate (and given to programs as {fps}).
        raise ConfigError(
            f"--fps {shown_number(fps_given)}: the frames have times (from the {time_source}); --fps is for a source "
            "without them, or a video whose times do not increase: leave it out"
        )
    # the nominal rate: given, else that of the times the user gave (a video's container said 30 Hz
    # beside --timestamps at 1 Hz), else the source's, else its frames' times'
    given_times = median_rate_hz(ts) if opts.timestamps_s is not None else None
    fps = fps_given or given_times or rec.fps or median_rate_hz(ts) or 1.0
    if not np.isfinite(fps) or fps <= 0:
        fps = median_rate_hz(ts) or 1.0
    if fps < MIN_FPS_HZ:  # refused by sequence.json's rule, in the words of a file not yet written
        raise ConfigError(
            f"{what}: the frames' times ({time_source}) are {1.0 / fps:g} s apart (median), a rate under the "
            f"{MIN_FPS_HZ:g} Hz a sequence's fps may be"
        )
    stereo = rec.has_right and cal.cam1 is not None and cal.T_cam0_cam1 is not None
    if rec.has_right and not stereo:  # a warning, and the stereo recording came out mono with exit code 0
        raise ConfigError(
            f"{what}: right images found but no right camera calibration and pose (EuRoC cam1/sensor.yaml with "
            "T_BS, a bag's right camera_info): give --camera with both cameras (a Kalibr camchain), or --left-only "
            "to import the left camera alone"
        )
    gt = opts.groundtruth if opts.groundtruth is not None else rec.groundtruth
    gt_source = "groundtruth file" if opts.groundtruth is not None else rec.format
    rig: dict = {}
    if height_mm is not None:
        rig["height_mm"] = height_mm
    else:
        log.warning("%s: no --height-mm; `floorvo run` needs rig.height_mm in sequence.json", what)
    meta: dict = {
        "name": rec.source.stem or rec.source.name,
        "camera": cal.cam0.to_dict(),
        "fps": float(fps),
        "frame_count": int(n),
        "rig": rig,
        "stereo": bool(stereo),
        "bit_depth": int(rec.bit_depth),
        "source": {
            "format": rec.format,
            "path": str(rec.source.resolve()),
            "timestamps": time_source,
            "groundtruth": None if gt is None else gt_source,
            **rec.details,
        },
        "versions": {"floorvo": __version__},
    }
    if stereo:
        meta["cameras"] = {"cam1": cal.cam1.to_dict()}  # type: ignore[union-attr]
        rig["T_cam0_cam1"] = np.asarray(cal.T_cam0_cam1, dtype=float).tolist()
    if rec.has_depth:
        meta["depth"] = {"format": "npy_float32_mm", "content": "depth along the optical axis, mm"}
    flats: dict[str, tuple[np.ndarray, str]] = {}
    if opts.flatfield is not None:
        w0, h0 = cal.cam0.width_px, cal.cam0.height_px
        flat = read_image_file(opts.flatfield, (w0, h0), f"the frames are {w0}x{h0} px")
        flats["cam0"] = (flat, f"--flatfield {opts.flatfield}")
    for cam_name, image in rec.flatfields.items():
        if cam_name not in flats and (cam_name == "cam0" or stereo):
            flats[cam_name] = (image, f"{what}: {cam_name} flat field")
    if "cam0" not in flats:  # sequence.json's calib block names cam0's: a cam1 flat field alone has no place
        flats.clear()
    for cam_name, (image, flat_what) in flats.items():
        model = cal.cam0 if cam_name == "cam0" else cal.cam1
        assert model is not None  # a cam1 flat field is kept only for a stereo import
        if image.shape != (model.height_px, model.width_px):
            raise ConfigError(
                f"{flat_what}: image is {image.shape[1]}x{image.shape[0]} px, "
                f"the frames are {model.width_px}x{model.height_px} px"
            )
    if "cam1" in flats and flats["cam1"][0].dtype != flats["cam0"][0].dtype:  # calib states one bit depth
        log.warning(
            "%s: cam1's flat field left out: it is %d-bit, cam0's (%s) %d-bit",
            what,
            8 * flats["cam1"][0].itemsize,
            flats["cam0"][1],
            8 * flats["cam0"][0].itemsize,
        )
        del flats["cam1"]
    if flats:
        meta["calib"] = {"flatfield": "calib/cam0_flatfield.png", "flatfield_bit_depth": 8 * flats["cam0"][0].itemsize}
    check_timestamps(ts, n, f"timestamps ({time_source})")
    if gt is not None:  # checked as the sequence's reader will check it: refused now, not after writing
        gt_what = "--groundtruth" if opts.groundtruth is not None else f"{what}: ground truth"
        check_groundtruth_times(gt[0], ts, gt_what, f"timestamps ({time_source})")
        if len(associate(gt[0], ts, GROUNDTRUTH_MAX_DIFF_S)[0]) == 0:
            raise SequenceError(
                f"{gt_what}: no pose within {GROUNDTRUTH_MAX_DIFF_S:g} s of a frame (poses at {shown_number(gt[0][0], '.6f')}-"
                f"{shown_number(gt[0][-1], '.6f')} s, frames at {shown_number(ts[0], '.6f')}-{shown_number(ts[-1], '.6f')} s, timestamps ({time_source})): "
                "the ground truth and the frames are on different clocks"
            )
    heights = opts.height_signal_mm if opts.height_signal_mm is not None else rec.height_signal_mm
    if heights is not None:
        heights_what = "--height-file" if opts.height_signal_mm is not None else f"{what}: measured heights"
        check_heights(np.asarray(heights, dtype=float), n, heights_what)
    # the readings' noise: the user's, else the source's where its readings are taken
    height_noise = rec.height_noise_mm if opts.height_signal_mm is None else None
    if opts.height_noise_mm is not None:
        height_noise = opts.height_noise_mm
        if heights is None:
            raise ConfigError(
                "--height-noise-mm: the import has no height signal to state the noise of (--height-file)"
            )
        if not 0.0 <= opts.height_noise_mm <= CAMERA_HEIGHT_RANGE_MM[1]:
            raise ConfigError(
                f"--height-noise-mm = {shown_number(opts.height_noise_mm)}: must be a standard deviation in mm, "
                f"0 to {CAMERA_HEIGHT_RANGE_MM[1]:g}"
            )
    if heights is not None and height_noise is not None:
        meta["rig"]["height_noise_mm"] = float(height_noise)
    # a rolling shutter's readout: the user's, else the source's (a floorsim export's sidecar)
    readout_ms, readout_what = (
        (opts.readout_ms, "--readout-ms") if opts.readout_ms is not None else (rec.readout_ms, f"{what}: readout_ms")
    )
    if readout_ms is not None:
        shortest_ms = 1000.0 * float(np.min(np.diff(ts))) if n > 1 else float("inf")
        if not 0.0 <= readout_ms <= shortest_ms:
            raise ConfigError(
                f"{readout_what} = {shown_number(readout_ms)}: must be a rolling shutter's readout in ms, 0 to "
                f"the shortest frame interval ({shortest_ms:.3f} ms): a row is read once a frame"
            )
        if readout_ms > 0.0:
            meta["sensor"] = {"shutter": "rolling", "readout_ms": float(readout_ms), "row_time": ROW_TIME_CONVENTION}
    attitude = opts.attitude_signal_rad if opts.attitude_signal_rad is not None else rec.attitude_signal_rad
    if attitude is not None:
        attitude_what = "--attitude-file" if opts.attitude_signal_rad is not None else f"{what}: measured attitude"
        check_attitude(np.asarray(attitude, dtype=float), n, attitude_what)
    with SequenceWriter(out, meta, overwrite=opts.overwrite) as writer:  # locked until the import ends
        exact_ns = {rec.format: rec.timestamps_ns, "timestamps file": opts.timestamps_ns}.get(time_source)
        writer.write_timestamps(ts, exact_ns)
        count = 0
        for i, fr in enumerate(rec.frames()):
            if i >= n:
                raise SequenceError(f"{what}: yields more frames than the {n} it announced")
            if 8 * fr.image.itemsize != rec.bit_depth:
                raise SequenceError(f"{what}: frame {i} is {8 * fr.image.itemsize}-bit, frame 0 is {rec.bit_depth}-bit")
            for img, label in ((fr.image, "image"), (fr.image_right, "right image"), (fr.depth_mm, "depth")):
                if img is not None and img.shape != (cal.cam0.height_px, cal.cam0.width_px):
                    raise SequenceError(
                        f"{what}: {label} of frame {i} is {img.shape[1]}x{img.shape[0]} px, "
                        f"frame 0 is {cal.cam0.width_px}x{cal.cam0.height_px} px"
                    )
            count = i + 1
            if writer.resumed and writer.has_frame(i):
                continue
            writer.write_frame(i, fr.image)
            if stereo:
                if fr.image_right is None:
                    raise SequenceError(f"{what}: frame {i} has no right image")
                writer.write_frame(i, fr.image_right, "cam1")
            if rec.has_depth:
                if fr.depth_mm is None:
                    raise SequenceError(f"{what}: frame {i} has no depth image")
                writer.write_depth(i, fr.depth_mm)
        if count != n:
            raise SequenceError(f"{what}: yielded {count} frame(s), announced {n}")
        for cam_name, (image, _) in flats.items():
            writer.write_calib(f"{cam_name}_flatfield", image)
        if gt is not None:
            writer.write_groundtruth(gt[0], gt[1])
        if heights is not None:
            writer.write_heights(heights)
        if attitude is not None:
            writer.write_attitude(attitude)
    log.info("imported %d frames of %s (%s) -> %s", n, what, rec.format, writer.root)
    return ImportResult(
        sequence=writer.root,
        format=rec.format,
        frames=n,
        width_px=cal.cam0.width_px,
        height_px=cal.cam0.height_px,
        bit_depth=int(rec.bit_depth),
        fps=float(fps),
        duration_s=float(ts[-1] - ts[0]),
        stereo=bool(stereo),
        depth=rec.has_depth,
        groundtruth_poses=0 if gt is None else len(gt[0]),
        height_mm=height_mm,
    )

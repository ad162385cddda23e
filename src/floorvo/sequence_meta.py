"""What ``sequence.json`` may hold: its keys, their types and rules, declared once.

``sequence.json`` is checked as strictly as a scene file, through the one configuration
mechanism (:mod:`floorvo.config`): an unknown key, a value of the wrong type (``"80mm"``
where a number goes, ``"none"`` where a table goes), a NaN or a value out of range is
refused with one line naming the key, the value and the rule, e.g.
``SEQ/sequence.json: rig.height_mm = nan mm: must be a finite number``.

Blocks that record how a sequence was made (``scene``, ``trajectory``, ``seeds``,
``versions``, ``source``, ...) are free-form tables: they are provenance, not read back.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from floorvo.camera import CAMERA_HEIGHT_RANGE_MM, K_problem, distortion_problem
from floorvo.config import Config, build, param
from floorvo.errors import ConfigError, ConfigFieldError, shown
from floorvo.geometry import rigid_problem

__all__ = [
    "SCHEMA_VERSION",
    "MAX_FPS_HZ",
    "MIN_FPS_HZ",
    "READABLE_SCHEMA_VERSIONS",
    "CameraBlock",
    "RigBlock",
    "DepthBlock",
    "CalibBlock",
    "SensorBlock",
    "rolling_row_offsets_s",
    "SequenceMeta",
    "check_sequence_meta",
    "stable_meta",
]

#: Version of the on-disk format written here (2: optional per-frame ``timestamps.txt``).
SCHEMA_VERSION = 2
#: Versions a reader accepts; it refuses any other.
READABLE_SCHEMA_VERSIONS = (1, 2)


def stable_meta(meta: dict) -> dict:
    """``sequence.json`` content without what may differ between identical renders (``render_stats``:
    timings) or between readable schema versions of one sequence (``schema_version``): what says
    whether two sequences are the same (a resumed render's, the sequence a run was made on)."""
    volatile = ("render_stats",) + (
        ("schema_version",) if meta.get("schema_version") in READABLE_SCHEMA_VERSIONS else ()
    )
    return {k: v for k, v in meta.items() if k not in volatile}


#: The most frames a sequence may have (its frame times are held in memory: 80 MB).
MAX_FRAME_COUNT = 10_000_000
#: The frame rates a sequence may have, Hz: ground truth is written to the microsecond (TUM), so
#: frames closer than 1 us could not be told apart (a render at 1e7 Hz wrote poses that all had
#: one time); exports stamp frames in nanoseconds (EuRoC, int64) and whole seconds (ROS 2,
#: int32), which 10 M frames at 0.01 Hz (1e9 s) still fit (1e-300 Hz ended in an OverflowError).
MIN_FPS_HZ = 0.01
MAX_FPS_HZ = 1_000_000.0
#: Formats of ``depth/`` frames.
DEPTH_FORMATS = ("png16", "npy_float32_mm")

Matrix = tuple[tuple[float, ...], ...]


def _matrix(value: Matrix, shape: tuple[int, int], key: str) -> np.ndarray:
    M = np.asarray(value, dtype=float) if all(len(r) == shape[1] for r in value) else np.zeros(0)
    if M.shape != shape:
        raise ConfigFieldError(key, f" = {[list(r) for r in value]}: must be a {shape[0]}x{shape[1]} matrix")
    if not np.isfinite(M).all():
        raise ConfigFieldError(key, f" = {M.tolist()}: must hold finite numbers")
    return M


@dataclass(frozen=True)
class CameraBlock(Config):
    """Intrinsics of one camera (:meth:`floorvo.camera.CameraModel.to_dict`)."""

    width_px: int = param(unit="px", min=1, doc="image width")
    height_px: int = param(unit="px", min=1, doc="image height")
    K: Matrix = param(
        doc="3x3 intrinsic matrix in pixels: [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], fx, fy > 0, "
        "-0.5 <= cx <= width_px, -0.5 <= cy <= height_px"
    )
    distortion: tuple[float, ...] = param((0.0, 0.0, 0.0, 0.0, 0.0), doc="OpenCV k1, k2, p1, p2[, k3]")
    model: str = param("pinhole", choices=("pinhole", "pinhole-brown-conrady"), doc="camera model")
    distortion_model: str = param(
        "opencv (k1, k2, p1, p2, k3)", choices=("opencv (k1, k2, p1, p2, k3)",), doc="meaning of distortion"
    )

    def validate(self) -> None:
        K = _matrix(self.K, (3, 3), "K")
        problem = K_problem(K, (self.width_px, self.height_px))
        if problem:
            raise ConfigFieldError("K", f" = {K.tolist()}: {problem}")
        problem = distortion_problem(self.distortion)
        if problem:
            raise ConfigFieldError("distortion", f" = {shown(list(self.distortion))}: {problem}")


@dataclass(frozen=True)
class RigBlock(Config):
    """The rig: camera height, stereo extrinsics, and what a render records about its LEDs."""

    height_mm: float | None = param(
        None,
        unit="mm",
        min=CAMERA_HEIGHT_RANGE_MM[0],
        max=CAMERA_HEIGHT_RANGE_MM[1],
        doc="camera height above the floor",
    )
    T_cam0_cam1: Matrix | None = param(None, doc="4x4 pose of cam1 in cam0's frame, mm")
    gsd_mm_per_px: float | None = param(None, unit="mm/px", gt=0, doc="ground sample distance at height_mm")
    led_height_mm: float | None = param(None, unit="mm", gt=0, doc="LED emitters above the floor")
    led_positions_cam_mm: Matrix | None = param(None, doc="LED positions in the camera frame, mm")
    height_noise_mm: float | None = param(
        None,
        unit="mm",
        min=0.0,
        max=CAMERA_HEIGHT_RANGE_MM[1],
        doc="standard deviation of each height.csv reading (the range sensor's datasheet figure; absent: not stated)",
    )

    def validate(self) -> None:
        if self.T_cam0_cam1 is not None:
            T = _matrix(self.T_cam0_cam1, (4, 4), "T_cam0_cam1")
            problem = rigid_problem(T)
            if problem:
                raise ConfigFieldError("T_cam0_cam1", f" = {T.tolist()}: must be a rigid 4x4 transform ({problem})")


@dataclass(frozen=True)
class DepthBlock(Config):
    """How ``depth/`` frames are stored."""

    format: str = param("png16", choices=DEPTH_FORMATS, doc="png16: 16-bit PNG in 1/100 mm; npy_float32_mm")
    scale_per_mm: float = param(100.0, gt=0, doc="png16 units per mm")
    content: str = param("", doc="what the depth measures")


@dataclass(frozen=True)
class CalibBlock(Config):
    """Calibration frames under ``calib/``."""

    flatfield: str = param("calib/cam0_flatfield.png", doc="flat-field frame of cam0")
    flatfield_bit_depth: int = param(16, choices=(8, 16), doc="its bit depth")


@dataclass(frozen=True)
class SensorBlock(Config):
    """Shutter timing and exposure of a render (optional: absent means a global shutter and
    one exposure for the whole sequence, as in every sequence written before it existed)."""

    shutter: str = param("global", choices=("global", "rolling"), doc="global or rolling shutter")
    readout_ms: float = param(0.0, unit="ms", min=0, doc="rolling shutter: time from the first row to the last")
    row_time: str = param("", doc="when row r is exposed, relative to the frame time")
    groundtruth_row: float | None = param(None, min=0, doc="image row whose pose groundtruth.txt holds")
    exposure_mode: str = param("fixed", choices=("fixed", "auto"), doc="one exposure, or one per frame")
    exposure_file: str | None = param(None, doc="per-frame exposure (frame, gain_e_per_unit, level) CSV")
    exposure_ms: float | None = param(
        None,
        unit="ms",
        min=0,
        doc="exposure time, centred on the frame time (each row's time under a rolling shutter); none: not recorded",
    )

    def row_offsets_s(self, height_px: int) -> np.ndarray:
        """(H,) exposure time of each row relative to the frame time (s) (:func:`rolling_row_offsets_s`)."""
        return rolling_row_offsets_s(height_px, self.readout_ms if self.shutter == "rolling" else 0.0)


#: ``sensor.row_time`` of a sequence taken by a rolling shutter: when row r is exposed
#: (:func:`rolling_row_offsets_s`).
ROW_TIME_CONVENTION = "t_frame + (r - (height_px - 1) / 2) * readout_ms / (height_px - 1)"


def rolling_row_offsets_s(height_px: int, readout_ms: float) -> np.ndarray:
    """(H,) exposure time of each image row relative to the frame time (s), for a rolling shutter.

    Convention (``sequence.json``'s ``sensor`` block): row r is exposed at
    ``t_frame + (r - (H - 1) / 2) * readout / (H - 1)``: the first row ``readout / 2`` before
    the frame time, the last ``readout / 2`` after it, the centre row at the frame time,
    where the ground-truth pose is defined. A straight run at speed v is therefore sheared
    by v x readout between the first and the last row. ``readout_ms = 0``: global shutter
    (all zeros).
    """
    h = int(height_px)
    if h <= 1 or readout_ms <= 0:
        return np.zeros(max(h, 0))
    return (np.arange(h) - (h - 1) / 2.0) * (readout_ms / 1000.0 / (h - 1))


@dataclass(frozen=True)
class SequenceMeta(Config):
    """The keys of ``sequence.json``."""

    schema_version: int = param(choices=READABLE_SCHEMA_VERSIONS, doc="on-disk format version")
    camera: CameraBlock = param(doc="intrinsics of cam0")
    fps: float = param(
        unit="Hz",
        min=MIN_FPS_HZ,
        max=MAX_FPS_HZ,
        doc="frame rate; frame i at i / fps unless timestamps.txt gives times",
    )
    frame_count: int = param(min=1, max=MAX_FRAME_COUNT, doc="number of frames in cam0/")
    format: str = param("floorbench-sequence", choices=("floorbench-sequence",), doc="format name")
    name: str = param("", doc="sequence name")
    bit_depth: int | None = param(None, choices=(8, 16), doc="bits per pixel of the frames")
    rig: RigBlock = param(default_factory=RigBlock, doc="camera height, stereo extrinsics")
    stereo: bool = param(False, doc="cam1/ frames, cameras.cam1 and rig.T_cam0_cam1 present")
    cameras: dict[str, Any] = param(default_factory=dict, doc="cam1: intrinsics of the right camera (keys as camera)")
    depth: dict[str, Any] | None = param(
        None, doc="depth/ frames: format ('png16', 1/100 mm, or 'npy_float32_mm'), scale_per_mm"
    )
    calib: dict[str, Any] | None = param(None, doc="calib/ frames: flatfield (path), flatfield_bit_depth (8 or 16)")
    sensor: dict[str, Any] | None = param(
        None, doc="shutter (global/rolling), readout_ms, row_time, groundtruth_row, exposure_mode, exposure_file"
    )
    floor_spacing_mm: float | None = param(None, unit="mm", gt=0, doc="floor mesh spacing of a render")
    events: dict[str, Any] | None = param(None, doc="trajectory events (teleport_frames)")
    seeds: dict[str, Any] | None = param(None, doc="provenance: random seeds")
    units: dict[str, Any] | None = param(None, doc="provenance: units")
    trajectory: dict[str, Any] | None = param(None, doc="provenance: the trajectory")
    scene: dict[str, Any] | None = param(None, doc="provenance: the resolved scene")
    versions: dict[str, Any] | None = param(None, doc="provenance: package versions")
    render_stats: dict[str, Any] | None = param(None, doc="provenance: render timings")
    synthetic: dict[str, Any] | None = param(None, doc="provenance: floorvo.synthetic settings")
    source: dict[str, Any] | None = param(None, doc="provenance: what floorvo import read")

    def validate(self) -> None:
        for name, block in self.cameras.items():
            if name != "cam1":
                raise ConfigError(f"cameras.{name}: unknown camera (known: cam1)")
            _nested(CameraBlock, block, f"cameras.{name}")
        if self.depth is not None:
            _nested(DepthBlock, self.depth, "depth")
        if self.calib is not None:
            _nested(CalibBlock, self.calib, "calib")
        if self.sensor is not None:
            _nested(SensorBlock, self.sensor, "sensor")
        if self.stereo and ("cam1" not in self.cameras or self.rig.T_cam0_cam1 is None):
            raise ConfigError("stereo = true: needs cameras.cam1 and rig.T_cam0_cam1")

    @property
    def sensor_block(self) -> SensorBlock:
        """The ``sensor`` block (a global shutter with a fixed exposure when the sequence has none)."""
        return build(SensorBlock, self.sensor or {}, "sensor")


def _nested(cls: type, value: Any, key: str) -> None:
    """Check a table that a free-form field holds as block ``cls``; errors name ``key`` in full."""
    if not isinstance(value, dict):
        raise ConfigError(f"{key} = {shown(value)}: must be a table")
    try:
        build(cls, value, key)
    except ConfigError as exc:  # a plain ConfigError: an enclosing Config does not re-prefix it
        raise ConfigError(str(exc)) from None


def check_sequence_meta(meta: Any) -> SequenceMeta:
    """``meta`` (parsed ``sequence.json``) checked key by key; one-line :class:`ConfigError` otherwise."""
    if not isinstance(meta, dict):
        raise ConfigError(f"must be a JSON object of keys, got {type(meta).__name__}")
    return build(SequenceMeta, meta)

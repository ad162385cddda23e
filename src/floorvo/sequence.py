"""The sequence on disk: the contract between floorsim, floorvo and other people's tools.

::

    SEQ/
      sequence.json     schema_version, resolved scene, seeds, package versions, units,
                        camera intrinsics (K, size, distortion), rig extrinsics, fps
      cam0/000000.png   mono frames (8- or 16-bit)
      cam1/000000.png   right camera when the rig is stereo
      depth/000000.png  16-bit depth in 1/100 mm (or depth/000000.npy, float32 mm)
      calib/cam0_flatfield.png   flat-field frame (same rig, flat uniform floor), optional
      calib/sensor.json          exposure of a rendered sequence (floorsim), optional
      timestamps.txt    per-frame times (s), one line per frame in frame order; optional
      height.csv        per-frame camera height above the floor (mm) from a range sensor:
                        ``frame,height_mm`` rows, an empty height = no reading; optional
      attitude.csv      per-frame roll and pitch of the camera against gravity (rad), from
                        an IMU's attitude filter: ``frame,roll_rad,pitch_rad`` rows, both
                        empty = no reading; optional
      groundtruth.txt   TUM: timestamp tx ty tz qx qy qz qw, T_world_cam0, metres

Frame ``i`` was taken at line ``i`` of ``timestamps.txt`` when the folder has one (a
recording: camera clock times, any spacing), at ``i / fps`` otherwise (a render). Schema
version 2 added ``timestamps.txt``; version 1 folders (no such file) still load.
``height.csv`` (issue 14 item 4) is optional in every version: a folder without it loads
as before, and a reader that does not know it ignores it (the estimators then use the
rig's constant height, as before); :attr:`Sequence.height_signal_mm` reads it.
``sequence.json`` may state the standard deviation of its readings, ``rig.height_noise_mm``
(optional; :attr:`Sequence.height_noise_mm`): the runner then loses the steps whose height
change that noise leaves uncertain (:mod:`floorvo.runner`).

``attitude.csv`` (issue 14, "6-DoF where the sensors allow it") is optional in the same
way; :attr:`Sequence.attitude_signal_rad` reads it. Its angles say where gravity (the
world's -z: the floor normal of a level floor) points in the camera frame (OpenCV's: x
right, y down, z along the optical axis, :mod:`floorvo.geometry`)::

    g_cam = R_world_cam^T (0, 0, -1) = (sin pitch, sin roll cos pitch, cos roll cos pitch)
    roll = atan2(g_y, g_z),  pitch = asin(g_x)

so a camera looking straight down reads (0, 0), and the camera's rotation is
``R_world_cam = Rz(yaw) Ry(pitch) Rx(roll) R_down`` (rotations about the world's axes,
``R_down`` = :data:`floorvo.geometry.R_WORLD_CAM_DOWN`; :func:`floorvo.geometry.T_world_cam_down`
with ``roll_rad``, ``pitch_rad``): roll turns the camera about the rig's forward axis (world
x at yaw 0: the image's x axis), pitch about its lateral axis. The yaw is not in the file: a
gravity sensor does not see it. A reading's angles are at most :data:`MAX_ATTITUDE_RAD` (0.5
rad) each: a downward floor camera tilted further sees no floor under its optical axis worth
the name, and a larger value is a unit or sign mistake (degrees). A planar mono estimator's
poses are turned into the tilted camera's 6-DoF poses with it (:func:`floorvo.runner.run_frames`).

Every file is written atomically, so a frame file that exists is complete; a render that
is interrupted and restarted skips the frames already on disk and readable
(:meth:`SequenceWriter.has_frame`) and removes the temporaries the interrupted one left.
"""

from __future__ import annotations

import json
import logging
import os
import re
import weakref
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from decimal import ROUND_HALF_EVEN, Decimal
from pathlib import Path
from typing import Any

import numpy as np

from floorvo.camera import CAMERA_HEIGHT_RANGE_MM, CameraModel, height_problem
from floorvo.errors import ConfigError, FloorbenchError, SequenceError, shorten, shown, shown_number
from floorvo.io import (
    atomic_write_bytes,
    atomic_write_json,
    atomic_write_text,
    checked_output_path,
    ensure_writable_dir,
    file_in_the_way,
    plain,
    png_size,
    read_json,
    read_npy,
    read_png,
    read_text,
    remove_stale_temporaries,
    write_png,
)
from floorvo.locking import LOCK_FILE, lock_folder
from floorvo.metrics import associate
from floorvo.sequence_meta import (
    READABLE_SCHEMA_VERSIONS,
    SCHEMA_VERSION,
    check_sequence_meta,
    rolling_row_offsets_s,
    stable_meta,
)
from floorvo.tum import MAX_TIME_S, read_tum, time_problem, write_tum

__all__ = [
    "SCHEMA_VERSION",
    "READABLE_SCHEMA_VERSIONS",
    "TIMESTAMPS_FILE",
    "HEIGHT_FILE",
    "ATTITUDE_FILE",
    "MAX_ATTITUDE_RAD",
    "GROUNDTRUTH_MAX_DIFF_S",
    "Sequence",
    "SequenceWriter",
    "frame_name",
    "sequence_files",
    "SEQUENCE_FORMAT",
    "check_timestamps",
    "check_heights",
    "check_attitude",
    "check_groundtruth_times",
    "read_groundtruth",
    "read_height_csv",
    "no_groundtruth_reason",
    "read_attitude_csv",
    "read_frame_csv",
    "time_text",
    "time_text_ns",
    "time_ns_of_text",
    "DEPTH_PNG_SCALE_PER_MM",
]

log = logging.getLogger(__name__)

#: The ``format`` field of every ``sequence.json`` this writer makes.
SEQUENCE_FORMAT = "floorbench-sequence"
#: Per-frame timestamps (s), one line per frame; absent: frame i at i / fps.
TIMESTAMPS_FILE = "timestamps.txt"
#: Per-frame measured camera height (mm), ``frame,height_mm`` rows; absent: no height signal.
HEIGHT_FILE = "height.csv"
#: The value column of :data:`HEIGHT_FILE`.
HEIGHT_COLUMNS = ("height_mm",)
#: Per-frame measured camera attitude against gravity (rad), ``frame,roll_rad,pitch_rad`` rows
#: (the module's docstring defines the angles); absent: no attitude signal.
ATTITUDE_FILE = "attitude.csv"
#: The value columns of :data:`ATTITUDE_FILE`.
ATTITUDE_COLUMNS = ("roll_rad", "pitch_rad")
#: The largest roll or pitch (rad) a reading of :data:`ATTITUDE_FILE` may have (29 degrees).
MAX_ATTITUDE_RAD = 0.5
#: Largest gap (s) between a frame's time and the ground-truth pose taken for it; the
#: same as the default association tolerance of ``floorvo score``.
GROUNDTRUTH_MAX_DIFF_S = 0.01
#: 16-bit depth PNGs store depth in 1/100 mm.
DEPTH_PNG_SCALE_PER_MM = 100.0


def frame_name(index: int, ext: str = "png") -> str:
    """File name of frame ``index``: six digits, e.g. ``000042.png``."""
    return f"{index:06d}.{ext}"


def _canonical(obj: Any) -> Any:
    """JSON round trip, so in-memory metadata compares equal to what is on disk."""
    return json.loads(json.dumps(plain(obj)))


def _differing_keys(old: dict, new: dict) -> str:
    """The keys of ``sequence.json`` in which ``old`` and ``new`` differ, a table's own keys named
    (``versions.render_code``: rendered by other renderer code), for a refusal's one line."""
    keys = []
    for k in sorted(set(old) | set(new), key=str):
        a, b = old.get(k), new.get(k)
        if a == b:
            continue
        if isinstance(a, dict) and isinstance(b, dict) and k in ("versions", "seeds", "rig"):
            keys += [f"{k}.{sub}" for sub in sorted(set(a) | set(b), key=str) if a.get(sub) != b.get(sub)]
        else:
            keys.append(str(k))
    return shorten(", ".join(keys) or "nothing")


class SequenceWriter:
    """Writes a sequence folder; resumable.

    Parameters
    ----------
    root:
        Output folder (created). Refused in one line: the empty path, the root of a file
        system, and an existing folder that holds other files but no sequence.
    meta:
        The content of ``sequence.json`` except ``schema_version``, which is added. Must
        hold ``camera`` (``CameraModel.to_dict()``), ``fps`` and ``frame_count``.
    resume:
        If ``root/sequence.json`` exists with the same metadata, keep the frames already
        written (a frame counts only if its files decode, see :meth:`has_frame`); if it
        exists with different metadata, refuse (unless ``overwrite``).
    overwrite:
        Replace an existing sequence with different metadata: the files the format names
        (:func:`sequence_files`) are deleted; anything else in the folder (a user's notes,
        subfolders) stays.
    defer:
        Check the folder now but change nothing in it until :meth:`begin` (or the first
        ``write_*`` call, which calls it): an existing sequence to overwrite is deleted and
        ``sequence.json`` written only then. A writer that may still refuse its work after
        opening (a render whose first frame turns out black) so leaves the folder as it was,
        and a folder it created empty, removed with the lock. Until then, frames of a
        sequence to be overwritten count as missing (:meth:`missing_frames`).

    Opening a folder locks it (:func:`floorvo.locking.lock_folder`): a second writer of
    the same folder, in another process, is refused in one line naming the holder's pid,
    until :meth:`close` (or the end of a ``with`` block, or the writer's garbage collection).
    Under that lock it removes the temporaries that a killed writer left behind
    (``.NAME.XXXXXXXX.tmp``, see :func:`floorvo.io.remove_stale_temporaries`); the lock file
    (:data:`floorvo.locking.LOCK_FILE`) is not a file of the format.
    """

    def __init__(
        self,
        root: str | os.PathLike,
        meta: dict,
        *,
        resume: bool = True,
        overwrite: bool = False,
        defer: bool = False,
    ):
        self.root = checked_output_path(root)
        meta = _canonical({"schema_version": SCHEMA_VERSION, "format": SEQUENCE_FORMAT, **meta})
        _check_meta(meta, self.root / "sequence.json")
        self.meta = meta
        if self.root.exists() and not self.root.is_dir():
            raise SequenceError(f"{self.root}: output path exists and is not a folder")
        self._lock = lock_folder(self.root, "sequence folder")
        self._release = weakref.finalize(self, self._lock.release)
        #: What :meth:`begin` still has to do: delete the sequence being overwritten, write sequence.json.
        self._replace_old = self._write_meta = False
        try:
            self._open(meta, resume, overwrite)
            if not defer:
                self.begin()
        except BaseException as exc:
            self._release.detach()
            self._lock.release(refused=isinstance(exc, FloorbenchError))
            raise

    def close(self) -> None:
        """Release the folder's lock (the writer writes nothing more); closing twice does nothing."""
        self._release()

    def __enter__(self) -> SequenceWriter:
        return self

    def __exit__(self, exc_type: object, exc: BaseException | None, tb: object) -> None:
        self._release.detach()
        self._lock.release(refused=isinstance(exc, FloorbenchError))

    def _open(self, meta: dict, resume: bool, overwrite: bool) -> None:
        meta_path = self.root / "sequence.json"
        old = None
        if self.root.is_dir():
            for folder in (self.root, *(self.root / sub for sub in _FRAME_FOLDERS), self.root / "calib"):
                remove_stale_temporaries(folder)
            if meta_path.exists():
                old = _read_own_meta(meta_path)
            else:
                others = sorted(p.name for p in self.root.iterdir() if p.name != LOCK_FILE)
                if others:
                    more = f" and {len(others) - 1} more" if len(others) > 1 else ""
                    raise SequenceError(
                        f"{self.root}: holds {others[0]!r}{more} but no sequence.json; "
                        "choose an empty or new output folder"
                    )
        ensure_writable_dir(self.root)
        if old is not None:
            same = stable_meta(old) == stable_meta(meta)
            if same and resume:
                self.resumed = True
                self._write_meta = old.get("schema_version") != SCHEMA_VERSION  # an older version of the same sequence
                return
            if not overwrite:
                raise SequenceError(
                    f"{self.root}: holds a different sequence (other scene, seed, settings or code: its "
                    f"sequence.json differs in {_differing_keys(stable_meta(old), stable_meta(meta))}); "
                    "choose another output folder or pass --overwrite"
                )
            self._replace_old = True
        self.resumed = False
        self._write_meta = True

    def begin(self) -> None:
        """Make the folder this writer's: delete the sequence it overwrites and write
        ``sequence.json`` (what a deferred writer, ``defer``, has put off; nothing when done already)."""
        if self._replace_old:
            for f in sequence_files(self.root):
                f.unlink(missing_ok=True)
            self._replace_old = False
        if self._write_meta:
            atomic_write_json(self.root / "sequence.json", self.meta)
            self._write_meta = False

    # ----------------------------------------------------------------- paths
    def frame_path(self, index: int, cam: str = "cam0") -> Path:
        return self.root / cam / frame_name(index)

    def depth_path(self, index: int) -> Path:
        fmt = (self.meta.get("depth") or {}).get("format", "png16")
        return self.root / "depth" / frame_name(index, "npy" if fmt == "npy_float32_mm" else "png")

    def required_paths(self, index: int) -> list[Path]:
        """Every file frame ``index`` must have for the sequence to be complete."""
        paths = [self.frame_path(index, "cam0")]
        if self.meta.get("stereo"):
            paths.append(self.frame_path(index, "cam1"))
        if self.meta.get("depth"):
            paths.append(self.depth_path(index))
        return paths

    def has_frame(self, index: int) -> bool:
        """True if every file of frame ``index`` is on disk and decodes.

        Writes are atomic, so a file of ours is complete; a file damaged afterwards (cut short
        by a copy, a full disk or a crash of the file system) does not count, and a resume
        renders the frame again. Nor do the files of a sequence a deferred writer (``defer``) is
        about to overwrite.
        """
        shape = self._frame_shape()
        return not self._replace_old and all(
            _decodes(p, self._expected_dtype(p), shape) for p in self.required_paths(index)
        )

    def _frame_shape(self) -> tuple[int, int] | None:
        """(height, width) px of every frame file (cam0, cam1, depth) as ``sequence.json`` states
        the camera, or None where it states none."""
        cam = self.meta.get("camera")
        if (
            not isinstance(cam, dict)
            or not isinstance(cam.get("width_px"), int)
            or not isinstance(cam.get("height_px"), int)
        ):
            return None
        return int(cam["height_px"]), int(cam["width_px"])

    def _expected_dtype(self, path: Path) -> np.dtype | None:
        """What a PNG frame file of this sequence must hold (:func:`_png_frame_dtype`; None for ``.npy``)."""
        return _png_frame_dtype(self.meta, path.parent.name) if path.suffix == ".png" else None

    def has_calib(self, name: str) -> bool:
        """True if ``calib/NAME.png`` is on disk and decodes (and is not about to be overwritten)."""
        return not self._replace_old and _decodes(self.root / "calib" / f"{name}.png")

    def missing_frames(self) -> list[int]:
        """Indices of the frames whose files are not all on disk and readable (logged when a file is damaged)."""
        missing = []
        for i in range(int(self.meta["frame_count"])):
            if not self.has_frame(i):
                missing.append(i)
                for p in self.required_paths(i):
                    if p.is_file() and not _decodes(p, self._expected_dtype(p), self._frame_shape()):
                        log.warning("%s: damaged (does not decode as this sequence's frame); writing it again", p)
        return missing

    # ----------------------------------------------------------------- writing
    def write_frame(self, index: int, image: np.ndarray, cam: str = "cam0") -> None:
        """Write a uint8/uint16 mono image as ``cam/NNNNNN.png`` (atomic)."""
        self.begin()
        write_png(self.frame_path(index, cam), image)

    def write_depth(self, index: int, depth_mm: np.ndarray) -> None:
        """Write a depth map (H, W) in mm; 0 or NaN = no measurement."""
        self.begin()
        path = self.depth_path(index)
        d = np.asarray(depth_mm, dtype=np.float64)
        if path.suffix == ".npy":
            import io

            buf = io.BytesIO()
            np.save(buf, np.nan_to_num(d, nan=0.0).astype(np.float32))
            atomic_write_bytes(path, buf.getvalue())
        else:
            q = np.round(np.nan_to_num(d, nan=0.0) * DEPTH_PNG_SCALE_PER_MM)
            write_png(path, np.clip(q, 0, 65535).astype(np.uint16))

    def write_calib(self, name: str, image: np.ndarray) -> None:
        """Write a calibration image as ``calib/NAME.png`` (e.g. ``cam0_flatfield``)."""
        self.begin()
        write_png(self.root / "calib" / f"{name}.png", image)

    def write_groundtruth(self, timestamps_s: np.ndarray, T_world_cam: np.ndarray) -> None:
        """Write ``groundtruth.txt`` (TUM, metres) for cam0."""
        self.begin()
        write_tum(self.root / "groundtruth.txt", timestamps_s, T_world_cam)

    def write_timestamps(self, timestamps_s: np.ndarray, timestamps_ns: Iterable[int] | None = None) -> None:
        """Write ``timestamps.txt``: the time (s) of each of the ``frame_count`` frames, increasing
        (:func:`time_text`). ``timestamps_ns``: the same times in integer nanoseconds where the
        source stamps so (EuRoC, ROS): written exactly, so that an export gives back those stamps."""
        ts = check_timestamps(np.asarray(timestamps_s, dtype=float), int(self.meta["frame_count"]), "timestamps")
        if timestamps_ns is None:
            texts = [time_text(float(t)) for t in ts]
        else:
            ns = [int(n) for n in timestamps_ns]
            if len(ns) != len(ts) or not np.allclose(np.array(ns, dtype=float) * 1e-9, ts, rtol=0, atol=1e-6):
                raise ValueError("write_timestamps: timestamps_ns are not the times of timestamps_s")
            texts = [time_text_ns(n) for n in ns]
        self.begin()
        lines = ["# timestamp_s of each frame, in frame order (cam0/000000.png first)", *texts]
        atomic_write_text(self.root / TIMESTAMPS_FILE, "\n".join(lines) + "\n")

    def write_heights(self, height_mm: np.ndarray, source: str = "range sensor") -> None:
        """Write ``height.csv``: the measured camera height above the floor (mm) of each of the
        ``frame_count`` frames, NaN where there is no reading (an empty cell)."""
        h = check_heights(np.asarray(height_mm, dtype=float), int(self.meta["frame_count"]), "height_mm")
        comment = f"camera height above the floor (mm) per frame, from a {source}; empty = no reading"
        self._write_frame_csv(HEIGHT_FILE, HEIGHT_COLUMNS, comment, h[:, None], "{:.6f}")

    def write_attitude(self, attitude_rad: np.ndarray, source: str = "IMU") -> None:
        """Write ``attitude.csv``: the measured roll and pitch (rad, the module's docstring defines
        them) of each of the ``frame_count`` frames, ``attitude_rad`` (frame_count, 2); a row of
        NaN where there is no reading (empty cells)."""
        a = check_attitude(np.asarray(attitude_rad, dtype=float), int(self.meta["frame_count"]), "attitude_rad")
        comment = f"camera roll and pitch against gravity (rad) per frame, from an {source}; empty = no reading"
        self._write_frame_csv(ATTITUDE_FILE, ATTITUDE_COLUMNS, comment, a, "{:.9f}")

    def _write_frame_csv(self, name: str, columns: tuple[str, ...], comment: str, values: np.ndarray, fmt: str) -> None:
        """A per-frame CSV (:func:`read_frame_csv`'s format): ``# comment``, the header, a row per frame."""
        self.begin()
        lines = [f"# {comment}", ",".join(("frame", *columns))]
        lines += [
            ",".join([str(i), *("" if np.isnan(v) else fmt.format(v) for v in row)]) for i, row in enumerate(values)
        ]
        atomic_write_text(self.root / name, "\n".join(lines) + "\n")


def _check_meta(meta: dict, meta_path: Path) -> None:
    """Every key of ``sequence.json`` checked (:mod:`floorvo.sequence_meta`); one-line SequenceError otherwise."""
    try:
        check_sequence_meta(meta)
    except ConfigError as exc:
        raise SequenceError(f"{meta_path}: {exc}") from None


#: Folders of per-frame files.
_FRAME_FOLDERS = ("cam0", "cam1", "depth")
_FRAME_FILE = re.compile(r"\d{6,}\.(png|npy)")
_CALIB_FILE = re.compile(r"cam\d+_flatfield\.png|sensor\.json|exposure\.csv")


def sequence_files(root: str | os.PathLike) -> list[Path]:
    """The files of the sequence format present in ``root`` (except ``sequence.json``).

    ``groundtruth.txt``, ``timestamps.txt``, ``height.csv``, ``attitude.csv``, ``cam0/``, ``cam1/`` and ``depth/`` frames
    (``NNNNNN.png``/``.npy``), ``calib/CAM_flatfield.png``, ``calib/sensor.json`` and ``calib/exposure.csv``. Nothing else: other files and
    folders in the sequence folder are not the format's (``--overwrite`` leaves them).
    """
    root = Path(root)
    files = [root / "groundtruth.txt", root / TIMESTAMPS_FILE, root / HEIGHT_FILE, root / ATTITUDE_FILE]
    for sub, pattern in [*((s, _FRAME_FILE) for s in _FRAME_FOLDERS), ("calib", _CALIB_FILE)]:
        d = root / sub
        if d.is_dir():
            files += sorted(p for p in d.iterdir() if pattern.fullmatch(p.name))
    return [p for p in files if p.is_file()]


def _read_own_meta(meta_path: Path) -> dict:
    """The content of an existing ``sequence.json`` written by this format; SequenceError otherwise."""
    try:
        old = json.loads(meta_path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        old = None
    ours = (
        isinstance(old, dict)
        and old.get("format", SEQUENCE_FORMAT) == SEQUENCE_FORMAT
        and old.get("schema_version") in READABLE_SCHEMA_VERSIONS
    )
    if not ours:
        raise SequenceError(
            f"{meta_path}: not a floorbench sequence (unreadable, or not format {SEQUENCE_FORMAT!r} of a "
            "readable schema_version); "
            "choose an empty or new output folder"
        )
    return old


def _decodes(path: Path, dtype: np.dtype | None = None, shape: tuple[int, int] | None = None) -> bool:
    """True if ``path`` is a file that reads as a frame (PNG, or ``.npy`` for depth): a mono
    image, of ``dtype`` and ``shape`` (height, width) where given (a resumed render took an 8-bit
    PNG where its 16-bit depth map should be as present, a colour one as a frame, and a frame of
    another size, which the finished sequence's readers then refused)."""
    if not path.is_file():
        return False
    if path.suffix == ".npy":
        try:
            arr = read_npy(path, _depth_dtype_problem)  # the header first: a stated shape of terabytes is not loaded
        except SequenceError:
            return False
        return shape is None or arr.shape == shape
    try:
        with open(path, "rb") as fh:
            fh.seek(-12, os.SEEK_END)
            if fh.read() != _PNG_END:  # cut short: no need to decode (libpng would complain on stderr)
                return False
        img = read_png(path)
    except (OSError, SequenceError):
        return False
    return img.ndim == 2 and (dtype is None or img.dtype == dtype) and (shape is None or img.shape == shape)


def _png_frame_dtype(meta: dict, folder: str) -> np.dtype | None:
    """The pixel type of a PNG in the sequence folder ``folder`` (``cam0``, ``cam1``, ``depth``), mono
    in every case: a png16 depth map's uint16 (1/100 mm), a camera frame's the ``bit_depth`` that
    ``sequence.json`` (``meta``) states; None where it states none (frame 0's then holds). The one
    rule of the writer (a resume writes a file of another type again) and the readers."""
    if folder == "depth":
        return np.dtype(np.uint16)
    bits = meta.get("bit_depth")
    if bits == 8:
        return np.dtype(np.uint8)
    return np.dtype(np.uint16) if bits == 16 else None


def _check_bit_depth(img: np.ndarray, bits: object, path: Path, key: str) -> None:
    """Refuse an image whose bits per pixel (8 for uint8, 16 for uint16) are not ``bits``, what
    sequence.json's ``key`` states (no check where ``bits`` is None; frames of a sequence that
    states none are held to frame 0's): a 16-bit frame read as 8-bit is 256 times too bright,
    and an estimator would measure it as if it were."""
    if bits is not None and 8 * img.dtype.itemsize != bits:
        raise SequenceError(f"{path}: image is {8 * img.dtype.itemsize}-bit, sequence.json says {key} = {bits}")


def _depth_dtype_problem(shape: tuple[int, ...], dtype: np.dtype) -> str | None:
    """Why a ``.npy`` depth map of ``dtype`` is refused (the format is ``npy_float32_mm``), or None."""
    if dtype.kind != "f" or dtype.itemsize != 4:
        return "a depth map is float32 mm (depth format npy_float32_mm)"
    return None


#: The last 12 bytes of every PNG: the empty IEND chunk and its CRC.
_PNG_END = b"\x00\x00\x00\x00IEND\xaeB`\x82"


def check_timestamps(
    ts: np.ndarray, frame_count: int | None, what: str, linenos: list[int] | None = None
) -> np.ndarray:
    """``ts`` if it holds ``frame_count`` (None: any number of) finite, strictly increasing times;
    else a one-line SequenceError naming ``what`` and, where ``linenos`` gives the line of each time
    in the file ``what`` names, the line (``times.txt:4: ...``: an error that named no file left the
    user to find which of the files given held the time).

    Increasing as ``timestamps.txt`` stores them, to the nanosecond: frames closer than that
    (an import at --fps 1e12) were written as equal times that the sequence's reader refused.
    """
    if ts.ndim != 1 or (frame_count is not None and len(ts) != frame_count):
        raise SequenceError(f"{what}: {len(ts)} timestamp(s) for {frame_count} frame(s); need one per frame")

    def at(k: int) -> str:
        return what if linenos is None else f"{what}:{linenos[k]}"

    if not np.isfinite(ts).all():
        k = int(np.argmin(np.isfinite(ts)))
        raise SequenceError(f"{at(k)}: timestamp of frame {k} is not a finite number")
    far = np.nonzero(np.abs(ts) > MAX_TIME_S)[0]
    if len(far):
        raise SequenceError(f"{at(int(far[0]))}: timestamp of frame {int(far[0])} {time_problem(float(ts[far[0]]))}")
    bad = np.nonzero(np.diff(np.round(ts, 9)) <= 0)[0]
    if len(bad):
        k = int(bad[0]) + 1
        ns = " (to the nanosecond, as timestamps.txt holds them)" if ts[k] > ts[k - 1] else ""
        raise SequenceError(
            f"{at(k)}: timestamps must increase{ns}, frame {k} at {shown_number(ts[k], '.9f')} s follows {shown_number(ts[k - 1], '.9f')} s"
        )
    return ts


def check_groundtruth_times(ts_gt: np.ndarray, frame_ts: np.ndarray, what: str, frame_source: str) -> None:
    """Ground truth of one pose per frame (as every render writes it) must be at the frames' times
    ``frame_ts`` (from ``frame_source``) within :data:`GROUNDTRUTH_MAX_DIFF_S`; else a one-line
    SequenceError naming ``what`` (the ground truth) and the first pose that is not. Ground truth
    at another rate (a motion-capture system) is paired by time and not checked here."""
    ts_gt, frame_ts = np.asarray(ts_gt, dtype=float), np.asarray(frame_ts, dtype=float)
    if len(ts_gt) != len(frame_ts):
        return
    off = np.abs(ts_gt - frame_ts)
    if not np.all(off <= GROUNDTRUTH_MAX_DIFF_S):
        i = int(np.argmax(~(off <= GROUNDTRUTH_MAX_DIFF_S)))
        raise SequenceError(
            f"{what}: one pose per frame, but pose {i} is at {shown_number(ts_gt[i], '.6f')} s and frame {i} at {shown_number(frame_ts[i], '.6f')} s "
            f"({frame_source}): the frame times and the ground truth disagree"
        )


def check_heights(h: np.ndarray, frame_count: int, what: str) -> np.ndarray:
    """``h`` if it holds ``frame_count`` heights (mm), each a camera height
    (:func:`floorvo.camera.height_problem`) or NaN (no reading); else a one-line SequenceError."""
    if h.ndim != 1 or len(h) != frame_count:
        raise SequenceError(f"{what}: {len(h)} height(s) for {frame_count} frame(s); need one per frame")
    lo, hi = CAMERA_HEIGHT_RANGE_MM
    bad = np.nonzero(~np.isnan(h) & ~((h >= lo) & (h <= hi)))[0]
    if len(bad):
        k = int(bad[0])
        raise SequenceError(f"{what}: height of frame {k} = {h[k]:g} mm: {height_problem(h[k])} (or empty)")
    return h


def check_attitude(a: np.ndarray, frame_count: int, what: str) -> np.ndarray:
    """``a`` if it holds ``frame_count`` rows of (roll, pitch) in rad, each a reading (both finite,
    at most :data:`MAX_ATTITUDE_RAD` in size) or no reading (both NaN); else a one-line SequenceError."""
    if a.ndim != 2 or a.shape[1] != 2 or len(a) != frame_count:
        rows = len(a) if a.ndim == 2 and a.shape[1] == 2 else f"an array of shape {a.shape}, not"
        raise SequenceError(f"{what}: {rows} (roll, pitch) row(s) for {frame_count} frame(s); need one per frame")
    nan = np.isnan(a)
    for k in range(len(a)):
        if nan[k].all():
            continue
        if nan[k].any():
            raise SequenceError(
                f"{what}: frame {k} has roll {a[k, 0]} and pitch {a[k, 1]}: both or neither (no reading) must be given"
            )
        for j, col in enumerate(ATTITUDE_COLUMNS):
            v = a[k, j]
            if not (np.isfinite(v) and abs(v) <= MAX_ATTITUDE_RAD):
                raise SequenceError(
                    f"{what}: {col} of frame {k} = {v}: must be a finite number of radians within "
                    f"+-{MAX_ATTITUDE_RAD} (or empty)"
                )
    return a


@dataclass
class Sequence:
    """A sequence folder, opened for reading.

    Use :meth:`open`; it validates ``sequence.json`` and the schema version. Images are
    read lazily, one at a time.
    """

    root: Path
    meta: dict
    _timestamps_s: np.ndarray | None = field(default=None, repr=False, compare=False)
    _heights: tuple[np.ndarray | None] | None = field(default=None, repr=False, compare=False)
    _attitude: tuple[np.ndarray | None] | None = field(default=None, repr=False, compare=False)
    _frame0_bits: dict[str, int] = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def open(cls, root: str | os.PathLike) -> Sequence:
        root = Path(root)
        meta_path = root / "sequence.json"
        if not root.is_dir():
            if root.exists():  # `floorvo run FILE` said the folder did not exist
                raise SequenceError(f"{root}: is a file, not a sequence folder")
            blocker = file_in_the_way(root)
            raise SequenceError(
                f"{root}: sequence folder does not exist" + (f" ({blocker} is a file)" if blocker is not None else "")
            )
        if not meta_path.is_file():
            raise SequenceError(f"{root}: not a sequence (no sequence.json)")
        meta = read_json(meta_path, SequenceError)
        if not isinstance(meta, dict):
            kind = "a list" if isinstance(meta, list) else f"{type(meta).__name__} {shown(meta)}"
            raise SequenceError(f"{meta_path}: holds {kind}; sequence.json must be a table of keys (a JSON object)")
        version = meta.get("schema_version")
        if version not in READABLE_SCHEMA_VERSIONS or isinstance(version, bool):
            raise SequenceError(
                f"{meta_path}: schema_version {shown(version)} is not supported "
                f"(this floorvo reads versions {', '.join(map(str, READABLE_SCHEMA_VERSIONS))})"
            )
        _check_meta(meta, meta_path)
        seq = cls(root, meta)
        _ = seq.timestamps_s  # validate timestamps.txt now
        _ = seq.height_signal_mm  # and height.csv
        _ = seq.attitude_signal_rad  # and attitude.csv
        return seq

    # ----------------------------------------------------------------- metadata
    @property
    def camera(self) -> CameraModel:
        """Intrinsics of cam0."""
        return CameraModel.from_dict(self.meta["camera"])

    def camera_model(self, cam: str = "cam0") -> CameraModel:
        """Intrinsics of ``cam`` (``cam1`` for the right camera of a stereo rig)."""
        if cam == "cam0":
            return self.camera
        block = (self.meta.get("cameras") or {}).get(cam)
        if block is None:
            raise SequenceError(f"{self.root}: sequence has no camera {cam!r}")
        return CameraModel.from_dict(block)

    @property
    def T_cam0_cam1(self) -> np.ndarray | None:
        """Pose of the right camera in the left camera's frame (mm), or None if mono."""
        rig = self.meta.get("rig") or {}
        T = rig.get("T_cam0_cam1")
        return None if T is None else np.asarray(T, dtype=float)

    @property
    def led_positions_cam_mm(self) -> np.ndarray | None:
        """(N, 3) positions of the rig's own lights (LEDs that ride with the camera) in the camera
        frame, mm, as a render records them (``rig.led_positions_cam_mm``); None when the
        sequence does not say (a synthetic warp, an imported recording)."""
        rig = self.meta.get("rig") or {}
        P = rig.get("led_positions_cam_mm")
        return None if not P else np.asarray(P, dtype=float).reshape(-1, 3)

    @property
    def readout_ms(self) -> float:
        """A rolling shutter's readout, first row to last (ms, ``sensor.readout_ms``); 0 for a global
        shutter or a sequence that states none."""
        sensor = self.meta.get("sensor") or {}  # validated on opening (SensorBlock)
        return float(sensor.get("readout_ms") or 0.0) if sensor.get("shutter") == "rolling" else 0.0

    @property
    def row_time_s(self) -> float:
        """The time (s) between the exposures of two neighbouring rows of cam0 under a rolling
        shutter (:attr:`readout_ms` over the rows less one: ``sequence.json``'s
        ``sensor.row_time``, :func:`floorvo.sequence_meta.rolling_row_offsets_s`); 0 for a
        global shutter or a sequence that states none."""
        offsets_s = rolling_row_offsets_s(self.camera.height_px, self.readout_ms)
        return float(offsets_s[1] - offsets_s[0]) if len(offsets_s) > 1 else 0.0

    @property
    def frame_count(self) -> int:
        return int(self.meta["frame_count"])

    @property
    def fps(self) -> float:
        return float(self.meta["fps"])

    @property
    def timestamps_s(self) -> np.ndarray:
        """(frame_count,) time of each frame in s: ``timestamps.txt`` when present, else ``i / fps``."""
        if self._timestamps_s is None:
            path = self.root / TIMESTAMPS_FILE
            if path.is_file():
                self._timestamps_s = check_timestamps(_read_timestamps(path), self.frame_count, str(path))
            else:
                self._timestamps_s = np.arange(self.frame_count) / self.fps
        return self._timestamps_s.copy()

    @property
    def timestamps_ns(self) -> list[int]:
        """The frame times of :attr:`timestamps_s` in integer nanoseconds, as ``timestamps.txt``
        writes them (:func:`time_ns_of_text`: exactly, where a float of seconds holds a Unix time
        only to about 240 ns), else ``i / fps`` rounded to the nanosecond: the stamps an export
        gives the frames."""
        ts = self.timestamps_s  # checked
        path = self.root / TIMESTAMPS_FILE
        if not path.is_file():
            return [int(round(float(t) * 1e9)) for t in ts]
        return [time_ns_of_text(text) for _, text in _timestamp_lines(path)]

    @property
    def height_signal_mm(self) -> np.ndarray | None:
        """(frame_count,) measured camera height above the floor per frame (mm, NaN where no
        reading) from ``height.csv``; None when the sequence has no such file."""
        if self._heights is None:
            path = self.root / HEIGHT_FILE
            h = check_heights(read_height_csv(path), self.frame_count, str(path)) if path.is_file() else None
            self._heights = (h,)
        h = self._heights[0]
        return None if h is None else h.copy()

    @property
    def height_noise_mm(self) -> float | None:
        """The standard deviation (mm) of each reading of :attr:`height_signal_mm`, as
        ``sequence.json`` states it (``rig.height_noise_mm``: a render's ``range_sensor.noise_mm``,
        an import's ``--height-noise-mm``, a range sensor's datasheet); None where it states none."""
        v = (self.meta.get("rig") or {}).get("height_noise_mm")
        return None if v is None else float(v)

    @property
    def attitude_signal_rad(self) -> np.ndarray | None:
        """(frame_count, 2) measured roll and pitch of the camera against gravity per frame (rad,
        the module's docstring defines them; a row of NaN where no reading) from ``attitude.csv``;
        None when the sequence has no such file."""
        if self._attitude is None:
            path = self.root / ATTITUDE_FILE
            a = check_attitude(read_attitude_csv(path), self.frame_count, str(path)) if path.is_file() else None
            self._attitude = (a,)
        a = self._attitude[0]
        return None if a is None else a.copy()

    @property
    def simulated(self) -> bool:
        """Whether the sequence was rendered by floorsim (``sequence.json``'s ``versions`` name
        ``floorsim``, as every render writes them) or drawn by :mod:`floorvo.synthetic` (its
        ``synthetic`` block). Such a sequence's ground truth holds one pose per frame, exactly;
        an imported recording's (``source``) may be at another rate."""
        versions = self.meta.get("versions")
        return (isinstance(versions, dict) and "floorsim" in versions) or isinstance(self.meta.get("synthetic"), dict)

    @property
    def has_stereo(self) -> bool:
        return bool(self.meta.get("stereo"))

    @property
    def has_depth(self) -> bool:
        return bool(self.meta.get("depth"))

    def lacks(self, needs: Iterable[str], who: str) -> str:
        """Why this sequence cannot give ``who`` (an estimator, a program) what it ``needs``
        (``depth``, ``stereo``: an estimator's ``requires``, a program's ``needs``); "" when it can."""
        needs = set(needs)
        if "depth" in needs and not self.has_depth:
            return f"{who} needs depth images, and {self.root} has none (render it with depth enabled)"
        if "stereo" in needs and not self.has_stereo:
            return f"{who} needs a stereo sequence (cam1), and {self.root} is mono"
        return ""

    @property
    def height_mm(self) -> float | None:
        """Nominal camera height above the floor (mm), if the sequence states it."""
        rig = self.meta.get("rig") or {}
        h = rig.get("height_mm")
        return None if h is None else float(h)

    # ----------------------------------------------------------------- data
    def image_path(self, index: int, cam: str = "cam0") -> Path:
        return self.root / cam / frame_name(index)

    def image(self, index: int, cam: str = "cam0") -> np.ndarray:
        """Frame ``index`` of ``cam`` as stored (uint8 or uint16, (H, W))."""
        self._check_index(index)
        cam_model = self.camera_model(cam)
        size = f"sequence.json says {cam_model.width_px}x{cam_model.height_px}"
        img = read_png(self.image_path(index, cam), cam_model.size, size)  # another size: refused before decoding
        if img.shape != (cam_model.height_px, cam_model.width_px):  # a colour frame too: the format's are mono
            channels = f" with {img.shape[2]} channels" if img.ndim == 3 else ""
            raise SequenceError(
                f"{self.image_path(index, cam)}: image is {img.shape[1]}x{img.shape[0]}{channels}, "
                f"sequence.json says a mono {cam_model.width_px}x{cam_model.height_px}"
            )
        stated = _png_frame_dtype(self.meta, cam)
        if stated is not None:
            _check_bit_depth(img, 8 * stated.itemsize, self.image_path(index, cam), "bit_depth")
        else:  # no depth stated: frame 0's is the sequence's (a 16-bit frame among 8-bit ones was read as it was)
            if cam not in self._frame0_bits:
                self._frame0_bits[cam] = 8 * (img if index == 0 else self.image(0, cam)).dtype.itemsize
            if 8 * img.dtype.itemsize != self._frame0_bits[cam]:
                raise SequenceError(
                    f"{self.image_path(index, cam)}: image is {8 * img.dtype.itemsize}-bit, frame 0 is "
                    f"{self._frame0_bits[cam]}-bit (sequence.json states no bit_depth: a sequence's frames have one)"
                )
        return img

    def depth_mm(self, index: int) -> np.ndarray:
        """Depth of frame ``index`` in mm, float32 (H, W); 0 where there is no measurement."""
        self._check_index(index)
        if not self.has_depth:
            raise SequenceError(f"{self.root}: sequence has no depth (render it with depth enabled)")
        npy = self.root / "depth" / frame_name(index, "npy")
        depth_meta = self.meta.get("depth")
        fmt = depth_meta.get("format") if isinstance(depth_meta, dict) else None
        # the format sequence.json states (a missing .npy frame was named as a missing .png), else the file there
        if fmt == "npy_float32_mm" or (fmt is None and npy.is_file()):
            path = npy
            hw = (self.camera.height_px, self.camera.width_px)

            def rule(shape: tuple[int, ...], dtype: np.dtype) -> str | None:
                if shape != hw:
                    return f"sequence.json says {hw[1]}x{hw[0]} (shape {hw})"
                return _depth_dtype_problem(shape, dtype)

            depth = read_npy(npy, rule, "depth map").astype(np.float32)
        else:
            path = self.root / "depth" / frame_name(index)
            stated = png_size(path)
            if stated is not None and stated != self.camera.size:  # refused before decoding (a PNG bomb)
                raise SequenceError(
                    f"{path}: depth map is {stated[0]}x{stated[1]}, sequence.json says "
                    f"{self.camera.width_px}x{self.camera.height_px}"
                )
            raw = read_png(path)
            if raw.dtype != _png_frame_dtype(self.meta, "depth") or raw.ndim != 2:  # 8-bit as 1/100 mm: 0-2.55 mm
                bits = f"{8 * raw.dtype.itemsize}-bit" + (f" with {raw.shape[2]} channels" if raw.ndim == 3 else "")
                raise SequenceError(
                    f"{path}: depth map is {bits}, sequence.json says depth format png16 "
                    "(one channel of 16 bits, 1/100 mm)"
                )
            depth = raw.astype(np.float32) / np.float32(DEPTH_PNG_SCALE_PER_MM)
        cam = self.camera
        if depth.shape != (cam.height_px, cam.width_px):  # as a frame of another size is refused (image)
            size = f"{depth.shape[1]}x{depth.shape[0]}" if depth.ndim == 2 else f"of shape {depth.shape}"
            raise SequenceError(f"{path}: depth map is {size}, sequence.json says {cam.width_px}x{cam.height_px}")
        return depth

    def flatfield(self, cam: str = "cam0") -> np.ndarray | None:
        """Flat-field calibration frame of ``cam`` as stored, or None if the sequence has none."""
        p = self.root / "calib" / f"{cam}_flatfield.png"
        if not p.is_file():
            return None
        model = self.camera_model(cam)
        img = read_png(p, model.size, f"sequence.json says a mono {model.width_px}x{model.height_px}")
        _check_bit_depth(img, (self.meta.get("calib") or {}).get("flatfield_bit_depth"), p, "calib.flatfield_bit_depth")
        if img.shape != (model.height_px, model.width_px):  # estimators ended in a ValueError from inside
            channels = f" with {img.shape[2]} channels" if img.ndim == 3 else ""
            raise SequenceError(
                f"{p}: image is {img.shape[1]}x{img.shape[0]}{channels}, sequence.json says a mono "
                f"{model.width_px}x{model.height_px}"
            )
        return img

    def groundtruth(self) -> tuple[np.ndarray, np.ndarray] | None:
        """``(timestamps_s (N,), T_world_cam0 (N, 4, 4) mm)`` or None when there is none.

        Ground truth of one pose per frame (N = ``frame_count``, as every render writes it)
        must be at the frames' times (``timestamps.txt``, or ``i / fps``) within
        :data:`GROUNDTRUTH_MAX_DIFF_S`: a ``sequence.json`` whose ``fps`` disagrees with
        ``groundtruth.txt`` is refused in one line instead of pairing frames with the wrong
        poses (``floorvo score`` scored 11 of 21 poses of such a sequence with exit code 0).
        Ground truth at another rate (a motion-capture system) is paired by time; a rendered
        (or synthetic, :attr:`simulated`) sequence's is refused in one line unless it holds one
        pose per frame: one cut short was scored over the frames it still held, with exit code 0.
        """
        p = self.root / "groundtruth.txt"
        if not p.is_file():
            if p.exists():  # a folder by that name was read as no ground truth: a score without it, exit 0
                raise SequenceError(no_groundtruth_reason(p, "score"))
            return None
        ts_gt, T = read_tum(p)
        if len(ts_gt) != self.frame_count and self.simulated:
            how = "rendered by floorsim" if "synthetic" not in self.meta else "drawn by floorvo.synthetic"
            raise SequenceError(
                f"{p}: {len(ts_gt)} pose(s) for {self.frame_count} frame(s) (frame_count in sequence.json): the ground "
                f"truth of a sequence {how} holds one pose per frame (a file cut short?)"
            )
        if len(ts_gt) == self.frame_count:
            stamps = self.root / TIMESTAMPS_FILE
            source = stamps if stamps.is_file() else f"fps = {self.fps:g} Hz in {self.root / 'sequence.json'}"
            check_groundtruth_times(ts_gt, self.timestamps_s, str(p), str(source))
        return ts_gt, T

    def groundtruth_at(
        self, timestamps_s: np.ndarray, max_diff_s: float = GROUNDTRUTH_MAX_DIFF_S
    ) -> tuple[np.ndarray, np.ndarray]:
        """Ground-truth pose at each of ``timestamps_s`` (M,): ``(T_world_cam0 (M, 4, 4) mm, found (M,) bool)``.

        A time takes the ground-truth pose nearest to it when that is at most ``max_diff_s``
        away (:func:`floorvo.metrics.associate`, the pairing ``floorvo score`` uses); where
        none is, ``found`` is False and the pose is the identity. No ground truth: none found.
        """
        ts = np.atleast_1d(np.asarray(timestamps_s, dtype=float))
        T = np.tile(np.eye(4), (len(ts), 1, 1))
        found = np.zeros(len(ts), bool)
        gt = self.groundtruth()
        if gt is not None:
            i_ref, i_q = associate(gt[0], ts, max_diff_s)
            T[i_q] = gt[1][i_ref]
            found[i_q] = True
        return T, found

    def frames(self, cam: str = "cam0") -> Iterator[tuple[int, float, np.ndarray]]:
        """Iterate ``(index, timestamp_s, image)`` over all frames of ``cam``."""
        ts = self.timestamps_s
        for i in range(self.frame_count):
            yield i, float(ts[i]), self.image(i, cam)

    def _check_index(self, index: int) -> None:
        if not 0 <= index < self.frame_count:
            raise SequenceError(f"{self.root}: frame index {index} out of range 0..{self.frame_count - 1}")


def no_groundtruth_reason(path: Path, purpose: str) -> str:
    """Why ``path`` (not a file) gives no ground truth to ``purpose`` against, in one line: it is
    missing, or something else by that name (a folder was read as no ground truth)."""
    if path.exists():
        return f"{path}: is not a file (the ground truth to {purpose} against, TUM text)"
    return f"{path}: no ground truth to {purpose} against (groundtruth.txt is missing)"


def read_groundtruth(source: str | os.PathLike, purpose: str) -> tuple[Path, tuple[np.ndarray, np.ndarray]]:
    """``(path, (timestamps_s (N,), T_world_cam (N, 4, 4) mm))`` of the ground truth to ``purpose``
    ("score", "calibrate", "plot") a run against: ``source`` is a sequence folder (read through
    :meth:`Sequence.groundtruth`, which checks it against the sequence's frames), a folder holding a
    ``groundtruth.txt`` alone, or a TUM file. A missing one is a one-line :class:`SequenceError`."""
    source = Path(source)
    path = source / "groundtruth.txt" if source.is_dir() else source
    if not path.is_file():
        raise SequenceError(no_groundtruth_reason(path, purpose))
    if source.is_dir() and (source / "sequence.json").is_file():
        gt = Sequence.open(source).groundtruth()
        if gt is not None:
            return path, gt
    return path, read_tum(path)


def _timestamp_lines(path: Path) -> list[tuple[int, str]]:
    """``(line number, text)`` of the times of a ``timestamps.txt`` (``#`` comments and blank lines skipped)."""
    lines = read_text(path, SequenceError, what="a text file").splitlines()
    return [(k, t) for k, t in ((k, line.strip()) for k, line in enumerate(lines, 1)) if t and not t.startswith("#")]


def _read_timestamps(path: Path) -> np.ndarray:
    """The numbers of a ``timestamps.txt`` (one per line; ``#`` comments and blank lines skipped)."""
    out = []
    for lineno, line in _timestamp_lines(path):
        try:
            out.append(float(line))
        except ValueError:
            raise SequenceError(f"{path}:{lineno}: not a timestamp in seconds: {shown(line)}") from None
    return np.array(out, dtype=float)


def time_text(t_s: float) -> str:
    """A time (s) as ``timestamps.txt`` holds it: the shortest decimal that reads back as the float
    ``t_s``, rounded to the nanosecond (``1700000000.0666``; ``f"{t:.9f}"`` wrote the
    ``1700000000.066600084`` of its binary value, and an export stamped those 84 ns)."""
    return np.format_float_positional(float(t_s), precision=9, unique=True, trim="0")


def time_text_ns(ns: int) -> str:
    """A time in integer nanoseconds (what EuRoC and ROS stamp) as ``timestamps.txt`` holds it:
    seconds with nine decimals, exactly. A float of seconds holds a Unix time only to about 240 ns:
    ``f"{t:.9f}"`` of one wrote other nanoseconds than the recording's (each import and export moved
    a EuRoC stamp by 256 ns)."""
    n = int(ns)
    return f"{'-' if n < 0 else ''}{abs(n) // 1_000_000_000}.{abs(n) % 1_000_000_000:09d}"


def time_ns_of_text(text: str) -> int:
    """The integer nanoseconds of a time in seconds written as text (:func:`time_text_ns`), exactly
    (decimals beyond the ninth rounded half to even)."""
    return int(Decimal(text.strip()).scaleb(9).to_integral_value(ROUND_HALF_EVEN))


def read_height_csv(path: str | os.PathLike) -> np.ndarray:
    """The heights (mm) of a ``height.csv`` (header ``frame,height_mm``): :func:`read_frame_csv`'s
    one column."""
    return read_frame_csv(path, HEIGHT_COLUMNS)[:, 0]


def read_attitude_csv(path: str | os.PathLike) -> np.ndarray:
    """The (N, 2) roll and pitch (rad) of an ``attitude.csv`` (header ``frame,roll_rad,pitch_rad``):
    :func:`read_frame_csv`'s two columns (the module's docstring defines the angles)."""
    return read_frame_csv(path, ATTITUDE_COLUMNS)


_CELLS = {2: "two", 3: "three"}


def read_frame_csv(path: str | os.PathLike, columns: tuple[str, ...]) -> np.ndarray:
    """The (N, len(columns)) values of a per-frame CSV: header ``frame,COLUMN,...``, then
    ``i,value,...`` for frames 0, 1, ... in order; an empty value is NaN (no reading), and so is
    ``nan`` (numpy's ``savetxt`` writes a missing reading so; ``inf`` is refused by the checks); ``#`` comments and
    blank lines skipped. A malformed line is a one-line SequenceError naming the file and the
    line. The reader of ``height.csv`` and ``attitude.csv``; what the values may be is checked
    by :func:`check_heights` and :func:`check_attitude`."""
    path = Path(path)
    header_line = ",".join(("frame", *columns))
    cells_wanted = len(columns) + 1
    out: list[list[float]] = []
    header = False
    for lineno, line in enumerate(read_text(path, SequenceError, what="a text file").splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        if not header:
            if line.replace(" ", "") != header_line:
                raise SequenceError(f"{path}:{lineno}: header {shown(line)}: must be {header_line!r}")
            header = True
            continue
        cells = [c.strip() for c in line.split(",")]
        if len(cells) != cells_wanted:
            n = _CELLS.get(cells_wanted, str(cells_wanted))
            raise SequenceError(f"{path}:{lineno}: {shown(line)}: need {n} cells, {header_line}")
        if cells[0] != str(len(out)):
            raise SequenceError(
                f"{path}:{lineno}: frame {shown(cells[0])}: rows must be frames 0, 1, ... in order, expected {len(out)}"
            )
        row = []
        for col, cell in zip(columns, cells[1:]):
            try:
                row.append(float(cell) if cell else float("nan"))
            except ValueError:
                raise SequenceError(f"{path}:{lineno}: {col} {shown(cell)} of frame {cells[0]}: not a number") from None
        out.append(row)
    if not header:
        raise SequenceError(f"{path}: no header line {header_line!r}")
    return np.array(out, dtype=float).reshape(len(out), len(columns))

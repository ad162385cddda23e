"""A EuRoC/ASL folder as a recording (what ``floorsim export --format euroc`` writes, too).

::

    SOURCE/mav0/cam0/data.csv          #timestamp [ns],filename
    SOURCE/mav0/cam0/data/<t_ns>.png
    SOURCE/mav0/cam0/sensor.yaml       T_BS (body <- camera, m), intrinsics, resolution, distortion
    SOURCE/mav0/cam1/...               right camera, optional
    SOURCE/mav0/state_groundtruth_estimate0/data.csv   T_world_body: t_ns, p (m), q (w, x, y, z), ...

``SOURCE`` may be the folder holding ``mav0`` or ``mav0`` itself. Frame times are the
image stamps (ns -> s). The ground truth is the body's pose; it becomes the camera's,
``T_world_cam0 = T_world_body @ T_BS(cam0)``. The right camera's pose in cam0 is
``T_BS(cam0)^-1 @ T_BS(cam1)``; cam1 frames pair with cam0 frames of the same stamp.
A cam1 whose stamps are not cam0's (a row missing or extra) is refused, naming the first
stamp without its partner: the stereo recording is not made a mono one behind the user's
back. ``ImportOptions.left_only`` (``--left-only``) imports cam0 alone.

What ``floorsim export --format euroc`` adds beside the layout is read back when present (a
flag of ``floorvo import`` wins over it): ``mav0/camN/flatfield.png`` (:data:`FLATFIELD_FILE`,
the camera's flat-field frame), ``camera_height_mm`` in ``mav0/cam0/sensor.yaml``
(:data:`CAMERA_HEIGHT_KEY`, the rig height) and ``mav0/height0/data.csv``
(:data:`HEIGHT_SENSOR`: ``timestamp_ns,height_mm`` rows at cam0 stamps, an empty value for no
reading; a frame without a row has none either) and ``mav0/attitude0/data.csv``
(:data:`ATTITUDE_SENSOR`: ``timestamp_ns,roll_rad,pitch_rad`` rows likewise, the sequence's
``attitude.csv``).
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from floorvo.camera import CAMERA_HEIGHT_RANGE_MM
from floorvo.errors import SequenceError, shown
from floorvo.geometry import invert_T
from floorvo.importers.camera_files import CameraCalibration, load_yaml, read_camera_file, transform_m_to_mm
from floorvo.importers.recording import FrameImages, Recording, read_image_file, size_of
from floorvo.importers.times import read_euroc_groundtruth
from floorvo.io import read_text

__all__ = [
    "CAMERA_HEIGHT_KEY",
    "FLATFIELD_FILE",
    "HEIGHT_NOISE_KEY",
    "HEIGHT_SENSOR",
    "READOUT_KEY",
    "detect",
    "read",
    "mav0_of",
]

log = logging.getLogger(__name__)

#: A camera's flat-field frame, beside its ``data.csv``.
FLATFIELD_FILE = "flatfield.png"
#: The key of cam0's ``sensor.yaml`` holding the camera height above the floor, mm.
CAMERA_HEIGHT_KEY = "camera_height_mm"
#: cam0's ``sensor.yaml`` entry of a rolling shutter's readout, first row to last, ms (a sidecar of
#: ``floorsim export``; the sequence's ``sensor.readout_ms``).
READOUT_KEY = "readout_ms"
#: The sensor folder of a range sensor's camera heights (mm) at cam0's frames.
HEIGHT_SENSOR = "height0"
#: The key of the range sensor's ``sensor.yaml`` holding the standard deviation of its readings, mm
#: (a sequence's ``rig.height_noise_mm``).
HEIGHT_NOISE_KEY = "noise_mm"
#: The sensor folder of an IMU's camera roll and pitch (rad) at cam0's frames.
ATTITUDE_SENSOR = "attitude0"


def mav0_of(source: Path) -> Path | None:
    """The ``mav0`` folder of ``source`` (itself or its child), or None."""
    for cand in (source / "mav0", source):
        if cand.is_dir() and (cand / "cam0" / "data.csv").is_file():
            return cand
    return None


def detect(source: Path) -> bool:
    return source.is_dir() and mav0_of(source) is not None


def _camera_stream(cam_dir: Path) -> tuple[np.ndarray, list[Path]]:
    """``(stamps_ns (N,) int64, files)`` of ``cam_dir/data.csv``, in time order."""
    csv_path = cam_dir / "data.csv"
    stamps, files = [], []
    for lineno, line in enumerate(read_text(csv_path, SequenceError, what="a CSV text file").splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        parts = [p.strip() for p in line.split(",")]
        if len(parts) < 2:
            raise SequenceError(f"{csv_path}:{lineno}: a row is 'timestamp_ns,filename'")
        try:
            stamp = int(parts[0])
        except ValueError:
            raise SequenceError(f"{csv_path}:{lineno}: {shown(parts[0])} is not a timestamp in ns") from None
        if not -(2**63) <= stamp < 2**63:  # 9.2e9 s, inside the 1e10 s of floorvo.tum.MAX_TIME_S: this bound is first
            raise SequenceError(
                f"{csv_path}:{lineno}: timestamp {stamp} ns is beyond what a 64-bit count of ns holds "
                "(9.2e18 ns, 292 years)"
            )
        stamps.append(stamp)
        files.append(cam_dir / "data" / parts[1])
    if not stamps:
        raise SequenceError(f"{csv_path}: lists no frames")
    order = np.argsort(stamps, kind="stable")
    st = np.asarray(stamps, dtype=np.int64)[order]
    if np.any(np.diff(st) <= 0):
        raise SequenceError(f"{csv_path}: two frames share the timestamp {int(st[np.argmin(np.diff(st))])} ns")
    return st, [files[i] for i in order]


def _T_BS_mm(cam_dir: Path) -> np.ndarray:
    """Pose of the camera in the body frame (mm) from ``sensor.yaml``'s ``T_BS``; identity if absent."""
    sensor = cam_dir / "sensor.yaml"
    if not sensor.is_file():
        return np.eye(4)
    d = load_yaml(sensor, "EuRoC sensor.yaml")
    if not isinstance(d, dict) or "T_BS" not in d:
        return np.eye(4)
    return transform_m_to_mm(d["T_BS"], f"{sensor} T_BS")


def _unpaired_stamp(mav: Path, st0: np.ndarray, st1: np.ndarray) -> str:
    """Why cam1's stamps ``st1`` (ns) do not pair one to one with cam0's ``st0``: the first cam0
    stamp without a cam1 row, else the first cam1 row without a cam0 frame; "" when they pair."""
    if np.array_equal(st0, st1):
        return ""
    rule = (
        "a stereo recording needs a cam1 frame at each cam0 stamp and no other; give --left-only to import cam0 alone"
    )
    missing, extra = np.setdiff1d(st0, st1), np.setdiff1d(st1, st0)
    if len(missing):
        k = int(np.searchsorted(st0, missing[0]))
        return (
            f"{mav / 'cam1' / 'data.csv'}: no row at {int(missing[0])} ns, the stamp of cam0's frame {k} "
            f"({len(missing)} of {len(st0)} cam0 stamps have none): {rule}"
        )
    return (
        f"{mav / 'cam1' / 'data.csv'}: the row at {int(extra[0])} ns has no cam0 frame "
        f"({len(extra)} cam1 row(s) without one): {rule}"
    )


def _sensor_mm(sensor: Path, key: str = CAMERA_HEIGHT_KEY) -> float | None:
    """The entry ``key`` of a ``sensor.yaml`` (mm: cam0's :data:`CAMERA_HEIGHT_KEY`, > 0; the range
    sensor's :data:`HEIGHT_NOISE_KEY`, from 0 to the largest camera height,
    :data:`floorvo.camera.CAMERA_HEIGHT_RANGE_MM`), None when absent; another value is a
    one-line error naming this file."""
    if not sensor.is_file():
        return None
    d = load_yaml(sensor, "EuRoC sensor.yaml")
    if not isinstance(d, dict) or key not in d:
        return None
    v = d[key]
    ok = isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v)
    if key == READOUT_KEY:
        if not (ok and v >= 0):
            raise SequenceError(f"{sensor}: {key} = {shown(v)}: must be a finite number of ms >= 0")
    elif key == HEIGHT_NOISE_KEY:
        if not (ok and 0 <= v <= CAMERA_HEIGHT_RANGE_MM[1]):
            raise SequenceError(
                f"{sensor}: {key} = {shown(v)}: must be a finite number of mm >= 0 and at most "
                f"{CAMERA_HEIGHT_RANGE_MM[1]:g}"
            )
    elif not (ok and v > 0):  # the camera height's range is checked where it is used (height_problem)
        raise SequenceError(f"{sensor}: {key} = {shown(v)}: must be a finite number of mm > 0")
    return float(v)


def _frame_values(csv_path: Path, st0: np.ndarray, columns: tuple[str, ...], what: str) -> np.ndarray:
    """(len(st0), len(columns)) values (NaN where none) of a sensor folder's ``data.csv`` at cam0's
    frames: rows ``timestamp_ns,COLUMN,...`` each at a cam0 stamp (one-line error otherwise);
    values are checked as the sequence's ``height.csv`` / ``attitude.csv`` are when written.
    ``what``: the value a row gives ("a height")."""
    rule = ",".join(("timestamp_ns", *columns))
    out = np.full((len(st0), len(columns)), np.nan)
    index = {int(t): k for k, t in enumerate(st0)}
    seen: set[int] = set()
    for lineno, line in enumerate(read_text(csv_path, SequenceError, what="a CSV text file").splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        parts = [p.strip() for p in line.split(",")]
        if len(parts) != len(columns) + 1:
            raise SequenceError(f"{csv_path}:{lineno}: a row is {rule!r} (empty: no reading)")
        try:
            t = int(parts[0])
            v = [float(c) if c else np.nan for c in parts[1:]]
        except ValueError:
            raise SequenceError(f"{csv_path}:{lineno}: {shown(line)} is not {rule!r}") from None
        if t not in index:
            raise SequenceError(f"{csv_path}:{lineno}: {t} ns is the stamp of no cam0 frame: {what} is a frame's")
        if t in seen:
            raise SequenceError(f"{csv_path}:{lineno}: a second row at {t} ns")
        seen.add(t)
        out[index[t]] = v
    return out


def read(source: Path, options=None) -> Recording:
    mav = mav0_of(source)
    if mav is None:
        raise SequenceError(f"{source}: not a EuRoC/ASL folder (no mav0/cam0/data.csv)")
    st0, files0 = _camera_stream(mav / "cam0")
    cal0 = read_camera_file(mav / "cam0" / "sensor.yaml") if (mav / "cam0" / "sensor.yaml").is_file() else None
    T_B0 = _T_BS_mm(mav / "cam0")
    files1: list[Path] | None = None
    cal = cal0
    left_only = bool(getattr(options, "left_only", False))
    if (mav / "cam1").is_dir() and not (mav / "cam1" / "data.csv").is_file() and not left_only:
        raise SequenceError(
            f"{mav / 'cam1'}: no data.csv (a EuRoC camera lists its frames there): the right camera cannot be "
            "read; give --left-only to import cam0 alone"
        )
    if (mav / "cam1" / "data.csv").is_file() and left_only:
        log.info("%s: cam1 left out (left_only)", mav)
    elif (mav / "cam1" / "data.csv").is_file():
        st1, f1 = _camera_stream(mav / "cam1")
        unpaired = _unpaired_stamp(mav, st0, st1)
        if unpaired:
            raise SequenceError(unpaired)
        files1 = f1
        if cal0 is not None and (mav / "cam1" / "sensor.yaml").is_file():
            cam1 = read_camera_file(mav / "cam1" / "sensor.yaml").cam0
            cal = CameraCalibration(cal0.cam0, cam1, invert_T(T_B0) @ _T_BS_mm(mav / "cam1"))
    first = read_image_file(files0[0])
    size = size_of(first)
    frame0 = f"cam0's first frame is {size[0]}x{size[1]} px"
    gt = None
    gt_csv = mav / "state_groundtruth_estimate0" / "data.csv"
    if gt_csv.is_file():
        t_gt, T_world_body = read_euroc_groundtruth(gt_csv)
        gt = (t_gt, T_world_body @ T_B0)

    # the sidecars a flag replaces are not read: a damaged one must not stop the import that replaces it
    flatfields = {
        c: read_image_file(mav / c / FLATFIELD_FILE, size, frame0)
        for c in ("cam0", "cam1")
        if (c == "cam0" or files1 is not None)
        and (mav / c / FLATFIELD_FILE).is_file()
        and not (c == "cam0" and getattr(options, "flatfield", None) is not None)
    }
    height_csv = mav / HEIGHT_SENSOR / "data.csv"
    height_given = getattr(options, "height_signal_mm", None) is not None
    heights = (
        _frame_values(height_csv, st0, ("height_mm",), "a height")[:, 0]
        if height_csv.is_file() and not height_given
        else None
    )
    attitude_csv = mav / ATTITUDE_SENSOR / "data.csv"
    attitude_given = getattr(options, "attitude_signal_rad", None) is not None
    attitude = (
        _frame_values(attitude_csv, st0, ("roll_rad", "pitch_rad"), "an attitude")
        if attitude_csv.is_file() and not attitude_given
        else None
    )

    def frames() -> Iterator[FrameImages]:
        for i, f in enumerate(files0):
            right = None if files1 is None else read_image_file(files1[i], size, frame0)
            yield FrameImages(read_image_file(f, size, frame0), right)  # another size: refused before decoding

    rate = None
    if cal0 is not None:
        d = load_yaml(mav / "cam0" / "sensor.yaml", "EuRoC sensor.yaml")
        r = d.get("rate_hz") if isinstance(d, dict) else None
        rate = float(r) if isinstance(r, (int, float)) and not isinstance(r, bool) and r > 0 else None
    return Recording(
        format="euroc",
        source=source,
        frame_count=len(files0),
        size_px=(first.shape[1], first.shape[0]),
        bit_depth=8 * first.itemsize,
        frames=frames,
        timestamps_s=st0 * 1e-9,
        timestamps_ns=st0,
        fps=rate,
        calibration=cal,
        has_right=files1 is not None,
        groundtruth=gt,
        details={"first_stamp_ns": int(st0[0])},
        height_mm=None if getattr(options, "height_mm", None) is not None else _sensor_mm(mav / "cam0" / "sensor.yaml"),
        flatfields=flatfields,
        height_signal_mm=heights,
        height_noise_mm=None if heights is None else _sensor_mm(mav / HEIGHT_SENSOR / "sensor.yaml", HEIGHT_NOISE_KEY),
        attitude_signal_rad=attitude,
        readout_ms=_sensor_mm(mav / "cam0" / "sensor.yaml", READOUT_KEY),
    )

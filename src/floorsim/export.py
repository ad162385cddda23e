"""Export a sequence folder to a ROS 2 bag or to the EuRoC/ASL folder layout.

Both read a floorvo sequence (:class:`floorvo.sequence.Sequence`) and write with the
libraries made for the format: ``rosbags`` for ROS 2 bags (sqlite3 storage, CDR), plain
CSV and YAML (PyYAML) for EuRoC.

ROS 2 bag topics (frames: ``world`` with z up; ``cam0``/``cam1`` optical frames, OpenCV
axes as in ROS's ``*_optical_frame`` convention; metres):

* ``/cam0/image_raw``, ``/cam1/image_raw`` (sensor_msgs/Image, mono8 or mono16)
* ``/cam0/camera_info``, ``/cam1/camera_info`` (sensor_msgs/CameraInfo, plumb_bob)
* ``/cam0/depth`` (sensor_msgs/Image, 32FC1, metres) when the sequence has depth
* ``/groundtruth/pose`` (geometry_msgs/PoseStamped, T_world_cam0) and ``/tf`` (world -> cam0): one
  message each per ground-truth pose, stamped with the pose's own time (a recording's ground truth
  may be at another rate than its frames: each frame's message held the pose of the same index,
  stamped with the frame's time); ``/tf_static`` (cam0 -> cam1 for stereo)
* ``/cam0/flatfield``, ``/cam1/flatfield`` (sensor_msgs/Image, one message at the first frame's
  stamp): the flat-field frames, when the sequence has them
* ``/cam0/height`` (sensor_msgs/Range, metres, float32) at each frame with a measured height
  (``height.csv``)
* the rig height, the height readings' noise (``rig.height_noise_mm``), the frame rate and a
  rolling shutter's readout (``sensor.readout_ms``) in the bag's ``custom_data``
  (``metadata.yaml``), keys :data:`floorvo.importers.rosbag2.CAMERA_HEIGHT_KEY` (mm),
  ``HEIGHT_NOISE_KEY`` (mm), ``FPS_KEY`` (Hz) and ``READOUT_KEY`` (ms; a bag has no field for them)

EuRoC layout: ``mav0/cam0/data/<t_ns>.png`` + ``data.csv`` + ``sensor.yaml`` (and
``cam1``), ``mav0/state_groundtruth_estimate0/data.csv`` (body = cam0; velocities by
finite differences, biases zero). Frames are stamped with the nanoseconds of ``timestamps.txt``
exactly (:attr:`floorvo.sequence.Sequence.timestamps_ns`; a float of seconds holds a Unix time only
to about 240 ns, and each export and import moved a recording's stamps by 256 ns). Ground-truth
rows carry the image stamps of their frames, to the nanosecond, and other rows their microsecond
(``groundtruth.txt`` holds microseconds); the bag's poses likewise. ``sensor.yaml``'s
``distortion_coefficients`` are EuRoC's radial-tangential (k1, k2, p1, p2), followed by
k3 when the camera has one (OpenCV's order): a reader that takes only four would model
another lens.

The EuRoC export carries what the layout has no file of its own for in sidecars that
``floorvo import`` reads back (other readers ignore them): each camera's flat-field frame as
``mav0/camN/flatfield.png``, the rig height as ``camera_height_mm`` and a rolling shutter's
readout as ``readout_ms`` in ``mav0/cam0/sensor.yaml``
and a range sensor's ``height.csv`` as a sensor folder of its own, ``mav0/height0/data.csv``
(``#timestamp [ns],height [mm]``, a row per cam0 frame, empty where there was no reading; its
``sensor.yaml`` states the readings' noise, ``noise_mm``, where the sequence does), an
IMU's ``attitude.csv`` likewise as ``mav0/attitude0/data.csv`` (``#timestamp [ns],roll
[rad],pitch [rad]``). So
both formats carry the whole sequence (``calib/`` beyond the flat fields aside: a render's
``sensor.json`` and ``exposure.csv``), and ``floorvo import`` gives it back; but for what one
format has no place for, said in a warning line: the bag leaves out ``attitude.csv``, the EuRoC
layout the depth images (``/cam0/depth`` in the bag; the EuRoC export dropped them without a word,
and ``orb-icp`` could not run on what came back).
"""

from __future__ import annotations

import errno
import logging
import os
import re
import secrets
import shutil
import sqlite3
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from floorvo.errors import FloorbenchError, FolderLockedError
from floorvo.geometry import xyz_quat_from_T
from floorvo.importers import rosbag2 as bag_reader
from floorvo.importers.euroc import (
    ATTITUDE_SENSOR,
    CAMERA_HEIGHT_KEY,
    FLATFIELD_FILE,
    HEIGHT_NOISE_KEY,
    HEIGHT_SENSOR,
    READOUT_KEY,
)
from floorvo.io import (
    TEMP_SUFFIX,
    atomic_write_bytes,
    atomic_write_csv,
    atomic_write_text,
    checked_output_path,
    make_folders,
)
from floorvo.locking import lock_folder
from floorvo.sequence import Sequence

__all__ = [
    "FORMATS",
    "euroc_distortion",
    "export_euroc",
    "export_rosbag2",
    "export_sequence",
]

log = logging.getLogger(__name__)


def _ns_of_groundtruth(t_s: float) -> int:
    """The nanosecond stamp of a ground-truth time: ``groundtruth.txt`` (TUM) holds microseconds, and
    a float of seconds a Unix time only to about 240 ns (``round(t * 1e9)`` of one was some hundred
    nanoseconds off the file's microsecond)."""
    return int(round(t_s * 1e6)) * 1000


#: The times (s) each format can stamp: a ROS 2 ``builtin_interfaces/Time`` holds int32 seconds
#: (and ROS refuses a negative time); EuRoC's stamps are int64 nanoseconds from 0.
_STAMP_RANGE_S = {"rosbag2": (0.0, float(2**31 - 1)), "euroc": (0.0, (2**63 - 1) / 1e9)}


def _check_stamps(seq: Sequence, fmt: str) -> None:
    """Refuse, in one line and before anything is written, a sequence with a frame or ground-truth
    time the format cannot stamp (:data:`_STAMP_RANGE_S`): a frame at 3e9 s ended the bag export
    in a ``struct.error`` traceback; a EuRoC export wrote nanosecond stamps past int64."""
    lo, hi = _STAMP_RANGE_S[fmt]
    gt = seq.groundtruth()
    for what, times in (("frame", seq.timestamps_s), ("ground-truth pose", None if gt is None else gt[0])):
        if times is None:
            continue
        bad = np.nonzero(~((times >= lo) & (times <= hi)))[0]
        if len(bad):
            k = int(bad[0])
            raise FloorbenchError(
                f"{seq.root}: {what} {k} at {times[k]:.9g} s cannot be stamped in {fmt} (times from {lo:g} to "
                f"{hi:.4g} s); shift the sequence's times (timestamps.txt, groundtruth.txt) into that range"
            )


def _check_out(out: str | os.PathLike, *, may_exist_empty: bool = True) -> Path:
    """The output path, refused in one line if empty, a file-system root, or taken (an empty folder may do)."""
    path = checked_output_path(out, FloorbenchError)
    taken = path.exists() and (not may_exist_empty or not path.is_dir() or any(path.iterdir()))
    if taken:
        raise FloorbenchError(f"{path}: output exists; choose a new path (exports are not merged into old ones)")
    return path


def _stage_names(final: Path) -> re.Pattern[str]:
    """The names of the temporary folders :func:`_staged` makes for ``final``: ``.NAME.XXXXXXXX.tmp``."""
    return re.compile(re.escape(f".{final.name}.") + r"[0-9a-f]{8}" + re.escape(TEMP_SUFFIX))


def _remove_stale_stages(final: Path) -> list[Path]:
    """Delete the temporary folders of exports to ``final`` that were killed (:func:`_staged`):
    only folders named as they are, beside ``final``, that no running export holds (each
    holds its folder's lock, :func:`floorvo.locking.lock_folder`, for as long as it writes;
    a killed process's lock is gone with it). A symbolic link is never followed. Returns the
    folders removed."""
    removed: list[Path] = []
    if not final.parent.is_dir():
        return removed
    names = _stage_names(final)
    for p in sorted(final.parent.iterdir()):
        if not names.fullmatch(p.name) or p.is_symlink() or not p.is_dir():
            continue
        try:
            lock = lock_folder(p, "export")
        except FolderLockedError:
            continue  # a running export's
        try:
            shutil.rmtree(p)
        finally:
            lock.release()
        log.info("%s: removed the temporary folder of an export that was killed", p)
        removed.append(p)
    return removed


@contextmanager
def _staged(final: Path) -> Iterator[Path]:
    """The path an export writes to, renamed to ``final`` when it is complete: ``final``'s name
    inside a hidden temporary folder ``.NAME.XXXXXXXX.tmp`` beside it, removed with what it holds
    when the export fails. A frame that failed to decode half-way left half an export under the
    final name, which the next export refused as 'output exists'. The folder is locked while the
    export writes, so that a killed export's (it stayed behind, hidden, for good) is removed by
    the next export to the same path (:func:`_remove_stale_stages`) and a running one's is not.
    Of two exports to one path the second to finish is refused (output exists)."""
    make_folders(final.parent)
    _remove_stale_stages(final)
    while True:
        stage = final.parent / f".{final.name}.{secrets.token_hex(4)}{TEMP_SUFFIX}"
        try:
            stage.mkdir()
            break
        except FileExistsError:
            continue
    # waits (briefly) only for another export's clean-up that took this new folder for a stale one;
    # the folder is made again if it removed it
    lock = lock_folder(stage, "export", wait=True)
    try:
        yield stage / final.name
        try:
            os.rename(stage / final.name, final)  # onto a missing path or an empty folder
        except OSError as exc:
            if exc.errno in (errno.EEXIST, errno.ENOTEMPTY):
                raise FloorbenchError(
                    f"{final}: output exists (written while this export ran); choose a new path"
                ) from None
            raise
    finally:
        shutil.rmtree(stage, ignore_errors=True)
        lock.release()


def export_rosbag2(seq: Sequence, out: str | os.PathLike) -> Path:
    """Write ``seq`` as a ROS 2 bag (sqlite3) folder at ``out`` (all or nothing: :func:`_staged`);
    returns its path."""
    _check_stamps(seq, "rosbag2")
    final = _check_out(out, may_exist_empty=False)
    with _staged(final) as dest:
        try:
            _write_rosbag2(seq, dest)
        except sqlite3.Error as exc:
            # the bag's storage (rosbags writes it through sqlite3): a full disk was a 28-line traceback
            # ('database or disk is full', raised as the writer closed)
            why = " ".join(str(exc).split()) or type(exc).__name__
            raise FloorbenchError(f"{final / (final.name + '.db3')}: {why} (sqlite3)") from None
    return final


def _write_rosbag2(seq: Sequence, out: Path) -> None:
    """The bag of :func:`export_rosbag2` at ``out`` (a path that does not exist: the writer makes it)."""
    try:
        from rosbags.rosbag2 import Writer
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise FloorbenchError("ROS 2 export needs the 'rosbags' package: pip install rosbags") from None
    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    Header, Time = T["std_msgs/msg/Header"], T["builtin_interfaces/msg/Time"]
    Image, CameraInfo, Roi = (
        T["sensor_msgs/msg/Image"],
        T["sensor_msgs/msg/CameraInfo"],
        T["sensor_msgs/msg/RegionOfInterest"],
    )
    PoseStamped, Pose = T["geometry_msgs/msg/PoseStamped"], T["geometry_msgs/msg/Pose"]
    Point, Quaternion, Vector3 = (
        T["geometry_msgs/msg/Point"],
        T["geometry_msgs/msg/Quaternion"],
        T["geometry_msgs/msg/Vector3"],
    )
    Range = T["sensor_msgs/msg/Range"]
    Transform, TransformStamped, TFMessage = (
        T["geometry_msgs/msg/Transform"],
        T["geometry_msgs/msg/TransformStamped"],
        T["tf2_msgs/msg/TFMessage"],
    )

    def header(ns: int, frame: str):
        return Header(stamp=Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), frame_id=frame)

    def transform(T44: np.ndarray):
        xyz_mm, q = xyz_quat_from_T(T44)
        xyz = xyz_mm / 1000.0
        return Transform(
            translation=Vector3(x=xyz[0], y=xyz[1], z=xyz[2]), rotation=Quaternion(x=q[0], y=q[1], z=q[2], w=q[3])
        )

    def cam_info(cam, ns: int, frame: str, baseline_tx_m: float = 0.0):
        K = cam.K
        P = np.zeros((3, 4))
        P[:, :3] = K
        P[0, 3] = -cam.fx_px * baseline_tx_m
        return CameraInfo(
            header=header(ns, frame),
            height=cam.height_px,
            width=cam.width_px,
            distortion_model="plumb_bob",
            d=np.asarray(cam.distortion, dtype=np.float64),
            k=K.ravel().astype(np.float64),
            r=np.eye(3).ravel(),
            p=P.ravel(),
            binning_x=0,
            binning_y=0,
            roi=Roi(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
        )

    def image_msg(img: np.ndarray, ns: int, frame: str):
        if img.dtype == np.uint8:
            enc, step, data = "mono8", img.shape[1], img
        elif img.dtype == np.uint16:
            enc, step, data = "mono16", img.shape[1] * 2, img.astype("<u2")
        else:
            enc, step, data = "32FC1", img.shape[1] * 4, img.astype("<f4")
        return Image(
            header=header(ns, frame),
            height=img.shape[0],
            width=img.shape[1],
            encoding=enc,
            is_bigendian=0,
            step=step,
            data=np.frombuffer(np.ascontiguousarray(data).tobytes(), dtype=np.uint8),
        )

    gt = seq.groundtruth()
    stamps, stamps_ns = seq.timestamps_s, seq.timestamps_ns  # the nanoseconds exactly as timestamps.txt has them
    cams = ["cam0"] + (["cam1"] if seq.has_stereo else [])
    if seq.attitude_signal_rad is not None:  # no message of the bag carries it yet (the EuRoC export does)
        log.warning("%s: attitude.csv is left out of the ROS 2 bag (export --format euroc carries it)", seq.root)
    with Writer(out, version=9) as w:
        conns = {}
        for c in cams:
            conns[f"/{c}/image_raw"] = w.add_connection(f"/{c}/image_raw", Image.__msgtype__, typestore=ts)
            conns[f"/{c}/camera_info"] = w.add_connection(f"/{c}/camera_info", CameraInfo.__msgtype__, typestore=ts)
        if seq.has_depth:
            conns["/cam0/depth"] = w.add_connection("/cam0/depth", Image.__msgtype__, typestore=ts)
        flats = {c: seq.flatfield(c) for c in cams}
        for c, flat in flats.items():
            if flat is not None:
                topic = f"/{c}/{bag_reader.FLATFIELD_TOPIC_NAME}"
                conns[topic] = w.add_connection(topic, Image.__msgtype__, typestore=ts)
        heights = seq.height_signal_mm
        if heights is not None:
            conns["/cam0/height"] = w.add_connection("/cam0/height", Range.__msgtype__, typestore=ts)
        if seq.height_mm is not None:
            w.set_custom_data(bag_reader.CAMERA_HEIGHT_KEY, repr(float(seq.height_mm)))
        if heights is not None and seq.height_noise_mm is not None:
            w.set_custom_data(bag_reader.HEIGHT_NOISE_KEY, repr(float(seq.height_noise_mm)))
        w.set_custom_data(bag_reader.FPS_KEY, repr(float(seq.fps)))
        if seq.readout_ms > 0.0:
            w.set_custom_data(bag_reader.READOUT_KEY, repr(float(seq.readout_ms)))
        if gt is not None:
            conns["/groundtruth/pose"] = w.add_connection("/groundtruth/pose", PoseStamped.__msgtype__, typestore=ts)
            conns["/tf"] = w.add_connection("/tf", TFMessage.__msgtype__, typestore=ts)
        T_cam0_cam1 = seq.T_cam0_cam1
        if T_cam0_cam1 is not None:
            conns["/tf_static"] = w.add_connection("/tf_static", TFMessage.__msgtype__, typestore=ts)
            tfs = TFMessage(
                transforms=[
                    TransformStamped(
                        header=header(stamps_ns[0], "cam0"), child_frame_id="cam1", transform=transform(T_cam0_cam1)
                    )
                ]
            )
            w.write(conns["/tf_static"], stamps_ns[0], ts.serialize_cdr(tfs, TFMessage.__msgtype__))

        def put(topic: str, ns: int, msg) -> None:
            w.write(conns[topic], ns, ts.serialize_cdr(msg, msg.__msgtype__))

        for c, flat in flats.items():
            if flat is not None:
                topic = f"/{c}/{bag_reader.FLATFIELD_TOPIC_NAME}"
                put(topic, stamps_ns[0], image_msg(flat, stamps_ns[0], c))
        for i in range(seq.frame_count):
            t_ns = stamps_ns[i]
            if heights is not None and np.isfinite(heights[i]):
                reading = Range(
                    header=header(t_ns, "cam0"),
                    radiation_type=1,  # INFRARED: a range sensor's kind is not recorded; a reading is a reading
                    field_of_view=0.0,
                    min_range=0.0,
                    max_range=float("inf"),
                    range=float(heights[i]) / 1000.0,
                )
                put("/cam0/height", t_ns, reading)
            for c in cams:
                cam = seq.camera_model(c)
                tx = 0.0 if c == "cam0" or T_cam0_cam1 is None else float(T_cam0_cam1[0, 3]) / 1000.0
                put(f"/{c}/image_raw", t_ns, image_msg(seq.image(i, c), t_ns, c))
                put(f"/{c}/camera_info", t_ns, cam_info(cam, t_ns, c, tx))
            if seq.has_depth:
                put("/cam0/depth", t_ns, image_msg((seq.depth_mm(i) / 1000.0).astype(np.float32), t_ns, "cam0"))
        if gt is not None:  # each pose at its own time (a recording's may be at another rate than the frames)
            for ns, Tw in zip(_stamps_ns(gt[0], stamps, stamps_ns), gt[1]):
                tr = transform(Tw)
                pose = Pose(
                    position=Point(x=tr.translation.x, y=tr.translation.y, z=tr.translation.z),
                    orientation=tr.rotation,
                )
                w.write(
                    conns["/groundtruth/pose"],
                    ns,
                    ts.serialize_cdr(PoseStamped(header=header(ns, "world"), pose=pose), PoseStamped.__msgtype__),
                )
                tf = TFMessage(
                    transforms=[TransformStamped(header=header(ns, "world"), child_frame_id="cam0", transform=tr)]
                )
                w.write(conns["/tf"], ns, ts.serialize_cdr(tf, TFMessage.__msgtype__))


def _frame_sidecar(
    folder: Path,
    columns: list[str],
    values: np.ndarray,
    stamps_ns: list[int],
    sensor_type: str,
    comment: str,
    fps: float,
    extra: dict | None = None,
) -> None:
    """A EuRoC-style sensor folder of one reading per cam0 frame: ``data.csv`` (``#timestamp
    [ns]`` at each frame's stamp ``stamps_ns`` (N), then the ``columns`` of ``values`` (N,) or
    (N, k), a NaN written empty: no reading) and ``sensor.yaml`` (``sensor_type``, ``comment``,
    the frame rate, and the entries ``extra``)."""
    folder.mkdir(parents=True, exist_ok=True)
    rows = np.asarray(values, dtype=float).reshape(len(stamps_ns), -1)
    atomic_write_csv(
        folder / "data.csv",
        ["#timestamp [ns]", *columns],
        [(stamps_ns[i], *(None if np.isnan(v) else float(v) for v in row)) for i, row in enumerate(rows)],
    )
    _yaml_dump(
        folder / "sensor.yaml", {"sensor_type": sensor_type, "comment": comment, "rate_hz": float(fps), **(extra or {})}
    )


def _yaml_dump(path: Path, data: dict) -> None:
    import yaml

    atomic_write_text(path, "%YAML:1.0\n" + yaml.safe_dump(data, sort_keys=False, default_flow_style=None))


def euroc_distortion(distortion) -> list[float]:
    """``sensor.yaml`` coefficients of OpenCV's (k1, k2, p1, p2, k3): the first four, and k3 when it is not 0."""
    k = [float(v) for v in (tuple(distortion) + (0.0,) * 5)[:5]]
    return k if k[4] != 0.0 else k[:4]


def _stamps_ns(t_s: np.ndarray, frame_stamps_s: np.ndarray, frame_stamps_ns: list[int]) -> list[int]:
    """Nanosecond stamps of the ground-truth times ``t_s``: a time within 1 us of a frame's (TUM files
    hold microseconds) gets the frame's stamp ``frame_stamps_ns``, another its microsecond
    (:func:`_ns_of_groundtruth`).

    ``frame_stamps_s`` (M,) increasing; ``frame_stamps_ns`` the same times in ns (:attr:`Sequence.timestamps_ns`).
    """
    t_s = np.asarray(t_s, dtype=float)
    f = np.asarray(frame_stamps_s, dtype=float)
    if f.size == 0:
        return [_ns_of_groundtruth(float(t)) for t in t_s]
    j = np.clip(np.searchsorted(f, t_s), 1, max(1, f.size - 1)) if f.size > 1 else np.zeros(t_s.shape, int)
    k = np.where(np.abs(f[j - 1] - t_s) <= np.abs(f[j] - t_s), j - 1, j) if f.size > 1 else j
    return [frame_stamps_ns[kk] if abs(f[kk] - t) <= 1e-6 else _ns_of_groundtruth(float(t)) for t, kk in zip(t_s, k)]


def export_euroc(seq: Sequence, out: str | os.PathLike) -> Path:
    """Write ``seq`` in the EuRoC/ASL layout under ``out/mav0`` (all or nothing: :func:`_staged`;
    ``out`` may be an empty folder); returns ``out``."""
    _check_stamps(seq, "euroc")
    final = _check_out(out)
    with _staged(final) as dest:
        _write_euroc(seq, dest)
    return final


def _write_euroc(seq: Sequence, out: Path) -> None:
    """The folders of :func:`export_euroc` under ``out``."""
    if seq.has_depth:  # the layout has no depth stream
        log.warning(
            "%s: the depth images are left out of the EuRoC export (export --format rosbag2 carries them)", seq.root
        )
    mav = out / "mav0"
    stamps, stamps_ns = seq.timestamps_s, seq.timestamps_ns  # the nanoseconds exactly as timestamps.txt has them
    cams = ["cam0"] + (["cam1"] if seq.has_stereo else [])
    for c in cams:
        d = mav / c / "data"
        d.mkdir(parents=True, exist_ok=True)
        rows = []
        for i in range(seq.frame_count):
            ns = stamps_ns[i]
            src = seq.image_path(i, c)
            seq.image(i, c)  # validates the frame before it is copied
            atomic_write_bytes(d / f"{ns}.png", src.read_bytes())
            rows.append((ns, f"{ns}.png"))
        atomic_write_csv(mav / c / "data.csv", ["#timestamp [ns]", "filename"], rows)
        if seq.flatfield(c) is not None:  # validated, then copied as it is
            atomic_write_bytes(mav / c / FLATFIELD_FILE, (seq.root / "calib" / f"{c}_flatfield.png").read_bytes())
        cam = seq.camera_model(c)
        T_BS = np.eye(4) if c == "cam0" else np.asarray(seq.T_cam0_cam1, dtype=float).copy()
        T_BS[:3, 3] /= 1000.0
        distortion = euroc_distortion(cam.distortion)
        if len(distortion) == 5:
            log.warning("%s: k3 = %g written as a fifth distortion coefficient (EuRoC has four)", c, distortion[4])
        _yaml_dump(
            mav / c / "sensor.yaml",
            {
                "sensor_type": "camera",
                "comment": f"floorbench {seq.meta.get('name', '')} {c}; body frame = cam0"
                + ("; distortion k1, k2, p1, p2, k3 (OpenCV)" if len(distortion) == 5 else ""),
                "T_BS": {"cols": 4, "rows": 4, "data": [float(v) for v in T_BS.ravel()]},
                "rate_hz": float(seq.fps),
                "resolution": [cam.width_px, cam.height_px],
                "camera_model": "pinhole",
                "intrinsics": [cam.fx_px, cam.fy_px, cam.cx_px, cam.cy_px],
                "distortion_model": "radial-tangential",
                "distortion_coefficients": distortion,
                **({CAMERA_HEIGHT_KEY: float(seq.height_mm)} if c == "cam0" and seq.height_mm is not None else {}),
                **({READOUT_KEY: float(seq.readout_ms)} if c == "cam0" and seq.readout_ms > 0.0 else {}),
            },
        )
    # Per-frame sidecars, as EuRoC's other sensors: a stamp, then values (empty = no reading).
    heights = seq.height_signal_mm
    if heights is not None:
        _frame_sidecar(
            mav / HEIGHT_SENSOR,
            ["height [mm]"],
            heights,
            stamps_ns,
            "range",
            "floorbench: cam0's height above the floor (mm) at each cam0 frame; empty = no reading",
            seq.fps,
            None if seq.height_noise_mm is None else {HEIGHT_NOISE_KEY: seq.height_noise_mm},
        )
    attitude = seq.attitude_signal_rad
    if attitude is not None:
        _frame_sidecar(
            mav / ATTITUDE_SENSOR,
            ["roll [rad]", "pitch [rad]"],
            attitude,
            stamps_ns,
            "attitude",
            "floorbench: cam0's roll and pitch against gravity (rad, floorvo.sequence's attitude.csv) "
            "at each cam0 frame; empty = no reading",
            seq.fps,
        )
    gt = seq.groundtruth()
    if gt is not None:
        g = mav / "state_groundtruth_estimate0"
        g.mkdir(parents=True, exist_ok=True)
        t, Ts = gt
        p = Ts[:, :3, 3] / 1000.0
        v = np.gradient(p, t, axis=0) if len(t) > 1 else np.zeros_like(p)
        gt_rows: list[list[object]] = []
        for k, ns in enumerate(_stamps_ns(t, stamps, stamps_ns)):
            _, q = xyz_quat_from_T(Ts[k])
            gt_rows.append(
                [
                    ns,
                    *[f"{x:.9f}" for x in p[k]],
                    *[f"{x:.12f}" for x in (q[3], q[0], q[1], q[2])],
                    *[f"{x:.9f}" for x in v[k]],
                    0,
                    0,
                    0,
                    0,
                    0,
                    0,
                ]
            )
        header = ["#timestamp"] + [
            f" {name}"  # EuRoC's header has a space after each comma
            for name in (
                "p_RS_R_x [m]",
                "p_RS_R_y [m]",
                "p_RS_R_z [m]",
                "q_RS_w []",
                "q_RS_x []",
                "q_RS_y []",
                "q_RS_z []",
                "v_RS_R_x [m s^-1]",
                "v_RS_R_y [m s^-1]",
                "v_RS_R_z [m s^-1]",
                "b_w_RS_S_x [rad s^-1]",
                "b_w_RS_S_y [rad s^-1]",
                "b_w_RS_S_z [rad s^-1]",
                "b_a_RS_S_x [m s^-2]",
                "b_a_RS_S_y [m s^-2]",
                "b_a_RS_S_z [m s^-2]",
            )
        ]
        atomic_write_csv(g / "data.csv", header, gt_rows)


FORMATS = {"rosbag2": export_rosbag2, "euroc": export_euroc}


def export_sequence(seq_dir: str | os.PathLike, fmt: str, out: str | os.PathLike) -> Path:
    """Export the sequence folder ``seq_dir`` in format ``fmt`` (``rosbag2`` or ``euroc``)."""
    if fmt not in FORMATS:
        raise FloorbenchError(f"--format {fmt!r}: unknown (known: {', '.join(FORMATS)})")
    seq = Sequence.open(seq_dir)
    if seq.led_positions_cam_mm is not None:  # homography-6dof's lights check reads them: it runs otherwise on the copy
        log.warning(
            "%s: the rig's LED positions (rig.led_positions_cam_mm) are left out of the %s export: neither "
            "format has a place for them",
            seq.root,
            "EuRoC" if fmt == "euroc" else "ROS 2 bag",
        )
    return FORMATS[fmt](seq, out)

"""A ROS 2 bag as a recording (read with ``rosbags``, sqlite3 or MCAP storage).

Topics by role; a role not given with ``--topic ROLE=NAME`` is found by message type and name:

* ``image``: ``sensor_msgs/Image`` or ``CompressedImage`` (mono8/16, 8UC1/16UC1,
  rgb/bgr(a) 8/16; colour converted to mono); the one image topic without ``depth`` in
  its name, or the one named ``left``/``cam0`` among several;
* ``right``: the image topic named ``right``/``cam1`` (a stereo rig);
* ``depth``: the image topic named ``depth`` (32FC1 metres or 16UC1 millimetres, raw or
  ``compressedDepth`` PNG);
* ``camera_info``, ``right_camera_info``: ``sensor_msgs/CameraInfo`` in the image topic's
  namespace (``/cam0/image_raw`` -> ``/cam0/camera_info``); its first message gives the
  camera (plumb_bob); the right camera's pose in the left's comes from ``/tf_static``
  (left frame -> right frame) or else from the right projection matrix (``P[0,3] = -fx B``);
* ``groundtruth``: ``geometry_msgs/PoseStamped``, ``PoseWithCovarianceStamped``,
  ``TransformStamped`` or ``nav_msgs/Odometry`` (its pose is taken as the camera's,
  ``T_world_cam0``), or ``/tf`` (the transforms whose child is the image's frame); a pose sent
  twice with one stamp is one pose, two different poses with one stamp are refused (the first
  was taken, as a TUM or EuRoC file with two is refused);
* ``flatfield``, ``right_flatfield``: an image topic named ``flatfield`` in the image's (the
  right image's) namespace (``/cam0/flatfield``): its first message is the camera's flat-field
  frame (never taken for a camera's images);
* ``height``: a ``sensor_msgs/Range`` topic with ``height`` in its name (another Range topic
  only when given: a robot's other range sensors measure something else): the camera height
  above the floor, each reading (m) belonging to the frame within 1 ms of its stamp (frames
  without one have none; a reading that is not finite and > 0 is none, and so is one outside
  :data:`floorvo.camera.CAMERA_HEIGHT_RANGE_MM`, counted in one warning line).

The rig height is the bag's ``custom_data`` entry :data:`CAMERA_HEIGHT_KEY` (mm) in
``metadata.yaml``, the height readings' noise its entry :data:`HEIGHT_NOISE_KEY` (mm), and the
nominal frame rate its entry :data:`FPS_KEY` (Hz; without it, the rate of the median spacing of
the frames), as ``floorsim export --format rosbag2`` writes them.

Frame times are the image headers' stamps (the bag's receive time where every stamp is zero;
some zero and some not is refused: two clocks).
A right or depth image belongs to the left image whose stamp is within 1 ms of its own. A left
image without a right partner is refused in one line giving their number and the first, as
EuRoC's cam1 rows are (leaving them out made a stereo sequence with gaps, under one warning);
``ImportOptions.left_only`` (``--left-only``) leaves the right topic out. Left images without a
depth partner are left out, their number and the first in one warning line. A right or depth
image without a left one is not read. The bag is read twice
(stamps and calibration first, images when written), so it is never held in memory.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from floorvo.camera import CAMERA_HEIGHT_RANGE_MM, CameraModel, height_problem, intrinsics_from_K
from floorvo.errors import ConfigError, FloorbenchError, SequenceError, shown, shown_number
from floorvo.geometry import T_from_xyz_quat, invert_T, position_problem
from floorvo.importers.camera_files import CameraCalibration, camera_from_parts, distortion_from, load_yaml
from floorvo.importers.recording import FrameImages, Recording, to_mono
from floorvo.io import IMAGE_FORMATS, image_header_size, image_size_problem
from floorvo.sequence_meta import MAX_FPS_HZ

__all__ = [
    "CAMERA_HEIGHT_KEY",
    "HEIGHT_NOISE_KEY",
    "FPS_KEY",
    "READOUT_KEY",
    "FLATFIELD_TOPIC_NAME",
    "ROLES",
    "detect",
    "read",
    "decode_image",
]

log = logging.getLogger(__name__)

#: Topic roles of ``--topic ROLE=NAME``.
ROLES = (
    "image",
    "right",
    "depth",
    "camera_info",
    "right_camera_info",
    "groundtruth",
    "flatfield",
    "right_flatfield",
    "height",
)
IMAGE_TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")
INFO_TYPE = "sensor_msgs/msg/CameraInfo"
RANGE_TYPE = "sensor_msgs/msg/Range"
#: The last part of a flat-field image topic's name (``/cam0/flatfield``).
FLATFIELD_TOPIC_NAME = "flatfield"
#: The ``custom_data`` key of a bag's ``metadata.yaml`` holding the camera height above the floor, mm.
CAMERA_HEIGHT_KEY = "floorbench.camera_height_mm"
#: The ``custom_data`` key of a bag's ``metadata.yaml`` holding the standard deviation of the height
#: topic's readings, mm (a sequence's ``rig.height_noise_mm``; ``sensor_msgs/Range`` has no field for it).
HEIGHT_NOISE_KEY = "floorbench.height_noise_mm"
#: The ``custom_data`` key of a bag's ``metadata.yaml`` holding the sequence's nominal frame rate, Hz
#: (a bag has no field for it: 29.97 Hz frames came back at the 29.985 Hz of their median spacing).
FPS_KEY = "floorbench.fps"
#: The ``custom_data`` key of a bag's ``metadata.yaml`` holding a rolling shutter's readout, first row
#: to last, ms (the sequence's ``sensor.readout_ms``).
READOUT_KEY = "floorbench.readout_ms"
POSE_TYPES = (
    "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "geometry_msgs/msg/TransformStamped",
    "nav_msgs/msg/Odometry",
)
TF_TYPE = "tf2_msgs/msg/TFMessage"
#: Largest stamp difference (ns) between a left image and its right or depth partner.
PAIR_TOLERANCE_NS = 1_000_000

#: Raw ``sensor_msgs/Image`` encodings: (numpy dtype, channels, channel order).
_ENCODINGS = {
    "mono8": ("u1", 1, ""),
    "8uc1": ("u1", 1, ""),
    "mono16": ("u2", 1, ""),
    "16uc1": ("u2", 1, ""),
    "bgr8": ("u1", 3, "bgr"),
    "rgb8": ("u1", 3, "rgb"),
    "bgra8": ("u1", 4, "bgr"),
    "rgba8": ("u1", 4, "rgb"),
    "bgr16": ("u2", 3, "bgr"),
    "rgb16": ("u2", 3, "rgb"),
    "bgra16": ("u2", 4, "bgr"),
    "rgba16": ("u2", 4, "rgb"),
    "32fc1": ("f4", 1, ""),
}


def detect(source: Path) -> bool:
    """True for a bag folder (``metadata.yaml``) or a ``.db3``/``.mcap`` file."""
    if source.is_dir():
        return (source / "metadata.yaml").is_file()
    return source.is_file() and source.suffix.lower() in (".db3", ".mcap")


def _stamp_ns(msg: Any, bag_ns: int) -> int:
    h = getattr(msg, "header", None)
    if h is None:
        return int(bag_ns)
    ns = int(h.stamp.sec) * 1_000_000_000 + int(h.stamp.nanosec)
    return ns if ns > 0 else int(bag_ns)


def decode_image(msg: Any, msgtype: str, what: str) -> np.ndarray:
    """Pixels of an Image or CompressedImage message: (H, W) mono uint8/uint16, or float32 for 32FC1.

    Colour is returned as (H, W, C) in BGR(A) order, for :func:`to_mono`.
    """
    if msgtype.endswith("CompressedImage"):
        fmt = str(msg.format).lower()
        data = np.asarray(msg.data, dtype=np.uint8)
        if "compresseddepth" in fmt:
            if "32fc1" in fmt:
                raise SequenceError(f"{what}: 32FC1 compressedDepth (inverse-depth quantised) is not supported")
            data = data[12:]  # compressed_depth_image_transport's 12-byte config header
        stated = image_header_size(data.tobytes())  # before decoding: a small file can state gigabytes
        if stated is None:
            raise SequenceError(
                f"{what}: compressed image ({shown(str(msg.format))}) is not a {IMAGE_FORMATS} image whose "
                "header states its size (corrupt, truncated or another format)"
            )
        problem = image_size_problem(stated)
        if problem:
            raise SequenceError(f"{what}: compressed image {problem}")
        img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)
        if img is None:
            raise SequenceError(f"{what}: compressed image ({msg.format!r}) could not be decoded")
        return img
    enc = str(msg.encoding).lower()
    if enc not in _ENCODINGS:
        raise SequenceError(
            f"{what}: image encoding {msg.encoding!r} is not supported (mono8/16, 8UC1/16UC1, rgb/bgr(a)8/16, 32FC1)"
        )
    kind, ch, order = _ENCODINGS[enc]
    dt = np.dtype(kind).newbyteorder(">" if msg.is_bigendian else "<")
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    row_bytes = w * ch * dt.itemsize
    raw = np.asarray(msg.data, dtype=np.uint8)
    if step < row_bytes or raw.size < h * step:
        raise SequenceError(f"{what}: {raw.size} data bytes do not hold {h} rows of step {step} ({msg.encoding})")
    rows = raw[: h * step].reshape(h, step)[:, :row_bytes]
    img = np.ascontiguousarray(rows).view(dt).astype(dt.newbyteorder("="))
    img = img.reshape(h, w, ch) if ch > 1 else img.reshape(h, w)
    if order == "rgb":
        img = np.ascontiguousarray(img[:, :, [2, 1, 0] + ([3] if ch == 4 else [])])
    return img


def _depth_mm(img: np.ndarray, what: str) -> np.ndarray:
    """Depth in mm (float32, 0 = none) from 32FC1 metres or 16UC1 millimetres."""
    if img.dtype == np.float32:
        d = img.astype(np.float64) * 1000.0
    elif img.dtype == np.uint16:
        d = img.astype(np.float64)
    else:
        raise SequenceError(f"{what}: depth of {img.dtype} pixels is not supported (32FC1 m or 16UC1 mm)")
    return np.nan_to_num(d, nan=0.0, posinf=0.0, neginf=0.0).astype(np.float32)


def _camera_of_info(msg: Any, what: str) -> CameraModel | None:
    K = np.asarray(msg.k, dtype=float).reshape(3, 3)
    if K[0, 0] <= 0 or K[1, 1] <= 0:
        return None  # an uncalibrated camera publishes zeros
    fx, fy, cx, cy = intrinsics_from_K(K, f"{what} camera_info k")
    dist = distortion_from(np.asarray(msg.d, dtype=float), msg.distortion_model, what)
    return camera_from_parts(msg.width, msg.height, fx, fy, cx, cy, dist, what)


def _T_of(position: Any, orientation: Any) -> np.ndarray:
    xyz = np.array([position.x, position.y, position.z], dtype=float) * 1000.0
    q = np.array([orientation.x, orientation.y, orientation.z, orientation.w], dtype=float)
    n = float(np.linalg.norm(q))
    if not np.isfinite(xyz).all() or not np.isfinite(q).all() or n < 1e-9:
        raise SequenceError("ground-truth pose with a non-finite value or a zero quaternion")
    far = position_problem(xyz)
    if far:
        raise SequenceError(f"ground-truth pose at {far}")
    return T_from_xyz_quat(xyz, q / n)


def _pose_of(msg: Any, msgtype: str) -> np.ndarray:
    """T (mm) of a pose-like message (see :data:`POSE_TYPES`)."""
    if msgtype.endswith("TransformStamped"):
        return _T_of(msg.transform.translation, msg.transform.rotation)
    pose = msg.pose.pose if msgtype.endswith(("Odometry", "PoseWithCovarianceStamped")) else msg.pose
    return _T_of(pose.position, pose.orientation)


def _namespace(topic: str) -> str:
    return topic.rsplit("/", 1)[0]


def _pick(cands: list[str], words: tuple[str, ...]) -> list[str]:
    return [t for t in cands if any(w in t.lower() for w in words)]


def choose_topics(types: dict[str, str], given: dict[str, str]) -> dict[str, str]:
    """Topic of each role (roles found by type and name where not ``given``); one-line errors."""
    for role, topic in given.items():
        if role not in ROLES:
            raise ConfigError(f"--topic {role}={topic}: unknown role (known: {', '.join(ROLES)})")
        if topic not in types:
            raise ConfigError(f"--topic {role}={topic}: no such topic in the bag (topics: {', '.join(sorted(types))})")
        want = {
            "camera_info": (INFO_TYPE,),
            "right_camera_info": (INFO_TYPE,),
            "groundtruth": POSE_TYPES + (TF_TYPE,),
            "height": (RANGE_TYPE,),
        }.get(role, IMAGE_TYPES)
        if types[topic] not in want:
            raise ConfigError(f"--topic {role}={topic}: is {types[topic]}, a {role} topic is one of {', '.join(want)}")
    out = dict(given)
    images = sorted(t for t, ty in types.items() if ty in IMAGE_TYPES)
    flat_like = [t for t in images if t.rsplit("/", 1)[-1].lower() == FLATFIELD_TOPIC_NAME]
    images = [t for t in images if t not in flat_like]
    depth_like = _pick(images, ("depth",))
    plain = [t for t in images if t not in depth_like and t not in out.values()]
    if "image" not in out:
        if len(plain) == 1:
            out["image"] = plain[0]
        elif len(_pick(plain, ("left", "cam0"))) == 1:
            out["image"] = _pick(plain, ("left", "cam0"))[0]
        elif not plain:
            raise SequenceError(f"bag has no image topic (topics: {', '.join(sorted(types))})")
        else:
            raise ConfigError(f"bag has several image topics ({', '.join(plain)}); choose one with --topic image=NAME")
    rest = [t for t in plain if t != out["image"]]
    if "right" not in out and len(_pick(rest, ("right", "cam1"))) == 1:
        out["right"] = _pick(rest, ("right", "cam1"))[0]
    if "depth" not in out and len(depth_like) == 1:
        out["depth"] = depth_like[0]
    infos = sorted(t for t, ty in types.items() if ty == INFO_TYPE)
    for role, img_role in (("camera_info", "image"), ("right_camera_info", "right")):
        if role in out or img_role not in out:
            continue
        same_ns = [t for t in infos if _namespace(t) == _namespace(out[img_role])]
        if len(same_ns) == 1:
            out[role] = same_ns[0]
        elif role == "camera_info" and len(infos) == 1:
            out[role] = infos[0]
    for role, img_role in (("flatfield", "image"), ("right_flatfield", "right")):
        if role in out or img_role not in out:
            continue
        same_ns = [t for t in flat_like if _namespace(t) == _namespace(out[img_role])]
        if len(same_ns) == 1:
            out[role] = same_ns[0]
    if "height" not in out:
        named = _pick(sorted(t for t, ty in types.items() if ty == RANGE_TYPE), ("height",))
        if len(named) == 1:
            out["height"] = named[0]
    if "groundtruth" not in out:
        poses = sorted(t for t, ty in types.items() if ty in POSE_TYPES)
        named = _pick(poses, ("groundtruth", "ground_truth", "gt"))
        if len(poses) == 1:
            out["groundtruth"] = poses[0]
        elif len(named) == 1:
            out["groundtruth"] = named[0]
        elif len(poses) > 1:
            log.warning("bag has several pose topics (%s); no ground truth taken (--topic groundtruth=NAME)", poses)
        elif "/tf" in types and types["/tf"] == TF_TYPE:
            out["groundtruth"] = "/tf"
    return out


def _open_reader(source: Path):
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise FloorbenchError("ROS 2 bag import needs the 'rosbags' package: pip install rosbags") from None
    path = source.parent if source.is_file() else source
    try:
        reader = AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        if path.is_dir() and not reader.is2:
            # A ROS 2 bag is a folder; AnyReader takes any path ending in .bag for a ROS 1 bag file
            # ("Is a directory"): a folder named rec.bag is read as the ROS 2 bag it is.
            from rosbags.rosbag2 import Reader as Reader2

            reader.is2, reader.readers = True, [Reader2(path)]
        reader.open()
    except Exception as exc:  # rosbags raises its own types for every kind of unreadable bag
        raise SequenceError(
            f"{source}: not a readable ROS 2 bag ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})"
        ) from None
    return reader


def _deserialized(reader: Any, raw: bytes, conn: Any, bag_ns: int, source: Path) -> Any:
    """The message ``raw`` of connection ``conn`` (its topic and type), deserialized; a message
    that is not one (cut short, or garbage) is a one-line :class:`SequenceError` naming the bag,
    the topic and the message's bag time (rosbags raised its own error from deep inside)."""
    try:
        return reader.deserialize(raw, conn.msgtype)
    except Exception as exc:  # rosbags raises its own types, and struct's, for a message it cannot read
        why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise SequenceError(
            f"{source} {conn.topic}: the message at {int(bag_ns)} ns (bag time) cannot be read as {conn.msgtype} ({why})"
        ) from None


def _nearest(sorted_ns: np.ndarray, t: int) -> int | None:
    """The stamp of ``sorted_ns`` (sorted int64 ns) nearest to ``t`` (the earlier one on a tie), or None."""
    if not len(sorted_ns):
        return None
    j = int(np.searchsorted(sorted_ns, t))
    cands = [int(sorted_ns[i]) for i in (j - 1, j) if 0 <= i < len(sorted_ns)]
    return min(cands, key=lambda c: abs(c - t))


def _pair(left_ns: np.ndarray, other_ns: np.ndarray) -> dict[int, int]:
    """``{other stamp: left stamp}`` for each left stamp with an other stamp within tolerance,
    each the other's nearest too (mutual nearest): frames under a millisecond apart gave a frame without a reading its neighbour's, and the neighbour none."""
    other = np.sort(np.asarray(other_ns, dtype=np.int64))
    left = np.sort(np.asarray(left_ns, dtype=np.int64))
    out: dict[int, int] = {}
    for t in left_ns:
        best = _nearest(other, int(t))
        if best is None or abs(best - int(t)) > PAIR_TOLERANCE_NS or best in out:
            continue
        if _nearest(left, best) == int(t):
            out[best] = int(t)
    return out


def read(source: Path, options=None) -> Recording:
    topics_given = dict(getattr(options, "topics", None) or {})
    reader = _open_reader(source)
    try:
        types = {c.topic: c.msgtype for c in reader.connections}
        topics = choose_topics(types, topics_given)
        if getattr(options, "left_only", False):
            for role in ("right", "right_camera_info", "right_flatfield"):
                topics.pop(role, None)
        if getattr(options, "flatfield", None) is not None:  # replaced by the flag: not read
            topics.pop("flatfield", None)
        by_topic: dict[str, list] = {}
        for c in reader.connections:
            by_topic.setdefault(c.topic, []).append(c)
        roles_of: dict[str, list[str]] = {}
        for role, name in topics.items():
            roles_of.setdefault(name, []).append(role)
        conns = [c for t in set(topics.values()) | {"/tf_static"} for c in by_topic.get(t, [])]
        stamps: dict[str, list[int]] = {"image": [], "right": [], "depth": []}
        unstamped: list[int] = []  # bag times (ns) that stood in for a left image's zero header stamp
        infos: dict[str, Any] = {}
        gt_t: list[int] = []
        gt_T: list[np.ndarray] = []
        tf_static: dict[tuple[str, str], np.ndarray] = {}
        frame_id: str = ""
        size: tuple[int, int] | None = None
        dtype = None
        tf_pending: list[tuple[int, str, str, np.ndarray]] = []
        flats: dict[str, np.ndarray] = {}
        height_readings: list[tuple[int, float]] = []  # (stamp ns, range m)
        for conn, bag_ns, raw in reader.messages(connections=conns):
            msg = _deserialized(reader, raw, conn, bag_ns, source)
            roles = roles_of.get(conn.topic, [])
            for role in roles:
                if role in stamps:
                    if role == "image" and _stamp_ns(msg, -1) == -1 and int(bag_ns) != 0:
                        unstamped.append(int(bag_ns))  # (a stamp 0 received at 0, as exported at t = 0, is not)
                    stamps[role].append(_stamp_ns(msg, bag_ns))
                    if role == "image" and size is None:
                        img = decode_image(msg, conn.msgtype, f"{source} {conn.topic}")
                        img = to_mono(img, f"{source} {conn.topic}")
                        size, dtype, frame_id = (img.shape[1], img.shape[0]), img.dtype, str(msg.header.frame_id)
                elif role in ("camera_info", "right_camera_info") and role not in infos:
                    infos[role] = msg
                elif role in ("flatfield", "right_flatfield") and role not in flats:
                    label = f"{source} {conn.topic}"
                    flats[role] = to_mono(decode_image(msg, conn.msgtype, label), label)
                elif role == "height":
                    height_readings.append((_stamp_ns(msg, bag_ns), float(msg.range)))
                elif role == "groundtruth" and conn.msgtype in POSE_TYPES:
                    gt_t.append(_stamp_ns(msg, bag_ns))
                    gt_T.append(_pose_of(msg, conn.msgtype))
                elif role == "groundtruth":
                    for tr in msg.transforms:
                        T = _T_of(tr.transform.translation, tr.transform.rotation)
                        tf_pending.append((_stamp_ns(tr, bag_ns), tr.header.frame_id, tr.child_frame_id, T))
            if conn.topic == "/tf_static" and conn.msgtype == TF_TYPE:
                for tr in msg.transforms:
                    tf_static[(tr.header.frame_id, tr.child_frame_id)] = _T_of(
                        tr.transform.translation, tr.transform.rotation
                    )
    finally:
        reader.close()
    what = f"{source} {topics['image']}"
    if size is None:
        raise SequenceError(f"{what}: the image topic has no messages")
    left = np.asarray(stamps["image"], dtype=np.int64)
    if 0 < len(unstamped) < len(left):
        # two clocks: the bag's receive time of some images beside the camera's stamps of the others
        # sorted a frame to the end of the sequence, 4 s after its neighbours, with exit code 0
        raise SequenceError(
            f"{what}: {len(unstamped)} of {len(left)} images have a zero header stamp (the first received at "
            f"{shown_number(unstamped[0] * 1e-9, '.9f')} s), the others the camera's: frame times from two clocks cannot be put in order"
        )
    if np.any(np.diff(left) <= 0):
        order = np.argsort(left, kind="stable")
        left = left[order]
        if np.any(np.diff(left) == 0):
            raise SequenceError(f"{what}: two images share the stamp {int(left[np.argmin(np.diff(left))])} ns")
    keep = np.ones(len(left), bool)
    partners: dict[str, dict[int, int]] = {}
    within = f"within {PAIR_TOLERANCE_NS / 1e6:g} ms"
    for role in ("right", "depth"):
        if role in topics:
            partners[role] = _pair(left, np.asarray(stamps[role], dtype=np.int64))
            paired = np.isin(left, list(partners[role].values()))
            if not paired.all():
                k = int(np.argmin(paired))
                missing = f"{int((~paired).sum())} of {len(left)} images have no {topics[role]} message {within}"
                first_one = f"the first: image {k} at {int(left[k])} ns"
                if role == "right":  # as EuRoC's cam1 rows (euroc._unpaired_stamp)
                    raise SequenceError(
                        f"{what}: {missing} ({first_one}): a stereo recording needs a right image at each left image's "
                        "stamp; give --left-only to import the left camera alone"
                    )
                log.warning("%s: %s (%s); they are left out", what, missing, first_one)
            keep &= paired
    if not keep.any():
        raise SequenceError(f"{what}: no image has a right/depth partner {within}")
    frames_ns = left[keep]
    index_of = {int(t): k for k, t in enumerate(frames_ns)}

    cal = None
    if "camera_info" in infos:
        cam0 = _camera_of_info(infos["camera_info"], f"{source} {topics['camera_info']}")
        if cam0 is not None:
            cal = CameraCalibration(cam0)
    right_frame = None
    if "right" in topics and cal is not None and "right_camera_info" in infos:
        info1 = infos["right_camera_info"]
        cam1 = _camera_of_info(info1, f"{source} {topics['right_camera_info']}")
        right_frame = info1.header.frame_id
        T01 = None
        if (frame_id, right_frame) in tf_static:
            T01 = tf_static[(frame_id, right_frame)]
        elif (right_frame, frame_id) in tf_static:
            T01 = invert_T(tf_static[(right_frame, frame_id)])
        else:
            P = np.asarray(info1.p, dtype=float).reshape(3, 4)
            if P[0, 0] > 0 and P[0, 3] != 0:
                T01 = np.eye(4)
                T01[0, 3] = -P[0, 3] / P[0, 0] * 1000.0
        if cam1 is not None and T01 is not None:
            cal = CameraCalibration(cal.cam0, cam1, T01)
    if tf_pending:
        to_cam = [(t_ns, parent, T) for t_ns, parent, child, T in tf_pending if child == frame_id]
        if not to_cam:
            raise SequenceError(f"{source} /tf: no transform to the image frame {frame_id!r}; no ground truth")
        tf_parent = to_cam[0][1]
        for t_ns, parent, T in to_cam:
            if parent == tf_parent:
                gt_t.append(t_ns)
                gt_T.append(T)
    gt = None
    if gt_t:
        t_arr = np.asarray(gt_t, dtype=np.int64)
        order = np.argsort(t_arr, kind="stable")
        t_sorted, T_sorted = t_arr[order], np.stack(gt_T)[order]
        first = np.concatenate([[True], np.diff(t_sorted) > 0])
        for j in np.nonzero(~first)[0].tolist():  # the same pose sent twice is one pose; two poses at one time are none
            if not np.allclose(T_sorted[j], T_sorted[j - 1], rtol=0, atol=1e-6):
                raise SequenceError(
                    f"{source} {topics['groundtruth']}: two different poses stamped {int(t_sorted[j])} ns: "
                    "ground truth holds one pose per time (give another topic with --topic groundtruth=NAME)"
                )
        gt = (t_sorted[first] * 1e-9, T_sorted[first])
    has_right = "right" in topics
    has_depth = "depth" in topics
    heights = None
    if "height" in topics:
        heights = np.full(len(frames_ns), np.nan)
        value_of = dict(height_readings)
        implausible = []
        for t_reading, t_frame in _pair(frames_ns, np.asarray(list(value_of), dtype=np.int64)).items():
            r_m = value_of[t_reading]
            if not (np.isfinite(r_m) and r_m > 0):  # REP 117: +-inf is out of range, no reading
                continue
            if height_problem(r_m * 1000.0):
                implausible.append(r_m)
            else:
                heights[index_of[t_frame]] = r_m * 1000.0
        if implausible:
            lo, hi = CAMERA_HEIGHT_RANGE_MM
            log.warning(
                "%s %s: %d reading(s) outside %g-%g mm (the first %.6g m) taken as no reading",
                source,
                topics["height"],
                len(implausible),
                lo,
                hi,
                implausible[0],
            )
    flatfields = {"cam0": flats["flatfield"]} if "flatfield" in flats else {}
    if "right_flatfield" in flats:
        flatfields["cam1"] = flats["right_flatfield"]
    img_topics = {topics[r]: r for r in ("image", "right", "depth") if r in topics}

    def frames() -> Iterator[FrameImages]:
        pending: dict[int, dict[str, np.ndarray]] = {}
        need = {"image"} | ({"right"} if has_right else set()) | ({"depth"} if has_depth else set())
        nxt = 0
        rd = _open_reader(source)
        try:
            cs = [c for c in rd.connections if c.topic in img_topics]
            for conn, bag_ns, raw in rd.messages(connections=cs):
                role = img_topics[conn.topic]
                msg = _deserialized(rd, raw, conn, bag_ns, source)
                t = _stamp_ns(msg, bag_ns)
                t_left = t if role == "image" else partners[role].get(t)
                if t_left is None or t_left not in index_of:
                    continue
                label = f"{source} {conn.topic} at {t} ns"
                img = decode_image(msg, conn.msgtype, label)
                pending.setdefault(t_left, {})[role] = _depth_mm(img, label) if role == "depth" else to_mono(img, label)
                while nxt < len(frames_ns) and need <= set(pending.get(int(frames_ns[nxt]), {})):
                    parts = pending.pop(int(frames_ns[nxt]))
                    yield FrameImages(parts["image"], parts.get("right"), parts.get("depth"))
                    nxt += 1
        finally:
            rd.close()
        if nxt != len(frames_ns):
            raise SequenceError(f"{what}: frame {nxt} at {int(frames_ns[nxt])} ns was not found when read again")

    return Recording(
        format="rosbag2",
        source=source,
        frame_count=len(frames_ns),
        size_px=size,
        bit_depth=8 * np.dtype(dtype).itemsize,
        frames=frames,
        timestamps_s=frames_ns * 1e-9,
        timestamps_ns=frames_ns,
        fps=_custom_number(source, FPS_KEY, "Hz", MAX_FPS_HZ),
        calibration=cal,
        has_right=has_right,
        has_depth=has_depth,
        groundtruth=gt,
        details={"topics": dict(sorted(topics.items())), "camera_frame": frame_id},
        height_mm=None
        if getattr(options, "height_mm", None) is not None
        else _custom_number(source, CAMERA_HEIGHT_KEY, "mm"),
        flatfields=flatfields,
        height_signal_mm=heights,
        height_noise_mm=None
        if heights is None
        else _custom_number(source, HEIGHT_NOISE_KEY, "mm", CAMERA_HEIGHT_RANGE_MM[1], zero_ok=True),
        readout_ms=_custom_number(source, READOUT_KEY, "ms", zero_ok=True),
    )


def _custom_number(source: Path, key: str, unit: str, most: float = np.inf, zero_ok: bool = False) -> float | None:
    """The bag's ``custom_data`` entry ``key`` (:data:`CAMERA_HEIGHT_KEY` and :data:`HEIGHT_NOISE_KEY`
    in mm, :data:`FPS_KEY` in Hz) from its ``metadata.yaml``; None when absent; a value that is not a number > 0 and at most
    ``most`` is a one-line error."""
    path = (source.parent if source.is_file() else source) / "metadata.yaml"
    if not path.is_file():
        return None
    d = load_yaml(path, "ROS 2 bag metadata")
    info = d.get("rosbag2_bagfile_information") if isinstance(d, dict) else None
    custom = info.get("custom_data") if isinstance(info, dict) else None
    if not isinstance(custom, dict) or key not in custom:
        return None
    raw = custom[key]
    try:
        v = float(raw)
    except (TypeError, ValueError):
        v = float("nan")
    if not (np.isfinite(v) and (0 <= v if zero_ok else 0 < v) and v <= most):
        bound = "" if most == np.inf else f" and at most {most:g}"
        least = ">= 0" if zero_ok else "> 0"
        raise SequenceError(f"{path}: custom_data {key} = {shown(raw)}: must be a number of {unit} {least}{bound}")
    return v

"""Camera calibration from the files people have, or from flags.

:func:`read_camera_file` reads, by the keys it finds:

* a ROS ``camera_info`` YAML (``camera_calibration_parsers``: ``image_width``,
  ``image_height``, ``camera_matrix``, ``distortion_model``, ``distortion_coefficients``),
  or a ``sensor_msgs/CameraInfo`` message dumped as YAML (``width``, ``height``, ``k``, ``d``);
* an OpenCV calibration YAML (``%YAML:1.0``, ``!!opencv-matrix`` blocks ``camera_matrix`` /
  ``K`` / ``cameraMatrix`` and ``distortion_coefficients`` / ``D`` / ``distCoeffs``);
* a Kalibr camchain (``cam0``, ``cam1``: ``intrinsics [fu, fv, pu, pv]``, ``resolution``,
  ``distortion_coeffs``, and ``T_cn_cnm1`` of cam1, metres);
* an EuRoC/ASL ``sensor.yaml`` (``intrinsics``, ``resolution``, ``distortion_coefficients``).

Only the pinhole model with OpenCV's radial-tangential distortion (k1, k2, p1, p2[, k3];
ROS ``plumb_bob``, Kalibr ``radtan``) is supported; a fisheye/equidistant calibration is
refused with one line. Translations come in metres and are returned in millimetres.
"""

from __future__ import annotations

import os
from collections.abc import Sequence as SequenceT
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from floorvo.camera import CameraModel, intrinsics_from_K
from floorvo.errors import ConfigError, shown
from floorvo.geometry import invert_T, rigid_problem
from floorvo.io import read_text

__all__ = [
    "CameraCalibration",
    "read_camera_file",
    "camera_from_flags",
    "camera_from_parts",
    "distortion_from",
    "transform_m_to_mm",
    "load_yaml",
]

#: Distortion model names meaning OpenCV's (k1, k2, p1, p2, k3).
RADTAN_MODELS = ("", "plumb_bob", "radtan", "radial-tangential", "radial_tangential", "opencv", "pinhole")


@dataclass(frozen=True)
class CameraCalibration:
    """Intrinsics of the left (or only) camera, and of a right camera with its pose when known.

    ``T_cam0_cam1``: (4, 4) pose of cam1 in cam0's frame, millimetres.
    """

    cam0: CameraModel
    cam1: CameraModel | None = None
    T_cam0_cam1: np.ndarray | None = None


def load_yaml(path: str | os.PathLike, what: str = "camera file") -> Any:
    """Parse a YAML file, OpenCV's dialect included (``%YAML:1.0`` header, ``!!opencv-matrix`` tags).

    A key given twice in one mapping is refused (PyYAML keeps the last one silently).
    """
    try:
        import yaml
    except ImportError:
        raise ConfigError(f"{what} {path}: reading YAML needs the 'pyyaml' package: pip install pyyaml") from None

    class _Loader(yaml.SafeLoader):
        def construct_mapping(self, node, deep=False):  # a key given twice: PyYAML keeps the last, silently
            keys = [self.construct_object(k, deep=True) for k, _ in node.value]
            for i, key in enumerate(keys):
                if key in keys[:i]:
                    raise ConfigError(
                        f"{what} {path}: key {shown(str(key))} is given twice (line {node.value[i][0].start_mark.line + 1})"
                    )
            return super().construct_mapping(node, deep=deep)

    def _matrix(loader, node):
        return loader.construct_mapping(node, deep=True)

    _Loader.add_constructor("tag:yaml.org,2002:opencv-matrix", _matrix)
    path = Path(path)
    text = read_text(path, ConfigError, label=f"{what} {path}", what="a YAML text file")
    if text.startswith("%YAML:"):  # OpenCV writes a directive PyYAML does not know
        text = text.split("\n", 1)[1] if "\n" in text else ""
    try:
        data = yaml.load(text, Loader=_Loader)  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        raise ConfigError(f"{what} {path}: not valid YAML{where}") from None
    return data


def _numbers(value: Any, what: str, count: int | None = None) -> np.ndarray:
    """Finite floats of a list or an OpenCV/ROS matrix block ``{rows, cols, data}``."""
    if isinstance(value, dict) and "data" in value:
        value = value["data"]
    try:
        arr = np.asarray(value, dtype=float).ravel()
    except (TypeError, ValueError):
        raise ConfigError(f"{what}: {shown(value)} is not a list of numbers") from None
    if count is not None and arr.size != count:
        raise ConfigError(f"{what}: needs {count} numbers, got {arr.size}")
    if not np.isfinite(arr).all():
        raise ConfigError(f"{what}: {shown(value)} holds a value that is not a finite number")
    return arr


def distortion_from(coeffs: Any, model: Any, what: str) -> tuple[float, ...]:
    model_s = str(model or "").strip().lower()
    if model_s not in RADTAN_MODELS and model_s != "rational_polynomial":
        raise ConfigError(
            f"{what}: distortion model {model!r} is not supported (pinhole with radial-tangential: "
            "plumb_bob, radtan, k1 k2 p1 p2 [k3])"
        )
    d = _numbers(coeffs, f"{what} distortion") if coeffs is not None else np.zeros(0)
    if d.size > 5 and np.any(d[5:] != 0):
        raise ConfigError(f"{what}: {d.size} distortion coefficients; only k1, k2, p1, p2, k3 are supported")
    if d.size in (1, 2, 3):
        raise ConfigError(f"{what}: {d.size} distortion coefficient(s); need k1, k2, p1, p2 [, k3]")
    out = np.zeros(5)
    out[: min(5, d.size)] = d[:5]
    return tuple(float(v) for v in out)


def camera_from_parts(
    width_px: Any, height_px: Any, fx: Any, fy: Any, cx: Any, cy: Any, distortion: Any, what: str
) -> CameraModel:
    """A :class:`CameraModel` from loosely typed parts, each checked (one-line :class:`ConfigError`)."""
    try:
        w, h = int(width_px), int(height_px)
        if w != float(width_px) or h != float(height_px):
            raise ValueError
    except (TypeError, ValueError):
        raise ConfigError(
            f"{what}: image size {shown(width_px)} x {shown(height_px)} is not a pair of whole numbers"
        ) from None
    f = _numbers([fx, fy, cx, cy], f"{what} intrinsics", 4)
    try:
        return CameraModel(w, h, f[0], f[1], f[2], f[3], tuple(distortion))
    except ConfigError as exc:  # name the file (or flags) the camera came from
        raise ConfigError(f"{what}: {str(exc).removeprefix('camera: ')}") from None


def _get(d: dict, keys: SequenceT[str]) -> Any:
    for k in keys:
        if k in d:
            return d[k]
    return None


def _from_matrix_yaml(d: dict, what: str) -> CameraModel:
    """ROS camera_info YAML, a dumped CameraInfo message, or an OpenCV calibration YAML."""
    K = _numbers(_get(d, ("camera_matrix", "K", "k", "cameraMatrix")), f"{what} camera matrix", 9).reshape(3, 3)
    fx, fy, cx, cy = intrinsics_from_K(K, f"{what} camera matrix")
    w = _get(d, ("image_width", "width", "imageWidth"))
    h = _get(d, ("image_height", "height", "imageHeight"))
    size = _get(d, ("image_size", "imageSize", "resolution"))
    if (w is None or h is None) and size is not None:
        w, h = (list(size) + [None, None])[:2]
    if w is None or h is None:
        raise ConfigError(f"{what}: no image size (image_width and image_height)")
    dist = distortion_from(
        _get(d, ("distortion_coefficients", "D", "d", "distCoeffs", "dist_coeffs")),
        _get(d, ("distortion_model",)),
        what,
    )
    return camera_from_parts(w, h, fx, fy, cx, cy, dist, what)


def _from_intrinsics(d: dict, what: str) -> CameraModel:
    """Kalibr camchain entry or EuRoC sensor.yaml: ``intrinsics [fu, fv, pu, pv]`` and ``resolution [w, h]``."""
    model = str(d.get("camera_model", "pinhole")).lower()
    if model != "pinhole":
        raise ConfigError(f"{what}: camera_model {shown(model)} is not supported (pinhole only)")
    f = _numbers(d.get("intrinsics"), f"{what} intrinsics", 4)
    res = d.get("resolution")
    if not isinstance(res, list) or len(res) != 2:
        raise ConfigError(f"{what}: resolution {shown(res)} is not [width, height]")
    dist = distortion_from(
        _get(d, ("distortion_coeffs", "distortion_coefficients")), d.get("distortion_model", "radtan"), what
    )
    return camera_from_parts(res[0], res[1], f[0], f[1], f[2], f[3], dist, what)


def transform_m_to_mm(value: Any, what: str) -> np.ndarray:
    """A 4x4 transform given in metres (nested list or ``{rows, cols, data}``) with its translation in mm."""
    T = _numbers(value, what, 16).reshape(4, 4)
    problem = rigid_problem(T, tol=1e-5)  # calibration tools write a handful of digits
    if problem:
        raise ConfigError(f"{what}: not a rigid 4x4 transform ({problem})")
    T = T.copy()
    T[:3, 3] *= 1000.0
    return T


def read_camera_file(path: str | os.PathLike) -> CameraCalibration:
    """The calibration in ``path`` (formats in the module docstring); one-line :class:`ConfigError` otherwise."""
    path = Path(path)
    what = f"camera file {path}"
    if not path.is_file():
        raise ConfigError(f"{what}: does not exist")
    d = load_yaml(path)
    if not isinstance(d, dict):
        raise ConfigError(f"{what}: expected a YAML mapping of calibration keys")
    if isinstance(d.get("cam0"), dict):  # Kalibr camchain
        cam0 = _from_intrinsics(d["cam0"], f"{what} cam0")
        c1 = d.get("cam1")
        if isinstance(c1, dict):
            cam1 = _from_intrinsics(c1, f"{what} cam1")
            if "T_cn_cnm1" not in c1:
                raise ConfigError(f"{what} cam1: T_cn_cnm1 (pose of cam0 in cam1, metres) is missing")
            T_cam1_cam0 = transform_m_to_mm(c1["T_cn_cnm1"], f"{what} cam1.T_cn_cnm1")
            return CameraCalibration(cam0, cam1, invert_T(T_cam1_cam0))
        return CameraCalibration(cam0)
    if "intrinsics" in d:  # EuRoC sensor.yaml
        return CameraCalibration(_from_intrinsics(d, what))
    if _get(d, ("camera_matrix", "K", "k", "cameraMatrix")) is not None:
        return CameraCalibration(_from_matrix_yaml(d, what))
    raise ConfigError(
        f"{what}: not a camera calibration this reader knows (ROS camera_info, OpenCV, Kalibr camchain, EuRoC sensor.yaml)"
    )


def camera_from_flags(
    size_px: tuple[int, int],
    fx: float | None,
    fy: float | None,
    cx: float | None,
    cy: float | None,
    distortion: SequenceT[float] | None = None,
) -> CameraModel:
    """The camera of ``--fx --fy --cx --cy [--distortion k1,k2,p1,p2[,k3]]`` for frames of ``size_px``."""
    given = {"--fx": fx, "--fy": fy, "--cx": cx, "--cy": cy}
    missing = [k for k, v in given.items() if v is None]
    if missing:
        raise ConfigError(f"camera flags: {', '.join(missing)} missing (give all of --fx --fy --cx --cy)")
    dist = distortion_from(list(distortion) if distortion else None, "plumb_bob", "--distortion")
    return camera_from_parts(size_px[0], size_px[1], fx, fy, cx, cy, dist, "camera flags")

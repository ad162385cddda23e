"""Pinhole camera model with optional Brown-Conrady distortion.

Pixel coordinates follow OpenCV: ``(u, v)`` = (column, row), the centre of the top-left
pixel at (0, 0). ``K`` is the 3x3 intrinsic matrix in pixels.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from floorvo.errors import ConfigError, shown, shown_number

__all__ = [
    "CameraModel",
    "CAMERA_HEIGHT_RANGE_MM",
    "K_RULE",
    "PRINCIPAL_POINT_RULE",
    "K_problem",
    "FOCAL_LENGTH_RANGE_PX",
    "MAX_DISTORTION_COEFFICIENT",
    "distortion_problem",
    "height_problem",
    "intrinsics_from_K",
]

#: The camera heights above the floor (mm) that any reader or flag accepts, ends included: every
#: floor camera lies between them, from an optical mouse sensor (its lens 2-3 mm above the
#: surface) to a camera under a warehouse roof or on a drone's optical-flow sensor (a few metres).
#: Outside them a height is a unit mistake (0.1 for 100 mm given in metres, 1e5 for 100 mm in
#: micrometres) or garbage (1e9 and 1e-9 mm were taken, and every step came out scaled by them).
CAMERA_HEIGHT_RANGE_MM = (1.0, 20_000.0)


def height_problem(height_mm: Any) -> str | None:
    """Why ``height_mm`` is no camera height above the floor (:data:`CAMERA_HEIGHT_RANGE_MM`), or
    None. The one rule of every height: ``rig.height_mm``, ``height.csv`` readings, a scene's
    ``camera.height_mm``, ``floorvo import --height-mm`` and ``--height-file``, a bag's or
    EuRoC sidecar's height."""
    lo, hi = CAMERA_HEIGHT_RANGE_MM
    try:
        h = float(height_mm)
    except (TypeError, ValueError):
        return "must be a number of mm"
    if not (lo <= h <= hi):  # NaN included
        return f"must be a finite number from {lo:g} to {hi:g} mm (a floor camera's height)"
    return None


#: The focal lengths fx, fy (px) that any camera may have, ends included: 1 px is a field of view
#: of 2 atan(w / 2) (an image of 648 px seeing 3 rad), 1e6 px a 300 mm lens on 0.3 um pixels.
#: Outside them a focal length is a unit mistake or garbage (``--fx 1e308`` was taken, and every
#: step came out 1e-305 mm).
FOCAL_LENGTH_RANGE_PX = (1.0, 1e6)
#: The largest magnitude of an OpenCV distortion coefficient (k1, k2, p1, p2, k3) any camera may
#: have: real calibrations stay within tens (k3 of a poorly constrained wide-angle fit within a few
#: hundred); 1e308 made every pixel of the undistorted image infinite.
MAX_DISTORTION_COEFFICIENT = 1e4

#: The rule a pinhole camera matrix ``K`` follows (:func:`K_problem`).
K_RULE = "must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0"
#: The rule the principal point follows in an image of known size (:func:`K_problem`).
#: Pixel centres count from 0 (OpenCV), so the image's top-left edge is at -0.5: a principal point in
#: the top-left pixel's outer half (-0.25 of a camera binned 2 x 2 from cx = 0) is in the image.
PRINCIPAL_POINT_RULE = "must lie in the image: -0.5 <= cx <= width_px and -0.5 <= cy <= height_px"


def K_problem(K: np.ndarray, size_px: tuple[int, int] | None = None) -> str | None:
    """Why the 3x3 matrix ``K`` (finite numbers) is no pinhole camera matrix, else None: :data:`K_RULE`
    when it is not ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` with ``fx, fy > 0`` (a skew, a bottom
    row other than ``[0, 0, 1]``); with the image size ``size_px = (width_px, height_px)``, the
    principal point's :data:`PRINCIPAL_POINT_RULE` when ``(cx, cy)`` is outside the image (a cx
    given in another unit, or from the calibration of another resolution). The one rule for
    ``sequence.json``, camera files, ``camera_info`` and :class:`CameraModel`. Focal lengths
    outside :data:`FOCAL_LENGTH_RANGE_PX` are refused too."""
    if K[0, 0] <= 0 or K[1, 1] <= 0 or K[0, 1] != 0 or K[1, 0] != 0 or not np.array_equal(K[2], [0, 0, 1]):
        return K_RULE
    lo, hi = FOCAL_LENGTH_RANGE_PX
    fx, fy = float(K[0, 0]), float(K[1, 1])
    if not (lo <= fx <= hi and lo <= fy <= hi):
        return (
            f"focal lengths (fx, fy) = ({shown_number(fx, 'g')}, {shown_number(fy, 'g')}) px must be from "
            f"{lo:g} to {hi:g} px (a camera's focal length in pixels)"
        )
    if size_px is not None:
        w, h = size_px
        cx, cy = float(K[0, 2]), float(K[1, 2])
        if not (-0.5 <= cx <= w and -0.5 <= cy <= h):
            return f"principal point (cx, cy) = ({cx:g}, {cy:g}) px {PRINCIPAL_POINT_RULE} ({w}x{h} px)"
    return None


def distortion_problem(distortion: Any, counts: tuple[int, ...] | None = (4, 5)) -> str | None:
    """Why ``distortion`` is no OpenCV distortion (4 or 5 finite numbers k1, k2, p1, p2[, k3], each
    of magnitude at most :data:`MAX_DISTORTION_COEFFICIENT`; ``counts=None``: any number of
    them), or None. The one rule of ``sequence.json``, camera files, ``camera_info``,
    ``--distortion`` and :class:`CameraModel`."""
    try:
        d = np.asarray(distortion, dtype=float)
    except (TypeError, ValueError):
        return "must be 4 or 5 numbers (OpenCV k1, k2, p1, p2[, k3])"
    if d.ndim != 1 or (counts is not None and len(d) not in counts) or not np.isfinite(d).all():
        return "must be 4 or 5 finite numbers (OpenCV k1, k2, p1, p2[, k3])"
    if d.size and np.abs(d).max() > MAX_DISTORTION_COEFFICIENT:
        return f"each coefficient must be from -{MAX_DISTORTION_COEFFICIENT:g} to {MAX_DISTORTION_COEFFICIENT:g}"
    return None


def intrinsics_from_K(K: Any, what: str = "camera: K") -> tuple[float, float, float, float]:
    """``(fx, fy, cx, cy)`` px of a pinhole camera matrix (:func:`K_problem`); a matrix that is not
    3x3 numbers or breaks the rule is a one-line :class:`~floorvo.errors.ConfigError` naming
    ``what``. Read as ``fx, fy, cx, cy`` alone, a matrix whose bottom row was ``[0, 0, 2]`` gave
    a camera off by a factor 2, silently."""
    try:
        A = np.asarray(K, dtype=float)
    except (TypeError, ValueError):
        A = np.zeros(0)
    if A.shape != (3, 3):
        raise ConfigError(f"{what} = {shown(K)}: must be a 3x3 matrix of numbers")
    fx, fy, cx, cy = float(A[0, 0]), float(A[1, 1]), float(A[0, 2]), float(A[1, 2])
    if not np.isfinite([fx, fy, cx, cy]).all():
        return fx, fy, cx, cy  # CameraModel refuses them, naming every intrinsic
    problem = K_problem(A)
    if problem:
        raise ConfigError(f"{what} = {shown(A.tolist())}: {problem}")
    return fx, fy, cx, cy


@dataclass(frozen=True)
class CameraModel:
    """Intrinsics of one camera.

    Attributes
    ----------
    width_px, height_px:
        Image size.
    fx_px, fy_px, cx_px, cy_px:
        Focal lengths and principal point, in pixels.
    distortion:
        OpenCV coefficients (k1, k2, p1, p2, k3); all zero for an ideal pinhole.
    """

    width_px: int
    height_px: int
    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float
    distortion: tuple[float, ...] = field(default=(0.0, 0.0, 0.0, 0.0, 0.0))

    def __post_init__(self) -> None:
        size = (self.width_px, self.height_px)
        if not all(isinstance(n, (int, np.integer)) and not isinstance(n, bool) and n > 0 for n in size):
            raise ConfigError(
                f"camera: image size must be positive whole pixels, got {shown(self.width_px)}x{shown(self.height_px)}"
            )
        values = (self.fx_px, self.fy_px, self.cx_px, self.cy_px, *self.distortion)
        if not all(isinstance(v, (int, float, np.number)) and not isinstance(v, bool) for v in values):
            raise ConfigError(f"camera: intrinsics and distortion must be numbers, got {shown(values)}")
        if not np.isfinite(np.asarray(values, dtype=float)).all():
            raise ConfigError(f"camera: intrinsics and distortion must be finite, got {shown(values)}")
        if self.fx_px <= 0 or self.fy_px <= 0:
            raise ConfigError(f"camera: focal lengths must be positive, got fx={self.fx_px}, fy={self.fy_px}")
        problem = K_problem(self.K, self.size)
        if problem:
            raise ConfigError(f"camera: {problem}")
        problem = distortion_problem(self.distortion, counts=None)
        if problem:
            raise ConfigError(f"camera: distortion = {shown([float(d) for d in self.distortion])}: {problem}")
        object.__setattr__(self, "distortion", tuple(float(d) for d in self.distortion))

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_sensor(
        cls,
        width_px: int = 648,
        height_px: int = 494,
        pixel_pitch_um: float = 7.4,
        focal_length_mm: float = 6.0,
        distortion: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0),
    ) -> CameraModel:
        """Ideal pinhole from the sensor's pixel pitch and the lens focal length.

        The principal point is the image centre, ((w - 1) / 2, (h - 1) / 2).
        """
        if pixel_pitch_um <= 0 or focal_length_mm <= 0:
            raise ConfigError(
                f"camera: pixel_pitch_um and focal_length_mm must be positive, got {pixel_pitch_um}, {focal_length_mm}"
            )
        f_px = focal_length_mm * 1000.0 / pixel_pitch_um
        return cls(width_px, height_px, f_px, f_px, (width_px - 1) / 2.0, (height_px - 1) / 2.0, tuple(distortion))

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> CameraModel:
        """Inverse of :meth:`to_dict` (the ``camera`` block of ``sequence.json`` and ``map.json``).

        A block that is not a table, lacks ``width_px``, ``height_px`` or ``K``, has a ``K``
        that is not a 3x3 matrix of numbers, or values :class:`CameraModel` refuses raises a
        one-line :class:`~floorvo.errors.ConfigError`.
        """
        if not isinstance(d, Mapping) or not {"width_px", "height_px", "K"} <= set(d):
            raise ConfigError(f"camera: {shown(d)}: need a table with width_px, height_px and K")
        fx, fy, cx, cy = intrinsics_from_K(d["K"], "camera: K")
        distortion = d.get("distortion", (0.0,) * 5)
        if not isinstance(distortion, (list, tuple)):
            raise ConfigError(f"camera: distortion = {shown(distortion)}: must be a list of numbers")
        return cls(d["width_px"], d["height_px"], fx, fy, cx, cy, tuple(distortion))

    def to_dict(self) -> dict:
        """JSON-ready dict: ``K`` (3x3 list), ``width_px``, ``height_px``, ``distortion``."""
        return {
            "model": "pinhole" if not any(self.distortion) else "pinhole-brown-conrady",
            "width_px": self.width_px,
            "height_px": self.height_px,
            "K": self.K.tolist(),
            "distortion": list(self.distortion),
            "distortion_model": "opencv (k1, k2, p1, p2, k3)",
        }

    def to_opencv_yaml(self, **extra: float) -> str:
        """The camera as OpenCV calibration YAML text (``cv::FileStorage``, ``%YAML:1.0``).

        Keys: ``image_width``, ``image_height`` (px), ``camera_matrix`` (3x3 ``K``, px),
        ``distortion_model`` (``plumb_bob``: k1, k2, p1, p2, k3), ``distortion_coefficients``
        (1x5), then every ``extra`` number by its name (e.g. ``camera_height_mm=100.0``). It
        is what ``cv2.FileStorage`` and the ROS/OpenCV calibration readers read.
        """
        import cv2  # only this method needs OpenCV's YAML writer

        fs = cv2.FileStorage("camera.yaml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
        fs.write("image_width", int(self.width_px))
        fs.write("image_height", int(self.height_px))
        fs.write("camera_matrix", self.K)
        fs.write("distortion_model", "plumb_bob")
        fs.write("distortion_coefficients", np.array(self.distortion, dtype=float).reshape(1, -1))
        for key, value in extra.items():
            fs.write(key, float(value))
        return fs.releaseAndGetString()

    # ------------------------------------------------------------------ properties
    @property
    def K(self) -> np.ndarray:
        """3x3 intrinsic matrix."""
        return np.array([[self.fx_px, 0.0, self.cx_px], [0.0, self.fy_px, self.cy_px], [0.0, 0.0, 1.0]])

    @property
    def size(self) -> tuple[int, int]:
        """(width_px, height_px)."""
        return (self.width_px, self.height_px)

    @property
    def has_distortion(self) -> bool:
        return any(d != 0.0 for d in self.distortion)

    def gsd_mm_per_px(self, height_mm: float) -> float:
        """Ground sample distance at ``height_mm`` above a fronto-parallel floor.

        Eq. (1) of paper 000: 2 d tan(theta) / w, with tan(theta) = (w / 2) / f.
        """
        return float(height_mm) / self.fx_px

    def fov_rad(self) -> tuple[float, float]:
        """Full horizontal and vertical field of view (rad)."""
        return (2 * np.arctan(self.width_px / 2 / self.fx_px), 2 * np.arctan(self.height_px / 2 / self.fy_px))

    def square_pinhole(self) -> CameraModel:
        """This camera itself when it is an ideal pinhole with square pixels, else that pinhole:
        ``f = max(fx, fy)`` (no axis is undersampled), the same size and principal point, no
        distortion. The pixels in which a method that assumes a rigid image motion (a floor
        point's distance in pixels proportional to its distance in mm) works: phase-corr's
        correlation, the keyframe map's fits (:mod:`floorvo.mapping`)."""
        if self.fx_px == self.fy_px and not self.has_distortion:
            return self
        f = max(self.fx_px, self.fy_px)
        return CameraModel(self.width_px, self.height_px, f, f, self.cx_px, self.cy_px)

    def rectify_maps(self, pinhole: CameraModel) -> tuple[np.ndarray, np.ndarray] | None:
        """``cv2.remap`` maps (two (H, W) float32 arrays, ``pinhole``'s size) that resample a frame of
        this camera into the ideal ``pinhole`` (no distortion; its own focal lengths and principal
        point): each pixel of ``pinhole`` takes this camera's pixel on the same ray
        (``cv2.initUndistortRectifyMap``). None when ``pinhole`` is this camera (nothing to do)."""
        if pinhole == self:
            return None
        import cv2  # as to_opencv_yaml

        mx, my = cv2.initUndistortRectifyMap(
            self.K, np.asarray(self.distortion), None, pinhole.K, pinhole.size, cv2.CV_32FC1
        )
        return mx, my

    def scaled(self, scale: float) -> CameraModel:
        """The same camera at ``scale`` times the resolution (pixel centres kept consistent).

        A pixel of the scaled image covers ``1 / scale`` pixels of the original, so
        f' = s f and c' = s (c + 0.5) - 0.5.
        """
        if not 0 < scale < np.inf:  # NaN: 'cannot convert float NaN to integer' from inside
            raise ConfigError(f"camera: scale must be a finite number > 0, got {scale}")
        w = max(1, int(round(self.width_px * scale)))
        h = max(1, int(round(self.height_px * scale)))
        sx, sy = w / self.width_px, h / self.height_px
        return CameraModel(
            w,
            h,
            self.fx_px * sx,
            self.fy_px * sy,
            (self.cx_px + 0.5) * sx - 0.5,
            (self.cy_px + 0.5) * sy - 0.5,
            self.distortion,
        )

    # ------------------------------------------------------------------ projection
    def project(self, p_cam: np.ndarray) -> np.ndarray:
        """Project (N, 3) points in the camera frame (mm) to (N, 2) pixels (u, v)."""
        p = np.atleast_2d(np.asarray(p_cam, dtype=float))
        x = p[:, 0] / p[:, 2]
        y = p[:, 1] / p[:, 2]
        if self.has_distortion:
            x, y = self._distort(x, y)
        return np.stack([self.fx_px * x + self.cx_px, self.fy_px * y + self.cy_px], axis=1)

    def unproject(self, uv_px: np.ndarray, depth_mm: np.ndarray | float = 1.0) -> np.ndarray:
        """Back-project (N, 2) pixels at depth(s) ``depth_mm`` (along z) to (N, 3) camera points."""
        uv = np.atleast_2d(np.asarray(uv_px, dtype=float))
        x = (uv[:, 0] - self.cx_px) / self.fx_px
        y = (uv[:, 1] - self.cy_px) / self.fy_px
        if self.has_distortion:
            import cv2

            pts = np.asarray(
                cv2.undistortPoints(uv.reshape(-1, 1, 2), self.K, np.asarray(self.distortion)), dtype=float
            ).reshape(-1, 2)
            x, y = pts[:, 0], pts[:, 1]
        z = np.broadcast_to(np.asarray(depth_mm, dtype=float), x.shape)
        return np.stack([x * z, y * z, z], axis=1)

    def undistorted_px(self, uv_px: np.ndarray) -> np.ndarray:
        """(N, 2) pixels of this camera's ideal pinhole (the same ``K``, no distortion) on the rays
        of the (N, 2) pixels ``uv_px``: ``K (x, y, 1)`` of :meth:`unproject`'s ``(x, y)``, in the
        dtype of ``uv_px`` when it is a float one. ``uv_px`` itself when the camera has no
        distortion. What a method in pixels that assumes a pinhole takes of a distorted lens's
        frames: a triangulation by ``P = K [R | t]``, an epipolar line of a fundamental matrix
        made from ``K``, a plane's homography ``K' (R + t n^T / d) K^-1``."""
        uv = np.asarray(uv_px)
        if not self.has_distortion or uv.size == 0:
            return uv
        x = self.unproject(uv.reshape(-1, 2), 1.0)
        out = np.stack([self.fx_px * x[:, 0] + self.cx_px, self.fy_px * x[:, 1] + self.cy_px], axis=1)
        return out.astype(uv.dtype if uv.dtype.kind == "f" else np.float64).reshape(uv.shape)

    def distorted_px(self, uv_pinhole_px: np.ndarray) -> np.ndarray:
        """The inverse of :meth:`undistorted_px`: the (N, 2) pixels of the frame on the rays of the
        ideal pinhole's (N, 2) pixels ``uv_pinhole_px`` (:meth:`project`), in their float dtype;
        ``uv_pinhole_px`` itself when the camera has no distortion."""
        uv = np.asarray(uv_pinhole_px)
        if not self.has_distortion or uv.size == 0:
            return uv
        flat = uv.reshape(-1, 2).astype(float)
        rays = np.column_stack(
            [(flat[:, 0] - self.cx_px) / self.fx_px, (flat[:, 1] - self.cy_px) / self.fy_px, np.ones(len(flat))]
        )
        out = self.project(rays)
        return out.astype(uv.dtype if uv.dtype.kind == "f" else np.float64).reshape(uv.shape)

    def _distort(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        k1, k2, p1, p2, k3 = (tuple(self.distortion) + (0.0,) * 5)[:5]
        r2 = x * x + y * y
        radial = 1 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2
        xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        return xd, yd

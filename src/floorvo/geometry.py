"""Rigid transforms, rigid fits and pixel <-> floor conversions, in millimetres and radians.

The one place for these primitives: every estimator, the mapping and the metrics use them.

Conventions
-----------
* Poses are 4x4 ``float64`` homogeneous matrices ``T_a_b`` that map points from frame
  ``b`` into frame ``a``: ``p_a = T_a_b @ p_b``. Translations are in millimetres.
  :func:`invert_T` also takes stacks ``(..., 4, 4)``.
* World frame: z up, mean floor plane at z = 0, x the default direction of travel.
* Camera frame: OpenCV's (x right, y down, z along the optical axis).
* A camera looking straight down with yaw 0 has its x axis along world +x, its y axis
  along world -y and its optical axis along world -z (:func:`T_world_cam_down`).
* A tilted downward camera (:func:`T_world_cam_down` with ``roll_rad``, ``pitch_rad``) has
  ``R_world_cam = Rz(yaw) Ry(pitch) Rx(roll) R_down``, rotations about the world's axes;
  roll and pitch are read back from the direction of gravity in the camera frame,
  ``R_world_cam^T (0, 0, -1) = (sin pitch, sin roll cos pitch, cos roll cos pitch)``
  (:func:`attitude_of_T`; the convention of a sequence's ``attitude.csv``), and the yaw is
  the heading of the camera's x axis (:func:`yaw_of_R`), which the tilt leaves unchanged.
* Quaternions are (x, y, z, w), as in TUM files.
* Floor coordinates of a downward camera: a floor point's camera-frame (x, y) in mm at
  depth ``height_mm`` (:func:`pixels_to_floor_mm`). A rigid map of floor points between two
  frames, ``q_b = R2 q_a + t2_mm``, is the planar part of ``T_b_a`` (:func:`planar_T`).
* Rigid fits (:func:`umeyama`, :func:`rigid_fit`, :func:`rigid_fit_robust`) take source and
  destination points ``(N, d)`` and return ``(R, t)`` with ``dst_i ~ R src_i + t``.
* The floor plane seen by a camera (:func:`fit_plane`): ``n . p = d`` for camera-frame
  points ``p`` (mm), ``n`` the unit normal pointing from the camera to the floor (about
  +z for a camera looking down) and ``d > 0`` the camera's height above the plane (mm).
  Its levelled frame (:func:`level_rotation`) has the camera's origin, z along ``n`` and
  the camera's x-y axes turned by the least rotation; there the floor is ``z = d`` and a
  floor point's levelled (x, y) are its floor coordinates, as for a level camera. The
  6-DoF step between two frames is the planar step of the levelled frames (a rotation
  about z, an x-y shift, the height change) composed with the two tilts
  (:func:`plane_step_T`, :func:`floor_plane_step`, :func:`plane_homography_motion`).
"""

from __future__ import annotations

import math
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt
from scipy.spatial.transform import Rotation
from scipy.special import fdtri, ndtr, stdtrit

from floorvo.camera import CameraModel

__all__ = [
    "R_WORLD_CAM_DOWN",
    "make_T",
    "per_interval_px",
    "motion_over_time",
    "invert_T",
    "rigid_problem",
    "RIGID_TOLERANCE",
    "MAX_POSITION_MM",
    "position_problem",
    "rot_z",
    "T_world_cam_down",
    "T_from_xyz_quat",
    "xyz_quat_from_T",
    "se2_from_T",
    "T_from_se2",
    "footprint_T",
    "R_nadir_cam",
    "tilted_camera_T",
    "attitude_of_T",
    "tilt_twist_rad",
    "tilt_change_rad",
    "block_homographies",
    "yaw_of_R",
    "yaws_of_T",
    "umeyama",
    "similarity_fit_2d",
    "rigid_fit",
    "rigid_fit_robust",
    "rigid_fit_2d_information",
    "rigid_fit_precision",
    "t_sigmas",
    "f_sigmas",
    "axis_scales_design",
    "axis_scales_fit",
    "rival_homography_support",
    "consensus_problem",
    "pixels_to_floor_mm",
    "floor_mm_to_pixels",
    "pixel_rigid_to_floor",
    "planar_T",
    "floor_rigid_to_T",
    "fit_plane",
    "plane_fit_precision",
    "depth_floor_plane",
    "depth_floor_plane_precision",
    "floor_plane_step_precision",
    "least_rotation",
    "level_rotation",
    "rays_to_plane",
    "plane_step_T",
    "floor_plane_step",
    "plane_homography_motion",
]

#: Rotation of a camera looking straight down with yaw 0: columns are the camera axes
#: expressed in the world (x_cam = +x_world, y_cam = -y_world, z_cam = -z_world).
R_WORLD_CAM_DOWN = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])


def make_T(R: npt.ArrayLike, t: npt.ArrayLike) -> np.ndarray:
    """Build a 4x4 transform from a 3x3 rotation and a 3-vector translation (mm)."""
    T = np.eye(4)
    T[:3, :3] = np.asarray(R, dtype=float)
    T[:3, 3] = np.asarray(t, dtype=float).reshape(3)
    return T


def invert_T(T: np.ndarray) -> np.ndarray:
    """Inverse of rigid transforms ``T`` (4, 4) or a stack (..., 4, 4): exact ``(R^T, -R^T t)``."""
    T = np.asarray(T, dtype=float)
    if T.ndim < 2 or T.shape[-2:] != (4, 4):
        raise ValueError(f"invert_T: need a (..., 4, 4) array of rigid transforms, got shape {T.shape}")
    Rt = np.swapaxes(T[..., :3, :3], -1, -2)
    out = np.zeros_like(T)
    out[..., :3, :3] = Rt
    out[..., :3, 3] = -(Rt @ T[..., :3, 3:4])[..., 0]
    out[..., 3, 3] = 1.0
    return out


#: The farthest a position may lie from the world origin along any axis, mm: 1e8 m holds any place
#: on Earth in metric map coordinates (UTM northings of 1e7 m included), where float64 still
#: resolves 2e-5 mm. A pose 1e308 m out made every step vanish in rounding, with exit code 0.
MAX_POSITION_MM = 1e11


def position_problem(xyz_mm: Any) -> str | None:
    """Why ``xyz_mm`` (3,) is no position a pose file or flag may give (:data:`MAX_POSITION_MM`), or
    None. The one rule of every reader of poses: TUM files, EuRoC and ROS 2 ground truth,
    ``--initial-pose``."""
    xyz = np.asarray(xyz_mm, dtype=float)
    if not np.isfinite(xyz).all():
        return "a non-finite position"
    far = float(np.max(np.abs(xyz)))
    if far > MAX_POSITION_MM:
        return f"a position {far / 1000.0:.3g} m from the origin (at most {MAX_POSITION_MM / 1000.0:g} m along an axis)"
    return None


#: How far ``R^T R`` may be from the identity, and the bottom row from ``[0, 0, 0, 1]``, in a
#: transform :func:`rigid_problem` accepts (float64 products of rotations stay near 1e-15).
RIGID_TOLERANCE = 1e-6


def rigid_problem(T: Any, tol: float = RIGID_TOLERANCE, *, stack: bool = False, unknown: bool = False) -> str | None:
    """Why ``T`` is not a rigid transform (4, 4) of finite numbers, or None when it is one.

    Rigid: ``R = T[:3, :3]`` orthonormal with ``det R = +1`` (a reflection is not a pose) and the
    bottom row ``[0, 0, 0, 1]``, each within ``tol`` (:data:`RIGID_TOLERANCE`; a file written
    with fewer digits may need more). The reason names the rule broken (for an error message).
    The one rigidity rule: estimator steps, ``rig.T_cam0_cam1``, a camera file's extrinsics, the
    poses the metrics (:mod:`floorvo.metrics`) and TUM writer (:func:`floorvo.tum.format_tum`) take.

    ``stack``: ``T`` is a stack (N, 4, 4) of transforms (N may be 0), each held to the rule; the
    reason names the first that breaks it (``pose 3: ...``). A transposed stack (the translation in
    the bottom row) breaks it; a (4, 4) or (N, 3, 3) array is refused by its shape. ``unknown``: a
    pose holding a NaN is an unknown pose and passes (a frame without ground truth); an infinite
    value does not. Vectorised: ~1 us a pose.
    """
    try:
        if np.iscomplexobj(T):  # made float, its imaginary part was dropped with a warning of numpy's
            return f"complex numbers, not a {'(N, 4, 4)' if stack else '(4, 4)'} array of real numbers"
        A = np.asarray(T, dtype=float)
    except (TypeError, ValueError):
        return f"a {type(T).__name__}, not a {'(N, 4, 4)' if stack else '(4, 4)'} array of numbers"
    if not stack:
        return _rigid_reason(A, tol) if A.shape == (4, 4) else f"shape {A.shape}, not (4, 4)"
    if A.ndim != 3 or A.shape[1:] != (4, 4):
        return f"shape {A.shape}, not (N, 4, 4)"
    check = ~np.isnan(A).any(axis=(1, 2)) if unknown else np.ones(len(A), bool)
    B = A[check]
    with np.errstate(invalid="ignore", over="ignore"):
        R = B[:, :3, :3]
        bad = (
            ~np.isfinite(B).all(axis=(1, 2))
            | (np.abs(B[:, 3] - [0.0, 0.0, 0.0, 1.0]).max(axis=1, initial=0.0) > tol)
            | (np.abs(np.swapaxes(R, 1, 2) @ R - np.eye(3)).max(axis=(1, 2), initial=0.0) > tol)
        )
        bad |= ~bad & ~(np.linalg.det(np.where(bad[:, None, None], np.eye(3), R)) > 0)
    if not bad.any():
        return None
    k = int(np.nonzero(check)[0][np.argmax(bad)])
    return f"pose {k}: {_rigid_reason(A[k], tol)}"


def _rigid_reason(A: np.ndarray, tol: float) -> str | None:
    """:func:`rigid_problem` of one (4, 4) float array."""
    if not np.isfinite(A).all():
        return "holds a non-finite value"
    if np.max(np.abs(A[3] - [0.0, 0.0, 0.0, 1.0])) > tol:
        return f"bottom row {A[3].tolist()}, not [0, 0, 0, 1]"
    R = A[:3, :3]
    if np.max(np.abs(R.T @ R - np.eye(3))) > tol or np.linalg.det(R) <= 0:
        return "its 3x3 part is not a rotation (orthonormal, determinant +1)"
    return None


def rot_z(yaw_rad: float) -> np.ndarray:
    """3x3 rotation about +z by ``yaw_rad`` (counter-clockwise seen from above)."""
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def per_interval_px(M: np.ndarray, n: float) -> np.ndarray:
    """The rigid image motion ``M`` (3x3, centred px) measured over ``n`` frame intervals, over
    one at constant velocity: ``1/n`` of its rotation and of its translation (a prediction; not
    exactly ``M^(1/n)``; a similarity's scale is left out). ``n`` need not be whole: a frame
    interval of another length than the one ``M`` was measured over (frames a camera dropped)."""
    if n == 1:
        return M
    out = rot_z(float(np.arctan2(M[1, 0], M[0, 0])) / n)
    out[:2, 2] = M[:2, 2] / n
    return out


def motion_over_time(M: np.ndarray, measured_span_s: float, span_s: float) -> np.ndarray:
    """The rigid image motion ``M`` (3x3, centred px), measured over ``measured_span_s`` seconds,
    at constant velocity over ``span_s`` seconds (:func:`per_interval_px`): a prediction for a frame
    that follows its reference by another time than ``M``'s (frames a camera dropped). ``M`` as
    it is where the spans agree within 1e-6 (frames at a steady rate, a render's ``i / fps``: its
    runs bit for bit as with a prediction per frame) or either span is unknown (<= 0)."""
    if measured_span_s <= 0.0 or not span_s > 0.0 or abs(span_s / measured_span_s - 1.0) < 1e-6:
        return M
    return per_interval_px(M, measured_span_s / span_s)


def rolling_shutter_undone(
    src_px: np.ndarray,
    dst_px: np.ndarray,
    *,
    interval_s: float,
    row_time_s: float,
    mid_row_px: float,
    rounds: int = 2,
    turn_before: tuple[float, float] | None = None,
    centre_px: tuple[float, float] = (0.0, 0.0),
) -> tuple[np.ndarray, np.ndarray]:
    """Pairs ``src_px -> dst_px`` (N, 2) px of two frames ``interval_s`` apart taken by a
    rolling shutter, moved to where global shutters at the two frame times see them.

    Row ``y`` of a frame is exposed at ``t_frame + (y - mid_row_px) row_time_s``
    (``sequence.json``'s ``sensor.row_time``, :func:`floorvo.sequence_meta.rolling_row_offsets_s`:
    ``mid_row_px`` the centre row, whose pose the ground truth holds; ``row_time_s`` the readout
    over the rows less one; the pairs may be in binned or centred px if both are in the same
    units). A point seen at row ``y1`` and then at ``y2`` moved over ``interval_s + (y2 - y1)
    row_time_s``: a step along the rows reads long by ``1 + dy row_time_s / interval_s`` (both of
    its components: the later rows see the floor later), 3 % at 32 px a frame with a 15 ms
    readout of 494 rows at 30 frames/s; a step along the rows' own direction (x) has no such
    term, and the shear it leaves is the same in both frames.

    The first guess moves each pair back along its own constant velocity (exact for a
    translation). Then, ``rounds`` times, the motion of the moved pairs over the interval is
    fitted (:func:`rigid_fit`: a turn by ``theta`` about a fixed point of the image, or a
    translation), and each pixel seen is carried by that motion, at its constant rate, back over
    its row's time: a camera moving at a constant planar twist moves the floor's picture exactly
    so. At 3 degrees a frame the first guess alone leaves a quarter of the readout's error on a
    turn (the velocity of a chord, not of the row's time).

    ``turn_before``: ``(theta_rad, interval_s)``, the image's turn over the interval before this
    one (the previous step's), where known. The turn rate then changes at a constant rate from
    one interval's middle to the next: the reference frame's rows are carried at the rate of its
    own time, the current frame's at theirs, each a turn about the principal point ``centre_px``
    (in the pairs' units) at the fitted motion's displacement there. With one rate for both, a
    turn whose rate changes (an S-curve) read its steps up to 0.5 % short or long with a 15 ms
    readout: the two frames' rows turned by different amounts, and a turn that varies down the
    rows shifts the picture along the motion. ``row_time_s = 0``: the pairs as given."""
    src = np.asarray(src_px, dtype=float)
    dst = np.asarray(dst_px, dtype=float)
    if row_time_s == 0.0 or len(src) == 0:
        return src, dst
    t_src_s = (src[:, 1] - mid_row_px) * row_time_s
    t_dst_s = (dst[:, 1] - mid_row_px) * row_time_s
    v_px_s = (dst - src) / (interval_s + t_dst_s - t_src_s)[:, None]
    a, b = src - v_px_s * t_src_s[:, None], dst - v_px_s * t_dst_s[:, None]
    if len(src) < 2:
        return a, b
    c = np.asarray(centre_px, dtype=float)
    for _ in range(rounds):
        R, t = rigid_fit(a, b)
        theta = float(np.arctan2(R[1, 0], R[0, 0]))
        theta_src = theta_dst = theta
        if turn_before is not None and turn_before[1] > 0.0:
            # the rate at each frame's time: the intervals' mean rates at their middles, linearly
            rate, rate_before = theta / interval_s, turn_before[0] / turn_before[1]
            accel = (rate - rate_before) / (0.5 * (interval_s + turn_before[1]))
            theta_src = (rate - 0.5 * accel * interval_s) * interval_s
            theta_dst = (rate + 0.5 * accel * interval_s) * interval_s
        moved_c = R @ c + t  # the displacement at the principal point is kept
        a = _carried(src, -t_src_s / interval_s, theta_src, moved_c - rot_z(theta_src)[:2, :2] @ c)
        b = _carried(dst, -t_dst_s / interval_s, theta_dst, moved_c - rot_z(theta_dst)[:2, :2] @ c)
    return a, b


def _carried(p_px: np.ndarray, share: np.ndarray, theta: float, t_px: np.ndarray) -> np.ndarray:
    """Points ``p_px`` (N, 2) carried by ``share`` (N,) of the image motion ``p -> R(theta) p + t_px``
    at its constant rate: the turn by ``share theta`` about the motion's fixed point
    ``c = t / (1 - e^{i theta})`` (complex numbers), ``e^{i share theta} p + (1 - e^{i share theta}) c``;
    ``(1 - e^{i a}) / (1 - e^{i theta}) = sin(a / 2) / sin(theta / 2) e^{i (a - theta) / 2}``, which
    tends to ``share`` (a translation) as ``theta`` goes to 0."""
    z = p_px[:, 0] + 1j * p_px[:, 1]
    alpha = share * theta
    if theta == 0.0:
        ratio = share.astype(complex)
    else:
        ratio = np.sin(alpha / 2) / np.sin(theta / 2) * np.exp(0.5j * (alpha - theta))
    out = np.exp(1j * alpha) * z + ratio * (t_px[0] + 1j * t_px[1])
    return np.column_stack([out.real, out.imag])


def T_world_cam_down(
    x_mm: float,
    y_mm: float,
    height_mm: float,
    yaw_rad: float = 0.0,
    roll_rad: float = 0.0,
    pitch_rad: float = 0.0,
) -> np.ndarray:
    """Pose of a downward-looking camera at (x, y, height) with yaw about world z.

    ``roll_rad`` and ``pitch_rad`` tilt the rig about its forward (x) and lateral (y) axes
    (R = Rz(yaw) Ry(pitch) Rx(roll) R_down, rotations about the world's axes), for
    disturbance models and an attitude signal (:func:`attitude_of_T` reads them back).
    """
    R_tilt = Rotation.from_euler("xy", [roll_rad, pitch_rad]).as_matrix()
    R = rot_z(yaw_rad) @ R_tilt @ R_WORLD_CAM_DOWN
    return make_T(R, [x_mm, y_mm, height_mm])


def T_from_xyz_quat(xyz: np.ndarray, quat_xyzw: np.ndarray) -> np.ndarray:
    """4x4 transform from a translation and an (x, y, z, w) quaternion."""
    return make_T(Rotation.from_quat(np.asarray(quat_xyzw, dtype=float)).as_matrix(), xyz)


def xyz_quat_from_T(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Translation and (x, y, z, w) quaternion (w >= 0) of a 4x4 transform."""
    T = np.asarray(T, dtype=float)
    q = Rotation.from_matrix(T[:3, :3]).as_quat()
    if q[3] < 0:
        q = -q
    return T[:3, 3].copy(), q


def yaw_of_R(R: np.ndarray) -> float:
    """Heading (rad) of a rotation: the angle of its image of +x in the xy-plane.

    For a downward camera pose ``T_world_cam`` this is the rig's yaw.
    """
    R = np.asarray(R, dtype=float)
    return float(np.arctan2(R[1, 0], R[0, 0]))


def yaws_of_T(T: np.ndarray) -> np.ndarray:
    """(N,) heading (rad) of each of the transforms ``T`` (N, 4, 4) or rotations (N, 3, 3), as
    :func:`yaw_of_R`: for the relative steps of a run, the yaw change of each step."""
    T = np.asarray(T, dtype=float)
    return np.arctan2(T[..., 1, 0], T[..., 0, 0])


def se2_from_T(T_world_cam: np.ndarray) -> np.ndarray:
    """(x_mm, y_mm, yaw_rad) of a downward camera pose."""
    T = np.asarray(T_world_cam, dtype=float)
    return np.array([T[0, 3], T[1, 3], yaw_of_R(T[:3, :3])])


def T_from_se2(x_mm: float, y_mm: float, yaw_rad: float, height_mm: float) -> np.ndarray:
    """Downward camera pose from an SE(2) pose and a height (inverse of :func:`se2_from_T`)."""
    return T_world_cam_down(x_mm, y_mm, height_mm, yaw_rad)


def footprint_T(T_world_cam: np.ndarray, height_mm: float) -> np.ndarray:
    """The camera's floor footprint as a level downward camera: (N, 4, 4) poses at
    ``height_mm`` over the floor point on each camera's optical axis, with its yaw.

    What a planar mono estimator sees of a tilted camera: a tilt change of d rad moves the
    footprint by about height x d, which the image shows as a shift (issue 14). For a
    camera looking straight down the footprint is under the camera and this is the pose
    with the height set to ``height_mm``. ``T_world_cam``: (N, 4, 4) or (4, 4), mm; a
    camera whose optical axis does not meet the floor gives NaN.
    """
    T = np.asarray(T_world_cam, dtype=float).reshape(-1, 4, 4)
    z_axis, c = T[:, :3, 2], T[:, :3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.where(z_axis[:, 2] < 0, -c[:, 2] / z_axis[:, 2], np.nan)
    xy = c[:, :2] + d[:, None] * z_axis[:, :2]
    yaw = np.arctan2(T[:, 1, 0], T[:, 0, 0])
    return np.stack([T_world_cam_down(x, y, height_mm, a) for (x, y), a in zip(xy, yaw)])


def tilted_camera_T(
    T_world_footprint: np.ndarray, roll_rad: float, pitch_rad: float, height_mm: float | None = None
) -> np.ndarray:
    """The tilted camera (4, 4) whose floor footprint is ``T_world_footprint``: the inverse of
    :func:`footprint_T` given the camera's attitude.

    ``T_world_footprint`` (4, 4) mm: a level downward camera pose over the floor point on the
    tilted camera's optical axis, with its yaw (what a planar mono estimator measures of a
    tilted camera, issue 14); only its x, y, z and yaw are used. ``roll_rad``, ``pitch_rad``:
    the camera's attitude against gravity (:func:`attitude_of_T`'s convention, a sequence's
    ``attitude.csv``); ``height_mm``: the camera's height above the floor (default: the
    footprint pose's z). The camera has the rotation ``Rz(yaw) Ry(pitch) Rx(roll) R_down``
    (:func:`T_world_cam_down`), whose x axis has the footprint's heading, and sits at that
    height on the line through the footprint point along its optical axis ``a``: ``c_xy =
    f_xy + height * a_xy / a_z``. So ``footprint_T(tilted_camera_T(F, r, p, h), F_z) == F`` and
    ``tilted_camera_T(footprint_T(T, h), *attitude_of_T(T), T_z) == T`` (to rounding).
    """
    F = np.asarray(T_world_footprint, dtype=float)
    h = float(F[2, 3]) if height_mm is None else float(height_mm)
    T = T_world_cam_down(0.0, 0.0, h, yaw_of_R(F[:3, :3]), float(roll_rad), float(pitch_rad))
    a = T[:3, 2]
    T[:2, 3] = F[:2, 3] + h * a[:2] / a[2]
    return T


def attitude_of_T(T_world_cam: np.ndarray) -> np.ndarray:
    """(roll_rad, pitch_rad) of a camera pose (4, 4), or (N, 2) of a stack (N, 4, 4): the
    direction of gravity (world -z) in the camera frame, ``g = R_world_cam^T (0, 0, -1) = (sin
    pitch, sin roll cos pitch, cos roll cos pitch)``, as ``roll = atan2(g_y, g_z)`` and ``pitch
    = asin(g_x)``. (0, 0) for a camera looking straight down, whatever its yaw; the ``roll_rad``
    and ``pitch_rad`` of :func:`T_world_cam_down` (for tilts under 90 degrees); what an IMU's
    attitude filter gives (a sequence's ``attitude.csv``)."""
    T = np.asarray(T_world_cam, dtype=float)
    g = -T[..., 2, :3]  # the third row of R: R^T (0, 0, 1)
    return np.stack([np.arctan2(g[..., 1], g[..., 2]), np.arcsin(np.clip(g[..., 0], -1.0, 1.0))], axis=-1)


def R_nadir_cam(roll_rad: float, pitch_rad: float) -> np.ndarray:
    """(3, 3) rotation from the frame of a camera at attitude ``roll_rad``, ``pitch_rad``
    (:func:`attitude_of_T`) to that of a camera at the same centre and yaw looking straight
    down: ``R_down^T Ry(pitch) Rx(roll) R_down``. A ray ``v`` of the tilted camera is
    ``R_nadir_cam v`` in the level one, so its pixels move by the homography
    ``K R_nadir_cam K^-1`` (levelling a frame with an attitude signal)."""
    return R_WORLD_CAM_DOWN.T @ T_world_cam_down(0.0, 0.0, 1.0, 0.0, roll_rad, pitch_rad)[:3, :3]


def tilt_twist_rad(attitude_prev_rad: npt.ArrayLike, attitude_cur_rad: npt.ArrayLike) -> float:
    """The rotation (rad) about the optical axis, camera z, between two tilts of a camera whose
    yaw is unchanged: the z component of the rotation vector of ``R_prev^T R_cur`` for the
    rotations ``Ry(pitch) Rx(roll) R_down`` of the two (roll, pitch) attitudes
    (:func:`attitude_of_T`).

    A planar mono estimator reads the rotation of the picture about its centre as the yaw
    step; a tilted camera whose roll and pitch change out of phase (a coning motion) turns
    about its optical axis while its heading stays: about ``(roll dpitch - pitch droll) / 2``
    a frame, 0.14 mrad on the motion suite's tilt (0.03 rad of each at 1.5 Hz, 30 fps), which
    summed over the steps turns the whole run (0.5 mm across 116 mm of a synthetic run). The
    runner takes it out of the step with an attitude signal (:func:`floorvo.runner.run_frames`).
    """
    (r0, p0), (r1, p1) = np.asarray(attitude_prev_rad, dtype=float), np.asarray(attitude_cur_rad, dtype=float)
    R0 = Rotation.from_euler("xy", [r0, p0]).as_matrix() @ R_WORLD_CAM_DOWN
    R1 = Rotation.from_euler("xy", [r1, p1]).as_matrix() @ R_WORLD_CAM_DOWN
    return float(Rotation.from_matrix(R0.T @ R1).as_rotvec()[2])


def tilt_change_rad(attitude_prev_rad: npt.ArrayLike, attitude_cur_rad: npt.ArrayLike) -> float:
    """The angle (rad) between the optical axes of a camera at two attitudes (roll_rad,
    pitch_rad) (:func:`attitude_of_T`) and the same yaw: how far it tilted from one to the
    other. The axis of a camera at attitude ``a`` is ``R_nadir_cam(a) (0, 0, 1)`` in the frame
    of the level camera at that yaw (:func:`R_nadir_cam`)."""
    z0 = R_nadir_cam(*np.asarray(attitude_prev_rad, dtype=float))[:, 2]
    z1 = R_nadir_cam(*np.asarray(attitude_cur_rad, dtype=float))[:, 2]
    return float(np.arctan2(np.linalg.norm(np.cross(z0, z1)), float(z0 @ z1)))


# ----------------------------------------------------------------------------- rigid fits
def umeyama(
    src: np.ndarray, dst: np.ndarray, weights: np.ndarray | None = None, *, with_scale: bool = False
) -> tuple[np.ndarray, np.ndarray, float]:
    """Least-squares similarity ``dst_i ~ s R src_i + t`` of matched points (Kabsch/Umeyama).

    Minimises ``sum_i w_i |dst_i - (s R src_i + t)|^2`` in closed form (Umeyama 1991, eqs.
    (34)-(42); the same SVD solution as paper 001's ICP step, eqs. (11)-(22)):

    * weighted centroids ``mu_s``, ``mu_d`` (eq. (12) of paper 001) and centred points;
    * ``W = sum_i w_i (dst_i - mu_d)(src_i - mu_s)^T`` (eq. (20)), ``W = U S V^T`` (eq. (21));
    * ``R = U diag(1, .., 1, det(U V^T)) V^T`` (eq. (22), ``R = U V^T``, with the reflection
      check). Paper 001 takes ``-R`` when ``det(U V^T) < 0``; that is not the best
      rotation. The closed form flips the
      singular vector of the smallest singular value instead. It matters for every planar
      point set (a floor in 3D), whose W has rank 2 and an arbitrary third singular vector;
    * ``s = trace(S diag(1, .., d)) / sum_i w_i |src_i - mu_s|^2`` when ``with_scale``, else 1;
    * ``t = mu_d - s R mu_s`` (eq. (17) of paper 001).

    ``src``, ``dst``: (N, d) with N >= d (and not all on a line in 3D); ``weights``: (N,)
    non-negative, not all zero, None = equal. Returns ``(R (d, d), t (d,), s)``, det R = +1.
    """
    src = np.asarray(src, dtype=float)
    dst = np.asarray(dst, dtype=float)
    if src.shape != dst.shape or src.ndim != 2 or src.shape[0] < max(2, src.shape[1]):
        d = src.shape[1] if src.ndim == 2 else "d"
        raise ValueError(f"rigid fit: need two (N, {d}) arrays with N >= {d}, got {src.shape} and {dst.shape}")
    n, d = src.shape
    w = np.ones(n) if weights is None else np.asarray(weights, dtype=float)
    if w.shape != (n,) or not np.all(w >= 0) or w.sum() <= 0:
        raise ValueError(f"rigid fit: weights must be (N,) = ({n},), non-negative, not all zero; got shape {w.shape}")
    w = w / w.sum()
    mu_s = w @ src
    mu_d = w @ dst
    xs = src - mu_s
    W = ((dst - mu_d) * w[:, None]).T @ xs
    U, S, Vt = np.linalg.svd(W)
    D = np.ones(d)
    D[-1] = np.sign(np.linalg.det(U @ Vt)) or 1.0
    R = (U * D) @ Vt
    s = float(S @ D / (w @ (xs**2).sum(axis=1))) if with_scale else 1.0
    t = mu_d - s * R @ mu_s
    return R, t, s


def similarity_fit_2d(
    src: np.ndarray, dst: np.ndarray, *, with_scale: bool = True
) -> tuple[np.ndarray, np.ndarray, float]:
    """:func:`umeyama` ``(R, t, s)`` of a few 2-D point pairs (equal weights), in closed form and
    plain Python: a few microseconds where :func:`umeyama`'s checks and SVD take about 22 us
    for four points (phase-corr fits its four blocks two to three times a frame). A similarity
    by default, the rigid fit (``s = 1``, :func:`rigid_fit`) without ``with_scale``: the same
    rotation.

    In 2-D the best rotation maximises ``a cos(theta) + b sin(theta)`` with ``a = sum_i xs_i .
    yd_i`` and ``b = sum_i xs_i x yd_i`` (the centred points), so ``theta = atan2(b, a)``, and
    the trace Umeyama's scale divides is ``hypot(a, b)`` (the two singular values' sum, or
    their difference where the reflection check flips one): the same fit to rounding (1e-15).
    For a few points only: its plain-Python loop grows with N, and for the hundreds of pairs
    the AKAZE estimators fit, :func:`umeyama`'s vectorised sums and SVD are the faster (300
    pairs: 31 us against 85).
    ``src``, ``dst``: (N, 2), N >= 2, ``src`` not all at one point; coincident ``dst`` points
    (``a = b = 0``) give the identity rotation."""
    ps, pd = np.asarray(src, dtype=float).tolist(), np.asarray(dst, dtype=float).tolist()
    n = len(ps)
    sx, sy = sum(p[0] for p in ps) / n, sum(p[1] for p in ps) / n
    dx, dy = sum(q[0] for q in pd) / n, sum(q[1] for q in pd) / n
    a = b = ss = 0.0
    for (px, py), (qx, qy) in zip(ps, pd, strict=True):
        px, py, qx, qy = px - sx, py - sy, qx - dx, qy - dy
        a += px * qx + py * qy
        b += px * qy - py * qx
        ss += px * px + py * py
    h = math.hypot(a, b)
    c, s = (a / h, b / h) if h > 0.0 else (1.0, 0.0)
    scale = h / ss if with_scale else 1.0
    R = np.array([[c, -s], [s, c]])
    return R, np.array([dx - scale * (c * sx - s * sy), dy - scale * (s * sx + c * sy)]), scale


def nearest_rotation_2d(M: np.ndarray) -> np.ndarray:
    """The rotation (2, 2) nearest ``M`` (2, 2) in the Frobenius norm: ``theta = atan2(M10 - M01,
    M00 + M11)``, which maximises ``trace(R^T M)``. Where ``det M > 0`` (a rotation scaled or
    sheared by a little) it is the ``U V^T`` of ``M``'s SVD, to rounding (1e-15), in a sixth of
    the time (0.8 us against 5.4)."""
    (m00, m01), (m10, m11) = np.asarray(M, dtype=float).tolist()
    h = math.hypot(m00 + m11, m10 - m01)
    c, s = ((m00 + m11) / h, (m10 - m01) / h) if h > 0.0 else (1.0, 0.0)
    return np.array([[c, -s], [s, c]])


def rigid_fit(src: np.ndarray, dst: np.ndarray, weights: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares rigid motion ``dst_i ~ R src_i + t`` (no scale): :func:`umeyama`'s ``(R, t)``.

    ``src``, ``dst``: (N, d) matched points (d = 2 for image or floor points, 3 for 3D).
    """
    R, t, _ = umeyama(src, dst, weights)
    return R, t


def rigid_fit_2d_information(
    src: np.ndarray, dst: np.ndarray, information: np.ndarray, *, iterations: int = 2
) -> tuple[np.ndarray, np.ndarray]:
    """Generalised least-squares rigid motion ``dst_i ~ R src_i + t`` in 2-D, each pair's residual
    weighted by its own 2 x 2 ``information`` matrix (the inverse of its error's covariance, up to
    one common factor): ``min sum_i r_i^T I_i r_i``. A point located precisely along one axis and
    poorly along the other (a block of a grained floor, whose shift along the grain is hardly
    measured) then sets the motion along the first axis only. With every ``I_i`` the identity it
    is :func:`similarity_fit_2d`'s rigid fit.

    Gauss-Newton on ``(theta, t)`` from the equal-weight fit, ``iterations`` steps, in plain
    Python as :func:`similarity_fit_2d` (phase-corr fits its blocks two to four times a frame):
    the rotations between frames are small, and the first step leaves the angle within about
    1e-6 rad of the optimum, the second within rounding. ``src``, ``dst``: (N, 2), N >= 2 points
    not all at one point; ``information``: (N, 2, 2) symmetric positive semi-definite, whose sum
    over the points is positive definite. Returns ``(R (2, 2), t (2,))``."""
    a = np.asarray(src, dtype=float).reshape(-1, 2)
    b = np.asarray(dst, dtype=float).reshape(-1, 2)
    W = np.asarray(information, dtype=float).reshape(-1, 2, 2)
    if len(b) != len(a) or len(W) != len(a) or len(a) < 2:
        raise ValueError(
            f"rigid_fit_2d_information: need (N, 2), (N, 2) and (N, 2, 2) arrays, N >= 2; got "
            f"{a.shape}, {b.shape}, {W.shape}"
        )
    R, t, _ = similarity_fit_2d(a, b, with_scale=False)
    theta, tx, ty = math.atan2(R[1, 0], R[0, 0]), float(t[0]), float(t[1])
    pts = list(zip(a.tolist(), b.tolist(), W.reshape(-1, 4).tolist(), strict=True))
    for _ in range(iterations):
        c, s = math.cos(theta), math.sin(theta)
        # Normal equations H dp = -g of the residuals r = R a + t - b, p = (theta, tx, ty):
        # the Jacobian rows are (-(R a)_y, 1, 0) for r_x and ((R a)_x, 0, 1) for r_y.
        h = [0.0] * 6  # H00 H01 H02 H11 H12 H22
        g0 = g1 = g2 = 0.0
        for (ax, ay), (bx, by), (wxx, wxy, _, wyy) in pts:
            rax, ray = c * ax - s * ay, s * ax + c * ay
            rx, ry = rax + tx - bx, ray + ty - by
            # W J columns: for theta (-ray, rax), for tx (1, 0), for ty (0, 1).
            u0, u1 = wxx * -ray + wxy * rax, wxy * -ray + wyy * rax
            h[0] += -ray * u0 + rax * u1
            h[1] += u0
            h[2] += u1
            h[3] += wxx
            h[4] += wxy
            h[5] += wyy
            g0 += u0 * rx + u1 * ry
            g1 += wxx * rx + wxy * ry
            g2 += wxy * rx + wyy * ry
        # The symmetric 3 x 3 system by Cramer's rule (np.linalg.solve's call costs more).
        a00, a01, a02, a11, a12, a22 = h
        c00, c01, c02 = a11 * a22 - a12 * a12, a02 * a12 - a01 * a22, a01 * a12 - a02 * a11
        det = a00 * c00 + a01 * c01 + a02 * c02
        if not det > 0.0:
            raise ValueError("rigid_fit_2d_information: the information does not determine the motion")
        c11, c12, c22 = a00 * a22 - a02 * a02, a01 * a02 - a00 * a12, a00 * a11 - a01 * a01
        theta -= (c00 * g0 + c01 * g1 + c02 * g2) / det
        tx -= (c01 * g0 + c11 * g1 + c12 * g2) / det
        ty -= (c02 * g0 + c12 * g1 + c22 * g2) / det
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]]), np.array([tx, ty])


def rigid_fit_robust(
    src: np.ndarray, dst: np.ndarray, *, iterations: int = 3, k_mad: float = 4.0, min_points: int = 3
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`rigid_fit` iterated with residual rejection (the iterative ICP of paper 001).

    Fit all pairs; then up to ``iterations`` times keep the pairs whose residual
    ``|R src_i + t - dst_i|`` (eq. (10) of paper 001) is at most ``median + k_mad * 1.4826
    MAD`` of the pairs kept so far, and refit; stop when the kept set no longer changes or
    would fall under ``min_points``. Returns ``(R, t, inlier_mask (N,))``.
    """
    src = np.asarray(src, dtype=float)
    dst = np.asarray(dst, dtype=float)
    keep = np.ones(len(src), dtype=bool)
    R, t = rigid_fit(src, dst)
    for _ in range(iterations):
        r = np.linalg.norm(src @ R.T + t - dst, axis=1)
        med = float(np.median(r[keep]))
        mad = float(np.median(np.abs(r[keep] - med))) * 1.4826
        new = r <= med + k_mad * max(mad, 1e-9)
        if new.sum() < min_points or np.array_equal(new, keep):
            break
        keep = new
        R, t = rigid_fit(src[keep], dst[keep])
    return R, t, keep


def t_sigmas(n_sigmas: float, dof: int) -> float:
    """How many standard errors *estimated from residuals* with ``dof`` degrees of freedom make
    the same two-sided tail as ``n_sigmas`` standard errors of a known normal error (Student's
    t): 3 -> 9.2 with 3 degrees of freedom (four points' 8 coordinates, 5 parameters), 6.6 with
    4, 3.04 with 200. A standard error from a handful of residuals is itself uncertain, and a
    deviation of "3 of them" happens far more often than 0.27 % of the time; this keeps the
    test's confidence. ``inf`` for ``dof < 1`` (no residual to estimate it from); 0 for
    ``n_sigmas <= 0``."""
    if n_sigmas <= 0.0:
        return 0.0
    if dof < 1:
        return float("inf")
    return float(stdtrit(dof, 1.0 - ndtr(-n_sigmas)))


def f_sigmas(n_sigmas: float, dfn: int, dfd: int) -> float:
    """The ratio of two variance estimates, of ``dfn`` and ``dfd`` degrees of freedom, that
    makes the same tail as ``n_sigmas`` standard errors of a normal error on both sides (the
    F distribution): where ``sum_i (x_i - 1)^2 / sum_i sigma_i^2`` over n measurements ``x_i``
    of 1, each with a standard error ``sigma_i`` estimated from ``dof`` residuals, exceeds
    ``f_sigmas(n_sigmas, n, n dof)``, the measurements do not scatter about 1 by their errors
    alone. ``f_sigmas(s, 1, dof) == t_sigmas(s, dof) ** 2`` (one measurement); 3 sigmas for
    eight measurements of 3 degrees of freedom each: 4.26. ``inf`` for ``dfd < 1``; 0 for
    ``n_sigmas <= 0``."""
    if n_sigmas <= 0.0:
        return 0.0
    if dfd < 1 or dfn < 1:
        return float("inf")
    return float(fdtri(dfn, dfd, 1.0 - 2.0 * ndtr(-n_sigmas)))


def rigid_fit_precision(
    src: np.ndarray, dst: np.ndarray, R: np.ndarray, t: np.ndarray, *, scale: float = 1.0
) -> tuple[float, float]:
    """Standard errors of a 2-D least-squares fit ``dst_i ~ scale R src_i + t`` from its residuals.

    The self-check "residual against the expected precision" of a step (issue 14): the
    residuals say how well the pairs locate the motion. With independent errors of equal
    variance per axis, estimated from the residuals ``r_i = dst_i - (scale R src_i + t)``
    as ``sigma^2 = sum |r_i|^2 / (2 N - p)`` (``p`` = 3 parameters, 4 with a scale other
    than 1), the fitted rotation angle has variance ``sigma^2 / S`` with ``S = sum |src_i -
    mean(src)|^2``, and the point the fit maps the origin of ``src`` to (``t``: the camera's
    own position when the points are centred on the optical axis) has a total variance over
    both axes of ``2 sigma^2 / N + |mean(src)|^2 sigma^2 / S`` (the centroid's error plus the
    rotation's error carried over the lever arm from the centroid to the origin; twice the
    second term with a scale, whose relative error has the angle's variance).

    ``src``, ``dst``: (N, 2) matched points, N >= 3 (not all at one point); ``R`` (2, 2),
    ``t`` (2,): the fit. Returns ``(sigma_origin, sigma_angle_rad)``: the first in the unit of
    the points. Real matching errors are not independent (a keypoint's error is shared by
    its neighbours under the same light), so the true error is often 2-4 times these.
    """
    a = np.asarray(src, dtype=float).reshape(-1, 2)
    b = np.asarray(dst, dtype=float).reshape(-1, 2)
    n = len(a)
    p = 3 if scale == 1.0 else 4
    if n < 3 or len(b) != n:
        raise ValueError(f"rigid_fit_precision: need two (N, 2) arrays with N >= 3, got {a.shape} and {b.shape}")
    r = b - (float(scale) * a @ np.asarray(R, dtype=float).T + np.asarray(t, dtype=float).reshape(2))
    var = float(np.sum(r**2)) / max(2 * n - p, 1)
    mu = a.mean(axis=0)
    spread = float(np.sum((a - mu) ** 2))
    if spread <= 0.0:
        return float("inf"), float("inf")
    var_angle = var / spread  # the relative scale, when fitted, has the same variance
    lever = float(mu @ mu) * var_angle * (p - 2)
    return float(np.sqrt(2.0 * var / n + lever)), float(np.sqrt(var_angle))


def axis_scales_design(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The design matrix ``A`` (2 N, 5) of :func:`axis_scales_fit`'s linearised motion at the
    ``points`` (N, 2) and ``(A^T A)^-1``: fixed by the points, so a caller that fits shifts at the
    same points every frame (phase-corr's block centres) makes them once and passes them as
    ``design``. Raises ``ValueError`` where the fit is not determined (see there)."""
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    n = len(p)
    if n < 3:
        raise ValueError(f"axis_scales_fit: need (N, 2) points with N >= 3, got {p.shape}")
    A = np.zeros((2 * n, 5))
    A[:n, 0], A[:n, 2], A[:n, 3] = p[:, 0], -p[:, 1], 1.0
    A[n:, 1], A[n:, 2], A[n:, 4] = p[:, 1], p[:, 0], 1.0
    AtA = A.T @ A
    if np.linalg.matrix_rank(AtA) < 5:
        raise ValueError("axis_scales_fit: the points do not spread along both axes")
    return A, np.linalg.inv(AtA)


def axis_scales_fit(
    points: np.ndarray, shifts: np.ndarray, design: tuple[np.ndarray, np.ndarray] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The image scale along each axis of a small motion, and its standard errors, from shifts at points.

    Least squares of the linearised motion ``d_x = (s_x - 1) p_x - theta p_y + t_x``,
    ``d_y = (s_y - 1) p_y + theta p_x + t_y`` (an axis-aligned scale, a small rotation
    ``theta`` and a translation: five parameters) to the shifts ``d_i`` measured at the
    points ``p_i``. A camera that rises by ``dh`` at height ``h`` shrinks its picture by
    ``h / (h + dh)`` on both axes; the two axes are fitted apart because a picture lit at
    grazing angle along one axis moves unevenly along it (BENCHMARKS.md, "phase-corr: the
    camera height from the image scale"). The standard errors are those of the fit from its
    residuals, ``sigma^2 = RSS / (2 N - 5)`` times the diagonal of ``(A^T A)^-1``.

    ``points``, ``shifts``: (N, 2), N >= 3, in one unit (px), the points not all on a line
    parallel to an axis; the shifts small against the points' spread (the linearisation).
    ``design``: :func:`axis_scales_design` of the same ``points`` (made here when None; the
    same result either way).
    Returns ``(scales (2,) = (s_x, s_y), sigmas (2,))``; the sigmas rest on ``2 N - 5``
    degrees of freedom (3 for phase-corr's four blocks: a rough estimate).
    """
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    d = np.asarray(shifts, dtype=float).reshape(-1, 2)
    n = len(p)
    if n < 3 or len(d) != n:
        raise ValueError(f"axis_scales_fit: need two (N, 2) arrays with N >= 3, got {p.shape} and {d.shape}")
    A, cov = axis_scales_design(p) if design is None else design
    b = np.concatenate([d[:, 0], d[:, 1]])
    x = cov @ (A.T @ b)
    var = float(np.sum((A @ x - b) ** 2)) / (2 * n - 5)  # n >= 3: at least one degree of freedom
    return 1.0 + x[:2], np.sqrt(var * np.diag(cov)[:2])


# ----------------------------------------------------------------------------- pixels <-> floor
def pixels_to_floor_mm(uv_px: np.ndarray, camera: CameraModel, height_mm: float) -> np.ndarray:
    """(N, 2) pixels (u, v) -> (N, 2) floor coordinates (mm) in the camera's x-y axes.

    Eq. (1) of paper 000 (``2 d tan(theta) / w`` mm per pixel, i.e.
    :meth:`CameraModel.gsd_mm_per_px`) generalised to the full camera model: the ray through
    the pixel (distortion included) meets the floor at depth ``height_mm`` (camera looking
    straight down).
    """
    return camera.unproject(np.asarray(uv_px, dtype=float).reshape(-1, 2), height_mm)[:, :2]


def floor_mm_to_pixels(xy_mm: np.ndarray, camera: CameraModel, height_mm: float) -> np.ndarray:
    """(N, 2) floor coordinates (mm, camera x-y axes, depth ``height_mm``) -> (N, 2) pixels.

    The inverse of :func:`pixels_to_floor_mm`.
    """
    xy = np.asarray(xy_mm, dtype=float).reshape(-1, 2)
    return camera.project(np.column_stack([xy, np.full(len(xy), float(height_mm))]))


def pixel_rigid_to_floor(
    R_px: np.ndarray, t_px: np.ndarray, camera: CameraModel, height_mm: float, *, centred: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """The rigid map of floor points ``q_b = R2 q_a + t2_mm`` from one of pixels ``p_b = R_px p_a + t_px``.

    A downward camera at ``height_mm`` sees a floor point at camera-frame ``q`` (mm) at pixel
    ``p = c + D q`` with ``D = diag(fx, fy) / h`` (eq. (1) of paper 000 with the pinhole
    model, no distortion), so ``R2 = D^-1 R D`` (re-orthonormalised; it equals ``R`` for
    square pixels) and ``t2 = D^-1 (R c + t - c)``. With ``centred``, the pixel map is
    between centred pixels ``p - c`` and ``t2 = D^-1 t``. Returns ``(R2 (2, 2), t2_mm (2,))``.
    """
    R = np.asarray(R_px, dtype=float)
    t = np.asarray(t_px, dtype=float).reshape(2)
    D = np.array([camera.fx_px, camera.fy_px]) / float(height_mm)
    R2 = nearest_rotation_2d((R * D[None, :]) / D[:, None])  # D^-1 R D, re-orthonormalised
    if not centred:
        c = np.array([camera.cx_px, camera.cy_px])
        t = R @ c + t - c
    return R2, t / D


def planar_T(R2: np.ndarray, t2_mm: np.ndarray) -> np.ndarray:
    """4x4 transform with rotation ``R2`` (2, 2) about z and translation ``(t2_mm, 0)``.

    For a rigid map of floor points ``q_b = R2 q_a + t2`` between frames a and b of a
    downward camera at a constant height, this is ``T_b_a`` (mm).
    """
    T = np.eye(4)
    T[:2, :2] = R2
    T[:2, 3] = np.asarray(t2_mm, dtype=float).reshape(2)
    return T


def floor_rigid_to_T(R2: np.ndarray, t2_mm: np.ndarray) -> np.ndarray:
    """Camera motion ``T_prev_cur`` (4x4, mm) from the rigid map of floor points between frames.

    ``R2, t2_mm`` map a floor point's camera-x/y coordinates (mm) in the previous frame to
    those in the current frame: ``q_cur = R2 q_prev + t2``. That is the planar part of
    ``T_cur_prev`` (:func:`planar_T`); the result is its inverse.
    """
    return invert_T(planar_T(R2, t2_mm))


def block_homographies(x_prev: np.ndarray, x_cur: np.ndarray) -> list[np.ndarray] | None:
    """Least-squares homographies (3, 3) of ``m`` interleaved blocks of the pairs ``x_prev ->
    x_cur`` (N, 2; N >= 8): pairs ``i, i + m, i + 2 m, ...`` for block ``i``, ``m`` = 4 (2 when
    N < 16). Each block has ``m`` times the variance of the whole, so a quantity read from each
    block's homography has the whole fit's standard error ``spread / sqrt(m)``, with ``spread``
    the blocks' sample standard deviation. None when a block has no homography."""
    m = 4 if len(x_prev) >= 16 else 2
    out = []
    for i in range(m):
        H, _ = cv2.findHomography(x_prev[i::m], x_cur[i::m], 0)
        if H is None:
            return None
        out.append(H)
    return out


def rival_homography_support(
    src_px: np.ndarray,
    dst_px: np.ndarray,
    inliers: np.ndarray,
    threshold_px: float,
    *,
    seed: int = 0,
    min_share: float = 0.5,
    confidence: float = 0.995,
) -> int:
    """How many of the matches outside ``inliers`` a second floor homography explains.

    A self-check of a step (issue 14: agreement of independent sets of matches): the floor
    seen by a downward camera moves by one homography between two frames, so the matches a
    RANSAC fit left out should be random and agree on nothing. When many of them agree on
    another homography (a static glare or dirt on the lens, a repeated pattern, an object
    moving on the floor), the frame shows two motions and the one kept may be the wrong
    one. ``src_px``, ``dst_px``: (N, 2) matched pixels; ``inliers``: (N,) bool of the fit
    kept; RANSAC (OpenCV, seeded with ``seed``) at ``threshold_px`` on the others. Returns
    the rival's inlier count (0 when fewer than 8 matches are left).

    Only a rival backed by at least ``min_share`` of the other matches counts (the caller's
    rule: :func:`consensus_problem` asks for half), so RANSAC draws the samples that find one
    with probability ``confidence``: ``log(1 - confidence) / log(1 - min_share^4)``, 83 for
    half at 99.5 % (Fischler and Bolles' count for a 4-point sample). On random matches no
    consensus ends RANSAC early and it used to draw all of a fixed 1000, 14 ms of orb-icp's
    frame on 25 left-out matches.
    """
    out = ~np.asarray(inliers, dtype=bool)
    if int(out.sum()) < 8:
        return 0
    cv2.setRNGSeed(int(seed))
    a = np.asarray(src_px, dtype=np.float32)[out]
    b = np.asarray(dst_px, dtype=np.float32)[out]
    iters = int(np.ceil(np.log(1.0 - confidence) / np.log(1.0 - float(min_share) ** 4)))
    H, mask = cv2.findHomography(a, b, cv2.RANSAC, float(threshold_px), maxIters=iters, confidence=confidence)
    return 0 if H is None or mask is None else int(mask.sum())


def consensus_problem(
    src_px: np.ndarray,
    dst_px: np.ndarray,
    inliers: np.ndarray,
    threshold_px: float,
    *,
    min_fraction: float,
    min_count: int,
    max_rival_fraction: float,
    seed: int = 0,
    what: str = "matches",
) -> str:
    """Why the consensus of a robust fit of ``src_px -> dst_px`` cannot be trusted ('' when it can).

    The self-checks every feature estimator applies to its step (issue 14: a step that
    cannot be measured is reported lost, not returned wrong): (1) the consensus
    ``inliers`` ((N,) bool) holds at least ``min_fraction`` of the N ``what``; (2) the matches
    left out do not show a second motion: :func:`rival_homography_support` finds no
    homography among them backed by more than ``max(min_count, max_rival_fraction x
    inliers)`` matches and by at least half of them. ``src_px``, ``dst_px``: (N, 2) pixels.
    """
    inl = np.asarray(inliers, dtype=bool)
    n_in, n_out = int(inl.sum()), int((~inl).sum())
    frac = float(inl.mean()) if len(inl) else 0.0
    if frac < min_fraction:
        return (
            f"only {100 * frac:.0f} % of {len(inl)} {what} agree with the homography (needs {100 * min_fraction:.0f} %)"
        )
    rival = rival_homography_support(src_px, dst_px, inl, threshold_px, seed=seed, min_share=0.5)
    if rival > max(min_count, max_rival_fraction * n_in) and rival >= 0.5 * n_out:
        return f"two motions: {rival} of the {n_out} other {what} agree on a second homography ({n_in} inliers)"
    return ""


# ----------------------------------------------------------------------------- the floor plane
def fit_plane(
    points_mm: np.ndarray, *, iterations: int = 3, k_mad: float = 4.0, min_points: int = 3
) -> tuple[np.ndarray, float, np.ndarray]:
    """Least-squares plane ``n . p = d`` of (N, 3) camera-frame points (mm), with residual rejection.

    Total least squares: ``n`` is the right singular vector of the smallest singular value
    of the centred points and ``d = n . centroid``, signed so that ``d > 0`` (``n`` points
    from the camera at the origin to the plane). The first fit takes the points whose depth
    (z) is within ``k_mad`` scaled MADs of the median depth (a floor seen from above: gross
    outliers, such as a wrong stereo match, cannot tilt it). Then up to ``iterations`` times the points
    whose distance ``|n . p - d|`` exceeds ``median + k_mad * 1.4826 MAD`` of those kept are
    dropped and the plane refitted (the rule of :func:`rigid_fit_robust`), stopping when the
    kept set no longer changes or would fall under ``min_points``. Non-finite rows are left
    out. Returns ``(n (3,), d_mm, inliers (N,) bool)``; refused (ValueError) with fewer than
    3 finite points.
    """
    P = np.asarray(points_mm, dtype=float).reshape(-1, 3)
    finite = np.isfinite(P).all(axis=1)
    if int(finite.sum()) < 3:
        raise ValueError(f"fit_plane: need at least 3 finite (N, 3) points, got {int(finite.sum())}")

    def fit(Q: np.ndarray) -> tuple[np.ndarray, float]:
        c = Q.mean(axis=0)
        _, _, Vt = np.linalg.svd(Q - c, full_matrices=False)
        n = Vt[-1]
        d = float(n @ c)
        return (n, d) if d >= 0 else (-n, -d)

    z = np.where(finite, P[:, 2], np.nan)
    z_med = float(np.nanmedian(z))
    z_mad = float(np.nanmedian(np.abs(z - z_med))) * 1.4826
    keep = finite & (np.abs(np.nan_to_num(z - z_med, nan=np.inf)) <= k_mad * max(z_mad, 1e-9))
    if int(keep.sum()) < max(3, min_points):
        keep = finite.copy()
    n, d = fit(P[keep])
    for _ in range(iterations):
        r = np.where(finite, np.abs(np.nan_to_num(P) @ n - d), np.inf)
        med = float(np.median(r[keep]))
        mad = float(np.median(np.abs(r[keep] - med))) * 1.4826
        new = r <= med + k_mad * max(mad, 1e-9)
        if new.sum() < max(3, min_points) or np.array_equal(new, keep):
            break
        keep = new
        n, d = fit(P[keep])
    return n, d, keep


def plane_fit_precision(
    points_mm: np.ndarray, n: np.ndarray, d_mm: float, *, overlap: float = 1.0
) -> tuple[float, float]:
    """Standard errors of a least-squares plane ``n . p = d`` fitted to (K, 3) points (mm), from its residuals.

    The counterpart of :func:`rigid_fit_precision` for :func:`fit_plane` (pass the points it
    kept). In the plane's levelled frame (:func:`level_rotation`) the fit is ``z = h + a x + b
    y`` about the points' centroid ``c``; with independent residuals of variance ``sigma^2 =
    sum r_i^2 / (K - 3)`` (``r_i = n . p_i - d``), the slopes have the covariance ``sigma^2
    S^-1`` (``S`` (2, 2): the scatter of the levelled x-y coordinates about their centroid) and
    the plane's distance from the camera, ``d`` (the camera's height: the plane at the foot of
    the camera, ``c_xy`` away from the centroid), the variance ``sigma^2 (1 / K + c_xy^T S^-1
    c_xy)``. Returns ``(sigma_height_mm, sigma_tilt_rad)``; the second is the total over both
    slopes (``sqrt(trace(sigma^2 S^-1))``). ``overlap`` (>= 1): how many points share one
    independent error, when their measurements share data (stereo points aligned by
    Lucas-Kanade windows wider than the grid's spacing: ``(window / spacing)^2``); the
    variances are multiplied by it (the fit has ``K / overlap`` independent points). Other
    correlated errors (a disparity bias shared by a region under the same light) make the true
    errors larger still. ``(inf, inf)`` with fewer than 4 points or points on a line.
    """
    P = np.asarray(points_mm, dtype=float).reshape(-1, 3)
    k = len(P)
    if k < 4:
        return float("inf"), float("inf")
    n = np.asarray(n, dtype=float).reshape(3)
    var = float(np.sum((P @ n - float(d_mm)) ** 2)) / (k - 3) * max(float(overlap), 1.0)
    q = P @ level_rotation(n)[:2].T  # levelled x-y (rows of Q: the levelled x and y axes)
    c = q.mean(axis=0)
    S = (q - c).T @ (q - c)
    if np.linalg.det(S) <= 1e-12 * max(float(np.trace(S)) ** 2, 1e-300):
        return float("inf"), float("inf")
    S_inv = np.linalg.inv(S)
    return float(np.sqrt(var * (1.0 / k + c @ S_inv @ c))), float(np.sqrt(var * np.trace(S_inv)))


def depth_floor_plane(
    depth_mm: np.ndarray, camera: CameraModel, step_px: int = 4, *, min_points: int = 100
) -> tuple[np.ndarray, float] | None:
    """The floor plane ``(n, d_mm)`` (camera frame) of a depth image (H, W) in mm along the optical axis.

    The pixels of a ``step_px`` grid that carry depth (finite, > 0) are back-projected through
    the camera model and :func:`fit_plane` fits them; ``d`` is the camera's height above
    the floor. None with fewer than ``min_points`` such pixels.
    """
    fitted = depth_floor_plane_precision(depth_mm, camera, step_px, min_points=min_points)
    return None if fitted is None else fitted[:2]


def depth_floor_plane_precision(
    depth_mm: np.ndarray, camera: CameraModel, step_px: int = 4, *, min_points: int = 100
) -> tuple[np.ndarray, float, tuple[float, float]] | None:
    """:func:`depth_floor_plane` with the plane's standard errors: ``(n, d_mm, (sigma_height_mm,
    sigma_tilt_rad))`` (:func:`plane_fit_precision` of the depth points the fit kept, each
    taken as an independent measurement), or None."""
    depth = np.asarray(depth_mm)
    g = int(step_px)
    v, u = np.mgrid[g // 2 : depth.shape[0] : g, g // 2 : depth.shape[1] : g]
    z = depth[v, u].astype(np.float64).ravel()
    ok = np.isfinite(z) & (z > 0)
    if int(ok.sum()) < min_points:
        return None
    uv = np.column_stack([u.ravel()[ok], v.ravel()[ok]]).astype(np.float64)
    P = camera.unproject(uv, z[ok])
    n, d, kept = fit_plane(P)
    return n, d, plane_fit_precision(P[kept], n, d)


def least_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The least rotation ``Q`` (3, 3) with ``Q a = b`` for unit vectors ``a``, ``b`` (3,): Rodrigues'
    formula about the axis ``a x b`` (the identity for ``a = b``; for ``a = -b``, half a turn
    about an axis across them)."""
    a = np.asarray(a, dtype=float).reshape(3)
    b = np.asarray(b, dtype=float).reshape(3)
    v = np.cross(a, b)
    c = float(a @ b)
    s2 = float(v @ v)
    if s2 < 1e-30:
        if c > 0:
            return np.eye(3)
        k = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        k /= np.linalg.norm(k)
        return 2.0 * np.outer(k, k) - np.eye(3)
    vx = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + vx + vx @ vx * ((1.0 - c) / s2)


def level_rotation(n: np.ndarray) -> np.ndarray:
    """The least rotation ``Q`` (3, 3) with ``Q n = +z``: camera axes -> the levelled frame's
    (:func:`least_rotation`). ``n``: (3,) unit normal with a positive z component (a floor in
    front of the camera).
    """
    n = np.asarray(n, dtype=float).reshape(3)
    return least_rotation(n / np.linalg.norm(n), np.array([0.0, 0.0, 1.0]))


def rays_to_plane(uv_px: np.ndarray, camera: CameraModel, n: np.ndarray, d_mm: float) -> np.ndarray:
    """(N, 3) camera-frame points (mm) where the rays of pixels ``uv_px`` (N, 2) meet the plane ``n . p = d``.

    The generalisation of :func:`pixels_to_floor_mm` to a tilted floor: the ray ``r`` of a
    pixel (distortion included, ``r_z = 1``) meets the plane at ``r d / (n . r)``.
    """
    r = camera.unproject(np.asarray(uv_px, dtype=float).reshape(-1, 2), 1.0)
    return r * (float(d_mm) / (r @ np.asarray(n, dtype=float)))[:, None]


def plane_step_T(
    n_prev: np.ndarray, d_prev_mm: float, n_cur: np.ndarray, d_cur_mm: float, R2: np.ndarray, t2_mm: np.ndarray
) -> np.ndarray:
    """The 6-DoF camera step ``T_prev_cur`` (4, 4) mm from the floor planes of both frames and a
    rigid map of levelled floor coordinates ``q_cur = R2 q_prev + t2_mm`` between them.

    With ``Q_a = level_rotation(n_a)``, a floor point is at ``(q_a, d_a)`` in frame a's
    levelled frame, so ``T_Lcur_Lprev`` is the rotation ``R2`` about z with the translation
    ``(t2_mm, d_cur - d_prev)``, and ``T_prev_cur = Q_prev^T T_Lcur_Lprev^-1 Q_cur``: the
    planar step (:func:`floor_rigid_to_T`) with the height change, between the two tilts.
    """
    T_Lc_Lp = planar_T(R2, t2_mm)
    T_Lc_Lp[2, 3] = float(d_cur_mm) - float(d_prev_mm)
    Qp = make_T(level_rotation(n_prev), np.zeros(3))
    Qc = make_T(level_rotation(n_cur), np.zeros(3))
    return invert_T(Qp) @ invert_T(T_Lc_Lp) @ Qc


def _levelled_floor_points(
    uv_prev_px: np.ndarray,
    uv_cur_px: np.ndarray,
    camera: CameraModel,
    plane_prev: tuple[np.ndarray, float],
    plane_cur: tuple[np.ndarray, float],
) -> tuple[np.ndarray, np.ndarray]:
    """The floor points (N, 2) mm of matched pixels (N, 2) in each frame's levelled floor
    coordinates: each ray met with its frame's plane ``(n, d_mm)`` (:func:`rays_to_plane`), turned
    by the plane's :func:`level_rotation`, its x and y."""
    (n_p, d_p), (n_c, d_c) = plane_prev, plane_cur
    q_prev = (rays_to_plane(uv_prev_px, camera, n_p, d_p) @ level_rotation(n_p).T)[:, :2]
    q_cur = (rays_to_plane(uv_cur_px, camera, n_c, d_c) @ level_rotation(n_c).T)[:, :2]
    return q_prev, q_cur


def floor_plane_step(
    uv_prev_px: np.ndarray,
    uv_cur_px: np.ndarray,
    camera: CameraModel,
    plane_prev: tuple[np.ndarray, float],
    plane_cur: tuple[np.ndarray, float],
    *,
    iterations: int = 3,
) -> tuple[np.ndarray, np.ndarray, float]:
    """The 6-DoF step ``T_prev_cur`` from matched pixels (N, 2) and each frame's floor plane ``(n, d_mm)``.

    Each matched pixel's ray meets its frame's plane (:func:`rays_to_plane`); the points in
    the levelled frames (:func:`level_rotation`) give floor coordinates free of the tilt and
    the height, whose rigid map (:func:`rigid_fit_robust`, ``iterations`` rejections) is the
    yaw and the in-plane shift; :func:`plane_step_T` adds the height change and the tilts.
    The planes carry what the matches measure poorly (height and tilt, from every depth or
    stereo point of the frame), the pixels what they measure well (the in-plane motion).
    Returns ``(T_prev_cur (4, 4), inliers (N,) bool, rms_mm)`` (RMS residual of the
    inliers' floor coordinates).
    """
    (n_p, d_p), (n_c, d_c) = plane_prev, plane_cur
    q_prev, q_cur = _levelled_floor_points(uv_prev_px, uv_cur_px, camera, plane_prev, plane_cur)
    R2, t2, keep = rigid_fit_robust(q_prev, q_cur, iterations=iterations)
    rms = float(np.sqrt(np.mean(np.sum((q_prev[keep] @ R2.T + t2 - q_cur[keep]) ** 2, axis=1))))
    return plane_step_T(n_p, d_p, n_c, d_c, R2, t2), keep, rms


def floor_plane_step_precision(
    uv_prev_px: np.ndarray,
    uv_cur_px: np.ndarray,
    camera: CameraModel,
    plane_prev: tuple[np.ndarray, float],
    plane_cur: tuple[np.ndarray, float],
    sigma_prev: tuple[float, float],
    sigma_cur: tuple[float, float],
) -> tuple[float, float, float]:
    """The standard errors of a :func:`floor_plane_step` step from the pairs it kept (N, 2) px and
    each frame's floor plane ``(n, d_mm)`` with its standard errors ``(sigma_height_mm,
    sigma_tilt_rad)`` (:func:`plane_fit_precision`): ``(sigma_mm, sigma_deg, sigma_fit_mm)``.

    Three fits' residuals: the in-plane rigid fit of the pairs in the levelled floor coordinates
    (:func:`rigid_fit_precision`: the camera's own displacement and the yaw; ``sigma_fit_mm``),
    and each plane's: its height, which is the step's height change, and its tilt, which turns
    the step and shifts every floor point, so the in-plane displacement, by the height times the
    tilt error. Independent, their variances add."""
    d_p, d_c = plane_prev[1], plane_cur[1]
    q_prev, q_cur = _levelled_floor_points(uv_prev_px, uv_cur_px, camera, plane_prev, plane_cur)
    R2, t2 = rigid_fit(q_prev, q_cur)
    sig_fit_mm, sig_yaw_rad = rigid_fit_precision(q_prev, q_cur, R2, t2)
    var_mm, var_rad = sig_fit_mm**2, sig_yaw_rad**2
    for d_mm, (sig_h_mm, sig_tilt_rad) in ((d_p, sigma_prev), (d_c, sigma_cur)):
        var_mm += sig_h_mm**2 + (d_mm * sig_tilt_rad) ** 2
        var_rad += sig_tilt_rad**2
    return float(np.sqrt(var_mm)), float(np.degrees(np.sqrt(var_rad))), float(sig_fit_mm)


def plane_homography_motion(
    H_norm: np.ndarray, n_prev: np.ndarray, d_prev_mm: float, *, tilt: bool = True
) -> tuple[np.ndarray, np.ndarray, float]:
    """The camera step of a floor-plane homography, given the floor plane of the previous frame.

    ``H_norm`` (3, 3) maps normalised image points of the previous frame to the current one
    (``x_cur ~ H_norm x_prev``; for pixels, ``H_norm = K^-1 H K``). A plane ``n . p = d`` of
    the previous camera induces ``H_norm ~ R + t n^T / d`` with ``p_cur = R p_prev + t``
    (Hartley & Zisserman, Multiple View Geometry, 2nd ed., Result 13.1; Ma, Soatto, Kosecka,
    Sastry, An Invitation to 3-D Vision, eq. (5.20)). With the normal known the decomposition
    is unique: on the vectors ``u`` of the plane (``n . u = 0``) ``H_norm u = s R u``, so the
    scale ``s`` and ``R`` are the similarity fit (:func:`umeyama`) of ``{u1, u2}`` to their
    images, and ``t = d (H_norm n / s - R n)``. The current frame's plane is ``n' = R n``,
    ``d' = d + n' . t``. Returns ``(T_prev_cur (4, 4) mm, n_cur (3,), d_cur_mm)``.

    ``tilt=False``: the step keeps the plane's tilt (``R`` a rotation about ``n``: the yaw; the
    height change and the shift are still measured): the images of ``u1, u2`` are taken in the
    plane (their components along ``n``, the homography's perspective terms, are left out) and
    ``s``, ``R`` are their 2-D similarity fit there. For a camera whose tilt change the
    homography cannot measure (homography-6dof under the rig's own grazing light).
    """
    Hn = np.asarray(H_norm, dtype=float).reshape(3, 3)
    if np.linalg.det(Hn) < 0:  # a homography is defined up to a (possibly negative) factor
        Hn = -Hn
    n = np.asarray(n_prev, dtype=float).reshape(3)
    n = n / np.linalg.norm(n)
    Q = level_rotation(n)
    u1, u2 = Q[0], Q[1]  # rows of Q: the levelled frame's x and y axes in the camera frame, normal to n
    src = np.stack([u1, u2, -u1, -u2])
    if tilt:
        R, _, s = umeyama(src, src @ Hn.T, with_scale=True)
    else:
        in_plane = src @ Hn.T @ Q[:2].T  # (4, 2): the images in the plane's coordinates (u1, u2)
        R2, _, s = umeyama(src @ Q[:2].T, in_plane, with_scale=True)
        R = Q.T @ make_T(np.pad(R2, ((0, 1), (0, 1))) + np.diag([0.0, 0.0, 1.0]), np.zeros(3))[:3, :3] @ Q
    t = float(d_prev_mm) * (Hn @ n / s - R @ n)
    n_cur = R @ n
    d_cur = float(d_prev_mm) + float(n_cur @ t)
    return invert_T(make_T(R, t)), n_cur, d_cur

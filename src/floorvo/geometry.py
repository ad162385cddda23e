"""Rigid transforms in millimetres and radians.

Conventions
-----------
* Poses are 4x4 ``float64`` homogeneous matrices ``T_a_b`` that map points from frame
  ``b`` into frame ``a``: ``p_a = T_a_b @ p_b``. Translations are in millimetres.
* World frame: z up, mean floor plane at z = 0, x the default direction of travel.
* Camera frame: OpenCV's (x right, y down, z along the optical axis).
* A camera looking straight down with yaw 0 has its x axis along world +x, its y axis
  along world -y and its optical axis along world -z (:func:`T_world_cam_down`).
* Quaternions are (x, y, z, w), as in TUM files.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = [
    "R_WORLD_CAM_DOWN",
    "make_T",
    "invert_T",
    "rot_z",
    "T_world_cam_down",
    "T_from_xyz_quat",
    "xyz_quat_from_T",
    "se2_from_T",
    "T_from_se2",
    "yaw_of_R",
    "rigid_fit_2d",
]

#: Rotation of a camera looking straight down with yaw 0: columns are the camera axes
#: expressed in the world (x_cam = +x_world, y_cam = -y_world, z_cam = -z_world).
R_WORLD_CAM_DOWN = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])


def make_T(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Build a 4x4 transform from a 3x3 rotation and a 3-vector translation (mm)."""
    T = np.eye(4)
    T[:3, :3] = np.asarray(R, dtype=float)
    T[:3, 3] = np.asarray(t, dtype=float).reshape(3)
    return T


def invert_T(T: np.ndarray) -> np.ndarray:
    """Inverse of a rigid 4x4 transform (exact: R^T, -R^T t)."""
    T = np.asarray(T, dtype=float)
    R = T[:3, :3]
    return make_T(R.T, -R.T @ T[:3, 3])


def rot_z(yaw_rad: float) -> np.ndarray:
    """3x3 rotation about +z by ``yaw_rad`` (counter-clockwise seen from above)."""
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def T_world_cam_down(
    x_mm: float,
    y_mm: float,
    height_mm: float,
    yaw_rad: float = 0.0,
    roll_rad: float = 0.0,
    pitch_rad: float = 0.0,
) -> np.ndarray:
    """Pose of a downward-looking camera at (x, y, height) with yaw about world z.

    ``roll_rad`` and ``pitch_rad`` tilt the rig about its own forward (x) and lateral (y)
    axes (R = Rz(yaw) Rx(roll) Ry(pitch) R_down), for disturbance models.
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


def se2_from_T(T_world_cam: np.ndarray) -> np.ndarray:
    """(x_mm, y_mm, yaw_rad) of a downward camera pose."""
    T = np.asarray(T_world_cam, dtype=float)
    return np.array([T[0, 3], T[1, 3], yaw_of_R(T[:3, :3])])


def T_from_se2(x_mm: float, y_mm: float, yaw_rad: float, height_mm: float) -> np.ndarray:
    """Downward camera pose from an SE(2) pose and a height (inverse of :func:`se2_from_T`)."""
    return T_world_cam_down(x_mm, y_mm, height_mm, yaw_rad)


def rigid_fit_2d(src: np.ndarray, dst: np.ndarray, weights: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares rigid motion (no scale) mapping 2D points ``src`` onto ``dst``.

    Solves ``min sum w_i |R src_i + t - dst_i|^2`` in closed form (Kabsch/Umeyama with
    the reflection check). ``src`` and ``dst`` are (N, 2), N >= 2.

    Returns ``(R, t)`` with R of shape (2, 2) and t of shape (2,).
    """
    src = np.asarray(src, dtype=float)
    dst = np.asarray(dst, dtype=float)
    if src.shape != dst.shape or src.ndim != 2 or src.shape[1] != 2 or src.shape[0] < 2:
        raise ValueError(f"rigid_fit_2d: need two (N, 2) arrays with N >= 2, got {src.shape} and {dst.shape}")
    w = np.ones(len(src)) if weights is None else np.asarray(weights, dtype=float)
    w = w / w.sum()
    mu_s = w @ src
    mu_d = w @ dst
    H = (src - mu_s).T @ ((dst - mu_d) * w[:, None])
    U, _, Vt = np.linalg.svd(H)
    D = np.diag([1.0, np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0])
    R = Vt.T @ D @ U.T
    t = mu_d - R @ mu_s
    return R, t

"""Synthetic floorvo sequences and views with exact ground truth, made in code (no renderer).

For tests and benchmarks that need a sequence folder fast: a procedural floor-like
texture (bumps at several scales lit from the side, albedo mottling) is viewed by a
downward camera at each pose of a trajectory through an exact sub-pixel affine warp of
the texture (a flat floor seen straight down); a rig-fixed LED falloff (bright at the left
and right edges, dark in the middle), sensor noise and 8-bit quantisation are applied,
and the flat-field frame (the falloff alone) is written to ``calib/cam0_flatfield.png``.
Optionally a depth image per frame (flat floor: the camera height) and a right camera
``baseline_mm`` along cam0's +x axis. A tilted pose (roll, pitch) is viewed exactly too:
each pixel's ray is intersected with the floor, and the depth image is that of the tilted
view (:func:`floor_depth`), so tests of 6-DoF estimators have exact truth.

    from floorvo.synthetic import line_poses, write_synthetic_sequence
    T = line_poses(length_mm=100.0, step_mm=4.0, height_mm=100.0)
    write_synthetic_sequence("out/synth", camera, T, height_mm=100.0, fps=30.0, seed=0)

For the map and the relocalisation (tests, benchmarks), :func:`view` crops the uint8 frame
a downward camera at ``T_world_cam`` sees of a texture (one texture pixel per ground
sample) by an exact affine warp: rotation about the principal point and translation in
px = mm / gsd. There a floor point ``(X, Y)`` (mm) is at texture pixel ``U = X / gsd + U0``,
``V = -Y / gsd + V0`` with ``(U0, V0)`` the texture centre (world y up, rows down).

In a sequence the floor texture (:func:`floor_texture`) has one pixel per ground sample
at ``height_mm``; a world point (X, Y) mm sits at texture pixel ``(X / gsd + U0, -Y / gsd + V0)``. The texture is built once, large enough for the whole
trajectory footprint, so keep trajectories within a few metres at full resolution.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from floorvo.camera import CameraModel
from floorvo.geometry import T_world_cam_down, attitude_of_T, se2_from_T
from floorvo.sequence import SequenceWriter, check_timestamps

__all__ = [
    "floor_texture",
    "floor_depth",
    "led_falloff",
    "line_poses",
    "render_view",
    "view",
    "texture_extent_mm",
    "write_synthetic_sequence",
]


def floor_texture(height_px: int, width_px: int | None = None, seed: int = 0) -> np.ndarray:
    """(H, W) float32 floor texture in (0, 1], deterministic from ``seed`` (square when ``width_px`` is None).

    A bumpy relief (Gaussian-filtered noise at 1, 2.5, 6 and 20 px) shaded by a light from
    -x, times albedo blobs, scaled so that its maximum is 1. The one procedural floor of the
    synthetic data: sequences (:func:`write_synthetic_sequence`) and exact views (:func:`view`).
    """
    width_px = height_px if width_px is None else width_px
    rng = np.random.default_rng(seed)
    h = np.zeros((height_px, width_px), np.float32)
    for sigma, amp in ((1.0, 1.0), (2.5, 1.5), (6.0, 2.0), (20.0, 3.0)):
        h += amp * cv2.GaussianBlur(rng.standard_normal((height_px, width_px)).astype(np.float32), (0, 0), sigma)
    shade = np.asarray(np.gradient(h, axis=1))  # faces towards -x are lit
    albedo = 1.0 + 0.3 * cv2.GaussianBlur(rng.standard_normal((height_px, width_px)).astype(np.float32), (0, 0), 8.0)
    tex = np.clip(albedo * (1.0 + 0.5 * shade / (shade.std() + 1e-6)), 0.05, None)
    return (tex / tex.max()).astype(np.float32)


def led_falloff(camera: CameraModel) -> np.ndarray:
    """(H, W) float32 rig-fixed LED falloff: bright at the left and right edges, dark in the middle."""
    u = np.arange(camera.width_px, dtype=np.float32)[None, :]
    v = np.arange(camera.height_px, dtype=np.float32)[:, None]
    w = camera.width_px
    left = 1.0 / (1.0 + (u / (0.25 * w)) ** 2)
    right = 1.0 / (1.0 + ((w - 1 - u) / (0.25 * w)) ** 2)
    return ((left + right) * (1.0 - 0.2 * ((v - camera.cy_px) / camera.height_px) ** 2)).astype(np.float32)


def line_poses(length_mm: float, step_mm: float, height_mm: float = 100.0, yaw_step_rad: float = 0.0) -> np.ndarray:
    """(N, 4, 4) T_world_cam of a downward camera moving along world +x by ``step_mm`` a frame
    (optionally turning by ``yaw_step_rad`` a frame and moving along its own heading)."""
    n = int(round(length_mm / step_mm)) + 1
    x = y = yaw = 0.0
    out = []
    for _ in range(n):
        out.append(T_world_cam_down(x, y, height_mm, yaw))
        x += step_mm * np.cos(yaw)
        y += step_mm * np.sin(yaw)
        yaw += yaw_step_rad
    return np.stack(out)


def render_view(
    coeffs: np.ndarray, origin_px: tuple[float, float], gsd_mm: float, camera: CameraModel, T_world_cam: np.ndarray
) -> np.ndarray:
    """(H, W) float32 view of a texture by a downward camera at ``T_world_cam`` (flat floor).

    ``coeffs``: cubic B-spline coefficients of the texture
    (``scipy.ndimage.spline_filter(texture, order=3)``); sampling is exact in position
    (OpenCV's warps quantise sample positions to 1/32 px, which would blur the truth).
    Pixel (u, v) sees world point (X, Y) + Rz(yaw) diag(1, -1) (x, y) height, with
    (x, y) the pixel's normalised image coordinates: ((u - cx) / fx, (v - cy) / fy) for
    an ideal pinhole, undistorted exactly (:func:`_undistorted_xy`) when the camera has
    distortion, so the whole camera model (fx != fy, principal point, distortion) is
    honoured. A tilted camera (roll or pitch: the optical axis not along world -z) sees
    the floor point where each pixel's ray meets z = 0 (:func:`floor_depth` gives the
    depth of those points).
    """
    from scipy.ndimage import map_coordinates

    T_world_cam = np.asarray(T_world_cam, dtype=float)
    Tt = np.diag([1.0, -1.0])  # texture px from world: U = X / gsd + U0, V = -Y / gsd + V0
    v, u = np.mgrid[0 : camera.height_px, 0 : camera.width_px].astype(np.float64)
    if not _is_level(T_world_cam):
        # A tilted camera: each pixel's ray meets the floor z = 0 (exact in position too).
        X, Y, _ = _floor_hits(camera, T_world_cam, u, v)
        U, V = X / gsd_mm + origin_px[0], -Y / gsd_mm + origin_px[1]
        return map_coordinates(coeffs, [V, U], order=3, prefilter=False, mode="mirror", output=np.float32)
    X, Y, yaw = se2_from_T(T_world_cam)
    height = float(T_world_cam[2, 3])
    c, sn = np.cos(yaw), np.sin(yaw)
    Rw = np.array([[c, -sn], [sn, c]]) @ np.diag([1.0, -1.0])  # world mm per normalised image unit (x height)
    b = Tt @ np.array([X, Y]) / gsd_mm + np.array(origin_px)
    du, dv = u - camera.cx_px, v - camera.cy_px
    if camera.fx_px == camera.fy_px and not camera.has_distortion:
        A = Tt @ Rw * (camera.gsd_mm_per_px(height) / gsd_mm)  # texture px per camera px
    else:
        du, dv = _undistorted_xy(camera, u, v)
        A = Tt @ Rw * (height / gsd_mm)  # texture px per normalised image unit
    U = A[0, 0] * du + A[0, 1] * dv + b[0]
    V = A[1, 0] * du + A[1, 1] * dv + b[1]
    return map_coordinates(coeffs, [V, U], order=3, prefilter=False, mode="mirror", output=np.float32)


def _is_level(T_world_cam: np.ndarray) -> bool:
    """Whether a camera pose looks straight down (optical axis along world -z, to 1e-12)."""
    return bool(np.abs(np.asarray(T_world_cam, dtype=float)[:3, 2] - [0.0, 0.0, -1.0]).max() < 1e-12)


def _floor_hits(
    camera: CameraModel, T_world_cam: np.ndarray, u: np.ndarray, v: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World (X, Y) mm where the rays of pixels ``(u, v)`` (arrays) meet the floor z = 0, and
    their depth along the optical axis (mm): the ray ``R (x, y, 1)`` from the camera centre
    ``c`` reaches z = 0 at ``lam = -c_z / (R (x, y, 1))_z``, which is the depth."""
    T = np.asarray(T_world_cam, dtype=float)
    x, y = _undistorted_xy(camera, u, v)
    R, c = T[:3, :3], T[:3, 3]
    dz = R[2, 0] * x + R[2, 1] * y + R[2, 2]
    lam = -c[2] / dz
    return c[0] + lam * (R[0, 0] * x + R[0, 1] * y + R[0, 2]), c[1] + lam * (R[1, 0] * x + R[1, 1] * y + R[1, 2]), lam


def floor_depth(camera: CameraModel, T_world_cam: np.ndarray) -> np.ndarray:
    """(H, W) float32 depth (mm, along the optical axis) of the flat floor z = 0 seen from ``T_world_cam``.

    Constant (the camera height) for a camera looking straight down; a tilted camera sees
    the floor nearer on one side.
    """
    T = np.asarray(T_world_cam, dtype=float)
    if _is_level(T):
        return np.full((camera.height_px, camera.width_px), np.float32(T[2, 3]))
    v, u = np.mgrid[0 : camera.height_px, 0 : camera.width_px].astype(np.float64)
    return _floor_hits(camera, T, u, v)[2].astype(np.float32)


def _undistorted_xy(camera: CameraModel, u: np.ndarray, v: np.ndarray, iterations: int = 20) -> tuple:
    """Normalised image coordinates ``(x, y)`` (arrays like ``u``) of pixels ``(u, v)``: the
    Brown-Conrady model of :meth:`CameraModel.project` inverted by fixed-point iteration
    (residual under 1e-12 for the distortion of a real lens)."""
    xd, yd = (u - camera.cx_px) / camera.fx_px, (v - camera.cy_px) / camera.fy_px
    x, y = xd.copy(), yd.copy()
    if camera.has_distortion:
        for _ in range(iterations):
            uv = camera.project(np.stack([x.ravel(), y.ravel(), np.ones(x.size)], axis=1))
            x = x - (uv[:, 0].reshape(x.shape) - u) / camera.fx_px
            y = y - (uv[:, 1].reshape(y.shape) - v) / camera.fy_px
    return x, y


def write_synthetic_sequence(
    out_dir: str | os.PathLike,
    camera: CameraModel,
    T_world_cam: np.ndarray,
    *,
    height_mm: float = 100.0,
    fps: float = 30.0,
    seed: int = 0,
    noise_dn: float = 1.0,
    depth: bool = False,
    depth_noise_mm: float = 0.0,
    height_noise_mm: float | None = None,
    attitude_noise_rad: float | None = None,
    stereo_baseline_mm: float | None = None,
    name: str = "synthetic",
    overwrite: bool = True,
    timestamps_s: np.ndarray | None = None,
) -> Path:
    """Write a floorvo sequence folder for the poses ``T_world_cam`` (N, 4, 4) mm; returns its path.

    Frames are 8-bit, with the LED falloff of :func:`led_falloff`, Gaussian noise of
    ``noise_dn`` and the flat-field frame in ``calib/``. ``depth``: a float32 mm depth map
    per frame (the flat floor, :func:`floor_depth`; poses may be tilted), with Gaussian noise
    of ``depth_noise_mm`` per pixel (seeded from ``seed``). ``height_noise_mm``: also a range
    sensor's camera height per frame (``height.csv``: the pose's height plus Gaussian noise of
    that size, seeded from ``seed``; ``sequence.json`` states it, ``rig.height_noise_mm``); None: no
    such file. ``attitude_noise_rad``: also an IMU's
    roll and pitch per frame (``attitude.csv``: :func:`floorvo.geometry.attitude_of_T` of the
    pose plus Gaussian noise of that size on each angle, seeded from ``seed``); None: no such
    file. ``stereo_baseline_mm``: also a right camera ``cam1``. ``timestamps_s``: the frames'
    times (N,) s, written to ``timestamps.txt`` (a recording's clock: frames dropped, jitter) and
    given to the ground truth; None: frame ``i`` at ``i / fps``, no such file.
    """
    T_world_cam = np.asarray(T_world_cam, dtype=float)
    if timestamps_s is not None:  # refused before anything is written (repeated times left a half-made folder)
        timestamps_s = check_timestamps(np.asarray(timestamps_s, dtype=float), len(T_world_cam), "timestamps_s")
    gsd = camera.gsd_mm_per_px(height_mm)
    xy = T_world_cam[:, :2, 3]
    reach = np.hypot(camera.width_px, camera.height_px) * gsd * 0.6 + (stereo_baseline_mm or 0.0) + 2.0
    lo, hi = xy.min(axis=0) - reach, xy.max(axis=0) + reach
    w_px, h_px = int(np.ceil((hi[0] - lo[0]) / gsd)), int(np.ceil((hi[1] - lo[1]) / gsd))
    from scipy.ndimage import spline_filter

    coeffs = spline_filter(floor_texture(h_px, w_px, seed), order=3, output=np.float32)
    origin = (-lo[0] / gsd, hi[1] / gsd)  # texture px of world (0, 0)
    fall = led_falloff(camera)
    T01 = None
    meta: dict[str, Any] = {
        "name": name,
        "camera": camera.to_dict(),
        "fps": float(fps),
        "frame_count": int(len(T_world_cam)),
        "rig": {"height_mm": float(height_mm)},
        "seeds": {"texture": int(seed)},
        "synthetic": {
            "generator": "floorvo.synthetic",
            "noise_dn": float(noise_dn),
            "depth_noise_mm": float(depth_noise_mm),
        },
    }
    if depth:
        meta["depth"] = {"format": "npy_float32_mm"}
    if height_noise_mm is not None:
        meta["rig"]["height_noise_mm"] = float(height_noise_mm)
    if stereo_baseline_mm:
        T01 = np.eye(4)
        T01[0, 3] = float(stereo_baseline_mm)
        meta["stereo"] = True
        meta["rig"]["T_cam0_cam1"] = T01.tolist()
        meta["cameras"] = {"cam1": camera.to_dict()}
    with SequenceWriter(out_dir, meta, overwrite=overwrite) as w:  # locked until the sequence is written
        rng = np.random.default_rng(seed + 1)
        rng_depth = np.random.default_rng(seed + 2)
        scale = None
        for i, T in enumerate(T_world_cam):
            cams = [("cam0", T)] + ([("cam1", T @ T01)] if T01 is not None else [])
            for cam, Tc in cams:
                img = render_view(coeffs, origin, gsd, camera, Tc) * fall
                if scale is None:
                    scale = 230.0 / float(np.percentile(img, 99.5))
                img = img * scale + rng.normal(0.0, noise_dn, img.shape)
                w.write_frame(i, np.clip(np.round(img), 0, 255).astype(np.uint8), cam)
            if depth:
                z = floor_depth(camera, T)
                if depth_noise_mm > 0:
                    z = (z + rng_depth.normal(0.0, depth_noise_mm, z.shape)).astype(np.float32)
                w.write_depth(i, z)
        flat = np.clip(fall / fall.max() * 60000.0, 0, 65535).astype(np.uint16)
        w.write_calib("cam0_flatfield", flat)
        if T01 is not None:
            w.write_calib("cam1_flatfield", flat)
        if timestamps_s is None:
            w.write_groundtruth(np.arange(len(T_world_cam)) / float(fps), T_world_cam)
        else:
            w.write_timestamps(timestamps_s)
            w.write_groundtruth(np.asarray(timestamps_s, dtype=float), T_world_cam)
        if height_noise_mm is not None:
            h = T_world_cam[:, 2, 3] + np.random.default_rng(seed + 3).normal(0.0, height_noise_mm, len(T_world_cam))
            w.write_heights(h, "synthetic range sensor")
        if attitude_noise_rad is not None:
            noise = np.random.default_rng(seed + 4).normal(0.0, attitude_noise_rad, (len(T_world_cam), 2))
            w.write_attitude(attitude_of_T(T_world_cam) + noise, "synthetic IMU")
    return Path(out_dir)


def texture_extent_mm(texture: np.ndarray, gsd_mm_per_px: float) -> tuple[float, float, float, float]:
    """(xmin, xmax, ymin, ymax) of the floor the texture covers, in mm."""
    h, w = texture.shape
    return (-(w / 2) * gsd_mm_per_px, (w / 2) * gsd_mm_per_px, -(h / 2) * gsd_mm_per_px, (h / 2) * gsd_mm_per_px)


def view(
    texture: np.ndarray,
    camera: CameraModel,
    T_world_cam: np.ndarray,
    height_mm: float,
    *,
    noise_std: float = 0.0,
    rng: np.random.Generator | None = None,
    centre_mm: tuple[float, float] = (0.0, 0.0),
) -> np.ndarray:
    """uint8 (H, W) frame of ``camera`` at ``T_world_cam`` (downward, yaw only) over ``texture``.

    A camera at (X0, Y0) with yaw psi sees floor point ``c + Rz(psi) [(u - cx) g, -(v - cy) g]``
    at pixel (u, v) (cam x = world x, cam y = world -y at yaw 0), so the image -> texture map
    is the rotation by psi about the principal point plus the translation (X0 / g, -Y0 / g).
    ``noise_std``: Gaussian sensor noise in grey levels (needs ``rng``); ``centre_mm``: the
    floor point (mm) at the texture's centre.
    """
    g = camera.gsd_mm_per_px(height_mm)
    x0, y0, psi = se2_from_T(T_world_cam)
    x0, y0 = x0 - centre_mm[0], y0 - centre_mm[1]
    th, tw = texture.shape
    Uc, Vc = x0 / g + tw / 2.0, -y0 / g + th / 2.0
    c, s = np.cos(psi), np.sin(psi)
    cx, cy = camera.cx_px, camera.cy_px
    M = np.array([[c, s, Uc - c * cx - s * cy], [-s, c, Vc + s * cx - c * cy]])
    img = cv2.warpAffine(
        texture, M, camera.size, flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_REFLECT
    )
    img = 30.0 + 200.0 * img
    if noise_std > 0:
        img = img + (rng or np.random.default_rng(0)).normal(0.0, noise_std, img.shape)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)

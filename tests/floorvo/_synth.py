"""Synthetic floor frames made in code: a relief lit from the side, warped by a known motion.

The motion is applied exactly: both frames are resampled from one large texture, the
current one through the rigid map that the camera motion ``T_prev_cur`` induces on a
flat floor at ``height_mm`` (camera looking straight down). A rig-fixed LED falloff and
sensor noise are applied to both, as in a real grazing-light frame.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from floorvo.camera import CameraModel
from floorvo.geometry import T_world_cam_down, invert_T, rot_z
from floorvo.synthetic import floor_texture as _floor_texture
from floorvo.synthetic import led_falloff as falloff  # rig-fixed: bright at the left and right edges


def floor_texture(size_px: int, seed: int) -> np.ndarray:
    """(size, size) float32 texture: a bumpy relief shaded by a light from -x, plus albedo blobs."""
    return _floor_texture(size_px, size_px, seed)


def view(texture: np.ndarray, camera: CameraModel, M_cur_from_prev: np.ndarray) -> np.ndarray:
    """The camera image whose centred pixel p shows texture at centre + M^-1 p."""
    size = texture.shape[0]
    c_tex = np.array([(size - 1) / 2, (size - 1) / 2])
    Minv = np.linalg.inv(M_cur_from_prev)
    A = np.eye(3)
    A[:2, 2] = c_tex
    B = np.eye(3)
    B[:2, 2] = [-camera.cx_px, -camera.cy_px]
    full = (A @ Minv @ B)[:2]
    return cv2.warpAffine(
        texture, full, (camera.width_px, camera.height_px), flags=cv2.INTER_CUBIC | cv2.WARP_INVERSE_MAP
    )


def pixel_motion(T_prev_cur: np.ndarray, camera: CameraModel, height_mm: float) -> np.ndarray:
    """3x3 map of centred pixels prev -> cur induced on the floor by camera motion T_prev_cur."""
    T_cur_prev = invert_T(T_prev_cur)
    M = np.eye(3)
    M[:2, :2] = T_cur_prev[:2, :2]
    M[:2, 2] = T_cur_prev[:2, 3] * camera.fx_px / height_mm
    return M


def frames_along(
    camera: CameraModel, T_world_cam: list[np.ndarray], height_mm: float = 100.0, seed: int = 0, noise_dn: float = 1.0
) -> tuple[list[np.ndarray], np.ndarray]:
    """(uint8 frames, flatfield uint16) of the floor seen from each pose ``T_world_cam`` (mm; the
    floor is placed under the first)."""
    size = int(2.2 * max(camera.width_px, camera.height_px))
    tex = floor_texture(size, seed)
    fall = falloff(camera)
    rng = np.random.default_rng(seed + 1)
    out = []
    for T in T_world_cam:
        img = view(tex, camera, pixel_motion(invert_T(T_world_cam[0]) @ T, camera, height_mm)) * fall
        out.append(_exposed(img, rng, noise_dn))
    return out, _flat(fall)


def _exposed(img: np.ndarray, rng: np.random.Generator, noise_dn: float) -> np.ndarray:
    """A view times the LED falloff as an 8-bit frame: its 99.5th percentile at 230 DN, plus noise."""
    img = img / np.percentile(img, 99.5) * 230.0 + rng.normal(0, noise_dn, img.shape)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def _flat(fall: np.ndarray) -> np.ndarray:
    """The flat-field frame (uint16) of the LED falloff ``fall``."""
    return np.clip(fall / fall.max() * 60000, 0, 65535).astype(np.uint16)


def rolling_frames_along(
    camera: CameraModel,
    pose_at,
    times_s: np.ndarray,
    row_time_s: float,
    height_mm: float = 100.0,
    seed: int = 0,
    noise_dn: float = 1.0,
    T_cam0_cam: np.ndarray | None = None,
    reach_mm: float = 0.0,
) -> tuple[list[np.ndarray], np.ndarray]:
    """(uint8 frames, flatfield uint16) as :func:`frames_along`, taken by a rolling shutter: row
    ``r`` of the frame at ``t`` shows the floor from ``pose_at(t + (r - (H - 1) / 2) row_time_s)``
    (``T_world_cam``, mm; ``sequence.json``'s ``sensor.row_time``). Each row is sampled through
    its own pose's pixel motion, exactly (one map per frame, bicubic): level poses, whose height
    (``T[2, 3]``; ``height_mm`` the texture's scale) scales the view about the principal point.
    ``T_cam0_cam``: the frames of a second camera of the rig at that pose from ``pose_at``'s (a
    stereo rig's right camera, its rows read out with the left's), over the same floor: give both
    cameras the same ``reach_mm`` (the baseline), which widens the floor drawn for them."""
    T01 = np.eye(4) if T_cam0_cam is None else np.asarray(T_cam0_cam, dtype=float)
    size = int(2.2 * max(camera.width_px, camera.height_px)) + int(reach_mm * camera.fx_px / height_mm)
    tex = floor_texture(size, seed)
    fall = falloff(camera)
    rng = np.random.default_rng(seed + 1)
    c_tex = (size - 1) / 2
    rows = np.arange(camera.height_px, dtype=float)
    u = np.arange(camera.width_px, dtype=float) - camera.cx_px
    T0_inv = invert_T(pose_at(float(times_s[0])))
    out = []
    for t in times_s:
        mx = np.empty((camera.height_px, camera.width_px), np.float32)
        my = np.empty_like(mx)
        for r in rows.astype(int):
            T = pose_at(float(t) + (r - (camera.height_px - 1) / 2) * row_time_s) @ T01
            Minv = np.linalg.inv(pixel_motion(T0_inv @ T, camera, height_mm))
            k = float(T[2, 3]) / height_mm  # a camera at another height sees the floor scaled about the centre
            v = (r - camera.cy_px) * k
            mx[r] = Minv[0, 0] * u * k + Minv[0, 1] * v + Minv[0, 2] + c_tex
            my[r] = Minv[1, 0] * u * k + Minv[1, 1] * v + Minv[1, 2] + c_tex
        out.append(_exposed(cv2.remap(tex, mx, my, cv2.INTER_CUBIC) * fall, rng, noise_dn))
    return out, _flat(fall)


def write_rolling_sequence(
    root: Path,
    camera: CameraModel,
    pose_at,
    times_s: np.ndarray,
    readout_ms: float,
    seed: int = 0,
    depth: bool = False,
    T_cam0_cam1: np.ndarray | None = None,
):
    """``(Sequence, T_world_cam (N, 4, 4))``: a sequence folder at ``root`` of the frames
    :func:`rolling_frames_along` draws at ``times_s`` with a readout of ``readout_ms`` (``sequence.json``'s
    ``sensor`` block states it; 0: a global shutter, no block), its flat field and its ground truth
    (the poses at the frame times). ``depth``: the flat floor's depth image per frame (level
    poses); ``T_cam0_cam1``: a right camera too, read out with the left."""
    from floorvo.sequence import Sequence, SequenceWriter

    row_time_s = readout_ms / 1000.0 / (camera.height_px - 1)
    reach_mm = 0.0 if T_cam0_cam1 is None else float(np.abs(T_cam0_cam1[:2, 3]).max())
    frames, flat = rolling_frames_along(camera, pose_at, times_s, row_time_s, seed=seed, reach_mm=reach_mm)
    meta = blank_meta(camera, len(times_s))
    if readout_ms:
        meta["sensor"] = {"shutter": "rolling", "readout_ms": float(readout_ms)}
    if depth:
        meta["depth"] = {"format": "npy_float32_mm"}
    right = None
    if T_cam0_cam1 is not None:
        right, _ = rolling_frames_along(
            camera, pose_at, times_s, row_time_s, seed=seed, T_cam0_cam=T_cam0_cam1, reach_mm=reach_mm
        )
        meta.update(stereo=True, cameras={"cam1": camera.to_dict()})
        meta["rig"]["T_cam0_cam1"] = np.asarray(T_cam0_cam1, dtype=float).tolist()
    truth = np.stack([pose_at(float(t)) for t in times_s])
    with SequenceWriter(root, meta) as w:
        for i, img in enumerate(frames):
            w.write_frame(i, img)
            if right is not None:
                w.write_frame(i, right[i], "cam1")
            if depth:
                w.write_depth(i, flat_floor_depth(camera))
        w.write_calib("cam0_flatfield", flat)
        if right is not None:
            w.write_calib("cam1_flatfield", flat)
        w.write_groundtruth(np.asarray(times_s, dtype=float), truth)
    return Sequence.open(root), truth


def frame_pair(
    camera: CameraModel, T_prev_cur: np.ndarray, height_mm: float = 100.0, seed: int = 0, noise_dn: float = 1.0
):
    """(prev uint8, cur uint8, flatfield uint16) for camera motion ``T_prev_cur`` (mm)."""
    (prev, cur), flat = frames_along(camera, [np.eye(4), T_prev_cur], height_mm, seed, noise_dn)
    return prev, cur, flat


def flat_floor_depth(camera: CameraModel, height_mm: float = 100.0) -> np.ndarray:
    """Depth (mm, along the optical axis) of a flat floor under a downward camera: constant."""
    return np.full((camera.height_px, camera.width_px), np.float32(height_mm))


def stereo_pairs(
    camera: CameraModel,
    T_prev_cur: np.ndarray,
    baseline_mm: float,
    height_mm: float = 100.0,
    seed: int = 0,
    noise_dn: float = 1.0,
):
    """Left and right frames at prev and cur for a rig with cam1 ``baseline_mm`` along cam0's +x.

    Returns ``((L0, R0), (L1, R1), flatfield uint16, T_cam0_cam1)``; each camera is a
    downward camera over the same flat textured floor with its own LED falloff.
    """
    size = int(2.2 * max(camera.width_px, camera.height_px)) + int(baseline_mm * camera.fx_px / height_mm)
    tex = floor_texture(size, seed)
    fall = falloff(camera)
    rng = np.random.default_rng(seed + 1)
    T01 = np.eye(4)
    T01[0, 3] = baseline_mm
    imgs = []
    for T in (np.eye(4), T01, T_prev_cur, T_prev_cur @ T01):
        img = view(tex, camera, pixel_motion(T, camera, height_mm)) * fall
        imgs.append(img)
    scale = 230.0 / np.percentile(imgs[0], 99.5)
    out = [np.clip(np.round(i * scale + rng.normal(0, noise_dn, i.shape)), 0, 255).astype(np.uint8) for i in imgs]
    flat = np.clip(fall / fall.max() * 60000, 0, 65535).astype(np.uint16)
    return (out[0], out[1]), (out[2], out[3]), flat, T01


def disturbed_poses(n: int = 10) -> np.ndarray:
    """(n, 4, 4) T_world_cam: 4 mm/frame with a 2 mm bounce at 2 Hz and roll/pitch of 0.03 rad
    at 1.5 Hz (30 fps): the motion suite's disturbances, up to 0.0094 rad of tilt change a frame."""
    t = np.arange(n) / 30.0
    w = 2 * np.pi * 1.5 * t
    return np.stack(
        [
            T_world_cam_down(
                4.0 * i, 0.0, 100.0 + 2.0 * np.sin(4 * np.pi * t[i]), 0.0, 0.03 * np.sin(w[i]), 0.03 * np.cos(w[i])
            )
            for i in range(n)
        ]
    )


def chain_scaled(T_true: np.ndarray, sx: float, sy: float = 1.0, s_yaw: float = 1.0) -> np.ndarray:
    """Poses (N, 4, 4) whose camera-frame steps are the true ones' with the x, y translation times
    (``sx``, ``sy``) and the yaw times ``s_yaw``: what an estimator with those scales reports."""
    out = [T_true[0].copy()]
    for i in range(len(T_true) - 1):
        d = invert_T(T_true[i]) @ T_true[i + 1]
        d[0, 3] *= sx
        d[1, 3] *= sy
        yaw = np.arctan2(d[1, 0], d[0, 0])
        d[:3, :3] = rot_z(yaw * s_yaw - yaw) @ d[:3, :3]
        out.append(out[-1] @ d)
    return np.stack(out)


def hand_run(
    root: Path, T_true: np.ndarray, T_est: np.ndarray, estimator: str = "phase-corr", lost_after: int | None = None
) -> tuple[Path, Path]:
    """A sequence folder (ground truth only, 64x48 px, 10 Hz) of the poses ``T_true`` and a run
    folder of ``estimator`` that reported ``T_est`` (N, 4, 4) mm; from frame ``lost_after`` on every
    frame is lost (not in the trajectory). Returns ``(run, sequence)``."""
    from floorvo.tum import write_tum

    seq, run = root / "seq", root / "run"
    seq.mkdir(parents=True)
    run.mkdir()
    ts = np.arange(len(T_true)) / 10.0
    write_tum(seq / "groundtruth.txt", ts, T_true)
    camera = {"width_px": 64, "height_px": 48, "K": [[60.0, 0, 31.5], [0, 60.0, 23.5], [0, 0, 1]]}
    meta = {"schema_version": 2, "camera": camera, "fps": 10.0, "frame_count": len(ts), "rig": {"height_mm": 100.0}}
    (seq / "sequence.json").write_text(json.dumps(meta))
    kept = len(ts) if lost_after is None else lost_after
    write_tum(run / "trajectory.txt", ts[:kept], T_est[:kept])
    rows = ["frame,total_ms,status,reason"]
    for i in range(len(ts)):
        status = "init" if i == 0 else ("ok" if i < kept else "lost")
        rows.append(f"{i},1.0,{status},{'weak peak' if status == 'lost' else ''}")
    (run / "timing.csv").write_text("\n".join(rows) + "\n")
    (run / "result.json").write_text(json.dumps({"estimator": estimator}))
    return run, seq


def blank_meta(camera: CameraModel, n: int) -> dict:
    """``sequence.json`` of an ``n``-frame mono sequence of ``camera`` at 30 fps, 100 mm up."""
    return {"camera": camera.to_dict(), "fps": 30.0, "frame_count": n, "rig": {"height_mm": 100.0}}


def blank_sequence(tmp_path: Path, camera: CameraModel, n: int = 3) -> Path:
    """``tmp_path/seq``: ``n`` uniform grey frames of ``camera`` (:func:`blank_meta`), for the
    files beside the frames (``height.csv``, ``attitude.csv``) to be written and read."""
    from floorvo.sequence import SequenceWriter

    root = tmp_path / "seq"
    with SequenceWriter(root, blank_meta(camera, n)) as w:
        for i in range(n):
            w.write_frame(i, np.full((camera.height_px, camera.width_px), 100, np.uint8))
    return root


class Scripted:
    """An estimator that replays one given StepResult per frame (the loop's only collaborator)."""

    name = "scripted"
    requires = frozenset()

    def __init__(self, script):
        self.script = script

    def start(self):
        return {"k": 0}

    def step(self, state, frame):
        res = self.script[state["k"]]
        state["k"] += 1
        return res

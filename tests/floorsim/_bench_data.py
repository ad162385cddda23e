"""Synthetic sequence and run folders for the bench tests (no renderer, no estimator)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from floorvo.camera import CameraModel
from floorvo.geometry import T_world_cam_down
from floorvo.io import atomic_write_bytes
from floorvo.sequence import SequenceWriter
from floorvo.tum import write_tum


def write_sequence(root: Path, n: int = 12, step_mm: float = 2.0, fps: float = 10.0) -> Path:
    """A tiny mono sequence along +x with random-texture frames and ground truth."""
    cam = CameraModel.from_sensor().scaled(0.25)
    w = SequenceWriter(root, {"camera": cam.to_dict(), "fps": fps, "frame_count": n, "rig": {"height_mm": 100.0}})
    rng = np.random.default_rng(0)
    for i in range(n):
        w.write_frame(i, rng.integers(0, 255, (cam.height_px, cam.width_px), dtype=np.uint8))
    ts = np.arange(n) / fps
    T = np.stack([T_world_cam_down(i * step_mm, 0.0, 100.0) for i in range(n)])
    w.write_groundtruth(ts, T)
    return Path(root)


def write_run(
    run: Path,
    seq: Path,
    *,
    scale: float = 1.01,
    y_drift_mm: float = 0.0,
    lost=(),
    total_ms: float = 5.0,
    estimator: str = "fake",
    matches: bool = False,
) -> Path:
    """A run folder whose trajectory is the ground truth with steps scaled by ``scale``."""
    from floorvo.tum import read_tum

    ts, T = read_tum(seq / "groundtruth.txt")
    est = T.copy()
    est[:, 0, 3] = T[0, 0, 3] + (T[:, 0, 3] - T[0, 0, 3]) * scale
    est[:, 1, 3] += np.arange(len(T)) * y_drift_mm
    keep = np.array([i not in lost for i in range(len(T))])
    run.mkdir(parents=True, exist_ok=True)
    write_tum(run / "trajectory.txt", ts[keep], est[keep])
    rows = ["frame,detect_ms,match_ms,estimate_ms,total_ms,status"]
    for i in range(len(T)):
        st = "init" if i == 0 else ("lost" if i in lost else "ok")
        rows.append(f"{i},{total_ms * 0.5},{total_ms * 0.3},{total_ms * 0.2},{total_ms + 0.1 * (i % 3)},{st}")
    (run / "timing.csv").write_text("\n".join(rows) + "\n")
    (run / "result.json").write_text(json.dumps({"estimator": estimator}))
    if matches:
        rng = np.random.default_rng(1)
        for i in (1, 5):
            a = rng.uniform(10, 100, (20, 2))
            import io

            buf = io.BytesIO()
            np.savez(buf, xy_prev_px=a, xy_cur_px=a - [4.0, 0.0])
            atomic_write_bytes(run / "matches" / f"{i:06d}.npz", buf.getvalue())
    return run

"""Run an estimator over a sequence folder and write RUN/trajectory.txt, timing.csv, result.json.

``trajectory.txt`` (TUM, metres, stamped with the sequence's frame times) starts at the
ground-truth pose of the first frame run (the nearest in time, within
:data:`~floorvo.sequence.GROUNDTRUTH_MAX_DIFF_S`) when there is one, at the identity
otherwise; frames where the track was lost are left out, so the gap shows in the file,
and the chain continues from the last good pose (the next frame is matched against the
last good one).
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass

import numpy as np

from floorvo.calibration import ScaleCalibration, apply_scale
from floorvo.errors import FloorbenchError
from floorvo.estimators import Frame, get_estimator, make_config
from floorvo.io import atomic_write_csv, atomic_write_json, atomic_write_text, ensure_writable_dir
from floorvo.sequence import GROUNDTRUTH_MAX_DIFF_S, Sequence
from floorvo.tum import write_tum

__all__ = ["run_estimator", "RunResult", "build_estimator"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RunResult:
    """Summary of a run (also written as result.json)."""

    estimator: str
    run_dir: str
    frames: int
    ok: int
    lost: int
    lost_frames: list
    fps: float
    median_total_ms: float


def build_estimator(seq: Sequence, name: str, overrides: Mapping[str, str] | None = None):
    """Instantiate estimator ``name`` for ``seq``; refuses a sequence lacking what it requires."""
    cls = get_estimator(name)
    cfg = make_config(name, overrides)
    req = set(getattr(cls, "requires", ()))
    if "depth" in req and not seq.has_depth:
        raise FloorbenchError(f"{name} needs depth images, and {seq.root} has none (render it with depth enabled)")
    if "stereo" in req and not seq.has_stereo:
        raise FloorbenchError(f"{name} needs a stereo sequence (cam1), and {seq.root} is mono")
    height = seq.height_mm
    if height is None:
        raise FloorbenchError(
            f"{seq.root}/sequence.json: rig.height_mm is missing (the camera height above the floor, mm)"
        )
    rig = {}
    if seq.has_stereo:
        rig = {
            "camera_right": seq.camera_model("cam1"),
            "T_cam0_cam1": seq.T_cam0_cam1,
            "flatfield_right": seq.flatfield("cam1"),
        }
    flat = seq.flatfield()
    return cls(cfg, seq.camera, height_mm=height, flatfield=flat, **rig), cfg


def run_estimator(
    seq: Sequence | str | os.PathLike,
    name: str,
    out_dir: str | os.PathLike,
    overrides: Mapping[str, str] | None = None,
    frames: range | list[int] | None = None,
    on_frame: Callable[[int, int], None] | None = None,
    scale_calibration: ScaleCalibration | None = None,
) -> RunResult:
    """Run estimator ``name`` over ``seq`` (or the listed ``frames`` of it) into ``out_dir``.

    ``scale_calibration`` (:mod:`floorvo.calibration`): divide each step's camera-frame
    x, y translation by the rig's calibrated scales before chaining it.
    """
    if not isinstance(seq, Sequence):
        seq = Sequence.open(seq)
    est, cfg = build_estimator(seq, name, overrides)
    out = ensure_writable_dir(out_dir)
    indices = list(range(seq.frame_count) if frames is None else frames)
    if not indices:
        raise FloorbenchError(f"{name}: no frames to run on")
    ts_all = seq.timestamps_s
    T_start, found = seq.groundtruth_at(ts_all[indices[:1]])
    T_world = T_start[0]
    if not found[0] and seq.groundtruth() is not None:
        log.warning(
            "%s: no ground-truth pose within %.3f s of frame %d (t = %.6f s); the trajectory starts at the identity",
            seq.root,
            GROUNDTRUTH_MAX_DIFF_S,
            indices[0],
            ts_all[indices[0]],
        )
    state = est.start()
    poses, stamps, rows, lost = [], [], [], []
    t_run = time.perf_counter()
    for k, i in enumerate(indices):
        frame = Frame(
            index=i,
            timestamp_s=float(ts_all[i]),
            image=seq.image(i),
            image_right=seq.image(i, "cam1") if "stereo" in est.requires else None,
            depth_mm=seq.depth_mm(i) if "depth" in est.requires else None,
        )
        res = est.step(state, frame)
        if res.status == "ok":
            step = res.T_prev_cur if scale_calibration is None else apply_scale(res.T_prev_cur, scale_calibration)
            T_world = T_world @ step
        if res.status in ("ok", "init"):
            poses.append(T_world.copy())
            stamps.append(float(ts_all[i]))
        else:
            lost.append({"frame": i, "reason": res.reason})
        tm = res.timing_ms
        rows.append(
            [
                i,
                f"{tm.get('detect', 0):.3f}",
                f"{tm.get('match', 0):.3f}",
                f"{tm.get('estimate', 0):.3f}",
                f"{tm.get('total', 0):.3f}",
                res.status,
                res.n_keypoints,
                res.n_matches,
                res.n_inliers,
            ]
        )
        if on_frame:
            on_frame(k + 1, len(indices))
    wall = time.perf_counter() - t_run
    if poses:
        write_tum(
            out / "trajectory.txt", np.array(stamps), np.stack(poses), header=f"floorvo {name}: T_world_cam, metres"
        )
    else:
        atomic_write_text(out / "trajectory.txt", f"# floorvo {name}: no frame tracked\n")
    atomic_write_csv(
        out / "timing.csv",
        [
            "frame",
            "detect_ms",
            "match_ms",
            "estimate_ms",
            "total_ms",
            "status",
            "n_keypoints",
            "n_matches",
            "n_inliers",
        ],
        rows,
    )
    totals = [float(r[4]) for r in rows]
    counts = {s: sum(1 for r in rows if r[5] == s) for s in ("init", "ok", "lost")}
    result = RunResult(
        estimator=name,
        run_dir=str(out),
        frames=len(indices),
        ok=counts["ok"],
        lost=counts["lost"],
        lost_frames=lost,
        fps=len(indices) / wall if wall > 0 else 0.0,
        median_total_ms=float(np.median(totals)) if totals else 0.0,
    )
    atomic_write_json(
        out / "result.json",
        {
            **asdict(result),
            "config": asdict(cfg),
            "scale_calibration": None if scale_calibration is None else scale_calibration.to_dict(),
            "sequence": str(seq.root),
            "status_counts": counts,
            "first_frame": indices[0],
            "last_frame": indices[-1],
        },
    )
    log.info("%s on %s: %d ok, %d lost, %.1f frames/s", name, seq.root, counts["ok"], counts["lost"], result.fps)
    return result

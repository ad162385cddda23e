"""Localise a whole sequence against a map: RUN/trajectory.txt, timing.csv, result.json.

The run folder has the layout of :func:`floorvo.run.run_estimator`, but the poses are the
map's absolute poses (no ground truth is used): each frame is placed by its own map fix
(``odometry="none"``) or by the ``map-fused`` estimator's belief (fix, else odometry).
Frames not localised are left out of ``trajectory.txt`` and listed with their reasons.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable, Mapping
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from floorvo.config import from_overrides
from floorvo.errors import ConfigError, FloorbenchError
from floorvo.estimators.base import Frame
from floorvo.io import atomic_write_csv, atomic_write_json, atomic_write_text, ensure_writable_dir
from floorvo.mapping.fused import MapFused, MapFusedConfig
from floorvo.sequence import Sequence
from floorvo.tum import write_tum

__all__ = ["localize_sequence", "localize_config", "SET_BY_OPTIONS"]

log = logging.getLogger(__name__)


#: Fields of :class:`MapFusedConfig` that ``floorvo localize`` takes as options, not ``--set``.
SET_BY_OPTIONS = ("map", "odometry")


def localize_config(
    map_dir: str | os.PathLike, odometry: str = "none", overrides: Mapping[str, Any] | None = None
) -> MapFusedConfig:
    """The configuration of a localize run: the map, the odometry and ``--set`` overrides."""
    for key in overrides or {}:
        if key in SET_BY_OPTIONS:
            raise ConfigError(f"localize.{key}: set by the --{key} option, not --set")
    return from_overrides(MapFusedConfig, {**(overrides or {}), "map": str(map_dir), "odometry": odometry}, "localize")


def localize_sequence(
    seq: Sequence | str | os.PathLike,
    map_dir: str | os.PathLike,
    out_dir: str | os.PathLike,
    *,
    odometry: str = "none",
    overrides: Mapping[str, str] | None = None,
    on_frame: Callable[[int, int], None] | None = None,
) -> dict:
    """Localise every frame of ``seq`` against the map in ``map_dir``; returns result.json's dict.

    ``overrides``: ``map-fused`` config fields (``fix_every``, ``min_corr``, ...).
    """
    if not isinstance(seq, Sequence):
        seq = Sequence.open(seq)
    if seq.height_mm is None:
        raise FloorbenchError(
            f"{seq.root}/sequence.json: rig.height_mm is missing (the camera height above the floor, mm)"
        )
    cfg = localize_config(map_dir, odometry, overrides)
    est = MapFused(cfg, seq.camera, height_mm=seq.height_mm, flatfield=seq.flatfield())
    out = ensure_writable_dir(out_dir)
    state = est.start()
    ts_all = seq.timestamps_s
    poses, stamps, rows, lost, fixes = [], [], [], [], 0
    t_run = time.perf_counter()
    n = seq.frame_count
    for i in range(n):
        res = est.step(state, Frame(index=i, timestamp_s=float(ts_all[i]), image=seq.image(i)))
        if res.status in ("ok", "init"):
            poses.append(state.T_world.copy())
            stamps.append(float(ts_all[i]))
            fixes += int("map" in res.reason)
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
                res.reason,
            ]
        )
        if on_frame:
            on_frame(i + 1, n)
    wall = time.perf_counter() - t_run
    name = "map-fused" if odometry != "none" else "relocalise"
    if poses:
        write_tum(
            out / "trajectory.txt",
            np.array(stamps),
            np.stack(poses),
            header=f"floorvo localize ({name}): T_world_cam from the map, metres",
        )
    else:
        atomic_write_text(out / "trajectory.txt", "# floorvo localize: no frame localised\n")
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
            "reason",
        ],
        rows,
    )
    counts = {s: sum(1 for r in rows if r[5] == s) for s in ("init", "ok", "lost")}
    totals = [float(r[4]) for r in rows]
    result = {
        "estimator": name,
        "run_dir": str(out),
        "frames": n,
        "ok": counts["ok"],
        "lost": counts["lost"],
        "lost_frames": lost,
        "fps": n / wall if wall > 0 else 0.0,
        "median_total_ms": float(np.median(totals)) if totals else 0.0,
        "config": asdict(cfg),
        "map": str(Path(map_dir)),
        "map_keyframes": est.map.n_keyframes,
        "sequence": str(seq.root),
        "status_counts": counts,
        "map_fixes": fixes,
        "first_frame": 0,
        "last_frame": n - 1,
    }
    atomic_write_json(out / "result.json", result)
    log.info(
        "localize %s: %d of %d frames placed (%d by map fixes), %.1f frames/s",
        seq.root,
        len(poses),
        n,
        fixes,
        result["fps"],
    )
    return result

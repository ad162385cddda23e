"""Localise a whole sequence against a map: RUN/trajectory.txt, timing.csv, result.json.

The run folder has the layout of :func:`floorvo.run.run_estimator` (written by
:class:`floorvo.runfolder.RunFolder`, the loop is :func:`floorvo.runner.run_sequence`),
but the poses are the map's absolute poses (no ground-truth pose is used; the run starts
at the identity): each frame is placed by its own map fix (``odometry="none"``) or by the
``map-fused`` estimator's belief (fix, else odometry). Frames not localised are left out
of ``trajectory.txt`` and listed with their reasons; ``timing.csv`` has a ``reason``
column, ``result.json`` counts the map fixes (steps that reported ``T_world_cam``).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Mapping
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

import numpy as np

from floorvo.config import from_overrides
from floorvo.errors import ConfigError
from floorvo.io import ensure_writable_dir
from floorvo.locking import locks_folder
from floorvo.mapping.fused import MapFused, MapFusedConfig
from floorvo.runfolder import SEQUENCE_SHA256, sequence_sha256
from floorvo.runner import camera_height_mm, run_sequence
from floorvo.sequence import Sequence

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
    return from_overrides(
        MapFusedConfig,
        {**(overrides or {}), "map": str(map_dir), "odometry": odometry},
        "localize",
        listed_by="floorvo list --config localize",
    )


@locks_folder("out_dir", "run folder")
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

    ``overrides``: ``map-fused`` config fields (``fix_every``, ``min_corr``, ...). ``out_dir`` is
    locked while the run lasts (:func:`floorvo.locking.lock_folder`).
    """
    if not isinstance(seq, Sequence):
        seq = Sequence.open(seq)
    height = camera_height_mm(seq)
    cfg = localize_config(map_dir, odometry, overrides)
    est = MapFused(
        cfg, seq.camera, height_mm=height, flatfield=seq.flatfield(), labels={"map": "--map", "odometry": "--odometry"}
    )
    lacking = seq.lacks(est.requires, f"--odometry {odometry}")
    if lacking:  # --odometry orb-icp on a mono sequence lost every step between fixes ('no depth image')
        raise ConfigError(lacking)
    out = ensure_writable_dir(out_dir)
    name = "map-fused" if odometry != "none" else "relocalise"
    n = seq.frame_count
    run = run_sequence(
        seq,
        est,
        T_world_start=np.eye(4),
        on_step=None if on_frame is None else (lambda k, frame, res: on_frame(k + 1, n)),
        name=name,
    )
    run = replace(run, run_dir=str(out))
    if run.placed.any():
        header = f"floorvo localize ({name}): T_world_cam from the map, metres"
    else:
        header = "floorvo localize: no frame localised"
    result = {
        **run.summary(),
        "config": asdict(cfg),
        "map": str(Path(map_dir)),
        "map_keyframes": est.map.n_keyframes,
        "sequence": str(seq.root),
        SEQUENCE_SHA256: sequence_sha256(seq.meta),
    }
    run.run_folder(header=header, result=result, reasons=True).write(out)
    log.info(
        "localize %s: %d of %d frames placed (%d by map fixes), %.1f frames/s",
        seq.root,
        int(run.placed.sum()),
        n,
        run.fixes,
        run.fps,
    )
    return result

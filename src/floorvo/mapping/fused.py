"""``map-fused``: odometry corrected by keyframe-map fixes (paper 003), so drift is bounded.

Each frame runs an odometry estimator (``odometry``, default ``phase-corr``; ``none`` for
pure relocalisation) and, every ``fix_every`` frames, localises the frame against the map
(:class:`floorvo.mapping.localize.Localizer`, which uses no earlier pose). The believed
pose ``T_world_cur`` is the map fix when there is one, the last belief composed with the
odometry step otherwise; a frame with neither is ``lost``. The drift is thus reset at
every fix, and a kidnapped rig is placed again by the first fix after landing.

``StepResult.T_prev_cur`` is the motion from the previous belief to the new one; a frame
placed by a map fix also reports the fix itself as ``StepResult.T_world_cam``. The runner
(:mod:`floorvo.runner`) places such a frame at the fix and counts it, and chains the
odometry steps between fixes, so :func:`floorvo.run.run_estimator` and
:func:`floorvo.mapping.localize_run.localize_sequence` both write the map's poses.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from floorvo.camera import CameraModel
from floorvo.config import param, parse_set_args
from floorvo.errors import ConfigError
from floorvo.estimators.base import (
    RESTART_NOTE,
    Frame,
    StepResult,
    frame_height_mm,
    state_error,
    takes_height_change_from_signal,
)
from floorvo.estimators.registry import get_estimator, make_config
from floorvo.geometry import invert_T
from floorvo.mapping.localize import LocalizeConfig, Localizer
from floorvo.mapping.map import load_map

__all__ = ["MapFused", "MapFusedConfig"]


@dataclass(frozen=True)
class MapFusedConfig(LocalizeConfig):
    """The localiser's parameters (:class:`LocalizeConfig`) and how fixes and odometry are fused."""

    config_name = "map-fused"

    map: str = param("", doc="map folder (floorvo map SEQ -o MAP)")
    odometry: str = param("phase-corr", doc="estimator between fixes; none: fixes only")
    odometry_set: str = param("", doc="the odometry's overrides as key=value;key=value")
    fix_every: int = param(1, unit="frames", min=1, doc="localise every N-th frame against the map")


@dataclass
class _State:
    odo_state: object = None
    T_world: np.ndarray | None = None  # belief of the last good frame
    last_fix: object = None  # floorvo.mapping.localize.Localization
    # belief of the frame the odometry measures its next step from (its last ok frame, or the one
    # it restarted on); None while that frame has no belief (the odometry restarted off the map)
    T_odo_ref: np.ndarray | None = None


class MapFused:
    """Odometry between keyframe-map fixes (paper 003 relocalisation)."""

    name = "map-fused"
    description = (
        "keyframe-map relocalisation (paper 003) fused with an odometry estimator; needs its map: "
        "--set map=MAP (floorvo run), --est-set map-fused.map=MAP (floorsim bench)"
    )
    Config = MapFusedConfig
    requires: frozenset[str] = frozenset()

    def __init__(
        self,
        config: MapFusedConfig,
        camera: CameraModel,
        *,
        height_mm: float,
        flatfield: np.ndarray | None = None,
        labels: Mapping[str, str] | None = None,
        **rig,
    ):
        # How errors name the map and odometry settings: as config keys here, as the
        # options --map and --odometry of `floorvo localize` (localize_sequence passes them).
        where = {"map": "map-fused.map", "odometry": "map-fused.odometry", **(labels or {})}
        if not config.map:
            raise ConfigError(
                f"{where['map']} = '': set the map folder (floorvo run: --set map=MAP; floorsim bench: "
                "--est-set map-fused.map=MAP), built with `floorvo map SEQ -o MAP`"
            )
        self.config = config
        self.map = load_map(config.map)
        if self.map.camera.size != camera.size:
            raise ConfigError(
                f"{where['map']} {config.map}: the map's camera is {self.map.camera.size}, the sequence's {camera.size}"
            )
        if abs(self.map.height_mm - float(height_mm)) > 0.01 * self.map.height_mm:
            raise ConfigError(
                f"{where['map']} {config.map}: built at height {self.map.height_mm} mm, "
                f"the sequence is at {height_mm} mm"
            )
        # a MapFusedConfig is a LocalizeConfig; the sequence's frames are resampled into the map's pinhole
        self.localizer = Localizer(self.map, config, flatfield=flatfield, camera=camera)
        self.odometry = None
        #: What the sequence must have: the odometry's (orb-icp's depth; :meth:`floorvo.sequence.Sequence.lacks`).
        self.requires: frozenset[str] = frozenset()
        if config.odometry != "none":
            if config.odometry == self.name:
                raise ConfigError(f"{where['odometry']} = 'map-fused': must be another estimator or 'none'")
            overrides = parse_set_args(kv for kv in config.odometry_set.split(";") if kv.strip())
            odo_cfg = make_config(config.odometry, overrides)
            self.odometry = get_estimator(config.odometry)(
                odo_cfg, camera, height_mm=height_mm, flatfield=flatfield, **rig
            )
            self.requires = frozenset(getattr(self.odometry, "requires", ()))
        elif config.odometry_set.strip():  # taken and ignored without a word
            raise ConfigError(f"map-fused.odometry_set = {config.odometry_set!r}: set with no odometry ('none')")
        #: Its steps between fixes are the odometry's: held to a height signal's noise as the odometry's are.
        self.height_change_from_signal = self.odometry is not None and takes_height_change_from_signal(self.odometry)

    def start(self) -> _State:
        return _State(odo_state=self.odometry.start() if self.odometry else None)

    def step(self, state: _State, frame: Frame) -> StepResult:
        if not isinstance(state, _State):
            raise state_error(self.name, state)
        t0 = time.perf_counter()
        odo = self.odometry.step(state.odo_state, frame) if self.odometry else None
        t1 = time.perf_counter()
        fix = None
        if frame.index % self.config.fix_every == 0:
            fix = self.localizer.localize(frame.image, height_mm=frame_height_mm(frame))
        t2 = time.perf_counter()
        timing = {"detect": 1e3 * (t1 - t0), "match": 0.0, "estimate": 1e3 * (t2 - t1), "total": 1e3 * (t2 - t0)}
        counts: dict[str, Any] = dict(
            n_keypoints=fix.n_keypoints if fix else 0,
            n_matches=fix.n_matches if fix else 0,
            n_inliers=fix.n_inliers if fix else 0,
            timing_ms=timing,
        )
        prev = state.T_world
        bridged = ""  # why an ok odometry step placed nothing
        if fix is not None and fix.ok:
            new = fix.T_world_cam
            state.last_fix = fix
        elif odo is not None and odo.ok and state.T_odo_ref is not None:
            # The odometry's step is from its own reference frame: the last frame it measured ok or
            # restarted on, not the last frame placed here (a fix it lost, or a frame it restarted on
            # after a kidnap: steps chained from the last placed frame reported 273 mm off as ok).
            new = state.T_odo_ref @ odo.T_prev_cur
        else:
            new = None
            if odo is not None and odo.ok:
                bridged = "odometry: its step is from the frame it restarted on, which the map did not place"
        if prev is None and new is None and odo is not None and odo.status == "init" and fix is None:
            new = np.eye(4)  # the first frame: anchored at the identity until a fix places the run
        if odo is not None and (odo.ok or odo.status == "init" or RESTART_NOTE in (odo.reason or "")):
            state.T_odo_ref = new  # the odometry's next step is from this frame
        if prev is None:
            # First frame (or no pose yet): anchor at the fix, or wait for one.
            if new is None:
                why = fix.reason if fix is not None else "no map fix yet"
                return StepResult("lost", reason=f"not localised: {why}", **counts)
            state.T_world = new
            fixed = fix is not None and fix.ok
            return StepResult(
                "init",
                reason="first pose" + (" from the map" if fixed else ""),
                T_world_cam=new if fixed else None,
                **counts,
            )
        if new is None:
            parts = []
            if fix is not None:
                parts.append(f"map: {fix.reason}")
            if bridged:
                parts.append(bridged)
            elif odo is not None:
                parts.append(f"odometry: {odo.reason or odo.status}")
            return StepResult("lost", reason="; ".join(parts) or "no fix and no odometry", **counts)
        state.T_world = new
        fixed = fix is not None and fix.ok
        return StepResult(
            "ok",
            invert_T(prev) @ new,
            reason="map fix" if fixed else "odometry",
            T_world_cam=new if fixed else None,
            **counts,
        )

"""Localisation of a live frame against the keyframe map (paper 003, section 3.2, Fig. 11).

For each live frame, independently of every earlier frame (so a kidnapped robot is placed
again on its first frame after landing):

1. **Retrieve** candidate keyframes (:mod:`floorvo.mapping.retrieval`): by descriptor
   voting through an LSH index (default) or a bag of binary words, so the cost grows
   slowly with the map size.
2. **Fit** eq. (5) between the live frame and each candidate from matched features.
3. **Verify** by content similarity (eqs. 20-23) the candidates with the most rigid
   inliers; the most similar keyframe is kept (the paper's "most similar keyframe").
4. **Pose** (eq. 24): ``T_world_live = T_world_kf @ T_kf_live`` with ``T_kf_live`` the
   rigid fit (refined by the matched sub-blocks) converted to a camera motion on the
   floor plane at the camera height.

The live frame is first resampled into the map's pinhole (:attr:`GlobalMap.pinhole`,
:class:`~floorvo.mapping.similarity.FramePreparer`) from its own camera, which may differ
from the map's (distortion, focal lengths, principal point; the camera height must be the
map's, as :class:`~floorvo.mapping.fused.MapFused` checks).

A frame that no keyframe explains (too few inliers, too few matched sub-blocks, low
correlation) is reported as not localised, with the reason, never placed at a guess.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from floorvo.camera import CameraModel
from floorvo.config import Config, param
from floorvo.errors import ConfigFieldError
from floorvo.estimators.base import frame_problem
from floorvo.mapping.keyframes import fit_to_T_i_j
from floorvo.mapping.map import GlobalMap
from floorvo.mapping.similarity import (
    FramePreparer,
    Similarity,
    content_similarity,
    detect_features,
    downscale,
    fit_features,
)

__all__ = ["LocalizeConfig", "Localization", "Localizer"]


@dataclass(frozen=True)
class LocalizeConfig(Config):
    """The localiser's parameters (steps 1-3 of the module docstring): how many candidate
    keyframes are retrieved and verified, and the similarity a fix must reach."""

    config_name = "localize"

    n_candidates: int = param(8, min=1, max=1000, doc="keyframes retrieved per frame")
    n_verify: int = param(3, min=1, max=100, doc="candidates (most inliers first) given the content similarity")
    min_block_fraction: float = param(
        0.5, min=0.0, max=1.0, doc="share of the overlap's sub-blocks that must match (eq. 22)"
    )
    min_corr: float = param(0.6, min=-1.0, max=1.0, doc="least correlation coefficient (eq. 23)")
    min_blocks: int = param(20, min=1, doc="least matched sub-blocks")
    verify_inlier_ratio: float = param(
        0.7, min=0.0, max=1.0, doc="verify candidates with this share of the best one's inliers"
    )
    retrieval: str = param(
        "vote", choices=("vote", "bow"), doc="vote: descriptor votes (LSH); bow: tf-idf bag of words"
    )

    def validate(self) -> None:
        if self.n_verify > self.n_candidates:
            raise ConfigFieldError("n_verify", f" = {self.n_verify}: must be <= n_candidates ({self.n_candidates})")


@dataclass(frozen=True)
class Localization:
    """Outcome for one frame. ``T_world_cam`` (4, 4) mm when ``ok``; otherwise ``reason``.

    ``keyframe``: map keyframe id used; ``similarity``: its eq. (23) value;
    ``timing_ms``: detect, match (retrieval + feature matching), estimate (similarity), total.
    """

    ok: bool
    T_world_cam: np.ndarray | None = None
    reason: str = ""
    keyframe: int = -1
    similarity: float = 0.0
    block_fraction: float = 0.0
    corr: float = 0.0
    n_keypoints: int = 0
    n_matches: int = 0
    n_inliers: int = 0
    timing_ms: dict = field(default_factory=dict)


class Localizer:
    """Localises frames against a :class:`GlobalMap` (see the module docstring).

    ``camera``: the camera of the frames (default: the map's); ``flatfield``: its flat-field frame.
    """

    def __init__(
        self,
        gmap: GlobalMap,
        config: LocalizeConfig | None = None,
        flatfield: np.ndarray | None = None,
        camera: CameraModel | None = None,
    ):
        self.map = gmap
        self.config = config or LocalizeConfig()
        self.flatfield = flatfield
        self.camera = camera or gmap.camera
        self.prepare = FramePreparer(self.camera, gmap.pinhole, flatfield)
        self.sim_cfg = gmap.config.similarity
        self.index = (
            gmap.vote_index if self.config.retrieval == "vote" else gmap.index
        )  # built now, not on the first query

    def localize(
        self, image: np.ndarray, rng: np.random.Generator | None = None, *, height_mm: float | None = None
    ) -> Localization:
        """Global pose of one raw (H, W) frame, using nothing but the frame and the map; a frame
        that is none of the camera's (:func:`floorvo.estimators.base.frame_problem`) is not localised.

        ``height_mm``: the camera's measured height at the frame (a height signal,
        ``Frame.height_mm``; None: the map's). The map converts its fits at its own height, so a
        frame taken higher or lower is first scaled to look as from the map's height
        (:class:`~floorvo.mapping.similarity.FramePreparer`), and the fix is placed at the
        measured height. A frame 2 mm low was fitted rigidly against a picture 2 % larger: its
        fix was that share of its offset from the keyframe off."""
        cfg, sc, m = self.config, self.sim_cfg, self.map
        rng = rng or np.random.default_rng(0)
        t0 = time.perf_counter()
        bad = frame_problem(image, self.camera)
        if bad:  # not localised, said: a frame of another size or a colour one had ended the whole run
            return Localization(False, reason=bad, timing_ms={"total": 1e3 * (time.perf_counter() - t0)})
        p = self.prepare(image, 1.0 if height_mm is None else float(height_mm) / m.height_mm)
        feats = detect_features(p, sc)
        small = downscale(p, sc.sim_scale)
        t1 = time.perf_counter()
        ids, _ = self.index.query(feats.desc, cfg.n_candidates)
        fits = []
        for k in ids:
            # Eq. (5): pixels of the live frame (j) onto keyframe k (i).
            fit = fit_features(m.features[int(k)], feats, sc, rng)
            fits.append((int(k), fit))
        t2 = time.perf_counter()
        good = sorted([kf for kf in fits if kf[1].ok], key=lambda kf: -kf[1].n_inliers)[: cfg.n_verify]
        # Only close calls are worth a second content similarity.
        good = [kf for kf in good if kf[1].n_inliers >= cfg.verify_inlier_ratio * good[0][1].n_inliers]
        best: tuple[int, Similarity] | None = None
        for k, fit in good:
            s = content_similarity(m.images[k], small, fit, sc, refine=True)
            if best is None or s.value > best[1].value:
                best = (k, s)
        t3 = time.perf_counter()
        timing = {
            "detect": 1e3 * (t1 - t0),
            "match": 1e3 * (t2 - t1),
            "estimate": 1e3 * (t3 - t2),
            "total": 1e3 * (t3 - t0),
        }
        n_matches = max((f.n_matches for _, f in fits), default=0)
        n_inl = max((f.n_inliers for _, f in fits), default=0)
        common: dict[str, Any] = dict(n_keypoints=len(feats), n_matches=n_matches, n_inliers=n_inl, timing_ms=timing)
        if not fits:  # retrieval found none: "best: empty map" was said of a map of 4 keyframes
            why = "the frame has no keypoints" if len(feats) == 0 else "no keyframe holds a descriptor near the frame's"
            return Localization(False, reason=f"no candidate keyframe ({why})", **common)
        if best is None:
            return Localization(False, reason=f"no candidate keyframe fits (best: {fits[0][1].reason})", **common)
        k, s = best
        fail = None
        if s.n_blocks < cfg.min_blocks:
            fail = f"{s.n_blocks} matched sub-blocks < {cfg.min_blocks}"
        elif s.block_fraction < cfg.min_block_fraction:
            fail = f"matched sub-blocks {s.block_fraction:.2f} of the overlap < {cfg.min_block_fraction}"
        elif s.corr < cfg.min_corr:
            fail = f"correlation {s.corr:.2f} < {cfg.min_corr}"
        if fail:
            return Localization(
                False,
                reason=f"keyframe {k} not similar enough: {fail}",
                keyframe=k,
                similarity=s.value,
                block_fraction=s.block_fraction,
                corr=s.corr,
                **common,
            )
        T_kf_live = fit_to_T_i_j(s.fit, m.pinhole, m.height_mm)
        if height_mm is not None:  # the camera that far above (or below) the map's height
            T_kf_live[2, 3] = m.height_mm - float(height_mm)  # its z axis points down
        T_world = m.T_world_kf[k] @ T_kf_live  # Eq. (24)
        return Localization(
            True, T_world, keyframe=k, similarity=s.value, block_fraction=s.block_fraction, corr=s.corr, **common
        )

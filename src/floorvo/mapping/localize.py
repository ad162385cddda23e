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

A frame that no keyframe explains (too few inliers, too few matched sub-blocks, low
correlation) is reported as not localised, with the reason, never placed at a guess.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from floorvo.errors import ConfigError
from floorvo.mapping.keyframes import fit_to_T_i_j
from floorvo.mapping.map import GlobalMap
from floorvo.mapping.similarity import (
    Similarity,
    content_similarity,
    detect_features,
    downscale,
    fit_features,
    prepare_image,
)

__all__ = ["LocalizeConfig", "Localization", "Localizer"]


@dataclass(frozen=True)
class LocalizeConfig:
    """``n_candidates``: keyframes retrieved by the bag of words; ``n_verify``: of those, how
    many (most rigid inliers first) get the content similarity, those with at least
    ``verify_inlier_ratio`` times the best candidate's inliers; ``min_block_fraction``: the
    share of the overlap's sub-blocks that must pass the mismatch check (eq. 22);
    ``min_corr``: least correlation coefficient (eq. 23); ``min_blocks``: least matched
    sub-blocks; ``retrieval``: ``vote`` (descriptor voting through an LSH index) or ``bow``
    (tf-idf bag of binary words)."""

    n_candidates: int = field(default=8, metadata={"min": 1, "max": 1000})
    n_verify: int = field(default=3, metadata={"min": 1, "max": 100})
    min_block_fraction: float = field(default=0.5, metadata={"min": 0.0, "max": 1.0})
    min_corr: float = field(default=0.6, metadata={"min": -1.0, "max": 1.0})
    min_blocks: int = field(default=20, metadata={"min": 1})
    verify_inlier_ratio: float = field(default=0.7, metadata={"min": 0.0, "max": 1.0})
    retrieval: str = field(default="vote", metadata={"choices": ("vote", "bow")})

    def __post_init__(self) -> None:
        from floorvo.estimators.base import validate_config

        validate_config(self, "localize")


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
    """Localises frames against a :class:`GlobalMap` (see the module docstring)."""

    def __init__(self, gmap: GlobalMap, config: LocalizeConfig | None = None, flatfield: np.ndarray | None = None):
        self.map = gmap
        self.config = config or LocalizeConfig()
        self.flatfield = flatfield
        self.sim_cfg = gmap.config.similarity
        self.index = (
            gmap.vote_index if self.config.retrieval == "vote" else gmap.index
        )  # built now, not on the first query
        if self.config.n_verify > self.config.n_candidates:
            raise ConfigError(
                f"localize.n_verify = {self.config.n_verify}: must be <= n_candidates ({self.config.n_candidates})"
            )

    def localize(self, image: np.ndarray, rng: np.random.Generator | None = None) -> Localization:
        """Global pose of one raw (H, W) frame, using nothing but the frame and the map."""
        cfg, sc, m = self.config, self.sim_cfg, self.map
        rng = rng or np.random.default_rng(0)
        t0 = time.perf_counter()
        cam = m.camera
        if image.shape != (cam.height_px, cam.width_px):
            raise ConfigError(
                f"localize: frame size {image.shape[1]}x{image.shape[0]} differs from the map camera's {cam.width_px}x{cam.height_px}"
            )
        p = prepare_image(image, self.flatfield)
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
        common = dict(n_keypoints=len(feats), n_matches=n_matches, n_inliers=n_inl, timing_ms=timing)
        if best is None:
            why = fits[0][1].reason if fits else "empty map"
            return Localization(False, reason=f"no candidate keyframe fits (best: {why})", **common)
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
        T_kf_live = fit_to_T_i_j(s.fit, cam, m.height_mm)
        T_world = m.T_world_kf[k] @ T_kf_live  # Eq. (24)
        return Localization(
            True, T_world, keyframe=k, similarity=s.value, block_fraction=s.block_fraction, corr=s.corr, **common
        )

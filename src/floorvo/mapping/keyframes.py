"""Keyframe extraction and keyframe global poses (paper 003, section 3.2).

The first keyframe is the first frame. From keyframe k the content similarity (eq. 23)
with each of the next ``window`` (50) frames is computed (step 1); the maximum is found
(the nearest frame), and the next keyframe is the first frame whose similarity has fallen
to ``ratio`` (50 %) of that maximum, or the ``window``-th frame when none has (step 2).
Consecutive keyframes therefore overlap by about half. A frame the keyframe does not place
at all (similarity 0) while a later frame of the window is still above ``ratio`` of the
maximum is a lost frame (blank, blurred, dropped to black), not the end of the overlap, and
step 2 passes over it; where the similarity does fall to 0 at the end of the overlap, the
last frame before it that is placed becomes the keyframe.

Global poses (eq. 24): the rigid map between consecutive keyframes (eq. 5, from their
matched features, refined by the matched sub-blocks) gives the heading difference and the
position difference, chained from the first keyframe's pose::

    theta_{k+1} = theta_k + d_theta
    x_{k+1} = x_k + cos(theta_k) dx - sin(theta_k) dy
    y_{k+1} = y_k + sin(theta_k) dx + cos(theta_k) dy

done here as ``T_world_kf[k+1] = T_world_kf[k] @ T_kf[k]_kf[k+1]`` with 4x4 poses in mm.

Pixels -> mm: a downward camera at ``height_mm`` maps a floor point at camera-frame
(x, y) mm to pixel (cx + fx x / h, cy + fy y / h), so a rigid map of pixels of frame j
onto frame i is the planar part of ``T_i_j`` after scaling by h / f (:func:`fit_to_T_i_j`,
:func:`floorvo.geometry.pixel_rigid_to_floor`).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from collections.abc import Sequence as Seq
from dataclasses import dataclass

import numpy as np

from floorvo.camera import CameraModel
from floorvo.config import Config, param
from floorvo.errors import FloorbenchError
from floorvo.geometry import pixel_rigid_to_floor, planar_T
from floorvo.mapping.similarity import Features, RigidFit, Similarity, SimilarityConfig, frame_similarity

__all__ = ["KeyframeConfig", "KeyframeResult", "extract_keyframes", "fit_to_T_i_j", "chain_poses"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class KeyframeConfig(Config):
    """``window``: frames compared after each keyframe (paper: 50); ``ratio``: the next
    keyframe is where the similarity falls to this fraction of the window's maximum
    (paper: 0.5)."""

    config_name = "keyframes"

    window: int = param(50, unit="frames", min=1, max=10000, doc="frames compared after each keyframe")
    ratio: float = param(0.5, gt=0, lt=1, doc="next keyframe where the similarity falls to this fraction")


@dataclass(frozen=True)
class KeyframeResult:
    """``indices``: keyframe frame indices (K,); ``T_kf_prev_kf`` (K, 4, 4): pose of keyframe k
    in keyframe k-1 (identity for k = 0); ``similarities``: per keyframe k > 0, the list of
    (frame, similarity) computed from keyframe k-1."""

    indices: list[int]
    T_kf_prev_kf: np.ndarray
    similarities: list[list[tuple[int, float]]]


def fit_to_T_i_j(fit: RigidFit, camera: CameraModel, height_mm: float) -> np.ndarray:
    """4x4 ``T_i_j`` (mm) of a downward camera from the rigid map of pixels j -> i (eq. 5).

    A floor point seen at camera-frame (x_j, y_j) in j is at ``q_i = R2 q_j + t2`` in i
    (:func:`floorvo.geometry.pixel_rigid_to_floor`); the result is the planar part of
    ``T_i_j`` (rotation about the optical axis, translation in the image plane, same height).
    """
    return planar_T(*pixel_rigid_to_floor(fit.R, fit.t_px, camera, height_mm))


def chain_poses(T_world_first: np.ndarray, T_kf_prev_kf: np.ndarray) -> np.ndarray:
    """Eq. (24): global keyframe poses (K, 4, 4) by chaining the relative transforms."""
    out = [np.asarray(T_world_first, dtype=float)]
    for T in T_kf_prev_kf[1:]:
        out.append(out[-1] @ T)
    return np.stack(out)


def extract_keyframes(
    small: Seq[np.ndarray] | Callable[[int], np.ndarray],
    feats: Seq[Features] | Callable[[int], Features],
    n_frames: int,
    camera: CameraModel,
    height_mm: float,
    sim_cfg: SimilarityConfig,
    kf_cfg: KeyframeConfig,
    *,
    rng: np.random.Generator | None = None,
    on_progress: Callable[[int, int], None] | None = None,
) -> KeyframeResult:
    """Section 3.2 steps 1-2 over frames ``0 .. n_frames - 1``.

    ``small[i]``: prepared frame i at the similarity scale; ``feats[i]``: its features
    (sequences, or callables that return them, e.g. a cache over a sequence on disk).
    Raises :class:`FloorbenchError` when a keyframe has no overlapping frame at all in its
    window (the map would break apart there).
    """
    get_small = small if callable(small) else small.__getitem__
    get_feats = feats if callable(feats) else feats.__getitem__
    rng = rng or np.random.default_rng(0)
    if n_frames < 1:
        raise FloorbenchError("keyframe extraction: no frames")
    k = 0
    indices = [0]
    rel = [np.eye(4)]
    sims_log: list[list[tuple[int, float]]] = []
    while k < n_frames - 1:
        last = min(k + kf_cfg.window, n_frames - 1)
        # Step 1: similarity of keyframe k with the next frames.
        results: list[tuple[int, Similarity]] = []
        for j in range(k + 1, last + 1):
            s = frame_similarity(get_small(k), get_feats(k), get_small(j), get_feats(j), sim_cfg, rng=rng)
            results.append((j, s))
        values = np.array([s.value for _, s in results])
        vmax = float(values.max())
        if vmax <= 0:
            raise FloorbenchError(
                f"keyframe extraction: frame {k} overlaps none of frames {k + 1}..{last} "
                "(similarity 0: too fast, a blank or blurred keyframe, or the frames are not of one floor)"
            )
        # Step 2: the first frame whose similarity fell to ratio x max, else the window's last;
        # frames with none before a later one still above it are lost frames, passed over (one
        # black frame just after a keyframe ended the whole map build: "no frame after keyframe
        # 9 can be placed against it").
        thr = kf_cfg.ratio * vmax
        last_above = int(np.flatnonzero(values > thr)[-1])
        lost = [j for n, (j, _) in enumerate(results) if values[n] <= 0 and n < last_above]
        if lost:
            log.warning("map: frames %s are not placed against keyframe frame %d (lost frames): passed over", lost, k)
        nxt = None
        for n, ((j, s), v) in enumerate(zip(results, values)):
            if v <= thr and not (v <= 0 and n < last_above):
                nxt = (j, s)
                break
        if nxt is None:
            nxt = results[-1]
        j, s = nxt
        if s.value <= 0 or not s.fit.ok:
            # The drop can be to zero (no overlap at all): keep the last frame that still overlaps.
            ok = [(jj, ss) for jj, ss in results if jj < j and ss.fit.ok and ss.value > 0]
            if not ok:
                raise FloorbenchError(f"keyframe extraction: no frame after keyframe {k} can be placed against it")
            j, s = ok[-1]
        indices.append(j)
        rel.append(fit_to_T_i_j(s.fit, camera, height_mm))
        sims_log.append([(jj, float(v)) for (jj, _), v in zip(results, values)])
        log.debug("keyframe %d: frame %d (similarity %.1f of max %.1f)", len(indices) - 1, j, s.value, vmax)
        k = j
        if on_progress:
            on_progress(k + 1, n_frames)
    return KeyframeResult(indices, np.stack(rel), sims_log)

"""Descriptor matching: the pure matchers every feature estimator and the mapping use.

Modelled on Kornia's ``feature/matching.py``: plain functions of two descriptor arrays
that return index pairs and distances, no state and no file I/O. Exact nearest
neighbours are brute force (Hamming distance for binary uint8 descriptors such as
AKAZE's MLDB and ORB, L2 for float descriptors such as SIFT) by ``cv2.batchDistance``,
the kernel of OpenCV's ``BFMatcher``, which returns arrays (no per-match Python objects
to unpack). A caller with its own (approximate) index passes its k nearest neighbours to
:func:`ratio_test` (:func:`knn_from_dmatches` turns OpenCV ``knnMatch`` results into them).

Conventions
-----------
* ``desc0`` (N0, B) and ``desc1`` (N1, B): one descriptor per row, both of one kind.
* A :class:`Matches` holds ``idx`` (M, 2) int64 pairs ``(i in desc0, j in desc1)``,
  ``distance`` (M,) of each pair and, for ratio matches, ``ratio`` (M,): nearest over
  second-nearest distance (Lowe's ratio, paper 001's ``gamma = d / L``). Pairs come in
  ascending ``i``.
* Uniqueness rules (``unique`` of :func:`ratio_test`): ``"none"`` lets several rows of
  ``desc0`` take the same row of ``desc1``; ``"first"`` keeps, for each row of ``desc1``,
  the pair of the lowest ``i``; ``"best"`` keeps the pair of the lowest ratio (ties: the
  lowest ``i``). ``cross_check`` of :func:`match_nn` keeps mutual nearest neighbours.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import chain

import cv2
import numpy as np
from scipy.spatial import cKDTree

__all__ = [
    "Matches",
    "UNIQUE_RULES",
    "knn",
    "knn_from_dmatches",
    "match_nn",
    "ratio_test",
    "match_ratio",
    "pack_descriptors",
    "hamming_distances",
    "match_guided",
]

#: Uniqueness rules of :func:`ratio_test` (see the module docstring).
UNIQUE_RULES = ("none", "first", "best")


@dataclass(frozen=True)
class Matches:
    """Matched index pairs ``idx`` (M, 2) ``(i in desc0, j in desc1)``, their ``distance``
    (M,) and, for ratio matches, the ratio ``d_nearest / d_second`` (M,) (None otherwise)."""

    idx: np.ndarray
    distance: np.ndarray
    ratio: np.ndarray | None = None

    def __len__(self) -> int:
        return int(len(self.idx))

    @property
    def i0(self) -> np.ndarray:
        """(M,) indices into ``desc0``."""
        return self.idx[:, 0]

    @property
    def i1(self) -> np.ndarray:
        """(M,) indices into ``desc1``."""
        return self.idx[:, 1]


def _empty(with_ratio: bool = False) -> Matches:
    return Matches(np.zeros((0, 2), np.int64), np.zeros(0), np.zeros(0) if with_ratio else None)


def _norm(desc0: np.ndarray, desc1: np.ndarray) -> tuple[int, int]:
    """OpenCV norm and distance type for the descriptor kind: Hamming (int) for uint8 (binary)
    rows, L2 (float) for float rows."""
    if desc0.dtype != desc1.dtype:
        raise ValueError(f"descriptors of two kinds: {desc0.dtype} and {desc1.dtype}")
    return (cv2.NORM_HAMMING, cv2.CV_32S) if desc0.dtype == np.uint8 else (cv2.NORM_L2, cv2.CV_32F)


def _check(desc0: np.ndarray, desc1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    d0, d1 = np.asarray(desc0), np.asarray(desc1)
    if d0.ndim != 2 or d1.ndim != 2 or (len(d0) and len(d1) and d0.shape[1] != d1.shape[1]):
        raise ValueError(f"need descriptors (N0, B) and (N1, B), got shapes {d0.shape} and {d1.shape}")
    return d0, d1


def knn(desc0: np.ndarray, desc1: np.ndarray, k: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` nearest rows of ``desc1`` for every row of ``desc0``, nearest first (exact).

    Returns ``(distance (N0, k) float64, index (N0, k) int64)``; where ``desc1`` has fewer
    than ``k`` rows the missing neighbours have distance ``inf`` and index -1. The same
    neighbours as OpenCV's brute-force ``knnMatch`` (``cv2.batchDistance``, which it runs),
    as arrays.
    """
    d0, d1 = _check(desc0, desc1)
    dist = np.full((len(d0), k), np.inf)
    idx = np.full((len(d0), k), -1, dtype=np.int64)
    if len(d0) == 0 or len(d1) == 0:
        return dist, idx
    norm, dtype = _norm(d0, d1)
    kk = min(k, len(d1))
    d, i = cv2.batchDistance(d0, d1, dtype, normType=norm, K=kk)
    dist[:, :kk], idx[:, :kk] = d, i
    return dist, idx


def knn_from_dmatches(found: Sequence[Sequence[cv2.DMatch]], n_query: int, k: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """:func:`knn`'s arrays from OpenCV ``knnMatch`` results (e.g. of a FLANN index, which
    may return fewer than ``k`` neighbours for a row): ``(distance (n_query, k), index (n_query, k))``."""
    if k == 2 and len(found) == n_query:
        # The common case, without a Python object per neighbour: every row has two
        # neighbours (OpenCV returns row i for query i).
        try:
            flat = np.fromiter(
                chain.from_iterable((a.distance, b.distance, a.trainIdx, b.trainIdx) for a, b in found),
                dtype=np.float64,
                count=4 * n_query,
            ).reshape(n_query, 4)
            return flat[:, :2].copy(), flat[:, 2:].astype(np.int64)
        except ValueError:  # a row with fewer (or more) neighbours
            pass
    dist = np.full((n_query, k), np.inf)
    idx = np.full((n_query, k), -1, dtype=np.int64)
    for m in found:
        for r, dm in enumerate(m[:k]):
            dist[dm.queryIdx, r], idx[dm.queryIdx, r] = dm.distance, dm.trainIdx
    return dist, idx


def match_nn(desc0: np.ndarray, desc1: np.ndarray, *, cross_check: bool = False) -> Matches:
    """Nearest row of ``desc1`` for every row of ``desc0`` (exact brute force).

    With ``cross_check`` only mutual nearest neighbours are kept (``j`` is the nearest of
    ``i`` and ``i`` the nearest of ``j``; ties go to the lowest index), as OpenCV's
    ``BFMatcher(crossCheck=True)`` does.
    """
    d0, d1 = _check(desc0, desc1)
    if len(d0) == 0 or len(d1) == 0:
        return _empty()
    dist, idx = knn(d0, d1, 1)
    rows = np.arange(len(d0))
    if cross_check:
        _, back = knn(d1, d0, 1)
        rows = rows[back[idx[:, 0], 0] == rows]
    return Matches(np.column_stack([rows, idx[rows, 0]]).astype(np.int64), dist[rows, 0])


def ratio_test(knn_distance: np.ndarray, knn_index: np.ndarray, ratio: float, *, unique: str = "none") -> Matches:
    """Lowe's ratio test on the two nearest neighbours of each row of ``desc0``.

    ``knn_distance``, ``knn_index``: (N0, 2) distances and ``desc1`` indices of the nearest
    and second-nearest neighbour (:func:`knn`, or an approximate index; a missing neighbour
    has distance ``inf`` or index -1 and gives no match). Row ``i`` matches its nearest
    ``j`` when ``d_nearest < ratio * d_second``. ``unique``: one of :data:`UNIQUE_RULES`
    (module docstring). Returns :class:`Matches` with ``ratio = d_nearest / d_second``
    (1 where ``d_second`` is 0), pairs in ascending ``i``.
    """
    dist = np.asarray(knn_distance, dtype=float)
    index = np.asarray(knn_index, dtype=np.int64)
    if dist.ndim != 2 or dist.shape[1] < 2 or index.shape != dist.shape:
        raise ValueError(f"ratio test: need (N, 2) neighbour distances and indices, got {dist.shape} and {index.shape}")
    if unique not in UNIQUE_RULES:
        raise ValueError(f"ratio test: unique = {unique!r} must be one of {', '.join(UNIQUE_RULES)}")
    if not 0.0 < ratio <= 1.0:
        raise ValueError(f"ratio test: ratio = {ratio!r} must be in (0, 1]")
    d_near, d_second = dist[:, 0], dist[:, 1]
    found = (index[:, 0] >= 0) & (index[:, 1] >= 0) & np.isfinite(d_second)
    ok = found & (d_near < ratio * d_second)
    rows = np.nonzero(ok)[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        gamma = np.where(d_second[rows] > 0, d_near[rows] / d_second[rows], 1.0)
    cols = index[rows, 0]
    if unique != "none" and len(rows):
        # Several rows of desc0 took one row of desc1: keep the first, or the one of lowest ratio.
        order = np.argsort(gamma, kind="stable") if unique == "best" else np.arange(len(rows))
        _, first = np.unique(cols[order], return_index=True)
        keep = np.sort(order[first])
        rows, cols, gamma = rows[keep], cols[keep], gamma[keep]
    return Matches(np.column_stack([rows, cols]).astype(np.int64), d_near[rows], gamma)


def match_ratio(desc0: np.ndarray, desc1: np.ndarray, ratio: float, *, unique: str = "none") -> Matches:
    """Ratio-test matches of ``desc0`` in ``desc1``: :func:`ratio_test` on the exact :func:`knn`."""
    return ratio_test(*knn(desc0, desc1, 2), ratio, unique=unique)


def pack_descriptors(desc: np.ndarray) -> np.ndarray:
    """uint8 binary descriptors (N, B) as (N, ceil(B / 8)) uint64 words (zero padded), for fast XOR/popcount."""
    desc = np.ascontiguousarray(desc, dtype=np.uint8)
    pad = (-desc.shape[1]) % 8
    if pad:
        desc = np.hstack([desc, np.zeros((len(desc), pad), dtype=np.uint8)])
    return desc.view(np.uint64)


def hamming_distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Bitwise Hamming distance between packed descriptor rows ``a`` (..., W) and ``b`` (..., W) (uint64 words)."""
    return np.bitwise_count(np.bitwise_xor(a, b)).sum(axis=-1, dtype=np.int32)


def match_guided(
    xy_pred_px: np.ndarray,
    xy1_px: np.ndarray,
    packed0: np.ndarray,
    packed1: np.ndarray,
    *,
    radius_px: float,
    max_candidates: int,
    max_distance: int,
) -> Matches:
    """Motion-predicted matching of paper 000 (section II-B, eq. (2)): nearest position first.

    Row ``i`` of ``desc0`` is predicted at ``xy_pred_px[i]`` (N0, 2) in the new frame; the
    new frame's keypoints ``xy1_px`` (N1, 2) within ``radius_px`` of it are visited in order
    of distance from the prediction (at most ``max_candidates``), and the first whose
    Hamming distance is under ``max_distance`` bits is the match. ``packed0``, ``packed1``:
    the binary descriptors packed by :func:`pack_descriptors`. Pairs in ascending ``i``;
    ``distance`` is the Hamming distance.
    """
    pred = np.asarray(xy_pred_px, dtype=float).reshape(-1, 2)
    pts = np.asarray(xy1_px, dtype=float).reshape(-1, 2)
    if len(pred) == 0 or len(pts) == 0:
        return _empty()
    k = min(int(max_candidates), len(pts))
    dist, idx = cKDTree(pts).query(pred, k=k, distance_upper_bound=radius_px)
    dist, idx = dist.reshape(len(pred), k), idx.reshape(len(pred), k)
    # Only the candidates inside the radius are compared (row-major: each row's nearest
    # position first); with many candidates most of the (N0, k) table lies outside it.
    rows, cols = np.nonzero(np.isfinite(dist))
    cand = idx[rows, cols]
    ham = hamming_distances(packed0[rows], packed1[cand])
    passed = ham < max_distance
    rows, cand, ham = rows[passed], cand[passed], ham[passed]
    rows, first = np.unique(rows, return_index=True)  # the nearest candidate passing the threshold
    return Matches(np.column_stack([rows, cand[first]]).astype(np.int64), ham[first].astype(float))

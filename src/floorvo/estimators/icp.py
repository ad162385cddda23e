"""3D-3D rigid motion by SVD (the ICP-SVD step of paper 001, section 5).

Given matched point sets ``P = {p_i}`` and ``P' = {p'_i}`` with ``p_i = R p'_i + t``
(eq. (9)), :func:`icp_svd` minimises eq. (11), ``1/2 sum |p_i - (R p'_i + t)|^2``:

* centroids ``p``, ``p'`` (eq. (12)) and centred points ``q_i``, ``q'_i`` (eq. (15));
* ``W = sum q_i q'_i^T`` (eq. (20)), ``W = U S V^T`` (eq. (21)), ``R = U V^T``;
* ``t = p - R p'`` (eq. (17)).

Reflection check: when ``det(U V^T) < 0`` the paper takes ``-R``; that is not the best
rotation (for 3x3 matrices ``-R`` is the point reflection of a reflection). The correct
closed form (Arun/Umeyama) flips the singular vector of the smallest singular value:
``R = U diag(1, 1, det(U V^T)) V^T``. This case occurs for every planar point set (a
floor): W then has rank 2 and the third singular vectors' signs are arbitrary.

:func:`icp_svd_robust` iterates the SVD solution with residual-based rejection (the
"iterative" ICP of paper 001 with known correspondences).

:func:`rigid_fit_3d` is the same solver in source/destination order
(``dst_i ~ R src_i + t``), the form the estimators use: with ``src`` the points in the
current camera and ``dst`` the same floor points in the previous camera, ``(R, t)`` is
``T_prev_cur``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["rigid_fit_3d", "icp_svd", "icp_svd_robust"]


def icp_svd(P: np.ndarray, P_prime: np.ndarray, weights: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(R (3, 3), t (3,))`` minimising ``sum w_i |P_i - (R P'_i + t)|^2``.

    ``P``, ``P_prime``: (N, 3) matched points, N >= 3 and not all collinear.
    """
    P = np.asarray(P, dtype=float)
    Q = np.asarray(P_prime, dtype=float)
    if P.shape != Q.shape or P.ndim != 2 or P.shape[1] != 3 or len(P) < 3:
        raise ValueError(f"icp_svd: need two (N, 3) arrays with N >= 3, got {P.shape} and {Q.shape}")
    w = np.ones(len(P)) if weights is None else np.asarray(weights, dtype=float)
    if w.shape != (len(P),) or not np.all(w >= 0) or w.sum() <= 0:
        raise ValueError(
            f"icp_svd: weights must be (N,) = ({len(P)},), non-negative, not all zero; got shape {w.shape}"
        )
    w = w / w.sum()
    p = w @ P  # eq. (12)
    p_prime = w @ Q
    q = P - p  # eq. (15)
    q_prime = Q - p_prime
    W = (q * w[:, None]).T @ q_prime  # eq. (20): sum q_i q'_i^T
    U, _, Vt = np.linalg.svd(W)  # eq. (21)
    d = np.sign(np.linalg.det(U @ Vt)) or 1.0
    R = U @ np.diag([1.0, 1.0, d]) @ Vt  # R = U V^T with the reflection check
    t = p - R @ p_prime  # eq. (17): t* = p - R p'
    return R, t


def rigid_fit_3d(src: np.ndarray, dst: np.ndarray, weights: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(R (3, 3), t (3,))`` minimising ``sum w_i |dst_i - (R src_i + t)|^2`` (eq. (11) of paper 001).

    ``src``, ``dst``: (N, 3) matched points, N >= 3 and not all collinear; ``weights``: (N,)
    non-negative, None = equal. ``det R = +1`` always (reflection check, see the module docstring).
    """
    return icp_svd(dst, src, weights)


def icp_svd_robust(
    P: np.ndarray, P_prime: np.ndarray, *, iterations: int = 3, k_mad: float = 4.0, min_points: int = 3
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Iterated :func:`icp_svd`: drop pairs whose residual exceeds ``median + k_mad * 1.4826 MAD``.

    Returns ``(R, t, inlier_mask (N,))``.
    """
    P = np.asarray(P, dtype=float)
    Q = np.asarray(P_prime, dtype=float)
    keep = np.ones(len(P), dtype=bool)
    R, t = icp_svd(P, Q)
    for _ in range(iterations):
        r = np.linalg.norm(P - (Q @ R.T + t), axis=1)  # eq. (10)
        med = float(np.median(r[keep]))
        mad = float(np.median(np.abs(r[keep] - med))) * 1.4826
        new = r <= med + k_mad * max(mad, 1e-9)
        if new.sum() < min_points or np.array_equal(new, keep):
            break
        keep = new
        R, t = icp_svd(P[keep], Q[keep])
    return R, t, keep

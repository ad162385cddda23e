"""ICP-SVD (paper 001, eqs. (8)-(21)) against exact rigid motions of noiseless point sets."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from floorvo.estimators.icp import icp_svd, icp_svd_robust


def _apply(R, t, X):
    return X @ R.T + t


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_exact_on_noiseless_3d_points(seed):
    rng = np.random.default_rng(seed)
    R = Rotation.random(random_state=seed).as_matrix()
    t = rng.normal(0, 50, 3)
    P_prime = rng.normal(0, 30, (40, 3))
    P = _apply(R, t, P_prime)  # eq. (9): p_i = R p'_i + t
    R_est, t_est = icp_svd(P, P_prime)
    np.testing.assert_allclose(R_est, R, atol=1e-10)
    np.testing.assert_allclose(t_est, t, atol=1e-9)
    assert np.linalg.det(R_est) == pytest.approx(1.0)


def test_planar_points_would_give_a_reflection():
    """Floor points (all z = 100): W has rank 2; R = U V^T alone is a reflection here."""
    rng = np.random.default_rng(5)
    P_prime = np.column_stack([rng.uniform(-40, 40, (30, 2)), np.full(30, 100.0)])
    yaw = np.radians(3.0)
    R = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1.0]])
    t = np.array([4.0, -1.5, 0.0])
    P = _apply(R, t, P_prime)
    # Construct the SVD the naive solution would use and confirm it is a reflection case for some
    # sign choice: flipping the null-space singular vector of W makes det(U V^T) = -1.
    q, qp = P - P.mean(0), P_prime - P_prime.mean(0)
    U, S, Vt = np.linalg.svd(q.T @ qp)
    assert S[2] < 1e-9 * S[0]
    flipped = U @ np.diag([1, 1, -1.0]) @ Vt if np.linalg.det(U @ Vt) > 0 else U @ Vt
    assert np.linalg.det(flipped) == pytest.approx(-1.0)
    # The paper's "-R" remedy is not the motion either.
    assert not np.allclose(-flipped, R, atol=1e-6)
    R_est, t_est = icp_svd(P, P_prime)
    np.testing.assert_allclose(R_est, R, atol=1e-10)
    np.testing.assert_allclose(t_est, t, atol=1e-9)


def test_mirrored_point_set_returns_a_rotation_not_the_reflection():
    """Points related by a true reflection: the best rotation is returned (det +1)."""
    rng = np.random.default_rng(3)
    P_prime = rng.normal(0, 10, (20, 3))
    M = np.diag([1.0, 1.0, -1.0])
    P = P_prime @ M.T
    R_est, _ = icp_svd(P, P_prime)
    assert np.linalg.det(R_est) == pytest.approx(1.0)
    assert not np.allclose(R_est, M)


def test_robust_iterations_drop_outliers():
    rng = np.random.default_rng(4)
    R = Rotation.from_euler("z", 10, degrees=True).as_matrix()
    t = np.array([1.0, 2.0, 3.0])
    P_prime = rng.normal(0, 20, (50, 3))
    P = _apply(R, t, P_prime)
    P[:5] += rng.normal(0, 30, (5, 3))  # five wrong matches
    R_est, t_est, keep = icp_svd_robust(P, P_prime)
    assert not keep[:5].any() and keep[5:].all()
    np.testing.assert_allclose(R_est, R, atol=1e-9)
    np.testing.assert_allclose(t_est, t, atol=1e-8)


def test_refuses_too_few_points():
    with pytest.raises(ValueError, match="N >= 3"):
        icp_svd(np.zeros((2, 3)), np.zeros((2, 3)))


def test_rigid_fit_3d_source_destination_order_on_a_floor_with_weights():
    """rigid_fit_3d(src, dst): dst = R src + t, exact on coplanar (floor) points; a weight of 0 ignores a pair."""
    from floorvo.estimators.icp import rigid_fit_3d

    rng = np.random.default_rng(11)
    src = np.column_stack([rng.uniform(-50, 50, (25, 2)), np.full(25, 100.0)])  # X_cur on the floor plane
    R = Rotation.from_euler("z", -7.5, degrees=True).as_matrix()
    t = np.array([-3.0, 12.0, 0.0])
    dst = _apply(R, t, src)  # X_prev = R X_cur + t
    R_est, t_est = rigid_fit_3d(src, dst)
    np.testing.assert_allclose(R_est, R, atol=1e-10)
    np.testing.assert_allclose(t_est, t, atol=1e-9)
    dst_bad = dst.copy()
    dst_bad[0] += [40.0, -25.0, 5.0]
    w = np.ones(25)
    w[0] = 0.0
    R_w, t_w = rigid_fit_3d(src, dst_bad, weights=w)
    np.testing.assert_allclose(R_w, R, atol=1e-10)
    np.testing.assert_allclose(t_w, t, atol=1e-9)
    R_u, _ = rigid_fit_3d(src, dst_bad)  # unweighted, the wrong pair pulls the fit away
    assert not np.allclose(R_u, R, atol=1e-6)
    with pytest.raises(ValueError, match="weights"):
        rigid_fit_3d(src, dst, weights=np.zeros(25))

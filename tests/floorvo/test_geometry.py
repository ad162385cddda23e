"""floorvo.geometry: the one rigid fit (Kabsch/Umeyama, paper 001's ICP-SVD, eqs. (8)-(22)),
the one rigid inverse and the pixel <-> floor conversions, against exact motions and hand computation."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from floorvo.camera import CameraModel
from floorvo.geometry import (
    T_world_cam_down,
    axis_scales_design,
    axis_scales_fit,
    consensus_problem,
    fit_plane,
    floor_mm_to_pixels,
    floor_rigid_to_T,
    footprint_T,
    invert_T,
    make_T,
    nearest_rotation_2d,
    pixel_rigid_to_floor,
    pixels_to_floor_mm,
    planar_T,
    plane_fit_precision,
    rigid_fit,
    rigid_fit_2d_information,
    rigid_fit_precision,
    rigid_fit_robust,
    rival_homography_support,
    rot_z,
    similarity_fit_2d,
    tilt_change_rad,
    umeyama,
)


def icp_svd(P, P_prime, weights=None):
    """Paper 001's argument order: ``P = R P' + t`` (eq. (9)) is ``rigid_fit(P', P)``."""
    return rigid_fit(P_prime, P, weights)


def icp_svd_robust(P, P_prime):
    return rigid_fit_robust(P_prime, P)


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
    """rigid_fit(src, dst): dst = R src + t, exact on coplanar (floor) points; a weight of 0 ignores a pair."""
    rigid_fit_3d = rigid_fit
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


# ----------------------------------------------------------------------------- Kabsch / Umeyama
def test_umeyama_recovers_known_rigid_motion():
    rng = np.random.default_rng(1)
    src = rng.normal(size=(30, 3)) * 50
    R = make_T(rot_z(0.7), [0, 0, 0])[:3, :3] @ np.array(
        [[1, 0, 0], [0, np.cos(0.3), -np.sin(0.3)], [0, np.sin(0.3), np.cos(0.3)]]
    )
    t = np.array([5.0, -3.0, 12.0])
    R_hat, t_hat, s = umeyama(src, src @ R.T + t)
    np.testing.assert_allclose(R_hat, R, atol=1e-10)
    np.testing.assert_allclose(t_hat, t, atol=1e-9)
    assert s == 1.0


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_kabsch_recovers_a_random_rigid_transform_exactly(d, seed):
    rng = np.random.default_rng(seed)
    R = Rotation.random(random_state=seed).as_matrix() if d == 3 else rot_z(rng.uniform(-np.pi, np.pi))[:2, :2]
    t = rng.normal(0, 100, d)
    src = rng.normal(0, 40, (25, d))
    R_est, t_est = rigid_fit(src, src @ R.T + t)
    np.testing.assert_allclose(R_est, R, atol=1e-12)
    np.testing.assert_allclose(t_est, t, atol=1e-10)
    assert np.linalg.det(R_est) == pytest.approx(1.0, abs=1e-12)


def test_umeyama_recovers_a_known_similarity_and_weights_are_relative():
    rng = np.random.default_rng(7)
    R = Rotation.random(random_state=7).as_matrix()
    src = rng.normal(0, 10, (30, 3))
    dst = 2.5 * src @ R.T + [1.0, -2.0, 3.0]
    R_est, t_est, s = umeyama(src, dst, with_scale=True)
    assert s == pytest.approx(2.5, rel=1e-12)
    np.testing.assert_allclose(R_est, R, atol=1e-12)
    np.testing.assert_allclose(t_est, [1.0, -2.0, 3.0], atol=1e-10)
    # Weights count only relative to each other: w and 7 w give the same fit.
    w = rng.uniform(0.1, 1.0, 30)
    noisy = dst + rng.normal(0, 0.5, dst.shape)
    a, b = umeyama(src, noisy, w, with_scale=True), umeyama(src, noisy, 7 * w, with_scale=True)
    for x, y in zip(a, b):
        np.testing.assert_allclose(x, y, atol=1e-12)


def test_rigid_fit_2d_information_is_the_generalised_least_squares_optimum():
    """:func:`rigid_fit_2d_information` minimises ``sum_i r_i^T I_i r_i``: against scipy's
    least squares on the whitened residuals (``L_i^T r_i``, ``I_i = L_i L_i^T``), for 3 x 3 points
    each with its own information (anisotropic, rotated); with identity information it is the
    equal-weight rigid fit. And what it is for: points whose x is 60x noisier than their y (a grain
    along x), given that, recover the rotation several times better than the equal-weight fit."""
    from scipy.optimize import least_squares

    rng = np.random.default_rng(11)
    g = (np.arange(3) - 1.0) * 128.0
    src = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2) + [5.0, -3.0]
    dst = src @ rot_z(0.004)[:2, :2].T + [-30.0, 2.0] + rng.normal(0.0, 0.5, src.shape)
    info = []
    for _ in src:
        a = rng.uniform(0.0, np.pi)
        U = rot_z(a)[:2, :2]
        info.append(U @ np.diag(rng.uniform(0.05, 2.0, 2)) @ U.T)
    info = np.array(info)
    R, t = rigid_fit_2d_information(src, dst, info)
    L = np.linalg.cholesky(info)

    def whitened(p):
        r = src @ rot_z(p[0])[:2, :2].T + p[1:] - dst
        return np.einsum("nji,nj->ni", L, r).ravel()

    ref = least_squares(whitened, [0.0, 0.0, 0.0], xtol=1e-14, ftol=1e-14, gtol=1e-14).x
    assert np.arctan2(R[1, 0], R[0, 0]) == pytest.approx(ref[0], abs=1e-10)
    np.testing.assert_allclose(t, ref[1:], atol=1e-8)
    R_eq, t_eq, _ = similarity_fit_2d(src, dst, with_scale=False)
    R_id, t_id = rigid_fit_2d_information(src, dst, np.tile(np.eye(2), (len(src), 1, 1)))
    np.testing.assert_allclose(R_id, R_eq, atol=1e-14)
    np.testing.assert_allclose(t_id, t_eq, atol=1e-10)
    # x 3 px noisy, y 0.05 px: the information says so.
    errs: dict[str, list[float]] = {"equal": [], "information": []}
    grain = np.tile(np.diag([1.0 / 3.0**2, 1.0 / 0.05**2]), (len(src), 1, 1))
    for _ in range(50):
        noisy = src @ rot_z(0.004)[:2, :2].T + [-30.0, 2.0] + rng.normal(0.0, 1.0, src.shape) * [3.0, 0.05]
        R_eq, _, _ = similarity_fit_2d(src, noisy, with_scale=False)
        R_in, _ = rigid_fit_2d_information(src, noisy, grain)
        errs["equal"].append(np.arctan2(R_eq[1, 0], R_eq[0, 0]) - 0.004)
        errs["information"].append(np.arctan2(R_in[1, 0], R_in[0, 0]) - 0.004)
    rms = {k: float(np.sqrt(np.mean(np.square(v)))) for k, v in errs.items()}
    assert rms["information"] < 0.2 * rms["equal"], rms


def test_similarity_fit_2d_is_umeyamas_fit():
    """The 2-D closed form (phase-corr's block fits) gives :func:`umeyama`'s similarity to rounding:
    four noisy points at a small and at a half turn, a reflected point set (Umeyama's
    reflection check picks the best rotation there too), and exact data."""
    rng = np.random.default_rng(3)
    src = np.array([[-48.0, -48.0], [48.0, -48.0], [-48.0, 48.0], [48.0, 48.0]]) + [5.0, -7.0]
    for angle, scale in ((0.02, 1.003), (np.pi - 0.1, 0.8)):
        dst = scale * src @ rot_z(angle)[:2, :2].T + [2.5, -1.5] + rng.normal(0, 0.3, src.shape)
        for a, b in zip(similarity_fit_2d(src, dst), umeyama(src, dst, with_scale=True)):
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)
    mirrored = src * [-1.0, 1.0] + rng.normal(0, 0.3, src.shape)
    for a, b in zip(similarity_fit_2d(src, mirrored), umeyama(src, mirrored, with_scale=True)):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)
    R, t, s = similarity_fit_2d(src, 2.0 * src @ rot_z(0.3)[:2, :2].T + [1.0, 2.0])
    np.testing.assert_allclose(R, rot_z(0.3)[:2, :2], atol=1e-15)
    np.testing.assert_allclose(t, [1.0, 2.0], atol=1e-13)
    assert s == pytest.approx(2.0, rel=1e-14)


def test_nearest_rotation_2d_is_the_svds_and_keeps_a_rotation():
    """The closed form gives the ``U V^T`` of the SVD for rotations seen through unequal focal
    lengths (``D^-1 R D``, what pixel_rigid_to_floor re-orthonormalises) and for a noisy
    rotation; a rotation is its own nearest; hand-worked: a quarter turn scaled by 3 along x."""
    rng = np.random.default_rng(5)
    for _ in range(200):
        R = rot_z(rng.uniform(-np.pi, np.pi))[:2, :2]
        D = rng.uniform(0.5, 2.0, 2)
        for M in ((R * D[None, :]) / D[:, None], R + rng.normal(0.0, 0.05, (2, 2))):
            U, _, Vt = np.linalg.svd(M)
            np.testing.assert_allclose(nearest_rotation_2d(M), U @ Vt, rtol=0, atol=1e-14)
        np.testing.assert_allclose(nearest_rotation_2d(R), R, rtol=0, atol=1e-15)
    # [[0, -1], [3, 0]]: a + d = 0, c - b = 4: theta = atan2(4, 0), a quarter turn.
    np.testing.assert_allclose(nearest_rotation_2d(np.array([[0.0, -1.0], [3.0, 0.0]])), [[0, -1], [1, 0]], atol=1e-16)


def test_kabsch_hand_computed_on_two_points():
    """(0, 0) -> (1, 1) and (2, 0) -> (1, 3), worked by hand: a quarter turn, then a shift by (1, 1)."""
    src = np.array([[0.0, 0.0], [2.0, 0.0]])
    dst = np.array([[1.0, 1.0], [1.0, 3.0]])
    R, t = rigid_fit(src, dst)
    np.testing.assert_allclose(R, [[0.0, -1.0], [1.0, 0.0]], atol=1e-15)
    np.testing.assert_allclose(t, [1.0, 1.0], atol=1e-15)


def test_rigid_fit_refuses_bad_shapes_and_weights_by_name():
    with pytest.raises(ValueError, match=r"\(N, 2\) arrays with N >= 2"):
        rigid_fit(np.zeros((1, 2)), np.zeros((1, 2)))
    with pytest.raises(ValueError, match="rigid fit"):
        rigid_fit(np.zeros((5, 2)), np.zeros((4, 2)))
    with pytest.raises(ValueError, match="weights"):
        rigid_fit(np.ones((3, 2)), np.ones((3, 2)), weights=[1.0, -1.0, 1.0])


# ----------------------------------------------------------------------------- inverse
def test_invert_T_single_and_batched_are_exact_inverses():
    rng = np.random.default_rng(3)
    T = np.stack([make_T(Rotation.random(random_state=i).as_matrix(), rng.normal(0, 50, 3)) for i in range(6)])
    stack = T.reshape(2, 3, 4, 4)
    inv = invert_T(stack)
    assert inv.shape == (2, 3, 4, 4)
    np.testing.assert_allclose(inv @ stack, np.broadcast_to(np.eye(4), (2, 3, 4, 4)), atol=1e-12)
    np.testing.assert_allclose(inv.reshape(6, 4, 4), np.linalg.inv(T), atol=1e-12)
    np.testing.assert_array_equal(invert_T(T[2]), inv.reshape(6, 4, 4)[2])
    # Hand computation: a quarter turn about z and a shift; the inverse turns back and shifts back.
    Q = make_T(rot_z(np.pi / 2), [1.0, 2.0, 3.0])
    np.testing.assert_allclose(invert_T(Q), make_T(rot_z(-np.pi / 2), [-2.0, 1.0, -3.0]), atol=1e-15)
    with pytest.raises(ValueError, match="4, 4"):
        invert_T(np.eye(3))


# ----------------------------------------------------------------------------- pixels <-> floor
def test_pixels_to_floor_hand_computed_and_round_trip():
    cam = CameraModel.from_sensor()  # 648 x 494, f = 6 mm / 7.4 um, centre (323.5, 246.5)
    g = cam.gsd_mm_per_px(100.0)  # eq. (1) of paper 000
    uv = np.array([[323.5, 246.5], [333.5, 246.5], [323.5, 226.5]])
    np.testing.assert_allclose(pixels_to_floor_mm(uv, cam, 100.0), [[0, 0], [10 * g, 0], [0, -20 * g]], atol=1e-12)
    dist = CameraModel(640, 480, 800.0, 820.0, 320.0, 240.0, (-0.1, 0.02, 0.001, -0.001, 0.0))
    xy = np.array([[5.0, -3.0], [-20.0, 15.0]])
    np.testing.assert_allclose(pixels_to_floor_mm(floor_mm_to_pixels(xy, dist, 100.0), dist, 100.0), xy, atol=1e-4)


@pytest.mark.parametrize("centred", [False, True])
def test_pixel_rigid_to_floor_agrees_with_converting_the_points(centred):
    """A rigid map of pixels becomes the rigid map of the same floor points (non-square pixels too)."""
    cam = CameraModel(400, 300, 500.0, 500.0 if centred else 520.0, 190.0, 160.0)
    rng = np.random.default_rng(9)
    # A floor motion q_b = R2 q_a + t2 (mm) seen in pixels.
    R2, t2 = rot_z(0.2)[:2, :2], np.array([3.0, -1.5])
    q_a = rng.uniform(-20, 20, (10, 2))
    p_a, p_b = floor_mm_to_pixels(q_a, cam, 100.0), floor_mm_to_pixels(q_a @ R2.T + t2, cam, 100.0)
    c = np.array([cam.cx_px, cam.cy_px])
    R_px, t_px = rigid_fit(p_a - c, p_b - c) if centred else rigid_fit(p_a, p_b)
    if cam.fx_px != cam.fy_px:  # pixels are not square: the image motion is not rigid, fit it as affine
        A = np.linalg.lstsq(np.column_stack([p_a, np.ones(10)]), p_b, rcond=None)[0].T
        R_px, t_px = A[:, :2], A[:, 2]
    R_est, t_est = pixel_rigid_to_floor(R_px, t_px, cam, 100.0, centred=centred)
    np.testing.assert_allclose(R_est, R2, atol=1e-9)
    np.testing.assert_allclose(t_est, t2, atol=1e-9)


def test_footprint_of_a_tilted_camera_by_hand():
    """Pitch p tilts the optical axis to (-sin p, 0, -cos p) (R = Rz Rx(roll) Ry(pitch) R_down):
    from 100 mm it meets the floor 100 tan p behind the camera along x; roll r moves it
    100 tan r along y (Rx(r) (0, 0, -1) = (0, sin r, -cos r)); a level camera is over it."""
    T = np.stack(
        [
            T_world_cam_down(10.0, 5.0, 100.0, 0.0, 0.0, 0.03),
            T_world_cam_down(10.0, 5.0, 100.0, 0.0, 0.02, 0.0),
            T_world_cam_down(10.0, 5.0, 98.0, 0.7),
        ]
    )
    F = footprint_T(T, 100.0)
    np.testing.assert_allclose(F[0][:3, 3], [10.0 - 100.0 * np.tan(0.03), 5.0, 100.0], atol=1e-9)
    np.testing.assert_allclose(F[1][:3, 3], [10.0, 5.0 + 100.0 * np.tan(0.02), 100.0], atol=1e-9)
    np.testing.assert_allclose(F[2], T_world_cam_down(10.0, 5.0, 100.0, 0.7), atol=1e-12)
    np.testing.assert_allclose(F[0][:3, :3], T_world_cam_down(0, 0, 1.0)[:3, :3], atol=1e-12)  # level, yaw 0


def test_floor_rigid_to_T_is_the_camera_motion():
    """Camera moving +2 mm along its x and turning 0.1 rad: floor points move the other way in the image."""
    T_prev_cur = make_T(rot_z(0.1), [2.0, 0.0, 0.0])
    T_cur_prev = invert_T(T_prev_cur)
    R2, t2 = T_cur_prev[:2, :2], T_cur_prev[:2, 3]  # q_cur = R2 q_prev + t2
    np.testing.assert_allclose(floor_rigid_to_T(R2, t2), T_prev_cur, atol=1e-15)
    np.testing.assert_array_equal(planar_T(R2, t2)[2:, :], np.eye(4)[2:, :])
    # And through a downward camera's world poses.
    T0, T1 = T_world_cam_down(0.0, 0.0, 100.0), T_world_cam_down(1.0, 2.0, 100.0, 0.3)
    step = invert_T(T0) @ T1
    back = invert_T(step)
    np.testing.assert_allclose(floor_rigid_to_T(back[:2, :2], back[:2, 3]), step, atol=1e-12)


def test_consensus_problem_names_a_thin_consensus_and_a_second_motion():
    rng = np.random.default_rng(0)
    src = rng.uniform(0, 600, (100, 2))
    dst = src + [5.0, 0.0]
    dst[60:] = src[60:] + [-20.0, 7.0]  # the 40 matches left out agree on another translation
    inl = np.arange(100) < 60
    kw = dict(min_fraction=0.2, min_count=6, max_rival_fraction=0.1)
    assert consensus_problem(src, dst, inl, 1.0, **kw) == (
        "two motions: 40 of the 40 other matches agree on a second homography (60 inliers)"
    )
    dst[60:] = rng.uniform(0, 600, (40, 2))  # left out at random: no second motion
    assert consensus_problem(src, dst, inl, 1.0, **kw) == ""
    assert consensus_problem(src, dst, np.arange(100) < 15, 1.0, **kw) == (
        "only 15 % of 100 matches agree with the homography (needs 20 %)"
    )


@pytest.mark.parametrize("with_scale", [False, True])
def test_rigid_fit_precision_matches_the_spread_of_fits_over_noise_draws(with_scale):
    """The standard errors of a 2-D fit, from one draw's residuals, against the spread of the
    fitted angle and of the origin's image over 2000 seeded noise draws (independent truth).

    Twelve points off-centre (the origin is outside their hull: the rotation's error moves
    the origin's image by the lever arm), 0.7 px of Gaussian noise on each axis."""
    rng = np.random.default_rng(5)
    src = rng.uniform(-60.0, 60.0, (12, 2)) + np.array([90.0, -40.0])
    R, t, s = rot_z(0.1)[:2, :2], np.array([30.0, -4.0]), (1.01 if with_scale else 1.0)
    angles, origins, sig_t, sig_a = [], [], [], []
    for _ in range(2000):
        dst = s * src @ R.T + t + rng.normal(0.0, 0.7, src.shape)
        Rf, tf, sf = umeyama(src, dst, with_scale=with_scale)
        angles.append(np.arctan2(Rf[1, 0], Rf[0, 0]))
        origins.append(tf)
        st, sa = rigid_fit_precision(src, dst, Rf, tf, scale=sf)
        sig_t.append(st)
        sig_a.append(sa)
    spread_angle = float(np.std(angles))
    spread_origin = float(np.sqrt(np.sum(np.var(np.array(origins), axis=0))))
    assert np.sqrt(np.mean(np.square(sig_a))) == pytest.approx(spread_angle, rel=0.1)
    assert np.sqrt(np.mean(np.square(sig_t))) == pytest.approx(spread_origin, rel=0.1)
    # The lever arm matters: the origin's error is well above the centroid's alone.
    assert spread_origin > 1.5 * np.sqrt(2 * 0.7**2 / 12)


def test_rigid_fit_precision_exact_pairs_and_bad_input():
    src = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]])
    R, t = rot_z(0.2)[:2, :2], np.array([1.0, 2.0])
    assert rigid_fit_precision(src, src @ R.T + t, R, t) == pytest.approx((0.0, 0.0), abs=1e-12)
    with pytest.raises(ValueError, match="N >= 3"):
        rigid_fit_precision(src[:2], src[:2], R, t)
    # All points at one place: the angle is not observed.
    same = np.zeros((4, 2))
    assert rigid_fit_precision(same, same, np.eye(2), np.zeros(2)) == (float("inf"), float("inf"))


@pytest.mark.parametrize("overlap", [1, 4])
def test_plane_fit_precision_matches_the_spread_of_fits_over_noise_draws(overlap):
    """The plane's standard errors (height at the camera, tilt), from one draw's residuals,
    against the spread of :func:`fit_plane` over 500 seeded noise draws (independent truth).

    A tilted floor 100 mm away, 160 points off-centre (the camera's foot is 18 mm from their
    centroid: the tilt's error moves the height there by that lever arm), 0.03 mm of Gaussian
    noise along the normal. ``overlap = 4``: each error is shared by four points (neighbouring
    Lucas-Kanade windows on the same pixels), so the fit has a quarter of the independent points
    and twice the spread; the residuals alone cannot tell, ``overlap`` says so."""
    rng = np.random.default_rng(7)
    n_true = Rotation.from_euler("xy", [0.03, -0.02]).apply([0.0, 0.0, 1.0])
    Q = np.eye(3)
    Q[:, 2] = n_true
    Q[:, 0] = np.cross([0.0, 1.0, 0.0], n_true)
    Q[:, 0] /= np.linalg.norm(Q[:, 0])
    Q[:, 1] = np.cross(n_true, Q[:, 0])
    # 160 points in groups of ``overlap`` neighbours (within 0.5 mm)
    q = np.repeat(rng.uniform(-15.0, 15.0, (160 // overlap, 2)), overlap, axis=0) + rng.uniform(-0.5, 0.5, (160, 2))
    base = np.column_stack([q + np.array([15.0, -10.0]), np.full(160, 100.0)]) @ Q.T  # on n . p = 100
    heights, tilts, sig_h, sig_t = [], [], [], []
    for _ in range(500):
        e = np.repeat(rng.normal(0.0, 0.03, 160 // overlap), overlap)
        P = base + e[:, None] * n_true
        n, d, keep = fit_plane(P)
        heights.append(d)
        tilts.append(np.arccos(min(1.0, float(n @ n_true))))
        sh, st = plane_fit_precision(P[keep], n, d, overlap=overlap)
        sig_h.append(sh)
        sig_t.append(st)
    spread_h = float(np.std(heights))
    spread_t = float(np.sqrt(np.mean(np.square(tilts))))
    assert np.sqrt(np.mean(np.square(sig_h))) == pytest.approx(spread_h, rel=0.15)
    assert np.sqrt(np.mean(np.square(sig_t))) == pytest.approx(spread_t, rel=0.15)
    # The lever arm matters: the height's error is well above the centroid's alone.
    assert spread_h > 1.5 * 0.03 / np.sqrt(160 / overlap)


def test_plane_fit_precision_exact_points_and_too_few():
    P = np.array([[0.0, 0.0, 50.0], [10.0, 0.0, 50.0], [0.0, 10.0, 50.0], [10.0, 10.0, 50.0]])
    assert plane_fit_precision(P, np.array([0.0, 0.0, 1.0]), 50.0) == pytest.approx((0.0, 0.0), abs=1e-12)
    assert plane_fit_precision(P[:3], np.array([0.0, 0.0, 1.0]), 50.0) == (float("inf"), float("inf"))
    line = np.column_stack([np.arange(5.0), np.zeros(5), np.full(5, 50.0)])  # the tilt across it is not observed
    assert plane_fit_precision(line, np.array([0.0, 0.0, 1.0]), 50.0) == (float("inf"), float("inf"))


def test_axis_scales_fit_exact_on_a_hand_built_small_motion_and_refuses_bad_input():
    """Four block centres of phase-corr's 2 x 2 grid (+-96 px) shifted by a picture scaled
    1.004 along x and 0.992 along y, turned 2 mrad and moved (3, -1) px, to first order in
    the small rotation: d = diag(0.004, -0.008) p + 0.002 (-p_y, p_x) + t. The fit returns
    the two scales; the shifts fit exactly, so their standard errors are 0."""
    p = np.array([[-96.0, -96.0], [96.0, -96.0], [-96.0, 96.0], [96.0, 96.0]])
    d = p * [0.004, -0.008] + 0.002 * np.stack([-p[:, 1], p[:, 0]], axis=1) + [3.0, -1.0]
    scales, sigmas = axis_scales_fit(p, d)
    assert scales == pytest.approx([1.004, 0.992], abs=1e-12)
    assert sigmas == pytest.approx([0.0, 0.0], abs=1e-9)
    # The design made once for the points (what phase-corr keeps for its blocks): the same numbers.
    for a, b in zip(axis_scales_fit(p, d, axis_scales_design(p)), (scales, sigmas)):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match="N >= 3"):
        axis_scales_fit(p[:2], d[:2])
    with pytest.raises(ValueError, match="both axes"):
        axis_scales_fit(np.array([[0.0, 0.0], [10.0, 0.0], [20.0, 0.0]]), np.zeros((3, 2)))


def test_axis_scales_fit_standard_errors_match_the_spread_over_noise_draws():
    """The standard errors from one draw's residuals against the spread of the fitted scales
    over 2000 seeded draws of 0.1 px Gaussian noise on 16 points (a 4 x 4 grid): independent truth."""
    rng = np.random.default_rng(11)
    g = (np.arange(4) - 1.5) * 64.0
    p = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
    fits, sigmas = [], []
    for _ in range(2000):
        d = p * [0.01, 0.01] + [2.0, 0.5] + rng.normal(0.0, 0.1, p.shape)
        s, sig = axis_scales_fit(p, d)
        fits.append(s)
        sigmas.append(sig)
    assert np.mean(fits, axis=0) == pytest.approx([1.01, 1.01], abs=2e-4)
    np.testing.assert_allclose(np.sqrt(np.mean(np.square(sigmas), axis=0)), np.std(fits, axis=0), rtol=0.1)


def test_rival_search_draws_the_samples_that_find_a_rival_of_half_the_others(monkeypatch):
    """The two-motions check counts a rival backed by half of the left-out matches or more;
    RANSAC draws the samples that find one with 99.5 % confidence (Fischler and Bolles:
    log(0.005) / log(1 - 0.5^4) = 83), not a fixed 1000 (14 ms of orb-icp's frame on random
    matches, where no consensus ends RANSAC early). A rival backed by 55 % of 40 left-out
    matches is found on every one of 20 seeds."""
    import cv2

    calls = []
    real = cv2.findHomography

    def spy(*args, **kwargs):
        calls.append(kwargs.get("maxIters"))
        return real(*args, **kwargs)

    monkeypatch.setattr(cv2, "findHomography", spy)
    rng = np.random.default_rng(2)
    n_in, n_out, n_rival = 100, 40, 22
    src = rng.uniform(0, 600, (n_in + n_out, 2))
    dst = src + np.array([30.0, 0.0])
    dst[n_in:] = rng.uniform(0, 600, (n_out, 2))  # random matches ...
    dst[n_in : n_in + n_rival] = src[n_in : n_in + n_rival] + np.array([-12.0, 7.0])  # ... 22 on a second motion
    inliers = np.arange(n_in + n_out) < n_in
    for seed in range(20):
        assert rival_homography_support(src, dst, inliers, 2.0, seed=seed) >= n_rival
    assert set(calls) == {int(np.ceil(np.log(0.005) / np.log(1 - 0.5**4)))} == {83}
    # consensus_problem (the check every feature estimator runs) reports it.
    why = consensus_problem(src, dst, inliers, 2.0, min_fraction=0.2, min_count=8, max_rival_fraction=0.1)
    assert why.startswith("two motions: ")


def test_t_sigmas_keeps_the_normal_tail_for_an_estimated_standard_error():
    """Student's t: the two-sided tail beyond t_sigmas(k, dof) estimated standard errors is the
    normal one beyond k (0.27 % for 3), by the t distribution's CDF; the figures the docstring
    gives (9.2 at 3 degrees of freedom, 6.6 at 4) and the normal limit for many."""
    from scipy import stats

    from floorvo.geometry import t_sigmas

    for dof in (1, 3, 4, 12, 200):
        assert 2 * stats.t.sf(t_sigmas(3.0, dof), dof) == pytest.approx(2 * stats.norm.sf(3.0), rel=1e-9)
    assert t_sigmas(3.0, 3) == pytest.approx(9.219, abs=1e-3)
    assert t_sigmas(3.0, 4) == pytest.approx(6.620, abs=1e-3)
    assert t_sigmas(3.0, 100000) == pytest.approx(3.0, abs=1e-3)
    assert t_sigmas(0.0, 4) == 0.0 and t_sigmas(3.0, 0) == float("inf")


def test_f_sigmas_keeps_the_normal_tail_for_a_ratio_of_variance_estimates():
    """F distribution: the tail beyond f_sigmas(k, n, m) is the normal two-sided one beyond k
    (0.27 % for 3), by the F distribution's survival function; for one measurement it is t_sigmas
    squared (the same test on one frame), and for many degrees of freedom both ways it tends to 1."""
    from scipy import stats

    from floorvo.geometry import f_sigmas, t_sigmas

    for n, m in ((1, 3), (8, 24), (3, 600), (40, 120)):
        assert stats.f.sf(f_sigmas(3.0, n, m), n, m) == pytest.approx(2 * stats.norm.sf(3.0), rel=1e-9)
    assert f_sigmas(3.0, 1, 3) == pytest.approx(t_sigmas(3.0, 3) ** 2, rel=1e-9)
    assert f_sigmas(3.0, 8, 24) == pytest.approx(4.257, abs=1e-3)
    assert f_sigmas(3.0, 100000, 100000) == pytest.approx(1.0, abs=0.05)
    assert f_sigmas(0.0, 8, 24) == 0.0 and f_sigmas(3.0, 8, 0) == float("inf")


@pytest.mark.parametrize(
    "a0, a1",
    [
        ((0.0, 0.0), (0.01, 0.0)),
        ((0.0, 0.0), (0.0, -0.02)),
        ((0.03, 0.0), (0.0, 0.03)),
        ((0.02, -0.01), (-0.015, 0.025)),
    ],
)
def test_tilt_change_is_the_angle_between_the_two_optical_axes(a0, a1):
    """The optical axes of the two poses in the world (the third column of each rotation of
    ``T_world_cam_down`` at those roll and pitch, the same yaw), their angle by the dot product."""
    z0 = T_world_cam_down(0.0, 0.0, 100.0, 0.0, *a0)[:3, 2]
    z1 = T_world_cam_down(5.0, 1.0, 99.0, 0.0, *a1)[:3, 2]
    expected = float(np.arccos(np.clip(z0 @ z1, -1.0, 1.0)))
    assert tilt_change_rad(a0, a1) == pytest.approx(expected, abs=1e-9)
    assert tilt_change_rad(a1, a0) == pytest.approx(expected, abs=1e-9)
    assert tilt_change_rad(a0, a0) == pytest.approx(0.0, abs=1e-12)

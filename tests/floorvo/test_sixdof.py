"""6-DoF steps from the floor plane (issue 14 item 4): the geometry against hand-made poses,
the tilted synthetic views against ray casting, and orb-icp / stereo-sift on a bouncing,
tilting synthetic run scored against its ground truth."""

from __future__ import annotations

import numpy as np
import pytest
from _synth import disturbed_poses
from scipy.spatial.transform import Rotation

from floorvo.camera import CameraModel
from floorvo.geometry import (
    T_world_cam_down,
    fit_plane,
    floor_plane_step,
    invert_T,
    least_rotation,
    level_rotation,
    plane_homography_motion,
    plane_step_T,
    rays_to_plane,
)
from floorvo.metrics import reason_kind, step_errors, wrong_steps
from floorvo.run import run_estimator
from floorvo.synthetic import floor_depth, floor_texture, render_view, write_synthetic_sequence

CAM = CameraModel.from_sensor(324, 247, pixel_pitch_um=14.8, focal_length_mm=6.0)


def _plane_of(T_world_cam: np.ndarray) -> tuple[np.ndarray, float]:
    """The floor z = 0 in the camera frame: normal = world -z seen from the camera, d = camera height."""
    return invert_T(T_world_cam)[:3, :3] @ np.array([0.0, 0.0, -1.0]), float(T_world_cam[2, 3])


def _floor_points(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(-12, 15, n), rng.uniform(-9, 9, n), np.zeros(n)])


def _in_cam(T_world_cam: np.ndarray, X_world: np.ndarray) -> np.ndarray:
    return (invert_T(T_world_cam) @ np.column_stack([X_world, np.ones(len(X_world))]).T).T[:, :3]


T_A = T_world_cam_down(0.0, 0.0, 100.5, 0.1, 0.02, -0.01)
T_B = T_world_cam_down(3.0, 1.0, 98.7, 0.13, -0.015, 0.012)


def test_fit_plane_recovers_a_tilted_floor_through_noise_and_outliers():
    P = _in_cam(T_A, _floor_points(2000, 0))
    rng = np.random.default_rng(1)
    P = P + rng.normal(0.0, 0.05, P.shape)
    P[:100] += [0.0, 0.0, 5.0]  # 5 % of the points 5 mm off the plane (dirt, a bad depth)
    n, d, inl = fit_plane(P)
    n_true, d_true = _plane_of(T_A)
    assert np.arccos(min(1.0, float(n @ n_true))) < 2e-4  # rad
    assert d == pytest.approx(d_true, abs=0.01)
    assert not inl[:100].any() and inl[100:].mean() > 0.95
    with pytest.raises(ValueError, match="at least 3 finite"):
        fit_plane(np.full((5, 3), np.nan))


def test_level_rotation_takes_the_normal_to_z_by_the_least_rotation():
    n = np.array([0.03, -0.02, 1.0])
    n /= np.linalg.norm(n)
    Q = level_rotation(n)
    np.testing.assert_allclose(Q @ n, [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(Q @ Q.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(Q) == pytest.approx(1.0)
    # The least rotation turns about an axis in the plane of n and z: the angle is that between them.
    assert np.linalg.norm(Rotation.from_matrix(Q).as_rotvec()) == pytest.approx(np.arccos(n[2]), rel=1e-12)
    np.testing.assert_array_equal(level_rotation(np.array([0.0, 0.0, 1.0])), np.eye(3))
    # the general case, a onto b: and half a turn for opposite vectors
    rng = np.random.default_rng(1)
    for _ in range(5):
        a, b = (v / np.linalg.norm(v) for v in rng.normal(size=(2, 3)))
        Q = least_rotation(a, b)
        np.testing.assert_allclose(Q @ a, b, atol=1e-12)
        assert np.linalg.norm(Rotation.from_matrix(Q).as_rotvec()) == pytest.approx(np.arccos(a @ b), rel=1e-9)
    a = np.array([0.0, 0.6, 0.8])
    Q = least_rotation(a, -a)
    np.testing.assert_allclose(Q @ a, -a, atol=1e-15)
    assert np.linalg.det(Q) == pytest.approx(1.0)


def test_rays_meet_the_plane_at_the_floor_points():
    X = _floor_points(30, 2)
    P = _in_cam(T_A, X)
    np.testing.assert_allclose(rays_to_plane(CAM.project(P), CAM, *_plane_of(T_A)), P, atol=1e-9)


def test_floor_plane_step_gives_the_6dof_step_from_planes_and_pixels():
    """A step with bounce (-1.8 mm), roll and pitch changes (0.035, 0.022 rad), yaw and a shift:
    exact from the two planes and the matched pixels, where a planar fit cannot see the tilt."""
    X = _floor_points(60, 3)
    uv_a, uv_b = CAM.project(_in_cam(T_A, X)), CAM.project(_in_cam(T_B, X))
    T, keep, rms = floor_plane_step(uv_a, uv_b, CAM, _plane_of(T_A), _plane_of(T_B))
    np.testing.assert_allclose(T, invert_T(T_A) @ T_B, atol=1e-12)
    assert keep.all() and rms < 1e-12
    # plane_step_T with a level pair is the planar step (yaw, shift) plus the height change.
    ez = np.array([0.0, 0.0, 1.0])
    c, s = np.cos(0.1), np.sin(0.1)
    T_level = plane_step_T(ez, 100.0, ez, 98.0, np.array([[c, -s], [s, c]]), np.array([1.0, 2.0]))
    T_want = np.eye(4)
    T_want[:3, :3] = Rotation.from_rotvec([0, 0, 0.1]).as_matrix()
    T_want[:3, 3] = [1.0, 2.0, -2.0]
    np.testing.assert_allclose(T_level, invert_T(T_want), atol=1e-15)


def test_plane_homography_motion_decomposes_with_the_known_normal():
    """H ~ R + t n^T / d (any scale, either sign): the step and the new plane come back exactly."""
    T_ba = invert_T(invert_T(T_A) @ T_B)
    n, d = _plane_of(T_A)
    for scale in (3.7, -0.2):
        H = scale * (T_ba[:3, :3] + np.outer(T_ba[:3, 3], n) / d)
        T, n_cur, d_cur = plane_homography_motion(H, n, d)
        np.testing.assert_allclose(T, invert_T(T_A) @ T_B, atol=1e-12)
        n_b, d_b = _plane_of(T_B)
        np.testing.assert_allclose(n_cur, n_b, atol=1e-14)
        assert d_cur == pytest.approx(d_b, abs=1e-10)


def test_plane_homography_motion_without_tilt_keeps_the_plane_and_measures_yaw_shift_height():
    """``tilt=False``: a step that keeps the plane's tilt (yaw about the normal, a shift, a height
    change) comes back exactly; a homography with a tilt change gives the step without it: the
    same plane normal, the rotation about it, the same height change."""
    n, d = _plane_of(T_A)
    R_yaw = Rotation.from_rotvec(0.07 * n).as_matrix()
    t = np.array([3.0, -1.0, 0.4])
    T, n_cur, d_cur = plane_homography_motion(2.5 * (R_yaw + np.outer(t, n) / d), n, d, tilt=False)
    T_want = invert_T(np.block([[R_yaw, t[:, None]], [np.zeros((1, 3)), np.ones((1, 1))]]))
    np.testing.assert_allclose(T, T_want, atol=1e-12)
    np.testing.assert_allclose(n_cur, n, atol=1e-14)
    R_tilted = Rotation.from_rotvec(0.07 * n + np.cross(n, [1.0, 0.0, 0.0]) * 0.004).as_matrix()
    H = R_tilted + np.outer(t, n) / d
    T_full, n_full, d_full = plane_homography_motion(H, n, d)
    T_level, n_level, d_level = plane_homography_motion(H, n, d, tilt=False)
    assert np.arccos(min(1.0, float(n_full @ n))) > 3e-3  # the full decomposition sees the tilt
    np.testing.assert_allclose(n_level, n, atol=1e-14)
    R = T_level[:3, :3]
    np.testing.assert_allclose(R @ n, n, atol=1e-14)  # a rotation about the normal: the yaw
    assert np.linalg.norm(Rotation.from_matrix(R).as_rotvec()) == pytest.approx(0.07, abs=2e-4)
    assert d_level == pytest.approx(d_full, abs=0.05)


def test_tilted_synthetic_view_and_depth_are_those_of_the_ray_cast_floor():
    from scipy.ndimage import spline_filter

    gsd = CAM.gsd_mm_per_px(100.0)
    tex = floor_texture(700, 700, 0)
    coeffs = spline_filter(tex, order=3, output=np.float32)
    origin = (350.0, 350.0)
    T = T_world_cam_down(1.0, -2.0, 99.0, 0.2, 0.03, -0.02)
    X = _floor_points(20, 4) * 0.8
    P = _in_cam(T, X)
    uv = CAM.project(P)
    depth = floor_depth(CAM, T)
    iu, iv = np.round(uv).astype(int).T
    # Depth at whole pixels: recompute the floor point through each of those pixels.
    P_px = rays_to_plane(np.column_stack([iu, iv]).astype(float), CAM, *_plane_of(T))
    np.testing.assert_allclose(depth[iv, iu], P_px[:, 2], rtol=1e-6)
    assert depth.min() < 99.0 - 1.0 < 99.0 + 1.0 < depth.max()  # the tilt makes one side nearer
    img = render_view(coeffs, origin, gsd, CAM, T)
    Xp = (T @ np.column_stack([P_px, np.ones(len(P_px))]).T).T
    U, V = Xp[:, 0] / gsd + origin[0], -Xp[:, 1] / gsd + origin[1]
    from scipy.ndimage import map_coordinates

    want = map_coordinates(coeffs, [V, U], order=3, prefilter=False, mode="mirror")
    np.testing.assert_allclose(img[iv, iu], want, atol=1e-5)
    # A level pose keeps the exact affine path.
    np.testing.assert_array_equal(floor_depth(CAM, T_world_cam_down(0, 0, 80.0)), np.float32(80.0))


@pytest.fixture(scope="module")
def disturbed_seq(tmp_path_factory):
    poses = disturbed_poses()
    root = tmp_path_factory.mktemp("sixdof") / "seq"
    write_synthetic_sequence(root, CAM, poses, depth=True, depth_noise_mm=0.3, stereo_baseline_mm=20.0)
    return root, poses


@pytest.mark.parametrize(
    "name, update, old",
    [("orb-icp", "plane", "icp"), ("stereo-sift", "plane", "planar")],
)
def test_6dof_update_holds_every_step_to_the_issue_bound_on_a_bouncing_tilting_run(
    disturbed_seq, tmp_path, name, update, old
):
    """Issue 14's bound (0.05 mm + 2 % of the step, 0.3 deg) on every step, against the true
    6-DoF step, with 0.3 mm of depth noise per pixel. The old updates miss it: orb-icp's ICP on
    the matched points lets the depth noise tilt its fit; stereo-sift's planar fit cannot see
    the tilt (0.94 mm a step)."""
    seq, poses = disturbed_seq
    run = run_estimator(seq, name, tmp_path / update, {"update": update})
    assert list(run.status[1:]) == ["ok"] * (len(poses) - 1)
    e = step_errors(poses, run.T_world_cam)
    assert not wrong_steps(e).any(), e
    assert np.all(e["rot_deg"] < np.degrees(1e-3)), e["rot_deg"]  # the tilt change (up to 0.0094 rad) is measured
    assert np.linalg.norm(run.T_world_cam[-1][:3, 3] - poses[-1][:3, 3]) < 0.2  # mm over 36 mm
    old_run = run_estimator(seq, name, tmp_path / old, {"update": old})
    assert wrong_steps(step_errors(poses, old_run.T_world_cam)).any()


def test_local_contrast_image_cancels_a_smooth_brightness_change():
    """Two views of one texture under different smooth illumination (a factor from 0.3 to 1.7
    across the frame) give nearly the same local-contrast image, where the plain ones differ."""
    from floorvo.imaging import local_contrast_uint8

    tex = floor_texture(200, 300, 5) * 200.0
    ramp = np.linspace(0.3, 1.7, 300, dtype=np.float32)[None, :] * np.ones((200, 1), np.float32)
    a, b = local_contrast_uint8(tex), local_contrast_uint8(tex * ramp)
    inner = (slice(20, -20), slice(20, -20))
    assert np.median(np.abs(a[inner].astype(int) - b[inner].astype(int))) <= 2
    assert np.median(np.abs(tex - tex * ramp)) > 10


@pytest.fixture(scope="module")
def tilted_mono_seq(tmp_path_factory):
    poses = disturbed_poses()
    root = tmp_path_factory.mktemp("homography") / "seq"
    write_synthetic_sequence(root, CAM, poses)
    return root, poses


def test_homography_6dof_measures_tilt_and_height_from_a_mono_camera(tilted_mono_seq, tmp_path):
    """The floor homography's perspective terms carry the tilt change (up to 9.4 mrad a step
    here): every step within issue 14's bound against the true 6-DoF step and the tilt change
    measured to 1 mrad, where the planar akaze-guided (same matching) gets every step wrong."""
    seq, poses = tilted_mono_seq
    run = run_estimator(seq, "homography-6dof", tmp_path / "h")
    assert list(run.status[1:]) == ["ok"] * (len(poses) - 1)
    e = step_errors(poses, run.T_world_cam)
    assert not wrong_steps(e).any(), e
    A = invert_T(poses[:-1]) @ poses[1:]
    B = invert_T(run.T_world_cam[:-1]) @ run.T_world_cam[1:]
    tilt_err = np.arccos(np.clip(np.einsum("ni,ni->n", A[:, :3, 2], B[:, :3, 2]), -1.0, 1.0))
    assert np.all(tilt_err < 1e-3), tilt_err
    planar = run_estimator(seq, "akaze-guided", tmp_path / "p")
    assert wrong_steps(step_errors(poses, planar.T_world_cam)).all()


def test_homography_6dof_reports_an_implausible_plane_lost_with_the_reason(tilted_mono_seq, tmp_path):
    seq, poses = tilted_mono_seq
    run = run_estimator(seq, "homography-6dof", tmp_path / "h", {"max_tilt_rad": "0.005"})
    assert list(run.status[1:]) == ["lost"] * (len(poses) - 1)
    assert all("floor plane tilted" in r and "rad from the optical axis > 0.005" in r for r in run.reason[1:])


def test_homography_6dof_reports_a_tilt_it_cannot_resolve_lost_not_wrong(tmp_path):
    """A quarter-size camera (162x123 px) sees too little of the floor to resolve a tilt from
    the homography's perspective terms: its fit turns the keypoints' noise into a tilt, and a
    tilt at 100 mm into a shift of a millimetre (before the blocks' agreement check, 10 of the
    10 steps of this straight, level run were reported ok, and wrong). Every step is now ok
    within issue 14's bound or lost with the reason; at half size (324x247) the same run is
    tracked, every step ok."""
    from floorvo.scoring import ok_step_errors
    from floorvo.synthetic import line_poses

    poses = line_poses(40.0, 4.0)
    runs = {}
    for scale in (0.25, 0.5):
        seq = tmp_path / f"seq{scale}"
        write_synthetic_sequence(seq, CameraModel.from_sensor().scaled(scale), poses, noise_dn=3.0, seed=3)
        run = runs[scale] = run_estimator(seq, "homography-6dof", tmp_path / f"run{scale}")
        e = ok_step_errors(run.status, run.reason, poses, run.T_world_cam)
        assert e is None or not wrong_steps(e).any(), e
        assert all(r for s, r in zip(run.status[1:], run.reason[1:]) if s == "lost")
    assert list(runs[0.5].status[1:]) == ["ok"] * (len(poses) - 1), runs[0.5].reason
    assert any(r.startswith("imprecise homography: 4 blocks of its pairs disagree") for r in runs[0.25].reason)
    assert any(reason_kind(r) == "imprecise homography" for r in runs[0.25].reason)


def test_homography_6dof_refuses_a_tilt_under_the_rigs_own_lights(tmp_path):
    """A rig whose grazing LEDs ride with the camera (the sequence records them, as every render
    does) tilts them with it: the shading then moves as much as the homography's perspective
    terms, and on the full-size tilt render the tilt read from them was 0.1-0.3 of the tilt
    change off (6 steps reported ok and wrong before this check). Level steps stay ok; each step
    whose tilt moves the footprint by more than issue 14's bound (1.3 mrad at 100 mm for a 4 mm
    step) is lost with the reason.
    Without the LEDs in the sequence (a texture warp: nothing moves the shading) the same steps
    are measured, every one ok."""
    import json

    n_level, n = 6, 12
    pitch = [0.0] * n_level + [0.008 * (i - n_level + 1) for i in range(n_level, n)]  # 8 mrad a frame after frame 5
    poses = np.stack([T_world_cam_down(4.0 * i, 0.0, 100.0, 0.0, pitch[i], 0.0) for i in range(n)])
    seq = write_synthetic_sequence(tmp_path / "seq", CAM, poses)
    plain = run_estimator(seq, "homography-6dof", tmp_path / "plain")
    assert list(plain.status[1:]) == ["ok"] * (n - 1), plain.reason
    meta = json.loads((seq / "sequence.json").read_text())
    meta["rig"]["led_positions_cam_mm"] = [[x, y, 97.0] for x in (-70.0, 70.0) for y in (-20.0, 0.0, 20.0)]
    (seq / "sequence.json").write_text(json.dumps(meta))
    lit = run_estimator(seq, "homography-6dof", tmp_path / "lit")
    true_tilt = np.abs(np.diff(pitch))
    for k in range(1, n):
        if true_tilt[k - 1] == 0.0:
            assert lit.status[k] == "ok", (k, lit.reason[k])
        else:
            assert lit.status[k] == "lost" and lit.reason[k].startswith("tilt not observable: the step tilts"), k
    e = step_errors(poses[:n_level], lit.T_world_cam[:n_level])
    assert not wrong_steps(e).any(), e
    off = run_estimator(seq, "homography-6dof", tmp_path / "off", {"rig_lights": "no"})
    assert list(off.status[1:]) == ["ok"] * (n - 1), off.reason

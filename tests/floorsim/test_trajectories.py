"""Scripted trajectories: exact poses against hand computation."""

import numpy as np
import pytest

from floorsim.trajectories import (
    TRAJECTORIES,
    build_trajectory,
    footprint_bounds_mm,
    paper000_subsequences,
)
from floorvo.camera import CameraModel
from floorvo.errors import ConfigError
from floorvo.geometry import se2_from_T


def _se2(traj):
    return np.array([se2_from_T(T) for T in traj.T_world_cam])


def test_uniform_is_paper000_model_I():
    tr = build_trajectory("uniform", {}, height_mm=100.0, fps=30.0)
    assert tr.frame_count == 26  # 100 mm at 4 mm/frame
    xy = _se2(tr)
    np.testing.assert_allclose(np.diff(xy[:, 0]), 4.0, atol=1e-12)
    np.testing.assert_allclose(xy[:, 1:], 0.0, atol=1e-12)
    np.testing.assert_allclose(tr.T_world_cam[:, 2, 3], 100.0)
    assert tr.path_length_mm() == pytest.approx(100.0)


@pytest.mark.parametrize("gain", [1.25, 1.75])
def test_sigmoid_follows_formula(gain):
    tr = build_trajectory("sigmoid", {"gain": gain, "frames": 20}, height_mm=100.0, fps=10.0)
    f = np.arange(20)
    expect = 10.0 / (1 + np.exp(-gain * (f - 9.5)))
    np.testing.assert_allclose(_se2(tr)[:, 0], expect, atol=1e-12)


def test_a_sigmoid_whose_midpoint_lies_far_away_stands_still_without_a_numpy_warning():
    """A midpoint f0 of 1e308 frames overflowed exp(-g (f - f0)) and printed numpy's overflow
    warning; the pose is exact all the same (1 / (1 + inf) = 0): the run stands at its start."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tr = build_trajectory("sigmoid", {"f0": 1e308, "frames": 5}, height_mm=100.0, fps=10.0)
    np.testing.assert_array_equal(_se2(tr)[:, 0], 0.0)


def test_line_paper001():
    tr = build_trajectory("line", {}, height_mm=100.0, fps=30.0)
    assert tr.frame_count == 301  # 3 m at 10 mm/frame
    assert _se2(tr)[-1, 0] == pytest.approx(3000.0)


def test_arc_radius_and_tangent_yaw():
    tr = build_trajectory("arc", {"radius_mm": 100.0, "length_mm": 50.0, "speed_mm_s": 50.0}, height_mm=100.0, fps=20.0)
    s = _se2(tr)
    # All points on the circle of radius 100 centred at (0, 100).
    np.testing.assert_allclose(np.hypot(s[:, 0], s[:, 1] - 100.0), 100.0, atol=1e-9)
    # Yaw = travelled arc / radius.
    np.testing.assert_allclose(s[:, 2], 50.0 * tr.timestamps_s / 100.0, atol=1e-12)


def test_spin_in_place():
    tr = build_trajectory("spin", {"angle_rad": -1.0, "rate_rad_s": 1.0}, height_mm=100.0, fps=10.0)
    s = _se2(tr)
    np.testing.assert_allclose(s[:, :2], 0.0, atol=1e-12)
    assert s[-1, 2] == pytest.approx(-1.0)


def test_s_curve_constant_ground_speed():
    tr = build_trajectory(
        "s_curve", {"length_mm": 200.0, "amplitude_mm": 15.0, "speed_mm_s": 100.0}, height_mm=100.0, fps=50.0
    )
    s = _se2(tr)
    steps = np.linalg.norm(np.diff(s[:, :2], axis=0), axis=1)
    np.testing.assert_allclose(steps, 2.0, rtol=2e-3)


def test_turns_straight_legs_and_right_angle_turns():
    # 3 legs of 40 mm joined by two left turns of 90 degrees on 20 mm radius, at 2 mm/frame.
    p = {"legs": 3, "leg_mm": 40.0, "turn_rad": float(np.pi / 2), "turn_radius_mm": 20.0, "speed_mm_s": 60.0}
    tr = build_trajectory("turns", p, height_mm=100.0, fps=30.0)
    arc = 20.0 * np.pi / 2
    total = 3 * 40.0 + 2 * arc
    assert tr.frame_count == int(np.floor(total / 2.0 + 1e-9)) + 1
    t = np.array([0.0, 40.0, 40.0 + arc / 2, 40.0 + arc, 80.0 + arc, 80.0 + 2 * arc, total]) / 60.0
    s = tr.se2_at(t)
    # By hand: the first leg along +x; the turn's centre (40, 20); the second leg along +y from
    # (60, 20); the second turn's centre (40, 60); the last leg along -x from (40, 80).
    h = np.sqrt(0.5) * 20.0
    expect = [
        [0, 0, 0],
        [40, 0, 0],
        [40 + h, 20 - h, np.pi / 4],
        [60, 20, np.pi / 2],
        [60, 60, np.pi / 2],
        [40, 80, np.pi],
        [0, 80, np.pi],
    ]
    np.testing.assert_allclose(s, expect, atol=1e-9)
    # Constant ground speed: every chord of 2 mm of path, shorter only inside a turn.
    steps = np.linalg.norm(np.diff(_se2(tr)[:, :2], axis=0), axis=1)
    assert np.all(steps <= 2.0 + 1e-9) and np.all(steps >= 2.0 * np.sinc(1 / (20.0 * np.pi)) - 1e-9)
    with pytest.raises(ConfigError, match=r"trajectory.turn_rad = 0.0"):
        build_trajectory("turns", {"turn_rad": 0.0}, height_mm=100.0, fps=30.0)


def test_lawnmower_covers_rectangle():
    tr = build_trajectory(
        "lawnmower", {"width_mm": 100.0, "depth_mm": 60.0, "lane_spacing_mm": 30.0}, height_mm=100.0, fps=30.0
    )
    s = _se2(tr)
    assert s[:, 0].min() == pytest.approx(0.0) and s[:, 0].max() == pytest.approx(100.0, abs=4.0)
    assert set(np.round(s[:, 1], 6)) >= {0.0, 30.0, 60.0}


def test_kidnap_teleports_marked_and_seeded():
    a = build_trajectory("kidnap", {"segments": 3}, height_mm=100.0, fps=30.0, seed=5)
    b = build_trajectory("kidnap", {"segments": 3}, height_mm=100.0, fps=30.0, seed=5)
    c = build_trajectory("kidnap", {"segments": 3}, height_mm=100.0, fps=30.0, seed=6)
    np.testing.assert_array_equal(a.T_world_cam, b.T_world_cam)
    assert not np.allclose(a.T_world_cam, c.T_world_cam)
    tf = a.events["teleport_frames"]
    assert len(tf) == 2
    s = _se2(a)
    steps = np.linalg.norm(np.diff(s[:, :2], axis=0), axis=1)
    within = np.delete(steps, [f - 1 for f in tf])
    np.testing.assert_allclose(within, 4.0, atol=1e-9)  # 120 mm/s at 30 fps
    # Every point stays inside the area.
    assert s[:, 0].min() >= -1e-9 and s[:, 0].max() <= 200 + 1e-9
    # The teleport falls half a frame before its frame: that frame's exposure (or a rolling
    # shutter's early rows) sees its own segment, standing at its start, and the frame before
    # sees its segment moving on (the teleport frame's early rows showed the last segment's floor).
    f, dt = tf[0], 1.0 / 30.0
    np.testing.assert_allclose(a.pose_at(f * dt - 0.4 * dt)[0], a.T_world_cam[f], atol=1e-9)
    before = a.pose_at((f - 1) * dt + 0.4 * dt)[0]
    np.testing.assert_allclose(
        before[:2, 3] - a.T_world_cam[f - 1][:2, 3],
        0.4 * (a.T_world_cam[f - 1] - a.T_world_cam[f - 2])[:2, 3],
        atol=1e-9,
    )


def test_disturbances_change_height_and_tilt_only_as_asked():
    base = build_trajectory("uniform", {}, height_mm=100.0, fps=30.0)
    bounced = build_trajectory(
        "uniform", {}, height_mm=100.0, fps=30.0, disturbance={"bounce_amp_mm": 2.0, "bounce_freq_hz": 3.0}
    )
    dz = bounced.T_world_cam[:, 2, 3] - 100.0
    np.testing.assert_allclose(dz, 2.0 * np.sin(2 * np.pi * 3.0 * base.timestamps_s), atol=1e-12)
    np.testing.assert_allclose(bounced.T_world_cam[:, :2, 3], base.T_world_cam[:, :2, 3], atol=1e-12)
    vib = build_trajectory(
        "line", {"length_mm": 300.0}, height_mm=100.0, fps=30.0, disturbance={"vibration_rms_mm": 0.1}, seed=1
    )
    t = np.linspace(0, 1, 20001)
    d = vib.pose_at(t)[:, 2, 3] - 100.0
    assert np.sqrt(np.mean(d**2)) == pytest.approx(0.1, rel=0.25)


def test_bad_params_refused_by_name():
    with pytest.raises(ConfigError, match=r"trajectory.step_mm = -1.0 mm: must be > 0"):
        build_trajectory("uniform", {"step_mm": -1.0}, height_mm=100.0, fps=30.0)
    with pytest.raises(ConfigError, match=r"trajectory.speed: unknown key"):
        build_trajectory("line", {"speed": 3.0}, height_mm=100.0, fps=30.0)
    with pytest.raises(ConfigError, match=r"trajectory.type = 'zigzag'"):
        build_trajectory("zigzag", {}, height_mm=100.0, fps=30.0)
    with pytest.raises(ConfigError, match=r"trajectory.frames = 'ten'"):
        build_trajectory("sigmoid", {"frames": "ten"}, height_mm=100.0, fps=30.0)
    with pytest.raises(ConfigError, match="height_mm"):
        build_trajectory("uniform", {}, height_mm=-5.0, fps=30.0)


def test_footprint_of_paper_rig():
    cam = CameraModel.from_sensor()
    tr = build_trajectory("uniform", {}, height_mm=100.0, fps=30.0)
    xmin, xmax, ymin, ymax = footprint_bounds_mm(tr.T_world_cam[:1], cam)
    assert xmax - xmin == pytest.approx(648 * cam.gsd_mm_per_px(100.0), rel=1e-9)
    assert ymax - ymin == pytest.approx(494 * cam.gsd_mm_per_px(100.0), rel=1e-9)


def test_paper000_protocol_counts():
    uni = paper000_subsequences("uniform")
    sig = paper000_subsequences("sigmoid_g125")
    assert len(uni) == 100 and len(sig) == 190
    assert uni[0][-1] == 100 and uni[-1][-1] == 199
    assert sig[0][0] == 0 and sig[0][-1] == 10 and max(r.max() for r in sig) == 199


def test_registry_has_the_design_types():
    assert {"uniform", "sigmoid", "line", "arc", "spin", "s_curve", "turns", "lawnmower", "kidnap", "strip"} <= set(
        TRAJECTORIES
    )


def test_a_trajectory_of_one_frame_is_refused():
    """160 mm of arc at 5000 mm/s is 167 mm a frame at 30 fps: one frame, which rendered as a
    sequence with no step to estimate or score (exit code 0). 4000 mm/s gives two frames."""
    arc = {"radius_mm": 150.0, "length_mm": 160.0}
    with pytest.raises(ConfigError, match=r"type 'arc' with these parameters \(at fps = 30\) gives 1 frame: must give"):
        build_trajectory("arc", {**arc, "speed_mm_s": 5000.0}, height_mm=100.0, fps=30.0)
    assert build_trajectory("arc", {**arc, "speed_mm_s": 4000.0}, height_mm=100.0, fps=30.0).frame_count == 2


@pytest.mark.parametrize("x_mm", [1e300, 1e15])
def test_a_path_that_leaves_the_range_of_positions_is_refused(x_mm):
    """spin at x_mm = 1e300 ended in a ValueError from the floor's mesh ('load_heightfield: height
    (33, 1)'); at 1e15 mm the floor was rendered from coordinates float64 holds to 0.125 mm."""

    with pytest.raises(
        ConfigError, match=r"^trajectory: type 'spin' with these parameters reaches a position .* m from"
    ):
        build_trajectory("spin", {"x_mm": x_mm}, height_mm=100.0, fps=30.0)
    assert build_trajectory("spin", {"x_mm": 1e9}, height_mm=100.0, fps=30.0).frame_count > 1


@pytest.mark.parametrize(
    "kind, params",
    [
        ("s_curve", {"length_mm": 160.0, "amplitude_mm": 15.0, "wavelength_mm": 160.0, "speed_mm_s": 120.0}),
        ("turns", {"legs": 2, "leg_mm": 40.0, "turn_radius_mm": 20.0, "speed_mm_s": 120.0}),
        ("lawnmower", {"width_mm": 60.0, "depth_mm": 40.0, "lane_spacing_mm": 20.0, "speed_mm_s": 120.0}),
    ],
)
def test_a_path_goes_on_before_its_start_and_after_its_end(kind, params):
    """An exposure or a rolling shutter's rows reach half an exposure (or readout) before the first
    frame and after the last: there the camera moves on along the path's tangent at its speed
    (it had stood still where the path starts, so a readout's first frame showed it at rest)."""
    tr = build_trajectory(kind, params, height_mm=100.0, fps=30.0)
    dt = 0.0075  # half a 15 ms readout
    for t_edge, sign in ((0.0, -1.0), (tr.duration_s, 1.0)):
        at_edge = tr.se2_at(t_edge)[0]
        inside = tr.se2_at(t_edge - sign * 1e-4)[0]
        heading = (at_edge[:2] - inside[:2]) * sign
        heading /= np.linalg.norm(heading)
        beyond = tr.se2_at(t_edge + sign * dt)[0]
        moved = (beyond[:2] - at_edge[:2]) * sign
        speed = params["speed_mm_s"]
        assert np.linalg.norm(moved) == pytest.approx(speed * dt, rel=0.02)  # moving, not held
        assert float(np.dot(moved, heading)) == pytest.approx(speed * dt, rel=0.02)  # along the tangent

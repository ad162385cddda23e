"""Camera model, transforms, TUM files and the sequence folder."""

import json

import numpy as np
import pytest

from floorvo.camera import CameraModel
from floorvo.errors import ConfigError, SequenceError
from floorvo.geometry import T_world_cam_down, invert_T, rigid_fit, rot_z, se2_from_T
from floorvo.sequence import SCHEMA_VERSION, Sequence, SequenceWriter
from floorvo.tum import read_tum, write_tum


def test_paper000_gsd_matches_eq1():
    cam = CameraModel.from_sensor()  # 648x494, 7.4 um, f = 6 mm
    # Eq. (1) of paper 000: 2 d tan(theta) / w with tan(theta) = (w/2 * pitch) / f
    tan_theta = (648 / 2 * 7.4e-3) / 6.0
    assert cam.gsd_mm_per_px(100.0) == pytest.approx(2 * 100.0 * tan_theta / 648, rel=1e-12)
    assert cam.gsd_mm_per_px(100.0) == pytest.approx(0.12333, abs=1e-5)


def test_scaled_camera_keeps_geometry():
    cam = CameraModel.from_sensor()
    q = cam.scaled(0.25)
    assert (q.width_px, q.height_px) == (162, 124)
    # A floor point seen by both cameras lands on the same place in units of image size.
    p = np.array([[3.0, -2.0, 100.0]])
    uv, uvq = cam.project(p)[0], q.project(p)[0]
    assert (uvq[0] + 0.5) / q.width_px == pytest.approx((uv[0] + 0.5) / cam.width_px, rel=1e-3)
    assert q.cx_px == pytest.approx((q.width_px - 1) / 2)


def test_project_unproject_round_trip_with_distortion():
    cam = CameraModel(640, 480, 800.0, 800.0, 320.0, 240.0, (-0.1, 0.02, 0.001, -0.001, 0.0))
    p = np.array([[5.0, -3.0, 100.0], [-20.0, 15.0, 100.0]])
    back = cam.unproject(cam.project(p), 100.0)
    np.testing.assert_allclose(back, p, atol=1e-4)


def test_pinhole_pixels_of_a_distorted_camera():
    """CameraModel.undistorted_px: the ideal pinhole's pixel (same K) on each pixel's ray, by hand
    from project (a point's distorted pixel goes to K (X/Z, Y/Z, 1)); distorted_px its inverse;
    both the pixels themselves, dtype kept, without distortion."""
    cam = CameraModel(640, 480, 800.0, 760.0, 300.0, 250.0, (-0.2, 0.05, 0.001, -0.001, 0.0))
    p = np.array([[5.0, -3.0, 100.0], [-20.0, 15.0, 100.0], [30.0, 25.0, 100.0]])
    pin = np.column_stack([800.0 * p[:, 0] / p[:, 2] + 300.0, 760.0 * p[:, 1] / p[:, 2] + 250.0])
    np.testing.assert_allclose(cam.undistorted_px(cam.project(p)), pin, atol=1e-4)
    np.testing.assert_allclose(cam.distorted_px(pin), cam.project(p), atol=1e-9)
    assert cam.undistorted_px(cam.project(p).astype(np.float32)).dtype == np.float32
    ideal = CameraModel(640, 480, 800.0, 760.0, 300.0, 250.0)
    uv = np.float32([[1.5, 2.5]])
    assert ideal.undistorted_px(uv) is uv and ideal.distorted_px(uv) is uv


def test_bad_camera_refused():
    with pytest.raises(ConfigError, match="focal"):
        CameraModel(10, 10, 0.0, 1.0, 5, 5)


@pytest.mark.parametrize("cx, cy", [(500.0, 5.0), (5.0, -0.6), (-40.0, 5.0), (5.0, 10.5)])
def test_a_principal_point_outside_the_image_is_refused(cx, cy):
    """Every reader of a camera (sequence.json, camera files, flags, camera_info) builds a
    CameraModel: a principal point far outside the image was accepted by all of them."""
    with pytest.raises(ConfigError, match=r"^camera: principal point \(cx, cy\) = .* must lie in the image") as info:
        CameraModel(10, 10, 20.0, 20.0, cx, cy)
    assert "\n" not in str(info.value) and "(10x10 px)" in str(info.value)
    for ok in ((0.0, 0.0), (10.0, 10.0), (4.5, 4.5), (-0.5, -0.25)):  # the top-left edge is at -0.5
        CameraModel(10, 10, 20.0, 20.0, *ok)


@pytest.mark.parametrize(
    "block, message",
    [
        ({"width_px": 10, "height_px": 10, "K": [[float("nan"), 0, 5], [0, 1, 5], [0, 0, 1]]}, "must be finite"),
        ({"width_px": 10.7, "height_px": 10, "K": [[1, 0, 5], [0, 1, 5], [0, 0, 1]]}, "whole pixels, got 10.7x10"),
        ({"width_px": "80mm", "height_px": 10, "K": [[1, 0, 5], [0, 1, 5], [0, 0, 1]]}, "got '80mm'x10"),
        ({"width_px": 10, "height_px": 10, "K": [[1, 0, 5], [0, 1, 5]]}, "K = .*: must be a 3x3 matrix"),
        ({"width_px": 10, "height_px": 10, "K": [[1, 0, 5], [0, 1, 5], [0, 0, "x"]]}, "must be a 3x3 matrix"),
        ({"width_px": 10, "height_px": 10, "K": [[1, 0, 5], [0, 1, 5], [0, 0, 1]], "distortion": 5}, "distortion = 5"),
        ({"width_px": 10, "height_px": 10, "K": [[1, 0, 5], [0, 1, 5], [0, 0, 1]], "distortion": "ab"}, "numbers"),
        ([1], r"camera: \[1\]: need a table"),
        ({"width_px": 10, "K": [[1, 0, 5], [0, 1, 5], [0, 0, 1]]}, "need a table with width_px, height_px and K"),
    ],
)
def test_malformed_camera_blocks_are_refused_in_one_line(block, message):
    """Issue 16: a NaN K gave LinAlgError later, 20.7 px was read as 20, text gave a ValueError repr."""
    with pytest.raises(ConfigError, match=message) as info:
        CameraModel.from_dict(block)
    assert "\n" not in str(info.value)


def test_camera_moving_plus_x_moves_floor_point_minus_u():
    cam = CameraModel.from_sensor()
    p_world = np.array([0.0, 0.0, 0.0, 1.0])
    uv = []
    for x in (0.0, 1.0):
        T = T_world_cam_down(x, 0.0, 100.0)
        uv.append(cam.project((invert_T(T) @ p_world)[:3])[0])
    du = uv[1][0] - uv[0][0]
    assert du == pytest.approx(-1.0 / cam.gsd_mm_per_px(100.0), rel=1e-9)
    assert uv[1][1] == pytest.approx(uv[0][1])


def test_se2_and_rigid_fit():
    T = T_world_cam_down(3.0, -4.0, 100.0, yaw_rad=0.3)
    np.testing.assert_allclose(se2_from_T(T), [3.0, -4.0, 0.3], atol=1e-12)
    rng = np.random.default_rng(0)
    src = rng.normal(size=(30, 2))
    R = rot_z(-0.7)[:2, :2]
    dst = src @ R.T + [1.5, -2.0]
    R_est, t_est = rigid_fit(src, dst)
    np.testing.assert_allclose(R_est, R, atol=1e-12)
    np.testing.assert_allclose(t_est, [1.5, -2.0], atol=1e-12)


def test_tum_round_trip_in_metres(tmp_path):
    Ts = np.stack([T_world_cam_down(4.0 * i, 0.5 * i, 100.0, 0.01 * i) for i in range(5)])
    ts = np.arange(5) / 30.0
    write_tum(tmp_path / "t.txt", ts, Ts)
    first = (tmp_path / "t.txt").read_text().splitlines()[1].split()
    assert float(first[1]) == pytest.approx(0.004)  # 4 mm written as metres
    ts2, Ts2 = read_tum(tmp_path / "t.txt")
    np.testing.assert_allclose(ts2, ts, atol=1e-6)
    np.testing.assert_allclose(Ts2, Ts, atol=1e-8)


def test_tum_errors(tmp_path):
    (tmp_path / "empty.txt").write_text("# nothing\n")
    with pytest.raises(SequenceError, match="empty"):
        read_tum(tmp_path / "empty.txt")
    (tmp_path / "bad.txt").write_text("0 1 2 3\n")
    with pytest.raises(SequenceError, match=r"bad.txt:1: a TUM line has 8 numbers"):
        read_tum(tmp_path / "bad.txt")
    # finite, but so far out that a step vanishes in rounding: every reader of poses refuses it
    (tmp_path / "far.txt").write_text("0 0 0 0.1 0 0 0 1\n0.1 1e200 0 0.1 0 0 0 1\n")
    with pytest.raises(SequenceError, match=r"far.txt:2: a position 1e\+200 m from the origin \(at most 1e\+08 m"):
        read_tum(tmp_path / "far.txt")
    (tmp_path / "ns.txt").write_text("1403636579758555392 0 0 0.1 0 0 0 1\n")
    with pytest.raises(SequenceError, match=r"ns.txt:1: timestamp = 1.40364e\+18 s is beyond 1e\+10 s"):
        read_tum(tmp_path / "ns.txt")
    (tmp_path / "utm.txt").write_text("0 512345.25 5412345.5 0.1 0 0 0 1\n")
    assert read_tum(tmp_path / "utm.txt")[1][0, 1, 3] == 5412345500.0  # UTM northing, mm


def _meta(n=3):
    return {
        "camera": CameraModel.from_sensor().scaled(0.25).to_dict(),
        "fps": 10.0,
        "frame_count": n,
        "scene": {"a": 1},
    }


def test_sequence_write_read_resume(tmp_path):
    w = SequenceWriter(tmp_path / "seq", _meta())
    img = (np.arange(124 * 162) % 251).astype(np.uint8).reshape(124, 162)
    w.write_frame(0, img)
    assert w.missing_frames() == [1, 2]
    # Restarting with the same metadata keeps frame 0.
    w2 = SequenceWriter(tmp_path / "seq", _meta())
    assert w2.resumed and w2.has_frame(0)
    # Different metadata is refused without --overwrite.
    other = _meta()
    other["scene"] = {"a": 2}
    with pytest.raises(SequenceError, match="different sequence"):
        SequenceWriter(tmp_path / "seq", other)
    seq = Sequence.open(tmp_path / "seq")
    np.testing.assert_array_equal(seq.image(0), img)
    with pytest.raises(SequenceError, match="missing"):
        seq.image(1)


def test_sequence_rejects_other_schema_and_corrupt_png(tmp_path):
    w = SequenceWriter(tmp_path / "seq", _meta(1))
    (tmp_path / "seq" / "cam0").mkdir(exist_ok=True)
    (tmp_path / "seq" / "cam0" / "000000.png").write_bytes(b"\x89PNG garbage")
    with pytest.raises(SequenceError, match="not a readable PNG"):
        Sequence.open(tmp_path / "seq").image(0)
    meta = json.loads((tmp_path / "seq" / "sequence.json").read_text())
    meta["schema_version"] = SCHEMA_VERSION + 1
    (tmp_path / "seq" / "sequence.json").write_text(json.dumps(meta))
    with pytest.raises(SequenceError, match="schema_version"):
        Sequence.open(tmp_path / "seq")
    assert w.root.exists()
    (tmp_path / "seq" / "sequence.json").write_text('{"schema_version": 1,')  # truncated
    with pytest.raises(SequenceError, match=r"sequence\.json: not valid JSON \(.* at line 1\)$"):
        Sequence.open(tmp_path / "seq")


def test_depth_png_round_trip(tmp_path):
    meta = _meta(1)
    meta["depth"] = {"format": "png16"}
    w = SequenceWriter(tmp_path / "seq", meta)
    d = np.full((124, 162), 100.0)
    d[0, 0] = 99.994
    w.write_depth(0, d)
    got = Sequence.open(tmp_path / "seq").depth_mm(0)
    assert got[5, 5] == pytest.approx(100.0)
    assert got[0, 0] == pytest.approx(99.99, abs=1e-4)


def test_write_tum_writes_only_what_read_tum_reads_back(tmp_path):
    """A transposed pose was written as the identity at the origin, a scaled rotation as the
    rotation it approximates, a NaN or a time out of order or closer than a microsecond to the last
    as a file read_tum refuses, a mirrored rotation raised from inside scipy: each is refused when
    written, in one line naming the pose, and nothing is written."""
    from floorvo.geometry import rigid_problem

    T = np.stack([T_world_cam_down(4.0 * i, 0.0, 100.0, 0.1 * i) for i in range(4)])
    t = np.array([0.0, 0.1, 0.2, 0.3])
    write_tum(tmp_path / "ok.txt", t, T)
    t_back, T_back = read_tum(tmp_path / "ok.txt")
    np.testing.assert_allclose(T_back, T, atol=1e-6)
    np.testing.assert_allclose(t_back, t)
    scaled, mirrored, nan, far = T.copy(), T.copy(), T.copy(), T.copy()
    scaled[1, :3, :3] *= 2.0
    mirrored[1, :3, 0] *= -1.0
    nan[1, 0, 3] = np.nan
    far[1, 0, 3] = 1e15  # 1e12 m: beyond MAX_POSITION_MM, what read_tum refuses
    cases = [
        (t, np.swapaxes(T, 1, 2), r"pose 0: bottom row"),
        (t, scaled, r"pose 1: its 3x3 part is not a rotation"),
        (t, mirrored, r"pose 1: its 3x3 part is not a rotation"),
        (t, nan, r"pose 1: holds a non-finite value"),
        (t, far, r"pose 1: a position 1e\+12 m from the origin"),
        (np.array([0.0, np.nan, 0.2, 0.3]), T, r"pose 1: timestamp is not a finite number"),
        (np.array([0.0, 0.2, 0.1, 0.3]), T, r"pose 2: timestamp 0.100000 s follows 0.200000 s"),
        (np.array([0.0, 0.1, 0.1000002, 0.3]), T, r"pose 2: .* \(as written, with 6 decimals\)"),
        (t[:3], T, r"need \(N,\) timestamps and \(N, 4, 4\) poses"),
    ]
    for times, poses, words in cases:
        with pytest.raises(ValueError, match="format_tum: " + words):
            write_tum(tmp_path / "bad.txt", times, poses)
    assert not (tmp_path / "bad.txt").exists()
    # The rule is rigid_problem's, over a stack: the same reasons, naming the pose.
    assert rigid_problem(T, stack=True) is None and rigid_problem(T[:0], stack=True) is None
    assert rigid_problem(scaled, stack=True) == "pose 1: " + str(rigid_problem(scaled[1]))
    assert rigid_problem(nan, stack=True, unknown=True) is None
    assert rigid_problem(T[0], stack=True) == "shape (4, 4), not (N, 4, 4)"


def test_a_camera_scaled_by_no_finite_positive_number_is_refused_in_one_line():
    """scaled(nan) raised 'cannot convert float NaN to integer' from inside; inf and 0 are refused too."""
    cam = CameraModel.from_sensor(648, 494)
    for bad in (float("nan"), float("inf"), 0.0, -0.5):
        with pytest.raises(ConfigError, match="camera: scale must be a finite number > 0"):
            cam.scaled(bad)
    half = cam.scaled(0.5)
    assert half.size == (324, 247) and half.fx_px == pytest.approx(cam.fx_px / 2)

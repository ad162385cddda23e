"""Exports read back with the libraries that wrote them; poses compared with groundtruth.txt."""

import csv
import re

import numpy as np
import pytest
import yaml

from floorsim.export import export_sequence
from floorvo.camera import CameraModel
from floorvo.geometry import T_from_xyz_quat, T_world_cam_down
from floorvo.sequence import Sequence, SequenceWriter


@pytest.fixture
def stereo_depth_seq(tmp_path):
    cam = CameraModel.from_sensor(40, 30, pixel_pitch_um=120.0)
    T01 = np.eye(4)
    T01[0, 3] = 20.0
    meta = {
        "camera": cam.to_dict(),
        "cameras": {"cam1": cam.to_dict()},
        "fps": 10.0,
        "frame_count": 4,
        "stereo": True,
        "depth": {"format": "png16"},
        "rig": {"height_mm": 100.0, "T_cam0_cam1": T01.tolist()},
    }
    w = SequenceWriter(tmp_path / "seq", meta)
    rng = np.random.default_rng(0)
    Ts = np.stack([T_world_cam_down(3.0 * i, 0.5 * i, 100.0, 0.02 * i) for i in range(4)])
    for i in range(4):
        w.write_frame(i, rng.integers(0, 255, (30, 40), dtype=np.uint8))
        w.write_frame(i, rng.integers(0, 255, (30, 40), dtype=np.uint8), "cam1")
        w.write_depth(i, np.full((30, 40), 100.0 + i))
    w.write_groundtruth(np.arange(4) / 10.0, Ts)
    return tmp_path / "seq", Ts


def test_rosbag2_round_trip(stereo_depth_seq, tmp_path):
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    seq_dir, Ts = stereo_depth_seq
    out = export_sequence(seq_dir, "rosbag2", tmp_path / "bag")
    ts = get_typestore(Stores.ROS2_HUMBLE)
    poses, images, depth, infos, static = [], {}, [], [], []
    with Reader(out) as r:
        for conn, _t_ns, raw in r.messages():
            msg = ts.deserialize_cdr(raw, conn.msgtype)
            if conn.topic == "/groundtruth/pose":
                p, q = msg.pose.position, msg.pose.orientation
                poses.append(T_from_xyz_quat(np.array([p.x, p.y, p.z]) * 1000.0, [q.x, q.y, q.z, q.w]))
            elif conn.topic.endswith("image_raw"):
                images.setdefault(conn.topic, []).append(msg.data.reshape(msg.height, msg.width))
            elif conn.topic == "/cam0/depth":
                depth.append(np.frombuffer(msg.data.tobytes(), "<f4").reshape(msg.height, msg.width))
            elif conn.topic == "/cam0/camera_info":
                infos.append(msg.k.reshape(3, 3))
            elif conn.topic == "/tf_static":
                static.append(msg.transforms[0].transform.translation.x)
    np.testing.assert_allclose(np.stack(poses), Ts, atol=1e-6)
    seq = Sequence.open(seq_dir)
    for c in ("cam0", "cam1"):
        for i, img in enumerate(images[f"/{c}/image_raw"]):
            np.testing.assert_array_equal(img, seq.image(i, c))
    np.testing.assert_allclose(depth[2], 0.102, atol=1e-6)  # metres
    np.testing.assert_allclose(infos[0], seq.camera.K)
    assert static == [pytest.approx(0.020)]


def test_euroc_round_trip(stereo_depth_seq, tmp_path):
    seq_dir, Ts = stereo_depth_seq
    out = export_sequence(seq_dir, "euroc", tmp_path / "euroc")
    rows = list(csv.reader(open(out / "mav0/state_groundtruth_estimate0/data.csv")))[1:]
    got = []
    for r in rows:
        v = [float(x) for x in r]
        got.append(T_from_xyz_quat(np.array(v[1:4]) * 1000.0, [v[5], v[6], v[7], v[4]]))
    np.testing.assert_allclose(np.stack(got), Ts, atol=1e-6)
    assert int(rows[1][0]) == 100_000_000  # 10 fps in nanoseconds
    text = (out / "mav0/cam1/sensor.yaml").read_text()
    sensor = yaml.safe_load(text.split("\n", 1)[1])
    assert sensor["T_BS"]["data"][3] == pytest.approx(0.020)
    seq = Sequence.open(seq_dir)
    assert sensor["intrinsics"] == pytest.approx(
        [seq.camera.fx_px, seq.camera.fy_px, seq.camera.cx_px, seq.camera.cy_px]
    )
    files = [r[1] for r in list(csv.reader(open(out / "mav0/cam0/data.csv")))[1:]]
    assert len(files) == 4 and (out / "mav0/cam0/data" / files[0]).read_bytes() == seq.image_path(0).read_bytes()


def test_export_refuses_existing_output(stereo_depth_seq, tmp_path):
    from floorvo.errors import FloorbenchError

    seq_dir, _ = stereo_depth_seq
    (tmp_path / "taken").mkdir()
    (tmp_path / "taken" / "x").write_text("x")
    with pytest.raises(FloorbenchError, match="output exists"):
        export_sequence(seq_dir, "euroc", tmp_path / "taken")


def _seq_30fps(root, distortion=(0.0,) * 5):
    cam = CameraModel.from_sensor(40, 30, pixel_pitch_um=120.0, distortion=distortion)
    w = SequenceWriter(root, {"camera": cam.to_dict(), "fps": 30.0, "frame_count": 4})
    Ts = np.stack([T_world_cam_down(3.0 * i, 0.0, 100.0, 0.0) for i in range(4)])
    for i in range(4):
        w.write_frame(i, np.full((30, 40), 10 * i, dtype=np.uint8))
    w.write_groundtruth(np.arange(4) / 30.0, Ts)
    return root


def test_euroc_groundtruth_stamps_are_the_image_stamps(tmp_path):
    """groundtruth.txt holds microseconds (0.033333 s); the export gives its rows the frames' nanoseconds."""
    out = export_sequence(_seq_30fps(tmp_path / "seq"), "euroc", tmp_path / "euroc")
    images = [int(r[0]) for r in list(csv.reader(open(out / "mav0/cam0/data.csv")))[1:]]
    gt = [int(r[0]) for r in list(csv.reader(open(out / "mav0/state_groundtruth_estimate0/data.csv")))[1:]]
    assert images == [0, 33_333_333, 66_666_667, 100_000_000]  # round(i / 30 s * 1e9)
    assert gt == images
    assert sorted(p.name for p in (out / "mav0/cam0/data").iterdir()) == sorted(f"{t}.png" for t in images)


def test_euroc_keeps_k3(tmp_path):
    """k3 is written after EuRoC's four radial-tangential coefficients; a camera without one keeps four."""
    d = (-0.12, 0.05, 0.001, -0.002, 0.03)
    out = export_sequence(_seq_30fps(tmp_path / "k3", d), "euroc", tmp_path / "e1")
    sensor = yaml.safe_load((out / "mav0/cam0/sensor.yaml").read_text().split("\n", 1)[1])
    assert sensor["distortion_coefficients"] == pytest.approx(list(d))
    out = export_sequence(_seq_30fps(tmp_path / "k0", d[:4] + (0.0,)), "euroc", tmp_path / "e0")
    sensor = yaml.safe_load((out / "mav0/cam0/sensor.yaml").read_text().split("\n", 1)[1])
    assert sensor["distortion_coefficients"] == pytest.approx(list(d[:4]))


@pytest.mark.parametrize("fmt", ["euroc", "rosbag2"])
def test_export_refuses_empty_output_path(stereo_depth_seq, tmp_path, monkeypatch, fmt):
    from floorvo.errors import FloorbenchError

    seq_dir, _ = stereo_depth_seq
    work = tmp_path / "cwd"
    work.mkdir()
    monkeypatch.chdir(work)
    with pytest.raises(FloorbenchError, match="path is empty"):
        export_sequence(seq_dir, fmt, "")
    assert list(work.iterdir()) == []


def test_rosbag2_refuses_an_existing_empty_folder(stereo_depth_seq, tmp_path):
    """The bag writer makes its folder itself: an existing one is refused in one line, not with WriterError."""
    from floorvo.errors import FloorbenchError

    seq_dir, _ = stereo_depth_seq
    (tmp_path / "bag").mkdir()
    with pytest.raises(FloorbenchError, match="output exists"):
        export_sequence(seq_dir, "rosbag2", tmp_path / "bag")


@pytest.mark.parametrize("fmt", ["rosbag2", "euroc"])
def test_an_export_leaves_nothing_out(tmp_path, caplog, fmt):
    """The flat field, a range sensor's height.csv and the rig height were dropped (first without a
    word, then with a warning naming the import flag that gives each back); both formats carry
    them now (test_export_import.py reads them back), and nothing is said to be left out."""
    import logging

    from floorvo.synthetic import line_poses, write_synthetic_sequence

    cam = CameraModel.from_sensor().scaled(0.1)
    seq = write_synthetic_sequence(tmp_path / "seq", cam, line_poses(4.0, 2.0), height_noise_mm=0.5)
    with caplog.at_level(logging.WARNING, logger="floorsim.export"):
        export_sequence(seq, fmt, tmp_path / "out")
    assert not caplog.records, [r.getMessage() for r in caplog.records]


@pytest.mark.parametrize(
    "fmt, times_s, words",
    [
        ("rosbag2", [3e9, 3e9 + 1, 3e9 + 2, 3e9 + 3], "frame 0 at 3e+09 s cannot be stamped in rosbag2"),
        ("rosbag2", [-2.0, -1.0, 0.0, 1.0], "frame 0 at -2 s cannot be stamped in rosbag2"),
        ("euroc", [9.5e9, 9.5e9 + 1, 9.5e9 + 2, 9.5e9 + 3], "frame 0 at 9.5e+09 s cannot be stamped in euroc"),
    ],
)
def test_times_a_format_cannot_stamp_are_refused_before_writing(tmp_path, fmt, times_s, words):
    """A frame at 3e9 s ended the bag export in a struct.error traceback (ROS time holds int32
    seconds), and EuRoC wrote nanosecond stamps past int64; refused in one line, nothing written."""
    from floorvo.errors import FloorbenchError

    cam = CameraModel(40, 30, 50.0, 50.0, 19.5, 14.5)
    w = SequenceWriter(tmp_path / "seq", {"camera": cam.to_dict(), "fps": 10.0, "frame_count": 4})
    for i in range(4):
        w.write_frame(i, np.full((30, 40), 10 * i, np.uint8))
    w.write_timestamps(np.array(times_s))
    with pytest.raises(FloorbenchError, match=re.escape(words)) as info:
        export_sequence(tmp_path / "seq", fmt, tmp_path / "out")
    assert "\n" not in str(info.value) and "shift the sequence's times" in str(info.value)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("fmt", ["euroc", "rosbag2"])
def test_an_export_that_fails_half_way_leaves_nothing_behind(stereo_depth_seq, tmp_path, fmt):
    """A frame that did not decode stopped the export with half of it under the output's name,
    which the next export refused as 'output exists'; an export is all or nothing now."""
    from floorvo.errors import SequenceError

    seq_dir, _ = stereo_depth_seq
    good = (seq_dir / "cam0" / "000002.png").read_bytes()
    (seq_dir / "cam0" / "000002.png").write_bytes(good[:60])
    with pytest.raises(SequenceError, match="000002.png: not a readable PNG"):
        export_sequence(seq_dir, fmt, tmp_path / "out")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["seq"]  # no output, no hidden temporary
    (seq_dir / "cam0" / "000002.png").write_bytes(good)
    assert export_sequence(seq_dir, fmt, tmp_path / "out") == tmp_path / "out"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "seq"]
    if fmt == "rosbag2":  # the bag's file is named after the folder it was written as
        assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["metadata.yaml", "out.db3"]


def test_a_full_disk_stops_a_bag_export_in_one_line(stereo_depth_seq, tmp_path, monkeypatch, capsys):
    """The bag's storage is sqlite3, whose full disk ('database or disk is full', raised as the
    writer closed) was a 28-line traceback; here its writer fails so after three messages."""
    import sqlite3

    from rosbags.rosbag2 import Writer

    from floorsim.cli import main

    seq_dir, _ = stereo_depth_seq
    write, calls = Writer.write, []

    def filling(self, *args, **kwargs):
        calls.append(1)
        if len(calls) > 3:
            raise sqlite3.OperationalError("database or disk is full")
        return write(self, *args, **kwargs)

    monkeypatch.setattr(Writer, "write", filling)
    assert main(["export", str(seq_dir), "--format", "rosbag2", "-o", str(tmp_path / "bag")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"floorsim: error: {tmp_path / 'bag' / 'bag.db3'}: database or disk is full (sqlite3)"], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["seq"]  # no output, no hidden temporary


def test_a_killed_exports_hidden_folder_is_removed_by_the_next_export(stereo_depth_seq, tmp_path):
    """A killed export left its hidden temporary folder beside the output for good. The next
    export to the same path removes it; a running export's (locked), a link named like one and
    other hidden folders stay."""
    import subprocess
    import sys

    from _procs import child_env, held_by_another_process

    seq_dir, _ = stereo_depth_seq
    killed = (
        "import os, signal, sys\nimport floorsim.export as E\n"
        "def die(seq, out):\n    (out / 'mav0').mkdir(parents=True)\n    os.kill(os.getpid(), signal.SIGKILL)\n"
        "E._write_euroc = die\nE.export_sequence(sys.argv[1], 'euroc', sys.argv[2])\n"
    )
    r = subprocess.run([sys.executable, "-c", killed, str(seq_dir), str(tmp_path / "out")], env=child_env())
    assert r.returncode == -9
    (stale,) = [p for p in tmp_path.iterdir() if p.name.startswith(".out.")]
    assert re.fullmatch(r"\.out\.[0-9a-f]{8}\.tmp", stale.name) and (stale / "out" / "mav0").is_dir()
    running = tmp_path / ".out.0123abcd.tmp"
    others = [tmp_path / ".out.notours.tmp", tmp_path / ".other.0123abcd.tmp"]
    for p in others:
        p.mkdir()
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / ".out.89abcdef.tmp").symlink_to(tmp_path / "elsewhere")
    with held_by_another_process(running):
        assert export_sequence(seq_dir, "euroc", tmp_path / "out") == tmp_path / "out"
        assert not stale.exists() and running.is_dir()
    assert all(p.is_dir() for p in others) and (tmp_path / "elsewhere").is_dir()
    assert (tmp_path / ".out.89abcdef.tmp").is_symlink()
    assert Sequence.open(seq_dir).frame_count == len(list((tmp_path / "out" / "mav0" / "cam0" / "data").iterdir()))

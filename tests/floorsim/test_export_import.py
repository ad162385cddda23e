"""Round trips: ``floorsim export`` (EuRoC, ROS 2 bag) then ``floorvo import`` give back the sequence.

The sequence is a small synthetic one (:mod:`floorvo.synthetic`: stereo, depth, exact ground
truth), not a render. The imported sequence must hold the same frames, camera, rig and ground
truth, and an estimator run over it must give the same trajectory (to 1e-6 m) as over the original.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from floorsim.export import export_sequence
from floorvo.camera import CameraModel
from floorvo.cli import main
from floorvo.run import run_estimator
from floorvo.sequence import Sequence
from floorvo.synthetic import line_poses, write_synthetic_sequence
from floorvo.tum import read_tum

CAM = CameraModel.from_sensor(162, 124, pixel_pitch_um=29.6, focal_length_mm=6.0)


@pytest.fixture(scope="module")
def original(tmp_path_factory):
    """Synthetic stereo + depth sequence (8 frames, 4 mm steps, turning) and a phase-corr run over it."""
    tmp = tmp_path_factory.mktemp("orig")
    T = line_poses(28.0, 4.0, 100.0, yaw_step_rad=np.radians(0.5))
    root = write_synthetic_sequence(tmp / "seq", CAM, T, depth=True, stereo_baseline_mm=10.0, seed=5)
    run_estimator(root, "phase-corr", tmp / "run")
    return Sequence.open(root), read_tum(tmp / "run" / "trajectory.txt")


@pytest.mark.parametrize("fmt", ["euroc", "rosbag2"])
def test_export_then_import_gives_the_same_sequence_and_trajectory(tmp_path, original, fmt, capsys):
    seq, (t_orig, T_orig) = original
    exported = export_sequence(seq.root, fmt, tmp_path / "exported")
    out = tmp_path / "imported"
    argv = ["import", str(exported), "-o", str(out), "--height-mm", "100"]
    argv += ["--flatfield", str(seq.root / "calib" / "cam0_flatfield.png")]  # a bag carries no flat field
    assert main(argv) == 0
    assert f"{fmt}: 8 frames 162x124 8-bit stereo" in capsys.readouterr().out
    imp = Sequence.open(out)
    assert imp.meta["source"]["format"] == fmt and imp.frame_count == seq.frame_count
    np.testing.assert_allclose(imp.camera.K, seq.camera.K)
    np.testing.assert_allclose(imp.camera_model("cam1").K, seq.camera_model("cam1").K)
    np.testing.assert_allclose(imp.T_cam0_cam1, seq.T_cam0_cam1, atol=1e-9)
    np.testing.assert_allclose(imp.timestamps_s, seq.timestamps_s, rtol=0, atol=1e-9)
    for i in range(seq.frame_count):
        np.testing.assert_array_equal(imp.image(i), seq.image(i))
        np.testing.assert_array_equal(imp.image(i, "cam1"), seq.image(i, "cam1"))
    if fmt == "rosbag2":
        assert imp.has_depth
        np.testing.assert_allclose(imp.depth_mm(3), seq.depth_mm(3), atol=1e-4)
    t_gt, T_gt = imp.groundtruth()
    t_ref, T_ref = seq.groundtruth()
    np.testing.assert_allclose(T_gt, T_ref, atol=1e-6)
    np.testing.assert_allclose(t_gt, t_ref, rtol=0, atol=1e-6)
    assert main(["run", str(out), "-e", "phase-corr", "-o", str(tmp_path / "run")]) == 0
    t_run, T_run = read_tum(tmp_path / "run" / "trajectory.txt")
    np.testing.assert_allclose(t_run, t_orig, rtol=0, atol=1e-6)
    np.testing.assert_allclose(T_run[:, :3, 3], T_orig[:, :3, 3], rtol=0, atol=1e-3)  # 1e-6 m, in mm
    np.testing.assert_allclose(T_run[:, :3, :3], T_orig[:, :3, :3], rtol=0, atol=1e-9)


@pytest.mark.parametrize("fmt, k3", [("euroc", 0.0), ("euroc", 0.004), ("rosbag2", 0.004)])
def test_distortion_survives_the_round_trip(tmp_path, fmt, k3):
    """k1, k2, p1, p2 and k3 (EuRoC's fifth coefficient when it is not 0, the bag's plumb_bob
    camera_info) come back as they were written."""
    from floorvo.sequence import SequenceWriter

    cam = CameraModel(40, 30, 50.0, 51.0, 19.5, 14.5, (-0.12, 0.03, 0.001, -0.002, k3))
    w = SequenceWriter(tmp_path / "seq", {"camera": cam.to_dict(), "fps": 10.0, "frame_count": 2})
    for i in range(2):
        w.write_frame(i, np.full((30, 40), 10 * i, np.uint8))
    exported = export_sequence(tmp_path / "seq", fmt, tmp_path / "exported")
    assert main(["import", str(exported), "-o", str(tmp_path / "imported")]) == 0
    got = Sequence.open(tmp_path / "imported").camera
    assert got.distortion == pytest.approx(cam.distortion, abs=1e-12)
    assert (got.fx_px, got.fy_px, got.cx_px, got.cy_px) == (50.0, 51.0, 19.5, 14.5)


def _drop_csv_row(csv_path, k: int) -> int:
    """Remove the ``k``-th data row of a EuRoC ``data.csv``; returns its stamp (ns)."""
    lines = csv_path.read_text().splitlines(keepends=True)
    rows = [i for i, line in enumerate(lines) if line.strip() and not line.startswith("#")]
    stamp = int(lines[rows[k]].split(",")[0])
    del lines[rows[k]]
    csv_path.write_text("".join(lines))
    return stamp


def test_a_euroc_cam1_missing_a_row_is_refused_unless_left_only_is_given(tmp_path, original, capsys):
    """One cam1 row missing made the import drop the whole right camera with a warning: a stereo
    recording came out mono, exit code 0. It is refused in one line naming the stamp and the
    rule; --left-only imports cam0 alone on purpose."""
    seq, _ = original
    exported = export_sequence(seq.root, "euroc", tmp_path / "exported")
    stamp = _drop_csv_row(exported / "mav0" / "cam1" / "data.csv", 3)
    out = tmp_path / "imported"
    assert main(["import", str(exported), "-o", str(out), "--height-mm", "100"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert f"cam1/data.csv: no row at {stamp} ns, the stamp of cam0's frame 3 (1 of 8 cam0 stamps have none)" in err[0]
    assert "give --left-only to import cam0 alone" in err[0]
    assert not out.exists()
    assert main(["import", str(exported), "-o", str(out), "--height-mm", "100", "--left-only"]) == 0
    assert "8 frames 162x124 8-bit," in capsys.readouterr().out
    imp = Sequence.open(out)
    assert not imp.has_stereo and imp.frame_count == 8


def test_a_euroc_cam1_folder_without_its_data_csv_is_refused_unless_left_only(tmp_path, original, capsys):
    """A cam1 folder without data.csv was passed over: a stereo recording imported mono, exit 0."""
    seq, _ = original
    exported = export_sequence(seq.root, "euroc", tmp_path / "exported")
    (exported / "mav0" / "cam1" / "data.csv").unlink()
    assert main(["import", str(exported), "-o", str(tmp_path / "imported")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cam1: no data.csv (a EuRoC camera lists its frames there)" in err[0], err
    assert main(["import", str(exported), "-o", str(tmp_path / "imported"), "--left-only"]) == 0


def test_right_images_without_a_right_camera_are_refused_unless_left_only(tmp_path, original, capsys):
    """Right images without the right camera's calibration were left out with a warning: the
    stereo recording came out mono, exit code 0."""
    seq, _ = original
    exported = export_sequence(seq.root, "euroc", tmp_path / "exported")
    (exported / "mav0" / "cam1" / "sensor.yaml").unlink()
    assert main(["import", str(exported), "-o", str(tmp_path / "imported")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "right images found but no right camera calibration and pose" in err[0], err
    assert not (tmp_path / "imported").exists()
    assert main(["import", str(exported), "-o", str(tmp_path / "imported"), "--left-only"]) == 0
    assert not Sequence.open(tmp_path / "imported").has_stereo


def test_a_euroc_cam1_row_without_a_cam0_frame_is_refused(tmp_path, original, capsys):
    seq, _ = original
    exported = export_sequence(seq.root, "euroc", tmp_path / "exported")
    stamp = _drop_csv_row(exported / "mav0" / "cam0" / "data.csv", 5)
    assert main(["import", str(exported), "-o", str(tmp_path / "imported")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"cam1/data.csv: the row at {stamp} ns has no cam0 frame (1 cam1 row(s)" in err[0]


def test_a_euroc_frame_stamp_beyond_64_bit_nanoseconds_is_refused(tmp_path, original, capsys):
    """9.3e18 ns (9.3e9 s, within the 1e10 s a time may be) overflowed numpy's int64: a traceback."""
    seq, _ = original
    exported = export_sequence(seq.root, "euroc", tmp_path / "exported")
    data = exported / "mav0" / "cam0" / "data.csv"
    lines = data.read_text().splitlines()
    lines[-1] = "9300000000000000000," + lines[-1].split(",", 1)[1]
    data.write_text("\n".join(lines) + "\n")
    assert main(["import", str(exported), "-o", str(tmp_path / "imported"), "--height-mm", "100"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"cam0/data.csv:{len(lines)}: timestamp 9300000000000000000 ns is beyond" in err[0], err


@pytest.mark.parametrize("header", [True, False])
def test_a_euroc_groundtruth_row_cut_mid_line_is_refused(tmp_path, original, capsys, header):
    """A ground-truth row of 10 of the header's 17 cells (a copy or a recording that stopped
    mid-line) was imported as a pose; so was one shorter than the rows before it in a file without
    a header. Refused in one line naming the file, the row and the rule."""
    seq, _ = original
    exported = export_sequence(seq.root, "euroc", tmp_path / "exported")
    gt = exported / "mav0" / "state_groundtruth_estimate0" / "data.csv"
    lines = gt.read_text().splitlines()
    assert lines[0].startswith("#timestamp") and len(lines[0].split(",")) == 17
    if not header:
        del lines[0]
    row = len(lines)
    lines[-1] = ",".join(lines[-1].split(",")[:10])  # the last row cut after its 10th cell
    gt.write_text("\n".join(lines) + "\n")
    out = tmp_path / "imported"
    assert main(["import", str(exported), "-o", str(out), "--height-mm", "100"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    names = "the header (line 1) names 17" if header else "the first row (line 1) has 17"
    assert len(err) == 1 and f"{gt}:{row}: a row of 10 cells, where {names}: every row has a cell" in err[0], err
    assert not out.exists()


def test_left_only_leaves_a_bags_right_topic_out(tmp_path, original, capsys):
    seq, _ = original
    exported = export_sequence(seq.root, "rosbag2", tmp_path / "exported")
    assert main(["import", str(exported), "-o", str(tmp_path / "imported"), "--left-only"]) == 0
    imp = Sequence.open(tmp_path / "imported")
    assert not imp.has_stereo and imp.frame_count == 8


def test_a_ros2_bag_folder_named_dot_bag_is_read_as_the_ros2_bag_it_is(tmp_path, original, capsys):
    """rosbags' AnyReader takes any path ending in .bag for a ROS 1 bag file: a ROS 2 bag folder
    named rec.bag (an export -o rec.bag) was refused ('not a readable ROS 2 bag (... Is a directory)')."""
    seq, _ = original
    exported = export_sequence(seq.root, "rosbag2", tmp_path / "rec.bag")
    assert main(["import", str(exported), "-o", str(tmp_path / "imported"), "--left-only"]) == 0, capsys.readouterr()
    imp = Sequence.open(tmp_path / "imported")
    assert imp.frame_count == 8
    np.testing.assert_array_equal(imp.image(5), seq.image(5))


def _bag_without(src, dst, topic: str, k: int, keep_bytes: int | None = None) -> None:
    """Copy the ROS 2 bag ``src`` to ``dst`` leaving out the ``k``-th message of ``topic``, or
    with only its first ``keep_bytes`` bytes (a message cut short)."""
    from rosbags.rosbag2 import Reader, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    with Reader(src) as r, Writer(dst, version=9) as w:
        conns = {c.id: w.add_connection(c.topic, c.msgtype, typestore=ts) for c in r.connections}
        seen = 0
        for c, t, raw in r.messages():
            if c.topic == topic:
                seen += 1
                if seen - 1 == k:
                    if keep_bytes is None:
                        continue
                    raw = raw[:keep_bytes]
            w.write(conns[c.id], t, raw)


@pytest.mark.parametrize(("topic", "k"), [("/cam0/image_raw", 5), ("/cam0/camera_info", 0)])
def test_a_bag_message_cut_short_is_refused_in_one_line(tmp_path, original, capsys, topic, k):
    """A message rosbags cannot deserialize (cut to 50 bytes) raised its AnyReaderError as a
    25-line traceback."""
    seq, _ = original
    exported = export_sequence(seq.root, "rosbag2", tmp_path / "exported")
    _bag_without(exported, tmp_path / "cut", topic, k, keep_bytes=50)
    out = tmp_path / "imported"
    assert main(["import", str(tmp_path / "cut"), "-o", str(out), "--height-mm", "100"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert f"{topic}: the message at " in err[0] and "ns (bag time) cannot be read as sensor_msgs/msg/" in err[0]
    assert not out.exists()


def test_a_bags_left_image_without_a_right_one_is_refused_unless_left_only(tmp_path, original, capsys, caplog):
    """A left image without its right partner was left out under a warning: a stereo sequence
    with a gap, exit code 0. It is refused in one line, as EuRoC's cam1 rows are; --left-only
    imports the left camera alone. A left image without its depth partner is left out, said
    in one line."""
    seq, _ = original
    exported = export_sequence(seq.root, "rosbag2", tmp_path / "exported")
    _bag_without(exported, tmp_path / "no_right", "/cam1/image_raw", 3)
    out = tmp_path / "imported"
    assert main(["import", str(tmp_path / "no_right"), "-o", str(out), "--height-mm", "100"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    stamp = int(round(seq.timestamps_s[3] * 1e9))
    assert "1 of 8 images have no /cam1/image_raw message within 1 ms (the first: image 3 at" in err[0]
    assert f"at {stamp} ns): a stereo recording needs a right image at each left image's stamp" in err[0]
    assert "give --left-only to import the left camera alone" in err[0]
    assert not out.exists()
    assert main(["import", str(tmp_path / "no_right"), "-o", str(out), "--height-mm", "100", "--left-only"]) == 0
    assert Sequence.open(out).frame_count == 8 and not Sequence.open(out).has_stereo
    _bag_without(exported, tmp_path / "no_depth", "/cam0/depth", 5)
    assert main(["import", str(tmp_path / "no_depth"), "-o", str(tmp_path / "d"), "--height-mm", "100"]) == 0
    assert Sequence.open(tmp_path / "d").frame_count == 7
    assert "1 of 8 images have no /cam0/depth message within 1 ms (the first: image 5 at" in caplog.text


@pytest.mark.parametrize("fmt", ["euroc", "rosbag2"])
def test_an_export_carries_the_flat_fields_heights_and_rig_height_back(tmp_path, capsys, fmt):
    """Both exports named the flat field, height.csv and the rig height as left out, and an import
    without three flags lost them. EuRoC carries them in sidecars (``camN/flatfield.png``,
    ``height0/``, ``camera_height_mm`` in cam0's sensor.yaml), the bag in topics
    (``/camN/flatfield``, ``/cam0/height`` Range) and its custom data; the import reads them back."""
    from floorvo.sequence import SequenceWriter

    T = line_poses(12.0, 4.0, 87.5)
    root = write_synthetic_sequence(
        tmp_path / "seq", CAM, T, height_mm=87.5, stereo_baseline_mm=10.0, height_noise_mm=0.2, seed=2
    )
    h = Sequence.open(root).height_signal_mm
    h[1] = np.nan  # a frame without a reading
    with SequenceWriter(root, Sequence.open(root).meta, overwrite=True) as w:
        w.write_heights(h)
    seq = Sequence.open(root)
    exported = export_sequence(root, fmt, tmp_path / "exported")
    capsys.readouterr()
    out = tmp_path / "imported"
    assert main(["import", str(exported), "-o", str(out)]) == 0
    assert "no --height-mm" not in capsys.readouterr().out
    imp = Sequence.open(out)
    assert imp.height_mm == 87.5 and imp.has_stereo and imp.frame_count == 4
    np.testing.assert_array_equal(imp.flatfield("cam0"), seq.flatfield("cam0"))
    np.testing.assert_array_equal(imp.flatfield("cam1"), seq.flatfield("cam1"))
    assert np.isnan(imp.height_signal_mm[1])
    # EuRoC's CSV holds the file's decimals; a bag's Range holds float32 metres (1e-5 mm)
    np.testing.assert_allclose(imp.height_signal_mm, seq.height_signal_mm, rtol=0, atol=0 if fmt == "euroc" else 1e-4)
    # and the readings' stated noise (rig.height_noise_mm), which the runner holds the steps to
    assert seq.height_noise_mm == 0.2 and imp.height_noise_mm == 0.2
    for i in range(seq.frame_count):
        np.testing.assert_array_equal(imp.image(i), seq.image(i))
    # a flag still wins over what the export carried
    flat_given = tmp_path / "flat.png"
    cv2.imwrite(str(flat_given), np.full((CAM.height_px, CAM.width_px), 77, np.uint8))
    argv = [
        "import",
        str(exported),
        "-o",
        str(tmp_path / "flagged"),
        "--height-mm",
        "90",
        "--flatfield",
        str(flat_given),
    ]
    assert main(argv) == 0
    flagged = Sequence.open(tmp_path / "flagged")
    assert flagged.height_mm == 90.0 and int(flagged.flatfield("cam0").max()) == 77
    assert flagged.flatfield("cam1") is None  # the source's is 16-bit: sequence.json states one bit depth
    assert flagged.height_noise_mm == 0.2  # the source's readings, and their noise
    # readings of the user's own replace the source's: the source's noise is not theirs
    argv_h = [*argv[:3], str(tmp_path / "own_heights"), "--height-file", str(out / "height.csv")]
    assert main(argv_h) == 0
    assert Sequence.open(tmp_path / "own_heights").height_noise_mm is None
    if fmt != "euroc":
        return
    noise = exported / "mav0" / "height0" / "sensor.yaml"
    kept = noise.read_text()
    noise.write_text(kept.replace("noise_mm: 0.2", "noise_mm: .nan"))
    assert main(["import", str(exported), "-o", str(tmp_path / "bad")]) == 1
    err = capsys.readouterr().err.strip()
    assert err.endswith("height0/sensor.yaml: noise_mm = nan: must be a finite number of mm >= 0 and at most 20000"), (
        err
    )
    noise.write_text(kept.replace("noise_mm: 0.2", "noise_mm: 1.0e+9"))  # was blamed on the output's sequence.json
    assert main(["import", str(exported), "-o", str(tmp_path / "bad")]) == 1
    err = capsys.readouterr().err.strip()
    assert err.endswith(
        "height0/sensor.yaml: noise_mm = 1000000000.0: must be a finite number of mm >= 0 and at most 20000"
    ), err
    noise.write_text(kept)
    # a sidecar row at no frame's stamp is refused in one line, before anything is written
    csv_path = exported / "mav0" / "height0" / "data.csv"
    csv_path.write_text(csv_path.read_text() + "17,88.0\n")
    assert main(["import", str(exported), "-o", str(tmp_path / "bad")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "height0/data.csv:6: 17 ns is the stamp of no cam0 frame" in err[0], err
    assert not (tmp_path / "bad").exists()
    csv_path.unlink()
    sensor = exported / "mav0" / "cam0" / "sensor.yaml"
    sensor.write_text(sensor.read_text().replace("camera_height_mm: 87.5", "camera_height_mm: -87.5"))
    assert main(["import", str(exported), "-o", str(tmp_path / "bad")]) == 1
    err = capsys.readouterr().err.strip()
    assert err.endswith("cam0/sensor.yaml: camera_height_mm = -87.5: must be a finite number of mm > 0"), err
    # the flag that replaces a damaged sidecar is enough
    assert main(["import", str(exported), "-o", str(tmp_path / "fixed"), "--height-mm", "87.5"]) == 0


def test_a_euroc_export_carries_the_attitude_back_and_a_bag_says_it_left_it_out(tmp_path, capsys, caplog):
    """attitude.csv (an IMU's roll and pitch, a frame without a reading) goes to EuRoC's
    ``mav0/attitude0/data.csv`` and comes back from ``floorvo import`` to the digit; a ROS 2 bag
    has no message for it yet, and the export says so."""
    from floorvo.geometry import T_world_cam_down, attitude_of_T
    from floorvo.sequence import SequenceWriter

    T = np.stack([T_world_cam_down(4.0 * i, 0.0, 100.0, 0.0, 0.01 * i, -0.005 * i) for i in range(4)])
    root = write_synthetic_sequence(tmp_path / "seq", CAM, T, attitude_noise_rad=0.001, seed=2)
    a = Sequence.open(root).attitude_signal_rad
    a[2] = np.nan
    with SequenceWriter(root, Sequence.open(root).meta) as w:
        w.write_attitude(a)
    exported = export_sequence(root, "euroc", tmp_path / "exported")
    assert (exported / "mav0" / "attitude0" / "data.csv").is_file()
    assert main(["import", str(exported), "-o", str(tmp_path / "imported"), "--height-mm", "100"]) == 0
    imp = Sequence.open(tmp_path / "imported").attitude_signal_rad
    np.testing.assert_array_equal(imp, a)
    assert np.abs(np.delete(imp, 2, 0) - np.delete(attitude_of_T(T), 2, 0)).max() < 0.005
    caplog.clear()
    export_sequence(root, "rosbag2", tmp_path / "bag")
    assert any("attitude.csv is left out of the ROS 2 bag" in r.getMessage() for r in caplog.records)


def test_a_euroc_export_says_it_leaves_the_depth_images_out(tmp_path, original, caplog):
    """The EuRoC layout has no depth stream: the export dropped depth/ without a word, and orb-icp
    could not run on what came back. The bag carries it (/cam0/depth)."""
    seq, _ = original
    export_sequence(seq.root, "euroc", tmp_path / "e")
    assert any("depth images are left out of the EuRoC export" in r.getMessage() for r in caplog.records)
    caplog.clear()
    export_sequence(seq.root, "rosbag2", tmp_path / "b")
    assert not any("depth" in r.getMessage() for r in caplog.records)


def test_an_export_says_it_leaves_the_rigs_led_positions_out(tmp_path, original, caplog):
    """Neither format carries rig.led_positions_cam_mm, which homography-6dof's lights check
    reads: on the copy it ran in another mode, without a word."""
    import json
    import shutil

    seq, _ = original
    root = tmp_path / "seq"
    shutil.copytree(seq.root, root)
    meta = json.loads((root / "sequence.json").read_text())
    meta["rig"]["led_positions_cam_mm"] = [[-70.0, -20.0, 97.0], [-70.0, 20.0, 97.0]]
    (root / "sequence.json").write_text(json.dumps(meta))
    for fmt in ("euroc", "rosbag2"):
        caplog.clear()
        export_sequence(root, fmt, tmp_path / fmt)
        assert any("LED positions (rig.led_positions_cam_mm) are left out" in r.getMessage() for r in caplog.records)
    caplog.clear()
    export_sequence(seq.root, "euroc", tmp_path / "plain")
    assert not any("LED positions" in r.getMessage() for r in caplog.records)


def _recording(root, gt_times_s, frame_times_s=None):
    """An imported-like sequence folder (not simulated: its ground truth may be at another rate than
    its 8 frames, 16-bit, stereo): frames at ``frame_times_s`` (default about 30 Hz at a Unix time,
    unevenly spaced), a distinct pose at each of ``gt_times_s``. Returns the sequence."""
    from floorvo.geometry import T_world_cam_down
    from floorvo.sequence import SequenceWriter

    cam = CameraModel(40, 30, 50.0, 51.0, 19.5, 14.5)
    ts = 1_700_000_000.0 + np.cumsum([0.0, 0.0333, 0.0334, 0.05, 0.0331, 0.0333, 0.0335, 0.0333])
    ts = ts if frame_times_s is None else np.asarray(frame_times_s)
    meta = {
        "camera": cam.to_dict(),
        "fps": 30.0,
        "frame_count": 8,
        "bit_depth": 16,
        "stereo": True,
        "cameras": {"cam1": cam.to_dict()},
        "rig": {"height_mm": 100.0, "T_cam0_cam1": [[1, 0, 0, 20.0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]},
        "source": {"format": "euroc"},
    }
    rng = np.random.default_rng(3)
    with SequenceWriter(root, meta) as w:
        w.write_timestamps(ts)
        for i in range(8):
            for c in ("cam0", "cam1"):
                w.write_frame(i, rng.integers(0, 65536, (30, 40), dtype=np.uint16), c)
        T = [T_world_cam_down(7.0 * k, -3.0 * k, 100.0 + k, 0.01 * k) for k in range(len(gt_times_s))]
        w.write_groundtruth(np.asarray(gt_times_s), np.stack(T))
    return Sequence.open(root)


@pytest.mark.parametrize("fmt", ["euroc", "rosbag2"])
@pytest.mark.parametrize("gt_rate", ["200 Hz over part of the run", "10 Hz"])
def test_ground_truth_at_another_rate_than_the_frames_comes_back_as_it_was(tmp_path, fmt, gt_rate):
    """A recording's ground truth at its own rate (a motion-capture system): the bag held one pose
    per frame, the pose of the frame's index stamped with the frame's time (poses 0-7 of 200 Hz
    ground truth put at the frames' times, 30 Hz apart, with exit code 0), and ended in an
    IndexError where there were fewer poses than frames. Each pose goes at its own time."""
    t0 = 1_700_000_000.0
    t_gt = t0 + 0.02 + 0.005 * np.arange(30) if gt_rate.startswith("200") else t0 + 0.1 * np.arange(3)
    seq = _recording(tmp_path / "seq", t_gt)
    exported = export_sequence(seq.root, fmt, tmp_path / "exported")
    assert main(["import", str(exported), "-o", str(tmp_path / "imported")]) == 0
    t_back, T_back = Sequence.open(tmp_path / "imported").groundtruth()
    t_ref, T_ref = seq.groundtruth()
    np.testing.assert_array_equal(np.round(t_back * 1e6), np.round(t_ref * 1e6))  # TUM holds microseconds
    np.testing.assert_allclose(T_back, T_ref, rtol=0, atol=1e-6)


def _euroc_stamps(folder, cam="cam0"):
    """The stamps (ns) of a EuRoC folder's camera ``data.csv``, as written."""
    rows = (folder / "mav0" / cam / "data.csv").read_text().splitlines()[1:]
    return [int(r.split(",")[0]) for r in rows]


@pytest.mark.parametrize("via", ["euroc", "rosbag2"])
def test_a_recordings_nanosecond_stamps_come_back_to_the_nanosecond(tmp_path, via):
    """EuRoC and ROS stamp frames in integer nanoseconds; a float of seconds holds a Unix time only
    to about 240 ns. An import wrote ``f"{t:.9f}"`` of such a float and an export stamped
    ``round(t * 1e9)`` of one: each pass moved every stamp by 256 ns (1403636579763555584 ->
    1403636579763555840). A EuRoC recording imported, exported (as EuRoC, or as a bag imported
    again) and exported as EuRoC has its own stamps, file names and ground-truth rows."""
    seq = _recording(tmp_path / "seq", [1_700_000_000.0])
    src = export_sequence(seq.root, "euroc", tmp_path / "src")
    stamps = [1403636579763555584 + 33_333_333 * k + 7 * k * k for k in range(8)]  # odd nanoseconds
    for cam in ("cam0", "cam1"):
        old = _euroc_stamps(src, cam)
        for a, b in zip(old, stamps):
            (src / "mav0" / cam / "data" / f"{a}.png").rename(src / "mav0" / cam / "data" / f"{b}.png")
        (src / "mav0" / cam / "data.csv").write_text(
            "#timestamp [ns],filename\n" + "".join(f"{b},{b}.png\n" for b in stamps)
        )
    gt = src / "mav0" / "state_groundtruth_estimate0" / "data.csv"
    header, row = gt.read_text().splitlines()[:2]
    gt.write_text(header + "\n" + "".join(f"{b}," + row.split(",", 1)[1] + "\n" for b in stamps[1:4]))
    assert main(["import", str(src), "-o", str(tmp_path / "imp")]) == 0
    again = tmp_path / "imp"
    if via == "rosbag2":
        export_sequence(again, "rosbag2", tmp_path / "bag")
        assert main(["import", str(tmp_path / "bag"), "-o", str(tmp_path / "imp2")]) == 0
        again = tmp_path / "imp2"
    out = export_sequence(again, "euroc", tmp_path / "out")
    assert _euroc_stamps(out) == stamps and _euroc_stamps(out, "cam1") == stamps
    assert sorted(p.name for p in (out / "mav0" / "cam0" / "data").iterdir()) == sorted(f"{b}.png" for b in stamps)
    rows = (out / "mav0" / "state_groundtruth_estimate0" / "data.csv").read_text().splitlines()[1:]
    assert [int(r.split(",")[0]) for r in rows] == stamps[1:4]  # at their frames' stamps


def test_frame_times_given_in_microseconds_are_exported_to_the_microsecond(tmp_path):
    """A timestamps file in seconds with six decimals at a Unix time: ``timestamps.txt`` held
    ``f"{t:.9f}"`` of the float (1700000000.066600084) and the export stamped those 84 ns; it holds
    the shortest decimal of the float (1700000000.0666), and the export stamps what was given."""
    given = [f"1700000000.{k * 33300 + 17:06d}" for k in range(8)]
    seq = _recording(tmp_path / "seq", [1_700_000_000.0], [float(t) for t in given])
    assert (seq.root / "timestamps.txt").read_text().splitlines()[1:] == [t.rstrip("0") for t in given]
    out = export_sequence(seq.root, "euroc", tmp_path / "out")
    assert _euroc_stamps(out) == [int(t.replace(".", "")) * 1000 for t in given]


@pytest.mark.parametrize("fmt", ["euroc", "rosbag2"])
def test_the_frame_rate_comes_back_as_it_was(tmp_path, fmt, capsys):
    """A bag has no field for the frame rate: a 30 Hz recording with uneven frame times came back at
    the 30.03 Hz of their median spacing. The bag carries it in its custom data (EuRoC in
    ``rate_hz``); one there that is no rate is refused in one line."""
    seq = _recording(tmp_path / "seq", [1_700_000_000.0])
    exported = export_sequence(seq.root, fmt, tmp_path / "exported")
    assert main(["import", str(exported), "-o", str(tmp_path / "imported")]) == 0
    assert Sequence.open(tmp_path / "imported").fps == 30.0
    if fmt == "rosbag2":
        meta = exported / "metadata.yaml"
        meta.write_text(meta.read_text().replace("floorbench.fps: '30.0'", "floorbench.fps: '-30'"))
        capsys.readouterr()
        assert main(["import", str(exported), "-o", str(tmp_path / "bad")]) == 1
        err = capsys.readouterr().err.strip()
        assert err.endswith(
            "metadata.yaml: custom_data floorbench.fps = '-30': must be a number of Hz > 0 and at most 1e+06"
        )
        assert not (tmp_path / "bad").exists()


def test_a_bag_reading_goes_to_its_own_frame_when_frames_are_under_a_millisecond_apart():
    """Frames 0.4 and 0.6 ms apart, the third without a height reading: it took the fourth
    frame's reading (the nearest unused within 1 ms), and the fourth then had none, without a word."""
    from floorvo.importers.rosbag2 import _pair

    frames = np.array([0, 400_000, 1_000_000, 1_400_000, 2_000_000], dtype=np.int64)  # ns
    readings = frames[[0, 1, 3, 4]]
    assert _pair(frames, readings) == {0: 0, 400_000: 400_000, 1_400_000: 1_400_000, 2_000_000: 2_000_000}
    # readings a little off their frames' stamps still pair, each with its own frame
    shifted = {int(r) + 50_000: int(r) for r in readings}
    assert _pair(frames, readings + 50_000) == shifted


@pytest.mark.parametrize("fmt", ["euroc", "rosbag2"])
def test_an_export_carries_a_rolling_shutters_readout_back(tmp_path, capsys, fmt):
    """A sequence taken by a rolling shutter states its readout (``sensor.readout_ms``), which the
    estimators undo; an export that dropped it came back as a global shutter's, and every step
    along the rows read long. EuRoC carries it in cam0's sensor.yaml, the bag in its custom data;
    ``--readout-ms`` still wins, and a global shutter's export states none."""
    import json

    root = write_synthetic_sequence(tmp_path / "seq", CAM, line_poses(12.0, 4.0, 100.0), seed=2)
    assert Sequence.open(root).readout_ms == 0.0
    exported = export_sequence(root, fmt, tmp_path / "exported_global")
    assert main(["import", str(exported), "-o", str(tmp_path / "imported_global")]) == 0
    assert Sequence.open(tmp_path / "imported_global").readout_ms == 0.0
    meta = json.loads((root / "sequence.json").read_text(encoding="utf-8"))
    meta["sensor"] = {"shutter": "rolling", "readout_ms": 12.5}
    (root / "sequence.json").write_text(json.dumps(meta), encoding="utf-8")
    assert Sequence.open(root).readout_ms == 12.5
    exported = export_sequence(root, fmt, tmp_path / "exported")
    capsys.readouterr()
    assert main(["import", str(exported), "-o", str(tmp_path / "imported")]) == 0
    imp = Sequence.open(tmp_path / "imported")
    assert imp.readout_ms == 12.5 and imp.row_time_s == pytest.approx(Sequence.open(root).row_time_s)
    assert main(["import", str(exported), "-o", str(tmp_path / "given"), "--readout-ms", "5"]) == 0
    assert Sequence.open(tmp_path / "given").readout_ms == 5.0


def test_a_euroc_readout_that_cannot_be_is_refused_in_one_line(tmp_path, capsys):
    """cam0's sensor.yaml ``readout_ms``: a negative one, or one longer than a frame interval, is
    refused in one line naming the file or the source, exit 1, and nothing is written."""
    root = write_synthetic_sequence(tmp_path / "seq", CAM, line_poses(12.0, 4.0, 100.0), seed=2)
    exported = export_sequence(root, "euroc", tmp_path / "exported")
    sensor = exported / "mav0" / "cam0" / "sensor.yaml"
    text = sensor.read_text(encoding="utf-8")
    assert "readout_ms" not in text  # a global shutter's export states none
    for value, says in (
        ("-3.0", "readout_ms = -3.0: must be a finite number of ms >= 0"),
        ("40.0", "readout_ms = 40.0: must be a rolling shutter's readout in ms, 0 to the shortest frame interval"),
    ):
        sensor.write_text(text.rstrip("\n") + f"\nreadout_ms: {value}\n", encoding="utf-8")
        capsys.readouterr()
        assert main(["import", str(exported), "-o", str(tmp_path / "imported")]) == 1
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and says in err, err
        assert not (tmp_path / "imported").exists()

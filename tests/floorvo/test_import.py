"""floorvo import: image folders, videos, hand-made ROS 2 bags, camera files; each imports and runs.

Inputs are made in the test from a synthetic sequence (:mod:`floorvo.synthetic`), whose
ground truth is exact, so an imported sequence is checked frame by frame against what was
written and its run against the same ground truth.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from floorvo.camera import CameraModel
from floorvo.cli import main
from floorvo.errors import ConfigError, SequenceError
from floorvo.geometry import xyz_quat_from_T
from floorvo.importers import ImportOptions, detect_format, import_sequence
from floorvo.importers.camera_files import read_camera_file
from floorvo.importers.recording import natural_key
from floorvo.sequence import Sequence
from floorvo.synthetic import line_poses, write_synthetic_sequence
from floorvo.tum import read_tum, write_tum

CAM = CameraModel.from_sensor(162, 124, pixel_pitch_um=29.6, focal_length_mm=6.0)  # GSD 0.4933 mm at 100 mm
FLAGS = ["--fx", str(CAM.fx_px), "--fy", str(CAM.fy_px), "--cx", str(CAM.cx_px), "--cy", str(CAM.cy_px)]


@pytest.fixture(scope="module")
def synth(tmp_path_factory):
    """A 7-frame synthetic line (4 mm steps, turning 0.5 deg a frame) with exact ground truth."""
    root = tmp_path_factory.mktemp("synth") / "seq"
    T = line_poses(24.0, 4.0, 100.0, yaw_step_rad=np.radians(0.5))
    write_synthetic_sequence(root, CAM, T, seed=3)
    seq = Sequence.open(root)
    return seq, [seq.image(i) for i in range(seq.frame_count)], T


def _one_line_error(capsys, argv) -> str:
    rc = main(argv)
    err = capsys.readouterr().err.strip()
    assert rc == 1, err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


def _end_error_mm(run_dir, T_true) -> float:
    _, Te = read_tum(run_dir / "trajectory.txt")
    return float(np.linalg.norm(Te[-1][:3, 3] - T_true[-1][:3, 3]))


# ----------------------------------------------------------------------------- image folders
def test_natural_order():
    names = ["img_10.png", "img_2.png", "img_1.png", "IMG_0003.png", "img_1b.png"]
    assert sorted(names, key=natural_key) == ["img_1.png", "img_1b.png", "img_2.png", "IMG_0003.png", "img_10.png"]


def test_image_folder_with_timestamps_file_imports_and_runs(tmp_path, synth, capsys):
    """Names like img_1.png .. img_7.png (unpadded: natural order), a timestamps file with uneven spacing."""
    seq, frames, T = synth
    src = tmp_path / "frames"
    src.mkdir()
    for i, img in enumerate(frames):
        cv2.imwrite(str(src / f"img_{i + 1}.png"), img)
    (src / "notes.txt").write_text("not a frame")
    stamps = 1700000000.0 + np.cumsum([0.0, 0.031, 0.035, 0.033, 0.030, 0.036, 0.034])
    (tmp_path / "times.txt").write_text("# t [s]\n" + "".join(f"{t:.6f}\n" for t in stamps))
    write_tum(tmp_path / "gt.txt", stamps, T)  # the synthetic ground truth, on the recording's clock
    out = tmp_path / "imp"
    argv = ["import", str(src), "-o", str(out), *FLAGS, "--height-mm", "100"]
    argv += ["--timestamps", str(tmp_path / "times.txt"), "--groundtruth", str(tmp_path / "gt.txt")]
    assert main(argv) == 0
    assert "images: 7 frames 162x124 8-bit" in capsys.readouterr().out
    imp = Sequence.open(out)
    assert imp.meta["source"]["format"] == "images" and imp.frame_count == 7
    np.testing.assert_allclose(imp.timestamps_s, stamps, atol=1e-6)
    for i in range(7):
        np.testing.assert_array_equal(imp.image(i), frames[i])
    np.testing.assert_allclose(imp.camera.K, CAM.K)
    assert main(["run", str(out), "-e", "phase-corr", "-o", str(tmp_path / "run")]) == 0
    t_run, T_run = read_tum(tmp_path / "run" / "trajectory.txt")
    np.testing.assert_allclose(t_run, stamps, atol=1e-6)  # the run is stamped with the recording's times
    np.testing.assert_allclose(T_run[0], T[0], atol=1e-9)  # and starts at its ground truth
    assert _end_error_mm(tmp_path / "run", T) < 0.2
    assert main(["score", str(tmp_path / "run"), "--gt", str(out)]) == 0
    score = json.loads((tmp_path / "run" / "score.json").read_text())
    assert score["n_matched"] == 7


def test_a_timestamps_file_in_nanoseconds_is_written_to_the_nanosecond(tmp_path, synth):
    """``--timestamps FILE --time-unit ns`` with a recording's Unix nanoseconds: the sequence holds
    them exactly (they went through a float of seconds, good to about 240 ns: 1700000000123456789
    became ...123456716), as the EuRoC and bag readers' do."""
    _, frames, _ = synth
    src = tmp_path / "frames"
    src.mkdir()
    for i, img in enumerate(frames):
        cv2.imwrite(str(src / f"{i:03d}.png"), img)
    stamps_ns = [1_700_000_000_123_456_789 + 33_333_333 * i + 7 * i * i for i in range(len(frames))]
    (tmp_path / "t.txt").write_text("".join(f"{n}\n" for n in stamps_ns))
    out = tmp_path / "imp"
    argv = ["import", str(src), "-o", str(out), *FLAGS, "--timestamps", str(tmp_path / "t.txt"), "--time-unit", "ns"]
    assert main(argv) == 0
    assert Sequence.open(out).timestamps_ns == stamps_ns


def _strict_json(path):
    """The JSON file at ``path`` read as a strict reader reads it: UTF-8 text without lone surrogates."""
    data = json.loads(path.read_bytes().decode("utf-8"))

    def check(obj):
        if isinstance(obj, str):
            obj.encode("utf-8")  # a lone surrogate (the escape \\udcff) raises here
        elif isinstance(obj, dict):
            for k, v in obj.items():
                check(k)
                check(v)
        elif isinstance(obj, list):
            for v in obj:
                check(v)

    check(data)
    return data


def test_file_names_that_are_not_utf8_are_written_escaped(tmp_path, synth, capsys):
    """An image named b"f\\xff0.png" (a byte that is not UTF-8, held by Python as the lone surrogate
    U+DCFF) was written into sequence.json as the escape \\udcff, which strict JSON readers refuse;
    so was a sequence or run folder of such a name into result.json and score.json. Such a byte is
    written as the text \\xff now (floorvo.io.path_text), the import resumes, and the run and the
    score read the folders they were given."""
    _, frames, _ = synth
    src = Path(os.fsdecode(bytes(tmp_path) + b"/fr\xfeames"))
    src.mkdir()
    for i, img in enumerate(frames[:3]):
        ok, buf = cv2.imencode(".png", img)
        Path(os.fsdecode(bytes(src) + f"/f\xff{i}.png".encode("latin-1"))).write_bytes(buf.tobytes())
    out = Path(os.fsdecode(bytes(tmp_path) + b"/s\xfe"))
    argv = ["import", str(src), "-o", str(out), *FLAGS, "--height-mm", "100", "--fps", "10"]
    assert main(argv) == 0
    meta = _strict_json(out / "sequence.json")
    assert meta["source"]["first_file"] == "f\\xff0.png" and meta["source"]["last_file"] == "f\\xff2.png"
    assert meta["source"]["path"].endswith("/fr\\xfeames")
    assert main(argv) == 0  # the same import again resumes: what it compares is written the same way
    capsys.readouterr()
    run = Path(os.fsdecode(bytes(tmp_path) + b"/run\xfe"))
    assert main(["run", str(out), "-e", "phase-corr", "-o", str(run)]) == 0
    assert _strict_json(run / "result.json")["sequence"].endswith("/s\\xfe")
    assert main(["score", str(run), "--gt", str(out)]) == 0
    _strict_json(run / "score.json")


def test_path_text_escapes_only_what_is_not_utf8(tmp_path):
    """Valid text is kept (accents too); an undecodable byte becomes \\xHH, another lone surrogate
    \\udXXX; every JSON and CSV writer writes text through it, keys included."""
    from floorvo.io import atomic_write_csv, atomic_write_json, path_text

    assert path_text("sol_\u00e9t\u00e9/f0.png") == "sol_\u00e9t\u00e9/f0.png"
    assert path_text(Path("a/f\udcff0.png")) == "a/f\\xff0.png"
    assert path_text("x\ud800") == "x\\ud800"
    atomic_write_json(tmp_path / "a.json", {"f\udcff": ["g\udcfe", Path("h\udcfd")]})
    assert _strict_json(tmp_path / "a.json") == {"f\\xff": ["g\\xfe", "h\\xfd"]}
    atomic_write_csv(tmp_path / "a.csv", ["name"], [["f\udcff0.png"]])  # was a UnicodeEncodeError
    assert (tmp_path / "a.csv").read_text(encoding="utf-8") == "name\nf\\xff0.png\n"


def test_list_file_colour_jpeg_and_16_bit(tmp_path, synth):
    """A TUM-style list (TIMESTAMP PATH) of colour frames; a 16-bit TIFF folder keeps 16 bits."""
    _, frames, _ = synth
    rgb = [np.dstack([f, np.roll(f, 3, axis=1), 255 - f]) for f in frames[:3]]
    (tmp_path / "rgb").mkdir()
    lines = []
    for i, img in enumerate(rgb):
        cv2.imwrite(str(tmp_path / "rgb" / f"{i}.bmp"), img)
        lines.append(f"{10 + 0.1 * i:.1f} rgb/{i}.bmp")
    (tmp_path / "rgb.txt").write_text("# timestamp filename\n" + "\n".join(lines) + "\n")
    assert detect_format(tmp_path / "rgb.txt") == "images"
    res = import_sequence(
        tmp_path / "rgb.txt",
        tmp_path / "a",
        options=ImportOptions(calibration=None, fps=None, intrinsics=(200.0, 200.0, 80.5, 61.5)),
    )
    a = Sequence.open(tmp_path / "a")
    assert res.bit_depth == 8 and a.frame_count == 3
    np.testing.assert_allclose(a.timestamps_s, [10.0, 10.1, 10.2])
    np.testing.assert_array_equal(a.image(1), cv2.cvtColor(rgb[1], cv2.COLOR_BGR2GRAY))

    (tmp_path / "deep").mkdir()
    deep = [f.astype(np.uint16) * 257 + i for i, f in enumerate(frames[:3])]
    for i, img in enumerate(deep):
        cv2.imwrite(str(tmp_path / "deep" / f"f{i:04d}.tif"), img)
    res = import_sequence(
        tmp_path / "deep", tmp_path / "b", options=ImportOptions(intrinsics=(200.0, 200.0, 80.5, 61.5), fps=25.0)
    )
    b = Sequence.open(tmp_path / "b")
    assert res.bit_depth == 16 and b.meta["bit_depth"] == 16
    np.testing.assert_array_equal(b.image(2), deep[2])
    np.testing.assert_allclose(b.timestamps_s, np.arange(3) / 25.0)


def test_jpeg_folder_imports_and_runs(tmp_path, synth):
    """Lossy JPEG frames still track (the codec changes pixels, not the geometry)."""
    _, frames, T = synth
    (tmp_path / "jpg").mkdir()
    for i, img in enumerate(frames):
        cv2.imwrite(str(tmp_path / "jpg" / f"img_{i:04d}.jpg"), img, [cv2.IMWRITE_JPEG_QUALITY, 95])
    import_sequence(
        tmp_path / "jpg",
        tmp_path / "s",
        options=ImportOptions(intrinsics=(CAM.fx_px, CAM.fy_px, CAM.cx_px, CAM.cy_px), height_mm=100.0, fps=30.0),
    )
    from floorvo.run import run_estimator

    res = run_estimator(tmp_path / "s", "phase-corr", tmp_path / "run")
    assert res.ok == len(T) - 1
    _, Te = read_tum(tmp_path / "run" / "trajectory.txt")
    step = np.linalg.norm(Te[-1][:3, 3] - Te[0][:3, 3])  # no ground truth: starts at the identity
    assert step == pytest.approx(np.linalg.norm(T[-1][:3, 3] - T[0][:3, 3]), rel=0.01)


# ----------------------------------------------------------------------------- video
def test_video_imports_with_its_frame_times_and_runs(tmp_path, synth):
    _, frames, T = synth
    path = tmp_path / "clip.avi"
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"FFV1"), 10.0, (CAM.width_px, CAM.height_px), isColor=False)
    assert w.isOpened()
    for f in frames:
        w.write(f)
    w.release()
    assert detect_format(path) == "video"
    res = import_sequence(
        path,
        tmp_path / "s",
        options=ImportOptions(intrinsics=(CAM.fx_px, CAM.fy_px, CAM.cx_px, CAM.cy_px), height_mm=100.0),
    )
    s = Sequence.open(tmp_path / "s")
    assert res.frames == 7 and s.fps == 10.0
    np.testing.assert_allclose(s.timestamps_s, np.arange(7) / 10.0, atol=1e-6)
    for i in (0, 6):
        np.testing.assert_array_equal(s.image(i), frames[i])  # FFV1 is lossless
    from floorvo.run import run_estimator

    run_estimator(s, "phase-corr", tmp_path / "run")
    t_run, Te = read_tum(tmp_path / "run" / "trajectory.txt")
    np.testing.assert_allclose(t_run, np.arange(7) / 10.0, atol=1e-6)
    moved = np.linalg.norm(Te[-1][:3, 3] - Te[0][:3, 3])
    assert moved == pytest.approx(np.linalg.norm(T[-1][:3, 3] - T[0][:3, 3]), rel=0.005)
    # with frame times given at 2 Hz, the nominal rate is theirs, not the container's 10 Hz
    res = import_sequence(
        path,
        tmp_path / "s2",
        options=ImportOptions(
            intrinsics=(CAM.fx_px, CAM.fy_px, CAM.cx_px, CAM.cy_px), height_mm=100.0, timestamps_s=np.arange(7) / 2.0
        ),
    )
    s2 = Sequence.open(tmp_path / "s2")
    assert s2.fps == 2.0
    np.testing.assert_allclose(s2.timestamps_s, np.arange(7) / 2.0, atol=1e-9)


def test_a_truncated_video_is_one_line_not_a_shorter_sequence(tmp_path, synth, capsys):
    """A video cut at two thirds imported the frames the decoder gave, the last one damaged
    (pixels off by up to 246 DN), as a shorter sequence with exit code 0."""
    _, frames, _ = synth
    path = tmp_path / "clip.avi"
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (CAM.width_px, CAM.height_px), isColor=False)
    for f in frames:
        w.write(f)
    w.release()
    data = path.read_bytes()
    (tmp_path / "cut.avi").write_bytes(data[: len(data) * 2 // 3])
    err = _one_line_error(capsys, ["import", str(tmp_path / "cut.avi"), "-o", str(tmp_path / "s"), *FLAGS])
    assert "of the 7 frames the container states could be decoded (the file is truncated or damaged" in err
    assert not (tmp_path / "s").exists()
    assert main(["import", str(path), "-o", str(tmp_path / "whole"), *FLAGS]) == 0  # the whole file imports


def test_a_video_whose_times_do_not_increase_is_refused_unless_fps_is_given(
    tmp_path, synth, capsys, caplog, monkeypatch
):
    """A container whose frame 3 is stamped at frame 2's time was imported with i / (stated fps)
    in place of every time and exit code 0; now it is one line naming the frame and both times,
    and --fps (or --timestamps) is the explicit way to import it."""
    _, frames, _ = synth
    path = tmp_path / "clip.avi"
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"FFV1"), 10.0, (CAM.width_px, CAM.height_px), isColor=False)
    for f in frames:
        w.write(f)
    w.release()
    real = cv2.VideoCapture

    class RepeatedStamp:
        """The real capture, but frame 3 reports frame 2's presentation time."""

        def __init__(self, *args):
            self._cap, self._read = real(*args), 0

        def read(self):
            out = self._cap.read()
            self._read += out[0]
            return out

        def get(self, prop):
            if prop == cv2.CAP_PROP_POS_MSEC:
                return 100.0 * (self._read - 1 - (self._read == 4))
            return self._cap.get(prop)

        def __getattr__(self, name):
            return getattr(self._cap, name)

    monkeypatch.setattr(cv2, "VideoCapture", RepeatedStamp)
    out = tmp_path / "s"
    err = _one_line_error(capsys, ["import", str(path), "-o", str(out), *FLAGS])
    assert "frame times must increase, but frame 3 at 0.200000 s follows frame 2 at 0.200000 s" in err
    assert "give --fps HZ to take i / HZ instead (the container states 10 fps) or --timestamps FILE" in err
    assert not out.exists()
    assert main(["import", str(path), "-o", str(out), *FLAGS, "--fps", "20"]) == 0
    assert "frame 3 at 0.200000 s follows frame 2 at 0.200000 s); taking i / 20.0 fps (--fps)" in caplog.text
    np.testing.assert_allclose(Sequence.open(out).timestamps_s, np.arange(7) / 20.0, atol=1e-9)
    (tmp_path / "t.txt").write_text("".join(f"{0.5 * i}\n" for i in range(7)))
    assert main(["import", str(path), "-o", str(tmp_path / "s2"), *FLAGS, "--timestamps", str(tmp_path / "t.txt")]) == 0
    np.testing.assert_allclose(Sequence.open(tmp_path / "s2").timestamps_s, np.arange(7) * 0.5, atol=1e-9)


# ----------------------------------------------------------------------------- camera files
def test_camera_files_ros_opencv_kalibr(tmp_path):
    (tmp_path / "ros.yaml").write_text(
        "image_width: 162\nimage_height: 124\ncamera_name: floor\n"
        "camera_matrix: {rows: 3, cols: 3, data: [200.5, 0, 80.25, 0, 201.5, 61.75, 0, 0, 1]}\n"
        "distortion_model: plumb_bob\n"
        "distortion_coefficients: {rows: 1, cols: 5, data: [-0.1, 0.01, 0.001, -0.002, 0.003]}\n"
    )
    ros = read_camera_file(tmp_path / "ros.yaml").cam0
    assert (ros.fx_px, ros.fy_px, ros.cx_px, ros.cy_px) == (200.5, 201.5, 80.25, 61.75)
    assert ros.distortion == (-0.1, 0.01, 0.001, -0.002, 0.003) and ros.size == (162, 124)

    fs = cv2.FileStorage(str(tmp_path / "cv.yml"), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", 640)
    fs.write("image_height", 480)
    fs.write("camera_matrix", np.array([[500.0, 0, 319.5], [0, 501.0, 239.5], [0, 0, 1]]))
    fs.write("distortion_coefficients", np.array([[0.1, -0.2, 0.0, 0.0, 0.05]]))
    fs.release()
    assert (tmp_path / "cv.yml").read_text().startswith("%YAML:1.0")
    cv = read_camera_file(tmp_path / "cv.yml").cam0
    assert (cv.width_px, cv.height_px, cv.fx_px, cv.fy_px, cv.cx_px, cv.cy_px) == (640, 480, 500.0, 501.0, 319.5, 239.5)
    assert cv.distortion == (0.1, -0.2, 0.0, 0.0, 0.05)

    (tmp_path / "camchain.yaml").write_text(
        "cam0:\n  camera_model: pinhole\n  intrinsics: [400.0, 401.0, 320.0, 240.0]\n"
        "  distortion_model: radtan\n  distortion_coeffs: [0.01, -0.02, 0.0, 0.0]\n  resolution: [640, 480]\n"
        "cam1:\n  camera_model: pinhole\n  intrinsics: [402.0, 403.0, 321.0, 241.0]\n"
        "  distortion_model: radtan\n  distortion_coeffs: [0.0, 0.0, 0.0, 0.0]\n  resolution: [640, 480]\n"
        "  T_cn_cnm1:\n  - [1.0, 0.0, 0.0, -0.05]\n  - [0.0, 1.0, 0.0, 0.0]\n  - [0.0, 0.0, 1.0, 0.0]\n"
        "  - [0.0, 0.0, 0.0, 1.0]\n"
    )
    kal = read_camera_file(tmp_path / "camchain.yaml")
    assert kal.cam0.fx_px == 400.0 and kal.cam0.distortion == (0.01, -0.02, 0.0, 0.0, 0.0) and kal.cam1.cx_px == 321.0
    # T_cn_cnm1 maps cam0 points into cam1: cam1 sits 50 mm along cam0's +x.
    np.testing.assert_allclose(kal.T_cam0_cam1[:3, 3], [50.0, 0.0, 0.0])


def test_camera_file_refusals(tmp_path):
    (tmp_path / "fish.yaml").write_text(
        "cam0:\n  camera_model: pinhole\n  intrinsics: [400, 400, 320, 240]\n"
        "  distortion_model: equidistant\n  distortion_coeffs: [0.1, 0, 0, 0]\n  resolution: [640, 480]\n"
    )
    with pytest.raises(ConfigError, match="distortion model 'equidistant' is not supported"):
        read_camera_file(tmp_path / "fish.yaml")
    (tmp_path / "k.yaml").write_text("image_width: 64\nimage_height: 48\ncamera_matrix: [1, 2, 3]\n")
    with pytest.raises(ConfigError, match="camera matrix: needs 9 numbers, got 3"):
        read_camera_file(tmp_path / "k.yaml")
    (tmp_path / "bad.yaml").write_text("a: [1, 2\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        read_camera_file(tmp_path / "bad.yaml")
    # a mirrored cam1 (det R = -1) passed the orthonormality test
    (tmp_path / "mirror.yaml").write_text(
        "cam0:\n  camera_model: pinhole\n  intrinsics: [400, 400, 320, 240]\n  resolution: [640, 480]\n"
        "cam1:\n  camera_model: pinhole\n  intrinsics: [400, 400, 320, 240]\n  resolution: [640, 480]\n"
        "  T_cn_cnm1: [[1, 0, 0, -0.05], [0, 1, 0, 0], [0, 0, -1, 0], [0, 0, 0, 1]]\n"
    )
    with pytest.raises(ConfigError, match=r"not a rigid 4x4 transform \(its 3x3 part is not a rotation"):
        read_camera_file(tmp_path / "mirror.yaml")
    # a key given twice: PyYAML kept the second camera matrix (half the focal length), silently
    (tmp_path / "twice.yaml").write_text(
        "image_width: 64\nimage_height: 48\ncamera_matrix: [100, 0, 32, 0, 100, 24, 0, 0, 1]\n"
        "camera_matrix: [50, 0, 32, 0, 50, 24, 0, 0, 1]\n"
    )
    with pytest.raises(ConfigError, match=r"twice.yaml: key 'camera_matrix' is given twice \(line 4\)"):
        read_camera_file(tmp_path / "twice.yaml")
    # a camera matrix of another form was read as fx, fy, cx, cy alone: K[2][2] = 2 gave a camera
    # twice as long in focal length as the matrix states, a skew was dropped
    for K in ("[100, 0, 32, 0, 100, 24, 0, 0, 2]", "[100, 3, 32, 0, 100, 24, 0, 0, 1]"):
        (tmp_path / "k2.yaml").write_text(f"image_width: 64\nimage_height: 48\ncamera_matrix: {K}\n")
        with pytest.raises(
            ConfigError, match=r"k2.yaml camera matrix = .*: must be \[\[fx, 0, cx\], \[0, fy, cy\], \[0, 0, 1\]\]"
        ):
            read_camera_file(tmp_path / "k2.yaml")


# ----------------------------------------------------------------------------- ROS 2 bags made here
def _mono8(Image, header, img):
    """A ``sensor_msgs/Image`` (rosbags' class ``Image``) of the mono8 frame ``img``, with ``header``."""
    return Image(
        header=header,
        height=img.shape[0],
        width=img.shape[1],
        encoding="mono8",
        is_bigendian=0,
        step=img.shape[1],
        data=img.ravel(),
    )


def _write_bag(path, frames, T, stamps_ns, *, compressed: bool, gt: str):
    """A bag as a driver would record it: mono or compressed images, 16UC1 depth, a pose or TF topic."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    M = ts.types
    Header, Time = M["std_msgs/msg/Header"], M["builtin_interfaces/msg/Time"]
    Image, Compressed = M["sensor_msgs/msg/Image"], M["sensor_msgs/msg/CompressedImage"]
    Odometry, PoseWC, Pose = (
        M["nav_msgs/msg/Odometry"],
        M["geometry_msgs/msg/PoseWithCovariance"],
        M["geometry_msgs/msg/Pose"],
    )
    TwistWC, Twist, V3 = (
        M["geometry_msgs/msg/TwistWithCovariance"],
        M["geometry_msgs/msg/Twist"],
        M["geometry_msgs/msg/Vector3"],
    )
    Point, Quat = M["geometry_msgs/msg/Point"], M["geometry_msgs/msg/Quaternion"]
    TFMessage, TS, Tr = (
        M["tf2_msgs/msg/TFMessage"],
        M["geometry_msgs/msg/TransformStamped"],
        M["geometry_msgs/msg/Transform"],
    )

    def header(ns, frame):
        return Header(stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=frame)

    with Writer(path, version=9) as w:
        img_t = Compressed.__msgtype__ if compressed else Image.__msgtype__
        c_img = w.add_connection("/camera/image" + ("/compressed" if compressed else ""), img_t, typestore=ts)
        c_depth = w.add_connection("/camera/depth/image_rect", Image.__msgtype__, typestore=ts)
        c_gt = w.add_connection(
            "/odom" if gt == "odometry" else "/tf",
            Odometry.__msgtype__ if gt == "odometry" else TFMessage.__msgtype__,
            typestore=ts,
        )
        for i, (img, Ti, ns) in enumerate(zip(frames, T, stamps_ns)):
            ns = int(ns)
            if compressed:
                ok, buf = cv2.imencode(".png", img)
                msg = Compressed(
                    header=header(ns, "camera_optical"),
                    format="mono8; png compressed mono8",
                    data=np.frombuffer(buf.tobytes(), np.uint8),
                )
            else:
                msg = _mono8(Image, header(ns, "camera_optical"), img)
            w.write(c_img, ns + 5_000_000, ts.serialize_cdr(msg, msg.__msgtype__))  # received 5 ms after the stamp
            depth = np.full(img.shape, 100 + i, "<u2")
            dmsg = Image(
                header=header(ns + 200_000, "camera_optical"),
                height=img.shape[0],
                width=img.shape[1],
                encoding="16UC1",
                is_bigendian=0,
                step=img.shape[1] * 2,
                data=np.frombuffer(depth.tobytes(), np.uint8),
            )
            w.write(c_depth, ns + 6_000_000, ts.serialize_cdr(dmsg, dmsg.__msgtype__))
            xyz, q = xyz_quat_from_T(Ti)
            xyz = xyz / 1000.0
            if gt == "odometry":
                pose = Pose(
                    position=Point(x=xyz[0], y=xyz[1], z=xyz[2]), orientation=Quat(x=q[0], y=q[1], z=q[2], w=q[3])
                )
                zero = V3(x=0.0, y=0.0, z=0.0)
                m = Odometry(
                    header=header(ns, "world"),
                    child_frame_id="camera_optical",
                    pose=PoseWC(pose=pose, covariance=np.zeros(36)),
                    twist=TwistWC(twist=Twist(linear=zero, angular=zero), covariance=np.zeros(36)),
                )
            else:
                tr = Tr(translation=V3(x=xyz[0], y=xyz[1], z=xyz[2]), rotation=Quat(x=q[0], y=q[1], z=q[2], w=q[3]))
                other = Tr(translation=V3(x=9.0, y=9.0, z=9.0), rotation=Quat(x=0.0, y=0.0, z=0.0, w=1.0))
                m = TFMessage(
                    transforms=[
                        TS(header=header(ns, "world"), child_frame_id="camera_optical", transform=tr),
                        TS(header=header(ns, "world"), child_frame_id="base_link", transform=other),
                    ]
                )
            w.write(c_gt, ns, ts.serialize_cdr(m, m.__msgtype__))


@pytest.mark.parametrize("compressed, gt", [(False, "odometry"), (True, "tf")])
def test_recorded_bag_imports_and_runs(tmp_path, synth, compressed, gt):
    """Header stamps (not receive times) become frame times; 16UC1 depth (mm) pairs within 1 ms; the
    ground truth comes from an Odometry topic or from /tf (the transform to the image's frame)."""
    _, frames, T = synth
    stamps_ns = 1_700_000_000_000_000_000 + np.cumsum([0, 33, 34, 33, 33, 34, 33]) * 1_000_000
    _write_bag(tmp_path / "bag", frames, T, stamps_ns, compressed=compressed, gt=gt)
    assert detect_format(tmp_path / "bag") == "rosbag2"
    res = import_sequence(
        tmp_path / "bag",
        tmp_path / "s",
        options=ImportOptions(intrinsics=(CAM.fx_px, CAM.fy_px, CAM.cx_px, CAM.cy_px), height_mm=100.0),
    )
    s = Sequence.open(tmp_path / "s")
    assert res.frames == 7 and s.has_depth and res.groundtruth_poses == 7
    np.testing.assert_allclose(s.timestamps_s, stamps_ns * 1e-9, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(s.image(3), frames[3])
    np.testing.assert_allclose(s.depth_mm(4), 104.0)
    t_gt, T_gt = s.groundtruth()
    np.testing.assert_allclose(T_gt, T, atol=1e-6)
    from floorvo.run import run_estimator

    run_estimator(s, "phase-corr", tmp_path / "run")
    t_run, T_run = read_tum(tmp_path / "run" / "trajectory.txt")
    np.testing.assert_allclose(T_run[0], T[0], atol=1e-6)
    assert _end_error_mm(tmp_path / "run", T) < 0.2


def test_bag_topic_choice_refusals(tmp_path, synth, capsys):
    _, frames, T = synth
    stamps_ns = 10**18 + np.arange(3) * 33_000_000
    _write_bag(tmp_path / "bag", frames[:3], T[:3], stamps_ns, compressed=False, gt="odometry")
    err = _one_line_error(
        capsys, ["import", str(tmp_path / "bag"), "-o", str(tmp_path / "s"), *FLAGS, "--topic", "image=/nope"]
    )
    assert "--topic image=/nope: no such topic in the bag" in err
    err = _one_line_error(
        capsys,
        ["import", str(tmp_path / "bag"), "-o", str(tmp_path / "s"), *FLAGS, "--topic", "groundtruth=/camera/image"],
    )
    assert "is sensor_msgs/msg/Image, a groundtruth topic is one of" in err
    err = _one_line_error(
        capsys, ["import", str(tmp_path / "bag"), "-o", str(tmp_path / "s"), *FLAGS, "--topic", "left=/camera/image"]
    )
    assert "--topic left=/camera/image: unknown role" in err


def test_a_bag_whose_images_are_stamped_by_two_clocks_is_one_line(tmp_path, synth, capsys):
    """One image with a zero header stamp took the bag's receive time, 4 s after the camera's
    stamps of the others: it was sorted to the end of the sequence, exit code 0."""
    _, frames, T = synth
    stamps_ns = np.array([10**18, 0, 10**18 + 66_000_000])
    _write_bag(tmp_path / "bag", frames[:3], T[:3], stamps_ns, compressed=False, gt="odometry")
    err = _one_line_error(capsys, ["import", str(tmp_path / "bag"), "-o", str(tmp_path / "s"), *FLAGS])
    assert (
        "/camera/image: 1 of 3 images have a zero header stamp (the first received at 0.005000000 s), the others the camera's"
        in err
    )
    assert not (tmp_path / "s").exists()


@pytest.mark.parametrize(
    "times, words",
    [
        (
            (100.0, 100.1, 100.2),
            "--groundtruth: one pose per frame, but pose 0 is at 100.000000 s and frame 0 at 0.000000 s",
        ),
        (
            (100.0, 100.1),
            "--groundtruth: no pose within 0.01 s of a frame (poses at 100.000000-100.100000 s, frames at",
        ),
    ],
)
def test_ground_truth_on_another_clock_than_the_frames_is_refused_before_writing(tmp_path, synth, capsys, times, words):
    """Ground truth 100 s after the frames was imported with exit code 0: one pose per frame into a
    sequence its own reader then refused ('the frame times and the ground truth disagree'), and
    poses at another rate into one that every score called 'shares no timestamp'."""
    _, frames, _ = synth
    src = tmp_path / "frames"
    src.mkdir()
    for i, img in enumerate(frames[:3]):
        cv2.imwrite(str(src / f"{i}.png"), img)
    (tmp_path / "gt.txt").write_text("".join(f"{t} 0 0 0.1 0 0 0 1\n" for t in times))
    argv = [
        "import",
        str(src),
        "-o",
        str(tmp_path / "s"),
        *FLAGS,
        "--fps",
        "10",
        "--groundtruth",
        str(tmp_path / "gt.txt"),
    ]
    assert words in _one_line_error(capsys, argv)
    assert not (tmp_path / "s").exists()


def test_frames_closer_than_a_nanosecond_are_refused_before_writing(tmp_path, synth, capsys):
    """--fps 1e12 imported a sequence whose timestamps.txt (nanoseconds) held equal times, and its
    reader then refused it ('timestamps must increase'); --fps 1e308 gave every frame the time 0.
    --fps is bounded as sequence.json's fps is (1e6 Hz), and times closer than a nanosecond
    from a --timestamps file are refused before anything is written."""
    _, frames, _ = synth
    src = tmp_path / "frames"
    src.mkdir()
    for i, img in enumerate(frames[:3]):
        cv2.imwrite(str(src / f"{i}.png"), img)
    for fps in ("1e12", "1e308", "0.001"):  # 0.001: passed here, then refused by sequence.json's rule in its words
        err = _one_line_error(capsys, ["import", str(src), "-o", str(tmp_path / "s"), *FLAGS, "--fps", fps])
        assert f"--fps {float(fps)}: must be a finite number from 0.01 to 1e+06 Hz" in err
    (tmp_path / "slow.txt").write_text("0\n1000\n2000\n")  # 1000 s apart: the same, from the times
    err = _one_line_error(
        capsys, ["import", str(src), "-o", str(tmp_path / "s"), *FLAGS, "--timestamps", str(tmp_path / "slow.txt")]
    )
    assert "the frames' times (timestamps file) are 1000 s apart (median), a rate under the 0.01 Hz" in err
    (tmp_path / "t.txt").write_text("0.0\n0.0000000001\n0.1\n")
    err = _one_line_error(
        capsys, ["import", str(src), "-o", str(tmp_path / "s"), *FLAGS, "--timestamps", str(tmp_path / "t.txt")]
    )
    assert "timestamps must increase (to the nanosecond, as timestamps.txt holds them), frame 1" in err
    assert not (tmp_path / "s").exists()
    assert main(["import", str(src), "-o", str(tmp_path / "ok"), *FLAGS, "--fps", "1e6"]) == 0
    # --fps beside frame times at another rate was written into sequence.json (and given to programs as {fps})
    (tmp_path / "t30.txt").write_text("0.0\n0.033333\n0.066667\n")
    argv = ["import", str(src), "-o", str(tmp_path / "s"), *FLAGS, "--timestamps", str(tmp_path / "t30.txt")]
    err = _one_line_error(capsys, argv + ["--fps", "25"])
    assert "--fps 25.0: the frames have times (from the timestamps file); --fps is for a source without them" in err
    assert not (tmp_path / "s").exists()


def test_absurd_intrinsics_are_refused_by_every_reader(tmp_path, synth, capsys):
    """--fx 1e308 (or a distortion of 1e308) was imported as it was, and every step of a run came
    out 1e-305 mm; one rule (FOCAL_LENGTH_RANGE_PX, MAX_DISTORTION_COEFFICIENT) serves every reader."""
    _, frames, _ = synth
    src = tmp_path / "frames"
    src.mkdir()
    for i, img in enumerate(frames[:3]):
        cv2.imwrite(str(src / f"{i}.png"), img)
    base = ["import", str(src), "-o", str(tmp_path / "out"), "--fps", "10"]
    for fx in ("1e308", "0.5", "2e6"):
        err = _one_line_error(capsys, [*base, "--fx", fx, "--fy", "200", "--cx", "80", "--cy", "60"])
        assert f"focal lengths (fx, fy) = ({float(fx):g}, 200) px must be from 1 to 1e+06 px" in err, err
    err = _one_line_error(capsys, [*base, *FLAGS, "--distortion", "1e308,0,0,0"])
    assert "distortion = [1e+308, 0.0, 0.0, 0.0, 0.0]: each coefficient must be from -10000 to 10000" in err, err
    (tmp_path / "cam.yaml").write_text(
        "image_width: 162\nimage_height: 124\ncamera_matrix: {rows: 3, cols: 3, data: [1e308, 0, 80, 0, 1e308, 62, 0, 0, 1]}\n"
    )
    err = _one_line_error(capsys, [*base, "--camera", str(tmp_path / "cam.yaml")])
    assert "cam.yaml" in err and "focal lengths (fx, fy) = (1e+308, 1e+308) px must be from 1 to 1e+06 px" in err
    assert not (tmp_path / "out").exists()
    seq = tmp_path / "seq"
    write_synthetic_sequence(seq, CAM, line_poses(8.0, 4.0), seed=0)
    meta = json.loads((seq / "sequence.json").read_text())
    meta["camera"]["K"][0][0] = 1e308
    (seq / "sequence.json").write_text(json.dumps(meta))
    with pytest.raises(SequenceError, match=r"focal lengths \(fx, fy\) = \(1e\+308, 202.703\) px must be from 1"):
        Sequence.open(seq)
    meta["camera"]["K"][0][0] = CAM.fx_px
    meta["camera"]["distortion"] = [0.1, -1e5, 0, 0, 0]
    (seq / "sequence.json").write_text(json.dumps(meta))
    with pytest.raises(
        SequenceError, match=r"distortion = \[0.1, -100000.0, 0.0, 0.0, 0.0\]: each coefficient must be"
    ):
        Sequence.open(seq)


# ----------------------------------------------------------------------------- refusals
def test_bad_inputs_give_one_line_errors(tmp_path, synth, capsys):
    _, frames, _ = synth
    src = tmp_path / "frames"
    src.mkdir()
    for i, img in enumerate(frames[:3]):
        cv2.imwrite(str(src / f"{i}.png"), img)
    out = str(tmp_path / "out")
    base = ["import", str(src), "-o", out]
    assert "holds no camera calibration; give --camera FILE" in _one_line_error(capsys, base + ["--fps", "10"])
    assert "states no frame times; give --timestamps FILE or --fps" in _one_line_error(capsys, base + FLAGS)
    for height in ("nan", "1e9", "1e-9", "0.1"):  # 0.1: 100 mm given in metres
        err = _one_line_error(capsys, base + FLAGS + ["--fps", "10", "--height-mm", height])
        assert f"--height-mm {float(height)} mm: must be a finite number from 1 to 20000 mm" in err
    assert "--fps -3.0: must be a finite number from 0.01 to 1e+06 Hz" in _one_line_error(
        capsys, base + FLAGS + ["--fps", "-3"]
    )
    assert "--fx, --cy missing" in _one_line_error(capsys, base + ["--fy", "200", "--cx", "80", "--fps", "10"])
    assert "--distortion '0.1,x': expected numbers" in _one_line_error(
        capsys, base + FLAGS + ["--fps", "10", "--distortion", "0.1,x"]
    )
    (tmp_path / "cam.yaml").write_text(
        "image_width: 640\nimage_height: 480\ncamera_matrix: {rows: 3, cols: 3, data: [500, 0, 320, 0, 500, 240, 0, 0, 1]}\n"
    )
    err = _one_line_error(capsys, base + ["--camera", str(tmp_path / "cam.yaml"), "--fps", "10"])
    assert "calibrated for 640x480 px, the frames of" in err and "are 162x124 px" in err
    # a principal point far outside the frames (a camera file's, the flags') was taken as it was
    (tmp_path / "far.yaml").write_text(
        "image_width: 162\nimage_height: 124\ncamera_matrix: {rows: 3, cols: 3, data: [500, 0, 8100, 0, 500, 62, 0, 0, 1]}\n"
    )
    err = _one_line_error(capsys, base + ["--camera", str(tmp_path / "far.yaml"), "--fps", "10"])
    assert "far.yaml" in err and "principal point (cx, cy) = (8100, 62) px must lie in the image" in err
    flags = ["--fx", "200", "--fy", "200", "--cx", "80", "--cy", "-500", "--fps", "10"]
    err = _one_line_error(capsys, base + flags)
    assert err.startswith("floorvo: error: camera flags: principal point (cx, cy) = (80, -500) px must lie"), err
    (tmp_path / "t2.txt").write_text("0.0\n0.1\n")
    err = _one_line_error(capsys, base + FLAGS + ["--timestamps", str(tmp_path / "t2.txt")])
    assert "2 timestamp(s) for the 3 frame(s)" in err
    (tmp_path / "t3.txt").write_text("0.0\n0.2\n0.1\n")
    err = _one_line_error(capsys, base + FLAGS + ["--timestamps", str(tmp_path / "t3.txt")])
    assert "timestamps must increase, frame 2 at 0.100000000 s follows 0.200000000 s" in err
    (tmp_path / "t4.txt").write_text("0.0\n0.1s\n0.2\n")
    assert "'0.1s' is not a timestamp in s" in _one_line_error(
        capsys, base + FLAGS + ["--timestamps", str(tmp_path / "t4.txt")]
    )
    # nanoseconds given as seconds: taken, and a 1e300 s time printed as a 300-digit number in an error
    (tmp_path / "t5.txt").write_text("1403636579758555392\n1403636579808555520\n1403636579858555392\n")
    err = _one_line_error(capsys, base + FLAGS + ["--timestamps", str(tmp_path / "t5.txt")])
    assert "timestamp of frame 0 = 1.40364e+18 s is beyond 1e+10 s (a time in seconds; this one looks like" in err
    (tmp_path / "gt.txt").write_text("0.0 1 2 3 0 0 0 1\n0.1 1 2\n")
    assert "a TUM line has 8 numbers" in _one_line_error(
        capsys, base + FLAGS + ["--fps", "10", "--groundtruth", str(tmp_path / "gt.txt")]
    )
    (tmp_path / "empty").mkdir()
    assert "format not recognised" in _one_line_error(capsys, ["import", str(tmp_path / "empty"), "-o", out])
    assert "does not exist" in _one_line_error(capsys, ["import", str(tmp_path / "nope"), "-o", out])
    (tmp_path / "broken.mp4").write_bytes(b"not a video at all")
    assert "not a video OpenCV can decode" in _one_line_error(
        capsys, ["import", str(tmp_path / "broken.mp4"), "-o", out, *FLAGS]
    )
    cv2.imwrite(str(src / "3.png"), frames[0][:100])
    err = _one_line_error(capsys, base + FLAGS + ["--fps", "10"])
    assert f"{src / '3.png'}: image is 162x100, frame 0 is 162x124 px" in err  # from its header
    assert not (tmp_path / "out" / "cam0" / "000003.png").exists()


def _png_header_only(path, width: int, height: int) -> None:
    """A PNG of 57 bytes whose header states ``width`` x ``height`` 8-bit grey pixels."""
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"")) + chunk(b"IEND", b"")
    )


def test_a_png_bomb_is_refused_from_its_header_before_decoding(tmp_path, synth, capsys, monkeypatch):
    """A PNG of 389 kB stating 20000 x 20000 pixels was decoded in full (400 MB) as an image-folder
    frame or a --flatfield; its header is read first now: more than 8192 x 8192 pixels, or (after
    the first frame, and for a flat field) another size than the frames', is refused in one line."""
    _, frames, _ = synth
    src = tmp_path / "frames"
    src.mkdir()
    for i, img in enumerate(frames[:3]):
        cv2.imwrite(str(src / f"{i}.png"), img)
    bomb = tmp_path / "bomb.png"
    _png_header_only(bomb, 100_000, 100_000)
    real_imdecode = cv2.imdecode

    def imdecode(data, flags):
        assert data.size != bomb.stat().st_size, "the bomb was decoded"
        return real_imdecode(data, flags)

    monkeypatch.setattr(cv2, "imdecode", imdecode)
    base = ["import", str(src), "-o", str(tmp_path / "out"), *FLAGS, "--fps", "10"]
    err = _one_line_error(capsys, [*base, "--flatfield", str(bomb)])
    assert f"{bomb}: image is 100000x100000, the frames are 162x124 px" in err
    (src / "3.png").write_bytes(bomb.read_bytes())
    err = _one_line_error(capsys, base)
    assert f"{src / '3.png'}: image is 100000x100000, frame 0 is 162x124 px" in err
    (src / "0.png").write_bytes(bomb.read_bytes())  # the first frame: no size to expect yet
    err = _one_line_error(capsys, base)
    assert f"{src / '0.png'}: image (PNG, JPEG, TIFF or BMP) states 100000x100000 px in its header, more than" in err
    assert not (tmp_path / "out" / "cam0" / "000003.png").exists()


def _header_only(kind: str, width: int, height: int) -> bytes:
    """A file of a few dozen bytes whose header states ``width`` x ``height`` pixels, in format ``kind``."""
    import struct

    if kind == "jpeg":  # SOI, an APP0 segment, a baseline SOF0 of one component, EOI
        app0 = b"\xff\xe0" + struct.pack(">H", 16) + b"JFIF\x00\x01\x01\x00\x00\x01\x00\x01\x00\x00"
        sof = b"\xff\xc0" + struct.pack(">HBHHB", 11, 8, height, width, 1) + b"\x01\x11\x00"
        return b"\xff\xd8" + app0 + sof + b"\xff\xd9"
    if kind == "bmp":  # file header and a 40-byte info header, 8 bits a pixel, rows top-down
        info = struct.pack("<IiiHHIIiiII", 40, width, -height, 1, 8, 0, 0, 2835, 2835, 0, 0)
        return b"BM" + struct.pack("<IHHI", 54 + len(info), 0, 0, 54) + info
    if kind in ("tiff-le", "tiff-be"):  # the first directory: ImageWidth, ImageLength (LONG), BitsPerSample
        e = "<" if kind == "tiff-le" else ">"
        entries = [(256, 4, 1, width), (257, 4, 1, height)]
        ifd = struct.pack(e + "H", 3) + b"".join(struct.pack(e + "HHII", *t) for t in entries)
        ifd += struct.pack(e + "HHIHH", 258, 3, 1, 8, 0) + struct.pack(e + "I", 0)
        return (b"II" if e == "<" else b"MM") + struct.pack(e + "HI", 42, 8) + ifd
    if kind == "bigtiff":
        entries = [(256, 16, 1, width), (257, 16, 1, height)]
        ifd = struct.pack("<Q", 2) + b"".join(struct.pack("<HHQQ", *t) for t in entries) + struct.pack("<Q", 0)
        return b"II" + struct.pack("<HHHQ", 43, 8, 0, 16) + ifd
    raise ValueError(kind)


@pytest.mark.parametrize("kind", ["jpeg", "bmp", "tiff-le", "tiff-be", "bigtiff"])
def test_image_header_size_reads_each_format(kind):
    """The size of a JPEG's start of frame, a BMP's info header and a TIFF's first directory,
    read without decoding (a JPEG states at most 65535 x 65535)."""
    from floorvo.io import image_header_size

    side = 65535 if kind == "jpeg" else 100_000
    assert image_header_size(_header_only(kind, side, side - 1)) == (side, side - 1)
    assert image_header_size(_header_only(kind, side, side)[:12]) is None  # cut before the size


@pytest.mark.parametrize(
    "ext, shape, dtype, params",
    [
        (".jpg", (37, 53), np.uint8, []),
        (".jpg", (37, 53, 3), np.uint8, [cv2.IMWRITE_JPEG_PROGRESSIVE, 1]),
        (".bmp", (37, 53), np.uint8, []),
        (".bmp", (5, 7, 3), np.uint8, []),
        (".tif", (37, 53), np.uint16, []),
        (".tif", (5, 7, 4), np.uint8, []),
        (".png", (20, 11), np.uint16, []),
    ],
)
def test_image_header_size_agrees_with_opencv(ext, shape, dtype, params):
    """The size read from the header is the size OpenCV decodes, for files OpenCV writes."""
    from floorvo.io import image_header_size

    img = np.random.default_rng(0).integers(0, 200, shape).astype(dtype)
    ok, buf = cv2.imencode(ext, img, params)
    decoded = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
    assert image_header_size(buf.tobytes()) == (decoded.shape[1], decoded.shape[0])


def test_image_bombs_of_every_format_are_refused_before_decoding(tmp_path, synth, capsys, monkeypatch):
    """A JPEG, BMP or TIFF was decoded with only OpenCV's own limit (2^30 pixels) as an image-folder
    frame, a --flatfield or a bag's compressed image: a JPEG of 60 bytes can state 65535 x 65535
    pixels. Their headers are read first now, as a PNG's; a format whose header is not read
    (a PGM, which OpenCV decodes too) is refused, and so is a video whose container states
    frames beyond the limit."""
    from types import SimpleNamespace

    from floorvo.importers.rosbag2 import decode_image

    _, frames, _ = synth
    src = tmp_path / "frames"
    src.mkdir()
    for i, img in enumerate(frames[:3]):
        cv2.imwrite(str(src / f"f{i + 1}.png"), img)

    real_imdecode = cv2.imdecode

    def imdecode(data, flags):
        assert data.size > 200, "a bomb was decoded"  # the bombs are under 100 bytes, the frames above 10 kB
        return real_imdecode(data, flags)

    monkeypatch.setattr(cv2, "imdecode", imdecode)
    base = ["import", str(src), "-o", str(tmp_path / "out"), *FLAGS, "--fps", "10"]
    limit = "more than the 67108864 px (8192 x 8192) an image may have"
    for kind, ext in [
        ("jpeg", ".jpg"),
        ("bmp", ".bmp"),
        ("tiff-le", ".tif"),
        ("tiff-be", ".tiff"),
        ("bigtiff", ".tif"),
    ]:
        side = 65535 if kind == "jpeg" else 100_000
        bomb = tmp_path / f"bomb{ext}"
        bomb.write_bytes(_header_only(kind, side, side))
        err = _one_line_error(capsys, [*base, "--flatfield", str(bomb)])
        assert f"{bomb}: image is {side}x{side}, the frames are 162x124 px" in err
        first = src / f"f0{ext}"  # sorts before f1.png: the first frame, no size to expect yet
        first.write_bytes(bomb.read_bytes())
        err = _one_line_error(capsys, base)
        assert f"{first}: image (PNG, JPEG, TIFF or BMP) states {side}x{side} px in its header, {limit}" in err
        first.unlink()
        msg = SimpleNamespace(format="mono8; jpeg compressed mono8", data=np.frombuffer(bomb.read_bytes(), np.uint8))
        with pytest.raises(SequenceError, match=f"^frame 3: compressed image states {side}x{side} px in its header"):
            decode_image(msg, "sensor_msgs/msg/CompressedImage", "frame 3")
    pgm = src / "f0.png"  # a PGM under a PNG's name: OpenCV decodes it by its content
    pgm.write_bytes(b"P5\n100000 100000\n255\n" + bytes(64))
    err = _one_line_error(capsys, base)
    assert f"{pgm}: not a readable image (PNG, JPEG, TIFF or BMP) (corrupt or truncated, or not a PNG," in err
    msg = SimpleNamespace(format="pgm", data=np.frombuffer(pgm.read_bytes(), np.uint8))
    with pytest.raises(SequenceError, match=r"^frame 3: compressed image \('pgm'\) is not a PNG, JPEG, TIFF or BMP"):
        decode_image(msg, "sensor_msgs/msg/CompressedImage", "frame 3")
    assert not (tmp_path / "out" / "cam0").exists()

    class HugeFrames:
        """A capture whose container states 100000 x 100000 frames; reading one fails the test."""

        def __init__(self, *args):
            pass

        def isOpened(self):
            return True

        def get(self, prop):
            return {cv2.CAP_PROP_FRAME_WIDTH: 100000.0, cv2.CAP_PROP_FRAME_HEIGHT: 100000.0}.get(prop, 0.0)

        def read(self):
            raise AssertionError("a frame was decoded")

        def release(self):
            pass

    monkeypatch.setattr(cv2, "VideoCapture", HugeFrames)
    (tmp_path / "v.mp4").write_bytes(b"\x00" * 64)
    err = _one_line_error(capsys, ["import", str(tmp_path / "v.mp4"), "-o", str(tmp_path / "out"), *FLAGS])
    assert f"{tmp_path / 'v.mp4'}: video states 100000x100000 px in its container, {limit}" in err


def test_import_resumes_and_refuses_another_source(tmp_path, synth):
    """The same import again keeps the frames on disk; another source into the same folder is refused."""
    _, frames, _ = synth
    for d in ("a", "b"):
        (tmp_path / d).mkdir()
        for i, img in enumerate(frames[:3]):
            cv2.imwrite(str(tmp_path / d / f"{i}.png"), img)
    opts = ImportOptions(intrinsics=(200.0, 200.0, 80.5, 61.5), fps=10.0, height_mm=100.0)
    import_sequence(tmp_path / "a", tmp_path / "s", options=opts)
    mtime = (tmp_path / "s" / "cam0" / "000001.png").stat().st_mtime_ns
    import_sequence(tmp_path / "a", tmp_path / "s", options=opts)
    assert (tmp_path / "s" / "cam0" / "000001.png").stat().st_mtime_ns == mtime
    with pytest.raises(SequenceError, match="holds a different sequence"):
        import_sequence(tmp_path / "b", tmp_path / "s", options=opts)


def test_readme_minimal_sequence_json_loads(tmp_path):
    """The hand-written sequence.json of the README's "Your own recordings" loads and is ready to run."""
    from pathlib import Path

    from floorvo.estimators import Frame
    from floorvo.run import build_estimator

    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    section = readme.split("## Your own recordings", 1)[1].split("\n## ", 1)[0]
    example = section.split("```json\n", 1)[1].split("```", 1)[0]
    root = tmp_path / "rec"
    (root / "cam0").mkdir(parents=True)
    (root / "sequence.json").write_text(example)
    meta = json.loads(example)
    img = np.random.default_rng(0).integers(0, 255, (meta["camera"]["height_px"], meta["camera"]["width_px"]), np.uint8)
    cv2.imwrite(str(root / "cam0" / "000000.png"), img)
    seq = Sequence.open(root)
    assert seq.frame_count == 300 and seq.height_mm == 100.0 and seq.camera.size == (648, 494)
    np.testing.assert_allclose(seq.timestamps_s[:3], [0.0, 1 / 30, 2 / 30])
    assert seq.image(0).shape == (494, 648)
    est, _ = build_estimator(seq, "phase-corr")  # refuses a sequence without rig.height_mm
    res = est.step(est.start(), Frame(index=0, timestamp_s=0.0, image=seq.image(0)))
    assert res.status == "init"


def test_import_writes_a_range_sensors_height_column(tmp_path, synth, capsys):
    """--height-file (CSV frame,height_mm, issue 14 item 4) becomes the sequence's height.csv;
    a file with another number of frames is refused in one line before anything is written."""
    seq, frames, T = synth
    src = tmp_path / "frames"
    src.mkdir()
    for i, img in enumerate(frames):
        cv2.imwrite(str(src / f"f{i:02d}.png"), img)
    heights = [100.0, 100.2, "", 99.8, 100.1, 100.0, 99.9]
    (tmp_path / "h.csv").write_text("frame,height_mm\n" + "".join(f"{i},{h}\n" for i, h in enumerate(heights)))
    out = tmp_path / "imp"
    argv = ["import", str(src), "-o", str(out), *FLAGS, "--height-mm", "100", "--fps", "30"]
    assert main([*argv, "--height-file", str(tmp_path / "h.csv")]) == 0
    np.testing.assert_array_equal(Sequence.open(out).height_signal_mm, [100.0, 100.2, np.nan, 99.8, 100.1, 100.0, 99.9])
    (tmp_path / "short.csv").write_text("frame,height_mm\n0,100\n1,100\n")
    err = _one_line_error(
        capsys, [*argv[:3], str(tmp_path / "imp2"), *argv[4:], "--height-file", str(tmp_path / "short.csv")]
    )
    assert "--height-file: 2 height(s) for 7 frame(s)" in err
    assert not (tmp_path / "imp2" / "height.csv").exists()
    # the readings' noise, stated beside them (rig.height_noise_mm), for the runner to hold the steps to
    assert Sequence.open(out).height_noise_mm is None
    assert main([*argv[:3], str(tmp_path / "imp3"), *argv[4:], "--height-file", str(tmp_path / "h.csv"),
                 "--height-noise-mm", "0.1"]) == 0  # fmt: skip
    assert Sequence.open(tmp_path / "imp3").height_noise_mm == 0.1
    err = _one_line_error(capsys, [*argv[:3], str(tmp_path / "imp4"), *argv[4:], "--height-noise-mm", "0.1"])
    assert "--height-noise-mm: the import has no height signal to state the noise of (--height-file)" in err
    err = _one_line_error(
        capsys,
        [
            *argv[:3],
            str(tmp_path / "imp5"),
            *argv[4:],
            "--height-file",
            str(tmp_path / "h.csv"),
            "--height-noise-mm",
            "-1",
        ],
    )
    assert "--height-noise-mm = -1.0: must be a standard deviation in mm, 0 to 20000" in err
    assert not (tmp_path / "imp4").exists() and not (tmp_path / "imp5").exists()


def test_import_writes_an_imus_attitude(tmp_path, synth, capsys):
    """--attitude-file (CSV frame,roll_rad,pitch_rad) becomes the sequence's attitude.csv; a
    file with an angle in degrees is refused in one line before anything is written."""
    seq, frames, T = synth
    src = tmp_path / "frames"
    src.mkdir()
    for i, img in enumerate(frames):
        cv2.imwrite(str(src / f"f{i:02d}.png"), img)
    rows = ["0.01,-0.02", "0.011,-0.019", ",", "0.0,0.0", "-0.01,0.02", "0.0,0.005", "0.001,0.0"]
    (tmp_path / "a.csv").write_text("frame,roll_rad,pitch_rad\n" + "".join(f"{i},{r}\n" for i, r in enumerate(rows)))
    out = tmp_path / "imp"
    argv = ["import", str(src), "-o", str(out), *FLAGS, "--height-mm", "100", "--fps", "30"]
    assert main([*argv, "--attitude-file", str(tmp_path / "a.csv")]) == 0
    a = Sequence.open(out).attitude_signal_rad
    assert a.shape == (7, 2) and np.isnan(a[2]).all() and a[4].tolist() == [-0.01, 0.02]
    (tmp_path / "deg.csv").write_text("frame,roll_rad,pitch_rad\n" + "".join(f"{i},1.5,0\n" for i in range(7)))
    err = _one_line_error(
        capsys, [*argv[:3], str(tmp_path / "imp2"), *argv[4:], "--attitude-file", str(tmp_path / "deg.csv")]
    )
    assert "--attitude-file: roll_rad of frame 0 = 1.5: must be a finite number of radians within +-0.5" in err
    assert not (tmp_path / "imp2" / "attitude.csv").exists()


def test_times_that_do_not_increase_are_refused_naming_the_file_and_line(tmp_path, synth, capsys):
    """A timestamps file (or an image list's times) with a repeated or decreasing time, or one in
    another unit: the error said 'timestamps (timestamps file): ... frame 3 ...', naming neither
    the file nor its line (comments and blank lines make frame 3 another line). A file with a
    byte-order mark, CRLF line ends, comments and blank lines is read as it is."""
    _, frames, _ = synth
    src = tmp_path / "frames"
    src.mkdir()
    for i, img in enumerate(frames[:4]):
        cv2.imwrite(str(src / f"{i}.png"), img)
    base = ["import", str(src), "-o", str(tmp_path / "out"), *FLAGS, "--timestamps"]
    times = tmp_path / "times.txt"
    times.write_text("# t [s]\n\n1700000000.1\n1700000000.2\n\n# pause\n1700000000.2\n1700000000.3\n")
    err = _one_line_error(capsys, [*base, str(times)])
    assert f"{times}:7: timestamps must increase, frame 2 at" in err, err
    times.write_text("1700000000.1\n1700000000.3\n1700000000.2\n1700000000.4\n")
    assert f"{times}:3: timestamps must increase, frame 2 at" in _one_line_error(capsys, [*base, str(times)])
    times.write_text("# ns\n1700000000100000000\n1700000000200000000\n1700000000300000000\n1700000000400000000\n")
    err = _one_line_error(capsys, [*base, str(times)])
    assert f"{times}:2: timestamp of frame 0 = 1.7e+18 s is beyond 1e+10 s" in err, err
    listed = tmp_path / "list.txt"
    listed.write_text("".join(f"{t} frames/{i}.png\n" for i, t in enumerate([1.0, 1.1, 1.1, 1.2])))
    err = _one_line_error(capsys, ["import", str(listed), "-o", str(tmp_path / "out"), *FLAGS])
    assert f"{listed}:3: timestamps must increase, frame 2 at" in err, err
    times.write_bytes(b"\xef\xbb\xbf# t [s]\r\n\r\n" + b"".join(b"170000000%d.5\r\n" % i for i in range(4)))
    assert main([*base, str(times)]) == 0
    np.testing.assert_array_equal(Sequence.open(tmp_path / "out").timestamps_s, 1.7e9 + np.arange(4) + 0.5)


def test_a_euroc_ground_truth_file_with_a_byte_order_mark_is_read_as_euroc(tmp_path, synth, capsys):
    """``--groundtruth gt.txt`` whose first line is EuRoC's ``#timestamp [ns], ...`` header behind a
    byte-order mark was taken for TUM: its rows ``t_ns px py pz qw qx qy qz`` were read as
    ``t tx ty tz qx qy qz qw`` (a time of 1e8 s for 0.1 s in ns, w taken for x)."""
    _, frames, T = synth
    src = tmp_path / "frames"
    src.mkdir()
    for i, img in enumerate(frames):
        cv2.imwrite(str(src / f"{i}.png"), img)
    rows = []
    for i, Ti in enumerate(T):
        xyz, q = xyz_quat_from_T(Ti)
        cells = [100_000_000 * i, *(xyz / 1000.0), q[3], q[0], q[1], q[2]]
        rows.append(",".join(str(c) for c in cells))
    gt = tmp_path / "gt.txt"
    header = "#timestamp [ns], p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z []"
    gt.write_bytes(b"\xef\xbb\xbf" + "\r\n".join([header, *rows, ""]).encode())
    out = tmp_path / "out"
    assert main(["import", str(src), "-o", str(out), *FLAGS, "--fps", "10", "--groundtruth", str(gt)]) == 0
    t_gt, T_gt = Sequence.open(out).groundtruth()
    np.testing.assert_allclose(t_gt, np.arange(len(T)) * 0.1, rtol=0, atol=1e-9)
    np.testing.assert_allclose(T_gt, T, rtol=0, atol=1e-6)


def test_a_bag_with_two_different_ground_truth_poses_at_one_stamp_is_refused(tmp_path, synth, capsys):
    """The bag reader kept the first of poses sharing a stamp, whichever it was (a TUM or EuRoC file
    with two poses at one time is refused); a pose sent twice alike is still one pose."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    _, frames, T = synth
    ts = get_typestore(Stores.ROS2_HUMBLE)
    M = ts.types
    Header, Time, Image = M["std_msgs/msg/Header"], M["builtin_interfaces/msg/Time"], M["sensor_msgs/msg/Image"]
    PoseStamped, Pose = M["geometry_msgs/msg/PoseStamped"], M["geometry_msgs/msg/Pose"]
    Point, Quat = M["geometry_msgs/msg/Point"], M["geometry_msgs/msg/Quaternion"]
    stamps = [1_700_000_000_000_000_000 + 100_000_000 * i for i in range(3)]

    def bag(path, second_x_m):
        with Writer(path, version=9) as w:
            c_img = w.add_connection("/cam/image_raw", Image.__msgtype__, typestore=ts)
            c_gt = w.add_connection("/groundtruth", PoseStamped.__msgtype__, typestore=ts)
            for i, ns in enumerate(stamps):
                h = Header(stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id="cam")
                msg = _mono8(Image, h, frames[i])
                w.write(c_img, ns, ts.serialize_cdr(msg, msg.__msgtype__))
                for x in (0.001 * i, 0.001 * i if i != 1 else second_x_m):  # each pose sent twice
                    p = Pose(position=Point(x=x, y=0.0, z=0.1), orientation=Quat(x=0.0, y=0.0, z=0.0, w=1.0))
                    w.write(c_gt, ns, ts.serialize_cdr(PoseStamped(header=h, pose=p), PoseStamped.__msgtype__))

    bag(tmp_path / "same", 0.001)
    assert main(["import", str(tmp_path / "same"), "-o", str(tmp_path / "a"), *FLAGS, "--height-mm", "100"]) == 0
    np.testing.assert_allclose(Sequence.open(tmp_path / "a").groundtruth()[1][:, 0, 3], [0.0, 1.0, 2.0])
    bag(tmp_path / "two", 0.005)
    err = _one_line_error(capsys, ["import", str(tmp_path / "two"), "-o", str(tmp_path / "b"), *FLAGS])
    assert f"two /groundtruth: two different poses stamped {stamps[1]} ns: ground truth holds one pose per time" in err
    assert not (tmp_path / "b").exists()


def test_a_folder_holding_frames_of_another_format_is_refused_not_read_without_them(tmp_path, synth, capsys):
    """Three PGM frames beside a PNG: the folder was imported as the one PNG, exit 0."""
    _, frames, _ = synth
    src = tmp_path / "frames"
    src.mkdir()
    for i, img in enumerate(frames[:3]):
        cv2.imwrite(str(src / f"f{i}.pgm"), img)
    cv2.imwrite(str(src / "f3.png"), frames[3])
    (src / "notes.txt").write_text("not an image: left alone")
    err = _one_line_error(capsys, ["import", str(src), "-o", str(tmp_path / "s"), *FLAGS, "--fps", "10"])
    assert "holds 3 image file(s) of a format not read as frames ('f0.pgm', ...)" in err
    assert not (tmp_path / "s").exists()


def test_import_states_a_rolling_shutters_readout(tmp_path, synth, capsys):
    """--readout-ms becomes sequence.json's sensor block (a rolling shutter), whose row time the
    estimators undo; a readout longer than a frame interval, or negative, is refused in one line
    before anything is written."""
    _, frames, _ = synth
    src = tmp_path / "frames"
    src.mkdir()
    for i, img in enumerate(frames):
        cv2.imwrite(str(src / f"f{i:02d}.png"), img)
    argv = ["import", str(src), "-o", str(tmp_path / "imp"), *FLAGS, "--height-mm", "100", "--fps", "30"]
    assert main([*argv, "--readout-ms", "15"]) == 0
    seq = Sequence.open(tmp_path / "imp")
    assert seq.meta["sensor"]["shutter"] == "rolling" and seq.meta["sensor"]["readout_ms"] == 15.0
    assert seq.row_time_s == pytest.approx(0.015 / (seq.camera.height_px - 1))
    assert main([*argv[:3], str(tmp_path / "global"), *argv[4:]]) == 0
    assert Sequence.open(tmp_path / "global").row_time_s == 0.0
    for bad in ("40", "-1"):
        err = _one_line_error(capsys, [*argv[:3], str(tmp_path / "bad"), *argv[4:], "--readout-ms", bad])
        assert f"--readout-ms = {float(bad)}: must be a rolling shutter's readout in ms, 0 to the shortest frame" in err
    assert not (tmp_path / "bad").exists()

"""Where a sequence may be written, what --overwrite deletes, what a resume trusts; file modes."""

from __future__ import annotations

import os
import stat

import numpy as np
import pytest

import floorvo.sequence
from floorvo.camera import CameraModel
from floorvo.errors import SequenceError
from floorvo.io import atomic_write_bytes, checked_output_path, remove_stale_temporaries
from floorvo.sequence import SequenceWriter, sequence_files


def _meta(n=3, **extra):
    camera = CameraModel.from_sensor(40, 30, pixel_pitch_um=120.0).to_dict()
    return {"camera": camera, "fps": 10.0, "frame_count": n, **extra}


def _frame(k: int) -> np.ndarray:
    return ((np.arange(30 * 40) * (k + 3)) % 251).astype(np.uint8).reshape(30, 40)


def _one_line(exc: pytest.ExceptionInfo) -> str:
    msg = str(exc.value)
    assert "\n" not in msg
    return msg


# ----------------------------------------------------------------- where a sequence may go
@pytest.mark.parametrize("path", ["", " ", "/", "//", "/tmp/..", "/./"])
def test_empty_path_and_file_system_root_are_refused(path):
    with pytest.raises(SequenceError) as exc:
        checked_output_path(path)
    assert ("empty" in _one_line(exc)) == (path.strip() == "") and path.strip() in str(exc.value)


def test_writer_refuses_root_before_writing_anything(monkeypatch):
    def no_write(*_a, **_k):
        raise AssertionError("the writer went on to write")

    monkeypatch.setattr(floorvo.sequence, "ensure_writable_dir", no_write)
    monkeypatch.setattr(floorvo.sequence, "atomic_write_json", no_write)
    with pytest.raises(SequenceError, match="root of a file system"):
        SequenceWriter("/", _meta())


def test_writer_refuses_empty_path(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SequenceError, match="path is empty") as exc:
        SequenceWriter("", _meta())
    _one_line(exc)
    assert list(tmp_path.iterdir()) == []


def test_writer_refuses_a_foreign_folder_and_takes_an_empty_one(tmp_path):
    (tmp_path / "photos").mkdir()
    (tmp_path / "photos" / "holiday.jpg").write_bytes(b"jpeg")
    with pytest.raises(SequenceError, match="holiday.jpg.*no sequence.json") as exc:
        SequenceWriter(tmp_path / "photos", _meta(), overwrite=True)
    _one_line(exc)
    assert sorted(p.name for p in (tmp_path / "photos").iterdir()) == ["holiday.jpg"]
    (tmp_path / "empty").mkdir()
    SequenceWriter(tmp_path / "empty", _meta())
    assert (tmp_path / "empty" / "sequence.json").is_file()


def test_writer_refuses_a_sequence_json_that_is_not_ours(tmp_path):
    (tmp_path / "seq").mkdir()
    (tmp_path / "seq" / "sequence.json").write_text('{"hello": 1}')
    with pytest.raises(SequenceError, match="not a floorbench sequence") as exc:
        SequenceWriter(tmp_path / "seq", _meta(), overwrite=True)
    _one_line(exc)
    assert (tmp_path / "seq" / "sequence.json").read_text() == '{"hello": 1}'


# ----------------------------------------------------------------- --overwrite
def test_overwrite_deletes_only_the_files_of_the_format(tmp_path):
    root = tmp_path / "seq"
    cam1 = CameraModel.from_sensor(40, 30, pixel_pitch_um=120.0).to_dict()
    T_01 = np.eye(4)
    T_01[0, 3] = 20.0
    stereo = {"stereo": True, "cameras": {"cam1": cam1}, "rig": {"T_cam0_cam1": T_01.tolist()}}
    w = SequenceWriter(root, _meta(3, depth={"format": "npy_float32_mm"}, **stereo))
    for i in range(3):
        w.write_frame(i, _frame(i))
        w.write_frame(i, _frame(i), "cam1")
        w.write_depth(i, np.full((30, 40), 100.0))
    w.write_frame(7, _frame(7))  # a frame beyond the new count: still the format's
    w.write_calib("cam0_flatfield", _frame(9))
    (root / "calib" / "sensor.json").write_text("{}")
    w.write_groundtruth(np.arange(3) / 10.0, np.stack([np.eye(4)] * 3))
    w.write_timestamps(np.arange(3) / 10.0)
    user = {
        "cam0/README.txt": "how I took these",
        "cam0/notes/000001.png": "not a frame: in a subfolder",
        "calib/checkerboard.png": "the user's",
        "notes.md": "mine",
        "depth/000001.png.bak": "a backup",
    }
    for rel, text in user.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text)
    assert len(sequence_files(root)) == 3 * 3 + 1 + 2 + 2
    SequenceWriter(root, _meta(2), overwrite=True)
    assert sequence_files(root) == []
    for rel, text in user.items():
        assert (root / rel).read_text() == text
    assert not (root / "cam0" / "000007.png").exists() and (root / "sequence.json").is_file()


# ----------------------------------------------------------------- resume
def test_resume_rewrites_damaged_frames(tmp_path):
    root = tmp_path / "seq"
    w = SequenceWriter(root, _meta(5, depth={"format": "npy_float32_mm"}))
    for i in range(5):
        w.write_frame(i, _frame(i))
        w.write_depth(i, np.full((30, 40), 100.0 + i))
    png1, png2, png3 = (root / "cam0" / f"00000{i}.png" for i in (1, 2, 3))
    data = png1.read_bytes()
    png1.write_bytes(data[: len(data) // 2])  # cut short
    bad = bytearray(png2.read_bytes())
    bad[len(bad) // 2] ^= 0xFF  # damaged inside, the end intact
    png2.write_bytes(bytes(bad))
    png3.write_bytes(b"")
    npy4 = root / "depth" / "000004.npy"
    npy4.write_bytes(npy4.read_bytes()[:100])
    w2 = SequenceWriter(root, _meta(5, depth={"format": "npy_float32_mm"}))
    assert w2.resumed
    assert w2.missing_frames() == [1, 2, 3, 4]
    assert w2.has_frame(0) and not w2.has_frame(1)


def test_resume_writes_again_a_frame_of_another_type(tmp_path):
    """A resumed render took an 8-bit PNG where its 16-bit depth map should be, or a colour PNG
    where a mono frame should be, as present (floorvo run refused the sequence after)."""
    import cv2

    root = tmp_path / "seq"
    w = SequenceWriter(root, _meta(3, depth={"format": "png16"}, bit_depth=8))
    for i in range(3):
        w.write_frame(i, _frame(i))
        w.write_depth(i, np.full((30, 40), 100.0 + i))
    cv2.imwrite(str(root / "depth" / "000001.png"), np.full((30, 40), 100, np.uint8))  # 8-bit depth
    cv2.imwrite(str(root / "cam0" / "000002.png"), np.dstack([_frame(2)] * 3))  # colour
    w2 = SequenceWriter(root, _meta(3, depth={"format": "png16"}, bit_depth=8))
    assert w2.resumed and w2.missing_frames() == [1, 2]
    # a mono frame of another size (a frame of a smaller render copied in: the run refused it after)
    for i in (1, 2):
        w2.write_frame(i, _frame(i))
        w2.write_depth(i, np.full((30, 40), 100.0 + i))
    cv2.imwrite(str(root / "cam0" / "000000.png"), _frame(0)[:25, :32])
    cv2.imwrite(str(root / "depth" / "000002.png"), (np.full((25, 32), 10000)).astype(np.uint16))
    w3 = SequenceWriter(root, _meta(3, depth={"format": "png16"}, bit_depth=8))
    assert w3.resumed and w3.missing_frames() == [0, 2]


def test_resume_removes_stale_temporaries(tmp_path):
    root = tmp_path / "seq"
    w = SequenceWriter(root, _meta())
    w.write_frame(0, _frame(0))
    stale = [
        root / "cam0" / ".000001.png.0a1b2c3d.tmp",  # this version's name
        root / "cam0" / ".000002.png.k_9zq0x1.tmp",  # tempfile.mkstemp's, from earlier versions
        root / ".groundtruth.txt.ffffffff.tmp",
        root / "calib" / ".sensor.json.12345678.tmp",
    ]
    kept = [root / "cam0" / "notes.tmp", root / "cam0" / ".hidden", root / "cam0" / ".000001.png.toolong99.tmp"]
    for p in stale + kept:
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(b"half a frame")
    SequenceWriter(root, _meta())
    assert not any(p.exists() for p in stale)
    assert all(p.exists() for p in kept)
    assert remove_stale_temporaries(tmp_path / "nowhere") == []


def test_a_folder_holding_only_temporaries_counts_as_empty(tmp_path):
    (tmp_path / "seq").mkdir()
    (tmp_path / "seq" / ".sequence.json.0123abcd.tmp").write_text("{")  # killed before its first rename
    SequenceWriter(tmp_path / "seq", _meta())
    assert sorted(p.name for p in (tmp_path / "seq").iterdir()) == ["sequence.json"]


# ----------------------------------------------------------------- file modes
@pytest.mark.parametrize("mask, mode", [(0o022, 0o644), (0o027, 0o640), (0o077, 0o600)])
def test_outputs_honour_the_umask(tmp_path, mask, mode):
    old = os.umask(mask)
    try:
        atomic_write_bytes(tmp_path / "a.bin", b"x")
        w = SequenceWriter(tmp_path / "seq", _meta())
        w.write_frame(0, _frame(0))
    finally:
        os.umask(old)
    for p in (tmp_path / "a.bin", tmp_path / "seq" / "sequence.json", tmp_path / "seq" / "cam0" / "000000.png"):
        assert stat.S_IMODE(p.stat().st_mode) == mode, p


def test_atomic_write_leaves_no_temporary_on_failure(tmp_path):
    with pytest.raises(TypeError):
        atomic_write_bytes(tmp_path / "x.bin", 12345)  # type: ignore[arg-type]
    assert list(tmp_path.iterdir()) == []

"""Issue 16: bad input and faults give one line naming the thing and the rule (exit code 1),
never a traceback, and impossible values are refused instead of giving wrong output."""

from __future__ import annotations

import errno
import os

import pytest

from floorsim.cli import main as floorsim_main
from floorvo.camera import CameraModel
from floorvo.cli import main as floorvo_main
from floorvo.synthetic import line_poses, write_synthetic_sequence


@pytest.fixture(scope="module")
def small_seq(tmp_path_factory):
    """A 3-frame synthetic sequence at quarter size (with ground truth)."""
    cam = CameraModel.from_sensor().scaled(0.25)
    return write_synthetic_sequence(tmp_path_factory.mktemp("seq") / "seq", cam, line_poses(8.0, 4.0), seed=0)


def _one_line(capsys, prog: str) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"{prog}: error: ") and "Traceback" not in err, err
    return err.strip()


def test_a_full_disk_is_one_line_naming_the_file_and_leaves_no_temporary(small_seq, tmp_path, monkeypatch, capsys):
    def full(fd):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "fsync", full)
    run = tmp_path / "run"
    assert floorvo_main(["run", str(small_seq), "-e", "phase-corr", "-o", str(run)]) == 1
    err = _one_line(capsys, "floorvo")
    assert f"{run}/" in err and "No space left on device (errno 28)" in err
    assert not [p for p in run.iterdir() if p.name.endswith(".tmp")]
    # the same through floorsim (a scene render writes sequence.json first)
    assert floorsim_main(["render", "demo", "--frames", "1", "-o", str(tmp_path / "seq")]) == 1
    err = _one_line(capsys, "floorsim")
    assert f"{tmp_path / 'seq' / 'sequence.json'}: No space left on device (errno 28)" in err


def test_an_unreadable_output_folder_is_one_line(small_seq, tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    assert floorvo_main(["run", str(small_seq), "-e", "phase-corr", "-o", str(blocker / "run")]) == 1
    assert str(blocker) in _one_line(capsys, "floorvo")

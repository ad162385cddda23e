"""Helpers for tests that need a second process: another writer holding a folder's lock,
and the environment that makes a child import this checkout's packages."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import floorvo

#: The ``src`` folder of the floorvo being tested.
SRC = str(Path(floorvo.__file__).resolve().parents[1])

#: A process that locks argv[1], says so, and holds it until its standard input closes.
_HOLD = (
    "import sys\nfrom floorvo.locking import lock_folder\n"
    "lock = lock_folder(sys.argv[1], 'folder')\nprint('held', flush=True)\nsys.stdin.read()\n"
)


def cli(prog: str) -> list[str]:
    """The command line that runs the CLI ``prog`` (``floorvo`` or ``floorsim``) of this checkout
    in a child (with :func:`child_env`); its arguments follow."""
    return [sys.executable, "-c", f"import sys; from {prog}.cli import main; sys.exit(main())"]


def child_env() -> dict[str, str]:
    """This environment, with this checkout's ``src`` first on PYTHONPATH."""
    return {**os.environ, "PYTHONPATH": os.pathsep.join([SRC, os.environ.get("PYTHONPATH", "")])}


@contextlib.contextmanager
def held_by_another_process(folder: Path) -> Iterator[subprocess.Popen]:
    """Another process holding ``folder``'s lock (:func:`floorvo.locking.lock_folder`) for the
    ``with`` block; yields its Popen (``.pid`` is the holder's pid)."""
    p = subprocess.Popen(
        [sys.executable, "-c", _HOLD, str(folder)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        env=child_env(),
    )
    try:
        assert p.stdout is not None and p.stdout.readline().strip() == "held"
        yield p
    finally:
        if p.poll() is None:
            assert p.stdin is not None
            p.stdin.close()
            p.wait(timeout=20)


def assert_refused(err: str, folder: Path, pid: int, what: str) -> None:
    """``err`` is the one-line refusal of a second writer of ``folder`` held by ``pid``."""
    assert "Traceback" not in err and err.strip().count("\n") == 0, err
    assert f"{folder}: another writer (pid {pid}) is writing this {what}" in err, err

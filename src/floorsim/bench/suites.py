"""Named bench suites: a suite file lists scene files that ``floorsim bench --suite`` runs together.

A suite is a TOML file (``scenes/SUITE/suite.toml`` for a shipped suite, or any path)::

    name = "motion"
    description = "turning, fast and disturbed robot motion (issue 14)"
    scenes = ["turn_arc_wood.toml", "turn_arc_asphalt.toml", ...]   # relative to the suite file

:func:`suite_scenes` resolves ``--suite NAME_OR_FILE`` to the scene files, in the order
listed; the bench then runs them as if they had been given on the command line (one
loop: :func:`floorsim.bench.run_bench`). Unknown keys, an empty list and a listed file
that is missing are refused in one line naming the suite file.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from floorsim.scene import scenes_dir
from floorvo.config import Config, build, param
from floorvo.errors import ConfigError, shown
from floorvo.io import read_toml

__all__ = ["SUITE_FILE", "SuiteSpec", "list_suites", "load_suite", "suite_scenes"]

#: The file name of a shipped suite inside its folder (``scenes/motion/suite.toml``).
SUITE_FILE = "suite.toml"


@dataclass(frozen=True)
class SuiteSpec(Config):
    """A suite file's keys: ``name``, ``description`` and ``scenes`` (paths relative to the file)."""

    name: str = param("", doc="the suite's name (default: its folder's)")
    description: str = param("", doc="one line shown by floorsim list")
    scenes: tuple[str, ...] = param((), doc="scene files of the suite, relative to the suite file")

    def validate(self) -> None:
        if not self.scenes:
            raise ConfigError("scenes = []: a suite lists at least one scene file")


def _suite_path(name_or_path: str | os.PathLike) -> Path:
    """The suite file of ``name_or_path``: a file, a folder holding ``suite.toml``, or a shipped suite's name."""
    p = Path(name_or_path)
    for cand in (p, p / SUITE_FILE, scenes_dir() / p.name / SUITE_FILE):
        if cand.is_file():
            return cand
    known = ", ".join(s.parent.name for s in list_suites()) or "none"
    raise ConfigError(f"--suite {shown(str(name_or_path))}: no such suite file or shipped suite (shipped: {known})")


def load_suite(name_or_path: str | os.PathLike) -> tuple[Path, SuiteSpec]:
    """``(suite file, its validated keys)`` for ``--suite NAME_OR_FILE``."""
    path = _suite_path(name_or_path)
    try:
        spec = build(SuiteSpec, read_toml(path, ConfigError))
    except ConfigError as exc:
        raise ConfigError(f"suite {path}: {exc}") from None
    return path, spec


def suite_scenes(name_or_path: str | os.PathLike) -> list[Path]:
    """The scene files of a suite, in the order the suite file lists them (each must exist)."""
    path, spec = load_suite(name_or_path)
    out = []
    for s in spec.scenes:
        scene = path.parent / s
        if not scene.is_file():
            raise ConfigError(f"suite {path}: scene {shown(s)} is not a file (paths are relative to the suite file)")
        out.append(scene)
    return out


def list_suites() -> list[Path]:
    """The suite files shipped under the scenes folder (``scenes/*/suite.toml``)."""
    d = scenes_dir()
    return sorted(d.glob(f"*/{SUITE_FILE}")) if d.is_dir() else []

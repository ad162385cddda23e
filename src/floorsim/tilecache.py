"""Disk cache of floor tiles: the material's height and albedo grids and the mesh's vertex
normals, keyed by the floor's content hash, shared by every render on the machine.

Building a full-size floor tile (4.2 M vertices) spends about 5 s in the material and 1.2 s
in the vertex normals before the mesh reaches Mitsuba; a sweep over lighting or sensor
settings renders the same floor at every point. The cache keeps those arrays:

- **Where**: ``$FLOORSIM_CACHE`` (``off`` disables the cache), else
  ``$XDG_CACHE_HOME/floorsim`` (default ``~/.cache/floorsim``); tiles under ``tiles/``.
- **Key**: SHA-256 of the floor's content (material, its resolved parameters, seed,
  relief scale, dirt and dust densities, mesh spacing, the tile's grid indices) and of the
  code that makes it (the source of the material modules and of the vertex normals), so a
  change to a material's code never serves stale tiles.
- **Size**: at most ``$FLOORSIM_CACHE_MAX_MB`` megabytes (default 4096); after each write
  the least recently used tiles (by modification time, touched on each hit) go first.
- **Concurrency**: each tile is written atomically (:func:`floorvo.io.atomic_write_bytes`:
  a temporary in the same folder, renamed), so a reader sees a whole tile or none; two
  renders that miss the same tile at once both write the same bytes; a tile evicted or
  damaged under a reader is a miss (rebuilt, with a warning when damaged).
- ``floorsim cache clear`` empties it; ``floorsim cache info`` prints where it is and its size.
- **Safety**: clearing and eviction delete only the cache's own entries
  (``tiles/XX/<64 hex digits>.npz`` whose ``XX`` is the key's first two digits, and their
  temporaries), never another file under the folder. ``$FLOORSIM_CACHE`` must be an absolute
  path to a folder (or one to be made) that is not the file-system root, the home folder or a
  folder holding it (:func:`cache_root_problem`); another value is refused in one line.
"""

from __future__ import annotations

import hashlib
import io
import json
import logging
import os
import re
import sys
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from floorsim import materials, render
from floorvo.errors import ConfigError, shown
from floorvo.io import ArrayRule, atomic_write_bytes, code_sha256, plain, read_npz

__all__ = ["TileCache", "default_cache", "cache_root", "cache_root_problem", "CACHE_FORMAT", "DEFAULT_MAX_MB"]

log = logging.getLogger(__name__)

#: Version of the cached arrays' layout; part of every key.
CACHE_FORMAT = 1
#: Default size limit (MB) when ``$FLOORSIM_CACHE_MAX_MB`` is unset.
DEFAULT_MAX_MB = 4096.0
#: A temporary older than this (s) was left by a killed writer; eviction removes it.
_STALE_TEMP_S = 3600.0

#: A cache entry's file name (its key, SHA-256 hex) and an atomic write's temporary of one.
_ENTRY_NAME = re.compile(r"([0-9a-f]{64})\.npz")
_TEMP_NAME = re.compile(r"\.([0-9a-f]{64})\.npz\.[0-9a-f]{8}\.tmp")

TileArrays = tuple[np.ndarray, np.ndarray, np.ndarray]


def cache_root() -> Path | None:
    """The cache folder: ``$FLOORSIM_CACHE``, else the user cache folder; None when ``FLOORSIM_CACHE=off``."""
    env = os.environ.get("FLOORSIM_CACHE")
    if env is not None and env.strip().lower() in ("off", "0", "none", "false"):
        return None
    if env:
        return Path(env).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "floorsim"


def cache_root_problem(root: Path) -> str:
    """Why ``root`` is no folder for the tile cache; "" when it is one. Refused: a relative path
    (a cache in whatever folder a command runs in), an existing file, the file-system root, the
    home folder and the folders holding it (a ``floorsim cache clear`` there would reach into
    every user file beneath)."""
    if not root.is_absolute():
        return "must be an absolute path (a folder for the tile cache, or 'off')"
    if root.exists() and not root.is_dir():
        return "not a folder (a folder for the tile cache, or 'off')"
    real = Path(os.path.realpath(root))
    if real == Path(real.anchor):
        return "is the file-system root: give a folder of its own for the tile cache (e.g. ~/.cache/floorsim)"
    try:
        home = Path(os.path.realpath(Path.home()))
    except (KeyError, RuntimeError):  # no home folder known
        return ""
    if real == home or real in home.parents:
        return "is the home folder or holds it: give a folder of its own for the tile cache (e.g. ~/.cache/floorsim)"
    return ""


def _max_bytes() -> int:
    raw = os.environ.get("FLOORSIM_CACHE_MAX_MB")
    if raw is None or raw == "":
        return int(DEFAULT_MAX_MB * 1e6)
    try:
        mb = float(raw)
    except ValueError:
        mb = float("nan")
    if not np.isfinite(mb) or mb < 0:
        raise ConfigError(f"FLOORSIM_CACHE_MAX_MB = {shown(raw)}: must be a number of megabytes >= 0")
    return int(mb * 1e6)


@cache
def code_fingerprint(material_module: str) -> str:
    """SHA-256 of the source that makes a tile (:func:`floorvo.io.code_sha256`): :mod:`floorsim.materials`,
    the material's own module (a plugin's) and :func:`floorsim.render.heightfield_vertex_normals`."""
    mods = [sys.modules.get(name) or materials for name in dict.fromkeys(["floorsim.materials", material_module])]
    return code_sha256(*mods, render.heightfield_vertex_normals)


@dataclass(frozen=True)
class TileCache:
    """A tile cache in folder ``root`` (see the module docstring) holding at most ``max_bytes``."""

    root: Path
    max_bytes: int = int(DEFAULT_MAX_MB * 1e6)

    @property
    def tiles_dir(self) -> Path:
        return self.root / "tiles"

    # ------------------------------------------------------------------ keys
    @staticmethod
    def key(floor: Mapping[str, Any], material_module: str = "floorsim.materials") -> str:
        """Hex key of a tile: SHA-256 of ``floor`` (plain data: material, parameters, seed, spacing,
        grid indices, ...) with :data:`CACHE_FORMAT` and :func:`code_fingerprint`."""
        doc = {"format": CACHE_FORMAT, "code": code_fingerprint(material_module), "floor": plain(dict(floor))}
        return hashlib.sha256(json.dumps(doc, sort_keys=True, allow_nan=True).encode()).hexdigest()

    def path(self, key: str) -> Path:
        return self.tiles_dir / key[:2] / f"{key}.npz"

    # ------------------------------------------------------------------ get / put
    def get(self, key: str, shape: tuple[int, int]) -> TileArrays | None:
        """(height (ny, nx), albedo (ny, nx), normals (ny, nx, 3)) float32 of tile ``key``, or None.

        A file that does not hold those arrays (damaged, cut short), or holds a value that is not
        finite, is a miss, logged."""
        p = self.path(key)
        if not p.is_file():
            return None

        def rule(*expected: int) -> ArrayRule:
            return lambda s, dtype: None if s == expected and dtype == np.float32 else f"must be float32 {expected}"

        rules = {"height_mm": rule(*shape), "albedo": rule(*shape), "normals": rule(*shape, 3)}
        try:  # each header checked before its data is read (a damaged header may state terabytes)
            z = read_npz(p, rules, str(p), "tile", ConfigError)
        except ConfigError as exc:
            log.warning("damaged tile in the cache: %s; building it again", exc)
            return None
        h, a, n = z["height_mm"], z["albedo"], z["normals"]
        bad = [k for k, v in (("height_mm", h), ("albedo", a), ("normals", n)) if not np.isfinite(v).all()]
        if bad:  # well formed, values damaged: a NaN height raised from inside the renderer
            log.warning("damaged tile in the cache: %s: %s not finite; building it again", p, ", ".join(bad))
            return None
        try:
            os.utime(p)  # recently used: evicted last
        except OSError:
            pass
        return h, a, n

    def put(self, key: str, arrays: TileArrays) -> None:
        """Store a tile atomically, then evict least recently used tiles beyond :attr:`max_bytes`.

        A cache that cannot be written (read-only, full disk) only logs a warning: the render goes on."""
        h, a, n = arrays
        buf = io.BytesIO()
        np.savez(buf, height_mm=h, albedo=a, normals=n)
        try:
            atomic_write_bytes(self.path(key), buf.getvalue())
        except OSError as exc:
            log.warning("tile cache %s: cannot write (%s); going on without it", self.root, exc.strerror or exc)
            return
        self.evict(keep=self.path(key))

    def load_or_build(self, key: str, shape: tuple[int, int], build: Callable[[], TileArrays]) -> TileArrays:
        """The tile from the cache, or ``build()``'s arrays, stored."""
        got = self.get(key, shape)
        if got is not None:
            log.debug("tile cache hit %s", key[:12])
            return got
        arrays = build()
        self.put(key, arrays)
        return arrays

    # ------------------------------------------------------------------ housekeeping
    def _files(self) -> list[Path]:
        """The cache's entries (see the module doc: key-named files in their key's folder), nothing else."""
        return self._keyed("*/*.npz", _ENTRY_NAME)

    def _temporaries(self) -> list[Path]:
        """Temporaries of the cache's entries (an atomic write's, perhaps left by a killed writer)."""
        return self._keyed("*/.*.tmp", _TEMP_NAME)

    def _keyed(self, pattern: str, name: re.Pattern[str]) -> list[Path]:
        """The files under the tiles folder matching the glob ``pattern`` whose name is ``name``
        (its first group the key) and whose folder is the key's first two characters, sorted."""
        d = self.tiles_dir
        if not d.is_dir():
            return []
        out = []
        for p in d.glob(pattern):
            m = name.fullmatch(p.name)
            if m and p.parent.name == m.group(1)[:2]:
                out.append(p)
        return sorted(out)

    def size_bytes(self) -> tuple[int, int]:
        """(number of tiles, their total bytes)."""
        n = total = 0
        for p in self._files():
            try:
                total += p.stat().st_size
                n += 1
            except FileNotFoundError:
                pass
        return n, total

    def evict(self, keep: Path | None = None) -> int:
        """Delete least recently used tiles until the cache holds at most :attr:`max_bytes` (never
        ``keep``, the tile just written), and temporaries older than an hour. Returns the tiles deleted."""
        entries = []
        now = time.time()
        for p in self._temporaries():
            try:
                if now - p.stat().st_mtime > _STALE_TEMP_S:
                    p.unlink()
            except FileNotFoundError:
                pass
        for p in self._files():
            try:
                st = p.stat()
            except FileNotFoundError:
                continue
            entries.append((st.st_mtime, p, st.st_size))
        total = sum(e[2] for e in entries)
        removed = 0
        for _, p, size in sorted(entries, key=lambda e: (e[0], str(e[1]))):
            if total <= self.max_bytes:
                break
            if keep is not None and p == keep:
                continue
            p.unlink(missing_ok=True)
            total -= size
            removed += 1
        return removed

    def clear(self) -> tuple[int, int]:
        """Delete every tile (and temporary) of the cache; returns (tiles, bytes) deleted."""
        n, total = self.size_bytes()
        for p in self._files():
            p.unlink(missing_ok=True)
        for p in self._temporaries():
            p.unlink(missing_ok=True)
        if self.tiles_dir.is_dir():
            for d in self.tiles_dir.iterdir():
                if d.is_dir() and re.fullmatch(r"[0-9a-f]{2}", d.name):
                    try:
                        d.rmdir()  # only when empty
                    except OSError:
                        pass
        return n, total


def default_cache() -> TileCache | None:
    """The cache the environment names (:func:`cache_root`, ``$FLOORSIM_CACHE_MAX_MB``), or None when off.

    A ``FLOORSIM_CACHE`` that is no folder for a cache (:func:`cache_root_problem`: a file, the
    file-system root, the home folder, a relative path) is refused in one line."""
    root = cache_root()
    if root is None:
        return None
    problem = cache_root_problem(root)
    if problem:
        source = "FLOORSIM_CACHE" if os.environ.get("FLOORSIM_CACHE") else "the tile cache folder"
        raise ConfigError(f"{source} = {shown(str(root))}: {problem}")
    return TileCache(root, _max_bytes())

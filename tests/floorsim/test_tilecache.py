"""The disk cache of floor tiles: keyed by content, bit-identical frames, size limit, damage, concurrency, CLI."""

from __future__ import annotations

import os
import threading
import time

import numpy as np
import pytest
from _tiny import tiny_scene

import floorsim.render
import floorsim.simulate
from floorsim.cli import main
from floorsim.simulate import render_sequence
from floorsim.tilecache import TileCache, default_cache
from floorvo.errors import ConfigError
from floorvo.sequence import Sequence


def _arrays(seed: int, shape=(40, 50)):
    rng = np.random.default_rng(seed)
    return tuple(rng.standard_normal(s).astype(np.float32) for s in (shape, shape, (*shape, 3)))


@pytest.mark.render
def test_a_warm_cache_skips_the_floor_and_gives_the_same_frames(tmp_path, monkeypatch):
    monkeypatch.setenv("FLOORSIM_CACHE", str(tmp_path / "cache"))
    calls = {"material": 0, "normals": 0}
    sample, normals = floorsim.simulate.sample_material, floorsim.render.heightfield_vertex_normals

    def counted_sample(*a, **k):
        calls["material"] += 1
        return sample(*a, **k)

    def counted_normals(xs, ys, height, *a, **k):
        calls["normals"] += np.shape(height) != (2, 2)  # not the flat-field frame's flat floor
        return normals(xs, ys, height, *a, **k)

    monkeypatch.setattr(floorsim.simulate, "sample_material", counted_sample)
    monkeypatch.setattr(floorsim.render, "heightfield_vertex_normals", counted_normals)
    cold = Sequence.open(render_sequence(tiny_scene(), tmp_path / "cold"))
    assert calls["material"] >= 1 and calls["normals"] >= 1
    n_tiles, size = default_cache().size_bytes()
    assert n_tiles == calls["material"] and size > 0
    calls.update(material=0, normals=0)
    warm = Sequence.open(render_sequence(tiny_scene(), tmp_path / "warm"))
    assert calls == {"material": 0, "normals": 0}
    for i in range(cold.frame_count):
        np.testing.assert_array_equal(warm.image(i), cold.image(i))
    # Another floor (seed) is another tile; another light is the same tile.
    render_sequence(tiny_scene(**{"floor.seed": 5, "trajectory.distance_mm": 4.0}), tmp_path / "seed5")
    assert calls["material"] >= 1
    calls.update(material=0)
    render_sequence(tiny_scene(**{"lights.height_mm": 6.0}), tmp_path / "led6")
    assert calls["material"] == 0


def test_keys_follow_the_floor_content():
    base = {"material": "vinyl", "params": {"bump_amplitude_mm": 0.03}, "seed": 1, "spacing_mm": 0.25, "grid": [0, 9]}
    k = TileCache.key(base)
    assert k == TileCache.key(dict(base)) and len(k) == 64
    for change in ({"seed": 2}, {"spacing_mm": 0.3}, {"grid": [1, 10]}, {"params": {"bump_amplitude_mm": 0.04}}):
        assert TileCache.key({**base, **change}) != k, change


def test_size_limit_evicts_the_least_recently_used(tmp_path):
    one = len(_tile_bytes())
    cache = TileCache(tmp_path, max_bytes=int(2.5 * one))
    for i, key in enumerate(("a" * 64, "b" * 64)):
        cache.put(key, _arrays(i))
    import os
    import time

    os.utime(cache.path("a" * 64), (time.time() - 100, time.time() - 100))
    os.utime(cache.path("b" * 64), (time.time() - 50, time.time() - 50))
    assert cache.get("a" * 64, (40, 50)) is not None  # a hit makes "a" the most recent
    cache.put("c" * 64, _arrays(2))
    assert cache.get("b" * 64, (40, 50)) is None
    assert cache.get("a" * 64, (40, 50)) is not None and cache.get("c" * 64, (40, 50)) is not None
    assert cache.size_bytes()[1] <= 2.5 * one


def _tile_bytes() -> bytes:
    import io

    buf = io.BytesIO()
    h, a, n = _arrays(0)
    np.savez(buf, height_mm=h, albedo=a, normals=n)
    return buf.getvalue()


def test_a_tile_whose_header_states_another_shape_is_built_again_unread(tmp_path, caplog):
    """np.load allocated the shape a damaged member's header stated before reading its data."""
    import io
    import zipfile

    cache = TileCache(tmp_path)
    key = "e" * 64
    cache.put(key, _arrays(0))
    head = io.BytesIO()
    np.lib.format.write_array_header_1_0(head, {"descr": "<f4", "fortran_order": False, "shape": (10**6, 10**6)})
    with zipfile.ZipFile(cache.path(key), "a") as zf, pytest.warns(UserWarning, match="Duplicate name"):
        zf.writestr("height_mm.npy", head.getvalue())  # the last member of a name is the one read
    assert cache.get(key, (40, 50)) is None
    assert "damaged tile" in caplog.text and "must be float32 (40, 50)" in caplog.text


def test_a_damaged_tile_is_built_again(tmp_path, caplog):
    cache = TileCache(tmp_path)
    key = "d" * 64
    cache.put(key, _arrays(0))
    p = cache.path(key)
    p.write_bytes(p.read_bytes()[:300])  # cut short
    assert cache.get(key, (40, 50)) is None
    assert "damaged tile" in caplog.text
    got = cache.load_or_build(key, (40, 50), lambda: _arrays(0))
    for x, y in zip(got, _arrays(0)):
        np.testing.assert_array_equal(x, y)
    assert cache.get(key, (40, 50)) is not None
    assert cache.get(key, (41, 50)) is None  # a tile of another shape is not served


def test_a_tile_with_values_that_are_not_finite_is_built_again(tmp_path, caplog):
    """A well-formed tile holding NaN heights was served, and the render raised 'cannot convert
    float NaN to integer' from inside the renderer."""
    cache = TileCache(tmp_path)
    key = "f" * 64
    h, a, n = _arrays(0)
    h = h.copy()
    h[3, 4] = np.nan
    cache.put(key, (h, a, n))
    assert cache.get(key, (40, 50)) is None
    assert "damaged tile in the cache" in caplog.text and "height_mm not finite" in caplog.text
    got = cache.load_or_build(key, (40, 50), lambda: _arrays(0))
    assert np.isfinite(got[0]).all() and cache.get(key, (40, 50)) is not None


def test_concurrent_writers_of_one_tile_leave_one_whole_tile(tmp_path):
    cache = TileCache(tmp_path)
    key = "e" * 64
    out: list = []
    start = threading.Barrier(6)

    def work():
        start.wait()
        out.append(cache.load_or_build(key, (40, 50), lambda: _arrays(3)))

    threads = [threading.Thread(target=work) for _ in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(out) == 6
    for got in out:
        np.testing.assert_array_equal(got[2], _arrays(3)[2])
    assert [p.name for p in cache.path(key).parent.iterdir()] == [cache.path(key).name]  # no temporaries


def test_cache_cli_info_clear_and_bad_settings(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("FLOORSIM_CACHE", str(tmp_path / "c"))
    TileCache(tmp_path / "c").put("f" * 64, _arrays(0))
    assert main(["cache", "info"]) == 0
    assert "1 tiles" in capsys.readouterr().out
    assert main(["cache", "clear"]) == 0
    assert "deleted 1 tiles" in capsys.readouterr().out
    assert TileCache(tmp_path / "c").size_bytes() == (0, 0)
    (tmp_path / "file").write_text("x")
    monkeypatch.setenv("FLOORSIM_CACHE", str(tmp_path / "file"))
    assert main(["cache", "info"]) == 1
    err = capsys.readouterr().err.strip()
    assert "FLOORSIM_CACHE" in err and "not a folder" in err and "\n" not in err
    monkeypatch.setenv("FLOORSIM_CACHE", str(tmp_path / "c"))
    monkeypatch.setenv("FLOORSIM_CACHE_MAX_MB", "lots")
    assert main(["cache", "info"]) == 1
    assert "FLOORSIM_CACHE_MAX_MB = 'lots'" in capsys.readouterr().err
    monkeypatch.setenv("FLOORSIM_CACHE", "off")
    assert default_cache() is None


@pytest.mark.parametrize("which", ["/", "home", "home_parent", "relative"])
def test_a_cache_folder_that_is_root_or_home_is_refused_before_anything_is_deleted(
    tmp_path, monkeypatch, capsys, which
):
    """FLOORSIM_CACHE=/ (or ~) was accepted, and ``floorsim cache clear`` then deleted every
    ``tiles/*/*.npz`` beneath it; such a folder is refused in one line naming the rule."""
    home = tmp_path / "home" / "me"
    home.mkdir(parents=True)
    monkeypatch.setenv("HOME", str(home))
    value = {"/": "/", "home": str(home), "home_parent": str(home.parent), "relative": "cache"}[which]
    monkeypatch.setenv("FLOORSIM_CACHE", value)
    mine = home / "tiles" / "aa" / ("a" * 64 + ".npz")  # a user's file that looks like a tile
    mine.parent.mkdir(parents=True)
    mine.write_bytes(b"mine")
    assert main(["cache", "clear"]) == 1
    err = capsys.readouterr().err.strip()
    rule = {"/": "file-system root", "home": "home folder", "home_parent": "holds it", "relative": "absolute path"}
    assert err.startswith("floorsim: error: FLOORSIM_CACHE = ") and rule[which] in err and "\n" not in err
    assert mine.read_bytes() == b"mine"
    with pytest.raises(ConfigError, match="FLOORSIM_CACHE"):
        default_cache()


def test_clear_and_evict_delete_only_the_caches_own_entries(tmp_path):
    """A cache folder shared with other files: clear and eviction touch only key-named tiles in
    their key's folder (and their temporaries), never another ``.npz`` or ``.tmp``."""
    cache = TileCache(tmp_path / "c", max_bytes=0)
    cache.put("d" * 64, _arrays(0))  # evicted at once by max_bytes=0 except the one just written
    others = [
        cache.tiles_dir / "notes" / "data.npz",
        cache.tiles_dir / "dd" / "results.npz",
        cache.tiles_dir / "ee" / ("d" * 64 + ".npz"),  # a key-like name in the wrong folder
        cache.tiles_dir / "dd" / ".x.tmp",
    ]
    for p in others:
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(b"not ours")
        os.utime(p, (time.time() - 7200, time.time() - 7200))
    stale = cache.tiles_dir / "dd" / f".{'d' * 64}.npz.0123abcd.tmp"
    stale.write_bytes(b"half")
    os.utime(stale, (time.time() - 7200, time.time() - 7200))
    cache.put("e" * 64, _arrays(1))
    assert not cache.path("d" * 64).exists() and not stale.exists()  # evicted: ours
    size = cache.path("e" * 64).stat().st_size
    assert cache.clear() == (1, size)
    assert not cache.path("e" * 64).exists()
    for p in others:
        assert p.read_bytes() == b"not ours", p

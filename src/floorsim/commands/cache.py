"""``floorsim cache clear`` / ``floorsim cache info``: the disk cache of floor tiles (floorsim.tilecache)."""

from __future__ import annotations


def add_parser(sub) -> None:
    p = sub.add_parser("cache", help="the disk cache of floor tiles: where it is, its size; clear it")
    p.add_argument("action", choices=("info", "clear"), help="info: folder, tiles and size; clear: delete every tile")
    p.set_defaults(func=run)


def run(args) -> int:
    from floorsim.tilecache import default_cache

    cache = default_cache()
    if cache is None:
        print("tile cache: off (FLOORSIM_CACHE=off)")
        return 0
    if args.action == "clear":
        n, size = cache.clear()
        print(f"tile cache {cache.root}: deleted {n} tiles ({size / 1e6:.1f} MB)")
    else:
        n, size = cache.size_bytes()
        print(f"tile cache {cache.root}: {n} tiles, {size / 1e6:.1f} MB of at most {cache.max_bytes / 1e6:.0f} MB")
    return 0

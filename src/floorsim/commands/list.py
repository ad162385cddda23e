"""``floorsim list``: materials, trajectory types and shipped scenes."""

from __future__ import annotations


def add_parser(sub) -> None:
    p = sub.add_parser("list", help="list materials, trajectory types and shipped scenes")
    p.set_defaults(func=run)


def run(args) -> int:
    import tomllib

    from floorsim.materials import MATERIALS
    from floorsim.scene import list_scenes
    from floorsim.trajectories import TRAJECTORIES

    print("materials:")
    for name, m in sorted(MATERIALS.items()):
        print(f"  {name:<14} {m.description}")
    print("trajectories:")
    for name, t in TRAJECTORIES.items():
        print(f"  {name:<14} {t.description}")
    print("scenes:")
    for path in list_scenes():
        try:
            desc = tomllib.loads(path.read_text()).get("description", "")
        except (tomllib.TOMLDecodeError, OSError):
            desc = "(unreadable)"
        print(f"  {path.stem:<24} {desc}")
    return 0

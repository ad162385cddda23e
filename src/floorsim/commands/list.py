"""``floorsim list``: materials, trajectory types, bench protocols and shipped scenes; ``--scene-keys``: every
scene key."""

from __future__ import annotations


def add_parser(sub) -> None:
    p = sub.add_parser("list", help="list materials, trajectory types, bench protocols and shipped scenes")
    p.add_argument(
        "--scene-keys",
        action="store_true",
        help="print every key a scene file (or --set SECTION.KEY=VALUE) takes: type, default, unit and rule",
    )
    p.set_defaults(func=run)


def print_scene_keys() -> None:
    from floorsim.materials import MATERIALS
    from floorsim.scene import Scene
    from floorsim.trajectories import TRAJECTORIES, Disturbance
    from floorvo.config import describe_fields, format_fields

    print("scene keys (a scene file's tables, or --set SECTION.KEY=VALUE):")
    print(format_fields(describe_fields(Scene), indent="  "))
    print('trajectory keys, by trajectory.type (e.g. [trajectory] type = "uniform"):')
    for name, t in TRAJECTORIES.items():
        print(f"  {name}: {t.description}")
        print(format_fields(describe_fields(t.Params, "trajectory"), indent="    "))
    print("  any type:")
    print(format_fields(describe_fields(Disturbance, "trajectory.disturbance"), indent="    "))
    print('floor.params keys, by floor.material (e.g. [floor] material = "vinyl"):')
    for name, m in sorted(MATERIALS.items()):
        print(f"  {name}: {m.description}")
        print(format_fields(describe_fields(m.Params, "floor.params"), indent="    "))


def run(args) -> int:
    # Imported when the command runs, as in every command module: `floorsim --help` stays quick.

    from floorsim.bench.protocols import PROTOCOLS
    from floorsim.materials import MATERIALS
    from floorsim.scene import list_scenes
    from floorsim.trajectories import TRAJECTORIES
    from floorvo.errors import ConfigError
    from floorvo.io import read_toml

    if args.scene_keys:
        print_scene_keys()
        return 0
    print("materials:")
    for name, m in sorted(MATERIALS.items()):
        print(f"  {name:<14} {m.description}")
    print("trajectories:")
    for name, t in TRAJECTORIES.items():
        print(f"  {name:<14} {t.description}")
    print("bench protocols (a scene's [bench] protocols = [NAME]):")
    for name, proto in PROTOCOLS.items():
        print(f"  {name:<24} {proto.description}")
    print("scenes:")
    for path in list_scenes():
        try:
            desc = str(read_toml(path, ConfigError).get("description", ""))
        except ConfigError:
            desc = "(unreadable)"
        print(f"  {path.stem:<24} {desc}")
    return 0

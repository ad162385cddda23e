"""``floorvo list``: the registered estimators, a line each."""

from __future__ import annotations


def add_parser(sub) -> None:
    p = sub.add_parser("list", help="list the registered estimators")
    p.set_defaults(func=run)


def run(args) -> int:
    from floorvo.estimators import REGISTRY, list_estimators

    for name in list_estimators():
        cls = REGISTRY[name]
        req = f" [needs {', '.join(sorted(cls.requires))}]" if cls.requires else ""
        print(f"{name:<18} {cls.description}{req}")
    return 0

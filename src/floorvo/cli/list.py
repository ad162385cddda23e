"""``floorvo list``: the estimators, a line each; ``--config NAME``: a config's fields.

Built-ins first by name with plugins among them (marked with their package and version);
installed plugins that cannot be loaded follow as ``unavailable`` with their one-line reason.
"""

from __future__ import annotations

from floorvo.errors import ConfigError

#: Configurations that are not an estimator's: the ``--set`` keys of ``floorvo map`` and
#: ``floorvo localize``, and the keys of a sequence folder's ``sequence.json``.
COMMAND_CONFIGS = {
    "map": "floorvo map --set KEY=VALUE",
    "localize": "floorvo localize --set KEY=VALUE (--map and --odometry are options)",
    "sequence": "sequence.json of a sequence folder (floorvo import writes it; tables hold nested keys)",
}


def add_parser(sub) -> None:
    p = sub.add_parser("list", help="list the registered estimators, or the fields of one configuration")
    p.add_argument(
        "--config",
        metavar="NAME",
        help="print the fields of an estimator's config (NAME: an estimator), of 'map' or 'localize', or the keys "
        "of 'sequence' (sequence.json): key, type, default, unit and rule",
    )
    p.set_defaults(func=run)


def _config_class(name: str) -> tuple[type, str, tuple[str, ...]]:
    """(config class, heading, keys left out) for ``floorvo list --config NAME``."""
    from floorvo.estimators import get_estimator, list_estimators, unavailable_estimators

    if name == "map":
        from floorvo.mapping.map import MapConfig

        return MapConfig, COMMAND_CONFIGS[name], ()
    if name == "localize":
        from floorvo.mapping.localize_run import SET_BY_OPTIONS, MapFusedConfig

        return MapFusedConfig, COMMAND_CONFIGS[name], SET_BY_OPTIONS
    if name == "sequence":
        from floorvo.sequence_meta import SequenceMeta

        return SequenceMeta, COMMAND_CONFIGS[name], ()
    if name not in list_estimators() and ":" not in name:
        failed = unavailable_estimators()
        if name in failed:  # an installed plugin that does not load: why, as `floorvo list` says
            raise ConfigError(f"--config {name!r}: the plugin is unavailable: {failed[name]}")
        known = ", ".join([*list_estimators(), *COMMAND_CONFIGS])
        raise ConfigError(f"--config {name!r}: no such configuration (known: {known})")
    cls = get_estimator(name)
    return cls.Config, f"{name}: {cls.description} (floorvo run -e {name} --set KEY=VALUE)", ()


def run(args) -> int:
    from floorvo.config import describe_fields, format_fields
    from floorvo.estimators import estimator_source, get_estimator, list_estimators, unavailable_estimators

    if args.config:
        cls, heading, exclude = _config_class(args.config)
        print(heading)
        print(format_fields(describe_fields(cls, exclude=exclude), indent="  "))
        return 0
    for name in list_estimators():
        cls = get_estimator(name)
        req = f" [needs {', '.join(sorted(cls.requires))}]" if cls.requires else ""
        source = estimator_source(name)
        origin = "" if source.kind == "built-in" else f" ({source.describe()})"
        print(f"{name:<18} {cls.description}{req}{origin}")
    for name, reason in unavailable_estimators().items():
        print(f"{name:<18} unavailable: {reason}")
    return 0

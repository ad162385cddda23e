"""Validated frozen parameter dataclasses, shared by scene sections and trajectory types.

A field declares its rule in ``metadata``: ``field(default=..., metadata=rule(">0", "mm"))``.
:func:`from_mapping` builds a dataclass from a plain dict (a TOML table), refusing unknown
keys, wrong types and values that break a rule, each with one line that names the key,
the value and the rule.
"""

from __future__ import annotations

import dataclasses
import math
import typing
from collections.abc import Mapping
from typing import Any

from floorvo.errors import ConfigError

__all__ = ["rule", "from_mapping", "check_rules", "to_plain"]

_OPS = {
    ">0": (lambda v: v > 0, "must be > 0"),
    ">=0": (lambda v: v >= 0, "must be >= 0"),
    ">=1": (lambda v: v >= 1, "must be >= 1"),
    "[0,1]": (lambda v: 0 <= v <= 1, "must be within [0, 1]"),
    "any": (lambda v: True, ""),
}


def rule(
    check: str = "any",
    unit: str = "",
    help: str = "",
    choices: tuple | None = None,
    lo: float | None = None,
    hi: float | None = None,
) -> dict:
    """Metadata for a dataclass field: a named check, a unit, a help line, choices or a [lo, hi] range."""
    return {"check": check, "unit": unit, "help": help, "choices": choices, "lo": lo, "hi": hi}


def _type_ok(value: Any, tp: Any) -> tuple[bool, Any]:
    """(ok, converted value) for the simple field types used here."""
    origin = typing.get_origin(tp)
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return False, value
        return True, float(value)
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            if isinstance(value, float) and value.is_integer():
                return True, int(value)
            return False, value
        return True, value
    if tp is bool:
        return isinstance(value, bool), value
    if tp is str:
        return isinstance(value, str), value
    if origin is tuple:
        args = typing.get_args(tp)
        if not isinstance(value, (list, tuple)):
            return False, value
        inner = args[0] if args else Any
        out = []
        for v in value:
            ok, cv = _type_ok(v, inner) if inner is not Any and inner is not Ellipsis else (True, v)
            if not ok:
                return False, value
            out.append(cv)
        return True, tuple(out)
    if origin is typing.Union or str(origin) == "types.UnionType":
        args = typing.get_args(tp)
        if value is None and type(None) in args:
            return True, None
        for a in args:
            if a is type(None):
                continue
            ok, cv = _type_ok(value, a)
            if ok:
                return True, cv
        return False, value
    return True, value


def _type_name(tp: Any) -> str:
    if tp is float:
        return "a number"
    if tp is int:
        return "an integer"
    if tp is bool:
        return "true or false"
    if tp is str:
        return "a string"
    if typing.get_origin(tp) is tuple:
        return "a list"
    return str(tp)


def check_rules(obj: Any, prefix: str) -> None:
    """Check every field of dataclass ``obj`` against its ``rule`` metadata."""
    for f in dataclasses.fields(obj):
        meta = f.metadata or {}
        value = getattr(obj, f.name)
        if value is None or isinstance(value, (tuple, dict)) or dataclasses.is_dataclass(value):
            continue
        key = f"{prefix}.{f.name}" if prefix else f.name
        unit = f" {meta.get('unit')}" if meta.get("unit") else ""
        if isinstance(value, float) and not math.isfinite(value):
            raise ConfigError(f"{key} = {value}: must be a finite number")
        choices = meta.get("choices")
        if choices is not None and value not in choices:
            raise ConfigError(f"{key} = {value!r}: must be one of {', '.join(map(repr, choices))}")
        check = meta.get("check", "any")
        fn, text = _OPS[check]
        if not fn(value):
            raise ConfigError(f"{key} = {value}{unit}: {text}")
        lo, hi = meta.get("lo"), meta.get("hi")
        if lo is not None and value < lo or hi is not None and value > hi:
            raise ConfigError(f"{key} = {value}{unit}: must be within [{lo}, {hi}]{unit}")


def from_mapping(
    cls: type, data: Mapping[str, Any] | None, prefix: str, nested: Mapping[str, type] | None = None
) -> Any:
    """Build dataclass ``cls`` from ``data``, refusing unknown keys and wrong types by name.

    ``nested`` maps a field name to the dataclass its sub-table loads into.
    """
    data = dict(data or {})
    nested = dict(nested or {})
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls)}
    for key in data:
        if key not in names:
            where = f"{prefix}.{key}" if prefix else key
            raise ConfigError(f"{where}: unknown key (known: {', '.join(sorted(names))})")
    kwargs = {}
    for key, value in data.items():
        where = f"{prefix}.{key}" if prefix else key
        if key in nested:
            if not isinstance(value, Mapping):
                raise ConfigError(f"{where}: must be a table, got {value!r}")
            kwargs[key] = from_mapping(nested[key], value, where)
            continue
        ok, conv = _type_ok(value, hints[key])
        if not ok:
            raise ConfigError(f"{where} = {value!r}: must be {_type_name(hints[key])}")
        kwargs[key] = conv
    obj = cls(**kwargs)
    check_rules(obj, prefix)
    return obj


def to_plain(obj: Any) -> Any:
    """A dataclass (possibly nested) as plain dicts/lists, for JSON and TOML."""
    if dataclasses.is_dataclass(obj):
        return {f.name: to_plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, (list, tuple)):
        return [to_plain(v) for v in obj]
    if isinstance(obj, dict):
        return {k: to_plain(v) for k, v in obj.items()}
    return obj

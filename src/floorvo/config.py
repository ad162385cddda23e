"""The one configuration mechanism of floorbench: typed, frozen, self-describing dataclasses.

Every configuration (an estimator's ``Config``, the mapping configs, each section of a
floorsim scene, a material's or a trajectory type's parameters) is a frozen dataclass
whose fields are declared with :func:`param`: type (the annotation), default, unit,
bounds (``min``/``max`` inclusive, ``gt``/``lt`` exclusive), choices and a one-line doc::

    @dataclass(frozen=True)
    class LightsSpec(Config):
        height_mm: float = param(3.0, unit="mm", gt=0, doc="LED emitters above the floor")
        side: str = param("both", choices=("both", "left", "right"), doc="which bars are lit")

* :func:`build` makes one from a plain mapping (a TOML table, nested tables for nested
  dataclass fields), refusing unknown keys, wrong types and values that break a rule;
  subclasses of :class:`Config` check their rules on every construction as well, and a
  cross-field rule (``a <= b``) is the class's :meth:`Config.validate` method.
* Every refusal is a one-line :class:`~floorvo.errors.ConfigFieldError` naming the key,
  the value and the rule: ``camera.height_mm = -100.0 mm: must be > 0 mm``.
* ``--set key=value`` strings are split by :func:`parse_set_args` (the one parser, used by
  both CLIs) and placed by :func:`apply_overrides` (dotted keys reach nested tables). Each
  value stays text (:class:`SetText`) until it lands in a field, where it is read by that
  field's type (:func:`parse_text`): ``true/yes/on/1`` for a bool, ``none`` for an optional
  field, a TOML array for a list; in a free-form table (a scene's ``trajectory``) it is read
  as a TOML literal, or kept as text when it is not one.
* :func:`describe_fields` and :func:`format_fields` list the fields (key, type, default,
  unit, rule, doc) for ``floorvo list --config NAME`` and ``floorsim list --scene-keys``.
"""

from __future__ import annotations

import copy
import dataclasses
import difflib
import math
import tomllib
import types
import typing
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from floorvo.errors import MAX_SHOWN_CHARS, ConfigError, ConfigFieldError, shorten, shown

__all__ = [
    "Config",
    "Rule",
    "FieldInfo",
    "SetText",
    "param",
    "build",
    "from_overrides",
    "check",
    "parse_set_args",
    "parse_text",
    "apply_overrides",
    "describe_fields",
    "format_fields",
    "to_plain",
    "with_defaults",
    "MAX_SEED",
]

#: The largest seed any configuration takes (``param(..., max=MAX_SEED)``): OpenCV's RNG, which
#: the estimators and the map seed, takes a C int (a larger seed ended in a ValueError or
#: OverflowError traceback), and Mitsuba's sampler 32 bits (seeds 2^32 apart rendered alike).
MAX_SEED = 2**31 - 1

_MISSING: Any = dataclasses.MISSING
_C = typing.TypeVar("_C")
_META = "floorbench.rule"


@dataclass(frozen=True)
class Rule:
    """What a field declares besides its type and default (see :func:`param`)."""

    unit: str = ""
    doc: str = ""
    min: float | None = None
    max: float | None = None
    gt: float | None = None
    lt: float | None = None
    choices: tuple | None = None

    def violation(self, value: Any) -> str | None:
        """The broken part of the rule as ``"must be ..."`` (unit included), or None."""
        if self.choices is not None and value not in self.choices:
            return f"must be one of {', '.join(map(repr, self.choices))}"
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return None
        if isinstance(value, float) and not math.isfinite(value):
            return "must be a finite number"
        unit = f" {self.unit}" if self.unit else ""
        for op, bound, ok in (
            (">", self.gt, lambda b: value > b),
            (">=", self.min, lambda b: value >= b),
            ("<", self.lt, lambda b: value < b),
            ("<=", self.max, lambda b: value <= b),
        ):
            if bound is not None and not ok(bound):
                return f"must be {op} {bound}{unit}"
        return None

    def describe(self) -> str:
        """The rule in a few characters (no unit): ``> 0``, ``[0, 1]``, ``one of 'a', 'b'``."""
        if self.choices is not None:
            return f"one of {', '.join(map(repr, self.choices))}"
        lower = (self.gt, "(", ">") if self.gt is not None else (self.min, "[", ">=")
        upper = (self.lt, ")", "<") if self.lt is not None else (self.max, "]", "<=")
        parts = []
        if self.gt is not None and self.min is not None:  # a positive quantity with a floor
            parts.append(f"> {self.gt}")
            lower = (self.min, "[", ">=")
        if lower[0] is not None and upper[0] is not None:
            parts.append(f"{lower[1]}{lower[0]}, {upper[0]}{upper[1]}")
        elif lower[0] is not None:
            parts.append(f"{lower[2]} {lower[0]}")
        elif upper[0] is not None:
            parts.append(f"{upper[2]} {upper[0]}")
        return ", ".join(parts)


def param(
    default: Any = _MISSING,
    *,
    default_factory: Any = _MISSING,
    unit: str = "",
    doc: str = "",
    min: float | None = None,
    max: float | None = None,
    gt: float | None = None,
    lt: float | None = None,
    choices: Iterable | None = None,
) -> Any:
    """A dataclass field with its rule: ``x_mm: float = param(1.0, unit="mm", gt=0, doc="...")``.

    ``min``/``max`` are inclusive bounds, ``gt``/``lt`` exclusive ones; ``choices`` the
    allowed values; ``unit`` is shown after the value in errors and listings; ``doc`` is the
    field's one-line description.
    """
    rule = Rule(unit, doc, min, max, gt, lt, tuple(choices) if choices is not None else None)
    return dataclasses.field(default=default, default_factory=default_factory, metadata={_META: rule})


def rule_of(f: dataclasses.Field) -> Rule:
    """The :class:`Rule` a field declared (an empty one for a plain field)."""
    return f.metadata.get(_META) or Rule()


class Config:
    """Base of every configuration dataclass: its rules are checked on each construction.

    ``config_name`` prefixes the keys of errors raised by a direct construction
    (``SimilarityConfig(ratio=2)`` -> ``similarity.ratio = 2: must be <= 1``); :func:`build`
    names them by where they were read instead. Override :meth:`validate` for a rule that
    ties several fields together, raising :class:`~floorvo.errors.ConfigFieldError`.
    """

    config_name: ClassVar[str] = ""

    def __post_init__(self) -> None:
        try:
            check(self)
        except ConfigFieldError as exc:
            raise exc.under(type(self).config_name) from None

    def validate(self) -> None:
        """Cross-field rules; the default has none."""


class SetText(str):
    """A ``--set`` value: text that is read by the type of the field it lands in."""


# ----------------------------------------------------------------------------- types
def _optional_inner(tp: Any) -> Any | None:
    """X for ``X | None``, else None."""
    origin = typing.get_origin(tp)
    if origin is typing.Union or origin is types.UnionType:
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if len(args) == 1 and len(typing.get_args(tp)) == 2:
            return args[0]
    return None


def _is_table(tp: Any) -> bool:
    return tp is dict or typing.get_origin(tp) in (dict, Mapping)


def _nested_config(tp: Any) -> type | None:
    """The dataclass of a nested table field: ``Spec`` for ``Spec`` or ``Spec | None``, else None."""
    inner = _optional_inner(tp)
    cand = tp if inner is None else inner
    return cand if dataclasses.is_dataclass(cand) and isinstance(cand, type) else None


def type_name(tp: Any) -> str:
    """The field type as a listing shows it: ``float``, ``int | none``, ``list of float``."""
    inner = _optional_inner(tp)
    if inner is not None:
        return f"{type_name(inner)} | none"
    if typing.get_origin(tp) is tuple:
        args = [a for a in typing.get_args(tp) if a is not Ellipsis]
        return f"list of {type_name(args[0])}" if args else "list"
    if _is_table(tp):
        return "table"
    return getattr(tp, "__name__", str(tp))


def _expected(tp: Any) -> str:
    """The type in an error: ``must be a number``."""
    inner = _optional_inner(tp)
    if inner is not None:
        return f"{_expected(inner)} or none"
    if tp is float:
        return "a number"
    if tp is int:
        return "integer"
    if tp is bool:
        return "true or false"
    if tp is str:
        return "a string"
    if typing.get_origin(tp) is tuple:
        return "a list"
    if _is_table(tp) or dataclasses.is_dataclass(tp):
        return "a table"
    return type_name(tp)


def _coerce(value: Any, tp: Any) -> tuple[bool, Any]:
    """(ok, value converted to ``tp``) for a value read from a file or already parsed."""
    if tp is Any:
        return True, value
    inner = _optional_inner(tp)
    if inner is not None:
        return (True, None) if value is None else _coerce(value, inner)
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return False, value
        return True, float(value)
    if tp is int:
        if isinstance(value, bool):
            return False, value
        if isinstance(value, int):
            return True, int(value)
        if isinstance(value, float) and value.is_integer():
            return True, int(value)
        return False, value
    if tp is bool:
        return isinstance(value, bool), value
    if tp is str:
        return isinstance(value, str), str(value) if isinstance(value, str) else value
    if typing.get_origin(tp) is tuple:
        if not isinstance(value, (list, tuple)):
            return False, value
        args = [a for a in typing.get_args(tp) if a is not Ellipsis]
        out = []
        for v in value:
            ok, cv = _coerce(v, args[0]) if args else (True, v)
            if not ok:
                return False, value
            out.append(cv)
        return True, tuple(out)
    if _is_table(tp):
        return isinstance(value, Mapping), dict(value) if isinstance(value, Mapping) else value
    return isinstance(value, tp) if isinstance(tp, type) else True, value


_TRUE = ("1", "true", "yes", "on")
_FALSE = ("0", "false", "no", "off")


def _toml_literal(text: str) -> Any:
    """``text`` read as a TOML value (``80``, ``true``, ``[1, 2]``, ``"a"``), or the text itself."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return str(text)


def parse_text(text: str, tp: Any = Any) -> Any:
    """Read one ``--set`` value by the type ``tp`` of the field it sets.

    ``none``/``null`` for an optional field; ``1/true/yes/on`` and ``0/false/no/off`` for a
    bool; Python's int and float syntax (``8.0`` is an int 8); a string as it is (quotes
    removed); anything else (lists, free-form tables, ``Any``) as a TOML literal, or as the
    text when it is not one. Raises ValueError when the text is not of the type.
    """
    s = str(text).strip()
    inner = _optional_inner(tp)
    if inner is not None:
        return None if s.lower() in ("none", "null") else parse_text(s, inner)
    if tp is bool:
        if s.lower() in _TRUE:
            return True
        if s.lower() in _FALSE:
            return False
        raise ValueError(s)
    if tp is int:
        try:
            return int(s)
        except ValueError:
            f = float(s)
            if not f.is_integer():
                raise ValueError(s) from None
            return int(f)
    if tp is float:
        return float(s)
    if tp is str:
        v = _toml_literal(s) if s[:1] in ("'", '"') else s
        return v if isinstance(v, str) else s
    return _toml_literal(s)


def _plain_text(value: Any) -> Any:
    """Every :class:`SetText` inside a free-form value read as a TOML literal (or kept as text)."""
    if isinstance(value, SetText):
        return _toml_literal(value)
    if isinstance(value, Mapping):
        return {k: _plain_text(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_plain_text(v) for v in value]
    return value


# ----------------------------------------------------------------------------- checking and building
def check(obj: Any) -> None:
    """Check every field of dataclass ``obj`` against its declared rule, then ``obj.validate()``.

    Raises :class:`ConfigFieldError` with the field name as the key (the caller prefixes it).
    """
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if value is None or dataclasses.is_dataclass(value):
            continue
        r = rule_of(f)
        broken = r.violation(value)
        if broken:
            numeric = isinstance(value, (int, float)) and not isinstance(value, bool) and r.choices is None
            unit = f" {r.unit}" if r.unit and numeric else ""
            raise ConfigFieldError(f.name, f" = {shown(value)}{unit}: {broken}")
    validate = getattr(obj, "validate", None)
    if callable(validate):
        validate()


def with_defaults(cls: type[_C], name: str, **defaults: Any) -> type[_C]:
    """A subclass of the Config dataclass ``cls`` named ``name`` whose listed fields have other defaults.

    Every field keeps its type, unit, rule and doc; only the defaults differ, and each new
    default is checked against its field's rule here (an unknown field name is a
    ``TypeError``, a default breaking the rule a :class:`ConfigFieldError`). This is how a
    named preset of an estimator is declared: one class, its ``Config`` with other defaults
    (``akaze-guided-fast``), so ``--set`` and ``floorvo list --config`` work on it unchanged.
    """
    fields = {f.name: f for f in dataclasses.fields(typing.cast(Any, cls))}
    hints = typing.get_type_hints(cls)
    annotations: dict[str, Any] = {}
    namespace: dict[str, Any] = {"__module__": cls.__module__, "__qualname__": name, "__annotations__": annotations}
    for key, value in defaults.items():
        if key not in fields:
            raise TypeError(f"{cls.__name__} has no field {key!r} (known: {', '.join(sorted(fields))})")
        annotations[key] = hints[key]
        namespace[key] = dataclasses.field(default=value, metadata=fields[key].metadata)
    sub: Any = dataclass(frozen=True)(type(name, (cls,), namespace))
    check(sub())
    return sub


def _join(prefix: str, key: str) -> str:
    """``prefix.key`` as errors name a field (a key read from a file is cut to one short line)."""
    return f"{prefix}.{shorten(key)}" if prefix else shorten(key)


def unknown_key_message(where: str, key: str, known: Iterable[str], unknown: str, listed_by: str | None) -> str:
    """One line for an unknown ``key`` at ``where`` among the ``known`` keys: every known key, unless
    they do not fit in a short line and ``listed_by`` names the command that lists them all
    (``floorvo list --config akaze-guided``): then the closest ones (``difflib``) and that
    command. An estimator has dozens of keys: naming them all made a line of 500 characters."""
    names = sorted(known)
    if listed_by is None or len(", ".join(names)) <= MAX_SHOWN_CHARS:
        return f"{where}: {unknown} (known: {', '.join(names)})"
    close = difflib.get_close_matches(key, names, n=3, cutoff=0.6)
    said = " or ".join([", ".join(close[:-1]), close[-1]] if len(close) > 1 else close)
    return f"{where}: {unknown} ({f'did you mean {said}? ' if close else ''}every key: {listed_by})"


def build(
    cls: type,
    data: Mapping[str, Any] | None,
    prefix: str = "",
    *,
    unknown: str = "unknown key",
    listed_by: str | None = None,
) -> Any:
    """Dataclass ``cls`` from a plain mapping, every key, type and rule checked (a field without a
    default is required).

    ``data`` holds field values; a nested dataclass field (``Spec`` or ``Spec | None``)
    takes a nested mapping; values that are :class:`SetText` are read by their field's
    type. ``prefix`` names where the mapping came from in errors (``camera`` ->
    ``camera.height_mm = ...``). ``unknown``: the words after an unknown key in its error
    (``unknown key (known: a, b)``); ``listed_by``: the command that lists every key, named
    there instead of them (:func:`unknown_key_message`).
    """
    if data is not None and not isinstance(data, Mapping):  # trajectory.disturbance = 1 was a traceback
        raise ConfigError(f"{prefix or cls.__name__} = {shown(data)}: must be a table")
    data = dict(data or {})
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    for key in data:
        if key not in fields:
            raise ConfigError(unknown_key_message(_join(prefix, key), key, fields, unknown, listed_by))
    for key, f in fields.items():
        if key not in data and f.default is _MISSING and f.default_factory is _MISSING:
            raise ConfigError(f"{_join(prefix, key)}: missing (a required key)")
    kwargs: dict[str, Any] = {}
    for key, value in data.items():
        where, tp = _join(prefix, key), hints[key]
        nested = _nested_config(tp)
        if nested is not None and value is None and tp is not nested:  # an optional table left empty
            kwargs[key] = None
            continue
        if nested is not None:
            tp = nested
            if isinstance(value, tp):
                kwargs[key] = value
                continue
            if isinstance(value, SetText):  # --set KEY={...}: a TOML inline table, as a file would give it
                value = _plain_text(value)
                if not isinstance(value, Mapping):
                    raise ConfigError(
                        f"{where} = {shown(value)}: must be a table (an inline TOML table, or set one of its keys: "
                        f"--set {where}.KEY=VALUE)"
                    )
            if not isinstance(value, Mapping):
                raise ConfigError(f"{where} = {shown(value)}: must be a table")
            kwargs[key] = build(tp, value, where, unknown=unknown, listed_by=listed_by)
            continue
        if isinstance(value, SetText):
            if _is_table(tp) or tp is Any:
                value = _plain_text(value)
            else:
                try:
                    value = parse_text(value, tp)
                except ValueError:
                    raise ConfigError(f"{where} = {shown(value)}: must be {_expected(tp)}") from None
        elif _is_table(tp):
            value = _plain_text(value)
        ok, conv = _coerce(value, tp)
        if not ok:
            raise ConfigError(f"{where} = {shown(value)}: must be {_expected(tp)}")
        kwargs[key] = conv
    try:
        obj = cls(**kwargs)
        if not isinstance(obj, Config):
            check(obj)
    except ConfigFieldError as exc:
        raise exc.under(prefix) from None
    return obj


def from_overrides(
    cls: type,
    overrides: Mapping[str, Any] | None,
    prefix: str = "",
    *,
    unknown: str = "unknown key",
    listed_by: str | None = None,
) -> Any:
    """``cls`` built from ``{"key": "text", "nested.key": "text"}`` overrides (``--set`` form).

    String values are read by their field's type; other values are taken as they are.
    """
    return build(cls, apply_overrides({}, overrides), prefix, unknown=unknown, listed_by=listed_by)


# ----------------------------------------------------------------------------- --set
def parse_set_args(items: Iterable[str] | None, flag: str = "--set") -> dict[str, SetText]:
    """``["KEY=VALUE", ...]`` (``--set`` arguments; ``flag`` names them in errors) into ``{KEY: VALUE}``;
    values stay text.

    A key given twice is refused (``--set grid=3 --set grid=4`` ran with 4, the last, silently).
    """
    out: dict[str, SetText] = {}
    for item in items or []:
        if "=" not in item:
            raise ConfigError(f"{flag} {shown(item)}: expected KEY=VALUE")
        key, value = item.split("=", 1)
        key = key.strip()
        if not key:
            raise ConfigError(f"{flag} {shown(item)}: empty key")
        if key in out:
            raise ConfigError(
                f"{flag} {shown(item)}: {shown(key)} is given twice (also = {shown(str(out[key]))}); give it once"
            )
        out[key] = SetText(value.strip())
    return out


def apply_overrides(d: Mapping[str, Any], overrides: Mapping[str, Any] | None) -> dict:
    """A copy of the table ``d`` with ``{"camera.height_mm": "80"}`` overrides placed in it.

    A dotted key reaches into nested tables (made when missing); string values are marked
    :class:`SetText`, to be read by the type of the field they land in when built.
    """
    out = copy.deepcopy(dict(d))
    for key, raw in (overrides or {}).items():
        parts = key.split(".")
        node = out
        for p in parts[:-1]:
            nxt = node.setdefault(p, {})
            if not isinstance(nxt, dict):
                raise ConfigError(f"--set {shorten(key)}: {shown(p)} is not a table")
            node = nxt
        node[parts[-1]] = SetText(raw) if isinstance(raw, str) else raw
    return out


# ----------------------------------------------------------------------------- listing
@dataclass(frozen=True)
class FieldInfo:
    """One row of a config listing: dotted ``key``, ``type``, ``default``, ``unit``, ``rule``, ``doc``."""

    key: str
    type: str
    default: str
    unit: str
    rule: str
    doc: str


def _default_text(value: Any) -> str:
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(_default_text(v) for v in value) + "]"
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{k} = {_default_text(v)}" for k, v in value.items()) + "}"
    return str(value)


def describe_fields(cls: type, prefix: str = "", exclude: Iterable[str] = ()) -> list[FieldInfo]:
    """Every field of config class ``cls`` (nested dataclasses flattened to dotted keys)."""
    hints = typing.get_type_hints(cls)
    skip = set(exclude)
    rows: list[FieldInfo] = []
    for f in dataclasses.fields(cls):
        if not f.init or f.name in skip:
            continue
        key, tp, r = _join(prefix, f.name), hints[f.name], rule_of(f)
        nested = _nested_config(tp)
        if nested is not None:
            rows.extend(describe_fields(nested, key))
            continue
        if f.default is not dataclasses.MISSING:
            default = _default_text(f.default)
        elif f.default_factory is not dataclasses.MISSING:
            default = _default_text(f.default_factory())
        else:
            default = "(required)"
        rule = r.describe() or ("true or false" if tp is bool else "any")
        rows.append(FieldInfo(key, type_name(tp), default, r.unit, rule, r.doc))
    return rows


def format_fields(rows: Iterable[FieldInfo], indent: str = "") -> str:
    """Rows of :func:`describe_fields` as an aligned text table with a header line."""
    head = FieldInfo("key", "type", "default", "unit", "rule", "description")
    table = [head, *rows]
    cols = ("key", "type", "default", "unit", "rule")
    widths = {c: max(len(getattr(r, c)) for r in table) for c in cols}
    lines = []
    for r in table:
        cells = [getattr(r, c).ljust(widths[c]) for c in cols]
        lines.append((indent + "  ".join([*cells, r.doc])).rstrip())
    return "\n".join(lines)


def to_plain(obj: Any) -> Any:
    """A config (possibly nested) as plain dicts and lists, for JSON and TOML."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: to_plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, (list, tuple)):
        return [to_plain(v) for v in obj]
    if isinstance(obj, Mapping):
        return {k: to_plain(v) for k, v in obj.items()}
    if isinstance(obj, SetText):
        return str(obj)
    return obj

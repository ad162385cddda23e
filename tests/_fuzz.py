"""Hypothesis strategies for the readers' property tests: JSON-like values, edits of a valid
document (a value replaced, a key dropped or added, the whole document swapped), TOML text.

The property every reader must have (issue 16): any input gives a valid object or one
:class:`~floorvo.errors.FloorbenchError` line, never another exception.
"""

from __future__ import annotations

import copy
import json
import math
from collections.abc import Callable
from typing import Any

from hypothesis import strategies as st

from floorvo.errors import FloorbenchError

#: Scalars a JSON or TOML file can hold, with the awkward ones (NaN, inf, huge numbers, text).
scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(2**70), 2**70),
    st.integers(-3, 3),
    st.floats(),
    st.floats(-10, 10),
    st.text(max_size=12),
    st.sampled_from(["80mm", "30fps", "none", "", "nan", "uniform", "1e999"]),
)
#: Scalars, lists and tables of them.
values = st.recursive(
    scalars, lambda c: st.lists(c, max_size=4) | st.dictionaries(st.text(max_size=8), c, max_size=4), max_leaves=10
)


def _slots(obj: Any) -> list[tuple[Any, Any]]:
    """Every (container, key) of a nested dict/list document."""
    out: list[tuple[Any, Any]] = []
    items = obj.items() if isinstance(obj, dict) else enumerate(obj) if isinstance(obj, list) else ()
    for k, v in items:
        out.append((obj, k))
        out.extend(_slots(v))
    return out


@st.composite
def edited(draw: st.DrawFn, base: Any, max_edits: int = 3) -> Any:
    """``base`` (plain JSON-like data) after 1 to ``max_edits`` edits, or replaced whole."""
    if draw(st.integers(0, 19)) == 0:
        return draw(values)
    doc = copy.deepcopy(base)
    for _ in range(draw(st.integers(1, max_edits))):
        slots = _slots(doc)
        action = draw(st.sampled_from(["replace", "replace", "drop", "add"])) if slots else "add"
        if action == "add":
            tables = [doc] * isinstance(doc, dict) + [c[k] for c, k in slots if isinstance(c[k], dict)]
            if tables:
                draw(st.sampled_from(tables))[draw(st.text(max_size=8))] = draw(values)
            continue
        container, key = draw(st.sampled_from(slots))
        if action == "drop":
            del container[key]
        else:
            old = container[key]
            # A value of the same kind (a nearby number, a list one item shorter) as often as a random one.
            near = st.just(old)
            if isinstance(old, bool):
                near = st.booleans()
            elif isinstance(old, (int, float)):
                near = st.sampled_from([-old, old * 1.1, 0, -1, old + 0.5, float("nan"), float("inf"), 1e308])
            elif isinstance(old, list) and old:
                near = st.just(old[:-1]) | st.just(old + old[-1:])
            container[key] = draw(near | values)
    return doc


def one_line_or_valid(read: Callable[[], Any]) -> Any:
    """Call ``read``; a :class:`FloorbenchError` must be one short line. Other exceptions propagate."""
    try:
        return read()
    except FloorbenchError as exc:
        msg = str(exc)
        assert msg and len(msg.splitlines()) == 1 and len(msg) < 1000, repr(msg)
        return exc


def toml_value(v: Any) -> str:
    """``v`` as a TOML value (inline tables and arrays); None is not representable (drop it first)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return ("nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")) if not math.isfinite(v) else repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v if x is not None) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {toml_value(x)}" for k, x in v.items() if x is not None) + "}"
    raise TypeError(type(v))


def toml_text(doc: dict) -> str:
    """A TOML file of the table ``doc`` (every value inline; None values left out)."""
    return "".join(f"{json.dumps(k)} = {toml_value(v)}\n" for k, v in doc.items() if v is not None)

"""User-facing errors.

Every error a user can cause by bad input (a scene file, a sequence folder, a config
value) is a :class:`FloorbenchError` whose message is one line naming the thing and the
rule. The CLIs print that line and exit with code 1; any other exception is a bug and
keeps its traceback.
"""

from __future__ import annotations

import math
from decimal import Decimal
from typing import Any

import numpy as np

__all__ = [
    "FloorbenchError",
    "ConfigError",
    "ConfigFieldError",
    "SequenceError",
    "FolderLockedError",
    "MAX_SHOWN_CHARS",
    "shown",
    "shown_number",
    "shorten",
    "MAX_FIXED_POINT",
]

#: The most characters of a value an error message quotes; a longer value is cut with an ellipsis.
MAX_SHOWN_CHARS = 80
#: Every character ``str.splitlines`` breaks a line at, and how a message shows it.
_LINE_BREAKS = {ord(c): repr(c)[1:-1] for c in "\n\r\v\f\x1c\x1d\x1e\x85\u2028\u2029"}


def shown(value: Any, limit: int = MAX_SHOWN_CHARS) -> str:
    """``value`` as an error message quotes it: text in quotes (``'80mm'``), a tuple as a list,
    ``None`` and booleans as the files a user writes spell them (``null``, ``true``, ``false``:
    JSON's and TOML's words, not Python's), anything else as ``str``; cut to ``limit`` characters
    with an ellipsis (a 100,000-character value must not become a 100,000-character message
    line), newlines escaped (one line)."""
    return shorten(_spelled(value), limit)


#: The largest magnitude :func:`shown_number` writes a float as its format asks; beyond it, in exponent form.
MAX_FIXED_POINT = 1e15
#: Integers below this magnitude (30 digits: a seed, a count as typed) are shown exactly.
MAX_EXACT_INT = 10**30


def shown_number(value: Any, spec: str = "") -> str:
    """The number ``value`` as an error message shows it, in at most about 30 characters.

    Formatted by ``spec`` (``".6f"``, ``".0f"``, ``"d"``; ``""``: ``str``) while its magnitude is
    below :data:`MAX_FIXED_POINT` (an integer: :data:`MAX_EXACT_INT`), in exponent form
    (``1e+308``, 6 significant digits) beyond:
    ``f"{1e308:.0f}"`` is 309 digits, and an integer read from a file (``frame_count`` of
    ``1e308``, made an int) as many. NaN and infinities as ``nan``, ``inf``; anything that is
    not a number as :func:`shown` shows it.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        return shown(value)
    if isinstance(value, (int, np.integer)):
        n = int(value)
        if abs(n) < MAX_EXACT_INT:
            return format(n, spec)
        try:
            return format(float(n), ".6g")
        except OverflowError:  # beyond any float
            return format(Decimal(n).normalize(), ".6g")
    x = float(value)
    if not math.isfinite(x):
        return str(x)
    return format(x, ".6g") if abs(x) >= MAX_FIXED_POINT else format(value, spec)


def _spelled(value: Any) -> str:
    """``value`` written as :func:`shown` quotes it, lists and tables inside it too: text in
    quotes, tuples as lists (a matrix read into tuples shows as it was written), ``None`` and
    booleans in the words of JSON and TOML."""
    if value is None:
        return "null"
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, (int, float, np.integer, np.floating)):
        return shown_number(value)
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(_spelled(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_spelled(k)}: {_spelled(v)}" for k, v in value.items()) + "}"
    return str(value)


def shorten(text: str, limit: int = MAX_SHOWN_CHARS) -> str:
    """``text`` (a name, a key, a path read from a file) on one line and cut to ``limit``
    characters with an ellipsis, as error messages quote it."""
    text = str(text).translate(_LINE_BREAKS)
    return text if len(text) <= limit else text[: max(0, limit - 3)] + "..."


class FloorbenchError(Exception):
    """A user-facing error with a one-line message naming the thing and the rule."""


class ConfigError(FloorbenchError, ValueError):
    """An invalid configuration value or key (scene file, estimator config, --set)."""


class ConfigFieldError(ConfigError):
    """A value that breaks its field's rule: ``{prefix}.{key}{detail}``, e.g.
    ``camera.height_mm = -100.0 mm: must be > 0 mm``. ``prefix`` says where the field was
    read (a scene section, an estimator's name); :meth:`under` names another place."""

    def __init__(self, key: str, detail: str, prefix: str = ""):
        self.key, self.detail, self.prefix = key, detail, prefix
        super().__init__(f"{prefix}.{key}{detail}" if prefix else f"{key}{detail}")

    def under(self, prefix: str) -> ConfigFieldError:
        """The same error for the field read under ``prefix``."""
        return ConfigFieldError(self.key, self.detail, prefix)

    def __reduce__(self):  # pickled across worker processes (sweeps)
        return (ConfigFieldError, (self.key, self.detail, self.prefix))


class SequenceError(FloorbenchError):
    """A sequence folder that is missing, corrupt or of another schema version."""


class FolderLockedError(FloorbenchError):
    """An output folder that another writer holds (:func:`floorvo.locking.lock_folder`).

    ``folder``: the folder; ``pid``: the holder's process id (None when it could not be read);
    the message names both in one line.
    """

    def __init__(self, message: str, folder: str = "", pid: int | None = None):
        self.folder, self.pid = folder, pid
        super().__init__(message)

    def __reduce__(self):  # pickled across worker processes (sweeps)
        return (FolderLockedError, (str(self), self.folder, self.pid))


class EstimatorLoadError(FloorbenchError):
    """An estimator from outside the built-ins (a plugin, a ``module:Class`` reference) that
    cannot be imported or is not an estimator; the message gives the one-line reason."""


class ExternalEstimatorError(FloorbenchError):
    """A run of an external estimator program that failed (crash, non-zero exit, timeout,
    missing or malformed trajectory). ``reason``: the one-line cause; ``stderr_tail``: the
    last lines of the program's standard error, joined on one line (may be empty)."""

    def __init__(self, message: str, reason: str = "", stderr_tail: str = ""):
        self.reason, self.stderr_tail = reason or message, stderr_tail
        super().__init__(message)

    def __reduce__(self):  # pickled across worker processes (sweeps)
        return (ExternalEstimatorError, (str(self), self.reason, self.stderr_tail))

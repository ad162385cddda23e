"""User-facing errors.

Every error a user can cause by bad input (a scene file, a sequence folder, a config
value) is a :class:`FloorbenchError` whose message is one line naming the thing and the
rule. The CLIs print that line and exit with code 1; any other exception is a bug and
keeps its traceback.
"""


class FloorbenchError(Exception):
    """A user-facing error with a one-line message naming the thing and the rule."""


class ConfigError(FloorbenchError, ValueError):
    """An invalid configuration value or key (scene file, estimator config, --set)."""


class SequenceError(FloorbenchError):
    """A sequence folder that is missing, corrupt or of another schema version."""

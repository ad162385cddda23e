"""User-facing errors.

Every error a user can cause by bad input (a scene file, a sequence folder, a config
value) is a :class:`FloorbenchError` whose message is one line naming the thing and the
rule. The CLIs print that line and exit with code 1; any other exception is a bug and
keeps its traceback.
"""

from __future__ import annotations


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

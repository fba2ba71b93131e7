"""One home for every error sengine raises on purpose.

A :class:`SEngineError` is a *user* mistake: the CLI prints its one-line
message and exits with status 2.  Anything else is a bug and gets a traceback.
Each subclass also derives from the builtin it specialises, as osmnx does.
"""

from __future__ import annotations

__all__ = [
    "SEngineError",
    "ConfigError",
    "RegistryError",
    "ParameterError",
    "NetworkError",
    "InputDataError",
]


class SEngineError(Exception):
    """Base of all user-facing errors; ``str(err)`` is the one line to print."""

    code = "error"

    def __init__(self, message: str, *, where: str | None = None):
        self.where = where
        self.message = message
        super().__init__(f"{where}: {message}" if where else message)


class ConfigError(SEngineError, ValueError):
    """A configuration file is not well formed, not valid, or refers to nothing."""

    code = "config"


class RegistryError(SEngineError, KeyError):
    """An unknown node type, a duplicate registration or a broken plugin."""

    code = "registry"

    def __str__(self) -> str:  # KeyError would quote the message
        return Exception.__str__(self)


class ParameterError(SEngineError, ValueError):
    """A parameter value that does not match its declaration."""

    code = "parameter"


class NetworkError(SEngineError, ValueError):
    """A network that cannot run: missing ports, kind mismatch, cycle ..."""

    code = "network"


class InputDataError(SEngineError, ValueError):
    """An input file (image, OSM, OBJ) that is missing, unreadable or unusable."""

    code = "input"

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
    "NodeError",
    "LimitError",
    "Problems",
    "OutputError",
    "SEngineWarning",
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


class NodeError(SEngineError, RuntimeError):
    """A node that failed while running: a plugin raising in ``run`` or returning the wrong shape."""

    code = "node"


class OutputError(SEngineError, OSError):
    """The output folder cannot be written: it is a file, not writable, or its name is too long."""

    code = "output"


class SEngineWarning(UserWarning):
    """A warning sengine gives on purpose (a broken plugin skipped ...); the CLI prints it as one line."""


class LimitError(SEngineError, ValueError):
    """Work refused before it starts because it would exceed a stated bound (features, memory)."""

    code = "limit"


class Problems(SEngineError):
    """Several problems found at once; ``str()`` is a summary line, :attr:`lines` one line per problem.

    Parameters
    ----------
    problems : list of SEngineError
        The problems in the order they were found.
    where : str, optional
        The file (or other source) the problems are in, for the summary line.
    """

    code = "problems"
    MAX_LINES = 20

    def __init__(self, problems: list[SEngineError], *, where: str | None = None):
        flat: list[SEngineError] = []
        for p in problems:
            flat.extend(p.problems if isinstance(p, Problems) else [p])
        self.problems = flat
        n = len(flat)
        super().__init__(f"{n} problem{'s' if n != 1 else ''}", where=where)

    @property
    def lines(self) -> list[str]:
        """The summary, then one line per problem (at most ``MAX_LINES`` in all)."""
        out = [str(self)]
        shown = self.problems[: self.MAX_LINES - 1]
        out += [" ".join(str(p).split()) for p in shown]
        if len(self.problems) > len(shown):
            out[-1] = f"... and {len(self.problems) - len(shown) + 1} more"
        return out

    @staticmethod
    def raise_if(problems: list[SEngineError], *, where: str | None = None) -> None:
        """Raise nothing for no problem, the problem itself for one, Problems for several."""
        if len(problems) == 1 and not isinstance(problems[0], Problems):
            raise problems[0]
        if problems:
            raise Problems(problems, where=where)

"""The built-in nodes, loaded as the first plugin of the ``sengine.nodes`` group.

The node library lives in the repository's top-level ``nodes/`` folder and is
shipped inside the distribution as ``sengine/_builtin/nodes``; either way it is
imported by path as the package ``sengine_nodes``, exactly as a user's
``<plugin path="..."/>`` would be.  No top-level ``nodes`` package is installed.
"""

from __future__ import annotations

from pathlib import Path

from .registry import load_path

__all__ = ["load", "data_dir"]

_HERE = Path(__file__).resolve().parent


def data_dir(name: str) -> Path:
    """The folder ``nodes``, ``networks`` or ``configs``, installed or in a checkout."""
    for candidate in (_HERE / "_builtin" / name, _HERE.parent / name):
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError(f"sengine's built-in folder {name!r} is missing from the installation")


def load() -> None:
    """Register every built-in node (entry point ``builtin``)."""
    load_path(data_dir("nodes"), module_name="sengine_nodes")

"""The factory: a dictionary of (nameId -> node class), as in skylineEngine §5.1.

Nodes register with :func:`register`.  Plugins are modules that register
nodes when imported; they arrive four ways, all through :func:`load_plugin`:

* the entry-point group ``sengine.nodes`` (the built-in node library,
  :mod:`sengine.nodes`, is the first such plugin: entry point ``builtin``);
* ``<plugin module="..."/>`` in a configuration file;
* ``<plugin path="..."/>`` (a ``.py`` file or a package folder);
* ``--plugin MODULE_OR_PATH`` on the command line.

References
----------
.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
"""

from __future__ import annotations

import difflib
import importlib
import importlib.metadata
import importlib.util
import logging
import re
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from .errors import RegistryError, SEngineWarning
from .node import Param, SENode
from .random import stable_hash

__all__ = [
    "REGISTRY",
    "register",
    "get",
    "check_formats",
    "load_plugin",
    "load_entry_points",
    "broken_plugins",
    "register_network",
    "network_class",
    "network_names",
    "declare_rule",
    "rule_params",
    "declare_kind",
    "kinds",
    "check_kind",
    "source_classes",
    "declare_map_kind",
    "map_kinds",
    "formats",
]

log = logging.getLogger(__name__)

ENTRY_POINT_GROUP = "sengine.nodes"
NAME_RE = re.compile(r"^[a-z][a-z0-9_]*(\.[a-z][a-z0-9_]*)*$", re.IGNORECASE)

REGISTRY: dict[str, type[SENode]] = {}
NETWORKS: dict[str, type] = {}  # base name -> network class (``<network base="...">``)
RULES: dict[str, dict[str, Param]] = {}  # plan element tag -> its declared attributes
KINDS: dict[str, dict[str, tuple[str, bool, str]]] = {}  # layer kind -> column -> (dtype kinds, required, doc)
MAP_KINDS: dict[str, tuple[str, str]] = {}  # <map kind=...> -> (kind of the port that carries it, doc)
_loaded: dict[str, str] = {}  # plugin key -> module name
_broken: dict[str, str] = {}
_entry_points_loaded = False

N = TypeVar("N", bound=type[SENode])


def register(cls: N | None = None, *, name: str | None = None, replace: bool = False) -> N | Callable[[N], N]:
    """Class decorator adding a node class to the registry under ``cls.name``.

    A second class under the same name is an error unless ``replace=True``,
    never a silent override.
    """

    def deco(c: N) -> N:
        if name:
            c.name = name
        if not isinstance(c, type) or not issubclass(c, SENode):
            raise TypeError(f"{c!r} is not an SENode subclass")
        if not c.name or not NAME_RE.match(c.name):
            raise RegistryError(f"{c.__qualname__}: node name {c.name!r} must be dotted identifiers like 'lots.paris'")
        c.check_declaration()
        old = REGISTRY.get(c.name)
        if old is not None and old is not c and not replace and _qualname(old) != _qualname(c):
            raise RegistryError(f"node name {c.name!r} is registered twice: {_qualname(old)} and {_qualname(c)}")
        REGISTRY[c.name] = c
        return c

    return deco(cls) if cls is not None else deco


def _qualname(c: type) -> str:
    return f"{c.__module__}.{c.__qualname__}"


def get(name: str, *, where: str | None = None) -> type[SENode]:
    """The node class registered as ``name``; the error lists close names."""
    load_entry_points()
    try:
        return REGISTRY[name]
    except KeyError:
        close = difflib.get_close_matches(name, REGISTRY, n=3, cutoff=0.5)
        hint = f"; did you mean {', '.join(repr(c) for c in close)}?" if close else ""
        raise RegistryError(f"unknown node type {name!r}{hint}", where=where) from None


def names() -> list[str]:
    load_entry_points()
    return sorted(REGISTRY)


def check_formats(formats) -> frozenset[str]:
    """The output formats asked for, lower case, each written by some registered node.

    A node declares the formats it writes as its class attribute ``formats``
    (and may suggest one for a common other name in ``format_hints``, e.g.
    ``{"shp": "gpkg"}``).  With no such node registered nothing is checked.

    Raises
    ------
    ParameterError
        One line naming the unknown format, a suggestion and the known ones.
    """
    from .errors import ParameterError

    asked = frozenset(str(f).strip().lower() for f in formats or () if str(f).strip())
    if not asked:
        return asked
    known: list[str] = []
    hints: dict[str, str] = {}
    for name in names():
        cls = get(name)
        known += [f for f in getattr(cls, "formats", ()) if f not in known]
        hints.update(getattr(cls, "format_hints", {}) or {})
    if not known:
        return asked
    for f in sorted(asked):
        if f not in known:
            near = hints.get(f) or next(iter(difflib.get_close_matches(f, known, n=1, cutoff=0.5)), None)
            hint = f"; did you mean {near!r}?" if near else ""
            raise ParameterError(f"unknown format {f!r}{hint}; formats: {', '.join(known)}", where="--format")
    return asked


def register_network(name: str) -> Callable[[type], type]:
    """Class decorator naming a network class for ``<network base="NAME">``.

    The class needs a ``from_config(pairs, *, where, **kwargs)`` classmethod
    (``pairs``: the ``(id, type)`` of the ``<node>`` elements).  A second class
    under the same name is an error.
    """

    def deco(cls: type) -> type:
        old = NETWORKS.get(name)
        if old is not None and _qualname(old) != _qualname(cls):
            raise RegistryError(f"network base {name!r} is registered twice: {_qualname(old)} and {_qualname(cls)}")
        NETWORKS[name] = cls
        return cls

    return deco


def network_class(name: str, *, where: str | None = None) -> type:
    """The network class registered as ``name``; the error lists the known ones."""
    load_entry_points()
    try:
        return NETWORKS[name]
    except KeyError:
        close = difflib.get_close_matches(name, NETWORKS, n=1, cutoff=0.5)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise RegistryError(
            f"unknown network base {name!r} (known: {', '.join(sorted(NETWORKS))}){hint}", where=where
        ) from None


def network_names() -> list[str]:
    """The registered network bases, sorted."""
    load_entry_points()
    return sorted(NETWORKS)


def load_entry_points() -> None:
    """Load every plugin of the ``sengine.nodes`` entry-point group once.

    A plugin that fails to load is a warning and is skipped; the failure is
    kept for :func:`broken_plugins` (``sengine nodes --check``).
    """
    global _entry_points_loaded
    if _entry_points_loaded:
        return
    _entry_points_loaded = True
    eps = sorted(importlib.metadata.entry_points(group=ENTRY_POINT_GROUP), key=lambda e: (e.name != "builtin", e.name))
    for ep in eps:
        try:
            obj = ep.load()
            if callable(obj) and not isinstance(obj, type):
                obj()
        except RegistryError:
            raise
        except Exception as exc:  # a broken third-party plugin must not break sengine
            _broken[ep.name] = f"{type(exc).__name__}: {exc}"
            warnings.warn(
                f"sengine plugin {ep.name!r} ({ep.value}) failed to load: {exc}", SEngineWarning, stacklevel=2
            )
    if not any(ep.name == "builtin" for ep in eps):
        warnings.warn(
            "sengine's built-in nodes are not registered: install the package (pip install .)",
            SEngineWarning,
            stacklevel=2,
        )


def broken_plugins() -> dict[str, str]:
    """Entry-point plugins that failed to load, with why (``sengine nodes --check``)."""
    load_entry_points()
    return dict(_broken)


def load_plugin(spec: str, *, base_dir: Path | None = None, where: str | None = None) -> str:
    """Import a plugin given as a module name or a path; return its module name.

    Parameters
    ----------
    spec : str
        A dotted module name, or a path to a ``.py`` file or a package folder
        (relative paths are resolved against ``base_dir``).
    """
    load_entry_points()
    looks_like_path = spec.endswith(".py") or "/" in spec or "\\" in spec
    if looks_like_path:
        path = Path(spec)
        if not path.is_absolute() and base_dir is not None:
            path = Path(base_dir) / path
        return load_path(path, where=where)
    if spec in _loaded:
        return _loaded[spec]
    try:
        importlib.import_module(spec)
    except ModuleNotFoundError as exc:
        raise RegistryError(f"plugin module {spec!r} not found ({exc.name} is missing)", where=where) from None
    except RegistryError:
        raise
    except Exception as exc:
        raise RegistryError(
            f"plugin module {spec!r} failed to import: {type(exc).__name__}: {exc}", where=where
        ) from None
    _loaded[spec] = spec
    return spec


def load_path(path: Path, *, module_name: str | None = None, where: str | None = None) -> str:
    """Import a ``.py`` file or a package folder by path (idempotent)."""
    path = Path(path).resolve()
    key = str(path)
    if key in _loaded:
        return _loaded[key]
    if not path.exists():
        raise RegistryError(f"plugin path {str(path)!r} does not exist", where=where)
    if module_name is None:
        stem = re.sub(r"\W", "_", path.stem if path.is_file() else path.name)
        module_name = f"sengine_plugin_{stem}_{stable_hash(key) % 10**8}"
    if path.is_dir():
        init = path / "__init__.py"
        if not init.exists():
            raise RegistryError(f"plugin folder {str(path)!r} has no __init__.py", where=where)
        spec = importlib.util.spec_from_file_location(module_name, init, submodule_search_locations=[str(path)])
    else:
        spec = importlib.util.spec_from_file_location(module_name, path)
    if spec is None or spec.loader is None:
        raise RegistryError(f"cannot import plugin {str(path)!r}", where=where)
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module
    try:
        spec.loader.exec_module(module)
    except RegistryError:
        del sys.modules[module_name]
        raise
    except Exception as exc:
        del sys.modules[module_name]
        raise RegistryError(
            f"plugin {str(path)!r} failed to import: {type(exc).__name__}: {exc}", where=where
        ) from None
    _loaded[key] = module_name
    log.debug("loaded plugin %s as %s", path, module_name)
    return module_name


def declare_rule(tag: str, params: dict[str, Param]) -> None:
    """Declare attributes of a plan element (``<district>``, ``<landuse>`` ...).

    Node modules declare the attributes they read, so that ``validate`` checks
    every rule before anything runs and ``sengine nodes`` lists them. An
    attribute declared twice must be declared the same way.
    """
    have = RULES.setdefault(tag, {})
    for name, param in params.items():
        if name in have and have[name] != param:
            raise RegistryError(f"<{tag}> attribute {name!r} is declared twice, differently")
        have[name] = param


def rule_params(tag: str) -> dict[str, Param] | None:
    """The declared attributes of ``<tag>``, or None when nothing declares the element."""
    load_entry_points()
    return RULES.get(tag)


def declare_kind(kind: str, columns: dict[str, tuple[str, bool, str]], *, doc: str = "") -> None:
    """Declare the attribute columns of a layer kind.

    Parameters
    ----------
    kind : str
        The port kind (``"lots"``, ``"roads"`` ...).
    columns : dict of str to (str, bool, str)
        Column name -> (numpy dtype kinds allowed, as in ``"iu"`` or ``"U"``
        or ``"O"``; whether every layer of the kind must have it; one-line doc).
    doc : str
        What a layer of the kind holds.

    A column declared twice must be declared the same way.
    """
    have = KINDS.setdefault(kind, {})
    for name, decl in columns.items():
        if name in have and have[name] != decl:
            raise RegistryError(f"layer kind {kind!r}: column {name!r} is declared twice, differently")
        have[name] = decl
    if doc:
        KIND_DOCS[kind] = doc


KIND_DOCS: dict[str, str] = {}


def kinds() -> dict[str, dict[str, tuple[str, bool, str]]]:
    """Every declared layer kind and its columns."""
    load_entry_points()
    return {k: dict(v) for k, v in KINDS.items()}


def check_kind(layer, kind: str, *, where: str | None = None) -> None:
    """Raise NetworkError when ``layer`` lacks a required column of ``kind`` or has one of the wrong dtype.

    Undeclared kinds (``any``, a plugin's own) and undeclared columns pass:
    a kind declares what its consumers may rely on, not all a layer may carry.
    """
    from .errors import NetworkError

    decl = KINDS.get(kind)
    if decl is None:
        return
    problems = []
    for name, (dtypes, required, _) in decl.items():
        col = layer.attrs.get(name)
        if col is None:
            if required and len(layer):
                problems.append(f"column {name!r} is missing")
            continue
        if col.dtype.kind not in dtypes:
            problems.append(f"column {name!r} has dtype {col.dtype} (kind {col.dtype.kind!r}), declared {dtypes!r}")
    if problems:
        raise NetworkError(f"layer of kind {kind!r}: " + "; ".join(problems), where=where)


def source_classes() -> dict[str, type[SENode]]:
    """Layer kind -> the registered node class that is the plan's source of it (:attr:`SENode.source_for`)."""
    load_entry_points()
    return {c.source_for: c for c in REGISTRY.values() if c.source_for}


def formats() -> dict[str, str]:
    """Every output format some registered node writes (its class attribute ``formats``) and that node's name."""
    out: dict[str, str] = {}
    for name in names():
        for f in getattr(get(name), "formats", ()) or ():
            out.setdefault(f, name)
    return out


def declare_map_kind(kind: str, port_kind: str, doc: str = "") -> None:
    """Declare a ``<map kind=...>`` of the plan and the port kind that carries it (``raster``, ``file``).

    A configuration's map of an undeclared kind is an error with a "did you
    mean"; the node registered as the source of ``port_kind``
    (:attr:`SENode.source_for`) turns each such map into a node.
    """
    old = MAP_KINDS.get(kind)
    if old is not None and old[0] != port_kind:
        raise RegistryError(f"map kind {kind!r} is declared twice, differently")
    MAP_KINDS[kind] = (port_kind, doc)


def map_kinds() -> dict[str, tuple[str, str]]:
    """Every declared map kind: its port kind and doc."""
    load_entry_points()
    return dict(MAP_KINDS)

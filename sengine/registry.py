"""The factory: a dictionary of (nameId -> node class), as in skylineEngine §5.1.

Nodes register with :func:`register`.  Plugins are modules that register
nodes when imported; they arrive four ways, all through :func:`load_plugin`:

* the entry-point group ``sengine.nodes`` (the built-in node library,
  :mod:`sengine.nodes`, is the first such plugin: entry point ``builtin``);
* ``<plugin module="..."/>`` in a configuration file;
* ``<plugin path="..."/>`` (a ``.py`` file or a package folder);
* ``--plugin MODULE_OR_PATH`` on the command line.

A plugin package may instead declare what its modules register
(:func:`declare_lazy`, an index made by :func:`survey`): each module is then
imported when something it registers is first asked for (a node type of the
configuration, a ``<district>`` rule, a network base), so that a run imports
only the modules, and their dependencies, that it uses.  The built-in node
library does so (:mod:`sengine.nodes._index`).

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
import pkgutil
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
    "declare_lazy",
    "survey",
    "write_index",
    "load_all",
    "find",
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
#: What lazily declared plugin modules register (:func:`declare_lazy`): category -> key -> modules.
LAZY_CATEGORIES = ("node", "network", "rule", "kind", "map_kind", "source", "format")
_LAZY: dict[str, dict[str, tuple[str, ...]]] = {c: {} for c in LAZY_CATEGORIES}
_LAZY_PACKAGES: list[str] = []  # packages whose every module a miss imports (a stale index stays correct)
_SHADOWED: dict[str, tuple[str, ...]] = {}  # node name -> the lazy modules whose class a plugin replaced first
#: Which modules declared what (category, key) -> module names, for :func:`survey`.
_ORIGIN: dict[tuple[str, str], set[str]] = {}

N = TypeVar("N", bound=type[SENode])


def register(cls: N | None = None, *, name: str | None = None, replace: bool = False) -> N | Callable[[N], N]:
    """Class decorator adding a node class to the registry under ``cls.name``.

    A second class under the same name is an error unless ``replace=True``,
    never a silent override.
    """

    def deco(c: N) -> N:
        if not isinstance(c, type) or not issubclass(c, SENode):
            raise TypeError(f"{c!r} is not an SENode subclass")
        if name:
            c.name = name
        if not c.name or not NAME_RE.match(c.name):
            raise RegistryError(f"{c.__qualname__}: node name {c.name!r} must be dotted identifiers like 'lots.paris'")
        c.check_declaration()
        if c.__module__ in _SHADOWED.get(c.name, ()):
            return c  # a plugin replaced this lazily declared node before its module was imported
        lazy = _LAZY["node"].get(c.name)
        if lazy and c.__module__ not in lazy:
            if replace:
                _SHADOWED[c.name] = _LAZY["node"].pop(c.name)
            else:  # the lazily declared class first: two classes under one name are an error below
                _need("node", c.name, fallback=False)
        old = REGISTRY.get(c.name)
        if old is not None and old is not c and not replace and _qualname(old) != _qualname(c):
            raise RegistryError(f"node name {c.name!r} is registered twice: {_qualname(old)} and {_qualname(c)}")
        REGISTRY[c.name] = c
        return c

    return deco(cls) if cls is not None else deco


def _qualname(c: type) -> str:
    return f"{c.__module__}.{c.__qualname__}"


def get(name: str, *, where: str | None = None) -> type[SENode]:
    """The node class registered as ``name`` (its module imported if not yet); the error lists close names."""
    cls = find(name, where=where)
    if cls is None:
        close = difflib.get_close_matches(name, names(), n=3, cutoff=0.5)
        hint = f"; did you mean {', '.join(repr(c) for c in close)}?" if close else ""
        raise RegistryError(f"unknown node type {name!r}{hint}", where=where)
    return cls


def find(name: str, *, where: str | None = None) -> type[SENode] | None:
    """The node class registered as ``name``, or None; imports the module that registers it if needed."""
    load_entry_points()
    if name not in REGISTRY:
        _need("node", name, where=where)
    return REGISTRY.get(name)


def names() -> list[str]:
    """Every registered node name, sorted (lazily declared ones included, their modules not imported)."""
    load_entry_points()
    return sorted(set(REGISTRY) | set(_LAZY["node"]))


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
    for cls in _writers():
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
        lazy = _LAZY["network"].get(name)
        if lazy and cls.__module__ not in lazy:
            _need("network", name, fallback=False)
            old = NETWORKS.get(name)
        if old is not None and _qualname(old) != _qualname(cls):
            raise RegistryError(f"network base {name!r} is registered twice: {_qualname(old)} and {_qualname(cls)}")
        NETWORKS[name] = cls
        return cls

    return deco


def network_class(name: str, *, where: str | None = None) -> type:
    """The network class registered as ``name``; the error lists the known ones."""
    load_entry_points()
    if name not in NETWORKS:
        _need("network", name, where=where)
    try:
        return NETWORKS[name]
    except KeyError:
        known = network_names()
        close = difflib.get_close_matches(name, known, n=1, cutoff=0.5)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise RegistryError(f"unknown network base {name!r} (known: {', '.join(known)}){hint}", where=where) from None


def network_names() -> list[str]:
    """The registered network bases, sorted."""
    load_entry_points()
    return sorted(set(NETWORKS) | set(_LAZY["network"]))


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
    _origin("rule", tag)
    have = RULES.setdefault(tag, {})
    for name, param in params.items():
        if name in have and have[name] != param:
            raise RegistryError(f"<{tag}> attribute {name!r} is declared twice, differently")
        have[name] = param


def rule_params(tag: str) -> dict[str, Param] | None:
    """The declared attributes of ``<tag>``, or None when nothing declares the element."""
    load_entry_points()
    _need("rule", tag, fallback=tag not in RULES)
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
    _origin("kind", kind)
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
    _need_all("kind")
    return {k: dict(v) for k, v in KINDS.items()}


def check_kind(layer, kind: str, *, where: str | None = None) -> None:
    """Raise NetworkError when ``layer`` lacks a required column of ``kind`` or has one of the wrong dtype.

    Undeclared kinds (``any``, a plugin's own) and undeclared columns pass:
    a kind declares what its consumers may rely on, not all a layer may carry.
    """
    from .errors import NetworkError

    _need("kind", kind, fallback=False)
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
    _need_all("source")
    return {c.source_for: c for c in REGISTRY.values() if c.source_for}


def formats() -> dict[str, str]:
    """Every output format some registered node writes (its class attribute ``formats``) and that node's name."""
    out: dict[str, str] = {}
    for cls in _writers():
        for f in getattr(cls, "formats", ()) or ():
            out.setdefault(f, cls.name)
    return out


def _writers() -> list[type[SENode]]:
    """The registered classes that declare output formats, by node name (their modules imported)."""
    load_entry_points()
    _need_all("format")
    return [REGISTRY[n] for n in sorted(REGISTRY) if getattr(REGISTRY[n], "formats", ())]


def declare_map_kind(kind: str, port_kind: str, doc: str = "") -> None:
    """Declare a ``<map kind=...>`` of the plan and the port kind that carries it (``raster``, ``file``).

    A configuration's map of an undeclared kind is an error with a "did you
    mean"; the node registered as the source of ``port_kind``
    (:attr:`SENode.source_for`) turns each such map into a node.
    """
    _origin("map_kind", kind)
    old = MAP_KINDS.get(kind)
    if old is not None and old[0] != port_kind:
        raise RegistryError(f"map kind {kind!r} is declared twice, differently")
    MAP_KINDS[kind] = (port_kind, doc)


def map_kinds() -> dict[str, tuple[str, str]]:
    """Every declared map kind: its port kind and doc."""
    load_entry_points()
    _need_all("map_kind")
    return dict(MAP_KINDS)


# -- lazy plugins: an index of what each module registers ------------------------------


def declare_lazy(index: dict[str, dict[str, list[str] | tuple[str, ...]]], *, package: str | None = None) -> None:
    """Declare what a plugin's modules register, to import each only when something of it is asked for.

    Parameters
    ----------
    index : dict
        Category (one of :data:`LAZY_CATEGORIES`: ``node`` names, ``network``
        bases, ``rule`` tags, layer ``kind`` names, ``map_kind`` names, the
        port kinds a ``source`` class makes, output ``format`` names) -> key
        -> the modules whose import registers or declares it, as made by
        :func:`survey`.
    package : str, optional
        The package the index describes: when something is asked for that
        no loaded module nor the index knows (a node type, a network base, a
        rule element), every module of the package is imported before the
        answer, so an index that is out of date is slower, never wrong.
    """
    for cat, entries in index.items():
        if cat not in _LAZY:
            raise RegistryError(f"lazy index: unknown category {cat!r} (known: {', '.join(LAZY_CATEGORIES)})")
        for key, modules in entries.items():
            _LAZY[cat][key] = tuple(dict.fromkeys((*_LAZY[cat].get(key, ()), *modules)))
    if package and package not in _LAZY_PACKAGES:
        _LAZY_PACKAGES.append(package)


def _need(cat: str, key: str, *, where: str | None = None, fallback: bool = True) -> None:
    """Import the modules that register ``key`` of category ``cat``; with none known, every lazy package's."""
    modules = _LAZY[cat].pop(key, None)
    if modules:
        for module in modules:
            _import_lazy(module, what=f"{cat.replace('_', ' ')} {key!r}", where=where)
    elif fallback and _LAZY_PACKAGES:
        load_all(where=where)


def _need_all(cat: str) -> None:
    """Import every module that registers something of category ``cat``."""
    for key in list(_LAZY[cat]):
        _need(cat, key, fallback=False)


def _import_lazy(module: str, *, what: str, where: str | None = None) -> None:
    try:
        importlib.import_module(module)
    except RegistryError:
        raise
    except Exception as exc:
        missing = f" ({exc.name} is missing)" if isinstance(exc, ModuleNotFoundError) and exc.name else ""
        raise RegistryError(
            f"{what}: module {module} failed to import{missing}: {type(exc).__name__}: {exc}", where=where
        ) from None


def load_all(*, where: str | None = None) -> list[str]:
    """Import every module of the lazily declared packages (``sengine nodes``, an unknown name); return them.

    A module that fails to import is a warning, kept for :func:`broken_plugins`.
    """
    load_entry_points()
    done = []
    for package in list(_LAZY_PACKAGES):
        for module in _modules(package):
            try:
                importlib.import_module(module)
                done.append(module)
            except RegistryError:
                raise
            except Exception as exc:
                _broken[module] = f"{type(exc).__name__}: {exc}"
                warnings.warn(f"sengine module {module} failed to import: {exc}", SEngineWarning, stacklevel=2)
    for cat in _LAZY.values():
        cat.clear()
    _LAZY_PACKAGES.clear()
    return done


def _modules(package: str) -> list[str]:
    """Every module of ``package`` but private ones (a leading underscore), sorted by name."""
    pkg = importlib.import_module(package)
    found = pkgutil.walk_packages(getattr(pkg, "__path__", []), prefix=f"{package}.")
    return sorted(m.name for m in found if not m.name.rpartition(".")[2].startswith("_"))


def _origin(cat: str, key: str) -> None:
    """Remember which module declares ``key`` of ``cat`` (the caller's caller), for :func:`survey`."""
    module = sys._getframe(2).f_globals.get("__name__")
    if module:
        _ORIGIN.setdefault((cat, key), set()).add(module)


def survey(package: str) -> dict[str, dict[str, list[str]]]:
    """Import every module of ``package`` and index what each registers (the argument of :func:`declare_lazy`).

    Node and network classes are indexed under the module that defines
    them, rules, layer kinds and map kinds under the modules that declare
    them; keys and modules sorted.
    """
    for module in _modules(package):
        importlib.import_module(module)

    def mine(module: str) -> bool:
        return module == package or module.startswith(f"{package}.")

    index: dict[str, dict[str, set[str]]] = {c: {} for c in LAZY_CATEGORIES}
    for name, cls in REGISTRY.items():
        if mine(cls.__module__):
            index["node"].setdefault(name, set()).add(cls.__module__)
            if cls.source_for:
                index["source"].setdefault(cls.source_for, set()).add(cls.__module__)
            for f in getattr(cls, "formats", ()) or ():
                index["format"].setdefault(f, set()).add(cls.__module__)
    for base, cls in NETWORKS.items():
        if mine(cls.__module__):
            index["network"].setdefault(base, set()).add(cls.__module__)
    for (cat, key), modules in _ORIGIN.items():
        for module in modules:
            if mine(module):
                index[cat].setdefault(key, set()).add(module)
    return {cat: {k: sorted(v) for k, v in sorted(entries.items())} for cat, entries in index.items()}


def write_index(package: str) -> Path:
    """Write :func:`survey`'s index of ``package`` as ``INDEX`` in its module ``_index.py``; return the path.

    The module's other text (its docstring) is kept; a missing module is
    made.  The file is formatted with ``ruff format`` when ruff is installed.
    """
    import pprint

    table = pprint.pformat(survey(package), width=110, sort_dicts=False)
    path = Path(importlib.import_module(package).__file__).parent / "_index.py"
    text = (
        path.read_text() if path.exists() else f'"""What the modules of {package} register (made by write_index)."""\n'
    )
    head = text.split("\nINDEX", 1)[0].rstrip("\n")
    path.write_text(f"{head}\n\nINDEX: dict[str, dict[str, list[str]]] = {table}\n")
    import shutil
    import subprocess

    ruff = shutil.which("ruff") or shutil.which("ruff", path=str(Path(sys.executable).parent))
    if ruff:  # the project's style (the file is checked with the rest)
        subprocess.run([ruff, "format", "--quiet", str(path)], check=False)
    return path

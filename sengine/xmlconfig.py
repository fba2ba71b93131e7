"""Configuration files: XML -> :class:`~sengine.network.Network` (skylineEngine §5.2).

The file identifies itself as sengine's (``<sengine version="1">``) and is
validated against ``sengine/schema/sengine.xsd``.  Configurations are treated
as untrusted: the parser expands no entities, loads no DTD and touches no
network, and a file that declares a DOCTYPE is refused outright.  Every error
names the file and line.

References
----------
.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable
from functools import lru_cache
from pathlib import Path
from typing import Any

from lxml import etree

from .errors import ConfigError, Problems, SEngineError
from .network import Network
from .node import unknown_name
from .plan import CityPlan, MapSpec, Rule
from .registry import load_plugin, map_kinds, network_class, rule_params

__all__ = ["load_config", "read_network_file", "SCHEMA_PATH"]

SCHEMA_PATH = Path(__file__).with_name("schema") / "sengine.xsd"
_MAX_INCLUDE_DEPTH = 8
MAX_CONFIG_BYTES = 8 * 2**20  # a configuration is a page of XML; a larger file is a mistake (or /dev/zero)


def _parser() -> etree.XMLParser:
    return etree.XMLParser(
        resolve_entities=False,
        no_network=True,
        load_dtd=False,
        dtd_validation=False,
        huge_tree=False,
        remove_comments=True,
        remove_pis=True,
    )


@lru_cache(maxsize=1)
def _schema() -> etree.XMLSchema:
    return etree.XMLSchema(etree.parse(str(SCHEMA_PATH), _parser()))


def parse(path: Path, label: str) -> etree._Element:
    """Parse and validate one sengine XML file; return its root element."""
    data = read_small_file(path, label, MAX_CONFIG_BYTES, ConfigError)
    doctype = data.find(b"<!DOCTYPE")
    if doctype >= 0:  # refuse before parsing: no DTD, no entity, no network
        line = data.count(b"\n", 0, doctype) + 1
        raise ConfigError(
            "DOCTYPE declarations (DTDs and entities) are not allowed in sengine files", where=f"{label}:{line}"
        )
    try:
        tree = etree.fromstring(data, _parser(), base_url=None).getroottree()
    except etree.XMLSyntaxError as exc:
        line = exc.lineno or 1
        msg = re.sub(r",? line \d+, column \d+$", "", str(exc.msg or exc)).strip()
        raise ConfigError(f"not well-formed XML: {msg}", where=f"{label}:{line}") from None
    if tree.docinfo.doctype or tree.docinfo.internalDTD is not None:
        raise ConfigError(
            "DOCTYPE declarations (DTDs and entities) are not allowed in sengine files", where=f"{label}:1"
        )
    root = tree.getroot()
    if not isinstance(root.tag, str) or root.tag != "sengine":
        raise ConfigError(
            f'not a sengine file: the root element is <{root.tag}>, expected <sengine version="1">',
            where=f"{label}:{root.sourceline or 1}",
        )
    schema = _schema()
    if not schema.validate(tree):
        problems: list[SEngineError] = []
        for err in schema.error_log:
            msg = re.sub(r"^Element '([^']+)'", r"<\1>", err.message)
            problems.append(ConfigError(f"invalid: {msg}", where=f"{label}:{err.line}"))
        Problems.raise_if(problems, where=label)
    return root


def read_small_file(path: Path, label: str, limit: int, error: type[SEngineError]) -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes, or one-line ``error``.

    A FIFO, a device (``/dev/zero``), a folder or a file over the limit is
    refused before reading, so a mistake never blocks or fills the memory.
    """
    import stat

    try:
        st = path.stat()
    except FileNotFoundError:
        raise error("file not found", where=label) from None
    except OSError as exc:
        raise error(f"cannot read file: {exc.strerror}", where=label) from None
    if stat.S_ISDIR(st.st_mode):
        raise error("is a folder, not a file", where=label)
    if not stat.S_ISREG(st.st_mode):
        raise error("is not a regular file (a pipe, socket or device?)", where=label)
    if st.st_size > limit:
        raise error(f"is {st.st_size:,} bytes, more than the {limit:,} a configuration may have", where=label)
    try:
        with open(path, "rb") as fh:
            return fh.read(limit + 1)
    except OSError as exc:
        raise error(f"cannot read file: {exc.strerror}", where=label) from None


def _where(label: str, el: etree._Element) -> str:
    return f"{label}:{el.sourceline}"


def _floats(text: str, n: int, what: str, where: str) -> tuple[float, ...]:
    parts = [p for p in re.split(r"[\s,]+", text.strip()) if p]
    try:
        vals = tuple(float(p) for p in parts)
    except ValueError:
        vals = ()
    if len(vals) != n:
        raise ConfigError(f"{what}={text!r} must be {n} numbers", where=where)
    return vals


def check_rule(tag: str, attrs, where: str) -> list[SEngineError]:
    """Check a rule element's attributes against their declarations (see :func:`~sengine.registry.declare_rule`).

    Returns every problem (unknown attribute with a "did you mean", value of
    the wrong type or out of bounds); an empty list when all is well or
    nothing declares the element.
    """
    declared = rule_params(tag)
    if declared is None:
        return []
    problems: list[SEngineError] = []
    for name, value in attrs.items():
        if name not in declared:
            problems.append(ConfigError(f"<{tag}> " + unknown_name("attribute", name, declared), where=where))
            continue
        try:
            declared[name].coerce(value, where, f"<{tag}> {name}")
        except SEngineError as err:
            problems.append(err)
    return problems


CITY_ATTRIBUTES = ("name", "seed", "size", "origin")
MAX_CITY_SIZE = 100_000.0  # m; 100 km a side is a metropolis region, beyond it a typo (1e6 m)


def _read_plan(
    city: etree._Element | None, label: str, base_dir: Path, problems: list[SEngineError]
) -> tuple[CityPlan, int | None]:
    """The plan of ``<city>``; problems are appended to ``problems``, not raised."""
    if city is None:
        return CityPlan(), None
    w = _where(label, city)
    attrs = dict(city.attrib)
    plan = CityPlan(where=w)
    plan.name = attrs.pop("name", plan.name)
    seed = int(attrs.pop("seed")) if "seed" in attrs else None
    try:
        if "size" in attrs:
            text = attrs.pop("size")
            size = _floats(text, 2, "size", w)
            if not all(math.isfinite(v) and 0 < v <= MAX_CITY_SIZE for v in size):
                raise ConfigError(f"size={text!r} must be two positive widths of at most {MAX_CITY_SIZE:g} m", where=w)
            plan.size = size  # type: ignore[assignment]
    except ConfigError as err:
        problems.append(err)
    try:
        if "origin" in attrs:
            text = attrs.pop("origin")
            lat, lon = _floats(text, 2, "origin", w)
            if not (-90 <= lat <= 90 and -180 <= lon <= 180):
                raise ConfigError(f"origin={text!r} is not a latitude and longitude in degrees", where=w)
            plan.origin = (lat, lon)
    except ConfigError as err:
        problems.append(err)
    for key in attrs:
        problems.append(ConfigError("<city> " + unknown_name("attribute", key, CITY_ATTRIBUTES), where=w))
    plan.attrs = attrs
    for el in city:
        ew = _where(label, el)
        if el.tag == "map":
            kind = el.get("kind")
            if kind in plan.maps:
                problems.append(
                    ConfigError(f"a map of kind {kind!r} is given twice (first at {plan.maps[kind].where})", where=ew)
                )
                continue
            extra = {k: v for k, v in el.attrib.items() if k not in ("kind", "src")}
            plan.maps[kind] = MapSpec(kind, (base_dir / el.get("src")).resolve(), extra, ew)
        else:
            problems += check_rule(el.tag, el.attrib, ew)
            plan.rules.append(Rule(el.tag, dict(el.attrib), ew))
    return plan, seed


def _check_map_kinds(plan: CityPlan, problems: list[SEngineError]) -> None:
    known = map_kinds()
    for kind, spec in plan.maps.items():
        if kind not in known:
            problems.append(ConfigError(unknown_name("map kind", kind, sorted(known)), where=spec.where or None))


def _apply_network(net: Network, el: etree._Element, label: str) -> None:
    """Add the nodes, parameters and connections of a ``<network>`` element.

    A ``<node>`` whose id the base network already has replaces that node's
    type (the paper's association) or, without ``type``, only sets parameters.
    """
    seen: dict[str, str] = {}
    for child in el:
        w = _where(label, child)
        if child.tag == "node":
            node_id, type_ = child.get("id"), child.get("type")
            if node_id in seen:
                raise ConfigError(f"node id {node_id!r} is defined twice (first at {seen[node_id]})", where=w)
            seen[node_id] = w
            if node_id in net.specs:
                if type_:
                    net.replace(node_id, type_, where=w)
            elif not type_:
                raise ConfigError(f"node {node_id!r} has no type and is not in the base network", where=w)
            else:
                net.add(node_id, type_, where=w)
            for p in child:
                net.set_param(node_id, p.get("name"), p.get("value"), where=_where(label, p))
        elif child.tag == "param":
            net.set_param(child.get("node"), child.get("name"), child.get("value"), where=w)
        elif child.tag == "connect":
            net.connect(child.get("from"), child.get("to"), where=w)
        elif child.tag == "disconnect":
            net.disconnect(child.get("from"), child.get("to"), where=w)


def _base_network(el: etree._Element, label: str, folder: Path, depth: int, **kw: Any) -> Network:
    base, file = el.get("base"), el.get("file")
    w = _where(label, el)
    for key, value in (("base", base), ("file", file)):
        if value is not None and not value.strip():
            raise ConfigError(f"<network> {key}= is empty", where=w)
    if base and file:
        raise ConfigError("<network> takes base= or file=, not both", where=w)
    if depth > _MAX_INCLUDE_DEPTH:
        raise ConfigError("network files include each other too deeply (a loop?)", where=w)
    if base:
        cls = network_class(base, where=w)
        pairs = [(n.get("id"), n.get("type")) for n in el if n.tag == "node" and n.get("type")]
        return cls.from_config(pairs, where=w, **kw)
    if file:
        return read_network_file((folder / file), label=file, depth=depth + 1, **kw)
    return Network(**kw)


def read_network_file(path: Path, *, label: str | None = None, depth: int = 0, **kw: Any) -> Network:
    """Read a network-only file (as in ``networks/``) into a Network."""
    path = Path(path)
    label = label or str(path)
    root = parse(path, label)
    el = root.find("network")
    if el is None:
        raise ConfigError("the file has no <network>", where=f"{label}:{root.sourceline}")
    net = _base_network(el, label, path.parent, depth, **kw)
    _apply_network(net, el, label)
    return net


def load_config(
    path: str | Path,
    *,
    sets: Iterable[str] = (),
    maps: Iterable[str] = (),
    plugins: Iterable[str] = (),
    seed: int | None = None,
) -> Network:
    """Read a configuration file and return a ready-to-run Network.

    Parameters
    ----------
    path : path-like
        The configuration file.
    sets : iterable of str
        ``NODE.PARAM=VALUE`` overrides (``--set``).
    maps : iterable of str or MapSpec
        ``KIND=PATH`` replacements for the plan's maps (``--map``), or MapSpecs.
    plugins : iterable of str
        Plugin modules or paths to load first (``--plugin``).
    seed : int, optional
        Overrides the configuration's seed.
    """
    path = Path(path)
    label = str(path)
    for spec in plugins:
        load_plugin(spec, base_dir=Path.cwd(), where=f"--plugin {spec}")
    root = parse(path, label)
    base_dir = path.parent.resolve()
    for el in root.findall("plugin"):
        w = _where(label, el)
        module, ppath = el.get("module"), el.get("path")
        if bool(module) == bool(ppath):
            raise ConfigError("<plugin> takes exactly one of module= or path=", where=w)
        load_plugin(module or ppath, base_dir=base_dir, where=w)  # type: ignore[arg-type]
    problems: list[SEngineError] = []
    plan, file_seed = _read_plan(root.find("city"), label, base_dir, problems)
    for item in maps:
        if isinstance(item, MapSpec):  # a map given by a command (sengine osm FILE, a batch variant)
            old = plan.maps.get(item.kind)
            keep = not item.attrs and old is not None  # a new file for the config's map keeps its min, max ...
            plan.maps[item.kind] = MapSpec(item.kind, item.src, dict(old.attrs), item.where) if keep else item
            continue
        kind, sep, src = item.partition("=")
        if not sep or not kind or not src:
            problems.append(ConfigError(f"--map {item!r} must be KIND=PATH"))
            continue
        old = plan.maps.get(kind)
        attrs = dict(old.attrs) if old else {}
        plan.maps[kind] = MapSpec(kind, Path(src).resolve(), attrs, f"--map {kind}")
    _check_map_kinds(plan, problems)
    kw = dict(plan=plan, seed=seed if seed is not None else (file_seed or 0), base_dir=base_dir, source=label)
    el = root.find("network")
    net: Network = Network(**kw)
    if el is not None:
        try:
            net = _base_network(el, label, base_dir, 0, **kw)
            _apply_network(net, el, label)
        except SEngineError as err:
            problems.append(err)
    for item in sets:
        target, sep, value = item.partition("=")
        node_id, dot, name = target.partition(".")
        if not sep or not dot or not node_id or not name:
            problems.append(ConfigError(f"--set {item!r} must be NODE.PARAM=VALUE"))
            continue
        try:
            net.set_param(node_id, name, value, where=f"--set {target}")
        except SEngineError as err:
            problems.append(err)
    net.wire_plan()
    if problems:  # report the network's own problems with them, so one run shows every mistake
        try:
            net.validate()
        except SEngineError as err:
            problems.append(err)
    Problems.raise_if(problems, where=label)
    return net

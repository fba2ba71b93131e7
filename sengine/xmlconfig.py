"""Configuration files: XML -> :class:`~sengine.network.Network` (skylineEngine §5.2).

The file identifies itself as sengine's (``<sengine version="1">``) and is
validated against ``sengine/schema/sengine.xsd``.  Configurations are treated
as untrusted: the parser expands no entities, loads no DTD and touches no
network, and a file that declares a DOCTYPE is refused outright.  Every error
names the file and line.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from functools import lru_cache
from pathlib import Path
from typing import Any

from lxml import etree

from .errors import ConfigError
from .network import Network
from .node import unknown_name
from .plan import CityPlan, MapSpec, Rule
from .registry import load_plugin, network_class, rule_params

__all__ = ["load_config", "read_network_file", "SCHEMA_PATH"]

SCHEMA_PATH = Path(__file__).with_name("schema") / "sengine.xsd"
_MAX_INCLUDE_DEPTH = 8


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
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise ConfigError("file not found", where=label) from None
    except OSError as exc:
        raise ConfigError(f"cannot read file: {exc.strerror}", where=label) from None
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
        err = schema.error_log.last_error
        for e in schema.error_log:  # the first error is the most useful
            err = e
            break
        msg = re.sub(r"^Element '([^']+)'", r"<\1>", err.message)
        raise ConfigError(f"invalid: {msg}", where=f"{label}:{err.line}")
    return root


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


def check_rule(tag: str, attrs, where: str) -> None:
    """Check a rule element's attributes against their declarations (see :func:`~sengine.registry.declare_rule`)."""
    declared = rule_params(tag)
    if declared is None:
        return
    for name, value in attrs.items():
        if name not in declared:
            raise ConfigError(f"<{tag}> " + unknown_name("attribute", name, declared), where=where)
        declared[name].coerce(value, where, f"<{tag}> {name}")


def _read_plan(city: etree._Element | None, label: str, base_dir: Path) -> tuple[CityPlan, int | None]:
    if city is None:
        return CityPlan(), None
    w = _where(label, city)
    attrs = dict(city.attrib)
    plan = CityPlan(where=w)
    plan.name = attrs.pop("name", plan.name)
    seed = int(attrs.pop("seed")) if "seed" in attrs else None
    if "size" in attrs:
        size = _floats(attrs.pop("size"), 2, "size", w)
        if min(size) <= 0:
            raise ConfigError(f"size={city.get('size')!r} must be positive (m)", where=w)
        plan.size = size  # type: ignore[assignment]
    if "origin" in attrs:
        lat, lon = _floats(attrs.pop("origin"), 2, "origin", w)
        if not (-90 <= lat <= 90 and -180 <= lon <= 180):
            raise ConfigError(f"origin={city.get('origin')!r} is not a latitude and longitude in degrees", where=w)
        plan.origin = (lat, lon)
    plan.attrs = attrs
    for el in city:
        ew = _where(label, el)
        if el.tag == "map":
            kind = el.get("kind")
            if kind in plan.maps:
                raise ConfigError(f"a map of kind {kind!r} is given twice (first at {plan.maps[kind].where})", where=ew)
            extra = {k: v for k, v in el.attrib.items() if k not in ("kind", "src")}
            plan.maps[kind] = MapSpec(kind, (base_dir / el.get("src")).resolve(), extra, ew)
        else:
            check_rule(el.tag, el.attrib, ew)
            plan.rules.append(Rule(el.tag, dict(el.attrib), ew))
    return plan, seed


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
    maps : iterable of str
        ``KIND=PATH`` replacements for the plan's maps (``--map``).
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
    plan, file_seed = _read_plan(root.find("city"), label, base_dir)
    for item in maps:
        kind, sep, src = item.partition("=")
        if not sep or not kind or not src:
            raise ConfigError(f"--map {item!r} must be KIND=PATH")
        old = plan.maps.get(kind)
        attrs = dict(old.attrs) if old else {}
        plan.maps[kind] = MapSpec(kind, Path(src).resolve(), attrs, f"--map {kind}")
    kw = dict(plan=plan, seed=seed if seed is not None else (file_seed or 0), base_dir=base_dir, source=label)
    el = root.find("network")
    if el is None:
        net: Network = Network(**kw)
    else:
        net = _base_network(el, label, base_dir, 0, **kw)
        _apply_network(net, el, label)
    for item in sets:
        target, sep, value = item.partition("=")
        node_id, dot, name = target.partition(".")
        if not sep or not dot or not node_id or not name:
            raise ConfigError(f"--set {item!r} must be NODE.PARAM=VALUE")
        net.set_param(node_id, name, value, where=f"--set {target}")
    return net

"""``streets.osm``: the generated street network as OpenStreetMap XML.

skylineEngine uses OSM as the vector input and output format of every street
module (paper 002 §5.2), so a synthetic network is written back as OSM: one
way per street segment, one node per distinct location.  Locations are
WGS84 at OSM's fixed precision (1e-7 deg); segments meeting at a junction
share its node, so the file reads back as a connected graph.  Ids are
negative, as for new data not yet in the OSM database (JOSM, osmium and
osmnx accept them), and the file says ``upload="never"`` so that JOSM
refuses to upload generated streets to the OSM database.  sengine reads the
file back (``sengine osm streets.osm``; :mod:`sengine.nodes.osm.stream`
resolves negative node ids), and ``osmium check-refs`` finds every node a
way uses.

The ``highway`` tag comes from the ``class`` column: sengine's synthetic
classes map to OSM values (:data:`HIGHWAY`), OSM values pass through.  The
other columns of a roads layer become ``oneway=yes``, ``layer``,
``bridge=yes``, ``tunnel=yes``, ``width`` (m), ``name``, and
``sengine:osm_id``, the OSM way a street segment was cut from (an OSM
city's).  A street network made from OpenStreetMap says so in the
attributes the OSM API itself writes (``copyright``, ``attribution``,
``license``).  The XML is written by numpy string formatting, a few lines
per way; the same layer gives the same bytes.

References
----------
.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np
import shapely

from sengine.layer import Layer

__all__ = ["HIGHWAY", "street_graph", "way_tags", "write_osm"]

log = logging.getLogger(__name__)

#: OSM ``highway`` value of sengine's synthetic road classes.
HIGHWAY = {"major": "primary", "boundary": "secondary", "minor": "residential", "": "road"}


def street_graph(
    geoms: np.ndarray, to_lonlat: Callable[[np.ndarray], np.ndarray]
) -> tuple[np.ndarray, list[np.ndarray], np.ndarray]:
    """Nodes and ways of a line layer at OSM precision.

    Parameters
    ----------
    geoms : array of LineString / MultiLineString
        Street centre lines (m, planar).
    to_lonlat : callable
        ``(n, 2)`` planar -> ``(n, 2)`` WGS84 lon / lat.

    Returns
    -------
    nodes : numpy.ndarray of int64, shape (k, 2)
        Distinct locations as OSM fixed-point lon / lat (deg * 1e7), numbered
        in order of first use.
    ways : list of numpy.ndarray
        Node indices of each way (consecutive repeats removed).
    feature : numpy.ndarray of int64
        Input feature index of each way (ways with fewer than 2 distinct
        nodes are dropped).
    """
    geoms = np.asarray(geoms, dtype=object)
    parts, feat = shapely.get_parts(geoms, return_index=True) if len(geoms) else (geoms, np.empty(0, np.int64))
    keep = (shapely.get_type_id(parts) == 1) & ~shapely.is_empty(parts)
    parts, feat = parts[keep], feat[keep]
    coords, line = shapely.get_coordinates(parts, return_index=True)
    if len(coords) == 0:
        return np.empty((0, 2), np.int64), [], np.empty(0, np.int64)
    fixed = np.round(to_lonlat(coords) * 1e7).astype(np.int64)
    _, first, inv = np.unique(fixed, axis=0, return_index=True, return_inverse=True)
    inv = inv.ravel()
    # renumber nodes by first use, so ids follow the ways
    rank = np.empty(len(first), np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(len(first))
    node_of = rank[inv]
    repeat = np.zeros(len(node_of), bool)
    repeat[1:] = (line[1:] == line[:-1]) & (node_of[1:] == node_of[:-1])
    node_of, line = node_of[~repeat], line[~repeat]
    bounds = np.flatnonzero(np.diff(line)) + 1
    ways = np.split(node_of, bounds)
    way_line = line[np.concatenate([[0], bounds])] if len(line) else np.empty(0, np.int64)
    ok = np.array([len(w) >= 2 for w in ways], bool)
    ways = [w for w, k in zip(ways, ok, strict=False) if k]
    way_line = way_line[ok]
    # drop nodes no kept way uses, renumbering the rest in order
    used = np.zeros(len(first), bool)
    if ways:
        used[np.concatenate(ways)] = True
    new = np.cumsum(used) - 1
    nodes = fixed[np.sort(first)][used]
    ways = [new[w] for w in ways]
    return nodes, ways, feat[way_line]


def _texts(layer: Layer, key: str, fmt) -> list[str | None]:
    """``fmt(value)`` of each feature's ``key`` column (None where the column or the value is missing)."""
    n = len(layer)
    if key not in layer.attrs:
        return [None] * n
    col = np.asarray(layer[key])
    nulls = set(layer.meta.get("null_negative", ()))
    out = []
    for v in col.tolist():
        if v is None or (isinstance(v, float) and not np.isfinite(v)) or (key in nulls and v < 0):
            out.append(None)
        else:
            out.append(fmt(v))
    return out


def way_tags(layer: Layer) -> list[dict[str, str]]:
    """OSM tags of every feature of a roads layer (``highway``, ``oneway``, ``layer``, ``width`` ...)."""
    n = len(layer)
    classes = [str(c) for c in layer["class"].tolist()] if "class" in layer.attrs else [""] * n
    ids = layer.ids.tolist()
    optional = {
        "oneway": _texts(layer, "oneway", lambda v: "yes" if v else None),
        "layer": _texts(layer, "layer", lambda v: str(int(v)) if int(v) else None),
        "bridge": _texts(layer, "bridge", lambda v: "yes" if v else None),
        "tunnel": _texts(layer, "tunnel", lambda v: "yes" if v else None),
        "width": _texts(layer, "width", lambda v: f"{v:.6g}" if v > 0 else None),
        "name": _texts(layer, "name", lambda v: str(v) if v else None),
        "sengine:osm_id": _texts(layer, "osm_id", lambda v: str(int(v)) if int(v) > 0 else None),
    }
    tags = []
    for i in range(n):
        cls = classes[i] if classes[i] not in ("None", "nan") else ""
        t = {"highway": HIGHWAY.get(cls, cls), "sengine:id": str(ids[i])}
        if cls in HIGHWAY and cls:
            t["sengine:class"] = cls
        for key, values in optional.items():
            if values[i] is not None:
                t[key] = values[i]
        tags.append(dict(sorted(t.items())))
    return tags


#: The attributes with which the OSM API marks its data (for a street network made from it).
OSM_NOTICE = (
    'copyright="OpenStreetMap and contributors" attribution="https://www.openstreetmap.org/copyright" '
    'license="https://opendatacommons.org/licenses/odbl/1-0/"'
)


def _degrees(fixed: np.ndarray) -> list[str]:
    """OSM fixed-point coordinates (deg * 1e7) as decimal text, trailing zeros dropped ("40.720113")."""
    fixed = np.asarray(fixed, np.int64)
    whole, frac = np.divmod(np.abs(fixed), 10_000_000)
    sign = np.where(fixed < 0, "-", "")
    return [
        f"{s}{w}.{f:07d}".rstrip("0").rstrip(".")
        for s, w, f in zip(sign.tolist(), whole.tolist(), frac.tolist(), strict=True)
    ]


def write_osm(
    path: str | Path,
    layer: Layer,
    to_lonlat: Callable[[np.ndarray], np.ndarray],
    *,
    generator: str = "sengine",
    attribution: str | None = None,
) -> dict:
    """Write a roads layer as OSM XML; return node, way and junction counts.

    Junctions are nodes used by more than one way, or twice by one way.
    ``attribution`` (a street network made from OpenStreetMap) adds the OSM
    API's ``copyright``, ``attribution`` and ``license`` attributes.
    """
    nodes, ways, feat = street_graph(layer.geometry, to_lonlat)
    path = Path(path)
    head = f'<osm version="0.6" generator={quoteattr(generator)} upload="never"'
    head += f" {OSM_NOTICE}>" if attribution else ">"
    parts = ['<?xml version="1.0" encoding="UTF-8"?>\n', head, "\n"]
    if len(nodes):
        lo, hi = _degrees(nodes.min(axis=0)), _degrees(nodes.max(axis=0))
        parts.append(f'  <bounds minlat="{lo[1]}" minlon="{lo[0]}" maxlat="{hi[1]}" maxlon="{hi[0]}"/>\n')
        lon, lat = _degrees(nodes[:, 0]), _degrees(nodes[:, 1])
        node_xml = '  <node id="-%d" lat="%s" lon="%s"/>\n'
        parts.append("".join([node_xml % row for row in zip(range(1, len(nodes) + 1), lat, lon, strict=True)]))
    tags = way_tags(layer)
    quoted: dict[str, str] = {}

    def q(v: str) -> str:
        t = quoted.get(v)
        if t is None:
            t = quoted[v] = quoteattr(v)
        return t

    for k, (w, f) in enumerate(zip(ways, feat.tolist(), strict=True), 1):
        nds = "".join([f'    <nd ref="-{r}"/>\n' for r in (w + 1).tolist()])
        tg = "".join([f"    <tag k={q(a)} v={q(b)}/>\n" for a, b in tags[f].items()])
        parts.append(f'  <way id="-{k}">\n{nds}{tg}  </way>\n')
    parts.append("</osm>\n")
    path.write_text("".join(parts), encoding="utf-8")
    uses = np.bincount(np.concatenate(ways), minlength=len(nodes)) if ways else np.zeros(0, int)
    counts = {"nodes": int(len(nodes)), "ways": int(len(ways)), "junctions": int((uses > 1).sum())}
    log.info("wrote %s: %d nodes, %d ways (%d junctions)", path, counts["nodes"], counts["ways"], counts["junctions"])
    return counts

"""``streets.osm``: the generated street network as OpenStreetMap XML.

skylineEngine uses OSM as the vector input and output format of every street
module (paper 002 §5.2), so a synthetic network is written back as OSM: one
way per street segment, one node per distinct location.  Locations are
WGS84 at OSM's fixed precision (1e-7 deg); segments meeting at a junction
share its node, so the file reads back as a connected graph.  Ids are
negative, as for new data not yet in the OSM database (JOSM, osmium and
osmnx accept them).  The ``highway`` tag comes from the ``class`` column:
sengine's synthetic classes map to OSM values (:data:`HIGHWAY`), OSM values
pass through.  Written with pyosmium's :class:`osmium.SimpleWriter`.

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

import numpy as np
import osmium
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


def way_tags(layer: Layer) -> list[dict[str, str]]:
    """OSM tags of every feature of a roads layer (``highway``, ``width`` ...)."""
    n = len(layer)
    classes = [str(c) for c in layer["class"].tolist()] if "class" in layer.attrs else [""] * n
    ids = layer.ids.tolist()
    widths = names = None
    if "width" in layer.attrs:
        w = np.asarray(layer["width"], np.float64)
        widths = [f"{v:.6g}" if np.isfinite(v) and v > 0 else None for v in w.tolist()]
    if "name" in layer.attrs:
        names = [str(v) if v else None for v in layer["name"].tolist()]
    tags = []
    for i in range(n):
        cls = classes[i]
        t = {"highway": HIGHWAY.get(cls, cls), "sengine:id": str(ids[i])}
        if cls in HIGHWAY and cls:
            t["sengine:class"] = cls
        if widths is not None and widths[i] is not None:
            t["width"] = widths[i]
        if names is not None and names[i] is not None:
            t["name"] = names[i]
        tags.append(t)
    return tags


def write_osm(
    path: str | Path, layer: Layer, to_lonlat: Callable[[np.ndarray], np.ndarray], *, generator: str = "sengine"
) -> dict:
    """Write a roads layer as OSM XML; return node, way and junction counts.

    Junctions are nodes used by more than one way, or twice by one way.
    """
    nodes, ways, feat = street_graph(layer.geometry, to_lonlat)
    path = Path(path)
    header = osmium.io.Header()
    header.set("generator", generator)
    if len(nodes):
        lo, hi = nodes.min(axis=0) / 1e7, nodes.max(axis=0) / 1e7
        header.add_box(osmium.osm.Box(osmium.osm.Location(lo[0], lo[1]), osmium.osm.Location(hi[0], hi[1])))
    writer = osmium.SimpleWriter(str(path), header=header, overwrite=True)
    try:
        lonlat = (nodes / 1e7).tolist()
        Node = osmium.osm.mutable.Node
        for i, (lon, lat) in enumerate(lonlat):
            writer.add_node(Node(id=-(i + 1), location=(lon, lat)))
        Way = osmium.osm.mutable.Way
        tags = way_tags(layer)
        refs = (-(np.concatenate(ways) + 1)).tolist() if ways else []
        ends = np.cumsum([len(w) for w in ways]).tolist()
        start = 0
        for k, (end, f) in enumerate(zip(ends, feat.tolist(), strict=False)):
            writer.add_way(Way(id=-(k + 1), nodes=refs[start:end], tags=tags[f]))
            start = end
    finally:
        writer.close()
    uses = np.bincount(np.concatenate(ways), minlength=len(nodes)) if ways else np.zeros(0, int)
    counts = {"nodes": int(len(nodes)), "ways": int(len(ways)), "junctions": int((uses > 1).sum())}
    log.info("wrote %s: %d nodes, %d ways (%d junctions)", path, counts["nodes"], counts["ways"], counts["junctions"])
    return counts

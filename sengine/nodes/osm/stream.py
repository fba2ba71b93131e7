"""Streaming an OpenStreetMap file into flat arrays, with pyosmium.

The file is read by libosmium and handed to Python one way at a time; each
``highway=*`` way becomes well-known binary through libosmium's geometry
factory and its tags go into flat lists, so that no object model of the
whole file is built.  The points of all ways are then decoded in one numpy
call.

The Python callback per way is the cost of the read (libosmium decodes a
city extract in a fraction of it), so the ways are shared between two
processes when the machine has two cores (:func:`sengine.parallel.run_jobs`):
libosmium's own tag filter (``osmium.filter.TagFilter``, in C++) hands the
``residential`` ways to one pass and every other kept class to the other,
each reading the whole file.  Either way the ways come out ordered by OSM id
(file order for the usual sorted extracts) with the class codes numbered by
first appearance: the extract does not depend on the number of processes.

Water, parks and buildings (areas assembled by pyosmium) are read in the
same pass as the other classes' ways.

Negative ids are those of objects not yet in the OSM database (JOSM's
convention, and that of sengine's own ``streets.osm``): libosmium's node
location index keeps positive ids only, so a file whose ways use negative
nodes is read a second time, its negative nodes' locations kept by a node
callback (:func:`_read_pass` with ``negative``).  Files without them cost
nothing more.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import numpy as np
import shapely

from sengine.errors import InputDataError
from sengine.parallel import available_cores, can_fork, in_worker, run_jobs

__all__ = ["OsmExtract", "read_osm", "decode_lines", "parse_height", "int_tag", "TAG_KEYS"]

_WATER = {("natural", "water"), ("waterway", "riverbank"), ("landuse", "reservoir"), ("landuse", "basin")}
_PARKS = {("leisure", "park"), ("leisure", "garden")}
#: OSM ``landuse`` (and school ``amenity``) areas -> the buildings' land use (``extras=landuse``).
LANDUSE = {
    ("landuse", "residential"): "residential",
    ("landuse", "commercial"): "commercial",
    ("landuse", "retail"): "commercial",
    ("landuse", "civil"): "office",
    ("landuse", "industrial"): "industrial",
    ("landuse", "education"): "educational",
    ("amenity", "school"): "educational",
    ("amenity", "university"): "educational",
    ("amenity", "college"): "educational",
    ("amenity", "kindergarten"): "educational",
}
#: OSM ``building`` values -> the building's land use (wiki "Key:building", its typology table);
#: ``yes`` and the civic, religious and other types say no use and count as unknown.
BUILDING_USE = {
    **dict.fromkeys(
        (
            "apartments", "residential", "house", "detached", "semidetached_house", "terrace",
            "bungalow", "dormitory", "cabin", "farm", "houseboat", "static_caravan",
        ),
        "residential",
    ),
    **dict.fromkeys(("commercial", "retail", "supermarket", "kiosk", "hotel"), "commercial"),
    **dict.fromkeys(("office", "government"), "office"),
    **dict.fromkeys(("industrial", "warehouse", "manufacture", "factory", "hangar", "depot"), "industrial"),
    **dict.fromkeys(("school", "university", "college", "kindergarten"), "educational"),
}  # fmt: skip
POLYGON_KINDS = ("water", "parks", "buildings", "landuse")
_NUM = re.compile(r"^\s*([0-9]+(?:[.,][0-9]+)?)\s*(m|ft|')?\s*$")
#: The tags kept per way besides ``highway`` (``tunnel`` holds ``covered`` when untagged).
TAG_KEYS = ("name", "layer", "bridge", "tunnel", "oneway")
_UNDEFINED = 2147483647  # libosmium's coordinate of a node missing from the file

#: The ``highway`` value whose ways the second process reads: the commonest in city extracts
#: (half of Liège's 80,000 kept ways).
SPLIT_CLASS = "residential"
#: Files smaller than this (bytes) are read in one process: a fork costs more than it saves.
PARALLEL_BYTES = 1 << 20


def int_tag(value: str | None) -> int:
    """An integer tag (``"2"``, ``"-1"``, ``"1.5"`` -> 1); 0 when absent or unreadable.

    Clamped to +-1,000,000 (an OSM ``layer`` is a small number; ``99999999999999999999``
    would not fit an int64).
    """
    try:
        number = float(value) if value else 0.0
    except ValueError:
        return 0
    if not math.isfinite(number):
        return 0
    return int(max(-1e6, min(1e6, number)))


#: OSM ``roof:shape`` values and the roof kinds of the buildings layer (others: flat).
ROOF_SHAPES = {
    "flat": "flat",
    "skillion": "shed",
    "lean_to": "shed",
    "gabled": "gable",
    "saltbox": "gable",
    "gambrel": "gable",
    "round": "gable",
    "hipped": "hip",
    "half-hipped": "hip",
    "side_hipped": "hip",
    "mansard": "hip",
    "pyramidal": "pyramid",
    "cone": "pyramid",
    "dome": "pyramid",
    "onion": "pyramid",
}


def parse_height(value: str | None) -> float:
    """A height tag in metres (``"12"``, ``"12.5 m"``, ``"40 ft"``); NaN when unreadable."""
    if not value:
        return float("nan")
    m = _NUM.match(value)
    if not m:
        return float("nan")
    h = float(m.group(1).replace(",", "."))
    return h * 0.3048 if m.group(2) in ("ft", "'") else h


@dataclass
class OsmExtract:
    """What :func:`read_osm` collects, still in WGS84.

    Attributes
    ----------
    fixed : ndarray (n, 2) of int64
        Every node of every kept highway way, way after way,
        as (lon, lat) in libosmium's fixed point (1e-7 deg): equal values
        are the same place.
    line : ndarray (n,) of int64
        Index of each point's way (non-decreasing).
    way_id, code : ndarray (w,) of int64
        Per kept way, ascending OSM id: the id and the code of its ``highway`` value in ``codes``.
    codes : dict of str to int
        ``highway`` value -> code, numbered by first appearance.
    tags : dict of str to ndarray (w,) of object
        ``name``, ``layer``, ``bridge``, ``tunnel`` (``tunnel`` or else
        ``covered``) and ``oneway`` values per way, None when absent.
    node_ids : ndarray (n,) of int64 or None
        OSM node id of each point (only when asked for).
    polygons : dict of str to (list of str, list of dict)
        ``"water"``, ``"parks"``, ``"buildings"``, ``"landuse"``: hex WKB multipolygons and their attributes.
    clipped : int
        Ways whose nodes are partly missing from the file (cut by the extract's bounding box).
    coastline : list of str
        Hex WKB LineStrings (lon, lat) of the ``natural=coastline`` ways, read
        with the water: land on their left, the sea on their right.
    """

    fixed: np.ndarray = field(default_factory=lambda: np.empty((0, 2), np.int64))
    line: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))
    way_id: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))
    code: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))
    codes: dict = field(default_factory=dict)
    tags: dict = field(default_factory=dict)
    node_ids: np.ndarray | None = None
    polygons: dict = field(default_factory=lambda: {k: ([], []) for k in POLYGON_KINDS})
    clipped: int = 0
    coastline: list = field(default_factory=list)


@dataclass
class _Ways:
    """The ways one pass collected, in its file order (small and picklable: it crosses a pipe)."""

    fixed: np.ndarray  # (n, 2) int32, libosmium fixed point
    size: np.ndarray  # points per way
    way_id: np.ndarray
    code: np.ndarray  # into names
    names: list
    more: list  # (way index, name, layer, bridge, tunnel, oneway) of ways with more tags than highway
    node_ids: np.ndarray | None
    clipped: int
    polygons: dict  # the areas of the pass (see OsmExtract.polygons), empty without extras
    coastline: list  # hex WKB of the coastline ways (with the water only)
    negative: bool = False  # some way uses a node with a negative id that the location index cannot hold


def read_osm(
    path: str | Path,
    *,
    classes: frozenset[str] | None = None,
    extras: frozenset[str] = frozenset(),
    node_ids: bool = False,
    where: str | None = None,
    workers: int | None = None,
) -> OsmExtract:
    """Stream an OSM file and collect its highway ways (and optional areas).

    Parameters
    ----------
    path : str or Path
        ``.osm``, ``.osm.bz2``, ``.osm.gz`` or ``.osm.pbf``.
    classes : frozenset of str, optional
        ``highway`` values to keep; all when None.
    extras : frozenset of str
        Any of ``"water"``, ``"parks"``, ``"buildings"``: also assemble those
        areas (closed ways and multipolygon relations, with pyosmium; costs
        a pass over the relations).
    node_ids : bool
        Also keep the OSM node id of every way node (slower).
    where : str, optional
        Prefix for error messages.
    workers : int, optional
        Processes reading the ways: 1, or 2 to read the :data:`SPLIT_CLASS`
        ways in a pass of their own, side by side with the other classes'
        (used only when ``classes`` holds it and another class).  Default:
        2 for a file of at least :data:`PARALLEL_BYTES` on a machine with
        two free cores, outside a worker process.  The result is the same.

    Returns
    -------
    OsmExtract

    Raises
    ------
    InputDataError
        Missing, truncated, corrupt or non-OSM file; a node outside
        [-180, 180] x [-90, 90].
    """
    path = Path(path)
    if not path.is_file():
        raise InputDataError(f"OSM file {str(path)!r} does not exist", where=where)
    out = OsmExtract()
    split = classes is not None and SPLIT_CLASS in classes and len(classes) > 1
    if workers is None:
        workers = _free_cores() if path.stat().st_size >= PARALLEL_BYTES else 1
    if split and workers >= 2:
        import osmium  # noqa: F401 (before the fork: a child must not wait on an import lock another thread held)

        split_off = frozenset({SPLIT_CLASS})
        parts = run_jobs(
            [
                partial(_read_pass, path, classes - split_off, extras=extras, node_ids=node_ids, where=where),
                partial(_read_pass, path, split_off, extras=frozenset(), node_ids=node_ids, where=where),
            ],
            2,
        )
    else:
        parts = [_read_pass(path, classes, extras=extras, node_ids=node_ids, where=where)]
    if any(p.negative for p in parts):  # new objects (negative ids): read again, keeping their locations
        parts = [_read_pass(path, classes, extras=extras, node_ids=node_ids, where=where, negative=True)]
    for kind, (geoms, attrs) in parts[0].polygons.items():
        out.polygons[kind] = (geoms, attrs)
    out.coastline = parts[0].coastline
    _merge(out, parts, node_ids=node_ids)
    return out


def _free_cores() -> int:
    """2 when a second reader would get a core of its own; 1 in a worker process or without a safe fork."""
    return 1 if in_worker() or not can_fork() else min(2, available_cores())


def _read_pass(
    path: Path, select: frozenset[str] | None, *, extras, node_ids: bool, where, negative: bool = False
) -> _Ways:
    """One pyosmium pass: the highway ways whose class is in ``select`` (all when None), and the ``extras`` areas.

    The class filter runs in libosmium (C++), so that other ways never
    reach Python.  With ``negative``, a node callback keeps the locations
    of the nodes with negative ids, which the ways then use.
    """
    import osmium

    wkb = osmium.geom.WKBFactory()
    create, every = wkb.create_linestring, osmium.geom.ALL
    hex_wkb: list = []
    way_id: list = []
    code_l: list = []
    more: list = []
    refs: list = []
    codes: dict = {}
    append_line, append_id, append_code, append_more = hex_wkb.append, way_id.append, code_l.append, more.append
    clipped = [0]
    neg: dict | None = {} if negative else None
    uses_negative = [False]

    def node(n):
        if n.id < 0 and n.location.valid():
            neg[n.id] = (n.location.lon, n.location.lat, n.id)

    coast: list = []
    sea = "water" in extras

    def way(w):
        tags = w.tags
        hw = tags.get("highway")
        if hw is None:  # the filter lets natural=* ways through only to find the coastline
            if sea and tags.get("natural") == "coastline":
                try:
                    coast.append(create(w, every))
                except (osmium.InvalidLocationError, RuntimeError):
                    pass  # clipped by the extract: its other pieces still close the sea
            return
        code = codes.get(hw)
        if code is None:
            code = codes[hw] = len(codes)
        kept = None
        try:
            append_line(create(w, every))
        except osmium.InvalidLocationError:
            if neg is None and not uses_negative[0] and any(n.ref < 0 for n in w.nodes):
                uses_negative[0] = True
            kept = _clipped_way(w, path, hex_wkb, where, neg)
            if neg is None or len(kept or ()) < len(w.nodes):
                clipped[0] += 1
            if kept is None:
                return
        except RuntimeError:  # libosmium geometry_error: a way of fewer than two nodes
            return
        append_id(w.id)
        append_code(code)
        if len(tags) > 1:  # most Liège-like street tables carry highway only
            append_more(
                (
                    len(code_l) - 1,
                    tags.get("name"),
                    tags.get("layer"),
                    tags.get("bridge"),
                    tags.get("tunnel") or tags.get("covered"),
                    tags.get("oneway"),
                )
            )
        if node_ids:
            refs.append(kept if kept is not None else [n.ref for n in w.nodes])

    callbacks = {"way": way}
    if negative:
        callbacks["node"] = node
    polygons: dict = {}
    if extras:
        polygons = {k: ([], []) for k in POLYGON_KINDS}
        callbacks["area"] = _area_callback(wkb, extras, polygons)
    if select is None:
        ways_filter = osmium.filter.KeyFilter("highway", *(("natural",) if sea else ()))
    else:
        coastline = (("natural", "coastline"),) if sea else ()
        ways_filter = osmium.filter.TagFilter(*(("highway", c) for c in sorted(select)), *coastline)
    ways_filter.enable_for(osmium.osm.WAY)  # areas, nodes and relations pass untouched
    try:
        osmium.make_simple_handler(**callbacks).apply_file(str(path), locations=True, filters=[ways_filter])
    except InputDataError:
        raise
    except (RuntimeError, ValueError, osmium.InvalidLocationError) as exc:
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputDataError(f"cannot read OSM file {str(path)!r}: {msg}", where=where) from None
    lonlat, line = decode_lines(hex_wkb)
    return _Ways(
        np.rint(lonlat * 1e7).astype(np.int32),
        np.bincount(line, minlength=len(code_l)),
        np.asarray(way_id, np.int64),
        np.asarray(code_l, np.int64),
        list(codes),
        more,
        np.fromiter((r for way in refs for r in way), np.int64) if node_ids else None,
        clipped[0],
        polygons,
        coast,
        uses_negative[0],
    )


def _area_callback(wkb, extras: frozenset[str], polygons: dict):
    """Pyosmium's area callback filling ``polygons`` (see :attr:`OsmExtract.polygons`)."""
    import osmium

    def area(a):
        tags = a.tags
        kind = None
        if "building" in tags and tags.get("building") != "no":
            kind = "buildings"
        elif any((k, tags.get(k)) in _WATER for k in ("natural", "waterway", "landuse")):
            kind = "water"
        elif ("leisure", tags.get("leisure")) in _PARKS:
            kind = "parks"
        use = LANDUSE.get(("landuse", tags.get("landuse"))) or LANDUSE.get(("amenity", tags.get("amenity")))
        if kind == "buildings":  # the building's own type first (building=apartments), then its landuse / amenity
            use = BUILDING_USE.get(tags.get("building", "").strip().lower()) or use
        if kind is None and use is not None:
            kind = "landuse"
        if kind is None or kind not in extras:
            return
        try:
            geom = wkb.create_multipolygon(a)
        except (osmium.InvalidLocationError, RuntimeError):
            return  # broken or clipped ring: skipped like osmium-tool does
        geoms, attrs = polygons[kind]
        geoms.append(geom)
        attrs.append(
            {
                "osm_id": a.orig_id(),
                "name": tags.get("name", ""),
                "height": parse_height(tags.get("height")),
                "levels": int_tag(tags.get("building:levels")),
                "roof": ROOF_SHAPES.get(tags.get("roof:shape", "flat").strip().lower(), "flat"),
                "roof_height": parse_height(tags.get("roof:height")),
                "use": use or "",
            }
        )

    return area


def _merge(out: OsmExtract, parts: list[_Ways], *, node_ids: bool) -> None:
    """Fill ``out``'s way arrays from the passes: ways by ascending id, codes by first appearance."""
    names = [c for p in parts for c in p.names]
    shift = np.cumsum([0] + [len(p.names) for p in parts])[:-1]
    way_id = np.concatenate([p.way_id for p in parts])
    code = np.concatenate([p.code + s for p, s in zip(parts, shift, strict=True)])
    size = np.concatenate([p.size for p in parts])
    fixed = np.concatenate([p.fixed for p in parts]).astype(np.int64)
    ids = np.concatenate([p.node_ids for p in parts]) if node_ids else None
    base = np.cumsum([0] + [len(p.way_id) for p in parts])[:-1]
    more = [(i + b, *rest) for p, b in zip(parts, base, strict=True) for i, *rest in p.more]
    out.clipped = sum(p.clipped for p in parts)
    order = np.argsort(way_id, kind="stable")
    start = np.cumsum(size) - size
    rank = np.empty(len(order), np.int64)
    rank[order] = np.arange(len(order))
    if np.any(order[1:] < order[:-1]):  # not in id order yet: move each way's points with it
        size = size[order]
        pts = np.repeat(start[order] - (np.cumsum(size) - size), size) + np.arange(int(size.sum()))
        fixed = fixed[pts]
        ids = ids[pts] if ids is not None else None
        way_id, code = way_id[order], code[order]
    # codes by first appearance in id order
    seen, first = np.unique(code, return_index=True)
    renum = np.zeros(len(names), np.int64)
    renum[seen[np.argsort(first)]] = np.arange(len(seen))
    out.codes = {names[c]: i for i, c in enumerate(seen[np.argsort(first)].tolist())}
    out.code = renum[code]
    out.way_id = way_id
    out.fixed = fixed
    out.line = np.repeat(np.arange(len(way_id), dtype=np.int64), size)
    out.node_ids = ids
    out.tags = {k: np.full(len(way_id), None, dtype=object) for k in TAG_KEYS}
    if more:
        i, *cols = zip(*more, strict=True)
        i = rank[np.asarray(i, np.int64)]
        for k, col in zip(TAG_KEYS, cols, strict=True):
            out.tags[k][i] = col


def _clipped_way(w, path, hex_wkb, where, negative: dict | None = None) -> list[int] | None:
    """Slow path for a way with missing node locations: keep its longest run of located nodes.

    ``negative`` holds the ``(lon, lat, id)`` of the nodes with negative ids.
    Returns the OSM ids of the kept nodes, or None when fewer than two are left.
    """
    runs, run = [], []
    for n in w.nodes:
        loc = n.location
        if loc.valid():
            run.append((loc.lon, loc.lat, n.ref))
            continue
        if negative is not None and n.ref in negative:
            run.append(negative[n.ref])
            continue
        if loc.x != _UNDEFINED or loc.y != _UNDEFINED:  # present, but outside the valid range
            raise InputDataError(
                f"OSM file {str(path)!r}: node {n.ref} has coordinates ({loc.x / 1e7}, {loc.y / 1e7}) "
                "outside [-180, 180] x [-90, 90]",
                where=where,
            )
        runs.append(run)
        run = []
    runs.append(run)
    best = max(runs, key=len)
    if len(best) < 2:
        return None
    hex_wkb.append(shapely.to_wkb(shapely.linestrings([p[:2] for p in best]), hex=True))
    return [p[2] for p in best]


def decode_lines(hex_wkb: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Coordinates and line index of a list of hex WKB LineStrings, without a geometry per line.

    libosmium writes little-endian 2D LineStrings (1 byte order, 4 bytes type,
    4 bytes count, 16 bytes per point); the whole list is decoded by numpy
    in one go.

    Returns
    -------
    xy : ndarray (n, 2) of float64
    line : ndarray (n,) of int64
        Index of each point's line, ascending.
    """
    if not hex_wkb:
        return np.empty((0, 2)), np.empty(0, np.int64)
    nbytes = np.fromiter(map(len, hex_wkb), np.int64, len(hex_wkb)) // 2
    raw = np.frombuffer(bytes.fromhex("".join(hex_wkb)), np.uint8)
    header = raw[(np.cumsum(nbytes) - nbytes)[:, None] + np.arange(9)]
    if not (np.all(header[:, 0] == 1) and np.all(header[:, 1:5].copy().view("<u4").ravel() == 2)):
        # not the libosmium layout (e.g. our own fallback WKB): let GEOS decode
        xy, line = shapely.get_coordinates(shapely.from_wkb(hex_wkb), return_index=True)
        return xy, line.astype(np.int64)
    npts = header[:, 5:9].copy().view("<u4").ravel().astype(np.int64)
    first = np.cumsum(nbytes) - nbytes + 9
    line = np.repeat(np.arange(len(hex_wkb), dtype=np.int64), npts)
    k = np.arange(line.size) - np.repeat(np.cumsum(npts) - npts, npts)
    offsets = first[line] + 16 * k
    xy = raw[offsets[:, None] + np.arange(16)].view("<f8").reshape(-1, 2)
    return xy, line

"""OpenStreetMap import: the ``majorRoads`` node of the load-map network.

skylineEngine reads a real city "as a simple image map, or as an
OpenStreetMap file" (002 §5.2, Fig. 6); for a real city the major- and
minor-road modules "are collapsed into a single node that simply reads the
file and passes the resulting network to the next modules" (002 §5.3).  This
module is that node.

The file (``.osm``, ``.osm.bz2``, ``.osm.pbf``) is streamed once with
pyosmium, each ``highway=*`` way turned into well-known binary by
libosmium's geometry factory and its tags into flat lists: no object model of
the whole file is built.  The points are then projected to the
UTM zone of the data with one vectorized pyproj call (each junction once)
and split into *street segments* between junctions with numpy.  A junction is a point shared by two ways (or visited twice by
one way) or a way's end.  Point identity is the OSM location itself
(libosmium's 1e-7 degree fixed-point integers): two ways share a junction
exactly when they share a node, except for the data error of two distinct
nodes stacked on one spot, which this treats as the junction it was meant to
be.  The topology is kept: every segment carries the indices ``u`` / ``v`` of
its end points into ``meta["nodes"]`` (planar xy) and ``meta["node_keys"]``.

Water (``natural=water``, ``waterway=riverbank``, ``landuse=reservoir``),
parks (``leisure=park``/``garden``) and buildings (with ``height`` /
``building:levels``) of the same file are optional extra layers, assembled
by pyosmium in the same pass.

References
----------
skylineEngine (paper 002), §5.2 "Input Module" and §5.3 "Major & Minor
Roads Modules".
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import shapely

from sengine import Layer, Param, Port, SENode, register
from sengine.errors import InputDataError
from sengine.geo import from_lonlat, utm_crs

from .clean import split_at_junctions

__all__ = [
    "MAJOR_CLASSES",
    "MINOR_CLASSES",
    "STREET_WIDTHS",
    "OsmExtract",
    "read_osm",
    "project_extract",
    "streets_layer",
    "OsmRead",
]

log = logging.getLogger(__name__)

#: ``highway`` values counted as major roads by default (avenues).
MAJOR_CLASSES = (
    "motorway,motorway_link,trunk,trunk_link,primary,primary_link,"
    "secondary,secondary_link,tertiary,tertiary_link"
)
#: ``highway`` values counted as minor roads by default; every other value is ignored.
MINOR_CLASSES = "unclassified,residential,living_street,pedestrian,road,busway"

#: Street width between block fronts (m) by class.  Anchored on the Prague
#: public-space minima (paper 003 §3.2): city avenue 24 m, important street
#: 18 m, local street 12 m, access street 8 m; paths 3 m.
STREET_WIDTHS = {
    "motorway": 24.0, "trunk": 24.0, "primary": 18.0, "secondary": 18.0, "tertiary": 15.0,
    "unclassified": 12.0, "residential": 12.0, "road": 12.0, "busway": 12.0,
    "living_street": 8.0, "pedestrian": 8.0, "service": 8.0, "track": 6.0,
}
_DEFAULT_WIDTH = 3.0  # footway, path, cycleway, steps ...

_WATER = {("natural", "water"), ("waterway", "riverbank"), ("landuse", "reservoir"), ("landuse", "basin")}
_PARKS = {("leisure", "park"), ("leisure", "garden")}
_NUM = re.compile(r"^\s*([0-9]+(?:[.,][0-9]+)?)\s*(m|ft|')?\s*$")


def _classes(text: str) -> frozenset[str]:
    return frozenset(c.strip() for c in str(text).split(",") if c.strip())


def _int_tag(value: str | None) -> int:
    try:
        return int(float(value)) if value else 0
    except ValueError:
        return 0


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
        Every node of every kept highway way, way after way in file order,
        as (lon, lat) in libosmium's fixed point (1e-7 deg): equal values
        are the same place.
    line : ndarray (n,) of int64
        Index of each point's way (non-decreasing).
    way_id, code : ndarray (w,) of int64
        Per kept way: OSM id and the code of its ``highway`` value in ``codes``.
    codes : dict of str to int
        ``highway`` value -> code.
    tags : dict of str to ndarray (w,) of object
        ``name``, ``layer``, ``bridge``, ``tunnel`` (``tunnel`` or else
        ``covered``) and ``oneway`` values per way, None when absent.
    node_ids : ndarray (n,) of int64 or None
        OSM node id of each point (only when asked for).
    polygons : dict of str to (list of str, list of dict)
        ``"water"``, ``"parks"``, ``"buildings"``: hex WKB multipolygons and their attributes.
    clipped : int
        Ways whose nodes are partly missing from the file (cut by the extract's bounding box).
    """

    fixed: np.ndarray = field(default_factory=lambda: np.empty((0, 2), np.int64))
    line: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))
    way_id: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))
    code: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))
    codes: dict = field(default_factory=dict)
    tags: dict = field(default_factory=dict)
    node_ids: np.ndarray | None = None
    polygons: dict = field(default_factory=lambda: {k: ([], []) for k in ("water", "parks", "buildings")})
    clipped: int = 0


_TAG_KEYS = ("name", "layer", "bridge", "tunnel", "oneway")
#: The tag key each area kind of :func:`read_osm` needs (see ``area`` in :func:`_read_pyosmium`).
_AREA_KEYS = {"building": "buildings", "natural": "water", "waterway": "water", "landuse": "water",
              "leisure": "parks"}
_UNDEFINED = 2147483647  # libosmium's coordinate of a node missing from the file


def read_osm(path: str | Path, *, classes: frozenset[str] | None = None, extras: frozenset[str] = frozenset(),
             node_ids: bool = False, where: str | None = None) -> OsmExtract:
    """Stream an OSM file and collect its highway ways (and optional areas).

    The file is streamed with pyosmium (locations kept in its node index).

    Parameters
    ----------
    path : str or Path
        ``.osm``, ``.osm.bz2``, ``.osm.gz`` or ``.osm.pbf``.
    classes : frozenset of str, optional
        ``highway`` values to keep; all when None.
    extras : frozenset of str
        Any of ``"water"``, ``"parks"``, ``"buildings"``: also assemble those
        areas (closed ways and multipolygon relations, with pyosmium; costs
        a pass over the file).
    node_ids : bool
        Also keep the OSM node id of every way node (slower when read with pyosmium).
    where : str, optional
        Prefix for error messages.

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
    return _read_pyosmium(path, classes=classes, extras=extras, node_ids=node_ids, where=where)


def _read_pyosmium(path: Path, *, classes, extras, node_ids: bool, where, ways: bool = True,
                   out: OsmExtract | None = None) -> OsmExtract:
    """:func:`read_osm` with pyosmium callbacks (any format); ``ways=False`` reads the areas only."""
    import osmium

    out = OsmExtract() if out is None else out
    wkb = osmium.geom.WKBFactory()
    every = osmium.geom.ALL
    hex_wkb: list = []
    way_id: list = []
    code_l: list = []
    more: list = []
    refs: list = []
    append_line = hex_wkb.append
    codes = out.codes
    append_id, append_code, append_more = way_id.append, code_l.append, more.append
    clipped = [0]

    def way(w):
        tags = w.tags
        hw = tags.get("highway")
        if hw is None:
            return
        code = codes.get(hw)
        if code is None:
            if classes is not None and hw not in classes:
                return
            code = codes[hw] = len(codes)
        kept = None
        try:
            append_line(wkb.create_linestring(w, every))
        except osmium.InvalidLocationError:
            kept = _clipped_way(w, path, hex_wkb, where)
            clipped[0] += 1
            if kept is None:
                return
        except RuntimeError:  # libosmium geometry_error: a way of fewer than two nodes
            return
        append_id(w.id)
        append_code(code)
        if len(tags) > 1:  # most Liège-like street tables carry highway only
            append_more((len(code_l) - 1, tags.get("name"), tags.get("layer"), tags.get("bridge"),
                         tags.get("tunnel") or tags.get("covered"), tags.get("oneway")))
        if node_ids:
            refs.append(kept if kept is not None else [n.ref for n in w.nodes])

    def area(a):
        tags = a.tags
        kind = None
        if "building" in tags and tags.get("building") != "no":
            kind = "buildings"
        elif any((k, tags.get(k)) in _WATER for k in ("natural", "waterway", "landuse")):
            kind = "water"
        elif ("leisure", tags.get("leisure")) in _PARKS:
            kind = "parks"
        if kind is None or kind not in extras:
            return
        try:
            geom = wkb.create_multipolygon(a)
        except (osmium.InvalidLocationError, RuntimeError):
            return  # broken or clipped ring: skipped like osmium-tool does
        geoms, attrs = out.polygons[kind]
        geoms.append(geom)
        attrs.append({
            "osm_id": a.orig_id(), "name": tags.get("name", ""),
            "height": parse_height(tags.get("height")),
            "levels": _int_tag(tags.get("building:levels")),
        })

    callbacks = {"way": way} if ways else {}
    if extras:
        callbacks["area"] = area
    handler = osmium.make_simple_handler(**callbacks)
    try:
        handler.apply_file(str(path), locations=True)
    except InputDataError:
        raise
    except (RuntimeError, ValueError, osmium.InvalidLocationError) as exc:
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputDataError(f"cannot read OSM file {str(path)!r}: {msg}", where=where) from None
    if not ways:
        return out
    out.clipped = clipped[0]
    if out.clipped:
        log.info("%s: %d ways lose nodes outside the extract; kept their parts inside", path.name, out.clipped)
    lonlat, line = decode_lines(hex_wkb)
    out.fixed = np.rint(lonlat * 1e7).astype(np.int64)
    out.line = line
    out.way_id = np.asarray(way_id, np.int64)
    out.code = np.asarray(code_l, np.int64)
    nway = len(code_l)
    out.tags = {k: np.full(nway, None, dtype=object) for k in _TAG_KEYS}
    if more:
        i, *cols = zip(*more, strict=True)
        i = np.asarray(i, np.int64)
        for k, col in zip(_TAG_KEYS, cols, strict=True):
            out.tags[k][i] = col
    if node_ids:
        out.node_ids = np.fromiter((r for way in refs for r in way), np.int64)
    return out


def _clipped_way(w, path, hex_wkb, where) -> list[int] | None:
    """Slow path for a way with missing node locations: keep its longest run of located nodes.

    Returns the OSM ids of the kept nodes, or None when fewer than two are left.
    """
    runs, run = [], []
    for n in w.nodes:
        loc = n.location
        if loc.valid():
            run.append((loc.lon, loc.lat, n.ref))
            continue
        if loc.x != _UNDEFINED or loc.y != _UNDEFINED:  # present, but outside the valid range
            raise InputDataError(
                f"OSM file {str(path)!r}: node {n.ref} has coordinates ({loc.x / 1e7}, {loc.y / 1e7}) "
                "outside [-180, 180] x [-90, 90]", where=where)
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


def project_extract(xy_lonlat: np.ndarray, bounds: tuple | None = None) -> tuple[np.ndarray, str, tuple[float, float]]:
    """Project lon/lat points to the UTM zone of their bounding-box centre.

    ``bounds`` ((lon, lat) min, (lon, lat) max) replaces the points' own
    bounding box when given.

    Returns
    -------
    xy : ndarray (n, 2)
        Metres, in the UTM frame (false easting kept, so the EPSG code is exact).
    crs : str
        ``"EPSG:326zz"`` (north) or ``"EPSG:327zz"`` (south).
    origin : (lat, lon)
        The bounding-box centre (deg), the city's geographic origin.
    """
    lo, hi = (xy_lonlat.min(axis=0), xy_lonlat.max(axis=0)) if bounds is None else bounds
    lon, lat = (lo + hi) / 2.0
    crs = utm_crs(lat, lon)
    return from_lonlat(crs)(xy_lonlat), crs, (float(lat), float(lon))


def _flags(values: np.ndarray, test) -> np.ndarray:
    """``test(value)`` per element of an object array, evaluated once per distinct value."""
    out = np.zeros(len(values), bool)
    has = np.flatnonzero(values != None)  # noqa: E711 (elementwise)
    if len(has):
        cache: dict = {}
        out[has] = [cache[v] if v in cache else cache.setdefault(v, test(v)) for v in values[has].tolist()]
    return out


def streets_layer(ext: OsmExtract, *, major: frozenset[str], where: str | None = None) -> Layer:
    """The roads layer of an extract: one LineString per street segment between junctions.

    Parameters
    ----------
    ext : OsmExtract
        From :func:`read_osm`.
    major : frozenset of str
        ``highway`` values flagged ``major``.

    Returns
    -------
    Layer
        Columns ``class`` (the highway value), ``major``, ``width`` (m),
        ``osm_id`` (way id), ``name``, ``layer`` (int; bridges default 1,
        tunnels -1), ``bridge``, ``tunnel``, ``oneway`` (bool), ``u``, ``v``
        (junction indices into ``meta["nodes"]``); meta ``crs``, ``origin``
        (lat, lon), ``nodes`` ((k, 2) planar xy), ``node_keys`` (OSM
        fixed-point location of each node, packed in an int64) and, when
        read with ``node_ids``, ``node_ids`` (the OSM id of each node).
    """
    fixed, line = ext.fixed, ext.line
    if not len(fixed):
        return Layer.empty(**{"class": object, "major": bool, "width": float})
    if np.any(np.abs(fixed[:, 0]) > 1_800_000_000) or np.any(np.abs(fixed[:, 1]) > 900_000_000):
        raise InputDataError("coordinates outside [-180, 180] x [-90, 90]", where=where)
    key = (fixed[:, 0] + 1_800_000_000) * 2_000_000_000 + (fixed[:, 1] + 900_000_000)
    pieces = split_at_junctions(key, line)
    vnode, ukeys = pieces.node, pieces.node_key
    uidx = np.empty(len(ukeys), np.int64)  # the first entry of each node
    uidx[vnode[::-1]] = np.arange(len(vnode) - 1, -1, -1)
    # the frame from all points; each node (junctions are shared) projected once
    nodes, crs, origin = project_extract(fixed[pieces.vertex[uidx]] / 1e7,
                                         bounds=(fixed.min(axis=0) / 1e7, fixed.max(axis=0) / 1e7))
    geoms = shapely.linestrings(nodes[vnode], indices=pieces.piece)
    row = pieces.line
    names = np.array(list(ext.codes), dtype=object)
    code = ext.code
    is_major = np.isin(names, list(major)) if major else np.zeros(len(names), bool)
    widths = np.array([STREET_WIDTHS.get(c.removesuffix("_link"), _DEFAULT_WIDTH) for c in names])
    tags = ext.tags
    nway = len(code)
    col = {k: tags.get(k, np.full(nway, None, dtype=object)) for k in _TAG_KEYS}
    name = np.where(col["name"] == None, "", col["name"])  # noqa: E711 (elementwise)
    bridge = _flags(col["bridge"], lambda b: b != "no")
    tunnel = _flags(col["tunnel"], lambda b: b != "no")
    oneway = _flags(col["oneway"], lambda b: b in ("yes", "1", "true", "-1"))
    lay = np.where(bridge, 1, np.where(tunnel, -1, 0)).astype(np.int64)
    has = np.flatnonzero(col["layer"] != None)  # noqa: E711 (elementwise)
    if len(has):
        lay[has] = [_int_tag(v) for v in col["layer"][has].tolist()]
    meta_ids = {}
    if ext.node_ids is not None and len(ext.node_ids) == len(key):
        meta_ids = {"node_ids": ext.node_ids[pieces.vertex[uidx]]}
    brk = np.flatnonzero(np.r_[True, pieces.piece[1:] != pieces.piece[:-1]])
    u, v = vnode[brk], vnode[np.r_[brk[1:], len(vnode)] - 1]
    c = code[row]
    n = len(geoms)
    # the Layer directly: from_geoms would copy the 80k-element geometry array through a list
    return Layer(
        geoms, np.arange(n, dtype=np.int64), np.full(n, -1, np.int64),
        {
            "class": names[c],
            "major": is_major[c],
            "width": widths[c],
            "osm_id": ext.way_id[row],
            "name": name[row],
            "layer": lay[row],
            "bridge": bridge[row],
            "tunnel": tunnel[row],
            "oneway": oneway[row],
            "u": u,
            "v": v,
        },
        {"crs": crs, "origin": origin, "nodes": nodes, "node_keys": ukeys, "source": "osm", **meta_ids},
    )


def polygons_layer(ext: OsmExtract, kind: str, meta: dict, *, floor_height: float,
                   default_height: float) -> Layer:
    """Water, parks or buildings of an extract, projected into the streets' frame."""
    hexes, attrs = ext.polygons[kind]
    if not hexes or "crs" not in meta:
        return Layer.empty(meta=meta, kind=object)
    geoms = shapely.from_wkb(hexes)
    geoms = shapely.transform(geoms, from_lonlat(meta["crs"]))
    osm_id = np.array([a["osm_id"] for a in attrs], np.int64)
    names = np.array([a["name"] for a in attrs], dtype=object)
    if kind == "water":
        return Layer.from_geoms(geoms, meta=meta, kind="water", osm_id=osm_id, name=names)
    if kind == "parks":
        return Layer.from_geoms(geoms, meta=meta, level="district", kind="park", osm_id=osm_id, name=names)
    height = np.array([a["height"] for a in attrs], float)
    levels = np.array([a["levels"] for a in attrs], np.int64)
    source = np.where(np.isfinite(height), "height", np.where(levels > 0, "levels", "default"))
    height = np.where(np.isfinite(height), height, np.where(levels > 0, levels * floor_height, default_height))
    floors = np.where(levels > 0, levels, np.maximum(1, np.round(height / floor_height))).astype(np.int64)
    return Layer.from_geoms(geoms, meta=meta, height=height, floors=floors, roof="flat", lot=-1, district=-1,
                            osm_id=osm_id, name=names, height_source=source.astype(object))


@register
class OsmRead(SENode):
    """Read the street network (and optionally water, parks, buildings) of an OpenStreetMap file.

    The ``majorRoads`` node of the load-map network (skylineEngine 002 §5.3):
    highway ways become street segments between junctions, projected to the
    UTM zone of the data.  Classes in ``major`` are flagged major, those in
    ``minor`` are kept as minor roads, all others are ignored.
    """

    name = "osm.read"
    inputs = {}
    outputs = {
        "roads": Port("roads", "street segments between junctions, with their OSM class"),
        "water": Port("polygons", "water areas (natural=water, waterway=riverbank)"),
        "parks": Port("parks", "parks (leisure=park/garden)"),
        "buildings": Port("buildings", "existing buildings with height / building:levels"),
    }
    params = {
        "path": Param("path", "", doc="OSM file; empty: the plan's <map kind='osm'> src"),
        "major": Param("str", MAJOR_CLASSES, doc="comma list of highway values counted as major roads"),
        "minor": Param("str", MINOR_CLASSES, doc="comma list of highway values kept as minor roads; '*' all others; the rest is ignored"),
        "extras": Param("str", "water,parks,buildings", doc="comma list of extra layers to read: water, parks, buildings"),
        "node_ids": Param("bool", False, doc="keep the OSM id of every junction in meta['node_ids'] (slower)"),
        "floor_height": Param("float", 3.2, min=2.0, max=10.0, unit="m", doc="storey height for building:levels"),
        "default_height": Param("float", 10.0, min=0.0, max=500.0, unit="m", doc="height of buildings with no height tag"),
    }

    def _path(self) -> Path:
        if self.p.path:
            path = Path(self.p.path)
            if not path.is_absolute() and self.context.base_dir is not None:
                path = Path(self.context.base_dir) / path
            return path
        plan = self.context.plan
        spec = getattr(plan, "maps", {}).get("osm") if plan is not None else None
        if spec is None:
            raise InputDataError("no OSM file: set the 'path' parameter or add <map kind=\"osm\" src=\"...\"/>",
                                 where=self.where)
        return Path(spec.src)

    def run(self) -> dict[str, Layer]:
        path = self._path()
        where = getattr(getattr(self.context.plan, "maps", {}).get("osm"), "where", None) if not self.p.path else None
        where = where or self.where
        major, minor = _classes(self.p.major), _classes(self.p.minor)
        extras = _classes(self.p.extras)
        bad = extras - {"water", "parks", "buildings"}
        if bad:
            from sengine.errors import ParameterError

            raise ParameterError(f"extras={self.p.extras!r}: unknown layer {sorted(bad)[0]!r} "
                                 "(expected water, parks, buildings)", where=self.where)
        keep = None if "*" in minor else major | minor
        ext = read_osm(path, classes=keep, extras=extras, node_ids=self.p.node_ids, where=where)
        try:
            roads = streets_layer(ext, major=major, where=f"{where}: {path.name}")
        except InputDataError as exc:
            raise InputDataError(f"OSM file {str(path)!r}: {exc.message}", where=where) from None
        meta = dict(roads.meta)
        if not len(roads):
            log.warning("%s: OSM file %s holds no highway of the classes %s: the city is empty",
                        self.where, path, ",".join(sorted(keep)) if keep else "*")
            lonlat = [shapely.get_coordinates(shapely.from_wkb(h)) for h in ext.polygons["buildings"][0][:1]]
            if lonlat:
                _, crs, origin = project_extract(lonlat[0])
                meta = {"crs": crs, "origin": origin, "source": "osm"}
            roads = roads.with_meta(**meta)
        log.info("%s: %d highway ways -> %d street segments (%s)", path.name, len(ext.code), len(roads),
                 meta.get("crs", "no CRS"))
        small = {k: v for k, v in meta.items() if k not in ("nodes", "node_keys", "node_ids")}
        out = {"roads": roads}
        for kind in ("water", "parks", "buildings"):
            out[kind] = polygons_layer(ext, kind, small, floor_height=self.p.floor_height,
                                       default_height=self.p.default_height)
        self.report = {"ways": len(ext.code), "segments": len(roads), "clipped_ways": ext.clipped,
                       **{kind: len(out[kind]) for kind in ("water", "parks", "buildings")}}
        return out

"""OpenStreetMap import: the ``majorRoads`` node of the load-map network.

skylineEngine reads a real city "as a simple image map, or as an
OpenStreetMap file" (002 §5.2, Fig. 6); for a real city the major- and
minor-road modules "are collapsed into a single node that simply reads the
file and passes the resulting network to the next modules" (002 §5.3).  This
module is that node.

The file is streamed once with pyosmium (``.osm``, ``.osm.bz2``,
``.osm.pbf``): each ``highway=*`` way is turned into well-known binary by
libosmium's own geometry factory, so no Python object is made per node.  All
coordinates are then decoded, projected to the UTM zone of the data with one
vectorized pyproj call, and split into *street segments* between junctions
with numpy.  A junction is a point shared by two ways (or visited twice by
one way) or a way's end.  Point identity is the OSM location itself
(libosmium's 1e-7 degree fixed-point integers): two ways share a junction
exactly when they share a node, except for the data error of two distinct
nodes stacked on one spot, which this treats as the junction it was meant to
be.  The topology is kept: every segment carries the indices ``u`` / ``v`` of
its end points into ``meta["nodes"]`` (planar xy) and ``meta["node_keys"]``.

Water (``natural=water``, ``waterway=riverbank``, ``landuse=reservoir``),
parks (``leisure=park``/``garden``) and buildings (with ``height`` /
``building:levels``) of the same file are optional extra layers.

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
    """What :func:`read_osm` collects, still in WGS84 lon/lat.

    Attributes
    ----------
    hex_wkb : list of str
        One hex WKB LineString per kept highway way (every node, libosmium order).
    way_id, code : list of int
        Per kept way: OSM id and the code of its ``highway`` value in ``codes``.
    codes : dict of str to int
        ``highway`` value -> code.
    more : list of tuple
        For ways with more tags than ``highway``: (way index, name, layer,
        bridge, tunnel or covered, oneway) tag values (None when absent).
    refs : list of list of int
        OSM node ids of each kept way (only when asked for: it costs a
        Python object per node).
    polygons : dict of str to (list of str, list of dict)
        ``"water"``, ``"parks"``, ``"buildings"``: hex WKB multipolygons and their attributes.
    clipped : int
        Ways whose nodes are partly missing from the file (cut by the extract's bounding box).
    """

    hex_wkb: list = field(default_factory=list)
    way_id: list = field(default_factory=list)
    code: list = field(default_factory=list)
    codes: dict = field(default_factory=dict)
    more: list = field(default_factory=list)
    refs: list = field(default_factory=list)
    polygons: dict = field(default_factory=lambda: {k: ([], []) for k in ("water", "parks", "buildings")})
    clipped: int = 0


def read_osm(path: str | Path, *, classes: frozenset[str] | None = None, extras: frozenset[str] = frozenset(),
             node_ids: bool = False, where: str | None = None) -> OsmExtract:
    """Stream an OSM file and collect its highway ways (and optional areas).

    Parameters
    ----------
    path : str or Path
        ``.osm``, ``.osm.bz2``, ``.osm.gz`` or ``.osm.pbf``.
    classes : frozenset of str, optional
        ``highway`` values to keep; all when None.
    extras : frozenset of str
        Any of ``"water"``, ``"parks"``, ``"buildings"``: also assemble those
        areas (closed ways and multipolygon relations; costs a second pass).
    node_ids : bool
        Also keep the OSM node id of every way node (slower).
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
    import osmium

    path = Path(path)
    if not path.is_file():
        raise InputDataError(f"OSM file {str(path)!r} does not exist", where=where)
    out = OsmExtract()
    wkb = osmium.geom.WKBFactory()
    every = osmium.geom.ALL
    append_line = out.hex_wkb.append
    codes = out.codes
    append_id, append_code, append_more = out.way_id.append, out.code.append, out.more.append

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
            kept = _clipped_way(w, path, out, where)
            if kept is None:
                return
        except RuntimeError:  # libosmium geometry_error: a way of fewer than two nodes
            return
        append_id(w.id)
        append_code(code)
        if len(tags) > 1:  # most Liège-like street tables carry highway only
            append_more((len(out.code) - 1, tags.get("name", ""), tags.get("layer"), tags.get("bridge"),
                         tags.get("tunnel") or tags.get("covered"), tags.get("oneway")))
        if node_ids:
            out.refs.append(kept if kept is not None else [n.ref for n in w.nodes])

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

    handler = osmium.make_simple_handler(way=way, area=area) if extras else osmium.make_simple_handler(way=way)
    try:
        handler.apply_file(str(path), locations=True)
    except InputDataError:
        raise
    except (RuntimeError, ValueError, osmium.InvalidLocationError) as exc:
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputDataError(f"cannot read OSM file {str(path)!r}: {msg}", where=where) from None
    if out.clipped:
        log.info("%s: %d ways lose nodes outside the extract; kept their parts inside", path.name, out.clipped)
    return out


def _clipped_way(w, path, out, where) -> list[int] | None:
    """Slow path for a way with missing node locations: keep its longest run of located nodes.

    Returns the OSM ids of the kept nodes, or None when fewer than two are left.
    """
    runs, run = [], []
    for n in w.nodes:
        loc = n.location
        if loc.valid():
            run.append((loc.lon, loc.lat, n.ref))
            continue
        if loc.x != 2147483647 or loc.y != 2147483647:  # present, but outside the valid range
            raise InputDataError(
                f"OSM file {str(path)!r}: node {n.ref} has coordinates ({loc.x / 1e7}, {loc.y / 1e7}) "
                "outside [-180, 180] x [-90, 90]", where=where)
        runs.append(run)
        run = []
    runs.append(run)
    best = max(runs, key=len)
    out.clipped += 1
    if len(best) < 2:
        return None
    out.hex_wkb.append(shapely.to_wkb(shapely.linestrings([p[:2] for p in best]), hex=True))
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


def project_extract(xy_lonlat: np.ndarray) -> tuple[np.ndarray, str, tuple[float, float]]:
    """Project lon/lat points to the UTM zone of their bounding-box centre.

    Returns
    -------
    xy : ndarray (n, 2)
        Metres, in the UTM frame (false easting kept, so the EPSG code is exact).
    crs : str
        ``"EPSG:326zz"`` (north) or ``"EPSG:327zz"`` (south).
    origin : (lat, lon)
        The bounding-box centre (deg), the city's geographic origin.
    """
    lo, hi = xy_lonlat.min(axis=0), xy_lonlat.max(axis=0)
    lon, lat = (lo + hi) / 2.0
    crs = utm_crs(lat, lon)
    return from_lonlat(crs)(xy_lonlat), crs, (float(lat), float(lon))


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
    lonlat, line = decode_lines(ext.hex_wkb)
    if not len(lonlat):
        return Layer.empty(**{"class": object, "major": bool, "width": float})
    if np.any(np.abs(lonlat[:, 0]) > 180.0) or np.any(np.abs(lonlat[:, 1]) > 90.0):
        raise InputDataError("coordinates outside [-180, 180] x [-90, 90]", where=where)
    fixed = np.rint(lonlat * 1e7).astype(np.int64)
    key = (fixed[:, 0] + 1_800_000_000) * 2_000_000_000 + (fixed[:, 1] + 900_000_000)
    xy, crs, origin = project_extract(lonlat)
    pieces = split_at_junctions(key, line)
    geoms = shapely.linestrings(xy[pieces.vertex], indices=pieces.piece)
    row = pieces.line
    nway = len(ext.code)
    names = np.array(list(ext.codes), dtype=object)
    code = np.asarray(ext.code, np.int64)
    is_major = np.isin(names, list(major)) if major else np.zeros(len(names), bool)
    widths = np.array([STREET_WIDTHS.get(c.removesuffix("_link"), _DEFAULT_WIDTH) for c in names])
    name = np.full(nway, "", dtype=object)
    lay = np.zeros(nway, np.int64)
    bridge = np.zeros(nway, bool)
    tunnel = np.zeros(nway, bool)
    oneway = np.zeros(nway, bool)
    if ext.more:
        i, nm, ly, br, tu, ow = zip(*ext.more, strict=True)
        i = np.asarray(i, np.int64)
        name[i] = nm
        bridge[i] = [b not in (None, "no") for b in br]
        tunnel[i] = [b not in (None, "no") for b in tu]
        oneway[i] = [b in ("yes", "1", "true", "-1") for b in ow]
        lay[i] = [_int_tag(v) if v is not None else (1 if b else -1 if t else 0)
                  for v, b, t in zip(ly, bridge[i], tunnel[i], strict=True)]
    vkey = key[pieces.vertex]
    ukeys, uidx = np.unique(vkey, return_index=True)
    meta_ids = {}
    if ext.refs:
        refs = np.fromiter((r for way in ext.refs for r in way), np.int64)
        if len(refs) == len(key):
            meta_ids = {"node_ids": refs[pieces.vertex[uidx]]}
    nodes = xy[pieces.vertex[uidx]]
    ends = np.searchsorted(ukeys, np.r_[key[pieces.first], key[pieces.last]])
    u, v = ends[: len(row)], ends[len(row):]
    c = code[row]
    return Layer.from_geoms(
        geoms,
        meta={"crs": crs, "origin": origin, "nodes": nodes, "node_keys": ukeys, "source": "osm", **meta_ids},
        **{
            "class": names[c],
            "major": is_major[c],
            "width": widths[c],
            "osm_id": np.asarray(ext.way_id, dtype=np.int64)[row],
            "name": name[row],
            "layer": lay[row],
            "bridge": bridge[row],
            "tunnel": tunnel[row],
            "oneway": oneway[row],
            "u": u,
            "v": v,
        },
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

"""OpenStreetMap import: the ``majorRoads`` node of the load-map network.

skylineEngine reads a real city "as a simple image map, or as an
OpenStreetMap file" (002 §5.2, Fig. 6); for a real city the major- and
minor-road modules "are collapsed into a single node that simply reads the
file and passes the resulting network to the next modules" (002 §5.3).  This
module is that node.

The file (``.osm``, ``.osm.bz2``, ``.osm.pbf``) is streamed with pyosmium
(:mod:`.osm_stream`: each ``highway=*`` way turned into well-known binary by
libosmium's geometry factory and its tags into flat lists, the ways shared
between two processes on a two-core machine).  The points are then
projected to the UTM zone of the data with one vectorized pyproj call (each
junction once) and split into *street segments* between junctions with
numpy.  A junction is a point shared by two ways (or visited twice by one
way) or a way's end.  Point identity is the OSM location itself
(libosmium's 1e-7 degree fixed-point integers): two ways share a junction
exactly when they share a node, except for the data error of two distinct
nodes stacked on one spot, which this treats as the junction it was meant to
be.  The topology is kept: every segment carries the indices ``u`` / ``v`` of
its end points into ``meta["nodes"]`` (planar xy) and ``meta["node_keys"]``.

Water (``natural=water``, ``waterway=riverbank``, ``landuse=reservoir``),
parks (``leisure=park``/``garden``) and buildings (with ``height`` /
``building:levels``) of the same file are optional extra layers, assembled
by pyosmium in the same pass.  With the water comes the sea: the parts of
the data's box on the right of the ``natural=coastline`` ways (kind
``sea``).  The roads' ``meta["extent"]`` is the box of the streets and the
map's buildings, along which ``roads.clean`` can close the street graph.

References
----------
§5.2 "Input Module" and §5.3 "Major & Minor Roads Modules" of [1]_.

.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import shapely

from sengine import Layer, NodeResult, Param, Port, SENode, register
from sengine.errors import InputDataError
from sengine.geom.crs import from_lonlat, utm_crs
from sengine.geom.polygons import right_of_lines
from sengine.geom.segments import lines_from_groups

from ..maps import check_regular_file
from ..roads.junctions import split_at_junctions
from .stream import TAG_KEYS, OsmExtract, int_tag, read_osm

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
    "motorway,motorway_link,trunk,trunk_link,primary,primary_link,secondary,secondary_link,tertiary,tertiary_link"
)
#: ``highway`` values counted as minor roads by default; every other value is ignored.
MINOR_CLASSES = "unclassified,residential,living_street,pedestrian,road,busway"

#: Street width between block fronts (m) by class.  Anchored on the Prague
#: public-space minima (paper 003 §3.2): city avenue 24 m, important street
#: 18 m, local street 12 m, access street 8 m; paths 3 m.
STREET_WIDTHS = {
    "motorway": 24.0,
    "trunk": 24.0,
    "primary": 18.0,
    "secondary": 18.0,
    "tertiary": 15.0,
    "unclassified": 12.0,
    "residential": 12.0,
    "road": 12.0,
    "busway": 12.0,
    "living_street": 8.0,
    "pedestrian": 8.0,
    "service": 8.0,
    "track": 6.0,
}
_DEFAULT_WIDTH = 3.0  # footway, path, cycleway, steps ...


def _classes(text: str) -> frozenset[str]:
    return frozenset(c.strip() for c in str(text).split(",") if c.strip())


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
    if not len(pieces):  # every way collapsed to a point (all its nodes in one place)
        return Layer.empty(**{"class": object, "major": bool, "width": float})
    vnode, ukeys = pieces.node, pieces.node_key
    uidx = np.empty(len(ukeys), np.int64)  # the first entry of each node
    uidx[vnode[::-1]] = np.arange(len(vnode) - 1, -1, -1)
    # the frame from all points; each node (junctions are shared) projected once
    nodes, crs, origin = project_extract(
        fixed[pieces.vertex[uidx]] / 1e7, bounds=(fixed.min(axis=0) / 1e7, fixed.max(axis=0) / 1e7)
    )
    geoms = lines_from_groups(nodes[vnode], pieces.piece)
    row = pieces.line
    names = np.array(list(ext.codes), dtype=object)
    code = ext.code
    is_major = np.isin(names, list(major)) if major else np.zeros(len(names), bool)
    widths = np.array([STREET_WIDTHS.get(c.removesuffix("_link"), _DEFAULT_WIDTH) for c in names])
    tags = ext.tags
    nway = len(code)
    col = {k: tags.get(k, np.full(nway, None, dtype=object)) for k in TAG_KEYS}
    name = np.where(col["name"] == None, "", col["name"])  # noqa: E711 (elementwise)
    bridge = _flags(col["bridge"], lambda b: b != "no")
    tunnel = _flags(col["tunnel"], lambda b: b != "no")
    oneway = _flags(col["oneway"], lambda b: b in ("yes", "1", "true", "-1"))
    lay = np.where(bridge, 1, np.where(tunnel, -1, 0)).astype(np.int64)
    has = np.flatnonzero(col["layer"] != None)  # noqa: E711 (elementwise)
    if len(has):
        lay[has] = [int_tag(v) for v in col["layer"][has].tolist()]
    meta_ids = {}
    if ext.node_ids is not None and len(ext.node_ids) == len(key):
        meta_ids = {"node_ids": ext.node_ids[pieces.vertex[uidx]]}
    brk = np.flatnonzero(np.r_[True, pieces.piece[1:] != pieces.piece[:-1]])
    u, v = vnode[brk], vnode[np.r_[brk[1:], len(vnode)] - 1]
    c = code[row]
    n = len(geoms)
    # the Layer directly: its arrays are fresh, from_geoms would copy them again
    return Layer(
        geoms,
        np.arange(n, dtype=np.int64),
        np.full(n, -1, np.int64),
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


def polygons_layer(ext: OsmExtract, kind: str, meta: dict, *, floor_height: float, default_height: float) -> Layer:
    """Water, parks, buildings or land-use zones of an extract, projected into the streets' frame."""
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
    if kind == "landuse":
        use = np.array([a["use"] for a in attrs], dtype=object)
        return Layer.from_geoms(geoms, meta=meta, kind="landuse", use=use, osm_id=osm_id, name=names)
    height = np.array([a["height"] for a in attrs], float)
    levels = np.array([a["levels"] for a in attrs], np.int64)
    source = np.where(np.isfinite(height), "height", np.where(levels > 0, "levels", "default"))
    height = np.where(np.isfinite(height), height, np.where(levels > 0, levels * floor_height, default_height))
    floors = np.where(levels > 0, levels, np.maximum(1, np.round(height / floor_height))).astype(np.int64)
    return Layer.from_geoms(
        geoms,
        meta=meta,
        height=height,
        floors=floors,
        roof=np.array([a.get("roof", "flat") for a in attrs], dtype=object),
        roof_height=np.array([a.get("roof_height", np.nan) for a in attrs], float),
        lot=-1,
        district=-1,
        osm_id=osm_id,
        name=names,
        height_source=source.astype(object),
        use=np.array([a["use"] for a in attrs], dtype=object),
    )


def sea_layer(ext: OsmExtract, meta: dict) -> Layer:
    """The sea of an extract: the parts of its box on the right of the coastline ways, kind ``sea``.

    The box is that of the streets and the coastline together.  A
    coastline that is cut short inside the box closes no sea there.
    """
    if not ext.coastline or "crs" not in meta:
        return Layer.empty(meta=meta, kind=object)
    coast = shapely.transform(shapely.from_wkb(ext.coastline), from_lonlat(meta["crs"]))
    pts = [shapely.get_coordinates(coast)]
    if "nodes" in meta and len(meta["nodes"]):
        pts.append(meta["nodes"])
    xy = np.concatenate(pts)
    sea = right_of_lines(coast, (*xy.min(axis=0), *xy.max(axis=0)))
    small = {k: v for k, v in meta.items() if k not in ("nodes", "node_keys", "node_ids")}
    return Layer.from_geoms(sea, meta=small, kind="sea", osm_id=-1, name="")


@register
class OsmRead(SENode):
    """Read the street network (and optionally water, parks, buildings) of an OpenStreetMap file.

    The ``majorRoads`` node of the load-map network (skylineEngine 002 §5.3):
    highway ways become street segments between junctions, projected to the
    UTM zone of the data.  Classes in ``major`` are flagged major, those in
    ``minor`` are kept as minor roads, all others are ignored.
    """

    name = "osm.read"
    inputs = {"osm_map": Port("file", "the OSM file of the plan (<map kind='osm'>)", required=False)}
    outputs = {
        "roads": Port("roads", "street segments between junctions, with their OSM class"),
        "water": Port("polygons", "water areas (natural=water, waterway=riverbank)"),
        "parks": Port("parks", "parks (leisure=park/garden)"),
        "buildings": Port("buildings", "existing buildings with height / building:levels"),
        "landuse": Port(
            "polygons",
            "land-use zones (landuse=residential/commercial/retail/civil/industrial/education, schools) with 'use'",
        ),
    }
    params = {
        "path": Param("path", "", doc="OSM file; empty: the plan's <map kind='osm'> src"),
        "major": Param("str", MAJOR_CLASSES, doc="comma list of highway values counted as major roads"),
        "minor": Param(
            "str",
            MINOR_CLASSES,
            doc="comma list of highway values kept as minor roads; '*' all others; the rest is ignored",
        ),
        "extras": Param(
            "str", "water,parks,buildings", doc="comma list of extra layers to read: water, parks, buildings, landuse"
        ),
        "node_ids": Param("bool", False, doc="keep the OSM id of every junction in meta['node_ids'] (slower)"),
        "floor_height": Param("float", 3.2, min=2.0, max=10.0, unit="m", doc="storey height for building:levels"),
        "default_height": Param(
            "float", 10.0, min=0.0, max=500.0, unit="m", doc="height of buildings with no height tag"
        ),
    }

    def _path(self, osm_map: Layer | None) -> tuple[Path, str]:
        if self.p.path:
            path = Path(self.p.path)
            if not path.is_absolute() and self.context.base_dir is not None:
                path = Path(self.context.base_dir) / path
            return path, self.where
        if osm_map is None or not len(osm_map):
            raise InputDataError(
                'no OSM file: set the \'path\' parameter or add <map kind="osm" src="..."/>', where=self.where
            )
        return Path(str(osm_map["src"][0])), osm_map.meta.get("where") or self.where

    def run(self, *, osm_map: Layer | None = None):
        path, where = self._path(osm_map)
        check_regular_file(path, "OSM file", where)  # a FIFO or /dev/zero would block or fill the memory
        major, minor = _classes(self.p.major), _classes(self.p.minor)
        extras = _classes(self.p.extras)
        bad = extras - {"water", "parks", "buildings", "landuse"}
        if bad:
            from sengine.errors import ParameterError

            raise ParameterError(
                f"extras={self.p.extras!r}: unknown layer {sorted(bad)[0]!r} (expected water, parks, buildings, landuse)",
                where=self.where,
            )
        keep = None if "*" in minor else major | minor
        ext = read_osm(path, classes=keep, extras=extras, node_ids=self.p.node_ids, where=where)
        try:
            roads = streets_layer(ext, major=major, where=f"{where}: {path.name}")
        except InputDataError as exc:
            raise InputDataError(f"OSM file {str(path)!r}: {exc.message}", where=where) from None
        meta = dict(roads.meta)
        if not len(roads):
            log.warning(
                "%s: OSM file %s holds no highway of the classes %s: the city is empty of streets, "
                "blocks and lots (%d buildings of the map)",
                self.where,
                path,
                ",".join(sorted(keep)) if keep else "*",
                len(ext.polygons["buildings"][0]),
            )
            lonlat = [shapely.get_coordinates(shapely.from_wkb(h)) for h in ext.polygons["buildings"][0][:1]]
            if lonlat:
                _, crs, origin = project_extract(lonlat[0])
                meta = {"crs": crs, "origin": origin, "source": "osm"}
            roads = roads.with_meta(**meta)
        log.info(
            "%s: %d highway ways -> %d street segments (%s)",
            path.name,
            len(ext.code),
            len(roads),
            meta.get("crs", "no CRS"),
        )
        small = {k: v for k, v in meta.items() if k not in ("nodes", "node_keys", "node_ids")}
        out = {"roads": roads}
        kinds = ("water", "parks", "buildings", "landuse") if "landuse" in extras else ("water", "parks", "buildings")
        out["landuse"] = Layer.empty(meta=small)
        for kind in kinds:
            out[kind] = polygons_layer(
                ext, kind, small, floor_height=self.p.floor_height, default_height=self.p.default_height
            )
        if len(out["buildings"]) and "nodes" in meta and len(meta["nodes"]):
            # the data's extent: the streets and the map's buildings (a village's houses past its last street)
            bb = shapely.total_bounds(out["buildings"].geometry)
            lo, hi = np.minimum(meta["nodes"].min(axis=0), bb[:2]), np.maximum(meta["nodes"].max(axis=0), bb[2:])
            out["roads"] = roads.with_meta(extent=tuple(float(c) for c in np.r_[lo, hi]))
        sea = sea_layer(ext, meta)
        if len(sea):
            out["water"] = Layer.concat([out["water"], sea]) if len(out["water"]) else sea
        report = {
            "ways": len(ext.code),
            "segments": len(roads),
            "clipped_ways": ext.clipped,
            "sea": len(sea),
            **{kind: len(out[kind]) for kind in kinds},
        }
        return NodeResult(out, report)

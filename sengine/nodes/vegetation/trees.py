"""The node ``vegetation.trees``: every zone of Ulmer et al. §3.2 filled with trees, as one point layer.

Zones and what fills them:

* **avenue**: the street trees of :mod:`.avenue`, on the sidewalk of every
  block (and of every block-level park), both sides of each street, split at
  crossings; with ``avenue_min_width``, only along streets at least that wide;
* **district**, **block**, **lot** and **patio** parks (the ``level`` of each
  feature of the ``parks`` stream, :mod:`sengine.nodes.parks`):
  ``Distr(density, deviation)`` (:mod:`.distr`) with that level's density;
* **region**: vegetation regions (forests, big parks, fields) on the
  ``regions`` port, scattered, or laid out by the Versailles pattern
  (:mod:`.versailles`: grass sub-regions with tree-lined avenues whose spacing
  grows with the split depth).

Every tree keeps ``spacing`` m from every other and stands on no road (the
street surfaces, or the road centre lines' half width), in no water and in
no building (park trees keep ``clearance`` m off the walls).  Each gets a
plant by ``I(category, type, instance)`` (:mod:`.plants`) from its zone's
palette.  Columns: ``zone``, ``category``, ``type`` (age class),
``instance``, ``height`` and ``crown`` (m), ``form`` (broad / conifer),
``park`` (id of its park or region, -1 for avenue trees), ``district``.

Each tree's id is stable whatever the batch (:mod:`sengine.nodes.parks.ids`):
its zone's key (its park's id, its block's for an avenue tree, its
region's) times :data:`~sengine.nodes.parks.ids.TREE_SPAN` plus its rank in
the zone; the layer is in id order.

References
----------
.. [1] A. Ulmer, J. Halatsch, A. Kunze, P. Müller and L. Van Gool, "Procedural design
   of urban open spaces", Proceedings of the 25th eCAADe Conference, Frankfurt am
   Main, pp. 351-358, 2007 (paper 001 in shared/papers).
"""

from __future__ import annotations

import logging
import time

import numpy as np
import shapely

from sengine import Layer, NodeResult, Param, Port, SENode, register
from sengine.errors import NodeError
from sengine.random import mix64, stable_hash

from ..parks.ids import TREE_KINDS, avenue_value, tree_ids
from .avenue import avenue_points, on_wide_streets, tree_lines
from .distr import distr, far_from
from .plants import choose_plants, parse_palette
from .versailles import versailles_split

__all__ = ["ZONES", "place_trees", "VegetationTrees"]

log = logging.getLogger(__name__)

#: The zones a tree can belong to.
ZONES = ("avenue", "district", "block", "lot", "patio", "region")
_ZONE_KEY = {z: np.uint64(stable_hash(f"zone/{z}")) for z in ZONES}


class _Areas:
    """Which points lie in (or on) some of a set of polygons: bounding boxes, then point-in-polygon.

    The polygons are prepared.  A bounding-box query hands a point every
    polygon whose box holds it, and a city's street or sidewalk polygon can
    have 40,000 vertices and a box over the whole city, so the polygons
    longer than ``big`` m across are kept apart: for points known to lie on
    lines (avenue trees on their block's tree line), a big polygon is tested
    only for the points of the lines it meets (an exact filter: a point of a
    line in a polygon makes the line meet it), one line-polygon predicate per
    line instead of a point-in-polygon test per point.
    """

    def __init__(self, geoms, big: float = 1000.0):
        geoms = np.asarray(geoms, dtype=object)
        shapely.prepare(geoms)
        b = shapely.bounds(geoms)
        large = np.hypot(b[:, 2] - b[:, 0], b[:, 3] - b[:, 1]) > big
        self.all = (shapely.STRtree(geoms), geoms)
        self.small = (shapely.STRtree(geoms[~large]), geoms[~large])
        self.large = (shapely.STRtree(geoms[large]), geoms[large])

    def covers(self, x: np.ndarray, y: np.ndarray, pts=None, along=None) -> np.ndarray:
        """Bool per point; ``along = (lines, line_of)``: each point lies on ``lines[line_of[i]]``."""
        out = np.zeros(len(x), bool)
        if not len(x):
            return out
        tree, polys = self.all if along is None else self.small
        pi, qi = tree.query(shapely.points(x, y) if pts is None else pts)
        if len(pi):
            out[pi[shapely.intersects_xy(polys[qi], x[pi], y[pi])]] = True
        tree, polys = self.large
        if along is not None and len(polys):
            lines, line_of = along
            li, qi = tree.query(lines)  # boxes, then the predicate on the prepared polygons
            meet = shapely.intersects(polys[qi], lines[li])
            li, qi = li[meet], qi[meet]
            order = np.argsort(li, kind="stable")
            li, qi = li[order], qi[order]
            start = np.searchsorted(li, np.arange(len(lines)))
            cnt = np.bincount(li, minlength=len(lines))[line_of]
            pi = np.repeat(np.arange(len(x)), cnt)
            qi = qi[np.repeat(start[line_of] - np.cumsum(cnt) + cnt, cnt) + np.arange(len(pi))]
            out[pi[shapely.intersects_xy(polys[qi], x[pi], y[pi])]] = True
        return out


def _obstacle_test(buildings, water, streets, roads, road_width, clearance: float):
    """``accept(x, y, clear, along=None)``: points on no street, in no water, ``clear`` m off every building.

    Big polygons (street surfaces, rivers) are tested point-in-polygon on
    prepared geometry after a bounding-box query (:class:`_Areas`): far
    faster than a predicate query, which prepares the points instead.
    ``along = (lines, line_of)`` says the points lie on those lines;
    ``pts`` are the points if made already.
    """
    areas = [_Areas(g) for g in (water, streets) if g is not None and len(g)]
    b_tree = shapely.STRtree(buildings) if buildings is not None and len(buildings) else None
    r_tree = shapely.STRtree(roads) if roads is not None and len(roads) else None
    half = np.asarray(road_width, np.float64) / 2 if r_tree is not None else None

    def accept(x, y, clear=clearance, along=None, pts=None):
        ok = np.ones(len(x), bool)
        if pts is None and areas:
            pts = shapely.points(x, y)
        for a in areas:
            ok &= ~a.covers(x, y, pts, along)
        if b_tree is not None and ok.any():
            idx = np.flatnonzero(ok)
            pts = shapely.points(x[idx], y[idx])
            if clear > 0:
                hit, _ = b_tree.query(pts, predicate="dwithin", distance=clear)
            else:
                hit, _ = b_tree.query(pts, predicate="intersects")
            ok[idx[hit]] = False
        if r_tree is not None and len(half) and ok.any():
            idx = np.flatnonzero(ok)
            pts = shapely.points(x[idx], y[idx])
            pi, ri = r_tree.query(pts, predicate="dwithin", distance=float(half.max()))
            near = shapely.distance(pts[pi], roads[ri]) < half[ri]
            ok[idx[pi[near]]] = False
        return ok

    return accept


def place_trees(
    *,
    seed: int,
    blocks=None,
    block_ids=None,
    parks=None,
    park_ids=None,
    park_level=None,
    regions=None,
    region_ids=None,
    sidewalks=None,
    streets=None,
    roads=None,
    road_width=None,
    buildings=None,
    water=None,
    density: dict | None = None,
    deviation: float = 0.0,
    spacing: float = 4.0,
    avenue_spacing: float = 10.0,
    avenue_offset: float = 1.5,
    avenue_clear: float = 8.0,
    avenue_min_width: float = 0.0,
    avenue_roads=None,
    corner: float = 35.0,
    clearance: float = 2.0,
    region_pattern: str = "scatter",
    versailles_depth: int = 3,
) -> dict[str, np.ndarray]:
    """Trees of every zone, as columns (``x``, ``y``, ``zone``, ``zone_row``, ``key``, ``geometry``: points).

    ``density`` maps a zone (district, block, lot, patio, region) to trees per
    m2.  ``avenue_roads`` (centre lines, widths) say which streets are at
    least ``avenue_min_width`` m wide (0: every street gets its trees).
    ``zone_row`` is the row of the tree's park, region or (avenue) block;
    ``key`` a uint64 per tree for its plant.  See the module notes for the rest.
    """
    density = density or {}
    accept = _obstacle_test(buildings, water, streets, roads, road_width, clearance)
    xs, zs, rows, keys, made = [], [], [], [], []
    seed = np.uint64(seed & 0xFFFFFFFFFFFFFFFF)
    # avenue trees: along the blocks (and block-level parks), kept on the sidewalks
    if avenue_spacing > 0 and blocks is not None and len(blocks):
        lines, row = tree_lines(blocks, avenue_offset)
        xy, li, _ = avenue_points(lines, spacing=avenue_spacing, clear=avenue_clear, corner=corner)
        row = row[li]
        pts = shapely.points(xy[:, 0], xy[:, 1])
        ok = accept(xy[:, 0], xy[:, 1], 0.0, along=(lines, li), pts=pts) if len(xy) else np.zeros(0, bool)
        if sidewalks is not None and len(sidewalks) and len(xy):
            ok &= _Areas(sidewalks).covers(xy[:, 0], xy[:, 1], pts, along=(lines, li))
        if avenue_min_width > 0 and len(xy):
            ok &= on_wide_streets(pts, *avenue_roads, avenue_min_width)
        rank = np.arange(len(li)) - np.searchsorted(li, li)
        k = mix64(mix64(seed ^ _ZONE_KEY["avenue"], np.asarray(block_ids, np.int64)[row].astype(np.uint64)), rank)
        xs.append(xy[ok])
        made.append(pts[ok])
        zs.append(np.full(int(ok.sum()), "avenue"))
        rows.append(row[ok])
        keys.append(k[ok])
    fixed = np.concatenate(xs) if xs else np.empty((0, 2))
    # vegetation regions: scattered, or Versailles (grass parts with avenue trees along their edges)
    zone_geoms, zone_kind, zone_row, zone_id = [], [], [], []
    if regions is not None and len(regions):
        if region_pattern == "versailles":
            parts, owner, _, _, _ = versailles_split(regions, depth=versailles_depth)
            lines = shapely.get_exterior_ring(parts)
            xy, li, _ = avenue_points(lines, spacing=avenue_spacing, clear=avenue_clear, corner=corner)
            ok = accept(xy[:, 0], xy[:, 1]) & far_from(xy, fixed, spacing) if len(xy) else np.zeros(0, bool)
            rank = np.arange(len(li)) - np.searchsorted(li, li)
            k = mix64(mix64(seed ^ _ZONE_KEY["region"], li.astype(np.uint64)), rank)
            xs.append(xy[ok])
            zs.append(np.full(int(ok.sum()), "region"))
            rows.append(owner[li[ok]])
            keys.append(k[ok])
            fixed = np.concatenate(xs)
        else:
            zone_geoms.append(np.asarray(regions, dtype=object))
            zone_kind.append(np.full(len(regions), "region"))
            zone_row.append(np.arange(len(regions)))
            zone_id.append(np.asarray(region_ids, np.int64))
    if parks is not None and len(parks):
        level = np.asarray(park_level).astype(str)
        zone_geoms.append(np.asarray(parks, dtype=object))
        zone_kind.append(level)
        zone_row.append(np.arange(len(parks)))
        zone_id.append(np.asarray(park_ids, np.int64))
    if zone_geoms:
        g = np.concatenate(zone_geoms)
        kind = np.concatenate(zone_kind)
        zrow = np.concatenate(zone_row)
        zid = np.concatenate(zone_id)
        dens = np.array([float(density.get(z, 0.0)) for z in kind])
        live = (dens > 0) & ~shapely.is_empty(g)
        kk = np.array([_ZONE_KEY.get(z, np.uint64(7)) for z in kind], np.uint64)
        zkey = mix64(kk, zid.astype(np.uint64))
        xy, ri, _ = distr(
            g[live],
            zkey[live].astype(np.int64),
            dens[live],
            deviation,
            seed=int(seed),
            spacing=spacing,
            fixed=fixed,
            accept=accept,
        )
        live_rows = np.flatnonzero(live)[ri]
        rank = np.arange(len(ri)) - np.searchsorted(ri, ri)
        xs.append(xy)
        zs.append(kind[live_rows])
        rows.append(zrow[live_rows])
        keys.append(mix64(seed ^ zkey[live_rows], rank.astype(np.uint64)))
    if not xs:
        return {
            "x": np.empty(0),
            "y": np.empty(0),
            "zone": np.empty(0, "<U8"),
            "zone_row": np.empty(0, np.int64),
            "key": np.empty(0, np.uint64),
            "geometry": np.empty(0, object),
        }
    xy = np.concatenate(xs)
    return {
        "x": xy[:, 0],
        "y": xy[:, 1],
        "zone": np.concatenate(zs).astype("<U8"),
        "zone_row": np.concatenate(rows).astype(np.int64),
        "key": np.concatenate(keys).astype(np.uint64),
        # the avenue trees' points were made for their tests already
        "geometry": np.concatenate([*made, shapely.points(xy[sum(len(m) for m in made) :])]),
    }


@register
class VegetationTrees(SENode):
    """Trees in every open-space zone: avenues, parks of every level, patios, vegetation regions (001 §3.2)."""

    name = "vegetation.trees"
    inputs = {
        "blocks": Port("blocks", "blocks: their sidewalks get the avenue trees", required=False),
        "parks": Port("parks", "parks of every level (column level)", required=False),
        "regions": Port("polygons", "vegetation regions: forests, big parks, fields", required=False),
        "sidewalks": Port("polygons", "sidewalks: avenue trees stand on them", required=False),
        "streets": Port("polygons", "street surfaces: no tree on them", required=False),
        "roads": Port("roads", "street centre lines: no tree within half their width", required=False),
        "buildings": Port("buildings", "buildings: no tree in them", required=False),
        "water": Port("polygons", "water: no tree in it", required=False),
    }
    outputs = {"vegetation": Port("vegetation", "one point per tree: zone, category, type, instance, height ...")}
    shard_streams = ("parks", "regions")
    #: How far (m) a tree may look beyond its enclosure (spacing, clearance) in a sharded run: below half
    #: the narrowest major road between enclosures (16 m in the demos), trees of two enclosures never meet.
    SHARD_REACH = 8.0
    params = {
        "spacing": Param("float", 4.0, min=0.0, max=100.0, unit="m", doc="least distance between two trees"),
        "avenue_spacing": Param(
            "float", 10.0, min=0.0, max=200.0, unit="m", doc="distance between street trees (0: no avenue trees)"
        ),
        "avenue_offset": Param(
            "float", 1.5, min=0.0, max=20.0, unit="m", doc="street trees' distance from the block edge, on the sidewalk"
        ),
        "avenue_clear": Param(
            "float", 8.0, min=0.0, max=100.0, unit="m", doc="no street tree this close to a crossing"
        ),
        "avenue_min_width": Param(
            "float",
            0.0,
            min=0.0,
            max=200.0,
            unit="m",
            doc="only streets at least this wide (kerb to kerb, the roads port) are avenues; 0: every street",
        ),
        "corner": Param(
            "float", 35.0, min=1.0, max=179.0, unit="deg", doc="a sharper turn of the street is a crossing"
        ),
        "district_density": Param("float", 0.005, min=0.0, max=1.0, unit="1/m2", doc="trees per m2 in district parks"),
        "block_density": Param("float", 0.006, min=0.0, max=1.0, unit="1/m2", doc="trees per m2 in block parks"),
        "lot_density": Param("float", 0.008, min=0.0, max=1.0, unit="1/m2", doc="trees per m2 in lot parks"),
        "patio_density": Param("float", 0.004, min=0.0, max=1.0, unit="1/m2", doc="trees per m2 in patios"),
        "region_density": Param("float", 0.03, min=0.0, max=1.0, unit="1/m2", doc="trees per m2 in regions"),
        "deviation": Param(
            "float", 0.0, min=0.0, max=10000.0, unit="m", doc="Distr deviation: 0 homogeneous, else Gaussian sigma"
        ),
        "clearance": Param("float", 2.0, min=0.0, max=50.0, unit="m", doc="park trees keep this far from walls"),
        "avenue_plants": Param("str", "plane,lime", doc="categories of street trees (I(category, type, instance))"),
        "park_plants": Param("str", "oak,lime,plane,maple,birch,pine", doc="categories of park trees"),
        "patio_plants": Param("str", "birch,cherry,maple", doc="categories of patio trees"),
        "region_plants": Param("str", "pine,spruce,birch,oak", doc="categories of trees in vegetation regions"),
        "instances": Param("int", 7, min=1, max=1000, unit="1", doc="appearances per category and age (rand(n))"),
        "region_pattern": Param(
            "str", "scatter", choices=("scatter", "versailles"), doc="how regions are filled (Versailles: 001 §4.1)"
        ),
        "versailles_depth": Param("int", 3, min=0, max=8, unit="1", doc="Versailles recursive splits"),
    }

    def shard_refusal(self, connected):
        if "regions" in connected:
            return "vegetation regions are not numbered by enclosure (connect them only to an unsharded run)"
        reach = max(self.p.spacing, self.p.clearance)
        if reach > self.SHARD_REACH:
            return (
                f"spacing / clearance {reach:g} m reach past the major road between two enclosures "
                f"(at most {self.SHARD_REACH:g} m)"
            )
        return None

    def run(
        self,
        *,
        blocks: Layer | None = None,
        parks: Layer | None = None,
        regions: Layer | None = None,
        sidewalks: Layer | None = None,
        streets: Layer | None = None,
        roads: Layer | None = None,
        buildings: Layer | None = None,
        water: Layer | None = None,
    ):
        t = time.perf_counter()
        p = self.p
        palettes = {
            z: parse_palette(getattr(p, f"{name}_plants"), f"{self.where} param '{name}_plants'")
            for z, name in (
                ("avenue", "avenue"),
                ("district", "park"),
                ("block", "park"),
                ("lot", "park"),
                ("patio", "patio"),
                ("region", "region"),
            )
        }
        edge = blocks
        if parks is not None and len(parks) and "level" in parks:  # block parks keep their street trees
            bp = parks.take(np.asarray(parks["level"]).astype(str) == "block")
            edge = Layer.concat([blocks, bp], renumber=False) if blocks is not None else bp
        geoms = lambda lay: None if lay is None or not len(lay) else lay.geometry  # noqa: E731
        road_lines = roads.geometry if roads is not None and len(roads) else None
        width = None if roads is None or "width" not in roads else np.nan_to_num(np.asarray(roads["width"], float))
        avenue_roads = None
        if p.avenue_min_width > 0:
            if road_lines is None or width is None:
                raise NodeError(
                    "param 'avenue_min_width' needs the street centre lines and their width on the roads port",
                    where=self.where,
                )
            avenue_roads = (road_lines, width)
        if streets is not None:
            # the street surfaces say where the road is (in a shard with none, still none: not the lines)
            road_lines = None
        trees = place_trees(
            seed=stable_hash(f"{self.context.seed}:{self.id}"),
            blocks=geoms(edge),
            block_ids=None if edge is None else edge.ids,
            parks=geoms(parks),
            park_ids=None if parks is None else parks.ids,
            park_level=None if parks is None or "level" not in parks else parks["level"],
            regions=geoms(regions),
            region_ids=None if regions is None else regions.ids,
            sidewalks=geoms(sidewalks),
            streets=geoms(streets),
            roads=road_lines,
            road_width=width,
            buildings=geoms(buildings),
            water=geoms(water),
            density={
                "district": p.district_density,
                "block": p.block_density,
                "lot": p.lot_density,
                "patio": p.patio_density,
                "region": p.region_density,
            },
            deviation=p.deviation,
            spacing=p.spacing,
            avenue_spacing=p.avenue_spacing,
            avenue_offset=p.avenue_offset,
            avenue_clear=p.avenue_clear,
            avenue_min_width=p.avenue_min_width,
            avenue_roads=avenue_roads,
            corner=p.corner,
            clearance=p.clearance,
            region_pattern=p.region_pattern,
            versailles_depth=p.versailles_depth,
        )
        zone = trees["zone"]
        n = len(zone)
        cols = {k: np.empty(n, dtype=object) for k in ("category", "type", "form")}
        cols.update(instance=np.zeros(n, np.int64), height=np.zeros(n), crown=np.zeros(n))
        for z in ZONES:
            sel = zone == z
            if sel.any():
                got = choose_plants(trees["key"][sel], palettes[z], instances=p.instances)
                for k in cols:
                    cols[k][sel] = got[k]
        park = np.full(n, -1, np.int64)
        district = np.full(n, -1, np.int64)
        inpark = np.isin(zone, ("district", "block", "lot", "patio"))
        if parks is not None and len(parks) and inpark.any():
            park[inpark] = parks.ids[trees["zone_row"][inpark]]
            if "district" in parks:
                district[inpark] = np.asarray(parks["district"], np.int64)[trees["zone_row"][inpark]]
        reg = zone == "region"
        if regions is not None and reg.any():
            park[reg] = regions.ids[trees["zone_row"][reg]]
        ave = zone == "avenue"
        if edge is not None and ave.any() and "district" in edge:
            district[ave] = np.asarray(edge["district"], np.int64)[trees["zone_row"][ave]]
        # stable ids: the zone's key (park, block, region) x TREE_SPAN + rank in the zone
        kind = np.full(n, TREE_KINDS.index("park"), np.int64)
        value = park.copy()
        kind[ave] = TREE_KINDS.index("avenue")
        if ave.any():
            n_blocks = 0 if blocks is None else len(blocks)
            row = trees["zone_row"][ave]
            from_block = row < n_blocks
            value[ave] = np.where(
                from_block,
                avenue_value(blocks.ids[np.minimum(row, n_blocks - 1)]) if n_blocks else 0,
                edge.ids[row],
            )
        kind[reg] = TREE_KINDS.index("region")
        ids = tree_ids(value, kind, where=self.where)
        order = np.argsort(ids, kind="stable")
        meta = next((dict(lay.meta) for lay in (blocks, parks, regions, roads) if lay is not None), {})
        zone, park, district = zone[order], park[order], district[order]
        cols = {k: v[order] for k, v in cols.items()}
        out = Layer.from_geoms(
            trees["geometry"][order],
            ids=ids[order],
            meta=meta,
            zone=zone.astype(object),
            category=cols["category"],
            type=cols["type"],
            instance=cols["instance"],
            height=cols["height"],
            crown=cols["crown"],
            form=cols["form"],
            park=park,
            district=district,
        )
        dt = time.perf_counter() - t
        counts = {z: int((zone == z).sum()) for z in ZONES}
        report = {"trees": n, **{f"{z}_trees": c for z, c in counts.items() if c}}
        log.info(
            "%s: %d trees in %.2f s (%s)", self.where, n, dt, ", ".join(f"{z} {c}" for z, c in counts.items() if c)
        )
        return NodeResult({"vegetation": out}, report)

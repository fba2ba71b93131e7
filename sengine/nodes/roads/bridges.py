"""Bridges: a major road of the pattern carried across the water it was cut by.

``roads.districts`` clips every district's pattern to the buildable land
(paper 002 Fig. 7: ``Clip(currMap, landUseMap)``), so a river cuts each
major road in two at its banks.  Here each major road that ends on the
water is continued straight on: the ray from its end along its last
segment crosses the water; where it reaches the far bank within
``max_span`` m and there is land beyond, a bridge is possible, ending on
the nearest road end of the far bank within ``snap`` m (so two halves of a
grid avenue join) or where the ray lands.  Of the possible bridges of each
water body the shortest are built first, none within ``min_gap`` m of
another, at most ``crossings`` of them.

The bridges join the roads as rows tagged ``bridge`` (``true``: OSM's
``bridge=yes``) of their road's class and width; every road gets the
column.  Both ends of a bridge are nodes of the street graph, so traffic
can cross: the near end is the end of the road it continues, and the far
end is a road end of the far bank or a point of a bank road, which is split
there in two rows (a possible bridge whose far end reaches no road within
``snap`` m is not built).  They are not part of the street graph the blocks are traced from
(a bridge and the banks would enclose the river as a block), as for a real
map's bridges in ``roads.clean``.  The ``bridges`` output holds each deck
as a polygon (the road's width, flat ends) with its ``span`` and
``thickness``: ``export.city`` draws it as a slab over the water in
``city.glb``.

References
----------
.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers), §5.3.1 and Fig. 7.
"""

from __future__ import annotations

import logging

import numpy as np
import shapely

from sengine import Layer, NodeResult, Param, Port, SENode, register

__all__ = ["bridge_candidates", "choose_bridges", "split_lines_at", "RoadsBridges"]

log = logging.getLogger(__name__)


def bridge_candidates(roads, major, water, *, max_span: float = 250.0, snap: float = 30.0, tol: float = 0.5):
    """Every bridge a major road ending on the water could make.

    Parameters
    ----------
    roads : array of shapely.LineString
        Street centre lines (m).
    major : array of bool
        Which roads may be carried across.
    water : array of shapely.Polygon
        Water bodies (m).
    max_span : float
        Longest bridge (m).
    snap : float
        A far end this close to a road end on the far bank ends there (m).
    tol : float
        A road end this close to the water ends on it (m).

    Returns
    -------
    dict of numpy.ndarray
        ``road`` (row), ``water`` (row), ``start`` and ``end`` (n, 2), ``span`` (m), ``onto``: the
        row of the road whose inside the far end lies on (to be split there), -1 when it is a road end.
    """
    roads = np.asarray(roads, dtype=object)
    water = np.asarray(water, dtype=object)
    none = {
        "road": np.empty(0, np.int64),
        "water": np.empty(0, np.int64),
        "start": np.empty((0, 2)),
        "end": np.empty((0, 2)),
        "span": np.empty(0),
        "onto": np.empty(0, np.int64),
    }
    if len(roads) == 0 or len(water) == 0:
        return none
    n0 = shapely.get_num_points(roads)
    first = shapely.get_coordinates(shapely.get_point(roads, 0))
    second = shapely.get_coordinates(shapely.get_point(roads, 1))
    last = shapely.get_coordinates(shapely.get_point(roads, n0 - 1))
    before = shapely.get_coordinates(shapely.get_point(roads, n0 - 2))
    ends = np.concatenate([first, last])
    prev = np.concatenate([second, before])
    road = np.concatenate([np.arange(len(roads))] * 2)
    sel = np.asarray(major, bool)[road]
    ends, prev, road = ends[sel], prev[sel], road[sel]
    tree = shapely.STRtree(water)
    pi, wi = tree.query(shapely.points(ends), predicate="dwithin", distance=tol)
    if len(pi) == 0:
        return none
    p, q, road = ends[pi], prev[pi], road[pi]
    d = p - q
    d /= np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-12)[:, None]
    ray = shapely.linestrings(np.stack([p - d * tol * 2, p + d * max_span], axis=1))
    wet = shapely.intersection(ray, water[wi])
    pieces, which = shapely.get_parts(wet, return_index=True)
    lines = shapely.get_type_id(pieces) == 1
    pieces, which = pieces[lines], which[lines]
    # the piece starting at the road end: the crossing
    at = shapely.distance(pieces, shapely.points(p[which])) < tol * 3
    pieces, which = pieces[at], which[at]
    a = shapely.get_coordinates(shapely.get_point(pieces, 0))
    b = shapely.get_coordinates(shapely.get_point(pieces, -1))
    far = np.where(
        (np.einsum("ij,ij->i", b - p[which], d[which]) >= np.einsum("ij,ij->i", a - p[which], d[which]))[:, None], b, a
    )
    span = np.hypot(*(far - p[which]).T)
    # the ray must leave the water before its end, onto land (not out of the water body's reach)
    beyond = shapely.points(far + d[which] * 2.0)
    out = (span < max_span - 1.0) & ~shapely.intersects(beyond, water[wi[which]])
    which, far, span = which[out], far[out], span[out]
    # snap the far end onto the nearest road end of the far bank (snap 0: only a road end or road right there;
    # STRtree.query_nearest refuses a max_distance of 0)
    reach = max(float(snap), 1e-6)
    if len(which):
        ends_all = np.concatenate([first, last])
        (src, tgt), _ = shapely.STRtree(shapely.points(ends_all)).query_nearest(
            shapely.points(far), max_distance=reach, return_distance=True
        )
        snapped = far.copy()
        firsts = np.r_[True, src[1:] != src[:-1]] if len(src) else np.zeros(0, bool)  # one end per bridge
        snapped[src[firsts]] = ends_all[tgt[firsts]]
        at_end = np.zeros(len(far), bool)
        at_end[src[firsts]] = True
        # otherwise onto the nearest point of a road of the far bank: the bridge is noded into it there
        onto = np.full(len(far), -1, np.int64)
        loose = np.flatnonzero(~at_end)
        if len(loose):
            (li, ri), _ = shapely.STRtree(roads).query_nearest(
                shapely.points(far[loose]), max_distance=reach, return_distance=True
            )
            one = np.r_[True, li[1:] != li[:-1]] if len(li) else np.zeros(0, bool)
            li, ri = li[one], ri[one]
            s_on = shapely.line_locate_point(roads[ri], shapely.points(far[loose[li]]))
            snapped[loose[li]] = shapely.get_coordinates(shapely.line_interpolate_point(roads[ri], s_on))
            onto[loose[li]] = ri
        far = snapped
        span = np.hypot(*(far - p[which]).T)
        keep = (span <= max_span) & (at_end | (onto >= 0))
        which, far, span, onto = which[keep], far[keep], span[keep], onto[keep]
    else:
        onto = np.empty(0, np.int64)
    return {"road": road[which], "water": wi[which], "start": p[which], "end": far, "span": span, "onto": onto}


def split_lines_at(lines, rows, points, tol: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """Split ``lines[rows[k]]`` at ``points[k]`` (points on the lines): a plane graph noded at the points.

    Parameters
    ----------
    lines : array of shapely.LineString
        The lines (m).
    rows : array of int
        Which line each point splits (a line may be split at several).
    points : numpy.ndarray, shape (k, 2)
        Points on those lines (m); one at a line's end or within ``tol`` m of
        an existing cut splits nothing.
    tol : float
        Pieces shorter than this are not made (m).

    Returns
    -------
    geoms : numpy.ndarray of shapely.LineString
        Every line, those split replaced in place by their pieces in order along the line.
    src : numpy.ndarray of int
        Row of each piece's line in ``lines``.
    """
    lines = np.asarray(lines, dtype=object)
    rows = np.asarray(rows, np.int64)
    points = np.asarray(points, np.float64).reshape(-1, 2)
    pieces: list[np.ndarray] = []
    src: list[np.ndarray] = []
    done = 0
    for r in np.unique(rows).tolist():  # the few lines a bridge lands on
        pieces.append(lines[done:r])
        src.append(np.arange(done, r))
        xy = shapely.get_coordinates(lines[r])
        seg = np.hypot(*np.diff(xy, axis=0).T)
        cum = np.r_[0.0, np.cumsum(seg)]
        pts = points[rows == r]
        at = shapely.line_locate_point(lines[r], shapely.points(pts))
        order = np.argsort(at, kind="stable")
        at, pts = at[order], pts[order]
        keep = (at > tol) & (at < cum[-1] - tol)
        at, pts = at[keep], pts[keep]
        keep = np.r_[True, np.diff(at) > tol] if len(at) else np.zeros(0, bool)
        at, pts = at[keep], pts[keep]
        # the pieces end exactly on the given points: the new node is the point itself
        cuts = np.r_[0.0, at, cum[-1]]
        ends = np.concatenate([xy[:1], pts, xy[-1:]])
        parts = []
        for k in range(len(cuts) - 1):
            inner = (cum > cuts[k] + tol) & (cum < cuts[k + 1] - tol)
            parts.append(shapely.linestrings(np.concatenate([ends[k : k + 1], xy[inner], ends[k + 1 : k + 2]])))
        pieces.append(np.array(parts, dtype=object))
        src.append(np.full(len(parts), r))
        done = r + 1
    pieces.append(lines[done:])
    src.append(np.arange(done, len(lines)))
    return np.concatenate(pieces), np.concatenate(src).astype(np.int64)


def choose_bridges(cand: dict, *, crossings: int = 3, min_gap: float = 300.0) -> np.ndarray:
    """Rows of ``cand`` to build: per water body the shortest first, ``min_gap`` m apart, at most ``crossings``."""
    n = len(cand["span"])
    if n == 0 or crossings <= 0:
        return np.empty(0, np.int64)
    mid = (cand["start"] + cand["end"]) / 2
    order = np.lexsort((cand["road"], cand["span"], cand["water"]))
    chosen: list[int] = []
    count: dict[int, int] = {}
    for i in order.tolist():  # a few candidates per river: a short greedy loop
        w = int(cand["water"][i])
        if count.get(w, 0) >= crossings:
            continue
        if chosen and np.min(np.hypot(*(mid[chosen] - mid[i]).T)) < min_gap:
            continue
        chosen.append(i)
        count[w] = count.get(w, 0) + 1
    return np.array(sorted(chosen), np.int64)


@register
class RoadsBridges(SENode):
    """Bridges where a major road of the pattern is cut by water (bridge=yes, a deck in city.glb)."""

    name = "roads.bridges"
    inputs = {
        "roads": Port("roads", "street centre lines (major ones may be carried across)"),
        "water": Port("polygons", "water bodies", required=False),
    }
    outputs = {
        "roads": Port("roads", "the roads plus the bridges (column bridge)"),
        "bridges": Port("polygons", "bridge decks (kind 'bridge', span, thickness)"),
    }
    params = {
        "max_span": Param("float", 250.0, min=1.0, max=5000.0, unit="m", doc="longest bridge"),
        "crossings": Param("int", 3, min=0, max=1000, unit="1", doc="most bridges over one water body"),
        "min_gap": Param("float", 300.0, min=0.0, max=100000.0, unit="m", doc="least distance between two bridges"),
        "snap": Param("float", 30.0, min=0.0, max=500.0, unit="m", doc="a bridge ends on a road end this close"),
        "thickness": Param("float", 1.5, min=0.1, max=20.0, unit="m", doc="deck thickness in city.glb"),
    }

    def counted(self, layers) -> int:
        """The bridges it made (its first output hands on every road)."""
        return len(layers["bridges"])

    def run(self, *, roads: Layer, water: Layer | None = None):
        empty = Layer.empty(meta=dict(roads.meta), kind=np.dtype("<U6"))
        if water is None or not len(water) or not len(roads):
            return NodeResult({"roads": roads, "bridges": empty}, {"bridges": 0})
        major = np.array(roads["major"], bool) if "major" in roads else np.ones(len(roads), bool)
        if "class" in roads:
            major &= np.asarray(roads["class"]).astype(str) != "boundary"  # a bank road runs along the water
        cand = bridge_candidates(roads.geometry, major, water.geometry, max_span=self.p.max_span, snap=self.p.snap)
        # a road that only touches the water at a point crosses nothing: a span of no length is no bridge
        cand = {k: v[cand["span"] > 1e-3] for k, v in cand.items()}
        pick = choose_bridges(cand, crossings=self.p.crossings, min_gap=self.p.min_gap)
        if len(pick) == 0:
            return NodeResult({"roads": roads, "bridges": empty}, {"bridges": 0})
        src = roads.take(cand["road"][pick])
        lines = shapely.linestrings(np.stack([cand["start"][pick], cand["end"][pick]], axis=1))
        span = cand["span"][pick]
        new = Layer(lines, src.ids, src.parent, dict(src.attrs), dict(roads.meta))
        onto = cand["onto"][pick]
        split = 0
        if (onto >= 0).any():  # the bank roads the far ends land on are noded there
            geoms, rows = split_lines_at(roads.geometry, onto[onto >= 0], cand["end"][pick][onto >= 0])
            split = len(geoms) - len(roads)
            roads = roads.take(rows)
            roads = Layer(geoms, roads.ids, roads.parent, dict(roads.attrs), dict(roads.meta))
        out = Layer.concat(
            [roads.with_columns(bridge=np.zeros(len(roads), bool)), new.with_columns(bridge=np.ones(len(new), bool))]
        )
        out = Layer(out.geometry, np.arange(len(out), dtype=np.int64), out.parent, out.attrs, out.meta)
        width = np.nan_to_num(np.asarray(src["width"], float), nan=10.0) if "width" in src else np.full(len(src), 10.0)
        decks = Layer.from_geoms(
            shapely.buffer(lines, np.maximum(width, 2.0) / 2, cap_style="flat"),
            meta=dict(roads.meta),
            kind=np.full(len(lines), "bridge"),
            span=np.round(span, 3),
            width=width,
            thickness=np.full(len(lines), float(self.p.thickness)),
            district=np.asarray(src["district"], np.int64) if "district" in src else np.full(len(src), -1),
        )
        report = {
            "bridges": len(pick),
            "bridge_m": round(float(span.sum()), 1),
            "candidates": len(cand["span"]),
            "bank_roads_split": split,
        }
        log.info("%s: %d bridges (%.0f m) of %d possible", self.where, len(pick), span.sum(), len(cand["span"]))
        return NodeResult({"roads": out, "bridges": decks}, report)

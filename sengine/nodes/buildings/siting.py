"""Siting: where on its lot a building may stand, and the bands it is drawn in.

The *building area* (paper 000 §5.3.2) is the part of the lot further than
the setbacks from its lines: ``front`` from the street (the build-to line:
the street wall of a building along the front stands on it), ``side`` from
the neighbouring lots beside it and ``rear`` from the lot behind.  A
**detached** building keeps its side setback (000: 4 m from neighbouring
lots, typical of Finnish detailed plans); an **attached** one has none, so
its side walls stand on the side lot lines and neighbours share party walls
(perimeter blocks).

Setbacks are distances: the building area is the lot minus every point
within the setback of a line of that kind (a round buffer of each lot's
lines, one overlay per kind, all lots at once).  Footprints are then cut out
of the building area:

* :func:`band` -- the part within a depth of one kind of line (a slab along
  the street: 000's "front" siting; along the sides for L and U shapes);
* :func:`ring` -- the part within a depth of the area's own edge (an O
  around a courtyard or atrium);
* :func:`centred_boxes` -- rectangles oriented to the street, centred on
  the area (towers, halls);
* :func:`limit_length` -- a footprint shortened along the street (000 §5.3.3
  step 8c).

References
----------
.. [1] J. Viinikka, "Procedural modelling as an urban planning tool",
   master's thesis, Aalto University, Espoo, 2014, §5.3.2-5.3.4 (paper 000).
.. [2] M. Zhang, J. Wu, Y. Liu, J. Zhang and G. Li, "GIS based procedural
   modeling in 3D urban design", ISPRS International Journal of
   Geo-Information 11(10):531, 2022. doi:10.3390/ijgi11100531, §3.3.2 (paper 004).
"""

from __future__ import annotations

import numpy as np
import shapely

from sengine.geom.polygons import frame_boxes, inset, threaded

from .edges import FRONT, REAR, SIDE, Lines, LotEdges

__all__ = [
    "QUAD_SEGS",
    "polygonal",
    "axis_extent",
    "building_area",
    "band",
    "side_lines",
    "ring",
    "centred_boxes",
    "limit_length",
]

#: Segments per quarter circle of the setback buffers (their arcs stay outside
#: a convex lot; only a reflex lot corner shows one).
QUAD_SEGS = 4


def polygonal(geoms) -> np.ndarray:
    """Each geometry reduced to its polygonal part (a Polygon or MultiPolygon; empty when none)."""
    geoms = np.asarray(geoms, dtype=object)
    out = geoms.copy()
    t = shapely.get_type_id(geoms)
    odd = ~np.isin(t, (3, 6)) & ~shapely.is_empty(geoms)
    if odd.any():  # a GeometryCollection from an overlay: keep its polygons
        idx = np.flatnonzero(odd)
        parts, pi = shapely.get_parts(geoms[idx], return_index=True)
        poly = shapely.get_type_id(parts) == 3
        res = np.full(len(idx), shapely.Polygon(), dtype=object)
        if poly.any():
            res = shapely.multipolygons(parts[poly], indices=pi[poly], out=res)
        out[idx] = res
    return out


def _clip_runs(area, owner, runs, a0, a1, b0, b1):
    """``area[owner]`` clipped to a box in each run's frame: ``a`` along the run from its origin,
    ``b`` into the lot; each bound is first narrowed to the area's own extent plus 1 m.

    An overlay, not an affine round trip through a rectangle clipper: the
    vertices kept are the lot's own, so neighbours' party walls stay on the
    very same line; an area inside its box is returned as it is.
    """
    g = area[owner]
    ax = runs["axis"]
    inward = runs["inward"]
    o = runs["origin"]
    nrm = np.stack([-ax[:, 1], ax[:, 0]], axis=1) * inward[:, None]
    lo, hi = axis_extent(g, ax, o)
    blo, bhi = axis_extent(g, nrm, o)
    inside = (a0 <= lo) & (a1 >= hi) & (b0 <= blo) & (b1 >= bhi)
    a0, a1 = np.maximum(a0, lo - 1.0), np.minimum(a1, hi + 1.0)
    b0, b1 = np.maximum(b0, blo - 1.0), np.minimum(b1, bhi + 1.0)
    # in the run's own frame the lot lies at positive b when inward is +1: mirror the others
    lo_b = np.where(inward > 0, b0, -b1)
    hi_b = np.where(inward > 0, b1, -b0)
    out = g.copy()
    cut = np.flatnonzero(~inside)
    if len(cut):
        box = frame_boxes(o[cut], ax[cut], a0[cut], a1[cut], lo_b[cut], hi_b[cut])
        out[cut] = threaded(shapely.intersection, g[cut], box)
    return out


def _by_lot(parts, owner, n, combine):
    """Fold the parts of each lot (``owner``: its position, increasing) with ``combine``, pairwise."""
    out = np.full(n, None, dtype=object)
    if len(parts) == 0:
        return out
    first = np.r_[True, owner[1:] != owner[:-1]]
    rank = np.arange(len(owner)) - np.maximum.accumulate(np.where(first, np.arange(len(owner)), 0))
    out[owner[first]] = parts[first]
    for k in range(1, int(rank.max()) + 1):
        sel = rank == k
        out[owner[sel]] = threaded(combine, out[owner[sel]], parts[sel])
    return out


def _minus(area, lines: Lines, dist, convex):
    """``area`` minus the points within ``dist`` of ``lines`` (both per lot; no-op where none).

    On a convex lot, the part at least ``dist`` beyond each run's line
    (half-plane clips, one per run); on others a round buffer and an overlay.
    """
    dist = np.asarray(dist, np.float64)
    todo = lines.has & (dist > 0) & ~shapely.is_empty(area)
    out = area.copy()
    fast = np.flatnonzero(todo & convex)
    if len(fast):
        owner, runs = lines.runs(fast)
        first = np.r_[True, owner[1:] != owner[:-1]]
        rank = np.arange(len(owner)) - np.maximum.accumulate(np.where(first, np.arange(len(owner)), 0))
        for k in range(int(rank.max(initial=-1)) + 1):  # one clip per run, every lot's k-th run at once
            sel = rank == k
            w = owner[sel]
            r = {key: v[sel] for key, v in runs.items()}
            inf = np.full(len(w), np.inf)
            out[w] = _clip_runs(out, w, r, -inf, inf, dist[w], inf)
    slow = np.flatnonzero(todo & ~convex)
    if len(slow):
        # the buffer's arcs are chords: widen it so they stay outside the true circle
        grow = 1.0 / np.cos(np.pi / (4 * QUAD_SEGS))
        zone = threaded(shapely.buffer, lines.geoms(slow), dist[slow] * grow, quad_segs=QUAD_SEGS)
        out[slow] = threaded(shapely.difference, area[slow], zone)
    return out


def building_area(lots, edges: LotEdges, front, side, rear) -> np.ndarray:
    """Each lot minus its setbacks (m, per lot or scalar): the building area (000 §5.3.2).

    Returns polygons, multipolygons (a lot narrowed to pieces) or empty
    geometries (a lot thinner than its setbacks).
    """
    lots = np.asarray(lots, dtype=object)
    n = len(lots)
    area = lots.copy()
    convex = shapely.area(lots) >= (1.0 - 1e-9) * shapely.area(shapely.convex_hull(lots)) if n else np.zeros(0, bool)
    for kind, dist in ((FRONT, front), (SIDE, side), (REAR, rear)):
        area = _minus(area, edges.lines(kind, n), np.broadcast_to(np.asarray(dist, np.float64), (n,)), convex)
    return polygonal(area)


def band(area, lines: Lines, depth) -> np.ndarray:
    """The part of ``area`` within ``depth`` (m, per lot) of ``lines`` (empty where a lot has none).

    Each straight run of a lot's lines reaches ``depth`` on both sides and
    beyond both ends (a square-capped buffer: a rectangle, cut with GEOS's
    rectangle clipper); a lot with several runs (a corner lot) takes the
    union of its pieces.
    """
    area = np.asarray(area, dtype=object)
    n = len(area)
    depth = np.broadcast_to(np.asarray(depth, np.float64), (n,))
    out = np.full(n, shapely.Polygon(), dtype=object)
    todo = np.flatnonzero(lines.has & (depth > 0) & ~shapely.is_empty(area))
    if len(todo):
        owner, runs = lines.runs(todo)
        d = depth[owner]
        pieces = polygonal(_clip_runs(area, owner, runs, runs["lo"] - d, runs["hi"] + d, -d, d))
        out[todo] = _by_lot(pieces, np.searchsorted(todo, owner), len(todo), shapely.union)
    return polygonal(out)


def side_lines(edges: LotEdges, n: int, which: str) -> Lines:
    """The side lines on one hand of each lot, seen from the street: ``"left"`` or ``"right"``.

    A side segment is on the left when its midpoint lies before the middle
    of the lot's corners along the front axis.
    """
    mask = edges.kind == SIDE
    if mask.any():
        ax = edges.axis[edges.lot]
        t = np.einsum("ij,ij->i", 0.5 * (edges.p0 + edges.p1), ax)
        t0 = np.einsum("ij,ij->i", edges.p0, ax)
        lo = np.full(n, np.inf)
        hi = np.full(n, -np.inf)
        np.minimum.at(lo, edges.lot, t0)
        np.maximum.at(hi, edges.lot, t0)
        centre = 0.5 * (lo + hi)[edges.lot]
        mask &= (t < centre) if which == "left" else (t >= centre)
    return edges.lines(SIDE, n, mask)


def ring(area, depth) -> np.ndarray:
    """The part of ``area`` within ``depth`` (m, per lot) of its own edge: an O around a court."""
    area = np.asarray(area, dtype=object)
    depth = np.broadcast_to(np.asarray(depth, np.float64), area.shape)
    core = inset(area, depth)
    return polygonal(threaded(shapely.difference, area, core))


def axis_extent(geoms, axis, origin=None):
    """Lowest and highest projection (m) of each geometry's points on its ``axis`` (from ``origin``)."""
    n = len(geoms)
    lo = np.zeros(n)
    hi = np.zeros(n)
    c, ci = shapely.get_coordinates(geoms, return_index=True)
    if len(ci):
        if origin is not None:
            c = c - origin[ci]
        t = np.einsum("ij,ij->i", c, axis[ci])
        lo[:] = np.inf
        hi[:] = -np.inf
        np.minimum.at(lo, ci, t)
        np.maximum.at(hi, ci, t)
        none = ~np.isfinite(lo)
        lo[none] = hi[none] = 0.0
    return lo, hi


def centred_boxes(area, axis, width, depth, *, count=1) -> tuple[np.ndarray, np.ndarray]:
    """Rectangles oriented to the street, ``width`` along it and ``depth`` across, inside ``area``.

    ``count`` (per lot, 1 or 2) boxes are spread along the street: one in
    the middle of the area, two at its quarter points.  Each box is clipped
    to the area.  Returns the boxes and the row (lot) of each.
    """
    area = np.asarray(area, dtype=object)
    n = len(area)
    axis = np.asarray(axis, np.float64).reshape(n, 2)
    count = np.broadcast_to(np.asarray(count, np.int64), (n,))
    width = np.broadcast_to(np.asarray(width, np.float64), (n,))
    depth = np.broadcast_to(np.asarray(depth, np.float64), (n,))
    c = shapely.centroid(area)
    inside = shapely.contains_properly(area, c) if n else np.zeros(0, bool)
    if (~inside).any():
        c = c.copy()
        c[~inside] = shapely.point_on_surface(area[~inside])
    xy = shapely.get_coordinates(c) if n else np.zeros((0, 2))
    if len(xy) != n:  # empty areas have no point
        xy = np.zeros((n, 2))
        ok = ~shapely.is_empty(c)
        xy[ok] = shapely.get_coordinates(c[ok])
    lo, hi = axis_extent(area, axis)
    row = np.repeat(np.arange(n), count)
    k = np.arange(len(row)) - np.repeat(np.cumsum(count) - count, count)
    centre_t = np.einsum("ij,ij->i", xy, axis)
    two = count[row] == 2
    t = np.where(two, lo[row] + (0.25 + 0.5 * k) * (hi - lo)[row], centre_t[row])
    nrm = np.stack([-axis[:, 1], axis[:, 0]], axis=1)
    s = np.einsum("ij,ij->i", xy, nrm)[row]
    centre = t[:, None] * axis[row] + s[:, None] * nrm[row]
    w, d = width[row], depth[row]
    boxes = frame_boxes(centre, axis[row], -w / 2, w / 2, -d / 2, d / 2)
    return polygonal(threaded(shapely.intersection, boxes, area[row])), row


def limit_length(geoms, axis, fraction) -> np.ndarray:
    """Each footprint cut down to ``fraction`` of its length along ``axis``, about its middle (000 step 8c)."""
    geoms = np.asarray(geoms, dtype=object)
    n = len(geoms)
    fraction = np.broadcast_to(np.asarray(fraction, np.float64), (n,))
    sel = np.flatnonzero((fraction < 1.0) & ~shapely.is_empty(geoms))
    if len(sel) == 0:
        return geoms
    ax = np.asarray(axis, np.float64).reshape(n, 2)[sel]
    lo, hi = axis_extent(geoms[sel], ax)
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo) * fraction[sel]
    nrm = np.stack([-ax[:, 1], ax[:, 0]], axis=1)
    slo, shi = axis_extent(geoms[sel], nrm)
    out = geoms.copy()
    box = frame_boxes(np.zeros((len(sel), 2)), ax, mid - half, mid + half, slo - 1.0, shi + 1.0)
    out[sel] = polygonal(threaded(shapely.intersection, geoms[sel], box))
    return out

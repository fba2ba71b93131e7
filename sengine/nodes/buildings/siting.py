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


def _convex_rings(geoms, coords=None):
    """Which geometries are convex polygons without holes, and their shells' coordinates (no closing point).

    ``coords``: ``shapely.get_coordinates(geoms, return_index=True)`` when
    the caller has it.  Returns ``(ok, xy, owner)``: ``xy`` and ``owner``
    list the vertices of the ``ok`` geometries only, ring after ring.
    """
    geoms = np.asarray(geoms, dtype=object)
    ok = (shapely.get_type_id(geoms) == 3) & (shapely.get_num_interior_rings(geoms) == 0)
    if coords is None:
        ok &= ~shapely.is_empty(geoms)
        idx = np.flatnonzero(ok)
        xy, owner = shapely.get_coordinates(geoms[idx], return_index=True)
        owner = idx[owner]
    else:
        xy, owner = coords
        ok &= np.bincount(owner, minlength=len(geoms)) > 0  # an empty polygon has no coordinates
        keep = ok[owner]
        xy, owner = xy[keep], owner[keep]
    if len(owner) == 0:
        return ok, xy, owner.astype(np.int64)
    last = np.r_[owner[1:] != owner[:-1], True]
    xy, owner = xy[~last], owner[~last]  # drop each ring's closing point
    if len(owner):
        start = np.r_[True, owner[1:] != owner[:-1]]
        first = np.maximum.accumulate(np.where(start, np.arange(len(owner)), 0))
        end = np.r_[start[1:], True]
        nxt = np.arange(len(owner)) + 1
        nxt[end] = first[end]
        e = xy[nxt] - xy
        turn = e[:, 0] * e[nxt][:, 1] - e[:, 1] * e[nxt][:, 0]
        scale = np.maximum(np.abs(e).sum(axis=1) * np.abs(e[nxt]).sum(axis=1), 1e-300)
        pos = np.bincount(owner, weights=(turn > 1e-12 * scale).astype(float), minlength=len(geoms)) > 0
        neg = np.bincount(owner, weights=(turn < -1e-12 * scale).astype(float), minlength=len(geoms)) > 0
        ok &= ~(pos & neg)
        keep = ok[owner]
        xy, owner = xy[keep], owner[keep]
    return ok, xy, owner


#: m: a vertex this close to a cutting line counts as on it (coordinates of about 1e6 m carry 1e-10 m).
ON_LINE = 1e-9


def _halfplane(xy, owner, normal, offset):
    """Sutherland-Hodgman: convex rings cut to ``dot(normal, p) >= offset``.

    The rings are vertex lists ``xy`` by ``owner`` (increasing); ``normal``
    and ``offset`` are per owner.  Kept vertices are the input's own floats.
    """
    if len(owner) == 0:
        return xy, owner
    s = np.einsum("ij,ij->i", xy, normal[owner]) - offset[owner]
    start = np.r_[True, owner[1:] != owner[:-1]]
    first = np.maximum.accumulate(np.where(start, np.arange(len(owner)), 0))
    end = np.r_[start[1:], True]
    nxt = np.arange(len(owner)) + 1
    nxt[end] = first[end]
    # a vertex within ON_LINE of the cut is on it: kept, and no crossing made beside it (a crossing a
    # hair from its vertex gave two vertices 1e-19 m apart and a self-touching ring)
    on = np.abs(s) <= ON_LINE
    inside = (s >= 0) | on
    cross = (inside != inside[nxt]) & ~on & ~on[nxt]
    with np.errstate(invalid="ignore"):  # an infinite offset (no cut) gives inf - inf where nothing crosses
        t = np.where(cross, s / np.where(cross, s - s[nxt], 1.0), 0.0)
    hit = xy + t[:, None] * (xy[nxt] - xy)
    count = inside.astype(np.int64) + cross
    out_owner = np.repeat(owner, count)
    out = np.empty((int(count.sum()), 2))
    at = np.cumsum(count) - count
    out[at[inside]] = xy[inside]
    out[(at + inside)[cross]] = hit[cross]
    return out, out_owner


def clip_box(geoms, origin, axis, a0, a1, b0, b1) -> np.ndarray:
    """Each geometry cut to the box ``a0 <= a <= a1``, ``b0 <= b <= b1`` of its own frame (m).

    ``a`` runs along ``axis`` from ``origin``, ``b`` along its left normal;
    infinite bounds cut nothing.  Convex polygons (most lots and their
    building areas) are cut in numpy, half-plane by half-plane, keeping
    their own vertices; the others by a GEOS overlay with the box.  A
    geometry inside its box comes back as it is.
    """
    geoms = np.asarray(geoms, dtype=object)
    n = len(geoms)
    origin = np.asarray(origin, np.float64).reshape(n, 2)
    axis = np.asarray(axis, np.float64).reshape(n, 2)
    a0, a1, b0, b1 = (np.broadcast_to(np.asarray(v, np.float64), (n,)) for v in (a0, a1, b0, b1))
    nrm = np.stack([-axis[:, 1], axis[:, 0]], axis=1)
    c, ci = shapely.get_coordinates(geoms, return_index=True)  # read once: extents and convex rings
    rel = c - origin[ci]
    lo, hi = _extent(rel, ci, axis, n)
    blo, bhi = _extent(rel, ci, nrm, n)
    inside = (a0 <= lo) & (a1 >= hi) & (b0 <= blo) & (b1 >= bhi)
    out = geoms.copy()
    cut = np.flatnonzero(~inside & (np.bincount(ci, minlength=n) > 0))  # an empty geometry has no coordinates
    if len(cut) == 0:
        return out
    pos = np.full(n, -1, np.int64)
    pos[cut] = np.arange(len(cut))
    sub = pos[ci] >= 0
    ok, xy, owner = _convex_rings(geoms[cut], (c[sub], pos[ci[sub]]))
    fast = cut[ok]
    if len(fast):
        pos = np.full(n, -1, np.int64)
        pos[fast] = np.arange(len(fast))
        own = pos[cut[owner]]
        o = origin[fast]
        for normal, bound, sign in ((axis, a0, 1.0), (axis, a1, -1.0), (nrm, b0, 1.0), (nrm, b1, -1.0)):
            if not np.isfinite(bound[fast]).any():
                continue
            nv = normal[fast] * sign
            off = np.einsum("ij,ij->i", nv, o) + sign * bound[fast]
            off = np.where(np.isfinite(off), off, -np.inf)
            xy, own = _halfplane(xy, own, nv, off)
        cnt = np.bincount(own, minlength=len(fast))
        res = np.full(len(fast), shapely.Polygon(), dtype=object)
        full = np.flatnonzero(cnt >= 3)
        if len(full):
            keep = np.isin(own, full)
            remap = np.full(len(fast), -1, np.int64)
            remap[full] = np.arange(len(full))
            rings = shapely.linearrings(xy[keep], indices=remap[own[keep]])
            res[full] = shapely.polygons(rings)
        out[fast] = res
    slow = cut[~ok]
    if len(slow):
        box = frame_boxes(
            origin[slow],
            axis[slow],
            np.maximum(a0[slow], lo[slow] - 1.0),
            np.minimum(a1[slow], hi[slow] + 1.0),
            np.maximum(b0[slow], blo[slow] - 1.0),
            np.minimum(b1[slow], bhi[slow] + 1.0),
        )
        out[slow] = threaded(shapely.intersection, geoms[slow], box)
    return out


def _clip_runs(area, owner, runs, a0, a1, b0, b1):
    """``area[owner]`` cut to a box in each run's frame.

    ``a`` runs along the run from its origin, ``b`` into the lot
    (:func:`clip_box`: the lot's own vertices are kept, so neighbours' party
    walls stay on the very same line).
    """
    inward = runs["inward"]
    # in the run's own frame the lot lies at positive b when inward is +1: mirror the others
    lo_b = np.where(inward > 0, b0, -b1)
    hi_b = np.where(inward > 0, b1, -b0)
    return clip_box(area[owner], runs["origin"], runs["axis"], a0, a1, lo_b, hi_b)


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


def building_area(lots, edges: LotEdges, front, side, rear, *, party=None) -> np.ndarray:
    """Each lot minus its setbacks (m, per lot or scalar): the building area (000 §5.3.2).

    ``party`` (per lot ``"left"``, ``"right"`` or ``""``) names the hand
    whose side lines take no setback: a semi-detached house stands on the
    line it shares with its partner.

    Returns polygons, multipolygons (a lot narrowed to pieces) or empty
    geometries (a lot thinner than its setbacks).
    """
    lots = np.asarray(lots, dtype=object)
    n = len(lots)
    area = lots.copy()
    convex = shapely.area(lots) >= (1.0 - 1e-9) * shapely.area(shapely.convex_hull(lots)) if n else np.zeros(0, bool)

    def per_lot(v):
        return np.broadcast_to(np.asarray(v, np.float64), (n,))

    for kind, dist in ((FRONT, front), (REAR, rear)):
        area = _minus(area, edges.lines(kind, n), per_lot(dist), convex)
    if party is None:
        return polygonal(_minus(area, edges.lines(SIDE, n), per_lot(side), convex))
    party = np.asarray(party)
    for hand in ("left", "right"):
        area = _minus(area, side_lines(edges, n, hand), np.where(party == hand, 0.0, per_lot(side)), convex)
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


def left_hand(edges: LotEdges, n: int) -> np.ndarray:
    """Whether each segment lies on its lot's left, seen from the street.

    A segment is on the left when its midpoint lies before the middle of the
    lot's corners along the front axis.
    """
    if not len(edges.lot):
        return np.zeros(0, bool)
    ax = edges.axis[edges.lot]
    t = np.einsum("ij,ij->i", 0.5 * (edges.p0 + edges.p1), ax)
    t0 = np.einsum("ij,ij->i", edges.p0, ax)
    lo = np.full(n, np.inf)
    hi = np.full(n, -np.inf)
    np.minimum.at(lo, edges.lot, t0)
    np.maximum.at(hi, edges.lot, t0)
    return t < 0.5 * (lo + hi)[edges.lot]


def side_lines(edges: LotEdges, n: int, which: str) -> Lines:
    """The side lines on one hand of each lot, seen from the street: ``"left"`` or ``"right"`` (:func:`left_hand`)."""
    mask = edges.kind == SIDE
    if mask.any():
        left = left_hand(edges, n)
        mask &= left if which == "left" else ~left
    return edges.lines(SIDE, n, mask)


def ring(area, depth) -> np.ndarray:
    """The part of ``area`` within ``depth`` (m, per lot) of its own edge: an O around a court."""
    area = np.asarray(area, dtype=object)
    depth = np.broadcast_to(np.asarray(depth, np.float64), area.shape)
    core = inset(area, depth)
    return polygonal(threaded(shapely.difference, area, core))


def axis_extent(geoms, axis, origin=None):
    """Lowest and highest projection (m) of each geometry's points on its ``axis`` (from ``origin``)."""
    c, ci = shapely.get_coordinates(geoms, return_index=True)
    if origin is not None:
        c = c - origin[ci]
    return _extent(c, ci, axis, len(geoms))


def _extent(c, ci, axis, n):
    """:func:`axis_extent` from the coordinates ``c`` (relative to the origin) of geometries ``ci`` (increasing)."""
    lo = np.zeros(n)
    hi = np.zeros(n)
    if len(ci):
        t = np.einsum("ij,ij->i", c, axis[ci])
        start = np.flatnonzero(np.r_[True, ci[1:] != ci[:-1]])  # each geometry's coordinates are consecutive
        lo[ci[start]] = np.minimum.reduceat(t, start)
        hi[ci[start]] = np.maximum.reduceat(t, start)
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
    return polygonal(clip_box(area[row], centre, axis[row], -w / 2, w / 2, -d / 2, d / 2)), row


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
    out = geoms.copy()
    out[sel] = polygonal(clip_box(geoms[sel], np.zeros((len(sel), 2)), ax, mid - half, mid + half, -np.inf, np.inf))
    return out

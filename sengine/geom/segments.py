"""Segment graphs: straight segments with shared node ids, made from lines and made plane.

Nothing here knows about cities: lines become ``(xy, u, v)`` arrays (node
coordinates, segment end node ids), coincident points are merged and
crossing segments split, vectorized over numpy arrays.  The faces of such a
graph are traced in :mod:`sengine.geom.planar`.

Public API
----------
:func:`merge_points` -- unique points (to a rounding) and the index map.
:func:`segments_from_lines` -- LineStrings to ``(xy, u, v, src)`` arrays
(optionally noded with ``shapely.node``).
:func:`planarize` -- split crossing segments of a ``(xy, u, v)`` graph.
:func:`argsort_int` -- stable argsort of integer keys by radix passes.
:func:`lines_from_groups` -- LineStrings from points grouped by line.
:func:`box_closure` -- the edges that close a graph along its bounding box.
"""

from __future__ import annotations

import logging

import numpy as np
import shapely

__all__ = ["argsort_int", "merge_points", "segments_from_lines", "planarize", "lines_from_groups", "box_closure"]

log = logging.getLogger(__name__)


def argsort_int(keys: np.ndarray) -> np.ndarray:
    """``np.argsort(keys, kind="stable")`` for integer keys, by 16-bit radix passes.

    numpy sorts 16-bit integers with a linear-time radix sort; keys spanning
    up to 48 bits are sorted digit by digit (least significant first, each
    pass stable), which beats the merge sort numpy uses for wider integers.
    """
    keys = np.asarray(keys)
    if len(keys) < 4096:
        return np.argsort(keys, kind="stable")
    lo = int(keys.min())
    passes = -(-max(int(keys.max()) - lo, 1).bit_length() // 16)
    if passes > 3:
        return np.argsort(keys, kind="stable")
    k = (keys - lo).astype(np.uint64)
    order = None
    for p in range(passes):
        digit = ((k if order is None else k[order]) >> np.uint64(16 * p)).astype(np.uint16)  # low 16 bits
        o = np.argsort(digit, kind="stable")
        order = o if order is None else order[o]
    return order


def merge_points(coords: np.ndarray, decimals: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Unique points of ``coords`` (n, 2) and the index of each row in them.

    Points equal after rounding to ``decimals`` (m) are one point (the first
    one's exact coordinates are kept); ``None`` compares exactly.
    """
    key = np.round(coords, decimals) if decimals is not None else coords
    key = np.ascontiguousarray(key, dtype=np.float64) + 0.0  # -0.0 == 0.0
    view = key.view(np.dtype((np.void, 16))).ravel()
    _, first, inv = np.unique(view, return_index=True, return_inverse=True)
    return coords[first], inv.ravel()


def segments_from_lines(lines, *, node: bool = False, decimals: int | None = 9):
    """Explode LineStrings into straight segments with shared node ids.

    Parameters
    ----------
    lines : array_like of shapely.LineString or MultiLineString
        Street centre lines (m).
    node : bool
        Run ``shapely.node`` first so that every crossing, T-junction and
        collinear overlap becomes a shared node.  Without it, segments meet
        only where they share an exact vertex.
    decimals : int or None
        Vertices equal after rounding to this many decimals (m) are one node.

    Returns
    -------
    xy : ndarray, shape (n, 2)
        Node coordinates.
    u, v : ndarray of int64, shape (m,)
        End node ids of each segment.
    src : ndarray of int64, shape (m,)
        Index in ``lines`` of the line each segment comes from (with
        ``node=True``: the nearest input line to the segment's midpoint).
    """
    lines = np.asarray(lines, dtype=object).ravel()
    empty = (np.empty((0, 2)), np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0, np.int64))
    if len(lines) == 0:
        return empty
    work = lines
    if node:
        noded = shapely.node(shapely.multilinestrings(shapely.get_parts(lines)))
        work = shapely.get_parts(noded)
    parts, pidx = shapely.get_parts(work, return_index=True)
    coords, cidx = shapely.get_coordinates(parts, return_index=True)
    if len(coords) < 2:
        return empty
    same = cidx[1:] == cidx[:-1]
    a = np.flatnonzero(same)
    xy, inv = merge_points(coords, decimals)
    u, v = inv[a], inv[a + 1]
    if node:
        mid = (coords[a] + coords[a + 1]) / 2.0
        tree = shapely.STRtree(lines)
        src = tree.query_nearest(shapely.points(mid), all_matches=False)[1]
    else:
        src = pidx[cidx[a]]
    keep = u != v
    return xy, u[keep].astype(np.int64), v[keep].astype(np.int64), np.asarray(src)[keep].astype(np.int64)


def _segments_intersect(p1, p2, p3, p4) -> np.ndarray:
    """Whether segments p1p2 and p3p4 share a point (rows of (k, 2) arrays)."""

    def orient(a, b, c):
        return np.sign((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))

    d1, d2 = orient(p3, p4, p1), orient(p3, p4, p2)
    d3, d4 = orient(p1, p2, p3), orient(p1, p2, p4)
    hit = (d1 * d2 <= 0) & (d3 * d4 <= 0)
    col = (d1 == 0) & (d2 == 0) & (d3 == 0) & (d4 == 0)
    if col.any():  # collinear: the projections must overlap on both axes
        lo1, hi1 = np.minimum(p1, p2)[col], np.maximum(p1, p2)[col]
        lo2, hi2 = np.minimum(p3, p4)[col], np.maximum(p3, p4)[col]
        hit[col] = np.all((lo1 <= hi2) & (lo2 <= hi1), axis=1)
    return hit


def _overlap_past_node(p1, p2, p3, p4) -> np.ndarray:
    """Whether collinear segments p1p2 and p3p4 that share an end point overlap beyond it."""
    r, s = p2 - p1, p4 - p3

    def cross(a, b):
        return a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]

    col = (cross(r, p3 - p1) == 0) & (cross(r, p4 - p1) == 0)
    rr, ss = np.einsum("ij,ij->i", r, r), np.einsum("ij,ij->i", s, s)
    inside = np.zeros(len(p1), bool)
    for a, d, dd, ends in ((p1, r, rr, (p3, p4)), (p3, s, ss, (p1, p2))):
        for e in ends:  # an end of one segment strictly inside the other
            t = np.einsum("ij,ij->i", e - a, d) / np.where(dd > 0, dd, 1.0)
            inside |= (t > 0) & (t < 1)
    return col & inside


def planarize(xy, u, v, *, decimals: int | None = 9):
    """Split segments that cross or touch without a shared node.

    The graph ``(xy, u, v)`` may come from a source that knows its topology
    (OSM node ids) but is not plane (bridges, tunnels, missing nodes).
    Candidate pairs come from one STRtree bounding-box query; the exact
    test and the split points are computed in numpy, so every segment keeps
    its source index and untouched segments keep their node ids.

    Parameters
    ----------
    xy : array_like (n, 2)
        Node coordinates (m).
    u, v : array_like of int (m,)
        Segment end node ids.
    decimals : int or None
        New split points are merged with nodes equal after rounding to this
        many decimals (m).

    Returns
    -------
    xy, u, v, src : as :func:`segments_from_lines`; ``src`` indexes the
        input segments.
    crossings : int
        Number of segment pairs that met away from a shared node.
    """
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    u = np.asarray(u, np.int64).ravel()
    v = np.asarray(v, np.int64).ravel()
    m = len(u)
    src = np.arange(m, dtype=np.int64)
    if m == 0:
        return xy, u, v, src, 0
    segs = shapely.linestrings(np.stack([xy[u], xy[v]], axis=1))
    i, j = shapely.STRtree(segs).query(segs)  # bounding boxes only
    sel = i < j
    i, j = i[sel], j[sel]
    shared = (u[i] == u[j]) | (u[i] == v[j]) | (v[i] == u[j]) | (v[i] == v[j])
    # a shared node rules out a crossing, not a collinear overlap past it (a short way along a long one)
    past = np.zeros(len(i), bool)
    past[shared] = _overlap_past_node(xy[u[i[shared]]], xy[v[i[shared]]], xy[u[j[shared]]], xy[v[j[shared]]])
    i, j = i[~shared | past], j[~shared | past]
    hit = _segments_intersect(xy[u[i]], xy[v[i]], xy[u[j]], xy[v[j]])
    i, j = i[hit], j[hit]
    if len(i) == 0:
        return xy, u, v, src, 0
    p, r = xy[u[i]], xy[v[i]] - xy[u[i]]
    q, s = xy[u[j]], xy[v[j]] - xy[u[j]]
    den = r[:, 0] * s[:, 1] - r[:, 1] * s[:, 0]
    qp = q - p
    col = den == 0
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (qp[:, 0] * s[:, 1] - qp[:, 1] * s[:, 0]) / den
        w = (qp[:, 0] * r[:, 1] - qp[:, 1] * r[:, 0]) / den
    t, w = np.clip(t, 0.0, 1.0), np.clip(w, 0.0, 1.0)
    pt = p + t[:, None] * r
    # snap to an exact end point when the crossing is one (T-junctions)
    for par, a_, b_ in ((w, xy[u[j]], xy[v[j]]), (t, xy[u[i]], xy[v[i]])):
        pt = np.where((par <= 1e-12)[:, None], a_, pt)
        pt = np.where((par >= 1 - 1e-12)[:, None], b_, pt)
    ev_seg = [i[~col], j[~col]]
    ev_t = [t[~col], w[~col]]
    ev_xy = [pt[~col], pt[~col]]
    if col.any():  # collinear overlaps: each end point inside the other segment
        for a_, b_ in ((i[col], j[col]), (j[col], i[col])):
            pa, ra = xy[u[a_]], xy[v[a_]] - xy[u[a_]]
            rr = np.einsum("ij,ij->i", ra, ra)
            for end in (xy[u[b_]], xy[v[b_]]):
                tt = np.einsum("ij,ij->i", end - pa, ra) / np.where(rr > 0, rr, 1.0)
                inside = (tt > 0) & (tt < 1)
                ev_seg.append(a_[inside])
                ev_t.append(tt[inside])
                ev_xy.append(end[inside])
    bad = np.unique(np.concatenate([i, j]))
    ev_seg += [bad, bad]
    ev_t += [np.zeros(len(bad)), np.ones(len(bad))]
    ev_xy += [xy[u[bad]], xy[v[bad]]]
    es, et, exy = np.concatenate(ev_seg), np.concatenate(ev_t), np.concatenate(ev_xy)
    o = np.lexsort((et, es))
    es, exy = es[o], exy[o]
    n0 = len(xy)
    nxy, inv = merge_points(np.concatenate([xy, exy]), decimals)
    # original nodes keep one id each (they are unique already unless duplicated)
    k = np.flatnonzero(es[1:] == es[:-1])
    good = np.ones(m, bool)
    good[bad] = False
    nu = np.concatenate([inv[u[good]], inv[n0 + k]])
    nv = np.concatenate([inv[v[good]], inv[n0 + k + 1]])
    nsrc = np.concatenate([src[good], es[k]])
    keep = nu != nv
    log.info("planarize: %d crossing pairs; %d segments split into %d", len(i), len(bad), len(k))
    return nxy, nu[keep], nv[keep], nsrc[keep], int(len(i))


def lines_from_groups(xy: np.ndarray, group: np.ndarray) -> np.ndarray:
    """LineStrings of points grouped by line: ``shapely.linestrings(xy, indices=group)``.

    ``group`` is non-decreasing from 0 with no gaps.  Street segments between
    junctions are mostly two points each: when all are, the lines are made
    from an ``(m, 2, 2)`` array, which shapely does about a quarter faster.
    """
    xy = np.asarray(xy, np.float64)
    if (
        len(xy) % 2 == 0
        and len(xy)
        and np.array_equal(group[0::2], group[1::2])
        and np.array_equal(group[0::2], np.arange(len(xy) // 2))
    ):
        return shapely.linestrings(xy.reshape(-1, 2, 2))
    return shapely.linestrings(xy, indices=group)


def box_closure(xy, u=None, v=None, *, margin: float = 0.0, box=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Edges that close a segment graph along the bounding box of its nodes.

    The box's four sides are cut at every node lying exactly on them (the
    box is made from the same coordinates, so the nodes that make it lie on
    it bit for bit), so that the graph plus these edges stays plane: no
    straight segment of the graph can cross the bounding box of its own
    end points.  Every bounded region between the graph and the box is
    then a face of the closed graph.

    Parameters
    ----------
    xy : ndarray (n, 2)
        Node coordinates (m).
    u, v : ndarray of int (m,), optional
        The graph's segments: a closing edge that repeats one of them (a
        segment lying along the box) is left out.
    margin : float
        Grow the box by this much on every side (m): no node lies on it
        then, and the graph floats inside one face, the land round it
        (which a caller clips back to the bounding box).
    box : (xmin, ymin, xmax, ymax), optional
        A box to close along instead, grown to hold every node.

    Returns
    -------
    xy : ndarray (n + c, 2)
        The nodes, then the ``c`` box corners that were not nodes already.
    cu, cv : ndarray of int64
        The closing edges, counter-clockwise round the box.  Empty when the
        box has no area (fewer than three nodes, or all on one line).
    """
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    none = np.empty(0, np.int64)
    if len(xy) < 3:
        return xy, none, none
    x0, y0 = xy.min(axis=0)
    x1, y1 = xy.max(axis=0)
    if box is not None:
        x0, y0, x1, y1 = min(x0, box[0]), min(y0, box[1]), max(x1, box[2]), max(y1, box[3])
    if not (x1 > x0 and y1 > y0):
        return xy, none, none
    x0, y0, x1, y1 = x0 - margin, y0 - margin, x1 + margin, y1 + margin
    w, h = x1 - x0, y1 - y0
    x, y = xy[:, 0], xy[:, 1]
    # position along the perimeter, counter-clockwise from (x0, y0); a corner takes its first side's value
    sides = [y == y0, x == x1, y == y1, x == x0]
    pos = [x - x0, w + (y - y0), w + h + (x1 - x), 2 * w + h + (y1 - y)]
    on = np.any(sides, axis=0)
    t = np.select(sides, pos, default=np.nan)
    corner_t = np.array([0.0, w, w + h, 2 * w + h])
    corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
    have = np.isin(corner_t, t[on])
    ids = np.r_[np.flatnonzero(on), len(xy) + np.arange(int((~have).sum()))]
    ts = np.r_[t[on], corner_t[~have]]
    xy = np.concatenate([xy, corners[~have]])
    o = np.lexsort((ids, ts))
    ring, ts = ids[o], ts[o]
    ring = ring[np.r_[True, ts[1:] != ts[:-1]]]  # nodes stacked on one spot: the first
    cu, cv = ring, np.roll(ring, -1)
    if u is not None and v is not None and len(u):
        n = len(xy)
        have_e = np.minimum(u, v).astype(np.int64) * n + np.maximum(u, v)
        new_e = np.minimum(cu, cv) * n + np.maximum(cu, cv)
        keep = ~np.isin(new_e, have_e)
        cu, cv = cu[keep], cv[keep]
    return xy, cu.astype(np.int64), cv.astype(np.int64)

"""Boundary segments of polygons, and which of them lie on another polygon's boundary.

Helpers for pieces cut out of a polygon (lots out of a block): the
boundary segments of many polygons as flat arrays
(:func:`ring_segments`), and which of them lie on their owner's boundary
(:func:`segments_on_boundary`: one STRtree query and numpy distances, no
GEOS geometry per segment).
"""

from __future__ import annotations

import numpy as np
import shapely

__all__ = [
    "polygon_parts",
    "ring_segments",
    "segments_on_boundary",
    "segments_on_box",
    "segments_on_lines",
    "street_edges",
]


def _ramp(counts) -> np.ndarray:
    """0, 1, ..., c - 1 for each count, concatenated."""
    counts = np.asarray(counts, np.int64)
    return np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)


def _first_of(groups: np.ndarray, n: int) -> np.ndarray:
    """Start index of each group ``0..n-1`` in a sorted ``groups`` array (n + 1 offsets)."""
    return np.r_[0, np.cumsum(np.bincount(groups, minlength=n))].astype(np.int64)


def polygon_parts(geoms, owner):
    """Non-empty Polygon parts of ``geoms`` (of positive area), with their owners."""
    parts, pi = shapely.get_parts(np.asarray(geoms, dtype=object), return_index=True)
    keep = (shapely.get_type_id(parts) == 3) & ~shapely.is_empty(parts)
    keep &= shapely.area(parts) > 0
    return parts[keep], np.asarray(owner)[pi[keep]]


def ring_segments(polys):
    """Every boundary segment of each Polygon, ring by ring.

    Same result as a per-ring walk over ``shapely.get_rings`` for Polygons,
    made without one ring geometry per polygon: hole-free polygons (most)
    are read with one ``get_coordinates`` call.

    Returns
    -------
    p0, p1 : ndarray (s, 2)
    index : ndarray of int64 (s,)
        Polygon of each segment (non-decreasing).
    ring : ndarray of int64 (s,)
        Ring number (unique over all polygons) of each segment.
    """
    polys = np.asarray(polys, dtype=object).ravel()
    holed = shapely.get_num_interior_rings(polys) > 0
    c, ci = shapely.get_coordinates(polys, return_index=True)
    ring = ci.astype(np.int64)
    if holed.any():
        h = np.flatnonzero(holed)
        rings, rp = shapely.get_rings(polys[h], return_index=True)
        _, rci = shapely.get_coordinates(rings, return_index=True)
        # coordinates of holed polygons come ring after ring in the same order
        sel = holed[ci]
        ring[sel] = len(polys) + rci
    a = np.flatnonzero(ring[1:] == ring[:-1])
    return c[a], c[a + 1], ci[a].astype(np.int64), ring[a]


def segments_on_boundary(geoms, owner, polys, *, tol: float = 1e-6, chunk: int = 12, return_match: bool = False):
    """Boundary segments of each geometry and whether each lies on its owner's boundary.

    A segment lies on the owner's boundary when its midpoint is within
    ``tol`` (m) of one of the owner's boundary segments; exact for pieces
    cut out of the owner.  Candidate (segment, owner segment) pairs come from one STRtree
    query of the geometries against the boxes of the owners' segments, the
    distances are computed in numpy: no GEOS point per segment.

    Parameters
    ----------
    geoms : array_like of shapely.Polygon (k,)
    owner : array_like of int (k,)
        Index into ``polys`` of each geometry's owner.
    polys : array_like of shapely.Polygon
    chunk : int
        Geometries with more segments are queried in runs of this many
        consecutive segments (their envelope would meet too many).
    return_match : bool
        Also return, for each segment, the owner's boundary segment it lies
        on (index into :func:`ring_segments` of ``polys``; -1 for none; the
        nearest where several are within ``tol``).

    Returns
    -------
    p0, p1, index, ring : as :func:`ring_segments` of ``geoms``
    on : ndarray of bool (s,)
    match : ndarray of int64 (s,), only with ``return_match``
    """
    geoms = np.asarray(geoms, dtype=object).ravel()
    owner = np.asarray(owner, np.int64)
    p0, p1, idx, ring = ring_segments(geoms)
    on = np.zeros(len(idx), bool)
    match = np.full(len(idx), -1, np.int64)
    best = np.full(len(idx), np.inf) if return_match else None

    def out():
        return (p0, p1, idx, ring, on) + ((match,) if return_match else ())

    if len(idx) == 0:
        return out()
    polys = np.asarray(polys, dtype=object).ravel()
    if return_match:  # matches are numbered over all of polys' segments
        b0, b1, bown, _ = ring_segments(polys)
    else:  # only the owners' segments: a few geometries need not index a whole city's boundaries
        used = np.unique(owner)
        b0, b1, bi_, _ = ring_segments(polys[used])
        bown = used[bi_]
    if len(bown) == 0:
        return out()
    lo = np.minimum(b0, b1) - tol
    hi = np.maximum(b0, b1) + tol
    tree = shapely.STRtree(shapely.box(lo[:, 0], lo[:, 1], hi[:, 0], hi[:, 1]))
    # query groups of consecutive segments: small geometries by their own envelope,
    # long boundaries (courtyards, whole blocks) in runs of `chunk` segments
    sstart = _first_of(idx, len(geoms))
    nseg = np.diff(sstart)
    small = nseg <= chunk
    gs = np.flatnonzero(small)
    qi, bi = tree.query(geoms[gs])
    g_first, g_cnt = sstart[gs[qi]], nseg[gs[qi]]
    same = bown[bi] == owner[gs[qi]]
    firsts, cnts, bis = [g_first[same]], [g_cnt[same]], [bi[same]]
    big = np.flatnonzero(~small)
    if len(big):
        nch = -(-nseg[big] // chunk)
        cg = np.repeat(big, nch)  # geometry of each chunk
        c0 = sstart[cg] + _ramp(nch) * chunk
        cc = np.minimum(chunk, sstart[cg] + nseg[cg] - c0)
        # envelope of each chunk: reduce over [start, end) pairs, a padding row after the last end
        lo_s = np.r_[np.minimum(p0, p1), np.zeros((1, 2))]
        hi_s = np.r_[np.maximum(p0, p1), np.zeros((1, 2))]
        bounds = np.ravel(np.c_[c0, c0 + cc])
        bl = np.minimum.reduceat(lo_s, bounds)[::2]
        bh = np.maximum.reduceat(hi_s, bounds)[::2]
        ci, bi = tree.query(shapely.box(bl[:, 0], bl[:, 1], bh[:, 0], bh[:, 1]))
        same = bown[bi] == owner[cg[ci]]
        firsts.append(c0[ci[same]])
        cnts.append(cc[ci[same]])
        bis.append(bi[same])
    first, cnt, bi = np.concatenate(firsts), np.concatenate(cnts), np.concatenate(bis)
    step = 1 << 22  # pairs per batch, to bound memory
    ends = np.cumsum(cnt)
    j0 = 0
    while j0 < len(first):
        j1 = int(np.searchsorted(ends, (ends[j0 - 1] if j0 else 0) + step, side="right"))
        j1 = max(j1, j0 + 1)
        c = cnt[j0:j1]
        ps = np.repeat(first[j0:j1], c) + _ramp(c)
        pb = np.repeat(bi[j0:j1], c)
        e = b1[pb] - b0[pb]
        w = 0.5 * (p0[ps] + p1[ps]) - b0[pb]
        ee = np.einsum("ij,ij->i", e, e)
        tt = np.clip(np.einsum("ij,ij->i", w, e) / np.where(ee > 0, ee, 1.0), 0.0, 1.0)
        r = w - tt[:, None] * e
        dd = np.einsum("ij,ij->i", r, r)
        near = dd <= tol * tol
        on[ps[near]] = True
        if return_match:
            ps_n, pb_n, dd_n = ps[near], pb[near], dd[near]
            o = np.lexsort((pb_n, dd_n))  # nearest first; ties: the lowest boundary segment
            ps_n, pb_n, dd_n = ps_n[o], pb_n[o], dd_n[o]
            u, f = np.unique(ps_n, return_index=True)
            better = dd_n[f] < best[u]
            best[u[better]] = dd_n[f][better]
            match[u[better]] = pb_n[f][better]
        j0 = j1
    return out()


def segments_on_box(p0, p1, box, *, tol: float = 1e-3) -> np.ndarray:
    """Which segments lie on a side of an axis-aligned box.

    The land an OSM extract closes round its streets is cut by the extract's
    box (``roads.clean``'s ``close="bbox"``): those sides are no street, so
    no lot fronts on them.

    Parameters
    ----------
    p0, p1 : ndarray (k, 2)
        Segment end points (m).
    box : tuple of float or None
        ``(xmin, ymin, xmax, ymax)`` (m); ``None``: no segment is on it.
    tol : float
        Distance (m) within which an end point lies on a side.

    Returns
    -------
    ndarray of bool (k,)
        Both end points on the same side.
    """
    p0, p1 = np.asarray(p0, float).reshape(-1, 2), np.asarray(p1, float).reshape(-1, 2)
    if box is None or not len(p0):
        return np.zeros(len(p0), bool)
    xmin, ymin, xmax, ymax = (float(c) for c in box)
    out = np.zeros(len(p0), bool)
    for axis, value in ((0, xmin), (0, xmax), (1, ymin), (1, ymax)):
        out |= (np.abs(p0[:, axis] - value) <= tol) & (np.abs(p1[:, axis] - value) <= tol)
    return out


def segments_on_lines(p0, p1, lines, *, tol: float = 0.02) -> np.ndarray:
    """Which segments lie on given lines (their midpoint within ``tol``); ``None`` lines hold every segment.

    Parameters
    ----------
    p0, p1 : ndarray (k, 2)
        Segment end points (m).
    lines : ndarray of object (k,)
        For each segment, the (Multi)LineString it should lie on (e.g. its
        block's street front), or ``None`` for no restriction.
    tol : float
        Distance (m).

    Returns
    -------
    ndarray of bool (k,)
    """
    lines = np.asarray(lines, dtype=object)
    out = np.ones(len(lines), bool)
    some = np.flatnonzero(np.not_equal(lines, None))
    if len(some):
        mid = shapely.points(0.5 * (np.asarray(p0, float)[some] + np.asarray(p1, float)[some]))
        near = lines[some]
        # a block's front is long and shared by all its lots' segments: prepared, GEOS measures
        # each point against its indexed facets instead of every segment (same distances)
        fresh = near[~shapely.is_prepared(near)]
        shapely.prepare(fresh)
        try:
            out[some] = shapely.dwithin(near, mid, tol)
        finally:
            shapely.destroy_prepared(fresh)  # the caller's geometries are left as they came
    return out


def street_edges(rs, own, fronts=None, box=None) -> np.ndarray:
    """Which edges of the block parts ``rs`` face a street: not on ``box``, and on their block's ``fronts``.

    Parameters
    ----------
    rs : sengine.geom.split.RingSet
        Block parts; edge ``i`` runs from vertex ``i`` to its next vertex.
    own : array_like of int
        Block of each polygon of ``rs``.
    fronts : array_like of object, optional
        Per block, its street-facing boundary, a (Multi)LineString, or
        ``None``: all of it (``blocks.landuse``'s ``street_front``).
    box : tuple of float, optional
        ``(xmin, ymin, xmax, ymax)``: edges on it (the extract's edge) face
        no street.

    Returns
    -------
    ndarray of bool
        One per vertex (edge) of ``rs``.
    """
    p0 = rs.xy
    p1 = rs.xy[rs.next_vertex()] if len(p0) else p0
    on = ~segments_on_box(p0, p1, box)
    if fronts is not None and on.any():
        sel = np.flatnonzero(on)
        lines = np.asarray(fronts, dtype=object)[np.asarray(own, np.int64)[rs.vertex_poly()[sel]]]
        on[sel] = segments_on_lines(p0[sel], p1[sel], lines)
    return on

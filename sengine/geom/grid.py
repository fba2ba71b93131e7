"""Polygons cut into grids of rectangular cells given in their own frames.

:func:`sengine.geom.polygons.clip_frame_boxes` clips a polygon once per box,
so a polygon of ``V`` vertices cut into ``nx * ny`` cells costs
``V * nx * ny``: ruinous for a large block cut into thousands of lots.
:func:`clip_frame_grid` makes the cells that lie wholly inside their polygon
as plain rectangles, drops those wholly outside, and clips only the cells on
the outline: about ``V * (nx + ny)``.  Which cells come near a ring is found
in numpy (each ring segment marks the cells its extent meets, column by
column); the others are inside or outside as their centre is (one point
test each), and only the cells near a ring see GEOS's box predicates.
"""

from __future__ import annotations

import numpy as np
import shapely

from .polygons import clip_frame_boxes, clip_unit_local

__all__ = ["clip_frame_grid", "box_pairs"]


def _ramp(counts) -> np.ndarray:
    counts = np.asarray(counts, np.int64)
    return np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)


def clip_frame_grid(geoms, center, axis, xs, nx, ys, ny, *, margin=None, clearance=0.0):
    """Each geometry cut into the cells of its own grid (vectorized; only the outline's cells clipped).

    Parameters
    ----------
    geoms : array_like of shapely.Geometry (n,)
    center, axis : array_like (n, 2)
        Each geometry's frame, as for :func:`sengine.geom.polygons.frame_boxes`
        (``x`` along ``axis``, ``y`` along its left normal, from ``center``).
    xs, ys : array_like
        Cell edges of every geometry in turn along ``x`` and ``y`` (m, in
        the frame), ``nx[i] + 1`` and ``ny[i] + 1`` of them for geometry ``i``.
    nx, ny : array_like of int (n,)
        Columns and rows of each grid.
    margin : array_like (n,), optional
        The outer cells reach this far past the first and last edges, so
        that the grid covers the geometry (m; default 1 m plus 1 % of the
        grid's size).
    clearance : float
        An ``inside`` cell stands farther than this (m) from every ring; a
        cell nearer (or touching) is clipped like the outline's.  Give the
        tolerance under which a caller takes a segment to lie on a ring, so
        that an ``inside`` cell is one that tolerance finds on no ring (a
        cell a hair inside a courtyard's edge is then no inner lot).

    Returns
    -------
    cells : ndarray of shapely.Geometry
        The non-empty cells (any type a clip gives: Polygon, MultiPolygon
        ...), geometry by geometry, column by column.
    owner, ix, iy : ndarray of int64
        Geometry, column and row of each cell.
    inside : ndarray of bool
        Cells that are their whole rectangle, inside the geometry's
        interior (they touch none of its rings, nor come within ``clearance``).  Every other cell has part
        of the geometry's boundary on its own, unless ``whole``.
    whole : ndarray of bool
        Cells that are their whole rectangle (``inside`` ones, and outline
        cells the clip left whole: they may touch a ring at a point or
        along an edge).
    """
    geoms = np.asarray(geoms, dtype=object).ravel()
    n = len(geoms)
    e64 = np.zeros(0, np.int64)
    if n == 0:
        return np.empty(0, object), e64, e64, e64, np.zeros(0, bool), np.zeros(0, bool)
    center = np.asarray(center, np.float64).reshape(-1, 2)
    axis = np.asarray(axis, np.float64).reshape(-1, 2)
    xs, ys = np.asarray(xs, np.float64), np.asarray(ys, np.float64)
    nx, ny = np.asarray(nx, np.int64), np.asarray(ny, np.int64)
    xstart = np.cumsum(nx + 1) - (nx + 1)
    ystart = np.cumsum(ny + 1) - (ny + 1)
    x_lo, x_hi = xs[xstart], xs[xstart + nx]
    y_lo, y_hi = ys[ystart], ys[ystart + ny]
    if margin is None:
        margin = 1.0 + 0.01 * ((x_hi - x_lo) + (y_hi - y_lo))
    margin = np.broadcast_to(np.asarray(margin, np.float64), (n,))
    own = np.repeat(np.arange(n), nx * ny)
    j = _ramp(nx * ny)
    ix, iy = j // ny[own], j % ny[own]  # column by column
    a0 = np.where(ix == 0, x_lo[own] - margin[own], xs[xstart[own] + ix])
    a1 = np.where(ix == nx[own] - 1, x_hi[own] + margin[own], xs[xstart[own] + ix + 1])
    b0 = np.where(iy == 0, y_lo[own] - margin[own], ys[ystart[own] + iy])
    b1 = np.where(iy == ny[own] - 1, y_hi[own] + margin[own], ys[ystart[own] + iy + 1])
    c = float(clearance)
    # cells farther than the clearance from every ring are wholly inside or wholly outside: their centre
    # tells which (numpy and one point test each); only the cells near a ring see GEOS's box predicates
    near = _near_rings(geoms, center, axis, xs, nx, ys, ny, c)
    inside = np.zeros(len(own), bool)
    edge = np.zeros(len(own), bool)
    far = np.flatnonzero(~near)
    nr = np.flatnonzero(near)
    fresh = geoms[~shapely.is_prepared(geoms)]  # the caller's own preparations stay as they are
    shapely.prepare(fresh)
    try:
        mid = _frame_points(center[own[far]], axis[own[far]], (a0[far] + a1[far]) / 2, (b0[far] + b1[far]) / 2)
        inside[far] = shapely.contains_xy(geoms[own[far]], mid[:, 0], mid[:, 1])
        boxes_nr = _boxes(center[own[nr]], axis[own[nr]], a0[nr], a1[nr], b0[nr], b1[nr])
        held = shapely.contains_properly(geoms[own[nr]], boxes_nr)
        if c > 0:  # a box the geometry holds, grown by the clearance (only those: a grown box held is held too)
            s = nr[held]
            grown = _boxes(center[own[s]], axis[own[s]], a0[s] - c, a1[s] + c, b0[s] - c, b1[s] + c)
            inside[s] = shapely.contains_properly(geoms[own[s]], grown)
            edge[s] = ~inside[s]  # held, but too near a ring: on the outline's side
        else:
            inside[nr[held]] = True
        # the others near a ring are clipped: the clip is empty for one that misses the geometry (on whole
        # Liège every one of them meets it, and a GEOS intersects test of each cost more than it saved)
        edge[nr[~held]] = True
    finally:
        shapely.destroy_prepared(fresh)
    cells = np.full(len(own), None, dtype=object)
    cells[nr] = boxes_nr
    fi = far[inside[far]]
    cells[fi] = _boxes(center[own[fi]], axis[own[fi]], a0[fi], a1[fi], b0[fi], b1[fi])
    cells[~inside] = None
    e = np.flatnonzero(edge)
    # outline cells: the geometry clipped to each column holding one, then that column to the cell
    col = own[e] * (int(nx.max()) + 1) + ix[e]
    ucol, first, back = np.unique(col, return_index=True, return_inverse=True)
    f = e[first]
    strips = _clip_strips(
        geoms, own[f], center, axis, a0[f], a1[f], y_lo[own[f]] - margin[own[f]], y_hi[own[f]] + margin[own[f]]
    )
    cells[e] = clip_frame_boxes(strips[back], center[own[e]], axis[own[e]], a0[e], a1[e], b0[e], b1[e])
    live = inside | edge
    live[e] &= ~shapely.is_empty(cells[e])
    whole = inside.copy()  # an outline cell the clip left whole (it touches the outline at most)
    whole[e] = shapely.area(cells[e]) >= (1.0 - 1e-9) * (a1[e] - a0[e]) * (b1[e] - b0[e])
    # GEOS's rectangle clip gives the whole rectangle back when it lies in a hole whose ring it only
    # touches: a whole outline cell whose centre is off the geometry is such a cell, and no lot
    w = e[whole[e]]
    if len(w):
        mid = np.stack([(a0[w] + a1[w]) / 2, (b0[w] + b1[w]) / 2], axis=1)
        xy = center[own[w]] + mid[:, :1] * axis[own[w]] + mid[:, 1:] * np.stack([-axis[own[w], 1], axis[own[w], 0]], 1)
        off = ~shapely.intersects_xy(geoms[own[w]], xy[:, 0], xy[:, 1])
        live[w[off]] = False
    return cells[live], own[live], ix[live], iy[live], inside[live], whole[live]


def _clip_strips(geoms, which, center, axis, a0, a1, b0, b1):
    """``clip_frame_boxes(geoms[which], center[which], axis[which], a0, a1, b0, b1)``, the same pieces, faster.

    A block cut into many columns was copied whole into each column's frame
    before GEOS clipped it.  Here a polygon's vertices are mapped into each
    rectangle's unit square in numpy (the same arithmetic), and a vertex that
    lies, with both its neighbours on the ring, beyond the same side of the
    rectangle is left out: the ring then takes the chord between the first and
    last vertices of that run, in the same open half-plane, so no edge that
    meets the rectangle changes, nor the ring's winding round any point of it,
    and GEOS's rectangle clipper gives the same pieces from the fewer
    vertices.  A ring's highest vertex and its neighbours stay (GEOS
    orients a ring there).  A ring left under four vertices is kept whole.  Geometries
    other than polygons go through :func:`clip_frame_boxes` as they are.
    """
    which = np.asarray(which, np.int64)
    k = len(which)
    a0, a1, b0, b1 = np.broadcast_arrays(*(np.asarray(x, np.float64) for x in (a0, a1, b0, b1)))
    out = np.empty(k, dtype=object)
    if k == 0:
        return out
    used = np.unique(which)
    is_poly = np.zeros(len(geoms), bool)
    is_poly[used] = shapely.get_type_id(geoms[used]) == shapely.GeometryType.POLYGON
    poly = is_poly[which]
    other = np.flatnonzero(~poly)
    if len(other):
        w = which[other]
        out[other] = clip_frame_boxes(geoms[w], center[w], axis[w], a0[other], a1[other], b0[other], b1[other])
    sel = np.flatnonzero(poly)
    if len(sel) == 0:
        return out
    w = which[sel]
    up = np.flatnonzero(is_poly)
    # each polygon's coordinates once, ring by ring (shell first): ring and polygon offsets
    coords, (ring_off, poly_off) = shapely.to_ragged_array(geoms[up])[1:]
    slot = np.full(len(geoms), -1, np.int64)
    slot[up] = np.arange(len(up))
    s = slot[w]
    # each vertex's frame coordinates (m) once per polygon: its strips differ only by their rectangles
    npt = np.diff(ring_off[poly_off])
    gi = np.repeat(up, npt)
    q = coords - center[gi]
    nrm = np.stack([-axis[:, 1], axis[:, 0]], axis=1)
    pu, pv = np.einsum("ij,ij->i", q, axis[gi]), np.einsum("ij,ij->i", q, nrm[gi])
    nring = np.diff(poly_off)[s]  # rings of each strip's polygon
    r = np.repeat(poly_off[s], nring) + _ramp(nring)  # their rings, strip by strip
    rlen = np.diff(ring_off)[r]
    vi = np.repeat(ring_off[r], rlen) + _ramp(rlen)  # their vertices, ring by ring
    rid = np.repeat(np.arange(len(r)), rlen)
    cs, ax = center[w], axis[w]
    # as polygons.frame_unit_coordinates maps them
    a0, a1, b0, b1 = a0[sel], a1[sel], b0[sel], b1[sel]
    sa, sb = np.where(a1 > a0, a1 - a0, 1.0), np.where(b1 > b0, b1 - b0, 1.0)
    nv = npt[s]
    u = (pu[vi] - np.repeat(a0, nv)) / np.repeat(sa, nv)
    v = (pv[vi] - np.repeat(b0, nv)) / np.repeat(sb, nv)
    side = np.select([u < 0.0, u > 1.0, v < 0.0, v > 1.0], [1, 2, 3, 4], 0)
    first = np.r_[True, rid[1:] != rid[:-1]]
    last = np.r_[rid[1:] != rid[:-1], True]
    drop = (side != 0) & ~first & ~last
    drop[1:-1] &= (side[:-2] == side[1:-1]) & (side[2:] == side[1:-1])
    # GEOS takes a ring's orientation at its highest vertex (in the square's frame) and that vertex's
    # neighbours: they stay, so that the clipper orients the fewer vertices as it did all of them
    start = np.flatnonzero(first)
    top = v == np.repeat(np.maximum.reduceat(v, start), rlen)
    near_top = top.copy()
    near_top[1:] |= top[:-1]
    near_top[:-1] |= top[1:]
    wrap = np.flatnonzero(first & top)  # the first vertex is the last: its neighbour before is the one before last
    near_top[np.flatnonzero(last)[rid[wrap]] - 1] = True
    drop &= ~near_top
    kept = np.bincount(rid, weights=~drop, minlength=len(r)).astype(np.int64)
    drop &= (kept >= 4)[rid]
    kept = np.bincount(rid, weights=~drop, minlength=len(r)).astype(np.int64)
    offsets = (np.r_[0, np.cumsum(kept)], np.r_[0, np.cumsum(nring)])
    keep = ~drop
    local = shapely.from_ragged_array(shapely.GeometryType.POLYGON, np.stack([u[keep], v[keep]], axis=1), offsets)
    out[sel] = clip_unit_local(geoms[w], local, cs, ax, a0, a1, b0, b1)
    return out


def _frame_points(center, axis, a, b):
    """Points ``a`` along ``axis`` and ``b`` along its left normal from ``center`` (world coordinates)."""
    nrm = np.stack([-axis[:, 1], axis[:, 0]], axis=1)
    return center + a[:, None] * axis + b[:, None] * nrm


def _grouped_count(edges, start, count, group, value, span, *, strict):
    """For each query, how many of its group's sorted ``edges[start : start + count]`` are below ``value``.

    ``strict``: below (``<``); else at most (``<=``).  One ``searchsorted``
    over all groups: each group's edges and queries are shifted by a
    multiple of ``span``, more than twice every value's magnitude (a value
    is then compared to within ``span * groups * 2**-52``).
    """
    if len(value) == 0:
        return np.zeros(0, np.int64)
    ng = len(start)
    eg = np.repeat(np.arange(ng), count)
    shifted = edges + eg * span
    pos = np.searchsorted(shifted, value + group * span, side="left" if strict else "right")
    return np.clip(pos - start[group], 0, count[group])


def _near_rings(geoms, center, axis, xs, nx, ys, ny, clearance):
    """Cells (column by column, as :func:`clip_frame_grid` numbers them) within ``clearance`` of a ring.

    Conservative: each ring segment marks the cells its bounding box in the
    frame, grown by the clearance and a tolerance, meets column by column
    (the segment clipped to the column's extent), so every cell it comes
    within ``clearance`` of is marked (and a few more).
    """
    n = len(geoms)
    parts, pidx = shapely.get_parts(shapely.boundary(geoms), return_index=True)
    xy, ci = shapely.get_coordinates(parts, return_index=True)
    e = np.flatnonzero(ci[1:] == ci[:-1])
    g = pidx[ci[e]]
    nrm = np.stack([-axis[:, 1], axis[:, 0]], axis=1)
    q0, q1 = xy[e] - center[g], xy[e + 1] - center[g]
    u0, u1 = np.einsum("ij,ij->i", q0, axis[g]), np.einsum("ij,ij->i", q1, axis[g])
    v0, v1 = np.einsum("ij,ij->i", q0, nrm[g]), np.einsum("ij,ij->i", q1, nrm[g])
    # the tolerance: far above the rounding of frame coordinates (1 um) and of the shifted searches
    scale = max(float(np.abs(xs).max()) if len(xs) else 0.0, float(np.abs(ys).max()) if len(ys) else 0.0, 1.0)
    span = 4.0 * (scale + clearance + 1.0)  # queries lie within the grid's extent grown by r (< 1 m)
    r = clearance + 1e-6 + 8.0 * span * max(n, 1) * np.finfo(np.float64).eps
    # inner edges of each grid (the outer cells reach out without end)
    xstart = np.cumsum(nx + 1) - (nx + 1)
    kx = np.repeat(np.arange(n), nx + 1)
    ky = np.repeat(np.arange(n), ny + 1)
    jx = _ramp(nx + 1)
    jy = _ramp(ny + 1)
    ex = xs[(jx > 0) & (jx < nx[kx])]
    ey = ys[(jy > 0) & (jy < ny[ky])]
    nex, ney = np.maximum(nx - 1, 0), np.maximum(ny - 1, 0)
    sx, sy = np.cumsum(nex) - nex, np.cumsum(ney) - ney
    # columns each segment's u range (grown) meets
    ulo, uhi = np.minimum(u0, u1) - r, np.maximum(u0, u1) + r
    c_lo = _grouped_count(ex, sx, nex, g, ulo, span, strict=True)
    c_hi = _grouped_count(ex, sx, nex, g, uhi, span, strict=False)
    cnt = np.maximum(c_hi - c_lo + 1, 0)
    seg = np.repeat(np.arange(len(e)), cnt)
    col = c_lo[seg] + _ramp(cnt)
    gs = g[seg]
    # the segment's part within the column (grown): its v range
    left = np.where(col > 0, xs[xstart[gs] + col] - r, -np.inf)
    right = np.where(col < nx[gs] - 1, xs[xstart[gs] + col + 1] + r, np.inf)
    du = u1[seg] - u0[seg]
    flat = np.abs(du) <= 1e-12 * scale
    with np.errstate(divide="ignore", invalid="ignore"):
        ta = np.where(flat, 0.0, (left - u0[seg]) / np.where(flat, 1.0, du))
        tb = np.where(flat, 1.0, (right - u0[seg]) / np.where(flat, 1.0, du))
    t0 = np.clip(np.minimum(ta, tb), 0.0, 1.0)
    t1 = np.clip(np.maximum(ta, tb), 0.0, 1.0)
    dv = v1[seg] - v0[seg]
    va, vb = v0[seg] + t0 * dv, v0[seg] + t1 * dv
    vlo, vhi = np.minimum(va, vb) - r, np.maximum(va, vb) + r
    r_lo = _grouped_count(ey, sy, ney, gs, vlo, span, strict=True)
    r_hi = _grouped_count(ey, sy, ney, gs, vhi, span, strict=False)
    rc = np.maximum(r_hi - r_lo + 1, 0)
    row = np.repeat(r_lo, rc) + _ramp(rc)
    cstart = np.cumsum(nx * ny) - nx * ny
    pair = np.repeat(np.arange(len(seg)), rc)
    near = np.zeros(int((nx * ny).sum()), bool)
    near[cstart[gs[pair]] + col[pair] * ny[gs[pair]] + row] = True
    return near


def _boxes(center, axis, a0, a1, b0, b1):
    """:func:`sengine.geom.polygons.frame_boxes`, built through shapely's ragged-array path (faster)."""
    k = len(a0)
    nrm = np.stack([-axis[:, 1], axis[:, 0]], axis=1)
    a = np.stack([a0, a1, a1, a0, a0], axis=1)[:, :, None]
    b = np.stack([b0, b0, b1, b1, b0], axis=1)[:, :, None]
    xy = (center[:, None, :] + a * axis[:, None, :] + b * nrm[:, None, :]).reshape(-1, 2)
    offsets = (np.arange(k + 1) * 5, np.arange(k + 1))
    return shapely.from_ragged_array(shapely.GeometryType.POLYGON, xy, offsets)


def box_pairs(lo_a, hi_a, lo_b, hi_b, *, group_a=None, group_b=None, cell=None):
    """Pairs of boxes that meet (closed), one of ``a`` and one of ``b`` of the same group, found on a grid.

    The pairs ``shapely.STRtree(boxes_b).query(boxes_a)`` gives (envelopes
    that intersect or touch), as a set, without making a GEOS box or tree:
    each box is listed in the square cells of side ``cell`` its extent
    meets, boxes of ``a`` and ``b`` are joined on (group, cell) by one sort,
    and a pair is kept in one cell only, the one holding the corner where
    the two boxes' lower ends meet (``max`` of their lows), which both
    boxes' cells include when they meet.

    Parameters
    ----------
    lo_a, hi_a : ndarray (n, 2)
        Lower and upper corners of the boxes of ``a`` (m); NaN (the bounds
        of an empty geometry): a box that meets nothing.
    lo_b, hi_b : ndarray (m, 2)
        Those of ``b``.
    group_a, group_b : ndarray of int, optional
        Only boxes of one group pair up (default: all one group).
    cell : float, optional
        Side of the grid's cells (m; default: twice the median extent of
        the boxes of ``a``; never under a 256th of the largest box nor a
        4096th of the whole extent).  Any size gives the same pairs; it sets
        the cost only.

    Returns
    -------
    ia, ib : ndarray of int64
        The pairs, ``ia`` non-decreasing (then ``ib`` by cell and number: an
        order fixed by the input, not by the tree STRtree builds).
    """
    lo_a, hi_a = np.asarray(lo_a, np.float64).reshape(-1, 2), np.asarray(hi_a, np.float64).reshape(-1, 2)
    lo_b, hi_b = np.asarray(lo_b, np.float64).reshape(-1, 2), np.asarray(hi_b, np.float64).reshape(-1, 2)
    na, nb = len(lo_a), len(lo_b)
    e64 = np.zeros(0, np.int64)
    if na == 0 or nb == 0:
        return e64, e64
    ga = np.zeros(na, np.int64) if group_a is None else np.asarray(group_a, np.int64)
    gb = np.zeros(nb, np.int64) if group_b is None else np.asarray(group_b, np.int64)
    fa = np.isfinite(lo_a).all(axis=1) & np.isfinite(hi_a).all(axis=1)
    fb = np.isfinite(lo_b).all(axis=1) & np.isfinite(hi_b).all(axis=1)
    if not (fa.all() and fb.all()):  # boxes of empty geometries (NaN) meet nothing, as in a tree
        ka, kb = np.flatnonzero(fa), np.flatnonzero(fb)
        ia, ib = box_pairs(lo_a[ka], hi_a[ka], lo_b[kb], hi_b[kb], group_a=ga[ka], group_b=gb[kb], cell=cell)
        return ka[ia], kb[ib]
    gmin = min(int(ga.min()), int(gb.min()))
    ng = max(int(ga.max()), int(gb.max())) - gmin + 1
    if ng > 1 << 20:  # many groups or far apart: numbered 0 .. G-1
        groups, inv = np.unique(np.r_[ga, gb], return_inverse=True)
        ga, gb, ng = inv[:na].astype(np.int64), inv[na:].astype(np.int64), len(groups)
    else:
        ga, gb = ga - gmin, gb - gmin
    if cell is None:
        cell = 2.0 * float(np.median((hi_a - lo_a).max(axis=1)))
    origin = np.minimum(lo_a.min(axis=0), lo_b.min(axis=0))
    size = np.maximum(hi_a.max(axis=0), hi_b.max(axis=0)) - origin
    # keys (group, column, row) fit in 62 bits: at most `side` cells a side
    side = max(int(np.sqrt(2.0**62 / ng)) - 2, 1)
    # and no box in more than 256 x 256 cells, nor the extent more than 4096 cells a side
    big = max(float((hi_a - lo_a).max()), float((hi_b - lo_b).max()))
    cell = max(float(cell), float(size.max()) / min(side, 4096), big / 256.0, 1e-9)
    ncell = int(np.floor(float(size.max()) / cell)) + 2

    def index(p):
        return np.floor((p - origin) / cell).astype(np.int64)

    def key(g, x, y):
        return (g * ncell + x) * ncell + y

    def listed(lo, hi, g):
        c0, c1 = index(lo), index(hi)
        cx, cy = c1[:, 0] - c0[:, 0] + 1, c1[:, 1] - c0[:, 1] + 1
        cnt = cx * cy
        box = np.repeat(np.arange(len(lo)), cnt)
        j = _ramp(cnt)
        return box, key(g[box], c0[box, 0] + j // cy[box], c0[box, 1] + j % cy[box])

    box_a, key_a = listed(lo_a, hi_a, ga)
    box_b, key_b = listed(lo_b, hi_b, gb)
    o = np.argsort(key_b, kind="stable")
    key_b, box_b = key_b[o], box_b[o]
    first = np.searchsorted(key_b, key_a, side="left")
    cnt = np.searchsorted(key_b, key_a, side="right") - first
    at = np.repeat(np.arange(len(key_a)), cnt)  # the cell entry of a each pair comes from
    ia = box_a[at]
    ib = box_b[np.repeat(first, cnt) + _ramp(cnt)]
    # boxes that meet, and only in the cell of the corner where their lower ends meet
    xa, xb = lo_a[:, 0][ia], lo_b[:, 0][ib]
    meet = (xa <= hi_b[:, 0][ib]) & (xb <= hi_a[:, 0][ia])
    at, ia, ib, xa, xb = at[meet], ia[meet], ib[meet], xa[meet], xb[meet]
    ya, yb = lo_a[:, 1][ia], lo_b[:, 1][ib]
    meet = (ya <= hi_b[:, 1][ib]) & (yb <= hi_a[:, 1][ia])
    at, ia, ib = at[meet], ia[meet], ib[meet]
    cx = np.floor((np.maximum(xa[meet], xb[meet]) - origin[0]) / cell).astype(np.int64)
    cy = np.floor((np.maximum(ya[meet], yb[meet]) - origin[1]) / cell).astype(np.int64)
    once = key_a[at] == key(ga[ia], cx, cy)
    return ia[once], ib[once]


def box_self_pairs(lo, hi, *, group=None, cell=None):
    """Pairs ``i < j`` of boxes of one set that meet (closed), of the same group, found on a grid.

    ``box_pairs(lo, hi, lo, hi, group_a=group, group_b=group)`` with the
    pairs ``i < j`` kept, in the same order (``i`` non-decreasing, then by
    cell and number), for half the work: each box is listed in its cells
    once, and within a cell only the boxes after it (by number) are paired
    with it, so no pair comes both ways round and no box meets itself.

    Parameters
    ----------
    lo, hi : ndarray (n, 2)
        Lower and upper corners of the boxes (m); NaN: a box that meets nothing.
    group : ndarray of int, optional
        Only boxes of one group pair up (default: all one group).
    cell : float, optional
        Side of the grid's cells (m; see :func:`box_pairs`): sets the cost only.

    Returns
    -------
    i, j : ndarray of int64
        The pairs, ``i < j``.
    """
    lo, hi = np.asarray(lo, np.float64).reshape(-1, 2), np.asarray(hi, np.float64).reshape(-1, 2)
    n = len(lo)
    e64 = np.zeros(0, np.int64)
    if n == 0:
        return e64, e64
    g = np.zeros(n, np.int64) if group is None else np.asarray(group, np.int64)
    fin = np.isfinite(lo).all(axis=1) & np.isfinite(hi).all(axis=1)
    if not fin.all():  # boxes of empty geometries (NaN) meet nothing
        k = np.flatnonzero(fin)
        i, j = box_self_pairs(lo[k], hi[k], group=g[k], cell=cell)
        return k[i], k[j]
    gmin = int(g.min())
    ng = int(g.max()) - gmin + 1
    if ng > 1 << 20:  # many groups or far apart: numbered 0 .. G-1
        groups, inv = np.unique(g, return_inverse=True)
        g, ng = inv.astype(np.int64).ravel(), len(groups)
    else:
        g = g - gmin
    if cell is None:
        cell = 2.0 * float(np.median((hi - lo).max(axis=1)))
    origin = lo.min(axis=0)
    size = hi.max(axis=0) - origin
    side = max(int(np.sqrt(2.0**62 / ng)) - 2, 1)  # as box_pairs: the same cells
    big = float((hi - lo).max())
    cell = max(float(cell), float(size.max()) / min(side, 4096), big / 256.0, 1e-9)
    ncell = int(np.floor(float(size.max()) / cell)) + 2
    c0 = np.floor((lo - origin) / cell).astype(np.int64)
    c1 = np.floor((hi - origin) / cell).astype(np.int64)
    cx, cy = c1[:, 0] - c0[:, 0] + 1, c1[:, 1] - c0[:, 1] + 1
    cnt = cx * cy
    box = np.repeat(np.arange(n), cnt)
    j = _ramp(cnt)
    key = (g[box] * ncell + c0[box, 0] + j // cy[box]) * ncell + c0[box, 1] + j % cy[box]
    o = np.argsort(key, kind="stable")  # within a cell, boxes by number
    key, box = key[o], box[o]
    after = np.searchsorted(key, key, side="right") - np.arange(1, len(key) + 1)  # later entries of its cell
    at = np.repeat(np.arange(len(key)), after)
    ia, ib = box[at], box[at + 1 + _ramp(after)]
    # boxes that meet, and only in the cell of the corner where their lower ends meet
    xa, xb = lo[ia, 0], lo[ib, 0]
    meet = (xa <= hi[ib, 0]) & (xb <= hi[ia, 0])
    at, ia, ib, xa, xb = at[meet], ia[meet], ib[meet], xa[meet], xb[meet]
    ya, yb = lo[ia, 1], lo[ib, 1]
    meet = (ya <= hi[ib, 1]) & (yb <= hi[ia, 1])
    at, ia, ib = at[meet], ia[meet], ib[meet]
    gx = np.floor((np.maximum(xa[meet], xb[meet]) - origin[0]) / cell).astype(np.int64)
    gy = np.floor((np.maximum(ya[meet], yb[meet]) - origin[1]) / cell).astype(np.int64)
    once = key[at] == (g[ia] * ncell + gx) * ncell + gy
    at, ia, ib = at[once], ia[once], ib[once]
    o = np.lexsort((ib, key[at], ia))  # box_pairs' order: by first box, its cells in order, second box
    return ia[o], ib[o]

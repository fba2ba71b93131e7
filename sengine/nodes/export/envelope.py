"""Closed solids under a lower envelope of planes: shed, gable, hip and pyramid roofs.

A roof over a convex footprint is the graph of a concave, piecewise linear
height function: the lowest of a few planes.  For a convex polygon the
straight-skeleton hip roof is exactly the lowest of the planes rising at one
pitch from each edge [1]_; a gable keeps only the planes of the edges along the
ridge (its ends become walls); a pyramid tilts each edge plane to meet the
others at one apex; a shed is a single plane.  Any footprint (concave, with
holes) takes a single plane or two planes meeting at a ridge.

The mesh is built for many footprints at once, in numpy passes:

1. every footprint is triangulated (:func:`sengine.nodes.export.mesh.triangulate`);
2. each triangle is cut by every line on which two of its footprint's planes
   are equal (the hips and ridges lie on those lines), one line at a time; an
   edge crossing a line gets one new vertex keyed by the edge's two end
   vertices, so both triangles beside an edge, and the footprint's boundary,
   share it: the surface stays watertight, without any tolerance merging;
3. every vertex is lifted to the envelope (each cut piece lies under one
   plane, so each triangle is planar), scaled to the roof height;
4. each footprint edge becomes a convex wall polygon (bottom edge, roof line on
   top) fanned from its first bottom corner; the floor is the footprint's
   triangulation turned down.

References
----------
.. [1] Aichholzer, O., Aurenhammer, F., Alberts, D., Gärtner, B., "A novel type
   of skeleton for polygons", Journal of Universal Computer Science 1(12),
   752-761, 1995.
"""

from __future__ import annotations

import numpy as np

from .mesh import Rings, triangulate, unique_int

__all__ = ["envelope_solids"]

#: Distance (m) under which a vertex counts as lying on a cut line.
ON_LINE = 1e-7


def envelope_solids(
    rings: Rings,
    planes: np.ndarray,
    eave: np.ndarray,
    rise: np.ndarray,
    base: np.ndarray,
    bounds: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Solids whose roofs are the lower envelope of planes, one per polygon of ``rings``.

    Parameters
    ----------
    rings : Rings
        Footprints (m), exteriors counter-clockwise, holes clockwise.
    planes : numpy.ndarray, shape (p, k, 3)
        Per polygon, ``k`` planes ``h = a x + b y + c`` in coordinates relative
        to the polygon's first vertex; unused slots hold ``c = inf``.
    eave : numpy.ndarray, shape (p,)
        Height (m) of the lowest roof point, where the walls stop.
    rise : numpy.ndarray, shape (p,)
        Height (m) from the lowest to the highest roof point.
    base : numpy.ndarray, shape (p,)
        Ground height (m).
    bounds : numpy.ndarray, shape (p, e, 3), optional
        For convex footprints: half-planes ``a x + b y + c >= 0`` whose
        intersection is the footprint (unused slots ``c = inf``).  A line on
        which two planes are equal is then cut only where those two are the
        lowest inside the footprint (a hip, a ridge), not along its whole
        length: a rectangle's hip roof keeps 8 roof triangles, not 20.

    Returns
    -------
    vertices : numpy.ndarray, shape (v, 3)
    faces : numpy.ndarray of int64, shape (f, 3)
        Counter-clockwise seen from outside.
    vertex_poly : numpy.ndarray of int64, shape (v,)
        Polygon of each vertex.
    face_kind : numpy.ndarray of uint8, shape (f,)
        0 ground, 1 wall, 2 roof.
    """
    m = len(rings.xy)
    if m == 0:
        return np.empty((0, 3)), np.empty((0, 3), np.int64), np.empty(0, np.int64), np.empty(0, np.uint8)
    vpoly0 = rings.vertex_poly()
    origin = rings.xy[rings.ring_start[rings.poly_ring[:-1]]]
    tri0 = triangulate(rings)
    # boundary edges, in ring order; each keeps the id of the footprint edge it is part of
    nxt = rings.next_vertex()
    bnd = np.column_stack([np.arange(m), nxt])
    borig = np.arange(m)
    xy = [rings.xy]
    vpoly = [vpoly0]
    rels = [rings.xy - origin.take(vpoly0, axis=0)]  # relative to the polygon's first vertex, kept as they grow
    tri = tri0.copy()
    k = planes.shape[1]
    valid = np.isfinite(planes[:, :, 2])
    nverts = m
    if bounds is not None:  # the footprint's half-planes, unused slots zero: the same for every line
        bounds = np.where(np.isfinite(bounds[:, :, 2])[:, :, None], bounds, 0.0)
    for i in range(k):
        for j in range(i + 1, k):
            both = valid[:, i] & valid[:, j]
            if not both.any():
                continue
            line = planes[:, i] - planes[:, j]
            norm = np.hypot(line[:, 0], line[:, 1])
            use = both & (norm > 1e-12)
            if not use.any():
                continue
            line = np.where(use[:, None], line / np.where(norm > 0, norm, 1.0)[:, None], 0.0)
            if bounds is not None:
                use &= _lowest_somewhere(planes, valid, bounds, line, i, j)
                if not use.any():
                    continue
            allxy = np.concatenate(xy) if len(xy) > 1 else xy[0]
            allpoly = np.concatenate(vpoly) if len(vpoly) > 1 else vpoly[0]
            rel = np.concatenate(rels) if len(rels) > 1 else rels[0]
            xy, vpoly, rels = [allxy], [allpoly], [rel]
            s = line[:, 0].take(allpoly) * rel[:, 0] + line[:, 1].take(allpoly) * rel[:, 1] + line[:, 2].take(allpoly)
            s[~use[allpoly]] = 0.0
            sg = (s > ON_LINE).view(np.int8) - (s < -ON_LINE).view(np.int8)
            tri, bnd, borig, new_xy, new_poly = _cut(tri, bnd, borig, allxy, allpoly, s, sg, nverts)
            if len(new_xy):
                xy.append(new_xy)
                vpoly.append(new_poly)
                rels.append(new_xy - origin.take(new_poly, axis=0))
                nverts += len(new_xy)
    allxy = np.concatenate(xy)
    allpoly = np.concatenate(vpoly)
    # lift: the lowest plane, scaled so the roof rises from eave to eave + rise (one plane at a time)
    rel = np.concatenate(rels)
    h = np.full(len(allpoly), np.inf)
    for i in range(k):
        pl = planes[:, i].take(allpoly, axis=0)
        hi_ = pl[:, 0] * rel[:, 0] + pl[:, 1] * rel[:, 1] + pl[:, 2]
        np.minimum(h, np.where(valid[:, i].take(allpoly), hi_, np.inf), out=h)
    n_poly = rings.n_polys
    lo = np.full(n_poly, np.inf)
    hi = np.full(n_poly, -np.inf)
    np.minimum.at(lo, allpoly, h)
    np.maximum.at(hi, allpoly, h)
    span = hi - lo
    frac = np.where(span[allpoly] > 1e-12, (h - lo[allpoly]) / np.where(span > 1e-12, span, 1.0)[allpoly], 0.0)
    z_top = eave[allpoly] + rise[allpoly] * frac
    n_top = len(allxy)
    vertices = np.concatenate(
        [np.column_stack([allxy, z_top]), np.column_stack([rings.xy, base[vpoly0]])]
    )  # top (roof, wall tops) then bottom ring
    bottom = n_top + np.arange(m)
    # walls: per footprint edge p -> q with pieces (u, w) in order from p to q
    p_b = bottom[borig]  # bottom of the footprint edge's first vertex
    q_b = bottom[nxt[borig]]
    first = np.ones(len(borig), bool)
    first[1:] = borig[1:] != borig[:-1]
    walls = [
        np.column_stack([p_b[first], q_b[first], nxt[borig[first]]]),  # (p_b, q_b, q_top)
        np.column_stack([p_b, bnd[:, 1], bnd[:, 0]]),  # (p_b, w_top, u_top)
    ]
    wall = np.concatenate(walls)
    floor = tri0[:, [0, 2, 1]] + n_top
    faces = np.concatenate([floor, wall, tri]).astype(np.int64)
    kind = np.concatenate(
        [np.zeros(len(floor), np.uint8), np.ones(len(wall), np.uint8), np.full(len(tri), 2, np.uint8)]
    )
    return vertices, faces, np.concatenate([allpoly, vpoly0]), kind


def _lowest_somewhere(planes, valid, bounds, line, i: int, j: int) -> np.ndarray:
    """Per polygon: whether planes i and j are the lowest along a piece of their equality line inside ``bounds``.

    A one-dimensional linear programme along the line ``x(t) = x0 + t d``:
    every other plane stays above plane i, every bound stays non-negative.
    ``bounds``: the half-planes with their unused slots zero.
    """
    a, b, c = line[:, 0], line[:, 1], line[:, 2]
    x0 = np.column_stack([-a * c, -b * c])  # the line's point nearest the origin (|(a, b)| = 1)
    d = np.column_stack([-b, a])
    pi = planes[:, i]
    diff = planes - pi[:, None, :]  # h_k - h_i >= 0
    cons = [np.where(valid[:, :, None], diff, 0.0)]
    cons.append(bounds)
    g = np.concatenate(cons, axis=1)
    alpha = g[:, :, 0] * d[:, None, 0] + g[:, :, 1] * d[:, None, 1]
    beta = g[:, :, 0] * x0[:, None, 0] + g[:, :, 1] * x0[:, None, 1] + g[:, :, 2]
    tol = 1e-9
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -beta / alpha
    lo = np.where(alpha > tol, t, -np.inf).max(axis=1)
    hi = np.where(alpha < -tol, t, np.inf).min(axis=1)
    flat_ok = np.where(np.abs(alpha) <= tol, beta >= -1e-9, True).all(axis=1)
    return flat_ok & (hi - lo > 1e-6)


def _cut(tri, bnd, borig, xy, vpoly, s, sg, nverts):
    """Cut triangles and boundary edges by the zero line of ``s``; return them and the new vertices."""
    # side bits of each vertex (1 above the line, 2 below): a triangle crosses when its three have both
    bit = (sg > 0).view(np.uint8) | ((sg < 0).view(np.uint8) << 1)
    cross = (bit[tri[:, 0]] | bit[tri[:, 1]] | bit[tri[:, 2]]) == 3
    bcross = (bit[bnd[:, 0]] | bit[bnd[:, 1]]) == 3
    if not cross.any() and not bcross.any():
        return tri, bnd, borig, np.empty((0, 2)), np.empty(0, np.int64)
    ct = tri.compress(cross, axis=0)
    cs = sg[ct]
    zero = cs == 0
    one_zero = zero.sum(axis=1) == 1
    # the special corner: the vertex on the line (one_zero), else the one alone on its side
    lone = np.where(
        (cs[:, 0] != cs[:, 1]) & (cs[:, 0] != cs[:, 2]),
        0,
        np.where((cs[:, 1] != cs[:, 0]) & (cs[:, 1] != cs[:, 2]), 1, 2),
    )
    special = np.where(one_zero, np.argmax(zero, axis=1), lone)
    roll = (special[:, None] + np.arange(3)) % 3
    r = np.take_along_axis(ct, roll, axis=1)
    v0, v1, v2 = r[:, 0], r[:, 1], r[:, 2]
    # crossing edges: (v1, v2) for one_zero; (v0, v1) and (v2, v0) otherwise; and the boundary's
    oz, tz = one_zero, ~one_zero
    bc = bnd.compress(bcross, axis=0)
    ea = np.concatenate([v1[oz], v0[tz], v2[tz], bc[:, 0]])
    eb = np.concatenate([v2[oz], v1[tz], v0[tz], bc[:, 1]])
    lo_, hi_ = np.minimum(ea, eb), np.maximum(ea, eb)
    key = lo_ * (1 << 31) + hi_
    ukey, inv = unique_int(key, return_inverse=True)
    p, q = ukey // (1 << 31), ukey % (1 << 31)
    t = s[p] / (s[p] - s[q])
    xp = xy.take(p, axis=0)
    new_xy = xp + t[:, None] * (xy.take(q, axis=0) - xp)
    new_poly = vpoly[p]
    ids = nverts + inv
    n1, n2 = int(oz.sum()), int(tz.sum())
    m_oz = ids[:n1]
    m01 = ids[n1 : n1 + n2]
    m20 = ids[n1 + n2 : n1 + 2 * n2]
    m_b = ids[n1 + 2 * n2 :]
    a0, a1, a2 = v0[oz], v1[oz], v2[oz]
    b0, b1, b2 = v0[tz], v1[tz], v2[tz]
    pieces = [
        tri.compress(~cross, axis=0),
        np.column_stack([a0, a1, m_oz]),
        np.column_stack([a0, m_oz, a2]),
        np.column_stack([b0, m01, m20]),
        np.column_stack([m01, b1, b2]),
        np.column_stack([m01, b2, m20]),
    ]
    tri = np.concatenate(pieces)
    if bcross.any():
        counts = np.where(bcross, 2, 1)
        nb = np.repeat(bnd, counts, axis=0)
        norig = np.repeat(borig, counts)
        pos_first = np.cumsum(counts) - counts
        f = pos_first[bcross]
        nb[f, 1] = m_b
        nb[f + 1, 0] = m_b
        bnd, borig = nb, norig
    return tri, bnd, borig, new_xy, new_poly

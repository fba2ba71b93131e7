"""Skeleton lots: street strips of a target depth cut into lots (Vanegas et al. 2012 [1]_).

The offset / straight-skeleton subdivision behind CityEngine's *skeleton*
block subdivision, for all blocks at once:

1. **Strips.** Each block is offset inwards by the target ``depth`` with a
   mitred buffer (:func:`sengine.geom.polygons.inset`): between the block's
   boundary and the offset curve lies the band of street-facing land; the
   offset polygon is the *interior*.  A mitred offset is the straight
   skeleton's wavefront at time ``depth`` [1]_ §4.1 (sides move parallel to
   themselves, corners stay sharp), so this band is the union of the
   skeleton faces cut at that depth, one per block edge.
2. **Streets.** The block's rings are cut into *streets* at vertices where
   the boundary turns by more than ``corner_angle`` (a ring without such a
   vertex is one closed street).  A convex corner of interior angle ``θ``
   keeps ``depth · cot(θ / 2)`` of street clear on each side: the strips of
   its two streets overlap there (the skeleton's corner faces, [1]_ §4.2).
3. **Cuts.** Along the rest of each street, cut positions ``lot_width_min +
   share of the remaining length`` follow one another, the shares drawn
   around 1 with a standard deviation of ``irregularity / 2`` (seeded per
   block), so lots are about ``width`` wide and never narrower than
   ``lot_width_min``.  Every cut is a ray along the street's inner normal
   ending where it first meets the offset curve or the block boundary (in a
   part of the block thinner than twice the depth, where the offset
   vanished, only one side's rays cross it: lots run through from street to
   street there, as they do in real narrow blocks).  All rays are cast at
   once against the boundary segments (an STRtree query, numpy
   intersections).
4. **Lots.** The block boundary, the offset curve and the rays are noded and
   polygonized per block (GEOS, one vectorized call each): the faces
   partition the block exactly.  The face at a corner between the last cut
   of one street and the first of the next is a *corner lot* facing both
   (``corner="merge"``), or is halved along the corner's bisector
   (``corner="split"``).  Faces of less than ``lot_area_min`` (or 1 m²), and
   with ``force_street_access`` street faces of less than ``lot_width_min``
   frontage, are merged into the neighbour they share most boundary with
   (counted).
5. **Interior.** What lies deeper than ``depth`` is by ``interior``:
   ``inner`` (left as one inner lot per offset component, flagged: the
   shared courtyard of a perimeter block; a component larger than
   ``inner_area_max`` is no courtyard but backland, e.g. the land between
   a town's last street and the edge of the extract, and is cut by the
   recursive method into inner lots under ``inner_area_max``: backland
   parcels, not one lot the size of a district),
   ``split`` (cut into inner lots under ``lot_area_max`` by the recursive
   method, flagged; every piece, those the cuts leave without an edge of
   the interior's outline too, so no compact inner lot stays larger: a
   piece no cut can halve within the method's aspect limit stays and is
   counted, ``skeleton_inner_over_max``), ``park`` (one courtyard / park lot per component,
   flagged ``park`` too) or ``merge`` (each part of the interior joins the
   street lot whose back edge is nearest, so every lot reaches a street).

Randomness is a hash of (block seed, part, street, lot), so the lots of a
block do not depend on the other blocks of the call.

References
----------
.. [1] C. A. Vanegas, T. Kelly, B. Weber, J. Halatsch, D. G. Aliaga and
   P. Müller, "Procedural Generation of Parcels in Urban Modeling",
   Computer Graphics Forum 31(2) (Proc. Eurographics 2012), pp. 681-690,
   2012.  doi:10.1111/j.1467-8659.2012.03047.x
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
import shapely

from sengine.geom.boundary import (
    polygon_parts,
    segments_on_boundary,
    segments_on_box,
    segments_on_lines,
    street_edges,
)
from sengine.geom.grid import box_pairs
from sengine.geom.polygons import inset
from sengine.geom.split import RingSet

from .contour import Marks, _scan, ramp
from .faces import _geos_faces, _graph_faces, _merge_interior, _merge_into
from .paris import _normal
from .recursive import recursive_lots

__all__ = ["skeleton_lots", "SkeletonLots", "CORNERS", "INTERIORS"]

log = logging.getLogger(__name__)

CORNERS = ("merge", "split")
INTERIORS = ("inner", "split", "merge", "park")
MARGIN = 0.5  # m: cuts keep this much more than the corner's clearance (rays do not meet at the mitre point)
SLIVER = 1.0  # m2: no lot is smaller


@dataclass
class SkeletonLots:
    """Lots of :func:`skeleton_lots`.

    Attributes
    ----------
    lots : ndarray of shapely.Polygon (k,)
    owner : ndarray of int64 (k,)
        Index of each lot's block, non-decreasing.
    inner : ndarray of bool (k,)
        Lots of the interior (no street frontage by construction).
    park : ndarray of bool (k,)
        Interior lots kept whole as a courtyard or park (``interior="park"``).
    report : dict
        Counts: ``skeleton_cuts``, ``skeleton_merged`` (faces merged into a
        neighbour: slivers, too small or without enough street),
        ``skeleton_thin`` (rays crossing a part thinner than twice the depth).
    on, known : ndarray of bool
        Which boundary segment of each lot lies on its block's boundary
        (order of :func:`sengine.geom.boundary.ring_segments`), for the lots
        ``known`` says (not for lots grown by a merge).
    """

    lots: np.ndarray
    owner: np.ndarray
    inner: np.ndarray
    park: np.ndarray
    report: dict = field(default_factory=dict)
    on: np.ndarray | None = None
    known: np.ndarray | None = None


def _after_merge(marks: Marks, faces, changed) -> Marks:
    """Marks of the faces left by a merge: a face that took in others has a new ring (another number of
    segments), so its marks are reset to unknown, keeping the flat marks aligned with every later face."""
    counts = marks.counts.copy()
    counts[changed] = Marks.unknown(faces[changed]).counts  # the others' outlines, and so counts, are as they were
    fresh = Marks(np.zeros(int(counts.sum()), bool), counts)
    fresh.flat[np.repeat(~changed, counts)] = marks.flat[np.repeat(~changed, marks.counts)]
    return fresh


def _per_block(x, n, dtype=np.float64):
    return np.broadcast_to(np.asarray(x, dtype), (n,)).copy()


# -- streets and cuts -----------------------------------------------------------------------------


def _streets(rs: RingSet, corner_angle: float, flag=None):
    """Vertices' turning angles and the street (run of edges between corners) of each edge.

    ``flag`` (per edge, optional): which edges face a street; a run also
    ends where it changes, so each run is all street or all open land.
    Returns ``turn`` (rad, > 0 convex: the rings have the interior on the
    left), ``run`` (street of each edge, edges of a street consecutive in
    ``order``), ``order`` (edges street by street, in ring order),
    ``closed`` (per street: a ring without corners).
    """
    N = len(rs.xy)
    nx = rs.next_vertex()
    prv = np.empty(N, np.int64)
    prv[nx] = np.arange(N)
    u = (rs.xy[nx] - rs.xy) / np.maximum(rs.edge_lengths(), 1e-300)[:, None]
    cr = u[prv, 0] * u[:, 1] - u[prv, 1] * u[:, 0]
    dt = np.einsum("ij,ij->i", u[prv], u)
    turn = np.arctan2(cr, dt)
    corner = np.abs(turn) > np.radians(corner_angle)
    if flag is not None:  # street meets open land: a run ends there too
        corner = corner | (flag != flag[prv])
    R = len(rs.poly)
    has = np.bincount(rs.ring[corner], minlength=R) > 0
    rstart = np.r_[0, np.cumsum(np.bincount(rs.ring, minlength=R))][:-1]
    start = corner.copy()
    start[rstart[~has & (np.bincount(rs.ring, minlength=R) > 0)]] = True  # a ring without corners: one street
    # rotate every ring to begin at its first street start
    k = np.arange(N) - rstart[rs.ring]
    first = np.full(R, np.iinfo(np.int64).max)
    np.minimum.at(first, rs.ring[start], k[start])
    nr = np.bincount(rs.ring, minlength=R)
    rot = np.mod(k - first[rs.ring], np.maximum(nr[rs.ring], 1))
    order = np.lexsort((rot, rs.ring))
    run = np.empty(N, np.int64)
    run[order] = np.cumsum(start[order]) - 1
    closed = ~has[rs.ring[order][start[order]]]
    return turn, u, run, order, closed, start


def _cuts(rs, own, d, width, lmin, amax, irregularity, seeds, corner_angle, corner, flag=None):
    """Cut rays of every street: origin, inner normal, street, edge, and whether it is a bisector.

    Runs of edges off the street (``flag`` False) get a cut at each end
    only, where they meet a street at a corner: between them lies one
    piece of land without frontage (it joins the interior).
    """
    turn, u, run, order, closed, start = _streets(rs, corner_angle, flag)
    N = len(rs.xy)
    ln = rs.edge_lengths()
    vp = rs.vertex_poly()
    S = len(closed)
    ro = run[order]
    es = np.empty(N)
    es[order] = _scan(ln[order], ro) - ln[order]  # arc of each edge's start within its street
    L = np.bincount(run, weights=ln, minlength=S)
    first_v = order[start[order]]  # start vertex of each street (a corner)
    sp = vp[first_v]  # part of each street
    # end corner: the start of the next street of the ring (cyclic)
    ring_s = rs.ring[first_v]
    nxt = np.r_[np.arange(1, S), 0]
    wrap = np.r_[ring_s[1:] != ring_s[:-1], True]
    rfirst = np.r_[0, np.flatnonzero(np.diff(ring_s)) + 1]
    ring_first_s = np.zeros(len(rs.poly), np.int64)
    ring_first_s[ring_s[rfirst]] = rfirst
    nxt[wrap] = ring_first_s[ring_s[wrap]]
    phi0 = turn[first_v]
    phi1 = turn[first_v[nxt]]
    dS, wS, lminS = d[sp], width[sp], lmin[sp]
    bend = np.abs(turn) > np.radians(corner_angle)
    cor0, cor1 = bend[first_v], bend[first_v[nxt]]  # else the run ends where street meets open land
    sflag = np.ones(S, bool) if flag is None else flag[first_v]

    def clearance(phi):
        convex = dS * np.tan(0.5 * np.minimum(phi, np.radians(170.0))) + MARGIN
        return np.where(phi > 0, convex, 0.5 * wS)

    c0 = np.where(closed | ~cor0, 0.0, clearance(phi0))
    c1 = np.where(closed | ~cor1, 0.0, clearance(phi1))
    U = L - c0 - c1
    w = np.maximum(np.minimum(wS, amax[sp] / np.maximum(dS, 1e-9)), lminS)
    m = np.floor(U / w + 0.5).astype(np.int64)
    m = np.where(U >= lminS, np.maximum(m, 1), 0)
    m = np.minimum(m, np.floor(U / np.maximum(lminS, 1e-9)).astype(np.int64) * (lminS > 0) + m * (lminS <= 0))
    m = np.maximum(m, 0)
    m = np.where(closed & (m < 2), 0, m)
    m = np.where(sflag, m, np.where(~closed & (U > MARGIN), 1, 0))  # off the street: a cut at each end
    ncut = np.where(closed, m, np.where(m > 0, m + 1, 0))
    # lot widths: lot_width_min plus a random share of the rest
    cs = np.repeat(np.arange(S), m)
    j = ramp(m)
    # key: (part's rank in its block, street's rank in its part, lot): the same in any batch
    street_rank = (np.arange(S) - np.searchsorted(sp, sp)).astype(np.uint64)
    part_rank = (np.arange(len(own)) - np.searchsorted(own, own)).astype(np.uint64)
    key = (part_rank[sp[cs]] << np.uint64(44)) + (street_rank[cs] << np.uint64(20)) + j.astype(np.uint64)
    z = np.clip(_normal(seeds[own[sp[cs]]], key), -2.5, 2.5)
    f = np.clip(1.0 + 0.5 * irregularity[sp[cs]] * z, 0.05, None)
    fs = np.bincount(cs, weights=f, minlength=S)
    wl = lminS[cs] + (U[cs] - m[cs] * lminS[cs]) * f / np.maximum(fs[cs], 1e-300)
    # cut arcs: c0 then c0 + cumulative widths (closed streets: from 0, m cuts)
    acc = _scan(wl, cs)
    cut_s = np.repeat(np.arange(S), ncut)
    cj = ramp(ncut)
    arc = c0[cut_s].copy()
    after = cj > 0
    # the cut after lot j-1 is at c0 + acc of lot j-1
    lot_index = np.repeat(np.cumsum(m) - m, ncut) + cj - 1
    arc[after] += acc[lot_index[after]]
    # find the edge of each cut: edges and cuts merged along (street, arc)
    kind = np.r_[np.zeros(N, np.int8), np.ones(len(arc), np.int8)]
    sk = np.r_[run, cut_s]
    ak = np.r_[es, arc]
    o = np.lexsort((kind, ak, sk))
    ids = np.r_[np.arange(N), np.full(len(arc), -1)][o]
    last_edge = np.maximum.accumulate(np.where(ids >= 0, np.arange(len(o)), -1))
    edge_of = np.empty(len(arc), np.int64)
    isc = kind[o] == 1
    edge_of[o[isc] - N] = ids[last_edge[isc]]
    e = edge_of
    t = np.clip(arc - es[e], 0.0, ln[e])
    toff = t.copy()
    p = rs.xy[e] + t[:, None] * u[e]
    nrm = np.stack([-u[e, 1], u[e, 0]], axis=1)
    at_v = t <= 1e-9  # a cut through a vertex: the mean of both edges' normals
    if at_v.any():
        nx = rs.next_vertex()
        prv = np.empty(N, np.int64)
        prv[nx] = np.arange(N)
        q = prv[e[at_v]]
        nb = nrm[at_v] + np.stack([-u[q, 1], u[q, 0]], axis=1)
        nrm[at_v] = nb / np.maximum(np.hypot(nb[:, 0], nb[:, 1]), 1e-300)[:, None]
    # off the street, no cut where the run meets a street in line: the street's own cut is there
    drop = ~sflag[cut_s] & (((cj == 0) & ~cor0[cut_s]) | ((cj == ncut[cut_s] - 1) & ~cor1[cut_s]))
    if drop.any():
        p, nrm, cut_s, e, toff = p[~drop], nrm[~drop], cut_s[~drop], e[~drop], toff[~drop]
    bis = np.zeros(len(p), bool)
    if corner == "split":  # the corner's bisector halves the corner lot
        cv = first_v[(~closed) & (phi0 > 0) & cor0]
        nx = rs.next_vertex()
        prv = np.empty(N, np.int64)
        prv[nx] = np.arange(N)
        bv = np.stack([-u[cv, 1], u[cv, 0]], axis=1) + np.stack([-u[prv[cv], 1], u[prv[cv], 0]], axis=1)
        bv /= np.maximum(np.hypot(bv[:, 0], bv[:, 1]), 1e-300)[:, None]
        p = np.r_[p, rs.xy[cv]]
        nrm = np.r_[nrm, bv]
        e = np.r_[e, cv]
        toff = np.r_[toff, np.zeros(len(cv))]
        cut_s = np.r_[cut_s, run[cv]]
        bis = np.r_[bis, np.ones(len(cv), bool)]
    return p, nrm, cut_s, e, bis, run, toff, sflag


def _cast(p, nrm, ray_part, reach, seg0, seg1, seg_part, seg_key, tmin=1e-6):
    """First hit of each ray ``p + t nrm`` (0 < t <= reach) on the segments of its own part.

    Returns the distance (inf for none), the key of the segment hit (-1),
    the segment hit (-1) and where along it (0 at ``seg0``, 1 at ``seg1``).
    """
    R = len(p)
    best = np.full(R, np.inf)
    key = np.full(R, -1, np.int64)
    seg = np.full(R, -1, np.int64)
    par = np.zeros(R)
    if R == 0 or len(seg0) == 0:
        return best, key, seg, par
    q = p + reach[:, None] * nrm
    # rays and segments of one part whose boxes meet (numpy, on a grid: no GEOS boxes or tree)
    ri, si = box_pairs(
        np.minimum(p, q),
        np.maximum(p, q),
        np.minimum(seg0, seg1),
        np.maximum(seg0, seg1),
        group_a=ray_part,
        group_b=seg_part,
    )
    a, b = seg0[si], seg1[si]
    ab = b - a
    n = nrm[ri]
    ap = a - p[ri]
    den = n[:, 0] * ab[:, 1] - n[:, 1] * ab[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (ap[:, 0] * ab[:, 1] - ap[:, 1] * ab[:, 0]) / den
        s = (ap[:, 0] * n[:, 1] - ap[:, 1] * n[:, 0]) / den
    ok = (den != 0) & (t > tmin) & (t <= reach[ri]) & (s >= -1e-12) & (s <= 1 + 1e-12)
    ri, si, t, s = ri[ok], si[ok], t[ok], np.clip(s[ok], 0.0, 1.0)
    # per ray (box_pairs lists them in order) the nearest hit, the lowest segment among equally near
    # ones: np.lexsort((si, t, ri))'s first of each ray, by two reductions instead of a sort
    if len(ri) == 0:
        return best, key, seg, par
    start = np.flatnonzero(np.r_[True, ri[1:] != ri[:-1]])
    grp = np.cumsum(np.r_[False, ri[1:] != ri[:-1]])
    near = t == np.minimum.reduceat(t, start)[grp]
    low = np.minimum.reduceat(np.where(near, si, np.iinfo(np.int64).max), start)
    f = np.flatnonzero(near & (si == low[grp]))
    best[ri[f]] = t[f]
    key[ri[f]] = seg_key[si[f]]
    seg[ri[f]] = si[f]
    par[ri[f]] = s[f]
    return best, key, seg, par


# -- all blocks -----------------------------------------------------------------------------------


def skeleton_lots(
    blocks,
    *,
    depth=22.0,
    width=15.0,
    lot_width_min=6.0,
    lot_area_min=20.0,
    lot_area_max=2000.0,
    inner_area_max=20000.0,
    irregularity=0.3,
    corner="merge",
    interior="inner",
    force_street_access=True,
    corner_angle=30.0,
    seeds=None,
    fronts=None,
    box=None,
) -> SkeletonLots:
    """Skeleton lots (Vanegas et al. 2012 [1]_): street strips of ``depth`` cut into lots of ``width``.

    Parameters
    ----------
    blocks : array_like of shapely.Polygon (n,)
        MultiPolygons are divided part by part.
    depth : float or array_like (n,)
        Target strip depth (m): how far lots reach from the street.
    width : float or array_like (n,)
        Target lot width along the street (m).
    lot_width_min : float or array_like (n,)
        Least street frontage of a lot (m).
    lot_area_min : float or array_like (n,)
        Lots smaller than this (m2) join a neighbour; never below 1 m2.
    lot_area_max : float or array_like (n,)
        Lots are made no wider than ``lot_area_max / depth``; inner lots are
        cut under this area (m2).
    inner_area_max : float or array_like (n,)
        ``interior="inner"``: an inner lot larger than this (m2) is backland,
        not a courtyard, and is cut by the recursive method into inner lots
        under this area (rows half its side deep, every piece cut).
    irregularity : float or array_like (n,)
        0 gives equal widths; the standard deviation of a lot's share of
        its street is ``irregularity / 2`` (1).
    corner : {"merge", "split"}
        A convex corner is one lot facing both streets, or two lots split on
        the corner's bisector.
    interior : {"inner", "split", "merge", "park"}
        What is deeper than ``depth``: one inner lot per component, inner
        lots under ``lot_area_max``, merged into the street lots, or one
        courtyard / park lot per component.
    force_street_access : bool
        Street faces with less than ``lot_width_min`` of frontage join a
        neighbour (else they stay, as inner lots).
    corner_angle : float
        A turn of the boundary by more than this (deg) ends a street.
    seeds : array_like of uint64 (n,), optional
        One seed per block; 0 when omitted.
    fronts : array_like of object (n,), optional
        Per block, the part of its boundary that faces a street (a
        (Multi)LineString, e.g. ``blocks.landuse``'s ``street_front`` where
        open land, water or a park was cut off it), or ``None``: all of it.
        Strips and lots run only along the street; the land along the rest
        (without frontage) joins the interior, so it becomes inner (rear)
        lots, not thin lots fronting onto open land.
    box : tuple of float, optional
        ``(xmin, ymin, xmax, ymax)``: block boundary on this box (the
        extract's edge that closed the land round its streets) is no street.

    Returns
    -------
    SkeletonLots

    References
    ----------
    .. [1] C. A. Vanegas, T. Kelly, B. Weber, J. Halatsch, D. G. Aliaga and
       P. Müller, "Procedural Generation of Parcels in Urban Modeling",
       Computer Graphics Forum 31(2), pp. 681-690, 2012.
    """
    if corner not in CORNERS:
        raise ValueError(f"corner={corner!r} is not one of {', '.join(CORNERS)}")
    if interior not in INTERIORS:
        raise ValueError(f"interior={interior!r} is not one of {', '.join(INTERIORS)}")
    blocks = np.asarray(blocks, dtype=object).ravel()
    n = len(blocks)
    report = {"skeleton_cuts": 0, "skeleton_merged": 0, "skeleton_thin": 0}
    empty = SkeletonLots(np.empty(0, object), np.empty(0, np.int64), np.empty(0, bool), np.empty(0, bool), report)
    if n == 0:
        return empty
    seeds = np.zeros(n, np.uint64) if seeds is None else np.asarray(seeds, np.uint64)
    d_b = _per_block(depth, n)
    w_b = _per_block(width, n)
    lmin_b = _per_block(lot_width_min, n)
    amin_b = np.maximum(_per_block(lot_area_min, n), SLIVER)
    amax_b = _per_block(lot_area_max, n)
    imax_b = _per_block(inner_area_max, n)
    irr_b = _per_block(irregularity, n)
    parts, own = polygon_parts(blocks, np.arange(n))
    rs = RingSet.from_polygons(parts)
    keep = np.bincount(rs.poly, minlength=rs.n) > 0
    rs, own, parts = rs.take(keep), own[keep], parts[keep]
    P = rs.n
    if P == 0:
        return empty
    parts = shapely.orient_polygons(parts)
    flag = street_edges(rs, own, fronts, box) if fronts is not None or box is not None else None
    # parts with land off the street: their faces without frontage join the interior
    open_part = np.zeros(P, bool) if flag is None else np.bincount(rs.vertex_poly(), ~flag, minlength=P) > 0
    d = d_b[own]
    # 1. the interior: the block offset by the depth
    core = inset(parts, d)
    cparts, cown = polygon_parts(core, np.arange(P))
    # 2-3. streets and cut rays
    p, nrm, cut_s, cut_e, bis, run, toff, sflag = _cuts(
        rs, own, d, w_b[own], lmin_b[own], amax_b[own], irr_b[own], seeds, corner_angle, corner, flag
    )
    vp = rs.vertex_poly()
    ray_part = vp[cut_e]
    rsI = RingSet.from_polygons(cparts)
    ipart = cown[rsI.vertex_poly()]
    S0 = np.r_[rs.xy, rsI.xy]
    S1 = np.r_[rs.xy[rs.next_vertex()], rsI.xy[rsI.next_vertex()]]
    spart = np.r_[vp, ipart]
    skey = np.r_[run, np.full(len(rsI.xy), -1, np.int64)]  # street of a boundary segment, -1 on the offset
    reach = 3.0 * d[ray_part] + 1.0
    t, hit, hseg, hpar = _cast(p, nrm, ray_part, reach, S0, S1, spart, skey)
    through = hit >= 0
    # a part thinner than twice the depth: only the rays of the lower street cross it (streets before
    # runs off the street)
    rank = np.where(sflag, 0, len(sflag)) + np.arange(len(sflag))
    rhit = rank[np.maximum(hit, 0)]
    keep = np.isfinite(t) & (~through | (rank[cut_s] < rhit) | ((cut_s == hit) & ~bis))
    keep |= bis & np.isfinite(t)
    report["skeleton_thin"] = int((through & keep).sum())
    p, nrm, t, ray_part = p[keep], nrm[keep], t[keep], ray_part[keep]
    cut_e, toff, hseg, hpar = cut_e[keep], toff[keep], hseg[keep], hpar[keep]
    report["skeleton_cuts"] = int(len(p))
    # 4. faces of the plane graph of block boundary, offset curve and rays
    faces, fpart, inner, ok, front, adj, marks, known = _graph_faces(
        rs, rsI, ipart, p, nrm, t, cut_e, toff, hseg, hpar, ray_part, flag
    )
    bad = np.flatnonzero(~ok)
    if len(bad):  # parts the graph could not close (overlapping blocks): GEOS noding and polygonize
        report["skeleton_geos"] = int(len(bad))
        g = _geos_faces(parts, core, cparts, cown, p, nrm, t, ray_part, bad)
        keepf = ~np.isin(fpart, bad)
        idx = np.flatnonzero(keepf)
        remap = np.full(len(faces), -1, np.int64)
        remap[idx] = np.arange(len(idx))
        sel = keepf[adj[0]] & keepf[adj[1]]
        adj = (remap[adj[0][sel]], remap[adj[1][sel]], adj[2][sel])
        faces, fpart, inner = np.r_[faces[keepf], g[0]], np.r_[fpart[keepf], g[1]], np.r_[inner[keepf], g[2]]
        marks = Marks.concat([marks.take(idx), Marks.unknown(g[0])])
        known = np.r_[known[keepf], np.zeros(len(g[0]), bool)]
        front = np.r_[front[keepf], np.zeros(len(g[0]))]
    area = shapely.area(faces)
    # frontage of the faces the graph did not give (GEOS ones), measured on the part's boundary
    unk = np.flatnonzero(front == 0) if len(bad) else np.zeros(0, np.int64)
    unk = unk[np.isin(fpart[unk], bad)]
    if len(unk):
        s0, s1, sidx, _, on = segments_on_boundary(faces[unk], fpart[unk], parts, tol=1e-5)
        if flag is not None:  # on the street only
            on &= ~segments_on_box(s0, s1, box)
            if fronts is not None and on.any():
                sel = np.flatnonzero(on)
                lines = np.asarray(fronts, dtype=object)[own[fpart[unk][sidx[sel]]]]
                on[sel] = segments_on_lines(s0[sel], s1[sel], lines)
        front[unk] = np.bincount(sidx[on], weights=np.hypot(*(s1 - s0)[on].T), minlength=len(unk))
    # faces along land off the street (no frontage at all): rear land, joining the interior below
    back = ~inner & (front <= 0) & open_part[fpart]
    inner = inner | back
    amin = amin_b[own[fpart]]
    small = ~inner & (area < amin)
    if force_street_access:
        small |= ~inner & (front < np.minimum(lmin_b[own[fpart]], 0.5 * w_b[own[fpart]]))
    # a part with no face big enough (a block about one lot in size) is one lot
    whole = np.flatnonzero(np.bincount(fpart, weights=~small & ~inner, minlength=P) == 0)
    if len(whole):
        drop = np.isin(fpart, whole)
        report["skeleton_merged"] += int(drop.sum())
        faces = np.r_[faces[~drop], parts[whole]]
        fpart = np.r_[fpart[~drop], whole]
        # a part with no street edge at all is one inner lot
        wstreet = (
            np.ones(len(whole), bool) if flag is None else np.bincount(rs.vertex_poly(), flag, minlength=P)[whole] > 0
        )
        inner = np.r_[inner[~drop], ~wstreet]
        back = np.r_[back[~drop], np.zeros(len(whole), bool)]
        small = np.r_[small[~drop], np.zeros(len(whole), bool)]
        marks = Marks.concat([marks.take(np.flatnonzero(~drop)), Marks.unknown(parts[whole])])
        known = np.r_[known[~drop], np.zeros(len(whole), bool)]
        remap = np.cumsum(~drop) - 1
        sel = ~drop[adj[0]] & ~drop[adj[1]]
        adj = (remap[adj[0][sel]], remap[adj[1][sel]], adj[2][sel])
    faces, alive, nm, changed = _merge_into(faces, small, inner, fpart, strict=True, adj=adj)
    report["skeleton_merged"] += nm
    fpart, inner, back = fpart[alive], inner[alive], back[alive]
    marks, known = _after_merge(marks.take(np.flatnonzero(alive)), faces, changed), known[alive] & ~changed
    if back.any():  # the land along open edges joins the interior beside it: compact rear land, not strips
        faces, alive, nm, changed = _merge_into(faces, back, inner, fpart, strict=True)
        report["skeleton_rear"] = int(nm)
        fpart, inner = fpart[alive], inner[alive]
        marks, known = _after_merge(marks.take(np.flatnonzero(alive)), faces, changed), known[alive] & ~changed
    # 5. the interior
    cut = inner if interior == "split" else np.zeros(len(faces), bool)
    if interior == "inner" and inner.any():  # backland, not a courtyard: cut too
        cut = inner & (shapely.area(faces) > imax_b[own[fpart]])
        report["skeleton_backland"] = int(cut.sum())
    if cut.any():
        ii = np.flatnonzero(cut)
        # the interior without the ray ends along its straight sides: fewer vertices to cut
        simple = shapely.simplify(faces[ii], 0.0)
        ok = (shapely.get_type_id(simple) == 3) & shapely.is_valid(simple)
        simple = np.where(ok, simple, faces[ii])
        backland = interior != "split"  # backland: cut into pieces under inner_area_max, rows half its side deep
        sub = recursive_lots(
            simple,
            max_area=imax_b[own[fpart[ii]]] if backland else amax_b[own[fpart[ii]]],
            min_frontage=0.0,
            jitter=min(0.9, float(irr_b.max())),  # the node passes one irregularity for all its blocks
            seeds=seeds[own[fpart[ii]]],
            # backland: every piece under inner_area_max, rows half its side deep, no scrap under a twentieth
            # of it either (backland parcels are large); split: every piece under lot_area_max too (the
            # recursive method's compact inside left pieces cut off all round as large as 118 ha on Liege)
            **(
                {
                    "inner": "split",
                    "depth": 0.5 * np.sqrt(imax_b[own[fpart[ii]]]),
                    "min_area": 0.05 * imax_b[own[fpart[ii]]],
                }
                if backland
                else {"inner": "split"}
            ),
        )
        faces = np.r_[faces[~cut], sub[0]]
        fpart = np.r_[fpart[~cut], fpart[ii][sub[1]]]
        # interior lots lie depth metres from the block's boundary: none of their segments is on it (backland
        # may border open land or the extract's edge: measured)
        marks = Marks.concat([marks.take(np.flatnonzero(~cut)), Marks.unknown(sub[0])])
        known = np.r_[known[~cut], np.full(len(sub[0]), interior == "split")]
        inner = np.r_[inner[~cut], np.ones(len(sub[0]), bool)]
    elif interior == "merge" and inner.any():
        spacing = 0.5 * np.minimum(w_b, d_b)[own[fpart]]
        faces, fpart, inner, stay, changed = _merge_interior(faces, fpart, inner, spacing, report)
        marks, known = _after_merge(marks.take(np.flatnonzero(stay)), faces, changed), known[stay] & ~changed
    # slivers left (inner ones, or with no street neighbour): into any neighbour
    for strict in (True, False):  # into their own kind first (an interior scrap may join a street lot)
        tiny = shapely.area(faces) < np.where(inner, amin_b[own[fpart]], SLIVER)
        if not tiny.any():
            break
        faces, alive, nm, changed = _merge_into(faces, tiny, inner, fpart, strict=strict)
        report["skeleton_merged"] += nm
        fpart, inner = fpart[alive], inner[alive]
        marks, known = _after_merge(marks.take(np.flatnonzero(alive)), faces, changed), known[alive] & ~changed
    report["skeleton_slivers"] = int((shapely.area(faces) < SLIVER).sum())
    if interior == "split":  # pieces no cut could halve (counted, as the recursive method's stuck ones)
        report["skeleton_inner_over_max"] = int((inner & (shapely.area(faces) > amax_b[own[fpart]] + 1e-6)).sum())
    park = inner.copy() if interior == "park" else np.zeros(len(faces), bool)
    o = np.lexsort((np.arange(len(faces)), own[fpart]))
    marks = marks.take(o)
    return SkeletonLots(faces[o], own[fpart[o]].astype(np.int64), inner[o], park[o], report, marks.flat, known[o])

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
   shared courtyard of a perimeter block, the backland of a large one),
   ``split`` (cut into inner lots under ``lot_area_max`` by the recursive
   method, flagged), ``park`` (one courtyard / park lot per component,
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

from sengine.geom.boundary import polygon_parts, ring_segments, segments_on_boundary
from sengine.geom.planar import planar_faces
from sengine.geom.polygons import inset, threaded
from sengine.geom.segments import argsort_int, merge_points
from sengine.geom.split import RingSet

from .contour import Marks, _scan, ramp
from .paris import _normal
from .recursive import recursive_lots

__all__ = ["skeleton_lots", "SkeletonLots", "CORNERS", "INTERIORS"]

log = logging.getLogger(__name__)

CORNERS = ("merge", "split")
INTERIORS = ("inner", "split", "merge", "park")
MARGIN = 0.5  # m: cuts keep this much more than the corner's clearance (rays do not meet at the mitre point)
OVERSHOOT = 1e-3  # m: rays run this far past what they hit, so that noding makes the junction
SLIVER = 1.0  # m2: no lot is smaller
SNAP = 1e-6  # m: grid of the snap-rounding noder used where GEOS's fast noder fails
SAME = 1e-9  # m: points of the face graph closer than this are one node


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


def _per_block(x, n, dtype=np.float64):
    return np.broadcast_to(np.asarray(x, dtype), (n,)).copy()


# -- streets and cuts -----------------------------------------------------------------------------


def _streets(rs: RingSet, corner_angle: float):
    """Vertices' turning angles and the street (run of edges between corners) of each edge.

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


def _cuts(rs, own, d, width, lmin, amax, irregularity, seeds, corner_angle, corner):
    """Cut rays of every street: origin, inner normal, street, edge, and whether it is a bisector."""
    turn, u, run, order, closed, start = _streets(rs, corner_angle)
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

    def clearance(phi):
        convex = dS * np.tan(0.5 * np.minimum(phi, np.radians(170.0))) + MARGIN
        return np.where(phi > 0, convex, 0.5 * wS)

    c0 = np.where(closed, 0.0, clearance(phi0))
    c1 = np.where(closed, 0.0, clearance(phi1))
    U = L - c0 - c1
    w = np.maximum(np.minimum(wS, amax[sp] / np.maximum(dS, 1e-9)), lminS)
    m = np.floor(U / w + 0.5).astype(np.int64)
    m = np.where(U >= lminS, np.maximum(m, 1), 0)
    m = np.minimum(m, np.floor(U / np.maximum(lminS, 1e-9)).astype(np.int64) * (lminS > 0) + m * (lminS <= 0))
    m = np.maximum(m, 0)
    m = np.where(closed & (m < 2), 0, m)
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
    bis = np.zeros(len(arc), bool)
    if corner == "split":  # the corner's bisector halves the corner lot
        cv = first_v[(~closed) & (phi0 > 0)]
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
    return p, nrm, cut_s, e, bis, run, toff


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
    lo, hi = np.minimum(seg0, seg1), np.maximum(seg0, seg1)
    tree = shapely.STRtree(shapely.box(lo[:, 0], lo[:, 1], hi[:, 0], hi[:, 1]))
    rlo, rhi = np.minimum(p, q), np.maximum(p, q)
    ri, si = tree.query(shapely.box(rlo[:, 0], rlo[:, 1], rhi[:, 0], rhi[:, 1]))
    same = seg_part[si] == ray_part[ri]
    ri, si = ri[same], si[same]
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
    o = np.lexsort((si, t, ri))
    firstm = np.r_[True, ri[o][1:] != ri[o][:-1]] if len(o) else np.zeros(0, bool)
    f = o[firstm]
    best[ri[f]] = t[f]
    key[ri[f]] = seg_key[si[f]]
    seg[ri[f]] = si[f]
    par[ri[f]] = s[f]
    return best, key, seg, par


def _node(lines):
    """``shapely.node`` of each MultiLineString; one GEOS cannot node (rays meeting at a point, nearly)
    is noded by snap rounding to a micrometre grid instead."""
    try:
        return threaded(shapely.node, lines)
    except shapely.errors.GEOSException:
        out = np.empty(len(lines), dtype=object)
        for k, g in enumerate(lines):  # rare: only after a failure, to find the culprits
            try:
                out[k] = shapely.node(g)
            except shapely.errors.GEOSException:
                out[k] = shapely.union_all([g], grid_size=SNAP)
        return out


def _chain(item_seg, item_par, item_node, seg_end, nseg):
    """Edges along segments cut at points: for each segment, its start, the points in order, its end.

    ``item_*``: one item per segment start (parameter -1) and per point on
    a segment; ``seg_end``: the end node of each segment.  Returns the
    edges ``u, v`` and the segment of each.
    """
    o = np.lexsort((item_par, item_seg))
    sg, nd = item_seg[o], item_node[o]
    last = np.r_[sg[1:] != sg[:-1], True]
    nxt = np.r_[nd[1:], 0]
    v = np.where(last, seg_end[sg], nxt)
    return nd, v, sg


def _graph_faces(rs, rsI, ipart, p, nrm, t, cut_e, toff, hseg, hpar, ray_part):
    """Faces of the plane graph: block rings, offset rings and rays, all joined at exact nodes.

    Every ray starts at a known point of a block edge and ends at a known
    point of the segment it hit, so the graph is plane by construction
    except where rays cross one another (found with an STRtree query and
    split).  Its faces (:func:`sengine.geom.planar.planar_faces`) are the
    lots; those right of a block edge fill a hole of the block and are
    dropped, those left of an offset edge are the interior.  Returns faces,
    their part, the interior flag, and per part whether its faces add up
    to its area (else it needs GEOS).
    """
    N, NI, P = len(rs.xy), len(rsI.xy), rs.n
    xy0 = np.r_[rs.xy, rsI.xy]
    seg_start = np.arange(N + NI)
    seg_end = np.r_[rs.next_vertex(), N + rsI.next_vertex()]
    seg_part = np.r_[rs.vertex_poly(), ipart]
    R = len(p)
    ln = rs.edge_lengths()
    q = p + t[:, None] * nrm
    # ray ends: a segment's end node (within a nanometre), or a new point on it
    slen = np.hypot(*(xy0[seg_end] - xy0[seg_start]).T)
    at = hpar * slen[hseg]
    end_node = np.where(at <= SAME, seg_start[hseg], np.where(at >= slen[hseg] - SAME, seg_end[hseg], -1))
    start_node = np.where(toff <= SAME, cut_e, np.where(toff >= ln[cut_e] - SAME, rs.next_vertex()[cut_e], -1))
    ev_seg = np.r_[cut_e[start_node < 0], hseg[end_node < 0]]
    ev_par = np.r_[(toff / np.maximum(ln[cut_e], 1e-300))[start_node < 0], hpar[end_node < 0]]
    ev_xy = np.r_[p[start_node < 0], q[end_node < 0]]
    ev_ray = np.r_[np.flatnonzero(start_node < 0), np.flatnonzero(end_node < 0)]
    ev_is_end = np.r_[np.zeros(int((start_node < 0).sum()), bool), np.ones(int((end_node < 0).sum()), bool)]
    # one node per distinct point of a segment (to a nanometre)
    key = np.c_[ev_seg.astype(np.float64), np.round(ev_par * slen[ev_seg], 9)]
    uniq, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inv = inv.ravel()
    ev_node = N + NI + inv
    start_node[ev_ray[~ev_is_end]] = ev_node[~ev_is_end]
    end_node[ev_ray[ev_is_end]] = ev_node[ev_is_end]
    xy = np.r_[xy0, ev_xy[first]]
    # crossings of rays with rays
    a0, a1 = p, q
    lo, hi = np.minimum(a0, a1), np.maximum(a0, a1)
    boxes = shapely.box(lo[:, 0], lo[:, 1], hi[:, 0], hi[:, 1])
    i, j = shapely.STRtree(boxes).query(boxes) if R else (np.zeros(0, np.int64), np.zeros(0, np.int64))
    sel = (i < j) & (ray_part[i] == ray_part[j])
    i, j = i[sel], j[sel]
    shared = (start_node[i] == start_node[j]) | (start_node[i] == end_node[j])
    shared |= (end_node[i] == start_node[j]) | (end_node[i] == end_node[j])
    i, j = i[~shared], j[~shared]
    r, sv = a1[i] - a0[i], a1[j] - a0[j]
    den = r[:, 0] * sv[:, 1] - r[:, 1] * sv[:, 0]
    qp = a0[j] - a0[i]
    with np.errstate(divide="ignore", invalid="ignore"):
        ta = (qp[:, 0] * sv[:, 1] - qp[:, 1] * sv[:, 0]) / den
        tb = (qp[:, 0] * r[:, 1] - qp[:, 1] * r[:, 0]) / den
    la, lb = np.hypot(*r.T), np.hypot(*sv.T)
    cross = (den != 0) & (ta * la > SAME) & ((1 - ta) * la > SAME) & (tb * lb > SAME) & ((1 - tb) * lb > SAME)
    i, j, ta, tb = i[cross], j[cross], ta[cross], tb[cross]
    cxy = a0[i] + ta[:, None] * r[cross]
    # crossings at one point (several rays through it) are one node
    ckey = np.c_[ray_part[i].astype(np.float64), np.round(cxy, 9)]
    _, cfirst, cinv = np.unique(ckey, axis=0, return_index=True, return_inverse=True)
    cnode = len(xy) + cinv.ravel()
    xy = np.r_[xy, cxy[cfirst]]
    # edges: segments cut at the ray ends, rays cut at their crossings
    su, sv_, sg = _chain(
        np.r_[seg_start, ev_seg], np.r_[np.full(N + NI, -1.0), ev_par], np.r_[seg_start, ev_node], seg_end, N + NI
    )
    ru, rv, rg = _chain(
        np.r_[np.arange(R), i, j], np.r_[np.full(R, -1.0), ta, tb], np.r_[start_node, cnode, cnode], end_node, R
    )
    u = np.r_[su, ru]
    v = np.r_[sv_, rv]
    epart = np.r_[seg_part[sg], ray_part[rg]]
    kind = np.r_[np.where(sg < N, 0, 1), np.full(len(ru), 2)]  # 0 block, 1 offset, 2 ray
    pf = planar_faces(xy, u, v)
    faces = pf.polygons
    F = len(faces)
    fpart = np.full(F, -1, np.int64)
    ef = pf.edge_faces
    left = ef[:, 0]
    has = left >= 0
    fpart[left[has]] = epart[has]
    right = ef[:, 1]
    has = right >= 0
    fpart[right[has]] = epart[has]
    drop = np.zeros(F, bool)
    hole = (kind == 0) & (right >= 0)  # right of a block edge: inside one of its holes
    drop[right[hole]] = True
    inner = np.zeros(F, bool)
    io = (kind == 1) & (left >= 0)
    inner[left[io]] = True
    keep = ~drop & (fpart >= 0)
    kept = np.flatnonzero(keep)
    fmap = np.full(F, -1, np.int64)
    fmap[kept] = np.arange(len(kept))
    el = np.hypot(*(xy[v] - xy[u]).T)
    # street frontage of each face: the block edges it lies left of
    onb = (kind == 0) & (left >= 0)
    front = np.bincount(np.maximum(fmap[left[onb]], 0), weights=el[onb] * (fmap[left[onb]] >= 0), minlength=len(kept))
    # neighbours: faces on both sides of an edge, with the length they share
    both = (left >= 0) & (right >= 0) & (left != right)
    a, b = fmap[left[both]], fmap[right[both]]
    okp = (a >= 0) & (b >= 0)
    adj = _pair_sums(np.r_[a[okp], b[okp]], np.r_[b[okp], a[okp]], np.r_[el[both][okp], el[both][okp]], len(kept))
    # per boundary segment of each face, whether it is a block edge: the face's walk, step by step
    marks, known = _walk_marks(pf, faces, u[kind == 0], v[kind == 0], len(xy))
    faces, fpart, inner = faces[kept], fpart[kept], inner[kept]
    marks, known = marks.take(kept), known[kept]
    total = np.bincount(fpart, weights=shapely.area(faces), minlength=P)
    ok = np.abs(total - rs.areas()) <= 1e-9 * np.maximum(np.abs(rs.areas()), 1.0)
    return faces, fpart, inner, ok, front, adj, marks, known


def _pair_sums(i, j, w, n):
    """Unique (i, j) pairs with the sum of ``w`` over each."""
    if len(i) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    key = i * n + j
    o = argsort_int(key)
    first = np.r_[True, key[o][1:] != key[o][:-1]]
    grp = np.cumsum(first) - 1
    return i[o][first], j[o][first], np.bincount(grp, weights=w[o])


def _walk_marks(pf, faces, bu, bv, n):
    """Which boundary segment of each face lies on a block edge (``bu``, ``bv``: block edge pieces).

    A face whose shell is one simple walk and that has no hole has its
    segments in walk order (:class:`sengine.geom.planar.PlanarFaces`); the
    others are left unknown (measured later).
    """
    F = len(faces)
    nseg = np.maximum(shapely.get_num_coordinates(faces) - 1 - shapely.get_num_interior_rings(faces), 0)
    known = np.zeros(F, bool)
    wp = pf.walk_polygon
    w = np.flatnonzero(wp >= 0)
    wlen = np.diff(pf.walk_start)[w]
    good = shapely.get_num_interior_rings(faces[wp[w]]) == 0
    good &= wlen == nseg[wp[w]]
    w, wlen = w[good], wlen[good]
    known[wp[w]] = True
    flat = np.zeros(int(nseg.sum()), bool)
    if len(w):
        bkey = np.unique(np.minimum(bu, bv) * n + np.maximum(bu, bv))
        row = np.repeat(np.arange(len(w)), wlen)
        k = ramp(wlen)
        start = pf.walk_start[w][row]
        a = pf.walk_vertex[start + k]
        b = pf.walk_vertex[start + np.mod(k + 1, wlen[row])]
        key = np.minimum(a, b) * n + np.maximum(a, b)
        pos = np.minimum(np.searchsorted(bkey, key), max(len(bkey) - 1, 0))
        on = (bkey[pos] == key) if len(bkey) else np.zeros(len(key), bool)
        fstart = np.cumsum(nseg) - nseg
        flat[fstart[wp[w]][row] + k] = on
    return Marks(flat, nseg), known


def _geos_faces(parts, core, cparts, cown, p, nrm, t, ray_part, sel):
    """Faces of parts ``sel`` by GEOS: lines noded (snap rounding where that fails) and polygonized."""
    P = len(parts)
    want = np.zeros(P, bool)
    want[sel] = True
    rk = want[ray_part]
    end = p[rk] + (t[rk] + OVERSHOOT)[:, None] * nrm[rk]
    rays = shapely.linestrings(np.stack([p[rk] - OVERSHOOT * nrm[rk], end], axis=1))  # crossing, not touching
    bnd = shapely.get_parts(shapely.boundary(parts[sel]), return_index=True)
    ck = want[cown]
    cb = shapely.get_parts(shapely.boundary(cparts[ck]), return_index=True)
    lines = np.r_[bnd[0], cb[0], rays]
    lpart = np.r_[sel[bnd[1]], cown[ck][cb[1]], ray_part[rk]]
    o = np.argsort(lpart, kind="stable")
    has = np.unique(lpart)
    ml = shapely.multilinestrings(lines[o], indices=np.searchsorted(has, lpart[o]))
    coll = shapely.polygonize(_node(ml).reshape(-1, 1), axis=-1)
    faces, fi = shapely.get_parts(np.asarray(coll).ravel(), return_index=True)
    fpart = has[fi]
    pt = shapely.point_on_surface(faces)
    inpart = shapely.area(faces) > 0
    shapely.prepare(parts)
    inpart &= shapely.contains_properly(parts[fpart], pt)
    faces, fpart, pt = faces[inpart], fpart[inpart], pt[inpart]
    inner = np.zeros(len(faces), bool)
    has_core = np.zeros(P, bool)
    has_core[cown] = True
    cq = np.flatnonzero(has_core[fpart])
    if len(cq):
        shapely.prepare(core)
        inner[cq] = shapely.contains_properly(core[fpart[cq]], pt[cq])
    return faces, fpart, inner


# -- faces and merges -----------------------------------------------------------------------------


def _neighbours(faces, fpart, want=None):
    """Pairs of faces (of one part) sharing boundary, and the length they share (m).

    Faces of one polygonize call share their edges vertex for vertex, so an
    edge is shared when the same two points bound a segment of both.  Only
    the faces of ``want`` (default all) and those near them are looked at.
    """
    sel = np.arange(len(faces))
    if want is not None:  # the wanted faces and those whose boxes meet theirs
        w = np.flatnonzero(want)
        near = shapely.STRtree(faces).query(faces[w])[1] if len(w) else np.zeros(0, np.int64)
        sel = np.unique(np.r_[w, near])
    p0, p1, idx, _ = ring_segments(faces[sel])
    if len(idx) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    idx = sel[idx]
    _, vid = merge_points(np.r_[p0, p1])
    a, b = vid[: len(idx)], vid[len(idx) :]
    key = np.minimum(a, b) * (int(vid.max()) + 1) + np.maximum(a, b)
    part = fpart[idx]
    o = np.lexsort((part, key))
    same = (key[o][1:] == key[o][:-1]) & (part[o][1:] == part[o][:-1])
    i, j = idx[o][:-1][same], idx[o][1:][same]
    ln = np.hypot(*(p1 - p0)[o][:-1][same].T)
    keep = i != j
    i, j, ln = i[keep], j[keep], ln[keep]
    # both directions, summed per pair
    ii, jj, ll = np.r_[i, j], np.r_[j, i], np.r_[ln, ln]
    if len(ii) == 0:
        return ii, jj, ll
    pk = ii * len(faces) + jj
    o = argsort_int(pk)
    first = np.r_[True, pk[o][1:] != pk[o][:-1]]
    grp = np.cumsum(first) - 1
    return ii[o][first], jj[o][first], np.bincount(grp, weights=ll[o])


def _touching(faces, fpart, sel):
    """Neighbours of faces ``sel`` found geometrically (boundaries within 1 um), with the length shared."""
    if len(sel) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    qi, j = shapely.STRtree(faces).query(faces[sel], predicate="dwithin", distance=1e-6)
    i = sel[qi]
    ok = (i != j) & (fpart[i] == fpart[j])
    i, j = i[ok], j[ok]
    bi, bj = shapely.boundary(faces[i]), shapely.boundary(faces[j])
    ln = shapely.length(shapely.intersection(bi, shapely.buffer(bj, 1e-6, quad_segs=1)))
    return i, j, ln


def _merge_into(faces, small, group, fpart, rounds=4, strict=False, adj=None):
    """Faces flagged ``small`` joined to the neighbour sharing most boundary.

    Neighbours of the same ``group`` (street or interior) that are not
    small come first, then any not small, then small ones (which may then
    grow out of it in the next round); with ``strict`` only the same group.
    Faces of no area (under 1e-9 m2: rays meeting at a point) are dropped.
    Returns the faces (joined ones removed, their hosts grown), the mask of
    the input faces kept, and the number merged or dropped; a small face
    with no neighbour stays.  ``adj`` (pairs of faces and the length they
    share, when known, e.g. from the face graph) spares looking for them.
    """
    faces = faces.copy()
    alive = shapely.area(faces) > 1e-9
    changed = np.zeros(len(faces), bool)
    merged = int((~alive).sum())
    small = small & alive
    if adj is not None:  # only small faces look for neighbours
        sel = small[adj[0]]
        adj = (adj[0][sel], adj[1][sel], adj[2][sel])
    for _ in range(rounds):
        todo = small & alive
        if not todo.any():
            break
        if adj is not None:
            i, j, ln = adj
            sel = alive[i] & alive[j]
            i, j, ln = i[sel], j[sel], ln[sel]
        else:
            live = np.flatnonzero(alive)
            i, j, ln = _neighbours(faces[live], fpart[live], todo[live])
            i, j = live[i], live[j]
        lonely = np.setdiff1d(np.flatnonzero(todo), i)
        if len(lonely):
            gi, gj, gl = _touching(faces, fpart, lonely)
            keep = alive[gj]
            i, j, ln = np.r_[i, gi[keep]], np.r_[j, gj[keep]], np.r_[ln, gl[keep]]
        ok = todo[i] & alive[j] & (ln > 0)
        if strict:
            ok &= group[i] == group[j]
        i, j, ln = i[ok], j[ok], ln[ok]
        if len(i) == 0:
            break
        rank = np.where((group[i] == group[j]) & ~small[j], 0, np.where(~small[j], 1, 2))
        o = np.lexsort((j, -ln, rank, i))
        first = np.r_[True, i[o][1:] != i[o][:-1]]
        src, dst = i[o][first], j[o][first]
        go = ~np.isin(dst, src)  # a host that joins another this round waits
        src, dst = src[go], dst[go]
        if len(src) == 0:
            break
        # group by host: union of the host and all faces joining it
        g = np.lexsort((src, dst))
        src, dst = src[g], dst[g]
        hosts, cnt = np.unique(dst, return_counts=True)
        grid = np.full((len(hosts), int(cnt.max()) + 1), None, dtype=object)
        grid[:, 0] = faces[hosts]
        grid[np.repeat(np.arange(len(hosts)), cnt), 1 + ramp(cnt)] = faces[src]
        u = shapely.union_all(grid, axis=1)
        one = (shapely.get_type_id(u) == 3) & shapely.is_valid(u)
        faces[hosts[one]] = u[one]
        changed[hosts[one]] = True
        went = one[np.repeat(np.arange(len(hosts)), cnt)]
        gone = src[went]
        alive[gone] = False
        merged += len(gone)
        if adj is not None:  # the joined faces' neighbours are their host's now
            host = np.arange(len(faces))
            host[gone] = dst[went]
            ai, aj = adj[0], host[adj[1]]
            sel = alive[ai] & (ai != aj)
            adj = _pair_sums(ai[sel], aj[sel], adj[2][sel], len(faces))
        small = small.copy()
        small[hosts[one]] = False
    return faces[alive], alive, merged, changed[alive]


# -- all blocks -----------------------------------------------------------------------------------


def skeleton_lots(
    blocks,
    *,
    depth=22.0,
    width=15.0,
    lot_width_min=6.0,
    lot_area_min=20.0,
    lot_area_max=2000.0,
    irregularity=0.3,
    corner="merge",
    interior="inner",
    force_street_access=True,
    corner_angle=30.0,
    seeds=None,
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
    irr_b = _per_block(irregularity, n)
    parts, own = polygon_parts(blocks, np.arange(n))
    rs = RingSet.from_polygons(parts)
    keep = np.bincount(rs.poly, minlength=rs.n) > 0
    rs, own, parts = rs.take(keep), own[keep], parts[keep]
    P = rs.n
    if P == 0:
        return empty
    parts = shapely.orient_polygons(parts)
    d = d_b[own]
    # 1. the interior: the block offset by the depth
    core = inset(parts, d)
    cparts, cown = polygon_parts(core, np.arange(P))
    # 2-3. streets and cut rays
    p, nrm, cut_s, cut_e, bis, run, toff = _cuts(
        rs, own, d, w_b[own], lmin_b[own], amax_b[own], irr_b[own], seeds, corner_angle, corner
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
    # a part thinner than twice the depth: only the rays of the lower street cross it
    keep = np.isfinite(t) & (~through | (cut_s < hit) | ((cut_s == hit) & ~bis))
    keep |= bis & np.isfinite(t)
    report["skeleton_thin"] = int((through & keep).sum())
    p, nrm, t, ray_part = p[keep], nrm[keep], t[keep], ray_part[keep]
    cut_e, toff, hseg, hpar = cut_e[keep], toff[keep], hseg[keep], hpar[keep]
    report["skeleton_cuts"] = int(len(p))
    # 4. faces of the plane graph of block boundary, offset curve and rays
    faces, fpart, inner, ok, front, adj, marks, known = _graph_faces(
        rs, rsI, ipart, p, nrm, t, cut_e, toff, hseg, hpar, ray_part
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
        front[unk] = np.bincount(sidx[on], weights=np.hypot(*(s1 - s0)[on].T), minlength=len(unk))
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
        inner = np.r_[inner[~drop], np.zeros(len(whole), bool)]
        small = np.r_[small[~drop], np.zeros(len(whole), bool)]
        marks = Marks.concat([marks.take(np.flatnonzero(~drop)), Marks.unknown(parts[whole])])
        known = np.r_[known[~drop], np.zeros(len(whole), bool)]
        remap = np.cumsum(~drop) - 1
        sel = ~drop[adj[0]] & ~drop[adj[1]]
        adj = (remap[adj[0][sel]], remap[adj[1][sel]], adj[2][sel])
    faces, alive, nm, changed = _merge_into(faces, small, inner, fpart, strict=True, adj=adj)
    report["skeleton_merged"] += nm
    fpart, inner = fpart[alive], inner[alive]
    marks, known = marks.take(np.flatnonzero(alive)), known[alive] & ~changed
    # 5. the interior
    if interior == "split" and inner.any():
        ii = np.flatnonzero(inner)
        # the interior without the ray ends along its straight sides: fewer vertices to cut
        simple = shapely.simplify(faces[ii], 0.0)
        ok = (shapely.get_type_id(simple) == 3) & shapely.is_valid(simple)
        simple = np.where(ok, simple, faces[ii])
        sub = recursive_lots(
            simple,
            max_area=amax_b[own[fpart[ii]]],
            min_frontage=0.0,
            jitter=min(0.9, float(irr_b.max())),  # the node passes one irregularity for all its blocks
            seeds=seeds[own[fpart[ii]]],
        )
        faces = np.r_[faces[~inner], sub[0]]
        fpart = np.r_[fpart[~inner], fpart[ii][sub[1]]]
        # interior lots lie depth metres from the block's boundary: none of their segments is on it
        marks = Marks.concat([marks.take(np.flatnonzero(~inner)), Marks.unknown(sub[0])])
        known = np.r_[known[~inner], np.ones(len(sub[0]), bool)]
        inner = np.r_[np.zeros(int((~inner).sum()), bool), np.ones(len(sub[0]), bool)]
    elif interior == "merge" and inner.any():
        spacing = 0.5 * np.minimum(w_b, d_b)[own[fpart]]
        faces, fpart, inner, stay, changed = _merge_interior(faces, fpart, inner, spacing, report)
        marks, known = marks.take(np.flatnonzero(stay)), known[stay] & ~changed
    # slivers left (inner ones, or with no street neighbour): into any neighbour
    for strict in (True, False):  # into their own kind first (an interior scrap may join a street lot)
        tiny = shapely.area(faces) < np.where(inner, amin_b[own[fpart]], SLIVER)
        if not tiny.any():
            break
        faces, alive, nm, changed = _merge_into(faces, tiny, inner, fpart, strict=strict)
        report["skeleton_merged"] += nm
        fpart, inner = fpart[alive], inner[alive]
        marks, known = marks.take(np.flatnonzero(alive)), known[alive] & ~changed
    report["skeleton_slivers"] = int((shapely.area(faces) < SLIVER).sum())
    park = inner.copy() if interior == "park" else np.zeros(len(faces), bool)
    o = np.lexsort((np.arange(len(faces)), own[fpart]))
    marks = marks.take(o)
    return SkeletonLots(faces[o], own[fpart[o]].astype(np.int64), inner[o], park[o], report, marks.flat, known[o])


def _robust(func, *arrays):
    """``func`` over arrays (rows), with ``None`` where GEOS fails (only rows, not the whole call)."""
    try:
        return threaded(func, *arrays)
    except shapely.errors.GEOSException:
        out = np.empty(len(arrays[0]), dtype=object)
        for k in range(len(out)):  # rare: after a failure, to find the culprits
            try:
                out[k] = func(*(a[k : k + 1] for a in arrays))[0]
            except shapely.errors.GEOSException:
                out[k] = None
        return out


def _merge_interior(faces, fpart, inner, spacing, report):
    """Each interior face shared out among the street lots along it, so that every lot reaches a street.

    The interior's boundary is sampled every ``spacing`` (m, per face); each
    sample belongs to the street lot whose back edge it lies on, and each
    point of the interior goes to the lot of the nearest sample (Voronoi
    cells of the samples, clipped to the interior): lots from facing
    streets meet half way, near the interior's medial axis.  A part where
    a lot would come out in pieces keeps its interior as inner lots
    (counted in ``skeleton_merge_kept``).
    """
    ii = np.flatnonzero(inner)
    si = np.flatnonzero(~inner)
    F = faces[ii]
    dens = shapely.segmentize(F, spacing[ii])
    p0, p1, fidx, _ = ring_segments(dens)
    mids = 0.5 * (p0 + p1)
    owner = np.full(len(mids), -1, np.int64)
    if len(mids) and len(si):
        qi, li = shapely.STRtree(faces[si]).query(shapely.points(mids), predicate="dwithin", distance=1e-6)
        ok = fpart[si[li]] == fpart[ii[fidx[qi]]]
        qi, li = qi[ok], li[ok]
        o = np.lexsort((li, qi))
        f = np.r_[True, qi[o][1:] != qi[o][:-1]] if len(o) else np.zeros(0, bool)
        owner[qi[o][f]] = si[li[o][f]]
    keep = owner >= 0
    mids, fidx, owner = mids[keep], fidx[keep], owner[keep]
    # one sample per point of a face (Voronoi cells merge equal points)
    key = np.c_[fidx.astype(np.float64), mids]
    _, first = np.unique(key, axis=0, return_index=True)
    first = np.sort(first)
    mids, fidx, owner = mids[first], fidx[first], owner[first]
    nf = np.bincount(fidx, minlength=len(ii))
    go = np.flatnonzero(nf >= 2)
    bad_part = np.zeros(int(fpart.max()) + 1, bool)
    bad_part[fpart[ii[nf < 2]]] = True  # an interior touching fewer than two samples stays inner
    sel = np.isin(fidx, go)
    mids, fidx, owner = mids[sel], fidx[sel], owner[sel]
    mp = shapely.multipoints(mids, indices=np.searchsorted(go, fidx))
    vor = shapely.voronoi_polygons(mp, extend_to=F[go], ordered=True)
    cells, ci = shapely.get_parts(vor, return_index=True)
    ok_count = np.bincount(ci, minlength=len(go)) == nf[go]
    bad_part[fpart[ii[go[~ok_count]]]] = True
    cell_ok = ok_count[ci]
    cells, cowner, cface = cells[cell_ok], owner[cell_ok], go[ci[cell_ok]]
    clipped = _robust(shapely.intersection, cells, F[cface])
    bad_part[fpart[ii[cface[shapely.is_missing(clipped)]]]] = True
    # each street lot with its cells
    o = np.lexsort((np.arange(len(cowner)), cowner))
    cowner, clipped = cowner[o], clipped[o]
    hosts, cnt = np.unique(cowner, return_counts=True)
    grid = np.full((len(hosts), int(cnt.max()) + 1 if len(cnt) else 1), None, dtype=object)
    grid[:, 0] = faces[hosts]
    grid[np.repeat(np.arange(len(hosts)), cnt), 1 + ramp(cnt)] = clipped
    grown = _robust(lambda g: shapely.union_all(g, axis=1), grid) if len(hosts) else np.empty(0, object)
    bad_part[fpart[hosts[shapely.get_type_id(grown) != 3]]] = True  # a missing one (None) has type -1
    new = faces.copy()
    new[hosts] = grown
    # every part's area must be kept (to 1e-9): else its interior stays inner
    P = int(fpart.max()) + 1
    before = np.bincount(fpart, weights=shapely.area(faces), minlength=P)
    after = np.bincount(fpart[si], weights=shapely.area(new[si]), minlength=P)
    bad_part |= np.abs(after - before) > 1e-9 * np.maximum(before, 1.0)
    bad_part &= np.bincount(fpart[ii], minlength=P) > 0
    report["skeleton_merge_kept"] = report.get("skeleton_merge_kept", 0) + int(bad_part.sum())
    use_new = ~bad_part[fpart]
    out = np.where(use_new, new, faces)
    stay = ~inner | bad_part[fpart]
    changed = np.zeros(len(faces), bool)
    changed[hosts] = True
    changed &= use_new
    return out[stay], fpart[stay], inner[stay], stay, changed[stay]

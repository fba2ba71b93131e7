"""Paris lots (skylineEngine §5.5, Fig. 9 left).

The contour of the block is split into equal segments; at each segment end
the inner normal is computed; each segment is split into three rectilinear
sub-segments whose ends are displaced inwards along their inner normals by a
random depth (mean ``depth``, deviation ``deviation``).  Lots are the
regions between the contour segments and the displaced inner line; the
remaining core is an inner lot (courtyard).

How it is computed, for all blocks at once and without polygon overlay:

1. Sample points, inner normals (the contour's direction averaged over two
   lot depths, so that lots fan out around corners and curves instead of
   crossing) and displaced points come from numpy interpolation along the
   exterior rings (:mod:`.lots_contour`); depths are clamped to ``REACH``
   of the radius of the block's largest inscribed circle (half its
   inscribed depth), so that lots from facing streets do not cross.
2. Each candidate lot is the polygon "contour segment, then its displaced
   points backwards"; the core is the polygon through all displaced points.
   Their boundaries add up to the block's contour (radial edges and the inner
   line cancel out), so when each of them is a simple counter-clockwise
   polygon they partition the block exactly: the winding numbers of the
   pieces add up to the block's and none is negative.  Vectorized
   ``is_valid`` calls check that.
3. Candidates that are not simple, or whose stretch of the displaced line
   crosses (or touches) another stretch of it, are merged run by run into
   one corner lot closed by a straight back edge; for a crossing, every
   candidate between the two stretches, the shorter way round the contour
   (up to ``SPAN`` candidates), joins the run.  Where two simple candidates
   overlap, the core through the displaced line would wind negatively, so
   the line crosses itself there (step 2 would refuse the polygon anyway):
   the overlaps are found on the line alone, in numpy
   (:func:`sengine.geom.planar.ring_crossings`), before any polygon is
   built.  That finds neighbours where the line folds (what windows of
   three candidates tested with GEOS found before) and also the two sides
   of an acute tip, whose lots overlap farther apart than neighbours: the
   tip becomes one corner lot instead of the whole block being refused and
   cut in two, again and again, at its middle, far from the tip.
   Candidates with some street but less than ``min_frontage`` join such a
   run too (with their street-side neighbour).  Only candidates without
   street (along a cut edge, step 4) join the core, so the core, the inner
   lot, never reaches a street; a polygon with no candidate of
   ``min_frontage`` is one lot, inner only if it has no street at all.
4. A block whose core is still not simple (thin arms, holes outside the
   core), or with a corner lot still not simple after growing twice by a
   candidate on each side, is cut in two across its main axis
   (:func:`sengine.geom.split.split`; the cut edges are not streets, so no lot
   faces them, and only lots without street are inner) and the halves start
   again, a few times; what remains is kept whole and counted.  A refused
   piece smaller than one nominal lot (``segment`` x ``depth``) is not cut:
   it is one lot (cutting it gave slivers that only joined their neighbours).

Randomness is a hash of (block seed, piece, sample), so results do not depend
on the order blocks are processed in.

References
----------
skylineEngine §5.5, Fig. 9.
"""

from __future__ import annotations

import logging
from typing import NamedTuple

import numpy as np
import shapely

from sengine.geom.boundary import polygon_parts, street_edges
from sengine.geom.merge import merge_small
from sengine.geom.planar import ring_crossings, star_simple
from sengine.geom.polygons import threaded
from sengine.geom.split import RingSet, split
from sengine.random import hash01

from .contour import Contour, Marks, Rings, ramp

__all__ = ["paris_lots"]

log = logging.getLogger(__name__)


def _normal(seed, key):
    """Standard normal numbers from (seed, key) uint64 pairs (Box-Muller on two hashes)."""
    key = np.asarray(key, np.uint64)
    with np.errstate(over="ignore"):
        u1 = hash01(seed, key * np.uint64(2) + np.uint64(1))
        u2 = hash01(seed, key * np.uint64(2) + np.uint64(2))
    return np.sqrt(-2.0 * np.log(np.maximum(u1, 1e-300))) * np.cos(2.0 * np.pi * u2)


def _clean(geoms, area):
    """Simple, counter-clockwise polygons (the partition certificate's test).

    ``geoms``: polygons, or their :class:`~.contour.Rings`, of which only
    those of positive area are tested.  Rings strictly star-shaped round
    their vertex mean (:func:`sengine.geom.planar.star_simple`, numpy: most
    candidate lots, which are nearly convex) are simple without building a
    polygon or asking GEOS; the others are built and GEOS tests them.
    """
    ok = np.asarray(area) > 0
    if isinstance(geoms, Rings):
        ask = ok & ~star_simple(geoms.xy, geoms.sizes)
        ok[ask] = threaded(shapely.is_valid, geoms.polygons(ask))  # GEOS runs without the GIL
        return ok
    ok[ok] = threaded(shapely.is_valid, np.asarray(geoms, dtype=object)[ok])
    return ok


# -- one pass over a set of polygons ------------------------------------------------------------

REACH = 0.9  # lots reach at most this share of the way to the centre of the block's inscribed circle
TOUCH = 1e-3  # m: less street than this is none (an inner lot may touch a street by less)


def inscribed_radius(polys, enough=np.inf) -> np.ndarray:
    """Radius (m) of the largest circle inside each polygon: half its inscribed depth (to 1 %).

    Where only whether the radius reaches ``enough`` (m) matters: a polygon
    whose interior point (``point_on_surface``) lies farther than ``enough``
    from its boundary, by more than the tolerance, gets that distance (a lower
    bound, at least ``enough``, as GEOS's circle would be) without the search.
    ``enough`` is one radius for all polygons or one each (m; ``inf``: always
    search).
    """
    polys = np.asarray(polys, dtype=object)
    out = np.zeros(len(polys))
    ok = np.flatnonzero(~shapely.is_empty(polys) & (shapely.area(polys) > 0))
    if len(ok):
        b = shapely.bounds(polys[ok])
        tol = 0.01 * np.maximum(np.minimum(b[:, 2] - b[:, 0], b[:, 3] - b[:, 1]), 1e-6)
        search = np.ones(len(ok), bool)
        enough = np.broadcast_to(np.asarray(enough, np.float64), polys.shape)[ok]
        if np.isfinite(enough).any():
            low = shapely.distance(shapely.point_on_surface(polys[ok]), shapely.boundary(polys[ok]))
            search = ~(low >= enough + tol)
            out[ok[~search]] = low[~search]
        # GEOS's search runs without the GIL: spread over threads (the same circles)
        circles = threaded(shapely.maximum_inscribed_circle, polys[ok[search]], tol[search])
        out[ok[search]] = shapely.length(circles)
    return out


def cstart_of(C):
    """Index of each polygon's first candidate."""
    return np.cumsum(C.nseg) - C.nseg


def _runs(flag, cp, ci, nseg):
    """Maximal cyclic runs of flagged candidates, in polygons with an unflagged one.

    Returns the run's polygon, first candidate and length.
    """
    P = len(nseg)
    cstart = np.cumsum(nseg) - nseg
    has_other = np.bincount(cp, weights=~flag, minlength=P) > 0
    gi = np.flatnonzero(~flag)
    g0 = np.zeros(P, np.int64)
    if len(gi):
        first = gi[np.r_[True, cp[gi][1:] != cp[gi][:-1]]]
        g0[cp[first]] = ci[first]
    # rotate each polygon to start at an unflagged candidate: runs do not wrap any more
    rb = np.zeros(len(cp), bool)
    rb[cstart[cp] + np.mod(ci - g0[cp], nseg[cp])] = flag
    rb &= has_other[cp]
    prev = np.r_[False, rb[:-1]]
    prev[cstart[nseg > 0]] = False
    nxt = np.r_[rb[1:], False]
    nxt[(cstart + nseg - 1)[nseg > 0]] = False
    s_pos, e_pos = np.flatnonzero(rb & ~prev), np.flatnonzero(rb & ~nxt)
    run_p = cp[s_pos]
    return run_p, np.mod(s_pos - cstart[run_p] + g0[run_p], nseg[run_p]), e_pos - s_pos + 1


class _Candidates(NamedTuple):
    """One perimeter candidate lot per contour segment of every polygon (ring order)."""

    poly: np.ndarray  # polygon of each candidate
    index: np.ndarray  # its index along its polygon's contour
    start: np.ndarray  # its first sample (3 per segment)
    lot: Rings  # its polygon: contour segment, then the displaced points backwards
    lot_area: np.ndarray  # signed area (m2): negative when it winds clockwise
    marks: Marks  # its segment marks
    core_part: np.ndarray  # no street (a cut edge), or its polygon has no candidate of min_frontage: joins the core
    bad: np.ndarray  # not simple, overlapping a neighbour, or short of street: joins a corner lot


class _Corners(NamedTuple):
    """Runs of bad candidates merged into corner lots closed by a straight back edge."""

    poly: np.ndarray  # polygon of each run
    first: np.ndarray  # its first candidate
    count: np.ndarray  # how many candidates it spans
    lot: Rings  # the corner lot
    marks: Marks
    refused: np.ndarray  # still not simple (or short of street) after growing twice: its polygon is cut


class _Cores(NamedTuple):
    """The inner lot of every polygon: the polygon through all its displaced points, or the whole polygon."""

    lot: np.ndarray  # (P,) object: the core of each polygon (None where none was made)
    mark: np.ndarray  # (P,) index into marks, -1: unknown
    marks: Marks
    done: np.ndarray  # (P,) the polygon's candidates, corners and core partition it: it is finished
    all_merged: np.ndarray  # (P,) no street worth a lot: the polygon is one lot
    whole_inner: np.ndarray  # (P,) ... and it has no street at all


def _candidates(rs, C, min_frontage) -> _Candidates:
    """The perimeter candidates, each tested alone (simple, counter-clockwise, enough street)."""
    P = rs.n
    nseg = C.nseg
    cp = np.repeat(np.arange(P), nseg)
    ci = ramp(nseg)
    ja = 3 * ci
    q, qa, front, qm = C.chains(cp, ja, ja + 3, np.ones(len(cp), np.int64), lazy=True)
    merge = front < TOUCH  # no street (a cut edge): part of the core
    # no candidate with enough street: the polygon is one lot (inner if it has no street)
    merge |= (np.bincount(cp, weights=front >= min_frontage, minlength=P) == 0)[cp]
    short = (front < min_frontage) & ~merge  # too little street: joins a neighbour (a corner lot)
    bad = ~_clean(q, np.where(merge | short, 0.0, qa)) & ~merge  # short ones are bad untested
    return _Candidates(cp, ci, ja, q, qa, qm, merge, bad)


def _corner_lots(C, cand: _Candidates, bad, min_frontage) -> tuple[_Corners, np.ndarray]:
    """Runs of bad candidates become corner lots; returns them and the final bad flags.

    A run whose corner lot is not simple (or has too little street) grows by
    one candidate on each side, twice; one still refused refuses its polygon
    (which is cut).
    """
    cp, ci, nseg, merge = cand.poly, cand.index, C.nseg, cand.core_part
    cstart = np.cumsum(nseg) - nseg
    bad = bad.copy()
    for it in range(3):
        run_p, s_i, n_i = _runs(bad, cp, ci, nseg)
        corner, ca, cfront, cm = C.chains(run_p, 3 * s_i, 3 * (s_i + n_i), 3 * n_i, lazy=True)
        refused = ~(_clean(corner, ca) & (cfront >= min_frontage))
        if not refused.any() or it == 2:
            break
        base, first, cnt, nn = cstart[run_p[refused]], s_i[refused], n_i[refused], nseg[run_p[refused]]
        for at in (base + np.mod(first - 1, nn), base + np.mod(first + cnt, nn)):
            bad[at] |= ~merge[at]
    return _Corners(run_p, s_i, n_i, corner, cm, refused), bad


def _cores(rs, C, cand: _Candidates, good, corners: _Corners) -> _Cores:
    """The core of each polygon, unit after unit in ring order (good candidates, corner lots, core runs)."""
    P = rs.n
    cp, ja, merge = cand.poly, cand.start, cand.core_part
    mp, ms_, mn = _runs(merge, cp, cand.index, C.nseg)
    gi = np.flatnonzero(good)
    up = np.r_[cp[gi], corners.poly, mp]
    ua = np.r_[ja[gi], 3 * corners.first, 3 * ms_]
    ub = np.r_[ja[gi] + 3, 3 * (corners.first + corners.count), 3 * (ms_ + mn)]
    uk = np.r_[np.zeros(len(gi), np.int64), np.ones(len(corners.poly), np.int64), np.full(len(mp), 2, np.int64)]
    o = np.lexsort((np.mod(ua, C.m[up]), up))
    core, core_a, cpoly, corem = C.core(up[o], ua[o], ub[o], uk[o])
    all_merged = np.bincount(cp, weights=~merge, minlength=P) == 0
    done = np.zeros(P, bool)
    done[cpoly] = _clean(core, core_a)
    core_of = np.full(P, None, dtype=object)
    core_of[cpoly] = core
    core_mark = np.full(P, -1, np.int64)  # index into corem, -1: unknown marks
    core_mark[cpoly] = np.arange(len(cpoly))
    done &= np.bincount(corners.poly, weights=corners.refused, minlength=P) == 0
    # holes must lie inside the core
    nring = np.bincount(rs.poly, minlength=P)
    holed = np.flatnonzero(done & (nring > 1))
    if len(holed):
        sub = rs.take(holed).polygons()
        for k, hi in enumerate(holed):
            holes = [shapely.Polygon(r) for r in sub[k].interiors]
            if shapely.contains_properly(core_of[hi], holes).all():
                core_of[hi] = shapely.Polygon(core_of[hi].exterior, [r.coords for r in sub[k].interiors])
                core_mark[hi] = -1
            else:
                done[hi] = False
    whole = np.flatnonzero(all_merged)  # no street worth a lot: the polygon is one lot
    done[whole] = True
    wsub = rs.take(whole)
    whole_inner = np.zeros(P, bool)
    whole_inner[whole] = wsub.flagged_length() < TOUCH
    whole_m = Marks.of(wsub)
    if len(whole):
        core_of[whole] = wsub.polygons()
        core_mark[whole] = len(cpoly) + np.arange(len(whole))
    return _Cores(core_of, core_mark, Marks.concat([corem, whole_m]), done, all_merged, whole_inner)


SPAN = 12  # candidates (240 m of contour by default): crossings farther apart round the contour are left to the cut


def _spans(C, cand, p, c1, c2):
    """Flags of the candidates from ``c1`` to ``c2`` of polygons ``p``, the shorter way round, at most SPAN."""
    fix = np.zeros(len(cand.poly), bool)
    n = C.nseg[p]
    fwd = np.mod(c2 - c1, n)
    start = np.where(fwd <= n - fwd, c1, c2)
    span = np.minimum(fwd, n - fwd) + 1
    ok = span <= SPAN
    p, n, start, span = p[ok], n[ok], start[ok], span[ok]
    row = np.repeat(np.arange(len(p)), span)
    fix[(cstart_of(C)[p])[row] + np.mod(start[row] + ramp(span), n[row])] = True
    return fix & ~cand.core_part


def _inner_crossings(C, cand: _Candidates) -> np.ndarray:
    """Candidates between two edges of the displaced line that cross (or touch), the shorter way round.

    Numpy, no polygon built (:func:`sengine.geom.planar.ring_crossings`,
    on runs of three edges: one candidate's stretch of the line each).
    """
    if len(cand.poly) == 0:
        return np.zeros(0, bool)
    # a line strictly star-shaped round its mean crosses nowhere (planar.star_simple, O(n)): most blocks
    closed = np.r_[C.inner, C.inner[C.mstart[C.m > 0]]]
    ring = np.r_[C.sp, np.flatnonzero(C.m > 0)]
    o = np.argsort(ring, kind="stable")
    live = np.flatnonzero(C.m > 0)
    sure = np.zeros(len(C.m), bool)
    sure[live] = star_simple(closed[o], C.m[live] + 1)
    sel = np.flatnonzero(~sure[C.sp])
    i, j = ring_crossings(C.inner[sel], C.m[~sure & (C.m > 0)], chain=3)
    i, j = sel[i], sel[j]
    return _spans(C, cand, C.sp[i], C.sj[i] // 3, C.sj[j] // 3)


def _pass(rs, depth, segment, min_frontage, C):
    """Paris lots of the polygons of ``rs`` that the certificate accepts (``segment``: m, per polygon).

    Returns lots, their polygon, inner flags, the accepted polygons, the
    number of corner lots, the lots' segment marks and whether each lot's
    marks are known.
    """
    P = rs.n
    cand = _candidates(rs, C, min_frontage)
    bad = (cand.bad | _inner_crossings(C, cand)) & ~cand.core_part
    corners, bad = _corner_lots(C, cand, bad, min_frontage)
    good = ~bad & ~cand.core_part
    cores = _cores(rs, C, cand, good, corners)
    done, core_of, all_merged = cores.done, cores.lot, cores.all_merged
    cp, ja = cand.poly, cand.start
    run_p, s_i, n_i = corners.poly, corners.first, corners.count
    # lots: good candidates, corner lots, cores (small cores join their longest neighbour)
    gsel = good & done[cp]
    csel = done[run_p]
    lots = np.r_[cand.lot.polygons(gsel), corners.lot.polygons(csel)]
    lpoly = np.r_[cp[gsel], run_p[csel]]
    shared = np.r_[
        _back_length(C, cp[gsel], ja[gsel], ja[gsel] + 3, 1),
        _back_length(C, run_p[csel], 3 * s_i[csel], 3 * (s_i + n_i)[csel], 3 * n_i[csel]),
    ]
    has_core = np.flatnonzero(done)
    small = np.zeros(P, bool)
    small[has_core] = shapely.area(core_of[has_core]) < 0.5 * depth * segment[has_core]
    small &= ~all_merged
    merged = np.zeros(P, bool)
    cand_j = np.flatnonzero(small[lpoly])
    if len(cand_j):
        o = np.lexsort((-shared[cand_j], lpoly[cand_j]))
        j = cand_j[o[np.r_[True, lpoly[cand_j][o][1:] != lpoly[cand_j][o][:-1]]]]
        u = _union(lots[j], core_of[lpoly[j]])
        a_sum = shapely.area(lots[j]) + shapely.area(core_of[lpoly[j]])
        oku = (shapely.get_type_id(u) == 3) & (np.abs(shapely.area(u) - a_sum) <= 1e-6 * a_sum)
        lots = lots.copy()
        lots[j[oku]] = u[oku]
        merged[lpoly[j[oku]]] = True
        replaced = j[oku]
    else:
        replaced = np.zeros(0, np.int64)
    kc = np.flatnonzero(done & ~merged)
    lots = np.r_[lots, core_of[kc]]
    lpoly = np.r_[lpoly, kc]
    inner = np.r_[np.zeros(len(lots) - len(kc), bool), ~all_merged[kc] | cores.whole_inner[kc]]
    # segment marks, where the construction knows them (not for GEOS-made lots)
    nq, nc = int(gsel.sum()), int(csel.sum())
    src = Marks.concat([cand.marks.take(np.flatnonzero(gsel)), corners.marks.take(np.flatnonzero(csel)), cores.marks])
    pick = np.r_[np.arange(nq + nc), nq + nc + cores.mark[kc]]
    known = np.r_[np.ones(nq + nc, bool), cores.mark[kc] >= 0]
    known[replaced] = False
    unk = np.flatnonzero(~known)
    src = Marks.concat([src, Marks.unknown(lots[unk])])
    pick[unk] = src.counts.size - len(unk) + np.arange(len(unk))
    return lots, lpoly, inner, done, nc, src.take(pick), known


def _union(a, b):
    """Element-wise union; a pair GEOS cannot unite gives None (that lot and core stay apart)."""
    try:
        return shapely.union(a, b)
    except shapely.errors.GEOSException:
        out = np.empty(len(a), dtype=object)
        for i in range(len(a)):
            try:
                out[i] = shapely.union(a[i], b[i])
            except shapely.errors.GEOSException:
                out[i] = None
        return out


def _back_length(C, p, ja, jb, step):
    """Length (m) of the way back through the inner points of samples jb, jb - step, ..., ja."""
    p, ja, jb = (np.asarray(x, np.int64) for x in (p, ja, jb))
    step = np.broadcast_to(np.asarray(step, np.int64), p.shape)
    nb = (jb - ja) // np.maximum(step, 1)
    row = np.repeat(np.arange(len(p)), nb)
    r = ramp(nb)
    m, ms = C.m[p][row], C.mstart[p][row]
    a = C.inner[ms + np.mod(jb[row] - r * step[row], m)]
    b = C.inner[ms + np.mod(jb[row] - (r + 1) * step[row], m)]
    return np.bincount(row, weights=np.hypot(*(a - b).T), minlength=len(p))


# -- all blocks -------------------------------------------------------------------------------


def _regrown(marks: Marks, lots, grown) -> Marks:
    """``marks`` of lots of which the ``grown`` ones took a sliver: theirs unknown, on their new outline."""
    counts = np.where(grown, Marks.unknown(lots).counts, marks.counts)
    flat = np.zeros(int(counts.sum()), bool)
    same = np.flatnonzero(~grown)
    flat[np.repeat((np.cumsum(counts) - counts)[same], counts[same]) + ramp(counts[same])] = marks.take(same).flat
    return Marks(flat, counts)


def paris_lots(
    blocks,
    *,
    segment=20.0,
    depth=15.0,
    deviation=3.0,
    seeds=None,
    rngs=None,
    min_frontage=2.0,
    min_area=0.0,
    max_cuts=8,
    report=None,
    street=False,
    fronts=None,
    box=None,
):
    """Paris lots (§5.5, Fig. 9 left).

    Parameters
    ----------
    blocks : array_like of shapely.Polygon (n,)
    segment : float or array_like (n,)
        Length of the contour segments (m), one for all blocks or one each;
        each segment becomes one perimeter lot.
    depth, deviation : float
        Mean and standard deviation (m) of the inward displacement of the
        three sub-segments' ends (clipped to [0.2, 3] x depth, and to
        ``REACH`` of half the block's inscribed depth, the radius of its
        largest inscribed circle).
    seeds : array_like of uint64 (n,), optional
        One seed per block; else drawn from ``rngs``; else 0.
    rngs : sequence of numpy.random.Generator (n,), optional
        One generator per block (``SENode.rng(block_id)``).
    min_frontage : float
        Perimeter pieces with less street frontage (m) join a neighbouring
        perimeter lot; only pieces without street join the core.
    min_area : float
        Lots under this area (m2), slivers where a displaced segment meets a
        corner lot, join the neighbour of their block with which they share
        the longest boundary (:func:`sengine.geom.merge.merge_small`), a
        street lot another street lot and an inner lot another inner lot.
    max_cuts : int
        How many times a block the partition test refuses may be cut in
        two before its pieces are kept whole.
    report : dict, optional
        Receives ``paris_inner`` (inner lots: cores, and pieces without
        street kept whole), ``paris_corner`` (corner lots
        merged from overlapping candidates), ``paris_cut`` (cuts made) and
        ``paris_fallback`` (pieces kept whole after ``max_cuts``),
        ``paris_small`` (refused pieces under ``segment`` x ``depth`` kept
        whole: one lot, not cut into slivers), ``merged_slivers`` and
        ``dropped_slivers`` (under 1 m2, touching no neighbour along a side).

    street : bool
        Also return which boundary segment of each lot lies on its block's
        boundary, where the construction knows it.
    fronts : array_like of object (n,), optional
        Per block, the part of its boundary that faces a street (a
        (Multi)LineString, e.g. ``blocks.landuse``'s ``street_front`` where
        open land, water or a park was cut off it), or ``None``: all of it.
        The rest is treated like a cut edge: the candidates along it have
        no street and join the core, so the land behind the street lots
        reaches it as one inner lot instead of lots fronting onto nothing.
    box : tuple of float, optional
        ``(xmin, ymin, xmax, ymax)``: block boundary on this box (the
        extract's edge that closed the land round its streets) is no street.

    Returns
    -------
    lots, owner : ndarray of shapely.Polygon, ndarray of int64 (non-decreasing)
    inner : ndarray of bool
        True for the core lot(s) (courtyards), which touch no street (less
        than ``TOUCH`` = 1 mm of the polygon's street edges).
    on, known : ndarray of bool, only with ``street``
        One mark per boundary segment of the lots (order of
        :func:`sengine.geom.boundary.ring_segments`), and per lot whether the marks
        are known (lots made by GEOS unions are not).
    """
    blocks = np.asarray(blocks, dtype=object).ravel()
    n = len(blocks)
    if seeds is None:
        seeds = (
            np.array([r.integers(0, 2**63, dtype=np.uint64) for r in rngs], np.uint64)
            if rngs is not None
            else np.zeros(n, np.uint64)
        )
    seeds = np.asarray(seeds, np.uint64)
    seg_b = np.broadcast_to(np.asarray(segment, np.float64), (n,))  # per block (blocks.grain's lot sizes)
    parts, own = polygon_parts(blocks, np.arange(n))
    rs = RingSet.from_polygons(parts, flag=True)  # every block edge faces a street ...
    if fronts is not None or box is not None:  # ... but those on open land or the extract's edge
        rs = RingSet(rs.xy, rs.ring, street_edges(rs, own, fronts, box), rs.poly, rs.n)
    keep = np.bincount(rs.poly, minlength=rs.n) > 0
    rs, own = rs.take(keep), own[keep]
    # piece key: 1 + the part's rank in its block (then 2 k + side after cuts): batch independent
    key = (np.arange(rs.n) - np.searchsorted(own, own) + 1).astype(np.uint64)
    out_l, out_o, out_i, out_m, out_k = [], [], [], [], []
    corners = cuts = small = 0
    for level in range(max_cuts + 1):
        if rs.n == 0:
            break
        segment = seg_b[own]  # per piece
        C = Contour(rs, segment)
        with np.errstate(over="ignore"):
            z = _normal(seeds[own][C.sp], key[C.sp] * np.uint64(1_000_003) + C.sj.astype(np.uint64))
        d = np.clip(depth + deviation * z, 0.2 * depth, 3.0 * depth)
        # the cap binds only under the piece's deepest displacement (or the depth, for the smoothing):
        # a piece whose inscribed circle is surely wider than that needs no circle search
        need = np.full(rs.n, depth)
        np.maximum.at(need, C.sp, d)
        cap = REACH * inscribed_radius(rs.polygons(), enough=need / REACH * (1 + 1e-9))
        d = np.minimum(d, cap[C.sp])
        C.smooth(np.minimum(2.0 * np.minimum(depth, cap), C.perim / 8.0))
        C.inner = C.pts + d[:, None] * C.nrm
        lots, lpoly, inner, done, nc, marks, known = _pass(rs, depth, segment, min_frontage, C)
        corners += nc
        out_l.append(lots)
        out_o.append(own[lpoly])
        out_i.append(inner)
        out_m.append(marks)
        out_k.append(known)
        fail = np.flatnonzero(~done)
        if len(fail) and level < max_cuts:
            # a refused piece under one nominal lot (segment x depth) is one lot: cut, it gives slivers
            tiny = fail[shapely.area(rs.take(fail).polygons()) < segment[fail] * depth]
            if len(tiny):
                sub = rs.take(tiny)
                out_l.append(sub.polygons())
                out_o.append(own[tiny])
                out_i.append(sub.flagged_length() < TOUCH)
                out_m.append(Marks.of(sub))
                out_k.append(np.ones(len(tiny), bool))
                small += len(tiny)
                done[tiny] = True
                fail = np.flatnonzero(~done)
        if len(fail) == 0 or level == max_cuts:
            break
        # cut the refused polygons in two across their main axis, and try again
        sub = rs.take(fail)
        axis = sub.min_rect_axis()
        ref, lo, hi = sub.extent_along(axis)
        point = ref + (0.5 * (lo + hi))[:, None] * axis
        pieces, parent, side, failed = split(sub, point, np.stack([-axis[:, 1], axis[:, 0]], axis=1))
        cuts += len(fail) - int(failed.sum())
        stuck = np.flatnonzero(failed)  # could not cut (should not happen): keep whole
        if len(stuck):
            out_l.append(sub.take(stuck).polygons())
            out_o.append(own[fail[stuck]])
            out_i.append(sub.take(stuck).flagged_length() < TOUCH)
            out_m.append(Marks.of(sub.take(stuck)))
            out_k.append(np.ones(len(stuck), bool))
        rs, own, key = pieces, own[fail[parent]], key[fail[parent]] * np.uint64(2) + side.astype(np.uint64)
    fallback = 0
    if rs.n and not done.all():
        rest = np.flatnonzero(~done)
        sub = rs.take(rest)
        fallback = len(rest)
        out_l.append(sub.polygons())
        out_o.append(own[rest])
        out_i.append(sub.flagged_length() < TOUCH)
        out_m.append(Marks.of(sub))
        out_k.append(np.ones(len(rest), bool))
    lots = np.concatenate(out_l) if out_l else np.empty(0, object)
    owner = np.concatenate(out_o).astype(np.int64) if out_o else np.empty(0, np.int64)
    inner = np.concatenate(out_i).astype(bool) if out_i else np.empty(0, bool)
    o = np.argsort(owner, kind="stable")
    lots, owner, inner = lots[o], owner[o], inner[o]
    marks = Marks.concat(out_m).take(o)
    known = np.concatenate(out_k)[o] if out_k else np.zeros(0, bool)
    merged = dropped = 0
    if min_area > 0 and (shapely.area(lots) < min_area).any():
        # a sliver on the street joins a street lot, never the courtyard (which has no street)
        lots, keep, grown, merged, dropped = merge_small(lots, 2 * owner + inner, min_area)
        owner, inner, known = owner[keep], inner[keep], known[keep] & ~grown
        marks = _regrown(marks.take(keep), lots, grown)
    if report is not None:
        for k, v in (
            ("paris_inner", int(inner.sum())),
            ("paris_corner", corners),
            ("paris_cut", cuts),
            ("paris_fallback", fallback),
            ("paris_small", small),
            ("merged_slivers", merged),
            ("dropped_slivers", dropped),
        ):
            report[k] = report.get(k, 0) + v
    return (lots, owner, inner) + ((marks.flat, known) if street else ())

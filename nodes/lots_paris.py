"""Paris lots (skylineEngine §5.5, Fig. 9 left).

The contour of the block is split into equal segments; at each segment end
the inner normal is computed; each segment is split into three rectilinear
sub-segments whose ends are displaced inwards along their inner normals by a
random depth (mean ``depth``, deviation ``deviation``).  Lots are the
regions between the contour segments and the displaced inner line; the
remaining core is an inner lot (courtyard).

How it is computed, for all blocks at once and without polygon overlay:

1. Sample points, inner normals (the contour's direction averaged over about
   one lot depth, so that lots fan out around corners and curves instead of
   crossing) and displaced points come from numpy interpolation along the
   exterior rings; depths are clamped to 0.3 of the block's typical width
   (2 area / perimeter) so that thin blocks keep a courtyard.
2. Each candidate lot is the polygon "contour segment, then its displaced
   points backwards"; the core is the polygon through all displaced points.
   Their boundaries add up to the block's contour (radial edges and the inner
   line cancel out), so when each of them is a simple counter-clockwise
   polygon they partition the block exactly: the winding numbers of the
   pieces add up to the block's and none is negative.  Vectorized
   ``is_valid`` calls check that.
3. Candidates that are not simple, or overlap a neighbour (tested on windows
   of three consecutive candidates, whose union must be simple too), are
   merged run by run into one corner lot closed by a straight back edge;
   a run whose corner lot is not simple either, and candidates with too
   little street frontage, are merged into the core (which then reaches the
   contour there).
4. A block whose core is still not simple (thin arms, holes outside the
   core) is cut in two across its main axis (:func:`sengine.split.split`;
   the cut edges are not streets, so no lot faces them) and the halves start
   again, a few times; what remains is kept whole and counted.

Randomness is a hash of (block seed, piece, sample), so results do not depend
on the order blocks are processed in.

References
----------
skylineEngine §5.5, Fig. 9.
"""

from __future__ import annotations

import logging

import numpy as np
import shapely

from sengine.geometry import threaded
from sengine.split import RingSet, polygon_parts, split

from .lots_recursive import hash01

__all__ = ["paris_lots"]

log = logging.getLogger(__name__)


def _ramp(counts):
    """0, 1, ..., c - 1 for each count, concatenated."""
    counts = np.asarray(counts, np.int64)
    return np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)


def _first_of(groups, n):
    return np.r_[0, np.cumsum(np.bincount(groups, minlength=n))].astype(np.int64)


def _normal(seed, key):
    """Standard normal numbers from (seed, key) uint64 pairs (Box-Muller on two hashes)."""
    key = np.asarray(key, np.uint64)
    with np.errstate(over="ignore"):
        u1 = hash01(seed, key * np.uint64(2) + np.uint64(1))
        u2 = hash01(seed, key * np.uint64(2) + np.uint64(2))
    return np.sqrt(-2.0 * np.log(np.maximum(u1, 1e-300))) * np.cos(2.0 * np.pi * u2)


def _clean(geoms, area):
    """Simple, counter-clockwise polygons (the partition certificate's test)."""
    ok = np.asarray(area) > 0
    ok[ok] = threaded(shapely.is_valid, np.asarray(geoms, dtype=object)[ok])  # GEOS runs without the GIL
    return ok


class _Marks:
    """One mark per boundary segment of each of a list of polygons (flat, with counts)."""

    def __init__(self, flat, counts):
        self.flat = np.asarray(flat, bool)
        self.counts = np.asarray(counts, np.int64)

    def take(self, idx) -> _Marks:
        idx = np.asarray(idx, np.int64)
        c = self.counts[idx]
        return _Marks(self.flat[np.repeat((np.cumsum(self.counts) - self.counts)[idx], c) + _ramp(c)], c)

    @staticmethod
    def concat(marks) -> _Marks:
        marks = list(marks)
        return _Marks(np.concatenate([m.flat for m in marks]) if marks else np.zeros(0, bool),
                      np.concatenate([m.counts for m in marks]) if marks else np.zeros(0, np.int64))

    @classmethod
    def unknown(cls, geoms) -> _Marks:
        geoms = np.asarray(geoms, dtype=object)
        c = np.maximum(shapely.get_num_coordinates(geoms) - 1 - shapely.get_num_interior_rings(geoms), 0)
        return cls(np.zeros(int(c.sum()), bool), c)

    @classmethod
    def of(cls, rs: RingSet) -> _Marks:
        return cls(rs.flag, np.bincount(rs.vertex_poly(), minlength=rs.n))


# -- the contour ------------------------------------------------------------------------------

class _Contour:
    """Samples along the exterior ring of each polygon of a ring set, and polygons made of its chains.

    The ring is kept as two laps (vertices repeated once) so that a stretch
    of contour crossing the ring's start is one contiguous slice.  Sample
    ``j`` of polygon ``p`` lies at arc length ``j * perim / m`` (m = 3 nseg).
    """

    def __init__(self, rs: RingSet, segment: float):
        P = rs.n
        first_ring = _first_of(rs.poly, P)[:-1]
        has = np.bincount(rs.poly, minlength=P) > 0
        ext = np.zeros(len(rs.poly), bool)
        ext[first_ring[has]] = True
        sel = ext[rs.ring]
        nx = rs.next_vertex()
        v, vi, flag = rs.xy[sel], rs.poly[rs.ring[sel]], rs.flag[sel]
        nxt = rs.xy[nx[sel]]
        el = np.hypot(*(nxt - v).T)
        nv = np.bincount(vi, minlength=P)
        perim = np.bincount(vi, weights=el, minlength=P)
        arc = np.cumsum(el) - el - (np.cumsum(perim) - perim)[vi]
        self.v, self.vi, self.varc = v, vi, arc
        # two laps; polygons 1 m apart on one increasing arc coordinate
        goff = np.cumsum(2 * perim + 1.0) - (2 * perim + 1.0)
        vstart = np.cumsum(nv) - nv
        k = np.arange(len(v)) - vstart[vi]
        lap = np.r_[vstart[vi] + k, vstart[vi] + k]
        second = np.r_[np.zeros(len(v), bool), np.ones(len(v), bool)]
        o = np.lexsort((k[lap], second, vi[lap]))
        lap, second = lap[o], second[o]
        self.lap_xy, self.lap_next, self.lap_len = v[lap], nxt[lap], el[lap]
        self.lap_flag = flag[lap]
        self.lap_arc = arc[lap] + np.where(second, perim[vi[lap]], 0.0)  # within the polygon
        self.lap_g = goff[vi[lap]] + self.lap_arc  # to search all polygons at once
        fl = np.where(self.lap_flag, self.lap_len, 0.0)
        self.lap_F = np.cumsum(fl) - fl  # street length before each lap edge (global)
        self.lstart, self.nlap = 2 * vstart, 2 * nv
        self.goff, self.perim = goff, perim
        self.nseg = np.where(has, np.maximum(3, np.floor(perim / segment + 0.5)), 0).astype(np.int64)
        self.m = 3 * self.nseg
        self.mstart = np.cumsum(self.m) - self.m
        self.sp = np.repeat(np.arange(P), self.m)
        self.sj = _ramp(self.m)
        self.s = self.sj * (perim / np.maximum(self.m, 1))[self.sp]
        self.pts = self._at(self.sp, self.s)
        self.nrm = np.zeros_like(self.pts)
        self.inner = self.pts

    def _search(self, p, s, right=True):
        """Lap index of the last vertex at or before (``right``) / strictly before arc ``s``, plus one.

        The global search only gives a first guess (the polygon's offset
        rounds ``s``); the answer is settled on the polygon's own arcs, so it
        does not depend on which other polygons share the batch.
        """
        i = np.searchsorted(self.lap_g, self.goff[p] + s, side="right" if right else "left")
        lo, hi = self.lstart[p], self.lstart[p] + self.nlap[p]
        i = np.clip(i, lo, hi)
        for _ in range(4):  # at most a step or two: rounding is far below edge lengths
            before = (i > lo) & ((self.lap_arc[np.maximum(i - 1, 0)] > s) if right
                                 else (self.lap_arc[np.maximum(i - 1, 0)] >= s))
            after = (i < hi) & ((self.lap_arc[np.minimum(i, len(self.lap_arc) - 1)] <= s) if right
                                else (self.lap_arc[np.minimum(i, len(self.lap_arc) - 1)] < s))
            if not (before.any() or after.any()):
                break
            i = i - before + after
        return i

    def _index(self, p, s):
        i = np.clip(self._search(p, s) - 1, self.lstart[p], self.lstart[p] + self.nlap[p] - 1)
        return i, s - self.lap_arc[i]

    def _at(self, p, s):
        """Points at arc length ``s`` in [0, 2 perim) of polygons ``p``."""
        i, r = self._index(p, s)
        f = np.clip(r / np.where(self.lap_len[i] > 0, self.lap_len[i], 1.0), 0.0, 1.0)
        return self.lap_xy[i] + f[:, None] * (self.lap_next[i] - self.lap_xy[i])

    def street(self, p, s0, s1):
        """Street (flagged) length (m) of the contour between arcs ``s0 < s1`` (< 2 perim)."""
        def F(s):
            i, r = self._index(p, s)
            return self.lap_F[i] + np.where(self.lap_flag[i], np.clip(r, 0.0, self.lap_len[i]), 0.0)
        return F(s1) - F(s0)

    def smooth(self, width):
        """Inner normals from the contour's direction over ``width`` (m, per polygon) on each side."""
        delta = np.asarray(width, np.float64)[self.sp]
        pa = self._at(self.sp, np.mod(self.s - delta, self.perim[self.sp]))
        pb = self._at(self.sp, self.s + delta)
        tan = pb - pa
        tan /= np.maximum(np.hypot(tan[:, 0], tan[:, 1]), 1e-12)[:, None]
        self.nrm = np.stack([-tan[:, 1], tan[:, 0]], axis=1)  # left of a counter-clockwise ring: inwards

    def arc(self, p, j):
        """Arc length (m) of sample ``j`` (unwrapped: may exceed m) of polygons ``p``."""
        return j * (self.perim / np.maximum(self.m, 1))[p]

    def _ring_vertices(self, p, ja, jb):
        """First lap index and count of the ring vertices strictly between samples ``ja`` and ``jb``."""
        i0 = self._search(p, self.arc(p, ja) + 1e-9, right=True)
        i1 = self._search(p, self.arc(p, jb) - 1e-9, right=False)
        return i0, np.maximum(i1 - i0, 0)

    def _polygons(self, kinds, idx, sizes, seg):
        """Polygons from (kind, index) coordinates: kind 0 sample point, 1 inner point, 2 lap vertex.

        ``seg`` marks the segment starting at each coordinate as lying on
        the contour's street edges.  Returns the polygons, their signed
        areas and their segment marks (a :class:`_Marks`).
        """
        table_off = np.array([0, len(self.pts), 2 * len(self.pts)])
        table = np.concatenate([self.pts, self.inner, self.lap_xy])
        xy = table[table_off[kinds] + idx]
        polys = shapely.from_ragged_array(shapely.GeometryType.POLYGON, xy,
                                          (np.r_[0, np.cumsum(sizes)], np.arange(len(sizes) + 1)))
        # signed areas of the closed rings, local to each ring's first vertex
        start = np.cumsum(sizes) - sizes
        ring = np.repeat(np.arange(len(sizes)), sizes)
        q = xy - xy[start][ring]
        last = np.r_[ring[1:] != ring[:-1], True] if len(ring) else np.zeros(0, bool)
        qn = np.r_[q[1:], q[:1]]
        cr = np.where(last, 0.0, q[:, 0] * qn[:, 1] - q[:, 1] * qn[:, 0])
        return polys, 0.5 * np.bincount(ring, weights=cr, minlength=len(sizes)), _Marks(seg[~last], sizes - 1)

    def chains(self, p, ja, jb, step):
        """Polygons: contour from sample ``ja`` to ``jb`` then the inner points of jb, jb - step, ..., ja.

        ``jb`` is unwrapped (``ja < jb <= ja + m``) and ``step`` divides
        ``jb - ja``.  Returns the polygons and their street length (m).
        """
        p, ja, jb = (np.asarray(x, np.int64) for x in (p, ja, jb))
        step = np.broadcast_to(np.asarray(step, np.int64), p.shape)
        m, ms = self.m[p], self.mstart[p]
        i0, nv = self._ring_vertices(p, ja, jb)
        nb = (jb - ja) // step + 1
        size = nv + nb + 3
        row = np.repeat(np.arange(len(p)), size)
        r = _ramp(size)
        nvr = nv[row]
        kinds = np.zeros(len(row), np.int64)
        idx = (ms + np.mod(ja, m))[row]  # pts[ja]: first and closing coordinates
        mid = (r >= 1) & (r <= nvr)
        kinds[mid] = 2
        idx[mid] = i0[row[mid]] + r[mid] - 1
        at_b = r == nvr + 1
        idx[at_b] = (ms + np.mod(jb, m))[row[at_b]]
        back = (r >= nvr + 2) & (r < size[row] - 1)
        q = r[back] - nvr[back] - 2
        rb = row[back]
        kinds[back] = 1
        idx[back] = ms[rb] + np.mod(jb[rb] - q * step[rb], m[rb])
        seg = np.zeros(len(row), bool)
        contour = r <= nvr
        seg[contour] = self.lap_flag[i0[row[contour]] - 1 + r[contour]]
        polys, area, marks = self._polygons(kinds, idx, size, seg)
        return polys, area, self.street(p, self.arc(p, ja), self.arc(p, jb)), marks

    def core(self, p, ja, jb, kind):
        """One core ring per polygon from units in ring order: kind 0 a lot's inner chain,
        1 a corner lot's back edge, 2 merged contour (radial in, contour, radial out).

        Units must be sorted by polygon and cover each polygon's ring.
        """
        p, ja, jb, kind = (np.asarray(x, np.int64) for x in (p, ja, jb, kind))
        i0, nv = self._ring_vertices(p, ja, jb)
        cnt = np.where(kind == 0, 3, np.where(kind == 1, 1, 3 + nv))
        m, ms = self.m[p], self.mstart[p]
        row = np.repeat(np.arange(len(p)), cnt)
        r = _ramp(cnt)
        kinds = np.ones(len(row), np.int64)
        idx = (ms + np.mod(ja, m))[row]  # inner[ja] starts every unit
        lot = (kind[row] == 0) & (r > 0)
        idx[lot] = ms[row[lot]] + np.mod(ja[row[lot]] + r[lot], m[row[lot]])
        mer = (kind[row] == 2) & (r > 0)
        rr = r[mer]
        rm = row[mer]
        kinds[mer] = np.where(rr == 1, 0, np.where(rr <= nv[rm] + 1, 2, 0))
        idx[mer] = np.where(rr == 1, ms[rm] + np.mod(ja[rm], m[rm]),
                            np.where(rr <= nv[rm] + 1, i0[rm] + rr - 2, ms[rm] + np.mod(jb[rm], m[rm])))
        seg = np.zeros(len(row), bool)
        contour = (kind[row] == 2) & (r >= 1) & (r <= nv[row] + 1)
        seg[contour] = self.lap_flag[i0[row[contour]] + r[contour] - 2]
        # close each polygon's ring with its first coordinate
        P = len(self.m)
        per = np.bincount(p[row], minlength=P)
        has = per > 0
        start = np.cumsum(per) - per
        order = np.r_[np.arange(len(row)), start[has]]
        owner = np.r_[p[row], np.flatnonzero(has)]
        o = np.argsort(owner, kind="stable")
        sizes = np.bincount(owner, minlength=P)
        seg = np.r_[seg, np.zeros(int(has.sum()), bool)]
        polys, area, marks = self._polygons(kinds[order[o]], idx[order[o]], sizes[sizes > 0], seg[order[o]])
        return polys, area, np.flatnonzero(has), marks


# -- one pass over a set of polygons ------------------------------------------------------------

RISK = 0.5  # an inner segment shorter than this share of its contour segment (or reversed) is risky


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


def _pass(rs, depth, segment, min_frontage, C):
    """Paris lots of the polygons of ``rs`` that the certificate accepts.

    Returns lots, their polygon, inner flags, the accepted polygons and the
    number of corner lots.
    """
    P = rs.n
    nseg = C.nseg
    cp = np.repeat(np.arange(P), nseg)
    ci = _ramp(nseg)
    ja = 3 * ci
    one = np.ones(len(cp), np.int64)
    q, qa, front, qm = C.chains(cp, ja, ja + 3, one)
    merge = front < min_frontage  # too little street: part of the core
    bad = ~_clean(q, qa) & ~merge
    # windows of w consecutive candidates: their union must be simple too,
    # otherwise two of them overlap (winding numbers add up)
    # (only where the inner line folds or bunches up: elsewhere neighbours cannot meet)
    w = np.minimum(3, nseg - 1)[cp]
    di = C.inner[C.mstart[C.sp] + np.mod(C.sj + 1, C.m[C.sp])] - C.inner
    dp = C.pts[C.mstart[C.sp] + np.mod(C.sj + 1, C.m[C.sp])] - C.pts
    fold = np.einsum("ij,ij->i", di, dp) < RISK * np.einsum("ij,ij->i", dp, dp)
    risky = np.bincount((cstart_of(C)[C.sp] + C.sj // 3)[fold],
                        minlength=len(cp)) > 0
    near = risky.copy()
    for k in (1, 2):  # a window starting at i covers i .. i + 2
        near |= risky[cstart_of(C)[cp] + np.mod(ci + k, nseg[cp])]
    wsel = np.flatnonzero(near)
    bad_win = np.zeros(len(cp), bool)
    if len(wsel):
        win, wa, _, _ = C.chains(cp[wsel], ja[wsel], ja[wsel] + 3 * w[wsel], one[wsel])
        bad_win[wsel] = ~_clean(win, wa)
    cstart = np.cumsum(nseg) - nseg
    for k in range(3):
        sel = bad_win & (k < w)
        bad[cstart[cp[sel]] + np.mod(ci[sel] + k, nseg[cp[sel]])] = True
    bad &= ~merge
    # runs of bad candidates become corner lots; a run whose corner lot is
    # not simple grows by one candidate on each side, then joins the core
    for it in range(3):
        run_p, s_i, n_i = _runs(bad, cp, ci, nseg)
        corner, ca, cfront, _ = C.chains(run_p, 3 * s_i, 3 * (s_i + n_i), 3 * n_i)
        f = ~(_clean(corner, ca) & (cfront >= min_frontage))
        if not f.any():
            break
        base, first, cnt, nn = cstart[run_p[f]], s_i[f], n_i[f], nseg[run_p[f]]
        if it < 2:  # grow
            for at in (base + np.mod(first - 1, nn), base + np.mod(first + cnt, nn)):
                bad[at] |= ~merge[at]
        else:  # give up: these candidates join the core
            members = np.repeat(base, cnt) + np.mod(np.repeat(first, cnt) + _ramp(cnt), np.repeat(nn, cnt))
            merge[members] = True
            bad[members] = False
    run_p, s_i, n_i = _runs(bad, cp, ci, nseg)
    corner, ca, cfront, cm = C.chains(run_p, 3 * s_i, 3 * (s_i + n_i), 3 * n_i)
    merge_runs = _runs(merge, cp, ci, nseg)
    good = ~bad & ~merge
    # the core, unit after unit in ring order
    gi = np.flatnonzero(good)
    mp, ms_, mn = merge_runs
    up = np.r_[cp[gi], run_p, mp]
    ua = np.r_[ja[gi], 3 * s_i, 3 * ms_]
    ub = np.r_[ja[gi] + 3, 3 * (s_i + n_i), 3 * (ms_ + mn)]
    uk = np.r_[np.zeros(len(gi), np.int64), np.ones(len(run_p), np.int64), np.full(len(mp), 2, np.int64)]
    o = np.lexsort((np.mod(ua, C.m[up]), up))
    core, core_a, cpoly, corem = C.core(up[o], ua[o], ub[o], uk[o])
    all_merged = np.bincount(cp, weights=~merge, minlength=P) == 0
    done = np.zeros(P, bool)
    done[cpoly] = _clean(core, core_a)
    core_of = np.full(P, None, dtype=object)
    core_of[cpoly] = core
    core_mark = np.full(P, -1, np.int64)  # index into corem, -1: unknown marks
    core_mark[cpoly] = np.arange(len(cpoly))
    done &= np.bincount(run_p, weights=~_clean(corner, ca) | (cfront < min_frontage), minlength=P) == 0
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
    whole = np.flatnonzero(all_merged)  # no street worth a lot: the polygon is one inner lot
    done[whole] = True
    whole_m = _Marks.of(rs.take(whole))
    if len(whole):
        core_of[whole] = rs.take(whole).polygons()
        core_mark[whole] = len(cpoly) + np.arange(len(whole))
    corem = _Marks.concat([corem, whole_m])
    # lots: good candidates, corner lots, cores (small cores join their longest neighbour)
    gsel = good & done[cp]
    csel = done[run_p]
    lots = np.r_[q[gsel], corner[csel]]
    lpoly = np.r_[cp[gsel], run_p[csel]]
    shared = np.r_[_back_length(C, cp[gsel], ja[gsel], ja[gsel] + 3, 1),
                   _back_length(C, run_p[csel], 3 * s_i[csel], 3 * (s_i + n_i)[csel], 3 * n_i[csel])]
    has_core = np.flatnonzero(done)
    small = np.zeros(P, bool)
    small[has_core] = shapely.area(core_of[has_core]) < 0.5 * depth * segment
    small &= ~all_merged
    merged = np.zeros(P, bool)
    cand = np.flatnonzero(small[lpoly])
    if len(cand):
        o = np.lexsort((-shared[cand], lpoly[cand]))
        j = cand[o[np.r_[True, lpoly[cand][o][1:] != lpoly[cand][o][:-1]]]]
        u = shapely.union(lots[j], core_of[lpoly[j]])
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
    inner = np.r_[np.zeros(len(lots) - len(kc), bool), np.ones(len(kc), bool)]
    # segment marks, where the construction knows them (not for GEOS-made lots)
    nq, nc = int(gsel.sum()), int(csel.sum())
    src = _Marks.concat([qm.take(np.flatnonzero(gsel)), cm.take(np.flatnonzero(csel)), corem])
    pick = np.r_[np.arange(nq + nc), nq + nc + core_mark[kc]]
    known = np.r_[np.ones(nq + nc, bool), core_mark[kc] >= 0]
    known[replaced] = False
    unk = np.flatnonzero(~known)
    src = _Marks.concat([src, _Marks.unknown(lots[unk])])
    pick[unk] = src.counts.size - len(unk) + np.arange(len(unk))
    return lots, lpoly, inner, done, nc, src.take(pick), known


def _back_length(C, p, ja, jb, step):
    """Length (m) of the way back through the inner points of samples jb, jb - step, ..., ja."""
    p, ja, jb = (np.asarray(x, np.int64) for x in (p, ja, jb))
    step = np.broadcast_to(np.asarray(step, np.int64), p.shape)
    nb = (jb - ja) // np.maximum(step, 1)
    row = np.repeat(np.arange(len(p)), nb)
    r = _ramp(nb)
    m, ms = C.m[p][row], C.mstart[p][row]
    a = C.inner[ms + np.mod(jb[row] - r * step[row], m)]
    b = C.inner[ms + np.mod(jb[row] - (r + 1) * step[row], m)]
    return np.bincount(row, weights=np.hypot(*(a - b).T), minlength=len(p))


# -- all blocks -------------------------------------------------------------------------------

def paris_lots(blocks, *, segment=20.0, depth=15.0, deviation=3.0, seeds=None, rngs=None, min_frontage=2.0,
               max_cuts=8, report=None, street=False):
    """Paris lots (§5.5, Fig. 9 left).

    Parameters
    ----------
    blocks : array_like of shapely.Polygon (n,)
    segment : float
        Length of the contour segments (m); each becomes one perimeter lot.
    depth, deviation : float
        Mean and standard deviation (m) of the inward displacement of the
        three sub-segments' ends (clipped to [0.2, 3] x depth, and to 0.3 of
        the block's typical width 2 area / perimeter).
    seeds : array_like of uint64 (n,), optional
        One seed per block; else drawn from ``rngs``; else 0.
    rngs : sequence of numpy.random.Generator (n,), optional
        One generator per block (``SENode.rng(block_id)``).
    min_frontage : float
        Perimeter pieces with less street frontage (m) join the core.
    max_cuts : int
        How many times a block the partition test refuses may be cut in
        two before its pieces are kept whole.
    report : dict, optional
        Receives ``paris_inner`` (core lots), ``paris_corner`` (corner lots
        merged from overlapping candidates), ``paris_cut`` (cuts made) and
        ``paris_fallback`` (pieces kept whole).

    street : bool
        Also return which boundary segment of each lot lies on its block's
        boundary, where the construction knows it.

    Returns
    -------
    lots, owner : ndarray of shapely.Polygon, ndarray of int64 (non-decreasing)
    inner : ndarray of bool
        True for the core lot(s) (courtyards) that need not touch a street.
    on, known : ndarray of bool, only with ``street``
        One mark per boundary segment of the lots (order of
        :func:`sengine.split.ring_segments`), and per lot whether the marks
        are known (lots made by GEOS unions are not).
    """
    blocks = np.asarray(blocks, dtype=object).ravel()
    n = len(blocks)
    if seeds is None:
        seeds = np.array([r.integers(0, 2**63, dtype=np.uint64) for r in rngs], np.uint64) if rngs is not None \
            else np.zeros(n, np.uint64)
    seeds = np.asarray(seeds, np.uint64)
    parts, own = polygon_parts(blocks, np.arange(n))
    rs = RingSet.from_polygons(parts, flag=True)  # every block edge faces a street
    keep = np.bincount(rs.poly, minlength=rs.n) > 0
    rs, own = rs.take(keep), own[keep]
    # piece key: 1 + the part's rank in its block (then 2 k + side after cuts): batch independent
    key = (np.arange(rs.n) - np.searchsorted(own, own) + 1).astype(np.uint64)
    out_l, out_o, out_i, out_m, out_k = [], [], [], [], []
    corners = cuts = 0
    for level in range(max_cuts + 1):
        if rs.n == 0:
            break
        C = _Contour(rs, segment)
        width = 2.0 * rs.areas() / np.maximum(C.perim, 1e-12)
        with np.errstate(over="ignore"):
            z = _normal(seeds[own][C.sp], key[C.sp] * np.uint64(1_000_003) + C.sj.astype(np.uint64))
        d = np.clip(depth + deviation * z, 0.2 * depth, 3.0 * depth)
        d = np.minimum(d, 0.3 * width[C.sp])
        C.smooth(np.minimum(2.0 * np.minimum(depth, 0.3 * width), C.perim / 8.0))
        C.inner = C.pts + d[:, None] * C.nrm
        lots, lpoly, inner, done, nc, marks, known = _pass(rs, depth, segment, min_frontage, C)
        corners += nc
        out_l.append(lots)
        out_o.append(own[lpoly])
        out_i.append(inner)
        out_m.append(marks)
        out_k.append(known)
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
            out_i.append(np.zeros(len(stuck), bool))
            out_m.append(_Marks.of(sub.take(stuck)))
            out_k.append(np.ones(len(stuck), bool))
        rs, own, key = pieces, own[fail[parent]], key[fail[parent]] * np.uint64(2) + side.astype(np.uint64)
    fallback = 0
    if rs.n and not done.all():
        rest = np.flatnonzero(~done)
        sub = rs.take(rest)
        fallback = len(rest)
        out_l.append(sub.polygons())
        out_o.append(own[rest])
        out_i.append(sub.flagged_length() < min_frontage)
        out_m.append(_Marks.of(sub))
        out_k.append(np.ones(len(rest), bool))
    lots = np.concatenate(out_l) if out_l else np.empty(0, object)
    owner = np.concatenate(out_o).astype(np.int64) if out_o else np.empty(0, np.int64)
    inner = np.concatenate(out_i).astype(bool) if out_i else np.empty(0, bool)
    o = np.argsort(owner, kind="stable")
    lots, owner, inner = lots[o], owner[o], inner[o]
    marks = _Marks.concat(out_m).take(o)
    known = np.concatenate(out_k)[o] if out_k else np.zeros(0, bool)
    if report is not None:
        for k, v in (("paris_inner", int(inner.sum())), ("paris_corner", corners), ("paris_cut", cuts),
                     ("paris_fallback", fallback)):
            report[k] = report.get(k, 0) + v
    return (lots, owner, inner) + ((marks.flat, known) if street else ())

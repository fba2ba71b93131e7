"""Contours of polygons for Paris lots (skylineEngine §5.5): samples, normals, chain polygons.

:class:`Contour` samples the exterior ring of each polygon of a
:class:`sengine.geom.ringset.RingSet` at equal arc lengths, gives each sample an
inner normal averaged over the contour around it, and builds polygons out
of contour stretches and displaced ("inner") points in one vectorized pass:
the candidate lots and corner lots (:meth:`Contour.chains`) and the core
(:meth:`Contour.core`), with the signed area of each and, per boundary
segment, whether it lies on a street edge of the contour (:class:`Marks`).
"""

from __future__ import annotations

import numpy as np
import shapely

from sengine.geom.split import RingSet

__all__ = ["Contour", "Marks", "Rings", "ramp"]


def ramp(counts):
    """0, 1, ..., c - 1 for each count, concatenated."""
    counts = np.asarray(counts, np.int64)
    return np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)


def _first_of(groups, n):
    return np.r_[0, np.cumsum(np.bincount(groups, minlength=n))].astype(np.int64)


def _scan(x, group):
    """Running sums of ``x`` within each group (``group`` non-decreasing).

    A Hillis-Steele scan: each sum depends on its own group's values only, to
    the last bit, so a polygon's arcs do not depend on the polygons before it
    in the batch (a global ``cumsum`` minus an offset would).
    """
    y = np.asarray(x, np.float64).copy()
    if len(y) == 0:
        return y
    start = np.flatnonzero(np.r_[True, group[1:] != group[:-1]])
    pos = np.arange(len(y)) - np.repeat(start, np.diff(np.r_[start, len(y)]))
    k = 1
    top = int(pos.max())
    while k <= top:
        i = np.flatnonzero(pos >= k)
        y[i] = y[i] + y[i - k]  # the right side is read before the write
        k *= 2
    return y


class Marks:
    """One mark per boundary segment of each of a list of polygons (flat, with counts)."""

    def __init__(self, flat, counts):
        self.flat = np.asarray(flat, bool)
        self.counts = np.asarray(counts, np.int64)

    def take(self, idx) -> Marks:
        idx = np.asarray(idx, np.int64)
        c = self.counts[idx]
        return Marks(self.flat[np.repeat((np.cumsum(self.counts) - self.counts)[idx], c) + ramp(c)], c)

    @staticmethod
    def concat(marks) -> Marks:
        marks = list(marks)
        return Marks(
            np.concatenate([m.flat for m in marks]) if marks else np.zeros(0, bool),
            np.concatenate([m.counts for m in marks]) if marks else np.zeros(0, np.int64),
        )

    @classmethod
    def unknown(cls, geoms) -> Marks:
        geoms = np.asarray(geoms, dtype=object)
        c = np.maximum(shapely.get_num_coordinates(geoms) - 1 - shapely.get_num_interior_rings(geoms), 0)
        return cls(np.zeros(int(c.sum()), bool), c)

    @classmethod
    def of(cls, rs: RingSet) -> Marks:
        return cls(rs.flag, np.bincount(rs.vertex_poly(), minlength=rs.n))


def _build(xy, sizes):
    """Polygons from closed rings given one after another."""
    sizes = np.asarray(sizes, np.int64)
    return shapely.from_ragged_array(
        shapely.GeometryType.POLYGON, xy, (np.r_[0, np.cumsum(sizes)], np.arange(len(sizes) + 1))
    )


class Rings:
    """Closed rings one after another (coordinates and counts): polygons not built until asked for."""

    def __init__(self, xy, sizes):
        self.xy = np.asarray(xy, np.float64)
        self.sizes = np.asarray(sizes, np.int64)
        self._built = None  # the polygons built so far (None: not yet)

    def __len__(self) -> int:
        return len(self.sizes)

    def take(self, idx) -> Rings:
        idx = np.asarray(idx)
        if idx.dtype == bool:
            idx = np.flatnonzero(idx)
        c = self.sizes[idx]
        return Rings(self.xy[np.repeat((np.cumsum(self.sizes) - self.sizes)[idx], c) + ramp(c)], c)

    def polygons(self, idx=None) -> np.ndarray:
        """The polygons (of rings ``idx``, all by default); each ring is built once."""
        idx = np.arange(len(self)) if idx is None else np.asarray(idx)
        if idx.dtype == bool:
            idx = np.flatnonzero(idx)
        if self._built is None:
            self._built = np.full(len(self), None, dtype=object)
        todo = np.unique(idx[shapely.is_missing(self._built[idx])])
        if len(todo):
            r = self.take(todo)
            self._built[todo] = _build(r.xy, r.sizes)
        return self._built[idx]


# -- the contour ------------------------------------------------------------------------------


class Contour:
    """Samples along the exterior ring of each polygon of a ring set, and polygons made of its chains.

    The ring is kept as two laps (vertices repeated once) so that a stretch
    of contour crossing the ring's start is one contiguous slice.  Sample
    ``j`` of polygon ``p`` lies at arc length ``j * perim / m`` (m = 3 nseg).
    """

    def __init__(self, rs: RingSet, segment: float | np.ndarray):
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
        arc = _scan(el, vi) - el  # arc length of each vertex from its ring's start
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
        self.lap_F = _scan(fl, vi[lap]) - fl  # street length before each lap edge, within its polygon
        self.lstart, self.nlap = 2 * vstart, 2 * nv
        self.goff, self.perim = goff, perim
        self.nseg = np.where(has, np.maximum(3, np.floor(perim / segment + 0.5)), 0).astype(np.int64)
        self.m = 3 * self.nseg
        self.mstart = np.cumsum(self.m) - self.m
        self.sp = np.repeat(np.arange(P), self.m)
        self.sj = ramp(self.m)
        self.s = self.sj * (perim / np.maximum(self.m, 1))[self.sp]
        self.pts = self._at(self.sp, self.s)
        self.nrm = np.zeros_like(self.pts)
        self.inner = self.pts
        self._table = None  # (inner, coordinate table of _polygons)

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
            before = (i > lo) & (
                (self.lap_arc[np.maximum(i - 1, 0)] > s) if right else (self.lap_arc[np.maximum(i - 1, 0)] >= s)
            )
            after = (i < hi) & (
                (self.lap_arc[np.minimum(i, len(self.lap_arc) - 1)] <= s)
                if right
                else (self.lap_arc[np.minimum(i, len(self.lap_arc) - 1)] < s)
            )
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

    def _polygons(self, kinds, idx, sizes, seg, lazy=False):
        """Polygons from (kind, index) coordinates: kind 0 sample point, 1 inner point, 2 lap vertex.

        ``seg`` marks the segment starting at each coordinate as lying on
        the contour's street edges.  Returns the polygons (as :class:`Rings`
        with ``lazy``), their signed areas and their segment marks (a
        :class:`Marks`).
        """
        table_off = np.array([0, len(self.pts), 2 * len(self.pts)])
        if self._table is None or self._table[0] is not self.inner:  # made once per set of inner points
            self._table = (self.inner, np.concatenate([self.pts, self.inner, self.lap_xy]))
        xy = self._table[1][table_off[kinds] + idx]
        polys = Rings(xy, sizes) if lazy else _build(xy, sizes)
        # signed areas of the closed rings, local to each ring's first vertex
        start = np.cumsum(sizes) - sizes
        ring = np.repeat(np.arange(len(sizes)), sizes)
        q = xy - xy[start[ring]]
        last = np.r_[ring[1:] != ring[:-1], True] if len(ring) else np.zeros(0, bool)
        cr = np.zeros(len(ring))  # each coordinate's cross product with the next one of its ring (0: the last)
        cr[:-1] = q[:-1, 0] * q[1:, 1] - q[:-1, 1] * q[1:, 0]
        cr[last] = 0.0
        return polys, 0.5 * np.bincount(ring, weights=cr, minlength=len(sizes)), Marks(seg[~last], sizes - 1)

    def chains(self, p, ja, jb, step, lazy=False):
        """Polygons: contour from sample ``ja`` to ``jb`` then the inner points of jb, jb - step, ..., ja.

        ``jb`` is unwrapped (``ja < jb <= ja + m``) and ``step`` divides
        ``jb - ja``.  Returns the polygons (their :class:`Rings` with
        ``lazy``: built only where asked), their signed areas, street
        length (m) and marks.
        """
        p, ja, jb = (np.asarray(x, np.int64) for x in (p, ja, jb))
        step = np.broadcast_to(np.asarray(step, np.int64), p.shape)
        m, ms = self.m[p], self.mstart[p]
        i0, nv = self._ring_vertices(p, ja, jb)
        nb = (jb - ja) // step + 1
        size = nv + nb + 3
        row = np.repeat(np.arange(len(p)), size)
        r = ramp(size)
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
        polys, area, marks = self._polygons(kinds, idx, size, seg, lazy)
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
        r = ramp(cnt)
        kinds = np.ones(len(row), np.int64)
        idx = (ms + np.mod(ja, m))[row]  # inner[ja] starts every unit
        lot = (kind[row] == 0) & (r > 0)
        idx[lot] = ms[row[lot]] + np.mod(ja[row[lot]] + r[lot], m[row[lot]])
        mer = (kind[row] == 2) & (r > 0)
        rr = r[mer]
        rm = row[mer]
        kinds[mer] = np.where(rr == 1, 0, np.where(rr <= nv[rm] + 1, 2, 0))
        idx[mer] = np.where(
            rr == 1,
            ms[rm] + np.mod(ja[rm], m[rm]),
            np.where(rr <= nv[rm] + 1, i0[rm] + rr - 2, ms[rm] + np.mod(jb[rm], m[rm])),
        )
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

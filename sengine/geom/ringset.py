"""Polygons as flat vertex arrays with one mark per edge (:class:`RingSet`).

Many polygons (with holes) held as numpy arrays: every vertex once (rings
are open), the ring of each vertex, the polygon of each ring, and one mark
per edge (``flag``: a boolean carried by the edge from a vertex to the next
one of its ring, e.g. "lies on the original outline").  Vectorized
measures (areas, edge lengths, extents, a small enclosing rectangle),
selection and reordering; shapely geometries are made once, at the end
(:meth:`RingSet.polygons`).  :mod:`sengine.geom.split` cuts them by lines.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import shapely

__all__ = ["RingSet"]


def _ramp(counts) -> np.ndarray:
    """0, 1, ..., c - 1 for each count, concatenated."""
    counts = np.asarray(counts, np.int64)
    return np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)


def _first_of(groups: np.ndarray, n: int) -> np.ndarray:
    """Start index of each group ``0..n-1`` in a sorted ``groups`` array (n + 1 offsets)."""
    return np.r_[0, np.cumsum(np.bincount(groups, minlength=n))].astype(np.int64)


@dataclass(frozen=True)
class RingSet:
    """Polygons as flat arrays (see the module docs).

    Attributes
    ----------
    xy : ndarray (N, 2)
        Vertices (m), rings open (no repeated first vertex), exteriors
        counter-clockwise and holes clockwise (interior on the left).
    ring : ndarray of int64 (N,)
        Ring of each vertex, non-decreasing.
    flag : ndarray of bool (N,)
        Mark of the edge from each vertex to the next one of its ring.
    poly : ndarray of int64 (R,)
        Polygon of each ring, non-decreasing; a polygon's exterior comes first.
    n : int
        Number of polygons (some may have no ring: empty).
    """

    xy: np.ndarray
    ring: np.ndarray
    flag: np.ndarray
    poly: np.ndarray
    n: int

    # -- making and unmaking --------------------------------------------------------
    @classmethod
    def from_polygons(cls, polys, flag: bool = True) -> RingSet:
        """Ring set of shapely Polygons (empty ones give ring-less polygons).

        Repeated consecutive vertices are dropped and rings of fewer than
        three vertices left out.  Every edge gets the mark ``flag``.
        """
        polys = np.asarray(polys, dtype=object).ravel()
        n = len(polys)
        tid = shapely.get_type_id(polys)
        if np.any((tid != 3) & ~shapely.is_empty(polys)):
            raise TypeError("RingSet.from_polygons takes Polygons only (explode MultiPolygons first)")
        if n == 0:
            return cls(np.zeros((0, 2)), np.zeros(0, np.int64), np.zeros(0, bool), np.zeros(0, np.int64), 0)
        polys = shapely.orient_polygons(polys)
        rings, pidx = shapely.get_rings(polys, return_index=True)
        c, ci = shapely.get_coordinates(rings, return_index=True)
        keep = np.r_[ci[1:] == ci[:-1], False] if len(ci) else np.zeros(0, bool)  # drop each closing vertex
        rs = cls(c[keep], ci[keep].astype(np.int64), np.full(int(keep.sum()), bool(flag)), pidx.astype(np.int64), n)
        return rs.cleaned()

    def cleaned(self) -> RingSet:
        """Without repeated consecutive vertices and without rings of < 3 vertices."""
        if len(self.xy) == 0:
            return self
        nx = self.next_vertex()
        keep = np.any(self.xy != self.xy[nx], axis=1)
        cnt = np.bincount(self.ring[keep], minlength=len(self.poly))
        keep &= cnt[self.ring] >= 3
        if keep.all():
            return self
        live = cnt >= 3
        rmap = np.cumsum(live) - 1
        return RingSet(self.xy[keep], rmap[self.ring[keep]], self.flag[keep], self.poly[live], self.n)

    def spike_tips(self, tol: float) -> np.ndarray:
        """Vertices where a ring turns straight back on itself (N,) bool.

        A vertex is a spike's tip when its two edges point opposite ways and
        the shorter one, longer than ``tol`` (m), ends within ``tol`` of the
        longer one's line (a shorter one is a repeated vertex).  A cut running
        along an edge of its polygon leaves such a zero-width spike; GEOS
        calls it valid when rounding leaves it 1e-15 m wide, but the next cut
        through its base makes a piece that touches itself.
        """
        nx = self.next_vertex()
        pv = np.empty_like(nx)
        pv[nx] = np.arange(len(nx))
        a, b = self.xy - self.xy[pv], self.xy[nx] - self.xy
        cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
        la, lb = np.hypot(a[:, 0], a[:, 1]), np.hypot(b[:, 0], b[:, 1])
        back = np.einsum("ij,ij->i", a, b) < 0.0
        return back & (np.abs(cross) <= tol * np.maximum(la, lb)) & (np.minimum(la, lb) > tol)

    def polygons(self) -> np.ndarray:
        """The polygons as a shapely array (n,).

        Their boundary segments (:func:`sengine.geom.boundary.ring_segments`) come in vertex order,
        so ``flag`` is the mark of each of them.
        """
        R = len(self.poly)
        if R == 0:
            return np.full(self.n, shapely.Polygon(), dtype=object) if self.n else np.empty(0, object)
        start = _first_of(self.ring, R)
        cnt = np.diff(start)
        # closed rings: each ring's vertices then its first one again
        src = np.arange(len(self.xy) + R)
        roff = start + np.arange(R + 1)  # offsets into the closed coordinate array
        ring_of = np.repeat(np.arange(R), cnt + 1)
        k = src - roff[ring_of]
        src = np.where(k < cnt[ring_of], start[ring_of] + k, start[ring_of])
        poff = _first_of(self.poly, self.n)
        return shapely.from_ragged_array(shapely.GeometryType.POLYGON, self.xy[src], (roff, poff))

    # -- structure --------------------------------------------------------------------
    def next_vertex(self) -> np.ndarray:
        """Index of the next vertex of each vertex's ring (N,)."""
        return self._next

    @cached_property
    def _next(self) -> np.ndarray:
        N = len(self.xy)
        nx = np.arange(1, N + 1)
        if N:
            last = np.r_[self.ring[1:] != self.ring[:-1], True]
            start = _first_of(self.ring, len(self.poly))[:-1]
            nx[last] = start[self.ring[last]]
        return nx

    def ring_areas(self) -> np.ndarray:
        """Signed area of each ring (m2; positive counter-clockwise)."""
        R = len(self.poly)
        if R == 0:
            return np.zeros(0)
        start = _first_of(self.ring, R)[:-1]
        q = self.xy - self.xy[start[self.ring]]  # local to the ring's first vertex: no cancellation
        qn = q[self.next_vertex()]
        return 0.5 * np.bincount(self.ring, weights=q[:, 0] * qn[:, 1] - q[:, 1] * qn[:, 0], minlength=R)

    def areas(self) -> np.ndarray:
        """Area of each polygon (m2)."""
        return np.bincount(self.poly, weights=self.ring_areas(), minlength=self.n)

    def edge_lengths(self) -> np.ndarray:
        """Length of the edge from each vertex to the next (m)."""
        return self._lengths

    @cached_property
    def _lengths(self) -> np.ndarray:
        d = self.xy[self.next_vertex()] - self.xy
        return np.hypot(d[:, 0], d[:, 1])

    def vertex_poly(self) -> np.ndarray:
        """Polygon of each vertex (N,)."""
        return self._vpoly

    @cached_property
    def _vpoly(self) -> np.ndarray:
        return self.poly[self.ring]

    def flagged_length(self) -> np.ndarray:
        """Total length of each polygon's marked edges (m)."""
        ln = self.edge_lengths()
        return np.bincount(self.vertex_poly()[self.flag], weights=ln[self.flag], minlength=self.n)

    def take(self, sel) -> RingSet:
        """The polygons ``sel`` (boolean mask or increasing indices), renumbered."""
        sel = np.asarray(sel)
        if sel.dtype == bool:
            mask = sel
        else:
            mask = np.zeros(self.n, bool)
            mask[sel] = True
        if mask.all():
            return self
        pmap = np.cumsum(mask) - 1
        rkeep = mask[self.poly]
        rmap = np.cumsum(rkeep) - 1
        vkeep = rkeep[self.ring]
        return RingSet(
            self.xy[vkeep], rmap[self.ring[vkeep]], self.flag[vkeep], pmap[self.poly[rkeep]], int(mask.sum())
        )

    def permuted(self, order) -> RingSet:
        """The polygons in the given order (any permutation or selection of indices)."""
        order = np.asarray(order, np.int64)
        rfirst = _first_of(self.poly, self.n)
        rcnt = np.diff(rfirst)[order]
        rings = np.repeat(rfirst[:-1][order], rcnt) + _ramp(rcnt)
        vfirst = _first_of(self.ring, len(self.poly))
        vcnt = np.diff(vfirst)[rings]
        verts = np.repeat(vfirst[:-1][rings], vcnt) + _ramp(vcnt)
        return RingSet(
            self.xy[verts],
            np.repeat(np.arange(len(rings)), vcnt),
            self.flag[verts],
            np.repeat(np.arange(len(order)), rcnt),
            len(order),
        )

    @staticmethod
    def concat(sets) -> RingSet:
        """One ring set of several, polygons in order."""
        sets = list(sets)
        if not sets:
            return RingSet(np.zeros((0, 2)), np.zeros(0, np.int64), np.zeros(0, bool), np.zeros(0, np.int64), 0)
        roff = np.cumsum([0] + [len(s.poly) for s in sets])
        poff = np.cumsum([0] + [s.n for s in sets])
        return RingSet(
            np.concatenate([s.xy for s in sets]).reshape(-1, 2),
            np.concatenate([s.ring + o for s, o in zip(sets, roff)]).astype(np.int64),
            np.concatenate([s.flag for s in sets]).astype(bool),
            np.concatenate([s.poly + o for s, o in zip(sets, poff)]).astype(np.int64),
            int(poff[-1]),
        )

    def extent_along(self, direction) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Projection range of each polygon on its own direction.

        Returns ``ref`` (n, 2), a vertex of each polygon, and ``lo``, ``hi``
        (n,): the smallest and largest ``(v - ref) . direction`` over its
        vertices (m, for a unit direction).
        """
        vp = self.vertex_poly()
        start = _first_of(self.ring, len(self.poly))[:-1]
        first_ring = _first_of(self.poly, self.n)[:-1]
        ref = np.zeros((self.n, 2))
        has = np.bincount(self.poly, minlength=self.n) > 0
        ref[has] = self.xy[start[first_ring[has]]]
        d = np.asarray(direction, np.float64).reshape(-1, 2)
        proj = np.einsum("ij,ij->i", self.xy - ref[vp], d[vp])
        lo = np.full(self.n, np.inf)
        hi = np.full(self.n, -np.inf)
        if len(vp):
            vstart = _first_of(vp, self.n)
            nz = np.flatnonzero(np.diff(vstart) > 0)
            lo[nz] = np.minimum.reduceat(proj, vstart[nz])
            hi[nz] = np.maximum.reduceat(proj, vstart[nz])
        return ref, lo, hi

    def min_rect_axis(self, max_vertices: int = 128) -> np.ndarray:
        """Long axis of a small enclosing rectangle of each polygon (unit (n, 2)).

        The rectangle is the smallest of those aligned with one of the
        polygon's exterior edges (the minimum-area box when the polygon is
        convex); polygons of more than ``max_vertices`` exterior vertices use
        GEOS's oriented envelope instead.
        """
        axis = np.tile([1.0, 0.0], (self.n, 1))
        if self.n == 0 or len(self.xy) == 0:
            return axis
        ext = np.zeros(len(self.poly), bool)
        ext[_first_of(self.poly, self.n)[:-1][np.bincount(self.poly, minlength=self.n) > 0]] = True
        v = np.flatnonzero(ext[self.ring])
        vp = self.poly[self.ring[v]]
        cnt = np.bincount(vp, minlength=self.n)
        big = cnt > max_vertices
        if big.any():
            from sengine.geom.polygons import obb_frame

            axis[big] = obb_frame(self.take(big).polygons())[1]
        small = ~big[vp]
        v, vp = v[small], vp[small]
        if len(v) == 0:
            return axis
        nx = self.next_vertex()
        e = self.xy[nx[v]] - self.xy[v]
        el = np.hypot(e[:, 0], e[:, 1])
        e = e / np.maximum(el, 1e-300)[:, None]
        # every (edge direction, vertex) pair of a polygon
        vstart = _first_of(vp, self.n)
        c = cnt * ~big
        pe = np.repeat(np.arange(len(v)), c[vp])  # edge of each pair
        k = np.arange(len(pe)) - np.repeat(np.cumsum(c[vp]) - c[vp], c[vp])
        pv = vstart[vp[pe]] + k  # vertex of each pair (same polygon)
        q = self.xy[v[pv]] - self.xy[v[pe]]
        a = np.einsum("ij,ij->i", q, e[pe])
        b = q[:, 0] * -e[pe, 1] + q[:, 1] * e[pe, 0]
        gs = np.r_[0, np.cumsum(c[vp])[:-1]]  # pair group starts (one group per edge)
        wa = np.maximum.reduceat(a, gs) - np.minimum.reduceat(a, gs)
        wb = np.maximum.reduceat(b, gs) - np.minimum.reduceat(b, gs)
        area = np.where(el > 0, wa * wb, np.inf)
        o = np.lexsort((area, vp))
        best = o[np.r_[True, vp[o][1:] != vp[o][:-1]]]
        long_b = wb[best] > wa[best]
        ax = np.where(long_b[:, None], np.stack([-e[best, 1], e[best, 0]], axis=1), e[best])
        axis[vp[best]] = ax
        return axis

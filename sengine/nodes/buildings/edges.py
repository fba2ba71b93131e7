"""Front, side and rear lot lines: which edge of a lot faces the street.

Zoning sets a building back by a different distance from each kind of lot
line (paper 000 §5.3.2: 4 m from the neighbouring lots' borders, not from
the street; 004 §3.3.2: setbacks per plot).  :func:`lot_edges` tags every
boundary segment of every lot:

* **front**: it lies on the street.  With the blocks, a segment on its
  block's boundary (every block edge faces a street: blocks are faces of the
  street graph, skylineEngine 002 §5.4); without them, a segment no other
  lot shares (within ``tol``).
* **rear**: not front, roughly parallel to the lot's main front (within
  45 degrees) and in the half of the lot away from it, on a lot that is not
  a corner lot.
* **side**: every other segment; on a corner lot (fronts in two directions)
  every segment that is not front, so the lot has no rear.

A lot with no front (an inner lot, a courtyard) takes its longest segment as
its front: that is where its access is.

This is the one place the buildings read the lot vocabulary from the
geometry; lots that carry their own front / side / rear tags can replace it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely

from sengine.geom.boundary import ring_segments, segments_on_boundary, segments_on_box, segments_on_lines

__all__ = ["FRONT", "SIDE", "REAR", "Lines", "LotEdges", "lot_edges"]

FRONT, SIDE, REAR = 0, 1, 2
ON_TOL = 1e-5  # m: a segment within this of the block boundary (or a neighbour) lies on it
CORNER_ANGLE = 30.0  # deg: fronts turning by more than this make a corner lot
REAR_ANGLE = 45.0  # deg: a rear line is within this of the front's direction


class Lines:
    """Some of each lot's boundary segments (one kind, one hand ...), as straight runs, for lots ``rows``.

    A *run* is the segments of one lot lying on one straight line (a plain
    street front is one run, a corner lot's front two).

    Attributes
    ----------
    has : ndarray of bool (n,)
        Whether the lot has any such segment.
    straight : ndarray of bool (n,)
        Whether they form a single run.
    """

    def __init__(self, p0, p1, seg_start, runs: dict, run_start, rows=None):
        self._p0, self._p1, self._seg_start = p0, p1, seg_start
        self._runs, self._run_start = runs, run_start
        n = len(run_start) - 1
        self.rows = np.arange(n) if rows is None else np.asarray(rows, np.int64)
        count = np.diff(run_start)[self.rows]
        self.has = count > 0
        self.straight = count == 1

    def __len__(self) -> int:
        return len(self.rows)

    def __getitem__(self, rows) -> Lines:
        return Lines(self._p0, self._p1, self._seg_start, self._runs, self._run_start, rows=self.rows[rows])

    def runs(self, which) -> tuple[np.ndarray, dict]:
        """The runs of the lots at positions ``which``: (position of its lot, run attributes).

        Run attributes: ``origin`` and ``axis`` (n, 2) of its line, ``inward``
        (+1: the lot lies to the left of ``axis``), ``lo`` and ``hi`` (m): the
        run's extent along ``axis`` from ``origin``.
        """
        which = np.asarray(which, np.int64)
        rows = self.rows[which]
        a, b = self._run_start[rows], self._run_start[rows + 1]
        cnt = b - a
        idx = np.repeat(a, cnt) + np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        return np.repeat(which, cnt), {k: v[idx] for k, v in self._runs.items()}

    def geoms(self, which=None) -> np.ndarray:
        """A MultiLineString per lot (of those ``which`` selects; ``None`` for a lot with none)."""
        rows = self.rows if which is None else self.rows[which]
        out = np.full(len(rows), None, dtype=object)
        a, b = self._seg_start[rows], self._seg_start[rows + 1]
        cnt = b - a
        if cnt.sum() == 0:
            return out
        seg = np.repeat(a, cnt) + np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        coords = np.stack([self._p0[seg], self._p1[seg]], axis=1).reshape(-1, 2)
        lines = shapely.linestrings(coords, indices=np.repeat(np.arange(len(seg)), 2))
        return shapely.multilinestrings(lines, indices=np.repeat(np.arange(len(rows)), cnt), out=out)


@dataclass(frozen=True)
class LotEdges:
    """Boundary segments of lots with their kind, and each lot's front frame.

    Attributes
    ----------
    p0, p1 : ndarray (s, 2)
        Segment ends (m), ring by ring as :func:`sengine.geom.boundary.ring_segments`.
    lot : ndarray of int64 (s,)
        Lot (row) of each segment.
    kind : ndarray of int8 (s,)
        :data:`FRONT`, :data:`SIDE` or :data:`REAR`.
    inward : ndarray of float (s,)
        ``+1`` where the lot lies to the left of the segment (``p0`` to ``p1``), ``-1`` to the right.
    axis : ndarray (n, 2)
        Unit vector along each lot's main front (its longest front segment).
    has_front : ndarray of bool (n,)
        Whether the lot touches the street (else its longest edge stands in).
    corner : ndarray of bool (n,)
        Whether the lot has fronts in two directions.
    street : ndarray (n,)
        Where each lot's main front line lies across ``axis``: its coordinate (m) along the left normal.
    facing : ndarray of float (n,)
        ``+1`` where the lot lies on the left normal's side of its main front line, ``-1`` on the other.
    """

    p0: np.ndarray
    p1: np.ndarray
    lot: np.ndarray
    kind: np.ndarray
    inward: np.ndarray
    axis: np.ndarray
    has_front: np.ndarray
    corner: np.ndarray
    street: np.ndarray
    facing: np.ndarray

    @property
    def front_angle(self) -> np.ndarray:
        """Direction of each lot's main front (deg in [0, 180))."""
        return np.degrees(np.arctan2(self.axis[:, 1], self.axis[:, 0])) % 180.0

    def lines(self, kind: int, n: int, mask=None) -> Lines:
        """The segments of one kind (and ``mask``, when given) of each of the ``n`` lots."""
        pick = self.kind == kind if mask is None else (self.kind == kind) & mask
        pick &= np.any(self.p1 != self.p0, axis=1)
        sel = np.flatnonzero(pick)
        lot = self.lot[sel]
        seg_start = np.r_[0, np.cumsum(np.bincount(lot, minlength=n))].astype(np.int64)
        p0, p1, inward = self.p0[sel], self.p1[sel], self.inward[sel]
        d = p1 - p0
        u = d / np.hypot(d[:, 0], d[:, 1])[:, None]
        # runs: the segments of a lot on one line (same direction and offset, quantized)
        theta = np.rint(np.arctan2(u[:, 1], u[:, 0]) / 1e-6).astype(np.int64)
        offset = np.rint((u[:, 0] * p0[:, 1] - u[:, 1] * p0[:, 0]) / 1e-4).astype(np.int64)
        o = np.lexsort((offset, theta, lot))
        key = np.stack([lot[o], theta[o], offset[o]], axis=1)
        new = np.r_[True, np.any(key[1:] != key[:-1], axis=1)] if len(o) else np.zeros(0, bool)
        run = np.empty(len(o), np.int64)
        run[o] = np.cumsum(new) - 1
        nrun = int(new.sum())
        head = o[new]
        origin, axis = p0[head], u[head]
        t0 = np.einsum("ij,ij->i", p0 - origin[run], axis[run])
        t1 = np.einsum("ij,ij->i", p1 - origin[run], axis[run])
        first = np.flatnonzero(new)  # in the sorted order each run's segments are consecutive
        lo = np.minimum.reduceat(np.minimum(t0, t1)[o], first) if nrun else np.zeros(0)
        hi = np.maximum.reduceat(np.maximum(t0, t1)[o], first) if nrun else np.zeros(0)
        runs = {"origin": origin, "axis": axis, "inward": inward[head], "lo": lo, "hi": hi}
        run_start = np.r_[0, np.cumsum(np.bincount(lot[head], minlength=n))].astype(np.int64)
        return Lines(p0, p1, seg_start, runs, run_start)


def _longest_per_lot(cand: np.ndarray, lot: np.ndarray, length: np.ndarray, n: int) -> np.ndarray:
    """Index (into the segments) of the longest of ``cand`` for each lot, ``-1`` for none."""
    best = np.full(n, -1, np.int64)
    if len(cand) == 0:
        return best
    # segments come lot by lot: the longest of each lot's, the last of equals
    lc, lc_len = lot[cand], length[cand]
    new = np.r_[True, lc[1:] != lc[:-1]]
    top = np.maximum.reduceat(lc_len, np.flatnonzero(new))[np.cumsum(new) - 1]
    hit = np.flatnonzero(lc_len == top)
    last = np.r_[lc[hit][1:] != lc[hit][:-1], True]
    best[lc[hit][last]] = cand[hit][last]
    return best


def lot_edges(lots, *, blocks=None, owner=None, box=None, fronts=None, tol: float = ON_TOL) -> LotEdges:
    """Tag every boundary segment of every lot as front, side or rear.

    Parameters
    ----------
    lots : array_like of shapely.Polygon (n,)
        Lots (m).
    blocks : array_like of shapely.Polygon, optional
        The blocks the lots were cut from; with ``owner``, a segment on its
        block's boundary is a front.
    owner : array_like of int (n,), optional
        Row in ``blocks`` of each lot's block (``-1``: measure against the neighbours).
    box : tuple of float, optional
        The box that closed an extract's land (``meta["bbox"]``): no front lies on it.
    fronts : array_like of object, optional
        Per block, its street-facing boundary where land was cut out of it
        (``blocks.landuse``'s ``street_front``; ``None``: all of it).
    tol : float
        Distance (m) within which a segment lies on a boundary.

    Returns
    -------
    LotEdges
    """
    lots = np.asarray(lots, dtype=object).ravel()
    n = len(lots)
    p0, p1, idx, ring = ring_segments(lots)
    front = np.zeros(len(idx), bool)
    known = np.zeros(n, bool)
    if blocks is not None and owner is not None and n:
        owner = np.asarray(owner, np.int64)
        known = owner >= 0
        if known.any():
            k = np.flatnonzero(known)
            _, _, kidx, _, on = segments_on_boundary(lots[k], owner[k], np.asarray(blocks, dtype=object), tol=tol)
            if fronts is not None:  # sides cut along water, a park or open land face no street
                mine = np.flatnonzero(np.isin(idx, k))[on]  # only a segment on its block can face a street
                on[on] = segments_on_lines(p0[mine], p1[mine], np.asarray(fronts, dtype=object)[owner[idx[mine]]])
            front[np.isin(idx, k)] = on  # the subset's segments come in the same order
    rest = ~known[idx] if n else np.zeros(0, bool)
    if rest.any():  # the street is where no other lot is
        s = np.flatnonzero(rest)
        mid = shapely.points(0.5 * (p0[s] + p1[s]))
        si, li = shapely.STRtree(lots).query(mid, predicate="dwithin", distance=tol)
        shared = np.zeros(len(s), bool)
        shared[si[li != idx[s[si]]]] = True
        front[s] = ~shared
    d = p1 - p0
    length = np.hypot(d[:, 0], d[:, 1])
    unit = d / np.maximum(length, 1e-300)[:, None]
    edge = ~segments_on_box(p0, p1, box)
    front &= (length > 1e-9) & edge
    best = _longest_per_lot(np.flatnonzero(front), idx, length, n)
    has_front = best >= 0
    fallback = _longest_per_lot(np.flatnonzero((length > 1e-9) & edge), idx, length, n)
    fallback = np.where(fallback >= 0, fallback, _longest_per_lot(np.flatnonzero(length > 1e-9), idx, length, n))
    best = np.where(has_front, best, fallback)
    axis = np.tile([1.0, 0.0], (n, 1))
    ok = best >= 0
    axis[ok] = unit[best[ok]]
    if (~has_front & ok).any():  # an inner lot: its longest edge is its front
        front[best[~has_front & ok]] = True
    # corner lots: a front segment turning away from the main front
    cross = np.abs(unit[:, 0] * axis[idx, 1] - unit[:, 1] * axis[idx, 0])
    corner = np.bincount(idx[front & (length > 0.5) & (cross > np.sin(np.radians(CORNER_ANGLE)))], minlength=n) > 0
    # rear: parallel to the main front, in the half of the lot away from it
    nrm = np.stack([-axis[:, 1], axis[:, 0]], axis=1)
    fo = np.where(ok, best, 0)
    origin = p0[fo] if len(fo) else np.zeros((0, 2))
    mid = 0.5 * (p0 + p1)
    off = np.einsum("ij,ij->i", mid - origin[idx], nrm[idx]) if len(idx) else np.zeros(0)
    c, ci = shapely.get_coordinates(lots, return_index=True)
    cv = np.einsum("ij,ij->i", c - origin[ci], nrm[ci]) if len(ci) else np.zeros(0)
    lo = np.full(n, np.inf)
    hi = np.full(n, -np.inf)
    np.minimum.at(lo, ci, cv)
    np.maximum.at(hi, ci, cv)
    # the lot lies on one side of its front line: measure the depth on that side
    far = np.where(np.abs(hi) >= np.abs(lo), hi, lo)
    parallel = cross < np.sin(np.radians(REAR_ANGLE))
    rear = (
        ~front & parallel & ~corner[idx] & (np.abs(off) > 0.5 * np.abs(far[idx])) & (np.sign(off) == np.sign(far[idx]))
    )
    kind = np.full(len(idx), SIDE, np.int8)
    kind[front] = FRONT
    kind[rear] = REAR
    # the lot lies to the left of a segment of its counter-clockwise shell or of a clockwise hole
    _, rings = np.unique(ring, return_inverse=True)
    signed = np.bincount(rings, weights=p0[:, 0] * p1[:, 1] - p1[:, 0] * p0[:, 1])
    shell = np.r_[True, idx[1:] != idx[:-1]] if len(idx) else np.zeros(0, bool)
    is_shell = np.zeros(len(signed), bool)
    is_shell[rings[shell]] = True
    left = (signed > 0) == is_shell
    inward = np.where(left[rings], 1.0, -1.0)
    street = np.einsum("ij,ij->i", origin, nrm) if n else np.zeros(0)
    facing = np.where(ok, inward[fo], 1.0) if len(inward) else np.ones(n)
    return LotEdges(p0, p1, idx, kind, inward, axis, has_front, corner, street, facing)

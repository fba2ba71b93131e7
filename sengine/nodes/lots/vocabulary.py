"""The lot vocabulary every lot method shares: kinds, front / side / rear edges, frontage, depth.

What CityEngine users and planners call a lot's parts, computed the same
way for the lots of any method (they all pass through
:meth:`sengine.nodes.lots.nodes._Lots.run`):

* ``kind``: ``street`` (faces one street), ``corner`` (faces two streets
  turning by more than 30°) or ``inner`` (no street frontage, or flagged
  inner by its method: courtyards, the interior of skeleton lots);
* ``frontage`` (m): the length of the lot's boundary on its block's
  boundary (every block edge faces a street: blocks are faces of the street
  graph);
* ``depth`` (m): the lot's extent perpendicular to its front, i.e. along
  the normal of its longest frontage segment (``nan`` for a lot without
  frontage: it has no front to be deep from);
* edge tags, by :func:`edge_tags` (not stored as columns: a building node
  asks for them when it needs them): each boundary segment of a lot is
  ``front`` (on a street), ``side`` (shared with a lot that fronts one of
  the same streets: the party walls of a street row) or ``rear`` (the rest:
  the back of the lot, against lots of another street or the interior).

A *street* of a block is a maximal run of its boundary between turns of
more than ``corner_angle`` (30°), so that two lots on one straight or gently
curving street front "the same street" and the two sides of a corner do not.

Lot methods hand their lots to the node as a :class:`LotSplit`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely

from sengine.geom.boundary import ring_segments, segments_on_boundary

__all__ = ["KINDS", "FRONT", "SIDE", "REAR", "TAGS", "LotSplit", "EdgeTags", "lot_kind", "lot_depth", "edge_tags"]

KINDS = ("street", "corner", "inner")
FRONT, SIDE, REAR = 0, 1, 2
TAGS = ("front", "side", "rear")
ON_TOL = 1e-5  # m: a segment within this of the block boundary lies on it


@dataclass
class LotSplit:
    """What a lot method gives the lot node.

    Attributes
    ----------
    lots : ndarray of shapely.Polygon (k,)
    owner : ndarray of int64 (k,)
        Index of each lot's block in the method's input, non-decreasing.
    method : ndarray of str (k,)
        The method's name for each lot.
    inner : ndarray of bool (k,)
        Lots the method made without street access (courtyards, interiors).
    on, known : ndarray of bool, optional
        Which boundary segment of each lot lies on its block's boundary
        (order of :func:`sengine.geom.boundary.ring_segments`), for the lots
        ``known`` says; ``None``: measure them all.
    park : ndarray of bool (k,), optional
        Interior lots kept whole as a courtyard or park.
    """

    lots: np.ndarray
    owner: np.ndarray
    method: np.ndarray
    inner: np.ndarray
    on: np.ndarray | None = None
    known: np.ndarray | None = None
    park: np.ndarray | None = None

    def __post_init__(self):
        k = len(self.lots)
        if self.park is None:
            self.park = np.zeros(k, bool)
        for name in ("owner", "method", "inner", "park"):
            if len(getattr(self, name)) != k:
                raise ValueError(f"LotSplit.{name} has length {len(getattr(self, name))}, expected {k}")


def lot_kind(frontage, corner, inner) -> np.ndarray:
    """``street`` / ``corner`` / ``inner`` of each lot (an inner lot is one without frontage too)."""
    frontage, corner, inner = np.asarray(frontage), np.asarray(corner, bool), np.asarray(inner, bool)
    k = np.where(corner, 1, 0)
    k = np.where(inner | ~(frontage > 0), 2, k)
    return np.asarray(KINDS, dtype="<U6")[k]


def lot_depth(lots, front_angle) -> np.ndarray:
    """Extent (m) of each lot perpendicular to its front direction (``front_angle``, deg).

    Lots without a front (``nan`` angle) get ``nan``.
    """
    lots = np.asarray(lots, dtype=object)
    k = len(lots)
    out = np.full(k, np.nan)
    if k == 0:
        return out
    ang = np.asarray(front_angle, np.float64)
    c, ci = shapely.get_coordinates(lots, return_index=True)
    has = np.isfinite(ang)
    a = np.radians(np.where(has, ang, 0.0))
    nrm = np.stack([-np.sin(a), np.cos(a)], axis=1)
    proj = np.einsum("ij,ij->i", c, nrm[ci])
    if len(ci):
        start = np.r_[0, np.flatnonzero(np.diff(ci)) + 1]
        lots_with = ci[start]
        hi = np.maximum.reduceat(proj, start)
        lo = np.minimum.reduceat(proj, start)
        out[lots_with] = hi - lo
    out[~has] = np.nan
    return out


def street_ids(blocks, *, corner_angle: float = 30.0):
    """Street of every boundary segment of each block (order of :func:`ring_segments`).

    Consecutive segments of a ring turning by at most ``corner_angle`` (deg)
    are one street; a ring that never turns more is one street.  Ids are
    unique over all blocks.
    """
    p0, p1, idx, ring = ring_segments(np.asarray(blocks, dtype=object))
    S = len(idx)
    if S == 0:
        return np.zeros(0, np.int64)
    d = p1 - p0
    ln = np.hypot(d[:, 0], d[:, 1])
    u = d / np.maximum(ln, 1e-300)[:, None]
    s = np.arange(S)
    start = np.r_[True, ring[1:] != ring[:-1]]
    first = np.maximum.accumulate(np.where(start, s, 0))
    end = np.r_[start[1:], True]
    last_of = np.zeros(S, np.int64)
    last_of[first[end]] = s[end]
    prev = np.where(start, last_of[first], s - 1)
    turn = np.abs(np.arctan2(u[prev, 0] * u[:, 1] - u[prev, 1] * u[:, 0], np.einsum("ij,ij->i", u[prev], u)))
    brk = (turn > np.radians(corner_angle)) & (ln > 0)
    rr = np.cumsum(start) - 1  # ring number 0 .. R - 1
    R = int(rr[-1]) + 1
    brk |= start & (np.bincount(rr, weights=brk, minlength=R) == 0)[rr]  # a ring without a turn: one street
    sid = np.cumsum(brk) - 1
    # the segments of a ring before its first break belong to its last street (cyclic)
    first_brk = np.full(R, S, np.int64)
    np.minimum.at(first_brk, rr[brk], s[brk])
    last_sid = np.zeros(R, np.int64)
    last_sid[rr[end]] = sid[end]
    sid = np.where(s < first_brk[rr], last_sid[rr], sid)
    return sid.astype(np.int64)


@dataclass
class EdgeTags:
    """Boundary segments of lots with their tag.

    Attributes
    ----------
    p0, p1 : ndarray (s, 2)
        Segment ends (m), in the order of :func:`sengine.geom.boundary.ring_segments`.
    lot : ndarray of int64 (s,)
        Lot of each segment.
    tag : ndarray of int8 (s,)
        :data:`FRONT` (0), :data:`SIDE` (1) or :data:`REAR` (2).
    street : ndarray of int64 (s,)
        Street of a front segment (:func:`street_ids`), -1 for the others.
    neighbour : ndarray of int64 (s,)
        The lot on the other side of a side or rear segment, -1 for none.
    """

    p0: np.ndarray
    p1: np.ndarray
    lot: np.ndarray
    tag: np.ndarray
    street: np.ndarray
    neighbour: np.ndarray

    def length(self, tag: int) -> np.ndarray:
        """Length (m) of each lot's segments of one tag (one value per lot)."""
        n = int(self.lot.max()) + 1 if len(self.lot) else 0
        sel = self.tag == tag
        return np.bincount(self.lot[sel], weights=np.hypot(*(self.p1 - self.p0)[sel].T), minlength=n)


def edge_tags(lots, owner, blocks, *, corner_angle: float = 30.0, tol: float = ON_TOL) -> EdgeTags:
    """Tag every boundary segment of each lot ``front``, ``side`` or ``rear``.

    Parameters
    ----------
    lots : array_like of shapely.Polygon (k,)
    owner : array_like of int (k,)
        Index into ``blocks`` of each lot's block.
    blocks : array_like of shapely.Polygon
    corner_angle : float
        Streets of a block break where its boundary turns by more (deg).
    tol : float
        A segment within this distance (m) of the block boundary is a front;
        the lot across a segment is found within it too.

    Returns
    -------
    EdgeTags
        ``front``: on the block boundary; ``side``: shared with another lot
        that fronts one of the same streets; ``rear``: the rest.

    Notes
    -----
    The lot across a segment is the one touching its midpoint: a segment
    running along two lots (a T-junction, as recursive cuts make) is tagged
    by the one at its middle.
    """
    lots = np.asarray(lots, dtype=object).ravel()
    owner = np.asarray(owner, np.int64)
    blocks = np.asarray(blocks, dtype=object).ravel()
    p0, p1, idx, _, on, match = segments_on_boundary(lots, owner, blocks, tol=tol, return_match=True)
    S = len(idx)
    sid = street_ids(blocks, corner_angle=corner_angle)
    street = np.full(S, -1, np.int64)
    street[on] = sid[match[on]]
    tag = np.full(S, REAR, np.int8)
    tag[on] = FRONT
    nb = np.full(S, -1, np.int64)
    rest = np.flatnonzero(~on & (np.hypot(*(p1 - p0).T) > 0))
    if len(rest) and len(lots) > 1:
        mid = shapely.points(0.5 * (p0[rest] + p1[rest]))
        qi, li = shapely.STRtree(lots).query(mid, predicate="dwithin", distance=tol)
        ok = (li != idx[rest[qi]]) & (owner[li] == owner[idx[rest[qi]]])
        qi, li = qi[ok], li[ok]
        # one neighbour per segment (the lowest index where a segment ends on a corner of several)
        o = np.lexsort((li, qi))
        f = np.r_[True, qi[o][1:] != qi[o][:-1]] if len(o) else np.zeros(0, bool)
        nb[rest[qi[o][f]]] = li[o][f]
    # side: the neighbour fronts a street this lot fronts too
    fs = np.flatnonzero(on)
    K = int(sid.max()) + 1 if len(sid) else 1
    pairs = np.unique(idx[fs] * K + street[fs])  # (lot, street) pairs, sorted
    has_nb = np.flatnonzero(nb >= 0)
    if len(has_nb) and len(pairs):
        lot_of_pair = pairs // K
        start = np.searchsorted(lot_of_pair, idx[has_nb])
        stop = np.searchsorted(lot_of_pair, idx[has_nb], side="right")
        cnt = stop - start
        row = np.repeat(np.arange(len(has_nb)), cnt)
        k = np.repeat(start, cnt) + (np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt))
        want = nb[has_nb][row] * K + pairs[k] % K
        hit = pairs[np.minimum(np.searchsorted(pairs, want), len(pairs) - 1)] == want
        side = np.bincount(row[hit], minlength=len(has_nb)) > 0
        tag[has_nb[side]] = SIDE
    return EdgeTags(p0, p1, idx, tag, street, nb)

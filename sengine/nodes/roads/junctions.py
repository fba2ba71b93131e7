"""Lines cut at their junctions: the street segments of a road map, as flat arrays.

A junction is a point shared by two lines (or visited twice by one line) or
a line's end; point identity is an integer key per point (the importers'
node ids, or :func:`point_keys` for exact coordinates).  The cut keeps the
topology: the segments know the node at each vertex.  Used by ``osm.read``
(cutting ways at shared OSM nodes) and ``roads.clean``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Pieces", "split_at_junctions", "point_keys", "take_pieces"]


@dataclass
class Pieces:
    """Lines cut at their junctions (result of :func:`split_at_junctions`).

    Attributes
    ----------
    vertex : ndarray of int64
        Indices into the input point arrays, piece after piece in order; a
        junction inside a line appears twice (end of one piece, start of the next).
    piece : ndarray of int64
        Piece index of each entry of ``vertex`` (non-decreasing).
    line : ndarray of int64
        Source line of each piece.
    first, last : ndarray of int64
        Input index of the first and last point of each piece.
    whole : ndarray of bool, optional
        Set by :func:`clean_streets`: the piece is its source line,
        unchanged (same points, none added or dropped).
    node, node_key : ndarray of int64, optional
        Set by :func:`split_at_junctions`: the node of each entry of
        ``vertex`` (``0 .. k-1``) and the key of each node (ascending).
    """

    vertex: np.ndarray
    piece: np.ndarray
    line: np.ndarray
    first: np.ndarray
    last: np.ndarray
    whole: np.ndarray | None = None
    node: np.ndarray | None = None
    node_key: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.line)


def split_at_junctions(key: np.ndarray, line: np.ndarray, *, ends_only: bool = False) -> Pieces:
    """Cut polylines at every point shared with another line (or revisited) and at their ends.

    Parameters
    ----------
    key : ndarray of int64 (n,)
        Identity of each point: equal keys are the same node.
    line : ndarray of int (n,)
        Line of each point, non-decreasing; points of a line are in order.
    ends_only : bool
        The caller knows that no inner point is shared (its keys are
        unique): lines are not cut, and no node numbers are made.

    Returns
    -------
    Pieces
        Consecutive repeated points are dropped first; lines left with fewer
        than two points vanish.
    """
    key = np.asarray(key)
    line = np.asarray(line, np.int64)
    n = len(key)
    if n == 0:
        z = np.empty(0, np.int64)
        return Pieces(z, z, z, z, z, node=z, node_key=z)
    keep = np.ones(n, bool)
    keep[1:] = ~((key[1:] == key[:-1]) & (line[1:] == line[:-1]))
    idx = np.flatnonzero(keep)
    k, ln = key[idx], line[idx]
    idx = idx[np.bincount(ln)[ln] >= 2]
    k, ln = key[idx], line[idx]
    m = len(idx)
    if m == 0:  # every line collapsed to one point
        z = np.empty(0, np.int64)
        return Pieces(z, z, z, z, z, node=z, node_key=z)
    first = np.r_[True, ln[1:] != ln[:-1]]
    last = np.r_[ln[1:] != ln[:-1], True]
    if ends_only:
        lab = np.cumsum(first) - 1
        return Pieces(idx, lab, ln[first], idx[first], idx[last])
    ukey, inv = _dense(k)
    used = np.bincount(inv)[inv]
    junction = (used >= 2) | first | last
    start = junction & ~last
    p = np.cumsum(start) - 1
    inner = np.flatnonzero(junction & ~first & ~last)
    pos = np.r_[np.arange(m), inner]
    lab = np.r_[p, p[inner] - 1]
    if len(inner):  # an inner junction ends one piece and starts the next: put its copy in place
        order = np.lexsort((pos, lab))
        pos, lab = pos[order], lab[order]
    brk = np.r_[True, lab[1:] != lab[:-1]]
    ends = np.r_[lab[1:] != lab[:-1], True]
    vertex = idx[pos]
    return Pieces(vertex, lab, ln[pos[brk]], vertex[brk], vertex[ends], node=inv[pos], node_key=ukey)


def _dense(k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(k, return_inverse=True)``; by a presence table, without sorting, for keys in a narrow range."""
    lo, hi = int(k.min()), int(k.max())
    if hi - lo > 4 * len(k) + 1024:
        ukey, inv = np.unique(k, return_inverse=True)
        return ukey, inv.ravel()
    present = np.zeros(hi - lo + 1, bool)
    present[k - lo] = True
    return np.flatnonzero(present) + lo, (np.cumsum(present) - 1)[k - lo]


def point_keys(xy: np.ndarray) -> np.ndarray:
    """An int64 identity per point: equal coordinates, equal key (``-0.0 == 0.0``)."""
    xy = np.ascontiguousarray(xy, np.float64) + 0.0
    _, inv = np.unique(xy.view(np.complex128).ravel(), return_inverse=True)
    return inv.ravel().astype(np.int64)


def take_pieces(pieces: Pieces, keep: np.ndarray) -> Pieces:
    """The pieces where ``keep`` is set, renumbered ``0 .. k-1`` in order."""
    kept = np.flatnonzero(keep)
    renum = np.full(len(pieces), -1, np.int64)
    renum[kept] = np.arange(len(kept))
    sel = keep[pieces.piece]
    return Pieces(
        pieces.vertex[sel],
        renum[pieces.piece[sel]],
        pieces.line[kept],
        pieces.first[kept],
        pieces.last[kept],
        None if pieces.whole is None else pieces.whole[kept],
        None if pieces.node is None else pieces.node[sel],
        pieces.node_key,
    )

"""Faces of plane segment graphs (the minimal circuits of §5.4).

Nothing here knows about cities: these are the faces of the planar
embedding of a segment graph ``(xy, u, v)``, vectorized over numpy arrays.
The graphs themselves (merged points, lines exploded into segments,
crossings split) come from :mod:`sengine.geom.segments`.

Public API
----------
:func:`trace_faces` -- the half-edge "next" permutation and its cycles.
:func:`planar_faces` -- bounded faces of a plane graph as polygons with
holes; bridges (dead ends) removed; the outer face(s) returned apart.
:func:`signed_area` -- shoelace area of rings given as grouped vertices.
:func:`star_simple` -- closed rings certainly simple and counter-clockwise (strictly star-shaped), in numpy.
:func:`ring_crossings` -- pairs of edges of a closed ring that cross or touch (not neighbours), in numpy.
:func:`split_walks` -- closed walks that revisit vertices cut into simple cycles.
:func:`spur_polygons` -- bounded faces with the dead-end trees inside them as spurs of their rings.

Half-edge convention: input edge ``e`` (from ``u[e]`` to ``v[e]``) gives
half-edges ``2 e`` (u -> v) and ``2 e + 1`` (v -> u); each half-edge bounds
the face on its left, so bounded faces are counter-clockwise (positive
signed area) and the outer face of each connected component is clockwise.

References
----------
.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
import shapely

from .grid import _ramp, box_self_pairs
from .segments import argsort_int
from .sorting import unique_int

__all__ = [
    "trace_faces",
    "permutation_cycles",
    "planar_faces",
    "PlanarFaces",
    "signed_area",
    "star_simple",
    "ring_crossings",
    "split_walks",
    "spur_polygons",
]

log = logging.getLogger(__name__)


def _angular_order(xy: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Half-edges (``2 e``: u -> v, ``2 e + 1``: v -> u) sorted by origin node, then angle.

    ``np.lexsort((angle, org))``, the same permutation (equal angles in
    half-edge order): the half-edges grouped by origin (an integer radix
    sort), then each node's few sorted by angle, all nodes of one degree at
    once as the rows of a matrix, instead of one sort of every angle (most
    nodes of a face graph have 2 or 3 half-edges: up to 4, each one's rank
    by comparing it with the others, no sort).
    """
    org = np.stack([u, v], axis=1).ravel()
    de = xy[v] - xy[u]
    d = np.empty((2 * len(u), 2))
    d[0::2] = de
    d[1::2] = -de + 0.0  # the twin's direction, as xy[u] - xy[v] gives it to the bit (+ 0.0: no -0.0)
    angle = np.arctan2(d[:, 1], d[:, 0])
    order = argsort_int(org)  # stable: within a node, half-edges in increasing order
    so = org[order]
    start = np.flatnonzero(np.r_[True, so[1:] != so[:-1]]) if len(so) else np.zeros(0, np.int64)
    size = np.diff(np.r_[start, len(so)])
    out = order.copy()
    for k in np.unique(size[size > 1]):
        at = start[size == k][:, None] + np.arange(k)  # the nodes of degree k, one row each
        rows = order[at]
        x = angle[rows]
        if k <= 4:  # a few: each one's rank is how many of its row come before it (ties: in row order)
            rank = np.zeros(x.shape, np.int64)
            for i in range(k):
                for j in range(i + 1, k):
                    jfirst = x[:, j] < x[:, i]
                    rank[:, i] += jfirst
                    rank[:, j] += ~jfirst
            out[np.take_along_axis(at, rank, axis=1)] = rows
            continue
        out[at] = np.take_along_axis(rows, np.argsort(x, axis=1, kind="stable"), axis=1)
    return out


def _cycle_min(nxt: np.ndarray) -> np.ndarray:
    """Each element's cycle minimum by pointer doubling (see :func:`permutation_cycles`)."""
    low = np.arange(len(nxt), dtype=np.int64)
    step = nxt
    while len(low):
        new = np.minimum(low, low[step])
        if np.array_equal(new, low):
            break
        low, step = new, step[step]
    return low


def _labels_of_min(low: np.ndarray) -> tuple[int, np.ndarray]:
    """Cycles numbered in the order of their lowest element, from each element's cycle minimum.

    The minima are the elements that are their own minimum; a running count
    of them numbers the cycles (no sort).
    """
    head = low == np.arange(len(low))
    rank = np.cumsum(head) - 1
    return int(head.sum()), rank[low].astype(np.int64)


def permutation_cycles(nxt: np.ndarray) -> tuple[int, np.ndarray]:
    """The cycles of a permutation, labelled in the order of their lowest element.

    Each element's cycle minimum by pointer doubling: after round ``k`` it
    holds the minimum of the ``2**k`` elements from it along the cycle;
    rounds stop when one changes nothing (then every window of the cycle has
    the cycle's minimum), at most ``log2`` of the longest cycle plus one.
    The labels are those of ``scipy.sparse.csgraph.connected_components``
    on the permutation's graph (weak components numbered from the lowest
    vertex), without importing scipy (0.3 s at start-up): a cycle's label
    is how many cycle minima come before its own (a running count, no sort).

    Parameters
    ----------
    nxt : ndarray of int (n,)
        A permutation of ``0 .. n-1``.

    Returns
    -------
    count : int
        Number of cycles.
    label : ndarray of int64 (n,)
        Cycle of each element, ``0 .. count-1``.
    """
    return _labels_of_min(_cycle_min(np.asarray(nxt, np.int64)))


def trace_faces(xy: np.ndarray, u: np.ndarray, v: np.ndarray, *, order: np.ndarray | None = None):
    """Cycles of the half-edge "next" permutation of a plane graph.

    Around each node, outgoing half-edges are sorted by angle (one
    ``numpy.lexsort``); the successor of half-edge ``h`` (a -> b) is the
    outgoing half-edge of ``b`` that comes clockwise right after the twin
    (b -> a): the lowest positive turn, skylineEngine §5.4 / Fig. 8.  Faces
    are the cycles of that permutation (:func:`permutation_cycles`).

    Parameters
    ----------
    xy : ndarray (n, 2)
        Node coordinates.
    u, v : ndarray of int (m,)
        Edges; no self-loops, no duplicates (see :func:`planar_faces`).
    order : ndarray of int64 (2 m,), optional
        The half-edges already sorted by origin node, then angle (for
        example a larger graph's order with the removed edges filtered
        out, which keeps it sorted); sorted here when None.

    Returns
    -------
    nxt : ndarray of int64 (2 m,)
        Successor of each half-edge in its face.
    face : ndarray of int64 (2 m,)
        Face label of each half-edge, ``0 .. nfaces-1``.
    area : ndarray of float (nfaces,)
        Signed area of each face walk (m2): positive for bounded faces.
    """
    return _trace(xy, u, v, order)[:3]


def _trace(xy, u, v, order=None):
    """:func:`trace_faces`, and each half-edge's cycle minimum and cross product (twice its area term)."""
    m = len(u)
    h = np.arange(2 * m, dtype=np.int64)
    org = np.empty(2 * m, np.int64)
    org[0::2] = u
    org[1::2] = v
    dst = np.empty(2 * m, np.int64)
    dst[0::2] = v
    dst[1::2] = u
    if order is None:
        order = _angular_order(xy, u, v)
    so = org[order]
    # start and size of each node's group in sorted order
    brk = np.flatnonzero(np.r_[True, so[1:] != so[:-1]])
    size = np.diff(np.r_[brk, 2 * m])
    prev_pos = h - 1  # clockwise neighbour in sorted order: the one before, the group's last for its first
    if len(h):
        prev_pos[brk] = brk + size - 1
    cw = np.empty(2 * m, np.int64)
    cw[order] = order[prev_pos]
    nxt = cw[h ^ 1]
    low = _cycle_min(nxt)
    nf, face = _labels_of_min(low)
    cross = xy[org, 0] * xy[dst, 1] - xy[dst, 0] * xy[org, 1]
    area = np.bincount(face, weights=cross, minlength=nf) / 2.0
    return nxt, face, area, low, cross


def _without(nxt: np.ndarray, low: np.ndarray, gone: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The "next" permutation and cycle minima of a plane graph with some edges removed, from the whole graph's.

    Around a node, the half-edge clockwise after ``h`` is ``nxt[h ^ 1]``;
    with some of them removed it is the first one left going on clockwise.
    So the successor of a half-edge left is its old successor, or, while
    that one is removed, the successor of the removed one's twin.  Cycles
    without a removed half-edge stay as they are (their minimum too, under
    the renumbering, which keeps the order); only the cycles that had one
    are doubled again, on their own.  Same result as tracing the smaller
    graph afresh (:func:`trace_faces` with the order filtered), for a few
    gathers over the whole graph.

    Parameters
    ----------
    nxt, low : ndarray of int64 (2 m,)
        The whole graph's next permutation and each half-edge's cycle minimum.
    gone : ndarray of bool (m,)
        Edges removed.

    Returns
    -------
    live : ndarray of int64 (2 k,)
        The half-edges left, in order (half-edge ``i`` of the smaller graph is ``live[i]``).
    nxt, low : ndarray of int64 (2 k,)
        The smaller graph's next permutation and cycle minima, numbered as it numbers its half-edges.
    """
    gone_h = np.repeat(np.asarray(gone, bool), 2)
    live = np.flatnonzero(~gone_h)
    y = nxt[live]
    todo = np.flatnonzero(gone_h[y])
    while len(todo):
        y[todo] = nxt[y[todo] ^ 1]
        todo = todo[gone_h[y[todo]]]
    newid = np.cumsum(~gone_h) - 1
    nxt2 = newid[y]
    hit = np.zeros(len(nxt), bool)
    hit[low[gone_h]] = True  # cycles that lose a half-edge, by their minimum
    low2 = newid[low[live]]
    sub = np.flatnonzero(hit[low[live]])
    if len(sub):
        loc = np.full(len(live), -1, np.int64)
        loc[sub] = np.arange(len(sub))
        low2[sub] = sub[_cycle_min(loc[nxt2[sub]])]
    return live, nxt2, low2


def _cycle_order(
    nxt: np.ndarray, face: np.ndarray, nf: int, low: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Half-edges listed face by face in walk order, and each face's start offset.

    List ranking by pointer jumping: O(n log L) numpy gathers, L the longest
    face.  ``low`` (optional): each half-edge's cycle minimum, when known.
    """
    n = len(nxt)
    h = np.arange(n, dtype=np.int64)
    if low is None:
        head = np.full(nf, n, np.int64)
        np.minimum.at(head, face, h)
    else:
        head = np.empty(nf, np.int64)
        head[face] = low
    pred = np.empty(n, np.int64)
    pred[nxt] = h
    tail = pred[head]
    succ = nxt.copy()
    succ[tail] = tail
    dist = (succ != h).astype(np.int64)
    # pointer jumping on the half-edges not yet at their tail only: the many short faces drop out
    # after a few rounds, the long ones (a block's interior) go on alone (the same sums)
    act = np.flatnonzero(succ != h)
    while len(act):
        s = succ[act]
        ss = succ[s]
        live = ss != s
        act, s, ss = act[live], s[live], ss[live]
        dist[act] += dist[s]
        succ[act] = ss
    size = np.bincount(face, minlength=nf)
    offset = np.r_[0, np.cumsum(size)[:-1]]
    rank = size[face] - 1 - dist
    ordered = np.empty(n, np.int64)
    ordered[offset[face] + rank] = h
    return ordered, offset


def _split_walk(vids: list[int]) -> list[list[int]]:
    """Split a closed walk that revisits vertices into simple closed walks (a stack, in Python).

    Going along the walk, a vertex already on the stack closes the cycle
    from its first visit to here: that cycle is emitted and popped, the
    vertex stays.  What is left at the end is the last cycle.  Cycles of
    fewer than three vertices are dropped.
    """
    stack: list[int] = []
    where: dict[int, int] = {}
    out = []
    for vid in vids:
        j = where.get(vid)
        if j is not None:
            out.append(stack[j:])
            for w in stack[j + 1 :]:
                where.pop(w, None)
            del stack[j + 1 :]
        else:
            where[vid] = len(stack)
            stack.append(vid)
    if len(stack) >= 3:
        out.append(stack)
    return [c for c in out if len(c) >= 3]


def split_walks(vid: np.ndarray, walk: np.ndarray, nwalk: int):
    """:func:`_split_walk` of many closed walks at once, vectorized.

    Parameters
    ----------
    vid : ndarray of int (n,)
        Vertex of each position, walk after walk.
    walk : ndarray of int (n,)
        Walk of each position (non-decreasing, ``0 .. nwalk-1``).
    nwalk : int

    Returns
    -------
    vertex : ndarray of int64
        The cycles' vertices, cycle after cycle, each in walk order.
    cycle : ndarray of int64
        Cycle of each entry, ``0 .. c-1``, in the order :func:`_split_walk` emits them walk by walk.
    cycle_walk : ndarray of int64 (c,)
        Walk of each cycle.

    Notes
    -----
    Two consecutive visits ``p < q`` of one vertex enclose an interval; on
    the boundary of a face of a plane graph these intervals nest (a walk
    ``a .. b .. a .. b`` would need the face to cross itself).  The cycle
    closed at ``q`` is its first visit ``p`` and the first visits of other
    vertices whose innermost enclosing interval is ``(p, q)``; first visits
    inside no interval make the walk's last cycle.  The innermost interval
    of each position is found per nesting depth with one ``searchsorted``.
    Walks that do not nest (not the faces of a plane embedding) go through
    :func:`_split_walk`.
    """
    vid = np.asarray(vid, np.int64)
    walk = np.asarray(walk, np.int64)
    n = len(vid)
    pos = np.arange(n, dtype=np.int64)
    key = walk * (int(vid.max(initial=0)) + 1) + vid
    o = argsort_int(key)
    same = key[o][1:] == key[o][:-1]
    p, q = o[:-1][same], o[1:][same]  # consecutive visits of one vertex in one walk
    k = len(p)
    level, nested = _nesting(p, q, n)
    if not nested:
        return _split_walks_python(vid, walk, nwalk)
    first = np.ones(n, bool)
    first[q] = False
    depth = np.cumsum(np.bincount(p + 1, minlength=n + 1) - np.bincount(q, minlength=n + 1))[:n]
    inner = np.full(n, -1, np.int64)
    if k:  # the last interval of the position's depth opened before it
        ikey = level * (n + 1) + p
        io = argsort_int(ikey)
        at = np.searchsorted(ikey[io], depth * (n + 1) + pos) - 1
        inner = np.where(depth > 0, io[np.maximum(at, 0)], -1)
    # cycles 0..k-1 close at q; cycle k + w is walk w's remainder, emitted at its end
    wend = np.searchsorted(walk, np.arange(nwalk), side="right")
    emitted = np.argsort(np.r_[2 * q, 2 * wend - 1], kind="stable")
    rank = np.empty(k + nwalk, np.int64)
    rank[emitted] = np.arange(k + nwalk)
    mpos = np.r_[pos[first], p]
    mcyc = rank[np.r_[np.where(inner[first] >= 0, inner[first], k + walk[first]), np.arange(k)]]
    e = np.lexsort((mpos, mcyc))
    mcyc, mpos = mcyc[e], mpos[e]
    big = np.bincount(mcyc, minlength=k + nwalk)[mcyc] >= 3
    used, cycle = np.unique(mcyc[big], return_inverse=True)
    return vid[mpos[big]], cycle.ravel().astype(np.int64), np.r_[walk[p], np.arange(nwalk)][emitted[used]]


def _nesting(p: np.ndarray, q: np.ndarray, n: int) -> tuple[np.ndarray, bool]:
    """Nesting level of intervals ``[p, q)`` (1 = outermost), and whether they nest properly.

    Read as brackets (a close before an open at the same position), each
    close must match the last open of its own level.
    """
    k = len(p)
    if np.any(q < p + 2):
        return np.empty(0, np.int64), False
    ev = np.r_[2 * p + 1, 2 * q]
    eo = np.argsort(ev, kind="stable")
    d = np.cumsum(np.where(eo < k, 1, -1))
    lev = np.empty(2 * k, np.int64)
    lev[eo] = np.where(eo < k, d, d + 1)
    big = 2 * n + 2
    okey = lev[:k] * big + ev[:k]
    so = np.argsort(okey, kind="stable")
    match = np.searchsorted(okey[so], lev[k:] * big + ev[k:]) - 1
    nested = bool(np.all(match >= 0) and np.array_equal(so[np.maximum(match, 0)], np.arange(k)))
    return lev[:k], nested


def _split_walks_python(vid: np.ndarray, walk: np.ndarray, nwalk: int):
    """:func:`split_walks` walk by walk with :func:`_split_walk`."""
    starts = np.searchsorted(walk, np.arange(nwalk + 1))
    cycles = [(w, c) for w in range(nwalk) for c in _split_walk(vid[starts[w] : starts[w + 1]].tolist())]
    if not cycles:
        z = np.empty(0, np.int64)
        return z, z, z
    size = [len(c) for _, c in cycles]
    return (
        np.fromiter((x for _, c in cycles for x in c), np.int64, sum(size)),
        np.repeat(np.arange(len(cycles)), size),
        np.array([w for w, _ in cycles], np.int64),
    )


def signed_area(xy: np.ndarray, index: np.ndarray, n: int | None = None) -> np.ndarray:
    """Shoelace signed area of rings given as grouped, ordered vertices.

    Parameters
    ----------
    xy : ndarray (k, 2)
        Ring vertices, not repeated at the end, grouped contiguously by ring.
    index : ndarray of int (k,)
        Ring index of each vertex, non-decreasing.
    n : int, optional
        Number of rings (default ``index.max() + 1``).

    Returns
    -------
    ndarray (n,)
        Signed areas (m2), positive for counter-clockwise rings.
    """
    index = np.asarray(index)
    n = int(index.max()) + 1 if n is None else n
    if len(index) == 0:
        return np.zeros(n)
    brk = np.flatnonzero(np.r_[True, index[1:] != index[:-1]])
    size = np.diff(np.r_[brk, len(index)])
    start = np.repeat(brk, size)
    k = np.arange(len(index))
    nxt = np.where(k + 1 < start + np.repeat(size, size), k + 1, start)
    cross = xy[:, 0] * xy[nxt, 1] - xy[nxt, 0] * xy[:, 1]
    return np.bincount(index, weights=cross, minlength=n) / 2.0


STAR_ULPS = 1024.0  # margin of the star certificate, in units of rounding of the largest coordinate


def star_simple(xy: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """Which closed rings are certainly simple and counter-clockwise: strictly star-shaped round their vertex mean.

    A ring each of whose edges has the mean ``c`` of the ring's vertices
    strictly on its left, and which goes round ``c`` once (it crosses the
    ray from ``c`` along +x once), is simple: each edge sweeps its own open
    interval of directions seen from ``c``, consecutive edges' intervals
    abut and together they go round once, so edges that are not neighbours
    see disjoint directions and cannot meet.  Such a ring makes a valid
    polygon (GEOS's ``is_valid``) of positive area.  Edges of zero length
    (a coordinate repeated) are passed over, as GEOS passes them.
    "Strictly" is by a margin (``STAR_ULPS`` units of rounding of the
    largest coordinate of the call, times the edge's distance from ``c``)
    far above the float error of the test, so a ring certified is simple in
    exact arithmetic.  False says nothing: the ring may still be simple.

    Parameters
    ----------
    xy : ndarray (k, 2)
        Ring coordinates (m), ring after ring, each ring closed (its first
        coordinate repeated at its end).
    sizes : ndarray of int (r,)
        Coordinates of each ring, the closing one included.

    Returns
    -------
    ndarray of bool (r,)
        Certainly simple and counter-clockwise.
    """
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    sizes = np.asarray(sizes, np.int64)
    r = len(sizes)
    out = np.zeros(r, bool)
    live = np.flatnonzero(sizes >= 4)
    if len(live) < r:  # rings of fewer than three vertices: none certified
        if len(live):
            keep = np.repeat(sizes >= 4, sizes)
            out[live] = star_simple(xy[keep], sizes[live])
        return out
    if r == 0:
        return out
    end = np.cumsum(sizes)
    start = end - sizes
    c = (np.add.reduceat(xy, start, axis=0) - xy[end - 1]) / (sizes - 1)[:, None]
    dx, dy = xy[:, 0] - np.repeat(c[:, 0], sizes), xy[:, 1] - np.repeat(c[:, 1], sizes)
    ax, ay, bx, by = dx[:-1], dy[:-1], dx[1:], dy[1:]  # edge k: coordinate k to k + 1 (the step from a ring's
    # last coordinate to the next ring's first is no edge: it is passed over below)
    cr = ax * by - ay * bx
    delta = STAR_ULPS * np.finfo(np.float64).eps * max(float(np.abs(xy).max()), 1.0)
    norm = np.abs(dx) + np.abs(dy)  # |a| + |b| of each edge: the L1 norms of its two ends
    with np.errstate(invalid="ignore"):
        strict = cr > delta * (norm[:-1] + norm[1:])
    same = (ax == bx) & (ay == by)
    up = (ay <= 0.0) & (by > 0.0)  # crosses the ray from c along +x, going round counter-clockwise
    between = end[:-1] - 1
    strict[between], same[between], up[between] = True, False, False
    # per ring: edges failing, crossings of the ray, edges of positive length (cumulative counts)
    bad = np.r_[0, np.cumsum(~(strict | same))]
    turn = np.r_[0, np.cumsum(up)]
    good = np.r_[0, np.cumsum(strict & ~same)]
    last = end - 1  # one past each ring's last edge
    fail = bad[last] - bad[start]
    turns = turn[last] - turn[start]
    edges = good[last] - good[start]
    return (fail == 0) & (turns == 1) & (edges >= 3)


def _orient(p, q, r):
    """Sign of the turn p -> q -> r (1 left, -1 right, 0 straight) for rows of points."""
    return np.sign((q[:, 0] - p[:, 0]) * (r[:, 1] - p[:, 1]) - (q[:, 1] - p[:, 1]) * (r[:, 0] - p[:, 0]))


COARSE = 4  # runs per box of the far pass of ring_crossings (sets the cost only)
EDGE_PAD = 1e-9  # edge boxes of ring_crossings grow by this times the largest coordinate (0.25 mm at 250 km)


def _box_meet(lo, hi, a, b):
    """Whether the boxes ``a`` and ``b`` (rows of ``lo``, ``hi``) meet (closed), pair by pair."""
    return (lo[a, 0] <= hi[b, 0]) & (lo[b, 0] <= hi[a, 0]) & (lo[a, 1] <= hi[b, 1]) & (lo[b, 1] <= hi[a, 1])


def ring_crossings(xy: np.ndarray, sizes: np.ndarray, chain: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Pairs of edges of the same closed ring that cross or touch, neighbours along the ring excepted.

    Edge ``i`` of a ring runs from its vertex ``i`` to the next one (the
    last back to the first).  Runs of ``chain`` consecutive edges are boxed
    and the pairs of runs whose boxes meet are found in two passes: runs
    near one another along the ring (up to ``2 COARSE - 1`` runs apart) are
    compared directly, and runs farther apart through boxes of ``COARSE``
    runs paired on a grid (:func:`sengine.geom.grid.box_self_pairs`; two boxes
    of runs that meet lie in coarse boxes that meet, and runs of the same
    or neighbouring coarse boxes are near), so the grid sees a quarter of
    the boxes and none of the pairs every ring has (each run with itself
    and its neighbours).  Two neighbouring runs whose ``2 chain + 1``
    vertices advance strictly along their chord cannot meet (a strictly
    monotone line is simple) and are passed over; the edges of the other
    pairs are tested two by two with the signs of their turns (edges that
    share a vertex, or collinear edges that overlap, touch).  Numpy
    throughout; the sign test is in floating point, so a pair touching
    within rounding may be reported or not.

    Parameters
    ----------
    xy : ndarray (k, 2)
        Vertices, ring after ring, not closed (no repeated first vertex).
    sizes : ndarray of int (r,)
        Vertices of each ring (at least 3 for any pair to be reported).
    chain : int
        Edges per box (sets the cost only).

    Returns
    -------
    i, j : ndarray of int64
        Edges (indices of their first vertex in ``xy``) with ``i < j``, of
        one ring, not consecutive along it, that meet.
    """
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    sizes = np.asarray(sizes, np.int64)
    e64 = np.zeros(0, np.int64)
    if len(xy) == 0:
        return e64, e64
    start = np.cumsum(sizes) - sizes
    ring = np.repeat(np.arange(len(sizes)), sizes)
    k = np.arange(len(xy)) - start[ring]
    nxt = start[ring] + np.mod(k + 1, sizes[ring])
    # runs of `chain` edges: run r of a ring covers its edges chain r .. chain r + chain - 1 (fewer at the end)
    nrun = -(-sizes // chain)
    rstart = np.cumsum(nrun) - nrun
    rr = np.repeat(np.arange(len(sizes)), nrun)
    rk = np.arange(int(nrun.sum())) - rstart[rr]
    cnt = np.minimum(chain, sizes[rr] - chain * rk)
    off = np.arange(chain + 1)
    pos = np.minimum(off[None, :], cnt[:, None])  # vertices of the run (the last repeated where shorter)
    at = start[rr][:, None] + np.mod(chain * rk[:, None] + pos, sizes[rr][:, None])
    lo = hi = first = prev = xy[at[:, 0]]
    steps = []
    for c in range(1, chain + 1):  # column by column: faster than a reduction over a short axis
        p = xy[at[:, c]]
        lo, hi = np.minimum(lo, p), np.maximum(hi, p)
        steps.append(p - prev)
        prev = p
    # a whole run strictly monotone along its chord meets itself nowhere (as two neighbouring runs, below)
    chord = prev - first
    bent = cnt < chain
    for s in steps:
        bent |= s[:, 0] * chord[:, 0] + s[:, 1] * chord[:, 1] <= 0
    # near pairs: each run and the next ones round its ring, up to 2 COARSE - 1 runs on (fewer in short rings)
    span = np.minimum(2 * COARSE - 1, nrun - 1)
    nd = span[rr] + 1
    ia = np.repeat(np.arange(len(rr)), nd)
    d = _ramp(nd)
    ring_a = rr[ia]
    ib = rstart[ring_a] + np.mod(rk[ia] + d, nrun[ring_a])
    meet = _box_meet(lo, hi, ia, ib)
    ia, ib, d = ia[meet], ib[meet], d[meet]
    # far pairs: boxes of COARSE runs that are not neighbours round the ring, paired on the grid
    nco = -(-nrun // COARSE)
    cfirst = np.flatnonzero(rk % COARSE == 0)  # first run of each coarse box (a ring's runs are contiguous)
    cring = rr[cfirst]
    ck = rk[cfirst] // COARSE
    clo = np.minimum.reduceat(lo, cfirst, axis=0)
    chi = np.maximum.reduceat(hi, cfirst, axis=0)
    ca, cb = box_self_pairs(clo, chi, group=cring)
    gap = ck[cb] - ck[ca]
    far = (gap >= 2) & (gap <= nco[cring[ca]] - 2)
    ca, cb = ca[far], cb[far]
    na, nb = (
        np.minimum(COARSE, nrun[cring[ca]] - COARSE * ck[ca]),
        np.minimum(COARSE, nrun[cring[cb]] - COARSE * ck[cb]),
    )
    row = np.repeat(np.arange(len(ca)), na * nb)
    q = _ramp(na * nb)
    fa = cfirst[ca][row] + q // nb[row]
    fb = cfirst[cb][row] + q % nb[row]
    n_f = nrun[rr[fa]]
    fwd = rk[fb] - rk[fa]
    keep = (fwd > span[rr[fa]]) & (n_f - fwd > span[rr[fa]])  # the near pass has the others
    fa, fb = fa[keep], fb[keep]
    meet = _box_meet(lo, hi, fa, fb)
    fa, fb = fa[meet], fb[meet]
    # neighbouring runs (the next one round the ring) strictly monotone along their chord: no crossing
    n = nrun[rr[ia]]
    adj = ((d == 1) | (d == n - 1)) & (n > 2)
    f = np.where(d == 1, ia, ib)[adj]
    g = np.where(d == 1, ib, ia)[adj]
    whole = (cnt[f] == chain) & (cnt[g] == chain)
    chord = prev[g] - first[f]  # from the first run's first vertex to the second's last
    steps = np.stack(steps, axis=1)
    mono = whole & (np.einsum("ikj,ij->ik", steps[f], chord) > 0).all(axis=1)
    mono &= (np.einsum("ikj,ij->ik", steps[g], chord) > 0).all(axis=1)
    keep = np.ones(len(ia), bool)
    keep[np.flatnonzero(adj)[mono]] = False
    self_ = keep & (d == 0) & bent[ia]
    other = keep & (d > 0)
    # edge pairs: a run with itself (edges two or more apart); of two runs, the edges of each whose box
    # meets the other run's box, two by two (padded far beyond rounding: the sign test below is not
    # exact, and a pair it would say touches is kept)
    sa, sb = np.triu_indices(chain, 2)
    srun = ia[self_]
    sa, sb, srun = np.tile(sa, len(srun)), np.tile(sb, len(srun)), np.repeat(srun, len(sa))
    whole = sb < cnt[srun]
    sa, sb, srun = sa[whole], sb[whole], srun[whole]
    ia, ib = np.r_[ia[other], fa], np.r_[ib[other], fb]
    pad = EDGE_PAD * max(float(np.abs(xy).max()), 1.0)
    elo, ehi = np.minimum(xy, xy[nxt]) - pad, np.maximum(xy, xy[nxt]) + pad
    live = np.arange(chain)

    def near(a, b):  # (pair, k): edge k of run a exists and its box meets run b's box
        e = at[a, :chain]
        lo_e, hi_e, lo_b, hi_b = elo[e], ehi[e], lo[b][:, None], hi[b][:, None]
        ok = (lo_e[..., 0] <= hi_b[..., 0]) & (lo_b[..., 0] <= hi_e[..., 0])
        ok &= (lo_e[..., 1] <= hi_b[..., 1]) & (lo_b[..., 1] <= hi_e[..., 1])
        return ok & (live < cnt[a][:, None])

    pair, ka, kb = np.nonzero(near(ia, ib)[:, :, None] & near(ib, ia)[:, None, :])
    ea, eb = np.r_[at[srun, sa], at[ia[pair], ka]], np.r_[at[srun, sb], at[ib[pair], kb]]
    i, j = np.minimum(ea, eb), np.maximum(ea, eb)
    keep = (i != j) & (nxt[i] != j) & (nxt[j] != i)
    i, j = i[keep], j[keep]
    a1, b1, a2, b2 = xy[i], xy[nxt[i]], xy[j], xy[nxt[j]]
    o1, o2 = _orient(a1, b1, a2), _orient(a1, b1, b2)
    o3, o4 = _orient(a2, b2, a1), _orient(a2, b2, b1)
    hit = (o1 * o2 <= 0) & (o3 * o4 <= 0)
    # collinear pairs (all four signs 0) meet only where their extents along the line overlap
    col = hit & (o1 == 0) & (o2 == 0)
    if col.any():
        c = np.flatnonzero(col)
        d = b1[c] - a1[c]
        d = np.where((d == 0).all(axis=1)[:, None], b2[c] - a2[c], d)
        t = lambda p: np.einsum("ij,ij->i", p, d)  # noqa: E731
        s1, s2 = np.sort(np.c_[t(a1[c]), t(b1[c])], axis=1), np.sort(np.c_[t(a2[c]), t(b2[c])], axis=1)
        point = (d == 0).all(axis=1)  # both edges of zero length: they meet where they are one point
        hit[c] = np.where(point, (a1[c] == a2[c]).all(axis=1), (s1[:, 0] <= s2[:, 1]) & (s2[:, 0] <= s1[:, 1]))
    i, j = i[hit], j[hit]
    o = np.lexsort((j, i))
    i, j = i[o], j[o]
    u = np.r_[True, (i[1:] != i[:-1]) | (j[1:] != j[:-1])] if len(i) else np.zeros(0, bool)
    return i[u], j[u]


@dataclass
class PlanarFaces:
    """The faces of a plane graph (result of :func:`planar_faces`).

    Attributes
    ----------
    polygons : ndarray of shapely.Polygon
        Bounded faces; a face holding a disconnected component has it as a
        hole.  Together they partition the area inside the outer rings.
    edge_faces : ndarray of int64, shape (m, 2)
        For each input edge, the polygon on its left (u -> v) and on its
        right; ``-1`` for the outside, for a dropped edge (self-loop,
        bridge) or a degenerate face.
    outline : ndarray of shapely.Polygon
        One polygon per outermost connected component: its outer boundary.
    bridge : ndarray of bool, shape (m,)
        Edges removed because the same face lies on both sides (dead ends
        and connectors between components).
    counts : dict
        ``edges``, ``duplicates``, ``self_loops``, ``bridges``, ``faces``,
        ``holes``, ``degenerate``, ``pinched`` (faces split at a vertex).
    walk_vertex : ndarray of int64
        The closed walks traced (cycles of the half-edge permutation of the
        bridgeless graph, bounded or not), walk after walk: the node id of
        each half-edge's origin, in walk order from the walk's lowest half-edge.
    walk_start : ndarray of int64, shape (w + 1,)
        Walk ``k`` is ``walk_vertex[walk_start[k]:walk_start[k + 1]]``.
    walk_area : ndarray of float, shape (w,)
        Signed area of each walk (m2): positive for bounded faces.
    walk_polygon : ndarray of int64, shape (w,)
        The polygon whose shell is the walk, vertex for vertex (simple
        bounded walks), else ``-1``.
    walk_edge : ndarray of int64, same length as ``walk_vertex``
        The edge each half-edge of the walks runs along, as a distinct edge
        (an index into the input's edges with duplicates counted once, the
        numbers of ``edge_unique``).
    edge_unique : ndarray of int64, shape (m,)
        Each input edge's distinct edge (``-1`` for a self-loop): an edge
        flag of the input reaches the walks as
        ``flag_u[edge_unique[flag]] = True; flag_u[walk_edge]``.
    spur_trace : dict
        The first trace, before the bridges were removed (what
        :func:`spur_polygons` needs): ``u``, ``v`` (the unique edges), ``next``
        and ``walk`` (per half-edge), ``area`` (per walk), ``polygon`` (per
        half-edge: the polygon it bounds after the bridges are gone, -1 for
        a bridge; a face pinched into several shells counts as its largest)
        and ``face`` (per polygon: its face).  Empty when the graph had no
        bridge.
    """

    polygons: np.ndarray
    edge_faces: np.ndarray
    outline: np.ndarray
    bridge: np.ndarray
    counts: dict = field(default_factory=dict)
    walk_vertex: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))
    walk_start: np.ndarray = field(default_factory=lambda: np.zeros(1, np.int64))
    walk_area: np.ndarray = field(default_factory=lambda: np.empty(0))
    walk_polygon: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))
    spur_trace: dict = field(default_factory=dict)
    walk_edge: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))
    edge_unique: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))


def _pinched(org: np.ndarray, face: np.ndarray, nf: int) -> np.ndarray:
    """Faces that leave some node by two half-edges (their walk passes it twice), from half-edges grouped by node.

    The repeated (face, node) pairs a sort of all of them finds, found
    within each node's few half-edges, all nodes of one degree at once.
    """
    out = np.zeros(nf, bool)
    if len(org) == 0:
        return out
    start = np.flatnonzero(np.r_[True, org[1:] != org[:-1]])
    size = np.diff(np.r_[start, len(org)])
    for k in np.unique(size[size > 1]):
        rows = np.sort(face[start[size == k][:, None] + np.arange(k)], axis=1)
        out[rows[:, 1:][rows[:, 1:] == rows[:, :-1]]] = True
    return out


def _unit_polygons(xy, vid, start, size, units) -> np.ndarray:
    """Polygons of the rings ``units`` (vertices ``vid[start:start + size]``, not closed), in one call.

    ``shapely.polygons(shapely.linearrings(...))``, the same bytes, without
    making each ring first and copying it into its polygon.
    """
    n = size[units]
    closed = n + 1
    row = np.repeat(np.arange(len(units)), closed)
    k = _ramp(closed)
    at = start[units][row] + np.where(k == n[row], 0, k)  # each ring's vertices, then its first again
    offsets = np.r_[0, np.cumsum(closed)]
    return shapely.from_ragged_array(shapely.GeometryType.POLYGON, xy[vid[at]], (offsets, np.arange(len(units) + 1)))


def planar_faces(xy, u, v, *, area_eps: float = 1e-9) -> PlanarFaces:
    """Bounded faces of a plane graph as polygons with holes.

    Parameters
    ----------
    xy : array_like (n, 2)
        Node coordinates (m).
    u, v : array_like of int (m,)
        Edge end node ids.  The graph must be plane (edges meet only at
        nodes; see :func:`sengine.geom.segments.planarize`).  Self-loops are ignored, duplicate
        edges (either direction) count once.
    area_eps : float
        Faces whose absolute signed area is at most this (m2) are degenerate
        (collinear overlaps) and dropped.

    Returns
    -------
    PlanarFaces

    Notes
    -----
    1. Half-edges are traced with :func:`trace_faces`.
    2. An edge with the same face on both sides is a bridge (a dead end, or
       a path joining two components); all bridges are removed at once and
       the faces traced again (a bridgeless graph has no new bridges).
    3. A walk that passes a vertex twice is split there into simple rings:
       the positive one is the shell, negative ones are holes touching it.
    4. The clockwise outer walk of each component becomes a hole of the
       smallest bounded face containing it, or an outline ring when none
       does.
    """
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    u0 = np.asarray(u, np.int64).ravel()
    v0 = np.asarray(v, np.int64).ravel()
    m0 = len(u0)
    n = len(xy)
    counts = {"edges": m0}
    loop = u0 == v0
    a = np.minimum(u0, v0)
    b = np.maximum(u0, v0)
    key = a[~loop] * n + b[~loop]
    uniq, inv = unique_int(key, return_inverse=True)
    emap = np.full(m0, -1, np.int64)
    emap[~loop] = inv.ravel()
    flip = u0 > v0
    eu, ev = uniq // n, uniq % n
    counts["self_loops"] = int(loop.sum())
    counts["duplicates"] = int((~loop).sum() - len(uniq))
    bridge_u = np.zeros(len(uniq), bool)
    live = np.arange(len(uniq))
    empty = PlanarFaces(
        np.empty(0, object),
        np.full((m0, 2), -1, np.int64),
        np.empty(0, object),
        np.zeros(m0, bool),
        {**counts, "bridges": 0, "faces": 0, "holes": 0, "degenerate": 0, "pinched": 0},
    )
    if len(uniq) == 0:
        return empty
    order = _angular_order(xy, eu, ev)
    nxt, face, area, low, cross = _trace(xy, eu, ev, order)
    br = face[0::2] == face[1::2]
    first = {"u": eu, "v": ev, "next": nxt, "walk": face, "area": area} if br.any() else {}
    if br.any():
        bridge_u[br] = True
        live = np.flatnonzero(~br)
        if len(live) == 0:
            empty.bridge = bridge_u[np.maximum(emap, 0)] & (emap >= 0)
            empty.counts["bridges"] = int(br.sum())
            return empty
        # the bridgeless graph's faces, from the first trace (as tracing it afresh would give them)
        hl, nxt, low = _without(nxt, low, br)
        nf, face = _labels_of_min(low)
        area = np.bincount(face, weights=cross[hl], minlength=nf) / 2.0
    counts["bridges"] = int(bridge_u.sum())
    nf = len(area)
    lu, lv = eu[live], ev[live]
    org = np.empty(2 * len(live), np.int64)
    org[0::2] = lu
    org[1::2] = lv
    ordered, offset = _cycle_order(nxt, face, nf, low)
    fsize = np.bincount(face, minlength=nf)
    degenerate = np.abs(area) <= area_eps
    counts["degenerate"] = int(degenerate.sum())
    # pinched walks: a vertex repeated within one face, i.e. two of its half-edges leaving in one face
    if br.any():  # the bridgeless graph's half-edges in the first trace's order (by node, then angle)
        gone_h = np.repeat(br, 2)
        order = (np.cumsum(~gone_h) - 1)[order[~gone_h[order]]]
    pinched = _pinched(org[order], face[order], nf)
    pinched &= ~degenerate
    counts["pinched"] = int(pinched.sum())
    # ring units: simple faces directly, pinched faces split into simple cycles
    simple = ~pinched & ~degenerate
    ovid = org[ordered]
    oface = np.repeat(np.arange(nf), fsize)
    take = simple[oface]
    unit_vid = [ovid[take]]
    sf = np.flatnonzero(simple)
    unit_face = [sf]
    unit_of_entry = [np.repeat(np.arange(len(sf)), fsize[sf])]
    nunit = len(sf)
    pf = np.flatnonzero(pinched)
    if len(pf):
        sel = pinched[oface]
        cv, cyc, cwalk = split_walks(ovid[sel], np.searchsorted(pf, oface[sel]), len(pf))
        unit_vid.append(cv)
        unit_of_entry.append(nunit + cyc)
        unit_face.append(pf[cwalk])
        nunit += len(cwalk)
    unit_vid = np.concatenate(unit_vid)
    unit_idx = np.concatenate(unit_of_entry)
    unit_face = np.concatenate(unit_face)
    uarea = signed_area(xy[unit_vid], unit_idx, nunit)
    bounded_face = area > area_eps
    is_shell = bounded_face[unit_face] & (uarea > area_eps)
    is_fhole = bounded_face[unit_face] & (uarea < -area_eps)
    is_outer = (area[unit_face] < -area_eps) & (uarea < -area_eps)
    # one polygon per shell unit; pinched holes go to their face's largest shell
    shells = np.flatnonzero(is_shell)
    poly_of_unit = np.full(nunit, -1, np.int64)
    poly_of_unit[shells] = np.arange(len(shells))
    face_poly = np.full(nf, -1, np.int64)
    sh_face = unit_face[shells]
    srt = np.argsort(uarea[shells], kind="stable")
    face_poly[sh_face[srt]] = np.arange(len(shells))[srt]
    first_entry = np.r_[0, np.flatnonzero(unit_idx[1:] != unit_idx[:-1]) + 1]
    unit_size = np.diff(np.r_[first_entry, len(unit_idx)])
    shell_polys = _unit_polygons(xy, unit_vid, first_entry, unit_size, shells)
    hole_units = np.flatnonzero(is_fhole)
    hole_poly = face_poly[unit_face[hole_units]]
    # outer walks: hole of the smallest shell strictly containing a vertex
    outer_units = np.flatnonzero(is_outer)
    pts = shapely.points(xy[unit_vid[first_entry[outer_units]]])
    host = np.full(len(outer_units), -1, np.int64)
    if len(shells) and len(outer_units):
        # a tree of the few outer walks' points asked by every shell (not a tree of every shell): the same pairs
        si, pi = shapely.STRtree(pts).query(shell_polys, predicate="contains")
        o = np.lexsort((si, pi))
        pi, si = pi[o], si[o]
        if len(pi):
            o = np.lexsort((np.abs(uarea[shells[si]]), pi))
            pi, si = pi[o], si[o]
            firsts = np.r_[True, pi[1:] != pi[:-1]]
            host[pi[firsts]] = si[firsts]
    face_host = np.full(nf, -1, np.int64)
    face_host[unit_face[outer_units]] = host
    counts["holes"] = int((host >= 0).sum() + len(hole_units))
    ring_units = np.r_[shells, hole_units, outer_units[host >= 0]]
    ring_poly = np.r_[np.arange(len(shells)), hole_poly, host[host >= 0]]
    ring_hole = np.r_[np.zeros(len(shells), bool), np.ones(len(hole_units) + int((host >= 0).sum()), bool)]
    ok = ring_poly >= 0
    ring_units, ring_poly, ring_hole = ring_units[ok], ring_poly[ok], ring_hole[ok]
    # rings only of the units that are no shell or a holed face's shell (few): the shells are polygons already
    need = np.unique(np.r_[ring_units[ring_hole], outer_units])
    rings_all = np.full(nunit, None, dtype=object)
    if len(need):
        row = np.repeat(np.arange(len(need)), unit_size[need])
        at = first_entry[need][row] + _ramp(unit_size[need])
        rings_all[need] = shapely.linearrings(xy[unit_vid[at]], indices=row)
    # polygons without holes are their shells, already built; only the holed ones are built again
    polygons = shell_polys.copy() if len(shells) else np.empty(0, object)
    holed = np.zeros(len(shells), bool)
    holed[ring_poly[ring_hole]] = True
    if holed.any():
        sel = holed[ring_poly]
        ru, rp, rh = ring_units[sel], ring_poly[sel], ring_hole[sel]
        o = np.lexsort((rh, rp))
        rings = rings_all[ru[o]]
        rings[~rh[o]] = shapely.get_exterior_ring(shell_polys[rp[o][~rh[o]]])  # the shell: the polygon's ring
        polygons[np.flatnonzero(holed)] = shapely.polygons(rings, indices=np.searchsorted(np.flatnonzero(holed), rp[o]))
    outline = shapely.polygons(shapely.reverse(rings_all[outer_units[host < 0]]))
    # per-edge faces
    hface = np.where(bounded_face[face], face_poly[face], face_host[face])
    hface = np.where(degenerate[face], -1, hface)
    ef_live = np.full((len(uniq), 2), -1, np.int64)
    ef_live[live, 0] = hface[0::2]
    ef_live[live, 1] = hface[1::2]
    edge_faces = np.full((m0, 2), -1, np.int64)
    ok = emap >= 0
    ef = ef_live[emap[ok]]
    ef[flip[ok]] = ef[flip[ok]][:, ::-1]
    edge_faces[ok] = ef
    bridge = np.zeros(m0, bool)
    bridge[ok] = bridge_u[emap[ok]]
    counts["faces"] = int(len(polygons))
    if first:  # the first trace's half-edges, each with the polygon it bounds once the bridges are gone
        poly0 = np.full(2 * len(uniq), -1, np.int64)
        poly0[2 * live] = hface[0::2]
        poly0[2 * live + 1] = hface[1::2]
        first.update(polygon=poly0, face=unit_face[shells])
    return PlanarFaces(
        np.asarray(polygons, dtype=object),
        edge_faces,
        np.asarray(outline, dtype=object),
        bridge,
        counts,
        ovid,
        np.r_[offset, len(ovid)].astype(np.int64),
        area,
        np.where(simple, face_poly, -1),
        first,
        live[ordered >> 1],  # half-edges 2 k and 2 k + 1 of the bridgeless graph run along its edge k
        emap,
    )


def spur_polygons(pf: PlanarFaces, xy) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bounded faces whose rings run round the dead ends inside them.

    A tree of bridges (dead ends) hanging from a face's boundary is part of
    that face's walk before the bridges are removed: the walk goes out
    along each branch and back.  Drawn as a ring, the walk is a polygon
    with zero-width spurs: not valid as a polygon, but an inward buffer of
    it (GEOS offsets every segment of the ring, the spurs' on both sides)
    keeps away from the dead ends as from the face's own sides.  So a face
    shrunk for its streets leaves its cul-de-sacs out in the same buffer.

    Parameters
    ----------
    pf : PlanarFaces
        Faces of a graph, from :func:`planar_faces`.
    xy : ndarray (n, 2)
        The graph's node coordinates.

    Returns
    -------
    ids : ndarray of int64 (k,)
        The polygons of ``pf`` (indices into ``pf.polygons``) with a dead
        end on one of their rings.  A face pinched at a vertex into several
        polygons (lobes) is one walk: it is given once, as its largest lobe.
    polygons : ndarray of shapely.Polygon (k,)
        Their walks as rings with the spurs (shell first, then the holes);
        a pinched face's walk runs round all its lobes and touches itself
        at the pinches.  A tree that touches no ring (a component of dead
        ends alone, floating in a face) is not among them.
    spurs : ndarray of int64 (s, 3)
        The bridges drawn as spurs, as node pairs (lower id first), and the
        polygon (index into ``ids``) each is a spur of.
    lobes : ndarray of int64 (l, 2)
        For the pinched faces among them: (index into ``ids``, polygon of
        ``pf``) for every lobe of the face, the largest included.

    Notes
    -----
    An inward buffer of such a ring with round joins equals, to the float,
    the face minus the ground near its boundary and its dead ends (checked
    on the 1,895 faces with dead ends of Liège's street network, 499 of
    them pinched, and on generated trees).  With mitred joins GEOS leaves a
    few tips uncut (1 to 2 of Liège's 13,769 spurs for 6 to 15 m; more,
    before each ring was made to start off a spur): use round joins.
    """
    tr = pf.spur_trace
    none = (np.empty(0, np.int64), np.empty(0, dtype=object), np.empty((0, 3), np.int64), np.empty((0, 2), np.int64))
    if not tr:
        return none
    xy = np.asarray(xy, np.float64)
    nxt, walk, area, poly = tr["next"], tr["walk"], tr["area"], tr["polygon"]
    nw = len(area)
    wpoly = np.full(nw, -1, np.int64)
    np.maximum.at(wpoly, walk, poly)
    spur = np.zeros(nw, bool)
    spur[walk[poly < 0]] = True  # walks with a bridge
    target = np.unique(wpoly[spur & (wpoly >= 0)])
    if not len(target):
        return none
    take_w = np.zeros(nw, bool)
    take_w[wpoly >= 0] = np.isin(wpoly[wpoly >= 0], target)
    hsel = np.flatnonzero(take_w[walk])
    renum = np.full(len(nxt), -1, np.int64)
    renum[hsel] = np.arange(len(hsel))
    wsel = np.flatnonzero(take_w)
    wren = np.full(nw, -1, np.int64)
    wren[wsel] = np.arange(len(wsel))
    ordered, offset = _cycle_order(renum[nxt[hsel]], wren[walk[hsel]], len(wsel))
    size = np.diff(np.r_[offset, len(ordered)])
    # each ring starts at a vertex of the face's own ring, never at a spur's tip: GEOS's mitred
    # offset of a ring misses the reversal at a tip where the ring closes
    ring_of = np.repeat(np.arange(len(wsel)), size)
    at = np.arange(len(ordered)) - offset[ring_of]
    own = poly[hsel[ordered]] >= 0
    first = np.full(len(wsel), np.iinfo(np.int64).max)
    np.minimum.at(first, ring_of[own], at[own])
    ordered = ordered[offset[ring_of] + (at + first[ring_of]) % size[ring_of]]
    org = np.where(hsel[ordered] % 2 == 0, tr["u"][hsel[ordered] >> 1], tr["v"][hsel[ordered] >> 1])
    rings = shapely.linearrings(xy[org], indices=ring_of)
    owner = np.searchsorted(target, wpoly[wsel])
    hole = area[wsel] < 0
    o = np.lexsort((hole, owner))
    e = np.unique(hsel[poly[hsel] < 0] >> 1)
    spurs = np.sort(np.stack([tr["u"][e], tr["v"][e]], axis=1), axis=1)
    spurs = np.column_stack([spurs, np.searchsorted(target, wpoly[walk[2 * e]])])
    pface = tr["face"]
    nlobe = np.bincount(pface, minlength=int(pface.max(initial=-1)) + 1)
    lobe = np.flatnonzero(np.isin(pface, pface[target[nlobe[pface[target]] > 1]]))
    k = np.searchsorted(pface[target], pface[lobe], sorter=np.argsort(pface[target]))
    k = np.argsort(pface[target])[k]
    return target, shapely.polygons(rings[o], indices=owner[o]), spurs, np.stack([k, lobe], axis=1)

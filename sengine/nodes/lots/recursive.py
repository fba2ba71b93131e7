"""Recursive lots after Parish and Müller (skylineEngine §5.5, [13]).

Each piece larger than ``max_area`` is cut across its longest edge near the
middle, and the cut is kept only if every part keeps some street frontage.
The pieces of all blocks are cut together, level by level, as flat vertex
arrays (:class:`sengine.geom.ringset.RingSet`): a cut is one vectorized
:func:`sengine.geom.split.split` call for all pieces of a level, and street
frontage is an exact per-edge mark carried through the cuts (edges of the
block are streets, cut edges are not), so no GEOS call runs per piece.
Shapely polygons are made once, for the final lots.

References
----------
[13] Parish, Müller, "Procedural modeling of cities", SIGGRAPH 2001.
skylineEngine §5.5.
"""

from __future__ import annotations

import numpy as np

from sengine.geom.boundary import polygon_parts
from sengine.geom.split import RingSet, cut_lengths, split
from sengine.random import hash01

__all__ = ["recursive_lots"]


def _longest(ln: np.ndarray, vp: np.ndarray, n: int) -> np.ndarray:
    """Index of the first longest edge of each polygon (-1 for none); ``vp`` sorted."""
    best = np.full(n, -1, np.int64)
    if len(ln) == 0:
        return best
    start = np.flatnonzero(np.r_[True, vp[1:] != vp[:-1]])
    top = np.maximum.reduceat(ln, start)
    cand = np.flatnonzero(ln == np.repeat(top, np.diff(np.r_[start, len(ln)])))
    first = np.r_[True, vp[cand][1:] != vp[cand][:-1]]
    best[vp[cand[first]]] = cand[first]
    return best


def _cut_level(rs, own, key, seeds, min_frontage, jitter):
    """One level: a cut for every piece, the first of four that keeps street access.

    Returns the accepted pieces (RingSet), their parent piece and side, the
    mask of pieces no cut could split, and the number of failed cuts.
    """
    failed_count = 0
    k = rs.n
    vp = rs.vertex_poly()
    e = rs.xy[rs.next_vertex()] - rs.xy
    ln = rs.edge_lengths()
    unit = e / np.maximum(ln, 1e-300)[:, None]
    best = _longest(ln, vp, k)
    d_edge = np.tile([1.0, 0.0], (k, 1))
    d_edge[best >= 0] = unit[best[best >= 0]]
    bestf = _longest(np.where(rs.flag, ln, -1.0), vp, k)
    has_f = bestf >= 0
    has_f[has_f] &= rs.flag[bestf[has_f]]
    d_front = d_edge.copy()
    d_front[has_f] = unit[bestf[has_f]]
    u01 = hash01(seeds[own], key)
    mf = min_frontage[own]
    accepted = np.zeros(k, bool)
    new_rs, new_p, new_s = [], [], []
    left = np.arange(k)  # pieces still without a cut
    for kind, jit in (("edge", jitter), ("front", jitter), ("rect", jitter), ("front", 0.0)):
        if len(left) == 0:
            break
        sub = rs.take(left)
        if kind == "edge":
            d = d_edge[left]
        elif kind == "front":
            d = d_front[left]
        else:
            d = sub.min_rect_axis()
        ref, lo, hi = sub.extent_along(d)
        t = 0.5 + jit * (u01[left] - 0.5)
        point = ref + (lo + t * (hi - lo))[:, None] * d
        cut = np.stack([-d[:, 1], d[:, 0]], axis=1)
        # a cut crossing the boundary twice gives one piece per side, with
        # the street length on that side: judge it before cutting
        nc, fl, fr = cut_lengths(sub, point, cut)
        simple = nc == 2
        try_ = (simple & (fl >= mf[left]) & (fr >= mf[left])) | (nc > 2)
        go = np.flatnonzero(try_)
        pieces, parent, side, failed = split(sub.take(try_), point[go], cut[go])
        failed_count += int(failed.sum())
        front = pieces.flagged_length()
        good = ~failed & (np.bincount(parent, minlength=len(go)) >= 2)
        np.logical_and.at(good, parent, front >= mf[left[go[parent]]])
        sel = good[parent]
        new_rs.append(pieces.take(sel))
        new_p.append(left[go[parent[sel]]])
        new_s.append(side[sel])
        accepted[left[go[good]]] = True
        left = left[~accepted[left]]
    par = np.concatenate(new_p) if new_p else np.empty(0, np.int64)
    side = np.concatenate(new_s) if new_s else np.empty(0, np.int8)
    return RingSet.concat(new_rs), par, side, ~accepted, failed_count


def recursive_lots(
    blocks, *, max_area=800.0, min_frontage=4.0, jitter=0.25, seeds=None, max_levels=24, report=None, street=False
):
    """Recursive lots after Parish and Müller [13], keeping street access.

    Each piece larger than ``max_area`` is cut perpendicular to its longest
    edge, at the middle of its extent along that edge moved by up to
    ``jitter`` of the extent.  If a part of the cut would have less than
    ``min_frontage`` of block boundary, the cut perpendicular to the
    piece's longest street-facing edge is tried, then the one perpendicular
    to the main axis of a small enclosing rectangle, then the street-facing
    one again at the exact middle; if all fail the piece stays whole (it
    may then be larger than ``max_area``), as it does after ``max_levels``
    levels.

    Parameters
    ----------
    blocks : array_like of shapely.Polygon (n,)
        MultiPolygons are cut part by part.
    max_area : float or array_like
        Stop splitting under this area (m2).
    min_frontage : float or array_like
        Street frontage every part must keep (m).
    jitter : float
        Cut position spread, as a fraction of the extent (0 = exact middle).
    seeds : array_like of uint64 (n,), optional
        One seed per block (from the block's generator); 0 when omitted.
    max_levels : int
        Recursion depth cap.
    report : dict, optional
        Receives ``max_recursive_levels`` (levels run), ``recursive_stuck``
        (pieces over ``max_area`` that no cut could split) and
        ``recursive_failed_cuts`` (cuts dropped because their crossings
        could not be paired exactly; another cut is tried).
    street : bool
        Also return which boundary segment of each lot lies on its block's
        boundary (exact: carried through the cuts).

    Returns
    -------
    lots : ndarray of shapely.Polygon
    owner : ndarray of int64
        Index into ``blocks`` of each lot's block, non-decreasing.
    on : ndarray of bool, only with ``street``
        One per boundary segment of the lots, in the order of
        :func:`sengine.geom.boundary.ring_segments`.
    """
    blocks = np.asarray(blocks, dtype=object).ravel()
    n = len(blocks)
    if n == 0:
        return (np.empty(0, object), np.empty(0, np.int64)) + ((np.zeros(0, bool),) if street else ())
    seeds = np.zeros(n, np.uint64) if seeds is None else np.asarray(seeds, np.uint64)
    max_area = np.broadcast_to(np.asarray(max_area, np.float64), (n,))
    min_frontage = np.broadcast_to(np.asarray(min_frontage, np.float64), (n,))
    parts, own = polygon_parts(blocks, np.arange(n))
    rs = RingSet.from_polygons(parts, flag=True)  # every block edge faces a street
    key = np.ones(rs.n, np.uint64)
    done_rs, done_o = [], []
    stuck_count = failed_count = levels = 0
    for _level in range(max_levels):
        todo = rs.areas() > max_area[own]
        # every part of a cut needs min_frontage: less than twice that in all and no cut can do
        hopeless = todo & (rs.flagged_length() < 2.0 * min_frontage[own])
        stuck_count += int(hopeless.sum())
        todo &= ~hopeless
        done_rs.append(rs.take(~todo))
        done_o.append(own[~todo])
        rs, own, key = rs.take(todo), own[todo], key[todo]
        if rs.n == 0:
            break
        levels += 1
        pieces, par, side, stuck, nfail = _cut_level(rs, own, key, seeds, min_frontage, jitter)
        failed_count += nfail
        stuck_count += int(stuck.sum())
        done_rs.append(rs.take(stuck))
        done_o.append(own[stuck])
        rs, own, key = pieces, own[par], key[par] * np.uint64(2) + side.astype(np.uint64)
    done_rs.append(rs)
    done_o.append(own)
    if report is not None:
        report["max_recursive_levels"] = max(report.get("max_recursive_levels", 0), levels)
        report["recursive_stuck"] = report.get("recursive_stuck", 0) + stuck_count
        report["recursive_failed_cuts"] = report.get("recursive_failed_cuts", 0) + failed_count
    done = RingSet.concat(done_rs)
    owner = np.concatenate(done_o).astype(np.int64)
    keep = np.flatnonzero(np.bincount(done.poly, minlength=done.n) > 0)  # drop empty pieces
    o = keep[np.argsort(owner[keep], kind="stable")]
    done = done.permuted(o)
    lots = done.polygons()
    return (lots, owner[o]) + ((done.flag.copy(),) if street else ())

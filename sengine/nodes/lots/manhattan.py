"""Manhattan lots (skylineEngine §5.5, Fig. 9 right).

A simplification of Aliaga et al. [2]_: the block is split lengthwise along
the main axis of its oriented bounding box into two rows that meet back to
back, and each row into ``count`` lots (or lots about ``width`` m wide).
A block deeper than four times the target ``depth`` gets a row of that
depth along each long side and, between them, inner rows about that deep
(the land behind the street rows, cut by the same columns).  All blocks
are cut in one vectorized call: each (block, lot box) pair is mapped onto
the unit square and clipped there
(:func:`sengine.geom.polygons.clip_frame_boxes`); clipped slivers under
``min_area`` join a neighbouring lot of their block
(:func:`sengine.geom.merge.merge_small`).

References
----------
.. [1] J. Martí, A. Puig, G. Patow et al., "skylineEngine: an urban
   procedural modelling tool", §5.5 (lots), Fig. 9.
.. [2] D. G. Aliaga, C. A. Vanegas and B. Beneš, "Interactive example-based
   urban layout synthesis", ACM Transactions on Graphics 27(5), 160
   (SIGGRAPH Asia 2008). doi:10.1145/1409060.1409113
"""

from __future__ import annotations

import numpy as np

from sengine.geom.boundary import polygon_parts, segments_on_boundary
from sengine.geom.merge import merge_small
from sengine.geom.polygons import clip_frame_boxes, obb_frame

__all__ = ["manhattan_lots", "manhattan_rows"]


def manhattan_rows(W, *, min_depth, depth):
    """Rows across blocks ``W`` deep (m): count, and which are inner.

    One row when ``W < 2 * min_depth``; two (back to back, ``W / 2`` deep)
    up to ``W = 4 * depth``; beyond, a row ``depth`` deep along each long
    side and ``floor((W - 2 depth) / depth)`` inner rows between them (each
    ``depth`` to ``2 * depth`` deep).

    Returns
    -------
    rows : ndarray of int64
    inner_rows : ndarray of int64
    """
    W = np.asarray(W, np.float64)
    two = W >= 2.0 * min_depth
    deep = two & (W > 4.0 * depth)
    inner = np.where(deep, np.floor((W - 2.0 * depth) / np.maximum(depth, 1e-9)), 0).astype(np.int64)
    return np.where(two, 2 + inner, 1).astype(np.int64), inner


def manhattan_lots(blocks, *, count=0, width=65.0, min_depth=10.0, depth=30.0, min_area=0.0, report=None):
    """Manhattan lots: two rows along the block's main axis (§5.5, Fig. 9 right).

    Parameters
    ----------
    blocks : array_like of shapely.Polygon (n,)
    count : int or array_like of int
        Lots per row; ``0`` derives it from ``width``.
    width : float or array_like of float
        Target lot width along the main axis (m), used when ``count`` is 0.
        The default 65 m gives 4 lots per side of a 270 m long block, i.e.
        about 8 lots per 80 m x 270 m block as in the paper's Manhattan run
        (931 blocks -> 7,471 lots); lots are then ~65 m x ~40 m.
    min_depth : float or array_like of float
        A block narrower than ``2 * min_depth`` (m) gets a single row.
    depth : float or array_like of float
        Target lot depth (m): a block deeper than ``4 * depth`` gets street
        rows of this depth and inner rows between them
        (:func:`manhattan_rows`).
    min_area : float or array_like of float
        Clipped pieces under this area (m2) join the neighbouring lot of
        their block with which they share the longest boundary.
    report : dict, optional
        Receives ``merged_slivers`` (pieces merged into a neighbour) and
        ``inner_rows`` (inner rows made).

    Returns
    -------
    lots : ndarray of shapely.Polygon
    owner : ndarray of int64
        Index into ``blocks`` of each lot's block.
    inner : ndarray of bool
        Lots of an inner row that do not reach the street.
    """
    blocks = np.asarray(blocks, dtype=object).ravel()
    n = len(blocks)
    if n == 0:
        return np.empty(0, object), np.empty(0, np.int64), np.zeros(0, bool)
    center, axis, L, W = obb_frame(blocks)
    count = np.broadcast_to(np.asarray(count, np.int64), (n,))
    width = np.broadcast_to(np.asarray(width, np.float64), (n,))
    min_depth = np.broadcast_to(np.asarray(min_depth, np.float64), (n,))
    depth = np.broadcast_to(np.asarray(depth, np.float64), (n,))
    per = np.where(count > 0, count, np.maximum(1, np.floor(L / np.maximum(width, 1e-9) + 0.5))).astype(np.int64)
    rows, inner_rows = manhattan_rows(W, min_depth=min_depth, depth=depth)
    nbox = per * rows
    own = np.repeat(np.arange(n), nbox)
    start = np.repeat(np.cumsum(nbox) - nbox, nbox)
    j = np.arange(len(own)) - start
    col = j % per[own]
    row = j // per[own]
    margin = 1.0 + 0.01 * (L + W)
    Lo, Wo, Po, Mo, Ro, Do = L[own], W[own], per[own], margin[own], rows[own], depth[own]
    a0 = -Lo / 2 + col * Lo / Po
    a1 = -Lo / 2 + (col + 1) * Lo / Po
    a0 = np.where(col == 0, a0 - Mo, a0)
    a1 = np.where(col == Po - 1, a1 + Mo, a1)
    # row edges across the block: the street rows, then the inner ones sharing what is left
    deep = Ro > 2
    h = np.where(deep, (Wo - 2 * Do) / np.maximum(Ro - 2, 1), Wo / np.maximum(Ro, 1))
    lo_edge = np.where(deep, -Wo / 2 + Do + (row - 1) * h, -Wo / 2 + row * h)
    hi_edge = lo_edge + h
    lo_edge = np.where(deep & (row == 0), -Wo / 2, lo_edge)
    hi_edge = np.where(deep & (row == 0), -Wo / 2 + Do, hi_edge)
    hi_edge = np.where(deep & (row == Ro - 1), Wo / 2, hi_edge)
    lo_edge = np.where(deep & (row == Ro - 1), Wo / 2 - Do, lo_edge)
    b0 = np.where(row == 0, -Wo / 2 - Mo, lo_edge)
    b1 = np.where(row == Ro - 1, Wo / 2 + Mo, hi_edge)
    pieces = clip_frame_boxes(blocks[own], center[own], axis[own], a0, a1, b0, b1)
    lots, idx = polygon_parts(pieces, np.arange(len(pieces)))
    owner, inner = own[idx], (deep & (row > 0) & (row < Ro - 1))[idx]
    lots, keep, merged = merge_small(lots, owner, np.broadcast_to(np.asarray(min_area, np.float64), (n,))[owner])
    owner, inner = owner[keep], inner[keep]
    if inner.any():  # a lot of an inner row is inner unless it reaches the street (at the block's ends)
        sub = np.flatnonzero(inner)
        _, _, si, _, on = segments_on_boundary(lots[sub], owner[sub], blocks, tol=1e-5)
        inner[sub[np.bincount(si[on], minlength=len(sub)) > 0]] = False
    if report is not None:
        report["merged_slivers"] = report.get("merged_slivers", 0) + merged
        report["inner_rows"] = report.get("inner_rows", 0) + int(inner_rows.sum())
    return lots, owner, inner

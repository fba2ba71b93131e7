"""Manhattan lots (skylineEngine §5.5, Fig. 9 right).

A simplification of Aliaga et al. [2]_: the block is split lengthwise along
the main axis of its oriented bounding box into two rows that meet back to
back, and each row into ``count`` lots (or lots about ``width`` m wide).
A block deeper than four times the target ``depth`` gets a row of that
depth along each long side, and the land between them (behind the street
rows) is cut into inner lots about as long as it is deep.  All blocks are
cut together (:func:`sengine.geom.grid.clip_frame_grid`: only the cells on
a block's outline are clipped); clipped slivers under ``min_area`` join a
neighbouring lot of their block (:func:`sengine.geom.merge.merge_small`).

References
----------
.. [1] "skylineEngine: an urban procedural modelling tool" (University of
   Girona; paper 002 of the project), §5.5 Lots, Fig. 9.
.. [2] D. G. Aliaga, C. A. Vanegas and B. Beneš, "Interactive example-based
   urban layout synthesis", ACM Transactions on Graphics 27(5), 160
   (SIGGRAPH Asia 2008). doi:10.1145/1409060.1409113
"""

from __future__ import annotations

import numpy as np
import shapely

from sengine.geom.boundary import polygon_parts, segments_on_boundary, segments_on_box, segments_on_lines
from sengine.geom.grid import clip_frame_grid
from sengine.geom.merge import merge_small
from sengine.geom.polygons import obb_frame

__all__ = ["manhattan_lots", "manhattan_rows"]

ON_TOL = 1e-5  # m: a lot's segment within this of its block's boundary lies on it (frontage is measured so)


def touches_along(lots, owner, blocks, *, fronts=None, box=None) -> np.ndarray:
    """Per lot: some segment of its boundary, longer than a nanometre, lies on its block's street.

    The frontage rule of :func:`sengine.nodes.lots.nodes.lot_attributes` (segments within
    :data:`ON_TOL`, zero-length ones left out): a lot that meets the outline at a point only
    (where a clip left a vertex doubled a hair apart) has no frontage and is inner.  The
    block's street is its boundary less what lies on ``box`` (the extract's edge) and off
    its ``fronts`` (per block, its street-facing boundary or ``None``: all of it; indexed
    like ``blocks``): a lot on open land only has no frontage either.
    """
    return street_segments(lots, owner, blocks, fronts=fronts, box=box)[1] > 0


def street_segments(lots, owner, blocks, *, fronts=None, box=None):
    """Per boundary segment of each lot: whether it lies on its block's street (see :func:`touches_along`).

    Returns ``on`` (the raw flag, within :data:`ON_TOL` of the block's boundary, in the order of
    :func:`sengine.geom.boundary.ring_segments`: what :func:`sengine.nodes.lots.nodes.lot_attributes`
    takes as known flags) and ``frontage`` (m per lot: the street segments' length, zero-length
    ones, those on ``box`` and those off ``fronts`` left out).
    """
    p0, p1, si, _, on = segments_on_boundary(lots, owner, blocks, tol=ON_TOL)
    ln = np.hypot(*(p1 - p0).T)
    street = on & (ln > 1e-9)
    if box is not None:
        street &= ~segments_on_box(p0, p1, box)
    if fronts is not None and street.any():
        sel = np.flatnonzero(street)
        lines = np.asarray(fronts, dtype=object)[np.asarray(owner, np.int64)[si[sel]]]
        street[sel] = segments_on_lines(p0[sel], p1[sel], lines)
    return on, np.bincount(si[street], weights=ln[street], minlength=len(lots))


def _ramp(counts) -> np.ndarray:
    """0, 1, ..., c - 1 for each count, concatenated."""
    counts = np.asarray(counts, np.int64)
    return np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)


def manhattan_rows(W, *, min_depth, depth) -> np.ndarray:
    """Rows across blocks ``W`` deep (m).

    ``1`` when ``W < 2 * min_depth``; ``2`` (back to back, ``W / 2`` deep
    each) up to ``W = 4 * depth``; ``3`` beyond: a street row ``depth`` deep
    along each long side and the inner land between them.
    """
    W = np.asarray(W, np.float64)
    two = W >= 2.0 * min_depth
    return np.where(two, np.where(W > 4.0 * depth, 3, 2), 1).astype(np.int64)


def _polygons(cells):
    """Polygon parts of positive area of the cells, and the cell of each (only non-Polygons exploded)."""
    cells = np.asarray(cells, dtype=object)
    poly = shapely.get_type_id(cells) == 3
    if poly.all():
        idx = np.flatnonzero(shapely.area(cells) > 0)
        return cells[idx], idx
    keep = np.flatnonzero(poly & (shapely.area(cells) > 0))
    other = np.flatnonzero(~poly)
    parts, pidx = polygon_parts(cells[other], other)
    idx = np.r_[keep, pidx]
    o = np.argsort(idx, kind="stable")
    return np.r_[cells[keep], parts][o], idx[o]


def _inner_land(blocks, center, axis, L, W, per, depth):
    """The land between the street rows of deep blocks: street lots at its ends, compact inner lots between.

    The band between the two street rows (``W - 2 depth`` deep) is cut by
    the first and last columns of the rows: those ends face the block's
    short sides and are cut, across, into lots about a column wide; the
    middle is cut into inner pieces about as long as the band is deep.

    Returns cells, their block (index into the arguments), and their
    ``inside``, ``whole`` and ``inner`` flags (as :func:`clip_frame_grid`).
    """
    n = len(blocks)
    Wi = W - 2 * depth
    col = L / per
    ends = 1.0 + 0.01 * (L + W)  # past the outline at the block's ends; the band's long sides stay put
    mid_len = np.maximum(L - 2 * col, 0.0)
    has_mid = per >= 3
    m = np.where(has_mid, np.maximum(1, np.floor(mid_len / np.maximum(Wi, 1e-9) + 0.5)), 0).astype(np.int64)
    # grids: for each block its end columns (one or two) and its middle (if any)
    nend = np.where(per == 1, 1, 2)
    g_blk = np.r_[np.repeat(np.arange(n), nend), np.flatnonzero(has_mid)]
    g_kind = np.r_[_end_kind(nend), np.full(int(has_mid.sum()), 2)]
    x0 = np.where(
        g_kind == 0,
        -L[g_blk] / 2 - ends[g_blk],
        np.where(g_kind == 1, L[g_blk] / 2 - col[g_blk], -L[g_blk] / 2 + col[g_blk]),
    )
    x1 = np.where(
        g_kind == 0,
        -L[g_blk] / 2 + col[g_blk],
        np.where(g_kind == 1, L[g_blk] / 2 + ends[g_blk], L[g_blk] / 2 - col[g_blk]),
    )
    single = (g_kind == 0) & (per[g_blk] == 1)
    x1 = np.where(single, L[g_blk] / 2 + ends[g_blk], x1)
    x1 = np.where((g_kind == 0) & (per[g_blk] == 2), 0.0, x1)
    x0 = np.where((g_kind == 1) & (per[g_blk] == 2), 0.0, x0)
    nx = np.where(g_kind == 2, m[g_blk], 1)
    ny = np.where(g_kind == 2, 1, np.maximum(1, np.floor(Wi[g_blk] / np.maximum(col[g_blk], 1e-9) + 0.5))).astype(
        np.int64
    )
    kx, ox = _ramp(nx + 1), np.repeat(np.arange(len(g_blk)), nx + 1)
    xs = x0[ox] + kx * (x1 - x0)[ox] / nx[ox]
    ky, oy = _ramp(ny + 1), np.repeat(np.arange(len(g_blk)), ny + 1)
    ys = -Wi[g_blk][oy] / 2 + ky * Wi[g_blk][oy] / ny[oy]
    cells, g, _, _, inside, whole = clip_frame_grid(
        blocks[g_blk], center[g_blk], axis[g_blk], xs, nx, ys, ny, margin=0.0, clearance=ON_TOL
    )
    return cells, g_blk[g], inside, whole, g_kind[g] == 2


def _end_kind(nend):
    """0 (first end) and 1 (last end) for each end column, blocks in turn."""
    return np.where(_ramp(nend) == 0, 0, 1)


def manhattan_lots(
    blocks, *, count=0, width=65.0, min_depth=10.0, depth=30.0, min_area=0.0, report=None, fronts=None, box=None
):
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
        rows of this depth and inner lots between them
        (:func:`manhattan_rows`).
    min_area : float or array_like of float
        Clipped pieces under this area (m2) join the neighbouring lot of
        their block with which they share the longest boundary.
    report : dict, optional
        Receives ``merged_slivers`` (pieces merged into a neighbour),
        ``dropped_slivers`` (pieces under 1 m2 touching their neighbours at
        points only, dropped) and ``inner_blocks`` (blocks with inner land).
    fronts : array_like of object (n,), optional
        Per block, the part of its boundary that faces a street (a
        (Multi)LineString, e.g. ``blocks.landuse``'s ``street_front``), or
        ``None``: all of it.
    box : tuple of float, optional
        ``(xmin, ymin, xmax, ymax)``: block boundary on this box (the
        extract's edge) is no street.  With ``fronts`` or ``box`` every lot
        that touches no street (only open land or the box) is inner.

    Returns
    -------
    lots : ndarray of shapely.Polygon
    owner : ndarray of int64
        Index into ``blocks`` of each lot's block.
    inner : ndarray of bool
        Lots of the inner land that do not reach the street.
    off_street : ndarray of bool
        Lots known to touch no street: their whole rectangle, inside the
        block (the others' frontage is to be measured).
    """
    blocks = np.asarray(blocks, dtype=object).ravel()
    n = len(blocks)
    if n == 0:
        return np.empty(0, object), np.empty(0, np.int64), np.zeros(0, bool), np.zeros(0, bool)
    center, axis, L, W = obb_frame(blocks)
    count = np.broadcast_to(np.asarray(count, np.int64), (n,))
    width = np.broadcast_to(np.asarray(width, np.float64), (n,))
    min_depth = np.broadcast_to(np.asarray(min_depth, np.float64), (n,))
    depth = np.broadcast_to(np.asarray(depth, np.float64), (n,))
    per = np.where(count > 0, count, np.maximum(1, np.floor(L / np.maximum(width, 1e-9) + 0.5))).astype(np.int64)
    rows = manhattan_rows(W, min_depth=min_depth, depth=depth)
    # column edges along the main axis, row edges across it (block frame, from the box's centre)
    own_x = np.repeat(np.arange(n), per + 1)
    k = _ramp(per + 1)
    xs = -L[own_x] / 2 + k * L[own_x] / per[own_x]
    own_y = np.repeat(np.arange(n), rows + 1)
    r = _ramp(rows + 1)
    Wy, Dy, Ry = W[own_y], depth[own_y], rows[own_y]
    ys = np.where(Ry == 3, np.select([r == 1, r == 2], [-Wy / 2 + Dy, Wy / 2 - Dy], 0.0), -Wy / 2 + r * Wy / Ry)
    ys = np.where(r == 0, -Wy / 2, np.where(r == Ry, Wy / 2, ys))
    cells, owner, _, row, inside, whole = clip_frame_grid(blocks, center, axis, xs, per, ys, rows, clearance=ON_TOL)
    street = (rows[owner] < 3) | (row != 1)  # the middle row of a deep block is cut again below
    cells, owner, inside, whole = cells[street], owner[street], inside[street], whole[street]
    inner = np.zeros(len(cells), bool)
    deep = np.flatnonzero(rows == 3)
    if len(deep):
        c2, o2, in2, wh2, inner2 = _inner_land(
            blocks[deep], center[deep], axis[deep], L[deep], W[deep], per[deep], depth[deep]
        )
        cells = np.r_[cells, c2]
        owner = np.r_[owner, deep[o2]]
        inside, whole = np.r_[inside, in2], np.r_[whole, wh2]
        inner = np.r_[inner, inner2]
        o = np.argsort(owner, kind="stable")
        cells, owner, inside, whole, inner = cells[o], owner[o], inside[o], whole[o], inner[o]
    lots, idx = _polygons(cells)
    owner, inner, inside, whole = owner[idx], inner[idx], inside[idx], whole[idx]
    lots, keep, grown, merged, dropped = merge_small(
        lots, owner, np.broadcast_to(np.asarray(min_area, np.float64), (n,))[owner]
    )
    owner, inner, inside, whole = owner[keep], inner[keep], inside[keep] & ~grown, whole[keep] & ~grown
    # an inner lot is inner unless it reaches the street (at the block's ends): a whole rectangle
    # inside the block does not, a clipped one does; a whole one on the outline is measured
    inner &= inside | whole
    sub = np.flatnonzero(inner & ~inside)
    if len(sub):
        inner[sub[touches_along(lots[sub], owner[sub], blocks)]] = False
    if fronts is not None or box is not None:  # a street row on open land only: inner (rear) land
        edge = np.flatnonzero(~inside)
        inner = inside.copy()
        inner[edge] = ~touches_along(lots[edge], owner[edge], blocks, fronts=fronts, box=box)
    if report is not None:
        report["merged_slivers"] = report.get("merged_slivers", 0) + merged
        report["dropped_slivers"] = report.get("dropped_slivers", 0) + dropped
        report["inner_blocks"] = report.get("inner_blocks", 0) + len(deep)
    return lots, owner, inner, inside

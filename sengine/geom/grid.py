"""Polygons cut into grids of rectangular cells given in their own frames.

:func:`sengine.geom.polygons.clip_frame_boxes` clips a polygon once per box,
so a polygon of ``V`` vertices cut into ``nx * ny`` cells costs
``V * nx * ny``: ruinous for a large block cut into thousands of lots.
:func:`clip_frame_grid` makes the cells that lie wholly inside their polygon
as plain rectangles (one prepared-geometry test each), drops those wholly
outside, and clips only the cells on the outline: about ``V * (nx + ny)``.
"""

from __future__ import annotations

import numpy as np
import shapely

from .polygons import clip_frame_boxes

__all__ = ["clip_frame_grid"]


def _ramp(counts) -> np.ndarray:
    counts = np.asarray(counts, np.int64)
    return np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)


def clip_frame_grid(geoms, center, axis, xs, nx, ys, ny, *, margin=None, clearance=0.0):
    """Each geometry cut into the cells of its own grid (vectorized; only the outline's cells clipped).

    Parameters
    ----------
    geoms : array_like of shapely.Geometry (n,)
    center, axis : array_like (n, 2)
        Each geometry's frame, as for :func:`sengine.geom.polygons.frame_boxes`
        (``x`` along ``axis``, ``y`` along its left normal, from ``center``).
    xs, ys : array_like
        Cell edges of every geometry in turn along ``x`` and ``y`` (m, in
        the frame), ``nx[i] + 1`` and ``ny[i] + 1`` of them for geometry ``i``.
    nx, ny : array_like of int (n,)
        Columns and rows of each grid.
    margin : array_like (n,), optional
        The outer cells reach this far past the first and last edges, so
        that the grid covers the geometry (m; default 1 m plus 1 % of the
        grid's size).
    clearance : float
        An ``inside`` cell stands farther than this (m) from every ring; a
        cell nearer (or touching) is clipped like the outline's.  Give the
        tolerance under which a caller takes a segment to lie on a ring, so
        that an ``inside`` cell is one that tolerance finds on no ring (a
        cell a hair inside a courtyard's edge is then no inner lot).

    Returns
    -------
    cells : ndarray of shapely.Geometry
        The non-empty cells (any type a clip gives: Polygon, MultiPolygon
        ...), geometry by geometry, column by column.
    owner, ix, iy : ndarray of int64
        Geometry, column and row of each cell.
    inside : ndarray of bool
        Cells that are their whole rectangle, inside the geometry's
        interior (they touch none of its rings, nor come within ``clearance``).  Every other cell has part
        of the geometry's boundary on its own, unless ``whole``.
    whole : ndarray of bool
        Cells that are their whole rectangle (``inside`` ones, and outline
        cells the clip left whole: they may touch a ring at a point or
        along an edge).
    """
    geoms = np.asarray(geoms, dtype=object).ravel()
    n = len(geoms)
    e64 = np.zeros(0, np.int64)
    if n == 0:
        return np.empty(0, object), e64, e64, e64, np.zeros(0, bool), np.zeros(0, bool)
    center = np.asarray(center, np.float64).reshape(-1, 2)
    axis = np.asarray(axis, np.float64).reshape(-1, 2)
    xs, ys = np.asarray(xs, np.float64), np.asarray(ys, np.float64)
    nx, ny = np.asarray(nx, np.int64), np.asarray(ny, np.int64)
    xstart = np.cumsum(nx + 1) - (nx + 1)
    ystart = np.cumsum(ny + 1) - (ny + 1)
    x_lo, x_hi = xs[xstart], xs[xstart + nx]
    y_lo, y_hi = ys[ystart], ys[ystart + ny]
    if margin is None:
        margin = 1.0 + 0.01 * ((x_hi - x_lo) + (y_hi - y_lo))
    margin = np.broadcast_to(np.asarray(margin, np.float64), (n,))
    own = np.repeat(np.arange(n), nx * ny)
    j = _ramp(nx * ny)
    ix, iy = j // ny[own], j % ny[own]  # column by column
    a0 = np.where(ix == 0, x_lo[own] - margin[own], xs[xstart[own] + ix])
    a1 = np.where(ix == nx[own] - 1, x_hi[own] + margin[own], xs[xstart[own] + ix + 1])
    b0 = np.where(iy == 0, y_lo[own] - margin[own], ys[ystart[own] + iy])
    b1 = np.where(iy == ny[own] - 1, y_hi[own] + margin[own], ys[ystart[own] + iy + 1])
    boxes = _boxes(center[own], axis[own], a0, a1, b0, b1)
    fresh = geoms[~shapely.is_prepared(geoms)]  # the caller's own preparations stay as they are
    shapely.prepare(fresh)
    try:
        c = float(clearance)
        inside = shapely.contains_properly(geoms[own], boxes)
        edge = np.zeros(len(own), bool)
        if c > 0:  # a box the geometry holds, grown by the clearance (only those: a grown box held is held too)
            s = np.flatnonzero(inside)
            grown = _boxes(center[own[s]], axis[own[s]], a0[s] - c, a1[s] + c, b0[s] - c, b1[s] + c)
            inside[s] = shapely.contains_properly(geoms[own[s]], grown)
            edge[s] = ~inside[s]  # held, but too near a ring: on the outline's side
        rest = np.flatnonzero(~inside & ~edge)
        edge[rest] = shapely.intersects(geoms[own[rest]], boxes[rest])
    finally:
        shapely.destroy_prepared(fresh)
    cells = np.where(inside, boxes, None)
    e = np.flatnonzero(edge)
    # outline cells: the geometry clipped to each column holding one, then that column to the cell
    col = own[e] * (int(nx.max()) + 1) + ix[e]
    ucol, first, back = np.unique(col, return_index=True, return_inverse=True)
    f = e[first]
    strips = clip_frame_boxes(
        geoms[own[f]],
        center[own[f]],
        axis[own[f]],
        a0[f],
        a1[f],
        y_lo[own[f]] - margin[own[f]],
        y_hi[own[f]] + margin[own[f]],
    )
    cells[e] = clip_frame_boxes(strips[back], center[own[e]], axis[own[e]], a0[e], a1[e], b0[e], b1[e])
    live = inside | edge
    live[e] &= ~shapely.is_empty(cells[e])
    whole = inside.copy()  # an outline cell the clip left whole (it touches the outline at most)
    whole[e] = shapely.area(cells[e]) >= (1.0 - 1e-9) * (a1[e] - a0[e]) * (b1[e] - b0[e])
    # GEOS's rectangle clip gives the whole rectangle back when it lies in a hole whose ring it only
    # touches: a whole outline cell whose centre is off the geometry is such a cell, and no lot
    w = e[whole[e]]
    if len(w):
        mid = np.stack([(a0[w] + a1[w]) / 2, (b0[w] + b1[w]) / 2], axis=1)
        xy = center[own[w]] + mid[:, :1] * axis[own[w]] + mid[:, 1:] * np.stack([-axis[own[w], 1], axis[own[w], 0]], 1)
        off = ~shapely.intersects_xy(geoms[own[w]], xy[:, 0], xy[:, 1])
        live[w[off]] = False
    return cells[live], own[live], ix[live], iy[live], inside[live], whole[live]


def _boxes(center, axis, a0, a1, b0, b1):
    """:func:`sengine.geom.polygons.frame_boxes`, built through shapely's ragged-array path (faster)."""
    k = len(a0)
    nrm = np.stack([-axis[:, 1], axis[:, 0]], axis=1)
    a = np.stack([a0, a1, a1, a0, a0], axis=1)[:, :, None]
    b = np.stack([b0, b0, b1, b1, b0], axis=1)[:, :, None]
    xy = (center[:, None, :] + a * axis[:, None, :] + b * nrm[:, None, :]).reshape(-1, 2)
    offsets = (np.arange(k + 1) * 5, np.arange(k + 1))
    return shapely.from_ragged_array(shapely.GeometryType.POLYGON, xy, offsets)

"""Partition lots: a block split into a regular grid of lots (Zhang et al. 2022, §3.3.1 [1]_).

The block's frame is its minimum-area oriented bounding box: ``x`` along the
long side, ``y`` across, the index starting at the corner of smallest ``x``
and ``y``.  Three splits, as in [1]_ (Fig. 3D-F):

* ``size`` -- lots of an absolute size ``size = "sx sy"`` (m) from that
  corner; the parts left at the far edges keep whatever size is left and are
  flagged ``remainder`` (so are lots the block's outline cuts short), but a
  leftover strip more elongated than 1:``max_aspect`` joins the column or
  row before it (those lots are remainders too);
* ``count`` -- ``count = "nx ny"`` equal parts;
* ``ratio`` -- a repeating pattern of widths in the proportions ``ratio``
  (e.g. ``"1 2"``) along ``x``, one repeat about ``size[0]`` long, stretched
  so whole repeats fill the block; rows about ``size[1]`` deep, stretched.

Every lot gets its grid index (columns ``ix``, ``iy``).  Lots can then be
clustered: ``cluster = "cx cy"`` groups ``cx`` by ``cy`` neighbouring cells
(at most 4) into one lot, indexed by the cluster.  All blocks are cut in one
pass, columns then rows (:func:`sengine.geom.grid.clip_frame_grid`), a
cluster being clipped as its own rectangle; pieces under ``min_area`` (slivers where
a grid line grazes the outline) join a neighbouring lot of their block.

References
----------
.. [1] M. Zhang, J. Wu, Y. Liu, J. Zhang and G. Li, "GIS based procedural
   modeling in 3D urban design", ISPRS International Journal of
   Geo-Information 11(10), 531, 2022. doi:10.3390/ijgi11100531
"""

from __future__ import annotations

import numpy as np
import shapely

from sengine import Layer, NodeResult, Param, register
from sengine.errors import ParameterError
from sengine.geom.grid import clip_frame_grid
from sengine.geom.merge import merge_small
from sengine.geom.polygons import obb_frame

from .contour import Marks
from .faces import _merge_into
from .manhattan import ON_TOL, _polygons, street_segments
from .nodes import _Lots
from .recursive import REAL_BLOCK
from .vocabulary import LotSplit

__all__ = ["grid_edges", "merge_narrow", "partition_lots", "partition_index", "check_partition", "LotsPartition"]

MODES = ("size", "count", "ratio")


def _ramp(counts) -> np.ndarray:
    """0, 1, ..., c - 1 for each count, concatenated."""
    counts = np.asarray(counts, np.int64)
    return np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)


def grid_edges(length, *, mode, size, count=1, ratio=(1.0,), cluster=1, min_last=0.0):
    """Cell edges along one axis of many blocks, as one flat array.

    Parameters
    ----------
    length : array_like (n,)
        Extent of each block's box along the axis (m).
    mode : {"size", "count", "ratio"}
        ``size``: cells ``size`` m long from 0, the last one short;
        ``count``: ``count`` equal cells; ``ratio``: whole repeats of the
        proportions ``ratio`` (one repeat about ``size`` m), stretched to fit.
    size : float
        Cell length or pattern period (m).
    count : int
    ratio : sequence of float
    cluster : int
        Keep every ``cluster``-th edge (and the last): cells of clusters.
    min_last : float
        ``size``: a last (leftover) cell shorter than this (m) joins the
        cell before it.

    Returns
    -------
    edges : ndarray
        Each block's edges in turn, increasing from 0 to its length (m).
    cells : ndarray of int64 (n,)
        Cells (clusters) of each block; block ``i`` has ``cells[i] + 1`` edges.
    """
    length = np.maximum(np.asarray(length, np.float64).ravel(), 0.0)
    n = len(length)
    if mode == "size":
        ncell = np.maximum(1, np.ceil(length / size - 1e-9)).astype(np.int64)
        ncell -= (ncell >= 2) & (length - (ncell - 1) * size < min_last)  # a thin leftover joins its neighbour
    elif mode == "count":
        ncell = np.full(n, int(count), np.int64)
    else:
        r = np.asarray(ratio, np.float64)
        reps = np.maximum(1, np.floor(length / size + 0.5)).astype(np.int64)
        ncell = reps * len(r)
    k = _ramp(ncell + 1)  # edge number within its block
    own = np.repeat(np.arange(n), ncell + 1)
    if mode == "size":
        edges = np.where(k == ncell[own], length[own], np.minimum(k * float(size), length[own]))
    elif mode == "count":
        edges = k / ncell[own] * length[own]
    else:
        c = np.r_[0.0, np.cumsum(r)]
        m = len(r)
        edges = ((k // m) * c[-1] + c[k % m]) / (reps[own] * c[-1]) * length[own]
    keep = (k % int(cluster) == 0) | (k == ncell[own])
    return edges[keep], np.bincount(own[keep], minlength=n) - 1


def _grid(L, W, *, mode, size, count, ratio, cluster, max_aspect=0.0):
    """Cluster edges along (x) and across (y) every block: (xs, nx, ys, ny).

    ``size``: a leftover column (row) narrower than a lot's depth (width)
    over ``max_aspect`` joins the one before it (``0``: none does).
    """
    if mode == "ratio":  # rows across: about size[1] deep, stretched
        ny0 = np.maximum(1, np.floor(W / size[1] + 0.5)).astype(np.int64)
        xs, nx = grid_edges(L, mode="ratio", size=size[0], ratio=ratio, cluster=cluster[0])
        ys, ny = _count_edges(W, ny0, cluster[1])
    else:
        fold = (size[1] / max_aspect, size[0] / max_aspect) if max_aspect > 0 else (0.0, 0.0)
        xs, nx = grid_edges(L, mode=mode, size=size[0], count=count[0], cluster=cluster[0], min_last=fold[0])
        ys, ny = grid_edges(W, mode=mode, size=size[1], count=count[1], cluster=cluster[1], min_last=fold[1])
    return xs, nx, ys, ny


def _cells(L, W, ix, iy, owner, *, mode, size, count, ratio, cluster, max_aspect=0.0):
    """Grid cells in each cluster ``(ix, iy)`` of block ``owner`` (fewer at the grid's far edges)."""
    _, n0x, _, n0y = _grid(L, W, mode=mode, size=size, count=count, ratio=ratio, cluster=(1, 1), max_aspect=max_aspect)
    cx, cy = (int(c) for c in cluster)
    return (np.minimum(cx, n0x[owner] - ix * cx) * np.minimum(cy, n0y[owner] - iy * cy)).astype(np.int64)


def _count_edges(length, ncell, cluster):
    """Like :func:`grid_edges` in ``count`` mode with a count per block."""
    k = _ramp(ncell + 1)
    own = np.repeat(np.arange(len(length)), ncell + 1)
    edges = k / ncell[own] * length[own]
    keep = (k % int(cluster) == 0) | (k == ncell[own])
    return edges[keep], np.bincount(own[keep], minlength=len(length)) - 1


#: m: a lot whose frontage misses ``lot_width_min`` by less than this (rounding) is not narrow.
WIDTH_TOL = 1e-6


def merge_narrow(lots, owner, blocks, lot_width_min, *, skip=None, fronts=None, box=None, rounds=3):
    """Street lots narrower than ``lot_width_min`` joined to a neighbour, a street-facing one first.

    CityEngine's ``lotWidthMin``: a lot whose street frontage is shorter
    than the minimum width (a grid cell the block's outline cuts at a slant,
    or grazes at a corner) is no buildable street lot, so it joins the
    neighbour of its block with which it shares most boundary, among the
    street-facing neighbours first (the lot beside it along the street),
    else any.  Grown lots are measured again, a few rounds.

    Parameters
    ----------
    lots : ndarray of shapely.Polygon (k,)
    owner : ndarray of int64 (k,)
        Index into ``blocks`` of each lot's block.
    blocks : array_like of shapely.Polygon
    lot_width_min : float
        Least street frontage of a street-facing lot (m); ``0`` merges none.
    skip : ndarray of bool (k,), optional
        Lots known to have no frontage (inside their block): not measured.
    fronts, box : optional
        The street of each block, as for :func:`partition_lots`.
    rounds : int
        Rounds of merging and measuring again.

    Returns
    -------
    lots : ndarray of shapely.Polygon
    keep : ndarray of int64
        Index of each lot left into the input.
    grown : ndarray of bool
        Lots left that took narrow ones.
    frontage : ndarray of float
        Street frontage of each lot left (m; 0 for ``skip`` ones).
    marks : Marks
        Per boundary segment of each lot left, whether it lies on its
        block's boundary (all False on ``skip`` lots).
    merged, left : int
        Narrow lots merged, and still narrow (no neighbour, or no union
        that is one polygon).
    """
    lots = np.asarray(lots, dtype=object)
    owner = np.asarray(owner, np.int64)
    k = len(lots)
    keep, grown, merged = np.arange(k), np.zeros(k, bool), 0
    marks = Marks.unknown(lots)
    front = np.zeros(k)
    look = np.ones(k, bool) if skip is None else ~np.asarray(skip, bool)
    for r in range(rounds + 1):
        idx = np.flatnonzero(look)
        if len(idx):
            on, front[idx] = street_segments(lots[idx], owner[idx], blocks, fronts=fronts, box=box)
            seg = np.repeat(look, marks.counts)
            marks.flat[seg] = on  # a subset's segments come in the same order
        narrow = (front > 0) & (front < lot_width_min - WIDTH_TOL)
        if r == rounds or not narrow.any():
            break
        # only the lots of blocks with a narrow one take part (neighbours are of the same block): the
        # spatial indexes cover those, not the city's
        sub = np.flatnonzero(np.isin(owner, np.unique(owner[narrow])))
        got, live, done, moved = _merge_into(lots[sub], narrow[sub], (front > 0)[sub], owner[sub], rounds=1)
        if done == 0:
            break
        alive = np.ones(len(lots), bool)
        alive[sub] = live
        lots = lots.copy()
        lots[sub[live]] = got
        changed = np.zeros(len(lots), bool)
        changed[sub[live]] = moved
        lots, changed = lots[alive], changed[alive]
        merged += done
        marks = marks.take(np.flatnonzero(alive))
        if changed.any():  # a grown lot has another ring: its marks are measured again
            fresh = Marks.unknown(lots[changed])
            marks = Marks.concat([marks.take(np.flatnonzero(~changed)), fresh])
            order = np.r_[np.flatnonzero(~changed), np.flatnonzero(changed)]
            marks = marks.take(np.argsort(order, kind="stable"))
        keep, owner, front = keep[alive], owner[alive], front[alive]
        grown = grown[alive] | changed
        look = changed
    left = int(((front > 0) & (front < lot_width_min - WIDTH_TOL)).sum())
    return lots, keep, grown, front, marks, merged, left


def partition_lots(
    blocks,
    *,
    mode="size",
    size=(30.0, 40.0),
    count=(4, 2),
    ratio=(1.0,),
    cluster=(1, 1),
    min_area=1.0,
    max_aspect=6.0,
    lot_width_min=0.0,
    report=None,
    fronts=None,
    box=None,
    marks=False,
):
    """Partition lots of each block (Zhang et al. 2022, §3.3.1 [1]_).

    Parameters
    ----------
    blocks : array_like of shapely.Polygon (n,)
    mode : {"size", "count", "ratio"}
        Absolute lot size, number of parts, or repeating ratio.
    size : (float, float)
        ``size``: lot size along and across the block (m); ``ratio``: length
        of one repeat of the pattern and row depth (m).
    count : (int, int)
        ``count``: parts along and across the block.
    ratio : sequence of float
        ``ratio``: proportions of the widths in one repeat.
    cluster : (int, int)
        Cells along and across merged into one lot (product at most 4).
    min_area : float
        Pieces under this area (m2) join a neighbouring lot of their block.
    max_aspect : float
        ``size``: a leftover column (row) at the far edge narrower than the
        lot depth (width) over this joins the column (row) before it, so
        that the grid leaves no strip more elongated than 1:``max_aspect``
        along an edge; ``0`` keeps every leftover as it is.
    lot_width_min : float
        A street-facing lot with less street frontage than this (m) joins a
        neighbour, a street-facing one first (:func:`merge_narrow`,
        CityEngine's ``lotWidthMin``); ``0`` keeps them.
    report : dict, optional
        Receives ``remainders``, ``merged_slivers`` and ``dropped_slivers``
        (pieces under 1 m2 touching their neighbours at points only), and
        with ``lot_width_min`` ``merged_narrow`` and ``narrow_left``.
    fronts : array_like of object (n,), optional
        Per block, the part of its boundary that faces a street (e.g.
        ``blocks.landuse``'s ``street_front``), or ``None``: all of it.
    box : tuple of float, optional
        ``(xmin, ymin, xmax, ymax)``: block boundary on this box (the
        extract's edge) is no street.  Lots touching no street (only open
        land or the box) are inner.

    Returns
    -------
    lots : ndarray of shapely.Polygon
    owner : ndarray of int64
        Index into ``blocks`` of each lot's block, non-decreasing.
    ix, iy : ndarray of int64
        Grid (or cluster) index of each lot.
    remainder : ndarray of bool
        ``size`` mode: lots smaller than a full lot (or cluster).
    cells : ndarray of int64
        Grid cells in each lot's cluster.
    inner : ndarray of bool
        Lots without street frontage (none of their boundary on their block's).
    marks : Marks, only with ``marks=True`` and ``lot_width_min > 0``
        Per boundary segment of each lot, whether it lies on its block's
        boundary (:func:`sengine.geom.boundary.ring_segments` order).
    """
    if mode not in MODES:
        raise ValueError(f"mode={mode!r} is not one of {', '.join(MODES)}")
    blocks = np.asarray(blocks, dtype=object).ravel()
    n = len(blocks)
    e64 = np.empty(0, np.int64)
    if n == 0:
        return np.empty(0, object), e64, e64, e64, np.zeros(0, bool), e64, np.zeros(0, bool)
    cx, cy = (int(c) for c in cluster)
    center, axis, L, W = obb_frame(blocks)
    grid = {"mode": mode, "size": size, "count": count, "ratio": ratio, "cluster": (cx, cy), "max_aspect": max_aspect}
    xs, nx, ys, ny = _grid(L, W, **grid)
    # the grid in the block frame centred on the box (edges from 0 shifted by half the box)
    xs = xs - np.repeat(L / 2, nx + 1)
    ys = ys - np.repeat(W / 2, ny + 1)
    pieces, own, ix, iy, inside, whole = clip_frame_grid(blocks, center, axis, xs, nx, ys, ny, clearance=ON_TOL)
    lots, cell = _polygons(pieces)
    owner, ix, iy, inside, whole = own[cell], ix[cell], iy[cell], inside[cell], whole[cell]
    lots, keep, grown, merged, dropped = merge_small(lots, owner, min_area, cell=(ix, iy))
    owner, ix, iy, inside, whole = owner[keep], ix[keep], iy[keep], inside[keep] & ~grown, whole[keep] & ~grown
    front = flags = None
    if lot_width_min > 0:
        lots, keep, grown, front, flags, narrow, left = merge_narrow(
            lots, owner, blocks, lot_width_min, skip=inside, fronts=fronts, box=box
        )
        owner, ix, iy, inside, whole = owner[keep], ix[keep], iy[keep], inside[keep] & ~grown, whole[keep] & ~grown
        if report is not None:
            report["merged_narrow"] = report.get("merged_narrow", 0) + narrow
            report["narrow_left"] = report.get("narrow_left", 0) + left
    cells = _cells(L, W, ix, iy, owner, **grid)
    area = shapely.area(lots)
    if mode == "size":  # not a whole cluster of whole lots: cut short, or holding a leftover
        full = cx * cy * size[0] * size[1]
        remainder = np.abs(area - full) > 1e-6 * full
    else:
        remainder = np.zeros(len(lots), bool)
    # a lot that is its whole box inside the block (and took no sliver) touches no street; a clipped
    # one does; a whole box on the outline may or may not: measured
    inner = inside.copy()
    street = fronts is not None or box is not None  # then a clipped lot may touch open land only: measured
    check = np.flatnonzero((whole | street) & ~inside)
    if len(check) and front is not None:  # measured by merge_narrow
        inner[check] = ~(front[check] > 0)
    elif len(check):
        inner[check] = ~(street_segments(lots[check], owner[check], blocks, fronts=fronts, box=box)[1] > 0)
    if report is not None:
        report["remainders"] = report.get("remainders", 0) + int(remainder.sum())
        report["merged_slivers"] = report.get("merged_slivers", 0) + merged
        report["dropped_slivers"] = report.get("dropped_slivers", 0) + dropped
    if marks:  # the segment flags merge_narrow measured (None without it)
        return lots, owner, ix, iy, remainder, cells, inner, flags
    return lots, owner, ix, iy, remainder, cells, inner


def partition_index(
    lots, owner, blocks, *, mode="size", size=(30.0, 40.0), count=(4, 2), ratio=(1.0,), cluster=(1, 1), max_aspect=0.0
):
    """Grid index ``(ix, iy)``, remainder flag and cell count of lots, from their geometry.

    The cluster holding each lot's centroid (inside its rectangle, which is convex),
    in its block's frame: the numbers :func:`partition_lots` gives, found
    again from the geometry (for a node that gets its lots back sorted and
    filtered).  ``owner`` indexes ``blocks``.
    """
    lots = np.asarray(lots, dtype=object)
    k = len(lots)
    owner = np.asarray(owner, np.int64)
    if k == 0:
        e64 = np.zeros(0, np.int64)
        return e64, e64, np.zeros(0, bool), e64
    blocks = np.asarray(blocks, dtype=object)
    center, axis, L, W = obb_frame(blocks)
    cx, cy = (int(c) for c in cluster)
    grid = {"mode": mode, "size": size, "count": count, "ratio": ratio, "cluster": (cx, cy), "max_aspect": max_aspect}
    xs, nx, ys, ny = _grid(L, W, **grid)
    # a lot's centroid lies in its own (convex) rectangle, or near it when the lot took a sliver
    p = shapely.get_coordinates(shapely.centroid(lots)) - center[owner]
    u = np.einsum("ij,ij->i", p, axis[owner]) + L[owner] / 2
    v = p[:, 0] * -axis[owner, 1] + p[:, 1] * axis[owner, 0] + W[owner] / 2

    def cell(edges, ncell, length, t):
        # each block's edges shifted past the previous block's: one searchsorted for all lots
        shift = np.r_[0.0, np.cumsum(length + 1.0)][:-1]
        own = np.repeat(np.arange(len(ncell)), ncell + 1)
        start = np.r_[0, np.cumsum(ncell + 1)][:-1]
        i = np.searchsorted(edges + shift[own], t + shift[owner], side="right") - 1 - start[owner]
        return np.clip(i, 0, ncell[owner] - 1).astype(np.int64)

    ix, iy = cell(xs, nx, L, u), cell(ys, ny, W, v)
    cells = _cells(L, W, ix, iy, owner, **grid)
    if mode == "size":
        full = cx * cy * size[0] * size[1]
        remainder = np.abs(shapely.area(lots) - full) > 1e-6 * full
    else:
        remainder = np.zeros(k, bool)
    return ix, iy, remainder, cells


def check_partition(blocks, *, mode, size, count, ratio, cluster, max_aspect=0.0, where=None, report=None) -> None:
    """Parameters that cannot hold: a one-line :class:`sengine.errors.ParameterError` naming the parameter.

    A cluster of more than 4 lots, a ratio without a positive part, or (mode
    ``size``) a lot larger than the box of every block of at least
    :data:`sengine.nodes.lots.recursive.REAL_BLOCK` m2: then no block gets
    one full lot.  A block too small only for some is one remainder lot,
    counted (``blocks_below_size`` in ``report``).
    """
    if int(cluster[0]) * int(cluster[1]) > 4:
        raise ParameterError(f"cluster={cluster[0]} {cluster[1]} makes clusters of more than 4 lots", where=where)
    if mode == "ratio" and (len(ratio) == 0 or min(ratio) <= 0):
        raise ParameterError(f"ratio={' '.join(f'{r:g}' for r in ratio)} must be positive numbers", where=where)
    if mode != "size":
        return
    blocks = np.asarray(blocks, dtype=object)
    area = shapely.area(blocks)
    live = ~shapely.is_empty(blocks) & (area > 0)
    if not live.any():
        return
    _, _, L, W = obb_frame(blocks[live])
    small = (L < size[0]) | (W < size[1])
    real = area[live] >= REAL_BLOCK  # slivers alone do not make a parameter wrong
    if real.any() and small[real].all():
        raise ParameterError(
            f"size={size[0]:g} {size[1]:g} m is larger than every block (the longest is {L.max():.1f} x "
            f"{W[np.argmax(L)]:.1f} m)",
            where=where,
        )
    if report is not None:
        report["blocks_below_size"] = report.get("blocks_below_size", 0) + int(small.sum())


def _numbers(text: str, name: str, where, *, integer=False) -> tuple:
    try:
        vals = tuple((int if integer else float)(v) for v in str(text).replace(",", " ").split())
    except ValueError:
        raise ParameterError(f"{name}={text!r} is not a list of numbers", where=where) from None
    if not vals:
        raise ParameterError(f"{name}={text!r} is empty", where=where)
    return vals


@register
class LotsPartition(_Lots):
    """Partition lots: a grid by absolute size (remainders kept), by count or by a repeating ratio; ix/iy
    index; clusters of up to 4 lots (Zhang et al. 2022, §3.3.1)."""

    name = "lots.partition"
    params = {
        "mode": Param("str", "size", choices=MODES, doc="absolute lot size, number of parts, or repeating ratio"),
        "size": Param(
            "float",
            (30.0, 40.0),
            min=0.5,
            count=2,
            unit="m",
            doc="size: lot width along the block and depth across it (30 x 40 m: a mid-rise building lot); "
            "ratio: pattern length and row depth",
        ),
        "count": Param("int", (4, 2), min=1, max=1000, count=2, unit="1", doc="count: parts along and across"),
        "ratio": Param("str", "1 2", doc="ratio: proportions of the widths in one repeat of the pattern"),
        "cluster": Param(
            "int", (1, 1), min=1, max=4, count=2, unit="1", doc="cells along and across merged into one lot (<= 4)"
        ),
        "min_area": Param("float", 1.0, min=0.0, unit="m2", doc="slivers under this join a neighbouring lot"),
        "max_aspect": Param(
            "float",
            6.0,
            min=0.0,
            unit="1",
            doc="size: a leftover column or row more elongated than 1:this joins the one beside it (0: keep all)",
        ),
        "lot_width_min": Param(
            "float",
            6.0,
            min=0.0,
            max=1000.0,
            unit="m",
            doc="a street lot with less street frontage joins a neighbour along the street (CityEngine's "
            "lotWidthMin; 0: keep all)",
        ),
    }

    def _options(self) -> dict:
        ratio = _numbers(self.p.ratio, "ratio", self.where)
        return {
            "mode": self.p.mode,
            "size": tuple(self.p.size),
            "count": tuple(self.p.count),
            "ratio": ratio,
            "cluster": tuple(self.p.cluster),
            "max_aspect": self.p.max_aspect,
        }

    def split(self, blocks, report):
        opts = self._options()
        check_partition(blocks.geometry, **opts, where=self.where, report=report)
        lots, owner, ix, iy, remainder, cells, inner, flags = partition_lots(
            blocks.geometry,
            **opts,
            min_area=self.p.min_area,
            lot_width_min=self.p.lot_width_min,
            report=report,
            fronts=blocks.get("street_front"),
            box=blocks.meta.get("bbox"),
            marks=True,
        )
        o = np.argsort(owner, kind="stable")
        lots, inner = lots[o], inner[o]
        self._index = (lots, ix[o], iy[o], remainder[o], cells[o])  # for run(): the lots come back sorted
        if flags is not None:  # merge_narrow measured every lot's frontage: the node need not again
            return LotSplit(
                lots, owner[o], np.full(len(lots), "partition"), inner, flags.take(o).flat, np.ones(len(lots), bool)
            )
        # what the method knows of frontage: none on the inner lots; the others are measured
        on = np.zeros(int((shapely.get_num_coordinates(lots) - 1 - shapely.get_num_interior_rings(lots)).sum()), bool)
        return LotSplit(lots, owner[o], np.full(len(lots), "partition"), inner, on, inner.copy())

    def run(self, *, blocks: Layer) -> NodeResult:
        self._index = None
        made = super().run(blocks=blocks)
        out, report = made.layers["lots"], made.report
        ix, iy = np.full(len(out), -1, np.int64), np.full(len(out), -1, np.int64)
        remainder, cells = np.zeros(len(out), bool), np.ones(len(out), np.int64)
        if self._index is not None and len(out):
            # the lots the split made are the very objects the layer holds: found by identity
            made, *cols = self._index
            ident = np.frompyfunc(id, 1, 1)
            mine, theirs = ident(made).astype(np.int64), ident(out.geometry).astype(np.int64)
            order = np.argsort(mine)
            pos = np.minimum(np.searchsorted(mine, theirs, sorter=order), len(order) - 1)
            hit = mine[order[pos]] == theirs
            src = order[pos[hit]]
            ix[hit], iy[hit], remainder[hit], cells[hit] = (c[src] for c in cols)
            whole = out["method"] == "whole"  # blocks the split did not partition (kept whole, counted)
            lost = ~hit & ~whole  # lots made anew after the split: their index from their geometry
            if lost.any():
                ix[lost], iy[lost], remainder[lost], cells[lost] = partition_index(
                    out.geometry[lost], blocks.rows_of(out["block"][lost]), blocks.geometry, **self._options()
                )
        self._index = None
        report["remainders"] = int(remainder.sum())
        return NodeResult({"lots": out.with_columns(ix=ix, iy=iy, remainder=remainder, cells=cells)}, report)

"""Fields: the open lots of a block that touch are one parcel of open land.

Lots are cut before anyone knows what stands on them: along a country road
the subdivision makes a row of house-sized lots, and only then does
``buildings.context`` find the road far from any street people live on and
mark those lots ``open`` (no building).  A field is one parcel, not a row
of 15 m strips, so this node unites the open lots of each block into the
connected pieces they make: every piece is one lot, numbered by the lowest
id among its lots and carrying that lot's attributes, with the frontages of
all of them summed and ``kind`` set to ``field``.  Built lots pass unchanged.

A block is never split across calls (the lots of one block are united only
with each other), so the node needs the whole layer: it does not map
features one by one.
"""

from __future__ import annotations

import logging

import numpy as np
import shapely

from sengine import Layer, NodeResult, Port, SENode, register
from sengine.geom.merge import TOUCH, kept_area

from .contour import ramp

__all__ = ["unite_by_group", "LotsFields"]

log = logging.getLogger(__name__)

#: Holes of a field smaller than this (m²) are rounding gaps between its lots, not land: filled.
MIN_HOLE = 1.0


def unite_by_group(geoms: np.ndarray, group: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The connected pieces of the union of each group's polygons, and the group of each piece.

    Parameters
    ----------
    geoms : numpy.ndarray of shapely polygons
        Polygons (m), e.g. lots; those of one group must not overlap.
    group : numpy.ndarray of int, shape (len(geoms),)
        Group of each polygon (its block).

    Returns
    -------
    pieces : numpy.ndarray of shapely polygons
        The pieces, groups in ascending order.
    piece_group : numpy.ndarray of int
        The group of each piece.
    """
    group = np.asarray(group, np.int64)
    if len(geoms) == 0:
        return np.empty(0, object), np.empty(0, np.int64)
    order = np.argsort(group, kind="stable")
    keys, count = np.unique(group[order], return_counts=True)
    # each group a row padded with None: one vectorized union along the rows (as lots.faces merges)
    grid = np.full((len(keys), int(count.max())), None, dtype=object)
    grid[np.repeat(np.arange(len(keys)), count), ramp(count)] = geoms[order]
    unions = shapely.union_all(grid, axis=1)
    # GEOS can lose a thin piece in an overlay: such a union is redone on a snapped grid
    row = np.repeat(np.arange(len(keys)), count)
    area = np.bincount(row, weights=shapely.area(geoms[order]), minlength=len(keys))
    outline = np.bincount(row, weights=shapely.length(geoms[order]), minlength=len(keys))
    for q in np.flatnonzero(~kept_area(unions, area, outline)):
        unions[q] = shapely.union_all(grid[q], grid_size=TOUCH)
    parts, which = shapely.get_parts(unions, return_index=True)
    keep = shapely.area(parts) > 0.0
    parts, which = parts[keep], which[keep]
    # lots meet along shared edges to within rounding: the union keeps the gaps as holes of no area
    for i in np.flatnonzero(shapely.get_num_interior_rings(parts) > 0):  # a few fields (40 on Liège)
        p = parts[i]
        parts[i] = shapely.Polygon(p.exterior, [r for r in p.interiors if shapely.Polygon(r).area >= MIN_HOLE])
    return parts, keys[which]


@register
class LotsFields(SENode):
    """Unite the open lots of each block that touch into whole fields."""

    name = "lots.fields"
    inputs = {"lots": Port("lots", "lots with 'block' and 'open' (buildings.context)")}
    outputs = {"lots": Port("lots", "the built lots as they were, and one lot per field")}
    params = {}

    def run(self, *, lots: Layer) -> NodeResult:
        n = len(lots)
        open_ = np.asarray(lots["open"], bool) if "open" in lots.attrs and n else np.zeros(n, bool)
        if not open_.any() or "block" not in lots.attrs:
            return NodeResult({"lots": lots}, {"fields": 0, "open_lots": int(open_.sum())})
        rows = np.flatnonzero(open_)
        block = np.asarray(lots["block"], np.int64)[rows]
        pieces, piece_block = unite_by_group(lots.geometry[rows], block)
        # each open lot belongs to the piece of its block holding its interior point
        sites = shapely.point_on_surface(lots.geometry[rows])
        lot_at, piece_at = shapely.STRtree(pieces).query(sites, predicate="intersects")
        same = piece_block[piece_at] == block[lot_at]
        lot_at, piece_at = lot_at[same], piece_at[same]
        # a lot touching two pieces' boundaries at its site goes to the first: one piece a lot
        first = np.r_[True, lot_at[1:] != lot_at[:-1]]
        lot_at, piece_at = lot_at[first], piece_at[first]
        ids = lots.ids[rows]
        # the piece's lot: its lowest id (the lots are in id order within a piece after a lexsort)
        o = np.lexsort((ids[lot_at], piece_at))
        lot_at, piece_at = lot_at[o], piece_at[o]
        head = np.r_[True, piece_at[1:] != piece_at[:-1]]
        lead = rows[lot_at[head]]
        fields = lots.take(lead).with_geometry(pieces[piece_at[head]])
        kind = np.asarray(lots["kind"]).dtype if "kind" in lots.attrs else np.dtype("<U5")
        columns = {"kind": np.full(len(fields), "field", dtype=np.result_type(kind, np.dtype("<U5")))}
        if "frontage" in lots.attrs:
            frontage = np.asarray(lots["frontage"], np.float64)[rows[lot_at]]
            columns["frontage"] = np.add.reduceat(frontage, np.flatnonzero(head))
        if "inner" in lots.attrs:
            columns["inner"] = np.zeros(len(fields), bool)
        fields = fields.with_columns(**columns)
        built = lots.take(np.flatnonzero(~open_))
        merged = Layer.concat([built, fields], renumber=False)
        merged = merged.take(np.argsort(merged.ids, kind="stable")).with_meta(**lots.meta)
        report = {"fields": len(fields), "open_lots": int(open_.sum())}
        log.info("%s: %d open lots make %d fields", self.where, report["open_lots"], report["fields"])
        return NodeResult({"lots": merged}, report)

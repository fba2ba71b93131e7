"""Land use from map polygons: water and parks inside a block are not built on.

In skylineEngine the land-use map says where the city may build: its water
and park classes are cut out of the buildable area before the streets are
laid (§3-4).  A real city's street faces already exist, and its land use
comes as polygons from the same file (``osm.read``'s ``water`` and
``parks``): a square inside a block, a park filling a block, a river
between two bridges.  This node cuts those polygons out of the blocks
before the lots are drawn, so that no lot and no building stands in a park
or in the water.

The edge a block gets along a park or the water counts as its boundary like
a street edge does: lots may face the park.

References
----------
skylineEngine (paper 002), §4 (parks and land use) and §5.2 (real maps).
"""

from __future__ import annotations

import logging

import numpy as np
import shapely

from sengine import Layer, Param, Port, SENode, register
from sengine.geom.polygons import inset

__all__ = ["cut_blocks", "BlocksLanduse"]

log = logging.getLogger(__name__)


def cut_blocks(blocks, cut, *, min_area: float = 0.0, min_width: float = 0.0) -> tuple[np.ndarray, np.ndarray, dict]:
    """The parts of each block outside every ``cut`` polygon.

    Parameters
    ----------
    blocks : array_like of shapely.Polygon
        Blocks (m).
    cut : array_like of shapely.Geometry
        Land that is not built on (m): water, parks.  Invalid polygons are
        repaired first; points and lines are ignored.
    min_area : float
        Pieces smaller than this are dropped (m2).
    min_width : float
        Pieces of a cut block that are nowhere this wide (their inset by
        half of it is empty) are dropped (m): the strip a park leaves
        along a street.

    Returns
    -------
    pieces : ndarray of shapely.Polygon
        The buildable pieces, block after block.
    block : ndarray of int64
        Index into ``blocks`` of each piece.
    counts : dict
        ``blocks_cut`` (blocks a polygon took land from), ``blocks_removed``
        (blocks left with no piece), ``pieces_dropped`` (under
        ``min_area`` or ``min_width``), ``area_removed_m2``.
    """
    blocks = np.asarray(blocks, dtype=object)
    cut = shapely.get_parts(shapely.make_valid(np.asarray(cut, dtype=object)))
    cut = cut[np.isin(shapely.get_type_id(cut), (3, 6))] if len(cut) else cut
    out = blocks.copy()
    bi = np.empty(0, np.int64)
    if len(blocks) and len(cut):
        bi, ci = shapely.STRtree(cut).query(blocks, predicate="intersects")
        o = np.lexsort((ci, bi))
        bi, ci = bi[o], ci[o]
        first = np.r_[0, np.flatnonzero(np.diff(bi)) + 1] if len(bi) else np.zeros(0, np.int64)
        rank = np.arange(len(bi)) - np.repeat(first, np.diff(np.r_[first, len(bi)]))
        # one difference per (block, polygon) pair, a round per rank: every block loses its k-th polygon in round k
        for k in range(int(rank.max(initial=-1)) + 1):
            sel = rank == k
            out[bi[sel]] = shapely.difference(out[bi[sel]], cut[ci[sel]])
    cut_ones = np.unique(bi)
    bad = cut_ones[~shapely.is_valid(out[cut_ones])] if len(cut_ones) else cut_ones
    out[bad] = shapely.make_valid(out[bad])  # an edge cut off a hair's breadth away collapses into a spike
    pieces, block = shapely.get_parts(out, return_index=True)
    nested = np.isin(shapely.get_type_id(pieces), (6, 7))  # a repaired block may hold a MultiPolygon
    if nested.any():
        inner, k = shapely.get_parts(pieces[nested], return_index=True)
        pieces, block = np.concatenate([pieces[~nested], inner]), np.concatenate([block[~nested], block[nested][k]])
        o = np.argsort(block, kind="stable")
        pieces, block = pieces[o], block[o]
    poly = shapely.get_type_id(pieces) == 3
    area = shapely.area(pieces)
    keep = poly & (area >= min_area)
    thin = np.flatnonzero(keep & np.isin(block, bi))  # only a cut can make a block thin
    if min_width > 0 and len(thin):
        keep[thin] = ~shapely.is_empty(inset(pieces[thin], min_width / 2.0))
    before = shapely.area(blocks).sum() if len(blocks) else 0.0
    counts = {
        "blocks_cut": int(len(np.unique(bi))),
        "blocks_removed": int(len(blocks) - len(np.unique(block[keep]))),
        "pieces_dropped": int((poly & ~keep).sum()),
        "area_removed_m2": round(float(before - area[keep].sum()), 1),
    }
    return pieces[keep], block[keep].astype(np.int64), counts


@register
class BlocksLanduse(SENode):
    """Blocks minus the water and the parks in them: the land the lots are drawn on (§4, §5.2)."""

    name = "blocks.landuse"
    inputs = {
        "blocks": Port("blocks", "blocks"),
        "water": Port("polygons", "water areas (e.g. osm.read's water)", required=False),
        "parks": Port("parks", "parks (e.g. osm.read's parks)", required=False),
    }
    outputs = {"blocks": Port("blocks", "the buildable pieces; a block cut in two keeps its id on the first piece")}
    params = {
        "min_area": Param("float", 50.0, min=0.0, unit="m2", doc="pieces smaller than this are dropped"),
        "min_width": Param(
            "float",
            4.0,
            min=0.0,
            unit="m",
            doc="pieces of a cut block nowhere this wide are dropped (a strip left along a park)",
        ),
    }

    def run(self, *, blocks: Layer, water: Layer | None = None, parks: Layer | None = None) -> dict[str, Layer]:
        cut = [lay.geometry for lay in (water, parks) if lay is not None and len(lay)]
        geoms = np.concatenate(cut) if cut else np.empty(0, dtype=object)
        pieces, src, counts = cut_blocks(blocks.geometry, geoms, min_area=self.p.min_area, min_width=self.p.min_width)
        out = blocks.take(src)
        # the first piece of a block keeps its id; further pieces get new ones after the largest
        again = np.r_[False, src[1:] == src[:-1]] if len(src) else np.zeros(0, bool)
        top = int(blocks.ids.max(initial=-1)) + 1
        ids = out.ids.copy()
        ids[again] = top + np.arange(int(again.sum()))
        out = Layer(pieces, ids, out.parent, out.attrs, out.meta)
        self.report = {**counts, "blocks": len(out)}
        log.info(
            "%s: %d of %d blocks lose water or park land (%.0f m2); %d pieces",
            self.where,
            counts["blocks_cut"],
            len(blocks),
            counts["area_removed_m2"],
            len(out),
        )
        return {"blocks": out}

"""Patio zones (``parks.patio``): Ulmer et al. §3.2, the open core of a block once buildings stand.

"A lot zone without a street edge is characterized as a patio zone.  It
serves to fill up the empty space in the center of blocks, enclosed by
buildings."  After the buildings, each block's open land (the block minus
its buildings, kept ``gap`` m off their walls) falls into pieces; a piece
that touches no street edge of its block is a patio zone: a courtyard, the
rear yards of a perimeter block.  With ``front`` > 0 the open land deeper
than ``front`` m from the street counts too, even where a gap between
buildings opens it to the street.  Pieces under ``min_area`` or thinner than
``min_width`` are left out (a light well is no garden).

Vectorized over all blocks: the buildings of each block become one
geometry (:func:`shapely.multipolygons` by block, buffered by ``gap``, which
also unions walls that touch), then one difference, one ``get_parts`` and
one distance test.  A patio's id comes from its block and its rank there
(:mod:`.ids`); the parks stream is handed on in id order.

References
----------
Patio zones, §3.2 of [1]_.

.. [1] A. Ulmer, J. Halatsch, A. Kunze, P. Müller and L. Van Gool, "Procedural design
   of urban open spaces", Proceedings of the 25th eCAADe Conference, Frankfurt am
   Main, pp. 351-358, 2007 (paper 001 in shared/papers).
"""

from __future__ import annotations

import logging

import numpy as np
import shapely

from sengine import Layer, NodeResult, Param, Port, SENode, register

from .ids import block_site, join_parks, park_ids, ranks
from .level import CountsItsLevel

__all__ = ["patio_zones", "ParksPatio"]

log = logging.getLogger(__name__)


def patio_zones(
    blocks, buildings, *, gap: float = 0.5, front: float = 0.0, min_area: float = 50.0, min_width: float = 4.0
) -> tuple[np.ndarray, np.ndarray]:
    """The patio zones of each block: open land that touches no street edge.

    Parameters
    ----------
    blocks : array_like of shapely.Polygon
        Blocks (m); their boundary is the street edge.
    buildings : array_like of shapely.Polygon
        Building footprints (m).
    gap : float
        Clearance kept from the walls (m).
    front : float
        Open land farther than this from the street edge is a patio even when
        open to the street (m); 0: only land enclosed by buildings.
    min_area : float
        Smallest patio (m2).
    min_width : float
        Narrowest patio (m): thinner pieces are opened away.

    Returns
    -------
    zones : numpy.ndarray of shapely.Polygon
    block : numpy.ndarray of int
        Row of each zone's block.
    """
    blocks = np.asarray(blocks, dtype=object)
    buildings = np.asarray(buildings, dtype=object)
    empty = np.empty(0, object), np.empty(0, np.int64)
    if len(blocks) == 0 or len(buildings) == 0:
        return empty
    bi, ki = shapely.STRtree(blocks).query(buildings, predicate="intersects")
    if len(bi) == 0:
        return empty
    order = np.lexsort((bi, ki))
    bi, ki = bi[order], ki[order]
    parts, part_of = shapely.get_parts(buildings[bi], return_index=True)
    poly = shapely.get_type_id(parts) == 3
    parts, owner = parts[poly], ki[part_of[poly]]
    built_blocks = np.unique(owner)
    multi = shapely.multipolygons(parts, indices=np.searchsorted(built_blocks, owner))
    walls = shapely.buffer(multi, max(gap, 1e-3), quad_segs=2, join_style="mitre")
    # buildings sharing party walls make a multipolygon whose parts touch along edges; its buffer can come
    # out invalid (Paris: a side location conflict in the difference below), so such walls are repaired
    bad = ~shapely.is_valid(walls)
    if bad.any():
        walls[bad] = shapely.make_valid(walls[bad])
    try:
        open_land = shapely.difference(blocks[built_blocks], walls)
    except shapely.errors.GEOSException:  # a wall union GEOS still cannot subtract ('free hole'): blocks made valid
        open_land = shapely.difference(shapely.make_valid(blocks[built_blocks]), shapely.make_valid(walls))
    street = shapely.boundary(blocks[built_blocks])
    if front > 0:
        open_land = shapely.difference(open_land, shapely.buffer(street, front, quad_segs=2))
    pieces, which = shapely.get_parts(open_land, return_index=True)
    if min_width > 0 and len(pieces):
        pieces = shapely.buffer(
            shapely.buffer(pieces, -min_width / 2, join_style="mitre"), min_width / 2, join_style="mitre"
        )
        pieces = shapely.intersection(pieces, open_land[which])
        pieces, sub = shapely.get_parts(pieces, return_index=True)
        which = which[sub]
    poly = shapely.get_type_id(pieces) == 3
    pieces, which = pieces[poly], which[poly]
    keep = shapely.area(pieces) >= min_area
    if front <= 0:  # enclosed: no street edge
        keep &= shapely.distance(pieces, street[which]) > 1e-3
    return pieces[keep], built_blocks[which[keep]]


@register
class ParksPatio(CountsItsLevel, SENode):
    """Patio zones: each block's open core once buildings stand, as parks of level 'patio' (001 §3.2)."""

    name = "parks.patio"
    level = "patio"
    shard_streams = ("parks",)
    inputs = {
        "blocks": Port("blocks", "blocks: their boundary is the street edge"),
        "buildings": Port("buildings", "buildings standing on the blocks"),
        "parks": Port("parks", "parks made upstream, passed through", required=False),
    }
    outputs = {"parks": Port("parks", "upstream parks plus the patio zones (level 'patio')")}
    params = {
        "mode": Param("str", "none", choices=("none", "all"), doc="all: make patio zones; none: hand parks on"),
        "gap": Param("float", 0.5, min=0.0, max=20.0, unit="m", doc="clearance kept from the walls"),
        "front": Param(
            "float",
            0.0,
            min=0.0,
            max=200.0,
            unit="m",
            doc="land this far from the street is a patio even if open to it",
        ),
        "min_area": Param("float", 50.0, min=0.0, unit="m2", doc="smallest patio"),
        "min_width": Param("float", 4.0, min=0.0, max=100.0, unit="m", doc="narrowest patio"),
    }

    def run(self, *, blocks: Layer, buildings: Layer, parks: Layer | None = None):
        if self.p.mode == "none":
            out = parks if parks is not None else Layer.empty(meta=dict(blocks.meta), level=np.dtype("<U8"))
            return NodeResult({"parks": out}, {"patios": 0})
        zones, row = patio_zones(
            blocks.geometry,
            buildings.geometry,
            gap=self.p.gap,
            front=self.p.front,
            min_area=self.p.min_area,
            min_width=self.p.min_width,
        )
        district = np.asarray(blocks["district"], np.int64)[row] if "district" in blocks else np.full(len(row), -1)
        bid = blocks.ids[row].astype(np.int64)
        new = Layer.from_geoms(
            zones,
            ids=park_ids(block_site(bid) + ranks(bid), "patio", where=self.where),
            parent=blocks.ids[row],
            meta=dict(blocks.meta),
            level=np.full(len(zones), "patio"),
            district=district,
            area=shapely.area(zones) if len(zones) else np.zeros(0),
            block=blocks.ids[row].astype(np.int64),
        )
        out = join_parks(parks, new, where=self.where)
        report = {"patios": len(new), "patio_area_m2": round(float(new.area()), 1)}
        log.info("%s: %d patio zones, %.0f m2", self.where, len(new), new.area())
        return NodeResult({"parks": out}, report)

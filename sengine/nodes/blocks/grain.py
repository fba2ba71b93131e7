"""The fabric of each block from its street grain: how large its lots are cut.

A town is not cut into lots of one size.  Along a village road the plots
are wide enough for a detached house with its garden on either side; in a
suburb of detached and semi-detached houses a little narrower; in the rows
of a town's nineteenth-century quarters a terraced house stands on a plot
of 5 to 8 m of street frontage (a Belgian example: a terraced house in
Bilzen on a lot 5.30 m wide [3]_; a new terrace in New South Wales must
be at least 6 m wide at the building line [4]_).  Lot size is a property
of the block, decided before the block is cut, as a CityEngine user sets
``lotAreaMax`` per block.

Where a map holds only streets, the street grain is the evidence left of
which fabric a block belongs to (:func:`sengine.geom.grain.street_density`,
km of street per km² of the land the streets serve; motorways and trunk
roads, which nothing fronts, left out): a compact town quarter has at least
18 km/km² [1]_, a village a few.  Each block gets its ``grain`` at a point
on it and, by the same bands as ``buildings.context``:

============ =========================== ==============================
``fabric``   street grain (km/km²)       lot size (``lot_area``, m²)
============ =========================== ==============================
``rural``    under ``rural_grain``        ``rural_lot_area``
``houses``   ``rural_grain`` up to        ``house_lot_area``
             ``urban_grain``, with the
             chance it falls short of
             ``urban_grain``
``rows``     the rest of that band        ``row_lot_area``
``urban``    ``urban_grain`` and above    ``urban_lot_area``
============ =========================== ==============================

From the village to the town centre detached houses give way to rows: a
block in the town band is ``houses`` with a chance falling linearly from
one at ``rural_grain`` to none at ``urban_grain``, drawn per block from
(seed, node id, block id), so that a street of houses is one fabric on
both sides of its block, not a house between two terraces.

``lot_area`` is the largest lot the lot nodes cut the block into
(``lots.recursive`` and ``lots.district``'s recursive blocks take it as
their ``max_area``; ``lots.skeleton`` as its ``lot_area_max``, with lots
``lot_area / depth`` wide; ``lots.paris`` cuts its contour into segments
``lot_area / depth`` long; 0 leaves the node's own); lots carry their block's
``grain`` and ``fabric``, and ``buildings.context`` builds houses on
``rural`` and ``houses`` lots and rows on ``rows`` lots.  With the defaults,
the recursive lots of whole Liège come out with a median frontage of 8 m in ``rows``, 18 m in ``houses``
and 26 m in ``rural`` blocks (under 1 % thinner than 1:10).  An ``urban``
block is cut into town houses' plots of ``urban_lot_area`` (300 m²: 10 m
of frontage on a 30 m deep plot, as in the nineteenth-century quarters of
Belgian towns) unless it holds one of the map's buildings, which say how
that centre is built better than any default: then it keeps the lot
node's own size (Helsinki's perimeter blocks stand on lots of 20 m and more).

References
----------
.. [1] UN-Habitat, "A new strategy of sustainable neighbourhood planning:
   five principles", Urban Planning Discussion Note 3, United Nations Human
   Settlements Programme, Nairobi, 2014 (principle 1: at least 18 km of
   street length per km²).
.. [2] Ville de Liège, "Topologie du bâti résidentiel", map from the
   cadastre, https://www.liege.be (read November 2026): single-family
   houses, terraced or detached, make up most of the built fabric outside
   the central quarters.
.. [3] "House in Belgium by Bassam El Okeily", Materialicious, March 2011:
   a terraced house on a lot 5.30 m wide in Bilzen.
.. [4] State Environmental Planning Policy (Exempt and Complying Development
   Codes) 2008 (New South Wales), clause 3B.38 (3): each terrace at least
   6 m wide at the building line.
"""

from __future__ import annotations

import logging

import numpy as np
import shapely

from sengine import Layer, NodeResult, Param, Port, SENode, register
from sengine.errors import ParameterError
from sengine.geom.grain import street_density
from sengine.random import uniform

__all__ = ["FABRICS", "GRAIN_PARAMS", "NO_FRONTAGE", "check_bands", "fabric_of", "holds_buildings", "BlocksGrain"]

log = logging.getLogger(__name__)

#: Values of the ``fabric`` column, from the sparsest street grain to the densest.
FABRICS = ("rural", "houses", "rows", "urban")
#: Road classes no building fronts: left out of the street grain.
NO_FRONTAGE = ("motorway", "motorway_link", "trunk", "trunk_link")


#: The street grain's measure and bands, shared with ``buildings.context``.
GRAIN_PARAMS = {
    "grain_radius": Param(
        "float",
        500.0,
        min=50.0,
        max=5000.0,
        unit="m",
        doc="half the side of the square the street grain is measured in",
    ),
    "rural_grain": Param(
        "float", 8.0, min=0.0, max=200.0, unit="km/km2", doc="street grain under which the land is rural (houses)"
    ),
    "urban_grain": Param(
        "float", 14.0, min=0.0, max=200.0, unit="km/km2", doc="street grain from which the land is urban"
    ),
}


def check_bands(p, where):
    """``p`` (checked parameters with ``rural_grain`` and ``urban_grain``), or a one-line error if they cross."""
    if p.rural_grain > p.urban_grain:
        raise ParameterError(
            f"rural_grain ({p.rural_grain:g}) must not exceed urban_grain ({p.urban_grain:g})", where=where
        )
    return p


def holds_buildings(blocks: np.ndarray, buildings: Layer | None) -> np.ndarray:
    """Which ``blocks`` (polygons) hold a point of one of the map's ``buildings`` (none without any)."""
    out = np.zeros(len(blocks), bool)
    if buildings is None or not len(buildings) or not len(blocks):
        return out
    _, inside = shapely.STRtree(blocks).query(shapely.point_on_surface(buildings.geometry), predicate="within")
    out[inside] = True
    return out


def fabric_of(grain: np.ndarray, u: np.ndarray, rural_grain: float, urban_grain: float) -> np.ndarray:
    """The fabric of each block from its street grain and a uniform draw.

    Parameters
    ----------
    grain : numpy.ndarray, shape (n,)
        Street grain at each block (km/km²).
    u : numpy.ndarray, shape (n,)
        A uniform draw in [0, 1) per block.
    rural_grain, urban_grain : float
        The band limits (km/km²), ``rural_grain <= urban_grain``.

    Returns
    -------
    numpy.ndarray of int, shape (n,)
        Index into :data:`FABRICS`: ``rural`` under ``rural_grain``;
        ``urban`` from ``urban_grain``; in between ``houses`` where ``u`` is
        under the share ``(urban_grain - grain) / (urban_grain - rural_grain)``,
        else ``rows``.
    """
    grain = np.asarray(grain, np.float64)
    span = max(urban_grain - rural_grain, 1e-9)
    town = np.where(np.asarray(u) < (urban_grain - grain) / span, 1, 2)
    return np.where(grain < rural_grain, 0, np.where(grain < urban_grain, town, 3)).astype(np.int64)


@register
class BlocksGrain(SENode):
    """The fabric of each block (rural, houses, rows, urban) and the size of its lots, from the street grain."""

    name = "blocks.grain"
    maps_features = True
    inputs = {
        "blocks": Port("blocks", "blocks to size"),
        "roads": Port("roads", "street centre lines (with 'class'): the street grain round the blocks"),
        "existing": Port(
            "buildings", "the map's buildings: an urban block holding one keeps the lot node's size", required=False
        ),
    }
    outputs = {"blocks": Port("blocks", "the blocks with 'grain' (km/km2), 'fabric' and 'lot_area' (m2) columns")}
    params = {
        **GRAIN_PARAMS,
        "rural_lot_area": Param(
            "float", 1200.0, min=0.0, max=1e7, unit="m2", doc="largest lot of a rural block (0: the lot node's own)"
        ),
        "house_lot_area": Param(
            "float", 800.0, min=0.0, max=1e7, unit="m2", doc="largest lot of a block of houses (0: the lot node's own)"
        ),
        "row_lot_area": Param(
            "float", 250.0, min=0.0, max=1e7, unit="m2", doc="largest lot of a block of rows (0: the lot node's own)"
        ),
        "urban_lot_area": Param(
            "float",
            300.0,
            min=0.0,
            max=1e7,
            unit="m2",
            doc="largest lot of an urban block that holds no map building: a town house's plot (0: the lot node's own)",
        ),
    }

    @classmethod
    def check_params(cls, values, where):
        """The declared checks, and the bands in order."""
        return check_bands(super().check_params(values, where), where)

    def run(self, *, blocks: Layer, roads: Layer, existing: Layer | None = None) -> NodeResult:
        p = self.p
        n = len(blocks)
        sites = shapely.get_coordinates(shapely.point_on_surface(blocks.geometry)) if n else np.zeros((0, 2))
        kind = np.asarray(roads.get("class", np.full(len(roads), "")), dtype=str)
        grain = street_density(roads.geometry[~np.isin(kind, NO_FRONTAGE)], sites, p.grain_radius)
        u = uniform(self.context.seed, f"{self.id}/houses", blocks.ids)
        code = fabric_of(grain, u, p.rural_grain, p.urban_grain)
        fabric = np.asarray(FABRICS)[code]
        lot_area = np.array([p.rural_lot_area, p.house_lot_area, p.row_lot_area, p.urban_lot_area])[code]
        # the map's own buildings say how a centre is built better than a town house's plot: keep the node's size
        built = holds_buildings(blocks.geometry, existing) & (fabric == "urban")
        lot_area[built] = 0.0
        report = {f"blocks_{f}": int((fabric == f).sum()) for f in FABRICS}
        report["urban_blocks_with_buildings"] = int(built.sum())
        log.info("%s: %s", self.where, ", ".join(f"{v} {k[7:]}" for k, v in report.items()))
        out = blocks.with_columns(grain=grain, fabric=fabric.astype(str), lot_area=lot_area)
        return NodeResult({"blocks": out}, report)

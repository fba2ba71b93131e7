"""Water of a synthetic city: the land-use map's water class as a ``water`` layer.

``roads.districts`` cuts every non-buildable land-use class out of the city
and hands the regions on (its ``landuse`` output, column ``kind``); an OSM
city's water comes from the map (``osm.read``).  This node picks the regions
of the water class, so a synthetic river or lake is drawn, exported in every
format and crossed by bridges like a real one.
"""

from __future__ import annotations

import numpy as np
import shapely

from sengine import Layer, NodeResult, Param, Port, SENode, register

__all__ = ["WaterLanduse"]


@register
class WaterLanduse(SENode):
    """The land-use map's water regions as the city's water layer (kind 'water')."""

    name = "water.landuse"
    inputs = {"landuse": Port("polygons", "non-buildable land-use regions, column kind (roads.districts)")}
    outputs = {"water": Port("polygons", "the water regions (kind 'water')")}
    params = {"kind": Param("str", "water", doc="the land-use class that is water")}

    def run(self, *, landuse: Layer):
        kind = np.asarray(landuse["kind"]).astype(str) if "kind" in landuse and len(landuse) else np.empty(0, str)
        water = landuse.take(kind == self.p.kind)
        area = float(shapely.area(water.geometry).sum()) if len(water) else 0.0
        return NodeResult({"water": water}, {"water_bodies": len(water), "water_km2": round(area / 1e6, 4)})

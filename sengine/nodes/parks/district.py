"""Parks at district level (``parks.district``): skylineEngine §4, Central Park.

"There are cities which have a park so large that it can be considered as a
district by itself."  The land-use map's ``park`` class is vectorized by
``roads.districts`` (one coverage with the districts, so the park's border
is a road); this node is the head of the ``parks`` stream: it takes those
regions, drops the ones under ``min_area`` (a stray pixel blob is no park) and
stamps their ``level``.  Their ids are stable (:mod:`.ids`): from the
enclosure (``areas``) holding each park's inner point, or the key after
every enclosure for a park outside them all, and its rank there; the layer
is in id order.  Mode ``none`` hands on no park at all (the land
stays cut out of the city: the map said nothing may be built there).

References
----------
§4 of [1]_.

.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
"""

from __future__ import annotations

import numpy as np
import shapely

from sengine import Layer, NodeResult, Param, Port, SENode, register
from sengine.geom.polygons import containing

from .ids import district_sites, park_ids
from .level import CountsItsLevel

__all__ = ["ParksDistrict"]


@register
class ParksDistrict(CountsItsLevel, SENode):
    """District-level parks: the land-use map's park class, the head of the parks stream (paper 002 §4)."""

    name = "parks.district"
    level = "district"
    inputs = {
        "parks": Port("parks", "the land-use map's park regions (roads.districts' parks)", required=False),
        "areas": Port("areas", "the areas enclosed by major roads: they key the parks' ids", required=False),
    }
    outputs = {"parks": Port("parks", "district-level parks (column level = 'district')")}
    params = {
        "mode": Param("str", "all", choices=("all", "none"), doc="all: every land-use park region; none: no park"),
        "min_area": Param("float", 0.0, min=0.0, unit="m2", doc="smaller regions are not parks"),
    }

    def run(self, *, parks: Layer | None = None, areas: Layer | None = None):
        if parks is None:
            parks = Layer.empty(level=np.dtype("<U8"), district=np.dtype(np.int64), area=np.dtype(np.float64))
        area = shapely.area(parks.geometry) if len(parks) else np.zeros(0)
        keep = area >= self.p.min_area if self.p.mode == "all" else np.zeros(len(parks), bool)
        out = parks if keep.all() else parks.take(keep)
        if "level" not in out or (len(out) and (np.asarray(out["level"]).astype(str) != "district").any()):
            out = out.with_columns(level=np.full(len(out), "district"))
        enclosure = np.zeros(len(out), np.int64)
        if areas is not None and len(areas) and len(out):
            host = containing(shapely.point_on_surface(out.geometry), areas.geometry)
            enclosure = np.where(host >= 0, areas.ids[np.maximum(host, 0)], int(areas.ids.max()) + 1)
        ids = park_ids(district_sites(enclosure), "district", where=self.where)
        out = Layer(out.geometry, ids, out.parent, dict(out.attrs), dict(out.meta)).take(np.argsort(ids, kind="stable"))
        report = {"district_parks": len(out), "park_area_m2": round(float(area[keep].sum()), 1)}
        return NodeResult({"parks": out}, report)

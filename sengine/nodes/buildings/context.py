"""Infill that fits: a generated building takes the storeys of the map's buildings around it.

In a built-up area, planning law admits a new building when it fits the
character of its surroundings in height and kind of building: Germany's
building code, for one, allows a project inside a built-up district only if
it "fits into the character of the immediate surroundings" by the type and
degree of use and the building method (BauGB §34 (1), the
*Einfügungsgebot*).  A real map holding buildings with a ``height`` or
``building:levels`` tag (``osm.read``'s ``height_source``) says what that
character is; a lot the map leaves free should not get a 21 m tower beside
two-storey houses because the node's default height says 15 m.

So each lot gets, as its ``floors`` rule column, the median storeys of the
``neighbours`` nearest tagged map buildings within ``radius`` of it, when at
least ``min_neighbours`` are there (elsewhere, and where the lot already
carries ``floors``, the lot is left to the height map and the node's
parameters); and where that median is at most ``low_rise`` storeys, the
low-rise typologies only (``low_rise_typology``: bars and L's, no towers or
U courts).  Untagged map buildings carry the reader's default height, not the
map's word, and are no evidence.  ``buildings.massing`` reads both columns
(:func:`sengine.nodes.buildings.rules.per_lot`).

References
----------
.. [1] Baugesetzbuch (BauGB, German Federal Building Code), §34 (1): projects
   within built-up areas, version of 3 November 2017 (BGBl. I S. 3634).
"""

from __future__ import annotations

import logging

import numpy as np
import shapely

from sengine import Layer, NodeResult, Param, Port, SENode, register
from sengine.errors import ParameterError

from .typology import TYPOLOGIES, parse_choices

__all__ = ["neighbour_floors", "BuildingsContext"]

log = logging.getLogger(__name__)

#: ``height_source`` values of map buildings whose storeys the map states (not the reader's default).
TAGGED = ("height", "levels")


def neighbour_floors(
    sites: np.ndarray, buildings: np.ndarray, floors: np.ndarray, *, k: int, radius: float, min_count: int
) -> np.ndarray:
    """Median storeys of the ``k`` buildings nearest each site within ``radius``; NaN with fewer than ``min_count``.

    Parameters
    ----------
    sites : numpy.ndarray, shape (n, 2)
        Points of the lots (m).
    buildings : numpy.ndarray, shape (m, 2)
        Points of the buildings (m).
    floors : numpy.ndarray, shape (m,)
        Their storeys.
    k : int
        Most neighbours taken.
    radius : float
        Farthest neighbour (m).
    min_count : int
        Fewest neighbours that make a median.
    """
    out = np.full(len(sites), np.nan)
    if len(sites) == 0 or len(buildings) < min_count:
        return out
    k = min(int(k), len(buildings))
    from scipy.spatial import cKDTree  # 0.1 s to import: only when there are buildings to ask

    dist, idx = cKDTree(buildings).query(sites, k=k, distance_upper_bound=radius)
    dist, idx = dist.reshape(len(sites), k), idx.reshape(len(sites), k)
    near = np.isfinite(dist)
    vals = np.where(near, np.asarray(floors, np.float64)[np.minimum(idx, len(buildings) - 1)], np.nan)
    enough = near.sum(axis=1) >= min_count
    if enough.any():
        out[enough] = np.nanmedian(vals[enough], axis=1)
    return out


@register
class BuildingsContext(SENode):
    """Storeys and typologies for the lots from the map's buildings around them (BauGB §34: infill that fits)."""

    name = "buildings.context"
    maps_features = True
    inputs = {
        "lots": Port("lots", "lots to build on"),
        "existing": Port(
            "buildings", "the map's buildings with 'floors' and 'height_source' (osm.read)", required=False
        ),
    }
    outputs = {"lots": Port("lots", "the lots with 'floors' and 'typology' rule columns where the map says")}
    params = {
        "radius": Param("float", 150.0, min=1.0, max=5000.0, unit="m", doc="farthest map building that counts"),
        "neighbours": Param("int", 12, min=1, max=200, unit="1", doc="nearest tagged map buildings taken"),
        "min_neighbours": Param(
            "int", 3, min=1, max=200, unit="1", doc="fewest tagged map buildings within radius that set the storeys"
        ),
        "low_rise": Param(
            "int",
            3,
            min=0,
            max=300,
            unit="1",
            doc="at most this many storeys around: low-rise typologies only (0: off)",
        ),
        "low_rise_typology": Param("str", "I:3,L", doc="typologies of lots in a low-rise neighbourhood"),
    }

    @classmethod
    def check_params(cls, values, where):
        """The declared checks, and ``low_rise_typology`` read as ``buildings.massing`` will read it."""
        p = super().check_params(values, where)
        try:
            parse_choices(p.low_rise_typology, TYPOLOGIES, what="typology")
        except ValueError as exc:
            raise ParameterError(f"low_rise_typology: {exc}", where=where) from None
        return p

    def run(self, *, lots: Layer, existing: Layer | None = None) -> NodeResult:
        n = len(lots)
        floors = np.full(n, np.nan)
        if existing is not None and len(existing) and n and "floors" in existing:
            src = np.asarray(existing.get("height_source", np.full(len(existing), "levels")), dtype=str)
            tagged = np.isin(src, TAGGED)
            pts = shapely.get_coordinates(shapely.point_on_surface(existing.geometry[tagged]))
            sites = shapely.get_coordinates(shapely.point_on_surface(lots.geometry))
            floors = neighbour_floors(
                sites,
                pts,
                np.asarray(existing["floors"])[tagged],
                k=self.p.neighbours,
                radius=self.p.radius,
                min_count=self.p.min_neighbours,
            )
            floors = np.where(np.isfinite(floors), np.maximum(np.rint(floors), 1.0), np.nan)
        if "floors" in lots:  # a lot's own rule column wins
            own = np.asarray(lots["floors"], np.float64)
            floors = np.where(np.isfinite(own) & (own > 0), own, floors)
        fitted = np.isfinite(floors)
        typology = np.asarray(lots.get("typology", np.full(n, "", dtype=object)), dtype=object).copy()
        low = fitted & (floors <= self.p.low_rise) & np.array([not t for t in typology.tolist()], bool)
        typology[low] = self.p.low_rise_typology
        # counts only: a run on several workers sums the reports of its chunks of lots
        report = {"lots_fitted": int(fitted.sum()), "low_rise_lots": int(low.sum())}
        log.info(
            "%s: %d of %d lots take the storeys of the map's buildings around them",
            self.where,
            report["lots_fitted"],
            n,
        )
        return NodeResult({"lots": lots.with_columns(floors=floors, typology=typology)}, report)

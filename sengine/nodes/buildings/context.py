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

A map that holds streets and no buildings (whole Liège's street network,
say) leaves only the streets as evidence, and they say a good deal: a
compact town quarter has at least 18 km of street per km² around it
(UN-Habitat's first principle of neighbourhood planning [2]_), a village
road through fields a few.  With the ``roads`` input, a lot that no map
building fits gets, by this street grain within ``grain_radius``
(:func:`sengine.geom.grain.street_density`; motorways and trunk roads,
which nothing fronts, left out): under ``rural_grain``, ``rural_floors``
and ``rural_typology`` (detached houses); from there up to
``urban_grain``, ``town_floors`` and ``low_rise_typology`` (terraced
rows) or, with a chance falling linearly from one at ``rural_grain`` to
none at ``urban_grain`` (drawn per lot from the seed, the node id and the
lot id), a house as under ``rural_grain``: suburbs of detached and
semi-detached houses run into the rows of a town centre; from
``urban_grain`` up, ``urban_floors`` and ``urban_typology`` (a town centre
of three-storey town houses and small blocks of flats in perimeter blocks:
bars, L's and U courts, no towers; 0 and empty leave the node's parameters
and the height map).  Houses and terraces are shallower than blocks of
flats: ``house_depth`` (10 m) becomes their lots' ``building_depth`` rule
column.  Wallonia's houses (Statbel, 1 January 2018) stand on a median
ground area of about 81 m² terraced, 99 m² semi-detached and over 104 m²
detached [4]_; a 14 m deep terrace on an 8 m plot (112 m²) is a third too
large.  Nor are two houses alike: each house lot (rural, and the houses
among the rows) draws its own ground area, log-normal about ``house_area``
with ``house_spread`` (drawn from the seed, the node id and the lot id),
and takes it as a house 1.2 times wider than deep (``house_width`` and
``building_depth``).  Statbel's classes for Wallonia's detached houses
(1.6 % under 65 m², 20.8 % under 104 m²) fix both: a median of 138 m² and
a spread of 0.35.  The lots carry the grain as a ``grain`` column (km/km²).
Nor is every rural road lined with houses: villages cluster round the
streets they live on, and the roads between them cross fields.  OpenStreetMap
says which is which: ``highway=residential`` (with ``living_street`` and
``pedestrian``) marks a street "used for accessing residential areas and in
residential areas", ``unclassified`` and the classes above it the roads that
link settlements [3]_.  So under ``rural_grain`` a lot farther than
``village_reach`` from any street lived on is open land: it carries
``open`` and ``buildings.massing`` leaves it unbuilt.  A map that names no
such street (untagged or generated roads) builds every lot, as before.
The defaults were read off the shipped extracts: the six- to eight-storey
perimeter blocks of Helsinki's centre have a median grain of 17 and Monaco
16, whole Liège's lots a median of 8 (quartiles 5.7 and 11.4;
its villages about 4); so 14 and 8.  With them, the fabrics of
``blocks.grain`` (town houses' plots in the urban grain), the house depth and
the urban storeys, whole Liège's street
network (no buildings) houses 1.03 million in the planning report instead of
5.3 million (every lot built), where its streets serve about 530 km², about
the size of the arrondissement of Liège (628,381 inhabitants on 796 km²,
Statbel, 1 January 2024): still some 1.6 times too many, with every floor
counted as homes.

References
----------
.. [1] Baugesetzbuch (BauGB, German Federal Building Code), §34 (1): projects
   within built-up areas, version of 3 November 2017 (BGBl. I S. 3634).
.. [2] UN-Habitat, "A new strategy of sustainable neighbourhood planning:
   five principles", Urban Planning Discussion Note 3, United Nations Human
   Settlements Programme, Nairobi, 2014.
.. [3] OpenStreetMap Wiki, "Tag:highway=residential" and
   "Tag:highway=unclassified", https://wiki.openstreetmap.org (read November 2026).
.. [4] Statbel (Statistics Belgium), building stock on 1 January 2018: houses
   by type (closed, half-open, open building) and built ground area (under
   45 m², 45-64, 65-104, over 104 m²), https://bestat.statbel.fgov.be (read
   November 2026).  Wallonia: terraced 30,166 / 102,501 / 190,335 / 95,589;
   semi-detached 10,193 / 48,602 / 142,577 / 166,919; detached 1,638 / 6,263 /
   97,232 / 400,878.
"""

from __future__ import annotations

import logging

import numpy as np
import shapely

from sengine import Layer, NodeResult, Param, Port, SENode, register
from sengine.errors import InputDataError, ParameterError
from sengine.geom.grain import street_density
from sengine.random import normal, uniform

from ..blocks.grain import FABRICS, GRAIN_PARAMS, NO_FRONTAGE, check_bands, fabric_of
from .typology import TYPOLOGIES, parse_choices

__all__ = ["neighbour_floors", "open_land", "BuildingsContext"]

log = logging.getLogger(__name__)

#: ``height_source`` values of map buildings whose storeys the map states (not the reader's default).
TAGGED = ("height", "levels")
#: Road classes of streets people live on (OSM: ``highway=residential`` is "used for accessing
#: residential areas and in residential areas", ``unclassified`` and above link settlements [3]_).
LIVED_ON = ("residential", "living_street", "pedestrian")
#: A detached house's width along the street to its depth: a little wider than deep (12 x 10 m at 120 m²).
HOUSE_ASPECT = 1.2


def open_land(sites: np.ndarray, lived_on: np.ndarray, reach: float) -> np.ndarray:
    """Whether each site lies farther than ``reach`` from every street in ``lived_on``.

    Parameters
    ----------
    sites : numpy.ndarray, shape (n, 2)
        Points of the lots (m).
    lived_on : numpy.ndarray of shapely geometries
        Centre lines of the streets people live on (m).
    reach : float
        Farthest a village's houses stand from one of its streets (m).

    Returns
    -------
    numpy.ndarray of bool, shape (n,)
        True for the sites no such street reaches (all of them when there is none).
    """
    far = np.ones(len(sites), bool)
    if len(sites) and len(lived_on):
        near, _ = shapely.STRtree(lived_on).query(shapely.points(sites), predicate="dwithin", distance=reach)
        far[near] = False
    return far


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
    """Storeys and typologies for the lots from the map's buildings and streets around them (BauGB §34)."""

    name = "buildings.context"
    maps_features = True
    inputs = {
        "lots": Port("lots", "lots to build on"),
        "existing": Port(
            "buildings", "the map's buildings with 'floors' and 'height_source' (osm.read)", required=False
        ),
        "roads": Port(
            "roads", "street centre lines (with 'class'): the street grain round lots no building fits", required=False
        ),
    }
    outputs = {
        "lots": Port(
            "lots", "the lots with 'floors' and 'typology' rule columns where the map says, 'grain' and 'open'"
        )
    }
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
        **GRAIN_PARAMS,
        "town_floors": Param(
            "int", 2, min=1, max=300, unit="1", doc="storeys of the rows between rural_grain and urban_grain"
        ),
        "rural_floors": Param(
            "int", 2, min=1, max=300, unit="1", doc="storeys of the houses (under rural_grain, and in town)"
        ),
        "rural_typology": Param("str", "house", doc="typologies under rural_grain, and of the houses in town"),
        "house_depth": Param(
            "float",
            10.0,
            min=0.0,
            max=200.0,
            unit="m",
            doc="depth of the houses and terraces under urban_grain (Statbel 2018, Wallonia: median ground area"
            " about 81 m2 terraced, 99 m2 semi-detached); 0: the massing's depth",
        ),
        "house_area": Param(
            "float",
            138.0,
            min=0.0,
            max=5000.0,
            unit="m2",
            doc="median ground area of the detached houses under urban_grain, drawn log-normal per lot (Statbel 2018,"
            " Wallonia's detached houses: 1.6 % under 65 m2, 21 % under 104 m2, which a median of 138 m2 and a"
            " spread of 0.35 fit); 0: house_depth and the massing's house width",
        ),
        "house_spread": Param(
            "float", 0.35, min=0.0, max=2.0, unit="1", doc="standard deviation of the log of the houses' ground area"
        ),
        "urban_floors": Param(
            "int",
            3,
            min=0,
            max=300,
            unit="1",
            doc="storeys from urban_grain up where no map building says (a town centre of three-storey town houses"
            " and small blocks of flats); 0: the massing's parameters and the height map",
        ),
        "urban_typology": Param(
            "str", "I:4,L,U", doc="typologies from urban_grain up where no map building says (empty: by land use)"
        ),
        "village_reach": Param(
            "float",
            150.0,
            min=0.0,
            max=5000.0,
            unit="m",
            doc="under rural_grain, a lot farther than this from a street people live on (OSM residential,"
            " living_street, pedestrian) is open land, left unbuilt (0: every lot is built)",
        ),
    }

    @classmethod
    def check_params(cls, values, where):
        """The declared checks, and the typologies read as ``buildings.massing`` will read them."""
        p = super().check_params(values, where)
        for name in ("low_rise_typology", "rural_typology", "urban_typology"):
            if name == "urban_typology" and not p.urban_typology:  # empty: by land use
                continue
            try:
                parse_choices(getattr(p, name), TYPOLOGIES, what="typology")
            except ValueError as exc:
                raise ParameterError(f"{name}: {exc}", where=where) from None
        return check_bands(p, where)

    def run(self, *, lots: Layer, existing: Layer | None = None, roads: Layer | None = None) -> NodeResult:
        p = self.p
        n = len(lots)
        floors = np.full(n, np.nan)
        sites = shapely.get_coordinates(shapely.point_on_surface(lots.geometry)) if n else np.zeros((0, 2))
        if existing is not None and len(existing) and n and "floors" in existing:
            src = np.asarray(existing.get("height_source", np.full(len(existing), "levels")), dtype=str)
            tagged = np.isin(src, TAGGED)
            pts = shapely.get_coordinates(shapely.point_on_surface(existing.geometry[tagged]))
            floors = neighbour_floors(
                sites,
                pts,
                np.asarray(existing["floors"])[tagged],
                k=p.neighbours,
                radius=p.radius,
                min_count=p.min_neighbours,
            )
            floors = np.where(np.isfinite(floors), np.maximum(np.rint(floors), 1.0), np.nan)
        if "floors" in lots:  # a lot's own rule column wins
            own = np.asarray(lots["floors"], np.float64)
            floors = np.where(np.isfinite(own) & (own > 0), own, floors)
        fitted = np.isfinite(floors)
        typology = np.asarray(lots.get("typology", np.full(n, "", dtype=object)), dtype=object).copy()
        untyped = ~typology.astype(bool)
        low = fitted & (floors <= p.low_rise) & untyped
        typology[low] = p.low_rise_typology
        columns = {}
        rural = town = house = fields = np.zeros(n, bool)
        fabric = np.asarray(lots["fabric"], str) if "fabric" in lots and n else None
        kind = np.asarray(roads.get("class", np.full(len(roads), "")), dtype=str) if roads is not None else None
        if fabric is not None or (roads is not None and n):
            if fabric is not None:  # the block's fabric (blocks.grain) decided its lots' size: follow it
                grain = np.asarray(lots["grain"], np.float64)
                names, code = np.unique(fabric, return_inverse=True)
                unknown = sorted(set(names.tolist()) - set(FABRICS))
                if unknown:
                    raise InputDataError(
                        f"lots carry fabric {unknown[0]!r}, not one of {', '.join(FABRICS)}", where=self.where
                    )
                code = np.array([FABRICS.index(f) for f in names], np.int64)[code.reshape(-1)]
            else:
                grain = street_density(roads.geometry[~np.isin(kind, NO_FRONTAGE)], sites, p.grain_radius)
                # from the village to the town centre detached houses give way to rows: a town lot is a
                # house with the chance its grain is short of urban_grain (all at rural_grain, none at urban)
                u = uniform(self.context.seed, f"{self.id}/town-house", lots.ids)
                code = fabric_of(grain, u, p.rural_grain, p.urban_grain)
            rural = ~fitted & (code == FABRICS.index("rural"))
            house = ~fitted & (code == FABRICS.index("houses"))
            rows = ~fitted & (code == FABRICS.index("rows"))
            urban = ~fitted & (code == FABRICS.index("urban"))
            town = house | rows
            floors[rural | house], floors[rows] = p.rural_floors, p.town_floors
            typology[(rural | house) & untyped] = p.rural_typology
            typology[rows & untyped] = p.low_rise_typology
            if p.urban_floors:  # a lot's own floors (a rule column) stay: it is fitted
                floors[urban] = p.urban_floors
            if p.urban_typology:
                typology[urban & untyped] = p.urban_typology
            if p.house_depth or p.house_area:  # houses and terraces are shallower than blocks of flats
                depth = np.asarray(lots.get("building_depth", np.full(n, np.nan)), np.float64).copy()
                free = ~(depth > 0)
                if p.house_depth:
                    depth[(rural | town) & free] = p.house_depth
                if p.house_area:  # no two houses alike: each its own ground area, as Statbel counts them
                    width = np.asarray(lots.get("house_width", np.full(n, np.nan)), np.float64).copy()
                    z = np.clip(normal(self.context.seed, f"{self.id}/house", lots.ids), -3.0, 3.0)
                    ground = p.house_area * np.exp(p.house_spread * z)
                    drawn = (rural | house) & free & ~(width > 0)
                    width[drawn] = np.sqrt(HOUSE_ASPECT * ground[drawn])
                    depth[drawn] = ground[drawn] / width[drawn]
                    columns["house_width"] = width
                columns["building_depth"] = depth
            # houses stand apart: a plot too narrow for one stays a garden rather than take a terrace
            siting = np.asarray(lots.get("siting", np.full(n, "", dtype=object)), dtype=object).copy()
            siting[(rural | house) & ~siting.astype(bool)] = "detached"
            columns["siting"] = siting
            lived_on = np.isin(kind, LIVED_ON) if kind is not None else np.zeros(0, bool)
            # a map that names no street lived on (untagged or synthetic roads) gives no evidence of fields
            if p.village_reach > 0 and lived_on.any() and rural.any():
                fields = rural & open_land(sites, roads.geometry[lived_on], p.village_reach)
            columns["grain"] = grain
            columns["open"] = fields
        # counts only: a run on several workers sums the reports of its chunks of lots
        report = {
            "lots_fitted": int(fitted.sum()),
            "low_rise_lots": int(low.sum()),
            "rural_lots": int(rural.sum()),
            "town_lots": int(town.sum()),
            "town_houses": int(house.sum()),
            "open_lots": int(fields.sum()),
        }
        log.info(
            "%s: %d of %d lots take the storeys of the map's buildings around them, %d rural and %d town ones"
            " those of the street grain; %d are open land",
            self.where,
            report["lots_fitted"],
            n,
            report["rural_lots"],
            report["town_lots"],
            report["open_lots"],
        )
        return NodeResult({"lots": lots.with_columns(floors=floors, typology=typology, **columns)}, report)

"""Statistics: shape columns, and the planning indicators of what was built.

:class:`StatsShape` adds area, perimeter, frontage and depth columns.
``frontage`` is the street-facing boundary length: the lots' own
``frontage`` column when present (computed against their block by the lot
nodes), else the exterior length (a block faces the street all round).
``depth`` is the extent perpendicular to the street: across the lot's
``front_angle`` direction when present, else the short side of the
oriented bounding box.

:class:`StatsPlanning` reports what a planner asks of a city (papers-digest
§10; paper 000 §5.2.4, paper 003 §5.2): per lot, block, district and for
the whole city the built footprint, the gross floor area (GFA: footprint
times floors), the floor area ratio (FAR = GFA / site area), the coverage
(footprint / site area) and the residents the floor area would house
(residential floor area / 50 m2 when the buildings carry a ``use``, the
floor area of unknown use counted as housing in the share the known uses
have, :func:`housing_floor_area`; all of it when no building has a use) with the retail floor area they demand (2.7 m2 each, 000
§5.2.4).  A building is counted on the lots it stands on, in proportion to
the area it covers there: a real building across two lots counts on each
with its part, so no building counts for more than its lots hold.  The
``walls`` section gives the share of the buildings' outline that is party
wall (shared with another building) and the share of the lots' street
fronts a building stands on (:mod:`sengine.nodes.buildings.walls`).

References
----------
The reported indicators (GFA, FAR, coverage, residents) follow [1]_ §5.2.4 and the coverage limits of [2]_ §5.2; FAR and coverage as in [3]_.

.. [1] J. Viinikka, "Procedural modelling as an urban-planning tool", Master's
   thesis, Aalto University, Espoo, 2014 (paper 000).
.. [2] V. Potočková, "Procedural generation of future urban construction according
   to rules", Bachelor's thesis, Czech Technical University in Prague, Faculty
   of Electrical Engineering, 2024 (paper 003).
.. [3] M. Zhang, J. Wu, Y. Liu, J. Zhang and G. Li, "GIS based procedural modeling
   in 3D urban design", ISPRS International Journal of Geo-Information 11(10),
   531, 2022, doi:10.3390/ijgi11100531 (paper 004).
"""

from __future__ import annotations

import logging

import numpy as np
import shapely

from sengine import Layer, NodeResult, Param, Port, SENode, register
from sengine.geom.polygons import obb_frame, shared_areas, threaded

__all__ = [
    "shape_stats",
    "building_shares",
    "built_on_sites",
    "planning_columns",
    "wall_shares",
    "StatsShape",
    "StatsPlanning",
]

log = logging.getLogger(__name__)

COVER_TOL = 1e-6  #: m: a building corner this close to its lot stands on it


def shape_stats(geoms, *, frontage=None, front_angle=None) -> dict:
    """Area (m2), perimeter (m), frontage (m) and depth (m) of each polygon.

    Parameters
    ----------
    geoms : array_like of shapely.Polygon
    frontage : array_like of float, optional
        Known street frontage (m); defaults to the exterior length.
    front_angle : array_like of float, optional
        Direction of the street front (deg); ``nan`` entries fall back to
        the oriented bounding box.
    """
    geoms = np.asarray(geoms, dtype=object)
    n = len(geoms)
    area = shapely.area(geoms) if n else np.zeros(0)
    perim = shapely.length(geoms) if n else np.zeros(0)
    if frontage is None:
        frontage = shapely.length(shapely.get_exterior_ring(shapely.get_geometry(geoms, 0))) if n else np.zeros(0)
    _, _, _, depth = obb_frame(geoms)
    if front_angle is not None and n:
        ang = np.radians(np.asarray(front_angle, np.float64))
        ok = np.isfinite(ang)
        if ok.any():
            c, ci = shapely.get_coordinates(geoms[ok], return_index=True)
            nrm = np.stack([-np.sin(ang[ok]), np.cos(ang[ok])], axis=1)
            proj = np.einsum("ij,ij->i", c, nrm[ci])
            hi = np.full(int(ok.sum()), -np.inf)
            lo = np.full(int(ok.sum()), np.inf)
            np.maximum.at(hi, ci, proj)
            np.minimum.at(lo, ci, proj)
            depth = depth.copy()
            depth[ok] = hi - lo
    return {"area": area, "perimeter": perim, "frontage": np.asarray(frontage, np.float64), "depth": depth}


@register
class StatsShape(SENode):
    """Add area (m2), perimeter, frontage and depth (m) columns."""

    name = "stats.shape"
    inputs = {"input": Port("any", "polygons: blocks, lots ...")}
    outputs = {"output": Port("any", "the same features with the new columns")}
    params = {}
    maps_features = True

    def run(self, *, input: Layer) -> tuple[dict[str, Layer], dict]:
        st = shape_stats(input.geometry, frontage=input.get("frontage"), front_angle=input.get("front_angle"))
        report = {"features": len(input), "area": float(st["area"].sum()), "frontage": float(st["frontage"].sum())}
        return NodeResult({"output": input.with_columns(**st)}, report)


def building_shares(sites: Layer, buildings: Layer) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Which building stands on which site, and with how much of its footprint (m2).

    Returns ``(building, site, area)`` index and area arrays, one entry per
    (building, site) pair that share ground.  A building inside the site its
    ``lot`` column names (every generated one) takes one ``covers`` test,
    or, where a cut out of the lot left a corner a rounding off its edge,
    a test of its corners (within :data:`COVER_TOL`); the others (real
    buildings across lots, or on none) are intersected with every site they touch.
    """
    geoms = buildings.geometry
    site = sites.rows_of(buildings["lot"]) if "lot" in buildings else np.full(len(buildings), -1, np.int64)
    inside = site >= 0
    inside[inside] = threaded(shapely.covers, sites.geometry[site[inside]], geoms[inside])
    near = np.flatnonzero(~inside & (site >= 0))
    if len(near):  # cut out of their lot, a rounding off its edges: every corner within COVER_TOL of it
        xy, bi = shapely.get_coordinates(geoms[near], return_index=True)
        d = shapely.distance(shapely.points(xy), sites.geometry[site[near][bi]])
        far = np.bincount(bi, weights=(d > COVER_TOL).astype(float), minlength=len(near)) > 0
        inside[near[~far]] = True
    named, rest = np.flatnonzero(inside), np.flatnonzero(~inside)
    ri, rsi, shared = shared_areas(geoms[rest], sites.geometry)
    return np.r_[named, rest[ri]], np.r_[site[named], rsi], np.r_[shapely.area(geoms[named]), shared]


def built_on_sites(sites: Layer, buildings: Layer, shares=None) -> tuple[np.ndarray, np.ndarray]:
    """Built footprint (m2) and gross floor area (m2, footprint times ``floors``) on each site.

    ``shares`` are :func:`building_shares` of the two layers (computed when not given).
    """
    bi, si, part = building_shares(sites, buildings) if shares is None else shares
    n = len(sites)
    return np.bincount(si, weights=part, minlength=n), np.bincount(
        si, weights=part * _floors(buildings)[bi], minlength=n
    )


def _floors(buildings: Layer) -> np.ndarray:
    return np.asarray(buildings.get("floors", np.ones(len(buildings))), np.float64)


def planning_columns(site_area: np.ndarray, foot: np.ndarray, gfa: np.ndarray) -> dict[str, np.ndarray]:
    """``footprint`` and ``floor_area`` (m2), ``far`` and ``coverage`` (1) of sites of the given areas."""
    with np.errstate(divide="ignore", invalid="ignore"):
        far = np.where(site_area > 0, gfa / site_area, 0.0)
        coverage = np.where(site_area > 0, foot / site_area, 0.0)
    # float even for no building at all (bincount of nothing is int64): the 'lots' kind says float
    return {
        "footprint": np.asarray(foot, np.float64),
        "floor_area": np.asarray(gfa, np.float64),
        "far": far,
        "coverage": coverage,
    }


#: Land uses whose floor area houses residents (the others are jobs, shops, schools ...).
HOUSING = ("residential", "mixed")
RETAIL_PER_RESIDENT = 2.7  #: m2 of retail floor area a resident demands (000 §5.2.4, Statistics Finland)


def housing_floor_area(uses: np.ndarray, floor_area: np.ndarray, site: np.ndarray, n_sites: int):
    """Residential floor area per site, and the share of the unknown-use floor area counted as housing.

    A building of no known use (``""``: OpenStreetMap's ``building=yes``)
    houses residents in the proportion the city's buildings of known use do:
    its floor area times residential / known floor area (1 when no
    building has a known use, so that a city of untagged buildings counts
    all of it, as before).

    Parameters
    ----------
    uses : numpy.ndarray of str
        Land use of each (building, site) piece.
    floor_area : numpy.ndarray of float
        Floor area of each piece (m2).
    site : numpy.ndarray of int
        Row of each piece's site (lot).
    n_sites : int
        Number of sites.
    """
    home = np.isin(uses, HOUSING)
    unknown = uses == ""
    known = float(floor_area[~unknown].sum())
    share = float(floor_area[home].sum()) / known if known > 0 else 1.0
    weight = np.where(home, 1.0, 0.0) + np.where(unknown, share, 0.0)
    return np.bincount(site, weights=floor_area * weight, minlength=n_sites), share


def _summary(site_area, foot, gfa, m2_per_resident: float, housing=None) -> dict:
    a, f, g = float(np.sum(site_area)), float(np.sum(foot)), float(np.sum(gfa))
    h = g if housing is None else float(np.sum(housing))
    residents = int(h // m2_per_resident)
    return {
        "site_area_m2": round(a, 1),
        "footprint_m2": round(f, 1),
        "floor_area_m2": round(g, 1),
        "far": round(g / a, 4) if a > 0 else 0.0,
        "coverage": round(f / a, 4) if a > 0 else 0.0,
        "residents": residents,
        "retail_demand_m2": round(residents * RETAIL_PER_RESIDENT, 1),
    }


def wall_shares(lots: Layer, buildings: Layer, blocks: Layer | None = None) -> dict:
    """Party-wall share of the buildings' outlines and street-wall share of the built lots' fronts."""
    from sengine.nodes.buildings.edges import FRONT, lot_edges
    from sengine.nodes.buildings.walls import party_walls, street_walls

    polys = shapely.get_type_id(buildings.geometry) == 3 if len(buildings) else np.zeros(0, bool)
    g = buildings.geometry[polys]
    if len(g) == 0 or len(lots) == 0:
        return {}
    perimeter = shapely.length(g)
    share = party_walls(g) / np.maximum(perimeter, 1e-12)
    owner = blocks.rows_of(lots["block"]) if blocks is not None and "block" in lots else None
    e = lot_edges(lots.geometry, blocks=None if owner is None else blocks.geometry, owner=owner)
    f = e.kind == FRONT
    rows = lots.rows_of(buildings["lot"][polys]) if "lot" in buildings else np.full(len(g), -1)
    on = street_walls(g, rows, (e.p0[f], e.p1[f], e.lot[f]))
    has = rows >= 0
    front = np.bincount(e.lot[f], weights=np.hypot(*(e.p1[f] - e.p0[f]).T), minlength=len(lots))
    built = np.unique(rows[has])
    built = built[front[built] > 0]
    lot_on = np.bincount(rows[has], weights=on[has], minlength=len(lots))
    street = lot_on[built] / front[built]
    return {
        "party_wall_share_median": round(float(np.median(share)), 4),
        "party_wall_share_mean": round(float(np.mean(share)), 4),
        "buildings_with_party_walls": round(float((share > 0).mean()), 4),
        "street_wall_share_median": round(float(np.median(street)), 4) if len(street) else 0.0,
        "street_wall_share_mean": round(float(np.mean(street)), 4) if len(street) else 0.0,
    }


#: Park levels that lie outside the blocks (district parks are cut out of the city, block parks replace blocks).
OUTSIDE_BLOCKS = ("district", "block")


def open_space(land: Layer, parks: Layer | None, trees: Layer | None, report: dict) -> dict:
    """Parks' area and share of the land, trees per km2 and per resident, for the city and each district.

    The land is the blocks plus the parks that are not on them (district and
    block levels); lot parks and patios lie on blocks and count within them.
    ``report`` holds the residents (city and ``districts``).
    """
    parks = parks if parks is not None else Layer.empty()
    trees = trees if trees is not None else Layer.empty()
    p_area = shapely.area(parks.geometry) if len(parks) else np.zeros(0)
    level = np.asarray(parks["level"]).astype(str) if "level" in parks and len(parks) else np.full(len(parks), "")
    p_dist = np.asarray(parks["district"], np.int64) if "district" in parks else np.full(len(parks), -1)
    l_area = shapely.area(land.geometry) if len(land) else np.zeros(0)
    l_dist = np.asarray(land["district"], np.int64) if "district" in land else np.full(len(land), -1)
    t_dist = np.asarray(trees["district"], np.int64) if "district" in trees else np.full(len(trees), -1)

    def summary(pm, lm, tm, residents) -> dict:
        land_m2 = float(l_area[lm].sum() + p_area[pm & np.isin(level, OUTSIDE_BLOCKS)].sum())
        park_m2 = float(p_area[pm].sum())
        n = int(tm.sum())
        out = {
            "land_m2": round(land_m2, 1),
            "park_m2": round(park_m2, 1),
            "park_share": round(park_m2 / land_m2, 4) if land_m2 > 0 else 0.0,
            "parks_by_level_m2": {
                lv: round(float(p_area[pm & (level == lv)].sum()), 1) for lv in np.unique(level[pm]).tolist()
            },
            "trees": n,
            "trees_per_km2": round(n / (land_m2 / 1e6), 1) if land_m2 > 0 else 0.0,
            "trees_per_resident": round(n / residents, 4) if residents else 0.0,
        }
        if n and "zone" in trees:
            z = np.asarray(trees["zone"]).astype(str)[tm]
            out["trees_by_zone"] = {str(k): int(v) for k, v in zip(*np.unique(z, return_counts=True))}
        return out

    city = summary(
        np.ones(len(parks), bool), np.ones(len(land), bool), np.ones(len(trees), bool), report["city"]["residents"]
    )
    districts = {}
    for d in sorted(set(p_dist.tolist()) | set(l_dist.tolist())):
        if d < 0:
            continue
        res = report.get("districts", {}).get(str(d), {}).get("residents", 0)
        districts[str(d)] = summary(p_dist == d, l_dist == d, t_dist == d, res)
    return {"city": city, "districts": districts}


@register
class StatsPlanning(SENode):
    """Footprint, gross floor area, FAR, coverage and residents per lot, block, district and city."""

    name = "stats.planning"
    inputs = {
        "lots": Port("lots", "lots: the sites"),
        "buildings": Port("buildings", "buildings with a floors column"),
        "blocks": Port(
            "blocks", "blocks, for block-level figures (a lot's 'block' column names its block)", required=False
        ),
        "parks": Port("parks", "parks of every level: area and share per district and city", required=False),
        "vegetation": Port("vegetation", "trees: per km2 and per resident", required=False),
    }
    outputs = {
        "lots": Port("lots", "the lots with footprint, floor_area (m2), far and coverage columns"),
        "blocks": Port(
            "blocks", "the blocks with the same columns, for what stands on their lots (empty without blocks)"
        ),
    }
    params = {
        "m2_per_resident": Param(
            "float",
            50.0,
            min=1.0,
            max=1000.0,
            unit="m2",
            doc="gross floor area per resident (residential floor area; all of it when buildings carry no use)",
        ),
        "walls": Param(
            "bool",
            False,
            doc="report party-wall and street-wall shares of the buildings (some seconds on a whole city)",
        ),
    }

    def run(
        self,
        *,
        lots: Layer,
        buildings: Layer,
        blocks: Layer | None = None,
        parks: Layer | None = None,
        vegetation: Layer | None = None,
    ) -> tuple[dict[str, Layer], dict]:
        from functools import partial

        from sengine.parallel import run_jobs

        # the wall shares are only reported: with workers, a second process measures them meanwhile
        jobs = [partial(self._planning, lots, buildings, blocks, parks, vegetation)]
        if self.p.walls:
            jobs.append(partial(wall_shares, lots, buildings, blocks))
        done = run_jobs(jobs, int(getattr(self.context, "workers", 1) or 1))
        layers, report = done[0]
        if self.p.walls:
            report["walls"] = done[1]
        return NodeResult(layers, report)

    def _planning(
        self, lots: Layer, buildings: Layer, blocks: Layer | None, parks: Layer | None, vegetation: Layer | None
    ) -> tuple[dict[str, Layer], dict]:
        """The planning columns and the report (``walls`` left as ``None``, in its place)."""
        per_resident = self.p.m2_per_resident
        lot_area = shapely.area(lots.geometry) if len(lots) else np.zeros(0)
        shares = building_shares(lots, buildings)
        foot, gfa = built_on_sites(lots, buildings, shares)
        housing = None
        uses = None
        if "use" in buildings and len(buildings):  # residents live in residential floor area only
            bi, si, part = shares
            uses = np.asarray(buildings["use"]).astype(str)
            floor_area = part * _floors(buildings)[bi]
            housing, unknown_share = housing_floor_area(uses[bi], floor_area, si, len(lots))
        out_lots = lots.with_columns(**planning_columns(lot_area, foot, gfa))
        all_foot = float(shapely.area(buildings.geometry).sum()) if len(buildings) else 0.0
        report = {
            "city": _summary(lot_area, foot, gfa, per_resident, housing),
            "buildings": len(buildings),
            "footprint_off_lots_m2": round(max(all_foot - float(foot.sum()), 0.0), 1),
        }
        if "district" in lots and len(lots):
            district = np.asarray(lots["district"], np.int64)
            report["districts"] = {
                str(d): _summary(
                    lot_area[district == d],
                    foot[district == d],
                    gfa[district == d],
                    per_resident,
                    None if housing is None else housing[district == d],
                )
                for d in np.unique(district)
            }
        if uses is not None:
            report["unknown_use_housing_share"] = round(unknown_share, 4)
            bi, _, part = shares
            floor_area = part * _floors(buildings)[bi]
            report["uses"] = {
                str(u): {
                    "buildings": int((uses == u).sum()),
                    "floor_area_m2": round(float(floor_area[uses[bi] == u].sum()), 1),
                }
                for u in np.unique(uses)
            }
        if self.p.walls:
            report["walls"] = None  # measured beside (run)
        if "source" in buildings and len(buildings):  # e.g. the map's buildings beside the generated ones
            src = np.asarray(buildings["source"]).astype(str)
            bi, _, part = shares
            floor_area = part * _floors(buildings)[bi]
            for kind in np.unique(src):
                mine = src[bi] == kind
                report[f"{kind}_buildings"] = {
                    "footprint_m2": round(float(part[mine].sum()), 1),
                    "floor_area_m2": round(float(floor_area[mine].sum()), 1),
                }
        out_blocks = Layer.empty(meta=lots.meta)
        if blocks is not None:
            if "block" in lots:  # the lots' sums: every building on a lot is on its block
                owner = blocks.rows_of(lots["block"])
                has = owner >= 0
                bf = np.bincount(owner[has], weights=foot[has], minlength=len(blocks))
                bg = np.bincount(owner[has], weights=gfa[has], minlength=len(blocks))
            else:
                bf, bg = built_on_sites(blocks, buildings)
            out_blocks = blocks.with_columns(**planning_columns(shapely.area(blocks.geometry), bf, bg))
        if parks is not None or vegetation is not None:
            report["open_space"] = open_space(blocks if blocks is not None else lots, parks, vegetation, report)
        c = report["city"]
        log.info(
            "%s: FAR %.2f, coverage %.0f %%, %.0f m2 of floor area on %.0f m2 of lots",
            self.where,
            c["far"],
            100 * c["coverage"],
            c["floor_area_m2"],
            c["site_area_m2"],
        )
        return {"lots": out_lots, "blocks": out_blocks}, report

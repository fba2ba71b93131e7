"""Buildings: one extruded footprint per lot, its height from the height map.

skylineEngine hands each lot to its buildingEngine (paper 002 §5.6) and lets
a greyscale **height map** control the skyline of the whole city (002 §5.2,
Fig. 5).  This module is the simple, fast end of that: one building per lot,
its footprint the lot inset by a setback, a flat roof, a height read from the
height map at the lot centroid with a seeded random variation, snapped to a
whole number of floors.  Buildings stay light (footprint plus attributes)
until an exporter turns them into meshes (``sengine.nodes.export.mesh``).

References
----------
.. [1] skylineEngine (paper 002), §5.2 (height map) and §5.6 (buildingEngine).
.. [2] Prague building regulations (paper 003), §3.2: storey height at least
   2.6 m.
"""

from __future__ import annotations

import logging

import numpy as np
import shapely

from sengine import Layer, NodeResult, Param, Port, SENode, register
from sengine.random import uniform

from ..maps import image_of

__all__ = [
    "inset_footprints",
    "snap_floors",
    "sample_height_map",
    "mapped_heights",
    "HEIGHT_PARAMS",
    "BuildingsExtrude",
]

log = logging.getLogger(__name__)


def inset_footprints(lots: np.ndarray, setback: float, *, min_area: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Footprints: each lot shrunk by ``setback`` on every side.

    Parameters
    ----------
    lots : array of Polygon
        Lot polygons (m).
    setback : float
        Inset distance (m); mitre joins keep rectilinear corners square.
    min_area : float
        Footprints smaller than this (m2) are dropped.

    Returns
    -------
    footprints : array of Polygon
        One per kept lot; when the inset splits a lot, its largest part.
    keep : numpy.ndarray of bool
        Which lots got a footprint.
    """
    lots = np.asarray(lots, dtype=object)
    if len(lots) == 0:
        return lots, np.zeros(0, bool)
    inset = shapely.buffer(lots, -float(setback), join_style="mitre") if setback > 0 else lots
    parts, idx = shapely.get_parts(inset, return_index=True)
    polys = shapely.get_type_id(parts) == 3
    parts, idx = parts[polys], idx[polys]
    area = shapely.area(parts)
    # largest part of each lot: sort by (lot, -area), take the first of each lot
    order = np.lexsort((-area, idx))
    first = np.ones(len(order), bool)
    first[1:] = idx[order][1:] != idx[order][:-1]
    best = order[first]
    ok = area[best] >= max(min_area, 1e-9)
    best = best[ok]
    keep = np.zeros(len(lots), bool)
    keep[idx[best]] = True
    footprints = np.empty(len(best), dtype=object)
    footprints[:] = list(parts[best])
    return footprints, keep


def existing_heights(points: np.ndarray, existing: Layer) -> np.ndarray:
    """Height (m) of the tallest tagged existing building containing each point; NaN for none.

    Only heights read from the data count (``height_source`` not
    ``"default"``), so a lot keeps the height map where the map is all there is.
    """
    out = np.full(len(points), np.nan)
    if existing is None or not len(existing) or "height" not in existing.attrs:
        return out
    tagged = np.isfinite(existing["height"])
    if "height_source" in existing.attrs:
        tagged &= existing["height_source"].astype(str) != "default"
    if not tagged.any():
        return out
    geoms, heights = existing.geometry[tagged], existing["height"][tagged]
    point_i, building_i = shapely.STRtree(geoms).query(points, predicate="within")
    np.fmax.at(out, point_i, heights[building_i])
    return out


def snap_floors(
    height: np.ndarray, floor_height: float, lo: float | None = None, hi: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Round heights to whole floors, staying within ``[lo, hi]`` where possible.

    Returns ``height = floors * floor_height`` (m) and ``floors`` (at least 1).
    """
    fh = float(floor_height)
    floors = np.rint(np.asarray(height, np.float64) / fh).astype(np.int64)
    fmin = 1 if lo is None else max(1, int(np.ceil(lo / fh - 1e-9)))
    fmax = None if hi is None else max(fmin, int(np.floor(hi / fh + 1e-9)))
    floors = np.clip(floors, fmin, fmax)
    return floors * fh, floors


def sample_height_map(height_map: Layer | None, x: np.ndarray, y: np.ndarray):
    """Heights (m) from the height map at points, with the map's min and max.

    Parameters
    ----------
    height_map : Layer or None
        The ``raster`` layer of ``maps.image`` for ``<map kind="height">``:
        its decoded grey image and its ``min`` / ``max`` (m, checked there).
    x, y : ndarray
        Points (m, the city's planar frame).

    Returns
    -------
    tuple of (ndarray, float, float) or None
        Black is ``min``, white is ``max`` (bilinear between pixel centres);
        ``None`` when the city has no height map.
    """
    image = image_of(height_map)
    if image is None:
        return None
    lo, hi = float(height_map["min"][0]), float(height_map["max"][0])
    return image.scaled(x, y, lo, hi), lo, hi


def mapped_heights(height_map, points, ids, *, seed, key: str, height: float, variation: float):
    """Heights (m) the height map asks for at ``points``, with a seeded variation; and the map's range.

    ``h = base x (1 + variation x (2u - 1))`` with ``base`` the height map
    at each point (``height`` without a map) and ``u`` uniform from
    ``(seed, key, id)`` (independent of batching), kept within the map's
    ``[min, max]`` (002 §5.2).

    Returns
    -------
    tuple of (ndarray, float or None, float or None)
        Heights and the map's ``min`` and ``max`` (``None`` without a map).
    """
    n = len(ids)
    sampled = sample_height_map(height_map, shapely.get_x(points), shapely.get_y(points)) if n else None
    base, lo, hi = (np.full(n, height), None, None) if sampled is None else sampled
    u = uniform(seed, key, ids)
    raw = base * (1.0 + variation * (2.0 * u - 1.0))
    return (raw if lo is None else np.clip(raw, lo, hi)), lo, hi


#: The height parameters every building node shares.
HEIGHT_PARAMS = {
    "height": Param(
        "float", 15.0, min=1.0, max=1000.0, unit="m", doc="building height when the city has no height map"
    ),
    "variation": Param(
        "float", 0.2, min=0.0, max=0.95, unit="1", doc="random height variation, a fraction of the mapped height (+/-)"
    ),
    "floor_height": Param(
        "float",
        3.2,
        min=2.6,
        max=10.0,
        unit="m",
        doc="storey height; heights snap to whole floors (at least 2.6 m, paper 003)",
    ),
}


@register
class BuildingsExtrude(SENode):
    """One flat-roofed building per lot: lot inset by a setback, height from the height map.

    Height: the tagged height of an existing building (optional input
    ``existing``, e.g. OSM buildings) containing the lot centroid; else the
    height map at the lot centroid (or ``height`` when the plan has none), times ``1 + variation * (2u - 1)`` with ``u`` a uniform number
    hashed from (seed, node id, lot id), kept within the map's range and
    snapped to whole floors of ``floor_height``.  Lots whose inset footprint
    is under ``min_area`` get no building; the count is reported as
    ``skipped``.  Lots marked ``inner`` (the courtyards of Paris blocks,
    §5.5) stay open unless ``courtyards`` is set; their count is reported as
    ``courtyards``.  Building ids are the lot ids.
    """

    name = "buildings.extrude"
    inputs = {
        "lots": Port("lots", "lots to build on"),
        "existing": Port(
            "buildings", "buildings already there (OSM): a lot inside one takes its tagged height", required=False
        ),
        "height_map": Port(
            "raster", "the height map (<map kind='height'>); none: every building 'height'", required=False
        ),
    }
    outputs = {"buildings": Port("buildings", "footprints with height, floors, roof, lot, district")}
    params = {
        "setback": Param("float", 2.0, min=0.0, max=50.0, unit="m", doc="inset of the footprint from every lot edge"),
        **HEIGHT_PARAMS,
        "min_area": Param("float", 20.0, min=0.0, unit="m2", doc="footprints smaller than this are not built"),
        "courtyards": Param("bool", False, doc="also build on inner lots (courtyards with no street frontage)"),
    }
    maps_features = True

    def run(self, *, lots: Layer, existing: Layer | None = None, height_map: Layer | None = None) -> NodeResult:
        p = self.p
        footprints, keep = inset_footprints(lots.geometry, p.setback, min_area=p.min_area)
        open_court = np.zeros(len(lots), bool)
        if not p.courtyards and "inner" in lots.attrs:
            open_court = lots["inner"].astype(bool) & keep
            footprints = footprints[~open_court[keep]]
            keep = keep & ~open_court
        ids = lots.ids[keep]
        skipped = int(len(lots) - keep.sum() - open_court.sum())
        c = shapely.centroid(lots.geometry[keep]) if len(ids) else np.empty(0, object)
        raw, lo, hi = mapped_heights(
            height_map, c, ids, seed=self.context.seed, key=f"{self.id}/height", height=p.height, variation=p.variation
        )
        known = existing_heights(c, existing) if existing is not None and len(ids) else np.full(len(ids), np.nan)
        surveyed = np.isfinite(known)
        height, floors = snap_floors(raw, p.floor_height, lo, hi)
        if surveyed.any():  # a surveyed height is kept as it is, whatever the map's range
            height[surveyed], floors[surveyed] = snap_floors(known[surveyed], p.floor_height)
        district = lots["district"][keep] if "district" in lots.attrs else np.full(len(ids), -1, np.int64)
        out = Layer(
            footprints,
            ids.copy(),
            ids.copy(),
            {
                "height": height.astype(np.float64),
                "floors": floors.astype(np.int64),
                "roof": np.full(len(ids), "flat"),
                "lot": ids.astype(np.int64),
                "district": np.asarray(district),
            },
            dict(lots.meta),
        )
        report = {
            "buildings": int(len(ids)),
            "skipped": skipped,
            "courtyards": int(open_court.sum()),
            "surveyed_heights": int(surveyed.sum()),
        }
        if skipped:
            log.info(
                "%s: %d lots too small for a %.3g m setback and %.3g m2 footprint",
                self.where,
                skipped,
                p.setback,
                p.min_area,
            )
        return NodeResult({"buildings": out}, report)

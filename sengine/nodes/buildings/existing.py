"""Existing buildings: the real footprints of the map stand, generated ones fill the rest.

A real city's map often holds its buildings too (OSM ``building=*`` with
``height`` or ``building:levels``, read by ``osm.read``).  As a CityEngine or
osmnx user expects from an OSM import, those footprints are kept as they
are, extruded to their tagged height (or the reader's default), and the
engine builds only where the map has nothing: a generated building that
would overlap an existing one is not built.  What is left is one buildings
layer with a ``source`` column (``"osm"`` or ``"generated"``), so every
exporter, the preview and the report take both alike.

``keep`` chooses the layer for the study at hand: ``both`` (the default: the
city as it is, completed), ``existing`` (the map's buildings only) or
``generated`` (the engine's envelope on every lot, as a capacity study
wants; the map's buildings are left out).

References
----------
skylineEngine (paper 002), §5.2 (real maps as input) and §5.6 (buildings).
"""

from __future__ import annotations

import logging

import numpy as np
import shapely

from sengine import Layer, NodeResult, Param, Port, SENode, register
from sengine.errors import InputDataError
from sengine.geom.polygons import largest_share, shared_areas

__all__ = ["overlap_areas", "map_buildings", "BuildingsExisting"]

log = logging.getLogger(__name__)

#: Storey height (m) for existing buildings that come with a height but no floors.
FLOOR_HEIGHT = 3.2


def overlap_areas(geoms, others) -> np.ndarray:
    """Area (m2) of each of ``geoms`` covered by ``others`` (summed over them).

    ``others`` are assumed not to overlap each other much (buildings): a
    part covered twice counts twice, which only errs on the side of "covered".
    """
    gi, _, area = shared_areas(geoms, others)
    return np.bincount(gi, weights=area, minlength=len(geoms))


def map_buildings(real: Layer, lots: Layer | None, first_id: int) -> Layer:
    """The map's buildings as a buildings layer, ids from ``first_id`` on.

    Each takes the lot holding most of its footprint (``lot`` and the
    parent id; ``-1`` on none) and that lot's ``district``; ``floors`` come
    from the map or from the height at :data:`FLOOR_HEIGHT` a storey.
    """
    n = len(real)
    lot_i = largest_share(real.geometry, lots.geometry) if lots is not None else np.full(n, -1, np.int64)
    has = lot_i >= 0
    lot = np.full(n, -1, np.int64)
    district = np.full(n, -1, np.int64)
    if has.any():
        lot[has] = lots.ids[lot_i[has]]
        if "district" in lots:
            district[has] = np.asarray(lots["district"], np.int64)[lot_i[has]]
    height = np.asarray(real["height"], np.float64)
    floors = real.get("floors", np.maximum(1, np.rint(height / FLOOR_HEIGHT)))
    cols = {
        "height": height,
        "floors": np.asarray(floors, np.int64),
        "roof": real.get("roof", np.full(n, "flat", dtype=object)),
        "roof_height": real.get("roof_height", np.full(n, np.nan)),
        "lot": lot,
        "district": district,
        "source": np.full(n, "osm", dtype=object),
        "osm_id": real.get("osm_id", np.full(n, -1, np.int64)),
        "name": real.get("name", np.full(n, "", dtype=object)),
        "height_source": real.get("height_source", np.full(n, "height", dtype=object)),
        # the map's land use of the building (building=apartments -> residential), "" when it says none
        "use": real.get("use", np.full(n, "", dtype=object)),
    }
    return Layer(
        real.geometry,
        first_id + np.arange(n, dtype=np.int64),
        lot.copy(),
        {k: np.asarray(v) for k, v in cols.items()},
        dict(real.meta),
    )


@register
class BuildingsExisting(SENode):
    """The map's existing buildings kept, generated buildings only where they leave room (§5.2)."""

    name = "buildings.existing"
    inputs = {
        "buildings": Port("buildings", "generated buildings (e.g. buildings.extrude)"),
        "existing": Port(
            "buildings", "buildings already there, with a height column (e.g. osm.read's buildings)", required=False
        ),
        "lots": Port("lots", "lots: give each existing building the lot and district it stands in", required=False),
    }
    outputs = {
        "buildings": Port(
            "buildings",
            "existing and generated buildings, with 'source' (and the map's "
            "'osm_id', 'name', 'height_source' when it has buildings)",
        )
    }
    params = {
        "keep": Param(
            "str",
            "both",
            choices=("both", "existing", "generated"),
            doc="the existing buildings and the generated ones clear of them, or one kind only",
        ),
        "overlap": Param(
            "float",
            1.0,
            min=0.0,
            unit="m2",
            doc="a generated building overlapping existing ones by more than this is not built",
        ),
    }

    def run(self, *, buildings: Layer, existing: Layer | None = None, lots: Layer | None = None) -> NodeResult:
        real = existing if existing is not None and self.p.keep != "generated" else Layer.empty()
        if len(real) and "height" not in real:
            raise InputDataError("existing buildings carry no 'height' column", where=self.where)
        geoms = real.geometry.copy()
        bad = ~shapely.is_valid(geoms) if len(geoms) else np.zeros(0, bool)
        geoms[bad] = shapely.make_valid(geoms[bad])  # map polygons may self-touch: repair them for the overlap test
        real = real.with_geometry(geoms)
        covered = overlap_areas(buildings.geometry, geoms)
        build = covered <= self.p.overlap if self.p.keep != "existing" else np.zeros(len(buildings), bool)
        generated = buildings.take(np.flatnonzero(build))
        m, n = len(generated), len(real)
        out = generated.with_columns(source=np.full(m, "generated", dtype=object))
        on_lots = 0
        if n:  # the map's columns, for the generated ones too (a city without map buildings has no use for them)
            kept = map_buildings(real, lots, first_id=int(buildings.ids.max(initial=-1)) + 1)
            on_lots = int((kept["lot"] >= 0).sum())
            out = out.with_columns(
                osm_id=np.full(m, -1, np.int64),
                name=np.full(m, "", dtype=object),
                height_source=np.full(m, "generated", dtype=object),
            )
            out = Layer.concat([out, kept], renumber=False).with_meta(**buildings.meta)
        report = {
            "buildings": len(out),
            "existing": n,
            "generated": m,
            "not_built": len(buildings) - m,
            "existing_on_lots": on_lots,
        }
        log.info(
            "%s: %d existing buildings kept, %d of %d generated buildings clear of them",
            self.where,
            n,
            m,
            len(buildings),
        )
        return NodeResult({"buildings": out}, report)

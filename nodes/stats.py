"""Shape statistics: area, perimeter, frontage and depth columns.

``frontage`` is the street-facing boundary length: the lots' own
``frontage`` column when present (computed against their block by the lot
nodes), else the exterior length (a block faces the street all round).
``depth`` is the extent perpendicular to the street: across the lot's
``front_angle`` direction when present, else the short side of the
oriented bounding box.
"""

from __future__ import annotations

import numpy as np
import shapely

from sengine import Layer, Port, SENode, register
from sengine.geometry import obb_frame

__all__ = ["shape_stats", "StatsShape"]


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

    def run(self, *, input: Layer) -> dict[str, Layer]:
        st = shape_stats(input.geometry, frontage=input.get("frontage"), front_angle=input.get("front_angle"))
        self.report = {"features": len(input), "area": float(st["area"].sum()),
                       "frontage": float(st["frontage"].sum())}
        return {"output": input.with_columns(**st)}

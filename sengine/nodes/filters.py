"""Filters: drop features outside size bounds.

Real street graphs leave slivers (medians between dual carriageways,
traffic islands); synthetic ones leave leftovers at the city edge.  The
paper's pipeline sends every block and lot on to the next stage; these
filters let a network drop the ones too small, too large or too thin to
build on, and count them.
"""

from __future__ import annotations

import logging

import numpy as np
import shapely

from sengine import Layer, NodeResult, Param, Port, SENode, register
from sengine.geom.polygons import obb_frame

__all__ = ["size_mask", "FilterArea"]

log = logging.getLogger(__name__)


def size_mask(geoms, *, min_area=0.0, max_area=np.inf, min_width=0.0, max_width=np.inf):
    """Which geometries lie within area and width bounds.

    Parameters
    ----------
    geoms : array_like of shapely.Geometry
    min_area, max_area : float
        Inclusive area bounds (m2).
    min_width, max_width : float
        Inclusive bounds (m) on the width: the short side of the minimum
        oriented bounding box.

    Returns
    -------
    keep : ndarray of bool
    why : dict of str to int
        How many fail each bound (a feature may fail several).
    """
    geoms = np.asarray(geoms, dtype=object)
    area = shapely.area(geoms) if len(geoms) else np.zeros(0)
    _, _, _, width = obb_frame(geoms)
    tests = {
        "below_min_area": area < min_area,
        "above_max_area": area > max_area,
        "below_min_width": width < min_width,
        "above_max_width": width > max_width,
    }
    keep = np.ones(len(geoms), bool)
    for t in tests.values():
        keep &= ~t
    return keep, {k: int(v.sum()) for k, v in tests.items()}


@register
class FilterArea(SENode):
    """Drop features outside area (m2) and width (m, OBB short side) bounds."""

    name = "filter.area"
    inputs = {"input": Port("any", "polygons: blocks, lots, parks ...")}
    outputs = {"output": Port("any", "the features within the bounds")}
    params = {
        "min_area": Param("float", 0.0, min=0.0, unit="m2", doc="drop features smaller than this"),
        "max_area": Param("float", 1e12, min=0.0, unit="m2", doc="drop features larger than this"),
        "min_width": Param("float", 0.0, min=0.0, unit="m", doc="drop features thinner than this (OBB short side)"),
        "max_width": Param("float", 1e9, min=0.0, unit="m", doc="drop features wider than this (OBB short side)"),
    }
    maps_features = True

    def run(self, *, input: Layer) -> tuple[dict[str, Layer], dict]:
        keep, why = size_mask(
            input.geometry,
            min_area=self.p.min_area,
            max_area=self.p.max_area,
            min_width=self.p.min_width,
            max_width=self.p.max_width,
        )
        report = {"kept": int(keep.sum()), "dropped": int((~keep).sum()), **why}
        log.info("%s: kept %d of %d features", self.where, int(keep.sum()), len(keep))
        return NodeResult({"output": input.take(keep)}, report)

"""Lots where a block's land runs to open land (issue 11): no thin strips fronting onto it.

``blocks.landuse`` cuts the land more than 100 m from any street off a block
as ``landuse=open``; the piece left keeps a ``street_front`` column, and the
land closed along the extract's box has no street either.  A lot method that
takes every block edge for a street cuts rows of lots facing the open edge:
lots without frontage that are not flagged inner, many of them thin.  Here
the street edges are those of ``street_front`` off the box: the rows face
the street and the land behind them becomes inner (rear) lots.
"""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from _lotcases import landuse_blocks
from test_lots_rows import obb_sides

from sengine import Context
from sengine.registry import get

# thin lots without street frontage (oriented box thinner than 1:10) lots.recursive leaves; it left
# 1 and 8 when it took the open edges for streets (and 247 and 694 lots without frontage not flagged inner)
THIN_NO_FRONT = {"helsinki": 0, "monaco": 7}


@pytest.mark.parametrize("city", ["helsinki", "monaco"])
def test_recursive_lots_face_the_street_not_open_land(city):
    blocks = landuse_blocks(city)
    built = blocks.take(np.flatnonzero(blocks["landuse"] != "open"))
    fronted = np.array([f is not None for f in built["street_front"]])
    assert fronted.sum() >= 10  # blocks cut back from open land: the case under test
    ran = get("lots.recursive")("lots", {}, Context(seed=1)).run(blocks=blocks)
    lots = ran["lots"]
    no_front = lots["frontage"] <= 0
    # every lot without street frontage is an inner lot, and is counted as one
    assert not (no_front & ~lots["inner"]).any() and ran.report["no_frontage"] == 0
    assert (lots["frontage"][~lots["inner"]] >= 4.0 - 1e-9).all()
    long, short = obb_sides(lots.geometry)
    assert int((no_front & (short < 0.1 * long)).sum()) <= THIN_NO_FRONT[city]
    # the land is still all cut: lots partition the built blocks, and a street lot stands on each front
    barea = shapely.area(built.geometry)
    order = np.argsort(built.ids)
    owner = order[np.searchsorted(built.ids[order], lots["block"])]
    assert np.array_equal(built.ids[owner], lots["block"])
    larea = np.bincount(owner, weights=shapely.area(lots.geometry), minlength=len(built))
    assert np.allclose(larea, barea, rtol=1e-3)
    assert np.isin(built.ids[fronted], lots["block"][~lots["inner"]]).all()
    assert shapely.is_valid(lots.geometry).all()
    # pieces no cut splits: 57 and 91 before (open-edge blocks among them), in blocks all on the street now
    assert ran.report["recursive_stuck"] <= {"helsinki": 21, "monaco": 4}[city]

"""sengine.geom.grain: street length per served land round points (summed-area tables on a fixed grid)."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from hypothesis import example, given, settings
from hypothesis import strategies as st

from sengine.geom.grain import street_density

coord = st.floats(-2000.0, 2000.0, allow_nan=False)
segment = st.tuples(coord, coord, coord, coord).filter(lambda s: (s[0], s[1]) != (s[2], s[3]))


def _lines(segs):
    return np.array([shapely.LineString([(a, b), (c, d)]) for a, b, c, d in segs], dtype=object)


@settings(max_examples=60, deadline=None)
@given(st.lists(segment, min_size=1, max_size=12), st.lists(st.tuples(coord, coord), min_size=2, max_size=20))
@example(segs=[(0.0, 0.0, 0.0, 1.0), (0.0, 0.0, 0.0, -2.2217692098046403e-61)], pts=[(0.0, 0.0), (0.0, 0.0)])
def test_a_points_grain_is_its_own_whatever_is_asked_with_it(segs, pts):
    """The grid is fixed by the cell size alone: asking points one by one or together gives the same bytes."""
    lines, pts = _lines(segs), np.array(pts)
    together = street_density(lines, pts, 300.0)
    alone = np.concatenate([street_density(lines, p[None], 300.0) for p in pts])
    assert together.tobytes() == alone.tobytes()
    assert (together >= 0).all()
    # a window over everything holds every metre of street, over the land the streets serve
    whole = street_density(lines, pts[:1], 10_000.0, reach=0.0)
    mids = []
    for line in shapely.segmentize(lines, 25.0):  # the pieces of at most half a cell, by hand
        xy = np.asarray(line.coords)
        mids += list(0.5 * (xy[1:] + xy[:-1]))
    mids = np.array(mids)
    origin = np.floor(mids.min(axis=0) / 50.0) * 50.0  # cells counted from a multiple of 50 m, as rounded there
    served = len(np.unique(np.floor((mids - origin) / 50.0), axis=0))
    assert whole[0] == pytest.approx(shapely.length(lines).sum() * 1000.0 / (served * 2500.0), rel=1e-9)


def test_a_grid_of_streets_has_two_over_its_spacing():
    ticks = np.arange(0.0, 4001.0, 100.0)
    lines = [shapely.LineString([(t + 25.0, 0), (t + 25.0, 4000)]) for t in ticks]
    lines += [shapely.LineString([(0, t + 25.0), (4000, t + 25.0)]) for t in ticks]
    got = street_density(np.array(lines, dtype=object), np.array([[2000.0, 2000.0]]), 500.0)
    # 21 cells of 50 m: 1,050 m of side, crossed by 10 or 11 streets each way
    assert 2 * 10 * 1050 / 1050**2 * 1000 <= got[0] <= 2 * 11 * 1050 / 1050**2 * 1000


def test_one_road_serves_a_band_and_the_sea_beside_a_quay_does_not_thin_it():
    road = np.array([shapely.LineString([(0.0, 0.0), (0.0, 5000.0)])], dtype=object)
    at = np.array([[10.0, 2500.0], [3000.0, 2500.0]])
    got = street_density(road, at, 500.0, reach=100.0)
    # 1,050 m of road over the 5 cells (250 m) either side of it that lie within 100 m
    assert got[0] == pytest.approx(1050.0 * 1000.0 / (1050.0 * 250.0))
    assert got[1] == 0.0  # nothing within reach: no served land
    # a quay along the data's edge (nothing to the east): the same grain as the same road inland
    grid = [shapely.LineString([(x, 0.0), (x, 5000.0)]) for x in np.arange(-3000.0, 1.0, 100.0)]
    quay = street_density(np.array(grid, dtype=object), np.array([[-5.0, 2500.0]]), 500.0)
    inland = street_density(np.array(grid, dtype=object), np.array([[-1505.0, 2500.0]]), 500.0)
    assert quay[0] >= 0.85 * inland[0]  # the quay's own served band still counts: within 15 %
    # counting the whole square as land would take off 40 %
    bare = street_density(np.array(grid, dtype=object), np.array([[-5.0, 2500.0]]), 500.0, reach=10_000.0)
    assert bare[0] < 0.65 * inland[0]


def test_no_streets_or_no_points_give_zeros():
    assert street_density(np.array([], dtype=object), np.zeros((3, 2)), 500.0).tolist() == [0.0, 0.0, 0.0]
    assert street_density(_lines([(0, 0, 10, 10)]), np.zeros((0, 2)), 500.0).shape == (0,)

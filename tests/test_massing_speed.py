"""The fast paths of buildings.massing give what the plain computations give (issues 12 and 13).

Each shortcut (prepared street fronts, per-depth footprint memo, extents and
longest segments by ``reduceat``) is checked against the straightforward
computation it replaced, on Monaco's real building polygons and on
hypothesis-generated inputs (concave, thin, tiny, with holes).
"""

from __future__ import annotations

import numpy as np
import shapely
from _city import monaco_lots
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from sengine.geom.boundary import ring_segments, segments_on_lines
from sengine.nodes.buildings.edges import _longest_per_lot, lot_edges
from sengine.nodes.buildings.siting import _extent, axis_extent, building_area, clip_box
from sengine.nodes.buildings.typology import _SIMPLE, Site, _footprint, _footprints

SETTINGS = settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])

_MONACO = None


def monaco():
    global _MONACO
    if _MONACO is None:
        lots = monaco_lots()
        g = lots.geometry
        _MONACO = g[shapely.get_type_id(g) == 3][:600]
    return _MONACO


coord = st.floats(-50.0, 50.0, allow_nan=False, width=32)
polygon = st.lists(st.tuples(coord, coord), min_size=3, max_size=9).map(
    lambda pts: shapely.make_valid(shapely.Polygon(pts)).buffer(0)
)
holed = st.tuples(coord, coord, st.floats(3.0, 30.0), st.floats(0.1, 0.9)).map(
    lambda t: shapely.Point(t[0], t[1]).buffer(t[2], 2).difference(shapely.Point(t[0], t[1]).buffer(t[2] * t[3], 2))
)
shapes = st.lists(st.one_of(polygon, holed, st.just(shapely.Polygon())), min_size=1, max_size=12)


def test_street_fronts_match_plain_distances_and_stay_unprepared():
    g = monaco()
    p0, p1, idx, _ = ring_segments(g)
    # a block's street front stand-in: every third lot's boundary, shared by the segments of the lots around it
    fronts = np.array([shapely.boundary(g[(i // 3) * 3]) if i % 5 else None for i in range(len(g))], dtype=object)
    shapely.prepare(fronts[1])  # one front the caller prepared itself stays prepared
    lines = fronts[idx]
    got = segments_on_lines(p0, p1, lines)
    some = np.not_equal(lines, None)
    want = np.ones(len(idx), bool)
    for k in np.flatnonzero(some):  # GEOS distance, point by point, unprepared
        want[k] = shapely.Point(0.5 * (p0[k] + p1[k])).distance(lines[k]) <= 0.02
    assert np.array_equal(got, want)
    assert 0 < got[some].sum() < some.sum()  # some segments on their front, some not
    prepared = shapely.is_prepared(fronts)
    assert prepared[1] and prepared.sum() == 1


@SETTINGS
@given(st.lists(st.tuples(st.integers(0, 6), st.sampled_from([0.5, 1.0, 2.0, 3.0])), min_size=1, max_size=40))
def test_longest_segment_per_lot_is_the_last_of_the_longest(data):
    lot = np.sort(np.array([d[0] for d in data], np.int64))
    length = np.array([d[1] for d in data])
    cand = np.flatnonzero(length > 0.7)
    got = _longest_per_lot(cand, lot, length, 7)
    for k in range(7):
        mine = cand[lot[cand] == k]
        if len(mine) == 0:
            assert got[k] == -1
        else:
            top = length[mine].max()
            assert got[k] == mine[length[mine] == top][-1]


@SETTINGS
@given(shapes, st.floats(0.0, 2 * np.pi))
def test_extents_match_every_coordinate(geoms, angle):
    geoms = np.array(geoms, dtype=object)
    n = len(geoms)
    axis = np.tile([np.cos(angle), np.sin(angle)], (n, 1))
    origin = np.tile([3.0, -2.0], (n, 1))
    lo, hi = axis_extent(geoms, axis, origin)
    c, ci = shapely.get_coordinates(geoms, return_index=True)
    lo2, hi2 = _extent(c - origin[ci], ci, axis, n)
    assert np.array_equal(lo, lo2) and np.array_equal(hi, hi2)
    for k, g in enumerate(geoms):
        xy = shapely.get_coordinates(g)
        t = (xy - origin[k]) @ axis[k]
        assert np.allclose((lo[k], hi[k]), (t.min(), t.max()) if len(t) else (0.0, 0.0), rtol=0, atol=1e-12)


@SETTINGS
@given(shapes, st.floats(0.0, 2 * np.pi), st.floats(-20.0, 20.0), st.floats(0.5, 40.0))
@example([shapely.Polygon(), shapely.Polygon([(0.0, -1.0), (1.0, 1.0), (1.0, 0.0)])], 0.0, 1.4256811894307327e-19, 1.0)
def test_clip_box_cuts_to_its_box(geoms, angle, a0, width):
    geoms = np.array(geoms, dtype=object)
    n = len(geoms)
    axis = np.tile([np.cos(angle), np.sin(angle)], (n, 1))
    origin = np.zeros((n, 2))
    out = clip_box(geoms, origin, axis, a0, a0 + width, -np.inf, np.inf)
    box = shapely.Polygon(
        [
            p[0] * axis[0] + p[1] * np.array([-axis[0, 1], axis[0, 0]])
            for p in [(a0, -1e3), (a0 + width, -1e3), (a0 + width, 1e3), (a0, 1e3)]
        ]
    )
    want = shapely.area(shapely.intersection(geoms, box))
    assert np.allclose(shapely.area(out), want, rtol=1e-6, atol=1e-6)
    assert shapely.is_valid(out[~shapely.is_empty(out)]).all()


def test_footprint_memo_gives_the_footprints_drawn_afresh():
    g = monaco()
    n = len(g)
    edges = lot_edges(g)
    fs, ss, rs = np.full(n, 2.0), np.zeros(n), np.full(n, 4.0)
    area = building_area(g, edges, fs, ss, rs)
    site = Site(area, edges, fs, ss, rs)
    rows = np.arange(n)
    rng = np.random.default_rng(3)
    for code in _SIMPLE:
        d1 = rng.uniform(6.0, 20.0, n)
        first = _footprints(code, site, rows, d1)
        # the FAR loop: half the lots redrawn at the same depth, half deeper, in a different subset
        sub = np.sort(rng.choice(n, n // 2, replace=False))
        d2 = np.where(rng.random(len(sub)) < 0.5, d1[sub], d1[sub] + 1.5)
        again = _footprints(code, site, sub, d2)
        fresh = _footprint(code, Site(area, edges, fs, ss, rs), sub, d2)
        assert np.array_equal(shapely.to_wkb(again), shapely.to_wkb(fresh)), code
        same = d2 == d1[sub]
        assert all(a is b for a, b in zip(again[same], first[sub][same]))  # taken, not redrawn
        built = ~shapely.is_empty(fresh)
        assert built.sum() > n // 4 and (shapely.area(fresh[built]) > 0).all()

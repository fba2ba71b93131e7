"""Minor roads (skylineEngine §5.3.2): each major area cut by its district's grid, one planar street graph."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import sengine.nodes.roads.minor as MINOR
import sengine.nodes.roads.patterns as PATTERNS
from sengine import CityPlan, Context, Layer, Rule
from sengine.nodes.maps import plan_inputs
from sengine.registry import get

SETTINGS = settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
SIZE = (2400.0, 1600.0)


def city(rules, seed=4, size=SIZE):
    plan = CityPlan(size=size, rules=[Rule("district", r, f"t.xml:{3 + i}") for i, r in enumerate(rules)])
    ctx = Context(seed=seed, plan=plan)
    districts = get("roads.districts")("majorRoads", {}, ctx)
    major = districts.run(**plan_inputs(plan, districts))
    node = get("roads.minor")("minorRoads", {}, ctx)
    out = node.run(areas=major["areas"], roads=major["roads"], **plan_inputs(plan, node))
    return major, out, node


def faces(roads: Layer) -> np.ndarray:
    return np.asarray(shapely.get_parts(shapely.polygonize(roads.geometry)), dtype=object)


def angle_of(lines) -> np.ndarray:
    """Direction (deg, mod 180) of every straight piece longer than 5 m of the lines."""
    xy, idx = shapely.get_coordinates(lines, return_index=True)
    same = idx[1:] == idx[:-1]
    d = (xy[1:] - xy[:-1])[same]
    d = d[np.hypot(*d.T) > 5.0]
    return np.degrees(np.arctan2(d[:, 1], d[:, 0])) % 180


def assert_plane_graph(roads: Layer):
    g = roads.geometry
    assert shapely.is_valid(g).all() and (shapely.length(g) > 0).all()
    tree = shapely.STRtree(g)
    assert len(tree.query(g, predicate="crosses")[0]) == 0
    assert len(tree.query(g, predicate="overlaps")[0]) == 0
    ends = np.concatenate(
        [shapely.get_coordinates(shapely.get_point(g, 0)), shapely.get_coordinates(shapely.get_point(g, -1))]
    )
    _, counts = np.unique(np.round(ends, 3), axis=0, return_counts=True)
    assert (counts >= 2).all(), "dead ends"
    # no segment passes through a junction: every junction is an end point
    junctions = shapely.points(np.unique(np.round(ends, 3), axis=0)[counts >= 3])
    i, j = shapely.STRtree(junctions).query(g, predicate="contains")  # interior of a line
    assert len(i) == 0


@pytest.mark.parametrize(
    "rule",
    [
        {"pattern": "grid", "spacing": "600 480", "angle": "29", "minor-spacing": "150 80"},
        {"pattern": "radial", "rings": "3", "spokes": "8", "minor-spacing": "120 90"},
        {"pattern": "organic", "sites": "15", "minor-spacing": "110 70", "minor-angle": "random"},
        {"pattern": "organic", "sites": "15", "minor-spacing": "100 100", "minor-angle": "45"},
    ],
    ids=["grid", "radial", "organic-random", "organic-45"],
)
def test_minor_roads_partition_every_area(rule):
    major, out, node = city([rule])
    roads = out["roads"]
    assert_plane_graph(roads)
    assert set(roads["class"]) <= {"major", "boundary", "minor"}
    assert (roads["major"] == (roads["class"] != "minor")).all()
    assert (roads["width"][roads["class"] == "minor"] == 12.0).all()
    assert (roads["width"][roads["major"]] == 20.0).all()
    # blocks (faces of the street graph) partition the outline, each inside one area
    f = faces(roads)
    outline = major["outline"].geometry[0]
    assert shapely.area(f).sum() == pytest.approx(outline.area, rel=1e-6)
    assert shapely.symmetric_difference(shapely.union_all(f), outline).area < 1e-6 * outline.area
    host = shapely.STRtree(major["areas"].geometry).query(shapely.point_on_surface(f), predicate="within")
    assert len(np.unique(host[0])) == len(f)
    assert len(f) > 2 * len(major["areas"])
    assert out.report["blocks_estimate"] == len(f)
    # major roads are all still there, split at the new junctions only
    maj = roads.geometry[roads["major"]]
    assert shapely.length(maj).sum() == pytest.approx(shapely.length(major["roads"].geometry).sum(), rel=1e-6)
    assert out["areas"] is major["areas"]


def test_follow_continues_the_major_grid():
    rule = {"pattern": "grid", "spacing": "600 480", "angle": "29", "offset": "10 20", "minor-spacing": "150 80"}
    _, out, _ = city([rule])
    roads = out["roads"]
    minor = roads.geometry[roads["class"] == "minor"]
    ang = angle_of(minor)
    assert np.all(np.isclose(ang, 29, atol=0.01) | np.isclose(ang, 119, atol=0.01))
    # the major and minor grids share their crossings: blocks are exact 150 x 80 cells
    f = faces(roads)
    exact = np.isclose(shapely.area(f), 150 * 80, rtol=1e-5)
    assert exact.mean() > 0.8


def test_fixed_angle():
    rule = {"pattern": "organic", "sites": "12", "minor-spacing": "120 90", "minor-angle": "-20"}
    _, out, _ = city([rule])
    ang = angle_of(out["roads"].geometry[out["roads"]["class"] == "minor"])
    assert np.all(np.isclose(ang, 160, atol=0.01) | np.isclose(ang, 70, atol=0.01))


def test_random_angle_per_area_is_seeded():
    rule = {"pattern": "organic", "sites": "20", "minor-spacing": "120 90", "minor-angle": "random"}
    _, a, _ = city([rule], seed=3)
    _, b, _ = city([rule], seed=3)
    _, c, _ = city([rule], seed=8)
    wkb = lambda out: list(shapely.to_wkb(out["roads"].geometry))  # noqa: E731
    assert wkb(a) == wkb(b)
    assert wkb(a) != wkb(c)
    angles = np.round(angle_of(a["roads"].geometry[a["roads"]["class"] == "minor"]) % 90, 3)
    assert len(np.unique(angles)) >= 10  # one grid angle per area, not one for all


def test_widths_and_district_per_rule():
    rules = [
        {"pattern": "grid", "spacing": "800 800", "minor-spacing": "200 100", "minor-width": "9", "major-width": "31"}
    ]
    _, out, _ = city(rules)
    r = out["roads"]
    assert set(r["width"][r["class"] == "minor"]) == {9.0}
    assert set(r["width"][r["major"]]) == {31.0}
    assert set(r["district"]) == {0}


def test_minor_lines_near_an_avenue_leave_no_sliver():
    # minor grid offset 3 m from the major grid: lines along avenues are dropped or merged
    rule = {"pattern": "grid", "spacing": "600 400", "minor-spacing": "150 100", "minor-angle": "0"}
    plan_rule = dict(rule, offset="3 3")
    _, out, _ = city([plan_rule])
    f = faces(out["roads"])
    w = PATTERNS.cell_width(f)
    assert w.min() > 0.3 * 100 - 1e-6


def test_pure_minor_grid_one_intersection_for_all_areas():
    areas = np.array([shapely.box(0, 0, 300, 200), shapely.box(300, 0, 600, 200)], dtype=object)
    styles = [MINOR.DistrictStyle(index=0, name="a", colour=None, minor_spacing=(100.0, 50.0), minor_angle=0.0)]
    lines, owner, ang = MINOR.minor_grid(areas, np.array([0, 0]), styles, lambda i: np.random.default_rng(i))
    assert set(owner) == {0, 1} and np.allclose(ang, 0)
    net = MINOR.minor_network(
        areas,
        np.array([0, 0]),
        shapely.get_parts(shapely.union_all(shapely.boundary(areas))),
        {},
        styles,
        lambda i: np.random.default_rng(i),
    )
    assert len(net["cells"]) == 2 * 3 * 4
    np.testing.assert_allclose(shapely.area(net["cells"]), 5000.0)


@SETTINGS
@given(
    seed=st.integers(0, 2**31),
    angle=st.floats(-90, 90),
    mdx=st.floats(60, 200),
    mdy=st.floats(40, 150),
    how=st.sampled_from(["follow", "random", "fixed"]),
    pattern=st.sampled_from(["grid", "radial", "organic"]),
)
def test_random_minor_grids_make_plane_graphs(seed, angle, mdx, mdy, how, pattern):
    rule = {
        "pattern": pattern,
        "spacing": "500 400",
        "angle": str(angle),
        "sites": "9",
        "spokes": "6",
        "rings": "2",
        "minor-spacing": f"{mdx} {mdy}",
        "minor-angle": str(-angle / 2) if how == "fixed" else how,
    }
    major, out, _ = city([rule], seed=seed, size=(1500.0, 1000.0))
    assert_plane_graph(out["roads"])
    f = faces(out["roads"])
    assert shapely.area(f).sum() == pytest.approx(major["outline"].geometry[0].area, rel=1e-6)


def test_roads_that_do_not_enclose_the_areas_fall_back_to_area_borders():
    areas = np.array([shapely.box(0, 0, 300, 200), shapely.box(300, 0, 600, 200)], dtype=object)
    styles = [MINOR.DistrictStyle(index=0, name="a", colour=None, minor_spacing=(100.0, 50.0), minor_angle=0.0)]
    only_one = np.array([shapely.LineString([(300, 0), (300, 200)])], dtype=object)
    net = MINOR.minor_network(areas, np.array([0, 0]), only_one, {}, styles, lambda i: np.random.default_rng(i))
    assert len(net["cells"]) == 24
    assert shapely.area(net["cells"]).sum() == pytest.approx(600 * 200)

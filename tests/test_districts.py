"""Districts and major roads (skylineEngine §5.3.1, Fig. 7): areas partition the buildable city, borders are shared."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from PIL import Image, ImageDraw

from sengine import CityPlan, Context, Rule
from sengine.errors import ConfigError, InputDataError
from sengine.nodes.maps import plan_inputs
from sengine.plan import MapSpec
from sengine.registry import get

SETTINGS = settings(
    max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture]
)
SIZE = (3000.0, 2000.0)


def run_major(plan, seed=5, **params):
    node = get("roads.districts")("majorRoads", params, Context(seed=seed, plan=plan))
    return node.run(**plan_inputs(plan, node)), node


def assert_partition(areas, outline):
    """Areas are valid, do not overlap and cover the outline exactly."""
    g = areas.geometry
    assert len(g) > 0
    assert shapely.is_valid(g).all()
    assert (shapely.get_type_id(g) == 3).all()  # Polygons
    total = outline.area
    assert shapely.area(g).sum() == pytest.approx(total, rel=1e-6)  # no overlaps
    union = shapely.union_all(g)
    assert shapely.symmetric_difference(union, outline).area <= 1e-6 * total  # no gaps, no holes but cut-outs


def assert_planar(roads):
    """Road segments meet only at their ends (a noded plane graph)."""
    g = roads.geometry
    assert shapely.is_valid(g).all() and (shapely.length(g) > 0).all()
    i, j = shapely.STRtree(g).query(g, predicate="crosses")
    assert len(i) == 0, f"{len(i)} crossing road pairs"
    i, j = shapely.STRtree(g).query(g, predicate="overlaps")
    assert len(i) == 0, f"{len(i)} overlapping road pairs"


PATTERNS = [
    {"pattern": "grid", "spacing": "300 200"},
    {"pattern": "grid", "spacing": "250 250", "angle": "29", "offset": "37 11"},
    {"pattern": "grid", "spacing": "400 150", "angle": "-61.5"},
    {"pattern": "grid", "spacing": "350 0", "angle": "90"},
    {"pattern": "radial", "rings": "5", "spokes": "9"},
    {"pattern": "radial", "center": "400 300", "ring-spacing": "250", "spokes": "7", "angle": "13"},
    {"pattern": "organic", "sites": "30", "relax": "3"},
    {"pattern": "organic", "sites": "50", "relax": "6", "weights": "1.5"},
]


@pytest.mark.parametrize("attrs", PATTERNS, ids=[" ".join(f"{k}={v}" for k, v in a.items()) for a in PATTERNS])
def test_single_pattern_partitions_the_extent(attrs):
    plan = CityPlan(size=SIZE, rules=[Rule("district", dict(attrs), "t.xml:3")])
    out, node = run_major(plan)
    outline = out["outline"].geometry[0]
    assert outline.area == pytest.approx(SIZE[0] * SIZE[1])
    assert_partition(out["areas"], outline)
    assert_planar(out["roads"])
    roads = out["roads"]
    assert set(roads["class"]) <= {"major", "boundary"}
    assert (roads["major"]).all() and (roads["width"] == 20.0).all()
    # the extent's edge is all road, class boundary
    edge = shapely.union_all(roads.geometry[roads["class"] == "boundary"])
    assert edge.length == pytest.approx(2 * (SIZE[0] + SIZE[1]), rel=1e-6)
    # the areas are the faces of the roads
    faces = shapely.get_parts(shapely.polygonize(roads.geometry))
    assert len(faces) == len(out["areas"])
    assert out.report["areas"] == len(out["areas"])


def test_grid_areas_follow_spacing_and_angle():
    rule = Rule("district", {"pattern": "grid", "spacing": "300 200", "angle": "30"}, "t.xml:3")
    out, _ = run_major(CityPlan(size=SIZE, rules=[rule]), merge=0.0)
    g = out["areas"].geometry
    full = np.isclose(shapely.area(g), 300 * 200, rtol=1e-6)
    assert full.sum() >= 40  # interior cells are exact 300 x 200 rectangles
    # their long sides point along 30 deg
    rect = shapely.oriented_envelope(g[full])
    xy = shapely.get_coordinates(rect).reshape(-1, 5, 2)
    d = xy[:, 1] - xy[:, 0]
    d2 = xy[:, 2] - xy[:, 1]
    long = np.where((np.hypot(*d.T) > np.hypot(*d2.T))[:, None], d, d2)
    ang = np.degrees(np.arctan2(long[:, 1], long[:, 0])) % 180
    np.testing.assert_allclose(ang, 30.0, atol=1e-3)  # coordinates are snapped to 1 mm


def test_slivers_are_merged():
    # a grid offset 50 m from the extent's edges would leave 50 m strips
    rule = Rule("district", {"pattern": "grid", "spacing": "300 300", "offset": "50 50"}, "t.xml:3")
    out, node = run_major(CityPlan(size=SIZE, rules=[rule]))
    w = 2 * shapely.area(out["areas"].geometry) / shapely.length(out["areas"].geometry)
    assert w.min() > 0.3 * 300 * 0.5
    assert out.report["merged_slivers"] > 0
    raw, _ = run_major(CityPlan(size=SIZE, rules=[rule]), merge=0.0)
    assert len(raw["areas"]) > len(out["areas"])


def test_same_seed_same_roads_other_seed_other_organic():
    rule = Rule("district", {"pattern": "organic", "sites": "25"}, "t.xml:3")
    plan = CityPlan(size=SIZE, rules=[rule])
    a, _ = run_major(plan, seed=1)
    b, _ = run_major(plan, seed=1)
    c, _ = run_major(plan, seed=2)
    assert list(shapely.to_wkb(a["roads"].geometry)) == list(shapely.to_wkb(b["roads"].geometry))
    assert list(shapely.to_wkb(a["roads"].geometry)) != list(shapely.to_wkb(c["roads"].geometry))


# -- a city from maps: three districts, a lake and a park --------------------------------------------
DISTRICT_COLOURS = ["#d03030", "#3050d0", "#30a030"]


def draw_maps(folder, shift=0):
    dist = Image.new("RGB", (300, 200), DISTRICT_COLOURS[0])
    d = ImageDraw.Draw(dist)
    d.ellipse((120 + shift, 20, 260 + shift, 160), fill=DISTRICT_COLOURS[1])
    d.polygon([(200, 200), (300, 200), (300, 0), (280, 0), (230, 120)], fill=DISTRICT_COLOURS[2])
    dist.save(folder / "d.png")
    land = Image.new("RGB", (300, 200), "#ffffff")
    d = ImageDraw.Draw(land)
    d.ellipse((30, 120, 80, 160), fill="#2060ff")  # lake
    d.rectangle((60, 30, 100, 60), fill="#30a040")  # park
    d.rectangle((0, 190, 300, 200), fill="#2060ff")  # sea along the south edge
    land.save(folder / "l.png")


def map_plan(folder, patterns=("grid", "radial", "organic")):
    extras = {
        "grid": {"spacing": "260 180", "angle": "12"},
        "radial": {"rings": "3", "spokes": "8"},
        "organic": {"sites": "12", "weights": "0.5"},
    }
    rules = [
        Rule("district", {"color": c, "pattern": p, "major-width": str(18 + 2 * i), **extras[p]}, f"c.xml:{5 + i}")
        for i, (c, p) in enumerate(zip(DISTRICT_COLOURS, patterns))
    ]
    rules += [
        Rule("landuse", {"color": "#ffffff", "class": "buildable"}, "c.xml:9"),
        Rule("landuse", {"color": "#2060ff", "class": "water"}, "c.xml:10"),
        Rule("landuse", {"color": "#30a040", "class": "park"}, "c.xml:11"),
    ]
    maps = {
        "district": MapSpec("district", folder / "d.png", {}, "c.xml:3"),
        "landuse": MapSpec("landuse", folder / "l.png", {}, "c.xml:4"),
    }
    return CityPlan(size=SIZE, maps=maps, rules=rules)


@pytest.fixture
def city(tmp_path):
    draw_maps(tmp_path)
    plan = map_plan(tmp_path)
    out, node = run_major(plan)
    return plan, out, node


def test_map_city_partitions_the_buildable_outline(city):
    plan, out, node = city
    outline = out["outline"].geometry[0]
    assert outline.area < SIZE[0] * SIZE[1] * 0.97  # lake, park and sea cut out
    assert_partition(out["areas"], outline)
    assert_planar(out["roads"])
    # holes of the outline are exactly the lake and the park
    holes = [shapely.Polygon(r) for p in shapely.get_parts(outline) for r in p.interiors]
    assert len(holes) == 2
    assert out.report["districts"] == 3
    assert set(out["areas"]["district"]) == {0, 1, 2}
    assert set(out["areas"]["pattern"]) == {"grid", "radial", "organic"}


def test_district_borders_are_shared_roads(city):
    plan, out, _ = city
    areas, roads = out["areas"], out["roads"]
    bound = shapely.union_all(roads.geometry[roads["class"] == "boundary"])
    grown = bound.buffer(0.01)
    for k in range(3):
        mine = shapely.union_all(areas.geometry[areas["district"] == k])
        # every district's border (land-use and extent edges included) is boundary road
        assert shapely.difference(mine.boundary, grown).length < 1e-6
        for j in range(k + 1, 3):
            other = shapely.union_all(areas.geometry[areas["district"] == j])
            assert shapely.intersection(mine, other).area < 1e-6  # no overlap
    # boundary roads between two districts take the wider major width
    widths = set(np.round(roads["width"], 6))
    assert widths <= {18.0, 20.0, 22.0}


def test_pattern_lines_end_on_the_border(city):
    # a major road piece never stops short of the district border (no dangles)
    _, out, _ = city
    g = out["roads"].geometry
    ends = np.concatenate(
        [shapely.get_coordinates(shapely.get_point(g, 0)), shapely.get_coordinates(shapely.get_point(g, -1))]
    )
    _, counts = np.unique(np.round(ends, 3), axis=0, return_counts=True)
    assert (counts >= 2).all()


def test_parks_from_the_land_use_map(city):
    _, out, _ = city
    parks = out["parks"]
    assert len(parks) == 1
    assert list(parks["level"]) == ["district"]
    assert parks.geometry[0].area == pytest.approx(41 * 31 * 100, rel=0.1)
    assert shapely.intersection(parks.geometry[0], out["outline"].geometry[0]).area < 1e-6
    assert set(out["landuse"]["kind"]) == {"water"}


def test_mixed_patterns_meet_cleanly_in_any_order(tmp_path):
    draw_maps(tmp_path, shift=-7)
    for order in (("organic", "grid", "radial"), ("radial", "organic", "grid")):
        out, _ = run_major(map_plan(tmp_path, order), seed=9)
        assert_partition(out["areas"], out["outline"].geometry[0])
        assert_planar(out["roads"])


def test_without_a_district_map_the_first_rule_styles_the_city():
    rules = [
        Rule("district", {"pattern": "radial", "spokes": "6"}, "t.xml:3"),
        Rule("district", {"pattern": "grid"}, "t.xml:4"),
    ]
    out, _ = run_major(CityPlan(size=SIZE, rules=rules))
    assert set(out["areas"]["district"]) == {0}
    assert set(out["areas"]["pattern"]) == {"radial"}


def test_unknown_district_colour_names_colour_pixel_and_line(tmp_path):
    draw_maps(tmp_path)
    im = Image.open(tmp_path / "d.png")
    ImageDraw.Draw(im).rectangle((10, 5, 15, 9), fill="#123456")
    im.save(tmp_path / "d.png")
    with pytest.raises(InputDataError, match=r"c\.xml:3: map 'd\.png': colour #123456 at pixel \(x=10, y=5\)"):
        run_major(map_plan(tmp_path))


def test_district_map_of_the_wrong_shape(tmp_path):
    draw_maps(tmp_path)
    Image.new("RGB", (300, 300), DISTRICT_COLOURS[0]).save(tmp_path / "d.png")
    with pytest.raises(InputDataError, match=r"c\.xml:3: map '.*d\.png': image is 300x300 px"):
        run_major(map_plan(tmp_path))


@pytest.mark.parametrize(
    "attrs,message",
    [
        ({"pattern": "hexagon"}, r"t\.xml:7: <district> pattern='hexagon' is not one of grid, radial, organic"),
        ({"spacing": "300"}, r"t\.xml:7: <district> spacing='300' is not 2 numbers"),
        ({"spacing": "0 0"}, r"spacing='0 0'"),
        ({"sites": "2.5", "pattern": "organic"}, r"sites='2.5' is not 1 whole number"),
        ({"minor-angle": "steep"}, r"minor-angle='steep' is not 1 number"),
        ({"color": "purple"}, r"t\.xml:7: colour 'purple'"),
    ],
)
def test_bad_district_rules(attrs, message):
    with pytest.raises((ConfigError, InputDataError), match=message):
        run_major(CityPlan(size=SIZE, rules=[Rule("district", attrs, "t.xml:7")]))


def test_rule_without_colour_under_a_district_map(tmp_path):
    draw_maps(tmp_path)
    plan = map_plan(tmp_path)
    plan.rules[1] = Rule("district", {"pattern": "grid"}, "c.xml:6")
    with pytest.raises(ConfigError, match=r"c\.xml:6: <district> needs a color"):
        run_major(plan)


@SETTINGS
@given(
    seed=st.integers(0, 2**31),
    angle=st.floats(-180, 180),
    dx=st.floats(120, 700),
    dy=st.floats(120, 700),
    pattern=st.sampled_from(["grid", "radial", "organic"]),
)
def test_random_patterns_partition(seed, angle, dx, dy, pattern):
    attrs = {
        "pattern": pattern,
        "spacing": f"{dx} {dy}",
        "angle": str(angle),
        "sites": str(int(dx // 20)),
        "rings": str(int(dy // 100)),
        "spokes": str(int(dx // 60)),
        "offset": f"{dy} {dx}",
    }
    out, _ = run_major(CityPlan(size=(1700.0, 1100.0), rules=[Rule("district", attrs, "t.xml:3")]), seed=seed)
    assert_partition(out["areas"], out["outline"].geometry[0])
    assert_planar(out["roads"])


# -- parks at block level (paper §4: one park module, several levels) --------------------------------
@pytest.mark.parametrize("mode", ["every", "random", "largest"])
def test_block_parks_split_the_blocks(mode):
    from sengine import Layer

    rng = np.random.default_rng(0)
    geoms = [shapely.box(x, y, x + rng.uniform(20, 90), y + 60) for x in range(0, 1000, 100) for y in (0, 100, 200)]
    blocks = Layer.from_geoms(geoms, ids=np.arange(100, 130), district=np.zeros(30, np.int64))
    upstream = Layer.from_geoms([shapely.box(0, 500, 100, 600)], level=["district"], district=[0])
    node = get("parks.block")("smallParks", {"mode": mode, "every": "7", "share": "0.2"}, Context(seed=3))
    out = node.run(blocks=blocks, parks=upstream)
    parks, rest = out["parks"], out["blocks"]
    new = parks.take(parks["level"] == "block")
    assert len(new) + len(rest) == len(blocks) and len(new) > 0
    assert set(new.parent) | set(rest.ids) == set(blocks.ids)
    assert list(parks["level"]).count("district") == 1
    if mode == "every":
        assert set(new.parent) == {105, 112, 119, 126}
    if mode == "largest":
        assert shapely.area(new.geometry).min() >= shapely.area(rest.geometry).max()
    again = get("parks.block")("smallParks", {"mode": mode, "every": "7", "share": "0.2"}, Context(seed=3))
    assert list(again.run(blocks=blocks, parks=upstream)["blocks"].ids) == list(rest.ids)

"""Buildings from planning rules: siting, party walls, FAR-to-building (000), typologies (004), heights."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
import shapely.affinity
from _city import ROOT, grid_city, monaco_lots
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sengine import CityPlan, Context, Layer, Rule
from sengine.errors import ParameterError
from sengine.geom.polygons import obb_frame
from sengine.nodes.buildings.edges import FRONT, REAR, SIDE, lot_edges
from sengine.nodes.buildings.far import depth_for, far_height, far_to_building, floors_for
from sengine.nodes.buildings.typology import TYPOLOGIES
from sengine.nodes.buildings.walls import party_walls
from sengine.nodes.maps import plan_inputs
from sengine.registry import get

Massing = get("buildings.massing")
Far = get("buildings.far")
SETTINGS = settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
GRID = 1e-9  # m: snap-rounding overlay for measurements (see test_lots)


def run(lots, blocks=None, *, node=Massing, plan=None, seed=7, custom=None, **params):
    n = node("buildings", {k: str(v) for k, v in params.items()}, Context(seed=seed, plan=plan))
    ran = n.run(lots=lots, blocks=blocks, custom=custom, **(plan_inputs(plan, n) if plan is not None else {}))
    out = ran["buildings"]
    return out, ran.report


def row_block(width, depth=30.0, count=3, rows=2, angle=0.0):
    """A block of ``rows`` x ``count`` lots of ``width`` x ``depth`` (m), rotated: lots and block layers."""
    lots = [
        shapely.box(i * width, j * depth, (i + 1) * width, (j + 1) * depth) for j in range(rows) for i in range(count)
    ]
    block = shapely.box(0, 0, count * width, rows * depth)
    rot = lambda g: shapely.affinity.rotate(g, angle, origin=(0, 0))  # noqa: E731
    lots_l = Layer.from_geoms(
        [rot(g) for g in lots], block=np.zeros(len(lots), np.int64), district=np.zeros(len(lots), np.int64)
    )
    return lots_l, Layer.from_geoms([rot(block)], ids=[0])


# -- FAR-to-building (000 §5.3) ---------------------------------------------------------


def test_worked_example_of_the_thesis():
    """000 §5.3.4 note 17: a target of 1,000 m2 on a 334 m2 footprint is 3 floors (2.99 rounded up)."""
    assert floors_for(1000.0, 334.0) == 3
    res = far_to_building(np.array([1000.0]), lambda rows, d, f: (np.full(len(rows), 334.0), np.zeros(len(rows))))
    assert res["floors"].tolist() == [3] and res["converged"].all() and res["iterations"].tolist() == [1]
    assert res["floor_area"][0] == pytest.approx(1002.0)
    # the same on a real lot: the middle lot of a row, attached, depth from the rule (14.375 m at 1,000 m2)
    d = float(depth_for(1000.0))
    assert d == pytest.approx(8 + 17 * 900 / 2400)
    width = 334.0 / d
    lots, blocks = row_block(width, depth=30.0)
    far = 1000.0 / (width * 30.0)
    b, report = run(lots, blocks, node=Far, far=far, typology="I", siting="attached", roof="flat")
    mid = b.take(np.flatnonzero(b["lot"] == 1))
    assert len(mid) == 1 and mid["floors"][0] == 3
    assert shapely.area(mid.geometry[0]) == pytest.approx(334.0, rel=1e-9)
    assert mid["gfa"][0] == pytest.approx(1002.0) and mid["far"][0] == pytest.approx(1002.0 / (width * 30.0))
    assert report["far_converged"] == report["far_iterated"] == len(lots)


def test_depth_rule_and_minimum_floor_area():
    np.testing.assert_allclose(depth_for([50, 100, 1300, 2500, 9000]), [8, 8, 16.5, 25, 25])
    res = far_to_building(np.array([79.9, 80.0]), lambda r, d, f: (np.full(len(r), 100.0), np.zeros(len(r))))
    assert res["build"].tolist() == [False, True]  # none under 80 m2 (000 §5.3.4)


def test_too_much_floor_area_shrinks_the_depth_then_the_length():
    # footprint linear in depth (40 m of frontage): 575 m2 at 14.375 m -> 2 floors 1,150 m2, 15 % over
    def strip(rows, d, frac):
        return 40.0 * d * frac, np.zeros(len(rows))

    res = far_to_building(np.array([1000.0]), strip)
    assert res["floors"][0] == 2 and res["converged"][0]
    assert res["depth"][0] == pytest.approx(12.5) and res["fraction"][0] == 1.0
    assert abs(res["floor_area"][0] - 1000.0) <= 50.0
    # a 1-floor target under the footprint at the 10 m depth floor: the length goes
    res = far_to_building(np.array([500.0]), strip)
    assert res["depth"][0] == pytest.approx(10.0) and res["fraction"][0] < 1.0
    # a depth that starts under the floor (9.4 m at 300 m2) is not reduced: the length goes at once
    res = far_to_building(np.array([300.0]), strip)
    assert res["depth"][0] == pytest.approx(float(depth_for(300.0))) and res["fraction"][0] < 1.0
    assert res["floors"][0] == 1 and abs(res["floor_area"][0] - 300.0) <= 15.0


def test_height_limit_leaves_the_target_short():
    res = far_to_building(
        np.array([5000.0]), lambda r, d, f: (np.full(len(r), 400.0), np.zeros(len(r))), max_floors=np.array([4])
    )
    assert res["floors"][0] == 4 and not res["converged"][0] and res["floor_area"][0] == 1600.0


def test_far_height_relation_of_paper_004():
    """H = FAR x f_h / d: the storeys of every single-part building reach its lot's FAR on its coverage."""
    plan, layers = grid_city()
    b, _ = run(layers["lots"], layers["blocks"], node=Far, far=2.5, typology="I:2,L,U,O,tower", roof="flat")
    lots = layers["lots"]
    rows = lots.rows_of(b["lot"])
    coverage = np.bincount(rows, weights=shapely.area(b.geometry), minlength=len(lots)) / shapely.area(lots.geometry)
    h = far_height(b["far"], 3.2, coverage[rows])
    np.testing.assert_allclose(h, b["height"], rtol=1e-9)
    np.testing.assert_allclose(b["height"], b["floors"] * 3.2)
    # and the FAR is met within 000's 5 % on every lot large enough to hold its target
    assert np.all(np.abs(b["far"] - 2.5) <= 0.05 * 2.5 + 1e-9)


# -- siting and party walls ----------------------------------------------------------------


def test_front_side_and_rear_lines():
    lots, blocks = row_block(10.0, count=3, rows=2)
    e = lot_edges(lots.geometry, blocks=blocks.geometry, owner=np.zeros(len(lots), np.int64))
    kinds = [sorted(e.kind[e.lot == i].tolist()) for i in range(len(lots))]
    # corner lots: two fronts and two sides; the middle lots: a front, two sides and a rear
    assert kinds[0] == kinds[2] == kinds[3] == kinds[5] == [FRONT, FRONT, SIDE, SIDE]
    assert kinds[1] == kinds[4] == [FRONT, SIDE, SIDE, REAR]
    assert e.corner.tolist() == [True, False, True, True, False, True]
    # without the block, the street is where no other lot is: the same tags
    e2 = lot_edges(lots.geometry)
    np.testing.assert_array_equal(e2.kind, e.kind)


def test_attached_neighbours_share_party_walls_exactly():
    lots, blocks = row_block(12.0, depth=35.0, count=6, rows=2, angle=23.0)
    b, _ = run(lots, blocks, typology="I", siting="attached", depth=14)
    assert len(b) == len(lots)
    walls = party_walls(b.geometry)
    assert (walls > 0).all()
    g = b.geometry
    i, j = shapely.STRtree(g).query(g, predicate="intersects")
    sel = i < j
    # no overlap ...
    overlap = shapely.area(shapely.intersection(g[i[sel]], g[j[sel]], grid_size=GRID))
    assert overlap.max(initial=0.0) < 1e-6
    # ... and no gap: each shared wall is the same length seen from either side
    for a, c in zip(i[sel], j[sel]):
        both = shapely.intersection(shapely.boundary(g[a]), shapely.buffer(g[c], 1e-6))
        back = shapely.intersection(shapely.boundary(g[c]), shapely.buffer(g[a], 1e-6))
        assert shapely.length(both) == pytest.approx(shapely.length(back), abs=1e-5)
    # the middle lots' buildings share both side walls: 2 x 14 m of a 2 x (12 + 14) m outline
    mid = (b["lot"] % 6 != 0) & (b["lot"] % 6 != 5)
    np.testing.assert_allclose(walls[mid] / shapely.length(g[mid]), 28.0 / 52.0, rtol=1e-6)


def test_detached_buildings_keep_side_and_rear_setbacks():
    lots, blocks = row_block(20.0, depth=40.0, count=4, rows=2, angle=-31.0)
    b, _ = run(lots, blocks, typology="I", siting="detached", setback_side=4, setback_rear=6, setback_front=3)
    e = lot_edges(lots.geometry, blocks=blocks.geometry, owner=np.zeros(len(lots), np.int64))
    rows = lots.rows_of(b["lot"])
    for k, want in ((SIDE, 4.0), (REAR, 6.0), (FRONT, 3.0)):
        s = np.flatnonzero(e.kind == k)
        line = shapely.linestrings(np.stack([e.p0[s], e.p1[s]], axis=1))
        for bi in range(len(b)):
            mine = e.lot[s] == rows[bi]
            if mine.any():
                assert shapely.distance(b.geometry[bi], line[mine]).min() >= want - 1e-6
    assert (party_walls(b.geometry) == 0).all()


@st.composite
def odd_lots(draw):
    """Concave, thin, tiny, holed and rotated lots cut out of a block, not only rectangles."""
    kind = draw(st.sampled_from(["star", "thin", "tiny", "holed", "skew", "rect"]))
    rng = np.random.default_rng(draw(st.integers(0, 2**31)))
    if kind == "star":
        k = draw(st.integers(5, 12))
        ang = np.sort(rng.uniform(0, 2 * np.pi, k))
        r = rng.uniform(15, 80, k)
        block = shapely.Polygon(np.c_[r * np.cos(ang), r * np.sin(ang)])
    elif kind == "thin":
        block = shapely.box(0, 0, draw(st.floats(60, 300)), draw(st.floats(3, 12)))
    elif kind == "tiny":
        block = shapely.box(0, 0, draw(st.floats(2, 12)), draw(st.floats(2, 12)))
    elif kind == "holed":
        w = draw(st.floats(60, 160))
        block = shapely.box(0, 0, w, w).difference(shapely.box(0.35 * w, 0.3 * w, 0.65 * w, 0.7 * w))
    elif kind == "skew":
        block = shapely.Polygon([(0, 0), (120, 10), (140, 70), (-20, 60)])
    else:
        block = shapely.box(0, 0, draw(st.floats(30, 200)), draw(st.floats(30, 120)))
    block = shapely.make_valid(block)
    block = max(shapely.get_parts(block), key=lambda p: p.area) if block.geom_type != "Polygon" else block
    # cut it into strips across its long side: lots with street fronts, odd ends
    x0, y0, x1, y1 = block.bounds
    cuts = np.sort(rng.uniform(x0, x1, draw(st.integers(1, 5))))
    edges = np.r_[x0 - 1, cuts, x1 + 1]
    lots = []
    for a, c in zip(edges[:-1], edges[1:]):
        piece = shapely.intersection(block, shapely.box(a, y0 - 1, c, y1 + 1))
        lots += [p for p in shapely.get_parts(piece) if p.geom_type == "Polygon" and p.area > 0.5]
    angle = draw(st.floats(0, 180))
    rot = lambda g: shapely.affinity.rotate(g, angle, origin=(0, 0))  # noqa: E731
    return [rot(g) for g in lots], rot(block)


@SETTINGS
@given(
    odd_lots(),
    st.sampled_from(TYPOLOGIES),
    st.sampled_from(["attached", "detached"]),
    st.floats(0, 6),
    st.integers(0, 1),
)
def test_no_building_leaves_its_lot_or_setbacks(data, typology, siting, front, loc):
    lots_g, block = data
    lots = Layer.from_geoms(lots_g, block=np.zeros(len(lots_g), np.int64), district=np.zeros(len(lots_g), np.int64))
    blocks = Layer.from_geoms([block], ids=[0])
    b, report = run(
        lots,
        blocks,
        typology=typology,
        siting=siting,
        setback_front=front,
        setback_side=4,
        setback_rear=4,
        loc=loc,
        far=2.0,
    )
    assert shapely.is_valid(b.geometry).all() and (shapely.area(b.geometry) > 0).all()
    assert (shapely.get_type_id(b.geometry) == 3).all()
    rows = lots.rows_of(b["lot"])
    assert (rows >= 0).all()
    assert shapely.within(b.geometry, shapely.buffer(lots.geometry[rows], 1e-6)).all()
    # the parts of one lot never overlap
    i, j = shapely.STRtree(b.geometry).query(b.geometry, predicate="intersects")
    sel = i < j
    assert (
        shapely.area(shapely.intersection(b.geometry[i[sel]], b.geometry[j[sel]], grid_size=GRID)).max(initial=0.0)
        < 1e-6
    )
    # clear of the street by the front setback (the building area is the lot minus its setbacks)
    e = lot_edges(lots.geometry, blocks=blocks.geometry, owner=np.zeros(len(lots), np.int64))
    s = np.flatnonzero(e.kind == FRONT)
    line = shapely.linestrings(np.stack([e.p0[s], e.p1[s]], axis=1))
    for bi in range(len(b)):
        mine = e.lot[s] == rows[bi]
        if mine.any():
            assert shapely.distance(b.geometry[bi], line[mine]).min() >= front - 1e-6
    assert report["buildings"] == len(b)
    np.testing.assert_allclose(b["gfa"], shapely.area(b.geometry) * b["floors"])


# -- heights, rules, levels of control -------------------------------------------------------


def test_map_heights_are_capped_by_far_and_height_class(tmp_path):
    plan, layers = grid_city(height_map=tmp_path)
    lots, blocks = layers["lots"], layers["blocks"]
    free, _ = run(lots, blocks, plan=plan, typology="I")
    assert free["far"].max() > 10  # the 240 m skyline
    capped, report = run(lots, blocks, plan=plan, typology="I", far=4)
    assert capped["far"].max() <= 4 * 1.05 + 1e-9 and report["far_iterated"] > 0
    low, _ = run(lots, blocks, plan=plan, typology="I", height_class="V")  # 12-21 m
    assert (low["floors"] * 3.2).max() <= 21.0 + 1e-9
    # where the map asks for less than the cap, the map stands
    under = np.isin(capped["lot"], free["lot"][free["far"] <= 4.0])
    kept = free.take(np.flatnonzero(np.isin(free["lot"], capped["lot"][under])))
    np.testing.assert_array_equal(np.sort(kept["floors"]), np.sort(capped["floors"][under]))


def test_district_and_landuse_rules_and_lot_columns(tmp_path):
    plan, layers = grid_city()
    lots, blocks = layers["lots"], layers["blocks"]
    plan = CityPlan(
        rules=[
            Rule("district", {"use": "office", "typology": "O", "far": "3", "loc": "0", "roof": "parapet"}, "x.xml:3")
        ]
    )
    b, _ = run(lots, blocks, plan=plan)
    assert set(b["typology"]) <= {"O", "I", "box"} and (b["use"] == "office").all()
    assert (b["roof"] == "parapet").all() and np.all(np.abs(b["far"] - 3) <= 0.15 + 1e-9)
    # a lot's own column wins over its district's rule
    col = np.where(lots.ids % 2 == 0, "tower", "I").astype(object)
    b2, _ = run(lots.with_columns(typology=col, far=np.full(len(lots), 1.5)), blocks, plan=plan)
    even = b2["lot"] % 2 == 0
    assert set(b2["typology"][~even]) <= {"I", "box"} and np.all(np.abs(b2["far"] - 1.5) <= 0.075 + 1e-9)
    with pytest.raises(ParameterError, match=r"x.xml:3.*typology 'Q'"):
        run(lots, blocks, plan=CityPlan(rules=[Rule("district", {"typology": "I,Q"}, "x.xml:3")]))
    with pytest.raises(ParameterError, match=r"x.xml:3.*height-class"):
        run(lots, blocks, plan=CityPlan(rules=[Rule("district", {"height-class": "IX"}, "x.xml:3")]))


@pytest.mark.parametrize(
    "column, value, message",
    [
        (
            "building_depth",
            "deep",
            r"^node 'buildings' \(buildings.massing\): lot column building_depth='deep' is not a valid float$",
        ),
        ("far", -1.0, r"^node 'buildings' \(buildings.massing\): lot column far=-1.0 is below the minimum 0.0$"),
        ("floors", np.inf, r"^node 'buildings' \(buildings.massing\): lot column floors=inf is not a valid int$"),
        (
            "house_width",
            2.0,
            r"^node 'buildings' \(buildings.massing\): lot column house_width=2.0 m is below the minimum 4.0 m$",
        ),
        ("typology", "I,Q", r"^node 'buildings' \(buildings.massing\): unknown typology 'Q' \(expected .*\)$"),
        (
            "siting",
            "terrace",
            r"^node 'buildings' \(buildings.massing\): lot column siting='terrace' is not one of auto, attached, detached$",
        ),
    ],
)
def test_a_lot_file_value_its_rule_would_refuse_is_a_one_line_error(column, value, message):
    lots, blocks = row_block(15.0)
    vals = np.full(len(lots), None, dtype=object)
    vals[2] = value  # one bad lot among lots that give none
    with pytest.raises(ParameterError, match=message) as err:
        run(lots.with_columns(**{column: vals}), blocks)
    assert "\n" not in str(err.value)


def test_a_detached_house_is_its_width_by_its_depth_on_a_corner_plot_too():
    """A corner plot's front band runs along both streets; the house stays one rectangle on its main front."""
    lots, blocks = row_block(30.0, depth=40.0, count=3, rows=1, angle=17.0)
    width, depth = np.array([14.0, 12.0, 16.0]), np.array([10.0, 11.0, 9.0])
    lots = lots.with_columns(typology=np.full(3, "house", dtype=object), house_width=width, building_depth=depth)
    b, _ = run(lots, blocks, loc=1, siting="detached", semi_detached=0.0, setback_front=3.0)
    row = np.asarray(b["lot"], np.int64)
    assert sorted(row.tolist()) == [0, 1, 2]
    _, _, long_, short = obb_frame(b.geometry)
    assert long_ == pytest.approx(width[row]) and short == pytest.approx(depth[row])
    assert shapely.area(b.geometry) == pytest.approx(width[row] * depth[row])


def test_a_house_on_a_wedge_plot_is_a_rectangle_not_a_triangle():
    """Wedge plots fanning to a point behind the street: a house keeps four square corners or stays a garden."""
    tip = (60.0, 60.0)  # six wedges, 20 m of street front each, meeting 60 m behind it
    xs = np.arange(0.0, 121.0, 20.0)
    geoms = [shapely.Polygon([(a, 0.0), (b, 0.0), tip]) for a, b in zip(xs[:-1], xs[1:])]
    n = len(geoms)
    lots = Layer.from_geoms(
        geoms,
        block=np.zeros(n, np.int64),
        district=np.zeros(n, np.int64),
        typology=np.full(n, "house", dtype=object),
        house_width=np.full(n, 13.0),
        building_depth=np.full(n, 10.0),
    )
    block = Layer.from_geoms([shapely.union_all(geoms)], ids=[0])
    b, _ = run(lots, block, loc=1, siting="detached", semi_detached=0.0)
    assert len(b) >= 2
    _, _, long_, short = obb_frame(b.geometry)
    assert (shapely.area(b.geometry) >= 0.8 * long_ * short).all()  # near rectangles: a corner trimmed at most
    own = lots.geometry[lots.rows_of(np.asarray(b["lot"], np.int64))]
    assert shapely.covers(shapely.buffer(own, 1e-6), b.geometry).all()
    assert (shapely.area(b.geometry) <= 13.0 * 10.0 * (1 + 1e-6)).all()


def test_custom_footprints_are_level_of_control_2():
    lots, blocks = row_block(20.0, depth=30.0, count=3, rows=1)
    mine = shapely.box(2, 2, 18, 20)
    custom = Layer.from_geoms([mine], lot=np.array([1]), height=np.array([31.0]))
    b, report = run(lots, blocks, custom=custom)
    c = b.take(np.flatnonzero(b["lot"] == 1))
    assert len(c) == 1 and shapely.equals(c.geometry[0], mine) and c["loc"][0] == 2 and c["height"][0] == 31.0
    assert c["floors"][0] == 9 and report["custom"] == 1
    assert len(b) == 3 and len(np.unique(b.ids)) == 3


def test_typologies_by_land_use_and_their_parts():
    plan, layers = grid_city()
    lots, blocks = layers["lots"], layers["blocks"]
    for use, kinds in (("commercial", {"towers", "hall", "L"}), ("educational", {"linked"})):
        b, report = run(lots, blocks, use=use)
        assert set(report["typologies"]) <= kinds | {"I", "box"}
        assert set(b["part"]) <= {"main", "podium"}
        podium = b["part"] == "podium"
        if podium.any():  # a podium is low, whatever its tower
            assert (b["floors"][podium] <= 2).all()
    towers, _ = run(lots, blocks, typology="tower")
    # a tower stands free: no party walls
    assert (party_walls(towers.geometry[towers["typology"] == "tower"]) == 0).all()


def test_roofs_oriented_to_the_street_and_within_the_envelope():
    plan, layers = grid_city()
    b, _ = run(layers["lots"], layers["blocks"], use="residential", typology="I")
    kinds = set(b["roof"])
    assert kinds <= {"flat", "parapet", "shed", "gable", "hip", "pyramid", "stepped"} and "gable" in kinds
    assert (b["roof_height"] <= 7.5 + 1e-9).all() and (b["roof_height"] >= 0).all()
    np.testing.assert_allclose(b["height"], b["floors"] * 3.2 + b["roof_height"])
    # grid_city's streets run at 12 deg and 102 deg: every roof follows one of them
    d = np.asarray(b["roof_direction"]) % 90.0
    assert np.all(np.minimum(np.abs(d - 12.0), np.abs(d - 102.0 % 90)) < 1e-6)


def test_same_seed_same_buildings_whatever_the_batch():
    plan, layers = grid_city()
    lots, blocks = layers["lots"], layers["blocks"]
    whole, _ = run(lots, blocks, seed=3, use="commercial")
    again, _ = run(lots, blocks, seed=3, use="commercial")
    half = len(lots) // 2
    a, _ = run(lots.take(np.arange(half)), blocks, seed=3, use="commercial")
    c, _ = run(lots.take(np.arange(half, len(lots))), blocks, seed=3, use="commercial")
    parts = Layer.concat([a, c], renumber=False)
    for other in (again, parts):
        np.testing.assert_array_equal(whole.ids, other.ids)
        assert shapely.to_wkb(whole.geometry).tolist() == shapely.to_wkb(other.geometry).tolist()
        for col in whole.columns:
            np.testing.assert_array_equal(whole[col], other[col])
    other_seed, _ = run(lots, blocks, seed=4, use="commercial")
    assert not np.array_equal(whole["typology"], other_seed["typology"][: len(whole)]) or len(other_seed) != len(whole)


def test_real_monaco_lots():
    lots = monaco_lots()  # the extract's building footprints standing in for irregular lots
    lots = lots.with_columns(district=np.zeros(len(lots), np.int64))
    b, report = run(lots, typology="I:3,L,U,O,tower,towers,hall,linked")
    assert len(np.unique(b["lot"])) > 0.7 * len(lots)
    assert shapely.is_valid(b.geometry).all()
    rows = lots.rows_of(b["lot"])
    assert shapely.within(b.geometry, shapely.buffer(lots.geometry[rows], 1e-6)).all()
    lot_gfa = np.bincount(rows, weights=b["gfa"], minlength=len(lots))
    np.testing.assert_allclose(lot_gfa[rows] / shapely.area(lots.geometry[rows]), b["far"], rtol=1e-9)


def test_monaco_and_helsinki_perimeter_blocks(tmp_path):
    """Real extracts, generated buildings only: party walls and street walls as real perimeter blocks have."""
    import sengine

    for name in ("monaco", "helsinki"):
        res = sengine.load(ROOT / "configs" / f"{name}.xml", sets=["buildings.keep=generated"]).run()
        walls = res.stats["report"]["planning"]["walls"]
        # real European perimeter blocks: a median 30-37 % of a building's outline is party wall
        assert 0.2 <= walls["party_wall_share_median"] <= 0.5, (name, walls)
        assert walls["street_wall_share_median"] >= 0.9, (name, walls)
        b = res.layers["buildings"]["buildings"]
        lots = res.layers["lots"]["lots"]
        planned = res.layers["planning"]["lots"]
        rows = lots.rows_of(b["lot"])
        assert shapely.within(b.geometry, shapely.buffer(lots.geometry[rows], 1e-6)).all()
        # the report's sums are the per-lot columns' sums, and the buildings' own gfa
        city = res.stats["report"]["planning"]["city"]
        assert city["floor_area_m2"] == pytest.approx(float(planned["floor_area"].sum()), abs=0.1)
        assert city["floor_area_m2"] == pytest.approx(float(b["gfa"].sum()), abs=0.1)
        assert city["footprint_m2"] == pytest.approx(float(planned["footprint"].sum()), abs=0.1)


def test_zones_give_the_land_use_and_landuse_rules_follow_it():
    lots, blocks = row_block(20.0, depth=30.0, count=4, rows=1)
    zones = Layer.from_geoms([shapely.box(-1, -1, 41, 31)], use=np.array(["educational"], dtype=object))
    plan = CityPlan(rules=[Rule("landuse", {"class": "educational", "far": "0.8", "loc": "0"}, "x.xml:4")])
    n = Massing("buildings", {}, Context(seed=7, plan=plan))
    b = n.run(lots=lots, blocks=blocks, zones=zones, **plan_inputs(plan, n))["buildings"]
    school = np.isin(b["lot"], lots.ids[:2])
    assert (b["use"][school] == "educational").all() and (b["use"][~school] == "residential").all()
    assert np.all(np.abs(b["far"][school] - 0.8) <= 0.04 + 1e-9) and (b["loc"][school] == 0).all()
    assert set(b["typology"][school]) <= {"linked", "I", "box"}


def test_osm_landuse_zones():
    from sengine import Context as Ctx

    read = get("osm.read")(
        "osm", {"path": str(ROOT / "configs/data/helsinki_centre.osm.pbf"), "extras": "landuse"}, Ctx()
    )
    result = read.run()
    zones = result["landuse"]
    uses = set(zones["use"])
    assert (
        {"residential", "commercial", "educational"}
        <= uses
        <= {
            "residential",
            "commercial",
            "office",
            "industrial",
            "educational",
        }
    )
    assert result.report["landuse"] == len(zones) > 50 and shapely.is_valid(zones.geometry).mean() > 0.95

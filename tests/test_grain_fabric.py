"""blocks.grain: each block's fabric (rural, houses, rows, urban) from the street grain, and lots and buildings that follow it."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
import shapely
from _lotcases import MINOR
from conftest import ROOT
from test_context import _street_grid
from test_lots_skeleton import check_partition
from test_massing import row_block

import sengine
from sengine import Context, Layer
from sengine.errors import InputDataError, ParameterError
from sengine.nodes.blocks.grain import FABRICS, fabric_of
from sengine.nodes.buildings.edges import lot_edges
from sengine.nodes.buildings.pairs import semi_pairs, side_neighbours
from sengine.nodes.buildings.walls import party_walls
from sengine.random import uniform
from sengine.registry import get

Grain = get("blocks.grain")
Context_ = get("buildings.context")
Recursive = get("lots.recursive")
Massing = get("buildings.massing")


def test_fabric_bands_and_the_house_chance_worked_by_hand():
    # rural under 8, urban from 14; between, houses where u < (14 - grain) / 6
    grain = np.array([0.0, 7.99, 8.0, 10.0, 10.0, 13.0, 13.0, 14.0, 30.0])
    u = np.array([0.99, 0.99, 0.99, 0.66, 0.67, 0.16, 0.17, 0.0, 0.0])
    names = np.asarray(FABRICS)[fabric_of(grain, u, 8.0, 14.0)]
    assert names.tolist() == ["rural", "rural", "houses", "houses", "rows", "houses", "rows", "urban", "urban"]
    # equal limits: no town band at all
    assert fabric_of(np.array([7.0, 8.0]), np.zeros(2), 8.0, 8.0).tolist() == [0, 3]


def _grid_roads():
    dense, k1 = _street_grid(0.0, 0.0, 3000.0, 100.0)  # 20 km/km2
    loose, k2 = _street_grid(10_000.0, 0.0, 3000.0, 200.0)  # 10 km/km2
    road = [shapely.LineString([(20_000.0, 0.0), (20_000.0, 3000.0)])]  # a country road
    return Layer.from_geoms(dense + loose + road, **{"class": np.concatenate([k1, k2, ["unclassified"]])})


def test_blocks_get_their_fabric_grain_and_lot_area_from_the_streets_round_them():
    xs = [1510.0] + [11_510.0 + 200.0 * k for k in range(6)] + [20_010.0]
    blocks = Layer.from_geoms([shapely.box(x, 1510, x + 80, 1590) for x in xs], ids=np.arange(10, 10 + len(xs)))
    out = Grain("grain", {}, Context(seed=3)).run(blocks=blocks, roads=_grid_roads())
    b = out["blocks"]
    grain = np.asarray(b["grain"])
    assert abs(grain[0] - 20.0) <= 2.0 and (np.abs(grain[1:7] - 10.0) <= 2.0).all() and grain[7] < 8.0
    u = uniform(3, "grain/houses", blocks.ids)
    town = np.where(u[1:7] < (14.0 - grain[1:7]) / 6.0, "houses", "rows")
    assert b["fabric"].tolist() == ["urban", *town, "rural"]
    want = {"rural": 1200.0, "houses": 800.0, "rows": 250.0, "urban": 300.0}
    assert np.asarray(b["lot_area"]).tolist() == [want[f] for f in b["fabric"]]
    counts = {f"blocks_{f}": int((np.asarray(b["fabric"]) == f).sum()) for f in FABRICS}
    assert out.report == {**counts, "urban_blocks_with_buildings": 0}
    # a map building in the urban block and one in the rural block: the urban block keeps the lot node's size
    houses = Layer.from_geoms([shapely.box(1520, 1520, 1530, 1530), shapely.box(20_020, 1520, 20_030, 1530)])
    built = Grain("grain", {}, Context(seed=3)).run(blocks=blocks, roads=_grid_roads(), existing=houses)
    assert np.asarray(built["blocks"]["lot_area"]).tolist() == [0.0, *np.asarray(b["lot_area"])[1:]]
    assert built.report["urban_blocks_with_buildings"] == 1
    # per block, not per batch: each block alone gets the same fabric
    for i in range(len(blocks)):
        one = Grain("grain", {}, Context(seed=3)).run(blocks=blocks.take([i]), roads=_grid_roads())["blocks"]
        assert one["fabric"][0] == b["fabric"][i] and one["grain"][0] == grain[i]


def test_a_rural_grain_above_the_urban_one_is_refused_in_one_line():
    with pytest.raises(ParameterError, match="rural_grain") as err:
        Grain("grain", {"rural_grain": "20", "urban_grain": "10"}, Context(seed=1))
    assert "grain" in str(err.value) and "\n" not in str(err.value)


def _sized_blocks(lot_area, fabric):
    n = len(lot_area)
    return Layer.from_geoms(
        [shapely.box(200.0 * i, 0.0, 200.0 * i + 120.0, 60.0) for i in range(n)],
        ids=np.arange(n),
        lot_area=np.asarray(lot_area, np.float64),
        fabric=np.asarray(fabric),
        grain=np.linspace(5.0, 20.0, n),
    )


def test_recursive_lots_take_each_blocks_lot_area_and_carry_its_fabric():
    blocks = _sized_blocks([250.0, 1200.0, 0.0], ["rows", "rural", "urban"])
    out = Recursive("lots", {"max_area": "800"}, Context(seed=1)).run(blocks=blocks)
    lots, report = out["lots"], out.report
    area = shapely.area(lots.geometry)
    block = np.asarray(lots["block"])
    largest = np.array([250.0, 1200.0, 800.0])[block]
    inner = np.asarray(lots["inner"], bool)
    assert int(((area > largest) & ~inner).sum()) == report["over_max_area"]
    # a lot over its block's size is one that no cut could halve without a part thinner than 1:6
    # (a 30 m deep row lot 9.5 m wide): a little over, never twice
    assert (area[~inner] <= 1.2 * largest[~inner]).all() and report["over_max_area"] == report["recursive_stuck"]
    med = [np.median(area[(block == k) & ~inner]) for k in range(3)]
    assert med[0] < 250.0 < med[2] < 800.0 < med[1]  # rows < urban (the node's 800) < rural
    # the lots partition their blocks, and carry their block's fabric and grain
    for k in range(3):
        assert shapely.area(shapely.union_all(lots.geometry[block == k])) == pytest.approx(7200.0, rel=1e-9)
    assert np.asarray(lots["fabric"]).tolist() == np.asarray(blocks["fabric"])[block].tolist()
    np.testing.assert_array_equal(np.asarray(lots["grain"]), np.asarray(blocks["grain"])[block])


def test_a_lot_area_below_the_lot_nodes_min_area_is_refused_in_one_line():
    blocks = _sized_blocks([20.0, 800.0], ["rows", "rural"])
    with pytest.raises(ParameterError, match="lot_area 20 m2 is below min_area=50") as err:
        Recursive("lots", {}, Context(seed=1)).run(blocks=blocks)
    assert "lots" in str(err.value) and "\n" not in str(err.value)


def _fabric_lots(fabric):
    n = len(fabric)
    return Layer.from_geoms(
        [shapely.box(20.0 * i, 0, 20.0 * i + 15, 30) for i in range(n)],
        ids=np.arange(n),
        fabric=np.asarray(fabric),
        grain=np.full(n, 10.0),
    )


def test_the_context_builds_what_the_blocks_fabric_says():
    lots = _fabric_lots(["rural", "houses", "rows", "urban"])
    out = Context_("context", {}, Context(seed=1)).run(lots=lots)
    got = out["lots"]
    assert np.asarray(got["floors"]).tolist() == [2.0, 2.0, 2.0, 3.0]  # a town centre of three storeys
    assert got["typology"].tolist() == ["house", "house", "I:3,L", "I:4,L,U"]  # no towers on the streets' word
    assert got["siting"].tolist() == ["detached", "detached", "", ""]  # houses stand apart
    depth = np.asarray(got["building_depth"])  # terraces 10 m deep, houses as deep as their drawn area makes them
    width = np.asarray(got["house_width"])
    assert depth[2] == 10.0 and np.isnan(depth[3]) and np.isnan(width[2:]).all()
    assert (width[:2] / depth[:2]) == pytest.approx([1.2, 1.2]) and (width[:2] * depth[:2] > 48.0).all()
    params = {"urban_floors": "0", "urban_typology": "", "house_depth": "0", "house_area": "0"}
    off = Context_("context", params, Context(seed=1))
    got = off.run(lots=lots)["lots"]
    assert np.isnan(got["floors"][3]) and got["typology"][3] == "" and "building_depth" not in got
    assert out.report["rural_lots"] == 1 and out.report["town_lots"] == 2 and out.report["town_houses"] == 1
    with pytest.raises(ParameterError, match="urban_typology") as err:
        Context_("context", {"urban_typology": "I,castle"}, Context(seed=1))
    assert "\n" not in str(err.value)
    with pytest.raises(InputDataError, match="fabric 'suburb'") as err:
        Context_("context", {}, Context(seed=1)).run(lots=_fabric_lots(["rural", "suburb"]))
    assert "\n" not in str(err.value)


def test_a_house_on_a_plot_too_narrow_to_stand_free_is_a_terrace_with_party_walls():
    lots, blocks = row_block(7.0, depth=30.0, count=8, rows=2, angle=17.0)  # two rows back to back
    node = Massing("buildings", {"typology": "house", "siting": "attached", "floors": "2"}, Context(seed=1))
    out = node.run(lots=lots, blocks=blocks)
    b = out["buildings"]
    # 7 m minus 4 m side setbacks leaves under half a house: each stands on its side lot lines instead,
    # the end-of-terrace houses on the corners too
    assert len(b) == 16 and out.report["attached_narrow"] == 16
    assert set(b["typology"]) == {"I"} and set(b["siting"]) == {"attached"}
    walls = party_walls(b.geometry)
    end = np.isin(np.asarray(b["lot"]) % 8, (0, 7))
    np.testing.assert_allclose(walls[~end], 2 * 14.0, rtol=1e-6)  # both 14 m side walls shared
    # the corner houses run along the side street too: they meet the row behind, back to back
    np.testing.assert_allclose(walls[end], 14.0 + 7.0, rtol=1e-6)
    # a lot wide enough keeps the detached house and its side setbacks
    wide, wide_blocks = row_block(20.0, depth=30.0, count=3, rows=2)
    out = node.run(lots=wide, blocks=wide_blocks)
    assert out.report["attached_narrow"] == 0 and set(out["buildings"]["typology"]) == {"house"}
    assert len(out["buildings"]) == 6 and (party_walls(out["buildings"].geometry) == 0).all()


def test_a_lots_building_depth_sets_how_deep_its_house_or_terrace_is():
    lots, blocks = row_block(7.0, depth=30.0, count=8, rows=2, angle=23.0)  # terraces, rotated
    node = Massing("buildings", {"typology": "I", "siting": "attached", "floors": "2"}, Context(seed=1))
    deep = node.run(lots=lots, blocks=blocks)["buildings"]
    shallow = node.run(lots=lots.with_columns(building_depth=np.full(16, 10.0)), blocks=blocks)["buildings"]
    assert len(deep) == len(shallow) == 16
    mid = ~np.isin(np.asarray(deep["lot"]) % 8, (0, 7))  # the end houses turn the corner
    np.testing.assert_allclose(shapely.area(deep.geometry[mid]), 7.0 * 14.0, rtol=1e-6)  # the massing's depth
    np.testing.assert_allclose(shapely.area(shallow.geometry[mid]), 7.0 * 10.0, rtol=1e-6)
    # a lot with no depth of its own (NaN) keeps the node's
    mixed = lots.with_columns(building_depth=np.where(np.arange(16) < 8, 10.0, np.nan))
    got = node.run(lots=mixed, blocks=blocks)["buildings"]
    lot = np.asarray(got["lot"])
    inner = ~np.isin(lot % 8, (0, 7))
    np.testing.assert_allclose(shapely.area(got.geometry[inner]), np.where(lot[inner] < 8, 70.0, 98.0), rtol=1e-6)


def test_a_terrace_shares_its_roof_kind_and_lots_elsewhere_draw_their_own():
    lots, blocks = row_block(7.0, depth=30.0, count=12, rows=2)
    node = Massing("buildings", {"typology": "I", "use": "residential", "floors": "2"}, Context(seed=1))
    alone = node.run(lots=lots, blocks=blocks)["buildings"]
    assert len(set(alone["roof"])) > 1  # 24 draws from gable, hip, parapet and flat
    terrace = node.run(lots=lots.with_columns(fabric=np.full(len(lots), "rows")), blocks=blocks)["buildings"]
    assert len(terrace) == len(alone) and len(set(terrace["roof"])) == 1
    # only the roofs differ: the same footprints
    np.testing.assert_array_equal(terrace.geometry, alone.geometry)


def test_a_detached_house_on_a_narrow_plot_leaves_a_garden():
    lots, blocks = row_block(7.0, depth=30.0, count=3, rows=1)
    node = Massing("buildings", {"typology": "house", "floors": "2"}, Context(seed=1))
    out = node.run(lots=lots.with_columns(siting=np.full(3, "detached", dtype=object)), blocks=blocks)
    assert len(out["buildings"]) == 0 and out.report["attached_narrow"] == 0


@pytest.mark.slow
def test_on_monaco_rows_are_narrow_terraces_and_houses_wide_detached_plots():
    """Monaco's streets read as a town (grain bands 0-40): row lots 5-11 m wide with party walls, house lots wider."""
    net = sengine.load(
        ROOT / "configs" / "monaco.xml",
        sets=["grain.rural_grain=0", "grain.urban_grain=40", "context.min_neighbours=200"],
    )
    result = net.run(seed=1)
    lots = result.layers["fields"]["lots"]
    fabric = np.asarray(lots["fabric"]).astype(str)
    street = (np.asarray(lots["frontage"]) > 0) & ~np.asarray(lots["inner"], bool)
    rows, houses = street & (fabric == "rows"), street & (fabric == "houses")
    assert rows.sum() > 300 and houses.sum() > 100
    front = np.asarray(lots["frontage"])
    assert 5.0 <= np.median(front[rows]) <= 11.0 < np.median(front[houses])
    gen = result.layers["generated"]["buildings"]
    of = dict(zip(lots.ids.tolist(), fabric))
    bf = np.array([of[int(k)] for k in gen["lot"]])
    walls = party_walls(gen.geometry) / shapely.length(gen.geometry)
    assert np.median(walls[bf == "rows"]) > 0.3  # terraces: both side walls shared
    assert np.median(walls[bf == "houses"]) == 0.0  # houses stand apart
    # each block's terraces have one roof kind
    block = np.asarray(lots["block"])[lots.rows_of(gen["lot"])]
    attached = (bf == "rows") & (np.asarray(gen["siting"]) == "attached")
    kinds = {b: set(np.asarray(gen["roof"])[attached & (block == b)]) for b in np.unique(block[attached])}
    assert len(kinds) > 5 and all(len(k) == 1 for k in kinds.values())
    # the report counts what the layers hold
    report = result.stats["report"]
    assert report["grain"]["blocks_rows"] == int(
        (np.asarray(result.layers["grain"]["blocks"]["fabric"]) == "rows").sum()
    )


# -- semi-detached pairs ----------------------------------------------------------------


def test_semi_pairs_pair_a_chain_from_its_first_lot_and_never_a_ring():
    # a street of 7 plots (0..6, left to right), plot 7 alone, plots 8-10 a ring round a small block
    left = np.array([-1, 0, 1, 2, 3, 4, 5, -1, 10, 8, 9])
    right = np.array([1, 2, 3, 4, 5, 6, -1, -1, 9, 10, 8])
    yes = np.ones(11, bool)
    got = semi_pairs(left, right, yes, np.zeros(11), 1.0)
    assert got.tolist() == ["right", "left", "right", "left", "right", "left", "", "", "", "", ""]
    assert (semi_pairs(left, right, yes, np.zeros(11), 0.0) == "").all()
    # the draw is read at the left plot of each pair
    u = np.array([0.9, 0.0, 0.1, 0.0, 0.9, 0.0, 0.0, 0, 0, 0, 0])
    assert semi_pairs(left, right, yes, u, 0.5).tolist()[:7] == ["", "", "right", "left", "", "", ""]
    # a plot that may not hold a pair breaks the chain: 3 out, so 4 starts a new one
    no3 = yes.copy()
    no3[3] = False
    assert semi_pairs(left, right, no3, np.zeros(11), 1.0).tolist()[:7] == [
        "right",
        "left",
        "",
        "",
        "right",
        "left",
        "",
    ]
    # neighbours that do not see each other are no pair
    bad = left.copy()
    bad[1] = -1
    assert semi_pairs(bad, right, yes, np.zeros(11), 1.0).tolist()[:3] == ["", "right", "left"]


@pytest.mark.parametrize("angle", [0.0, 33.0, -121.0])
def test_side_neighbours_of_two_rows_seen_from_their_streets(angle):
    lots, blocks = row_block(16.0, depth=35.0, count=5, rows=2, angle=angle)  # lots 0-4 face y = 0, 5-9 y = 70
    edges = lot_edges(lots.geometry, blocks=blocks.geometry, owner=np.zeros(len(lots), np.int64))
    left, right = side_neighbours(lots.geometry, edges)
    # the front row is seen from the south: its left is west; the back row is seen from the north
    assert left[1:4].tolist() == [0, 1, 2] and right[1:4].tolist() == [2, 3, 4]
    assert left[6:9].tolist() == [7, 8, 9] and right[6:9].tolist() == [5, 6, 7]


def test_semi_detached_houses_share_one_wall_and_keep_the_other_setback():
    lots, blocks = row_block(16.0, depth=35.0, count=8, rows=2, angle=20.0)
    params = {"typology": "house", "siting": "detached", "floors": "2", "semi_detached": "1"}
    out = Massing("buildings", params, Context(seed=1)).run(lots=lots, blocks=blocks)
    b = out["buildings"]
    walls = party_walls(b.geometry)
    corner = np.isin(np.asarray(b["lot"]) % 8, (0, 7))
    # the corner houses face two streets and stand alone; the six between pair off, one 14 m wall each
    assert out.report["semi_detached"] == 12 and (walls[corner] == 0).all()
    np.testing.assert_allclose(walls[~corner], 14.0, rtol=1e-6)
    # each is 0.7 of a house (10 m) wide and keeps 4 m from its other side line
    np.testing.assert_allclose(shapely.area(b.geometry[~corner]), 0.7 * 10.0 * 14.0, rtol=1e-6)
    sides = [shapely.boundary(lots.geometry[k]) for k in np.asarray(b["lot"])[~corner]]
    gap = shapely.distance(b.geometry[~corner], np.asarray(sides, dtype=object))
    assert (gap < 1e-6).all()  # on one side line (its partner's) ...
    # ... and none stands nearer than 4 m to a lot that is not its partner
    g = b.geometry
    i, j = shapely.STRtree(g).query(g, predicate="dwithin", distance=3.99)
    pair_ids = set(map(tuple, np.sort(np.c_[i[i != j], j[i != j]], axis=1).tolist()))
    assert all(abs(int(b["lot"][x]) - int(b["lot"][y])) == 1 for x, y in pair_ids)
    assert len(pair_ids) == 6
    # a pair is built as one: one roof kind (and so one height), while the pairs draw theirs apart
    roof = np.asarray(b["roof"]).astype(str)
    assert all(roof[x] == roof[y] for x, y in pair_ids) and len({roof[x] for x, _ in pair_ids}) > 1
    np.testing.assert_allclose([b["height"][x] - b["height"][y] for x, y in pair_ids], 0.0, atol=1e-9)
    none = Massing("buildings", {**params, "semi_detached": "0"}, Context(seed=1)).run(lots=lots, blocks=blocks)
    assert none.report["semi_detached"] == 0 and (party_walls(none["buildings"].geometry) == 0).all()


# -- skeleton and paris lots take the block's lot size too ------------------------------------------

Skeleton = get("lots.skeleton")
Paris = get("lots.paris")
District = get("lots.district")


@cache
def _monaco_grain_blocks() -> Layer:
    """Monaco's blocks (load-map nodes) through blocks.grain with the town band 0-40 km/km2: rows and houses.

    Moved to a local frame (south-west corner at the origin) after the grain is measured, for the overlays.
    """
    ctx = Context(seed=1)
    read = {"path": str(ROOT / "configs/data/monaco.osm.pbf"), "extras": "", "minor": MINOR}
    roads = get("osm.read")("majorRoads", read, ctx).run()["roads"]
    roads = get("roads.clean")("clean", {"sliver_width": 6}, ctx).run(roads=roads)["roads"]
    blocks = get("blocks.circuits")("blocks", {"node": False, "sidewalk": 2, "min_area": 50}, ctx).run(roads=roads)
    grain = Grain("grain", {"rural_grain": "0", "urban_grain": "40"}, ctx).run(blocks=blocks["blocks"], roads=roads)
    b = grain["blocks"]
    origin = shapely.bounds(b.geometry)[:, :2].min(axis=0)
    return Layer.from_geoms(
        shapely.transform(b.geometry, lambda xy: xy - origin),
        ids=b.ids,
        **{c: np.asarray(b[c]) for c in ("grain", "fabric", "lot_area")},
    )


def _without_lot_area(blocks: Layer) -> Layer:
    return Layer.from_geoms(blocks.geometry, ids=blocks.ids, grain=blocks["grain"], fabric=blocks["fabric"])


def _street_median(lots: Layer, fabric: str, column: str) -> float:
    sel = (np.asarray(lots["fabric"]) == fabric) & (np.asarray(lots["kind"]) != "inner")
    value = shapely.area(lots.geometry) if column == "area" else np.asarray(lots[column])
    return float(np.median(value[sel]))


@pytest.mark.parametrize("node", [Skeleton, Paris])
def test_skeleton_and_paris_lots_follow_each_blocks_lot_area_on_monaco(node):
    blocks = _monaco_grain_blocks()
    fabric = np.asarray(blocks["fabric"])
    assert (fabric == "rows").sum() >= 10 and (fabric == "houses").sum() >= 20  # both fabrics on real blocks
    lots = node("lots", {}, Context(seed=1)).run(blocks=blocks)["lots"]
    check_partition(blocks, lots)
    # a 250 m2 row plot at the node's 22 m depth is 11.4 m wide, an 800 m2 house plot 36 m: 0.31 of it
    rows, houses = (_street_median(lots, f, "frontage") for f in ("rows", "houses"))
    assert 9.0 <= rows <= 14.0 and 0.2 <= rows / houses <= 0.4
    rows_a, houses_a = (_street_median(lots, f, "area") for f in ("rows", "houses"))
    assert rows_a <= 300.0 and 0.2 <= rows_a / houses_a <= 0.45
    # without the column every block gets the node's own size (15 m skeleton lots, 20 m Paris segments)
    same = node("lots", {}, Context(seed=1)).run(blocks=_without_lot_area(blocks))["lots"]
    one = _street_median(same, "rows", "frontage") / _street_median(same, "houses", "frontage")
    assert 0.7 <= one <= 1.4


@pytest.mark.parametrize("node", [Skeleton, Paris])
def test_blocks_without_a_lot_area_get_the_same_bytes_as_before(node):
    blocks = _monaco_grain_blocks()
    # rows blocks keep their 250 m2; the others are set to 0 (the node's own size)
    own = np.where(np.asarray(blocks["fabric"]) == "rows", 250.0, 0.0)
    mixed = node("lots", {}, Context(seed=1)).run(blocks=blocks.with_columns(lot_area=own))["lots"]
    plain = node("lots", {}, Context(seed=1)).run(blocks=_without_lot_area(blocks))["lots"]
    zero = np.asarray(blocks.ids)[own == 0]
    a, b = np.isin(mixed["block"], zero), np.isin(plain["block"], zero)
    assert a.sum() > 100 and a.sum() == b.sum()
    assert shapely.to_wkb(mixed.geometry[a]).tolist() == shapely.to_wkb(plain.geometry[b]).tolist()
    np.testing.assert_array_equal(np.asarray(mixed.ids)[a], np.asarray(plain.ids)[b])
    # and the rows blocks did change
    assert (~a).sum() != (~b).sum()


@pytest.mark.parametrize("method,node", [("skeleton", Skeleton), ("paris", Paris)])
def test_district_lots_by_skeleton_or_paris_take_the_lot_area_as_their_nodes_do(method, node):
    blocks = _monaco_grain_blocks()
    got = District("lots", {"default": method}, Context(seed=1)).run(blocks=blocks)["lots"]
    want = node("lots", {}, Context(seed=1)).run(blocks=blocks)["lots"]
    assert shapely.to_wkb(got.geometry).tolist() == shapely.to_wkb(want.geometry).tolist()


@pytest.mark.parametrize(
    "node,params,name", [(Skeleton, {}, "lot_area_min=50"), (Paris, {"min_area": "100"}, "min_area=100")]
)
def test_a_lot_area_below_the_skeleton_or_paris_minimum_is_refused_in_one_line(node, params, name):
    blocks = (
        _sized_blocks([20.0, 800.0], ["rows", "rural"]) if not params else _sized_blocks([80.0, 0.0], ["rows", "urban"])
    )
    with pytest.raises(ParameterError, match=f"lot_area .* m2 is below {name} m2") as err:
        node("lots", params, Context(seed=1)).run(blocks=blocks)
    assert "lots" in str(err.value) and "\n" not in str(err.value)

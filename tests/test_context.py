"""buildings.context: infill that fits, storeys and typologies from the map's tagged buildings around a lot."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from conftest import ROOT
from hypothesis import given, settings
from hypothesis import strategies as st

import sengine
from sengine import Context, Layer
from sengine.errors import ParameterError
from sengine.nodes.buildings.context import neighbour_floors, open_land
from sengine.random import normal, uniform
from sengine.registry import get

Node = get("buildings.context")


def run(lots, existing=None, roads=None, **params):
    out = Node("context", params, Context(seed=1)).run(lots=lots, existing=existing, roads=roads)
    return out["lots"], out.report


def _lots(xs):
    return Layer.from_geoms([shapely.box(x, 0, x + 15, 30) for x in xs], ids=np.arange(len(xs)))


def _houses(xs, floors, source="levels"):
    return Layer.from_geoms(
        [shapely.box(x, 40, x + 10, 50) for x in xs],
        floors=np.asarray(floors, np.int64),
        height_source=np.full(len(xs), source, dtype=object),
    )


def test_a_lot_takes_the_median_storeys_of_its_tagged_neighbours():
    lots = _lots([0.0, 2000.0])  # the second lot has no map building within 150 m
    houses = _houses([0, 20, 40, 60, 80], [2, 2, 3, 9, 2])
    out, report = run(lots, houses)
    assert out["floors"][0] == 2.0 and np.isnan(out["floors"][1])
    assert out["typology"].tolist() == ["I:3,L", ""]  # two storeys around: bars and L's, no towers
    assert report == {
        "lots_fitted": 1,
        "low_rise_lots": 1,
        "rural_lots": 0,
        "town_lots": 0,
        "town_houses": 0,
        "open_lots": 0,
    }


def test_untagged_buildings_and_too_few_neighbours_set_nothing():
    lots = _lots([0.0])
    # the reader's default height says nothing of the place
    out, _ = run(lots, _houses([0, 20, 40], [8, 8, 8], source="default"))
    assert np.isnan(out["floors"][0]) and out["typology"][0] == ""
    out, _ = run(lots, _houses([0, 20], [2, 2]))  # two, where three are asked for
    assert np.isnan(out["floors"][0])
    out, _ = run(lots, _houses([0, 20], [2, 2]), min_neighbours=2)
    assert out["floors"][0] == 2.0


def test_a_lots_own_rules_win_and_high_rise_keeps_every_typology():
    lots = _lots([0.0, 30.0]).with_columns(
        floors=np.array([np.nan, 4.0]), typology=np.array(["", "tower"], dtype=object)
    )
    out, _ = run(lots, _houses([0, 20, 40, 60], [7, 8, 8, 9]))
    assert out["floors"].tolist() == [8.0, 4.0]
    assert out["typology"].tolist() == ["", "tower"]  # eight storeys is no low-rise neighbourhood


@pytest.mark.parametrize("text", ["bogus", "I:-1", ""])
def test_a_bad_low_rise_typology_is_refused_naming_the_parameter(text):
    with pytest.raises(ParameterError, match="low_rise_typology") as err:
        Node("context", {"low_rise_typology": text}, Context(seed=1))
    assert "context" in str(err.value) and "\n" not in str(err.value)


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.tuples(st.floats(0, 500), st.floats(0, 500), st.integers(1, 30)), min_size=0, max_size=40),
    st.integers(1, 15),
    st.floats(10, 300),
    st.integers(1, 5),
)
def test_neighbour_floors_is_the_median_of_the_k_nearest_within_the_radius(houses, k, radius, need):
    sites = np.array([[100.0, 100.0], [400.0, 50.0], [250.0, 480.0]])
    xy = np.array([(x, y) for x, y, _ in houses]).reshape(-1, 2)
    floors = np.array([f for _, _, f in houses], float)
    got = neighbour_floors(sites, xy, floors, k=k, radius=radius, min_count=need)
    for s, value in zip(sites, got, strict=True):
        d = np.hypot(*(xy - s).T) if len(xy) else np.zeros(0)
        order = np.argsort(d, kind="stable")[:k]
        near = order[d[order] <= radius]
        if len(near) < need:
            assert np.isnan(value)
        else:  # ties at the k-th distance may swap which neighbour counts: compare as a median bound
            assert floors[near].min() <= value <= floors[near].max()
            if len(near) == len(np.unique(d[near])) and len(near) < k:
                assert value == pytest.approx(np.median(floors[near]))


def test_a_village_gets_no_towers(tmp_path):
    """Kirchberg an der Iller: the map's houses have two storeys; the free lots get houses, not towers."""
    net = sengine.load(
        ROOT / "configs" / "helsinki.xml", maps=[f"osm={ROOT / 'configs' / 'data' / 'kirchberg_iller.osm'}"]
    )
    result = net.run(seed=1)
    gen = result.layers["generated"]["buildings"]
    assert len(gen) > 10
    assert not np.isin(np.asarray(gen["typology"]).astype(str), ("tower", "towers", "U", "hall")).any()
    assert np.asarray(gen["floors"]).max() <= 3
    assert result.stats["report"]["context"]["lots_fitted"] == result.stats["counts"]["lots"]


def _street_grid(x0, y0, size, spacing, kind="residential"):
    """Streets every ``spacing`` m both ways over a ``size`` m square at (x0, y0)."""
    ticks = np.arange(0.0, size + 1e-9, spacing)
    lines = [shapely.LineString([(x0 + t, y0), (x0 + t, y0 + size)]) for t in ticks]
    lines += [shapely.LineString([(x0, y0 + t), (x0 + size, y0 + t)]) for t in ticks]
    return lines, np.full(len(lines), kind, dtype=object)


def test_the_street_grain_sets_storeys_and_typologies_where_the_map_has_no_buildings():
    # a dense grid (100 m: 20 km/km2), a looser one (200 m: 10) and a lone country road
    dense, k1 = _street_grid(0.0, 0.0, 3000.0, 100.0)
    loose, k2 = _street_grid(10_000.0, 0.0, 3000.0, 200.0)
    road = [shapely.LineString([(20_000.0, 0.0), (20_000.0, 3000.0)])]
    roads = Layer.from_geoms(dense + loose + road, **{"class": np.concatenate([k1, k2, ["unclassified"]])})
    lots = Layer.from_geoms(
        [shapely.box(x + 10, 1510, x + 25, 1540) for x in (1500.0, 11_500.0, 20_000.0)], ids=np.arange(3)
    )
    out, report = run(lots, roads=roads)
    grain = out["grain"]
    # 2 / spacing, give or take the one street each way that the 1,050 m square may catch or miss
    assert abs(grain[0] - 20.0) <= 2.0 and abs(grain[1] - 10.0) <= 2.0
    assert grain[2] < 8.0  # one road serves a band of land, not the fields beyond it
    # urban: a town centre of three storeys in perimeter blocks; houses and terraces 10 m deep
    assert out["floors"][0] == 3.0 and out["typology"][0] == "I:4,L,U"
    assert out["floors"][1:].tolist() == [2.0, 2.0]
    # the town lot is a house with the chance (14 - grain) / (14 - 8), drawn from (seed 1, "context", lot 1)
    house = uniform(1, "context/town-house", [1])[0] < (14.0 - grain[1]) / 6.0
    assert out["typology"][1:].tolist() == ["house" if house else "I:3,L", "house"]
    # a terrace is 10 m deep; a house is its own ground area, 138 m2 x exp(0.35 z), 1.2 times wider than deep
    depth, width = out["building_depth"], out["house_width"]
    assert np.isnan(depth[0]) and np.isnan(width[0])
    houses = np.array([house, True])
    ground = 138.0 * np.exp(0.35 * normal(1, "context/house", [1, 2]))
    assert depth[1:][~houses].tolist() == [10.0] and np.isnan(width[1:][~houses]).all()
    assert depth[1:][houses] * width[1:][houses] == pytest.approx(ground[houses])
    assert width[1:][houses] / depth[1:][houses] == pytest.approx(np.full(houses.sum(), 1.2))
    # the country road lot is 5 km from the nearest street lived on: a field
    assert out["open"].tolist() == [False, False, True]
    assert report == {
        "lots_fitted": 0,
        "low_rise_lots": 0,
        "rural_lots": 1,
        "town_lots": 1,
        "town_houses": int(house),
        "open_lots": 1,
    }


def test_houses_ground_areas_follow_statbel_classes_for_wallonia():
    """4,000 country lots: their houses' ground areas fall in Statbel's classes as Wallonia's detached houses do.

    Statbel, 1 January 2018, Wallonia's detached houses: 1,638 + 6,263 of 506,011 under 65 m² (1.6 %), and
    97,232 more up to 104 m² (20.8 % under 104 m²).
    """
    road = shapely.LineString([(0.0, 0.0), (0.0, 100_000.0)])
    roads = Layer.from_geoms([road], **{"class": np.array(["residential"], dtype=object)})
    lots = Layer.from_geoms(
        [shapely.box(5.0, y, 35.0, y + 20.0) for y in np.arange(4000) * 25.0], ids=np.arange(4000) * 7 + 3
    )
    out, report = run(lots, roads=roads)
    assert report["rural_lots"] == 4000
    ground = out["building_depth"] * out["house_width"]
    assert np.median(ground) == pytest.approx(138.0, rel=0.05)
    assert (ground < 104.0).mean() == pytest.approx(0.208, abs=0.03)
    assert (ground < 65.0).mean() == pytest.approx(0.016, abs=0.01)
    inner = (ground > 138.0 * np.exp(-1.05) + 1e-6) & (ground < 138.0 * np.exp(1.05) - 1e-6)  # z within 3
    assert inner.mean() > 0.99 and len(np.unique(np.round(ground[inner], 6))) == inner.sum()  # no two alike
    # house_area 0: every house the house depth, the width left to the massing
    flat, _ = run(lots, roads=roads, house_area=0.0)
    assert (flat["building_depth"] == 10.0).all() and "house_width" not in flat


@pytest.mark.parametrize("spacing", [150.0, 200.0, 250.0])
def test_town_houses_give_way_to_rows_as_the_grain_rises(spacing):
    """Detached houses in town with the chance (urban_grain - grain) / (urban_grain - rural_grain)."""
    grid, kinds = _street_grid(0.0, 0.0, 3000.0, spacing)
    roads = Layer.from_geoms(grid, **{"class": kinds})
    xs = np.arange(1000.0, 2000.0, 2.0)
    lots = Layer.from_geoms([shapely.box(x, 1510, x + 1, 1520) for x in xs], ids=np.arange(len(xs)))
    out, report = run(lots, roads=roads)
    grain = np.asarray(out["grain"])
    assert ((grain > 8.0) & (grain < 14.0)).all()  # about 2 / spacing: all town
    chance = (14.0 - grain) / 6.0
    houses = np.asarray(out["typology"]) == "house"
    assert report["town_houses"] == int(houses.sum()) and report["town_lots"] == len(xs)
    # 500 independent draws: within four standard errors of the expected count
    assert abs(houses.sum() - chance.sum()) <= 4.0 * np.sqrt((chance * (1 - chance)).sum())
    assert (np.asarray(out["floors"]) == 2.0).all()
    # the same seed gives the same houses
    again, _ = run(lots, roads=roads)
    assert (np.asarray(again["typology"]) == np.asarray(out["typology"])).all()


def test_motorways_add_no_grain_and_map_buildings_win_over_it():
    lots = _lots([0.0])
    motorway = Layer.from_geoms(
        [shapely.LineString([(-500.0, y), (500.0, y)]) for y in np.arange(-500.0, 501.0, 50.0)],
        **{"class": np.full(21, "motorway", dtype=object)},
    )
    out, report = run(lots, roads=motorway)
    assert out["grain"][0] == 0.0 and report["rural_lots"] == 1
    out, report = run(lots, _houses([0, 20, 40], [6, 6, 6]), roads=motorway)
    assert out["floors"][0] == 6.0 and report["rural_lots"] == 0 and report["lots_fitted"] == 1


def test_a_rural_grain_above_the_urban_one_is_refused():
    with pytest.raises(ParameterError, match="rural_grain") as err:
        Node("context", {"rural_grain": 20.0, "urban_grain": 10.0}, Context(seed=1))
    assert "context" in str(err.value) and "\n" not in str(err.value)


def test_a_village_from_its_streets_alone_gets_detached_houses():
    """Kirchberg an der Iller with its map buildings set aside: the village streets say houses, and houses stand apart."""
    net = sengine.load(
        ROOT / "configs" / "helsinki.xml", maps=[f"osm={ROOT / 'configs' / 'data' / 'kirchberg_iller.osm'}"]
    )
    net.set_param("context", "min_neighbours", 200)  # no lot has that many map buildings near
    # semi-detached pairs (the default) touch their partner only
    paired = net.run(seed=1).layers["generated"]["buildings"]
    houses = paired.geometry[np.asarray(paired["typology"]).astype(str) == "house"]
    a, b = shapely.STRtree(houses).query(houses, predicate="dwithin", distance=1.0)
    assert (np.bincount(a[a != b], minlength=len(houses)) <= 1).all()
    net.set_param("generated", "semi_detached", 0.0)
    result = net.run(seed=1)
    lots = result.layers["context"]["lots"]
    assert (np.asarray(lots["grain"]) < 8.0).all()
    gen = result.layers["generated"]["buildings"]
    typ = np.asarray(gen["typology"]).astype(str)
    # a house the plot cannot hold leaves a garden: no slab or box in its place
    assert len(gen) >= 10 and (typ == "house").all()
    assert np.asarray(gen["floors"]).max() <= 2
    houses = gen.geometry[typ == "house"]
    # detached: no two houses touch, and each keeps within the greatest house width along its street
    tree = shapely.STRtree(houses)
    a, b = tree.query(houses, predicate="dwithin", distance=1.0)
    assert (a == b).all()
    # each house at most its lot's drawn width along its street (the roof's direction is the street's), and
    # no larger than its drawn ground area (a narrow plot makes it deeper, never wider)
    angle = np.radians(np.asarray(gen["roof_direction"])[typ == "house"])
    xy, which = shapely.get_coordinates(houses, return_index=True)
    t = xy[:, 0] * np.cos(angle[which]) + xy[:, 1] * np.sin(angle[which])
    along = np.maximum.reduceat(t, np.r_[0, np.flatnonzero(np.diff(which)) + 1])
    along -= np.minimum.reduceat(t, np.r_[0, np.flatnonzero(np.diff(which)) + 1])
    row = lots.rows_of(np.asarray(gen["lot"], np.int64)[typ == "house"])
    width, depth = np.asarray(lots["house_width"])[row], np.asarray(lots["building_depth"])[row]
    assert (along <= width + 1e-6).all() and (shapely.area(houses) <= width * depth * (1 + 1e-6)).all()
    assert len(np.unique(np.round(width, 6))) == len(width)  # no two houses alike


def test_open_land_is_beyond_reach_of_every_street_lived_on():
    streets = np.array([shapely.LineString([(0, 0), (100, 0)]), shapely.LineString([(500, 0), (500, 100)])])
    sites = np.array([[50.0, 149.0], [50.0, 151.0], [-149.0, 0.0], [651.0, 50.0], [649.0, 50.0], [300.0, 0.0]])
    # distances by hand: 149, 151, 149, 151, 149, 200 (to the nearer street)
    assert open_land(sites, streets, 150.0).tolist() == [False, True, False, True, False, True]
    assert open_land(sites, np.array([], dtype=object), 150.0).all()  # no street lived on: nothing reaches
    assert open_land(np.zeros((0, 2)), streets, 150.0).shape == (0,)


def _village_and_country_road():
    """A village of residential streets 100 m apart (600 m square) and a 3 km unclassified road out of it."""
    village, kinds = _street_grid(0.0, 0.0, 600.0, 100.0)
    road = shapely.LineString([(600.0, 300.0), (3600.0, 300.0)])
    roads = Layer.from_geoms(village + [road], **{"class": np.concatenate([kinds, ["unclassified"]])})
    # lots along the country road, their sites 20 m off it, every 100 m from the village's edge
    xs = np.arange(610.0, 3500.0, 100.0)
    lots = Layer.from_geoms([shapely.box(x, 305, x + 15, 335) for x in xs], ids=np.arange(len(xs)))
    return roads, lots, xs


def test_country_road_lots_beyond_the_village_are_fields_and_stay_unbuilt():
    roads, lots, xs = _village_and_country_road()
    # a low rural grain everywhere along this road, so that only the distance decides
    out, report = run(lots, roads=roads, rural_grain=30.0, urban_grain=30.0)
    site_x = xs + 7.5
    # the nearest street lived on is the village's east edge at x = 600, its site 20 m off the road:
    expected = np.hypot(site_x - 600.0, 0.0) > 150.0
    assert out["open"].tolist() == expected.tolist()
    assert report["open_lots"] == int(expected.sum()) > 20 and report["rural_lots"] == len(xs)
    built = get("buildings.massing")("generated", {}, Context(seed=1)).run(lots=out)
    on = np.unique(np.asarray(built["buildings"]["lot"], np.int64))
    assert set(on.tolist()) == set(np.flatnonzero(~expected).tolist())  # every near lot built, no field
    assert built.report["open_land"] == int(expected.sum())


def test_no_fields_without_streets_lived_on_or_with_reach_zero():
    roads, lots, _ = _village_and_country_road()
    out, report = run(lots, roads=roads, rural_grain=30.0, urban_grain=30.0, village_reach=0.0)
    assert not np.asarray(out["open"]).any() and report["open_lots"] == 0
    untagged = roads.with_columns(**{"class": np.full(len(roads), "unclassified", dtype=object)})
    out, report = run(lots, roads=untagged, rural_grain=30.0, urban_grain=30.0)
    assert not np.asarray(out["open"]).any() and report["open_lots"] == 0
    # town and urban lots are never fields, however far the streets lived on
    out, report = run(lots, roads=roads, rural_grain=0.0, urban_grain=0.0)
    assert not np.asarray(out["open"]).any() and report["rural_lots"] == 0

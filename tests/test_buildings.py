"""buildings.extrude: footprints inside lots, heights from the height map, floors, determinism."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from _city import grid_city, monaco_lots
from hypothesis import given, settings
from hypothesis import strategies as st

import sengine.nodes.buildings.extrude as B
from sengine import Context, Layer
from sengine.nodes.maps import plan_inputs
from sengine.plan import CityPlan
from sengine.random import uniform
from sengine.registry import get

Extrude = get("buildings.extrude")


def run(lots, plan=None, seed=7, node_id="buildings", **params):
    node = Extrude(node_id, params, Context(seed=seed, plan=plan))
    ran = node.run(lots=lots, **(plan_inputs(plan, node) if plan is not None else {}))
    out = ran["buildings"]
    return out, ran.report


@pytest.fixture(scope="module")
def city(tmp_path_factory):
    return grid_city(height_map=tmp_path_factory.mktemp("maps"))


def assert_within_lots(buildings, lots):
    lot_of = dict(zip(lots.ids.tolist(), lots.geometry))
    lot_geoms = np.array([lot_of[i] for i in buildings["lot"].tolist()], dtype=object)
    inside = shapely.within(buildings.geometry, shapely.buffer(lot_geoms, 1e-6))
    assert inside.all(), f"{(~inside).sum()} footprints leave their lot"


def test_one_building_per_lot_inside_its_lot(city):
    plan, layers = city
    lots = layers["lots"]
    b, report = run(lots, plan, setback=2.0)
    assert len(b) == len(lots) == report["buildings"]
    assert report["skipped"] == 0
    assert_within_lots(b, lots)
    np.testing.assert_array_equal(b.ids, lots.ids)
    np.testing.assert_array_equal(b.parent, lots.ids)
    # the inset is exactly the setback: a rectangle loses 2 m on every side
    perimeter = shapely.length(lots.geometry)
    expected = shapely.area(lots.geometry) - 2.0 * perimeter + 16.0  # (w-4)(h-4) = wh - 2(2w+2h) + 16
    np.testing.assert_allclose(shapely.area(b.geometry), expected, rtol=1e-9)
    assert set(b.columns) >= {"height", "floors", "roof", "lot", "district"}
    assert (b["roof"] == "flat").all()
    assert b.meta["crs"] == lots.meta["crs"]


def test_heights_follow_map_and_snap_to_floors(city):
    plan, layers = city
    b, _ = run(layers["lots"], plan, floor_height=3.5, variation=0.25)
    h, f = b["height"], b["floors"]
    assert (f >= 1).all()
    np.testing.assert_array_equal(h, f * 3.5)
    assert h.min() >= 12.0 - 1e-9 and h.max() <= 240.0 + 1e-9
    # the map is brightest in the centre: central buildings are taller on average
    c = shapely.centroid(b.geometry)
    x, y = shapely.get_x(c), shapely.get_y(c)
    d = np.hypot(x - plan.size[0] / 2, y - plan.size[1] / 2)
    near, far = h[d < np.quantile(d, 0.2)], h[d > np.quantile(d, 0.8)]
    assert near.mean() > far.mean() + 20.0
    # and without variation each height is the map's value rounded to a floor
    b0, _ = run(layers["lots"], plan, floor_height=3.5, variation=0.0)
    img_h = B.sample_height_map(plan_inputs(plan, Extrude)["height_map"], x, y)[0]
    assert np.abs(b0["height"] - img_h).max() <= 3.5 / 2 + 1e-9


def test_no_height_map_uses_height_param(city):
    _, layers = city
    b, _ = run(layers["lots"], CityPlan(), height=30.0, variation=0.2, floor_height=3.0)
    assert b["height"].min() >= 24.0 - 1e-9 and b["height"].max() <= 36.0 + 1e-9
    np.testing.assert_array_equal(b["height"], b["floors"] * 3.0)
    assert len(np.unique(b["height"])) > 3  # the variation is there


def test_seeded_and_independent_of_chunking(city):
    plan, layers = city
    lots = layers["lots"]
    a, _ = run(lots, plan)
    b, _ = run(lots, plan)
    np.testing.assert_array_equal(a["height"], b["height"])
    # in two chunks, in reverse order: each lot's building is the same
    n = len(lots) // 3
    parts = [run(lots.take(np.arange(n, len(lots))[::-1]), plan)[0], run(lots.take(np.arange(n)), plan)[0]]
    joined = Layer.concat(parts, renumber=False)
    order = np.argsort(joined.ids)
    np.testing.assert_array_equal(joined.ids[order], a.ids)
    np.testing.assert_array_equal(joined["height"][order], a["height"])
    assert shapely.equals_exact(joined.geometry[order], a.geometry).all()
    # another seed or node id changes the draw
    assert not np.array_equal(run(lots, plan, seed=8)[0]["height"], a["height"])
    assert not np.array_equal(run(lots, plan, node_id="towers")[0]["height"], a["height"])


def test_uniform_is_uniform():
    u = uniform(3, "n", np.arange(200_000))
    assert 0.0 <= u.min() and u.max() < 1.0
    hist = np.histogram(u, bins=10, range=(0, 1))[0]
    assert np.abs(hist / 20_000 - 1).max() < 0.03
    assert abs(np.corrcoef(u[:-1], u[1:])[0, 1]) < 0.01


def test_small_lots_are_skipped_and_counted():
    lots = Layer.from_geoms(
        [shapely.box(0, 0, 3, 3), shapely.box(10, 0, 30, 20), shapely.box(40, 0, 41, 50)], ids=[5, 6, 7]
    )
    b, report = run(lots, None, setback=2.0, min_area=20.0)
    assert b.ids.tolist() == [6]
    assert report == {"buildings": 1, "skipped": 2, "courtyards": 0, "surveyed_heights": 0}
    empty, report = run(lots.take(np.zeros(3, bool)), None)
    assert len(empty) == 0 and report["skipped"] == 0


def test_real_monaco_footprints_as_lots():
    lots = monaco_lots()
    b, report = run(lots, None, setback=1.0, min_area=10.0)
    assert report["buildings"] + report["skipped"] == len(lots)
    assert report["buildings"] > 0.8 * len(lots)
    assert shapely.is_valid(b.geometry).all()
    assert (shapely.get_type_id(b.geometry) == 3).all()
    assert_within_lots(b, lots)
    assert (shapely.area(b.geometry) >= 10.0).all()


def test_bad_height_map_attributes_name_the_line(city, tmp_path):
    from sengine.errors import ConfigError, ParameterError
    from sengine.plan import MapSpec

    plan, layers = city

    def with_attrs(attrs):
        return CityPlan(
            size=plan.size, maps={"height": MapSpec("height", plan.maps["height"].src, attrs, "city.xml:7")}
        )

    # the height map's source node reads and checks it, before any building is made
    with pytest.raises(ParameterError, match=r"city.xml:7: min='x' is not a valid float"):
        run(layers["lots"], with_attrs({"min": "x"}))
    with pytest.raises(ConfigError, match=r"city.xml:7: height map needs min and max"):
        run(layers["lots"], with_attrs({"min": "30", "max": "10"}))


@settings(max_examples=60, deadline=None)
@given(
    w=st.floats(2, 80),
    h=st.floats(2, 80),
    angle=st.floats(0, 180),
    notch=st.floats(0, 0.9),
    setback=st.floats(0, 6),
)
def test_random_lots_footprints_inside(w, h, angle, notch, setback):
    import shapely.affinity as A

    lot = shapely.box(0, 0, w, h)
    if notch > 0:  # an L-shaped, concave lot
        lot = lot.difference(shapely.box(w * (1 - notch), h * (1 - notch), w + 1, h + 1))
    lot = A.rotate(lot, angle, origin=(0, 0))
    lots = Layer.from_geoms([lot])
    b, report = run(lots, None, setback=setback, min_area=1.0)
    assert report["buildings"] + report["skipped"] == 1
    if len(b):
        assert shapely.within(b.geometry[0], lot.buffer(1e-6))
        assert b.geometry[0].area >= 1.0
        assert b.geometry[0].area <= lot.area + 1e-9
        # the footprint keeps the setback from the lot boundary
        assert lot.exterior.distance(b.geometry[0]) >= setback * (1 - 1e-6) - 1e-6


def test_paris_courtyards_stay_open():
    """Inner lots (courtyards, no street frontage) get no building unless asked for."""
    blocks = Layer.from_geoms([shapely.box(0, 0, 120, 90), shapely.box(200, 0, 330, 110)], district=np.array([-1, -1]))
    ctx = Context(seed=3, plan=CityPlan(size=(400.0, 200.0)))
    lots = get("lots.paris")("lots", {"depth": "15"}, ctx).run(blocks=blocks)["lots"]
    inner = lots["inner"].astype(bool)
    assert inner.any() and (~inner).any()
    node = get("buildings.extrude")("b", {}, ctx)
    ran = node.run(lots=lots)
    built = ran["buildings"]
    assert not np.isin(built["lot"], lots.ids[inner]).any()
    assert ran.report["courtyards"] == int(inner.sum())
    with_courts = get("buildings.extrude")("b", {"courtyards": "true"}, ctx).run(lots=lots)["buildings"]
    assert np.isin(lots.ids[inner], with_courts["lot"]).all()


def test_surveyed_heights_of_existing_buildings_win():
    """A lot inside a tagged existing building (OSM) takes that height; untagged ones do not count."""
    lots = Layer.from_geoms([shapely.box(0, 0, 20, 30), shapely.box(30, 0, 50, 30), shapely.box(60, 0, 80, 30)])
    existing = Layer.from_geoms(
        [shapely.box(-5, -5, 25, 35), shapely.box(25, -5, 55, 35)],
        height=np.array([111.0, 60.0]),
        height_source=np.array(["height", "default"]),
    )
    ctx = Context(seed=1, plan=CityPlan(size=(100.0, 40.0)))
    node = get("buildings.extrude")("b", {"height": "12", "variation": "0"}, ctx)
    ran = node.run(lots=lots, existing=existing)
    built = ran["buildings"]
    assert built["height"].tolist() == pytest.approx([35 * 3.2, 4 * 3.2, 4 * 3.2])  # 111 m -> 35 floors
    assert ran.report["surveyed_heights"] == 1

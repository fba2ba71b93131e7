"""buildings.existing: the map's buildings stand, generated ones fill only the room they leave."""

from __future__ import annotations

import json

import numpy as np
import pytest
import shapely
from conftest import ROOT
from hypothesis import given, settings
from hypothesis import strategies as st

import sengine
from sengine import Context, Layer
from sengine.registry import get

Existing = get("buildings.existing")


def run(buildings, existing, lots=None, **params):
    node = Existing("existing", params, Context(seed=1))
    ran = node.run(buildings=buildings, existing=existing, lots=lots)
    return ran["buildings"], ran.report


def street_of_lots():
    """Five 20 m x 30 m lots in a row, a generated building inset 2 m on each."""
    lots = Layer.from_geoms(
        [shapely.box(20 * i, 0, 20 * i + 20, 30) for i in range(5)],
        ids=np.arange(10, 15),
        district=np.array([1, 1, 1, 2, 2]),
    )
    built = Layer.from_geoms(
        shapely.buffer(lots.geometry, -2.0, join_style="mitre"),
        ids=lots.ids,
        parent=lots.ids,
        height=np.full(5, 12.8),
        floors=np.full(5, 4),
        roof="flat",
        lot=lots.ids,
        district=lots["district"],
    )
    return lots, built


def test_existing_buildings_stand_and_generated_ones_keep_clear():
    lots, built = street_of_lots()
    existing = Layer.from_geoms(
        [
            shapely.box(3, 3, 15, 25),  # inside lot 10: its generated building goes
            shapely.box(37.5, 5, 42.5, 10),  # across lots 11 and 12, 2.5 m x 5 m into each: both go
            shapely.box(79, 0, 80, 1),  # a shed in lot 13's setback: lot 13 is still built
            shapely.box(200, 0, 210, 10),
        ],  # outside every lot: kept, with no lot
        height=np.array([31.0, 9.0, 3.0, 20.0]),
        floors=np.array([10, 3, 1, 6]),
        roof="flat",
        osm_id=np.array([7, 8, 9, 10]),
        name=np.array(["Hall", "", "", ""], dtype=object),
        height_source=np.array(["height", "levels", "default", "height"], dtype=object),
    )
    out, report = run(built, existing, lots)
    gen = out["source"] == "generated"
    assert sorted(out["lot"][gen].tolist()) == [13, 14]
    assert report == {"buildings": 6, "existing": 4, "generated": 2, "not_built": 3, "existing_on_lots": 3}
    osm = ~gen
    assert out["osm_id"][osm].tolist() == [7, 8, 9, 10] and (out["osm_id"][gen] == -1).all()
    assert out["height"][osm].tolist() == [31.0, 9.0, 3.0, 20.0]  # the map's heights, untouched
    assert out["lot"][osm].tolist() == [10, 11, 13, -1]  # the lot holding most of each (the lower id on a tie)
    assert out["district"][osm].tolist() == [1, 1, 2, -1]
    assert out["name"][osm].tolist() == ["Hall", "", "", ""]
    assert len(np.unique(out.ids)) == len(out) and set(out.ids[gen]) == {13, 14}
    assert shapely.equals(out.geometry[osm], existing.geometry).all()


def test_keep_chooses_one_kind():
    lots, built = street_of_lots()
    existing = Layer.from_geoms([shapely.box(3, 3, 15, 25)], height=np.array([31.0]))
    only_map, rep = run(built, existing, lots, keep="existing")
    assert len(only_map) == 1 and only_map["source"].tolist() == ["osm"] and rep["generated"] == 0
    only_gen, rep = run(built, existing, lots, keep="generated")
    assert len(only_gen) == 5 and set(only_gen["source"]) == {"generated"} and rep["existing"] == 0
    assert set(only_gen.columns) == set(built.columns) | {"source"}  # no empty map columns without map buildings
    tall = Layer.from_geoms([shapely.box(200, 0, 210, 10)], height=np.array([31.0]))  # no floors column
    assert run(built, tall, lots)[0]["floors"].tolist() == [4, 4, 4, 4, 4, 10]
    with pytest.raises(sengine.errors.InputDataError, match="height"):
        run(built, Layer.from_geoms([shapely.box(0, 0, 1, 1)]))


boxes = st.lists(
    st.tuples(st.floats(0, 90), st.floats(0, 90), st.floats(1, 15), st.floats(1, 15)), min_size=0, max_size=25
)


@settings(max_examples=60, deadline=None)
@given(boxes, boxes, st.sampled_from([0.0, 1.0, 20.0]))
def test_no_generated_building_overlaps_the_map_more_than_allowed(gen, real, overlap):
    gen_g = [shapely.box(x, y, x + w, y + h) for x, y, w, h in gen]
    real_g = [shapely.box(x, y, x + w, y + h) for x, y, w, h in real]
    built = Layer.from_geoms(
        gen_g,
        height=np.full(len(gen_g), 9.6),
        floors=np.full(len(gen_g), 3),
        roof="flat",
        lot=np.arange(len(gen_g)),
        district=np.full(len(gen_g), -1),
    )
    existing = Layer.from_geoms(real_g, height=np.full(len(real_g), 20.0))
    out, report = run(built, existing, overlap=str(overlap))
    gen_mask = out["source"] == "generated"
    kept, osm = out.geometry[gen_mask], out.geometry[~gen_mask]
    assert len(osm) == len(real_g) and report["generated"] == len(kept) == len(out) - len(real_g)
    covered = np.array([sum(shapely.intersection(g, r).area for r in real_g) for g in kept])
    assert (covered <= overlap + 1e-9).all()
    # and every generated building left out did overlap the map by more
    gone = [g for g in gen_g if not any(shapely.equals(g, k) for k in kept)]
    assert all(sum(shapely.intersection(g, r).area for r in real_g) > overlap - 1e-9 for g in gone)
    assert len(np.unique(out.ids)) == len(out)


def test_monaco_keeps_its_osm_buildings_and_fills_the_rest(tmp_path):
    net = sengine.load(ROOT / "configs" / "monaco.xml")
    result = net.run(seed=1, out=tmp_path / "out", formats={"geojson", "cityjson"})
    layers, stats = result.layers, result.stats
    osm_in = layers["majorRoads"]["buildings"]
    out = layers["buildings"]["buildings"]
    osm = out["source"] == "osm"
    assert sorted(out["osm_id"][osm].tolist()) == sorted(osm_in["osm_id"].tolist())  # every map building stands
    assert out["height"][osm].max() > 60  # Monaco's towers, tagged, not the 10 m default
    gen = out.take(np.flatnonzero(~osm))
    assert 0 < len(gen) < len(layers["generated"]["buildings"])  # the map leaves some lots free, not all
    real = shapely.make_valid(out.geometry[osm])
    tree = shapely.STRtree(real)
    gi, ri = tree.query(gen.geometry, predicate="intersects")
    covered = np.bincount(gi, shapely.area(shapely.intersection(gen.geometry[gi], real[ri])), len(gen))
    assert covered.max(initial=0) <= 1.0
    # generated ones stay on their lots; the counts agree with the report and the files
    lots = layers["lots"]["lots"]
    lot_of = dict(zip(lots.ids.tolist(), lots.geometry))
    assert shapely.within(gen.geometry, shapely.buffer([lot_of[i] for i in gen["lot"].tolist()], 1e-6)).all()
    rep = stats["report"]["buildings"]
    assert rep["buildings"] == len(out) == stats["counts"]["buildings"]
    assert rep["existing"] == int(osm.sum()) and rep["generated"] == len(gen)
    features = json.loads((tmp_path / "out" / "buildings.geojson").read_text())["features"]
    assert len(features) == len(out)
    assert {f["properties"]["source"] for f in features} == {"osm", "generated"}
    city = json.loads((tmp_path / "out" / "buildings.city.json").read_text())
    assert sum(o["type"] == "Building" for o in city["CityObjects"].values()) == len(out)


def test_a_self_crossing_map_footprint_is_repaired_not_fatal():
    lots, built = street_of_lots()
    bowtie = shapely.Polygon([(2, 2), (18, 28), (18, 2), (2, 28)])  # crosses itself in lot 10
    assert not bowtie.is_valid
    out, report = run(built, Layer.from_geoms([bowtie], height=np.array([12.0])), lots)
    osm = out.geometry[out["source"] == "osm"]
    assert len(osm) == 1 and shapely.is_valid(osm).all()
    assert osm[0].area == pytest.approx(2 * 0.5 * 16 * 13)  # the two triangles of the bow-tie
    assert 10 not in out["lot"][out["source"] == "generated"].tolist() and report["generated"] == 4

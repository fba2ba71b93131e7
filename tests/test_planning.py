"""stats.planning: footprint, floor area, FAR and coverage per lot, block, district and city."""

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
from sengine.nodes.stats import COVER_TOL
from sengine.registry import get

Planning = get("stats.planning")


def run(lots, buildings, blocks=None, **params):
    node = Planning("planning", params, Context(seed=1))
    out = node.run(lots=lots, buildings=buildings, blocks=blocks)
    return out["lots"], out["blocks"], out.report


def test_buildings_count_on_the_lots_they_stand_on():
    lots = Layer.from_geoms(
        [shapely.box(0, 0, 20, 30), shapely.box(20, 0, 40, 30), shapely.box(0, 40, 20, 70)],
        ids=[5, 6, 7],
        block=np.array([1, 1, 2]),
        district=np.array([0, 0, 3]),
    )
    blocks = Layer.from_geoms([shapely.box(0, 0, 40, 30), shapely.box(0, 40, 20, 70)], ids=[1, 2])
    buildings = Layer.from_geoms(
        [
            shapely.box(2, 2, 12, 12),  # 100 m2 x 3 floors on lot 5
            shapely.box(15, 15, 25, 25),  # across lots 5 and 6, 50 m2 on each, 2 floors; named lot 5
            shapely.box(50, 0, 60, 10),
        ],  # on no lot
        floors=np.array([3, 2, 4]),
        lot=np.array([5, 5, -1]),
    )
    lots_out, blocks_out, report = run(lots, buildings, blocks)
    assert lots_out["footprint"].tolist() == pytest.approx([150.0, 50.0, 0.0])
    assert lots_out["floor_area"].tolist() == pytest.approx([400.0, 100.0, 0.0])
    assert lots_out["far"].tolist() == pytest.approx([400 / 600, 100 / 600, 0.0])
    assert lots_out["coverage"].tolist() == pytest.approx([150 / 600, 50 / 600, 0.0])
    assert blocks_out.ids.tolist() == [1, 2]
    assert blocks_out["floor_area"].tolist() == pytest.approx([500.0, 0.0])
    assert blocks_out["far"].tolist() == pytest.approx([500 / 1200, 0.0])
    # lots that do not name their block: the blocks are measured on the ground, to the same figures
    unnamed = Layer(lots.geometry, lots.ids, lots.parent, {"district": lots["district"]})
    assert run(unnamed, buildings, blocks)[1]["floor_area"].tolist() == pytest.approx([500.0, 0.0])
    city = report["city"]
    assert city == {
        "site_area_m2": 1800.0,
        "footprint_m2": 200.0,
        "floor_area_m2": 500.0,
        "far": round(500 / 1800, 4),
        "coverage": round(200 / 1800, 4),
        "residents": 10,
        "retail_demand_m2": 27.0,  # 2.7 m2 a resident (000 §5.2.4)
    }
    assert report["footprint_off_lots_m2"] == 100.0
    assert report["districts"]["0"]["floor_area_m2"] == 500.0 and report["districts"]["3"]["far"] == 0.0
    _, _, report = run(lots, buildings, m2_per_resident="25")
    assert report["city"]["residents"] == 20
    # with a land use, only the residential floor area houses residents
    used = buildings.with_columns(use=np.array(["residential", "office", "residential"]))
    _, _, report = run(lots, used)
    assert (
        report["city"]["residents"] == 300 // 50
    )  # the 100 m2 x 3 floors; the office and the off-lot one do not count
    assert report["uses"]["office"] == {"buildings": 1, "floor_area_m2": 200.0}


lots_grid = st.tuples(st.integers(1, 5), st.integers(1, 5), st.floats(5, 40), st.floats(5, 40))
boxes = st.lists(
    st.tuples(
        st.floats(-20, 200),
        st.floats(-20, 200),
        st.floats(0.5, 30),
        st.floats(0.5, 30),
        st.integers(1, 30),
        st.integers(-1, 30),
    ),
    max_size=30,
)


@settings(max_examples=60, deadline=None)
@given(lots_grid, boxes)
def test_floor_area_is_shared_out_exactly_whatever_the_lot_column_says(grid, bs):
    """Lots partition a grid; every building's area inside it lands on the lots, wrong ``lot`` hints or not."""
    nx, ny, w, h = grid
    lots = Layer.from_geoms([shapely.box(i * w, j * h, (i + 1) * w, (j + 1) * h) for i in range(nx) for j in range(ny)])
    geoms = [shapely.box(x, y, x + bw, y + bh) for x, y, bw, bh, _, _ in bs]
    floors = np.array([f for *_, f, _ in bs], np.int64)
    buildings = Layer.from_geoms(geoms, floors=floors, lot=np.array([lot for *_, lot in bs], np.int64))
    lots_out, _, report = run(lots, buildings)
    ground = shapely.box(0, 0, nx * w, ny * h)
    inside = np.array([g.intersection(ground).area for g in geoms])
    # a building whose corners lie within COVER_TOL of its named lot counts whole there: a strip
    # of its outline at most that wide may be counted that lies off the lots
    rim = COVER_TOL * np.array([g.length for g in geoms]) + 1e-9
    assert lots_out["footprint"].sum() == pytest.approx(inside.sum(), abs=rim.sum())
    assert lots_out["floor_area"].sum() == pytest.approx((inside * floors).sum(), abs=(rim * floors).sum())
    assert report["footprint_off_lots_m2"] == pytest.approx(sum(g.area for g in geoms) - inside.sum(), abs=0.1)
    area = shapely.area(lots.geometry)
    assert np.allclose(lots_out["far"] * area, lots_out["floor_area"])


def test_unknown_use_houses_residents_in_the_share_of_the_known_uses():
    """A building=yes counts as housing in the proportion the tagged buildings are housing."""
    lots = Layer.from_geoms([shapely.box(100 * i, 0, 100 * i + 50, 50) for i in range(4)], ids=[1, 2, 3, 4])
    buildings = Layer.from_geoms(
        [shapely.box(100 * i + 5, 5, 100 * i + 25, 25) for i in range(4)],  # 400 m2 each
        floors=np.array([3, 1, 2, 5]),
        lot=np.array([1, 2, 3, 4]),
        use=np.array(["residential", "office", "", ""], dtype=object),
    )
    _, _, report = run(lots, buildings, m2_per_resident="50")
    share = 1200 / (1200 + 400)  # residential / known floor area
    assert report["unknown_use_housing_share"] == pytest.approx(share, abs=1e-4)
    housing = 1200 + share * (800 + 2000)
    assert report["city"]["residents"] == int(housing // 50)
    # no building of known use: all floor area houses residents, as when there is no use column
    blind = buildings.with_columns(use=np.array(["", "", "", ""], dtype=object))
    assert run(lots, blind, m2_per_resident="50")[2]["city"]["residents"] == (1200 + 400 + 800 + 2000) // 50
    # every use known: only residential floor area
    known = buildings.with_columns(use=np.array(["residential", "office", "office", "mixed"], dtype=object))
    assert run(lots, known, m2_per_resident="50")[2]["city"]["residents"] == (1200 + 2000) // 50


@pytest.mark.slow
def test_monaco_map_buildings_house_about_its_population(tmp_path):
    """Monaco's mapped buildings alone: residents near the real 38,400 (IMSEE, 2023 census).

    The extract spills over into Beausoleil and Cap-d'Ail and counts 50 m2 a
    resident where Monaco's dwellings hold about 65 m2 of floor area a
    resident, so the estimate lies above the census, not below it; before
    the map's building types were read it was 0 (no mapped building had a use).
    """
    net = sengine.load(ROOT / "configs" / "monaco.xml", sets=["buildings.keep=existing"])
    planning = net.run(seed=1, out=tmp_path / "m", formats={"png"}).stats["report"]["planning"]
    assert 38_400 <= planning["city"]["residents"] <= 1.5 * 38_400
    assert 0.5 < planning["unknown_use_housing_share"] < 0.95


def test_manhattan_report_matches_the_lots_file(tmp_path):
    result = sengine.load(ROOT / "configs" / "manhattan.xml").run(seed=1, out=tmp_path / "o", formats={"geojson"})
    stats, layers = result.stats, result.layers
    feats = json.loads((tmp_path / "o" / "lots.geojson").read_text())["features"]
    gfa = sum(f["properties"]["floor_area"] for f in feats)
    b = layers["buildings"]["buildings"]
    # every generated building stands inside its lot: its whole floor area is on the lots
    assert gfa == pytest.approx(float((shapely.area(b.geometry) * b["floors"]).sum()), rel=1e-9)
    city = stats["report"]["planning"]["city"]
    assert city["floor_area_m2"] == pytest.approx(gfa, abs=0.1)
    assert city["site_area_m2"] == pytest.approx(layers["lots"]["lots"].area(), abs=0.1)
    assert city["far"] == pytest.approx(gfa / city["site_area_m2"], abs=1e-4)
    assert 0 < city["coverage"] < 1
    assert all(0 <= f["properties"]["coverage"] <= 1 + 1e-9 for f in feats)
    blocks = json.loads((tmp_path / "o" / "blocks.geojson").read_text())["features"]
    assert sum(f["properties"]["floor_area"] for f in blocks) == pytest.approx(gfa, rel=1e-9)
    districts = stats["report"]["planning"]["districts"]
    assert sum(d["floor_area_m2"] for d in districts.values()) == pytest.approx(city["floor_area_m2"], abs=1.0)

"""buildings.check (paper 003 §3.2): ZB, street widths, height classes, roof envelope, storeys; --check."""

from __future__ import annotations

import json

import numpy as np
import pytest
import shapely
from conftest import CONFIGS, run_cli

from sengine import CityPlan, Context, Layer, Rule
from sengine.nodes.buildings.regulation import STREET_MINIMA, ZB_TABLE, street_minimum, zb_limit
from sengine.nodes.maps import plan_inputs
from sengine.registry import get

Check = get("buildings.check")


def run(plan=None, **inputs):
    params = inputs.pop("params", {})
    node = Check("check", params, Context(seed=1, plan=plan))
    ran = node.run(**inputs, **(plan_inputs(plan, node) if plan is not None else {}))
    return ran, ran.report


def test_zb_at_the_table_points_and_interpolated():
    for structure, (m, s1, v, _) in ZB_TABLE.items():
        got = zb_limit([structure] * 5, [500.0, 2000.0, 2000.1, 12000.0, 50000.0])
        assert got[0] == got[1] == m  # small: up to 2,000 m2 inclusive
        assert got[3] == pytest.approx(v)  # 12,000 m2 is still mid-size: ZB_S = ZB_V there
        assert got[4] == v  # large
        assert got[2] == pytest.approx(v + (s1 - v) * (12000 - 2000.1) / 10000)
    # the thesis's formula at a mid-size block of 7,000 m2, block structure: 50 % + 25 % x 0.5
    assert zb_limit(["block"], [7000.0])[0] == pytest.approx(0.625)
    assert zb_limit(["garden-city"], [7000.0])[0] == pytest.approx(0.275)


def test_street_minima_by_class():
    got = street_minimum(["primary", "tertiary", "residential", "service", "footway", "major", "minor"])
    assert got.tolist() == [24.0, 18.0, 12.0, 8.0, 8.0, 18.0, 12.0]
    assert sorted(STREET_MINIMA.values()) == [8.0, 12.0, 18.0, 24.0]


def test_buildings_blocks_and_streets_get_ok_and_violation():
    blocks = Layer.from_geoms([shapely.box(0, 0, 40, 40), shapely.box(100, 0, 300, 100)], district=np.array([0, 0]))
    buildings = Layer.from_geoms(
        [
            shapely.box(0, 0, 40, 36),  # 90 % of a small block (ZB_M 85 %): over
            shapely.box(100, 0, 150, 20),  # 5 % of a large block: fine
            shapely.box(160, 0, 180, 12),  # 12 m deep, gable 7.2 m: 50 deg, outside the envelope
            shapely.box(200, 0, 220, 20),  # storeys of 2.5 m
        ],
        height=np.array([20.0, 45.0, 16.0 + 7.2, 10.0]),
        roof_height=np.array([0.0, 0.0, 7.2, 0.0]),
        roof=np.array(["flat", "flat", "gable", "flat"]),
        floors=np.array([6, 14, 5, 4]),
        district=np.zeros(4, np.int64),
    )
    roads = Layer.from_geoms(
        shapely.linestrings([[[0, 50], [100, 50]]] * 3),
        **{"class": np.array(["primary", "tertiary", "residential"])},
        width=np.array([24.0, 15.0, 12.0]),
    )
    plan = CityPlan(rules=[Rule("district", {"height-class": "VI", "structure": "block"}, "x.xml:2")])
    out, report = run(plan, buildings=buildings, blocks=blocks, roads=roads)
    b, k, r = out["buildings"], out["blocks"], out["roads"]
    # height class VI is 16-26 m: 45 m is over, 10 m under
    assert b["violation"].tolist() == ["", "height-class-over", "roof", "height-class-under,storey-height"]
    assert b["ok"].tolist() == [True, False, False, False]
    assert k["violation"].tolist() == ["coverage", ""] and k["zb"].tolist() == [0.85, 0.5]
    assert k["coverage"][0] == pytest.approx(0.9)
    assert r["violation"].tolist() == ["", "street-width", ""] and r["min_width"].tolist() == [24.0, 18.0, 12.0]
    assert report["violations"] == 3 + 1 + 1
    assert report["summary"] == "regulation: 3 of 4 buildings; 1 of 2 blocks over ZB; 1 of 3 streets too narrow"
    # with no height class nothing is over or under; a recessed storey may be 3.5 m
    ok_b = buildings.with_columns(
        roof=np.array(["flat", "stepped", "flat", "flat"]), roof_height=np.array([0, 3.5, 0, 0.0])
    )
    out, report = run(buildings=ok_b)
    assert out["buildings"]["violation"].tolist() == ["", "", "", "storey-height"]
    assert report["summary"] == "regulation: 1 of 4 buildings"


def test_check_option_exits_1_with_one_line(tmp_path):
    res = run_cli("run", CONFIGS / "planning.xml", "-o", tmp_path / "p", "--check", "-q")
    assert res.returncode == 1, res.stderr
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("sengine: check failed: check: regulation: ")
    stats = json.loads((tmp_path / "p" / "stats.json").read_text())
    check = stats["report"]["check"]
    assert check["violations"] > 0 and check["summary"] in lines[0]
    # the checked layers are exported with their verdicts
    feats = json.loads((tmp_path / "p" / "buildings.geojson").read_text())["features"]
    bad = sum(not f["properties"]["ok"] for f in feats)
    assert bad == check["buildings_checked"] - sum(f["properties"]["ok"] for f in feats)
    assert {"violation", "typology", "use", "roof", "roof_height", "gfa", "far"} <= set(feats[0]["properties"])
    # no height class (neither the plan's nor the check's): no height violation; the exit status says if any remain
    res = run_cli(
        "run",
        CONFIGS / "planning.xml",
        "-o",
        tmp_path / "q",
        "--check",
        "-q",
        "--set",
        "check.height_class=",
        "--set",
        "buildings.height_class=",
        "--set",
        "check.structure=grown",
        "--set",
        "buildings.far=1",
    )
    stats = json.loads((tmp_path / "q" / "stats.json").read_text())
    assert stats["report"]["check"]["buildings_height_class_under"] == 0
    assert res.returncode == (1 if stats["report"]["check"]["violations"] else 0)


def test_planning_demo_report_reads_like_a_plan(tmp_path):
    import sengine

    res = sengine.load(CONFIGS / "planning.xml").run()
    rep = res.stats["report"]
    city = rep["planning"]["city"]
    uses = rep["planning"]["uses"]
    assert set(uses) <= {"residential", "commercial", "office", "educational"} and len(uses) >= 3
    assert 2.0 <= city["far"] <= 4.5  # the rules' FARs, 3.2 to 4.0, less what the height class cuts
    assert city["residents"] == int(uses["residential"]["floor_area_m2"] // 50)
    b = res.layers["buildings"]["buildings"]
    # every land use built with its own types
    assert set(b["typology"][b["use"] == "educational"]) <= {"linked", "L", "I", "box"}
    assert (b["height"] - b["roof_height"] <= 26.0 + 1e-9).all()  # class VI caps the floors

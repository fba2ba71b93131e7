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
from sengine.nodes.buildings.context import neighbour_floors
from sengine.registry import get

Node = get("buildings.context")


def run(lots, existing=None, **params):
    out = Node("context", params, Context(seed=1)).run(lots=lots, existing=existing)
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
    assert report == {"lots_fitted": 1, "low_rise_lots": 1}


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

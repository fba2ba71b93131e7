"""lots.fields: the open lots of a block that touch are one field."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage

from sengine import Context, Layer
from sengine.nodes.lots.fields import unite_by_group
from sengine.registry import get

Fields = get("lots.fields")


def run(lots):
    out = Fields("fields", {}, Context(seed=1)).run(lots=lots)
    return out["lots"], out.report


def grid_lots(open_cells: np.ndarray, blocks: np.ndarray, size: float = 10.0) -> Layer:
    """A lot per cell of a grid (row-major ids from 100), with its block and whether it is open."""
    ny, nx = open_cells.shape
    j, i = np.divmod(np.arange(nx * ny), nx)
    geoms = shapely.box(i * size, j * size, (i + 1) * size, (j + 1) * size)
    return Layer.from_geoms(
        geoms,
        ids=100 + np.arange(nx * ny),
        block=blocks.ravel().astype(np.int64),
        open=open_cells.ravel().astype(bool),
        frontage=np.full(nx * ny, 10.0),
        kind=np.full(nx * ny, "street"),
        inner=np.zeros(nx * ny, bool),
    )


def test_unite_by_group_by_hand():
    squares = shapely.box([0, 10, 30, 0], [0, 0, 0, 50], [10, 20, 40, 60], [10, 10, 10, 60])
    pieces, group = unite_by_group(squares, np.array([1, 1, 1, 2]))
    # group 1: two touching squares and one apart; group 2: one square
    assert group.tolist() == [1, 1, 2]
    assert sorted(shapely.area(pieces[group == 1]).tolist()) == [100.0, 200.0]
    assert pieces[group == 2][0].equals(squares[3])
    empty, none = unite_by_group(np.empty(0, object), np.empty(0, np.int64))
    assert len(empty) == 0 and len(none) == 0


def test_a_row_of_open_lots_is_one_field_and_a_built_lot_splits_it():
    # one block of 6 lots in a row: open, open, built, open, open, open
    lots = grid_lots(np.array([[1, 1, 0, 1, 1, 1]]), np.zeros((1, 6)))
    out, report = run(lots)
    assert report == {"fields": 2, "open_lots": 5}
    assert out.ids.tolist() == [100, 102, 103]  # each field is numbered by its lowest lot
    assert shapely.area(out.geometry).tolist() == [200.0, 100.0, 300.0]
    assert out["kind"].tolist() == ["field", "street", "field"]
    assert out["frontage"].tolist() == [20.0, 10.0, 30.0]
    assert out.geometry[0].equals(shapely.box(0, 0, 20, 10)) and out.geometry[2].equals(shapely.box(30, 0, 60, 10))
    assert out.geometry[1].equals(lots.geometry[2])  # the built lot passes unchanged


def test_open_lots_of_two_blocks_stay_apart_and_nothing_open_is_a_pass_through():
    lots = grid_lots(np.ones((1, 4)), np.array([[0, 0, 1, 1]]))
    out, report = run(lots)
    assert report["fields"] == 2 and out["block"].tolist() == [0, 1]
    built = grid_lots(np.zeros((2, 3)), np.zeros((2, 3)))
    same, report = run(built)
    assert same is built and report == {"fields": 0, "open_lots": 0}


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 7), st.integers(1, 7), st.integers(0, 2**32 - 1))
def test_fields_are_the_connected_open_land_of_each_block(nx, ny, seed):
    rng = np.random.default_rng(seed)
    open_cells = rng.random((ny, nx)) < 0.6
    blocks = (rng.random((ny, nx)) < 0.3).astype(np.int64)  # two blocks, scattered
    lots = grid_lots(open_cells, blocks)
    out, report = run(lots)
    # oracle: the 4-connected components of each block's open cells (cells touching at a corner only
    # make one polygon's parts that GEOS keeps apart: the union of two corner squares is a MultiPolygon)
    expected = sum(ndimage.label(open_cells & (blocks == b))[1] for b in (0, 1))
    assert report["fields"] == expected and report["open_lots"] == int(open_cells.sum())
    field = np.asarray(out["kind"]) == "field"
    assert field.sum() == expected and len(out) == int((~open_cells).sum()) + expected
    # a partition: the area is kept and nothing overlaps
    assert np.isclose(shapely.area(out.geometry).sum(), nx * ny * 100.0)
    assert np.isclose(shapely.area(shapely.union_all(out.geometry)), nx * ny * 100.0)
    assert shapely.is_valid(out.geometry).all() and len(np.unique(out.ids)) == len(out)
    # each field holds the open lots of its own block only, and carries its lowest id
    site = shapely.point_on_surface(lots.geometry)
    for k in np.flatnonzero(field):
        inside = shapely.contains(out.geometry[k], site)
        assert (open_cells.ravel()[inside]).all()
        assert (blocks.ravel()[inside] == out["block"][k]).all()
        assert out.ids[k] == lots.ids[inside].min()


def test_village_fields_in_the_load_map_network_are_unbuilt():
    """A village with a country road out of it: the road's lots are one field each side, and unbuilt."""
    village = [shapely.LineString([(x, 0), (x, 600)]) for x in np.arange(0.0, 601.0, 100.0)]
    village += [shapely.LineString([(0, y), (600, y)]) for y in np.arange(0.0, 601.0, 100.0)]
    road = shapely.LineString([(600.0, 300.0), (3600.0, 300.0)])
    roads = Layer.from_geoms(village + [road], **{"class": np.array(["residential"] * len(village) + ["unclassified"])})
    xs = np.arange(610.0, 3500.0, 20.0)
    lots = Layer.from_geoms(
        [shapely.box(x, 305, x + 20, 335) for x in xs], ids=np.arange(len(xs)), block=np.zeros(len(xs), np.int64)
    )
    ctx = get("buildings.context")("context", {"rural_grain": 30.0, "urban_grain": 30.0}, Context(seed=1))
    marked = ctx.run(lots=lots, roads=roads)["lots"]
    out, report = run(marked)
    n_open = int(np.asarray(marked["open"]).sum())
    assert n_open > 100 and report == {"fields": 1, "open_lots": n_open}
    assert len(out) == len(xs) - n_open + 1
    built = get("buildings.massing")("generated", {}, Context(seed=1)).run(lots=out)
    on = np.asarray(built["buildings"]["lot"], np.int64)
    field_id = out.ids[np.asarray(out["kind"]) == "field"][0]
    assert field_id not in on and len(np.unique(on)) == len(xs) - n_open


@pytest.mark.parametrize("order", [np.arange(6), np.array([5, 3, 1, 0, 2, 4])])
def test_fields_do_not_depend_on_the_lots_order(order):
    lots = grid_lots(np.array([[1, 1, 0, 1, 1, 1]]), np.zeros((1, 6)))
    out, _ = run(lots.take(order))
    ref, _ = run(lots)
    assert out.ids.tolist() == ref.ids.tolist()
    assert all(a.equals(b) for a, b in zip(out.geometry, ref.geometry))

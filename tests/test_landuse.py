"""blocks.landuse: water and parks of the map are cut out of the blocks before the lots are drawn."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import shapely
from hypothesis import example, given, settings
from hypothesis import strategies as st

import sengine
from sengine import Context, Layer
from sengine.nodes.blocks.landuse import cut_blocks
from sengine.registry import get

ROOT = Path(__file__).resolve().parent.parent

coord = st.floats(0, 300, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.tuples(coord, coord, st.floats(2, 80)), max_size=6),
    st.lists(st.tuples(coord, coord, st.floats(1, 120), st.floats(1, 30)), max_size=4),
)
@example(circles=[(212.5, 16.0, 80.0)], rects=[(132.0, 5e-324, 4.0, 1.0)])  # a cut a hair above the block's edge
def test_pieces_and_cut_land_partition_each_block(circles, rects):
    blocks = np.array([shapely.box(x, y, x + 90, y + 60) for x in (0, 100, 200) for y in (0, 70, 140)])
    cut = [shapely.Point(x, y).buffer(r, quad_segs=4) for x, y, r in circles]
    cut += [shapely.box(x, y, x + w, y + h) for x, y, w, h in rects]
    pieces, src, counts = cut_blocks(blocks, cut, min_area=0.0)
    land = shapely.union_all(cut) if cut else shapely.Polygon()
    assert shapely.is_valid(pieces).all() and (shapely.get_type_id(pieces) == 3).all()
    per_block = np.bincount(src, weights=shapely.area(pieces), minlength=len(blocks))
    taken = shapely.area(shapely.intersection(blocks, land))
    assert np.allclose(per_block + taken, shapely.area(blocks), atol=1e-6)
    assert shapely.area(shapely.intersection(pieces, land)).sum() <= 1e-6
    assert counts["blocks_cut"] == int(shapely.intersects(blocks, land).sum())
    assert counts["area_removed_m2"] == pytest.approx(taken.sum(), abs=0.1)


def test_a_river_splits_a_block_and_slivers_go():
    blocks = Layer.from_geoms(
        [
            shapely.box(0, 0, 100, 60),
            shapely.box(110, 0, 210, 60),
            shapely.box(220, 0, 320, 60),
            shapely.box(330, 0, 430, 60),
        ],
        ids=[4, 9, 12, 15],
        district=np.array([2, 3, 3, 3]),
    )
    water = Layer.from_geoms([shapely.box(40, -10, 55, 70), shapely.box(110, 0, 210, 59.5)], kind="water")
    parks = Layer.from_geoms(
        [shapely.Point(80, 30).buffer(8), shapely.box(220, 3, 320, 60), shapely.box(330, 5, 430, 60)], kind="park"
    )
    node = get("blocks.landuse")("landuse", {"min_area": "60", "min_width": "4"}, Context())
    ran = node.run(blocks=blocks, water=water, parks=parks)
    out = ran["blocks"]
    # block 4 falls in two pieces (the first keeps the id); block 9 keeps a 0.5 m strip of 50 m2 (under
    # min_area) and block 12 a 3 m strip of 300 m2 (under min_width): both go; block 15 keeps its 5 m strip
    assert sorted(out.ids.tolist()) == [4, 15, 16]
    assert out["district"].tolist() == [2, 2, 3]
    assert sorted(shapely.area(out.geometry)) == pytest.approx([5 * 100, 40 * 60, 45 * 60 - parks.geometry[0].area])
    assert ran.report["blocks_removed"] == 2 and ran.report["pieces_dropped"] == 2
    assert ran.report["blocks_cut"] == 4 and ran.report["blocks"] == 3
    assert all(shapely.intersection(g, parks.geometry[0]).area < 1e-9 for g in out.geometry)


def test_monaco_builds_nothing_in_its_parks_or_water():
    layers, stats = sengine.load(ROOT / "configs" / "monaco.xml").run(seed=1)
    read = layers["majorRoads"]
    land = shapely.union_all(shapely.make_valid(np.concatenate([read["parks"].geometry, read["water"].geometry])))
    shapely.prepare(land)
    # the street faces do hold park land (so the test can fail) ...
    blocks = layers["blocks"]["blocks"]
    assert shapely.area(shapely.intersection(blocks.geometry, land)).sum() > 10_000
    # ... which no lot and no generated building takes (the map's own buildings stand where they stand)
    for lay in (layers["lots"]["lots"], layers["generated"]["buildings"]):
        assert shapely.area(shapely.intersection(lay.geometry, land)).sum() < 1e-3
    rep = stats["report"]["landuse"]
    cut = layers["landuse"]["blocks"]
    assert rep["blocks"] == len(cut) == stats["counts"]["landuse"] and rep["blocks_cut"] > 5
    assert rep["area_removed_m2"] == pytest.approx(blocks.area() - cut.area(), abs=1.0)
    # the lots partition the built land-use blocks; open land (the sea the coastline closes is water) gets none
    lots = layers["lots"]["lots"]
    order = np.argsort(cut.ids)
    owner = order[np.searchsorted(cut.ids[order], lots["block"])]
    assert np.array_equal(cut.ids[owner], lots["block"])
    lot_area = np.bincount(owner, weights=shapely.area(lots.geometry), minlength=len(cut))
    built = cut["landuse"] == "built"
    assert np.allclose(lot_area[built], shapely.area(cut.geometry[built]), rtol=1e-3)
    assert rep["open_blocks"] == (~built).sum() > 0 and not lot_area[~built].any()
    assert "sea" in set(read["water"]["kind"])


def test_sides_cut_along_land_are_no_street_front():
    """A park cut out of a block's east half: the lots along the park have no frontage there, none is built."""
    blocks = Layer.from_geoms([shapely.box(0, 0, 120, 60), shapely.box(200, 0, 320, 60)])
    parks = Layer.from_geoms([shapely.box(60, -5, 125, 65)], kind="park")
    ran = get("blocks.landuse")("landuse", {}, Context()).run(blocks=blocks, parks=parks)
    out = ran["blocks"]
    front = out["street_front"]
    assert front[out.ids == 1][0] is None  # uncut: faces streets all round
    cut = front[out.ids == 0][0]
    # the cut block keeps its west, north and south sides (60 + 60 + 60 m); its new east side faces the park
    assert shapely.length(cut) == pytest.approx(180.0, abs=0.1)
    assert ran.report["pieces_with_land_edges"] == 1
    lots = get("lots.recursive")("lots", {}, Context(seed=1)).run(blocks=out)["lots"]
    east = shapely.get_coordinates(lots.geometry[lots["block"] == 0])[:, 0].max()
    assert east == pytest.approx(60.0)
    for lot, frontage in zip(lots.geometry, lots["frontage"]):
        on_park = shapely.length(shapely.intersection(lot.boundary, shapely.LineString([(60, 0), (60, 60)])))
        assert frontage <= shapely.length(lot.boundary) - on_park + 1e-6
    # a lot whose only side on the block boundary faces the park has no frontage and gets no building
    b = get("buildings.massing")("b", {}, Context(seed=1)).run(lots=lots, blocks=out)["buildings"]
    no_front = lots.ids[lots["kind"] == "inner"]
    assert not np.isin(b["lot"], no_front).any()
    # and none turns its front to the park: the lots along it front onto the north and south streets
    on_park = shapely.dwithin(b.geometry, shapely.LineString([(60, 0), (60, 60)]), 0.01)
    assert np.isin(np.asarray(b["roof_direction"])[on_park], (0.0, 180.0)).all()


def test_monaco_builds_no_front_on_open_land():
    """Monaco's land beyond 100 m of its streets is open: no generated building lines its edge."""
    net = sengine.load(ROOT / "configs" / "monaco.xml")
    layers, stats = net.run(workers=1)
    blocks, lots, built = layers["landuse"]["blocks"], layers["lots"]["lots"], layers["generated"]["buildings"]
    open_land = shapely.union_all(blocks.geometry[blocks["landuse"] == "open"])
    near_open = shapely.dwithin(built.geometry, open_land, 0.5)
    # before street fronts, 9.0 % (186 of 2,071) of the generated buildings stood on the open land's edge
    assert near_open.mean() < 0.02, near_open.mean()
    lot_of = dict(zip(lots.ids.tolist(), lots["frontage"].tolist()))
    assert all(lot_of[i] > 0 for i in built["lot"].tolist())

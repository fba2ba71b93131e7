"""The lot vocabulary on every lot method: kind, frontage, depth, and front / side / rear edges."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
import shapely.affinity
from _lotcases import osm_blocks
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_lots_skeleton import block_polygon

from sengine import Context, Layer
from sengine.geom.polygons import obb_frame
from sengine.nodes.lots.vocabulary import FRONT, KINDS, REAR, SIDE, LotSplit, edge_tags, street_ids
from sengine.registry import get

METHODS = ["lots.manhattan", "lots.recursive", "lots.paris", "lots.skeleton"]
SETTINGS = settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def owner_of(blocks: Layer, lots: Layer) -> np.ndarray:
    o = np.argsort(blocks.ids)
    return o[np.searchsorted(blocks.ids[o], lots["block"])]


def check_vocabulary(blocks: Layer, lots: Layer, name: str):
    kind, inner, front = lots["kind"], lots["inner"], lots["frontage"]
    assert set(np.unique(kind)) <= set(KINDS)
    assert np.array_equal(kind == "inner", inner | (front <= 0)), name
    assert np.array_equal(kind == "corner", lots["corner"] & (kind != "inner")), name
    # depth: positive, no more than the lot's extent
    _, _, length, width = obb_frame(lots.geometry)
    depth = lots["depth"]
    has = front > 0
    assert np.all(np.isnan(depth[~has])), name  # no front, no depth
    assert np.all(np.isfinite(depth[has])) and np.all(depth[has] > 0), name
    assert np.all(depth[has] <= np.hypot(length, width)[has] + 1e-6), name
    owner = owner_of(blocks, lots)
    tags = edge_tags(lots.geometry, owner, blocks.geometry)
    seg_len = np.hypot(*(tags.p1 - tags.p0).T)
    # front: on the block's boundary, adding up to the frontage column
    assert np.allclose(tags.length(FRONT)[: len(lots)], np.pad(front, (0, 0)), atol=1e-6 * max(1.0, front.max())), name
    fr = tags.tag == FRONT
    d = shapely.distance(
        shapely.points(0.5 * (tags.p0[fr] + tags.p1[fr])), shapely.boundary(blocks.geometry[owner[tags.lot[fr]]])
    )
    assert np.all(d <= 1e-5), name
    assert np.all(tags.street[fr] >= 0) and np.all(tags.street[~fr] == -1)
    # side: the lot across fronts one of this lot's streets; rear: it does not (or there is none)
    streets = {}
    for lot, s in zip(tags.lot[fr], tags.street[fr]):
        streets.setdefault(int(lot), set()).add(int(s))
    for t in (SIDE, REAR):
        sel = np.flatnonzero((tags.tag == t) & (seg_len > 1e-9))
        for k in sel[:: max(1, len(sel) // 400)]:  # a sample of a few hundred
            a, b = int(tags.lot[k]), int(tags.neighbour[k])
            common = bool(streets.get(a, set()) & streets.get(b, set())) if b >= 0 else False
            assert common == (t == SIDE), f"{name}: segment {k} of lot {a} tagged {t} against lot {b}"
    # lots without frontage have neither front nor side (a paris courtyard may keep a hole's edge)
    in_seg = (front <= 0)[tags.lot]
    assert np.all(tags.tag[in_seg] == REAR), name
    # a side is a side from both lots (where lots meet vertex to vertex: skeleton lots are noded together;
    # elsewhere a segment along two lots (a T-junction) takes the lot at its midpoint)
    if name == "lots.skeleton":
        side = np.flatnonzero(tags.tag == SIDE)
        pairs = set(zip(tags.lot[side].tolist(), tags.neighbour[side].tolist()))
        assert all((b, a) in pairs for a, b in pairs), name


@pytest.mark.parametrize("name", METHODS)
def test_vocabulary_on_monaco(name):
    blocks = osm_blocks("monaco")
    lots = get(name)("lots", {}, Context(seed=2)).run(blocks=blocks)["lots"]
    check_vocabulary(blocks, lots, name)


@SETTINGS
@given(st.lists(block_polygon(), min_size=1, max_size=3))
def test_vocabulary_on_generated_blocks(polys):
    big = [p for p in polys if p.length >= 12.0]  # blocks with room for a lot of 6 m frontage
    if not big:
        return
    blocks = Layer.from_geoms(big, ids=np.arange(len(big)) * 5 + 1)
    for name in METHODS:
        lots = get(name)("lots", {}, Context(seed=7)).run(blocks=blocks)["lots"]
        check_vocabulary(blocks, lots, name)


# a hypothesis block where lots.skeleton merges faces: the merged faces kept their old segment counts,
# shifting the segment flags of every later lot (frontage 1 or 22 m where 94 m were measured)
MERGED_BLOCK = (
    "POLYGON ((11.297470666614931 73.28626412568394, -1.2526332120272503 23.026900341763614, -88.30704793"
    "959758 171.60489254361687, -128.41774767443388 62.027160464305446, -112.10233725592373 10.0592024752"
    "14043, -13.191409587882877 0.8897497404858918, -131.4226519030534 -47.736409570081925, -75.710704861"
    "80308 -92.44905905156826, 89.54389344428381 -140.47323833373954, 53.17874502638611 -70.7026634084425"
    ", 117.85029641646328 -82.85071216075417, 11.297470666614931 73.28626412568394))"
)


def test_frontage_of_skeleton_lots_after_a_merge():
    blocks = Layer.from_geoms([shapely.from_wkt(MERGED_BLOCK)], ids=np.array([1]))
    lots = get("lots.skeleton")("lots", {}, Context(seed=7)).run(blocks=blocks)["lots"]
    check_vocabulary(blocks, lots, "lots.skeleton")


def test_tags_of_skeleton_lots_on_a_rectangle():
    """150 m x 90 m, 22 m deep and 15 m wide lots: a street lot has 15 m of front, 44 m of side, 15 m of rear."""
    blocks = Layer.from_geoms([shapely.affinity.rotate(shapely.box(0, 0, 150, 90), 17)])
    lots = get("lots.skeleton")("lots", {"irregularity": 0.0, "lot_area_max": 1e6}, Context()).run(blocks=blocks)[
        "lots"
    ]
    tags = edge_tags(lots.geometry, np.zeros(len(lots), np.int64), blocks.geometry)
    street = np.flatnonzero(lots["kind"] == "street")
    assert len(street) == 2 * (7 + 3)  # (150 - 2 x 22.5) / 15 on the long sides, (90 - 2 x 22.5) / 15 on the short
    assert np.allclose(tags.length(FRONT)[street], 15.0)
    assert np.allclose(tags.length(SIDE)[street], 44.0)
    assert np.allclose(tags.length(REAR)[street], 15.0)
    corner = np.flatnonzero(lots["kind"] == "corner")
    assert len(corner) == 4 and np.allclose(tags.length(FRONT)[corner], 45.0)
    core = np.flatnonzero(lots["kind"] == "inner")
    assert len(core) == 1 and tags.length(FRONT)[core] == 0 and tags.length(SIDE)[core] == 0


def test_through_lots_of_a_thin_block_front_two_streets():
    blocks = Layer.from_geoms([shapely.box(0, 0, 300, 30)])  # thinner than twice the 22 m depth
    lots = get("lots.skeleton")("lots", {}, Context(seed=1)).run(blocks=blocks)["lots"]
    street = lots["kind"] == "street"
    assert street.sum() >= 10 and (lots["street_edges"][street] == 2).all()
    assert not (lots["kind"] == "inner").any()
    assert np.allclose(lots["depth"][street], 30.0)


def test_street_ids():
    box = shapely.box(0, 0, 10, 10)
    round_ = shapely.Point(0, 0).buffer(50)
    holed = shapely.box(0, 0, 100, 100).difference(shapely.box(40, 40, 60, 60))
    sid = street_ids([box, round_, holed])
    p0, _, idx, _ = __import__("sengine.geom.boundary", fromlist=["ring_segments"]).ring_segments([box, round_, holed])
    assert [len(np.unique(sid[idx == k])) for k in range(3)] == [4, 1, 8]


def test_lot_split_checks_lengths():
    with pytest.raises(ValueError, match="LotSplit.owner has length 1, expected 2"):
        LotSplit(np.array([shapely.box(0, 0, 1, 1)] * 2, dtype=object), np.zeros(1), np.array(["a", "a"]), np.zeros(2))

"""Stable ids of parks and trees (issues 13 and 14): from what they stand on, the same whatever the batch."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from sengine import Layer
from sengine.errors import LimitError, NodeError
from sengine.node import Context
from sengine.nodes.blocks.circuits import ID_SPAN
from sengine.nodes.lots.nodes import LOT_SPAN, lot_ids
from sengine.nodes.parks.ids import TREE_SPAN, park_ids, ranks, tree_ids
from sengine.registry import get


def _grid_blocks(n: int, enclosure: int = 3, size: float = 60.0) -> Layer:
    """``n`` square blocks in a row with block ids ``enclosure x ID_SPAN + rank``, 20 m of road between them."""
    geoms = [shapely.box(i * (size + 20), 0, i * (size + 20) + size, size) for i in range(n)]
    ids = enclosure * ID_SPAN + np.arange(n)
    return Layer.from_geoms(geoms, ids=ids, parent=np.full(n, enclosure), district=np.zeros(n, np.int64))


def _node(name, params=None, seed=4):
    return get(name)(name.split(".")[-1], params or {}, Context(seed=seed))


def test_block_park_ids_come_from_the_block_whatever_the_batch():
    blocks = _grid_blocks(10)
    node = _node("parks.block", {"mode": "every", "every": "3"})
    whole = node.run(blocks=blocks)["parks"]
    assert np.array_equal(whole.parent, blocks.ids[blocks.ids % 3 == 0])
    assert np.array_equal(whole.ids, whole.parent * LOT_SPAN * 4 + 1)
    halves = [node.run(blocks=blocks.take(np.arange(a, b)))["parks"] for a, b in ((0, 4), (4, 10))]
    assert np.array_equal(np.concatenate([h.ids for h in halves]), whole.ids)


def test_lot_park_ids_come_from_the_lot_and_stay_unique_beside_block_parks():
    lots = Layer.from_geoms(
        [shapely.box(i * 10, 0, i * 10 + 9, 9) for i in range(40)],
        ids=(3 * ID_SPAN + 1) * LOT_SPAN + np.arange(40),
        block=np.full(40, 3 * ID_SPAN + 1),
    )
    upstream = _node("parks.block", {"mode": "every", "every": "1"}).run(blocks=_grid_blocks(2))["parks"]
    out = _node("parks.lot", {"mode": "every", "every": "7"}).run(lots=lots, parks=upstream)["parks"]
    lot = np.asarray(out["level"]).astype(str) == "lot"
    assert np.array_equal(out.ids[lot], lots.ids[lots.ids % 7 == 0] * 4 + 2)
    assert len(np.unique(out.ids)) == len(out) == 2 + int((lots.ids % 7 == 0).sum())
    assert (np.diff(out.ids) > 0).all()  # the stream is in id order
    # block 3 x ID_SPAN + 1's park and its first lot's park share a site, not an id
    assert set((out.ids // 4).tolist()) >= {(3 * ID_SPAN + 1) * LOT_SPAN}


def test_patio_ids_come_from_their_block_and_rank():
    blocks = _grid_blocks(3)
    # a ring of walls round an open core in each block: one patio per block, two in the last
    rings = [shapely.box(x + 5, 5, x + 55, 55).difference(shapely.box(x + 15, 15, x + 45, 45)) for x in (0, 80)]
    rings.append(
        shapely.box(165, 5, 215, 55).difference(shapely.box(170, 10, 188, 50)).difference(shapely.box(192, 10, 210, 50))
    )
    buildings = Layer.from_geoms(rings)
    out = _node("parks.patio", {"mode": "all", "min_area": "20", "min_width": "2"}).run(
        blocks=blocks, buildings=buildings
    )["parks"]
    block = np.asarray(out["block"], np.int64)
    assert np.array_equal(block, blocks.ids[[0, 1, 2, 2]])
    assert np.array_equal(out.ids, (block * LOT_SPAN + [0, 0, 0, 1]) * 4 + 3)
    one = _node("parks.patio", {"mode": "all", "min_area": "20", "min_width": "2"}).run(
        blocks=blocks.take([2]), buildings=buildings
    )["parks"]
    assert np.array_equal(one.ids, out.ids[2:])


def test_district_park_ids_come_from_their_enclosure():
    areas = Layer.from_geoms([shapely.box(0, 0, 100, 100), shapely.box(100, 0, 200, 100)], ids=[0, 1])
    parks = Layer.from_geoms(
        [
            shapely.box(120, 10, 130, 20),
            shapely.box(10, 10, 20, 20),
            shapely.box(300, 0, 310, 10),
            shapely.box(140, 10, 150, 20),
        ]
    )
    out = _node("parks.district").run(parks=parks, areas=areas)["parks"]
    # enclosure 0 rank 0; enclosure 1 ranks 0, 1; outside every enclosure: the key after them (2)
    span = ID_SPAN * LOT_SPAN * 4
    assert out.ids.tolist() == [0, span, span + 4, 2 * span]
    assert shapely.equals(out.geometry[0], parks.geometry[1])


def test_tree_ids_are_zone_key_times_span_plus_rank():
    value = np.array([40, 40, 9, 40, 9, 9])
    kind = np.array([0, 0, 1, 0, 1, 0])
    ids = tree_ids(value, kind)
    assert ids.tolist() == [
        160 * TREE_SPAN,
        160 * TREE_SPAN + 1,
        37 * TREE_SPAN,
        160 * TREE_SPAN + 2,
        37 * TREE_SPAN + 1,
        36 * TREE_SPAN,
    ]
    assert ranks([5, 5, 2, 5, 2]).tolist() == [0, 1, 0, 2, 1]
    with pytest.raises(NodeError, match="more than 100,000 trees"):
        tree_ids(np.zeros(TREE_SPAN + 1, np.int64), np.zeros(TREE_SPAN + 1, np.int64))
    with pytest.raises(NodeError, match="out of range"):
        tree_ids(np.array([2**60]), np.array([0]))
    with pytest.raises(NodeError, match="out of range"):
        park_ids(np.array([-1]), "lot")


def test_trees_keep_their_ids_in_any_batch_of_blocks_and_parks():
    blocks = _grid_blocks(8)
    walks = Layer.from_geoms(shapely.buffer(blocks.geometry, 4.0).tolist())
    walks = Layer.from_geoms(shapely.difference(walks.geometry, blocks.geometry))
    parks = _node("parks.block", {"mode": "every", "every": "4"}).run(blocks=blocks)
    node = _node("vegetation.trees", {"block_density": "0.01"})
    whole = node.run(blocks=parks["blocks"], parks=parks["parks"], sidewalks=walks)["vegetation"]
    assert len(whole) > 50 and len(np.unique(whole.ids)) == len(whole) and (np.diff(whole.ids) > 0).all()
    zone = np.asarray(whole["zone"]).astype(str)
    assert {"avenue", "block"} <= set(zone)
    # park trees: their park's id x 4 (kind 0), avenue trees: their block's park-slot id x 4 + 1
    park = zone == "block"
    assert np.array_equal(whole.ids[park] // TREE_SPAN, np.asarray(whole["park"])[park] * 4)
    assert ((whole.ids[~park] // TREE_SPAN) % 4 == 1).all()
    # the same trees, with the same ids and bytes, from the first half of the blocks and parks alone
    keep_b = parks["blocks"].ids < blocks.ids[4]
    keep_p = parks["parks"].parent < blocks.ids[4]
    half = node.run(blocks=parks["blocks"].take(keep_b), parks=parks["parks"].take(keep_p), sidewalks=walks)[
        "vegetation"
    ]
    mine = np.isin(whole.ids, half.ids)
    assert len(half) and mine.sum() == len(half)
    assert np.array_equal(shapely.to_wkb(whole.geometry[mine]), shapely.to_wkb(half.geometry))


def test_lot_ids_hold_a_block_of_whole_lieges_size():
    # whole Liège's largest block (17 km² of rural dead ends round the extract's edge) makes 19,611 lots
    block = np.repeat(np.array([3, 2797], np.int64), [5, 19_611])
    ids = lot_ids(block)
    assert len(np.unique(ids)) == len(ids)
    assert np.array_equal(ids // LOT_SPAN, block)
    with pytest.raises(LimitError, match="block 7 makes more than"):
        lot_ids(np.full(LOT_SPAN + 1, 7, np.int64))


def test_the_metropolis_tree_ids_fit_64_bits():
    # configs/metropolis.xml at full scale: some 3,650 major-road enclosures (365 at --scale 0.1);
    # its last enclosure's last block's last lot park, and that park's last tree
    enclosure = 3_700
    lot = (enclosure * ID_SPAN + ID_SPAN - 1) * LOT_SPAN + LOT_SPAN - 1
    park = park_ids(np.array([lot]), "patio")
    ids = tree_ids(park, np.array([0]))
    assert ids[0] == ((park[0] * 4) * TREE_SPAN) and ids[0] < np.iinfo(np.int64).max

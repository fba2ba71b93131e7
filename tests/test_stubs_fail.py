"""The lot property tests can fail (issue 15 part 7): stubs that do no work are caught.

Two stubs of the usual shapes, each run through :func:`test_lots.check_lots` (the
checks of ``test_every_method_partitions_random_blocks`` and ``test_real_blocks``):

* a lot method that keeps every block whole (one lot per block, its street
  facts measured, so partition, frontage and corner checks all hold);
* ``sengine.geom.split.split`` refusing every cut (every polygon "failed"),
  under the real ``lots.recursive`` and ``lots.paris``.

Both used to pass those checks; the "a roomy block gets several lots"
property added to ``check_lots`` makes them fail.
"""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from test_lots import check_lots

import sengine.nodes.lots.nodes as LOTS
import sengine.nodes.lots.paris as PARIS
import sengine.nodes.lots.recursive as RECURSIVE
from sengine import Context, Layer
from sengine.geom.split import RingSet
from sengine.registry import get

BLOCKS = [
    shapely.affinity.rotate(shapely.box(0, 0, 270, 80), 29),  # rotated
    shapely.Polygon([(0, 0), (120, 0), (120, 90), (60, 20), (0, 90)]),  # concave
    shapely.box(0, 0, 150, 150).difference(shapely.box(50, 50, 100, 100)),  # holed
]


def blocks_layer() -> Layer:
    return Layer.from_geoms(BLOCKS, ids=np.arange(len(BLOCKS)) * 10 + 3, district=np.zeros(len(BLOCKS), int))


def keep_whole(blocks: Layer) -> Layer:
    """The stub lot method: every block is one lot, with its street facts measured."""
    owner = np.arange(len(blocks))
    attrs = LOTS.lot_attributes(blocks.geometry, owner, blocks.geometry)
    return Layer.from_geoms(
        blocks.geometry,
        parent=blocks.ids,
        block=blocks.ids,
        inner=np.zeros(len(blocks), bool),
        frontage=attrs["frontage"],
        street_edges=attrs["street_edges"],
        corner=attrs["corner"],
    )


def refuse_every_cut(rs: RingSet, point, direction, **kw):
    """The stub split: no pieces, every polygon failed."""
    n = rs.n
    return rs.take(np.zeros(0, np.int64)), np.zeros(0, np.int64), np.zeros(0, np.int8), np.ones(n, bool)


def test_the_real_methods_pass():
    blocks = blocks_layer()
    for name in ("lots.recursive", "lots.paris", "lots.manhattan"):
        check_lots(blocks, get(name)("lots", {}, Context(seed=5)).run(blocks=blocks)["lots"], name)


def test_a_method_keeping_every_block_whole_fails():
    blocks = blocks_layer()
    with pytest.raises(AssertionError, match="roomy blocks kept whole"):
        check_lots(blocks, keep_whole(blocks), "keep-whole stub")


@pytest.mark.parametrize("name, module", [("lots.recursive", RECURSIVE), ("lots.paris", PARIS)])
def test_a_split_refusing_every_cut_fails(monkeypatch, name, module):
    monkeypatch.setattr(module, "split", refuse_every_cut)
    blocks = blocks_layer()
    ran = get(name)("lots", {}, Context(seed=5)).run(blocks=blocks)
    with pytest.raises(AssertionError, match="roomy blocks kept whole"):
        check_lots(blocks, ran["lots"], name)

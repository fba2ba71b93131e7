"""Stable ids of the open-space features: parks of every level and trees, derived from what they stand on.

A city's ids do not depend on the batch that made them (a whole city, one
shard of its enclosures in :mod:`sengine.shard`, a chunk of a node's
input): blocks are ``enclosure x ID_SPAN + rank`` and lots ``block x
LOT_SPAN + rank`` (:mod:`sengine.nodes.blocks.circuits`,
:mod:`sengine.nodes.lots.nodes`).  Parks and trees follow the same rule:

* a park's **site** is on the lot scale: a lot park's is its lot id, a
  block park's its block's first lot slot (``block x LOT_SPAN``), a patio's
  ``block x LOT_SPAN + rank`` (its rank among its block's patios) and a
  district park's ``enclosure x ID_SPAN x LOT_SPAN + rank`` (the enclosure
  holding its inner point, or the remainder key after every enclosure, as
  blocks outside every enclosure get);
* **park id** = ``site x 4 + level`` (district 0, block 1, lot 2, patio 3):
  unique across levels, and ordered by enclosure first;
* **tree id** = ``zone key x TREE_SPAN + rank``, the zone key being
  ``value x 4 + kind``: kind 0 a park tree (value: its park's id), 1 an
  avenue tree (value: the id its block has or would have as a block park,
  ``block x LOT_SPAN x 4 + 1``), 2 a tree of a vegetation region (value:
  the region's id); rank is its place in the zone.

Sorted by id, the open-space layers are in enclosure order, so a sharded
run's parts, one after the other, are the whole city's layers.
"""

from __future__ import annotations

import numpy as np

from sengine.errors import NodeError

from ..blocks.circuits import ID_SPAN
from ..lots.nodes import LOT_SPAN

__all__ = [
    "LEVELS",
    "TREE_SPAN",
    "TREE_KINDS",
    "park_ids",
    "block_site",
    "district_sites",
    "ranks",
    "tree_ids",
    "avenue_value",
    "join_parks",
]

#: Park levels, in the order of their code in a park id.
LEVELS = ("district", "block", "lot", "patio")
#: Trees a zone may hold (the rank's span in a tree id).
TREE_SPAN = 100_000
#: Kinds of tree zone, in the order of their code in a zone key.
TREE_KINDS = ("park", "avenue", "region")
_MAX = np.iinfo(np.int64).max


def ranks(keys) -> np.ndarray:
    """Rank of each element among the earlier elements with the same key (0, 1, 2 ...), in input order."""
    keys = np.asarray(keys, np.int64)
    if not len(keys):
        return np.zeros(0, np.int64)
    order = np.argsort(keys, kind="stable")
    k = keys[order]
    first = np.r_[True, k[1:] != k[:-1]]
    start = np.maximum.accumulate(np.where(first, np.arange(len(k)), 0))
    out = np.empty(len(keys), np.int64)
    out[order] = np.arange(len(k)) - start
    return out


def block_site(block_ids) -> np.ndarray:
    """A block's site on the lot scale: its first lot slot ``block x LOT_SPAN``."""
    return np.asarray(block_ids, np.int64) * LOT_SPAN


def district_sites(enclosure) -> np.ndarray:
    """Sites of district parks from the enclosure key of each: ``enclosure x ID_SPAN x LOT_SPAN + rank``."""
    enclosure = np.asarray(enclosure, np.int64)
    return enclosure * (ID_SPAN * LOT_SPAN) + ranks(enclosure)


def park_ids(site, level: str, *, where: str = "") -> np.ndarray:
    """Park ids ``site x 4 + level code`` (see the module notes); sites must be non-negative."""
    site = np.asarray(site, np.int64)
    if len(site) and (site.min() < 0 or site.max() > (_MAX - 3) // 4):
        raise NodeError(f"a {level} park's site id {int(site.max())} is out of range for park ids", where=where)
    return site * len(LEVELS) + LEVELS.index(level)


def avenue_value(block_ids) -> np.ndarray:
    """The value keying a block's avenue trees: the id the block has or would have as a block park."""
    return park_ids(block_site(block_ids), "block")


def tree_ids(value, kind, *, where: str = "") -> np.ndarray:
    """Tree ids ``(value x 4 + kind) x TREE_SPAN + rank``, rank counted per zone in input order.

    ``kind`` holds codes of :data:`TREE_KINDS`.  A zone holding more than
    :data:`TREE_SPAN` trees, or a value too large for 64-bit ids, is a
    one-line :class:`~sengine.errors.NodeError`.
    """
    value = np.asarray(value, np.int64)
    if not len(value):
        return np.zeros(0, np.int64)
    limit = _MAX // (len(TREE_KINDS) + 1) // TREE_SPAN - 1
    if value.min() < 0 or value.max() > limit:
        raise NodeError(f"a tree zone's id {int(value.max())} is out of range for tree ids", where=where)
    zone = value * (len(TREE_KINDS) + 1) + np.asarray(kind, np.int64)
    rank = ranks(zone)
    if rank.max() >= TREE_SPAN:
        raise NodeError(
            f"a zone holds more than {TREE_SPAN:,} trees; lower its density or raise the spacing", where=where
        )
    return zone * TREE_SPAN + rank


def join_parks(upstream, new, *, where: str = ""):
    """The parks stream: the upstream parks and the new ones, in id order (an id met twice is a NodeError)."""
    from sengine import Layer

    out = Layer.concat([upstream, new], renumber=False) if upstream is not None and len(upstream) else new
    ids = np.sort(out.ids)
    if len(ids) > 1 and (ids[1:] == ids[:-1]).any():
        dup = int(ids[1:][ids[1:] == ids[:-1]][0])
        raise NodeError(f"park id {dup} arrives twice on the parks stream (parks not numbered by parks.*)", where=where)
    return out.take(np.argsort(out.ids, kind="stable"))

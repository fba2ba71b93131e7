"""Parks at block level (``parks.block``): skylineEngine §4 (one park module, wired at several levels).

"There are cities which have a park so large that it can be considered as a
district by itself ... Other parks are much smaller, having sizes ranging from
a few blocks to the space equivalent to a single building."  District-level
parks come from the land-use map (``roads.districts``' ``parks`` output);
this module turns chosen blocks into parks before they are cut into lots,
and hands the other blocks on.  It also passes upstream parks through, so
one ``parks`` stream reaches the exporter, in id order; a block park's id
comes from its block (:mod:`.ids`).

References
----------
§4 (one Parks module at district, block and lot level) and Fig. 3 of [1]_.

.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
"""

from __future__ import annotations

import logging

import numpy as np
import shapely

from sengine import Layer, NodeResult, Param, Port, SENode, register

from .ids import block_site, join_parks, park_ids
from .level import CountsItsLevel

__all__ = ["choose_park_blocks", "ParksBlock"]

log = logging.getLogger(__name__)

MODES = ("none", "every", "random", "largest", "inside")


def choose_park_blocks(
    geoms, ids, *, mode: str, every: int = 12, share: float = 0.05, min_area: float = 0.0, rng_of=None, zones=None
) -> np.ndarray:
    """Which blocks become parks.

    Parameters
    ----------
    geoms : array_like of shapely.Polygon
        The blocks (m).
    ids : array_like of int
        Their stable ids.
    mode : {"none", "every", "random", "largest", "inside"}
        ``none``: no block; ``every``: the blocks whose id is a multiple of ``every``;
        ``random``: each block with probability ``share``, drawn from
        ``rng_of(block id)`` so the choice does not depend on the batch;
        ``largest``: the ``share`` largest blocks;
        ``inside``: blocks whose inner point lies in ``zones``.
    every : int
        Period for ``every``.
    share : float
        Fraction of blocks for ``random`` and ``largest``.
    min_area : float
        Blocks smaller than this never become parks (m2).
    rng_of : callable, optional
        ``rng_of(id)`` -> numpy.random.Generator (``random`` mode).
    zones : shapely.Geometry, optional
        Park zones (``inside`` mode).

    Returns
    -------
    numpy.ndarray of bool
    """
    geoms = np.asarray(geoms, dtype=object)
    ids = np.asarray(ids, np.int64)
    n = len(geoms)
    area = shapely.area(geoms) if n else np.zeros(0)
    if mode == "none":
        pick = np.zeros(n, bool)
    elif mode == "every":
        pick = (ids % max(int(every), 1)) == 0
    elif mode == "random":
        pick = np.array([rng_of(int(i)).random() < share for i in ids], dtype=bool) if n else np.zeros(0, bool)
    elif mode == "largest":
        k = int(round(share * n))
        pick = np.zeros(n, bool)
        if k > 0:
            order = np.lexsort((ids, -area))
            pick[order[:k]] = True
    elif mode == "inside":
        pick = np.zeros(n, bool)
        if zones is not None and n and not zones.is_empty:
            pick = shapely.within(shapely.point_on_surface(geoms), zones)
    else:  # pragma: no cover - guarded by the parameter's choices
        raise ValueError(f"mode {mode!r} is not one of {', '.join(MODES)}")
    return pick & (area >= min_area)


@register
class ParksBlock(CountsItsLevel, SENode):
    """Block-level parks: turn chosen blocks into parks and hand the rest on to the lots (paper 002 §4).

    Upstream parks (district level, from the land-use map) connected to
    ``parks`` are passed through with the new ones, so one stream reaches the
    exporter.
    """

    name = "parks.block"
    level = "block"
    maps_features = False
    shard_streams = ("parks",)
    inputs = {
        "blocks": Port("blocks", "blocks to choose from"),
        "parks": Port(
            "parks",
            "parks made upstream (district level), passed through; mode 'inside' takes their outline as zones",
            required=False,
        ),
    }
    outputs = {
        "parks": Port("parks", "upstream parks plus the new block-level parks (column level)"),
        "blocks": Port("blocks", "the blocks that did not become parks"),
    }
    params = {
        "mode": Param(
            "str",
            "every",
            choices=MODES,
            doc="how blocks are chosen (none, every Nth id, random, largest, inside the land-use park class)",
        ),
        "every": Param("int", 12, min=1, max=1_000_000, unit="1", doc="every Nth block id becomes a park"),
        "share": Param("float", 0.05, min=0.0, max=1.0, unit="1", doc="fraction of blocks (random, largest)"),
        "min_area": Param("float", 0.0, min=0.0, unit="m2", doc="smaller blocks never become parks"),
    }

    def shard_refusal(self, connected):
        if self.p.mode == "largest":
            return "mode 'largest' ranks every block of the city (use every or random)"
        if self.p.mode == "inside":
            return "mode 'inside' reads every district park's outline (use every or random)"
        return None

    def run(self, *, blocks: Layer, parks: Layer | None = None):
        zones = None
        if self.p.mode == "inside":
            zones = park_zones(parks)
        pick = choose_park_blocks(
            blocks.geometry,
            blocks.ids,
            mode=self.p.mode,
            every=self.p.every,
            share=self.p.share,
            min_area=self.p.min_area,
            rng_of=lambda i: self.rng(i),
            zones=zones,
        )
        if self.p.mode == "none":  # no block-level parks: the blocks go on untouched
            out = parks if parks is not None else Layer.empty(meta=dict(blocks.meta), level=np.dtype("<U8"))
            return NodeResult({"parks": out, "blocks": blocks}, {"block_parks": 0, "park_area_m2": 0.0})
        chosen = blocks.take(pick)
        district = chosen["district"] if "district" in chosen else np.full(len(chosen), -1, np.int64)
        new = Layer.from_geoms(
            chosen.geometry,
            ids=park_ids(block_site(chosen.ids), "block", where=self.where),
            parent=chosen.ids,
            meta=dict(blocks.meta),
            level=np.full(len(chosen), "block"),
            district=np.asarray(district, np.int64),
            area=shapely.area(chosen.geometry) if len(chosen) else np.zeros(0),
        )
        out = join_parks(parks, new, where=self.where)
        report = {"block_parks": int(pick.sum()), "park_area_m2": round(float(new.area()), 1)}
        log.info("parks.block: %d of %d blocks become parks", int(pick.sum()), len(blocks))
        return NodeResult({"parks": out, "blocks": blocks.take(~pick)}, report)


def park_zones(parks: Layer | None):
    """The district-level parks (the land-use map's park class, from ``roads.districts``) as one geometry.

    Empty without parks.  These are the zones of mode ``inside``: they come
    on the ``parks`` port, so the land-use map is vectorized once, upstream.
    """
    if parks is None or not len(parks):
        return shapely.Polygon()
    geoms = parks.geometry
    if "level" in parks:
        geoms = geoms[np.asarray(parks["level"]).astype(str) == "district"]
    return shapely.union_all(geoms) if len(geoms) else shapely.Polygon()

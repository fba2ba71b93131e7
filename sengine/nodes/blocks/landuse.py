"""Land use from map polygons: water and parks inside a block are not built on.

In skylineEngine the land-use map says where the city may build: its water
and park classes are cut out of the buildable area before the streets are
laid (§3-4).  A real city's street faces already exist, and its land use
comes as polygons from the same file (``osm.read``'s ``water`` and
``parks``): a square inside a block, a park filling a block, a river
between two bridges.  This node cuts those polygons out of the blocks
before the lots are drawn, so that no lot and no building stands in a park
or in the water.

The edge a block gets along a park or the water counts as its boundary like
a street edge does: lots may face the park.

Land that no street serves is not built on either (:func:`open_land`): the
land of a block larger than ``max_block_area``, or of a block along the
edge of the data, farther than ``max_depth`` from its streets (its sides
and the cul-de-sacs cut into it), and a piece that touches no street at
all (cut off by the water), are kept as open land: column ``landuse`` is
``"open"`` (``"built"`` elsewhere), and the lot nodes leave it whole.

References
----------
skylineEngine (paper 002), §4 (parks and land use) and §5.2 (real maps).
"""

from __future__ import annotations

import logging

import numpy as np
import shapely

from sengine import Layer, NodeResult, Param, Port, SENode, register
from sengine.geom.polygons import inset

__all__ = ["cut_blocks", "open_land", "BlocksLanduse"]

#: Values of the blocks' ``landuse`` column: lots are drawn on ``BUILT`` blocks only.
BUILT, OPEN = "built", "open"
FRONT_TOL = 0.01  # m: a side of a piece within this of its block's boundary still faces the street

log = logging.getLogger(__name__)


def cut_blocks(blocks, cut, *, min_area: float = 0.0, min_width: float = 0.0) -> tuple[np.ndarray, np.ndarray, dict]:
    """The parts of each block outside every ``cut`` polygon.

    Parameters
    ----------
    blocks : array_like of shapely.Polygon
        Blocks (m).
    cut : array_like of shapely.Geometry
        Land that is not built on (m): water, parks.  Invalid polygons are
        repaired first; points and lines are ignored.
    min_area : float
        Pieces smaller than this are dropped (m2).
    min_width : float
        Pieces of a cut block that are nowhere this wide (their inset by
        half of it is empty) are dropped (m): the strip a park leaves
        along a street.

    Returns
    -------
    pieces : ndarray of shapely.Polygon
        The buildable pieces, block after block.
    block : ndarray of int64
        Index into ``blocks`` of each piece.
    counts : dict
        ``blocks_cut`` (blocks a polygon took land from), ``blocks_removed``
        (blocks left with no piece), ``pieces_dropped`` (under
        ``min_area`` or ``min_width``), ``area_removed_m2``.
    """
    blocks = np.asarray(blocks, dtype=object)
    cut = shapely.get_parts(shapely.make_valid(np.asarray(cut, dtype=object)))
    cut = cut[np.isin(shapely.get_type_id(cut), (3, 6))] if len(cut) else cut
    out = blocks.copy()
    bi = np.empty(0, np.int64)
    if len(blocks) and len(cut):
        bi, ci = shapely.STRtree(cut).query(blocks, predicate="intersects")
        o = np.lexsort((ci, bi))
        bi, ci = bi[o], ci[o]
        first = np.r_[0, np.flatnonzero(np.diff(bi)) + 1] if len(bi) else np.zeros(0, np.int64)
        rank = np.arange(len(bi)) - np.repeat(first, np.diff(np.r_[first, len(bi)]))
        # one difference per (block, polygon) pair, a round per rank: every block loses its k-th polygon in round k
        for k in range(int(rank.max(initial=-1)) + 1):
            sel = rank == k
            out[bi[sel]] = shapely.difference(out[bi[sel]], cut[ci[sel]])
    cut_ones = np.unique(bi)
    bad = cut_ones[~shapely.is_valid(out[cut_ones])] if len(cut_ones) else cut_ones
    out[bad] = shapely.make_valid(out[bad])  # an edge cut off a hair's breadth away collapses into a spike
    pieces, block = shapely.get_parts(out, return_index=True)
    nested = np.isin(shapely.get_type_id(pieces), (6, 7))  # a repaired block may hold a MultiPolygon
    if nested.any():
        inner, k = shapely.get_parts(pieces[nested], return_index=True)
        pieces, block = np.concatenate([pieces[~nested], inner]), np.concatenate([block[~nested], block[nested][k]])
        o = np.argsort(block, kind="stable")
        pieces, block = pieces[o], block[o]
    poly = shapely.get_type_id(pieces) == 3
    area = shapely.area(pieces)
    keep = poly & (area >= min_area)
    thin = np.flatnonzero(keep & np.isin(block, bi))  # only a cut can make a block thin
    if min_width > 0 and len(thin):
        keep[thin] = ~shapely.is_empty(inset(pieces[thin], min_width / 2.0))
    before = shapely.area(blocks).sum() if len(blocks) else 0.0
    counts = {
        "blocks_cut": int(len(np.unique(bi))),
        "blocks_removed": int(len(blocks) - len(np.unique(block[keep]))),
        "pieces_dropped": int((poly & ~keep).sum()),
        "area_removed_m2": round(float(before - area[keep].sum()), 1),
    }
    return pieces[keep], block[keep].astype(np.int64), counts


def open_land(
    pieces, block, blocks, *, max_area: float, max_depth: float, box=None, min_area: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """The land of each block that no street serves, split off as open land.

    Parameters
    ----------
    pieces : ndarray of shapely.Polygon (k,)
        Pieces of blocks (what :func:`cut_blocks` leaves).
    block : ndarray of int (k,)
        Index into ``blocks`` of each piece.
    blocks : ndarray of shapely.Polygon
        The blocks before the cut: their boundary faces the streets (the
        cul-de-sacs cut into them included).
    max_area : float
        Pieces larger than this (m2), and pieces of blocks along the edge
        of the data, lose their land farther than ``max_depth`` from their
        streets to open land (farmland behind a village street, the far
        side of a rail yard, a lake the map does not tag).
    max_depth : float
        How far from a street (m) a large or border block is built on.
    box : (xmin, ymin, xmax, ymax), optional
        The edge of the data (m): a block side along it is no street.
    min_area : float
        Parts smaller than this (m2) are dropped (counted).

    Returns
    -------
    pieces : ndarray of shapely.Polygon
        The pieces, the split ones replaced by their built and open parts.
    block : ndarray of int64
        Index into ``blocks`` of each (non-decreasing when ``block`` was).
    is_open : ndarray of bool
        Open land: no street serves it.  A piece that touches no street at
        all (cut off by the water, or closed only by the edge of the data)
        is open as a whole.
    counts : dict
        ``open_no_street`` (whole pieces), ``open_split`` (pieces split into
        built and open land), ``open_parts_dropped`` (under ``min_area``).
    """
    pieces = np.asarray(pieces, dtype=object)
    block = np.asarray(block, np.int64)
    blocks = np.asarray(blocks, dtype=object)
    k = len(pieces)
    counts = {"open_no_street": 0, "open_split": 0, "open_parts_dropped": 0}
    if not k:
        return pieces, block, np.zeros(0, bool), counts
    area = shapely.area(pieces)
    # the streets of a piece: its block's boundary, off the edge of the data
    edge = shapely.boundary(blocks[block])
    border = np.zeros(k, bool)
    if box is not None:
        rim = shapely.buffer(shapely.boundary(shapely.box(*box)), 1e-6, cap_style="flat", join_style="mitre")
        border = shapely.intersects(edge, rim)
        edge[border] = shapely.difference(edge[border], rim)
    # only a cut piece, or a block along the edge of the data, can miss every street
    whole = np.isclose(area, shapely.area(blocks[block]), rtol=1e-9)
    ask = ~whole | border
    lonely = np.zeros(k, bool)
    lonely[ask] = ~shapely.intersects(pieces[ask], edge[ask])
    counts["open_no_street"] = int(lonely.sum())
    far = np.full(k, None, dtype=object)
    big = np.flatnonzero(~lonely & ~border & (area > max_area))
    if len(big):  # every side a street (or the water, a park, which lots may face): the land beyond reach
        far[big] = shapely.buffer(pieces[big], -max_depth, quad_segs=4)
    edgy = np.flatnonzero(~lonely & border)
    if len(edgy):  # the sides along the edge of the data are no streets: grown past it, eroded, clipped back
        rect = shapely.box(*box)
        band = shapely.difference(shapely.box(*np.add(box, np.r_[-1, -1, 1, 1] * (2 * max_depth + 1))), rect)
        grown = shapely.union(pieces[edgy], band)
        far[edgy] = shapely.intersection(shapely.buffer(grown, -max_depth, quad_segs=4), rect)
    split = np.flatnonzero(np.not_equal(far, None))
    split = split[~shapely.is_empty(far[split])]
    split = split[shapely.area(far[split]) >= max(min_area, 1e-9)]
    counts["open_split"] = int(len(split))
    geoms, owner, is_open = [pieces], [np.arange(k)], [lonely]
    if len(split):
        near = shapely.difference(pieces[split], far[split])
        keep = np.ones(k, bool)
        keep[split] = False
        geoms = [pieces[keep], near, far[split]]
        owner = [np.flatnonzero(keep), split, split]
        is_open = [lonely[keep], np.zeros(len(split), bool), np.ones(len(split), bool)]
    parts, pidx = shapely.get_parts(np.concatenate(geoms), return_index=True)
    owner, is_open = np.concatenate(owner)[pidx], np.concatenate(is_open)[pidx]
    ok = (shapely.get_type_id(parts) == 3) & (shapely.area(parts) >= min_area)
    counts["open_parts_dropped"] = int((~ok & np.isin(owner, split)).sum())
    parts, owner, is_open = parts[ok], owner[ok], is_open[ok]
    o = np.lexsort((is_open, owner))  # piece by piece, its built part first
    return parts[o], block[owner[o]], is_open[o], counts


def street_fronts(pieces: np.ndarray, blocks: np.ndarray, *, tol: float = FRONT_TOL) -> np.ndarray:
    """The part of each piece's boundary that faces a street: what it keeps of its block's boundary.

    A block traced from the street graph faces streets all round; cutting
    water, a park or open land out of it makes new sides that face no
    street, so no lot may front onto them (a lot's frontage is street
    frontage).

    Parameters
    ----------
    pieces : ndarray of Polygon
        The pieces of land (m).
    blocks : ndarray of Polygon
        The block each piece was cut from.
    tol : float
        Distance (m) within which a side of a piece lies on its block's boundary.

    Returns
    -------
    ndarray of object
        ``None`` for a piece that is its whole block (every side faces a street),
        else its street-facing boundary as a (Multi)LineString, possibly empty.
    """
    out = np.full(len(pieces), None, dtype=object)
    cut = np.flatnonzero(~shapely.equals_exact(pieces, blocks, tolerance=0.0)) if len(pieces) else np.zeros(0, int)
    if len(cut):
        rim = shapely.buffer(shapely.boundary(blocks[cut]), tol, cap_style="flat", quad_segs=1)
        out[cut] = shapely.intersection(shapely.boundary(pieces[cut]), rim)
    return out


@register
class BlocksLanduse(SENode):
    """Blocks minus the water and the parks in them: the land the lots are drawn on (§4, §5.2)."""

    name = "blocks.landuse"
    inputs = {
        "blocks": Port("blocks", "blocks"),
        "water": Port("polygons", "water areas (e.g. osm.read's water)", required=False),
        "parks": Port("parks", "parks (e.g. osm.read's parks)", required=False),
    }
    outputs = {
        "blocks": Port(
            "blocks",
            "the pieces of land; a block cut in two keeps its id on the first piece; column landuse "
            "'built' or 'open' (no street serves it: the lot nodes leave it whole); column street_front: "
            "the street-facing boundary of a cut piece (None: all of it)",
        )
    }
    params = {
        "max_block_area": Param(
            "float",
            500_000.0,
            min=0.0,
            unit="m2",
            doc="a block larger than this (50 ha: 700 x 700 m, past the largest urban superblocks of "
            "16-25 ha) is built on only within max_depth of its streets; the rest is open land: farmland, "
            "forest, a rail yard, a lake the map does not tag",
        ),
        "max_depth": Param(
            "float",
            100.0,
            min=1.0,
            unit="m",
            doc="how far from its streets (cul-de-sacs included) a large block, or one along the edge of "
            "the data, is built on: two rows of lots back to back",
        ),
        "min_area": Param("float", 50.0, min=0.0, unit="m2", doc="pieces smaller than this are dropped"),
        "min_width": Param(
            "float",
            4.0,
            min=0.0,
            unit="m",
            doc="pieces of a cut block nowhere this wide are dropped (a strip left along a park)",
        ),
    }

    def run(self, *, blocks: Layer, water: Layer | None = None, parks: Layer | None = None) -> NodeResult:
        cut = [lay.geometry for lay in (water, parks) if lay is not None and len(lay)]
        geoms = np.concatenate(cut) if cut else np.empty(0, dtype=object)
        pieces, src, counts = cut_blocks(blocks.geometry, geoms, min_area=self.p.min_area, min_width=self.p.min_width)
        pieces, src, is_open, ocounts = open_land(
            pieces,
            src,
            blocks.geometry,
            max_area=self.p.max_block_area,
            max_depth=self.p.max_depth,
            box=blocks.meta.get("bbox"),
            min_area=self.p.min_area,
        )
        out = blocks.take(src)
        # the first piece of a block keeps its id; further pieces get new ones after the largest
        again = np.r_[False, src[1:] == src[:-1]] if len(src) else np.zeros(0, bool)
        top = int(blocks.ids.max(initial=-1)) + 1
        ids = out.ids.copy()
        ids[again] = top + np.arange(int(again.sum()))
        landuse = np.where(is_open, OPEN, BUILT)
        # parts too small to keep, split off the open land, are removed land too
        counts["area_removed_m2"] = round(float(blocks.area() - shapely.area(pieces).sum()), 1)
        front = street_fronts(pieces, blocks.geometry[src])
        counts["pieces_with_land_edges"] = int(np.not_equal(front, None).sum())
        out = Layer(pieces, ids, out.parent, {**out.attrs, "landuse": landuse, "street_front": front}, out.meta)
        report = {**counts, **ocounts, "open_blocks": int(is_open.sum()), "blocks": len(out)}
        log.info(
            "%s: %d of %d blocks lose water or park land (%.0f m2); %d pieces",
            self.where,
            counts["blocks_cut"],
            len(blocks),
            counts["area_removed_m2"],
            len(out),
        )
        return NodeResult({"blocks": out}, report)

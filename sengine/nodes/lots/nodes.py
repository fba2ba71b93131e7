"""Lots: partitions of a block into parcels (skylineEngine §5.5, Fig. 9).

Three methods, as in the paper, each in its own module:

* **Manhattan** (:mod:`.lots_manhattan`; §5.5, Fig. 9 right): two rows of
  lots along the main axis of the block's oriented bounding box.
* **Paris** (:mod:`.lots_paris`; §5.5, Fig. 9 left): the contour split into
  equal segments, each displaced inwards by a random depth; a courtyard in
  the middle.
* **Recursive** (:mod:`.lots_recursive`; Parish and Müller [13]): cut across
  the longest edge until lots are under ``max_area``, keeping street access.
* **Skeleton** (:mod:`.skeleton`; Vanegas et al. 2012): street strips of a
  target depth from the block's offset, cut into lots of a target width,
  corner lots facing two streets, the interior left inner, merged or a park.

This module holds what they share: the street-facing attributes of a lot
(frontage, street edges, corner, and through :mod:`.vocabulary` its kind
and depth) and the node classes.  Every block edge
faces a street (blocks are faces of the street graph), so a lot's
*frontage* is the length of its boundary lying on its block's boundary.

References
----------
skylineEngine §5.5.  [13] Parish, Müller, "Procedural modeling of cities",
SIGGRAPH 2001.
"""

from __future__ import annotations

import logging

import numpy as np
import shapely

from sengine import Layer, NodeResult, Param, Port, SENode, register
from sengine.errors import ParameterError
from sengine.geom.boundary import ring_segments, segments_on_boundary, segments_on_box, segments_on_lines
from sengine.random import mix64
from sengine.registry import declare_rule

from ..maps import rules_of
from .manhattan import ON_TOL, manhattan_lots
from .paris import paris_lots
from .recursive import check_recursive, recursive_lots
from .skeleton import CORNERS, INTERIORS, skeleton_lots
from .vocabulary import LotSplit, lot_depth, lot_kind

__all__ = [
    "lot_attributes",
    "frontage",
    "manhattan_lots",
    "recursive_lots",
    "paris_lots",
    "skeleton_lots",
    "LotsManhattan",
    "LotsSkeleton",
    "LotsParis",
    "LotsRecursive",
    "LotsDistrict",
]

log = logging.getLogger(__name__)


# -- frontage and lot attributes ---------------------------------------------------


def frontage(geoms, owner, blocks) -> np.ndarray:
    """Length (m) of each geometry's boundary lying on its owner's boundary.

    Parameters
    ----------
    geoms : array_like of shapely.Polygon (k,)
    owner : array_like of int (k,)
        Index into ``blocks`` for each geometry.
    blocks : array_like of shapely.Polygon
    """
    geoms = np.asarray(geoms, dtype=object)
    if len(geoms) == 0:
        return np.zeros(0)
    p0, p1, idx, _, on = segments_on_boundary(geoms, owner, blocks, tol=ON_TOL)
    ln = np.hypot(*(p1 - p0).T)
    return np.bincount(idx[on], weights=ln[on], minlength=len(geoms))


def lot_attributes(
    lots,
    owner,
    blocks,
    *,
    corner_angle: float = 30.0,
    edge_angle: float = 15.0,
    on=None,
    known=None,
    box=None,
    fronts=None,
) -> dict:
    """Street-facing facts of each lot, from its block's boundary.

    Parameters
    ----------
    lots : array_like of shapely.Polygon (k,)
    owner : array_like of int (k,)
        Index into ``blocks`` of each lot's block.
    blocks : array_like of shapely.Polygon
    corner_angle : float
        Two frontage edges turning by more than this (deg) make a corner lot.
    edge_angle : float
        Consecutive frontage segments turning by less than this (deg) count as
        one street edge.
    on, known : ndarray of bool, optional
        Which boundary segment of each lot lies on its block's boundary, as
        the method knows it (one per segment of :func:`sengine.geom.boundary.ring_segments`
        of ``lots``), and for which lots it knows (default all when ``on`` is
        given); the others are measured (within ``ON_TOL``).
    box : tuple of float, optional
        The box that closed the land round an extract's streets (the blocks'
        ``meta["bbox"]``): block boundary on it is no street, so no frontage.
    fronts : array_like of object, optional
        Per block, its street-facing boundary where water, a park or open
        land was cut out of it (``blocks.landuse``'s ``street_front``;
        ``None``: all of it): the rest of its boundary is no frontage.

    Returns
    -------
    dict of ndarray
        ``frontage`` (m), ``street_edges`` (int: maximal straight runs of
        boundary on the block boundary), ``corner`` (bool) and
        ``front_angle`` (deg in [0, 180): direction of the longest frontage
        segment, ``nan`` for none).
    """
    lots = np.asarray(lots, dtype=object)
    k = len(lots)
    out = {
        "frontage": np.zeros(k),
        "street_edges": np.zeros(k, np.int64),
        "corner": np.zeros(k, bool),
        "front_angle": np.full(k, np.nan),
    }
    if k == 0:
        return out
    owner = np.asarray(owner, np.int64)
    if on is None:
        p0, p1, idx, ring, on = segments_on_boundary(lots, owner, blocks, tol=ON_TOL)
    else:
        p0, p1, idx, ring = ring_segments(lots)
        on = np.asarray(on, bool).copy()
        if len(on) != len(idx):
            raise ValueError(f"lot_attributes: {len(on)} segment flags for {len(idx)} segments")
        unknown = np.flatnonzero(~np.asarray(known, bool)) if known is not None else np.zeros(0, np.int64)
        if len(unknown):
            _, _, uidx, _, uon = segments_on_boundary(lots[unknown], owner[unknown], blocks, tol=ON_TOL)
            mine = np.isin(idx, unknown)
            on[mine] = uon  # segments of a subset come in the same order
    if len(idx) == 0:
        return out
    d = p1 - p0
    ln = np.hypot(d[:, 0], d[:, 1])
    on &= (ln > 1e-9) & ~segments_on_box(p0, p1, box)
    if fronts is not None and on.any():
        sel = np.flatnonzero(on)
        on[sel] = segments_on_lines(p0[sel], p1[sel], np.asarray(fronts, dtype=object)[owner[idx[sel]]])
    dirn = d / np.maximum(ln, 1e-300)[:, None]
    out["frontage"] = np.bincount(idx[on], weights=ln[on], minlength=k)
    # previous segment within the same ring (cyclic)
    s = np.arange(len(idx))
    start = np.r_[True, ring[1:] != ring[:-1]]
    first = np.maximum.accumulate(np.where(start, s, 0))
    end = np.r_[start[1:], True]
    last_of = np.zeros(len(idx), np.int64)
    last_of[first[end]] = s[end]
    prev = np.where(start, last_of[first], s - 1)
    # skip zero-length predecessors is not needed for straight runs: treat as breaks
    turn = np.abs(_cross(dirn, dirn[prev])) > np.sin(np.radians(edge_angle))
    turn |= np.einsum("ij,ij->i", dirn, dirn[prev]) < 0
    new_edge = on & (~on[prev] | turn)
    # a ring whose every segment is frontage and never turns still counts one edge
    out["street_edges"] = np.bincount(idx[new_edge], minlength=k)
    allon = np.bincount(idx, weights=(~on).astype(float), minlength=k) == 0
    out["street_edges"] = np.where(allon & (out["street_edges"] == 0) & (out["frontage"] > 0), 1, out["street_edges"])
    # longest frontage segment per lot and its direction
    cand = np.flatnonzero(on)
    if len(cand):
        o = np.lexsort((ln[cand], idx[cand]))
        c = cand[o]
        lastmask = np.r_[idx[c][1:] != idx[c][:-1], True]
        best = c[lastmask]
        bl = idx[best]
        d0 = np.zeros((k, 2))
        d0[bl] = dirn[best]
        out["front_angle"][bl] = np.degrees(np.arctan2(dirn[best, 1], dirn[best, 0])) % 180.0
        big = on & (ln > 0.5)
        crossv = np.abs(_cross(dirn, d0[idx]))
        out["corner"] = np.bincount(idx[big & (crossv > np.sin(np.radians(corner_angle)))], minlength=k) > 0
    return out


def _cross(a, b):
    return a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]


# -- nodes ---------------------------------------------------------------------------

_METHODS = ("manhattan", "paris", "recursive", "skeleton")


def _check_partition(blocks, lots, owner, report):
    """Blocks whose lots miss more than 0.1 % of their area are kept whole (counted)."""
    n = len(blocks)
    barea = shapely.area(blocks)
    larea = np.bincount(owner, weights=shapely.area(lots), minlength=n) if len(lots) else np.zeros(n)
    bad = np.abs(larea - barea) > 1e-3 * np.maximum(barea, 1e-12)
    bad &= barea > 0
    if bad.any():
        report["kept_whole"] = report.get("kept_whole", 0) + int(bad.sum())
        keep = ~bad[owner]
        whole = np.flatnonzero(bad)
        return np.r_[lots[keep], blocks[whole]], np.r_[owner[keep], whole], keep, len(whole)
    return lots, owner, np.ones(len(lots), bool), 0


class _SegmentFlags:
    """Per-segment 'lies on the block boundary' flags of lots, as far as the method knows them."""

    def __init__(self, lots, on=None, known=None):
        self.count = shapely.get_num_coordinates(lots) - 1 - shapely.get_num_interior_rings(lots)
        self.count = np.maximum(self.count, 0)
        self.on = np.zeros(int(self.count.sum()), bool) if on is None else np.asarray(on, bool)
        self.known = np.zeros(len(lots), bool) if on is None else np.asarray(known, bool)
        if len(self.on) != self.count.sum():  # not aligned with the lots: measure them all
            self.on, self.known = np.zeros(int(self.count.sum()), bool), np.zeros(len(lots), bool)

    def take(self, idx) -> _SegmentFlags:
        idx = np.asarray(idx, np.int64)
        start = np.cumsum(self.count) - self.count
        c = self.count[idx]
        seg = np.repeat(start[idx], c) + np.arange(int(c.sum())) - np.repeat(np.cumsum(c) - c, c)
        out = _SegmentFlags.__new__(_SegmentFlags)
        out.count, out.on, out.known = c, self.on[seg], self.known[idx]
        return out

    def append(self, lots) -> _SegmentFlags:
        """These flags, then unknown ones for ``lots``."""
        return self.join(_SegmentFlags(lots))

    def join(self, more: _SegmentFlags) -> _SegmentFlags:
        out = _SegmentFlags.__new__(_SegmentFlags)
        out.count = np.r_[self.count, more.count]
        out.on, out.known = np.r_[self.on, more.on], np.r_[self.known, more.known]
        return out


#: Lots a block may hold: a lot's id is ``block id x LOT_SPAN + its rank in the block``.  Whole
#: Liège's largest block (17 km² of rural roads, all dead ends, round the edge of the extract)
#: makes 19,611 lots; the metropolis's tree ids, the longest ids derived from lots
#: (:mod:`sengine.nodes.parks.ids`), still fit 64 bits at this span.
LOT_SPAN = 100_000


def lot_ids(block, *, where: str = "") -> np.ndarray:
    """Ids of lots sorted by block: ``block id x LOT_SPAN + rank``, derived from the block, not the run's order.

    The same lot has the same id whether its city runs whole, in chunks or
    in shards (:mod:`sengine.shard`), and the buildings' random draws keyed
    by it are the same too.
    """
    block = np.asarray(block, np.int64)
    if not len(block):
        return np.zeros(0, np.int64)
    first = np.r_[True, block[1:] != block[:-1]]
    rank = np.arange(len(block)) - np.maximum.accumulate(np.where(first, np.arange(len(block)), 0))
    if rank.max() >= LOT_SPAN:
        from sengine.errors import LimitError

        b = int(block[int(np.argmax(rank))])
        raise LimitError(f"block {b} makes more than {LOT_SPAN:,} lots; make the lots larger", where=where)
    return block * LOT_SPAN + rank


class _Lots(SENode):
    """Shared body of the lot nodes: attributes, partition check, layer."""

    inputs = {"blocks": Port("blocks", "blocks to divide")}
    outputs = {"lots": Port("lots", "lots; parent = block id")}
    maps_features = True
    method = ""

    def split(self, blocks: Layer, report: dict, **inputs: Layer | None) -> LotSplit:
        """The method's lots of ``blocks`` (see :class:`.vocabulary.LotSplit`); ``inputs``: the other ports."""
        raise NotImplementedError

    def run(self, *, blocks: Layer, **inputs: Layer | None) -> NodeResult:
        blocks = blocks.take(np.flatnonzero(blocks["landuse"] != "open")) if "landuse" in blocks else blocks
        report: dict = {"blocks": len(blocks)}
        geoms = blocks.geometry
        if len(blocks) == 0:
            none = Layer.from_geoms(
                [],
                meta=blocks.meta,
                block=np.empty(0, np.int64),
                district=np.empty(0, np.int64),
                corner=np.empty(0, bool),
                frontage=np.empty(0),
                street_edges=np.empty(0, np.int64),
                method=np.empty(0, "<U9"),
                inner=np.empty(0, bool),
                front_angle=np.empty(0),
                kind=np.empty(0, "<U6"),
                depth=np.empty(0),
                park=np.empty(0, bool),
            )
            return NodeResult({"lots": none}, report)
        empty = shapely.is_empty(geoms) | (shapely.area(geoms) <= 0)
        report["skipped_empty"] = int(empty.sum())
        res = self.split(blocks, report, **inputs)
        lots, owner, method, inner, park = res.lots, res.owner, res.method, res.inner, res.park
        flags = _SegmentFlags(lots, res.on, res.known)
        ok = np.flatnonzero(~shapely.is_empty(lots) & (shapely.get_type_id(lots) == 3))
        lots, owner, method, inner, park = lots[ok], owner[ok], method[ok], inner[ok], park[ok]
        flags = flags.take(ok)
        lots, owner, keep, nwhole = _check_partition(geoms, lots, owner, report)
        method = np.r_[method[keep], np.full(nwhole, "whole")]
        inner = np.r_[inner[keep], np.zeros(nwhole, bool)]
        park = np.r_[park[keep], np.zeros(nwhole, bool)]
        flags = flags.take(np.flatnonzero(keep)).append(lots[len(lots) - nwhole :])
        o = np.lexsort((np.arange(len(owner)), owner))
        lots, owner, method, inner, park, flags = lots[o], owner[o], method[o], inner[o], park[o], flags.take(o)
        att = lot_attributes(
            lots,
            owner,
            geoms,
            on=flags.on,
            known=flags.known,
            **_streets_of(blocks),
        )
        district = (
            np.asarray(blocks["district"], np.int64)[owner]
            if "district" in blocks
            else np.full(len(lots), -1, np.int64)
        )
        kind = lot_kind(att["frontage"], att["corner"], inner)
        report["lots"] = int(len(lots))
        report["no_frontage"] = int(((att["frontage"] <= 0) & ~inner).sum())
        report["kinds"] = {k: int((kind == k).sum()) for k in ("street", "corner", "inner")}
        lay = Layer.from_geoms(
            lots,
            ids=lot_ids(blocks.ids[owner], where=self.where),
            parent=blocks.ids[owner],
            meta=blocks.meta,
            block=blocks.ids[owner],
            district=district,
            corner=att["corner"],
            frontage=att["frontage"],
            street_edges=att["street_edges"],
            method=method.astype(str),
            inner=inner,
            front_angle=att["front_angle"],
            kind=kind,
            depth=lot_depth(lots, att["front_angle"]),
            park=park,
            # the block's fabric (blocks.grain) goes with its lots: the buildings follow it
            **{c: blocks[c][owner] for c in INHERITED if c in blocks},
        )
        return NodeResult({"lots": lay}, report)


def _manhattan(self, geoms, report, *, count, width, min_depth, row_depth, min_area, fronts=None, box=None):
    lots, owner, inner, off_street = manhattan_lots(
        geoms,
        count=count,
        width=width,
        min_depth=min_depth,
        depth=row_depth,
        min_area=min_area,
        report=report,
        fronts=fronts,
        box=box,
    )
    o = np.argsort(owner, kind="stable")
    lots, off_street = lots[o], off_street[o]
    # what the method knows of frontage: none on the lots inside their block; the others are measured
    on = np.zeros(int((shapely.get_num_coordinates(lots) - 1 - shapely.get_num_interior_rings(lots)).sum()), bool)
    return LotSplit(lots, owner[o], np.full(len(lots), "manhattan"), inner[o], on, off_street)


def _seeds(self, ids) -> np.ndarray:
    """One seed per block, from (network seed, node id, block id): independent of batching."""
    base = self.rng().integers(0, 2**63, dtype=np.uint64)
    return mix64(base, np.asarray(ids).astype(np.uint64))


def _apart(geoms) -> list[np.ndarray]:
    """Positions of ``geoms`` in passes whose polygons never overlap (touching is no overlap).

    Blocks cut from one street graph never overlap and make one pass; a
    polygon overlapping earlier ones goes to the first pass holding none of
    them (greedy colouring of the overlap graph, in order).
    """
    n = len(geoms)
    if n < 2:
        return [np.arange(n)]
    tree = shapely.STRtree(geoms)
    a, b = tree.query(geoms, predicate="overlaps")
    also, into = tree.query(geoms, predicate="contains")  # equal or nested: not 'overlaps'
    a, b = np.minimum(np.r_[a, also], np.r_[b, into]), np.maximum(np.r_[a, also], np.r_[b, into])
    pair = a < b
    if not pair.any():
        return [np.arange(n)]
    later: dict[int, list[int]] = {}
    for i, j in zip(a[pair].tolist(), b[pair].tolist()):
        later.setdefault(j, []).append(i)
    colour = np.zeros(n, np.int64)
    for j in sorted(later):
        taken = {int(colour[i]) for i in later[j]}
        colour[j] = next(c for c in range(n) if c not in taken)
    return [np.flatnonzero(colour == c) for c in range(int(colour.max()) + 1)]


def _recursive(
    self,
    geoms,
    ids,
    report,
    *,
    max_area,
    min_area,
    min_frontage,
    row_depth,
    max_aspect,
    jitter,
    inner_lots,
    fronts=None,
    box=None,
):
    check_recursive(
        geoms, max_area=max_area, min_area=min_area, min_frontage=min_frontage, where=self.where, report=report
    )
    lots, owner, on, inner = recursive_lots(
        geoms,
        max_area=max_area,
        min_area=min_area,
        min_frontage=min_frontage,
        depth=row_depth,
        max_aspect=max_aspect,
        jitter=jitter,
        inner=inner_lots,
        seeds=_seeds(self, ids),
        report=report,
        street=True,
        fronts=fronts,
        box=box,
    )
    largest = np.asarray(max_area, np.float64)[owner] if np.ndim(max_area) else max_area
    over = int(((shapely.area(lots) > largest) & ~inner).sum())  # inner lots stay whole by design
    report["over_max_area"] = report.get("over_max_area", 0) + over
    return LotSplit(lots, owner, np.full(len(lots), "recursive"), inner, on, np.ones(len(lots), bool))


def _paris(self, geoms, ids, report, *, segment, depth, deviation, min_frontage, min_area, fronts=None, box=None):
    lots, owner, inner, on, known = paris_lots(
        geoms,
        segment=segment,
        depth=depth,
        deviation=deviation,
        seeds=_seeds(self, ids),
        min_frontage=min_frontage,
        min_area=min_area,
        report=report,
        street=True,
        fronts=fronts,
        box=box,
    )
    return LotSplit(lots, owner, np.full(len(lots), "paris"), inner, on, known)


def _skeleton(self, geoms, ids, report, *, where=None, fronts=None, box=None, lot_area=None, **p):
    """Skeleton lots of ``geoms``; a block whose whole boundary is shorter than ``lot_width_min`` is
    kept whole (counted), and when every block is so, the parameter cannot hold: an error.  ``lot_area``
    (per block, m2, 0: unset): each block's own lot size (:func:`_skeleton_sizes`)."""
    where = where or self.where
    if p["lot_width_min"] > p["width"]:
        raise ParameterError(
            f"lot_width_min={p['lot_width_min']:g} m is more than the target width={p['width']:g} m", where=where
        )
    if p["lot_area_min"] > p["lot_area_max"]:
        raise ParameterError(
            f"lot_area_min={p['lot_area_min']:g} m2 is more than lot_area_max={p['lot_area_max']:g} m2", where=where
        )
    perim = shapely.length(shapely.boundary(geoms)) if len(geoms) else np.zeros(0)
    live = shapely.area(geoms) > 0
    short = live & (perim < p["lot_width_min"])
    if live.any() and short[live].all():
        raise ParameterError(
            f"lot_width_min={p['lot_width_min']:g} m is more than the whole boundary of every block "
            f"(the longest is {perim[live].max():.1f} m)",
            where=where,
        )
    report["skipped_width"] = report.get("skipped_width", 0) + int(short.sum())
    if short.any():
        log.warning("%s: %d block(s) shorter all round than lot_width_min are kept whole", where, int(short.sum()))
    go = np.flatnonzero(~short)
    sizes = _skeleton_sizes(lot_area, p)
    seeds = _seeds(self, ids)
    keep = np.flatnonzero(short)
    parts = []
    # one face graph is traced for all the blocks of a pass, so blocks lying over each other (a user's
    # file; a street graph's never do) go to different passes
    for run in _apart(geoms[go]):
        sel = go[run]
        fr = None if fronts is None else np.asarray(fronts, dtype=object)[sel]
        res = skeleton_lots(
            geoms[sel],
            seeds=seeds[sel],
            fronts=fr,
            box=box,
            **{k: v[sel] if isinstance(v, np.ndarray) else v for k, v in sizes.items()},
        )
        for k, v in res.report.items():
            report[k] = report.get(k, 0) + v
        parts.append((res, sel))
    lots = np.concatenate([res.lots for res, _ in parts] + [geoms[keep]])
    owner = np.concatenate([sel[res.owner] for res, sel in parts] + [keep]).astype(np.int64)
    inner = np.concatenate([res.inner for res, _ in parts] + [np.zeros(len(keep), bool)])
    park = np.concatenate([res.park for res, _ in parts] + [np.zeros(len(keep), bool)])
    flags = _SegmentFlags(np.zeros(0, dtype=object))
    for res, _ in parts:
        flags = flags.join(_SegmentFlags(res.lots, res.on, res.known))
    flags = flags.append(geoms[keep])
    o = np.argsort(owner, kind="stable")
    flags = flags.take(o)
    meth = np.full(len(lots), "skeleton")
    return LotSplit(lots[o], owner[o], meth, inner[o], flags.on, flags.known, park[o])


_P_ROW_DEPTH = Param(
    "float",
    30.0,
    min=1.0,
    max=1000.0,
    unit="m",
    doc="target lot depth: blocks deeper than this get back-to-back rows (recursive: twice, manhattan: 4x)",
)
_P_MIN_AREA = Param(
    "float",
    50.0,
    min=1.0,
    max=1e6,
    unit="m2",
    doc="no lot smaller than this: cuts leaving one are refused, slivers merge",
)
_P_MANHATTAN = {
    "count": Param("int", 0, min=0, max=1000, unit="1", doc="lots per side of the main axis; 0 = from width"),
    "width": Param(
        "float",
        65.0,
        min=0.5,
        unit="m",
        doc="target lot width along the main axis (65 m: ~8 lots per 80 x 270 m block, as in the paper)",
    ),
    "min_depth": Param("float", 10.0, min=0.0, unit="m", doc="blocks narrower than twice this get one row"),
    "row_depth": _P_ROW_DEPTH,
    "min_area": _P_MIN_AREA,
}
_P_RECURSIVE = {
    "max_area": Param("float", 800.0, min=1.0, unit="m2", doc="split lots until they are under this area"),
    "min_area": _P_MIN_AREA,
    "min_frontage": Param("float", 4.0, min=0.0, unit="m", doc="street frontage every street-facing lot must keep"),
    "row_depth": _P_ROW_DEPTH,
    "max_aspect": Param(
        "float",
        6.0,
        min=1.0,
        max=100.0,
        unit="1",
        doc="no cut leaves a lot longer than this times its width (1:max_aspect)",
    ),
    "jitter": Param("float", 0.25, min=0.0, max=0.9, unit="1", doc="cut position spread, fraction of the extent"),
    "inner_lots": Param(
        "str",
        "compact",
        choices=("compact", "split"),
        doc="land behind the rows of a deep block: inner lots split only to max_aspect (compact) or to max_area",
    ),
}
_P_PARIS = {
    "segment": Param("float", 20.0, min=1.0, unit="m", doc="contour segment length (one perimeter lot each)"),
    "depth": Param(
        "float", 22.0, min=0.5, unit="m", doc="mean lot depth (inward displacement; European perimeter blocks: 15-35 m)"
    ),
    "deviation": Param("float", 3.0, min=0.0, unit="m", doc="standard deviation of the lot depth"),
    "min_frontage": Param(
        "float", 2.0, min=0.0, unit="m", doc="perimeter pieces with less frontage join a neighbouring lot"
    ),
    "min_area": _P_MIN_AREA,
}


_P_SKELETON = {
    "depth": Param(
        "float",
        22.0,
        min=0.5,
        unit="m",
        doc="target strip depth: how far lots reach from the street (European perimeter blocks: 15-35 m)",
    ),
    "width": Param("float", 15.0, min=0.5, unit="m", doc="target lot width along the street"),
    "lot_width_min": Param("float", 6.0, min=0.0, max=1000.0, unit="m", doc="least street frontage of a lot"),
    "lot_area_min": Param("float", 50.0, min=1.0, max=1e6, unit="m2", doc="smaller lots join a neighbour (counted)"),
    "lot_area_max": Param(
        "float",
        2000.0,
        min=1.0,
        max=1e7,
        unit="m2",
        doc="lots are no wider than this / depth; interior=split cuts inner lots under it",
    ),
    "inner_area_max": Param(
        "float",
        20000.0,
        min=1.0,
        max=1e9,
        unit="m2",
        doc="interior=inner: a larger inner lot (2 ha: a 140 m square) is backland, not a courtyard, and is cut "
        "into inner lots under this",
    ),
    "irregularity": Param(
        "float", 0.3, min=0.0, max=1.0, unit="1", doc="spread of lot widths: standard deviation of a share / 2"
    ),
    "corner": Param(
        "str", "merge", choices=CORNERS, doc="merge: one corner lot facing both streets; split: halved on the bisector"
    ),
    "interior": Param(
        "str",
        "inner",
        choices=INTERIORS,
        doc="land deeper than depth: one inner lot, inner lots under lot_area_max, merged into the street lots, a park",
    ),
    "force_street_access": Param(
        "bool", True, doc="street pieces with less than lot_width_min of frontage join a neighbour"
    ),
    "corner_angle": Param("float", 30.0, min=1.0, max=170.0, unit="deg", doc="a turn of more than this ends a street"),
}


#: Block columns their lots carry (blocks.grain's fabric: the massing follows it).
INHERITED = ("grain", "fabric")


def _lot_area(blocks: Layer, sel, min_area: float, where, name: str = "min_area") -> np.ndarray | None:
    """The ``lot_area`` column (m2, blocks.grain) of blocks ``sel``, 0 where unset; ``None`` without the column.

    A positive lot area under the node's least lot (``name``: its
    parameter, ``min_area``) cannot hold: a one-line :class:`ParameterError`.
    """
    if "lot_area" not in blocks:
        return None
    own = np.asarray(blocks["lot_area"], np.float64)[sel]
    small = own[(own > 0) & (own < min_area)]
    if len(small):
        raise ParameterError(f"the blocks' lot_area {small.min():g} m2 is below {name}={min_area:g} m2", where=where)
    return np.where(own > 0, own, 0.0)


def _max_area(blocks: Layer, sel, max_area: float, min_area: float, where) -> np.ndarray | float:
    """The largest lot of each block ``sel``: its ``lot_area`` column (blocks.grain) where positive, else ``max_area``."""
    own = _lot_area(blocks, sel, min_area, where)
    return max_area if own is None else np.where(own > 0, own, max_area)


def _skeleton_sizes(lot_area: np.ndarray | None, p: dict) -> dict:
    """Skeleton parameters ``p`` with each block's ``lot_area`` (m2, blocks.grain) where positive, per block.

    The block's lot area is its ``lot_area_max``, and its lots are as wide
    as that area at the node's ``depth`` (``lot_area / depth``, m, at least
    ``lot_width_min``): a 250 m2 row plot 22 m deep is 11.4 m wide, an
    800 m2 house plot 36 m.  Blocks without one (0) keep the node's
    ``width`` and ``lot_area_max``; without any, ``p`` is returned as it is.
    """
    if lot_area is None or not (lot_area > 0).any():
        return p
    own = lot_area > 0
    width = np.maximum(lot_area / max(p["depth"], 1e-9), p["lot_width_min"])
    return {
        **p,
        "lot_area_max": np.where(own, lot_area, p["lot_area_max"]),
        "width": np.where(own, width, p["width"]),
    }


def _paris_segment(blocks: Layer, sel, segment: float, depth: float, min_area: float, where) -> np.ndarray | float:
    """The lot frontage of each block ``sel`` for Paris lots: its ``lot_area`` (blocks.grain) / ``depth``
    where positive (m, at least the parameter's 1 m), else ``segment``."""
    own = _lot_area(blocks, sel, min_area, where)
    if own is None or not (own > 0).any():
        return segment
    return np.where(own > 0, np.maximum(own / max(depth, 1e-9), _P_PARIS["segment"].min), segment)


def _streets_of(blocks: Layer) -> dict:
    """Which of the blocks' sides face a street: ``fronts`` (their ``street_front``) and the extract's ``box``."""
    return {"fronts": blocks.get("street_front"), "box": blocks.meta.get("bbox")}


@register
class LotsManhattan(_Lots):
    """Manhattan lots: two rows along the block's main axis, ``count`` or ``width`` per side (§5.5)."""

    name = "lots.manhattan"
    params = dict(_P_MANHATTAN)

    def split(self, blocks, report):
        return _manhattan(self, blocks.geometry, report, **_streets_of(blocks), **dict(self.p))


@register
class LotsRecursive(_Lots):
    """Recursive lots (Parish and Müller): split across the longest edge until under max_area (§5.5)."""

    name = "lots.recursive"
    params = dict(_P_RECURSIVE)

    def split(self, blocks, report):
        p = dict(self.p)
        p["max_area"] = _max_area(blocks, slice(None), p["max_area"], p["min_area"], self.where)
        return _recursive(self, blocks.geometry, blocks.ids, report, **_streets_of(blocks), **p)


@register
class LotsParis(_Lots):
    """Paris lots: contour segments displaced inwards by a random depth, core courtyard (§5.5, Fig. 9)."""

    name = "lots.paris"
    params = dict(_P_PARIS)

    def split(self, blocks, report):
        p = dict(self.p)
        p["segment"] = _paris_segment(blocks, slice(None), p["segment"], p["depth"], p["min_area"], self.where)
        return _paris(self, blocks.geometry, blocks.ids, report, **_streets_of(blocks), **p)


@register
class LotsSkeleton(_Lots):
    """Skeleton lots (Vanegas et al. 2012): street strips of a depth cut into lots, corner lots, an interior."""

    name = "lots.skeleton"
    params = dict(_P_SKELETON)

    def split(self, blocks, report):
        p = dict(self.p)
        own = _lot_area(blocks, slice(None), p["lot_area_min"], self.where, "lot_area_min")
        return _skeleton(self, blocks.geometry, blocks.ids, report, **_streets_of(blocks), lot_area=own, **p)


# district rule attribute -> node parameter
_RULE_ATTRS = {
    "lot-count": "count",
    "lot-width": "width",
    "lot-min-depth": "min_depth",
    "lot-area": "max_area",
    "lot-min-area": "min_area",
    "lot-row-depth": "row_depth",
    "lot-aspect": "max_aspect",
    "lot-inner": "inner_lots",
    "lot-frontage": "min_frontage",
    "lot-jitter": "jitter",
    "lot-segment": "segment",
    "lot-depth": "depth",
    "lot-deviation": "deviation",
    "lot-width-min": "lot_width_min",
    "lot-area-min": "lot_area_min",
    "lot-area-max": "lot_area_max",
    "lot-irregularity": "irregularity",
    "lot-corner": "corner",
    "lot-interior": "interior",
    "lot-street-access": "force_street_access",
}
# skeleton parameters a district takes from the district node (width: the rule's lot-width, else 15 m)
_SKELETON_SHARED = ("depth", "lot_width_min", "lot_area_min", "lot_area_max", "irregularity", "corner", "interior")


@register
class LotsDistrict(_Lots):
    """Per-district lots: the method and sizes from each district rule (``lots``, ``lot-width`` ...)."""

    name = "lots.district"
    inputs = {
        **_Lots.inputs,
        "district_rules": Port("rules", "the <district> rules: each district's lot method and sizes", required=False),
    }
    params = {
        "default": Param("str", "manhattan", choices=_METHODS, doc="method for blocks of no or unset district"),
        **_P_MANHATTAN,
        **_P_RECURSIVE,
        "segment": _P_PARIS["segment"],
        "depth": _P_PARIS["depth"],
        "deviation": _P_PARIS["deviation"],
        **{k: _P_SKELETON[k] for k in _SKELETON_SHARED if k != "depth"},
        "force_street_access": _P_SKELETON["force_street_access"],
    }

    def _rule_params(self, rules: list, district: int) -> tuple[str, dict, str]:
        values = dict(self.p)
        values["skeleton_width"] = _P_SKELETON["width"].default
        method = self.p.default
        where = self.where
        if 0 <= district < len(rules):
            rule = rules[district]
            method = rule.get("lots", method) or method
            if method not in _METHODS:
                raise ParameterError(
                    f"district rule lots={method!r} is not one of {', '.join(_METHODS)}", where=rule.where or self.where
                )
            for attr, pname in _RULE_ATTRS.items():
                if rule.get(attr) is not None:
                    values[pname] = self.params[pname].coerce(rule.get(attr), rule.where or self.where, attr)
            if rule.get("lot-width") is not None:
                values["skeleton_width"] = values["width"]
            where = rule.where or self.where
        return method, values, where

    def run(self, *, blocks: Layer, district_rules: Layer | None = None) -> NodeResult:
        return super().run(blocks=blocks, district_rules=district_rules)

    def split(self, blocks, report, district_rules=None):
        rules = rules_of(district_rules)
        geoms = blocks.geometry
        district = (
            np.asarray(blocks["district"], np.int64) if "district" in blocks else np.full(len(blocks), -1, np.int64)
        )
        outs, sels = [], []
        box = blocks.meta.get("bbox")
        for dist in np.unique(district):
            sel = np.flatnonzero(district == dist)
            method, v, where = self._rule_params(rules, int(dist))
            fronts = None if blocks.get("street_front") is None else blocks["street_front"][sel]
            if method == "manhattan":
                res = _manhattan(
                    self,
                    geoms[sel],
                    report,
                    count=v["count"],
                    width=v["width"],
                    min_depth=v["min_depth"],
                    row_depth=v["row_depth"],
                    min_area=v["min_area"],
                    fronts=fronts,
                    box=box,
                )
            elif method == "recursive":
                res = _recursive(
                    self,
                    geoms[sel],
                    blocks.ids[sel],
                    report,
                    max_area=_max_area(blocks, sel, v["max_area"], v["min_area"], where),
                    min_area=v["min_area"],
                    min_frontage=v["min_frontage"],
                    row_depth=v["row_depth"],
                    max_aspect=v["max_aspect"],
                    jitter=v["jitter"],
                    inner_lots=v["inner_lots"],
                    fronts=fronts,
                    box=box,
                )
            elif method == "skeleton":
                res = _skeleton(
                    self,
                    geoms[sel],
                    blocks.ids[sel],
                    report,
                    where=where,
                    lot_area=_lot_area(blocks, sel, v["lot_area_min"], where, "lot_area_min"),
                    width=v["skeleton_width"],
                    force_street_access=v["force_street_access"],
                    fronts=fronts,
                    box=box,
                    **{k: v[k] for k in _SKELETON_SHARED},
                )
            else:
                res = _paris(
                    self,
                    geoms[sel],
                    blocks.ids[sel],
                    report,
                    segment=_paris_segment(blocks, sel, v["segment"], v["depth"], v["min_area"], where),
                    depth=v["depth"],
                    deviation=v["deviation"],
                    min_frontage=min(v["min_frontage"], 2.0),
                    min_area=v["min_area"],
                    fronts=fronts,
                    box=box,
                )
            outs.append(res)
            sels.append(sel)
            report[f"blocks_{method}"] = report.get(f"blocks_{method}", 0) + len(sel)
        flags = _SegmentFlags(outs[0].lots, outs[0].on, outs[0].known)
        for r in outs[1:]:
            flags = flags.join(_SegmentFlags(r.lots, r.on, r.known))
        owner = np.concatenate([sel[r.owner] for sel, r in zip(sels, outs)])
        o = np.argsort(owner, kind="stable")
        flags = flags.take(o)
        return LotSplit(
            np.concatenate([r.lots for r in outs])[o],
            owner[o],
            np.concatenate([r.method for r in outs]).astype(str)[o],
            np.concatenate([r.inner for r in outs])[o],
            flags.on,
            flags.known,
            np.concatenate([r.park for r in outs])[o],
        )


declare_rule(
    "district",
    {
        "lots": Param("str", "manhattan", choices=_METHODS, doc="lot method for lots.district"),
        **{attr: LotsDistrict.params[name] for attr, name in _RULE_ATTRS.items()},
    },
)

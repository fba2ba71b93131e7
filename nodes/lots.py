"""Lots: partitions of a block into parcels (skylineEngine §5.5, Fig. 9).

Three methods, as in the paper:

* **Manhattan** (§5.5, Fig. 9 right; a simplification of Aliaga et al. [1]):
  the block is split lengthwise along the main axis of its oriented bounding
  box into two halves, and each half into ``count`` lots (or lots about
  ``width`` m wide).  All blocks are cut in one vectorized call: each
  (block, strip box) pair is mapped onto the unit square and clipped there
  (:func:`sengine.geometry.clip_frame_boxes`).
* **Paris** (§5.5, Fig. 9 left): the contour is split into equal segments;
  at each segment end the inner normal is computed; each segment is split
  into three rectilinear sub-segments whose ends are displaced inwards along
  their inner normals by a random depth (mean ``depth``, deviation
  ``deviation``).  Lots are the regions between the contour segments and the
  displaced inner line; the remaining core is an inner lot (courtyard).
* **Recursive** (Parish and Müller [13]): split across the longest edge near
  its middle (with jitter) until lots are under ``max_area``; splits that
  would leave a piece without street frontage are rejected.  Vectorized level
  by level over all pieces of all blocks.

Every block edge faces a street (blocks are faces of the street graph), so a
lot's *frontage* is the length of its boundary lying on its block's boundary.

References
----------
skylineEngine §5.5.  [1] Aliaga, Vanegas, Beneš, "Interactive example-based
urban layout synthesis", 2008.  [13] Parish, Müller, "Procedural modeling of
cities", SIGGRAPH 2001.
"""

from __future__ import annotations

import logging

import numpy as np
import shapely

from sengine import Layer, Param, Port, SENode, register
from sengine.errors import ParameterError
from sengine.geometry import boundary_segments, clip_frame_boxes, obb_frame, segments_on, split_by_line

__all__ = ["lot_attributes", "frontage", "manhattan_lots", "recursive_lots", "paris_lots",
           "LotsManhattan", "LotsParis", "LotsRecursive", "LotsDistrict"]

log = logging.getLogger(__name__)

ON_TOL = 1e-5  # m: a segment within this of the block boundary lies on it


# -- frontage and lot attributes ---------------------------------------------------

def frontage(geoms, owner, ref_boundary) -> np.ndarray:
    """Length (m) of each geometry's boundary lying on its owner's boundary.

    Parameters
    ----------
    geoms : array_like of shapely.Polygon (k,)
    owner : array_like of int (k,)
        Index into ``ref_boundary`` for each geometry.
    ref_boundary : array_like of shapely.Geometry
        Boundaries of the owners (``shapely.boundary(blocks)``).
    """
    geoms = np.asarray(geoms, dtype=object)
    if len(geoms) == 0:
        return np.zeros(0)
    p0, p1, idx, _ = boundary_segments(geoms)
    if len(idx) == 0:
        return np.zeros(len(geoms))
    on = segments_on(p0, p1, np.asarray(ref_boundary, dtype=object)[np.asarray(owner)[idx]], tol=ON_TOL)
    ln = np.hypot(*(p1 - p0).T)
    return np.bincount(idx[on], weights=ln[on], minlength=len(geoms))


def lot_attributes(lots, owner, blocks, *, corner_angle: float = 30.0, edge_angle: float = 15.0) -> dict:
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
    out = {"frontage": np.zeros(k), "street_edges": np.zeros(k, np.int64), "corner": np.zeros(k, bool),
           "front_angle": np.full(k, np.nan)}
    if k == 0:
        return out
    bnd = shapely.boundary(np.asarray(blocks, dtype=object))
    p0, p1, idx, ring = boundary_segments(lots)
    if len(idx) == 0:
        return out
    on = segments_on(p0, p1, bnd[np.asarray(owner)[idx]], tol=ON_TOL)
    d = p1 - p0
    ln = np.hypot(d[:, 0], d[:, 1])
    on &= ln > 1e-9
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
    out["street_edges"] = np.where(allon & (out["street_edges"] == 0) & (out["frontage"] > 0), 1,
                                   out["street_edges"])
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


def _explode(geoms, owner):
    """Polygon parts of ``geoms`` (non-empty), with their owners."""
    parts, pi = shapely.get_parts(np.asarray(geoms, dtype=object), return_index=True)
    keep = (shapely.get_type_id(parts) == 3) & ~shapely.is_empty(parts)
    keep &= shapely.area(parts) > 0
    return parts[keep], np.asarray(owner)[pi[keep]]


def _hash01(seed: np.ndarray, key: np.ndarray) -> np.ndarray:
    """Uniform [0, 1) numbers from (seed, key) uint64 pairs (splitmix64)."""
    with np.errstate(over="ignore"):
        z = np.asarray(seed, np.uint64) ^ (np.asarray(key, np.uint64) * np.uint64(0x9E3779B97F4A7C15))
        z = z + np.uint64(0x9E3779B97F4A7C15)
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        z = z ^ (z >> np.uint64(31))
    return (z >> np.uint64(11)).astype(np.float64) / float(1 << 53)


# -- Manhattan -----------------------------------------------------------------------

def manhattan_lots(blocks, *, count=0, width=65.0, min_depth=10.0):
    """Manhattan lots: two rows along the block's main axis (§5.5, Fig. 9 right).

    Parameters
    ----------
    blocks : array_like of shapely.Polygon (n,)
    count : int or array_like of int
        Lots per side; ``0`` derives it from ``width``.
    width : float or array_like of float
        Target lot width along the main axis (m), used when ``count`` is 0.
        The default 65 m gives 4 lots per side of a 270 m long block, i.e.
        about 8 lots per 80 m x 270 m block as in the paper's Manhattan run
        (931 blocks -> 7,471 lots); lots are then ~65 m x ~40 m.
    min_depth : float or array_like of float
        A block narrower than ``2 * min_depth`` (m) gets a single row.

    Returns
    -------
    lots : ndarray of shapely.Polygon
    owner : ndarray of int64
        Index into ``blocks`` of each lot's block.
    """
    blocks = np.asarray(blocks, dtype=object).ravel()
    n = len(blocks)
    if n == 0:
        return np.empty(0, object), np.empty(0, np.int64)
    center, axis, L, W = obb_frame(blocks)
    count = np.broadcast_to(np.asarray(count, np.int64), (n,))
    width = np.broadcast_to(np.asarray(width, np.float64), (n,))
    min_depth = np.broadcast_to(np.asarray(min_depth, np.float64), (n,))
    per = np.where(count > 0, count, np.maximum(1, np.floor(L / np.maximum(width, 1e-9) + 0.5))).astype(np.int64)
    rows = np.where(W >= 2 * min_depth, 2, 1)
    nbox = per * rows
    own = np.repeat(np.arange(n), nbox)
    start = np.repeat(np.cumsum(nbox) - nbox, nbox)
    j = np.arange(len(own)) - start
    col = j % per[own]
    row = j // per[own]
    margin = 1.0 + 0.01 * (L + W)
    Lo, Wo, Po, Mo = L[own], W[own], per[own], margin[own]
    a0 = -Lo / 2 + col * Lo / Po
    a1 = -Lo / 2 + (col + 1) * Lo / Po
    a0 = np.where(col == 0, a0 - Mo, a0)
    a1 = np.where(col == Po - 1, a1 + Mo, a1)
    two = rows[own] == 2
    b0 = np.where(two & (row == 1), 0.0, -Wo / 2 - Mo)
    b1 = np.where(two & (row == 0), 0.0, Wo / 2 + Mo)
    pieces = clip_frame_boxes(blocks[own], center[own], axis[own], a0, a1, b0, b1)
    return _explode(pieces, own)


# -- recursive (Parish and Müller) --------------------------------------------------------

def recursive_lots(blocks, *, max_area=800.0, min_frontage=4.0, jitter=0.25, seeds=None, max_levels=24):
    """Recursive lots after Parish and Müller [13], keeping street access.

    Each piece larger than ``max_area`` is cut perpendicular to its longest
    edge, at the middle of its extent along that edge moved by up to
    ``jitter`` of the extent.  If a part of the cut would have less than
    ``min_frontage`` of block boundary, the cut perpendicular to the
    piece's longest street-facing edge is tried, then the one perpendicular
    to the main axis of its oriented bounding box, then the street-facing
    one again at the exact middle; if all fail the piece
    stays whole (it may then be larger than ``max_area``).

    Parameters
    ----------
    blocks : array_like of shapely.Polygon (n,)
    max_area : float or array_like
        Stop splitting under this area (m2).
    min_frontage : float or array_like
        Street frontage every part must keep (m).
    jitter : float
        Cut position spread, as a fraction of the extent (0 = exact middle).
    seeds : array_like of uint64 (n,), optional
        One seed per block (from the block's generator); 0 when omitted.
    max_levels : int
        Recursion depth cap.

    Returns
    -------
    lots, owner : as :func:`manhattan_lots`.
    """
    blocks = np.asarray(blocks, dtype=object).ravel()
    n = len(blocks)
    if n == 0:
        return np.empty(0, object), np.empty(0, np.int64)
    seeds = np.zeros(n, np.uint64) if seeds is None else np.asarray(seeds, np.uint64)
    max_area = np.broadcast_to(np.asarray(max_area, np.float64), (n,))
    min_frontage = np.broadcast_to(np.asarray(min_frontage, np.float64), (n,))
    bnd = shapely.boundary(blocks)
    pieces, own = _explode(blocks, np.arange(n))
    key = np.ones(len(pieces), np.uint64)
    done_g, done_o = [], []
    for _level in range(max_levels):
        todo = shapely.area(pieces) > max_area[own]
        done_g.append(pieces[~todo])
        done_o.append(own[~todo])
        pieces, own, key = pieces[todo], own[todo], key[todo]
        if len(pieces) == 0:
            break
        k = len(pieces)
        # attempt 1: across the longest edge; attempt 2: across the OBB main axis
        p0, p1, idx, _ = boundary_segments(pieces)
        ln = np.hypot(*(p1 - p0).T)
        o = np.lexsort((ln, idx))
        best = o[np.r_[idx[o][1:] != idx[o][:-1], True]]
        d_edge = np.zeros((k, 2))
        d_edge[idx[best]] = (p1[best] - p0[best]) / np.maximum(ln[best], 1e-300)[:, None]
        on = segments_on(p0, p1, bnd[own[idx]], tol=ON_TOL)
        lnf = np.where(on, ln, 0.0)
        o = np.lexsort((lnf, idx))
        bestf = o[np.r_[idx[o][1:] != idx[o][:-1], True]]
        d_front = d_edge.copy()
        d_front[idx[bestf]] = (p1[bestf] - p0[bestf]) / np.maximum(ln[bestf], 1e-300)[:, None]
        _, d_obb, _, _ = obb_frame(pieces)
        u01 = _hash01(seeds[own], key)
        accepted = np.zeros(k, bool)
        new_g, new_o, new_k = [], [], []
        for d, jit in ((d_edge, jitter), (d_front, jitter), (d_obb, jitter), (d_front, 0.0)):
            pending = np.flatnonzero(~accepted)
            if len(pending) == 0:
                break
            dd = d[pending]
            proj = np.einsum("ij,ij->i", p0, d[idx])
            lo = np.full(k, np.inf)
            hi = np.full(k, -np.inf)
            np.minimum.at(lo, idx, proj)
            np.maximum.at(hi, idx, proj)
            lo, hi = lo[pending], hi[pending]
            t = 0.5 + jit * (u01[pending] - 0.5)
            c = lo + t * (hi - lo)
            b = shapely.bounds(pieces[pending])
            ref = (b[:, :2] + b[:, 2:]) / 2.0
            pt = ref + (c - np.einsum("ij,ij->i", ref, dd))[:, None] * dd
            cut_dir = np.stack([-dd[:, 1], dd[:, 0]], axis=1)
            left, right = split_by_line(pieces[pending], pt, cut_dir)
            side = np.r_[np.zeros(len(pending), np.int64), np.ones(len(pending), np.int64)]
            parts, pidx = shapely.get_parts(np.r_[left, right], return_index=True)
            keep = (shapely.get_type_id(parts) == 3) & (shapely.area(parts) > 0)
            parts, pidx = parts[keep], pidx[keep]
            which = pending[pidx % len(pending)]
            fr = frontage(parts, own[which], bnd)
            good = np.ones(k, bool)
            np.logical_and.at(good, which, fr >= min_frontage[own[which]])
            nparts = np.bincount(which, minlength=k)
            good &= nparts >= 2
            ok_piece = np.zeros(k, bool)
            ok_piece[pending] = True
            good &= ok_piece
            sel = good[which]
            new_g.append(parts[sel])
            new_o.append(own[which[sel]])
            new_k.append(key[which[sel]] * np.uint64(2) + side[pidx[sel]].astype(np.uint64))
            accepted |= good
        stuck = ~accepted
        done_g.append(pieces[stuck])
        done_o.append(own[stuck])
        pieces = np.concatenate(new_g) if new_g else np.empty(0, object)
        own = np.concatenate(new_o) if new_o else np.empty(0, np.int64)
        key = np.concatenate(new_k) if new_k else np.empty(0, np.uint64)
    done_g.append(pieces)
    done_o.append(own)
    lots = np.concatenate(done_g)
    owner = np.concatenate(done_o).astype(np.int64)
    o = np.argsort(owner, kind="stable")
    return lots[o], owner[o]


# -- Paris ---------------------------------------------------------------------------

def _paris_one(block, *, segment, depth, deviation, rng, min_frontage):
    """Paris lots of one block: (lots, inner flags); raises on failure."""
    poly = shapely.orient_polygons(block) if hasattr(shapely, "orient_polygons") else \
        shapely.geometry.polygon.orient(block, 1.0)
    ring = shapely.LineString(poly.exterior.coords)
    perim = ring.length
    nseg = int(max(3, np.floor(perim / segment + 0.5)))
    m = 3 * nseg
    s = np.arange(m) * perim / m
    pts = shapely.get_coordinates(shapely.line_interpolate_point(ring, s))
    delta = min(0.5, perim / m / 4.0)
    pa = shapely.get_coordinates(shapely.line_interpolate_point(ring, (s - delta) % perim))
    pb = shapely.get_coordinates(shapely.line_interpolate_point(ring, (s + delta) % perim))
    tan = pb - pa
    tl = np.hypot(tan[:, 0], tan[:, 1])
    tan = tan / np.maximum(tl, 1e-12)[:, None]
    nrm = np.stack([-tan[:, 1], tan[:, 0]], axis=1)
    d = rng.normal(depth, deviation, m) if deviation > 0 else np.full(m, float(depth))
    d = np.clip(d, 0.2 * depth, 3.0 * depth)
    inner = pts + d[:, None] * nrm
    vc = np.asarray(ring.coords)[:-1]
    vs = np.r_[0.0, np.cumsum(np.hypot(*np.diff(np.asarray(ring.coords), axis=0).T))][:-1]
    cands = []
    for i in range(nseg):
        a, b = 3 * i, 3 * i + 3
        s0, s1 = s[a], (s[b] if b < m else perim)
        mid = vc[(vs > s0) & (vs < s1)]
        bi = b % m
        coords = np.vstack([pts[a:a + 1], mid, pts[bi:bi + 1], inner[bi:bi + 1], inner[a + 2:a:-1], inner[a:a + 1]])
        cands.append(shapely.Polygon(coords))
    cands = shapely.intersection(shapely.make_valid(np.asarray(cands, dtype=object)), poly)
    cands = np.asarray([shapely.union_all(shapely.get_parts(c)[shapely.get_type_id(shapely.get_parts(c)) == 3])
                        for c in cands], dtype=object)
    tree = shapely.STRtree(cands)
    pi, qi = tree.query(cands, predicate="overlaps")
    if np.any(pi != qi):
        acc = shapely.Polygon()
        res = []
        for c in cands:
            res.append(shapely.difference(c, acc))
            acc = shapely.union(acc, c)
        cands = np.asarray(res, dtype=object)
    parts, _ = _explode(cands, np.zeros(len(cands), np.int64))
    fr = frontage(parts, np.zeros(len(parts), np.int64), [shapely.boundary(poly)])
    outer = parts[fr >= min_frontage]
    core = shapely.difference(poly, shapely.union_all(outer)) if len(outer) else poly
    core_parts, _ = _explode([core], [0])
    # small core crumbs (corners, clipped bow-ties) join the lot they share most boundary with
    small = shapely.area(core_parts) < 0.5 * depth * segment
    if small.any() and len(outer):
        outer = outer.copy()
        tree = shapely.STRtree(outer)
        merged_away = []
        for crumb in core_parts[small]:
            near = tree.query(crumb, predicate="intersects")
            if len(near) == 0:
                continue
            shared = shapely.length(shapely.intersection(shapely.boundary(outer[near]), crumb.boundary))
            if shared.max() <= 0:
                continue
            j = near[np.argmax(shared)]
            merged = shapely.union(outer[j], crumb)
            if merged.geom_type == "Polygon" and abs(merged.area - outer[j].area - crumb.area) <= 1e-6 * merged.area:
                outer[j] = merged
                merged_away.append(crumb)
        core_parts = np.asarray([c for c in core_parts if not any(c is m for m in merged_away)], dtype=object)
    lots = np.r_[outer, core_parts]
    is_inner = np.r_[np.zeros(len(outer), bool), np.ones(len(core_parts), bool)]
    return lots, is_inner


def paris_lots(blocks, *, segment=20.0, depth=15.0, deviation=3.0, rngs=None, min_frontage=2.0, report=None):
    """Paris lots (§5.5, Fig. 9 left).

    Parameters
    ----------
    blocks : array_like of shapely.Polygon (n,)
    segment : float
        Length of the contour segments (m); each becomes one perimeter lot.
    depth, deviation : float
        Mean and standard deviation (m) of the inward displacement of the
        three sub-segments' ends (clipped to [0.2, 3] x depth).
    rngs : sequence of numpy.random.Generator (n,), optional
        One generator per block (``SENode.rng(block_id)``).
    min_frontage : float
        Perimeter pieces with less street frontage (m) join the core.
    report : dict, optional
        Receives ``paris_fallback`` (blocks kept whole because the method
        failed on them: very concave, thin or tiny) and ``paris_inner``.

    Returns
    -------
    lots, owner : as :func:`manhattan_lots`
    inner : ndarray of bool
        True for the core lot(s) (courtyards) that need not touch a street.
    """
    blocks = np.asarray(blocks, dtype=object).ravel()
    out_g, out_o, out_i = [], [], []
    fallback = 0
    for bi, block in enumerate(blocks):
        rng = rngs[bi] if rngs is not None else np.random.default_rng(0)
        parts = shapely.get_parts(block)
        for part in parts:
            try:
                if part.is_empty or part.area <= 0:
                    continue
                lots, inner = _paris_one(part, segment=segment, depth=depth, deviation=deviation, rng=rng,
                                         min_frontage=min_frontage)
                if abs(shapely.area(lots).sum() - part.area) > 1e-3 * part.area or not shapely.is_valid(lots).all():
                    raise ValueError("lots do not partition the block")
            except Exception as exc:  # GEOS topology errors on degenerate blocks
                log.debug("paris lots: block %d kept whole (%s)", bi, exc)
                fallback += 1
                lots, inner = np.asarray([part], dtype=object), np.zeros(1, bool)
            out_g.append(lots)
            out_o.append(np.full(len(lots), bi, np.int64))
            out_i.append(inner)
    if report is not None:
        report["paris_fallback"] = report.get("paris_fallback", 0) + fallback
        report["paris_inner"] = report.get("paris_inner", 0) + int(sum(i.sum() for i in out_i))
    if not out_g:
        return np.empty(0, object), np.empty(0, np.int64), np.empty(0, bool)
    return np.concatenate(out_g), np.concatenate(out_o), np.concatenate(out_i)


# -- nodes ---------------------------------------------------------------------------

_METHODS = ("manhattan", "paris", "recursive")


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


class _Lots(SENode):
    """Shared body of the lot nodes: attributes, partition check, layer."""

    inputs = {"blocks": Port("blocks", "blocks to divide")}
    outputs = {"lots": Port("lots", "lots; parent = block id")}
    maps_features = True
    method = ""

    def split(self, blocks: Layer, report: dict):  # -> lots, owner, method names, inner flags
        raise NotImplementedError

    def run(self, *, blocks: Layer) -> dict[str, Layer]:
        report: dict = {"blocks": len(blocks)}
        geoms = blocks.geometry
        if len(blocks) == 0:
            self.report = report
            return {"lots": Layer.from_geoms([], meta=blocks.meta, block=np.empty(0, np.int64),
                                             district=np.empty(0, np.int64), corner=np.empty(0, bool),
                                             frontage=np.empty(0), street_edges=np.empty(0, np.int64),
                                             method=np.empty(0, "<U9"), inner=np.empty(0, bool),
                                             front_angle=np.empty(0))}
        empty = shapely.is_empty(geoms) | (shapely.area(geoms) <= 0)
        report["skipped_empty"] = int(empty.sum())
        lots, owner, method, inner = self.split(blocks, report)
        ok = ~shapely.is_empty(lots) & (shapely.get_type_id(lots) == 3)
        lots, owner, method, inner = lots[ok], owner[ok], method[ok], inner[ok]
        lots, owner, keep, nwhole = _check_partition(geoms, lots, owner, report)
        method = np.r_[method[keep], np.full(nwhole, "whole")]
        inner = np.r_[inner[keep], np.zeros(nwhole, bool)]
        o = np.lexsort((np.arange(len(owner)), owner))
        lots, owner, method, inner = lots[o], owner[o], method[o], inner[o]
        att = lot_attributes(lots, owner, geoms)
        district = np.asarray(blocks["district"], np.int64)[owner] if "district" in blocks \
            else np.full(len(lots), -1, np.int64)
        report["lots"] = int(len(lots))
        report["no_frontage"] = int(((att["frontage"] <= 0) & ~inner).sum())
        self.report = report
        lay = Layer.from_geoms(lots, parent=blocks.ids[owner], meta=blocks.meta, block=blocks.ids[owner],
                               district=district, corner=att["corner"], frontage=att["frontage"],
                               street_edges=att["street_edges"], method=method.astype(str), inner=inner,
                               front_angle=att["front_angle"])
        return {"lots": lay}


def _manhattan(self, geoms, report, *, count, width, min_depth):
    lots, owner = manhattan_lots(geoms, count=count, width=width, min_depth=min_depth)
    return lots, owner, np.full(len(lots), "manhattan"), np.zeros(len(lots), bool)


def _recursive(self, geoms, ids, report, *, max_area, min_frontage, jitter):
    seeds = np.array([self.rng(int(i)).integers(0, 2**63, dtype=np.uint64) for i in ids], np.uint64)
    lots, owner = recursive_lots(geoms, max_area=max_area, min_frontage=min_frontage, jitter=jitter, seeds=seeds)
    over = int((shapely.area(lots) > max_area).sum())
    report["over_max_area"] = report.get("over_max_area", 0) + over
    return lots, owner, np.full(len(lots), "recursive"), np.zeros(len(lots), bool)


def _paris(self, geoms, ids, report, *, segment, depth, deviation, min_frontage):
    rngs = [self.rng(int(i)) for i in ids]
    lots, owner, inner = paris_lots(geoms, segment=segment, depth=depth, deviation=deviation, rngs=rngs,
                                    min_frontage=min_frontage, report=report)
    return lots, owner, np.full(len(lots), "paris"), inner


_P_MANHATTAN = {
    "count": Param("int", 0, min=0, max=1000, unit="1", doc="lots per side of the main axis; 0 = from width"),
    "width": Param("float", 65.0, min=0.5, unit="m",
                   doc="target lot width along the main axis (65 m: ~8 lots per 80 x 270 m block, as in the paper)"),
    "min_depth": Param("float", 10.0, min=0.0, unit="m", doc="blocks narrower than twice this get one row"),
}
_P_RECURSIVE = {
    "max_area": Param("float", 800.0, min=1.0, unit="m2", doc="split lots until they are under this area"),
    "min_frontage": Param("float", 4.0, min=0.0, unit="m", doc="street frontage every lot must keep"),
    "jitter": Param("float", 0.25, min=0.0, max=0.9, unit="1", doc="cut position spread, fraction of the extent"),
}
_P_PARIS = {
    "segment": Param("float", 20.0, min=1.0, unit="m", doc="contour segment length (one perimeter lot each)"),
    "depth": Param("float", 15.0, min=0.5, unit="m", doc="mean lot depth (inward displacement)"),
    "deviation": Param("float", 3.0, min=0.0, unit="m", doc="standard deviation of the lot depth"),
    "min_frontage": Param("float", 2.0, min=0.0, unit="m", doc="perimeter pieces with less frontage join the core"),
}


@register
class LotsManhattan(_Lots):
    """Manhattan lots: two rows along the block's main axis, ``count`` or ``width`` per side (§5.5)."""

    name = "lots.manhattan"
    params = dict(_P_MANHATTAN)

    def split(self, blocks, report):
        return _manhattan(self, blocks.geometry, report, count=self.p.count, width=self.p.width,
                          min_depth=self.p.min_depth)


@register
class LotsRecursive(_Lots):
    """Recursive lots (Parish and Müller): split across the longest edge until under max_area (§5.5)."""

    name = "lots.recursive"
    params = dict(_P_RECURSIVE)

    def split(self, blocks, report):
        return _recursive(self, blocks.geometry, blocks.ids, report, max_area=self.p.max_area,
                          min_frontage=self.p.min_frontage, jitter=self.p.jitter)


@register
class LotsParis(_Lots):
    """Paris lots: contour segments displaced inwards by a random depth, core courtyard (§5.5, Fig. 9)."""

    name = "lots.paris"
    params = dict(_P_PARIS)

    def split(self, blocks, report):
        return _paris(self, blocks.geometry, blocks.ids, report, segment=self.p.segment, depth=self.p.depth,
                      deviation=self.p.deviation, min_frontage=self.p.min_frontage)


# district rule attribute -> node parameter
_RULE_ATTRS = {
    "lot-count": "count", "lot-width": "width", "lot-min-depth": "min_depth",
    "lot-area": "max_area", "lot-frontage": "min_frontage", "lot-jitter": "jitter",
    "lot-segment": "segment", "lot-depth": "depth", "lot-deviation": "deviation",
}


@register
class LotsDistrict(_Lots):
    """Per-district lots: the method and sizes from each district rule (``lots``, ``lot-width`` ...)."""

    name = "lots.district"
    params = {
        "default": Param("str", "manhattan", choices=_METHODS, doc="method for blocks of no or unset district"),
        **_P_MANHATTAN, **_P_RECURSIVE,
        "segment": _P_PARIS["segment"], "depth": _P_PARIS["depth"], "deviation": _P_PARIS["deviation"],
    }

    def _rule_params(self, district: int) -> tuple[str, dict]:
        plan = self.context.plan
        rules = plan.rules_of("district") if plan is not None else []
        values = dict(self.p)
        method = self.p.default
        if 0 <= district < len(rules):
            rule = rules[district]
            method = rule.get("lots", method) or method
            if method not in _METHODS:
                raise ParameterError(f"district rule lots={method!r} is not one of {', '.join(_METHODS)}",
                                     where=rule.where or self.where)
            for attr, pname in _RULE_ATTRS.items():
                if rule.get(attr) is not None:
                    values[pname] = self.params[pname].coerce(rule.get(attr), rule.where or self.where, attr)
        return method, values

    def split(self, blocks, report):
        geoms = blocks.geometry
        district = np.asarray(blocks["district"], np.int64) if "district" in blocks \
            else np.full(len(blocks), -1, np.int64)
        out_l, out_o, out_m, out_i = [], [], [], []
        for dist in np.unique(district):
            sel = np.flatnonzero(district == dist)
            method, v = self._rule_params(int(dist))
            if method == "manhattan":
                res = _manhattan(self, geoms[sel], report, count=v["count"], width=v["width"],
                                 min_depth=v["min_depth"])
            elif method == "recursive":
                res = _recursive(self, geoms[sel], blocks.ids[sel], report, max_area=v["max_area"],
                                 min_frontage=v["min_frontage"], jitter=v["jitter"])
            else:
                res = _paris(self, geoms[sel], blocks.ids[sel], report, segment=v["segment"], depth=v["depth"],
                             deviation=v["deviation"], min_frontage=min(v["min_frontage"], 2.0))
            lots, owner, meth, inner = res
            out_l.append(lots)
            out_o.append(sel[owner])
            out_m.append(meth)
            out_i.append(inner)
            report[f"blocks_{method}"] = report.get(f"blocks_{method}", 0) + len(sel)
        return np.concatenate(out_l), np.concatenate(out_o), np.concatenate(out_m), np.concatenate(out_i)

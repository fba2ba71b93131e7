"""Recursive lots in back-to-back rows, after Parish and Müller (skylineEngine §5.5, [1]_).

Each piece larger than ``max_area``, or more elongated than ``max_aspect``,
is cut in two, level by level, until its lots are small and compact
enough.  Which cut, in order of preference:

1. **rows** -- a piece deeper than twice the target ``depth`` (the node's
   ``row_depth``), measured across its street front, is cut parallel to
   that front: at the middle when it faces streets on both sides (the two
   halves then meet back to back, as lots do in a real block), else
   ``depth`` behind its front (the part behind is an *inner* piece,
   without street);
2. **across the front** -- perpendicular to the piece's street front, near
   the middle of the front (moved by up to ``jitter``);
3. **across the long axis** -- perpendicular to the principal axis of the
   piece's area (Parish and Müller halve the long side [1]_);
4. the cut of 2 at the exact middle;
5. **shed** -- a street-facing piece still too elongated, or too deep and
   too large, is halved across its long axis, the far part becoming inner;
6. **bend** -- a piece no cut above could split, cut as in 2 (then 4 across
   the long axis) with its parts allowed to be as elongated as the piece
   really is: a curved strip's second moments spread over its bend and
   understate how thin it is (a strip 12 m wide and 370 m long along a
   curve measures about 1:9), so its halves, each straighter, measure more
   elongated than the whole and every other cut is refused.  Its true
   elongation is that of the rectangle of the same area and perimeter
   (:func:`perimeter_aspect`), and so is each part's (the lesser of its
   two measures); a ragged piece no such cut splits, not even the loose one
   below, is then cut across the diagonals of its long axis (a 6,200 m²
   block with arms 30 m wide stayed whole: every straight cut left an arm
   that measured too elongated);
7. **loose** -- in a block with edges on no street (``fronts``, ``box``),
   a piece still left is halved across its long axis, one part at least
   keeping the street (the far one may be inner, of any shape): such a
   block's pieces reach far from the street and would otherwise stay whole.

A cut is kept only if every part has at least ``min_area``, no part is
more elongated than ``max_aspect`` (or than the piece was; not checked for
row cuts, whose rows are cut again), and -- for cuts 2 to 4 of a piece that
faces a street -- every part keeps at least ``min_frontage`` of street.  A
piece no cut can split stays whole.  So lots never become stripes: a cut
that would make one is refused, and a deep piece is split into rows rather
than into ever thinner slices.  Pieces cut off the street are split only
to ``max_aspect`` (``inner="compact"``) or like the others.

The pieces of all blocks are cut together, as flat vertex arrays
(:class:`sengine.geom.ringset.RingSet`): one vectorized
:func:`sengine.geom.split.split` call per kind of cut and level, with
street frontage an exact per-edge mark carried through the cuts (block
edges are streets, cut edges are not); shapely polygons are made once, for
the final lots.

References
----------
.. [1] Y. I. H. Parish and P. Müller, "Procedural modeling of cities",
   Proceedings of the 28th Annual Conference on Computer Graphics and
   Interactive Techniques (SIGGRAPH '01), pp. 301-308, 2001.
   doi:10.1145/383259.383292
.. [2] "skylineEngine: an urban procedural modelling tool" (University of
   Girona; paper 002 of the project), §5.5 Lots.
"""

from __future__ import annotations

import numpy as np
import shapely

from sengine.errors import ParameterError
from sengine.geom.boundary import polygon_parts, street_edges
from sengine.geom.split import RingSet, cut_lengths, split
from sengine.random import hash01

__all__ = ["recursive_lots", "piece_axes", "check_recursive", "perimeter_aspect"]

PARALLEL = np.cos(np.radians(30.0))  # a street edge within 30 deg of the front runs along it
FRONT_EPS = 1e-6  # m: a piece with less marked boundary than this has no street at all
#: m2: blocks at least this large judge whether a parameter can hold for any block
#: (blocks.circuits drops faces under 50 m2 by default: smaller ones are slivers)
REAL_BLOCK = 50.0


def _normal(d: np.ndarray) -> np.ndarray:
    return np.stack([-d[:, 1], d[:, 0]], axis=1)


def _moments(rs: RingSet):
    """Area, and central second moments of area per unit area (m2), of each polygon.

    Green's theorem over the rings (holes, clockwise, subtract), in
    coordinates local to each polygon's first vertex.
    """
    n = rs.n
    vp = rs.vertex_poly()
    ref = np.zeros((n, 2))
    if len(vp):
        first = np.r_[0, np.flatnonzero(vp[1:] != vp[:-1]) + 1]
        ref[vp[first]] = rs.xy[first]
    q = rs.xy - ref[vp]
    qn = q[rs.next_vertex()]
    x0, y0, x1, y1 = q[:, 0], q[:, 1], qn[:, 0], qn[:, 1]
    cr = x0 * y1 - x1 * y0

    def total(v):
        return np.bincount(vp, weights=v * cr, minlength=n)

    area = 0.5 * np.bincount(vp, weights=cr, minlength=n)
    with np.errstate(divide="ignore", invalid="ignore"):
        a = np.where(area > 0, area, np.nan)
        cx = total(x0 + x1) / (6.0 * a)
        cy = total(y0 + y1) / (6.0 * a)
        sxx = total(x0 * x0 + x0 * x1 + x1 * x1) / (12.0 * a) - cx * cx
        syy = total(y0 * y0 + y0 * y1 + y1 * y1) / (12.0 * a) - cy * cy
        sxy = total(x0 * y1 + 2.0 * x0 * y0 + 2.0 * x1 * y1 + x1 * y0) / (24.0 * a) - cx * cy
    return area, sxx, syy, sxy


def piece_axes(rs: RingSet) -> dict:
    """Area, long axis, aspect, front axis and street length of each polygon of ``rs``.

    Returns
    -------
    dict of ndarray
        ``area`` (m2), ``long``, ``aspect``, ``front`` and ``street`` as below.
    long : ndarray (n, 2)
        Unit vector along the principal axis of the polygon's area (its
        largest second moment).
    aspect : ndarray (n,)
        Square root of the ratio of the two principal second moments: a
        rectangle's long side over its short side (``inf`` for flat or
        empty pieces).  A measure in O(vertices), unlike an oriented box.
    front : ndarray (n, 2)
        Unit vector along the piece's street front: the length-weighted mean
        direction of its marked edges (doubled angles, so opposite edges
        agree); the long axis where the piece is all street (a whole block)
        or no direction dominates.
    street : ndarray (n,)
        Length of marked edges (m).
    """
    n = rs.n
    area, sxx, syy, sxy = _moments(rs)
    half = 0.5 * (sxx - syy)
    rad = np.hypot(half, sxy)
    big, small = 0.5 * (sxx + syy) + rad, 0.5 * (sxx + syy) - rad
    with np.errstate(divide="ignore", invalid="ignore"):
        aspect = np.sqrt(big / small)
    aspect = np.where(np.isfinite(aspect) & (small > 0), aspect, np.inf)
    theta = 0.5 * np.arctan2(sxy, half)
    u = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    u[~np.isfinite(u).all(axis=1)] = (1.0, 0.0)
    vp = rs.vertex_poly()
    ln = rs.edge_lengths()
    e = rs.xy[rs.next_vertex()] - rs.xy
    w = np.where(rs.flag, ln, 0.0)
    th = 2.0 * np.arctan2(e[:, 1], e[:, 0])
    c = np.bincount(vp, weights=w * np.cos(th), minlength=n)
    s = np.bincount(vp, weights=w * np.sin(th), minlength=n)
    street = np.bincount(vp, weights=w, minlength=n)
    perimeter = np.bincount(vp, weights=ln, minlength=n)
    phi = 0.5 * np.arctan2(s, c)
    front = np.stack([np.cos(phi), np.sin(phi)], axis=1)
    weak = np.hypot(c, s) <= 0.25 * street  # e.g. street on two sides at right angles: the longest one
    if weak.any():
        best = _longest(np.where(rs.flag, ln, -1.0), vp, n)
        ok = weak & (best >= 0)
        front[ok] = e[best[ok]] / np.maximum(ln[best[ok]], 1e-300)[:, None]
    whole = (street >= perimeter - 1e-9) | (street <= FRONT_EPS)  # a whole block, or no street: the long axis
    front[whole] = u[whole]
    return {"area": area, "long": u, "aspect": aspect, "front": front, "street": street}


def perimeter_aspect(area, perimeter) -> np.ndarray:
    """Long side over short side of the rectangle with this area and perimeter (``1`` if none is so long).

    A rectangle ``L x W`` has ``P**2 / A = 4 (1 + r)**2 / r`` with ``r = L / W``;
    solved for ``r >= 1``.  Unlike second moments it does not depend on how
    a strip bends; a ragged outline overstates it.
    """
    area = np.asarray(area, np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.asarray(perimeter, np.float64) ** 2 / (4.0 * area) - 2.0  # r + 1/r
    k = np.where(np.isfinite(k) & (k > 2.0), k, 2.0)
    return 0.5 * (k + np.sqrt(k * k - 4.0))


def _take(ax: dict, sel) -> dict:
    return {k: v[sel] for k, v in ax.items()}


def _concat(axes: list[dict]) -> dict:
    if not axes:
        return {
            "area": np.zeros(0),
            "long": np.zeros((0, 2)),
            "aspect": np.zeros(0),
            "front": np.zeros((0, 2)),
            "street": np.zeros(0),
        }
    return {k: np.concatenate([a[k] for a in axes]) for k in axes[0]}


def _longest(ln: np.ndarray, vp: np.ndarray, n: int) -> np.ndarray:
    """Index of the first longest edge of each polygon (``-1`` for none or none >= 0); ``vp`` sorted."""
    best = np.full(n, -1, np.int64)
    if len(ln) == 0:
        return best
    start = np.flatnonzero(np.r_[True, vp[1:] != vp[:-1]])
    top = np.maximum.reduceat(ln, start)
    cand = np.flatnonzero(ln == np.repeat(top, np.diff(np.r_[start, len(ln)])))
    first = np.r_[True, vp[cand][1:] != vp[cand][:-1]]
    best[vp[cand[first]]] = cand[first]
    best[best >= 0] = np.where(ln[best[best >= 0]] >= 0, best[best >= 0], -1)
    return best


def _has_cut(rs: RingSet) -> np.ndarray:
    """Polygons with an unmarked edge (cut out of their block, not a whole block)."""
    return np.bincount(rs.vertex_poly(), weights=~rs.flag, minlength=rs.n) > 0


def _row_cuts(rs: RingSet, front, min_frontage, depth, max_area, max_aspect):
    """Row cuts of pieces deeper than ``2 * depth`` across their front: (applies, point, direction, deep).

    The line runs along ``front``: through the middle when street edges
    along the front lie on both sides of it (back-to-back rows), else
    ``depth`` behind the street edges of the one side that has them.  A
    piece with street on both sides is also cut in two rows when a lot of
    its whole depth could not be under ``max_area`` without being more
    elongated than ``max_aspect``.
    """
    n = rs.n
    nrm = _normal(front)
    ref, lo, hi = rs.extent_along(nrm)
    mid = 0.5 * (lo + hi)
    vp = rs.vertex_poly()
    nx = rs.next_vertex()
    e = rs.xy[nx] - rs.xy
    ln = rs.edge_lengths()
    along = rs.flag & (np.abs(np.einsum("ij,ij->i", e, front[vp])) > PARALLEL * ln)
    w = np.where(along, ln, 0.0)
    q = np.einsum("ij,ij->i", 0.5 * (rs.xy + rs.xy[nx]) - ref[vp], nrm[vp])
    up = q > mid[vp]
    f_hi = np.bincount(vp, weights=w * up, minlength=n)
    f_lo = np.bincount(vp, weights=w * ~up, minlength=n)
    with np.errstate(divide="ignore", invalid="ignore"):
        q_hi = np.bincount(vp, weights=w * up * q, minlength=n) / f_hi
        q_lo = np.bincount(vp, weights=w * ~up * q, minlength=n) / f_lo
    has_hi, has_lo = f_hi >= min_frontage, f_lo >= min_frontage
    t = np.where(has_hi & has_lo, mid, np.where(has_hi, q_hi - depth, q_lo + depth))
    t = np.clip(np.nan_to_num(t, nan=0.0), lo + 0.5 * depth, hi - 0.5 * depth)
    deep = hi - lo > 2.0 * depth
    # too deep for a lot under max_area and within max_aspect: back-to-back rows where both sides face a street
    deep_for_area = (hi - lo) ** 2 > max_area * max_aspect
    applies = (deep & (has_hi | has_lo)) | (deep_for_area & has_hi & has_lo)
    return applies, ref + t[:, None] * nrm, front, deep


def _cross_cuts(rs: RingSet, d, t01, *, street_only=False):
    """Cuts perpendicular to ``d`` at the fraction ``t01`` of each piece's extent along it.

    With ``street_only`` the extent is that of the piece's marked edges (its
    street front), so that both parts get a share of the front.
    """
    ref, lo, hi = rs.extent_along(d)
    if street_only and len(rs.xy):
        vp = rs.vertex_poly()
        q = np.einsum("ij,ij->i", rs.xy - ref[vp], d[vp])
        qn = q[rs.next_vertex()]
        start = np.r_[0, np.flatnonzero(vp[1:] != vp[:-1]) + 1]
        has = np.flatnonzero(np.bincount(vp, minlength=rs.n) > 0)
        flo = np.minimum.reduceat(np.where(rs.flag, np.minimum(q, qn), np.inf), start)
        fhi = np.maximum.reduceat(np.where(rs.flag, np.maximum(q, qn), -np.inf), start)
        front = np.isfinite(flo) & np.isfinite(fhi)
        lo[has[front]], hi[has[front]] = flo[front], fhi[front]
    return ref + (lo + t01 * (hi - lo))[:, None] * d, _normal(d)


def _try_cuts(rs, point, direction, *, fronted, min_frontage, min_area, cap, rule, bent=False):
    """Cut every piece of ``rs`` by its line and judge the parts.

    ``rule`` says what a kept cut must give: ``keep`` -- every part of a
    street-facing piece keeps ``min_frontage`` of street and none is more
    elongated than ``cap``; ``rows`` -- one part at least keeps the street
    (the others may be inner); ``shed`` -- as ``rows``, and no part more
    elongated than ``cap``.  Every part has at least ``min_area``.

    Returns the parts (RingSet) and their measures (:func:`piece_axes`),
    their piece and side, which pieces' cuts are kept, and the number of
    cuts that failed geometrically.
    """
    k = rs.n
    go = np.ones(k, bool)
    if rule == "keep":  # a cut crossing the boundary twice leaves each side's street on that side: judge it first
        nc, fl, fr = cut_lengths(rs, point, direction)
        go = ~(fronted & (nc == 2) & ((fl < min_frontage) | (fr < min_frontage)))
    idx = np.flatnonzero(go)
    pieces, parent, side, failed = split(rs.take(go), point[idx], direction[idx])
    good = ~failed & (np.bincount(parent, minlength=len(idx)) >= 2)
    ax = piece_axes(pieces)
    if len(parent):
        aspect, street = ax["aspect"], ax["street"]
        on_street = street >= min_frontage[idx][parent]
        ok = ax["area"] >= min_area[idx][parent]
        if rule == "keep":
            ok &= on_street | ~fronted[idx][parent]
        else:  # the front side keeps its street; the back may be an inner piece
            has = np.zeros(len(idx), bool)
            np.logical_or.at(has, parent, on_street)
            good &= has
        if rule != "rows":
            if bent:  # each part as elongated as it really is, like the piece (see bend in the notes)
                aspect = np.minimum(aspect, _bent_aspect(pieces))
            ok &= aspect <= cap[idx][parent]
        np.logical_and.at(good, parent, ok)
    accepted = np.zeros(k, bool)
    accepted[idx[good]] = True
    sel = good[parent]
    return pieces.take(sel), _take(ax, sel), idx[parent[sel]], side[sel], accepted, int(failed.sum())


def _bent_aspect(rs: RingSet) -> np.ndarray:
    """:func:`perimeter_aspect` of each polygon of ``rs`` (holes' edges count in its perimeter)."""
    return perimeter_aspect(rs.areas(), np.bincount(rs.vertex_poly(), weights=rs.edge_lengths(), minlength=rs.n))


def _cut_level(rs, ax, own, key, seeds, p):
    """One level: the first kept cut of each piece (rows, across the front, across the long axis, middle, shed, bend).

    Returns the parts (RingSet) and their measures, their piece and side,
    the mask of pieces no cut could split, the number of failed cuts and of
    row cuts.
    """
    k = rs.n
    u, aspect, front, street = ax["long"], ax["aspect"], ax["front"], ax["street"]
    mf = p["min_frontage"][own]
    fronted = street >= mf
    cap = np.maximum(p["max_aspect"][own], aspect * (1.0 - 1e-9))
    t01 = 0.5 + p["jitter"][own] * (hash01(seeds[own], key) - 0.5)
    ma = p["min_area"][own]
    applies, rpoint, rdir, deep = _row_cuts(rs, front, mf, p["depth"][own], p["max_area"][own], p["max_aspect"][own])
    accepted = np.zeros(k, bool)
    out_rs, out_ax, out_p, out_s = [], [], [], []
    failed_count = rows = 0
    left = np.arange(k)
    half = np.full(k, 0.5)
    # a stripe, or a piece too deep and too large, that no cut could split keeping every part on the street
    shed = fronted & ((aspect > p["max_aspect"][own]) | (deep & (ax["area"] > p["max_area"][own])))
    for kind in ("rows", "front", "long", "middle", "shed", "bend", "bend_long", "loose", "bend_45", "bend_135"):
        if kind == "rows":
            cand = left[applies[left]]
        elif kind == "shed":  # ... sheds its far end as an inner piece
            cand = left[shed[left]]
        elif kind == "loose":  # a block with open land (no street on some edges): split what is left
            cand = left[p["open"][own][left]]
        else:
            cand = left
        if len(cand) == 0:
            continue
        sub = rs.take(cand)
        if kind == "rows":
            point, direction = rpoint[cand], rdir[cand]
        elif kind in ("long", "shed", "bend_long", "loose"):
            point, direction = _cross_cuts(sub, u[cand], (t01 if kind == "long" else half)[cand])
        elif kind in ("bend_45", "bend_135"):  # a ragged piece: across the diagonals of its long axis
            a = np.radians(45.0 if kind == "bend_45" else 135.0)
            d = u[cand] @ np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
            point, direction = _cross_cuts(sub, d, half[cand])
        else:
            t = (t01 if kind == "front" else half)[cand]
            point, direction = _cross_cuts(sub, front[cand], t, street_only=True)
        pieces, pax, par, side, acc, nfail = _try_cuts(
            sub,
            point,
            direction,
            fronted=fronted[cand],
            min_frontage=mf[cand],
            min_area=ma[cand],
            cap=np.maximum(cap[cand], _bent_aspect(sub)) if kind.startswith("bend") else cap[cand],
            rule={"rows": "rows", "shed": "shed", "loose": "rows"}.get(kind, "keep"),
            bent=kind.startswith("bend"),
        )
        failed_count += nfail
        if kind == "rows":
            rows += int(acc.sum())
        out_rs.append(pieces)
        out_ax.append(pax)
        out_p.append(cand[par])
        out_s.append(side)
        accepted[cand[acc]] = True
        left = left[~accepted[left]]
        if len(left) == 0:
            break
    par = np.concatenate(out_p) if out_p else np.empty(0, np.int64)
    side = np.concatenate(out_s) if out_s else np.empty(0, np.int8)
    return RingSet.concat(out_rs), _concat(out_ax), par, side, ~accepted, failed_count, rows


def recursive_lots(
    blocks,
    *,
    max_area=800.0,
    min_area=50.0,
    min_frontage=4.0,
    depth=30.0,
    max_aspect=6.0,
    jitter=0.25,
    inner="compact",
    seeds=None,
    max_levels=40,
    report=None,
    street=False,
    fronts=None,
    box=None,
):
    """Recursive lots in back-to-back rows, keeping street access (Parish and Müller [1]_).

    See the module notes for the cuts and when they are kept.

    Parameters
    ----------
    blocks : array_like of shapely.Polygon (n,)
        MultiPolygons are cut part by part.
    max_area : float or array_like
        Pieces larger than this are split (m2).
    min_area : float or array_like
        No cut leaves a part smaller than this (m2).
    min_frontage : float or array_like
        Street frontage every part of a street-facing piece keeps (m).
    depth : float or array_like
        Target lot depth (m): a piece deeper than twice this across its
        street front is first split into rows along it.
    max_aspect : float or array_like
        No cut leaves a part whose enclosing rectangle is more elongated
        than this (long side over short side, ``1``), unless the piece
        already was; more elongated pieces are split as well.
    jitter : float
        Cut position spread, as a fraction of the extent (0 = exact middle);
        row cuts are not moved.
    inner : {"compact", "split"}
        Pieces cut off the street (behind the rows of a deep block): split
        only until no more elongated than ``max_aspect`` (``compact``: the
        inside of a large block stays one or a few inner lots), or like
        the others until under ``max_area`` (``split``).
    seeds : array_like of uint64 (n,), optional
        One seed per block (from the block's generator); 0 when omitted.
    max_levels : int
        Recursion depth cap.
    report : dict, optional
        Receives ``max_recursive_levels`` (levels run), ``recursive_rows``
        (row cuts), ``recursive_stuck`` (pieces over ``max_area`` that no
        cut could split), ``recursive_failed_cuts`` (cuts dropped because
        their crossings could not be paired exactly; another cut is tried)
        and ``recursive_inner`` (lots without street access).
    street : bool
        Also return which boundary segment of each lot lies on its block's
        boundary (exact: carried through the cuts), and the inner lots.
    fronts : array_like of object (n,), optional
        Per block, the part of its boundary that faces a street (a
        (Multi)LineString, e.g. ``blocks.landuse``'s ``street_front`` where
        open land, water or a park was cut off it), or ``None``: all of it.
        The rest of the boundary is no street: no row faces it, the cuts
        give it no frontage, and land behind the rows along the real
        street becomes inner lots (rear lots of compact shape) instead of
        thin lots fronting onto open land.
    box : tuple of float, optional
        ``(xmin, ymin, xmax, ymax)``: block boundary on this box (the
        extract's edge that closed the land round its streets) is no street.

    Returns
    -------
    lots : ndarray of shapely.Polygon
    owner : ndarray of int64
        Index into ``blocks`` of each lot's block, non-decreasing.
    on : ndarray of bool, only with ``street``
        One per boundary segment of the lots, in the order of
        :func:`sengine.geom.boundary.ring_segments`: on the block's street
        (its boundary less what ``fronts`` and ``box`` take off).
    inner : ndarray of bool, only with ``street``
        Lots cut off the street (less than ``min_frontage`` of it, and not
        a whole block).
    """
    blocks = np.asarray(blocks, dtype=object).ravel()
    n = len(blocks)
    if n == 0:
        empty = (np.empty(0, object), np.empty(0, np.int64))
        return empty + ((np.zeros(0, bool), np.zeros(0, bool)) if street else ())
    seeds = np.zeros(n, np.uint64) if seeds is None else np.asarray(seeds, np.uint64)

    def per_block(v):
        return np.broadcast_to(np.asarray(v, np.float64), (n,))

    p = {
        "max_area": per_block(max_area),
        "min_area": per_block(min_area),
        "min_frontage": np.maximum(per_block(min_frontage), FRONT_EPS),
        "depth": per_block(depth),
        "max_aspect": per_block(max_aspect),
        "jitter": per_block(jitter),
    }
    parts, own = polygon_parts(blocks, np.arange(n))
    rs = RingSet.from_polygons(parts, flag=True)  # every block edge faces a street ...
    if fronts is not None or box is not None:  # ... but those on open land or the extract's edge
        rs = RingSet(rs.xy, rs.ring, street_edges(rs, own, fronts, box), rs.poly, rs.n)
    p["open"] = np.zeros(n, bool)  # blocks with edges on no street: the 'loose' cut is theirs
    p["open"][own[rs.vertex_poly()[~rs.flag]]] = True
    key = np.ones(rs.n, np.uint64)
    done_rs, done_o = [], []
    stuck_count = failed_count = levels = rows = 0
    if inner not in ("compact", "split"):
        raise ValueError(f"inner={inner!r} is not one of compact, split")
    ax = piece_axes(rs)
    for _level in range(max_levels):
        area = ax["area"]
        big = area > p["max_area"][own]
        if inner == "compact":  # inner pieces (cut, without street) are split for their shape only
            big &= (ax["street"] >= p["min_frontage"][own]) | ~_has_cut(rs)
        todo = big | (ax["aspect"] > p["max_aspect"][own])
        todo &= area >= 2.0 * p["min_area"][own]
        done_rs.append(rs.take(~todo))
        done_o.append(own[~todo])
        stuck_count += int((~todo & big).sum())
        rs, ax, own, key, big = rs.take(todo), _take(ax, todo), own[todo], key[todo], big[todo]
        if rs.n == 0:
            break
        levels += 1
        pieces, pax, par, side, stuck, nfail, nrows = _cut_level(rs, ax, own, key, seeds, p)
        failed_count += nfail
        rows += nrows
        stuck_count += int((stuck & big).sum())
        done_rs.append(rs.take(stuck))
        done_o.append(own[stuck])
        rs, ax, own, key = pieces, pax, own[par], key[par] * np.uint64(2) + side.astype(np.uint64)
    done_rs.append(rs)
    done_o.append(own)
    done = RingSet.concat(done_rs)
    owner = np.concatenate(done_o).astype(np.int64)
    keep = np.flatnonzero(np.bincount(done.poly, minlength=done.n) > 0)  # drop empty pieces
    o = keep[np.argsort(owner[keep], kind="stable")]
    done = done.permuted(o)
    owner = owner[o]
    lots = done.polygons()
    frontage = done.flagged_length()
    off_street = (frontage < p["min_frontage"][owner]) & _has_cut(done)
    if report is not None:
        report["max_recursive_levels"] = max(report.get("max_recursive_levels", 0), levels)
        report["recursive_rows"] = report.get("recursive_rows", 0) + rows
        report["recursive_stuck"] = report.get("recursive_stuck", 0) + stuck_count
        report["recursive_failed_cuts"] = report.get("recursive_failed_cuts", 0) + failed_count
        report["recursive_inner"] = report.get("recursive_inner", 0) + int(off_street.sum())
    return (lots, owner) + ((done.flag.copy(), off_street) if street else ())


def check_recursive(blocks, *, max_area, min_area, min_frontage, where=None, report=None) -> np.ndarray:
    """Blocks the parameters cannot hold for; an error when they hold for none.

    ``min_area`` above ``max_area`` holds for no block.  A block whose whole
    boundary is shorter than ``min_frontage`` cannot hold one lot with that
    frontage: it is kept as one lot and counted (``blocks_below_min_frontage``
    in ``report``); when that is so of every block of at least
    :data:`REAL_BLOCK` m2 (there being one), the parameter is wrong and a
    :class:`sengine.errors.ParameterError` naming it is raised.

    Returns
    -------
    ndarray of bool
        The blocks below ``min_frontage``.
    """
    if min_area > np.min(max_area, initial=np.inf):
        raise ParameterError(f"min_area={min_area:g} m2 is above max_area={np.min(max_area):g} m2", where=where)
    blocks = np.asarray(blocks, dtype=object)
    area = shapely.area(blocks)
    live = ~shapely.is_empty(blocks) & (area > 0)
    perimeter = shapely.length(blocks)
    short = live & (perimeter < min_frontage)
    real = live & (area >= REAL_BLOCK)  # slivers alone do not make a parameter wrong
    if real.any() and short[real].all():
        raise ParameterError(
            f"min_frontage={min_frontage:g} m is more than the whole boundary of every block "
            f"(the longest is {perimeter[live].max():.1f} m)",
            where=where,
        )
    if report is not None:
        report["blocks_below_min_frontage"] = report.get("blocks_below_min_frontage", 0) + int(short.sum())
    return short

"""``Distr(density, deviation)``: point shapes scattered in regions (Ulmer et al. §2.2), with a minimum spacing.

"We introduce a new shape operation Distr(density, deviation) which places
point shapes in the current shape.  If the parameter deviation is 0 the
points are homogenously distributed, otherwise the points are Gaussian
distributed (both according to the density value)."  Here the expected
number of points in a region of area ``A`` is ``density * A`` (density in
points per m2), realised as ``floor(density * A)`` plus one with probability
its fractional part, so the count over many regions is exact in
expectation and its error is under one point per region.  With deviation
``s`` = 0 the points are uniform in the region; with ``s`` > 0 they are
normal around the region's inner point with standard deviation ``s`` m in
each axis, truncated to the region (a grove, a clump).

Points are drawn by rejection from the region's bounding box (or the
Gaussian), in a few vectorized rounds over all regions at once: every
candidate's numbers come from a counter-based hash of (seed, region id,
candidate number) (:func:`sengine.random.mix64`), so a region's points do not
depend on which other regions are drawn with it.

The minimum spacing ``r`` is a hard core: candidates closer than ``r`` to
an accepted point are rejected (:func:`near_pairs`, a grid), and among
new candidates the Matérn type II rule keeps, of every pair closer than
``r``, the one with the smaller mark; regions short of their count draw
again, so the requested count is met whenever the hard core leaves room
(random sequential packing fills about 55 % of the densest packing,
``density * r**2 <= 0.6``).

References
----------
``Distr`` and ``I`` in §2.2 of [1]_; the hard-core thinning of [2]_.

.. [1] A. Ulmer, J. Halatsch, A. Kunze, P. Müller and L. Van Gool, "Procedural design
   of urban open spaces", Proceedings of the 25th eCAADe Conference, Frankfurt am
   Main, pp. 351-358, 2007 (paper 001 in shared/papers).
.. [2] B. Matérn, "Spatial variation", Meddelanden från Statens Skogsforskningsinstitut
   49(5), 1960; 2nd edition, Lecture Notes in Statistics 36, Springer, 1986.
"""

from __future__ import annotations

import numpy as np
import shapely

from sengine.random import hash01, mix64

__all__ = ["expected_counts", "distr", "hard_core", "far_from", "near_pairs"]


def expected_counts(area: np.ndarray, density: np.ndarray, u: np.ndarray) -> np.ndarray:
    """``floor(density * area)`` plus one with probability the fraction: the count of each region."""
    lam = np.maximum(np.asarray(density, np.float64) * np.asarray(area, np.float64), 0.0)
    base = np.floor(lam)
    return (base + (np.asarray(u) < lam - base)).astype(np.int64)


def _normals(u1: np.ndarray, u2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Box-Muller: two standard normals from two uniforms in [0, 1)."""
    r = np.sqrt(-2.0 * np.log1p(-u1))
    return r * np.cos(2 * np.pi * u2), r * np.sin(2 * np.pi * u2)


#: Most candidate pairs :func:`near_pairs` compares on its grid; more (a spacing large against the points'
#: spread) go to a ``scipy.spatial.cKDTree``.
GRID_PAIRS = 1 << 21


def near_pairs(a: np.ndarray, b: np.ndarray, r: float, *, strict: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Pairs ``(i, j)`` of points ``a[i]``, ``b[j]`` within ``r`` of each other (closer than ``r`` if ``strict``).

    The points are binned on a grid of ``r`` cells and each is compared with
    the points of its own and the eight cells around it (numpy: sorted cell
    keys, ``searchsorted``); the squared distance is compared with ``r**2``.
    Without ``scipy.spatial`` (0.1 s to import) unless the grid would compare
    more than :data:`GRID_PAIRS` pairs.  Pairs come in no particular order.
    """
    a = np.asarray(a, np.float64).reshape(-1, 2)
    b = np.asarray(b, np.float64).reshape(-1, 2)
    none = np.empty(0, np.int64), np.empty(0, np.int64)
    if len(a) == 0 or len(b) == 0 or not r > 0:
        return none
    lo = np.minimum(a.min(axis=0), b.min(axis=0))
    ca = np.floor((a - lo) / r).astype(np.int64) + 1
    cb = np.floor((b - lo) / r).astype(np.int64) + 1
    ny = int(max(ca[:, 1].max(), cb[:, 1].max())) + 2
    kb = cb[:, 0] * ny + cb[:, 1]
    order = np.argsort(kb, kind="stable")
    ks = kb[order]
    ranges = []
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            k = (ca[:, 0] + dx) * ny + (ca[:, 1] + dy)
            s, e = np.searchsorted(ks, k, "left"), np.searchsorted(ks, k, "right")
            ranges.append((s, e - s))
    if sum(int(c.sum()) for _, c in ranges) > GRID_PAIRS:
        from scipy.spatial import cKDTree

        # all in C: a list per point (query_ball_point) costs minutes when the pairs run to millions
        m = cKDTree(a).sparse_distance_matrix(cKDTree(b), r, output_type="ndarray")
        if strict:
            m = m[m["v"] < r]
        return m["i"].astype(np.int64), m["j"].astype(np.int64)
    out_i, out_j = [], []
    for s, cnt in ranges:
        total = int(cnt.sum())
        if total == 0:
            continue
        i = np.repeat(np.arange(len(a)), cnt)
        j = order[np.repeat(s - (np.cumsum(cnt) - cnt), cnt) + np.arange(total)]
        d2 = (a[i, 0] - b[j, 0]) ** 2 + (a[i, 1] - b[j, 1]) ** 2
        ok = d2 < r * r if strict else d2 <= r * r
        out_i.append(i[ok])
        out_j.append(j[ok])
    if not out_i:
        return none
    return np.concatenate(out_i), np.concatenate(out_j)


def hard_core(xy: np.ndarray, r: float, mark: np.ndarray, fixed: np.ndarray | None = None) -> np.ndarray:
    """Which of ``xy`` keep: none closer than ``r`` to a ``fixed`` point, and Matérn II among themselves.

    Of two candidates within ``r``, the one with the larger ``mark``
    goes (even when the other goes too: type II).  Returns a bool mask.
    """
    n = len(xy)
    keep = np.ones(n, bool)
    if n == 0 or r <= 0:
        return keep
    if fixed is not None and len(fixed):
        keep &= far_from(xy, fixed, r)
    a, b = near_pairs(xy, xy, r)
    a, b = a[a < b], b[a < b]
    if len(a):
        loser = np.where((mark[a] > mark[b]) | ((mark[a] == mark[b]) & (a > b)), a, b)
        keep[loser] = False
    return keep


def far_from(xy: np.ndarray, fixed, r: float) -> np.ndarray:
    """Which points lie at least ``r`` from every ``fixed`` point.

    ``fixed`` is an (k, 2) array (m), or a :class:`scipy.spatial.cKDTree` of
    one built by a caller that asks many times.
    """
    keep = np.ones(len(xy), bool)
    if hasattr(fixed, "query"):  # a k-d tree
        if len(xy) and r > 0:
            d, _ = fixed.query(xy, k=1, distance_upper_bound=r)
            keep = ~(d < r)
        return keep
    if fixed is None or len(xy) == 0 or r <= 0 or len(fixed) == 0:
        return keep
    i, _ = near_pairs(xy, fixed, r, strict=True)
    keep[i] = False
    return keep


def distr(
    regions,
    ids,
    density,
    deviation=0.0,
    *,
    seed: int = 0,
    spacing: float = 0.0,
    fixed: np.ndarray | None = None,
    accept=None,
    rounds: int = 12,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``Distr(density, deviation)`` over many regions at once.

    Parameters
    ----------
    regions : array_like of shapely.Polygon / MultiPolygon
        Where to place points (m).
    ids : array_like of int
        Stable id of each region: keys its random numbers.
    density : float or array of float
        Expected points per m2 in each region.
    deviation : float or array of float
        0: homogeneous; otherwise the standard deviation (m) of a Gaussian
        around the region's inner point.
    seed : int
        A 64-bit stream key (the node's seed mixed with its id).
    spacing : float
        Minimum distance between points, and to ``fixed`` (m).
    fixed : numpy.ndarray, shape (k, 2), optional
        Points already placed (e.g. avenue trees) that new ones keep clear of.
    accept : callable, optional
        ``accept(x, y) -> bool array``: candidates it refuses are dropped
        (not on a road, in water, in a building ...).
    rounds : int
        Most drawing rounds; a region still short after them stays short.

    Returns
    -------
    xy : numpy.ndarray, shape (m, 2)
        The points (m), grouped by region in input order.
    region : numpy.ndarray of int
        Row of each point's region.
    wanted : numpy.ndarray of int
        The count each region asked for (``expected_counts``).
    """
    regions = np.asarray(regions, dtype=object)
    ids = np.asarray(ids, np.int64)
    n = len(regions)
    empty = np.empty((0, 2)), np.empty(0, np.int64), np.zeros(n, np.int64)
    if n == 0:
        return empty
    density = np.broadcast_to(np.asarray(density, np.float64), (n,))
    deviation = np.broadcast_to(np.asarray(deviation, np.float64), (n,))
    area = shapely.area(regions)
    key = mix64(np.uint64(seed & 0xFFFFFFFFFFFFFFFF), ids.astype(np.uint64))
    wanted = expected_counts(area, density, hash01(key, np.uint64(0xFFFFFFFF)))
    bounds = shapely.bounds(regions)
    w, h = bounds[:, 2] - bounds[:, 0], bounds[:, 3] - bounds[:, 1]
    gauss = deviation > 0
    centre = shapely.get_coordinates(shapely.point_on_surface(regions))
    # acceptance estimate: the region's share of its box (uniform) or of the 3-sigma disc (Gaussian)
    rate = np.where(gauss, area / np.maximum(np.pi * (3 * deviation) ** 2, 1e-9), area / np.maximum(w * h, 1e-9))
    rate = np.clip(rate, 0.02, 1.0)
    shapely.prepare(regions)
    got = np.zeros(n, np.int64)
    drawn = np.zeros(n, np.int64)
    acc_xy, acc_reg, acc_mark = [np.empty((0, 2))], [np.empty(0, np.int64)], [np.empty(0)]
    placed = np.asarray(fixed, np.float64).reshape(-1, 2) if fixed is not None else np.empty((0, 2))
    for _ in range(max(int(rounds), 1)):
        need = wanted - got
        if not (need > 0).any():
            break
        m = np.where(need > 0, np.ceil(need / rate * 1.25).astype(np.int64) + 4, 0)
        m = np.minimum(m, 50 * wanted + 64)
        reg = np.repeat(np.arange(n), m)
        start = np.repeat(np.cumsum(m) - m, m)
        k = (np.arange(len(reg)) - start + np.repeat(drawn, m)).astype(np.uint64)
        drawn += m
        kr = key[reg]
        u1, u2, u3 = (hash01(kr, np.uint64(3) * k + np.uint64(j)) for j in range(3))
        gx, gy = _normals(u1, u2)
        x = np.where(gauss[reg], centre[reg, 0] + deviation[reg] * gx, bounds[reg, 0] + u1 * w[reg])
        y = np.where(gauss[reg], centre[reg, 1] + deviation[reg] * gy, bounds[reg, 1] + u2 * h[reg])
        ok = shapely.contains_xy(regions[reg], x, y)
        if accept is not None and ok.any():
            ok[ok] = accept(x[ok], y[ok])
        x, y, reg, u3 = x[ok], y[ok], reg[ok], u3[ok]
        xy = np.column_stack([x, y])
        keep = hard_core(xy, spacing, u3, fixed=np.concatenate(acc_xy)) & far_from(xy, placed, spacing)
        xy, reg, u3 = xy[keep], reg[keep], u3[keep]
        # each region keeps the candidates with the smallest marks, up to its need
        order = np.lexsort((u3, reg))
        xy, reg, u3 = xy[order], reg[order], u3[order]
        first = np.searchsorted(reg, np.arange(n))
        rank = np.arange(len(reg)) - first[reg]
        take = rank < need[reg]
        acc_xy.append(xy[take])
        acc_reg.append(reg[take])
        acc_mark.append(u3[take])
        got += np.bincount(reg[take], minlength=n)
        # regions that accepted almost nothing per candidate get a truer acceptance estimate
        seen = np.bincount(reg, minlength=n)
        rate = np.where(m > 0, np.clip(np.maximum(seen, 1) / np.maximum(m, 1), 0.005, 1.0), rate)
    xy = np.concatenate(acc_xy)
    reg = np.concatenate(acc_reg)
    order = np.argsort(reg, kind="stable")
    return xy[order], reg[order], wanted

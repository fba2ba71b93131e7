"""FAR-to-building (paper 000 §5.3): a building of the floor area a FAR asks for, in credible proportions.

Given a lot and its floor area ratio, the algorithm of 000 §5.3.3 builds:

1. the target floor area ``T = lot area x FAR``; under :data:`MIN_FLOOR_AREA`
   (80 m2) nothing is built;
2. a building depth from ``T``: :data:`DEPTH_MIN` (8 m) at 100 m2 up to
   :data:`DEPTH_MAX` (25 m) at 2,500 m2, linear in between (:func:`depth_for`);
3. a footprint of that depth, sited on the lot's building area;
4. floors ``ceil(T / footprint area)``;
5. a test: floor area within :data:`TOLERANCE` (5 %) of ``T`` stops; more
   floor area than that shrinks the depth by the excess (never below
   :data:`DEPTH_FLOOR`, 10 m, or 8 m for ``T <= 100`` m2) and then the
   length, and goes back to 3.

The worked example of the thesis: ``T = 1,000`` m2 on a 334 m2 footprint
gives ``ceil(2.99) = 3`` floors, 1,002 m2, within tolerance.  Every step is
vectorized over the lots still iterating; a footprint is any function of
(depth, length fraction) -> areas, so the typologies of
:mod:`.typology` all go through the same loop.

The height then follows paper 004's relation ``H = FAR x f_h / d`` (``f_h``
the floor height, ``d`` the coverage, footprint / lot area): a building of
``floors`` whole storeys on a footprint covering ``d`` of its lot reaches
``FAR = floors x d`` (:func:`far_height`).

References
----------
.. [1] J. Viinikka, "Procedural modelling as an urban planning tool",
   master's thesis, Aalto University, Espoo, 2014, §5.2.1 (levels of control) and
   §5.3 (FAR-to-building algorithm), paper 000.
.. [2] M. Zhang, J. Wu, Y. Liu, J. Zhang and G. Li, "GIS based procedural
   modeling in 3D urban design", ISPRS International Journal of
   Geo-Information 11(10):531, 2022. doi:10.3390/ijgi11100531, §3.3.2 (paper 004).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = [
    "MIN_FLOOR_AREA",
    "DEPTH_MIN",
    "DEPTH_MAX",
    "DEPTH_FLOOR",
    "TOLERANCE",
    "depth_for",
    "floors_for",
    "far_height",
    "far_to_building",
]

MIN_FLOOR_AREA = 80.0  #: m2: no building for a smaller target (000 §5.3.4)
DEPTH_MIN, DEPTH_MAX = 8.0, 25.0  #: m: building depth at and below / at and above the areas below
AREA_MIN, AREA_MAX = 100.0, 2500.0  #: m2: target floor areas the depth is interpolated between
DEPTH_FLOOR = 10.0  #: m: the depth is never reduced below this (8 m for targets of at most 100 m2)
TOLERANCE = 0.05  #: the floor area is accepted within this share of the target


def depth_for(target) -> np.ndarray:
    """Building depth (m) for a target floor area (m2): 8 m at 100 m2 to 25 m at 2,500 m2 (000 §5.3.4)."""
    return np.interp(np.asarray(target, np.float64), [AREA_MIN, AREA_MAX], [DEPTH_MIN, DEPTH_MAX])


def floors_for(target, footprint, *, max_floors=None) -> np.ndarray:
    """Floors ``ceil(target / footprint)`` (000 §5.3.3 step 5), at least 1, at most ``max_floors``."""
    target = np.asarray(target, np.float64)
    footprint = np.asarray(footprint, np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        f = np.ceil(np.where(footprint > 0, target / footprint, 1.0) - 1e-9)
    f = np.maximum(f, 1.0)
    if max_floors is not None:
        f = np.minimum(f, np.maximum(np.asarray(max_floors, np.float64), 1.0))
    return f.astype(np.int64)


def far_height(far, floor_height, coverage) -> np.ndarray:
    """Height (m) of the storeys of a building reaching ``far`` on ``coverage`` of its lot: ``FAR x f_h / d`` (004)."""
    far = np.asarray(far, np.float64)
    coverage = np.asarray(coverage, np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(coverage > 0, far * np.asarray(floor_height, np.float64) / coverage, 0.0)


def far_to_building(
    target,
    footprint: Callable[[np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]],
    *,
    depth=None,
    max_floors=None,
    first=None,
    tolerance: float = TOLERANCE,
    max_iter: int = 24,
):
    """The FAR-to-building loop of 000 §5.3.3, vectorized over lots.

    Parameters
    ----------
    target : array_like of float (n,)
        Target floor area per lot (m2); lots under :data:`MIN_FLOOR_AREA`
        get no building.
    footprint : callable
        ``footprint(rows, depth, fraction) -> (main, fixed)``: for the lots
        ``rows``, the area (m2) of the storeys that take the floors (``main``)
        and the floor area (m2) of parts of fixed height (a podium; 0 for
        none) at building depth ``depth`` (m) and ``fraction`` of the full
        length along the street.
    depth : array_like of float (n,), optional
        Initial depth (m); default :func:`depth_for` of the target.
    max_floors : array_like of int (n,), optional
        Height limit in floors (a height class, a height map); a lot at its
        limit keeps its full footprint and falls short of the target.
    first : tuple of ndarray, optional
        ``footprint(all rows, depth, 1)`` when the caller has it already.

    Returns
    -------
    dict of ndarray (n,)
        ``build`` (bool), ``depth`` (m), ``fraction`` (1), ``floors`` (int),
        ``area`` (m2 per main storey), ``floor_area`` (m2, all storeys),
        ``iterations`` (int), ``converged`` (bool: within tolerance) and
        ``short`` (bool: under the target at the height limit).
    """
    target = np.asarray(target, np.float64)
    n = len(target)
    build = target >= MIN_FLOOR_AREA
    d = depth_for(target) if depth is None else np.broadcast_to(np.asarray(depth, np.float64), (n,)).copy()
    dmin = np.where(target <= AREA_MIN, DEPTH_MIN, DEPTH_FLOOR)
    dmin = np.minimum(dmin, d)
    frac = np.ones(n)
    maxf = None if max_floors is None else np.broadcast_to(np.asarray(max_floors, np.int64), (n,))
    floors = np.zeros(n, np.int64)
    area = np.zeros(n)
    gfa = np.zeros(n)
    its = np.zeros(n, np.int64)
    done = ~build
    converged = np.zeros(n, bool)
    short = np.zeros(n, bool)
    d_prev = d.copy()
    for it in range(max_iter):
        rows = np.flatnonzero(~done)
        if len(rows) == 0:
            break
        if it == 0 and first is not None:
            main, fixed = (np.asarray(a, np.float64)[rows] for a in first)
        else:
            main, fixed = footprint(rows, d[rows], frac[rows])
        main = np.asarray(main, np.float64)
        fixed = np.asarray(fixed, np.float64)
        f = floors_for(target[rows] - fixed, main, max_floors=None if maxf is None else maxf[rows])
        g = f * main + fixed
        # a depth cut that left the area as it was (the bands of a U on a narrow lot): cut the length next
        stalled = (its[rows] > 0) & (main >= 0.995 * area[rows]) & (d[rows] < d_prev[rows])
        dmin[rows[stalled]] = d[rows[stalled]]
        floors[rows], area[rows], gfa[rows] = f, main, g
        d_prev[rows] = d[rows]
        its[rows] += 1
        t = target[rows]
        ok = np.abs(g - t) <= (tolerance + 1e-9) * t
        over = ~ok & (g > t)
        empty = main <= 0
        capped = ~ok & ~over  # short of the target at the height limit: keep it
        converged[rows[ok]] = True
        short[rows[capped & ~empty]] = True
        done[rows[ok | capped | empty]] = True
        shrink = rows[over & ~empty]
        if it == max_iter - 1:  # the last evaluation stands: floors and areas match (depth, fraction)
            break
        if len(shrink) == 0:
            continue
        scale = target[shrink] / gfa[shrink]
        deep = d[shrink] > dmin[shrink] + 1e-9
        d[shrink[deep]] = np.maximum(dmin[shrink[deep]], d[shrink[deep]] * scale[deep])
        long = shrink[~deep]
        frac[long] = frac[long] * scale[~deep]
        done[long[frac[long] < 0.05]] = True
    build &= area > 0
    floors[~build] = 0
    gfa[~build] = 0.0
    return {
        "build": build,
        "depth": d,
        "fraction": frac,
        "floors": floors,
        "area": area,
        "floor_area": gfa,
        "iterations": its,
        "converged": converged & build,
        "short": short & build,
    }

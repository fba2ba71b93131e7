"""Slow, obviously-right reference implementations the tests compare the library with.

Each was once part of :mod:`sengine.geom.polygons`; the library now uses the
vectorized :mod:`sengine.geom.split` and :mod:`sengine.geom.boundary`, and
these stay only as oracles.
"""

from __future__ import annotations

import numpy as np
import shapely

from sengine.geom.polygons import frame_boxes


def split_by_line(polys, point, direction):
    """Both sides of each polygon cut by the line through ``point`` along ``direction``.

    Parameters
    ----------
    polys : array_like of shapely.Polygon (k,)
    point, direction : array_like (k, 2)
        A point of each cut line and its direction (need not be unit).

    Returns
    -------
    left, right : ndarray of shapely.Geometry (k,)
        The parts left and right of the directed line (either may be empty
        or a MultiPolygon for concave polygons).
    """
    polys = np.asarray(polys, dtype=object).ravel()
    point = np.asarray(point, np.float64).reshape(-1, 2)
    d = np.asarray(direction, np.float64).reshape(-1, 2)
    d = d / np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-300)[:, None]
    b = shapely.bounds(polys)
    big = (
        2.0 * (np.hypot(b[:, 2] - b[:, 0], b[:, 3] - b[:, 1]) + np.hypot(point[:, 0] - b[:, 0], point[:, 1] - b[:, 1]))
        + 1.0
    )
    left = shapely.intersection(polys, frame_boxes(point, d, -big, big, 0.0, big))
    right = shapely.intersection(polys, frame_boxes(point, d, -big, big, -big, 0.0))
    return left, right


def boundary_segments(geoms):
    """Every straight boundary segment of each polygon (all rings).

    Returns
    -------
    p0, p1 : ndarray (s, 2)
        Segment ends, in ring order (exteriors as stored, then holes).
    index : ndarray of int64 (s,)
        Index of the geometry each segment belongs to.
    ring : ndarray of int64 (s,)
        Global ring number, to tell consecutive segments of one ring apart.
    """
    geoms = np.asarray(geoms, dtype=object).ravel()
    parts, pidx = shapely.get_parts(geoms, return_index=True)
    rings, ridx = shapely.get_rings(parts, return_index=True)
    c, ci = shapely.get_coordinates(rings, return_index=True)
    a = np.flatnonzero(ci[1:] == ci[:-1])
    return c[a], c[a + 1], pidx[ridx[ci[a]]].astype(np.int64), ci[a].astype(np.int64)


def segments_on(p0, p1, reference, *, tol: float = 1e-6):
    """Whether each segment lies on its reference geometry's boundary.

    A segment counts as lying on the reference when its midpoint is within
    ``tol`` (m) of it; exact for segments whose ends are on the reference
    and that do not cut a corner of it (true for pieces cut out of a
    polygon whose boundary is the reference).

    Parameters
    ----------
    p0, p1 : ndarray (s, 2)
    reference : array_like of shapely.Geometry (s,)
        For example ``shapely.boundary(parent)[index]``.
    """
    mid = shapely.points((np.asarray(p0) + np.asarray(p1)) / 2.0)
    return shapely.distance(mid, reference) <= tol

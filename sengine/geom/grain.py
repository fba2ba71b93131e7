"""Street grain: kilometres of street per square kilometre around points.

How many streets run through a neighbourhood says much of what stands
there: a compact town quarter has at least 18 km of street per km²
(UN-Habitat's first principle of sustainable neighbourhood planning [1]_),
a village street in open fields a few.  Where a map holds streets and no
buildings, this density is the evidence of a place's grain that remains.

The density at a point is the street length inside the square of side
``2 radius`` centred on it, over the land in that square that the streets
serve (within ``reach`` of one): the sea beside a harbour front, or the
land beyond the edge of the map's data, would otherwise thin the grain of
the very streets along them, and a road through open fields serves a band
of ``2 reach``, not the fields.  Street lengths are
summed on a grid of ``cell`` metres whose lines are multiples of ``cell``
(so a point's value does not depend on which other points or lines are
asked about together) and the squares are read off its summed-area table
[2]_: two cumulative sums, then four look-ups per point, whatever the
radius (and the same for the served land).  Each street is cut into pieces of at most ``cell / 2`` and a
piece counts in the cell of its midpoint, so a square's total is exact to
within half a cell along its border.

References
----------
.. [1] UN-Habitat, "A new strategy of sustainable neighbourhood planning:
   five principles", Urban Planning Discussion Note 3, United Nations Human
   Settlements Programme, Nairobi, 2014 (principle 1: at least 18 km of
   street length per km²).
.. [2] F. C. Crow, "Summed-area tables for texture mapping", Computer
   Graphics (SIGGRAPH '84) 18(3):207-212, 1984.
"""

from __future__ import annotations

import numpy as np
import shapely

__all__ = ["street_density"]


def _box_sums(table: np.ndarray, i: np.ndarray, j: np.ndarray, k: int) -> np.ndarray:
    """Sums of the grid behind summed-area ``table`` over the squares of ``2k + 1`` cells round cells (i, j)."""
    ny, nx = table.shape[0] - 1, table.shape[1] - 1
    x0, x1 = np.clip(i - k, 0, nx), np.clip(i + k + 1, 0, nx)
    y0, y1 = np.clip(j - k, 0, ny), np.clip(j + k + 1, 0, ny)
    return table[y1, x1] - table[y0, x1] - table[y1, x0] + table[y0, x0]


def _summed(grid: np.ndarray) -> np.ndarray:
    table = np.zeros((grid.shape[0] + 1, grid.shape[1] + 1))
    table[1:, 1:] = grid.cumsum(axis=0).cumsum(axis=1)
    return table


def street_density(
    lines: np.ndarray, points: np.ndarray, radius: float, *, cell: float = 50.0, reach: float = 100.0
) -> np.ndarray:
    """Street length per served land (km/km²) in the square of side ``2 radius`` round each point.

    Parameters
    ----------
    lines : numpy.ndarray of shapely geometries
        Street centre lines (m, a planar frame).
    points : numpy.ndarray, shape (n, 2)
        Where to measure (m).
    radius : float
        Half the side of the square measured (m); rounded to whole cells.
    cell : float
        Grid step (m).
    reach : float
        Land counts when a street passes within this distance (m, rounded
        to whole cells): the sea, and land beyond the data's edge, do not
        thin out the streets along them.

    Returns
    -------
    numpy.ndarray, shape (n,)
        km of street per km² of served land (m per 1,000 m²); 0 where no street is near.
    """
    points = np.asarray(points, np.float64).reshape(-1, 2)
    out = np.zeros(len(points))
    lines = np.asarray(lines, dtype=object)
    if len(points) == 0 or len(lines) == 0:
        return out
    xy, part = shapely.get_coordinates(shapely.segmentize(lines, cell / 2.0), return_index=True)
    same = part[1:] == part[:-1]
    mid = 0.5 * (xy[1:] + xy[:-1])[same]
    length = np.hypot(*(xy[1:] - xy[:-1])[same].T)
    if len(mid) == 0:
        return out
    k, kr = max(int(round(radius / cell)), 0), max(int(round(reach / cell)), 0)
    origin = np.floor(mid.min(axis=0) / cell) * cell - kr * cell
    nx, ny = (np.floor((mid.max(axis=0) - origin) / cell).astype(np.int64) + 1 + kr).tolist()
    ij = np.floor((mid - origin) / cell).astype(np.int64)
    streets = np.bincount(ij[:, 1] * nx + ij[:, 0], weights=length, minlength=nx * ny).reshape(ny, nx)
    cj, ci = np.divmod(np.arange(nx * ny), nx)
    served = (_box_sums(_summed(streets > 0), ci, cj, kr) > 0).reshape(ny, nx)
    at = np.floor((points - origin) / cell).astype(np.int64)
    total = _box_sums(_summed(streets), at[:, 0], at[:, 1], k)
    land = _box_sums(_summed(served), at[:, 0], at[:, 1], k) * cell * cell
    np.divide(np.maximum(total, 0.0) * 1000.0, land, out=out, where=land > 0)
    return out

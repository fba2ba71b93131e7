"""Manhattan lots (skylineEngine §5.5, Fig. 9 right).

A simplification of Aliaga et al. [1]: the block is split lengthwise along
the main axis of its oriented bounding box into two halves, and each half
into ``count`` lots (or lots about ``width`` m wide).  All blocks are cut in
one vectorized call: each (block, strip box) pair is mapped onto the unit
square and clipped there (:func:`sengine.geom.polygons.clip_frame_boxes`).

References
----------
skylineEngine §5.5.  [1] Aliaga, Vanegas, Beneš, "Interactive example-based
urban layout synthesis", 2008.
"""

from __future__ import annotations

import numpy as np

from sengine.geom.boundary import polygon_parts
from sengine.geom.polygons import clip_frame_boxes, obb_frame

__all__ = ["manhattan_lots"]


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
    return polygon_parts(pieces, own)

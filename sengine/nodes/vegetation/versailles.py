"""The Versailles pattern: recursive splits into sub-regions with a central avenue (Ulmer et al. §4.1).

"The region is subsequently split into sub-regions, each containing a center
avenue and left and right grass zones.  In the Versailles example, three
recursive split steps subdivide the major region into eight sub-regions ...
By passing the recursion depth to the treeAvenue pattern, avenue parameters
like street width, tree density and tree type are adjusted automatically to
the importance of the avenue."

Each step cuts every region across its long axis (its minimum oriented
bounding box) at the middle, leaving an avenue strip whose width halves at
each level (``width`` at depth 0); the ``depth`` steps give ``2**depth``
grass sub-regions and ``2**depth - 1`` avenues, each tagged with its depth so
the avenue trees' spacing and plants can follow it.

References
----------
§4.1 and Fig. 2 of [1]_.

.. [1] A. Ulmer, J. Halatsch, A. Kunze, P. Müller and L. Van Gool, "Procedural design
   of urban open spaces", Proceedings of the 25th eCAADe Conference, Frankfurt am
   Main, pp. 351-358, 2007 (paper 001 in shared/papers).
"""

from __future__ import annotations

import numpy as np
import shapely

from sengine.geom.polygons import obb_frame

__all__ = ["versailles_split"]


def versailles_split(
    regions, *, depth: int = 3, width: float = 24.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Split every region ``depth`` times across its long axis, leaving avenues.

    Parameters
    ----------
    regions : array_like of shapely.Polygon
        The major regions (m).
    depth : int
        Recursive split steps: ``2**depth`` sub-regions per region.
    width : float
        Width of the first avenue (m); each deeper one is half as wide.

    Returns
    -------
    parts : numpy.ndarray of shapely.Polygon
        The grass sub-regions.
    part_region : numpy.ndarray of int
        Row of each part's region.
    avenues : numpy.ndarray of shapely.LineString
        Centre line of each avenue, clipped to its region.
    avenue_region, avenue_depth : numpy.ndarray of int
        Row of each avenue's region and the split step that made it (0 first).
    """
    cur = np.asarray(regions, dtype=object)
    owner = np.arange(len(cur))
    lines, line_owner, line_depth = [], [], []
    for d in range(int(depth)):
        if len(cur) == 0:
            break
        centre, axis, length, _ = obb_frame(cur)
        normal = np.column_stack([-axis[:, 1], axis[:, 0]])
        reach = (length + 1.0)[:, None] * 2
        cut = shapely.linestrings(np.stack([centre - normal * reach, centre + normal * reach], axis=1))
        w = width / 2**d
        strip = shapely.buffer(cut, w / 2, cap_style="flat")  # the whole line: its ends lie outside the region
        cut = shapely.intersection(cut, cur)
        halves = shapely.difference(cur, strip)
        parts, idx = shapely.get_parts(halves, return_index=True)
        poly = (shapely.get_type_id(parts) == 3) & (shapely.area(parts) > 0)
        # keep the two largest pieces of each split (a concave region may leave crumbs)
        parts, idx = parts[poly], idx[poly]
        order = np.lexsort((-shapely.area(parts), idx))
        parts, idx = parts[order], idx[order]
        rank = np.arange(len(idx)) - np.searchsorted(idx, idx)
        keep = rank < 2
        lines.append(cut)
        line_owner.append(owner)
        line_depth.append(np.full(len(cut), d))
        cur, owner = parts[keep], owner[idx[keep]]
    cat = lambda a, dt: np.concatenate(a) if a else np.empty(0, dt)  # noqa: E731
    return cur, owner, cat(lines, object), cat(line_owner, np.int64), cat(line_depth, np.int64)

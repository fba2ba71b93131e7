"""Avenue zones: trees along the streets, on the sidewalk, split at crossings (Ulmer et al. §3.2).

"Avenue zones are straightforward created along streets.  They span over
several blocks if necessary and can be split by crossing streets."  A
block's edge is the inner edge of its sidewalk (``blocks.circuits`` shrinks
each street face by the half street and the sidewalk), so the tree line of a
block is its outline moved ``offset`` m out onto the sidewalk (a mitred
buffer).  The line turns at every street crossing: a vertex where it turns
by more than ``corner`` degrees ends one run of trees and starts the next.
On each run trees stand every ``spacing`` m, centred on the run, and none
within ``clear`` m of its ends, so the crossings and their sight lines stay
free.  Both sides of a street get their row, from the blocks on either side.
Where only the wide streets are avenues (Paris's boulevards and avenues have
their rows of planes, its narrow *rues* none), :func:`on_wide_streets` keeps
the trees whose nearest street is wide enough.

All rings are handled at once: one coordinate array, turn angles by
``numpy``, runs by cumulative arc length, and each tree placed on its
segment found by one ``searchsorted`` (``shapely.line_interpolate_point``
walks the whole ring per point: 20 times slower on Liège's long rings).

References
----------
Avenue zones, §3.2, and the Beverly Hills example (§4.2: "regions are aware of
bordering streets ... and distribute sidewalks and avenue trees accordingly")
of [1]_.

.. [1] A. Ulmer, J. Halatsch, A. Kunze, P. Müller and L. Van Gool, "Procedural design
   of urban open spaces", Proceedings of the 25th eCAADe Conference, Frankfurt am
   Main, pp. 351-358, 2007 (paper 001 in shared/papers).
"""

from __future__ import annotations

import numpy as np
import shapely

__all__ = ["tree_lines", "avenue_points", "on_wide_streets"]


def tree_lines(blocks, offset: float) -> tuple[np.ndarray, np.ndarray]:
    """The tree line of each block: its exterior moved ``offset`` m outwards; returns (rings, block row)."""
    blocks = np.asarray(blocks, dtype=object)
    if len(blocks) == 0:
        return np.empty(0, object), np.empty(0, np.int64)
    grown = shapely.buffer(blocks, offset, join_style="mitre", mitre_limit=3.0) if offset > 0 else blocks
    polys, row = shapely.get_parts(grown, return_index=True)
    keep = shapely.get_type_id(polys) == 3
    return shapely.get_exterior_ring(polys[keep]), row[keep]


NM = 1e9  # nanometres per metre: arc lengths are summed as whole nanometres


def avenue_points(
    lines, *, spacing: float = 10.0, clear: float = 6.0, corner: float = 35.0, min_run: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Trees along closed tree lines, every ``spacing`` m, split at turns over ``corner`` degrees.

    Parameters
    ----------
    lines : array_like of shapely.LinearRing / LineString
        Closed tree lines (m).
    spacing : float
        Distance between trees along a run (m).
    clear : float
        No tree within this arc length of a run's end, i.e. of a crossing (m).
    corner : float
        A turn sharper than this (degrees) is a crossing.
    min_run : float
        Runs shorter than this get no tree (m).

    Returns
    -------
    xy : numpy.ndarray, shape (m, 2)
        The trees (m).
    line : numpy.ndarray of int
        Row of each tree's line.
    heading : numpy.ndarray of float
        Direction of the line at each tree (rad, counter-clockwise from east).
    """
    lines = np.asarray(lines, dtype=object)
    out = np.empty((0, 2)), np.empty(0, np.int64), np.empty(0)
    if len(lines) == 0 or spacing <= 0:
        return out
    xy, li = shapely.get_coordinates(lines, return_index=True)
    # drop each ring's closing vertex
    last = np.r_[li[1:] != li[:-1], True]
    xy, li = xy[~last], li[~last]
    if len(xy) == 0:
        return out
    n = len(lines)
    start = np.searchsorted(li, np.arange(n))
    count = np.bincount(li, minlength=n)
    nxt = np.arange(len(xy)) + 1
    nxt[start[count > 0] + count[count > 0] - 1] = start[count > 0]  # wrap
    prv = np.empty_like(nxt)
    prv[nxt] = np.arange(len(xy))
    edge = xy[nxt] - xy
    seg = np.hypot(edge[:, 0], edge[:, 1])
    ang = np.arctan2(edge[:, 1], edge[:, 0])
    turn = np.abs((ang - ang[prv] + np.pi) % (2 * np.pi) - np.pi)
    brk = turn > np.radians(corner)
    # arc length of each vertex along its ring, and each ring's perimeter; summed in whole nanometres,
    # where sums are exact, so that a ring's arc lengths do not depend on the rings before it in the
    # batch (a sharded or chunked run places the same trees as a whole one)
    segq = np.rint(seg * NM).astype(np.int64)
    cumq = np.cumsum(segq) - segq
    arc = (cumq - cumq[start[li]]) / NM
    perim = np.bincount(li, weights=segq, minlength=n) / NM
    # a ring with no crossing is one run starting at its first vertex
    has = np.bincount(li, weights=brk, minlength=n) > 0
    brk |= ~has[li] & (np.arange(len(xy)) == start[li])
    bi = np.flatnonzero(brk)
    bring = li[bi]
    b0 = arc[bi]
    nb = np.r_[bring[1:] != bring[:-1], True]  # the last break of each ring wraps to its first
    first_of = np.searchsorted(bring, bring)
    b1 = np.where(nb, arc[bi[first_of]] + perim[bring], np.r_[b0[1:], 0.0])
    run = b1 - b0
    usable = run - 2 * clear
    k = np.where((usable >= 0) & (run >= min_run), np.floor(usable / spacing + 1e-9).astype(np.int64) + 1, 0)
    rid = np.repeat(np.arange(len(bi)), k)
    j = np.arange(len(rid)) - np.repeat(np.cumsum(k) - k, k)
    s = b0[rid] + (run[rid] - (k[rid] - 1) * spacing) / 2 + j * spacing
    ring = bring[rid]
    s = np.mod(s, perim[ring])
    # the segment each tree lies on (arc lengths increase over all rings together), then along it
    g = cumq[start[ring]] + np.rint(s * NM).astype(np.int64)
    vi = np.clip(np.searchsorted(cumq, g, side="right") - 1, start[ring], start[ring] + count[ring] - 1)
    t = np.clip((g - cumq[vi]) / np.maximum(segq[vi], 1), 0.0, 1.0)
    pts = xy[vi] + t[:, None] * edge[vi]
    return pts, ring, ang[vi]


def on_wide_streets(points, lines, width, min_width: float) -> np.ndarray:
    """Whether the street nearest each point is at least ``min_width`` m wide.

    Parameters
    ----------
    points : array_like of shapely.Point
        Street trees (m).
    lines : array_like of shapely.LineString
        Street centre lines (m).
    width : array_like of float
        Each street's width, kerb to kerb (m).
    min_width : float
        The narrowest street that is an avenue (m).

    Returns
    -------
    numpy.ndarray of bool
        One flag per point; False where there is no street at all.
    """
    points = np.asarray(points, dtype=object)
    out = np.zeros(len(points), bool)
    if not len(points) or not len(lines):
        return out
    pi, li = shapely.STRtree(np.asarray(lines, dtype=object)).query_nearest(points, all_matches=False)
    out[pi] = np.asarray(width, float)[li] >= min_width
    return out

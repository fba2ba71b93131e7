"""Generic planar-geometry helpers shared by the node library.

Nothing here knows about cities: rings, oriented boxes, insets and
half-planes, vectorized over numpy / shapely 2 arrays.  Plane graphs of
segments and their faces live in :mod:`sengine.geom.planar`.

Public API
----------
    :func:`obb_frame` -- centre, long-axis unit vector, length and width of
    the minimum-area oriented bounding box of each polygon.
    :func:`frame_boxes` -- rectangles given in an OBB frame, in world frame.
    :func:`clip_frame_boxes` -- geometries clipped to such rectangles, fast.
    :func:`inset` -- inward offset (negative mitred buffer) by per-polygon
    distances.
    :func:`buffer_local` -- ``shapely.buffer`` of long rings about a local origin (no
    snap-rounding retry).
    :func:`threaded` / :func:`strtree_query` -- element-wise shapely work
    spread over threads (GEOS runs without Python's lock).
    :func:`containing` -- the polygon each point lies in.
    :func:`shared_areas` -- the pairs of geometries that overlap, and by how much.
    :func:`largest_share` -- the polygon holding the largest part of each geometry.
    :func:`subtract_buffers` -- polygons minus the buffers of lines assigned to them.
    :func:`right_of_lines` -- the parts of a box on the right of directed lines.
"""

from __future__ import annotations

import logging
import os

import numpy as np
import shapely

__all__ = [
    "obb_frame",
    "frame_boxes",
    "clip_frame_boxes",
    "inset",
    "buffer_local",
    "threaded",
    "strtree_query",
    "containing",
    "shared_areas",
    "largest_share",
    "subtract_buffers",
    "right_of_lines",
]

log = logging.getLogger(__name__)


# -- rings, boxes, frames ------------------------------------------------------------


def obb_frame(geoms):
    """Frame of the minimum-area oriented bounding box of each geometry.

    Parameters
    ----------
    geoms : array_like of shapely.Geometry

    Returns
    -------
    center : ndarray (n, 2)
        Box centre (m).
    axis : ndarray (n, 2)
        Unit vector along the box's long side (the main axis); the short
        side runs along ``(-axis[:, 1], axis[:, 0])``.
    length, width : ndarray (n,)
        Long and short side (m); ``0`` for empty geometries.
    """
    geoms = np.asarray(geoms, dtype=object).ravel()
    n = len(geoms)
    center = np.zeros((n, 2))
    axis = np.tile([1.0, 0.0], (n, 1))
    length = np.zeros(n)
    width = np.zeros(n)
    if n == 0:
        return center, axis, length, width
    env = shapely.oriented_envelope(geoms)
    isp = shapely.get_type_id(env) == 3
    isp &= shapely.get_num_coordinates(env) == 5
    if isp.any():
        c = shapely.get_coordinates(shapely.get_exterior_ring(env[isp])).reshape(-1, 5, 2)
        e0 = c[:, 1] - c[:, 0]
        e1 = c[:, 2] - c[:, 1]
        l0 = np.hypot(e0[:, 0], e0[:, 1])
        l1 = np.hypot(e1[:, 0], e1[:, 1])
        long0 = l0 >= l1
        ax = np.where(long0[:, None], e0, e1)
        ln = np.maximum(l0, l1)
        center[isp] = c[:, :4].mean(axis=1)
        axis[isp] = ax / np.where(ln > 0, ln, 1.0)[:, None]
        length[isp] = ln
        width[isp] = np.minimum(l0, l1)
    rest = ~isp & ~shapely.is_empty(geoms)
    if rest.any():  # lines and points: the bounding box
        b = shapely.bounds(geoms[rest])
        center[rest] = (b[:, :2] + b[:, 2:]) / 2.0
        dx, dy = b[:, 2] - b[:, 0], b[:, 3] - b[:, 1]
        axis[rest] = np.where((dx >= dy)[:, None], [1.0, 0.0], [0.0, 1.0])
        length[rest] = np.maximum(dx, dy)
        width[rest] = np.minimum(dx, dy)
    return center, axis, length, width


def frame_boxes(center, axis, a0, a1, b0, b1):
    """Rectangles ``[a0, a1] x [b0, b1]`` given in local frames, as polygons.

    ``a`` runs along ``axis``, ``b`` along its left normal, both from
    ``center`` (m).  All arguments broadcast to ``(k,)`` / ``(k, 2)``.
    """
    center = np.asarray(center, np.float64).reshape(-1, 2)
    axis = np.asarray(axis, np.float64).reshape(-1, 2)
    a0, a1, b0, b1 = np.broadcast_arrays(*(np.asarray(x, np.float64) for x in (a0, a1, b0, b1)))
    nrm = np.stack([-axis[:, 1], axis[:, 0]], axis=1)
    corners = np.stack(
        [
            center + a0[:, None] * axis + b0[:, None] * nrm,
            center + a1[:, None] * axis + b0[:, None] * nrm,
            center + a1[:, None] * axis + b1[:, None] * nrm,
            center + a0[:, None] * axis + b1[:, None] * nrm,
        ],
        axis=1,
    )
    return shapely.polygons(corners)


#: :func:`inset` spreads arrays of at least this many polygons over threads.
PARALLEL_MIN = 1000


def _cpus() -> int:
    """CPUs for GEOS threads: those this process may use.

    One inside a worker process: the executor already spreads work over
    processes there, threads would oversubscribe.
    """
    import multiprocessing

    if multiprocessing.parent_process() is not None:
        return 1
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def threaded(func, *arrays, threads: int | None = None, min_size: int = PARALLEL_MIN, **kwargs):
    """``func(*arrays, **kwargs)`` for an element-wise shapely function, spread over threads.

    GEOS runs without Python's lock in the heavy shapely functions (buffer,
    overlays, tree queries), so arrays of at least ``min_size`` elements
    are cut into contiguous chunks, one per thread (default: the CPUs this
    process may use, at most 4), and the results concatenated: the same
    result as one call.
    """
    size = len(arrays[0])
    n = min(_cpus(), 4) if threads is None else int(threads)
    if n <= 1 or size < max(min_size, 2):
        return func(*arrays, **kwargs)
    from concurrent.futures import ThreadPoolExecutor

    bounds = np.linspace(0, size, n + 1).astype(np.int64)
    with ThreadPoolExecutor(n) as pool:
        parts = list(pool.map(lambda k: func(*(a[bounds[k] : bounds[k + 1]] for a in arrays), **kwargs), range(n)))
    return np.concatenate(parts, axis=-1)


def strtree_query(tree, geoms, *, threads: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``tree.query(geoms)`` (bounding boxes) with the queries spread over threads; same output."""
    geoms = np.asarray(geoms, dtype=object)
    n = min(_cpus(), 4) if threads is None else int(threads)
    if n <= 1 or len(geoms) < PARALLEL_MIN:
        return tree.query(geoms)
    from concurrent.futures import ThreadPoolExecutor

    bounds = np.linspace(0, len(geoms), n + 1).astype(np.int64)
    with ThreadPoolExecutor(n) as pool:
        parts = list(pool.map(lambda k: tree.query(geoms[bounds[k] : bounds[k + 1]]), range(n)))
    for k, part in enumerate(parts):
        part[0] += bounds[k]
    out = np.concatenate(parts, axis=1)
    return out[0], out[1]


def inset(polys, distance, *, mitre_limit: float = 3.0, threads: int | None = None, rounded=None):
    """Offset polygons inwards by ``distance`` (m, scalar or per polygon).

    A mitred negative buffer: straight sides move parallel to themselves
    and corners stay sharp (up to ``mitre_limit``).  Parts thinner than
    ``2 * distance`` vanish; the result may be empty or a MultiPolygon.
    Polygons flagged in ``rounded`` (bool per polygon) get round joins
    instead (2 segments a quarter circle): the robust choice for rings
    with zero-width spurs (:func:`sengine.geom.planar.spur_polygons`).

    GEOS buffers without holding Python's lock, so an array of at least
    :data:`PARALLEL_MIN` polygons is dealt out over ``threads`` threads
    (default: the CPUs this process may use, at most 4; one in a worker
    process); each polygon's result is the same as on one thread.  A
    polygon of at least :data:`LOCAL_MIN` coordinates is buffered about a
    local origin (:func:`buffer_local`).
    """
    polys = np.asarray(polys, dtype=object)
    dist = -np.broadcast_to(np.asarray(distance, np.float64), polys.shape)
    if rounded is not None and np.any(rounded):
        rounded = np.asarray(rounded, bool)
        out = np.empty(len(polys), dtype=object)
        out[~rounded] = inset(polys[~rounded], -dist[~rounded], mitre_limit=mitre_limit, threads=threads)
        out[rounded] = threaded(buffer_local, polys[rounded], dist[rounded], threads=threads, quad_segs=2)
        return out
    kw = {"join_style": "mitre", "mitre_limit": mitre_limit}
    n = min(_cpus(), 4) if threads is None else int(threads)
    if n <= 1 or polys.ndim != 1 or len(polys) < PARALLEL_MIN:
        return buffer_local(polys, dist, **kw)
    from concurrent.futures import ThreadPoolExecutor

    out = np.empty(len(polys), dtype=object)
    # dealt out round-robin: neighbouring polygons are alike, so every thread gets a fair share of work
    with ThreadPoolExecutor(n) as pool:
        done = pool.map(lambda k: buffer_local(polys[k::n], dist[k::n], **kw), range(n))
        for k, part in enumerate(done):
            out[k::n] = part
    return out


#: :func:`buffer_local` moves polygons of at least this many coordinates to a local origin first.
LOCAL_MIN = 10_000


def buffer_local(geoms, distance, **kwargs):
    """``shapely.buffer``, the geometries of at least :data:`LOCAL_MIN` coordinates about a local origin.

    GEOS nodes a buffer's offset curves in floating point; on a long ring
    far from the origin (projected coordinates of 10^5 to 10^6 m, rings of
    thousands of vertices with zero-width spurs, such as the land round a
    city with its dead ends) that noding can fail, and GEOS then buffers
    again with snap-rounding at falling precisions: several times the work,
    and a result moved by the snapping (2 m² on Liège's 1,446 km² land
    face).  Moved so that its bounding box starts at the origin (by whole
    metres: for a box away from the origin the subtraction is exact), the
    offset curves are computed with the bits the large coordinates spent
    on their magnitude, the first noding holds (4.5 times faster on that
    face) and the result is moved back.  Smaller geometries are buffered
    where they are, their results unchanged to the byte: moved, they come
    out different in the last bits only, which lots split from them pass
    on, and no retry was seen on them (Helsinki's and Monaco's land faces
    and street edges, 1,177 to 5,335 coordinates, buffer in 1 to 3 ms
    either way; Liège's other faces are no faster moved).  The threshold
    is a measured heuristic, not a bound: GEOS gives no sign of a retry.

    Parameters
    ----------
    geoms : array_like of shapely.Geometry
    distance : float or array_like of float
        Buffer distance (m), negative inwards.
    **kwargs
        As ``shapely.buffer`` takes them.

    Returns
    -------
    ndarray of shapely.Geometry
    """
    geoms = np.asarray(geoms, dtype=object)
    dist = np.broadcast_to(np.asarray(distance, np.float64), geoms.shape)
    big = shapely.get_num_coordinates(geoms) >= LOCAL_MIN
    if not big.any():
        return shapely.buffer(geoms, dist, **kwargs)
    out = np.empty(geoms.shape, dtype=object)
    out[~big] = shapely.buffer(geoms[~big], dist[~big], **kwargs)
    some = geoms[big]
    origin = np.floor(shapely.bounds(some)[:, :2])
    xy, at = shapely.get_coordinates(some, return_index=True)
    moved = shapely.buffer(shapely.set_coordinates(some, xy - origin[at]), dist[big], **kwargs)  # some: a copy
    xy, at = shapely.get_coordinates(moved, return_index=True)
    out[big] = shapely.set_coordinates(moved, xy + origin[at])
    return out


def clip_frame_boxes(geoms, center, axis, a0, a1, b0, b1):
    """Each geometry clipped to a rectangle given in its own frame (vectorized).

    Equivalent to ``shapely.intersection(geoms, frame_boxes(...))`` but maps
    every (geometry, rectangle) pair affinely onto the unit square and uses
    GEOS's rectangle clipper (``shapely.clip_by_rect``), several times
    faster than a general overlay.  Pieces the clipper returns invalid are
    redone with ``shapely.intersection``.

    Parameters
    ----------
    geoms : array_like of shapely.Geometry (k,)
    center, axis, a0, a1, b0, b1 : as :func:`frame_boxes` (k rows; scalars
        broadcast).  A reversed interval (``a1 < a0``) is the one between its
        ends, as in :func:`frame_boxes`; a rectangle of zero width gives an
        empty polygon.
    """
    geoms = np.asarray(geoms, dtype=object).ravel()
    k = len(geoms)
    if k == 0:
        return np.empty(0, object)
    center = np.broadcast_to(np.asarray(center, np.float64).reshape(-1, 2), (k, 2))
    axis = np.broadcast_to(np.asarray(axis, np.float64).reshape(-1, 2), (k, 2))
    a0, a1, b0, b1 = (np.broadcast_to(np.asarray(x, np.float64), (k,)) for x in (a0, a1, b0, b1))
    a0, a1 = np.minimum(a0, a1), np.maximum(a0, a1)
    b0, b1 = np.minimum(b0, b1), np.maximum(b0, b1)
    flat = (a1 == a0) | (b1 == b0)
    if flat.any():  # the unit-square map needs a width: a flat rectangle clips to nothing
        out = np.full(k, shapely.Polygon(), dtype=object)
        keep = np.flatnonzero(~flat)
        if len(keep):
            out[keep] = clip_frame_boxes(geoms[keep], center[keep], axis[keep], a0[keep], a1[keep], b0[keep], b1[keep])
        return out
    c, ci = shapely.get_coordinates(geoms, return_index=True)
    local = shapely.set_coordinates(geoms.copy(), frame_unit_coordinates(c, ci, center, axis, a0, a1, b0, b1))
    return clip_unit_local(geoms, local, center, axis, a0, a1, b0, b1)


def _frame_args(center, axis, a0, a1, b0, b1):
    center = np.asarray(center, np.float64).reshape(-1, 2)
    axis = np.asarray(axis, np.float64).reshape(-1, 2)
    a0, a1, b0, b1 = np.broadcast_arrays(*(np.asarray(x, np.float64) for x in (a0, a1, b0, b1)))
    return center, axis, a0, a1, b0, b1


def frame_unit_coordinates(c, ci, center, axis, a0, a1, b0, b1) -> np.ndarray:
    """World points ``c`` (m) of rectangle ``ci`` mapped affinely onto its unit square (as :func:`clip_frame_boxes`)."""
    nrm = np.stack([-axis[:, 1], axis[:, 0]], axis=1)
    sa = np.where(a1 > a0, a1 - a0, 1.0)
    sb = np.where(b1 > b0, b1 - b0, 1.0)
    q = c - center[ci]
    return np.stack(
        [(np.einsum("ij,ij->i", q, axis[ci]) - a0[ci]) / sa[ci], (np.einsum("ij,ij->i", q, nrm[ci]) - b0[ci]) / sb[ci]],
        axis=1,
    )


def clip_unit_local(geoms, local, center, axis, a0, a1, b0, b1) -> np.ndarray:
    """The second half of :func:`clip_frame_boxes`: geometries in their rectangles' unit squares, clipped.

    ``local`` (each geometry, or one with vertices far outside its rectangle
    left out, mapped onto its rectangle's unit square by
    :func:`frame_unit_coordinates`) is clipped to the unit square and mapped
    back to the world; pieces the clipper returns invalid are redone from
    ``geoms`` by ``shapely.intersection``.
    """
    center, axis, a0, a1, b0, b1 = _frame_args(center, axis, a0, a1, b0, b1)
    nrm = np.stack([-axis[:, 1], axis[:, 0]], axis=1)
    sa = np.where(a1 > a0, a1 - a0, 1.0)
    sb = np.where(b1 > b0, b1 - b0, 1.0)
    pieces = shapely.clip_by_rect(local, 0.0, 0.0, 1.0, 1.0)
    c2, ci2 = shapely.get_coordinates(pieces, return_index=True)
    x = a0[ci2] + c2[:, 0] * sa[ci2]
    y = b0[ci2] + c2[:, 1] * sb[ci2]
    world = center[ci2] + x[:, None] * axis[ci2] + y[:, None] * nrm[ci2]
    pieces = shapely.set_coordinates(pieces, world)
    bad = ~shapely.is_valid(pieces)
    if bad.any():
        idx = np.flatnonzero(bad)
        pieces[idx] = shapely.intersection(
            geoms[idx], frame_boxes(center[idx], axis[idx], a0[idx], a1[idx], b0[idx], b1[idx])
        )
    return pieces


def containing(points, polys) -> np.ndarray:
    """Index of the polygon each point lies in (``-1`` for none; the lowest index where several do)."""
    out = np.full(len(points), -1, np.int64)
    if len(points) == 0 or len(polys) == 0:
        return out
    pi, qi = shapely.STRtree(polys).query(points, predicate="within")
    o = np.lexsort((qi, pi))  # by point, then by polygon: a point's first hit is its lowest polygon
    pi, qi = pi[o], qi[o]
    first = np.r_[True, pi[1:] != pi[:-1]] if len(pi) else np.zeros(0, bool)
    out[pi[first]] = qi[first]
    return out


def shared_areas(geoms, others) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Intersecting pairs ``(geoms index, others index)`` and the area (m2) each pair shares."""
    geoms, others = np.asarray(geoms, dtype=object), np.asarray(others, dtype=object)
    if not len(geoms) or not len(others):
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    gi, oi = shapely.STRtree(others).query(geoms, predicate="intersects")
    return gi, oi, shapely.area(shapely.intersection(geoms[gi], others[oi])) if len(gi) else np.zeros(0)


def largest_share(geoms, polys) -> np.ndarray:
    """Index of the polygon holding the largest part of each geometry (``-1`` for none; the lowest on a tie)."""
    out = np.full(len(geoms), -1, np.int64)
    gi, pi, area = shared_areas(geoms, polys)
    o = np.lexsort((pi, -area, gi))  # per geometry, the largest share first
    gi, pi, area = gi[o], pi[o], area[o]
    first = np.r_[True, gi[1:] != gi[:-1]] if len(gi) else np.zeros(0, bool)
    first &= area > 0
    out[gi[first]] = pi[first]
    return out


def subtract_buffers(polys, lines, owner, distance, *, cap_style: str = "round", quad_segs: int = 4) -> np.ndarray:
    """Each polygon minus the ground within ``distance`` of the lines given to it.

    Parameters
    ----------
    polys : array_like of shapely.Geometry (k,)
        Polygons (m); empty ones stay empty.
    lines : array_like of shapely.LineString (n,)
        Lines (m), each subtracted from one polygon.
    owner : array_like of int (n,)
        Index into ``polys`` of each line's polygon.
    distance : float or array_like of float (n,)
        Buffer distance of each line (m); lines at 0 or less take nothing.
    cap_style : {"round", "flat", "square"}
        End caps of the buffers.
    quad_segs : int
        Segments per quarter circle of the round joins and caps.

    Returns
    -------
    ndarray of shapely.Geometry (k,)
        The differences (possibly empty or MultiPolygons); polygons no line
        is given to are returned as they are.

    Notes
    -----
    The lines of one polygon at one distance (to the mm) are merged
    (``shapely.line_merge``: one buffer of a few long lines costs much less
    than one per segment) and buffered together; a polygon's few distances
    are subtracted in rounds, one vectorized difference per round.
    """
    out = np.asarray(polys, dtype=object).copy()
    lines = np.asarray(lines, dtype=object)
    owner = np.asarray(owner, np.int64)
    dist = np.broadcast_to(np.asarray(distance, np.float64), owner.shape)
    live = dist > 0
    if not live.any():
        return out
    lines, owner, dist = lines[live], owner[live], dist[live]
    groups, group = np.unique(np.column_stack([owner, np.round(dist, 3)]), axis=0, return_inverse=True)
    group = group.ravel()
    reach = np.zeros(len(groups))
    np.maximum.at(reach, group, dist)
    o = np.argsort(group, kind="stable")
    merged = shapely.line_merge(shapely.multilinestrings(lines[o], indices=group[o]))
    cuts = threaded(shapely.buffer, merged, reach, min_size=64, quad_segs=quad_segs, cap_style=cap_style)
    gpoly = groups[:, 0].astype(np.int64)
    rank = np.arange(len(gpoly)) - np.searchsorted(gpoly, gpoly)  # groups come sorted by polygon
    for k in range(int(rank.max()) + 1):
        sel = rank == k
        out[gpoly[sel]] = threaded(shapely.difference, out[gpoly[sel]], cuts[sel], min_size=64)
    return out


def right_of_lines(lines, box) -> np.ndarray:
    """The parts of a box that lie on the right of directed lines.

    The lines and the box's boundary are noded and polygonized; each part
    votes by probes a millimetre either side of every segment of the lines
    on its boundary, and the parts most probes find on the right are
    returned (an OpenStreetMap coastline has the sea on its right).  Lines
    that end inside the box close nothing: where they do not cut it, no
    part is on their right.

    Parameters
    ----------
    lines : array_like of shapely.LineString
        Directed lines (m).
    box : (xmin, ymin, xmax, ymax)
        The box (m).

    Returns
    -------
    ndarray of shapely.Polygon
    """
    lines = np.asarray(lines, dtype=object)
    if not len(lines):
        return np.empty(0, dtype=object)
    rect = shapely.box(*box)
    noded = shapely.node(shapely.union_all(np.r_[shapely.intersection(lines, rect), [shapely.boundary(rect)]]))
    parts = shapely.get_parts(shapely.polygonize(shapely.get_parts(noded)))
    if not len(parts):
        return parts
    xy, idx = shapely.get_coordinates(lines, return_index=True)
    seg = np.flatnonzero(idx[1:] == idx[:-1])
    d = xy[seg + 1] - xy[seg]
    ln = np.hypot(*d.T)
    seg, d, ln = seg[ln > 0], d[ln > 0], ln[ln > 0]
    mid = (xy[seg] + xy[seg + 1]) / 2.0
    right = np.stack([d[:, 1], -d[:, 0]], axis=1) / ln[:, None] * 1e-3
    votes = np.zeros(len(parts))
    for side, sign in ((right, 1.0), (-right, -1.0)):
        host = containing(shapely.points(mid + side), parts)
        np.add.at(votes, host[host >= 0], sign)
    return parts[votes > 0]

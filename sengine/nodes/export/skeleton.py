"""Hip and gable roofs on any simple polygon (concave, with holes) by the straight skeleton.

The straight skeleton [1]_ shrinks a polygon by moving every edge inward at
the same speed; the roof over it rises at one pitch from every eave, so its
faces are the skeleton's faces, each lifted to its edge's distance.  CGAL's
``Straight_skeleton_2`` [2]_ (exact predicates, holes allowed) computes it,
through the compiled extension that ``compas_cgal`` ships; it is called
directly on numpy arrays so that no ``compas`` object is built.  Convex
footprints, most of a city, do not come here: their hip roof is a lower
envelope of planes (:mod:`sengine.nodes.export.envelope`).

The roofs are built in three tiers, each taking what the one before hands back:

1. :mod:`.wavefront` computes the skeletons of all one-ring footprints of up to
   48 vertices together in numpy passes, and :mod:`.skeleton_faces` turns them
   into solids in batch, checking every face (8,770 of 8,850 concave footprints
   of 30,000 Liège buildings);
2. the same batch on CGAL's interior skeleton, one call a footprint (the
   wavefront's refusals and larger footprints: about 60 of them);
3. CGAL's own extrusion of the skeleton, one footprint at a time
   (:func:`_one`, about 30 of them, 6 ms each), and every footprint with a
   hole: CGAL's interior skeleton with holes crashed the process on a
   sliver hole (a segmentation fault, which no ``try`` catches).

Before, every concave footprint took the third tier: 1.6 ms each, 14.8 s for
those 8,900.

A **gable** is the hip roof with its end triangles turned into walls: a roof
face that is a triangle over one eave, whose apex no other triangle shares,
has its apex moved onto that eave's wall plane (the ridge runs out to the
gable), as renderers of OpenStreetMap buildings do.

References
----------
.. [1] Aichholzer, O., Aurenhammer, F., Alberts, D., Gärtner, B., "A novel type
   of skeleton for polygons", Journal of Universal Computer Science 1(12),
   752-761, 1995.
.. [2] Cacciola, F., "A CGAL implementation of the straight skeleton of a simple
   2D polygon with holes", 2nd CGAL User Workshop, 2004.
"""

from __future__ import annotations

import contextlib
import os
import sys

import mapbox_earcut
import numpy as np

from .mesh import Rings, cluster_points, fill_skipped, split_t_junctions, subset_rings
from .skeleton_faces import hip_solids

__all__ = ["skeleton_solids", "available"]


@contextlib.contextmanager
def _quiet_stderr():
    """File descriptor 2 to /dev/null meanwhile: CGAL writes its warnings there, past Python's ``sys.stderr``."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):  # no real descriptor 2 (an embedding host): nothing to silence
        yield
        return
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def _extension():
    try:
        from compas_cgal import _straight_skeleton_2  # type: ignore[attr-defined]
    except ImportError:  # pragma: no cover - compas_cgal is a dependency
        return None
    return _straight_skeleton_2


def available() -> bool:
    """Whether the straight-skeleton extension can be imported."""
    return _extension() is not None


def skeleton_solids(
    rings: Rings,
    polys: np.ndarray,
    eave: np.ndarray,
    rise: np.ndarray,
    base: np.ndarray,
    gable: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Closed solids with a hip (or gable) roof over polygons ``polys`` of ``rings``.

    Parameters
    ----------
    rings : Rings
        Footprints (m).
    polys : numpy.ndarray of int
        Which polygons of ``rings`` to build.
    eave, rise, base : numpy.ndarray, shape (p,)
        Per polygon of ``rings``: wall top, roof rise and ground height (m).
    gable : numpy.ndarray of bool, shape (p,)
        Per polygon of ``rings``: turn the end triangles into gables.

    Returns
    -------
    vertices, faces, vertex_poly, face_kind
        As :func:`sengine.nodes.export.envelope.envelope_solids`.
    failed : numpy.ndarray of int
        Polygons the skeleton could not be computed for (not in the mesh).
    """
    ext = _extension()
    polys = np.asarray(polys, np.int64)
    vs, fs, vp, fk, failed = [], [], [], [], []
    off = 0
    slow = polys
    for engine in ("wavefront", "cgal"):  # the batch: our own wavefront first, CGAL for what it hands back
        if ext is None or not slow.size:
            break
        sub = subset_rings(rings, slow)
        with _quiet_stderr():
            v, f, p, k, bad = hip_solids(ext, sub, eave[slow], rise[slow], base[slow], np.asarray(gable)[slow], engine)
        vs.append(v)
        fs.append(f + off)
        vp.append(slow[p])
        fk.append(k)
        off += len(v)
        slow = slow[bad]
    with _quiet_stderr():  # CGAL prints its refusals; they are counted here (failed) and fall back
        for p in slow.tolist():  # what the batch could not build: CGAL's own extrusion, one by one
            out = None if ext is None else _one(ext, rings, p, float(eave[p]), float(rise[p]), float(base[p]), gable[p])
            if out is None:
                failed.append(p)
                continue
            v, f, k = out
            vs.append(v)
            fs.append(f + off)
            fk.append(k)
            vp.append(np.full(len(v), p, np.int64))
            off += len(v)
    if not vs:
        e = np.empty(0, np.int64)
        return np.empty((0, 3)), np.empty((0, 3), np.int64), e, np.empty(0, np.uint8), np.asarray(failed, np.int64)
    return np.concatenate(vs), np.concatenate(fs), np.concatenate(vp), np.concatenate(fk), np.asarray(failed, np.int64)


def _one(ext, rings: Rings, p: int, eave: float, rise: float, base: float, gable: bool):
    r0, r1 = int(rings.poly_ring[p]), int(rings.poly_ring[p + 1])
    v0, v1 = int(rings.ring_start[r0]), int(rings.ring_start[r1])
    xy = rings.xy[v0:v1]
    n = len(xy)
    starts = (rings.ring_start[r0 : r1 + 1] - v0).tolist()
    origin = xy[0]
    local = xy - origin
    snapped, keep = _snap(local, starts)
    contours = [
        np.ascontiguousarray(np.column_stack([snapped[a:b][keep[a:b]], np.zeros(int(keep[a:b].sum()))]))
        for a, b in zip(starts, starts[1:])
    ]
    speeds = [[1.0] * len(c) for c in contours]
    try:
        sv, sf = ext.extrude_straight_skeleton(contours[0], contours[1:], speeds, False, -1.0)
    except Exception:  # CGAL refuses degenerate input (collinear or self-touching rings)
        return None
    sv = np.asarray(sv, np.float64)
    z = sv[:, 2]
    zmax = z.max() if len(z) else 0.0
    if not zmax > 0:
        return None
    # CGAL hands the footprint's vertices back exactly: find each among the rings
    ring_index = {(float(a), float(b)): i for i, (a, b) in enumerate(snapped.tolist()) if keep[i]}
    low = z <= 0.0
    vid = np.full(len(sv), -1, np.int64)
    for i in np.flatnonzero(low).tolist():
        j = ring_index.get((float(sv[i, 0]), float(sv[i, 1])))
        if j is None:
            return None
        vid[i] = j
    # CGAL may give several skeleton nodes at one point, or a hair apart (simultaneous events): one vertex
    high = np.flatnonzero(~low)
    canon = np.arange(len(sv))
    canon[high] = high[cluster_points(sv[high], MERGE)]
    high = np.unique(canon[high])
    vid[high] = n + np.arange(len(high))
    roof = []
    for face in sf:
        f = [int(canon[v]) for v in face]
        f = [v for k, v in enumerate(f) if v != f[k - 1]]  # k = 0 compares with the last
        if len(f) >= 3 and z[f].max() > 0.0:
            roof.append(f)
    wall_faces = []
    if gable:
        nxt0 = np.arange(1, n + 1)
        for a_, b_ in zip(starts, starts[1:]):
            nxt0[b_ - 1] = a_
        prv0 = np.empty(n, np.int64)
        prv0[nxt0] = np.arange(n)
        roof, wall_faces = _gables(sv, z, roof, vid, local, nxt0, prv0)
    n_top = n + len(high)
    top = np.empty((n_top, 3))
    top[:n, :2] = xy
    top[:n, 2] = eave
    top[n:, :2] = sv[high, :2] + origin
    top[n:, 2] = eave + rise * (z[high] / zmax)
    flat2 = np.empty((n_top, 2))  # local plan coordinates of the top vertices
    flat2[:n] = local
    flat2[n:] = sv[high, :2]
    # walls and floor
    i = np.arange(n)
    nxt = i + 1
    for a_, b_ in zip(starts, starts[1:]):
        nxt[b_ - 1] = a_
    roof = [_with_dropped(vid[f].tolist(), n, nxt) for f in roof]
    gable_walls = [_with_dropped(vid[f].tolist(), n, nxt) for f in wall_faces]
    plane_xy = np.empty((n_top, 2))  # where CGAL computed the skeleton (the snapped ring) and its time
    plane_xy[:n] = snapped
    plane_xy[n:] = sv[high, :2]
    time = np.zeros(n_top)
    time[n:] = z[high]
    roof = _one_eave_a_face(roof, n, nxt, flat2, plane_xy, time)
    lost = _lost_faces(roof + gable_walls, n, nxt, flat2, plane_xy, time)
    if lost is None:
        return None
    tris = []
    for face in roof + lost:  # each face turned to look up as a whole (a sliver's own sign is noise)
        if len(face) == 3:
            t = np.array([[0, 1, 2]])
        else:
            t = mapbox_earcut.triangulate_float64(flat2[face], np.array([len(face)], np.uint32)).reshape(-1, 3)
        if _area2(flat2[np.asarray(face)[t]]).sum() < 0:
            t = t[:, [0, 2, 1]]
        tris += fill_skipped([face], np.asarray(face)[t].tolist())
    tri = np.asarray(tris, np.int64).reshape(-1, 3)
    gab = _fans(gable_walls, n)
    bottom = np.column_stack([xy, np.full(n, base)])
    walls = np.concatenate([np.column_stack([i + n_top, nxt + n_top, nxt]), np.column_stack([i + n_top, nxt, i])])
    floor = mapbox_earcut.triangulate_float64(xy - origin, np.asarray(starts[1:], np.uint32)).astype(np.int64)
    floor = floor.reshape(-1, 3)
    if _area2(local[floor]).sum() > 0:  # the floor looks down (earcut winds all its triangles one way)
        floor = floor[:, [0, 2, 1]]
    prv = np.empty(n, np.int64)
    prv[nxt] = i  # seen from below, the rings run backwards
    floor, _ = split_t_junctions(local, floor, prv, np.zeros(n, np.int64), np.array([0, n]))
    floor = floor + n_top
    faces = np.concatenate([floor, walls, gab, tri])
    if not _closed(faces):  # never hand on an open solid: the caller draws another roof
        return None
    kind = np.concatenate(
        [
            np.zeros(len(floor), np.uint8),
            np.ones(len(walls) + len(gab), np.uint8),
            np.full(len(tri), 2, np.uint8),
        ]
    )
    return np.concatenate([top, bottom]), faces, kind


#: Skeleton nodes closer than this (m) are one vertex: CGAL's simultaneous events
#: give several nodes at one point, computed apart by a few units in the last place.
MERGE = 1e-7


#: Grid (m) the footprint is snapped to for CGAL: on arbitrary doubles its exact
#: constructions dominate (2.8 ms a Liège footprint); on a millimetre grid 1.1 ms.
SNAP = 1e-3


def _snap(local: np.ndarray, starts: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Ring coordinates on the :data:`SNAP` grid and which to keep (not repeating the next one).

    Falls back to the coordinates as they are when snapping would make a ring
    degenerate or the polygon invalid (CGAL must never see one).
    """
    import shapely

    snapped = np.round(local / SNAP) * SNAP
    keep = np.ones(len(local), bool)
    rings = []
    for a, b in zip(starts, starts[1:]):
        ring = snapped[a:b]
        same = (ring == np.roll(ring, -1, axis=0)).all(axis=1)
        keep[a:b] = ~same
        rings.append(ring[~same])
    if min(len(r) for r in rings) >= 3 and shapely.is_valid(shapely.Polygon(rings[0], rings[1:])):
        return snapped, keep
    return local, np.ones(len(local), bool)


def _with_dropped(face: list[int], n: int, nxt: np.ndarray) -> list[int]:
    """Put back the footprint vertices CGAL drops (collinear ones) on each eave of a face.

    An eave runs ``a -> b`` along the ring; the ring vertices between them go in between.
    """
    out = []
    k = len(face)
    for j in range(k):
        a, b = face[j], face[(j + 1) % k]
        out.append(a)
        if a < n and b < n and nxt[a] != b:
            c, guard = int(nxt[a]), 0
            while c != b and guard < n:
                out.append(c)
                c, guard = int(nxt[c]), guard + 1
            if guard >= n:  # b is not ahead of a on the ring: not an eave
                del out[len(out) - guard :]
    return out


def _area2(t: np.ndarray) -> np.ndarray:
    """Twice the signed area of triangles ``t`` (k, 3, 2) (m2; positive counter-clockwise)."""
    a, b, c = t[:, 0], t[:, 1], t[:, 2]
    return (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])


def _lost_faces(
    faces: list[list[int]],
    n: int,
    nxt: np.ndarray,
    flat2: np.ndarray,
    plane_xy: np.ndarray | None = None,
    time: np.ndarray | None = None,
) -> list[list[int]] | None:
    """The roof faces CGAL left out, rebuilt from the crack they leave; ``None`` if the roof is beyond repair.

    ``extrude_skeleton`` triangulates each skeleton face in its own plane and
    silently drops a face whose outline passes one point twice (CGAL's
    constrained triangulation throws on the touching constraints).  That is
    what simultaneous events make: a square ring 0.6 m thick collapses
    everywhere at 0.3 m, and CGAL gives several skeleton nodes at each corner
    of the middle line; a star whose edges all touch one circle collapses to
    its centre, and CGAL gives a cluster of nodes a millimetre wide there.
    Once those nodes are one vertex the dropped faces leave a crack: the
    edges that only one face (or one eave) uses, chained into loops.

    A loop along one eave is one dropped face, handed back whole.  A loop
    along several eaves is several dropped faces side by side, and a plan
    triangulation of their union is not the roof (it may join three eave
    corners into a flat triangle at the eave, 7 % of a star's roof volume
    lost): each face is rebuilt as its eave and the loop's skeleton nodes
    that lie in its plane, the plane through the eave rising one metre a
    metre of skeleton time, in the loop's order (a face is cut from the loop
    by chords, which keep that order).  The faces must tile the loop in plan
    and use every node, else ``None``.

    Parameters
    ----------
    faces : list of list of int
        Roof faces and gable walls (top vertex ids: ``< n`` eave vertices).
    n : int
        Number of footprint vertices.
    nxt : numpy.ndarray of int
        Next footprint vertex along its ring (the footprint's inside on its left).
    flat2 : numpy.ndarray, shape (t, 2)
        Plan coordinates of the top vertices (m).
    plane_xy, time : numpy.ndarray, shapes (t, 2) and (t,), optional
        Where CGAL computed each top vertex (the snapped ring, m) and its
        skeleton time (m; 0 on the eave).  Without them a loop along
        several eaves is beyond repair.
    """
    count: dict[tuple[int, int], int] = {}
    for f in faces:
        for a, b in zip(f, f[1:] + f[:1]):
            if a != b:
                key = (a, b) if a < b else (b, a)
                count[key] = count.get(key, 0) + 1
    for a in range(n):  # the eaves: each is the top of a wall
        b = int(nxt[a])
        key = (a, b) if a < b else (b, a)
        count[key] = count.get(key, 0) + 1
    if any(c > 2 for c in count.values()):
        return None
    crack = [e for e, c in count.items() if c == 1]
    if not crack:
        return []
    adj: dict[int, list[int]] = {}
    for a, b in crack:
        adj.setdefault(a, []).append(b)
        adj.setdefault(b, []).append(a)
    if any(len(v) != 2 for v in adj.values()):
        return None  # cracks touching at a vertex: no unambiguous outline
    out, seen, cut = [], set(), False
    for start in sorted(adj):
        if start in seen:
            continue
        loop, prev, cur = [start], -1, start
        seen.add(start)
        while True:
            a, b = adj[cur]
            prev, cur = cur, (b if a == prev else a)
            if cur == start:
                break
            loop.append(cur)
            seen.add(cur)
        if len(loop) < 3:
            return None
        eaves = _eave_runs(loop, n, nxt, flat2)
        if len(eaves) == 1:
            out.append(loop)
            continue
        if not eaves or plane_xy is None or time is None:
            return None
        split = _faces_by_plane(loop, eaves, n, nxt, flat2, plane_xy, time)
        if split is None:
            return None
        out += split
        cut = True
    if cut:
        used = {v for f in faces + out for v in f}
        if any(v not in used for v in range(n, len(flat2))):
            return None  # a skeleton node inside the crack that no rebuilt face reaches
    return out


def _one_eave_a_face(faces, n, nxt, flat2, plane_xy, time) -> list[list[int]]:
    """CGAL's faces, each along one eave: a face along several is cut into theirs where it can be.

    A skeleton face stands over one eave, in that eave's plane.  On a polygon
    whose edges nearly all touch one circle (a regular star whose inner
    corners turn by a degree) CGAL's extrusion hands back faces along two
    eaves, without the arc between them: 6 cm out of any plane on a star
    20 m across, and a plan triangulation of such a face drew the roof
    0.3 % too low.  They are cut as :func:`_lost_faces` cuts a crack.  A
    face along eaves that all but run straight on (the flat vertices of a
    drawn outline, turning by a hundredth of a degree) stays whole when all
    its vertices lie within two grid steps of one of its eaves' planes; so
    does a face no cut is found for (Manhattan's one: a holed footprint whose
    hole turns by a fraction of a degree, its face 2 mm off its planes).
    """
    out = []
    for face in faces:
        eaves = _eave_runs(face, n, nxt, flat2)
        if len(eaves) <= 1 or min(_plane_offset(face, r, nxt, plane_xy, time).max() for r in eaves) <= 2 * SNAP:
            out.append(face)  # one eave, or eaves that all but run straight on (a footprint's flat vertices)
            continue
        split = _faces_by_plane(face, eaves, n, nxt, flat2, plane_xy, time)
        out += [face] if split is None else split  # no cut found: the face as CGAL gave it, as before
    return out


def _eave_runs(loop: list[int], n: int, nxt: np.ndarray, flat2: np.ndarray) -> list[list[int]]:
    """Positions in ``loop`` of each straight eave along it (runs of ring vertices on one line, in ring order)."""
    k = len(loop)
    steps = []  # loop positions i whose edge loop[i] -> loop[i + 1] is an eave (either way round)
    for i in range(k):
        a, b = loop[i], loop[(i + 1) % k]
        if a < n and b < n and (int(nxt[a]) == b or int(nxt[b]) == a):
            steps.append(i)
    if not steps:
        return []
    runs: list[list[int]] = []
    for i in steps:
        j = (i + 1) % k
        if runs and runs[-1][-1] == i:
            p, q, r = flat2[loop[runs[-1][0]]], flat2[loop[i]], flat2[loop[j]]
            d1, d2 = q - p, r - q
            if abs(d1[0] * d2[1] - d1[1] * d2[0]) <= 1e-9 * np.hypot(*d1) * np.hypot(*d2):
                runs[-1].append(j)  # straight on: the same eave (CGAL drops collinear vertices)
                continue
        runs.append([i, j])
    if len(runs) > 1 and runs[-1][-1] == runs[0][0]:  # the run through the loop's start
        p, q, r = flat2[loop[runs[-1][0]]], flat2[loop[runs[0][0]]], flat2[loop[runs[0][-1]]]
        d1, d2 = q - p, r - q
        if abs(d1[0] * d2[1] - d1[1] * d2[0]) <= 1e-9 * np.hypot(*d1) * np.hypot(*d2):
            runs[0] = runs.pop()[:-1] + runs[0]
    return runs


#: A skeleton node lies in a face's plane when its time is within this (m) of its
#: distance to the face's eave: CGAL's nodes are exact on the snapped ring up to
#: rounding and :data:`MERGE`; nodes of one simultaneous event lie some 0.1 mm apart.
ON_PLANE = 1e-6


def _faces_by_plane(loop, eaves, n, nxt, flat2, plane_xy, time) -> list[list[int]] | None:
    """Cut ``loop`` along several eaves into their faces (see :func:`_lost_faces`); ``None`` if they do not tile it.

    First by the nodes that lie in each eave's plane (to :data:`ON_PLANE`);
    where an arc is missing, so that no node lies in two planes, from the
    ring corner between two eaves to the node nearest both planes (to
    :data:`SNAP`, the grid CGAL ran on), each part cut again.
    """
    k = len(loop)
    ids = np.asarray(loop)
    node = ids >= n
    faces = []
    for run in eaves:
        member = node & (_plane_offset(loop, run, nxt, plane_xy, time) <= ON_PLANE)
        member[run] = True
        order = [(run[0] + j) % k for j in range(k)]
        face = [loop[i] for i in order if member[i]]
        if len(face) < 3:
            faces = None
            break
        faces.append(face)
    if faces is not None and _tiles(loop, faces, flat2):
        return faces
    faces = _cut_at_corners(loop, n, nxt, flat2, plane_xy, time)
    return faces if faces is not None and _tiles(loop, faces, flat2) else None


def _tiles(loop: list[int], faces: list[list[int]], flat2: np.ndarray) -> bool:
    """Whether ``faces`` tile the polygon ``loop`` in plan.

    Each edge of the loop is an edge of one face, each other edge of two
    (one each way round), and their areas add up to the loop's (no fold).
    """
    count: dict[tuple[int, int], int] = {}
    for f in faces:
        if len(set(f)) != len(f):
            return False
        for a, b in zip(f, f[1:] + f[:1]):
            key = (a, b) if a < b else (b, a)
            count[key] = count.get(key, 0) + 1
    rim = {(a, b) if a < b else (b, a) for a, b in zip(loop, loop[1:] + loop[:1])}
    if any(c != (1 if e in rim else 2) for e, c in count.items()) or not rim <= count.keys():
        return False
    whole = abs(_ring_area(flat2[np.asarray(loop)]))
    parts = sum(abs(_ring_area(flat2[np.asarray(f)])) for f in faces)
    return abs(parts - whole) <= 1e-6 * whole + 1e-9


def _plane_offset(loop, run, nxt, plane_xy, time) -> np.ndarray:
    """How far (m) each vertex of ``loop`` is off the plane of the eave ``run`` (positions in ``loop``).

    The plane rises from the eave's line one metre a metre of skeleton time
    inward (the footprint's inside on the left of its ring).
    """
    first, last = loop[run[0]], loop[run[-1]]
    a, b = (first, last) if int(nxt[first]) == loop[run[1]] else (last, first)
    e = plane_xy[b] - plane_xy[a]
    length = np.hypot(*e)
    ids = np.asarray(loop)
    if not length > 0:
        return np.full(len(ids), np.inf)
    d = plane_xy[ids] - plane_xy[a]
    return np.abs(time[ids] - (e[0] * d[:, 1] - e[1] * d[:, 0]) / length)


def _cut_at_corners(face, n, nxt, flat2, plane_xy, time, depth: int = 0) -> list[list[int]] | None:
    """Cut ``face`` from a ring corner between two of its eaves to the node nearest both planes, until one eave a face."""
    eaves = _eave_runs(face, n, nxt, flat2)
    if len(eaves) == 1:
        return [face] if _plane_offset(face, eaves[0], nxt, plane_xy, time).max() <= SNAP else None
    if not eaves or depth > len(face):
        return None
    k = len(face)
    node = np.asarray(face) >= n
    for r1 in eaves:
        r2 = next((r for r in eaves if r[0] == r1[-1]), None)
        if r2 is None:
            continue
        off = np.maximum(_plane_offset(face, r1, nxt, plane_xy, time), _plane_offset(face, r2, nxt, plane_xy, time))
        off[~node] = np.inf
        x = int(np.argmin(off))
        if not off[x] <= SNAP:
            continue
        j = r1[-1]
        one = [face[(j + i) % k] for i in range((x - j) % k + 1)]
        two = [face[(x + i) % k] for i in range((j - x) % k + 1)]
        if len(one) < 3 or len(two) < 3:
            continue
        a = _cut_at_corners(one, n, nxt, flat2, plane_xy, time, depth + 1)
        b = _cut_at_corners(two, n, nxt, flat2, plane_xy, time, depth + 1)
        if a is not None and b is not None:
            return a + b
    return None


def _ring_area(xy: np.ndarray) -> float:
    """Signed area of a closed ring (m2; positive counter-clockwise)."""
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _closed(faces: np.ndarray) -> bool:
    """Every directed edge of the triangles has exactly one reverse twin (a closed, consistently wound shell)."""
    e = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    if (e[:, 0] == e[:, 1]).any():
        return False
    m = int(faces.max()) + 1
    fwd = np.sort(e[:, 0] * m + e[:, 1])
    rev = np.sort(e[:, 1] * m + e[:, 0])
    return bool((np.diff(fwd) > 0).all() and np.array_equal(fwd, rev))


def _fans(faces: list[list[int]], n: int) -> np.ndarray:
    """Fan-triangulate gable walls from their apex (the eave may hold collinear vertices)."""
    out = []
    for f in faces:
        j = next((j for j, v in enumerate(f) if v >= n), 0)
        f = f[j:] + f[:j]
        out += [[f[0], f[k], f[k + 1]] for k in range(1, len(f) - 1)]
    return np.asarray(out, np.int64).reshape(-1, 3)


def _gables(sv, z, roof: list[list[int]], vid, local, nxt, prv) -> tuple[list[list[int]], list[list[int]]]:
    """Move the apex of each lone end triangle onto its eave's wall plane; return (roof faces, gable walls).

    Only the end of a wing turns into a gable: an eave whose neighbouring
    eaves stand square to it (within 10 degrees), so that the hips beside it
    become the wing's long roof planes.
    """
    ends = []
    apex_count: dict[int, int] = {}
    for k, face in enumerate(roof):
        if len(face) != 3:
            continue
        low = [v for v in face if z[v] <= 0.0]
        if len(low) != 2:
            continue
        apex = next(v for v in face if z[v] > 0.0)
        ends.append((k, apex))
        apex_count[apex] = apex_count.get(apex, 0) + 1
    walls = set()
    for k, apex in ends:
        if apex_count[apex] != 1:
            continue  # a pyramid top or a shared ridge end: keep the hip
        i = roof[k].index(apex)
        a, b = roof[k][(i + 1) % 3], roof[k][(i + 2) % 3]
        ra, rb = int(vid[a]), int(vid[b])
        if nxt[ra] != rb:
            continue
        pa, pb, pc = local[ra], local[rb], sv[apex, :2]  # the wall as it is, not as snapped
        d = pb - pa
        before = local[ra] - local[prv[ra]]
        after = local[nxt[rb]] - local[rb]
        unit = d / np.hypot(*d)
        if any(abs(np.dot(e, unit)) > np.sin(np.radians(10.0)) * np.hypot(*e) for e in (before, after)):
            continue
        t = float(np.dot(pc - pa, d) / np.dot(d, d))
        if not 0.05 < t < 0.95:
            continue
        sv[apex, :2] = pa + t * d
        walls.add(k)
    return [f for k, f in enumerate(roof) if k not in walls], [roof[k] for k in sorted(walls)]

"""Batched meshes from planar features: extruded solids, flat surfaces, ribbons.

Buildings travel through the network as footprints plus a height (architecture
note "buildings stay light until export"); a mesh exporter turns a whole layer
into one vertex array and one face array here, in a handful of numpy passes:

* every polygon (multi-parts exploded, exterior counter-clockwise, holes
  clockwise) is flattened into one coordinate array with ring and polygon
  offsets (:func:`ring_arrays`);
* caps are triangulated per polygon: convex polygons without holes (most lots
  and footprints) by a vectorized fan, the others by mapbox-earcut in a tight
  loop (:func:`triangulate`);
* walls are two triangles per ring edge, built from the ring arrays at once
  (:func:`extrude`).

All functions work in the planar frame, z up (metres).  :func:`to_y_up` turns
the result into glTF's frame (x east, y up, z south).  Faces wind
counter-clockwise seen from outside, so normals point out of solids and up
from surfaces.
"""

from __future__ import annotations

from dataclasses import dataclass

import mapbox_earcut
import numpy as np
import shapely

from sengine.geom.sorting import stable_argsort, unique_int  # re-exported: the roofs import them from here

__all__ = [
    "Rings",
    "ring_arrays",
    "triangulate",
    "fill_skipped",
    "split_t_junctions",
    "subset_rings",
    "cluster_points",
    "extrude",
    "flat",
    "ribbons",
    "to_y_up",
    "merge",
    "weld",
    "stable_argsort",
    "unique_int",
]


@dataclass(frozen=True)
class Rings:
    """Polygons flattened into arrays.

    Attributes
    ----------
    xy : numpy.ndarray, shape (m, 2)
        Ring vertices without the closing repeat, ring after ring.
    ring_start : numpy.ndarray, shape (r + 1,)
        Offsets of each ring in ``xy``.
    poly_ring : numpy.ndarray, shape (p + 1,)
        Offsets of each polygon's rings (exterior first) in the ring list.
    feature : numpy.ndarray, shape (p,)
        Index of the input feature each polygon part came from.
    """

    xy: np.ndarray
    ring_start: np.ndarray
    poly_ring: np.ndarray
    feature: np.ndarray

    @property
    def n_polys(self) -> int:
        return len(self.feature)

    def vertex_ring(self) -> np.ndarray:
        """Ring index of every vertex."""
        return np.repeat(np.arange(len(self.ring_start) - 1), np.diff(self.ring_start))

    def vertex_poly(self) -> np.ndarray:
        """Polygon index of every vertex."""
        ring_poly = np.repeat(np.arange(self.n_polys), np.diff(self.poly_ring))
        return ring_poly[self.vertex_ring()]

    def next_vertex(self) -> np.ndarray:
        """Index of the following vertex along its ring (wrapping)."""
        n = len(self.xy)
        nxt = np.arange(1, n + 1)
        ends = self.ring_start[1:] - 1
        nxt[ends] = self.ring_start[:-1]
        return nxt


def ring_arrays(geoms: np.ndarray) -> Rings:
    """Explode polygonal features into :class:`Rings`.

    Parameters
    ----------
    geoms : array of shapely geometries
        Polygons or MultiPolygons (other types and empty geometries are
        skipped), in metres.

    Returns
    -------
    Rings
        Exterior rings counter-clockwise, interior rings clockwise.
    """
    geoms = np.asarray(geoms, dtype=object)
    types = shapely.get_type_id(geoms)
    if (types == 3).all():  # the common case: plain polygons, no copy
        parts, feature = geoms, np.arange(len(geoms))
    else:
        parts, feature = shapely.get_parts(geoms, return_index=True)
        types = shapely.get_type_id(parts)
    keep = (types == 3) & ~shapely.is_empty(parts)
    keep &= shapely.area(parts) > 0.0
    parts, feature = parts[keep], feature[keep]
    coords, vpoly = shapely.get_coordinates(parts, return_index=True)
    dup = (vpoly[1:] == vpoly[:-1]) & (coords[1:, 0] == coords[:-1, 0]) & (coords[1:, 1] == coords[:-1, 1])
    if dup.any():  # only the polygons with repeated vertices are rebuilt
        hit = np.unique(vpoly[1:][dup])
        parts = parts.copy()
        parts[hit] = shapely.remove_repeated_points(parts[hit])
    holed = shapely.get_num_interior_rings(parts) > 0
    if dup.any():
        rings, ring_poly = shapely.get_rings(parts, return_index=True)
        counts = shapely.get_num_coordinates(rings)
        coords = shapely.get_coordinates(rings)
    elif holed.any():  # the coordinates read above run ring after ring: only the holed polygons' rings counted
        hp = np.flatnonzero(holed)
        hr, hr_of = shapely.get_rings(parts[hp], return_index=True)
        n_r = np.ones(len(parts), np.int64)
        n_r[hp] = np.bincount(hr_of, minlength=len(hp))
        ring_poly = np.repeat(np.arange(len(parts)), n_r)
        counts = np.bincount(vpoly, minlength=len(parts))[ring_poly]
        first_ring = np.cumsum(n_r) - n_r
        k = np.arange(len(hr)) - (np.cumsum(n_r[hp]) - n_r[hp])[hr_of]  # ring k of its polygon
        counts[first_ring[hp][hr_of] + k] = shapely.get_num_coordinates(hr)
    else:  # no holes: one ring per polygon, the coordinates read above
        counts = np.bincount(vpoly, minlength=len(parts))
        ring_poly = np.arange(len(parts))
    starts = np.concatenate([[0], np.cumsum(counts)])
    mask = np.ones(len(coords), bool)
    mask[starts[1:] - 1] = False  # the closing vertex of every ring
    xy = coords.compress(mask, axis=0)  # not coords[mask]: NumPy's row masks and gathers are slow
    ring_start = np.concatenate([[0], np.cumsum(counts - 1)]).astype(np.int64)
    poly_ring = np.concatenate([[0], np.cumsum(np.bincount(ring_poly, minlength=len(parts)))]).astype(np.int64)
    xy = _orient(xy, ring_start, poly_ring)
    return Rings(xy, ring_start, poly_ring, feature.astype(np.int64))


def _orient(xy: np.ndarray, ring_start: np.ndarray, poly_ring: np.ndarray) -> np.ndarray:
    """Reverse the rings that wind the wrong way: exteriors CCW, holes CW (numpy, no GEOS)."""
    n_rings = len(ring_start) - 1
    if len(xy) == 0:
        return xy
    vr = np.repeat(np.arange(n_rings), np.diff(ring_start))
    s, e = ring_start[vr], ring_start[vr + 1]
    i = np.arange(len(xy))
    nxt = np.where(i + 1 < e, i + 1, s)
    d = xy - xy.take(s, axis=0)  # relative to the ring's first vertex: exact enough in a UTM frame
    area2 = np.bincount(vr, weights=d[:, 0] * d[nxt, 1] - d[nxt, 0] * d[:, 1], minlength=n_rings)
    exterior = np.zeros(n_rings, bool)
    exterior[poly_ring[:-1]] = True
    flip = np.where(exterior, area2 < 0, area2 > 0)
    if not flip.any():
        return xy
    return xy.take(np.where(flip[vr], s + e - 1 - i, i), axis=0)


def triangulate(rings: Rings) -> np.ndarray:
    """Triangles covering every polygon of ``rings``, counter-clockwise.

    Convex polygons without holes are fanned in one vectorized step; the
    others go through mapbox-earcut one polygon at a time.

    Returns
    -------
    numpy.ndarray of int64, shape (t, 3)
        Indices into ``rings.xy``; every ring vertex is used (flat
        triangles over collinear vertices are kept, so solids stay closed).
    """
    xy = rings.xy
    if len(xy) == 0:
        return np.empty((0, 3), np.int64)
    n_rings = np.diff(rings.poly_ring)
    ring_len = np.diff(rings.ring_start)
    # convexity per ring: no turn to the right (exteriors are counter-clockwise)
    nxt = rings.next_vertex()
    prev = np.empty_like(nxt)
    prev[nxt] = np.arange(len(nxt))
    e0 = xy - xy.take(prev, axis=0)
    e1 = xy.take(nxt, axis=0) - xy
    cross = e0[:, 0] * e1[:, 1] - e0[:, 1] * e1[:, 0]
    scale = np.hypot(*e0.T) * np.hypot(*e1.T)
    right_turn = cross < -1e-9 * scale
    first_ring = rings.poly_ring[:-1]
    n_right = np.bincount(rings.vertex_ring(), weights=right_turn, minlength=len(ring_len))[first_ring]
    fan = (n_rings == 1) & (n_right == 0)
    # a ring with one reflex vertex is two convex pieces (cut along an edge at it, extended): its fan from
    # that vertex stays inside and, like a convex fan, has no T-junction
    fan1 = (n_rings == 1) & (n_right == 1)

    parts = []
    # vectorized fans: (s, s+k, s+k+1), k = 1 .. n-2
    if fan.any():
        s = rings.ring_start[first_ring[fan]]
        n = ring_len[first_ring[fan]]
        nt = np.maximum(n - 2, 0)
        start = np.repeat(s, nt)
        k = np.arange(nt.sum()) - np.repeat(np.cumsum(nt) - nt, nt) + 1
        parts.append(np.column_stack([start, start + k, start + k + 1]))
    if fan1.any():  # fans from the reflex vertex: (r, r+k, r+k+1) around the ring
        vpoly0 = rings.vertex_poly()
        rv = np.flatnonzero(right_turn & fan1[vpoly0])
        s = rings.ring_start[first_ring[vpoly0[rv]]]
        n = ring_len[first_ring[vpoly0[rv]]]
        nt = n - 2
        k = np.arange(nt.sum()) - np.repeat(np.cumsum(nt) - nt, nt) + 1
        s_, n_, r_ = np.repeat(s, nt), np.repeat(n, nt), np.repeat(rv - s, nt)
        parts.append(np.column_stack([r_ + s_, (r_ + k) % n_ + s_, (r_ + k + 1) % n_ + s_]))
    fan = fan | fan1
    # small rings seen whole from one of their vertices (star-shaped from it): the fan from the first such
    # vertex, every triangle turning left (the rays sweep round it once, no T-junction); earcut for the rest
    star = (n_rings == 1) & (n_right >= 2) & (ring_len[first_ring] <= STAR_MAX)
    if star.any():
        tri, ok = _star_fans(xy, rings.ring_start[first_ring[star]], ring_len[first_ring[star]])
        if tri is not None:
            parts.append(tri)
            star[np.flatnonzero(star)[~ok]] = False
            fan = fan | star
    # earcut for the rest; it winds all of a polygon's triangles one way: turned counter-clockwise
    # together, by their total area (a triangle's own sign is noise when it is flat, and turning
    # it alone would wind it against its neighbours: a crack)
    rest = np.flatnonzero(~fan)
    if rest.size:
        # one earcut call a polygon, nothing else in the loop; offsets and winding in numpy afterwards
        r0, r1 = rings.poly_ring[rest], rings.poly_ring[rest + 1]
        v0 = rings.ring_start[r0]
        ends = rings.ring_start[1:] - rings.ring_start[rings.poly_ring[np.repeat(np.arange(len(n_rings)), n_rings)]]
        ends = ends.astype(np.uint32)
        earcut = mapbox_earcut.triangulate_float64
        got = [
            earcut(xy[a:b], ends[c:d])
            for a, b, c, d in zip(v0.tolist(), rings.ring_start[r1].tolist(), r0.tolist(), r1.tolist())
        ]
        cnt = np.array([len(t) for t in got], np.int64) // 3
        if cnt.sum():
            tri = np.concatenate(got).astype(np.int64).reshape(-1, 3)
            tp = np.repeat(np.arange(len(rest)), cnt)
            tri += v0[tp][:, None]
            a, b, c = (
                xy.take(tri[:, k], axis=0) - xy.take(v0[tp], axis=0) for k in range(3)
            )  # relative to the polygon's first vertex
            area2 = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
            flip = (np.bincount(tp, weights=area2, minlength=len(rest)) < 0)[tp]
            tri[flip] = tri[flip][:, [0, 2, 1]]
            parts.append(tri)
    if not parts:
        return np.empty((0, 3), np.int64)
    tri = np.concatenate(parts)
    # flat triangles over collinear ring vertices stay: dropping one would open a crack beside a wall
    tri = tri.compress((tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 2] != tri[:, 0]), axis=0)
    unused = np.bincount(tri.ravel(), minlength=len(xy)) == 0
    if unused.any():  # collinear ring vertices skipped or in a dropped flat triangle: the walls need them
        tri = _refill(rings, tri, np.unique(rings.vertex_poly()[unused]))
    vpoly = rings.vertex_poly()
    cut = np.flatnonzero(~fan[vpoly[tri[:, 0]]])  # a fan of a convex ring has no T-junction; earcut's may
    if cut.size:
        fixed, origin = split_t_junctions(xy, tri[cut], nxt, vpoly, rings.ring_start[rings.poly_ring])
        if len(fixed) != len(cut):  # in place of the triangles they split, the order otherwise kept
            rest = np.setdiff1d(np.arange(len(tri)), cut)
            order = np.argsort(np.concatenate([rest, cut[origin]]), kind="stable")
            tri = np.concatenate([tri[rest], fixed])[order]
    return tri


#: Rings of at most this many vertices are tried as stars before earcut.
STAR_MAX = 16
#: Apexes tried together in one pass of :func:`_star_fans`.
STAR_STAGE = 3


def _star_fans(xy: np.ndarray, start: np.ndarray, n: np.ndarray) -> tuple[np.ndarray | None, np.ndarray]:
    """Fans of the rings ``start[i] .. start[i] + n[i]`` from the first vertex whose fan has only left turns.

    Rings are taken by vertex count; the apexes are tried in stages of
    :data:`STAR_STAGE` (each stage one numpy pass over the rings still without
    one), so a ring seen whole from its first vertices (most) costs a few
    apexes, not all of them.  Returns the triangles of the rings that have
    such a vertex and which rings do.
    """
    ok = np.zeros(len(start), bool)
    out = []
    for nn in np.unique(n).tolist():
        sel = np.flatnonzero(n == nn)
        st = start[sel]
        pts = xy[st[:, None] + np.arange(nn)] - xy[st][:, None, :]  # (p, nn, 2), relative to the first vertex
        ext2 = (np.abs(pts).max(axis=(1, 2)) ** 2)[:, None]
        j = np.arange(1, nn - 1)[None, :]
        best = np.full(len(sel), -1)
        left = np.arange(len(sel))
        for a0 in range(0, nn, STAR_STAGE):
            a = np.arange(a0, min(a0 + STAR_STAGE, nn))[:, None]
            ib, ic = (a + j) % nn, (a + j + 1) % nn  # (apex, k)
            p = pts[left]
            d1 = p[:, ib] - p[:, a[:, 0], None, :]
            d2 = p[:, ic] - p[:, a[:, 0], None, :]
            area2 = d1[..., 0] * d2[..., 1] - d1[..., 1] * d2[..., 0]
            good = (area2 > 1e-12 * ext2[left, :, None]).all(axis=2)
            has = good.any(axis=1)
            best[left[has]] = a0 + np.argmax(good[has], axis=1)
            left = left[~has]
            if not left.size:
                break
        has = best >= 0
        if not has.any():
            continue
        ok[sel[has]] = True
        best = best[has]
        k = np.arange(1, nn - 1)[None, :]
        apex = np.broadcast_to(best[:, None], (len(best), nn - 2))
        out.append(
            np.stack([apex, (best[:, None] + k) % nn, (best[:, None] + k + 1) % nn], axis=2) + st[has, None, None]
        )
    if not out:
        return None, ok
    tri = np.concatenate([t.reshape(-1, 3) for t in out])
    return tri, ok


def split_t_junctions(
    xy: np.ndarray, tri: np.ndarray, nxt: np.ndarray, vpoly: np.ndarray, poly_start: np.ndarray, tol: float = 1e-7
) -> tuple[np.ndarray, np.ndarray]:
    """Split triangles whose edge runs over ring vertices of their polygon (T-junctions), so the mesh closes.

    Earcut may join holes whose edges lie on one line (a terrace ring cut by
    its recessed storeys, for one) with a single triangle edge running along
    all of them; the ring vertices on that edge are then used by the
    triangles on its other side only, a crack of zero width that leaves the
    solid open.  Such an edge has no reverse twin and is no ring edge: the
    triangle on it becomes a fan from its third vertex over the vertices on
    it (same winding).

    Parameters
    ----------
    xy : numpy.ndarray, shape (m, 2)
        Ring vertices (m).
    tri : numpy.ndarray of int64, shape (t, 3)
        Counter-clockwise triangles (all of a polygon's, or its edges lack their twins).
    nxt : numpy.ndarray of int, shape (m,)
        Next vertex along each vertex's ring.
    vpoly : numpy.ndarray of int, shape (m,)
        Polygon of each vertex (vertices of one polygon are contiguous).
    poly_start : numpy.ndarray of int, shape (p + 1,)
        Offset of each polygon's first vertex.
    tol : float
        Distance (m) from the edge under which a vertex is on it.

    Returns
    -------
    triangles : numpy.ndarray of int64, shape (t', 3)
    origin : numpy.ndarray of int64, shape (t',)
        Input triangle each output triangle comes from (ascending).
    """
    m = len(xy)
    origin = np.arange(len(tri))
    for _ in range(8):  # each pass splits a triangle on one edge; a triangle rarely has two such edges
        if not len(tri):
            break
        e = tri[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
        key = np.sort(e[:, 0] * m + e[:, 1])
        rev = e[:, 1] * m + e[:, 0]
        at = np.minimum(np.searchsorted(key, rev), len(key) - 1)
        lone = (key[at] != rev) & (nxt[e[:, 0]] != e[:, 1])
        if not lone.any():
            break
        done = np.zeros(len(tri), bool)
        pieces = {}
        for k in np.flatnonzero(lone).tolist():
            t = k // 3
            if done[t]:
                continue
            u, w = int(e[k, 0]), int(e[k, 1])
            p = int(vpoly[u])
            a, b = int(poly_start[p]), int(poly_start[p + 1])
            d = xy[w] - xy[u]
            ln2 = float(d @ d)
            if not ln2 > 0:
                continue
            rel = xy[a:b] - xy[u]
            s = rel @ d / ln2
            off = np.abs(rel[:, 0] * d[1] - rel[:, 1] * d[0]) / np.sqrt(ln2)
            on = np.flatnonzero((s > 0) & (s < 1) & (off <= tol)) + a
            on = on[(on != u) & (on != w)]
            if not on.size:
                continue
            seq = [u, *on[np.argsort(s[on - a], kind="stable")].tolist(), w]
            c = int(tri[t][(k % 3 + 2) % 3])
            pieces[t] = np.array([[i, j, c] for i, j in zip(seq, seq[1:])], np.int64)
            done[t] = True
        if not pieces:
            break
        src = np.concatenate([np.flatnonzero(~done), np.repeat(list(pieces), [len(v) for v in pieces.values()])])
        order = np.argsort(src, kind="stable")
        tri = np.concatenate([tri[~done], *pieces.values()])[order]
        origin = origin[src[order]]
    return tri, origin


def _refill(rings: Rings, tri: np.ndarray, polys: np.ndarray) -> np.ndarray:
    """Triangles of ``polys`` redone with :func:`fill_skipped` so that every ring vertex is used."""
    vpoly = rings.vertex_poly()
    tpoly = vpoly[tri[:, 0]]
    hit = np.zeros(rings.n_polys, bool)
    hit[polys] = True
    mine = hit[tpoly]
    redone = [tri.compress(~mine, axis=0)]
    # each polygon's triangles, in their order, as one slice of the polygons' triangles sorted by polygon
    own = np.flatnonzero(mine)
    own = own[stable_argsort(tpoly[own])]
    at = np.searchsorted(tpoly[own], np.concatenate([polys, [rings.n_polys]]))
    for k, p in enumerate(polys.tolist()):
        r0, r1 = rings.poly_ring[p], rings.poly_ring[p + 1]
        ring_ids = [list(range(rings.ring_start[r], rings.ring_start[r + 1])) for r in range(r0, r1)]
        fixed = fill_skipped(ring_ids, tri.take(own[at[k] : at[k + 1]], axis=0).tolist())
        redone.append(np.asarray(fixed, np.int64).reshape(-1, 3))
    tri = np.concatenate(redone)
    return tri.take(np.argsort(vpoly[tri[:, 0]], kind="stable"), axis=0)


def fill_skipped(rings: list[list[int]], tris: list[list[int]]) -> list[list[int]]:
    """Triangles that use every vertex of ``rings``: earcut skips collinear ones, which leaves cracks.

    A run of skipped vertices between used ``u`` and ``w`` along a ring splits
    the triangle on edge ``u w`` into a fan from its third vertex (same
    winding).  Solids stay closed where a wall or a neighbouring face has
    those vertices.
    """
    used = {v for t in tris for v in t}
    for ring in rings:
        if all(v in used for v in ring) or not any(v in used for v in ring):
            continue
        j0 = next(j for j, v in enumerate(ring) if v in used)
        walk = ring[j0:] + ring[:j0] + [ring[j0]]
        runs, cur = [], [walk[0]]
        for v in walk[1:]:
            cur.append(v)
            if v in used:
                if len(cur) > 2:
                    runs.append(cur)
                cur = [v]
        for run in runs:
            u, w = run[0], run[-1]
            for ti, t in enumerate(tris):
                seq = None
                for r in range(3):
                    if t[r] == u and t[(r + 1) % 3] == w:
                        seq = run
                    elif t[r] == w and t[(r + 1) % 3] == u:
                        seq = run[::-1]
                    if seq is not None:
                        c = t[(r + 2) % 3]
                        break
                if seq is not None:
                    tris = tris[:ti] + [[p, q, c] for p, q in zip(seq, seq[1:])] + tris[ti + 1 :]
                    break
    return tris


def extrude(
    geoms: np.ndarray,
    heights: np.ndarray,
    *,
    base: float | np.ndarray = 0.0,
    bottom: bool = True,
    rings: Rings | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Prisms over many footprints, as one mesh.

    Parameters
    ----------
    geoms : array of Polygon / MultiPolygon
        Footprints (m).
    heights : array of float
        Height of each feature above its base (m).
    base : float or array of float
        Ground elevation of each feature (m).
    bottom : bool
        Close the solid with a downward-facing floor.
    rings : Rings, optional
        ``ring_arrays(geoms)`` when the caller has it already (its polygon
        features index ``geoms``).

    Returns
    -------
    vertices : numpy.ndarray, shape (v, 3)
        Planar x, y and z up (m); bottom ring vertices then top ones.
    faces : numpy.ndarray of int64, shape (f, 3)
        Counter-clockwise seen from outside.
    vertex_feature : numpy.ndarray of int64, shape (v,)
        Input feature index of each vertex.
    """
    rings = ring_arrays(geoms) if rings is None else rings
    heights = np.broadcast_to(np.asarray(heights, np.float64), (len(geoms),))
    bases = np.broadcast_to(np.asarray(base, np.float64), (len(geoms),))
    m = len(rings.xy)
    vfeat = rings.feature[rings.vertex_poly()] if m else np.empty(0, np.int64)
    z0 = bases[vfeat]
    z1 = z0 + heights[vfeat]
    vertices = (
        np.concatenate([np.column_stack([rings.xy, z0]), np.column_stack([rings.xy, z1])]) if m else np.empty((0, 3))
    )
    caps = triangulate(rings)
    i = np.arange(m)
    j = rings.next_vertex() if m else i
    walls = np.concatenate([np.column_stack([i, j, j + m]), np.column_stack([i, j + m, i + m])])
    faces = [caps + m, walls]
    if bottom:
        faces.insert(1, caps[:, [0, 2, 1]])
    return vertices, np.concatenate(faces).astype(np.int64), np.concatenate([vfeat, vfeat])


def flat(geoms: np.ndarray, z: float = 0.0, *, max_holes: int = 48) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Polygons as upward-facing triangulated surfaces at height ``z`` (m).

    A polygon with more than ``max_holes`` holes (a city-wide street surface
    around hundreds of blocks) is first cut into a grid of rectangles, each
    holding a few dozen holes, because earcut's hole bridging grows with the
    product of holes and vertices; the pieces cover the same area.

    Returns ``vertices (v, 3)``, ``faces (f, 3)`` and ``vertex_feature (v,)``.
    """
    geoms, feature = _chop(np.asarray(geoms, dtype=object), max_holes)
    rings = ring_arrays(geoms)
    vertices = np.column_stack([rings.xy, np.full(len(rings.xy), float(z))])
    vfeat = feature[rings.feature[rings.vertex_poly()]] if len(rings.xy) else np.empty(0, np.int64)
    return vertices, triangulate(rings), vfeat


def _chop(geoms: np.ndarray, max_holes: int) -> tuple[np.ndarray, np.ndarray]:
    """Cut polygons with many holes into grid pieces; return pieces and their feature index."""
    feature = np.arange(len(geoms))
    holes = shapely.get_num_interior_rings(geoms)  # -1 for non-polygons
    big = np.flatnonzero(holes > max_holes)
    if big.size == 0:
        return geoms, feature
    pieces, owner = [geoms[holes <= max_holes]], [feature[holes <= max_holes]]
    for i in big.tolist():
        g = geoms[i]
        k = int(np.ceil(np.sqrt(holes[i] / (max_holes / 2))))
        x0, y0, x1, y1 = g.bounds
        xs, ys = np.linspace(x0, x1, k + 1), np.linspace(y0, y1, k + 1)
        cut = np.array(
            [shapely.clip_by_rect(g, xs[a], ys[b], xs[a + 1], ys[b + 1]) for a in range(k) for b in range(k)],
            dtype=object,
        )
        pieces.append(cut)
        owner.append(np.full(len(cut), i))
    return np.concatenate(pieces), np.concatenate(owner)


def ribbons(
    geoms: np.ndarray, width: float | np.ndarray = 1.0, z: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lines as flat, upward-facing quads of ``width`` (m), one per segment.

    Parameters
    ----------
    geoms : array of LineString / MultiLineString (or polygons: their rings)
    width : float or array of float
        Ribbon width of each feature (m).
    z : float
        Height of the ribbons (m).

    Returns ``vertices (v, 3)``, ``faces (f, 3)`` and ``vertex_feature (v,)``.
    """
    geoms = np.asarray(geoms, dtype=object)
    width = np.broadcast_to(np.asarray(width, np.float64), (len(geoms),))
    lines, feat = _lines(geoms, with_feature=True)
    coords, idx = shapely.get_coordinates(lines, return_index=True)
    same = idx[1:] == idx[:-1]
    a, b = coords[:-1][same], coords[1:][same]
    f = feat[idx[:-1][same]]
    d = b - a
    length = np.hypot(d[:, 0], d[:, 1])
    ok = length > 1e-9
    a, b, d, length, f = a[ok], b[ok], d[ok], length[ok], f[ok]
    nrm = np.column_stack([-d[:, 1], d[:, 0]]) / length[:, None] * (width[f] / 2.0)[:, None]
    quad = np.stack([a - nrm, b - nrm, b + nrm, a + nrm], axis=1).reshape(-1, 2)
    vertices = np.column_stack([quad, np.full(len(quad), float(z))])
    base = np.arange(len(a))[:, None] * 4
    faces = np.concatenate([base + [0, 1, 2], base + [0, 2, 3]]).astype(np.int64)
    return vertices, faces, np.repeat(f, 4)


def _lines(geoms: np.ndarray, with_feature: bool = False):
    parts, feat = shapely.get_parts(geoms, return_index=True)
    polys = shapely.get_type_id(parts) == 3
    if polys.any():
        rings, ri = shapely.get_rings(parts[polys], return_index=True)
        parts = np.concatenate([parts[~polys], rings])
        feat = np.concatenate([feat[~polys], feat[polys][ri]])
    keep = np.isin(shapely.get_type_id(parts), (1, 2)) & ~shapely.is_empty(parts)
    parts, feat = parts[keep], feat[keep]
    return (parts, feat) if with_feature else parts


def to_y_up(vertices: np.ndarray) -> np.ndarray:
    """Planar (x east, y north, z up) to glTF (x east, y up, z south): a rotation."""
    v = np.asarray(vertices, np.float64)
    return np.column_stack([v[:, 0], v[:, 2], -v[:, 1]])


def merge(*meshes: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Concatenate ``(vertices, faces)`` pairs into one."""
    vs, fs, off = [], [], 0
    for v, f, *_ in meshes:
        vs.append(v)
        fs.append(f + off)
        off += len(v)
    if not vs:
        return np.empty((0, 3)), np.empty((0, 3), np.int64)
    return np.concatenate(vs), np.concatenate(fs)


def weld(vertices: np.ndarray, faces: np.ndarray, owner: np.ndarray, *, return_merged: bool = False):
    """Merge vertices of one owner with exactly equal coordinates.

    One sort of a 64-bit hash of (owner, coordinate bits), then equal
    neighbours merge: a few times faster than sorting on four keys.  The
    welded vertices come in the order of their hashes, each the first of its
    input vertices.  Keys that share a hash (coordinates with many trailing
    zero bits do: whole metres) are sorted on the keys themselves.  Returns
    ``(vertices, faces, owner)`` and, with
    ``return_merged``, a mask of the welded vertices that stand for more than
    one input vertex.
    """
    v = np.ascontiguousarray(vertices, np.float64) + 0.0  # -0.0 and 0.0 alike
    bits = v.view(np.uint64).reshape(-1, 3)
    with np.errstate(over="ignore"):
        h = bits[:, 0] * np.uint64(0x9E3779B97F4A7C15)
        h ^= bits[:, 1] * np.uint64(0xBF58476D1CE4E5B9)
        h ^= bits[:, 2] * np.uint64(0x94D049BB133111EB)
        h ^= np.asarray(owner).astype(np.uint64) * np.uint64(0xD6E8FEB86659FD93)
        h ^= h >> np.uint64(31)
    owner = np.asarray(owner)
    order = np.argsort(h)  # not stable (4x faster): each group's first input vertex is found below
    hs, vs, o = h[order], v.take(order, axis=0), owner[order]
    new = np.ones(len(order), bool)
    new[1:] = (hs[1:] != hs[:-1]) | (o[1:] != o[:-1]) | (vs[1:] != vs[:-1]).any(axis=1)
    if (~new[1:] != (hs[1:] == hs[:-1])).any():  # a hash shared by two keys (round coordinates): exact order
        order = np.lexsort((bits[:, 2], bits[:, 1], bits[:, 0], owner, h))
        hs, vs, o = h[order], v[order], owner[order]
        new[1:] = (hs[1:] != hs[:-1]) | (o[1:] != o[:-1]) | (vs[1:] != vs[:-1]).any(axis=1)
    group = np.cumsum(new) - 1
    remap = np.empty(len(order), np.int64)
    remap[order] = group
    first = np.minimum.reduceat(order, np.flatnonzero(new)) if len(order) else order  # as a stable sort's
    out = np.asarray(vertices).take(first, axis=0), remap.take(faces), o[new]
    if return_merged:
        return (*out, np.bincount(group, minlength=int(new.sum())) > 1)
    return out


def drop_collapsed(faces: np.ndarray, *extra: np.ndarray, merged: np.ndarray | None = None):
    """Drop the triangles a weld collapsed: repeated corners, and pairs of one triangle in both windings.

    ``merged`` (from :func:`weld`) limits the search to triangles touching a
    welded vertex.  Returns ``faces`` and each of ``extra`` (per-face arrays)
    without them.
    """
    if merged is not None:
        near = merged[faces].any(axis=1)
        if not near.any():
            return (faces, *extra)
        sub = drop_collapsed(faces[near], np.flatnonzero(near))
        keep = ~near
        keep[sub[1]] = True
        return (faces[keep], *(e[keep] for e in extra))
    ok = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 2] != faces[:, 0])
    srt = np.sort(faces, axis=1)
    # a triangle and its mirror share the sorted corners; an even rotation keeps the winding
    r = np.argmin(faces, axis=1)
    rolled = np.take_along_axis(faces, (r[:, None] + np.arange(3)) % 3, axis=1)
    sign = np.where(rolled[:, 1] < rolled[:, 2], 1, -1)
    _, inv = np.unique(srt, axis=0, return_inverse=True)
    inv = inv.ravel()
    net = np.zeros(inv.max() + 1 if len(inv) else 0, np.int64)
    np.add.at(net, inv[ok], sign[ok])
    count = np.bincount(inv[ok], minlength=len(net))
    ok &= ~((count[inv] >= 2) & (net[inv] == 0))
    return (faces[ok], *(e[ok] for e in extra))


def subset_rings(rings: Rings, sel: np.ndarray) -> Rings:
    """The polygons ``sel`` of ``rings`` as their own :class:`Rings`."""
    r0, r1 = rings.poly_ring[sel], rings.poly_ring[sel + 1]
    nr = r1 - r0
    ring_ids = np.repeat(r0 - np.concatenate([[0], np.cumsum(nr)[:-1]]), nr) + np.arange(nr.sum())
    lens = np.diff(rings.ring_start)[ring_ids]
    starts = rings.ring_start[ring_ids]
    vid = np.repeat(starts - np.concatenate([[0], np.cumsum(lens)[:-1]]), lens) + np.arange(lens.sum())
    return Rings(
        rings.xy.take(vid, axis=0),
        np.concatenate([[0], np.cumsum(lens)]).astype(np.int64),
        np.concatenate([[0], np.cumsum(nr)]).astype(np.int64),
        np.asarray(sel, np.int64),
    )


def cluster_points(p: np.ndarray, tol: float, group: np.ndarray | None = None) -> np.ndarray:
    """Per point, the first (lowest) index of the points (of its ``group``) within ``tol`` of it, chained.

    Single linkage along a sweep in x: CGAL's simultaneous events give several skeleton nodes at
    one point, computed apart by a few units in the last place.
    """
    k = len(p)
    group = np.zeros(k, np.int64) if group is None else group
    order = np.lexsort((p[:, 0], group))
    q, gq = p[order], group[order]
    a_, b_ = [], []
    j = 1
    while j < k:
        near = (gq[j:] == gq[:-j]) & (q[j:, 0] - q[:-j, 0] <= tol)
        if not near.any():
            break
        i = np.flatnonzero(near)
        close = np.abs(q[i + j] - q[i]).max(axis=1) <= tol
        a_.append(order[i[close]])
        b_.append(order[i[close] + j])
        j += 1
    label = np.arange(k)
    if a_:
        a, b = np.concatenate(a_), np.concatenate(b_)
        while True:  # propagate the smallest label along the pairs until nothing changes
            mn = np.minimum(label[a], label[b])
            new = label.copy()
            np.minimum.at(new, a, mn)
            np.minimum.at(new, b, mn)
            new = new[new]
            if np.array_equal(new, label):
                break
            label = new
    return label

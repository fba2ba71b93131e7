"""Hip and gable roofs for many footprints at once, from CGAL's interior straight skeleton.

The straight skeleton [1]_ of a footprint is a plane graph: its edges are the
footprint's own edges and the arcs traced by the wavefront's vertices.  Each
face of that graph belongs to one footprint edge, and a point of the face
rises above the eave by its distance to that edge's line (the time the
wavefront took to reach it), times the pitch.  CGAL's ``Straight_skeleton_2``
[2]_ gives the graph (``create_interior_straight_skeleton``, through the
compiled extension ``compas_cgal`` ships); everything after it is done here in
numpy passes over all footprints together, not per footprint:

1. the footprints go to CGAL on an integer millimetre grid, without the
   vertices that turn by less than :data:`FLAT_TURN` (CGAL's exact fallback
   spends most of its time on nearly collinear edges); they are put back on
   the eaves afterwards;
2. half-edges are sorted by angle around their source; the next half-edge of
   a face is the one just clockwise of the twin (faces on the left); faces
   are the cycles of that permutation, labelled by pointer doubling;
3. every face must hold exactly one footprint edge; a node's height is its
   distance to the lines of its faces' edges, which must agree;
4. a **gable** turns a lone end triangle into a wall (its apex moved onto the
   eave's wall plane), as :mod:`sengine.nodes.export.skeleton` describes;
5. convex faces (and gable walls) are fanned in one step from their first
   skeleton node, faces with one reflex vertex from it; the others go to
   :func:`~.mesh.triangulate` together (a fan from a vertex that sees the
   whole face, else earcut);
6. walls, floor, and a closedness check per solid (every directed edge of
   the roof has one reverse twin, the eaves' being the walls'; walls and
   floor close on the ring by construction); a footprint failing anywhere is
   handed back to the caller (which draws it with CGAL's own extrusion, one
   by one).

References
----------
.. [1] Aichholzer, O., Aurenhammer, F., Alberts, D., Gärtner, B., "A novel type
   of skeleton for polygons", Journal of Universal Computer Science 1(12),
   752-761, 1995.
.. [2] Cacciola, F., "A CGAL implementation of the straight skeleton of a simple
   2D polygon with holes", 2nd CGAL User Workshop, 2004.
"""

from __future__ import annotations

import numpy as np
import shapely

from .mesh import Rings, cluster_points, stable_argsort, triangulate, unique_int
from .wavefront import MAX_VERTICES, wavefront_skeletons

__all__ = ["hip_solids", "SNAP", "FLAT_TURN"]

#: Grid (m) the footprints are given to CGAL on, as integers (exact doubles).
SNAP = 1e-3
#: Vertices turning by less than this (rad) are left out of the skeleton and put back on the eave.
FLAT_TURN = np.radians(0.1)
#: Skeleton nodes closer than this (grid units) are one vertex: CGAL's simultaneous events give
#: several a hair apart; :mod:`.wavefront` events a tenth of a millimetre apart (wings of nearly one
#: width) are one event, as CGAL's exact arithmetic finds them.
MERGE = {"cgal": 1e-4, "wavefront": 1.0}
#: A node's distances to the edge lines of its faces may differ by this much (grid units): CGAL's
#: nodes are exact to rounding; :mod:`.wavefront` takes nearly opposite edges for opposite.
AGREE = {"cgal": 1e-2, "wavefront": 2.0}
#: A face turning right by less than this (sine) at a vertex still counts as convex.
CONVEX_TOL = np.sin(np.radians(0.2))


def hip_solids(
    ext, rings: Rings, eave: np.ndarray, rise: np.ndarray, base: np.ndarray, gable: np.ndarray, engine: str = "cgal"
):
    """Closed solids with a hip (or gable) roof over every polygon of ``rings``.

    Parameters
    ----------
    ext : module
        ``compas_cgal._straight_skeleton_2``.
    rings : Rings
        Footprints (m), exteriors counter-clockwise, holes clockwise.
    eave, rise, base : numpy.ndarray, shape (p,)
        Per polygon: wall top, roof rise and ground height (m).
    gable : numpy.ndarray of bool, shape (p,)
        Per polygon: turn the end triangles into gables.
    engine : {"cgal", "wavefront"}
        Who computes the skeleton: CGAL, or :mod:`.wavefront` (one-ring
        polygons of at most :data:`~.wavefront.MAX_VERTICES` vertices; the
        others are handed back).

    Returns
    -------
    vertices : numpy.ndarray, shape (v, 3)
    faces : numpy.ndarray of int64, shape (f, 3)
        Counter-clockwise seen from outside.
    vertex_poly : numpy.ndarray of int64, shape (v,)
    face_kind : numpy.ndarray of uint8, shape (f,)
        0 ground, 1 wall, 2 roof.
    failed : numpy.ndarray of int
        Polygons not built here (not in the mesh).
    """
    n_poly = rings.n_polys
    eave, rise, base = (np.asarray(a, np.float64).reshape(n_poly) for a in (eave, rise, base))
    gable = np.asarray(gable, bool).reshape(n_poly)
    xy = rings.xy
    m = len(xy)
    vpoly = rings.vertex_poly()
    vring = rings.vertex_ring()
    origin = xy[rings.ring_start[rings.poly_ring[:-1]]]
    local = xy - origin[vpoly]
    nxt = rings.next_vertex()
    prv = np.empty_like(nxt)
    prv[nxt] = np.arange(m)
    bad = np.zeros(n_poly, bool)

    # 1. the skeleton's input: integer millimetres, nearly straight vertices left out
    q = np.round(local / SNAP)
    kidx, kring, kstart = _drop_flat(q, vring, rings.ring_start)
    short = np.diff(kstart) < 3
    ring_poly = np.repeat(np.arange(n_poly), np.diff(rings.poly_ring))
    bad[ring_poly[short]] = True
    qk = q.take(kidx, axis=0)
    bad |= ~_valid(qk, kstart, rings.poly_ring, bad)
    if engine == "wavefront":
        nk0 = kstart[rings.poly_ring[1:]] - kstart[rings.poly_ring[:-1]]
        bad |= (np.diff(rings.poly_ring) != 1) | (nk0 > MAX_VERTICES)
        pts, ids, edges, etype, cnt, ecnt, gave_up = wavefront_skeletons(
            qk, kstart, rings.poly_ring, np.flatnonzero(~bad)
        )
        bad[gave_up] = True
    else:
        pts, ids, edges, etype, cnt, ecnt, bad = _skeletons(ext, qk, kstart, rings.poly_ring, bad)
    if not len(pts):
        e = np.empty(0, np.int64)
        return np.empty((0, 3)), np.empty((0, 3), np.int64), e, np.empty(0, np.uint8), np.arange(n_poly)
    row_poly = np.repeat(np.arange(n_poly), cnt)
    # edge ids to rows
    key = row_poly * (1 << 32) + ids
    order = stable_argsort(key)
    epoly = np.repeat(np.arange(n_poly), ecnt)
    ekey = epoly[:, None] * (1 << 32) + edges
    at = np.minimum(np.searchsorted(key[order], ekey), max(len(key) - 1, 0))
    found = key[order][at] == ekey if len(key) else np.ones(ekey.shape, bool)
    bad[epoly[~found.all(axis=1)]] = True
    erow = order[at] if len(key) else at
    # the contour CGAL kept (it may leave out collinear vertices too): rows on boundary edges, found
    # among the kept vertices by their coordinates (CGAL hands them back exactly); the wavefront's
    # are the kept vertices themselves, row k of a polygon its k-th
    contour = np.zeros(len(pts), bool)
    contour[erow.compress(etype == 2, axis=0).ravel()] = True
    crow = np.flatnonzero(contour)
    kid = np.full(len(pts), -1)
    if engine == "wavefront":
        kid[crow] = kstart[rings.poly_ring[row_poly[crow]]] + ids[crow]
    else:
        kpoly = ring_poly[kring]
        allp = np.concatenate([kpoly, row_poly[crow]])
        allxy = np.concatenate([qk, pts[crow]])
        src = np.concatenate([np.zeros(len(qk), np.int8), np.ones(len(crow), np.int8)])
        o = np.lexsort((src, allxy[:, 1], allxy[:, 0], allp))
        sp = np.flatnonzero(src[o] == 1)
        prev_o = o[np.maximum(sp - 1, 0)]
        match = (sp > 0) & (src[prev_o] == 0) & (allp[prev_o] == allp[o[sp]])
        match &= (allxy[prev_o] == allxy[o[sp]]).all(axis=1)
        bad[allp[o[sp[~match]]]] = True
        kid[crow[o[sp] - len(qk)]] = np.where(match, prev_o, 0)
    orig = kidx[kid[crow]]  # ring vertex of each contour row
    # the next contour row along its ring
    oc = stable_argsort(orig)
    rc = vring[orig[oc]]
    cf = np.ones(len(oc), bool)
    cf[1:] = rc[1:] != rc[:-1]
    cfs = np.flatnonzero(cf)
    clast = np.concatenate([cfs[1:], [len(oc)]]) - 1
    cn = np.arange(1, len(oc) + 1)
    cn[clast] = cfs
    cnext = np.full(len(pts), -1)
    cnext[crow[oc]] = crow[oc[cn]]
    nk = np.bincount(row_poly[crow], minlength=n_poly)  # contour vertices per polygon

    # 2. one vertex per point (simultaneous events), then the faces of the plane graph
    canon = np.arange(len(pts))
    node = np.flatnonzero(~contour & ~bad[row_poly])
    canon[node] = node[cluster_points(pts[node], MERGE[engine], row_poly[node])]
    eu, ev = canon[erow[:, 0]], canon[erow[:, 1]]
    live = (eu != ev) & ~bad[epoly]
    eu, ev = eu[live], ev[live]
    ek = unique_int(np.minimum(eu, ev) * (1 << 32) + np.maximum(eu, ev))
    eu, ev = ek >> 32, ek & ((1 << 32) - 1)
    ne = len(eu)
    hu, hv = np.concatenate([eu, ev]), np.concatenate([ev, eu])
    p_hu = pts.take(hu, axis=0)
    d = pts.take(hv, axis=0) - p_hu
    ang = np.arctan2(d[:, 1], d[:, 0])
    srt = _sort_around(hu, ang)
    pos = np.empty_like(srt)
    pos[srt] = np.arange(len(srt))
    su = hu[srt]
    first = np.ones(len(srt), bool)
    first[1:] = su[1:] != su[:-1]
    grp = np.cumsum(first) - 1
    gstart = np.flatnonzero(first)
    gend = np.concatenate([gstart[1:], [len(srt)]]) - 1
    prev_sorted = np.where(first, gend[grp], np.arange(len(srt)) - 1)
    twin = np.concatenate([np.arange(ne, 2 * ne), np.arange(ne)])
    hnext = srt[prev_sorted[pos[twin]]]
    label = _cycles(hnext)

    # 3. one footprint edge per face; heights
    eave_h = contour[hu] & (cnext[hu] == hv)
    rev_h = contour[hv] & (cnext[hv] == hu)
    hpoly = row_poly[hu]
    n_lab = len(hnext)
    size = np.bincount(label, minlength=n_lab)
    n_eave = np.bincount(label, weights=eave_h, minlength=n_lab)
    n_rev = np.bincount(label, weights=rev_h, minlength=n_lab)
    is_face = size > 0
    outer = is_face & (n_rev == size)
    inner = is_face & (n_eave == 1) & (n_rev == 0)
    lab_poly = np.zeros(n_lab, np.int64)
    lab_poly[label] = hpoly
    bad[lab_poly[is_face & ~outer & ~inner]] = True
    bad[nk != np.bincount(lab_poly[inner], minlength=n_poly)] = True
    # the eave half-edge of each face and each half-edge's distance to its line
    estart = np.full(n_lab, -1)
    estart[label[eave_h]] = np.flatnonzero(eave_h)
    fe = estart[label]
    inner_h = inner[label]
    fe0 = np.maximum(fe, 0)
    a_, b_ = pts.take(hu[fe0], axis=0), pts.take(hv[fe0], axis=0)
    dd = b_ - a_
    ln = np.hypot(dd[:, 0], dd[:, 1])
    rel = p_hu - a_
    t = np.where(inner_h, (dd[:, 0] * rel[:, 1] - dd[:, 1] * rel[:, 0]) / np.where(ln > 0, ln, 1.0), 0.0)
    tmax = np.full(len(pts), -np.inf)
    tmin = np.full(len(pts), np.inf)
    np.maximum.at(tmax, hu[inner_h], t[inner_h])
    np.minimum.at(tmin, hu[inner_h], t[inner_h])
    used = np.isfinite(tmax)
    bad[row_poly[used & ~contour & ((tmax - tmin > AGREE[engine]) | (tmin <= 0))]] = True
    bad[row_poly[used & contour & (np.maximum(np.abs(tmax), np.abs(tmin)) > AGREE[engine])]] = True
    node_t = np.where(used & ~contour, tmax, 0.0) * SNAP  # m from the eave's line
    zmax = np.zeros(n_poly)
    np.maximum.at(zmax, row_poly, node_t)
    bad |= ~(zmax > 0)

    # output ids: ring vertices (top), skeleton nodes, ring vertices (bottom)
    keep_node = used & ~contour & ~bad[row_poly]
    nodes = np.flatnonzero(keep_node)
    out_id = np.full(len(pts), -1)
    out_id[nodes] = m + np.arange(len(nodes))
    out_id[contour] = kidx[kid[contour]]
    plan = np.concatenate([local, pts.take(nodes, axis=0) * SNAP])  # plan coordinates, local to each polygon (m)
    vpoly_plan = np.concatenate([vpoly, row_poly[nodes]])

    # 4. faces as vertex sequences starting at their eave, the left-out ring vertices put back
    faces = np.flatnonzero(inner & ~bad[lab_poly])
    fpoly = lab_poly[faces]
    fsize = size[faces]
    start = estart[faces]
    if not len(faces):
        e = np.empty(0, np.int64)
        return np.empty((0, 3)), np.empty((0, 3), np.int64), e, np.empty(0, np.uint8), np.arange(n_poly)
    K = int(fsize.max())
    # the faces' vertices, k-th column at step k, on the faces that long only (largest first; most have 3-5)
    by_size = np.argsort(-fsize, kind="stable")
    longer = np.searchsorted(-fsize[by_size], -np.arange(K), side="left")  # faces with more than k vertices
    cyc_s = np.zeros((len(faces), K), np.int64)
    cur = start[by_size]
    for k in range(K):
        c = cur[: longer[k]]
        cyc_s[: longer[k], k] = out_id[hu[c]]
        cur = hnext[c]
    back = np.empty_like(by_size)
    back[by_size] = np.arange(len(by_size))
    cyc = cyc_s.take(back, axis=0)
    oa, ob = cyc[:, 0], cyc[:, 1]
    ring_len = np.diff(rings.ring_start)[vring[oa]]
    run = (ob - oa) % ring_len  # ring vertices from a to b, b included
    flen = run + fsize - 1
    fo = np.concatenate([[0], np.cumsum(flen)])
    fid = np.repeat(np.arange(len(faces)), flen)
    j = np.arange(fo[-1]) - fo[fid]
    rs = rings.ring_start[vring[oa]][fid]
    on_run = j <= run[fid]
    seq = np.where(
        on_run,
        rs + (oa[fid] - rs + j) % ring_len[fid],
        cyc.ravel()[fid * K + np.minimum(np.maximum(j - run[fid] + 1, 0), K - 1)],
    )

    # gables: lone end triangles over a wing's end become walls
    wall = np.zeros(len(faces), bool)
    tri_end = (fsize == 3) & (cyc[:, min(2, K - 1)] >= m) if K >= 3 else np.zeros(len(faces), bool)
    if tri_end.any():
        apex = cyc[tri_end, 2]
        cnt_apex = np.bincount(apex - m, minlength=len(nodes))
        cand = np.flatnonzero(tri_end)[(cnt_apex[apex - m] == 1) & gable[fpoly[tri_end]] & (run[tri_end] == 1)]
        ra, rb = oa[cand], ob[cand]
        pa, pb = local[ra], local[rb]
        dv = pb - pa
        unit = dv / np.hypot(dv[:, 0], dv[:, 1])[:, None]
        before, after = local[ra] - local[prv[ra]], local[nxt[rb]] - local[rb]
        s10 = np.sin(np.radians(10.0))
        square = (np.abs((before * unit).sum(1)) <= s10 * np.hypot(*before.T)) & (
            np.abs((after * unit).sum(1)) <= s10 * np.hypot(*after.T)
        )
        ap = cyc[cand, 2]
        tt = ((plan[ap] - pa) * dv).sum(1) / (dv * dv).sum(1)
        go = square & (tt > 0.05) & (tt < 0.95)
        plan[ap[go]] = pa[go] + tt[go, None] * dv[go]
        wall[cand[go]] = True

    # 5. triangles
    px, py = plan[:, 0].copy(), plan[:, 1].copy()
    f_of = fid
    nxt_s = np.where(j + 1 < flen[fid], np.arange(len(seq)) + 1, fo[fid])
    prv_s = np.empty_like(nxt_s)
    prv_s[nxt_s] = np.arange(len(seq))
    sx, sy = px.take(seq), py.take(seq)
    e0x, e0y = sx - sx.take(prv_s), sy - sy.take(prv_s)
    e1x, e1y = sx.take(nxt_s) - sx, sy.take(nxt_s) - sy
    cross = e0x * e1y - e0y * e1x
    reflex = cross < -CONVEX_TOL * np.hypot(e0x, e0y) * np.hypot(e1x, e1y)
    n_reflex = np.bincount(f_of, weights=reflex, minlength=len(faces))
    # convex faces and gable walls: fanned from the first skeleton node (index run + 1); one reflex
    # vertex: fanned from it (two convex pieces); the others, all at once, by mesh.triangulate (fans
    # from a vertex that sees the whole face, earcut for the few without one). A gable wall is a
    # segment in plan: it is never handed there, only fanned from its apex
    convex = (n_reflex <= 1) | wall
    sh = run + 1
    one = (n_reflex == 1) & ~wall
    rpos = np.zeros(len(faces), np.int64)
    rpos[f_of[reflex]] = j[reflex]
    sh = np.where(one, rpos, sh)
    rot = seq[fo[fid] + (j + sh[fid]) % flen[fid]]
    ntri = np.where(convex, flen - 2, 0)
    tf = np.repeat(np.arange(len(faces)), ntri)
    tk = np.arange(ntri.sum()) - np.repeat(np.cumsum(ntri) - ntri, ntri) + 1
    roof_tri = np.column_stack([rot[fo[tf]], rot[fo[tf] + tk], rot[fo[tf] + tk + 1]])
    # a face convex within CONVEX_TOL may still fold a fan triangle (a round footprint's faces turn right
    # by a hair at many vertices): such faces go with the others
    folded = _folded_xy(px, py, roof_tri)
    fold = np.bincount(tf[folded], minlength=len(faces)) > 0
    fold &= ~wall
    if fold.any():
        convex &= ~fold
        keep_t = convex[tf]
        roof_tri, tf, folded = roof_tri.compress(keep_t, axis=0), tf[keep_t], folded[keep_t]
    roof_kind = np.where(wall[tf], 1, 2).astype(np.uint8)
    hard = np.flatnonzero(~convex)
    if hard.size:
        lens = flen[hard]
        sidx = np.repeat(fo[hard] - np.concatenate([[0], np.cumsum(lens)[:-1]]), lens) + np.arange(lens.sum())
        sub = Rings(plan[rot[sidx]], np.concatenate([[0], np.cumsum(lens)]), np.arange(len(hard) + 1), hard)
        more = rot[sidx][triangulate(sub)]
        roof_tri = np.concatenate([roof_tri, more])
        roof_kind = np.concatenate([roof_kind, np.full(len(more), 2, np.uint8)])
        folded = np.concatenate([folded, _folded_xy(px, py, more)])

    # no roof triangle folds over (a skeleton that came out wrong): every one turns left in plan
    folded &= roof_kind == 2
    bad[vpoly_plan[roof_tri[folded, 0]]] = True

    # 6. the solid: heights, walls, floor; each polygon checked closed
    n_top = m + len(nodes)
    zr = eave[vpoly]
    zn = eave[row_poly[nodes]] + rise[row_poly[nodes]] * node_t[nodes] / zmax[row_poly[nodes]]
    vertices = np.concatenate(
        [
            np.column_stack([xy, zr]),
            np.column_stack([plan[m:] + origin[row_poly[nodes]], zn]),
            np.column_stack([xy, base[vpoly]]),
        ]
    )
    vertex_poly = np.concatenate([vpoly, row_poly[nodes], vpoly])
    i = np.arange(m)
    walls = np.concatenate([np.column_stack([i + n_top, nxt + n_top, nxt]), np.column_stack([i + n_top, nxt, i])])
    floor = triangulate(rings)[:, [0, 2, 1]] + n_top
    faces_all = np.concatenate([floor, walls, roof_tri])
    kinds = np.concatenate([np.zeros(len(floor), np.uint8), np.ones(len(walls), np.uint8), roof_kind])
    fp = vertex_poly[faces_all[:, 0]]
    # the walls (two triangles an eave) and the floor (the footprint's caps, as mesh.extrude's) close on
    # the ring by construction; the roof is checked against the eaves
    bad |= ~_roof_closed(roof_tri, vertex_poly[:n_top], nxt, n_poly)
    keep_f = ~bad[fp]
    keep_v = ~bad[vertex_poly]
    remap = np.cumsum(keep_v) - 1
    # each polygon's faces together (floor, walls, roof), in polygon order
    order_f = np.flatnonzero(keep_f)
    order_f = order_f[stable_argsort(fp[order_f])]
    return (
        vertices.compress(keep_v, axis=0),
        remap.take(faces_all.take(order_f, axis=0)),
        vertex_poly[keep_v],
        kinds[order_f],
        np.flatnonzero(bad),
    )


def _drop_flat(q: np.ndarray, vring: np.ndarray, ring_start: np.ndarray):
    """Ring vertices to keep (repeats and vertices turning less than :data:`FLAT_TURN` left out).

    Four passes drop flat vertices, never two neighbours in one pass; a last
    one drops the repeats left over (two vertices on one grid point at the
    end of a longer run of flat ones: the wavefront has no line for the edge
    between them).

    Returns the kept vertices' indices, their rings and the rings' offsets among them.
    """
    idx = np.arange(len(q))
    step = 0
    while step < 5:
        r = vring[idx]
        first = np.ones(len(idx), bool)
        first[1:] = r[1:] != r[:-1]
        fs = np.flatnonzero(first)
        last = np.concatenate([fs[1:], [len(idx)]]) - 1
        g = np.cumsum(first) - 1
        k = np.arange(len(idx))
        is_last = np.zeros(len(idx), bool)
        is_last[last] = True
        nx = np.where(is_last, fs[g], k + 1)
        p = q.take(idx, axis=0)
        d1 = p.take(nx, axis=0) - p
        repeat = (d1[:, 0] == 0) & (d1[:, 1] == 0)
        if step < 4:
            pv = np.empty_like(nx)
            pv[nx] = k
            d0 = p - p.take(pv, axis=0)
            cross = d0[:, 0] * d1[:, 1] - d0[:, 1] * d1[:, 0]
            dot = (d0 * d1).sum(axis=1)
            cand = repeat | (np.abs(np.arctan2(cross, dot)) <= FLAT_TURN)
            drop = cand & ~cand[pv]  # never two neighbours in one pass: a gentle curve keeps its chord close
        else:
            drop = repeat  # the point stays, once
        # never below three vertices a ring
        left = np.bincount(g, weights=~drop, minlength=len(fs))
        drop &= left[g] >= 3
        if drop.any():
            idx = idx[~drop]
            step += 1
        else:  # nothing flat left: on to the repeat pass (or done)
            step = 4 if step < 4 else 5
    r = vring[idx]
    kstart = np.searchsorted(r, np.arange(len(ring_start)))
    return idx, r, kstart.astype(np.int64)


def _valid(qk: np.ndarray, kstart: np.ndarray, poly_ring: np.ndarray, bad: np.ndarray) -> np.ndarray:
    """Per polygon: its kept, snapped rings make a valid polygon (CGAL must never see another)."""
    n_poly = len(poly_ring) - 1
    ok = np.zeros(n_poly, bool)
    lens = np.diff(kstart)
    rings_ok = lens >= 3
    nr = np.diff(poly_ring)
    one = np.flatnonzero((nr == 1) & ~bad)
    if one.size:
        r = poly_ring[one]
        ln = lens[r]
        sel = np.repeat(kstart[r] - np.concatenate([[0], np.cumsum(ln)[:-1]]), ln) + np.arange(ln.sum())
        ids = np.repeat(np.arange(one.size), ln)
        closed = np.concatenate([qk[sel], qk[kstart[r]]])
        cid = np.concatenate([ids, np.arange(one.size)])
        o = np.argsort(cid, kind="stable")
        polys = shapely.polygons(shapely.linearrings(closed[o], indices=cid[o]))
        ok[one] = shapely.is_valid(polys)
    for p in np.flatnonzero((nr > 1) & ~bad).tolist():
        rr = range(poly_ring[p], poly_ring[p + 1])
        if all(rings_ok[r] for r in rr):
            parts = [qk[kstart[r] : kstart[r + 1]] for r in rr]
            ok[p] = shapely.is_valid(shapely.Polygon(parts[0], parts[1:]))
    return ok


def _skeletons(ext, qk, kstart, poly_ring, bad):
    """CGAL's interior straight skeleton of every polygon not ``bad``: rows, ids, edges, edge types, counts."""
    n_poly = len(poly_ring) - 1
    pts, ids, edges, types = [], [], [], []
    cnt = np.zeros(n_poly, np.int64)
    ecnt = np.zeros(n_poly, np.int64)
    one = ext.create_interior_straight_skeleton
    ks, pr = kstart.tolist(), poly_ring.tolist()
    for p in np.flatnonzero(~bad).tolist():
        r0, r1 = pr[p], pr[p + 1]
        if r1 - r0 != 1:
            # footprints with holes go to the extrusion: CGAL's interior skeleton with holes crashed the
            # process (SIGSEGV, no exception) on a valid footprint of the districts demo whose hole was a
            # sliver triangle of 24 mm2
            bad[p] = True
            continue
        try:
            sv, si, se, st = one(qk[ks[r0] : ks[r0 + 1]])
        except Exception:  # CGAL refuses degenerate input
            bad[p] = True
            continue
        pts.append(sv)
        ids += si
        edges.append(se)
        types += st
        cnt[p] = len(sv)
        ecnt[p] = len(se)
    if not pts:
        e = np.empty(0, np.int64)
        return np.empty((0, 2)), e, np.empty((0, 2), np.int64), e, cnt, ecnt, bad
    return (
        np.concatenate(pts)[:, :2],
        np.asarray(ids, np.int64),
        np.concatenate(edges).astype(np.int64),
        np.asarray(types, np.int8),
        cnt,
        ecnt,
        bad,
    )


#: Half-edges around a node sorted in one padded row each up to this many; busier nodes by lexsort.
ROW_SORT_MAX = 8


def _sort_around(src: np.ndarray, ang: np.ndarray) -> np.ndarray:
    """``np.lexsort((ang, src))``: half-edges by source node, then by angle, ties in input order.

    Grouped by source with one integer sort; in each group of ``k`` half-edges
    (three at most nodes), each one's place is how many of the others come
    before it, found for all groups of that size at once in a (groups, k, k)
    comparison.  Several times faster than ``lexsort`` on a float key; groups
    of more than :data:`ROW_SORT_MAX` go to ``lexsort``.
    """
    n = len(src)
    if n == 0:
        return np.arange(0)
    o = stable_argsort(src)
    s = src[o]
    first = np.ones(n, bool)
    first[1:] = s[1:] != s[:-1]
    gs = np.flatnonzero(first)
    k = np.diff(np.append(gs, n))
    out = np.empty(n, np.int64)
    for size in np.unique(k).tolist():
        st = gs[k == size]
        if size == 1:
            out[st] = o[st]
        elif size <= ROW_SORT_MAX:
            pos = st[:, None] + np.arange(size)  # (groups, size): places in o, input order within a group
            a = ang[o[pos]]
            before = (a[:, None, :] < a[:, :, None]) | (
                (a[:, None, :] == a[:, :, None]) & np.tri(size, size, -1, bool)[None]
            )
            rank = before.sum(axis=2)
            out[st[:, None] + rank] = o[pos]
        else:
            pos = (st[:, None] + np.arange(size)).ravel()
            out[pos] = o[pos][np.lexsort((ang[o[pos]], s[pos]))]
    return out


def _cycles(nxt: np.ndarray) -> np.ndarray:
    """Label of each element of the permutation ``nxt``: the smallest index on its cycle.

    Pointer doubling: after step ``s`` each label is the least over the next
    ``2**s`` elements; when a step changes nothing, consecutive windows that
    tile each cycle agree, so every label is its cycle's least.
    """
    label = np.arange(len(nxt))
    jump = nxt.copy()
    while True:
        new = np.minimum(label, label[jump])
        if np.array_equal(new, label):
            return label
        label, jump = new, jump[jump]


def _folded(tp: np.ndarray) -> np.ndarray:
    """Per triangle ``tp`` (t, 3, 2): it turns right in plan, beyond the slivers between nodes a hair apart."""
    e2 = ((tp[:, 1] - tp[:, 0]) ** 2).sum(1) + ((tp[:, 2] - tp[:, 1]) ** 2).sum(1)
    return _area2(tp) < -1e-3 * e2


def _folded_xy(px: np.ndarray, py: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """:func:`_folded` of the triangles ``tri`` (t, 3) of the points ``(px, py)``, gathered by component."""
    ax, ay = px.take(tri[:, 0]), py.take(tri[:, 0])
    bx, by = px.take(tri[:, 1]), py.take(tri[:, 1])
    cx, cy = px.take(tri[:, 2]), py.take(tri[:, 2])
    e2 = ((bx - ax) ** 2 + (by - ay) ** 2) + ((cx - bx) ** 2 + (cy - by) ** 2)
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax) < -1e-3 * e2


def _area2(t: np.ndarray) -> np.ndarray:
    a, b, c = t[:, 0], t[:, 1], t[:, 2]
    return (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])


def _roof_closed(tri: np.ndarray, vertex_poly: np.ndarray, nxt: np.ndarray, n_poly: int) -> np.ndarray:
    """Per polygon: its roof triangles ``tri`` close on its eaves.

    Every directed edge has exactly one reverse twin among the roof's, except
    the eaves: ring vertex ``u`` (``u < len(nxt)``) to ``nxt[u]``, which the
    roof must run along exactly once each (the wall's top edge is the twin).
    One sort of the edges as ``2 * (lo * n + hi) + (lo is the source)``: a
    twinned edge's two codes are ``2 k`` and ``2 k + 1``, side by side.
    """
    ok = np.ones(n_poly, bool)
    m = len(nxt)
    ring_count = np.bincount(vertex_poly[:m], minlength=n_poly)
    if not len(tri):
        return ok & (ring_count == 0)
    n_vert = len(vertex_poly)
    u = tri.ravel()
    v = tri[:, [1, 2, 0]].ravel()
    lo, hi = np.minimum(u, v), np.maximum(u, v)
    ok[vertex_poly[lo[lo == hi]]] = False
    code = np.sort((lo * n_vert + hi) * 2 + (u < v))
    nb = np.empty_like(code)  # where the twin must sit: after an even code, before an odd one
    nb[:-1], nb[-1] = code[1:], -1
    odd = (code & 1).astype(bool)
    nb[odd] = np.concatenate([[-1], code[:-1]])[odd]
    dup = np.zeros(len(code), bool)
    dup[1:] = code[1:] == code[:-1]
    dup[:-1] |= code[:-1] == code[1:]
    key = code >> 1
    a, b = key // n_vert, key % n_vert
    src, dst = np.where(odd, a, b), np.where(odd, b, a)
    eave = (src < m) & (dst == nxt[np.minimum(src, m - 1)])
    alone = nb != (code ^ 1)
    broken = dup | (alone & ~eave) | (~alone & eave)
    ok[vertex_poly[a[broken]]] = False
    ok[vertex_poly[b[broken]]] = False
    ok &= np.bincount(vertex_poly[src[eave & alone & ~dup]], minlength=n_poly) == ring_count
    return ok

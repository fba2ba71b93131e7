"""Faces of skeleton lots: the plane graph of block rings, offset rings and cut rays, and merges.

The pieces :mod:`.skeleton` cuts a block into are the faces of a plane
graph whose nodes are exact: every ray starts at a known point of a block
edge and ends at a known point of the segment it hit, so only rays that
cross one another need splitting (:func:`_graph_faces`; the faces come from
:func:`sengine.geom.planar.planar_faces`).  The few parts that graph cannot
close (overlapping blocks) are noded and polygonized by GEOS instead
(:func:`_geos_faces`).  Faces too small or without enough street join the
neighbour they share most boundary with (:func:`_merge_into`), and the
interior can be shared out among the street lots (:func:`_merge_interior`).
"""

from __future__ import annotations

import numpy as np
import shapely

from sengine.geom.boundary import ring_segments
from sengine.geom.grid import box_self_pairs
from sengine.geom.merge import TOUCH, kept_area
from sengine.geom.planar import planar_faces
from sengine.geom.polygons import threaded
from sengine.geom.segments import argsort_int, merge_points

from .contour import Marks, ramp

OVERSHOOT = 1e-3  # m: rays run this far past what they hit, so that GEOS noding makes the junction
SNAP = 1e-6  # m: grid of the snap-rounding noder used where GEOS's fast noder fails
SAME = 1e-9  # m: points of the face graph closer than this are one node


def _node(lines):
    """``shapely.node`` of each MultiLineString; one GEOS cannot node (rays meeting at a point, nearly)
    is noded by snap rounding to a micrometre grid instead."""
    try:
        return threaded(shapely.node, lines)
    except shapely.errors.GEOSException:
        out = np.empty(len(lines), dtype=object)
        for k, g in enumerate(lines):  # rare: only after a failure, to find the culprits
            try:
                out[k] = shapely.node(g)
            except shapely.errors.GEOSException:
                out[k] = shapely.union_all([g], grid_size=SNAP)
        return out


def unique_rows(key):
    """``np.unique(key, axis=0, return_index=True, return_inverse=True)[1:]``: the same numbers, faster.

    Rows sorted by a stable ``lexsort`` (first column first): each distinct
    row's first index, in the order of the sorted rows, and each row's group.
    NumPy sorts rows through a structured view, about 2.5 times slower.
    """
    key = np.asarray(key)
    n = len(key)
    if n == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    o = np.lexsort(key.T[::-1])
    k = key[o]
    new = np.r_[True, (k[1:] != k[:-1]).any(axis=1)]
    inv = np.empty(n, np.int64)
    inv[o] = np.cumsum(new) - 1
    return o[new], inv


def _along(seg, par) -> np.ndarray:
    """``np.lexsort((par, seg))``, the same permutation: items grouped by segment (an integer radix sort),
    then the segments with as many items sorted by parameter at once, as the rows of a matrix.

    Faster where many segments hold several items (block edges cut by
    their rays: 0.08 -> 0.04 s on whole Liège); a lexsort of items nearly
    in order already (rays cut at their few crossings) is faster still.
    """
    o = argsort_int(seg)
    s = seg[o]
    start = np.flatnonzero(np.r_[True, s[1:] != s[:-1]]) if len(s) else np.zeros(0, np.int64)
    size = np.diff(np.r_[start, len(s)])
    out = o.copy()
    for k in np.unique(size[size > 1]):
        at = start[size == k][:, None] + np.arange(k)
        rows = o[at]
        out[at] = np.take_along_axis(rows, np.argsort(par[rows], axis=1, kind="stable"), axis=1)
    return out


def _unique_along(seg, par):
    """:func:`unique_rows` of the rows ``(seg, par)`` (integer segment, position along it), sorted by
    :func:`_along` instead of a lexsort of two float columns: the same first indices and groups."""
    n = len(seg)
    if n == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    o = _along(seg, par)
    s, q = seg[o], par[o]
    new = np.r_[True, (s[1:] != s[:-1]) | (q[1:] != q[:-1])]
    inv = np.empty(n, np.int64)
    inv[o] = np.cumsum(new) - 1
    return o[new], inv


def _chain(item_seg, item_par, item_node, seg_end, nseg, grouped=False):
    """Edges along segments cut at points: for each segment, its start, the points in order, its end.

    ``item_*``: one item per segment start (parameter -1) and per point on
    a segment; ``seg_end``: the end node of each segment.  Returns the
    edges ``u, v`` and the segment of each.  ``grouped``: sort the items
    with :func:`_along` (many segments with several points).
    """
    o = _along(item_seg, item_par) if grouped else np.lexsort((item_par, item_seg))
    sg, nd = item_seg[o], item_node[o]
    last = np.r_[sg[1:] != sg[:-1], True]
    nxt = np.r_[nd[1:], 0]
    v = np.where(last, seg_end[sg], nxt)
    return nd, v, sg


def _graph_faces(rs, rsI, ipart, p, nrm, t, cut_e, toff, hseg, hpar, ray_part, flag=None):
    """Faces of the plane graph: block rings, offset rings and rays, all joined at exact nodes.

    Every ray starts at a known point of a block edge and ends at a known
    point of the segment it hit, so the graph is plane by construction
    except where rays cross one another (found with an STRtree query and
    split).  Its faces (:func:`sengine.geom.planar.planar_faces`) are the
    lots; those right of a block edge fill a hole of the block and are
    dropped, those left of an offset edge are the interior.  Returns faces,
    their part, the interior flag, and per part whether its faces add up
    to its area (else it needs GEOS).  ``flag`` (per block edge, optional):
    which edges face a street; the frontage counts only those.
    """
    N, NI, P = len(rs.xy), len(rsI.xy), rs.n
    xy0 = np.r_[rs.xy, rsI.xy]
    seg_start = np.arange(N + NI)
    seg_end = np.r_[rs.next_vertex(), N + rsI.next_vertex()]
    seg_part = np.r_[rs.vertex_poly(), ipart]
    R = len(p)
    ln = rs.edge_lengths()
    q = p + t[:, None] * nrm
    # ray ends: a segment's end node (within a nanometre), or a new point on it
    slen = np.hypot(*(xy0[seg_end] - xy0[seg_start]).T)
    at = hpar * slen[hseg]
    end_node = np.where(at <= SAME, seg_start[hseg], np.where(at >= slen[hseg] - SAME, seg_end[hseg], -1))
    start_node = np.where(toff <= SAME, cut_e, np.where(toff >= ln[cut_e] - SAME, rs.next_vertex()[cut_e], -1))
    ev_seg = np.r_[cut_e[start_node < 0], hseg[end_node < 0]]
    ev_par = np.r_[(toff / np.maximum(ln[cut_e], 1e-300))[start_node < 0], hpar[end_node < 0]]
    ev_xy = np.r_[p[start_node < 0], q[end_node < 0]]
    ev_ray = np.r_[np.flatnonzero(start_node < 0), np.flatnonzero(end_node < 0)]
    ev_is_end = np.r_[np.zeros(int((start_node < 0).sum()), bool), np.ones(int((end_node < 0).sum()), bool)]
    # one node per distinct point of a segment (to a nanometre)
    first, inv = _unique_along(ev_seg, np.round(ev_par * slen[ev_seg], 9))
    ev_node = N + NI + inv
    start_node[ev_ray[~ev_is_end]] = ev_node[~ev_is_end]
    end_node[ev_ray[ev_is_end]] = ev_node[ev_is_end]
    xy = np.r_[xy0, ev_xy[first]]
    # crossings of rays with rays
    a0, a1 = p, q
    lo, hi = np.minimum(a0, a1), np.maximum(a0, a1)
    i, j = box_self_pairs(lo, hi, group=ray_part)  # rays of one part whose boxes meet, i < j
    shared = (start_node[i] == start_node[j]) | (start_node[i] == end_node[j])
    shared |= (end_node[i] == start_node[j]) | (end_node[i] == end_node[j])
    i, j = i[~shared], j[~shared]
    r, sv = a1[i] - a0[i], a1[j] - a0[j]
    den = r[:, 0] * sv[:, 1] - r[:, 1] * sv[:, 0]
    qp = a0[j] - a0[i]
    with np.errstate(divide="ignore", invalid="ignore"):
        ta = (qp[:, 0] * sv[:, 1] - qp[:, 1] * sv[:, 0]) / den
        tb = (qp[:, 0] * r[:, 1] - qp[:, 1] * r[:, 0]) / den
    la, lb = np.hypot(*r.T), np.hypot(*sv.T)
    cross = (den != 0) & (ta * la > SAME) & ((1 - ta) * la > SAME) & (tb * lb > SAME) & ((1 - tb) * lb > SAME)
    i, j, ta, tb = i[cross], j[cross], ta[cross], tb[cross]
    cxy = a0[i] + ta[:, None] * r[cross]
    # crossings at one point (several rays through it) are one node
    ckey = np.c_[ray_part[i].astype(np.float64), np.round(cxy, 9)]
    cfirst, cinv = unique_rows(ckey)
    cnode = len(xy) + cinv
    xy = np.r_[xy, cxy[cfirst]]
    # edges: segments cut at the ray ends, rays cut at their crossings
    su, sv_, sg = _chain(
        np.r_[seg_start, ev_seg],
        np.r_[np.full(N + NI, -1.0), ev_par],
        np.r_[seg_start, ev_node],
        seg_end,
        N + NI,
        grouped=True,
    )
    ru, rv, rg = _chain(
        np.r_[np.arange(R), i, j], np.r_[np.full(R, -1.0), ta, tb], np.r_[start_node, cnode, cnode], end_node, R
    )
    u = np.r_[su, ru]
    v = np.r_[sv_, rv]
    epart = np.r_[seg_part[sg], ray_part[rg]]
    kind = np.r_[np.where(sg < N, 0, 1), np.full(len(ru), 2)]  # 0 block, 1 offset, 2 ray
    pf = planar_faces(xy, u, v)
    faces = pf.polygons
    F = len(faces)
    fpart = np.full(F, -1, np.int64)
    ef = pf.edge_faces
    left = ef[:, 0]
    has = left >= 0
    fpart[left[has]] = epart[has]
    right = ef[:, 1]
    has = right >= 0
    fpart[right[has]] = epart[has]
    drop = np.zeros(F, bool)
    hole = (kind == 0) & (right >= 0)  # right of a block edge: inside one of its holes
    drop[right[hole]] = True
    inner = np.zeros(F, bool)
    io = (kind == 1) & (left >= 0)
    inner[left[io]] = True
    keep = ~drop & (fpart >= 0)
    kept = np.flatnonzero(keep)
    fmap = np.full(F, -1, np.int64)
    fmap[kept] = np.arange(len(kept))
    el = np.hypot(*(xy[v] - xy[u]).T)
    # street frontage of each face: the block edges it lies left of
    onb = (kind == 0) & (left >= 0)
    if flag is not None:
        onb[: len(su)] &= np.r_[np.asarray(flag, bool), np.zeros(NI, bool)][sg]
    front = np.bincount(np.maximum(fmap[left[onb]], 0), weights=el[onb] * (fmap[left[onb]] >= 0), minlength=len(kept))
    # neighbours: faces on both sides of an edge, with the length they share
    both = (left >= 0) & (right >= 0) & (left != right)
    a, b = fmap[left[both]], fmap[right[both]]
    okp = (a >= 0) & (b >= 0)
    adj = _pair_sums(np.r_[a[okp], b[okp]], np.r_[b[okp], a[okp]], np.r_[el[both][okp], el[both][okp]], len(kept))
    # per boundary segment of each face, whether it is a block edge: the face's walk, step by step
    marks, known = _walk_marks(pf, faces, kind == 0)
    faces, fpart, inner = faces[kept], fpart[kept], inner[kept]
    marks, known = marks.take(kept), known[kept]
    total = np.bincount(fpart, weights=shapely.area(faces), minlength=P)
    ok = np.abs(total - rs.areas()) <= 1e-9 * np.maximum(np.abs(rs.areas()), 1.0)
    return faces, fpart, inner, ok, front, adj, marks, known


def _pair_sums(i, j, w, n):
    """Unique (i, j) pairs with the sum of ``w`` over each."""
    if len(i) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    key = i * n + j
    o = argsort_int(key)
    first = np.r_[True, key[o][1:] != key[o][:-1]]
    grp = np.cumsum(first) - 1
    return i[o][first], j[o][first], np.bincount(grp, weights=w[o])


def _walk_marks(pf, faces, block_edge):
    """Which boundary segment of each face lies on a block edge (``block_edge``: per edge of the graph).

    A face whose shell is one simple walk and that has no hole has its
    segments in walk order (:class:`sengine.geom.planar.PlanarFaces`); the
    others are left unknown (measured later).
    """
    F = len(faces)
    nseg = np.maximum(shapely.get_num_coordinates(faces) - 1 - shapely.get_num_interior_rings(faces), 0)
    known = np.zeros(F, bool)
    wp = pf.walk_polygon
    w = np.flatnonzero(wp >= 0)
    wlen = np.diff(pf.walk_start)[w]
    good = shapely.get_num_interior_rings(faces[wp[w]]) == 0
    good &= wlen == nseg[wp[w]]
    w, wlen = w[good], wlen[good]
    known[wp[w]] = True
    flat = np.zeros(int(nseg.sum()), bool)
    if len(w):
        # a walk's segment is on the block when its edge is a block edge (or one of its duplicates is)
        on_edge = np.zeros(int(pf.edge_unique.max()) + 1 if len(pf.edge_unique) else 0, bool)
        on_edge[pf.edge_unique[np.asarray(block_edge, bool) & (pf.edge_unique >= 0)]] = True
        row = np.repeat(np.arange(len(w)), wlen)
        k = ramp(wlen)
        on = on_edge[pf.walk_edge[pf.walk_start[w][row] + k]]
        fstart = np.cumsum(nseg) - nseg
        flat[fstart[wp[w]][row] + k] = on
    return Marks(flat, nseg), known


def _geos_faces(parts, core, cparts, cown, p, nrm, t, ray_part, sel):
    """Faces of parts ``sel`` by GEOS: lines noded (snap rounding where that fails) and polygonized."""
    P = len(parts)
    want = np.zeros(P, bool)
    want[sel] = True
    rk = want[ray_part]
    end = p[rk] + (t[rk] + OVERSHOOT)[:, None] * nrm[rk]
    rays = shapely.linestrings(np.stack([p[rk] - OVERSHOOT * nrm[rk], end], axis=1))  # crossing, not touching
    bnd = shapely.get_parts(shapely.boundary(parts[sel]), return_index=True)
    ck = want[cown]
    cb = shapely.get_parts(shapely.boundary(cparts[ck]), return_index=True)
    lines = np.r_[bnd[0], cb[0], rays]
    lpart = np.r_[sel[bnd[1]], cown[ck][cb[1]], ray_part[rk]]
    o = np.argsort(lpart, kind="stable")
    has = np.unique(lpart)
    ml = shapely.multilinestrings(lines[o], indices=np.searchsorted(has, lpart[o]))
    coll = shapely.polygonize(_node(ml).reshape(-1, 1), axis=-1)
    faces, fi = shapely.get_parts(np.asarray(coll).ravel(), return_index=True)
    fpart = has[fi]
    pt = shapely.point_on_surface(faces)
    inpart = shapely.area(faces) > 0
    shapely.prepare(parts)
    inpart &= shapely.contains_properly(parts[fpart], pt)
    faces, fpart, pt = faces[inpart], fpart[inpart], pt[inpart]
    inner = np.zeros(len(faces), bool)
    has_core = np.zeros(P, bool)
    has_core[cown] = True
    cq = np.flatnonzero(has_core[fpart])
    if len(cq):
        shapely.prepare(core)
        inner[cq] = shapely.contains_properly(core[fpart[cq]], pt[cq])
    return faces, fpart, inner


# -- faces and merges -----------------------------------------------------------------------------


def _neighbours(faces, fpart, want=None):
    """Pairs of faces (of one part) sharing boundary, and the length they share (m).

    Faces of one polygonize call share their edges vertex for vertex, so an
    edge is shared when the same two points bound a segment of both.  Only
    the faces of ``want`` (default all) and those near them are looked at.
    """
    sel = np.arange(len(faces))
    if want is not None:  # the wanted faces and those whose boxes meet theirs
        w = np.flatnonzero(want)
        # the tree on the few wanted faces, asked by all (the same pairs as the other way round, for a
        # tree of a few boxes instead of one of every face)
        near = shapely.STRtree(faces[w]).query(faces)[0] if len(w) else np.zeros(0, np.int64)
        sel = np.unique(np.r_[w, near])
    p0, p1, idx, _ = ring_segments(faces[sel])
    if len(idx) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    idx = sel[idx]
    _, vid = merge_points(np.r_[p0, p1])
    a, b = vid[: len(idx)], vid[len(idx) :]
    key = np.minimum(a, b) * (int(vid.max()) + 1) + np.maximum(a, b)
    part = fpart[idx]
    o = np.lexsort((part, key))
    same = (key[o][1:] == key[o][:-1]) & (part[o][1:] == part[o][:-1])
    i, j = idx[o][:-1][same], idx[o][1:][same]
    ln = np.hypot(*(p1 - p0)[o][:-1][same].T)
    keep = i != j
    i, j, ln = i[keep], j[keep], ln[keep]
    # both directions, summed per pair
    ii, jj, ll = np.r_[i, j], np.r_[j, i], np.r_[ln, ln]
    if len(ii) == 0:
        return ii, jj, ll
    pk = ii * len(faces) + jj
    o = argsort_int(pk)
    first = np.r_[True, pk[o][1:] != pk[o][:-1]]
    grp = np.cumsum(first) - 1
    return ii[o][first], jj[o][first], np.bincount(grp, weights=ll[o])


def _touching(faces, fpart, sel):
    """Neighbours of faces ``sel`` found geometrically (boundaries within 1 um), with the length shared."""
    if len(sel) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    j, qi = shapely.STRtree(faces[sel]).query(faces, predicate="dwithin", distance=1e-6)  # a tree of the few
    o = np.lexsort((j, qi))  # pairs by face sought, as asking the tree of all faces gave them
    qi, j = qi[o], j[o]
    i = sel[qi]
    ok = (i != j) & (fpart[i] == fpart[j])
    i, j = i[ok], j[ok]
    bi, bj = shapely.boundary(faces[i]), shapely.boundary(faces[j])
    ln = shapely.length(shapely.intersection(bi, shapely.buffer(bj, 1e-6, quad_segs=1)))
    return i, j, ln


def _merge_into(faces, small, group, fpart, rounds=4, strict=False, adj=None):
    """Faces flagged ``small`` joined to the neighbour sharing most boundary.

    Neighbours of the same ``group`` (street or interior) that are not
    small come first, then any not small, then small ones (which may then
    grow out of it in the next round); with ``strict`` only the same group.
    Faces of no area (under 1e-9 m2: rays meeting at a point) are dropped.
    Returns the faces (joined ones removed, their hosts grown), the mask of
    the input faces kept, and the number merged or dropped; a small face
    with no neighbour stays.  ``adj`` (pairs of faces and the length they
    share, when known, e.g. from the face graph) spares looking for them.
    """
    faces = faces.copy()
    alive = shapely.area(faces) > 1e-9
    changed = np.zeros(len(faces), bool)
    merged = int((~alive).sum())
    small = small & alive
    if adj is not None:  # only small faces look for neighbours
        sel = small[adj[0]]
        adj = (adj[0][sel], adj[1][sel], adj[2][sel])
    for _ in range(rounds):
        todo = small & alive
        if not todo.any():
            break
        if adj is not None:
            i, j, ln = adj
            sel = alive[i] & alive[j]
            i, j, ln = i[sel], j[sel], ln[sel]
        else:
            live = np.flatnonzero(alive)
            i, j, ln = _neighbours(faces[live], fpart[live], todo[live])
            i, j = live[i], live[j]
        lonely = np.setdiff1d(np.flatnonzero(todo), i)
        if len(lonely):
            gi, gj, gl = _touching(faces, fpart, lonely)
            keep = alive[gj]
            i, j, ln = np.r_[i, gi[keep]], np.r_[j, gj[keep]], np.r_[ln, gl[keep]]
        ok = todo[i] & alive[j] & (ln > 0)
        if strict:
            ok &= group[i] == group[j]
        i, j, ln = i[ok], j[ok], ln[ok]
        if len(i) == 0:
            break
        rank = np.where((group[i] == group[j]) & ~small[j], 0, np.where(~small[j], 1, 2))
        o = np.lexsort((j, -ln, rank, i))
        first = np.r_[True, i[o][1:] != i[o][:-1]]
        src, dst = i[o][first], j[o][first]
        go = ~np.isin(dst, src)  # a host that joins another this round waits
        src, dst = src[go], dst[go]
        if len(src) == 0:
            break
        # group by host: union of the host and all faces joining it
        g = np.lexsort((src, dst))
        src, dst = src[g], dst[g]
        hosts, cnt = np.unique(dst, return_counts=True)
        grid = np.full((len(hosts), int(cnt.max()) + 1), None, dtype=object)
        grid[:, 0] = faces[hosts]
        grid[np.repeat(np.arange(len(hosts)), cnt), 1 + ramp(cnt)] = faces[src]
        u = shapely.union_all(grid, axis=1)
        # a union GEOS got wrong (area lost: thin faces with nearly coincident edges) is redone snapped
        row = np.repeat(np.arange(len(hosts)), cnt)
        whole = shapely.area(faces[hosts]) + np.bincount(row, weights=shapely.area(faces[src]), minlength=len(hosts))
        outline = shapely.length(faces[hosts]) + np.bincount(
            row, weights=shapely.length(faces[src]), minlength=len(hosts)
        )
        wrong = np.flatnonzero(~kept_area(u, whole, outline))
        for q in wrong:  # snapped (a failing snap leaves the wrong union, refused below)
            try:
                u[q] = shapely.union_all(grid[q], grid_size=TOUCH)
            except shapely.errors.GEOSException:
                pass
        one = (shapely.get_type_id(u) == 3) & shapely.is_valid(u) & kept_area(u, whole, outline)
        faces[hosts[one]] = u[one]
        changed[hosts[one]] = True
        went = one[np.repeat(np.arange(len(hosts)), cnt)]
        gone = src[went]
        alive[gone] = False
        merged += len(gone)
        if adj is not None:  # the joined faces' neighbours are their host's now
            host = np.arange(len(faces))
            host[gone] = dst[went]
            ai, aj = adj[0], host[adj[1]]
            sel = alive[ai] & (ai != aj)
            adj = _pair_sums(ai[sel], aj[sel], adj[2][sel], len(faces))
        small = small.copy()
        small[hosts[one]] = False
    return faces[alive], alive, merged, changed[alive]


def _robust(func, *arrays):
    """``func`` over arrays (rows), with ``None`` where GEOS fails (only rows, not the whole call)."""
    try:
        return threaded(func, *arrays)
    except shapely.errors.GEOSException:
        out = np.empty(len(arrays[0]), dtype=object)
        for k in range(len(out)):  # rare: after a failure, to find the culprits
            try:
                out[k] = func(*(a[k : k + 1] for a in arrays))[0]
            except shapely.errors.GEOSException:
                out[k] = None
        return out


def _merge_interior(faces, fpart, inner, spacing, report):
    """Each interior face shared out among the street lots along it, so that every lot reaches a street.

    The interior's boundary is sampled every ``spacing`` (m, per face); each
    sample belongs to the street lot whose back edge it lies on, and each
    point of the interior goes to the lot of the nearest sample (Voronoi
    cells of the samples, clipped to the interior): lots from facing
    streets meet half way, near the interior's medial axis.  A part where
    a lot would come out in pieces keeps its interior as inner lots
    (counted in ``skeleton_merge_kept``).
    """
    ii = np.flatnonzero(inner)
    si = np.flatnonzero(~inner)
    F = faces[ii]
    dens = shapely.segmentize(F, spacing[ii])
    p0, p1, fidx, _ = ring_segments(dens)
    mids = 0.5 * (p0 + p1)
    owner = np.full(len(mids), -1, np.int64)
    if len(mids) and len(si):
        qi, li = shapely.STRtree(faces[si]).query(shapely.points(mids), predicate="dwithin", distance=1e-6)
        ok = fpart[si[li]] == fpart[ii[fidx[qi]]]
        qi, li = qi[ok], li[ok]
        o = np.lexsort((li, qi))
        f = np.r_[True, qi[o][1:] != qi[o][:-1]] if len(o) else np.zeros(0, bool)
        owner[qi[o][f]] = si[li[o][f]]
    keep = owner >= 0
    mids, fidx, owner = mids[keep], fidx[keep], owner[keep]
    # one sample per point of a face (Voronoi cells merge equal points)
    key = np.c_[fidx.astype(np.float64), mids]
    first = unique_rows(key)[0]
    first = np.sort(first)
    mids, fidx, owner = mids[first], fidx[first], owner[first]
    nf = np.bincount(fidx, minlength=len(ii))
    go = np.flatnonzero(nf >= 2)
    bad_part = np.zeros(int(fpart.max()) + 1, bool)
    bad_part[fpart[ii[nf < 2]]] = True  # an interior touching fewer than two samples stays inner
    sel = np.isin(fidx, go)
    mids, fidx, owner = mids[sel], fidx[sel], owner[sel]
    mp = shapely.multipoints(mids, indices=np.searchsorted(go, fidx))
    vor = shapely.voronoi_polygons(mp, extend_to=F[go], ordered=True)
    cells, ci = shapely.get_parts(vor, return_index=True)
    ok_count = np.bincount(ci, minlength=len(go)) == nf[go]
    bad_part[fpart[ii[go[~ok_count]]]] = True
    cell_ok = ok_count[ci]
    cells, cowner, cface = cells[cell_ok], owner[cell_ok], go[ci[cell_ok]]
    clipped = _robust(shapely.intersection, cells, F[cface])
    bad_part[fpart[ii[cface[shapely.is_missing(clipped)]]]] = True
    # each street lot with its cells
    o = np.lexsort((np.arange(len(cowner)), cowner))
    cowner, clipped = cowner[o], clipped[o]
    hosts, cnt = np.unique(cowner, return_counts=True)
    grid = np.full((len(hosts), int(cnt.max()) + 1 if len(cnt) else 1), None, dtype=object)
    grid[:, 0] = faces[hosts]
    grid[np.repeat(np.arange(len(hosts)), cnt), 1 + ramp(cnt)] = clipped
    grown = _robust(lambda g: shapely.union_all(g, axis=1), grid) if len(hosts) else np.empty(0, object)
    bad_part[fpart[hosts[shapely.is_missing(grown)]]] = True
    # a lot whose cells came out in pieces keeps the piece it stands in; the others join a neighbour
    multi = np.flatnonzero(shapely.get_type_id(grown) == 6)
    orphans = np.empty(0, object)
    opart = np.empty(0, np.int64)
    if len(multi):
        pieces, pi = shapely.get_parts(grown[multi], return_index=True)
        mine = shapely.intersects(pieces, shapely.point_on_surface(faces[hosts[multi[pi]]]))
        first = np.zeros(len(multi), bool)
        own_piece = np.full(len(multi), -1, np.int64)
        for_host = np.flatnonzero(mine)
        own_piece[pi[for_host[::-1]]] = for_host[::-1]  # the first piece holding the lot
        first[own_piece >= 0] = True
        bad_part[fpart[hosts[multi[~first]]]] = True
        grown[multi[first]] = pieces[own_piece[first]]
        rest = np.ones(len(pieces), bool)
        rest[own_piece[first]] = False
        orphans, opart = pieces[rest], fpart[hosts[multi[pi[rest]]]]
    new = faces.copy()
    new[hosts] = grown
    if len(orphans):  # the orphans join the lot they share most boundary with
        pool = np.r_[new[si], orphans]
        ppart = np.r_[fpart[si], opart]
        small = np.r_[np.zeros(len(si), bool), np.ones(len(orphans), bool)]
        merged, alive, _, _ = _merge_into(pool, small, np.zeros(len(pool), bool), ppart)
        if alive[len(si) :].any():  # an orphan found no neighbour: its part stays inner
            bad_part[opart[alive[len(si) :]]] = True
        new[si] = merged[: len(si)] if alive[: len(si)].all() else new[si]
    # every part's area must be kept (to 1e-9): else its interior stays inner
    P = int(fpart.max()) + 1
    before = np.bincount(fpart, weights=shapely.area(faces), minlength=P)
    after = np.bincount(fpart[si], weights=shapely.area(new[si]), minlength=P)
    bad_part |= np.abs(after - before) > 1e-9 * np.maximum(before, 1.0)
    bad_part &= np.bincount(fpart[ii], minlength=P) > 0
    report["skeleton_merge_kept"] = report.get("skeleton_merge_kept", 0) + int(bad_part.sum())
    use_new = ~bad_part[fpart]
    out = np.where(use_new, new, faces)
    stay = ~inner | bad_part[fpart]
    changed = np.zeros(len(faces), bool)
    changed[hosts] = True
    changed &= use_new
    return out[stay], fpart[stay], inner[stay], stay, changed[stay]

"""The straight skeleton of many simple polygons at once, by moving their wavefronts in numpy passes.

Every edge moves inward at unit speed; a wavefront vertex moves with the
velocity ``u`` that keeps it on both of its edges' lines (``n1 . u = n2 . u =
1``, so ``u = (n1 + n2) / (1 + n1 . n2)``).  Events, the earliest of each
polygon handled in one pass for all polygons together [1]_:

* **edge event**: an edge shrinks to nothing; its two vertices become one (a
  loop of three collapses to a point);
* **split event**: a reflex vertex reaches an edge of the wavefront; the loop
  splits in two there;
* **spike**: a vertex between two opposite edges (a wing the width of twice
  the time, collapsed all along its length) is a doubled segment: it is cut
  back to the nearer of its neighbours, the ridge drawn;
* a loop of two vertices is a last ridge segment.

Each vertex's trajectory and each ridge is an arc of the skeleton, in the
form CGAL's ``create_interior_straight_skeleton`` gives it (nodes, arcs),
which :mod:`sengine.nodes.export.skeleton_faces` turns into roofs and checks:
a polygon whose faces do not come out right is handed back to CGAL.  Holes
and polygons of more than :data:`MAX_VERTICES` vertices go to CGAL directly.

References
----------
.. [1] Felkel, P., Obdržálek, Š., "Straight skeleton implementation", Proceedings
   of the 14th Spring Conference on Computer Graphics, 210-218, 1998.
"""

from __future__ import annotations

import numpy as np

from .mesh import stable_argsort, unique_int

__all__ = ["wavefront_skeletons", "MAX_VERTICES"]

#: Polygons with more vertices go to CGAL (one event a polygon a pass, each pass's search quadratic in its
#: vertices: beyond this CGAL's exact skeleton is the quicker; 24 before sent 40 of 30,000 Liège buildings there).
MAX_VERTICES = 48
#: Below this ``1 + n1 . n2`` two edges count as opposite (a spike): within 0.008 degrees of it, which
#: over a wing 30 m long moves a node by 2 mm at most.
SPIKE = 1e-8
#: Tolerance (grid units) of the split-event test along the hit edge and of equal times.
TOL = 1e-6


def wavefront_skeletons(qk: np.ndarray, kstart: np.ndarray, poly_ring: np.ndarray, todo: np.ndarray):
    """Skeletons of the one-ring polygons ``todo`` (counter-clockwise rings of ``qk``).

    Returns rows, ids, edges (by id), edge types (2 on the outline), rows and
    edges per polygon, and which polygons of ``todo`` it gave up on (their
    counts are 0).
    """
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # events that never come: inf
        try:
            return _wavefront(qk, kstart, poly_ring, todo)
        except OverflowError:  # more wavefront vertices than the pool holds (never seen): all to CGAL
            n_poly = len(poly_ring) - 1
            e, z = np.empty(0, np.int64), np.zeros(n_poly, np.int64)
            return np.empty((0, 2)), e, np.empty((0, 2), np.int64), np.empty(0, np.int8), z, z.copy(), todo


def _wavefront(qk, kstart, poly_ring, todo):
    n_poly = len(poly_ring) - 1
    cnt = np.zeros(n_poly, np.int64)
    ecnt = np.zeros(n_poly, np.int64)
    todo = np.asarray(todo, np.int64)
    r = poly_ring[todo]
    ln = kstart[r + 1] - kstart[r]
    nv = int(ln.sum())
    if not nv:
        e = np.empty(0, np.int64)
        return np.empty((0, 2)), e, np.empty((0, 2), np.int64), np.empty(0, np.int8), cnt, ecnt, todo[:0]
    # the outline: edge i runs from vertex i to the next, all polygons in one array
    vid = np.repeat(kstart[r] - np.concatenate([[0], np.cumsum(ln)[:-1]]), ln) + np.arange(nv)
    xy = qk.take(vid, axis=0).astype(np.float64)
    vp = np.repeat(np.arange(len(todo)), ln)
    first = np.concatenate([[0], np.cumsum(ln)[:-1]])
    nxt = np.arange(1, nv + 1)
    nxt[first + ln - 1] = first
    prv = np.empty_like(nxt)
    prv[nxt] = np.arange(nv)
    d = xy.take(nxt, axis=0) - xy
    dl = np.hypot(d[:, 0], d[:, 1])
    D = d / np.where(dl > 0, dl, 1.0)[:, None]
    N = np.column_stack([-D[:, 1], D[:, 0]])
    C = (N * xy).sum(axis=1)
    Nx, Ny, Dx, Dy = N[:, 0].copy(), N[:, 1].copy(), D[:, 0].copy(), D[:, 1].copy()
    # the wavefront: a pool of vertices, the first nv the outline's
    cap = 8 * nv + 16
    P0 = np.zeros((cap, 2))
    T0 = np.zeros(cap)
    V = np.zeros((cap, 2))
    EL = np.zeros(cap, np.int64)
    ER = np.zeros(cap, np.int64)
    NX = np.zeros(cap, np.int64)
    PV = np.zeros(cap, np.int64)
    NODE = np.zeros(cap, np.int64)
    POLY = np.zeros(cap, np.int64)
    ALIVE = np.zeros(cap, bool)
    P0[:nv], EL[:nv], ER[:nv], NX[:nv], PV[:nv] = xy, prv, np.arange(nv), nxt, prv
    NODE[:nv], POLY[:nv], ALIVE[:nv] = np.arange(nv), vp, True
    used = nv
    node_xy = [xy]
    node_poly = [vp]
    n_nodes = nv
    arcs = []
    failed = np.zeros(len(todo), bool)
    failed[vp[dl == 0]] = True  # a repeated vertex: no edge line

    def velocity(el, er):
        n1, n2 = N.take(el, axis=0), N.take(er, axis=0)
        den = 1.0 + (n1 * n2).sum(axis=1)
        ok = den > SPIKE
        return np.where(ok[:, None], (n1 + n2) / np.where(ok, den, 1.0)[:, None], 0.0), ~ok

    V[:nv], spike0 = velocity(EL[:nv], ER[:nv])
    SPIKY = np.zeros(cap, bool)
    SPIKY[:nv] = spike0

    def pos(v, t):
        return P0.take(v, axis=0) + V.take(v, axis=0) * (t - T0[v])[:, None]

    def new_nodes(p, polys):
        nonlocal n_nodes
        ids = n_nodes + np.arange(len(p))
        node_xy.append(p)
        node_poly.append(polys)
        n_nodes += len(p)
        return ids

    def new_vertices(k):
        nonlocal used
        if used + k > cap:
            raise OverflowError
        ids = used + np.arange(k)
        used += k
        return ids

    def make(z, el, er, pv, nx, p, t, node, poly):
        EL[z], ER[z], PV[z], NX[z], T0[z], NODE[z], POLY[z] = el, er, pv, nx, t, node, poly
        ALIVE[z] = True
        NX[pv] = z
        PV[nx] = z
        V[z], SPIKY[z] = velocity(el, er)
        P0[z] = _meet(
            N.take(el, axis=0), N.take(er, axis=0), C[el] + t, C[er] + t, p
        )  # on both lines: no drift from event to event

    steps = 0
    limit = 6 * int(ln.max()) + 10
    while True:
        act = np.flatnonzero(ALIVE[:used])
        act = act[~failed[POLY[act]]]
        if not act.size:
            break
        steps += 1
        if steps > limit:
            failed[POLY[act]] = True
            break
        pa = POLY[act]
        busy = np.zeros(len(todo), bool)
        # 1. loops of two: the last ridge
        two = act[NX[NX[act]] == act]
        two = two[two < NX[two]]
        two = two[~_dup(POLY[two])]
        if two.size:
            a, b = two, NX[two]
            t = np.maximum(T0[a], T0[b])
            na = new_nodes(pos(a, t), POLY[a])
            nb = new_nodes(pos(b, t), POLY[b])
            arcs += [np.column_stack([NODE[a], na]), np.column_stack([NODE[b], nb]), np.column_stack([na, nb])]
            ALIVE[a] = ALIVE[b] = False
            busy[POLY[a]] = True
        # 2. spikes: cut back to the nearer neighbour
        sp = act[SPIKY[act] & ALIVE[act] & ~busy[pa]]
        sp = sp[~_dup(POLY[sp])]
        if sp.size:
            busy[POLY[sp]] = True
            _spikes(sp, P0, T0, NX, PV, EL, ER, NODE, POLY, ALIVE, pos, new_nodes, new_vertices, make, arcs)
        # 3. the earliest event of each remaining polygon
        free = act[~busy[pa] & ALIVE[act]]
        if not free.size:
            continue
        tnow = np.zeros(len(todo))
        pf = POLY[free]
        np.maximum.at(tnow, pf, T0[free])
        v, w = free, NX[free]
        ev_e = ER[v]
        dx, dy = Dx[ev_e], Dy[ev_e]
        T0v, T0w = T0[v], T0[w]
        Pv, Pw, Vv, Vw = P0.take(v, axis=0), P0.take(w, axis=0), V.take(v, axis=0), V.take(w, axis=0)
        A = (dx * (Pw[:, 0] - Vw[:, 0] * T0w) + dy * (Pw[:, 1] - Vw[:, 1] * T0w)) - (
            dx * (Pv[:, 0] - Vv[:, 0] * T0v) + dy * (Pv[:, 1] - Vv[:, 1] * T0v)
        )
        B = dx * (Vw[:, 0] - Vv[:, 0]) + dy * (Vw[:, 1] - Vv[:, 1])
        tn = tv = tnow[pf]
        # when and where the edge's line and its neighbours' meet: three lines, no drift
        xe, ye, t3 = _concurrent(EL[v], ev_e, ER[w], Nx, Ny, C)
        te = np.where((B < -1e-12) & np.isfinite(t3), t3, np.inf)
        gone = A + B * tn <= TOL  # an edge already gone: now, where its vertices are (set below)
        te = np.where(gone, tn, te)
        te = np.maximum(te, tn)
        # split events: reflex vertices against the other edges of their polygon
        fl, fr = EL[free], ER[free]
        reflex = free[(Dx[fl] * Dy[fr] - Dy[fl] * Dx[fr]) < 0]
        best_t = np.full(len(todo), np.inf)
        np.minimum.at(best_t, pf, te)
        ts_v = ts_w = np.empty(0, np.int64)
        ts, tsx = np.empty(0), np.empty((0, 2))
        if reflex.size:
            order = stable_argsort(POLY[free])
            fs = free[order]
            k = np.bincount(POLY[fs], minlength=len(todo))
            start = np.concatenate([[0], np.cumsum(k)[:-1]])
            kr = k[POLY[reflex]]
            rv = np.repeat(reflex, kr)
            j = np.arange(kr.sum()) - np.repeat(np.cumsum(kr) - kr, kr)
            rw = fs[np.repeat(start[POLY[reflex]], kr) + j]
            # the tests in stages, the cheap ones first, each on the pairs the one before kept; on the
            # components, not (n, 2) rows (one gather each, no row sums: the same sums in the same order)
            e = ER[rw]
            gain = Nx[e] * V[rv, 0] + Ny[e] * V[rv, 1]
            keep = (rw != rv) & (NX[rw] != rv) & (gain - 1.0 < -1e-12)  # it gains on the edge
            rv, rw, e = rv[keep], rw[keep], e[keep]
            x, y, t = _concurrent(EL[rv], ER[rv], e, Nx, Ny, C)
            tn = tnow[POLY[rv]]
            # a split no earlier than the polygon's edge event is never taken (it must come strictly
            # earlier, by TOL): such pairs skip the extent test
            keep = (t >= tn - TOL) & np.isfinite(t)
            t = np.maximum(t, tn)
            keep &= t < best_t[POLY[rv]] - TOL
            rv, rw, e, x, y, t = rv[keep], rw[keep], e[keep], x[keep], y[keep], t[keep]
            dx, dy = Dx[e], Dy[e]
            s = dx * x + dy * y
            w2 = NX[rw]
            P, Q, dt = P0.take(rw, axis=0), V.take(rw, axis=0), t - T0[rw]
            s0 = dx * (P[:, 0] + Q[:, 0] * dt) + dy * (P[:, 1] + Q[:, 1] * dt)
            P, Q, dt = P0.take(w2, axis=0), V.take(w2, axis=0), t - T0[w2]
            s1 = dx * (P[:, 0] + Q[:, 0] * dt) + dy * (P[:, 1] + Q[:, 1] * dt)
            ok = (s >= s0 - TOL) & (s <= s1 + TOL)
            ts_v, ts_w, ts, tsx = rv[ok], rw[ok], t[ok], np.column_stack([x[ok], y[ok]])
            split_best = np.full(len(todo), np.inf)
            np.minimum.at(split_best, POLY[ts_v], ts)
        else:
            split_best = np.full(len(todo), np.inf)
        # each polygon: its earliest edge event, unless a split comes strictly earlier
        use_split = split_best < best_t - TOL
        ev = np.flatnonzero((te <= best_t[pf]) & ~use_split[pf])
        ev = ev[~_dup(pf[ev])]
        ev_x = np.column_stack([xe[ev], ye[ev]])
        g = ev[gone[ev]]
        if g.size:
            ev_x[gone[ev]] = (pos(v[g], tv[g]) + pos(w[g], tv[g])) / 2.0
        ev = v[ev]
        pick = (ts <= split_best[POLY[ts_v]]) & use_split[POLY[ts_v]]
        sv_, sw_, st_, sx_ = ts_v[pick], ts_w[pick], ts[pick], tsx[pick]
        first_s = ~_dup(POLY[sv_])
        sv_, sw_, st_, sx_ = sv_[first_s], sw_[first_s], st_[first_s], sx_[first_s]
        stuck = np.zeros(len(todo), bool)
        stuck[pf] = True
        stuck &= ~np.isfinite(np.minimum(best_t, split_best))
        failed |= stuck
        ok = ~failed[POLY[ev]]
        ev, ev_x = ev[ok], ev_x[ok]
        if ev.size:
            _edge_events(
                ev, best_t[POLY[ev]], ev_x, NX, PV, EL, ER, NODE, POLY, ALIVE, new_nodes, new_vertices, make, arcs
            )
        if sv_.size:
            ok = ~failed[POLY[sv_]]
            _splits(
                sv_[ok],
                sw_[ok],
                st_[ok],
                sx_[ok],
                NX,
                PV,
                EL,
                ER,
                NODE,
                POLY,
                ALIVE,
                new_nodes,
                new_vertices,
                make,
                arcs,
            )
    # the polygons' rows and edges, in CGAL's form: outline vertices first (ids 0..n-1), then nodes
    nxy = np.concatenate(node_xy)
    npoly = np.concatenate(node_poly)
    arc = np.concatenate(arcs) if arcs else np.empty((0, 2), np.int64)
    keep_poly = ~failed
    order = stable_argsort(npoly)
    order = order[keep_poly[npoly[order]]]
    local_id = np.empty(len(nxy), np.int64)
    k = np.bincount(npoly[order], minlength=len(todo))
    local_id[order] = np.arange(len(order)) - np.repeat(np.concatenate([[0], np.cumsum(k)[:-1]]), k)
    arc = arc[keep_poly[npoly[arc[:, 0]]]]
    outline = np.column_stack([np.arange(nv), nxt])
    outline = outline[keep_poly[vp]]
    edges = np.concatenate([outline, arc])
    types = np.concatenate([np.full(len(outline), 2, np.int8), np.ones(len(arc), np.int8)])
    epoly = npoly[edges[:, 0]]
    eo = stable_argsort(epoly)
    cnt[todo] = k
    ecnt[todo] = np.bincount(epoly, minlength=len(todo))
    return nxy[order], local_id[order], local_id[edges[eo]], types[eo], cnt, ecnt, todo[failed]


def _concurrent(l1, l2, l3, Nx, Ny, C):
    """The point ``(x, y)`` and time ``t`` at which the moving lines ``l1``, ``l2``, ``l3`` meet (t inf: never).

    ``Nx``, ``Ny`` are the lines' unit normals by component, ``C`` their offsets
    (``N . p = C + t`` at time ``t``).
    """
    n1x, n1y = Nx[l1], Ny[l1]
    a1, b1 = n1x - Nx[l2], n1y - Ny[l2]
    a2, b2 = n1x - Nx[l3], n1y - Ny[l3]
    c1 = C[l1]
    r1, r2 = c1 - C[l2], c1 - C[l3]
    det = a1 * b2 - a2 * b1
    ok = np.abs(det) > 1e-9
    det = np.where(ok, det, 1.0)
    x = (r1 * b2 - r2 * b1) / det
    y = (a1 * r2 - a2 * r1) / det
    t = np.where(ok, n1x * x + n1y * y - c1, np.inf)
    return x, y, t


def _meet(n1, n2, c1, c2, p):
    """Where the lines ``n1 . x = c1`` and ``n2 . x = c2`` cross; ``p`` where they are (nearly) parallel."""
    det = n1[:, 0] * n2[:, 1] - n1[:, 1] * n2[:, 0]
    ok = np.abs(det) > 1e-3
    det = np.where(ok, det, 1.0)
    x = (c1 * n2[:, 1] - c2 * n1[:, 1]) / det
    y = (n1[:, 0] * c2 - n2[:, 0] * c1) / det
    return np.where(ok[:, None], np.column_stack([x, y]), p)


def _dup(p: np.ndarray) -> np.ndarray:
    """True for every element whose value came before (keeps the first of each polygon)."""
    if not len(p):
        return np.zeros(0, bool)
    _, first = unique_int(p, return_index=True)
    out = np.ones(len(p), bool)
    out[first] = False
    return out


def _edge_events(v, t, X, NX, PV, EL, ER, NODE, POLY, ALIVE, new_nodes, new_vertices, make, arcs):
    w = NX[v]
    nn = new_nodes(X, POLY[v])
    arcs += [np.column_stack([NODE[v], nn]), np.column_stack([NODE[w], nn])]
    u = NX[w]
    tri = NX[u] == v
    if tri.any():  # a loop of three collapses to its point
        arcs.append(np.column_stack([NODE[u[tri]], nn[tri]]))
        ALIVE[u[tri]] = False
    ALIVE[v] = ALIVE[w] = False
    g = ~tri
    if g.any():
        z = new_vertices(int(g.sum()))
        make(z, EL[v[g]], ER[w[g]], PV[v[g]], u[g], X[g], t[g], nn[g], POLY[v[g]])


def _splits(v, w, t, X, NX, PV, EL, ER, NODE, POLY, ALIVE, new_nodes, new_vertices, make, arcs):
    nn = new_nodes(X, POLY[v])
    arcs.append(np.column_stack([NODE[v], nn]))
    w2 = NX[w]
    e = ER[w]
    pv, nx = PV[v], NX[v]
    el, er = EL[v], ER[v]
    ALIVE[v] = False
    z1 = new_vertices(len(v))
    z2 = new_vertices(len(v))
    make(z1, el, e, pv, w2, X, t, nn, POLY[v])
    make(z2, e, er, w, nx, X, t, nn, POLY[v])


def _spikes(z, P0, T0, NX, PV, EL, ER, NODE, POLY, ALIVE, pos, new_nodes, new_vertices, make, arcs):
    t = T0[z]
    p, q = PV[z], NX[z]
    X = P0[z]
    Pp, Pq = pos(p, t), pos(q, t)
    dp = np.hypot(*(Pp - X).T)
    dq = np.hypot(*(Pq - X).T)
    same = np.abs(dp - dq) <= TOL
    left = ~same & (dp < dq)
    right = ~same & ~left
    if same.any():
        zs, ps, qs = z[same], p[same], q[same]
        Y = (Pp[same] + Pq[same]) / 2.0
        ny = new_nodes(Y, POLY[zs])
        arcs += [np.column_stack([NODE[zs], ny]), np.column_stack([NODE[ps], ny]), np.column_stack([NODE[qs], ny])]
        ALIVE[zs] = ALIVE[ps] = ALIVE[qs] = False
        three = PV[ps] == qs
        g = ~three
        if g.any():
            y = new_vertices(int(g.sum()))
            make(y, EL[ps[g]], ER[qs[g]], PV[ps[g]], NX[qs[g]], Y[g], t[same][g], ny[g], POLY[zs[g]])
    if left.any():
        zs, ps = z[left], p[left]
        ny = new_nodes(Pp[left], POLY[zs])
        arcs += [np.column_stack([NODE[zs], ny]), np.column_stack([NODE[ps], ny])]
        ALIVE[zs] = ALIVE[ps] = False
        y = new_vertices(len(zs))
        make(y, EL[ps], ER[zs], PV[ps], q[left], Pp[left], t[left], ny, POLY[zs])
    if right.any():
        zs, qs = z[right], q[right]
        ny = new_nodes(Pq[right], POLY[zs])
        arcs += [np.column_stack([NODE[zs], ny]), np.column_stack([NODE[qs], ny])]
        ALIVE[zs] = ALIVE[qs] = False
        y = new_vertices(len(zs))
        make(y, EL[zs], ER[qs], p[right], NX[qs], Pq[right], t[right], ny, POLY[zs])

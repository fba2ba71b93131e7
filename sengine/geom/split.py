"""Many polygons cut by lines at once, on flat vertex arrays.

A :class:`sengine.geom.ringset.RingSet` holds polygons (with holes) as flat
numpy arrays, with one mark per edge (e.g. "lies on the original outline").
:func:`split` cuts every polygon by its own line in one vectorized pass and
keeps the marks: pieces of an edge keep its mark, the new edges along the
cut line get ``chord_flag``.  Shapely geometries are made only at the end
(:meth:`RingSet.polygons`), once, which is what makes recursive subdivision
of hundreds of thousands of pieces cheap: no GEOS overlay per piece.

The cut is exact for any simple polygon, convex or not, with holes: the
crossings of the line with all rings are sorted along the line and paired
(even-odd rule), each pair is a chord of the polygon, and the pieces are the
cycles of "follow the boundary, jump along the chord".  Vertices lying
exactly on the line count as being on its left (symbolic perturbation), so
degenerate cuts through vertices or along edges give valid pieces; a cut
whose crossings do not alternate (rounding on nearly tangent lines) is
reported as failed rather than guessed.

References
----------
The even-odd chord pairing is the classic polygon/line split, e.g.
D. Eberly, "Clipping a polygon against a line" (Geometric Tools); the
perturbation rule is H. Edelsbrunner and E. Mücke's "simulation of
simplicity" (ACM TOG 9(1), 1990) applied to the cut line.
"""

from __future__ import annotations

import numpy as np
import shapely

from .ringset import RingSet, _first_of, _ramp

__all__ = ["RingSet", "split", "cut_lengths"]  # RingSet re-exported: cut and pieces come together

# -- the cut ------------------------------------------------------------------------------


def _signed(rs: RingSet, point, direction):
    """Signed distance ``s`` (left > 0) and abscissa ``t`` of every vertex on its polygon's line."""
    point = np.asarray(point, np.float64).reshape(-1, 2)
    d = np.asarray(direction, np.float64).reshape(-1, 2)
    d = d / np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-300)[:, None]
    vp = rs.vertex_poly()
    q = rs.xy - point[vp]
    dv = d[vp]
    s = q[:, 1] * dv[:, 0] - q[:, 0] * dv[:, 1]
    t = q[:, 0] * dv[:, 0] + q[:, 1] * dv[:, 1]
    return s, t, vp, d


def cut_lengths(rs: RingSet, point, direction):
    """What a cut would do, without cutting: crossings and marked length per side.

    Parameters
    ----------
    rs : RingSet
    point, direction : array_like (n, 2)
        Each polygon's cut line, as for :func:`split`.

    Returns
    -------
    crossings : ndarray of int64 (n,)
        Number of boundary crossings; 2 means the cut gives exactly one
        piece on each side.
    left, right : ndarray (n,)
        Length of marked edges (m) left and right of the line, i.e. the
        marked length each side's pieces will share.
    """
    s, t, vp, _ = _signed(rs, point, direction)
    pos = s >= 0.0
    nx = rs.next_vertex()
    crossing = pos != pos[nx]
    ln = rs.edge_lengths()
    sn = s[nx]
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = np.where(crossing, s / (s - sn), 1.0)  # share of the edge on its first vertex's side
    w = np.where(rs.flag, ln, 0.0)
    # an edge lying on the line goes with the side its interior is on (left when it runs along the line)
    on_line = (s == 0.0) & (sn == 0.0)
    pos = np.where(on_line, t[nx] > t, pos)
    first_left = np.where(pos, lam, 1.0 - lam) * w
    left = np.bincount(vp, weights=first_left, minlength=rs.n)
    right = np.bincount(vp, weights=w, minlength=rs.n) - left
    return np.bincount(vp, weights=crossing, minlength=rs.n).astype(np.int64), left, right


def split(rs: RingSet, point, direction, *, chord_flag: bool = False, touch_tol: float = 1e-9):
    """Cut every polygon of ``rs`` by its own line.

    Parameters
    ----------
    rs : RingSet
        ``n`` polygons.
    point, direction : array_like (n, 2)
        A point of each polygon's cut line and its direction (any length).
    chord_flag : bool
        Mark of the new edges along the cut.
    touch_tol : float
        Polygons with a vertex this close to their line (m), and polygons
        with holes, have their pieces checked with GEOS (``is_valid``): a
        cut through vertices or along edges, or through a hole touching its
        shell, can leave pieces that touch themselves.

    Returns
    -------
    pieces : RingSet
        The pieces: all left ones, then all right ones (``parent`` and
        ``side`` tell whose and which; a polygon's pieces do not depend on
        the other polygons of the call).
    parent : ndarray of int64
        Polygon each piece comes from.
    side : ndarray of int8
        1 left of the directed line, 0 right of it.
    failed : ndarray of bool (n,)
        Polygons whose crossings could not be paired (nearly tangent cuts)
        or whose pieces would touch themselves or have a spike along the
        line (a cut along an edge); they give no pieces.  A polygon
        the line misses gives itself as its only piece.
    """
    n = rs.n
    point = np.asarray(point, np.float64).reshape(-1, 2)
    s, t, vp, d = _signed(rs, point, direction)
    pos = s >= 0.0  # on the line counts as left
    nx = rs.next_vertex()
    ce = np.flatnonzero(pos != pos[nx])  # edges crossing the line
    a, b = ce, nx[ce]
    sa, sb = s[a], s[b]
    lam = sa / (sa - sb)
    mu = sb / (sb - sa)  # 1 - lam, exact 0 when b is on the line
    near_a = lam <= 0.5
    cxy = np.where(
        near_a[:, None], rs.xy[a] + lam[:, None] * (rs.xy[b] - rs.xy[a]), rs.xy[b] + mu[:, None] * (rs.xy[a] - rs.xy[b])
    )
    ct = np.where(near_a, t[a] + lam * (t[b] - t[a]), t[b] + mu * (t[a] - t[b]))
    leaving = pos[a]  # the edge goes from left to right
    # order along the perturbed line s = -eps: ties at a vertex broken by the other end
    tp, tq = np.where(leaving, t[a], t[b]), np.where(leaving, t[b], t[a])
    key = (tq - tp) / np.abs(sa - sb)
    cp = vp[a]
    # crossings come grouped by polygon (edges are in vertex order); sort each group along the
    # line: a swap for the common pair, a lexsort for polygons crossed more than twice
    C = len(ce)
    order = np.arange(C)
    ncr = np.bincount(cp, minlength=n)
    first = np.flatnonzero(np.r_[True, cp[1:] != cp[:-1]]) if C else np.zeros(0, np.int64)
    two = first[ncr[cp[first]] == 2]
    swap = (ct[two + 1] < ct[two]) | ((ct[two + 1] == ct[two]) & (key[two + 1] < key[two]))
    order[two[swap]], order[two[swap] + 1] = two[swap] + 1, two[swap]
    many = np.flatnonzero(ncr[cp] > 2)
    if len(many):
        order[many] = many[np.lexsort((key[many], ct[many], cp[many]))]
    cstart = _first_of(cp[order], n)
    rank = np.arange(C) - cstart[cp[order]]
    ok = (rank % 2 == 0) == leaving[order]
    failed = np.zeros(n, bool)
    failed[cp[order][~ok]] = True
    if failed.any():
        keep = ~failed
        sub = rs.take(keep)
        idx = np.flatnonzero(keep)
        pieces, parent, side, f2 = split(sub, point[keep], d[keep], chord_flag=chord_flag, touch_tol=touch_tol)
        failed[idx[f2]] = True
        return pieces, idx[parent], side, failed
    partner = np.empty(C, np.int64)
    partner[order] = order[np.where(rank % 2 == 0, np.arange(C) + 1, np.arange(C) - 1)]
    cross_at = np.full(len(rs.xy), -1, np.int64)
    cross_at[ce] = np.arange(C)
    # a chord running along marked edges that lie on the line keeps their mark
    chord = np.full(C, bool(chord_flag))
    on_line = np.flatnonzero((s == 0.0) & (s[nx] == 0.0) & rs.flag)
    if len(on_line):
        lo_i = order[rank % 2 == 0]  # first crossing of each chord
        hi_i = partner[lo_i]
        mid = 0.5 * (ct[lo_i] + ct[hi_i])
        ta, tb = t[on_line], t[nx[on_line]]
        e_lo, e_hi, e_p = np.minimum(ta, tb), np.maximum(ta, tb), vp[on_line]
        for k in range(len(on_line)):  # rare: cuts along marked edges
            hit = (cp[lo_i] == e_p[k]) & (mid > e_lo[k]) & (mid < e_hi[k])
            chord[lo_i[hit]] = True
            chord[hi_i[hit]] = True
    touch = np.zeros(n, bool)
    touch[vp[np.abs(s) <= touch_tol]] = True
    # without vertices on the line and without holes every cycle is a piece: no clean-up needed
    general = touch | (np.bincount(rs.poly, minlength=n) > 1)
    out = [_side(rs, left, pos, cross_at, cxy, leaving, partner, chord, general) for left in (True, False)]
    pieces = RingSet.concat([o[0] for o in out])
    parent = np.concatenate([o[1] for o in out])
    side = np.concatenate([np.full(len(o[1]), 1 if left else 0, np.int8) for o, left in zip(out, (True, False))])
    bad = np.zeros(n, bool)
    for o in out:
        bad |= o[2]
    # A cut through vertices or along edges may leave pieces that touch
    # themselves on the line (zero-width bridges) or run out and back along
    # it (spikes GEOS calls valid when rounding leaves them 1e-15 m wide),
    # and cutting open a hole that touches its shell leaves a ring through
    # that point twice: check the pieces of those few polygons (``general``).
    check = np.flatnonzero(general[parent])
    if len(check):
        sub = pieces.take(check)
        spiked = np.bincount(sub.vertex_poly(), weights=sub.spike_tips(touch_tol), minlength=sub.n) > 0
        twice = _twice_on_line(sub, point[parent[check]], d[parent[check]], touch_tol)
        bad[parent[check[spiked | twice | ~shapely.is_valid(sub.polygons())]]] = True
    if bad.any():
        keep = ~bad[parent]
        pieces = pieces.take(keep)
        parent, side = parent[keep], side[keep]
        failed |= bad
    return pieces, parent, side, failed


def _twice_on_line(rs: RingSet, point, direction, tol: float) -> np.ndarray:
    """Polygons whose boundary runs twice over some stretch of their line (n,) bool.

    Edges within ``tol`` (m) of the line at both ends are projected onto it;
    two of one polygon that overlap by more than ``tol`` make a slit of zero
    width: a piece reaching out along the line and back.  GEOS calls it valid
    when rounding leaves it 1e-15 m wide (a cut along an edge of a turned
    polygon), but the next cut across it makes a piece that touches itself.
    A spike (:meth:`RingSet.spike_tips`) is the slit whose two edges meet.
    """
    s, t, vp, _ = _signed(rs, point, direction)
    nx = rs.next_vertex()
    e = np.flatnonzero((np.abs(s) <= tol) & (np.abs(s[nx]) <= tol))
    out = np.zeros(rs.n, bool)
    many = np.flatnonzero(np.bincount(vp[e], minlength=rs.n) > 1)
    for k in many:  # rare: polygons with two or more edges on their line
        mine = e[vp[e] == k]
        lo, hi = np.minimum(t[mine], t[nx[mine]]), np.maximum(t[mine], t[nx[mine]])
        o = np.argsort(lo, kind="stable")
        lo, reach = lo[o], np.maximum.accumulate(hi[o])
        out[k] = bool((lo[1:] < reach[:-1] - tol).any())
    return out


def _side(rs, left, pos, cross_at, cxy, leaving, partner, chord_flag, general):
    """Pieces of every polygon on one side of its line: (RingSet, parent, bad).

    ``chord_flag`` is the mark of the chord leaving each crossing.  Unless
    ``general`` (per polygon: vertices on its line, or holes), every cycle
    is a piece.
    """
    R = len(rs.poly)
    on = pos if left else ~pos
    has_c = cross_at >= 0
    cnt = on.astype(np.int64) + has_c
    off = np.cumsum(cnt) - cnt
    M = int(cnt.sum())
    if M == 0:
        return RingSet.concat([]), np.zeros(0, np.int64), np.zeros(rs.n, bool)
    # nodes: kept vertices, then (same slot + 1) the crossing on the edge leaving them
    vnode = off[on]
    cnode = (off + on)[has_c]
    cidx = cross_at[has_c]
    nxy = np.empty((M, 2))
    nxy[vnode] = rs.xy[on]
    nxy[cnode] = cxy[cidx]
    exits = leaving[cidx] == left  # the boundary leaves this side here
    nflag = np.empty(M, bool)
    nflag[vnode] = rs.flag[on]
    nflag[cnode] = np.where(exits, chord_flag[cidx], rs.flag[has_c])
    nring = np.repeat(rs.ring, cnt)
    node_of_c = np.empty(len(partner), np.int64)
    node_of_c[cidx] = cnode
    is_entry = np.zeros(M, bool)
    is_entry[cnode[~exits]] = True
    rstart = _first_of(nring, R)
    rlen = np.diff(rstart)
    k = np.arange(M) - rstart[nring]  # position in the ring's node sequence
    n_entry = np.bincount(nring[is_entry], minlength=R)
    crossed = n_entry[nring] > 0
    # runs: from an entry to the next exit of the same ring (cyclic)
    run_off = np.cumsum(n_entry) - n_entry
    ce_cum = np.cumsum(is_entry) - np.r_[0, np.cumsum(is_entry)][rstart[nring]]  # entries so far in ring
    run = np.where(crossed, run_off[nring] + (ce_cum - 1) % np.maximum(n_entry[nring], 1), -1)
    nruns = int(n_entry.sum())
    entry_nodes = np.flatnonzero(is_entry)
    run_entry_k = np.zeros(max(nruns, 1), np.int64)
    run_entry_k[run[entry_nodes]] = k[entry_nodes]
    pos_in = np.where(crossed, (k - run_entry_k[np.maximum(run, 0)]) % np.maximum(rlen[nring], 1), k)
    next_run = np.empty(nruns, np.int64)
    next_run[run[cnode[exits]]] = run[node_of_c[partner[cidx[exits]]]]
    runs_of = np.bincount(rs.poly, weights=n_entry, minlength=rs.n).astype(np.int64)
    rep, rank = _cycles(next_run, int(runs_of.max()) if rs.n else 0)
    if nruns == 0:  # nothing crossed: keep the indexing below valid
        rep, rank = np.zeros(1, np.int64), np.zeros(1, np.int64)
    # cycle key: crossed nodes by their cycle's first run, uncrossed rings after all of them
    cyc = np.where(crossed, rep[np.maximum(run, 0)], nruns + nring)
    par_node = rs.poly[nring]
    # A polygon with at most one run has its cycles (the run, uncrossed rings)
    # each in one piece of the node sequence, in order; only the others are sorted.
    o = np.arange(M)
    cx = np.flatnonzero(runs_of[par_node] > 1)
    if len(cx):
        rk = rank[run[cx]]
        o[cx] = cx[np.lexsort((pos_in[cx], rk, cyc[cx], par_node[cx]))]
    cyc, par_node = cyc[o], par_node[o]
    newc = np.r_[True, cyc[1:] != cyc[:-1]]
    ncyc = int(newc.sum())
    # each cycle a ring (and a polygon of its own) until shells and holes are known
    cs = RingSet(nxy[o], np.cumsum(newc) - 1, nflag[o], np.arange(ncyc), ncyc)
    cpar = par_node[newc]
    bad = np.zeros(rs.n, bool)
    gen = general[cpar]
    if not gen.any():
        return cs, cpar, bad
    # cycles of polygons with vertices on the line or holes: clean, drop flat ones, give holes to shells
    easy = cs.take(~gen)
    cs, cpar = cs.take(gen), cpar[gen]
    hard, hpar = _pieces(cs.cleaned(), cpar, bad)
    return RingSet.concat([easy, hard]), np.r_[par_node[newc][~gen], hpar], bad


def _pieces(cs, cyc_par, bad):
    """Pieces from cleaned cycles (one polygon per cycle): shells with their holes, flat ones dropped."""
    cpar = cyc_par[cs.poly]
    ar = cs.ring_areas()
    size = np.zeros(len(cpar))
    if len(cpar):
        st = _first_of(cs.ring, len(cpar))[:-1]
        size = np.max(np.maximum.reduceat(cs.xy, st) - np.minimum.reduceat(cs.xy, st), axis=1)
    flat = np.abs(ar) <= 1e-10 * size * size  # collinear leftovers of cuts along edges
    shell_ids = np.flatnonzero((ar > 0) & ~flat)
    hole_ids = np.flatnonzero((ar < 0) & ~flat)
    if len(hole_ids) == 0:
        out = RingSet(cs.xy, cs.ring, cs.flag, np.arange(len(cpar)), len(cpar))
        return (out if len(shell_ids) == len(cpar) else out.take(shell_ids)), cpar[shell_ids]
    owner = np.full(len(cpar), -1, np.int64)
    owner[shell_ids] = np.arange(len(shell_ids))
    owner[hole_ids] = _hole_owner(cs, cpar, shell_ids, hole_ids, bad)
    # pieces: each shell then its holes
    ro = np.lexsort((ar < 0, owner))
    ro = ro[owner[ro] >= 0]
    vstart = _first_of(cs.ring, len(cpar))
    vcnt = np.diff(vstart)[ro]
    vsel = np.repeat(vstart[ro], vcnt) + _ramp(vcnt)
    out = RingSet(cs.xy[vsel], np.repeat(np.arange(len(ro)), vcnt), cs.flag[vsel], owner[ro], len(shell_ids))
    return out, cpar[shell_ids]


def _cycles(nxt: np.ndarray, maxlen: int) -> tuple[np.ndarray, np.ndarray]:
    """Cycles of a permutation whose cycles have at most ``maxlen`` elements.

    Returns each element's cycle representative (its smallest member, by
    pointer doubling) and its rank along the cycle from the representative.
    """
    R = len(nxt)
    rep = np.arange(R)
    if R == 0:
        return rep, np.zeros(0, np.int64)
    j = nxt.copy()
    span = 1
    while span < maxlen:  # rep = min over the next 2 * span elements
        rep = np.minimum(rep, rep[j])
        j = j[j]
        span *= 2
    rank = np.zeros(R, np.int64)
    heads = np.flatnonzero(rep == np.arange(R))
    cur = nxt[heads]
    r = 0
    while True:
        act = cur != heads
        cur, heads = cur[act], heads[act]
        if len(cur) == 0:
            break
        r += 1
        rank[cur] = r
        cur = nxt[cur]
    return rep, rank


def _hole_owner(cs, cpar, shell_ids, hole_ids, bad):
    """Shell (index into ``shell_ids``) holding each hole ring: same parent, point in polygon."""
    res = np.full(len(hole_ids), -1, np.int64)
    hp = cpar[hole_ids]
    sp = cpar[shell_ids]
    cnt = np.bincount(sp, minlength=int(max(hp.max(), sp.max() if len(sp) else 0)) + 1)
    first = np.searchsorted(sp, np.arange(len(cnt)))  # shells of a parent are consecutive
    one = cnt[hp] == 1
    res[one] = first[hp[one]]
    bad[hp[cnt[hp] == 0]] = True
    many = np.flatnonzero(cnt[hp] > 1)
    if len(many):
        vstart = _first_of(cs.ring, len(cpar))
        for h in many:  # rare: a holed piece cut into several pieces
            r = hole_ids[h]
            # the midpoint of the hole's first edge: inside the piece, off the hole's own ring
            p = 0.5 * (cs.xy[vstart[r]] + cs.xy[vstart[r] + 1])
            for si in range(first[hp[h]], first[hp[h]] + cnt[hp[h]]):
                ring = cs.xy[vstart[shell_ids[si]] : vstart[shell_ids[si] + 1]]
                if _inside(p, ring):
                    res[h] = si
                    break
            if res[h] < 0:
                bad[hp[h]] = True
    return res


def _inside(p, ring) -> bool:
    """Even-odd point in ring test."""
    x, y = ring[:, 0], ring[:, 1]
    x2, y2 = np.roll(x, -1), np.roll(y, -1)
    c = (y > p[1]) != (y2 > p[1])
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = x + (p[1] - y) * (x2 - x) / (y2 - y)
    return bool(np.count_nonzero(c & (p[0] < xc)) % 2)

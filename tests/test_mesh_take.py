"""Shortcuts under the LoD2 roofs against the constructions they replaced (issue 12).

mesh._star_fans tries the apexes in stages, mesh._refill slices each
polygon's triangles out of one sort, roofs.roof_kinds reads each distinct
value once, and the terrace roofs reuse rings already made: each must give
exactly what the plain construction gave, on real footprints (Monaco's) and
hypothesis inputs.
"""

from __future__ import annotations

import math

import numpy as np
import shapely
from _city import monaco_lots
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sengine.nodes.export import mesh, roofs
from sengine.nodes.export.mesh import Rings, ring_arrays, subset_rings

SETTINGS = settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _star_fans_every_apex(xy, start, n):
    """The construction _star_fans replaced: every apex of every ring in one pass."""
    ok = np.zeros(len(start), bool)
    out = []
    for nn in np.unique(n).tolist():
        sel = np.flatnonzero(n == nn)
        st_ = start[sel]
        pts = xy[st_[:, None] + np.arange(nn)] - xy[st_][:, None, :]
        a = np.arange(nn)[:, None]
        j = np.arange(1, nn - 1)[None, :]
        ib, ic = (a + j) % nn, (a + j + 1) % nn
        d1 = pts[:, ib] - pts[:, :, None, :]
        d2 = pts[:, ic] - pts[:, :, None, :]
        area2 = d1[..., 0] * d2[..., 1] - d1[..., 1] * d2[..., 0]
        ext = np.abs(pts).max(axis=(1, 2))
        good = (area2 > 1e-12 * (ext**2)[:, None, None]).all(axis=2)
        has = good.any(axis=1)
        if not has.any():
            continue
        ok[sel[has]] = True
        best = np.argmax(good[has], axis=1)
        apex = np.broadcast_to(best[:, None], (len(best), nn - 2))
        out.append(np.stack([apex, ib[best], ic[best]], axis=2) + st_[has, None, None])
    if not out:
        return None, ok
    return np.concatenate([t.reshape(-1, 3) for t in out]), ok


@st.composite
def _rings(draw):
    """Rings of 3-16 vertices around a centre (radii vary: many concave, some not star-shaped from any vertex)."""
    k = draw(st.integers(1, 12))
    xy, lens = [], []
    for _ in range(k):
        n = draw(st.integers(3, 16))
        r = np.array(draw(st.lists(st.floats(0.2, 30.0), min_size=n, max_size=n)))
        jitter = np.array(draw(st.lists(st.floats(-0.4, 0.4), min_size=n, max_size=n)))
        t = 2 * math.pi * (np.arange(n) + jitter) / n
        c = np.array([680_000.0, 5_600_000.0]) + draw(st.floats(-500, 500))
        xy.append(c + np.column_stack([r * np.cos(t), r * np.sin(t)]))
        lens.append(n)
    return np.concatenate(xy), np.array(lens)


@SETTINGS
@given(_rings())
def test_star_fans_in_stages_pick_the_first_apex_as_every_apex_at_once(rings):
    xy, n = rings
    start = np.concatenate([[0], np.cumsum(n)[:-1]])
    got, got_ok = mesh._star_fans(xy, start, n)
    want, want_ok = _star_fans_every_apex(xy, start, n)
    assert np.array_equal(got_ok, want_ok)
    assert (got is None) == (want is None)
    if got is not None:
        assert np.array_equal(got, want)


def test_star_fans_on_monaco_footprints():
    g = monaco_lots().geometry
    r = ring_arrays(g[shapely.get_num_interior_rings(g) == 0])
    n = np.diff(r.ring_start)
    small = np.flatnonzero(n <= mesh.STAR_MAX)
    got, ok = mesh._star_fans(r.xy, r.ring_start[small], n[small])
    want, want_ok = _star_fans_every_apex(r.xy, r.ring_start[small], n[small])
    assert ok.sum() > 100 and (~ok).sum() > 0  # both kinds present: the test can tell
    assert np.array_equal(ok, want_ok) and np.array_equal(got, want)


def _refill_by_scan(rings, tri, polys):
    """The construction _refill replaced: a scan of all triangles per polygon."""
    vpoly = rings.vertex_poly()
    tpoly = vpoly[tri[:, 0]]
    redone = [tri[~np.isin(tpoly, polys)]]
    for p in polys.tolist():
        r0, r1 = rings.poly_ring[p], rings.poly_ring[p + 1]
        ring_ids = [list(range(rings.ring_start[r], rings.ring_start[r + 1])) for r in range(r0, r1)]
        redone.append(np.asarray(mesh.fill_skipped(ring_ids, tri[tpoly == p].tolist()), np.int64).reshape(-1, 3))
    tri = np.concatenate(redone)
    return tri[np.argsort(vpoly[tri[:, 0]], kind="stable")]


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 40))
def test_refill_by_slices_is_the_scan(seed, k):
    g = monaco_lots().geometry[:400]
    r = ring_arrays(g)
    tri = mesh.triangulate(r)
    rng = np.random.default_rng(seed)
    polys = np.unique(rng.choice(r.n_polys, size=min(k, r.n_polys), replace=False))
    drop = rng.random(len(tri)) < 0.05  # triangles missing: fill_skipped has work to do
    tri = tri[~drop]
    got = mesh._refill(r, tri, polys)
    assert np.array_equal(got, _refill_by_scan(r, tri, polys))
    assert len(got) >= len(tri) - int(drop.sum())


def _kinds_one_by_one(values):
    text = [str(v).strip().lower() if isinstance(v, str) else "" for v in values]
    codes = np.array([roofs.ROOF_KINDS.index(t) if t in roofs.ROOF_KINDS else 0 for t in text], np.int8)
    unknown = sum(1 for t in text if t and t not in roofs.ROOF_KINDS)
    return codes, unknown


_VALUE = st.sampled_from(["gable", " Hip ", "PYRAMID", "flat", "", "dome", "stepped"]) | st.none()
_VALUE |= st.floats(allow_nan=True) | st.integers(-3, 3) | st.text(max_size=6)


@SETTINGS
@given(st.lists(_VALUE, max_size=60), st.booleans())
def test_roof_kinds_of_distinct_values_are_read_one_by_one(values, nan_objects):
    if nan_objects:  # NaNs that are different objects (a column read from a file)
        values = values + [float("nan"), float("nan")]
    arr = np.empty(len(values), object)
    arr[:] = values
    codes, unknown = roofs.roof_kinds(arr, len(arr))
    want, want_unknown = _kinds_one_by_one(values)
    assert np.array_equal(codes, want) and unknown == want_unknown


def test_roof_kinds_of_unhashable_values():
    arr = np.empty(3, object)
    arr[:] = [["gable"], "hip", {"a": 1}]
    codes, unknown = roofs.roof_kinds(arr, 3)
    assert codes.tolist() == [0, roofs.HIP, 0] and unknown == 0


def test_prisms_and_strips_from_rings_already_made_are_the_same():
    g = monaco_lots().geometry[:800]
    parts = shapely.get_parts(g)
    parts = parts[shapely.area(parts) > 0]
    rings = ring_arrays(parts)
    assert rings.n_polys == len(parts)
    sel = np.arange(0, len(parts), 3)
    sub = subset_rings(rings, sel)
    own = Rings(sub.xy, sub.ring_start, sub.poly_ring, np.arange(len(sel)))
    h = np.linspace(3.0, 30.0, len(sel))
    for a, b in zip(mesh.extrude(parts[sel], h, base=1.5), mesh.extrude(parts[sel], h, base=1.5, rings=own)):
        assert a.dtype == b.dtype and np.array_equal(a, b)
    inner = shapely.buffer(parts[sel], -roofs.PARAPET_THICKNESS, join_style="mitre")
    plain, done = roofs._strips(parts[sel], inner, roofs.PARAPET_THICKNESS)
    given_, done2 = roofs._strips(parts[sel], inner, roofs.PARAPET_THICKNESS, own, ring_arrays(inner))
    assert done.sum() > 50 and np.array_equal(done, done2)
    assert all(np.array_equal(a, b) for a, b in zip(plain, given_))

"""The batched pieces under the LoD2 roofs (mesh.stable_argsort, unique_int, weld, skeleton_faces._roof_closed, roofs._strips).

Each is checked against the construction it replaced or a plain oracle, on
real footprints (Monaco's) and hypothesis inputs.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import shapely
import shapely.affinity
from _city import monaco_lots
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from shapely.geometry import Polygon, box

from sengine.nodes.export import roofs, skeleton
from sengine.nodes.export.mesh import ring_arrays, stable_argsort, unique_int, weld
from sengine.nodes.export.skeleton_faces import ROW_SORT_MAX, _roof_closed, _sort_around, hip_solids

SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@SETTINGS
@given(
    keys=st.lists(st.integers(-(2**40), 2**40), max_size=300) | st.lists(st.integers(0, 5), max_size=300),
    big=st.booleans(),
)
def test_stable_argsort_is_numpys_stable_argsort(keys, big):
    k = np.array(keys, np.int64)
    if big and len(k):  # keys spanning too much for key * n + position: numpy's own sort
        k[0] = 2**61
    assert np.array_equal(stable_argsort(k), np.argsort(k, kind="stable"))


@SETTINGS
@given(runs=st.lists(st.tuples(st.integers(-5, 5) | st.integers(-(2**61), 2**61), st.integers(1, 30)), max_size=40))
def test_stable_argsort_of_runs_is_numpys_stable_argsort(runs):
    # a building's vertices come in runs of one key: the runs are sorted, a key's runs in input order
    k = np.repeat(np.array([v for v, _ in runs], np.int64), [c for _, c in runs])
    assert np.array_equal(stable_argsort(k), np.argsort(k, kind="stable"))


@SETTINGS
@given(
    keys=st.lists(st.integers(-(2**40), 2**40), max_size=300) | st.lists(st.integers(0, 5), max_size=300),
    big=st.booleans(),
)
def test_unique_int_is_numpys_unique(keys, big):
    k = np.array(keys, np.int64)
    if big and len(k):  # keys spanning too much for one sort of key * n + position
        k[0] = 2**61
    assert np.array_equal(unique_int(k), np.unique(k))
    for flags in ({"return_index": True}, {"return_inverse": True}, {"return_index": True, "return_inverse": True}):
        got, want = unique_int(k, **flags), np.unique(k, **flags)
        assert len(got) == len(want)
        assert all(np.array_equal(g, w.reshape(g.shape)) for g, w in zip(got, want))


@SETTINGS
@given(
    src=st.lists(st.integers(0, 40), max_size=300),
    angles=st.lists(st.sampled_from([-3.0, -1.5, 0.0, 0.5, 0.5000000001, 2.0, 3.1]), min_size=300, max_size=300),
    busy=st.integers(0, 3 * ROW_SORT_MAX),
)
def test_sort_around_is_lexsort(src, angles, busy):
    s = np.array(src + [7] * busy, np.int64)  # node 7 with more half-edges than a row holds
    a = np.resize(np.array(angles), len(s))  # ties in angle: kept in input order
    assert np.array_equal(_sort_around(s, a), np.lexsort((a, s)))


def _weld_oracle(vertices, faces, owner):
    """The weld as a dictionary: first input vertex of each (owner, x, y, z), -0.0 as 0.0."""
    first: dict[tuple, int] = {}
    for i, (p, o) in enumerate(zip((vertices + 0.0).tolist(), owner.tolist())):
        first.setdefault((o, *p), i)
    return first


@SETTINGS
@given(
    pts=st.lists(st.tuples(st.integers(0, 3), st.integers(0, 3), st.sampled_from([0.0, -0.0, 1.5])), max_size=80),
    owners=st.integers(1, 3),
    seed=st.integers(0, 2**32 - 1),
)
def test_weld_merges_equal_vertices_of_one_owner_keeping_the_first(pts, owners, seed):
    rng = np.random.default_rng(seed)
    v = np.array(pts, np.float64).reshape(-1, 3)
    owner = rng.integers(0, owners, len(v))
    faces = rng.integers(0, max(len(v), 1), (len(v), 3)) if len(v) else np.empty((0, 3), np.int64)
    wv, wf, wo = weld(v, faces, owner)
    first = _weld_oracle(v, faces, owner)
    assert len(wv) == len(first) == len(wo)
    # every welded vertex is the first input vertex of its key (bit for bit, a -0.0 kept as it came)
    firsts = sorted(first.values())
    assert sorted(map(tuple, wv.view(np.uint64).tolist())) == sorted(map(tuple, v[firsts].view(np.uint64).tolist()))
    # each face corner lands on the welded vertex of its input vertex's key
    assert np.array_equal(wv[wf] + 0.0, v[faces] + 0.0)
    assert np.array_equal(wo[wf], owner[faces])


@lru_cache(maxsize=1)
def _monaco_hips():
    """Hip solids (the batch, CGAL's skeleton) of Monaco's concave footprints, with their rings."""
    g = monaco_lots().geometry
    g = g[(shapely.area(shapely.convex_hull(g)) - shapely.area(g) > 1.0) & (shapely.get_num_interior_rings(g) == 0)]
    rings = ring_arrays(g[:400])
    n = rings.n_polys
    with skeleton._quiet_stderr():
        v, f, vp, k, bad = hip_solids(
            skeleton._extension(), rings, np.full(n, 10.0), np.full(n, 3.0), np.zeros(n), np.zeros(n, bool)
        )
    assert not bad.size  # so the output keeps the layout: ring vertices on top, nodes, ring vertices below
    return rings, v, f, vp, k


def _closed_oracle(faces: np.ndarray, vertex_poly: np.ndarray, n_poly: int) -> np.ndarray:
    """Per polygon: every directed edge of its triangles has exactly one reverse twin (dictionaries)."""
    ok = np.ones(n_poly, bool)
    count: dict[tuple[int, int], int] = {}
    for a, b, c in faces.tolist():
        for e in ((a, b), (b, c), (c, a)):
            count[e] = count.get(e, 0) + 1
            if e[0] == e[1]:
                ok[vertex_poly[e[0]]] = False
    for (a, b), c in count.items():
        if c != 1 or count.get((b, a), 0) != 1:
            ok[vertex_poly[a]] = ok[vertex_poly[b]] = False
    return ok


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from(["drop", "flip", "repeat", "swap", "none"]))
def test_the_roof_check_finds_what_a_whole_solid_check_finds(seed, how):
    rings, v, f, vp, k = _monaco_hips()
    n_poly, m = rings.n_polys, len(rings.xy)
    n_top = len(v) - m
    rng = np.random.default_rng(seed)
    roof, rest = f[k == 2], f[k != 2]
    hit = rng.choice(len(roof), size=rng.integers(1, 6), replace=False)
    if how == "drop":
        roof = np.delete(roof, hit, axis=0)
    elif how == "flip":
        roof[hit] = roof[hit][:, [0, 2, 1]]
    elif how == "repeat":
        roof = np.concatenate([roof, roof[hit]])
    elif how == "swap":  # a corner moved to another vertex of the same roof
        roof[hit, 0] = roof[hit, 1]
    want = _closed_oracle(np.concatenate([rest, roof]), vp, n_poly)
    got = _roof_closed(roof, vp[:n_top], rings.next_vertex(), n_poly)
    assert np.array_equal(got, want)
    assert got.all() == (how == "none")


def _insets(g, d):
    g = np.array(g, object)
    return shapely.buffer(g, -d, join_style="mitre")


@SETTINGS
@given(
    w=st.floats(3.0, 30.0),
    ln=st.floats(1.0, 4.0),
    a=st.floats(0.15, 0.85),
    shape=st.sampled_from(["rect", "L", "U", "star", "collinear"]),
    angle=st.floats(0, 180),
    d=st.sampled_from([roofs.PARAPET_THICKNESS, roofs.STEP_SETBACK]),
)
def test_the_terrace_ring_strips_tile_the_ring(w, ln, a, shape, angle, d):
    ln *= w
    if shape == "rect":
        g = box(0, 0, ln, w)
    elif shape == "L":
        g = Polygon([(0, 0), (ln, 0), (ln, a * w), (a * w, a * w), (a * w, ln), (0, ln)])
    elif shape == "U":
        b = a * w / 2
        g = Polygon([(0, 0), (ln, 0), (ln, w), (ln - b, w), (ln - b, b), (b, b), (b, w), (0, w)])
    elif shape == "star":
        t = np.linspace(0, 2 * np.pi, 12, endpoint=False)
        r = np.where(np.arange(12) % 2 == 0, ln, ln * (0.5 + a / 2))
        g = Polygon(np.column_stack([r * np.cos(t), r * np.sin(t)]))
    else:  # a vertex in the middle of an edge
        g = Polygon([(0, 0), (ln * a, 0), (ln, 0), (ln, w), (0, w)])
    g = shapely.affinity.translate(shapely.affinity.rotate(g, angle, origin=(0, 0)), 680_000.0, 5_600_000.0)
    inner = _insets([g], d)
    if shapely.is_empty(inner[0]) or shapely.area(inner[0]) <= 1.0:
        return
    (v, f, vf), done = roofs._strips(np.array([g], object), inner, d)
    if not done[0]:
        return
    t = v[f][:, :, :2] - v[0, :2]
    area2 = (t[:, 1, 0] - t[:, 0, 0]) * (t[:, 2, 1] - t[:, 0, 1]) - (t[:, 1, 1] - t[:, 0, 1]) * (
        t[:, 2, 0] - t[:, 0, 0]
    )
    assert (area2 > 0).all(), "every triangle faces up"
    ring = g.difference(inner[0])
    assert area2.sum() / 2 == np.float64(ring.area) or abs(area2.sum() / 2 - ring.area) <= 1e-9 * g.area
    # the triangles do not overlap: their union has their summed area
    tris = shapely.polygons(v[f][:, :, :2])
    assert abs(shapely.union_all(tris).area - area2.sum() / 2) <= 1e-6 * g.area
    # every edge has its twin, but the outline's and the inset's
    e = f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    pairs = {tuple(x) for x in e.tolist()}
    lone = [x for x in e.tolist() if (x[1], x[0]) not in pairs]
    assert len(lone) == 2 * (len(v) // 2)


def test_monaco_parapet_rings_by_strips_are_the_rings_earcut_makes():
    g = monaco_lots().geometry[:600]
    g = g[shapely.get_num_interior_rings(g) == 0]
    inner = _insets(g, roofs.PARAPET_THICKNESS)
    good = np.isin(shapely.get_type_id(inner), (3, 6)) & ~shapely.is_empty(inner)
    g, inner = g[good], inner[good]
    (v, f, vf), done = roofs._strips(g, inner, roofs.PARAPET_THICKNESS)
    assert done.mean() > 0.5, "most footprints take the strips"
    t = v[f][:, :, :2] - v[f][:, :1, :2]
    area2 = (t[:, 1, 0]) * (t[:, 2, 1]) - (t[:, 1, 1]) * (t[:, 2, 0])
    assert (area2 > 0).all()
    got = np.bincount(vf[f[:, 0]], weights=area2 / 2, minlength=len(g))
    want = shapely.area(g) - shapely.area(inner)
    assert np.allclose(got[done], want[done], rtol=1e-9, atol=1e-6)
    # a whole parapet building from them is closed, at the volume of the prism less the well
    s = roofs.building_solids(g[done][:50], np.full(50, 12.0), roof=["parapet"] * 50)
    assert s.notes == {}
    vol = _volumes(s, 50)
    well = shapely.area(inner[done][:50]) * roofs.PARAPET_HEIGHT
    assert np.allclose(vol, shapely.area(g[done][:50]) * 12.0 - well, rtol=1e-9)


def _volumes(s, n):
    t = s.vertices[s.faces]
    ff = s.face_feature()
    o = np.zeros((n, 3))
    o[s.vertex_feature[::-1]] = s.vertices[::-1]
    t = t - o[ff][:, None, :]
    return np.bincount(ff, weights=np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])) / 6, minlength=n)


def _rings_oracle(parts):
    """Ring vertices (closing repeat dropped), ring offsets and polygon ring offsets, read ring by ring."""
    xy, ring_start, poly_ring = [], [0], [0]
    for p in parts:
        rs = shapely.get_rings(p)
        for r in rs:
            c = shapely.get_coordinates(r)[:-1]
            xy.append(c)
            ring_start.append(ring_start[-1] + len(c))
        poly_ring.append(poly_ring[-1] + len(rs))
    return np.concatenate(xy), np.array(ring_start), np.array(poly_ring)


@SETTINGS
@given(st.lists(st.tuples(st.integers(3, 9), st.integers(0, 3), st.floats(0, 360)), min_size=1, max_size=12))
def test_ring_arrays_reads_holed_polygons_ring_by_ring(specs):
    parts = []
    for k, holes, angle in specs:  # a k-gon with up to three square holes, some polygons without
        t = np.radians(angle) + np.linspace(0, 2 * np.pi, k, endpoint=False)
        shell = 40.0 * np.column_stack([np.cos(t), np.sin(t)]) + 1000.0
        hs = [box(1000.0 - 9 + 7 * h, 997.0, 1000.0 - 5 + 7 * h, 1001.0).exterior.coords[::-1] for h in range(holes)]
        p = Polygon(shell, hs)
        parts.append(p if p.is_valid else Polygon(shell))
    parts = np.array(parts, object)
    r = ring_arrays(parts)
    xy, ring_start, poly_ring = _rings_oracle(parts)
    # ring_arrays turns exteriors counter-clockwise and holes clockwise: compare as point sets per ring
    assert np.array_equal(r.ring_start, ring_start) and np.array_equal(r.poly_ring, poly_ring)
    for a, b in zip(ring_start[:-1].tolist(), ring_start[1:].tolist()):
        assert sorted(map(tuple, r.xy[a:b].tolist())) == sorted(map(tuple, xy[a:b].tolist()))

"""blocks.circuits: minimal circuits partition the city (skylineEngine §5.4)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import shapely
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

import sengine.nodes.blocks.circuits as B
from sengine import Layer
from sengine.registry import get

SETTINGS = settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
MONACO = Path(__file__).resolve().parent.parent / "configs" / "data" / "monaco.osm.pbf"


def polygonize_ref(lines):
    noded = shapely.node(shapely.multilinestrings(shapely.get_parts(np.asarray(lines, dtype=object))))
    ref = shapely.get_parts(shapely.polygonize(shapely.get_parts(noded)))
    return ref[shapely.area(ref) > 1e-9]


def assert_partition_like(faces, ref):
    total, ref_total = shapely.area(faces).sum(), shapely.area(ref).sum()
    assert abs(total - ref_total) <= 1e-6 * max(ref_total, 1.0)
    if len(faces):
        # snap-rounding overlay (grid_size): GEOS's default overlay can misjudge nearly collinear edges
        union = shapely.union_all(faces, grid_size=1e-9)
        assert abs(union.area - total) <= 1e-6 * max(total, 1.0), "faces overlap"
        ref_union = shapely.union_all(ref, grid_size=1e-9)
        assert shapely.symmetric_difference(union, ref_union, grid_size=1e-9).area <= 1e-6 * max(total, 1.0)


@st.composite
def jittered_grid(draw):
    """A street grid with jitter, removed edges (dead ends), duplicates and collinear overlaps."""
    nx_, ny = draw(st.integers(2, 6)), draw(st.integers(2, 6))
    seed = draw(st.integers(0, 2**31))
    rng = np.random.default_rng(seed)
    step = draw(st.floats(20, 120))
    # jitter near find_blocks' node merge (1e-6 m) makes nanometre slivers that one route closes
    # and the other keeps: none, or at least a millimetre
    jitter = draw(st.floats(0, 0.3)) * step
    jitter = jitter if jitter >= 1e-3 else 0.0
    gx, gy = np.meshgrid(np.arange(nx_ + 1) * step, np.arange(ny + 1) * step, indexing="ij")
    pts = np.stack([gx, gy], -1) + rng.uniform(-jitter, jitter, (nx_ + 1, ny + 1, 2))
    lines = []
    for i in range(nx_ + 1):
        for j in range(ny + 1):
            if i < nx_:
                lines.append([pts[i, j], pts[i + 1, j]])
            if j < ny:
                lines.append([pts[i, j], pts[i, j + 1]])
    lines = np.asarray(lines)
    drop = rng.random(len(lines)) < draw(st.floats(0, 0.3))
    lines = list(lines[~drop])
    for _ in range(draw(st.integers(0, 4))):  # dead ends poking into blocks
        p = pts[rng.integers(nx_ + 1), rng.integers(ny + 1)]
        lines.append([p, p + rng.uniform(-0.4, 0.4, 2) * step])
    for _ in range(draw(st.integers(0, 3))):  # duplicates, reversed
        if lines:
            a, b = lines[rng.integers(len(lines))]
            lines.append([b, a])
    for _ in range(draw(st.integers(0, 2))):  # collinear overlap along a grid row
        j = rng.integers(ny + 1)
        lines.append([pts[0, j], pts[min(2, nx_), j]])
    return shapely.linestrings(np.asarray(lines, float))


@SETTINGS
@given(jittered_grid())
def test_blocks_of_jittered_grids_match_polygonize(lines):
    bf = B.find_blocks(lines)
    ref = polygonize_ref(lines)
    assert shapely.is_valid(bf.faces).all()
    assert len(bf.faces) == len(ref)
    assert_partition_like(bf.faces, ref)


@SETTINGS
@given(st.integers(1, 8), st.integers(1, 8), st.floats(5, 200))
def test_clean_grid_counts(nx_, ny, step):
    lines = [shapely.LineString([(i * step, 0), (i * step, ny * step)]) for i in range(nx_ + 1)]
    lines += [shapely.LineString([(0, j * step), (nx_ * step, j * step)]) for j in range(ny + 1)]
    bf = B.find_blocks(lines)
    assert len(bf.faces) == nx_ * ny
    assert np.allclose(shapely.area(bf.faces), step * step)
    assert len(bf.outline) == 1 and np.isclose(bf.outline[0].area, nx_ * ny * step * step)


def test_arrays_entry_point_matches_lines_entry():
    rng = np.random.default_rng(3)
    xy = rng.uniform(0, 500, (40, 2))
    tri = shapely.delaunay_triangles(shapely.multipoints(xy), only_edges=True)
    lines = shapely.get_parts(tri)
    c = shapely.get_coordinates(lines).reshape(-1, 2, 2)
    # node ids by coordinate, as an OSM importer would give
    ids = {tuple(p): k for k, p in enumerate(xy.tolist())}
    u = np.array([ids[tuple(p)] for p in c[:, 0].tolist()])
    v = np.array([ids[tuple(p)] for p in c[:, 1].tolist()])
    a = B.find_blocks((xy, u, v), node=False)
    b = B.find_blocks(lines)
    assert len(a.faces) == len(b.faces) == len(polygonize_ref(lines))
    assert np.isclose(shapely.area(a.faces).sum(), shapely.area(shapely.union_all(lines).convex_hull))
    assert np.array_equal(np.sort(a.src), np.arange(len(u)))


def test_disconnected_component_becomes_hole():
    lines = [shapely.box(0, 0, 100, 100).exterior, shapely.box(40, 40, 60, 60).exterior]
    bf = B.find_blocks(lines)
    areas = sorted(shapely.area(bf.faces))
    assert np.allclose(areas, [400.0, 9600.0])
    assert assert_partition_like(bf.faces, polygonize_ref(lines)) is None


def _roads(lines, width=10.0):
    lines = np.asarray(lines, dtype=object)
    return Layer.from_geoms(lines, width=np.full(len(lines), width), meta={"crs": "EPSG:32631"})


def test_node_shrinks_blocks_and_partitions_faces():
    lines = [shapely.LineString([(i * 100.0, 0), (i * 100.0, 300)]) for i in range(4)]
    lines += [shapely.LineString([(0, j * 100.0), (300, j * 100.0)]) for j in range(4)]
    lines.append(shapely.LineString([(50, 0), (50, 30)]))  # dead end
    node = get("blocks.circuits")("blocks", {"sidewalk": 3.0, "min_area": 1.0})
    out = node.run(roads=_roads(lines, 10.0))
    blocks, streets, walks, faces = out["blocks"], out["streets"], out["sidewalks"], out["faces"]
    assert len(faces) == 9 and len(blocks) == 9
    # the cul-de-sac is cut out of its block: its street (5 m round it, 2 segments a quarter circle), then
    # the sidewalk (3 m more, mitred), from the block's edge to round its tip
    cut = shapely.buffer(shapely.buffer(lines[-1], 5.0, quad_segs=2), 3.0, join_style="mitre", mitre_limit=3.0)
    want = np.full(9, (100 - 2 * 8) ** 2.0)
    want[0] = shapely.difference(shapely.box(8, 8, 92, 92), cut).area
    assert np.allclose(shapely.area(blocks.geometry), want)
    assert set(walks["kind"]) == {"sidewalk"} and set(streets["kind"]) == {"street"}
    # street ring (with the cul-de-sac's surface) + sidewalk ring + block = face, for every face
    assert np.allclose(
        shapely.area(streets.geometry) + shapely.area(walks.geometry) + shapely.area(blocks.geometry),
        shapely.area(faces.geometry),
    )
    assert out.report["bridges"] == 1 and out.report["dead_ends_cut"] == 1 and len(streets) == 9
    assert shapely.within(blocks.geometry, faces.geometry[blocks["face"]]).all()
    assert shapely.distance(blocks.geometry, lines[-1]).min() >= 5.0 * np.cos(np.pi / 8) + 3.0 - 1e-6  # chords
    # laid over the block instead: the block whole, the cul-de-sac a street polygon of its own
    over = get("blocks.circuits")("blocks", {"sidewalk": 3.0, "min_area": 1.0, "dead_ends": "over"})
    out = over.run(roads=_roads(lines, 10.0))
    assert np.allclose(shapely.area(out["blocks"].geometry), (100 - 2 * 8) ** 2)
    assert len(out["streets"]) == 10 and out.report["dead_ends_cut"] == 0


def test_street_inset_moves_each_side_by_its_own_street():
    """A grid whose four avenues are 24 m wide and its inner streets 8 m: each block side keeps its own street."""
    xs = ys = [0.0, 100.0, 200.0, 300.0]
    lines, widths = [], []
    for i, x in enumerate(xs):
        lines.append(shapely.LineString([(x, 0), (x, 300)]))
        widths.append(24.0 if i in (0, 3) else 8.0)
    for j, y in enumerate(ys):
        lines.append(shapely.LineString([(0, y), (300, y)]))
        widths.append(24.0 if j in (0, 3) else 8.0)
    roads = Layer.from_geoms(lines, width=np.array(widths), meta={"crs": "EPSG:32631"})
    out = get("blocks.circuits")("blocks", {"sidewalk": 2.0, "inset": "street"}).run(roads=roads)
    blocks, faces = out["blocks"], out["faces"]
    # every side moves by its street's half-width and the sidewalk: 12 + 2 on avenues, 4 + 2 on inner streets
    want = {(0, 0): (14, 14, 94, 94), (1, 1): (106, 106, 194, 194), (2, 0): (206, 14, 286, 94)}
    for (i, j), box in want.items():
        at = shapely.contains_xy(blocks.geometry, 100 * i + 50, 100 * j + 50)
        assert at.sum() == 1 and shapely.equals_exact(
            blocks.geometry[at][0].normalize(), shapely.box(*box).normalize(), tolerance=1e-6
        )
    # street ring + sidewalk ring + block = face, face by face
    f = blocks["face"]
    parts = [shapely.area(out[k].geometry) for k in ("streets", "sidewalks")]
    assert np.allclose(parts[0][:9] + parts[1] + shapely.area(blocks.geometry), shapely.area(faces.geometry[f]))
    # the mean inset gives the centre block the same 6 m, but the corner ones only a mean of 10 m
    mean = get("blocks.circuits")("blocks", {"sidewalk": 2.0}).run(roads=roads)["blocks"]
    assert np.allclose(sorted(shapely.area(mean.geometry))[-1], (100 - 2 * 6) ** 2)


@SETTINGS
@given(st.lists(st.floats(2.0, 30.0), min_size=8, max_size=8), st.floats(0.0, 4.0))
def test_street_inset_keeps_every_street_clear(widths, sidewalk):
    lines = [shapely.LineString([(x, 0), (x, 300)]) for x in (0.0, 90.0, 200.0, 300.0)]
    lines += [shapely.LineString([(0, y), (300, y)]) for y in (0.0, 120.0, 210.0, 300.0)]
    roads = Layer.from_geoms(lines, width=np.array(widths), meta={"crs": "EPSG:32631"})
    out = get("blocks.circuits")("blocks", {"sidewalk": str(sidewalk), "inset": "street", "min_area": "1"}).run(
        roads=roads
    )
    blocks = out["blocks"].geometry
    for line, w in zip(lines, widths, strict=True):  # no block comes nearer a street than its half-width + sidewalk
        if len(blocks):
            assert shapely.distance(blocks, line).min() >= w / 2 + sidewalk - 1e-6
    # and the three layers still partition the faces
    total = sum(shapely.area(out[k].geometry).sum() for k in ("streets", "sidewalks", "blocks"))
    assert total == pytest.approx(shapely.area(out["faces"].geometry).sum(), rel=1e-9)


def test_node_outline_areas_and_reports():
    lines = [shapely.LineString([(i * 100.0, 0), (i * 100.0, 200)]) for i in range(3)]
    lines += [shapely.LineString([(0, j * 100.0), (200, j * 100.0)]) for j in range(3)]
    lines.append(shapely.LineString([(0, 0), (1, 1)]))  # a sliver-free dead end
    outline = Layer.from_geoms([shapely.box(-1, -1, 201, 101)])
    areas = Layer.from_geoms([shapely.box(0, 0, 100, 100), shapely.box(100, 0, 200, 100)], ids=[7, 8], district=[2, 5])
    node = get("blocks.circuits")("blocks", {"sidewalk": 2.0, "width_from": "param", "street_width": 6})
    out = node.run(roads=_roads(lines, 50.0), outline=outline, areas=areas)
    blocks = out["blocks"]
    assert out.report["dropped_outside_outline"] == 2
    assert sorted(blocks["district"].tolist()) == [2, 5]
    assert sorted(blocks.parent.tolist()) == [7, 8]
    assert np.allclose(shapely.area(blocks.geometry), (100 - 10) ** 2)


def test_thin_faces_are_dropped_and_counted():
    lines = [
        shapely.box(0, 0, 200, 100).exterior,
        shapely.LineString([(0, 50), (200, 50)]),
        shapely.LineString([(0, 52), (200, 52)]),
    ]  # a 2 m median strip
    node = get("blocks.circuits")("blocks", {"min_area": 10.0})
    out = node.run(roads=_roads(lines, 8.0))
    assert len(out["faces"]) == 3
    assert len(out["blocks"]) == 2
    assert out.report["vanished_by_inset"] == 1
    assert node.run(roads=_roads([], 8.0))["blocks"].geometry.shape == (0,)


def read_highways(path):
    osmium = pytest.importorskip("osmium")
    pyproj = pytest.importorskip("pyproj")
    lon, lat, idx = [], [], []
    k = 0
    for obj in osmium.FileProcessor(str(path)).with_locations():
        if obj.is_way() and "highway" in obj.tags:
            for nd in obj.nodes:
                if nd.location.valid():
                    lon.append(nd.lon)
                    lat.append(nd.lat)
                    idx.append(k)
            k += 1
    lon, lat, idx = np.asarray(lon), np.asarray(lat), np.asarray(idx)
    tr = pyproj.Transformer.from_crs("EPSG:4326", "EPSG:32632", always_xy=True)
    x, y = tr.transform(lon, lat)
    x, y = x - x.mean(), y - y.mean()
    ok = np.bincount(idx) >= 2
    keep = ok[idx]
    return shapely.linestrings(np.c_[x[keep], y[keep]], indices=np.unique(idx[keep], return_inverse=True)[1])


def test_monaco_blocks_match_polygonize():
    lines = read_highways(MONACO)
    assert len(lines) > 2000
    bf = B.find_blocks(lines, decimals=None)
    ref = polygonize_ref(lines)
    assert shapely.is_valid(bf.faces).all()
    assert bf.counts["bridges"] > 0
    assert len(bf.faces) == len(ref)
    assert_partition_like(bf.faces, ref)


def test_faces_traced_by_clean_are_taken_over():
    from sengine import Context

    roads = get("osm.read")("r", {"path": str(MONACO), "extras": ""}, Context()).run()["roads"]
    ran = get("roads.clean")("c", {}, Context()).run(roads=roads)
    cleaned, graph = ran["roads"], ran["graph"]
    assert isinstance(graph.meta["faces"], B.BlockFaces) and len(graph["row"]) == len(graph["u"]) == len(graph)
    assert graph.meta["decimals"] == 6 and "graph" not in cleaned.meta  # on its port, not behind it
    node = get("blocks.circuits")("b", {"node": "false"}, Context())
    taken = node.run(roads=cleaned, graph=graph)
    rep_taken = dict(taken.report)
    traced = node.run(roads=cleaned)  # no graph: traced from the lines
    assert rep_taken == traced.report
    for port in ("faces", "blocks", "streets", "sidewalks"):  # the same polygons in the same order
        a, b = taken[port].geometry, traced[port].geometry
        assert len(a) == len(b) and shapely.equals_exact(a, b, 0).all()
    # taken over only for the rows and the node merge they were traced for
    assert B.traced_faces(graph, len(cleaned) - 1, decimals=6) is None
    assert B.traced_faces(graph, len(cleaned), decimals=5) is None
    assert B.traced_faces(graph, len(cleaned), decimals=6) is not None


def test_clean_hands_no_faces_on_when_nodes_would_merge():
    from sengine import Context

    lines = [
        [(0, 0), (100, 0)],
        [(100, 0), (100, 100)],
        [(100, 100), (0, 100)],
        [(0, 100), (0, 0)],
        [(0, 0), (50, 50)],
        [(50, 50 + 1e-8), (100, 100)],
    ]  # two ends 1e-8 m apart: one node at 6 decimals
    roads = _roads([shapely.LineString(c) for c in lines])
    ran = get("roads.clean")("c", {"dead_ends": "false"}, Context()).run(roads=roads)
    cleaned, graph = ran["roads"], ran["graph"]
    assert graph.meta["decimals"] is None
    assert B.traced_faces(graph, len(cleaned), decimals=6) is None
    out = get("blocks.circuits")("b", {"node": "false", "min_area": "1"}, Context()).run(roads=cleaned, graph=graph)
    assert len(out["faces"]) == 2  # the diagonal closes, as the lines entry merges the two ends


@SETTINGS
@given(st.lists(st.floats(0.0, 1e6), max_size=60), st.integers(1, 12))
@example([0.0, 2.2250738585072e-309], 2)  # a subnormal total still cuts by shares (found by hypothesis)
def test_cost_chunks_deal_every_item_once_heaviest_first(cost, parts):
    chunks = B.cost_chunks(cost, parts)
    got = np.concatenate(chunks) if chunks else np.zeros(0, np.int64)
    assert np.array_equal(np.sort(got), np.arange(len(cost)))  # every index once
    assert all(len(c) for c in chunks) and len(chunks) <= max(parts, 1)
    if cost:
        c = np.asarray(cost)
        assert c[chunks[0][0]] == c.max()  # the costliest item starts the first chunk
        share = c.sum() / parts
        big = np.flatnonzero(c > share)
        for i in big:  # an item above one share is a chunk of its own
            assert [len(k) for k in chunks if i in k] == [1]


def test_shrink_faces_in_chunks_equals_one_vectorized_call():
    lines = read_highways(MONACO)
    faces = B.find_blocks(lines, decimals=None).faces
    # enough faces for the threaded path (translated copies), some inset with round joins
    faces = np.concatenate([shapely.transform(faces, lambda xy, k=k: xy + 5000.0 * k) for k in range(3)])
    assert len(faces) >= B.PARALLEL_MIN
    hw = 3.0 + (np.arange(len(faces)) % 5)
    rounded = np.arange(len(faces)) % 3 == 0
    street, walk, block = B.shrink_faces(faces, hw, 3.0, rounded=rounded)
    ref = B._shrink_some(faces, faces, hw, rounded, 3.0, threads=1)
    for got, want in zip((street, walk, block), ref, strict=True):
        assert shapely.to_wkb(got).tolist() == shapely.to_wkb(want).tolist()  # same bytes, same order
    live = ~shapely.is_empty(block)
    assert 0 < live.sum() < len(faces)
    total = shapely.area(street) + shapely.area(walk) + shapely.area(block)
    np.testing.assert_allclose(total, shapely.area(faces), rtol=1e-6)  # the three partition each face


@st.composite
def lobed_faces(draw):
    """Concave faces of a few overlapping boxes, some with holes, far from the origin (UTM-like)."""
    n = draw(st.integers(1, 12))
    faces = []
    for _ in range(n):
        boxes = draw(st.lists(st.tuples(*[st.floats(0, 120)] * 2, *[st.floats(4, 60)] * 2), min_size=1, max_size=5))
        face = shapely.union_all([shapely.box(x, y, x + w, y + h) for x, y, w, h in boxes])
        holes = draw(st.lists(st.tuples(st.floats(0, 150), st.floats(0, 150), st.floats(0.5, 6)), max_size=3))
        for x, y, r in holes:
            face = face.difference(shapely.Point(x, y).buffer(r, quad_segs=2))
        faces.extend(p for p in shapely.get_parts(face) if p.area > 1.0)
    # dumbbells: two squares joined by a corridor thinner than any inset, so that their insets come in pieces
    for s1, s2, gap, y in draw(
        st.lists(st.tuples(*[st.floats(10, 60)] * 2, st.floats(1, 20), st.floats(0, 9)), max_size=3)
    ):
        bell = shapely.union_all([shapely.box(0, 0, s1, s1), shapely.box(s1, y, s1 + gap, y + 0.5)])
        bell = bell.union(shapely.box(s1 + gap, 0, s1 + gap + s2, s2))
        faces.append(bell.difference(shapely.Point(s1 + gap + s2 / 2, s2 / 2).buffer(2.0, quad_segs=2)))
    # a hole closing round a pocket of the face but for a narrow gap: its inset is a part inside the inset's hole
    for g, x in draw(st.lists(st.tuples(st.floats(0.2, 1.0), st.floats(-20, 20)), max_size=2)):
        cup = shapely.box(30, 30, 70, 72).difference(shapely.box(40, 40, 60, 70))
        cup = cup.difference(shapely.box(50 - g, 69, 50 + g, 73))
        faces.append(shapely.box(0, 0, 100 + x, 100).difference(cup))
    return np.array([shapely.transform(f, lambda xy: xy + (6.5e5, 5.6e6)) for f in faces] or [shapely.Polygon()])


@SETTINGS
@given(lobed_faces(), st.floats(0.3, 4.0), st.floats(0.3, 4.0))
def test_ring_between_is_the_difference(faces, d1, d2):
    # the street edge and the block of each face, as shrink_faces makes them: often MultiPolygons, with holes
    edge = B.inset(faces, d1)
    block = B.inset(faces, d1 + d2)
    gap = np.ones(len(faces), bool)
    for outer, inner in ((faces, edge), (edge, block)):
        got = B._ring_between(outer, inner, gap=gap)
        want = shapely.difference(outer, inner)
        assert shapely.is_valid(got).all()
        np.testing.assert_allclose(shapely.area(got), shapely.area(want), rtol=1e-9, atol=1e-6)
        assert shapely.equals(got, want).all()
        assert (shapely.get_num_geometries(got) == shapely.get_num_geometries(want)).all()
    multi = shapely.get_type_id(edge) == 6
    if multi.any():  # an edge in pieces: each piece around the block parts inside it
        ring = B._ring_between(edge[multi], block[multi], gap=gap[multi])
        assert (shapely.get_type_id(ring) == 6).all()


LIEGE = Path(__file__).resolve().parent.parent.parent / "shared" / "data" / "liege_streets.osm.pbf"


@pytest.mark.slow
@pytest.mark.skipif(not LIEGE.exists(), reason="Liège street network not present (not in the repository)")
def test_liege_land_face_inset_without_snap_rounding():
    from sengine import Context
    from sengine.geom.polygons import LOCAL_MIN, buffer_local
    from sengine.nodes.standard import NETWORKS_DIR
    from sengine.xmlconfig import read_network_file

    specs = read_network_file(NETWORKS_DIR / "loadmap.xml").specs
    ctx = Context()
    roads = get("osm.read")("r", {"path": str(LIEGE), "extras": ""}, ctx).run()["roads"]
    out = get("roads.clean")("c", dict(specs["clean"].params), ctx).run(roads=roads)
    bf = B.traced_faces(out["graph"], len(out["roads"]), decimals=6)
    assert bf is not None
    sid, spoly, _, _ = B.spur_polygons(bf, bf.xy)
    land = int(np.argmax(shapely.get_num_coordinates(spoly)))  # the land round the city, its dead ends as spurs
    shape = spoly[land]
    assert shapely.get_num_coordinates(shape) >= LOCAL_MIN  # moved to a local origin
    hw = B.face_half_widths(bf, np.asarray(out["roads"]["width"], np.float64))[sid[land]]
    got = buffer_local([shape], -hw, quad_segs=2)[0]
    # the same inset about another origin, moved back: to the float, as no snap-rounding moved it
    far = shapely.transform(shape, lambda xy: xy - (650_000.0, 5_600_000.0))
    there = shapely.transform(shapely.buffer(far, -hw, quad_segs=2), lambda xy: xy + (650_000.0, 5_600_000.0))
    assert shapely.is_valid(got) and shapely.hausdorff_distance(got, there) < 1e-6
    assert abs(got.area - there.area) < 1e-6 * got.area
    # it lies inside the face, kept as clear of every dead end and side as GEOS's buffer in place keeps it
    # (to the mm its snapping moved it; round joins of 2 chords a quarter circle sag up to 17 % at spur tips)
    face = bf.faces[sid[land]]
    assert shapely.area(shapely.difference(got, face)) < 1e-3
    ring = shapely.points(shapely.get_coordinates(shape))
    clear = shapely.distance(ring, got)
    assert clear.min() > 0.8 * hw
    np.testing.assert_allclose(clear, shapely.distance(ring, shapely.buffer(shape, -hw, quad_segs=2)), atol=5e-3)

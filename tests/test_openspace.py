"""Open space (issue 14): parks at three levels, patios, vegetation, water, bridges and their exports."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest
import shapely
from _city import ROOT, data_file
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree
from test_roofs import _validator_ready, gltf_validate, validate_cityjson

import sengine
from sengine import Layer
from sengine.errors import NodeError, ParameterError
from sengine.node import Context
from sengine.nodes.export.gltf import glb_bytes
from sengine.nodes.vegetation import avenue_points, distr, tree_lines, versailles_split
from sengine.nodes.vegetation.distr import far_from
from sengine.registry import get

# -- Distr(density, deviation) -------------------------------------------------------------------


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    size=st.floats(1200.0, 5000.0),
    holes=st.integers(0, 6),
)
def test_big_area_test_along_lines_gives_the_point_test_answer(seed, size, holes):
    """``_Areas.covers`` with the points' lines (big polygons tested per line) = the plain bounding-box test.

    Areas: a ring-shaped polygon over 1 km across (big: tested along lines) with holes, small boxes
    and a concave notch; points on random closed lines (block tree lines) crossing all of them.
    """
    from sengine.nodes.vegetation.trees import _Areas

    rng = np.random.default_rng(seed)
    big = shapely.difference(shapely.box(0, 0, size, size), shapely.box(40, 40, size - 40, size - 40))
    cuts = [shapely.box(*(c := rng.uniform(50, size - 150, 2)), *(c + rng.uniform(20, 100, 2))) for _ in range(holes)]
    big = shapely.difference(big, shapely.union_all(cuts)) if cuts else big
    small = [shapely.box(*(c := rng.uniform(0, size - 60, 2)), *(c + rng.uniform(5, 60, 2))) for _ in range(40)]
    notch = shapely.Polygon([(10, 10), (300, 10), (300, 300), (150, 80), (10, 300)])
    areas = _Areas(np.array([big, notch, *small], dtype=object))
    assert len(areas.large[1]) == 1 and len(areas.small[1]) == 41
    centres = rng.uniform(0, size, (30, 2))
    lines = shapely.get_exterior_ring(shapely.buffer(shapely.points(centres), rng.uniform(10, 400, 30)))
    xy, li, _ = avenue_points(lines, spacing=7.0, clear=0.0, corner=179.0)
    with_lines = areas.covers(xy[:, 0], xy[:, 1], along=(lines, li))
    plain = areas.covers(xy[:, 0], xy[:, 1])
    truth = shapely.intersects_xy(shapely.union_all(np.array([big, notch, *small])), xy[:, 0], xy[:, 1])
    assert len(xy) > 100 and 0 < plain.sum() < len(xy)
    assert (with_lines == plain).all() and (plain == truth).all()


@pytest.mark.parametrize("deviation", [0.0, 25.0])
def test_distr_gives_the_requested_count_within_sampling_error(deviation):
    """Each region's count is floor(lambda) + Bernoulli(frac): the total is within 4 sigma of sum(lambda).

    sigma <= sqrt(regions / 4) (a Bernoulli variance is at most 1/4): 300 regions give a tolerance of
    4 * sqrt(75) = 34.6 trees on some 7,000.
    """
    rng = np.random.default_rng(1)
    regions = [
        shapely.box(x, 0, x + w, h)
        for x, w, h in zip(np.arange(300) * 500, rng.uniform(50, 400, 300), rng.uniform(50, 300, 300))
    ]
    area = shapely.area(np.array(regions))
    density = 0.0004
    xy, reg, wanted = distr(regions, np.arange(300), density, deviation, seed=9, spacing=0.0)
    lam = density * area
    assert abs(len(xy) - lam.sum()) <= 4 * np.sqrt(len(regions) / 4)
    assert (np.bincount(reg, minlength=300) == wanted).all()
    assert (np.abs(wanted - lam) < 1).all()
    assert shapely.contains_xy(np.array(regions)[reg], xy[:, 0], xy[:, 1]).all()
    if deviation > 0:  # Gaussian around the region's centre: nearer the centre than uniform points are
        centre = shapely.get_coordinates(shapely.point_on_surface(np.array(regions)))
        u, ureg, _ = distr(regions, np.arange(300), density, 0.0, seed=9)
        near = np.median(np.hypot(*(xy - centre[reg]).T))
        assert near < 0.8 * np.median(np.hypot(*(u - centre[ureg]).T))


polygons = st.builds(
    lambda w, h, hole, notch: shapely.difference(
        shapely.box(0, 0, w, h),
        shapely.union(
            shapely.box(w * 0.3, h * 0.3, w * 0.3 + hole * w * 0.4, h * 0.3 + hole * h * 0.4),
            shapely.box(w * (1 - notch), h * 0.5, w, h),
        ),
    ),
    st.floats(5, 400),
    st.floats(2, 300),
    st.floats(0, 1),
    st.floats(0, 0.9),
)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(polygons, min_size=1, max_size=4), st.floats(0.001, 0.08), st.floats(0.5, 6.0))
def test_minimum_spacing_holds_and_points_stay_inside(polys, density, spacing):
    geoms = np.array([shapely.affinity.translate(p, 1000 * i, 0) for i, p in enumerate(polys)], dtype=object)
    geoms = geoms[~shapely.is_empty(geoms)]
    xy, reg, wanted = distr(geoms, np.arange(len(geoms)), density, 0.0, seed=3, spacing=spacing)
    assert len(xy) <= wanted.sum()
    if len(xy) > 1:
        d, _ = cKDTree(xy).query(xy, k=2)
        assert d[:, 1].min() >= spacing - 1e-9
    assert shapely.contains_xy(geoms[reg], xy[:, 0], xy[:, 1]).all()
    # below random packing density the count is met
    if density * spacing**2 < 0.3 and (shapely.area(geoms) > 20 * spacing**2).all():
        assert len(xy) >= 0.97 * wanted.sum()


@pytest.mark.slow  # 10-97 s in session 14's runs
@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(polygons, min_size=1, max_size=3), st.floats(0.5, 6.0), st.integers(0, 2**31))
def test_points_keep_clear_of_fixed_points(polys, spacing, seed):
    """Trees placed before (avenues) are obstacles: no new point within ``spacing`` of one."""
    geoms = np.array([shapely.affinity.translate(p, 1000 * i, 0) for i, p in enumerate(polys)], dtype=object)
    geoms = geoms[~shapely.is_empty(geoms)]
    box = shapely.bounds(geoms)
    rng = np.random.default_rng(seed)
    fixed = rng.uniform(box[:, :2].min(0), box[:, 2:].max(0), size=(400, 2))
    xy, _, _ = distr(geoms, np.arange(len(geoms)), 0.05, 0.0, seed=seed, spacing=spacing, fixed=fixed)
    if len(xy):
        d, _ = cKDTree(fixed).query(xy, k=1)
        assert d.min() >= spacing - 1e-9
    # far_from answers the same from the points or from their tree, and refuses what lies too near
    assert not far_from(fixed + 0.25 * spacing, fixed, spacing).any()
    assert not far_from(fixed + 0.25 * spacing, cKDTree(fixed), spacing).any()


# -- avenue trees and Versailles -----------------------------------------------------------------


def test_avenue_trees_are_spaced_and_stop_short_of_the_corners():
    blocks = np.array([shapely.box(0, 0, 100, 60), shapely.Point(300, 0).buffer(40)], dtype=object)
    lines, row = tree_lines(blocks, 1.5)
    xy, li, _ = avenue_points(lines, spacing=10, clear=6)
    corners = shapely.get_coordinates(lines[0])
    on_box = row[li] == 0
    d = np.hypot(*(xy[on_box][:, None] - corners[None]).transpose(2, 0, 1)).min(axis=1)
    assert d.min() >= 6 - 1e-9
    # 103 m sides: 10 trees, 63 m sides: 6 trees
    assert on_box.sum() == 2 * 10 + 2 * 6
    # the circle is one run without crossings
    assert abs((~on_box).sum() - shapely.length(lines[1]) // 10) <= 1


@pytest.mark.parametrize(
    "region",
    [
        shapely.box(0, 0, 800, 500),
        shapely.Point(0, 0).buffer(300),
        shapely.Polygon([(0, 0), (600, 0), (600, 200), (200, 200), (200, 500), (0, 500)]),
    ],
    ids=["rectangle", "disc", "L"],
)
def test_versailles_three_splits_give_eight_sub_regions(region):
    parts, owner, avenues, _, depth = versailles_split([region], depth=3, width=24)
    assert len(parts) == 8 and (owner == 0).all()
    assert sorted(np.bincount(depth).tolist()) == [1, 2, 4]
    assert shapely.union_all(parts).within(region.buffer(1e-6))
    assert (
        not shapely.intersects(parts[:, None], parts[None]).sum() - len(parts)
        or shapely.area(shapely.intersection(parts[:, None], parts[None])).sum() - shapely.area(parts).sum() < 1e-6
    )


# -- the standard network: parks at three levels, water, bridges, trees ---------------------------


@pytest.fixture(scope="module")
def paris():
    net = sengine.load(
        ROOT / "configs" / "paris.xml",
        sets=[
            "blockParks.mode=every",
            "blockParks.every=40",
            "lotParks.mode=every",
            "lotParks.every=60",
            "patios.mode=all",
            "patios.front=8",
        ],
    )
    layers, stats = net.run(seed=11, check_kinds=True)
    return net, layers, stats["report"], stats["counts"]


@pytest.mark.slow
def test_parks_at_every_level_in_one_network_without_a_cycle(paris):
    net, layers, report, _ = paris
    import networkx as nx

    g = nx.DiGraph([(a, c) for a, _, c, _ in net.validate().edges])
    assert nx.is_directed_acyclic_graph(g)
    parks = layers["patios"]["parks"]
    assert set(np.asarray(parks["level"]).astype(str)) == {"district", "block", "lot", "patio"}
    # a lot park is a lot with no building
    lp = parks.take(np.asarray(parks["level"]).astype(str) == "lot")
    b = layers["buildings"]["buildings"]
    assert len(lp) > 20
    assert not np.isin(b["lot"], lp["lot"]).any()
    pi, bi = shapely.STRtree(b.geometry).query(lp.geometry, predicate="intersects")
    assert shapely.area(shapely.intersection(lp.geometry[pi], b.geometry[bi])).sum() < 1e-3
    # block parks are no longer blocks; patios touch no building
    blocks = layers["blockParks"]["blocks"]
    bp = parks.take(np.asarray(parks["level"]).astype(str) == "block")
    assert not np.isin(bp.parent, blocks.ids).any()
    pz = parks.take(np.asarray(parks["level"]).astype(str) == "patio")
    pi, bi = shapely.STRtree(b.geometry).query(pz.geometry, predicate="intersects")
    assert len(pz) > 0 and len(pi) == 0


@pytest.mark.slow
def test_each_node_counts_what_it_made(paris):
    # the parks nodes hand the stream on and roads.bridges every road: the counts line says what each added
    _, layers, _, counts = paris
    level = np.asarray(layers["patios"]["parks"]["level"]).astype(str)
    made = {node: int((level == lev).sum()) for node, lev in PARK_NODES.items()}
    assert {node: counts[node] for node in PARK_NODES} == made
    assert sum(made.values()) == len(level) and min(made.values()) > 0
    assert counts["bridges"] == len(layers["bridges"]["bridges"]) > 0
    assert counts["bridges"] < len(layers["bridges"]["roads"])


PARK_NODES = {"districtParks": "district", "blockParks": "block", "lotParks": "lot", "patios": "patio"}


@pytest.mark.slow
def test_no_tree_on_a_road_in_water_or_in_a_building(paris):
    _, layers, report, _ = paris
    t = layers["vegetation"]["vegetation"]
    assert len(t) > 10_000
    pts = t.geometry
    for lay in (layers["blocks"]["streets"], layers["water"]["water"], layers["buildings"]["buildings"]):
        hit, _ = shapely.STRtree(lay.geometry).query(pts, predicate="intersects")
        assert len(hit) == 0
    d, _ = cKDTree(shapely.get_coordinates(pts)).query(shapely.get_coordinates(pts), k=2)
    assert d[:, 1].min() >= 4.0 - 1e-9
    zones = set(np.asarray(t["zone"]).astype(str))
    assert {"avenue", "district", "block", "lot", "patio"} <= zones
    # the report's counts are the layer's
    os_ = report["planning"]["open_space"]["city"]
    assert os_["trees"] == len(t) == report["vegetation"]["trees"]
    assert 0 < os_["park_share"] < 1
    assert sum(d["trees"] for d in report["planning"]["open_space"]["districts"].values()) <= len(t)


@pytest.mark.slow
def test_the_river_has_water_and_bridges(paris):
    _, layers, report, _ = paris
    water = layers["water"]["water"]
    assert len(water) == 1 and 0.5e6 < water.area() < 0.7e6
    roads = layers["bridges"]["roads"]
    br = roads.take(np.asarray(roads["bridge"], bool))
    assert 1 <= len(br) <= 3
    assert shapely.length(br.geometry).max() <= 250
    assert shapely.crosses(br.geometry, water.geometry[0]).all()
    decks = layers["bridges"]["bridges"]
    assert len(decks) == len(br)
    # both ends of every bridge are nodes of the street graph: road ends shared (exactly) with >= 2 bank-side roads
    rest = roads.take(~np.asarray(roads["bridge"], bool)).geometry
    ends = np.concatenate([shapely.get_coordinates(shapely.get_point(rest, i)) for i in (0, -1)])
    for line in br.geometry:
        for end in shapely.get_coordinates(line)[[0, -1]]:
            assert (ends == end).all(axis=1).sum() >= 2


def test_a_bridge_is_noded_into_the_bank_road_it_lands_on():
    """A river 100 m wide, one unbroken bank road on each side, a major road ending on the south bank:
    the bridge's far end splits the north bank road there, so the three share one node."""
    water = Layer.from_geoms([shapely.box(-1000, 0, 1000, 100)])
    roads = Layer.from_geoms(
        [
            shapely.LineString([(-900, 0), (-300, 0), (0, 0), (800, 0)]),  # south bank
            shapely.LineString([(-900, 100), (-200, 100), (450, 100), (900, 100)]),  # north bank, no vertex at x=3
            shapely.LineString([(3, -400), (3, 0)]),  # the major road ending on the water
        ],
        major=np.array([False, False, True]),
        width=np.array([8.0, 8.0, 12.0]),
    )
    res = get("roads.bridges")("b", {"snap": 20.0}, Context()).run(roads=roads, water=water)
    out = res["roads"]
    bridge = np.asarray(out["bridge"], bool)
    assert bridge.sum() == 1 and res.report["bank_roads_split"] == 1 and len(out) == 5
    a, b = shapely.get_coordinates(out.geometry[bridge][0])
    assert np.allclose(a, (3, 0)) and np.allclose(b, (3, 100))
    rest = out.geometry[~bridge]
    starts = shapely.get_coordinates(shapely.get_point(rest, 0))
    stops = shapely.get_coordinates(shapely.get_point(rest, -1))
    assert (stops == b).all(axis=1).sum() == 1 and (starts == b).all(axis=1).sum() == 1
    assert np.isclose(shapely.length(rest).sum(), 1700 + 1800 + 400)


# -- a real extract: avenue trees on sidewalks, stopping at crossings -----------------------------


@pytest.fixture(scope="module")
def kirchberg(tmp_path_factory):
    cfg = tmp_path_factory.mktemp("k") / "k.xml"
    cfg.write_text(
        f'<sengine version="1"><city name="k" seed="2"><map kind="osm" src="{data_file("kirchberg_iller.osm")}"/></city>'
        '<network base="loadmap"/></sengine>'
    )
    net = sengine.load(cfg)
    return net.run(seed=2)


def test_avenue_trees_lie_on_sidewalks_and_stop_at_crossings(kirchberg):
    layers, _ = kirchberg
    t = layers["vegetation"]["vegetation"]
    ave = t.take(np.asarray(t["zone"]).astype(str) == "avenue")
    assert len(ave) > 20
    walk = layers["blocks"]["sidewalks"].geometry
    hit, _ = shapely.STRtree(walk).query(ave.geometry, predicate="within")
    assert len(np.unique(hit)) == len(ave)
    roads = layers["clean"]["roads"].geometry
    ends = np.concatenate([shapely.get_coordinates(shapely.get_point(roads, i)) for i in (0, -1)])
    node, deg = np.unique(np.round(ends, 3), axis=0, return_counts=True)
    crossings = node[deg >= 3]
    d, _ = cKDTree(crossings).query(shapely.get_coordinates(ave.geometry))
    assert d.min() >= 8.0 - 0.5  # avenue_clear, measured from the sidewalk corner (further from the centre)


def test_only_wide_streets_are_avenues():
    # Paris plants its boulevards and avenues, not its narrow rues: avenue_min_width keeps the trees whose
    # nearest street is that wide, and says so if it has no street widths to read (Monaco: streets of
    # many widths)
    def run(name, params=None, **ins):
        return get(name)(name.split(".")[0], params or {}, Context(seed=2)).run(**ins)

    raw = run("osm.read", {"path": str(data_file("monaco.osm.pbf"))})["roads"]
    roads = run("roads.clean", {}, roads=raw)["roads"]
    city = run("blocks.circuits", {}, roads=roads)
    ins = dict(blocks=city["blocks"], sidewalks=city["sidewalks"], streets=city["streets"], roads=roads)

    def avenue(**params):
        t = run("vegetation.trees", params, **ins)["vegetation"]
        return t.take(np.asarray(t["zone"]).astype(str) == "avenue")

    every = avenue()
    width = np.asarray(roads["width"], float)
    cut = float(np.median(width[width > 0])) + 0.5
    wide = avenue(avenue_min_width=cut)
    assert 0 < len(wide) < len(every)
    # the same trees, fewer of them
    assert {tuple(c) for c in shapely.get_coordinates(wide.geometry)} <= {
        tuple(c) for c in shapely.get_coordinates(every.geometry)
    }
    nearest = shapely.STRtree(roads.geometry).query_nearest(wide.geometry, all_matches=False)[1]
    assert (width[nearest] >= cut).all()
    with pytest.raises(NodeError, match="avenue_min_width"):
        run("vegetation.trees", {"avenue_min_width": cut}, **{**ins, "roads": None})


def test_same_seed_same_bytes(kirchberg, tmp_path):
    layers, _ = kirchberg
    node = get("vegetation.trees")
    ins = dict(
        blocks=layers["landuse"]["blocks"],
        parks=layers["majorRoads"]["parks"],
        sidewalks=layers["blocks"]["sidewalks"],
        streets=layers["blocks"]["streets"],
        buildings=layers["buildings"]["buildings"],
        water=layers["majorRoads"]["water"],
    )
    a = node("vegetation", {}, Context(seed=2)).run(**ins)["vegetation"]
    b = node("vegetation", {}, Context(seed=2)).run(**ins)["vegetation"]
    c = node("vegetation", {}, Context(seed=3)).run(**ins)["vegetation"]
    assert json.dumps(a.to_geojson()) == json.dumps(b.to_geojson())
    assert glb_bytes({"vegetation": a})[0] == glb_bytes({"vegetation": b})[0]
    assert json.dumps(a.to_geojson()) != json.dumps(c.to_geojson())


def test_an_unknown_plant_is_a_parameter_error():
    node = get("vegetation.trees")("vegetation", {"avenue_plants": "plane,baobab"}, Context(seed=1))
    with pytest.raises(ParameterError, match="baobab"):
        node.run(blocks=Layer.from_geoms([shapely.box(0, 0, 50, 50)], district=-1))


# -- exports --------------------------------------------------------------------------------------


def _trees():
    node = get("vegetation.trees")("vegetation", {"region_pattern": "versailles"}, Context(seed=5))
    blocks = Layer.from_geoms(
        [shapely.box(x, y, x + 80, y + 60) for x in range(0, 1000, 100) for y in range(0, 800, 80)], district=-1
    )
    regions = Layer.from_geoms([shapely.box(1200, 0, 2000, 500)], kind="region")
    parks = Layer.from_geoms([shapely.box(0, 900, 600, 1300)], level="district", district=-1)
    return node.run(blocks=blocks, regions=regions, parks=parks)["vegetation"]


def test_trees_are_instanced_in_the_glb_and_pass_the_validator(tmp_path):
    t = _trees()
    assert {"avenue", "region", "district"} <= set(np.asarray(t["zone"]).astype(str))
    inst, counts = glb_bytes({"vegetation": t})
    baked, _ = glb_bytes({"vegetation": t}, instancing=False)
    assert counts["vegetation"]["instances"] == len(t)
    # 40 bytes a tree for its placement and 37 for its row of the property table (baked: 750, no table)
    assert len(inst) < len(baked) / 8
    n = struct.unpack("<I", inst[12:16])[0]
    doc = json.loads(inst[20 : 20 + n])
    assert "EXT_mesh_gpu_instancing" in doc["extensionsUsed"]
    cats = sorted(set(np.asarray(t["category"]).astype(str)))
    assert [m["name"] for m in doc["meshes"]] == [f"vegetation/{c}" for c in cats]
    got = sum(
        doc["accessors"][nd["extensions"]["EXT_mesh_gpu_instancing"]["attributes"]["TRANSLATION"]]["count"]
        for nd in doc["nodes"]
    )
    assert got == len(t)
    # every instance names its plant: its feature id is its row in the property table (EXT_instance_features)
    binary = inst[20 + n + 8 :]

    def view(i, dtype):
        v = doc["bufferViews"][i]
        return np.frombuffer(binary[v.get("byteOffset", 0) : v.get("byteOffset", 0) + v["byteLength"]], dtype)

    meta = doc["extensions"]["EXT_structural_metadata"]
    table = meta["propertyTables"][0]
    assert table["class"] == "vegetation" and table["count"] == len(t)
    enum = meta["schema"]["enums"][meta["schema"]["classes"]["vegetation"]["properties"]["category"]["enumType"]]
    names = {e["value"]: e["name"] for e in enum["values"]}
    category = np.array([names[c] for c in view(table["properties"]["category"]["values"], np.uint8)])
    height = view(table["properties"]["height"]["values"], "<f4")
    assert (category == np.asarray(t["category"]).astype(str)).all()
    assert np.allclose(height, np.asarray(t["height"], float), atol=1e-4)
    seen = []
    for nd in doc["nodes"]:
        ids = nd["extensions"]["EXT_instance_features"]["featureIds"][0]
        attrs = nd["extensions"]["EXT_mesh_gpu_instancing"]["attributes"]
        assert ids["propertyTable"] == 0 and ids["attribute"] == 0
        rows = view(doc["accessors"][attrs["_FEATURE_ID_0"]]["bufferView"], "<f4").astype(np.int64)
        assert ids["featureCount"] == len(np.unique(rows)) == len(rows)
        assert (category[rows] == nd["name"].split("/")[1]).all()
        xyz = view(doc["accessors"][attrs["TRANSLATION"]]["bufferView"], "<f4").reshape(-1, 3)
        xy = shapely.get_coordinates(t.geometry[rows])
        assert np.allclose(xyz[:, 0], xy[:, 0], atol=0.01) and np.allclose(-xyz[:, 2], xy[:, 1], atol=0.01)
        seen.append(rows)
    assert np.array_equal(np.sort(np.concatenate(seen)), np.arange(len(t)))
    if _validator_ready():
        for data, name in ((inst, "i.glb"), (baked, "b.glb")):
            (tmp_path / name).write_bytes(data)
            report = gltf_validate(tmp_path / name)
            assert report["issues"]["numErrors"] == 0, report["issues"]["messages"][:5]


def test_trees_in_every_format(tmp_path):
    t = _trees()
    b = Layer.from_geoms([shapely.box(5, 5, 20, 20)], height=10.0, floors=3, roof="flat", lot=-1, district=-1)
    export = get("export.city")(
        "export", {}, Context(seed=1, out=tmp_path, formats=frozenset({"geojson", "cityjson", "png", "gpkg"}))
    )
    export.run(vegetation=t, buildings=b)
    gj = json.loads((tmp_path / "vegetation.geojson").read_text())
    assert len(gj["features"]) == len(t)
    props = gj["features"][0]["properties"]
    assert {"zone", "category", "type", "instance", "height", "crown"} <= set(props)
    assert gj["features"][0]["geometry"]["type"] == "Point"
    doc = json.loads((tmp_path / "buildings.city.json").read_text())
    svo = [o for o in doc["CityObjects"].values() if o["type"] == "SolitaryVegetationObject"]
    assert len(svo) == len(t)
    validate_cityjson(doc)
    assert (tmp_path / "city.gpkg").stat().st_size > 0


@settings(max_examples=40, deadline=None)
@given(
    st.lists(
        st.tuples(st.floats(0, 5_000), st.floats(0, 5_000), st.floats(5, 300), st.floats(0, 3)), min_size=2, max_size=6
    )
)
def test_avenue_trees_of_a_ring_do_not_depend_on_the_rings_before_it(rings):
    """The same ring gives the same trees, to the bit, whatever else is in the batch (shards, chunks)."""
    lines = np.array(
        [
            shapely.affinity.rotate(shapely.box(x, y, x + w, y + 0.7 * w), a, use_radians=True).exterior
            for x, y, w, a in rings
        ],
        dtype=object,
    )
    alone, ring_alone, ang_alone = avenue_points(lines[-1:], spacing=7.3, clear=4.0, corner=35.0)
    xy, ring, ang = avenue_points(lines, spacing=7.3, clear=4.0, corner=35.0)
    last = ring == len(lines) - 1
    assert np.array_equal(xy[last], alone) and np.array_equal(ang[last], ang_alone)

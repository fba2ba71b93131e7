"""export.city and sengine.io: glb, GeoJSON (RFC 7946), streets.osm, preview.png, OBJ, CityJSON."""

from __future__ import annotations

import json
from collections import Counter

import numpy as np
import osmium
import pytest
import shapely
import trimesh
from _city import MONACO_ORIGIN, grid_city, monaco_lots
from PIL import Image

from sengine import Context, Layer
from sengine.geom.crs import from_lonlat, local_crs, to_lonlat
from sengine.nodes.export import mesh
from sengine.nodes.export.gltf import COLOURS
from sengine.nodes.export.prepare import prepare_layers
from sengine.plan import CityPlan
from sengine.registry import get

Export = get("export.city")
Extrude = get("buildings.extrude")
ALL = frozenset({"glb", "geojson", "osm", "png", "obj", "cityjson"})


@pytest.fixture(scope="module")
def city(tmp_path_factory):
    plan, layers = grid_city(height_map=tmp_path_factory.mktemp("maps"))
    layers["buildings"] = Extrude("buildings", {}, Context(seed=3, plan=plan)).run(lots=layers["lots"])["buildings"]
    return plan, layers


def export(out, plan, layers, formats=ALL, options=None, **params):
    node = Export(
        "export", params, Context(seed=3, plan=plan, out=out, formats=frozenset(formats), options=dict(options or {}))
    )
    out = node.run(**layers)
    assert dict(out) == {}
    return out.report


@pytest.fixture(scope="module")
def written(city, tmp_path_factory):
    plan, layers = city
    out = tmp_path_factory.mktemp("out")
    export(out, plan, layers)
    return out


# -- mesh building ---------------------------------------------------------------
def test_extrusion_is_closed_and_has_the_right_volume():
    lots = monaco_lots()
    g = lots.geometry
    h = np.linspace(3.0, 60.0, len(g))
    v, f, _ = mesh.extrude(g, h)
    tm = trimesh.Trimesh(v, f, process=False)
    assert tm.is_winding_consistent
    np.testing.assert_allclose(tm.volume, (shapely.area(g) * h).sum(), rtol=1e-9)
    # each building on its own is watertight (sample a few with holes and concave ones)
    holed = np.flatnonzero(shapely.get_num_interior_rings(g) > 0)
    assert holed.size
    for i in list(holed[:5]) + list(range(0, len(g), 97)):
        v, f, _ = mesh.extrude(g[i : i + 1], [10.0])
        one = trimesh.Trimesh(v, f, process=True)
        assert one.is_watertight and one.volume > 0
        np.testing.assert_allclose(one.volume, g[i].area * 10.0, rtol=1e-9)


def test_flat_surfaces_cover_the_polygons_facing_up():
    lots = monaco_lots()
    v, f, _ = mesh.flat(lots.geometry, 0.5)
    tm = trimesh.Trimesh(v, f, process=False)
    np.testing.assert_allclose(tm.area, lots.area(), rtol=1e-9)
    assert (tm.face_normals[:, 2] > 0.999).all()
    assert np.allclose(v[:, 2], 0.5)


# -- glb -------------------------------------------------------------------------
def test_glb_nodes_bounds_and_heights(city, written):
    plan, layers = city
    scene = trimesh.load(written / "city.glb")
    assert isinstance(scene, trimesh.Scene)
    assert set(scene.graph.nodes_geometry) == set(layers)
    assert set(scene.geometry) == set(layers)
    b = scene.geometry["buildings"]
    # metres, Y up: max Y is the tallest building
    assert b.bounds[1, 1] == pytest.approx(layers["buildings"]["height"].max(), abs=1e-4)
    assert b.bounds[0, 1] == pytest.approx(0.0, abs=1e-6)
    # planar x -> X, planar y -> -Z
    lo, hi = shapely.total_bounds(layers["buildings"].geometry).reshape(2, 2)
    np.testing.assert_allclose(b.bounds[:, 0], [lo[0], hi[0]], atol=1e-3)
    np.testing.assert_allclose(b.bounds[:, 2], [-hi[1], -lo[1]], atol=1e-3)
    # vertex counts match the batched meshes, and the solid keeps its volume
    expected_v = 2 * shapely.get_num_coordinates(layers["buildings"].geometry).sum() - 2 * len(layers["buildings"])
    assert len(b.vertices) == expected_v
    vol = (shapely.area(layers["buildings"].geometry) * layers["buildings"]["height"]).sum()
    assert b.volume == pytest.approx(vol, rel=1e-5)
    lots = scene.geometry["lots"]
    assert lots.area == pytest.approx(layers["lots"].area(), rel=1e-5)
    # per-layer colours
    assert tuple(b.visual.material.baseColorFactor[:3]) == COLOURS["buildings"]


def test_glb_large_coordinates_keep_precision(tmp_path):
    lots = monaco_lots()
    utm = "EPSG:32632"
    ll = shapely.transform(lots.geometry, to_lonlat(lots.meta["crs"]))
    g = shapely.transform(ll, from_lonlat(utm))
    b = Extrude("b", {"setback": 0.5, "min_area": 5.0}, Context(seed=1)).run(
        lots=Layer.from_geoms(g, ids=lots.ids, meta={"crs": utm})
    )["buildings"]
    export(tmp_path, None, {"buildings": b}, {"glb"}, options={"origin": "geo"})
    scene = trimesh.load(tmp_path / "city.glb")
    world = scene.to_geometry()
    lo, hi = shapely.total_bounds(b.geometry).reshape(2, 2)
    assert lo[0] > 1e5  # really a UTM frame
    np.testing.assert_allclose(world.bounds[:, 0], [lo[0], hi[0]], atol=0.02)
    np.testing.assert_allclose(world.bounds[:, 2], [-hi[1], -lo[1]], atol=0.02)
    assert scene.metadata["sengine"]["planar_offset"][0] != 0.0


# -- GeoJSON ---------------------------------------------------------------------
def _rings(geom):
    if geom["type"] == "Polygon":
        yield from [(k, np.array(r)) for k, r in enumerate(geom["coordinates"])]
    elif geom["type"] == "MultiPolygon":
        for poly in geom["coordinates"]:
            yield from [(k, np.array(r)) for k, r in enumerate(poly)]


def _signed_area(r):
    return 0.5 * np.sum(r[:-1, 0] * r[1:, 1] - r[1:, 0] * r[:-1, 1])


def check_rfc7946(path, layer, origin):
    text = path.read_text()
    data = json.loads(text)
    assert data["type"] == "FeatureCollection" and "crs" not in data
    assert len(data["features"]) == len(layer)
    lat0, lon0 = origin
    cols = set(layer.columns) | {"id", "parent_id"}
    for feat, fid in zip(data["features"], layer.ids.tolist()):
        assert feat["type"] == "Feature" and feat["id"] == fid
        assert set(feat["properties"]) == cols
        coords = np.array(shapely.get_coordinates(shapely.from_geojson(json.dumps(feat["geometry"]))))
        assert (np.abs(coords[:, 0] - lon0) < 0.5).all() and (np.abs(coords[:, 1] - lat0) < 0.5).all()
        assert np.allclose(coords, np.round(coords, 7), atol=1e-12)
        for k, ring in _rings(feat["geometry"]):
            a = _signed_area(ring)
            assert (a > 0) if k == 0 else (a < 0), "exterior rings CCW, holes CW"
    # coordinates go back to the planar frame within 2 cm
    back = shapely.transform(
        shapely.from_geojson([json.dumps(f["geometry"]) for f in data["features"]]),
        from_lonlat(layer.meta.get("crs") or local_crs(origin)),
    )
    assert shapely.hausdorff_distance(back, layer.geometry).max() < 0.02
    return data


def test_geojson_every_layer(city, written):
    plan, layers = city
    prepared, _ = prepare_layers(layers, {"district": plan, "landuse": plan})
    for name, layer in prepared.items():
        data = check_rfc7946(written / f"{name}.geojson", layer, plan.origin)
        props = data["features"][0]["properties"]
        for col in layers[name].columns:
            v = layer[col][0]
            v = v.item() if hasattr(v, "item") else v
            assert props[col] == (None if col in layer.meta.get("null_negative", ()) and v < 0 else v)
    # planar (0, 0) is the city's origin
    lon, lat = to_lonlat(local_crs(plan.origin))(np.zeros((1, 2)))[0]
    assert (lat, lon) == pytest.approx(plan.origin, abs=1e-9)


def test_geojson_real_polygons_with_holes(tmp_path):
    lots = monaco_lots()
    # reversed rings on input must still come out as RFC 7946 wants
    flipped = lots.with_geometry(shapely.orient_polygons(lots.geometry, exterior_cw=True))
    flipped = flipped.with_columns(height=np.where(np.arange(len(lots)) % 5 == 0, np.nan, 10.0))
    export(tmp_path, CityPlan(origin=MONACO_ORIGIN), {"lots": flipped}, {"geojson"})
    data = check_rfc7946(tmp_path / "lots.geojson", prepare_layers({"lots": flipped})[0]["lots"], MONACO_ORIGIN)
    assert data["features"][0]["properties"]["height"] is None


@pytest.mark.parametrize("chunk", [1, 7, 100])
def test_geojson_written_in_chunks_is_the_same_text(city, written, chunk):
    from sengine.io.geojson import feature_collection_chunks

    plan, layers = city
    text = (written / "lots.geojson").read_text(encoding="utf-8")
    lots = prepare_layers(layers, {"district": plan, "landuse": plan})[0]["lots"]
    assert len(lots) > 100  # so that chunks of 100 split it too
    pieces = list(feature_collection_chunks(lots, to_lonlat(lots.meta["crs"]), name="lots", chunk=chunk))
    assert len(pieces) == 2 + -(-len(lots) // chunk)
    assert "".join(pieces) + "\n" == text


# -- OSM XML ---------------------------------------------------------------------
def test_streets_osm_reads_back_with_shared_junctions(city, written):
    _, layers = city
    roads = layers["roads"]
    ways, refs, tags = 0, Counter(), Counter()
    nodes = {}
    for o in osmium.FileProcessor(str(written / "streets.osm")):
        if o.is_node():
            nodes[o.id] = (o.location.lon, o.location.lat)
            assert o.id < 0
        elif o.is_way():
            ways += 1
            assert o.id < 0
            refs.update(n.ref for n in o.nodes)
            tags[o.tags["highway"]] += 1
    assert ways == len(roads)
    assert set(refs) == set(nodes)
    # a junction in the plan (an end point shared by several segments) is one shared node
    ends = np.round(np.concatenate([shapely.get_coordinates(shapely.get_point(roads.geometry, k)) for k in (0, -1)]), 3)
    _, counts = np.unique(ends, axis=0, return_counts=True)
    assert sum(1 for c in refs.values() if c > 1) == (counts > 1).sum()
    assert len(nodes) == len(counts)
    assert tags == Counter(
        {"primary": int((roads["class"] == "major").sum()), "residential": int((roads["class"] == "minor").sum())}
    )


# -- preview ---------------------------------------------------------------------
def test_preview_png(city, written):
    path = written / "preview.png"
    assert path.stat().st_size < 3_000_000
    with Image.open(path) as im:
        assert max(im.size) == 1600
        assert "date" not in im.info and "time" not in im.info
        rgb = np.asarray(im.convert("RGB")).reshape(-1, 3)
    key = (rgb[:, 0].astype(np.int64) << 16) | (rgb[:, 1].astype(np.int64) << 8) | rgb[:, 2]
    counts = Counter(key.tolist())

    def n_pixels(c):
        return counts.get((c[0] << 16) | (c[1] << 8) | c[2], 0)

    assert n_pixels(COLOURS["roads"]) > 1000
    assert n_pixels(COLOURS["parks"]) > 100
    assert n_pixels(COLOURS["lots"]) > 1000
    assert len(counts) > 20  # the height ramp is used


def test_preview_outlines_the_maps_buildings_only():
    from sengine.nodes.export.preview import _FIXED, render

    boxes = [shapely.box(20 * i, 0, 20 * i + 12, 12) for i in range(6)]
    source = np.array(["generated", "osm"] * 3, dtype=object)
    built = Layer.from_geoms(boxes, height=np.full(6, 10.0), source=source)
    edge = _FIXED["map_edge"]

    def edge_pixels(layer):
        image = np.asarray(render({"buildings": layer}, size=400))
        scale = (400 - 2 * 10) / 112  # px per m: 10 px padding, the 112 m the boxes span
        return (np.flatnonzero((image[:-64] == edge).any(axis=0)) - 10) / scale  # columns, in metres

    cols = edge_pixels(built)
    assert len(cols) and all(any(20 * i - 1 <= c <= 20 * i + 13 for i in (1, 3, 5)) for c in cols)
    assert not len(edge_pixels(built.with_columns(source=np.full(6, "generated", dtype=object))))


# -- OBJ / CityJSON ----------------------------------------------------------------
def test_obj_one_group_per_layer(city, written):
    _, layers = city
    text = (written / "city.obj").read_text()
    groups = [line[2:] for line in text.splitlines() if line.startswith("g ")]
    assert sorted(groups) == sorted(layers)
    assert (written / "city.mtl").read_text().count("newmtl") == len(layers)
    tm = trimesh.load(written / "city.obj", force="mesh", process=False)
    assert tm.bounds[1, 1] == pytest.approx(layers["buildings"]["height"].max(), abs=1e-3)


def test_cityjson_lod1_solids(city, written):
    plan, layers = city
    doc = json.loads((written / "buildings.city.json").read_text())
    assert doc["type"] == "CityJSON" and doc["version"] == "2.0"
    objs = doc["CityObjects"]
    assert len(objs) == len(layers["buildings"])
    verts = np.array(doc["vertices"]) * doc["transform"]["scale"] + doc["transform"]["translate"]
    b0 = objs[f"building-{layers['buildings'].ids[0]}"]
    assert b0["type"] == "Building"
    assert b0["attributes"]["measuredHeight"] == pytest.approx(layers["buildings"]["height"][0], abs=5e-4)  # mm
    geom = b0["geometry"][0]
    # export.city's default lod is 2; these buildings all have flat roofs, so the solids are the boxes
    assert geom["type"] == "Solid" and geom["lod"] == "2"
    shell = geom["boundaries"][0]
    # a closed shell: as a triangle mesh it has the footprint area times the height as volume
    tris = []
    for surface in shell:
        ring = surface[0]
        tris += [[ring[0], ring[k], ring[k + 1]] for k in range(1, len(ring) - 1)]
    tm = trimesh.Trimesh(verts, np.array(tris), process=True)
    assert tm.is_watertight
    # the local frame has no EPSG code: the solids are in the UTM zone of the origin, and land where the
    # GeoJSON footprints are
    origin_zone = 32600 + int((plan.origin[1] + 180) // 6) + 1
    assert doc["metadata"]["referenceSystem"] == f"https://www.opengis.net/def/crs/EPSG/0/{origin_zone}"
    utm = f"EPSG:{origin_zone}"
    footprint = shapely.transform(
        layers["buildings"].geometry[0], lambda xy: from_lonlat(utm)(to_lonlat(local_crs(plan.origin))(xy))
    )
    assert tm.volume == pytest.approx(footprint.area * layers["buildings"]["height"][0], rel=1e-4)  # mm vertices
    floor = verts[shell[0][0]]  # the bottom surface's outer ring
    assert (floor[:, 2] == 0).all()
    assert shapely.distance(footprint.exterior, shapely.points(floor[:, :2])).max() < 0.002


# -- node behaviour ------------------------------------------------------------------
def test_default_formats_and_format_choice(city, tmp_path):
    plan, layers = city
    export(tmp_path / "d", plan, layers, formats=())
    names = sorted(p.name for p in (tmp_path / "d").iterdir())
    page = ["index.html", "viewer.js", "city.view.js"]
    assert names == sorted(["city.glb", "preview.png", "streets.osm", *page] + [f"{n}.geojson" for n in layers])
    export(tmp_path / "o", plan, {"buildings": layers["buildings"]}, formats={"obj"})
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == ["city.mtl", "city.obj"]


def test_same_inputs_same_bytes(city, tmp_path):
    plan, layers = city
    export(tmp_path / "a", plan, layers)
    export(tmp_path / "b", plan, layers)
    files = sorted(p.name for p in (tmp_path / "a").iterdir())
    assert len(files) == 7 + 6  # geojson x7, glb, osm, png, obj, mtl, cityjson
    for name in files:
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name


def test_report_counts(city, tmp_path):
    plan, layers = city
    report = export(tmp_path, plan, layers, formats={"glb", "osm"})
    assert report["osm.ways"] == len(layers["roads"])
    assert report["glb.buildings.triangles"] > 0
    assert all(isinstance(v, (int, float)) for v in report.values())


def test_in_memory_run_writes_nothing(city):
    node = Export("export", {}, Context())
    out = node.run(roads=city[1]["roads"])
    assert dict(out) == {} and not out.report


def test_empty_layers_export(tmp_path):
    export(tmp_path, CityPlan(), {"lots": Layer.empty(), "roads": Layer.empty()})
    assert json.loads((tmp_path / "lots.geojson").read_text())["features"] == []
    assert sum(1 for o in osmium.FileProcessor(str(tmp_path / "streets.osm"))) == 0
    with Image.open(tmp_path / "preview.png") as im:
        im.load()


# -- random polygons -------------------------------------------------------------------
def _star(seed: int, n: int, hole: bool, offset: float):
    rng = np.random.default_rng(seed)
    ang = np.sort(rng.uniform(0, 2 * np.pi, n))
    r = rng.uniform(5, 20, n)
    shell = np.column_stack([np.cos(ang) * r, np.sin(ang) * r]) + offset
    poly = shapely.Polygon(shell)
    if hole and poly.is_valid:
        poly = poly.difference(shapely.Point(offset, offset).buffer(2.0, 4))
    return poly


@pytest.mark.parametrize("offset", [0.0, 5.0e5])
def test_random_polygons_mesh_exactly(offset):
    from hypothesis import given, settings
    from hypothesis import strategies as st

    @settings(max_examples=80, deadline=None)
    @given(
        seed=st.integers(0, 2**32 - 1),
        n=st.integers(3, 40),
        hole=st.booleans(),
        h=st.floats(0.5, 300),
        rev=st.booleans(),
    )
    def check(seed, n, hole, h, rev):
        poly = _star(seed, n, hole, offset)
        if not poly.is_valid or poly.area < 1.0 or poly.geom_type != "Polygon":
            return
        if rev:
            poly = shapely.orient_polygons(poly, exterior_cw=True)
        v, f, _ = mesh.extrude(np.array([poly]), [h])
        tm = trimesh.Trimesh(v - [offset, offset, 0], f, process=True)
        assert tm.is_watertight and tm.is_winding_consistent
        assert tm.volume == pytest.approx(poly.area * h, rel=1e-6)
        v, f, _ = mesh.flat(np.array([poly]), 0.0)
        flat = trimesh.Trimesh(v - [offset, offset, 0], f, process=False)
        assert flat.area == pytest.approx(poly.area, rel=1e-6)
        assert (flat.face_normals[:, 2] > 0).all()

    check()


def test_water_lies_under_the_streets(city, tmp_path):
    plan, layers = city
    x0, y0, x1, y1 = shapely.total_bounds(layers["streets"].geometry)
    river = shapely.box(x0, (y0 + y1) / 2 - 20, x1, (y0 + y1) / 2 + 20)
    water = Layer.from_geoms([river, shapely.Point(x0, y0).buffer(30)], meta=layers["streets"].meta, kind="water")
    report = export(tmp_path, plan, {**layers, "water": water}, formats={"glb", "geojson", "png"})
    assert report["geojson.water"] == 2 and report["glb.water.triangles"] > 0
    w = trimesh.load(tmp_path / "city.glb").geometry["water"]
    assert w.area == pytest.approx(water.area(), rel=1e-3)
    assert w.bounds[:, 1] == pytest.approx([-0.5, -0.5])  # below the street surface (y = 0)
    with Image.open(tmp_path / "preview.png") as im:
        rgb = np.asarray(im.convert("RGB")).reshape(-1, 3)
    assert (rgb == COLOURS["water"]).all(axis=1).sum() > 100

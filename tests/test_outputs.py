"""Outputs people open (issue 16): GeoPackage, GeoParquet, clean geometry, OSM that round-trips, 3D origins, attribution.

Every output layer of every demo and shipped OSM extract is read back with
the tools a user has (pyogrio / GDAL, pyarrow, pyosmium, trimesh) and checked
with numbers: valid, non-empty geometries of one type per layer, the same
feature count in every format, GeoParquet 1.1 metadata, every way's nodes
present, the city at the glTF origin.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import osmium
import pyarrow.parquet as pq
import pyogrio
import pytest
import shapely
import trimesh
from conftest import CONFIGS, DATA
from hypothesis import given
from hypothesis import strategies as st
from PIL import Image

import sengine
from sengine import Layer
from sengine.cli import main
from sengine.geom.cleanup import clean_geometries, layer_type, snap_to_type
from sengine.nodes.export.gpkg import write_gpkg_layer
from sengine.nodes.export.parquet import ParquetLayerWriter
from sengine.nodes.export.table import OSM_ATTRIBUTION

VECTOR = "geojson,gpkg,parquet"
DEMOS = ["manhattan", "districts", "paris", "roadmap", "helsinki", "monaco"]
EXTRACTS = ["helsinki_centre.osm.pbf", "monaco.osm.pbf", "west_oakland.osm.bz2", "kirchberg_iller.osm"]
TYPES = {"Polygon", "MultiPolygon", "LineString", "MultiLineString", "Point"}  # Point: the trees


def run_config(name: str, out: Path, formats: str = VECTOR, **options) -> dict:
    net = sengine.load(CONFIGS / f"{name}.xml")
    return net.run(out=out, formats=formats.split(","), workers=1, options=options).stats


def run_osm(path: Path, out: Path, *args: str) -> None:
    assert main(["osm", str(path), "-o", str(out), "--workers", "1", "-q", *args]) == 0


def check_vector_outputs(out: Path) -> dict[str, int]:
    """Every layer in GeoJSON, GPKG and GeoParquet: valid, non-degenerate, one type, the same counts; returns them."""
    layers = sorted(p.stem for p in out.glob("*.geojson"))
    assert layers
    tables = dict(pyogrio.list_layers(out / "city.gpkg").tolist())
    assert set(tables) == set(layers)
    counts = {}
    for name in layers:
        data = json.loads((out / f"{name}.geojson").read_text())
        geoms = shapely.from_geojson([json.dumps(f["geometry"]) for f in data["features"]]) if data["features"] else []
        info = pyogrio.read_info(out / "city.gpkg", layer=name)
        _, _, wkb, _ = pyogrio.raw.read(out / "city.gpkg", layer=name, return_fids=False)[:4]
        table = pq.read_table(out / f"{name}.parquet")
        in_gpkg = shapely.from_wkb(wkb)
        in_parquet = shapely.from_wkb(table["geometry"].to_numpy(zero_copy_only=False))
        assert len(geoms) == info["features"] == len(in_gpkg) == table.num_rows, name
        counts[name] = len(geoms)
        for frame, g in (("geojson", np.asarray(geoms, object)), ("gpkg", in_gpkg), ("parquet", in_parquet)):
            if not len(g):
                continue
            assert shapely.is_valid(g).all(), f"{name}.{frame}: {shapely.is_valid_reason(g[~shapely.is_valid(g)])[:3]}"
            assert not shapely.is_empty(g).any(), f"{name}.{frame}: empty geometries"
            kinds = set(shapely.get_type_id(g).tolist())
            assert len(kinds) == 1, f"{name}.{frame}: several geometry types {kinds}"
            dim = shapely.get_dimensions(g[0])
            if dim > 0:  # points (trees) have neither
                size = shapely.area(g) if dim == 2 else shapely.length(g)
                assert (size > 0).all(), f"{name}.{frame}: zero area or length"
        if len(in_gpkg):
            assert info["geometry_type"] == layer_type(in_gpkg) and info["geometry_type"] in TYPES
        check_geoparquet(out / f"{name}.parquet", in_parquet, table)
    return counts


def check_geoparquet(path: Path, geoms: np.ndarray, table) -> None:
    """GeoParquet 1.1 metadata: version, primary column, WKB, PROJJSON CRS, types and bbox of what is there."""
    meta = pq.read_schema(path).metadata
    geo = json.loads(meta[b"geo"])
    assert geo["version"] == "1.1.0" and geo["primary_column"] == "geometry"
    col = geo["columns"]["geometry"]
    assert col["encoding"] == "WKB"
    crs = col["crs"]
    assert crs["$schema"].startswith("https://proj.org/schemas/") and crs["id"]["authority"] == "EPSG"
    assert crs["type"] in ("ProjectedCRS", "GeographicCRS")
    if len(geoms):
        assert col["geometry_types"] == sorted({layer_type(geoms)})
        lo = shapely.total_bounds(geoms)
        np.testing.assert_allclose(col["bbox"], lo, atol=1e-9)
        # the covering column holds each row's bounds
        b = table["bbox"].to_pylist()
        np.testing.assert_allclose([[r["xmin"], r["ymin"], r["xmax"], r["ymax"]] for r in b], shapely.bounds(geoms))
    assert col["covering"]["bbox"]["xmin"] == ["bbox", "xmin"]


# -- every demo and every shipped extract ---------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("name", DEMOS)
def test_every_demo_layer_is_clean_in_every_vector_format(tmp_path, name):
    stats = run_config(name, tmp_path / "out")
    counts = check_vector_outputs(tmp_path / "out")
    report = {k: v for k, v in stats["report"]["export"].items() if k.startswith("gpkg.")}
    assert {k.split(".")[1]: v for k, v in report.items()} == counts


@pytest.mark.slow
@pytest.mark.parametrize("extract", EXTRACTS)
def test_every_extract_layer_is_clean_in_every_vector_format(tmp_path, extract):
    run_osm(DATA / extract, tmp_path / "out", "--format", VECTOR + ",glb,cityjson")
    check_vector_outputs(tmp_path / "out")
    # made from OpenStreetMap: every file says so
    assert json.loads((tmp_path / "out" / "lots.geojson").read_text())["attribution"] == OSM_ATTRIBUTION
    assert pyogrio.read_info(tmp_path / "out" / "city.gpkg", layer="lots")["layer_metadata"]["DESCRIPTION"] == (
        OSM_ATTRIBUTION
    )
    glb = trimesh.load(tmp_path / "out" / "city.glb")
    assert glb is not None
    doc = _glb_json(tmp_path / "out" / "city.glb")
    assert doc["asset"]["copyright"] == OSM_ATTRIBUTION
    assert OSM_ATTRIBUTION in json.loads((tmp_path / "out" / "buildings.city.json").read_text())["metadata"]["title"]


def _glb_json(path: Path) -> dict:
    data = path.read_bytes()
    n = int.from_bytes(data[12:16], "little")
    return json.loads(data[20 : 20 + n])


# -- Manhattan: what the files say --------------------------------------------------------
@pytest.fixture(scope="module")
def manhattan(tmp_path_factory):
    out = tmp_path_factory.mktemp("manhattan") / "out"
    stats = run_config("manhattan", out, "glb,geojson,osm,png,obj,cityjson,gpkg,parquet")
    return out, stats


def test_manhattan_values_rounded_null_and_named(manhattan):
    out, stats = manhattan
    districts = {"downtown", "village", "midtown", "uptown"}
    for name in ("blocks", "lots", "buildings"):
        feats = json.loads((out / f"{name}.geojson").read_text())["features"]
        props = [f["properties"] for f in feats]
        assert {p["district_name"] for p in props} <= districts and len({p["district_name"] for p in props}) == 4
        assert {p["landuse"] for p in props} == {"buildable"}
        for p in props:
            for v in p.values():
                if isinstance(v, float):
                    assert round(v, 3) == v  # millimetres, not 73.60000000000001
                assert v != "" and v != -1 or isinstance(v, bool)
    heights = [f["properties"]["height"] for f in json.loads((out / "buildings.geojson").read_text())["features"]]
    assert all(round(h, 3) == h for h in heights)
    parks = json.loads((out / "parks.geojson").read_text())["features"]
    assert parks[0]["properties"]["parent_id"] is None and parks[0]["properties"]["landuse"] == "park"
    # the GeoPackage keeps the same values with nulls as nulls
    meta, _, _, fields = pyogrio.raw.read(out / "city.gpkg", layer="parks")
    assert fields[list(meta["fields"]).index("parent_id")][0] is None or np.isnan(
        fields[list(meta["fields"]).index("parent_id")][0]
    )
    # zero-area lots were dropped and the report says how many
    clean = {k: v for k, v in stats["report"]["export"].items() if k.startswith("clean.")}
    dropped = sum(v for k, v in clean.items() if ".dropped" in k and k.startswith("clean.lots"))
    assert stats["counts"]["lots"] - dropped == stats["report"]["export"]["gpkg.lots.features"]


def test_manhattan_crs_and_no_attribution(manhattan):
    out, _ = manhattan
    # a synthetic city: no OSM notice anywhere
    assert "attribution" not in json.loads((out / "roads.geojson").read_text())
    assert "copyright" not in _glb_json(out / "city.glb")["asset"]
    # GeoPackage and GeoParquet in the UTM zone of the city's origin (Manhattan: 18N)
    assert pyogrio.read_info(out / "city.gpkg", layer="lots")["crs"] == "EPSG:32618"
    geo = json.loads(pq.read_schema(out / "lots.parquet").metadata[b"geo"])
    assert geo["columns"]["geometry"]["crs"]["id"]["code"] == 32618
    # GeoJSON stays WGS84 (RFC 7946): no crs member
    assert "crs" not in json.loads((out / "lots.geojson").read_text())


def test_obj_one_object_per_layer_at_the_origin(manhattan):
    out, stats = manhattan
    text = (out / "city.obj").read_text()
    objects = [line[2:] for line in text.splitlines() if line.startswith("o ")]
    groups = [line[2:] for line in text.splitlines() if line.startswith("g ")]
    assert objects == groups and set(objects) >= {"roads", "lots", "buildings", "streets"}
    assert len(objects) == len(set(objects))
    mesh = trimesh.load(out / "city.obj", force="mesh", process=False)
    triangles = sum(v for k, v in stats["report"]["export"].items() if k.startswith("obj."))
    assert len(mesh.faces) == triangles
    assert "# origin: planar x 0.000 y 0.000" in text  # a synthetic city's origin is its planar (0, 0)


# -- --format, --crs, --origin on the command line ---------------------------------------------
@pytest.mark.parametrize(
    "formats, hint",
    [("fbx", "did you mean 'glb'?"), ("glb,shp", "did you mean 'gpkg'?"), ("geojsn", "did you mean 'geojson'?")],
)
def test_unknown_format_is_one_line_with_a_suggestion(tmp_path, capsys, formats, hint):
    code = main(["run", str(CONFIGS / "manhattan.xml"), "-o", str(tmp_path / "out"), "--format", formats])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "unknown format" in err and hint in err, err
    assert not (tmp_path / "out").exists()  # no partial output


def test_bad_crs_is_one_line(tmp_path, capsys):
    code = main(["run", str(CONFIGS / "manhattan.xml"), "-o", str(tmp_path / "out"), "--crs", "EPSG:99999999"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "EPSG:99999999" in err, err
    assert not (tmp_path / "out").exists()


@pytest.fixture(scope="module")
def monaco(tmp_path_factory):
    base = tmp_path_factory.mktemp("monaco")
    run_osm(DATA / "monaco.osm.pbf", base / "local", "--format", "glb,obj,cityjson,osm,geojson,png")
    run_osm(DATA / "monaco.osm.pbf", base / "geo", "--format", "glb,obj,cityjson", "--origin", "geo")
    run_osm(DATA / "monaco.osm.pbf", base / "webm", "--format", "geojson,gpkg,parquet", "--crs", "EPSG:3857")
    return base


def test_origin_local_puts_the_city_at_the_gltf_origin(monaco):
    local = trimesh.load(monaco / "local" / "city.glb").to_geometry()
    geo = trimesh.load(monaco / "geo" / "city.glb").to_geometry()
    doc = _glb_json(monaco / "local" / "city.glb")
    extras = doc["scenes"][0]["extras"]["sengine"]
    # materials named by layer, one per node; no node moved away from the origin
    # (trees: a node per plant category, sharing one trunk material beside their crown's)
    layer = lambda names: [n for n in names if not n.startswith("vegetation/")]  # noqa: E731
    assert layer(m["name"] for m in doc["materials"]) == layer(n["name"] for n in doc["nodes"])
    assert {"roads", "buildings", "lots"} <= {m["name"] for m in doc["materials"]}
    assert not any("translation" in n for n in doc["nodes"])
    ox, oy = extras["origin"]["planar"]
    assert ox > 1e5 and extras["crs"].startswith("EPSG:326")  # Monaco's UTM frame
    assert 43.6 < extras["origin"]["lat"] < 43.8 and 7.3 < extras["origin"]["lon"] < 7.5
    # the Monaco extract is a few km across: local coordinates stay within it, world ones are UTM
    assert np.abs(local.bounds[:, [0, 2]]).max() < 5000 and geo.bounds[0, 0] > 1e5
    # the same city, moved by the origin (x east; glTF z south)
    np.testing.assert_allclose(geo.bounds[:, 0] - ox, local.bounds[:, 0], atol=0.02)
    np.testing.assert_allclose(geo.bounds[:, 2] + oy, local.bounds[:, 2], atol=0.02)
    # OBJ: the same offset
    v_local = np.array([[float(t) for t in line.split()[1:]] for line in _obj_vertices(monaco / "local" / "city.obj")])
    v_geo = np.array([[float(t) for t in line.split()[1:]] for line in _obj_vertices(monaco / "geo" / "city.obj")])
    np.testing.assert_allclose(v_geo[:, 0] - ox, v_local[:, 0], atol=0.0015)
    assert np.abs(v_local[:, [0, 2]]).max() < 5000
    # CityJSON: the translate is the origin, the model stays georeferenced
    cj_local = json.loads((monaco / "local" / "buildings.city.json").read_text())
    cj_geo = json.loads((monaco / "geo" / "buildings.city.json").read_text())
    assert cj_local["transform"]["translate"][:2] == [ox, oy]
    # (LoD2 welds vertices on the millimetre grid, whose order follows the translate: compare the models' extents)
    v0 = np.array(cj_local["vertices"]) * 0.001 + cj_local["transform"]["translate"]
    v1 = np.array(cj_geo["vertices"]) * 0.001 + cj_geo["transform"]["translate"]
    assert abs(len(v0) - len(v1)) <= 0.001 * len(v1)
    np.testing.assert_allclose([v0.min(axis=0), v0.max(axis=0)], [v1.min(axis=0), v1.max(axis=0)], atol=0.0011)


def _obj_vertices(path: Path) -> list[str]:
    return [line for line in path.read_text().splitlines() if line.startswith("v ")][:2000]


def test_crs_option_reaches_every_vector_output(monaco):
    out = monaco / "webm"
    assert pyogrio.read_info(out / "city.gpkg", layer="roads")["crs"] == "EPSG:3857"
    geo = json.loads(pq.read_schema(out / "roads.parquet").metadata[b"geo"])
    assert geo["columns"]["geometry"]["crs"]["id"]["code"] == 3857
    data = json.loads((out / "roads.geojson").read_text())
    assert data["crs"]["properties"]["name"] == "urn:ogc:def:crs:EPSG::3857"
    x = shapely.get_coordinates(shapely.from_geojson(json.dumps(data["features"][0]["geometry"])))[:, 0]
    assert (np.abs(x - 826_000) < 10_000).all()  # Monaco in web Mercator metres
    assert np.allclose(x, np.round(x, 3))


def test_preview_carries_the_osm_notice(monaco):
    img = np.asarray(Image.open(monaco / "local" / "preview.png").convert("L"))
    corner = img[-18:, -240:]
    assert (corner < 128).sum() > 50  # the notice's ink in the bottom right corner


# -- OSM round trip -----------------------------------------------------------------
def test_streets_osm_round_trip_gives_the_same_faces(manhattan, tmp_path):
    out, stats = manhattan
    path = out / "streets.osm"
    head = path.read_text()[:300]
    assert 'upload="never"' in head
    # every way's nodes are in the file (osmium check-refs), every id negative
    nodes, refs, tags = set(), [], []

    def way(w):
        refs.extend(n.ref for n in w.nodes)
        tags.append(dict(w.tags))

    osmium.make_simple_handler(node=lambda n: nodes.add(n.id), way=way).apply_file(str(path))
    assert nodes and set(refs) <= nodes and max(nodes) < 0
    assert {"highway", "sengine:id", "width"} <= set(tags[0])
    # read back with `sengine osm`: the same street graph faces
    # like for like: the synthetic city's graph is not closed along a box
    run_osm(path, tmp_path / "back", "--format", "geojson", "--set", "clean.close=none")
    back = json.load(open(tmp_path / "back" / "stats.json"))
    assert back["report"]["majorRoads"]["clipped_ways"] == 0
    assert back["report"]["majorRoads"]["ways"] == stats["report"]["export"]["osm.ways"]
    assert back["report"]["blocks"]["faces"] == stats["report"]["blocks"]["faces"]
    faces = []
    for folder in (out, tmp_path / "back"):
        roads = json.loads((folder / "roads.geojson").read_text())["features"]
        lines = shapely.from_geojson([json.dumps(f["geometry"]) for f in roads])
        faces.append(shapely.get_parts(shapely.polygonize(shapely.get_parts(shapely.union_all(lines)))))
    assert len(faces[0]) == len(faces[1])
    a, b = shapely.union_all(faces[0]), shapely.union_all(faces[1])
    assert shapely.symmetric_difference(a, b).area < 1e-6 * a.area
    # every face of one has its twin in the other (areas within 1 part in 10^4)
    np.testing.assert_allclose(np.sort(shapely.area(faces[0])), np.sort(shapely.area(faces[1])), rtol=1e-4)


def test_osm_city_writes_its_tags_back(tmp_path):
    run_osm(DATA / "monaco.osm.pbf", tmp_path / "out", "--format", "osm,geojson")
    path = tmp_path / "out" / "streets.osm"
    assert "copyright=" in path.read_text()[:400] and "opendatacommons.org" in path.read_text()[:400]
    tags = []
    osmium.make_simple_handler(way=lambda w: tags.append(dict(w.tags))).apply_file(str(path))
    keys = {k for t in tags for k in t}
    assert {"highway", "oneway", "layer", "bridge", "width", "name", "sengine:osm_id"} <= keys
    assert all(int(t["sengine:osm_id"]) > 0 for t in tags if "sengine:osm_id" in t)
    # one way per street segment, with the segment's own values
    roads = {f["id"]: f["properties"] for f in json.loads((tmp_path / "out" / "roads.geojson").read_text())["features"]}
    assert len(tags) == len(roads)
    for t in tags:
        p = roads[int(t["sengine:id"])]
        assert t["highway"] == p["class"] and float(t["width"]) == p["width"]
        assert (t.get("oneway") == "yes") == p["oneway"] and (t.get("bridge") == "yes") == p["bridge"]
        assert (t.get("tunnel") == "yes") == p["tunnel"] and int(t.get("layer", 0)) == p["layer"]
        assert t.get("name") == p["name"] and int(t["sengine:osm_id"]) == p["osm_id"]
    assert any(int(t.get("layer", "0")) > 0 for t in tags)  # Monaco's bridges


# -- writers: append mode, determinism --------------------------------------------------
def _squares(n: int, x0: float = 500_000.0) -> Layer:
    g = shapely.box(x0 + np.arange(n) * 10.0, 4_500_000.0, x0 + np.arange(n) * 10.0 + 8.0, 4_500_008.0)
    return Layer.from_geoms(g, ids=np.arange(n) + 1, height=np.linspace(3.0, 30.0, n), meta={"crs": "EPSG:32631"})


def test_gpkg_and_parquet_append_shard_after_shard(tmp_path):
    a, b = _squares(30), _squares(20, x0=600_000.0)
    b = Layer(b.geometry, b.ids + 100, b.parent, dict(b.attrs), dict(b.meta))
    same = lambda xy: xy  # noqa: E731
    path = tmp_path / "city.gpkg"
    write_gpkg_layer(path, "lots", a, same, "EPSG:32631", chunk=7)
    write_gpkg_layer(path, "lots", b, same, "EPSG:32631", append=True, chunk=7)
    meta, fids, wkb, fields = pyogrio.raw.read(path, layer="lots", return_fids=True)
    assert len(wkb) == 50 and sorted(fids.tolist()) == sorted(a.ids.tolist() + b.ids.tolist())
    with ParquetLayerWriter(tmp_path / "lots.parquet", "EPSG:32631") as w:
        assert w.write(a, same, chunk=7) == 30
        assert w.write(b, same, chunk=7) == 20
    f = pq.ParquetFile(tmp_path / "lots.parquet")
    assert f.metadata.num_rows == 50 and f.metadata.num_row_groups == 5 + 3
    geo = json.loads(f.schema_arrow.metadata[b"geo"])
    assert geo["columns"]["geometry"]["bbox"][0] == 500_000.0 and geo["columns"]["geometry"]["bbox"][2] == 600_198.0


def test_gpkg_and_parquet_same_bytes_for_any_workers(tmp_path):
    for k, workers in enumerate((1, 2)):
        net = sengine.load(CONFIGS / "manhattan.xml")
        net.run(out=tmp_path / f"o{k}", formats=["gpkg", "parquet", "geojson"], workers=workers)
    for p in sorted((tmp_path / "o0").iterdir()):
        if p.name != "stats.json":
            assert p.read_bytes() == (tmp_path / "o1" / p.name).read_bytes(), p.name


# -- clean geometry on generated shapes ---------------------------------------------------
coord = st.floats(-50.0, 50.0, allow_nan=False, allow_infinity=False)


@st.composite
def polygon_soup(draw):
    """Bowties, slivers, zero-area rings, tiny squares, polygons with holes, empties and Nones."""
    out = []
    for _ in range(draw(st.integers(1, 12))):
        kind = draw(st.sampled_from(["ring", "tiny", "sliver", "holed", "empty", "none", "multi"]))
        x, y = draw(coord), draw(coord)
        if kind == "ring":
            pts = draw(st.lists(st.tuples(coord, coord), min_size=3, max_size=8))
            out.append(shapely.Polygon(pts))
        elif kind == "tiny":
            s = draw(st.floats(1e-5, 1e-2))
            out.append(shapely.box(x, y, x + s, y + s))
        elif kind == "sliver":
            out.append(shapely.Polygon([(x, y), (x + 30, y + 1e-4), (x + 30, y), (x, y)]))
        elif kind == "holed":
            out.append(shapely.box(x, y, x + 20, y + 20).difference(shapely.box(x + 5, y + 5, x + 10, y + 10)))
        elif kind == "multi":
            out.append(shapely.MultiPolygon([shapely.box(x, y, x + 1, y + 1), shapely.box(x + 3, y, x + 4, y + 1)]))
        elif kind == "empty":
            out.append(shapely.Polygon())
        else:
            out.append(None)
    arr = np.empty(len(out), dtype=object)
    arr[:] = out
    return arr


@given(polygon_soup())
def test_clean_geometries_valid_nonempty_one_type_on_the_grid(geoms):
    out, keep, counts = clean_geometries(geoms)
    assert len(out) == keep.sum()
    assert counts["dropped_empty"] + counts["dropped_degenerate"] + counts["dropped_type"] == (~keep).sum()
    if len(out):
        assert shapely.is_valid(out).all() and not shapely.is_empty(out).any()
        assert (shapely.area(out) >= 1e-6).all()
        assert len(set(shapely.get_type_id(out).tolist())) == 1
        xy = shapely.get_coordinates(out)
        np.testing.assert_allclose(xy, np.round(xy, 3), atol=1e-9)
    # a valid polygon of some size comes through with its area
    valid = np.array([g is not None and g.is_valid and g.area > 1.0 for g in geoms], bool)
    if valid.any():
        assert keep[valid].all()
        # snapping to the mm grid moves each vertex at most 0.5 mm: the area by at most perimeter x 1 mm
        slack = shapely.length(geoms[valid]) * 1e-3
        assert (np.abs(shapely.area(out[valid[keep]]) - shapely.area(geoms[valid])) <= slack + 1e-9).all()


@given(st.floats(1e-6, 5e-3), st.floats(0.0, 1.0))
def test_snap_in_another_frame_keeps_the_type(width, shift):
    """A polygon thinner than the grid, rounded in its output frame: repaired or reported, never invalid."""
    thin = shapely.Polygon([(0, 0), (10, width), (20, 0), (10, 2 * width), (0, 0)])
    ok = shapely.box(shift, 0, shift + 5, 5)
    out, collapsed = snap_to_type(np.array([thin, ok], object), 1e-3, 3)
    assert not collapsed[1] and shapely.is_valid(out[~collapsed]).all()
    assert set(shapely.get_type_id(out[~collapsed]).tolist()) == {3}

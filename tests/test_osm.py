"""osm.read on the committed OpenStreetMap extracts, bad files, and blocks against an independent route."""

from __future__ import annotations

import bz2
import logging
from pathlib import Path

import numpy as np
import pytest
import shapely

from sengine import CityPlan, Context, MapSpec
from sengine.errors import InputDataError, ParameterError
from sengine.geom.crs import to_lonlat
from sengine.nodes.maps import plan_inputs
from sengine.registry import get

DATA = Path(__file__).resolve().parent.parent / "configs" / "data"
HELSINKI = DATA / "helsinki_centre.osm.pbf"
MONACO = DATA / "monaco.osm.pbf"
OAKLAND = DATA / "west_oakland.osm.bz2"
KIRCHBERG = DATA / "kirchberg_iller.osm"
MIN_AREA = 50.0


def read(path, **params):
    node = get("osm.read")("majorRoads", {"path": str(path), **params}, Context())
    return node.run(), node


@pytest.fixture(scope="module")
def helsinki():
    return read(HELSINKI)


@pytest.fixture(scope="module")
def monaco():
    return read(MONACO)


@pytest.mark.parametrize(
    "path, crs, lat, lon",
    [
        (HELSINKI, "EPSG:32635", 60.17, 24.94),
        (MONACO, "EPSG:32632", 43.74, 7.42),
        (OAKLAND, "EPSG:32610", 37.81, -122.29),
        (KIRCHBERG, "EPSG:32632", 48.13, 10.08),
    ],
)
def test_every_format_reads_into_utm(path, crs, lat, lon):
    out, node = read(path)
    roads = out["roads"]
    assert len(roads) > 0
    assert roads.meta["crs"] == crs
    assert roads.meta["origin"] == pytest.approx((lat, lon), abs=0.05)
    # back to lon/lat: every vertex lies near the origin (a few km)
    xy = shapely.get_coordinates(roads.geometry)
    ll = to_lonlat(crs)(xy)
    assert np.abs(ll[:, 0] - lon).max() < 0.1 and np.abs(ll[:, 1] - lat).max() < 0.1
    assert shapely.is_valid(roads.geometry).all()
    assert set(np.unique(roads["class"])) <= set(node.p.major.split(",")) | set(node.p.minor.split(","))
    assert out.report["segments"] == len(roads)


def test_topology_is_kept(helsinki):
    roads = helsinki[0]["roads"]
    nodes = roads.meta["nodes"]
    start = shapely.get_coordinates(shapely.get_point(roads.geometry, 0))
    end = shapely.get_coordinates(shapely.get_point(roads.geometry, -1))
    assert np.array_equal(nodes[roads["u"]], start)
    assert np.array_equal(nodes[roads["v"]], end)
    # segments meet only at their ends: no inner vertex is another segment's vertex
    coords, idx = shapely.get_coordinates(roads.geometry, return_index=True)
    inner = np.ones(len(coords), bool)
    inner[np.r_[0, np.flatnonzero(np.diff(idx)) + 1]] = False
    inner[np.r_[np.flatnonzero(np.diff(idx)), len(idx) - 1]] = False
    keys = coords.view(np.complex128).ravel()
    _, cnt = np.unique(keys, return_counts=True)
    assert cnt.max() >= 3  # real junctions
    ends_keys = set(keys[~inner].tolist())
    assert not (set(keys[inner].tolist()) & ends_keys)
    assert len(np.unique(roads["osm_id"])) <= len(roads)


def test_class_filter_is_configurable():
    out, _ = read(MONACO, major="primary", minor="residential")
    assert set(np.unique(out["roads"]["class"])) == {"primary", "residential"}
    assert out["roads"]["major"].sum() == (out["roads"]["class"] == "primary").sum()
    everything, _ = read(MONACO, minor="*")
    assert "footway" in set(everything["roads"]["class"])
    assert len(everything["roads"]) > 2 * len(out["roads"])


def test_bridges_and_tunnels_are_flagged(monaco):
    roads = monaco[0]["roads"]
    assert roads["tunnel"].sum() > 20 and roads["bridge"].sum() > 0
    assert (roads["layer"][roads["tunnel"]] <= 0).mean() > 0.9
    assert (roads["width"] > 0).all()


def test_extra_layers(helsinki, monaco):
    b = monaco[0]["buildings"]
    assert len(b) > 1000
    tagged = b["height_source"] != "default"  # 'height' or 'building:levels'
    assert tagged.sum() > 400 and 100 < b["height"][tagged].max() < 120
    assert (b["height_source"] == "height").sum() > 30
    assert (b["floors"] >= 1).all() and (b["height"] > 0).all()
    hb = helsinki[0]["buildings"]
    assert 100 < (hb["height_source"] != "default").sum() < len(hb)
    for kind in ("water", "parks"):
        layer = helsinki[0][kind]
        assert len(layer) > 0 and shapely.is_valid(layer.geometry).all()
        assert layer.meta["crs"] == "EPSG:32635"
    none, _ = read(HELSINKI, extras="")
    assert len(none["buildings"]) == 0 and len(none["roads"]) == len(helsinki[0]["roads"])


def test_buildings_take_their_use_from_the_building_tag(monaco):
    """building=apartments is housing, building=hotel commerce; building=yes says nothing."""
    b = monaco[0]["buildings"]
    uses = np.asarray(b["use"]).astype(str)
    counts = {u: int((uses == u).sum()) for u in np.unique(uses)}
    # the file: 420 apartments, 44 residential, 5 house, 1 terrace; 25 commercial, 19 retail, 12 hotel ...
    assert counts["residential"] >= 470
    assert counts["commercial"] >= 56 and counts["educational"] >= 10
    assert 600 < counts[""] < 800  # building=yes (639), churches, hospitals, construction sites


def test_path_from_the_plan():
    plan = CityPlan(maps={"osm": MapSpec("osm", OAKLAND, {}, "city.xml:3")})
    node = get("osm.read")("majorRoads", {}, Context(plan=plan))
    out = node.run(**plan_inputs(plan, node))
    assert len(out["roads"]) > 0
    with pytest.raises(InputDataError, match="no OSM file"):
        get("osm.read")("majorRoads", {}, Context(plan=CityPlan())).run()
    with pytest.raises(ParameterError, match="extras"):
        get("osm.read")("majorRoads", {"path": str(OAKLAND), "extras": "trees"}, Context()).run()


# -- edge cases of real files ---------------------------------------------------------


def _osm_module():

    import sengine.nodes.osm.read as module

    return module


def _write_pbf(path, nodes, ways, options=""):
    import osmium

    w = osmium.SimpleWriter(osmium.io.File(str(path), "pbf" + options))
    for i, lon, lat in nodes:
        w.add_node(osmium.osm.mutable.Node(id=i, location=(lon, lat)))
    for i, refs, tags in ways:
        w.add_way(osmium.osm.mutable.Way(id=i, nodes=refs, tags=tags))
    w.close()


def test_ways_with_missing_or_too_few_nodes(tmp_path):
    """Clipped extracts: a way keeps its longest run of located nodes; one-node ways are no lines."""
    osm = _osm_module()
    nodes = [(i, 7.40 + 0.001 * i, 43.70 + 0.0005 * (i % 3)) for i in range(1, 12)]
    ways = [
        (100, [1, 2, 3], {"highway": "residential", "name": "Rue A", "oneway": "yes"}),
        (101, [3, 99, 4, 5, 6, 98, 7], {"highway": "primary"}),  # missing nodes: longest run 4-5-6 kept
        (102, [8], {"highway": "residential"}),  # one node: no line
        (103, [8, 8], {"highway": "service", "bridge": "yes", "layer": "2"}),
        (104, [9, 97], {"highway": "residential"}),  # one located node left: dropped, counted clipped
        (105, [9, 10, 11], {"highway": "footway", "covered": "yes"}),
        (106, [1, 11], {"building": "yes"}),
        (107, [], {"highway": "residential"}),
    ]
    for options in ("", ",pbf_dense_nodes=false", ",pbf_compression=none"):
        path = tmp_path / f"edge{len(options)}.osm.pbf"
        _write_pbf(path, nodes, ways, options)
        ext = osm.read_osm(path, node_ids=True)
        assert list(ext.way_id) == [100, 101, 103, 105] and ext.clipped == 2
        assert list(ext.node_ids) == [1, 2, 3, 4, 5, 6, 8, 8, 9, 10, 11]
        assert ext.tags["tunnel"][3] == "yes" and ext.tags["layer"][2] == "2"
        only = osm.read_osm(path, classes=frozenset({"residential"}))
        assert list(only.way_id) == [100]


def test_pbf_node_out_of_range(tmp_path):
    path = tmp_path / "wild.osm.pbf"
    _write_pbf(path, [(1, 7.4, 95.0), (2, 7.41, 43.7)], [(10, [1, 2], {"highway": "residential"})])
    osm = _osm_module()
    with pytest.raises(InputDataError, match="outside") as exc:
        osm.read_osm(path)
    _one_line_naming(exc, path)


# -- bad input: one line naming the file ---------------------------------------------


def _one_line_naming(exc, path):
    msg = str(exc.value)
    assert "\n" not in msg and str(path) in msg
    return msg


def test_truncated_pbf(tmp_path):
    bad = tmp_path / "cut.osm.pbf"
    bad.write_bytes(MONACO.read_bytes()[:200_000])
    with pytest.raises(InputDataError) as exc:
        read(bad)
    _one_line_naming(exc, bad)


def test_corrupt_pbf(tmp_path):
    bad = tmp_path / "noise.osm.pbf"
    bad.write_bytes(np.random.default_rng(1).bytes(5000))
    with pytest.raises(InputDataError) as exc:
        read(bad)
    _one_line_naming(exc, bad)


def test_not_an_osm_file(tmp_path):
    bad = tmp_path / "notes.osm"
    bad.write_text("this is not xml\n")
    with pytest.raises(InputDataError) as exc:
        read(bad)
    _one_line_naming(exc, bad)
    wrong = tmp_path / "image.osm.bz2"
    wrong.write_bytes(bz2.compress(b"<html><body>not osm</body></html>"))
    with pytest.raises(InputDataError):
        read(wrong)


def test_missing_file(tmp_path):
    with pytest.raises(InputDataError, match="does not exist"):
        read(tmp_path / "nowhere.osm.pbf")


def test_no_highways_is_an_empty_city(tmp_path, caplog):
    f = tmp_path / "fields.osm"
    f.write_text(
        '<?xml version="1.0"?>\n<osm version="0.6">\n'
        '<node id="1" lat="48.0" lon="10.0"/><node id="2" lat="48.001" lon="10.0"/>'
        '<node id="3" lat="48.001" lon="10.001"/>\n'
        '<way id="5"><nd ref="1"/><nd ref="2"/><nd ref="3"/><nd ref="1"/><tag k="building" v="yes"/></way>\n'
        '<way id="6"><nd ref="1"/><nd ref="3"/><tag k="waterway" v="ditch"/></way>\n</osm>\n'
    )
    with caplog.at_level(logging.WARNING):
        out, _ = read(f)
    assert len(out["roads"]) == 0
    assert "empty of streets" in caplog.text and "fields.osm" in caplog.text and "1 buildings of the map" in caplog.text
    assert len(out["buildings"]) == 1 and out["roads"].meta["crs"] == "EPSG:32632"
    cleaned = get("roads.clean")("clean", {}, Context()).run(roads=out["roads"])
    assert len(cleaned["roads"]) == 0


def test_coordinates_out_of_range(tmp_path):
    f = tmp_path / "wild.osm"
    f.write_text(
        '<?xml version="1.0"?>\n<osm version="0.6">\n'
        '<node id="1" lat="95.0" lon="7.4"/><node id="2" lat="43.7" lon="7.41"/>\n'
        '<way id="10"><nd ref="1"/><nd ref="2"/><tag k="highway" v="residential"/></way>\n</osm>\n'
    )
    with pytest.raises(InputDataError, match="outside") as exc:
        read(f)
    _one_line_naming(exc, f)


# -- blocks against an independent route -------------------------------------------------


def _sengine_faces(roads):
    cleaned = get("roads.clean")("clean", {}, Context()).run(roads=roads)["roads"]
    out = get("blocks.circuits")("blocks", {"node": "false", "min_area": str(MIN_AREA)}, Context()).run(roads=cleaned)
    return out["faces"].geometry, out["blocks"]


def _library_faces(roads):
    """shapely.node + shapely.polygonize of the ground-level segments.

    Tunnels pass under the blocks, bridges and ways on other layers over
    them: none of them closes a block, so only the ground level is traced.
    """
    keep = ~roads["tunnel"] & ~roads["bridge"] & (roads["layer"] == 0)
    g = roads.geometry[keep]
    polys = shapely.get_parts(shapely.polygonize(shapely.get_parts(shapely.node(shapely.multilinestrings(g)))))
    return polys[shapely.area(polys) >= MIN_AREA]


@pytest.mark.parametrize("city", ["helsinki", "monaco"])
def test_blocks_match_node_and_polygonize(city, request):
    roads = request.getfixturevalue(city)[0]["roads"]
    faces, blocks = _sengine_faces(roads)
    ref = _library_faces(roads)
    assert len(ref) > 80
    assert abs(len(faces) - len(ref)) <= 0.01 * len(ref)
    a, r = shapely.area(faces).sum(), shapely.area(ref).sum()
    assert abs(a - r) <= 0.01 * r
    # the faces partition their union: no two overlap
    assert shapely.area(shapely.union_all(faces)) == pytest.approx(a, rel=1e-6)
    assert 0 < len(blocks) <= len(faces) * 1.2
    assert blocks.meta["crs"] == roads.meta["crs"]


def test_noding_bridges_would_change_monaco(monaco):
    """The plain library route nodes bridges with the roads below them: more, smaller faces."""
    roads = monaco[0]["roads"]
    g = roads.geometry[~roads["tunnel"]]
    polys = shapely.get_parts(shapely.polygonize(shapely.get_parts(shapely.node(shapely.multilinestrings(g)))))
    plain = int((shapely.area(polys) >= MIN_AREA).sum())
    faces, _ = _sengine_faces(roads)
    assert plain > len(faces)


# -- the load-map network: configs and `sengine osm` ------------------------------------

CONFIGS = DATA.parent


def test_helsinki_config_runs_the_loadmap_network(tmp_path):
    from sengine.xmlconfig import load_config

    net = load_config(CONFIGS / "helsinki.xml")
    result = net.run(out=tmp_path / "out", formats={"geojson"})
    counts = result.stats["counts"]
    assert counts["majorRoads"] > 800 and counts["blocks"] > 40 and counts["buildings"] > counts["blocks"]
    rep = result.stats["report"]["clean"]
    # cul-de-sacs are streets: kept (and cut out of their blocks), none removed
    assert rep["dead_ends_kept"] > 50 and rep["dead_ends_removed"] == 0 and rep["tunnels_dropped"] > 0
    assert result.stats["report"]["blocks"]["dead_ends_cut"] == rep["dead_ends_kept"]
    assert (tmp_path / "out" / "blocks.geojson").exists()


@pytest.mark.slow
def test_sengine_osm_command(tmp_path, cli):
    done = cli("osm", OAKLAND, "-o", tmp_path / "oak", "--format", "geojson")
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "oak" / "stats.json").exists()
    bad = tmp_path / "cut.osm.pbf"
    bad.write_bytes(HELSINKI.read_bytes()[:100_000])
    done = cli("osm", bad, "-o", tmp_path / "bad")
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "cut.osm.pbf" in lines[0]
    assert not (tmp_path / "bad").exists()


def test_osm_node_ids_on_request(helsinki):
    out, _ = read(HELSINKI, extras="", node_ids="true")
    roads = out["roads"]
    ids = roads.meta["node_ids"]
    assert len(ids) == len(roads.meta["nodes"]) and len(np.unique(ids)) == len(ids)
    assert (ids > 0).all()
    assert "node_ids" not in helsinki[0]["roads"].meta  # off by default: it costs a Python object per node
    # a junction's id is shared by the segments that meet there
    u_ids = ids[roads["u"]]
    assert len(np.unique(u_ids)) < len(u_ids)
    # and each id is the OSM node at that place
    import osmium

    from sengine.geom.crs import from_lonlat

    want = set(ids[:200].tolist())
    loc = {
        n.id: (n.location.lon, n.location.lat)
        for n in osmium.FileProcessor(str(HELSINKI), osmium.osm.NODE)
        if n.id in want
    }
    xy = from_lonlat(roads.meta["crs"])(np.array([loc[i] for i in ids[:200]]))
    assert np.allclose(xy, roads.meta["nodes"][:200], atol=1e-6)

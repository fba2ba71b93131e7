"""The engine core: plugins, determinism, the standard networks, the CLI and the Layer."""

from __future__ import annotations

import csv
import json
import os
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import shapely
from conftest import ROOT, run_cli

import sengine
from sengine import Layer, Param, Port, SENode, register
from sengine.errors import NetworkError, ParameterError, Problems, RegistryError
from sengine.network import Network
from sengine.nodes.standard import LoadMapNetwork, StdNetwork
from sengine.registry import get, load_plugin

PLUGIN = Path(__file__).parent / "fixtures" / "squares_plugin.py"


@pytest.fixture(scope="module", autouse=True)
def demo_plugin():
    load_plugin(str(PLUGIN))


# -- plugins, three ways ----------------------------------------------------------


def _fake_distribution(site: Path) -> None:
    """A package installed the way pip would: module plus dist-info with an entry point."""
    (site / "cityblocks_plugin.py").write_text(
        textwrap.dedent('''
        import shapely
        from sengine import Layer, Param, Port, SENode, register

        @register
        class Stripes(SENode):
            """Parallel strips of land (a third-party node)."""
            name = "thirdparty.stripes"
            inputs = {}
            outputs = {"strips": Port("polygons")}
            params = {"count": Param("int", 4, min=1, max=50, unit="1", doc="strips")}

            def run(self):
                return {"strips": Layer.from_geoms([shapely.box(i * 10, 0, i * 10 + 8, 30) for i in range(self.p.count)])}
    ''')
    )
    dist = site / "cityblocks_plugin-1.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: cityblocks-plugin\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text("[sengine.nodes]\ncityblocks = cityblocks_plugin\n")
    (dist / "RECORD").write_text("")


@pytest.mark.slow
def test_plugin_by_entry_point(tmp_path):
    site = tmp_path / "site"
    site.mkdir()
    _fake_distribution(site)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(site), str(ROOT)]))
    listing = run_cli("nodes", "--json", env=env, cwd=tmp_path)
    assert listing.returncode == 0, listing.stderr
    names = {n["name"] for n in json.loads(listing.stdout)}
    assert "thirdparty.stripes" in names and "null" in names
    config = tmp_path / "c.xml"
    config.write_text(
        '<sengine version="1"><network><node id="s" type="thirdparty.stripes">'
        '<param name="count" value="6"/></node><node id="n" type="null"/>'
        '<connect from="s" to="n"/></network></sengine>'
    )
    ran = run_cli("run", config, "-o", tmp_path / "out", env=env, cwd=tmp_path)
    assert ran.returncode == 0, ran.stderr
    stats = json.loads((tmp_path / "out" / "stats.json").read_text())
    assert stats["counts"] == {"s": 6, "n": 6}


def test_plugin_by_xml_path(tmp_path, fixtures):
    result = sengine.load(fixtures / "squares.xml").run(seed=1, out=tmp_path / "o")
    assert result.stats["counts"] == {"source": 7, "inset": 7}
    assert (tmp_path / "o" / "write.geojson").exists()


@pytest.mark.slow
def test_plugin_by_command_line(tmp_path):
    config = tmp_path / "c.xml"
    config.write_text('<sengine version="1"><network><node id="lines" type="demo.lines"/></network></sengine>')
    first = run_cli("run", config, "-o", tmp_path / "no")
    assert first.returncode == 2 and "unknown node type 'demo.lines'" in first.stderr
    ran = run_cli("run", config, "-o", tmp_path / "out", "--plugin", PLUGIN)
    assert ran.returncode == 0, ran.stderr
    assert json.loads((tmp_path / "out" / "stats.json").read_text())["counts"] == {"lines": 3}


def test_broken_entry_point_is_a_warning_not_a_crash(tmp_path):
    site = tmp_path / "site"
    site.mkdir()
    (site / "broken_plugin.py").write_text("raise RuntimeError('half installed')\n")
    dist = site / "broken_plugin-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: broken-plugin\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[sengine.nodes]\nbroken = broken_plugin\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(site), str(ROOT)]))
    res = run_cli("nodes", "--check", env=env, cwd=tmp_path)
    assert res.returncode == 1
    assert "half installed" in res.stderr and "null" in res.stdout


def test_unknown_type_suggests_close_names():
    with pytest.raises(RegistryError, match=r"unknown node type 'demo.squres'; did you mean 'demo.squares'"):
        get("demo.squres")


def test_duplicate_registration_is_an_error():
    class Other(SENode):
        name = "demo.squares"
        outputs = {"x": Port("polygons")}

        def run(self):
            return {}

    with pytest.raises(RegistryError, match="registered twice"):
        register(Other)


def test_run_signature_must_match_ports():
    class Bad(SENode):
        name = "demo.bad"
        inputs = {"a": Port("polygons")}

        def run(self, *, b):
            return {}

    with pytest.raises(TypeError, match=r"differ from its input ports \['a'\]"):
        register(Bad)


# -- parameters and randomness ------------------------------------------------------


def test_parameters_are_checked_and_coerced():
    cls = get("demo.squares")
    node = cls("s", {"count": "12", "size": "2.5"})
    assert node.p.count == 12 and node.p.size == 2.5
    with pytest.raises(ParameterError, match="count=1.5 is not a valid int|count='1.5' is not a valid int"):
        cls("s", {"count": "1.5"})
    with pytest.raises(ParameterError, match="size=0.0 m is below the minimum 0.1 m"):
        cls("s", {"size": 0})
    choice = Param("str", "a", choices=("a", "b"))
    with pytest.raises(ParameterError, match="mode='c' is not one of a, b"):
        choice.coerce("c", "here", "mode")
    assert Param("bool", False).coerce("yes", "w", "flag") is True


def test_feature_seeding_is_independent_of_batch():
    cls = get("demo.squares")
    a = cls("n1", {}, sengine.Context(seed=5))
    b = cls("n1", {}, sengine.Context(seed=5))
    c = cls("n2", {}, sengine.Context(seed=5))
    assert a.rng(42).random() == b.rng(42).random()
    assert a.rng(42).random() != a.rng(43).random()
    assert a.rng(42).random() != c.rng(42).random()
    assert a.rng().random() != cls("n1", {}, sengine.Context(seed=6)).rng().random()


# -- running -------------------------------------------------------------------------


def test_same_seed_same_bytes(tmp_path, fixtures):
    outs = []
    for name in ("a", "b"):
        net = sengine.load(fixtures / "squares.xml")
        net.run(seed=3, out=tmp_path / name)
        outs.append(tmp_path / name)
    files = sorted(p.name for p in outs[0].iterdir())
    assert files == sorted(p.name for p in outs[1].iterdir()) == ["stats.json", "write.geojson"]
    assert (outs[0] / "write.geojson").read_bytes() == (outs[1] / "write.geojson").read_bytes()
    sa, sb = (json.loads((o / "stats.json").read_text()) for o in outs)
    assert sa["counts"] == sb["counts"] and sa["seed"] == sb["seed"] == 3
    other = sengine.load(fixtures / "squares.xml").run(seed=4)
    assert not shapely.equals(
        other["source"].geometry, sengine.load(fixtures / "squares.xml").run(seed=3)["source"].geometry
    ).all()


def test_stats_json_shape(tmp_path, fixtures, cli):
    res = cli("run", fixtures / "squares.xml", "-o", tmp_path / "o", "--seed", "9", "--set", "source.count=4")
    assert res.returncode == 0, res.stderr
    stats = json.loads((tmp_path / "o" / "stats.json").read_text())
    assert stats["sengine"] == sengine.__version__
    assert stats["seed"] == 9 and stats["config"].endswith("squares.xml")
    assert stats["counts"] == {"source": 4, "inset": 4}
    assert set(stats["seconds"]) == {"source", "inset", "write", "total"}
    assert stats["areas"]["source"] == pytest.approx(400.0)


def test_topological_order_not_file_order():
    net = Network()
    net.add("late", "demo.inset")
    net.add("early", "demo.squares", {"count": 2})
    net.connect("early", "late")
    layers, stats = net.run(seed=1)
    assert list(stats["counts"]) == ["early", "late"]
    assert np.all(layers["late"]["polygons"].parent == layers["early"]["squares"].ids)


def test_validation_collects_every_problem():
    net = Network()
    net.add("a", "demo.nope")
    net.add("b", "demo.squares", {"count": -1})
    with pytest.raises(Problems, match=r"2 problems") as exc:
        net.validate()
    lines = exc.value.lines
    assert len(lines) == 3 and "unknown node type 'demo.nope'" in lines[1] and "count=-1" in lines[2]
    assert isinstance(exc.value.problems[0], RegistryError) and isinstance(exc.value.problems[1], ParameterError)


# -- the standard networks -----------------------------------------------------------


def test_std_network_requires_major_and_minor_roads():
    with pytest.raises(NetworkError, match="needs the standard name 'majorRoads'"):
        StdNetwork({"minorRoads": "null"})


def test_std_network_rejects_unknown_name():
    with pytest.raises(NetworkError, match="'parks' is not a standard name"):
        StdNetwork({"majorRoads": "demo.squares", "minorRoads": "null", "parks": "null"})


def test_std_network_association_replaces_node():
    net = StdNetwork({"majorRoads": "demo.squares", "minorRoads": "demo.inset"})
    assert net.names() == ["majorRoads", "minorRoads"]
    assert net.standard("minorRoads").type == "demo.inset"
    with pytest.raises(NetworkError, match="no node behind the standard name 'lots'"):
        net.standard("lots")
    layers, stats = net.run(seed=2)
    assert stats["counts"] == {"majorRoads": 5, "minorRoads": 5}
    assert shapely.area(layers["minorRoads"]["polygons"].geometry).max() == pytest.approx(64.0)


def test_loadmap_network_minor_roads_is_null():
    net = LoadMapNetwork()
    assert net.standard("minorRoads").type == "null"
    with pytest.raises(NetworkError, match="has no standard name 'avenues'"):
        LoadMapNetwork({"avenues": "null"})
    swapped = LoadMapNetwork({"lots": "lots.paris"})
    assert swapped.standard("lots").type == "lots.paris"


def test_std_network_from_xml(tmp_path, cli):
    config = tmp_path / "std.xml"
    config.write_text(
        f'<sengine version="1"><plugin path="{PLUGIN}"/><network base="std">'
        '<node id="majorRoads" type="demo.squares"/><node id="minorRoads" type="demo.inset">'
        '<param name="distance" value="2"/></node></network></sengine>'
    )
    res = cli("run", config, "-o", tmp_path / "o")
    assert res.returncode == 0, res.stderr
    stats = json.loads((tmp_path / "o" / "stats.json").read_text())
    assert stats["counts"] == {"majorRoads": 5, "minorRoads": 5}
    assert stats["areas"]["minorRoads"] == pytest.approx(5 * 36.0)


# -- CLI surfaces --------------------------------------------------------------------


def test_nodes_json_lists_declarations(cli):
    res = cli("nodes", "--json", "--plugin", PLUGIN)
    assert res.returncode == 0, res.stderr
    nodes = {n["name"]: n for n in json.loads(res.stdout)}
    sq = nodes["demo.squares"]
    assert set(sq) >= {"name", "doc", "inputs", "outputs", "params"}
    count = next(p for p in sq["params"] if p["name"] == "count")
    assert count == {
        "name": "count",
        "type": "int",
        "default": 5,
        "min": 1,
        "max": 10000,
        "choices": None,
        "unit": "1",
        "doc": "number of squares",
    }
    assert sq["outputs"] == [{"name": "squares", "kind": "polygons", "doc": "one square per feature"}]


def test_validate_command(fixtures, cli):
    res = cli("validate", fixtures / "squares.xml")
    assert res.returncode == 0 and "valid, 3 nodes, 2 connections" in res.stdout


@pytest.mark.parametrize("suffix", [".dot", ".svg", ".png"])
def test_graph_command(suffix, fixtures, tmp_path, cli):
    out = tmp_path / f"net{suffix}"
    res = cli("graph", fixtures / "squares.xml", "-o", out)
    assert res.returncode == 0, res.stderr
    data = out.read_bytes()
    if suffix == ".dot":
        assert b'"source" -> "inset" [label="squares' in data
    elif suffix == ".svg":
        assert b"<svg" in data and b">inset<" in data and b">demo.squares<" in data
    else:
        from PIL import Image

        img = Image.open(out)
        pixels = np.asarray(img.convert("RGB")).reshape(-1, 3)
        assert img.size[0] > 300 and len(np.unique(pixels, axis=0)) > 3


def test_batch_runs_each_seed(fixtures, tmp_path, cli):
    res = cli("batch", fixtures / "squares.xml", "-o", tmp_path / "b", "--seeds", "1-3", "--workers", "1")
    assert res.returncode == 0, res.stderr
    with open(tmp_path / "b" / "batch.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["id"] for r in rows] == ["s1", "s2", "s3"] and [r["seed"] for r in rows] == ["1", "2", "3"]
    for r in rows:  # each row holds its run's counts
        own = json.loads((tmp_path / "b" / r["id"] / "stats.json").read_text())
        assert {k: int(r[f"n_{k}"]) for k in own["counts"]} == own["counts"]
    # the same seeds two at a time in two processes: the same files
    res = cli("batch", fixtures / "squares.xml", "-o", tmp_path / "p", "--seeds", "1-3", "--workers", "2")
    assert res.returncode == 0, res.stderr
    for s in (1, 2, 3):
        a, b = (tmp_path / d / f"s{s}" / "write.geojson" for d in ("b", "p"))
        assert a.read_bytes() == b.read_bytes()


def test_installed_package_has_builtins_without_top_level_nodes(tmp_path):
    """From outside the checkout: the built-in nodes load, no top-level ``nodes`` package exists."""
    code = (
        "import importlib.util, json, sengine, sengine.registry as r;"
        "print(json.dumps({'file': sengine.__file__, 'names': r.names(),"
        " 'nodes': importlib.util.find_spec('nodes') is not None,"
        " 'networks': importlib.util.find_spec('networks') is not None}))"
    )
    import subprocess

    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    res = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    info = json.loads(res.stdout)
    assert "null" in info["names"]
    if Path(info["file"]).resolve().is_relative_to(ROOT / "sengine"):
        pytest.skip("sengine is installed in development mode; the check is for `pip install .`")
    assert not info["nodes"] and not info["networks"]


# -- the Layer -------------------------------------------------------------------------


def test_layer_geojson_round_trip():
    lay = Layer.from_geoms(
        [shapely.box(0, 0, 2, 1), shapely.Point(3, 4)],
        parent=[7, 8],
        kind=np.array(["lot", "tree"]),
        height=np.array([12.5, np.nan]),
    )
    data = lay.to_geojson()
    assert [f["properties"]["kind"] for f in data["features"]] == ["lot", "tree"]
    assert data["features"][1]["properties"]["height"] is None
    back = Layer.from_geojson(json.loads(json.dumps(data)))
    assert len(back) == 2 and list(back.parent) == [7, 8]
    assert shapely.equals(back.geometry, lay.geometry).all()


def test_layer_take_concat_and_columns():
    a = Layer.from_geoms([shapely.Point(0, 0), shapely.Point(1, 1)], kind=np.array(["x", "y"]))
    b = Layer.from_geoms([shapely.Point(2, 2)], height=np.array([3.0]))
    both = Layer.concat([a, b])
    assert len(both) == 3 and list(both.ids) == [0, 1, 2]
    assert list(both["kind"]) == ["x", "y", ""] and np.isnan(both["height"][0])
    picked = both.take(np.array([False, True, True]))
    assert list(picked.ids) == [1, 2]
    with pytest.raises(ValueError, match="column 'h' has shape"):
        a.with_columns(h=np.zeros(3))


def test_chunk_reports_merge():
    """Counts of a node's chunks add up; ``max_*`` figures take the largest; the rest comes from the first."""
    from sengine.network import _sum_reports

    merged = _sum_reports(
        [
            {"lots": 3, "max_levels": 4, "method": "a", "sub": {"n": 1}},
            {"lots": 5, "max_levels": 2, "method": "b", "sub": {"n": 2}},
        ]
    )
    assert merged == {"lots": 8, "max_levels": 4, "method": "a", "sub": {"n": 3}}


@pytest.mark.parametrize("fork_after", [0.0, float("inf")], ids=["forked", "timed-then-here"])
def test_workers_give_the_same_result(tmp_path, fixtures, monkeypatch, fork_after):
    """A feature-mapping node cut into chunks (over 2 processes, or here after timing one): same bytes as 1 process."""
    from sengine import network

    monkeypatch.setattr(network, "FORK_AFTER", fork_after)
    files, reports = [], []
    for workers in (1, 2):
        net = sengine.load(fixtures / "squares.xml")
        net.set_param("source", "count", 1500)
        result = net.run(seed=5, out=tmp_path / f"w{workers}", workers=workers)
        files.append((tmp_path / f"w{workers}" / "write.geojson").read_bytes())
        reports.append(result.stats["report"])
    assert files[0] == files[1]
    assert reports[0] == reports[1] == {"inset": {"shrunk": 1500, "method": "buffer"}}
    assert json.loads(files[0])["features"][1499]["properties"]["parent_id"] == 1499


def test_disconnect_then_connect_inserts_a_node(tmp_path):
    """A base network's connection is removed and a node put in between."""
    base = tmp_path / "base.xml"
    base.write_text(
        f'<sengine version="1"><plugin path="{PLUGIN}"/><network>'
        '<node id="src" type="demo.squares"/><node id="out" type="demo.inset"/>'
        '<connect from="src.squares" to="out.polygons"/></network></sengine>'
    )
    config = tmp_path / "c.xml"
    config.write_text(
        '<sengine version="1"><network file="base.xml">'
        '<node id="mid" type="demo.inset"><param name="distance" value="2"/></node>'
        '<disconnect from="src" to="out"/>'
        '<connect from="src" to="mid"/><connect from="mid" to="out"/></network></sengine>'
    )
    layers, stats = sengine.load(config).run(seed=1)
    assert list(stats["counts"]) == ["src", "mid", "out"]
    assert shapely.area(layers["out"]["polygons"].geometry) == pytest.approx(np.full(5, 16.0))  # 10 - 2*2 - 2*1

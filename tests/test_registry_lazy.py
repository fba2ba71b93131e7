"""The lazy registry: node modules imported when a run first asks for them (issue 13, start-up time)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from conftest import CONFIGS, ROOT, run_cli

from sengine import registry
from sengine.errors import RegistryError


def _python(code: str, *, path: Path | None = None) -> subprocess.CompletedProcess:
    """Run ``code`` in a fresh interpreter (the registry's state is per process)."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(str(p) for p in (path, ROOT) if p))
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, env=env, timeout=300
    )


def test_index_is_up_to_date():
    from sengine.nodes._index import INDEX

    assert registry.survey("sengine.nodes") == INDEX, (
        "sengine/nodes/_index.py is out of date: "
        "python -c \"from sengine.registry import write_index; write_index('sengine.nodes')\""
    )


def test_index_is_complete_and_exact():
    """Every node name the library registers is indexed under the module that defines its class."""
    from sengine.nodes._index import INDEX

    registry.load_all()
    builtin = {n: c for n, c in registry.REGISTRY.items() if c.__module__.startswith("sengine.nodes.")}
    assert len(builtin) >= 30
    assert {n: [c.__module__] for n, c in builtin.items()} == INDEX["node"]
    assert set(INDEX["network"]) == {"std", "pattern", "loadmap"}
    assert set(INDEX["format"]) == {"glb", "geojson", "osm", "png", "obj", "cityjson", "gpkg", "parquet", "html"}
    # one source class per port kind: which class makes a map does not depend on import order
    assert all(len(v) == 1 for v in INDEX["source"].values())


def test_loading_a_config_imports_only_its_nodes():
    res = _python(
        """
        import json, sys
        import sengine
        from sengine import registry
        net = sengine.load("configs/manhattan.xml")
        types = sorted({s.type for s in net.specs.values()})
        mods = sorted(m for m in sys.modules if m.startswith("sengine.nodes."))
        print(json.dumps({"types": types, "mods": mods, "names": len(registry.names())}))
        """
    )
    assert res.returncode == 0, res.stderr
    got = json.loads(res.stdout)
    assert "stats.planning" in got["types"] and "export.city" in got["types"]
    for unused in ("osm.read", "osm.stream", "roads.objimport", "roads.roadimage", "export.gpkg", "export.parquet"):
        assert f"sengine.nodes.{unused}" not in got["mods"], unused
    # every name is known without its module imported
    from sengine.nodes._index import INDEX

    assert got["names"] == len(INDEX["node"])
    assert len(got["mods"]) < 80


def test_unknown_node_type_names_close_ones_from_a_lazy_registry():
    res = _python(
        """
        from sengine.registry import get
        from sengine.errors import RegistryError
        try:
            get("roads.minro")
        except RegistryError as e:
            print(e)
        """
    )
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip().startswith("unknown node type 'roads.minro'; did you mean 'roads.minor'")
    assert len(res.stdout.strip().splitlines()) == 1


def test_unknown_node_in_a_config_is_one_line(tmp_path):
    config = tmp_path / "c.xml"
    config.write_text('<sengine version="1"><network><node id="a" type="lots.manhatan"/></network></sengine>')
    res = run_cli("validate", config)
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "unknown node type 'lots.manhatan'" in lines[0] and "lots.manhattan" in lines[0]


def test_a_stale_index_is_slower_not_wrong():
    res = _python(
        """
        import sengine.nodes._index as ix
        del ix.INDEX["node"]["roads.minor"]          # a node the index does not know
        ix.INDEX["node"]["lots.paris"] = ["sengine.nodes.core"]  # one it places in the wrong module
        from sengine.registry import get
        print(get("roads.minor").__module__, get("lots.paris").__module__)
        """
    )
    assert res.returncode == 0, res.stderr
    assert res.stdout.split() == ["sengine.nodes.roads.minor", "sengine.nodes.lots.nodes"]


def test_plugin_may_replace_a_builtin_node_before_its_module_is_imported():
    res = _python(
        """
        from sengine import SENode, Port, register
        from sengine.registry import get, load_entry_points
        from sengine.errors import RegistryError

        load_entry_points()  # as load_plugin does before a plugin registers

        class Mine(SENode):
            name = "roads.minor"
            outputs = {"x": Port("polygons")}
            def run(self):
                return {}

        try:
            register(Mine)
        except RegistryError as e:
            print("refused:", e)
        register(Mine, replace=True)
        get("lots.manhattan")  # imports modules beside it; the built-in roads.minor stays shadowed
        import sengine.nodes.roads.minor
        print(get("roads.minor") is Mine)
        """
    )
    assert res.returncode == 0, res.stderr
    lines = res.stdout.strip().splitlines()
    assert lines[0].startswith("refused: node name 'roads.minor' is registered twice")
    assert "sengine.nodes.roads.minor.MinorRoads" in lines[0] or "sengine.nodes.roads.minor." in lines[0]
    assert lines[1] == "True"


def _lazy_plugin(site: Path) -> None:
    """A third-party package declaring its own lazy index, one of whose modules is broken."""
    pkg = site / "lazyplug"
    pkg.mkdir()
    (pkg / "__init__.py").write_text(
        "from sengine.registry import declare_lazy\n"
        "declare_lazy({'node': {'lazy.ok': ['lazyplug.ok'], 'lazy.bad': ['lazyplug.bad']}}, package=__name__)\n"
    )
    (pkg / "ok.py").write_text(
        textwrap.dedent('''
        import shapely
        from sengine import Layer, Port, SENode, register

        @register
        class Ok(SENode):
            """Two squares."""
            name = "lazy.ok"
            inputs = {}
            outputs = {"squares": Port("polygons")}

            def run(self):
                return {"squares": Layer.from_geoms([shapely.box(0, 0, 1, 1), shapely.box(2, 0, 3, 1)])}
        ''')
    )
    (pkg / "bad.py").write_text("import not_installed_anywhere  # noqa\n")


def test_third_party_lazy_plugin(tmp_path):
    site = tmp_path / "site"
    site.mkdir()
    _lazy_plugin(site)
    res = _python(
        """
        import sys
        from sengine.registry import get, load_plugin, names
        from sengine.errors import RegistryError
        load_plugin("lazyplug")
        print("lazy.bad" in names(), "lazyplug.bad" in sys.modules)
        print(get("lazy.ok").name, "lazyplug.bad" in sys.modules)
        try:
            get("lazy.bad")
        except RegistryError as e:
            print(e)
        """,
        path=site,
    )
    assert res.returncode == 0, res.stderr
    lines = res.stdout.strip().splitlines()
    assert lines[0] == "True False" and lines[1] == "lazy.ok False"
    assert lines[2].startswith(
        "node 'lazy.bad': module lazyplug.bad failed to import (not_installed_anywhere is missing)"
    )
    config = tmp_path / "c.xml"
    config.write_text(
        '<sengine version="1"><plugin module="lazyplug"/><network><node id="s" type="lazy.ok"/></network></sengine>'
    )
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(site), str(ROOT)]))
    ran = run_cli("run", config, "-o", tmp_path / "out", "--format", "geojson", env=env, cwd=tmp_path)
    assert ran.returncode == 0, ran.stderr
    assert json.loads((tmp_path / "out" / "stats.json").read_text())["counts"] == {"s": 2}
    listed = run_cli("nodes", "--check", "--plugin", "lazyplug", env=env, cwd=tmp_path)
    assert listed.returncode == 1 and "lazyplug.bad" in listed.stderr and "lazy.ok" in listed.stdout


def test_nodes_listing_has_every_builtin_node():
    from sengine.nodes._index import INDEX

    res = run_cli("nodes", "--json", "--all")
    assert res.returncode == 0, res.stderr
    got = json.loads(res.stdout)
    assert {n["name"] for n in got["nodes"]} >= set(INDEX["node"])
    assert set(got["rules"]) == set(INDEX["rule"]) and set(got["maps"]) == set(INDEX["map_kind"])
    assert set(got["formats"]) == set(INDEX["format"]) and set(got["kinds"]) >= set(INDEX["kind"])


def test_demo_configs_validate():
    for config in ("manhattan.xml", "paris.xml", "helsinki.xml"):
        res = run_cli("validate", CONFIGS / config)
        assert res.returncode == 0, (config, res.stderr)


def test_declare_lazy_refuses_an_unknown_category():
    with pytest.raises(RegistryError, match="unknown category 'nodes'"):
        registry.declare_lazy({"nodes": {"x": ["y"]}})

"""sengine.registry in this process, function by function, with the exact messages a user reads.

test_registry_lazy and test_engine check the registry through fresh interpreters and whole
networks; these pin register, get, the network and format tables, plugins by module and by
path, rules, kinds, map kinds and the lazy index on a registry emptied for each test (its
state is put back after), for the mutation run of docs/mutation.md.  Plugins are real files
written to a temporary folder; entry points are real ``*.dist-info`` folders on ``sys.path``.
"""

from __future__ import annotations

import sys
import uuid
import warnings

import numpy as np
import pytest

from sengine import registry
from sengine.errors import NetworkError, ParameterError, RegistryError, SEngineWarning
from sengine.layer import Layer
from sengine.node import Param, Port, SENode
from sengine.random import stable_hash

#: Under mutmut every function is called through a trampoline, one frame deeper: ``_origin``
#: (which reads its caller's caller's module) then records the wrong module.  The assertions on
#: it run outside mutmut only; docs/mutation.md says how its mutants were checked.
TRAMPOLINED = hasattr(registry, "mutants_x_declare_rule__mutmut")

_STATE = ("REGISTRY", "NETWORKS", "RULES", "KINDS", "MAP_KINDS", "KIND_DOCS", "_loaded", "_broken", "_SHADOWED")


@pytest.fixture(autouse=True)
def blank():
    """An empty registry whose entry points count as loaded; everything put back afterwards."""
    registry.load_entry_points()
    saved = {k: dict(getattr(registry, k)) for k in _STATE}
    nested = {k: {kk: dict(vv) for kk, vv in getattr(registry, k).items()} for k in ("RULES", "KINDS")}
    lazy = {c: dict(v) for c, v in registry._LAZY.items()}
    packages = list(registry._LAZY_PACKAGES)
    origin = {k: set(v) for k, v in registry._ORIGIN.items()}
    for k in _STATE:
        getattr(registry, k).clear()
    for v in registry._LAZY.values():
        v.clear()
    registry._LAZY_PACKAGES.clear()
    registry._ORIGIN.clear()
    yield
    for k in _STATE:
        getattr(registry, k).clear()
        getattr(registry, k).update(nested.get(k, saved[k]))
    for c, v in registry._LAZY.items():
        v.clear()
        v.update(lazy[c])
    registry._LAZY_PACKAGES[:] = packages
    registry._ORIGIN.clear()
    registry._ORIGIN.update(origin)
    registry._entry_points_loaded = True


def _node(node_name: str, *, module: str = "tests.fake", **attrs) -> type[SENode]:
    def run(self):
        return {}

    body = {"name": node_name, "outputs": {"out": Port("polygons")}, "run": run, "__module__": module, **attrs}
    return type("Fake", (SENode,), body)


def _unique() -> str:
    return f"regunit_{uuid.uuid4().hex[:12]}"


def _package(tmp_path, monkeypatch, files: dict[str, str]) -> str:
    """A real package of ``files`` (module name -> source) on sys.path; its name."""
    name = _unique()
    pkg = tmp_path / name
    pkg.mkdir()
    (pkg / "__init__.py").write_text(files.pop("__init__", ""))
    for mod, src in files.items():
        (pkg / f"{mod}.py").write_text(src)
    monkeypatch.syspath_prepend(str(tmp_path))
    return name


# -- register / get / find / names ---------------------------------------------------------


def test_register_returns_the_class_and_keeps_it_under_its_name():
    a = _node("fam.alpha")
    assert registry.register(a) is a
    assert registry.REGISTRY == {"fam.alpha": a}
    b = _node("fam.beta")
    deco = registry.register(name="fam.gamma")
    assert deco(b) is b and b.name == "fam.gamma"
    assert registry.get("fam.gamma") is b and registry.find("fam.alpha") is a
    assert registry.find("fam.none") is None
    assert registry.names() == ["fam.alpha", "fam.gamma"]
    assert registry.register(a) is a  # the same class again is no error


def test_register_refuses_bad_classes_and_names():
    with pytest.raises(TypeError) as e:
        registry.register(int)
    assert str(e.value) == "<class 'int'> is not an SENode subclass"
    with pytest.raises(TypeError, match="is not an SENode subclass"):
        registry.register(name="a.b")(42)
    for bad in ("", "Lots-paris", "lots..paris", "9lots", "lots.9", "lots.", "lots paris"):
        with pytest.raises(RegistryError) as e:
            registry.register(_node(bad))
        assert str(e.value) == f"Fake: node name {bad!r} must be dotted identifiers like 'lots.paris'"
    for good in ("a", "Lots.Paris", "a_1.b2.c_", "x.y.z"):
        registry.register(_node(good))
    assert sorted(registry.REGISTRY) == sorted(["a", "Lots.Paris", "a_1.b2.c_", "x.y.z"])

    class BadRun(SENode):
        name = "fam.badrun"
        inputs = {"a": Port("polygons")}

        def run(self):
            return {}

    with pytest.raises(TypeError, match="keyword-only arguments"):
        registry.register(BadRun)
    assert "fam.badrun" not in registry.REGISTRY


def test_register_twice_is_an_error_unless_replace():
    a = _node("fam.twin", module="tests.one")
    b = _node("fam.twin", module="tests.two")
    registry.register(a)
    with pytest.raises(RegistryError) as e:
        registry.register(b)
    assert str(e.value) == "node name 'fam.twin' is registered twice: tests.one.Fake and tests.two.Fake"
    assert registry.REGISTRY["fam.twin"] is a
    assert registry.register(b, replace=True) is b and registry.REGISTRY["fam.twin"] is b
    # a class of the same module and name (a module imported twice) replaces silently
    c = _node("fam.twin", module="tests.two")
    assert registry.register(c) is c and registry.REGISTRY["fam.twin"] is c


def test_get_unknown_names_close_ones():
    for n in ("roads.minor", "roads.major", "roads.mixer", "lots.paris", "roads.minors"):
        registry.register(_node(n, module=f"tests.{n.replace('.', '_')}"))
    with pytest.raises(RegistryError) as e:
        registry.get("roads.minro", where="c.xml:3")
    # three at most, best first: 'roads.major' (the fourth) is left out
    assert str(e.value) == (
        "c.xml:3: unknown node type 'roads.minro'; did you mean 'roads.minor', 'roads.minors', 'roads.mixer'?"
    )
    assert e.value.where == "c.xml:3"
    with pytest.raises(RegistryError) as e:
        registry.get("zzzzzz")
    assert str(e.value) == "unknown node type 'zzzzzz'" and e.value.where is None
    # cutoff 0.5: 'lots.pxxxx' is 0.6 like 'lots.paris'; 'l.pa' (ratio 4/7 > 0.5) too
    with pytest.raises(RegistryError) as e:
        registry.get("l.pa")
    assert str(e.value) == "unknown node type 'l.pa'; did you mean 'lots.paris'?"
    with pytest.raises(RegistryError) as e:  # ratio 2*3/(3+10) = 0.46 < 0.5
        registry.get("lot")
    assert str(e.value) == "unknown node type 'lot'"


# -- lazily declared nodes ---------------------------------------------------------------------


NODE_SRC = """
from sengine import Port, SENode, register

@register
class {cls}(SENode):
    name = {name!r}
    outputs = {{"out": Port("polygons")}}

    def run(self):
        return {{}}
"""


def test_lazy_node_is_imported_when_asked_for(tmp_path, monkeypatch):
    pkg = _package(
        tmp_path,
        monkeypatch,
        {"a": NODE_SRC.format(cls="A", name="lz.a"), "b": NODE_SRC.format(cls="B", name="lz.b")},
    )
    registry.declare_lazy({"node": {"lz.a": [f"{pkg}.a"], "lz.b": [f"{pkg}.b"]}}, package=pkg)
    assert registry.names() == ["lz.a", "lz.b"] and f"{pkg}.a" not in sys.modules
    assert registry.get("lz.a").__module__ == f"{pkg}.a"
    assert f"{pkg}.a" in sys.modules and f"{pkg}.b" not in sys.modules
    assert registry._LAZY["node"] == {"lz.b": (f"{pkg}.b",)}
    # an unknown name imports the whole package (a stale index is slower, not wrong)
    assert registry.find("lz.c") is None
    assert f"{pkg}.b" in sys.modules and registry._LAZY_PACKAGES == [] and registry._LAZY["node"] == {}
    assert sorted(registry.REGISTRY) == ["lz.a", "lz.b"]


def test_declare_lazy_merges_and_refuses_unknown_categories():
    registry.declare_lazy({"node": {"x.a": ["m1", "m2"]}, "rule": {"district": ("m1",)}}, package="p1")
    registry.declare_lazy({"node": {"x.a": ["m2", "m3"]}}, package="p1")
    registry.declare_lazy({}, package="p2")
    registry.declare_lazy({})
    assert registry._LAZY["node"] == {"x.a": ("m1", "m2", "m3")}
    assert registry._LAZY["rule"] == {"district": ("m1",)}
    assert registry._LAZY_PACKAGES == ["p1", "p2"]
    with pytest.raises(RegistryError) as e:
        registry.declare_lazy({"nodes": {}})
    assert str(e.value) == (
        "lazy index: unknown category 'nodes' (known: node, network, rule, kind, map_kind, source, format)"
    )
    assert registry.LAZY_CATEGORIES == ("node", "network", "rule", "kind", "map_kind", "source", "format")


def test_lazy_module_that_fails_is_one_line(tmp_path, monkeypatch):
    pkg = _package(
        tmp_path,
        monkeypatch,
        {"bad": "raise ValueError('boom')\n", "gone": "import no_such_module_regunit\n"},
    )
    registry.declare_lazy(
        {"node": {"x.bad": [f"{pkg}.bad"], "x.gone": [f"{pkg}.gone"]}, "map_kind": {"my_kind": [f"{pkg}.bad"]}}
    )
    with pytest.raises(RegistryError) as e:
        registry.get("x.bad", where="c.xml:4")
    assert str(e.value) == f"c.xml:4: node 'x.bad': module {pkg}.bad failed to import: ValueError: boom"
    with pytest.raises(RegistryError) as e:
        registry.find("x.gone")
    assert str(e.value) == (
        f"node 'x.gone': module {pkg}.gone failed to import (no_such_module_regunit is missing): "
        "ModuleNotFoundError: No module named 'no_such_module_regunit'"
    )
    with pytest.raises(RegistryError) as e:
        registry.map_kinds()
    assert str(e.value).startswith(f"map kind 'my_kind': module {pkg}.bad failed")


def test_lazy_module_raising_registry_error_passes_it_on(tmp_path, monkeypatch):
    src = "from sengine.errors import RegistryError\nraise RegistryError('mine', where='here')\n"
    pkg = _package(tmp_path, monkeypatch, {"m": src})
    registry.declare_lazy({"node": {"x.m": [f"{pkg}.m"]}})
    with pytest.raises(RegistryError) as e:
        registry.get("x.m")
    assert str(e.value) == "here: mine"


def test_replacing_a_lazy_node_before_its_module_is_imported(tmp_path, monkeypatch):
    pkg = _package(tmp_path, monkeypatch, {"a": NODE_SRC.format(cls="A", name="lz.a")})
    registry.declare_lazy({"node": {"lz.a": [f"{pkg}.a"]}}, package=pkg)
    mine = _node("lz.a", module="tests.mine")
    assert registry.register(mine, replace=True) is mine
    assert registry._SHADOWED == {"lz.a": (f"{pkg}.a",)} and "lz.a" not in registry._LAZY["node"]
    __import__(f"{pkg}.a")  # the built-in module arrives later: it does not take the name back
    assert registry.get("lz.a") is mine
    assert sys.modules[f"{pkg}.a"].A.__module__ == f"{pkg}.a"


def test_registering_over_a_lazy_node_imports_it_first_and_refuses(tmp_path, monkeypatch):
    pkg = _package(tmp_path, monkeypatch, {"a": NODE_SRC.format(cls="A", name="lz.a")})
    registry.declare_lazy({"node": {"lz.a": [f"{pkg}.a"]}}, package=pkg)
    with pytest.raises(RegistryError) as e:
        registry.register(_node("lz.a", module="tests.mine"))
    assert str(e.value) == f"node name 'lz.a' is registered twice: {pkg}.a.A and tests.mine.Fake"
    assert registry.REGISTRY["lz.a"].__module__ == f"{pkg}.a"
    # no fallback import of the whole package: a second module of it stays unimported
    assert registry._LAZY_PACKAGES == [pkg]


def test_lazy_module_registering_its_own_node_is_no_conflict(tmp_path, monkeypatch):
    pkg = _package(tmp_path, monkeypatch, {"a": NODE_SRC.format(cls="A", name="lz.a")})
    registry.declare_lazy({"node": {"lz.a": [f"{pkg}.a"]}})
    __import__(f"{pkg}.a")  # imported directly, not through the registry
    assert registry.REGISTRY["lz.a"].__module__ == f"{pkg}.a"
    assert registry._LAZY["node"] == {"lz.a": (f"{pkg}.a",)}  # still indexed: get() imports it (a no-op)
    assert registry.get("lz.a") is registry.REGISTRY["lz.a"]


# -- formats --------------------------------------------------------------------------------


def test_check_formats():
    assert registry.check_formats(["GLB", " obj "]) == frozenset({"glb", "obj"})  # nothing declares formats
    assert registry.check_formats(None) == frozenset() and registry.check_formats(["", "  "]) == frozenset()
    registry.register(_node("export.a", module="t.a", formats=("glb", "obj"), format_hints={"shp": "gpkg"}))
    registry.register(_node("export.b", module="t.b", formats=("obj", "gpkg"), format_hints=None))
    registry.register(_node("export.c", module="t.c"))
    assert registry.check_formats([" GLB", "gpkg", "", "obj"]) == frozenset({"glb", "gpkg", "obj"})
    assert registry.check_formats([]) == frozenset()
    with pytest.raises(ParameterError) as e:
        registry.check_formats(["glb", "shp"])
    assert str(e.value) == "--format: unknown format 'shp'; did you mean 'gpkg'?; formats: glb, obj, gpkg"
    assert e.value.where == "--format"
    with pytest.raises(ParameterError) as e:
        registry.check_formats(["gbl"])
    assert str(e.value) == "--format: unknown format 'gbl'; did you mean 'glb'?; formats: glb, obj, gpkg"
    with pytest.raises(ParameterError) as e:  # ratio 4/7: above the cutoff 0.5, below difflib's default 0.6
        registry.check_formats(["glxx"])
    assert str(e.value) == "--format: unknown format 'glxx'; did you mean 'glb'?; formats: glb, obj, gpkg"
    with pytest.raises(ParameterError) as e:  # the first unknown in sorted order
        registry.check_formats(["zzz", "fbx"])
    assert str(e.value) == "--format: unknown format 'fbx'; formats: glb, obj, gpkg"
    assert registry.formats() == {"glb": "export.a", "obj": "export.a", "gpkg": "export.b"}


def test_formats_of_lazy_writers_import_them(tmp_path, monkeypatch):
    src = NODE_SRC.format(cls="W", name="export.w").replace("    def run", "    formats = ('png',)\n\n    def run")
    pkg = _package(tmp_path, monkeypatch, {"w": src})
    registry.declare_lazy({"node": {"export.w": [f"{pkg}.w"]}, "format": {"png": [f"{pkg}.w"]}})
    assert registry.formats() == {"png": "export.w"}
    assert registry._LAZY["format"] == {}
    with pytest.raises(ParameterError, match="unknown format 'abc'; formats: png"):
        registry.check_formats(["abc"])


# -- networks -------------------------------------------------------------------------------


def test_register_network_and_network_class():
    class Std:
        pass

    class Pattern:
        pass

    Std.__module__ = Pattern.__module__ = "tests.nets"
    Std.__qualname__ = "Std"
    assert registry.register_network("std")(Std) is Std
    assert registry.register_network("pattern")(Pattern) is Pattern
    assert registry.register_network("std")(Std) is Std  # the same class again
    assert registry.network_class("std") is Std and registry.network_names() == ["pattern", "std"]

    class Std2:
        pass

    with pytest.raises(RegistryError) as e:
        registry.register_network("std")(Std2)
    assert str(e.value) == (
        "network base 'std' is registered twice: tests.nets.Std and "
        f"{Std2.__module__}.test_register_network_and_network_class.<locals>.Std2"
    )
    with pytest.raises(RegistryError) as e:
        registry.network_class("stf", where="c.xml:2")
    assert str(e.value) == "c.xml:2: unknown network base 'stf' (known: pattern, std); did you mean 'std'?"
    with pytest.raises(RegistryError) as e:  # ratio 4/7: above the cutoff 0.5, below difflib's default 0.6
        registry.network_class("stxx")
    assert str(e.value) == "unknown network base 'stxx' (known: pattern, std); did you mean 'std'?"
    with pytest.raises(RegistryError) as e:
        registry.network_class("grid")
    assert str(e.value) == "unknown network base 'grid' (known: pattern, std)" and e.value.where is None


NET_SRC = """
from sengine.registry import register_network

@register_network("lzn")
class Net:
    pass
"""


def test_lazy_network(tmp_path, monkeypatch):
    pkg = _package(tmp_path, monkeypatch, {"n": NET_SRC, "extra": "", "bad": "raise OSError('disk')\n"})
    registry.declare_lazy({"network": {"lzn": [f"{pkg}.n"], "lzbad": [f"{pkg}.bad"]}}, package=pkg)
    assert registry.network_names() == ["lzbad", "lzn"] and f"{pkg}.n" not in sys.modules
    assert registry.network_class("lzn").__module__ == f"{pkg}.n"
    assert f"{pkg}.extra" not in sys.modules and registry._LAZY_PACKAGES == [pkg]  # only the indexed module
    with pytest.raises(RegistryError) as e:
        registry.network_class("lzbad", where="c.xml:9")
    assert str(e.value) == f"c.xml:9: network 'lzbad': module {pkg}.bad failed to import: OSError: disk"

    class Other:
        pass

    registry.declare_lazy({"network": {"lzm": [f"{pkg}.n"]}})  # indexed in the wrong module
    assert registry.register_network("lzm")(Other) is Other
    assert registry.NETWORKS["lzm"] is Other and registry._LAZY["network"] == {}


def test_registering_over_a_lazy_network_imports_it_and_refuses(tmp_path, monkeypatch):
    pkg = _package(tmp_path, monkeypatch, {"n": NET_SRC})
    registry.declare_lazy({"network": {"lzn": [f"{pkg}.n"]}})

    class Mine:
        pass

    Mine.__module__, Mine.__qualname__ = "tests.mine", "Mine"
    with pytest.raises(RegistryError) as e:
        registry.register_network("lzn")(Mine)
    assert str(e.value) == f"network base 'lzn' is registered twice: {pkg}.n.Net and tests.mine.Mine"


# -- rules, kinds, map kinds, sources --------------------------------------------------------


def test_declare_rule_and_rule_params(tmp_path, monkeypatch):
    a = Param("float", default=1.0)
    registry.declare_rule("district", {"lot-area": a})
    registry.declare_rule("district", {"lot-area": Param("float", default=1.0), "kind": Param("str", default="x")})
    assert list(registry.rule_params("district")) == ["lot-area", "kind"]
    assert registry.rule_params("district")["lot-area"] == a
    with pytest.raises(RegistryError) as e:
        registry.declare_rule("district", {"lot-area": Param("float", default=2.0)})
    assert str(e.value) == "<district> attribute 'lot-area' is declared twice, differently"
    assert registry.rule_params("landuse") is None
    if not TRAMPOLINED:
        assert registry._ORIGIN[("rule", "district")] == {__name__}
    # a lazily declared rule and an unknown tag that makes the package load
    src = "from sengine.node import Param\nfrom sengine.registry import declare_rule\n"
    src += "declare_rule('landuse', {'far': Param('float', default=2.0)})\n"
    pkg = _package(tmp_path, monkeypatch, {"r": src, "s": src.replace("landuse", "park")})
    registry.declare_lazy({"rule": {"landuse": [f"{pkg}.r"]}}, package=pkg)
    assert list(registry.rule_params("landuse")) == ["far"] and f"{pkg}.s" not in sys.modules
    assert registry.rule_params("district") is not None and f"{pkg}.s" not in sys.modules  # known: no fallback
    assert list(registry.rule_params("park")) == ["far"]  # unknown: the whole package
    if not TRAMPOLINED:
        assert registry._ORIGIN[("rule", "park")] == {f"{pkg}.s"}


def test_declare_kind_kinds_and_docs():
    registry.declare_kind("lots", {"block_id": ("iu", True, "the block")}, doc="parcels")
    registry.declare_kind("lots", {"block_id": ("iu", True, "the block"), "use": ("U", False, "")})
    assert registry.kinds() == {"lots": {"block_id": ("iu", True, "the block"), "use": ("U", False, "")}}
    assert registry.KIND_DOCS == {"lots": "parcels"}
    registry.declare_kind("roads", {})
    assert "roads" not in registry.KIND_DOCS and registry.kinds()["roads"] == {}
    with pytest.raises(RegistryError) as e:
        registry.declare_kind("lots", {"block_id": ("i", True, "the block")})
    assert str(e.value) == "layer kind 'lots': column 'block_id' is declared twice, differently"
    k = registry.kinds()
    k["lots"]["x"] = 1  # a copy
    assert "x" not in registry.KINDS["lots"]


def test_check_kind():
    import shapely

    registry.declare_kind("lots", {"block_id": ("iu", True, ""), "use": ("U", False, ""), "h": ("f", False, "")})
    geoms = np.array([shapely.box(0, 0, 1, 1)], dtype=object)
    good = Layer.from_geoms(geoms, block_id=np.array([3], dtype=np.uint32), use=np.array(["x"]))
    registry.check_kind(good, "lots")
    registry.check_kind(Layer.from_geoms(geoms, block_id=np.array([3])), "lots")  # optional columns may be missing
    registry.check_kind(Layer.from_geoms(geoms), "roads")  # undeclared kind
    registry.check_kind(Layer.from_geoms(geoms[:0]), "lots")  # an empty layer needs no column
    with pytest.raises(NetworkError) as e:
        registry.check_kind(Layer.from_geoms(geoms, use=np.array([1.5])), "lots", where="node 'l'")
    assert str(e.value) == (
        "node 'l': layer of kind 'lots': column 'block_id' is missing; "
        "column 'use' has dtype float64 (kind 'f'), declared 'U'"
    )
    assert e.value.where == "node 'l'"
    with pytest.raises(NetworkError) as e:
        registry.check_kind(Layer.from_geoms(geoms, block_id=np.array([1.0]), h=np.array([2])), "lots")
    assert str(e.value) == (
        "layer of kind 'lots': column 'block_id' has dtype float64 (kind 'f'), declared 'iu'; "
        "column 'h' has dtype int64 (kind 'i'), declared 'f'"
    )


def test_check_kind_imports_a_lazy_kind(tmp_path, monkeypatch):
    src = "from sengine.registry import declare_kind\ndeclare_kind('lzk', {'a': ('i', True, '')})\n"
    pkg = _package(tmp_path, monkeypatch, {"k": src, "other": "raise ValueError('not me')\n"})
    registry.declare_lazy({"kind": {"lzk": [f"{pkg}.k"]}}, package=pkg)
    import shapely

    with pytest.raises(NetworkError, match="column 'a' is missing"):
        registry.check_kind(Layer.from_geoms([shapely.Point(0, 0)]), "lzk")
    registry.check_kind(Layer.from_geoms([shapely.Point(0, 0)]), "unknown_kind")  # no fallback
    assert f"{pkg}.other" not in sys.modules and registry._LAZY_PACKAGES == [pkg]


def test_need_all_imports_only_indexed_modules(tmp_path, monkeypatch):
    src = "from sengine.registry import declare_kind\ndeclare_kind('lzk', {'a': ('i', True, '')})\n"
    pkg = _package(tmp_path, monkeypatch, {"k": src, "extra": ""})
    registry.declare_lazy({"kind": {"lzk": [f"{pkg}.k"], "empty": []}}, package=pkg)
    assert registry._LAZY["kind"]["empty"] == ()
    assert registry.kinds() == {"lzk": {"a": ("i", True, "")}}
    # a key indexed with no module does not make the whole package load
    assert f"{pkg}.extra" not in sys.modules and registry._LAZY_PACKAGES == [pkg]
    assert registry._LAZY["kind"] == {}


def test_map_kinds():
    registry.declare_map_kind("height", "raster", "metres")
    registry.declare_map_kind("height", "raster", "another doc")
    registry.declare_map_kind("mesh", "file")
    assert registry.map_kinds() == {"height": ("raster", "another doc"), "mesh": ("file", "")}
    with pytest.raises(RegistryError) as e:
        registry.declare_map_kind("height", "file")
    assert str(e.value) == "map kind 'height' is declared twice, differently"
    if not TRAMPOLINED:
        assert registry._ORIGIN[("map_kind", "height")] == {__name__}


def test_source_classes():
    r = _node("src.r", module="t.r", source_for="raster")
    registry.register(r)
    registry.register(_node("src.none", module="t.n"))
    assert registry.source_classes() == {"raster": r}


# -- entry points and plugins ----------------------------------------------------------------


def _dist(site, dist: str, eps: dict[str, str]) -> None:
    info = site / f"{dist}-1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 1.0\n")
    lines = "\n".join(f"{k} = {v}" for k, v in eps.items())
    (info / "entry_points.txt").write_text(f"[sengine.nodes]\n{lines}\n")


EP_SRC = """
CALLS = []
def first():
    CALLS.append("builtin")
def second():
    CALLS.append("aaa")
def third():
    CALLS.append("zzz")
def broken():
    raise ImportError("no luck")
def refuse():
    from sengine.errors import RegistryError
    raise RegistryError("duplicate in plugin")
class Klass:
    def __init__(self):
        CALLS.append("klass")
"""


def test_entry_points_run_builtin_first_and_broken_ones_warn(tmp_path, monkeypatch):
    mod = _unique()
    (tmp_path / f"{mod}.py").write_text(EP_SRC)
    # a distribution named sengine earlier on sys.path shadows the installed one
    _dist(tmp_path, "sengine", {"zzz": f"{mod}:third", "builtin": f"{mod}:first", "aaa": f"{mod}:second"})
    # a class and a module are loaded, not called
    _dist(tmp_path, "regunit_other", {"broken": f"{mod}:broken", "klass": f"{mod}:Klass", "module": mod})
    monkeypatch.syspath_prepend(str(tmp_path))
    registry._entry_points_loaded = False
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        registry.load_entry_points()
        registry.load_entry_points()  # once
    assert sys.modules[mod].CALLS == ["builtin", "aaa", "zzz"]
    assert [str(w.message) for w in caught] == [f"sengine plugin 'broken' ({mod}:broken) failed to load: no luck"]
    assert all(w.category is SEngineWarning for w in caught)
    if not TRAMPOLINED:  # stacklevel=2: the warning names the caller's line
        assert [w.filename for w in caught] == [__file__]
    assert registry._entry_points_loaded is True
    assert registry.broken_plugins() == {"broken": "ImportError: no luck"}


def test_missing_builtin_entry_point_warns_and_registry_errors_pass(tmp_path, monkeypatch):
    mod = _unique()
    (tmp_path / f"{mod}.py").write_text(EP_SRC)
    _dist(tmp_path, "sengine", {"aaa": f"{mod}:second"})
    monkeypatch.syspath_prepend(str(tmp_path))
    registry._entry_points_loaded = False
    with pytest.warns(SEngineWarning) as caught:
        registry.load_entry_points()
    assert [str(w.message) for w in caught] == [
        "sengine's built-in nodes are not registered: install the package (pip install .)"
    ]
    if not TRAMPOLINED:
        assert [w.filename for w in caught] == [__file__]
    assert sys.modules[mod].CALLS == ["aaa"] and registry.broken_plugins() == {}

    other = tmp_path / "o"
    _dist(other, "sengine", {"builtin": f"{mod}:refuse"})
    monkeypatch.syspath_prepend(str(other))
    registry._entry_points_loaded = False
    with pytest.raises(RegistryError, match="^duplicate in plugin$"):
        registry.load_entry_points()
    assert registry._entry_points_loaded is True


def test_load_plugin_by_module_name(tmp_path, monkeypatch):
    pkg = _package(
        tmp_path,
        monkeypatch,
        {
            "ok": NODE_SRC.format(cls="P", name="plug.ok"),
            "bad": "x = 1 / 0\n",
            "dep": "import no_such_dependency_regunit\n",
            "reg": "from sengine.errors import RegistryError\nraise RegistryError('own')\n",
        },
    )
    assert registry.load_plugin(f"{pkg}.ok") == f"{pkg}.ok"
    assert registry._loaded[f"{pkg}.ok"] == f"{pkg}.ok" and "plug.ok" in registry.REGISTRY
    del registry.REGISTRY["plug.ok"]
    assert registry.load_plugin(f"{pkg}.ok") == f"{pkg}.ok"  # remembered: not imported again
    with pytest.raises(RegistryError) as e:
        registry.load_plugin(f"{pkg}.bad", where="c.xml:7")
    assert str(e.value) == f"c.xml:7: plugin module '{pkg}.bad' failed to import: ZeroDivisionError: division by zero"
    with pytest.raises(RegistryError) as e:
        registry.load_plugin(f"{pkg}.dep")
    assert str(e.value) == f"plugin module '{pkg}.dep' not found (no_such_dependency_regunit is missing)"
    with pytest.raises(RegistryError) as e:
        registry.load_plugin(f"{pkg}.nothere", where="--plugin")
    assert str(e.value) == f"--plugin: plugin module '{pkg}.nothere' not found ({pkg}.nothere is missing)"
    with pytest.raises(RegistryError) as e:
        registry.load_plugin(f"{pkg}.reg")
    assert str(e.value) == "own"
    assert f"{pkg}.bad" not in registry._loaded and f"{pkg}.reg" not in registry._loaded


def test_load_plugin_by_path(tmp_path, monkeypatch):
    sub = tmp_path / "plugins"
    sub.mkdir()
    (sub / "my-nodes.py").write_text(NODE_SRC.format(cls="P", name="path.ok"))
    name = registry.load_plugin("plugins/my-nodes.py", base_dir=tmp_path, where="c.xml:2")
    key = str((sub / "my-nodes.py").resolve())
    assert name == f"sengine_plugin_my_nodes_{stable_hash(key) % 10**8}"
    assert registry._loaded == {key: name} and sys.modules[name].P is registry.REGISTRY["path.ok"]
    assert registry.load_plugin(str(sub / "my-nodes.py")) == name  # absolute: the same key, not again
    monkeypatch.chdir(tmp_path)
    assert registry.load_plugin("plugins/my-nodes.py") == name  # relative to the working folder
    with pytest.raises(RegistryError) as e:
        registry.load_plugin("nope.py", base_dir=sub)
    assert str(e.value) == f"plugin path {str((sub / 'nope.py').resolve())!r} does not exist"
    with pytest.raises(RegistryError) as e:  # a backslash makes it a path too, not a module name
        registry.load_plugin("a\\b", base_dir=sub, where="w")
    backslash = str((sub / "a\\b").resolve())
    assert str(e.value) == f"w: plugin path {backslash!r} does not exist"
    with pytest.raises(RegistryError) as e:  # a slash
        registry.load_plugin("x/y")
    assert str(e.value) == f"plugin path {str((tmp_path / 'x/y').resolve())!r} does not exist"


def test_load_path_of_a_package_folder_and_broken_files(tmp_path, caplog):
    pkg = tmp_path / "my.pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("from .inner import VALUE\n")
    (pkg / "inner.py").write_text("VALUE = 42\n")
    with caplog.at_level("DEBUG", logger="sengine.registry"):
        name = registry.load_path(pkg)
    assert [r.getMessage() for r in caplog.records] == [f"loaded plugin {pkg.resolve()} as {name}"]
    assert name == f"sengine_plugin_my_pkg_{stable_hash(str(pkg.resolve())) % 10**8}"
    assert sys.modules[name].VALUE == 42
    assert registry.load_path(pkg, module_name="other") == name  # by path, once
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(RegistryError) as e:
        registry.load_path(empty, where="c.xml:1")
    assert str(e.value) == f"c.xml:1: plugin folder {str(empty.resolve())!r} has no __init__.py"
    bad = tmp_path / "bad.py"
    bad.write_text("raise KeyError('k')\n")
    with pytest.raises(RegistryError) as e:
        registry.load_path(bad, module_name="regunit_bad_module", where="c.xml:5")
    assert str(e.value) == f"c.xml:5: plugin {str(bad.resolve())!r} failed to import: KeyError: 'k'"
    assert "regunit_bad_module" not in sys.modules and str(bad.resolve()) not in registry._loaded
    reg = tmp_path / "reg.py"
    reg.write_text("from sengine.errors import RegistryError\nraise RegistryError('dup', where='x')\n")
    with pytest.raises(RegistryError) as e:
        registry.load_path(reg, module_name="regunit_reg_module")
    assert str(e.value) == "x: dup" and "regunit_reg_module" not in sys.modules
    text = tmp_path / "notes.txt"
    text.write_text("hello")
    with pytest.raises(RegistryError) as e:
        registry.load_path(text, where="c.xml:6")
    assert str(e.value) == f"c.xml:6: cannot import plugin {str(text.resolve())!r}"
    ok = tmp_path / "ok.py"
    ok.write_text("X = 1\n")
    assert registry.load_path(ok, module_name="regunit_named") == "regunit_named"
    assert sys.modules["regunit_named"].X == 1


# -- load_all, survey, write_index ----------------------------------------------------------


SURVEY_SRC = {
    "__init__": "",
    "nodes": NODE_SRC.format(cls="A", name="sv.a").replace(
        "    def run", "    source_for = 'raster'\n    formats = ('png', 'glb')\n\n    def run"
    ),
    "more": NODE_SRC.format(cls="B", name="sv.b")
    + "\nfrom sengine.registry import register_network, declare_rule, declare_kind, declare_map_kind\n"
    + "from sengine.node import Param\n"
    + "@register_network('svnet')\nclass Net:\n    pass\n"
    + "declare_rule('district', {'x': Param('int', default=1)})\n"
    + "declare_kind('svkind', {'c': ('i', True, '')})\n"
    + "declare_map_kind('svmap', 'raster')\n",
    "_private": "raise RuntimeError('never imported')\n",
}


def test_survey_indexes_what_each_module_registers(tmp_path, monkeypatch):
    pkg = _package(tmp_path, monkeypatch, dict(SURVEY_SRC))
    registry.register(_node("other.x", module="elsewhere"))
    registry.declare_rule("district", {"y": Param("int", default=1)})  # declared here, not in the package
    assert registry._modules(pkg) == [f"{pkg}.more", f"{pkg}.nodes"]
    for m in ("more", "nodes"):
        __import__(f"{pkg}.{m}")
    if not TRAMPOLINED:
        assert registry._ORIGIN == {
            ("rule", "district"): {__name__, f"{pkg}.more"},
            ("kind", "svkind"): {f"{pkg}.more"},
            ("map_kind", "svmap"): {f"{pkg}.more"},
        }
    registry._ORIGIN.clear()  # as _origin records them outside mutmut (see TRAMPOLINED)
    registry._ORIGIN.update(
        {
            ("rule", "district"): {__name__, f"{pkg}.more"},
            ("kind", "svkind"): {f"{pkg}.more"},
            ("map_kind", "svmap"): {f"{pkg}.more"},
        }
    )
    index = registry.survey(pkg)
    assert index == {
        "node": {"sv.a": [f"{pkg}.nodes"], "sv.b": [f"{pkg}.more"]},
        "network": {"svnet": [f"{pkg}.more"]},
        "rule": {"district": [f"{pkg}.more"]},
        "kind": {"svkind": [f"{pkg}.more"]},
        "map_kind": {"svmap": [f"{pkg}.more"]},
        "source": {"raster": [f"{pkg}.nodes"]},
        "format": {"glb": [f"{pkg}.nodes"], "png": [f"{pkg}.nodes"]},
    }
    assert list(index) == list(registry.LAZY_CATEGORIES)
    assert list(index["format"]) == ["glb", "png"]


def test_modules_skip_private_ones_at_any_depth_and_plain_modules_have_none(tmp_path, monkeypatch):
    pkg = _package(tmp_path, monkeypatch, {"a": "", "_b": ""})
    sub = tmp_path / pkg / "sub"
    sub.mkdir()
    (sub / "__init__.py").write_text("")
    (sub / "_hidden.py").write_text("")
    (sub / "seen.py").write_text("")
    assert registry._modules(pkg) == [f"{pkg}.a", f"{pkg}.sub", f"{pkg}.sub.seen"]
    assert registry._modules(f"{pkg}.a") == []


def test_survey_keeps_a_package_apart_from_one_whose_name_extends_it(tmp_path, monkeypatch):
    pkg = _package(tmp_path, monkeypatch, {"m": NODE_SRC.format(cls="A", name="sv.m")})
    registry.register(_node("sv.twin", module=f"{pkg}x.m"))
    registry.register(_node("sv.top", module=pkg))
    assert registry.survey(pkg)["node"] == {"sv.m": [f"{pkg}.m"], "sv.top": [pkg]}


def test_write_index_and_load_all(tmp_path, monkeypatch):
    files = dict(SURVEY_SRC)
    files["broken"] = "raise ValueError('bad module')\n"
    pkg = _package(tmp_path, monkeypatch, files)
    (tmp_path / pkg / "broken.py").unlink()  # survey imports every module: broken only for load_all
    old = '"""Kept docstring."""\n\nimport os  # kept X\n\nINDEX = {}\nINDEX_NOTE = 1\n'
    (tmp_path / pkg / "_index.py").write_text(old)
    path = registry.write_index(pkg)
    assert path == tmp_path / pkg / "_index.py"
    text = path.read_text()
    # the text before the first INDEX kept, everything from it on replaced
    head = '"""Kept docstring."""\n\nimport os  # kept X\n\nINDEX: dict[str, dict[str, list[str]]] = {\n'
    assert text.startswith(head)
    assert "INDEX_NOTE" not in text and text.endswith("}\n")
    # formatted by ruff (pprint writes single quotes), categories in their own order
    assert "'" not in text and '\n    "node": {"sv.a": [' in text
    ns: dict = {}
    exec(text, ns)
    assert ns["INDEX"] == registry.survey(pkg) and ns["INDEX"]["node"]["sv.b"] == [f"{pkg}.more"]
    assert list(ns["INDEX"]) == list(registry.LAZY_CATEGORIES)
    (tmp_path / pkg / "_index.py").unlink()
    text = registry.write_index(pkg).read_text()
    assert text.startswith(f'"""What the modules of {pkg} register (made by write_index)."""\n\nINDEX: ')

    (tmp_path / pkg / "broken.py").write_text("raise ValueError('bad module')\n")
    registry.declare_lazy({"node": {"q": ["x"]}, "kind": {"k": ["x"]}}, package=pkg)
    registry.declare_lazy({}, package="sengine.geom")  # a second package
    with pytest.warns(SEngineWarning) as caught:
        done = registry.load_all()
    assert [str(w.message) for w in caught] == [f"sengine module {pkg}.broken failed to import: bad module"]
    if not TRAMPOLINED:
        assert [w.filename for w in caught] == [__file__]
    assert done[:2] == [f"{pkg}.more", f"{pkg}.nodes"] and f"{pkg}.broken" not in done
    assert "sengine.geom.raster" in done
    assert registry._broken == {f"{pkg}.broken": "ValueError: bad module"}
    assert all(not v for v in registry._LAZY.values()) and registry._LAZY_PACKAGES == []
    assert registry.load_all() == []


def test_load_all_passes_registry_errors(tmp_path, monkeypatch):
    pkg = _package(tmp_path, monkeypatch, {"r": "from sengine.errors import RegistryError\nraise RegistryError('r')\n"})
    registry.declare_lazy({}, package=pkg)
    with pytest.raises(RegistryError, match="^r$"):
        registry.load_all()

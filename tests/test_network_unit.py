"""sengine.network on small node classes, with the exact messages a user reads.

test_engine runs the demo networks; these pin building a network (add, replace, set_param,
connect, disconnect, merge), validate's problems one by one, port resolution, the plan's
source nodes, check, the run loop and its stats, the chunked executor over worker processes,
the plugin error wrapping, report merging and the output folder, for the mutation run of
docs/mutation.md.  Nodes are registered under ``nu.*`` for this module.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import re
import shutil
import subprocess
import time
from functools import partial
from types import SimpleNamespace
from typing import ClassVar

import numpy as np
import pytest
import shapely

from sengine import registry
from sengine.errors import NetworkError, NodeError, OutputError, ParameterError, Problems, RegistryError
from sengine.layer import Layer
from sengine.network import (
    FORK_AFTER,
    MIN_CHUNK,
    Connection,
    Network,
    NodeSpec,
    Result,
    _call_run,
    _move_into,
    _output_folder,
    _run_node,
    _run_order,
    _sum_reports,
    _write_json,
    check_output_folder,
    layer_area,
)
from sengine.node import Context, NodeResult, Param, Port, SENode
from sengine.plan import CityPlan, MapSpec
from sengine.progress import Progress


def _boxes(n: int, size: float = 1.0) -> Layer:
    return Layer.from_geoms([shapely.box(3 * i, 0, 3 * i + size, size) for i in range(n)])


class Src(SENode):
    name = "nu.src"
    outputs = {"polys": Port("polygons")}
    params = {"n": Param("int", default=2, min=0), "size": Param("float", default=1.0, min=0.0)}

    def run(self):
        return NodeResult({"polys": _boxes(self.p.n, self.p.size)}, {"made": self.p.n})


class Lines(SENode):
    name = "nu.lines"
    outputs = {"lines": Port("lines")}

    def run(self):
        return {"lines": Layer.from_geoms([shapely.LineString([(0, 0), (4, 0)])])}


class Grow(SENode):
    name = "nu.grow"
    inputs = {"polys": Port("polygons")}
    outputs = {"out": Port("polygons")}
    params = {"d": Param("float", default=1.0)}
    maps_features = True

    def run(self, *, polys):
        if self.context.options.get("slow") and len(polys) == MIN_CHUNK:
            time.sleep(0.3)  # the first chunk: the executor then sends the rest to the workers
        g = shapely.buffer(polys.geometry, self.p.d, join_style="mitre")
        out = Layer.from_geoms(g, ids=polys.ids, parent=polys.ids)
        return NodeResult({"out": out}, {"features": len(polys), "max_len": len(polys)})


class Renumber(Grow):
    """Numbers its features 0..n-1 per call: chunked outputs must be renumbered."""

    name = "nu.renumber"

    def run(self, *, polys):
        res = super().run(polys=polys)
        out = res.layers["out"]
        return {"out": Layer.from_geoms(out.geometry, parent=out.parent)}


class Whole(Grow):
    """Grow that does not map features one by one: never cut into chunks."""

    name = "nu.whole"
    maps_features = False


class Two(SENode):
    name = "nu.two"
    outputs = {"a": Port("polygons"), "b": Port("lines")}

    def run(self):
        return {"a": _boxes(1), "b": Lines("l").run()["lines"]}


class TakesRaster(SENode):
    name = "nu.takesraster"
    inputs = {"r": Port("nuraster")}

    def run(self, *, r):
        return None


def _area_or_none(polys):
    return None if polys is None else float(polys.area())


class Early(SENode):
    """A node whose job on its ``polys`` input starts in another process as soon as that input is made."""

    name = "nu.early"
    inputs = {"polys": Port("polygons", required=False), "other": Port("polygons", required=False)}
    outputs = {"out": Port("polygons")}
    params = {"take": Param("bool", default=True)}
    early_inputs = ("polys",)
    SEEN: ClassVar[list] = []

    def early(self, *, polys):
        return partial(_area_or_none, polys)

    def run(self, *, polys, other):
        Early.SEEN.append(self)
        started = self.early_started()
        value = self.early_result() if self.p.take else None
        return NodeResult({"out": _boxes(0)}, {"started": started, "value": -1.0 if value is None else value})


class Pair(SENode):
    name = "nu.pair"
    inputs = {"a": Port("polygons"), "b": Port("polygons", required=False)}
    outputs = {"merged": Port("polygons")}

    def run(self, *, a, b):
        return {"merged": Layer.concat([a] + ([b] if b is not None else []))}


class Sink(SENode):
    name = "nu.sink"
    inputs = {"polys": Port("polygons"), "lines": Port("lines", required=False)}
    formats = ("txt",)

    def run(self, *, polys, lines):
        if self.context.out is not None:
            (self.context.out / "count.txt").write_text(f"{len(polys)}\n")
        return None


class Any_(SENode):
    name = "nu.any"
    inputs = {"x": Port("any")}
    outputs = {"y": Port("any")}

    def run(self, *, x):
        return {"y": x}


class NoIO(SENode):
    name = "nu.noio"

    def run(self):
        return None


class Fails(SENode):
    name = "nu.fails"
    outputs = {"out": Port("polygons")}
    params = {"how": Param("str", default="value")}

    def run(self):
        if self.p.how == "memory":
            raise MemoryError
        if self.p.how == "param":
            raise ParameterError("bad thing", where="here")
        raise ValueError("broken plugin")


class Raster(SENode):
    """The plan's source of ``raster`` layers: one per map of the plan."""

    name = "nu.raster"
    outputs = {"raster": Port("nuraster")}
    params = {"kind": Param("str", default="x")}
    source_for = "nuraster"

    @classmethod
    def plan_source(cls, key, plan):
        spec = plan.maps.get(key)
        return None if spec is None else ({"kind": key}, spec.where)

    def check(self):
        if self.p.kind == "nocheck":
            raise ParameterError("a source that ran is not checked again")

    def run(self):
        if self.p.kind == "broken":
            raise ParameterError("map 'broken' cannot be read", where="plan.xml:4")
        return {"raster": Layer.from_geoms([shapely.box(0, 0, 1, 1)], kind=np.array([self.p.kind]))}


class RasterIn(SENode):
    """A plan source with an input: ``check`` does not run it."""

    name = "nu.rasterin"
    inputs = {"polys": Port("polygons", required=False)}
    outputs = {"raster": Port("nuother")}
    source_for = "nuother"

    def run(self, *, polys):
        raise AssertionError("not run by check")


class UsesMap(SENode):
    name = "nu.usesmap"
    inputs = {
        "polys": Port("polygons"),
        "nuheight_map": Port("nuraster", required=False),
        "zone_map": Port("nuraster", required=False),
        "other_thing": Port("polygons", required=False),
        "nokey": Port("nuraster", required=False),
        "big_zone_map": Port("nuraster", required=False),
    }
    outputs = {"out": Port("polygons")}

    def check(self, *, polys, nuheight_map, zone_map, other_thing, nokey, big_zone_map):
        if nuheight_map is not None and nuheight_map.attrs["kind"][0] == "height":
            raise ParameterError(f"checked {len(nuheight_map)} map, polys {polys}, zone {zone_map}", where="check")

    def run(self, *, polys, nuheight_map, zone_map, other_thing, nokey, big_zone_map):
        return {"out": polys}


class NotMine(SENode):
    """A built-in node's bug keeps its traceback: its class lives in the sengine package."""

    name = "nu.builtin"
    outputs = {"out": Port("polygons")}

    def run(self):
        raise ValueError("a bug")


NotMine.__module__ = "sengine.nodes.fake"

NODES = (Src, Lines, Grow, Renumber, Whole, Two, TakesRaster, Early, Pair, Sink, Any_, NoIO, Fails, Raster, RasterIn)
NODES += (UsesMap, NotMine)


@pytest.fixture(autouse=True, scope="module")
def nodes():
    registry.load_entry_points()
    for cls in NODES:
        registry.register(cls, replace=True)
    registry.declare_map_kind("nuheight", "nuraster")
    registry.declare_map_kind("nulone", "nuraster")
    yield
    # only what this module added goes: the library's modules imported meanwhile stay registered
    for cls in NODES:
        del registry.REGISTRY[cls.name]
    del registry.MAP_KINDS["nuheight"], registry.MAP_KINDS["nulone"]


def _chain(n: int = 2, **grow) -> Network:
    net = Network(source="t.xml")
    net.add("s", "nu.src", {"n": n}, where="t.xml:2")
    net.add("g", "nu.grow", grow, where="t.xml:3")
    net.connect("s", "g", where="t.xml:4")
    return net


# -- small pieces ---------------------------------------------------------------------------


def test_spec_connection_result_and_area():
    assert NodeSpec("a", "t").label() == "node 'a' (t)"
    assert NodeSpec("a", "t", where="f.xml:3").label() == "f.xml:3: node 'a' (t)"
    assert Connection.parse("a.out", "b.in", "w") == Connection("a", "out", "b", "in", "w")
    assert Connection.parse("a", "b") == Connection("a", None, "b", None, "")
    assert Connection.parse("a.x.y", "b.") == Connection("a", "x.y", "b", None, "")
    one, two = _boxes(1), _boxes(2, 2.0)
    r = Result({"n": {"first": one, "second": two}}, {"k": 1})
    layers, stats = r
    assert layers == {"n": {"first": one, "second": two}} and stats == {"k": 1}
    assert r["n"] is one
    assert layer_area({"a": two, "b": one}, 2) == 8.0
    assert layer_area({"a": two}, 0) == 0.0 and layer_area({}, 3) == 0.0


def test_run_order_takes_the_first_ready_in_file_order():
    assert _run_order(["a", "b", "c"], []) == ["a", "b", "c"]
    assert _run_order(["c", "b", "a"], [("a", "c")]) == ["b", "a", "c"]
    assert _run_order(["x", "y", "z", "w"], [("z", "x"), ("w", "y")]) == ["z", "x", "w", "y"]
    # a node made ready later but earlier in the file goes first among those ready
    assert _run_order(["b", "a", "c"], [("a", "b"), ("c", "b")]) == ["a", "c", "b"]
    from graphlib import CycleError

    with pytest.raises(CycleError) as e:
        _run_order(["a", "b", "c"], [("a", "b"), ("b", "a")])
    assert sorted(e.value.args[1][:-1]) == ["a", "b"] and e.value.args[1][0] == e.value.args[1][-1]


def test_sum_reports():
    assert _sum_reports([]) == {}
    reps = [
        {"n": 2, "max_len": 5, "name": "a", "flag": True, "x": 1.5, "sub": {"k": 1, "max_k": 3}},
        {"n": 3, "max_len": 4, "name": "b", "flag": False, "sub": {"k": 2, "max_k": 7}, "late": 1},
        {"n": 1, "max_len": 9, "x": 0.5, "late": 2},
    ]
    assert _sum_reports(reps) == {
        "n": 6,
        "max_len": 9,
        "name": "a",
        "flag": True,
        "x": 2.0,
        "sub": {"k": 3, "max_k": 7},
        "late": 3,
    }
    assert _sum_reports([{"v": 2}, {"v": "x"}]) == {"v": 2}


# -- building ---------------------------------------------------------------------------------


def test_add_replace_set_param_connect_disconnect():
    net = Network(seed=7, base_dir="here", source="s.xml")
    assert (net.seed, net.base_dir, net.source) == (7, __import__("pathlib").Path("here"), "s.xml")
    assert isinstance(net.plan, CityPlan) and Network().base_dir is None
    assert (Network().seed, Network().source) == (0, "")
    spec = net.add("a", "nu.src", {"n": 3}, where="s.xml:2")
    assert spec == NodeSpec("a", "nu.src", {"n": 3}, "s.xml:2", {"n": "s.xml:2"})
    with pytest.raises(NetworkError) as e:
        net.add("a", "nu.lines", where="s.xml:9")
    assert str(e.value) == "s.xml:9: node id 'a' is defined twice (first at s.xml:2)"
    net.add("b", "nu.grow")
    with pytest.raises(NetworkError) as e:
        net.add("b", "nu.grow")
    assert str(e.value) == "node id 'b' is defined twice (first at an earlier line)" and e.value.where is None
    net.replace("a", "nu.lines", where="s.xml:5")
    assert (net.specs["a"].type, net.specs["a"].where) == ("nu.lines", "s.xml:5")
    net.replace("a", "nu.src")
    assert (net.specs["a"].type, net.specs["a"].where) == ("nu.src", "s.xml:5")
    net.set_param("b", "d", 2.5, where="s.xml:6")
    assert net.specs["b"].params == {"d": 2.5} and net.specs["b"].param_where == {"d": "s.xml:6"}
    net.set_param("b", "e", 1)
    assert net.specs["b"].param_where == {"d": "s.xml:6", "e": ""}
    del net.specs["b"].params["e"], net.specs["b"].param_where["e"]
    with pytest.raises(NetworkError) as e:
        net._spec("zz")
    assert e.value.where is None
    with pytest.raises(NetworkError) as e:
        net.replace("zz", "t", where="s.xml:8")
    assert e.value.where == "s.xml:8"
    with pytest.raises(NetworkError) as e:
        net.set_param("zz", "d", 1, where="s.xml:7")
    assert str(e.value) == "s.xml:7: no node with id 'zz' in the network (nodes: a, b)"
    with pytest.raises(NetworkError) as e:
        Network().replace("q", "t")
    assert str(e.value) == "no node with id 'q' in the network (nodes: none)" and e.value.where is None
    net.connect("a.polys", "b.polys", where="s.xml:8")
    net.connect("a", "b")
    net.connect("b", "a")
    assert net.connections == [
        Connection("a", "polys", "b", "polys", "s.xml:8"),
        Connection("a", None, "b", None, ""),
        Connection("b", None, "a", None, ""),
    ]
    net.disconnect("a", "b")  # a port left out matches any: both connections go
    assert net.connections == [Connection("b", None, "a", None, "")]
    net.connect("a.polys", "b.polys")
    net.connect("a.other", "b.polys")
    net.disconnect("a.polys", "b")
    assert [c.src_port for c in net.connections] == [None, "other"]
    with pytest.raises(NetworkError) as e:
        net.disconnect("b", "a.x", where="s.xml:9")
    assert str(e.value) == "s.xml:9: there is no connection from 'b' to 'a.x' to remove"
    with pytest.raises(NetworkError) as e:
        net.disconnect("a", "c")
    assert e.value.where is None
    net.disconnect("a.other", "b.polys")
    assert net.connections == [Connection("b", None, "a", None, "")]


def test_merge():
    a = Network()
    a.add("s", "nu.src", {"n": 1}, where="a.xml:1")
    b = Network()
    b.add("g", "nu.grow", {"d": 2.0}, where="b.xml:1")
    b.set_param("g", "d", 3.0, where="b.xml:5")
    b.connect("s", "g", where="b.xml:2")
    a.merge(b)
    assert list(a.specs) == ["s", "g"] and a.specs["g"].params == {"d": 3.0} and a.specs["g"].type == "nu.grow"
    assert a.specs["g"].param_where == {"d": "b.xml:5"} and a.specs["g"].where == "b.xml:1"
    assert a.connections == [Connection("s", None, "g", None, "b.xml:2")]
    c = Network()
    c.add("s", "nu.src", where="c.xml:1")
    with pytest.raises(NetworkError, match=r"^c.xml:1: node id 's' is defined twice \(first at a.xml:1\)$"):
        a.merge(c)


# -- validation ---------------------------------------------------------------------------------


def _problems(net: Network) -> list[str]:
    with pytest.raises(Problems) as e:
        net.validate()
    assert e.value.where == (net.source or None)
    return [str(p) for p in e.value.problems]


def test_validate_collects_every_problem():
    net = Network(source="v.xml")
    net.add("s", "nu.src", where="v.xml:1")
    net.add("bad", "nu.src", {"n": -1}, where="v.xml:2")
    net.add("u", "zz.qqqq", where="v.xml:3")
    net.add("g", "nu.grow", where="v.xml:4")
    net.add("p", "nu.pair", where="v.xml:5")
    net.add("k", "nu.sink", where="v.xml:6")
    net.set_param("g", "dd", 1, where="v.xml:9")
    net.connect("u", "g", where="v.xml:10")  # the unknown node is reported once, not again here
    net.connect("s", "zz", where="v.xml:11")
    net.connect("s.polys", "p.c", where="v.xml:12")
    net.connect("bad", "k", where="v.xml:13")  # bad is reported already: k's input is not
    assert _problems(net) == [
        "v.xml:2: node 'bad' (nu.src): n=-1 is below the minimum 0",
        "v.xml:3: node 'u' (zz.qqqq): unknown node type 'zz.qqqq'",
        "v.xml:9: node 'g' (nu.grow): unknown parameter 'dd'; did you mean 'd'? (parameters: d)",
        "v.xml:11: connection names unknown node 'zz' (nodes: s, bad, u, g, p, k)",
        "v.xml:12: node 'p' (nu.pair) has no input 'c' (inputs: a, b)",
        # g's, p's and k's inputs echo failed connections: not reported
    ]
    net.connections.pop()
    assert (
        _problems(net)[-1] == "v.xml:6: node 'k' (nu.sink): required input 'polys' (kind 'polygons') is not connected"
    )


def test_param_where_names_the_line_of_the_parameter():
    net = Network()
    net.add("s", "nu.src", where="a.xml:2")
    net.set_param("s", "size", -1, where="b.xml:7")
    net.set_param("s", "n", 2, where="")
    with pytest.raises(ParameterError) as e:
        net.validate()
    assert str(e.value) == "b.xml:7: node 's' (nu.src): size=-1.0 is below the minimum 0.0"
    net.set_param("s", "size", -1, where="")  # no line of its own: the node's
    with pytest.raises(ParameterError) as e:
        net.validate()
    assert str(e.value) == "a.xml:2: node 's' (nu.src): size=-1.0 is below the minimum 0.0"


def test_validate_one_problem_is_itself_and_a_cycle_names_its_nodes():
    net = Network(source="c.xml")
    net.add("a", "nu.any")
    net.add("b", "nu.any")
    net.connect("a", "b")
    net.connect("b", "a")
    with pytest.raises(NetworkError) as e:
        net.validate()
    assert str(e.value) in (
        "c.xml: the network has a cycle: a -> b -> a",
        "c.xml: the network has a cycle: b -> a -> b",
    )
    net.source = ""
    with pytest.raises(NetworkError) as e:
        net.validate()
    assert e.value.where is None and str(e.value).startswith("the network has a cycle: ")


def test_resolve_messages():
    net = Network()
    net.add("s", "nu.src")
    net.add("l", "nu.lines")
    net.add("n", "nu.noio")
    net.add("g", "nu.grow")
    net.add("p", "nu.pair")
    net.add("k", "nu.sink")
    net.add("t", "nu.two")
    net.add("r", "nu.takesraster")
    cases = [
        ("s.x", "g", "w:1", "w:1: node 's' (nu.src) has no output 'x' (outputs: polys)"),
        ("n.x", "g", "", "node 'n' (nu.noio) has no output 'x' (outputs: none)"),
        ("s", "n.x", "", "node 'n' (nu.noio) has no input 'x' (inputs: none)"),
        ("k", "g", "w:2", "w:2: node 'k' (nu.sink) has no outputs to connect"),
        ("s", "n", "w:3", "w:3: node 'n' (nu.noio) has no inputs to connect"),
        ("t.x", "g", "", "node 't' (nu.two) has no output 'x' (outputs: a, b)"),
        ("t.b", "g", "", "port kind mismatch: 't' gives b:lines but 'g' takes polys:polygons"),
        ("t", "r", "", "port kind mismatch: 't' gives a:polygons, b:lines but 'r' takes r:nuraster"),
        ("l", "g", "", "port kind mismatch: 'l' gives lines:lines but 'g' takes polys:polygons"),
        ("l.lines", "p.a", "", "port kind mismatch: 'l' gives lines:lines but 'p' takes a:polygons"),
        ("l", "p", "", "port kind mismatch: 'l' gives lines:lines but 'p' takes a:polygons, b:polygons"),
    ]
    for src, dst, where, msg in cases:
        net.connections = [Connection.parse(src, dst, where)]
        with pytest.raises(Problems) as e:
            net.validate()
        assert str(e.value.problems[0]) == msg, (src, dst)
        assert e.value.problems[0].where == (where or None)


def test_resolve_of_an_empty_network_and_the_first_port_that_takes_the_kind():
    net = Network()
    net.connect("a", "b", where="e.xml:1")
    with pytest.raises(NetworkError) as e:
        net.validate()
    assert str(e.value) == "e.xml:1: connection names unknown node 'a' (nodes: none)"
    net = Network()
    net.add("l", "nu.lines")
    net.add("k", "nu.sink")
    net.add("t", "nu.two")
    net.add("p", "nu.pair")
    net.add("s", "nu.src")
    net.connect("l", "k")  # the first free port (polys) does not take lines: the next one does
    net.connect("s", "k")
    net.connect("t", "p")  # the first output (a) fits the first free input
    net.connect("t", "p")  # then the second free input
    edges = net.validate().edges
    assert edges == [
        ("l", "lines", "k", "lines"),
        ("s", "polys", "k", "polys"),
        ("t", "a", "p", "a"),
        ("t", "a", "p", "b"),
    ]


def test_resolve_fills_free_ports_in_order_and_refuses_a_second_connection():
    net = Network()
    net.add("s", "nu.src")
    net.add("t", "nu.src")
    net.add("p", "nu.pair")
    net.add("l", "nu.lines")
    net.add("k", "nu.sink")
    net.connect("s", "p")
    net.connect("t", "p")
    net.connect("p", "k")
    net.connect("l", "k")  # lines go to the lines port, whatever its place
    bound = net.validate()
    assert [n.id for n in bound.nodes.values()] == ["s", "t", "p", "l", "k"]
    assert bound.edges == [
        ("s", "polys", "p", "a"),
        ("t", "polys", "p", "b"),
        ("p", "merged", "k", "polys"),
        ("l", "lines", "k", "lines"),
    ]
    assert bound.order == ["s", "t", "p", "l", "k"]
    net.connect("s", "p", where="x.xml:8")  # no free port of that kind left
    with pytest.raises(NetworkError) as e:
        net.validate()
    assert str(e.value) == "x.xml:8: port kind mismatch: 's' gives polys:polygons but 'p' takes none free"
    net.connections[-1] = Connection.parse("s.polys", "p.a", "x.xml:9")
    with pytest.raises(NetworkError) as e:
        net.validate()
    assert str(e.value) == "x.xml:9: input 'p.a' is connected twice (also from 's' at another line)"
    net.connections[0] = Connection.parse("s", "p", "x.xml:1")
    with pytest.raises(NetworkError) as e:
        net.validate()
    assert str(e.value) == "x.xml:9: input 'p.a' is connected twice (also from 's' at x.xml:1)"


def test_any_ports_and_named_source_port():
    net = Network()
    net.add("l", "nu.lines")
    net.add("a", "nu.any")
    net.add("g", "nu.grow")
    net.connect("l.lines", "a.x")
    net.connect("a.y", "g.polys")
    assert net.validate().edges == [("l", "lines", "a", "x"), ("a", "y", "g", "polys")]


def test_plan_sources_run_first():
    net = Network()
    net.add("s", "nu.src")
    net.add("u", "nu.usesmap")
    net.add("r", "nu.raster", {"kind": "q"})
    net.connect("s", "u")
    net.connect("r", "u.nuheight_map")
    assert net.validate().order == ["r", "s", "u"]


# -- the plan's inputs ---------------------------------------------------------------------------


def _planned(**maps) -> Network:
    plan = CityPlan(maps={k: MapSpec(k, f"{k}.png", where=w) for k, w in maps.items()})
    net = Network(plan=plan, source="plan.xml")
    net.add("s", "nu.src")
    net.add("u", "nu.usesmap")
    net.connect("s", "u")
    return net


def test_wire_plan_adds_and_connects_source_nodes():
    # nuheight: a declared map kind, made whatever takes it; zone: not a declared map kind,
    # made because a port asks for it; nothing declares "lone" nor asks for it
    net = _planned(nuheight="plan.xml:3", zone="plan.xml:4", lone="plan.xml:5", nulone="plan.xml:2")
    net.plan.maps["big_zone"] = MapSpec("big_zone", "b.png", where="plan.xml:6")
    net.add("v", "nu.usesmap")
    net.add("x", "nu.unknown")  # left for validate
    net.add("r", "nu.raster")  # a source takes no plan input itself
    net.connect("s", "v")
    net.add("w", "nu.usesmap")
    net.connect("s", "w")
    net.add("wm", "nu.raster", {"kind": "other"})
    net.connect("wm", "w.nuheight_map")  # a named connection: left alone
    assert net.wire_plan() == ["nuheightMap", "nuloneMap", "zoneMap", "big_zoneMap"]
    assert net.specs["nuheightMap"] == NodeSpec(
        "nuheightMap", "nu.raster", {"kind": "nuheight"}, "plan.xml:3", {"kind": "plan.xml:3"}
    )
    assert net.specs["zoneMap"].params == {"kind": "zone"} and net.specs["zoneMap"].where == "plan.xml:4"
    assert net.specs["nuloneMap"].params == {"kind": "nulone"}
    assert net.specs["big_zoneMap"].params == {"kind": "big_zone"}
    assert net.connections[4:] == [
        Connection("nuheightMap", None, "u", "nuheight_map", "plan.xml:3"),
        Connection("zoneMap", None, "u", "zone_map", "plan.xml:4"),
        Connection("big_zoneMap", None, "u", "big_zone_map", "plan.xml:6"),
        Connection("nuheightMap", None, "v", "nuheight_map", "plan.xml:3"),
        Connection("zoneMap", None, "v", "zone_map", "plan.xml:4"),
        Connection("big_zoneMap", None, "v", "big_zone_map", "plan.xml:6"),
        Connection("zoneMap", None, "w", "zone_map", "plan.xml:4"),
        Connection("big_zoneMap", None, "w", "big_zone_map", "plan.xml:6"),
    ]
    n = len(net.connections)
    assert net.wire_plan() == [] and len(net.connections) == n  # idempotent: every port is named now
    del net.specs["x"]
    bound = net.validate()
    assert bound.order[:6] == ["r", "wm", "nuheightMap", "nuloneMap", "zoneMap", "big_zoneMap"]


def test_wire_plan_leaves_ports_the_plan_has_nothing_for():
    net = Network(plan=CityPlan())
    net.add("s", "nu.src")
    net.add("u", "nu.usesmap")
    net.connect("s", "u")
    assert net.wire_plan() == [] and list(net.specs) == ["s", "u"] and len(net.connections) == 1
    # a source node the config made itself is connected by name, not made again
    net.add("zoneMap", "nu.raster", {"kind": "z"}, where="c.xml:9")
    assert net.wire_plan() == [] and net.connections[1:] == [Connection("zoneMap", None, "u", "zone_map", "c.xml:9")]


def test_check_runs_sources_then_node_checks():
    net = _planned()
    net.add("hm", "nu.raster", {"kind": "height"})
    net.connect("hm", "u.nuheight_map")
    with pytest.raises(ParameterError) as e:
        net.check()
    assert str(e.value) == "check: checked 1 map, polys None, zone None"
    net.specs["hm"].params["kind"] = "other"
    result = net.check()
    assert list(result.layers) == ["hm"] and result.stats == {}
    assert list(result.layers["hm"]["raster"].attrs["kind"]) == ["other"]
    net.specs["hm"].params["kind"] = "broken"
    net.add("hm2", "nu.raster", {"kind": "height"})
    net.add("u2", "nu.usesmap")
    net.connect("s", "u2")
    net.connect("hm2", "u2.nuheight_map")
    with pytest.raises(Problems) as e:
        net.check()
    assert [str(p) for p in e.value.problems] == [
        "plan.xml:4: map 'broken' cannot be read",
        "check: checked 1 map, polys None, zone None",
    ]
    assert e.value.where == "plan.xml"


def test_check_skips_sources_with_inputs_and_does_not_check_a_source_again():
    net = Network()
    net.add("ri", "nu.rasterin")  # a source with an input is not run by check
    net.add("hm", "nu.raster", {"kind": "broken"})
    with pytest.raises(ParameterError, match="map 'broken' cannot be read"):
        net.check()
    net.specs["hm"].params["kind"] = "nocheck"
    assert list(net.check().layers) == ["hm"]


# -- running ---------------------------------------------------------------------------------


class Events(Progress):
    def __init__(self):
        self.seen = []
        self.seconds = []

    def start(self, i, n, node_id, type_):
        self.seen.append(("start", i, n, node_id, type_))

    def advance(self, done, total, unit):
        self.seen.append(("advance", done, total, unit))

    def finish(self, i, n, node_id, type_, count, seconds):
        self.seen.append(("finish", i, n, node_id, type_, count))
        self.seconds.append(seconds)

    def close(self):
        self.seen.append(("close",))


def test_run_returns_layers_and_stats(tmp_path, caplog):
    net = _chain(3, d=0.5)
    net.add("k", "nu.sink")
    net.add("e", "nu.noio")
    net.add("hm", "nu.raster")
    net.connect("g", "k")
    events = Events()
    out = tmp_path / "out"
    t0 = time.perf_counter()
    with caplog.at_level("INFO", logger="sengine.network"):
        result = net.run(seed=5, out=out, progress=events, formats=["TXT"])
    wall = time.perf_counter() - t0
    lines = [r.getMessage() for r in caplog.records if r.name == "sengine.network"]
    assert [re.sub(r"in \d+\.\d{3} s$", "in T s", m) for m in lines] == [
        "hm (nu.raster): 1 features in T s",
        "s (nu.src): 3 features in T s",
        "g (nu.grow): 3 features in T s",
        "k (nu.sink): 0 features in T s",
        "e (nu.noio): 0 features in T s",
    ]
    layers, stats = result
    assert list(layers) == ["hm", "s", "g", "k", "e"]
    assert layers["k"] == {} and layers["e"] == {}
    assert result["g"].area() == pytest.approx(3 * 4.0) and list(result["g"].parent) == [0, 1, 2]
    assert {k: v for k, v in stats.items() if k != "seconds"} == {
        "sengine": __import__("sengine").__version__,
        "config": "t.xml",
        "seed": 5,
        "counts": {"s": 3, "g": 3},  # sinks and plan sources count nothing
        "areas": {"hm": 1.0, "s": 3.0, "g": 12.0},
        "report": {"s": {"made": 3}, "g": {"features": 3, "max_len": 3}},
    }
    assert list(stats["seconds"]) == ["hm", "s", "g", "k", "e", "total"]
    assert all(isinstance(v, float) and v >= 0 and round(v, 4) == v for v in stats["seconds"].values())
    assert stats["seconds"]["total"] >= max(v for k, v in stats["seconds"].items() if k != "total")
    assert stats["seconds"]["total"] <= wall + 1e-4
    net.specs["s"].params["size"] = 1.23  # 3 boxes of 1.5129 m2: 4.5 to 0.1 m2
    assert net.run().stats["areas"]["s"] == 4.5
    assert sorted(os.listdir(out)) == ["count.txt", "stats.json"]
    assert (out / "count.txt").read_text() == "3\n"
    assert json.loads((out / "stats.json").read_text()) == stats
    assert (out / "stats.json").read_text().startswith('{\n  "sengine": ')
    assert [p for p in os.listdir(tmp_path) if p != "out"] == []  # the temporary folder is gone
    assert events.seen[0] == ("start", 1, 5, "hm", "nu.raster")
    assert [e for e in events.seen if e[0] == "finish"] == [
        ("finish", 1, 5, "hm", "nu.raster", 1),
        ("finish", 2, 5, "s", "nu.src", 3),
        ("finish", 3, 5, "g", "nu.grow", 3),
        ("finish", 4, 5, "k", "nu.sink", 0),
        ("finish", 5, 5, "e", "nu.noio", 0),
    ]
    assert events.seen[-1] == ("close",)
    # the default seed is the network's; no out writes nothing
    net.seed = 11
    assert net.run().stats["seed"] == 11 and net.run(seed="3").stats["seed"] == 3


def test_run_passes_the_context():
    seen = {}

    class Look(SENode):
        name = "nu.look"
        outputs = {"o": Port("polygons")}

        def run(self):
            c = self.context
            seen.update(seed=c.seed, out=c.out, formats=c.formats, workers=c.workers, options=c.options, name=c.name)
            seen["plan"] = c.plan
            seen["base"] = c.base_dir
            return {"o": _boxes(0)}

    registry.register(Look, replace=True)
    try:
        plan = CityPlan(name="Gir")
        net = Network(plan=plan, base_dir="/b", seed=4)
        net.add("l", "nu.look")
        net.run(workers=0, options={"crs": "utm"}, formats=["txt"])
        assert seen == {
            "seed": 4,
            "out": None,
            "formats": frozenset({"txt"}),
            "workers": 1,
            "options": {"crs": "utm"},
            "name": "Gir",
            "plan": plan,
            "base": __import__("pathlib").Path("/b"),
        }
        net.run(workers=3)
        assert seen["workers"] == 3 and seen["options"] == {} and seen["formats"] == frozenset()
        assert Network(plan=CityPlan(name="")).run().stats["counts"] == {}
        ctx = net._context(9)
        assert (ctx.seed, ctx.out, ctx.workers, ctx.name) == (9, None, 1, "Gir")
        assert Network(plan=CityPlan(name=""))._context(0).name == ""
        assert Network(plan=SimpleNamespace(maps={}))._context(0).name == ""  # a plan without a name
    finally:
        del registry.REGISTRY["nu.look"]


def test_run_refuses_unknown_formats_and_a_progress_it_cannot_use(tmp_path):
    with pytest.raises(ParameterError) as e:
        _chain().run(formats=["pdf"], out=tmp_path / "o")
    assert str(e.value).startswith("--format: unknown format 'pdf'")
    assert not (tmp_path / "o").exists() and os.listdir(tmp_path) == []
    with pytest.raises(TypeError):
        _chain().run(progress=42)


def test_a_failed_run_leaves_no_output_and_closes_events(tmp_path):
    net = _chain()
    net.add("f", "nu.fails")
    events = Events()
    out = tmp_path / "o"
    with pytest.raises(NodeError) as e:
        net.run(out=out, progress=events)
    assert str(e.value) == (
        "node 'f' (nu.fails): failed: ValueError: broken plugin (a bug in the plugin; --debug shows the traceback)"
    )
    assert os.listdir(tmp_path) == [] and events.seen[-1] == ("close",)
    out.mkdir()
    (out / "old.txt").write_text("x")
    with pytest.raises(NodeError):
        net.run(out=out)
    assert os.listdir(tmp_path) == ["o"] and os.listdir(out) == ["old.txt"]


def test_check_kinds_under_debug():
    class Kinded(SENode):
        name = "nu.kinded"
        outputs = {"polys": Port("nupolys"), "k": Port("nukind")}

        def run(self):
            return {"polys": _boxes(1), "k": _boxes(1)}

    registry.register(Kinded, replace=True)
    registry.declare_kind("nukind", {"needed": ("i", True, "")})
    try:
        net = Network()
        net.add("s", "nu.kinded", where="t.xml:2")
        with pytest.raises(NetworkError) as e:
            net.run(check_kinds=True)
        assert str(e.value) == (
            "t.xml:2: node 's' (nu.kinded) output 'k': layer of kind 'nukind': column 'needed' is missing"
        )
        assert net.run().stats["counts"] == {"s": 1}
    finally:
        del registry.KINDS["nukind"], registry.REGISTRY["nu.kinded"]


def test_call_run_wraps_plugin_errors_only():
    with pytest.raises(NodeError) as e:
        _call_run(Fails("f", {"how": "memory"}), {})
    assert str(e.value) == "node 'f' (nu.fails): ran out of memory (try smaller inputs or fewer --workers)"
    with pytest.raises(ParameterError) as e:
        _call_run(Fails("f", {"how": "param"}), {})
    assert str(e.value) == "here: bad thing"
    with pytest.raises(NodeError) as e:
        _call_run(Fails("f", where="w"), {})
    assert isinstance(e.value.__cause__, ValueError) and e.value.where == "w"
    with pytest.raises(ValueError, match="^a bug$"):
        _call_run(NotMine("b"), {})


def test_call_run_clears_an_old_report():
    class Old(SENode):
        name = "nu.old"
        outputs = {"o": Port("polygons")}

        def run(self):
            if self.context.seed:
                self.report = {"n": 1}
            return {"o": _boxes(1)}

    node = Old("o", context=Context(seed=1))
    assert _call_run(node, {}).report == {"n": 1}
    node.context = Context(seed=0)
    assert _call_run(node, {}).report is None
    assert _call_run(Src("s"), {}).report == {"made": 2}


def test_run_node_in_chunks_gives_the_single_process_result():
    polys = _boxes(10 * MIN_CHUNK + 10)  # 2570 features
    polys = Layer.from_geoms(polys.geometry, ids=polys.ids + 1000)  # ids not 0..n-1: kept, not renumbered
    node = Grow("g", {"d": 0.25}, Context(options={"slow": True}))
    whole = _run_node(node, {"polys": polys}, 1)
    assert whole.report == {"features": len(polys), "max_len": len(polys)}
    # workers: a first chunk of MIN_CHUNK runs here and takes 0.3 s, so the rest goes to the workers
    assert 0.3 * (len(polys) - MIN_CHUNK) / MIN_CHUNK > FORK_AFTER
    parts = _run_node(node, {"polys": polys}, 2)
    # min(2 workers * 4, 2314 // 256) = 8 chunks of the 2314 after the first: 289 or 290
    assert parts.report == {"features": len(polys), "max_len": 290}
    assert list(parts.layers["out"].ids) == list(range(1000, 1000 + len(polys)))
    for a, b in ((whole.layers["out"], parts.layers["out"]),):
        assert np.array_equal(a.ids, b.ids) and np.array_equal(a.parent, b.parent)
        assert shapely.equals_exact(a.geometry, b.geometry, 0).all()
    # quick work: the rest runs here in one call
    quick = Grow("g", {"d": 0.25})
    res = _run_node(quick, {"polys": polys}, 2)
    assert res.report == {"features": len(polys), "max_len": len(polys) - MIN_CHUNK}
    assert np.array_equal(res.layers["out"].ids, whole.layers["out"].ids)
    # 300 after the first chunk: one chunk of them
    res = _run_node(node, {"polys": polys.take(np.arange(MIN_CHUNK + 300))}, 2)
    assert res.report == {"features": MIN_CHUNK + 300, "max_len": 300}


def test_run_node_renumbers_chunks_that_number_their_own_features():
    polys = _boxes(2 * MIN_CHUNK + 3)
    node = Renumber("r", {"d": 0.25})
    whole = _run_node(node, {"polys": polys}, 1).layers["out"]
    parts = _run_node(node, {"polys": polys}, 2).layers["out"]
    assert list(whole.ids) == list(range(len(polys))) and list(parts.ids) == list(range(len(polys)))
    assert np.array_equal(parts.parent, polys.ids)
    assert _run_node(node, {"polys": polys}, 2).report is None  # no chunk reported anything


def test_run_node_runs_small_or_unmapped_inputs_whole():
    small = _boxes(2 * MIN_CHUNK - 1)
    assert _run_node(Grow("g"), {"polys": small}, 4).report["max_len"] == len(small)
    big = _boxes(2 * MIN_CHUNK)
    assert _run_node(Grow("g"), {"polys": big}, 4).report["max_len"] == MIN_CHUNK
    assert _run_node(Grow("g"), {"polys": big}, 1).report["max_len"] == len(big)
    pair = Pair("p")
    res = _run_node(pair, {"a": big, "b": None}, 4)
    assert len(res.layers["merged"]) == len(big)
    assert _run_node(Whole("w"), {"polys": big}, 4).report["max_len"] == len(big)  # does not map features
    assert _run_node(Src("s"), {}, 4).report == {"made": 2}  # no input at all


def test_run_with_workers_counts_progress_of_every_chunk():
    net = Network()
    net.add("s", "nu.src", {"n": 2 * MIN_CHUNK + 10})
    net.add("g", "nu.grow")
    net.connect("s", "g")
    events = Events()
    res = net.run(workers=2, progress=events)
    adv = [e for e in events.seen if e[0] == "advance"]
    assert adv[0] == ("advance", 0, 2 * MIN_CHUNK + 10, "polys")
    assert adv[-1] == ("advance", 2 * MIN_CHUNK + 10, 2 * MIN_CHUNK + 10, "polys")
    assert res.stats["report"]["g"]["features"] == 2 * MIN_CHUNK + 10
    # the chunks of the workers count too
    events = Events()
    n = 10 * MIN_CHUNK + 10
    net.specs["s"].params["n"] = n
    res = net.run(workers=2, progress=events, options={"slow": True})
    adv = [e for e in events.seen if e[0] == "advance"]
    assert adv[0] == ("advance", 0, n, "polys") and adv[-1] == ("advance", n, n, "polys")
    assert all(0 <= e[1] <= n for e in adv) and res.stats["report"]["g"]["max_len"] == 290
    assert len(events.seconds) == 2 and all(isinstance(t, float) and t >= 0 for t in events.seconds)


def test_early_jobs_start_when_their_inputs_are_made():
    def report(workers=None, take=True, connect=("s",), chain=False):
        net = Network()
        net.add("s", "nu.src", {"n": 3, "size": 2.0})
        if chain:
            net.add("g", "nu.grow")
            net.connect("s", "g")
        net.add("e", "nu.early", {"take": take})
        for src in connect:
            net.connect(src, "e.polys")
        if chain:
            net.connect("g", "e.other")
        Early.SEEN.clear()
        res = net.run(workers=workers) if workers is not None else net.run()
        return res.stats["report"]["e"]

    assert report(2) == {"started": True, "value": 12.0}  # e runs right after s
    assert report(2, chain=True) == {"started": True, "value": 12.0}
    assert report(1) == {"started": False, "value": -1.0}  # one process: run does the work
    assert report() == {"started": False, "value": -1.0}  # one worker by default
    assert report(2, connect=()) == {"started": False, "value": -1.0}  # nothing reaches its early input
    # a job no node took is stopped when the run ends
    assert report(2, take=False) == {"started": True, "value": -1.0}
    assert [n.early_started() for n in Early.SEEN] == [False]
    assert multiprocessing.active_children() == []


# -- the output folder ---------------------------------------------------------------------------


def test_output_folder_checks(tmp_path):
    file = tmp_path / "file"
    file.write_text("x")
    with pytest.raises(OutputError) as e:
        check_output_folder(file)
    assert str(e.value) == f"output folder {str(file)!r} is an existing file"
    with pytest.raises(OutputError) as e:
        check_output_folder(file / "sub")
    assert str(e.value).startswith(f"cannot write the output folder {str(file / 'sub')!r}: ")
    with pytest.raises(OutputError) as e:
        check_output_folder(tmp_path / ("n" * 300))
    assert str(e.value) == f"cannot write the output folder {str(tmp_path / ('n' * 300))!r}: File name too long"
    check_output_folder(tmp_path / "new" / "deeper" / "deepest")
    assert sorted(os.listdir(tmp_path)) == ["file", "new"] and os.listdir(tmp_path / "new") == ["deeper"]
    assert os.listdir(tmp_path / "new" / "deeper") == []
    tmp = _output_folder(tmp_path / "o")
    assert tmp.parent == tmp_path and tmp.name.startswith(".o.") and tmp.name.endswith(".tmp") and tmp.is_dir()


def test_output_folder_that_cannot_be_written(tmp_path):
    """A folder the run may not write: refused before any work, the temporary folder beside it removed."""
    parent = tmp_path / "p"
    ro = parent / "ro"
    ro.mkdir(parents=True)
    if os.geteuid() != 0:
        ro.chmod(0o500)
    else:  # root writes anywhere but into an immutable folder
        done = subprocess.run(["chattr", "+i", str(ro)], capture_output=True) if shutil.which("chattr") else None
        if done is None or done.returncode != 0:
            pytest.skip("running as root without chattr +i: every folder is writable")
    try:
        assert not os.access(ro, os.W_OK)
        with pytest.raises(OutputError) as e:
            _output_folder(ro)
        assert str(e.value) == f"cannot write the output folder {str(ro)!r}: Permission denied"
        assert os.listdir(parent) == ["ro"]
    finally:
        if os.geteuid() == 0:
            subprocess.run(["chattr", "-i", str(ro)], check=True)
        else:
            ro.chmod(0o700)


def test_move_into_puts_stats_last_and_replaces_folders(tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    for name in ("z.txt", "stats.json", "a.txt"):
        (src / name).write_text(name)
    (src / "tiles").mkdir()
    (src / "tiles" / "new").write_text("n")
    out = tmp_path / "out"
    (out / "tiles").mkdir(parents=True)
    (out / "tiles" / "old").write_text("o")
    (out / "keep.txt").write_text("k")
    _move_into(src, out)
    assert sorted(os.listdir(out)) == ["a.txt", "keep.txt", "stats.json", "tiles", "z.txt"]
    assert os.listdir(out / "tiles") == ["new"] and os.listdir(src) == []
    # stats.json last: a move that fails leaves no stats.json behind
    (src / "z.d").mkdir()
    (src / "stats.json").write_text("{}")
    (out / "z.d").write_text("a file where the new run has a folder")
    (out / "stats.json").unlink()
    with pytest.raises(OSError):
        _move_into(src, out)
    assert not (out / "stats.json").exists()
    fresh = tmp_path / "x" / "y"
    src = tmp_path / "src2"
    src.mkdir()
    src.joinpath("f").write_text("f")
    _move_into(src, fresh)
    assert os.listdir(fresh) == ["f"]
    _write_json(tmp_path / "s.json", {"b": 1, "a": [1, 2]})
    assert (tmp_path / "s.json").read_text() == '{\n  "b": 1,\n  "a": [\n    1,\n    2\n  ]\n}\n'


# -- inspection ------------------------------------------------------------------------------


def test_graph_of_a_valid_and_an_invalid_network():
    net = _chain()
    net.add("k", "nu.sink")
    net.connect("g", "k")
    g = net.graph()
    assert dict(g.nodes(data="type")) == {"s": "nu.src", "g": "nu.grow", "k": "nu.sink"}
    assert sorted(g.edges(data=True)) == [
        ("g", "k", {"src_port": "out", "dst_port": "polys"}),
        ("s", "g", {"src_port": "polys", "dst_port": "polys"}),
    ]
    net.connect("s.polys", "x.y")
    g = net.graph()
    assert sorted((a, b, d["src_port"], d["dst_port"]) for a, b, d in g.edges(data=True)) == [
        ("g", "k", "", ""),
        ("s", "g", "", ""),
        ("s", "x", "polys", "y"),
    ]


def test_registry_errors_name_the_node_line():
    net = Network()
    net.add("a", "nu.srcc", where="f.xml:3")
    with pytest.raises(RegistryError) as e:
        net.validate()
    assert str(e.value).startswith("f.xml:3: node 'a' (nu.srcc): unknown node type 'nu.srcc'; did you mean 'nu.src'")

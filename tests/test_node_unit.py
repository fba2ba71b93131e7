"""sengine.node, declaration by declaration, with the exact messages a user reads.

test_engine runs nodes through networks; these pin Port, Param (coercion, bounds, choices,
counts), Params, NodeResult.of and SENode's checks on small node classes, for the mutation
run of docs/mutation.md.
"""

from __future__ import annotations

import pickle
import re

import numpy as np
import pytest
import shapely

from sengine.errors import NodeError, ParameterError
from sengine.layer import Layer
from sengine.node import ANY, Context, NodeResult, Param, Params, Port, SENode, unknown_name
from sengine.random import generator


def _msg(exc) -> str:
    return str(exc.value)


def test_port_accepts():
    assert Port("roads").accepts("roads")
    assert not Port("roads").accepts("blocks")
    assert Port(ANY).accepts("blocks") and Port("blocks").accepts("any")
    assert ANY == "any"
    p = Port("lots")
    assert p.doc == "" and p.required is True


def test_param_defaults_and_unknown_type():
    p = Param("float")
    assert (p.default, p.min, p.max, p.choices, p.unit, p.doc, p.count) == (None, None, None, None, "", "", 1)
    with pytest.raises(TypeError) as e:
        Param("double")
    assert (
        _msg(e) == "unknown parameter type 'double'; expected one of ['bool', 'colour', 'float', 'int', 'path', 'str']"
    )


def test_coerce_numbers_from_strings_and_values():
    f = Param("float", min=0.0, max=10.0, unit="m")
    assert f.coerce(" 2.5 ", "w", "x") == 2.5 and isinstance(f.coerce("2", "w", "x"), float)
    assert f.coerce(3, "w", "x") == 3.0 and isinstance(f.coerce(3, "w", "x"), float)
    assert f.coerce(0, "w", "x") == 0.0 and f.coerce("10", "w", "x") == 10.0  # inclusive bounds
    i = Param("int", min=1, max=5)
    assert i.coerce(" 4 ", "w", "n") == 4 and isinstance(i.coerce("4", "w", "n"), int)
    assert i.coerce(2.0, "w", "n") == 2 and isinstance(i.coerce(2.0, "w", "n"), int)
    assert i.coerce(1, "w", "n") == 1 and i.coerce(5, "w", "n") == 5
    with pytest.raises(ParameterError) as e:
        i.coerce("4.5", "node 'a' (t)", "n")
    assert _msg(e) == "node 'a' (t): n='4.5' is not a valid int"
    assert e.value.where == "node 'a' (t)"
    with pytest.raises(ParameterError) as e:
        f.coerce("wide", "w", "x")
    assert _msg(e) == "w: x='wide' is not a valid float"
    with pytest.raises(ParameterError) as e:
        f.coerce(None, "w", "x")
    assert _msg(e) == "w: x=None is not a valid float"


def test_coerce_bounds_messages_with_and_without_units():
    f = Param("float", min=0.5, max=10.0, unit="m")
    with pytest.raises(ParameterError) as e:
        f.coerce("0.25", "w", "depth")
    assert _msg(e) == "w: depth=0.25 m is below the minimum 0.5 m"
    with pytest.raises(ParameterError) as e:
        f.coerce(12, "w", "depth")
    assert _msg(e) == "w: depth=12.0 m is above the maximum 10.0 m"
    ratio = Param("float", min=0, max=1, unit="1")
    with pytest.raises(ParameterError) as e:
        ratio.coerce(2, "w", "share")
    assert _msg(e) == "w: share=2.0 is above the maximum 1"
    bare = Param("int", min=-3)
    with pytest.raises(ParameterError) as e:
        bare.coerce(-4, "w", "k")
    assert _msg(e) == "w: k=-4 is below the minimum -3"
    assert bare.coerce(10**9, "w", "k") == 10**9  # no maximum
    assert Param("float", max=1.0).coerce(-1e300, "w", "k") == -1e300  # no minimum
    for bad in ("nan", "inf", float("-inf")):
        with pytest.raises(ParameterError, match=r"^w: k=(nan|inf|-inf) is not a finite number$"):
            Param("float").coerce(bad, "w", "k")
    for bad in (float("inf"), float("nan"), "inf"):  # int(inf) overflows, int(nan) and int("inf") are no number
        with pytest.raises(ParameterError, match=r"^w: k=(inf|nan|'inf') is not a valid int$"):
            Param("int").coerce(bad, "w", "k")


def test_coerce_bool():
    b = Param("bool")
    for text, want in (("true", True), (" Yes ", True), ("1", True), ("FALSE", False), ("no", False), ("0", False)):
        assert b.coerce(text, "w", "flag") is want
    assert b.coerce(1, "w", "flag") is True and b.coerce(0, "w", "flag") is False
    with pytest.raises(ParameterError) as e:
        b.coerce("maybe", "w", "flag")
    assert _msg(e) == "w: flag='maybe' is not a valid bool"


def test_coerce_str_path_and_choices():
    s = Param("str", choices=("grid", "skeleton", "paris"))
    assert s.coerce("paris", "w", "method") == "paris"
    with pytest.raises(ParameterError) as e:
        s.coerce("skeletn", "w", "method")
    assert _msg(e) == "w: method='skeletn' is not one of grid, skeleton, paris; did you mean 'skeleton'?"
    with pytest.raises(ParameterError) as e:
        s.coerce("zzz", "w", "method")
    assert _msg(e) == "w: method='zzz' is not one of grid, skeleton, paris"
    assert Param("path").coerce("maps/a.png", "w", "file") == "maps/a.png"
    assert Param("str").coerce(12, "w", "name") == "12"


def test_coerce_colour():
    c = Param("colour")
    assert c.coerce("#d33", "w", "fill") == "#d33"
    assert c.coerce("208 48 48", "w", "fill") == "208 48 48"
    with pytest.raises(ParameterError) as e:
        c.coerce("red", "node 'x' (t)", "fill")
    assert _msg(e) == "node 'x' (t): fill: colour 'red' is not '#rrggbb', '#rgb' or 'r g b' (0-255)"
    assert e.value.where == "node 'x' (t)"
    with pytest.raises(ParameterError) as e:  # parse_colour's message, not a bare "not a valid colour"
        c.coerce("300 0 0", "w", "fill")
    assert _msg(e) == "w: fill: colour '300 0 0' is not '#rrggbb', '#rgb' or 'r g b' (0-255)"


def test_coerce_counts():
    size = Param("float", count=2, min=0.0, unit="m")
    assert size.coerce("800 260", "w", "size") == (800.0, 260.0)
    assert size.coerce(" 800,260 ", "w", "size") == (800.0, 260.0)
    assert size.coerce("800 ,  260", "w", "size") == (800.0, 260.0)
    assert size.coerce([1, "2"], "w", "size") == (1.0, 2.0)
    assert size.coerce(",800 260,", "w", "size") == (800.0, 260.0)  # the empty pieces round a leading comma
    assert size.coerce(["1", "", "2"], "w", "size") == (1.0, 2.0)
    with pytest.raises(ParameterError) as e:
        size.coerce("800", "w", "size")
    assert _msg(e) == "w: size='800' must be 2 numbers"
    with pytest.raises(ParameterError) as e:
        size.coerce((1, 2, 3), "w", "size")
    assert _msg(e) == "w: size=(1, 2, 3) must be 2 numbers"
    with pytest.raises(ParameterError) as e:
        size.coerce("5 -1", "w", "size")
    assert _msg(e) == "w: size=-1.0 m is below the minimum 0.0 m"
    ints = Param("int", count=3)
    assert ints.coerce("1 2 3", "w", "rgb") == (1, 2, 3)
    # count applies to numbers only: a string parameter keeps its text
    assert Param("str", count=2).coerce("a b", "w", "s") == "a b"


def test_param_describe():
    p = Param("float", 2.0, 0.0, 9.0, None, "m", "spacing of things")
    assert p.describe("spacing") == {
        "name": "spacing",
        "type": "float",
        "default": 2.0,
        "min": 0.0,
        "max": 9.0,
        "choices": None,
        "unit": "m",
        "doc": "spacing of things",
    }
    q = Param("str", "a", choices=("a", "b"))
    assert q.describe("m")["choices"] == ["a", "b"]
    assert Param("str", "a", choices=()).describe("m")["choices"] is None
    assert Param("int", count=2).describe("n")["count"] == 2
    assert "count" not in Param("int").describe("n")


def test_unknown_name():
    assert unknown_name("parameter", "lot-aera", ["lot-area", "depth"]) == (
        "unknown parameter 'lot-aera'; did you mean 'lot-area'? (parameters: lot-area, depth)"
    )
    assert unknown_name("port", "zz", ["roads"]) == "unknown port 'zz' (ports: roads)"
    assert unknown_name("port", "zz", []) == "unknown port 'zz' (ports: none)"
    # cutoff 0.6: 'abcd' vs 'abxy' is 0.5, no hint; 'abcd' vs 'abcx' is 0.75
    assert "did you mean" not in unknown_name("x", "abcd", ["abxy"])
    assert "did you mean 'abcx'" in unknown_name("x", "abcd", ["abxy", "abcx"])


def test_params_mapping():
    p = Params({"spacing": 2.0, "mode": "a"})
    assert p["spacing"] == 2.0 and p.spacing == 2.0 and p.mode == "a"
    assert list(p) == ["spacing", "mode"] and len(p) == 2 and dict(p) == {"spacing": 2.0, "mode": "a"}
    assert repr(p) == "Params({'spacing': 2.0, 'mode': 'a'})"
    with pytest.raises(AttributeError, match="^nothing$"):
        _ = p.nothing
    with pytest.raises(AttributeError, match="^_values_x$"):
        _ = p._values_x
    with pytest.raises(KeyError):
        p["nothing"]
    hidden = Params({"_x": 1})  # names starting with _ are never looked up as parameters
    assert hidden["_x"] == 1
    with pytest.raises(AttributeError, match="^_x$"):
        _ = hidden._x
    q = pickle.loads(pickle.dumps(p))
    assert dict(q) == dict(p) and isinstance(q, Params)
    assert not hasattr(p, "__deepcopy_x__")
    with pytest.raises(TypeError):
        p._values["spacing"] = 3.0  # read-only


def _layer(n):
    return Layer.from_geoms(np.array([shapely.Point(i, 0) for i in range(n)], dtype=object))


class Two(SENode):
    """A test node with two outputs.

    Second paragraph, not in the description.
    """

    name = "test.two"
    inputs = {"src": Port("points", "where from"), "opt": Port("any", required=False)}
    outputs = {"a": Port("points", "first"), "b": Port("points")}
    params = {
        "k": Param("int", 3, min=1, max=9, unit="1", doc="how many"),
        "need": Param("str", None, doc="required"),
        "mode": Param("str", "x", choices=("x", "y")),
    }

    def run(self, *, src, opt=None):
        return {"a": src, "b": src}


class Sink(SENode):
    name = "test.sink"
    inputs = {"src": Port("points")}

    def run(self, *, src):
        return None


def test_senode_init_and_params():
    n = Two("t1", {"need": "v", "k": "4"})
    assert n.id == "t1" and n.where == "node 't1' (test.two)"
    assert dict(n.p) == {"k": 4, "need": "v", "mode": "x"}
    assert isinstance(n.context, Context) and n.context.seed == 0
    assert Two("t1", {"need": "v"}, where="file.xml:3").where == "file.xml:3"
    ctx = Context(seed=7)
    assert Two("t1", {"need": "v"}, ctx).context is ctx
    with pytest.raises(ParameterError) as e:
        Two("t1", {})
    assert _msg(e) == "node 't1' (test.two): parameter 'need' is required"
    with pytest.raises(ParameterError) as e:
        Two("t1", {"need": "v", "kk": 1, "zzz": 2})
    assert _msg(e) == "node 't1' (test.two): unknown parameter 'kk'; did you mean 'k'? (parameters: k, need, mode)"
    with pytest.raises(ParameterError) as e:
        Two("t1", {"need": "v", "k": 10})
    assert _msg(e) == "node 't1' (test.two): k=10 is above the maximum 9"
    assert dict(Sink("s").p) == {} and Sink("s", None).where == "node 's' (test.sink)"


def test_context_defaults():
    c = Context()
    assert (c.seed, c.plan, c.base_dir, c.out, c.formats, c.workers, c.options, c.name) == (
        0,
        None,
        None,
        None,
        frozenset(),
        1,
        {},
        "",
    )
    assert Context().options is not c.options


def test_check_declaration():
    Two.check_declaration()

    class Wrong(SENode):
        name = "test.wrong"
        inputs = {"src": Port("points")}

        def run(self, *, source):
            return {}

    with pytest.raises(TypeError) as e:
        Wrong.check_declaration()
    assert _msg(e) == "Wrong.run keyword-only arguments ['source'] differ from its input ports ['src']"

    class Positional(SENode):
        inputs = {"src": Port("points")}

        def run(self, src):
            return {}

    with pytest.raises(TypeError, match=r"keyword-only arguments \[\] differ"):
        Positional.check_declaration()

    class BadDefault(SENode):
        name = "test.bad"
        params = {"k": Param("int", 0, min=1)}

        def run(self):
            return {}

    with pytest.raises(ParameterError) as e:
        BadDefault.check_declaration()
    assert _msg(e) == "BadDefault: k=0 is below the minimum 1"


def test_rng_plan_source_counted_check_and_refusal():
    n = Two("t1", {"need": "v"}, Context(seed=11))
    a = n.rng(5).random(4)
    assert np.array_equal(a, generator(11, "t1", 5).random(4))
    assert not np.array_equal(a, n.rng(6).random(4))
    assert np.array_equal(n.rng().random(2), generator(11, "t1").random(2))
    assert Two.plan_source("raster", object()) is None
    assert n.counted({"a": _layer(3), "b": _layer(5)}) == 3
    assert n.counted({}) == 0
    assert n.check(src=None, opt=None) is None
    assert n.shard_refusal(frozenset({"src"})) is None
    assert n.join_shard(None, shard=0) is None
    for call in (
        lambda: n.shard_inputs({}, np.zeros(0, int)),
        lambda: n.write_shard({}, shard=0, city_ports=frozenset()),
        lambda: n.finish_shards({}, [], city_ports=frozenset()),
    ):
        with pytest.raises(NotImplementedError):
            call()
    assert (SENode.shard_port, SENode.shard_formats, SENode.shard_streams) == (None, (), ())
    assert (SENode.maps_features, SENode.source_for, SENode.name) == (False, None, "")


def test_describe():
    d = Two.describe()
    assert d == {
        "name": "test.two",
        "doc": "A test node with two outputs.",
        "inputs": [
            {"name": "src", "kind": "points", "required": True, "doc": "where from"},
            {"name": "opt", "kind": "any", "required": False, "doc": ""},
        ],
        "outputs": [{"name": "a", "kind": "points", "doc": "first"}, {"name": "b", "kind": "points", "doc": ""}],
        "params": [
            Two.params["k"].describe("k"),
            Two.params["need"].describe("need"),
            Two.params["mode"].describe("mode"),
        ],
        "maps_features": False,
    }

    class Doc(SENode):
        """Two lines
        of summary.

        More.
        """

    assert Doc.describe()["doc"] == "Two lines of summary."
    assert Sink.describe()["doc"] == "Abstract base of every node."  # inherited docstring


# ---------------------------------------------------------------------------------------------
# NodeResult.of


def test_node_result_forms():
    n = Two("t1", {"need": "v"})
    la, lb = _layer(2), _layer(3)
    r = NodeResult.of(n, {"b": lb, "a": la})
    assert list(r) == ["a", "b"] and r["a"] is la and len(r) == 2 and r.report is None
    r = NodeResult.of(n, ({"a": la, "b": lb}, {"made": 5}))
    assert r.report == {"made": 5} and isinstance(r.report, dict)
    r = NodeResult.of(n, NodeResult({"a": la, "b": lb}, {"x": 1}))
    assert r.report == {"x": 1} and list(r.layers) == ["a", "b"]
    r = NodeResult.of(n, ({"a": la, "b": lb}, {}))
    assert r.report is None  # an empty report is none
    n.report = {"old": 2}  # the old way: a report set on the node
    assert NodeResult.of(n, {"a": la, "b": lb}).report == {"old": 2}
    assert NodeResult.of(n, ({"a": la, "b": lb}, {"new": 1})).report == {"new": 1}
    s = Sink("s")
    assert NodeResult.of(s, None).layers == {} and NodeResult.of(s, None).report is None
    assert NodeResult.of(s, (None, {"files": 2})).report == {"files": 2}
    assert NodeResult.of(s, {}).layers == {}


def test_node_result_wrong_shapes():
    n = Two("t1", {"need": "v"})
    la = _layer(2)
    with pytest.raises(NodeError) as e:
        NodeResult.of(n, None)
    assert _msg(e) == (
        "node 't1' (test.two): run() returned NoneType, expected a dict of output layers (a, b), "
        "a (dict, report) pair or a NodeResult"
    )
    with pytest.raises(NodeError) as e:
        NodeResult.of(n, [la, la])
    assert "run() returned list, expected" in _msg(e)
    with pytest.raises(NodeError) as e:
        NodeResult.of(Sink("s"), 5)
    assert _msg(e) == (
        "node 's' (test.sink): run() returned int, expected a dict of output layers (none), "
        "a (dict, report) pair or a NodeResult"
    )
    with pytest.raises(NodeError) as e:
        NodeResult.of(n, ({"a": la, "b": la}, [1]))
    assert _msg(e) == "node 't1' (test.two): run() returned a report of type list, expected a dict"
    with pytest.raises(NodeError) as e:
        NodeResult.of(n, {"a": la})
    assert _msg(e) == "node 't1' (test.two): run() returned ports ['a'], declared ['a', 'b'] (missing 'b')"
    with pytest.raises(NodeError) as e:
        NodeResult.of(n, {"a": la, "b": la, 3: la})
    assert _msg(e) == "node 't1' (test.two): run() returned ports ['3', 'a', 'b'], declared ['a', 'b'] (undeclared '3')"
    with pytest.raises(NodeError) as e:
        NodeResult.of(n, {"a": la, "b": [1], "c": la, "d": la})
    assert _msg(e) == (
        "node 't1' (test.two): run() returned ports ['a', 'b', 'c', 'd'], declared ['a', 'b'] "
        "(undeclared 'c', 'd'; 'b' is a list, not a Layer)"
    )
    with pytest.raises(NodeError) as e:
        NodeResult.of(n, {"b": 1})
    assert _msg(e) == (
        "node 't1' (test.two): run() returned ports ['b'], declared ['a', 'b'] (missing 'a'; 'b' is a int, not a Layer)"
    )
    with pytest.raises(NodeError) as e:
        NodeResult.of(n, {})
    assert _msg(e) == "node 't1' (test.two): run() returned ports [], declared ['a', 'b'] (missing 'a', 'b')"
    with pytest.raises(NodeError) as e:
        NodeResult.of(n, {"a": 1, "b": "x"})
    assert _msg(e) == (
        "node 't1' (test.two): run() returned ports ['a', 'b'], declared ['a', 'b'] "
        "('a' is a int, not a Layer, 'b' is a str, not a Layer)"
    )
    # a 3-tuple, or a pair whose first item is no mapping, is not a (layers, report) pair
    with pytest.raises(NodeError, match=re.escape("run() returned tuple")):
        NodeResult.of(n, ({"a": la, "b": la}, None, None))
    with pytest.raises(NodeError, match=re.escape("run() returned tuple")):
        NodeResult.of(n, (la, {"x": 1}))

"""sengine.xmlconfig in process: the plan it reads, the network it builds, every message and its line.

test_config_errors.py checks what the CLI prints for a mistake; these tests
read configurations with :func:`load_config` and :func:`read_network_file`
directly and check the objects and the exact ``file:line: message`` text.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from conftest import FIXTURES

from sengine.errors import ConfigError, NetworkError, ParameterError, Problems, SEngineError
from sengine.plan import CityPlan, MapSpec, Rule
from sengine.xmlconfig import (
    MAX_CITY_SIZE,
    _base_network,
    _floats,
    check_rule,
    load_config,
    parse,
    read_network_file,
    read_small_file,
)

PLUGIN = str(FIXTURES / "squares_plugin.py")


def write(folder: Path, name: str, text: str | bytes) -> Path:
    path = folder / name
    path.write_bytes(text.encode() if isinstance(text, str) else text)
    return path


def config(city: str = "", network: str = "", plugin: bool = True) -> str:
    head = f'<sengine version="1">\n  <plugin path="{PLUGIN}"/>\n' if plugin else '<sengine version="1">\n'
    return head + city + network + "</sengine>\n"


SQUARES = '  <network>\n    <node id="s" type="demo.squares"/>\n  </network>\n'


def error_of(fn, *args, **kw) -> SEngineError:
    with pytest.raises(SEngineError) as info:
        fn(*args, **kw)
    return info.value


# -- parse ------------------------------------------------------------------------------


def test_doctype_is_refused_at_its_first_line(tmp_path):
    text = '<?xml version="1.0"?>\n<!DOCTYPE sengine>\n<sengine version="1"/>\n<!DOCTYPE x>\n'
    err = error_of(parse, write(tmp_path, "d.xml", text), "d.xml")
    assert isinstance(err, ConfigError)
    assert str(err) == "d.xml:2: DOCTYPE declarations (DTDs and entities) are not allowed in sengine files"
    second = error_of(parse, write(tmp_path, "n.xml", '\n<!DOCTYPE sengine>\n<sengine version="1"/>\n'), "n.xml")
    assert str(second) == "n.xml:2: DOCTYPE declarations (DTDs and entities) are not allowed in sengine files"
    first = error_of(parse, write(tmp_path, "e.xml", '<!DOCTYPE sengine>\n<sengine version="1"/>\n'), "e.xml")
    assert str(first) == "e.xml:1: DOCTYPE declarations (DTDs and entities) are not allowed in sengine files"


def test_a_doctype_the_byte_scan_misses_is_refused_after_parsing(tmp_path):
    # UTF-16 hides the DOCTYPE from the byte scan; an external DTD has no internal subset
    text = '<?xml version="1.0" encoding="UTF-16"?>\n<!DOCTYPE sengine SYSTEM "nowhere.dtd">\n<sengine version="1"/>\n'
    err = error_of(parse, write(tmp_path, "u.xml", text.encode("utf-16")), "u.xml")
    assert str(err) == "u.xml:1: DOCTYPE declarations (DTDs and entities) are not allowed in sengine files"
    write(tmp_path, "bad.dtd", '<!ENTITY % x "garbage <<<')  # never read: no DTD is loaded
    ext = f'<?xml version="1.0" encoding="UTF-16"?>\n<!DOCTYPE sengine SYSTEM "{tmp_path / "bad.dtd"}">\n<sengine/>\n'
    err = error_of(parse, write(tmp_path, "w.xml", ext.encode("utf-16")), "w.xml")
    assert str(err) == "w.xml:1: DOCTYPE declarations (DTDs and entities) are not allowed in sengine files"
    internal = '<?xml version="1.0" encoding="UTF-16"?>\n<!DOCTYPE sengine [<!ELEMENT sengine ANY>]>\n<sengine/>\n'
    err = error_of(parse, write(tmp_path, "v.xml", internal.encode("utf-16")), "v.xml")
    assert str(err) == "v.xml:1: DOCTYPE declarations (DTDs and entities) are not allowed in sengine files"


def test_syntax_errors_name_the_line_without_lxml_position(tmp_path):
    err = error_of(parse, write(tmp_path, "t.xml", '<sengine version="1">\n  <city>\n</sengine>\n'), "t.xml")
    assert str(err) == "t.xml:3: not well-formed XML: Opening and ending tag mismatch: city line 2 and sengine"
    err = error_of(read_network_file, tmp_path / "t.xml", label="L")
    assert str(err).startswith("L:3: not well-formed XML: ")


def test_deep_nesting_is_refused_by_the_parser(tmp_path):
    deep = '<sengine version="1">' + "<x>" * 300 + "</x>" * 300 + "</sengine>"
    err = error_of(parse, write(tmp_path, "deep.xml", deep), "deep.xml")
    assert str(err).startswith("deep.xml:1: not well-formed XML")


def test_wrong_root_names_its_line(tmp_path):
    err = error_of(parse, write(tmp_path, "r.xml", '<?xml version="1.0"?>\n\n<city name="x"/>\n'), "r.xml")
    assert str(err) == 'r.xml:3: not a sengine file: the root element is <city>, expected <sengine version="1">'


def test_several_schema_problems_are_one_error_naming_the_file(tmp_path):
    text = '<sengine version="1">\n  <city size="a"/>\n  <network foo="1"/>\n</sengine>\n'
    err = error_of(parse, write(tmp_path, "s.xml", text), "s.xml")
    assert isinstance(err, Problems) and str(err) == "s.xml: 2 problems"
    assert str(err.problems[0]).startswith("s.xml:2: invalid: <city>, attribute 'size': ")
    assert str(err.problems[1]) == "s.xml:3: invalid: <network>, attribute 'foo': The attribute 'foo' is not allowed."


def test_comments_and_processing_instructions_are_dropped(tmp_path):
    text = config(
        '  <city name="c" size="100 100">\n    <!-- a note -->\n    <?pi data?>\n    <rule kind="x"/>\n  </city>\n',
        '  <network>\n    <!-- n -->\n    <?pi?>\n    <node id="s" type="demo.squares"/>\n  </network>\n',
    )
    net = load_config(write(tmp_path, "c.xml", text))
    assert [r.tag for r in net.plan.rules] == ["rule"] and list(net.specs) == ["s"]


# -- read_small_file ------------------------------------------------------------------------


def test_read_small_file_refusals(tmp_path):
    assert str(error_of(read_small_file, tmp_path / "none.xml", "L", 10, ConfigError)) == "L: file not found"
    assert str(error_of(read_small_file, tmp_path, "L", 10, ConfigError)) == "L: is a folder, not a file"
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    err = error_of(read_small_file, fifo, "L", 10, ConfigError)
    assert str(err) == "L: is not a regular file (a pipe, socket or device?)"
    big = write(tmp_path, "big.xml", b"x" * 1235)
    err = error_of(read_small_file, big, "L", 1234, ParameterError)
    assert isinstance(err, ParameterError)
    assert str(err) == "L: is 1,235 bytes, more than the 1,234 a configuration may have"
    under = write(tmp_path, "f", b"y" * 20)
    err = error_of(read_small_file, under / "child", "L", 10, ConfigError)  # a file used as a folder
    assert str(err) == "L: cannot read file: Not a directory"


def test_read_small_file_reads_up_to_the_limit(tmp_path):
    exact = write(tmp_path, "exact", b"0123456789")
    assert read_small_file(exact, "L", 10, ConfigError) == b"0123456789"
    assert read_small_file(exact, "L", 11, ConfigError) == b"0123456789"


# -- the plan ---------------------------------------------------------------------------------


def test_the_plan_holds_what_the_city_element_says(tmp_path):
    city = (
        '  <city name="Girona" seed="42" size="1500 800" origin="41.98 2.82">\n'
        '    <map kind="height" src="maps/h.png" min="0" max="30"/>\n'
        '    <district color="#ff0000" pattern="grid" spacing="80 80"/>\n'
        '    <landuse color="#00ff00" class="park"/>\n'
        "  </city>\n"
    )
    net = load_config(write(tmp_path, "g.xml", config(city, SQUARES)))
    plan = net.plan
    assert isinstance(plan, CityPlan) and plan.name == "Girona" and plan.where == f"{tmp_path / 'g.xml'}:3"
    assert plan.size == (1500.0, 800.0) and plan.origin == (41.98, 2.82) and plan.attrs == {}
    assert net.seed == 42 and net.source == str(tmp_path / "g.xml") and net.base_dir == tmp_path.resolve()
    h = plan.maps["height"]
    assert h == MapSpec(
        "height", (tmp_path / "maps" / "h.png").resolve(), {"min": "0", "max": "30"}, f"{plan.where[:-1]}4"
    )
    assert plan.rules == [
        Rule("district", {"color": "#ff0000", "pattern": "grid", "spacing": "80 80"}, f"{tmp_path / 'g.xml'}:5"),
        Rule("landuse", {"color": "#00ff00", "class": "park"}, f"{tmp_path / 'g.xml'}:6"),
    ]
    assert plan.rules_of("landuse") == plan.rules[1:] and plan.rules_of("rule") == []
    assert plan.rules[0].get("pattern") == "grid" and plan.rules[0].get("far") is None
    assert plan.rules[0].get("far", "2") == "2"
    assert plan.extent == (0.0, 0.0, 1500.0, 800.0)


def test_plan_defaults(tmp_path):
    net = load_config(write(tmp_path, "d.xml", config('  <city size="10 10"/>\n', SQUARES)))
    assert net.plan.name == "city" and net.plan.origin == (41.9794, 2.8214) and net.seed == 0
    bare = load_config(write(tmp_path, "b.xml", config("", SQUARES)))
    assert bare.plan.size == (2000.0, 2000.0) and bare.plan.where == "" and bare.plan.maps == {}


@pytest.mark.parametrize(
    ("size", "ok"),
    [("0.5 0.5", True), (f"{MAX_CITY_SIZE:g} 1", True), ("100000.5 10", False), ("0 10", False)],
)
def test_size_bounds(tmp_path, size, ok):
    path = write(tmp_path, "s.xml", config(f'  <city size="{size}"/>\n', SQUARES))
    if ok:
        assert load_config(path).plan.size == tuple(float(v) for v in size.split())
    else:
        err = error_of(load_config, path)
        assert str(err) == f"{path}:3: size={size!r} must be two positive widths of at most 100000 m"


@pytest.mark.parametrize("origin", ["-90 -180", "90 180", "0 0"])
def test_origin_bounds_inclusive(tmp_path, origin):
    net = load_config(write(tmp_path, "o.xml", config(f'  <city origin="{origin}"/>\n', SQUARES)))
    assert net.plan.origin == tuple(float(v) for v in origin.split())


@pytest.mark.parametrize("origin", ["-90.5 0", "90.5 0", "0 -180.5", "0 180.5"])
def test_origin_out_of_range(tmp_path, origin):
    path = write(tmp_path, "o.xml", config(f'  <city origin="{origin}"/>\n', SQUARES))
    assert str(error_of(load_config, path)) == f"{path}:3: origin={origin!r} is not a latitude and longitude in degrees"


def test_malformed_numbers_and_unknown_attributes_are_all_reported(tmp_path):
    path = write(tmp_path, "m.xml", config('  <city size="-1 5" origin="91 0" nmae="x"/>\n', SQUARES))
    err = error_of(load_config, path)
    assert isinstance(err, Problems) and str(err) == f"{path}: 3 problems"
    assert [str(p) for p in err.problems] == [
        f"{path}:3: size='-1 5' must be two positive widths of at most 100000 m",
        f"{path}:3: origin='91 0' is not a latitude and longitude in degrees",
        f"{path}:3: <city> unknown attribute 'nmae'; did you mean 'name'? (attributes: name, seed, size, origin)",
    ]


def test_floats_reads_n_numbers_or_names_the_attribute():
    assert _floats(" 1, 2.5 ", 2, "size", "w") == (1.0, 2.5)
    assert _floats("1 2 3", 3, "x", "w") == (1.0, 2.0, 3.0)
    assert str(error_of(_floats, "1 2 3", 2, "size", "f:4")) == "f:4: size='1 2 3' must be 2 numbers"
    assert str(error_of(_floats, "1 x", 2, "origin", "f:5")) == "f:5: origin='1 x' must be 2 numbers"


def test_map_twice_and_unknown_map_kind(tmp_path):
    city = '  <city>\n    <map kind="height" src="a.png"/>\n    <map kind="height" src="b.png"/>\n'
    city += '    <map kind="district" src="d.png"/>\n  </city>\n'
    path = write(tmp_path, "m.xml", config(city, SQUARES))
    with pytest.raises(ConfigError, match="given twice"):
        load_config(path)
    from sengine.xmlconfig import _read_plan

    problems: list = []
    plan, _ = _read_plan(parse(path, "m.xml").find("city"), "m.xml", tmp_path, problems)
    assert [str(p) for p in problems] == ["m.xml:5: a map of kind 'height' is given twice (first at m.xml:4)"]
    assert sorted(plan.maps) == ["district", "height"] and plan.maps["height"].src == (tmp_path / "a.png").resolve()
    path = write(tmp_path, "k.xml", config('  <city>\n    <map kind="heigth" src="a.png"/>\n  </city>\n', SQUARES))
    err = error_of(load_config, path)
    assert str(err).startswith(f"{path}:4: unknown map kind 'heigth'; did you mean 'height'? (map kinds: district, ")


def test_rule_attributes_are_checked_against_their_declarations(tmp_path):
    city = '  <city>\n    <district colour="#ff0000"/>\n    <landuse color="#00ff00" far="-3"/>\n  </city>\n'
    path = write(tmp_path, "r.xml", config(city, SQUARES))
    err = error_of(load_config, path)
    assert isinstance(err, Problems) and len(err.problems) == 2
    assert str(err.problems[0]).startswith(f"{path}:4: <district> unknown attribute 'colour'; did you mean 'color'?")
    assert str(err.problems[1]).startswith(f"{path}:5: ") and "far" in str(err.problems[1])
    assert check_rule("rule", {"anything": "1"}, "w") == []
    assert check_rule("district", {"color": "#ff0000", "spacing": "80 80"}, "w") == []
    two = check_rule("district", {"colr": "#fff", "spacng": "1 1"}, "w")
    assert [p.message.split(";")[0] for p in two] == [
        "<district> unknown attribute 'colr'",
        "<district> unknown attribute 'spacng'",
    ]
    probs = check_rule("district", {"spacing": "abc", "colr": "#fff"}, "here:9")
    assert len(probs) == 2 and all(str(p).startswith("here:9: ") for p in probs)
    assert "<district> spacing" in str(probs[0]) and "<district> unknown attribute 'colr'" in str(probs[1])


# -- the network --------------------------------------------------------------------------------


def test_nodes_params_and_connections(tmp_path):
    network = (
        "  <network>\n"
        '    <node id="s" type="demo.squares">\n      <param name="count" value="3"/>\n    </node>\n'
        '    <node id="i" type="demo.inset"/>\n'
        '    <param node="s" name="size" value="4.5"/>\n'
        '    <connect from="s" to="i"/>\n'
        "  </network>\n"
    )
    path = write(tmp_path, "n.xml", config("", network))
    net = load_config(path)
    assert net.specs["s"].params == {"count": "3", "size": "4.5"}
    assert net.specs["s"].param_where == {"count": f"{path}:5", "size": f"{path}:8"}
    assert net.specs["s"].where == f"{path}:4" and net.specs["i"].type == "demo.inset"
    assert [(c.src, c.dst) for c in net.connections] == [("s", "i")]


def test_node_twice_and_node_without_type(tmp_path):
    twice = '  <network>\n    <node id="s" type="demo.squares"/>\n    <node id="s" type="demo.inset"/>\n  </network>\n'
    path = write(tmp_path, "t.xml", config("", twice))
    assert str(error_of(load_config, path)) == f"{path}:5: node id 's' is defined twice (first at {path}:4)"
    untyped = '  <network>\n    <node id="q"/>\n  </network>\n'
    path = write(tmp_path, "u.xml", config("", untyped))
    assert str(error_of(load_config, path)) == f"{path}:4: node 'q' has no type and is not in the base network"


def test_base_network_associations_and_replacements(tmp_path):
    network = (
        '  <network base="pattern">\n'
        '    <node id="lots" type="null"/>\n'
        '    <node id="blocks">\n      <param name="node" value="true"/>\n    </node>\n'
        '    <disconnect from="lots" to="lotParks"/>\n'
        "  </network>\n"
    )
    path = write(tmp_path, "p.xml", config("", network, plugin=False))
    whole = load_config(write(tmp_path, "q.xml", config('  <city name="pp" seed="7"/>\n', network, plugin=False)))
    assert whole.specs["lots"].type == "null" and whole.plan.name == "pp" and whole.seed == 7
    assert whole.source == str(tmp_path / "q.xml") and whole.base_dir == tmp_path.resolve()
    from sengine.xmlconfig import _apply_network, _base_network
    from sengine.xmlconfig import parse as parse_

    el = parse_(path, "p.xml").find("network")
    net = _base_network(el, "p.xml", tmp_path, 0)
    _apply_network(net, el, "p.xml")
    assert net.specs["lots"].type == "null" and net.specs["lots"].where == "p.xml:3"
    assert net.specs["blocks"].type == "blocks.circuits" and net.specs["blocks"].params["node"] == "true"
    assert not any(c.src == "lots" and c.dst == "lotParks" for c in net.connections)
    std = '  <network base="std">\n    <node id="majorRoads" type="null"/>\n    <node id="minorRoads" type="null"/>\n'
    std += '    <connect from="majorRoads" to="minorRoads"/>\n  </network>\n'
    el = parse_(write(tmp_path, "std.xml", config("", std, plugin=False)), "std.xml").find("network")
    net = _base_network(el, "std.xml", tmp_path, 0)
    assert list(net.specs) == ["majorRoads", "minorRoads"] and net.specs["majorRoads"].where == "std.xml:2"
    assert net.specs["majorRoads"].type == "null" and net.specs["minorRoads"].type == "null"
    _apply_network(net, el, "std.xml")
    assert net.specs["majorRoads"].where == "std.xml:3" and net.specs["minorRoads"].where == "std.xml:4"


@pytest.mark.parametrize(
    ("attrs", "message"),
    [
        ('file=""', "<network> file= is empty"),
        ('base="std" file="x.xml"', "<network> takes base= or file=, not both"),
    ],
)
def test_network_reference_errors(tmp_path, attrs, message):
    path = write(tmp_path, "b.xml", config("", f"  <network {attrs}/>\n"))
    assert str(error_of(load_config, path)) == f"{path}:3: {message}"


def chain(folder: Path, n: int) -> Path:
    """f0.xml includes f1.xml ... f{n}.xml, which holds one node."""
    for i in range(n):
        write(folder, f"f{i}.xml", f'<sengine version="1">\n  <network file="f{i + 1}.xml"/>\n</sengine>\n')
    write(
        folder,
        f"f{n}.xml",
        '<sengine version="1">\n  <network>\n    <node id="z" type="null"/>\n  </network>\n</sengine>\n',
    )
    return folder / "f0.xml"


def test_network_files_include_each_other_up_to_eight_deep(tmp_path):
    net = read_network_file(chain(tmp_path, 8))
    assert list(net.specs) == ["z"] and net.specs["z"].where == "f8.xml:3"
    deeper = tmp_path / "deeper"
    deeper.mkdir()
    err = error_of(read_network_file, chain(deeper, 9))
    assert str(err) == "f9.xml:2: network files include each other too deeply (a loop?)"


def test_a_config_includes_network_files_eight_deep(tmp_path):
    chain(tmp_path, 8)
    path = write(tmp_path, "c.xml", config("", '  <network file="f1.xml"/>\n'))
    assert list(load_config(path).specs) == ["z"]


def test_network_problems_are_reported_with_the_others(tmp_path):
    path = write(tmp_path, "x.xml", config("", '  <network>\n    <node id="i" type="demo.inset"/>\n  </network>\n'))
    err = error_of(load_config, path, maps=["bad"])
    assert isinstance(err, Problems) and len(err.problems) == 2
    assert str(err.problems[0]) == "--map 'bad' must be KIND=PATH"
    assert isinstance(err.problems[1], NetworkError) and "required input 'polygons'" in str(err.problems[1])


def test_a_config_includes_a_network_file(tmp_path):
    write(
        tmp_path,
        "wiring.xml",
        '<sengine version="1">\n  <network>\n    <node id="w" type="demo.squares"/>\n  </network>\n</sengine>\n',
    )
    path = write(tmp_path, "c.xml", config('  <city name="inc" seed="5"/>\n', '  <network file="wiring.xml"/>\n'))
    net = load_config(path)
    assert list(net.specs) == ["w"] and net.specs["w"].where == "wiring.xml:3"
    assert net.plan.name == "inc" and net.seed == 5 and net.source == str(path)


def test_read_network_file_without_network(tmp_path):
    path = write(tmp_path, "nn.xml", '<sengine version="1">\n</sengine>\n')
    assert str(error_of(read_network_file, path)) == f"{path}:1: the file has no <network>"
    assert str(error_of(read_network_file, path, label="L")) == "L:1: the file has no <network>"


# -- load_config's overrides --------------------------------------------------------------------


def test_map_overrides(tmp_path):
    city = '  <city>\n    <map kind="height" src="h.png" max="30"/>\n  </city>\n'
    path = write(tmp_path, "m.xml", config(city, SQUARES))
    net = load_config(path, maps=["height=other=1.png", "district=d.png"])
    h, d = net.plan.maps["height"], net.plan.maps["district"]
    assert h == MapSpec("height", Path("other=1.png").resolve(), {"max": "30"}, "--map height")
    assert d == MapSpec("district", Path("d.png").resolve(), {}, "--map district")
    given = MapSpec("height", tmp_path / "x.png", {}, "batch")
    assert load_config(path, maps=[given]).plan.maps["height"] == MapSpec(
        "height", tmp_path / "x.png", {"max": "30"}, "batch"
    )
    own = MapSpec("height", tmp_path / "y.png", {"max": "9"}, "cmd")
    assert load_config(path, maps=[own]).plan.maps["height"] == own
    fresh = MapSpec("district", tmp_path / "z.png", {}, "cmd")
    both = load_config(path, maps=[fresh, given]).plan.maps
    assert both["district"] == fresh and both["height"].where == "batch"
    err = error_of(load_config, path, maps=["height", "=x.png", "height=", "district=d.png"])
    assert isinstance(err, Problems) and str(err) == f"{path}: 3 problems"
    assert [str(p) for p in err.problems] == [
        "--map 'height' must be KIND=PATH",
        "--map '=x.png' must be KIND=PATH",
        "--map 'height=' must be KIND=PATH",
    ]


def test_set_overrides_and_seed(tmp_path):
    path = write(tmp_path, "s.xml", config('  <city seed="9"/>\n', SQUARES))
    net = load_config(path, sets=["s.count=4", "s.size=a=b"], seed=0)
    assert net.specs["s"].params == {"count": "4", "size": "a=b"} and net.seed == 0
    assert net.specs["s"].param_where["count"] == "--set s.count"
    assert load_config(path).seed == 9 and load_config(path, seed=3).seed == 3
    err = error_of(load_config, path, sets=["s.count", "count=3", ".count=3", "s.=3", "ghost.count=1"])
    assert isinstance(err, Problems) and str(err) == f"{path}: 5 problems"
    assert [str(p) for p in err.problems[:4]] == [
        "--set 's.count' must be NODE.PARAM=VALUE",
        "--set 'count=3' must be NODE.PARAM=VALUE",
        "--set '.count=3' must be NODE.PARAM=VALUE",
        "--set 's.=3' must be NODE.PARAM=VALUE",
    ]
    assert str(err.problems[4]).startswith("--set ghost.count: no node with id 'ghost'")
    with pytest.raises(SEngineError, match=r"unknown parameter 'a\.b'|'a\.b'"):  # the name is all after the first dot
        load_config(path, sets=["s.a.b=1"]).validate()


def test_plugins_given_by_path_resolve_against_the_working_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(FIXTURES)
    path = write(tmp_path, "p.xml", config("", SQUARES, plugin=False))
    net = load_config(path, plugins=["squares_plugin.py"])
    assert net.specs["s"].type == "demo.squares"
    path = write(tmp_path, "q.xml", '<sengine version="1">\n  <plugin module="a" path="b.py"/>\n</sengine>\n')
    assert str(error_of(load_config, path)) == f"{path}:2: <plugin> takes exactly one of module= or path="


def test_blank_network_references_are_refused():
    from lxml import etree

    # the schema refuses base=" " already; the check holds for networks built in code too
    for attrs, key in (({"base": " "}, "base"), ({"file": "  "}, "file")):
        el = etree.fromstring(etree.tostring(etree.Element("network", attrs)))
        assert str(error_of(_base_network, el, "n.xml", Path("."), 0)) == f"n.xml:1: <network> {key}= is empty"

"""Every user mistake in a config: exit status 2, one line, no traceback, nothing in OUT."""

from __future__ import annotations

import pytest

from sengine.cli import main

HEAD = '<sengine version="1">\n  <plugin path="PLUGIN"/>\n'


def net(body: str, city: str = '  <city name="t" size="100 100"/>\n') -> str:
    return HEAD + city + "  <network>\n" + body + "  </network>\n</sengine>\n"


SRC = '    <node id="source" type="demo.squares"/>\n'
INSET = '    <node id="inset" type="demo.inset"/>\n'
WIRE = '    <connect from="source" to="inset"/>\n'

CASES = {
    "not well-formed": ('<sengine version="1">\n  <city>\n</sengine>\n', r"t\.xml:3: not well-formed XML"),
    "empty file": ("", r"t\.xml:1: not well-formed XML"),
    "wrong root": ('<city name="x"/>\n', r"not a sengine file: the root element is <city>"),
    "missing version": ("<sengine>\n</sengine>\n", r"t\.xml:1: invalid: .*version"),
    "wrong version": ('<sengine version="2">\n</sengine>\n', r"t\.xml:1: invalid: .*version"),
    "unknown element": ('<sengine version="1">\n  <town/>\n</sengine>\n', r"t\.xml:2: invalid: <town>"),
    "node without id": (net('    <node type="demo.squares"/>\n'), r"t\.xml:5: invalid: .*'id' is required"),
    "bad node id": (net('    <node id="1st" type="demo.squares"/>\n'), r"t\.xml:5: invalid: .*'id'"),
    "unknown node type": (
        net('    <node id="s" type="demo.squarez"/>\n'),
        r"t\.xml:5: node 's' \(demo.squarez\): unknown node type 'demo.squarez'; did you mean 'demo.squares'",
    ),
    "unknown output port": (
        net(SRC + INSET + '    <connect from="source.nope" to="inset"/>\n'),
        r"t\.xml:7: node 'source' \(demo.squares\) has no output 'nope' \(outputs: squares\)",
    ),
    "unknown input port": (
        net(SRC + INSET + '    <connect from="source" to="inset.nope"/>\n'),
        r"t\.xml:7: node 'inset' \(demo.inset\) has no input 'nope'",
    ),
    "connect unknown node": (
        net(SRC + '    <connect from="source" to="ghost"/>\n'),
        r"t\.xml:6: connection names unknown node 'ghost'",
    ),
    "kind mismatch": (
        net('    <node id="l" type="demo.lines"/>\n' + INSET + '    <connect from="l" to="inset"/>\n'),
        r"t\.xml:7: port kind mismatch: 'l' gives lines:lines but 'inset' takes polygons:polygons",
    ),
    "cycle": (
        net(
            SRC + '    <node id="a" type="null"/>\n    <node id="b" type="null"/>\n'
            '    <connect from="a" to="b"/>\n    <connect from="b" to="a"/>\n'
        ),
        r"cycle: a -> b -> a",
    ),
    "missing required input": (net(SRC + INSET), r"t\.xml:6: node 'inset' \(demo.inset\): required input 'polygons'"),
    "input connected twice": (
        net(
            SRC
            + '    <node id="s2" type="demo.squares"/>\n'
            + INSET
            + WIRE
            + '    <connect from="s2" to="inset.polygons"/>\n'
        ),
        r"input 'inset.polygons' is connected twice",
    ),
    "disconnect what is not connected": (
        net(SRC + INSET + '    <disconnect from="inset" to="source"/>\n'),
        r"t\.xml:7: there is no connection from 'inset' to 'source' to remove",
    ),
    "duplicate node id": (net(SRC + SRC), r"t\.xml:6: node id 'source' is defined twice"),
    "parameter below minimum": (
        net('    <node id="s" type="demo.squares">\n      <param name="count" value="0"/>\n    </node>\n'),
        r"t\.xml:6: node 's' \(demo.squares\): count=0 is below the minimum 1",
    ),
    "parameter above maximum": (
        net('    <node id="s" type="demo.squares">\n      <param name="size" value="1e9"/>\n    </node>\n'),
        r"size=1000000000.0 m is above the maximum 10000.0 m",
    ),
    "parameter wrong type": (
        net('    <node id="s" type="demo.squares">\n      <param name="count" value="many"/>\n    </node>\n'),
        r"count='many' is not a valid int",
    ),
    "unknown parameter": (
        net('    <node id="s" type="demo.squares">\n      <param name="colour" value="red"/>\n    </node>\n'),
        r"unknown parameter 'colour' \(parameters: count, size\)",
    ),
    "param for unknown node": (
        net(SRC + '    <param node="ghost" name="count" value="3"/>\n'),
        r"t\.xml:6: no node with id 'ghost'",
    ),
    "missing plugin file": (
        '<sengine version="1">\n  <plugin path="nowhere.py"/>\n</sengine>\n',
        r"t\.xml:2: plugin path '.*nowhere.py' does not exist",
    ),
    "missing plugin module": (
        '<sengine version="1">\n  <plugin module="no_such_sengine_plugin"/>\n</sengine>\n',
        r"t\.xml:2: plugin module 'no_such_sengine_plugin' not found",
    ),
    "plugin with both": (
        '<sengine version="1">\n  <plugin module="a" path="b.py"/>\n</sengine>\n',
        r"t\.xml:2: <plugin> takes exactly one of module= or path=",
    ),
    "unknown network base": (
        '<sengine version="1">\n  <network base="nosuch"/>\n</sengine>\n',
        r"t\.xml:2: unknown network base 'nosuch'",
    ),
    "bad city size": (net(SRC, city='  <city size="-5 10"/>\n'), r"t\.xml:3: size='-5 10' must be two positive widths"),
    "bad origin": (net(SRC, city='  <city origin="95 10"/>\n'), r"t\.xml:3: origin='95 10' is not a latitude"),
    "malformed size": (net(SRC, city='  <city size="ten"/>\n'), r"t\.xml:3: invalid: .*size"),
    "map twice": (
        net(
            SRC,
            city='  <city>\n    <map kind="height" src="a.png"/>\n    <map kind="height" src="b.png"/>\n  </city>\n',
        ),
        r"t\.xml:5: a map of kind 'height' is given twice",
    ),
    "XXE local file": (
        '<?xml version="1.0"?>\n<!DOCTYPE sengine [<!ENTITY x SYSTEM "file:///etc/passwd">]>\n'
        '<sengine version="1"><city name="&x;"/></sengine>\n',
        r"DOCTYPE declarations \(DTDs and entities\) are not allowed",
    ),
    "billion laughs": (
        '<?xml version="1.0"?>\n<!DOCTYPE lolz [\n <!ENTITY lol "lol">\n'
        ' <!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">\n'
        ' <!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">\n'
        ' <!ENTITY lol4 "&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;">\n]>\n'
        '<sengine version="1"><city name="&lol4;"/></sengine>\n',
        r"DOCTYPE declarations \(DTDs and entities\) are not allowed",
    ),
    "external DTD over the network": (
        '<?xml version="1.0"?>\n<!DOCTYPE sengine SYSTEM "http://example.invalid/s.dtd">\n<sengine version="1"/>\n',
        r"DOCTYPE declarations",
    ),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_config_is_one_line_exit_2(case, tmp_path, fixtures, capsys):
    text, pattern = CASES[case]
    config = tmp_path / "t.xml"
    config.write_text(text.replace("PLUGIN", str(fixtures / "squares_plugin.py")))
    out = tmp_path / "OUT"
    status = main(["run", str(config), "-o", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert status == 2
    import re

    lines = err.strip().splitlines()
    assert lines[0].startswith("sengine: error: ")
    assert "Traceback" not in err
    if len(lines) > 1:  # several problems: a summary line, then one line each
        n = re.search(r": (\d+) problems$", lines[0])
        assert n and len(lines) == int(n.group(1)) + 1, err
        assert all(line.startswith("  ") for line in lines[1:]), err
    assert re.search(pattern, err), err
    assert not out.exists() or not any(out.iterdir())
    assert not list(tmp_path.glob(".OUT.*")), "temporary output left behind"


def test_missing_config_file(tmp_path, capsys):
    status = main(["run", str(tmp_path / "nope.xml"), "-o", str(tmp_path / "OUT")])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and "nope.xml: file not found" in err


@pytest.mark.parametrize(
    "argv, pattern",
    [
        (["--set", "ghost.count=3"], r"--set ghost.count: no node with id 'ghost'"),
        (
            ["--set", "source.count=-1"],
            r"--set source.count: node 'source' \(demo.squares\): count=-1 is below the minimum 1",
        ),
        (["--set", "count"], r"--set 'count' must be NODE.PARAM=VALUE"),
        (["--map", "height"], r"--map 'height' must be KIND=PATH"),
        (
            ["--plugin", "not_a_module_anywhere"],
            r"--plugin not_a_module_anywhere: plugin module 'not_a_module_anywhere' not found",
        ),
        (["--workers", "0"], r"^sengine run: error: argument --workers: 0 is less than 1"),
        (["--workers", "two"], r"argument --workers: 'two' is not a whole number"),
        (["--no-such-option"], r"^sengine: error: unrecognized arguments: --no-such-option"),
    ],
)
def test_bad_command_line_override(argv, pattern, fixtures, tmp_path, capsys):
    out = tmp_path / "OUT"
    status = main(["run", str(fixtures / "squares.xml"), "-o", str(out), "--quiet", *argv])
    err = capsys.readouterr().err
    import re

    assert status == 2 and len(err.strip().splitlines()) == 1
    assert re.search(pattern, err), err
    assert not out.exists()


def test_debug_shows_traceback(fixtures, tmp_path):
    from sengine.errors import ParameterError

    with pytest.raises(ParameterError, match="count=-1 is below the minimum 1"):
        main(["run", str(fixtures / "squares.xml"), "-o", str(tmp_path / "o"), "--debug", "--set", "source.count=-1"])


def test_failing_node_leaves_no_partial_output(fixtures, tmp_path, monkeypatch):
    """A node that writes a file and then a later node fails: OUT stays empty."""
    from sengine import registry
    from sengine.errors import InputDataError

    main(["nodes", "--plugin", str(fixtures / "squares_plugin.py")])
    inset = registry.get("demo.inset")

    def boom(self, *, polygons):  # noqa: ARG001
        raise InputDataError("the input went bad", where=self.where)

    config = tmp_path / "c.xml"
    config.write_text(
        (fixtures / "squares.xml")
        .read_text()
        .replace("squares_plugin.py", str(fixtures / "squares_plugin.py"))
        .replace(
            '    <connect from="source.squares" to="inset.polygons"/>',
            '    <node id="second" type="demo.inset"/>\n    <connect from="source.squares" to="inset.polygons"/>\n'
            '    <connect from="inset" to="second"/>',
        )
    )
    original = inset.run
    calls = []

    def second_fails(self, *, polygons):
        calls.append(self.id)
        if self.id == "second":
            return boom(self, polygons=polygons)
        return original(self, polygons=polygons)

    monkeypatch.setattr(inset, "run", second_fails)
    out = tmp_path / "OUT"
    assert main(["run", str(config), "-o", str(out), "--quiet"]) == 2
    assert calls == ["inset", "second"]  # the first inset did write its file ...
    assert not out.exists()  # ... into a temporary folder that is gone
    assert [p.name for p in tmp_path.iterdir()] == ["c.xml"]

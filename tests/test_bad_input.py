"""A corpus of a few hundred bad inputs, generated here (issue 15, part 8).

Every element and attribute of the schema and every declared parameter with
wrong types, NaN, inf, negative and huge values; truncated, empty, special
(a FIFO, /dev/zero, a folder) and enormous-header image, OSM and OBJ files;
plugins that fail at import or in ``run``; absurd sizes and spacings; an
output folder that cannot be written.  Each must end in one line (or, for
several problems, a summary line and one line each) and exit status 2 --
or exit 0 when the input is legal -- with no traceback and nothing in OUT.
They run in this process through :func:`sengine.cli.main`; a few need a
process of their own (signals, stderr of a whole run).
"""

from __future__ import annotations

import bz2
import os
import re
import signal
import struct
import subprocess
import sys
import time
import zlib
from pathlib import Path

import numpy as np
import pytest
from conftest import CONFIGS, DATA, interruptible
from PIL import Image

from sengine.cli import main
from sengine.errors import SEngineError
from sengine.registry import RULES, get, names
from sengine.xmlconfig import SCHEMA_PATH

BAD_NUMBERS = ["abc", "nan", "NaN", "inf", "-inf", "1e400", "-1e30", "1e30", "", "1 2 3"]


# -- the harness ----------------------------------------------------------------------------------


def outcome(argv: list[str], capsys) -> tuple[int, list[str]]:
    """Run ``sengine ARGV`` here; return the exit status and the stderr lines, checking the one-line rule."""
    status = main([str(a) for a in argv])
    cap = capsys.readouterr()
    err = cap.err
    assert "Traceback" not in err and "Traceback" not in cap.out, err
    lines = [line for line in err.splitlines() if line.strip()]
    if status == 2:
        assert lines, "exit 2 without a message"
        assert lines[0].startswith(("sengine: error: ", "sengine run: error: ", "sengine validate: error: ")), err
        if len(lines) > 1:  # several problems: a summary, then one line each, at most 20 in all
            n = re.search(r": (\d+) problems$", lines[0])
            assert n, err
            assert len(lines) == min(int(n.group(1)) + 1, 20) and all(x.startswith("  ") for x in lines[1:]), err
    else:  # a legal input: at most one-line warnings
        assert all(x.startswith("sengine: warning: ") or x.startswith("sengine: WARNING: ") for x in lines), err
    return status, lines


def assert_refused(argv, capsys, pattern: str | None = None, out: Path | None = None) -> list[str]:
    status, lines = outcome(argv, capsys)
    assert status == 2, (argv, lines)
    if pattern:
        assert any(re.search(pattern, line) for line in lines), (pattern, lines)
    if out is not None:
        assert not out.exists() or not any(out.iterdir()), f"{out} has files"
        assert not list(out.parent.glob(f".{out.name}.*")), "temporary output left behind"
    return lines


CITY = '<city name="t" seed="3" size="1200 900" origin="41.98 2.82"{attrs}>\n{rules}</city>\n'
RULE = '    <district name="a" pattern="grid" spacing="300 300" minor-spacing="100 60"{attrs}/>\n'


def config(tmp_path: Path, *, city_attrs="", rule_attrs="", rules=None, network='<network base="pattern"/>') -> Path:
    rules = RULE.format(attrs=rule_attrs) if rules is None else rules
    text = f'<sengine version="1">\n{CITY.format(attrs=city_attrs, rules=rules)}{network}\n</sengine>\n'
    path = tmp_path / "c.xml"
    path.write_text(text)
    return path


def xml_attr(value: str) -> str:
    return value.replace("&", "&amp;").replace('"', "&quot;").replace("<", "&lt;")


# -- the schema: every attribute of every element ------------------------------------------------


def schema_attributes() -> list[tuple[str, str, str]]:
    """``(element, attribute, xsd type)`` for every attribute the schema declares."""
    from lxml import etree

    ns = {"xs": "http://www.w3.org/2001/XMLSchema"}
    tree = etree.parse(str(SCHEMA_PATH))
    out = []
    for el in tree.iter("{http://www.w3.org/2001/XMLSchema}element"):
        name = el.get("name")
        if not name:
            continue
        for attr in el.iterfind("./xs:complexType//xs:attribute", ns):
            owner = next(a for a in attr.iterancestors() if a.tag == el.tag)
            if owner is el:  # not an attribute of a nested element
                out.append((name, attr.get("name"), attr.get("type") or "restricted"))
    for ct in tree.iterfind("./xs:complexType", ns):
        for attr in ct.iterfind(".//xs:attribute", ns):
            out.append((f"type:{ct.get('name')}", attr.get("name"), attr.get("type") or ""))
    return out


def test_the_schema_is_covered():
    seen = {(e, a) for e, a, _ in schema_attributes()}
    assert {("city", "size"), ("city", "seed"), ("map", "kind"), ("node", "id"), ("type:edge", "from")} <= seen
    assert {(e, a) for e, a in seen} <= {(e, a) for e, a in SCHEMA_CASES}, "an attribute without bad cases"


def _doc(tmp_path, **parts) -> Path:
    text = (
        '<sengine version="1">\n{plugin}<city name="t" seed="3" size="1200 900" origin="41.98 2.82">\n'
        '    <district name="a" pattern="grid" spacing="300 300"/>\n{map}</city>\n{network}\n</sengine>\n'
    )
    values = {"plugin": "", "map": "", "network": '<network base="pattern"/>', **parts}
    path = tmp_path / "s.xml"
    path.write_text(text.format(**values))
    return path


# each schema attribute with its bad values: (element, attribute) -> builder(value) -> document parts
SCHEMA_CASES = {
    ("sengine", "version"): lambda v: {"_root": f'<sengine version="{v}">'},
    ("plugin", "module"): lambda v: {"plugin": f'<plugin module="{v}"/>\n'},
    ("plugin", "path"): lambda v: {"plugin": f'<plugin path="{v}"/>\n'},
    ("city", "name"): None,  # any text is a name
    ("city", "seed"): lambda v: {"_city": f'seed="{v}"'},
    ("city", "size"): lambda v: {"_city": f'size="{v}"'},
    ("city", "origin"): lambda v: {"_city": f'origin="{v}"'},
    ("map", "kind"): lambda v: {"map": f'    <map kind="{v}" src="x.png"/>\n'},
    ("map", "src"): lambda v: {"map": f'    <map kind="height" src="{v}" min="0" max="50"/>\n'},
    ("node", "id"): lambda v: {"network": f'<network><node id="{v}" type="null"/></network>'},
    ("node", "type"): lambda v: {"network": f'<network><node id="n" type="{v}"/></network>'},
    ("network", "base"): lambda v: {"network": f'<network base="{v}"/>'},
    ("network", "file"): lambda v: {"network": f'<network file="{v}"/>'},
    ("param", "node"): lambda v: {
        "network": f'<network base="pattern"><param node="{v}" name="merge" value="0.1"/></network>'
    },
    ("type:param", "name"): lambda v: {
        "network": f'<network base="pattern"><param node="lots" name="{v}" value="1"/></network>'
    },
    ("type:param", "value"): lambda v: {
        "network": f'<network base="pattern"><param node="majorRoads" name="merge" value="{v}"/></network>'
    },
    ("type:edge", "from"): lambda v: {
        "network": f'<network base="pattern"><connect from="{v}" to="export.water"/></network>'
    },
    ("type:edge", "to"): lambda v: {
        "network": f'<network base="pattern"><connect from="majorRoads.landuse" to="{v}"/></network>'
    },
}
SCHEMA_VALUES = ["abc", "nan", "inf", "-1", "-5 10", "1e400 1", "0 0", "", "1e6 1e6", "99999999999999999999999", "ü"]


def _schema_doc(tmp_path, builder, value) -> Path:
    parts = builder(xml_attr(value))
    root = parts.pop("_root", None)
    city = parts.pop("_city", None)
    path = _doc(tmp_path, **parts)
    text = path.read_text()
    if root:
        text = text.replace('<sengine version="1">', root, 1)
    if city:
        key = city.split("=")[0]
        text = re.sub(rf'{key}="[^"]*"', city, text, count=1)
    path.write_text(text)
    return path


@pytest.mark.parametrize("element, attribute", [k for k, v in SCHEMA_CASES.items() if v is not None])
@pytest.mark.parametrize("value", SCHEMA_VALUES)
def test_schema_attribute_with_a_bad_value(element, attribute, value, tmp_path, capsys):
    path = _schema_doc(tmp_path, SCHEMA_CASES[(element, attribute)], value)
    status, lines = outcome(["validate", path], capsys)
    legal = {
        ("city", "seed", "99999999999999999999999"),  # any whole number seeds a run
        ("city", "origin", "-5 10"),  # 5 deg south, 10 deg east
        ("city", "origin", "0 0"),
        ("plugin", "module", "abc"),  # the standard library's abc: a module that registers nothing
        ("plugin", "path", "abc"),  # no slash, no .py: a module name
    }
    assert status == (0 if (element, attribute, value) in legal else 2), lines


# -- declared parameters: node parameters and rule attributes --------------------------------------


def bad_values(param) -> list[str]:
    if param.type in ("float", "int"):
        vals = ["abc", "nan", "inf", "-inf", "1e30", "-1e30", ""]
        if param.type == "int":
            vals.append("1.5")
        if param.count > 1:
            vals.append("1")
        return vals
    if param.type == "bool":
        return ["maybe", ""]
    if param.type == "colour":
        return ["#12", "red", "300 0 0"]
    if param.choices:
        return [param.choices[0][:-1] + "x", ""]
    return []


def _legal(param, value) -> bool:
    try:
        param.coerce(value, "w", "p")
    except SEngineError:
        return False
    return True


PLUGIN = '''
import numpy as np
from sengine import Layer, Port, SENode, register

@register
class Any(SENode):
    """An empty layer of any kind (feeds a probed node's inputs)."""
    name = "corpus.any"
    outputs = {"out": Port("any", "an empty layer")}
    def run(self):
        return {"out": Layer.empty()}
'''

SOURCE_PARAMS = {"maps.image": {"kind": "district", "src": "x.png"}, "maps.file": {"kind": "osm", "src": "x.osm"}}


@pytest.fixture(scope="module")
def corpus_plugin(tmp_path_factory):
    path = tmp_path_factory.mktemp("corpus") / "corpus_plugin.py"
    path.write_text(PLUGIN)
    return path


def _probe(tmp_path, plugin, node_type, name, value) -> Path:
    cls = get(node_type)
    given = dict(SOURCE_PARAMS.get(node_type, {}))
    if node_type == "plan.rules":
        given["tag"] = "district"
    given[name] = value
    body = "".join(f'      <param name="{k}" value="{xml_attr(str(v))}"/>\n' for k, v in given.items())
    wires = "".join(f'    <connect from="src" to="probe.{p}"/>\n' for p, port in cls.inputs.items() if port.required)
    text = (
        f'<sengine version="1">\n  <plugin path="{plugin}"/>\n  <city size="1000 1000"/>\n  <network>\n'
        f'    <node id="src" type="corpus.any"/>\n    <node id="probe" type="{node_type}">\n{body}    </node>\n'
        f"{wires}  </network>\n</sengine>\n"
    )
    path = tmp_path / "p.xml"
    path.write_text(text)
    return path


def _builtin_params():
    for node_type in names():
        cls = get(node_type)
        if not cls.__module__.startswith("sengine.nodes"):
            continue
        for name, param in cls.params.items():
            for value in bad_values(param):
                yield node_type, name, value


def _split(cases, slow_values=("inf", "-inf", "1e30", "-1e30", "1.5", "1", "red", "300 0 0", "")):
    """NaN, wrong types and typos of every parameter run by default; the other values with the slow tests."""
    return [pytest.param(*c, marks=pytest.mark.slow if c[-1] in slow_values else ()) for c in cases]


@pytest.mark.parametrize("node_type, name, value", _split(list(_builtin_params())))
def test_node_parameter_with_a_bad_value(node_type, name, value, tmp_path, capsys, corpus_plugin):
    path = _probe(tmp_path, corpus_plugin, node_type, name, value)
    param = get(node_type).params[name]
    status, lines = outcome(["validate", path], capsys)
    if _legal(param, value):  # legal here: whatever else validate says, it is not about this value
        assert not any(f"{name}=" in line and "probe" in line for line in lines[1:] or lines), lines
    else:
        assert status == 2 and len(lines) == 1, lines
        assert "node 'probe'" in lines[0] and name in lines[0] and "p.xml:" in lines[0], lines
    if param.type in ("float", "int") and value in ("nan", "inf", "-inf"):
        assert status == 2, (node_type, name, value, lines)


def _rule_params():
    for tag in ("district", "landuse"):
        for name, param in sorted(RULES.get(tag, {}).items()):
            for value in bad_values(param) + (["-1"] if param.type in ("float", "int") else []):
                yield tag, name, value


@pytest.mark.parametrize("tag, name, value", list(_rule_params()))
def test_rule_attribute_with_a_bad_value(tag, name, value, tmp_path, capsys):
    param = RULES[tag][name]
    rule = f'    <{tag} {name}="{xml_attr(value)}"/>\n'
    if tag == "landuse":
        rule = RULE.format(attrs="") + rule
    path = config(tmp_path, rules=rule)
    status, lines = outcome(["validate", path], capsys)
    if not _legal(param, value):
        assert status == 2 and len(lines) == 1 and f"<{tag}> {name}" in lines[0] and "c.xml:" in lines[0], lines
    if param.type in ("float", "int") and (value in ("nan", "inf", "-inf") or value == "1e30" and param.max):
        assert status == 2, lines


# the lot attributes are declared by the lot nodes, being rewritten on another branch: they
# are to get their maxima there (a lot-area of 1e30 m2 is accepted, and keeps every block whole)
UNBOUNDED_LOT_ATTRIBUTES = {
    "lot-area",
    "lot-depth",
    "lot-deviation",
    "lot-frontage",
    "lot-min-depth",
    "lot-segment",
    "lot-width",
}


def test_every_numeric_rule_attribute_has_a_maximum():
    unbounded = {
        name
        for tag in ("district", "landuse")
        for name, p in RULES.get(tag, {}).items()
        if p.type in ("float", "int") and p.max is None
    }
    assert unbounded <= UNBOUNDED_LOT_ATTRIBUTES, sorted(unbounded - UNBOUNDED_LOT_ATTRIBUTES)


def test_unknown_city_attribute_is_an_error(tmp_path, capsys):
    assert_refused(["validate", config(tmp_path, city_attrs=' sizee="10 10"')], capsys, r"did you mean 'size'")


# -- absurd sizes and spacings: refused before any work, with the estimate ------------------------


ABSURD = {
    "city of 1e6 m": ({"city_attrs": ""}, ("1200 900", "1e6 1e6"), r"size='1e6 1e6' must be two positive widths"),
    "spacing of 1 cm": (
        {"rule_attrs": ""},
        ('spacing="300 300"', 'spacing="0.01 0.01"'),
        r"makes about 1\.1e\+10 areas",
    ),
    "minor spacing of 1 cm": ({}, ('minor-spacing="100 60"', 'minor-spacing="0.01 0.01"'), r"about 1\.1e\+10 blocks"),
    "1e6 sites": ({}, ('pattern="grid"', 'pattern="organic" sites="1000000"'), r"sites=1000000 is above the maximum"),
    "1e5 rings": ({}, ('pattern="grid"', 'pattern="radial" rings="100000"'), r"rings=100000 is above the maximum"),
    "lot area of 1 m2": ({}, ('minor-spacing="100 60"', 'minor-spacing="100 60" lot-area="0.1"'), r"lot-area"),
    "spacing of 0": ({}, ('spacing="300 300"', 'spacing="0 0"'), r"spacing='0 0' is not 2 numbers"),
    "1e5 sites": ({}, ('pattern="grid"', 'pattern="organic" sites="100000"'), r"1e\+05 areas.*use fewer sites"),
    "rings 10 cm apart": (
        {},
        ('pattern="grid"', 'pattern="radial" ring-spacing="0.1"'),
        r"ring-spacing 0.1 m x 8 spokes .* makes about 6e\+04 areas.*make the ring-spacing larger",
    ),
}


@pytest.mark.parametrize("case", sorted(ABSURD))
@pytest.mark.parametrize("command", ["validate", "run"])
def test_absurd_sizes_are_refused_before_work(case, command, tmp_path, capsys):
    _, (old, new), pattern = ABSURD[case]
    path = config(tmp_path)
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))
    out = tmp_path / "OUT"
    argv = ["validate", path] if command == "validate" else ["run", path, "-o", out, "-q", "--workers", "1"]
    t0 = time.perf_counter()
    assert_refused(argv, capsys, pattern, out=out if command == "run" else None)
    assert time.perf_counter() - t0 < 5.0  # refused, not attempted


# -- files: configs, image maps, OSM and OBJ files ----------------------------------------------------


def _fifo(tmp_path: Path, name: str) -> Path:
    path = tmp_path / name
    os.mkfifo(path)
    return path


def _png_header(path: Path, width: int, height: int) -> None:
    """A PNG whose header claims ``width`` x ``height`` pixels, with almost no data."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 64)) + chunk(b"IEND", b"")
    )


def _truncated_png(path: Path) -> None:
    data = (CONFIGS / "maps" / "manhattan_landuse.png").read_bytes()
    path.write_bytes(data[: len(data) // 2])


CONFIG_FILES = {
    "empty": lambda p: p.write_text(""),
    "binary": lambda p: p.write_bytes(bytes(range(256)) * 4),
    "truncated": lambda p: p.write_text((CONFIGS / "manhattan.xml").read_text()[:700]),
    "nul bytes": lambda p: p.write_bytes(b'<sengine version="1">\0\0\0</sengine>'),
    "9 MB": lambda p: p.write_text("<!-- " + "x" * 9_000_000 + " -->"),
    "a folder": lambda p: p.mkdir(),
    "a fifo": lambda p: os.mkfifo(p),
    "html": lambda p: p.write_text("<html><body>not a city</body></html>"),
    "deep nesting": lambda p: p.write_text(
        '<sengine version="1">' + "<network>" * 5000 + "</network>" * 5000 + "</sengine>"
    ),
}


@pytest.mark.parametrize("case", sorted(CONFIG_FILES))
@pytest.mark.parametrize("command", ["validate", "run", "graph"])
def test_bad_config_file(case, command, tmp_path, capsys):
    path = tmp_path / "bad.xml"
    CONFIG_FILES[case](path)
    out = tmp_path / "OUT"
    argv = {
        "validate": ["validate", path],
        "run": ["run", path, "-o", out],
        "graph": ["graph", path, "-o", tmp_path / "g.svg"],
    }
    lines = assert_refused(argv[command], capsys, out=out if command == "run" else None)
    assert "bad.xml" in lines[0]
    assert not out.exists() and not (tmp_path / "g.svg").exists()


def test_config_that_is_dev_zero(capsys, tmp_path):
    assert_refused(["validate", "/dev/zero"], capsys, r"/dev/zero: is not a regular file")
    assert_refused(["run", "/dev/null", "-o", tmp_path / "OUT"], capsys, r"/dev/null", out=tmp_path / "OUT")


def _manhattan(tmp_path: Path) -> Path:
    (tmp_path / "maps").mkdir(exist_ok=True)
    for png in (CONFIGS / "maps").glob("manhattan_*.png"):
        (tmp_path / "maps" / png.name).write_bytes(png.read_bytes())
    path = tmp_path / "manhattan.xml"
    path.write_text((CONFIGS / "manhattan.xml").read_text())
    return path


IMAGES = {
    "empty": (lambda p: p.write_bytes(b""), r"cannot read the image|is empty"),
    "text": (lambda p: p.write_text("not an image"), r"cannot read the image"),
    "truncated": (_truncated_png, r"cannot read the image"),
    "header claims 100000 x 150000 px": (lambda p: _png_header(p, 100_000, 150_000), r"15000 Mpx.*the limit is"),
    "a folder": (lambda p: p.mkdir(), r"is a folder"),
    "a fifo": (lambda p: os.mkfifo(p), r"not a regular file"),
    "1 x 1 px": (lambda p: Image.new("RGB", (1, 1)).save(p), r"ratios must agree"),
    "wrong aspect": (lambda p: Image.new("RGB", (300, 100)).save(p), r"ratios must agree"),
    "unknown colour": (lambda p: Image.new("RGB", (60, 90), (1, 2, 3)).save(p), r"colour #010203"),
}


@pytest.mark.parametrize("case", sorted(IMAGES))
@pytest.mark.parametrize("kind", ["district", "landuse"])
@pytest.mark.parametrize("command", ["validate", "run"])
def test_bad_image_map(case, kind, command, tmp_path, capsys):
    make, pattern = IMAGES[case]
    bad = tmp_path / "bad.png"
    make(bad)
    config_path = _manhattan(tmp_path)
    out = tmp_path / "OUT"
    base = ["validate", config_path] if command == "validate" else ["run", config_path, "-o", out, "-q"]
    lines = assert_refused([*base, "--map", f"{kind}={bad}"], capsys, pattern, out=out)
    assert f"--map {kind}" in lines[0] or "bad.png" in lines[0], lines


@pytest.mark.parametrize("special", ["/dev/zero", "/dev/null"])
def test_image_map_that_is_a_device(special, tmp_path, capsys):
    assert_refused(
        ["validate", _manhattan(tmp_path), "--map", f"height={special}"], capsys, r"not a regular file|empty"
    )


def test_image_map_that_is_missing(tmp_path, capsys):
    assert_refused(["validate", _manhattan(tmp_path), "--map", f"height={tmp_path / 'nope.png'}"], capsys, "not found")


def _osm(text: str) -> str:
    return f"<?xml version='1.0' encoding='UTF-8'?>\n<osm version='0.6'>\n{text}</osm>\n"


def _way(nodes, tags="") -> str:
    return f"  <way id='1'>{''.join(f'<nd ref={n!r}/>' for n in nodes)}<tag k='highway' v='residential'/>{tags}</way>\n"


def _nodes(coords) -> str:
    return "".join(f"  <node id='{i + 1}' lat='{lat}' lon='{lon}'/>\n" for i, (lat, lon) in enumerate(coords))


SQUARE = [(41.98, 2.82), (41.981, 2.82), (41.981, 2.821), (41.98, 2.821)]
OSM_FILES = {
    "empty.osm": (lambda p: p.write_text(""), r"osm file .* is empty"),
    "garbage.osm": (lambda p: p.write_text("<<< not xml >>>"), r"OSM file|cannot read"),
    "truncated.osm.pbf": (lambda p: p.write_bytes((DATA / "monaco.osm.pbf").read_bytes()[:5000]), r"truncated.osm.pbf"),
    "garbage.osm.bz2": (lambda p: p.write_bytes(b"BZh9" + os.urandom(500)), r"garbage.osm.bz2"),
    "text.osm.bz2": (lambda p: p.write_bytes(bz2.compress(b"no xml in here")), r"text.osm.bz2"),
    "folder.osm": (lambda p: p.mkdir(), r"is a folder"),
    "fifo.osm": (lambda p: os.mkfifo(p), r"not a regular file"),
    "one point.osm": (
        lambda p: p.write_text(_osm(_nodes([SQUARE[0]] * 4) + _way(["1", "2", "3", "4", "1"]))),
        None,  # legal, and empty: a one-line warning that the city has no streets
    ),
    "layer overflow.osm": (
        lambda p: p.write_text(
            _osm(_nodes(SQUARE) + _way(["1", "2", "3", "4", "1"], "<tag k='layer' v='99999999999999999999'/>"))
        ),
        None,
    ),
    "nan coordinates.osm": (lambda p: p.write_text(_osm(_nodes([("nan", "nan")] * 4) + _way(["1", "2", "3"]))), None),
    "missing nodes.osm": (lambda p: p.write_text(_osm(_way(["7", "8", "9"]))), None),
    "no highways.osm": (lambda p: p.write_text(_osm(_nodes(SQUARE))), None),
}


@pytest.mark.parametrize("case", sorted(OSM_FILES))
def test_bad_osm_file(case, tmp_path, capsys):
    make, pattern = OSM_FILES[case]
    path = tmp_path / case.replace(" ", "_")
    make(path)
    out = tmp_path / "OUT"
    status, lines = outcome(["osm", path, "-o", out, "-q", "--workers", "1", "--format", "geojson"], capsys)
    if pattern is None:  # legal but empty or degenerate: a one-line warning and a (small) city, or one error
        assert status in (0, 2) and len(lines) <= 2, lines
        if status == 2:
            assert not out.exists()
    else:
        assert status == 2 and len(lines) == 1 and re.search(pattern, lines[0]), lines
        assert not out.exists()


OBJ_FILES = {
    "empty.obj": ("", r"obj file .* is empty"),
    "nan vertices.obj": ("v nan 0 0\nv 1 0 0\nv 1 0 1\nl 1 2 3\n", r"OBJ file"),
    "two coordinates.obj": ("v 0 0\nv 1 0\nv 1 1\nl 1 2 3\n", r"OBJ file"),
    "bad index.obj": ("v 0 0 0\nv 1 0 0\nl 1 99\n", r"OBJ file"),
    "bad line.obj": ("v 0 0 0\nl a b\n", r"bad line element"),
    "binary.obj": (bytes(range(256)), r"not a text OBJ file"),
    "inf vertices.obj": ("v inf 0 0\nv 1 0 0\nv 0 0 1\nl 1 2 3\n", r"OBJ file"),
}


@pytest.mark.parametrize("case", sorted(OBJ_FILES))
def test_bad_obj_file(case, tmp_path, capsys):
    text, pattern = OBJ_FILES[case]
    path = tmp_path / case.replace(" ", "_")
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    cfg = tmp_path / "obj.xml"
    cfg.write_text(
        f'<sengine version="1">\n  <city size="100 100">\n    <map kind="obj" src="{path}"/>\n  </city>\n'
        '  <network>\n    <node id="majorRoads" type="obj.roads"/>\n    <node id="minorRoads" type="null"/>\n'
        '    <connect from="majorRoads" to="minorRoads"/>\n  </network>\n</sengine>\n'
    )
    out = tmp_path / "OUT"
    assert_refused(["run", cfg, "-o", out, "-q"], capsys, pattern, out=out)


# -- plugins ----------------------------------------------------------------------------------------------------

PLUGINS = {
    "syntax error": ("def oops(:\n", r"failed to import: SyntaxError"),
    "raises at import": ("raise RuntimeError('no licence server')\n", r"failed to import: RuntimeError: no licence"),
    "imports a missing module": ("import no_such_module_anywhere\n", r"No module named 'no_such_module_anywhere'"),
    "bad node name": (
        "from sengine import SENode, register\n@register\nclass X(SENode):\n    name = 'Bad Name!'\n",
        r"node name 'Bad Name!' must be dotted identifiers",
    ),
    "run keywords differ from the ports": (
        "from sengine import Port, SENode, register\n@register\nclass Y(SENode):\n"
        "    name = 'corpus.keywords'\n    inputs = {'a': Port('lots')}\n    def run(self, *, b):\n        return {}\n",
        r"keyword-only arguments \['b'\] differ from its input ports \['a'\]",
    ),
    "a built-in name twice": (
        "from sengine import SENode, register\n@register\nclass Z(SENode):\n    name = 'lots.paris'\n",
        r"node name 'lots.paris' is registered twice",
    ),
    "a bad default": (
        "from sengine import Param, SENode, register\n@register\nclass W(SENode):\n    name = 'corpus.default'\n"
        "    params = {'x': Param('float', float('nan'), unit='m', doc='x')}\n    def run(self):\n        return {}\n",
        r"x=nan is not a finite number",
    ),
}


@pytest.mark.parametrize("case", sorted(PLUGINS))
@pytest.mark.parametrize("how", ["config", "command line"])
def test_broken_plugin(case, how, tmp_path, capsys):
    code, pattern = PLUGINS[case]
    plugin = tmp_path / f"broken_{how[0]}_{abs(hash(case)) % 10**6}.py"
    plugin.write_text(code)
    if how == "config":
        cfg = tmp_path / "p.xml"
        cfg.write_text(f'<sengine version="1">\n  <plugin path="{plugin}"/>\n</sengine>\n')
        argv = ["validate", cfg]
    else:
        argv = ["validate", config(tmp_path), "--plugin", plugin]
    lines = assert_refused(argv, capsys, pattern)
    assert len(lines) == 1


def test_plugin_folder_without_init(tmp_path, capsys):
    (tmp_path / "pkg").mkdir()
    assert_refused(["validate", config(tmp_path), "--plugin", f"{tmp_path / 'pkg'}/"], capsys, "has no __init__.py")


# -- the output folder and the command line ----------------------------------------------------------------------


def test_output_folder_that_is_a_file(tmp_path, capsys):
    out = tmp_path / "OUT"
    out.write_text("precious")
    t0 = time.perf_counter()
    assert_refused(["run", config(tmp_path), "-o", out, "-q"], capsys, r"is an existing file")
    assert out.read_text() == "precious" and time.perf_counter() - t0 < 5.0


def test_output_folder_under_a_file(tmp_path, capsys):
    (tmp_path / "f").write_text("x")
    assert_refused(["run", config(tmp_path), "-o", tmp_path / "f" / "OUT", "-q"], capsys, r"cannot write the output")


def test_output_folder_with_too_long_a_name(tmp_path, capsys):
    out = tmp_path / ("x" * 300)
    assert_refused(["run", config(tmp_path), "-o", out, "-q"], capsys, r"cannot write the output folder.*too long")
    assert [p.name for p in tmp_path.iterdir()] == ["c.xml"]


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root writes anywhere")
def test_output_folder_not_writable(tmp_path, capsys):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        assert_refused(["run", config(tmp_path), "-o", locked / "OUT", "-q"], capsys, r"cannot write")
    finally:
        locked.chmod(0o700)


COMMAND_LINES = {
    "--seeds 1-1000000000": (["batch", "{cfg}", "-o", "{out}", "--seeds", "1-1000000000"], r"1,000,000,000 seeds"),
    "--seeds 5-1": (["batch", "{cfg}", "-o", "{out}", "--seeds", "5-1"], r"runs backwards"),
    "--seeds x": (["batch", "{cfg}", "-o", "{out}", "--seeds", "x"], r"is not a seed"),
    "--format fbx": (["run", "{cfg}", "-o", "{out}", "--format", "fbx"], r"unknown format 'fbx'"),
    "--format glb,shp": (["run", "{cfg}", "-o", "{out}", "--format", "glb,shp"], r"unknown format 'shp'"),
    "--map heigth": (["run", "{cfg}", "-o", "{out}", "--map", "heigth=x.png"], r"did you mean 'height'"),
    "--set nan": (["run", "{cfg}", "-o", "{out}", "--set", "majorRoads.merge=nan"], r"merge=nan is not a finite"),
    "--set unknown": (["run", "{cfg}", "-o", "{out}", "--set", "majorRoads.mrege=1"], r"did you mean 'merge'"),
    "--workers -3": (["run", "{cfg}", "-o", "{out}", "--workers", "-3"], r"--workers"),
    "--seed abc": (["run", "{cfg}", "-o", "{out}", "--seed", "abc"], r"--seed"),
    "osm missing": (["osm", "{tmp}/nope.osm.pbf", "-o", "{out}"], r"file not found"),
    "graph into a folder": (["graph", "{cfg}", "-o", "{tmp}"], r"graph|folder|\.dot, \.svg or \.png"),
    "graph unknown suffix": (["graph", "{cfg}", "-o", "{tmp}/g.jpg"], r"\.dot, \.svg or \.png"),
    "graph under a file": (["graph", "{cfg}", "-o", "{cfg}/g.svg"], r"cannot write .*g\.svg"),
    "graph name too long": (["graph", "{cfg}", "-o", "{tmp}/" + "x" * 300 + ".png"], r"cannot write .*too long"),
    "batch under a file": (["batch", "{cfg}", "-o", "{cfg}/runs", "--seeds", "1-2"], r"cannot write the output folder"),
}


@pytest.mark.parametrize("case", sorted(COMMAND_LINES))
def test_bad_command_line(case, tmp_path, capsys):
    argv, pattern = COMMAND_LINES[case]
    cfg = config(tmp_path)
    out = tmp_path / "OUT"
    argv = [a.format(cfg=cfg, out=out, tmp=tmp_path) for a in argv]
    assert_refused(argv, capsys, pattern, out=out)


# -- whole processes: stderr stays one line, signals end every process ------------------------------------------


WARNING_PLUGIN = '''
import struct, zlib
import numpy as np
from PIL import Image
from sengine import Layer, Port, SENode, register

@register
class Noisy(SENode):
    """Makes numpy and Pillow warn, as real inputs do (a zero height range, an over-large image header)."""
    name = "noisy.warn"
    outputs = {"out": Port("polygons", "nothing")}
    def run(self):
        np.log(np.zeros(3))  # RuntimeWarning: divide by zero
        def chunk(k, d):
            return struct.pack(">I", len(d)) + k + d + struct.pack(">I", zlib.crc32(k + d) & 0xFFFFFFFF)
        path = self.context.out / "big.png"
        ihdr = struct.pack(">IIBBBBB", 10000, 9000, 8, 2, 0, 0, 0)
        path.write_bytes(b"\\x89PNG\\r\\n\\x1a\\n" + chunk(b"IHDR", ihdr) + chunk(b"IEND", b""))
        Image.open(path).close()  # DecompressionBombWarning: 90 Mpx
        path.unlink()
        return {"out": Layer.empty()}
'''


def test_library_warnings_do_not_reach_stderr(tmp_path):
    """numpy and Pillow warn inside a run: stderr stays empty (``--debug`` shows them)."""
    (tmp_path / "noisy_plugin.py").write_text(WARNING_PLUGIN)
    cfg = tmp_path / "noisy.xml"
    cfg.write_text(
        '<sengine version="1">\n  <plugin path="noisy_plugin.py"/>\n  <network>\n'
        '    <node id="n" type="noisy.warn"/>\n  </network>\n</sengine>\n'
    )
    env = {**os.environ, "PYTHONWARNINGS": "default"}
    cmd = [sys.executable, "-m", "sengine", "run", str(cfg), "-o", str(tmp_path / "OUT"), "-q"]
    done = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 0 and done.stderr == "", done.stderr
    debug = subprocess.run([*cmd, "--debug"], capture_output=True, text=True, env=env, timeout=300)
    assert "RuntimeWarning" in debug.stderr and "DecompressionBombWarning" in debug.stderr, debug.stderr


SLOW_PLUGIN = '''
import time
import numpy as np
import shapely
from sengine import Layer, Port, SENode, register

@register
class Many(SENode):
    """Many small squares."""
    name = "slow.many"
    outputs = {"out": Port("polygons", "squares")}
    def run(self):
        n = 4000
        return {"out": Layer.from_geoms(shapely.box(np.arange(n), 0, np.arange(n) + 0.5, 0.5), kind="square")}

@register
class Slow(SENode):
    """Takes its time over each feature (a node the executor spreads over workers)."""
    name = "slow.map"
    inputs = {"polygons": Port("polygons", "squares")}
    outputs = {"polygons": Port("polygons", "the same")}
    maps_features = True
    def run(self, *, polygons):
        time.sleep(0.004 * len(polygons))
        return {"polygons": polygons}
'''


def _children(pid: int) -> set[int]:
    out = set()
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                out.add(int(entry.name))
    return out


def _alive(pid: int) -> bool:
    try:
        state = (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc").is_dir() or sys.platform != "linux", reason="reads /proc")
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_ends_every_process_of_the_run(sig, tmp_path):
    (tmp_path / "slow_plugin.py").write_text(SLOW_PLUGIN)
    cfg = tmp_path / "slow.xml"
    cfg.write_text(
        '<sengine version="1">\n  <plugin path="slow_plugin.py"/>\n  <network>\n'
        '    <node id="many" type="slow.many"/>\n    <node id="slow" type="slow.map"/>\n'
        '    <connect from="many" to="slow"/>\n  </network>\n</sengine>\n'
    )
    out = tmp_path / "OUT"
    proc = subprocess.Popen(
        [sys.executable, "-m", "sengine", "run", str(cfg), "-o", str(out), "--workers", "3", "-q"],
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=interruptible,
    )
    kids: set[int] = set()
    deadline = time.time() + 60
    while time.time() < deadline and len(kids) < 2:
        kids |= _children(proc.pid)
        time.sleep(0.05)
    assert kids, "the run never forked its workers"
    proc.send_signal(sig)
    status = proc.wait(timeout=30)
    err = proc.stderr.read()
    assert status == (143 if sig == signal.SIGTERM else 130), err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    time.sleep(0.5)
    assert not [k for k in kids if _alive(k)], "a worker outlived its run"
    assert not out.exists() and not list(tmp_path.glob(".OUT.*"))


def test_the_corpus_is_a_few_hundred_inputs():
    n = (
        len([k for k, v in SCHEMA_CASES.items() if v]) * len(SCHEMA_VALUES)
        + len(list(_builtin_params()))
        + len(list(_rule_params()))
        + 2 * len(ABSURD)
        + 3 * len(CONFIG_FILES)
        + 4 * len(IMAGES)
        + len(OSM_FILES)
        + len(OBJ_FILES)
        + 2 * len(PLUGINS)
        + len(COMMAND_LINES)
    )
    assert n >= 300, n
    np.testing.assert_(n < 5000)


@pytest.mark.parametrize("special", ["fifo", "/dev/zero", "folder"])
def test_osm_path_parameter_that_is_special(special, tmp_path, capsys):
    """A path set on the node itself is checked as the plan's map files are: it never blocks or fills memory."""
    if special == "fifo":
        target = _fifo(tmp_path, "streets.osm")
    elif special == "folder":
        target = tmp_path / "streets.osm"
        target.mkdir()
    else:
        target = Path(special)
    out = tmp_path / "OUT"
    argv = ["run", CONFIGS / "monaco.xml", "-o", out, "-q", "--set", f"majorRoads.path={target}"]
    assert_refused(argv, capsys, r"OSM file .*(not a regular file|is a folder)", out=out)


def test_an_all_water_city_is_legal_and_says_it_is_empty(tmp_path):
    """Legal but empty input: exit 0 and one line that says so."""
    cfg = _manhattan(tmp_path)
    water = tmp_path / "maps" / "water.png"
    Image.new("RGB", (60, 90), (0x20, 0x60, 0xFF)).save(water)
    out = tmp_path / "OUT"
    cmd = [sys.executable, "-m", "sengine", "run", str(cfg), "-o", str(out), "-q", "--workers", "1"]
    done = subprocess.run([*cmd, "--map", f"landuse={water}"], capture_output=True, text=True, timeout=300)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 0 and len(lines) == 1, done.stderr
    assert lines[0].startswith("sengine: WARNING: ") and "nothing buildable: the city is empty" in lines[0]
    assert (out / "stats.json").exists()


@pytest.mark.parametrize(
    "config, setting",
    [
        ("districts.xml", "minorRoads.grid=1.0"),  # cells snapped to a 1 m grid collapse to lines: no GEOS error
        ("manhattan.xml", "majorRoads.grid=1.0"),
        ("manhattan.xml", "blocks.min_area=1e9"),  # no block at all: an empty, legal city
    ],
)
def test_extreme_legal_parameters_run(config, setting, tmp_path, capsys):
    """The bounds of a parameter are part of its declaration: its extreme values run (found by sweeping them)."""
    out = tmp_path / "OUT"
    status, lines = outcome(["run", CONFIGS / config, "-o", out, "-q", "--workers", "1", "--set", setting], capsys)
    assert status == 0, lines
    assert (out / "stats.json").exists()

"""Every input on a port, declared all the way down (issue 15, parts 2 and 4).

The plan's maps and rules are source nodes on the graph; ``run`` hands its
report back; layer kinds declare their columns; ``validate`` finds every
problem a run would, all at once.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
import shapely
from conftest import CONFIGS
from PIL import Image

from sengine import Layer, NodeResult
from sengine.cli import main
from sengine.errors import NetworkError, NodeError, Problems
from sengine.registry import check_kind, get, kinds
from sengine.xmlconfig import load_config

MANHATTAN = CONFIGS / "manhattan.xml"


def _config(tmp_path, text: str, name: str = "city.xml"):
    (tmp_path / "maps").mkdir(exist_ok=True)
    for png in (CONFIGS / "maps").glob("manhattan_*.png"):
        (tmp_path / "maps" / png.name).write_bytes(png.read_bytes())
    path = tmp_path / name
    path.write_text(text)
    return path


def _err(capsys) -> list[str]:
    return capsys.readouterr().err.strip().splitlines()


# -- part 2: every input on a port ------------------------------------------------------------


def test_manhattan_inputs_are_nodes_on_the_graph():
    net = load_config(MANHATTAN)
    g = net.graph()
    types = {n: d["type"] for n, d in g.nodes(data=True)}
    assert types["districtMap"] == types["landuseMap"] == types["heightMap"] == "maps.image"
    assert types["districtRules"] == types["landuseRules"] == "plan.rules"
    edges = {(u, v, d["dst_port"]) for u, v, d in g.edges(data=True)}
    assert ("districtMap", "majorRoads", "district_map") in edges
    assert ("landuseMap", "majorRoads", "landuse_map") in edges
    assert ("districtRules", "majorRoads", "district_rules") in edges
    assert ("districtRules", "minorRoads", "district_rules") in edges
    assert ("landuseRules", "majorRoads", "landuse_rules") in edges
    # wiring twice adds nothing
    assert net.wire_plan() == [] and len(net.graph().edges) == len(g.edges)


def test_source_layers_carry_the_plan():
    result = load_config(MANHATTAN).check()
    dmap = result.layers["districtMap"]["map"]
    assert len(dmap) == 1 and dmap.meta["extent"] == (0.0, 0.0, 7200.0, 10800.0)
    assert dmap.meta["image"].shape[1] / dmap.meta["image"].shape[0] == pytest.approx(7200 / 10800, rel=0.01)
    hmap = result.layers["heightMap"]["map"]
    assert (hmap["min"][0], hmap["max"][0]) == (12.0, 240.0)
    rules = result.layers["districtRules"]["rules"]
    assert list(rules["name"]) == ["downtown", "village", "midtown", "uptown"]
    assert rules["lot-area"][0] == "2600" and rules["lot-area"][1] is None
    assert all(re.search(r"manhattan\.xml:\d+$", w) for w in rules["where"])


def test_graph_port_holds_the_faces_blocks_take_over():
    from sengine.nodes.blocks.circuits import traced_faces

    roads = Layer.from_geoms(
        [shapely.LineString([(x, 0), (x, 300)]) for x in (0, 100, 200, 300)]
        + [shapely.LineString([(0, y), (300, y)]) for y in (0, 150, 300)]
    )
    out = get("roads.clean")("clean", {}).run(roads=roads)
    graph = out["graph"]
    check_kind(graph, "graph")
    faces = graph.meta["faces"]
    assert len(faces.faces) == 3 * 2
    # each graph segment joins its two nodes and lies on its street segment
    xy = graph.meta["xy"]
    ends = shapely.get_coordinates(graph.geometry).reshape(-1, 2, 2)
    assert np.array_equal(ends[:, 0], xy[graph["u"]]) and np.array_equal(ends[:, 1], xy[graph["v"]])
    assert shapely.covers(out["roads"].geometry[graph["row"]], graph.geometry).all()
    # blocks.circuits takes the same faces over from the port; the roads carry no graph behind it
    assert "graph" not in out["roads"].meta
    taken = traced_faces(graph, len(out["roads"]), decimals=6)
    assert taken is not None and len(taken.faces) == 6
    # numbered for other decimals, the faces are not taken over by a blocks node that merges to 6
    other = get("roads.clean")("clean", {"decimals": "3"}).run(roads=roads)
    assert other["graph"].meta["decimals"] == 3
    assert traced_faces(other["graph"], len(other["roads"]), decimals=6) is None


PLUGIN = '''
import shapely
from sengine import Layer, NodeResult, Port, SENode, register

def _one():
    return Layer.from_geoms([shapely.box(0, 0, 1, 1)], kind="x")

@register
class NewForm(SENode):
    """Returns NodeResult."""
    name = "shape.result"
    outputs = {"out": Port("polygons", "one box")}
    def run(self):
        return NodeResult({"out": _one()}, {"made": 1})

@register
class PairForm(SENode):
    """Returns (layers, report)."""
    name = "shape.pair"
    outputs = {"out": Port("polygons", "one box")}
    def run(self):
        return {"out": _one()}, {"made": 2}

@register
class OldForm(SENode):
    """Sets self.report."""
    name = "shape.old"
    outputs = {"out": Port("polygons", "one box")}
    def run(self):
        self.report = {"made": 3}
        return {"out": _one()}

@register
class WrongPort(SENode):
    """Returns an undeclared port."""
    name = "shape.wrongport"
    outputs = {"out": Port("polygons", "one box")}
    def run(self):
        return {"oot": _one()}

@register
class NotADict(SENode):
    """Returns a list."""
    name = "shape.list"
    outputs = {"out": Port("polygons", "one box")}
    def run(self):
        return [_one()]

@register
class NotALayer(SENode):
    """Returns a shapely array."""
    name = "shape.array"
    outputs = {"out": Port("polygons", "one box")}
    def run(self):
        return {"out": [shapely.box(0, 0, 1, 1)]}

@register
class Raises(SENode):
    """Raises in run."""
    name = "shape.raises"
    outputs = {"out": Port("polygons", "one box")}
    def run(self):
        raise ZeroDivisionError("plugin bug")

@register
class BadColumn(SENode):
    """Lots with a text block id."""
    name = "shape.badlots"
    outputs = {"lots": Port("lots", "lots")}
    def run(self):
        return {"lots": Layer.from_geoms([shapely.box(0, 0, 1, 1)], block="7", district=0, corner=False,
                                          frontage=1.0, street_edges=1, method="x")}
'''


@pytest.fixture(scope="module")
def shapes_plugin(tmp_path_factory):
    path = tmp_path_factory.mktemp("plugin") / "shapes_plugin.py"
    path.write_text(PLUGIN)
    return path


def _plugin_config(tmp_path, node_type: str, plugin) -> str:
    path = tmp_path / f"{node_type}.xml"
    path.write_text(
        f'<sengine version="1">\n  <plugin path="{plugin}"/>\n  <network>\n'
        f'    <node id="n" type="{node_type}"/>\n  </network>\n</sengine>\n'
    )
    return str(path)


@pytest.mark.parametrize("node_type, made", [("shape.result", 1), ("shape.pair", 2), ("shape.old", 3)])
def test_every_form_of_run_gives_its_report(node_type, made, tmp_path, shapes_plugin):
    result = load_config(_plugin_config(tmp_path, node_type, shapes_plugin)).run()
    assert result.stats["report"]["n"] == {"made": made}
    assert len(result["n"]) == 1


@pytest.mark.parametrize(
    "node_type, pattern",
    [
        ("shape.wrongport", r"returned ports \['oot'\], declared \['out'\] \(missing 'out'; undeclared 'oot'\)"),
        ("shape.list", r"run\(\) returned list, expected a dict of output layers"),
        ("shape.array", r"'out' is a list, not a Layer"),
        ("shape.raises", r"failed: ZeroDivisionError: plugin bug"),
    ],
)
def test_plugin_of_the_wrong_shape_is_one_line(node_type, pattern, tmp_path, capsys, shapes_plugin):
    out = tmp_path / "OUT"
    status = main(["run", _plugin_config(tmp_path, node_type, shapes_plugin), "-o", str(out), "--quiet"])
    lines = _err(capsys)
    assert status == 2 and len(lines) == 1, lines
    assert "node 'n'" in lines[0] and re.search(pattern, lines[0]), lines[0]
    assert not out.exists()
    with pytest.raises(NodeError):
        load_config(_plugin_config(tmp_path, node_type, shapes_plugin)).run()


# -- part 4: declared all the way down --------------------------------------------------------


def test_kind_check_finds_a_wrong_dtype_and_a_missing_column(tmp_path, shapes_plugin):
    with pytest.raises(NetworkError, match=r"column 'block' has dtype <U1 .*declared 'iu'"):
        load_config(_plugin_config(tmp_path, "shape.badlots", shapes_plugin)).run(check_kinds=True)
    load_config(_plugin_config(tmp_path, "shape.badlots", shapes_plugin)).run()  # not checked without --debug
    lots = Layer.from_geoms([shapely.box(0, 0, 1, 1)], block=1)
    with pytest.raises(NetworkError, match="column 'district' is missing"):
        check_kind(lots, "lots")
    check_kind(Layer.empty(), "lots")  # an empty layer needs no column
    check_kind(lots, "some.plugin.kind")  # undeclared kinds pass


@pytest.mark.parametrize(
    "config",
    [
        pytest.param(p.name, marks=() if p.name == "manhattan.xml" else pytest.mark.slow)
        for p in sorted(CONFIGS.glob("*.xml"))
    ],
)
def test_every_demo_layer_keeps_its_kind(config):
    """Every layer of every demo carries its kind's columns with their dtypes (the run checks them)."""
    net = load_config(CONFIGS / config)
    result = net.run(check_kinds=True)
    bound = net.validate()
    seen = {bound.nodes[n].outputs[p].kind for n, outs in result.layers.items() for p in outs}
    assert {"roads", "blocks", "lots", "buildings"} <= seen and seen - {"any"} <= set(kinds())


BAD_PLAN = {
    "lot-aera": (('lot-area="2600"', 'lot-aera="2600"'), r"unknown attribute 'lot-aera'; did you mean 'lot-area'"),
    "heigth": (('kind="height"', 'kind="heigth"'), r"unknown map kind 'heigth'; did you mean 'height'"),
    "minor-spacng": (
        ('minor-spacing="250 80"', 'minor-spacng="250 80"'),
        r"unknown attribute 'minor-spacng'; did you mean 'minor-spacing'",
    ),
    "lot-area -5": (('lot-area="2600"', 'lot-area="-5"'), r"lot-area=-5.0 m2 is below the minimum"),
    "gird": (('pattern="grid" spacing="450', 'pattern="gird" spacing="450'), r"pattern='gird' .*did you mean 'grid'"),
    "missing map": (("manhattan_landuse.png", "nowhere.png"), r"nowhere.png': file not found"),
    "wrong aspect": (("manhattan_height.png", "manhattan_height_wide.png"), r"the ratios must agree"),
    "unknown colour": (('color="#6a5acd"', 'color="#6a5ace"'), r"colour #6a5acd .* is not in the district rules"),
    "height max 1e30": (('max="240"', 'max="1e30"'), r"max=1e\+30 m is above the maximum 1000"),
    "height without max": ((' max="240"', ""), r"height map needs min and max"),
    "NaN angle": (('angle="-10"', 'angle="nan"'), r"angle=nan is not a finite number"),
    "city of 1e6 m": (('size="7200 10800"', 'size="1e6 1.5e6"'), r"size='1e6 1.5e6' must be two positive widths"),
}


@pytest.mark.parametrize("case", sorted(BAD_PLAN))
def test_validate_rejects_what_run_rejects(case, tmp_path, capsys):
    (old, new), pattern = BAD_PLAN[case]
    text = MANHATTAN.read_text()
    assert old in text
    config = _config(tmp_path, text.replace(old, new, 1))
    Image.new("L", (300, 100), 0).save(tmp_path / "maps" / "manhattan_height_wide.png")
    assert main(["validate", str(config)]) == 2
    lines = _err(capsys)
    assert len(lines) == 1 and re.search(pattern, lines[0]), lines
    out = tmp_path / "OUT"
    assert main(["run", str(config), "-o", str(out), "--quiet", "--workers", "1"]) == 2
    lines = _err(capsys)
    assert len(lines) == 1 and re.search(pattern, lines[0]), lines
    assert not out.exists()


def test_every_problem_of_a_config_is_listed(tmp_path, capsys):
    text = MANHATTAN.read_text()
    for (old, new), _ in (BAD_PLAN[k] for k in ("lot-aera", "heigth", "minor-spacng", "gird")):
        text = text.replace(old, new, 1)
    config = _config(tmp_path, text)
    assert main(["validate", str(config)]) == 2
    lines = _err(capsys)
    assert lines[0].endswith("city.xml: 4 problems") and len(lines) == 5, lines
    for key in ("lot-aera", "heigth", "minor-spacng", "gird"):
        assert sum(key in line for line in lines[1:]) == 1, (key, lines)
    assert all(re.match(r"  \S*city\.xml:\d+: ", line) for line in lines[1:]), lines


def test_at_most_twenty_lines():
    many = Problems([NetworkError(f"problem {i}") for i in range(50)], where="x.xml")
    assert len(many.lines) == 20 and many.lines[0] == "x.xml: 50 problems"
    assert many.lines[-1] == "... and 32 more" and many.lines[1] == "problem 0"


@pytest.mark.parametrize(
    "formats, pattern",
    [("fbx", r"unknown format 'fbx'"), ("glb,shp", r"unknown format 'shp'"), ("gbl", r"did you mean 'glb'")],
)
def test_unknown_format_is_an_error(formats, pattern, tmp_path, capsys):
    out = tmp_path / "OUT"
    assert main(["run", str(MANHATTAN), "-o", str(out), "--format", formats]) == 2
    lines = _err(capsys)
    assert len(lines) == 1 and re.search(pattern, lines[0]) and "--format" in lines[0]
    assert not out.exists()


def test_nodes_lists_rules_kinds_maps_and_formats(capsys):
    assert main(["nodes"]) == 0
    text = capsys.readouterr().out
    assert "<district> attributes of the plan" in text and "    - lot-area: float" in text
    assert "<landuse> attributes of the plan" in text
    assert "    - height (port height_map:raster)" in text
    assert "    - lots: block*:iu" in text and "    - glb  export.city" in text
    assert main(["nodes", "--json", "--all"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert {"nodes", "rules", "kinds", "maps", "formats"} == set(info)
    assert info["kinds"]["lots"]["block"]["required"] and "cityjson" in info["formats"]
    assert any(p["name"] == "minor-spacing" for p in info["rules"]["district"])


def test_node_result_reads_as_its_layers():
    lay = Layer.from_geoms([shapely.box(0, 0, 1, 1)])
    res = NodeResult({"a": lay}, {"n": 1})
    assert res["a"] is lay and list(res) == ["a"] and len(res) == 1 and dict(res) == {"a": lay}


PARITY = [
    ('lots="manhattan"', 'lots="manhatan"'),
    ('minor-angle="follow"', 'minor-angle="abc"'),
    ('relax="4"', 'relax="4.5"'),
    ('class="buildable"/>', 'class="buildable" buildable="maybe"/>'),
    ('weights="0.8"', 'weights="0.8" center="1 2 3"'),
    ('angle="-10"', 'angle="-10" ring-spacing="0"'),
]


@pytest.mark.parametrize("old, new", PARITY)
def test_validate_and_run_agree(old, new, tmp_path, capsys):
    """What ``run`` refuses, ``validate`` refuses first, with the same first line."""
    config = _config(tmp_path, MANHATTAN.read_text().replace(old, new, 1))
    assert main(["validate", str(config)]) == 2
    first = _err(capsys)[0]
    out = tmp_path / "OUT"
    assert main(["run", str(config), "-o", str(out), "-q", "--workers", "1"]) == 2
    assert _err(capsys)[0] == first and not out.exists()


def test_only_the_plan_sources_read_the_plan():
    from sengine import nodes

    root = Path(nodes.__file__).parent
    readers = {str(p.relative_to(root)) for p in root.rglob("*.py") if re.search(r"context\.plan\b", p.read_text())}
    assert readers == {"maps.py"}, sorted(readers)
    assert "maps.py" in readers

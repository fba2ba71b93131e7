"""Blocks that close on real maps (issue 11, part 5).

Bridges and tunnels close no block but the faces beside them close; cul-de-sacs
are cut out of their blocks so that lots front onto them; the edge of the data
closes the border; land no street serves is open land; no street centre line
crosses a lot.  Checked on the shipped OpenStreetMap extracts through the
load-map network, and on generated street graphs.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import shapely
from conftest import run_cli
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import sengine
from sengine import Context, Layer
from sengine.geom.planar import planar_faces, spur_polygons
from sengine.geom.polygons import right_of_lines
from sengine.geom.segments import box_closure
from sengine.nodes.blocks.landuse import open_land
from sengine.registry import get

SETTINGS = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
DATA = Path(__file__).resolve().parent.parent / "configs" / "data"
LIEGE = Path(__file__).resolve().parent.parent.parent / "shared" / "data" / "liege_streets.osm.pbf"
EXTRACTS = ["helsinki_centre.osm.pbf", "monaco.osm.pbf", "kirchberg_iller.osm", "west_oakland.osm.bz2"]


def _roads(lines, width=10.0, **cols):
    lines = np.asarray(lines, dtype=object)
    return Layer.from_geoms(lines, width=np.full(len(lines), width), meta={"crs": "EPSG:32631"}, **cols)


def _clean(roads, **params):
    node = get("roads.clean")("clean", {k: str(v) for k, v in params.items()}, Context())
    out = node.run(roads=roads)
    return out["roads"], out.report


def _blocks(roads, **params):
    node = get("blocks.circuits")("blocks", {"node": "false", **{k: str(v) for k, v in params.items()}}, Context())
    ran = node.run(roads=roads)
    return ran, ran.report


def _grid(n=4, step=100.0):
    lines = [shapely.LineString([(i * step, 0), (i * step, (n - 1) * step)]) for i in range(n)]
    return lines + [shapely.LineString([(0, j * step), ((n - 1) * step, j * step)]) for j in range(n)]


def _through_lots(lines, lots) -> float:
    """Total length (m) of street centre lines inside lots."""
    if not len(lines) or not len(lots):
        return 0.0
    li, lo = shapely.STRtree(lots).query(lines, predicate="intersects")
    return float(shapely.length(shapely.intersection(lines[li], lots[lo])).sum())


# -- geometry --------------------------------------------------------------------------


def test_box_closure_cuts_the_box_at_the_nodes_on_it():
    xy = np.array([[0.0, 0], [10, 5], [4, 8], [10, 8]])
    out, cu, cv = box_closure(xy, np.array([1]), np.array([3]))  # node 1 - node 3 lies along the east side
    assert out[4:].tolist() == [[10, 0], [0, 8]]  # the corners that were not nodes
    # counter-clockwise from (0, 0), through every node on the box; 1 - 3 is the graph's own edge
    assert list(zip(cu.tolist(), cv.tolist(), strict=True)) == [(0, 4), (4, 1), (3, 2), (2, 5), (5, 0)]
    out, cu, cv = box_closure(xy, margin=2.0)  # past the box: four corners, no node on it
    assert len(cu) == 4 and shapely.box(-2, -2, 12, 10).equals(shapely.Polygon(out[cu]))
    out, cu, cv = box_closure(xy, box=(-5, 0, 10, 20))  # grown to the given extent
    assert shapely.Polygon(out[cu]).bounds == (-5, 0, 10, 20)
    assert len(box_closure(xy[:2])[1]) == 0  # no area, no box


def test_right_of_lines_is_the_sea_of_a_coastline():
    coast = shapely.LineString([(-10, 40), (50, 45), (110, 40)])  # west to east: the sea is south
    sea = right_of_lines([coast], (0, 0, 100, 100))
    assert len(sea) == 1 and sea[0].contains(shapely.Point(50, 10)) and not sea[0].contains(shapely.Point(50, 90))
    assert len(right_of_lines([shapely.LineString([(20, 50), (60, 50)])], (0, 0, 100, 100))) == 0  # closes nothing


@st.composite
def square_with_trees(draw):
    """A square face with a tree of dead ends hanging from some of its sides (a branch or two each)."""
    corners = [(0.0, 0.0), (100.0, 0.0), (100.0, 100.0), (0.0, 100.0)]
    inward = [(0, 1), (-1, 0), (0, -1), (1, 0)]
    xy, u, v = list(corners), [], []
    sides = draw(st.lists(st.integers(0, 3), min_size=1, max_size=4, unique=True))
    for side in range(4):
        a, b = side, (side + 1) % 4
        if side not in sides:
            u.append(a)
            v.append(b)
            continue
        t = draw(st.floats(0.2, 0.8))
        root = len(xy)
        xy.append(tuple(np.add(corners[a], t * np.subtract(corners[b], corners[a]))))
        u += [a, root]
        v += [root, b]
        tip = len(xy)
        xy.append(tuple(np.add(xy[root], np.multiply(inward[side], draw(st.floats(10, 40))))))
        u.append(root)
        v.append(tip)
        if draw(st.booleans()):  # a branch off the tip, square to it
            xy.append(tuple(np.add(xy[tip], np.multiply(inward[side][::-1], draw(st.floats(5, 20))))))
            u.append(tip)
            v.append(len(xy) - 1)
    return np.array(xy), np.array(u), np.array(v)


@SETTINGS
@given(square_with_trees(), st.floats(2.0, 9.0))
def test_spur_inset_keeps_clear_of_the_dead_ends(graph, d):
    """An inward buffer of a face drawn with its dead ends as spurs is the face minus the ground near them."""
    xy, u, v = graph
    pf = planar_faces(xy, u, v)
    ids, polys, spurs, lobes = spur_polygons(pf, xy)
    assert list(ids) == [0] and len(spurs) == pf.bridge.sum() and not len(lobes)
    dead = shapely.linestrings(np.stack([xy[u[pf.bridge]], xy[v[pf.bridge]]], axis=1))
    want = shapely.difference(
        shapely.buffer(pf.polygons[0], -d), shapely.buffer(shapely.union_all(dead), d, quad_segs=16)
    )
    got = shapely.buffer(polys[0], -d, quad_segs=16)
    assert shapely.is_valid(got)
    assert shapely.area(shapely.symmetric_difference(got, want)) <= 1e-3 * shapely.area(want) + 1e-6


# -- bridges ---------------------------------------------------------------------------


def test_a_bridge_closes_no_block_and_takes_no_land():
    lines = _grid()
    bridge = shapely.LineString([(-20, 150), (320, 160)])  # over the whole grid, no junction
    lines.append(bridge)
    n = len(lines)
    roads = _roads(
        lines, 10.0, bridge=np.arange(n) == n - 1, tunnel=np.zeros(n, bool), layer=(np.arange(n) == n - 1) * 1
    )
    cleaned, rep = _clean(roads, dead_ends="false")  # its ends meet no street here: keep it all the same
    assert rep["off_ground"] == 1
    assert rep["crossings_noded"] == _clean(_roads(lines[:-1]))[1]["crossings_noded"]  # the grid's own
    assert bool(cleaned["bridge"].any())  # still a street
    out, brep = _blocks(cleaned, sidewalk=3.0)
    assert len(out["faces"]) == 9  # the faces on both sides of it close on the ground
    assert brep["bridges_over_blocks"] == 1
    blocks = out["blocks"].geometry
    deck = shapely.buffer(bridge, 5.0 - 1e-6, cap_style="flat")
    assert shapely.area(shapely.intersection(blocks, deck)).sum() < 1e-6  # no lot under the deck
    kinds = out["streets"]["kind"]
    assert (kinds == "bridge").sum() == 1
    assert shapely.area(out["streets"].geometry[kinds == "bridge"][0]) == pytest.approx(5.0 * 2 * bridge.length)
    over, _ = _blocks(cleaned, sidewalk=3.0, bridges="over")
    assert shapely.area(over["blocks"].geometry).sum() > shapely.area(blocks).sum() + 1000


@st.composite
def grid_with_bridge(draw):
    n = draw(st.integers(3, 5))
    step = 80.0
    rng = np.random.default_rng(draw(st.integers(0, 2**31)))
    lines = []
    for i in range(n):
        x = i * step + rng.uniform(-10, 10, n)
        lines.append(shapely.LineString(np.c_[x, np.arange(n) * step]))
        y = i * step + rng.uniform(-10, 10, n)
        lines.append(shapely.LineString(np.c_[np.arange(n) * step, y]))
    span = (n - 1) * step
    a = (draw(st.floats(-30, 0)), draw(st.floats(0, span)))
    b = (span + draw(st.floats(0, 30)), draw(st.floats(0, span)))
    return lines, shapely.LineString([a, b])


@SETTINGS
@given(grid_with_bridge())
def test_random_grid_with_a_bridge_over_it(case):
    """The bridge changes no face, keeps its deck off the blocks, and the faces cover the ground enclosures."""
    lines, bridge = case
    n = len(lines) + 1
    flag = np.arange(n) == n - 1
    roads = _roads([*lines, bridge], 8.0, bridge=flag, tunnel=np.zeros(n, bool), layer=flag.astype(int))
    cleaned, _ = _clean(roads, dead_ends="false")
    out, rep = _blocks(cleaned, sidewalk=2.0, min_area=1.0)
    ground, _ = _blocks(_clean(_roads(lines, 8.0), dead_ends="false")[0], sidewalk=2.0, min_area=1.0)
    assert len(out["faces"]) == len(ground["faces"])
    ref = shapely.get_parts(shapely.polygonize(shapely.get_parts(shapely.node(shapely.multilinestrings(lines)))))
    ref = ref[shapely.area(ref) >= 1.0]
    assert shapely.area(out["faces"].geometry).sum() == pytest.approx(shapely.area(ref).sum(), rel=1e-6)
    blocks = out["blocks"].geometry
    assert shapely.is_valid(blocks).all()
    assert _through_lots(np.array([bridge]), blocks) == 0.0
    assert rep["bridges_over_blocks"] == int(_through_lots(np.array([bridge]), ground["blocks"].geometry) > 0)


# -- cul-de-sacs -----------------------------------------------------------------------


def test_lots_front_onto_a_cul_de_sac():
    square = [shapely.LineString([(0, 0), (200, 0), (200, 200), (0, 200), (0, 0)])]
    culdesac = shapely.LineString([(100, 0), (100, 120), (60, 150)])
    roads = _roads([*square, culdesac], 10.0)
    cleaned, rep = _clean(roads, dead_ends="false")
    assert rep["dead_ends_kept"] == 1 and rep["dead_ends_removed"] == 0
    out, brep = _blocks(cleaned, sidewalk=3.0)
    assert brep["dead_ends_cut"] == 1
    lots = get("lots.recursive")("lots", {"max_area": "600"}, Context()).run(blocks=out["blocks"])["lots"]
    g = lots.geometry
    assert shapely.is_valid(g).all() and (shapely.area(g) > 0).all()
    assert shapely.area(g).sum() == pytest.approx(out["blocks"].area(), rel=1e-3)
    assert _through_lots(cleaned.geometry, g) == 0.0
    # lots line both sides of the cul-de-sac: their fronts lie on its sidewalk's edge (5 + 3 m from its centre line)
    fronting = shapely.dwithin(g, culdesac, 8.0 + 1e-6) & (lots["frontage"] > 0)
    assert fronting.sum() >= 8
    sides = np.sign(shapely.get_x(shapely.centroid(g[fronting])) - 100.0)
    assert {-1.0, 1.0} <= set(sides.tolist())
    # the street surface of the cul-de-sac is drawn with its block's street ring
    streets = shapely.union_all(out["streets"].geometry)
    assert shapely.covers(shapely.buffer(streets, 1e-6), shapely.buffer(culdesac, 4.0, cap_style="flat"))


def test_a_village_of_dead_ends_gets_blocks_and_lots():
    tree = [
        shapely.LineString([(0, 0), (0, 300)]),
        shapely.LineString([(0, 150), (-120, 180)]),
        shapely.LineString([(0, 220), (140, 200)]),
    ]
    roads = _roads(tree, 8.0)
    dropped, _ = _clean(roads)  # the default drops dead ends: nothing is left
    assert len(dropped) == 0
    cleaned, rep = _clean(roads, dead_ends="false", close="bbox")
    assert len(cleaned) == 5 and rep["closing_edges"] == 4 and rep["dead_ends_kept"] == 5
    out, brep = _blocks(cleaned, sidewalk=2.0)
    assert len(out["blocks"]) >= 1 and brep["closed_by_bbox"] == len(out["blocks"])
    box = shapely.box(*cleaned.meta["bbox"])
    assert box.bounds == (-120.0, 0.0, 140.0, 300.0)
    assert shapely.within(out["blocks"].geometry, box.buffer(1e-6)).all()
    lots = get("lots.recursive")("lots", {}, Context()).run(blocks=out["blocks"])["lots"]
    assert len(lots) > 20 and _through_lots(cleaned.geometry, lots.geometry) == 0.0


# -- the edge of the data --------------------------------------------------------------


def test_the_box_closes_the_border_with_no_street_along_it():
    # a comb: a street with teeth, no street round it
    lines = [shapely.LineString([(0, 100), (400, 100)])]
    lines += [shapely.LineString([(x, 0), (x, 250)]) for x in (50, 150, 250, 350)]
    roads = _roads(lines, 10.0)
    open_, _ = _blocks(_clean(roads, dead_ends="false")[0], sidewalk=3.0)
    assert len(open_["blocks"]) == 0  # nothing closes without the box
    cleaned, rep = _clean(roads, dead_ends="false", close="bbox")
    out, brep = _blocks(cleaned, sidewalk=3.0)
    box = shapely.box(0, 0, 400, 250)
    assert cleaned.meta["bbox"] == box.bounds and cleaned.meta["closing"] is not None
    assert len(out["blocks"]) == 10 and brep["closed_by_bbox"] == 10
    layers = [out[k].geometry for k in ("blocks", "streets", "sidewalks")]
    # the box is covered: blocks, streets and sidewalks partition it ...
    assert sum(shapely.area(g).sum() for g in layers) == pytest.approx(box.area, rel=1e-9)
    assert shapely.union_all(np.concatenate(layers)).area == pytest.approx(box.area, rel=1e-9)
    # ... and the blocks reach the box: the edge of the data is no street (no street surface, no sidewalk)
    rim = shapely.boundary(box)
    on_rim = shapely.length(shapely.intersection(shapely.union_all(out["blocks"].geometry), rim))
    # all of it but where the 10 street ends meet it, each 2 x (5 + 3) m wide with its sidewalks
    assert on_rim == pytest.approx(2 * (400 + 250) - 10 * 16, abs=1e-6)


# -- open land -------------------------------------------------------------------------


def test_open_land_is_what_no_street_serves():
    big = shapely.box(0, 0, 1000, 1000)  # 100 ha, streets all round
    small = shapely.box(2000, 0, 2100, 100)
    lonely = shapely.box(3050, 50, 3150, 150)  # a piece of a block that the water cut off its streets
    blocks = np.array([big, small, shapely.box(2990, 0, 3200, 200)])
    pieces = np.array([big, small, lonely])
    out, owner, is_open, counts = open_land(pieces, np.array([0, 1, 2]), blocks, max_area=500_000, max_depth=100)
    assert counts == {"open_no_street": 1, "open_split": 1, "open_parts_dropped": 0}
    assert owner.tolist() == [0, 0, 1, 2] and is_open.tolist() == [False, True, False, True]
    assert shapely.area(out[1]) == pytest.approx(800 * 800)  # the core beyond 100 m
    assert shapely.area(out[0]) + shapely.area(out[1]) == pytest.approx(big.area)
    # along the edge of the data only the land near a street is built on, whatever its size
    edge, owner, is_open, counts = open_land(
        np.array([small]), np.array([0]), np.array([small]), max_area=500_000, max_depth=30, box=(2000, 0, 2100, 300)
    )
    assert counts["open_split"] == 1 and is_open.tolist() == [False, True]
    assert shapely.area(edge[0]) == pytest.approx(100 * 30, rel=1e-3)  # 30 m along the one street (y = 100)


# -- real maps through the load-map network ----------------------------------------------


def _loadmap(path: Path, tmp_path: Path):
    cfg = tmp_path / "city.xml"
    cfg.write_text(
        f'<sengine version="1"><city name="t" seed="1"><map kind="osm" src="{path.resolve()}"/></city>'
        '<network base="loadmap"/></sengine>'
    )
    return sengine.load(cfg).run(seed=1)


def _check_closes(layers, stats):
    roads = layers["clean"]["roads"]
    ground = ~roads["tunnel"] & ~roads["bridge"] & (roads["layer"] == 0)
    rim = shapely.boundary(shapely.box(*roads.meta["bbox"]))
    lines = np.r_[roads.geometry[ground], [rim]]
    enclosures = shapely.get_parts(shapely.polygonize(shapely.get_parts(shapely.node(shapely.multilinestrings(lines)))))
    enclosures = enclosures[shapely.area(enclosures) >= 50.0]
    every = shapely.union_all(enclosures)
    land = layers["landuse"]["blocks"]
    read = layers["majorRoads"]
    parts = [land.geometry, read["water"].geometry, read["parks"].geometry]
    parts += [layers["blocks"][k].geometry for k in ("streets", "sidewalks")]
    covered = shapely.union_all(shapely.make_valid(np.concatenate(parts)))
    # every enclosure is a block (built or open land), a cut-out (water, park) or street surface
    missing = shapely.area(shapely.difference(every, covered))
    assert missing <= 1e-3 * shapely.area(every)
    lots = layers["lots"]["lots"]
    assert _through_lots(roads.geometry[~roads["tunnel"]], lots.geometry) < 1e-6
    # open land gets no lot
    assert not np.isin(lots["block"], land.ids[land["landuse"] == "open"]).any()
    rep = stats["report"]
    assert rep["landuse"]["open_blocks"] == int((land["landuse"] == "open").sum())
    assert rep["blocks"]["dead_ends_cut"] == rep["clean"]["dead_ends_kept"]
    return rep


@pytest.mark.parametrize("name", EXTRACTS)
def test_every_enclosure_of_a_real_map_closes(name, tmp_path):
    layers, stats = _loadmap(DATA / name, tmp_path)
    rep = _check_closes(layers, stats)
    assert stats["counts"]["blocks"] > 0 and stats["counts"]["lots"] > 0
    assert rep["blocks"]["closed_by_bbox"] > 0


def test_kirchberg_a_village_gets_blocks_and_lots(tmp_path):
    layers, stats = _loadmap(DATA / "kirchberg_iller.osm", tmp_path)
    assert stats["counts"]["blocks"] >= 2 and stats["counts"]["lots"] >= 20
    # its houses past the last street stand in a block: the box holds the map's buildings
    houses = layers["majorRoads"]["buildings"].geometry
    land = shapely.union_all(layers["landuse"]["blocks"].geometry)
    assert shapely.area(shapely.intersection(houses, land)).sum() > 0.9 * shapely.area(houses).sum()


def test_monaco_builds_nothing_in_the_sea(tmp_path):
    layers, stats = _loadmap(DATA / "monaco.osm.pbf", tmp_path)
    water = layers["majorRoads"]["water"]
    sea = shapely.union_all(water.geometry[water["kind"] == "sea"])
    assert sea.area > 1e6  # the Mediterranean in the extract's box: some 280 ha
    assert shapely.area(shapely.intersection(layers["lots"]["lots"].geometry, sea)).sum() < 1e-3


@pytest.mark.slow
@pytest.mark.skipif(not LIEGE.exists(), reason="Liège street network not present")
def test_whole_liege_closes(tmp_path):
    layers, stats = _loadmap(LIEGE, tmp_path)
    _check_closes(layers, stats)


def test_same_seed_same_bytes(tmp_path):
    outs = []
    for k, workers in enumerate((1, 2)):
        out = tmp_path / f"o{k}"
        res = run_cli("osm", DATA / "kirchberg_iller.osm", "-o", out, "--workers", str(workers), "-q")
        assert res.returncode == 0, res.stderr
        outs.append(out)
    files = sorted(p.name for p in outs[0].iterdir() if p.name != "stats.json")
    assert files and files == sorted(p.name for p in outs[1].iterdir() if p.name != "stats.json")
    for f in files:
        assert (outs[0] / f).read_bytes() == (outs[1] / f).read_bytes(), f

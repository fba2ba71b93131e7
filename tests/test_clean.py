"""roads.clean: crossings on one level, duplicates, dead ends, slivers; properties on random grids."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from sengine import Context, Layer
from sengine.registry import get

DATA = Path(__file__).resolve().parent.parent / "configs" / "data"


def roads_of(lines, **cols):
    geoms = [shapely.LineString(c) for c in lines]
    n = len(geoms)
    base = {"class": np.full(n, "residential", dtype=object), "major": np.zeros(n, bool), "width": np.full(n, 10.0)}
    base.update({k: np.asarray(v) for k, v in cols.items()})
    return Layer.from_geoms(geoms, meta={"crs": "EPSG:32631"}, **base)


def clean(roads, **params):
    node = get("roads.clean")("clean", {k: str(v) for k, v in params.items()}, Context())
    out = node.run(roads=roads)
    return out, out.report


def faces_of(roads):
    polys = shapely.get_parts(shapely.polygonize(roads.geometry))
    return polys


def grid(nx_, ny_, step=100.0, over=30.0):
    """Long lines crossing each other with no shared vertex (OSM-style missing junctions)."""
    w, h = (nx_ - 1) * step, (ny_ - 1) * step
    vert = [[(i * step, -over), (i * step, h + over)] for i in range(nx_)]
    horz = [[(-over, j * step), (w + over, j * step)] for j in range(ny_)]
    return vert + horz


@settings(max_examples=25, deadline=None)
@given(st.integers(2, 6), st.integers(2, 6), st.floats(20.0, 200.0))
def test_random_grids_become_cells(nx_, ny_, step):
    out, rep = clean(roads_of(grid(nx_, ny_, step)))
    roads = out["roads"]
    assert rep["crossings_noded"] == nx_ * ny_
    # the overhanging arms are dead ends and go
    assert rep["dead_ends_removed"] == 2 * (nx_ + ny_)
    cells = faces_of(roads)
    assert len(cells) == (nx_ - 1) * (ny_ - 1)
    assert shapely.area(cells).sum() == pytest.approx((nx_ - 1) * (ny_ - 1) * step * step)
    # plane: no two output segments cross
    tree = shapely.STRtree(roads.geometry)
    i, j = tree.query(roads.geometry, predicate="crosses")
    assert len(i) == 0
    # every node has degree >= 2
    ends = np.r_[roads["u"], roads["v"]]
    assert np.bincount(ends).min(initial=2) >= 2 or set(np.unique(ends)) == set(ends)
    deg = np.bincount(ends)
    assert (deg[np.unique(ends)] >= 2).all()
    assert np.array_equal(
        roads.meta["nodes"][roads["u"]], shapely.get_coordinates(shapely.get_point(roads.geometry, 0))
    )


def test_bridges_and_other_levels_do_not_make_junctions():
    lines = grid(3, 3)
    diag = [(-10.0, -10.0), (210.0, 210.0)]  # crosses the whole grid without shared nodes
    n = len(lines) + 1
    bridge = np.zeros(n, bool)
    bridge[-1] = True
    out, rep = clean(roads_of(lines + [diag], bridge=bridge, layer=np.r_[np.zeros(n - 1), 1].astype(int)))
    assert rep["crossings_noded"] == 9  # grid only
    assert len(faces_of(out["roads"].take(~out["roads"]["bridge"]))) == 4
    # the same diagonal on the ground is noded everywhere it crosses
    out2, rep2 = clean(roads_of(lines + [diag]))
    assert rep2["crossings_noded"] > 9
    # and a diagonal on another layer (no bridge tag) is not
    out3, rep3 = clean(roads_of(lines + [diag], layer=np.r_[np.zeros(n - 1), -1].astype(int)))
    assert rep3["crossings_noded"] == 9


def test_tunnels_are_dropped_or_kept():
    lines = grid(3, 3)
    tunnel = np.zeros(len(lines), bool)
    tunnel[0] = True
    out, rep = clean(roads_of(lines, tunnel=tunnel))
    assert rep["tunnels_dropped"] == 1
    assert len(faces_of(out["roads"])) == 2
    out, rep = clean(roads_of(lines, tunnel=tunnel), tunnels="keep")
    assert rep["tunnels_dropped"] == 0


def test_duplicate_ways_merge_and_the_major_one_wins():
    square = [(0, 0), (100, 0), (100, 100), (0, 100), (0, 0)]
    lines = [square, square[::-1], [(0, 0), (50, 0.2), (100, 0)]]
    cls = np.array(["residential", "primary", "residential"], dtype=object)
    major = np.array([False, True, False])
    out, rep = clean(roads_of(lines, **{"class": cls, "major": major}))
    roads = out["roads"]
    assert rep["duplicates_merged"] >= 2
    cells = faces_of(roads)
    assert len(cells) == 1 and shapely.area(cells[0]) == pytest.approx(10_000.0)
    assert set(roads["class"]) == {"primary"}


def test_dead_ends_go_iteratively():
    square = [(0, 0), (100, 0), (100, 100), (0, 100), (0, 0)]
    tree = [[(100, 100), (150, 150)], [(150, 150), (200, 150)], [(150, 150), (150, 220)], [(200, 150), (260, 150)]]
    out, rep = clean(roads_of([square, *tree]))
    assert rep["dead_ends_removed"] == 4
    assert len(out["roads"]) >= 1
    assert shapely.length(out["roads"].geometry).sum() == pytest.approx(400.0)
    kept, rep = clean(roads_of([square, *tree]), dead_ends="false")
    assert rep["dead_ends_removed"] == 0
    assert shapely.length(kept["roads"].geometry).sum() > 600.0


def test_slivers_between_dual_carriageways_and_islands():
    # two blocks either side of a dual carriageway 6 m apart, and a small island
    lines = [
        [(0, 0), (200, 0)],
        [(0, 6), (200, 6)],  # the two carriageways
        [(0, -100), (0, 0), (0, 6), (0, 106)],
        [(200, -100), (200, 0), (200, 6), (200, 106)],
        [(0, -100), (200, -100)],
        [(0, 106), (200, 106)],
        [(80, 30), (90, 30), (85, 38), (80, 30)],
        [(85, 38), (85, 106)],
        [(80, 30), (80, 6)],  # island
    ]
    out, rep = clean(roads_of(lines), sliver_width=8, island_area=150)
    s = out["slivers"]
    assert rep["medians"] == 1 and rep["islands"] == 1 and rep["slivers_merged"] == 2
    assert sorted(s["kind"]) == ["island", "median"]
    median = s.geometry[s["kind"] == "median"][0]
    assert shapely.area(median) == pytest.approx(1200.0)
    assert rep["faces"] == 5


def test_known_topology_and_coordinates_give_the_same_result():
    out = get("osm.read")("r", {"path": str(DATA / "helsinki_centre.osm.pbf"), "extras": ""}, Context()).run()
    roads = out["roads"]
    by_ids, rep1 = clean(roads)
    plain = Layer.from_geoms(
        roads.geometry,
        meta=roads.meta,
        **{k: roads[k] for k in ("class", "major", "width", "layer", "bridge", "tunnel")},
    )
    by_xy, rep2 = clean(plain)
    assert rep1 == rep2
    assert len(by_ids["roads"]) == len(by_xy["roads"])
    a = np.sort(shapely.length(by_ids["roads"].geometry))
    b = np.sort(shapely.length(by_xy["roads"].geometry))
    assert np.allclose(a, b)


def test_empty_and_multilines():
    out, rep = clean(Layer.empty(**{"class": object, "major": bool, "width": float}))
    assert len(out["roads"]) == 0 and len(out["slivers"]) == 0
    multi = shapely.MultiLineString([[(0, 0), (100, 0), (100, 100)], [(100, 100), (0, 100), (0, 0)]])
    lay = Layer.from_geoms([multi], **{"class": np.array(["residential"], dtype=object), "major": False, "width": 8.0})
    out, rep = clean(lay)
    assert len(faces_of(out["roads"])) == 1

"""obj.roads and obj.lots: street networks and ready lots from OBJ files made in the test."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from sengine import CityPlan, Context, MapSpec
from sengine.errors import InputDataError
from sengine.nodes.maps import plan_inputs
from sengine.registry import get


def write_grid_lines(path: Path, nx_: int, ny_: int, step: float, *, up: str = "y", relative: bool = False) -> None:
    """A street grid as OBJ line elements: long lines through every node (shared vertices)."""
    verts = [(i * step, j * step) for j in range(ny_) for i in range(nx_)]
    out = ["# street grid", "o streets"]
    for x, y in verts:
        out.append(f"v {x} 0 {-y}" if up == "y" else f"v {x} {y} 0")
    vid = lambda i, j: j * nx_ + i + 1  # noqa: E731
    n = len(verts)
    for j in range(ny_):
        ids = [vid(i, j) for i in range(nx_)]
        out.append("l " + " ".join(str(k - n - 1 if relative else k) for k in ids))
    for i in range(nx_):
        out.append("l " + " ".join(str(vid(i, j)) for j in range(ny_)))
    path.write_text("\n".join(out) + "\n")


def write_lots(path: Path) -> None:
    """Three separate lots, Y-up: a quad, a pentagon, and an L made of two quads."""
    shapes = [
        [(0, 0), (20, 0), (20, 30), (0, 30)],
        [(30, 0), (50, 0), (55, 15), (40, 30), (30, 20)],
    ]
    out, k = [], 1
    for n, ring in enumerate(shapes):
        out.append(f"o lot{n}")
        out += [f"v {x} 0 {-y}" for x, y in ring]
        out.append("f " + " ".join(str(k + i) for i in range(len(ring))))
        k += len(ring)
    # an L-shaped lot made of two quads sharing an edge (shared vertices: one piece)
    out.append("o lotL")
    pts = [(60, 0), (80, 0), (80, 10), (60, 10), (60, 30), (70, 30), (70, 10)]
    out += [f"v {x} 0 {-y}" for x, y in pts]
    out.append(f"f {k} {k + 1} {k + 2} {k + 3}")
    out.append(f"f {k + 3} {k + 6} {k + 5} {k + 4}")
    path.write_text("\n".join(out) + "\n")


def node(name, path, **params):
    return get(name)("n", {"path": str(path), **{k: str(v) for k, v in params.items()}}, Context())


@settings(max_examples=10, deadline=None)
@given(st.integers(2, 6), st.integers(2, 6), st.floats(30.0, 150.0), st.booleans())
def test_obj_street_grid_gives_its_cells(tmp_path_factory, nx_, ny_, step, relative):
    path = tmp_path_factory.mktemp("obj") / "grid.obj"
    write_grid_lines(path, nx_, ny_, step, relative=relative)
    roads = node("obj.roads", path).run()["roads"]
    assert len(roads) == nx_ + ny_
    xy = shapely.get_coordinates(roads.geometry)
    assert xy[:, 1].min() == pytest.approx(0.0) and xy[:, 1].max() == pytest.approx((ny_ - 1) * step)
    cleaned = get("roads.clean")("clean", {}, Context()).run(roads=roads)["roads"]
    faces = get("blocks.circuits")("blocks", {"node": "false"}, Context()).run(roads=cleaned)["faces"]
    assert len(faces) == (nx_ - 1) * (ny_ - 1)
    assert faces.area() == pytest.approx((nx_ - 1) * (ny_ - 1) * step * step)


def test_up_axis_and_scale(tmp_path):
    write_grid_lines(tmp_path / "z.obj", 3, 2, 10.0, up="z")
    roads = node("obj.roads", tmp_path / "z.obj", up="z", scale=2.5).run()["roads"]
    xy = shapely.get_coordinates(roads.geometry)
    assert xy.max(axis=0) == pytest.approx([50.0, 25.0])
    assert roads.meta["crs"].startswith("+proj=tmerc")


def test_obj_lots_are_one_polygon_per_piece(tmp_path):
    path = tmp_path / "lots.obj"
    write_lots(path)
    out = node("obj.lots", path).run()
    lots = out["lots"]
    assert len(lots) == 3 and len(out["blocks"]) == 3
    areas = np.sort(shapely.area(lots.geometry))
    assert areas == pytest.approx(
        np.sort([600.0, shapely.Polygon([(30, 0), (50, 0), (55, 15), (40, 30), (30, 20)]).area, 400.0])
    )
    assert shapely.is_valid(lots.geometry).all()
    assert set(lots["method"]) == {"obj"} and (lots["block"] == -1).all()
    # the L piece keeps its concave corner: its convex hull is larger
    lshape = lots.geometry[np.argmin(np.abs(shapely.area(lots.geometry) - 400.0))]
    assert shapely.area(shapely.convex_hull(lshape)) > 450.0
    buildings = get("buildings.extrude")("b", {}, Context()).run(lots=lots)["buildings"]
    assert len(buildings) >= 1
    assert shapely.within(shapely.buffer(buildings.geometry, -0.01), shapely.union_all(lots.geometry)).all()


def test_plan_map_and_errors(tmp_path):
    path = tmp_path / "grid.obj"
    write_grid_lines(path, 3, 3, 50.0)
    plan = CityPlan(maps={"obj": MapSpec("obj", path, {}, "city.xml:5")})
    roads = get("obj.roads")("n", {}, Context(plan=plan))
    assert len(roads.run(**plan_inputs(plan, roads))["roads"]) == 6
    lots_node = get("obj.lots")("n", {}, Context(plan=plan))
    with pytest.raises(InputDataError, match="no faces") as exc:
        lots_node.run(**plan_inputs(plan, lots_node))
    assert "city.xml:5" in str(exc.value) and "grid.obj" in str(exc.value)
    lots = tmp_path / "lots.obj"
    write_lots(lots)
    with pytest.raises(InputDataError, match="no line elements"):
        node("obj.roads", lots).run()
    with pytest.raises(InputDataError, match="does not exist"):
        node("obj.roads", tmp_path / "none.obj").run()
    garbage = tmp_path / "garbage.obj"
    garbage.write_bytes(np.random.default_rng(0).bytes(3000))
    with pytest.raises(InputDataError, match="garbage.obj") as exc:
        node("obj.roads", garbage).run()
    assert "\n" not in str(exc.value)
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nl 1 7\n")
    with pytest.raises(InputDataError, match="does not exist"):
        node("obj.roads", bad).run()
    text = tmp_path / "text.obj"
    text.write_text("hello\n")
    with pytest.raises(InputDataError, match="no vertices"):
        node("obj.lots", text).run()

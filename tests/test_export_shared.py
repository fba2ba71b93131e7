"""What the exporter makes once and shares: the roofs, the glb's and the page's surfaces, column encodings.

The files must not depend on which process made what: the same bytes for
any number of workers, and the fast column encodings equal to the plain
Python ones they replaced.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from _city import grid_city
from hypothesis import given, settings
from hypothesis import strategies as st

from sengine import Context, Layer
from sengine.nodes.export import gltf, mesh, roofs
from sengine.nodes.export.prepare import _empty
from sengine.registry import get

Export = get("export.city")
Extrude = get("buildings.extrude")
FORMATS = frozenset({"glb", "geojson", "osm", "png", "obj", "cityjson", "html"})


@pytest.fixture(scope="module")
def city(tmp_path_factory):
    plan, layers = grid_city(nx=5, ny=4, height_map=tmp_path_factory.mktemp("maps"))
    b = Extrude("buildings", {}, Context(seed=3, plan=plan)).run(lots=layers["lots"])["buildings"]
    kinds = np.array(["gable", "hip", "flat", None], dtype=object)[np.arange(len(b)) % 4]
    layers["buildings"] = Layer(b.geometry, b.ids, b.parent, {**b.attrs, "roof": kinds}, dict(b.meta))
    return plan, layers


def _export(out, plan, layers, workers: int) -> dict:
    ctx = Context(seed=3, plan=plan, out=out, formats=FORMATS, workers=workers)
    return dict(Export("export", {"lod": 2}, ctx).run(**layers).report)


def test_same_bytes_for_any_workers(city, tmp_path):
    plan, layers = city
    one = _export(tmp_path / "1", plan, layers, 1)
    two = _export(tmp_path / "2", plan, layers, 2)
    three = _export(tmp_path / "3", plan, layers, 3)
    assert one == two == three
    assert one["glb.buildings.triangles"] > 12 * len(layers["buildings"]) // 2  # roofs and walls were drawn
    files = sorted(p.name for p in (tmp_path / "1").iterdir())
    assert {"city.glb", "city.obj", "buildings.city.json", "city.view.js", "index.html"} <= set(files)
    for name in files:
        a = (tmp_path / "1" / name).read_bytes()
        assert a == (tmp_path / "2" / name).read_bytes() == (tmp_path / "3" / name).read_bytes(), name
    assert not roofs._SHARED and not gltf._SURFACES  # nothing kept after the export


def test_layer_surfaces_are_the_meshes_and_shared_ones_are_reused(city):
    _, layers = city
    lots, roads = layers["lots"], layers["roads"]
    flat, ribbons = gltf.layer_surfaces("lots", lots)
    assert ribbons is None
    v, f, vf = mesh.flat(lots.geometry, gltf.LEVELS["lots"])
    assert np.array_equal(flat[0], v) and np.array_equal(flat[1], f) and np.array_equal(flat[2], vf)
    # the triangles cover the lots: area within 1e-6 relative
    tri = flat[0][flat[1]][:, :, :2]
    a, b = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    area = 0.5 * np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]).sum()
    assert math.isclose(area, float(shapely.area(lots.geometry).sum()), rel_tol=1e-6)
    _, rib = gltf.layer_surfaces("roads", roads, line_width=2.0)
    assert len(rib[1]) >= 2 * len(roads) and set(np.unique(rib[2])) == set(range(len(roads)))
    made = gltf.make_surfaces({"lots": lots, "roads": roads}, line_width=2.0)
    with gltf.shared_surfaces({"lots": lots, "roads": roads}, made, line_width=2.0):
        assert gltf.layer_surfaces("lots", lots, line_width=2.0) is made["lots"]
        assert gltf.layer_surfaces("roads", roads, line_width=1.0) is not made["roads"]  # another width
    assert not gltf._SURFACES


VALUES = st.one_of(
    st.none(),
    st.text(max_size=4),
    st.sampled_from(["", "a", "é", "ß", "residential", "1", "1.0", "True"]),
    st.integers(-3, 3),
    st.floats(allow_nan=True, allow_infinity=True, width=32),
    st.booleans(),
)


def _enum_reference(col):
    text = np.array(["" if v is None else str(v) for v in col.tolist()], dtype=object)
    names, codes = np.unique(text, return_inverse=True)
    if len(names) > 255 or (names == "").any():
        return None
    return [str(n) for n in names], codes


@settings(max_examples=200, deadline=None)
@given(st.lists(VALUES, min_size=1, max_size=60))
def test_enum_column_equals_the_python_loop(values):
    col = np.array(values + [object()], dtype=object)[:-1]  # an object array whatever the values
    got, want = gltf._enum_column(col), _enum_reference(col)
    assert (got is None) == (want is None)
    if got is not None:
        assert got[0] == want[0] and np.array_equal(got[1], want[1])


@settings(max_examples=200, deadline=None)
@given(st.lists(VALUES, max_size=60))
def test_utf8_texts_equal_the_python_loop(values):
    col = np.array(values + [object()], dtype=object)[:-1]
    want = [
        b"" if v is None or (isinstance(v, float) and not np.isfinite(v)) else str(v).encode("utf-8") for v in values
    ]
    assert gltf._utf8(col) == want


@settings(max_examples=200, deadline=None)
@given(st.lists(st.one_of(VALUES, st.builds(lambda: shapely.Point(0, 0))), max_size=60))
def test_empty_values_equal_the_python_loop(values):
    col = np.array(values + [object()], dtype=object)[:-1]
    want = [v is None or (isinstance(v, str) and v == "") for v in values]
    assert _empty(col).tolist() == want
    arrays = np.array([np.arange(2), None, ""] + [object()], dtype=object)[:-1]  # comparisons that are no truth value
    assert _empty(arrays).tolist() == [False, True, True]

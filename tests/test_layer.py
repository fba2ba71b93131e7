"""sengine.Layer, method by method: construction, dtypes, defaults, lookups and conversions.

Unit tests with exact numbers (ids, dtypes, fill values, coordinates) so a
changed default, dtype or key in layer.py fails here in well under a second.
"""

from __future__ import annotations

import sys

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from sengine import Layer


def boxes(n: int, size: float = 10.0) -> list:
    return [shapely.box(20.0 * i, 0.0, 20.0 * i + size, size) for i in range(n)]


# -- construction -------------------------------------------------------------


def test_from_geoms_defaults_and_dtypes():
    lay = Layer.from_geoms(boxes(3))
    assert lay.geometry.dtype == object and len(lay) == 3
    assert lay.ids.dtype == np.int64 and lay.ids.tolist() == [0, 1, 2]
    assert lay.parent.dtype == np.int64 and lay.parent.tolist() == [-1, -1, -1]
    assert lay.columns == [] and dict(lay.meta) == {}


def test_from_geoms_takes_generators_arrays_and_casts_ids():
    gen = Layer.from_geoms(g for g in boxes(2))  # a one-shot iterable
    assert len(gen) == 2 and gen.geometry[1].equals(boxes(2)[1])
    arr = np.empty(2, object)
    arr[:] = boxes(2)
    lay = Layer.from_geoms(arr, ids=np.array([7, 9], np.int32), parent=np.array([1.0, 2.0]))
    assert lay.ids.dtype == np.int64 and lay.ids.tolist() == [7, 9]
    assert lay.parent.dtype == np.int64 and lay.parent.tolist() == [1, 2]
    scalar = Layer.from_geoms(boxes(3), parent=4, meta={"crs": "EPSG:32631"})
    assert scalar.parent.tolist() == [4, 4, 4] and scalar.meta == {"crs": "EPSG:32631"}


def test_scalar_columns_broadcast_with_their_value():
    lay = Layer.from_geoms(boxes(3), h=2.5, n=3, kind="lot", flag=True, obj=None)
    assert lay["h"].tolist() == [2.5] * 3 and lay["h"].dtype.kind == "f"
    assert lay["n"].tolist() == [3] * 3 and lay["n"].dtype.kind == "i"
    assert lay["kind"].tolist() == ["lot"] * 3 and lay["kind"].dtype.kind == "U"
    assert lay["flag"].tolist() == [True] * 3 and lay["flag"].dtype == bool
    assert lay["obj"].tolist() == [None] * 3 and lay["obj"].dtype == object
    geom = shapely.Point(1, 2)
    assert all(g is geom for g in lay.with_columns(anchor=np.asarray(geom, dtype=object))["anchor"])


def test_length_errors_name_the_column():
    with pytest.raises(ValueError, match=r"^ids has length 2, expected 3$"):
        Layer(np.empty(3, object), np.zeros(2, np.int64), np.zeros(3, np.int64))
    with pytest.raises(ValueError, match=r"^parent has length 4, expected 3$"):
        Layer(np.empty(3, object), np.zeros(3, np.int64), np.zeros(4, np.int64))
    with pytest.raises(ValueError, match=r"^column 'h' has length 1, expected 3$"):
        Layer(np.empty(3, object), np.zeros(3, np.int64), np.zeros(3, np.int64), {"h": np.zeros(1)})
    with pytest.raises(ValueError, match=r"^column 'parent' has shape \(2,\), expected \(3,\)$"):
        Layer.from_geoms(boxes(3), parent=[1, 2])
    with pytest.raises(ValueError, match=r"^column 'width' has shape \(2,\), expected \(3,\)$"):
        Layer.from_geoms(boxes(3), width=[1.0, 2.0])
    with pytest.raises(ValueError, match=r"^column 'width' has shape \(4,\), expected \(3,\)$"):
        Layer.from_geoms(boxes(3)).with_columns(width=np.ones(4))


def test_empty_is_typed():
    lay = Layer.empty(meta={"crs": "EPSG:2154"}, h=np.float32, n=np.int16)
    assert len(lay) == 0 and lay.meta == {"crs": "EPSG:2154"}
    assert lay.geometry.dtype == object and lay.ids.dtype == np.int64 and lay.parent.dtype == np.int64
    assert lay["h"].dtype == np.float32 and lay["n"].dtype == np.int16 and lay.columns == ["h", "n"]
    assert Layer.empty().meta == {} and lay.area() == 0.0


def test_concat_fills_missing_columns_with_typed_defaults():
    a = Layer.from_geoms(
        boxes(2),
        ids=[5, 6],
        parent=[1, 2],
        meta={"crs": "A", "k": 1},
        f=np.array([1.5, 2.5]),
        i=np.array([3, 4], np.int32),
        b=np.array([True, True]),
        s=np.array(["x", "y"]),
        o=np.array([{"a": 1}, {"b": 2}], dtype=object),
    )
    b = Layer.from_geoms(boxes(3), ids=[7, 8, 9], meta={"crs": "B"}, extra=np.array([1, 2, 3], np.uint8))
    c = Layer.concat([a, b])
    assert c.columns == ["f", "i", "b", "s", "o", "extra"]
    assert np.array_equal(c["f"][:2], [1.5, 2.5]) and np.isnan(c["f"][2:]).all() and c["f"].dtype == np.float64
    assert c["i"].tolist() == [3, 4, -1, -1, -1] and c["i"].dtype == np.int32
    assert c["b"].tolist() == [True, True, False, False, False] and c["b"].dtype == bool
    assert c["s"].tolist() == ["x", "y", "", "", ""] and c["s"].dtype.kind == "U"
    assert c["o"].tolist() == [{"a": 1}, {"b": 2}, None, None, None] and c["o"].dtype == object
    assert c["extra"].tolist() == [255, 255, 1, 2, 3] and c["extra"].dtype == np.uint8  # -1 wraps in unsigned
    assert c.ids.tolist() == [0, 1, 2, 3, 4] and c.ids.dtype == np.int64
    assert c.parent.tolist() == [1, 2, -1, -1, -1]
    assert c.meta == {"crs": "B", "k": 1}  # later layers win
    kept = Layer.concat(iter([a, b]), renumber=False)
    assert kept.ids.tolist() == [5, 6, 7, 8, 9] and kept.meta == {"crs": "B", "k": 1}
    assert len(Layer.concat([])) == 0 and Layer.concat([]).columns == []


# -- access ---------------------------------------------------------------------


def test_item_access_membership_and_get():
    lay = Layer.from_geoms(boxes(2), ids=[3, 4], parent=[0, 1], h=[1.0, 2.0])
    assert lay["id"] is lay.ids and lay["parent_id"] is lay.parent and lay["h"].tolist() == [1.0, 2.0]
    assert "id" in lay and "parent_id" in lay and "h" in lay and "ids" not in lay and "w" not in lay
    assert lay.get("h").tolist() == [1.0, 2.0] and lay.get("w") is None and lay.get("w", 0) == 0
    with pytest.raises(KeyError):
        lay["w"]


def test_rows_of_finds_unsorted_ids_and_reports_missing():
    lay = Layer.from_geoms(boxes(5), ids=[40, 10, 30, 20, 50])
    assert lay.rows_of([10, 20, 30, 40, 50]).tolist() == [1, 3, 2, 0, 4]
    assert lay.rows_of([5, 15, 55, 50, -1, 10**12]).tolist() == [-1, -1, -1, 4, -1, -1]
    assert lay.rows_of(np.array([30.0])).tolist() == [2] and lay.rows_of([]).tolist() == []
    assert lay.rows_of([20]).dtype == np.int64
    empty = Layer.empty().rows_of([1, 2])
    assert empty.tolist() == [-1, -1] and empty.dtype == np.int64
    one = Layer.from_geoms(boxes(1), ids=[7])
    assert one.rows_of([6, 7, 8]).tolist() == [-1, 0, -1]


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(-1000, 1000), unique=True, max_size=30), st.lists(st.integers(-1100, 1100), max_size=30))
def test_rows_of_is_the_index_of_each_id(ids, queries):
    lay = Layer.from_geoms([shapely.Point(0, 0)] * len(ids), ids=ids)
    where = {v: i for i, v in enumerate(ids)}
    assert lay.rows_of(queries).tolist() == [where.get(q, -1) for q in queries]


def test_take_with_columns_geometry_and_meta_copy_everything_else():
    lay = Layer.from_geoms(boxes(3), ids=[4, 5, 6], parent=[1, 1, 2], meta={"crs": "X"}, h=[1.0, 2.0, 3.0])
    sub = lay.take(np.array([True, False, True]))
    assert sub.ids.tolist() == [4, 6] and sub.parent.tolist() == [1, 2] and sub["h"].tolist() == [1.0, 3.0]
    assert sub.meta == {"crs": "X"} and sub.meta is not lay.meta and sub.geometry[1].equals(lay.geometry[2])
    assert lay.take([2, 0]).ids.tolist() == [6, 4]

    wc = lay.with_columns(w=7.0, h=[9.0, 8.0, 7.0])
    assert wc.columns == ["h", "w"] and wc["w"].tolist() == [7.0] * 3 and wc["h"].tolist() == [9.0, 8.0, 7.0]
    assert wc.geometry is lay.geometry and wc.ids is lay.ids and wc.parent is lay.parent
    assert wc.meta == {"crs": "X"} and lay.columns == ["h"]  # the input is unchanged

    new = [shapely.box(0, 0, 1, 1), shapely.box(0, 0, 2, 2), shapely.box(0, 0, 3, 3)]
    wg = lay.with_geometry(new)
    assert wg.geometry.dtype == object and wg.geometry.shape == (3,) and wg.area() == pytest.approx(14.0)
    assert wg.ids is lay.ids and wg.parent is lay.parent and wg.columns == ["h"] and wg.meta == {"crs": "X"}
    assert lay.area() == pytest.approx(300.0)
    with pytest.raises(ValueError):
        lay.with_geometry(new[:2])

    wm = lay.with_meta(origin=(50.6, 5.57), crs="Y")
    assert wm.meta == {"crs": "Y", "origin": (50.6, 5.57)} and lay.meta == {"crs": "X"}
    assert wm.geometry is lay.geometry and wm.ids is lay.ids and wm.parent is lay.parent and wm.columns == ["h"]


def test_area_sums_polygons_and_is_zero_for_lines():
    assert Layer.from_geoms(boxes(4, size=3.0)).area() == pytest.approx(36.0)
    assert Layer.from_geoms([shapely.LineString([(0, 0), (5, 0)])]).area() == 0.0
    assert isinstance(Layer.from_geoms(boxes(1)).area(), float)


# -- GeoJSON ----------------------------------------------------------------------


def test_geojson_round_trip_and_precision():
    lay = Layer.from_geoms(
        [shapely.Point(1.23456, 2.5), shapely.Point(3.0, 4.0)], ids=[8, 9], parent=[3, -1], kind=["a", "b"]
    )
    data = lay.to_geojson(precision=2)
    assert data["features"][0]["geometry"]["coordinates"] == [1.23, 2.5]
    assert lay.to_geojson()["features"][0]["geometry"]["coordinates"] == [1.23456, 2.5]
    fine = Layer.from_geoms([shapely.Point(1.123456789, 0.0)]).to_geojson()  # 7 decimals by default
    assert fine["features"][0]["geometry"]["coordinates"] == [1.1234568, 0.0]
    shifted = lay.to_geojson(lambda xy: xy + 100.0)
    assert shifted["features"][1]["geometry"]["coordinates"] == [103.0, 104.0]
    back = Layer.from_geojson(lay.to_geojson())
    assert back.ids.tolist() == [8, 9] and back.parent.tolist() == [3, -1] and back["kind"].tolist() == ["a", "b"]


def test_from_geojson_fills_ids_parents_and_sparse_properties():
    pt = {"type": "Point", "coordinates": [1.0, 2.0]}
    data = {
        "type": "FeatureCollection",
        "features": [
            {"type": "Feature", "geometry": pt, "properties": {"parent_id": None, "a": 1}},
            {"type": "Feature", "geometry": pt, "properties": {"b": "x"}},
            {"type": "Feature", "geometry": pt, "properties": None},
            {"type": "Feature", "geometry": pt, "properties": {"id": 40, "parent_id": 2, "a": 3}},
        ],
    }
    lay = Layer.from_geojson(data)
    assert lay.ids.tolist() == [0, 1, 2, 40] and lay.parent.tolist() == [-1, -1, -1, 2]
    assert lay.columns == ["a", "b"]
    assert lay["a"].tolist() == [1, None, None, 3] and lay["b"].tolist() == [None, "x", None, None]
    assert shapely.get_coordinates(lay.geometry).tolist() == [[1.0, 2.0]] * 4
    empty = Layer.from_geojson({"type": "FeatureCollection"})
    assert len(empty) == 0 and empty.columns == []
    assert len(Layer.from_geojson({"features": []})) == 0


# -- geopandas and networkx ---------------------------------------------------------


def test_geopandas_bool_objects_crs_and_meta():
    gpd = pytest.importorskip("geopandas")
    pd = pytest.importorskip("pandas")
    gdf = gpd.GeoDataFrame(
        {"flag": pd.Series([True, False], dtype=object), "mixed": pd.Series([True, "x"], dtype=object)},
        geometry=gpd.GeoSeries(boxes(2)),
        crs="EPSG:32631",
    )
    lay = Layer.from_geopandas(gdf)
    assert lay["flag"].dtype == bool and lay["flag"].tolist() == [True, False]
    assert lay["mixed"].dtype == object and lay["mixed"].tolist() == [True, "x"]
    assert lay.ids.tolist() == [0, 1] and lay.parent.tolist() == [-1, -1]
    assert lay.meta == {"crs": "EPSG:32631"} and lay.geometry.dtype == object
    assert Layer.from_geopandas(gdf, meta={"crs": "EPSG:2154", "k": 1}).meta == {"crs": "EPSG:2154", "k": 1}
    # a crs carried in the frame's sengine meta wins over the frame's own
    gdf.attrs["sengine_meta"] = {"crs": "EPSG:32631", "origin": (1, 2)}
    gdf2 = gdf.to_crs(4326)
    gdf2.attrs["sengine_meta"] = {"crs": "custom", "origin": (1, 2)}
    assert Layer.from_geopandas(gdf2).meta == {"crs": "custom", "origin": (1, 2)}
    first = gpd.GeoDataFrame({"geometry": gpd.GeoSeries(boxes(1)), "a": [1], "b": ["x"]}, geometry="geometry")
    assert Layer.from_geopandas(first).columns == ["a", "b"]  # columns after the geometry are kept
    none = gpd.GeoDataFrame({"v": [1]}, geometry=gpd.GeoSeries(boxes(1)))
    assert Layer.from_geopandas(none).meta == {} and Layer.from_geopandas(none).columns == ["v"]
    empty = gpd.GeoDataFrame({"flag": pd.Series([], dtype=object)}, geometry=gpd.GeoSeries([]))
    assert Layer.from_geopandas(empty)["flag"].dtype == object


def test_geopandas_keeps_plain_meta_only():
    pytest.importorskip("geopandas")
    meta = {"s": "x", "i": 1, "f": 1.5, "b": True, "n": None, "t": (1, "a"), "arr": np.zeros(2), "bad": ([1],)}
    meta["l"] = [1, 2]
    gdf = Layer.from_geoms(boxes(1), meta=meta).to_geopandas()
    assert gdf.attrs["sengine_meta"] == {"s": "x", "i": 1, "f": 1.5, "b": True, "n": None, "t": (1, "a")}
    assert gdf.crs is None


def test_to_geopandas_names_the_missing_dependency(monkeypatch):
    monkeypatch.setitem(sys.modules, "geopandas", None)  # as if not installed
    with pytest.raises(ImportError, match=r"^Layer\.to_geopandas needs geopandas: pip install 'sengine\[geo\]'$"):
        Layer.from_geoms(boxes(1)).to_geopandas()


def test_networkx_from_junction_columns():
    pytest.importorskip("networkx")
    lines = [shapely.LineString([(0, 0), (10, 0)]), shapely.LineString([(10, 0), (10, 5), (10, 10)])]
    # the node table's own numbering (not the sorted end points): junction 0 is (10, 10)
    nodes = np.array([[10.0, 10.0], [0.0, 0.0], [10.0, 0.0]])
    lay = Layer.from_geoms(
        lines,
        ids=[11, 12],
        meta={"nodes": nodes.ravel().tolist(), "crs": "EPSG:32631"},
        u=np.array([1.0, 2.0]),
        v=np.array([2.0, 0.0]),
        name=np.array(["a", "b"], dtype=object),
        width=np.array([4, 6], np.int32),
    )
    g = lay.to_networkx()
    assert g.graph["crs"] == "EPSG:32631"
    assert sorted(g.nodes(data=True)) == [
        (0, {"x": 10.0, "y": 10.0}),
        (1, {"x": 0.0, "y": 0.0}),
        (2, {"x": 10.0, "y": 0.0}),
    ]
    assert all(type(k) is int for k in g.nodes)
    edges = sorted(g.edges(keys=True, data=True), key=lambda e: e[2])
    assert [(min(u, v), max(u, v), k) for u, v, k, _ in edges] == [(1, 2, 11), (0, 2, 12)]
    data = edges[1][3]
    assert data["length"] == 10.0 and data["name"] == "b" and data["width"] == 6 and type(data["width"]) is int
    assert data["u"] == 2.0 and type(data["u"]) is float and data["geometry"].equals(lines[1])
    # junction columns without the node table: the end points are the nodes
    g2 = Layer.from_geoms(lines, u=[0, 1], v=[1, 2]).to_networkx()
    assert g2.number_of_nodes() == 3 and g2.graph["crs"] is None
    assert sorted((d["x"], d["y"]) for _, d in g2.nodes(data=True)) == [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0)]
    # the node table without one of the junction columns is not used
    only_u = Layer.from_geoms(lines, u=[5, 6], meta={"nodes": [[0.0, 0.0]]}).to_networkx()
    assert only_u.number_of_nodes() == 3
    only_v = Layer.from_geoms(lines, v=[5, 6], meta={"nodes": [[0.0, 0.0]]}).to_networkx()
    assert only_v.number_of_nodes() == 3
    both = Layer.from_geoms(lines, u=[1, 2], v=[2, 0], meta={"nodes": nodes})
    g3 = both.to_networkx()
    assert sorted(g3.edges(keys=True)) == [(0, 2, 1), (1, 2, 0)] and g3.nodes[0] == {"x": 10.0, "y": 10.0}
    empty = Layer.empty(u=np.int64, v=np.int64, meta={"nodes": np.zeros((0, 2))}).to_networkx()
    assert empty.number_of_nodes() == 0 and empty.number_of_edges() == 0
    assert Layer.empty().to_networkx().number_of_edges() == 0

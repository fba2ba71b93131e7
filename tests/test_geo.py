"""geopandas both ways, ``__geo_interface__`` and the street graph as networkx (issue 15, part 5)."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from conftest import DATA
from hypothesis import given, settings
from hypothesis import strategies as st

from sengine import Context, Layer
from sengine.registry import get

gpd = pytest.importorskip("geopandas")


def polygon_with_hole(x, y, w, h, hole):
    outer = shapely.box(x, y, x + w, y + h)
    if hole:
        return shapely.difference(outer, shapely.box(x + w / 4, y + h / 4, x + w / 2, y + h / 2))
    return outer


layers = st.lists(
    st.tuples(
        st.floats(-1e4, 1e4),
        st.floats(-1e4, 1e4),
        st.floats(0.5, 500),
        st.floats(0.5, 500),
        st.booleans(),
        st.integers(-5, 10**9),
        st.sampled_from(["lot", "park", "ünïcode", ""]),
        st.floats(-1e6, 1e6),
    ),
    min_size=0,
    max_size=12,
)


@settings(max_examples=40, deadline=None)
@given(layers)
def test_geopandas_round_trip(rows):
    geoms = [polygon_with_hole(x, y, w, h, hole) for x, y, w, h, hole, *_ in rows]
    n = len(rows)
    lay = Layer.from_geoms(
        geoms,
        ids=np.arange(n) * 7 + 3,
        parent=np.array([r[5] for r in rows], np.int64),
        meta={"crs": "EPSG:32631", "origin": (50.6, 5.57), "nodes": np.zeros((2, 2))},
        kind=np.array([r[6] for r in rows], dtype=object),
        value=np.array([r[7] for r in rows], float),
        hole=np.array([r[4] for r in rows], bool),
        count=np.arange(n, dtype=np.int64),
    )
    gdf = lay.to_geopandas()
    assert len(gdf) == n and list(gdf.columns) == ["id", "parent_id", "kind", "value", "hole", "count", "geometry"]
    assert gdf.crs is not None and gdf.crs.to_epsg() == 32631
    back = Layer.from_geopandas(gdf)
    assert np.array_equal(back.ids, lay.ids) and np.array_equal(back.parent, lay.parent)
    assert back.columns == lay.columns
    for name in lay.columns:
        assert list(back[name]) == list(lay[name]), name
    assert back["value"].dtype.kind == "f" and back["hole"].dtype.kind == "b" and back["count"].dtype.kind == "i"
    assert all(shapely.equals_exact(back.geometry, lay.geometry, 0.0)) if n else len(back) == 0
    assert back.meta["crs"] == "EPSG:32631" and back.meta["origin"] == (50.6, 5.57)
    assert "nodes" not in back.meta  # arrays stay behind: the meta carried is plain data


@settings(max_examples=20, deadline=None)
@given(layers)
def test_geo_interface_is_the_features(rows):
    geoms = [polygon_with_hole(x, y, w, h, hole) for x, y, w, h, hole, *_ in rows]
    lay = Layer.from_geoms(geoms, kind=np.array([r[6] for r in rows], dtype=object))
    fc = lay.__geo_interface__
    assert fc["type"] == "FeatureCollection" and len(fc["features"]) == len(lay)
    for f, g, kind in zip(fc["features"], lay.geometry, lay["kind"] if len(lay) else []):
        assert shapely.geometry.shape(f["geometry"]).equals(g)
        assert f["properties"]["kind"] == kind
    if len(lay):  # geopandas reads the interface too
        assert len(gpd.GeoDataFrame.from_features(fc)) == len(lay)


def test_a_real_street_layer_round_trips_and_projects():
    roads = get("osm.read")("r", {"path": str(DATA / "monaco.osm.pbf"), "extras": ""}, Context()).run()["roads"]
    gdf = roads.to_geopandas()
    assert gdf.crs.to_epsg() == 32632
    lonlat = gdf.to_crs(4326)
    minx, miny, maxx, maxy = lonlat.total_bounds
    assert 7.38 < minx < maxx < 7.45 and 43.71 < miny < maxy < 43.76  # Monaco
    back = Layer.from_geopandas(gdf)
    assert np.array_equal(back["u"], roads["u"]) and list(back["class"]) == list(roads["class"])
    assert shapely.equals_exact(back.geometry, roads.geometry, 0.0).all()


def test_street_graph_as_networkx():
    lines = [shapely.LineString([(x, 0), (x, 200)]) for x in (0, 100, 200)]
    lines += [shapely.LineString([(0, y), (200, y)]) for y in (0, 100, 200)]
    roads = Layer.from_geoms(lines, width=np.full(6, 10.0))
    cleaned = get("roads.clean")("c", {"dead_ends": "false"}, Context()).run(roads=roads)["roads"]
    g = cleaned.to_networkx()
    assert g.number_of_nodes() == 9 and g.number_of_edges() == 12 == len(cleaned)
    assert sorted(d for _, d in g.degree()) == [2] * 4 + [3] * 4 + [4]
    for u, v, data in g.edges(data=True):
        ends = {(g.nodes[u]["x"], g.nodes[u]["y"]), (g.nodes[v]["x"], g.nodes[v]["y"])}
        coords = shapely.get_coordinates(data["geometry"])
        assert ends == {tuple(coords[0]), tuple(coords[-1])}
        assert data["length"] == pytest.approx(100.0) and data["width"] == 10.0
    # without junction columns the nodes are the distinct end points
    g2 = roads.to_networkx()
    assert g2.number_of_nodes() == 8 and g2.number_of_edges() == 6  # corners and mid-sides: not noded
    assert Layer.empty().to_networkx().number_of_nodes() == 0

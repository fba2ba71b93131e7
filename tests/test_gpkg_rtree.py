"""The GeoPackage's spatial index (issue 16): packed in numpy, written into SQLite's R*Tree tables.

What a user relies on is checked with the tools they have: SQLite's own
``rtreecheck`` and ``integrity_check``, GDAL (pyogrio) reporting a fast
spatial filter, bounding-box reads equal to those of the same rows in a
file whose index GDAL built itself, and GDAL adding rows to a table whose
index it did not write.
"""

from __future__ import annotations

import sqlite3

import numpy as np
import pyogrio
import pytest
import shapely
from conftest import DATA
from hypothesis import given, settings
from hypothesis import strategies as st

from sengine import Layer
from sengine.cli import main
from sengine.nodes.export.gpkg import RTREE_MAXCELLS, pack_rtree, rtree_boxes, write_gpkg_layer, write_rtree

SAME = lambda xy: xy  # noqa: E731


def _table(path, n: int) -> None:
    """A table and its ``gpkg_geometry_columns`` row: what :func:`write_rtree` needs of a GeoPackage."""
    con = sqlite3.connect(path)
    con.execute("CREATE TABLE gpkg_geometry_columns (table_name TEXT, column_name TEXT)")
    con.execute("INSERT INTO gpkg_geometry_columns VALUES ('t', 'geom')")
    con.execute('CREATE TABLE t ("id" INTEGER PRIMARY KEY, geom BLOB)')
    con.commit()
    con.close()


@st.composite
def boxes(draw):
    n = draw(st.sampled_from([0, 1, 2, 50, 51, 52, 700, 2602, 2700]))  # 2602 > 51**2: three levels
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    origin = draw(st.sampled_from([0.0, -180.0, 500_000.0, 4_500_000.0]))
    spread = draw(st.sampled_from([1e-6, 1.0, 10_000.0]))
    lo = origin + rng.random((n, 2)) * spread
    size = rng.random((n, 2)) * spread * draw(st.sampled_from([0.0, 0.01, 0.5]))  # 0: points
    ids = rng.permutation(n * 3)[:n].astype(np.int64) + draw(st.sampled_from([0, 5_707_200_000, 2**40]))
    if draw(st.booleans()):  # ascending, as a table's rows come: pack_rtree places them without a sort
        ids = np.sort(ids)
    return ids, np.column_stack([lo, lo + size])


@settings(max_examples=30, deadline=None)
@given(boxes(), st.integers(0, 2**32 - 1))
def test_packed_rtree_is_what_sqlite_checks_and_queries(tmp_path_factory, data, seed):
    ids, bounds = data
    path = tmp_path_factory.mktemp("rt") / "t.gpkg"
    _table(path, len(ids))
    write_rtree(path, "t", ids, bounds)
    con = sqlite3.connect(path)
    assert con.execute("SELECT rtreecheck('rtree_t_geom')").fetchone()[0] == "ok"
    assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    assert con.execute("SELECT count(*) FROM rtree_t_geom").fetchone()[0] == len(ids)
    depth = int.from_bytes(con.execute("SELECT data FROM rtree_t_geom_node WHERE nodeno = 1").fetchone()[0][:2], "big")
    assert depth == (0 if len(ids) <= RTREE_MAXCELLS else 1 if len(ids) <= RTREE_MAXCELLS**2 else 2)
    # every box holds its feature's bounds, and a window query gives what a scan of the boxes gives
    got = np.array(con.execute("SELECT id, minx, maxx, miny, maxy FROM rtree_t_geom ORDER BY id").fetchall()).reshape(
        -1, 5
    )
    order = np.argsort(ids)
    assert np.array_equal(got[:, 0].astype(np.int64), ids[order])
    b = bounds[order]
    assert (got[:, 1] <= b[:, 0]).all() and (got[:, 2] >= b[:, 2]).all()
    assert (got[:, 3] <= b[:, 1]).all() and (got[:, 4] >= b[:, 3]).all()
    f32 = rtree_boxes(bounds).astype(np.float64)
    rng = np.random.default_rng(seed)
    if len(ids):
        x0, y0 = bounds[:, :2].min(axis=0)
        x1, y1 = bounds[:, 2:].max(axis=0)
        for _ in range(5):
            qx = np.sort(rng.uniform(x0, x1 + 1e-9, 2))
            qy = np.sort(rng.uniform(y0, y1 + 1e-9, 2))
            rows = con.execute(
                "SELECT id FROM rtree_t_geom WHERE maxx >= ? AND minx <= ? AND maxy >= ? AND miny <= ?",
                (qx[0], qx[1], qy[0], qy[1]),
            ).fetchall()
            hit = (f32[:, 1] >= qx[0]) & (f32[:, 0] <= qx[1]) & (f32[:, 3] >= qy[0]) & (f32[:, 2] <= qy[1])
            assert sorted(r[0] for r in rows) == sorted(ids[hit].tolist())
    con.close()


def test_pack_rtree_is_the_same_for_the_same_input_and_full():
    rng = np.random.default_rng(3)
    lo = rng.random((10_000, 2)) * 1000
    bounds = np.column_stack([lo, lo + 2])
    ids = np.arange(10_000)
    a, b = pack_rtree(ids, bounds), pack_rtree(ids, bounds)
    assert np.array_equal(a["node"], b["node"]) and np.array_equal(a["rowid"], b["rowid"])
    shuffled = np.random.default_rng(4).permutation(10_000)  # ids in another order: the same rows by id
    c = pack_rtree(ids[shuffled], bounds[shuffled])
    assert np.array_equal(np.sort(c["rowid"][:, 0]), a["rowid"][:, 0]) and (np.diff(c["rowid"][:, 0]) > 0).all()
    leaves = len(a["node"]) - len(np.unique(a["parent"][:, 1]))  # nodes no node has for parent
    assert leaves == -(-10_000 // RTREE_MAXCELLS)  # every leaf full but the last
    assert len(a["node"]) == 1 + len(a["parent"])  # a tree: every node but the root has a parent


@pytest.fixture(scope="module")
def monaco(tmp_path_factory):
    out = tmp_path_factory.mktemp("monaco")
    assert main(["osm", str(DATA / "monaco.osm.pbf"), "-o", str(out), "--workers", "1", "-q", "--format", "gpkg"]) == 0
    return out / "city.gpkg"


def test_every_table_of_a_real_city_has_an_index_gdal_uses(monaco, tmp_path):
    con = sqlite3.connect(monaco)
    assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    names = [n for n, _ in pyogrio.list_layers(monaco).tolist()]
    assert {"lots", "buildings", "roads", "blocks"} <= set(names)
    for name in names:
        info = pyogrio.read_info(monaco, layer=name)
        assert info["capabilities"]["fast_spatial_filter"], name
        r = f"rtree_{name}_geom"
        assert con.execute(f"SELECT rtreecheck('{r}')").fetchone()[0] == "ok", name
        rows = con.execute(f'SELECT count(*) FROM "{name}" WHERE geom IS NOT NULL').fetchone()[0]
        assert con.execute(f'SELECT count(*) FROM "{r}"').fetchone()[0] == rows == info["features"], name
        ext = con.execute(
            "SELECT count(*) FROM gpkg_extensions WHERE table_name = ? AND extension_name = 'gpkg_rtree_index'", (name,)
        ).fetchone()[0]
        assert ext == 1, name
        trig = con.execute("SELECT count(*) FROM sqlite_master WHERE type = 'trigger' AND name LIKE ?", (r + "%",))
        assert trig.fetchone()[0] == 7, name
    con.close()


def test_bbox_reads_equal_those_of_gdal_own_index(monaco, tmp_path):
    """The same rows written by GDAL with its own index: every window reads the same features from both."""
    ref = tmp_path / "gdal.gpkg"
    rng = np.random.default_rng(11)
    for name in ("lots", "buildings", "roads"):
        meta, table = pyogrio.read_arrow(monaco, layer=name, return_fids=True)
        assert meta["fid_column"] == "id" and meta["geometry_name"] == "geom"
        fids = table.column("id")
        assert len(fids) > 100
        pyogrio.write_arrow(
            table,
            ref,
            layer=name,
            driver="GPKG",
            geometry_name="geom",
            geometry_type=meta["geometry_type"],
            crs=meta["crs"],
            append=ref.exists(),
            layer_options={"FID": "id"},
        )
        x0, y0, x1, y1 = pyogrio.read_info(monaco, layer=name)["total_bounds"]
        for _ in range(8):
            w, h = (x1 - x0) * rng.uniform(0.02, 0.4), (y1 - y0) * rng.uniform(0.02, 0.4)
            cx, cy = rng.uniform(x0, x1), rng.uniform(y0, y1)
            box = (cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2)
            ours = pyogrio.read_arrow(monaco, layer=name, bbox=box, return_fids=True, columns=[])[1]
            theirs = pyogrio.read_arrow(ref, layer=name, bbox=box, return_fids=True, columns=[])[1]
            a = np.sort(ours.column("id").to_numpy())
            b = np.sort(theirs.column("id").to_numpy())
            assert np.array_equal(a, b), (name, box)
            # the window selects: the features whose geometry meets it, of all read without a filter
            g = shapely.from_wkb(table.column("geom").to_numpy(zero_copy_only=False))
            meets = shapely.intersects(g, shapely.box(*box))
            assert np.array_equal(a, np.sort(fids.to_numpy()[meets])), (name, box)


def test_gdal_adds_rows_to_a_table_whose_index_it_did_not_write(tmp_path):
    g = shapely.box(np.arange(30) * 10.0, 0.0, np.arange(30) * 10.0 + 8.0, 8.0)
    a = Layer.from_geoms(g, ids=np.arange(30) + 1, meta={"crs": "EPSG:32631"})
    b = Layer.from_geoms(shapely.box(1000.0, 1000.0, 1010.0, 1010.0 + np.arange(5)), ids=np.arange(5) + 100)
    path = tmp_path / "city.gpkg"
    write_gpkg_layer(path, "lots", a, SAME, "EPSG:32631", chunk=7)
    write_gpkg_layer(path, "lots", b, SAME, "EPSG:32631", append=True, chunk=7)
    con = sqlite3.connect(path)
    assert con.execute("SELECT rtreecheck('rtree_lots_geom')").fetchone()[0] == "ok"
    assert con.execute("SELECT count(*) FROM rtree_lots_geom").fetchone()[0] == 35
    con.close()
    hit = pyogrio.read_arrow(path, layer="lots", bbox=(999.0, 999.0, 1011.0, 1020.0), return_fids=True)[1]
    assert sorted(hit.column("id").to_pylist()) == list(range(100, 105))
    hit = pyogrio.read_arrow(path, layer="lots", bbox=(0.0, 0.0, 25.0, 8.0), return_fids=True)[1]
    assert sorted(hit.column("id").to_pylist()) == [1, 2, 3]


def test_a_table_is_declared_and_keyed_as_gdal_writes_it_alone(tmp_path):
    """Rows added with AUTOINCREMENT off, then given back: the same declaration, counts, extent and sequence."""
    rng = np.random.default_rng(5)
    lo = rng.random((300, 2)) * 1000
    g = shapely.box(lo[:, 0], lo[:, 1], lo[:, 0] + 5, lo[:, 1] + 5)
    ids = np.sort(rng.choice(10**9, 300, replace=False)).astype(np.int64)
    lay = Layer.from_geoms(g, ids=ids, meta={"crs": "EPSG:32631"})
    lay.attrs["name"] = np.array([f"n{i}" if i % 3 else None for i in range(300)], dtype=object)
    ours = tmp_path / "ours.gpkg"
    write_gpkg_layer(ours, "lots", lay, SAME, "EPSG:32631", chunk=64)
    meta, table = pyogrio.read_arrow(ours, layer="lots", return_fids=True)
    gdal = tmp_path / "gdal.gpkg"
    pyogrio.write_arrow(
        table,
        gdal,
        layer="lots",
        driver="GPKG",
        geometry_name="geom",
        geometry_type="Polygon",
        crs="EPSG:32631",
        layer_options={"FID": "id"},
    )
    a, b = sqlite3.connect(ours), sqlite3.connect(gdal)
    assert a.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    ddl = "SELECT sql FROM sqlite_master WHERE type = 'table' AND name = 'lots'"
    assert "PRIMARY KEY AUTOINCREMENT" in a.execute(ddl).fetchone()[0]
    assert a.execute(ddl).fetchone() == b.execute(ddl).fetchone()
    for q in (
        "SELECT * FROM sqlite_sequence",
        "SELECT * FROM gpkg_ogr_contents",
        "SELECT min_x, min_y, max_x, max_y FROM gpkg_contents",
        "SELECT id, name, geom FROM lots ORDER BY id",
    ):
        assert a.execute(q).fetchall() == b.execute(q).fetchall(), q
    assert a.execute("SELECT seq FROM sqlite_sequence WHERE name = 'lots'").fetchone()[0] == ids.max()
    a.close()
    b.close()

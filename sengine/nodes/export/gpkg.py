"""``city.gpkg``: every layer as a table of one OGC GeoPackage (``--format gpkg``).

A GeoPackage is what QGIS users expect: one SQLite file, one table per layer
with its spatial index (a bounding-box query on whole Liège's 250,000 lots
takes milliseconds where the GeoJSON takes seconds), in a projected CRS with
an EPSG code (the city's UTM zone by default, ``--crs`` for another).
The rows are written with pyogrio (GDAL) from Arrow record batches
(:class:`sengine.nodes.export.table.LayerBatches`), a chunk of features at a
time; :func:`write_gpkg_layer` with ``append=True`` adds rows to a table
that exists, as a sharded city writes shard after shard.

The spatial index of a new table is not GDAL's: GDAL builds it when the
file closes, reading every geometry back and inserting the boxes one by
one into an R*-tree (a third of its writing time on whole Liège).  Here
the boxes the writer already has are packed into an R-tree in numpy
(:func:`pack_rtree`) and written straight into the tables of SQLite's
R*Tree module (:func:`write_rtree`), with the triggers and the
``gpkg_extensions`` row the GeoPackage RTree extension asks for, as GDAL
writes them: GDAL, QGIS and SQLite use and maintain it as their own.

GDAL inserts a row at a time, and with the table's key declared
``AUTOINCREMENT`` (as GDAL declares it) SQLite reads and rewrites the
table's ``sqlite_sequence`` row on every insert: a new table's rows are
added while the declaration lacks that word, which is then given back
(:func:`_autoincrement`); the file is the same, table by table and row by row.

The feature id (``fid``) of each row is the feature's sengine ``id``.  Each
table's description names the data's licence when it comes from
OpenStreetMap.  GDAL's time stamps are fixed (:data:`GDAL_OPTIONS`), so the
same layers give the same bytes.
"""

from __future__ import annotations

import itertools
import json
import logging
import sqlite3
from collections.abc import Callable, Iterable, Iterator, Mapping
from functools import partial
from pathlib import Path

import numpy as np

from sengine.layer import Layer

from .table import CHUNK, LayerBatches, rebatch, require

__all__ = ["write_gpkg_layer", "write_gpkg_batches", "write_gpkg", "pack_rtree", "write_rtree"]

log = logging.getLogger(__name__)

#: GDAL settings while writing: the date it writes into ``gpkg_contents.last_change``, fixed so
#: that runs give the same bytes; no SQLite journal nor sync, since the file is written into the
#: run's temporary folder and moved into place only once complete; a larger page cache; and
#: 32 KiB pages (a new file's; SQLite's default is 4 KiB): whole Liège's rows then go in with an
#: eighth of the page splits, GDAL's writing 11-13 % less CPU (0.89 s against 1.00 s, lots and
#: buildings, best of 7 alternated), for at most some 30 KiB more per table on a small city.
GDAL_OPTIONS = {
    "OGR_CURRENT_DATE": "2000-01-01T00:00:00.000Z",
    "OGR_SQLITE_JOURNAL": "OFF",
    "OGR_SQLITE_SYNCHRONOUS": "OFF",
    "OGR_SQLITE_CACHE": "512",
    "OGR_SQLITE_PRAGMA": "page_size=32768",
}


def write_gpkg_layer(
    path: str | Path,
    name: str,
    layer: Layer,
    transform: Callable[[np.ndarray], np.ndarray],
    crs: str,
    *,
    grid: float = 0.001,
    append: bool = False,
    attribution: str | None = None,
    chunk: int = CHUNK,
) -> dict:
    """Write (or, with ``append``, add to) table ``name`` of the GeoPackage at ``path``.

    Parameters
    ----------
    path : path-like
        The ``.gpkg`` file; created when missing, other tables are kept.
    name : str
        Table (layer) name.
    layer : Layer
        A cleaned layer (planar, m).
    transform : callable
        Planar ``(n, 2)`` -> output ``(n, 2)`` coordinates in ``crs``.
    crs : str
        Output frame, ``"EPSG:n"``.
    grid : float
        Output coordinate grid (m, or degrees for a geographic ``crs``).
    append : bool
        Add the rows to an existing table (same columns) instead of creating it.
    attribution : str, optional
        Licence notice, written as the table's description and metadata.

    Returns
    -------
    dict
        ``features`` written (and ``collapsed`` when the output snap dropped some).
    """
    batches = LayerBatches(layer, transform, grid, name=name, chunk=chunk, bbox=True)
    write_gpkg_batches(
        path,
        name,
        batches.schema(),
        batches,
        batches.geometry_type,
        crs,
        append=append,
        attribution=attribution,
        chunk=chunk,
    )
    counts = {"features": batches.written}
    if batches.collapsed:
        counts["collapsed"] = batches.collapsed
    return counts


def write_gpkg_batches(
    path: str | Path,
    name: str,
    schema,
    batches,
    geometry_type: str,
    crs: str,
    *,
    append: bool = False,
    attribution: str | None = None,
    chunk: int = CHUNK,
) -> None:
    """Write Arrow record batches (attributes and a WKB ``geometry``) as table ``name`` of the GeoPackage.

    The rows go to GDAL in batches of exactly ``chunk``
    (:func:`~sengine.nodes.export.table.rebatch`), so that a layer written
    at once and the same rows coming shard after shard make the same file.
    A new table of ``chunk`` rows or more is made empty by GDAL, its rows
    added with AUTOINCREMENT off (:func:`_autoincrement`); every new table gets its spatial index from
    :func:`write_rtree`, from the batches' ``bbox`` column (GeoParquet's
    covering, not written) or, with none, from the geometries; rows added to
    a table (``append``) are indexed by its triggers.
    """
    pyogrio = require("pyogrio", "gpkg")
    require("pyarrow", "gpkg")
    import pyarrow as pa

    boxes: list = []
    rows = rebatch(batches, schema, chunk)
    first = next(rows, None)  # a full first batch: a table of `chunk` rows or more (the same whole or in shards)
    large = not append and first is not None and first.num_rows >= max(int(chunk), 1)
    rows = itertools.chain([] if first is None else [first], rows)
    if "bbox" in schema.names:
        schema = schema.remove(schema.get_field_index("bbox"))
    reader = pa.RecordBatchReader.from_batches(schema, _index_rows(rows, None if append else boxes))
    layer_options = {"FID": "id", "IDENTIFIER": name, "SPATIAL_INDEX": "NO"}
    if attribution:
        layer_options["DESCRIPTION"] = attribution
    write = partial(
        pyogrio.write_arrow,
        path=str(path),
        layer=name,
        driver="GPKG",
        geometry_name="geometry",
        geometry_type=geometry_type,
        crs=crs,
    )
    old = {k: pyogrio.get_gdal_config_option(k) for k in GDAL_OPTIONS}
    pyogrio.set_gdal_config_options(GDAL_OPTIONS)
    ddl = None
    try:
        if append:
            write(reader, append=True)
            return
        metadata = {"attribution": attribution} if attribution else None
        if large:  # the table made empty, its rows added with AUTOINCREMENT off, then given back
            write(pa.RecordBatchReader.from_batches(schema, []), layer_metadata=metadata, layer_options=layer_options)
            ddl = _autoincrement(path, name, None)
            write(reader, append=True)
        else:  # a small table: GDAL's one pass (the dance would cost more than it saves)
            write(reader, layer_metadata=metadata, layer_options=layer_options)
    finally:
        pyogrio.set_gdal_config_options(old)
    ids = np.concatenate([b[0] for b in boxes]) if boxes else np.zeros(0, np.int64)
    bounds = np.concatenate([b[1] for b in boxes]) if boxes else np.zeros((0, 4))
    if ddl is not None:
        _autoincrement(path, name, ddl)
    write_rtree(path, name, ids, bounds)


def _autoincrement(path: str | Path, table: str, ddl: str | None) -> str | None:
    """Take AUTOINCREMENT off the key of table ``table`` (``ddl`` None) or give it back (``ddl``, the original).

    GDAL declares a table's key ``INTEGER PRIMARY KEY AUTOINCREMENT``, so
    that SQLite reads and rewrites the table's ``sqlite_sequence`` row on
    every insert: GDAL inserts a row at a time, and that is a fifth of its
    writing time on whole Liège (lots and buildings: 0.76 s of CPU without,
    0.94-0.96 s with, best of 5 alternated).  A table's rows are stored alike
    either way (the keyword only changes how SQLite picks a new key when none
    is given, and every sengine row brings its own), so the rows are added
    while the declaration lacks the keyword (``PRAGMA writable_schema``,
    only that word changed), then the declaration is given back as GDAL
    wrote it with the ``sqlite_sequence`` row SQLite would have kept (the
    largest key).  Returns the original declaration, or ``None`` when there
    was nothing to take off or SQLite refuses (a build in defensive mode):
    the rows then go in the usual way.
    """
    con = sqlite3.connect(str(path), isolation_level=None)
    try:
        (sql,) = con.execute("SELECT sql FROM sqlite_master WHERE type = 'table' AND name = ?", (table,)).fetchone()
        if ddl is None and sql.count(_AUTO) != 1:
            return None
        con.execute("BEGIN")
        con.execute("PRAGMA writable_schema = ON")
        try:
            con.execute(
                "UPDATE sqlite_master SET sql = ? WHERE type = 'table' AND name = ?",
                (sql.replace(_AUTO, "PRIMARY KEY") if ddl is None else ddl, table),
            )
        except sqlite3.DatabaseError:
            con.execute("ROLLBACK")
            return None
        con.execute("PRAGMA writable_schema = OFF")
        if ddl is not None:
            q = table.replace('"', '""')
            con.execute(f'INSERT INTO sqlite_sequence SELECT ?, max(rowid) FROM "{q}" HAVING count(*)', (table,))
        con.execute("COMMIT")
        return sql
    finally:
        con.close()


_AUTO = "PRIMARY KEY AUTOINCREMENT"


def _index_rows(batches: Iterable, boxes: list | None) -> Iterator:
    """``batches`` without their ``bbox`` column; each batch's ids and bounds appended to ``boxes``."""
    import shapely

    for b in batches:
        names = b.schema.names
        if boxes is not None:
            ids = b.column(names.index("id")).to_numpy(zero_copy_only=False)
            if "bbox" in names:
                s = b.column(names.index("bbox"))
                bounds = np.column_stack([s.field(k).to_numpy(zero_copy_only=False) for k in _BBOX])
            else:
                geoms = shapely.from_wkb(b.column(names.index("geometry")).to_numpy(zero_copy_only=False))
                bounds = shapely.bounds(geoms)
            boxes.append((np.asarray(ids, np.int64), bounds))
        yield b.drop_columns(["bbox"]) if "bbox" in names else b


_BBOX = ("xmin", "ymin", "xmax", "ymax")


def write_gpkg(
    path: str | Path,
    layers: Mapping[str, Layer],
    transforms: Mapping[str, Callable[[np.ndarray], np.ndarray]],
    crs: str,
    *,
    grid: float = 0.001,
    attribution: str | None = None,
) -> dict:
    """Write every layer as a table of one new GeoPackage; return ``{layer: counts}``."""
    path = Path(path)
    if path.exists():
        path.unlink()
    report = {}
    for name in sorted(layers):
        report[name] = write_gpkg_layer(
            path, name, layers[name], transforms[name], crs, grid=grid, attribution=attribution
        )
    log.info("wrote %s: %d tables, %d features", path, len(report), sum(r["features"] for r in report.values()))
    return report


# -- the spatial index: a packed R-tree written straight into SQLite's R*Tree tables -----------
#: Cells of (64-bit id, 4 single-precision bounds) in one node of SQLite's R*Tree module, at most.
RTREE_MAXCELLS = 51
_CELL = np.dtype([("id", ">i8"), ("box", ">f4", (4,))])
_RNDTOWARDS = 1.0 - 1.0 / 8388608.0
_RNDAWAY = 1.0 + 1.0 / 8388608.0


def rtree_boxes(bounds: np.ndarray) -> np.ndarray:
    """``(n, 4)`` float32 ``minx, maxx, miny, maxy`` of ``(n, 4)`` float64 ``xmin, ymin, xmax, ymax`` bounds.

    Rounded outwards exactly as SQLite's R*Tree module rounds a value it
    stores (``rtreeValueDown`` / ``rtreeValueUp``): a box always contains
    its feature.
    """
    b = np.asarray(bounds, dtype=np.float64)
    out = np.empty((len(b), 4), np.float32)
    for j, (col, up) in enumerate(((0, False), (2, True), (1, False), (3, True))):
        d = b[:, col]
        f = d.astype(np.float32)
        wrong = (f < d) if up else (f > d)
        if wrong.any():
            dw = d[wrong]
            if up:
                f[wrong] = (dw * np.where(dw < 0, _RNDTOWARDS, _RNDAWAY)).astype(np.float32)
            else:
                f[wrong] = (dw * np.where(dw < 0, _RNDAWAY, _RNDTOWARDS)).astype(np.float32)
        out[:, j] = f
    return out


def _spread(v: np.ndarray) -> np.ndarray:
    """The 16 low bits of ``v`` spread to the even bits of a 32-bit integer."""
    v = v & 0xFFFF
    v = (v | (v << 8)) & 0x00FF00FF
    v = (v | (v << 4)) & 0x0F0F0F0F
    v = (v | (v << 2)) & 0x33333333
    return (v | (v << 1)) & 0x55555555


def morton_order(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Order of points ``(x, y)`` along a Z-order (Morton) curve on a 65,536-cell grid over their extent.

    Ties keep their input order, so that the order is the same on every run.
    """
    if not len(x):
        return np.zeros(0, np.int64)
    x0, y0 = float(x.min()), float(y.min())
    span = max(float(x.max()) - x0, float(y.max()) - y0)
    scale = 65535.0 / span if span > 0 else 0.0
    xi = ((x - x0) * scale).astype(np.uint64)
    yi = ((y - y0) * scale).astype(np.uint64)
    # the position in the low bits makes every key distinct: one plain sort gives the order, ties in input order
    shift = np.uint64(max(len(x) - 1, 1).bit_length())
    keys = ((_spread(xi) | (_spread(yi) << np.uint64(1))) << shift) | np.arange(len(x), dtype=np.uint64)
    return (np.sort(keys) & ((np.uint64(1) << shift) - np.uint64(1))).astype(np.int64)


def pack_rtree(ids: np.ndarray, bounds: np.ndarray, node_size: int = 4 + 24 * RTREE_MAXCELLS) -> dict:
    """The three tables of an SQLite R*Tree holding boxes ``bounds`` of features ``ids``, packed bottom up.

    Features are sorted along a Z-order curve through their box centres
    (:func:`morton_order`) and cut into leaves of :data:`RTREE_MAXCELLS` cells, leaves into nodes, up to
    one root: a packed R-tree (Kamel and Faloutsos 1993), full nodes and
    little overlap, where inserting the features one by one into the R*-tree
    costs several times more.

    Parameters
    ----------
    ids : (n,) int64
        Feature ids (the table's ``fid``).
    bounds : (n, 4) float64
        Their ``xmin, ymin, xmax, ymax`` (finite).
    node_size : int
        Bytes of a node: SQLite's, ``min(page size - 64, 4 + 24 * 51)``.

    Returns
    -------
    dict
        ``node`` (``(m, node_size)`` uint8: row ``i`` is node ``i + 1``'s
        blob, the root is node 1),
        ``parent`` (``(m - 1, 2)`` int64 node, parent node) and ``rowid``
        (``(n, 2)`` int64 feature id, leaf node), as the module's
        ``%_node``, ``%_parent`` and ``%_rowid`` tables hold them.

    References
    ----------
    Kamel, I. and Faloutsos, C. "On packing R-trees". Proceedings of the
    Second International Conference on Information and Knowledge
    Management (CIKM), 1993, pp. 490-499.
    """
    ids = np.asarray(ids, dtype=np.int64)
    cap = min((node_size - 4) // 24, RTREE_MAXCELLS)
    if not len(ids):
        return {
            "node": np.zeros((0, node_size), np.uint8),
            "parent": np.zeros((0, 2), np.int64),
            "rowid": np.zeros((0, 2), np.int64),
        }
    b = np.asarray(bounds, dtype=np.float64)
    order = morton_order((b[:, 0] + b[:, 2]) / 2, (b[:, 1] + b[:, 3]) / 2)
    boxes = rtree_boxes(b[order])
    leaf_ids = ids[order]
    levels = [boxes]
    while len(levels[-1]) > cap:  # the boxes of the nodes below are the cells of the nodes above
        box = levels[-1]
        starts = np.arange(0, len(box), cap)
        levels.append(
            np.column_stack(
                [
                    np.minimum.reduceat(box[:, 0], starts),
                    np.maximum.reduceat(box[:, 1], starts),
                    np.minimum.reduceat(box[:, 2], starts),
                    np.maximum.reduceat(box[:, 3], starts),
                ]
            )
        )
    # levels[k] are the cells of the nodes at height k (0: leaves); the root holds levels[-1]
    height = len(levels)
    nodes_at = [(len(c) + cap - 1) // cap for c in levels]  # nodes at each height
    first = np.zeros(height, np.int64)  # node number of the first node at each height: root 1, then downwards
    nxt = 1
    for k in range(height - 1, -1, -1):
        first[k] = nxt
        nxt += nodes_at[k]
    node = np.zeros((nxt - 1, node_size), np.uint8)  # every node's blob, in node number order
    parent = []
    for k, cells in enumerate(levels):
        m = len(cells)
        rec = np.zeros(nodes_at[k] * cap, _CELL)
        rec["id"][:m] = leaf_ids if k == 0 else first[k - 1] + np.arange(m)
        rec["box"][:m] = cells
        blob = node[first[k] - 1 : first[k] - 1 + nodes_at[k]]
        count = np.full(nodes_at[k], cap, ">u2")
        count[-1] = m - cap * (nodes_at[k] - 1)
        blob[:, 2:4] = count.view(np.uint8).reshape(-1, 2)
        if k == height - 1:
            blob[0, :2] = np.array([height - 1], ">u2").view(np.uint8)
        blob[:, 4 : 4 + cap * 24] = rec.view(np.uint8).reshape(nodes_at[k], cap * 24)
        if k:
            parent.append(np.column_stack([first[k - 1] + np.arange(m), first[k] + np.arange(m) // cap]))
    leaf = first[0] + np.arange(len(ids)) // cap
    if len(ids) < 2 or (np.diff(ids) > 0).all():  # ids ascending (a table's own order): place, no sort
        by_id = np.empty(len(ids), np.int64)
        by_id[order] = leaf
        rowid = np.column_stack([ids, by_id])
    else:
        rowid = np.column_stack([leaf_ids, leaf])
        rowid = rowid[np.argsort(rowid[:, 0], kind="stable")]
    parent = np.concatenate(parent) if parent else np.zeros((0, 2), np.int64)
    return {"node": node, "parent": parent[np.argsort(parent[:, 0], kind="stable")], "rowid": rowid}


#: What GDAL writes for a table's R-tree (OGC 12-128r18, the RTree Spatial Indexes extension), ``{t}``
#: the table, ``{g}`` its geometry column, ``{i}`` its fid column, ``{r}`` the index.
_RTREE_TRIGGERS = (
    'CREATE TRIGGER "{r}_insert" AFTER INSERT ON "{t}" WHEN (new."{g}" NOT NULL AND NOT ST_IsEmpty(NEW."{g}")) '
    'BEGIN INSERT OR REPLACE INTO "{r}" VALUES (NEW."{i}",ST_MinX(NEW."{g}"), ST_MaxX(NEW."{g}"),'
    'ST_MinY(NEW."{g}"), ST_MaxY(NEW."{g}")); END',
    'CREATE TRIGGER "{r}_update2" AFTER UPDATE OF "{g}" ON "{t}" WHEN OLD."{i}" = NEW."{i}" AND '
    '(NEW."{g}" ISNULL OR ST_IsEmpty(NEW."{g}")) BEGIN DELETE FROM "{r}" WHERE id = OLD."{i}"; END',
    'CREATE TRIGGER "{r}_update4" AFTER UPDATE ON "{t}" WHEN OLD."{i}" != NEW."{i}" AND '
    '(NEW."{g}" ISNULL OR ST_IsEmpty(NEW."{g}")) BEGIN DELETE FROM "{r}" WHERE id IN (OLD."{i}", NEW."{i}"); END',
    'CREATE TRIGGER "{r}_update5" AFTER UPDATE ON "{t}" WHEN OLD."{i}" != NEW."{i}" AND '
    '(NEW."{g}" NOTNULL AND NOT ST_IsEmpty(NEW."{g}")) BEGIN DELETE FROM "{r}" WHERE id = OLD."{i}"; '
    'INSERT OR REPLACE INTO "{r}" VALUES (NEW."{i}",ST_MinX(NEW."{g}"), ST_MaxX(NEW."{g}"),'
    'ST_MinY(NEW."{g}"), ST_MaxY(NEW."{g}")); END',
    'CREATE TRIGGER "{r}_update6" AFTER UPDATE OF "{g}" ON "{t}" WHEN OLD."{i}" = NEW."{i}" AND '
    '(NEW."{g}" NOTNULL AND NOT ST_IsEmpty(NEW."{g}")) AND (OLD."{g}" NOTNULL AND NOT ST_IsEmpty(OLD."{g}")) '
    'BEGIN UPDATE "{r}" SET minx = ST_MinX(NEW."{g}"), maxx = ST_MaxX(NEW."{g}"),miny = ST_MinY(NEW."{g}"), '
    'maxy = ST_MaxY(NEW."{g}") WHERE id = NEW."{i}";END',
    'CREATE TRIGGER "{r}_update7" AFTER UPDATE OF "{g}" ON "{t}" WHEN OLD."{i}" = NEW."{i}" AND '
    '(NEW."{g}" NOTNULL AND NOT ST_IsEmpty(NEW."{g}")) AND (OLD."{g}" ISNULL OR ST_IsEmpty(OLD."{g}")) '
    'BEGIN INSERT INTO "{r}" VALUES (NEW."{i}",ST_MinX(NEW."{g}"), ST_MaxX(NEW."{g}"),'
    'ST_MinY(NEW."{g}"), ST_MaxY(NEW."{g}")); END',
    'CREATE TRIGGER "{r}_delete" AFTER DELETE ON "{t}" WHEN old."{g}" NOT NULL '
    'BEGIN DELETE FROM "{r}" WHERE id = OLD."{i}"; END',
)
_EXTENSIONS = (
    "CREATE TABLE IF NOT EXISTS gpkg_extensions (table_name TEXT,column_name TEXT,extension_name TEXT NOT NULL,"
    "definition TEXT NOT NULL,scope TEXT NOT NULL,CONSTRAINT ge_tce UNIQUE (table_name, column_name, extension_name))"
)


def write_rtree(path: str | Path, table: str, ids: np.ndarray, bounds: np.ndarray, *, fid: str = "id") -> None:
    """Add the spatial index of table ``table`` to the GeoPackage at ``path``: what GDAL would build, faster.

    The R-tree is packed here (:func:`pack_rtree`) from the bounds the
    writer already has and its tables filled in one transaction; then the
    triggers that keep it up to date and its ``gpkg_extensions`` row, as GDAL
    writes them, so that GDAL, QGIS and any GeoPackage reader use and
    maintain it as their own.
    """
    b = np.asarray(bounds, dtype=np.float64).reshape(-1, 4)
    ok = np.isfinite(b).all(axis=1)  # null and empty geometries have no box (nor an entry)
    con = sqlite3.connect(str(path), isolation_level=None)
    try:
        (geometry,) = con.execute(
            "SELECT column_name FROM gpkg_geometry_columns WHERE table_name = ?", (table,)
        ).fetchone()
        r = f"rtree_{table}_{geometry}"
        con.execute("PRAGMA journal_mode = OFF")
        con.execute("PRAGMA synchronous = OFF")
        con.execute("BEGIN")
        page = con.execute("PRAGMA page_size").fetchone()[0]
        packed = pack_rtree(np.asarray(ids, np.int64)[ok], b[ok], min(page - 64, 4 + 24 * RTREE_MAXCELLS))
        q = r.replace('"', '""')
        con.execute(f'CREATE VIRTUAL TABLE "{q}" USING rtree(id, minx, maxx, miny, maxy)')
        node = packed["node"]
        if len(node):
            con.execute(f'DELETE FROM "{q}_node"')
            # every node cut out of one blob by SQLite: no Python object per node
            con.execute(
                f'INSERT INTO "{q}_node" WITH RECURSIVE n(i) AS (SELECT 1 UNION ALL SELECT i + 1 FROM n WHERE i < ?1) '
                "SELECT i, substr(?2, (i - 1) * ?3 + 1, ?3) FROM n",
                (len(node), node.tobytes(), node.shape[1]),
            )
            _insert_pairs(con, f"{q}_parent", packed["parent"])
            _insert_pairs(con, f"{q}_rowid", packed["rowid"])
        names = {"t": table.replace('"', '""'), "g": geometry.replace('"', '""'), "i": fid.replace('"', '""'), "r": q}
        for sql in _RTREE_TRIGGERS:
            con.execute(sql.format(**names))
        con.execute(_EXTENSIONS)
        con.execute(
            "INSERT INTO gpkg_extensions VALUES (?, ?, 'gpkg_rtree_index', "
            "'http://www.geopackage.org/spec120/#extension_rtree', 'write-only')",
            (table, geometry),
        )
        con.execute("COMMIT")
    finally:
        con.close()


def _insert_pairs(con, table: str, pairs: np.ndarray) -> None:
    """Insert ``(n, 2)`` integer rows into ``table``: in one statement (JSON) when they fit, else row by row."""
    if not len(pairs):
        return
    a, b = pairs[:, 0], pairs[:, 1]
    shift = max(int(b.max()).bit_length(), 1)
    if a.min() >= 0 and b.min() >= 0 and int(a.max()) < (1 << (62 - shift)):
        packed = (a << shift) | b  # two numbers in one: SQLite's JSON reader takes them apart in C
        con.execute(
            f'INSERT INTO "{table}" SELECT value >> {shift}, value & {(1 << shift) - 1} FROM json_each(?)',
            (json.dumps(packed.tolist()),),
        )
    else:
        con.executemany(f'INSERT INTO "{table}" VALUES (?, ?)', pairs.tolist())

"""``<layer>.parquet``: each layer as a GeoParquet 1.1 file (``--format parquet``).

GeoParquet is the columnar format of DuckDB, GeoPandas, Apache Sedona and
QGIS (through GDAL): the geometry is a well-known-binary column and the
file's ``geo`` metadata names its encoding, geometry types, bounding box and
CRS as PROJJSON.  A ``bbox`` struct column (xmin, ymin, xmax, ymax) is the
version 1.1 *covering*, with which a reader skips the row groups outside a
query window.  One row group per :data:`sengine.nodes.export.table.CHUNK`
features, written as they are made (:class:`ParquetLayerWriter`, which a
sharded city feeds shard after shard), compressed with zstd.

References
----------
Open Geospatial Consortium, GeoParquet specification, version 1.1.0 (2024),
https://geoparquet.org/releases/v1.1.0/.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable
from pathlib import Path

import numpy as np

from sengine.layer import Layer

from .table import CHUNK, LayerBatches, require

__all__ = ["GEOPARQUET_VERSION", "geo_metadata", "ParquetLayerWriter", "write_parquet"]

log = logging.getLogger(__name__)

GEOPARQUET_VERSION = "1.1.0"


def geo_metadata(crs: str, geometry_types: list[str], bbox: list[float] | None) -> dict:
    """The ``geo`` file metadata of GeoParquet 1.1 for one WKB ``geometry`` column with a ``bbox`` covering."""
    from pyproj import CRS

    column = {
        "encoding": "WKB",
        "geometry_types": sorted(set(geometry_types)),
        "crs": CRS.from_user_input(crs).to_json_dict(),
        "covering": {
            "bbox": {
                "xmin": ["bbox", "xmin"],
                "ymin": ["bbox", "ymin"],
                "xmax": ["bbox", "xmax"],
                "ymax": ["bbox", "ymax"],
            }
        },
    }
    if CRS.from_user_input(crs).is_geographic:
        column["edges"] = "planar"
    if bbox:
        column["bbox"] = [float(v) for v in bbox]
    return {"version": GEOPARQUET_VERSION, "primary_column": "geometry", "columns": {"geometry": column}}


class ParquetLayerWriter:
    """A GeoParquet file written batch after batch; the ``geo`` metadata goes in when it is closed.

    Parameters
    ----------
    path : path-like
        The ``.parquet`` file (replaced).
    crs : str
        Output frame, ``"EPSG:n"``.
    attribution : str, optional
        Licence notice, kept under the file metadata key ``attribution``.

    Use :meth:`write` once per layer chunk or shard (same columns each time),
    then :meth:`close` (or ``with``).
    """

    def __init__(self, path: str | Path, crs: str, *, attribution: str | None = None):
        require("pyarrow", "parquet")
        self.path = Path(path)
        self.crs = crs
        self.attribution = attribution
        self._writer = None
        self._schema = None
        self._chunk = CHUNK
        self._pending: list = []
        self._rows = 0
        self._types: set[str] = set()
        self._bounds = np.array([np.inf, np.inf, -np.inf, -np.inf])
        self.written = 0
        self.collapsed = 0

    def write(
        self,
        layer: Layer,
        transform: Callable[[np.ndarray], np.ndarray],
        *,
        grid: float = 0.001,
        name: str = "",
        chunk: int = CHUNK,
    ) -> int:
        """Append the features of ``layer`` (cleaned, planar) in row groups of ``chunk``; return how many."""
        batches = LayerBatches(layer, transform, grid, name=name, chunk=chunk, bbox=True)
        n = self.write_batches(batches.schema(), batches, chunk=chunk)
        if batches.written:
            self.add_extent(batches.geometry_type, batches.bounds)
        self.collapsed += batches.collapsed
        return n

    def write_batches(self, schema, batches, *, chunk: int = CHUNK) -> int:
        """Append Arrow record batches (``schema``: attributes, WKB ``geometry``, ``bbox``); return the rows.

        Rows are cut into row groups of exactly ``chunk`` rows across calls
        (:func:`~sengine.nodes.export.table.rebatch`): a layer written in one
        call and the same rows written shard after shard give the same file.
        Say what the rows hold with :meth:`add_extent`.
        """
        import pyarrow as pa
        import pyarrow.parquet as pq

        if self._writer is None:
            # no ARROW:schema copy: the footer's "geo" key, written at close, is then the one every reader sees
            self._writer = pq.ParquetWriter(self.path, schema, compression="zstd", store_schema=False)
            self._schema = schema
            self._chunk = max(int(chunk), 1)
        n = 0
        for batch in batches:
            if batch.num_rows:
                self._pending.append(batch)
                self._rows += batch.num_rows
                n += batch.num_rows
            if self._rows >= self._chunk:
                table = pa.Table.from_batches(self._pending, schema=self._schema).combine_chunks()
                full = (self._rows // self._chunk) * self._chunk
                for lo in range(0, full, self._chunk):
                    self._writer.write_table(table.slice(lo, self._chunk), row_group_size=self._chunk)
                rest = table.slice(full)
                self._pending, self._rows = rest.to_batches(), rest.num_rows
        self.written += n
        return n

    def add_extent(self, geometry_type: str, bounds) -> None:
        """Record the geometry type and output bounds of rows written (for the ``geo`` metadata)."""
        self._types.add(geometry_type)
        b = np.asarray(bounds, np.float64)
        if len(b) == 4:
            self._bounds = np.concatenate([np.minimum(self._bounds[:2], b[:2]), np.maximum(self._bounds[2:], b[2:])])

    def close(self) -> None:
        import pyarrow as pa

        if self._writer is None:
            return
        if self._rows:
            table = pa.Table.from_batches(self._pending, schema=self._schema).combine_chunks()
            self._writer.write_table(table, row_group_size=self._chunk)
            self._pending, self._rows = [], 0
        bbox = self._bounds.tolist() if self.written else None
        meta = {"geo": json.dumps(geo_metadata(self.crs, sorted(self._types), bbox), sort_keys=True)}
        if self.attribution:
            meta["attribution"] = self.attribution
        self._writer.add_key_value_metadata(meta)
        self._writer.close()
        self._writer = None

    def __enter__(self) -> ParquetLayerWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def write_parquet(
    path: str | Path,
    layer: Layer,
    transform: Callable[[np.ndarray], np.ndarray],
    crs: str,
    *,
    name: str = "",
    grid: float = 0.001,
    attribution: str | None = None,
) -> dict:
    """Write one layer as a GeoParquet 1.1 file; return ``features`` written (and ``collapsed``)."""
    with ParquetLayerWriter(path, crs, attribution=attribution) as w:
        w.write(layer, transform, grid=grid, name=name)
    counts = {"features": w.written}
    if w.collapsed:
        counts["collapsed"] = w.collapsed
    log.info("wrote %s: %d features", path, w.written)
    return counts

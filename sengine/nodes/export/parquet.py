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
        import pyarrow.parquet as pq

        batches = LayerBatches(layer, transform, grid, name=name, chunk=chunk, bbox=True)
        if self._writer is None:
            # no ARROW:schema copy: the footer's "geo" key, written at close, is then the one every reader sees
            self._writer = pq.ParquetWriter(self.path, batches.schema(), compression="zstd", store_schema=False)
        for batch in batches:
            if batch.num_rows:
                self._writer.write_batch(batch, row_group_size=max(int(chunk), 1))
        if batches.written:
            self._types.add(batches.geometry_type)
            b = batches.bounds
            self._bounds = np.concatenate([np.minimum(self._bounds[:2], b[:2]), np.maximum(self._bounds[2:], b[2:])])
        self.written += batches.written
        self.collapsed += batches.collapsed
        return batches.written

    def close(self) -> None:
        if self._writer is None:
            return
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

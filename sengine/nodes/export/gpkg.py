"""``city.gpkg``: every layer as a table of one OGC GeoPackage (``--format gpkg``).

A GeoPackage is what QGIS users expect: one SQLite file, one table per layer
with its spatial index (a bounding-box query on whole Liège's 250,000 lots
takes milliseconds where the GeoJSON takes seconds), in a projected CRS with
an EPSG code (the city's UTM zone by default, ``--crs`` for another).
Written with pyogrio (GDAL) from Arrow record batches
(:class:`sengine.nodes.export.table.LayerBatches`), a chunk of features at a
time; :func:`write_gpkg_layer` with ``append=True`` adds rows to a table
that exists, as a sharded city writes shard after shard.

The feature id (``fid``) of each row is the feature's sengine ``id``.  Each
table's description names the data's licence when it comes from
OpenStreetMap.  GDAL's time stamps are fixed (:data:`GDAL_OPTIONS`), so the
same layers give the same bytes.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from sengine.layer import Layer

from .table import CHUNK, LayerBatches, rebatch, require

__all__ = ["write_gpkg_layer", "write_gpkg_batches", "write_gpkg"]

log = logging.getLogger(__name__)

#: GDAL settings while writing: the date it writes into ``gpkg_contents.last_change``, fixed so
#: that runs give the same bytes; no SQLite journal nor sync, since the file is written into the
#: run's temporary folder and moved into place only once complete; a larger page cache.
GDAL_OPTIONS = {
    "OGR_CURRENT_DATE": "2000-01-01T00:00:00.000Z",
    "OGR_SQLITE_JOURNAL": "OFF",
    "OGR_SQLITE_SYNCHRONOUS": "OFF",
    "OGR_SQLITE_CACHE": "512",
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
    batches = LayerBatches(layer, transform, grid, name=name, chunk=chunk)
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
    """
    pyogrio = require("pyogrio", "gpkg")
    require("pyarrow", "gpkg")
    import pyarrow as pa

    reader = pa.RecordBatchReader.from_batches(schema, rebatch(batches, schema, chunk))
    layer_options = {"FID": "id", "IDENTIFIER": name}
    if attribution:
        layer_options["DESCRIPTION"] = attribution
    old = {k: pyogrio.get_gdal_config_option(k) for k in GDAL_OPTIONS}
    pyogrio.set_gdal_config_options(GDAL_OPTIONS)
    try:
        pyogrio.write_arrow(
            reader,
            str(path),
            layer=name,
            driver="GPKG",
            geometry_name="geometry",
            geometry_type=geometry_type,
            crs=crs,
            append=append,
            layer_metadata={"attribution": attribution} if attribution and not append else None,
            layer_options=None if append else layer_options,
        )
    finally:
        pyogrio.set_gdal_config_options(old)


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

"""A layer as Arrow record batches: the common ground of the GeoPackage and GeoParquet writers.

Attribute columns become Arrow arrays once (``id``, ``parent_id`` with null
for none, then every column; ``None`` is null), and the geometry is
reprojected, snapped (:func:`sengine.geom.cleanup.snap_to_type`) and
turned into well-known binary :data:`CHUNK` features at a time, so that a
whole city's layer never sits in memory twice.  The batches of a layer are
the same whatever the chunk size, and the writers that consume them append
batch after batch: a sharded city streams its shards into one file the
same way.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field

import numpy as np
import shapely

from sengine.errors import SEngineError
from sengine.geom.cleanup import GRID, layer_type, snap_to_type
from sengine.layer import Layer
from sengine.progress import advance

__all__ = ["CHUNK", "OSM_ATTRIBUTION", "TYPE_IDS", "require", "attribute_arrays", "LayerBatches", "rebatch"]

log = logging.getLogger(__name__)

#: Features converted and written at a time.
CHUNK = 20_000
#: The notice the OpenStreetMap licence asks for on everything made from its data.
OSM_ATTRIBUTION = "© OpenStreetMap contributors, ODbL"
#: shapely type id of each layer geometry type name.
TYPE_IDS = {"Point": 0, "LineString": 1, "Polygon": 3, "MultiPoint": 4, "MultiLineString": 5, "MultiPolygon": 6}
#: The geometry type of a layer that is empty, by layer name.
EMPTY_TYPES = {"roads": "LineString"}


class MissingDependencyError(SEngineError, ImportError):
    """A writer's optional library is not installed."""

    code = "dependency"


def require(module: str, fmt: str):
    """Import ``module`` for format ``fmt``; a one-line error naming the package when it is missing."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        package = module.split(".")[0]
        raise MissingDependencyError(
            f"--format {fmt} needs the Python package {package!r}: pip install {package}", where="export"
        ) from None


def _array(pa, col: np.ndarray):
    col = np.asarray(col)
    if col.dtype.kind in "fiub":
        return pa.array(col)
    if col.dtype.kind == "U":  # straight from numpy's fixed-width text, no Python strings
        return pa.array(col, type=pa.string())
    if col.dtype.kind == "S":
        return pa.array(col.astype(object), type=pa.string())
    if col.dtype.kind == "O":  # text and None (the usual object column, or nothing but None): Arrow's own loop
        try:
            arr = pa.array(col)
        except (pa.ArrowInvalid, pa.ArrowTypeError):
            arr = None
        if arr is not None and (pa.types.is_string(arr.type) or pa.types.is_null(arr.type)):
            return arr
    values = [v.item() if isinstance(v, np.generic) else v for v in col.tolist()]
    try:
        return pa.array(values)
    except (pa.ArrowInvalid, pa.ArrowTypeError):  # mixed types: their text
        return pa.array([None if v is None else str(v) for v in values], type=pa.string())


def attribute_arrays(layer: Layer) -> dict:
    """``{name: pyarrow.Array}`` of ``id``, ``parent_id`` (null for none) and every attribute column.

    The integer columns named in ``layer.meta["null_negative"]`` hold null where negative.
    """
    import pyarrow as pa

    parent = pa.array(layer.parent, mask=layer.parent < 0)
    cols = {"id": pa.array(layer.ids), "parent_id": parent}
    nulls = set(layer.meta.get("null_negative", ()))
    for key, col in layer.attrs.items():
        arr = pa.array(col, mask=col < 0) if key in nulls else _array(pa, col)
        if pa.types.is_null(arr.type):  # a column of nothing but nulls still needs a type
            arr = arr.cast(pa.string())
        cols[key] = arr
    return cols


@dataclass
class LayerBatches:
    """A layer's record batches in an output frame.

    Parameters
    ----------
    layer : Layer
        A cleaned layer (:func:`sengine.nodes.export.prepare.prepare_layer`), planar.
    transform : callable
        ``(n, 2)`` planar -> ``(n, 2)`` output coordinates; one whose
        ``identity`` attribute is True (:func:`sengine.geom.crs.reproject`
        between equal frames) with the layer's own grid leaves the cleaned
        geometries as they are.
    grid : float
        Output coordinate grid (0.001 m; 1e-7 deg).
    name : str
        Layer name (for the geometry type of an empty layer).
    chunk : int
        Features per batch.
    bbox : bool
        Add a ``bbox`` struct column (xmin, ymin, xmax, ymax), GeoParquet 1.1's covering.

    Attributes
    ----------
    geometry_type : str
        The layer's one type (``"Polygon"``, ``"MultiPolygon"`` ...).
    bounds : list of float
        Output bounds of what was written, once the batches are consumed.
    written, collapsed : int
        Features written, and features the output snap left empty (dropped).
    """

    layer: Layer
    transform: Callable[[np.ndarray], np.ndarray]
    grid: float
    name: str = ""
    chunk: int = CHUNK
    bbox: bool = False
    geometry_type: str = field(init=False)
    bounds: list = field(init=False, default_factory=list)
    written: int = field(init=False, default=0)
    collapsed: int = field(init=False, default=0)

    def __post_init__(self):
        t = layer_type(self.layer.geometry)
        self.geometry_type = t if t != "Unknown" or len(self.layer) else EMPTY_TYPES.get(self.name, "Polygon")
        self._cols = attribute_arrays(self.layer)

    def schema(self):
        """The Arrow schema of the batches: attributes, ``geometry`` (WKB) and, asked for, ``bbox``."""
        import pyarrow as pa

        fields = [pa.field(k, v.type) for k, v in self._cols.items()]
        fields.append(pa.field("geometry", pa.binary()))
        if self.bbox:
            fields.append(pa.field("bbox", _BBOX_TYPE(pa)))
        return pa.schema(fields)

    def __iter__(self) -> Iterator:
        import pyarrow as pa

        schema = self.schema()
        cols = self._cols
        geoms = self.layer.geometry
        type_id = TYPE_IDS.get(self.geometry_type, -1)
        lo_all = np.full(2, np.inf)
        hi_all = np.full(2, -np.inf)
        step = max(int(self.chunk), 1)
        # a layer cleaned on this grid and written in its own frame is ready as it is
        ready = getattr(self.transform, "identity", False) and self.grid == GRID
        decimals = int(round(-np.log10(self.grid)))
        for lo in range(0, len(geoms), step):
            hi = min(lo + step, len(geoms))
            out = geoms[lo:hi]
            if ready:
                keep = np.ones(len(out), bool)
            else:  # reproject and round in one pass over the coordinates, then repair what that folded
                xy = np.round(self.transform(shapely.get_coordinates(out)), decimals)
                out = shapely.set_coordinates(out.copy(), xy)
                out, collapsed = snap_to_type(out, self.grid, type_id, rounded=True)
                keep = ~collapsed
                self.collapsed += int(collapsed.sum())
                out = out[keep]
            arrays = [
                cols[k].slice(lo, hi - lo) if ready else cols[k].slice(lo, hi - lo).filter(pa.array(keep)) for k in cols
            ]
            arrays.append(pa.array(shapely.to_wkb(out, output_dimension=2), type=pa.binary()))
            b = shapely.bounds(out)
            if len(out):
                lo_all = np.minimum(lo_all, np.nanmin(b[:, :2], axis=0))
                hi_all = np.maximum(hi_all, np.nanmax(b[:, 2:], axis=0))
            if self.bbox:
                arrays.append(
                    pa.StructArray.from_arrays([pa.array(b[:, i]) for i in range(4)], fields=list(_BBOX_TYPE(pa)))
                )
            self.written += len(out)
            yield pa.RecordBatch.from_arrays(arrays, schema=schema)
            advance(hi - lo)  # the batch is written: counted for the run's progress
        if self.written:
            self.bounds = [float(v) for v in (*lo_all, *hi_all)]


def _BBOX_TYPE(pa):
    return pa.struct([pa.field(k, pa.float64()) for k in ("xmin", "ymin", "xmax", "ymax")])


def rebatch(batches: Iterable, schema, chunk: int = CHUNK) -> Iterator:
    """The rows of ``batches`` again, in batches of exactly ``chunk`` rows (the last may be shorter).

    The writers write one batch per row group or transaction: cut the same
    way, a layer written in one go and the same rows written shard after
    shard give the same file.
    """
    import pyarrow as pa

    chunk = max(int(chunk), 1)
    pending: list = []
    rows = 0
    for batch in batches:
        if not batch.num_rows:
            continue
        if not rows and batch.num_rows == chunk and batch.schema == schema:
            yield batch  # already cut as wanted (a layer's own batches): no copy
            continue
        pending.append(batch)
        rows += batch.num_rows
        while rows >= chunk:
            table = pa.Table.from_batches(pending, schema=schema).combine_chunks()
            yield _one_batch(table.slice(0, chunk), schema)
            rest = table.slice(chunk)
            pending, rows = rest.to_batches(), rest.num_rows
    if rows:
        yield _one_batch(pa.Table.from_batches(pending, schema=schema), schema)


def _one_batch(table, schema):
    import pyarrow as pa

    batches = table.combine_chunks().to_batches()
    return batches[0] if len(batches) == 1 else pa.RecordBatch.from_pylist([], schema=schema)

"""GeoJSON layers (RFC 7946): WGS84 longitude / latitude, every attribute kept.

Each layer is written to ``<name>.geojson`` as one FeatureCollection.  Planar
coordinates go to WGS84 through :mod:`sengine.geom.crs` from the layer's
``meta["crs"]`` (or the city's geographic origin), are rounded to 7 decimals
(about 1 cm), and polygon exteriors are counter-clockwise with clockwise holes
(RFC 7946 §3.1.6).  Rounding can fold a thin polygon: the few features it
makes invalid are repaired on the grid (:func:`sengine.geom.cleanup.snap_to_type`)
and a feature it leaves empty is dropped.  Properties are the feature's
``id``, ``parent_id`` (``null`` for none) and every attribute column; NaN,
``None`` and the negative values of the integer columns named in
``meta["null_negative"]`` become ``null``.  Keys are sorted, so the same layer always
gives the same bytes.  Another frame than WGS84 can be asked for (``crs``):
the file then names it in the ``crs`` member GDAL reads (the 2008 GeoJSON
convention), and an ``attribution`` member carries the data's licence
notice when there is one.

Geometries are serialised by GEOS in one vectorized call and attribute values
column by column, so a layer of thousands of features takes milliseconds; a
whole city's layer is written in chunks of :data:`CHUNK` features.

References
----------
.. [1] H. Butler, M. Daly, A. Doyle, S. Gillies, S. Hagen and T. Schaub, "The
   GeoJSON Format", RFC 7946, Internet Engineering Task Force, 2016.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import shapely

from ..geom.cleanup import snap_to_type
from ..progress import advance

if TYPE_CHECKING:
    from ..layer import Layer

__all__ = ["to_wgs84", "output_geometries", "feature_collection_chunks", "feature_collection_text", "write_geojson"]

log = logging.getLogger(__name__)


def to_wgs84(geoms: np.ndarray, to_lonlat: Callable[[np.ndarray], np.ndarray], *, precision: int = 7) -> np.ndarray:
    """Geometries in longitude / latitude, rounded, polygons oriented per RFC 7946.

    Parameters
    ----------
    geoms : array of shapely geometries
        Planar geometries (m).
    to_lonlat : callable
        Maps an ``(n, 2)`` planar array to ``(n, 2)`` lon / lat (deg).
    precision : int
        Decimals kept (7 decimals of a degree is about 1 cm).
    """
    geoms = np.asarray(geoms, dtype=object)
    if len(geoms) == 0:
        return geoms

    def f(xy: np.ndarray) -> np.ndarray:
        return np.round(to_lonlat(xy), precision)

    out = geoms.copy()
    poly = shapely.get_type_id(geoms) == 3
    if poly.any():  # plain polygons: project, round and orient in one pass of numpy
        p = geoms[poly]
        coords, vpoly = shapely.get_coordinates(p, return_index=True)
        if shapely.get_num_interior_rings(p).any():
            rings, ring_poly = shapely.get_rings(p, return_index=True)
            counts = shapely.get_num_coordinates(rings)
        else:
            counts = np.bincount(vpoly, minlength=len(p))
            ring_poly = np.arange(len(p))
        ll = f(coords)
        out[poly] = shapely.set_coordinates(p, _orient_closed(ll, counts, ring_poly))
    if (~poly).any():
        other = shapely.transform(geoms[~poly], f)
        if np.isin(shapely.get_type_id(other), _POLYGONAL).any():  # points and lines have nothing to orient
            other = shapely.orient_polygons(other, exterior_cw=False)
        out[~poly] = other
    return out


#: Type ids that hold polygons: MultiPolygon, GeometryCollection (a Polygon goes the numpy way).
_POLYGONAL = (6, 7)


def output_geometries(
    geoms: np.ndarray, to_lonlat: Callable[[np.ndarray], np.ndarray], *, precision: int = 7
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`to_wgs84`, then the features that rounding made invalid repaired on the grid.

    Returns the geometries and a mask of those to write (a feature the
    rounding left empty is not).
    """
    out = to_wgs84(geoms, to_lonlat, precision=precision)
    keep = np.ones(len(out), bool)
    if len(out) == 0:
        return out, keep
    bad = ~shapely.is_valid(out) & ~shapely.is_empty(out)
    if bad.any():
        types = np.unique(shapely.get_type_id(out))
        type_id = int(types[0]) if len(types) == 1 else -1
        fixed, collapsed = snap_to_type(out[bad], 10.0**-precision, type_id)
        out[bad] = shapely.orient_polygons(fixed, exterior_cw=False)
        keep[np.flatnonzero(bad)[collapsed]] = False
    return out, keep


def _orient_closed(xy: np.ndarray, counts: np.ndarray, ring_poly: np.ndarray) -> np.ndarray:
    """Reverse closed rings so exteriors run counter-clockwise and holes clockwise."""
    n = len(counts)
    if n == 0:
        return xy
    starts = np.concatenate([[0], np.cumsum(counts)])
    vr = np.repeat(np.arange(n), counts)
    s, e = starts[vr], starts[vr + 1]
    i = np.arange(len(xy))
    d = xy - xy[s]
    last = i + 1 >= e
    nxt = np.where(last, i, i + 1)  # the closing vertex adds nothing
    area2 = np.bincount(vr, weights=d[:, 0] * d[nxt, 1] - d[nxt, 0] * d[:, 1], minlength=n)
    exterior = np.ones(n, bool)
    exterior[1:] = ring_poly[1:] != ring_poly[:-1]
    flip = np.where(exterior, area2 < 0, area2 > 0)
    if not flip.any():
        return xy
    return xy[np.where(flip[vr], s + e - 1 - i, i)]


def _column_texts(col: np.ndarray) -> list[str]:
    """JSON text of every value of a column (NaN and infinities as ``null``)."""
    col = np.asarray(col)
    kind = col.dtype.kind
    if kind in "iu":
        return list(map(str, col.tolist()))
    if kind == "b":
        return np.where(col, "true", "false").tolist()
    if kind == "f":
        texts = list(map(repr, col.astype(np.float64).tolist()))
        for i in np.flatnonzero(~np.isfinite(col)).tolist():
            texts[i] = "null"
        return texts
    values = col.tolist()
    try:
        uniq = {v: _dumps(v) for v in set(values)}
        return [uniq[v] for v in values]
    except TypeError:  # unhashable values (lists ...)
        return [_dumps(v) for v in values]


def _dumps(v: Any) -> str:
    if isinstance(v, float) and not np.isfinite(v):
        return "null"
    return json.dumps(v, sort_keys=True, separators=(",", ":"), default=_default, ensure_ascii=False)


def _default(v: Any) -> Any:
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, np.ndarray):
        return v.tolist()
    return str(v)


#: Features rendered at a time: the text of a chunk is written before the next one is made.
CHUNK = 20_000


def feature_collection_chunks(
    layer: Layer,
    to_lonlat: Callable[[np.ndarray], np.ndarray],
    *,
    name: str | None = None,
    precision: int = 7,
    chunk: int = CHUNK,
    crs: str | None = None,
    attribution: str | None = None,
    counts: dict | None = None,
) -> Iterator[str]:
    """The RFC 7946 FeatureCollection of ``layer`` as pieces of JSON text (sorted keys).

    Values are rendered column by column (ints with ``str``, floats with
    ``repr`` as :mod:`json` does, strings through :func:`json.dumps` once per
    distinct value) and features are assembled with one ``%`` template, which
    keeps a layer of thousands of features in the milliseconds.  ``chunk``
    features at a time, so that a whole city's layer never sits in memory as
    text; the pieces join to the same text for any ``chunk``.  ``crs``
    (``"EPSG:n"``) names a frame other than WGS84 that ``to_lonlat`` maps
    to; ``attribution`` is the data's licence notice.
    """
    geoms, keep = output_geometries(layer.geometry, to_lonlat, precision=precision)
    parent = layer.parent
    if (parent < 0).any():
        parent = parent.astype(object)
        parent[layer.parent < 0] = None
    cols = {"id": layer.ids, "parent_id": parent, **dict(layer.attrs)}
    for key in layer.meta.get("null_negative", ()):  # integer references where negative means none
        col = np.asarray(cols[key])
        cols[key] = np.where(col < 0, None, col.astype(object))
    ids = layer.ids
    if not keep.all():
        geoms, ids = geoms[keep], ids[keep]
        cols = {k: np.asarray(v)[keep] for k, v in cols.items()}
        log.info("%s: %d features left empty by rounding, not written", name or "layer", int((~keep).sum()))
    if counts is not None:
        counts.update(features=int(keep.sum()), collapsed=int((~keep).sum()))
    keys = sorted(cols)
    props = "{" + ",".join(_dumps(k).replace("%", "%%") + ":%s" for k in keys) + "}"
    feature = '{"geometry":%s,"id":%s,"properties":' + props + ',"type":"Feature"}'  # one template a feature
    head = "{"
    if attribution:
        head += '"attribution":' + _dumps(attribution) + ","
    if crs and crs.upper() not in ("EPSG:4326", "OGC:CRS84"):
        code = crs.split(":")[-1]
        head += '"crs":{"properties":{"name":' + _dumps(f"urn:ogc:def:crs:EPSG::{code}") + '},"type":"name"},'
    yield head + '"features":['
    advance(int((~keep).sum()))  # the features left out count as done
    for lo in range(0, len(geoms), max(int(chunk), 1)):
        part = slice(lo, lo + max(int(chunk), 1))
        geo_texts = [("null" if t is None else t) for t in shapely.to_geojson(geoms[part]).tolist()]
        texts = [_column_texts(cols[k][part]) for k in keys]
        id_texts = _column_texts(ids[part])
        yield ("," if lo else "") + ",".join([feature % row for row in zip(geo_texts, id_texts, *texts, strict=False)])
        advance(len(geo_texts))  # written: counted for the run's progress (sengine.progress)
    yield "]" + (',"name":' + _dumps(name) if name else "") + ',"type":"FeatureCollection"}'


def feature_collection_text(
    layer: Layer, to_lonlat: Callable[[np.ndarray], np.ndarray], *, name: str | None = None, precision: int = 7
) -> str:
    """The RFC 7946 FeatureCollection of ``layer`` as JSON text (see :func:`feature_collection_chunks`)."""
    return "".join(feature_collection_chunks(layer, to_lonlat, name=name, precision=precision))


def write_geojson(
    path: str | Path,
    layer: Layer,
    to_lonlat: Callable[[np.ndarray], np.ndarray],
    *,
    name: str | None = None,
    precision: int = 7,
    crs: str | None = None,
    attribution: str | None = None,
) -> int:
    """Write ``layer`` as RFC 7946 GeoJSON, a chunk of features at a time; return the number of features written."""
    counts: dict = {}
    with open(path, "w", encoding="utf-8") as f:
        for piece in feature_collection_chunks(
            layer, to_lonlat, name=name, precision=precision, crs=crs, attribution=attribution, counts=counts
        ):
            f.write(piece)
        f.write("\n")
    written = counts["features"]
    log.info("wrote %s: %d features", path, written)
    return written

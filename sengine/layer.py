"""The Layer: the columnar batch of features that streams between nodes.

A layer is a geometry column (a numpy object array of shapely 2 geometries),
stable integer feature ids, the id of each feature's parent in the layer it
was made from (``-1`` for none), and any number of attribute columns, each a
numpy array of the same length.  Layers are immutable by convention: methods
return new layers and never change their inputs.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely
import shapely.geometry

from .io.geojson import feature_collection_text

__all__ = ["Layer"]


def _column(values: Any, n: int, name: str) -> np.ndarray:
    arr = np.asarray(values)
    if arr.ndim == 0:
        arr = np.full(n, arr.item() if arr.dtype != object else values)
    if arr.shape != (n,):
        raise ValueError(f"column {name!r} has shape {arr.shape}, expected ({n},)")
    return arr


@dataclass(frozen=True, eq=False)
class Layer:
    """A columnar batch of features.

    Parameters
    ----------
    geometry : numpy.ndarray of shapely.Geometry
        One geometry per feature, in metres in the city's planar frame.
    ids : numpy.ndarray of int64
        Stable feature ids, unique within the layer.
    parent : numpy.ndarray of int64
        Id of each feature's parent feature upstream, ``-1`` for none.
    attrs : dict of str to numpy.ndarray
        Attribute columns, each of the same length as ``geometry``.
    meta : dict
        Layer-wide facts (for example the geographic origin); copied along.
    """

    geometry: np.ndarray
    ids: np.ndarray
    parent: np.ndarray
    attrs: Mapping[str, np.ndarray] = field(default_factory=dict)
    meta: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self):
        n = len(self.geometry)
        for name, col in (("ids", self.ids), ("parent", self.parent)):
            if len(col) != n:
                raise ValueError(f"{name} has length {len(col)}, expected {n}")
        for name, col in self.attrs.items():
            if len(col) != n:
                raise ValueError(f"column {name!r} has length {len(col)}, expected {n}")

    # -- construction -------------------------------------------------------
    @classmethod
    def from_geoms(
        cls,
        geoms: Iterable[Any],
        *,
        ids: Iterable[int] | None = None,
        parent: Iterable[int] | int | None = None,
        meta: Mapping[str, Any] | None = None,
        **attrs: Any,
    ) -> Layer:
        """Build a layer from geometries; ids default to ``0..n-1``."""
        geoms = list(geoms) if not isinstance(geoms, np.ndarray) else geoms
        geometry = np.empty(len(geoms), dtype=object)
        if isinstance(geoms, np.ndarray) and geoms.ndim == 1 and geoms.dtype == object:
            geometry[:] = geoms  # references copied array to array: no Python list (200,000 geometries: 20 -> 1 ms)
        else:
            geometry[:] = list(geoms)
        n = len(geometry)
        ids_arr = np.arange(n, dtype=np.int64) if ids is None else np.asarray(ids, np.int64)
        par = np.full(n, -1, np.int64) if parent is None else _column(parent, n, "parent").astype(np.int64)
        cols = {k: _column(v, n, k) for k, v in attrs.items()}
        return cls(geometry, ids_arr, par, cols, dict(meta or {}))

    @classmethod
    def empty(cls, meta: Mapping[str, Any] | None = None, **columns: np.dtype) -> Layer:
        """An empty layer, optionally with typed empty columns."""
        attrs = {k: np.empty(0, dtype=v) for k, v in columns.items()}
        return cls(np.empty(0, object), np.empty(0, np.int64), np.empty(0, np.int64), attrs, dict(meta or {}))

    @classmethod
    def concat(cls, layers: Iterable[Layer], *, renumber: bool = True) -> Layer:
        """Stack layers; columns missing from a layer are filled with defaults."""
        layers = [lay for lay in layers]
        if not layers:
            return cls.empty()
        names: list[str] = []
        for lay in layers:
            names += [k for k in lay.attrs if k not in names]
        cols = {}
        for name in names:
            parts = []
            proto = next(lay.attrs[name] for lay in layers if name in lay.attrs)
            for lay in layers:
                if name in lay.attrs:
                    parts.append(lay.attrs[name])
                else:
                    parts.append(np.full(len(lay), _default(proto.dtype), dtype=proto.dtype))
            cols[name] = np.concatenate(parts)
        geometry = np.concatenate([lay.geometry for lay in layers])
        parent = np.concatenate([lay.parent for lay in layers])
        ids = np.arange(len(geometry), dtype=np.int64) if renumber else np.concatenate([lay.ids for lay in layers])
        meta: dict[str, Any] = {}
        for lay in layers:
            meta.update(lay.meta)
        return cls(geometry, ids, parent, cols, meta)

    # -- access ---------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.geometry)

    def __getitem__(self, name: str) -> np.ndarray:
        if name == "id":
            return self.ids
        if name == "parent_id":
            return self.parent
        return self.attrs[name]

    def __contains__(self, name: str) -> bool:
        return name in self.attrs or name in ("id", "parent_id")

    def get(self, name: str, default: Any = None) -> Any:
        """The attribute column ``name``, or ``default`` when the layer has none."""
        return self.attrs.get(name, default)

    @property
    def columns(self) -> list[str]:
        """The attribute columns' names, in order."""
        return list(self.attrs)

    def rows_of(self, ids) -> np.ndarray:
        """Row of the feature with each of ``ids`` (``-1`` for ids not in the layer)."""
        ids = np.asarray(ids, np.int64)
        if not len(self):
            return np.full(len(ids), -1, np.int64)
        order = np.argsort(self.ids, kind="stable")
        pos = order[np.minimum(np.searchsorted(self.ids, ids, sorter=order), len(order) - 1)]
        return np.where(self.ids[pos] == ids, pos, -1)

    def take(self, index: np.ndarray) -> Layer:
        """The features selected by a boolean mask or an integer index."""
        index = np.asarray(index)
        return Layer(
            self.geometry[index],
            self.ids[index],
            self.parent[index],
            {k: v[index] for k, v in self.attrs.items()},
            dict(self.meta),
        )

    def with_columns(self, **columns: Any) -> Layer:
        """A copy with columns added or replaced."""
        n = len(self)
        attrs = dict(self.attrs)
        attrs.update({k: _column(v, n, k) for k, v in columns.items()})
        return Layer(self.geometry, self.ids, self.parent, attrs, dict(self.meta))

    def with_geometry(self, geometry: np.ndarray) -> Layer:
        """A copy with the geometry column replaced (same length)."""
        g = np.empty(len(self), dtype=object)
        g[:] = list(geometry)
        return Layer(g, self.ids, self.parent, dict(self.attrs), dict(self.meta))

    def with_meta(self, **meta: Any) -> Layer:
        """A copy with meta entries added or replaced."""
        return Layer(self.geometry, self.ids, self.parent, dict(self.attrs), {**self.meta, **meta})

    def area(self) -> float:
        """Total area of the features (m2)."""
        return float(shapely.area(self.geometry).sum()) if len(self) else 0.0

    # -- geopandas, networkx and the geo interface --------------------------------------------
    @property
    def __geo_interface__(self) -> dict:
        """The layer as a GeoJSON-like FeatureCollection in its planar frame, full precision.

        What ``shapely.geometry.shape``, ``geopandas.GeoDataFrame.from_features``
        and other readers of the geo interface take: ``properties`` hold
        ``id``, ``parent_id`` and every attribute as Python values.
        """
        names = list(self.attrs)
        cols = [self.attrs[k].tolist() for k in names]
        ids, parent = self.ids.tolist(), self.parent.tolist()
        feats = []
        for i, g in enumerate(self.geometry):
            props = {"id": ids[i], "parent_id": parent[i], **{k: c[i] for k, c in zip(names, cols)}}
            geom = shapely.geometry.mapping(g) if g is not None else None
            feats.append({"type": "Feature", "id": ids[i], "geometry": geom, "properties": props})
        return {"type": "FeatureCollection", "features": feats}

    def to_geopandas(self):
        """A ``geopandas.GeoDataFrame``: columns ``id``, ``parent_id``, every attribute, and ``geometry``.

        The CRS is ``meta["crs"]`` (planar metres) when the layer has one;
        the rest of the meta that is plain data (numbers, text, tuples) is
        kept in ``gdf.attrs["sengine_meta"]`` so :meth:`from_geopandas` gives
        it back.  Needs the optional dependency geopandas
        (``pip install sengine[geo]``).
        """
        gpd = _geopandas()
        data = {"id": self.ids, "parent_id": self.parent, **dict(self.attrs)}
        gdf = gpd.GeoDataFrame(data, geometry=gpd.GeoSeries(self.geometry), crs=self.meta.get("crs"))
        gdf.attrs["sengine_meta"] = {k: v for k, v in self.meta.items() if _plain(v)}
        return gdf

    @classmethod
    def from_geopandas(cls, gdf, *, meta: Mapping[str, Any] | None = None) -> Layer:
        """A layer from a ``geopandas.GeoDataFrame`` (the inverse of :meth:`to_geopandas`).

        ``id`` and ``parent_id`` columns become the feature ids and parents
        (else ``0..n-1`` and ``-1``); every other column becomes an attribute
        column (pandas text columns as object arrays); the frame's CRS goes to
        ``meta["crs"]``.  The geometries must be in metres for the nodes to
        make sense of them: project first (``gdf.to_crs(...)``) if they are
        in degrees.
        """
        geom_col = gdf.geometry.name
        cols = {}
        for name in gdf.columns:
            if name == geom_col:
                continue
            values = gdf[name].to_numpy()
            if values.dtype == object and len(values) and all(isinstance(v, bool) for v in values):
                values = values.astype(bool)
            cols[str(name)] = values
        ids = cols.pop("id", None)
        parent = cols.pop("parent_id", None)
        info = dict(gdf.attrs.get("sengine_meta", {}))
        if gdf.crs is not None:
            info["crs"] = gdf.crs.to_string() if info.get("crs") is None else info["crs"]
        info.update(meta or {})
        geoms = np.asarray(gdf.geometry.values, dtype=object)
        return cls.from_geoms(geoms, ids=ids, parent=parent, meta=info, **cols)

    def to_networkx(self):
        """The street graph of a line layer as a ``networkx.MultiGraph`` (as osmnx draws one).

        Nodes are the lines' end points: the junction indices ``u`` / ``v``
        with ``meta["nodes"]`` (what ``osm.read`` and ``roads.clean`` give),
        else the distinct end coordinates; each carries ``x`` and ``y`` (m).
        One edge per feature, keyed by its id, with every attribute, the
        ``geometry`` and its ``length`` (m).  The graph's ``crs`` is
        ``meta["crs"]``.
        """
        import networkx as nx

        n = len(self)
        start = shapely.get_coordinates(shapely.get_point(self.geometry, 0)) if n else np.empty((0, 2))
        end = shapely.get_coordinates(shapely.get_point(self.geometry, -1)) if n else np.empty((0, 2))
        if "u" in self.attrs and "v" in self.attrs and "nodes" in self.meta:
            xy = np.asarray(self.meta["nodes"], np.float64).reshape(-1, 2)
            u, v = np.asarray(self["u"], np.int64), np.asarray(self["v"], np.int64)
        else:
            xy, inv = np.unique(np.vstack([start, end]), axis=0, return_inverse=True)
            inv = inv.ravel()
            u, v = inv[:n], inv[n:]
        g = nx.MultiGraph(crs=self.meta.get("crs"))
        used = np.unique(np.r_[u, v]) if n else np.empty(0, np.int64)
        g.add_nodes_from((int(k), {"x": float(xy[k, 0]), "y": float(xy[k, 1])}) for k in used)
        length = shapely.length(self.geometry) if n else np.zeros(0)
        names = list(self.attrs)
        for i in range(n):
            data = {
                k: self.attrs[k][i].item() if hasattr(self.attrs[k][i], "item") else self.attrs[k][i] for k in names
            }
            data.update(geometry=self.geometry[i], length=float(length[i]))
            g.add_edge(int(u[i]), int(v[i]), key=int(self.ids[i]), **data)
        return g

    # -- GeoJSON --------------------------------------------------------------
    def to_geojson(self, transform: Callable[[np.ndarray], np.ndarray] | None = None, *, precision: int = 7) -> dict:
        """A GeoJSON FeatureCollection with every attribute as a property.

        ``transform`` maps an (n, 2) array of planar coordinates to the output
        frame (for RFC 7946 output: WGS84 lon/lat); identity when omitted.
        Written by the same code as the GeoJSON exporter
        (:func:`sengine.io.geojson.feature_collection_text`).
        """
        return json.loads(feature_collection_text(self, transform or (lambda xy: xy), precision=precision))

    @classmethod
    def from_geojson(cls, data: Mapping[str, Any]) -> Layer:
        """Read a FeatureCollection written by :meth:`to_geojson` (planar)."""
        feats = data.get("features", [])
        geoms = shapely.from_geojson([json.dumps(f["geometry"]) for f in feats]) if feats else []
        props = [dict(f.get("properties") or {}) for f in feats]
        ids = [p.pop("id", i) for i, p in enumerate(props)]
        parent = [-1 if v is None else v for v in (p.pop("parent_id", -1) for p in props)]
        names: list[str] = []
        for p in props:
            names += [k for k in p if k not in names]
        cols = {k: np.asarray([p.get(k) for p in props]) for k in names}
        return cls.from_geoms(geoms, ids=ids, parent=parent, **cols)


def _geopandas():
    try:
        import geopandas
    except ImportError:  # pragma: no cover - depends on the environment
        raise ImportError("Layer.to_geopandas needs geopandas: pip install 'sengine[geo]'") from None
    return geopandas


def _plain(value: Any) -> bool:
    """Whether a meta value is plain data worth carrying through a GeoDataFrame."""
    if isinstance(value, (str, int, float, bool)) or value is None:
        return True
    return isinstance(value, tuple) and all(isinstance(v, (str, int, float, bool)) for v in value)


def _default(dtype: np.dtype) -> Any:
    """The fill of a column missing from a layer: -1 (all ones when unsigned), NaN, False, "" or None."""
    if dtype.kind == "i":
        return -1
    if dtype.kind == "u":  # -1 does not fit an unsigned column (NumPy 2 raises): its bit pattern does
        return np.iinfo(dtype).max
    if dtype.kind == "f":
        return np.nan
    if dtype.kind == "b":
        return False
    if dtype.kind in "US":
        return ""
    return None

"""Layers made fit to open: clean geometry, rounded values, nulls, district and land-use names.

Every exporter of ``export.city`` writes the layers this module returns, so
that a GIS user finds in each file:

* valid, non-empty geometries with area (polygons) or length (lines), of
  one type per layer (Multi* for all when any feature needs it), their
  coordinates on a millimetre grid (:func:`sengine.geom.cleanup.clean_geometries`);
  what was repaired or dropped is counted in the run's report;
* lengths, heights and areas rounded to the millimetre (every float column
  to :data:`DECIMALS` decimals: ``73.6``, not ``73.60000000000001``);
* nulls where a value is missing: an empty string becomes ``None``, and a
  negative reference (``district``, ``lot``, ``block``, ``osm_id`` ... of
  ``-1``) stays an integer column named in ``meta["null_negative"]``, which
  the writers write as null (as they do ``parent_id`` ``-1``);
* ``district_name``, the ``name`` of the configuration's ``<district>``
  rule a feature's ``district`` index points to, and ``landuse``, its
  land-use class: ``park`` and ``water`` for those layers, and for the built
  layers (blocks, lots, buildings) the plan's buildable ``<landuse>`` class
  when it has exactly one.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping

import numpy as np
import shapely

from sengine.geom.cleanup import GRID, clean_geometries, snap_to_type
from sengine.geom.crs import layer_crs, to_lonlat
from sengine.layer import Layer

from ..roads.districts import _rules, landuse_classes

__all__ = ["DECIMALS", "REFERENCE_COLUMNS", "prepare_layer", "prepare_layers", "district_names", "built_landuse"]

log = logging.getLogger(__name__)

#: Decimals kept by float columns: a millimetre for lengths and heights.
DECIMALS = 3
#: Integer columns in which a negative value means "none" (written as null).
REFERENCE_COLUMNS = frozenset({"district", "lot", "block", "face", "osm_id", "building", "park", "parent"})
#: Layers whose features stand on buildable land.
BUILT_LAYERS = frozenset({"blocks", "lots", "buildings"})
#: The land-use class of every feature of these layers.
LAYER_LANDUSE = {"parks": "park", "water": "water"}


def district_names(rules) -> list[str] | None:
    """Name of each ``<district>`` rule, by index (``d<i>`` when unnamed); None without rules.

    ``rules``: a ``district_rules`` layer, a list of rules or None.
    """
    rules = _rules(rules, "district")
    if not rules:
        return None
    return [str(r.get("name") or f"d{i}") for i, r in enumerate(rules)]


def built_landuse(rules) -> str | None:
    """The one buildable ``<landuse>`` class, or None (none, or several: not known per feature)."""
    buildable = sorted({cls for _, cls, ok, _ in landuse_classes(rules, colour=False) if ok})  # no map needed
    return buildable[0] if len(buildable) == 1 else None


def _nullable(col: np.ndarray, missing: np.ndarray) -> np.ndarray:
    out = col.astype(object)
    out[missing] = None
    return out


#: Lines shorter, and polygons thinner (area / perimeter), than this (m) are also tried on the
#: WGS84 grid of the GeoJSON output (1e-7 deg, about a centimetre): those it folds to nothing are dropped.
PROBE_SIZE = 0.05


def _collapse_in_wgs84(geoms: np.ndarray, to_ll: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """Which features the 1e-7 degree grid of WGS84 outputs would fold to nothing (only small ones are tried)."""
    out = np.zeros(len(geoms), bool)
    if len(geoms) == 0:
        return out
    dim = int(shapely.get_dimensions(geoms[0]))
    if dim == 1:
        small = shapely.length(geoms) < PROBE_SIZE
    elif dim == 2:
        small = shapely.area(geoms) < PROBE_SIZE * shapely.length(geoms)
    else:
        return out
    if small.any():
        type_id = int(shapely.get_type_id(geoms[0]))
        ll = shapely.transform(geoms[small], to_ll)
        _, collapsed = snap_to_type(ll, 1e-7, type_id)
        out[np.flatnonzero(small)[collapsed]] = True
    return out


def _empty(col: np.ndarray) -> np.ndarray:
    """Which values of an object column are None or the empty text (compared in C, not a Python loop)."""
    try:
        return np.asarray(np.equal(col, None) | np.equal(col, ""), bool)
    except (ValueError, TypeError):  # a value whose comparison is no truth value (an array)
        return np.array([v is None or (isinstance(v, str) and v == "") for v in col.tolist()], bool)


def prepare_layer(
    name: str,
    layer: Layer,
    *,
    districts: list[str] | None = None,
    landuse: str | None = None,
    grid: float = GRID,
    to_ll: Callable[[np.ndarray], np.ndarray] | None = None,
) -> tuple[Layer, dict]:
    """One layer cleaned for writing; returns the layer and its counts (see :func:`clean_geometries`).

    Parameters
    ----------
    name : str
        Layer name (``lots``, ``parks`` ...).
    layer : Layer
        The layer (m, planar).
    districts : list of str, optional
        District names by index, for a ``district_name`` column.
    landuse : str, optional
        Land-use class of every feature without one.
    grid : float
        Coordinate grid (m).
    to_ll : callable, optional
        Planar -> WGS84 lon / lat: small features that the WGS84 outputs'
        grid would fold to nothing are dropped here (``dropped_degenerate``),
        so that every format writes the same features.
    """
    geoms, keep, counts = clean_geometries(layer.geometry, grid)
    if to_ll is not None:
        gone = _collapse_in_wgs84(geoms, to_ll)
        if gone.any():
            kept = np.flatnonzero(keep)
            keep[kept[gone]] = False
            geoms = geoms[~gone]
            counts["dropped_degenerate"] += int(gone.sum())
    lay = layer if keep.all() else layer.take(keep)
    cols: dict[str, np.ndarray] = {}
    null_negative = []
    for key, col in lay.attrs.items():
        col = np.asarray(col)
        kind = col.dtype.kind
        if kind == "f":
            col = np.round(col, DECIMALS)
        elif kind in "iu" and key in REFERENCE_COLUMNS and (col < 0).any():
            null_negative.append(key)
        elif kind in "US":
            col = _nullable(col, col == "") if (col == "").any() else col
        elif kind == "O":
            if shapely.is_geometry(col).any():
                continue  # working geometry (a block's street front), not an attribute
            empty = _empty(col)
            if empty.any():
                col = col.copy()
                col[empty] = None
        cols[key] = col
    if districts is not None and "district" in lay.attrs:
        d = np.asarray(lay.attrs["district"])
        if d.dtype.kind in "iu":
            table = np.array([*districts, None], dtype=object)
            cols["district_name"] = table[np.where((d >= 0) & (d < len(districts)), d, len(districts))]
    default_use = LAYER_LANDUSE.get(name) or (landuse if name in BUILT_LAYERS else None)
    if default_use is not None and "landuse" not in cols:
        cols["landuse"] = np.full(len(lay), default_use, dtype=object)
    meta = dict(lay.meta)
    if null_negative:
        meta["null_negative"] = tuple(null_negative)
    out = Layer(geoms, lay.ids, lay.parent, cols, meta)
    return out, counts


def prepare_layers(
    layers: Mapping[str, Layer], rules: Mapping | None = None, *, origin=(41.9794, 2.8214), grid: float = GRID
) -> tuple[dict[str, Layer], dict]:
    """Every layer through :func:`prepare_layer`; returns the layers and ``{layer: counts}`` of the non-zero counts.

    ``rules`` maps ``district`` and ``landuse`` to their rules (layers or
    lists); ``origin`` (lat, lon) places layers without ``meta["crs"]``.
    """
    rules = rules or {}
    districts = district_names(rules.get("district"))
    landuse = built_landuse(rules.get("landuse"))
    out: dict[str, Layer] = {}
    report: dict[str, dict] = {}
    for name, lay in layers.items():
        to_ll = to_lonlat(layer_crs(lay.meta, origin))
        out[name], counts = prepare_layer(name, lay, districts=districts, landuse=landuse, grid=grid, to_ll=to_ll)
        counts = {k: v for k, v in counts.items() if v}
        if counts:
            report[name] = counts
            log.info("%s: %s", name, ", ".join(f"{k} {v}" for k, v in counts.items()))
    return out, report

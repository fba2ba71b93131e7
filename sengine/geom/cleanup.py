"""Clean output geometry: snapped to a grid, valid, non-degenerate, one type per layer.

What a GIS user opens must pass ``ST_IsValid``, hold no empty, zero-area or
zero-length feature, and have one geometry type per layer (GDAL calls a layer
that mixes Polygon and MultiPolygon ``Unknown``).  Every exported layer goes
through :func:`clean_geometries` once in its planar frame, and each writer
snaps again in its output frame (:func:`snap`), since rounding projected
coordinates can itself fold a thin polygon.

The work is vectorized: coordinates are rounded with one numpy call,
validity is tested with one GEOS call, and only the few invalid features
are repaired one by one (``make_valid`` with the *structure* method, which
keeps polygons polygonal, then GEOS's snap-rounding ``set_precision`` so the
repaired feature lies on the grid as well).
"""

from __future__ import annotations

import numpy as np
import shapely

__all__ = [
    "GRID",
    "round_coordinates",
    "snap",
    "snap_to_type",
    "dominant_dimension",
    "clean_geometries",
    "unify_type",
    "layer_type",
]

#: The grid output coordinates are snapped to in a projected frame (m): a millimetre.
GRID = 0.001

_EMPTY = {0: "POINT EMPTY", 1: "LINESTRING EMPTY", 2: "POLYGON EMPTY"}
_MAKE_MULTI = {0: shapely.multipoints, 1: shapely.multilinestrings, 2: shapely.multipolygons}


def _decimals(grid: float) -> int:
    return int(round(-np.log10(grid)))


def round_coordinates(geoms: np.ndarray, grid: float = GRID) -> np.ndarray:
    """Geometries with every coordinate rounded to a multiple of ``grid`` (a power of ten)."""
    geoms = np.asarray(geoms, dtype=object)
    if len(geoms) == 0:
        return geoms
    coords = shapely.get_coordinates(geoms)
    return shapely.set_coordinates(geoms.copy(), np.round(coords, _decimals(grid)))


def _parts_of_dimension(geoms: np.ndarray, dim: int) -> np.ndarray:
    """Each geometry reduced to its parts of dimension ``dim``: one part as itself, several as a Multi*.

    A geometry with no such part becomes an empty one.
    """
    geoms = np.asarray(geoms, dtype=object)
    parts, idx = shapely.get_parts(geoms, return_index=True)
    keep = (shapely.get_dimensions(parts) == dim) & ~shapely.is_empty(parts)
    parts, idx = parts[keep], idx[keep]
    out = np.full(len(geoms), shapely.from_wkt(_EMPTY[dim]), dtype=object)
    counts = np.bincount(idx, minlength=len(geoms))
    alone = counts[idx] == 1
    out[idx[alone]] = parts[alone]
    several = np.flatnonzero(counts > 1)
    if len(several):
        sel = ~alone
        out[several] = _MAKE_MULTI[dim](parts[sel], indices=np.searchsorted(several, idx[sel]))
    return out


def snap(
    geoms: np.ndarray, grid: float = GRID, dim: int | None = None, *, rounded: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Round coordinates to ``grid`` and repair the features that this (or their input) made invalid.

    Parameters
    ----------
    geoms : array of shapely geometries
        In any frame (m for a projected one, degrees for WGS84).
    grid : float
        Power of ten the coordinates are rounded to (0.001 m; 1e-7 deg).
    dim : int, optional
        Dimension the features must keep (2 polygons, 1 lines); default
        :func:`dominant_dimension`.
    rounded : bool
        The coordinates are already on the grid: only repair.

    Returns
    -------
    geoms : numpy.ndarray
        The snapped geometries; a repaired one keeps only its parts of
        dimension ``dim`` (possibly none: an empty geometry).
    repaired : numpy.ndarray of bool
        The features that had to be repaired.
    """
    out = np.asarray(geoms, dtype=object).copy() if rounded else round_coordinates(geoms, grid)
    if len(out) == 0:
        return out, np.zeros(0, bool)
    dim = dominant_dimension(out) if dim is None else dim
    bad = ~shapely.is_valid(out) & ~shapely.is_empty(out)
    if bad.any():
        with np.errstate(all="ignore"):  # GEOS's floating point on degenerate input is not an error here
            return _repair(out, np.asarray(geoms, dtype=object), bad, grid, dim), bad
    return out, bad


def _repair(out: np.ndarray, geoms: np.ndarray, bad: np.ndarray, grid: float, dim: int) -> np.ndarray:
    """``out`` with its ``bad`` features rebuilt from ``geoms``: valid, on the grid, of dimension ``dim``."""
    fixed = shapely.make_valid(geoms[bad], method="structure", keep_collapsed=False)
    fixed = shapely.set_precision(fixed, grid)
    fixed = _parts_of_dimension(fixed, dim)
    still = ~shapely.is_valid(fixed)
    if still.any():  # snap rounding folded it again: GEOS's repair on the grid, then keep the right parts
        fixed[still] = _parts_of_dimension(
            shapely.set_precision(shapely.make_valid(fixed[still], method="structure"), grid), dim
        )
    out[bad] = fixed
    return out


def dominant_dimension(geoms: np.ndarray) -> int:
    """The dimension most features have (0 points, 1 lines, 2 polygons); the higher one on a tie, -1 if none."""
    dims = shapely.get_dimensions(np.asarray(geoms, dtype=object))
    dims = dims[dims >= 0]
    if len(dims) == 0:
        return -1
    counts = np.bincount(dims, minlength=3)
    return int(2 - np.argmax(counts[::-1]))


def unify_type(geoms: np.ndarray) -> np.ndarray:
    """Every single-part feature as a one-part Multi* when some feature of the layer is Multi*.

    The input holds features of one dimension; empty ones are left alone.
    """
    geoms = np.asarray(geoms, dtype=object)
    if len(geoms) == 0:
        return geoms
    types = shapely.get_type_id(geoms)
    multi = np.isin(types, (4, 5, 6))
    single = np.isin(types, (0, 1, 3)) & ~shapely.is_empty(geoms)
    if not multi.any() or not single.any():
        return geoms
    out = geoms.copy()
    for t, make in ((0, shapely.multipoints), (1, shapely.multilinestrings), (3, shapely.multipolygons)):
        sel = np.flatnonzero(single & (types == t))
        if len(sel):
            out[sel] = make(geoms[sel], indices=np.arange(len(sel)))
    return out


def clean_geometries(
    geoms: np.ndarray, grid: float = GRID, *, min_area: float = 1e-6, min_length: float = 1e-3
) -> tuple[np.ndarray, np.ndarray, dict]:
    """The features of a layer made fit to write: snapped, valid, non-degenerate, of one type.

    Parameters
    ----------
    geoms : array of shapely geometries
        One layer (m, planar).
    grid : float
        Coordinate grid (m).
    min_area : float
        Polygonal features with less area are degenerate and dropped (m2).
    min_length : float
        Line features shorter than this are degenerate and dropped (m).

    Returns
    -------
    geoms : numpy.ndarray
        The kept features, snapped, valid and of one type (Multi* for all
        when any needs it).
    keep : numpy.ndarray of bool
        Which input features were kept.
    counts : dict
        ``repaired`` (invalid features made valid), ``dropped_empty``,
        ``dropped_degenerate`` (zero area or length, or nothing of the
        layer's dimension left after repair), ``dropped_type`` (features of
        another dimension than most of the layer's: a point in a road
        layer).
    """
    geoms = np.asarray(geoms, dtype=object)
    counts = {"repaired": 0, "dropped_empty": 0, "dropped_degenerate": 0, "dropped_type": 0}
    if len(geoms) == 0:
        return geoms, np.zeros(0, bool), counts
    missing = np.array([g is None for g in geoms.tolist()], bool)
    empty = missing.copy()
    empty[~missing] = shapely.is_empty(geoms[~missing])
    dim = dominant_dimension(geoms[~empty])
    gdim = np.full(len(geoms), -1)
    gdim[~empty] = shapely.get_dimensions(geoms[~empty])
    # a collection holding parts of the layer's dimension keeps those parts
    coll = ~empty & (shapely.get_type_id(np.where(missing, None, geoms)) == 7)
    fixed = geoms.copy()
    if coll.any() and dim >= 0:
        fixed[coll] = _parts_of_dimension(geoms[coll], dim)
        gdim[coll] = np.where(shapely.is_empty(fixed[coll]), -1, dim)
    other = ~empty & (gdim != dim)
    live = ~empty & ~other
    out = np.empty(len(geoms), dtype=object)
    snapped, repaired = snap(fixed[live], grid, dim)
    out[live] = snapped
    size = np.zeros(len(geoms))
    if dim == 2:
        size[live] = shapely.area(snapped)
        small = min_area
    elif dim == 1:
        size[live] = shapely.length(snapped)
        small = min_length
    else:
        size[live] = np.where(shapely.is_empty(snapped), 0.0, 1.0)
        small = 0.5
    degenerate = live & (size < small)
    keep = live & ~degenerate
    counts["repaired"] = int(repaired.sum())
    counts["dropped_empty"] = int(empty.sum())
    counts["dropped_degenerate"] = int(degenerate.sum())
    counts["dropped_type"] = int(other.sum())
    return unify_type(out[keep]), keep, counts


_TYPE_NAMES = {0: "Point", 1: "LineString", 3: "Polygon", 4: "MultiPoint", 5: "MultiLineString", 6: "MultiPolygon"}
_DIM_OF_TYPE = {0: 0, 1: 1, 3: 2, 4: 0, 5: 1, 6: 2}


def layer_type(geoms: np.ndarray) -> str:
    """The one geometry type of a cleaned layer (``"Polygon"``, ``"MultiPolygon"`` ...; ``"Unknown"`` if empty)."""
    types = np.unique(shapely.get_type_id(np.asarray(geoms, dtype=object)))
    types = types[types >= 0]
    if len(types) == 1 and int(types[0]) in _TYPE_NAMES:
        return _TYPE_NAMES[int(types[0])]
    return "Unknown"


def snap_to_type(
    geoms: np.ndarray, grid: float, type_id: int, *, rounded: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Snap features already cleaned in another frame, keeping them valid and of the layer's type.

    A writer calls this after reprojecting a cleaned layer: rounding the new
    coordinates may fold a thin feature, which is then repaired on the grid.
    A repair that splits a feature of a single-part layer keeps its largest
    part; one that leaves nothing is reported.

    Parameters
    ----------
    geoms : array of shapely geometries
        Reprojected features of one type.
    grid : float
        Power of ten the output coordinates are rounded to.
    type_id : int
        The layer's shapely type id (:func:`shapely.get_type_id`).
    rounded : bool
        The coordinates are already on the grid: only repair.

    Returns
    -------
    geoms : numpy.ndarray
    collapsed : numpy.ndarray of bool
        Features left empty (or degenerate) by the snap: the writer drops them.
    """
    if type_id not in _DIM_OF_TYPE:
        out = np.asarray(geoms, dtype=object) if rounded else round_coordinates(geoms, grid)
        return out, np.zeros(len(out), bool)
    dim = _DIM_OF_TYPE[type_id]
    out, repaired = snap(geoms, grid, dim, rounded=rounded)
    collapsed = np.zeros(len(out), bool)
    if repaired.any():
        idx = np.flatnonzero(repaired)
        fixed = out[idx]
        multi = np.isin(shapely.get_type_id(fixed), (4, 5, 6))
        if type_id in (0, 1, 3) and multi.any():  # keep the largest part
            for k in np.flatnonzero(multi).tolist():
                parts = shapely.get_parts(fixed[k])
                size = shapely.area(parts) if dim == 2 else shapely.length(parts)
                fixed[k] = parts[int(np.argmax(size))]
        elif type_id in (4, 5, 6):
            single = np.isin(shapely.get_type_id(fixed), (0, 1, 3)) & ~shapely.is_empty(fixed)
            if single.any():
                fixed[single] = _MAKE_MULTI[dim](fixed[single], indices=np.arange(int(single.sum())))
        size = shapely.area(fixed) if dim == 2 else shapely.length(fixed) if dim == 1 else np.ones(len(fixed))
        collapsed[idx] = shapely.is_empty(fixed) | (size <= 0)
        out[idx] = fixed
    return out, collapsed

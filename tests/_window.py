"""One query window read from a city's GeoJSON, GeoPackage and GeoParquet files, as their users read them.

A window is a polygon stated in one planar frame (the city's UTM zone, the
frame of ``city.gpkg`` and ``<layer>.parquet``).  Each file is asked for the
features whose geometry meets that polygon, in the file's own frame:

* GeoJSON (WGS84) and GeoPackage through GDAL (pyogrio ``mask=``, which is
  ``ogr2ogr -spat`` / ``-clipsrc``'s filter): the window, densified and
  reprojected to the file's CRS, is the layer's spatial filter; GDAL tests
  the boxes (the GeoPackage's R-tree) and then the geometries;
* GeoParquet through pyarrow: the rows whose ``bbox`` covering meets the
  window's box (the row groups outside it are skipped), then the geometries
  themselves (``shapely.intersects``), as GDAL's Parquet driver, DuckDB's
  ``ST_Intersects`` or GeoPandas' ``.intersects`` after ``bbox=`` do.

A box read of a GeoJSON in lon / lat spanned by two reprojected corners is
not the same window (the UTM grid is turned by its convergence, about 2° in
Liège), and the covering alone answers "which boxes meet the window", not
"which features": both made the three files seem to disagree.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import shapely

#: Largest edge (m, in the window's frame) of the densified window before it is reprojected.
DENSIFY = 10.0


def file_crs(path: Path, layer: str | None = None) -> str:
    """The CRS of a GeoJSON / GeoPackage layer (GDAL) or of a GeoParquet file (its ``geo`` metadata)."""
    if Path(path).suffix == ".parquet":
        import json

        import pyarrow.parquet as pq
        from pyproj import CRS

        geo = json.loads(pq.read_schema(path).metadata[b"geo"])
        col = geo["columns"][geo["primary_column"]]
        return CRS.from_json_dict(col["crs"]).to_string() if "crs" in col else "EPSG:4326"
    import pyogrio

    return pyogrio.read_info(path, layer=layer)["crs"]


def window_in(window: shapely.Geometry, crs: str, target: str) -> shapely.Geometry:
    """``window`` (a polygon in ``crs``) in frame ``target``: edges densified, then every vertex reprojected."""
    from pyproj import Transformer

    if str(crs) == str(target):
        return window
    tr = Transformer.from_crs(crs, target, always_xy=True)
    dense = shapely.segmentize(window, DENSIFY)
    return shapely.transform(dense, lambda xy: np.column_stack(tr.transform(xy[:, 0], xy[:, 1])))


def window_ids(
    path: Path, window: shapely.Geometry, crs: str, *, layer: str | None = None, whole_rows: bool = False
) -> np.ndarray:
    """Sorted ids of the features of ``path`` (``layer`` of a GeoPackage) whose geometry meets ``window``.

    Parameters
    ----------
    path : Path
        ``<layer>.geojson``, ``city.gpkg`` or ``<layer>.parquet``.
    window : shapely.Geometry
        The query polygon, in ``crs``.
    crs : str
        The frame the window is stated in.
    layer : str, optional
        The GeoPackage table.
    whole_rows : bool
        Read every column, as a user reading the features does (for timing); else the ids and geometry only.
    """
    path = Path(path)
    target = file_crs(path, layer)
    win = window_in(window, crs, target)
    if path.suffix == ".parquet":
        import pyarrow.dataset as ds

        x0, y0, x1, y1 = shapely.bounds(win)
        f = (ds.field("bbox", "xmin") <= x1) & (ds.field("bbox", "xmax") >= x0)
        f &= (ds.field("bbox", "ymin") <= y1) & (ds.field("bbox", "ymax") >= y0)
        t = ds.dataset(path).to_table(columns=None if whole_rows else ["id", "geometry"], filter=f)
        g = shapely.from_wkb(t.column("geometry").to_numpy(zero_copy_only=False))
        ids = t.column("id").to_numpy()[shapely.intersects(g, win)]
    else:
        import pyogrio

        # the geometry is read: without it (read_geometry=False) GDAL keeps what the R-tree gives, untested
        if path.suffix == ".gpkg":  # the id is the table's fid
            t = pyogrio.read_arrow(path, layer=layer, mask=win, return_fids=True, columns=None if whole_rows else [])[1]
        else:
            t = pyogrio.read_arrow(path, layer=layer, mask=win, columns=None if whole_rows else ["id"])[1]
        ids = t.column("id").to_numpy()
    return np.sort(np.asarray(ids, np.int64))


def box_ids_as_before(path: Path, box: tuple, *, layer: str | None = None) -> np.ndarray:
    """Sorted ids read the way bench/export.py read them before: a box (in the file's own frame), no geometry test.

    GDAL (``bbox=``) does test the geometries; the GeoParquet covering filter alone does not.
    """
    path = Path(path)
    if path.suffix == ".parquet":
        import pyarrow.dataset as ds

        x0, y0, x1, y1 = box
        f = (ds.field("bbox", "xmin") <= x1) & (ds.field("bbox", "xmax") >= x0)
        f &= (ds.field("bbox", "ymin") <= y1) & (ds.field("bbox", "ymax") >= y0)
        ids = ds.dataset(path).to_table(columns=["id"], filter=f).column("id").to_numpy()
    else:
        import pyogrio

        kw = {"return_fids": True, "columns": []} if path.suffix == ".gpkg" else {"columns": ["id"]}
        ids = pyogrio.read_arrow(path, layer=layer, bbox=tuple(box), **kw)[1].column("id")
        ids = ids.to_numpy()
    return np.sort(np.asarray(ids, np.int64))

"""The exporter node: writes the city's layers to the run's output folder.

skylineEngine's output is a model for rendering and GIS (paper 002 §1, §5.2:
OSM is the vector format of the street modules).  ``export.city`` takes any
of the city's layers and writes, into ``context.out``, the formats asked for
with ``--format`` (``context.formats``; empty means the defaults):

========== ======================================= ========================
format     file(s)                                 writer
========== ======================================= ========================
glb        ``city.glb`` (node per layer, Y up, m)  :mod:`sengine.nodes.export.gltf`
geojson    ``<layer>.geojson`` (RFC 7946, WGS84)   :mod:`sengine.io.geojson`
osm        ``streets.osm`` (roads, OSM XML)        :mod:`sengine.nodes.export.osmxml`
png        ``preview.png`` (plan view)             :mod:`sengine.nodes.export.preview`
obj        ``city.obj`` + ``city.mtl``             :mod:`sengine.nodes.export.obj`
cityjson   ``buildings.city.json`` (LoD1 / LoD2)   :mod:`sengine.nodes.export.cityjson`
gpkg       ``city.gpkg`` (a table per layer)       :mod:`sengine.nodes.export.gpkg`
parquet    ``<layer>.parquet`` (GeoParquet 1.1)    :mod:`sengine.nodes.export.parquet`
html       ``index.html`` + ``city.view.js`` (3D)  :mod:`sengine.nodes.export.html`
========== ======================================= ========================

``lod`` (``--lod``) chooses the buildings of the 3D formats (glb, obj,
cityjson, html): 1 flat-roofed boxes, 2 with their roofs
(:mod:`sengine.nodes.export.roofs`).

Every layer is first made fit to open (:mod:`sengine.nodes.export.prepare`:
valid, non-degenerate geometry of one type per layer on a millimetre grid,
rounded values, nulls, district and land-use names); what was repaired or
dropped is counted in the report (``clean``).

The run's export options (``context.options``, from the command line):

* ``crs`` (``--crs utm|wgs84|EPSG:n``): the frame of the vector outputs.
  GeoPackage and GeoParquet default to ``utm``, the city's projected frame
  with an EPSG code; GeoJSON stays WGS84 (RFC 7946) unless asked; OSM XML
  is always WGS84.  Projected coordinates are rounded to the millimetre,
  geographic ones to 1e-7 degree (about a centimetre, OSM's precision).
* ``origin`` (``--origin local|geo``): ``local`` (default) places glb and
  OBJ vertices relative to the city's origin (its geographic origin in its
  planar frame, to the metre), kept as metadata (the glb's scene
  ``extras``, the OBJ's header, CityJSON's ``transform.translate``); ``geo``
  keeps the planar frame's coordinates (UTM for an OSM city).

Outputs made from OpenStreetMap carry "© OpenStreetMap contributors, ODbL"
(:data:`sengine.nodes.export.table.OSM_ATTRIBUTION`), as its licence asks.

Planar coordinates are read in each layer's ``meta["crs"]``, or the local
frame of the layers' geographic origin (``meta["origin"]``); ``preview.png``
is framed on the layers' city extent (``meta["extent"]``, set by synthetic
cities).  District names and the land-use class come from the
``district_rules`` and ``landuse_rules`` ports.  ``stats.json`` is the
executor's.

References
----------
.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from sengine import CityPlan, Layer, NodeResult, Param, Port, SENode, progress, register
from sengine.errors import ParameterError
from sengine.geom.crs import from_lonlat, is_geographic, layer_crs, output_crs, reproject, to_lonlat
from sengine.parallel import run_jobs

from .prepare import prepare_layers
from .table import OSM_ATTRIBUTION

__all__ = [
    "FORMATS",
    "DEFAULT_FORMATS",
    "FORMAT_HINTS",
    "ORIGINS",
    "north_angle",
    "city_origin",
    "export_layers",
    "export_formats",
    "early_solids",
    "ExportCity",
]

log = logging.getLogger(__name__)

FORMATS = ("glb", "geojson", "osm", "png", "obj", "cityjson", "gpkg", "parquet", "html")
# html: a city to look at in a browser with no other program (the page and its data, a few MB a city district)
DEFAULT_FORMATS = frozenset({"glb", "geojson", "osm", "png", "html"})
#: What to suggest for a format sengine does not write.
FORMAT_HINTS = {
    "shp": "gpkg",
    "shapefile": "gpkg",
    "geopackage": "gpkg",
    "geoparquet": "parquet",
    "gltf": "glb",
    "fbx": "glb",
    "dae": "glb",
    "3ds": "obj",
    "stl": "obj",
    "ply": "obj",
    "json": "geojson",
    "citygml": "cityjson",
    "pbf": "osm",
    "xml": "osm",
    "jpg": "png",
    "jpeg": "png",
    "htm": "html",
    "web": "html",
    "viewer": "html",
}
ORIGINS = ("local", "geo")


def city_origin(layers: dict[str, Layer], lat_lon, crs: str) -> tuple[np.ndarray, tuple[float, float]]:
    """The city's origin: planar ``(x, y)`` in ``crs`` rounded to the metre, and its ``(lat, lon)``.

    A layer's ``meta["origin"]`` (an OSM city's centre, a synthetic city's
    planar ``(0, 0)``) wins over ``lat_lon``; with neither, the centre of
    the layers' bounds.
    """
    import shapely

    origin = next((lay.meta["origin"] for lay in layers.values() if lay.meta.get("origin") is not None), None)
    if origin is None and lat_lon is None:
        b = [shapely.total_bounds(lay.geometry) for lay in layers.values() if len(lay)]
        b = np.array([v for v in b if np.isfinite(v).all()] or [[0.0, 0.0, 0.0, 0.0]])
        xy = np.round([(b[:, 0].min() + b[:, 2].max()) / 2, (b[:, 1].min() + b[:, 3].max()) / 2])
        lon, lat = to_lonlat(crs)(xy[None])[0]
        return xy, (float(lat), float(lon))
    lat, lon = (float(v) for v in (origin if origin is not None else lat_lon))
    xy = from_lonlat(crs)(np.array([[lon, lat]]))[0]
    return np.round(xy), (lat, lon)


def layers_frame(layers: dict[str, Layer | None]) -> tuple[tuple | None, tuple[float, float]]:
    """The city's planar extent and geographic origin (lat, lon), from the first layers' meta that hold them."""
    metas = [lay.meta for lay in layers.values() if lay is not None]
    extent = next((m["extent"] for m in metas if "extent" in m), None)
    lat_lon = next((tuple(m["origin"]) for m in metas if "origin" in m), CityPlan().origin)
    return extent, lat_lon


def export_layers(
    out: Path,
    layers: dict[str, Layer | None],
    formats,
    *,
    rules=None,
    extent=None,
    lat_lon=None,
    line_width: float = 1.0,
    preview_size: int = 1600,
    workers: int = 1,
    crs: str | None = None,
    origin: str = "local",
    attribution: str | None = None,
    lod: int = 2,
    city_name: str = "",
    early_solids: Callable[[], tuple | None] | None = None,
) -> dict:
    """Write ``layers`` into folder ``out`` in each of ``formats``.

    Parameters
    ----------
    out : pathlib.Path
        Existing folder to write into.
    layers : dict of str to Layer or None
        Layers by name (``roads``, ``streets``, ``sidewalks``, ``blocks``,
        ``lots``, ``buildings``, ``parks``, ``water``, ``bridges``,
        ``vegetation``); ``None`` ones are skipped.
    formats : iterable of str
        Names among :data:`FORMATS` (another is a :class:`ParameterError`),
        empty means :data:`DEFAULT_FORMATS`.
    rules : dict, optional
        ``{"district": ..., "landuse": ...}`` rules layers (or lists of rules)
        naming the features' district and land-use class.
    extent : tuple of float, optional
        The city extent (m) that frames ``preview.png`` (none: the layers' bounds).
    lat_lon : tuple of float, optional
        Latitude and longitude placing layers that carry no ``meta["crs"]``
        (default: the default plan's origin).
    workers : int
        Processes writing files side by side (:func:`sengine.parallel.run_jobs`);
        the files are the same for any number.
    crs : str, optional
        ``utm``, ``wgs84`` or ``EPSG:n`` for every vector output (see the module notes).
    origin : {"local", "geo"}
        Where the glb and OBJ vertices are placed (see the module notes).
    attribution : str, optional
        The data's licence notice; default :data:`OSM_ATTRIBUTION` when a
        layer (or the plan) comes from OpenStreetMap.
    lod : int
        Buildings in glb, obj, cityjson and html: 1 boxes, 2 with roofs.
    city_name : str
        The city's name (``<city name>``; a file name loses its extensions):
        the title of ``preview.png`` and of the html page.
    early_solids : callable, optional
        Returns ``(key, solids)`` of the buildings made ahead (:func:`early_solids`,
        in another process) or ``None``; asked once the files without
        buildings are written.  Solids whose key is not this export's
        buildings' (:func:`~sengine.nodes.export.roofs.solids_key`) are made here.

    Returns
    -------
    dict
        Counts per format (features, triangles, nodes ...), ``clean`` (what
        was repaired or dropped per layer), ``seconds`` (wall) and
        ``cpu_seconds`` (CPU of the process that wrote each file) per format.
    """
    import importlib

    from sengine.io import geojson

    def writer(module: str):  # each writer's module imported when its format is asked for
        return importlib.import_module(f"{__package__}.{module}")

    out = Path(out)
    formats = export_formats(formats)  # the others are other exporters'
    if origin not in ORIGINS:
        raise ParameterError(f"origin {origin!r} is not one of {', '.join(ORIGINS)}", where="--origin")
    layers = {k: v for k, v in layers.items() if v is not None}
    t = time.perf_counter()
    origin_ll = tuple(lat_lon) if lat_lon is not None else CityPlan().origin
    layers, cleaned = prepare_layers(layers, rules, origin=origin_ll)
    t_clean = time.perf_counter() - t
    crs_of = {k: layer_crs(v.meta, origin_ll) for k, v in layers.items()}
    any_crs = next(iter(crs_of.values()), layer_crs({}, origin_ll))
    if attribution is None and _from_osm(layers):
        attribution = OSM_ATTRIBUTION
    centre, centre_ll = city_origin(layers, origin_ll, any_crs)
    offset = centre if origin == "local" else None
    jobs: list[tuple[str, str | None, Callable[[], Any]]] = []  # (format, layer, write)
    if "png" in formats:
        # the plan's extent frames a synthetic city; data in another frame (OSM in UTM) frames itself
        extent = extent if extent is not None and not _outside(layers, extent) else None
        jobs.append(
            (
                "png",
                None,
                partial(
                    writer("preview").write_preview,
                    out / "preview.png",
                    layers,
                    size=preview_size,
                    extent=extent,
                    attribution=attribution,
                    title=writer("preview").city_title(city_name),
                    north=north_angle(any_crs, centre_ll),
                ),
            )
        )
    if "glb" in formats:
        jobs.append(
            (
                "glb",
                None,
                partial(
                    writer("gltf").write_glb,
                    out / "city.glb",
                    layers,
                    line_width=line_width,
                    crs=any_crs,
                    origin=None if offset is None else (offset, centre_ll),
                    copyright=attribution,
                    lod=lod,
                ),
            )
        )
    if "html" in formats:  # the page is always around the city's origin, as a browser wants it
        jobs.append(
            (
                "html",
                None,
                partial(
                    writer("html").write_html,
                    out,
                    layers,
                    offset=centre,
                    line_width=line_width,
                    name=writer("preview").city_title(city_name),
                    attribution=attribution,
                    crs=any_crs,
                    origin={"lat": centre_ll[0], "lon": centre_ll[1], "planar": [float(c) for c in centre]},
                    lod=lod,
                ),
            )
        )
    if "obj" in formats:
        jobs.append(
            (
                "obj",
                None,
                partial(
                    writer("obj").write_obj,
                    out / "city.obj",
                    layers,
                    line_width=line_width,
                    offset=offset,
                    crs=any_crs,
                    attribution=attribution,
                    lod=lod,
                ),
            )
        )
    if "geojson" in formats:  # one job per layer, the largest first
        target = output_crs(crs, any_crs, default="wgs84")
        decimals = 7 if is_geographic(target) else 3
        for name in sorted(layers, key=lambda k: -len(layers[k])):
            jobs.append(
                (
                    "geojson",
                    name,
                    partial(
                        geojson.write_geojson,
                        out / f"{name}.geojson",
                        layers[name],
                        reproject(crs_of[name], target),
                        name=name,
                        precision=decimals,
                        crs=target,
                        attribution=attribution,
                    ),
                )
            )
    if "gpkg" in formats or "parquet" in formats:
        target = output_crs(crs, any_crs, default="utm")
        grid = 1e-7 if is_geographic(target) else 1e-3
        transforms = {k: reproject(crs_of[k], target) for k in layers}
        if "gpkg" in formats:  # one file: one job
            jobs.append(
                (
                    "gpkg",
                    None,
                    partial(
                        writer("gpkg").write_gpkg,
                        out / "city.gpkg",
                        layers,
                        transforms,
                        target,
                        grid=grid,
                        attribution=attribution,
                    ),
                )
            )
        if "parquet" in formats:
            for name in sorted(layers, key=lambda k: -len(layers[k])):
                jobs.append(
                    (
                        "parquet",
                        name,
                        partial(
                            writer("parquet").write_parquet,
                            out / f"{name}.parquet",
                            layers[name],
                            transforms[name],
                            target,
                            name=name,
                            grid=grid,
                            attribution=attribution,
                        ),
                    )
                )
    if "osm" in formats and "roads" in layers:
        jobs.append(
            (
                "osm",
                None,
                partial(
                    writer("osmxml").write_osm,
                    out / "streets.osm",
                    layers["roads"],
                    to_lonlat(crs_of["roads"]),
                    attribution=attribution,
                ),
            )
        )
    if "cityjson" in formats and "buildings" in layers:
        jobs.append(
            (
                "cityjson",
                None,
                partial(
                    writer("cityjson").write_cityjson,
                    out / "buildings.city.json",
                    layers["buildings"],
                    vegetation=layers.get("vegetation"),
                    crs=crs_of["buildings"],
                    origin=None if offset is None else (offset, any_crs),
                    attribution=attribution,
                    lod=lod,
                ),
            )
        )
    # What several 3D writers draw alike is made once: the buildings' roofs by this process, the flat
    # polygons and ribbons of the glb and the page by any, while the workers write the files that need
    # neither; the 3D writers then start (forked: they inherit them).
    b = layers.get("buildings")
    asked = {fmt for fmt, _, _ in jobs}
    share = lod >= 2 and len(_SOLID & asked) >= 2 and b is not None and len(b) and "height" in b.attrs
    surfaces = {"glb", "html"} <= asked
    solid_asked = bool(lod >= 2 and _SOLID & asked and b is not None and len(b) and "height" in b.attrs)
    early = early_solids if solid_asked else None  # the roofs, made ahead: asked for after the flat files
    # progress: every job counts the features it writes, the chunked writers chunk by chunk
    weights = [_weight(layers, fmt, name) for fmt, name, _ in jobs]
    timed = [partial(_timed, write, 0 if fmt in _CHUNKED else w) for (fmt, _, write), w in zip(jobs, weights)]
    progress.expect(sum(weights) + (len(b) if share else 0), "features")
    if not (share or surfaces or early):
        done = run_jobs(timed, workers)
    else:
        solid = [fmt in _SOLID for fmt, _, _ in jobs]
        with contextlib.ExitStack() as stack:

            def make_roofs() -> None:  # job 0: always this process's, first
                stack.enter_context(writer("roofs").shared_solids(b, lod))
                progress.advance(len(b))

            first = [make_roofs] if share and early is None else []
            if surfaces:
                first.append(partial(writer("gltf").make_surfaces, layers, line_width=line_width))
            made = run_jobs(first + [j for j, s in zip(timed, solid) if not s], workers)
            if early is not None:  # made in another process meanwhile (or here now, when it failed)
                stack.enter_context(writer("roofs").shared_solids(b, lod, made=early()))
                if share:
                    progress.advance(len(b))
            if surfaces:
                stack.enter_context(writer("gltf").shared_surfaces(layers, made[len(first) - 1], line_width=line_width))
            flat = made[len(first) :]
            solids = run_jobs([j for j, s in zip(timed, solid) if s], workers)
        flat.reverse()
        solids.reverse()
        done = [solids.pop() if s else flat.pop() for s in solid]
    report: dict = {fmt: {} for fmt in FORMATS if any(f == fmt for f, _, _ in jobs)}
    seconds = dict.fromkeys(report, 0.0)
    cpu = dict.fromkeys(report, 0.0)
    for (fmt, name, _), (result, dt, dc) in zip(jobs, done, strict=True):
        if name is None:
            report[fmt] = result
        else:
            report[fmt][name] = result
        seconds[fmt] += dt
        cpu[fmt] += dc
    log.info(
        "exported %s in %.3f s of writing with %d worker(s) (%s), %.3f s cleaning",
        ", ".join(sorted(seconds)),
        sum(seconds.values()),
        max(1, min(workers, len(jobs))),
        ", ".join(f"{k} {v:.3f}" for k, v in seconds.items()),
        t_clean,
    )
    report["clean"] = cleaned
    seconds["clean"] = t_clean
    report["seconds"] = seconds
    report["cpu_seconds"] = cpu
    return report


def export_formats(formats) -> set[str]:
    """The formats of :data:`FORMATS` that ``formats`` (``--format``) asks this exporter for; none: the defaults."""
    asked = {str(f).strip().lower() for f in formats or ()} - {""}
    return (asked & set(FORMATS)) if asked else set(DEFAULT_FORMATS)


def early_solids(buildings: Layer, lod: int) -> tuple[str, Any]:
    """The buildings' solids as the export will draw them, with their key: a job for another process.

    The buildings go through :func:`~.prepare.prepare_layers` as in
    :func:`export_layers` (the geometry and the roof columns do not depend
    on the rules), then :func:`~.roofs.layer_solids`.  The export takes them
    when the key (:func:`~.roofs.solids_key`) is its own buildings'.
    """
    from . import roofs

    _, lat_lon = layers_frame({"buildings": buildings})
    prepared = prepare_layers({"buildings": buildings}, None, origin=lat_lon)[0]["buildings"]
    return roofs.solids_key(prepared, lod), roofs.layer_solids(prepared, lod)


def _from_osm(layers: dict[str, Layer]) -> bool:
    """Whether the city is made from OpenStreetMap data (a layer read from it)."""
    return any(lay.meta.get("source") == "osm" for lay in layers.values())


def north_angle(crs: str, lat_lon: tuple[float, float]) -> float:
    """Where true north points at ``lat_lon`` in the planar frame ``crs``: degrees clockwise from grid north.

    Zero on a frame's central meridian; in UTM the meridian convergence:
    -2.0 degrees at Liège, 2.6 degrees east of its zone's meridian (true
    north leans west there), +1.1 at Monaco, west of its own.
    """
    lat, lon = lat_lon
    lat = min(max(float(lat), -89.0), 89.0)
    xy = from_lonlat(crs)(np.array([[lon, lat], [lon, lat + 1e-3]], float))
    dx, dy = xy[1] - xy[0]
    return float(np.degrees(np.arctan2(dx, dy))) if np.isfinite([dx, dy]).all() and (dx or dy) else 0.0


#: Writers that draw the buildings' solids (:func:`sengine.nodes.export.roofs.layer_solids`).
_SOLID = frozenset({"glb", "obj", "cityjson", "html"})
#: Writers that count their features chunk by chunk (:func:`sengine.progress.advance`); the others when done.
_CHUNKED = frozenset({"geojson", "gpkg", "parquet"})


def _weight(layers: dict[str, Layer], fmt: str, name: str | None) -> int:
    """The features a job writes: its layer's, the roads' (OSM), the buildings' (CityJSON), else every layer's."""
    if name is not None:
        return len(layers[name])
    if fmt in ("osm", "cityjson"):
        return len(layers["roads" if fmt == "osm" else "buildings"])
    return sum(len(v) for v in layers.values())


def _timed(write: Callable[[], Any], count: int = 0) -> tuple[Any, float, float]:
    """Run a writer; return its result, wall seconds and CPU seconds (its process'); count ``count`` features done."""
    t, c = time.perf_counter(), time.process_time()
    result = write()
    progress.advance(count)
    return result, time.perf_counter() - t, time.process_time() - c


def _outside(layers: dict[str, Layer], extent) -> bool:
    """Whether some layer reaches more than 10 % beyond ``extent`` (another frame, or no city extent)."""
    import shapely

    x0, y0, x1, y1 = extent
    m = 0.1 * max(x1 - x0, y1 - y0)
    for lay in layers.values():
        if len(lay):
            b = shapely.total_bounds(lay.geometry)
            if np.isfinite(b).all() and (b[0] < x0 - m or b[1] < y0 - m or b[2] > x1 + m or b[3] > y1 + m):
                return True
    return False


@register
class ExportCity(SENode):
    """Write the city's layers: city.glb, <layer>.geojson, streets.osm, preview.png, index.html (and OBJ, CityJSON, GPKG, GeoParquet).

    Formats come from ``--format`` (the run context); with none given the
    defaults are glb, geojson, osm, png and html.  ``--crs`` and ``--origin``
    come as the context's ``options``.
    """

    name = "export.city"
    inputs = {
        "roads": Port("roads", "street centre lines", required=False),
        "streets": Port("polygons", "street surfaces", required=False),
        "sidewalks": Port("polygons", "sidewalk surfaces", required=False),
        "blocks": Port("blocks", "blocks", required=False),
        "lots": Port("lots", "lots", required=False),
        "buildings": Port("buildings", "building footprints with height", required=False),
        "parks": Port("parks", "parks", required=False),
        "water": Port("polygons", "water areas (rivers, lakes, harbours)", required=False),
        "bridges": Port("polygons", "bridge decks (roads.bridges): slabs in city.glb", required=False),
        "vegetation": Port("vegetation", "trees: instanced meshes in city.glb, points elsewhere", required=False),
        "district_rules": Port("rules", "the <district> rules: district names", required=False),
        "landuse_rules": Port("rules", "the <landuse> rules: the land-use class", required=False),
    }
    outputs = {}
    formats = FORMATS
    shard_formats = ("parquet", "gpkg", "glb")
    format_hints = FORMAT_HINTS
    params = {
        "line_width": Param(
            "float", 1.0, min=0.05, max=50.0, unit="m", doc="width of road centre-line ribbons in the 3D exports"
        ),
        "preview_size": Param("int", 1600, min=200, max=8000, unit="px", doc="long side of preview.png"),
        "lod": Param(
            "int",
            2,
            min=1,
            max=2,
            unit="1",
            doc="buildings in glb, obj, cityjson and html: 1 flat-roofed boxes, 2 with their roofs (--lod)",
        ),
    }

    early_inputs = ("buildings",)

    def early(self, *, buildings: Layer | None = None) -> Callable[[], Any] | None:
        """The buildings' roofs, made in another process while the nodes up to this one run (:func:`early_solids`)."""
        b = buildings
        if self.context.out is None or b is None or not len(b) or "height" not in b.attrs or self.p.lod < 2:
            return None
        if not _SOLID & export_formats(self.context.formats):
            return None
        return partial(early_solids, b, self.p.lod)

    def run(
        self,
        *,
        roads: Layer | None = None,
        streets: Layer | None = None,
        sidewalks: Layer | None = None,
        blocks: Layer | None = None,
        lots: Layer | None = None,
        buildings: Layer | None = None,
        parks: Layer | None = None,
        water: Layer | None = None,
        bridges: Layer | None = None,
        vegetation: Layer | None = None,
        district_rules: Layer | None = None,
        landuse_rules: Layer | None = None,
    ) -> NodeResult:
        out = self.context.out
        if out is None:  # an in-memory run (tests, notebooks): nothing to write
            log.info("%s: no output folder, nothing written", self.where)
            return NodeResult({}, {})
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        options = dict(getattr(self.context, "options", None) or {})
        layers = {
            "roads": roads,
            "streets": streets,
            "sidewalks": sidewalks,
            "blocks": blocks,
            "lots": lots,
            "buildings": buildings,
            "parks": parks,
            "water": water,
            "bridges": bridges if bridges is not None and len(bridges) else None,
            "vegetation": vegetation,
        }
        extent, lat_lon = layers_frame(layers)
        report = export_layers(
            out,
            layers,
            self.context.formats,
            rules={"district": district_rules, "landuse": landuse_rules},
            extent=extent,
            lat_lon=lat_lon,
            line_width=self.p.line_width,
            preview_size=self.p.preview_size,
            workers=self.context.workers,
            crs=options.get("crs"),
            origin=options.get("origin") or "local",
            lod=self.p.lod,
            city_name=getattr(self.context, "name", ""),
            early_solids=self.early_result if self.early_started() else None,
        )
        report.pop("seconds", None)  # timings would make stats.json differ between runs
        report.pop("cpu_seconds", None)
        return NodeResult({}, _flat_counts(report))

    # a sharded run (sengine.shard): each shard's layers as parts, joined into the files at the end
    def write_shard(self, inputs: dict, *, shard: int, city_ports: frozenset) -> dict:
        from .shards import LAYER_PORTS, write_part

        ports = frozenset(LAYER_PORTS) - city_ports
        return write_part(
            self, inputs, shard=f"{shard:04d}", ports=ports, folder=self._parts(), city_origin=city_origin
        )

    def join_shard(self, part: dict, *, shard: int) -> None:
        from .shards import stream_part

        stream_part(self, part)

    def finish_shards(self, inputs: dict, parts: list, *, city_ports: frozenset) -> dict:
        from .shards import join_parts

        report = join_parts(self, inputs, parts, city_ports=city_ports, folder=self._parts(), city_origin=city_origin)
        return _flat_counts(report)

    def _parts(self) -> Path:
        return Path(self.context.out) / ".parts" / self.id


def _flat_counts(report: dict) -> dict:
    """``{"glb.buildings.triangles": 123, ...}``: the JSON-able counts of a report."""
    flat: dict = {}

    def walk(prefix, v):
        if isinstance(v, dict):
            for k, x in v.items():
                walk(f"{prefix}.{k}" if prefix else str(k), x)
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            flat[prefix] = v
        elif isinstance(v, tuple):
            for k, x in enumerate(v):
                walk(f"{prefix}.{k}", x)

    walk("", report)
    return flat

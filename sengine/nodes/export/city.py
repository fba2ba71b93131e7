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
========== ======================================= ========================

``lod`` (``--lod``) chooses the buildings of the 3D formats (glb, obj,
cityjson): 1 flat-roofed boxes, 2 with their roofs
(:mod:`sengine.nodes.export.roofs`).

WGS84 coordinates come from each layer's ``meta["crs"]``, or the local frame
of the plan's geographic origin.  ``stats.json`` is the executor's.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

from sengine import CityPlan, Layer, Param, Port, SENode, register
from sengine.geom.crs import layer_crs, to_lonlat
from sengine.parallel import run_jobs

__all__ = ["FORMATS", "DEFAULT_FORMATS", "export_layers", "ExportCity"]

log = logging.getLogger(__name__)

FORMATS = ("glb", "geojson", "osm", "png", "obj", "cityjson")
DEFAULT_FORMATS = frozenset({"glb", "geojson", "osm", "png"})


def export_layers(
    out: Path,
    layers: dict[str, Layer | None],
    formats,
    *,
    plan=None,
    line_width: float = 1.0,
    preview_size: int = 1600,
    workers: int = 1,
    lod: int = 2,
) -> dict:
    """Write ``layers`` into folder ``out`` in each of ``formats``.

    Parameters
    ----------
    out : pathlib.Path
        Existing folder to write into.
    layers : dict of str to Layer or None
        Layers by name (``roads``, ``streets``, ``sidewalks``, ``blocks``,
        ``lots``, ``buildings``, ``parks``, ``water``); ``None`` ones are skipped.
    formats : iterable of str
        Names among :data:`FORMATS`; others are ignored, empty means
        :data:`DEFAULT_FORMATS`.
    plan : CityPlan, optional
        Its ``origin`` places layers that carry no ``meta["crs"]``.
    workers : int
        Processes writing files side by side (:func:`sengine.parallel.run_jobs`);
        the files are the same for any number.
    lod : int
        Buildings in glb, obj and cityjson: 1 boxes, 2 with roofs.

    Returns
    -------
    dict
        Counts per format (features, triangles, nodes ...) and ``seconds``.
    """
    from sengine.io import geojson

    from . import cityjson, gltf, obj, osmxml, preview

    out = Path(out)
    formats = set(formats or ()) & set(FORMATS) or set(DEFAULT_FORMATS)
    layers = {k: v for k, v in layers.items() if v is not None}
    origin = (plan or CityPlan()).origin
    crs = {k: layer_crs(v.meta, origin) for k, v in layers.items()}
    any_crs = next(iter(crs.values()), layer_crs({}, origin))
    jobs: list[tuple[str, str | None, Callable[[], Any]]] = []  # (format, layer, write)
    if "png" in formats:
        # the plan's extent frames a synthetic city; data in another frame (OSM in UTM) frames itself
        extent = plan.extent if plan is not None else None
        extent = extent if extent is not None and not _outside(layers, extent) else None
        jobs.append(
            ("png", None, partial(preview.write_preview, out / "preview.png", layers, size=preview_size, extent=extent))
        )
    if "glb" in formats:
        jobs.append(
            (
                "glb",
                None,
                partial(gltf.write_glb, out / "city.glb", layers, line_width=line_width, crs=any_crs, lod=lod),
            )
        )
    if "obj" in formats:
        jobs.append(("obj", None, partial(obj.write_obj, out / "city.obj", layers, line_width=line_width, lod=lod)))
    if "geojson" in formats:  # one job per layer, the largest first
        for name in sorted(layers, key=lambda k: -len(layers[k])):
            jobs.append(
                (
                    "geojson",
                    name,
                    partial(
                        geojson.write_geojson, out / f"{name}.geojson", layers[name], to_lonlat(crs[name]), name=name
                    ),
                )
            )
    if "osm" in formats and "roads" in layers:
        jobs.append(
            ("osm", None, partial(osmxml.write_osm, out / "streets.osm", layers["roads"], to_lonlat(crs["roads"])))
        )
    if "cityjson" in formats and "buildings" in layers:
        jobs.append(
            (
                "cityjson",
                None,
                partial(
                    cityjson.write_cityjson,
                    out / "buildings.city.json",
                    layers["buildings"],
                    crs=crs["buildings"],
                    lod=lod,
                ),
            )
        )
    done = run_jobs([partial(_timed, write) for _, _, write in jobs], workers)
    report: dict = {fmt: {} for fmt in FORMATS if any(f == fmt for f, _, _ in jobs)}
    seconds = dict.fromkeys(report, 0.0)
    for (fmt, name, _), (result, dt) in zip(jobs, done, strict=True):
        if name is None:
            report[fmt] = result
        else:
            report[fmt][name] = result
        seconds[fmt] += dt
    log.info(
        "exported %s in %.3f s of writing with %d worker(s) (%s)",
        ", ".join(sorted(seconds)),
        sum(seconds.values()),
        max(1, min(workers, len(jobs))),
        ", ".join(f"{k} {v:.3f}" for k, v in seconds.items()),
    )
    report["seconds"] = seconds
    return report


def _timed(write: Callable[[], Any]) -> tuple[Any, float]:
    t = time.perf_counter()
    return write(), time.perf_counter() - t


def _outside(layers: dict[str, Layer], extent) -> bool:
    """Whether some layer reaches more than 10 % beyond ``extent`` (another frame, or no city extent)."""
    import numpy as np
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
    """Write the city's layers: city.glb, <layer>.geojson, streets.osm, preview.png (and OBJ, CityJSON).

    Formats come from ``--format`` (the run context); with none given the
    defaults are glb, geojson, osm and png.
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
    }
    outputs = {}
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
            doc="buildings in glb, obj and cityjson: 1 flat-roofed boxes, 2 with their roofs (--lod)",
        ),
    }

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
    ) -> dict[str, Layer]:
        out = self.context.out
        if out is None:  # an in-memory run (tests, notebooks): nothing to write
            log.info("%s: no output folder, nothing written", self.where)
            self.report = {}
            return {}
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        layers = {
            "roads": roads,
            "streets": streets,
            "sidewalks": sidewalks,
            "blocks": blocks,
            "lots": lots,
            "buildings": buildings,
            "parks": parks,
            "water": water,
        }
        report = export_layers(
            out,
            layers,
            self.context.formats,
            plan=self.context.plan,
            line_width=self.p.line_width,
            preview_size=self.p.preview_size,
            workers=self.context.workers,
            lod=self.p.lod,
        )
        report.pop("seconds", None)  # timings would make stats.json differ between runs
        self.report = _flat_counts(report)
        return {}


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

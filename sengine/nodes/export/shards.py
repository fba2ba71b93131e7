"""``export.city`` in a sharded run (:mod:`sengine.shard`): parts per shard, joined into the city's files.

Each shard task cleans its layers (:func:`~sengine.nodes.export.prepare.prepare_layers`),
turns them into Arrow record batches in the output frame
(:class:`~sengine.nodes.export.table.LayerBatches`) and writes them as one
Arrow IPC part per layer (``.parts/<node>/<layer>/<shard>.arrow`` in the
run's folder), and with ``glb`` its own ``city-<shard>.glb``.  Once every
shard is done, the parts are streamed in shard order into
``<layer>.parquet`` (GeoParquet, row groups of
:data:`~sengine.nodes.export.table.CHUNK` rows) and ``city.gpkg``, a chunk
at a time, with the layers made once for the whole city (roads, parks,
water) written as they are.  A layer that needs Multi geometries in one
shard has them in every shard (as :func:`prepare_layers` does for a whole
layer), and the ``geo`` metadata holds the union of the shards' bounds: the
files are those of the unsharded run.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from sengine import CityPlan
from sengine.errors import ParameterError
from sengine.geom.crs import is_geographic, layer_crs, output_crs, reproject

from .table import CHUNK, OSM_ATTRIBUTION, LayerBatches, require

__all__ = ["SHARD_FORMATS", "LAYER_PORTS", "write_part", "join_parts"]

log = logging.getLogger(__name__)

#: What a sharded run writes: streamed tables, and the glb as one file per shard.
SHARD_FORMATS = ("parquet", "gpkg", "glb")
#: The exporter's layer ports, in its order.
LAYER_PORTS = (
    "roads",
    "streets",
    "sidewalks",
    "blocks",
    "lots",
    "buildings",
    "parks",
    "water",
    "bridges",
    "vegetation",
)
_MULTI = {"Polygon": "MultiPolygon", "LineString": "MultiLineString", "Point": "MultiPoint"}


def shard_formats(formats) -> set[str]:
    """The formats of a sharded run: the asked ones (default parquet); others are a ParameterError."""
    asked = {str(f).strip().lower() for f in formats or ()} - {""}
    if not asked:
        return {"parquet"}
    bad = sorted(asked - set(SHARD_FORMATS))
    if bad:
        raise ParameterError(
            f"--shards writes {', '.join(SHARD_FORMATS)}, not {', '.join(bad)} (run without --shards for those)",
            where="--format",
        )
    return asked


def _frame(inputs: dict, options: dict):
    """Origin (lat, lon), planar frame of the layers and output frame and grid of the tables."""
    metas = [inputs[k].meta for k in LAYER_PORTS if inputs.get(k) is not None]
    lat_lon = next((tuple(m["origin"]) for m in metas if "origin" in m), CityPlan().origin)
    any_crs = layer_crs(metas[0] if metas else {}, lat_lon)
    target = output_crs(options.get("crs"), any_crs, default="utm")
    return lat_lon, any_crs, target, (1e-7 if is_geographic(target) else 1e-3)


def _attribution(inputs: dict) -> str | None:
    return (
        OSM_ATTRIBUTION
        if any(inputs[k].meta.get("source") == "osm" for k in LAYER_PORTS if inputs.get(k) is not None)
        else None
    )


def write_part(node, inputs: dict, *, shard, ports, folder: Path, city_origin) -> dict:
    """Write the layers of ``ports`` as Arrow parts named ``shard``; with glb, ``city-<shard>.glb`` too.

    ``city_origin`` is :func:`sengine.nodes.export.city.city_origin` (the glb's origin).

    Returns ``{"layers": {name: {"path", "type", "bounds", "written", "collapsed"}}, "clean": ..., "glb": ...}``.
    """
    import pyarrow as pa

    from . import gltf
    from .prepare import prepare_layers

    formats = shard_formats(node.context.formats)
    options = dict(getattr(node.context, "options", None) or {})
    lat_lon, any_crs, target, grid = _frame(inputs, options)
    layers = {k: inputs[k] for k in LAYER_PORTS if k in ports and inputs.get(k) is not None}
    if "bridges" in layers and not len(layers["bridges"]):  # as export.city: no bridges, no table
        del layers["bridges"]
    rules = {"district": inputs.get("district_rules"), "landuse": inputs.get("landuse_rules")}
    layers, cleaned = prepare_layers(layers, rules, origin=lat_lon)
    attribution = _attribution(inputs)
    out: dict = {"layers": {}, "clean": cleaned}
    if formats & {"parquet", "gpkg"}:
        for name, lay in layers.items():
            batches = LayerBatches(lay, reproject(layer_crs(lay.meta, lat_lon), target), grid, name=name, bbox=True)
            path = folder / name / f"{shard}.arrow"
            path.parent.mkdir(parents=True, exist_ok=True)
            with pa.OSFile(str(path), "wb") as sink, pa.ipc.new_file(sink, batches.schema()) as w:
                for batch in batches:
                    w.write_batch(batch)
            out["layers"][name] = {
                "target": target,
                "attribution": attribution,
                "path": str(path),
                "type": batches.geometry_type,
                "bounds": list(batches.bounds),
                "written": batches.written,
                "collapsed": batches.collapsed,
            }
    if "glb" in formats and layers:
        everything = {k: inputs[k] for k in LAYER_PORTS if inputs.get(k) is not None}
        centre, centre_ll = city_origin(everything, lat_lon, any_crs)
        local = (options.get("origin") or "local") == "local"
        out["glb"] = gltf.write_glb(
            Path(node.context.out) / ("city.glb" if shard == "city" else f"city-{shard}.glb"),
            layers,
            line_width=node.p.line_width,
            crs=any_crs,
            origin=(centre, centre_ll) if local else None,
            copyright=attribution,
            lod=node.p.lod,
        )
    return out


def _promote(table, want: str):
    """The table with its ``geometry`` column made ``want`` (Multi*) where a row has the single type."""
    import pyarrow as pa
    import shapely

    g = shapely.from_wkb(np.asarray(table.column("geometry").to_numpy(zero_copy_only=False), dtype=object))
    make = {"MultiPolygon": shapely.multipolygons, "MultiLineString": shapely.multilinestrings}.get(want)
    if make is None:
        return table
    single = shapely.get_type_id(g) == {"MultiPolygon": 3, "MultiLineString": 1}[want]
    if single.any():
        g = g.copy()
        g[single] = make(g[single], indices=np.arange(int(single.sum())))
    col = pa.array(shapely.to_wkb(g, output_dimension=2), type=pa.binary())
    return table.set_column(table.schema.get_field_index("geometry"), "geometry", col)


def _part_batches(parts: list[dict], want: str, schema):
    """The batches of the parts in order, cast to ``schema`` and promoted to geometry type ``want``."""
    import pyarrow as pa

    for part in parts:
        with pa.OSFile(part["path"], "rb") as src:  # read into memory: batches outlive the file (rebatched)
            reader = pa.ipc.open_file(src)
            for i in range(reader.num_record_batches):
                t = pa.Table.from_batches([reader.get_batch(i)])
                if part["type"] != want:
                    t = _promote(t, want)
                if t.schema != schema:
                    t = t.cast(schema)
                yield from t.combine_chunks().to_batches()


def _schemas(parts: list[dict]):
    import pyarrow as pa

    out = []
    for part in parts:
        with pa.memory_map(part["path"], "r") as src:
            out.append(pa.ipc.open_file(src).schema)
    return out


def stream_part(node, part: dict) -> None:
    """Append a shard's parts to the ``<layer>.parquet`` files as soon as it comes (in shard order).

    A layer's file is started with the first shard's geometry type and
    schema; a later shard that needs another (Multi geometries, a column
    type) makes :func:`join_parts` write that file again from every part.
    """
    from . import parquet

    formats = shard_formats(node.context.formats)
    if "parquet" not in formats:
        return
    streams = node.__dict__.setdefault("_streams", {})
    out = Path(node.context.out)
    for name, info in part["layers"].items():
        schema = _schemas([info])[0]
        st = streams.get(name)
        if st is None:
            st = streams[name] = {
                "writer": parquet.ParquetLayerWriter(
                    out / f"{name}.parquet", info["target"], attribution=info["attribution"]
                ),
                "type": info["type"],
                "schema": schema,
                "ok": True,
                "parts": 0,
            }
        st["parts"] += 1
        if not st["ok"]:
            continue
        if (info["written"] and info["type"] != st["type"]) or schema != st["schema"]:
            st["ok"] = False  # rewritten at the end from every part
            continue
        st["writer"].write_batches(schema, _part_batches([info], info["type"], schema), chunk=CHUNK)
        if info["written"]:
            st["writer"].add_extent(info["type"], info["bounds"])


def join_parts(node, inputs: dict, parts: list[dict], *, city_ports: frozenset, folder: Path, city_origin) -> dict:
    """Write the city's files from the shards' parts (and the whole-city layers of ``city_ports``)."""
    import pyarrow as pa

    from . import gpkg, parquet

    formats = shard_formats(node.context.formats)
    options = dict(getattr(node.context, "options", None) or {})
    out = Path(node.context.out)
    city = write_part(node, inputs, shard="city", ports=city_ports, folder=folder, city_origin=city_origin)
    lat_lon, any_crs, target, grid = _frame(inputs, options)
    attribution = _attribution(inputs)
    names = sorted({n for p in [city, *parts] for n in p["layers"]})
    streams = node.__dict__.pop("_streams", {})
    report: dict = {"clean": {}, "shards": len(parts)}
    for p in [city, *parts]:
        for layer, rep in (p.get("clean") or {}).items():
            acc = report["clean"].setdefault(layer, {})
            for k, v in rep.items():
                if isinstance(v, (int, float)) and not isinstance(v, bool):
                    acc[k] = acc.get(k, 0) + v
    gpkg_path = out / "city.gpkg"
    if "gpkg" in formats and gpkg_path.exists():
        gpkg_path.unlink()
    for name in names:
        mine = (
            [city["layers"][name]]
            if name in city["layers"]
            else [p["layers"][name] for p in parts if name in p["layers"]]
        )
        types = {p["type"] for p in mine if p["written"]} or {mine[0]["type"]}
        want = next((_MULTI[t] for t in types if _MULTI.get(t) in types), None) or sorted(types)[0]
        if len(types) > 1 and want not in _MULTI.values():
            want = sorted(types)[0]
        schemas = _schemas(mine)
        schema = (
            schemas[0]
            if all(s == schemas[0] for s in schemas)
            else pa.unify_schemas(schemas, promote_options="permissive")
        )
        written = sum(p["written"] for p in mine)
        bounds = [p["bounds"] for p in mine if p["written"]]
        if "parquet" in formats:
            require("pyarrow", "parquet")
            st = streams.pop(name, None)
            if (
                st is not None
                and st["ok"]
                and st["parts"] == len(mine)
                and st["type"] == want
                and st["schema"] == schema
            ):
                st["writer"].close()  # streamed shard by shard as they came
            else:
                if st is not None:
                    st["writer"].close()
                with parquet.ParquetLayerWriter(out / f"{name}.parquet", target, attribution=attribution) as w:
                    w.write_batches(schema, _part_batches(mine, want, schema), chunk=CHUNK)
                    for b in bounds:
                        w.add_extent(want, b)
            report.setdefault("parquet", {})[name] = {"features": written}
        if "gpkg" in formats:
            gschema = schema.remove(schema.get_field_index("bbox")) if "bbox" in schema.names else schema
            gpkg.write_gpkg_batches(
                gpkg_path,
                name,
                gschema,
                (
                    b.drop_columns(["bbox"]) if "bbox" in b.schema.names else b
                    for b in _part_batches(mine, want, schema)
                ),
                want,
                target,
                attribution=attribution,
            )
            report.setdefault("gpkg", {})[name] = {"features": written}
    if "glb" in formats:
        report["glb"] = {"files": sum(1 for p in [city, *parts] if "glb" in p)}
    log.info("%s: joined %d shards into %s", node.where, len(parts), ", ".join(sorted(formats)))
    return report

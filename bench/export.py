"""Benchmark: every format of ``export.city``, on a Manhattan-sized grid city and on whole Liège.

Two cities:

* ``grid``: the Manhattan-like example of the paper (002 §8: 931 blocks,
  7,471 lots), a grid city of the same size (930 blocks, 7,440 lots, each
  with a building); also times ``buildings.extrude``.
* ``liege``: whole Liège from OpenStreetMap (about 80,000 highway ways ->
  250,000 lots and 240,000 buildings), run through the load-map network in
  memory, then exported.

For each city and format the exporter is run alone (``--workers 1``,
``--repeat`` times, the formats interleaved so that background load hits
them alike) and the best writing seconds (the writer's own clock, as
reported by :func:`sengine.nodes.export.city.export_layers`) and the megabytes
written are kept, with each run's CPU seconds (``cpu_seconds_runs``: the
ratios ``cpu_ratio_*`` best against best, ``cpu_ratio_worst_run_*`` the
worst of the runs, each GeoJSON run against the same round's); ``seconds_clean`` is the shared preparation of the layers
(clean geometry, rounded values), done once per export whatever the formats.
Issue 16's target: GeoPackage and GeoParquet each at least 3x faster to
write than GeoJSON on whole Liège (``ratio_geojson_over_gpkg``,
``ratio_geojson_over_parquet``).  Writes ``bench/results/export.json``.

``--city e2e`` times instead the command users run on whole Liège,
``sengine osm FILE -o OUT`` with the default outputs (roofs, trees, the 3D
page), at ``--lod 1`` and ``--lod 2`` in turn, each a fresh process: wall
seconds from process start to the files written, CPU seconds, peak resident
memory (``os.wait4``), megabytes written and the executor's seconds per node
(``stats.json``).  ``ratio_lod2_over_lod1`` is the roofs' own cost measured
in one run.  ``--compare "PYTHON [PATH]"`` interleaves another checkout (its
Python, and the folder put first on ``PYTHONPATH``), for before / after
ratios under the same load.  Issue 12's target: LoD 2 within 1.3x of the
whole-city time when it was filed (21-27.5 s).  Writes
``bench/results/export_e2e.json``.

    python bench/export.py [--repeat 3] [--osm PATH.osm.pbf] [--city grid|liege|both|e2e]
                           [--formats geojson,gpkg,parquet] [--compare "PYTHON [PATH]"] [--workers N]
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

from _city import grid_city  # noqa: E402
from _osm import osm_network  # noqa: E402
from _results import write  # noqa: E402
from _window import window_ids  # noqa: E402

from sengine import Context  # noqa: E402
from sengine.nodes.maps import plan_inputs  # noqa: E402
from sengine.registry import get  # noqa: E402

DEFAULT_OSM = HERE.parent.parent / "shared" / "data" / "liege_streets.osm.pbf"
FORMATS = ("glb", "geojson", "osm", "png", "obj", "cityjson", "gpkg", "parquet")
TARGET = 3.0  # issue 16: GeoPackage and GeoParquet at least 3x faster to write than GeoJSON


def grid_layers(tmp: Path, repeat: int) -> tuple[object, dict, dict]:
    plan, layers = grid_city(nx=31, ny=30, lots_per_side=4, height_map=tmp)
    extrude = get("buildings.extrude")("buildings", {}, Context(seed=7))
    maps = plan_inputs(plan, extrude, base_dir=tmp)  # the height map on its port, as a network wires it
    best = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        layers["buildings"] = extrude.run(lots=layers["lots"], **maps)["buildings"]
        best = min(best, time.perf_counter() - t)
    return plan, layers, {"seconds_buildings_extrude": round(best, 4)}


def liege_layers(path: Path) -> tuple[object, dict, dict]:
    """Whole Liège through the load-map network in memory: the exporter's inputs."""
    net = osm_network(path, name="liege")
    net.specs.pop("export")  # the layers only: the bench calls the writers itself
    net.connections = [c for c in net.connections if c.dst != "export"]
    t = time.perf_counter()
    res = net.run(workers=1)
    seconds = time.perf_counter() - t
    lay = res.layers
    layers = {
        "roads": lay["clean"]["roads"],
        "streets": lay["blocks"]["streets"],
        "sidewalks": lay["blocks"]["sidewalks"],
        "blocks": lay["planning"]["blocks"],
        "lots": lay["planning"]["lots"],
        "buildings": lay["buildings"]["buildings"],
        "parks": lay["majorRoads"]["parks"],
        "water": lay["majorRoads"]["water"],
    }
    return net.plan, layers, {"seconds_city": round(seconds, 3)}


def time_formats(plan, layers: dict, repeat: int, tmp: Path, formats=FORMATS) -> dict:
    from sengine.nodes.export.city import export_layers, layers_frame

    extent, lat_lon = layers_frame(layers)

    best: dict[str, float] = {}
    cpu: dict[str, list] = {fmt: [] for fmt in formats}  # every run's CPU seconds, in run order
    clean: float = float("inf")
    sizes: dict[str, int] = {}
    for k in range(repeat):
        for fmt in formats:
            out = tmp / f"{fmt}-{k}"
            out.mkdir()
            rep = export_layers(out, layers, {fmt}, extent=extent, lat_lon=lat_lon)
            best[fmt] = min(best.get(fmt, float("inf")), rep["seconds"][fmt])
            cpu[fmt].append(rep["cpu_seconds"][fmt])
            clean = min(clean, rep["seconds"]["clean"])
            sizes[fmt] = sum(p.stat().st_size for p in out.iterdir())
            if k < repeat - 1 or fmt not in ("geojson", "gpkg", "parquet"):
                for p in out.iterdir():
                    p.unlink()
    mb = {k: round(v / 1e6, 2) for k, v in sizes.items()}
    result = {
        "features": {name: len(lay) for name, lay in layers.items()},
        "seconds_clean": round(clean, 3),
        "seconds_per_format": {k: round(v, 3) for k, v in best.items()},
        "cpu_seconds_per_format": {k: round(min(v), 3) for k, v in cpu.items()},
        "cpu_seconds_runs": {k: [round(x, 3) for x in v] for k, v in cpu.items()},
        "mb_per_format": mb,
    }
    for fmt in ("gpkg", "parquet"):  # CPU: best against best, and the worst of the runs (each run's own pair)
        if {"geojson", fmt} <= set(formats):
            result[f"cpu_ratio_geojson_over_{fmt}"] = round(min(cpu["geojson"]) / min(cpu[fmt]), 2)
            result[f"cpu_ratio_worst_run_geojson_over_{fmt}"] = round(
                min(a / b for a, b in zip(cpu["geojson"], cpu[fmt])), 2
            )
    if {"geojson", "gpkg", "parquet"} <= set(formats):
        result["ratio_geojson_over_gpkg"] = round(best["geojson"] / best["gpkg"], 2)
        result["ratio_geojson_over_parquet"] = round(best["geojson"] / best["parquet"], 2)
        result["bbox_query_lots"] = bbox_query(tmp, repeat - 1, layers["lots"])
    return result


def bbox_query(tmp: Path, k: int, lots) -> dict:
    """Seconds to read the lots meeting a 1 km x 1 km window around the city's centre from each file.

    One window, the same for every file: a square in the lots' planar frame,
    densified and reprojected to each file's frame, and the features whose
    geometry meets it (:func:`_window.window_ids`).  GeoJSON and GeoPackage
    through GDAL (pyogrio ``mask=``: the GeoPackage uses its R-tree, the
    GeoJSON is parsed whole), GeoParquet through pyarrow (a filter on its
    ``bbox`` covering columns, then the geometries tested), every column
    read.  Best of three;
    ``same_ids`` says whether the three read the same features.
    """
    import numpy as np
    import shapely

    from sengine.geom.crs import layer_crs

    planar = layer_crs(lots.meta, (0.0, 0.0))
    x0, y0, x1, y1 = shapely.total_bounds(lots.geometry)
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    window = shapely.box(cx - 500, cy - 500, cx + 500, cy + 500)
    files = {
        "geojson": (tmp / f"geojson-{k}" / "lots.geojson", None),
        "gpkg": (tmp / f"gpkg-{k}" / "city.gpkg", "lots"),
        "parquet": (tmp / f"parquet-{k}" / "lots.parquet", None),
    }
    result: dict = {}
    ids = {}
    for fmt, (path, layer) in files.items():
        t_best = float("inf")
        for _ in range(3):
            t = time.perf_counter()
            ids[fmt] = window_ids(path, window, planar, layer=layer, whole_rows=True)
            t_best = min(t_best, time.perf_counter() - t)
        result[fmt] = {"seconds": round(t_best, 4), "features": len(ids[fmt])}
    result["same_ids"] = all(np.array_equal(ids["gpkg"], v) for v in ids.values())
    return result


def e2e_run(python: str, path: str | None, osm: Path, lod: int, workers: int, tmp: Path) -> dict:
    """``sengine osm OSM -o OUT --lod LOD`` in a fresh process: wall and CPU seconds, peak MB, MB written."""
    out = tmp / f"e2e-{lod}"
    env = dict(os.environ)
    if path:
        env["PYTHONPATH"] = path + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    cmd = [python, "-m", "sengine", "osm", str(osm), "-o", str(out), "--lod", str(lod), "--quiet"]
    cmd += ["--workers", str(workers)]
    t = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=path or HERE.parent, env=env, stderr=subprocess.PIPE, text=True)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t
    err = proc.stderr.read()
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode:
        shutil.rmtree(out, ignore_errors=True)
        return {"error": err.strip().splitlines()[-1] if err.strip() else proc.returncode}
    files = {p.name: p.stat().st_size for p in out.iterdir()}
    stats = json.loads((out / "stats.json").read_text())
    shutil.rmtree(out)
    return {
        "wall_seconds": round(wall, 2),
        "cpu_seconds": round(usage.ru_utime + usage.ru_stime, 2),  # the process and the workers it waited for
        "peak_rss_mb": round(usage.ru_maxrss / 1024.0, 1),
        "mb_written": round(sum(files.values()) / 1e6, 1),
        "mb_per_file": {k: round(v / 1e6, 1) for k, v in sorted(files.items())},
        "node_seconds": stats.get("seconds", {}),
    }


def e2e(osm: Path, repeat: int, workers: int, compare: str | None) -> dict:
    """Whole-city runs at LoD 1 and 2 (and ``compare``'s), interleaved; the best wall time of each is kept."""
    routes = {"sengine": (sys.executable, None)}
    if compare:
        python, *rest = shlex.split(compare)
        routes["compare"] = (python, rest[0] if rest else None)
    best: dict = {}
    with tempfile.TemporaryDirectory(dir=os.environ.get("SENGINE_BENCH_TMP")) as tmp:
        for _ in range(repeat):
            for route, (python, path) in routes.items():
                for lod in (1, 2):
                    r = e2e_run(python, path, osm, lod, workers, Path(tmp))
                    print(route, lod, json.dumps({k: v for k, v in r.items() if k != "mb_per_file"}), file=sys.stderr)
                    key = f"{route}_lod{lod}"
                    if "error" in r or r["wall_seconds"] < best.get(key, {}).get("wall_seconds", float("inf")):
                        best[key] = r
    result = {"osm": osm.name, "repeat": repeat, "workers": workers, "runs": best, "compare": compare or ""}
    for route in routes:
        one, two = best.get(f"{route}_lod1", {}), best.get(f"{route}_lod2", {})
        if "wall_seconds" in one and "wall_seconds" in two:
            result[f"{route}_ratio_lod2_over_lod1"] = round(two["wall_seconds"] / one["wall_seconds"], 2)
    if compare:
        for lod in (1, 2):
            a, b = best.get(f"compare_lod{lod}", {}), best.get(f"sengine_lod{lod}", {})
            if "wall_seconds" in a and "wall_seconds" in b:
                result[f"speedup_lod{lod}"] = round(a["wall_seconds"] / b["wall_seconds"], 2)
                result[f"cpu_speedup_lod{lod}"] = round(a["cpu_seconds"] / b["cpu_seconds"], 2)
    return result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--osm", type=Path, default=DEFAULT_OSM, help="whole Liège (or another city) as .osm.pbf")
    ap.add_argument("--city", choices=("grid", "liege", "both", "e2e"), default="both")
    ap.add_argument("--out", type=Path, default=None, help="default: bench/results/export.json (export_e2e.json)")
    ap.add_argument("--compare", help='e2e: another checkout to interleave, "PYTHON [PATH]"')
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="e2e: --workers of each run")
    ap.add_argument(
        "--formats", default=",".join(FORMATS), help="formats to time, e.g. geojson,gpkg,parquet (default: all)"
    )
    args = ap.parse_args()
    formats = tuple(f for f in args.formats.split(",") if f)
    if set(formats) - set(FORMATS):
        sys.exit(f"bench/export.py: --formats: not among {', '.join(FORMATS)}")
    if args.city == "e2e":
        if not args.osm.exists():
            sys.exit(f"bench/export.py: {args.osm} not found (--osm PATH)")
        results = e2e(args.osm, args.repeat, args.workers, args.compare)
        write(args.out or HERE / "results" / "export_e2e.json", "export_e2e", results)
        print(json.dumps(results, indent=1, sort_keys=True))
        return
    args.out = args.out or HERE / "results" / "export.json"
    get("export.city")  # loads the built-in nodes (sengine.nodes)
    results: dict = {"target_ratio": TARGET, "repeat": args.repeat, "formats": list(formats)}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        if args.city in ("grid", "both"):
            plan, layers, extra = grid_layers(tmp, args.repeat)
            (tmp / "grid").mkdir()
            results["grid"] = {**extra, **time_formats(plan, layers, args.repeat, tmp / "grid", formats)}
        if args.city in ("liege", "both"):
            if not args.osm.exists():
                sys.exit(f"bench/export.py: {args.osm} not found (--osm PATH)")
            plan, layers, extra = liege_layers(args.osm)
            (tmp / "liege").mkdir()
            results["liege"] = {
                "osm": args.osm.name,
                **extra,
                **time_formats(plan, layers, args.repeat, tmp / "liege", formats),
            }
            r = results["liege"]
            if "ratio_geojson_over_gpkg" in r:
                r["meets_target"] = min(r["ratio_geojson_over_gpkg"], r["ratio_geojson_over_parquet"]) >= TARGET
    write(args.out, "export", results)
    print(json.dumps(results, indent=1, sort_keys=True))


if __name__ == "__main__":
    main()

"""Benchmark: an OpenStreetMap file to blocks, sengine against the library route.

Times Liège's street network (about 80,000 highway ways) from file to blocks
two ways, each in a fresh process so that peak memory is its own:

* ``sengine``: the load-map network's nodes ``osm.read`` -> ``roads.clean``
  -> ``blocks.circuits`` with the parameters of ``networks/loadmap.xml``
  ("file to blocks", which includes the sidewalk inset and the street and
  sidewalk polygons); and "file to faces", the same product as the library
  route: ``roads.clean`` traces the faces of its plane segment graph
  (``meta["graph"]["blocks"]``, which ``blocks.circuits`` takes over), so
  that is ``osm.read`` -> ``roads.clean`` (plus ``find_blocks`` on the
  graph when clean handed no faces on).
* ``library``: what one writes with the libraries alone -- pyosmium with
  node locations (a Python list of coordinates per way), one pyproj call,
  ``shapely.node`` and ``shapely.polygonize`` -- with the same class filter
  and the same area threshold.

Both give faces between street centre lines; they must agree within 1 % in
count and in area.  Results go to ``bench/results/osm.json``: seconds (best
of ``--repeat``, wall clock) and the CPU seconds of that run (the process's
own time, steadier on a shared machine), peak resident memory, ways per
second, face counts.

Usage::

    python bench/osm.py [PATH.osm.pbf] [--repeat 3] [--out bench/results/osm.json]
"""

from __future__ import annotations

import argparse
import json
import platform
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DEFAULT = ROOT.parent / "shared" / "data" / "liege_streets.osm.pbf"
MIN_AREA = 50.0  # m2, blocks.circuits' default min_area


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def route_sengine(path: str) -> dict:
    import numpy as np
    import shapely

    from sengine.node import Context
    from sengine.registry import get

    get("osm.read"), get("roads.clean"), get("blocks.circuits")  # load the node library before timing
    base = _peak_mb()
    c0, t0 = time.process_time(), time.perf_counter()
    read = get("osm.read")("majorRoads", {"path": path, "extras": ""}, Context())
    roads = read.run()["roads"]
    t1 = time.perf_counter()
    clean = get("roads.clean")("clean", {}, Context())
    cleaned = clean.run(roads=roads)["roads"]
    t2 = time.perf_counter()
    # the circuits alone (what polygonize gives): roads.clean traced them on its plane segment graph
    g = cleaned.meta["graph"]
    bf = g.get("blocks")
    if bf is None:
        from sengine_nodes.blocks import find_blocks

        bf = find_blocks((g["xy"], g["u"], g["v"]), node=False, decimals=None)
    circuits = bf.faces[shapely.area(bf.faces) >= MIN_AREA]
    c3, t3 = time.process_time(), time.perf_counter()
    del bf
    blocks = get("blocks.circuits")("blocks", {"node": "false", "min_area": str(MIN_AREA)}, Context())
    out = blocks.run(roads=cleaned)
    c4, t4 = time.process_time(), time.perf_counter()
    faces = out["faces"].geometry
    return {
        "seconds": (t2 - t0) + (t4 - t3),
        "cpu_seconds": (c3 - c0) + (c4 - c3),
        "seconds_to_faces": t3 - t0,
        "stages": {"osm.read": t1 - t0, "roads.clean (traces the faces too)": t2 - t1,
                   "faces >= min_area": t3 - t2,
                   "blocks.circuits (node: faces taken over + sidewalk inset + street polygons)": t4 - t3},
        "circuits": int(len(circuits)),
        "peak_rss_mb": _peak_mb(), "rss_before_mb": base,
        "ways": read.report["ways"], "segments": len(roads),
        "faces": int(len(faces)), "faces_area_m2": float(shapely.area(faces).sum()),
        "blocks": int(len(out["blocks"])), "clean_report": clean.report,
        "crs": roads.meta["crs"], "_check": int(np.sum(shapely.is_valid(faces))),
    }


def _classes() -> frozenset[str]:
    from sengine.builtin import load

    load()
    import sengine_nodes.osm as osm

    return frozenset(c.strip() for c in (osm.MAJOR_CLASSES + "," + osm.MINOR_CLASSES).split(","))


def route_library(path: str) -> dict:
    import numpy as np
    import osmium
    import pyproj
    import shapely

    keep = _classes()
    base = _peak_mb()
    c0, t0 = time.process_time(), time.perf_counter()
    lines: list = []
    tunnel = ("yes", "building_passage", "culvert")

    class Ways(osmium.SimpleHandler):
        def way(self, w):
            hw = w.tags.get("highway")
            if hw not in keep or w.tags.get("tunnel") in tunnel:
                return
            pts = [(n.lon, n.lat) for n in w.nodes if n.location.valid()]
            if len(pts) >= 2:
                lines.append(pts)

    Ways().apply_file(path, locations=True)
    n = np.fromiter(map(len, lines), np.int64, len(lines))
    lonlat = np.array([p for line in lines for p in line], dtype=np.float64)
    lon, lat = lonlat.mean(axis=0)
    zone = int((lon + 180) // 6) % 60 + 1
    epsg = (32600 if lat >= 0 else 32700) + zone
    tr = pyproj.Transformer.from_crs(4326, epsg, always_xy=True)
    x, y = tr.transform(lonlat[:, 0], lonlat[:, 1])
    geoms = shapely.linestrings(np.column_stack([x, y]), indices=np.repeat(np.arange(len(n)), n))
    t1 = time.perf_counter()
    noded = shapely.node(shapely.multilinestrings(geoms))
    t2 = time.perf_counter()
    polys = shapely.get_parts(shapely.polygonize(shapely.get_parts(noded)))
    area = shapely.area(polys)
    faces = polys[area >= MIN_AREA]
    c3, t3 = time.process_time(), time.perf_counter()
    return {
        "seconds": t3 - t0,
        "cpu_seconds": c3 - c0,
        "stages": {"read+project": t1 - t0, "shapely.node": t2 - t1, "shapely.polygonize": t3 - t2},
        "peak_rss_mb": _peak_mb(), "rss_before_mb": base,
        "ways": len(lines), "faces": int(len(faces)), "faces_area_m2": float(area[area >= MIN_AREA].sum()),
        "crs": f"EPSG:{epsg}",
    }


ROUTES = {"sengine": route_sengine, "library": route_library}


def _child(route: str, path: str) -> dict:
    proc = subprocess.run([sys.executable, __file__, "--route", route, path], capture_output=True, text=True,
                          cwd=ROOT, timeout=600)
    if proc.returncode:
        raise RuntimeError(f"{route} failed:\n{proc.stderr}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("path", nargs="?", default=str(DEFAULT), help="OSM file (default: Liège)")
    ap.add_argument("--repeat", type=int, default=3, help="runs per route; the best time is kept")
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "results" / "osm.json")
    ap.add_argument("--route", choices=sorted(ROUTES), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.route:
        sys.path.insert(0, str(ROOT))
        print(json.dumps(ROUTES[args.route](args.path)))
        return 0
    runs: dict = {r: [] for r in ROUTES}
    for _ in range(args.repeat):
        for r in ROUTES:  # interleaved, so background load hits both alike
            runs[r].append(_child(r, args.path))
    best = {r: min(rs, key=lambda d: d["seconds"]) for r, rs in runs.items()}
    best["sengine"]["seconds_to_faces"] = min(d["seconds_to_faces"] for d in runs["sengine"])
    for r, d in best.items():
        d["all_seconds"] = [round(x["seconds"], 3) for x in runs[r]]
        d["ways_per_s"] = d["ways"] / d["seconds"]
        d.pop("_check", None)
    s, lib = best["sengine"], best["library"]
    result = {
        "file": Path(args.path).name,
        "min_area_m2": MIN_AREA,
        "sengine": s,
        "library": lib,
        "speedup_file_to_blocks": lib["seconds"] / s["seconds"],
        "speedup_file_to_faces": lib["seconds"] / s["seconds_to_faces"],
        "ratio_sengine_to_library": s["seconds"] / lib["seconds"],
        "ratio_sengine_to_library_cpu": s["cpu_seconds"] / lib["cpu_seconds"],
        "faces_diff_pct": 100.0 * (s["faces"] - lib["faces"]) / max(lib["faces"], 1),
        "area_diff_pct": 100.0 * (s["faces_area_m2"] - lib["faces_area_m2"]) / max(lib["faces_area_m2"], 1e-9),
        "machine": {"python": platform.python_version(), "cpu_count": __import__("os").cpu_count(),
                    "platform": platform.platform()},
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"{result['file']}: sengine {s['seconds']:.2f} s to blocks, {s['seconds_to_faces']:.2f} s to faces "
          f"({s['faces']} faces, {s['blocks']} blocks), library {lib['seconds']:.2f} s ({lib['faces']} faces); "
          f"speed-up {result['speedup_file_to_blocks']:.2f}x / {result['speedup_file_to_faces']:.2f}x "
          f"(sengine / library: {result['ratio_sengine_to_library']:.2f} wall, "
          f"{result['ratio_sengine_to_library_cpu']:.2f} CPU); "
          f"faces {result['faces_diff_pct']:+.2f} %, area {result['area_diff_pct']:+.2f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())

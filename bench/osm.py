"""Benchmark: an OpenStreetMap file to blocks, sengine against the library route.

Times Liège's street network (about 80,000 highway ways) from file to blocks
two ways, each in a fresh process so that peak memory is its own:

* ``sengine``: the load-map network's nodes ``osm.read`` -> ``roads.clean``
  -> ``blocks.circuits`` with the parameters of ``sengine/nodes/networks/loadmap.xml``
  ("file to blocks", which includes the sidewalk inset and the street and
  sidewalk polygons); and "file to faces", the same product as the library
  route: ``roads.clean`` traces the faces of its plane segment graph
  (on its ``graph`` port, which ``blocks.circuits`` takes over), so
  that is ``osm.read`` -> ``roads.clean`` (plus ``find_blocks`` on the
  graph when clean handed no faces on).
* ``library``: what one writes with the libraries alone -- pyosmium with
  node locations (a Python list of coordinates per way), one pyproj call,
  ``shapely.node`` and ``shapely.polygonize`` -- with the same class filter,
  the same ground level (no bridge, tunnel or other layer), the same
  closing edges (the streets' bounding box, when the load-map network
  closes along it) and the same area threshold.

Both give faces between street centre lines; they must agree within 1 % in
count and in area.  Each route imports its libraries (pyosmium, pyproj,
shapely, the node library) before its clock starts.  Issue 4's target is
sengine in at most a third of the library route's time, on both measures:
``ratio_faces`` (file to faces / library) and ``ratio_blocks`` (file to
blocks / the library route plus a vectorized ``shapely.buffer`` inset of its
faces by :data:`INSET`, as issue 13 restates it like for like).  Results go to ``bench/results/osm.json``: seconds (best
of ``--repeat``, wall clock; the runs alternate between the routes, so
that background load hits both alike) and the CPU seconds of that run (all
the route's processes, should a stage fork), peak resident memory,
ways per second, face counts.

Usage::

    python bench/osm.py [PATH.osm.pbf] [--repeat 3] [--out bench/results/osm.json]
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

from _results import write  # bench/ is on sys.path when run as a script

ROOT = Path(__file__).resolve().parent.parent
DEFAULT = ROOT.parent / "shared" / "data" / "liege_streets.osm.pbf"
MIN_AREA = 50.0  # m2, blocks.circuits' default min_area


TARGET = 1 / 3  # issue 4: sengine in at most a third of the library route's time
#: The library route's block inset (m): half of blocks.circuits' default 10 m street and its 3 m sidewalk.
INSET = 5.0 + 3.0


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _cpu() -> float:
    """CPU seconds of this process and its finished children (a forked reader)."""
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def route_sengine(path: str) -> dict:
    import numpy as np
    import osmium  # noqa: F401 (imported before the clock, as the library route does)
    import shapely

    from sengine.node import Context, NodeResult
    from sengine.registry import get

    get("osm.read"), get("roads.clean"), get("blocks.circuits")  # load the node library before timing
    params = _loadmap_params()
    base = _peak_mb()
    c0, t0 = _cpu(), time.perf_counter()
    read = get("osm.read")("majorRoads", {"path": path, "extras": ""}, Context())
    read_out = NodeResult.of(read, read.run())  # a node hands its report with its layers
    roads = read_out.layers["roads"]
    c1, t1 = _cpu(), time.perf_counter()
    clean = get("roads.clean")("clean", params["clean"], Context())
    clean_out = NodeResult.of(clean, clean.run(roads=roads))
    cleaned = clean_out.layers["roads"]
    c2, t2 = _cpu(), time.perf_counter()
    # the circuits alone (what polygonize gives): roads.clean traced them on its plane segment graph
    g = clean_out.layers["graph"]
    bf = g.meta.get("faces")
    if bf is None:
        from sengine.nodes.blocks.circuits import find_blocks

        bf = find_blocks((g.meta["xy"], g["u"], g["v"]), node=False, decimals=None)
    circuits = bf.faces[shapely.area(bf.faces) >= MIN_AREA]
    c3, t3 = _cpu(), time.perf_counter()
    del bf
    blocks = get("blocks.circuits")("blocks", {**params["blocks"], "min_area": str(MIN_AREA)}, Context())
    out = NodeResult.of(blocks, blocks.run(roads=cleaned, graph=clean_out.layers["graph"])).layers
    c4, t4 = _cpu(), time.perf_counter()
    faces = out["faces"].geometry
    box = cleaned.meta.get("bbox")
    if box is not None:  # the land round the streets, as the library route closes it: within the box
        faces = shapely.intersection(faces, shapely.box(*box))
    return {
        "seconds": (t2 - t0) + (t4 - t3),
        "cpu_seconds": c4 - c0,
        "cpu_seconds_to_faces": c3 - c0,
        "seconds_to_faces": t3 - t0,
        "stages": {
            "osm.read": t1 - t0,
            "roads.clean (traces the faces too)": t2 - t1,
            "faces >= min_area": t3 - t2,
            "blocks.circuits (node: faces taken over + sidewalk inset + street polygons)": t4 - t3,
        },
        # CPU seconds of the same stages (forked processes included): on a busy machine the wall
        # clock of a stage counts the time the others' processes held the cores
        "stages_cpu": {"osm.read": c1 - c0, "roads.clean": c2 - c1, "blocks.circuits": c4 - c3},
        "circuits": int(len(circuits)),
        "peak_rss_mb": _peak_mb(),
        "rss_before_mb": base,
        "ways": read_out.report["ways"],
        "segments": len(roads),
        "faces": int(len(faces)),
        "faces_area_m2": float(shapely.area(faces).sum()),
        "blocks": int(len(out["blocks"])),
        "clean_report": clean_out.report,
        "crs": roads.meta["crs"],
        "_check": int(np.sum(shapely.is_valid(faces))),
    }


def _loadmap_params() -> dict:
    """The parameters ``sengine/nodes/networks/loadmap.xml`` gives the clean and blocks nodes."""
    from sengine.nodes.standard import NETWORKS_DIR
    from sengine.xmlconfig import read_network_file

    specs = read_network_file(NETWORKS_DIR / "loadmap.xml").specs
    return {k: dict(specs[k].params) for k in ("clean", "blocks")}


def _classes() -> frozenset[str]:

    import sengine.nodes.osm.read as osm

    return frozenset(c.strip() for c in (osm.MAJOR_CLASSES + "," + osm.MINOR_CLASSES).split(","))


def route_library(path: str) -> dict:
    import numpy as np
    import osmium
    import pyproj
    import shapely

    keep = _classes()
    close = _loadmap_params()["clean"].get("close") == "bbox"
    base = _peak_mb()
    c0, t0 = _cpu(), time.perf_counter()
    lines: list = []
    off = ("yes", "building_passage", "culvert")

    class Ways(osmium.SimpleHandler):
        def way(self, w):
            hw = w.tags.get("highway")
            if hw not in keep:
                return
            # the ground level: no tunnel, no bridge, no other layer (as the loadmap network traces it)
            t = w.tags
            if t.get("tunnel") in off or t.get("bridge", "no") != "no" or t.get("layer", "0") not in ("0", ""):
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
    if close:  # closed along the streets' bounding box
        geoms = np.r_[geoms, [shapely.boundary(shapely.box(*shapely.total_bounds(geoms)))]]
    c1, t1 = _cpu(), time.perf_counter()
    noded = shapely.node(shapely.multilinestrings(geoms))
    c2, t2 = _cpu(), time.perf_counter()
    polys = shapely.get_parts(shapely.polygonize(shapely.get_parts(noded)))
    area = shapely.area(polys)
    faces = polys[area >= MIN_AREA]
    c3, t3 = _cpu(), time.perf_counter()
    # the blocks of the library route: the faces inset in one vectorized buffer, by half a street and a sidewalk
    blocks = shapely.buffer(faces, -INSET, join_style="mitre")
    c4, t4 = _cpu(), time.perf_counter()
    return {
        "seconds": t3 - t0,
        "cpu_seconds": c3 - c0,
        "seconds_blocks": t4 - t0,
        "cpu_seconds_blocks": c4 - c0,
        "blocks": int((~shapely.is_empty(blocks)).sum()),
        "stages": {
            "read+project": t1 - t0,
            "shapely.node": t2 - t1,
            "shapely.polygonize": t3 - t2,
            f"shapely.buffer(faces, -{INSET:g})": t4 - t3,
        },
        "stages_cpu": {"read+project": c1 - c0, "shapely.node": c2 - c1, "polygonize": c3 - c2, "buffer": c4 - c3},
        "peak_rss_mb": _peak_mb(),
        "rss_before_mb": base,
        "ways": len(lines),
        "faces": int(len(faces)),
        "faces_area_m2": float(area[area >= MIN_AREA].sum()),
        "crs": f"EPSG:{epsg}",
    }


ROUTES = {"sengine": route_sengine, "library": route_library}


def _child(route: str, path: str) -> dict:
    proc = subprocess.run(
        [sys.executable, __file__, "--route", route, path], capture_output=True, text=True, cwd=ROOT, timeout=600
    )
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
    best["library"]["seconds_blocks"] = min(d["seconds_blocks"] for d in runs["library"])
    best["library"]["all_seconds_blocks"] = [round(d["seconds_blocks"], 3) for d in runs["library"]]
    best["sengine"]["seconds_to_faces"] = min(d["seconds_to_faces"] for d in runs["sengine"])
    best["sengine"]["all_seconds_to_faces"] = [round(d["seconds_to_faces"], 3) for d in runs["sengine"]]
    for r, d in best.items():
        d["all_seconds"] = [round(x["seconds"], 3) for x in runs[r]]
        d["ways_per_s"] = d["ways"] / d["seconds"]
        d.pop("_check", None)
    s, lib = best["sengine"], best["library"]
    # issue 13, like for like: file -> faces against the library's faces; file -> blocks (with the
    # sidewalk inset) against the library's faces plus a vectorized buffer inset of them
    ratio = {"faces": s["seconds_to_faces"] / lib["seconds"], "blocks": s["seconds"] / lib["seconds_blocks"]}
    median = {
        k: statistics.median(s[f"all_{key}"]) / statistics.median(lib[f"all_{lkey}"])
        for k, key, lkey in (("faces", "seconds_to_faces", "seconds"), ("blocks", "seconds", "seconds_blocks"))
    }
    result = {
        "file": Path(args.path).name,
        "min_area_m2": MIN_AREA,
        "sengine": s,
        "library": lib,
        "ratio_faces": ratio["faces"],
        "ratio_blocks": ratio["blocks"],
        "ratio_faces_cpu": s["cpu_seconds_to_faces"] / lib["cpu_seconds"],
        "ratio_blocks_cpu": s["cpu_seconds"] / lib["cpu_seconds_blocks"],
        "ratio_of_medians": median,
        "target_ratio": TARGET,
        "meets_target": {k: bool(v <= TARGET) for k, v in ratio.items()},
        "faces_diff_pct": 100.0 * (s["faces"] - lib["faces"]) / max(lib["faces"], 1),
        "area_diff_pct": 100.0 * (s["faces_area_m2"] - lib["faces_area_m2"]) / max(lib["faces_area_m2"], 1e-9),
    }
    write(args.out, "osm", result)
    verdict = {k: "meets" if v else "misses" for k, v in result["meets_target"].items()}
    print(
        f"{result['file']}: library {lib['seconds']:.2f} s ({lib['faces']} faces; "
        f"{lib['seconds_blocks']:.2f} s with the buffer inset); sengine "
        f"file->faces {s['seconds_to_faces']:.2f} s = {ratio['faces']:.2f} x library ({verdict['faces']} "
        f"the {TARGET:.2f} target), file->blocks {s['seconds']:.2f} s = {ratio['blocks']:.2f} x library + inset "
        f"({verdict['blocks']} it; {s['faces']} faces, {s['blocks']} blocks); "
        f"faces {result['faces_diff_pct']:+.2f} %, area {result['area_diff_pct']:+.2f} %"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Benchmark: blocks as minimal circuits (skylineEngine §5.4), vectorized.

Cases, each run in a fresh process so that its peak memory is its own:

* ``grid``: a synthetic jittered street grid (``--grid N``: N x N blocks,
  2 N (N + 1) segments) through ``find_blocks`` (lines entry: node merge,
  planarize, faces) and through the ``blocks.circuits`` node (plus the
  sidewalk inset and the street / sidewalk layers).
* ``liege``: Liège's street network (about 80,000 highway ways, one straight
  segment each), read here simply with pyosmium and projected with pyproj,
  then ``find_blocks`` on the ``(xy, u, v)`` arrays entry (node ids from OSM
  node ids, merged by coordinates), the ``blocks.circuits`` node on the
  same segments as LineStrings, ``shapely.polygonize`` for reference, and
  ``lots.manhattan`` on the resulting blocks.

Times are the best of ``--repeat`` runs; ``peak_rss_mb`` is the process's
peak resident memory (``resource``), ``peak_traced_mb`` the peak of Python
and numpy allocations during one ``find_blocks`` call (``tracemalloc``;
GEOS memory is not traced).  Results go to ``bench/results/blocks.json``.

Usage::

    python bench/blocks.py [--grid 200] [--repeat 3] [--osm PATH] [--out bench/results/blocks.json]
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np
import shapely
from _results import write  # bench/ is on sys.path when run as a script

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
LIEGE = next(
    (
        p
        for p in (ROOT / "configs/data/liege_streets.osm.pbf", ROOT.parent / "shared/data/liege_streets.osm.pbf")
        if p.exists()
    ),
    ROOT / "configs/data/liege_streets.osm.pbf",
)


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _best(fn, repeat):
    best, out = float("inf"), None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def _traced(fn) -> float:
    tracemalloc.start()
    fn()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak / 2**20


def _modules():

    import sengine.nodes.blocks.circuits as blocks
    import sengine.nodes.lots.nodes as lots

    return blocks, lots


def grid_lines(n: int, step: float = 100.0, jitter: float = 15.0, seed: int = 0):
    rng = np.random.default_rng(seed)
    gx, gy = np.meshgrid(np.arange(n + 1) * step, np.arange(n + 1) * step, indexing="ij")
    pts = np.stack([gx, gy], -1) + rng.uniform(-jitter, jitter, (n + 1, n + 1, 2))
    horiz = np.stack([pts[:-1, :], pts[1:, :]], axis=2).reshape(-1, 2, 2)
    vert = np.stack([pts[:, :-1], pts[:, 1:]], axis=2).reshape(-1, 2, 2)
    return shapely.linestrings(np.concatenate([horiz, vert]))


def read_liege(path: Path):
    """Highway ways as (xy, u, v): one straight segment per way in this file."""
    import osmium
    from pyproj import Transformer

    ids, lon, lat, way = [], [], [], []
    for k, obj in enumerate(osmium.FileProcessor(str(path)).with_locations()):
        if obj.is_way():
            for nd in obj.nodes:
                ids.append(nd.ref)
                lon.append(nd.lon)
                lat.append(nd.lat)
                way.append(k)
    ids, way = np.asarray(ids), np.asarray(way)
    x, y = Transformer.from_crs("EPSG:4326", "EPSG:32631", always_xy=True).transform(np.asarray(lon), np.asarray(lat))
    uid, inv = np.unique(ids, return_inverse=True)
    xy = np.zeros((len(uid), 2))
    xy[inv] = np.c_[x, y]
    same = way[1:] == way[:-1]  # consecutive nodes of one way
    a = np.flatnonzero(same)
    return xy, inv[a], inv[a + 1], len(np.unique(way))


def case_grid(n: int, repeat: int) -> dict:
    from sengine import Layer
    from sengine.registry import get

    B, _ = _modules()
    lines = grid_lines(n)
    t_find, bf = _best(lambda: B.find_blocks(lines), repeat)
    roads = Layer.from_geoms(lines, width=np.full(len(lines), 12.0))
    node = get("blocks.circuits")("blocks", {})
    t_node, out = _best(lambda: node.run(roads=roads), repeat)
    traced = _traced(lambda: B.find_blocks(lines))
    return {
        "case": f"grid {n}x{n}",
        "segments": int(len(lines)),
        "faces": int(len(bf.faces)),
        "blocks": int(len(out["blocks"])),
        "expected_faces": n * n,
        "find_blocks_s": round(t_find, 4),
        "node_s": round(t_node, 4),
        "segments_per_s": round(len(lines) / t_find),
        "peak_traced_mb": round(traced, 1),
        "peak_rss_mb": round(_peak_mb(), 1),
        "report": node.report,
    }


def case_liege(path: Path, repeat: int) -> dict:
    from sengine import Layer
    from sengine.registry import get

    B, L = _modules()
    t_read, (xy, u, v, nways) = _best(lambda: read_liege(path), 1)
    t_find, bf = _best(lambda: B.find_blocks((xy, u, v)), repeat)
    traced = _traced(lambda: B.find_blocks((xy, u, v)))
    lines = shapely.linestrings(np.stack([xy[u], xy[v]], axis=1))
    roads = Layer.from_geoms(lines, width=np.full(len(lines), 10.0))
    node = get("blocks.circuits")("blocks", {})
    t_node, out = _best(lambda: node.run(roads=roads), repeat)
    lots_node = get("lots.manhattan")("lots", {})
    t_lots, lots = _best(lambda: lots_node.run(blocks=out["blocks"]), repeat)
    # reference: GEOS noding + polygonize on the same segments
    t_poly, ref = _best(
        lambda: shapely.get_parts(shapely.polygonize(shapely.get_parts(shapely.node(shapely.multilinestrings(lines))))),
        1,
    )
    ref_area = float(shapely.area(ref).sum())
    area = float(shapely.area(bf.faces).sum())
    return {
        "case": "liege",
        "file": path.name,
        "ways": int(nways),
        "segments": int(len(u)),
        "read_s": round(t_read, 3),
        "find_blocks_s": round(t_find, 4),
        "file_to_faces_s": round(t_read + t_find, 3),
        "node_s": round(t_node, 4),
        "lots_manhattan_s": round(t_lots, 4),
        "segments_per_s": round(len(u) / t_find),
        "faces": int(len(bf.faces)),
        "blocks": int(len(out["blocks"])),
        "lots": int(len(lots["lots"])),
        "lots_per_s": round(len(lots["lots"]) / t_lots),
        "polygonize_s": round(t_poly, 3),
        "polygonize_faces": int(len(ref)),
        "area_rel_diff_vs_polygonize": abs(area - ref_area) / ref_area,
        "find_blocks_counts": bf.counts,
        "node_report": node.report,
        "peak_traced_mb": round(traced, 1),
        "peak_rss_mb": round(_peak_mb(), 1),
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--grid", type=int, default=200, help="grid of N x N blocks")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--osm", type=Path, default=LIEGE)
    ap.add_argument("--out", type=Path, default=ROOT / "bench/results/blocks.json")
    ap.add_argument("--case", choices=("grid", "liege"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.case == "grid":
        print(json.dumps(case_grid(args.grid, args.repeat)))
        return 0
    if args.case == "liege":
        print(json.dumps(case_liege(args.osm, args.repeat)))
        return 0
    results = []
    for case in ("grid", "liege"):
        if case == "liege" and not args.osm.exists():
            print(f"skip liege: {args.osm} not found", file=sys.stderr)
            continue
        proc = subprocess.run(
            [
                sys.executable,
                __file__,
                "--case",
                case,
                "--grid",
                str(args.grid),
                "--repeat",
                str(args.repeat),
                "--osm",
                str(args.osm),
            ],
            capture_output=True,
            text=True,
            check=True,
        )
        res = json.loads(proc.stdout.strip().splitlines()[-1])
        print(json.dumps(res, indent=1), file=sys.stderr)
        results.append(res)
    write(args.out, "blocks", results)
    return 0


if __name__ == "__main__":
    sys.exit(main())

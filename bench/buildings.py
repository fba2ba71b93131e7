"""Benchmark: buildings to meshes per second, LoD1 boxes and LoD2 roofs, on whole Liège.

Builds the city of an OSM extract as ``sengine osm`` does (the load-map
network; default: whole Liège, ``shared/data/liege_streets.osm.pbf``, 241k
buildings, generated on its lots plus the map's own), then times, on one core
and best of ``--repeat``:

* ``lod1``: :func:`sengine.nodes.export.roofs.box_solids` (flat-roofed boxes);
* ``lod2_tagged``: :func:`~sengine.nodes.export.roofs.layer_solids` with the
  map's own ``roof:shape`` tags (most OSM buildings have none: flat);
* ``lod2_every_kind``: every building given one of the seven roof kinds in
  turn (by id), the hard case: a seventh of them each gable, hip, pyramid ...

Targets (issue 12): LoD1 >= 100,000 buildings/s, LoD2 >= 20,000 buildings/s.
Writes ``bench/results/buildings.json``.

    python bench/buildings.py [--osm PATH] [--repeat 3] [--limit N]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections import Counter
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import numpy as np  # noqa: E402
import shapely  # noqa: E402
from _osm import osm_network  # noqa: E402
from _results import RESULTS, write  # noqa: E402

LIEGE = HERE.parent.parent / "shared" / "data" / "liege_streets.osm.pbf"


def best_of(repeat: int, func) -> tuple[float, float, object]:
    """Best wall-clock and best CPU seconds of ``repeat`` runs, and the last result.

    CPU time is what other processes on a shared machine disturb least.
    """
    best, cpu, out = float("inf"), float("inf"), None
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        out = func()
        best = min(best, time.perf_counter() - t)
        cpu = min(cpu, time.process_time() - c)
    return best, cpu, out


def city_buildings(path: Path):
    """The buildings layer that ``sengine osm PATH`` exports (run in memory, one worker)."""
    net = osm_network(path, name="bench")
    layers, _ = net.run(workers=1)
    ((src, port),) = [
        (s, sp) for s, sp, d, dp in net.validate().edges if net.specs[d].type == "export.city" and dp == "buildings"
    ]
    return layers[src][port]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--osm", type=Path, default=Path(os.environ.get("SENGINE_LIEGE", LIEGE)))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--limit", type=int, default=0, help="only the first N buildings (0: all)")
    ap.add_argument("--out", type=Path, default=RESULTS / "buildings.json")
    args = ap.parse_args()
    from sengine.nodes.export import roofs

    t = time.perf_counter()
    buildings = city_buildings(args.osm)
    read_s = time.perf_counter() - t
    if args.limit:
        buildings = buildings.take(np.arange(min(args.limit, len(buildings))))
    n = len(buildings)
    geoms = buildings.geometry
    kinds = np.array(roofs.ROOF_KINDS, object)[buildings.ids % len(roofs.ROOF_KINDS)]
    every = buildings.with_columns(roof=kinds, roof_height=np.full(n, np.nan))
    cases = {
        "lod1": lambda: roofs.box_solids(geoms, buildings["height"]),
        "lod2_tagged": lambda: roofs.layer_solids(buildings, 2),
        "lod2_every_kind": lambda: roofs.layer_solids(every, 2),
    }
    results: dict = {
        "osm": args.osm.name,
        "buildings": n,
        "seconds_city": round(read_s, 2),
        "tagged_roofs": dict(Counter(buildings.get("roof", np.full(n, "flat", object)).tolist())),
        "concave_share": round(
            float(np.mean(~np.isclose(shapely.area(shapely.convex_hull(geoms)), shapely.area(geoms), rtol=1e-9))), 3
        ),
        "with_holes": int((shapely.get_num_interior_rings(geoms) > 0).sum()),
        "cases": {},
    }
    for name, func in cases.items():
        seconds, cpu, solids = best_of(args.repeat, func)
        results["cases"][name] = {
            "seconds": round(seconds, 3),
            "buildings_per_second": round(n / seconds),
            "cpu_seconds": round(cpu, 3),
            "buildings_per_cpu_second": round(n / cpu),
            "vertices": int(len(solids.vertices)),
            "triangles": int(len(solids.faces)),
            "notes": solids.notes,
        }
        print(
            f"{name}: {n / seconds:,.0f} buildings/s ({seconds:.2f} s; CPU {cpu:.2f} s, {n / cpu:,.0f}/s; "
            f"{len(solids.faces):,} triangles)",
            file=sys.stderr,
        )
    results["targets"] = {"lod1": 100_000, "lod2": 20_000}
    write(args.out, "buildings", results)


if __name__ == "__main__":
    main()

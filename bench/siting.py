"""Benchmark: building footprints from planning rules on whole Liège (the footprint half of issue 12).

Lots come from Liège's street network (about 80,000 segments) through the
load-map nodes ``osm.read`` -> ``roads.clean`` -> ``blocks.circuits`` ->
``lots.recursive`` (about 3,450 blocks, 250,000 lots), made once and cached
(pickled layers) in the temporary folder.  On them, in one process, best of
``--repeat`` runs of ``node.run``:

* ``buildings.extrude``: the box on every lot (lot inset by 2 m), the baseline;
* ``buildings.massing``: siting with front / side / rear setbacks and party
  walls, typologies by land use (residential: I, L, U, tower), floors from
  the height (no height map here), roofs;
* ``buildings.massing`` with ``far=3``: the same, the FAR capping the floors
  (the FAR-to-building loop on the lots over it);
* ``buildings.far`` with ``far=2``: FAR-to-building (000 §5.3) on every lot.

Figures: seconds, buildings (parts) and lots per second, and each case's
time over the extrude baseline measured in the same run.  Results go to
``bench/results/siting.json``.  (``bench/buildings.py`` measures the other
half, buildings to meshes.)

Usage::

    python bench/siting.py [PATH.osm.pbf] [--repeat 3] [--out bench/results/siting.json]
"""

from __future__ import annotations

import argparse
import hashlib
import pickle
import resource
import sys
import tempfile
import time
from pathlib import Path

from _results import write  # bench/ is on sys.path when run as a script

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
DEFAULT = ROOT.parent / "shared" / "data" / "liege_streets.osm.pbf"

CASES = (
    ("extrude", "buildings.extrude", {}),
    ("massing", "buildings.massing", {}),
    ("massing_far_cap_3", "buildings.massing", {"far": "3"}),
    ("far_2", "buildings.far", {"far": "2"}),
)


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def liege_lots(path: Path):
    """Lots and blocks of the extract through the load-map nodes, cached."""
    st = path.stat()
    tag = hashlib.sha1(f"{path.resolve()}:{st.st_size}:{st.st_mtime_ns}".encode()).hexdigest()[:12]
    cache = Path(tempfile.gettempdir()) / f"sengine_bench_siting_{tag}.pkl"
    if cache.exists():
        return pickle.loads(cache.read_bytes())
    from sengine import Context
    from sengine.registry import get

    ctx = Context(seed=1)
    roads = get("osm.read")("majorRoads", {"path": str(path), "extras": ""}, ctx).run()["roads"]
    roads = get("roads.clean")("clean", {}, ctx).run(roads=roads)["roads"]
    blocks = get("blocks.circuits")("blocks", {"node": False}, ctx).run(roads=roads)["blocks"]
    lots = get("lots.recursive")("lots", {}, ctx).run(blocks=blocks)["lots"]
    cache.write_bytes(pickle.dumps((lots, blocks)))
    return lots, blocks


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("path", nargs="?", default=str(DEFAULT))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "siting.json"))
    args = ap.parse_args(argv)
    from sengine import Context
    from sengine.registry import get

    lots, blocks = liege_lots(Path(args.path))
    results = {}
    best = {name: float("inf") for name, _, _ in CASES}
    counts = {}
    for _ in range(args.repeat):  # cases interleaved: background load hits them alike
        for name, node, params in CASES:
            n = get(node)("buildings", params, Context(seed=1))
            kw = {"lots": lots} if node == "buildings.extrude" else {"lots": lots, "blocks": blocks}
            t = time.perf_counter()
            out = n.run(**kw)["buildings"]
            best[name] = min(best[name], time.perf_counter() - t)
            counts[name] = (len(out), n.report)
    base = best["extrude"]
    for name, node, params in CASES:
        built, report = counts[name]
        results[name] = {
            "node": node,
            "params": params,
            "seconds": round(best[name], 3),
            "buildings": built,
            "buildings_per_s": round(built / best[name]),
            "lots_per_s": round(len(lots) / best[name]),
            "over_extrude": round(best[name] / base, 2),
            "far_iterated": report.get("far_iterated", 0),
            "typologies": report.get("typologies", {}),
        }
        print(
            f"{name:20s} {best[name]:7.2f} s  {built:7d} buildings  {built / best[name]:9.0f} /s  "
            f"x{best[name] / base:.1f} extrude"
        )
    write(
        args.out,
        "siting",
        {
            "source": Path(args.path).name,
            "lots": len(lots),
            "blocks": len(blocks),
            "repeat": args.repeat,
            "peak_rss_mb": round(_peak_mb(), 1),
            "cases": results,
        },
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

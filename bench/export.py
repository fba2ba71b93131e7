"""Benchmark: buildings.extrude and every exporter on a Manhattan-sized grid city.

The Manhattan-like example of the paper (002 §8) has 931 blocks and 7,471 lots;
this builds a grid city of the same size (930 blocks, 7,440 lots, each with a
building), then times ``buildings.extrude`` and each format of ``export.city``.
Writes ``bench/results/export.json``.

    python bench/export.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

from _city import grid_city  # noqa: E402

from sengine import Context  # noqa: E402
from sengine.registry import get  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    get("export.city")  # loads the built-in nodes (sengine.nodes)
    from sengine.nodes.export.city import export_layers

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        plan, layers = grid_city(nx=31, ny=30, lots_per_side=4, height_map=tmp)
        extrude = get("buildings.extrude")("buildings", {}, Context(seed=7, plan=plan))
        best_b = float("inf")
        for _ in range(args.repeat):
            t = time.perf_counter()
            layers["buildings"] = extrude.run(lots=layers["lots"])["buildings"]
            best_b = min(best_b, time.perf_counter() - t)
        formats = ("glb", "geojson", "osm", "png", "obj", "cityjson")
        best: dict[str, float] = {}
        sizes: dict[str, int] = {}
        for k in range(args.repeat):
            out = tmp / f"out{k}"
            out.mkdir()
            rep = export_layers(out, layers, formats, plan=plan)
            for f, s in rep["seconds"].items():
                best[f] = min(best.get(f, float("inf")), s)
            sizes = {p.name: p.stat().st_size for p in sorted(out.iterdir())}
    default = sum(best[f] for f in ("glb", "geojson", "osm", "png"))
    result = {
        "city": {name: len(lay) for name, lay in layers.items()},
        "seconds_buildings_extrude": round(best_b, 4),
        "seconds_per_format": {k: round(v, 4) for k, v in best.items()},
        "seconds_default_formats": round(default, 4),
        "seconds_all_formats": round(sum(best.values()), 4),
        "bytes": sizes,
        "repeat": args.repeat,
        "python": platform.python_version(),
        "machine": platform.machine(),
    }
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / "export.json").write_text(json.dumps(result, indent=2, sort_keys=True) + "\n")
    print(json.dumps(result, indent=2, sort_keys=True))


if __name__ == "__main__":
    main()

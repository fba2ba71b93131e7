"""Benchmark: the Manhattan-like demo (configs/manhattan.xml), the paper's experiment.

Runs, each in a fresh process so that its peak memory is its own:

* ``api``: ``sengine.load(config).run(seed, out)``: seconds per stage (the
  executor's own timings), total seconds, stage counts, peak resident memory;
* ``scale10``: the same maps and rules on a city of 10x the area (both
  sides times sqrt(10)), to see how each stage scales;
* ``cli``: ``sengine run CONFIG -o OUT`` as a subprocess, wall time from
  process start to the files written (imports and exports included).

Times are the best of ``--repeat`` runs.  Results go to
``bench/results/manhattan.json``.

Usage::

    python bench/manhattan.py [--repeat 3] [--seed 7] [--out bench/results/manhattan.json]
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CONFIG = ROOT / "configs" / "manhattan.xml"
PAPER = {"majorRoads": 86, "blocks": 931, "lots": 7471}


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def case(name: str, seed: int, repeat: int) -> dict:
    """Run one case in this process; print its JSON figures."""
    sys.path.insert(0, str(ROOT))
    import sengine

    best = None
    for _ in range(repeat):
        net = sengine.load(CONFIG)
        if name == "scale10":
            k = math.sqrt(10.0)
            net.plan.size = (net.plan.size[0] * k, net.plan.size[1] * k)
        with tempfile.TemporaryDirectory() as tmp:
            t = time.perf_counter()
            try:
                _, stats = net.run(seed=seed, out=Path(tmp) / "out")
            except TypeError:  # an executor without out=
                _, stats = net.run(seed=seed)
            wall = time.perf_counter() - t
        if best is None or wall < best["wall_seconds"]:
            best = {"wall_seconds": round(wall, 4), "seconds": stats.get("seconds", {}),
                    "counts": stats.get("counts", {}), "size_m": list(net.plan.size)}
    best["peak_rss_mb"] = round(_peak_mb(), 1)
    return best


def cli(seed: int, repeat: int) -> dict:
    times = []
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "out"
            t = time.perf_counter()
            proc = subprocess.run([sys.executable, "-m", "sengine", "run", str(CONFIG), "-o", str(out),
                                   "--seed", str(seed)], capture_output=True, text=True, cwd=ROOT)
            wall = time.perf_counter() - t
            if proc.returncode != 0:
                return {"error": proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else proc.returncode}
            files = sorted(p.name for p in out.iterdir())
        times.append(wall)
    return {"wall_seconds": round(min(times), 4), "files": files}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "results" / "manhattan.json")
    ap.add_argument("--case", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.case:
        print(json.dumps(case(args.case, args.seed, args.repeat)))
        return
    results = {}
    for name in ("api", "scale10"):
        proc = subprocess.run([sys.executable, __file__, "--case", name, "--seed", str(args.seed),
                               "--repeat", str(args.repeat if name == "api" else 1)],
                              capture_output=True, text=True, cwd=ROOT)
        if proc.returncode != 0:
            results[name] = {"error": proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else "failed"}
        else:
            results[name] = json.loads(proc.stdout.strip().splitlines()[-1])
        print(name, json.dumps(results[name]))
    results["cli"] = cli(args.seed, args.repeat)
    print("cli", json.dumps(results["cli"]))
    api = results.get("api", {})
    if "counts" in api:
        results["paper"] = {k: {"paper": v, "sengine": api["counts"].get(k),
                                "ratio": round(api["counts"].get(k, 0) / v, 3)} for k, v in PAPER.items()}
    if "counts" in api and "counts" in results.get("scale10", {}):
        results["scaling"] = {k: {"counts_ratio": round(results["scale10"]["counts"].get(k, 0) / max(v, 1), 2),
                                  "seconds_ratio": round(results["scale10"]["seconds"].get(k, 0)
                                                         / max(api["seconds"].get(k, 1e-9), 1e-9), 2)}
                              for k, v in api["counts"].items()}
    results["meta"] = {"python": platform.python_version(), "machine": platform.machine(),
                       "processor": platform.processor(), "seed": args.seed, "repeat": args.repeat,
                       "config": str(CONFIG.relative_to(ROOT))}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

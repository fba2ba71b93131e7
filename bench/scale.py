"""Benchmark: one very large city, maps to GeoParquet + stats, at 100k, 300k and 1M lots (issue 13).

Runs ``sengine run configs/metropolis.xml --scale F --format parquet`` for
each scale, each in a fresh process (wall seconds from process start to files
written; peak resident memory of its largest process from
``resource.getrusage``, and of the process and its workers together,
sampled every 0.1 s with psutil), sharded
(``--shards``, ``--workers``) or not.  ``configs/metropolis.xml`` at scale
1 makes about a million lots.  Issue 13's targets: 1M lots within 90 s and
6 GB on the project's 2-core machine, and linear growth: ten times the lots
at most eleven times the time (``growth`` = time ratio / lot ratio between
the smallest and the largest scale, at most 1.1).

Usage::

    python bench/scale.py [--scales 0.1,0.3,1] [--shards 16] [--workers 2] [--out bench/results/scale.json]
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _results import write  # bench/ is on sys.path when run as a script

ROOT = Path(__file__).resolve().parent.parent
CONFIG = ROOT / "configs" / "metropolis.xml"
TARGET_SECONDS = 90.0
TARGET_GB = 6.0


def run_one(scale: float, shards: int | None, workers: int, out: Path) -> dict:
    cmd = [sys.executable, "-m", "sengine", "run", str(CONFIG), "--scale", str(scale), "-o", str(out)]
    cmd += ["--format", "parquet", "--workers", str(workers), "-q"]
    if shards:
        cmd += ["--shards", str(shards)]
    import psutil

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    peak_tree = 0
    while proc.poll() is None:  # the whole tree's resident memory, sampled every 0.1 s
        try:
            root = psutil.Process(proc.pid)
            rss = sum(p.memory_info().rss for p in [root, *root.children(recursive=True)])
            peak_tree = max(peak_tree, rss)
        except psutil.Error:
            pass
        time.sleep(0.1)
    stderr = proc.stderr.read()
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"scale {scale}: {stderr.strip()[-2000:]}")
    stats = json.loads((out / "stats.json").read_text())
    # ru_maxrss of the children is the largest single process (the parent or one worker), in KiB
    return {
        "scale": scale,
        "shards": shards,
        "workers": workers,
        "seconds": round(wall, 2),
        "cpu_seconds": round(after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime, 2),
        "peak_rss_gb_largest_process": round(after.ru_maxrss / 1024**2, 3),
        "peak_rss_gb_all_processes_sampled": round(peak_tree / 1024**3, 3),
        "counts": stats["counts"],
        "lots": stats["counts"].get("lots", 0),
        "node_seconds": stats["seconds"],
        "files_mb": round(sum(f.stat().st_size for f in out.glob("*.parquet")) / 1e6, 1),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scales", default="0.1,0.3,1")
    ap.add_argument("--shards", type=int, default=16, help="0: unsharded")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "results" / "scale.json")
    args = ap.parse_args()
    results = []
    with tempfile.TemporaryDirectory(prefix="sengine-scale-") as tmp:
        for s in [float(v) for v in args.scales.split(",")]:
            r = run_one(s, args.shards or None, args.workers, Path(tmp) / f"s{s}")
            print(json.dumps({k: v for k, v in r.items() if k != "node_seconds"}), file=sys.stderr)
            results.append(r)
    lo, hi = results[0], results[-1]
    summary = {
        "target_seconds_1m": TARGET_SECONDS,
        "target_gb_1m": TARGET_GB,
        "growth": round((hi["seconds"] / lo["seconds"]) / max(hi["lots"] / max(lo["lots"], 1), 1e-9), 3)
        if len(results) > 1
        else None,
        "seconds_per_100k_lots": [round(r["seconds"] / max(r["lots"], 1) * 1e5, 2) for r in results],
    }
    write(args.out, "scale", {"runs": results, "summary": summary})


if __name__ == "__main__":
    main()

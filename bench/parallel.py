"""Benchmark: sengine.parallel.run_jobs on concurrent.futures vs the hand-written fork pool it replaced.

Two cases, each timed for both pools, interleaved (A B A B ...) so that a
busy moment of the shared machine hurts both alike:

* ``manhattan``: the Manhattan demo (configs/manhattan.xml) with
  ``workers=2``, in a fresh process per run: the executor's feature chunks
  and the exporter's files go through ``run_jobs``;
* ``overhead``: 50 calls of ``run_jobs`` on 8 jobs of 1 ms each (the cost
  of starting a pool and bringing the results back).

The hand-written pool is read from the commit before it was replaced
(``git show HASH:sengine/parallel.py``), so this runs in a git checkout.
Results go to ``bench/results/parallel.json``; ``ratio`` is the
hand-written pool's median time over the standard library's (above 1: the
standard library is faster).

Usage::

    python bench/parallel.py [--repeat 5]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
import types
from pathlib import Path

from _results import write

ROOT = Path(__file__).resolve().parent.parent
OLD_COMMIT = "abb08f830fbd43ef038c6940e27ab823ff14df0a"  # the last commit with the hand-written pool


def _old_parallel() -> types.ModuleType:
    source = subprocess.run(
        ["git", "show", f"{OLD_COMMIT}:sengine/parallel.py"], cwd=ROOT, check=True, capture_output=True, text=True
    ).stdout
    mod = types.ModuleType("old_parallel")
    exec(compile(source, "old_parallel.py", "exec"), mod.__dict__)
    return mod


def _use(pool: str) -> None:
    """Point every caller of run_jobs at ``pool`` ('futures' or 'handwritten')."""
    if pool == "futures":
        return
    import sengine.network
    import sengine.nodes.export.city
    import sengine.nodes.osm.stream

    old = _old_parallel().run_jobs
    for mod in (sengine.network, sengine.nodes.export.city, sengine.nodes.osm.stream):
        mod.run_jobs = old


def case_manhattan(pool: str) -> float:
    sys.path.insert(0, str(ROOT))
    import sengine

    net = sengine.load(ROOT / "configs" / "manhattan.xml")
    net.validate()  # loads the node library before the pool is chosen
    _use(pool)
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        net.run(out=Path(tmp) / "m", workers=2)
        return time.perf_counter() - t


def case_overhead(pool: str) -> float:
    sys.path.insert(0, str(ROOT))
    if pool == "futures":
        from sengine.parallel import run_jobs
    else:
        run_jobs = _old_parallel().run_jobs

    def job(i):
        def run():
            time.sleep(0.001)
            return i

        return run

    jobs = [job(i) for i in range(8)]
    t = time.perf_counter()
    for _ in range(50):
        assert run_jobs(jobs, 2) == list(range(8))
    return time.perf_counter() - t


def _child(case: str, pool: str) -> float:
    out = subprocess.run(
        [sys.executable, __file__, "--child", case, pool], check=True, capture_output=True, text=True, cwd=ROOT
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "results" / "parallel.json")
    ap.add_argument("--child", nargs=2, metavar=("CASE", "POOL"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        case, pool = args.child
        print(json.dumps(round({"manhattan": case_manhattan, "overhead": case_overhead}[case](pool), 4)))
        return
    results = {}
    for case in ("manhattan", "overhead"):
        times: dict[str, list[float]] = {"handwritten": [], "futures": []}
        for _ in range(args.repeat):
            for pool in times:
                times[pool].append(_child(case, pool))
        med = {pool: statistics.median(ts) for pool, ts in times.items()}
        results[case] = {
            "seconds": times,
            "median": {p: round(m, 4) for p, m in med.items()},
            "best": {p: round(min(ts), 4) for p, ts in times.items()},
            "ratio_handwritten_over_futures": round(med["handwritten"] / med["futures"], 3),
        }
        print(f"{case}: {results[case]['median']} ratio {results[case]['ratio_handwritten_over_futures']}")
    write(args.out, "parallel", {"repeat": args.repeat, "cases": results})


if __name__ == "__main__":
    main()

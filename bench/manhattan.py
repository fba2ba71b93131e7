"""Benchmark: the Manhattan-like demo (configs/manhattan.xml), the paper's experiment.

Runs, each in a fresh process so that its peak memory is its own:

* ``api``: ``sengine.load(config).run(seed, out)``: seconds per stage (the
  executor's own timings), total seconds, stage counts, peak resident memory;
* ``scale10``: the same maps and rules on a city of 10x the area (both
  sides times sqrt(10)), to see how each stage scales;
* ``cli``: ``sengine run CONFIG -o OUT`` as a subprocess, wall time from
  process start to the files written (imports and exports included), and its
  CPU seconds (all its processes, and its main process's own:
  the critical path on a machine whose other cores are free);
  ``--compare "PYTHON [PATH]"`` runs another checkout in turn
  (before / after ratios under the same load; issue 13's target: 2 s).  Time
  the command users run with ``--sengine``: the ``sengine`` of a venv made
  with ``pip install .`` loads compiled bytecode, while ``python -m sengine``
  from a checkout compiles the project's modules when bytecode is not kept
  (``PYTHONDONTWRITEBYTECODE``; the result says whether it was set and
  whether ``sengine/__pycache__`` existed).  ``start_to_files_median_seconds``
  is the median over ``--repeat`` fresh processes.

Every run uses ``--workers`` processes (default: every core, as the CLI).
Times are the best of ``--repeat`` runs (the cli case also gives the median).
Results go to ``bench/results/manhattan.json``.

Usage::

    python bench/manhattan.py [--repeat 3] [--seed 7] [--workers N] [--sengine PATH]
                              [--compare "PYTHON [PATH]"] [--cli-only] [--out bench/results/manhattan.json]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import shlex
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _results import environment

from sengine.parallel import available_cores

ROOT = Path(__file__).resolve().parent.parent
CONFIG = ROOT / "configs" / "manhattan.xml"
PAPER = {"majorRoads": 86, "blocks": 931, "lots": 7471}


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def case(name: str, seed: int, repeat: int, workers: int) -> dict:
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
            _, stats = net.run(seed=seed, out=Path(tmp) / "out", workers=workers)
            wall = time.perf_counter() - t
        if best is None or wall < best["wall_seconds"]:
            best = {
                "wall_seconds": round(wall, 4),
                "seconds": stats.get("seconds", {}),
                "counts": stats.get("counts", {}),
                "size_m": list(net.plan.size),
                "workers": workers,
            }
    best["peak_rss_mb"] = round(_peak_mb(), 1)
    return best


def _own_cpu_at_exit(pid: int) -> float | None:
    """CPU seconds of process ``pid`` itself (its children's left out), read when it has exited, before it is reaped.

    Linux only (``waitid(WNOWAIT)`` and ``/proc/PID/stat``, whose utime and
    stime a zombie keeps); ``None`` elsewhere.
    """
    try:
        os.waitid(os.P_PID, pid, os.WEXITED | os.WNOWAIT)
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime + stime, in ticks
    except (AttributeError, OSError, ValueError, IndexError):
        return None


def _median(values: list) -> float | None:
    known = [v for v in values if v is not None]
    return round(statistics.median(known), 3) if known else None


def cli(seed: int, repeat: int, workers: int, exe: list[str], compare: list[str] | None = None) -> dict:
    """``sengine run`` in a fresh process: wall seconds from process start to the files written.

    ``compare`` (``[PYTHON, PATH]``: another checkout's Python and the folder
    put first on ``PYTHONPATH``) is run in turn with ``exe``, so that both
    see the same load; ``speedup`` is its best time over ``exe``'s.
    """
    routes = {"sengine": (exe, None)}
    if compare:
        routes["compare"] = ([compare[0], "-m", "sengine"], compare[1] if len(compare) > 1 else None)
    times: dict[str, list[float]] = {k: [] for k in routes}
    cpu: dict[str, list[float]] = {k: [] for k in routes}
    main_cpu: dict[str, list[float | None]] = {k: [] for k in routes}
    files = []
    for _ in range(repeat):
        for route, (cmd, path) in routes.items():
            env = dict(os.environ)
            if path:
                env["PYTHONPATH"] = path
            with tempfile.TemporaryDirectory() as tmp:
                out = Path(tmp) / "out"
                args = [*cmd, "run", str(CONFIG), "-o", str(out), "--seed", str(seed)]
                t = time.perf_counter()
                proc = subprocess.Popen(
                    [*args, "--workers", str(workers), "--quiet"],
                    stderr=subprocess.PIPE,
                    text=True,
                    cwd=path or ROOT,
                    env=env,
                )
                own = _own_cpu_at_exit(proc.pid)
                _, status, usage = os.wait4(proc.pid, 0)
                wall = time.perf_counter() - t
                err = proc.stderr.read()
                if os.waitstatus_to_exitcode(status) != 0:
                    return {"error": err.strip().splitlines()[-1] if err.strip() else status}
                if route == "sengine":
                    files = sorted(p.name for p in out.iterdir())
            times[route].append(wall)
            cpu[route].append(usage.ru_utime + usage.ru_stime)
            main_cpu[route].append(own)
    result = {
        # the start-to-files time of issue 13 (target 2 s): the median of the fresh processes
        "start_to_files_median_seconds": round(statistics.median(times["sengine"]), 4),
        "wall_seconds": round(min(times["sengine"]), 4),
        "median_seconds": round(statistics.median(times["sengine"]), 4),
        "all_seconds": [round(t, 3) for t in times["sengine"]],
        "cpu_seconds": round(min(cpu["sengine"]), 3),
        # the main process's own CPU (its workers' left out): the run's critical path when the workers keep up
        "main_cpu_median_seconds": _median(main_cpu["sengine"]),
        "workers": workers,
        "command": " ".join(exe),
        "files": files,
        # with PYTHONDONTWRITEBYTECODE=1 and no __pycache__ a checkout compiles every module it imports each run
        "pythondontwritebytecode": os.environ.get("PYTHONDONTWRITEBYTECODE", ""),
        "pycache_present": any((ROOT / "sengine").rglob("__pycache__")),
    }
    if compare:
        result["compare"] = {
            "command": " ".join(compare),
            "wall_seconds": round(min(times["compare"]), 4),
            "median_seconds": round(statistics.median(times["compare"]), 4),
            "all_seconds": [round(t, 3) for t in times["compare"]],
            "cpu_seconds": round(min(cpu["compare"]), 3),
            "main_cpu_median_seconds": _median(main_cpu["compare"]),
        }
        result["speedup"] = round(min(times["compare"]) / min(times["sengine"]), 3)
        result["speedup_median"] = round(statistics.median(times["compare"]) / statistics.median(times["sengine"]), 3)
        result["cpu_speedup"] = round(min(cpu["compare"]) / min(cpu["sengine"]), 3)
    return result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "results" / "manhattan.json")
    ap.add_argument(
        "--workers", type=int, default=available_cores(), help="processes per run (default: every core, as the CLI)"
    )
    ap.add_argument(
        "--sengine",
        dest="exe",
        default=None,
        help="the sengine command to time in the cli case, e.g. the one of a venv made with "
        "`pip install .` (compiled bytecode, as users run it); default: python -m sengine",
    )
    ap.add_argument(
        "--compare",
        help='cli case: another checkout run in turn, "PYTHON [PATH]" (its Python, and the folder put on PYTHONPATH)',
    )
    ap.add_argument("--cli-only", action="store_true", help="only the cli case")
    ap.add_argument("--case", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.case:
        print(json.dumps(case(args.case, args.seed, args.repeat, args.workers)))
        return
    results = {}
    for name in () if args.cli_only else ("api", "scale10"):
        proc = subprocess.run(
            [
                sys.executable,
                __file__,
                "--case",
                name,
                "--seed",
                str(args.seed),
                "--repeat",
                str(args.repeat if name == "api" else 1),
                "--workers",
                str(args.workers),
            ],
            capture_output=True,
            text=True,
            cwd=ROOT,
        )
        if proc.returncode != 0:
            results[name] = {"error": proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else "failed"}
        else:
            results[name] = json.loads(proc.stdout.strip().splitlines()[-1])
        print(name, json.dumps(results[name]))
    exe = [args.exe] if args.exe else [sys.executable, "-m", "sengine"]
    results["cli"] = cli(args.seed, args.repeat, args.workers, exe, shlex.split(args.compare) if args.compare else None)
    print("cli", json.dumps(results["cli"]))
    api = results.get("api", {})
    if "counts" in api:
        results["paper"] = {
            k: {"paper": v, "sengine": api["counts"].get(k), "ratio": round(api["counts"].get(k, 0) / v, 3)}
            for k, v in PAPER.items()
        }
    if "counts" in api and "counts" in results.get("scale10", {}):
        results["scaling"] = {
            k: {
                "counts_ratio": round(results["scale10"]["counts"].get(k, 0) / max(v, 1), 2),
                "seconds_ratio": round(
                    results["scale10"]["seconds"].get(k, 0) / max(api["seconds"].get(k, 1e-9), 1e-9), 2
                ),
            }
            for k, v in api["counts"].items()
        }
    results["meta"] = {
        **environment(),
        "seed": args.seed,
        "repeat": args.repeat,
        "config": str(CONFIG.relative_to(ROOT)),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

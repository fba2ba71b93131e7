"""Where and how every benchmark writes its figures: one JSON file per benchmark."""

from __future__ import annotations

import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np
import shapely

RESULTS = Path(__file__).resolve().parent / "results"


def reference_seconds(repeat: int = 3) -> float:
    """Seconds of a fixed pure-Python loop on one core (best of ``repeat``): one sign of the machine's state.

    The shared 2-core VM this project is built on ran the same Manhattan
    run 1.5x slower at some hours than at others.  This figure catches a
    slower core; it does not catch a busy second core or slow file reads,
    so compare figures from different runs with care (the benchmarks also
    interleave or repeat their cases).
    """
    best = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        sum(range(10_000_000))
        best = min(best, time.perf_counter() - t)
    return round(best, 4)


def environment() -> dict:
    """The versions and machine the figures were measured with, and its speed at the time."""
    return {
        "python": platform.python_version(),
        "machine": platform.machine(),
        "cpus": os.cpu_count(),
        "numpy": np.__version__,
        "shapely": shapely.__version__,
        "geos": shapely.geos_version_string,
        "reference_seconds": reference_seconds(),
    }


def write(out: Path, benchmark: str, results) -> Path:
    """Write ``{"benchmark", "environment", "results"}`` to ``out`` and say so on stderr."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    doc = {"benchmark": benchmark, "environment": environment(), "results": results}
    out.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
    print(f"wrote {out}", file=sys.stderr)
    return out

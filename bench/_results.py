"""Where and how every benchmark writes its figures: one JSON file per benchmark."""

from __future__ import annotations

import json
import os
import platform
import sys
from pathlib import Path

import numpy as np
import shapely

RESULTS = Path(__file__).resolve().parent / "results"


def environment() -> dict:
    """The versions and machine the figures were measured with."""
    return {"python": platform.python_version(), "machine": platform.machine(), "cpus": os.cpu_count(),
            "numpy": np.__version__, "shapely": shapely.__version__, "geos": shapely.geos_version_string}


def write(out: Path, benchmark: str, results) -> Path:
    """Write ``{"benchmark", "environment", "results"}`` to ``out`` and say so on stderr."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    doc = {"benchmark": benchmark, "environment": environment(), "results": results}
    out.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
    print(f"wrote {out}", file=sys.stderr)
    return out

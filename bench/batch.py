"""Benchmark: ``sengine batch`` of 8 Paris-size variants on one worker, two workers and a Dask LocalCluster.

The variants are configs/paris.xml (4.5 km x 3 km, some 14,000 lots) on two
map sets (its own district, land-use and height maps, and the same flipped
left to right, made here with Pillow) times seeds 1-4, written with the
default formats (glb, geojson, osm, png).  Three cases, each the ``sengine
batch`` command in a fresh process, wall time from process start to exit,
interleaved (one, local, dask, one, local, dask ...) so that a busy moment
of the shared machine hurts all alike:

* ``one``: ``--workers 1`` (the variants in turn, in the batch's process);
* ``local``: ``--workers 2`` (a pool of two processes);
* ``dask``: ``--workers 2 --scheduler dask`` (a LocalCluster of two workers,
  started and closed within the timed command).

Every output file but ``stats.json`` (timings) is hashed and the three cases
compared.  CPU seconds (the command's and its processes', ``RUSAGE_CHILDREN``)
and the load average are recorded too: on a machine shared with other
work, two workers cannot be twice as fast as one.  Issue 13 asks: ``local`` at least 1.8x faster than ``one``;
``dask`` within 10 % of ``local`` and byte-identical.  Results go to
``bench/results/batch.json``.

Usage::

    python bench/batch.py [--repeat 2] [--sengine PATH]
"""

from __future__ import annotations

import argparse
import hashlib
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _results import write

ROOT = Path(__file__).resolve().parent.parent
CONFIG = ROOT / "configs" / "paris.xml"
CASES = {
    "one": ["--workers", "1"],
    "local": ["--workers", "2"],
    "dask": ["--workers", "2", "--scheduler", "dask"],
}


def make_maps(folder: Path) -> list[str]:
    """Two map sets, stems ``paris`` and ``flipx``; return the ``--maps`` arguments."""
    from PIL import Image

    args = []
    for kind in ("district", "landuse", "height"):
        sub = folder / kind
        sub.mkdir(parents=True)
        name = "districts" if kind == "district" else kind
        with Image.open(ROOT / "configs" / "maps" / f"paris_{name}.png") as im:
            im.save(sub / "paris.png")
            im.transpose(Image.Transpose.FLIP_LEFT_RIGHT).save(sub / "flipx.png")
        args.append(f"{kind}={sub}")
    return args


def digests(out: Path) -> dict[str, str]:
    return {
        str(p.relative_to(out)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(out.glob("*/*"))
        if p.is_file() and p.name != "stats.json" and not p.parent.name.startswith(".")
    }


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_case(exe: list[str], args: list[str], out: Path) -> tuple[float, float, dict[str, str], str]:
    """Wall seconds, CPU seconds of the command and its processes, output hashes, batch.csv."""
    cpu = _cpu()
    t = time.perf_counter()
    res = subprocess.run([*exe, "batch", str(CONFIG), "-o", str(out), "-q", *args], capture_output=True, text=True)
    wall = time.perf_counter() - t
    cpu = _cpu() - cpu
    if res.returncode != 0:
        raise SystemExit(f"sengine batch {' '.join(args)} failed:\n{res.stderr}")
    table = (out / "batch.csv").read_text()
    files = digests(out)
    shutil.rmtree(out)
    return wall, cpu, files, table


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--sengine", default=None, help="the sengine command to time (default: python -m sengine)")
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "results" / "batch.json")
    args = ap.parse_args()
    exe = [args.sengine] if args.sengine else [sys.executable, "-m", "sengine"]
    times: dict[str, list[float]] = {c: [] for c in CASES}
    cpus: dict[str, list[float]] = {c: [] for c in CASES}
    load = [os.getloadavg()[0]]
    files: dict[str, dict[str, str]] = {}
    lots: list[int] = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        maps = make_maps(tmp / "maps")
        common = ["--maps", *maps, "--seeds", "1-4"]
        for k in range(args.repeat):
            for case, extra in CASES.items():
                wall, cpu, got, table = run_case(exe, [*common, *extra], tmp / f"{case}{k}")
                times[case].append(round(wall, 3))
                cpus[case].append(round(cpu, 3))
                if case in files and files[case] != got:
                    raise SystemExit(f"{case}: two runs gave different files")
                files[case] = got
                if not lots:
                    rows = [line.split(",") for line in table.splitlines()]
                    col = rows[0].index("n_lots")
                    lots = [int(r[col]) for r in rows[1:]]
                print(f"{case}: {wall:.2f} s, {cpu:.2f} s CPU", file=sys.stderr)
    load.append(os.getloadavg()[0])
    med = {c: statistics.median(ts) for c, ts in times.items()}
    same = files["one"] == files["local"] == files["dask"]
    result = {
        "variants": len(lots),
        "lots_per_variant": lots,
        "files_per_run": len(files["one"]),
        "seconds": times,
        "median_seconds": med,
        "cpu_seconds": cpus,
        "load_average_1min_before_after": [round(x, 2) for x in load],
        "speedup_local_2_workers_over_1": round(med["one"] / med["local"], 3),
        "dask_over_local": round(med["dask"] / med["local"], 3),
        "byte_identical_one_local_dask": same,
        "targets": {"speedup_local_2_workers_over_1": ">= 1.8", "dask_over_local": "<= 1.10"},
    }
    print(
        f"8 variants: one {med['one']:.1f} s, local {med['local']:.1f} s "
        f"(x{result['speedup_local_2_workers_over_1']}), dask {med['dask']:.1f} s "
        f"({result['dask_over_local']} of local), identical: {same}",
        file=sys.stderr,
    )
    write(args.out, "batch", result)


if __name__ == "__main__":
    main()

"""Benchmark: the lot nodes (skylineEngine §5.5) on real and generated blocks.

Blocks come from

* ``liege``: Liège's street network (about 80,000 segments) through the
  nodes ``osm.read`` -> ``roads.clean`` -> ``blocks.circuits`` (as in the
  load-map network), about 3,450 blocks, many large and irregular;
* ``manhattan`` / ``paris``: ``configs/manhattan.xml`` and
  ``configs/paris.xml`` when they exist, run up to their ``blocks`` node.

Blocks are made once per case and cached (pickled ``Layer``) in the
temporary folder, keyed on the source file and on the code that makes them
(``sengine/*.py``, ``geom``, ``nodes/osm``, ``roads``, ``blocks``).  Each lot node (``lots.skeleton``, ``lots.recursive``,
``lots.paris``, ``lots.manhattan``, and ``lots.partition`` once it exists;
default parameters) then runs on them in a fresh process, so that
``peak_rss_mb`` (the process's peak resident memory, ``resource``) is its
own; times are the best of ``--repeat`` runs of ``node.run`` (method plus
lot attributes).  Besides seconds and lots per second each result has the
lot shapes a planner checks: ``thin_share`` (street-facing lots whose
oriented box is thinner than 1:10), ``thin_share_all`` (all lots),
``median_frontage`` and ``median_depth`` (m, street-facing lots) and the
count of each ``kind``.  Results go to ``bench/results/lots.json``.

``lots.skeleton?interior=split`` is the skeleton method with its interior
cut into inner lots under ``lot_area_max`` (instead of one inner lot per
block interior).

Usage::

    python bench/lots.py [--repeat 3] [--cases liege,manhattan,paris]
                         [--methods lots.recursive,...] [--rounds 1] [--out bench/results/lots.json]

With ``--rounds N`` every method runs N times, the methods alternated, and
each result carries its CPU time over ``lots.recursive``'s in the same round
(``cpu_ratio_to_recursive_rounds`` and their median): the issue's 1.5x target
is such a ratio, and this machine's speed drifts more between runs than the
methods differ.

To measure another revision, point ``SENGINE_BENCH_CODE`` at a copy of its
package (``baseline_code(ref)`` makes one from git).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import pickle
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import shapely
from _results import write  # bench/ is on sys.path when run as a script

ROOT = Path(__file__).resolve().parent.parent
CODE = Path(os.environ.get("SENGINE_BENCH_CODE", ROOT))  # the sengine measured (a baseline's copy, or this one)
sys.path.insert(0, str(CODE))
LIEGE = next(
    (
        p
        for p in (ROOT / "configs/data/liege_streets.osm.pbf", ROOT.parent / "shared/data/liege_streets.osm.pbf")
        if p.exists()
    ),
    ROOT / "configs/data/liege_streets.osm.pbf",
)
# a method, or a method with parameters: "lots.skeleton?interior=split"
METHODS = (
    "lots.skeleton",
    "lots.skeleton?interior=split",
    "lots.recursive",
    "lots.paris",
    "lots.partition",
    "lots.manhattan",
)


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _code_tag() -> str:
    """A digest of the measured package's sources that make blocks (so a code change re-makes them)."""
    h = hashlib.sha1()
    for sub in ("sengine/geom", "sengine/nodes/osm", "sengine/nodes/roads", "sengine/nodes/blocks"):
        for f in sorted((CODE / sub).rglob("*.py")):
            h.update(f.read_bytes())
    for f in sorted((CODE / "sengine").glob("*.py")):
        h.update(f.read_bytes())
    return h.hexdigest()[:12]


def _cache_path(case: str, source: Path) -> Path:
    st = source.stat()
    key = f"{source.resolve()}:{st.st_size}:{st.st_mtime_ns}:{_code_tag()}"
    tag = hashlib.sha1(key.encode()).hexdigest()[:12]
    return Path(tempfile.gettempdir()) / f"sengine_bench_lots_{case}_{tag}.pkl"


def liege_blocks(path: Path):
    """Blocks of the Liège extract through the load-map nodes."""
    from sengine import Context
    from sengine.registry import get

    ctx = Context(seed=1)
    roads = get("osm.read")("majorRoads", {"path": str(path), "extras": ""}, ctx).run()["roads"]
    roads = get("roads.clean")("clean", {}, ctx).run(roads=roads)["roads"]
    return get("blocks.circuits")("blocks", {"node": False}, ctx).run(roads=roads)["blocks"]


def config_blocks(path: Path):
    """The ``blocks`` layer of a configuration, running only the nodes it needs."""
    from sengine.xmlconfig import load_config

    net = load_config(path)
    need, todo = set(), ["blocks"]
    while todo:
        node = todo.pop()
        if node in need:
            continue
        need.add(node)
        todo += [c.src for c in net.connections if c.dst == node]
    net.specs = {k: v for k, v in net.specs.items() if k in need}
    net.connections = [c for c in net.connections if c.src in need and c.dst in need]
    return net.run()["blocks"]


def sources() -> dict[str, Path]:
    out = {"liege": LIEGE}
    for name in ("manhattan", "paris"):
        out[name] = ROOT / "configs" / f"{name}.xml"
    return out


def blocks_of(case: str):
    src = sources()[case]
    cache = _cache_path(case, src)
    if cache.exists():
        with cache.open("rb") as f:
            return pickle.load(f), 0.0
    t = time.perf_counter()
    blocks = liege_blocks(src) if case == "liege" else config_blocks(src)
    dt = time.perf_counter() - t
    with cache.open("wb") as f:
        pickle.dump(blocks, f)
    return blocks, dt


def run_method(case: str, method: str, repeat: int) -> dict:
    from sengine import Context
    from sengine.registry import get

    blocks, _ = blocks_of(case)
    name, _, query = method.partition("?")
    params = dict(kv.split("=", 1) for kv in query.split("&") if kv)
    best, best_cpu, out, node = float("inf"), float("inf"), None, None
    for _ in range(repeat):
        node = get(name)("lots", params, Context(seed=1))
        t, c = time.perf_counter(), time.process_time()
        result = node.run(blocks=blocks)
        out = result["lots"]
        best = min(best, time.perf_counter() - t)
        best_cpu = min(best_cpu, time.process_time() - c)
    g = out.geometry
    from sengine.geom.polygons import obb_frame

    _, _, length, width = obb_frame(g)
    thin = width < 0.1 * length
    street = out["kind"] != "inner" if "kind" in out else ~out["inner"]
    depth = out["depth"] if "depth" in out else np.full(len(out), np.nan)
    barea = shapely.area(blocks.geometry)
    larea = np.bincount(np.searchsorted(blocks.ids, out["block"]), weights=shapely.area(g), minlength=len(blocks))
    rel = np.abs(larea - barea) / np.maximum(barea, 1e-12)
    return {
        "case": case,
        "method": method,
        "blocks": int(len(blocks)),
        "lots": int(len(out)),
        "seconds": round(best, 3),
        "cpu_seconds": round(best_cpu, 3),  # this process's CPU time (GEOS threads included): steadier when busy
        "lots_per_s": round(len(out) / best),
        "peak_rss_mb": round(_peak_mb(), 1),
        "max_partition_error": float(rel.max()) if len(rel) else 0.0,
        "no_frontage": int(((out["frontage"] <= 0) & ~out["inner"]).sum()),
        "invalid": int((~shapely.is_valid(g)).sum()),
        "under_1m2": int((shapely.area(g) < 1.0).sum()),
        "thin_share": round(float(thin[street].mean()), 4) if street.any() else 0.0,
        "thin_share_all": round(float(thin.mean()), 4) if len(thin) else 0.0,
        "median_frontage": round(float(np.median(out["frontage"][street])), 2) if street.any() else None,
        "median_depth": round(float(np.nanmedian(depth[street])), 2) if street.any() else None,
        "kinds": {k: int((out["kind"] == k).sum()) for k in ("street", "corner", "inner")} if "kind" in out else None,
        "report": getattr(result, "report", None) or getattr(node, "report", None),
    }


def lot_shapes(lots) -> dict:
    """Thin shares, median frontage and depth of street-facing lots (see the module notes)."""
    g = lots.geometry
    k = len(g)
    if k == 0:
        return {"thin_share": 0.0, "thin_share_street": 0.0, "median_frontage": 0.0, "median_depth": 0.0}
    env = shapely.oriented_envelope(g)
    c = shapely.get_coordinates(shapely.get_exterior_ring(env))
    ok = shapely.get_num_coordinates(env) == 5
    sides = np.zeros((k, 2))
    xy = c.reshape(-1, 5, 2) if ok.all() else None
    if xy is not None:
        sides = np.stack([np.hypot(*(xy[:, 1] - xy[:, 0]).T), np.hypot(*(xy[:, 2] - xy[:, 1]).T)], axis=1)
    thin = sides.min(axis=1) < 0.1 * sides.max(axis=1)
    street = ~np.asarray(lots["inner"], bool) & (lots["frontage"] > 0)
    # depth: extent across the direction of the longest street edge
    ang = np.radians(np.nan_to_num(np.asarray(lots["front_angle"], float)))
    nrm = np.stack([-np.sin(ang), np.cos(ang)], axis=1)
    pts, pi = shapely.get_coordinates(g, return_index=True)
    q = np.einsum("ij,ij->i", pts, nrm[pi])
    start = np.r_[0, np.flatnonzero(pi[1:] != pi[:-1]) + 1]
    depth = np.zeros(k)
    depth[pi[start]] = np.maximum.reduceat(q, start) - np.minimum.reduceat(q, start)
    return {
        "thin_share": round(float(thin.mean()), 4),
        "thin_share_street": round(float(thin[street].mean()), 4) if street.any() else 0.0,
        "median_frontage": round(float(np.median(lots["frontage"][street])), 2) if street.any() else 0.0,
        "median_depth": round(float(np.median(depth[street])), 2) if street.any() else 0.0,
    }


def baseline_code(ref: str) -> Path:
    """A copy of the package at git revision ``ref`` (cached in the temporary folder)."""
    sha = subprocess.run(["git", "-C", str(ROOT), "rev-parse", ref], capture_output=True, text=True, check=True)
    dest = Path(tempfile.gettempdir()) / f"sengine_bench_code_{sha.stdout.strip()[:12]}"
    if not (dest / "sengine").exists():
        dest.mkdir(parents=True, exist_ok=True)
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", ref, "sengine"], capture_output=True, check=True)
        subprocess.run(["tar", "-x", "-C", str(dest)], input=archive.stdout, check=True)
    return dest


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--cases", default="liege,manhattan,paris")
    ap.add_argument("--out", type=Path, default=ROOT / "bench/results/lots.json")
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument(
        "--rounds",
        type=int,
        default=1,
        help="run every method this many times, alternated, and give each its CPU time over lots.recursive's in "
        "the same round (median over rounds): steadier than one run each while the machine's speed drifts",
    )
    ap.add_argument("--run", nargs=2, metavar=("CASE", "METHOD"), help=argparse.SUPPRESS)
    ap.add_argument("--prepare", metavar="CASE", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.prepare:
        blocks, dt = blocks_of(args.prepare)
        print(json.dumps({"case": args.prepare, "blocks": int(len(blocks)), "blocks_s": round(dt, 2)}))
        return 0
    if args.run:
        print(json.dumps(run_method(args.run[0], args.run[1], args.repeat)))
        return 0
    results = []
    for case in args.cases.split(","):
        src = sources().get(case)
        if src is None or not src.exists():
            print(f"skip {case}: {src} not found", file=sys.stderr)
            continue
        prep = subprocess.run([sys.executable, __file__, "--prepare", case], capture_output=True, text=True)
        if prep.returncode:
            print(f"skip {case}: {prep.stderr.strip().splitlines()[-1:]}", file=sys.stderr)
            continue
        print(prep.stdout.strip(), file=sys.stderr)
        from sengine.registry import names

        methods = [m for m in args.methods.split(",") if m.partition("?")[0] in names()]
        rounds = {m: [] for m in methods}
        for _ in range(max(args.rounds, 1)):
            for method in methods:
                proc = subprocess.run(
                    [sys.executable, __file__, "--run", case, method, "--repeat", str(args.repeat)],
                    capture_output=True,
                    text=True,
                    check=True,
                )
                res = json.loads(proc.stdout.strip().splitlines()[-1])
                print(json.dumps({k: v for k, v in res.items() if k != "report"}), file=sys.stderr)
                rounds[method].append(res)
        base = [r["cpu_seconds"] for r in rounds.get("lots.recursive", [])]
        for method in methods:
            res = min(rounds[method], key=lambda r: r["cpu_seconds"])
            res["cpu_seconds_rounds"] = [r["cpu_seconds"] for r in rounds[method]]
            if base:  # each round's CPU time over recursive's in that round
                ratios = [r["cpu_seconds"] / b for r, b in zip(rounds[method], base)]
                res["cpu_ratio_to_recursive_rounds"] = [round(x, 3) for x in ratios]
                res["cpu_ratio_to_recursive_median"] = round(float(np.median(ratios)), 3)
                print(f"{case} {method}: CPU / recursive {res['cpu_ratio_to_recursive_rounds']}", file=sys.stderr)
            results.append(res)
    write(args.out, "lots", results)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Benchmark: how real the lots and buildings look, measured the way a planner would.

For each case the whole network runs in memory (no files), then the final lots
and generated buildings are measured:

* lots: count, the share thinner than 1:10 (oriented box short side under a
  tenth of its long side), of all lots and of street-facing ones (frontage > 0),
  median area, frontage and depth (the oriented box's side more nearly
  perpendicular to the lot's main frontage), the largest lot;
* generated buildings (``source`` is not ``osm``): count, the share of each
  building's perimeter that is a party wall (within 5 cm of another building's
  outline), as a median and as the share of buildings that have one; the median
  distance from a building to its block's edge (the street wall); the median
  wing depth (the diameter of the largest circle inside the footprint: a
  perimeter block's wing is as deep as that); the share of each block's land
  that generated buildings cover (median over blocks with one);
* the generated buildings by Statbel's types of houses (:func:`house_types`:
  detached, semi-detached, terraced, flats), and each type's footprints in
  Statbel's classes of ground area beside Wallonia's houses (:func:`ground_areas`);
* where the lots carry ``blocks.grain``'s ``fabric``, all of the above per fabric;
* the ``planning`` node's city figures: FAR, coverage, GFA and residents.

Real-world figures to compare with are in the README's realism section.

Usage::

    python bench/realism.py [--cases manhattan,helsinki,monaco,liege] [--out bench/results/realism.json]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import shapely
from _osm import osm_network  # bench/ is on sys.path when run as a script
from _results import RESULTS, write

import sengine
from sengine.geom.polygons import obb_frame

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "configs" / "data"
LIEGE = ROOT.parent / "shared" / "data" / "liege_streets.osm.pbf"
PARTY_TOL = 0.05  # m: an outline this close to a neighbour's counts as a shared wall


def _osm_network(path: Path, sets: list[str]):
    """The network ``sengine osm FILE`` runs, with every lot built on (``buildings.keep=generated``)."""
    return osm_network(path, ["buildings.keep=generated", *sets])


CASES = {
    "manhattan": lambda sets: sengine.load(ROOT / "configs" / "manhattan.xml", sets=sets),
    "helsinki": lambda sets: _osm_network(DATA / "helsinki_centre.osm.pbf", sets),
    "monaco": lambda sets: _osm_network(DATA / "monaco.osm.pbf", sets),
    "liege": lambda sets: _osm_network(LIEGE, sets),
    "paris": lambda sets: sengine.load(ROOT / "configs" / "paris.xml", sets=sets),
}


def lot_figures(lots) -> dict:
    """Shape figures of a lots layer (see the module docstring)."""
    geoms = lots.geometry
    center, axis, length, width = obb_frame(geoms)
    aspect = np.where(length > 0, width / np.maximum(length, 1e-12), 0.0)
    thin = aspect < 0.1
    frontage = np.asarray(lots["frontage"], float) if "frontage" in lots else np.zeros(len(lots))
    street = frontage > 0
    if "depth" in lots:
        depth = np.asarray(lots["depth"], float)
    else:
        ang = np.radians(np.asarray(lots["front_angle"], float)) if "front_angle" in lots else np.zeros(len(lots))
        front = np.c_[np.cos(ang), np.sin(ang)]
        along = np.abs(np.einsum("ij,ij->i", front, axis))  # 1: the long side runs along the street
        depth = np.where(along >= np.sqrt(0.5), width, length)
    area = shapely.area(geoms)
    sel = street & np.isfinite(depth)
    return {
        "lots": int(len(lots)),
        "thin_share": round(float(thin.mean()), 4) if len(lots) else 0.0,
        "thin_share_street_facing": round(float(thin[street].mean()), 4) if street.any() else 0.0,
        "street_facing": int(street.sum()),
        "median_area_m2": round(float(np.median(area)), 1) if len(lots) else 0.0,
        "max_area_m2": round(float(area.max()), 1) if len(lots) else 0.0,
        "median_frontage_m": round(float(np.median(frontage[street])), 2) if street.any() else 0.0,
        "median_depth_m": round(float(np.median(depth[sel])), 2) if sel.any() else 0.0,
        "below_1m2": int((area < 1.0).sum()),
    }


def _generated(buildings) -> np.ndarray:
    """Which buildings the engine made (``source`` is not ``osm``)."""
    if "source" not in buildings:
        return np.ones(len(buildings), bool)
    return np.asarray(buildings["source"]).astype(str) != "osm"


def building_figures(buildings, blocks) -> dict:
    """Party walls and street walls of the generated buildings."""
    gen = _generated(buildings)
    geoms = buildings.geometry[gen]
    n = len(geoms)
    if n == 0:
        return {"buildings": 0}
    tree = shapely.STRtree(geoms)
    a, b = tree.query(geoms, predicate="dwithin", distance=PARTY_TOL)
    keep = a != b
    a, b = a[keep], b[keep]
    shared = shapely.length(shapely.intersection(shapely.boundary(geoms[a]), shapely.buffer(geoms[b], PARTY_TOL)))
    perimeter = shapely.length(geoms)
    party = np.minimum(np.bincount(a, weights=shared, minlength=n) / np.maximum(perimeter, 1e-12), 1.0)
    out = {
        "buildings": int(n),
        "party_wall_share_median": round(float(np.median(party)), 4),
        "with_party_wall": round(float((party > 0.01).mean()), 4),
    }
    if blocks is not None and len(blocks):
        btree = shapely.STRtree(blocks.geometry)
        nearest = btree.query_nearest(geoms, return_distance=False)
        ai, bi = nearest
        d = np.full(n, np.nan)
        d[ai] = shapely.distance(geoms[ai], shapely.boundary(blocks.geometry[bi]))
        out["median_distance_to_block_edge_m"] = round(float(np.nanmedian(d)), 2)
        out["on_block_edge_share"] = round(float((d < 0.05).mean()), 4)
        cover = np.bincount(bi, weights=shapely.area(geoms[ai]), minlength=len(blocks))
        has = cover > 0
        share = cover[has] / shapely.area(blocks.geometry[has])
        out["block_coverage_median"] = round(float(np.median(np.minimum(share, 1.0))), 4)
    radius = shapely.length(shapely.maximum_inscribed_circle(geoms, tolerance=0.05))
    out["wing_depth_median_m"] = round(float(np.median(2.0 * radius)), 2)
    return out


def _house_kinds(buildings) -> tuple[np.ndarray, dict]:
    """The generated buildings and, for each Statbel type, which of them are of it (see :func:`house_types`)."""
    gen = _generated(buildings)
    geoms = buildings.geometry[gen]
    n = len(geoms)
    a, b = shapely.STRtree(geoms).query(geoms, predicate="dwithin", distance=PARTY_TOL)
    keep = a != b
    a, b = a[keep], b[keep]
    shared = shapely.length(shapely.intersection(shapely.boundary(geoms[a]), shapely.buffer(geoms[b], PARTY_TOL)))
    neighbours = np.bincount(a[shared > 1.0], minlength=n)
    flats = np.asarray(buildings["floors"])[gen] >= 3
    return geoms, {
        "open": ~flats & (neighbours == 0),
        "semi": ~flats & (neighbours == 1),
        "closed": ~flats & (neighbours >= 2),
        "flats": flats,
    }


def house_types(buildings) -> dict:
    """Shares of the generated buildings as Statbel types its building stock.

    ``flats``: three storeys or more (a block of flats); the others by the
    neighbours they share a wall with (over 1 m of outline within
    :data:`PARTY_TOL`): none ``open`` (detached), one ``semi`` (semi-detached
    or end of terrace), two or more ``closed`` (terraced).
    """
    if not _generated(buildings).any():
        return {}
    _, kinds = _house_kinds(buildings)
    return {k: round(float(v.mean()), 4) for k, v in kinds.items()}


#: Statbel's classes of built ground area (m2) and Wallonia's houses in them on 1 January 2018
#: (Statbel, building stock by type and ground area: terraced, semi-detached, detached incl. farms).
GROUND_CLASSES = (45.0, 65.0, 105.0)
WALLONIA_2018 = {
    "closed": (30_166, 102_501, 190_335, 95_589),
    "semi": (10_193, 48_602, 142_577, 166_919),
    "open": (1_638, 6_263, 97_232, 400_878),
}


def ground_areas(buildings) -> dict:
    """Each house type's footprints: median (m2) and shares in Statbel's classes beside Wallonia's (2018)."""
    if not _generated(buildings).any():
        return {}
    geoms, kinds = _house_kinds(buildings)
    area = shapely.area(geoms)
    out = {}
    for k, real in WALLONIA_2018.items():
        a = area[kinds[k]]
        counts = np.bincount(np.searchsorted(GROUND_CLASSES, a, side="right"), minlength=4)
        out[k] = {
            "median_m2": round(float(np.median(a)), 1) if len(a) else 0.0,
            "classes": [round(float(c / max(len(a), 1)), 4) for c in counts],
            "wallonia_2018": [round(c / sum(real), 4) for c in real],
        }
    return out


def by_fabric(lots, buildings, blocks) -> dict:
    """:func:`lot_figures`, :func:`building_figures` and :func:`house_types` per fabric (``blocks.grain``)."""
    if "fabric" not in lots:
        return {}
    fabric = np.asarray(lots["fabric"]).astype(str)
    ids = np.asarray(lots.ids, np.int64)
    order = np.argsort(ids, kind="stable")
    lot = np.asarray(buildings["lot"], np.int64) if len(buildings) else np.zeros(0, np.int64)
    at = order[np.minimum(np.searchsorted(ids, lot, sorter=order), len(ids) - 1)] if len(ids) else lot
    bf = np.where((len(ids) > 0) & (ids[at] == lot), fabric[at], "") if len(ids) else np.full(len(lot), "")
    out = {}
    for f in np.unique(fabric):
        b = buildings.take(np.flatnonzero(bf == f))
        gfa = float(np.sum(b["gfa"])) if "gfa" in b and len(b) else 0.0
        out[str(f)] = {
            "lots": lot_figures(lots.take(np.flatnonzero(fabric == f))),
            "buildings": building_figures(b, blocks),
            "types": house_types(b),
            "ground_areas": ground_areas(b),
            "median_floors": float(np.median(b["floors"])) if len(b) else 0.0,
            "gfa_per_building_m2": round(gfa / max(len(b), 1), 1),
        }
    return out


def measure(case: str, sets: list[str]) -> dict:
    net = CASES[case](sets)
    t = time.perf_counter()
    layers, stats = net.run(workers=1)
    seconds = time.perf_counter() - t
    lots = layers["planning"]["lots"] if "planning" in layers else layers["lots"]["lots"]
    buildings = layers["buildings"]["buildings"]
    blocks = next((layers[k]["blocks"] for k in ("landuse", "blocks") if k in layers), None)
    city = (stats.get("report", {}).get("planning") or {}).get("city", {})
    return {
        "seconds": round(seconds, 3),
        "lots": lot_figures(lots),
        "buildings": building_figures(buildings, blocks),
        "types": house_types(buildings),
        "ground_areas": ground_areas(buildings),
        "by_fabric": by_fabric(lots, buildings, blocks),
        "planning": city,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", default="manhattan,helsinki,monaco")
    ap.add_argument("--set", dest="sets", action="append", default=[], help="NODE.PARAM=VALUE for every case")
    ap.add_argument("--out", type=Path, default=RESULTS / "realism.json")
    args = ap.parse_args(argv)
    figures = {}
    for case in args.cases.split(","):
        figures[case] = measure(case, args.sets)
        print(case, figures[case], file=sys.stderr)
    write(args.out, "realism", {"sets": args.sets, "cases": figures})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

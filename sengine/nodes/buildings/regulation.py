"""Regulation check: the city against Prague's Metropolitan Plan rules (paper 003 §3.2).

Four rules a planner checks a proposal against, each a column on the
features it concerns (``ok`` and ``violation``: the codes of the rules
broken, comma-separated) and a count in the node's report:

* **block coverage** ``ZB`` (003 §3.2.1, Table 3.1): the share of a block's
  area its buildings cover may not exceed a limit set by the block's
  structure type and size: small blocks (at most 2,000 m2) ``ZB_M``, large
  ones (over 12,000 m2) ``ZB_V``, mid-size ones interpolated,
  ``ZB_S = ZB_V + (ZB_S1 - ZB_V) (12,000 - P) / 10,000`` (code ``coverage``);
* **street width** (003 §3.2.2): the public space of a street is at least
  24 m for city avenues, 18 m for important streets, 12 m for local and 8 m
  for access streets (code ``street-width``);
* **height class** (003 §3.2.3): the regulated height (the top of the last
  full storey) within the class's range, I 0-6 m ... VIII over 40 m (codes
  ``height-class-over`` / ``height-class-under``); above it either a roof
  of at most 45 degrees and 7.5 m or a recessed storey of at most 3.5 m
  (code ``roof``);
* **storey height** (003 §3.2.4): at least 2.6 m (code ``storey-height``).

The report's ``violations`` counts every feature breaking a rule and
``summary`` says it in one line: ``sengine run --check`` exits with status
1 when a node reports violations.

References
----------
.. [1] V. Potočková, "Procedural generation of future urban construction
   according to rules", bachelor's thesis, Czech Technical University in
   Prague, 2024, §3.2 (paper 003), after the Prague Metropolitan Plan and
   Prague building regulations.
"""

from __future__ import annotations

import logging

import numpy as np
import shapely

from sengine import Layer, NodeResult, Param, Port, SENode, register
from sengine.geom.polygons import shared_areas
from sengine.registry import declare_rule

from ..maps import rules_of
from .rules import class_bounds

__all__ = ["ZB_TABLE", "STRUCTURES", "STREET_MINIMA", "zb_limit", "street_minimum", "BuildingsCheck"]

log = logging.getLogger(__name__)

#: Table 3.1 of 003: structure type -> (ZB_M small, ZB_S1 mid-size base, ZB_V large, ZB_N unknown block).
ZB_TABLE = {
    "grown": (0.95, 0.85, 0.60, 0.65),
    "block": (0.85, 0.75, 0.50, 0.65),
    "hybrid": (0.95, 0.85, 0.50, 0.65),
    "heterogeneous": (0.65, 0.55, 0.35, 0.40),
    "village": (0.30, 0.30, 0.20, 0.25),
    "garden-city": (0.35, 0.35, 0.20, 0.25),
}
STRUCTURES = tuple(ZB_TABLE)
SMALL, LARGE = 2000.0, 12000.0  #: m2: block size classes of 003 §3.2.1

#: Street class of 003 §3.2.2 -> least public-space width (m).
STREET_MINIMA = {"avenue": 24.0, "important": 18.0, "local": 12.0, "access": 8.0}
#: Road ``class`` values (OSM ``highway``, the synthetic networks' classes) -> street class.
STREET_CLASS = {
    **dict.fromkeys(("motorway", "trunk", "primary", "motorway_link", "trunk_link", "primary_link"), "avenue"),
    **dict.fromkeys(("secondary", "tertiary", "secondary_link", "tertiary_link", "major", "boundary"), "important"),
    **dict.fromkeys(("unclassified", "residential", "road", "busway", "minor"), "local"),
}
ROOF_SLOPE_MAX = 45.0  #: deg
ROOF_HEIGHT_MAX = 7.5  #: m: a sloped roof or attic above the regulated height
RECESSED_MAX = 3.5  #: m: a recessed storey above the regulated height
STOREY_MIN = 2.6  #: m

declare_rule(
    "district",
    {
        "structure": Param(
            "str", None, choices=STRUCTURES, doc="structure type for the coverage limit ZB (003 Table 3.1)"
        )
    },
)


def zb_limit(structure, area) -> np.ndarray:
    """The coverage limit ZB (share) of blocks of a structure type and an area (m2), 003 §3.2.1.

    Small blocks (at most 2,000 m2) take ``ZB_M``, large ones (over 12,000 m2)
    ``ZB_V``, mid-size ones ``ZB_V + (ZB_S1 - ZB_V) (12,000 - P) / 10,000``.
    (``ZB_N``, for land that is not a block, is kept in :data:`ZB_TABLE`; every
    block here is one.)
    """
    structure = np.asarray(structure).astype(str)
    area = np.asarray(area, np.float64)
    out = np.full(len(area), np.nan)
    for name, (m, s1, v, _unknown) in ZB_TABLE.items():
        sel = structure == name
        mid = v + (s1 - v) * (LARGE - area) / 10000.0
        out[sel] = np.where(area[sel] <= SMALL, m, np.where(area[sel] <= LARGE, mid[sel], v))
    return out


def street_minimum(classes) -> np.ndarray:
    """Least public-space width (m) of streets of the given road classes (003 §3.2.2); access streets 8 m."""
    names = np.asarray(classes).astype(str)
    return np.array([STREET_MINIMA[STREET_CLASS.get(c, "access")] for c in names], np.float64)


def _codes(flags: dict[str, np.ndarray], n: int) -> np.ndarray:
    out = np.full(n, "", dtype=object)
    for code, bad in flags.items():
        out[bad] = np.where(out[bad] == "", code, out[bad] + "," + code)
    return out.astype(str) if n else np.empty(0, "<U1")


@register
class BuildingsCheck(SENode):
    """Check buildings, blocks and streets against Prague's rules (003 §3.2).

    Coverage ZB, street widths, height classes and roof envelope, storey
    height; ``ok`` / ``violation`` columns and a report.
    """

    name = "buildings.check"
    inputs = {
        "buildings": Port("buildings", "buildings with height, floors (and roof_height, roof, district)"),
        "blocks": Port("blocks", "blocks: their coverage against ZB", required=False),
        "roads": Port("roads", "street centre lines with class and width", required=False),
        "district_rules": Port(
            "rules", "the <district> rules: height-class and structure per district", required=False
        ),
    }
    outputs = {
        "buildings": Port("buildings", "the buildings with ok, violation, height_class"),
        "blocks": Port("blocks", "the blocks with coverage, zb, ok, violation (empty without blocks)"),
        "roads": Port("roads", "the roads with min_width, ok, violation (empty without roads)"),
    }
    params = {
        "structure": Param(
            "str", "block", choices=STRUCTURES, doc="structure type of blocks whose district sets none (003 Table 3.1)"
        ),
        "height_class": Param(
            "str",
            "",
            choices=("", "I", "II", "III", "IV", "V", "VI", "VII", "VIII"),
            doc="height class of buildings whose district sets none; empty: no height check",
        ),
    }

    @staticmethod
    def _district_values(rules, attr: str, district, default: str) -> np.ndarray:
        out = np.full(len(district), default, dtype=object)
        for i, rule in enumerate(rules):
            value = rule.get(attr)
            if value is not None:
                out[np.asarray(district) == i] = value
        return out.astype(str)

    def run(
        self,
        *,
        buildings: Layer,
        blocks: Layer | None = None,
        roads: Layer | None = None,
        district_rules: Layer | None = None,
    ) -> NodeResult:
        rules = rules_of(district_rules)
        n = len(buildings)
        report: dict = {}
        # buildings: height class, roof envelope, storey height
        district = np.asarray(buildings.get("district", np.full(n, -1)), np.int64)
        hclass = self._district_values(rules, "height-class", district, self.p.height_class)
        if "height_class" in buildings:
            own = np.asarray(buildings["height_class"]).astype(str)
            hclass = np.where((own != "") & (own != "None"), own, hclass)
        height = np.asarray(buildings.get("height", np.zeros(n)), np.float64)
        roof_h = np.nan_to_num(np.asarray(buildings.get("roof_height", np.zeros(n)), np.float64))
        floors = np.asarray(buildings.get("floors", np.ones(n)), np.float64)
        roof = np.asarray(buildings.get("roof", np.full(n, "flat"))).astype(str)
        regulated = height - roof_h
        lo, hi = class_bounds(hclass)
        checked = hclass != ""
        _, _, _, width = _obb_width(buildings.geometry)
        with np.errstate(divide="ignore", invalid="ignore"):
            slope = np.degrees(np.arctan2(roof_h, np.maximum(width / 2.0, 1e-9)))
            storey = np.where(floors > 0, regulated / floors, np.inf)
        sloped = np.isin(roof, ("gable", "hip", "pyramid", "shed"))
        slope = np.where(roof == "shed", np.degrees(np.arctan2(roof_h, np.maximum(width, 1e-9))), slope)
        flags = {
            "height-class-over": checked & (regulated > hi + 1e-6),
            "height-class-under": checked & (regulated < lo - 1e-6),
            "roof": (sloped & ((roof_h > ROOF_HEIGHT_MAX + 1e-6) | (slope > ROOF_SLOPE_MAX + 1e-6)))
            | ((roof == "stepped") & (roof_h > RECESSED_MAX + 1e-6)),
            "storey-height": storey < STOREY_MIN - 1e-6,
        }
        codes = _codes(flags, n)
        out_b = buildings.with_columns(ok=codes == "", violation=codes, height_class=hclass)
        for k, v in flags.items():
            report[f"buildings_{k.replace('-', '_')}"] = int(v.sum())
        report["buildings_checked"] = n
        bad = int((codes != "").sum())
        parts = [f"{bad:,} of {n:,} buildings"] if bad else []
        # blocks: coverage against ZB
        out_k = Layer.empty(meta=buildings.meta)
        if blocks is not None:
            m = len(blocks)
            area = shapely.area(blocks.geometry) if m else np.zeros(0)
            _, bi, shared = shared_areas(buildings.geometry, blocks.geometry) if m and n else ([], np.zeros(0, int), [])
            covered = np.bincount(np.asarray(bi, np.int64), weights=np.asarray(shared, float), minlength=m)
            with np.errstate(divide="ignore", invalid="ignore"):
                coverage = np.where(area > 0, covered / area, 0.0)
            structure = self._district_values(
                rules, "structure", np.asarray(blocks.get("district", np.full(m, -1)), np.int64), self.p.structure
            )
            zb = zb_limit(structure, area)
            over = coverage > zb + 1e-9
            codes_k = _codes({"coverage": over}, m)
            out_k = blocks.with_columns(coverage=coverage, zb=zb, structure=structure, ok=~over, violation=codes_k)
            report["blocks_checked"] = m
            report["blocks_over_zb"] = int(over.sum())
            if over.any():
                parts.append(f"{int(over.sum()):,} of {m:,} blocks over ZB")
            bad += int(over.sum())
        out_r = Layer.empty(meta=buildings.meta)
        if roads is not None:
            k = len(roads)
            minimum = street_minimum(roads.get("class", np.full(k, "")))
            width = np.asarray(roads.get("width", np.full(k, np.nan)), np.float64)
            narrow = np.isfinite(width) & (width < minimum - 1e-9)
            codes_r = _codes({"street-width": narrow}, k)
            out_r = roads.with_columns(min_width=minimum, ok=~narrow, violation=codes_r)
            report["streets_checked"] = k
            report["streets_too_narrow"] = int(narrow.sum())
            if narrow.any():
                parts.append(f"{int(narrow.sum()):,} of {k:,} streets too narrow")
            bad += int(narrow.sum())
        report["violations"] = bad
        report["summary"] = ("regulation: " + "; ".join(parts)) if parts else "regulation: no violation"
        log.info("%s: %s", self.where, report["summary"])
        return NodeResult({"buildings": out_b, "blocks": out_k, "roads": out_r}, report)


def _obb_width(geoms):
    from sengine.geom.polygons import obb_frame

    return obb_frame(geoms)

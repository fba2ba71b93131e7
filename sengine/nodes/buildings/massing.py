"""Massing: buildings from planning rules on every lot (paper 000's "Massing" module).

For each lot, as CityEngine's rule file does with a lot's attributes:

1. **Siting** (:mod:`.edges`, :mod:`.siting`): the lot's front, side and
   rear lines and its building area behind the setbacks; attached buildings
   stand on their side lot lines and share party walls with their
   neighbours, detached ones keep the side setback (000: 4 m).
2. **Typology** (:mod:`.typology`): one of paper 004's 8 building types (or
   the plain box), drawn by land use, or as a rule names them.
3. **Floors**, by the lot's level of control (000 §5.2.1):

   * **0, indicator**: the FAR-to-building algorithm of 000 §5.3 (:mod:`.far`)
     builds the floor area ``lot area x FAR`` in credible proportions;
   * **1, parameters**: the rule's ``floors``, else the height map at the lot
     (002 §5.2) with a seeded variation, capped by the zone's FAR (the
     footprint shrinks by the same algorithm where even that is too much)
     and by its height class (003 §3.2.3);
   * **2, custom**: the footprints and heights of the ``custom`` input for
     the lots it names (a planner's own design), taken as they are.

4. **Roofs** (004 Fig. 7) by land use and typology, with their height above
   the top storey and the direction of the street.

The buildings layer has one feature per building part (a podium and its
towers are separate parts) with ``height`` (m, ground to the highest point),
``floors``, ``roof``, ``roof_height`` (m; ``height`` minus it is the top of
the last full storey), ``roof_direction`` (deg counter-clockwise from east,
in [0, 180): the direction of the lot's main street front; gable and hip
ridges and a shed roof's eaves run along it, a shed slopes across it),
``typology``, ``part`` (``main``, ``podium`` or ``custom``),
``use``, ``loc``, ``gfa`` (m2), ``far`` (of the lot, all its parts),
``lot`` and ``district``.  Part ids are ``lot id x 16 + k``: the same
whatever the batch.

References
----------
.. [1] J. Viinikka, "Procedural modelling as an urban planning tool",
   master's thesis, Aalto University, Espoo, 2014, §5.2-5.3 (paper 000).
.. [2] M. Zhang, J. Wu, Y. Liu, J. Zhang and G. Li, "GIS based procedural
   modeling in 3D urban design", ISPRS International Journal of
   Geo-Information 11(10):531, 2022. doi:10.3390/ijgi11100531, §3.3.2-3.4 (paper 004).
.. [3] V. Potočková, "Procedural generation of future urban construction
   according to rules", bachelor's thesis, Czech Technical University in
   Prague, 2024, §3.2 (paper 003).
.. [4] skylineEngine: an urban procedural modelling tool (University of
   Girona), paper 002, §5.2 (height map) and §5.6 (buildings).
"""

from __future__ import annotations

import logging

import numpy as np
import shapely

from sengine import Layer, NodeResult, Param, Port, SENode, register
from sengine.errors import InputDataError
from sengine.geom.polygons import obb_frame
from sengine.geom.sorting import unique_int
from sengine.random import uniform

from ..maps import image_of, rules_of
from .edges import lot_edges
from .extrude import HEIGHT_PARAMS, mapped_heights
from .far import TOLERANCE, depth_for, far_to_building
from .pairs import semi_pairs, side_neighbours
from .rules import class_bounds, per_lot
from .siting import band, building_area, side_lines
from .typology import (
    BY_USE,
    LOW,
    MAIN,
    ROOF_KINDS,
    SITING_BY_USE,
    TYPOLOGIES,
    USES,
    Site,
    choose,
    draw_parts,
    parse_choices,
    roof_heights,
    roof_kinds,
)

__all__ = ["PARTS", "BuildingsMassing", "BuildingsFar"]

log = logging.getLogger(__name__)

#: Building parts per lot at most: a part's id is ``lot id x PARTS + k``.
PARTS = 16
_TOWERLIKE = (TYPOLOGIES.index("tower"), TYPOLOGIES.index("towers"), TYPOLOGIES.index("hall"))
_FREE = (TYPOLOGIES.index("tower"), TYPOLOGIES.index("house"))  # stand free whatever the siting


class _Massing(SENode):
    inputs = {
        "lots": Port(
            "lots", "lots to build on (with 'block' and 'district'; optional rule columns; 'open' lots stay unbuilt)"
        ),
        "blocks": Port("blocks", "the blocks of the lots: their edges are the street fronts", required=False),
        "zones": Port(
            "polygons",
            "land-use zones with a 'use' column (e.g. osm.read's landuse): the lots' land use",
            required=False,
        ),
        "custom": Port(
            "buildings",
            "level of control 2: footprints with a 'lot' column and 'height' or 'floors', taken as they are",
            required=False,
        ),
        "height_map": Port("raster", "the height map (level of control 1 without 'floors')", required=False),
        "landuse_map": Port("raster", "the land-use map: each lot's <landuse> rule by its colour", required=False),
        "district_rules": Port("rules", "the <district> rules: use, far, setbacks ... per district", required=False),
        "landuse_rules": Port("rules", "the <landuse> rules: use, far, setbacks ... per land use", required=False),
    }
    outputs = {
        "buildings": Port(
            "buildings",
            "building parts with height, floors, roof, roof_height, roof_direction, typology, use, gfa, far, lot",
        )
    }
    maps_features = True
    default_loc = 1

    @classmethod
    def _params(cls, loc: int, far: float) -> dict:
        return {
            "loc": Param(
                "int", loc, min=0, max=1, unit="1", doc="level of control: 0 FAR indicator, 1 parameters / height map"
            ),
            "far": Param(
                "float", far, min=0.0, max=100.0, unit="1", doc="floor area ratio: target (loc 0) or cap (0: none)"
            ),
            "use": Param("str", "residential", choices=USES, doc="land use of lots no rule or map gives one"),
            "typology": Param(
                "str", "auto", doc="building types and shares ('I:3,L,tower'); auto: by land use (004 Fig. 5)"
            ),
            "siting": Param(
                "str",
                "auto",
                choices=("auto", "attached", "detached"),
                doc="attached: party walls on the side lot lines; detached: side setbacks; auto: by land use",
            ),
            "setback_front": Param(
                "float",
                0.0,
                min=0.0,
                max=100.0,
                unit="m",
                doc="build-to line: the street wall's distance from the street",
            ),
            "setback_side": Param(
                "float", 4.0, min=0.0, max=100.0, unit="m", doc="side setback of detached buildings (000: 4 m)"
            ),
            "setback_rear": Param("float", 4.0, min=0.0, max=100.0, unit="m", doc="setback from the rear lot line"),
            "depth": Param("float", 14.0, min=4.0, max=200.0, unit="m", doc="building depth (loc 1)"),
            "tower": Param("float", 24.0, min=6.0, max=200.0, unit="m", doc="side of a tower's square (loc 1)"),
            "house": Param(
                "float", 10.0, min=4.0, max=100.0, unit="m", doc="greatest width of a detached house along the street"
            ),
            "semi_detached": Param(
                "float",
                0.7,
                min=0.0,
                max=1.0,
                unit="1",
                doc="chance two neighbouring detached houses are built as a semi-detached pair (Wallonia 2018: "
                "28 % of buildings semi-detached, 38 % detached)",
            ),
            "semi_width": Param(
                "float",
                0.7,
                min=0.1,
                max=1.0,
                unit="1",
                doc="width of each house of a semi-detached pair, as a share of a detached house's (Statbel 2018,"
                " Wallonia: median ground area about 99 m2 semi-detached, 138 m2 detached)",
            ),
            "podium_floors": Param("int", 2, min=1, max=20, unit="1", doc="floors of podiums and linking corridors"),
            "podium_depth": Param("float", 20.0, min=4.0, max=200.0, unit="m", doc="depth of podiums from the street"),
            "floors": Param(
                "int", 0, min=0, max=300, unit="1", doc="floors of every building (loc 1); 0: the height map"
            ),
            "height": HEIGHT_PARAMS["height"],
            "variation": HEIGHT_PARAMS["variation"],
            "height_class": Param(
                "str",
                "",
                choices=("", "I", "II", "III", "IV", "V", "VI", "VII", "VIII"),
                doc="Prague height class capping the regulated height (003); empty: none",
            ),
            "floor_height": HEIGHT_PARAMS["floor_height"],
            "roof": Param("str", "auto", doc="roof kinds and shares ('gable:2,hip'); auto: by land use (004 Fig. 7)"),
            "min_area": Param("float", 20.0, min=0.0, unit="m2", doc="building parts smaller than this are not built"),
            "courtyards": Param("bool", False, doc="also build on inner lots (courtyards with no street frontage)"),
        }

    # -- the steps ---------------------------------------------------------------------
    def _rules(self, lots: Layer, zones: Layer | None, plan: dict) -> dict:
        p = self.p
        defaults = {
            "use": p.use,
            "far": p.far if p.far > 0 else None,
            "loc": p.loc,
            "floors": p.floors if p.floors > 0 else None,
            "height_class": p.height_class or None,
            "typology": p.typology,
            "siting": p.siting,
            "setback_front": p.setback_front,
            "setback_side": p.setback_side,
            "setback_rear": p.setback_rear,
            "depth": p.depth,
            "house": p.house,
            "roof": p.roof,
        }
        return per_lot(
            lots,
            defaults,
            self.where,
            zones,
            districts=rules_of(plan["district_rules"]),
            landuses=rules_of(plan["landuse_rules"]),
            landuse_map=image_of(plan["landuse_map"]),
        )

    def _typologies(self, r: dict, ids) -> np.ndarray:
        use = r["use"].astype(str)
        texts = np.where(np.isin(r["typology"].astype(str), ("auto", "None", "")), "", r["typology"].astype(str))
        key = np.char.add(np.char.add(texts.astype(str), "|"), use)
        uniq, inv = np.unique(key, return_inverse=True)
        tables = []
        for k in uniq:
            text, _, u = k.partition("|")
            if text:
                try:
                    tables.append(parse_choices(text, TYPOLOGIES, what="typology"))
                except ValueError as exc:
                    from sengine.errors import ParameterError

                    raise ParameterError(str(exc), where=self.where) from None
            else:
                tables.append(BY_USE.get(u, BY_USE["residential"]))
        u = uniform(self.context.seed, f"{self.id}/typology", ids)
        return choose(tables, inv, u, TYPOLOGIES)

    def _map_floors(self, lots: Layer, ids, height_map: Layer | None) -> np.ndarray:
        """Floors the height map (or ``height``) asks for at each lot, with the seeded variation."""
        p = self.p
        c = shapely.point_on_surface(lots.geometry) if len(lots) else np.empty(0, object)
        raw, _, _ = mapped_heights(
            height_map, c, ids, seed=self.context.seed, key=f"{self.id}/height", height=p.height, variation=p.variation
        )
        return np.maximum(1, np.rint(raw / p.floor_height)).astype(np.int64)

    def run(
        self,
        *,
        lots: Layer,
        blocks: Layer | None = None,
        zones: Layer | None = None,
        custom: Layer | None = None,
        height_map: Layer | None = None,
        landuse_map: Layer | None = None,
        district_rules: Layer | None = None,
        landuse_rules: Layer | None = None,
    ) -> NodeResult:
        p = self.p
        fh = p.floor_height
        n_all = len(lots)
        open_court = np.zeros(n_all, bool)
        if not p.courtyards and "inner" in lots.attrs:
            open_court = np.asarray(lots["inner"], bool)
        if not p.courtyards and "kind" in lots.attrs:  # no street frontage at all: a yard, not a building plot
            open_court = open_court | (np.asarray(lots["kind"]) == "inner")
        # open land (buildings.context: fields along a country road) is not built on
        open_land = np.asarray(lots["open"], bool) if "open" in lots.attrs else np.zeros(n_all, bool)
        custom_lot = np.zeros(n_all, bool)
        if custom is not None and len(custom):
            if "lot" not in custom:
                raise InputDataError("custom buildings carry no 'lot' column", where=self.where)
            custom_lot = np.isin(lots.ids, np.asarray(custom["lot"], np.int64))
        work = np.flatnonzero(~open_court & ~open_land & ~custom_lot)
        L = lots.take(work)
        n = len(L)
        ids = L.ids
        plan = {
            "landuse_map": landuse_map,
            "district_rules": district_rules,
            "landuse_rules": landuse_rules,
        }
        r = self._rules(L, zones, plan)
        use = r["use"].astype(str)
        loc = np.asarray([int(v) for v in r["loc"]], np.int64)
        siting = r["siting"].astype(str)
        siting = np.where(siting == "auto", np.array([SITING_BY_USE.get(u, "attached") for u in use]), siting)
        fs = r["setback_front"].astype(np.float64)
        ss = np.where(siting == "attached", 0.0, r["setback_side"].astype(np.float64))
        rs = r["setback_rear"].astype(np.float64)
        house = r["house"].astype(np.float64)  # each detached house's width (m)
        owner = None
        if blocks is not None and "block" in L:
            owner = blocks.rows_of(np.asarray(L["block"], np.int64))
        edges = lot_edges(
            L.geometry,
            blocks=None if owner is None else blocks.geometry,
            owner=owner,
            box=lots.meta.get("bbox"),
            fronts=None if owner is None else blocks.get("street_front"),
        )
        area = building_area(L.geometry, edges, fs, ss, rs)
        typ = self._typologies(r, ids)
        # a tower or a house stands free: its building area keeps the side setback whatever the siting
        side = r["setback_side"].astype(np.float64)
        free = np.isin(typ, _FREE) & (ss < side)
        if free.any():
            alone = building_area(L.geometry[free], _sub_edges(edges, free), fs[free], side[free], rs[free])
            # on a plot too narrow for that (what the side setbacks leave is under half a house wide) it
            # is a terraced or semi-detached house: a slab on the side lot lines, sharing party walls
            rows = np.flatnonzero(free)
            narrow = obb_frame(alone)[3] < 0.5 * p.house
            typ[rows[narrow]] = TYPOLOGIES.index("I")
            ss[rows[~narrow]] = side[rows[~narrow]]
            area[rows[~narrow]] = alone[~narrow]
            report_attached = int(narrow.sum())
        else:
            report_attached = 0
        # semi-detached: neighbouring houses paired off, each standing on the line it shares with its partner
        party = np.full(n, "", dtype="<U5")
        pair = np.full(n, -1, np.int64)  # the lot id of each pair's left house: a pair is built as one
        cand = (typ == TYPOLOGIES.index("house")) & (ss >= side) & ~edges.corner  # a corner house faces two streets
        if p.semi_detached > 0 and cand.sum() > 1:
            left, right = side_neighbours(L.geometry, edges)
            u = uniform(self.context.seed, f"{self.id}/semi", ids)
            party = semi_pairs(left, right, cand, u, p.semi_detached)
            first = np.flatnonzero(party == "right")
            pair[first] = pair[right[first]] = ids[first]
            for hand in ("left", "right"):
                on = party == hand
                if on.any():
                    sub = _sub_edges(edges, on)
                    paired = building_area(L.geometry[on], sub, fs[on], side[on], rs[on], party=party[on])
                    # the house runs from the shared line, at most a house long (not centred on the front)
                    house[on] *= p.semi_width  # each house of a pair narrower than a detached one
                    area[on] = band(paired, side_lines(sub, int(on.sum()), hand), house[on])
        site = Site(area, edges, fs, ss, rs, podium_depth=p.podium_depth, house=house)
        lot_area = shapely.area(L.geometry) if n else np.zeros(0)
        far = np.array([np.nan if v is None else float(v) for v in r["far"]], np.float64)
        _, hmax = class_bounds(np.where(r["height_class"] == None, "", r["height_class"]).astype(str))  # noqa: E711
        class_floors = np.where(np.isfinite(hmax), np.maximum(1, np.floor(hmax / fh + 1e-9)), 10_000).astype(np.int64)
        towerlike = np.isin(typ, _TOWERLIKE)
        target = np.where(loc == 0, np.nan_to_num(far) * lot_area, np.nan)
        depth = np.where(
            towerlike, p.tower, np.where(loc == 0, depth_for(np.nan_to_num(target)), r["depth"].astype(np.float64))
        )
        parts = _Drawn(site, typ, p.podium_floors, p.podium_depth, p.min_area)
        # every lot drawn once at its first depth; a typology the building area cannot hold
        # falls back to a slab, then to the whole area, but a house that does not fit leaves a garden
        rows = np.arange(n)
        main, low = parts.draw(rows, depth, np.ones(n))
        room = ~shapely.is_empty(area) & (typ != TYPOLOGIES.index("house"))
        for fallback in ("I", "box"):
            bad = np.flatnonzero((main <= 0) & room)
            if not len(bad):
                break
            typ[bad] = TYPOLOGIES.index(fallback)
            depth[bad] = np.where(
                loc[bad] == 0, depth_for(np.nan_to_num(target[bad])), r["depth"].astype(np.float64)[bad]
            )
            main[bad], low[bad] = parts.draw(bad, depth[bad], np.ones(len(bad)))
        build = main > 0
        floors = np.zeros(n, np.int64)
        report = {
            "far_iterated": 0,
            "far_converged": 0,
            "far_capped_by_height": 0,
            "attached_narrow": report_attached,
            "semi_detached": int((party != "").sum()),
        }
        # level of control 1: explicit floors, else the height map; the FAR and the height class cap them
        one = build & (loc == 1)
        explicit = np.array([v is not None for v in r["floors"]], bool)
        if one.any():
            f = self._map_floors(L, ids, height_map)
            f[explicit] = np.array([int(v) for v in r["floors"][explicit]], np.int64)
            f = np.minimum(f, class_floors)
            floors[one] = f[one]
            cap = far * lot_area
            over = one & np.isfinite(cap) & (f * main + low > cap * (1.0 + TOLERANCE))
            if over.any():
                capped = np.flatnonzero(over)
                res = self._far_loop(parts, cap[capped], depth[capped], f[capped], capped, (main[capped], low[capped]))
                floors[capped] = res["floors"]
                build[capped] &= res["build"]
                report["far_iterated"] += len(capped)
                report["far_converged"] += int(res["converged"].sum())
        # level of control 0: the FAR-to-building algorithm (000 §5.3.3)
        zero = build & (loc == 0)
        if zero.any():
            rows0 = np.flatnonzero(zero)
            res = self._far_loop(
                parts, target[rows0], depth[rows0], class_floors[rows0], rows0, (main[rows0], low[rows0])
            )
            floors[rows0] = res["floors"]
            build[rows0] &= res["build"]
            report["far_iterated"] += len(rows0)
            report["far_converged"] += int(res["converged"].sum())
            report["far_capped_by_height"] += int(res["short"].sum())
        g, row, role = parts.final(build)
        out = self._layer(L, g, row, role, typ, use, loc, floors, r, edges, lot_area, siting, pair)
        if custom_lot.any():
            out = Layer.concat([out, self._custom(lots, custom, custom_lot)], renumber=False).with_meta(**lots.meta)
        report = {
            "buildings": len(out),
            "lots": n_all,
            "lots_built": distinct(out["lot"]),
            "courtyards": int(open_court.sum()),
            "open_land": int((open_land & ~open_court).sum()),
            "custom": int(custom_lot.sum()),
            "not_built": n - distinct(row),
            **report,
            "typologies": {str(t): int(c) for t, c in zip(*np.unique(out["typology"].astype(str), return_counts=True))}
            if len(out)
            else {},
        }
        log.info("%s: %d building parts on %d of %d lots", self.where, len(out), report["lots_built"], n_all)
        return NodeResult({"buildings": out}, report)

    def _far_loop(self, parts, target, depth, max_floors, rows, first):
        def sub(k, d, frac):
            return parts.draw(rows[k], d, frac)

        return far_to_building(target, sub, depth=depth, max_floors=max_floors, first=first)

    def _layer(self, L, g, row, role, typ, use, loc, floors, r, edges, lot_area, siting, pair) -> Layer:
        p = self.p
        fh = p.floor_height
        m = len(g)
        lot_ids = L.ids[row]
        first = np.r_[True, row[1:] != row[:-1]] if m else np.zeros(0, bool)
        rank = np.arange(m) - np.maximum.accumulate(np.where(first, np.arange(m), 0)) if m else np.zeros(0, np.int64)
        keep = rank < PARTS
        g, row, role, rank, lot_ids = g[keep], row[keep], role[keep], rank[keep], lot_ids[keep]
        m = len(g)
        f = np.where(role == MAIN, floors[row], np.minimum(p.podium_floors, floors[row]))
        f = np.maximum(f, 1)
        typology = np.array(TYPOLOGIES, dtype=object)[typ[row]] if m else np.empty(0, object)
        # a terrace is built as one: the attached houses of a block of rows (blocks.grain) share their roof
        # kind, drawn by block; so do the two houses of a semi-detached pair, drawn by its left lot
        group = np.full(m, -1, np.int64)
        if m and "fabric" in L and "block" in L:
            terrace = (np.asarray(L["fabric"]).astype(str)[row] == "rows") & (siting[row] == "attached")
            group[terrace] = np.asarray(L["block"], np.int64)[row][terrace]
        roof = self._roofs(use[row], typology, role, lot_ids * PARTS + rank, r["roof"][row], group, pair[row])
        roof_h = roof_heights(roof, g, fh) if m else np.zeros(0)
        area = shapely.area(g) if m else np.zeros(0)
        gfa = area * f
        lot_gfa = np.bincount(row, weights=gfa, minlength=len(L))
        with np.errstate(divide="ignore", invalid="ignore"):
            lot_far = np.where(lot_area > 0, lot_gfa / lot_area, 0.0)
        district = np.asarray(L.get("district", np.full(len(L), -1)), np.int64)
        return Layer(
            g,
            (lot_ids * PARTS + rank).astype(np.int64),
            lot_ids.astype(np.int64),
            {
                "height": f * fh + roof_h,
                "floors": f.astype(np.int64),
                "roof": roof.astype(str) if m else np.empty(0, "<U1"),
                "roof_height": roof_h,
                "roof_direction": edges.front_angle[row] if m else np.empty(0),
                "typology": typology.astype(str) if m else np.empty(0, "<U1"),
                "part": np.where(role == MAIN, "main", "podium").astype(str) if m else np.empty(0, "<U1"),
                "use": use[row].astype(str) if m else np.empty(0, "<U1"),
                "siting": siting[row].astype(str) if m else np.empty(0, "<U1"),
                "loc": loc[row],
                "height_class": np.where(r["height_class"] == None, "", r["height_class"]).astype(str)[row]  # noqa: E711
                if m
                else np.empty(0, "<U1"),
                "gfa": gfa,
                "far": lot_far[row],
                "lot": lot_ids.astype(np.int64),
                "district": district[row],
            },
            dict(L.meta),
        )

    def _roofs(self, use, typology, role, ids, rule_roof, terrace, pair) -> np.ndarray:
        """Roof kind of each part: drawn per part, per block for ``terrace`` (block id or -1), per ``pair`` (-1: none)."""
        out = roof_kinds(use, typology, role, self.context.seed, f"{self.id}/roof", ids)
        for key, group in (("terrace-roof", terrace), ("pair-roof", pair)):
            t = np.flatnonzero(group >= 0)
            if len(t):
                out[t] = roof_kinds(use[t], typology[t], role[t], self.context.seed, f"{self.id}/{key}", group[t])
        texts = np.asarray(rule_roof).astype(str)
        given = ~np.isin(texts, ("auto", "None", "")) & (np.asarray(role) == MAIN)
        if given.any():
            uniq, inv = np.unique(texts[given], return_inverse=True)
            tables = []
            for t in uniq:
                try:
                    tables.append(parse_choices(t, ROOF_KINDS, what="roof kind"))
                except ValueError as exc:
                    from sengine.errors import ParameterError

                    raise ParameterError(str(exc), where=self.where) from None
            u = uniform(self.context.seed, f"{self.id}/roof-rule", np.asarray(ids)[given])
            out[given] = np.array(ROOF_KINDS, dtype=object)[choose(tables, inv, u, ROOF_KINDS)]
        return out

    def _custom(self, lots: Layer, custom: Layer, on: np.ndarray) -> Layer:
        """Level of control 2: the planner's own footprints, on the lots they name."""
        fh = self.p.floor_height
        lot = np.asarray(custom["lot"], np.int64)
        keep = np.isin(lot, lots.ids[on])
        c = custom.take(np.flatnonzero(keep))
        lot = lot[keep]
        m = len(c)
        if "height" in c:
            height = np.asarray(c["height"], np.float64)
            floors = np.asarray(c.get("floors", np.maximum(1, np.floor(height / fh + 1e-9))), np.int64)
        elif "floors" in c:
            floors = np.asarray(c["floors"], np.int64)
            height = floors * fh
        else:
            raise InputDataError("custom buildings carry neither 'height' nor 'floors'", where=self.where)
        rank = np.zeros(m, np.int64)
        if m:
            o = np.argsort(lot, kind="stable")
            first = np.r_[True, lot[o][1:] != lot[o][:-1]]
            rank[o] = np.arange(m) - np.maximum.accumulate(np.where(first, np.arange(m), 0))
        rows = lots.rows_of(lot)
        lot_area = shapely.area(lots.geometry[rows]) if m else np.zeros(0)
        gfa = shapely.area(c.geometry) * floors if m else np.zeros(0)
        lot_gfa = np.bincount(rows, weights=gfa, minlength=len(lots))[rows] if m else np.zeros(0)
        district = (
            np.asarray(lots.get("district", np.full(len(lots), -1)), np.int64)[rows] if m else np.zeros(0, np.int64)
        )
        return Layer(
            c.geometry,
            lot * PARTS + (PARTS - 1 - rank),
            lot.copy(),
            {
                "height": height,
                "floors": floors,
                "roof": np.asarray(c.get("roof", np.full(m, "flat"))).astype(str),
                "roof_height": np.asarray(c.get("roof_height", np.zeros(m)), np.float64),
                "roof_direction": np.asarray(c.get("roof_direction", np.full(m, np.nan)), np.float64),
                "typology": np.full(m, "custom"),
                "part": np.full(m, "custom"),
                "use": np.asarray(c.get("use", np.full(m, self.p.use))).astype(str),
                "siting": np.full(m, "custom"),
                "loc": np.full(m, 2, np.int64),
                "height_class": np.full(m, ""),
                "gfa": gfa,
                "far": np.where(lot_area > 0, lot_gfa / np.where(lot_area > 0, lot_area, 1.0), 0.0),
                "lot": lot.copy(),
                "district": district,
            },
            dict(lots.meta),
        )


class _Drawn:
    """The parts of every lot's building as last drawn (the FAR loop redraws some lots)."""

    def __init__(self, site, typ, low_floors, podium_depth, min_part):
        self.site, self.typ, self.low_floors = site, typ, low_floors
        self.podium_depth, self.min_part = podium_depth, min_part
        self.calls: list = []
        self.latest = np.full(len(typ), -1, np.int64)

    def draw(self, rows, depth, frac):
        """Draw lots ``rows`` (increasing); the area (m2) of their main storey and their fixed floor area (m2)."""
        rows = np.asarray(rows, np.int64)
        g, row, role = draw_parts(
            self.site, rows, self.typ[rows], depth, frac, podium_depth=self.podium_depth, min_part=self.min_part
        )
        self.latest[rows] = len(self.calls)
        self.calls.append((g, row, role))
        a = shapely.area(g) if len(g) else np.zeros(0)
        pos = np.searchsorted(rows, row)
        main = np.bincount(pos, weights=a * (role == MAIN), minlength=len(rows))
        low = np.bincount(pos, weights=a * (role == LOW), minlength=len(rows)) * self.low_floors
        return main, low

    def final(self, build):
        """The parts of the lots to ``build``, as last drawn, by lot (low parts first)."""
        keep = [
            (g[m], row[m], role[m])
            for k, (g, row, role) in enumerate(self.calls)
            for m in [(self.latest[row] == k) & build[row]]
        ]
        if not keep:
            return np.empty(0, object), np.zeros(0, np.int64), np.zeros(0, np.int8)
        g = np.concatenate([k[0] for k in keep])
        row = np.concatenate([k[1] for k in keep])
        role = np.concatenate([k[2] for k in keep])
        o = np.lexsort((role, row))
        return g[o], row[o], role[o]


def distinct(values) -> int:
    """How many different integers ``values`` holds (:func:`sengine.geom.sorting.unique_int`)."""
    return len(unique_int(np.asarray(values)))


def _sub_edges(edges, mask):
    """The edges of the lots selected by ``mask``, renumbered."""
    from .edges import LotEdges

    rows = np.flatnonzero(mask)
    new = np.full(len(mask), -1, np.int64)
    new[rows] = np.arange(len(rows))
    s = mask[edges.lot]
    return LotEdges(
        edges.p0[s],
        edges.p1[s],
        new[edges.lot[s]],
        edges.kind[s],
        edges.inward[s],
        edges.axis[rows],
        edges.has_front[rows],
        edges.corner[rows],
        edges.street[rows],
        edges.facing[rows],
    )


@register
class BuildingsMassing(_Massing):
    """Buildings from planning rules: setbacks and party walls, typologies by land use, floors from the map capped by FAR.

    Each lot's building area lies behind its front, side and rear setbacks
    (attached buildings stand on the side lot lines); a typology of paper
    004 (I, L, U, O, tower, towers with podium, hall with podium, linked,
    box) is drawn by land use; floors come from the height map (level of
    control 1), capped by the zone's FAR and height class, or from the FAR
    itself on lots at level 0 (000's FAR-to-building); lots named in the
    ``custom`` input keep the planner's footprints (level 2).
    """

    name = "buildings.massing"
    params = _Massing._params(1, 0.0)


@register
class BuildingsFar(_Massing):
    """FAR-to-building (paper 000 §5.3): each lot gets the floor area of its FAR in credible proportions.

    Target floor area = lot area x FAR (none under 80 m2); building depth 8 m
    at 100 m2 to 25 m at 2,500 m2; floors = ceil(target / footprint); the
    depth (never under 10 m) and then the length shrink until the floor area
    is within 5 % of the target.  The same siting, typologies, roofs and
    levels of control as ``buildings.massing``, with level 0 by default.
    """

    name = "buildings.far"
    params = _Massing._params(0, 2.0)

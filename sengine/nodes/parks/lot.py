"""Parks at lot level (``parks.lot``): skylineEngine §4, Ulmer et al. §3.2 lot zones.

The smallest parks of skylineEngine's Fig. 3 take "the space equivalent to
a single building": chosen lots are kept free of buildings and become
parks (a square, a pocket park, a playground).  The node sits after the
lots and before the buildings, so the lots it takes are never built on; the
others go on to the buildings node.  Lots are chosen

* ``every``: every Nth lot id;
* ``random``: each lot with probability ``share`` (its own seeded draw);
* ``area``: lots in a seeded random order until ``share`` of the lots' area;
* ``inner``: the lots without a street edge (``street_edges == 0``: Paris
  courtyard lots, landlocked rear lots), which no building can be reached on;
* ``ids``: the lot ids a rule names.

``use`` restricts the choice to lots of districts whose ``<district use=...>``
is that land use (e.g. parks only in residential districts).  A lot
park's id comes from its lot (:mod:`.ids`); the parks stream is handed on
in id order.

References
----------
§4 of [1]_; lot zones in §3.2 of [2]_.

.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
.. [2] A. Ulmer, J. Halatsch, A. Kunze, P. Müller and L. Van Gool, "Procedural design
   of urban open spaces", Proceedings of the 25th eCAADe Conference, Frankfurt am
   Main, pp. 351-358, 2007 (paper 001 in shared/papers).
"""

from __future__ import annotations

import logging

import numpy as np
import shapely

from sengine import Layer, NodeResult, Param, Port, SENode, register
from sengine.errors import ParameterError
from sengine.random import uniform

from ..roads.districts import _rules
from .ids import join_parks, park_ids
from .level import CountsItsLevel

__all__ = ["LOT_MODES", "choose_park_lots", "ParksLot"]

log = logging.getLogger(__name__)

LOT_MODES = ("none", "every", "random", "area", "inner", "ids")


def choose_park_lots(
    geoms, ids, *, mode: str, every: int = 20, share: float = 0.05, u=None, street_edges=None, named=(), allowed=None
) -> np.ndarray:
    """Which lots become parks.

    Parameters
    ----------
    geoms : array_like of shapely.Polygon
        The lots (m).
    ids : array_like of int
        Their stable ids.
    mode : str
        One of :data:`LOT_MODES` (see the module notes).
    every : int
        Period of ``every``.
    share : float
        Probability (``random``) or share of the lots' area (``area``).
    u : array of float, optional
        One uniform draw in [0, 1) per lot, keyed by its id (``random``, ``area``).
    street_edges : array of int, optional
        Street edges of each lot (``inner``).
    named : iterable of int
        Lot ids (``ids``).
    allowed : array of bool, optional
        Lots that may become parks at all (``use``).

    Returns
    -------
    numpy.ndarray of bool
    """
    ids = np.asarray(ids, np.int64)
    n = len(ids)
    if mode == "none" or n == 0:
        return np.zeros(n, bool)
    ok = np.ones(n, bool) if allowed is None else np.asarray(allowed, bool)
    if mode == "every":
        pick = ids % max(int(every), 1) == 0
    elif mode == "random":
        pick = np.asarray(u) < share
    elif mode == "area":
        area = np.where(ok, shapely.area(np.asarray(geoms, dtype=object)), 0.0)
        order = np.lexsort((ids, np.asarray(u)))
        before = np.cumsum(area[order]) - area[order]  # area chosen before this lot
        pick = np.zeros(n, bool)
        pick[order] = (before < share * area.sum()) & (area[order] > 0)
    elif mode == "inner":
        pick = np.asarray(street_edges) == 0 if street_edges is not None else np.zeros(n, bool)
    elif mode == "ids":
        pick = np.isin(ids, np.asarray(list(named), np.int64))
    else:  # pragma: no cover - guarded by the parameter's choices
        raise ValueError(f"mode {mode!r} is not one of {', '.join(LOT_MODES)}")
    return pick & ok


@register
class ParksLot(CountsItsLevel, SENode):
    """Lot-level parks: chosen lots stay free of buildings and become parks (paper 002 §4)."""

    name = "parks.lot"
    level = "lot"
    shard_streams = ("parks",)
    inputs = {
        "lots": Port("lots", "lots to choose from"),
        "parks": Port("parks", "parks made upstream, passed through", required=False),
        "district_rules": Port("rules", "the <district> rules (their use attribute, for 'use')", required=False),
    }
    outputs = {
        "parks": Port("parks", "upstream parks plus the new lot-level parks (level 'lot')"),
        "lots": Port("lots", "the lots that did not become parks: the buildings' sites"),
    }
    params = {
        "mode": Param("str", "none", choices=LOT_MODES, doc="how lots are chosen (see parks.lot's notes)"),
        "every": Param("int", 20, min=1, max=1_000_000, unit="1", doc="every Nth lot id becomes a park"),
        "share": Param("float", 0.05, min=0.0, max=1.0, unit="1", doc="probability (random) or area share (area)"),
        "ids": Param("str", "", doc="lot ids for mode ids, comma-separated"),
        "use": Param("str", "", doc="only lots of districts with this <district use=...> (empty: any)"),
        "min_area": Param("float", 0.0, min=0.0, unit="m2", doc="smaller lots never become parks"),
    }

    def shard_refusal(self, connected):
        if self.p.mode == "area":
            return "mode 'area' takes a share of the whole city's lot area (use every, random, inner or ids)"
        return None

    def run(self, *, lots: Layer, parks: Layer | None = None, district_rules: Layer | None = None):
        if self.p.mode == "none":
            out = parks if parks is not None else Layer.empty(meta=dict(lots.meta), level=np.dtype("<U8"))
            return NodeResult({"parks": out, "lots": lots}, {"lot_parks": 0})
        try:
            named = [int(t) for t in str(self.p.ids).replace(",", " ").split()]
        except ValueError:
            raise ParameterError(
                f"ids {self.p.ids!r} is not a list of lot ids", where=f"{self.where} param 'ids'"
            ) from None
        area = shapely.area(lots.geometry) if len(lots) else np.zeros(0)
        allowed = area >= self.p.min_area
        if self.p.use:
            uses = [str(r.get("use") or "") for r in _rules(district_rules, "district")]
            good = np.array([u == self.p.use for u in uses] + [False], bool)
            d = np.asarray(lots["district"], np.int64) if "district" in lots else np.full(len(lots), -1)
            allowed &= good[np.where((d >= 0) & (d < len(uses)), d, len(uses))]
        pick = choose_park_lots(
            lots.geometry,
            lots.ids,
            mode=self.p.mode,
            every=self.p.every,
            share=self.p.share,
            u=uniform(self.context.seed, f"{self.id}/lot", lots.ids),
            street_edges=lots.get("street_edges"),
            named=named,
            allowed=allowed,
        )
        chosen = lots.take(pick)
        col = lambda k: np.asarray(chosen[k], np.int64) if k in chosen else np.full(len(chosen), -1, np.int64)  # noqa: E731
        new = Layer.from_geoms(
            chosen.geometry,
            ids=park_ids(chosen.ids, "lot", where=self.where),
            parent=chosen.ids,
            meta=dict(lots.meta),
            level=np.full(len(chosen), "lot"),
            district=col("district"),
            area=area[pick],
            lot=chosen.ids.astype(np.int64),
            block=col("block"),
        )
        out = join_parks(parks, new, where=self.where)
        report = {"lot_parks": int(pick.sum()), "park_area_m2": round(float(area[pick].sum()), 1)}
        log.info("%s: %d of %d lots become parks", self.where, int(pick.sum()), len(lots))
        return NodeResult({"parks": out, "lots": lots.take(~pick)}, report)

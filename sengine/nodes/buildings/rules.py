"""Planning rules of the buildings: per district, per land use and per lot.

A planner states the rules of a zone once (``<district far="2.5"
typology="I,L" siting="attached"/>``, ``<landuse class="industrial"
setback-side="6"/>``) and may override them lot by lot with columns of the
lots layer (``far``, ``loc``, ``floors``, ``typology``, ``use``,
``height_class``, ``siting``, ``building_depth``, ``house_width``), as
CityEngine users set a rule attribute per shape; a lot's value is checked as
the rule's would be in the XML.  The
most specific source wins: the lot's column, then its land-use rule, then its
district rule, then the node's parameter.

The land use of a lot is its ``use`` column; else the class of the
``<landuse>`` rule whose colour the land-use map shows under the lot when
that class is one of :data:`~.typology.USES`; else its district's ``use``;
else the node's ``use`` parameter.

References
----------
.. [1] J. Viinikka, "Procedural modelling as an urban planning tool",
   master's thesis, Aalto University, Espoo, 2014, §5.2.1 (levels of control), paper 000.
.. [2] V. Potočková, "Procedural generation of future urban construction
   according to rules", bachelor's thesis, Czech Technical University in
   Prague, 2024, §3.2.3 (height classes), paper 003.
"""

from __future__ import annotations

import numpy as np

from sengine import Param
from sengine.errors import ConfigError, ParameterError
from sengine.registry import declare_rule

from .typology import ROOF_KINDS, TYPOLOGIES, USES, parse_choices

__all__ = ["HEIGHT_CLASSES", "RULE_PARAMS", "class_bounds", "landuse_rule_at", "per_lot"]

#: Prague development height classes (003 §3.2.3): (lowest, highest) regulated height in m.
HEIGHT_CLASSES = {
    "I": (0.0, 6.0),
    "II": (0.0, 9.0),
    "III": (0.0, 12.0),
    "IV": (9.0, 16.0),
    "V": (12.0, 21.0),
    "VI": (16.0, 26.0),
    "VII": (21.0, 40.0),
    "VIII": (40.0, np.inf),
}

#: Rule attribute -> its declaration; the node reads each under the same name with ``_`` for ``-``.
RULE_PARAMS = {
    "use": Param("str", None, choices=USES, doc="land use of the zone's lots (chooses typologies and roofs)"),
    "far": Param("float", None, min=0.0, max=100.0, unit="1", doc="floor area ratio: the target (loc 0) or cap"),
    "loc": Param(
        "int", None, min=0, max=1, unit="1", doc="level of control: 0 FAR indicator, 1 explicit parameters (000)"
    ),
    "floors": Param("int", None, min=1, max=300, unit="1", doc="floors of every building (loc 1; else the map)"),
    "height-class": Param(
        "str", None, choices=tuple(HEIGHT_CLASSES), doc="Prague height class I-VIII: the highest regulated height"
    ),
    "typology": Param("str", None, doc="building types and shares, e.g. 'I:3,L,tower' (default: by land use)"),
    "siting": Param("str", None, choices=("auto", "attached", "detached"), doc="party walls or side setbacks"),
    "setback-front": Param("float", None, min=0.0, max=100.0, unit="m", doc="build-to line from the street"),
    "setback-side": Param("float", None, min=0.0, max=100.0, unit="m", doc="side setback of detached buildings"),
    "setback-rear": Param("float", None, min=0.0, max=100.0, unit="m", doc="setback from the rear lot line"),
    "depth": Param("float", None, min=4.0, max=200.0, unit="m", doc="building depth (loc 1)"),
    "house": Param("float", None, min=4.0, max=100.0, unit="m", doc="greatest width of a detached house"),
    "roof": Param("str", None, doc="roof kinds and shares, e.g. 'gable:2,hip' (default: by land use)"),
}

#: Lot columns that override a rule, and the rule (a lot's own ``depth`` is its depth from the street, not
#: its building's: ``building_depth`` is).
LOT_COLUMNS = {
    "far": "far",
    "loc": "loc",
    "floors": "floors",
    "typology": "typology",
    "height_class": "height_class",
    "siting": "siting",
    "building_depth": "depth",
    "house_width": "house",
}

for _tag in ("district", "landuse"):
    declare_rule(_tag, {k: v for k, v in RULE_PARAMS.items() if not (_tag == "landuse" and k == "use")})


def class_bounds(names) -> tuple[np.ndarray, np.ndarray]:
    """Lowest and highest regulated height (m) of each height class name (``""``: 0 and inf)."""
    names = np.asarray(names).astype(str)
    lo = np.zeros(len(names))
    hi = np.full(len(names), np.inf)
    for k, (a, b) in HEIGHT_CLASSES.items():
        sel = names == k
        lo[sel], hi[sel] = a, b
    return lo, hi


def landuse_rule_at(image, rules, x, y) -> np.ndarray:
    """Index into ``rules`` (the ``<landuse>`` rules) of the land-use map's colour at each point.

    Parameters
    ----------
    image : sengine.geom.raster.ImageMap or None
        The decoded land-use map (``None``: no map, every point gets ``-1``).
    rules : list of Rule
        The ``<landuse>`` rules, each with its ``color``.
    x, y : ndarray
        Points (m, the city's planar frame).

    Returns
    -------
    ndarray of int64
        The nearest legend colour's rule at each point (RGB distance), ``-1`` without a map.
    """
    out = np.full(len(x), -1, np.int64)
    if image is None or not rules or len(x) == 0:
        return out
    from sengine.geom.raster import parse_colour

    legend = np.array([parse_colour(r.get("color"), where=r.where) for r in rules if r.get("color")], np.int64)
    if len(legend) != len(rules):
        raise ConfigError("<landuse> needs a color attribute", where=rules[0].where or None)
    rgb = np.asarray(image.sample(x, y), np.int64).reshape(len(x), -1)
    if rgb.shape[1] == 1:
        rgb = np.repeat(rgb, 3, axis=1)
    d2 = ((rgb[:, None, :3] - legend[None, :, :]) ** 2).sum(axis=2)
    return d2.argmin(axis=1)


def _coerce_choices(value: str, names, what: str, where: str) -> str:
    try:
        parse_choices(value, names, what=what)
    except ValueError as exc:
        raise ParameterError(str(exc), where=where or None) from None
    return value


def _apply(out: dict, rule, sel, where: str, *, skip=()) -> None:
    """Set the attributes ``rule`` gives on the lots ``sel``."""
    for attr, decl in RULE_PARAMS.items():
        raw = rule.get(attr)
        if raw is None or attr in skip:
            continue
        value = decl.coerce(raw, rule.where or where, attr)
        if attr == "typology":
            value = _coerce_choices(value, TYPOLOGIES, "typology", rule.where)
        elif attr == "roof":
            value = _coerce_choices(value, ROOF_KINDS, "roof kind", rule.where)
        out[attr.replace("-", "_")][sel] = value


def zone_use(lots, zones) -> np.ndarray:
    """The ``use`` of the zone (polygons with a ``use`` column) under each lot's inner point; ``None`` outside."""
    import shapely

    from sengine.geom.polygons import containing

    n = len(lots)
    out = np.full(n, None, dtype=object)
    if zones is None or not len(zones) or "use" not in zones or n == 0:
        return out
    inside = containing(shapely.point_on_surface(lots.geometry), zones.geometry)
    has = inside >= 0
    out[has] = np.asarray(zones["use"], dtype=object)[inside[has]]
    return out


def per_lot(
    lots, defaults: dict, where: str, zones=None, *, districts=(), landuses=(), landuse_map=None
) -> dict[str, np.ndarray]:
    """Each rule value for each lot: lot column, land-use rule, district rule, node default.

    The land use of a lot is its ``use`` column, else the class of the
    land-use map under it (a class of :data:`~.typology.USES`), else the
    ``use`` of the ``zones`` polygon under it (OSM ``landuse``), else its
    district's ``use``, else the default.  The ``<landuse>`` rule of a lot
    is the one whose colour the map shows under it, or, without a map, the
    one whose ``class`` is the lot's land use.

    Parameters
    ----------
    lots : Layer
        Lots with ``district`` (and optionally the override columns).
    defaults : dict
        Node parameter values under the rule names with ``_`` (``setback_front`` ...);
        ``None`` where the node sets none.
    where : str
        The node, for messages.
    zones : Layer, optional
        Land-use polygons with a ``use`` column.
    districts, landuses : list of Rule
        The plan's ``<district>`` and ``<landuse>`` rules (from the ``rules`` ports).
    landuse_map : sengine.geom.raster.ImageMap, optional
        The decoded land-use map.

    Returns
    -------
    dict of str to ndarray (object)
        One array per rule attribute (``_`` names), ``None`` where nothing sets it.
    """
    import shapely

    n = len(lots)
    out = {k.replace("-", "_"): np.full(n, defaults.get(k.replace("-", "_")), dtype=object) for k in RULE_PARAMS}
    if n == 0:
        return out
    idx = np.asarray(lots.get("district", np.full(n, -1)), np.int64)
    for i, rule in enumerate(districts):
        sel = idx == i
        if sel.any():
            _apply(out, rule, sel, where)
    zoned = zone_use(lots, zones)
    has = np.array([u in USES for u in zoned], bool)
    out["use"][has] = zoned[has]
    mapped = np.full(n, -1, np.int64)
    if landuses and landuse_map is not None:
        pts = shapely.point_on_surface(lots.geometry)
        mapped = landuse_rule_at(landuse_map, landuses, shapely.get_x(pts), shapely.get_y(pts))
        for i, rule in enumerate(landuses):
            cls = (rule.get("class") or "").strip().lower()
            if cls in USES:
                out["use"][mapped == i] = cls
    if "use" in lots:
        vals = np.asarray(lots["use"], dtype=object)
        known = np.array([v in USES for v in vals], bool)
        out["use"][known] = vals[known]
    for i, rule in enumerate(landuses):
        cls = (rule.get("class") or "").strip().lower()
        sel = mapped == i if (mapped >= 0).any() else out["use"].astype(str) == cls
        if sel.any():
            _apply(out, rule, sel, where, skip=("use",))
    for col, rule in LOT_COLUMNS.items():
        if col in lots:
            vals = np.asarray(lots[col], dtype=object)
            known = np.array([v is not None and v == v and str(v) != "" for v in vals], bool)
            out[rule][known] = _lot_values(vals[known], rule, col, where)
    return out


def _lot_values(vals: np.ndarray, rule: str, col: str, where: str) -> np.ndarray:
    """A lot column's given values, checked against their rule's declaration (a lot file may hold anything).

    Numbers are checked as one array, text by its distinct values; a value
    the rule would refuse in the XML is a :class:`ParameterError` naming the
    column.
    """
    attr = rule.replace("_", "-")
    decl = RULE_PARAMS[attr]
    name = f"lot column {col}"
    if decl.type in ("float", "int"):
        try:
            num = np.asarray(vals, np.float64)
        except (TypeError, ValueError):
            bad = next(v for v in vals if not _is_number(v))
            raise ParameterError(f"{name}={bad!r} is not a valid {decl.type}", where=where or None) from None
        lo = -np.inf if decl.min is None else decl.min
        hi = np.inf if decl.max is None else decl.max
        for v in num[~((num >= lo) & (num <= hi))][:1]:  # NaN and inf fail too: the declaration says why
            decl.coerce(float(v), where or None, name)
        return num.astype(object)
    for v in np.unique(vals.astype(str)):
        decl.coerce(v, where or None, name)
        if attr in ("typology", "roof"):
            _coerce_choices(
                v, TYPOLOGIES if attr == "typology" else ROOF_KINDS, attr.replace("roof", "roof kind"), where
            )
    return vals


def _is_number(v) -> bool:
    try:
        float(v)
    except (TypeError, ValueError):
        return False
    return True

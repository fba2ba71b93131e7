"""Building typologies by land use (paper 004 §3.3.2, Figs. 4, 5 and 7).

Paper 004 builds each functional zone from a library of **8 building
types** (Fig. 4): main hall with podium, multi-towers with podium, buildings
linked by a corridor, tower, O, L, U and I shapes; and combines them by land
use (Fig. 5): residential zones are slab blocks and tower apartments,
commercial ones retail parks (L shapes around a square) and malls (podium
and towers), office ones U, L and O (atrium) clusters and single slabs,
industrial ones L, U and I halls, educational ones buildings linked by
corridors beside a playground.  Here each type is a footprint generator on a
lot's building area (:mod:`.siting`), drawn at a building depth ``d`` so the
FAR-to-building loop (:mod:`.far`) can shrink it:

========== ================ ====================================================
code       paper 004 type   footprint
========== ================ ====================================================
``I``      I-shape (slab)   a band of depth ``d`` along the street
``L``      L-shape          the street band and one side band
``U``      U-shape          the street band and both side bands
``O``      O-shape          a ring of depth ``d`` round a court (atrium)
``tower``  tower            a ``d`` x ``d`` square oriented to the street
``towers`` multi-towers     one or two ``d`` x ``d`` towers on a low podium
           with podium      (the street band, ``podium_depth`` deep)
``hall``   main hall with   a hall ``d`` deep across the area on a low podium
           podium           filling the rest of it
``linked`` corridor-linked  a street bar and a rear bar of depth ``d`` and a
                            low corridor between them
``box``    (CityEngine's    the whole building area
           extrusion)
``house``  (detached house) a ``house`` x ``d`` rectangle on the main front,
                            centred on it; it keeps its side setbacks, and on a
                            plot narrower than itself grows deeper (at most
                            1.5 times) to keep its ground area
========== ================ ====================================================

The detached house is not one of paper 004's types, which build city
zones; it is what lines a village street or a suburb's (``buildings.context``
gives it to lots where streets are sparse).

Roofs (004 §3.4, Fig. 7): flat, flat with parapet, single slope (``shed``),
double slope (``gable``), hip, pyramid and stepped; slope, hip and pyramid
roofs are "often observed on residential buildings" and the others on all
kinds, which :data:`ROOFS` encodes per land use and type.  Roof heights keep
within Prague's envelope above the regulated height (003 §3.2.3): a slope of
at most 45 degrees and 7.5 m, or a recessed storey of at most 3.5 m.

References
----------
.. [1] M. Zhang, J. Wu, Y. Liu, J. Zhang and G. Li, "GIS based procedural
   modeling in 3D urban design", ISPRS International Journal of
   Geo-Information 11(10):531, 2022. doi:10.3390/ijgi11100531, §3.3.2 and §3.4 (paper 004).
.. [2] V. Potočková, "Procedural generation of future urban construction
   according to rules", bachelor's thesis, Czech Technical University in
   Prague, 2024, §3.2.3 (paper 003).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import shapely

from sengine.geom.polygons import inset, obb_frame, threaded
from sengine.random import uniform

from .edges import FRONT, REAR, LotEdges
from .siting import _convex_rings, axis_extent, band, centred_boxes, clip_box, limit_length, polygonal, ring, side_lines

__all__ = [
    "TYPOLOGIES",
    "USES",
    "BY_USE",
    "SITING_BY_USE",
    "ROOFS",
    "ROOF_KINDS",
    "Site",
    "choose",
    "parse_choices",
    "draw_parts",
    "roof_heights",
    "rectangle_width",
]

#: The footprint generators, in a fixed order (a typology's code is its index).
TYPOLOGIES = ("I", "L", "U", "O", "tower", "towers", "hall", "linked", "box", "house")
#: Land uses with a typology table (004 Fig. 5); any other use builds as ``residential``.
USES = ("residential", "commercial", "office", "industrial", "educational", "mixed")
#: Land use -> typologies and their shares (004 Fig. 5).
BY_USE = {
    "residential": {"I": 0.6, "L": 0.15, "U": 0.1, "tower": 0.15},  # slab blocks, tower apartments
    "commercial": {"towers": 0.4, "hall": 0.3, "L": 0.3},  # malls, retail parks of L shapes
    "office": {"U": 0.25, "L": 0.25, "O": 0.25, "I": 0.25},  # U, L and atrium clusters, single slabs
    "industrial": {"I": 0.5, "L": 0.3, "U": 0.2},  # halls along a loop
    "educational": {"linked": 1.0},  # buildings linked by corridors
    "mixed": {"I": 0.5, "L": 0.25, "O": 0.25},  # perimeter blocks
}
#: Land use -> siting when a rule asks for ``auto``: perimeter blocks attached, halls and schools detached.
SITING_BY_USE = {
    "residential": "attached",
    "commercial": "attached",
    "office": "attached",
    "mixed": "attached",
    "industrial": "detached",
    "educational": "detached",
}
#: Roof kinds of the buildings layer (004 Fig. 7).
ROOF_KINDS = ("flat", "parapet", "shed", "gable", "hip", "pyramid", "stepped")
#: (land use, typology) -> roof kinds and their shares; ``(use, "*")`` for any other typology.
ROOFS = {
    ("residential", "tower"): {"parapet": 0.6, "flat": 0.2, "stepped": 0.2},
    ("residential", "*"): {"gable": 0.35, "hip": 0.35, "parapet": 0.2, "flat": 0.1},
    ("mixed", "*"): {"hip": 0.3, "gable": 0.2, "parapet": 0.3, "flat": 0.2},
    ("commercial", "*"): {"flat": 0.5, "parapet": 0.4, "stepped": 0.1},
    ("office", "*"): {"flat": 0.4, "parapet": 0.4, "stepped": 0.2},
    ("industrial", "*"): {"shed": 0.4, "gable": 0.2, "flat": 0.4},
    ("educational", "*"): {"hip": 0.4, "gable": 0.3, "flat": 0.3},
}
ROOF_PITCH = 35.0  #: deg: pitch of gable, hip and pyramid roofs
SHED_PITCH = 12.0  #: deg: pitch of single-slope roofs
ROOF_MAX = 7.5  #: m: highest sloped roof above the top storey (003 §3.2.3)
PARAPET = 1.0  #: m: parapet above a flat roof
RECESSED = 3.0  #: m: a stepped roof's recessed storey (003: at most 3.5 m, set back at least 2 m)
CORRIDOR = 4.0  #: m: width of a corridor linking two bars
TOWER_SETBACK = 3.0  #: m: towers stand back from their podium's edge
HALL_MARGIN = 8.0  #: m: width of the podium round a main hall (at most a fifth of the area's width)
MIN_WIDTH = 4.0  #: m: building parts narrower than this are not built
COURT_MIN = 12.0  #: m: the narrowest court an O is built round
RING_MIN = 8.0  #: m: the thinnest ring of an O (000's least building depth)
HOUSE_DEEPER = 1.5  #: a house on a plot narrower than itself grows at most this much deeper to keep its area
HOUSE_FILL = 0.8  #: a house the plot cuts to less than this share of its oriented box is refitted whole
HOUSE_SHRINK = 0.8  #: ... or, where it does not fit whole, shrunk by this factor each way (one step)
LOW, MAIN = 0, 1  #: part roles: of fixed height (podium, corridor) or taking the floors


@dataclass
class Site:
    """What the generators need of each lot: its building area and its lines (per lot row)."""

    area: np.ndarray  # building area (polygon per lot)
    edges: LotEdges
    front: np.ndarray  # front setback (m) per lot
    side: np.ndarray  # side setback (m) per lot
    rear: np.ndarray  # rear setback (m) per lot
    podium_depth: float = 20.0
    house: np.ndarray | float = 10.0  # greatest length of a detached house along the street (m, per lot)
    #: footprints already drawn, per typology: (depth per lot row, footprint per lot row); see :func:`_footprints`
    memo: dict = field(default_factory=dict, repr=False)

    def __post_init__(self):
        n = len(self.area)
        self.house = np.broadcast_to(np.asarray(self.house, np.float64), (n,))
        self.front_lines = self.edges.lines(FRONT, n)
        self.rear_lines = self.edges.lines(REAR, n)
        self.left_lines = side_lines(self.edges, n, "left")
        self.right_lines = side_lines(self.edges, n, "right")
        self.axis = self.edges.axis


def parse_choices(text: str, names, *, what: str) -> dict[str, float]:
    """``"I:2,L"`` -> ``{"I": 2.0, "L": 1.0}``; a ValueError names an unknown entry."""
    out: dict[str, float] = {}
    for item in str(text).split(","):
        item = item.strip()
        if not item:
            continue
        name, _, w = item.partition(":")
        name = name.strip()
        if name not in names:
            raise ValueError(f"unknown {what} {name!r} (expected {', '.join(names)})")
        try:
            weight = float(w) if w.strip() else 1.0
        except ValueError:
            raise ValueError(f"{what} {name!r} has weight {w!r}, not a number") from None
        if not np.isfinite(weight) or weight < 0:
            raise ValueError(f"{what} {name!r} has weight {w!r}, not a positive number")
        out[name] = out.get(name, 0.0) + weight
    if not out or sum(out.values()) <= 0:
        raise ValueError(f"no {what} given")
    return out


def choose(tables: list[dict[str, float]], which: np.ndarray, u: np.ndarray, names) -> np.ndarray:
    """Index in ``names`` drawn for each row from ``tables[which[row]]`` with uniform numbers ``u``."""
    out = np.zeros(len(which), np.int64)
    for t, table in enumerate(tables):
        sel = np.flatnonzero(which == t)
        if len(sel) == 0:
            continue
        keys = list(table)
        w = np.array([table[k] for k in keys], np.float64)
        cum = np.cumsum(w / w.sum())
        pick = np.minimum(np.searchsorted(cum, u[sel], side="right"), len(keys) - 1)
        out[sel] = np.array([names.index(k) for k in keys])[pick]
    return out


def _union(a, b):
    both = ~shapely.is_empty(a) & ~shapely.is_empty(b)
    out = np.where(shapely.is_empty(a), b, a)
    if both.any():
        out = out.copy()
        out[both] = threaded(shapely.union, a[both], b[both])
    return polygonal(out)


#: Typologies of one main part per lot, its whole length a function of the depth alone.
_SIMPLE = ("box", "I", "L", "U", "O")


def _footprint(code: str, site: Site, rows, d):
    """Full-length footprint of a :data:`_SIMPLE` typology ``code`` on lots ``rows`` at depth ``d`` (m)."""
    A = site.area[rows]
    fs, ss = site.front[rows], site.side[rows]
    if code == "box":
        return A
    if code == "I":
        return band(A, site.front_lines[rows], fs + d)
    if code == "L":
        return _union(band(A, site.front_lines[rows], fs + d), band(A, site.left_lines[rows], ss + d))
    if code == "U":
        g = _union(band(A, site.front_lines[rows], fs + d), band(A, site.left_lines[rows], ss + d))
        return _union(g, band(A, site.right_lines[rows], ss + d))
    # O: the ring thins to keep a court of COURT_MIN; an area too narrow for both has none
    d = np.minimum(d, np.maximum((rectangle_width(A) - COURT_MIN) / 2.0, 0.0))
    return np.where(d >= RING_MIN, ring(A, np.maximum(d, RING_MIN)), A)


def _footprints(code: str, site: Site, rows, d):
    """:func:`_footprint`, each lot's drawn once per depth.

    The FAR loop (:mod:`.far`) shortens a footprint once its depth is at
    its floor: those lots are redrawn at the very depth they had, and the
    footprint (each lot's alone: every step is element-wise) is taken from
    ``site.memo`` instead of cutting and uniting its bands again.
    """
    n = len(site.area)
    depth_of, geom_of = site.memo.setdefault(code, (np.full(n, np.nan), np.full(n, None, dtype=object)))
    rows = np.asarray(rows, np.int64)
    d = np.asarray(d, np.float64)
    out = geom_of[rows]
    miss = np.flatnonzero(depth_of[rows] != d)
    if len(miss):
        g = _footprint(code, site, rows[miss], d[miss])
        out[miss] = g
        depth_of[rows[miss]] = d[miss]
        geom_of[rows[miss]] = g
    return out


def _house(site: Site, rows: np.ndarray, d: np.ndarray, frac: np.ndarray) -> np.ndarray:
    """Detached houses on lots ``rows``: a ``site.house`` x ``d`` rectangle each (m), or nothing.

    The rectangle stands on the lot's main front, about the middle of the
    building area's street band.  On a plot narrower than the house it grows
    deeper to keep its ground area (at most :data:`HOUSE_DEEPER`).  Where the
    building area cuts it to under :data:`HOUSE_FILL` of its oriented box (a
    triangle on a wedge plot), the house moves to the widest place of the building area within
    two and a half houses' depth of the street (the centre of its largest
    inscribed circle there), else of the whole area, turned end-on to the street if
    that fits, else shrunk by :data:`HOUSE_SHRINK` each way; a plot that
    holds none of these whole stays a garden.  A house is a rectangle, never
    the sliver of one, nor a shed: Statbel counts 0.3 % of Wallonia's
    detached houses under 45 m².
    """
    ax = site.axis[rows]
    g = _footprints("I", site, rows, d)
    lo_, hi_ = _axis_extent(g, ax)
    width = site.house[rows]
    squeezed = (hi_ > lo_) & (hi_ - lo_ < width)
    if squeezed.any():
        deeper = d * np.minimum(width / np.maximum(hi_ - lo_, 1e-9), HOUSE_DEEPER)
        g = _footprints("I", site, rows, np.where(squeezed, deeper, d))
        lo_, hi_ = _axis_extent(g, ax)
        # the deeper band may be wider (a tapering plot): deep enough to keep the area at that width, no more
        d = np.where(squeezed, d * np.clip(width / np.maximum(hi_ - lo_, 1e-9), 1.0, HOUSE_DEEPER), d)
    # the house's width along its main front, about the band's middle, and from that front no deeper than
    # the setback and the house (a corner plot's band runs along its side street too)
    w = np.minimum(width, frac * (hi_ - lo_))
    mid = 0.5 * (lo_ + hi_)
    s0 = site.edges.street[rows]
    s1 = s0 + site.edges.facing[rows] * (site.front[rows] + d)
    g = polygonal(
        clip_box(g, np.zeros((len(g), 2)), ax, mid - w / 2, mid + w / 2, np.minimum(s0, s1), np.maximum(s0, s1))
    )
    _, _, long_, short = obb_frame(g)
    cut = np.flatnonzero(~shapely.is_empty(g) & (shapely.area(g) < HOUSE_FILL * long_ * short))
    if len(cut):
        area = site.area[rows[cut]]
        # the widest place of the area near the street (within two and a half houses' depth of it), then
        # that of the whole area (the far end of a deep plot)
        near = band(area, site.front_lines[rows[cut]], site.front[rows[cut]] + 2.5 * d[cut])
        near = np.where(shapely.is_empty(near), area, near)
        centres = [
            shapely.get_coordinates(shapely.get_point(shapely.maximum_inscribed_circle(a), 0)) for a in (near, area)
        ]
        fit = np.full(len(cut), shapely.Polygon(), dtype=object)
        todo = np.arange(len(cut))
        # whole, then turned end-on to the street, then a step smaller each way
        steps = ((1.0, False), (1.0, True), (HOUSE_SHRINK, False), (HOUSE_SHRINK, True))
        for (scale, turn), centre in ((step, c) for step in steps for c in centres):
            hw, hd = 0.5 * scale * w[cut[todo]], 0.5 * scale * d[cut[todo]]
            if turn:
                hw, hd = hd, hw
            box = clip_box(area[todo], centre[todo], ax[cut[todo]], -hw, hw, -hd, hd)
            whole = shapely.area(box) >= (1.0 - 1e-6) * 4.0 * hw * hd
            fit[todo[whole]] = box[whole]
            todo = todo[~whole]
            if not len(todo):
                break
        g[cut] = polygonal(fit)
    return g


def _generate(code: str, site: Site, rows, d, frac, *, podium_depth: float):
    """Parts of typology ``code`` on lots ``rows``: (geometries, row of each, role of each)."""
    A = site.area[rows]
    ax = site.axis[rows]
    fs, rs = site.front[rows], site.rear[rows]

    if code in _SIMPLE:
        g = _footprints(code, site, rows, d)
        return limit_length(g, ax, frac), np.asarray(rows), np.full(len(rows), MAIN)
    if code == "house":
        return _house(site, np.asarray(rows), d, frac), np.asarray(rows), np.full(len(rows), MAIN)
    if code == "tower":
        g, r = centred_boxes(A, ax, d, d)
        return limit_length(g, ax[r], frac[r]), np.asarray(rows)[r], np.full(len(r), MAIN)
    if code == "towers":
        podium = band(A, site.front_lines[rows], fs + max(podium_depth, 0.0))
        base = polygonal(inset(podium, TOWER_SETBACK))
        lo_, hi_ = _axis_extent(base, ax)
        count = np.where(hi_ - lo_ >= 2.6 * d, 2, 1)  # two towers stand apart along the street
        towers, r = centred_boxes(base, ax, d, d, count=count)
        towers = limit_length(towers, ax[r], frac[r])
        low = _minus_parts(podium, towers, r)
        return _concat((towers, np.asarray(rows)[r], MAIN), (low, np.asarray(rows), LOW))
    if code == "hall":
        margin = np.minimum(HALL_MARGIN, 0.2 * obb_frame(A)[3])
        core = polygonal(inset(A, margin))
        hall = limit_length(band(core, site.front_lines[rows], fs + margin + d), ax, frac)
        low = _minus_parts(A, hall, np.arange(len(rows)))
        return _concat((hall, np.asarray(rows), MAIN), (low, np.asarray(rows), LOW))
    if code == "linked":
        bars = _union(band(A, site.front_lines[rows], fs + d), band(A, site.rear_lines[rows], rs + d))
        bars = limit_length(bars, ax, frac)
        lo_, hi_ = _axis_extent(A, ax)
        corridor, r = centred_boxes(A, ax, np.full(len(rows), CORRIDOR), np.maximum(hi_ - lo_, 1.0) * 4.0)
        low = _minus_parts(corridor, bars[r], np.arange(len(r)))
        return _concat((bars, np.asarray(rows), MAIN), (low, np.asarray(rows)[r], LOW))
    raise ValueError(f"unknown typology {code!r}")  # pragma: no cover - codes come from TYPOLOGIES


def _axis_extent(geoms, axis):
    return axis_extent(geoms, axis)


def _minus_parts(base, parts, row):
    """``base`` (per lot) minus every one of ``parts`` belonging to it (``row``: index into ``base``)."""
    out = np.asarray(base, dtype=object).copy()
    if len(parts) == 0:
        return out
    row = np.asarray(row, np.int64)
    parts = np.asarray(parts, dtype=object)
    order = np.argsort(row, kind="stable")
    row_s, parts_s = row[order], parts[order]
    first = np.r_[True, row_s[1:] != row_s[:-1]]
    rank = np.arange(len(row_s)) - np.maximum.accumulate(np.where(first, np.arange(len(row_s)), 0))
    for k in range(int(rank.max()) + 1):  # the k-th part of every lot that has one, in one call
        sel = rank == k
        rr = row_s[sel]
        out[rr] = threaded(shapely.difference, out[rr], parts_s[sel])
    return polygonal(out)


def _concat(*groups):
    geoms, rows, roles = [], [], []
    for g, r, role in groups:
        geoms.append(np.asarray(g, dtype=object))
        rows.append(np.asarray(r, np.int64))
        roles.append(np.full(len(g), role, np.int8))
    return np.concatenate(geoms), np.concatenate(rows), np.concatenate(roles)


def draw_parts(site: Site, rows, codes, d, frac, *, podium_depth: float = 20.0, min_part: float = 10.0):
    """Every part of the buildings of lots ``rows`` with typology ``codes`` (indices into TYPOLOGIES).

    Returns
    -------
    geoms : ndarray of Polygon
        One polygon per part (multipart pieces are split; pieces under
        ``min_part`` m2 dropped).
    row : ndarray of int64
        Lot row of each part.
    role : ndarray of int8
        :data:`MAIN` (takes the floors) or :data:`LOW` (fixed height: podium, corridor).
    """
    rows = np.asarray(rows, np.int64)
    codes = np.asarray(codes, np.int64)
    d = np.asarray(d, np.float64)
    frac = np.asarray(frac, np.float64)
    out = []
    for c in np.unique(codes):
        sel = np.flatnonzero(codes == c)
        out.append(_generate(TYPOLOGIES[c], site, rows[sel], d[sel], frac[sel], podium_depth=podium_depth))
    if not out:
        return np.empty(0, object), np.zeros(0, np.int64), np.zeros(0, np.int8)
    g = np.concatenate([o[0] for o in out])
    r = np.concatenate([o[1] for o in out])
    role = np.concatenate([o[2] for o in out]).astype(np.int8)
    parts, pi = shapely.get_parts(g, return_index=True)
    keep = (shapely.get_type_id(parts) == 3) & (shapely.area(parts) >= min_part)
    parts, pi = parts[keep], pi[keep]
    keep = ~_slivers(parts)
    parts, pi = parts[keep], pi[keep]
    o = np.lexsort((role[pi], r[pi]))  # by lot, low parts first (drawn under the rest): the same whatever the grouping
    return parts[o], r[pi][o], role[pi][o]


def rectangle_width(geoms) -> np.ndarray:
    """Short side (m) of the rectangle with each polygon's area and perimeter.

    Exact for rectangles; for a bar bent into an L, U or O, about the bar's
    depth: the building depth a roof spans.
    """
    a = shapely.area(geoms)
    p = shapely.length(geoms)
    return np.maximum(p / 4.0 - np.sqrt(np.maximum(p * p / 16.0 - a, 0.0)), 0.0)


def _slivers(parts) -> np.ndarray:
    """Parts a clip left too thin to build: narrower than :data:`MIN_WIDTH`, or mostly so.

    A part is measured by the width of the rectangle of its area and
    perimeter (:func:`rectangle_width`); a part under twice the least width
    by that measure (a thin L, a narrow ring) loses its thin arms to an
    opening by ``MIN_WIDTH / 2`` and is a sliver when less than half of it remains.
    The parts kept are not changed (party walls stay exact).
    """
    if len(parts) == 0:
        return np.zeros(0, bool)
    width = rectangle_width(parts)
    out = width < MIN_WIDTH
    odd = np.flatnonzero(~out & (width < 2.0 * MIN_WIDTH))
    if len(odd):  # a convex part has no thin arm: its rectangle width says it all
        convex, _, _ = _convex_rings(parts[odd])
        odd = odd[~convex]
    if len(odd):
        r = MIN_WIDTH / 2.0
        opened = shapely.buffer(shapely.buffer(parts[odd], -r, join_style="mitre"), r, join_style="mitre")
        out[odd] = shapely.area(opened) < 0.5 * shapely.area(parts[odd])
    return out


def roof_heights(kind, footprints, floor_height) -> np.ndarray:
    """Height (m) of each roof above the top storey, from its kind and the footprint's depth.

    The depth is :func:`rectangle_width` of the footprint.  Gable, hip and
    pyramid: ``tan(35 deg) x depth / 2``; shed: ``tan(12 deg) x depth``; all at most
    7.5 m (003's envelope).  Parapet 1 m, stepped a recessed storey of
    ``min(floor_height, 3 m)``, flat 0.
    """
    kind = np.asarray(kind).astype(str)
    width = rectangle_width(footprints) if len(kind) else np.zeros(0)
    t = np.tan(np.radians(ROOF_PITCH))
    h = np.zeros(len(kind))
    h = np.where(np.isin(kind, ("gable", "hip", "pyramid")), t * width / 2.0, h)
    h = np.where(kind == "shed", np.tan(np.radians(SHED_PITCH)) * width, h)
    h = np.minimum(h, ROOF_MAX)
    h = np.where(kind == "parapet", PARAPET, h)
    h = np.where(kind == "stepped", min(float(floor_height), RECESSED), h)
    return h


def roof_kinds(uses, typologies, role, seed: int, key: str, ids) -> np.ndarray:
    """Roof kind of each part drawn from :data:`ROOFS` by land use and typology (low parts flat)."""
    uses = np.asarray(uses).astype(str)
    typologies = np.asarray(typologies).astype(str)
    n = len(uses)
    u = uniform(seed, key, np.asarray(ids, np.int64))
    out = np.full(n, "flat", dtype=object)
    for (use, typ), table in ROOFS.items():
        if typ == "*":
            sel = (uses == use) & ~np.isin(typologies, [t for u, t in ROOFS if u == use])
        else:
            sel = (uses == use) & (typologies == typ)
        idx = np.flatnonzero(sel & (np.asarray(role) == MAIN))
        if len(idx):
            keys = list(table)
            pick = choose([table], np.zeros(len(idx), np.int64), u[idx], keys)
            out[idx] = np.array(keys, dtype=object)[pick]
    return out

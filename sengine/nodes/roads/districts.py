"""Districts and major roads: skylineEngine §5.3.1, Fig. 7.

The district map says where each district lies (one colour per district),
the configuration's ``<district>`` rules say how each is styled (street
pattern, widths, lot method), and the optional land-use map says where
nothing may be built.  Fig. 7 of the paper::

    currMap = empty
    for each pattern in districtMap:
        generate pattern; position and orient it
        bounds = Bounds(pattern, districtMap)
        finalP = Clip(pattern, bounds)
        finalP = Merge(finalP, bounds)
        currMap = Merge(finalP, currMap)
    if land-use map: currMap = Clip(currMap, landUseMap)

Here ``Bounds`` is the district's region vectorized from the map
(:func:`sengine.geom.raster.vectorize`: all regions come from one coverage, so
neighbours share their border exactly), the land-use clip is applied to each
region before the merge (the cut-out borders become roads too), and the
merge is one noding of every region border and clipped pattern line followed
by a polygonization (:func:`patterns.split_cells`).  Cells smaller than
``merge`` times the pattern's cell are dissolved into a neighbour of the same
district, so pattern lines that graze a border leave no slivers.

``<district>`` attributes (all optional except ``color`` with a district map):

=================  =====================================================  ==========
name               meaning                                                 default
=================  =====================================================  ==========
``name``           label of the district                                  ``d<i>``
``pattern``        ``grid``, ``radial`` or ``organic``                    ``grid``
``spacing``        grid: ``"dx dy"`` between major roads (m)              ``400 400``
``angle``          grid / radial: rotation (deg, counter-clockwise)       ``0``
``offset``         grid: ``"x y"`` of one grid crossing (m)               ``0 0``
``center``         radial: ``"x y"`` (m)                                  centroid
``rings``          radial: number of rings                                ``4``
``ring-spacing``   radial: distance between rings (m), overrides rings    --
``spokes``         radial: number of spokes                               ``8``
``sites``          organic: number of Voronoi sites                       ``30``
``relax``          organic: Lloyd iterations                              ``3``
``weights``        organic: density variation (0 = uniform)               ``0``
``major-width``    street width of the major roads (m)                    ``20``
``minor-spacing``  ``"dx dy"`` of the minor grid (m), see ``roads.minor`` ``100 100``
``minor-angle``    deg, ``follow`` (the major angle) or ``random``        ``follow``
``minor-width``    street width of the minor roads (m)                    ``12``
``lots``           lot method for ``lots.district``                       ``manhattan``
=================  =====================================================  ==========

``<landuse color=... class=...>``: classes ``water`` and ``park`` (and any
class other than ``buildable``, ``residential``, ``commercial``,
``industrial``, ``office``, ``mixed``) are cut out of the city; set
``buildable="true"`` or ``"false"`` to decide explicitly.  The ``park`` class
becomes the district-level parks (paper §4: Central Park).

References
----------
§4 (parks at district level), §5.2 (image maps), §5.3.1 and Fig. 7 (districts and patterns) of [1]_; the organic pattern's Lloyd relaxation [2]_ with a density function [3]_.

.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
.. [2] S. Lloyd, "Least squares quantization in PCM", IEEE Transactions on
   Information Theory 28(2), 129-137, 1982.
.. [3] Q. Du, V. Faber and M. Gunzburger, "Centroidal Voronoi tessellations:
   applications and algorithms", SIAM Review 41(4), 637-676, 1999.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np
import shapely
from shapely import STRtree

from sengine import CityPlan, Layer, NodeResult, Param, Port, SENode, register
from sengine.errors import ConfigError, LimitError, Problems
from sengine.geom.raster import ImageMap, classify, parse_colour, vectorize
from sengine.registry import declare_rule

from ..maps import image_of, plan_meta, rules_of
from .patterns import (
    cell_edges,
    clip_lines,
    grid_lines,
    merge_small_cells,
    organic_lines,
    organic_sites,
    radial_lines,
    side_points,
    split_cells,
)

__all__ = [
    "DistrictStyle",
    "district_styles",
    "landuse_classes",
    "city_regions",
    "pattern_lines",
    "major_network",
    "plan_meta",
    "RoadsDistricts",
]

log = logging.getLogger(__name__)

PATTERNS = ("grid", "radial", "organic")
BUILDABLE_CLASSES = frozenset({"buildable", "residential", "commercial", "industrial", "office", "mixed"})

declare_rule(
    "district",
    {
        "color": Param("colour", doc="the district's colour in the district map"),
        "name": Param("str", doc="label of the district (default d<i>)"),
        "pattern": Param("str", "grid", choices=PATTERNS, doc="major-road pattern"),
        "spacing": Param(
            "float", (400.0, 400.0), min=0.0, max=100_000.0, unit="m", count=2, doc="grid: 'dx dy' between major roads"
        ),
        "angle": Param(
            "float", 0.0, min=-360.0, max=360.0, unit="deg", doc="grid / radial: rotation, counter-clockwise"
        ),
        "offset": Param(
            "float", (0.0, 0.0), min=-1e6, max=1e6, unit="m", count=2, doc="grid: 'x y' of one grid crossing"
        ),
        "center": Param(
            "float", None, min=-1e6, max=1e6, unit="m", count=2, doc="radial: 'x y' of the centre (default: centroid)"
        ),
        "rings": Param("int", 4, min=0, max=1000, doc="radial: number of rings"),
        "ring-spacing": Param(
            "float", None, min=0.0, max=100_000.0, unit="m", doc="radial: distance between rings, overrides rings"
        ),
        "spokes": Param("int", 8, min=0, max=1000, doc="radial: number of spokes"),
        "sites": Param("int", 30, min=1, max=100_000, doc="organic: number of Voronoi sites"),
        "relax": Param("int", 3, min=0, max=100, doc="organic: Lloyd iterations"),
        "weights": Param("float", 0.0, min=0.0, max=100.0, doc="organic: density variation (0 = uniform)"),
        "major-width": Param("float", 20.0, min=0.0, max=200.0, unit="m", doc="street width of the major roads"),
        "minor-spacing": Param(
            "float", (100.0, 100.0), min=0.0, max=100_000.0, unit="m", count=2, doc="'dx dy' of the minor grid"
        ),
        "minor-angle": Param("str", "follow", doc="minor grid angle: deg, 'follow' (the major angle) or 'random'"),
        "minor-width": Param("float", 12.0, min=0.0, max=200.0, unit="m", doc="street width of the minor roads"),
    },
)
declare_rule(
    "landuse",
    {
        "color": Param("colour", doc="the class's colour in the land-use map"),
        "class": Param("str", "buildable", doc="land-use class: water, park, residential, commercial, ..."),
        "buildable": Param("bool", None, doc="whether lots may be made here (default: by class)"),
        "name": Param("str", doc="label of the class"),
    },
)


@dataclass(frozen=True)
class DistrictStyle:
    """One ``<district>`` rule, checked and converted (lengths in m, angles in deg)."""

    index: int
    name: str
    colour: tuple[int, int, int] | None
    pattern: str = "grid"
    spacing: tuple[float, float] = (400.0, 400.0)
    angle: float = 0.0
    offset: tuple[float, float] = (0.0, 0.0)
    center: tuple[float, float] | None = None
    rings: int = 4
    ring_spacing: float | None = None
    spokes: int = 8
    sites: int = 30
    relax: int = 3
    weights: float = 0.0
    major_width: float = 20.0
    minor_spacing: tuple[float, float] = (100.0, 100.0)
    minor_angle: float | str = "follow"
    minor_width: float = 12.0
    lots: str = "manhattan"
    where: str = ""
    attrs: dict = field(default_factory=dict)

    def cell_size(self) -> tuple[float, float] | None:
        """Area (m2) and width (m) of a typical major cell, when the pattern fixes them."""
        if self.pattern == "grid" and self.spacing[0] > 0 and self.spacing[1] > 0:
            return self.spacing[0] * self.spacing[1], min(self.spacing)
        if self.pattern == "grid":
            return None
        return None


MAX_FEATURES = 2_000_000  # blocks or lots of one district; whole Liège has 251,780 lots
MAX_AREAS = 20_000  # areas enclosed by major roads in one district (the paper's Manhattan has 86)


def _per_cell(area: float, dx: float, dy: float) -> float:
    """Cells of a ``dx`` x ``dy`` grid over ``area`` (m2); a spacing of 0 draws no line that way."""
    side = math.sqrt(area)
    return (area / (dx if dx > 0 else side)) / (dy if dy > 0 else side)


def feature_estimates(
    styles: list[DistrictStyle], areas, extent=None
) -> list[tuple[DistrictStyle, str, float, str, int, str]]:
    """Rough counts of what each district will make: ``(style, what, count, because, limit, advice)``.

    Major cells from the pattern, blocks from ``minor-spacing``, lots from
    ``lot-area`` when the rule sets it; ``areas`` are the districts' areas
    (m2); ``extent`` (the city's, m) bounds a radial pattern's reach.
    """
    out = []
    for style, area in zip(styles, areas):
        area = float(area)
        if not area > 0:
            continue
        if style.pattern == "grid":
            major, why = _per_cell(area, *style.spacing), f"spacing {style.spacing[0]:g} x {style.spacing[1]:g} m"
            advice = "make the spacing larger"
        elif style.pattern == "radial":
            rings, why = float(style.rings), f"{style.rings} rings x {style.spokes} spokes"
            advice = "use fewer rings or spokes"
            if style.ring_spacing:
                if extent is not None:
                    x0, y0, x1, y1 = extent
                    cx, cy = style.center or ((x0 + x1) / 2, (y0 + y1) / 2)
                    reach = max(math.hypot(x - cx, y - cy) for x in (x0, x1) for y in (y0, y1))
                else:
                    reach = 2 * math.sqrt(area)
                rings = reach / style.ring_spacing
                why = f"ring-spacing {style.ring_spacing:g} m x {style.spokes} spokes"
                advice = "make the ring-spacing larger"
            major = (rings + 1) * max(style.spokes, 1)
        else:
            major, why, advice = float(style.sites), f"{style.sites} sites", "use fewer sites"
        out.append((style, "areas", major, why, MAX_AREAS, advice))
        mdx, mdy = style.minor_spacing
        blocks = _per_cell(area, mdx, mdy)
        out.append((style, "blocks", blocks, f"minor-spacing {mdx:g} x {mdy:g} m", MAX_FEATURES, "make it larger"))
        lot_area = style.attrs.get("lot-area") if style.attrs else None
        try:
            lot_area = float(lot_area) if lot_area is not None else None
        except ValueError:
            lot_area = None
        if lot_area and lot_area > 0:
            out.append((style, "lots", area / lot_area, f"lot-area {lot_area:g} m2", MAX_FEATURES, "make it larger"))
    return out


def check_estimates(styles: list[DistrictStyle], areas, extent=None) -> None:
    """Refuse, before any work, a district that would make more than MAX_AREAS areas or MAX_FEATURES blocks or lots.

    Raises LimitError naming the district, the estimate and the rule that
    makes it (a spacing of 1 cm over a city is 1e11 blocks, not a city).
    """
    problems = []
    for style, what, count, why, limit, advice in feature_estimates(styles, areas, extent):
        if count > limit:
            problems.append(
                LimitError(
                    f"district {style.name!r}: {why} over its {float(areas[style.index]) / 1e6:.3g} km2 makes about "
                    f"{count:.2g} {what}; the limit is {limit:,} per district ({advice})",
                    where=style.where or None,
                )
            )
    Problems.raise_if(problems)


def _numbers(rule, key: str, n: int, default, *, positive: bool = False, integer: bool = False):
    text = rule.get(key)
    if text is None:
        return default
    try:
        vals = [float(v) for v in str(text).replace(",", " ").split()]
    except ValueError:
        vals = []
    ok = len(vals) == n and all(math.isfinite(v) for v in vals)
    if ok and positive:
        ok = all(v >= 0 for v in vals) and any(v > 0 for v in vals)
    if ok and integer:
        ok = all(v == int(v) for v in vals)
    if not ok:
        want = f"{n} {'whole ' if integer else ''}number{'s' if n > 1 else ''}"
        sign = " (>= 0, not all 0)" if positive else ""
        raise ConfigError(f"<{rule.tag}> {key}={text!r} is not {want}{sign}", where=rule.where or None)
    if integer:
        vals = [int(v) for v in vals]
    return tuple(vals) if n > 1 else vals[0]


def parse_district(rule, index: int) -> DistrictStyle:
    """Check one ``<district>`` rule; errors name the rule's file and line."""
    where = rule.where or None
    pattern = (rule.get("pattern") or "grid").strip().lower()
    if pattern not in PATTERNS:
        raise ConfigError(f"<district> pattern={pattern!r} is not one of {', '.join(PATTERNS)}", where=where)
    colour = parse_colour(rule.get("color"), where=rule.where) if rule.get("color") else None
    minor_angle = (rule.get("minor-angle") or "follow").strip().lower()
    if minor_angle not in ("follow", "random"):
        minor_angle = _numbers(rule, "minor-angle", 1, 0.0)
    center = _numbers(rule, "center", 2, None)
    style = DistrictStyle(
        index=index,
        name=rule.get("name") or f"d{index}",
        colour=colour,
        pattern=pattern,
        spacing=_numbers(rule, "spacing", 2, (400.0, 400.0), positive=True),
        angle=_numbers(rule, "angle", 1, 0.0),
        offset=_numbers(rule, "offset", 2, (0.0, 0.0)),
        center=center,
        rings=_numbers(rule, "rings", 1, 4, integer=True),
        ring_spacing=_numbers(rule, "ring-spacing", 1, None, positive=True),
        spokes=_numbers(rule, "spokes", 1, 8, integer=True),
        sites=_numbers(rule, "sites", 1, 30, integer=True),
        relax=_numbers(rule, "relax", 1, 3, integer=True),
        weights=_numbers(rule, "weights", 1, 0.0),
        major_width=_numbers(rule, "major-width", 1, 20.0, positive=True),
        minor_spacing=_numbers(rule, "minor-spacing", 2, (100.0, 100.0), positive=True),
        minor_angle=minor_angle,
        minor_width=_numbers(rule, "minor-width", 1, 12.0, positive=True),
        lots=(rule.get("lots") or "manhattan").strip().lower(),
        where=rule.where,
        attrs=dict(rule.attrs),
    )
    for key, val, lo in (
        ("rings", style.rings, 0),
        ("spokes", style.spokes, 0),
        ("sites", style.sites, 1),
        ("relax", style.relax, 0),
    ):
        if val < lo:
            raise ConfigError(f"<district> {key}={val} is below the minimum {lo}", where=where)
    if style.weights < 0:
        raise ConfigError(f"<district> weights={style.weights} is below the minimum 0", where=where)
    return style


def _rules(rules, tag: str) -> list:
    """A list of Rule from a ``rules`` layer, a plan, a list of rules or None."""
    if rules is None:
        return []
    if isinstance(rules, Layer):
        return rules_of(rules, tag)
    if hasattr(rules, "rules_of"):
        return rules.rules_of(tag)
    return list(rules)


def district_styles(rules) -> list[DistrictStyle]:
    """The district rules as styles; one default style when there are none.

    Parameters
    ----------
    rules : Layer or list of Rule or CityPlan or None
        The ``district_rules`` layer (:mod:`sengine.nodes.maps`), or the rules themselves.
    """
    rules = _rules(rules, "district")
    if not rules:
        return [DistrictStyle(index=0, name="city", colour=None)]
    return [parse_district(r, i) for i, r in enumerate(rules)]


def landuse_classes(rules, *, colour: bool = True) -> list[tuple[tuple[int, int, int] | None, str, bool, str]]:
    """``(colour, class, buildable, where)`` for each ``<landuse>`` rule (a layer, list or plan as for :func:`district_styles`).

    ``colour``: every rule must give one (it reads a land-use map); ``False``:
    a rule without one (land-use rules of a plan without a map) gets ``None``.
    """
    out = []
    for rule in _rules(rules, "landuse"):
        if colour and not rule.get("color"):
            raise ConfigError("<landuse> needs a color attribute", where=rule.where or None)
        cls = (rule.get("class") or "buildable").strip().lower()
        flag = rule.get("buildable")
        if flag is None:
            buildable = cls in BUILDABLE_CLASSES
        elif flag.strip().lower() in ("true", "yes", "1", "false", "no", "0"):
            buildable = flag.strip().lower() in ("true", "yes", "1")
        else:
            raise ConfigError(f"<landuse> buildable={flag!r} is not true or false", where=rule.where or None)
        rgb = parse_colour(rule.get("color"), where=rule.where) if rule.get("color") else None
        out.append((rgb, cls, buildable, rule.where))
    return out


def city_regions(
    extent,
    styles: list[DistrictStyle],
    *,
    district_map: ImageMap | None = None,
    landuse_map: ImageMap | None = None,
    legend: list | None = None,
    district_tolerance: float | None = None,
    landuse_tolerance: float | None = None,
    simplify: float = 1.0,
    grid_size: float = 1e-3,
):
    """Vectorize the district and land-use maps into district regions and land-use regions.

    Parameters
    ----------
    extent : tuple of float
        ``(xmin, ymin, xmax, ymax)`` of the city (m).
    styles : list of DistrictStyle
    district_map, landuse_map : ImageMap, optional
        The decoded maps (:class:`sengine.nodes.maps.MapsImage`).
    legend : list, optional
        :func:`landuse_classes` of the ``<landuse>`` rules (needed with a land-use map).
    district_tolerance, landuse_tolerance : float, optional
        Largest RGB distance to a legend colour (``None``: by file type).
    simplify : float
        Coverage simplification tolerance (pixels).
    grid_size : float
        Snap grid (m).

    Returns
    -------
    districts : list of shapely.Geometry
        Region of each style (may be empty), before the land-use clip.
    landuse : list of (str, bool, shapely.Geometry)
        Class, buildable flag and region of each land-use class present.
    buildable : shapely.Geometry
        The extent minus every non-buildable land-use region.
    """
    frame = shapely.box(*extent)
    if district_map is None:
        districts = [frame] + [shapely.Polygon()] * (len(styles) - 1)
    else:
        img = district_map
        missing = [s for s in styles if s.colour is None]
        if missing:
            raise ConfigError(
                "<district> needs a color attribute when the plan has a district map", where=missing[0].where or None
            )
        labels = classify(
            img,
            [s.colour for s in styles],
            tolerance=district_tolerance,
            names=[s.name for s in styles],
            what="district rules",
        )
        regions = vectorize(img, labels, simplify=simplify, grid_size=grid_size)
        districts = [regions.get(s.index, shapely.Polygon()) for s in styles]
    landuse: list[tuple[str, bool, shapely.Geometry]] = []
    buildable = frame
    if landuse_map is not None:
        if not legend:
            raise ConfigError(
                "the plan has a land-use map but no <landuse color=... class=...> rules",
                where=landuse_map.where or None,
            )
        img = landuse_map
        labels = classify(
            img,
            [c for c, *_ in legend],
            tolerance=landuse_tolerance,
            names=[c for _, c, *_ in legend],
            what="land-use rules",
        )
        regions = vectorize(img, labels, simplify=simplify, grid_size=grid_size)
        by_class: dict[str, list] = {}
        flags: dict[str, bool] = {}
        for k, geom in regions.items():
            _, cls, ok, _ = legend[k]
            by_class.setdefault(cls, []).append(geom)
            flags[cls] = ok
        landuse = [(cls, flags[cls], shapely.union_all(g, grid_size=grid_size)) for cls, g in by_class.items()]
        cut = [g for _, ok, g in landuse if not ok]
        if cut:
            buildable = shapely.difference(frame, shapely.union_all(cut, grid_size=grid_size), grid_size=grid_size)
    return districts, landuse, buildable


def pattern_lines(style: DistrictStyle, district, region, rng: np.random.Generator) -> np.ndarray:
    """Generate, position and orient one district's pattern (Fig. 7 lines 3-4).

    Parameters
    ----------
    style : DistrictStyle
    district : shapely.Geometry
        The district's region as drawn in the map (m).
    region : shapely.Geometry
        Its buildable part (organic sites are seeded there).
    rng : numpy.random.Generator

    Returns
    -------
    numpy.ndarray of shapely.LineString
        Unclipped pattern lines covering the district.
    """
    bounds = district.bounds
    if style.pattern == "grid":
        return grid_lines(bounds, style.spacing, style.angle, style.offset)
    if style.pattern == "radial":
        centre = style.center or tuple(shapely.centroid(district).coords[0])
        reach = shapely.hausdorff_distance(shapely.points(centre), shapely.boundary(district))
        reach = max(shapely.distance(shapely.points(centre), shapely.boundary(district)), reach)
        return radial_lines(
            bounds,
            centre,
            rings=style.rings,
            ring_spacing=style.ring_spacing,
            spokes=style.spokes,
            angle=style.angle,
            max_radius=reach,
        )
    seeds = organic_sites(region, style.sites, rng, relax=style.relax, weights=style.weights)
    return organic_lines(region, seeds)


def major_network(styles, districts, buildable, rngs, *, merge: float = 0.3, grid_size: float = 1e-3):
    """Fig. 7: the areas enclosed by major roads and the major road segments.

    Parameters
    ----------
    styles : list of DistrictStyle
    districts : list of shapely.Geometry
        Region of each district (from the map), aligned with ``styles``.
    buildable : shapely.Geometry
        Where the city may be built (m).
    rngs : callable
        ``rngs(i)`` -> numpy.random.Generator of district ``i``.
    merge : float
        Cells smaller than ``merge`` times the district's typical cell (area,
        and width) dissolve into a neighbour.
    grid_size : float
        Snap-rounding grid (m).

    Returns
    -------
    dict
        ``cells`` (Polygons), ``cell_district`` (int), ``edges`` (LineStrings),
        ``edge_class`` (str), ``edge_district`` (int), ``edge_width`` (float),
        ``outline`` (Polygon or MultiPolygon), ``merged`` (int).
    """
    used = [i for i, g in enumerate(districts) if not g.is_empty]
    raw = np.array([districts[i] for i in used], dtype=object)
    regions = shapely.intersection(raw, buildable, grid_size=grid_size)
    keep = ~shapely.is_empty(regions) & (shapely.area(regions) > 0)
    used = [u for u, k in zip(used, keep) if k]
    raw, regions = raw[keep], regions[keep]
    lines, owner = [], []
    for k, i in enumerate(used):
        pat = pattern_lines(styles[i], raw[k], regions[k], rngs(i))
        along = 0.1 * min(v for v in styles[i].spacing if v > 0) if styles[i].pattern == "grid" else 1.0
        pieces, _ = clip_lines(pat, regions[k], along=along)
        lines.append(pieces)
        owner.append(np.full(len(pieces), k))
    lines_arr = np.concatenate(lines) if lines else np.empty(0, object)
    cells, region, noded = split_cells(regions, lines_arr, grid_size=grid_size)
    # thresholds: the grid cell when the pattern fixes it, else the median cell
    min_area = np.zeros(len(cells))
    min_width = np.zeros(len(cells))
    areas = shapely.area(cells)
    widths = 2 * areas / np.maximum(shapely.length(cells), 1e-12)
    for k, i in enumerate(used):
        sel = region == k
        size = styles[i].cell_size()
        if size is None and sel.any():
            size = (float(np.median(areas[sel])), float(np.median(widths[sel])) * 2)
        if size is not None:
            min_area[sel] = merge * size[0]
            min_width[sel] = merge * size[1] * 0.5
    cells, region, merged = merge_small_cells(cells, region, min_area, min_width, grid_size=grid_size)
    cell_district = np.asarray(used, dtype=np.int64)[region] if len(cells) else np.empty(0, np.int64)
    edges = cell_edges(cells, grid_size=grid_size, noded=noded)
    cls, dist, width = classify_edges(edges, cells, cell_district, {s.index: s.major_width for s in styles})
    outline = shapely.union_all(regions, grid_size=grid_size)
    log.info(
        "major roads: %d districts, %d pattern lines, %d areas (%d slivers merged), %d road segments",
        len(used),
        len(lines_arr),
        len(cells),
        merged,
        len(edges),
    )
    return {
        "cells": cells,
        "cell_district": cell_district,
        "edges": edges,
        "edge_class": cls,
        "edge_district": dist,
        "edge_width": width,
        "outline": outline,
        "merged": merged,
    }


def classify_edges(edges, cells, cell_district, widths: dict, *, offset: float = 0.05):
    """Class, district and width of each major road segment from the cells on its two sides.

    A segment with the same district on both sides is ``major``; one between
    two districts, or on the city's outline, is ``boundary`` and takes the
    wider of its districts' widths.
    """
    n = len(edges)
    if n == 0:
        return np.empty(0, dtype="<U8"), np.empty(0, np.int64), np.empty(0, float)
    left, right = side_points(edges, offset)
    tree = STRtree(cells)
    sides = []
    for pts in (left, right):
        d = np.full(n, -1, np.int64)
        pi, ci = tree.query(pts, predicate="within")
        d[pi] = cell_district[ci]
        sides.append(d)
    dl, dr = sides
    cls = np.where(dl == dr, "major", "boundary").astype("<U8")
    dist = np.where(dl >= 0, dl, dr)
    wl = np.array([widths.get(int(d), 0.0) for d in dl])
    wr = np.array([widths.get(int(d), 0.0) for d in dr])
    return cls, dist, np.maximum(wl, wr)


@register
class RoadsDistricts(SENode):
    """Districts and major roads from the district and land-use maps (paper 002 §5.3.1, Fig. 7).

    Each district's pattern (grid, radial or organic) is generated,
    positioned, clipped to the district's region and merged with the
    district borders; the land-use map cuts out water and parks, whose
    borders become roads too.  Without a district map the whole extent is
    one district styled by the first ``<district>`` rule.
    """

    name = "roads.districts"
    inputs = {
        "district_rules": Port("rules", "the <district> rules (one default district when none)", required=False),
        "landuse_rules": Port("rules", "the <landuse> rules: the land-use map's legend", required=False),
        "district_map": Port("raster", "the district map (none: the whole city is one district)", required=False),
        "landuse_map": Port("raster", "the land-use map (none: everything is buildable)", required=False),
    }
    outputs = {
        "areas": Port("areas", "polygons enclosed by major roads, with their district"),
        "roads": Port("roads", "major road segments between junctions (class major / boundary)"),
        "outline": Port("outline", "the buildable city: extent minus land-use cut-outs"),
        "parks": Port("parks", "district-level parks from the land-use map's park class"),
        "landuse": Port("polygons", "non-buildable land-use regions (water ...), column kind"),
    }
    params = {
        "merge": Param(
            "float",
            0.3,
            min=0.0,
            max=1.0,
            unit="1",
            doc="areas under this share of the district's typical area merge into a neighbour",
        ),
        "simplify": Param(
            "float", 1.0, min=0.0, max=20.0, unit="px", doc="simplification of the map regions' pixel staircase"
        ),
        "grid": Param("float", 0.001, min=1e-6, max=1.0, unit="m", doc="snap-rounding grid of the noding"),
    }

    def check(
        self,
        *,
        district_rules: Layer | None = None,
        landuse_rules: Layer | None = None,
        district_map: Layer | None = None,
        landuse_map: Layer | None = None,
    ) -> None:
        """Every colour of the maps is in the rules (what ``sengine validate`` checks)."""
        self._regions(district_rules, landuse_rules, district_map, landuse_map, vector=False)

    def _regions(self, district_rules, landuse_rules, district_map, landuse_map, *, vector: bool = True):
        styles = district_styles(district_rules)
        if district_map is not None and not len(district_map):
            district_map = None
        if landuse_map is not None and not len(landuse_map):
            landuse_map = None
        given = (district_rules, district_map, landuse_map, landuse_rules)
        meta = next((lay.meta for lay in given if lay is not None and "extent" in lay.meta), None)
        meta = {k: v for k, v in (meta or plan_meta(CityPlan())).items() if k in ("crs", "origin", "extent")}
        legend = landuse_classes(landuse_rules) if landuse_map is not None else []
        tol = [
            None if m is None or m["tolerance"][0] < 0 else float(m["tolerance"][0])
            for m in (district_map, landuse_map)
        ]
        if not vector:  # only the legend checks and the estimates
            x0, y0, x1, y1 = meta["extent"]
            areas = [(x1 - x0) * (y1 - y0)] + [0.0] * (len(styles) - 1)
            for img, colours, names, what, t in (
                (
                    image_of(district_map),
                    [s.colour for s in styles],
                    [s.name for s in styles],
                    "district rules",
                    tol[0],
                ),
                (image_of(landuse_map), [c for c, *_ in legend], [c for _, c, *_ in legend], "land-use rules", tol[1]),
            ):
                if img is not None:
                    if what == "district rules" and any(c is None for c in colours):
                        raise ConfigError(
                            "<district> needs a color attribute when the plan has a district map",
                            where=next(s.where for s in styles if s.colour is None) or None,
                        )
                    labels = classify(img, colours, tolerance=t, names=names, what=what)
                    if what == "district rules":
                        px = img.pixel_size[0] * img.pixel_size[1]
                        areas = list(np.bincount(labels.ravel(), minlength=len(styles)) * px)
            check_estimates(styles, areas, meta["extent"])
            return None
        regions = city_regions(
            meta["extent"],
            styles,
            district_map=image_of(district_map),
            landuse_map=image_of(landuse_map),
            legend=legend if landuse_map is not None else None,
            district_tolerance=tol[0],
            landuse_tolerance=tol[1],
            simplify=self.p.simplify,
            grid_size=self.p.grid,
        )
        return styles, regions, meta

    def run(
        self,
        *,
        district_rules: Layer | None = None,
        landuse_rules: Layer | None = None,
        district_map: Layer | None = None,
        landuse_map: Layer | None = None,
    ):
        if district_map is None or not len(district_map):
            # one district over the whole extent: refuse an absurd spacing before anything is drawn
            lay = next((x for x in (district_rules, landuse_map) if x is not None and "extent" in x.meta), None)
            if lay is not None:
                x0, y0, x1, y1 = lay.meta["extent"]
                styles = district_styles(district_rules)
                check_estimates(styles, [(x1 - x0) * (y1 - y0)] + [0.0] * (len(styles) - 1), lay.meta["extent"])
        styles, (districts, landuse, buildable), meta = self._regions(
            district_rules, landuse_rules, district_map, landuse_map
        )
        check_estimates(styles, [float(shapely.area(d)) for d in districts], meta["extent"])
        if buildable.is_empty or buildable.area <= 0:
            log.warning("%s: the land-use map leaves nothing buildable: the city is empty", self.where)
        net = major_network(
            styles, districts, buildable, lambda i: self.rng(i), merge=self.p.merge, grid_size=self.p.grid
        )
        names = np.array([s.name for s in styles])
        pats = np.array([s.pattern for s in styles])
        cd = net["cell_district"]
        areas = Layer.from_geoms(
            net["cells"],
            meta=meta,
            district=cd,
            name=names[cd] if len(cd) else np.empty(0, "<U1"),
            pattern=pats[cd] if len(cd) else np.empty(0, "<U1"),
            area=shapely.area(net["cells"]),
        )
        roads = Layer.from_geoms(
            net["edges"],
            meta=meta,
            **{"class": net["edge_class"]},
            major=np.ones(len(net["edges"]), bool),
            width=net["edge_width"],
            district=net["edge_district"],
        )
        outline = Layer.from_geoms([net["outline"]], meta=meta, kind="outline")
        park_geoms = [g for cls, _, g in landuse if cls == "park"]
        parks_parts = shapely.get_parts(np.array(park_geoms, dtype=object)) if park_geoms else np.empty(0, object)
        parks = Layer.from_geoms(
            parks_parts,
            meta=meta,
            level=np.full(len(parks_parts), "district"),
            district=_district_at(parks_parts, districts),
            area=shapely.area(parks_parts) if len(parks_parts) else np.empty(0),
        )
        cut = [(cls, g) for cls, ok, g in landuse if not ok and cls != "park"]
        lu_geoms, lu_kind = [], []
        for cls, g in cut:
            parts = shapely.get_parts(g)
            lu_geoms += list(parts)
            lu_kind += [cls] * len(parts)
        lu = Layer.from_geoms(
            lu_geoms, meta=meta, kind=np.array(lu_kind, dtype=object).astype(str) if lu_kind else np.empty(0, "<U1")
        )
        report = {
            "districts": int(sum(not g.is_empty for g in districts)),
            "areas": len(areas),
            "merged_slivers": int(net["merged"]),
            "major_roads_km": round(float(shapely.length(net["edges"]).sum()) / 1000.0, 3),
            "buildable_km2": round(float(net["outline"].area) / 1e6, 4),
            "parks": len(parks),
        }
        return NodeResult({"areas": areas, "roads": roads, "outline": outline, "parks": parks, "landuse": lu}, report)


def _district_at(geoms, districts) -> np.ndarray:
    """District index under each geometry's inner point (-1 none)."""
    out = np.full(len(geoms), -1, np.int64)
    if len(geoms) == 0:
        return out
    pts = shapely.point_on_surface(np.asarray(geoms, dtype=object))
    for i, d in enumerate(districts):
        if not d.is_empty:
            out[shapely.within(pts, d)] = i
    return out

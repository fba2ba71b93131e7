"""Minor roads: skylineEngine §5.3.2.

"As they usually consist of small regular grids bound by avenues (the major
roads), we simply compute the intersection of each area with a regular grid
... the user is free to specify either a fixed angle for the major areas in
each district, or leave the system to choose a random angle for each grid."

Each area enclosed by major roads gets its district's minor grid
(``minor-spacing`` "dx dy" in m, ``minor-angle`` in deg, ``follow`` or
``random``); all grids of all areas are cut in one vectorized
``shapely.intersection``, noded with the major roads and polygonized; strips
thinner than ``merge`` times the grid cell dissolve into a neighbour, so a
grid line that runs close to an avenue leaves no sliver block.  The output is
every street segment between junctions, major and minor, as one planar graph.

References
----------
§5.3.2 (minor roads) of [1]_.

.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
"""

from __future__ import annotations

import logging

import numpy as np
import shapely
from shapely import STRtree

from sengine import Layer, NodeResult, Param, Port, SENode, register

from .districts import DistrictStyle, district_styles
from .patterns import cell_edges, clip_lines, grid_lines, merge_small_cells, side_points, split_cells

__all__ = ["minor_grid", "minor_network", "main_angle", "RoadsMinor"]

log = logging.getLogger(__name__)


def main_angle(polygons) -> np.ndarray:
    """Direction of the long side of each polygon's minimum rotated rectangle (deg)."""
    rect = shapely.oriented_envelope(np.asarray(polygons, dtype=object))
    xy, idx = shapely.get_coordinates(rect, return_index=True)
    out = np.zeros(len(rect))
    first = np.searchsorted(idx, np.arange(len(rect)))
    ok = (first + 2 < len(xy)) & (shapely.get_type_id(rect) == 3)
    p0, p1, p2 = xy[first[ok]], xy[first[ok] + 1], xy[first[ok] + 2]
    a, b = p1 - p0, p2 - p1
    la, lb = np.hypot(*a.T), np.hypot(*b.T)
    d = np.where((la >= lb)[:, None], a, b)
    out[ok] = np.degrees(np.arctan2(d[:, 1], d[:, 0]))
    return out


def minor_grid(areas, district, styles: list[DistrictStyle], rng_of) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grid lines of every area, ready to be cut in one call.

    Angle and position per area: ``follow`` takes the district's major grid
    angle and crossing (``offset``), so minor lines continue the avenues'
    grid, or for radial and organic districts the long side of the area's
    minimum rotated rectangle, starting at the area's centroid; a number is
    that angle at the district's ``offset``; ``random`` draws the angle
    uniformly in [0, 180) deg and the position in one grid cell from
    ``rng_of(i)`` (the generator of area ``i``).

    Returns
    -------
    lines : numpy.ndarray of shapely.LineString
    owner : numpy.ndarray of int
        Area index of each line.
    angle : numpy.ndarray of float
        The grid angle used for each area (deg).
    """
    areas = np.asarray(areas, dtype=object)
    n = len(areas)
    angles = np.zeros(n)
    long_side = main_angle(areas) if n else np.zeros(0)
    lines, owner = [], []
    cent = shapely.centroid(areas)
    for i in range(n):
        st = styles[district[i]] if 0 <= district[i] < len(styles) else styles[0]
        dx, dy = st.minor_spacing
        if st.minor_angle == "random":
            rng = rng_of(i)
            angle = float(rng.uniform(0.0, 180.0))
            c = cent[i]
            origin = (c.x + rng.uniform(0, dx or 1.0), c.y + rng.uniform(0, dy or 1.0))
        elif st.minor_angle == "follow":
            if st.pattern == "grid":
                angle, origin = st.angle, st.offset
            else:
                angle, origin = float(long_side[i]), (cent[i].x, cent[i].y)
        else:
            angle, origin = float(st.minor_angle), st.offset
        angles[i] = angle
        g = grid_lines(areas[i].bounds, (dx, dy), angle, origin)
        lines.append(g)
        owner.append(np.full(len(g), i, np.int64))
    if not lines:
        return np.empty(0, object), np.empty(0, np.int64), angles
    return np.concatenate(lines), np.concatenate(owner), angles


def minor_network(
    areas, district, major, major_attrs: dict, styles, rng_of, *, merge: float = 0.3, grid_size: float = 1e-3
):
    """Cut each area with its minor grid and node everything into street segments.

    Parameters
    ----------
    areas : array_like of shapely.Polygon
        Areas enclosed by major roads (m).
    district : array_like of int
        District of each area.
    major : array_like of shapely.LineString
        The major roads.
    major_attrs : dict of str to numpy.ndarray
        Columns of ``major`` to copy onto the major segments of the output.
    styles : list of DistrictStyle
    rng_of : callable
        ``rng_of(i)`` -> generator for area ``i``.
    merge : float
        Blocks under ``merge * dx * dy`` or thinner than ``merge * min(dx, dy)`` merge.
    grid_size : float
        Snap-rounding grid (m).

    Returns
    -------
    dict
        ``edges``, ``major`` (bool), ``source`` (index into ``major`` or -1),
        ``district``, ``cells``, ``cell_area`` (area index), ``merged``.
    """
    areas = np.asarray(areas, dtype=object)
    district = np.asarray(district, np.int64)
    major = np.asarray(major, dtype=object)
    lines, owner, _ = minor_grid(areas, district, styles, rng_of)
    dist_style = [styles[d] if 0 <= d < len(styles) else styles[0] for d in district]
    spacing = np.array([s.minor_spacing for s in dist_style]).reshape(-1, 2)
    pos = np.where(spacing > 0, spacing, np.inf).min(axis=1) if len(spacing) else np.zeros(0)
    pieces, src = clip_lines(lines, areas[owner], along=0.0)
    if len(pieces):
        # drop pieces lying along their area's border (a minor line on an avenue)
        rings = shapely.boundary(areas[owner[src]])
        tol = 0.1 * pos[owner[src]]
        near = np.ones(len(pieces), bool)
        for f in (0.25, 0.5, 0.75):
            near &= shapely.distance(shapely.line_interpolate_point(pieces, f, normalized=True), rings) < tol
        pieces = pieces[~near]
    # the major roads are the areas' borders, each once; if they do not close every
    # area (roads from elsewhere), fall back to the areas' own boundaries
    cells, cell_area, noded = split_cells(areas, pieces, grid_size=grid_size, borders=major if len(major) else None)
    if len(major) and abs(shapely.area(cells).sum() - shapely.area(areas).sum()) > 1e-6 * shapely.area(areas).sum():
        log.warning("roads.minor: the major roads do not enclose every area; using the areas' boundaries")
        cells, cell_area, noded = split_cells(areas, np.concatenate([pieces, major]), grid_size=grid_size)
    full = np.prod(np.where(spacing > 0, spacing, np.nan), axis=1) if len(spacing) else np.zeros(0)
    full = np.where(np.isfinite(full), full, pos**2)
    cells, cell_area, merged = merge_small_cells(
        cells, cell_area, merge * full[cell_area], merge * pos[cell_area], grid_size=grid_size
    )
    edges = cell_edges(cells, grid_size=grid_size, noded=noded)
    n = len(edges)
    source = np.full(n, -1, np.int64)
    if n and len(major):
        mids = shapely.line_interpolate_point(edges, 0.5, normalized=True)
        ei, mi = STRtree(major).query_nearest(mids, max_distance=max(10 * grid_size, 1e-6), all_matches=False)
        source[ei] = mi
    is_major = source >= 0
    edist = np.full(n, -1, np.int64)
    if n:
        left, right = side_points(edges, 0.05)
        tree = STRtree(cells)
        for pts in (right, left):
            pi, ci = tree.query(pts, predicate="within")
            edist[pi] = district[cell_area[ci]]
    if "district" in major_attrs and is_major.any():
        edist[is_major] = np.asarray(major_attrs["district"])[source[is_major]]
    log.info(
        "minor roads: %d grid lines, %d pieces, %d blocks (%d slivers merged), %d segments (%d minor)",
        len(lines),
        len(pieces),
        len(cells),
        merged,
        n,
        int((~is_major).sum()),
    )
    return {
        "edges": edges,
        "major": is_major,
        "source": source,
        "district": edist,
        "cells": cells,
        "cell_area": cell_area,
        "merged": merged,
    }


@register
class RoadsMinor(SENode):
    """Minor roads: each area enclosed by major roads cut by its district's regular grid (paper 002 §5.3.2).

    The grid's spacing, angle (fixed, ``follow`` the major grid, or
    ``random`` per area) and street width come from the district rules
    (``minor-spacing``, ``minor-angle``, ``minor-width``).  Outputs every
    street segment, major and minor, noded into one planar graph.
    """

    name = "roads.minor"
    inputs = {
        "areas": Port("areas", "areas enclosed by major roads, with their district"),
        "roads": Port("roads", "the major roads"),
        "district_rules": Port(
            "rules", "the <district> rules: minor-spacing, minor-angle, minor-width", required=False
        ),
    }
    outputs = {
        "roads": Port("roads", "all street segments between junctions (major and minor)"),
        "areas": Port("areas", "the areas, passed through"),
    }
    params = {
        "merge": Param(
            "float",
            0.3,
            min=0.0,
            max=1.0,
            unit="1",
            doc="blocks under this share of the grid cell (area, or width) merge into a neighbour",
        ),
        "grid": Param("float", 0.001, min=1e-6, max=1.0, unit="m", doc="snap-rounding grid of the noding"),
    }

    def run(self, *, areas: Layer, roads: Layer, district_rules: Layer | None = None):
        styles = district_styles(district_rules)
        district = np.asarray(areas["district"], np.int64) if "district" in areas else np.zeros(len(areas), np.int64)
        ids = areas.ids
        net = minor_network(
            areas.geometry,
            district,
            roads.geometry,
            dict(roads.attrs),
            styles,
            lambda i: self.rng(int(ids[i])),
            merge=self.p.merge,
            grid_size=self.p.grid,
        )
        n = len(net["edges"])
        src, is_major = net["source"], net["major"]
        cls = np.full(n, "minor", dtype=object)
        width = np.array(
            [styles[d].minor_width if 0 <= d < len(styles) else styles[0].minor_width for d in net["district"]],
            dtype=float,
        )
        if "class" in roads and is_major.any():
            cls[is_major] = np.asarray(roads["class"]).astype(str)[src[is_major]]
        elif is_major.any():
            cls[is_major] = "major"
        if "width" in roads and is_major.any():
            width[is_major] = np.asarray(roads["width"], float)[src[is_major]]
        meta = dict(roads.meta or areas.meta)
        out = Layer.from_geoms(
            net["edges"],
            meta=meta,
            **{"class": cls.astype(str) if n else np.empty(0, "<U5")},
            major=is_major,
            width=width,
            district=net["district"],
        )
        report = {
            "minor_segments": int((~is_major).sum()),
            "major_segments": int(is_major.sum()),
            "blocks_estimate": len(net["cells"]),
            "merged_slivers": int(net["merged"]),
            "minor_roads_km": round(float(shapely.length(net["edges"][~is_major]).sum()) / 1000.0, 3) if n else 0.0,
        }
        return NodeResult({"roads": out, "areas": areas}, report)

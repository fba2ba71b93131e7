"""Street patterns and the planar cells they cut (skylineEngine §5.3, Fig. 7).

Pure functions, no engine imports: each takes plain numbers, shapely
geometries and an explicit ``numpy.random.Generator`` and returns numpy arrays
of shapely geometries, in metres.

* :func:`grid_lines`, :func:`radial_lines`, :func:`organic_lines` generate a
  pattern over a region ("generate pattern; position and orient it");
* :func:`clip_lines` cuts the pattern to a region ("Clip(pattern, bounds)")
  and drops pieces that run along the region's border, which would only
  double it;
* :func:`split_cells` merges region borders and pattern into one noded
  linework and polygonizes it ("Merge(finalP, bounds)", "Merge(finalP,
  currMap)"); :func:`merge_small_cells` dissolves slivers left where a pattern
  line passes close to a border; :func:`cell_edges` gives the street segments
  between junctions.

References
----------
§5.3.1 (districts), §5.3.2 (minor roads) and Fig. 7 of [1]_; the organic pattern's Lloyd relaxation [2]_ with a density function [3]_.

.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
.. [2] S. Lloyd, "Least squares quantization in PCM", IEEE Transactions on
   Information Theory 28(2), 129-137, 1982.
.. [3] Q. Du, V. Faber and M. Gunzburger, "Centroidal Voronoi tessellations:
   applications and algorithms", SIAM Review 41(4), 637-676, 1999.
"""

from __future__ import annotations

import heapq
import math

import numpy as np
import shapely
from shapely import STRtree

__all__ = [
    "grid_lines",
    "radial_lines",
    "organic_sites",
    "nearest_site",
    "organic_lines",
    "clip_lines",
    "split_cells",
    "merge_small_cells",
    "cell_edges",
    "side_points",
]


def _cover_radius(bounds, centre) -> float:
    xmin, ymin, xmax, ymax = bounds
    cx, cy = centre
    return float(max(math.hypot(x - cx, y - cy) for x in (xmin, xmax) for y in (ymin, ymax))) + 1.0


def grid_lines(bounds, spacing, angle: float = 0.0, origin=(0.0, 0.0)) -> np.ndarray:
    """Lines of a regular grid covering ``bounds``.

    The grid's frame is turned ``angle`` degrees counter-clockwise about
    ``origin``; in that frame the lines are ``x' = i * dx`` (spaced ``dx``
    apart) and ``y' = j * dy``.  A spacing of 0 leaves out that family.

    Parameters
    ----------
    bounds : tuple of float
        ``(xmin, ymin, xmax, ymax)`` to cover (m).
    spacing : tuple of float
        ``(dx, dy)`` between lines (m).
    angle : float
        Rotation of the grid (deg, counter-clockwise from east).
    origin : tuple of float
        A grid intersection (m): the pattern's position.

    Returns
    -------
    numpy.ndarray of shapely.LineString
    """
    dx, dy = (float(v) for v in spacing)
    ox, oy = (float(v) for v in origin)
    cx, cy = (bounds[0] + bounds[2]) / 2.0, (bounds[1] + bounds[3]) / 2.0
    r = _cover_radius(bounds, (cx, cy))
    t = math.radians(angle)
    u = np.array([math.cos(t), math.sin(t)])  # x' axis
    v = np.array([-math.sin(t), math.cos(t)])  # y' axis
    # the covering disc's centre in the grid frame
    pc = np.array([cx - ox, cy - oy])
    uc, vc = pc @ u, pc @ v
    out = []
    for step, along, across, c_across, c_along in ((dx, v, u, uc, vc), (dy, u, v, vc, uc)):
        if step <= 0:
            continue
        k = np.arange(math.floor((c_across - r) / step), math.ceil((c_across + r) / step) + 1)
        offs = k * step
        base = np.array([ox, oy]) + offs[:, None] * across[None, :]
        a = base + (c_along - r) * along
        b = base + (c_along + r) * along
        out.append(shapely.linestrings(np.stack([a, b], axis=1)))
    return np.concatenate(out) if out else np.empty(0, object)


def radial_lines(
    bounds,
    centre,
    *,
    rings: int = 4,
    ring_spacing: float | None = None,
    spokes: int = 8,
    angle: float = 0.0,
    max_radius: float | None = None,
    chord: float = 40.0,
) -> np.ndarray:
    """Concentric rings and straight spokes around ``centre``.

    Parameters
    ----------
    bounds : tuple of float
        ``(xmin, ymin, xmax, ymax)`` to cover (m).
    centre : tuple of float
        The pattern's centre (m).
    rings : int
        Number of rings (used when ``ring_spacing`` is None): ring ``k`` has
        radius ``k * max_radius / (rings + 1)``.
    ring_spacing : float, optional
        Distance between rings (m).
    spokes : int
        Number of spokes, evenly spread round the circle.
    angle : float
        Bearing of the first spoke (deg, counter-clockwise from east).
    max_radius : float, optional
        Radius the rings fill (m); default the farthest corner of ``bounds``.
    chord : float
        Largest chord of the polygons approximating the rings (m).

    Returns
    -------
    numpy.ndarray of shapely.LineString
    """
    cx, cy = (float(v) for v in centre)
    reach = _cover_radius(bounds, (cx, cy))
    rmax = float(max_radius) if max_radius else reach
    if ring_spacing:
        radii = np.arange(1, int(rmax // ring_spacing) + 1) * float(ring_spacing)
    else:
        radii = rmax * np.arange(1, rings + 1) / (rings + 1) if rings > 0 else np.empty(0)
    out = []
    for rad in radii:
        n = max(12, int(math.ceil(2 * math.pi * rad / chord)))
        th = np.linspace(0.0, 2 * math.pi, n + 1) + math.radians(angle)
        ring = np.stack([cx + rad * np.cos(th), cy + rad * np.sin(th)], axis=1)
        ring[-1] = ring[0]
        out.append(shapely.linestrings(ring))
    if spokes > 0:
        th = math.radians(angle) + 2 * math.pi * np.arange(spokes) / spokes
        ends = np.stack([cx + reach * np.cos(th), cy + reach * np.sin(th)], axis=1)
        starts = np.repeat([[cx, cy]], spokes, axis=0)
        out.extend(shapely.linestrings(np.stack([starts, ends], axis=1)))
    arr = np.empty(len(out), dtype=object)
    arr[:] = out
    return arr


def _density(pts: np.ndarray, region, weights: float, rng: np.random.Generator) -> np.ndarray:
    """A smooth random density ``exp(weights * z)``, ``z`` in about [-1, 1]."""
    if weights <= 0:
        return np.ones(len(pts))
    xmin, ymin, xmax, ymax = region.bounds
    size = max(xmax - xmin, ymax - ymin)
    k = 5
    cx = rng.uniform(xmin, xmax, k)
    cy = rng.uniform(ymin, ymax, k)
    sign = rng.choice([-1.0, 1.0], k)
    sigma = size * rng.uniform(0.15, 0.35, k)
    d2 = (pts[:, :1] - cx) ** 2 + (pts[:, 1:] - cy) ** 2
    z = (sign * np.exp(-d2 / (2 * sigma**2))).sum(axis=1)
    z = z / max(np.abs(z).max(), 1e-9)
    return np.exp(weights * z)


def organic_sites(
    region,
    sites: int,
    rng: np.random.Generator,
    *,
    relax: int = 3,
    weights: float = 0.0,
    samples_per_site: int = 200,
) -> np.ndarray:
    """Seed points relaxed with Lloyd's algorithm inside ``region`` [2]_.

    Notes
    -----
    The region is covered by a regular lattice of about
    ``samples_per_site * sites`` sample points.  Each Lloyd iteration gives
    every sample to its nearest site (a discrete Voronoi diagram,
    :func:`nearest_site`) and moves each site to the density-weighted
    mean of its samples.  With ``weights = 0`` the density is uniform and
    this is Lloyd's algorithm; with ``weights > 0`` the density is a smooth
    random field ``exp(weights * z)`` and the sites converge to a centroidal
    Voronoi tessellation of that density: cells are small where it is high
    and large where it is low.  This stands in for the paper's *weighted*
    Voronoi diagram (a power diagram is not used).

    Parameters
    ----------
    region : shapely.Polygon or shapely.MultiPolygon
        Where the sites live (m).
    sites : int
        Number of sites.
    rng : numpy.random.Generator
        Source of randomness.
    relax : int
        Lloyd iterations.
    weights : float
        Strength of the density variation (0 = uniform).
    samples_per_site : int
        Lattice points per site.

    Returns
    -------
    numpy.ndarray, shape (n, 2)
    """
    if sites <= 0 or region.is_empty:
        return np.empty((0, 2))
    xmin, ymin, xmax, ymax = region.bounds
    step = math.sqrt(max(region.area, 1e-9) / (samples_per_site * sites))
    gx = np.arange(xmin + step / 2, xmax, step)
    gy = np.arange(ymin + step / 2, ymax, step)
    xx, yy = np.meshgrid(gx, gy)
    pts = np.stack([xx.ravel(), yy.ravel()], axis=1)
    pts = pts[shapely.contains_xy(region, pts[:, 0], pts[:, 1])]
    if len(pts) == 0:
        return np.empty((0, 2))
    dens = _density(pts, region, weights, rng)
    n = min(sites, len(pts))
    pick = rng.choice(len(pts), size=n, replace=False, p=dens / dens.sum())
    seeds = pts[pick] + rng.uniform(-step / 2, step / 2, (n, 2))
    for _ in range(max(relax, 0)):
        owner = nearest_site(pts, seeds)
        w = np.bincount(owner, weights=dens, minlength=n)
        mx = np.bincount(owner, weights=dens * pts[:, 0], minlength=n)
        my = np.bincount(owner, weights=dens * pts[:, 1], minlength=n)
        ok = w > 0
        seeds[ok] = np.stack([mx[ok] / w[ok], my[ok] / w[ok]], axis=1)
    return seeds


#: Up to this many sites, :func:`nearest_site` compares every sample with every site (numpy) rather than
#: build a k-d tree: the same answers, no ``scipy.spatial`` to import (0.1 s) for a district's few dozen sites.
BRUTE_FORCE_SITES = 256


def nearest_site(points: np.ndarray, sites: np.ndarray) -> np.ndarray:
    """Index of the nearest of ``sites`` to each of ``points`` (both (n, 2), m).

    Squared distances ``dx**2 + dy**2`` compared directly for a few sites (in
    chunks of about four million pairs), a ``scipy.spatial.cKDTree`` query
    for more; equally distant sites (a tie to the last bit) may go either way.
    """
    if len(sites) > BRUTE_FORCE_SITES:
        from scipy.spatial import cKDTree

        return cKDTree(sites).query(points)[1]
    out = np.empty(len(points), np.int64)
    chunk = max(1, (1 << 22) // max(len(sites), 1))
    for s in range(0, len(points), chunk):
        p = points[s : s + chunk]
        d = (p[:, None, 0] - sites[None, :, 0]) ** 2 + (p[:, None, 1] - sites[None, :, 1]) ** 2
        out[s : s + chunk] = d.argmin(axis=1)
    return out


def organic_lines(region, seeds: np.ndarray) -> np.ndarray:
    """The edges of the Voronoi diagram of ``seeds`` around ``region`` (m)."""
    if len(seeds) < 2:
        return np.empty(0, object)
    env = shapely.envelope(region).buffer(10.0 + math.sqrt(region.area))
    edges = shapely.voronoi_polygons(shapely.multipoints(seeds), extend_to=env, only_edges=True)
    parts = shapely.get_parts(edges)
    return np.asarray(parts, dtype=object)


def clip_lines(lines, regions, *, along: float = 1.0):
    """Cut lines to regions and drop the pieces that lie along a region's border.

    Parameters
    ----------
    lines : array_like of shapely.LineString
        Pattern lines.
    regions : shapely.Geometry or array_like of shapely.Geometry
        One region for all lines, or one per line (one vectorized
        ``shapely.intersection`` either way).
    along : float
        A piece whose middle is closer than this to its region's border, and
        whose two ends also are, runs along the border and is dropped (m).

    Returns
    -------
    pieces : numpy.ndarray of shapely.LineString
    index : numpy.ndarray of int
        For each piece, the index of the line it came from.
    """
    lines = np.asarray(lines, dtype=object)
    if len(lines) == 0:
        return np.empty(0, object), np.empty(0, np.int64)
    if isinstance(regions, shapely.Geometry):
        shapely.prepare(regions)
    cut = shapely.intersection(lines, regions)
    parts, idx = shapely.get_parts(cut, return_index=True)
    keep = (shapely.get_type_id(parts) == 1) & (shapely.length(parts) > 1e-9)
    parts, idx = parts[keep], idx[keep]
    if len(parts) == 0 or along <= 0:
        return parts, idx
    rings = shapely.boundary(regions if isinstance(regions, shapely.Geometry) else np.asarray(regions, object)[idx])
    mids = shapely.line_interpolate_point(parts, 0.5, normalized=True)
    near = shapely.distance(mids, rings) < along
    # a short piece crossing a corner has its middle near the border too; it is
    # a real street only if it leaves the border somewhere, so also test quarters
    for f in (0.25, 0.75):
        near &= shapely.distance(shapely.line_interpolate_point(parts, f, normalized=True), rings) < along
    return parts[~near], idx[~near]


def split_cells(regions, lines, *, grid_size: float = 1e-3, borders=None):
    """Polygonize region borders plus lines into cells.

    Parameters
    ----------
    regions : array_like of shapely.Polygon or shapely.MultiPolygon
        Disjoint regions (m); each cell falls in exactly one.
    lines : array_like of shapely.LineString
        Lines inside the regions (already clipped).
    grid_size : float
        Snap-rounding grid of the noding (m).
    borders : array_like of shapely.LineString, optional
        The regions' borders when known as lines (each shared border once);
        default the regions' boundaries.

    Returns
    -------
    cells : numpy.ndarray of shapely.Polygon
    region : numpy.ndarray of int
        Index of each cell's region.
    noded : numpy.ndarray of shapely.LineString
        The noded linework the cells were made of (for :func:`cell_edges`).
    """
    regions = np.asarray(regions, dtype=object)
    lines = np.asarray(lines, dtype=object)
    rim = shapely.boundary(regions) if borders is None else np.asarray(borders, dtype=object)
    work = np.concatenate([rim, lines]) if len(lines) else rim
    noded = np.asarray(shapely.get_parts(shapely.union_all(work, grid_size=grid_size)), dtype=object)
    faces = np.asarray(shapely.get_parts(shapely.polygonize(noded)), dtype=object)
    if len(faces) == 0:
        return faces, np.empty(0, np.int64), noded
    pts = shapely.point_on_surface(faces)
    fi, ri = STRtree(regions).query(pts, predicate="within")
    region = np.full(len(faces), -1, np.int64)
    region[fi] = ri
    keep = region >= 0
    return faces[keep], region[keep], noded


def cell_width(cells) -> np.ndarray:
    """``2 A / P``: about the short side of a long cell (m)."""
    return 2.0 * shapely.area(cells) / np.maximum(shapely.length(cells), 1e-12)


def merge_small_cells(cells, region, min_area, min_width, *, grid_size: float = 1e-3):
    """Dissolve small or thin cells into a neighbour of the same region.

    A cell is small when its area is below ``min_area`` or its width
    (``2 A / P``) below ``min_width``; smallest first, it joins the neighbour
    in its region with which it shares the longest border.  A cell with no
    such neighbour stays.

    Parameters
    ----------
    cells : array_like of shapely.Polygon
    region : array_like of int
        Region of each cell; cells merge only within a region.
    min_area, min_width : float or array_like of float
        Thresholds per cell (m2, m), or one for all.
    grid_size : float
        Snap-rounding grid of the unions (m).

    Returns
    -------
    cells : numpy.ndarray of shapely.Polygon
    region : numpy.ndarray of int
    merged : int
        How many cells were dissolved.
    """
    cells = np.asarray(cells, dtype=object).copy()
    region = np.asarray(region, dtype=np.int64)
    n = len(cells)
    if n == 0:
        return cells, region, 0
    min_area = np.broadcast_to(np.asarray(min_area, float), (n,)).copy()
    min_width = np.broadcast_to(np.asarray(min_width, float), (n,)).copy()

    def small(i: int) -> bool:
        g = cells[i]
        return g.area < min_area[i] or 2.0 * g.area / max(g.length, 1e-12) < min_width[i]

    area = shapely.area(cells)
    flag = (area < min_area) | (cell_width(cells) < min_width)
    if not flag.any():
        return cells, region, 0
    tree = STRtree(cells.copy())
    owner = np.arange(n)

    def find(i: int) -> int:
        while owner[i] != i:
            owner[i] = owner[owner[i]]
            i = owner[i]
        return i

    heap = [(float(area[i]), int(i)) for i in np.flatnonzero(flag)]
    heapq.heapify(heap)
    merged = 0
    while heap:
        a, i = heapq.heappop(heap)
        if find(i) != i or abs(cells[i].area - a) > 1e-6 * max(a, 1.0) or not small(i):
            continue
        cand = {find(int(j)) for j in tree.query(cells[i], predicate="intersects")}
        cand = np.array([j for j in cand if j != i and region[j] == region[i]], dtype=np.int64)
        if len(cand) == 0:
            continue
        shared = shapely.length(shapely.intersection(shapely.boundary(cells[i]), shapely.boundary(cells[cand])))
        if shared.max() <= grid_size * 10:
            continue
        j = int(cand[int(np.argmax(shared))])
        cells[j] = _polygonal(shapely.union(cells[j], cells[i], grid_size=grid_size))
        owner[i] = j
        merged += 1
        if small(j):
            heapq.heappush(heap, (cells[j].area, j))
    alive = np.array([find(i) == i for i in range(n)])
    out = cells[alive]
    # a union may come back as a MultiPolygon when two parts touch at a point only
    parts, idx = shapely.get_parts(out, return_index=True)
    return parts, region[alive][idx], merged


def _polygonal(geom):
    """The polygonal part of an overlay result.

    Snapped to a coarse grid, a thin piece of a union collapses to a line and
    the result is a mixed collection, which the next overlay refuses.
    """
    if geom.geom_type in ("Polygon", "MultiPolygon"):
        return geom
    parts = [p for p in shapely.get_parts(geom) if p.geom_type in ("Polygon", "MultiPolygon")]
    return shapely.union_all(parts) if parts else shapely.Polygon()


def cell_edges(cells, *, grid_size: float = 1e-3, noded=None) -> np.ndarray:
    """Street segments between junctions along the borders of ``cells``.

    The cell borders are noded together (or, given ``noded``, the linework
    the cells were polygonized from is kept where it lies on a cell border:
    pieces dissolved by :func:`merge_small_cells` and dangles drop out) and
    merged through every vertex of degree two, so each segment runs from one
    junction to the next.

    Returns
    -------
    numpy.ndarray of shapely.LineString
    """
    cells = np.asarray(cells, dtype=object)
    if noded is None:
        merged_in = shapely.union_all(shapely.boundary(cells), grid_size=grid_size)
    else:
        noded = np.asarray(noded, dtype=object)
        rims = shapely.boundary(cells)
        mids = shapely.line_interpolate_point(noded, 0.5, normalized=True)
        on = np.zeros(len(noded), bool)
        hit, _ = STRtree(rims).query(mids, predicate="dwithin", distance=grid_size * 1e-3)
        on[hit] = True
        merged_in = shapely.multilinestrings(noded[on])
    merged = shapely.line_merge(merged_in)
    parts = shapely.get_parts(merged)
    parts = parts[(shapely.get_type_id(parts) == 1) & (shapely.length(parts) > 0)]
    return np.asarray(parts, dtype=object)


def side_points(lines, offset: float) -> tuple[np.ndarray, np.ndarray]:
    """Points ``offset`` metres left and right of each line's middle."""
    lines = np.asarray(lines, dtype=object)
    length = shapely.length(lines)
    h = np.minimum(length / 4.0, 0.05)
    a = shapely.line_interpolate_point(lines, length / 2.0 - h)
    b = shapely.line_interpolate_point(lines, length / 2.0 + h)
    m = shapely.line_interpolate_point(lines, length / 2.0)
    ax, ay = shapely.get_x(a), shapely.get_y(a)
    bx, by = shapely.get_x(b), shapely.get_y(b)
    dx, dy = bx - ax, by - ay
    norm = np.maximum(np.hypot(dx, dy), 1e-12)
    nx, ny = -dy / norm * offset, dx / norm * offset
    mx, my = shapely.get_x(m), shapely.get_y(m)
    return shapely.points(mx + nx, my + ny), shapely.points(mx - nx, my - ny)

"""Road network from an image map: the ``majorRoads`` node for a drawn city plan.

skylineEngine lets the user "directly load a city map ... specified as a
simple image map" (002 §5.2, Fig. 6); the street network then goes on to the
blocks exactly as an OpenStreetMap one does (§5.3).  Roads are the pixels of
one colour (white on black by default).  They are thinned to one-pixel centre
lines (``skimage.morphology.skeletonize``), the skeleton pixels become a
graph (4-neighbours, and diagonal neighbours only where no 4-path joins
them, so no pixel triangles), the graph is cut into polylines between
junction and end pixels, and each polyline is placed on the city extent in
metres and simplified.

References
----------
.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import shapely

from sengine import Layer, NodeResult, Param, Port, SENode, register
from sengine.errors import InputDataError
from sengine.geom.crs import local_crs
from sengine.geom.raster import parse_colour, read_map

from ..maps import image_of

__all__ = ["road_mask", "skeleton_graph", "trace_polylines", "image_roads", "RoadsImage"]

log = logging.getLogger(__name__)


def road_mask(pixels: np.ndarray, colour: tuple[int, int, int], tolerance: float) -> np.ndarray:
    """Pixels within ``tolerance`` (Euclidean RGB distance, 0-441) of ``colour``."""
    px = pixels.astype(np.float64)
    if px.ndim == 2:
        px = np.repeat(px[:, :, None], 3, axis=2)
    d = np.sqrt(((px[:, :, :3] - np.asarray(colour, np.float64)) ** 2).sum(axis=2))
    return d <= tolerance


def skeleton_graph(skel: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pixel graph of a one-pixel-wide skeleton.

    Parameters
    ----------
    skel : ndarray of bool (rows, cols)

    Returns
    -------
    rc : ndarray of int (n, 2)
        Row and column of each skeleton pixel (node id = row index).
    u, v : ndarray of int64
        Edges: 4-neighbours always, diagonal neighbours only when neither of
        the two pixels sharing a side with both is on the skeleton.
    """
    rows, cols = skel.shape
    rc = np.argwhere(skel)
    ids = np.full(skel.shape, -1, np.int64)
    ids[rc[:, 0], rc[:, 1]] = np.arange(len(rc))
    pad = np.pad(ids, 1, constant_values=-1)
    on = pad >= 0
    us, vs = [], []
    r, c = rc[:, 0] + 1, rc[:, 1] + 1
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        nb = pad[r + dr, c + dc]
        ok = nb >= 0
        if dr and dc:  # diagonal: only when no 4-path (r, c+dc) or (r+dr, c) exists
            ok &= ~on[r, c + dc] & ~on[r + dr, c]
        us.append(ids[rc[ok, 0], rc[ok, 1]])
        vs.append(nb[ok])
    return rc, np.concatenate(us), np.concatenate(vs)


def trace_polylines(n: int, u: np.ndarray, v: np.ndarray) -> list[np.ndarray]:
    """Cut a graph into polylines that run between nodes of degree other than 2.

    Parameters
    ----------
    n : int
        Number of nodes.
    u, v : ndarray of int
        Edges.

    Returns
    -------
    list of ndarray of int
        Node ids of each polyline, in order; a loop of degree-2 nodes comes
        back to its start.
    """
    deg = np.bincount(np.r_[u, v], minlength=n)
    order = np.argsort(np.r_[u, v], kind="stable")
    other = np.r_[v, u][order]
    edge = np.r_[np.arange(len(u)), np.arange(len(u))][order]
    start = np.r_[0, np.cumsum(deg)]
    used = np.zeros(len(u), bool)
    lines: list[np.ndarray] = []

    def walk(a: int, k: int) -> None:
        path = [a]
        cur, e = int(other[k]), int(edge[k])
        used[e] = True
        path.append(cur)
        while deg[cur] == 2:
            nxt = None
            for kk in range(start[cur], start[cur + 1]):
                if not used[edge[kk]]:
                    nxt = kk
                    break
            if nxt is None:
                break
            used[edge[nxt]] = True
            cur = int(other[nxt])
            path.append(cur)
        lines.append(np.asarray(path, np.int64))

    for a in np.flatnonzero(deg != 2):
        for k in range(start[a], start[a + 1]):
            if not used[edge[k]]:
                walk(int(a), k)
    for e in np.flatnonzero(~used):  # loops made only of degree-2 nodes
        if not used[e]:
            a = int(u[e])
            k = next(kk for kk in range(start[a], start[a + 1]) if edge[kk] == e)
            walk(a, k)
    return lines


def image_roads(
    mask: np.ndarray, extent: tuple[float, float, float, float], *, simplify: float, min_length: float
) -> np.ndarray:
    """Street centre lines (m) of a boolean road mask placed on ``extent``.

    Parameters
    ----------
    mask : ndarray of bool (rows, cols)
        Road pixels; row 0 is the north edge.
    extent : (xmin, ymin, xmax, ymax)
        City extent (m) the image covers.
    simplify : float
        Douglas-Peucker tolerance (m) applied to each polyline.
    min_length : float
        Dead-end spurs shorter than this (m) are skeleton noise and dropped.

    Returns
    -------
    ndarray of shapely.LineString
    """
    from skimage.morphology import skeletonize

    skel = skeletonize(mask)
    rc, u, v = skeleton_graph(skel)
    if len(u) == 0:
        return np.empty(0, object)
    rows, cols = mask.shape
    xmin, ymin, xmax, ymax = extent
    x = xmin + (rc[:, 1] + 0.5) * (xmax - xmin) / cols
    y = ymax - (rc[:, 0] + 0.5) * (ymax - ymin) / rows
    xy = np.column_stack([x, y])
    paths = trace_polylines(len(rc), u, v)
    sizes = np.fromiter(map(len, paths), np.int64, len(paths))
    idx = np.concatenate(paths)
    lines = shapely.linestrings(xy[idx], indices=np.repeat(np.arange(len(paths)), sizes))
    # spurs: a polyline with a free end (degree-1 pixel) shorter than min_length
    deg = np.bincount(np.r_[u, v], minlength=len(rc))
    heads = idx[np.r_[0, np.cumsum(sizes)[:-1]]]
    tails = idx[np.cumsum(sizes) - 1]
    spur = ((deg[heads] == 1) | (deg[tails] == 1)) & (shapely.length(lines) < min_length)
    lines = lines[~spur]
    if simplify > 0:
        lines = shapely.simplify(lines, simplify, preserve_topology=False)
    return lines[~shapely.is_empty(lines) & (shapely.length(lines) > 0)]


@register
class RoadsImage(SENode):
    """Street network from a road-map image (roads drawn in one colour), skeletonized and vectorized.

    The ``majorRoads`` node for a drawn map (skylineEngine 002 §5.2): the
    image is the plan's ``<map kind="roads" src="..."/>`` (or ``path``),
    placed on the city extent; its ``color`` / ``tolerance`` attributes
    override the parameters.
    """

    name = "roads.image"
    inputs = {
        "roads_map": Port("raster", "the road-map image (<map kind='roads'>), on the city extent", required=False)
    }
    outputs = {"roads": Port("roads", "street centre lines traced from the image")}
    params = {
        "path": Param(
            "path", "", doc="road-map image read directly, on an extent of 'size'; empty: the roads_map port"
        ),
        "size": Param(
            "float", (2000.0, 2000.0), min=1.0, max=100_000.0, unit="m", count=2, doc="extent of an image given by path"
        ),
        "color": Param("str", "#ffffff", doc="colour of the roads in the image"),
        "tolerance": Param(
            "float", 96.0, min=0.0, max=442.0, unit="1", doc="largest RGB distance from 'color' still counted as road"
        ),
        "simplify": Param("float", -1.0, min=-1.0, max=1000.0, unit="m", doc="simplification tolerance; -1: one pixel"),
        "min_length": Param(
            "float", -1.0, min=-1.0, unit="m", doc="drop dead-end spurs shorter than this; -1: three pixels"
        ),
        "width": Param("float", 12.0, min=0.0, max=200.0, unit="m", doc="street width between block fronts"),
        "road_class": Param("str", "minor", choices=("major", "minor"), doc="class given to every street"),
    }

    def run(self, *, roads_map: Layer | None = None):
        where = self.where
        colour_text, tolerance = self.p.color, self.p.tolerance
        if self.p.path:
            src = Path(self.p.path)
            if not src.is_absolute() and self.context.base_dir is not None:
                src = Path(self.context.base_dir) / src
            extent = (0.0, 0.0, *self.p.size)
            image = read_map(src, extent, where=where, colour=True)
            origin = (0.0, 0.0)
        elif roads_map is not None and len(roads_map):
            image = image_of(roads_map)
            src, where = Path(str(roads_map["src"][0])), image.where or self.where
            # the <map> element's color / tolerance override the parameters
            if str(roads_map["color"][0]):
                colour_text = str(roads_map["color"][0])
            if roads_map["tolerance"][0] >= 0:
                tolerance = float(roads_map["tolerance"][0])
            extent, origin = tuple(roads_map.meta["extent"]), tuple(roads_map.meta["origin"])
        else:
            raise InputDataError(
                'no road-map image: set \'path\' or add <map kind="roads" src="..."/>', where=self.where
            )
        colour = parse_colour(colour_text, where=where)
        mask = road_mask(image.data, colour, tolerance)
        px = max(image.pixel_size)
        simplify = px if self.p.simplify < 0 else self.p.simplify
        min_length = 3 * px if self.p.min_length < 0 else self.p.min_length
        lines = image_roads(mask, image.extent, simplify=simplify, min_length=min_length)
        if len(lines) == 0:
            raise InputDataError(
                f"road map '{src}' has no road pixels of colour {colour_text} (tolerance {tolerance:g})",
                where=where,
            )
        n = len(lines)
        report = {"road_pixels": int(mask.sum()), "segments": n}
        log.info("%s: %s: %d road pixels -> %d street lines", self.where, src.name, int(mask.sum()), n)
        roads = Layer.from_geoms(
            lines,
            meta={"crs": local_crs(origin), "origin": origin, "source": "image", "extent": tuple(extent)},
            **{
                "class": np.full(n, self.p.road_class, dtype=object),
                "major": self.p.road_class == "major",
                "width": np.full(n, self.p.width),
                "layer": np.zeros(n, np.int64),
                "bridge": np.zeros(n, bool),
                "tunnel": np.zeros(n, bool),
            },
        )
        return NodeResult({"roads": roads}, report)

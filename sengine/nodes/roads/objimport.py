"""OBJ import: street networks or ready lots made in another tool (skylineEngine 002 §1, §5.4).

skylineEngine takes "street networks or lots made elsewhere" as ``.obj``
files, and circuits "directly imported ... from a .obj file" skip the block
search (§5.4).  Two nodes read them with trimesh:

* ``obj.roads`` -- the file's line elements (``l``) are street centre lines;
  they enter the pipeline where a map's roads do (``majorRoads``), and go
  through ``roads.clean`` and the blocks;
* ``obj.lots`` -- the file's faces are ready polygons, one per connected
  piece of the mesh (one object, or faces sharing no vertex with others);
  they enter as ``lots`` (to the buildings) or as ``blocks`` (to a lot
  subdivision).

OBJ is usually Y-up: plan coordinates are ``(x, -z)`` (``up="y"``) or
``(x, y)`` (``up="z"``), times ``scale`` metres per unit.

References
----------
.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
"""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np
import shapely
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from sengine import Layer, NodeResult, Param, Port, SENode, register
from sengine.errors import InputDataError
from sengine.geom.crs import local_crs

from ..maps import check_regular_file

__all__ = ["load_obj", "obj_lines", "obj_polygons", "ObjRoads", "ObjLots"]

log = logging.getLogger(__name__)


def load_obj(path: Path, *, where: str | None = None):
    """Vertices (n, 3), triangles (m, 3) and line elements of an OBJ file.

    trimesh reads the vertices (in file order, ``process=False``) and the
    faces; the ``l`` elements, which trimesh does not keep, are read from
    the text, with OBJ's 1-based and negative (relative) indices.

    Returns
    -------
    vertices : ndarray (n, 3)
    faces : ndarray of int (m, 3)
    lines : list of ndarray of int
        Vertex indices of each ``l`` element.
    """
    import trimesh

    path = Path(path)
    if not path.is_file():
        raise InputDataError(f"OBJ file '{path}' does not exist", where=where)
    try:
        text = path.read_text(errors="strict")
    except (UnicodeDecodeError, OSError) as exc:
        raise InputDataError(f"OBJ file '{path}' is not a text OBJ file ({type(exc).__name__})", where=where) from None
    nverts = 0
    lines: list[np.ndarray] = []
    for lineno, raw in enumerate(text.splitlines(), 1):
        parts = raw.split()
        if not parts:
            continue
        if parts[0] == "v":
            nverts += 1
            try:
                xyz = [float(p) for p in parts[1:4]]
            except ValueError:
                xyz = []
            if len(xyz) != 3 or not all(math.isfinite(c) for c in xyz):
                raise InputDataError(
                    f"OBJ file '{path}', line {lineno}: a vertex needs three finite coordinates, got {raw.strip()!r}",
                    where=where,
                )
        elif parts[0] == "l":
            try:
                idx = np.array([int(p.split("/")[0]) for p in parts[1:]], np.int64)
            except ValueError:
                raise InputDataError(
                    f"OBJ file '{path}', line {lineno}: bad line element {raw.strip()!r}", where=where
                ) from None
            idx = np.where(idx < 0, nverts + idx, idx - 1)
            if len(idx) >= 2:
                lines.append(idx)
    if nverts == 0:
        raise InputDataError(f"OBJ file '{path}' has no vertices (not an OBJ file?)", where=where)
    try:
        geom = trimesh.load(str(path), file_type="obj", process=False, maintain_order=True)
    except Exception as exc:  # trimesh raises many kinds on malformed files
        raise InputDataError(f"OBJ file '{path}' cannot be read: {exc}", where=where) from None
    if isinstance(geom, trimesh.Scene):
        geom = geom.dump(concatenate=True) if geom.geometry else None
    vertices = np.asarray(getattr(geom, "vertices", np.empty((0, 3))), np.float64)
    faces = np.asarray(getattr(geom, "faces", np.empty((0, 3))), np.int64).reshape(-1, 3)
    if len(vertices) != nverts:  # trimesh merged or dropped vertices: lines would point wrongly
        raise InputDataError(f"OBJ file '{path}': read {len(vertices)} of {nverts} vertices", where=where)
    for idx in lines:
        if idx.min() < 0 or idx.max() >= nverts:
            raise InputDataError(
                f"OBJ file '{path}': a line element refers to a vertex that does not exist", where=where
            )
    return vertices, faces, lines


def _plan_xy(vertices: np.ndarray, up: str, scale: float) -> np.ndarray:
    if up == "y":
        return np.column_stack([vertices[:, 0], -vertices[:, 2]]) * scale
    return vertices[:, :2] * scale


def obj_lines(vertices: np.ndarray, lines: list[np.ndarray], *, up: str = "y", scale: float = 1.0) -> np.ndarray:
    """The ``l`` elements as planar LineStrings (m)."""
    if not lines:
        return np.empty(0, object)
    xy = _plan_xy(vertices, up, scale)
    sizes = np.fromiter(map(len, lines), np.int64, len(lines))
    return shapely.linestrings(xy[np.concatenate(lines)], indices=np.repeat(np.arange(len(lines)), sizes))


def obj_polygons(
    vertices: np.ndarray, faces: np.ndarray, *, up: str = "y", scale: float = 1.0, min_area: float = 0.0
) -> np.ndarray:
    """One planar polygon per connected piece of a mesh (pieces share no vertex).

    The triangles of each piece are projected on the plan and merged
    (``shapely.coverage_union_all`` per piece); pieces under ``min_area``
    (m2) and degenerate (vertical) triangles are dropped.
    """
    if len(faces) == 0:
        return np.empty(0, object)
    xy = _plan_xy(vertices, up, scale)
    m = len(faces)
    rows = np.repeat(np.arange(m), 3)
    inc = coo_matrix((np.ones(3 * m), (rows, faces.ravel())), shape=(m, len(vertices))).tocsr()
    adj = inc @ inc.T
    _, piece = connected_components(adj, directed=False)
    tri = shapely.polygons(xy[faces])
    ok = shapely.area(tri) > 1e-12
    out = []
    order = np.argsort(piece[ok], kind="stable")
    tri, piece = tri[ok][order], piece[ok][order]
    brk = np.flatnonzero(np.r_[True, piece[1:] != piece[:-1], True])
    for a, b in zip(brk[:-1], brk[1:], strict=False):
        poly = shapely.union_all(tri[a:b], grid_size=None)
        poly = shapely.make_valid(poly) if not shapely.is_valid(poly) else poly
        out.extend(shapely.get_parts(poly).tolist())
    polys = np.asarray([p for p in out if p.geom_type == "Polygon"], dtype=object)
    return polys[shapely.area(polys) >= min_area] if len(polys) else polys


class _ObjNode(SENode):
    inputs = {"obj_map": Port("file", "the OBJ file of the plan (<map kind='obj'>)", required=False)}

    def _source(self, obj_map: Layer | None) -> tuple[Path, str]:
        if self.p.path:
            p = Path(self.p.path)
            if not p.is_absolute() and self.context.base_dir is not None:
                p = Path(self.context.base_dir) / p
            return p, self.where
        if obj_map is None or not len(obj_map):
            raise InputDataError('no OBJ file: set \'path\' or add <map kind="obj" src="..."/>', where=self.where)
        return Path(str(obj_map["src"][0])), obj_map.meta.get("where") or self.where

    @staticmethod
    def _meta(obj_map: Layer | None) -> dict:
        origin = tuple(obj_map.meta["origin"]) if obj_map is not None and "origin" in obj_map.meta else (0.0, 0.0)
        return {"crs": local_crs(origin), "origin": origin, "source": "obj"}


_COMMON = {
    "path": Param("path", "", doc="OBJ file; empty: the plan's <map kind='obj'> src"),
    "up": Param("str", "y", choices=("y", "z"), doc="the file's up axis: y (plan x, -z) or z (plan x, y)"),
    "scale": Param("float", 1.0, min=1e-6, max=1e6, unit="m", doc="metres per OBJ unit"),
}


@register
class ObjRoads(_ObjNode):
    """Street centre lines from the line elements of an OBJ file (skylineEngine 002 §1).

    Use it as the ``majorRoads`` node of a load-map network: the lines go
    through roads.clean and the blocks like a map's streets.
    """

    name = "obj.roads"
    outputs = {"roads": Port("roads", "street centre lines (the file's l elements)")}
    params = {
        **_COMMON,
        "width": Param("float", 12.0, min=0.0, max=200.0, unit="m", doc="street width between block fronts"),
        "road_class": Param("str", "minor", choices=("major", "minor"), doc="class given to every street"),
    }

    def run(self, *, obj_map: Layer | None = None):
        path, where = self._source(obj_map)
        check_regular_file(path, "OBJ file", where)
        vertices, _, lines = load_obj(path, where=where)
        geoms = obj_lines(vertices, lines, up=self.p.up, scale=self.p.scale)
        if len(geoms):
            geoms = geoms[shapely.length(geoms) > 0]
        if not len(geoms):
            raise InputDataError(
                f"OBJ file '{path}' has no line elements (l): obj.roads reads street centre lines", where=where
            )
        n = len(geoms)
        log.info("%s: %s: %d street lines", self.where, path.name, n)
        return NodeResult(
            {
                "roads": Layer.from_geoms(
                    geoms,
                    meta=self._meta(obj_map),
                    **{
                        "class": np.full(n, self.p.road_class, dtype=object),
                        "major": self.p.road_class == "major",
                        "width": np.full(n, self.p.width),
                    },
                )
            },
            {"lines": n},
        )


@register
class ObjLots(_ObjNode):
    """Ready lots (or blocks) from the faces of an OBJ file, one per connected piece of the mesh.

    Wire ``lots`` to the buildings, or ``blocks`` to a lot subdivision
    (skylineEngine 002 §5.4: circuits imported from a .obj file).
    """

    name = "obj.lots"
    outputs = {
        "lots": Port("lots", "one lot per connected piece of the mesh"),
        "blocks": Port("blocks", "the same polygons as blocks"),
    }
    params = {
        **_COMMON,
        "min_area": Param("float", 1.0, min=0.0, unit="m2", doc="pieces smaller than this are dropped"),
    }

    def run(self, *, obj_map: Layer | None = None):
        path, where = self._source(obj_map)
        check_regular_file(path, "OBJ file", where)
        vertices, faces, _ = load_obj(path, where=where)
        polys = obj_polygons(vertices, faces, up=self.p.up, scale=self.p.scale, min_area=self.p.min_area)
        if not len(polys):
            raise InputDataError(
                f"OBJ file '{path}' has no faces (f) of at least {self.p.min_area:g} m2 on the plan", where=where
            )
        n = len(polys)
        meta = self._meta(obj_map)
        # the file says nothing about streets: frontage unknown (NaN)
        lots = Layer.from_geoms(
            polys,
            meta=meta,
            block=-1,
            district=-1,
            corner=False,
            frontage=np.full(n, np.nan),
            street_edges=0,
            method="obj",
        )
        blocks = Layer.from_geoms(polys, meta=meta, district=-1)
        log.info("%s: %s: %d polygons", self.where, path.name, n)
        return NodeResult({"lots": lots, "blocks": blocks}, {"polygons": n})

"""Street surface among the faces of a street graph: medians and traffic islands.

The thin faces between dual carriageways and the tiny traffic islands
inside junctions are street surface, not blocks (skylineEngine 002 §5.4
takes blocks as the minimal circuits of the street graph; a real map has
these extra circuits).  They are found on the faces the blocks are traced
with: mean width ``2 area / perimeter`` below ``sliver_width`` makes a
median, an area below ``island_area`` an island.  ``roads.clean`` hands
them on as polygons to be drawn as street surface.

References
----------
.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
"""

from __future__ import annotations

import numpy as np
import shapely

from sengine.geom.planar import PlanarFaces, planar_faces

from .junctions import Pieces

__all__ = ["segment_graph", "find_slivers"]


def segment_graph(pieces: Pieces, xy: np.ndarray, key: np.ndarray):
    """The straight-segment graph of street segments.

    Returns
    -------
    nodes : ndarray (k, 2)
        Node coordinates (m).
    u, v : ndarray of int64
        End node ids of every straight segment.
    pu, pv : ndarray of int64
        End node ids of every piece (street segment).
    row : ndarray of int64
        Piece of every straight segment.
    """
    if pieces.node is not None:  # the split's node numbering (ascending key), without unused nodes
        used = np.zeros(len(pieces.node_key), bool)
        used[pieces.node] = True
        inv = (np.cumsum(used) - 1)[pieces.node]
        first = np.empty(int(used.sum()), np.int64)
        first[inv[::-1]] = np.arange(len(inv) - 1, -1, -1)
    else:
        _, first, inv = np.unique(key[pieces.vertex], return_index=True, return_inverse=True)
        inv = inv.ravel()
    nodes = xy[pieces.vertex[first]]
    lab = pieces.piece
    s = np.flatnonzero(lab[1:] == lab[:-1])
    starts = np.flatnonzero(np.r_[True, lab[1:] != lab[:-1]]) if len(lab) else np.empty(0, np.int64)
    ends = np.r_[starts[1:] - 1, len(lab) - 1] if len(lab) else starts
    return nodes, inv[s], inv[s + 1], inv[starts], inv[ends], lab[s]


def find_slivers(
    nodes: np.ndarray, u: np.ndarray, v: np.ndarray, *, sliver_width: float, island_area: float, faces=None
) -> tuple[np.ndarray, np.ndarray, int]:
    """Faces of the street graph that are street surface, not blocks.

    Parameters
    ----------
    nodes, u, v : ndarray
        A plane segment graph (see :func:`segment_graph`).
    sliver_width : float
        Faces whose mean width ``2 area / perimeter`` (m) is below this are
        medians between dual carriageways.
    island_area : float
        Faces smaller than this (m2) are traffic islands.
    faces : PlanarFaces or BlockFaces, optional
        The faces of exactly this graph, already traced (their closed walks
        are used); traced here when None.

    Returns
    -------
    polygons : ndarray of shapely.Polygon
    kind : ndarray of str
        ``"island"`` or ``"median"``.
    nfaces : int
        Number of faces of the graph.

    Notes
    -----
    Area and perimeter are those of each face's closed walk (its outer
    ring; what lies inside does not count), and a sliver's polygon is that
    walk as a ring (made valid when the walk touches itself).
    """
    empty = (np.empty(0, object), np.empty(0, object), 0)
    if faces is None:
        faces = planar_faces(nodes, u, v)
    wv, ws, warea = faces.walk_vertex, faces.walk_start, faces.walk_area
    nf = len(warea)
    if nf == 0 or not len(wv):
        return empty
    size = np.diff(ws)
    walk = np.repeat(np.arange(nf), size)
    k = np.arange(len(wv))
    first = ws[:-1][walk]
    nxt = np.where(k + 1 < first + size[walk], k + 1, first)
    p, q = nodes[wv], nodes[wv[nxt]]
    perimeter = np.bincount(walk, weights=np.hypot(*(q - p).T), minlength=nf)
    # bounded faces turn counter-clockwise (positive), the outer walks clockwise (see planar_faces)
    area = warea
    bounded = area > 0
    width = 2.0 * area / np.maximum(perimeter, 1e-12)
    island = bounded & (area < island_area)
    median = bounded & ~island & (width < sliver_width)
    sel = island | median
    nfaces = int(bounded.sum())
    if not sel.any():
        return (*empty[:2], nfaces)
    faces_sel = np.flatnonzero(sel)
    polys = _walk_polygons(faces, faces_sel, nodes)
    bad = ~shapely.is_valid(polys)
    if bad.any():  # a walk through a pinch vertex
        polys[bad] = shapely.make_valid(polys[bad])
    return polys, np.where(island[faces_sel], "island", "median").astype(object), nfaces


def _walk_polygons(faces, walks: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """The polygon of each of ``walks`` (closed walks of ``faces``) as a ring.

    A simple walk whose face has no hole is that face's polygon already: it
    is taken over; the others are built from their vertices.
    """
    wv, ws = faces.walk_vertex, faces.walk_start
    polys = np.empty(len(walks), dtype=object)
    shell = np.asarray(getattr(faces, "walk_polygon", np.empty(0, np.int64)))
    own = np.full(len(walks), -1, np.int64) if len(shell) != len(ws) - 1 else shell[walks]
    taken = np.flatnonzero(own >= 0)
    if len(taken):
        done = faces.polygons if isinstance(faces, PlanarFaces) else faces.faces
        whole = shapely.get_num_interior_rings(done[own[taken]]) == 0
        taken = taken[whole]
        polys[taken] = done[own[taken]]
    rest = np.ones(len(walks), bool)
    rest[taken] = False
    rest = np.flatnonzero(rest)
    if len(rest):
        n = np.diff(ws)[walks[rest]]
        owner = np.repeat(np.arange(len(rest)), n)
        idx = ws[walks[rest]][owner] + np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
        polys[rest] = shapely.polygons(shapely.linearrings(nodes[wv[idx]], indices=owner))
    return polys

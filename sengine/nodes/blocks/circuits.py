"""Blocks: minimal closed circuits of the street graph (skylineEngine §5.4, Fig. 8).

The street network is a plane graph; blocks are its bounded faces.  Each
undirected street segment is doubled into two half-edges (Fig. 8a); from
every half-edge the walk continues along the outgoing segment with the
lowest positive turning angle, which closes a circuit around one block
(Fig. 8b, c).  The one circuit that turns the other way round is the city
outline and is removed (Fig. 8d).  The remaining circuits partition the
city area: their union is the area inside the outline and no two overlap.

Instead of walking node by node, the whole walk is vectorized
(:func:`sengine.geom.planar.planar_faces`): half-edges are sorted by angle
around their node with one ``numpy.lexsort``, the "next half-edge"
permutation is one gather, and the circuits are the cycles of that
permutation.  Dead ends (edges with the same face on both sides) are
dropped before the final trace; a component floating inside a block
becomes a hole of it.

When the roads come from ``roads.clean``, which traces these faces on
its plane segment graph anyway, the node takes them over from
its ``graph`` port (:func:`traced_faces`: same faces, same order).

On a real map three more things hold (issue 11):

* Only the ground level closes blocks (:func:`ground_level`): a bridge, a
  tunnel or a way on another ``layer`` crosses the streets without a
  junction, so the faces are traced without it and close on both sides of
  it.  A bridge still gets its street surface (kind ``bridge``) and, with
  ``bridges="cut"``, keeps the ground under its deck out of the block.
* A cul-de-sac is a street inside its face: with ``dead_ends="cut"`` it is
  a spur of the face's ring (:func:`sengine.geom.planar.spur_polygons`), so
  that the street and sidewalk insets keep clear of it in the same buffer
  and the lots front onto it.
* Edges closing the graph round the data's box (``roads.clean``'s
  ``close="bbox"``; ``src`` -1 here) are no streets: the land they close is
  shrunk from its streets only and clipped back to the box
  (``meta["bbox"]``), with no street or sidewalk along it.

Blocks are then shrunk for the streets and sidewalks (§5.4, last
paragraph): each face is inset by the length-weighted mean half-width of
the streets around it, giving the street surface, and by the sidewalk
width again, giving the block; the two rings are kept as ``streets`` and
``sidewalks`` polygon layers.  With ``inset="street"`` each side moves by
its own street's half-width instead (:func:`inset_by_street`), so that an
avenue keeps its width beside an alley.

References
----------
skylineEngine, §5.4 "Blocks Module" and Figure 8.
"""

from __future__ import annotations

import logging
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
import shapely

from sengine import Layer, NodeResult, Param, Port, SENode, register
from sengine.geom.planar import PlanarFaces, planar_faces, spur_polygons
from sengine.geom.polygons import PARALLEL_MIN, containing, frame_boxes, inset, subtract_buffers, threaded
from sengine.geom.segments import merge_points, planarize, segments_from_lines
from sengine.parallel import available_cores

if TYPE_CHECKING:
    import networkx as nx

__all__ = [
    "find_blocks",
    "BlockFaces",
    "traced_faces",
    "face_half_widths",
    "shrink_faces",
    "cost_chunks",
    "inset_by_street",
    "shrink_faces_by_street",
    "ground_level",
    "segment_widths",
    "inner_segments",
    "cut_inner_streets",
    "clip_to_box",
    "shrink_city",
    "street_graph",
    "canonical_faces",
    "face_order",
    "ranked_ids",
    "shard_lines",
    "ID_SPAN",
    "SHARD_KEY",
    "BlocksCircuits",
]

log = logging.getLogger(__name__)


@dataclass(kw_only=True)
class BlockFaces(PlanarFaces):
    """Result of :func:`find_blocks`: the faces of the street graph and the graph they were traced on.

    Attributes
    ----------
    polygons, edge_faces, bridge, outline, counts, walk_vertex, walk_start, walk_area, walk_polygon
        As :class:`sengine.geom.planar.PlanarFaces` gives them, for the graph
        below; ``counts`` adds the street graph's numbers for the node's
        report (segments, repeated, crossings).
    xy : ndarray (n, 2)
        Node coordinates of the plane graph actually traced (m).
    u, v : ndarray of int64 (m,)
        Its segments (after merging coincident nodes and splitting crossings).
    src : ndarray of int64 (m,)
        For each segment, the input line (lines entry) or input edge (arrays
        entry) it comes from.
    """

    xy: np.ndarray
    u: np.ndarray
    v: np.ndarray
    src: np.ndarray

    @property
    def faces(self) -> np.ndarray:
        """Bounded faces of the street graph (blocks before the sidewalk inset), possibly with holes."""
        return self.polygons


def find_blocks(streets, *, node: bool = True, decimals: int | None = 6) -> BlockFaces:
    """Find the blocks of a street network as minimal closed circuits.

    Parameters
    ----------
    streets : array_like of shapely.LineString, or tuple ``(xy, u, v)``
        Either street centre lines (m; any number of vertices each), or a
        street graph that already knows its topology: ``xy`` an ``(n, 2)``
        float array of node coordinates (m, planar), ``u`` and ``v`` int
        arrays of length ``m`` with the end node ids (row indices into
        ``xy``) of each straight segment.  The OSM importer calls it the
        second way, with node ids from OSM node ids.
    node : bool
        Make the graph plane first: segments that cross, or end on another
        segment's interior, or overlap collinearly, are split there
        (:func:`sengine.geom.segments.planarize`, vectorized).  Turn off only for
        input known to be plane: crossings without a node give overlapping,
        invalid faces.
    decimals : int or None
        Nodes whose coordinates are equal after rounding to this many
        decimals (m) are merged; ``None`` keeps the given ids / exact
        coordinates.

    Returns
    -------
    BlockFaces
        ``src`` maps each traced segment back to the input line (lines
        entry) or the input edge index (arrays entry).

    Notes
    -----
    The circuit finder is skylineEngine's (§5.4, Fig. 8) written as one
    permutation: see :func:`sengine.geom.planar.trace_faces`.  It runs in
    O(m log m) numpy time (about 0.5 s for Liège's 80,000 segments).
    """
    counts: dict = {}
    if isinstance(streets, tuple) and len(streets) == 3:
        xy = np.asarray(streets[0], np.float64).reshape(-1, 2)
        u = np.asarray(streets[1], np.int64).ravel()
        v = np.asarray(streets[2], np.int64).ravel()
        if len(u) != len(v):
            raise ValueError(f"u and v differ in length: {len(u)} != {len(v)}")
        if len(u) and (min(u.min(), v.min()) < 0 or max(u.max(), v.max()) >= len(xy)):
            raise ValueError(f"node ids must index xy (0 .. {len(xy) - 1})")
        src = np.arange(len(u), dtype=np.int64)
        if decimals is not None and len(xy):
            xy, inv = merge_points(xy, decimals)
            u, v = inv[u], inv[v]
    else:
        xy, u, v, src = segments_from_lines(streets, node=False, decimals=decimals)
    counts["segments"] = int(len(u))
    # one segment per node pair (two-way streets often come twice)
    a, b = np.minimum(u, v), np.maximum(u, v)
    keep = a != b
    _, first = np.unique(a[keep] * max(len(xy), 1) + b[keep], return_index=True)
    first = np.sort(np.flatnonzero(keep)[first])
    counts["repeated"] = int(len(u) - len(first))
    u, v, src = u[first], v[first], src[first]
    if node and len(u):
        xy, u, v, s2, crossings = planarize(xy, u, v, decimals=decimals)
        src = src[s2]
        counts["crossings"] = crossings
    pf: PlanarFaces = planar_faces(xy, u, v)
    for k in ("duplicates", "self_loops", "bridges", "holes", "degenerate", "pinched", "faces"):
        counts[k] = pf.counts.get(k, 0)
    log.info(
        "blocks: %d segments -> %d faces (%d dead-end/bridge segments dropped, %d holes)",
        counts["segments"],
        counts["faces"],
        counts["bridges"],
        counts["holes"],
    )
    return BlockFaces(**{**vars(pf), "counts": counts}, xy=xy, u=u, v=v, src=src)


def traced_faces(graph, rows: int, *, decimals: int | None) -> BlockFaces | None:
    """The faces ``roads.clean`` traced already, when they are what :func:`find_blocks` would give.

    ``roads.clean`` traces the faces of its plane segment graph once (to find
    slivers) and hands them on on its ``graph`` port (meta ``faces``), its
    nodes numbered as the lines entry numbers them after merging to meta
    ``decimals`` (set only when that merges no two nodes).  They are taken
    over when the graph belongs to exactly these ``rows`` and was numbered
    for these ``decimals``: then they are the faces, in the order, that
    ``find_blocks(lines, node=False, decimals=decimals)`` gives.

    Parameters
    ----------
    graph : Layer or None
        The ``graph`` layer (:func:`sengine.nodes.roads.clean.graph_layer`).
    rows : int
        The length of the roads layer being traced.
    decimals : int or None
        How the tracer would number the nodes.

    Returns
    -------
    BlockFaces or None
        With ``src`` indexing the rows, as the lines entry gives it.
    """
    if graph is None:
        return None
    meta = graph.meta
    bf = meta.get("faces")
    if meta.get("rows") != rows or not isinstance(bf, BlockFaces):
        return None
    if meta.get("decimals") is None or meta.get("decimals") != decimals:
        return None
    return replace(bf, src=np.asarray(graph["row"], np.int64)[bf.src], counts=dict(bf.counts))


def face_half_widths(bf: BlockFaces, widths) -> np.ndarray:
    """Length-weighted mean half-width of the streets around each face (m).

    Parameters
    ----------
    bf : BlockFaces
    widths : array_like of float
        Street width (m) per input line / input edge (indexed by ``bf.src``);
        closing edges (``src`` -1) are no streets and do not count.
    """
    widths = np.asarray(widths, np.float64)
    nf = len(bf.faces)
    if nf == 0:
        return np.zeros(0)
    seg_len = np.hypot(*(bf.xy[bf.v] - bf.xy[bf.u]).T)
    hw = segment_widths(bf, widths) / 2.0
    f = bf.edge_faces.ravel()
    w = np.repeat(seg_len, 2)
    h = np.repeat(hw, 2)
    ok = (f >= 0) & np.repeat(bf.src >= 0, 2)
    tot = np.bincount(f[ok], weights=w[ok], minlength=nf)
    acc = np.bincount(f[ok], weights=(w * h)[ok], minlength=nf)
    return np.where(tot > 0, acc / np.where(tot > 0, tot, 1.0), 0.0)


def ground_level(roads: Layer) -> np.ndarray:
    """Rows of a road layer at ground level: no bridge, no tunnel, ``layer`` 0.

    The blocks are the faces of the ground-level street graph: a bridge or a
    tunnel crosses other ways without a junction and closes no block; ways
    tagged with another ``layer`` pass over or under the others likewise.
    Columns that are absent count as ground level (all rows of a synthetic
    or traced network).
    """
    ground = np.ones(len(roads), bool)
    for col in ("bridge", "tunnel"):
        if col in roads:
            ground &= ~np.asarray(roads[col], bool)
    if "layer" in roads:
        ground &= np.asarray(roads["layer"], np.int64) == 0
    return ground


def segment_widths(bf: BlockFaces, widths) -> np.ndarray:
    """Street width (m) of each traced segment of ``bf``: ``widths[src]``, 0 on closing edges (``src`` -1)."""
    widths = np.asarray(widths, np.float64)
    if not len(widths):
        return np.zeros(len(bf.src))
    return np.where(bf.src >= 0, widths[np.maximum(bf.src, 0)], 0.0)


def shrink_faces(faces, half_width, sidewalk: float, *, shape=None, rounded=None):
    """Street, sidewalk and block polygons of each face (§5.4, last paragraph).

    Parameters
    ----------
    faces : array_like of shapely.Polygon
        Faces between street centre lines.
    half_width : array_like of float
        Half the street width around each face (m).
    sidewalk : float
        Sidewalk width (m).
    shape : array_like of shapely.Polygon, optional
        What is inset, per face: the face, or the face with the dead ends
        inside it as spurs of its rings (:func:`sengine.geom.planar.spur_polygons`),
        which the insets then keep clear of too (default: the faces).
    rounded : array_like of bool, optional
        Faces inset with round joins (those given with spurs: see
        :func:`sengine.geom.polygons.inset`); the others are mitred.

    Returns
    -------
    street, walk, block : ndarray of shapely.Geometry
        ``face - inset(face, hw)``, ``inset(face, hw) - block`` and
        ``block = inset(face, hw + sidewalk)``; the three partition the face.
        ``block`` may be empty (face too thin) or a MultiPolygon.
    """
    faces = np.asarray(faces, dtype=object)
    shape = faces if shape is None else np.asarray(shape, dtype=object)
    hw = np.asarray(half_width, np.float64)
    spur = np.zeros(len(faces), bool) if rounded is None else np.asarray(rounded, bool)
    threads = _geos_threads()
    if threads <= 1 or len(faces) < PARALLEL_MIN:
        return _shrink_some(faces, shape, hw, spur, sidewalk, threads=threads)
    # each face's insets and rings in one job: the faces dealt out in chunks of about equal work, the
    # heaviest first (the land round a city, with its dead ends as spurs, is one face as long as a
    # hundred blocks); each polygon's result is the same as in one vectorized call
    chunks = cost_chunks(shapely.get_num_coordinates(shape) * np.where(spur, 2, 1), 4 * threads)
    out = [np.empty(len(faces), dtype=object) for _ in range(3)]
    with ThreadPoolExecutor(threads) as pool:
        done = pool.map(lambda k: _shrink_some(faces[k], shape[k], hw[k], spur[k], sidewalk, threads=1), chunks)
        for k, parts in zip(chunks, done, strict=True):
            for arr, part in zip(out, parts, strict=True):
                arr[k] = part
    return tuple(out)


def _shrink_some(faces, shape, hw, spur, sidewalk: float, *, threads: int | None = None):
    """:func:`shrink_faces` of some faces, with GEOS on ``threads`` threads (default: the CPUs)."""
    edge = inset(shape, hw, rounded=spur, threads=threads)
    if sidewalk <= 0:
        nogap = np.zeros(len(faces), bool)
        return _ring_between(faces, edge, gap=hw > 0, threads=threads), _ring_between(edge, edge, gap=nogap), edge
    # a face with nothing left inside its street surface has no block either: no second inset for it
    block = edge.copy()
    live = np.flatnonzero(~shapely.is_empty(edge))
    # a face with spurs: its block is its street edge shrunk by the sidewalk (a valid polygon, a third cheaper)
    source = np.where(spur, edge, shape)[live]
    block[live] = inset(source, np.where(spur, sidewalk, hw + sidewalk)[live], threads=threads)
    street = _ring_between(faces, edge, gap=hw > 0, threads=threads)
    return street, _ring_between(edge, block, gap=np.ones(len(faces), bool), threads=threads), block


def cost_chunks(cost, parts: int) -> list[np.ndarray]:
    """Indices cut into about ``parts`` chunks of about equal total ``cost``, the costliest items first.

    Items are taken by decreasing cost (stable) and cut where the running
    total passes a multiple of ``sum / parts``: an item costing more than
    that share is a chunk of its own, at the front, so that a pool of
    threads taking chunks in order starts the longest jobs first
    (longest-processing-time scheduling).

    Parameters
    ----------
    cost : array_like of float (n,)
        Estimated work of each item (any unit, >= 0).
    parts : int
        Chunks wanted (fewer when there are fewer items).

    Returns
    -------
    list of ndarray of int64
        Non-empty chunks; together every index once.
    """
    cost = np.asarray(cost, np.float64)
    if not len(cost):
        return []
    order = np.argsort(-cost, kind="stable")
    before = np.cumsum(cost[order]) - cost[order]  # running total before each item
    total = float(cost.sum())
    share = total / max(int(parts), 1) if total > 0 else 1.0  # all free: one chunk (a subnormal share still cuts)
    bin_ = np.minimum(np.floor(before / share), max(int(parts), 1) - 1).astype(np.int64)
    cut = np.flatnonzero(np.r_[True, bin_[1:] != bin_[:-1]])
    return np.split(order, cut[1:])


def _geos_threads() -> int:
    """Threads for GEOS work here: as :func:`sengine.geom.polygons.inset` takes them (1 in a worker process)."""
    import multiprocessing

    if multiprocessing.parent_process() is not None:
        return 1
    return min(available_cores(), 4)


def inset_by_street(
    faces, bf: BlockFaces, face_ids, segment_distance, *, shape=None, inner=None, rounded=None
) -> np.ndarray:
    """Each face shrunk street by street: every side by its own street's distance.

    Parameters
    ----------
    faces : array_like of shapely.Polygon
        Faces of ``bf`` (its ``faces[face_ids]``).
    bf : BlockFaces
        The traced street graph: its segments and the faces on their sides.
    face_ids : array_like of int
        Index into ``bf.faces`` of each of ``faces``.
    segment_distance : array_like of float
        Distance (m) to move off each segment of ``bf`` (its ``u``, ``v``);
        NaN: none of its own (it moves by the face's nearest side's).
    shape : array_like of shapely.Polygon, optional
        What is inset, per face (see :func:`shrink_faces`; default the faces).
    inner : (ndarray, ndarray) of int, optional
        Segments of ``bf`` inside the faces (dead ends) and the face (index
        into ``faces``) of each: the ground within their distance is taken
        off too, where it is farther than the face's nearest side.
    rounded : array_like of bool, optional
        Faces inset with round joins (see :func:`shrink_faces`).

    Returns
    -------
    ndarray of shapely.Geometry
        Each face inset (mitred) by the smallest distance of its sides,
        minus the ground within each farther side's distance of it (round
        at its ends).  The farther sides of a face at one distance are
        merged into lines (``shapely.line_merge``: a buffer of a few long
        lines is much cheaper than one of many segments) and buffered
        together; a face's few distances are taken off in rounds.
    """
    faces = np.asarray(faces, dtype=object)
    shape = faces if shape is None else np.asarray(shape, dtype=object)
    pos = np.full(len(bf.faces), -1, np.int64)
    pos[np.asarray(face_ids, np.int64)] = np.arange(len(faces))
    seg = np.repeat(np.arange(len(bf.u)), 2)
    owner = bf.edge_faces.ravel()
    owner = np.where(owner >= 0, pos[np.maximum(owner, 0)], -1)
    seg, owner = seg[owner >= 0], owner[owner >= 0]
    dist = np.asarray(segment_distance, np.float64)[seg]
    known = np.isfinite(dist)  # segments without a distance move with the nearest side
    seg, owner, dist = seg[known], owner[known], dist[known]
    nearest = np.full(len(faces), np.inf)
    np.minimum.at(nearest, owner, dist)
    out = inset(shape, np.where(np.isfinite(nearest), np.maximum(nearest, 0.0), 0.0), rounded=rounded)
    if inner is not None and len(inner[0]):
        iseg, iown = (np.asarray(a, np.int64) for a in inner)
        seg, owner = np.r_[seg, iseg], np.r_[owner, iown]
        dist = np.r_[dist, np.asarray(segment_distance, np.float64)[iseg]]
    farther = dist > nearest[owner]
    seg, owner, dist = seg[farther], owner[farther], dist[farther]
    if not len(seg):
        return out
    # distances equal to the mm share a buffer, at the largest of them
    groups, group = np.unique(np.column_stack([owner, np.round(dist, 3)]), axis=0, return_inverse=True)
    reach = np.zeros(len(groups))
    np.maximum.at(reach, group, dist)
    o = np.argsort(group, kind="stable")
    lines = shapely.linestrings(np.stack([bf.xy[bf.u[seg[o]]], bf.xy[bf.v[seg[o]]]], axis=1))
    sides = shapely.line_merge(shapely.multilinestrings(lines, indices=group[o]))
    cuts = threaded(shapely.buffer, sides, reach, min_size=64, quad_segs=4)
    gface = groups[:, 0].astype(np.int64)
    rank = np.arange(len(gface)) - np.searchsorted(gface, gface)  # groups come sorted by face
    for k in range(int(rank.max()) + 1):
        sel = rank == k
        out[gface[sel]] = threaded(shapely.difference, out[gface[sel]], cuts[sel], min_size=64)
    return out


def shrink_faces_by_street(
    faces,
    bf: BlockFaces,
    face_ids,
    segment_half_width,
    sidewalk: float,
    *,
    bare=None,
    shape=None,
    inner=None,
    rounded=None,
):
    """:func:`shrink_faces` with each side moved by its own street's half-width (and the sidewalk).

    ``bare`` marks the segments of ``bf`` that are no streets (closing
    edges): they have no width of their own, and move by the face's
    nearest street's (the closing edges run beyond the box the caller clips to).
    ``shape``, ``inner`` and ``rounded`` are the dead ends inside the faces,
    as :func:`inset_by_street` takes them.
    """
    faces = np.asarray(faces, dtype=object)
    hw = np.asarray(segment_half_width, np.float64)
    bare = np.zeros(len(hw), bool) if bare is None else np.asarray(bare, bool)
    hw = np.where(bare, np.nan, hw)
    kw = {"shape": shape, "inner": inner, "rounded": rounded}
    edge = inset_by_street(faces, bf, face_ids, hw, **kw)
    block = inset_by_street(faces, bf, face_ids, hw + sidewalk, **kw) if sidewalk > 0 else edge
    # an inset keeps clear of the face's rings where every street around it has a width
    narrow = np.zeros(len(bf.faces), bool)
    for side in bf.edge_faces.T:
        narrow[side[(side >= 0) & (hw <= 0)]] = True
    wide = ~narrow[np.asarray(face_ids, np.int64)]
    return (
        _ring_between(faces, edge, gap=wide),
        _ring_between(edge, block, gap=np.full(len(faces), sidewalk > 0)),
        block,
    )


def inner_segments(bf: BlockFaces, faces, *, known=None) -> tuple[np.ndarray, np.ndarray]:
    """Streets inside a face: the dead ends and connectors of ``bf``, and the face each lies in.

    Parameters
    ----------
    bf : BlockFaces
    faces : array_like of shapely.Polygon
        The faces kept (some of ``bf.faces``).
    known : (ndarray, ndarray), optional
        Segments whose face is known already: sorted keys ``a * n + b``
        (``a < b`` their nodes, ``n`` the number of nodes) and the face of
        each (index into ``faces``, -1 for none); the others are looked up.

    Returns
    -------
    seg : ndarray of int64
        Segments of ``bf`` with the same face on both sides (``bf.bridge``)
        that are streets (not closing edges).
    face : ndarray of int64
        Index into ``faces`` of the face holding each one's midpoint, -1
        for none (outside the city, or in a face that was dropped).
    """
    seg = np.flatnonzero(bf.bridge & (bf.src >= 0))
    face = np.full(len(seg), -1, np.int64)
    if not len(seg) or not len(faces):
        return seg, face
    look = np.ones(len(seg), bool)
    if known is not None and len(known[0]):
        n = max(len(bf.xy), 1)
        key = np.minimum(bf.u[seg], bf.v[seg]) * n + np.maximum(bf.u[seg], bf.v[seg])
        at = np.minimum(np.searchsorted(known[0], key), len(known[0]) - 1)
        hit = known[0][at] == key
        face[hit] = known[1][at[hit]]
        look = ~hit
    if look.any():
        mid = shapely.points((bf.xy[bf.u[seg[look]]] + bf.xy[bf.v[seg[look]]]) / 2.0)
        face[look] = containing(mid, np.asarray(faces, dtype=object))
    return seg, face


def cut_inner_streets(face, street, walk, block, lines, owner, half_width, sidewalk: float):
    """Streets inside faces (cul-de-sacs) cut out of their blocks, so that lots front onto them.

    Parameters
    ----------
    face, street, walk, block : ndarray of shapely.Geometry (k,)
        Per face: the face, its street ring, sidewalk ring and block, as
        :func:`shrink_faces` gives them.
    lines : ndarray of shapely.LineString (n,)
        Street centre lines inside the faces.
    owner : ndarray of int (n,)
        Face (index into ``face``) of each line.
    half_width : array_like of float (n,)
        Half the street width of each line (m).
    sidewalk : float
        Sidewalk width (m).

    Returns
    -------
    street, walk, block : ndarray of shapely.Geometry (k,)
        The street surface within ``half_width`` of the lines joins the
        street ring, the sidewalk around it joins the sidewalk ring, the
        block loses both: the three still partition each face.
    """
    street, walk, block = street.copy(), walk.copy(), block.copy()
    if not len(lines):
        return street, walk, block
    hw = np.asarray(half_width, np.float64)
    have = np.unique(owner)
    pos = np.searchsorted(have, owner)
    edge = threaded(shapely.difference, face[have], street[have], min_size=64)  # inside the street ring
    edge = subtract_buffers(edge, lines, pos, hw)
    block[have] = subtract_buffers(block[have], lines, pos, hw + sidewalk)
    street[have] = threaded(shapely.difference, face[have], edge, min_size=64)
    walk[have] = threaded(shapely.difference, edge, block[have], min_size=64)
    return street, walk, block


def _ring_between(outer, inner, gap=None, *, threads: int | None = None):
    """``outer - inner`` where ``inner`` lies inside ``outer``.

    Where ``gap`` is set (``inner`` an inset of ``outer`` by a positive
    distance, so no ring of one touches a ring of the other), an ``outer``
    and an ``inner`` Polygon or MultiPolygon give the result directly from
    their rings (:func:`_nested_rings`); an empty ``inner`` gives ``outer``.
    The rest goes through ``shapely.difference``.
    """
    out = np.empty(len(outer), dtype=object)
    if len(outer) == 0:
        return out
    gap = np.ones(len(outer), bool) if gap is None else np.asarray(gap, bool)
    empty = shapely.is_empty(inner)
    tin, tout = shapely.get_type_id(inner), shapely.get_type_id(outer)
    direct = gap & ((tout == 3) | (tout == 6)) & ~empty & ((tin == 3) | (tin == 6))
    same = gap & empty
    out[same] = outer[same]
    idx = np.flatnonzero(direct)
    if len(idx):
        got = _nested_rings(outer[idx], inner[idx])
        done = np.not_equal(got, None)
        out[idx[done]] = got[done]
        direct[idx[~done]] = False
    rest = ~direct & ~same
    if rest.any():
        out[rest] = threaded(shapely.difference, outer[rest], inner[rest], min_size=64, threads=threads)
    return out


def _nested_rings(outer, inner) -> np.ndarray:
    """``outer - inner`` from their rings, for (Multi)Polygons whose rings do not touch, ``inner`` inside ``outer``.

    The shells of the result are those of ``outer``'s parts and the holes
    of ``inner``'s; its holes are those of ``outer``'s parts and the shells
    of ``inner``'s, each in the smallest of its row's shells holding its
    first vertex (:func:`_smallest_shell`).  A row with a hole in no shell
    (not nested so) is left None, for ``shapely.difference``.
    """
    out = np.full(len(outer), None, dtype=object)
    oparts, oi = shapely.get_parts(outer, return_index=True)
    iparts, ii = shapely.get_parts(inner, return_index=True)
    orings, opi = shapely.get_rings(oparts, return_index=True)
    irings, ipi = shapely.get_rings(iparts, return_index=True)
    oshell = np.r_[True, opi[1:] != opi[:-1]] if len(opi) else np.zeros(0, bool)  # get_rings: shell first
    ishell = np.r_[True, ipi[1:] != ipi[:-1]] if len(ipi) else np.zeros(0, bool)
    shells = np.concatenate([orings[oshell], irings[~ishell]])
    srow = np.concatenate([oi[opi[oshell]], ii[ipi[~ishell]]])
    holes = np.concatenate([orings[~oshell], irings[ishell]])
    hrow = np.concatenate([oi[opi[~oshell]], ii[ipi[ishell]]])
    # shells by row (stable: a row's outer shells, then the holes of its inner parts, each in order)
    so = np.argsort(srow, kind="stable")
    shells, srow = shells[so], srow[so]
    owner = _smallest_shell(shells, srow, holes, hrow)
    bad = np.zeros(len(outer), bool)
    bad[hrow[owner < 0]] = True
    keep = ~bad[hrow]
    rings = np.concatenate([shells, holes[keep]])
    ring_owner = np.concatenate([np.arange(len(shells)), owner[keep]])
    o = np.argsort(ring_owner, kind="stable")  # per polygon: its shell, then its holes in order
    polys = shapely.polygons(rings[o], indices=ring_owner[o])
    count = np.bincount(srow, minlength=len(outer))
    first = np.cumsum(count) - count
    single = (count == 1) & ~bad
    out[single] = polys[first[single]]
    multi = (count > 1) & ~bad
    if multi.any():
        take = np.flatnonzero(multi[srow])
        out[multi] = shapely.multipolygons(polys[take], indices=np.cumsum(multi)[srow[take]] - 1)
    return out


def _smallest_shell(shells, shell_row, holes, hole_row) -> np.ndarray:
    """For each hole ring, the smallest shell ring of its row around its first vertex (index into ``shells``).

    ``shell_row`` comes sorted.  A hole whose row has one shell is given it
    unasked; -1 where no shell holds the vertex.
    """
    n_rows = int(max(np.max(shell_row, initial=-1), np.max(hole_row, initial=-1))) + 1
    count = np.bincount(shell_row, minlength=n_rows)
    start = np.cumsum(count) - count
    owner = np.where(count[hole_row] == 1, start[hole_row], -1)
    ask = np.flatnonzero(count[hole_row] > 1)
    if not len(ask):
        return owner
    xy = shapely.get_coordinates(shapely.get_point(holes[ask], 0))
    k = count[hole_row[ask]]
    pair = np.repeat(np.arange(len(ask)), k)
    cand = np.repeat(start[hole_row[ask]] - (np.cumsum(k) - k), k) + np.arange(int(k.sum()))
    box = shapely.bounds(shells[cand])
    x, y = xy[pair, 0], xy[pair, 1]
    near = (box[:, 0] <= x) & (x <= box[:, 2]) & (box[:, 1] <= y) & (y <= box[:, 3])
    pair, cand, x, y = pair[near], cand[near], x[near], y[near]
    if len(cand):
        tested = np.unique(cand)
        filled = np.empty(len(shells), dtype=object)
        filled[tested] = shapely.polygons(shells[tested])
        # prepared: a few shells (the land round a city, 20,000 vertices) hold hundreds of holes each, and an
        # unprepared point-in-polygon walks every edge per point (Liège: 19 -> 2 ms); the same predicate
        shapely.prepare(filled[tested])
        area = np.zeros(len(shells))
        area[tested] = shapely.area(filled[tested])
        inside = shapely.contains_xy(filled[cand], x, y)
        pair, cand = pair[inside], cand[inside]
        o = np.lexsort((area[cand], pair))  # per hole, the smallest shell first
        pair, cand = pair[o], cand[o]
        lead = np.r_[True, pair[1:] != pair[:-1]] if len(pair) else np.zeros(0, bool)
        owner[ask[pair[lead]]] = cand[lead]
    return owner


def clip_to_box(geoms, box) -> np.ndarray:
    """Polygons clipped to a box (GEOS's rectangle clip; a proper intersection where that comes out invalid)."""
    out = shapely.clip_by_rect(np.asarray(geoms, dtype=object), *box)
    bad = ~shapely.is_valid(out)
    if bad.any():
        out[bad] = shapely.intersection(np.asarray(geoms, dtype=object)[bad], shapely.box(*box))
    return out


def _split_by_lobes(geoms, group, lobes, lobe_group) -> np.ndarray:
    """The parts of each group's geometry, handed to the lobe of that group that holds each part.

    ``geoms[g]`` lies inside the union of the lobes ``lobes[lobe_group == g]``
    (polygons touching only at vertices), kept clear of their rings, so that
    every part of it lies in one lobe.  Returns one geometry per lobe
    (empty when no part lies in it).
    """
    out = np.full(len(lobes), shapely.Polygon(), dtype=object)
    parts, pg = shapely.get_parts(np.asarray(geoms, dtype=object)[group], return_index=True)
    if not len(parts):
        return out
    pg = np.asarray(group)[pg]
    host = containing(shapely.point_on_surface(parts), lobes)
    ok = host >= 0
    ok[ok] = np.asarray(lobe_group)[host[ok]] == pg[ok]
    parts, host = parts[ok], host[ok]
    o = np.argsort(host, kind="stable")
    parts, host = parts[o], host[o]
    one = np.bincount(host, minlength=len(lobes)) == 1
    single = one[host]
    out[host[single]] = parts[single]
    if (~single).any():
        out[np.unique(host[~single])] = shapely.multipolygons(
            parts[~single], indices=np.unique(host[~single], return_inverse=True)[1].ravel()
        )
    return out


def shrink_city(
    faces, fid, hw, bf: BlockFaces, width, sidewalk: float, *, by_street, bare, dead_ends: bool = True, canonical=False
):
    """Street, sidewalk and block of every face, the streets inside the faces cut out.

    Parameters
    ----------
    faces : ndarray of shapely.Polygon (k,)
        The faces kept, ``bf.faces[fid]``.
    fid : ndarray of int64 (k,)
    hw : ndarray of float (k,)
        Mean street half-width of each face (m; :func:`face_half_widths`).
    bf : BlockFaces
    width : ndarray of float
        Street width per row (``bf.src``; m).
    sidewalk : float
        Sidewalk width (m).
    by_street : ndarray of bool (k,)
        Faces shrunk side by side (:func:`shrink_faces_by_street`), the rest
        by their mean half-width (:func:`shrink_faces`).
    bare : ndarray of bool
        Segments of ``bf`` that are no streets (closing edges).
    dead_ends : bool
        Cut the streets inside the faces (dead ends, connectors) out of
        their blocks; else they get street polygons of their own over them.
    canonical : bool
        The faces are in canonical form (:func:`canonical_faces`): so are
        then the faces with spurs, whatever walk traced them.

    Returns
    -------
    street, walk, block : ndarray of shapely.Geometry (k,)
        As :func:`shrink_faces` gives them: they partition each face.
    seg : ndarray of int64
        The dead-end segments of ``bf`` left outside every block: they need
        street polygons of their own.
    counts : dict
        ``dead_ends_cut`` (rows cut out of a block).

    Notes
    -----
    A dead end hanging from a face's ring is a spur of it
    (:func:`sengine.geom.planar.spur_polygons`): the face's insets keep
    clear of it in the same buffer (with round joins, which GEOS offsets
    robustly round a spur's tip), so it costs little more.  In a face
    shrunk by its mean half-width the spur takes that width too.  A face
    pinched at a vertex into several lobes is shrunk as its whole walk and
    the pieces are handed to the lobes.  Trees floating inside a face are
    cut out with :func:`cut_inner_streets`.
    """
    k = len(faces)
    counts = {"dead_ends_cut": 0}
    shape = faces.copy()
    spiky = np.zeros(k, bool)  # shaped with spurs: inset with round joins
    pinched = np.zeros(0, np.int64)
    slot = np.full(len(bf.faces), -1, np.int64)
    slot[fid] = np.arange(k)
    if dead_ends:
        sid, spoly, spurs, lobes = spur_polygons(bf, bf.xy)
        if canonical:
            spoly = canonical_faces(spoly)
    else:
        sid, spoly = np.empty(0, np.int64), np.empty(0, dtype=object)
        spurs, lobes = np.empty((0, 3), np.int64), np.empty((0, 2), np.int64)
    at = slot[sid]
    # the face of each spur: the slot of its polygon, or of the lobe of its pinched face that holds it
    n_xy = max(len(bf.xy), 1)
    skey = spurs[:, 0] * n_xy + spurs[:, 1]
    sface = at[spurs[:, 2]]
    if len(lobes):
        lobe_slot = slot[lobes[:, 1]]
        lobes = lobes[lobe_slot >= 0]
        in_lobe = np.flatnonzero(np.isin(spurs[:, 2], lobes[:, 0]))
        mid = shapely.points((bf.xy[spurs[in_lobe, 0]] + bf.xy[spurs[in_lobe, 1]]) / 2.0)
        host = containing(mid, faces[slot[lobes[:, 1]]])
        sface[in_lobe] = np.where(host >= 0, slot[lobes[np.maximum(host, 0), 1]], -1)
    o = np.argsort(skey)
    seg, inside = inner_segments(bf, faces, known=(skey[o], sface[o]))
    key = np.minimum(bf.u[seg], bf.v[seg]) * n_xy + np.maximum(bf.u[seg], bf.v[seg])
    spurred = np.isin(key, skey) & (inside >= 0)
    if dead_ends and len(seg):
        counts["dead_ends_cut"] = int(len(np.unique(bf.src[seg[inside >= 0]])))
        # pinched faces: shrunk apart, as one walk; their lobes are left empty here
        pinched = np.unique(lobes[:, 0])
        lobe_slot = slot[lobes[:, 1]]
        plain = np.ones(len(sid), bool)
        plain[pinched] = False
        shape[at[plain & (at >= 0)]] = spoly[plain & (at >= 0)]
        spiky[at[plain & (at >= 0)]] = True
        shape[lobe_slot[lobe_slot >= 0]] = shapely.Polygon()
    street = np.empty(k, dtype=object)
    walk, block = street.copy(), street.copy()
    seg_hw = segment_widths(bf, width) / 2.0
    m = ~by_street
    if m.any():
        street[m], walk[m], block[m] = shrink_faces(faces[m], hw[m], sidewalk, shape=shape[m], rounded=spiky[m])
    if by_street.any():
        pos = np.cumsum(by_street) - 1
        own = spurred & by_street[np.maximum(inside, 0)]
        street[by_street], walk[by_street], block[by_street] = shrink_faces_by_street(
            faces[by_street],
            bf,
            fid[by_street],
            seg_hw,
            sidewalk,
            bare=bare,
            shape=shape[by_street],
            inner=(seg[own], pos[inside[own]]),
            rounded=spiky[by_street],
        )
    if len(pinched):
        lobe_slot = slot[lobes[:, 1]]
        big = at[pinched]  # the largest lobe's slot (its face's mean width and side widths)
        live = big >= 0
        grp = np.flatnonzero(live)
        gshape, gslot = spoly[pinched[grp]], big[grp]
        sel = np.isin(lobes[:, 0], pinched[grp]) & (lobe_slot >= 0)
        lgroup = np.searchsorted(pinched[grp], lobes[sel, 0])
        lslot = lobe_slot[sel]
        bys = by_street[gslot]
        edge_g = np.empty(len(grp), dtype=object)
        block_g = edge_g.copy()
        if (~bys).any():
            edge_g[~bys] = inset(gshape[~bys], hw[gslot[~bys]], rounded=np.ones((~bys).sum(), bool))
            block_g[~bys] = inset(gshape[~bys], hw[gslot[~bys]] + sidewalk, rounded=np.ones((~bys).sum(), bool))
        if bys.any():
            sl = gslot[bys]
            own = spurred & np.isin(inside, sl)
            ipos = np.searchsorted(sl, inside[own], sorter=np.argsort(sl))
            ipos = np.argsort(sl)[ipos]
            d1 = np.where(bare, np.nan, seg_hw)
            d2 = d1 + sidewalk
            args = (faces[sl], bf, fid[sl])
            kw = {"shape": gshape[bys], "inner": (seg[own], ipos), "rounded": np.ones(bys.sum(), bool)}
            edge_g[bys] = inset_by_street(*args, d1, **kw)
            block_g[bys] = inset_by_street(*args, d2, **kw)
        ledge = _split_by_lobes(edge_g, lgroup, faces[lslot], lgroup)
        lblock = _split_by_lobes(block_g, lgroup, faces[lslot], lgroup)
        street[lslot] = _ring_between(faces[lslot], ledge, gap=~by_street[lslot] & (hw[lslot] > 0))
        walk[lslot] = _ring_between(ledge, lblock, gap=np.full(len(lslot), sidewalk > 0))
        block[lslot] = lblock
    if dead_ends:
        # the rest inside a face (trees floating in it): cut out one by one
        cut = (inside >= 0) & ~spurred
        seg_cut = seg[cut]
        if len(seg_cut):
            segs = shapely.linestrings(np.stack([bf.xy[bf.u[seg_cut]], bf.xy[bf.v[seg_cut]]], axis=1))
            street, walk, block = cut_inner_streets(
                faces, street, walk, block, segs, inside[cut], width[bf.src[seg_cut]] / 2.0, sidewalk
            )
        seg = seg[inside < 0]
    return street, walk, block, seg, counts


#: Ids a major-road enclosure gives its faces and its blocks: ``enclosure id x ID_SPAN + rank``.
ID_SPAN = 10_000
#: Key of a road layer's ``meta``: the rows of the ``areas`` whose faces a shard keeps (empty: the faces
#: outside every area), set by :mod:`sengine.shard`.
SHARD_KEY = "shard_areas"


def canonical_faces(faces) -> np.ndarray:
    """Faces in one form whatever walk traced them: each ring from its lowest vertex, shell counter-clockwise.

    ``shapely.normalize`` starts every ring at the same vertex and sorts the
    holes; reversing it turns the shell back counter-clockwise (holes
    clockwise), as the walk gives them.  A face traced in a shard of the
    street graph is then the same polygon, coordinate for coordinate, as in
    the whole graph.
    """
    faces = np.asarray(faces, dtype=object)
    return shapely.reverse(shapely.normalize(faces)) if len(faces) else faces


def face_order(faces, host, n_areas: int) -> np.ndarray:
    """Order of the faces by enclosure (``host``, row of the areas; -1 last), then by their bounds.

    Bounds come from the coordinates alone, so the order is the same for
    any subset of the enclosures; faces with equal bounds (two triangles
    of a square) are told apart by their centroid.
    """
    if not len(faces):
        return np.zeros(0, np.int64)
    b = shapely.bounds(faces)
    c = np.round(shapely.get_coordinates(shapely.centroid(faces)), 6)
    h = np.where(np.asarray(host) >= 0, host, n_areas)
    return np.lexsort((c[:, 1], c[:, 0], b[:, 3], b[:, 2], b[:, 1], b[:, 0], h))


def ranked_ids(enclosure, *, where: str = "", what: str = "blocks") -> np.ndarray:
    """Ids ``enclosure x ID_SPAN + rank`` for features sorted by enclosure (rank: their place within it)."""
    enclosure = np.asarray(enclosure, np.int64)
    if not len(enclosure):
        return np.zeros(0, np.int64)
    first = np.r_[True, enclosure[1:] != enclosure[:-1]]
    start = np.maximum.accumulate(np.where(first, np.arange(len(enclosure)), 0))
    rank = np.arange(len(enclosure)) - start
    if rank.max() >= ID_SPAN:
        from sengine.errors import LimitError

        e = int(enclosure[int(np.argmax(rank))])
        raise LimitError(
            f"enclosure {e} holds more than {ID_SPAN:,} {what}; make the minor-road spacing larger", where=where
        )
    return enclosure * ID_SPAN + rank


#: How near (m) a road's midpoint must be to an enclosure to count as on its boundary.
SHARD_TOLERANCE = 0.01


def shard_lines(lines, areas, rows) -> np.ndarray:
    """Which road lines a shard of the enclosures traces its faces on.

    Parameters
    ----------
    lines : ndarray of shapely.LineString
        The whole city's noded street graph (each line from node to node).
    areas : ndarray of shapely.Polygon
        The enclosures (areas enclosed by major roads).
    rows : array_like of int
        The shard's enclosures (rows of ``areas``); empty: the remainder,
        the land outside every enclosure.

    Returns
    -------
    ndarray of bool
        For a shard, the lines inside or on the boundary of its enclosures
        (midpoint within :data:`SHARD_TOLERANCE`): their faces are exactly
        the whole graph's faces inside those enclosures, since the graph is
        noded once and no line crosses an enclosure's boundary.  For the
        remainder, every line not strictly inside an enclosure: its faces
        are the enclosures themselves (dropped by their host) and the faces
        outside them.
    """
    return _select_lines(_line_hosts(lines, areas), rows)


def _line_hosts(lines, areas) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
    """``(n, li, ai, deep)``: the (line, enclosure) pairs of lines in or on an enclosure, and which are inside."""
    lines = np.asarray(lines, dtype=object)
    if not len(lines):
        return 0, np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, bool)
    mid = shapely.line_interpolate_point(lines, 0.5, normalized=True)
    li, ai = shapely.STRtree(areas).query(mid, predicate="dwithin", distance=SHARD_TOLERANCE)
    edge = shapely.distance(mid[li], shapely.boundary(np.asarray(areas, dtype=object)[ai])) <= SHARD_TOLERANCE
    deep = ~edge & shapely.within(mid[li], np.asarray(areas, dtype=object)[ai])
    return len(lines), li, ai, deep


def _select_lines(hosts, rows) -> np.ndarray:
    n, li, ai, deep = hosts
    rows = np.asarray(rows, np.int64)
    keep = np.zeros(n, bool)
    if len(rows):
        keep[li[np.isin(ai, rows)]] = True
    else:
        keep[:] = True
        keep[li[deep]] = False
    return keep


def street_graph(bf: BlockFaces) -> nx.Graph:
    """The traced street graph as a networkx Graph.

    Nodes are node ids with attribute ``xy``; edges carry ``src`` (input
    index), ``length`` (m), ``faces`` (left, right face ids) and ``bridge``.
    """
    import networkx as nx  # here: a run does not need it, and its import is slow

    g = nx.Graph()
    g.add_nodes_from((i, {"xy": tuple(p)}) for i, p in enumerate(bf.xy.tolist()))
    length = np.hypot(*(bf.xy[bf.v] - bf.xy[bf.u]).T)
    g.add_edges_from(
        (int(a), int(b), {"src": int(s), "length": float(ln), "faces": (int(fl), int(fr)), "bridge": bool(br)})
        for a, b, s, ln, (fl, fr), br in zip(bf.u, bf.v, bf.src, length, bf.edge_faces, bf.bridge)
    )
    return g


@register
class BlocksCircuits(SENode):
    """Blocks as minimal closed circuits of the street graph, shrunk for streets and sidewalks (§5.4)."""

    name = "blocks.circuits"
    inputs = {
        "roads": Port("roads", "street centre lines with a width column"),
        "outline": Port("outline", "buildable city: faces outside it are dropped", required=False),
        "areas": Port("areas", "areas enclosed by major roads: give blocks their district", required=False),
        "graph": Port(
            "graph", "the plane graph roads.clean traced (its faces are taken over when they fit)", required=False
        ),
    }
    outputs = {
        "blocks": Port("blocks", "blocks, shrunk for streets and sidewalks"),
        "streets": Port("polygons", "street surface around each block, kind 'street'"),
        "sidewalks": Port("polygons", "sidewalk ring of each block, kind 'sidewalk'"),
        "faces": Port("blocks", "faces between street centre lines, before shrinking"),
    }
    params = {
        "sidewalk": Param("float", 3.0, min=0.0, max=50.0, unit="m", doc="sidewalk width"),
        "street_width": Param(
            "float",
            10.0,
            min=0.0,
            max=200.0,
            unit="m",
            doc="street width where the roads carry none (or 'width_from' is param)",
        ),
        "width_from": Param(
            "str",
            "roads",
            choices=("roads", "param"),
            doc="street widths from the roads' width column, or street_width for all",
        ),
        "inset": Param(
            "str",
            "mean",
            choices=("mean", "street"),
            doc="shrink each face by the mean half-width of its streets, or each side by its own "
            "street's (a few times slower on a whole city)",
        ),
        "min_area": Param("float", 50.0, min=0.0, unit="m2", doc="faces and blocks smaller than this are dropped"),
        "node": Param("bool", True, doc="split crossing segments first (turn off only for plane input)"),
        "dead_ends": Param(
            "str",
            "cut",
            choices=("cut", "over"),
            doc="streets inside a block (cul-de-sacs, connectors): cut their street and sidewalk out of it, "
            "so that lots front onto them, or lay their street surface over the block",
        ),
        "bridges": Param(
            "str",
            "cut",
            choices=("cut", "over"),
            doc="bridges and ways on another layer cross blocks without splitting them: keep the ground "
            "under their deck out of the block (no lot under a bridge), or leave it to the block",
        ),
        "decimals": Param("int", 6, min=0, max=12, unit="1", doc="merge nodes equal to this many decimals (m)"),
    }

    shard_port = "areas"

    def shard_inputs(self, inputs: dict, rows) -> dict:
        roads, areas = inputs["roads"], inputs.get("areas")
        rows = np.asarray(rows, np.int64)
        if areas is None or not len(areas):
            return inputs
        key = (id(roads), id(areas))
        cache = getattr(self, "_shard_cache", None)
        if cache is None or cache[0] != key:  # once per process: where each line lies
            cache = self._shard_cache = (key, _line_hosts(roads.geometry, areas.geometry))
        keep = _select_lines(cache[1], rows)
        return {**inputs, "roads": roads.take(np.flatnonzero(keep)).with_meta(**{SHARD_KEY: rows})}

    def run(
        self,
        *,
        roads: Layer,
        outline: Layer | None = None,
        areas: Layer | None = None,
        graph: Layer | None = None,
    ):
        meta = {k: v for k, v in roads.meta.items() if k != SHARD_KEY}  # the roads' shard, not the blocks'
        report: dict = {}
        lines = roads.geometry
        n = len(roads)
        keep = ~shapely.is_empty(lines) if n else np.zeros(0, bool)
        width = np.full(n, self.p.street_width)
        if self.p.width_from == "roads" and "width" in roads:
            w = np.asarray(roads["width"], np.float64)
            width = np.where(np.isfinite(w) & (w >= 0), w, self.p.street_width)
        ground = ground_level(roads) & keep
        bf = None
        if not self.p.node and keep.all():  # faces roads.clean traced already
            bf = traced_faces(graph, n, decimals=self.p.decimals)
        if bf is None:
            rows = np.flatnonzero(ground)
            closing = roads.meta.get("closing")
            traced = lines[rows] if closing is None else np.r_[lines[rows], np.array([closing], dtype=object)]
            bf = find_blocks(traced, node=self.p.node, decimals=self.p.decimals)
            bf = replace(bf, src=np.where(bf.src < len(rows), rows[np.minimum(bf.src, max(len(rows) - 1, 0))], -1))
        report.update({k: int(v) for k, v in bf.counts.items()})
        bare = bf.src < 0  # closing edges: no street, no sidewalk
        faces = bf.faces
        fid = np.arange(len(faces))
        hw = face_half_widths(bf, width)
        valid = threaded(shapely.is_valid, faces) if len(faces) else np.zeros(0, bool)
        report["dropped_invalid"] = int((~valid).sum())
        area = shapely.area(faces)
        small = valid & (area < self.p.min_area)
        report["dropped_small"] = int(small.sum())
        ok = valid & ~small
        if outline is not None and len(outline) and ok.any():
            city = shapely.union_all(outline.geometry)
            shapely.prepare(city)
            inside = np.zeros(len(faces), bool)
            inside[ok] = shapely.contains(city, shapely.point_on_surface(faces[ok]))
            report["dropped_outside_outline"] = int((ok & ~inside).sum())
            ok &= inside
        faces, fid, hw = faces[ok], fid[ok], hw[ok]
        host = None
        if areas is not None and len(areas):
            # faces in a canonical form and order, with ids derived from them (not from the walk's
            # order): the same for the whole city and for a shard of its enclosures (sengine.shard)
            host = containing(shapely.point_on_surface(faces), areas.geometry)
            shard = roads.meta.get(SHARD_KEY)
            if shard is not None:
                mine = np.isin(host, np.asarray(shard, np.int64)) if len(shard) else host < 0
                report["dropped_other_shards"] = int((~mine).sum())
                faces, fid, hw, host = faces[mine], fid[mine], hw[mine], host[mine]
            faces = canonical_faces(faces)
            o = face_order(faces, host, len(areas))
            faces, fid, hw, host = faces[o], fid[o], hw[o], host[o]
        closed = np.zeros(len(bf.faces), bool)  # faces with a closing edge
        ef = bf.edge_faces[bare].ravel()
        closed[ef[ef >= 0]] = True
        closed = closed[fid]
        by_street = np.full(len(faces), self.p.inset == "street")
        street, walk, block, seg, counts = shrink_city(
            faces,
            fid,
            hw,
            bf,
            width,
            self.p.sidewalk,
            by_street=by_street,
            bare=bare,
            dead_ends=self.p.dead_ends == "cut",
            canonical=host is not None,
        )
        report.update(counts)
        box = roads.meta.get("bbox")
        if box is not None and closed.any():  # the land round the streets, clipped back to their box
            for arr in (faces, street, walk, block):
                arr[closed] = clip_to_box(arr[closed], box)
        # bridges and tunnels: over or under the blocks, closing none
        off = keep & ~ground
        tunnel = np.asarray(roads["tunnel"], bool) if "tunnel" in roads else np.zeros(n, bool)
        deck = np.flatnonzero(off & ~tunnel)
        deck_lines = shapely.get_parts(lines[deck], return_index=True) if len(deck) else (lines[:0], deck)
        deck_rows = deck[deck_lines[1]] if len(deck) else deck
        deck_lines = deck_lines[0]
        report["bridges_over_blocks"] = report["tunnels_under_blocks"] = 0
        if len(block) and (off.any()):
            live = ~shapely.is_empty(block)
            tree = shapely.STRtree(np.where(live, block, None))
            if len(deck_lines):
                li, bi = tree.query(deck_lines, predicate="intersects")
                report["bridges_over_blocks"] = int(len(np.unique(deck_rows[li])))
                if self.p.bridges == "cut" and len(li):
                    block = subtract_buffers(block, deck_lines[li], bi, width[deck_rows[li]] / 2.0, cap_style="flat")
            under = np.flatnonzero(off & tunnel)
            if len(under):
                report["tunnels_under_blocks"] = int(
                    len(np.unique(tree.query(lines[under], predicate="intersects")[0]))
                )
        gone = shapely.is_empty(block)
        report["vanished_by_inset"] = int(gone.sum())
        parts, pidx = shapely.get_parts(block, return_index=True)
        parts, pidx = parts[~gone[pidx]], pidx[~gone[pidx]]
        big = shapely.area(parts) >= self.p.min_area
        report["dropped_small_after_inset"] = int((~big).sum())
        parts, pidx = parts[big], pidx[big]
        report["split_by_inset"] = int(len(pidx) - len(np.unique(pidx)))
        report["closed_by_bbox"] = int(closed[pidx].sum())
        # districts and parent areas
        district = np.full(len(parts), -1, np.int64)
        parent = np.full(len(parts), -1, np.int64)
        fdistrict = np.full(len(faces), -1, np.int64)
        fparent = np.full(len(faces), -1, np.int64)
        block_ids = face_ids = street_ids = walk_ids = None
        if host is not None:
            has = host >= 0
            fparent[has] = areas.ids[host[has]]
            if "district" in areas:
                fdistrict[has] = np.asarray(areas["district"], np.int64)[host[has]]
            district, parent = fdistrict[pidx], fparent[pidx]
            enclosure = np.where(has, areas.ids[np.maximum(host, 0)], int(areas.ids.max()) + 1)
            face_ids = ranked_ids(enclosure, where=self.where, what="faces")
            block_ids = ranked_ids(enclosure[pidx], where=self.where, what="blocks")
        report["blocks"] = int(len(parts))
        log.info("%s: %d faces -> %d blocks (%s)", self.where, len(bf.faces), len(parts), report)
        battrs = {"district": district, "face": fid[pidx] if face_ids is None else face_ids[pidx]}
        if bare.any():
            battrs["closed"] = closed[pidx]
        blocks = Layer.from_geoms(parts, ids=block_ids, parent=parent, meta=meta, **battrs)
        faces_l = Layer.from_geoms(
            faces,
            ids=fid if face_ids is None else face_ids,
            parent=fparent,
            meta=meta,
            district=fdistrict,
            half_width=hw,
        )
        # dead ends and connectors outside the faces: their street surface as flat-capped rectangles
        a, b = bf.xy[bf.u[seg]], bf.xy[bf.v[seg]]
        ln = np.hypot(*(b - a).T)
        hwd = width[bf.src[seg]] / 2.0
        dead_poly = (
            frame_boxes((a + b) / 2.0, (b - a) / np.maximum(ln, 1e-12)[:, None], -ln / 2.0, ln / 2.0, -hwd, hwd)
            if len(a)
            else np.empty(0, object)
        )
        deck_poly = shapely.buffer(deck_lines, width[deck_rows] / 2.0, cap_style="flat", quad_segs=4)
        sgeom = np.concatenate([street, dead_poly, deck_poly])
        skind = np.r_[np.full(len(street) + len(dead_poly), "street"), np.full(len(deck_poly), "bridge")]
        live = ~shapely.is_empty(sgeom)
        wlive = ~shapely.is_empty(walk)
        if face_ids is not None:  # a face's street and sidewalk take its id; the others their road's, after
            beyond = (int(areas.ids.max()) + 2) * ID_SPAN
            street_ids = np.r_[face_ids, beyond + bf.src[seg], beyond + deck_rows][live]
            walk_ids = face_ids[wlive]
        streets = Layer.from_geoms(sgeom[live], ids=street_ids, meta=meta, kind=skind[live])
        wgeom = walk[wlive]
        walks = Layer.from_geoms(wgeom, ids=walk_ids, meta=meta, kind=np.full(len(wgeom), "sidewalk"))
        return NodeResult({"blocks": blocks, "streets": streets, "sidewalks": walks, "faces": faces_l}, report)

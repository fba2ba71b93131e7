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
``meta["graph"]`` (:func:`traced_faces`: same faces, same order).

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

from sengine import Layer, Param, Port, SENode, register
from sengine.geom.planar import PlanarFaces, planar_faces
from sengine.geom.polygons import containing, frame_boxes, inset, threaded
from sengine.geom.segments import merge_points, planarize, segments_from_lines

if TYPE_CHECKING:
    import networkx as nx

__all__ = [
    "find_blocks",
    "BlockFaces",
    "traced_faces",
    "face_half_widths",
    "shrink_faces",
    "inset_by_street",
    "shrink_faces_by_street",
    "street_graph",
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


def traced_faces(meta: dict, rows: int, *, decimals: int | None) -> BlockFaces | None:
    """The faces a road layer already carries, when they are what :func:`find_blocks` would give.

    ``roads.clean`` traces the faces of its plane segment graph once (to find
    slivers) and hands them on in ``meta["graph"]``, its nodes numbered as
    the lines entry numbers them after merging to ``graph["decimals"]``
    (set only when that merges no two nodes).  They are taken over when the
    graph belongs to exactly these ``rows`` and was numbered for these
    ``decimals``: then they are the faces, in the order, that
    ``find_blocks(lines, node=False, decimals=decimals)`` gives.

    Returns
    -------
    BlockFaces or None
        With ``src`` indexing the rows, as the lines entry gives it.
    """
    g = meta.get("graph")
    if not isinstance(g, dict) or g.get("rows") != rows or not isinstance(g.get("blocks"), BlockFaces):
        return None
    if g.get("decimals") is None or g.get("decimals") != decimals:
        return None
    bf = g["blocks"]
    return replace(bf, src=np.asarray(g["row"], np.int64)[bf.src], counts=dict(bf.counts))


def face_half_widths(bf: BlockFaces, widths) -> np.ndarray:
    """Length-weighted mean half-width of the streets around each face (m).

    Parameters
    ----------
    bf : BlockFaces
    widths : array_like of float
        Street width (m) per input line / input edge (indexed by ``bf.src``).
    """
    widths = np.asarray(widths, np.float64)
    nf = len(bf.faces)
    if nf == 0:
        return np.zeros(0)
    seg_len = np.hypot(*(bf.xy[bf.v] - bf.xy[bf.u]).T)
    hw = widths[bf.src] / 2.0
    f = bf.edge_faces.ravel()
    w = np.repeat(seg_len, 2)
    h = np.repeat(hw, 2)
    ok = f >= 0
    tot = np.bincount(f[ok], weights=w[ok], minlength=nf)
    acc = np.bincount(f[ok], weights=(w * h)[ok], minlength=nf)
    return np.where(tot > 0, acc / np.where(tot > 0, tot, 1.0), 0.0)


def shrink_faces(faces, half_width, sidewalk: float):
    """Street, sidewalk and block polygons of each face (§5.4, last paragraph).

    Parameters
    ----------
    faces : array_like of shapely.Polygon
        Faces between street centre lines.
    half_width : array_like of float
        Half the street width around each face (m).
    sidewalk : float
        Sidewalk width (m).

    Returns
    -------
    street, walk, block : ndarray of shapely.Geometry
        ``face - inset(face, hw)``, ``inset(face, hw) - block`` and
        ``block = inset(face, hw + sidewalk)``; the three partition the face.
        ``block`` may be empty (face too thin) or a MultiPolygon.
    """
    faces = np.asarray(faces, dtype=object)
    hw = np.asarray(half_width, np.float64)
    edge = inset(faces, hw)
    if sidewalk <= 0:
        return _ring_between(faces, edge, gap=hw > 0), _ring_between(edge, edge, gap=np.zeros(len(faces), bool)), edge
    # a face with nothing left inside its street surface has no block either: no second inset for it
    block = edge.copy()
    live = np.flatnonzero(~shapely.is_empty(edge))
    with ThreadPoolExecutor(1) as pool:  # the second inset (GEOS threads) while this thread makes the streets
        blocks = pool.submit(inset, faces[live], hw[live] + sidewalk)
        street = _ring_between(faces, edge, gap=hw > 0)
        block[live] = blocks.result()
    return street, _ring_between(edge, block, gap=np.ones(len(faces), bool)), block


def inset_by_street(faces, bf: BlockFaces, face_ids, segment_distance) -> np.ndarray:
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
        Distance (m) to move off each segment of ``bf`` (its ``u``, ``v``).

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
    pos = np.full(len(bf.faces), -1, np.int64)
    pos[np.asarray(face_ids, np.int64)] = np.arange(len(faces))
    seg = np.repeat(np.arange(len(bf.u)), 2)
    owner = bf.edge_faces.ravel()
    owner = np.where(owner >= 0, pos[np.maximum(owner, 0)], -1)
    seg, owner = seg[owner >= 0], owner[owner >= 0]
    dist = np.asarray(segment_distance, np.float64)[seg]
    nearest = np.full(len(faces), np.inf)
    np.minimum.at(nearest, owner, dist)
    out = inset(faces, np.where(np.isfinite(nearest), np.maximum(nearest, 0.0), 0.0))
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


def shrink_faces_by_street(faces, bf: BlockFaces, face_ids, segment_half_width, sidewalk: float):
    """:func:`shrink_faces` with each side moved by its own street's half-width (and the sidewalk)."""
    faces = np.asarray(faces, dtype=object)
    hw = np.asarray(segment_half_width, np.float64)
    edge = inset_by_street(faces, bf, face_ids, hw)
    block = inset_by_street(faces, bf, face_ids, hw + sidewalk) if sidewalk > 0 else edge
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


def _ring_between(outer, inner, gap=None):
    """``outer - inner`` where ``inner`` lies inside ``outer``.

    Where ``gap`` is set (``inner`` an inset of ``outer`` by a positive
    distance, so no ring of one touches a ring of the other), an ``outer``
    Polygon and an ``inner`` Polygon or MultiPolygon without holes give the
    result directly: ``outer``'s rings with ``inner``'s shells as more
    holes; an empty ``inner`` gives ``outer``.  The rest goes through
    ``shapely.difference``.
    """
    out = np.empty(len(outer), dtype=object)
    if len(outer) == 0:
        return out
    gap = np.ones(len(outer), bool) if gap is None else np.asarray(gap, bool)
    empty = shapely.is_empty(inner)
    tin = shapely.get_type_id(inner)
    simple_in = ((tin == 3) & (shapely.get_num_interior_rings(inner) == 0)) | (tin == 6)
    direct = gap & (shapely.get_type_id(outer) == 3) & ~empty & simple_in
    if np.any(direct & (tin == 6)):  # a MultiPolygon qualifies only when no part has holes
        m = np.flatnonzero(direct & (tin == 6))
        parts, pidx = shapely.get_parts(inner[m], return_index=True)
        holed = np.zeros(len(m), bool)
        holed[pidx[shapely.get_num_interior_rings(parts) > 0]] = True
        direct[m[holed]] = False
    same = gap & empty
    out[same] = outer[same]
    idx = np.flatnonzero(direct)
    if len(idx):
        orings, oi = shapely.get_rings(outer[idx], return_index=True)
        parts, pi = shapely.get_parts(inner[idx], return_index=True)
        rings = np.concatenate([orings, shapely.get_exterior_ring(parts)])
        owner = np.concatenate([oi, pi])
        # per result: outer shell, outer holes, then inner shells (get_rings lists the shell first)
        o = np.argsort(owner, kind="stable")
        out[idx] = shapely.polygons(rings[o], indices=owner[o])
    rest = ~direct & ~same
    if rest.any():
        out[rest] = threaded(shapely.difference, outer[rest], inner[rest], min_size=64)  # big, holed faces
    return out


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
        "decimals": Param("int", 6, min=0, max=12, unit="1", doc="merge nodes equal to this many decimals (m)"),
    }

    def run(self, *, roads: Layer, outline: Layer | None = None, areas: Layer | None = None):
        meta = {k: v for k, v in roads.meta.items() if k != "graph"}  # the roads' graph, not the blocks'
        report: dict = {}
        lines = roads.geometry
        keep = ~shapely.is_empty(lines) if len(lines) else np.zeros(0, bool)
        lines = lines[keep]
        width = np.full(len(lines), self.p.street_width)
        if self.p.width_from == "roads" and "width" in roads:
            w = np.asarray(roads["width"], np.float64)[keep]
            width = np.where(np.isfinite(w) & (w >= 0), w, self.p.street_width)
        bf = None
        if not self.p.node and keep.all():  # faces roads.clean traced already
            bf = traced_faces(roads.meta, len(roads), decimals=self.p.decimals)
        if bf is None:
            bf = find_blocks(lines, node=self.p.node, decimals=self.p.decimals)
        report.update({k: int(v) for k, v in bf.counts.items()})
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
        if self.p.inset == "street":
            street, walk, block = shrink_faces_by_street(faces, bf, fid, width[bf.src] / 2.0, self.p.sidewalk)
        else:
            street, walk, block = shrink_faces(faces, hw, self.p.sidewalk)
        gone = shapely.is_empty(block)
        report["vanished_by_inset"] = int(gone.sum())
        parts, pidx = shapely.get_parts(block, return_index=True)
        parts, pidx = parts[~gone[pidx]], pidx[~gone[pidx]]
        big = shapely.area(parts) >= self.p.min_area
        report["dropped_small_after_inset"] = int((~big).sum())
        parts, pidx = parts[big], pidx[big]
        report["split_by_inset"] = int(len(pidx) - len(np.unique(pidx)))
        # districts and parent areas
        district = np.full(len(parts), -1, np.int64)
        parent = np.full(len(parts), -1, np.int64)
        fdistrict = np.full(len(faces), -1, np.int64)
        fparent = np.full(len(faces), -1, np.int64)
        if areas is not None and len(areas):
            host = containing(shapely.point_on_surface(faces), areas.geometry)
            has = host >= 0
            fparent[has] = areas.ids[host[has]]
            if "district" in areas:
                fdistrict[has] = np.asarray(areas["district"], np.int64)[host[has]]
            district, parent = fdistrict[pidx], fparent[pidx]
        report["blocks"] = int(len(parts))
        self.report = report
        log.info("%s: %d faces -> %d blocks (%s)", self.where, len(bf.faces), len(parts), report)
        blocks = Layer.from_geoms(parts, parent=parent, meta=meta, district=district, face=fid[pidx])
        faces_l = Layer.from_geoms(faces, ids=fid, parent=fparent, meta=meta, district=fdistrict, half_width=hw)
        # dead ends and connectors: their street surface as flat-capped rectangles
        a, b = bf.xy[bf.u[bf.bridge]], bf.xy[bf.v[bf.bridge]]
        ln = np.hypot(*(b - a).T)
        hwd = width[bf.src[bf.bridge]] / 2.0
        dead_poly = (
            frame_boxes((a + b) / 2.0, (b - a) / np.maximum(ln, 1e-12)[:, None], -ln / 2.0, ln / 2.0, -hwd, hwd)
            if len(a)
            else np.empty(0, object)
        )
        sgeom = np.concatenate([street, dead_poly])
        sgeom = sgeom[~shapely.is_empty(sgeom)]
        streets = Layer.from_geoms(sgeom, meta=meta, kind=np.full(len(sgeom), "street"))
        wgeom = walk[~shapely.is_empty(walk)]
        walks = Layer.from_geoms(wgeom, meta=meta, kind=np.full(len(wgeom), "sidewalk"))
        return {"blocks": blocks, "streets": streets, "sidewalks": walks, "faces": faces_l}

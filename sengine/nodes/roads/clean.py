"""Street-graph clean-up for real maps, between the roads and the blocks.

Blocks are the minimal closed circuits of the street graph (skylineEngine
002 §5.4, Fig. 8).  That holds for a *plane* graph whose edges meet only at
shared nodes; a real map (OpenStreetMap, a traced image, an OBJ) is not
quite one.  This module prepares it, on whole numpy arrays:

1. **Split** -- every line is cut at its junctions into street segments
   (:mod:`.junctions`).
2. **Duplicates** -- segments joining the same two junctions along the same
   path (within ``dup_tol``) are merged, the higher-ranked class kept; done
   first, so that twin ways (both directions of a street) are not cut at
   two slightly different crossing points.
3. **Crossings** -- two segments that cross without a shared node get one,
   and a segment end lying exactly on another segment gets a T-junction,
   but only on the same level: ways tagged ``bridge`` / ``tunnel`` or on
   different ``layer`` values pass over each other (in OSM most junctions
   are shared nodes already).  Then split and merge duplicates again.
4. **Dead ends** -- segments ending at a degree-1 node are dropped,
   repeatedly, until none is left: they bound no block.  Off
   (``dead_ends=false``) for real maps, where a cul-de-sac is a street the
   blocks node cuts out of its block so that lots front onto it.
5. **Ground level** -- the faces are traced on the ground-level graph only:
   bridges, tunnels and ways on another ``layer`` pass over or under the
   blocks and close none, so the faces on both sides of a bridge close
   where the ground streets close them.  They stay rows of the roads (the
   blocks node draws their street surface).
6. **Closing** -- with ``close="bbox"`` the graph is closed round the
   bounding box of the streets (and of ``meta["extent"]``, the data's
   extent an importer gives) (:func:`sengine.geom.segments.box_closure`),
   a margin beyond it: the land between the outermost streets and the edge
   of the data becomes a face too, which the blocks node clips back to the
   box (``meta["bbox"]``).  The closing edges are no streets (no row, no
   width); they go on in the graph with ``row`` -1 and as ``meta["closing"]``.
7. **Slivers** -- the thin faces between dual carriageways and the tiny
   traffic islands inside junctions are street surface, not blocks: faces
   narrower than ``sliver_width`` or smaller than ``island_area`` are found
   with the face tracer the blocks use (:mod:`.slivers`), counted (``slivers_merged``) and
   handed on as ``slivers`` (polygons of kind ``median`` / ``island``) to
   be drawn as street surface.  The faces are traced once: the plane
   segment graph and its faces go out on the ``graph`` port (kind
   ``graph``), numbered as ``blocks.circuits`` would number them with ``decimals``,
   which takes them over.  The graph keeps their edges, so the block
   faces still partition the city; the blocks node's street and sidewalk
   inset leaves nothing of them (``vanished_by_inset``).

Point identity is exact coordinate equality: the importers project every
shared node once, so shared nodes are bit-identical.

References
----------
.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
"""

from __future__ import annotations

import logging

import numpy as np
import shapely

from sengine import Layer, NodeResult, Param, Port, SENode, register
from sengine.geom.polygons import strtree_query
from sengine.geom.segments import argsort_int, box_closure, lines_from_groups, merge_points

from ..blocks.circuits import find_blocks, ground_level
from .junctions import Pieces, point_keys, split_at_junctions, take_pieces
from .slivers import find_slivers, segment_graph

__all__ = ["crossing_points", "clean_streets", "face_graph", "RoadsClean"]

log = logging.getLogger(__name__)

#: How far beyond the streets' bounding box the closing edges run (m): farther than any street
#: and sidewalk inset (``blocks.circuits`` allows 100 m + 50 m), so that the face round the
#: streets, clipped back to the box, keeps no street surface along it.
CLOSE_MARGIN = 250.0

#: Rank of highway classes when duplicates are merged: the first one wins.
CLASS_RANK = (
    "motorway",
    "trunk",
    "primary",
    "secondary",
    "tertiary",
    "unclassified",
    "residential",
    "living_street",
    "pedestrian",
    "service",
)


def crossing_points(
    xy: np.ndarray, line: np.ndarray, level: np.ndarray, key: np.ndarray | None = None, segs: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """Where segments of lines on the same level meet without a shared node.

    Proper crossings get a new node shared by both segments; a segment end
    lying exactly on another segment's interior (a T-junction) splits that
    segment at the end's node.  Collinear overlaps are left to the
    duplicate merge.

    Parameters
    ----------
    xy : ndarray (n, 2)
        Points of all lines, line after line.
    line : ndarray of int (n,)
        Line of each point (non-decreasing).
    level : ndarray of int (nlines,)
        Lines meet at a new junction only when their levels are equal.
    key : ndarray of int64 (n,), optional
        Node identity of each point (default: :func:`point_keys`).
    segs : ndarray of object, optional
        For each line of two points, its shapely LineString when one is at
        hand (None elsewhere); the other segments are made here.

    Returns
    -------
    at : ndarray of int64 (k,)
        For each point to insert, the index of the first point of the segment it splits.
    t : ndarray of float (k,)
        Its position along that segment, in (0, 1).
    point : ndarray (k, 2)
        The points; all copies of one junction are bit-identical.
    node : ndarray of int64 (k,)
        Node key of each inserted point: an existing key for a T-junction,
        else ``-1 - c`` for the c-th new crossing node.
    crossings : int
        Number of new crossing nodes.
    """
    empty = (np.empty(0, np.int64), np.empty(0), np.empty((0, 2)), np.empty(0, np.int64), 0)
    a = np.flatnonzero(line[1:] == line[:-1])
    if len(a) < 2:
        return empty
    key = point_keys(xy) if key is None else key
    p, q = xy[a], xy[a + 1]
    given = None if segs is None else np.asarray(segs, dtype=object)[line[a]]
    segs = np.empty(len(a), dtype=object)
    have = np.zeros(len(a), bool) if given is None else np.not_equal(given, None)
    if have.any():
        segs[have] = given[have]
    if not have.all():
        segs[~have] = shapely.linestrings(np.stack([p[~have], q[~have]], axis=1))
    i, j = strtree_query(shapely.STRtree(segs), segs)  # bounding boxes only
    sel = i < j
    i, j = i[sel], j[sel]
    ka, kb, kc, kd = key[a[i]], key[a[i] + 1], key[a[j]], key[a[j] + 1]
    sel = ~((ka == kc) | (ka == kd) | (kb == kc) | (kb == kd))
    sel &= level[line[a[i]]] == level[line[a[j]]]
    i, j = i[sel], j[sel]
    r, s = q[i] - p[i], q[j] - p[j]
    w = p[j] - p[i]
    den = r[:, 0] * s[:, 1] - r[:, 1] * s[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[:, 0] * s[:, 1] - w[:, 1] * s[:, 0]) / den
        u = (w[:, 0] * r[:, 1] - w[:, 1] * r[:, 0]) / den
    in_i, in_j = (t > 0) & (t < 1), (u > 0) & (u < 1)
    end_i, end_j = (t == 0) | (t == 1), (u == 0) | (u == 1)
    hit = (den != 0) & ((in_i & in_j) | (in_i & end_j) | (end_i & in_j))
    i, j, t, u, in_i, in_j = i[hit], j[hit], t[hit], u[hit], in_i[hit], in_j[hit]
    pt = p[i] + t[:, None] * (q[i] - p[i])
    node = np.full(len(i), -1, np.int64)
    for cond, idx in ((t == 0, a[i]), (t == 1, a[i] + 1), (u == 0, a[j]), (u == 1, a[j] + 1)):
        pt[cond] = xy[idx[cond]]
        node[cond] = key[idx[cond]]
    cross = node < 0
    ncross = int(cross.sum())
    node[cross] = -1 - np.arange(ncross)
    at = np.r_[a[i][in_i], a[j][in_j]]
    return at, np.r_[t[in_i], u[in_j]], np.r_[pt[in_i], pt[in_j]], np.r_[node[in_i], node[in_j]], ncross


def clean_streets(
    geoms: np.ndarray,
    *,
    ends: tuple[np.ndarray, np.ndarray] | None = None,
    level: np.ndarray | None = None,
    rank: np.ndarray | None = None,
    dup_tol: float = 0.5,
    dead_ends: bool = True,
) -> tuple[Pieces, np.ndarray, np.ndarray, dict]:
    """Node same-level crossings, split at junctions, merge duplicates, drop dead ends.

    Parameters
    ----------
    geoms : ndarray of shapely.LineString
        Street centre lines (m); MultiLineStrings are exploded.
    ends : (ndarray, ndarray) of int, optional
        Known topology of LineStrings that are already cut at their
        junctions: the node ids of each line's first and last point (as
        ``osm.read`` gives).  Inner points are then new nodes and no
        coordinate is compared; without it, equal coordinates are one node.
    level : ndarray of int, optional
        Per line; crossings are noded only between lines of equal level
        (give bridges and tunnels a level of their own).  All 0 when None.
    rank : ndarray of int, optional
        Per line; of duplicate segments the one with the lowest rank is kept.
    dup_tol : float
        Hausdorff distance (m) under which two segments between the same two
        junctions are one street.
    dead_ends : bool
        Drop dead ends (iteratively).

    Returns
    -------
    pieces : Pieces
        Street segments; ``pieces.line`` indexes ``geoms``.
    xy : ndarray (k, 2)
        The points ``pieces.vertex`` refers to.
    key : ndarray of int64 (k,)
        Node identity of each point.
    counts : dict
        ``crossings_noded``, ``t_junctions_noded``, ``duplicates_merged``,
        ``dead_ends_removed`` (segments).
    """
    geoms = np.asarray(geoms, dtype=object)
    plain = bool(len(geoms)) and bool(np.all(shapely.get_type_id(geoms) == 1))
    if plain:  # LineStrings are their own single part (get_parts would copy each one)
        parts, src = geoms, np.arange(len(geoms))
    else:
        parts, src = shapely.get_parts(geoms, return_index=True)
    xy, pidx = shapely.get_coordinates(parts, return_index=True)
    orig = np.arange(len(xy))  # where each point comes from (-1: added)
    # parts of one multi-line must stay apart: split them by part index instead of source line
    part_line = pidx.astype(np.int64)
    nparts = len(parts)
    level_p = np.zeros(nparts, np.int64) if level is None else np.asarray(level, np.int64)[src]
    counts = {"crossings_noded": 0, "t_junctions_noded": 0, "duplicates_merged": 0, "dead_ends_removed": 0}
    if ends is not None and nparts == len(geoms) and len(xy):
        eu, ev = (np.asarray(e, np.int64) for e in ends)
        top = int(max(eu.max(initial=-1), ev.max(initial=-1))) + 1
        key = top + np.arange(len(xy), dtype=np.int64)
        first = np.r_[True, part_line[1:] != part_line[:-1]]
        last = np.r_[part_line[1:] != part_line[:-1], True]
        key[first] = eu[part_line[first]]
        key[last] = ev[part_line[last]]
        known = True
    else:
        key = point_keys(xy)
        known = False
    r = np.zeros(len(geoms), np.int64) if rank is None else np.asarray(rank, np.int64)
    # merge duplicates first: twin ways would otherwise be cut at slightly different crossing points
    pieces = split_at_junctions(key, part_line, ends_only=known)
    keep, ndup = _duplicates(pieces, xy, key, r[src[pieces.line]], dup_tol)
    pieces = take_pieces(pieces, keep)
    npts = np.bincount(pidx, minlength=nparts)
    pstart = np.cumsum(npts) - npts
    segs = None
    if plain:  # a piece that is a whole two-point input line is its own segment: no new geometry
        size = np.bincount(pieces.piece, minlength=len(pieces))
        part = pieces.line
        two = (size == 2) & (npts[part] == 2) & (orig[pieces.first] == pstart[part])
        segs = np.where(two, parts[part], None)
    xy, key, part_line, part_of = xy[pieces.vertex], key[pieces.vertex], pieces.piece, pieces.line
    orig = orig[pieces.vertex]
    at, t, pt, node, ncross = crossing_points(xy, part_line, level_p[part_of], key, segs=segs)
    counts["crossings_noded"] = ncross
    counts["t_junctions_noded"] = int((node >= 0).sum())
    if len(at):
        order = np.lexsort((np.r_[np.zeros(len(xy)), t], np.r_[np.arange(len(xy)), at]))
        xy = np.r_[xy, pt][order]
        node = np.where(node < 0, int(key.max()) + 1 + (-1 - node), node)
        key = np.r_[key, node][order]
        part_line = np.r_[part_line, part_line[at]][order]
        orig = np.r_[orig, np.full(len(at), -1)][order]
    pieces = split_at_junctions(key, part_line)
    part = part_of[pieces.line]
    pieces.line = src[part]
    keep, ndup2 = _duplicates(pieces, xy, key, r[pieces.line], dup_tol)
    counts["duplicates_merged"] = ndup + ndup2
    if dead_ends:
        counts["dead_ends_removed"] = _drop_dead_ends(pieces, key, keep)
    if plain:
        size = np.bincount(pieces.piece, minlength=len(pieces))
        o0, o1 = orig[pieces.first], orig[pieces.last]
        pieces.whole = (size == npts[part]) & (o0 == pstart[part]) & (o1 == pstart[part] + npts[part] - 1)
    return take_pieces(pieces, keep), xy, key, counts


def _drop_dead_ends(pieces: Pieces, key: np.ndarray, keep: np.ndarray) -> int:
    """Unset ``keep`` of pieces ending at a node of degree 1, round after round; the number dropped.

    Each round drops every live piece with an end of degree one; only the
    ends of the pieces just dropped can reach degree one next, so later
    rounds look at their incident pieces alone.
    """
    m = len(pieces)
    if not m:
        return 0
    if pieces.node is not None:
        starts = np.flatnonzero(np.r_[True, pieces.piece[1:] != pieces.piece[:-1]])
        u, v = pieces.node[starts], pieces.node[np.r_[starts[1:], len(pieces.piece)] - 1]
        inv = np.r_[u, v]
    else:
        _, inv = np.unique(np.r_[key[pieces.first], key[pieces.last]], return_inverse=True)
        inv = inv.ravel()
        u, v = inv[:m], inv[m:]
    nn = int(inv.max()) + 1
    deg = np.bincount(u[keep], minlength=nn) + np.bincount(v[keep], minlength=nn)
    # node -> incident pieces, as a CSR table (scipy fills it by counting, no sort)
    from scipy.sparse import csr_matrix  # 0.15 s to import: only when there are pieces to trim

    table = csr_matrix((np.ones(2 * m, np.int8), (inv, np.r_[np.arange(m), np.arange(m)])), shape=(nn, m))
    inc, inc_start = table.indices, table.indptr
    dead = np.flatnonzero(keep & ((deg[u] == 1) | (deg[v] == 1)))
    removed = 0
    while len(dead):
        keep[dead] = False
        removed += len(dead)
        deg -= np.bincount(u[dead], minlength=nn) + np.bincount(v[dead], minlength=nn)
        ends = np.unique(np.r_[u[dead], v[dead]])
        ends = ends[deg[ends] == 1]
        n = inc_start[ends + 1] - inc_start[ends]
        idx = np.repeat(inc_start[ends] - (np.cumsum(n) - n), n) + np.arange(int(n.sum()))
        dead = np.unique(inc[idx])
        dead = dead[keep[dead]]
    return removed


def _sort_by(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """``np.lexsort((c, b, a))``: by ``a``, then ``b``, then ``c`` (stable); one argsort when the three fit one int64."""
    if not len(a):
        return np.empty(0, np.int64)
    lo = [int(x.min()) for x in (a, b, c)]
    span = [int(x.max()) - m + 1 for x, m in zip((a, b, c), lo, strict=True)]
    if span[0] * span[1] * span[2] >= 2**62:
        return np.lexsort((c, b, a))
    packed = ((a - lo[0]) * span[1] + (b - lo[1])) * span[2] + (c - lo[2])
    return argsort_int(packed)


def _duplicates(
    pieces: Pieces, xy: np.ndarray, key: np.ndarray, rank: np.ndarray, dup_tol: float
) -> tuple[np.ndarray, int]:
    """Keep-mask of pieces: of pieces joining the same two nodes within ``dup_tol`` (Hausdorff, m), the lowest rank."""
    keep = np.ones(len(pieces), bool)
    if not len(pieces):
        return keep, 0
    u, v = key[pieces.first], key[pieces.last]
    a, b = np.minimum(u, v), np.maximum(u, v)
    order = _sort_by(a, b, rank)
    same = (a[order][1:] == a[order][:-1]) & (b[order][1:] == b[order][:-1])
    if not same.any():
        return keep, 0
    cand = np.flatnonzero(np.r_[False, same])
    grp_first = order[np.maximum.accumulate(np.where(np.r_[True, ~same], np.arange(len(order)), 0))]
    # two straight pieces between the same nodes are the same street: no distance needed
    npts = np.bincount(pieces.piece, minlength=len(pieces))
    straight = (npts[order[cand]] == 2) & (npts[grp_first[cand]] == 2)
    keep[order[cand[straight]]] = False
    cand = cand[~straight]
    if not len(cand):
        return keep, int(straight.sum())
    need = np.unique(np.r_[order[cand], grp_first[cand]])
    sel = np.isin(pieces.piece, need)
    lines = np.empty(len(pieces), dtype=object)
    lines[need] = shapely.linestrings(xy[pieces.vertex[sel]], indices=np.searchsorted(need, pieces.piece[sel]))
    dup = shapely.hausdorff_distance(lines[order[cand]], lines[grp_first[cand]]) <= dup_tol
    keep[order[cand[dup]]] = False
    return keep, int(dup.sum() + straight.sum())


def face_graph(nodes, u, v, row, ground, *, close: bool = False, box=None, decimals: int | None = None) -> dict:
    """The graph the blocks are traced on: the ground-level segments, closed along the box when asked.

    Parameters
    ----------
    nodes : ndarray (k, 2)
        Node coordinates of the plane segment graph (m).
    u, v, row : ndarray of int64 (m,)
        Its straight segments and the street segment (row) each lies on.
    ground : ndarray of bool
        Per row: at ground level (see :func:`sengine.nodes.blocks.circuits.ground_level`).
    close : bool
        Add the edges that close the graph round the bounding box of its
        nodes, :data:`CLOSE_MARGIN` beyond it
        (:func:`sengine.geom.segments.box_closure`), with ``row`` -1: the land
        between the streets and the box is one more face, which the blocks
        node clips back to the box (``graph["bbox"]``).
    box : (xmin, ymin, xmax, ymax), optional
        The extent of the data (m; e.g. the map's buildings too): the box
        closed along holds it and the nodes.
    decimals : int or None
        Number the nodes as :func:`sengine.nodes.blocks.circuits.find_blocks`'
        lines entry does after merging to this many decimals (only when that
        merges no two nodes; ``graph["decimals"]`` says whether it did).

    Returns
    -------
    dict
        ``xy``, ``u``, ``v``, ``row`` (-1: a closing edge), ``decimals``
        (None: numbered otherwise), ``closing`` (the closing edges as one
        LineString ring, or None) and ``bbox`` (the box it closes, xmin,
        ymin, xmax, ymax, or None).
    """
    sel = np.asarray(ground, bool)[row] if len(row) else np.zeros(0, bool)
    fu, fv, frow = u[sel], v[sel], row[sel]
    used = np.zeros(len(nodes), bool)
    used[fu] = True
    used[fv] = True
    renum = np.cumsum(used) - 1
    fxy, fu, fv = nodes[used], renum[fu], renum[fv]
    closing = None
    if close and len(fu):
        fxy, cu, cv = box_closure(fxy, fu, fv, margin=CLOSE_MARGIN, box=box)
        if len(cu):
            ring = np.r_[cu, cu[:1]] if np.array_equal(np.roll(cu, -1), cv) else None
            closing = shapely.linestrings(fxy[ring]) if ring is not None else None
            if closing is None:  # a side lies along a street: the closing edges are pieces of the ring
                closing = shapely.multilinestrings(shapely.linestrings(np.stack([fxy[cu], fxy[cv]], axis=1)))
            fu, fv, frow = np.r_[fu, cu], np.r_[fv, cv], np.r_[frow, np.full(len(cu), -1, np.int64)]
    bbox = None
    if closing is not None:
        lo, hi = nodes[used].min(axis=0), nodes[used].max(axis=0)
        if box is not None:
            lo, hi = np.minimum(lo, box[:2]), np.maximum(hi, box[2:])
        bbox = tuple(float(c) for c in np.r_[lo, hi])
    graph = {"xy": fxy, "u": fu, "v": fv, "row": frow, "decimals": None, "closing": closing, "bbox": bbox}
    if decimals is not None and len(fxy):
        mxy, inv = merge_points(fxy, decimals)
        if len(mxy) == len(fxy):  # no two nodes merge: only the numbering changes
            graph.update(xy=mxy, u=inv[fu], v=inv[fv], decimals=decimals)
    return graph


@register
class RoadsClean(SENode):
    """Make a real street network plane and tidy before block detection.

    Nodes same-level crossings (not bridges or tunnels), merges duplicate
    ways, drops dead ends (or keeps them), traces the faces of the
    ground-level graph (closed along the data's bounding box on request) and
    finds the slivers between dual carriageways and the traffic islands
    (skylineEngine 002 §5.4 needs a plane graph).
    """

    name = "roads.clean"
    inputs = {"roads": Port("roads", "street centre lines, e.g. from osm.read")}
    outputs = {
        "roads": Port("roads", "plane street segments between junctions"),
        "slivers": Port("polygons", "medians and traffic islands: street surface, not blocks"),
        "graph": Port("graph", "the plane segment graph (columns u, v, row) and its traced faces (meta 'faces')"),
    }
    params = {
        "tunnels": Param(
            "str",
            "drop",
            choices=("drop", "keep"),
            doc="tunnels pass under blocks: drop them, or keep them as streets that close no block",
        ),
        "dup_tol": Param(
            "float",
            0.5,
            min=0.0,
            max=50.0,
            unit="m",
            doc="segments between the same junctions closer than this are duplicates",
        ),
        "dead_ends": Param(
            "bool", True, doc="drop dead ends iteratively (false: keep cul-de-sacs, the blocks node cuts them out)"
        ),
        "close": Param(
            "str",
            "none",
            choices=("none", "bbox"),
            doc="close the ground-level graph along the streets' bounding box (closing edges are no streets), "
            "so that the land at the edge of the data makes faces too",
        ),
        "sliver_width": Param(
            "float", 8.0, min=0.0, max=100.0, unit="m", doc="faces thinner than this (2 area / perimeter) are medians"
        ),
        "island_area": Param("float", 150.0, min=0.0, unit="m2", doc="faces smaller than this are traffic islands"),
        "find_slivers": Param("bool", True, doc="trace faces to find medians and islands"),
        "decimals": Param(
            "int",
            6,
            min=0,
            max=12,
            unit="1",
            doc="number the face graph's nodes merged to this many decimals (m), as blocks.circuits 'decimals' does",
        ),
    }

    def run(self, *, roads: Layer) -> tuple[dict[str, Layer], dict]:
        n0 = len(roads)
        meta = {k: v for k, v in roads.meta.items() if k not in ("nodes", "node_keys")}
        keep = np.ones(n0, bool)
        tunnel = roads.get("tunnel")
        if tunnel is not None and self.p.tunnels == "drop":
            keep &= ~tunnel.astype(bool)
        lay = roads if keep.all() else roads.take(np.flatnonzero(keep))
        n = len(lay)
        level = np.asarray(lay.get("layer", np.zeros(n, np.int64)), np.int64)
        struct = np.zeros(n, bool)
        for col in ("bridge", "tunnel"):
            if col in lay:
                struct |= lay[col].astype(bool)
        # a bridge or tunnel meets other ways only at shared nodes: give each its own level
        level = np.where(struct, -(10**9) - np.arange(n), level)
        cls = lay.get("class")
        rank = np.zeros(n, np.int64)
        if cls is not None and n:
            lut = {c: i for i, c in enumerate(CLASS_RANK)}
            # a handful of distinct class objects (importers share them): rank each object once
            obj, first, inv = np.unique(np.fromiter(map(id, cls), np.int64, n), return_index=True, return_inverse=True)
            ranks = [lut.get(str(cls[i]).removesuffix("_link"), len(CLASS_RANK)) for i in first.tolist()]
            rank = np.asarray(ranks, np.int64)[inv.ravel()]
        if "major" in lay:
            rank = rank - 100 * lay["major"].astype(np.int64)
        ends = (lay["u"], lay["v"]) if "u" in lay and "v" in lay else None
        pieces, xy, key, counts = clean_streets(
            lay.geometry, ends=ends, level=level, rank=rank, dup_tol=self.p.dup_tol, dead_ends=self.p.dead_ends
        )
        geoms = np.empty(len(pieces), dtype=object)
        whole = pieces.whole if pieces.whole is not None else np.zeros(len(pieces), bool)
        geoms[whole] = lay.geometry[pieces.line[whole]]  # untouched lines: the same (immutable) geometries
        if not whole.all():
            sel = ~whole[pieces.piece]
            rest = np.flatnonzero(~whole)
            geoms[rest] = lines_from_groups(xy[pieces.vertex[sel]], np.searchsorted(rest, pieces.piece[sel]))
        nodes, su, sv, pu, pv, row = segment_graph(pieces, xy, key)
        ground = ground_level(lay)[pieces.line]
        # the faces are traced once, here, and blocks.circuits takes them over: numbered as its
        # lines entry numbers nodes (merged to its default decimals), they come out in the same order
        graph = face_graph(
            nodes,
            su,
            sv,
            row,
            ground,
            close=self.p.close == "bbox",
            box=roads.meta.get("extent"),
            decimals=self.p.decimals,
        )
        closing, bbox = graph.pop("closing"), graph.pop("bbox")
        graph["rows"] = len(pieces)
        faces = None
        if self.p.find_slivers and len(graph["u"]):
            faces = find_blocks((graph["xy"], graph["u"], graph["v"]), node=False, decimals=None)
            graph["blocks"] = faces
        counts["off_ground"] = int((~ground).sum())
        counts["dead_ends_kept"] = 0
        counts["closing_edges"] = int((graph["row"] < 0).sum())
        if faces is not None:
            erow = graph["row"][faces.src]  # the row of each traced edge
            counts["dead_ends_kept"] = int(len(np.unique(erow[faces.bridge & (erow >= 0)])))
        out = lay.take(pieces.line)
        out = Layer(
            np.asarray(geoms, dtype=object),
            np.arange(len(pieces), dtype=np.int64),
            out.ids.copy(),
            {**out.attrs, "u": pu, "v": pv},
            {
                **meta,
                "planar": True,
                "nodes": nodes,
                # the edges closing the graph round the bounding box (no streets), and the box; or None
                "closing": closing,
                "bbox": bbox,
            },
        )
        counts["tunnels_dropped"] = int(n0 - n)
        slivers = Layer.empty(meta=meta, kind=object)
        counts["slivers_merged"] = counts["islands"] = counts["medians"] = 0
        if faces is not None:
            polys, kind, nfaces = find_slivers(
                graph["xy"],
                graph["u"],
                graph["v"],
                sliver_width=self.p.sliver_width,
                island_area=self.p.island_area,
                faces=faces,
            )
            if closing is not None and len(polys):  # the land along the box is no street surface
                keep = ~shapely.intersects(polys, closing)
                polys, kind = polys[keep], kind[keep]
            slivers = Layer.from_geoms(polys, meta=meta, kind=kind)
            counts["faces"] = nfaces
            counts["islands"] = int((kind == "island").sum())
            counts["medians"] = int((kind == "median").sum())
            counts["slivers_merged"] = len(polys)
        log.info(
            "%s: %d roads -> %d street segments; %s",
            self.where,
            n0,
            len(out),
            ", ".join(f"{k} {v}" for k, v in counts.items()),
        )
        return NodeResult({"roads": out, "slivers": slivers, "graph": graph_layer(graph, meta)}, counts)


def graph_layer(graph: dict, meta: dict) -> Layer:
    """The ``graph`` layer of a plane segment graph: one straight segment per feature.

    Columns ``u``, ``v`` (node indices into ``meta["xy"]``) and ``row`` (the
    street segment of the roads layer the segment lies on); meta ``xy``,
    ``rows`` (the roads layer's length), ``decimals`` (how the nodes were
    numbered, ``None`` for as they are) and ``faces`` (the traced
    :class:`~sengine.nodes.blocks.circuits.BlockFaces`, or ``None``).
    """
    xy = np.asarray(graph["xy"], np.float64).reshape(-1, 2)
    u, v = np.asarray(graph["u"], np.int64), np.asarray(graph["v"], np.int64)
    geoms = shapely.linestrings(np.stack([xy[u], xy[v]], axis=1)) if len(u) else np.empty(0, object)
    gmeta = {**meta, "xy": xy, "rows": graph["rows"], "decimals": graph["decimals"], "faces": graph.get("blocks")}
    return Layer.from_geoms(geoms, meta=gmeta, u=u, v=v, row=np.asarray(graph["row"], np.int64))

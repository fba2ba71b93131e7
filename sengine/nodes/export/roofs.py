"""Buildings as closed solids with their roofs: flat, parapet, shed, gable, hip, pyramid, stepped.

skylineEngine's buildings carry a roof kind (paper 004 §3.4, Fig. 7: flat,
flat with parapet, single slope, gable, hip, pyramid, stepped); the buildings
layer states it per building in columns (the layer contract):

``height`` (m)
    ground to the highest point, as OSM's ``height``;
``roof`` (str)
    one of :data:`ROOF_KINDS`; a missing column or empty value is ``flat``;
``roof_height`` (m)
    the roof part of ``height``: walls stop at ``height - roof_height``.
    Missing: :func:`default_roof_heights` (a 30° pitch over half the short
    side of the oriented bounding box for gable, hip and pyramid, 15° over
    the short side for a shed, a 1 m parapet, a 3 m recessed top storey);
``roof_direction`` (deg, optional)
    the ridge's compass bearing (clockwise from planar north, the y axis);
    missing: the long axis of the footprint's oriented bounding box.  A shed
    rises to the left of it.

Every solid is closed and outward-facing, made of a floor, walls up to the
eave and the roof, with shared vertices; :class:`Solids` also tells, per
triangle, whether it is ground, wall or roof (CityJSON's semantic surfaces).
The kinds take the cheapest exact route:

========== ================================================= ====================
kind       how                                               footprints
========== ================================================= ====================
flat       prism (:func:`sengine.nodes.export.mesh.extrude`) any
shed       one plane (:mod:`.envelope`)                      any
gable      planes of the eaves along the ridge (:mod:`.envelope`); convex
           straight skeleton, ends turned to gables          concave, with holes
           (:mod:`.skeleton`: :mod:`.wavefront`, else CGAL)
hip        lowest of the edge planes (:mod:`.envelope`);     convex
           straight skeleton (:mod:`.skeleton`)              concave, with holes
pyramid    edge planes through one apex (:mod:`.envelope`);  convex
           else drawn as hip
parapet    prism, parapet ring on top, deck 1 m lower        any
stepped    prism to the eave, terrace, recessed top storey   any
========== ================================================= ====================

A roof that cannot be built (a parapet ring on a footprint thinner than it,
a skeleton CGAL refuses) falls back to flat, and :attr:`Solids.notes` counts it.

References
----------
.. [1] Kim, J., Kang, Y., et al., "Procedural modelling of cities by land use",
   paper 004 of this project's sources (``shared/papers``), §3.4 and Fig. 7.
.. [2] Biljecki, F., Ledoux, H., Stoter, J., "An improved LOD specification for
   3D building models", Computers, Environment and Urban Systems 59, 25-37, 2016.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
import shapely

from sengine.geom.polygons import obb_frame

from . import mesh
from .envelope import envelope_solids
from .mesh import Rings, ring_arrays, stable_argsort, subset_rings
from .skeleton import skeleton_solids

__all__ = [
    "ROOF_KINDS",
    "SURFACES",
    "Solids",
    "roof_kinds",
    "default_roof_heights",
    "building_solids",
    "box_solids",
    "layer_solids",
    "shared_solids",
    "solids_key",
]

#: Roof kinds of the buildings layer's ``roof`` column.
ROOF_KINDS = ("flat", "parapet", "shed", "gable", "hip", "pyramid", "stepped")
FLAT, PARAPET, SHED, GABLE, HIP, PYRAMID, STEPPED = range(7)

#: Semantic surface of each face kind (CityJSON names).
SURFACES = ("GroundSurface", "WallSurface", "RoofSurface")

PITCH_DEG = 30.0  # gable, hip, pyramid: pitch over half the short side
SHED_PITCH_DEG = 15.0  # shed: pitch over the whole short side
PARAPET_HEIGHT = 1.0  # m above the deck
PARAPET_THICKNESS = 0.3  # m
STEP_HEIGHT = 3.0  # m, the recessed top storey
STEP_SETBACK = 2.0  # m, 003 §3.2: a recessed storey set back at least 2 m
MIN_WALL = 3.0  # m of wall kept under a roof (half the height for lower buildings)
MAX_ENVELOPE_EDGES = 8  # convex footprints with more edges go to the skeleton


@dataclass
class Solids:
    """Many closed building solids as one mesh.

    Attributes
    ----------
    vertices : numpy.ndarray, shape (v, 3)
        Planar x, y and z up (m), no duplicates within a building.
    faces : numpy.ndarray of int64, shape (f, 3)
        Counter-clockwise seen from outside.
    vertex_feature : numpy.ndarray of int64, shape (v,)
        Input feature of each vertex.
    face_kind : numpy.ndarray of uint8, shape (f,)
        Index into :data:`SURFACES` (0 ground, 1 wall, 2 roof).
    notes : dict of str to int
        Counts of roofs drawn otherwise than asked, by reason.
    vertex_part : numpy.ndarray of int64, shape (v,), optional
        Polygon part of each vertex (a multi-polygon's parts are separate
        closed shells); ``None`` when every feature is one shell.
    """

    vertices: np.ndarray
    faces: np.ndarray
    vertex_feature: np.ndarray
    face_kind: np.ndarray
    notes: dict = field(default_factory=dict)
    vertex_part: np.ndarray | None = None

    def face_feature(self) -> np.ndarray:
        """Input feature of each face."""
        return self.vertex_feature[self.faces[:, 0]] if len(self.faces) else np.empty(0, np.int64)


def roof_kinds(values, n: int) -> tuple[np.ndarray, int]:
    """Codes (index into :data:`ROOF_KINDS`) of a ``roof`` column; unknown names count and become flat."""
    if values is None:
        return np.zeros(n, np.int8), 0
    values = np.asarray(values, dtype=object).reshape(n)
    try:  # a few distinct values: each read once, then looked up
        name = {v: str(v).strip().lower() if isinstance(v, str) else "" for v in set(values.tolist())}
        text = np.array([name[v] for v in values.tolist()], dtype=object)
    except (TypeError, KeyError):  # unhashable values, or NaNs that are not one object
        text = np.array([str(v).strip().lower() if isinstance(v, str) else "" for v in values], dtype=object)
    codes = np.zeros(n, np.int8)
    known = np.zeros(n, bool)
    for k, name in enumerate(ROOF_KINDS):
        hit = text == name
        codes[hit] = k
        known |= hit
    unknown = int((~known & (text != "")).sum())
    return codes, unknown


def default_roof_heights(codes: np.ndarray, width: np.ndarray) -> np.ndarray:
    """Roof height (m) by kind when the layer gives none; ``width`` is the footprint's short side (m)."""
    half = np.tan(np.radians(PITCH_DEG)) * width / 2.0
    rh = np.zeros(len(codes))
    rh = np.where(np.isin(codes, (GABLE, HIP, PYRAMID)), half, rh)
    rh = np.where(codes == SHED, np.tan(np.radians(SHED_PITCH_DEG)) * width, rh)
    rh = np.where(codes == PARAPET, PARAPET_HEIGHT, rh)
    return np.where(codes == STEPPED, STEP_HEIGHT, rh)


def _column(values, n: int) -> np.ndarray:
    if values is None:
        return np.full(n, np.nan)
    out = np.full(n, np.nan)
    arr = np.asarray(values)
    if arr.dtype.kind in "fiub":
        return np.asarray(arr, np.float64).reshape(n)
    for i, v in enumerate(arr.tolist()):
        try:
            out[i] = float(v)
        except (TypeError, ValueError):
            pass
    return out


def box_solids(geoms, height, *, base=0.0) -> Solids:
    """LoD1: every footprint as a flat-roofed prism of its ``height`` (m)."""
    geoms = np.asarray(geoms, dtype=object)
    h = np.nan_to_num(np.broadcast_to(np.asarray(height, np.float64), (len(geoms),)))
    v, f, vf = mesh.extrude(geoms, h, base=base)
    return Solids(v, f, vf, _prism_kinds(len(v) // 2, len(f)))


def _prism_kinds(m: int, n_faces: int) -> np.ndarray:
    """Face kinds of :func:`mesh.extrude`'s output: top caps, bottom caps, then two triangles per wall."""
    caps = (n_faces - 2 * m) // 2
    return np.concatenate([np.full(caps, 2, np.uint8), np.zeros(caps, np.uint8), np.ones(2 * m, np.uint8)])


def building_solids(geoms, height, *, roof=None, roof_height=None, roof_direction=None, base=0.0) -> Solids:
    """LoD2: every footprint as a closed solid with its roof.

    Parameters
    ----------
    geoms : array of Polygon / MultiPolygon
        Footprints (m); each part of a multi-polygon gets its own roof.
    height : array of float
        Ground to highest point (m).
    roof : array of str, optional
        Roof kinds (:data:`ROOF_KINDS`); missing or empty is flat.
    roof_height : array of float, optional
        Roof part of the height (m); NaN or missing: :func:`default_roof_heights`.
    roof_direction : array of float, optional
        Ridge bearing (deg, clockwise from planar north); NaN or missing: the
        long axis of the oriented bounding box.
    base : float or array of float
        Ground height (m).

    Returns
    -------
    Solids
    """
    geoms = np.asarray(geoms, dtype=object)
    n = len(geoms)
    height = np.nan_to_num(np.broadcast_to(np.asarray(height, np.float64), (n,)).copy())
    base = np.broadcast_to(np.asarray(base, np.float64), (n,))
    codes, unknown = roof_kinds(roof, n)
    notes: dict[str, int] = {}
    if unknown:
        notes["unknown roof kind, drawn flat"] = unknown
    parts, pf = shapely.get_parts(geoms, return_index=True)
    keep = (shapely.get_type_id(parts) == 3) & ~shapely.is_empty(parts)
    keep[keep] &= shapely.area(parts[keep]) > 0.0
    parts, pf = parts[keep], pf[keep]
    rings = ring_arrays(parts)
    if rings.n_polys != len(parts):  # ring_arrays dropped nothing above; keep the two in step anyway
        parts, pf = parts[rings.feature], pf[rings.feature]
        rings = ring_arrays(parts)
    kind = codes[pf].astype(np.int64)
    H, B = height[pf], base[pf]
    kind[H <= 0] = FLAT
    axis, width = np.tile([1.0, 0.0], (len(parts), 1)), np.zeros(len(parts))
    shaped = np.flatnonzero(np.isin(kind, (SHED, GABLE, HIP, PYRAMID)))  # they need a ridge and a width
    if shaped.size:
        _, axis[shaped], _, width[shaped] = obb_frame(parts[shaped])
    bearing = _column(roof_direction, n)[pf]
    rad = np.radians(bearing)
    ridge = np.where(np.isfinite(bearing)[:, None], np.column_stack([np.sin(rad), np.cos(rad)]), axis)
    rh = _column(roof_height, n)[pf]
    rh = np.where(np.isfinite(rh) & (rh > 0), rh, default_roof_heights(kind, width))
    rh[kind == FLAT] = 0.0
    cap = H - np.minimum(MIN_WALL, H / 2.0)
    over = rh > cap
    if (over & (kind != FLAT)).any():
        notes["roof higher than the building allows, lowered"] = int((over & (kind != FLAT)).sum())
    rh = np.minimum(rh, cap)
    kind[(rh < 0.05) & (kind != PARAPET)] = FLAT
    top = B + H
    eave = top - rh

    out: list[tuple] = []  # (vertices, faces, vertex_poly, face_kind)
    n_rings = np.diff(rings.poly_ring)
    convex = _convex(rings) & (n_rings == 1) & (np.diff(rings.ring_start)[rings.poly_ring[:-1]] <= MAX_ENVELOPE_EDGES)
    flat = kind == FLAT

    # shed: one plane, any footprint
    sel = np.flatnonzero(kind == SHED)
    if sel.size:
        out.append(_envelope(rings, sel, _shed_planes(rings, sel, ridge), eave, rh, B))
    # gable, hip, pyramid on convex footprints: edge planes
    for k in (GABLE, HIP, PYRAMID):
        sel = np.flatnonzero((kind == k) & convex)
        if sel.size:
            planes, bounds = _edge_planes(rings, sel, k, ridge, parts)
            for group, pl, bd in _by_plane_count(sel, planes, bounds):
                out.append(_envelope(rings, group, pl, eave, rh, B, bd))
    # the others: the straight skeleton
    sel = np.flatnonzero(np.isin(kind, (GABLE, HIP, PYRAMID)) & ~convex)
    if sel.size:
        if (kind[sel] == PYRAMID).any():
            notes["pyramid on a concave footprint, drawn as hip"] = int((kind[sel] == PYRAMID).sum())
        v, f, vp, fk, failed = skeleton_solids(rings, sel, eave, rh, B, kind == GABLE)
        out.append((v, f, vp, fk))
        if failed.size:
            gab = failed[kind[failed] == GABLE]
            if gab.size:  # a two-plane gable stands on any footprint
                out.append(_envelope(rings, gab, _gable_planes(rings, gab, ridge), eave, rh, B))
            rest = failed[kind[failed] != GABLE]
            if rest.size:
                notes["no straight skeleton, drawn flat"] = int(rest.size)
                flat[rest] = True
    # parapet and stepped: prisms with a ring on top
    for k in (PARAPET, STEPPED):
        sel = np.flatnonzero(kind == k)
        if sel.size:
            solid, bad = _terrace(parts, rings, sel, k, top, rh, B)
            out.append(solid)
            if bad.size:
                notes[f"{ROOF_KINDS[k]} roof on a footprint too thin for it, drawn flat"] = int(bad.size)
                flat[bad] = True
    sel = np.flatnonzero(flat)
    if sel.size:
        v, f, vp = mesh.extrude(parts[sel], H[sel], base=B[sel], rings=_own(rings, sel))
        out.append((v, f, sel[vp], _prism_kinds(len(v) // 2, len(f))))
    if not out:
        return Solids(np.empty((0, 3)), np.empty((0, 3), np.int64), np.empty(0, np.int64), np.empty(0, np.uint8), notes)
    vs, fs, off = [], [], 0
    for v, f, _, _ in out:
        vs.append(v)
        fs.append(f + off)
        off += len(v)
    vp = np.concatenate([o[2] for o in out])
    f_all = np.concatenate(fs)
    fk_all = np.concatenate([o[3] for o in out])
    # each building's vertices and faces together, in input order (deterministic, friendly to viewers)
    order = stable_argsort(vp)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    forder = stable_argsort(vp[f_all[:, 0]])
    # take(axis=0), not [ ]: NumPy's fancy index of rows is several times slower on these sizes
    vpo = vp[order]
    return Solids(
        np.concatenate(vs).take(order, axis=0),
        rank.take(f_all.take(forder, axis=0)),
        pf[vpo],
        fk_all[forder],
        notes,
        vpo,
    )


def layer_solids(layer, lod: int = 2) -> Solids:
    """The solids of a buildings layer (polygon rows; others get none) at level of detail ``lod``.

    ``lod`` 1 gives flat-roofed boxes of ``height``, 2 the roofs of the
    ``roof``, ``roof_height`` and ``roof_direction`` columns; ``base`` (m), when
    present, is each building's ground height.  Inside :func:`shared_solids`
    of this layer and ``lod`` they are the ones made there (read-only).
    """
    made = _SHARED.get((id(layer), int(lod)))
    if made is not None and made[0] is layer:
        return made[1]
    geoms = layer.geometry
    n = len(geoms)
    height = np.nan_to_num(np.asarray(layer.get("height", np.zeros(n)), np.float64))
    base = np.asarray(layer.get("base", np.zeros(n)), np.float64)
    polys = np.isin(shapely.get_type_id(geoms), (3, 6))
    if not polys.all():  # lines or points in a buildings layer get no solid
        geoms = np.where(polys, geoms, None)
    roof = layer.get("roof") if lod >= 2 else None
    kinds = set(np.asarray(roof, dtype=object).tolist()) if roof is not None else set()  # a few distinct values
    if not any(isinstance(v, str) and v.strip() and v.strip().lower() != "flat" for v in kinds):
        return box_solids(geoms, height, base=base)
    return building_solids(
        geoms,
        height,
        roof=roof,
        roof_height=layer.get("roof_height"),
        roof_direction=layer.get("roof_direction"),
        base=base,
    )


def _convex(rings: Rings) -> np.ndarray:
    """Per polygon: its exterior turns left (or goes straight) at every vertex."""
    if rings.n_polys == 0:
        return np.zeros(0, bool)
    xy = rings.xy
    nxt = rings.next_vertex()
    prev = np.empty_like(nxt)
    prev[nxt] = np.arange(len(nxt))
    e0 = xy - xy.take(prev, axis=0)
    e1 = xy.take(nxt, axis=0) - xy
    cross = e0[:, 0] * e1[:, 1] - e0[:, 1] * e1[:, 0]
    scale = np.hypot(*e0.T) * np.hypot(*e1.T)
    right = cross < -1e-6 * scale
    bad_ring = np.bincount(rings.vertex_ring(), weights=right, minlength=len(rings.ring_start) - 1) > 0
    return ~bad_ring[rings.poly_ring[:-1]]


def _envelope(rings: Rings, sel: np.ndarray, planes: np.ndarray, eave, rise, base, bounds=None) -> tuple:
    sub = subset_rings(rings, sel)
    v, f, vp, fk = envelope_solids(sub, planes, eave[sel], rise[sel], base[sel], bounds)
    return v, f, sel[vp], fk


def _exterior_edges(rings: Rings, sel: np.ndarray):
    """Per selected polygon: exterior vertices relative to its first one, padded (p, k, 2), and the mask."""
    r = rings.poly_ring[sel]
    s, e = rings.ring_start[r], rings.ring_start[r + 1]
    n = (e - s).astype(np.int64)
    k = int(n.max())
    j = np.arange(k)
    idx = np.minimum(s[:, None] + j, e[:, None] - 1)
    pts = rings.xy[idx] - rings.xy[s][:, None, :]
    return pts, j < n[:, None], n


def _edge_planes(rings: Rings, sel: np.ndarray, kind: int, ridge: np.ndarray, parts: np.ndarray) -> np.ndarray:
    """Planes ``h = a x + b y + c`` (local coordinates) of the roof over each convex footprint."""
    pts, mask, n = _exterior_edges(rings, sel)
    k = pts.shape[1]
    nxt = np.where(np.arange(k)[None, :] + 1 < n[:, None], np.arange(k)[None, :] + 1, 0)
    b = np.take_along_axis(pts, nxt[:, :, None], axis=1)
    d = b - pts
    ln = np.hypot(d[..., 0], d[..., 1])
    ok = mask & (ln > 1e-9)
    ln = np.where(ok, ln, 1.0)
    nrm = np.stack([-d[..., 1], d[..., 0]], axis=-1) / ln[..., None]  # inward (left of a CCW ring)
    c = -(nrm * pts).sum(axis=-1)
    planes = np.concatenate([nrm, c[..., None]], axis=-1)
    bounds = np.where(ok[..., None], planes, [0.0, 0.0, np.inf])
    if kind == PYRAMID:  # every plane reaches 1 at the centroid
        cen = shapely.get_coordinates(shapely.centroid(parts[sel])) - rings.xy[rings.ring_start[rings.poly_ring[sel]]]
        at = (nrm * cen[:, None, :]).sum(axis=-1) + c
        ok &= at > 1e-9
        planes = planes / np.where(ok, at, 1.0)[..., None]
    if kind == GABLE:  # the eaves along the ridge; the others are gable ends
        u = ridge[sel]
        along = np.abs((d / ln[..., None] * u[:, None, :]).sum(axis=-1)) >= np.cos(np.radians(45.0))
        side = ((nrm * np.column_stack([-u[:, 1], u[:, 0]])[:, None, :]).sum(axis=-1)) > 0
        ok_side = ok & along
        both = (ok_side & side).any(axis=1) & (ok_side & ~side).any(axis=1)
        ok = np.where(both[:, None], ok_side, False)
        if (~both).any():  # no eave on one side of the ridge: the two-plane gable
            g = _gable_planes(rings, sel[~both], ridge)
            planes[~both] = np.inf
            planes[~both, :2] = g
            ok[~both, :2] = True
    planes = planes.copy()
    planes[~ok] = [0.0, 0.0, np.inf]
    return planes, bounds


def _gable_planes(rings: Rings, sel: np.ndarray, ridge: np.ndarray) -> np.ndarray:
    """Two planes meeting at a ridge along ``ridge`` through the middle of the footprint."""
    pts, mask, _ = _exterior_edges(rings, sel)
    u = ridge[sel]
    nv = np.column_stack([-u[:, 1], u[:, 0]])
    proj = (pts * nv[:, None, :]).sum(axis=-1)
    mid = (np.where(mask, proj, np.inf).min(axis=1) + np.where(mask, proj, -np.inf).max(axis=1)) / 2.0
    p1 = np.column_stack([-nv, mid])
    p2 = np.column_stack([nv, -mid])
    return np.stack([p1, p2], axis=1)


def _shed_planes(rings: Rings, sel: np.ndarray, ridge: np.ndarray) -> np.ndarray:
    u = ridge[sel]
    return np.column_stack([-u[:, 1], u[:, 0], np.zeros(len(sel))])[:, None, :]


def _by_plane_count(sel: np.ndarray, planes: np.ndarray, bounds: np.ndarray):
    """Split polygons by how many planes they use, dropping the unused slots (fewer cutting passes)."""
    valid = np.isfinite(planes[:, :, 2])
    order = np.argsort(~valid, axis=1, kind="stable")
    planes = np.take_along_axis(planes, order[:, :, None], axis=1)
    count = valid.sum(axis=1)
    for c in np.unique(count).tolist():
        hit = count == c
        yield sel[hit], planes[hit, : max(c, 1)], bounds[hit]


def _terrace(parts, rings: Rings, sel: np.ndarray, kind: int, top, rh, base):
    """Parapet (a ring around a lower deck) or stepped (a terrace around a recessed top storey)."""
    d = PARAPET_THICKNESS if kind == PARAPET else STEP_SETBACK
    inner = shapely.buffer(parts[sel], -d, join_style="mitre")
    good = ~shapely.is_empty(inner) & np.isin(shapely.get_type_id(inner), (3, 6))
    good[good] &= shapely.area(inner[good]) > 1.0
    bad = sel[~good]
    sel, inner = sel[good], inner[good]
    if not sel.size:
        e = np.empty(0, np.int64)
        return (np.empty((0, 3)), np.empty((0, 3), np.int64), e, np.empty(0, np.uint8)), bad
    ring_z = top[sel] if kind == PARAPET else top[sel] - rh[sel]  # the ring (parapet top or terrace)
    pieces = []
    # outer prism without its top: floor and walls up to the ring
    outer = _own(rings, sel)  # the footprints' rings (as ring_arrays(parts[sel]) would make them again)
    inner_rings = ring_arrays(inner)
    v, f, vf = _topped(mesh.extrude(parts[sel], ring_z - base[sel], base=base[sel], rings=outer), ring_z)
    fk = _prism_kinds(len(v) // 2, len(f))
    keep = fk != 2
    pieces.append((v, f[keep], vf, fk[keep]))
    # the ring, facing up: a strip of trapezoids where the inset is the outline moved in, else earcut
    strip = _strips(parts[sel], inner, d, outer, inner_rings)
    v, f, vf = strip[0]
    rest = np.flatnonzero(~strip[1])
    if rest.size:
        v2, f2, vf2 = mesh.flat(_annulus(parts[sel][rest], inner[rest]), 0.0, max_holes=10**9)
        f = np.concatenate([f, f2 + len(v)])
        v, vf = np.concatenate([v, v2]), np.concatenate([vf, rest[vf2]])
    v[:, 2] = ring_z[vf]
    pieces.append((v, f, vf, np.full(len(f), 2, np.uint8)))
    if kind == PARAPET:  # the well: walls facing in, the deck facing up
        deck = ring_z - rh[sel]
        v, f, vf = _topped(mesh.extrude(inner, ring_z - deck, base=deck, rings=inner_rings), ring_z)
        fk = _prism_kinds(len(v) // 2, len(f))
        keep = fk != 2
        f, fk = f[keep][:, [0, 2, 1]], fk[keep]
        fk[fk == 0] = 2
    else:  # the recessed storey: walls out, its roof up
        v, f, vf = mesh.extrude(inner, top[sel] - ring_z, base=ring_z, bottom=False, rings=inner_rings)
        fk = _prism_kinds_open(len(v) // 2, len(f))
    pieces.append((v, f, vf, fk))
    vs, fs, vps, fks, off = [], [], [], [], 0
    for v, f, vf, fk in pieces:
        vs.append(v)
        fs.append(f + off)
        vps.append(sel[vf])
        fks.append(fk)
        off += len(v)
    v, f, vp = mesh.weld(np.concatenate(vs), np.concatenate(fs), np.concatenate(vps))
    return (v, f, vp, np.concatenate(fks)), bad


def _topped(solid, z: np.ndarray):
    """A :func:`mesh.extrude` solid with its top ring exactly at ``z`` of its feature.

    ``base + (z - base)`` can miss ``z`` by a unit in the last place, and the
    ring drawn beside the top at ``z`` would then not weld to it: the solid
    stays open there (a stepped roof on a base of -0.66 m did).
    """
    v, f, vf = solid
    n = len(v) // 2  # bottom ring vertices, then the top ones
    v[n:, 2] = np.asarray(z, np.float64)[vf[n:]]
    return v, f, vf


def _own(rings: Rings, sel: np.ndarray) -> Rings:
    """Polygons ``sel`` of ``rings`` as their own :class:`Rings`, polygon ``i`` of feature ``i``."""
    sub = subset_rings(rings, sel)
    return Rings(sub.xy, sub.ring_start, sub.poly_ring, np.arange(len(sel), dtype=np.int64))


def _strips(outer: np.ndarray, inner: np.ndarray, d: float, outer_rings: Rings | None = None, inner_rings=None):
    """The ring between footprints ``outer`` and their mitred insets ``inner`` by ``d`` (m), as strips.

    Where the inset is a one-ring polygon of as many vertices as the
    footprint, each of its edges parallel to a footprint edge and ``d`` to
    its left (no edge vanished, the outline only moved in), the ring is the
    trapezoids between corresponding edges, two triangles each, for all
    footprints at once.  The others are left to earcut.

    Parameters
    ----------
    outer, inner : numpy.ndarray of shapely geometries
        Footprints and their insets.
    d : float
        Inset distance (m).
    outer_rings, inner_rings : Rings, optional
        ``ring_arrays`` of ``outer`` and of ``inner`` when the caller has them.

    Returns
    -------
    (vertices (v, 3), faces (f, 3), vertex_feature (v,)), done
        Upward triangles of the ring of the footprints ``done`` (bool per
        footprint) and which ones are done; z is 0.
    """
    n = len(outer)
    done = np.zeros(n, bool)
    empty = (np.empty((0, 3)), np.empty((0, 3), np.int64), np.empty(0, np.int64))
    cand = np.flatnonzero(
        (shapely.get_type_id(outer) == 3)
        & (shapely.get_type_id(inner) == 3)
        & (shapely.get_num_interior_rings(outer) == 0)
        & (shapely.get_num_interior_rings(inner) == 0)
        & (shapely.get_num_coordinates(outer) == shapely.get_num_coordinates(inner))
    )
    if not cand.size:
        return empty, done
    # their rings, taken from those of all footprints and insets (a one-part inset is one polygon of them)
    outer_rings = ring_arrays(outer) if outer_rings is None else outer_rings
    inner_rings = ring_arrays(inner) if inner_rings is None else inner_rings
    ro = _own(outer_rings, np.searchsorted(outer_rings.feature, cand))
    ri = _own(inner_rings, np.searchsorted(inner_rings.feature, cand))
    if ro.n_polys != len(cand) or ri.n_polys != len(cand) or len(ro.xy) != len(ri.xy):
        return empty, done  # a ring lost a repeated vertex: too rare to sort out here
    k = np.diff(ro.ring_start)
    if not np.array_equal(k, np.diff(ri.ring_start)):
        return empty, done
    vp = ro.vertex_poly()
    s = ro.ring_start[:-1]
    # the inset vertex nearest each footprint's first vertex starts its ring
    dist = np.hypot(*(ri.xy - ro.xy[s][vp]).T)
    first = np.lexsort((dist, vp))[s]
    shift = first - s
    i = np.arange(len(ro.xy)) - s[vp]
    a = s[vp] + i
    a1 = s[vp] + (i + 1) % k[vp]
    b = s[vp] + (i + shift[vp]) % k[vp]
    b1 = s[vp] + (i + 1 + shift[vp]) % k[vp]
    po, pi = ro.xy, ri.xy
    eo, ei = po[a1] - po[a], pi[b1] - pi[b]
    lo, li = np.hypot(*eo.T), np.hypot(*ei.T)
    cross = eo[:, 0] * ei[:, 1] - eo[:, 1] * ei[:, 0]
    off = (eo[:, 0] * (pi[b, 1] - po[a, 1]) - eo[:, 1] * (pi[b, 0] - po[a, 0])) / np.where(lo > 0, lo, 1.0)

    def area2(p, q, r):
        return (q[:, 0] - p[:, 0]) * (r[:, 1] - p[:, 1]) - (q[:, 1] - p[:, 1]) * (r[:, 0] - p[:, 0])

    good = (
        (lo > 0)
        & (li > 0)
        & (np.abs(cross) <= 1e-6 * lo * li)
        & ((eo * ei).sum(axis=1) > 0)
        & (np.abs(off - d) <= 1e-6 * (1.0 + d))
        & (area2(po[a], po[a1], pi[b1]) > 0)
        & (area2(po[a], pi[b1], pi[b]) > 0)
    )
    ok = np.bincount(vp, weights=~good, minlength=len(cand)) == 0
    if not ok.any():
        return empty, done
    done[cand[ok]] = True
    keep = ok[vp]
    m = len(po)
    # vertices: the footprints' rings, then the insets'; only the good polygons' triangles
    aa, aa1, bb, bb1 = a[keep], a1[keep], b[keep] + m, b1[keep] + m
    faces = np.concatenate([np.column_stack([aa, aa1, bb1]), np.column_stack([aa, bb1, bb])])
    faces = faces.reshape(2, -1, 3).transpose(1, 0, 2).reshape(-1, 3)  # each trapezoid's two together
    used = np.concatenate([keep, keep])
    remap = np.cumsum(used) - 1
    xy = np.concatenate([po, pi])[used]
    vf = cand[np.concatenate([vp, vp])[used]]
    return (np.column_stack([xy, np.zeros(len(xy))]), remap[faces], vf), done


def _annulus(outer: np.ndarray, inner: np.ndarray) -> np.ndarray:
    """``outer`` minus ``inner`` (an inset of it) built from their own rings.

    A boolean difference may drop collinear vertices that the walls keep,
    which would crack the solid; rings reused as they are cannot.
    """
    simple = (shapely.get_type_id(inner) == 3) & (shapely.get_num_interior_rings(inner) == 0)
    simple &= shapely.get_num_interior_rings(outer) == 0
    out = np.empty(len(outer), dtype=object)
    if simple.any():
        shells = shapely.get_exterior_ring(outer[simple])
        holes = shapely.get_exterior_ring(inner[simple])
        out[simple] = shapely.polygons(shells, holes=holes[:, None])
    for i in np.flatnonzero(~simple).tolist():
        g = outer[i]
        pieces = shapely.get_parts(inner[i])
        g_holes = [shapely.Polygon(h) for h in g.interiors]
        ring_parts, taken = [], set()
        for p in pieces:
            for h in p.interiors:  # a grown hole of the footprint: the ring around the holes inside it
                hp = shapely.Polygon(h)
                inside = [k for k, gh in enumerate(g_holes) if hp.contains(gh.representative_point())]
                taken.update(inside)
                ring_parts.append(shapely.Polygon(h, [g_holes[k].exterior for k in inside]))
        rest = [gh.exterior for k, gh in enumerate(g_holes) if k not in taken]  # holes the inset opened up
        ring_parts.insert(0, shapely.Polygon(g.exterior, [p.exterior for p in pieces] + rest))
        out[i] = shapely.MultiPolygon(ring_parts) if len(ring_parts) > 1 else ring_parts[0]
    return out


def _prism_kinds_open(m: int, n_faces: int) -> np.ndarray:
    caps = n_faces - 2 * m
    return np.concatenate([np.full(caps, 2, np.uint8), np.ones(2 * m, np.uint8)])


_SHARED: dict[tuple[int, int], tuple[object, Solids]] = {}  # (id(layer), lod) -> (layer, its solids)


#: The columns :func:`layer_solids` reads besides the geometry.
SOLID_COLUMNS = ("height", "base", "roof", "roof_height", "roof_direction")


def solids_key(layer, lod: int = 2) -> str:
    """A digest of what :func:`layer_solids` reads of ``layer`` at ``lod``: equal keys, equal solids."""
    import hashlib

    h = hashlib.sha256(f"{int(lod)}:{len(layer)}".encode())
    h.update(b"".join(w or b"" for w in shapely.to_wkb(layer.geometry).tolist()))
    for name in SOLID_COLUMNS:
        col = layer.get(name)
        if col is None:
            h.update(b"-")
            continue
        col = np.asarray(col)
        h.update(f"{name}:{col.dtype.str}:".encode())
        h.update(repr(col.tolist()).encode() if col.dtype.kind == "O" else np.ascontiguousarray(col).tobytes())
    return h.hexdigest()


@contextmanager
def shared_solids(layer, lod: int = 2, made: tuple[str, Solids] | None = None) -> Iterator[Solids]:
    """Make the solids of ``layer`` at ``lod`` once, here, for every writer that asks within the block.

    The exporters of one run (glb, OBJ, CityJSON, the html page) each ask
    :func:`layer_solids` for the same buildings; their roofs (the straight
    skeletons above all) are the costly part.  Made before the writers'
    processes are forked, they are inherited by them.  Writers must not
    change the arrays.  ``made``: ``(solids_key, solids)`` made elsewhere
    (in another process, ahead of the export), taken when the key is this
    layer's.
    """
    key = (id(layer), int(lod))
    if made is not None and made[0] == solids_key(layer, lod):
        solids = made[1]
    else:
        solids = layer_solids(layer, lod)
    _SHARED[key] = (layer, solids)
    try:
        yield solids
    finally:
        _SHARED.pop(key, None)

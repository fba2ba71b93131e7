"""CityJSON 2.0 buildings as LoD1 or LoD2 solids (``--format cityjson``, ``--lod``).

Each building is a ``Building`` city object with one ``Solid`` (a
``MultiSolid`` when its footprint has several parts), every surface
counter-clockwise seen from outside and labelled with its semantic surface
(``GroundSurface``, ``WallSurface``, ``RoofSurface``).  LoD1 (``lod`` "1"): a
floor, a flat roof and one quad per footprint edge.  LoD2 (``lod`` "2"): the
roof of the building's ``roof`` column (:mod:`sengine.nodes.export.roofs`),
walls up to the eave, as triangles.  Vertices are integers with a
millimetre ``transform``, in a frame that GIS tools can place: the layer's
own when it has an EPSG code (UTM, for an OSM city), else the UTM zone of the
city's origin (a synthetic city's local transverse Mercator has no code); the
code goes into ``metadata.referenceSystem``.  z is up, in metres.
Attributes: ``measuredHeight``, ``storeysAboveGround``, ``roofType`` and every
layer column.  Trees, when given, are ``SolitaryVegetationObject`` points.  ``transform.translate`` is the city's origin when one is
given (``--origin local``), else the floor of the model's lowest corner;
the data's licence notice goes into ``metadata.title``.  Keys are sorted;
the output is deterministic.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np

from sengine.geom.crs import registered_frame, reproject
from sengine.layer import Layer

from .mesh import drop_collapsed, ring_arrays, weld
from .roofs import SURFACES, layer_solids

__all__ = ["city_model", "add_vegetation", "write_cityjson"]

log = logging.getLogger(__name__)


def _value(v):
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, float) and not np.isfinite(v):
        return None
    return v


def city_model(
    buildings: Layer,
    *,
    crs: str | None = None,
    scale: float = 0.001,
    origin: tuple | None = None,
    attribution: str | None = None,
    lod: int = 1,
) -> dict:
    """The CityJSON 2.0 document of a buildings layer (needs a ``height`` column) in planar frame ``crs``.

    ``origin`` is ``((x, y), frame)``: the city's origin (m) in planar
    ``frame``, used as ``transform.translate``.  ``lod`` 1 gives boxes, 2 the
    roofs' closed triangle shells with semantic surfaces.
    """
    if lod >= 2:
        solids = layer_solids(buildings, 2)
        if solids.vertex_part is not None:
            return _lod2_model(buildings, solids, crs=crs, scale=scale, origin=origin, attribution=attribution)
    rings = ring_arrays(buildings.geometry)
    m = len(rings.xy)
    code, planar = registered_frame(crs, rings.xy) if crs else (None, rings.xy)
    height = np.nan_to_num(np.asarray(buildings.get("height", np.zeros(len(buildings))), np.float64))
    vpoly = rings.vertex_poly() if m else np.empty(0, np.int64)
    z1 = height[rings.feature[vpoly]] if m else np.empty(0)
    xyz = np.concatenate([np.column_stack([planar, np.zeros(m)]), np.column_stack([planar, z1])])
    translate = _translate(xyz, crs, code, origin)
    ints = np.rint((xyz - translate) / scale).astype(np.int64)
    rs = rings.ring_start.tolist()
    pr = rings.poly_ring.tolist()
    polys_of: dict[int, list[int]] = {}
    for p, f in enumerate(rings.feature.tolist()):
        polys_of.setdefault(f, []).append(p)

    def shell(p: int) -> list:
        bottom, top, walls = [], [], []
        for r in range(pr[p], pr[p + 1]):
            idx = list(range(rs[r], rs[r + 1]))
            bottom.append(idx[::-1])
            top.append([i + m for i in idx])
            nxt = idx[1:] + idx[:1]
            walls += [[[i, j, j + m, i + m]] for i, j in zip(idx, nxt, strict=False)]
        return [bottom, top, *walls]

    def labels(p: int) -> list:
        return [0, 2] + [1] * (rs[pr[p + 1]] - rs[pr[p]])

    lod_name = "2" if lod >= 2 else "1"

    cols = {k: v.tolist() for k, v in buildings.attrs.items()}
    objects = {}
    for i, fid in enumerate(buildings.ids.tolist()):
        parts = polys_of.get(i)
        if not parts:
            continue
        attrs = _attributes(cols, i, height[i])
        if len(parts) == 1:
            geom = {"type": "Solid", "lod": lod_name, "boundaries": [shell(parts[0])]}
            geom["semantics"] = {"surfaces": _SURFACES, "values": [labels(parts[0])]}
        else:
            geom = {"type": "MultiSolid", "lod": lod_name, "boundaries": [[shell(p)] for p in parts]}
            geom["semantics"] = {"surfaces": _SURFACES, "values": [[labels(p)] for p in parts]}
        objects[f"building-{fid}"] = {"type": "Building", "attributes": attrs, "geometry": [geom]}
    return _document(objects, xyz, ints, translate, scale, code, attribution=attribution)


_SURFACES = [{"type": t} for t in SURFACES]


def _attributes(cols: dict, i: int, height: float) -> dict:
    attrs = {k: _value(cols[k][i]) for k in cols}
    attrs["measuredHeight"] = float(height)
    if "floors" in cols:
        attrs["storeysAboveGround"] = int(cols["floors"][i])
    if "roof" in cols:
        attrs["roofType"] = str(cols["roof"][i])
    return attrs


def _translate(xyz: np.ndarray, crs: str | None, code, origin: tuple | None) -> np.ndarray:
    """``transform.translate``: the city's origin ``((x, y), frame)`` in the output frame, else the lowest corner."""
    translate = np.floor(xyz.min(axis=0)) if len(xyz) else np.zeros(3)
    if origin is not None and crs:
        (ox, oy), frame = origin
        o = np.array([[ox, oy]], np.float64)
        if str(frame) != str(crs):
            o = reproject(frame, crs)(o)
        o = registered_frame(crs, o)[1] if code else o
        translate = np.array([*np.round(o[0]), 0.0])
    return translate


def _document(
    objects: dict,
    xyz: np.ndarray,
    ints: np.ndarray,
    translate: np.ndarray,
    scale: float,
    code,
    *,
    attribution: str | None = None,
    lod: int = 1,
) -> dict:
    meta: dict = {}
    if len(xyz):
        lo, hi = xyz.min(axis=0), xyz.max(axis=0)
        meta["geographicalExtent"] = [float(v) for v in np.concatenate([lo, hi])]
    if attribution:
        meta["title"] = f"buildings (LoD{lod}); {attribution}"
    if code:
        meta["referenceSystem"] = f"https://www.opengis.net/def/crs/EPSG/0/{code}"
    return {
        "type": "CityJSON",
        "version": "2.0",
        "transform": {"scale": [scale] * 3, "translate": [float(v) for v in translate]},
        "metadata": meta,
        "CityObjects": objects,
        "vertices": ints.tolist(),
    }


def _lod2_model(
    buildings: Layer, solids, *, crs: str | None, scale: float, origin: tuple | None, attribution: str | None
) -> dict:
    """LoD2: each part's closed triangle shell, one semantic surface label per triangle."""
    v = solids.vertices
    code, planar = registered_frame(crs, v[:, :2]) if crs and len(v) else (None, v[:, :2])
    xyz = np.column_stack([planar, v[:, 2]]) if len(v) else np.empty((0, 3))
    translate = _translate(xyz, crs, code, origin)
    ints = np.rint((xyz - translate) / scale).astype(np.int64)
    # a building's vertices that round to one millimetre point become one; their slivers go
    ints, faces, vpart, merged = weld(ints, solids.faces, solids.vertex_part, return_merged=True)
    faces, face_kind = drop_collapsed(faces, solids.face_kind, merged=merged)
    ints = ints.astype(np.int64)
    xyz = ints * scale + translate
    part_feature = np.zeros(int(vpart.max()) + 1 if len(vpart) else 0, np.int64)
    part_feature[solids.vertex_part] = solids.vertex_feature
    height = np.nan_to_num(np.asarray(buildings.get("height", np.zeros(len(buildings))), np.float64))
    fpart = vpart[faces[:, 0]] if len(faces) else np.empty(0, np.int64)
    order = np.argsort(fpart, kind="stable")  # faces grouped by part, parts by feature
    faces, face_kind, fpart = faces[order], face_kind[order], fpart[order]
    ffeat = part_feature[fpart]
    cut = np.flatnonzero(np.diff(fpart)) + 1
    starts = np.concatenate([[0], cut]).astype(np.int64) if len(faces) else np.empty(0, np.int64)
    ends = np.concatenate([cut, [len(faces)]]).astype(np.int64) if len(faces) else np.empty(0, np.int64)
    tri = faces.tolist()
    kinds = face_kind.tolist()
    shells_of: dict[int, list] = {}
    for a, b in zip(starts.tolist(), ends.tolist()):
        shell = [[t] for t in tri[a:b]]
        shells_of.setdefault(int(ffeat[a]), []).append((shell, kinds[a:b]))
    cols = {k: c.tolist() for k, c in buildings.attrs.items()}
    objects = {}
    for i, fid in enumerate(buildings.ids.tolist()):
        shells = shells_of.get(i)
        if not shells:
            continue
        if len(shells) == 1:
            geom = {"type": "Solid", "lod": "2", "boundaries": [shells[0][0]]}
            geom["semantics"] = {"surfaces": _SURFACES, "values": [shells[0][1]]}
        else:
            geom = {"type": "MultiSolid", "lod": "2", "boundaries": [[s] for s, _ in shells]}
            geom["semantics"] = {"surfaces": _SURFACES, "values": [[k] for _, k in shells]}
        objects[f"building-{fid}"] = {
            "type": "Building",
            "attributes": _attributes(cols, i, height[i]),
            "geometry": [geom],
        }
    return _document(objects, xyz, ints, translate, scale, code, attribution=attribution, lod=2)


def add_vegetation(doc: dict, trees: Layer, *, crs: str | None) -> None:
    """Append each tree of ``trees`` to a CityJSON document as a ``SolitaryVegetationObject``.

    Its vertex (z 0 at the foot) goes into the document's frame and
    transform; attributes ``species`` (the category), ``height`` and
    ``crownDiameter`` (m, CityGML's names), and the layer's other columns.
    """
    import shapely

    xy = shapely.get_coordinates(trees.geometry)
    code, planar = registered_frame(crs, xy) if crs and len(xy) else (None, xy)
    scale = doc["transform"]["scale"][0]
    translate = np.asarray(doc["transform"]["translate"], np.float64)
    xyz = np.column_stack([planar, np.zeros(len(planar))])
    ints = np.rint((xyz - translate) / scale).astype(np.int64)
    base = len(doc["vertices"])
    doc["vertices"].extend(ints.tolist())
    cols = {k: c.tolist() for k, c in trees.attrs.items()}
    rename = {"category": "species", "crown": "crownDiameter"}
    for i, fid in enumerate(trees.ids.tolist()):
        attrs = {rename.get(k, k): _value(c[i]) for k, c in cols.items()}
        doc["CityObjects"][f"tree-{fid}"] = {
            "type": "SolitaryVegetationObject",
            "attributes": {k: v for k, v in attrs.items() if v is not None},
            "geometry": [{"type": "MultiPoint", "lod": "1", "boundaries": [base + i]}],
        }
    real = ints * scale + translate
    ext = doc["metadata"].get("geographicalExtent")
    lo, hi = real.min(axis=0), real.max(axis=0)
    if ext:
        lo, hi = np.minimum(lo, ext[:3]), np.maximum(hi, ext[3:])
    doc["metadata"]["geographicalExtent"] = [float(v) for v in np.concatenate([lo, hi])]


def write_cityjson(
    path: str | Path,
    buildings: Layer,
    *,
    crs: str | None = None,
    origin: tuple | None = None,
    attribution: str | None = None,
    lod: int = 1,
    vegetation: Layer | None = None,
) -> int:
    """Write ``buildings`` as CityJSON 2.0 at ``lod`` 1 or 2; return the number of city objects (see :func:`city_model`).

    ``vegetation`` (points with ``category``, ``height``, ``crown``) adds one
    ``SolitaryVegetationObject`` per tree, a LoD1 ``MultiPoint`` at its foot.
    """
    doc = city_model(buildings, crs=crs, origin=origin, attribution=attribution, lod=lod)
    if vegetation is not None and len(vegetation):
        add_vegetation(doc, vegetation, crs=crs)
    Path(path).write_text(
        json.dumps(doc, sort_keys=True, separators=(",", ":"), allow_nan=False) + "\n", encoding="utf-8"
    )
    log.info("wrote %s: %d buildings", path, len(doc["CityObjects"]))
    return len(doc["CityObjects"])

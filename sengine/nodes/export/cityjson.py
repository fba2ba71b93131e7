"""CityJSON 2.0 buildings as LoD1 solids (``--format cityjson``).

Each building is a ``Building`` city object with one ``Solid`` (``lod`` "1"):
a floor, a flat roof and one quad per footprint edge, every surface
counter-clockwise seen from outside.  Vertices are integers with a
millimetre ``transform``, in a frame that GIS tools can place: the layer's
own when it has an EPSG code (UTM, for an OSM city), else the UTM zone of the
city's origin (a synthetic city's local transverse Mercator has no code); the
code goes into ``metadata.referenceSystem``.  z is up, in metres.
Attributes: ``measuredHeight``, ``storeysAboveGround``, ``roofType`` and every
layer column.  ``transform.translate`` is the city's origin when one is
given (``--origin local``), else the floor of the model's lowest corner;
the data's licence notice goes into ``metadata.title``.  Keys are sorted;
the output is deterministic.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np

from sengine.geom.crs import registered_frame
from sengine.layer import Layer

from .mesh import ring_arrays

__all__ = ["city_model", "write_cityjson"]

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
) -> dict:
    """The CityJSON 2.0 document of a buildings layer (needs a ``height`` column) in planar frame ``crs``.

    ``origin`` is ``((x, y), frame)``: the city's origin (m) in planar
    ``frame``, used as ``transform.translate``.
    """
    rings = ring_arrays(buildings.geometry)
    m = len(rings.xy)
    code, planar = registered_frame(crs, rings.xy) if crs else (None, rings.xy)
    height = np.nan_to_num(np.asarray(buildings.get("height", np.zeros(len(buildings))), np.float64))
    vpoly = rings.vertex_poly() if m else np.empty(0, np.int64)
    z1 = height[rings.feature[vpoly]] if m else np.empty(0)
    xyz = np.concatenate([np.column_stack([planar, np.zeros(m)]), np.column_stack([planar, z1])])
    translate = np.floor(xyz.min(axis=0)) if m else np.zeros(3)
    if origin is not None and crs:
        (ox, oy), frame = origin
        o = np.array([[ox, oy]], np.float64)
        if str(frame) != str(crs):
            from sengine.geom.crs import reproject

            o = reproject(frame, crs)(o)
        o = registered_frame(crs, o)[1] if code else o
        translate = np.array([*np.round(o[0]), 0.0])
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

    cols = {k: v.tolist() for k, v in buildings.attrs.items()}
    objects = {}
    for i, fid in enumerate(buildings.ids.tolist()):
        parts = polys_of.get(i)
        if not parts:
            continue
        attrs = {k: _value(cols[k][i]) for k in cols}
        attrs["measuredHeight"] = float(height[i])
        if "floors" in cols:
            attrs["storeysAboveGround"] = int(cols["floors"][i])
        if "roof" in cols:
            attrs["roofType"] = str(cols["roof"][i])
        if len(parts) == 1:
            geom = {"type": "Solid", "lod": "1", "boundaries": [shell(parts[0])]}
        else:
            geom = {"type": "MultiSolid", "lod": "1", "boundaries": [[shell(p)] for p in parts]}
        objects[f"building-{fid}"] = {"type": "Building", "attributes": attrs, "geometry": [geom]}
    meta: dict = {}
    if m:
        lo, hi = xyz.min(axis=0), xyz.max(axis=0)
        meta["geographicalExtent"] = [float(v) for v in np.concatenate([lo, hi])]
    if attribution:
        meta["title"] = f"buildings (LoD1); {attribution}"
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


def write_cityjson(
    path: str | Path,
    buildings: Layer,
    *,
    crs: str | None = None,
    origin: tuple | None = None,
    attribution: str | None = None,
) -> int:
    """Write ``buildings`` as CityJSON 2.0; return the number of city objects (see :func:`city_model`)."""
    doc = city_model(buildings, crs=crs, origin=origin, attribution=attribution)
    Path(path).write_text(
        json.dumps(doc, sort_keys=True, separators=(",", ":"), allow_nan=False) + "\n", encoding="utf-8"
    )
    log.info("wrote %s: %d buildings", path, len(doc["CityObjects"]))
    return len(doc["CityObjects"])

"""``index.html``: the city in 3D in a browser (``--format html``), with ``city.view.js`` its data.

Every layer becomes a mesh as in the glb (:mod:`sengine.nodes.export.mesh`:
buildings as the glb's solids, with their roofs at ``lod`` 2
(:mod:`sengine.nodes.export.roofs`), lines as ribbons, other polygons flat at
their layer's level), around the same origin, but every vertex also carries
its feature's row so that the page can colour features by a column and show
the attributes of the one clicked.  The columns are the layer's own, the
same as the glb's property table (``EXT_structural_metadata``), plus, for
buildings, ``lot_far``: the floor area ratio of the lot each stands on (lots
carry ``far``, buildings their ``lot``), which map buildings that carry no
``far`` of their own have too.  Buildings have no floor in the page (nobody
looks at a city from below ground).

The page itself (:mod:`sengine.viewer`) knows the view format only; this
module is where city layers meet it.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import shapely

from sengine.layer import Layer
from sengine.viewer import ViewLayer, write_view

from . import mesh, roofs
from .gltf import _DEFAULT_COLOUR, COLOURS, LAYERS, layer_surfaces
from .preview import city_title

__all__ = ["view_layer", "view_layers", "write_html"]

log = logging.getLogger(__name__)


def view_layer(name: str, layer: Layer, *, offset=(0.0, 0.0), line_width: float = 1.0, lod: int = 2) -> ViewLayer:
    """The mesh and columns of one layer for the page (planar ``offset`` subtracted; y up).

    A layer of polygons with a ``height`` column is made of the glb's building
    solids at ``lod`` (1 boxes, 2 with roofs), without their ground faces.
    """
    geoms = layer.geometry
    types = shapely.get_type_id(geoms) if len(geoms) else np.empty(0, int)
    lines = np.isin(types, (1, 2, 5))
    polys = np.isin(types, (3, 6))
    parts = []
    solid = bool(polys.any() and "height" in layer.attrs)
    if polys.any():
        if solid:
            solids = roofs.layer_solids(layer, lod)  # rows that are no polygons get none
            f = solids.faces[solids.face_kind != 0]  # no floors
            parts.append((solids.vertices, f, solids.vertex_feature))
        else:
            parts.append(layer_surfaces(name, layer, line_width=line_width)[0])
    if lines.any():
        parts.append(layer_surfaces(name, layer, line_width=line_width)[1])
    if parts:
        v, f = mesh.merge(*[(p[0], p[1]) for p in parts])
        feature = np.concatenate([p[2] for p in parts])
    else:
        v, f, feature = np.empty((0, 3)), np.empty((0, 3), np.int64), np.empty(0, np.int64)
    v = v.copy()
    v[:, :2] -= np.asarray(offset, np.float64)
    columns = {"id": np.asarray(layer.ids)}
    columns.update({k: np.asarray(c) for k, c in layer.attrs.items() if k != "id"})
    for key in layer.meta.get("null_negative", ()):  # integer references where negative means none, as in GeoJSON
        if key in columns and columns[key].dtype.kind in "iu":
            col = columns[key]
            columns[key] = np.where(col < 0, None, col.astype(object))
    kind = "solid" if solid else "line" if lines.any() and not polys.any() else "surface"
    return ViewLayer(
        name=name,
        colour=COLOURS.get(name, _DEFAULT_COLOUR),
        kind=kind,
        position=mesh.to_y_up(v),
        index=f,
        feature=feature,
        columns=columns,
        features=len(layer),
        scale=line_width if kind == "line" else None,
    )


def _lot_far(buildings: Layer, lots: Layer | None) -> np.ndarray | None:
    """The ``far`` of each building's lot (NaN where it has none), or None when the layers cannot tell."""
    if lots is None or "far" not in lots.attrs or "lot" not in buildings.attrs or "lot_far" in buildings.attrs:
        return None
    lot = np.asarray(buildings["lot"])
    if lot.dtype.kind not in "iu":
        lot = np.array([-1 if v is None else int(v) for v in lot.tolist()], np.int64)
    order = np.argsort(lots.ids, kind="stable")
    ids = np.asarray(lots.ids)[order]
    pos = np.clip(np.searchsorted(ids, lot), 0, max(len(ids) - 1, 0))
    found = (len(ids) > 0) & (ids[pos] == lot) if len(ids) else np.zeros(len(lot), bool)
    far = np.array([np.nan if v is None else float(v) for v in np.asarray(lots["far"]).tolist()], np.float64)[order]
    return np.where(found, far[pos] if len(ids) else np.nan, np.nan)


def view_layers(
    layers: Mapping[str, Layer], *, offset=(0.0, 0.0), line_width: float = 1.0, lod: int = 2
) -> list[ViewLayer]:
    """Every non-empty layer for the page, in the glb's drawing order (buildings at ``lod``)."""
    order = [n for n in LAYERS if n in layers] + sorted(n for n in layers if n not in LAYERS)
    out = []
    for name in order:
        lay = layers[name]
        if lay is None or not len(lay):
            continue
        view = view_layer(name, lay, offset=offset, line_width=line_width, lod=lod)
        if name == "buildings":
            far = _lot_far(lay, layers.get("lots"))
            if far is not None:
                view.columns["lot_far"] = far
        if len(view.index):
            out.append(view)
    return out


def write_html(
    out: str | Path,
    layers: Mapping[str, Layer],
    *,
    offset=(0.0, 0.0),
    line_width: float = 1.0,
    name: str = "",
    attribution: str | None = None,
    crs: str = "",
    origin: Mapping | None = None,
    plan: str | None = "preview.png",
    lod: int = 2,
) -> dict:
    """Write ``index.html``, ``viewer.js`` and ``city.view.js`` into folder ``out``; return counts per layer.

    ``offset`` (planar x, y; m) is subtracted from every vertex, as the glb's
    ``--origin local`` does; ``plan`` names the plan image shown below the
    3D view (None: none); ``lod`` draws buildings as boxes (1) or with their
    roofs (2), as in the glb.
    """
    views = view_layers(layers, offset=offset, line_width=line_width, lod=lod)
    return write_view(
        out, views, name=city_title(name), attribution=attribution, crs=crs, origin=origin or {}, plan=plan
    )

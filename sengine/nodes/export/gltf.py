"""``city.glb``: the city as a binary glTF 2.0 scene, one named node per layer.

Layers become meshes in batches (:mod:`sengine.nodes.export.mesh`): buildings are
extruded to their ``height``; lines (roads) become thin flat ribbons; other
polygons (water, streets, sidewalks, blocks, lots, parks) become flat surfaces at
slightly different heights so they do not z-fight.  Units are metres; the
frame is glTF's: x east, **y up**, z south (planar y -> -Z, height -> Y).

With ``origin`` (``--origin local``, the default of ``export.city``) the
vertices are relative to the city's origin and the scene sits at the glTF
origin, where Blender and web viewers look; the origin (planar and lat /
lon) and the CRS are stored in the scene's ``extras``.  Without it
(``--origin geo``), when the planar coordinates are far from zero (a UTM
frame), the vertices are stored relative to a round offset and each node
carries that offset as its translation, so float32 vertex buffers keep
centimetre precision while the scene's world coordinates stay those of the
planar frame.  Materials are named by layer; ``asset.copyright`` holds the
data's licence notice.

Buildings are one mesh whose every vertex carries its building's row as a
feature id (``EXT_mesh_features``), and the buildings' columns travel as a
property table (``EXT_structural_metadata``): a viewer that knows the
extensions (Cesium, the 3D Tiles tools) picks a building and shows its id,
height, floors, roof, use ...; one that does not still draws the mesh.  This
was chosen over one node per building by measurement (see the commit that
added it): on the Manhattan demo one node per building made the glb larger
and, at 7,000 nodes, far slower to load in three.js and Blender, while the
feature ids cost 4 bytes a vertex.  ``lod`` 1 draws buildings as boxes, 2 with
their roofs (:mod:`sengine.nodes.export.roofs`).

The writer is a few dozen lines of ``struct`` and ``json`` (glTF 2.0 §4.4,
GLB file format) rather than trimesh's exporter: importing trimesh (and
scipy.spatial with it) costs about half a second per run, more than writing
a whole city.  The file holds no time stamp and its JSON keys are sorted:
the same layers give the same bytes.  trimesh reads it back in the tests.
"""

from __future__ import annotations

import json
import logging
import struct
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import shapely

from sengine.layer import Layer

from . import mesh, roofs

__all__ = ["LAYERS", "COLOURS", "LEVELS", "layer_mesh", "glb_bytes", "write_glb"]

log = logging.getLogger(__name__)

#: Layer names the exporters know, in drawing order.
LAYERS = ("water", "streets", "sidewalks", "blocks", "lots", "parks", "bridges", "roads", "buildings", "vegetation")

#: Base colour (sRGB, 0-255) of each layer.
COLOURS = {
    "water": (135, 175, 210),
    "roads": (70, 70, 76),
    "streets": (150, 150, 155),
    "sidewalks": (205, 203, 196),
    "blocks": (228, 222, 205),
    "lots": (240, 235, 220),
    "parks": (120, 175, 95),
    "buildings": (214, 208, 200),
    "bridges": (160, 150, 140),
    "vegetation": (70, 130, 60),
}
_DEFAULT_COLOUR = (180, 180, 180)

#: Height (m) of each flat layer, so that overlapping surfaces do not z-fight.
LEVELS = {
    "water": -0.5,
    "streets": 0.0,
    "sidewalks": 0.12,
    "blocks": 0.12,
    "lots": 0.15,
    "parks": 0.2,
    "roads": 0.25,
    "bridges": 0.22,
}


def layer_mesh(name: str, layer: Layer, *, line_width: float = 1.0, lod: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (planar x, y, z up; m) and faces of one layer.

    A layer with a ``height`` column and polygons is made of building solids
    (boxes for ``lod`` 1, roofs for 2); line layers become ribbons
    ``line_width`` m wide; other polygons are flat.
    """
    v, f, _ = _layer_mesh(name, layer, line_width=line_width, lod=lod)
    return v, f


def _layer_mesh(name: str, layer: Layer, *, line_width: float = 1.0, lod: int = 1):
    """:func:`layer_mesh` and, for building layers, each vertex's row in the layer (else None)."""
    geoms = layer.geometry
    if len(geoms) == 0:
        return np.empty((0, 3)), np.empty((0, 3), np.int64), None
    types = shapely.get_type_id(geoms)
    lines = np.isin(types, (1, 2, 5))
    polys = np.isin(types, (3, 6))
    if name == "bridges" and polys.all():  # decks: slabs whose top carries the road ribbon
        t = np.nan_to_num(np.asarray(layer.get("thickness", np.ones(len(layer))), np.float64), nan=1.0)
        v, f, _ = mesh.extrude(geoms, t, base=LEVELS["bridges"] - t)
        return v, f, None
    if polys.any() and "height" in layer.attrs and not lines.any():
        solids = roofs.layer_solids(layer, lod)
        if solids.notes:
            log.info("%s: %s", name, ", ".join(f"{k}: {v:,}" for k, v in sorted(solids.notes.items())))
        return solids.vertices, solids.faces, solids.vertex_feature
    parts = []
    flat, ribbons = layer_surfaces(name, layer, line_width=line_width)
    if polys.any():
        if "height" in layer.attrs:
            h = np.nan_to_num(np.asarray(layer["height"], np.float64)[polys])
            base = np.asarray(layer.get("base", np.zeros(len(layer))), np.float64)[polys]
            parts.append(mesh.extrude(geoms[polys], h, base=base)[:2])
        else:
            parts.append(flat[:2])
    if lines.any():
        parts.append(ribbons[:2])
    v, f = mesh.merge(*parts)
    return v, f, None


_SURFACES: dict[tuple[int, str, float], tuple[Layer, tuple]] = {}  # (id(layer), name, line width) -> (layer, made)


def layer_surfaces(name: str, layer: Layer, *, line_width: float = 1.0) -> tuple[tuple | None, tuple | None]:
    """The flat polygons (when the layer has no ``height``) and the line ribbons of a layer, each ``(v, f, row)``.

    ``v`` are vertices (planar x, y, z up; m) at the layer's :data:`LEVELS`,
    ``f`` triangles, ``row`` each vertex's row in the layer; None where the
    layer has no such geometry.  The glb and the html page draw them alike:
    inside :func:`shared_surfaces` they are the ones made there (read-only).
    """
    made = _SURFACES.get((id(layer), name, float(line_width)))
    if made is not None and made[0] is layer:
        return made[1]
    geoms = layer.geometry
    types = shapely.get_type_id(geoms) if len(geoms) else np.empty(0, int)
    lines = np.isin(types, (1, 2, 5))
    polys = np.isin(types, (3, 6))
    flat = ribbons = None
    if polys.any() and "height" not in layer.attrs:
        rows = np.flatnonzero(polys)
        v, f, vf = mesh.flat(geoms[polys], LEVELS.get(name, 0.1))
        flat = (v, f, rows[vf])
    if lines.any():
        rows = np.flatnonzero(lines)
        v, f, vf = mesh.ribbons(geoms[lines], line_width, LEVELS.get(name, 0.25))
        ribbons = (v, f, rows[vf])
    return flat, ribbons


def make_surfaces(layers: Mapping[str, Layer], *, line_width: float = 1.0) -> dict[str, tuple]:
    """:func:`layer_surfaces` of every layer but the trees and the buildings (for :func:`shared_surfaces`)."""
    return {
        name: layer_surfaces(name, lay, line_width=line_width)
        for name, lay in layers.items()
        if lay is not None and len(lay) and name not in ("vegetation", "buildings")
    }


@contextmanager
def shared_surfaces(layers: Mapping[str, Layer], made: dict[str, tuple], *, line_width: float = 1.0) -> Iterator[None]:
    """Within the block, :func:`layer_surfaces` of ``layers`` are those of ``made`` (:func:`make_surfaces`'s).

    The glb and the html page of one export triangulate the same lots,
    blocks and streets: made once (in whichever process), they are handed
    to both writers, forked inside the block.  Writers must not change the arrays.
    """
    keys = []
    for name, value in made.items():
        key = (id(layers[name]), name, float(line_width))
        _SURFACES[key] = (layers[name], value)
        keys.append(key)
    try:
        yield
    finally:
        for key in keys:
            _SURFACES.pop(key, None)


def _offset(vertices: list[np.ndarray]) -> np.ndarray:
    """A round planar (x, y) offset when coordinates are large, else zero."""
    pts = [v[:, :2] for v in vertices if len(v)]
    if not pts:
        return np.zeros(2)
    lo = np.min([p.min(axis=0) for p in pts], axis=0)
    hi = np.max([p.max(axis=0) for p in pts], axis=0)
    if np.abs(np.concatenate([lo, hi])).max() < 1.0e5:
        return np.zeros(2)
    return np.round((lo + hi) / 2.0, -3)


def glb_bytes(
    layers: Mapping[str, Layer],
    *,
    line_width: float = 1.0,
    crs: str | None = None,
    origin: tuple | None = None,
    copyright: str | None = None,
    lod: int = 1,
    instancing: bool = True,
) -> tuple[bytes, dict]:
    """The binary glTF of ``layers`` and the vertex / triangle counts of each mesh.

    One node, one mesh and one material (named by layer) per non-empty layer,
    in :data:`LAYERS` order; float32 positions and uint32 indices, no normals
    (viewers shade flat).  A building layer's primitive has a
    ``_FEATURE_ID_0`` attribute (the row of each vertex's building) and a
    property table of the layer's columns; ``lod`` 1 draws buildings as
    boxes, 2 with their roofs.  ``origin`` is ``((x, y), (lat, lon))``, the
    city's origin planar (m) and geographic (deg): vertices are placed
    relative to it.  ``copyright`` goes into ``asset.copyright``.

    Trees (the ``vegetation`` layer: points with ``category``, ``form``,
    ``height``, ``crown``, ``instance``) become one low-poly mesh per plant
    category (:mod:`sengine.nodes.export.trees`), a node each, placed at every
    tree by ``EXT_mesh_gpu_instancing``; ``instancing=False`` bakes every tree
    into one mesh instead.  Each instance carries its row of the layer as a
    feature id (``EXT_instance_features``, an instance attribute
    ``_FEATURE_ID_0``) into a property table of the layer's columns (zone,
    category, type, instance, height, crown, park ...; text as enums, numbers
    as 32-bit), so a viewer that knows the extensions names the plant clicked.
    """
    trees = layers.get("vegetation")
    built = {
        name: _layer_mesh(name, lay, line_width=line_width, lod=lod)
        for name, lay in layers.items()
        if lay is not None and name != "vegetation"
    }
    built = {k: v for k, v in built.items() if len(v[1])}
    local = origin is not None
    off = np.asarray(origin[0], np.float64) if local else _offset([v for v, _, _ in built.values()])
    order = [n for n in LAYERS if n in built] + sorted(n for n in built if n not in LAYERS)
    blobs: list[bytes] = []
    views, accessors, gl_meshes, materials, nodes = [], [], [], [], []
    tables, classes, enums = [], {}, {}
    length = 0
    counts = {}

    def add_view(data: bytes, target: int | None = None) -> int:
        nonlocal length
        pad = -length % 8  # metadata views need 8-byte alignment; vertex data 4
        if pad:
            blobs.append(b"\0" * pad)
            length += pad
        view = {"buffer": 0, "byteOffset": length, "byteLength": len(data)}
        if target is not None:
            view["target"] = target
        views.append(view)
        blobs.append(data)
        length += len(data)
        return len(views) - 1

    translation = [float(off[0]), 0.0, float(-off[1])]
    for k, name in enumerate(order):
        v, f, vfeat = built[name]
        v = v.copy()
        v[:, :2] -= off
        pos = np.ascontiguousarray(mesh.to_y_up(v), dtype=np.float32)
        if vfeat is not None:  # vertices a building's float32 positions cannot tell apart become one
            pos, f, vfeat = _weld32(pos, f, vfeat)
        idx = np.ascontiguousarray(f, dtype=np.uint32)
        attributes = {"POSITION": len(accessors)}
        accessors.append(
            {
                "bufferView": add_view(pos.tobytes(), 34962),
                "componentType": 5126,
                "count": len(pos),
                "type": "VEC3",
                "min": [float(c.min()) for c in pos.T],
                "max": [float(c.max()) for c in pos.T],
            }
        )
        primitive = {"attributes": attributes, "indices": len(accessors), "material": k, "mode": 4}
        accessors.append(
            {
                "bufferView": add_view(idx.tobytes(), 34963),
                "componentType": 5125,
                "count": int(idx.size),
                "type": "SCALAR",
            }
        )
        if vfeat is not None:  # pickable buildings: a feature id per vertex and a property table
            fid = np.ascontiguousarray(vfeat, dtype=np.float32)  # exact up to 16.7 million buildings
            attributes["_FEATURE_ID_0"] = len(accessors)
            accessors.append(
                {
                    "bufferView": add_view(fid.tobytes(), 34962),
                    "componentType": 5126,
                    "count": len(fid),
                    "type": "SCALAR",
                }
            )
            cls, table = _property_table(name, layers[name], add_view)
            classes[name] = cls
            primitive["extensions"] = {
                "EXT_mesh_features": {
                    "featureIds": [
                        {"featureCount": len(layers[name]), "attribute": 0, "propertyTable": len(tables), "label": name}
                    ]
                }
            }
            tables.append(table)
        rgba = [round(c / 255.0, 6) for c in COLOURS.get(name, _DEFAULT_COLOUR)] + [1.0]
        materials.append(
            {
                "name": name,
                "doubleSided": name != "buildings",
                "pbrMetallicRoughness": {"baseColorFactor": rgba, "metallicFactor": 0.0, "roughnessFactor": 0.9},
            }
        )
        gl_meshes.append({"name": name, "primitives": [primitive]})
        node = {"name": name, "mesh": k}
        if off.any() and not local:
            node["translation"] = translation
        nodes.append(node)
        counts[name] = {"vertices": int(len(pos)), "triangles": int(len(f))}
    if trees is not None and len(trees):
        counts["vegetation"] = _tree_nodes(
            trees,
            off,
            add_view,
            accessors,
            gl_meshes,
            materials,
            nodes,
            translation if off.any() and not local else None,
            instancing=instancing,
        )
        if instancing:  # pickable trees: each instance's row in a property table of the layer's columns
            cls, table = _property_table("vegetation", trees, add_view, compact=True, enums=enums)
            classes["vegetation"] = cls
            for nd in nodes:
                if "_tree_rows" in nd:
                    nd["extensions"]["EXT_instance_features"] = {
                        "featureIds": [
                            {
                                "featureCount": nd.pop("_tree_rows"),
                                "attribute": 0,
                                "propertyTable": len(tables),
                                "label": "vegetation",
                            }
                        ]
                    }
            tables.append(table)
    extras = {"units": "m", "up": "y", "crs": crs or "", "planar_offset": [float(off[0]), float(off[1])]}
    if local:
        extras["origin"] = {"planar": [float(off[0]), float(off[1])], "lat": origin[1][0], "lon": origin[1][1]}
    asset = {"version": "2.0", "generator": "sengine"}
    if copyright:
        asset["copyright"] = copyright
    doc = {
        "asset": asset,
        "scene": 0,
        "scenes": [
            {
                "name": "city",
                "extras": {"sengine": {**extras, "lod": int(lod)}},
            }
        ],
    }
    if nodes:  # glTF arrays may not be empty: an empty city is a scene without nodes
        doc["scenes"][0]["nodes"] = list(range(len(nodes)))
        doc.update(
            {
                "nodes": nodes,
                "meshes": gl_meshes,
                "materials": materials,
                "accessors": accessors,
                "bufferViews": views,
                "buffers": [{"byteLength": length + (-length % 4)}],
            }
        )
    used = sorted({e for n in nodes for e in n.get("extensions", {})})
    if used:
        doc["extensionsUsed"] = used
    if tables:
        meshed = any("extensions" in pr for m in gl_meshes for pr in m["primitives"])  # buildings' feature ids
        doc["extensionsUsed"] = sorted({*used, "EXT_structural_metadata", *(["EXT_mesh_features"] if meshed else [])})
        schema = {"id": "sengine", "classes": classes}
        if enums:
            schema["enums"] = enums
        doc["extensions"] = {"EXT_structural_metadata": {"schema": schema, "propertyTables": tables}}
    text = json.dumps(doc, sort_keys=True, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    binary = b"".join(blobs)
    binary += b"\0" * (-len(binary) % 4)
    chunks = struct.pack("<II", len(text), 0x4E4F534A) + text
    if binary:
        chunks += struct.pack("<II", len(binary), 0x004E4942) + binary
    return struct.pack("<III", 0x46546C67, 2, 12 + len(chunks)) + chunks, counts


def _tree_nodes(trees, off, add_view, accessors, gl_meshes, materials, nodes, translation, *, instancing=True) -> dict:
    """Append a mesh and a node per plant category of ``trees``; return the vertex / triangle / instance counts."""
    from ..vegetation.plants import PLANTS
    from . import trees as tm

    cats = np.asarray(trees.get("category", np.full(len(trees), "lime")), dtype=object).astype(str)
    rows = np.arange(len(trees))
    forms = np.asarray(trees.get("form", np.full(len(trees), "")), dtype=object).astype(str)

    def add_accessor(data: np.ndarray, type_: str, target: int | None, minmax: bool = False) -> int:
        arr = np.ascontiguousarray(data, dtype=np.float32)
        acc = {"bufferView": add_view(arr.tobytes(), target), "componentType": 5126, "count": len(arr), "type": type_}
        if minmax:
            acc["min"] = [float(c.min()) for c in arr.T]
            acc["max"] = [float(c.max()) for c in arr.T]
        accessors.append(acc)
        return len(accessors) - 1

    def material(name: str, rgb) -> int:
        rgba = [round(c / 255.0, 6) for c in rgb] + [1.0]
        materials.append(
            {
                "name": name,
                "doubleSided": False,
                "pbrMetallicRoughness": {"baseColorFactor": rgba, "metallicFactor": 0.0, "roughnessFactor": 0.9},
            }
        )
        return len(materials) - 1

    trunk = material("vegetation/trunk", tm.TRUNK_COLOUR)
    counts = {"vertices": 0, "triangles": 0, "instances": 0, "meshes": 0}
    for cat in sorted(set(cats.tolist())):
        sel = cats == cat
        lay = trees.take(sel)
        form = forms[sel][0] if forms[sel][0] else PLANTS.get(cat, ("broad",))[0]
        crown = material(f"vegetation/{cat}", tm.CROWN_COLOURS.get(cat, COLOURS["vegetation"]))
        prims = []
        for part, mat in ((0, trunk), (1, crown)):
            if instancing:
                v, f = tm.unit_tree(form)[part]
            else:
                v, f = tm.baked(lay, form, part)
                v = v - np.array([off[0], off[1], 0.0])
            pos = mesh.to_y_up(v)
            idx = np.ascontiguousarray(f, dtype=np.uint32)
            a_pos = add_accessor(pos, "VEC3", 34962, minmax=True)
            accessors.append(
                {
                    "bufferView": add_view(idx.tobytes(), 34963),
                    "componentType": 5125,
                    "count": int(idx.size),
                    "type": "SCALAR",
                }
            )
            prims.append({"attributes": {"POSITION": a_pos}, "indices": len(accessors) - 1, "material": mat, "mode": 4})
            counts["vertices"] += len(pos)
            counts["triangles"] += len(f) * (len(lay) if instancing else 1)
        gl_meshes.append({"name": f"vegetation/{cat}", "primitives": prims})
        node = {"name": f"vegetation/{cat}", "mesh": len(gl_meshes) - 1}
        if instancing:
            t, yaw, scale = tm.instances(lay)
            t = t - np.array([off[0], off[1], 0.0])
            quat = np.column_stack([np.zeros(len(yaw)), np.sin(yaw / 2), np.zeros(len(yaw)), np.cos(yaw / 2)])
            node["extensions"] = {
                "EXT_mesh_gpu_instancing": {
                    "attributes": {
                        "TRANSLATION": add_accessor(mesh.to_y_up(t), "VEC3", None),
                        "ROTATION": add_accessor(quat, "VEC4", None),
                        "SCALE": add_accessor(scale, "VEC3", None),
                        # the tree's row in the layer's property table (EXT_instance_features)
                        "_FEATURE_ID_0": add_accessor(rows[sel], "SCALAR", None),
                    }
                }
            }
            node["_tree_rows"] = int(sel.sum())
        if translation is not None:
            node["translation"] = translation
        nodes.append(node)
        counts["instances"] += len(lay)
        counts["meshes"] += 1
    return counts


def _weld32(pos: np.ndarray, faces: np.ndarray, feature: np.ndarray):
    """Merge a building's vertices with equal float32 positions; drop the triangles that collapse."""
    v, f, feat, merged = mesh.weld(pos.astype(np.float64), faces, feature, return_merged=True)
    (f,) = mesh.drop_collapsed(f, merged=merged)
    return np.ascontiguousarray(v, dtype=np.float32), f, feat


def _property_table(name: str, layer: Layer, add_view, *, compact: bool = False, enums: dict | None = None):
    """``EXT_structural_metadata`` class and property table of a layer's ids and columns.

    Integers are INT64, floats FLOAT64, booleans UINT8, everything else
    UTF-8 strings (with UINT32 offsets).  ``compact`` (the trees: hundreds
    of thousands of rows, a few words each) stores integers that fit as
    INT32, floats as FLOAT32 and text columns of at most 255 distinct values
    as ENUMs of UINT8 (their value lists go into ``enums``, the schema's).
    """
    columns = {"id": np.asarray(layer.ids)}
    columns.update({k: np.asarray(v) for k, v in layer.attrs.items() if k != "id"})
    props, values = {}, {}
    for key in sorted(columns):
        col = columns[key]
        pid = "".join(c if c.isalnum() or c == "_" else "_" for c in key)
        if not pid or not (pid[0].isalpha() or pid[0] == "_"):
            pid = "_" + pid
        if compact and col.dtype.kind in "iu" and len(col) and -(2**31) <= col.min() and col.max() < 2**31:
            props[pid] = {"type": "SCALAR", "componentType": "INT32"}
            values[pid] = {"values": add_view(col.astype("<i4").tobytes())}
        elif compact and col.dtype.kind == "f":
            props[pid] = {"type": "SCALAR", "componentType": "FLOAT32"}
            values[pid] = {"values": add_view(col.astype("<f4").tobytes())}
        elif compact and enums is not None and col.dtype.kind in "OUS" and len(col) and _enum_column(col) is not None:
            names, codes = _enum_column(col)
            enum_id = f"{name}_{pid}"
            enums[enum_id] = {
                "valueType": "UINT8",
                "values": [{"name": n, "value": i} for i, n in enumerate(names)],
            }
            props[pid] = {"type": "ENUM", "enumType": enum_id}
            values[pid] = {"values": add_view(codes.astype(np.uint8).tobytes())}
        elif col.dtype.kind == "b":
            props[pid] = {"type": "SCALAR", "componentType": "UINT8"}
            values[pid] = {"values": add_view(col.astype(np.uint8).tobytes())}
        elif col.dtype.kind in "iu":
            props[pid] = {"type": "SCALAR", "componentType": "INT64"}
            values[pid] = {"values": add_view(col.astype("<i8").tobytes())}
        elif col.dtype.kind == "f":
            props[pid] = {"type": "SCALAR", "componentType": "FLOAT64"}
            values[pid] = {"values": add_view(col.astype("<f8").tobytes())}
        else:
            data = _utf8(col)
            offsets = np.concatenate([[0], np.cumsum([len(d) for d in data])]).astype("<u4")
            props[pid] = {"type": "STRING"}
            # every value empty: a bufferView of 0 bytes is invalid glTF (the Khronos validator's
            # VALUE_NOT_IN_RANGE); the table leaves the property out (the class keeps it, not required)
            if offsets[-1]:
                values[pid] = {
                    "values": add_view(b"".join(data)),
                    "stringOffsets": add_view(offsets.tobytes()),
                    "stringOffsetType": "UINT32",
                }
        if pid != key:
            props[pid]["name"] = key
    return {"name": name, "properties": props}, {"class": name, "count": len(layer), "properties": values}


def _utf8(col: np.ndarray) -> list[bytes]:
    """Each value's UTF-8 text (None and non-finite floats empty); each distinct text value encoded once."""
    memo: dict[str, bytes] = {}
    out = []
    for v in col.tolist():
        if type(v) is str:  # the common case: a few distinct names (only str: 0.0 == -0.0, 1 == True ...)
            b = memo.get(v)
            if b is None:
                b = memo[v] = v.encode("utf-8")
        elif v is None or (isinstance(v, float) and not np.isfinite(v)):
            b = b""
        else:
            b = str(v).encode("utf-8")
        out.append(b)
    return out


def _enum_column(col: np.ndarray):
    """A text column of at most 255 distinct non-empty names: (sorted names, code per row); else None."""
    obj = col if col.dtype.kind == "O" else col.astype(object)
    text = obj.astype(str)  # str() of each value, in C: a fixed-width array sorts without Python comparisons
    text[np.equal(obj, None)] = ""
    names, codes = np.unique(text, return_inverse=True)
    if len(names) > 255 or (names == "").any():
        return None
    return [str(n) for n in names], codes


def write_glb(
    path: str | Path,
    layers: Mapping[str, Layer],
    *,
    line_width: float = 1.0,
    crs: str | None = None,
    origin: tuple | None = None,
    copyright: str | None = None,
    lod: int = 1,
    instancing: bool = True,
) -> dict:
    """Write ``layers`` to a binary glTF file; return vertex and face counts per layer (see :func:`glb_bytes`)."""
    data, counts = glb_bytes(
        layers, line_width=line_width, crs=crs, origin=origin, copyright=copyright, lod=lod, instancing=instancing
    )
    Path(path).write_bytes(data)
    log.info("wrote %s: %d meshes, %d triangles", path, len(counts), sum(c["triangles"] for c in counts.values()))
    return counts

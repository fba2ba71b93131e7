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
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import shapely

from sengine.layer import Layer

from . import mesh

__all__ = ["LAYERS", "COLOURS", "LEVELS", "layer_mesh", "glb_bytes", "write_glb"]

log = logging.getLogger(__name__)

#: Layer names the exporters know, in drawing order.
LAYERS = ("water", "streets", "sidewalks", "blocks", "lots", "parks", "roads", "buildings")

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
}
_DEFAULT_COLOUR = (180, 180, 180)

#: Height (m) of each flat layer, so that overlapping surfaces do not z-fight.
LEVELS = {"water": -0.5, "streets": 0.0, "sidewalks": 0.12, "blocks": 0.12, "lots": 0.15, "parks": 0.2, "roads": 0.25}


def layer_mesh(name: str, layer: Layer, *, line_width: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (planar x, y, z up; m) and faces of one layer.

    A layer with a ``height`` column and polygons is extruded (buildings);
    line layers become ribbons ``line_width`` m wide; other polygons are flat.
    """
    geoms = layer.geometry
    if len(geoms) == 0:
        return np.empty((0, 3)), np.empty((0, 3), np.int64)
    types = shapely.get_type_id(geoms)
    lines = np.isin(types, (1, 2, 5))
    polys = np.isin(types, (3, 6))
    parts = []
    if polys.any():
        if "height" in layer.attrs:
            h = np.nan_to_num(np.asarray(layer["height"], np.float64)[polys])
            base = np.asarray(layer.get("base", np.zeros(len(layer))), np.float64)[polys]
            parts.append(mesh.extrude(geoms[polys], h, base=base)[:2])
        else:
            parts.append(mesh.flat(geoms[polys], LEVELS.get(name, 0.1))[:2])
    if lines.any():
        parts.append(mesh.ribbons(geoms[lines], line_width, LEVELS.get(name, 0.25))[:2])
    return mesh.merge(*parts)


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
) -> tuple[bytes, dict]:
    """The binary glTF of ``layers`` and the vertex / triangle counts of each mesh.

    One node, one mesh and one material (named by layer) per non-empty layer,
    in :data:`LAYERS` order; float32 positions and uint32 indices, no normals
    (viewers shade flat).  ``origin`` is ``((x, y), (lat, lon))``, the city's
    origin planar (m) and geographic (deg): vertices are placed relative to
    it.  ``copyright`` goes into ``asset.copyright``.
    """
    meshes = {name: layer_mesh(name, lay, line_width=line_width) for name, lay in layers.items() if lay is not None}
    meshes = {k: v for k, v in meshes.items() if len(v[1])}
    local = origin is not None
    off = np.asarray(origin[0], np.float64) if local else _offset([v for v, _ in meshes.values()])
    order = [n for n in LAYERS if n in meshes] + sorted(n for n in meshes if n not in LAYERS)
    blobs: list[bytes] = []
    views, accessors, gl_meshes, materials, nodes = [], [], [], [], []
    length = 0
    counts = {}

    def add_view(data: bytes, target: int) -> int:
        nonlocal length
        views.append({"buffer": 0, "byteOffset": length, "byteLength": len(data), "target": target})
        blobs.append(data)
        length += len(data)  # float32 / uint32 data keeps 4-byte alignment
        return len(views) - 1

    translation = [float(off[0]), 0.0, float(-off[1])]
    for k, name in enumerate(order):
        v, f = meshes[name]
        v = v.copy()
        v[:, :2] -= off
        pos = np.ascontiguousarray(mesh.to_y_up(v), dtype=np.float32)
        idx = np.ascontiguousarray(f, dtype=np.uint32)
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
        accessors.append(
            {
                "bufferView": add_view(idx.tobytes(), 34963),
                "componentType": 5125,
                "count": int(idx.size),
                "type": "SCALAR",
            }
        )
        rgba = [round(c / 255.0, 6) for c in COLOURS.get(name, _DEFAULT_COLOUR)] + [1.0]
        materials.append(
            {
                "name": name,
                "doubleSided": name != "buildings",
                "pbrMetallicRoughness": {"baseColorFactor": rgba, "metallicFactor": 0.0, "roughnessFactor": 0.9},
            }
        )
        gl_meshes.append(
            {
                "name": name,
                "primitives": [{"attributes": {"POSITION": 2 * k}, "indices": 2 * k + 1, "material": k, "mode": 4}],
            }
        )
        node = {"name": name, "mesh": k}
        if off.any() and not local:
            node["translation"] = translation
        nodes.append(node)
        counts[name] = {"vertices": int(len(pos)), "triangles": int(len(f))}
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
                "extras": {"sengine": extras},
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
                "buffers": [{"byteLength": length}],
            }
        )
    text = json.dumps(doc, sort_keys=True, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    binary = b"".join(blobs)
    binary += b"\0" * (-len(binary) % 4)
    chunks = struct.pack("<II", len(text), 0x4E4F534A) + text
    if binary:
        chunks += struct.pack("<II", len(binary), 0x004E4942) + binary
    return struct.pack("<III", 0x46546C67, 2, 12 + len(chunks)) + chunks, counts


def write_glb(
    path: str | Path,
    layers: Mapping[str, Layer],
    *,
    line_width: float = 1.0,
    crs: str | None = None,
    origin: tuple | None = None,
    copyright: str | None = None,
) -> dict:
    """Write ``layers`` to a binary glTF file; return vertex and face counts per layer (see :func:`glb_bytes`)."""
    data, counts = glb_bytes(layers, line_width=line_width, crs=crs, origin=origin, copyright=copyright)
    Path(path).write_bytes(data)
    log.info("wrote %s: %d meshes, %d triangles", path, len(counts), sum(c["triangles"] for c in counts.values()))
    return counts

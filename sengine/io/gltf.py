"""``city.glb``: the city as a binary glTF 2.0 scene, one named node per layer.

Layers become meshes in batches (:mod:`sengine.io.mesh`): buildings are
extruded to their ``height``; lines (roads) become thin flat ribbons; other
polygons (streets, sidewalks, blocks, lots, parks) become flat surfaces at
slightly different heights so they do not z-fight.  Units are metres; the
frame is glTF's: x east, **y up**, z south (planar y -> -Z, height -> Y).

When the planar coordinates are far from zero (a UTM frame), the vertices are
stored relative to a round offset and each node carries that offset as its
translation, so float32 vertex buffers keep centimetre precision while the
scene's world coordinates stay those of the planar frame.  The offset and the
CRS are also stored in the scene's ``extras``.

The file holds no time stamp: the same layers give the same bytes.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import shapely
import trimesh

from ..layer import Layer
from . import mesh

__all__ = ["LAYERS", "COLOURS", "LEVELS", "layer_mesh", "build_scene", "write_glb"]

log = logging.getLogger(__name__)

#: Layer names the exporters know, in drawing order.
LAYERS = ("streets", "sidewalks", "blocks", "lots", "parks", "roads", "buildings")

#: Base colour (sRGB, 0-255) of each layer.
COLOURS = {
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
LEVELS = {"streets": 0.0, "sidewalks": 0.12, "blocks": 0.12, "lots": 0.15, "parks": 0.2, "roads": 0.25}


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


def build_scene(
    layers: Mapping[str, Layer], *, line_width: float = 1.0, crs: str | None = None
) -> trimesh.Scene:
    """A trimesh Scene with one node (and one mesh) per non-empty layer."""
    meshes = {name: layer_mesh(name, lay, line_width=line_width) for name, lay in layers.items() if lay is not None}
    meshes = {k: v for k, v in meshes.items() if len(v[1])}
    off = _offset([v for v, _ in meshes.values()])
    scene = trimesh.Scene()
    order = [n for n in LAYERS if n in meshes] + sorted(n for n in meshes if n not in LAYERS)
    transform = np.eye(4)
    transform[:3, 3] = mesh.to_y_up(np.array([[off[0], off[1], 0.0]]))[0]
    for name in order:
        v, f = meshes[name]
        v = v.copy()
        v[:, :2] -= off
        tm = trimesh.Trimesh(mesh.to_y_up(v), f, process=False, validate=False)
        rgba = [c / 255.0 for c in COLOURS.get(name, _DEFAULT_COLOUR)] + [1.0]
        material = trimesh.visual.material.PBRMaterial(
            name=name, baseColorFactor=rgba, metallicFactor=0.0, roughnessFactor=0.9,
            doubleSided=name != "buildings",
        )
        tm.visual = trimesh.visual.TextureVisuals(material=material)
        scene.add_geometry(tm, geom_name=name, node_name=name, transform=transform)
    scene.metadata.update({"sengine": {"units": "m", "up": "y", "planar_offset": [float(off[0]), float(off[1])],
                                       "crs": crs or ""}})
    return scene


def write_glb(path: str | Path, layers: Mapping[str, Layer], *, line_width: float = 1.0,
              crs: str | None = None) -> dict:
    """Write ``layers`` to a binary glTF file; return vertex and face counts per layer."""
    scene = build_scene(layers, line_width=line_width, crs=crs)
    data = trimesh.exchange.gltf.export_glb(scene, include_normals=False)
    Path(path).write_bytes(data)
    counts = {name: {"vertices": int(len(g.vertices)), "triangles": int(len(g.faces))}
              for name, g in scene.geometry.items()}
    log.info("wrote %s: %d meshes, %d triangles", path, len(counts), sum(c["triangles"] for c in counts.values()))
    return counts

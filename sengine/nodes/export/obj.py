"""Wavefront OBJ export (``--format obj``): one named object per layer.

The meshes are those of the glTF export (:func:`sengine.nodes.export.gltf.layer_mesh`),
in the same frame: metres, x east, **y up**, z south.  Each layer is an
object and a group (``o roads`` / ``g roads``: Blender makes an object of
each) with its own material in a companion ``.mtl`` file.  With an
``offset`` (``--origin local``) the vertices are relative to the city's
origin, so that Blender's single-precision floats keep them to the
millimetre; the header comments name the offset and the CRS.  Coordinates
are written with millimetre precision; the output is deterministic.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from sengine.layer import Layer

from .gltf import COLOURS, LAYERS, layer_mesh
from .mesh import to_y_up

__all__ = ["write_obj"]

log = logging.getLogger(__name__)


def write_obj(
    path: str | Path,
    layers: Mapping[str, Layer],
    *,
    line_width: float = 1.0,
    offset=None,
    crs: str | None = None,
    attribution: str | None = None,
    lod: int = 1,
) -> dict:
    """Write ``layers`` as OBJ (+ MTL beside it); return triangle counts per object.

    ``offset`` (planar x, y in m) is subtracted from every vertex; ``lod`` 1
    draws buildings as boxes, 2 with their roofs.
    """
    path = Path(path)
    mtl = path.with_suffix(".mtl")
    names = [n for n in LAYERS if n in layers] + sorted(n for n in layers if n not in LAYERS)
    off = np.zeros(2) if offset is None else np.asarray(offset, np.float64)
    head = "# sengine city: metres, y up (x east, z south)\n"
    if crs:
        head += f"# planar frame: {crs}\n"
    head += f"# origin: planar x {off[0]:.3f} y {off[1]:.3f} subtracted from every vertex\n"
    if attribution:
        head += f"# {attribution}\n"
    out = [head + f"mtllib {mtl.name}\n"]
    materials = []
    counts: dict[str, int] = {}
    offset = 1
    for name in names:
        lay = layers[name]
        if lay is None:
            continue
        v, f = layer_mesh(name, lay, line_width=line_width, lod=lod)
        if len(f) == 0:
            continue
        v = v.copy()
        v[:, :2] -= off
        v = to_y_up(v)
        out.append(f"o {name}\ng {name}\nusemtl {name}\n")
        out.append(("v %.3f %.3f %.3f\n" * len(v)) % tuple(v.ravel().tolist()))
        out.append(("f %d %d %d\n" * len(f)) % tuple((f + offset).ravel().tolist()))
        offset += len(v)
        counts[name] = int(len(f))
        r, g, b = (c / 255.0 for c in COLOURS.get(name, (180, 180, 180)))
        materials.append(f"newmtl {name}\nKd {r:.4f} {g:.4f} {b:.4f}\nKa 0 0 0\nd 1\nillum 1\n")
    path.write_text("".join(out), encoding="utf-8")
    mtl.write_text("".join(materials), encoding="ascii")
    log.info("wrote %s: %d groups, %d triangles", path, len(counts), sum(counts.values()))
    return counts

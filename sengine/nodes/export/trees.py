"""Low-poly tree meshes for ``city.glb``: one mesh per plant category, placed by instancing.

A tree is a trunk (a hexagonal prism) and a crown: an icosahedron for a
broad-leaved tree, a six-sided cone for a conifer.  Each mesh is made for a
tree 1 m high and 1 m across the crown and placed by a scale of (crown,
height, crown), a turn about the vertical by its instance number, and a
translation to its foot (glTF's y-up frame).  ``city.glb`` stores one mesh
per category and, per tree, those three (``EXT_mesh_gpu_instancing``: 40
bytes a tree), instead of every tree's vertices (some 1,300 bytes a tree);
:func:`baked` gives the latter, for viewers without the extension and for
the size comparison of ``bench/vegetation.py``.
"""

from __future__ import annotations

import numpy as np

from sengine.layer import Layer

__all__ = ["unit_tree", "instances", "baked", "CROWN_COLOURS", "TRUNK_COLOUR"]

TRUNK_COLOUR = (110, 85, 60)
#: Crown colour (sRGB) of each plant category.
CROWN_COLOURS = {
    "plane": (95, 150, 70),
    "lime": (110, 160, 75),
    "oak": (80, 130, 60),
    "maple": (120, 150, 60),
    "birch": (140, 175, 90),
    "cherry": (200, 150, 170),
    "pine": (50, 100, 60),
    "spruce": (40, 90, 65),
}


def _prism(r: float, z0: float, z1: float, sides: int = 6):
    a = np.arange(sides) * 2 * np.pi / sides
    ring = np.column_stack([r * np.cos(a), r * np.sin(a)])
    v = np.concatenate([np.column_stack([ring, np.full(sides, z0)]), np.column_stack([ring, np.full(sides, z1)])])
    i = np.arange(sides)
    j = (i + 1) % sides
    f = np.concatenate([np.column_stack([i, j, j + sides]), np.column_stack([i, j + sides, i + sides])])
    top = np.column_stack(
        [np.full(sides - 2, sides), np.arange(sides + 1, 2 * sides - 1), np.arange(sides + 2, 2 * sides)]
    )
    bottom = np.column_stack([np.zeros(sides - 2, int), np.arange(2, sides), np.arange(1, sides - 1)])
    return v, np.concatenate([f, top, bottom])


def _icosahedron(r: float, zc: float):
    t = (1 + 5**0.5) / 2
    v = np.array(
        [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
         [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float
    )  # fmt: skip
    v = v / np.linalg.norm(v[0]) * r
    f = np.array(
        [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6],
         [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10],
         [8, 6, 7], [9, 8, 1]]
    )  # fmt: skip
    v = v[:, [0, 2, 1]]  # y-up icosahedron to z-up
    f = f[:, ::-1]  # the axis swap mirrors: keep the faces counter-clockwise from outside
    v[:, 2] += zc
    return v, f


def _cone(r: float, z0: float, z1: float, sides: int = 6):
    a = np.arange(sides) * 2 * np.pi / sides
    v = np.concatenate([np.column_stack([r * np.cos(a), r * np.sin(a), np.full(sides, z0)]), [[0, 0, z1]]])
    i = np.arange(sides)
    f = np.column_stack([i, (i + 1) % sides, np.full(sides, sides)])
    base = np.column_stack([np.zeros(sides - 2, int), np.arange(2, sides), np.arange(1, sides - 1)])
    return v, np.concatenate([f, base])


def unit_tree(form: str) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """(trunk, crown) meshes of a tree 1 m high and 1 m across, z up, its foot at the origin."""
    if form == "conifer":
        return _prism(0.08, 0.0, 0.25), _cone(0.5, 0.15, 1.0)
    return _prism(0.08, 0.0, 0.45), _icosahedron(0.5, 0.55)


def instances(trees: Layer, base: float = 0.15) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Planar translation (x, y, z up; m), yaw (rad) and (crown, height, crown) scale of each tree."""
    import shapely

    xy = shapely.get_coordinates(trees.geometry)
    h = np.maximum(np.nan_to_num(np.asarray(trees.get("height", np.full(len(trees), 10.0)), float)), 0.5)
    c = np.maximum(np.nan_to_num(np.asarray(trees.get("crown", h * 0.6), float)), 0.3)
    inst = np.asarray(trees.get("instance", np.zeros(len(trees), np.int64)), np.int64)
    yaw = (inst * 2.399963) % (2 * np.pi)  # the golden angle: instances face different ways
    return np.column_stack([xy, np.full(len(xy), base)]), yaw, np.column_stack([c, h, c])


def baked(trees: Layer, form: str, part: int, base: float = 0.15) -> tuple[np.ndarray, np.ndarray]:
    """Every tree's trunk (``part`` 0) or crown (1) as one mesh (planar, z up): the glb without instancing."""
    v0, f0 = unit_tree(form)[part]
    t, yaw, s = instances(trees, base)
    n = len(t)
    cos, sin = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
    x = v0[None, :, 0] * s[:, None, 0]
    y = v0[None, :, 1] * s[:, None, 0]
    z = v0[None, :, 2] * s[:, None, 1]
    v = np.stack([x * cos - y * sin + t[:, None, 0], x * sin + y * cos + t[:, None, 1], z + t[:, None, 2]], axis=-1)
    f = (f0[None] + (np.arange(n) * len(v0))[:, None, None]).reshape(-1, 3)
    return v.reshape(-1, 3), f

"""Every output layer of every demo is valid (issue 15 part 7), checked per feature, not as sums.

Each demo config runs in memory; every layer every node hands on is checked:
polygon layers valid, non-empty, each feature of positive area; line layers
each feature of positive length; feature ids unique within the layer.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import shapely

import sengine

CONFIGS = Path(__file__).resolve().parent.parent / "configs"
DEMOS = sorted(p.stem for p in CONFIGS.glob("*.xml"))
POLYGONAL = (3, 6)  # Polygon, MultiPolygon
LINEAR = (1, 2, 5)  # LineString, LinearRing, MultiLineString


def layer_problems(where: str, layer) -> list[str]:
    """What is wrong with one layer (empty list: nothing)."""
    out = []
    ids = np.asarray(layer.ids)
    if len(np.unique(ids)) != len(ids):
        out.append(f"{where}: {len(ids) - len(np.unique(ids))} duplicate ids")
    g = np.asarray(layer.geometry, dtype=object)
    present = np.array([x is not None for x in g], bool)
    if not present.any():
        return out
    g = g[present]
    kind = shapely.get_type_id(g)
    poly, line = np.isin(kind, POLYGONAL), np.isin(kind, LINEAR)
    if poly.any():
        bad = ~shapely.is_valid(g[poly])
        if bad.any():
            out.append(f"{where}: {int(bad.sum())} invalid polygons ({shapely.is_valid_reason(g[poly][bad][:2])})")
        if shapely.is_empty(g[poly]).any():
            out.append(f"{where}: {int(shapely.is_empty(g[poly]).sum())} empty polygons")
        if (shapely.area(g[poly]) <= 0).any():
            out.append(f"{where}: {int((shapely.area(g[poly]) <= 0).sum())} polygons of no area")
    if line.any() and (shapely.length(g[line]) <= 0).any():
        out.append(f"{where}: {int((shapely.length(g[line]) <= 0).sum())} lines of no length")
    return out


@pytest.mark.slow
@pytest.mark.parametrize("name", DEMOS)
def test_every_layer_of_the_demo_is_valid(name):
    layers, _ = sengine.load(CONFIGS / f"{name}.xml").run(workers=1)
    problems, checked = [], 0
    for node_id, ports in layers.items():
        for port, layer in ports.items():
            if not hasattr(layer, "geometry"):
                continue
            checked += 1
            problems += layer_problems(f"{name}: {node_id}.{port}", layer)
    assert checked > 5
    assert not problems, "\n".join(problems[:20])

"""Blocks of the shipped OpenStreetMap extracts for the lot tests (through the load-map nodes).

Helsinki and Monaco come with the repository (``configs/data``); whole Liège
is read from ``../shared/data`` when it is there (the slow tests skip without it).
Each is moved to a local frame (its south-west corner at the origin) so that
areas and overlays keep their precision.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
import shapely

from sengine import Context, Layer
from sengine.registry import get

ROOT = Path(__file__).resolve().parent.parent
LIEGE = ROOT.parent / "shared" / "data" / "liege_streets.osm.pbf"
MINOR = "unclassified,residential,living_street,pedestrian,road"


def _blocks(path: Path, *, minor: str | None, clean: dict, blocks: dict) -> Layer:
    ctx = Context(seed=1)
    read = {"path": str(path), "extras": ""}
    if minor is not None:
        read["minor"] = minor
    roads = get("osm.read")("majorRoads", read, ctx).run()["roads"]
    roads = get("roads.clean")("clean", clean, ctx).run(roads=roads)["roads"]
    out = get("blocks.circuits")("blocks", {"node": False, **blocks}, ctx).run(roads=roads)["blocks"]
    origin = shapely.bounds(out.geometry)[:, :2].min(axis=0)
    return Layer.from_geoms(
        shapely.transform(out.geometry, lambda xy: xy - origin), ids=out.ids, district=np.zeros(len(out), int)
    )


@cache
def osm_blocks(name: str) -> Layer:
    """Blocks of ``helsinki``, ``monaco`` or ``liege`` as their demo configs make them."""
    if name == "helsinki":
        return _blocks(
            ROOT / "configs/data/helsinki_centre.osm.pbf",
            minor=MINOR,
            clean={"tunnels": "drop", "sliver_width": 8, "island_area": 150},
            blocks={"sidewalk": 3, "min_area": 50},
        )
    if name == "monaco":
        return _blocks(
            ROOT / "configs/data/monaco.osm.pbf",
            minor=MINOR,
            clean={"sliver_width": 6},
            blocks={"sidewalk": 2, "min_area": 50},
        )
    if name == "liege":
        return _blocks(LIEGE, minor=None, clean={}, blocks={})
    raise KeyError(name)


@cache
def landuse_blocks(name: str) -> Layer:
    """Blocks of ``helsinki`` or ``monaco`` as ``sengine osm`` makes them (load-map network up to ``landuse``).

    Land more than 100 m from any street is cut off as ``landuse=open``; the
    piece left has a ``street_front`` column (its street-facing boundary),
    and the land closed along the extract's box is no street either.
    """
    import tempfile

    import sengine

    src = {"helsinki": "helsinki_centre.osm.pbf", "monaco": "monaco.osm.pbf"}[name]
    with tempfile.TemporaryDirectory() as tmp:
        cfg = Path(tmp) / "city.xml"
        cfg.write_text(
            f'<sengine version="1"><city name="t" seed="1"><map kind="osm" src="{ROOT / "configs/data" / src}"/>'
            '</city><network base="loadmap"/></sengine>'
        )
        net = sengine.load(cfg)
    need, todo = set(), ["landuse"]
    while todo:
        node = todo.pop()
        if node not in need:
            need.add(node)
            todo += [c.src for c in net.connections if c.dst == node]
    net.specs = {k: v for k, v in net.specs.items() if k in need}
    net.connections = [c for c in net.connections if c.src in need and c.dst in need]
    return net.run(seed=1)["landuse"]

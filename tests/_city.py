"""Test inputs for buildings and exports: a synthetic grid city and Monaco's real footprints.

* :func:`grid_city` lays out a rotated grid of streets (major every few
  blocks), blocks shrunk for sidewalks, each block split into two rows of lots
  (the Manhattan method, paper 002 §5.5), plus one park block.
* :func:`monaco_lots` reads the building polygons of the Monaco extract with
  pyosmium and projects them to the local frame: a few hundred irregular,
  sometimes concave, sometimes holed polygons standing in for lots.
* :func:`height_png` writes a greyscale height map (a radial skyline).
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
import shapely
import shapely.affinity

from sengine import Layer
from sengine.geom.crs import from_lonlat, local_crs
from sengine.plan import CityPlan, MapSpec

ROOT = Path(__file__).resolve().parent.parent
MONACO_ORIGIN = (43.7384, 7.4246)


def data_file(name: str) -> Path:
    """A committed sample file of ``configs/data`` (a missing one is a failure, not a skip)."""
    path = ROOT / "configs" / "data" / name
    if not path.is_file():
        raise FileNotFoundError(path)
    return path


def height_png(path: Path, size=(400, 200)) -> Path:
    """A greyscale PNG: white in the centre fading to black at the corners."""
    from PIL import Image

    w, h = size
    yy, xx = np.mgrid[0:h, 0:w]
    r = np.hypot((xx - w / 2) / (w / 2), (yy - h / 2) / (h / 2)) / np.sqrt(2)
    Image.fromarray(np.clip(255 * (1 - r), 0, 255).astype(np.uint8), "L").save(path)
    return path


def grid_city(
    nx: int = 8,
    ny: int = 6,
    *,
    block=(160.0, 70.0),
    street=20.0,
    sidewalk=3.0,
    lots_per_side=6,
    angle=12.0,
    origin=(40.75, -73.99),
    height_map: Path | None = None,
    hmin=12.0,
    hmax=240.0,
):
    """Layers and plan of a small synthetic grid city (m, planar frame at ``origin``).

    With ``height_map`` (a folder), a radial height map PNG matching the city's
    aspect ratio is written there and put in the plan.
    """
    bw, bh = block
    pitch_x, pitch_y = bw + street, bh + street
    width, height = nx * pitch_x + 2 * street, ny * pitch_y + 2 * street
    centre = (width / 2, height / 2)
    crs = local_crs(origin)
    meta = {"crs": crs, "origin": tuple(origin)}  # as a synthetic city's layers carry it (nodes.maps.plan_meta)

    def rot(g):
        return shapely.affinity.rotate(g, angle, origin=centre)

    xs = street + np.arange(nx + 1) * pitch_x - street / 2
    ys = street + np.arange(ny + 1) * pitch_y - street / 2
    segs, cls = [], []
    for i, x in enumerate(xs):
        for y0, y1 in zip(ys[:-1], ys[1:]):
            segs.append(rot(shapely.LineString([(x, y0), (x, y1)])))
            cls.append("major" if i % 4 == 0 else "minor")
    for j, y in enumerate(ys):
        for x0, x1 in zip(xs[:-1], xs[1:]):
            segs.append(rot(shapely.LineString([(x0, y), (x1, y)])))
            cls.append("major" if j % 3 == 0 else "minor")
    cls = np.array(cls)
    roads = Layer.from_geoms(
        segs, meta=meta, **{"class": cls, "major": cls == "major", "width": np.full(len(segs), street)}
    )
    faces, blocks, sidewalks, lots, lot_block, corner, park_ids = [], [], [], [], [], [], []
    for i in range(nx):
        for j in range(ny):
            x0, y0 = street + i * pitch_x, street + j * pitch_y
            face = shapely.box(x0, y0, x0 + bw, y0 + bh)
            inner = face.buffer(-sidewalk, join_style="mitre")
            faces.append(rot(face))
            bid = len(blocks)
            blocks.append(rot(inner))
            sidewalks.append(rot(face.difference(inner)))
            if (i, j) == (nx // 2, ny // 2):
                park_ids.append(bid)
                continue
            ix0, iy0, ix1, iy1 = inner.bounds
            cuts = np.linspace(ix0, ix1, lots_per_side + 1)
            mid = (iy0 + iy1) / 2
            for k in range(lots_per_side):
                for ya, yb in ((iy0, mid), (mid, iy1)):
                    lots.append(rot(shapely.box(cuts[k], ya, cuts[k + 1], yb)))
                    lot_block.append(bid)
                    corner.append(k in (0, lots_per_side - 1))
    outline = rot(shapely.box(0, 0, width, height))
    streets = shapely.difference(outline, shapely.union_all(faces))
    lot_block = np.array(lot_block)
    lots_layer = Layer.from_geoms(
        lots,
        parent=lot_block,
        meta=meta,
        block=lot_block,
        district=np.zeros(len(lots), np.int64),
        corner=np.array(corner),
        method=np.full(len(lots), "manhattan"),
    )
    plan = CityPlan(name="grid", size=(width, height), origin=origin)
    if height_map is not None:
        png = height_png(Path(height_map) / "height.png", (int(round(width / 4)), int(round(height / 4))))
        plan.maps["height"] = MapSpec("height", png, {"min": str(hmin), "max": str(hmax)}, "test.xml:3")
    return plan, {
        "roads": roads,
        "streets": Layer.from_geoms([streets], meta=meta, kind=np.array(["street"])),
        "sidewalks": Layer.from_geoms(sidewalks, meta=meta, kind=np.full(len(sidewalks), "sidewalk")),
        "blocks": Layer.from_geoms(blocks, meta=meta, district=np.zeros(len(blocks), np.int64)),
        "lots": lots_layer,
        "parks": Layer.from_geoms(
            [blocks[b] for b in park_ids], parent=park_ids, meta=meta, level=np.full(len(park_ids), "block")
        ),
    }


@lru_cache(maxsize=1)
def monaco_lots() -> Layer:
    """Monaco's building polygons as a lots layer in the local frame."""
    import osmium

    path = data_file("monaco.osm.pbf")
    wkb = osmium.geom.WKBFactory()
    geoms, ids = [], []
    fp = osmium.FileProcessor(str(path)).with_areas().with_filter(osmium.filter.KeyFilter("building"))
    for o in fp:
        if o.is_area():
            geoms.append(shapely.from_wkb(wkb.create_multipolygon(o)))
            ids.append(o.id)
    crs = local_crs(MONACO_ORIGIN)
    g = shapely.transform(np.array(geoms, dtype=object), from_lonlat(crs))
    g = shapely.make_valid(g)
    parts, idx = shapely.get_parts(g, return_index=True)
    keep = shapely.get_type_id(parts) == 3
    parts, idx = parts[keep], idx[keep]
    # one polygon per lot: the first polygon part of each building
    _, first = np.unique(idx, return_index=True)
    parts = parts[first]
    n = len(parts)
    return Layer.from_geoms(
        parts,
        ids=np.array(ids)[idx[first]],
        meta={"crs": crs},
        block=np.full(n, -1),
        district=np.zeros(n, np.int64),
        corner=np.zeros(n, bool),
    )

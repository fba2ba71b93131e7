"""One query window, three formats, one answer (issue 16's bbox discrepancy).

bench/export.py read "the same" window of whole Liège's lots as 320
features from the GeoJSON, 321 from the GeoPackage and 322 from the
GeoParquet.  The files held the same features; the queries differed: the
GeoJSON was asked for a lon / lat box spanned by two reprojected corners
(another window: the UTM grid is turned by about 2° there), and the
GeoParquet's ``bbox`` covering was taken for the answer (which boxes meet
the window, not which features).  Asked as GDAL asks (``ogr2ogr -spat``:
the index, then the geometry), in each file's own frame, the three agree
(:mod:`_window`).  Checked on Monaco as ``sengine osm`` writes it and on
generated features a centimetre from a window's edge: concave ones whose
box meets it, thin, tiny, and holed ones around it.
"""

from __future__ import annotations

import numpy as np
import pyogrio
import pytest
import shapely
from _window import box_ids_as_before, window_ids
from conftest import DATA
from hypothesis import given, settings
from hypothesis import strategies as st

from sengine import Layer
from sengine.cli import main
from sengine.geom.crs import reproject
from sengine.io.geojson import write_geojson
from sengine.nodes.export.gpkg import write_gpkg_layer
from sengine.nodes.export.parquet import write_parquet
from sengine.nodes.export.prepare import prepare_layer

UTM = "EPSG:32631"  # Liège's zone
X0, Y0 = 676_000.0, 5_622_000.0  # Liège's centre, m
GAP = 0.05  # m from the window's edge, in or out: five times the GeoJSON's 1e-7 degree grid


@pytest.fixture(scope="module")
def monaco(tmp_path_factory):
    out = tmp_path_factory.mktemp("monaco")
    argv = ["osm", str(DATA / "monaco.osm.pbf"), "-o", str(out), "--workers", "1", "-q"]
    assert main([*argv, "--format", "geojson,gpkg,parquet"]) == 0
    return out


def _windows(bounds, rng, n: int):
    x0, y0, x1, y1 = bounds
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    yield shapely.box(cx - 500, cy - 500, cx + 500, cy + 500)  # the bench's: 1 km around the centre
    for _ in range(n):
        s = rng.uniform(20.0, 1500.0)
        cx, cy = rng.uniform(x0, x1), rng.uniform(y0, y1)
        yield shapely.box(cx - s / 2, cy - s / 2, cx + s / 2, cy + s / 2)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["lots", "buildings", "roads"])
def test_monaco_window_reads_the_same_features_from_every_format(monaco, name):
    info = pyogrio.read_info(monaco / "city.gpkg", layer=name)
    crs = info["crs"]
    assert crs.startswith("EPSG:326")
    table = pyogrio.read_arrow(monaco / "city.gpkg", layer=name, return_fids=True)[1]
    ids = table.column("id").to_numpy()
    geoms = shapely.from_wkb(table.column("geom").to_numpy(zero_copy_only=False))
    assert len(ids) == info["features"] > 300
    rng = np.random.default_rng(16)
    sizes = []
    for win in _windows(info["total_bounds"], rng, 6):
        gj = window_ids(monaco / f"{name}.geojson", win, crs)
        gp = window_ids(monaco / "city.gpkg", win, crs, layer=name)
        pq = window_ids(monaco / f"{name}.parquet", win, crs)
        truth = np.sort(ids[shapely.intersects(geoms, win)])
        assert np.array_equal(gp, truth), (name, win.bounds)
        assert np.array_equal(gj, truth), (name, win.bounds, np.setxor1d(gj, truth))
        assert np.array_equal(pq, truth), (name, win.bounds, np.setxor1d(pq, truth))
        # the covering alone answers with boxes: never fewer, every extra one outside the window
        boxes = box_ids_as_before(monaco / f"{name}.parquet", win.bounds)
        assert np.isin(truth, boxes).all()
        extra = np.setdiff1d(boxes, truth)
        assert not shapely.intersects(geoms[np.isin(ids, extra)], win).any()
        sizes.append(len(truth))
    assert sizes[0] > 50 and max(sizes) > min(sizes)  # the central window is busy, the others differ


# -- generated features around a window, a few centimetres in or out -------------------------------
W = shapely.box(X0, Y0, X0 + 300.0, Y0 + 200.0)


def _feature(kind: str, inside: bool, side: str, t: float, d: float) -> shapely.Polygon:
    """A polygon of ``kind`` meeting ``W`` by ``d`` (m) past its edge ``side`` at ``t`` along it, or ``d`` short of it."""
    x0, y0, x1, y1 = W.bounds
    if kind == "ring":  # a square with a hole around the whole window: its box holds the window
        hole = shapely.box(x0 + d, y0 + d, x1 - d, y1 - d) if inside else shapely.box(x0 - d, y0 - d, x1 + d, y1 + d)
        return shapely.Polygon(shapely.box(x0 - 40, y0 - 40, x1 + 40, y1 + 40).exterior.coords, [hole.exterior.coords])
    if kind == "ell":  # an L around the north-east corner: its box meets the window, the L only when inside
        cx, cy = (x1 - d, y1 - d) if inside else (x1 + d, y1 + d)
        return shapely.Polygon(
            [(cx - 20, cy), (cx, cy), (cx, cy - 20), (cx + 5, cy - 20), (cx + 5, cy + 5), (cx - 20, cy + 5)]
        )
    px, py = {"w": (x0, y0 + t * 200), "e": (x1, y0 + t * 200), "s": (x0 + t * 300, y0), "n": (x0 + t * 300, y1)}[side]
    nx, ny = {"w": (-1, 0), "e": (1, 0), "s": (0, -1), "n": (0, 1)}[side]  # the side's outward normal
    s = -d if inside else d
    ax, ay = px + nx * s, py + ny * s  # the feature's nearest point to the edge
    size = {"box": 8.0, "thin": 30.0, "tiny": 0.02, "concave": 10.0}[kind]
    if kind == "thin":  # a 5 cm sliver along the normal, outwards from the anchor
        return shapely.buffer(shapely.LineString([(ax, ay), (ax + nx * size, ay + ny * size)]), 0.025, cap_style="flat")
    h = size / 2
    tx, ty = -ny, nx  # along the edge
    corners = [
        (ax + tx * h, ay + ty * h),
        (ax + tx * h + nx * size, ay + ty * h + ny * size),
        (ax - tx * h + nx * size, ay - ty * h + ny * size),
        (ax - tx * h, ay - ty * h),
    ]
    if kind == "concave":  # a notch cut into the far side, 70 % deep
        corners = corners[:2] + [(ax + nx * size * 0.3, ay + ny * size * 0.3)] + corners[2:]
    return shapely.Polygon(corners)


@st.composite
def features(draw):
    """Polygons placed in or out of ``W`` by at least GAP, and whether each meets ``W``."""
    out, meets = [], []
    for _ in range(draw(st.integers(1, 25))):
        kind = draw(st.sampled_from(["box", "thin", "tiny", "ell", "ring", "concave"]))
        inside = draw(st.booleans())
        side = draw(st.sampled_from(["w", "e", "s", "n"]))
        t = draw(st.floats(0.05, 0.95))  # where along the side
        d = draw(st.sampled_from([GAP, 0.2, 3.0]))  # how far past the edge (in) or short of it (out), m
        g = shapely.orient_polygons(_feature(kind, inside, side, t, d))
        assert g.is_valid and g.area > 0, (kind, g)
        # placed as asked: meeting the window, or a GAP from it; an L or a ring out has a box that meets it
        assert shapely.intersects(g, W) == inside, (kind, inside)
        if inside:
            assert shapely.area(shapely.intersection(g, W)) >= 0.02 * min(GAP, 0.02) * 0.99, kind
        else:
            assert shapely.distance(g, W) >= GAP - 1e-9, kind
        out.append(g)
        meets.append(inside)
    return np.array(out, dtype=object), np.array(meets)


@settings(max_examples=25, deadline=None)
@given(features())
def test_generated_features_near_the_edge_read_alike(tmp_path_factory, data):
    geoms, meets = data
    tmp = tmp_path_factory.mktemp("win")
    ids = np.arange(len(geoms), dtype=np.int64) * 7 + 3
    raw = Layer.from_geoms(geoms, ids=ids, meta={"crs": UTM})
    lay, _ = prepare_layer("lots", raw, to_ll=reproject(UTM, "EPSG:4326"))
    assert len(lay) == len(geoms)  # nothing here is small enough to be dropped
    write_geojson(tmp / "lots.geojson", lay, reproject(UTM, "EPSG:4326"), precision=7, crs="EPSG:4326")
    write_gpkg_layer(tmp / "city.gpkg", "lots", lay, reproject(UTM, UTM), UTM)
    write_parquet(tmp / "lots.parquet", lay, reproject(UTM, UTM), UTM, name="lots")
    truth = np.sort(ids[meets])
    for path, layer in ((tmp / "lots.geojson", None), (tmp / "city.gpkg", "lots"), (tmp / "lots.parquet", None)):
        got = window_ids(path, W, UTM, layer=layer)
        assert np.array_equal(got, truth), (path.name, np.setxor1d(got, truth))

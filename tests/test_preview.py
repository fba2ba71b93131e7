"""preview.png: framed on the city proper, with the city's name and a north arrow that points to true north."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from PIL import Image

from sengine import Layer
from sengine.geom.crs import utm_crs
from sengine.nodes.export.city import north_angle
from sengine.nodes.export.preview import _FIXED, city_title, frame, render

INK = _FIXED["ink"]


def _city():
    lots = Layer.from_geoms([shapely.box(100 * i, 0, 100 * i + 90, 90) for i in range(4)])
    roads = Layer.from_geoms([shapely.LineString([(0, -5), (400, -5)])])
    park = Layer.from_geoms([shapely.box(-3000, 95, 5000, 4000)])  # a park relation far larger than the streets
    return {"lots": lots, "roads": roads, "parks": park}


def test_frame_is_the_city_not_the_park():
    layers = _city()
    assert frame(layers) == (0.0, -5.0, 400.0, 90.0)
    # with the plan's extent of a synthetic city, that extent too
    assert frame(layers, extent=(-50, -50, 500, 100)) == (-50.0, -50.0, 500.0, 100.0)
    # a city of parks alone is framed on them
    assert frame({"parks": layers["parks"]}) == (-3000.0, 95.0, 5000.0, 4000.0)
    image = np.asarray(render(layers, size=800))
    map_part = image[:-64]
    assert map_part.shape[1] == 800 and map_part.shape[0] < 250  # 400 m x 95 m at 1.95 px/m
    # the lots fill the picture's width (not a corner of a 8 km park)
    from sengine.nodes.export.preview import _LAYER_INDEX

    cols = np.flatnonzero((map_part == _LAYER_INDEX["lots"]).any(axis=0))
    assert cols.min() < 30 and cols.max() > 750


def test_title_and_north_arrow_are_drawn():
    layers = _city()
    plain = np.asarray(render(layers, size=800))
    titled = np.asarray(render(layers, size=800, title="kirchberg"))
    diff = plain != titled
    rows, cols = np.nonzero(diff)
    assert diff.sum() > 100 and rows.max() < 60 and cols.max() < 200  # the name, top left
    # the arrow, top right: its dark half on the left of the tip when north is up
    arrow = plain[10:80, 800 - 80 : 800]
    assert (arrow == INK).sum() > 150
    turned = np.asarray(render(layers, size=800, north=90.0))[10:80, 800 - 80 : 800]
    assert (turned != arrow).sum() > 100
    # inside the dial (centre: row 38, column 40 of the crop) the arrow points up, or right when north is 90 degrees
    rr, cc = np.mgrid[0:70, 0:80]
    inside = (rr - 38) ** 2 + (cc - 40) ** 2 < 22**2

    def ink_extent(a):
        r, c = np.nonzero((a == INK) & inside)
        return r.min() - 38, c.max() - 40

    top, right = ink_extent(arrow)
    assert top < -15 and right < 15  # a tip at the top
    top, right = ink_extent(turned)
    assert top > -15 and right > 15  # a tip on the right


@pytest.mark.parametrize(
    "lat,lon,expect",
    [
        (50.63, 5.57, -1.99),  # Liège, UTM 31N, east of the zone's meridian (3 E): true north leans west
        (43.74, 7.42, 1.09),  # Monaco, UTM 32N, west of its meridian (9 E): east
        (45.0, 9.0, 0.0),  # on the zone's meridian
    ],
)
def test_north_angle_is_the_meridian_convergence(lat, lon, expect):
    crs = utm_crs(lat, lon)
    assert north_angle(crs, (lat, lon)) == pytest.approx(expect, abs=0.05)


def test_city_title_drops_file_extensions():
    assert city_title("liege_streets.osm.pbf") == "liege_streets"
    assert city_title("west_oakland.osm.bz2") == "west_oakland"
    assert city_title("manhattan") == "manhattan"
    assert city_title("") == "city"


def test_demo_preview_has_title_and_arrow(tmp_path):
    from conftest import DATA, run_cli

    r = run_cli("osm", DATA / "kirchberg_iller.osm", "-o", tmp_path / "k", "--format", "png", "--workers", "1")
    assert r.returncode == 0, r.stderr
    image = np.asarray(Image.open(tmp_path / "k" / "preview.png"))
    assert (image[5:50, 5:250] == INK).sum() > 80  # "kirchberg_iller" in its box
    w = image.shape[1]
    assert (image[10:80, w - 80 :] == INK).sum() > 150

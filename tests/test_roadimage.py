"""roads.image: a drawn road map becomes street centre lines and then blocks."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image, ImageDraw

from sengine import CityPlan, Context, MapSpec
from sengine.errors import InputDataError
from sengine.nodes.maps import plan_inputs
from sengine.registry import get

CONFIGS = Path(__file__).resolve().parent.parent / "configs"


def grid_image(path, nx_, ny_, *, size=(400, 300), colour=(255, 255, 255), bg=(0, 0, 0), stroke=3, margin=20):
    im = Image.new("RGB", size, bg)
    d = ImageDraw.Draw(im)
    w, h = size
    xs = np.linspace(margin, w - margin, nx_).round().astype(int)
    ys = np.linspace(margin, h - margin, ny_).round().astype(int)
    for x in xs:
        d.line([(x, margin), (x, h - margin)], fill=colour, width=stroke)
    for y in ys:
        d.line([(margin, y), (w - margin, y)], fill=colour, width=stroke)
    im.save(path)
    return xs, ys


def run_image(path, size=(2000.0, 1500.0), attrs=None, **params):
    plan = CityPlan(size=size, maps={"roads": MapSpec("roads", Path(path), attrs or {}, "city.xml:4")})
    node = get("roads.image")("majorRoads", {k: str(v) for k, v in params.items()}, Context(plan=plan))
    return node.run(**plan_inputs(plan, node))["roads"], node


def blocks_of(roads):
    cleaned = get("roads.clean")("clean", {}, Context()).run(roads=roads)["roads"]
    return get("blocks.circuits")("blocks", {"node": "false"}, Context()).run(roads=cleaned)


@settings(max_examples=8, deadline=None)
@given(st.integers(2, 6), st.integers(2, 5))
def test_grid_image_gives_grid_blocks(tmp_path_factory, nx_, ny_):
    path = tmp_path_factory.mktemp("img") / "grid.png"
    grid_image(path, nx_, ny_)
    roads, node = run_image(path)
    assert roads.meta["crs"].startswith("+proj=tmerc")
    xy = shapely.get_coordinates(roads.geometry)
    assert (xy[:, 0] >= 0).all() and (xy[:, 0] <= 2000).all() and (xy[:, 1] >= 0).all() and (xy[:, 1] <= 1500).all()
    faces = blocks_of(roads)["faces"]
    assert len(faces) == (nx_ - 1) * (ny_ - 1)
    # the cells cover the drawn grid's interior: 5 m per pixel, margins of 20 px
    inner = (400 - 40) * 5.0 * (300 - 40) * 5.0
    assert faces.area() == pytest.approx(inner, rel=0.03)


def test_image_is_placed_north_up(tmp_path):
    im = Image.new("L", (200, 100), 0)
    ImageDraw.Draw(im).line([(20, 10), (180, 10)], fill=255, width=3)  # near the top row
    im.save(tmp_path / "top.png")
    roads, _ = run_image(tmp_path / "top.png", size=(2000.0, 1000.0))
    y = shapely.get_coordinates(roads.geometry)[:, 1]
    assert y.min() > 850 and len(roads) == 1
    assert shapely.length(roads.geometry[0]) == pytest.approx(1600.0, abs=40.0)


def test_configured_colour(tmp_path):
    path = tmp_path / "red.png"
    grid_image(path, 3, 3, colour=(200, 30, 30), bg=(240, 240, 240))
    with pytest.raises(InputDataError, match="no road pixels"):
        run_image(path, tolerance=10)  # no white roads; the light grey background is 26 away from white
    roads, _ = run_image(path, attrs={"color": "#c81e1e"})
    assert len(blocks_of(roads)["faces"]) == 4
    roads2, _ = run_image(path, color="#c81e1e")
    assert len(roads2) == len(roads)


def test_no_roads_is_an_error_naming_the_file(tmp_path):
    path = tmp_path / "blank.png"
    Image.new("RGB", (40, 30), (0, 0, 0)).save(path)
    with pytest.raises(InputDataError, match="blank.png") as exc:
        run_image(path)
    assert "\n" not in str(exc.value) and "city.xml:4" in str(exc.value)


def test_missing_or_bad_image(tmp_path):
    with pytest.raises(InputDataError, match="not found"):
        run_image(tmp_path / "none.png")
    bad = tmp_path / "bad.png"
    bad.write_text("not an image")
    with pytest.raises(InputDataError, match="bad.png"):
        run_image(bad)


def test_roadmap_demo_config(tmp_path):
    from sengine.xmlconfig import load_config

    result = load_config(CONFIGS / "roadmap.xml").run(out=tmp_path / "out", formats={"geojson"})
    counts = result.stats["counts"]
    assert counts["majorRoads"] > 100 and counts["blocks"] > 60 and counts["lots"] > counts["blocks"]

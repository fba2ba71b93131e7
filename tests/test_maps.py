"""Image maps (sengine.geom.raster): every format samples right, regions form a gap-free coverage, errors name file and pixel."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from PIL import Image, ImageDraw

from sengine.errors import InputDataError
from sengine.geom.raster import classify, colour_hex, parse_colour, read_map, vectorize
from sengine.plan import MapSpec

EXTENT = (0.0, 0.0, 600.0, 400.0)  # 1 m per pixel for a 600 x 400 image
SETTINGS = settings(
    max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture]
)


def ramp(dtype=np.uint8, full=255):
    """A 600 x 400 greyscale ramp: value = column * full / 599, the same on every row."""
    cols = np.linspace(0, full, 600)
    return np.repeat(np.rint(cols)[None, :], 400, axis=0).astype(dtype)


GREY_CASES = [
    ("l8.png", lambda a: Image.fromarray(ramp()), 255),
    ("l16.png", lambda a: Image.fromarray(ramp(np.uint16, 65535)), 65535),
    ("l16.tif", lambda a: Image.fromarray(ramp(np.uint16, 65535)), 65535),
    ("l8.tif", lambda a: Image.fromarray(ramp()), 255),
    ("l8.jpg", lambda a: Image.fromarray(ramp()), 255),
    ("rgb.png", lambda a: Image.fromarray(np.repeat(ramp()[:, :, None], 3, axis=2)), 255),
    ("pal.png", lambda a: Image.fromarray(ramp()).convert("P"), 255),
    ("la.png", lambda a: Image.fromarray(ramp()).convert("LA"), 255),
]


@pytest.mark.parametrize("name,make,full", GREY_CASES, ids=[c[0] for c in GREY_CASES])
def test_grey_formats_sample_the_ramp(tmp_path, name, make, full):
    path = tmp_path / name
    make(None).save(path)
    img = read_map(path, EXTENT)
    assert img.shape == (400, 600)
    x = np.array([0.5, 150.5, 300.5, 599.5])
    y = np.array([10.0, 200.0, 390.0, 5.0])
    frac = img.fraction(x, y, bilinear=False)
    want = np.floor(x) / 599.0
    tol = 0.03 if name.endswith(".jpg") else 1.5 / 255
    np.testing.assert_allclose(frac, want, atol=tol)
    heights = img.scaled(x, y, 12.0, 240.0, bilinear=False)
    np.testing.assert_allclose(heights, 12.0 + 228.0 * want, atol=228.0 * tol)


def test_sixteen_bit_keeps_its_precision(tmp_path):
    a = np.full((40, 60), 1000, np.uint16)
    a[:, 30:] = 1001  # one step in 65535: lost in 8 bits
    Image.fromarray(a).save(tmp_path / "h.png")
    img = read_map(tmp_path / "h.png", (0, 0, 60, 40), colour=False)
    assert img.data.dtype == np.uint16 and img.full_scale == 65535
    f = img.fraction([10.0, 50.0], [20.0, 20.0], bilinear=False)
    assert f[1] - f[0] == pytest.approx(1 / 65535)


def test_bilevel_image(tmp_path):
    im = Image.new("1", (60, 40), 0)
    ImageDraw.Draw(im).rectangle((30, 0, 59, 39), fill=1)
    im.save(tmp_path / "b.png")
    img = read_map(tmp_path / "b.png", (0, 0, 60, 40))
    np.testing.assert_allclose(img.fraction([10, 50], [20, 20], bilinear=False), [0.0, 1.0])


def test_row_zero_is_north(tmp_path):
    a = np.zeros((40, 60), np.uint8)
    a[:10, :] = 255  # top rows white
    Image.fromarray(a).save(tmp_path / "n.png")
    img = read_map(tmp_path / "n.png", (100, 200, 160, 240))
    assert img.fraction([130], [239], bilinear=False)[0] == 1.0  # north edge
    assert img.fraction([130], [201], bilinear=False)[0] == 0.0  # south edge
    col, row = img.pixel_index([100.2, 159.9], [239.9, 200.1])
    assert list(col) == [0, 59] and list(row) == [0, 39]
    cx, cy = img.pixel_centre(0, 0)
    assert (cx, cy) == (100.5, 239.5)


def test_bilinear_is_smooth_between_pixel_centres(tmp_path):
    Image.fromarray(ramp()).save(tmp_path / "r.png")
    img = read_map(tmp_path / "r.png", EXTENT)
    x = np.linspace(1, 598, 50)
    f = img.fraction(x, np.full(50, 200.0))
    np.testing.assert_allclose(f, (x - 0.5) / 599, atol=2 / 255)


def colour_map(path, fmt=None, size=(600, 400)):
    """Three colour regions: red west, blue disc, white rest."""
    im = Image.new("RGB", size, (255, 255, 255))
    d = ImageDraw.Draw(im)
    w, h = size
    d.polygon([(0, 0), (w // 2, 0), (w // 3, h), (0, h)], fill=(208, 48, 48))
    d.ellipse((int(w * 0.6), int(h * 0.25), int(w * 0.85), int(h * 0.75)), fill=(32, 96, 255))
    im.save(path, format=fmt, **({"quality": 85} if fmt == "JPEG" else {}))
    return [(255, 255, 255), (208, 48, 48), (32, 96, 255)]


@pytest.mark.parametrize(
    "name,fmt", [("c.png", None), ("c.tif", None), ("c.jpg", "JPEG"), ("c.bmp", None), ("p.png", "P")]
)
def test_colour_regions_partition_the_extent(tmp_path, name, fmt):
    path = tmp_path / name
    legend = colour_map(path, None if fmt == "P" else fmt)
    if fmt == "P":
        Image.open(path).convert("P", palette=Image.Palette.ADAPTIVE, colors=8).save(path)
    img = read_map(path, EXTENT)
    labels = classify(img, legend)
    assert set(np.unique(labels)) == {0, 1, 2}
    # pixel (10, 200) is red, (450, 200) in the disc, (590, 10) white
    assert labels[200, 10] == 1 and labels[200, 450] == 2 and labels[10, 590] == 0
    regions = vectorize(img, labels, grid_size=1e-3)
    geoms = np.array(list(regions.values()), dtype=object)
    assert shapely.is_valid(geoms).all()
    total = shapely.union_all(geoms)
    assert total.area == pytest.approx(600 * 400, rel=1e-9)
    assert shapely.area(geoms).sum() == pytest.approx(600 * 400, rel=1e-9)  # no overlap
    assert regions[2].area == pytest.approx(np.pi * 75 * 100, rel=0.03)
    # the red/white border is shared exactly: its length seen from both sides agrees
    a = shapely.intersection(regions[0].boundary, regions[1].boundary)
    assert a.length > 400


def test_jpeg_noise_is_tolerated_and_cleaned(tmp_path):
    legend = colour_map(tmp_path / "c.jpg", "JPEG")
    img = read_map(tmp_path / "c.jpg", EXTENT)
    assert img.lossy
    labels = classify(img, legend)
    regions = vectorize(img, labels)
    # no specks: each colour is one polygon
    assert all(g.geom_type == "Polygon" for g in regions.values())


def test_unknown_colour_names_colour_pixel_file_and_line(tmp_path):
    path = tmp_path / "d.png"
    colour_map(path)
    im = Image.open(path)
    ImageDraw.Draw(im).rectangle((500, 20, 509, 29), fill=(1, 2, 3))
    im.save(path)
    spec = MapSpec("district", path, {}, "city.xml:4")
    img = read_map(spec, EXTENT)
    with pytest.raises(InputDataError, match=r"city\.xml:4: map 'd\.png': colour #010203 at pixel \(x=500, y=20\)"):
        classify(img, [(255, 255, 255), (208, 48, 48), (32, 96, 255)], names=["a", "b", "c"])


def test_wrong_size_is_an_error_naming_the_file(tmp_path):
    path = tmp_path / "w.png"
    Image.new("RGB", (600, 300)).save(path)
    with pytest.raises(InputDataError, match=r"x\.xml:2: map '.*w\.png': image is 600x300 px") as err:
        read_map(MapSpec("landuse", path, {}, "x.xml:2"), EXTENT)
    assert "\n" not in str(err.value)
    read_map(path, (0, 0, 6000, 3020))  # within 1 %


@pytest.mark.parametrize("content", [b"", b"not an image at all", b"\x89PNG\r\n\x1a\n\x00\x00garbage"])
def test_unreadable_file(tmp_path, content):
    path = tmp_path / "broken.png"
    path.write_bytes(content)
    with pytest.raises(InputDataError, match=r"x\.xml:3: map '.*broken\.png': cannot read the image"):
        read_map(MapSpec("district", path, {}, "x.xml:3"), EXTENT)


def test_missing_file(tmp_path):
    with pytest.raises(InputDataError, match=r"map '.*nope\.png': file not found"):
        read_map(tmp_path / "nope.png", EXTENT)


def test_colour_parsing():
    assert parse_colour("#d03030") == (208, 48, 48)
    assert parse_colour("D03030") == (208, 48, 48)
    assert parse_colour("#d33") == (221, 51, 51)
    assert parse_colour("208, 48 48") == (208, 48, 48)
    assert colour_hex((208, 48, 48)) == "#d03030"
    with pytest.raises(InputDataError, match="colour 'red'"):
        parse_colour("red", where="a.xml:1")
    with pytest.raises(InputDataError):
        parse_colour("300 1 1")


@st.composite
def label_images(draw):
    rows = draw(st.integers(4, 30))
    cols = draw(st.integers(4, 30))
    k = draw(st.integers(1, 5))
    rng = np.random.default_rng(draw(st.integers(0, 2**31)))
    blocky = draw(st.booleans())
    if blocky:  # rectangles painted over each other
        lab = np.zeros((rows, cols), np.int64)
        for _ in range(draw(st.integers(0, 8))):
            r0, c0 = rng.integers(0, rows), rng.integers(0, cols)
            lab[r0 : r0 + rng.integers(1, rows), c0 : c0 + rng.integers(1, cols)] = rng.integers(0, k)
    else:  # salt and pepper: the hardest case for noding
        lab = rng.integers(0, k, (rows, cols))
    return lab


@SETTINGS
@given(lab=label_images(), simplify=st.sampled_from([0.0, 1.0, 2.0]))
def test_vectorize_is_a_coverage_of_the_labels(tmp_path, lab, simplify):
    rows, cols = lab.shape
    palette = np.array([(0, 0, 0), (255, 0, 0), (0, 255, 0), (0, 0, 255), (255, 255, 0)], np.uint8)
    Image.fromarray(palette[lab]).save(tmp_path / "l.png")
    extent = (10.0, 20.0, 10.0 + cols * 7.0, 20.0 + rows * 7.0)
    img = read_map(tmp_path / "l.png", extent)
    labels = classify(img, palette[: lab.max() + 1])
    assert (labels == lab).all()
    regions = vectorize(img, labels, simplify=simplify, grid_size=1e-6)
    geoms = np.array(list(regions.values()), dtype=object)
    assert shapely.is_valid(geoms).all()
    area = cols * rows * 49.0
    assert shapely.union_all(geoms).area == pytest.approx(area, rel=1e-6)
    assert shapely.area(geoms).sum() == pytest.approx(area, rel=1e-6)
    if simplify == 0:  # exact pixel areas
        for k, g in regions.items():
            assert g.area == pytest.approx((lab == k).sum() * 49.0, rel=1e-9)

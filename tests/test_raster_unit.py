"""sengine.geom.raster, function by function, with values worked out by hand.

test_maps reads real image files of every format; these pin the pixel grid (edges, indices,
centres), sampling (nearest and bilinear on a 2 x 2 image), the Pillow modes, the one-line
errors with their exact wording, classification with and without compression noise, and
vectorization of tiny label images, for the mutation run of docs/mutation.md.
"""

from __future__ import annotations

import os
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
import shapely
from PIL import Image

from sengine.errors import InputDataError
from sengine.geom.raster import (
    LOSSY_FORMATS,
    MAX_PIXELS,
    ImageMap,
    _majority,
    _runs,
    _smooth_edges,
    classify,
    colour_hex,
    parse_colour,
    read_map,
    vectorize,
)
from sengine.plan import MapSpec

GRID = np.array([[0.0, 1.0], [0.5, 1.0]], np.float32)  # a 2 x 2 float map on a 2 m square


def _map(data, extent=(0.0, 0.0, 2.0, 2.0), **kw):
    return ImageMap(np.asarray(data), extent, Path("m.png"), **kw)


# ---------------------------------------------------------------------------------------------
# the pixel grid


def test_grid_geometry():
    m = _map(np.zeros((4, 8), np.uint8), (10.0, 20.0, 26.0, 24.0))
    assert m.shape == (4, 8) and type(m.shape[0]) is int
    assert m.pixel_size == (2.0, 1.0)
    xs, ys = m.edges()
    assert xs.tolist() == [10, 12, 14, 16, 18, 20, 22, 24, 26]
    assert ys.tolist() == [24, 23, 22, 21, 20]  # row edge 0 is north
    cols, rows = m.pixel_index([10.0, 11.9, 12.0, 25.9, 26.0, -100.0], [24.0, 23.5, 23.0, 20.1, 20.0, 100.0])
    assert cols.tolist() == [0, 0, 1, 7, 7, 0] and rows.tolist() == [0, 0, 1, 3, 3, 0]
    assert cols.dtype == np.int64
    cols, rows = m.pixel_index(1e9, -1e9)
    assert int(cols) == 7 and int(rows) == 3
    x, y = m.pixel_centre([0, 7], [0, 3])
    assert x.tolist() == [11.0, 25.0] and y.tolist() == [23.5, 20.5]
    assert m.label() == "map 'm.png'"
    assert not m.lossy and _map(GRID, format="JPEG").lossy and _map(GRID, format="PNG").lossy is False
    assert LOSSY_FORMATS == {"JPEG", "MPO", "WEBP", "JPEG2000"}


def test_edges_end_exactly_on_the_extent():
    m = _map(np.zeros((3, 7), np.uint8), (0.1, 0.2, 0.7, 0.5))
    xs, ys = m.edges()
    assert xs[-1] == 0.7 and ys[-1] == 0.2 and xs[0] == 0.1 and ys[0] == 0.5
    assert len(xs) == 8 and len(ys) == 4


def test_sample_grey_fraction_and_scaled():
    m = _map(GRID, full_scale=1.0)
    assert m.sample([0.5, 1.5, 0.5], [1.5, 1.5, 0.5]).tolist() == [0.0, 1.0, 0.5]
    assert m.grey().tolist() == [[0.0, 1.0], [0.5, 1.0]]
    # bilinear between the four pixel centres (0.5 or 1.5 m)
    f = m.fraction([1.0, 0.5, 0.75, -5.0, 2.0, 1.5], [1.0, 1.5, 1.0, 10.0, 0.0, 0.5])
    assert f.tolist() == [0.625, 0.0, 0.4375, 0.0, 1.0, 1.0]
    assert m.fraction([0.75], [1.0], bilinear=False).tolist() == [0.5]
    assert m.scaled([1.0], [1.0], 10.0, 30.0).tolist() == [22.5]
    assert m.scaled([0.75], [1.0], 10.0, 30.0, bilinear=False).tolist() == [20.0]
    # one column, three rows: bilinear along the column only
    col = _map(np.array([[0], [100], [200]], np.uint8), (0.0, 0.0, 1.0, 3.0), full_scale=200.0)
    assert col.fraction([0.5, 0.5, 0.9], [2.5, 2.0, 0.5]).tolist() == [0.0, 0.25, 1.0]
    row = _map(np.array([[0, 100, 200]], np.uint8), (0.0, 0.0, 3.0, 1.0), full_scale=200.0)
    assert row.fraction([0.5, 1.0, 2.9], [0.5, 0.5, 0.1]).tolist() == [0.0, 0.25, 1.0]


def test_grey_of_colour_and_full_scale():
    rgb = _map(np.array([[[100, 200, 50], [255, 255, 255]]], np.uint8), (0.0, 0.0, 2.0, 1.0))
    g = rgb.grey()
    assert g.shape == (1, 2) and np.allclose(g, [[153.0 / 255.0, 1.0]], atol=1e-12)
    sixteen = _map(np.array([[0, 65535, 70000]], np.int32), (0.0, 0.0, 3.0, 1.0), full_scale=65535.0)
    assert sixteen.grey().tolist() == [[0.0, 1.0, 1.0]]  # clipped to [0, 1]
    neg = _map(np.array([[-1.0, 0.5]], np.float32), (0.0, 0.0, 2.0, 1.0), full_scale=1.0)
    assert neg.grey().tolist() == [[0.0, 0.5]]


# ---------------------------------------------------------------------------------------------
# reading


def _save(tmp_path, name, im, **kw):
    path = tmp_path / name
    im.save(path, **kw)
    return path


def test_read_map_modes(tmp_path):
    ext = (0.0, 0.0, 3.0, 1.0)
    a = np.array([[0, 128, 255]], np.uint8)
    m = read_map(_save(tmp_path, "l.png", Image.fromarray(a)), ext)
    assert m.data.dtype == np.uint8 and m.data.tolist() == [[0, 128, 255]] and m.full_scale == 255.0
    assert (m.mode, m.format, m.where) == ("L", "PNG", "") and m.src.name == "l.png" and m.extent == ext
    assert type(m.extent[0]) is float
    # colour=True: grey as grey RGB
    c = read_map(tmp_path / "l.png", ext, colour=True)
    assert c.data.shape == (1, 3, 3) and c.data[:, :, 0].tolist() == [[0, 128, 255]] and c.data.dtype == np.uint8
    # 1-bit
    b = read_map(_save(tmp_path, "b.png", Image.fromarray(a > 100)), ext)
    assert b.data.tolist() == [[0, 255, 255]] and b.full_scale == 255.0 and b.data.dtype == np.uint8
    # LA keeps the grey
    la = read_map(_save(tmp_path, "la.png", Image.fromarray(a).convert("LA")), ext)
    assert la.data.tolist() == [[0, 128, 255]] and la.data.ndim == 2
    # 16 bit
    a16 = np.array([[0, 30000, 65535]], np.uint16)
    s = read_map(_save(tmp_path, "s.png", Image.fromarray(a16)), ext)
    assert s.data.dtype == np.uint16 and s.data.tolist() == [[0, 30000, 65535]] and s.full_scale == 65535.0
    s8 = read_map(tmp_path / "s.png", ext, colour=True)  # 16-bit grey to 8-bit grey RGB, rounded
    assert s8.data[:, :, 1].tolist() == [[0, 117, 255]] and s8.full_scale == 255.0 and s8.data.dtype == np.uint8
    # 32-bit integer: full scale from the values
    i_small = read_map(_save(tmp_path, "i.tif", Image.fromarray(np.array([[0, 7, 255]], np.int32))), ext)
    assert i_small.data.dtype == np.int32 and i_small.full_scale == 255.0 and i_small.mode == "I"
    i_big = read_map(_save(tmp_path, "j.tif", Image.fromarray(np.array([[0, 7, 256]], np.int32))), ext)
    assert i_big.full_scale == 65535.0
    i_neg = read_map(_save(tmp_path, "k.tif", Image.fromarray(np.array([[-1, 7, 200]], np.int32))), ext)
    assert i_neg.full_scale == 65535.0
    # float
    f = read_map(_save(tmp_path, "f.tif", Image.fromarray(np.array([[0.0, 0.25, 1.0]], np.float32))), ext)
    assert f.data.dtype == np.float32 and f.data.tolist() == [[0.0, 0.25, 1.0]] and f.full_scale == 1.0
    # RGB kept as colour by default, made grey on request
    rgb = Image.fromarray(np.array([[[100, 200, 50], [0, 0, 0], [255, 255, 255]]], np.uint8))
    r = read_map(_save(tmp_path, "r.png", rgb), ext)
    assert r.data.shape == (1, 3, 3) and r.data[0, 0].tolist() == [100, 200, 50]
    g = read_map(tmp_path / "r.png", ext, colour=False)
    assert g.data.tolist() == [[153, 0, 255]] and g.data.dtype == np.uint8


def test_read_map_palettes(tmp_path):
    ext = (0.0, 0.0, 2.0, 1.0)
    p = Image.fromarray(np.array([[[204, 51, 51], [255, 255, 255]]], np.uint8)).convert("P")  # web palette colours
    m = read_map(_save(tmp_path, "p.png", p), ext)
    assert m.mode == "P" and m.data.shape == (1, 2, 3) and m.data[0].tolist() == [[204, 51, 51], [255, 255, 255]]
    # a palette with a transparent entry goes through RGBA, then RGB
    t = Image.new("P", (2, 1))
    t.putpalette([10, 20, 30, 40, 50, 60] + [0] * 762)
    t.putpixel((1, 0), 1)
    t.info["transparency"] = 0
    path = _save(tmp_path, "t.png", t, transparency=0)
    m = read_map(path, ext)
    assert m.data.shape == (1, 2, 3) and m.data[0].tolist() == [[10, 20, 30], [40, 50, 60]]
    g = read_map(path, ext, colour=False)  # grey of the RGB(A) palette colours
    assert g.data.ndim == 2 and g.full_scale == 255.0


def test_read_map_errors(tmp_path):
    ext = (0.0, 0.0, 600.0, 400.0)
    with pytest.raises(InputDataError) as e:
        read_map(tmp_path / "none.png", ext, where="c.xml:5")
    assert str(e.value) == f"c.xml:5: map '{tmp_path / 'none.png'}': file not found"
    with pytest.raises(InputDataError) as e:
        read_map(tmp_path, ext)
    assert str(e.value) == f"map '{tmp_path}' is a folder, not an image file"
    fifo = tmp_path / "pipe.png"
    os.mkfifo(fifo)
    with pytest.raises(InputDataError) as e:
        read_map(fifo, ext, where="c.xml:6")
    assert str(e.value) == f"c.xml:6: map '{fifo}' is not a regular file (a pipe or device?)"
    with pytest.raises(InputDataError) as e:
        read_map(tmp_path / "x" / "y.png" / "z", ext)
    assert "file not found" in str(e.value)
    longname = tmp_path / ("n" * 300 + ".png")  # ENAMETOOLONG: an OSError other than not-found
    with pytest.raises(InputDataError) as e:
        read_map(longname, ext)
    assert str(e.value) == f"map '{longname}': cannot read the file (File name too long)"
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"not an image")
    with pytest.raises(InputDataError, match=r"^map '.*bad\.png': cannot read the image \(cannot identify image file"):
        read_map(bad, ext)


def _png_header(cols: int, rows: int) -> bytes:
    """A PNG whose header announces cols x rows pixels (its data is one empty IDAT: never decoded here)."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    ihdr = struct.pack(">IIBBBBB", cols, rows, 8, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"")) + chunk(b"IEND", b"")


def test_read_map_refuses_huge_images_before_decoding(tmp_path):
    assert MAX_PIXELS == 64_000_000
    path = tmp_path / "huge.png"
    path.write_bytes(_png_header(8001, 8000))
    with pytest.raises(InputDataError) as e:
        read_map(path, (0.0, 0.0, 8001.0, 8000.0), where="c.xml:2")
    assert str(e.value) == (
        f"c.xml:2: map '{path}': the image is 8001x8000 px (64 Mpx, about 0.2 GB decoded); the limit is 64 Mpx"
    )
    # exactly at the limit it is decoded (and this one then fails as truncated: not the size message)
    path.write_bytes(_png_header(8000, 8000))
    with pytest.raises(InputDataError) as e:
        read_map(path, (0.0, 0.0, 8000.0, 8000.0))
    assert "cannot read the image" in str(e.value)


def test_read_map_aspect_and_mapspec(tmp_path):
    path = _save(tmp_path, "w.png", Image.new("L", (100, 50)))
    with pytest.raises(InputDataError) as e:
        read_map(MapSpec("landuse", path, {}, "x.xml:2"), (0.0, 0.0, 100.0, 100.0))
    assert str(e.value) == (
        f"x.xml:2: map '{path}': image is 100x50 px (width/height 2.000) but the city is 100x100 m "
        "(width/height 1.000); the ratios must agree within 1%"
    )
    # the where given wins over the MapSpec's
    with pytest.raises(InputDataError, match=r"^y\.xml:9: "):
        read_map(MapSpec("landuse", path, {}, "x.xml:2"), (0.0, 0.0, 100.0, 100.0), where="y.xml:9")
    m = read_map(MapSpec("landuse", path, {}, "x.xml:2"), (0.0, 0.0, 200.0, 100.0))
    assert m.where == "x.xml:2" and m.src == path
    # within tolerance: 2 / 1.98 is 1.0101 (1.01 %), 2 / 1.99 is 0.5 %
    read_map(path, (0.0, 0.0, 199.0, 100.0))
    with pytest.raises(InputDataError, match="within 1%"):
        read_map(path, (0.0, 0.0, 198.0, 100.0))
    read_map(path, (0.0, 0.0, 198.0, 100.0), aspect_tolerance=0.02)
    with pytest.raises(InputDataError, match="within 2%"):
        read_map(path, (0.0, 0.0, 190.0, 100.0), aspect_tolerance=0.02)
    # the other way: wider city than image
    read_map(path, (0.0, 0.0, 201.0, 100.0))
    with pytest.raises(InputDataError):
        read_map(path, (0.0, 0.0, 203.0, 100.0))


# ---------------------------------------------------------------------------------------------
# colours and classification


def test_parse_colour_and_hex():
    assert parse_colour("  #AbC ") == (170, 187, 204)
    assert parse_colour("0 0 0") == (0, 0, 0) and parse_colour("255,255,255") == (255, 255, 255)
    for bad in ("#abcd", "1 2", "1 2 3 4", "1 2 x", "-1 0 0", "256 0 0", "#ggg"):
        with pytest.raises(InputDataError) as e:
            parse_colour(bad, where="a.xml:1")
        assert str(e.value) == f"a.xml:1: colour {bad!r} is not '#rrggbb', '#rgb' or 'r g b' (0-255)"
    with pytest.raises(InputDataError) as e:
        parse_colour("red")
    assert str(e.value) == "colour 'red' is not '#rrggbb', '#rgb' or 'r g b' (0-255)" and e.value.where is None
    assert colour_hex((0, 15, 255)) == "#000fff" and colour_hex(np.array([1, 2, 3], np.uint8)) == "#010203"


RED, WHITE, BLUE = (208, 48, 48), (255, 255, 255), (32, 96, 255)


def test_classify_lossless_by_hand():
    data = np.array([[RED, WHITE, BLUE], [BLUE, BLUE, RED]], np.uint8)
    m = _map(data, (0.0, 0.0, 3.0, 2.0))
    labels = classify(m, [WHITE, RED, BLUE])
    assert labels.tolist() == [[1, 0, 2], [2, 2, 1]]
    assert classify(m, np.array([WHITE, RED, BLUE]).ravel()).tolist() == labels.tolist()  # flat legend
    # greyscale maps are compared as grey RGB
    g = _map(np.array([[0, 255], [128, 0]], np.uint8))
    assert classify(g, [(0, 0, 0), (255, 255, 255), (128, 128, 128)]).tolist() == [[0, 1], [2, 0]]
    g16 = _map(np.array([[0, 65535]], np.uint16), (0.0, 0.0, 2.0, 1.0), full_scale=65535.0)
    assert classify(g16, [(255, 255, 255), (0, 0, 0)]).tolist() == [[1, 0]]
    # a tolerance lets near colours in: (210, 48, 48) is 2 from RED
    near = _map(np.array([[[210, 48, 48], WHITE]], np.uint8), (0.0, 0.0, 2.0, 1.0))
    with pytest.raises(InputDataError):
        classify(near, [WHITE, RED])
    assert classify(near, [WHITE, RED], tolerance=2.0).tolist() == [[1, 0]]
    with pytest.raises(InputDataError):
        classify(near, [WHITE, RED], tolerance=1.99)


def test_classify_error_message():
    odd = (1, 2, 3)
    data = np.array([[RED, WHITE, odd], [odd, (9, 9, 9), WHITE]], np.uint8)
    m = _map(data, (0.0, 0.0, 3.0, 2.0), where="c.xml:7")
    with pytest.raises(InputDataError) as e:
        classify(m, [WHITE, RED], names=["open"], what="district rules")
    # the most frequent stray colour, at its first pixel in reading order; every stray pixel counted
    assert str(e.value) == (
        "c.xml:7: map 'm.png': colour #010203 at pixel (x=2, y=0) is not in the district rules "
        "(3 pixels match no colour within 0; known: #ffffff open, #d03030)"
    )
    one = _map(np.array([[RED, (9, 9, 9)]], np.uint8), (0.0, 0.0, 2.0, 1.0))
    with pytest.raises(InputDataError) as e:
        classify(one, [RED], tolerance=1.5)
    assert str(e.value) == (
        "map 'm.png': colour #090909 at pixel (x=1, y=0) is not in the legend "
        "(1 pixel match no colour within 1.5; known: #d03030)"
    )
    assert e.value.where is None
    with pytest.raises(InputDataError) as e:
        classify(m, [])
    assert str(e.value) == "c.xml:7: map 'm.png': no legend to match its colours against"


def test_classify_lossy_tolerates_border_pixels_and_smooths():
    # a JPEG-like map: a white field with a red square and one off-colour pixel on its border
    data = np.zeros((8, 8, 3), np.uint8)
    data[:] = WHITE
    data[2:6, 2:6] = RED
    data[1, 3] = (230, 150, 150)  # blended, 116 from white and 120 from red: beyond 60 of both
    data[6, 6] = (250, 250, 250)  # near white
    lossy = _map(data, (0.0, 0.0, 8.0, 8.0), format="JPEG")
    labels = classify(lossy, [WHITE, RED])
    want = np.zeros((8, 8), int)
    want[2:6, 2:6] = 1
    # the blended pixel is nearest red (146 against 151) and so is kept red by the filter next to it at (2, 2),
    # then loses its 3 x 3 vote to white (4 red, 5 white); the square's other corners (4 of 9) turn white
    want[2, 5] = want[5, 2] = want[5, 5] = 0
    assert labels.tolist() == want.tolist()
    with pytest.raises(InputDataError, match=r"colour #e69696 at pixel \(x=3, y=1\)"):
        classify(_map(data, (0.0, 0.0, 8.0, 8.0), format="PNG"), [WHITE, RED])
    assert classify(_map(data, (0.0, 0.0, 8.0, 8.0), format="PNG"), [WHITE, RED], tolerance=200).shape == (8, 8)
    # a 3 x 3 patch of stray colour is an error even in a lossy file
    data[5:8, 5:8] = (0, 200, 0)
    with pytest.raises(
        InputDataError, match=r"colour #00c800 at pixel \(x=5, y=5\) .* \(9 pixels match no colour within 60"
    ):
        classify(_map(data, (0.0, 0.0, 8.0, 8.0), format="JPEG"), [WHITE, RED])
    # lossy with one legend colour: no smoothing needed
    one = _map(np.full((3, 3, 3), 250, np.uint8), (0.0, 0.0, 3.0, 3.0), format="JPEG")
    assert classify(one, [WHITE]).tolist() == [[0] * 3] * 3
    # lossy smoothing removes a single speck of a legend colour
    speck = np.zeros((5, 5, 3), np.uint8)
    speck[:] = WHITE
    speck[2, 2] = RED
    assert classify(_map(speck, (0.0, 0.0, 5.0, 5.0), format="JPEG"), [WHITE, RED]).sum() == 0
    assert classify(_map(speck, (0.0, 0.0, 5.0, 5.0), format="PNG"), [WHITE, RED]).sum() == 1


def test_majority_by_hand():
    lab = np.array([[0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 2, 2], [0, 0, 2, 2]])
    got = _majority(lab, 3)
    assert got.tolist() == [[0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 2, 2], [0, 0, 2, 2]]
    # ties keep the centre: a vertical border, 3 x 3 windows split 6 / 3 or 3 / 6 at the edge (nearest mode)
    half = np.array([[0, 0, 1, 1]] * 3)
    assert _majority(half, 2).tolist() == half.tolist()
    # labels need not start at 0 nor be contiguous
    sparse = np.array([[3, 3, 3], [3, 7, 3], [3, 3, 3]])
    assert _majority(sparse, 8).tolist() == [[3] * 3] * 3
    # a 2 x 2 checkerboard window: ties everywhere, every centre kept
    cb = np.array([[0, 1], [1, 0]])
    assert _majority(cb, 2).tolist() == [[0, 1], [1, 0]]


# ---------------------------------------------------------------------------------------------
# vectorizing


def test_runs_by_hand():
    mask = np.array([[True, True, False, True], [False, False, False, False], [False, True, True, True]])
    row, start, end = _runs(mask)
    assert row.tolist() == [0, 0, 2] and start.tolist() == [0, 3, 1] and end.tolist() == [2, 4, 4]
    row, start, end = _runs(np.zeros((2, 0), bool))
    assert len(row) == len(start) == len(end) == 0


def test_vectorize_by_hand():
    # left column label 1, the rest 0, on 3 x 2 pixels of 2 m: areas 2 * 2 * 2 and 4 * 2 * 2
    lab = np.array([[1, 0, 0], [1, 0, 0]])
    m = _map(np.zeros((2, 3), np.uint8), (10.0, 0.0, 16.0, 4.0))
    out = vectorize(m, lab, simplify=0.0)
    assert sorted(out) == [0, 1] and all(type(k) is int for k in out)
    assert out[1].equals(shapely.box(10, 0, 12, 4)) and out[0].equals(shapely.box(12, 0, 16, 4))
    out = vectorize(m, lab)  # straight borders stay straight
    assert out[1].equals(shapely.box(10, 0, 12, 4)) and out[0].equals(shapely.box(12, 0, 16, 4))
    # one label: the frame
    one = vectorize(m, np.zeros((2, 3), int))
    assert list(one) == [0] and one[0].equals(shapely.box(10, 0, 16, 4))
    # a horizontal border between rows
    tb = vectorize(m, np.array([[2, 2, 2], [5, 5, 5]]))
    assert tb[2].equals(shapely.box(10, 2, 16, 4)) and tb[5].equals(shapely.box(10, 0, 16, 2))
    # grid_size snaps coordinates
    snapped = vectorize(_map(np.zeros((1, 3)), (0.0, 0.0, 1.0, 1 / 3)), np.array([[0, 1, 1]]), grid_size=0.01)
    assert shapely.area(snapped[0]) == pytest.approx(0.33 * 0.33, abs=1e-12)
    assert shapely.area(snapped[1]) == pytest.approx(0.67 * 0.33, abs=1e-12)
    for g in snapped.values():
        xy = shapely.get_coordinates(g)
        assert np.allclose(xy * 100, np.rint(xy * 100), atol=1e-9)


def test_vectorize_staircase_is_smoothed_and_stays_a_coverage():
    # a diagonal staircase of 8 x 8 pixels: label 1 below the diagonal
    n = 8
    lab = (np.add.outer(np.arange(n), -np.arange(n)) > 0).astype(int)
    m = _map(np.zeros((n, n), np.uint8), (0.0, 0.0, float(n), float(n)))
    stair = vectorize(m, lab, simplify=0.0)
    smooth = vectorize(m, lab, simplify=1.0)
    for out in (stair, smooth):
        geoms = np.array([out[0], out[1]], dtype=object)
        assert shapely.is_valid(geoms).all()
        assert shapely.area(geoms).sum() == pytest.approx(n * n, rel=1e-12)
        assert shapely.union_all(geoms).area == pytest.approx(n * n, rel=1e-12)
    assert stair[1].area == n * (n - 1) / 2  # 28 whole pixels
    # the staircase has 2 vertices per step; smoothed it is a straight cut within half a pixel
    assert shapely.get_num_coordinates(stair[1]) > 2 * (n - 1)
    assert shapely.get_num_coordinates(smooth[1]) <= 6
    assert abs(smooth[1].area - n * n / 2) <= n * 0.5 * np.sqrt(2) * np.sqrt(2)
    assert smooth[1].area != stair[1].area


def test_smooth_edges_by_hand():
    extent = (0.0, 0.0, 10.0, 10.0)
    stairs = shapely.LineString([(2, 2), (3, 2), (3, 3), (4, 3), (4, 4)])  # 1 m steps: all replaced
    out = _smooth_edges(np.array([stairs], dtype=object), extent, 1.5)
    assert out.dtype == object and len(out) == 1
    assert shapely.get_coordinates(out[0]).tolist() == [[2, 2], [2.5, 2], [3, 2.5], [3.5, 3], [4, 3.5], [4, 4]]
    corner = shapely.LineString([(2, 2), (6, 2), (6, 6)])  # two 4 m sides: the corner stays
    out = _smooth_edges(np.array([corner], dtype=object), extent, 1.5)
    assert shapely.get_coordinates(out[0]).tolist() == [[2, 2], [4, 2], [6, 2], [6, 4], [6, 6]]
    out = _smooth_edges(np.array([corner], dtype=object), extent, 4.0)  # not longer than 4: smoothed
    assert shapely.get_coordinates(out[0]).tolist() == [[2, 2], [4, 2], [6, 4], [6, 6]]
    short = shapely.LineString([(1, 1), (2, 2)])
    assert _smooth_edges(np.array([short], dtype=object), extent, 1.5)[0] is short
    # a vertex on the frame stays even between short steps
    edge = shapely.LineString([(1, 1), (0, 1), (0, 2)])
    out = _smooth_edges(np.array([edge], dtype=object), extent, 1.5)
    assert shapely.get_coordinates(out[0]).tolist() == [[1, 1], [0.5, 1], [0, 1], [0, 1.5], [0, 2]]
    # a closed ring: corners between long sides stay, the start vertex too when its sides are long
    ring = shapely.LineString([(2, 2), (6, 2), (6, 6), (2, 6), (2, 2)])
    out = _smooth_edges(np.array([ring], dtype=object), extent, 1.5)
    xy = shapely.get_coordinates(out[0]).tolist()
    assert xy[0] == xy[-1] == [2, 2] and [6, 2] in xy and [6, 6] in xy and [2, 6] in xy and [4, 2] in xy
    small = shapely.LineString([(2, 2), (3, 2), (3, 3), (2, 3), (2, 2)])  # 1 m ring: every corner cut
    xy = shapely.get_coordinates(_smooth_edges(np.array([small], dtype=object), extent, 1.5)[0]).tolist()
    assert xy == [[2.5, 2], [3, 2.5], [2.5, 3], [2, 2.5], [2.5, 2]]


# ---------------------------------------------------------------------------------------------
# second round: cases the first mutation run showed untested


def test_fraction_off_the_origin_and_past_the_edges():
    # GRID again, on (10, 20)-(14, 22): 2 m x 1 m pixels
    m = _map(GRID, (10.0, 20.0, 14.0, 22.0), full_scale=1.0)
    f = m.fraction([12.0, 11.0, 11.5, 11.0], [21.0, 21.5, 21.0, 19.0])
    assert f.tolist() == [0.625, 0.0, 0.4375, 0.5]  # the last is south of the map: the bottom row's value
    x, y = m.pixel_centre([1], [1])
    assert x.tolist() == [13.0] and y.tolist() == [20.5]
    half = _map(np.zeros((4, 2), np.uint8), (0.0, 0.0, 2.0, 2.0))  # pixels 1 m x 0.5 m
    assert half.pixel_centre([0], [3])[1].tolist() == [0.25]
    # a curved row of four: the last interval blends the last two pixels, not an extrapolation of earlier ones
    row = _map(np.array([[0, 0, 100, 400]], np.uint16), (0.0, 0.0, 4.0, 1.0), full_scale=400.0)
    assert row.fraction([3.5, 3.0, 2.9], [0.5, 0.5, 0.5]).tolist() == pytest.approx([1.0, 0.625, 0.55], abs=1e-12)
    col = _map(np.array([[0], [0], [100], [400]], np.uint16), (0.0, 0.0, 1.0, 4.0), full_scale=400.0)
    assert col.fraction([0.5, 0.5], [0.5, 1.0]).tolist() == [1.0, 0.625]


def test_read_map_where_prefixes_and_pillow_state(tmp_path):
    ext = (0.0, 0.0, 600.0, 400.0)
    with pytest.raises(InputDataError) as e:
        read_map(tmp_path, ext, where="c.xml:3")
    assert str(e.value) == f"c.xml:3: map '{tmp_path}' is a folder, not an image file"
    longname = tmp_path / ("n" * 300 + ".png")
    with pytest.raises(InputDataError) as e:
        read_map(longname, ext, where="c.xml:4")
    assert str(e.value) == f"c.xml:4: map '{longname}': cannot read the file (File name too long)"
    # a MapSpec without a line gives no prefix
    with pytest.raises(InputDataError) as e:
        read_map(MapSpec("landuse", tmp_path / "none.png", {}, ""), ext)
    assert str(e.value) == f"map '{tmp_path / 'none.png'}': file not found"
    # Pillow's own decompression-bomb limit is put back after reading
    before = Image.MAX_IMAGE_PIXELS
    path = _save(tmp_path, "ok.png", Image.new("L", (3, 2)))
    read_map(path, (0.0, 0.0, 3.0, 2.0))
    assert Image.MAX_IMAGE_PIXELS == before is not None
    # a one-column image is not empty
    one = read_map(_save(tmp_path, "one.png", Image.new("L", (1, 3))), (0.0, 0.0, 1.0, 3.0))
    assert one.shape == (3, 1)


def test_read_map_size_messages_round_as_written(tmp_path):
    path = tmp_path / "huge.png"
    path.write_bytes(_png_header(13100, 5000))  # 65.5 Mpx: rounds to 66 (half to even)
    with pytest.raises(InputDataError) as e:
        read_map(path, (0.0, 0.0, 13100.0, 5000.0))
    assert "(66 Mpx, about 0.2 GB decoded); the limit is 64 Mpx" in str(e.value)
    path.write_bytes(_png_header(15000, 10000))  # 150 Mpx, 0.45 GB: rounds up to 0.5
    with pytest.raises(InputDataError) as e:
        read_map(path, (0.0, 0.0, 15000.0, 10000.0))
    assert "(150 Mpx, about 0.5 GB decoded)" in str(e.value)


def test_read_map_aspect_message_off_the_origin_and_at_the_tolerance(tmp_path):
    path = _save(tmp_path, "w.png", Image.new("L", (100, 50)))
    with pytest.raises(InputDataError) as e:
        read_map(path, (10.0, 20.0, 110.0, 120.0))
    assert "but the city is 100x100 m (width/height 1.000)" in str(e.value)
    read_map(path, (10.0, 20.0, 110.0, 120.0), aspect_tolerance=1.0)  # exactly 100 % off: allowed


def test_read_map_logs_what_it_read(tmp_path, caplog):
    path = _save(tmp_path, "g.png", Image.new("L", (3, 2)))
    with caplog.at_level("DEBUG", logger="sengine.geom.raster"):
        read_map(path, (0.0, 0.0, 3.0, 2.0))
    assert [r.getMessage() for r in caplog.records] == [f"read {path}: 3x2 px, mode L, format PNG"]


def test_read_map_sixteen_bit_big_endian_and_integers_as_colour(tmp_path):
    ext = (0.0, 0.0, 3.0, 1.0)
    big = Image.fromarray(np.array([[0, 30000, 65535]], ">u2"))
    path = _save(tmp_path, "b.tif", big)
    m = read_map(path, ext)
    assert m.mode == "I;16B" and m.data.dtype == np.uint16 and m.data.tolist() == [[0, 30000, 65535]]
    assert m.full_scale == 65535.0
    c = read_map(path, ext, colour=True)
    assert c.data.shape == (1, 3, 3) and c.data[:, :, 2].tolist() == [[0, 117, 255]]
    # 32-bit integers as colour: scaled by 255 / 65535, rounded, clipped to 0..255
    ints = np.array([[-300, 0, 65000, 70000]], np.int32)
    i = read_map(_save(tmp_path, "i.tif", Image.fromarray(ints)), (0.0, 0.0, 4.0, 1.0), colour=True)
    assert i.data.shape == (1, 4, 3) and i.data.dtype == np.uint8 and i.full_scale == 255.0
    assert i.data[:, :, 0].tolist() == [[0, 0, 253, 255]]
    f = np.array([[0.0, 0.5, 1.0]], np.float32)
    fc = read_map(_save(tmp_path, "f.tif", Image.fromarray(f)), ext, colour=True)
    assert fc.data[:, :, 1].tolist() == [[0, 128, 255]] and fc.data.shape == (1, 3, 3)
    rgb = read_map(_save(tmp_path, "r.png", Image.new("RGB", (3, 1))), ext)
    assert rgb.full_scale == 255.0 and rgb.data.dtype == np.uint8


def _first_kept(ring_xy, corner):
    """Whether _smooth_edges keeps a closed ring's start vertex (its output then starts there)."""
    out = _smooth_edges(np.array([shapely.LineString(ring_xy)], dtype=object), (0.0, 0.0, 100.0, 100.0), corner)
    return shapely.get_coordinates(out[0])[0].tolist() == list(map(float, ring_xy[0]))


def test_smooth_edges_corner_rules():
    ext = (0.0, 0.0, 10.0, 10.0)

    def smooth(xy, corner=1.5):
        out = _smooth_edges(np.array([shapely.LineString(xy)], dtype=object), ext, corner)
        return shapely.get_coordinates(out[0]).tolist()

    # a long side then a short one: the vertex between them is a pixel step, replaced
    assert smooth([(2, 2), (6, 2), (6, 3)]) == [[2, 2], [4, 2], [6, 2.5], [6, 3]]
    # a short step before two long sides: only the vertex between the long sides stays
    assert smooth([(2, 2), (3, 2), (7, 2), (7, 6)]) == [[2, 2], [2.5, 2], [5, 2], [7, 2], [7, 4], [7, 6]]
    # a side exactly as long as `corner` is not longer: either side alone makes the vertex a step
    assert smooth([(2, 2), (6, 2), (6, 7)], 4.0) == [[2, 2], [4, 2], [6, 4.5], [6, 7]]
    assert smooth([(2, 2), (7, 2), (7, 6)], 4.0) == [[2, 2], [4.5, 2], [7, 4], [7, 6]]
    # vertices on each side of the frame stay
    assert smooth([(9, 1), (10, 1), (10, 2)]) == [[9, 1], [9.5, 1], [10, 1], [10, 1.5], [10, 2]]
    assert smooth([(1, 1), (1, 0), (2, 0)]) == [[1, 1], [1, 0.5], [1, 0], [1.5, 0], [2, 0]]
    assert smooth([(1, 9), (1, 10), (2, 10)]) == [[1, 9], [1, 9.5], [1, 10], [1.5, 10], [2, 10]]
    # a short edge before others does not end the loop
    out = _smooth_edges(
        np.array([shapely.LineString([(1, 1), (2, 2)]), shapely.LineString([(2, 2), (3, 2), (3, 3)])], dtype=object),
        ext,
        1.5,
    )
    assert len(out) == 2 and shapely.get_coordinates(out[1]).tolist() == [[2, 2], [2.5, 2], [3, 2.5], [3, 3]]


def test_smooth_edges_start_of_a_closed_ring():
    # on the frame: kept whatever its sides
    out = _smooth_edges(
        np.array([shapely.LineString([(0, 5), (1, 5), (1, 6), (0, 5)])], dtype=object), (0, 0, 10, 10), 1.5
    )
    assert shapely.get_coordinates(out[0])[0].tolist() == [0.0, 5.0]
    # short side before, long after: a step
    assert not _first_kept([(2, 2), (3, 2), (3, 6), (2, 2)], 1.5)
    # long after and long two sides on, short before: a step
    assert not _first_kept([(2, 2), (6, 2), (6, 6), (2.5, 2.5), (2, 2)], 1.5)
    # sides 5, 4, 5, 4 with corner 4: the start has a side of exactly 4 before it, then one after it
    assert not _first_kept([(2, 2), (7, 2), (7, 6), (2, 6), (2, 2)], 4.0)
    assert not _first_kept([(7, 2), (7, 6), (2, 6), (2, 2), (7, 2)], 4.0)
    assert _first_kept([(7, 2), (7, 6), (2, 6), (2, 2), (7, 2)], 3.9)


def test_classify_lossy_patch_is_a_full_square_and_worst_is_most_frequent():
    # a plus of stray pixels in a lossy map: no 3 x 3 square of them, so no error
    data = np.zeros((7, 7, 3), np.uint8)
    data[:] = WHITE
    data[2:5, 3] = data[3, 2:5] = (0, 200, 0)
    labels = classify(_map(data, (0.0, 0.0, 7.0, 7.0), format="JPEG"), [WHITE, RED])
    assert labels.shape == (7, 7)
    # the stray colour named is the most frequent, not the first in key order
    two = np.array([[(9, 9, 9), (9, 9, 9), (9, 9, 9), (1, 2, 3)]], np.uint8)
    with pytest.raises(InputDataError, match=r"colour #090909 at pixel \(x=0, y=0\) .*\(4 pixels match"):
        classify(_map(two, (0.0, 0.0, 4.0, 1.0)), [WHITE])


def test_vectorize_defaults_corner_pixel_and_log(caplog):
    # one pixel in the corner of a 3 x 3 map on 2 m pixels: its border (frame - corner - frame) is smoothed
    lab = np.zeros((3, 3), int)
    lab[0, 0] = 1
    m = _map(np.zeros((3, 3), np.uint8), (0.0, 0.0, 6.0, 6.0))
    sharp = vectorize(m, lab, simplify=0.0)
    assert sharp[1].area == 4.0
    with caplog.at_level("DEBUG", logger="sengine.geom.raster"):
        soft = vectorize(m, lab)
    assert soft[1].area < 4.0 and soft[0].area + soft[1].area == pytest.approx(36.0, rel=1e-12)
    assert [r.getMessage() for r in caplog.records] == ["vectorized m.png: 2 faces into 2 regions"]
    explicit = vectorize(m, lab, simplify=1.0, grid_size=0.0)
    assert all(soft[k].equals_exact(explicit[k], 0.0) for k in (0, 1))
    # the smoothing scales with the pixel size: the same map on 0.5 m pixels gives the same shape, scaled
    small = vectorize(_map(np.zeros((3, 3), np.uint8), (0.0, 0.0, 1.5, 1.5)), lab)
    assert small[1].area == pytest.approx(soft[1].area / 16.0, rel=1e-9)
    # a staircase on 0.3 m pixels: the defaults are simplify 1 pixel and no grid
    n = 8
    stair = (np.add.outer(np.arange(n), -np.arange(n)) > 0).astype(int)
    fine = _map(np.zeros((n, n), np.uint8), (0.0, 0.0, 0.3 * n, 0.3 * n))
    d, e = vectorize(fine, stair), vectorize(fine, stair, simplify=1.0, grid_size=0.0)
    assert all(d[k].equals_exact(e[k], 0.0) for k in (0, 1))

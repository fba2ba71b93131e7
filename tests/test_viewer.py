"""The viewer page (``--format html``, ``sengine view``): its data read back, and the page in headless Chromium.

The browser tests load the page from ``file://`` (and once over ``sengine
view --serve``) in Debian's Chromium with software WebGL, and check what a
person would: the canvas shows the city, a layer switched off changes the
picture, a click on a building or a lot shows its id and attributes.
"""

from __future__ import annotations

import base64
import io
import json
import os
import re
import signal
import subprocess
import sys
import urllib.request
from pathlib import Path

import numpy as np
import pytest
import shapely
from _browser import browser, open_page
from conftest import DATA, ROOT, interruptible, run_cli
from PIL import Image

from sengine import Layer
from sengine.viewer import DATA_FILE, ViewLayer, view_text

BACKGROUND = np.array([0xF4, 0xF3, 0xEF])


# -- the view format, read back in Python ---------------------------------------------------------------------
def read_view(path: Path) -> dict:
    """``city.view.js`` decoded as the page decodes it: layers with their arrays and columns."""
    text = path.read_text(encoding="ascii")
    m = re.fullmatch(r"window\.SENGINE_VIEW = (\{.*\});\n", text, flags=re.S)
    assert m, "city.view.js is one assignment"
    doc = json.loads(m.group(1))
    bins = [doc["bin"]] if isinstance(doc["bin"], str) else doc["bin"]
    assert all(len(b) <= 16 * 1024 * 1024 for b in bins), "base64 strings of at most 16 MB (parsed 25x faster)"
    blob = b"".join(base64.b64decode(b) for b in bins)
    for lay in doc["layers"]:
        v, t, n = lay["vertices"], lay["triangles"], lay["features"]
        lay["position_"] = np.frombuffer(blob, "<f4", 3 * v, lay["position"]).reshape(-1, 3)
        lay["index_"] = np.frombuffer(blob, "<u4", 3 * t, lay["index"]).reshape(-1, 3)
        lay["feature_"] = np.frombuffer(blob, "<f4", v, lay["feature"])
        cols = {}
        for c in lay["columns"]:
            if c["type"] == "float":
                cols[c["name"]] = np.frombuffer(blob, "<f8", n, c["offset"])
            elif c["type"] == "int":
                cols[c["name"]] = np.frombuffer(blob, "<i4", n, c["offset"])
            elif c["type"] == "bool":
                cols[c["name"]] = np.frombuffer(blob, np.uint8, n, c["offset"])
            else:
                dt = {1: np.uint8, 2: "<u2", 4: "<u4"}[c["width"]]
                codes = np.frombuffer(blob, dt, n, c["offset"])
                cols[c["name"]] = np.array(c["values"], dtype=object)[codes]
        lay["columns_"] = cols
    return doc


@pytest.fixture(scope="module")
def manhattan(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("view") / "manhattan"
    r = run_cli(
        "run", ROOT / "configs" / "manhattan.xml", "-o", out, "--format", "html,png,geojson,glb", "--workers", "1"
    )
    assert r.returncode == 0, r.stderr
    return out


@pytest.fixture(scope="module")
def monaco(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("view") / "monaco"
    r = run_cli("osm", DATA / "monaco.osm.pbf", "-o", out, "--format", "html,png,geojson,glb", "--workers", "2")
    assert r.returncode == 0, r.stderr
    return out


@pytest.mark.slow
@pytest.mark.parametrize("city", ["manhattan", "monaco"])
def test_view_data_holds_every_feature(city, request):
    """Every feature of every layer is in the page with its own triangles, its row and its columns as written."""
    out = request.getfixturevalue(city)
    doc = read_view(out / DATA_FILE)
    assert doc["format"] == "sengine-view" and doc["version"] == 1
    assert doc["name"] == city
    written = {p.stem: json.loads(p.read_text())["features"] for p in out.glob("*.geojson")}
    names = [lay["name"] for lay in doc["layers"]]
    assert {"buildings", "lots", "streets"} <= set(names)
    for lay in doc["layers"]:
        n = lay["features"]
        feats = written[lay["name"]]
        assert n == len(feats), lay["name"]
        rows = lay["feature_"]
        assert np.array_equal(rows, np.round(rows)) and rows.min() >= 0 and rows.max() < n
        tri_rows = rows[lay["index_"]]
        assert (tri_rows == tri_rows[:, :1]).all(), "a triangle belongs to one feature"
        assert lay["index_"].max() < lay["vertices"]
        assert np.isfinite(lay["position_"]).all()
        if lay["kind"] != "line":  # a line feature shorter than a ribbon's segment may have none
            assert len(np.unique(tri_rows[:, 0])) == n, f"{lay['name']}: a feature without triangles"
        # tiles: contiguous runs of the triangles, upward faces first, each inside its bounds
        tiles = np.array(lay["tiles"], float)
        assert tiles[0, 0] == 0 and (tiles[1:, 0] == tiles[:-1, 0] + tiles[:-1, 2]).all()
        assert tiles[:, 2].sum() == lay["triangles"] and (tiles[:, 1] <= tiles[:, 2]).all()
        pos = lay["position_"].astype(float)
        top_area = np.zeros(n)  # the area each feature shows from above
        a_, b_, c_ = (pos[lay["index_"][:, i]] for i in range(3))
        ny = (b_ - a_)[:, 2] * (c_ - a_)[:, 0] - (b_ - a_)[:, 0] * (c_ - a_)[:, 2]
        norm = np.linalg.norm(np.cross(b_ - a_, c_ - a_), axis=1)
        upward_all = np.abs(ny) >= 0.5 * norm
        tri_feat = rows[lay["index_"][:, 0]].astype(int)
        np.add.at(top_area, tri_feat[upward_all], 0.5 * np.abs(ny[upward_all]))
        size = np.sqrt(top_area)
        for first, up, count, *rest in tiles.tolist():
            b, by_size = rest[:6], rest[6:]
            first, up, count = int(first), int(up), int(count)
            tri = pos[lay["index_"][first : first + count]]
            assert (tri.min(axis=(0, 1)) >= np.array(b[:3]) - 0.01).all()
            assert (tri.max(axis=(0, 1)) <= np.array(b[3:]) + 0.01).all()
            upward = upward_all[first : first + count]
            assert upward[:up].all() and not upward[up:].any()
            # the roofs of the features at least 8, 16, 32, 64 m across come first, largest first
            s = size[tri_feat[first : first + up]]
            assert (np.diff(s) <= 1e-3 * s.max() + 1e-9).all()  # (float32 areas there, float64 here)
            for limit, m in zip((8, 16, 32, 64), by_size):  # (float32 areas: a triangle either side of the limit)
                assert abs(m - (s >= limit).sum()) <= 3
        ids = lay["columns_"]["id"]
        assert [f["id"] for f in feats] == ids.tolist()
    b = next(lay for lay in doc["layers"] if lay["name"] == "buildings")
    assert b["kind"] == "solid"
    heights = np.array([f["properties"]["height"] for f in written["buildings"]], float)
    assert np.allclose(b["columns_"]["height"], heights)
    # a building's top is at its height above the ground (y up), within float32
    top = np.zeros(b["features"])
    np.maximum.at(top, b["feature_"].astype(int), b["position_"][:, 1])
    assert np.allclose(top, heights, atol=1e-3)
    # every building of a lot with a FAR shows that FAR (map buildings too, which have no far of their own)
    lots = {f["id"]: f["properties"].get("far") for f in written["lots"]}
    expect = [lots.get(f["properties"].get("lot")) for f in written["buildings"]]
    expect = np.array([np.nan if v is None else v for v in expect], float)
    assert np.allclose(b["columns_"]["lot_far"], expect, equal_nan=True)
    assert np.isfinite(b["columns_"]["lot_far"]).mean() > 0.4
    # the page's buildings are the glb's solids (roofs at lod 2): the same triangles but the floors, the same top
    glb = glb_buildings(out / "city.glb")
    floors = glb["down"].sum()
    assert floors >= b["features"]
    # (the glb drops the few triangles that collapse once its vertices are welded in float32)
    assert 0 <= b["triangles"] - (len(glb["index"]) - floors) <= 0.005 * len(glb["index"])
    # no floors: nothing faces down but slivers of float32 rounding (those the glb drops), under 0.1 m2
    p, i = b["position_"].astype(np.float64), b["index_"]
    area = 0.5 * np.linalg.norm(np.cross(p[i[:, 1]] - p[i[:, 0]], p[i[:, 2]] - p[i[:, 0]]), axis=1)
    assert not ((_normals_y(p, i) < -0.999) & (area > 0.1)).any(), "a floor in the page"
    assert abs(b["position_"][:, 1].max() - glb["position"][:, 1].max()) < 0.01


def read_glb(path: Path) -> tuple[dict, bytes]:
    """The JSON chunk and the binary chunk of a glb."""
    import struct

    data = path.read_bytes()
    n = struct.unpack_from("<I", data, 12)[0]
    m = struct.unpack_from("<I", data, 20 + n)[0]
    return json.loads(data[20 : 20 + n]), data[28 + n : 28 + n + m]


def _buffer_view(doc: dict, binary: bytes, i: int, dtype) -> np.ndarray:
    bv = doc["bufferViews"][i]
    return np.frombuffer(binary, dtype, count=bv["byteLength"] // np.dtype(dtype).itemsize, offset=bv["byteOffset"])


def glb_buildings(path: Path) -> dict:
    """The glb's buildings mesh (positions, triangles) and its property table (``EXT_structural_metadata``)."""
    doc, binary = read_glb(path)
    mesh = next(m for m in doc["meshes"] if m["name"] == "buildings")
    (prim,) = mesh["primitives"]
    pos = doc["accessors"][prim["attributes"]["POSITION"]]
    ext = prim["extensions"]["EXT_mesh_features"]["featureIds"][0]
    meta = doc["extensions"]["EXT_structural_metadata"]
    table = meta["propertyTables"][ext["propertyTable"]]
    props = meta["schema"]["classes"][table["class"]]["properties"]
    columns = {}
    for pid, spec in props.items():
        if pid not in table["properties"]:  # a text column empty in every row: in the class, not in the table
            columns[spec.get("name", pid)] = [""] * table["count"]
            continue
        values = table["properties"][pid]
        if spec["type"] == "STRING":
            offs = _buffer_view(doc, binary, values["stringOffsets"], "<u4")
            raw = _buffer_view(doc, binary, values["values"], "u1").tobytes()
            col = [raw[a:b].decode() for a, b in zip(offs[:-1], offs[1:])]
        else:
            dtype = {"INT64": "<i8", "FLOAT64": "<f8", "UINT8": "u1"}[spec["componentType"]]
            col = _buffer_view(doc, binary, values["values"], dtype).tolist()
        columns[spec.get("name", pid)] = col
    position = _buffer_view(doc, binary, pos["bufferView"], "<f4").reshape(-1, 3)
    acc = doc["accessors"][prim["indices"]]
    dtype = {5125: "<u4", 5123: "<u2"}[acc["componentType"]]
    index = _buffer_view(doc, binary, acc["bufferView"], dtype)[: acc["count"]].reshape(-1, 3)
    return {"position": position, "index": index, "down": _normals_y(position, index) < -0.999, "columns": columns}


def _normals_y(position: np.ndarray, index: np.ndarray) -> np.ndarray:
    """The y (up) component of each triangle's unit normal."""
    p = np.asarray(position, np.float64)
    n = np.cross(p[index[:, 1]] - p[index[:, 0]], p[index[:, 2]] - p[index[:, 0]])
    return n[:, 1] / np.maximum(np.linalg.norm(n, axis=1), 1e-12)


def test_view_text_same_layers_same_bytes_and_columns():
    """Columns of every type, with nulls, survive; the same layers give the same text."""
    geoms = np.array([shapely.box(0, 0, 10, 10), shapely.box(20, 0, 30, 5)], dtype=object)
    lay = Layer.from_geoms(
        geoms,
        height=np.array([12.5, np.nan]),
        floors=np.array([4, 2]),
        corner=np.array([True, False]),
        use=np.array(["housing", None], dtype=object),
        district=np.array([3, None], dtype=object),
    )
    pos = np.array([[0, 0, 0], [10, 0, 0], [10, 0, -10], [20, 0, 0], [30, 0, 0], [30, 0, -5]], np.float32)
    view = ViewLayer(
        "lots",
        (1, 2, 3),
        "surface",
        pos,
        np.array([[0, 1, 2], [3, 4, 5]]),
        np.array([0, 0, 0, 1, 1, 1]),
        {"id": lay.ids, **lay.attrs},
        2,
    )
    a = view_text([view], name="t", attribution="© x")
    assert a == view_text([view], name="t", attribution="© x")
    path = Path(os.environ.get("TMPDIR", "/tmp")) / f"sengine-view-{os.getpid()}.js"
    path.write_text(a, encoding="ascii")
    try:
        doc = read_view(path)
    finally:
        path.unlink()
    cols = doc["layers"][0]["columns_"]
    assert cols["height"][0] == 12.5 and np.isnan(cols["height"][1])
    assert cols["floors"].tolist() == [4, 2]
    assert cols["corner"].tolist() == [1, 0]
    assert cols["use"].tolist() == ["housing", None]
    assert cols["district"][0] == 3.0 and np.isnan(cols["district"][1])
    assert doc["attribution"] == "© x"
    assert doc["bounds"] == [0.0, 0.0, -10.0, 30.0, 0.0, 0.0]
    with pytest.raises(ValueError, match="column height has 2 values for 3 features"):
        view_text([ViewLayer("x", (0, 0, 0), "surface", pos, view.index, view.feature, {"height": cols["height"]}, 3)])


def test_view_data_in_pieces_reads_back_in_the_page(tmp_path, monkeypatch):
    """The arrays cut into many base64 strings are the same arrays, in Python and in the browser."""
    import sengine.viewer as viewer

    monkeypatch.setattr(viewer, "BIN_CHUNK", 48)
    geoms = np.array([shapely.box(10 * i, 0, 10 * i + 8, 8) for i in range(40)], dtype=object)
    lay = Layer.from_geoms(geoms, height=np.arange(40, dtype=float) + 0.5, use=np.array(["a", "b"] * 20, object))
    from sengine.nodes.export.html import view_layers

    text = viewer.view_text(view_layers({"buildings": lay}, lod=1), name="pieces")
    (tmp_path / DATA_FILE).write_text(text, encoding="ascii")
    doc = read_view(tmp_path / DATA_FILE)
    assert len(re.findall(r'^"', text, flags=re.M)) > 10  # many strings, one a line
    b = doc["layers"][0]
    assert b["columns_"]["height"].tolist() == (np.arange(40) + 0.5).tolist()
    assert b["columns_"]["use"].tolist() == ["a", "b"] * 20
    viewer.write_page(tmp_path)
    with browser() as ctx:
        page = open_page(ctx, (tmp_path / "index.html").as_uri())
        got = page.evaluate(
            """() => { const b = window.sengineViewer.view.layers[0];
                       return [Array.from({length: b.features}, (_, i) => b.columns.height.get(i)),
                               Array.from(b.position.slice(0, 6))]; }"""
        )
        assert got[0] == (np.arange(40) + 0.5).tolist()
        assert np.allclose(got[1], b["position_"].ravel()[:6])
        assert not page.errors, page.errors


def test_view_command_needs_the_data(tmp_path):
    (tmp_path / "empty").mkdir()
    r = run_cli("view", tmp_path / "empty")
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "--format html" in r.stderr and "Traceback" not in r.stderr
    r = run_cli("view", tmp_path / "nowhere")
    assert r.returncode == 2 and "no such output folder" in r.stderr
    r = run_cli("view", tmp_path, "--port", "70000")
    assert r.returncode == 2 and "not a port" in r.stderr


def test_view_serve_on_a_taken_port_is_one_line(tmp_path):
    import socket

    (tmp_path / DATA_FILE).write_text("window.SENGINE_VIEW = {};\n")
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        sock.listen(1)
        port = sock.getsockname()[1]
        r = run_cli("view", tmp_path, "--serve", "--port", port)
    assert r.returncode == 2
    assert (
        r.stderr.startswith(f"sengine: error: --port: cannot serve on 127.0.0.1:{port}") and r.stderr.count("\n") == 1
    )
    assert (tmp_path / "index.html").exists()  # the page is written before it is served


# -- the page in a browser ----------------------------------------------------------------------------------------
def canvas_image(page) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(page.locator("#view canvas").screenshot())).convert("RGB"), np.int16)


def changed(a: np.ndarray, b: np.ndarray) -> float:
    """Share of pixels that differ by more than a rounding step."""
    return float((np.abs(a - b).max(axis=2) > 8).mean())


def tallest(out: Path, layer: str = "buildings") -> int:
    feats = json.loads((out / f"{layer}.geojson").read_text())["features"]
    return max(feats, key=lambda f: (f["properties"].get("height") or 0, -f["id"]))["id"]


@pytest.mark.slow
@pytest.mark.parametrize("city", ["manhattan", "monaco"])
def test_page_shows_the_city_and_answers(city, request):
    out = request.getfixturevalue(city)
    r = run_cli("view", out)  # (re)writes the page around the data
    assert r.returncode == 0, r.stderr
    url = r.stdout.strip()
    assert url.startswith("file://") and url.endswith("/index.html")
    with browser() as ctx:
        page = open_page(ctx, url)
        assert page.title() == f"{city} · sengine"
        # the canvas shows the city: many pixels off the background, in many colours
        img = canvas_image(page)
        off = (np.abs(img - BACKGROUND).max(axis=2) > 12).mean()
        assert off > 0.05, f"only {off:.1%} of the canvas is drawn"
        assert len(np.unique(img.reshape(-1, 3), axis=0)) > 50
        # switching a layer off changes the picture; on again gives it back
        box = page.locator('input[data-layer="buildings"]')
        box.click()
        page.wait_for_timeout(200)
        without = canvas_image(page)
        assert changed(img, without) > 0.01
        box.click()
        page.wait_for_timeout(200)
        assert changed(img, canvas_image(page)) < 0.001
        # plain layer colours, then colour by FAR: the buildings change colour each time
        page.select_option("#colour", "layer")
        page.wait_for_timeout(200)
        plain = canvas_image(page)
        assert changed(img, plain) > 0.01
        page.select_option("#colour", "far")
        page.wait_for_timeout(200)
        assert changed(plain, canvas_image(page)) > 0.01
        assert "lot_far" in page.inner_text("#legend")
        # the planner's columns of today's buildings are colour modes: floors, use, building type
        modes = page.evaluate("[...document.querySelectorAll('#colour option')].map((o) => o.value)")
        assert {"height", "floors", "use", "far"} <= set(modes)
        if city == "manhattan":  # (Monaco's map buildings have no type; its generated ones do)
            assert "typology" in modes
            page.select_option("#colour", "typology")
            page.wait_for_timeout(200)
            legend = page.inner_text("#legend")
            assert "buildings: typology" in legend and "towers" in legend, legend
        page.select_option("#colour", "far")
        # a click on a building shows its id and attributes
        bid = tallest(out)
        at = page.evaluate("([id]) => window.sengineViewer.focus('buildings', id)", [bid])
        canvas = page.locator("#view canvas").bounding_box()
        page.mouse.click(canvas["x"] + at["x"], canvas["y"] + at["y"])
        picked = page.locator("#picked")
        assert picked.get_attribute("data-layer") == "buildings"
        assert int(picked.get_attribute("data-id")) == bid
        feats = json.loads((out / "buildings.geojson").read_text())["features"]
        height = next(f for f in feats if f["id"] == bid)["properties"]["height"]
        info = page.inner_text("#info")
        assert re.search(rf"height\s+{re.escape(format(height, 'g'))}\b", info), info
        # its attributes are the glb's property table row (EXT_structural_metadata), plus the page's lot_far
        shown = page.evaluate(
            """() => {
              const s = window.sengineViewer.selected();
              const layer = window.sengineViewer.view.layers.find((l) => l.name === s.layer);
              return Object.fromEntries(Object.entries(layer.columns).map(([k, c]) => [k, c.get(s.row)]));
            }"""
        )
        names = page.evaluate("[...document.querySelectorAll('#info th')].map((th) => th.textContent)")
        assert names == list(shown)
        table = glb_buildings(out / "city.glb")["columns"]
        row = table["id"].index(bid)
        assert set(shown) - {"lot_far"} == set(table)
        for key, values in table.items():
            want, got = values[row], shown[key]
            if isinstance(want, str):
                assert got == (want or None), key
            elif isinstance(want, float) and not np.isfinite(want):
                assert got is None, key
            elif isinstance(want, int) and want < 0 and got is None:  # a reference to none (-1): null, as in GeoJSON
                assert key in ("district", "lot", "block", "parent_id"), key
            else:
                assert got == pytest.approx(want, rel=1e-9), key
        # with the buildings off, a click there shows the lot beneath
        box.click()
        lot = next(f for f in feats if f["id"] == bid)["properties"].get("lot")
        if lot is not None:
            at = page.evaluate("([id]) => window.sengineViewer.focus('lots', id)", [lot])
            page.mouse.click(canvas["x"] + at["x"], canvas["y"] + at["y"])
            assert page.locator("#picked").get_attribute("data-layer") == "lots"
            assert int(page.locator("#picked").get_attribute("data-id")) == lot
        # the plan is below
        assert page.evaluate("document.querySelector('#plan img').naturalWidth") > 200
        assert not page.errors, page.errors


@pytest.mark.slow
def test_view_serve_on_localhost(monaco):
    """``sengine view OUT --serve`` serves the page on a free port of 127.0.0.1 until interrupted."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "sengine", "view", str(monaco), "--serve"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=interruptible,
    )
    try:
        line = proc.stdout.readline()
        m = re.search(r"http://127\.0\.0\.1:(\d+)/", line)
        assert m, line + proc.stderr.read()
        url = m.group(0)
        with urllib.request.urlopen(url + DATA_FILE, timeout=30) as resp:
            assert resp.status == 200
            assert resp.read(30).startswith(b"window.SENGINE_VIEW = {")
        with browser() as ctx:
            page = open_page(ctx, url)
            img = canvas_image(page)
            assert (np.abs(img - BACKGROUND).max(axis=2) > 12).mean() > 0.05
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=30)
    assert proc.returncode == 130

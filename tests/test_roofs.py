"""Roofs as geometry (export/roofs.py, envelope.py, skeleton.py) and the exports per building.

Every solid is checked with trimesh on its own indices (``process=False``:
no merging that could hide a crack): watertight, consistently wound, positive
volume, and the volume between the eave prism and the full-height prism.
"""

from __future__ import annotations

import json
import os
import shutil
import struct
import subprocess
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest
import shapely
import shapely.affinity
import trimesh
from _city import monaco_lots
from hypothesis import HealthCheck, example, given, note, settings
from hypothesis import strategies as st
from shapely.geometry import Polygon, box

import sengine
from sengine import Context, Layer
from sengine.cli import main
from sengine.nodes.export import roofs
from sengine.nodes.export.cityjson import city_model
from sengine.nodes.export.gltf import glb_bytes
from sengine.registry import get

ROOT = Path(__file__).resolve().parent.parent
SCHEMA = Path(__file__).resolve().parent / "data" / "cityjson-2.0.2.min.schema.json"
VALIDATOR = ROOT / ".ci" / "validate_gltf.js"
SETTINGS = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
KINDS = roofs.ROOF_KINDS


def solids_ok(s: roofs.Solids, n: int) -> list[trimesh.Trimesh]:
    """Each feature's solid is closed and outward; return them."""
    out = []
    for i in range(n):
        vsel = np.flatnonzero(s.vertex_feature == i)
        fsel = np.flatnonzero(s.face_feature() == i)
        remap = np.full(len(s.vertices), -1)
        remap[vsel] = np.arange(len(vsel))
        faces = remap[s.faces[fsel]]
        assert (faces >= 0).all(), "a face uses another building's vertex"
        tm = trimesh.Trimesh(s.vertices[vsel], faces, process=False)
        assert tm.is_watertight, f"feature {i} is not closed"
        assert tm.is_winding_consistent, f"feature {i} is not consistently wound"
        assert tm.volume > 0, f"feature {i} faces inward (volume {tm.volume})"
        # no duplicate vertices within a building (but two straight-skeleton nodes CGAL puts
        # a hair apart may land on one float once moved into a UTM frame)
        v = s.vertices[vsel]
        _, first, count = np.unique(v, axis=0, return_index=True, return_counts=True)
        dup = v[first[count > 1]]
        assert len(dup) <= 2 and (dup[:, 2] > v[:, 2].min() + 1e-9).all(), dup
        out.append(tm)
    return out


# -- footprints a city has: rectangles, convex, thin, L / U shapes, holes ---------------------
@st.composite
def footprints(draw):
    shape = draw(st.sampled_from(["rect", "convex", "thin", "L", "U", "holed", "star"]))
    w = draw(st.floats(4.0, 30.0))
    ln = w * draw(st.floats(1.0, 4.0))
    if shape == "rect":
        g = box(0, 0, ln, w)
    elif shape == "thin":
        g = box(0, 0, ln * 3, draw(st.floats(1.2, 3.0)))
    elif shape == "convex":
        k = draw(st.integers(3, 9))
        ang = np.sort(np.array(draw(st.lists(st.floats(0, 2 * np.pi), min_size=k, max_size=k, unique=True))))
        g = Polygon(np.column_stack([ln * np.cos(ang), w * np.sin(ang)])).convex_hull
    elif shape == "L":
        a = w * draw(st.floats(0.3, 0.8))
        g = Polygon([(0, 0), (ln, 0), (ln, a), (a, a), (a, ln), (0, ln)])
    elif shape == "U":
        a = w * draw(st.floats(0.25, 0.45))
        g = Polygon([(0, 0), (ln, 0), (ln, w), (ln - a, w), (ln - a, a), (a, a), (a, w), (0, w)])
    elif shape == "holed":
        a = draw(st.floats(0.15, 0.35))
        g = box(0, 0, ln, w).difference(box(ln * a, w * a, ln * (1 - a), w * (1 - a)))
    else:  # a concave star
        k = draw(st.integers(5, 8))
        t = np.linspace(0, 2 * np.pi, 2 * k, endpoint=False)
        r = np.where(np.arange(2 * k) % 2 == 0, ln, ln * draw(st.floats(0.4, 0.8)))
        g = Polygon(np.column_stack([r * np.cos(t), r * np.sin(t)]))
    g = shapely.affinity.rotate(g, draw(st.floats(0, 180)), origin=(0, 0))
    g = shapely.affinity.translate(g, draw(st.floats(-1e3, 1e3)) + 680_000.0, draw(st.floats(-1e3, 1e3)) + 5_600_000.0)
    return shapely.normalize(g) if g.is_valid and g.area > 1.0 else box(0, 0, 10, 8)


# found by the derandomized run (CI=true): a square ring 0.6 m thick, whose skeleton collapses everywhere at
# once; CGAL dropped the face of one hole edge (its outline passed a point twice), the solid was open
RING = shapely.from_wkt(
    "POLYGON ((679994.7802655326 5599997.819547733, 679996.2999066327 5600001.5196411, 680000 5600000, "
    "679998.4803588998 5599996.299906633, 679994.7802655326 5599997.819547733), (679995.5632257026 "
    "5599998.146615573, 679998.1532910598 5599997.082866803, 679999.2170398299 5599999.67293216, "
    "679996.6269744728 5600000.7366809305, 679995.5632257026 5599998.146615573))"
)
# a ring whose terrace inset splits in two beside the hole: earcut ran one edge over four ring vertices
SLOT = shapely.from_wkt(
    "POLYGON ((680000 5600000, 680000 5600008, 680024 5600008, 680024 5600000, 680000 5600000), "
    "(680006 5600002, 680018 5600002, 680018 5600006, 680006 5600006, 680006 5600002))"
)

#: Found by hypothesis: a five-point star whose gable roof is lowered to keep MIN_WALL of wall (10 m
#: of roof over 3 m of wall at 13 m), and a 5 m square whose stepped roof stood on a base of
#: -0.66 m, where base + (z - base) missed the terrace's z by an ulp and the solid stayed open.
STAR = shapely.Polygon(
    [
        (679983.8196601125, 5599988.244294954),
        (679990.0, 5600000.0),
        (679983.8196601125, 5600011.755705046),
        (679996.9098300562, 5600009.510565163),
        (680006.1803398875, 5600019.021130326),
        (680008.0901699438, 5600005.877852523),
        (680020.0, 5600000.0),
        (680008.0901699438, 5599994.122147477),
        (680006.1803398875, 5599980.978869674),
        (679996.9098300562, 5599990.489434837),
    ]
)
SMALL = shapely.Polygon(
    [
        (679999.8255025165, 5600004.996954135),
        (680004.8224566516, 5600005.171451619),
        (680004.9969541351, 5600000.174497483),
        (680000.0, 5600000.0),
    ]
)


@SETTINGS
@given(g=footprints(), kind=st.sampled_from(KINDS), height=st.floats(4.0, 80.0), base=st.floats(-5.0, 50.0))
@example(g=RING, kind="gable", height=4.0, base=0.0)
@example(g=RING, kind="hip", height=12.0, base=0.0)
@example(g=SLOT, kind="stepped", height=4.0, base=0.0)
@example(g=SLOT, kind="parapet", height=4.0, base=0.0)
@example(g=STAR, kind="gable", height=13.0, base=0.0)
@example(g=SMALL, kind="stepped", height=11.0, base=-0.6595188500030398)
def test_every_roof_is_a_closed_outward_solid(g, kind, height, base):
    note(g.wkt)
    s = roofs.building_solids(np.array([g], object), [height], roof=[kind], base=base)
    (tm,) = solids_ok(s, 1)
    area = g.area
    assert tm.volume <= area * height * (1 + 1e-9) + 1e-6
    # walls at least to the eave: a roof keeps MIN_WALL of wall under it (half the height below 2 x that)
    assert tm.volume >= area * min(roofs.MIN_WALL, height / 2) * (1 - 1e-9) - 1e-6
    z = s.vertices[:, 2]
    assert z.min() == pytest.approx(base, abs=1e-9)
    assert z.max() == pytest.approx(base + height, abs=1e-6)
    kinds = np.bincount(s.face_kind, minlength=3)
    assert kinds.all(), "ground, walls and roof are all there"
    drawn = sum(s.notes.values())
    if kind in ("gable", "hip", "shed", "stepped", "parapet", "pyramid") and not drawn:
        assert len(np.unique(np.round(z, 6))) > 2, f"a {kind} roof is more than a box"


def test_a_ring_collapsing_at_once_keeps_its_hip_roof(capfd):
    """Simultaneous skeleton events: every face is there, drawn as asked, at the closed-form volume."""
    h, rh = 12.0, 2.0
    s = roofs.building_solids(np.array([RING], object), [h], roof=["hip"], roof_height=[rh])
    # CGAL's own "Failed to triangulate skeleton face" is not printed: the face is rebuilt, nothing to tell
    assert capfd.readouterr().err == ""
    (tm,) = solids_ok(s, 1)
    assert s.notes == {}
    # a ring of even width: the roof's mean rise is half of it (the footprint snapped to the millimetre for CGAL)
    assert tm.volume == pytest.approx(RING.area * (h - rh / 2), rel=1e-3)
    roof_area = trimesh.Trimesh(s.vertices, s.faces[s.face_kind == 2], process=False).area
    assert roof_area == pytest.approx(RING.area * np.hypot(1.0, rh / 0.3), rel=1e-3)  # one pitch over 0.3 m


def test_a_terrace_split_beside_a_hole_is_closed():
    s = roofs.building_solids(np.array([SLOT], object), [9.0], roof=["stepped"])
    (tm,) = solids_ok(s, 1)
    assert s.notes == {}
    # prism to the terrace at 6 m, the two recessed storeys 2 m x 4 m standing 3 m on it
    assert tm.volume == pytest.approx(SLOT.area * 6.0 + 2 * 8.0 * 3.0, rel=1e-9)


def test_a_box_over_a_nearly_straight_corner_is_closed():
    """Manhattan's building 98 (seed 7): a pentagon whose corner turns right by a hair.

    Fanned as convex, its flat first triangle has a negative area by rounding;
    turned alone, it wound against its neighbour and the box was open (133 of
    Manhattan's 8,635 buildings were, at every level of detail).
    """
    g = Polygon(
        [
            (4595.126218751707, 7450.09565217511),
            (4600.609864021195, 7459.988719353445),
            (4654.316026236377, 7430.218901578975),
            (4651.46109141168, 7425.068301818694),
            (4648.99546588126, 7420.620056571177),
        ]
    )
    for solids in (roofs.box_solids([g], [20.0]), roofs.building_solids(np.array([g], object), [20.0], roof=["flat"])):
        (tm,) = solids_ok(solids, 1)
        assert tm.volume == pytest.approx(g.area * 20.0, rel=1e-9)


def test_closed_form_volumes_of_a_rectangle():
    g = np.array([box(0, 0, 20, 10)], object)
    h, rh = 15.0, 4.0
    area = 200.0
    expect = {
        "flat": area * h,
        "shed": area * (h - rh) + area * rh / 2,
        "gable": area * (h - rh) + area * rh / 2,
        "hip": area * (h - rh) + rh * 10 * (3 * 20 - 10) / 6,
        "pyramid": area * (h - rh) + area * rh / 3,
        "stepped": area * (h - rh) + 16 * 6 * rh,  # a storey set back 2 m
        "parapet": area * h - 19.4 * 9.4 * rh,  # a 0.3 m ring around a deck rh lower
    }
    for kind, volume in expect.items():
        s = roofs.building_solids(g, [h], roof=[kind], roof_height=[rh])
        (tm,) = solids_ok(s, 1)
        assert tm.volume == pytest.approx(volume, rel=1e-9), kind


def test_the_ridge_follows_the_long_axis_or_the_direction():
    g = np.array([shapely.affinity.rotate(box(0, 0, 30, 10), 30, origin=(0, 0))], object)
    s = roofs.building_solids(g, [12.0], roof=["gable"], roof_height=[3.0])
    top = s.vertices[np.isclose(s.vertices[:, 2], 12.0)]
    d = top.max(axis=0) - top.min(axis=0)
    assert np.degrees(np.arctan2(d[1], d[0])) == pytest.approx(30.0, abs=1e-6)
    assert np.hypot(d[0], d[1]) == pytest.approx(30.0)  # a gable's ridge runs from wall to wall
    # roof_direction 0 deg (north): across the 10 m side the ridge is 10 m long
    s = roofs.building_solids(np.array([box(0, 0, 30, 10)], object), [12.0], roof=["gable"], roof_direction=[0.0])
    top = s.vertices[np.isclose(s.vertices[:, 2], 12.0)]
    assert np.ptp(top[:, 0]) == pytest.approx(0.0, abs=1e-9) and np.ptp(top[:, 1]) == pytest.approx(10.0)


def test_default_pitch_and_the_wall_kept_under_a_roof():
    g = np.array([box(0, 0, 20, 10)], object)
    s = roofs.building_solids(g, [20.0], roof=["hip"])
    walls = s.vertices[(s.vertices[:, 2] > 0) & (s.vertices[:, 2] < 20.0)]
    eave = walls[:, 2].min()
    assert 20.0 - eave == pytest.approx(np.tan(np.radians(30)) * 5.0)
    s = roofs.building_solids(g, [4.0], roof=["hip"], roof_height=[10.0])  # too high: lowered to half
    assert s.notes == {"roof higher than the building allows, lowered": 1}
    z = np.unique(np.round(s.vertices[:, 2], 9))
    assert z[1] == pytest.approx(2.0)


def test_fallbacks_are_counted():
    thin = box(0, 0, 30, 0.5)  # no parapet ring fits inside, no recessed storey
    s = roofs.building_solids(
        np.array([thin, thin, box(0, 0, 9, 9)], object), [9.0] * 3, roof=["parapet", "stepped", "dome"]
    )
    assert s.notes == {
        "parapet roof on a footprint too thin for it, drawn flat": 1,
        "stepped roof on a footprint too thin for it, drawn flat": 1,
        "unknown roof kind, drawn flat": 1,
    }
    solids_ok(s, 3)


@lru_cache(maxsize=1)
def _monaco():
    lots = monaco_lots()
    n = len(lots)
    kinds = np.array(KINDS, object)[np.arange(n) % len(KINDS)]
    height = 8.0 + (np.arange(n) % 9) * 3.0
    return lots.with_columns(height=height, roof=kinds, floors=np.maximum(1, height // 3).astype(np.int64))


def test_real_footprints_of_monaco_with_every_roof():
    lay = _monaco()
    geoms = lay.geometry
    s = roofs.layer_solids(lay, 2)
    assert set(np.unique(s.vertex_feature)) == set(range(len(lay)))
    concave = ~np.isclose(shapely.area(shapely.convex_hull(geoms)), shapely.area(geoms))
    holed = shapely.get_num_interior_rings(geoms) > 0
    assert concave.sum() > 20 and holed.any()
    pick = np.unique(np.concatenate([np.flatnonzero(concave)[:60], np.flatnonzero(holed), np.arange(0, len(lay), 7)]))
    sub = roofs.layer_solids(lay.take(pick), 2)
    for tm, i in zip(solids_ok(sub, len(pick)), pick):
        assert tm.volume <= geoms[i].area * lay["height"][i] * (1 + 1e-9)
    # each building's roof stays over its footprint (the straight skeleton runs on a millimetre grid)
    for i in pick[:40]:
        xy = sub.vertices[sub.vertex_feature == np.searchsorted(pick, i), :2]
        assert shapely.buffer(geoms[i], 1e-3).contains(shapely.multipoints(xy))


def test_same_layer_same_bytes():
    lay = _monaco()
    a, _ = glb_bytes({"buildings": lay}, lod=2)
    b, _ = glb_bytes({"buildings": lay}, lod=2)
    assert a == b


# -- glb: pickable buildings ---------------------------------------------------------------
def read_glb(data: bytes) -> tuple[dict, bytes]:
    magic, version, total = struct.unpack_from("<III", data)
    assert magic == 0x46546C67 and version == 2 and total == len(data)
    n, kind = struct.unpack_from("<II", data, 12)
    doc = json.loads(data[20 : 20 + n])
    m, _ = struct.unpack_from("<II", data, 20 + n)
    return doc, data[28 + n : 28 + n + m]


def view(doc, binary, i, dtype):
    bv = doc["bufferViews"][i]
    return np.frombuffer(binary, dtype, count=bv["byteLength"] // np.dtype(dtype).itemsize, offset=bv["byteOffset"])


@pytest.mark.parametrize("lod", [1, 2])
def test_glb_feature_ids_and_property_table(lod):
    lay = _monaco()
    lay = lay.with_columns(use=np.where(np.arange(len(lay)) % 2, "residential", "office").astype(object))
    data, counts = glb_bytes({"buildings": lay}, lod=lod)
    doc, binary = read_glb(data)
    assert doc["extensionsUsed"] == ["EXT_mesh_features", "EXT_structural_metadata"]
    (prim,) = doc["meshes"][0]["primitives"]
    fid_acc = doc["accessors"][prim["attributes"]["_FEATURE_ID_0"]]
    pos_acc = doc["accessors"][prim["attributes"]["POSITION"]]
    assert fid_acc["count"] == pos_acc["count"] == counts["buildings"]["vertices"]
    fid = view(doc, binary, fid_acc["bufferView"], "<f4")
    assert set(np.unique(fid).astype(int)) == set(range(len(lay)))
    pos = view(doc, binary, pos_acc["bufferView"], "<f4").reshape(-1, 3)
    # every vertex lies over its own building's footprint (glTF: x east, y up, z south)
    xy = np.column_stack([pos[:, 0], -pos[:, 2]]).astype(np.float64)
    b = shapely.bounds(lay.geometry)[fid.astype(int)]
    assert ((xy >= b[:, :2] - 0.01) & (xy <= b[:, 2:] + 0.01)).all()
    # no duplicate vertex within a building
    assert len(np.unique(np.column_stack([fid, pos]), axis=0)) == len(pos)
    ext = prim["extensions"]["EXT_mesh_features"]["featureIds"][0]
    assert ext["featureCount"] == len(lay) and ext["attribute"] == 0
    meta = doc["extensions"]["EXT_structural_metadata"]
    table = meta["propertyTables"][ext["propertyTable"]]
    assert table["count"] == len(lay)
    props = meta["schema"]["classes"][table["class"]]["properties"]
    assert {"id", "height", "floors", "roof", "use"} <= set(props)
    ids = view(doc, binary, table["properties"]["id"]["values"], "<i8")
    np.testing.assert_array_equal(ids, lay.ids)
    height = view(doc, binary, table["properties"]["height"]["values"], "<f8")
    np.testing.assert_array_equal(height, lay["height"])
    offs = view(doc, binary, table["properties"]["roof"]["stringOffsets"], "<u4")
    raw = view(doc, binary, table["properties"]["roof"]["values"], "u1").tobytes()
    roof = [raw[a:b].decode() for a, b in zip(offs[:-1], offs[1:])]
    assert roof == list(lay["roof"])
    for bv in doc["bufferViews"]:
        assert bv["byteOffset"] % 8 == 0


def test_an_empty_text_column_makes_no_empty_buffer_view(tmp_path):
    """Manhattan's typologies leave ``height_class`` empty everywhere: its strings took 0 bytes, and a
    bufferView of byteLength 0 is invalid glTF (the Khronos validator's one error on the demo)."""
    lay = _monaco()
    lay = lay.with_columns(height_class=np.full(len(lay), "", object), note=np.full(len(lay), None, object))
    data, _ = glb_bytes({"buildings": lay}, lod=2)
    doc, _ = read_glb(data)
    assert min(bv["byteLength"] for bv in doc["bufferViews"]) >= 1
    meta = doc["extensions"]["EXT_structural_metadata"]
    (table,) = meta["propertyTables"]
    assert {"height_class", "note"} <= set(meta["schema"]["classes"][table["class"]]["properties"])
    assert not {"height_class", "note"} & set(table["properties"])  # no value: left out of the table
    assert "roof" in table["properties"]
    if _validator_ready():
        (tmp_path / "b.glb").write_bytes(data)
        assert gltf_validate(tmp_path / "b.glb")["issues"]["numErrors"] == 0


def _validator_ready() -> bool:
    return shutil.which("node") is not None and (ROOT / ".ci" / "node" / "node_modules" / "gltf-validator").is_dir()


def gltf_validate(path: Path) -> dict:
    if not _validator_ready():
        if os.environ.get("CI"):
            pytest.fail("the Khronos glTF validator is missing: bash .ci/run installs it into .ci/node")
        pytest.skip("the Khronos glTF validator is not installed (npm install --prefix .ci/node)")
    out = subprocess.run(["node", str(VALIDATOR), str(path)], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


@pytest.fixture(scope="module")
def manhattan() -> dict[str, Layer]:
    """The layers Manhattan's export.city writes, the buildings given a roof of every kind."""
    net = sengine.load(ROOT / "configs" / "manhattan.xml")
    layers, _ = net.run(seed=7)
    out = {dp: layers[src][sp] for src, sp, dst, dp in net.validate().edges if net.specs[dst].type == "export.city"}
    b = out["buildings"]
    out["buildings"] = b.with_columns(roof=np.array(KINDS, object)[np.arange(len(b)) % len(KINDS)])
    return out


@pytest.mark.slow
@pytest.mark.parametrize("lod", [1, 2])
def test_manhattan_glb_passes_the_khronos_validator(manhattan, tmp_path, lod):
    export = get("export.city")(
        "export", {"lod": lod}, Context(seed=7, out=tmp_path, formats=frozenset({"glb", "cityjson"}))
    )
    export.run(**manhattan)
    report = gltf_validate(tmp_path / "city.glb")
    issues = report["issues"]
    assert issues["numErrors"] == 0, issues["messages"][:10]
    assert report["info"]["totalTriangleCount"] > 0
    doc = json.loads((tmp_path / "buildings.city.json").read_text())
    validate_cityjson(doc)
    # the buildings' LoD (trees are LoD1 points at their foot whatever the buildings' LoD)
    lods = {g["lod"] for o in doc["CityObjects"].values() if o["type"] == "Building" for g in o["geometry"]}
    assert lods == {str(lod)}


# -- CityJSON --------------------------------------------------------------------------------
@lru_cache(maxsize=1)
def _schema_validator():
    import jsonschema

    return jsonschema.Draft7Validator(json.loads(SCHEMA.read_text()))


def validate_cityjson(doc: dict, sample: int = 25) -> None:
    """Validate ``doc`` against the official schema: its header and ``sample`` city objects spread over it.

    jsonschema checks every surface against every geometry type (seconds per
    hundred buildings), so a sample stands for the rest; their vertices are
    renumbered into a document of their own.
    """
    names = sorted(doc["CityObjects"])
    pick = names[:: max(1, len(names) // sample)]
    objects = json.loads(json.dumps({k: doc["CityObjects"][k] for k in pick}))
    used: dict[int, int] = {}

    def remap(x):
        if isinstance(x, list):
            return [remap(y) for y in x]
        return used.setdefault(x, len(used))

    for obj in objects.values():
        for geom in obj["geometry"]:
            geom["boundaries"] = remap(geom["boundaries"])
    sub = dict(doc, CityObjects=objects)
    sub["vertices"] = [doc["vertices"][i] for i in sorted(used, key=used.get)]
    _schema_validator().validate(sub)


@pytest.mark.parametrize("lod", [1, 2])
def test_cityjson_passes_the_official_schema_with_semantic_surfaces(lod):
    lay = _monaco()
    doc = city_model(lay, crs=lay.meta.get("crs"), lod=lod)
    validate_cityjson(doc)
    assert len(doc["CityObjects"]) == len(lay)
    verts = np.asarray(doc["vertices"], np.float64) * doc["transform"]["scale"] + doc["transform"]["translate"]
    kinds_seen = set()
    for obj in list(doc["CityObjects"].values())[::15]:
        (geom,) = obj["geometry"]
        assert geom["lod"] == str(lod)
        solids = [geom["boundaries"]] if geom["type"] == "Solid" else geom["boundaries"]
        values = [geom["semantics"]["values"]] if geom["type"] == "Solid" else geom["semantics"]["values"]
        for solid, labels in zip(solids, values):
            (shell,) = solid
            (lab,) = labels
            assert len(lab) == len(shell)
            kinds_seen |= set(lab)
            if lod == 2:  # the shell alone is closed and outward
                tm = trimesh.Trimesh(verts, [s[0] for s in shell], process=True)
                assert tm.is_watertight and tm.volume > 0
    assert kinds_seen == {0, 1, 2}
    assert [s["type"] for s in geom["semantics"]["surfaces"]] == ["GroundSurface", "WallSurface", "RoofSurface"]


def test_cli_lod_sets_every_exporter(tmp_path):
    out = tmp_path / "o"
    args = ["run", str(ROOT / "configs" / "manhattan.xml"), "-o", str(out), "-q", "--format", "cityjson"]
    assert main([*args, "--lod", "1", "--workers", "1"]) == 0
    doc = json.loads((out / "buildings.city.json").read_text())
    assert {g["lod"] for o in doc["CityObjects"].values() for g in o["geometry"]} == {"1"}
    assert main([*args, "--lod", "3"]) == 2

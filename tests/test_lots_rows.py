"""Back-to-back rows (lots.recursive, lots.manhattan), lots.partition (004 §3.3.1), slivers and bad parameters.

Issue 11, parts 2, 3 and 6: lots meet back to back in deep blocks; recursive
splits stop at an aspect ratio, so street-facing lots are (almost) never
thinner than 1:10 on real extracts; partition splits by size (remainders
flagged), count or ratio, with an (x, y) index and clusters of up to 4; no
lot under 1 m2.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import shapely
import shapely.affinity
from _lotcases import osm_blocks
from hypothesis import example, given
from hypothesis import strategies as st
from test_lots import SETTINGS, block_polygon, check_lots

from sengine import Context, Layer
from sengine.errors import ParameterError
from sengine.geom.merge import merge_small
from sengine.nodes.lots.partition import partition_index, partition_lots
from sengine.nodes.lots.recursive import perimeter_aspect
from sengine.registry import get

DATA = Path(__file__).resolve().parent.parent / "configs" / "data"
ROW_METHODS = ["lots.recursive", "lots.manhattan"]
ALL = ROW_METHODS + ["lots.partition"]


def obb_sides(geoms):
    """Long and short side of each geometry's minimum-area oriented box (m)."""
    env = shapely.oriented_envelope(np.asarray(geoms, dtype=object))
    xy = shapely.get_coordinates(shapely.get_exterior_ring(env)).reshape(-1, 5, 2)
    a = np.hypot(*(xy[:, 1] - xy[:, 0]).T)
    b = np.hypot(*(xy[:, 2] - xy[:, 1]).T)
    return np.maximum(a, b), np.minimum(a, b)


def thin_share(lots) -> float:
    """Share of street-facing lots thinner than 1:10 (oriented box short side under a tenth of the long)."""
    street = ~lots["inner"] & (lots["frontage"] > 0)
    long, short = obb_sides(lots.geometry[street])
    return float((short < 0.1 * long).mean())


# -- back-to-back rows -------------------------------------------------------------------------


@pytest.mark.parametrize("name", ROW_METHODS)
@pytest.mark.parametrize("angle", [0.0, 29.0, 117.0])
def test_lots_of_a_deep_block_meet_back_to_back(name, angle):
    """A 240 m x 70 m block (deeper than twice the 30 m target): two rows whose rear edges are shared."""
    block = shapely.affinity.rotate(shapely.box(0, 0, 240, 70), angle, origin=(0, 0))
    blocks = Layer.from_geoms([block])
    lots = get(name)("lots", {}, Context(seed=3)).run(blocks=blocks)["lots"]
    check_lots(blocks, lots, name)
    assert not lots["inner"].any()
    c, s_ = np.cos(np.radians(-angle)), np.sin(np.radians(-angle))
    local = shapely.transform(lots.geometry, lambda xy: xy @ np.array([[c, s_], [-s_, c]]))  # back to the frame
    lo, hi = shapely.bounds(local)[:, 1], shapely.bounds(local)[:, 3]
    # no lot runs through the block: each lies in one half, behind its street, and keeps frontage
    front = np.where(hi <= 35.0 + 1e-6, 0, np.where(lo >= 35.0 - 1e-6, 1, -1))
    assert (front >= 0).all(), "a lot runs the whole depth of the block"
    assert (lots["frontage"] > 0).all()
    # the rear edges of the two rows cover the same 240 m: each lot meets a lot behind it
    rear = [
        shapely.union_all(
            shapely.intersection(shapely.boundary(local[front == f]), shapely.box(-1, 35 - 1e-6, 241, 35 + 1e-6))
        )
        for f in (0, 1)
    ]
    assert rear[0].length == pytest.approx(240.0, abs=1e-3) and rear[1].length == pytest.approx(240.0, abs=1e-3)
    assert shapely.length(shapely.intersection(rear[0], rear[1], grid_size=1e-6)) == pytest.approx(240.0, abs=1e-3)
    # lots about 35 m deep; none thinner than 1:10
    long, short = obb_sides(lots.geometry)
    assert (short >= 0.1 * long).all()


@pytest.mark.parametrize("name", ROW_METHODS)
def test_a_very_deep_block_keeps_street_rows_and_flags_the_inside(name):
    """A 300 m x 300 m block: street lots at most twice the 30 m target deep, the land behind them inner lots."""
    blocks = Layer.from_geoms([shapely.box(0, 0, 300, 300)])
    lots = get(name)("lots", {}, Context(seed=4)).run(blocks=blocks)["lots"]
    check_lots(blocks, lots, name)
    inner = lots["inner"]
    assert inner.any() and (lots["frontage"][inner] < 4.0).all()
    # how far each street lot reaches from the street: its farthest vertex from the block's outline
    ring = shapely.get_exterior_ring(blocks.geometry[0])
    pts, which = shapely.get_coordinates(lots.geometry[~inner], return_index=True)
    reach = np.zeros((~inner).sum())
    np.maximum.at(reach, which, shapely.distance(shapely.points(pts), ring))
    assert (reach <= 2 * 30.0 + 1e-6).all(), np.sort(reach)[-5:]
    assert 0.3 <= shapely.area(lots.geometry[inner]).sum() / 300**2 <= (240 / 300) ** 2 + 1e-9  # at most the 240 m core


@pytest.mark.parametrize("sweep", [60.0, 120.0, 200.0])
def test_a_curved_strip_is_cut_across(sweep):
    """A strip 12 m wide bent along an arc (Monaco's curved blocks): lots across it, none kept whole."""
    r, length = 100.0, 370.0
    arc = shapely.LineString([(r * np.cos(t), r * np.sin(t)) for t in np.linspace(0, np.radians(sweep), 60)])
    strip = shapely.affinity.scale(arc, length / arc.length, length / arc.length).buffer(6.0, cap_style="flat")
    blocks = Layer.from_geoms([strip])
    ran = get("lots.recursive")("lots", {}, Context(seed=3)).run(blocks=blocks)
    lots = ran["lots"]
    check_lots(blocks, lots, "lots.recursive")
    assert ran.report["recursive_stuck"] == 0 and ran.report["over_max_area"] == 0
    assert len(lots) >= strip.area / 800.0 and (~lots["inner"]).all()
    long, short = obb_sides(lots.geometry)
    assert (short >= 0.1 * long).all()


def test_perimeter_aspect_of_rectangles_and_bends():
    assert np.allclose(perimeter_aspect([12.0 * 370.0, 100.0], [2 * (12 + 370.0), 40.0]), [370 / 12, 1.0])
    assert perimeter_aspect([0.0], [10.0])[0] == 1.0  # empty piece: no elongation to trust


@SETTINGS
@given(
    st.lists(block_polygon(), min_size=1, max_size=3),
    st.floats(8.0, 60.0),
    st.floats(2.0, 10.0),
    st.floats(100.0, 2000.0),
    st.sampled_from(["compact", "split"]),
)
def test_recursive_rows_partition_random_blocks(polys, row_depth, max_aspect, max_area, inner):
    """Random blocks (concave, thin, tiny, holed) and parameters: an exact partition, no sliver under min_area."""
    blocks = Layer.from_geoms(polys)
    params = {"row_depth": row_depth, "max_aspect": max_aspect, "max_area": max_area, "min_area": 20.0}
    params["inner_lots"] = inner
    node = get("lots.recursive")("lots", params, Context(seed=9))
    ran = node.run(blocks=blocks)
    lots = ran["lots"]
    check_lots(blocks, lots, "lots.recursive")
    area = shapely.area(lots.geometry)
    whole = np.isclose(area, shapely.area(blocks.geometry)[np.searchsorted(blocks.ids, lots["block"])])
    assert (area[~whole] >= 20.0 - 1e-6).all(), "a cut left a lot under min_area"
    assert ran.report["lots"] == len(lots) and ran.report["recursive_inner"] == int(lots["inner"].sum())


@pytest.fixture(scope="module")
def real_blocks():
    """Blocks of the Monaco and Helsinki extracts through the load-map nodes (as configs/*.xml set them)."""
    out = {}
    for name, minor, sliver, walk in (
        ("monaco", "unclassified,residential,living_street,pedestrian,road", 6, 2),
        ("helsinki_centre", "unclassified,residential,living_street,pedestrian,road", 8, 3),
    ):
        ctx = Context(seed=1)
        roads = get("osm.read")(
            "majorRoads", {"path": str(DATA / f"{name}.osm.pbf"), "extras": "", "minor": minor}, ctx
        ).run()["roads"]
        roads = get("roads.clean")("clean", {"sliver_width": sliver, "tunnels": "drop"}, ctx).run(roads=roads)["roads"]
        blocks = get("blocks.circuits")("blocks", {"node": False, "sidewalk": walk, "min_area": 50}, ctx)
        out[name] = blocks.run(roads=roads)["blocks"]
    return out


@pytest.mark.parametrize("name", ALL)
@pytest.mark.parametrize("city", ["monaco", "helsinki_centre"])
def test_few_thin_lots_on_real_extracts(real_blocks, name, city):
    """At most 2 % of street-facing lots thinner than 1:10 (default parameters); every lot valid, none under 1 m2."""
    blocks = real_blocks[city]
    node = get(name)("lots", {}, Context(seed=2))
    ran = node.run(blocks=blocks)
    lots = ran["lots"]
    assert shapely.is_valid(lots.geometry).all()
    assert thin_share(lots) <= 0.02, f"{name} on {city}: {thin_share(lots):.1%} thinner than 1:10"
    assert (shapely.area(lots.geometry) >= 1.0).all()
    assert ran.report["no_frontage"] == 0 and ran.report.get("kept_whole", 0) == 0
    barea = shapely.area(blocks.geometry)
    larea = np.bincount(np.searchsorted(blocks.ids, lots["block"]), weights=shapely.area(lots.geometry))
    assert np.allclose(larea, barea, rtol=1e-3)


@pytest.mark.slow
@pytest.mark.parametrize("name", ALL)
def test_few_thin_lots_on_whole_liege(name):
    """Whole Liège (80,000 street ways, some 3,450 blocks): at most 2 % of street-facing lots thinner than 1:10."""
    path = next(
        (
            p
            for p in (DATA / "liege_streets.osm.pbf", DATA.parent.parent.parent / "shared/data/liege_streets.osm.pbf")
            if p.exists()
        ),
        None,
    )
    if path is None:
        pytest.skip("liege_streets.osm.pbf is not on this machine (it is not in the repository)")
    ctx = Context(seed=1)
    roads = get("osm.read")("majorRoads", {"path": str(path), "extras": ""}, ctx).run()["roads"]
    roads = get("roads.clean")("clean", {}, ctx).run(roads=roads)["roads"]
    blocks = get("blocks.circuits")("blocks", {"node": False}, ctx).run(roads=roads)["blocks"]
    node = get(name)("lots", {}, Context(seed=1))
    ran = node.run(blocks=blocks)
    lots = ran["lots"]
    assert thin_share(lots) <= 0.02
    assert (shapely.area(lots.geometry) >= 1.0).all()
    assert ran.report["no_frontage"] == 0


# -- lots.partition ------------------------------------------------------------------------------


def partition(params, polys, seed=1):
    blocks = Layer.from_geoms(polys)
    node = get("lots.partition")("lots", params, Context(seed=seed))
    ran = node.run(blocks=blocks)
    return blocks, ran["lots"], ran


@pytest.mark.parametrize("angle", [0.0, 33.0])
def test_partition_by_size_keeps_remainders(angle):
    """A 100 m x 60 m block, lots 30 m x 25 m: 3 x 2 whole lots; the 10 m and 10 m leftovers flagged."""
    block = shapely.affinity.rotate(shapely.box(0, 0, 100, 60), angle)
    blocks, lots, ran = partition({"size": "30 25", "max_aspect": 0}, [block])
    check_lots(blocks, lots, "lots.partition")
    area = shapely.area(lots.geometry)
    assert len(lots) == 4 * 3
    full = ~lots["remainder"]
    assert full.sum() == 6 and np.allclose(area[full], 750.0)
    assert np.allclose(np.sort(area[~full]), [100.0, 250.0, 250.0, 300.0, 300.0, 300.0])
    assert sorted(zip(lots["ix"][full].tolist(), lots["iy"][full].tolist())) == [
        (i, j) for i in range(3) for j in range(2)
    ]
    assert set(lots["ix"].tolist()) == {0, 1, 2, 3} and set(lots["iy"].tolist()) == {0, 1, 2}
    assert ran.report["remainders"] == 6
    # lots no street reaches are inner: the two in the middle of the 4 x 3 grid
    assert lots["inner"].sum() == 2 and (lots["frontage"][lots["inner"]] == 0).all()


def test_partition_folds_thin_leftovers_by_default():
    """A 92 m x 60 m block, lots 30 m x 30 m: the 2 m leftover column (1:15) joins the column before it."""
    blocks, lots, ran = partition({"size": "30 30"}, [shapely.box(0, 0, 92, 60)])
    check_lots(blocks, lots, "lots.partition")
    long, short = obb_sides(lots.geometry)
    assert (short * 6.0 >= long - 1e-9).all()
    assert len(lots) == 6 and np.allclose(np.sort(shapely.area(lots.geometry)), [900] * 4 + [960] * 2)
    assert lots["remainder"].sum() == 2 and set(lots["ix"].tolist()) == {0, 1, 2}
    # max_aspect=0 keeps the strip as its own column of remainders
    blocks, lots, ran = partition({"size": "30 30", "max_aspect": 0}, [shapely.box(0, 0, 92, 60)])
    assert len(lots) == 8 and np.allclose(np.sort(shapely.area(lots.geometry))[:2], [60, 60])


def test_partition_by_count_and_ratio():
    block = shapely.affinity.rotate(shapely.box(0, 0, 120, 50), 12)
    blocks, lots, _ = partition({"mode": "count", "count": "4 2"}, [block])
    check_lots(blocks, lots, "lots.partition")
    assert len(lots) == 8 and np.allclose(shapely.area(lots.geometry), 750.0) and not lots["remainder"].any()
    # ratio 1:2 repeated: one repeat about 40 m long -> 3 repeats over 120 m, widths 13.3 and 26.7 m; rows ~25 m
    blocks, lots, _ = partition({"mode": "ratio", "ratio": "1 2", "size": "40 25"}, [block])
    check_lots(blocks, lots, "lots.partition")
    assert len(lots) == 12
    area = shapely.area(lots.geometry)
    by_col = np.bincount(lots["ix"], weights=area) / 2
    assert np.allclose(by_col, np.tile([120 / 9 * 25, 240 / 9 * 25], 3))


def test_partition_clusters_up_to_four_lots():
    block = shapely.box(0, 0, 120, 60)
    blocks, lots, _ = partition({"mode": "count", "count": "4 2", "cluster": "2 2"}, [block])
    check_lots(blocks, lots, "lots.partition")
    assert len(lots) == 2 and np.allclose(shapely.area(lots.geometry), 3600.0) and (lots["cells"] == 4).all()
    assert sorted(lots["ix"].tolist()) == [0, 1] and (lots["iy"] == 0).all()
    blocks, lots, _ = partition({"mode": "count", "count": "3 1", "cluster": "2 1"}, [block])
    assert sorted(lots["cells"].tolist()) == [1, 2] and np.allclose(np.sort(shapely.area(lots.geometry)), [2400, 4800])
    with pytest.raises(
        ParameterError, match=r"node 'lots' \(lots.partition\): cluster=3 2 makes clusters of more than 4"
    ):
        partition({"cluster": "3 2"}, [block])


# Found by the derandomized run of the whole suite only (Hypothesis draws from the literal constants of
# the local modules imported so far, so the suite explores other examples than the module alone): a
# square block with a courtyard whose edges lie on grid lines.  A cell a hair (1e-15 m) inside the
# courtyard's edge was taken as an inner lot (no frontage) while lot_attributes, within 1e-5 m, measured
# 6 m; a cell touching the courtyard's corner at a point had frontage 0 but was not inner.
COURTYARD_EDGE = shapely.from_wkt(
    "POLYGON ((0 0, -2.093438249717753 39.94518139018295, 37.8517431404652 42.0386196399007, 39.94518139018295 "
    "2.093438249717753, 0 0), (22.501702059307345 29.21768992295872, 10.51814764225246 28.58965844804339, "
    "11.35552294213956 12.611585891970213, 23.339077359194448 13.239617366885538, 22.501702059307345 "
    "29.21768992295872))"
)
COURTYARD_CORNER = shapely.from_wkt(
    "POLYGON ((0 0, -1.7011827630621246 39.96380834213201, 38.26262557906989 41.66499110519413, "
    "39.96380834213201 1.7011827630621246, 0 0), (22.78745707113572 28.995375497329686, 10.798314568496117 "
    "28.485020668411046, 11.478787673720966 12.499497331558242, 23.46793017636057 13.009852160476878, "
    "22.78745707113572 28.995375497329686))"
)


# Found by hypothesis (issue 11 session): a 3 m grid cell lying in the courtyard, its edges on the courtyard's
# ring, came back whole from GEOS's rectangle clip: a 9 m2 lot in the hole, the block's lots 0.6 % too large.
HOLE_CELL = shapely.from_wkt(
    "POLYGON ((100 3, 98.87032801858426 42.98404483308816, 138.85437285167242 44.1137168145039, 139.98404483308815 "
    "4.129671981415742, 100 3), (123.19965651286188 31.66663457201116, 111.20444306293543 31.327732977586436, "
    "111.65631185550173 15.334115044351172, 123.65152530542818 15.673016638775895, 123.19965651286188 "
    "31.66663457201116))"
)


def _holed_square(side, half_hole, angle):
    """A square block ``side`` m with a centred square hole ``2 half_hole`` m, turned ``angle`` degrees."""
    c = side / 2
    hole = shapely.box(c - half_hole, c - half_hole, c + half_hole, c + half_hole)
    poly = shapely.Polygon(shapely.box(0, 0, side, side).exterior.coords, [hole.exterior.coords])
    return shapely.affinity.rotate(poly, angle, origin=(0, 0))


# Found by hypothesis (issue 11, defect a): a 99.6 m square with a centred 36 m hole, ratio mode with 1.2-2.4 m
# wide cells (narrower than lot_width_min): GEOS 3.14 united two thin neighbours whose shared vertex differs by
# 3e-15 m into one of them alone, the lots lost 3 % of the block and the block was kept whole
HOLED_SQUARE = _holed_square(99.6134570490665, 18.04823970610724, 126.32191717283106)

# Found by hypothesis (this session, failing on main too): a 0.25 m2 block cut 3 x 2: its 0.04 m2 cells join
# pieces that touch them at points only, a union snapped to a 1 um grid, which stuck out of the block by
# 3.4e-7 m2 (1.4e-6 of it); the finest grid that makes one polygon (here 1 nm) is used now
TINY_TILTED = shapely.Polygon(
    [
        (2.4996145181203615, 0.0196299078795343),
        (2.479984610240827, 0.5192444259998957),
        (1.9803700921204657, 0.49961451812036145),
        (2.0, 0.0),
    ]
)


@SETTINGS
@given(
    st.lists(block_polygon(), min_size=1, max_size=3),
    st.sampled_from(["size", "count", "ratio"]),
    st.tuples(st.floats(3.0, 60.0), st.floats(3.0, 60.0)),
    st.tuples(st.integers(1, 2), st.integers(1, 2)),
)
@example([COURTYARD_EDGE], "size", (3.0, 3.0), (1, 2))
@example([COURTYARD_CORNER], "size", (3.0, 3.0), (1, 1))
@example([shapely.box(0, 0, 24, 28), shapely.box(0, 0, 50, 57)], "size", (25.0, 40.0), (2, 2))  # the first holds no lot
@example([shapely.box(0, 1, 1, 3)], "count", (3.0, 3.0), (1, 1))  # 6 cells of 0.33 m2: merged to one lot
@example([HOLE_CELL], "size", (3.0, 3.0), (1, 1))  # a cell in the hole, touching its ring: GEOS's clip kept it whole
@example(
    [shapely.box(0, 0, 48, 48).difference(shapely.box(14.4, 14.4, 28.8, 33.6))], "size", (23.0, 23.0), (2, 2)
)  # one cluster
@example([HOLED_SQUARE], "ratio", (4.8234947927489555, 24.203806345555055), (2, 2))  # a union that lost area
@example([TINY_TILTED], "count", (3.0, 3.0), (1, 1))  # cells touching at points, united on a 1 um grid: stuck out
def test_partition_random_blocks(polys, mode, size, cluster):
    """Random blocks and modes: an exact partition, valid lots, none under 1 m2 unless a whole tiny block;
    a size no block can hold is an error."""
    params = {
        "mode": mode,
        "size": f"{size[0]} {size[1]}",
        "count": "3 2",
        "ratio": "1 2 1",
        "cluster": f"{cluster[0]} {cluster[1]}",
    }
    real = [p for p in polys if p.area >= 50.0]
    # blocks that cannot hold one lot of the size in their frame stay whole (a remainder lot)
    too_small = [min(obb_sides([p])[0][0] - size[0], obb_sides([p])[1][0] - size[1]) < 0 for p in real]
    if mode == "size" and real and all(too_small):
        with pytest.raises(ParameterError, match="is larger than every block"):
            partition(params, polys)
        return
    # ... and so may blocks that cannot hold two clusters of cells side by side, either way round
    # (a 48 m square, 23 m cells in clusters of 2 x 2: one 46 m lot and 2 m strips merged into it)
    cx, cy = cluster[0] * size[0], cluster[1] * size[1]

    def one_cluster(p) -> bool:
        w, h = obb_sides([p])[0][0], obb_sides([p])[1][0]
        return not any(
            a >= 2 * u and b >= v or b >= 2 * v and a >= u for a, b in ((w, h), (h, w)) for u, v in [(cx, cy)]
        )

    blocks, lots, ran = partition(params, polys)
    whole = sum(t or one_cluster(p) for t, p in zip(too_small, real)) if mode == "size" else 0
    check_lots(blocks, lots, "lots.partition", known_whole=whole)
    area = shapely.area(lots.geometry)
    barea = shapely.area(blocks.geometry)[lots["block"]]
    assert ((area >= 1.0) | (barea < 1.0 + 1e-9) | (np.bincount(lots["block"])[lots["block"]] == 1)).all()
    assert (lots["ix"] >= 0).all() and (lots["iy"] >= 0).all() and (lots["cells"] >= 1).all()
    assert (lots["cells"] <= cluster[0] * cluster[1]).all()
    assert np.array_equal(lots["inner"], lots["frontage"] <= 0)
    if mode == "size":
        full = cluster[0] * cluster[1] * size[0] * size[1]
        assert np.array_equal(lots["remainder"], np.abs(area - full) > 1e-6 * full)
    else:
        assert not lots["remainder"].any()


def test_partition_function_matches_the_node(real_blocks):
    blocks = real_blocks["monaco"]
    node = get("lots.partition")("lots", {"cluster": "2 1"}, Context(seed=1))
    lots = node.run(blocks=blocks)["lots"]
    made, owner, ix, iy, rem, cells, inner = partition_lots(
        blocks.geometry, **node._options(), lot_width_min=node.p.lot_width_min
    )
    o = np.argsort(owner, kind="stable")
    assert len(made) == len(lots)
    for a, b in (
        (ix, lots["ix"]),
        (iy, lots["iy"]),
        (rem, lots["remainder"]),
        (cells, lots["cells"]),
        (inner, lots["inner"]),
    ):
        assert np.array_equal(a[o], b)
    # the index found again from the geometry alone (the node's fallback) agrees but for lots that took a sliver
    # (or a narrow neighbour: without lot_width_min here)
    lots = get("lots.partition")("lots", {"cluster": "2 1", "lot_width_min": 0}, Context(seed=1)).run(blocks=blocks)
    lots = lots["lots"]
    gx, gy, _, _ = partition_index(lots.geometry, blocks.rows_of(lots["block"]), blocks.geometry, **node._options())
    assert ((gx == lots["ix"]) & (gy == lots["iy"])).mean() >= 0.99


# -- lots.partition: least frontage (lot_width_min, CityEngine's lotWidthMin) ---------------------


def narrow_street_lots(lots, width) -> np.ndarray:
    street = ~lots["inner"] & (lots["frontage"] > 0)
    return street & (lots["frontage"] < width - 1e-6)


@pytest.mark.parametrize("city", ["monaco", "helsinki"])
def test_partition_lots_keep_the_least_frontage_on_real_extracts(city):
    """Issue 11a: a grid cell the outline cuts at a slant had 0.04 m of street; with the default
    lot_width_min (6 m) every street lot keeps 6 m of frontage; the merges keep the partition."""
    blocks = osm_blocks(city)  # in a local frame: the overlay checks keep their precision
    blocks, lots, ran = partition({}, blocks.geometry)
    check_lots(blocks, lots, "lots.partition")
    assert not narrow_street_lots(lots, 6.0).any()
    assert ran.report["narrow_left"] == 0 and ran.report["merged_narrow"] > 0
    # the defect, without the rule: slivers of frontage (under a metre in Helsinki)
    _, loose, ran0 = partition({"lot_width_min": 0}, blocks.geometry)
    assert narrow_street_lots(loose, 6.0).sum() >= ran.report["merged_narrow"] > 0
    assert len(loose) - len(lots) == ran.report["merged_narrow"]
    assert "merged_narrow" not in ran0.report


def test_partition_a_slanted_block_edge_leaves_no_sliver_of_street():
    """A right triangle (legs 100 m and 57 m) cut into 10 m cells: the cells along the hypotenuse have
    0.2 to 3 m of street; each joins a neighbour along the street, and every street lot keeps 6 m."""
    block = shapely.Polygon([(0, 0), (100, 0), (0, 57)])
    blocks, loose, _ = partition({"size": "10 10", "lot_width_min": 0, "max_aspect": 0}, [block])
    assert narrow_street_lots(loose, 6.0).sum() >= 6 and loose["frontage"][~loose["inner"]].min() < 0.5
    blocks, lots, ran = partition({"size": "10 10", "max_aspect": 0}, [block])
    check_lots(blocks, lots, "lots.partition")
    assert not narrow_street_lots(lots, 6.0).any() and ran.report["narrow_left"] == 0
    assert len(loose) - len(lots) == ran.report["merged_narrow"] == 6
    # along the street: each took a street neighbour, so the inner lots are those of the grid without the rule
    assert lots["inner"].sum() == loose["inner"].sum()


@SETTINGS
@given(
    st.lists(block_polygon(), min_size=1, max_size=3),
    st.tuples(st.floats(8.0, 60.0), st.floats(8.0, 60.0)),
    st.floats(0.0, 15.0),
)
@example(
    [
        shapely.Polygon(
            [(12.125, 0.499), (4.243, 25.614), (1.118, 45.808), (47.965, 48.695), (50.503, 4.248), (44.195, 1.533)]
        )
    ],
    (40.0, 42.0),
    0.0,
)
def test_partition_lot_width_min_on_random_blocks(polys, size, width):
    """Concave, thin, tiny and holed blocks: an exact partition; a street lot narrower than lot_width_min
    is left only where the report counts it (no neighbour in its block, or no union one polygon)."""
    real = [p for p in polys if p.area >= 50.0]
    too_small = [min(obb_sides([p])[0][0] - size[0], obb_sides([p])[1][0] - size[1]) < 0 for p in real]
    params = {"size": f"{size[0]} {size[1]}", "lot_width_min": width}
    if real and all(too_small):
        return  # an error (tested above)
    blocks, lots, ran = partition(params, polys)
    # a block under two cells' area may rightly be one lot: its remainders join the one cell it holds
    one_lot = [small or p.area < 2 * size[0] * size[1] for p, small in zip(real, too_small, strict=True)]
    check_lots(blocks, lots, "lots.partition", known_whole=sum(one_lot))
    narrow = narrow_street_lots(lots, width)
    assert int(narrow.sum()) == ran.report.get("narrow_left", 0)
    # what is left narrow is (nearly always) a block's only street lot
    per_block = np.bincount(lots["block"], weights=(lots["frontage"] > 0), minlength=len(blocks))
    assert (per_block[lots["block"][narrow]] >= 1).all()


# -- same seed, same bytes; slivers -------------------------------------------------------------


@pytest.mark.parametrize("name", ALL)
def test_same_seed_same_bytes_and_batch_independence(real_blocks, name):
    blocks = real_blocks["helsinki_centre"]

    def run(seed, sub=None):
        b = blocks if sub is None else blocks.take(sub)
        return get(name)("lots", {}, Context(seed=seed)).run(blocks=b)["lots"]

    a, b = run(5), run(5)
    assert shapely.to_wkb(a.geometry).tolist() == shapely.to_wkb(b.geometry).tolist()
    for col in a.columns:
        assert np.array_equal(a[col], b[col], equal_nan=a[col].dtype.kind == "f"), col
    if name == "lots.recursive":
        assert shapely.to_wkb(run(6).geometry).tolist() != shapely.to_wkb(a.geometry).tolist()
    half = np.arange(1, len(blocks), 2)
    part = run(5, half)
    mine = np.isin(a["block"], blocks.ids[half])
    assert shapely.to_wkb(part.geometry).tolist() == shapely.to_wkb(a.geometry[mine]).tolist()


def test_merge_small_gives_slivers_to_the_longest_neighbour():
    pieces = [
        shapely.box(0, 0, 10, 10),
        shapely.box(10, 0, 20, 10),
        shapely.box(20, 0, 20.05, 10),
        shapely.box(0, 10, 20, 10.02),
    ]
    out, keep, grown, merged, dropped = merge_small(pieces, [0, 0, 0, 0], 1.0)
    assert merged == 2 and dropped == 0 and keep.tolist() == [0, 1]
    assert np.isclose(shapely.area(out).sum(), 200 + 0.5 + 0.4)
    assert shapely.get_type_id(out).tolist() == [3, 3] and shapely.is_valid(out).all()
    assert grown.tolist() == [True, True]
    # another group is not a neighbour; a whole tiny group stays as it is
    out, keep, _, merged, dropped = merge_small(pieces[:1] + [shapely.box(10, 0, 10.01, 10)], [0, 1], 1.0)
    assert merged == 0 and dropped == 0 and len(out) == 2


# -- bad input ----------------------------------------------------------------------------------


def test_parameters_that_cannot_hold_are_one_line_errors():
    blocks = Layer.from_geoms([shapely.box(0, 0, 100, 60), shapely.box(200, 0, 280, 50)])
    with pytest.raises(ParameterError, match=r"node 'lots' \(lots.recursive\): min_frontage=1000 m is more than"):
        get("lots.recursive")("lots", {"min_frontage": 1000}).run(blocks=blocks)
    with pytest.raises(ParameterError, match=r"\(lots.recursive\): min_area=900 m2 is above max_area=800 m2"):
        get("lots.recursive")("lots", {"min_area": 900}).run(blocks=blocks)
    with pytest.raises(ParameterError, match=r"\(lots.partition\): size=200 10 m is larger than every block"):
        get("lots.partition")("lots", {"size": "200 10"}).run(blocks=blocks)
    for name in ROW_METHODS:
        with pytest.raises(ParameterError, match=r"row_depth=0.0 m is below the minimum 1.0 m"):
            get(name)("lots", {"row_depth": 0})
    with pytest.raises(ParameterError, match=r"ratio='1 x' is not a list of numbers"):
        get("lots.partition")("lots", {"mode": "ratio", "ratio": "1 x"}).run(blocks=blocks)


def test_parameters_that_fail_for_some_blocks_are_counted():
    blocks = Layer.from_geoms([shapely.box(0, 0, 100, 60), shapely.box(200, 0, 203, 3)])
    node = get("lots.recursive")("lots", {"min_frontage": 20})
    ran = node.run(blocks=blocks)
    lots = ran["lots"]
    assert ran.report["blocks_below_min_frontage"] == 1 and (lots["block"] == 1).sum() == 1
    node = get("lots.partition")("lots", {"size": "50 50"})
    ran = node.run(blocks=blocks)
    lots = ran["lots"]
    assert ran.report["blocks_below_size"] == 1 and lots["remainder"][lots["block"] == 1].all()


def test_cli_bad_lot_parameter_is_one_line_exit_2(tmp_path, capsys):
    from sengine.cli import main

    cfg = Path(__file__).resolve().parent.parent / "configs" / "manhattan.xml"
    code = main(["run", str(cfg), "-o", str(tmp_path / "out"), "--set", "lots.row_depth=-3"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "row_depth" in err[0] and "lots" in err[0]
    assert not (tmp_path / "out").exists()

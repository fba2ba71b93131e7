"""Sharded runs (issue 13 part 4): a city cut along its major-road enclosures equals the whole city."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from sengine import Layer
from sengine.cli import main
from sengine.node import Context
from sengine.nodes.blocks.circuits import ID_SPAN
from sengine.nodes.lots.nodes import LOT_SPAN
from sengine.registry import get
from sengine.shard import group_enclosures, merge_reports

ROOT = Path(__file__).resolve().parent.parent
METROPOLIS = ROOT / "configs" / "metropolis.xml"
TABLES = ("blocks", "buildings", "lots", "parks", "roads", "sidewalks", "streets", "vegetation", "water", "bridges")
#: Every park level on (the pattern network leaves block, lot and patio parks off).
OPEN_SPACE = (
    *("--set", "blockParks.mode=every", "--set", "blockParks.every=7"),
    *("--set", "lotParks.mode=every", "--set", "lotParks.every=9", "--set", "patios.mode=all"),
)


def _grid_city(nx_: int, ny: int, step: float, rng: np.random.Generator):
    """A noded street grid, an enclosure per major cell (every ``k`` lines), a few cells left out."""
    xs, ys = np.arange(nx_ + 1) * step, np.arange(ny + 1) * step
    lines = [shapely.LineString([(x, ys[j]), (x, ys[j + 1])]) for x in xs for j in range(ny)]
    lines += [shapely.LineString([(xs[i], y), (xs[i + 1], y)]) for y in ys for i in range(nx_)]
    # a dead end inside some cells: a spur of its face
    for i in range(0, nx_, 2):
        x, y = xs[i] + step / 2, ys[0]
        lines.append(shapely.LineString([(x, y), (x, y + step / 3)]))
    k = 2
    areas = [
        shapely.box(xs[i], ys[j], xs[min(i + k, nx_)], ys[min(j + k, ny)])
        for i in range(0, nx_, k)
        for j in range(0, ny, k)
    ]
    drop = rng.random(len(areas)) < 0.25  # land outside every enclosure: the remainder's
    areas = [a for a, d in zip(areas, drop) if not d]
    roads = Layer.from_geoms(lines, width=np.full(len(lines), 8.0))
    return roads, Layer.from_geoms(areas, district=np.zeros(len(areas), np.int64))


def _blocks(roads, areas, rows=None):
    node = get("blocks.circuits")("blocks", {"node": "false", "sidewalk": "2"}, Context())
    inputs = {"roads": roads, "outline": None, "areas": areas}
    if rows is not None:
        inputs = node.shard_inputs(inputs, rows)
    return node.run(**inputs)


@settings(max_examples=15, deadline=None)
@given(st.integers(2, 7), st.integers(2, 7), st.integers(1, 5), st.integers(0, 2**31))
def test_shards_of_enclosures_give_the_whole_citys_faces_and_blocks(nx_, ny, shards, seed):
    roads, areas = _grid_city(nx_, ny, 60.0, np.random.default_rng(seed))
    whole = _blocks(roads, areas)
    groups = [*group_enclosures(shapely.area(areas.geometry), shards), np.zeros(0, np.int64)]
    parts = [_blocks(roads, areas, g) for g in groups]
    for port in ("faces", "blocks", "streets", "sidewalks"):
        joined = Layer.concat([p[port] for p in parts], renumber=False)
        assert len(joined) == len(whole[port]), port
        assert np.array_equal(joined.ids, whole[port].ids), port
        assert len(np.unique(joined.ids)) == len(joined)
        assert np.array_equal(shapely.to_wkb(joined.geometry), shapely.to_wkb(whole[port].geometry)), port
    # no face lost: the faces partition the grid's box
    total = shapely.area(whole["faces"].geometry).sum()
    assert total == pytest.approx(nx_ * ny * 60.0**2, rel=1e-9)


def test_group_enclosures_is_contiguous_complete_and_balanced():
    w = np.random.default_rng(3).random(1000)
    groups = group_enclosures(w, 8)
    assert np.array_equal(np.concatenate(groups), np.arange(1000))
    sums = np.array([w[g].sum() for g in groups])
    assert len(groups) == 8 and sums.max() < 1.2 * w.sum() / 8
    assert [g.tolist() for g in group_enclosures(w[:3], 10)] == [[0], [1], [2]]
    assert group_enclosures([], 4) == []


def test_merge_reports_adds_and_recomputes_ratios():
    a = {"city": {"site_area_m2": 100.0, "footprint_m2": 50.0, "floor_area_m2": 300.0, "far": 3.0, "coverage": 0.5}}
    b = {"city": {"site_area_m2": 300.0, "footprint_m2": 50.0, "floor_area_m2": 100.0, "far": 0.33, "coverage": 0.17}}
    m = merge_reports([a, b])["city"]
    assert m["floor_area_m2"] == 400.0 and m["far"] == 1.0 and m["coverage"] == 0.25


def _run(argv, capsys):
    status = main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return status, err


@pytest.mark.slow
def test_sharded_metropolis_is_byte_identical_to_the_unsharded_one(tmp_path, capsys):
    base = [METROPOLIS, "--scale", "0.004", "--format", "parquet,gpkg", "-q"]
    assert _run(["run", *base, "-o", tmp_path / "whole", "--workers", "1"], capsys)[0] == 0
    assert _run(["run", *base, "-o", tmp_path / "shards", "--workers", "2", "--shards", "5"], capsys)[0] == 0
    whole, shards = tmp_path / "whole", tmp_path / "shards"
    for name in [f"{t}.parquet" for t in TABLES] + ["city.gpkg"]:
        assert (whole / name).read_bytes() == (shards / name).read_bytes(), name
    a = json.loads((whole / "stats.json").read_text())
    b = json.loads((shards / "stats.json").read_text())
    assert a["counts"] == b["counts"] and b["shards"] == 6
    assert a["counts"]["lots"] > 3000
    # each node's area too, summed shard by shard (float sums in another order: to the 0.1 m2 rounding)
    assert a["areas"].keys() == b["areas"].keys() and "lots" in b["areas"]
    for node_id, area in a["areas"].items():
        assert b["areas"][node_id] == pytest.approx(area, rel=1e-9, abs=0.11), node_id
    city_a, city_b = a["report"]["planning"]["city"], b["report"]["planning"]["city"]
    for key in ("site_area_m2", "floor_area_m2", "far", "coverage"):
        assert city_b[key] == pytest.approx(city_a[key], rel=1e-6, abs=0.11)
    assert not list(shards.glob(".parts*")) and not list(tmp_path.glob(".*.tmp"))


@pytest.mark.slow
def test_lot_and_building_ids_derive_from_their_block(tmp_path, capsys):
    import pyarrow.parquet as pq

    out = tmp_path / "m"
    assert _run(["run", METROPOLIS, "--scale", "0.004", "--format", "parquet", "-q", "-o", out], capsys)[0] == 0
    blocks, lots, bld = (pq.read_table(out / f"{t}.parquet") for t in ("blocks", "lots", "buildings"))
    bid, lid = blocks["id"].to_numpy(), lots["id"].to_numpy()
    assert len(np.unique(bid)) == len(bid) and len(np.unique(lid)) == len(lid)
    assert np.isin(lid // LOT_SPAN, bid).all() and np.array_equal(lid // LOT_SPAN, lots["block"].to_numpy())
    assert np.isin(bld["id"].to_numpy() // 16, lid).all()
    assert np.isin(bid // ID_SPAN, np.unique(blocks["parent_id"].to_numpy())).all()


@pytest.mark.slow
def test_open_space_at_every_level_sharded_and_chunked_gives_the_same_bytes(tmp_path, capsys):
    """District parks made once pass down the parks stream: each comes out of one shard with its trees."""
    import pyarrow.parquet as pq

    base = [METROPOLIS, "--scale", "0.004", "--format", "parquet,gpkg", "-q", *OPEN_SPACE]
    assert _run(["run", *base, "-o", tmp_path / "whole", "--workers", "1"], capsys)[0] == 0
    assert _run(["run", *base, "-o", tmp_path / "shards", "--workers", "2", "--shards", "3"], capsys)[0] == 0
    assert _run(["run", *base, "-o", tmp_path / "chunks", "--workers", "2"], capsys)[0] == 0
    for other in ("shards", "chunks"):  # avenue arc lengths are summed per ring in whole nanometres: exact
        for name in [f"{t}.parquet" for t in TABLES] + ["city.gpkg"]:
            same = (tmp_path / "whole" / name).read_bytes() == (tmp_path / other / name).read_bytes()
            assert same, (other, name)
    parks = pq.read_table(tmp_path / "whole" / "parks.parquet")
    level, pid = parks["level"].to_numpy(zero_copy_only=False), parks["id"].to_numpy()
    assert set(level) == {"district", "block", "lot", "patio"}
    assert len(np.unique(pid)) == len(pid) and (np.diff(pid) > 0).all()
    code = {"district": 0, "block": 1, "lot": 2, "patio": 3}
    assert (pid % 4 == np.array([code[v] for v in level])).all()
    trees = pq.read_table(tmp_path / "whole" / "vegetation.parquet")
    tid = trees["id"].to_numpy()
    assert len(tid) > 10_000 and len(np.unique(tid)) == len(tid)
    inpark = trees["zone"].to_numpy(zero_copy_only=False) != "avenue"
    assert np.array_equal(tid[inpark] // 100_000 // 4, trees["park"].to_numpy()[inpark])


def test_shards_refuse_what_they_cannot_do(tmp_path, capsys):
    osm = ROOT / "configs" / "monaco.xml"
    status, err = _run(["run", osm, "-o", tmp_path / "o", "--shards", "4", "-q"], capsys)
    assert status == 2 and err.count("\n") == 1 and "--shards needs" in err
    status, err = _run(
        ["run", METROPOLIS, "--scale", "0.004", "-o", tmp_path / "p", "--shards", "4", "--format", "png"], capsys
    )
    assert status == 2 and err.count("\n") == 1 and "png" in err
    for setting, word in (("blockParks.mode=largest", "largest"), ("vegetation.spacing=20", "spacing")):
        status, err = _run(
            ["run", METROPOLIS, "--scale", "0.004", "-o", tmp_path / "p", "--shards", "4", "--set", setting], capsys
        )
        assert status == 2 and err.count("\n") == 1 and word in err and "enclosure" in err, err
    assert not (tmp_path / "o").exists() and not (tmp_path / "p").exists()
    assert not list(tmp_path.glob(".*"))


def test_scale_refuses_an_absurd_size_with_its_estimate(tmp_path, capsys):
    status, err = _run(["run", METROPOLIS, "--scale", "1e6", "-o", tmp_path / "o", "-q"], capsys)
    assert status == 2 and err.count("\n") == 1
    assert "27,000 x 27,000 km" in err and "limit" in err
    status, err = _run(["run", ROOT / "configs" / "monaco.xml", "--scale", "2", "-o", tmp_path / "o", "-q"], capsys)
    assert status == 2 and "OSM" in err
    status, err = _run(["run", METROPOLIS, "--scale", "0", "-o", tmp_path / "o", "-q"], capsys)
    assert status == 2 and "positive" in err
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_shards_on_a_dask_local_cluster_give_the_same_bytes(tmp_path, capsys):
    pytest.importorskip("distributed")
    base = [METROPOLIS, "--scale", "0.004", "--format", "parquet", "-q", "--shards", "3", "--workers", "2"]
    assert _run(["run", *base, "-o", tmp_path / "local"], capsys)[0] == 0
    status, err = _run(["run", *base, "-o", tmp_path / "dask", "--scheduler", "dask"], capsys)
    assert status == 0 and not err.strip(), err
    for name in [f"{t}.parquet" for t in TABLES]:
        assert (tmp_path / "local" / name).read_bytes() == (tmp_path / "dask" / name).read_bytes(), name


@pytest.mark.slow
def test_shards_on_a_cluster_elsewhere_give_the_same_bytes(tmp_path, capsys, remote_cluster):
    """Workers that inherited nothing (a cluster at tcp://) get the whole city once each and write the same files."""
    base = [METROPOLIS, "--scale", "0.004", "--format", "parquet", "-q", "--shards", "3", "--workers", "2"]
    assert _run(["run", *base, "-o", tmp_path / "local"], capsys)[0] == 0
    status, err = _run(["run", *base, "-o", tmp_path / "remote", "--scheduler", remote_cluster], capsys)
    assert status == 0 and not err.strip(), err
    for name in [f"{t}.parquet" for t in TABLES]:
        assert (tmp_path / "local" / name).read_bytes() == (tmp_path / "remote" / name).read_bytes(), name


def test_a_bad_scheduler_is_refused_before_any_work(tmp_path, capsys):
    status, err = _run(
        ["run", METROPOLIS, "--scale", "0.004", "-o", tmp_path / "o", "--shards", "3", "--scheduler", "yarn"], capsys
    )
    assert status == 2 and err.count("\n") == 1 and "tcp://HOST:PORT" in err
    assert not (tmp_path / "o").exists()

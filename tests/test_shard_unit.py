"""Fast unit tests of :mod:`sengine.shard` (written for its mutation score, docs/mutation.md).

A tiny metropolis (``scale 0.001``: about 90 blocks, 900 lots) runs whole
and in shards in this process (one worker: the shards run here, where
mutmut sees them), once per module; a recording sink (``su.record``) shows
what the shard protocol hands a sink, and in which order.
"""

from __future__ import annotations

import json
import logging
import re
from pathlib import Path

import numpy as np
import pytest
import shapely

from sengine import __version__, registry, shard
from sengine.cli import _apply_scale
from sengine.errors import ParameterError, SEngineError
from sengine.node import NodeResult, Port, SENode
from sengine.scheduler import InProcess
from sengine.shard import group_enclosures, merge_reports, run_sharded
from sengine.xmlconfig import load_config

ROOT = Path(__file__).resolve().parent.parent
METROPOLIS = ROOT / "configs" / "metropolis.xml"
SCALE = 0.001
SHARDS = 3


class Record(SENode):
    """A sink that records every call of the shard protocol (class-level: the bound instance is not ours)."""

    name = "su.record"
    inputs = {"blocks": Port("blocks", required=False), "water": Port("polygons", required=False)}
    calls: list = []

    def run(self, *, blocks=None, water=None):
        return None

    def write_shard(self, inputs, *, shard, city_ports):
        part = {
            "shard": shard,
            "blocks": len(inputs["blocks"]),
            "ids": inputs["blocks"].ids.tolist(),
            "water": None if inputs["water"] is None else len(inputs["water"]),
            "city_ports": sorted(city_ports),
        }
        Record.calls.append(("write", shard, part))
        return part

    def join_shard(self, part, *, shard):
        Record.calls.append(("join", shard, part["shard"]))

    def finish_shards(self, inputs, parts, *, city_ports):
        Record.calls.append(("finish", {k: v is not None for k, v in inputs.items()}, parts, sorted(city_ports)))
        return {"blocks": sum(p["blocks"] for p in parts), "shards": len(parts)}


class FailsInShard(SENode):
    """Fails in shard 1 only (its blocks are passed on elsewhere)."""

    name = "su.fails"
    inputs = {"blocks": Port("blocks")}
    outputs = {"blocks": Port("blocks")}

    def run(self, *, blocks):
        return NodeResult({"blocks": blocks})

    def write_shard(self, inputs, *, shard, city_ports):  # never reached: not a sink
        raise AssertionError


class Streamed(SENode):
    """Passes on the stream features (the enclosures themselves) its shard got; reports its context."""

    name = "su.stream"
    inputs = {"blocks": Port("blocks"), "parks": Port("areas", required=False)}
    outputs = {"blocks": Port("blocks")}
    shard_streams = ("parks",)

    def run(self, *, blocks, parks=None):
        ctx = self.context
        return NodeResult({"blocks": parks}, {"crs": str(ctx.options.get("crs")), "workers": str(ctx.workers)})


NODES = (Record, FailsInShard, Streamed)


@pytest.fixture(autouse=True, scope="module")
def nodes():
    for cls in NODES:
        registry.register(cls, replace=True)
    yield
    for cls in NODES:
        del registry.REGISTRY[cls.name]


def _net(**sets):
    net = load_config(METROPOLIS)
    _apply_scale(net, SCALE)
    for key, value in sets.items():
        node_id, _, name = key.partition("__")
        net.set_param(node_id, name, value)
    return net


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The tiny metropolis whole and in shards, with the progress calls of the sharded run."""
    root = tmp_path_factory.mktemp("shard_unit")
    whole = _net().run(out=root / "whole", formats=("parquet", "gpkg"))
    calls = []
    sharded = run_sharded(
        _net(),
        out=root / "shards",
        shards=SHARDS,
        formats=("parquet", "gpkg"),
        progress=lambda *a: calls.append(a),
    )
    return root, whole, sharded, calls


def _files(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


# -- group_enclosures ---------------------------------------------------------------------------------------------
def test_group_enclosures_cuts_at_the_balanced_totals():
    # cumulative 1, 2, 3, 4: half is reached at row 1, which closes the first group
    assert [g.tolist() for g in group_enclosures([1, 1, 1, 1], 2)] == [[0, 1], [2, 3]]
    assert [g.tolist() for g in group_enclosures([1, 1, 1, 1, 1, 1], 3)] == [[0, 1], [2, 3], [4, 5]]
    assert [g.tolist() for g in group_enclosures([3, 1, 1, 1], 2)] == [[0], [1, 2, 3]]
    groups = group_enclosures(np.ones(7), 2.9)  # a float count is truncated
    assert [g.tolist() for g in groups] == [[0, 1, 2, 3], [4, 5, 6]]  # the row crossing half goes first
    assert all(g.dtype.kind == "i" for g in groups)


def test_group_enclosures_gives_every_group_one_enclosure_and_leaves_room():
    # a heavy first enclosure: the later cuts would all fall on row 1
    assert [g.tolist() for g in group_enclosures([100, 1, 1, 1], 3)] == [[0], [1], [2, 3]]
    # a heavy last one: the cuts would all fall at the end
    assert [g.tolist() for g in group_enclosures([1, 1, 1, 100], 3)] == [[0, 1], [2], [3]]
    assert [g.tolist() for g in group_enclosures([1, 1, 1, 100], 4)] == [[0], [1], [2], [3]]


def test_group_enclosures_clamps_the_count_and_handles_zero_weights():
    assert [g.tolist() for g in group_enclosures([5, 1], 0)] == [[0, 1]]
    assert [g.tolist() for g in group_enclosures([5, 1], -3)] == [[0, 1]]
    assert [g.tolist() for g in group_enclosures([5, 1, 2], 7)] == [[0], [1], [2]]
    # no weight at all: balanced by count
    assert [g.tolist() for g in group_enclosures([0, 0, 0, 0], 2)] == [[0, 1], [2, 3]]
    assert [g.tolist() for g in group_enclosures([-1, 0, -2, 0, 0, 0], 3)] == [[0, 1], [2, 3], [4, 5]]
    # negative weights count as zero
    assert [g.tolist() for g in group_enclosures([-5, 1, 1, -5], 2)] == [[0, 1], [2, 3]]
    assert group_enclosures(np.zeros(0), 3) == []


# -- merge_reports ----------------------------------------------------------------------------------------------
def test_merge_reports_adds_numbers_takes_the_largest_max_and_keeps_the_first_of_the_rest():
    a = {"n": 2, "x": 1.5, "max_len": 3, "name": "a", "flag": True, "only_a": 7}
    b = {"n": 5, "x": 0.25, "max_len": 9, "name": "b", "flag": False, "only_b": "z"}
    c = {"n": 1, "max_len": 4}
    assert merge_reports([a, b, c]) == {
        "n": 8,
        "x": 1.75,
        "max_len": 9,
        "name": "a",
        "flag": True,
        "only_a": 7,
        "only_b": "z",
    }
    assert merge_reports([{"max_len": 9}, {"max_len": 2}]) == {"max_len": 9}
    assert merge_reports([{"flag": False}, {"flag": True}]) == {"flag": False}
    assert merge_reports([]) == {}
    assert merge_reports([{"n": 3}]) == {"n": 3}


def test_merge_reports_merges_nested_dicts_and_rounds_floats():
    a = {"city": {"n": 1, "inner": {"m": 0.123456}}, "t": 0.00001}
    b = {"city": {"n": 2, "inner": {"m": 1.0}, "new": {"k": 1}}, "t": 0.00002}
    m = merge_reports([a, b])
    assert m == {"city": {"n": 3, "inner": {"m": 1.1235}, "new": {"k": 1}}, "t": 0.0}
    assert merge_reports([{"v": 2.123456}]) == {"v": 2.1235}


def test_merge_reports_ratios_of_the_sums():
    a = {"site_area_m2": 30.0, "footprint_m2": 10.0, "floor_area_m2": 20.0, "far": 9.0, "coverage": 9.0}
    b = {"site_area_m2": 40.0, "footprint_m2": 10.0, "floor_area_m2": 30.0, "far": 9.0, "coverage": 9.0}
    m = merge_reports([a, b])
    assert m["far"] == round(50 / 70, 4) == 0.7143 and m["coverage"] == round(20 / 70, 4) == 0.2857
    exact = merge_reports([{"site_area_m2": 100_000_000, "footprint_m2": 12_344_996, "floor_area_m2": 12_344_996}])
    assert exact["far"] == 0.1234 and exact["coverage"] == 0.1234  # rounded once, not to 5 places first
    only = merge_reports([{"site_area_m2": 0.5, "footprint_m2": 0.25, "floor_area_m2": 1.0}])
    assert only == {"site_area_m2": 0.5, "footprint_m2": 0.25, "floor_area_m2": 1.0, "far": 2.0, "coverage": 0.5}
    zero = merge_reports([{"site_area_m2": 0.0, "footprint_m2": 1.0, "floor_area_m2": 2.0, "far": 5.0}])
    assert zero["far"] == 0.0 and zero["coverage"] == 0.0
    # one of the three missing: the ratios are summed like any number
    part = merge_reports([{"site_area_m2": 1.0, "footprint_m2": 1.0, "far": 1.0}, {"far": 2.0}])
    assert part["far"] == 3.0 and "coverage" not in part


# -- run_sharded ------------------------------------------------------------------------------------------------
def _sharded_run_writes_the_whole_citys_bytes(runs):
    root, whole, sharded, _ = runs
    names = _files(root / "whole")
    assert names == _files(root / "shards")  # no .parts folder, nothing else
    assert "city.gpkg" in names and "lots.parquet" in names
    for name in names:
        if name != "stats.json":
            assert (root / "whole" / name).read_bytes() == (root / "shards" / name).read_bytes(), name
    assert sorted(p.name for p in root.iterdir()) == ["shards", "whole"]  # no temporary folder left
    assert shard._CITY is None


def _sharded_stats_sum_the_shards(runs):
    root, whole, sharded, _ = runs
    a, b = whole.stats, sharded.stats
    assert json.loads((root / "shards" / "stats.json").read_text()) == b
    assert b["sengine"] == __version__ and b["config"] == str(METROPOLIS) and b["seed"] == 13
    assert b["shards"] == SHARDS + 1
    assert b["counts"] == a["counts"] and b["counts"]["lots"] > 500 and "districtMap" not in b["counts"]
    assert a["areas"].keys() == b["areas"].keys() and "lots" in b["areas"] and "blocks" in b["areas"]
    for node_id, area in a["areas"].items():
        assert b["areas"][node_id] == pytest.approx(area, rel=1e-9, abs=0.11), node_id
    assert "blockParks" not in b["areas"]  # no block park: an area of 0 is left out
    assert a["report"].keys() == b["report"].keys()
    city_a, city_b = a["report"]["planning"]["city"], b["report"]["planning"]["city"]
    assert city_a.keys() == city_b.keys()
    for key in ("site_area_m2", "footprint_m2", "floor_area_m2", "far", "coverage"):  # the ratios of the sums
        assert city_b[key] == pytest.approx(city_a[key], rel=1e-6, abs=0.11), key
    for node_id in ("majorRoads", "minorRoads", "water", "districtParks"):  # made once, as in the whole run
        assert b["areas"].get(node_id) == a["areas"].get(node_id) and b["report"].get(node_id) == a["report"].get(
            node_id
        )
    assert b["report"]["majorRoads"] and all(round(v, 1) == v for v in b["areas"].values())
    secs = b["seconds"]
    assert all(round(v, 4) == v and 0 <= v <= secs["total"] for v in secs.values()), secs
    assert secs["majorRoads"] == pytest.approx(runs[3][5][5], abs=1e-4)
    assert set(secs) == set(a["seconds"]) | {"shards", "join"}
    assert all(secs[k] > 0 for k in ("shards", "total", "lots", "export", "majorRoads"))
    assert secs["total"] >= secs["shards"] >= secs["lots"] and secs["join"] >= 0
    assert secs["export"] != secs["shards"]  # the export is timed on its own, not given the shards' time


def _sharded_result_holds_the_whole_citys_layers_only(runs):
    _, whole, sharded, _ = runs
    assert set(sharded.layers) == {
        "districtMap",
        "landuseMap",
        "heightMap",
        "districtRules",
        "landuseRules",
        "majorRoads",
        "minorRoads",
        "districtParks",
        "water",
        "bridges",
    }
    for node_id in ("majorRoads", "minorRoads", "water"):
        for port, lay in sharded.layers[node_id].items():
            assert np.array_equal(lay.ids, whole.layers[node_id][port].ids), (node_id, port)


def _sharded_progress_counts_the_city_nodes_then_the_shards(runs):
    _, whole, sharded, calls = runs
    city = ["districtMap", "landuseMap", "heightMap", "districtRules", "landuseRules", "majorRoads", "minorRoads"]
    city += ["districtParks", "water", "bridges"]
    n = len(city) + 1
    assert [c[:3] for c in calls[:-1]] == [(i, n, k) for i, k in enumerate(city, 1)]
    counts = sharded.stats["counts"]
    assert [c[4] for c in calls[:-1]] == [counts.get(k, 0) for k in city]
    assert all(isinstance(c[3], str) and c[3] for c in calls[:-1])  # each node's type
    assert calls[0][4] == 0 and calls[5][4] == counts["majorRoads"] > 0
    assert all(c[5] >= 0 for c in calls) and calls[5][5] > 0
    last = calls[-1]
    assert last[:5] == (n, n, "shards", f"{SHARDS + 1} shards", counts["blocks"])
    assert last[5] > 0 and last[5] == pytest.approx(sharded.stats["seconds"]["shards"], abs=1e-3)


def test_a_sharded_run_equals_the_whole_city(runs):
    """One test for every check of the module's runs: mutmut credits a module fixture's calls to one test."""
    _sharded_run_writes_the_whole_citys_bytes(runs)
    _sharded_stats_sum_the_shards(runs)
    _sharded_result_holds_the_whole_citys_layers_only(runs)
    _sharded_progress_counts_the_city_nodes_then_the_shards(runs)


def test_a_seed_given_to_the_run_wins(tmp_path):
    res = run_sharded(_net(), out=tmp_path / "s", shards=1, seed="7")
    assert res.stats["seed"] == 7 and res.stats["shards"] == 2
    assert res.stats["counts"]["lots"] > 500 and _net().seed == 13


def test_a_sink_sees_each_shards_part_in_order(tmp_path):
    net = _net()
    net.add("rec", "su.record")
    net.connect("blockParks.blocks", "rec.blocks")
    net.connect("water.water", "rec.water")
    Record.calls.clear()
    res = run_sharded(net, out=tmp_path / "s", shards=2, formats=("parquet",))
    writes = [c for c in Record.calls if c[0] == "write"]
    joins = [c for c in Record.calls if c[0] == "join"]
    finish = [c for c in Record.calls if c[0] == "finish"]
    k = res.stats["shards"]
    assert k == 3 and [w[1] for w in writes] == [0, 1, 2] and [j[1:] for j in joins] == [(i, i) for i in range(k)]
    assert Record.calls.index(joins[-1]) < Record.calls.index(finish[0])
    parts = [w[2] for w in writes]
    assert all(p["water"] == len(res.layers["water"]["water"]) for p in parts)  # the city's water, whole
    assert all(p["city_ports"] == ["water"] for p in parts)
    ids = np.concatenate([p["ids"] for p in parts])
    assert len(ids) == res.stats["counts"]["blocks"] and (np.diff(ids) > 0).all()  # shard order = id order
    assert all(p["blocks"] > 0 for p in parts[:-1])
    (_, given, got, ports) = finish[0]
    assert given == {"blocks": False, "water": True} and got == parts and ports == ["water"]
    assert res.stats["report"]["rec"] == {"blocks": len(ids), "shards": k}
    assert res.stats["seconds"]["rec"] >= 0 and "rec" not in res.stats["counts"]


def test_a_stream_feature_goes_to_the_shard_of_its_enclosure(tmp_path, caplog):
    net = _net()
    net.add("st", "su.stream")
    net.connect("blocks.blocks", "st.blocks")
    net.connect("majorRoads.areas", "st.parks")  # each enclosure's inner point lies in itself
    net.add("rec", "su.record")
    net.connect("st.blocks", "rec.blocks")
    Record.calls.clear()
    with caplog.at_level(logging.INFO, logger="sengine.shard"):
        res = run_sharded(net, out=tmp_path / "s", shards=3, options={"crs": "EPSG:3857"})
    areas = res.layers["majorRoads"]["areas"]
    parts = [c[2] for c in Record.calls if c[0] == "write"]
    groups = group_enclosures(shapely.area(areas.geometry), 3)
    assert len(parts) == len(groups) + 1 == res.stats["shards"]
    for g, part in zip(groups, parts):
        assert part["ids"] == areas.ids[g].tolist()
    assert parts[-1]["ids"] == []  # the remainder: no enclosure
    assert res.stats["counts"]["st"] == len(areas)
    assert res.stats["report"]["st"] == {"crs": "EPSG:3857", "workers": "1"}
    logged = [r.getMessage() for r in caplog.records if r.name == "sengine.shard"]
    assert len(logged) == len(parts)
    for i, text in enumerate(logged, 1):
        m = re.fullmatch(r"shard (\d+)/(\d+): \{.*'st': (\d+).*\} in (\d+\.\d\d) s", text)
        assert m and m[1] == str(i) and m[2] == str(len(parts)), text
        assert 0 < float(m[4]) <= res.stats["seconds"]["shards"] + 0.01
    assert sorted(int(re.search(r"'st': (\d+)", t)[1]) for t in logged) == sorted(len(p["ids"]) for p in parts)


def test_the_shards_run_where_the_city_is_sent_not_inherited(runs, tmp_path, monkeypatch):
    """A scheduler whose workers inherit nothing (a cluster elsewhere) gets the city with each task."""
    import sengine.scheduler

    class Elsewhere(InProcess):
        inherits = False

        def run(self, fn, args, shared=None):
            assert shared is not None
            city, shard._CITY = shard._CITY, None  # as in a process that did not inherit it
            try:
                yield from super().run(fn, args, shared)
            finally:
                shard._CITY = city

    monkeypatch.setattr(sengine.scheduler, "make_scheduler", lambda spec, workers, tasks: Elsewhere(workers))
    res = run_sharded(_net(), out=tmp_path / "s", shards=2, formats=("parquet",))
    whole = runs[0] / "whole"
    assert res.stats["counts"] == runs[1].stats["counts"]
    for name in ("lots.parquet", "parks.parquet", "vegetation.parquet"):
        assert (tmp_path / "s" / name).read_bytes() == (whole / name).read_bytes(), name


def test_a_shard_task_without_a_city_says_so():
    assert shard._CITY is None
    with pytest.raises(SEngineError, match="^a shard task ran where the city was not made and none was sent$"):
        shard._run_shard(0)


def test_a_failing_shard_stops_the_run_and_leaves_nothing(tmp_path, monkeypatch):
    def boom(self, *, blocks):
        if len(blocks) and shard._CITY is not None:
            raise ValueError("shard boom")
        return NodeResult({"blocks": blocks})

    monkeypatch.setattr(FailsInShard, "run", boom)
    net = _net()
    net.add("f", "su.fails")
    net.connect("blockParks.blocks", "f.blocks")
    with pytest.raises(SEngineError, match="^node 'f' \\(su.fails\\): failed: ValueError: shard boom"):
        run_sharded(net, out=tmp_path / "s", shards=2)
    assert shard._CITY is None and list(tmp_path.iterdir()) == []


def _refused(tmp_path, net, match, exc=SEngineError, **kw):
    with pytest.raises(exc, match=match) as info:
        run_sharded(net, out=tmp_path / "o", shards=2, **kw)
    assert list(tmp_path.iterdir()) == [] and shard._CITY is None  # before any work, nothing left
    return info.value


def test_networks_sharding_cannot_run_are_refused_in_one_line(tmp_path):
    net = _net()
    net.disconnect("minorRoads.areas", "blocks.areas")
    _refused(
        tmp_path,
        net,
        "^--shards needs a network whose blocks are traced within areas enclosed by major roads "
        r"\(a node with a shard port, fed: the pattern network's blocks.circuits\)$",
    )
    net = _net()
    net.add("blocks2", "blocks.circuits")
    for c in [c for c in net.connections if c.dst == "blocks"]:
        net.connect(f"{c.src}.{c.src_port}" if c.src_port else c.src, f"blocks2.{c.dst_port}")
    _refused(tmp_path, net, r"^--shards: the network has 2 face tracers \(blocks, blocks2\); one$")
    err = _refused(tmp_path, _net(blockParks__mode="largest"), r"^--shards: .*blockParks.* cannot run one enclosure")
    assert "largest" in str(err) and str(err).endswith("(run without --shards)")


def test_a_sink_that_cannot_write_shards_is_refused(tmp_path):
    class NoWrite(SENode):
        name = "su.nowrite"
        inputs = {"blocks": Port("blocks")}

        def run(self, *, blocks):
            return None

    registry.register(NoWrite, replace=True)
    try:
        net = _net()
        net.add("nw", "su.nowrite")
        net.connect("blockParks.blocks", "nw.blocks")
        _refused(tmp_path, net, r"^--shards: node 'nw' \(su.nowrite\) cannot write shard by shard$")
    finally:
        del registry.REGISTRY["su.nowrite"]


def _unhook(net, node_id):
    for c in [c for c in net.connections if c.dst == node_id]:
        net.disconnect(f"{c.src}.{c.src_port}" if c.src_port else c.src, f"{c.dst}.{c.dst_port}")


def test_formats_the_shards_cannot_write_are_refused(tmp_path):
    err = _refused(
        tmp_path,
        _net(),
        r"^--format: --shards writes glb, gpkg, parquet, not html, png \(run without --shards for those\)$",
        ParameterError,
        formats=("html", "png", "parquet"),
    )
    assert err.where == "--format"
    net = _net()
    _unhook(net, "export")  # no sink after the tracer: nothing can be written
    _refused(
        tmp_path,
        net,
        r"^--format: --shards writes nothing, not parquet \(run without --shards for those\)$",
        ParameterError,
        formats=("parquet",),
    )

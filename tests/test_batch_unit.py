"""Fast unit tests of :mod:`sengine.batch` (written for its mutation score, docs/mutation.md).

The batches run in this process (one worker: :class:`~sengine.scheduler.InProcess`),
where mutmut sees them, on a tiny metropolis (the configuration's maps on
an 854 m square: about 90 blocks), a fraction of a second a variant.
"""

from __future__ import annotations

import csv
import hashlib
import json
import os
import signal
import threading
from pathlib import Path

import pytest

from sengine.batch import (
    FIGURES,
    BatchInterrupted,
    BatchSpec,
    _caption,
    _columns,
    _csv_line,
    _figures,
    _file_hash,
    _finished,
    _install,
    _locked,
    _one_line,
    _remove_temporaries,
    _row,
    _signals_ignored,
    _signals_interrupt,
    _Task,
    _variant_digest,
    _write_tables,
    build_network,
    network_digest,
    run_batch,
    run_variant,
)
from sengine.errors import ConfigError, SEngineError
from sengine.variants import Variant

ROOT = Path(__file__).resolve().parent.parent
MAPS = ROOT / "configs" / "maps"


@pytest.fixture(scope="module")
def config(tmp_path_factory) -> Path:
    """configs/metropolis.xml on an 854 m square, its maps named by absolute path."""
    text = (ROOT / "configs" / "metropolis.xml").read_text()
    text = text.replace('size="27000 27000"', 'size="854 854"').replace('src="maps/', f'src="{MAPS}/')
    path = tmp_path_factory.mktemp("config") / "tiny.xml"
    path.write_text(text)
    return path


def _spec(config, out, **kw) -> BatchSpec:
    return BatchSpec(config=str(config), out=str(out), **kw)


def _rows(out: Path) -> list[dict]:
    with open(out / "batch.csv", newline="") as f:
        return list(csv.DictReader(f))


def _dirs(out: Path) -> list[str]:
    return sorted(p.name for p in out.iterdir() if p.is_dir())


# -- small parts -------------------------------------------------------------------------------------------------
def test_batch_interrupted_says_how_many_finished():
    e = BatchInterrupted(signal.SIGTERM, 2, 5, Path("/x/out"))
    assert (e.signum, e.finished, e.total, e.out) == (signal.SIGTERM, 2, 5, Path("/x/out"))
    assert str(e) == "interrupted: 2 of 5 variants finished in /x/out"
    assert isinstance(e, KeyboardInterrupt) and e.args == (signal.SIGTERM,)
    assert (BatchInterrupted(2).finished, BatchInterrupted(2).total, BatchInterrupted(2).out) == (0, 0, None)


def test_one_line_errors():
    assert _one_line(SEngineError("bad\n  thing  here")) == "bad thing here"
    assert _one_line(ValueError("a\nb")) == "ValueError: a b"
    assert _one_line(ConfigError("x", where="f.csv:2")) == "f.csv:2: x"


def test_figures_come_from_the_first_city_summary_with_far():
    report = {
        "lots": {"made": 3},
        "odd": "text",
        "a": {"city": {"n": 1}},
        "planning": {"city": {"far": 1.5, "coverage": 0.25, "floor_area_m2": 900.0, "residents": 12}},
        "later": {"city": {"far": 9.0}},
    }
    assert _figures(report) == {"far": 1.5, "coverage": 0.25, "gfa_m2": 900.0, "residents": 12}
    assert _figures({"p": {"city": {"far": 2.0}}}) == {"far": 2.0, "coverage": None, "gfa_m2": None, "residents": None}
    assert _figures({}) == {col: None for col, _ in FIGURES} == _figures({"p": {"city": "no"}})


def test_columns_rows_and_csv_lines():
    a = Variant("a", 1, maps=(("landuse", "/m/a.png", "w"),), params=(("lots.depth", "18", "w"),))
    b = Variant("b", None, maps=(("district", "/m/b.png", "w"), ("landuse", "/m/b2.png", "w")))
    cols = _columns([a, b], ["roads", "lots"])
    assert cols == [
        "id",
        "seed",
        "landuse",
        "district",
        "lots.depth",
        "n_roads",
        "n_lots",
        "far",
        "coverage",
        "gfa_m2",
        "residents",
        "seconds",
        "inputs_hash",
    ]
    stats = {
        "seed": 7,
        "counts": {"roads": 10, "lots": 2},
        "report": {"planning": {"city": {"far": 0.5, "floor_area_m2": 10.0}}},
        "seconds": {"total": 1.25},
    }
    row = _row(a, stats, "0123456789abcdef0123", ["roads", "lots", "missing"])
    assert row == {
        "id": "a",
        "seed": 7,
        "landuse": "/m/a.png",
        "lots.depth": "18",
        "n_roads": 10,
        "n_lots": 2,
        "n_missing": None,
        "far": 0.5,
        "coverage": None,
        "gfa_m2": 10.0,
        "residents": None,
        "seconds": 1.25,
        "inputs_hash": "0123456789abcdef",
    }
    assert _row(b, {}, "ab", [])["seed"] is None and _row(b, {}, "ab", [])["seconds"] is None
    assert _row(b, {}, "ab", ["lots"])["n_lots"] is None  # stats without counts
    assert _csv_line(["id", "far", "x", "c"], {"id": "a,b", "far": 0.0, "x": None}) == '"a,b",0.0,,\n'


def test_captions():
    assert _caption({"n_lots": 1234, "far": 1.234, "coverage": 0.456, "residents": 12345}) == (
        "1,234 lots, FAR 1.23, cov 0.46, 12,345 res"
    )
    assert _caption({"n_lots": 0, "far": 0.0}) == "0 lots, FAR 0.00"
    assert _caption({"n_lots": None, "coverage": 0.5}) == "cov 0.50"
    assert _caption({}) == ""


def test_tables_in_order_and_parquet_only_with_rows(tmp_path):
    import pyarrow.parquet as pq

    cols = ["id", "seed", "far"]
    _write_tables(tmp_path, cols, [])
    assert (tmp_path / "batch.csv").read_text() == "id,seed,far\n" and not (tmp_path / "batch.parquet").exists()
    rows = [{"id": "b", "seed": 2, "far": None}, {"id": "a", "seed": 1, "far": 1.5}]
    _write_tables(tmp_path, cols, rows)
    assert (tmp_path / "batch.csv").read_text() == "id,seed,far\nb,2,\na,1,1.5\n"
    table = pq.read_table(tmp_path / "batch.parquet")
    assert table.column_names == cols and table.to_pylist() == rows
    assert sorted(p.name for p in tmp_path.iterdir()) == ["batch.csv", "batch.parquet"]
    _write_tables(tmp_path, cols, [])  # no row now: no table that still lists the old ones
    assert (tmp_path / "batch.csv").read_text() == "id,seed,far\n" and not (tmp_path / "batch.parquet").exists()


def test_file_hashes_follow_the_contents(tmp_path):
    f = tmp_path / "m.png"
    assert _file_hash(f) == "missing"
    f.write_bytes(b"one")
    assert _file_hash(f) == hashlib.sha256(b"one").hexdigest()
    big = tmp_path / "big"
    data = os.urandom((1 << 20) + 5)  # more than one chunk
    big.write_bytes(data)
    assert _file_hash(big) == hashlib.sha256(data).hexdigest()
    f.write_bytes(b"other contents")
    assert _file_hash(f) == hashlib.sha256(b"other contents").hexdigest()
    assert _variant_digest("abc", 7) == hashlib.sha256(b"abc:7").hexdigest()


def test_network_digest_changes_with_every_input(config, tmp_path):
    v = Variant("s13")
    spec = _spec(config, tmp_path)
    net = build_network(spec, v)
    d = network_digest(net, ("parquet",))
    assert len(d) == 64 and d == network_digest(build_network(spec, v), ["parquet"])
    assert d == network_digest(net, ("parquet",), ())
    others = {
        network_digest(net, ("gpkg",)),
        network_digest(net, ("parquet",), (("crs", "EPSG:3857"),)),
        network_digest(net, ("parquet",), (("crs", "EPSG:4326"),)),
        network_digest(build_network(spec, Variant("x", params=(("lots.depth", "18", "w"),))), ("parquet",)),
        network_digest(build_network(_spec(config, tmp_path, fixed_sets=("lots.depth=19",)), v), ("parquet",)),
    }
    copy = tmp_path / "landuse.png"
    copy.write_bytes((MAPS / "metropolis_landuse.png").read_bytes())
    same_map = Variant("m", maps=(("landuse", str(copy), "w"),))
    d_copy = network_digest(build_network(spec, same_map), ("parquet",))
    assert d_copy == network_digest(build_network(spec, same_map), ("parquet",))
    with open(copy, "ab") as fh:  # the same path, other contents
        fh.write(b"\0")
    others.add(network_digest(build_network(spec, same_map), ("parquet",)))
    assert len(others) == 6 and d not in others and d_copy not in others
    net2 = build_network(spec, v)
    net2.connect("water.water", "export.blocks")
    assert network_digest(net2, ("parquet",)) != d
    doc_d = net.plan.name
    net.plan.name = "other"
    assert network_digest(net, ("parquet",)) != d
    net.plan.name = doc_d


def test_build_network_applies_the_variants_maps_and_values(config, tmp_path):
    lu = str(MAPS / "metropolis_districts.png")
    v = Variant("x", maps=(("landuse", lu, "m.csv:2"),), params=(("lots.depth", "21", "m.csv:2"),))
    net = build_network(_spec(config, tmp_path, fixed_sets=("blocks.sidewalk=2.5",)), v)
    assert str(net.plan.maps["landuse"].src) == lu
    assert str(net.specs["lots"].params["depth"]) == "21" and str(net.specs["blocks"].params["sidewalk"]) == "2.5"
    with pytest.raises(SEngineError, match="^m.csv:2"):
        build_network(_spec(config, tmp_path), Variant("x", params=(("nope.depth", "1", "m.csv:2"),)))


def test_install_replaces_an_older_variant(tmp_path):
    part, final = tmp_path / ".v.part.tmp", tmp_path / "v"
    part.mkdir()
    (part / "a").write_text("new")
    _install(part, final)
    assert (final / "a").read_text() == "new" and not part.exists()
    part.mkdir()
    (part / "b").write_text("newer")
    _install(part, final)
    assert sorted(p.name for p in final.iterdir()) == ["b"] and sorted(p.name for p in tmp_path.iterdir()) == ["v"]


def test_temporaries_are_removed_and_counted(tmp_path):
    (tmp_path / ".a.x.part.tmp").mkdir()
    (tmp_path / ".a.x.part.tmp" / "f").write_text("x")
    (tmp_path / ".batch.csv.1234.tmp").write_text("x")
    (tmp_path / "keep").mkdir()
    (tmp_path / "keep.tmp").write_text("no dot first")
    (tmp_path / ".hidden").write_text("no .tmp")
    (tmp_path / ".tmp").write_text("nothing between")
    target = tmp_path / "keep" / "inside"
    target.mkdir()
    (tmp_path / ".link.tmp").symlink_to(target)
    assert _remove_temporaries(tmp_path) == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == [".hidden", ".tmp", "keep", "keep.tmp"]
    assert target.is_dir()  # a link is removed, not followed
    assert _remove_temporaries(tmp_path) == 0


def test_finished_needs_the_same_hash_and_readable_stats(tmp_path):
    v = Variant("v")
    assert _finished(tmp_path, v, "h") is None
    (tmp_path / "v").mkdir()
    (tmp_path / "v" / "variant.json").write_text(json.dumps({"hash": "h"}))
    assert _finished(tmp_path, v, "h") is None  # no stats
    (tmp_path / "v" / "stats.json").write_text('{"seed": 3}')
    assert _finished(tmp_path, v, "h") == {"seed": 3}
    assert _finished(tmp_path, v, "other") is None
    (tmp_path / "v" / "stats.json").write_text("{broken")
    assert _finished(tmp_path, v, "h") is None


def test_a_second_batch_into_the_folder_is_refused(tmp_path):
    with _locked(tmp_path):
        with pytest.raises(SEngineError, match="another sengine batch is writing into this folder"):
            with _locked(tmp_path):
                pass
    with _locked(tmp_path):  # released
        pass
    assert (tmp_path / ".batch.lock").exists()


def test_signals_raise_then_are_ignored_then_restored():
    before = (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM))
    with pytest.raises(BatchInterrupted) as info:
        with _signals_interrupt():
            os.kill(os.getpid(), signal.SIGTERM)
    assert info.value.signum == signal.SIGTERM
    with pytest.raises(BatchInterrupted):
        with _signals_interrupt():
            os.kill(os.getpid(), signal.SIGINT)
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == before
    with _signals_ignored():
        assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN == signal.getsignal(signal.SIGTERM)
        os.kill(os.getpid(), signal.SIGTERM)  # nothing happens
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == before
    seen = []

    def in_thread():  # signal handlers belong to the main thread: left alone elsewhere
        with _signals_interrupt(), _signals_ignored():
            seen.append(signal.getsignal(signal.SIGTERM))

    t = threading.Thread(target=in_thread)
    t.start()
    t.join()
    assert seen == [before[1]]


# -- a variant ---------------------------------------------------------------------------------------------------
def test_a_variant_is_renamed_into_place_with_its_record(config, tmp_path):
    v = Variant("s5", 5, params=(("lots.depth", "18", "w"),))
    stats = run_variant(_Task(_spec(config, tmp_path, formats=("parquet",)), v, "d" * 64, 1))
    assert stats["seed"] == 5 and stats["counts"]["lots"] > 100
    assert _dirs(tmp_path) == ["s5"]
    record = json.loads((tmp_path / "s5" / "variant.json").read_text())
    assert record == {"id": "s5", "hash": "d" * 64, "seed": 5, "inputs": v.inputs()}
    assert json.loads((tmp_path / "s5" / "stats.json").read_text())["counts"] == stats["counts"]
    assert (tmp_path / "s5" / "lots.parquet").exists()
    stats = run_variant(_Task(_spec(config, tmp_path), Variant("s5"), "e" * 64, 1))  # no seed: the config's
    assert stats["seed"] == 13 and json.loads((tmp_path / "s5" / "variant.json").read_text())["seed"] == 13
    assert _dirs(tmp_path) == ["s5"] and sorted(p.name for p in tmp_path.iterdir()) == ["s5"]


def test_a_failing_variant_leaves_nothing(config, tmp_path):
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"not a picture")
    out = tmp_path / "o"
    out.mkdir()
    with pytest.raises(SEngineError, match="cannot read the image"):
        run_variant(_Task(_spec(config, out), Variant("b", maps=(("landuse", str(bad), "w"),)), "h", 1))
    assert list(out.iterdir()) == []


# -- a batch -----------------------------------------------------------------------------------------------------
def test_a_batch_makes_skips_redoes_and_forces(config, tmp_path):
    out = tmp_path / "out"
    spec = _spec(config, out, formats=("png",))
    variants = [Variant("s1", 1), Variant("s2", 2), Variant("d18", 1, params=(("lots.depth", "18", "w"),))]
    done, starts = [], []
    rep = run_batch(spec, variants, on_done=lambda *a: done.append(a), on_start=lambda *a: starts.append(a))
    assert rep.made == ["s1", "s2", "d18"] and rep.skipped == [] and rep.failed == {}
    assert rep.out == out and rep.variants == variants and rep.scheduler == "local" and rep.seconds > 0
    assert starts == [(3, "local")] and [d[:2] for d in done] == [(1, 3), (2, 3), (3, 3)]
    assert [d[2]["id"] for d in done] == ["s1", "s2", "d18"] and done[0][2] == rep.rows[0]
    rows = _rows(out)
    assert [r["id"] for r in rows] == ["s1", "s2", "d18"] and [r["seed"] for r in rows] == ["1", "2", "1"]
    assert list(rows[0])[:3] == ["id", "seed", "lots.depth"] and rows[2]["lots.depth"] == "18"
    assert rows[0]["lots.depth"] == "" and int(rows[0]["n_lots"]) > 100 and float(rows[0]["far"]) > 0
    assert "n_districtMap" in rows[0] and "n_majorRoads" in rows[0] and "n_export" not in rows[0]
    assert rows[0]["n_lots"] != rows[2]["n_lots"] or rows[0]["inputs_hash"] != rows[2]["inputs_hash"]
    assert [r["inputs_hash"] for r in rows] == [r["inputs_hash"] for r in rep.rows]
    assert len({r["inputs_hash"] for r in rows}) == 3
    assert _dirs(out) == ["d18", "s1", "s2"] and (out / "contact.png").exists() and (out / "batch.parquet").exists()
    assert (out / "s1" / "preview.png").exists()
    from sengine.contact import contact_sheet  # the sheet shows each variant's preview with its caption

    tiles = [(out / r["id"] / "preview.png", r["id"], _caption(r)) for r in rep.rows]
    assert contact_sheet(tiles, tmp_path / "sheet.png").read_bytes() == (out / "contact.png").read_bytes()
    names = sorted(p.name for p in out.iterdir() if not p.is_dir())
    assert names == [".batch.lock", "batch.csv", "batch.parquet", "contact.png"]
    mtime = (out / "s1" / "variant.json").stat().st_mtime_ns
    # a rerun skips all; a killed run's temporaries go
    (out / ".s9.abcd.part.tmp").mkdir()
    done.clear()
    starts.clear()
    again = run_batch(spec, variants, on_done=lambda *a: done.append(a), on_start=lambda *a: starts.append(a))
    assert again.skipped == ["s1", "s2", "d18"] and again.made == [] and done == [] and starts == []
    assert _rows(out) == rows and again.rows == rep.rows and not (out / ".s9.abcd.part.tmp").exists()
    # a changed variant is redone, the others skipped; the table keeps the batch's order
    changed = [variants[0], Variant("s2", 2, params=(("lots.depth", "30", "w"),)), variants[2]]
    third = run_batch(spec, changed)
    assert third.made == ["s2"] and third.skipped == ["s1", "d18"]
    assert [r["id"] for r in _rows(out)] == ["s1", "s2", "d18"] and _rows(out)[1]["lots.depth"] == "30"
    assert (out / "s1" / "variant.json").stat().st_mtime_ns == mtime
    forced = run_batch(spec, changed[:1], force=True)
    assert forced.made == ["s1"] and forced.skipped == [] and [r["id"] for r in _rows(out)] == ["s1"]
    assert (out / "s1" / "variant.json").stat().st_mtime_ns != mtime


def test_a_failed_variant_is_named_and_the_others_made(config, tmp_path):
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"not a picture")
    out = tmp_path / "out"
    variants = [Variant("bad", maps=(("landuse", str(bad), "m.csv:2"),)), Variant("good", 3)]
    failed = []
    rep = run_batch(_spec(config, out), variants, on_failed=lambda v, e: failed.append((v.id, e)))
    assert rep.made == ["good"] and list(rep.failed) == ["bad"] and [f[0] for f in failed] == ["bad"]
    assert "cannot read the image" in rep.failed["bad"] and "\n" not in rep.failed["bad"]
    assert isinstance(failed[0][1], SEngineError) and rep.failed["bad"] == _one_line(failed[0][1])
    assert [r["id"] for r in _rows(out)] == ["good"] and _dirs(out) == ["good"]
    assert [r["id"] for r in rep.rows] == ["good"]


def test_a_bad_variant_network_is_refused_before_anything_is_written(config, tmp_path):
    out = tmp_path / "out"
    with pytest.raises(SEngineError, match="lots.depth|depth"):
        run_batch(_spec(config, out), [Variant("a", params=(("lots.depth", "-5", "m.csv:2"),))])
    with pytest.raises(ConfigError, match="is not one of local, dask"):
        run_batch(_spec(config, out), [Variant("a")], scheduler="yarn")
    assert not out.exists()


def test_a_signal_keeps_the_finished_variants(config, tmp_path):
    out = tmp_path / "out"
    variants = [Variant(f"s{i}", i) for i in range(1, 4)]

    def stop_after_first(k, n, row):
        os.kill(os.getpid(), signal.SIGTERM)

    with pytest.raises(BatchInterrupted) as info:
        run_batch(_spec(config, out, formats=("png",)), variants, on_done=stop_after_first)
    e = info.value
    assert (e.signum, e.finished, e.total, e.out) == (signal.SIGTERM, 1, 3, out)
    assert _dirs(out) == ["s1"] and [r["id"] for r in _rows(out)] == ["s1"] and (out / "contact.png").exists()
    assert not [p for p in out.iterdir() if p.name.endswith(".tmp")]
    assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL
    rep = run_batch(_spec(config, out, formats=("png",)), variants)  # the rerun makes the rest
    assert rep.skipped == ["s1"] and rep.made == ["s2", "s3"]

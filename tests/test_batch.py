"""sengine batch: variants from maps, a manifest, seeds and sweeps; resumable, crash-safe, same bytes on any scheduler.

The cities are configs/districts.xml (three districts, three patterns) with
variant maps made here from its own maps by flips and rotations (Pillow),
written as preview only (``--format png``) to keep the runs short.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import CONFIGS, run_cli
from PIL import Image

from sengine.parallel import in_worker, run_jobs
from sengine.scheduler import InProcess, LocalProcesses, make_scheduler

CONFIG = CONFIGS / "districts.xml"
FLIPS = {
    "flipx": Image.Transpose.FLIP_LEFT_RIGHT,
    "flipy": Image.Transpose.FLIP_TOP_BOTTOM,
    "turn": Image.Transpose.ROTATE_180,
}


@pytest.fixture(scope="module")
def maps(tmp_path_factory) -> Path:
    """``lu/<stem>.png`` and ``d/<stem>.png``: the districts config's land-use and district maps, flipped."""
    root = tmp_path_factory.mktemp("maps")
    for kind, folder in (("landuse", "lu"), ("districts", "d")):
        (root / folder).mkdir()
        with Image.open(CONFIGS / "maps" / f"districts_{kind}.png") as im:
            for stem, how in FLIPS.items():
                im.transpose(how).save(root / folder / f"{stem}.png")
    return root


def batch(out: Path, *args, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return run_cli("batch", CONFIG, "-o", out, "--format", "png", *args, cwd=cwd)


def read_rows(out: Path) -> list[dict]:
    with open(out / "batch.csv", newline="") as f:
        return list(csv.DictReader(f))


def finished(out: Path) -> list[str]:
    """Ids of the complete variant folders in ``out`` (a folder appears only by a rename when complete)."""
    return sorted(p.name for p in out.iterdir() if p.is_dir() and not p.name.startswith("."))


def assert_complete(folder: Path) -> None:
    record = json.loads((folder / "variant.json").read_text())
    stats = json.loads((folder / "stats.json").read_text())
    assert record["id"] == folder.name and stats["counts"]["lots"] > 1000
    with Image.open(folder / "preview.png") as im:
        im.load()  # a truncated PNG raises here
        assert im.size[0] == 1600


def files(folder: Path) -> dict[str, bytes]:
    """Every output file of a batch's variants, but the timings (stats.json)."""
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in sorted(folder.glob("*/*"))
        if p.name != "stats.json" and not p.parent.name.startswith(".")
    }


# -- bad input: one line, exit 2, nothing written ------------------------------------------------------------------
BAD = {
    "missing map": ("id,landuse\na,lu/none.png\n", [], "column landuse: map file 'lu/none.png' not found"),
    "duplicate id": ("id,seed\na,1\na,2\n", [], "the variant id 'a' is also the id of"),
    "bad parameter value": ("id,lots.depth\na,-5\n", [], "variants.csv:2: column lots.depth: node 'lots'"),
    "bad sweep value": (None, ["--set", "lots.depth=2,deep"], "--set lots.depth: node 'lots'"),
    "unmatched stem": (None, ["--maps", "landuse=lu/*.png", "district=d/flip*.png"], "the stem 'turn'"),
    "backwards seeds": (None, ["--seeds", "5-1"], "the range 5-1 runs backwards"),
    "a billion seeds": (None, ["--seeds", "1-1000000000"], "1,000,000,000 seeds"),
    "unknown scheduler": (None, ["--scheduler", "yarn"], "is not one of local, dask or tcp://HOST:PORT"),
    "seed and seeds": (None, ["--seed", "1", "--seeds", "2"], "give --seeds or --seed, not both"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_input_is_one_line_and_writes_nothing(case, maps, tmp_path):
    manifest, args, message = BAD[case]
    if manifest is not None:
        (maps / "variants.csv").write_text(manifest)
        args = ["--manifest", "variants.csv"]
    out = tmp_path / "out"
    res = batch(out, *args, cwd=maps)
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("sengine: error: "), res.stderr
    assert message in lines[0]
    assert not out.exists()


def test_a_variant_that_fails_is_named_and_the_others_are_made(maps, tmp_path):
    (maps / "broken.png").write_bytes(b"not a picture")
    (maps / "with_broken.csv").write_text("id,landuse\ngood,lu/flipx.png\nbroken,broken.png\n")
    out = tmp_path / "b"
    res = batch(out, "--manifest", "with_broken.csv", "--workers", "2", cwd=maps)
    assert res.returncode == 2
    lines = res.stderr.splitlines()
    assert len(lines) == 2, res.stderr
    assert lines[0].startswith("sengine: error: variant broken: with_broken.csv:3: column landuse: ")
    assert f"'{maps}/broken.png': cannot read the image" in lines[0]
    assert "cannot read the image" in lines[0]
    assert lines[1] == "sengine: error: 1 of 2 variants failed (broken); a rerun retries them"
    assert finished(out) == ["good"] and [r["id"] for r in read_rows(out)] == ["good"]
    assert not [p for p in out.iterdir() if p.name.endswith(".tmp")]


# -- a batch, its table, and its reruns ----------------------------------------------------------------------------
@pytest.mark.slow
def test_manifest_times_seeds_then_rerun_skips_redoes_and_forces(maps, tmp_path):
    (maps / "variants.csv").write_text("id,landuse,district,lots.depth\nflipped,lu/flipx.png,d/flipx.png,\ndeep,,,30\n")
    out = tmp_path / "b"
    res = batch(out, "--manifest", maps / "variants.csv", "--seeds", "1,2", "--workers", "2")
    assert res.returncode == 0, res.stderr
    ids = ["flipped-s1", "flipped-s2", "deep-s1", "deep-s2"]
    assert finished(out) == sorted(ids)
    assert not [p for p in out.iterdir() if p.name.endswith(".tmp")]
    rows = read_rows(out)
    assert [r["id"] for r in rows] == ids  # the batch's order, whatever order they finished in
    for row in rows:
        folder = out / row["id"]
        assert_complete(folder)
        stats = json.loads((folder / "stats.json").read_text())
        record = json.loads((folder / "variant.json").read_text())
        assert int(row["seed"]) == stats["seed"] == record["seed"]
        assert {k: int(row[f"n_{k}"]) for k in stats["counts"]} == stats["counts"]
        city = stats["report"]["planning"]["city"]
        assert float(row["far"]) == city["far"] and float(row["coverage"]) == city["coverage"]
        assert float(row["gfa_m2"]) == city["floor_area_m2"] and int(row["residents"]) == city["residents"]
        assert record["hash"].startswith(row["inputs_hash"]) and len(row["inputs_hash"]) == 16
    assert rows[0]["landuse"] == str(maps / "lu" / "flipx.png") and rows[2]["landuse"] == ""
    assert rows[2]["lots.depth"] == "30" and rows[0]["lots.depth"] == ""
    # the flipped maps and the deeper lots make other cities than the config's
    base = batch(tmp_path / "base", "--seeds", "1")
    assert base.returncode == 0, base.stderr
    base_row = read_rows(tmp_path / "base")[0]
    assert base_row["n_lots"] != rows[0]["n_lots"] and base_row["n_lots"] != rows[2]["n_lots"]
    # the same table as Parquet
    pq = pytest.importorskip("pyarrow.parquet")
    table = pq.read_table(out / "batch.parquet").to_pylist()
    assert [t["id"] for t in table] == ids and [t["n_lots"] for t in table] == [int(r["n_lots"]) for r in rows]
    # the contact sheet: a 2 x 2 grid of previews
    with Image.open(out / "contact.png") as sheet:
        assert 700 < sheet.size[0] < 800 and sheet.size[1] > 500
        tile = sheet.convert("L").crop((8, 8, 368, 200))
        assert len(tile.getcolors(maxcolors=1 << 16)) > 20  # a picture, not a blank tile

    stamps = {i: (out / i / "stats.json").stat().st_mtime_ns for i in ids}
    res = batch(out, "--manifest", maps / "variants.csv", "--seeds", "1,2", "--workers", "2")
    assert res.returncode == 0, res.stderr
    assert "0 variants made, 4 already made" in res.stdout
    assert {i: (out / i / "stats.json").stat().st_mtime_ns for i in ids} == stamps
    assert [r["id"] for r in read_rows(out)] == ids

    with Image.open(maps / "lu" / "flipx.png") as im:  # a changed map: its variants only are made again
        im.transpose(Image.Transpose.ROTATE_180).save(maps / "lu" / "flipx.png")
    res = batch(out, "--manifest", maps / "variants.csv", "--seeds", "1,2", "--workers", "2")
    assert res.returncode == 0, res.stderr
    assert "2 variants made, 2 already made" in res.stdout
    now = {i: (out / i / "stats.json").stat().st_mtime_ns for i in ids}
    assert [i for i in ids if now[i] != stamps[i]] == ["flipped-s1", "flipped-s2"]

    res = batch(out, "--manifest", maps / "variants.csv", "--seeds", "1,2", "--force", "--workers", "1")
    assert res.returncode == 0, res.stderr
    assert "4 variants made" in res.stdout and "already" not in res.stdout
    assert all((out / i / "stats.json").stat().st_mtime_ns != now[i] for i in ids)
    assert finished(out) == sorted(ids) and len(read_rows(out)) == 4


@pytest.mark.slow
def test_a_cluster_elsewhere_makes_the_same_variants(maps, tmp_path, remote_cluster):
    """--scheduler tcp://: workers that inherited nothing make the same bytes as one local process."""
    args = ["--maps", "landuse=lu/flip*.png", "district=d/flip*.png"]
    runs, said = {}, {}
    for name, extra in {"one": ["--workers", "1"], "remote": ["--scheduler", remote_cluster]}.items():
        res = batch(tmp_path / name, *args, *extra, cwd=maps)
        assert res.returncode == 0, res.stderr
        runs[name], said[name] = files(tmp_path / name), res.stdout
    assert len(runs["one"]) == 2 * 2 and runs["remote"] == runs["one"]
    assert f"({remote_cluster})" in said["remote"]


@pytest.mark.slow
def test_map_sets_sweeps_and_same_bytes_on_every_scheduler(maps, tmp_path):
    pytest.importorskip("distributed")
    args = ["--maps", "landuse=lu/flip*.png", "district=d/flip*.png", "--set", "lots.depth=10,20"]
    runs = {}
    for name, extra in {
        "one": ["--workers", "1"],
        "local": ["--workers", "2"],
        "dask": ["--workers", "2", "--scheduler", "dask"],
    }.items():
        res = batch(tmp_path / name, *args, *extra, cwd=maps)
        assert res.returncode == 0, res.stderr
        runs[name] = files(tmp_path / name)
    ids = [r["id"] for r in read_rows(tmp_path / "one")]
    assert ids == [f"{stem}-lots.depth={d}" for stem in ("flipx", "flipy") for d in (10, 20)]
    assert len(runs["one"]) == 4 * 2  # preview.png and variant.json per variant
    assert runs["local"] == runs["one"] and runs["dask"] == runs["one"]
    assert (tmp_path / "dask" / "contact.png").read_bytes() == (tmp_path / "one" / "contact.png").read_bytes()
    previews = {runs["one"][f"{i}/preview.png"] for i in ids}
    assert len(previews) == 4  # four different cities


# -- crash safety ----------------------------------------------------------------------------------------------------
def _start(out: Path, *args) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "sengine", "batch", CONFIG, "-o", out, "--format", "png", *map(str, args)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _wait_for_variants(proc: subprocess.Popen, out: Path, n: int, timeout: float = 120) -> None:
    t = time.monotonic()
    while time.monotonic() - t < timeout:
        if out.exists() and len(finished(out)) >= n:
            return
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    raise AssertionError(f"no {n} variants in {timeout} s")


def _gone(procs, timeout: float = 15) -> list:
    """The processes of ``procs`` still alive after ``timeout`` s (zombies count as gone)."""
    import psutil

    t = time.monotonic()
    alive = list(procs)
    while alive and time.monotonic() - t < timeout:
        alive = [p for p in alive if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]
        time.sleep(0.05)
    return alive


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="workers die with their parent on Linux only")
def test_kill_9_then_rerun_loses_none_corrupts_none_redoes_none(tmp_path):
    psutil = pytest.importorskip("psutil")
    out = tmp_path / "b"
    proc = _start(out, "--seeds", "1-6", "--workers", "2")
    _wait_for_variants(proc, out, 1)
    workers = psutil.Process(proc.pid).children(recursive=True)
    assert workers, "the batch runs its variants in worker processes"
    proc.send_signal(signal.SIGKILL)
    proc.communicate()
    assert not _gone(workers), "a worker outlived its killed batch"
    done = finished(out)
    assert 1 <= len(done) < 6
    for vid in done:
        assert_complete(out / vid)
    stamps = {vid: (out / vid / "variant.json").stat().st_mtime_ns for vid in done}

    res = batch(out, "--seeds", "1-6", "--workers", "2")
    assert res.returncode == 0, res.stderr
    assert f"{6 - len(done)} variants made, {len(done)} already made" in res.stdout
    assert finished(out) == [f"s{i}" for i in range(1, 7)]
    assert not [p.name for p in out.iterdir() if p.name.endswith(".tmp")]  # the killed run's leftovers are gone
    for vid in finished(out):
        assert_complete(out / vid)
    assert {vid: (out / vid / "variant.json").stat().st_mtime_ns for vid in done} == stamps
    assert [r["id"] for r in read_rows(out)] == [f"s{i}" for i in range(1, 7)]


@pytest.mark.slow
@pytest.mark.parametrize("scheduler", ["local", "dask"])
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_a_signal_stops_every_worker_and_keeps_finished_variants(scheduler, sig, tmp_path):
    psutil = pytest.importorskip("psutil")
    if scheduler == "dask":
        pytest.importorskip("distributed")
    out = tmp_path / "b"
    proc = _start(out, "--seeds", "1-8", "--workers", "2", "--scheduler", scheduler)
    _wait_for_variants(proc, out, 1)
    workers = psutil.Process(proc.pid).children(recursive=True)
    proc.send_signal(sig)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 128 + sig, stderr
    assert not _gone(workers, timeout=5), "a worker outlived its stopped batch"
    done = finished(out)
    assert stderr.strip().splitlines()[-1] == f"sengine: interrupted: {len(done)} of 8 variants finished in {out}"
    assert len(done) < 8
    for vid in done:
        assert_complete(out / vid)
    assert not [p.name for p in out.iterdir() if p.name.endswith(".tmp")]  # no partial variant
    assert [r["id"] for r in read_rows(out)] == sorted(done, key=lambda v: int(v[1:]))


# -- schedulers --------------------------------------------------------------------------------------------------------
def _square(x):
    if x == 3:
        raise ValueError("three")
    return x * x, os.getpid()


@pytest.mark.parametrize("make", [lambda: InProcess(2), lambda: LocalProcesses(2)], ids=["inprocess", "local"])
def test_a_scheduler_yields_every_outcome_and_goes_on_after_a_failure(make):
    with make() as sched:
        outcomes = sorted(sched.run(_square, range(6)), key=lambda o: o[0])
    assert [i for i, _, _ in outcomes] == list(range(6))
    assert [ok for _, ok, _ in outcomes] == [True, True, True, False, True, True]
    assert isinstance(outcomes[3][2], ValueError) and str(outcomes[3][2]) == "three"
    assert [v[0] for _, ok, v in outcomes if ok] == [0, 1, 4, 16, 25]
    pids = {v[1] for _, ok, v in outcomes if ok}
    if isinstance(sched, LocalProcesses):
        assert os.getpid() not in pids and sched.task_workers == 1
    else:
        assert pids == {os.getpid()} and sched.task_workers == 2


def test_local_scheduler_forks_only_for_more_than_one_task():
    assert isinstance(make_scheduler("local", 4, 1), InProcess)
    assert isinstance(make_scheduler("local", 1, 9), InProcess)
    with make_scheduler("local", 4, 3) as sched:
        assert isinstance(sched, LocalProcesses) and sched.slots == 3


def _inside_dask(_):
    handlers = (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM))
    return in_worker(), os.getpid(), run_jobs([os.getpid] * 3, 2), handlers


@pytest.mark.slow
def test_inside_a_dask_task_sengine_never_forks():
    pytest.importorskip("distributed")
    from sengine.batch import _signals_interrupt

    with _signals_interrupt(), make_scheduler("dask", 1, 1) as sched:  # as a batch makes it
        [(_, ok, (inside, pid, pids, handlers))] = list(sched.run(_inside_dask, [None]))
    assert ok and inside and pid != os.getpid()
    assert pids == [pid] * 3  # run_jobs ran its jobs in the task's own process
    assert handlers == (signal.SIG_IGN, signal.SIG_DFL)  # not the batch's handlers, inherited by the fork


def test_contact_sheet_grid_captions_and_same_bytes(tmp_path):
    from sengine.contact import contact_sheet

    tiles = []
    for i in range(5):
        png = tmp_path / f"p{i}.png"
        if i != 2:  # variant 2 has no preview
            Image.new("RGB", (800, 400), (40 * i, 200 - 30 * i, 90)).save(png)
        tiles.append((png, f"v{i}", f"{1000 + i:,} lots, FAR 1.{i}"))
    a = contact_sheet(tiles, tmp_path / "a.png", tile_width=200)
    b = contact_sheet(tiles, tmp_path / "b.png", tile_width=200)
    assert a.read_bytes() == b.read_bytes()
    with Image.open(a) as sheet:
        rgb = sheet.convert("RGB")
    # 3 columns x 2 rows of 200 px tiles, 8 px apart; pictures 100 px high under which two caption lines sit
    assert rgb.size[0] == 8 + 3 * 208 and rgb.size[1] > 2 * (8 + 100)
    cell_h = (rgb.size[1] - 8) // 2

    def near(got, want):  # the sheet has a 256-colour palette: colours move by a few levels
        return max(abs(g - w) for g, w in zip(got, want)) <= 6

    assert near(rgb.getpixel((8 + 100, 8 + 50)), (0, 200, 90))  # tile 0's picture
    assert near(rgb.getpixel((8 + 208 + 100, 8 + 50)), (40, 170, 90))  # tile 1's, to its right
    assert near(rgb.getpixel((8 + 416 + 150, 8 + 80)), (225, 225, 222))  # tile 2: no preview, a grey box
    assert near(rgb.getpixel((8 + 100, 8 + cell_h + 50)), (120, 110, 90))  # tile 3 starts the second row
    caption = rgb.crop((8, 8 + 100, 8 + 200, 8 + cell_h - 8)).convert("L")
    assert caption.getextrema()[0] < 100  # dark text under the picture

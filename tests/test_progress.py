"""Progress: events on ``Network.run(progress=...)``, counts from forked workers, the terminal display.

The display is checked in a pseudo-terminal as a person sees it: the step
that is running is named while it runs, long steps show a bar with a count,
rate and time left, nothing is written off a terminal or with ``--quiet``.
"""

from __future__ import annotations

import fcntl
import os
import pty
import re
import struct
import sys
import termios
import time

import pytest
from conftest import ROOT, run_cli

import sengine
from sengine import network
from sengine.parallel import can_fork
from sengine.progress import Progress, TerminalProgress, as_progress


class Recorder(Progress):
    def __init__(self):
        self.events = []

    def start(self, i, n, node_id, type_):
        self.events.append(("start", i, n, node_id, type_))

    def advance(self, done, total, unit):
        self.events.append(("advance", done, total, unit))

    def finish(self, i, n, node_id, type_, count, seconds):
        self.events.append(("finish", i, n, node_id, type_, count, seconds))

    def close(self):
        self.events.append(("close",))


def _steps(events):
    """The events of each step: {node_id: [advance events]}, checking start/finish pairs in order."""
    steps, current, i_prev = {}, None, 0
    for ev in events:
        if ev[0] == "start":
            assert current is None, "a step starts before the last one finished"
            current = ev[3]
            assert ev[1] == i_prev + 1
            i_prev = ev[1]
            steps[current] = []
        elif ev[0] == "advance":
            assert current is not None, "a count outside any step"
            steps[current].append(ev[1:])
        elif ev[0] == "finish":
            assert ev[3] == current and ev[1] == i_prev
            current = None
    assert events[-1] == ("close",) and current is None
    return steps


@pytest.mark.parametrize(
    "workers,fork_after",
    [(1, None), pytest.param(2, 0.0, marks=pytest.mark.skipif(not can_fork(), reason="no fork"))],
    ids=["one-process", "forked"],
)
def test_events_name_each_step_and_count_its_chunks(tmp_path, fixtures, monkeypatch, workers, fork_after):
    """start, counts, finish for every node in order; chunks done in forked workers are counted here."""
    if fork_after is not None:
        monkeypatch.setattr(network, "FORK_AFTER", fork_after)
    net = sengine.load(fixtures / "squares.xml")
    net.set_param("source", "count", 1500)
    rec = Recorder()
    result = net.run(seed=5, out=tmp_path / "out", workers=workers, progress=rec)
    steps = _steps(rec.events)
    assert list(steps) == ["source", "inset", "write"]
    finished = [ev for ev in rec.events if ev[0] == "finish"]
    assert [ev[5] for ev in finished] == [1500, 1500, 0]
    assert all(ev[2] == 3 and ev[6] >= 0 for ev in finished)
    inset = steps["inset"]
    if workers > 1:  # chunked: counted in the input's features up to the whole layer
        assert inset[0] == (0, 1500, "polygons")
        assert inset[-1] == (1500, 1500, "polygons")
        dones = [d for d, _, _ in inset]
        assert dones == sorted(dones)
    else:  # run whole: nothing to count
        assert inset == []
    assert steps["source"] == []
    assert steps["write"][-1][0] == 1500  # the GeoJSON text is made (and counted) a chunk of features at a time
    assert result.stats["counts"]["inset"] == 1500


def test_plain_callables_and_partial_objects_still_work(tmp_path, fixtures):
    calls = []
    net = sengine.load(fixtures / "squares.xml")
    net.run(out=tmp_path / "a", progress=lambda *a: calls.append(a))
    assert [(c[0], c[1], c[2], c[3], c[4]) for c in calls] == [
        (1, 3, "source", "demo.squares", 7),
        (2, 3, "inset", "demo.inset", 7),
        (3, 3, "write", "demo.write", 0),
    ]
    assert all(isinstance(c[5], float) for c in calls)

    class OnlyFinish:
        def __init__(self):
            self.ids = []

        def finish(self, i, n, node_id, type_, count, seconds):
            self.ids.append(node_id)

    only = OnlyFinish()
    net.run(out=tmp_path / "b", progress=only)
    assert only.ids == ["source", "inset", "write"]
    with pytest.raises(TypeError, match="progress must be a callable"):
        as_progress(5)


def test_progress_does_not_change_the_files(tmp_path, fixtures, monkeypatch):
    monkeypatch.setattr(network, "FORK_AFTER", 0.0)
    net = sengine.load(fixtures / "squares.xml")
    net.set_param("source", "count", 900)
    net.run(seed=2, out=tmp_path / "quiet", workers=2)
    net.run(seed=2, out=tmp_path / "loud", workers=2, progress=TerminalProgress(open(os.devnull, "w")))
    assert (tmp_path / "quiet" / "write.geojson").read_bytes() == (tmp_path / "loud" / "write.geojson").read_bytes()


def test_events_close_when_the_run_fails(tmp_path, fixtures, monkeypatch):
    from sengine import registry

    net = sengine.load(fixtures / "squares.xml")

    def boom(self, **inputs):
        raise RuntimeError("disk full")

    monkeypatch.setattr(registry.get("demo.write"), "run", boom)
    rec = Recorder()
    with pytest.raises(RuntimeError, match="disk full"):
        net.run(out=tmp_path / "x", progress=rec)
    assert [e[0] for e in rec.events] == ["start", "finish", "start", "finish", "start", "close"]
    assert not (tmp_path / "x").exists()


# -- the terminal display -------------------------------------------------------------------------------------------
def run_in_pty(args, cols=120, rows=30, timeout=300):
    """Run ``python -m sengine ARGS`` with stdout and stderr on a pseudo-terminal of ``cols`` x ``rows``."""
    pid, fd = pty.fork()
    if pid == 0:  # the child: a terminal of that size, then the command
        try:
            fcntl.ioctl(2, termios.TIOCSWINSZ, struct.pack("HHHH", rows, cols, 0, 0))
            os.execv(sys.executable, [sys.executable, "-m", "sengine", *map(str, args)])
        finally:
            os._exit(127)
    out = bytearray()
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            chunk = os.read(fd, 65536)
        except OSError:  # EIO: the child closed the terminal
            break
        if not chunk:
            break
        out += chunk
    _, status = os.waitpid(pid, 0)
    os.close(fd)
    return os.waitstatus_to_exitcode(status), out.decode("utf-8", "replace")


def _screens(text):
    """Every state of the terminal's lines: the text cut at carriage returns and newlines."""
    return [s.strip() for s in re.split(r"[\r\n]+", text) if s.strip()]


@pytest.mark.slow
def test_terminal_names_the_running_step_with_a_bar(tmp_path):
    code, text = run_in_pty(
        ["run", ROOT / "configs" / "manhattan.xml", "-o", tmp_path / "m", "--workers", "2", "--format", "geojson,png"]
    )
    assert code == 0, text
    lines = _screens(text)
    n = int(re.search(r"^\[1/(\d+)\] ", lines[0]).group(1))  # the plan's maps and rules, then the city's nodes
    names = ["majorRoads", "minorRoads", "blocks", "lots", "buildings", "planning", "export"]
    ks = []
    for node in names:
        running = next(j for j, s in enumerate(lines) if re.match(rf"\[\d+/{n}\] {node} \(.*\): running", s))
        k = int(re.match(r"\[(\d+)/", lines[running]).group(1))
        done = next(
            j for j, s in enumerate(lines) if re.match(rf"\[{k}/{n}\] {node} \(.*\): ([\d,]+ features?|done), ", s)
        )
        assert running < done, f"{node}: named only after it finished"
        ks.append(k)
    assert ks == sorted(ks) and ks[-1] == n
    # chunked nodes count their input's features in the workers (--workers 2), with a rate
    assert any(re.search(rf"\[{ks[4]}/{n}\] buildings .*\| [\d.]+k?/[\d.]+k? lots \[", s) for s in lines), lines
    # the export counts its features with a bar, a rate and the time left
    bars = [s for s in lines if s.startswith(f"[{n}/{n}] export (export.city):") and "%|" in s]
    assert bars, lines
    assert re.search(r"100%\|.*\| [\d.]+k?/[\d.]+k? features \[\d\d:\d\d<\d\d:\d\d, +[\d.]+k? features/s\]", bars[-1])
    assert lines[-1].startswith(f"{tmp_path / 'm'}: majorRoads 91")


@pytest.mark.slow
def test_batch_draws_one_bar_over_its_variants(tmp_path, fixtures):
    """``sengine batch`` on a terminal: one bar counting variants, each variant's line above it, never drawn over."""
    out = tmp_path / "b"
    code, text = run_in_pty(["batch", fixtures / "squares.xml", "-o", out, "--seeds", "1-3", "--workers", "2"])
    assert code == 0, text
    lines = _screens(text)
    made = [s for s in lines if re.fullmatch(r"\[\d/3\] s\d: source 7, inset 7 in [\d.]+ s", s)]
    assert sorted(s[:5] for s in made) == ["[1/3]", "[2/3]", "[3/3]"], lines
    bars = [s for s in lines if s.startswith("batch: 3 variants (local)")]
    assert any(re.search(r"100%\|.*\| 3/3 variants \[", s) for s in bars), bars
    # a line is a variant's, the bar, or the summary: none drawn over another
    assert all(s in made or s in bars or s.startswith(f"{out}: 3 variants made") for s in lines), lines
    assert lines[-1].startswith(f"{out}: 3 variants made")
    # off a terminal the lines are the same, without the bar
    r = run_cli("batch", fixtures / "squares.xml", "-o", tmp_path / "c", "--seeds", "1-3", "--workers", "2")
    assert r.returncode == 0 and r.stderr == ""
    plain = [s for s in r.stdout.splitlines() if re.fullmatch(r"\[\d/3\] s\d: source 7, inset 7 in [\d.]+ s", s)]
    assert sorted(s.split(" in ")[0][6:] for s in plain) == sorted(s.split(" in ")[0][6:] for s in made)


@pytest.mark.slow
def test_quiet_and_off_a_terminal_say_nothing_on_stderr(tmp_path):
    code, text = run_in_pty(["run", ROOT / "configs" / "manhattan.xml", "-o", tmp_path / "q", "--quiet"])
    assert code == 0 and text.strip() == "", text
    r = run_cli("run", ROOT / "configs" / "manhattan.xml", "-o", tmp_path / "p")  # stderr a pipe
    assert r.returncode == 0 and r.stderr == ""
    assert r.stdout.startswith(f"{tmp_path / 'p'}: majorRoads")


def test_terminal_clock_runs_between_counts(tmp_path):
    """A step that counts nothing still shows its clock running."""
    path = tmp_path / "out.txt"
    with open(path, "w") as f:
        p = TerminalProgress(f, tick=0.2)
        p.start(1, 1, "majorRoads", "osm.read")
        time.sleep(1.3)
        p.finish(1, 1, "majorRoads", "osm.read", 10, 1.3)
        p.close()
    lines = _screens(path.read_text())
    assert "[1/1] majorRoads (osm.read): running 00:01" in lines
    assert lines.count("[1/1] majorRoads (osm.read): running 00:00") >= 3
    assert lines[-1] == "[1/1] majorRoads (osm.read): 10 features, 1.30 s"


def test_terminal_progress_draws_a_bar(tmp_path):
    """The display alone, on a file: the running step's line, then its bar with count and rate, then its line."""
    path = tmp_path / "out.txt"
    with open(path, "w") as f:
        p = TerminalProgress(f, tick=0)
        p.start(2, 5, "lots", "lots.paris")
        p.advance(500, 2000, "blocks")
        p.advance(2000, 2000, "blocks")
        p.finish(2, 5, "lots", "lots.paris", 12345, 1.5)
        p.close()
    lines = _screens(path.read_text())
    assert lines[0] == "[2/5] lots (lots.paris): running 00:00"
    assert any(re.search(r"25%\|.*\| 500/2\.00k blocks \[", s) for s in lines)
    assert any(re.search(r"100%\|.*\| 2\.00k/2\.00k blocks \[.*blocks/s\]", s) for s in lines)
    assert lines[-1] == "[2/5] lots (lots.paris): 12,345 features, 1.50 s"
    # a few items are counted as they are (3/12, not 3.00/12.0)
    with open(path, "w") as f:
        p = TerminalProgress(f, tick=0)
        p.begin("batch: 12 variants (local)")
        p.advance(3, 12, "variants")
        p.write("[3/12] s3: done", f)
        p.close()
    lines = _screens(path.read_text())
    assert any(re.search(r"25%\|.*\| 3/12 variants \[\d\d:\d\d<", s) for s in lines), lines
    assert "[3/12] s3: done" in lines

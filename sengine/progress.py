"""Progress of a run: events for the running step, counts from any process, a terminal display.

:meth:`sengine.network.Network.run` takes ``progress=``:

* ``None``: nothing is reported;
* a plain callable ``progress(i, n, node_id, type, count, seconds)``: called
  after each node, as it always was;
* an object with the methods of :class:`Progress` (``start``, ``advance``,
  ``finish``, ``close``; any it lacks are skipped), such as
  :class:`TerminalProgress`:

  - ``start(i, n, node_id, type)`` when node ``i`` of ``n`` starts running;
  - ``advance(done, total, unit)`` while it runs, when it counts its work
    (``done`` of ``total`` features or files; ``total`` may be None);
  - ``finish(i, n, node_id, type, count, seconds)`` when it is done;
  - ``close()`` once, when the run ends (also on an error).

A step counts its work with :func:`expect` and :func:`advance`, which any
code of the run may call, in this process or in a worker that
:func:`sengine.parallel.run_jobs` forked: the executor counts the features of
a node it runs in chunks, the exporters the features their writers have
written, chunk by chunk.  Counts go into one integer in shared memory; only
the run's own process reports them, at most every :data:`INTERVAL` seconds
(and while it waits for its workers).  Events never change what a run makes.
"""

from __future__ import annotations

import os
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import IO, Any

__all__ = ["Progress", "TerminalProgress", "as_progress", "step", "expect", "advance", "poll", "INTERVAL"]

#: Seconds between two ``advance`` events of a step (the last count of a step is always reported).
INTERVAL = 0.1


class Progress:
    """What a run reports while it runs; every method does nothing here: override the ones wanted."""

    def start(self, i: int, n: int, node_id: str, type_: str) -> None:
        """Node ``i`` of ``n`` (``node_id``, registered ``type_``) starts running."""

    def advance(self, done: int, total: int | None, unit: str) -> None:
        """The running node has done ``done`` of ``total`` ``unit`` (features, files ...)."""

    def finish(self, i: int, n: int, node_id: str, type_: str, count: int, seconds: float) -> None:
        """Node ``i`` of ``n`` is done: ``count`` features out, in ``seconds``."""

    def close(self) -> None:
        """The run is over (done or failed)."""


class _AfterEach(Progress):
    """A plain callable ``fn(i, n, node_id, type, count, seconds)`` called after each node."""

    def __init__(self, fn: Callable[..., Any]):
        self.fn = fn

    def finish(self, i: int, n: int, node_id: str, type_: str, count: int, seconds: float) -> None:
        self.fn(i, n, node_id, type_, count, seconds)


class _Methods(Progress):
    """An object with some of :class:`Progress`'s methods: those it has are called, the others skipped."""

    def __init__(self, obj: Any):
        for name in ("start", "advance", "finish", "close"):
            method = getattr(obj, name, None)
            if callable(method):
                setattr(self, name, method)


def as_progress(progress: Any) -> Progress | None:
    """The :class:`Progress` that ``progress`` (None, a callable, or an object with the methods) stands for.

    Raises
    ------
    TypeError
        ``progress`` is neither None, callable, nor has any of the methods.
    """
    if progress is None or isinstance(progress, Progress):
        return progress
    if any(callable(getattr(progress, m, None)) for m in ("start", "advance", "finish")):
        return _Methods(progress)
    if callable(progress):
        return _AfterEach(progress)
    raise TypeError(f"progress must be a callable or have start/advance/finish methods, not {type(progress).__name__}")


class _Step:
    """The running step's count: an integer in shared memory that forked workers add to."""

    def __init__(self, events: Progress, shared):
        self.events = events
        self.shared = shared
        self.pid = os.getpid()  # the run's own process: the one that reports
        self.total: int | None = None
        self.unit = "features"
        self.reported = -1
        self.at = 0.0

    def done(self) -> int:
        return int(self.shared.value)

    def report(self, force: bool = False) -> None:
        """Send the count to the events (the run's own process only), at most every :data:`INTERVAL` s."""
        if os.getpid() != self.pid:
            return
        done = self.done()
        if done == 0 and self.total is None:  # nothing counted, nothing expected: the step is just running
            return
        now = time.perf_counter()
        final = self.total is not None and done >= self.total
        if done != self.reported and (force or final or now - self.at >= INTERVAL):
            self.reported, self.at = done, now
            self.events.advance(done, self.total, self.unit)


class _Counter:
    """A stand-in for a shared integer where shared memory cannot be had (a count this process sees alone)."""

    def __init__(self) -> None:
        self.value = 0

    def get_lock(self):
        return _NoLock()


class _NoLock:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


_shared = None  # this process's shared integer, made once, before any step forks workers
_current: _Step | None = None  # the running step of a run that reports progress


def _shared_value():
    global _shared
    if _shared is None:
        try:
            import multiprocessing

            _shared = multiprocessing.get_context("fork" if sys.platform != "win32" else "spawn").Value("q", 0)
        except (OSError, ValueError, ImportError):  # no shared memory (some containers)
            _shared = _Counter()
    return _shared


@contextmanager
def step(events: Progress | None, i: int, n: int, node_id: str, type_: str) -> Iterator[None]:
    """Run a step under ``events``: ``start`` now, counts through :func:`advance` until the block ends.

    With ``events`` None nothing is reported and :func:`advance` costs nothing.
    ``finish`` is the caller's (it knows the count).
    """
    global _current
    if events is None:
        yield
        return
    shared = _shared_value()
    with shared.get_lock():
        shared.value = 0
    outer, _current = _current, _Step(events, shared)
    try:
        events.start(i, n, node_id, type_)
        yield
        if _current.reported >= 0 or _current.done():
            _current.report(force=True)
    finally:
        _current = outer


def expect(total: int | None, unit: str = "features") -> None:
    """Say how much work the running step has (``total`` ``unit``); the count starts again at 0."""
    cur = _current
    if cur is None:
        return
    cur.total = None if total is None else int(total)
    cur.unit = unit
    if os.getpid() == cur.pid:
        with cur.shared.get_lock():
            cur.shared.value = 0
        cur.reported = -1
        cur.report(force=True)


def advance(k: int = 1) -> None:
    """Count ``k`` more units of the running step's work (from this process or a forked worker)."""
    cur = _current
    if cur is None or k <= 0:
        return
    with cur.shared.get_lock():
        cur.shared.value += int(k)
    cur.report()


def poll() -> None:
    """Report the count of the running step (what forked workers added); :func:`run_jobs` calls it as it waits."""
    cur = _current
    if cur is not None:
        cur.report()


class TerminalProgress(Progress):
    """A progress display on a terminal, with `tqdm <https://tqdm.github.io>`_.

    The running step is a line that names it (``[7/12] lots (lots.paris)``)
    with its clock, redrawn every ``tick`` seconds; once it counts its work the line becomes a bar
    with the count, rate and time left.  Each finished step leaves one line:
    its count and seconds.  :meth:`begin` and :meth:`write` serve any other
    long count the same way (``sengine batch``: one bar over the variants,
    a line above it for each one made).

    Parameters
    ----------
    file : file-like, optional
        Where to write (default ``sys.stderr``).
    tick : float
        Seconds between two redraws of the running step's clock (0: only on counts).
    """

    def __init__(self, file: IO[str] | None = None, tick: float = 0.5):
        self.file = file if file is not None else sys.stderr
        self.tick = tick
        self._bar = None
        self._clock = None
        self._stop = threading.Event()

    def _run_clock(self) -> None:
        """Every ``tick`` seconds, take the running step's count and redraw its line (its clock runs between counts).

        A thread of this process: the workers that :func:`sengine.parallel.run_jobs`
        forks never draw (they only add to the shared count), and this process
        may be busy with a job of its own.
        """
        while not self._stop.wait(self.tick):
            poll()  # what forked workers counted while this process is busy with a job of its own
            bar = self._bar
            if bar is not None:
                bar.refresh()

    def start(self, i: int, n: int, node_id: str, type_: str) -> None:
        """A line for the running step, its clock ticking (a thread of this process redraws it)."""
        self.begin(f"[{i}/{n}] {node_id} ({type_})")

    def begin(self, desc: str) -> None:
        """A line named ``desc`` with its clock ticking, until :meth:`advance` gives it a count."""
        from tqdm import tqdm

        self._close_bar()
        if self._clock is None and self.tick > 0:
            self._stop.clear()
            self._clock = threading.Thread(target=self._run_clock, name="sengine-progress", daemon=True)
            self._clock.start()
        sized = min(self._size()) > 0
        self._bar = tqdm(
            total=None,
            desc=desc,
            file=self.file,
            leave=False,
            # a terminal that tells no size (a bare pty, some CI consoles) is taken as 100 x 24
            dynamic_ncols=sized,
            ncols=None if sized else 100,
            nrows=None if sized else 24,
            unit_scale=True,
            mininterval=0,  # counts come at most every INTERVAL s already: show each
            miniters=0,
            bar_format="{desc}: running {elapsed}",
        )

    def advance(self, done: int, total: int | None, unit: str) -> None:
        """The running step's line becomes a bar: count, rate and time left (with a total)."""
        bar = self._bar
        if bar is None:
            return
        if bar.unit != f" {unit}" or bar.total != total:
            if bar.total is not None or bar.n:  # a step's second count (roofs, then features): rate and clock anew
                bar.reset(total=total)
            bar.unit = f" {unit}"
            bar.total = total
            bar.unit_scale = (total or 0) >= 1000  # 85.9k features, but 3/12 variants
            bar.bar_format = (
                "{desc}: {percentage:3.0f}%|{bar}| {n_fmt}/{total_fmt}{unit} [{elapsed}<{remaining}, {rate_noinv_fmt}]"
                if total
                else "{desc}: {n_fmt}{unit} [{elapsed}, {rate_noinv_fmt}]"
            )
        bar.update(done - bar.n)

    def finish(self, i: int, n: int, node_id: str, type_: str, count: int, seconds: float) -> None:
        """The step's bar goes; one line stays: its count and seconds."""
        from tqdm import tqdm

        self._close_bar()
        what = f"{count:,} feature{'' if count == 1 else 's'}" if count else "done"
        tqdm.write(f"[{i}/{n}] {node_id} ({type_}): {what}, {seconds:.2f} s", file=self.file)

    def write(self, line: str, file: IO[str] | None = None) -> None:
        """Print ``line`` on ``file`` (default: the display's) above the bar, which is drawn again below it."""
        from tqdm import tqdm

        tqdm.write(line, file=file if file is not None else self.file)

    def close(self) -> None:
        """Stop the clock and clear the bar."""
        if self._clock is not None:
            self._stop.set()
            self._clock.join()
            self._clock = None
        self._close_bar()
        self.file.flush()

    def _size(self) -> tuple[int, int]:
        try:
            return tuple(os.get_terminal_size(self.file.fileno()))
        except (AttributeError, OSError, ValueError):
            return (0, 0)

    def _close_bar(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

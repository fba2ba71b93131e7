"""Independent jobs side by side in forked processes.

The executor's feature chunks, the exporter's files, ``sengine batch``'s seeds
and the OSM reader's two passes are independent jobs: each reads what the
run has made so far and returns a result.  On a POSIX system ``workers - 1``
processes are forked; they inherit the jobs (nothing is pickled on the way
in).  This process runs the first job (the longest, whose result then needs
no pickling), and every process takes the next job not yet taken until none
are left.  Only the workers' results travel back, pickled through a pipe.
Elsewhere, or with one worker, the jobs run here in turn.  Either way the
results, and the files the jobs write, are the same.
"""

from __future__ import annotations

import os
import pickle
import sys
from collections.abc import Callable, Sequence
from typing import Any

__all__ = ["available_cores", "can_fork", "in_worker", "run_jobs"]

_in_worker = False  # set in the processes run_jobs forks
_running = False  # set while this process runs jobs of a run_jobs call: jobs within jobs run in turn


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity where the system tells)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # macOS, Windows
        return os.cpu_count() or 1


def in_worker() -> bool:
    """Whether this process is one that :func:`run_jobs` forked."""
    return _in_worker


def can_fork() -> bool:
    """Whether forking is safe here (macOS lists fork, but its system libraries are not fork-safe)."""
    return hasattr(os, "fork") and sys.platform != "darwin"


def run_jobs(jobs: Sequence[Callable[[], Any]], workers: int) -> list[Any]:
    """The results of ``jobs`` (callables without arguments), in order.

    Parameters
    ----------
    jobs : sequence of callable
        Independent jobs.  They are taken in this order, the first by this
        process: put the longest first.
    workers : int
        Processes to use, this one included.  1, a job of another
        ``run_jobs`` call (no processes within processes) or a system where
        forking is not safe (Windows, macOS) runs the jobs here, in turn.

    Returns
    -------
    list
        ``[job() for job in jobs]``.  The exception of the first job that
        failed (in job order) is raised here, once every process stopped.
    """
    global _in_worker, _running
    workers = min(int(workers), len(jobs))
    if workers <= 1 or _in_worker or _running or not can_fork():
        return [job() for job in jobs]
    import multiprocessing  # here: the CLI imports this module, and most runs never fork

    try:
        taken = multiprocessing.get_context("fork").Value("l", 1)  # the next job to take (0 is this process's)
    except OSError:  # no shared memory (some containers): one process
        return [job() for job in jobs]
    children = []
    for _ in range(workers - 1):
        try:
            read, write = os.pipe()
            pid = os.fork()
        except OSError:  # no process to spare: the ones forked so far do the work
            break
        if pid == 0:  # a worker: take jobs, send (index, ok, result) back, leave without cleanup handlers
            _in_worker = True
            os.close(read)
            status = 1
            try:
                done = _take_jobs(jobs, taken)
                try:
                    data = pickle.dumps(done, protocol=pickle.HIGHEST_PROTOCOL)
                except Exception as exc:  # noqa: BLE001 (a result or an error that does not pickle)
                    data = pickle.dumps([(i, False, RuntimeError(f"job {i}: {exc}")) for i, _, _ in done])
                with os.fdopen(write, "wb") as pipe:
                    pipe.write(data)
                status = 0
            finally:
                os._exit(status)
        os.close(write)
        children.append((pid, os.fdopen(read, "rb")))
    done = None
    try:
        _running = True
        done = _take_jobs(jobs, taken, first=0)
    finally:
        _running = False
        if done is None:  # interrupted here: the workers stop after their current job
            with taken.get_lock():
                taken.value = len(jobs)
        received = _receive([pipe for _, pipe in children])
        for (pid, pipe), data in zip(children, received):
            pipe.close()
            _, status = os.waitpid(pid, 0)
            if done is not None and status == 0 and data:
                done += pickle.loads(data)
    results: list[Any] = [None] * len(jobs)
    finished = [False] * len(jobs)
    for i, ok, value in sorted(done, key=lambda d: d[0]):
        if not ok:
            raise value
        results[i], finished[i] = value, True
    if not all(finished):
        raise RuntimeError(f"a worker process died before finishing job {finished.index(False)}")
    return results


def _receive(pipes: list) -> list[bytes]:
    """Everything each worker sends, read side by side; while waiting, the running step's count is reported
    (:func:`sengine.progress.poll`: what the workers have done so far)."""
    import selectors

    from .progress import poll

    data = [bytearray() for _ in pipes]
    with selectors.DefaultSelector() as sel:
        for k, pipe in enumerate(pipes):
            sel.register(pipe.fileno(), selectors.EVENT_READ, k)
        open_ = len(pipes)
        while open_:
            for key, _ in sel.select(timeout=0.2):
                chunk = os.read(key.fd, 1 << 20)
                if chunk:
                    data[key.data] += chunk
                else:  # the worker is done
                    sel.unregister(key.fd)
                    open_ -= 1
            poll()
    return [bytes(d) for d in data]


def _take_jobs(jobs: Sequence[Callable[[], Any]], taken, first: int | None = None) -> list[tuple[int, bool, Any]]:
    """Run job ``first``, then the next job not yet taken until none are left; stop at the first failure."""
    done = []
    i = first
    while True:
        if i is None:
            with taken.get_lock():
                i = taken.value
                taken.value = i + 1
        if i >= len(jobs):
            return done
        try:
            done.append((i, True, jobs[i]()))
        except Exception as exc:  # noqa: BLE001 (handed to run_jobs, which raises it in job order)
            done.append((i, False, exc))
            with taken.get_lock():  # the others stop after their current job
                taken.value = len(jobs)
            return done
        i = None

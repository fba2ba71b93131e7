"""Independent jobs side by side in forked worker processes.

The executor's feature chunks, the exporter's files and ``sengine batch``'s
seeds are independent jobs: each reads what the run has made so far and
returns a small result.  On a POSIX system they run in forked processes, which
inherit the jobs (the layers are not pickled on the way in; only the results
come back), so that a 2-core machine writes two files at once.  Elsewhere, or
with one worker, they run in turn in this process.  Either way the results,
and the files the jobs write, are the same.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Sequence
from typing import Any

__all__ = ["available_cores", "run_jobs"]

_JOBS: Sequence[Callable[[], Any]] = ()  # the jobs of the pool being run, inherited by its forked workers


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity where the system tells)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # macOS, Windows
        return os.cpu_count() or 1


def _can_fork() -> bool:
    import multiprocessing

    # macOS lists fork but its system libraries are not fork-safe
    return sys.platform != "darwin" and "fork" in multiprocessing.get_all_start_methods()


def _call(i: int) -> Any:
    return _JOBS[i]()


def run_jobs(jobs: Sequence[Callable[[], Any]], workers: int) -> list[Any]:
    """The results of ``jobs`` (callables without arguments), in order.

    Parameters
    ----------
    jobs : sequence of callable
        Independent jobs.  They start in this order as workers come free:
        put the longest first.
    workers : int
        Processes to use; 1 (or a system without a safe ``fork``: Windows,
        macOS) runs the jobs here, in turn.

    Returns
    -------
    list
        ``[job() for job in jobs]``; a job's exception is raised here.
    """
    global _JOBS
    workers = min(int(workers), len(jobs))
    if workers <= 1 or not _can_fork():
        return [job() for job in jobs]
    import multiprocessing  # here: the CLI imports this module, and most runs never fork
    from concurrent.futures import ProcessPoolExecutor

    outer, _JOBS = _JOBS, jobs
    try:
        with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("fork")) as pool:
            return list(pool.map(_call, range(len(jobs))))
    finally:
        _JOBS = outer

"""Independent jobs side by side in forked processes (the standard library's process pool).

The executor's feature chunks, the exporter's files and the OSM reader's two
passes are independent jobs: each reads what the run has made so far and
returns a result.  On a POSIX system a :class:`concurrent.futures.ProcessPoolExecutor`
of ``workers - 1`` processes is forked; they inherit the jobs (only a job's
index is pickled on the way in, so jobs may be closures holding large
layers).  This process runs the first job (the longest, whose result then
needs no pickling), then, like every worker, the next job not yet taken
until none are left (a job the pool has not handed out is cancelled there
and run here).  Only the
workers' results travel back, pickled.  Elsewhere, with one worker, inside a
job of another ``run_jobs`` call or inside a Dask task, the jobs run here in
turn.  Either way the results, and the files the jobs write, are the same.

:class:`Background` runs one job in a forked process while this one goes
on (a node's early job, :meth:`sengine.node.SENode.early`: the exporter's
roofs, made while the nodes between the buildings and the export run).

Worker processes ignore SIGINT and die with this process: whoever runs the
pool decides when it stops (an interrupt here kills the workers, and a
killed parent takes its workers with it on Linux), so no process is left
computing on its own.

This replaced a hand-written fork pool (a shared job counter and one pipe
per worker).  ``bench/parallel.py`` times both: on the Manhattan demo with
two workers they were within 2 % (0.657 s and 0.669 s, medians of 5); the
standard library's pool costs some 4 ms more per call (its manager thread
and shutdown), which a run pays a handful of times.
"""

from __future__ import annotations

import os
import signal
import sys
from collections.abc import Callable, Sequence
from typing import Any

__all__ = [
    "available_cores",
    "Background",
    "can_fork",
    "in_worker",
    "in_dask_task",
    "run_jobs",
    "worker_setup",
    "worker_signals",
    "kill_workers",
]

_in_worker = False  # set in the processes run_jobs (or a batch's local scheduler) starts
_running = False  # set while this process runs jobs of a run_jobs call: jobs within jobs run in turn
_jobs: Sequence[Callable[[], Any]] = ()  # the jobs of the running run_jobs call, inherited by its forked workers
_early: dict[int, Callable[[], Any]] = {}  # a Background's job while its process is forked (inherited by it)


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity where the system tells)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # macOS, Windows
        return os.cpu_count() or 1


def in_dask_task() -> bool:
    """Whether this code runs inside a task on a Dask worker (where sengine never forks)."""
    if "distributed" not in sys.modules:  # never import Dask just to ask
        return False
    try:
        from distributed import get_worker

        get_worker()
    except (ImportError, ValueError):
        return False
    return True


def in_worker() -> bool:
    """Whether this process is a worker of sengine's or of Dask's: it runs its jobs in turn, forking nothing."""
    return _in_worker or in_dask_task()


def can_fork() -> bool:
    """Whether forking is safe here (macOS lists fork, but its system libraries are not fork-safe)."""
    return hasattr(os, "fork") and sys.platform != "darwin"


def worker_setup(parent: int) -> None:
    """Set up a worker process: mark it, ignore SIGINT, die by SIGTERM, and die with its parent.

    Parameters
    ----------
    parent : int
        Process id of the process that started the pool.  On Linux the
        kernel kills the worker when that process ends, however it ends
        (``prctl(PR_SET_PDEATHSIG)``); elsewhere a worker notices only when it
        next reads its work queue.
    """
    global _in_worker
    _in_worker = True
    worker_signals()
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):  # no libc to ask: the queue's end still stops the worker
            pass
    if os.getppid() != parent:  # the parent died before the line above
        os._exit(1)


def worker_signals() -> bool:
    """In a worker process: ignore SIGINT (its parent stops it) and die by SIGTERM; True when set.

    A forked worker inherits its parent's Python signal handlers (a batch's
    handler raises an exception on SIGTERM), which must not run in it.
    Only the main thread can set handlers: elsewhere nothing is done.
    """
    import threading

    if threading.current_thread() is not threading.main_thread():
        return False
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    return True


def kill_workers(pool) -> None:
    """Kill the processes of a :class:`concurrent.futures.ProcessPoolExecutor` and wait for them."""
    if hasattr(pool, "kill_workers"):  # Python 3.14
        pool.kill_workers()
        return
    processes = list((getattr(pool, "_processes", None) or {}).values())
    for proc in processes:
        try:
            proc.kill()
        except (OSError, ValueError, AttributeError):  # already gone
            pass
    for proc in processes:
        try:
            proc.join(5)
        except (OSError, ValueError, AttributeError, AssertionError):
            pass


def run_jobs(jobs: Sequence[Callable[[], Any]], workers: int) -> list[Any]:
    """The results of ``jobs`` (callables without arguments), in order.

    Parameters
    ----------
    jobs : sequence of callable
        Independent jobs.  They are taken in this order, the first by this
        process: put the longest first.
    workers : int
        Processes to use, this one included.  1, a job of another
        ``run_jobs`` call (no processes within processes), a Dask task or a
        system where forking is not safe (Windows, macOS) runs the jobs here,
        in turn.

    Returns
    -------
    list
        ``[job() for job in jobs]``.  The exception of the first job that
        failed (in job order) is raised here, once every process stopped; a
        worker that died is a :class:`RuntimeError`.
    """
    global _running, _jobs
    workers = min(int(workers), len(jobs))
    if workers <= 1 or _running or in_worker() or not can_fork():
        return [job() for job in jobs]
    import multiprocessing  # here: most runs never fork
    from concurrent.futures import ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    _jobs = jobs
    try:
        pool = ProcessPoolExecutor(
            workers - 1,
            mp_context=multiprocessing.get_context("fork"),
            initializer=worker_setup,
            initargs=(os.getpid(),),
        )
    except OSError:  # no shared memory for the queues' locks (some containers): one process
        _jobs = ()
        return [job() for job in jobs]
    try:
        try:
            futures = [pool.submit(_run_job, i) for i in range(1, len(jobs))]  # forks at the first submit
        except OSError:  # no process to spare: the jobs run here
            kill_workers(pool)
            pool.shutdown(wait=False, cancel_futures=True)
            return [job() for job in jobs]
        except BrokenProcessPool:  # a worker died on its first job before every job was handed out
            kill_workers(pool)
            raise RuntimeError("a worker process died before every job was handed out") from None
        outcomes: dict[int, tuple[bool, Any]] = {}  # the jobs run here: index -> (ok, result or error)
        _running = True
        try:
            for i in range(len(jobs)):  # job 0, then every job no worker has taken yet
                if i and not futures[i - 1].cancel():
                    continue
                try:
                    outcomes[i] = (True, jobs[i]())
                except Exception as exc:  # noqa: BLE001 (raised below, in job order)
                    outcomes[i] = (False, exc)
                    break
                if any(f.done() and not f.cancelled() and f.exception() is not None for f in futures):
                    break
        finally:
            _running = False
        done = _wait(futures)
        if any(not ok for ok, _ in outcomes.values()) or any(
            not f.cancelled() and f.exception() is not None for f in done
        ):
            for f in futures:  # the workers stop after their current job
                f.cancel()
            wait(futures)
        results = []
        for i in range(len(jobs)):
            if i in outcomes:
                ok, value = outcomes[i]
            elif futures[i - 1].cancelled():
                continue  # not run, after a failure
            else:
                value = futures[i - 1].exception()
                ok = value is None
                if isinstance(value, BrokenProcessPool):
                    raise RuntimeError(f"a worker process died before finishing job {i}") from None
                if ok:
                    value = futures[i - 1].result()
            if not ok:
                raise value
            results.append(value)
        return results
    except BaseException as exc:
        if not isinstance(exc, Exception):  # an interrupt here (Ctrl-C, a signal handler's): stop the workers now
            kill_workers(pool)
        raise  # after a failure the workers stop after their current job (shutdown below)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
        _jobs = ()


def _wait(futures: list) -> set:
    """The futures done when all are, or when one failed.

    While waiting, the running step's count is reported
    (:func:`sengine.progress.poll`: what the workers have counted so far).
    """
    from concurrent.futures import FIRST_EXCEPTION, wait

    from .progress import poll

    while True:
        done, pending = wait(futures, timeout=0.2, return_when=FIRST_EXCEPTION)
        poll()
        if not pending or any(not f.cancelled() and f.exception() is not None for f in done):
            return done


def _run_job(i: int) -> Any:
    """Job ``i`` of the run_jobs call this worker was forked from."""
    return _jobs[i]()


class Background:
    """One job in a forked process while this process goes on; :meth:`result` waits for it.

    The job (a callable without arguments, a closure holding large layers)
    is inherited by the process forked for it, as :func:`run_jobs`'s are;
    only its result travels back, pickled.  :meth:`startable` says whether a
    job can go to the background here: with more than one worker, where
    forking is safe, outside a worker or a Dask task.

    Parameters
    ----------
    job : callable
        The job.
    """

    def __init__(self, job: Callable[[], Any]):
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        key = id(job)
        _early[key] = job
        try:
            self._pool = ProcessPoolExecutor(
                1,
                mp_context=multiprocessing.get_context("fork"),
                initializer=worker_setup,
                initargs=(os.getpid(),),
            )
            self._future = self._pool.submit(_run_early, key)  # forks here, with the job in _early
        finally:
            _early.pop(key, None)

    @staticmethod
    def startable(workers: int) -> bool:
        """Whether a run of ``workers`` processes may put a job in the background here."""
        return int(workers) > 1 and can_fork() and not _running and not in_worker()

    def result(self) -> Any:
        """The job's result (its exception raised here); ``None`` when its process died (the caller does the work)."""
        from concurrent.futures.process import BrokenProcessPool

        try:
            return self._future.result()
        except BrokenProcessPool:
            return None
        finally:
            self.close()

    def close(self) -> None:
        """Stop the process (now, when the job is still running) and wait for it."""
        if not self._future.done():
            kill_workers(self._pool)
        self._pool.shutdown(wait=True, cancel_futures=True)


def _run_early(key: int) -> Any:
    """The job of the :class:`Background` this process was forked for."""
    return _early[key]()

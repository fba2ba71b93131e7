"""Where independent tasks run: here, in local processes, or on a Dask cluster.

A *task* is a picklable call ``fn(arg)`` that writes its own files and
returns a small result: a batch's variant today, a shard of a very large
city later.  A scheduler runs a list of them and yields each outcome as it
comes; the caller records it (a row appended to a table) before the next.

=========================  ===================================================
``--scheduler local``      :class:`LocalProcesses`: a process pool on this
                           machine (forked where forking is safe, spawned
                           elsewhere), or :class:`InProcess` for one worker
``--scheduler dask``       :class:`DaskScheduler` on a ``distributed.LocalCluster``
``--scheduler tcp://H:P``  :class:`DaskScheduler` on an existing Dask cluster;
                           its workers must see the configuration, the maps
                           and the output folder at the same paths
=========================  ===================================================

A task learns from :attr:`Scheduler.task_workers` how many processes it may
use itself: only :class:`InProcess` lets a task fork (its nodes' chunks);
inside a pool or a Dask task sengine never forks
(:func:`sengine.parallel.in_worker`).  :meth:`Scheduler.stop` kills what
runs now (an interrupt): no worker is left computing on its own.
"""

from __future__ import annotations

import logging
import os
import re
from collections.abc import Callable, Iterator, Sequence
from functools import partial
from typing import Any

from .errors import ConfigError, SEngineError

__all__ = ["Scheduler", "InProcess", "LocalProcesses", "DaskScheduler", "check_scheduler", "make_scheduler"]

log = logging.getLogger(__name__)

Outcome = tuple[int, bool, Any]  # (task index, succeeded, result or exception)


class Scheduler:
    """Runs tasks ``fn(arg)``; subclasses say where.

    Attributes
    ----------
    name : str
        What ``--scheduler`` said (for messages and the batch table).
    slots : int
        Tasks that run side by side.
    task_workers : int
        Processes a task may use itself.
    inherits : bool
        Tasks see this process's memory as it was when they started (they
        run here, or in processes forked from here): a large object the
        caller keeps in a module global reaches them without being sent.
    """

    name = "local"
    slots = 1
    task_workers = 1
    inherits = True

    def run(self, fn: Callable[..., Any], args: Sequence[Any], shared: Any = None) -> Iterator[Outcome]:
        """Yield ``(index, ok, value)`` for each task as it finishes (``value``: its result or exception).

        Each task is ``fn(arg)``, or ``fn(arg, shared)`` when ``shared`` is
        given: one object every task reads, sent to each worker once where
        the scheduler can (Dask scatters it).
        """
        raise NotImplementedError

    def stop(self) -> None:
        """Kill the running tasks now (an interrupt); the scheduler is closed afterwards."""

    def close(self) -> None:
        """Release the workers once every task is done."""

    def __enter__(self) -> Scheduler:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is not None and not issubclass(exc_type, Exception):  # an interrupt
            self.stop()
        self.close()


class InProcess(Scheduler):
    """Every task here, in turn; a task may fork ``workers`` processes for its nodes."""

    def __init__(self, workers: int = 1):
        self.task_workers = max(1, int(workers))

    def run(self, fn, args, shared=None):
        """Run ``fn(arg)`` for each of ``args``; yield ``(index, ok, result or error)`` as each finishes."""
        call = fn if shared is None else partial(_with_shared, fn, shared)
        for i, arg in enumerate(args):
            try:
                yield i, True, call(arg)
            except Exception as exc:  # noqa: BLE001 (the caller records it and goes on)
                yield i, False, exc


class LocalProcesses(Scheduler):
    """A :class:`concurrent.futures.ProcessPoolExecutor` of ``workers`` processes on this machine.

    Forked where forking is safe (tasks and the registry are inherited),
    spawned elsewhere (macOS, Windows: tasks are pickled and plugins load
    again in each worker).  Workers ignore SIGINT and die with this process.
    """

    def __init__(self, workers: int):
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        from .parallel import can_fork, worker_setup

        self.slots = max(1, int(workers))
        self.inherits = can_fork()
        context = multiprocessing.get_context("fork" if self.inherits else "spawn")
        self._pool = ProcessPoolExecutor(
            self.slots, mp_context=context, initializer=worker_setup, initargs=(os.getpid(),)
        )

    def run(self, fn, args, shared=None):
        """Run ``fn(arg)`` for each of ``args``; yield ``(index, ok, result or error)`` as each finishes."""
        from concurrent.futures import as_completed
        from concurrent.futures.process import BrokenProcessPool

        # spawned workers get the shared object with each task (pickled each time: fine for a few tasks)
        extra = () if shared is None else (shared,)
        futures = {self._pool.submit(fn, arg, *extra): i for i, arg in enumerate(args)}
        for f in as_completed(futures):
            exc = f.exception()
            if isinstance(exc, BrokenProcessPool):
                exc = RuntimeError("a worker process died (killed, or out of memory) while running it")
            yield futures[f], exc is None, f.result() if exc is None else exc

    def stop(self) -> None:
        """Stop every task still running or waiting (an interrupt)."""
        from .parallel import kill_workers

        kill_workers(self._pool)

    def close(self) -> None:
        """Release the workers once every task is done."""
        self._pool.shutdown(wait=True, cancel_futures=True)


# The LocalCluster sengine starts runs a few long tasks, watched by nobody's dashboard.  Its
# workers are forked where forking is safe (they inherit sengine and its node library: the
# cluster is up in 0.3 s instead of 3 s); Dask's statistical profiler (every task's stack
# every 10 ms), event-loop tick (20 ms) and system and memory monitors (0.5 s, 0.1 s) wake
# every process's event loop, which then takes the GIL from the task: some 12 % more CPU
# per variant on Paris-size cities, 2-3 % with these settings.
_LOCAL_CLUSTER = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "500ms",
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.worker.memory.monitor-interval": "1s",
}


class DaskScheduler(Scheduler):
    """Tasks on Dask: a ``distributed.LocalCluster`` of ``workers`` processes, or the cluster at ``address``.

    Each task is one Dask task (``pure=False``: a rerun runs it again);
    cluster workers run one task at a time (``threads_per_worker=1``) and a
    task never forks there.  The LocalCluster's workers are forked where
    forking is safe (they inherit sengine's modules and node library),
    spawned elsewhere.
    """

    def __init__(self, workers: int, address: str | None = None):
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise ConfigError(
                "--scheduler dask needs Dask's distributed scheduler: pip install 'sengine[dask]'"
            ) from None
        self.name = address or "dask"
        # a cluster's own workers are forked from here only on this machine, where forking is safe
        self.inherits = False
        self._cluster = None
        self._futures: list = []
        if address is None:
            import dask

            from .parallel import can_fork

            self.slots = max(1, int(workers))
            method = "fork" if can_fork() else dask.config.get("distributed.worker.multiprocessing-method")
            self.inherits = method == "fork"
            with dask.config.set(_LOCAL_CLUSTER | {"distributed.worker.multiprocessing-method": method}):
                self._cluster = LocalCluster(
                    n_workers=self.slots,
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=None,
                    # a task's error comes back with its future; the rest (cancelled tasks, closed
                    # connections on an interrupt) is noise unless sengine logs at debug level
                    silence_logs=logging.DEBUG if log.isEnabledFor(logging.DEBUG) else logging.CRITICAL,
                )
                self._client = Client(self._cluster)
            # forked workers inherit this process's signal handlers: give them a worker's own
            from .parallel import worker_signals

            self._client.run(worker_signals)
        else:
            try:
                self._client = Client(address, timeout=10)
            except (OSError, TimeoutError, ValueError) as exc:
                raise SEngineError(f"cannot reach the Dask scheduler at {address}: {exc}") from None
            self.slots = max(1, sum(w.get("nthreads", 1) for w in self._client.scheduler_info()["workers"].values()))

    def run(self, fn, args, shared=None):
        """Run ``fn(arg)`` for each of ``args``; yield ``(index, ok, result or error)`` as each finishes."""
        from distributed import as_completed

        # the shared object goes to every worker once; each task gets it from its worker's memory.  It is
        # scattered as the one item of a list: Dask scatters a list's items apart and a dict's values under
        # the dict's own keys (names two runs on a shared cluster could both use)
        extra = () if shared is None else tuple(self._client.scatter([shared], broadcast=True, hash=False))
        self._futures = [self._client.submit(fn, arg, *extra, pure=False) for arg in args]
        index = {f.key: i for i, f in enumerate(self._futures)}
        for f in as_completed(self._futures):
            if f.status == "finished":
                yield index[f.key], True, f.result()
            else:
                yield index[f.key], False, f.exception()

    def stop(self) -> None:
        """Stop every task still running or waiting (an interrupt)."""
        logging.disable(logging.CRITICAL)  # Dask logs every task it cancels, and the closing connections
        try:
            if self._cluster is not None:  # ours: closing it kills its workers
                self._cluster.close()
                self._cluster = None
            elif self._futures and self._client.status == "running":  # a shared cluster: cancel our tasks
                try:
                    self._client.cancel(self._futures, force=True)
                except (RuntimeError, OSError, TimeoutError):  # the cluster is already going
                    pass
            self.close()
        finally:
            logging.disable(logging.NOTSET)

    def close(self) -> None:
        """Release the workers once every task is done."""
        try:
            if self._client.status not in ("closed", "closing"):
                self._client.close()
        finally:
            if self._cluster is not None:
                self._cluster.close()
                self._cluster = None


def _with_shared(fn, shared, arg):
    return fn(arg, shared)


def check_scheduler(spec: str) -> str:
    """Check ``--scheduler spec`` before anything is written; return it stripped.

    Raises
    ------
    ConfigError
        Not ``local``, ``dask`` or a Dask address (``tcp://HOST:PORT``,
        ``tls://``, ``inproc://``), or Dask is not installed.
    """
    spec = spec.strip()
    if spec == "local":
        return spec
    if spec != "dask" and not re.fullmatch(r"(tcp|tls|inproc|ucx|ws|wss)://\S+", spec):
        raise ConfigError(f"--scheduler {spec!r} is not one of local, dask or tcp://HOST:PORT (a Dask scheduler)")
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise ConfigError(
            f"--scheduler {spec} needs Dask's distributed scheduler: pip install 'sengine[dask]'"
        ) from None
    return spec


def make_scheduler(spec: str, workers: int, tasks: int) -> Scheduler:
    """The scheduler ``--scheduler spec`` names, for ``tasks`` tasks and ``--workers workers``.

    ``local`` runs one task at a time here (its nodes may then use every
    worker) when there is one worker or one task, else a process pool of
    ``min(workers, tasks)``; ``dask`` starts a LocalCluster of as many
    processes; ``tcp://HOST:PORT`` (or ``tls://``) joins that cluster.
    """
    spec = check_scheduler(spec)
    if spec == "local":
        if workers <= 1 or tasks <= 1:
            return InProcess(workers)
        return LocalProcesses(min(workers, tasks))
    if spec == "dask":
        return DaskScheduler(min(workers, max(tasks, 1)))
    return DaskScheduler(workers, address=spec)

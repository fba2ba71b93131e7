"""sengine.scheduler's schedulers one by one, for the mutation run of docs/mutation.md.

test_batch and test_shard run the schedulers under whole batches and sharded cities; these pin each
scheduler's attributes, outcomes, shared object, failures, interrupt and closing, and the
``--scheduler`` check, in a few seconds (a Dask LocalCluster of forked processes, and one in this
process standing for a remote cluster).
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import signal
import sys
import threading
import time

import pytest

from sengine import parallel
from sengine.errors import ConfigError, SEngineError
from sengine.scheduler import (
    DaskScheduler,
    InProcess,
    LocalProcesses,
    Scheduler,
    check_scheduler,
    make_scheduler,
)


def _task(x, shared=None):
    """A task: its argument squared, this process and what it knows of its worker."""
    if x == 3:
        raise ValueError("three")
    if shared is not None:
        x = x + shared["add"]
    return (
        x * x,
        os.getpid(),
        parallel.in_worker(),
        signal.getsignal(signal.SIGINT) == signal.SIG_IGN,
        signal.getsignal(signal.SIGTERM) == signal.SIG_DFL,
    )


def _dies(x):
    if x == 1:
        os._exit(7)
    return x


def _sleeps(x):
    if x:
        time.sleep(60)
    return x


_release = threading.Event()


def _waits(x):
    """Task 0 returns at once, the others wait for the test (Dask threads of this process)."""
    if x:
        _release.wait(30)
    return x


def _by_index(outcomes):
    return sorted(outcomes, key=lambda o: o[0])


class _Recorder(Scheduler):
    def __init__(self):
        self.calls = []

    def stop(self):
        self.calls.append("stop")

    def close(self):
        self.calls.append("close")


def test_the_base_scheduler_and_its_context():
    base = Scheduler()
    assert (base.name, base.slots, base.task_workers, base.inherits) == ("local", 1, 1, True)
    with pytest.raises(NotImplementedError):
        base.run(_task, [1])
    assert base.stop() is None and base.close() is None
    rec = _Recorder()
    with rec as entered:
        assert entered is rec
    assert rec.calls == ["close"]  # a normal end: close only
    rec = _Recorder()
    with pytest.raises(ValueError), rec:
        raise ValueError("a task's error")
    assert rec.calls == ["close"]  # an Exception is not an interrupt
    rec = _Recorder()
    with pytest.raises(KeyboardInterrupt), rec:
        raise KeyboardInterrupt
    assert rec.calls == ["stop", "close"]  # an interrupt kills the tasks first


def test_in_process_runs_every_task_here_in_turn():
    sched = InProcess(3)
    assert sched.task_workers == 3 and sched.slots == 1 and sched.inherits is True
    assert InProcess().task_workers == 1 and InProcess(0).task_workers == 1 and InProcess("2").task_workers == 2
    outcomes = list(sched.run(_task, [0, 1, 2, 3, 4]))
    assert [(i, ok) for i, ok, _ in outcomes] == [(0, True), (1, True), (2, True), (3, False), (4, True)]
    assert [v[:3] for _, ok, v in outcomes if ok] == [(x * x, os.getpid(), False) for x in (0, 1, 2, 4)]
    assert isinstance(outcomes[3][2], ValueError) and str(outcomes[3][2]) == "three"
    shared = [v[0] for _, ok, v in sched.run(_task, [1, 2], shared={"add": 10}) if ok]
    assert shared == [121, 144]
    # a generator: each task runs when its outcome is asked for
    seen = []
    gen = sched.run(seen.append, ["a", "b"])
    assert seen == []
    assert next(gen) == (0, True, None) and seen == ["a"]


def test_local_processes_run_tasks_in_set_up_workers():
    with LocalProcesses(2) as sched:
        assert (sched.slots, sched.task_workers, sched.inherits, sched.name) == (2, 1, True, "local")
        outcomes = _by_index(sched.run(_task, range(6)))
        assert [(i, ok) for i, ok, _ in outcomes] == [(0, True), (1, True), (2, True), (3, False), (4, True), (5, True)]
        assert isinstance(outcomes[3][2], ValueError) and str(outcomes[3][2]) == "three"
        values = [v for _, ok, v in outcomes if ok]
        assert [v[0] for v in values] == [0, 1, 4, 16, 25]
        assert {v[1] for v in values} & {os.getpid()} == set() and len({v[1] for v in values}) <= 2
        assert all(v[2:] == (True, True, True) for v in values)  # worker_setup ran in each worker
        assert [v[0] for _, ok, v in _by_index(sched.run(_task, [1, 2], shared={"add": 10}))] == [121, 144]
    assert multiprocessing.active_children() == []  # closed: its workers are gone
    assert LocalProcesses(0).slots == 1 and LocalProcesses("3").slots == 3


_MARK = {"value": "as imported"}


def _mark(_):
    return _MARK["value"], parallel.in_worker()


def test_local_processes_fork_here_and_spawn_where_forking_is_unsafe(monkeypatch):
    """Forked workers see this process's memory as it is now; spawned ones import the modules afresh."""
    monkeypatch.setitem(_MARK, "value", "changed here")
    with LocalProcesses(3) as sched:
        assert sched._pool._max_workers == 3  # the pool has as many processes as slots
        assert [v for _, _, v in sched.run(_mark, [0])] == [("changed here", True)]
    monkeypatch.setattr(parallel, "can_fork", lambda: False)  # as on macOS
    with LocalProcesses(1) as sched:
        assert sched.inherits is False and sched._pool._max_workers == 1
        assert [v for _, _, v in sched.run(_mark, [0])] == [("as imported", True)]
    assert multiprocessing.active_children() == []


def _writes(arg):
    folder, i = arg
    time.sleep(0.02)
    (folder / f"{i}.txt").write_text(str(i))
    return i


def test_local_processes_close_cancels_the_tasks_not_started(tmp_path):
    """A caller that stops reading (its own error) leaves the waiting tasks unrun: close cancels them."""
    sched = LocalProcesses(1)
    gen = sched.run(_writes, [(tmp_path, i) for i in range(30)])
    with pytest.raises(ValueError), sched:
        assert next(gen) == (0, True, 0)
        raise ValueError("the caller's own error")
    written = len(list(tmp_path.iterdir()))
    assert 1 <= written < 30  # the tasks already handed to the worker, not all 30
    assert multiprocessing.active_children() == []


def test_local_processes_a_dead_worker_is_an_error():
    with LocalProcesses(1) as sched:
        outcomes = _by_index(sched.run(_dies, [0, 1]))
    assert outcomes[0] == (0, True, 0)
    i, ok, exc = outcomes[1]
    assert (i, ok, type(exc)) == (1, False, RuntimeError)
    assert str(exc) == "a worker process died (killed, or out of memory) while running it"
    assert multiprocessing.active_children() == []


def test_local_processes_stop_kills_running_tasks():
    sched = LocalProcesses(2)
    gen = sched.run(_sleeps, [0, 1, 2])  # task 0 returns at once, 1 and 2 sleep
    assert next(gen) == (0, True, 0)
    procs = list(sched._pool._processes.values())
    assert len(procs) == 2
    t = time.monotonic()
    with pytest.raises(KeyboardInterrupt), sched:
        raise KeyboardInterrupt  # as a batch's interrupt: stop, then close
    assert time.monotonic() - t < 10  # not the tasks' 60 s
    assert [p.exitcode for p in procs] == [-signal.SIGKILL] * 2
    rest = sorted(gen, key=lambda o: o[0])
    assert [(i, ok, type(v)) for i, ok, v in rest] == [(1, False, RuntimeError), (2, False, RuntimeError)]


def test_check_scheduler_accepts_and_refuses():
    assert check_scheduler(" local ") == "local"
    assert check_scheduler("dask\n") == "dask"
    for scheme in ("tcp", "tls", "inproc", "ucx", "ws", "wss"):
        assert check_scheduler(f" {scheme}://10.0.0.1:8786") == f"{scheme}://10.0.0.1:8786"
    for bad in ("yarn", "tcp://", "tcp://a b", "xtcp://a:1", "http://a:1", "Local", "dask2"):
        with pytest.raises(ConfigError) as err:
            check_scheduler(bad)
        assert str(err.value) == (
            f"--scheduler {bad.strip()!r} is not one of local, dask or tcp://HOST:PORT (a Dask scheduler)"
        )


def test_without_dask_its_schedulers_are_refused(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed raises ImportError
    assert check_scheduler("local") == "local"
    for spec in ("dask", "tcp://h:1"):
        with pytest.raises(ConfigError) as err:
            check_scheduler(spec)
        assert str(err.value) == f"--scheduler {spec} needs Dask's distributed scheduler: pip install 'sengine[dask]'"
    with pytest.raises(ConfigError) as err:
        DaskScheduler(1)
    assert str(err.value) == "--scheduler dask needs Dask's distributed scheduler: pip install 'sengine[dask]'"
    with pytest.raises(ConfigError):
        make_scheduler("dask", 2, 2)
    assert isinstance(make_scheduler("local", 2, 2), LocalProcesses)  # local never needs Dask


def test_make_scheduler_local():
    for workers, tasks in ((1, 9), (4, 1), (0, 5), (3, 0)):
        sched = make_scheduler(" local", workers, tasks)
        assert type(sched) is InProcess and sched.task_workers == max(1, workers)
    with make_scheduler("local", 4, 3) as sched:
        assert type(sched) is LocalProcesses and sched.slots == 3
    with make_scheduler("local", 2, 5) as sched:
        assert type(sched) is LocalProcesses and sched.slots == 2
    with pytest.raises(ConfigError):
        make_scheduler("yarn", 2, 2)


@pytest.fixture(scope="module")
def distributed():
    return pytest.importorskip("distributed")


def _handlers(_=None):
    return signal.getsignal(signal.SIGINT) == signal.SIG_IGN, signal.getsignal(signal.SIGTERM) == signal.SIG_DFL


def test_dask_local_cluster(distributed, monkeypatch):
    monkeypatch.setitem(_MARK, "value", "changed here")
    with make_scheduler("dask", 3, 1) as sched:  # min(workers, tasks): one process
        assert type(sched) is DaskScheduler and (sched.name, sched.slots, sched.inherits) == ("dask", 1, True)
        workers = sched._client.scheduler_info()["workers"].values()
        assert [w["nthreads"] for w in workers] == [1]  # one task at a time per process
        # no dashboard: the scheduler's plain HTTP routes listen on the loopback only, not on every interface
        http = sched._cluster.scheduler.http_server
        assert {sock.getsockname()[0] for sock in http._sockets.values()} == {"127.0.0.1"}
        # Dask's own log lines in the workers are silenced (sengine's logger is not at debug level)
        assert [v for _, _, v in sched.run(_nanny_log_level, [0])] == [logging.CRITICAL]
        outcomes = _by_index(sched.run(_task, [2, 3, 4]))
        assert [(i, ok) for i, ok, _ in outcomes] == [(0, True), (1, False), (2, True)]
        assert isinstance(outcomes[1][2], ValueError) and str(outcomes[1][2]) == "three"
        assert [v[:3] for _, ok, v in outcomes if ok][0][0] == 4 and outcomes[2][2][0] == 16
        assert outcomes[0][2][1] != os.getpid() and outcomes[0][2][2] is True  # a Dask task: in_worker
        assert outcomes[0][2][3:] == (True, True)  # worker_signals ran on the forked worker
        assert [v[0] for _, _, v in _by_index(sched.run(_task, [1, 2], shared={"add": 10}))] == [121, 144]
        # the LocalCluster's settings reach its worker, forked from this process as it was when it started
        [(_, _, seen)] = list(sched.run(_dask_view, [0]))
        assert seen == ("changed here", True, False, "500ms", "fork")
        cluster, client = sched._cluster, sched._client
    assert sched._cluster is None and client.status == "closed" and cluster.status.name == "closed"
    with make_scheduler("dask", 2, 0) as sched:  # no task: still one process
        assert sched.slots == 1
    with DaskScheduler(0) as sched:
        assert sched.slots == 1


def _dask_view(_):
    import dask

    return (
        _MARK["value"],
        parallel.in_worker(),
        dask.config.get("distributed.worker.profile.enabled"),
        dask.config.get("distributed.admin.tick.interval"),
        dask.config.get("distributed.worker.multiprocessing-method"),
    )


def test_dask_local_cluster_spawned_where_forking_is_unsafe(distributed, monkeypatch):
    """Without fork, the LocalCluster's workers start as Dask's configuration says (spawn): they import afresh."""
    import dask

    monkeypatch.setattr(parallel, "can_fork", lambda: False)
    monkeypatch.setitem(_MARK, "value", "changed here")
    with dask.config.set({"distributed.worker.multiprocessing-method": "spawn"}), DaskScheduler(1) as sched:
        assert sched.inherits is False and sched.slots == 1
        [(_, ok, seen)] = list(sched.run(_dask_view, [0]))
    assert ok and seen[:2] == ("as imported", True)


def _nanny_log_level(_):
    return logging.getLogger("distributed.nanny").getEffectiveLevel()


def test_dask_local_cluster_stop(distributed, caplog):
    caplog.set_level(logging.DEBUG, logger="sengine.scheduler")  # sengine at debug level: Dask's lines shown
    sched = DaskScheduler(1)
    assert [v for _, _, v in sched.run(_nanny_log_level, [0])] == [logging.DEBUG]
    cluster, client = sched._cluster, sched._client
    with pytest.raises(KeyboardInterrupt), sched:
        raise KeyboardInterrupt
    assert sched._cluster is None and cluster.status.name == "closed" and client.status == "closed"
    assert logging.root.manager.disable == logging.NOTSET  # logging is back on after the stop


def test_dask_scheduler_at_an_address(distributed):
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=2, processes=False, dashboard_address=None
    ) as cluster:
        address = cluster.scheduler_address
        with make_scheduler(address, 5, 1) as sched:
            assert type(sched) is DaskScheduler
            assert (sched.name, sched.slots, sched.inherits, sched._cluster) == (address, 4, False, None)
            outcomes = _by_index(sched.run(_task, [2, 3]))
            assert outcomes[0][:2] == (0, True) and outcomes[0][2][0] == 4 and outcomes[0][2][1] == os.getpid()
            assert outcomes[1][:2] == (1, False) and str(outcomes[1][2]) == "three"
            client = sched._client
        assert client.status == "closed" and cluster.status.name == "running"  # not ours: left running
        with DaskScheduler(1, address=address) as sched:
            # the same task twice is run twice (pure=False), each outcome under its own index
            assert sorted(i for i, _, _ in sched.run(_task, [2, 2])) == [0, 1]
            # the shared object is on every worker once, under a key of this run's own (not its hash)
            keys = []
            for _ in range(2):
                gen = sched.run(_task, [1], shared={"add": 10})
                assert next(gen)[2][0] == 121
                holders = {}
                for worker, held in sched._client.has_what().items():
                    for key in held:
                        if str(key).startswith("dict-"):
                            holders.setdefault(key, set()).add(worker)
                assert len(holders) == 1 and len(next(iter(holders.values()))) == 2
                keys += list(holders)
                gen.close()
            assert keys[0] != keys[1]
        # an interrupt on a shared cluster cancels this scheduler's tasks, and leaves the cluster up
        sched = DaskScheduler(1, address=address)
        gen = sched.run(_waits, [0, 1])
        assert next(gen) == (0, True, 0)  # task 1 waits
        futures = list(sched._futures)
        try:
            with pytest.raises(KeyboardInterrupt), sched:
                raise KeyboardInterrupt
            assert [f.status for f in futures] == ["cancelled", "cancelled"]
            assert sched._client.status == "closed" and cluster.status.name == "running"
        finally:
            _release.set()
    with distributed.LocalCluster(n_workers=0, processes=False, dashboard_address=None) as empty:
        with DaskScheduler(3, address=empty.scheduler_address) as sched:
            assert sched.slots == 1  # no worker yet: still one slot
    with pytest.raises(SEngineError) as err:
        DaskScheduler(1, address="inproc://nowhere/1/2")
    assert str(err.value).startswith("cannot reach the Dask scheduler at inproc://nowhere/1/2: ")

"""sengine.parallel's helpers and Background, for the mutation run of docs/mutation.md.

test_parallel runs ``run_jobs`` end to end; these pin the worker set-up (flag, signals, dying with
its parent), killing a pool's processes, the cores count and :class:`Background` (a result, an
exception, a process that died, a job stopped while it runs).
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import sys
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from types import SimpleNamespace

import pytest

from sengine import parallel
from sengine.errors import InputDataError
from sengine.parallel import Background, available_cores, can_fork, in_dask_task, in_worker, kill_workers

# the platform test itself, not can_fork(): a wrong can_fork() must fail here, not skip every test
pytestmark = pytest.mark.skipif(not hasattr(os, "fork") or sys.platform == "darwin", reason="forking is not safe here")


def _in_child(fn) -> tuple[int, str]:
    """Run ``fn`` in a forked child; its exit status and what it wrote to the pipe."""
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child
        code = 0
        try:
            os.close(r)
            os.write(w, repr(fn()).encode())
        except BaseException as exc:  # noqa: BLE001 (reported to the parent)
            os.write(w, f"raised {type(exc).__name__}".encode())
            code = 9
        finally:
            os._exit(code)
    os.close(w)
    out = b""
    while chunk := os.read(r, 4096):
        out += chunk
    os.close(r)
    _, status = os.waitpid(pid, 0)
    return os.waitstatus_to_exitcode(status), out.decode()


def test_cores_fork_and_worker_flags():
    assert available_cores() == len(os.sched_getaffinity(0)) >= 1
    assert can_fork() is (hasattr(os, "fork") and sys.platform != "darwin")
    assert in_worker() is False and parallel._in_worker is False
    assert in_dask_task() is ("distributed" in sys.modules and in_dask_task())


def test_cores_without_an_affinity_call(monkeypatch):
    """macOS and Windows have no sched_getaffinity: the cores count, or 1 when it is unknown."""
    monkeypatch.delattr(os, "sched_getaffinity")
    monkeypatch.setattr(os, "cpu_count", lambda: 6)
    assert available_cores() == 6
    monkeypatch.setattr(os, "cpu_count", lambda: None)
    assert available_cores() == 1


def test_can_fork_is_false_on_macos_and_without_fork(monkeypatch):
    with monkeypatch.context() as m:
        m.setattr(sys, "platform", "darwin")  # macOS lists fork, but its libraries are not fork-safe
        assert can_fork() is False
    assert can_fork() is True
    monkeypatch.delattr(os, "fork")  # Windows
    assert can_fork() is False


def test_worker_setup_marks_the_process_and_sets_its_signals():
    def child():
        parallel.worker_setup(os.getppid())
        return (
            in_worker(),
            signal.getsignal(signal.SIGINT) == signal.SIG_IGN,
            signal.getsignal(signal.SIGTERM) == signal.SIG_DFL,
        )

    assert _in_child(child) == (0, "(True, True, True)")
    # a worker whose parent is not the one it was told (it died before the worker was set up) exits
    code, out = _in_child(lambda: parallel.worker_setup(os.getppid() + 1))
    assert (code, out) == (1, "")


def test_worker_dies_with_its_parent():
    """prctl(PR_SET_PDEATHSIG, SIGKILL): the grandchild is killed when the child that set it up ends."""
    if not sys.platform.startswith("linux"):
        pytest.skip("Linux only")
    r, w = os.pipe()
    child = os.fork()
    if child == 0:  # the child: it starts a worker, tells its pid and ends
        code = 0
        try:
            pid = os.fork()
            if pid == 0:  # the grandchild: a worker of the child
                parallel.worker_setup(os.getppid())
                os.write(w, b"set\n")
                time.sleep(30)
                os._exit(0)
            os.write(w, f"{pid}\n".encode())
            time.sleep(0.3)
        except BaseException:  # noqa: BLE001 (the parent sees no pid)
            code = 9
        finally:
            os._exit(code)
    os.close(w)  # the grandchild holds the pipe open too: read lines, not to the end
    _, status = os.waitpid(child, 0)
    lines = b""
    while lines.count(b"\n") < 2:
        chunk = os.read(r, 100)
        if not chunk:
            break
        lines += chunk
    os.close(r)
    words = lines.split()
    assert os.waitstatus_to_exitcode(status) == 0 and len(words) == 2 and b"set" in words
    grandchild = int(next(x for x in words if x != b"set"))
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline:
        try:
            os.kill(grandchild, 0)
        except ProcessLookupError:
            break
        time.sleep(0.02)
    else:
        os.kill(grandchild, signal.SIGKILL)
        raise AssertionError("the worker outlived its parent")


def test_worker_signals_only_in_the_main_thread():
    saved = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    try:
        got = []
        t = threading.Thread(target=lambda: got.append(parallel.worker_signals()))
        t.start()
        t.join()
        assert got == [False] and signal.getsignal(signal.SIGINT) == saved[0]
        assert parallel.worker_signals() is True
        assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN
        assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL
    finally:
        signal.signal(signal.SIGINT, saved[0])
        signal.signal(signal.SIGTERM, saved[1])


def test_kill_workers_stops_the_pool_processes_at_once():
    pool = ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("fork"))
    procs = []
    try:
        futures = [pool.submit(time.sleep, 60) for _ in range(2)]
        while len(pool._processes) < 2:
            time.sleep(0.01)
        procs = list(pool._processes.values())
        t = time.monotonic()
        kill_workers(pool)
        assert time.monotonic() - t < 10
        # the pool's own thread may reap a worker at the same moment (its waitpid wins, ours sees
        # ECHILD and reads no exit code yet): give it a moment to record the code
        deadline = time.monotonic() + 10
        while any(p.exitcode is None for p in procs) and time.monotonic() < deadline:
            time.sleep(0.01)
        # the first kill breaks the pool, whose thread may terminate (SIGTERM) the other before we kill it
        codes = [(p.is_alive(), p.exitcode) for p in procs]
        assert codes[0] == (False, -signal.SIGKILL)
        assert codes[1] in ((False, -signal.SIGKILL), (False, -signal.SIGTERM))
        assert all(f.exception() is not None for f in futures)
    finally:
        for p in procs:  # whatever kill_workers did: no sleeping worker is left behind
            p.kill()
        pool.shutdown(wait=True, cancel_futures=True)
    # Python 3.14's pool kills its own workers: only that is called
    called = []
    kill_workers(SimpleNamespace(kill_workers=lambda: called.append("pool"), _processes={1: None}))
    assert called == ["pool"]
    kill_workers(SimpleNamespace())  # a pool without processes: nothing to do
    kill_workers(SimpleNamespace(_processes=None))


def _value():
    return ("made", os.getpid())


def _fails():
    raise InputDataError("bad map", where="m.png")


def _dies():
    os._exit(5)


def _sleeps():
    time.sleep(60)
    return "late"


def test_background_result_in_another_process():
    assert Background.startable(2) is True
    assert Background.startable(1) is False and Background.startable("3") is True
    job = Background(_value)
    value, pid = job.result()
    assert value == "made" and pid != os.getpid()
    assert parallel._early == {}  # the job is not kept here once forked
    assert multiprocessing.active_children() == []  # result() closes the pool


def test_background_errors_and_death():
    with pytest.raises(InputDataError, match="^m.png: bad map$"):
        Background(_fails).result()
    assert Background(_dies).result() is None  # the caller then does the work itself
    assert multiprocessing.active_children() == []


def _set_up():
    return in_worker(), signal.getsignal(signal.SIGINT) == signal.SIG_IGN, os.getppid()


def test_background_runs_in_one_set_up_worker():
    job = Background(_set_up)
    assert len(job._pool._processes) == 1  # one process, not one per core
    assert job.result() == (True, True, os.getpid())  # worker_setup ran in it


def test_background_close_stops_a_running_job():
    job = Background(_sleeps)
    time.sleep(0.2)
    t = time.monotonic()
    job.close()
    assert time.monotonic() - t < 10
    assert multiprocessing.active_children() == []


def test_startable_is_false_in_a_worker_and_while_jobs_run():
    def child():
        parallel.worker_setup(os.getppid())
        return Background.startable(4)

    assert _in_child(child) == (0, "False")
    assert parallel.run_jobs([lambda: Background.startable(4)] * 2, 1) == [True, True]
    parallel._running = True
    try:
        assert Background.startable(4) is False
    finally:
        parallel._running = False


# -- run_jobs: what happens while and after jobs fail --------------------------------------


def _sleep_then(seconds, value=None, fail=False, mark=None):
    def run():
        time.sleep(seconds)
        if mark is not None:
            mark.joinpath(f"{os.getpid()}-{time.monotonic_ns()}").write_text("")
        if fail:
            raise InputDataError("job failed", where="w")
        return value

    return run


def test_jobs_this_process_took_do_not_break_the_wait_for_a_long_worker_job():
    """The pool's futures of jobs run here are cancelled: waiting for a long worker job must skip them."""
    jobs = [_sleep_then(0.05, 0), _sleep_then(0.6, 1)] + [_sleep_then(0.0, i) for i in range(2, 6)]
    assert parallel.run_jobs(jobs, 2) == [0, 1, 2, 3, 4, 5]
    assert multiprocessing.active_children() == []  # the workers are gone when run_jobs returns


def test_a_worker_failure_stops_the_jobs_not_yet_taken(tmp_path):
    """Job 1 fails in the worker at once; this process, busy with job 0, then cancels the rest."""
    jobs = [_sleep_then(0.6, 0), _sleep_then(0.0, 1, fail=True)]
    jobs += [_sleep_then(0.25, i, mark=tmp_path) for i in range(2, 12)]
    with pytest.raises(InputDataError, match="^w: job failed$"):
        parallel.run_jobs(jobs, 2)
    # the worker ran some jobs while job 0 ran here (0.6 s / 0.25 s, plus those already queued), not all
    assert len(os.listdir(tmp_path)) < 10
    assert multiprocessing.active_children() == []


def _first_waits_for(mark):
    def run():  # job 0, here: until the worker has finished job 1 (and its future is marked done)
        deadline = time.monotonic() + 5
        while not mark.exists() and time.monotonic() < deadline:
            time.sleep(0.01)
        time.sleep(0.3)
        return 0, os.getpid()

    return run


def _second_marks(mark):
    def run():  # job 1, taken by the worker while job 0 runs here
        mark.write_text("")
        return 1, os.getpid()

    return run


def _quick_here(i):
    def run():  # slow in a worker, instant here: this process takes some of them
        if parallel.in_worker():
            time.sleep(0.2)
        return i, os.getpid()

    return run


def test_this_process_goes_on_taking_jobs_after_a_worker_finished_one(tmp_path):
    """A worker's success neither stops this process taking jobs nor makes it wait for the workers."""
    mark = tmp_path / "job1"
    jobs = [_first_waits_for(mark), _second_marks(mark)] + [_quick_here(i) for i in range(2, 10)]
    out = parallel.run_jobs(jobs, 2)
    assert [i for i, _ in out] == list(range(10))
    assert out[0][1] == os.getpid() and mark.exists()
    assert sum(pid == os.getpid() for _, pid in out[2:]) >= 1  # not all left to the busy worker


class _Seen:
    def __init__(self, finished):
        self.finished = finished
        self.advances = []

    def start(self, i, n, node_id, type_):
        pass

    def advance(self, done, total, unit):
        self.advances.append((done, self.finished.exists()))


def _counts_later(finished):
    def run():  # in the worker (or here, if this process took it): counts after a while, then ends
        from sengine import progress

        time.sleep(0.8)  # after the first polls of the wait (0.2 s apart)
        progress.advance(5)  # counted in the shared integer the parent reads
        time.sleep(0.6)
        finished.write_text("")
        return 2, os.getpid()

    return run


def test_while_waiting_for_the_workers_their_counts_are_reported(tmp_path):
    """run_jobs polls the running step's count as it waits: a worker's count shows before its job ends."""
    from sengine import progress

    seen = _Seen(tmp_path / "finished")
    with progress.step(progress.as_progress(seen), 1, 1, "n", "t"):
        # job 1 ends at once in the worker; the wait goes on polling for job 2 after it
        mark = tmp_path / "job1"
        jobs = [_first_waits_for(mark), _second_marks(mark), _counts_later(seen.finished)]
        pids = [pid for _, pid in parallel.run_jobs(jobs, 2)]
    assert pids[0] == os.getpid() and pids[1] != os.getpid() and pids[2] == pids[1]
    assert seen.advances[0] == (5, False)  # reported while job 2 still ran


def test_in_a_dask_task_jobs_run_in_turn():
    distributed = pytest.importorskip("distributed")
    assert parallel.in_dask_task() is False  # imported, but not in a task
    with distributed.Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=None) as client:
        assert client.submit(parallel.in_dask_task, pure=False).result() is True
        assert client.submit(parallel.in_worker, pure=False).result() is True
        pids = client.submit(lambda: parallel.run_jobs([os.getpid] * 3, 2), pure=False).result()
        assert pids == [os.getpid()] * 3  # threads of this process: no fork within a Dask task
    assert parallel.in_dask_task() is False

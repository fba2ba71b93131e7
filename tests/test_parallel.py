"""sengine.parallel.run_jobs: forked workers and this process share the jobs; results and errors as in one process."""

from __future__ import annotations

import os
import sys
import time

import pytest

from sengine.errors import InputDataError
from sengine.parallel import in_worker, run_jobs

# the platform test itself, not can_fork(): a wrong can_fork() must fail here, not skip every test
pytestmark = pytest.mark.skipif(not hasattr(os, "fork") or sys.platform == "darwin", reason="forking is not safe here")


def _square(i):
    def run():
        time.sleep(0.01)  # long enough for every process to get some
        return i * i, os.getpid()

    return run


@pytest.mark.parametrize("workers", [1, 2, 3])
def test_results_come_back_in_job_order(workers):
    out = run_jobs([_square(i) for i in range(20)], workers)
    assert [r for r, _ in out] == [i * i for i in range(20)]
    pids = {pid for _, pid in out}
    assert os.getpid() in pids  # this process takes jobs too
    assert len(pids) <= workers


def test_jobs_write_the_same_files_in_any_process(tmp_path):
    def write(i):
        return lambda: (tmp_path / f"{i}.txt").write_text(str(i) * i)

    assert run_jobs([write(i) for i in range(8)], 2) == [i for i in range(8)]
    assert sorted(p.read_text() for p in tmp_path.iterdir()) == sorted(str(i) * i for i in range(8))


def test_a_failing_job_raises_its_own_error_here():
    def job(i):
        def run():
            if i == 3:
                raise InputDataError("bad file", where="x.osm")
            return i

        return run

    for workers in (1, 2):
        with pytest.raises(InputDataError, match="x.osm: bad file"):
            run_jobs([job(i) for i in range(6)], workers)


def test_a_worker_that_dies_is_an_error_not_a_missing_result():
    def job():
        if in_worker():
            os._exit(3)
        time.sleep(0.5)  # here: slow, so that the worker surely takes a job and dies
        return "here"

    with pytest.raises(RuntimeError, match="worker process died"):
        run_jobs([job] * 3, 2)


def test_no_processes_within_processes():
    def outer():
        time.sleep(0.2)  # long enough for the worker to start and take an outer job
        return os.getpid(), run_jobs([os.getpid] * 3, 2)

    out = run_jobs([outer] * 4, 2)
    for pid, inner in out:
        assert inner == [pid] * 3  # the inner jobs ran in turn in the process that took the outer job
    assert len({pid for pid, _ in out}) == 2
    assert len({pid for pid, _ in run_jobs([outer] * 2, 2)}) == 2  # and this process forks again afterwards


def test_without_a_process_to_spare_the_jobs_run_here(monkeypatch):
    def no_fork():
        raise BlockingIOError(11, "Resource temporarily unavailable")

    monkeypatch.setattr(os, "fork", no_fork)
    assert [r for r, pid in run_jobs([_square(i) for i in range(5)], 2)] == [0, 1, 4, 9, 16]


def test_an_interrupt_here_kills_the_workers_at_once():
    psutil = pytest.importorskip("psutil")

    def job(i):
        def run():
            time.sleep(0.5 if i == 0 else 60)
            if i == 0:
                raise KeyboardInterrupt  # Ctrl-C while this process runs its job
            return i

        return run

    t = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        run_jobs([job(i) for i in range(4)], 3)
    assert time.monotonic() - t < 10  # not the 60 s the workers' jobs would take
    # multiprocessing's resource tracker, started once by any spawned process, lives as long as this one
    alive = [
        p
        for p in psutil.Process().children()
        if p.status() != psutil.STATUS_ZOMBIE and "resource_tracker" not in " ".join(p.cmdline())
    ]
    assert alive == []

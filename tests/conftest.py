"""Shared fixtures: the repository's folders and a CLI runner."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import settings

# CI explores the same examples every run (a red CI is then reproducible);
# a developer's run draws new ones.  "The same" for the same selection of tests
# only: Hypothesis also draws literal constants of every local module imported
# so far, so a module run alone explores other examples than the whole suite.
# A failure seen only in the suite is a real input: print_blob gives the
# @reproduce_failure line that replays it alone.
settings.register_profile("ci", derandomize=True, deadline=None, print_blob=True)
settings.register_profile("dev", deadline=None, print_blob=True)
settings.load_profile("ci" if os.environ.get("CI") else "dev")

ROOT = Path(__file__).resolve().parent.parent
FIXTURES = Path(__file__).resolve().parent / "fixtures"
CONFIGS = ROOT / "configs"
DATA = CONFIGS / "data"


@pytest.fixture(scope="session")
def root() -> Path:
    return ROOT


@pytest.fixture(scope="session")
def fixtures() -> Path:
    return FIXTURES


def run_cli(*args: str, cwd: Path | None = None, env: dict | None = None) -> subprocess.CompletedProcess:
    """Run ``python -m sengine ARGS`` in a fresh process; capture text output."""
    return subprocess.run(
        [sys.executable, "-m", "sengine", *map(str, args)],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )


@pytest.fixture
def cli():
    return run_cli


@pytest.fixture(scope="module")
def remote_cluster():
    """The address of a Dask cluster whose workers share nothing with this process.

    Two worker processes spawned (not forked) from a fresh interpreter, as on
    another machine: they see the same file system, nothing of the caller's
    memory.  ``--scheduler tcp://...`` joins it.
    """
    pytest.importorskip("distributed")
    import dask
    from distributed import LocalCluster

    with dask.config.set({"distributed.worker.multiprocessing-method": "spawn"}):
        cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    try:
        yield cluster.scheduler_address
    finally:
        cluster.close()

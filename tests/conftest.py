"""Shared fixtures: the repository's folders and a CLI runner."""

from __future__ import annotations

import os
import signal
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


def interruptible() -> None:
    """``preexec_fn`` of a child a test interrupts: SIGINT at its default, whoever started the tests.

    A shell starts a background job (``.ci/run &``) with SIGINT ignored, every
    process below it inherits that, and Python then installs no
    KeyboardInterrupt handler: the child would never see the test's Ctrl-C.
    """
    signal.signal(signal.SIGINT, signal.SIG_DFL)


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
    """The address of a Dask cluster that shares nothing with this process but the file system.

    A ``dask scheduler`` and a ``dask worker`` of two processes, started as
    separate programs in their own session (as on another machine) and
    killed with their whole process group afterwards, so that no process of
    theirs outlives the tests.  ``--scheduler tcp://...`` joins it.
    """
    pytest.importorskip("distributed")
    import signal
    import socket
    import time

    from distributed import Client

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    address = f"tcp://127.0.0.1:{port}"
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL, "start_new_session": True}
    cli = [sys.executable, "-m"]
    procs = [
        subprocess.Popen(
            [*cli, "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
            **quiet,
        )
    ]
    try:
        procs.append(
            subprocess.Popen(
                [*cli, "distributed.cli.dask_worker", address, "--nworkers", "2", "--nthreads", "1", "--no-dashboard"],
                **quiet,
            )
        )
        with Client(address, timeout=60) as client:
            client.wait_for_workers(2, timeout=120)
        yield address
    finally:
        for proc in reversed(procs):
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            proc.wait(timeout=30)
        time.sleep(0.1)

"""Headless Chromium for the viewer's tests and benchmark: Debian's ``chromium`` driven by Playwright.

Playwright's own browsers are never installed (``playwright install``
downloads a build of its own); the system's ``/usr/bin/chromium`` is used
through ``executable_path``.  A test skips only when Chromium truly cannot
run here (Playwright or Chromium not installed, or Chromium failing to
start), and says why; under ``CI=true`` each of those fails the test
instead (``.ci/run`` installs both).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

#: Flags that work on a closed network in a container: no sandbox, software GL, nothing fetched in the background.
FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    # WebGL on the CPU (SwiftShader): since Chromium 137 it must be asked for
    "--enable-unsafe-swiftshader",
    "--use-angle=swiftshader",
)


def chromium_path() -> str | None:
    for name in (os.environ.get("SENGINE_CHROMIUM"), "/usr/bin/chromium", shutil.which("chromium")):
        if name and Path(name).exists():
            return name
    return None


def _missing(what: str, why: str = "is not installed here"):
    if os.environ.get("CI") == "true":
        pytest.fail(f"{what} {why}: CI must run the browser tests (.ci/run installs it)")
    pytest.skip(f"{what} {why}")


@contextlib.contextmanager
def browser(viewport=(1280, 800)) -> Iterator:
    """A Playwright browser context of Debian's Chromium with a new empty profile."""
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        _missing("playwright (pip)")
    path = chromium_path()
    if path is None:
        _missing("chromium (/usr/bin/chromium)")
    with sync_playwright() as p, tempfile.TemporaryDirectory(prefix="sengine-chromium-") as profile:
        try:
            ctx = p.chromium.launch_persistent_context(
                profile,
                executable_path=path,
                args=list(FLAGS),
                headless=True,
                viewport={"width": viewport[0], "height": viewport[1]},
                timeout=120_000,
            )
        except Exception as exc:  # noqa: BLE001 (Playwright's errors: the browser would not start)
            first = next((line for line in str(exc).splitlines() if line.strip()), type(exc).__name__)
            _missing(f"chromium ({path})", f"does not start: {first}")
        try:
            yield ctx
        finally:
            ctx.close()


def open_page(ctx, url: str, timeout: float = 180.0):
    """A page at ``url`` once the viewer has started; its errors are collected in ``page.errors``."""
    page = ctx.new_page()
    page.errors = []
    page.on("pageerror", lambda e: page.errors.append(str(e)))
    page.goto(url, wait_until="commit", timeout=timeout * 1000)
    page.wait_for_function("document.body.dataset.ready", timeout=timeout * 1000)
    state = page.evaluate("document.body.dataset.ready")
    if state != "1":
        raise AssertionError(f"the viewer did not start: {page.errors or page.inner_text('#error')}")
    return page

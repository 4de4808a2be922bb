"""Shared fixtures: one backend for the whole run, a private reference cache, and the
headless Chromium of the browser tests."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

#: Debian's Chromium (``bin/setup.sh --test`` installs it); else the first on PATH.
CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]


@pytest.fixture(scope="session", autouse=True)
def _backend(tmp_path_factory):
    """Select the backend once (as the CLI does) and keep the user's cache untouched."""
    os.environ["RASTER_ORACLE_CACHE"] = str(tmp_path_factory.mktemp("cache"))
    from raster_oracle.scenes import backend

    info = backend.select()
    _seed_self_check(info.variant)
    return info


def _seed_self_check(variant: str) -> None:
    """A passed self-check verdict for the suite's backend, in force in this process and
    cached for the command lines the tests start: the suite itself checks the backend, and
    running the battery in every worker would cost each one its seconds. Tests of the
    self-check use their own cache folder and clear the verdict in force."""
    import json

    from raster_oracle.oracle.certify import verdict as V
    from raster_oracle.scenes import backend

    key = V.machine_key(variant)
    record = {"key": key, "passed": True, "failed": [], "checks": [], "checked_at": None}
    record["seeded_by"] = "tests/conftest.py"
    path = V.verdict_path(key)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(record))
    backend.set_self_check(V.summary(record))


@pytest.fixture(scope="session")
def mi(_backend):
    from raster_oracle.scenes import backend

    return backend.mitsuba()


def _require_browser() -> None:
    """Skip without Playwright or Chromium; under CI (``CI`` set) fail instead: a report test
    that silently does not run is a green gate on a page nobody opened."""
    problem = None
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        problem = "Playwright for Python is not installed (pip install playwright)"
    if problem is None and not (CHROMIUM.exists() or shutil.which("chromium")):
        problem = f"Chromium is not installed at {CHROMIUM} (apt-get install chromium)"
    if problem is None:
        return
    if os.environ.get("CI"):
        pytest.fail(f"browser test cannot run under CI: {problem}", pytrace=False)
    pytest.skip(problem)


@pytest.fixture(scope="module")
def browser():
    """A headless Chromium for the module's browser tests."""
    _require_browser()
    from playwright.sync_api import sync_playwright

    executable = str(CHROMIUM) if CHROMIUM.exists() else shutil.which("chromium")
    with sync_playwright() as p:
        instance = p.chromium.launch(executable_path=executable, args=CHROMIUM_ARGS)
        try:
            yield instance
        finally:
            instance.close()

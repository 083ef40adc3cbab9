"""Fixtures of the integration tests: Playwright driving Debian's Chromium.

In CI (``CI=true``) the browser tests fail when Chromium is missing; elsewhere they skip.
"""

from __future__ import annotations

import fcntl
import os
from collections.abc import Iterator
from typing import Any

import pytest
from browsers import ARGS, CHROMIUM


@pytest.fixture(scope="module")
def playwright() -> Iterator[Any]:
    if not CHROMIUM.exists():
        if os.environ.get("CI") == "true":
            pytest.fail(f"{CHROMIUM} is missing: install Debian's chromium package")
        pytest.skip(f"{CHROMIUM} is missing (apt-get install chromium)")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as running:
        yield running


@pytest.fixture(scope="module")
def chromium(playwright: Any) -> Iterator[Any]:
    browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
    yield browser
    browser.close()


@pytest.fixture(autouse=True)
def one_browser_test_at_a_time(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[None]:
    """Run the browser tests of all workers one after another (a lock file they share).

    Two Chromium tests at once on two cores left real-time clocks over a second late; the other
    worker goes on with tests that need no browser while one runs.
    """
    if request.node.get_closest_marker("browser") is None:
        yield
        return
    lock = tmp_path_factory.getbasetemp().parent / "browser-tests.lock"
    with lock.open("w") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        yield

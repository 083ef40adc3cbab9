"""Waiting in the tests: poll a condition until it holds, always with a deadline.

One helper for every test that waits for something another thread or process does (a server's
state, a file appearing, a stream vanishing), instead of a fixed sleep: it returns as soon as
the event happened and fails, naming what it waited for, when it never does.
"""

from __future__ import annotations

import inspect
import time
from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")


def wait_for(
    condition: Callable[[], T], timeout: float = 60.0, what: str = "", interval: float = 0.05
) -> T:
    """Call ``condition`` every ``interval`` seconds until it returns a true value; return it.

    Parameters
    ----------
    condition
        What to wait for; called at least once, then until true or the deadline.
    timeout
        Deadline (s) from the first call: generous, since the tests run on busy machines.
    what
        What is awaited, for the failure message (default: the line calling ``wait_for``).
    interval
        Pause between two calls (s).

    Raises
    ------
    AssertionError
        When ``condition`` is still false after ``timeout`` seconds.
    """
    deadline = time.monotonic() + timeout
    while not (value := condition()):
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout:g} s waiting for {what or _caller()}")
        time.sleep(interval)
    return value


def _caller() -> str:
    """The source line that called `wait_for` (the test's own words for what it waited for)."""
    frame = inspect.stack()[2]
    return (frame.code_context or ["the condition"])[0].strip()

"""Ctrl+C while compiled code is called: the process survives every interruption.

A child process (`interrupted_kernels.py`) calls the compiled code of the tabular and the deep
learners, or of a model partner, without pause, while this test sends it SIGINT every fifth of a
millisecond from outside (as a terminal or a lab's process manager would). Each call is short,
so the interruptions land also while numba converts the call's arguments; the child must catch
every one and exit 0.

- The learners, under Python's default handler (a program or notebook using the package): a
  `numpy.random.Generator` passed to a compiled function crashed the process within a second
  (`mirror_avatar.learning.kernels`).
- A model partner, under the console's handler: numba looks up a compiled function given as an
  argument in Python, and an interruption there turned into an unrelated `TypeError`; the
  console's handler waits until numba is done (`mirror_avatar.common.interruptions`).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

CHILD = Path(__file__).with_name("interrupted_kernels.py")

PLAYING = 3.0
"""Seconds the child plays tasks while being interrupted."""


def pester(process: subprocess.Popen[str]) -> None:
    """Send SIGINT to ``process`` every 0.2 ms until it exits (at most two minutes)."""
    deadline = time.monotonic() + 120.0
    while process.poll() is None and time.monotonic() < deadline:
        try:
            os.kill(process.pid, signal.SIGINT)
        except ProcessLookupError:
            return
        time.sleep(0.0002)


@pytest.mark.long
@pytest.mark.parametrize(
    ("kind", "handler"), [("tabular", "default"), ("deep", "default"), ("dynamical", "console")]
)
def test_interruptions_of_compiled_calls_are_caught(kind: str, handler: str) -> None:
    command = [sys.executable, "-X", "faulthandler", str(CHILD), kind, handler, str(PLAYING)]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert process.stdout is not None
        assert process.stdout.readline() == "ready\n", process.communicate(timeout=120)[1]
        pester(process)
        out, error = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    assert process.returncode == 0, error[:2000]
    reached, interrupted = map(int, out.split())
    assert reached > 100, "too few signals reached the child during its calls to test anything"
    assert interrupted > 0

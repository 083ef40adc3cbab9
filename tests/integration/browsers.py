"""What the browser tests share: Debian's Chromium, how it is launched, where screenshots go."""

from __future__ import annotations

import csv
from collections.abc import Callable
from pathlib import Path

import numpy as np
import psutil

CHROMIUM = Path("/usr/bin/chromium")
ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
SCREENSHOTS = Path(__file__).parents[2] / "output" / "screenshots"


def chromium_mains() -> set[int]:
    """Process ids of the running Chromium browsers this test process started (no helpers).

    Browsers that already exited but are not reaped yet (zombies) are left out, and so are a
    browser's children caught between fork and exec (still named and invoked as their parent):
    a browser's parent is not Chromium.
    """
    mains = set()
    for child in psutil.Process().children(recursive=True):
        try:
            parent = child.parent()
            forked = parent is not None and CHROMIUM.name in parent.name()
            main = CHROMIUM.name in child.name() and "--type=" not in " ".join(child.cmdline())
            if main and not forked:
                mains.add(child.pid)
        except (psutil.ZombieProcess, psutil.NoSuchProcess):
            continue
    return mains


def on_the_clock(inputs: Path, positions: np.ndarray) -> np.ndarray:
    """Each recorded sample's position with the time the server took it, shape (n, 2).

    The times are the trial's inputs file's ``clock_s``: the monotonic clock (or LSL's, the
    same on Linux), as `time.monotonic` stamps the driven moves, so the two line up whenever
    the trial started and however late a busy machine took its samples.
    """
    with inputs.open(encoding="utf-8") as file:
        clock = [float(row["clock_s"]) for row in csv.DictReader(file)]
    assert len(clock) == len(positions), inputs
    return np.column_stack([clock, positions])


MOST_LATE_S = 1.0
"""Longest delay from a driven mouse move to the samples that hold it (s): on a machine busy
with other work the page's events and the server's samples were seen to lag by more than 0.3 s."""


def mismatch(recorded: np.ndarray, driven: np.ndarray) -> np.ndarray:
    """|recorded - driven| (units) at the delay from a move to its sample that fits best
    (from -0.3 s to `MOST_LATE_S`); driven positions hold until the next move."""

    def errors(offset: float) -> np.ndarray:
        index = np.searchsorted(driven[:, 0], recorded[:, 0] + offset, side="right") - 1
        return np.abs(recorded[:, 1] - driven[np.maximum(index, 0), 1])

    offsets = np.arange(-0.3, MOST_LATE_S, 0.002)
    return min((errors(offset) for offset in offsets), key=lambda e: float(np.mean(e)))


def assert_matches(recorded: np.ndarray, driven: np.ndarray) -> None:
    """The samples taken while the mouse was driven hold the driven positions.

    Both are (time, position) pairs on the monotonic clock: ``recorded`` as `on_the_clock`
    gives them, ``driven`` as the tests' ``drive`` stamps its moves.
    """
    during = (recorded[:, 0] >= driven[0, 0]) & (recorded[:, 0] <= driven[-1, 0])
    assert during.any(), "no sample was recorded while the mouse was driven"
    error = mismatch(recorded[during], driven)
    step = np.abs(np.diff(driven[:, 1])).max()
    # exact (sub-pixel) for most samples; a sample taken as the pointer moves is one step off,
    # and a few may be further off when the machine is busy and a mouse move arrives late
    assert np.median(error) < 0.001
    assert np.mean(error < step + 0.002) > 0.9


def fitted_lag(
    recorded: np.ndarray, motion: Callable[[np.ndarray], np.ndarray], latest: float = MOST_LATE_S
) -> float:
    """How long after ``motion`` had a position a recorded sample holds it (s), fitted.

    ``recorded`` is (time, position) pairs and ``motion`` the position at any time (s, vectorised),
    on one clock; the lag minimises the mean squared difference of the recorded positions from
    the motion that late, searched from -0.3 s to ``latest`` in 1 ms steps.
    """
    lags = np.arange(-0.3, latest, 0.001)
    costs = [np.mean((recorded[:, 1] - motion(recorded[:, 0] - lag)) ** 2) for lag in lags]
    return float(lags[int(np.argmin(costs))])

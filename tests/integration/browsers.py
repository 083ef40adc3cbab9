"""What the browser tests share: Debian's Chromium, how it is launched, where screenshots go."""

from __future__ import annotations

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

    Browsers that already exited but are not reaped yet (zombies) are left out.
    """
    mains = set()
    for child in psutil.Process().children(recursive=True):
        try:
            if CHROMIUM.name in child.name() and "--type=" not in " ".join(child.cmdline()):
                mains.add(child.pid)
        except (psutil.ZombieProcess, psutil.NoSuchProcess):
            continue
    return mains


def mismatch(recorded: np.ndarray, driven: np.ndarray) -> np.ndarray:
    """|recorded - driven| (units) at the clock offset that fits best; driven positions hold
    until the next move, the first one from time 0 (the pointer is parked there beforehand)."""

    def errors(offset: float) -> np.ndarray:
        index = np.searchsorted(driven[:, 0], recorded[:, 0] + offset, side="right") - 1
        return np.abs(recorded[:, 1] - driven[np.maximum(index, 0), 1])

    offsets = np.arange(-0.3, 0.3, 0.002)
    return min((errors(offset) for offset in offsets), key=lambda e: float(np.mean(e)))


def assert_matches(recorded: np.ndarray, driven: np.ndarray) -> None:
    error = mismatch(recorded[recorded[:, 0] <= driven[-1, 0]], driven)
    step = np.abs(np.diff(driven[:, 1])).max()
    # exact (sub-pixel) for most samples; a sample taken as the pointer moves is one step off,
    # and a few may be further off when the machine is busy and a mouse move arrives late
    assert np.median(error) < 0.001
    assert np.mean(error < step + 0.002) > 0.9

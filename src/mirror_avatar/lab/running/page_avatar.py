"""An avatar stepped in its person's page: what the server sends, receives and records of it.

An avatar slot with ``runs = "browser"`` (`mirror_avatar.lab.design.plan.RUNS`) is played by the
page of the dyad's one person (METHODS section 16). When a trial opens, the engine resets a
`PageAvatar` with the seed it gives every player; the avatar's message
(`mirror_avatar.browser.browser_arrays`: its model file's arrays) goes to the page, which builds
the player (``lab/static/avatars.js``) and answers with its state at tick 0. On each frame of
sample k the page steps the avatar to tick k + 1 from the person's position as the page shows it
then, and sends the avatar's position and velocity with that position of the person
(`mirror_avatar.lab.running.messages.AvatarPosition`).

The server steps nothing: at each sample it records the newest tick the page reported, as it
records a person's newest position. A sample at which no newer tick has arrived is *missing*:
the last reported position is kept (a session file's positions are finite), its tick says which
it is, and it is counted (`PageAvatar.missing`). The trial's ``inputs.csv`` gives, per sample,
the tick recorded (``tick_LABEL``), the person's position the page stepped it from
(``seen_LABEL``) and whether it was missing (``missing_LABEL``); every tick the page reported,
recorded at a sample or not, is written to the trial's ``trial-NN_page.csv`` when it ends
(`PageAvatar.write_steps`).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mirror_avatar.browser import browser_arrays
from mirror_avatar.files.atomic import LineFile
from mirror_avatar.players.base import ExternalPlayer, Player

READY_TIMEOUT = 10.0
"""Longest wait for the page to build its avatar before a trial's clock starts (s; **choice**:
a page builds a deep player's network in well under a second, a slow phone in a few)."""


@dataclass(frozen=True)
class PageStep:
    """The avatar's state at one tick, as the page reported it.

    Attributes
    ----------
    tick
        The sample it belongs to (the page stepped to it on the frame of sample ``tick - 1``).
    x, v
        The avatar's position (units) and velocity (units/s).
    seen
        The person's position (units) the page stepped it from (NaN at tick 0).
    """

    tick: int
    x: float
    v: float
    seen: float


class PageAvatar(ExternalPlayer):
    """An avatar's player stepped in its person's page; the server records what the page reports.

    Parameters
    ----------
    player
        The avatar's player, as the server would run it (a kind the page steps).
    slot
        The avatar's slot's label (its columns and counts are named by it).
    n_steps
        Control periods of a trial (its references are drawn for them).

    Attributes
    ----------
    message
        What the page builds the player from (`mirror_avatar.browser.browser_arrays`), made at
        each `reset`.
    ready
        Set when the page has built the player (its tick 0 received).
    missing
        Samples of the trial at which no newer tick had arrived.
    last_step, last_missing
        The step recorded at the latest sample, and whether it was missing there.
    steps
        The start (tick 0), then every step the page reported in the trial, in order of tick.
    """

    def __init__(self, player: Player, slot: str, n_steps: int) -> None:
        browser_arrays(player, 0, 1)  # a kind the page cannot step is refused here
        self.player = player
        self.slot = slot
        self.n_steps = n_steps
        self.label = player.label
        self.period = player.period
        self.message: dict[str, Any] = {}
        self.ready = threading.Event()
        self.missing = 0
        self.last_missing = False
        self.last_step = PageStep(0, math.nan, math.nan, math.nan)
        self.steps: list[PageStep] = []
        self._newest = self.last_step
        self._lock = threading.Lock()

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        """Make the page's message with ``seed``; return the avatar's start (tick 0)."""
        self.message = browser_arrays(self.player, seed, self.n_steps)
        x, v = self.message["start"]
        self.ready.clear()
        self.missing = 0
        with self._lock:
            self._newest = PageStep(0, x, v, math.nan)
            self.steps = [self._newest]
        self.last_step = PageStep(-1, x, v, math.nan)
        return x, v

    def put(self, step: PageStep) -> None:
        """Take a step the page reported (from the event loop); an older tick is ignored."""
        self.ready.set()
        with self._lock:
            if step.tick > self._newest.tick:
                self._newest = step
                self.steps.append(step)

    def current_state(self) -> tuple[float, float]:
        """Return the newest reported state; none newer than the last recorded is missing."""
        with self._lock:
            newest = self._newest
        self.last_missing = newest.tick <= self.last_step.tick
        self.missing += int(self.last_missing)
        self.last_step = newest
        return newest.x, newest.v

    def tick_columns(self) -> list[str]:
        """Return the avatar's columns of the trial's ``inputs.csv``."""
        return [f"{name}_{self.slot}" for name in ("tick", "seen", "missing")]

    def tick_fields(self) -> list[str]:
        """Return the latest sample's fields of `tick_columns`."""
        seen = "" if math.isnan(self.last_step.seen) else repr(self.last_step.seen)
        return [str(self.last_step.tick), seen, str(int(self.last_missing))]

    def write_steps(self, path: Path) -> None:
        """Write every step the page reported: ``tick,seen,x,v`` (units, units/s) a line.

        Raises
        ------
        OSError
            When the file cannot be written (it must not exist yet), naming it.
        """
        with self._lock:
            steps = list(self.steps)
        lines = LineFile(path, "tick,seen,x,v")
        try:
            for step in steps:
                lines.write(f"{step.tick},{step.seen!r},{step.x!r},{step.v!r}")
        finally:
            lines.close()

    def describe(self) -> dict[str, Any]:
        """Return the avatar's player's description, saying it ran in the browser."""
        return self.player.describe() | {"runs": "browser"}

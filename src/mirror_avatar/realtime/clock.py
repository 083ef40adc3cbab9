"""The real-time clock: one coroutine ticking a trial on absolute deadlines, and its bounds.

`run_on_clock` calls a trial's ``tick`` once per control period T at the deadlines
``start + k * T`` (absolute, so a late tick does not shift the ones after it: the clock catches
up), each in the trial's own worker thread, so a slow avatar, a slow disk or another session's
work on the default thread pool delays no one else's clock. How late each tick was is passed to
the trial, which records it with the sample.

A tick whose player diverges (`mirror_avatar.players.base.PlayerDiverged`) ends the trial, its
message (the player and the sample) the reason. Two bounds end a trial that cannot keep real
time, each saying why (`ClockLimits`):

- ``max_step``: the players' step alone (timed in the ticking thread, file writes excluded)
  took longer than this: an avatar too slow for real time. Event-loop stalls, a flood of
  connections or another session do not count against the avatar.
- ``max_lateness``: a tick came later than this after its deadline: the clock fell behind,
  whatever the cause, and the samples would no longer be real time.

`time_players` measures, before a session starts, how long its avatars take to step on this
machine, so that a spec too slow for the control period is refused when the session is created.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from mirror_avatar.players.base import Observation, Player, PlayerDiverged
from mirror_avatar.realtime.trial import write_failure

MAX_LATENESS = 1.0
"""Default bound (s) on how late a tick may come before its trial is ended (**choice**: over 30
control periods; a momentary stall of the machine stays under it and the clock catches up, an
avatar slower than real time crosses it within a second or two of play)."""

MAX_STEP = 0.5
"""Default bound (s) on one step of the players before the trial is ended."""

TIMED_STEPS = 20
"""Steps of each avatar `time_players` measures (after one untimed step that compiles it)."""


@dataclass(frozen=True)
class ClockLimits:
    """How much a trial's clock may slip before the trial is ended.

    Parameters
    ----------
    max_step
        Longest step of the players (s).
    max_lateness
        Longest delay of a tick after its deadline (s).
    slow_reason
        The end reason when a step is too long.
    """

    max_step: float = MAX_STEP
    max_lateness: float = MAX_LATENESS
    slow_reason: str = "an avatar is too slow for real time"


class Ticking(Protocol):
    """What `run_on_clock` drives (`mirror_avatar.realtime.trial.ClockedTrial`)."""

    period: float
    step_time: float

    @property
    def k(self) -> int:
        """Samples taken so far."""
        ...

    @property
    def finished(self) -> bool:
        """Whether every sample has been taken."""
        ...

    def tick(self, lateness: float = 0.0) -> None:
        """Take the next sample, ``lateness`` s after its deadline."""
        ...


async def run_on_clock(
    trial: Ticking,
    limits: ClockLimits,
    stop_reason: Callable[[], str | None] = lambda: None,
    after_tick: Callable[[], None] = lambda: None,
) -> tuple[bool, str]:
    """Tick ``trial`` every period on absolute deadlines until it finishes or must end.

    Parameters
    ----------
    trial
        The trial (its ``tick`` runs in a worker thread of its own).
    limits
        The bounds that end a trial that cannot keep its clock.
    stop_reason
        Asked before each tick: why the trial must stop now (a stop, a lost input), or None.
    after_tick
        Called after each tick on the event loop (frames to the pages, markers...).

    Returns
    -------
    tuple
        Whether the trial completed, and why it ended (``"completed"``, the stop reason,
        ``limits.slow_reason``, the clock's lateness, `write_failure`'s words, or which player
        diverged at which sample).
    """
    loop = asyncio.get_running_loop()
    executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="clock")
    try:
        start = loop.time()
        while not trial.finished:
            deadline = start + trial.k * trial.period
            delay = deadline - loop.time()
            if delay > 0:
                await asyncio.sleep(delay)
            reason = stop_reason()
            if reason is not None:
                return False, reason
            lateness = max(0.0, loop.time() - deadline)
            try:
                await loop.run_in_executor(executor, trial.tick, lateness)
            except OSError as error:
                return False, write_failure(error)
            except PlayerDiverged as error:
                return False, str(error)
            if trial.step_time > limits.max_step:
                return False, limits.slow_reason
            if lateness > limits.max_lateness:
                late = f"{lateness * 1000.0:.0f} ms late (bound {limits.max_lateness * 1000.0:.0f})"
                return False, f"the clock could not be kept: sample {trial.k - 1} was {late}"
            after_tick()
        return True, "completed"
    finally:
        executor.shutdown(wait=False)


def time_players(players: Sequence[Player], steps: int = TIMED_STEPS) -> list[float]:
    """Measure each player's step on this machine: the median of ``steps`` steps (s).

    Each player is reset, stepped once untimed (compiling its step) and then ``steps`` times
    against a partner at rest, timed with `time.perf_counter`. The players are left as reset
    would leave them after that many steps: reset them before use.
    """
    medians = []
    for player in players:
        player.reset(seed=0)
        observation = Observation.of_partner(0, 0.0, 0.0, 0.0)
        player.step(observation)
        times = np.empty(steps)
        for i in range(steps):
            began = time.perf_counter()
            player.step(Observation.of_partner(i + 1, 0.0, 0.0, 0.0))
            times[i] = time.perf_counter() - began
        medians.append(float(np.median(times)))
    return medians

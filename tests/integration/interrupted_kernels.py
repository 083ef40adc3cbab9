"""Child of `test_kernels_interrupted`: play tiny tasks through the compiled learners, non-stop.

It ignores SIGINT while it starts, then installs the handler ``sys.argv[2]``: ``default``,
Python's own (Ctrl+C raises `KeyboardInterrupt` wherever the interpreter is, as in a notebook),
or ``console``, the console script's (`mirror_avatar.common.interruptions.interrupt`). It prints
``ready`` and, for ``sys.argv[3]`` seconds, plays three-sample tasks through the learner
``sys.argv[1]`` (``tabular`` or ``deep``), or steps a model partner whose compiled rates are an
argument of the integrator (``dynamical``), catching every interruption. It prints how many
signals reached it during a call and how many calls they interrupted, and exits 0 if the process
survived them.
"""

from __future__ import annotations

import signal
import sys
import time
from collections.abc import Callable
from functools import partial
from types import FrameType

signal.signal(signal.SIGINT, signal.SIG_IGN)

import numpy as np  # noqa: E402

from mirror_avatar.common.interruptions import interrupt  # noqa: E402
from mirror_avatar.deep.player import DeepCyberPlayer  # noqa: E402
from mirror_avatar.deep.training import greedy_deep  # noqa: E402
from mirror_avatar.learning.agent import CyberPlayer  # noqa: E402
from mirror_avatar.learning.training import ImitationTask, greedy_tabular  # noqa: E402
from mirror_avatar.players.hkb_partner import hkb_partner_step  # noqa: E402


def tiny_task() -> ImitationTask:
    """A three-sample task: the kernel's own work is negligible beside its call."""
    still = np.zeros(3)
    return ImitationTask(still, still, still[None], still[None], still, still, still)


def player_call(kind: str) -> Callable[[], object]:
    """One call of the compiled code of ``kind``, as the package makes it."""
    task = tiny_task()
    if kind == "tabular":
        player = CyberPlayer()
        player.initialise_q(0, 1e-2)
        return partial(greedy_tabular(player), task)
    if kind == "deep":
        deep = DeepCyberPlayer()
        deep.initialise_policy(0)
        return partial(greedy_deep(deep), task)
    state, params, inputs = np.zeros(2), np.array([1.0, 1.0, 1.0, 1.0, 0.5, 0.5]), np.zeros(2)
    return partial(hkb_partner_step, state, params, inputs, 0.01)


class Calls:
    """Calls of ``play`` that the SIGINT ``handler`` may interrupt, and only those.

    The handler is passed the signals that land during a call (between `playing` turning True
    and False), so every `KeyboardInterrupt` is raised inside `make`'s ``try`` and none escapes
    from the loop around it; the others are dropped. `reached` counts the signals passed on,
    `interrupted` the calls they interrupted (the console's handler holds back those that land
    inside numba, and sends them again later).
    """

    def __init__(self, play: Callable[[], object], handler: Callable[..., object]) -> None:
        self.play, self.handler = play, handler
        self.playing = False
        self.reached = 0
        self.interrupted = 0

    def on_signal(self, signum: int, frame: FrameType | None) -> None:
        """SIGINT handler: pass the signal to `handler` while a call is under way."""
        if self.playing:
            self.reached += 1
            self.handler(signum, frame)

    def make(self) -> None:
        """Make one call, counting it if it was interrupted."""
        try:
            self.playing = True
            self.play()
            self.playing = False
        except KeyboardInterrupt:
            self.playing = False
            self.interrupted += 1


def main(kind: str, handler: str, seconds: float) -> None:
    """Make calls for ``seconds`` with the SIGINT ``handler``, counting interruptions."""
    play = player_call(kind)
    play()
    calls = Calls(play, interrupt if handler == "console" else signal.default_int_handler)
    signal.signal(signal.SIGINT, calls.on_signal)
    print("ready", flush=True)
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        calls.make()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    print(calls.reached, calls.interrupted, flush=True)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], float(sys.argv[3]))

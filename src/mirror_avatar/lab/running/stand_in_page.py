"""A virtual participant's page on its animation frames, as ``participant.js`` and ``clock.js`` do.

The server shapes each page's frames to the condition's partner view
(`mirror_avatar.lab.running.partner_frames`: delayed, hidden, predicted, or given a ``due`` page
time when equalised); a page only holds and draws them. `PageDisplay` does what
``participant.js`` does with them: it keeps the frames received, oldest first, and on each
animation frame (`ANIMATION_PERIOD_MS` apart on the page's clock, `next_frame_ms`) draws the
newest of those due by then (a frame without ``due`` is due on arrival), so a frame superseded
before an animation frame is never drawn. The partners it drew last are what a stand-in sees
(`mirror_avatar.lab.running.pilot.StandIn`). Every drawn frame with a partner shown is reported
with the animation frame's time, `SHOWN_BATCH` to a ``shown`` message
(`mirror_avatar.lab.running.views`); a countdown starts the next trial's drawing afresh.

A page sends its pointer's positions read since its previous animation frame, each with the
page time it was read at, in ``pointer`` batches of at most
`mirror_avatar.lab.running.messages.MAX_BATCH` (`pointer_batches`, as ``clock.js``'s
``batches``), or its position at the animation frame when none was read.
"""

from __future__ import annotations

import collections
import json
import math
from collections.abc import Mapping, Sequence
from typing import Any

from mirror_avatar.lab.running.messages import MAX_BATCH

ANIMATION_PERIOD_MS = 1000.0 / 60.0
"""Time between a stand-in page's animation frames (ms): a 60 Hz display's."""

SHOWN_BATCH = 10
"""Frames drawn reported per ``shown`` message (``SHOWN_BATCH`` in ``participant.js``)."""


class PageDisplay:
    """The frames a page holds and the partners it draws (see the module docstring).

    ``partners`` maps each visible partner's place among the frame's partners (0 for the first
    after the page's own point) to the position drawn (units); a hidden partner is left out.
    """

    def __init__(self) -> None:
        self.partners: dict[int, float] = {}
        self._pending: collections.deque[Mapping[str, Any]] = collections.deque()
        self._drawn: list[tuple[int, float]] = []

    def clear(self) -> None:
        """Forget every frame and partner, reported or not (a trial's countdown)."""
        self.partners = {}
        self._pending.clear()
        self._drawn = []

    def receive(self, frame: Mapping[str, Any]) -> None:
        """Hold a ``frame`` message until an animation frame draws it."""
        self._pending.append(frame)

    def draw(self, t_ms: float) -> None:
        """Draw at the animation frame of page time ``t_ms`` (ms) the newest frame due by then."""
        newest = None
        while self._pending and not self._pending[0].get("due", -math.inf) > t_ms:
            newest = self._pending.popleft()
        if newest is None:
            return
        self.partners = {j: x for j, x in enumerate(newest["x"][1:]) if x is not None}
        if self.partners:
            self._drawn.append((int(newest["k"]), round(t_ms, 1)))

    def reports(self) -> list[str]:
        """Return the ``shown`` message of the last `SHOWN_BATCH` frames drawn, once they are."""
        if len(self._drawn) < SHOWN_BATCH:
            return []
        drawn, self._drawn = self._drawn, []
        message = {"type": "shown", "k": [k for k, _ in drawn], "t": [t for _, t in drawn]}
        return [json.dumps(message)]


def next_frame_ms(start_ms: float, now_ms: float) -> float:
    """Return the page time (ms) of the first animation frame after ``now_ms``.

    The frames are `ANIMATION_PERIOD_MS` apart from ``start_ms``; those missed while the page
    was busy are skipped, as a browser skips them.
    """
    frames = math.floor((now_ms - start_ms) / ANIMATION_PERIOD_MS) + 1
    return start_ms + frames * ANIMATION_PERIOD_MS


def pointer_batches(
    samples: Sequence[tuple[float, float]], sent_ms: float, first_seq: int
) -> list[dict[str, Any]]:
    """Return the ``pointer`` messages of one animation frame.

    Parameters
    ----------
    samples
        The positions read since the previous frame, oldest first: (page time in ms, position
        in units) each.
    sent_ms
        The page time of sending (ms).
    first_seq
        The first message's number; each next one's is one more.
    """
    return [
        {
            "type": "pointer",
            "seq": first_seq + n,
            "sent": sent_ms,
            "ago": [max(0.0, round(sent_ms - t, 1)) for t, _ in part],
            "x": [round(x, 5) for _, x in part],
        }
        for n, start in enumerate(range(0, len(samples), MAX_BATCH))
        if (part := samples[start : start + MAX_BATCH])
    ]

"""Each page's frame of a sample: its own position, and its partners' as the condition shows them.

A page's own position is the one just recorded. Its partners' are those recorded ``delay``
samples earlier (none before that: not drawn), none while occluded, and drawn as the condition's
view says (`mirror_avatar.lab.design.partner_view.PartnerView`, METHODS section 19):

- ``as_arrives``: the positions, drawn as they arrive;
- ``equalised``: the positions and ``due``, the page time at which every page draws them:
  their sample's time plus the declared lag, or the slowest connected page's one-way delay
  (half the 95th percentile of the round trips of its clock's window:
  `mirror_avatar.realtime.partner_view.LAG_QUANTILE`), on the page's clock
  (`mirror_avatar.realtime.partner_view.due_page_ms`); a page whose clock is not known yet
  draws them as they arrive;
- ``predicted``: each partner extrapolated from its last samples
  (`mirror_avatar.realtime.partner_view.dead_reckon`) over the declared horizon, or the page's
  own one-way delay (half its median round trip; none before its clock is known).

The recording keeps the true positions; what each page was sent is remembered for the view
file (`mirror_avatar.lab.running.views.ViewLog`).
"""

from __future__ import annotations

import collections
import math
from collections.abc import Iterable

import numpy as np

from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.files.trials import PLAYING_RANGE
from mirror_avatar.lab.design.partner_view import PartnerView
from mirror_avatar.lab.running.participant import Participant
from mirror_avatar.lab.running.trial import LabTrial
from mirror_avatar.lab.running.views import SentFrame
from mirror_avatar.realtime.inputs import BrowserInput
from mirror_avatar.realtime.page_clock import PageClock
from mirror_avatar.realtime.partner_view import (
    FIT_SAMPLES,
    LAG_QUANTILE,
    dead_reckon,
    due_page_ms,
    one_way_ms,
)

AS_ARRIVES = PartnerView()
"""The partners drawn as they arrive."""


def page_clock(participant: Participant) -> PageClock | None:
    """Return the participant's page clock (None for a device without one)."""
    source = participant.source
    return source.clock if isinstance(source, BrowserInput) else None


def slowest_one_way_ms(people: Iterable[Participant]) -> float:
    """Return the largest one-way delay (ms) of the connected pages' clocks (0 with none).

    Each page's is half the `LAG_QUANTILE` of its clock window's round trips.
    """
    delays = [
        one_way_ms(clock.recent_delays(), LAG_QUANTILE)
        for person in people
        if person.outbox is not None and (clock := page_clock(person)) is not None
    ]
    return max((delay for delay in delays if delay is not None), default=0.0)


class PartnerFrames:
    """Sends each page its frame of each sample (see the module docstring).

    Remembers the samples a delay and a prediction need: ``(time, positions)`` of the last
    ``delay + FIT_SAMPLES``, from the trial's first sample.
    """

    def __init__(self) -> None:
        self._history: collections.deque[tuple[float, list[float]]] = collections.deque(maxlen=1)

    def send(
        self,
        trial: LabTrial,
        playing: dict[int, Participant],
        delay: int = 0,
        hidden: bool = False,
        view: PartnerView = AS_ARRIVES,
    ) -> None:
        """Send each connected page its frame of the sample just taken.

        Parameters
        ----------
        trial
            The trial playing.
        playing
            The people playing, by player index.
        delay
            How many samples late the partners are drawn.
        hidden
            Whether the partners are hidden at this sample.
        view
            How the pages draw them.
        """
        if trial.k == 1 or self._history.maxlen != delay + FIT_SAMPLES:
            self._history = collections.deque(maxlen=delay + FIT_SAMPLES)
        positions = trial.positions()
        self._history.append((trial.tick_log.last_stamp, positions))
        kept = max(0, len(self._history) - delay)  # the samples at least `delay` old
        past = list(self._history)[:kept] if not hidden else []
        lag_ms = None
        if view.handling == "equalised":
            lag_ms = (
                slowest_one_way_ms(playing.values()) if view.lag_s is None else view.lag_s * 1000.0
            )
        k = trial.k - 1
        for participant in playing.values():
            if participant.outbox is None:
                continue
            own, *others = participant.visible
            clock = page_clock(participant)
            sent = _partners(past, others, view, clock)
            frame = {"type": "frame", "k": k, "x": [positions[own], *sent.x],
                     "progress": trial.progress}  # fmt: skip
            offset = math.nan if clock is None else clock.offset_ms
            if lag_ms is not None and past and not math.isnan(offset):
                frame["due"] = round(due_page_ms(sent.sample_s, lag_ms, offset), 1)
            trial.views.sent(participant.label, k, sent)
            participant.outbox.put_frame(frame)


def _partners(
    past: list[tuple[float, list[float]]],
    others: list[int],
    view: PartnerView,
    clock: PageClock | None,
) -> SentFrame:
    """Return what a page is sent of its partners ``others`` from the samples ``past``."""
    if not past:
        return SentFrame(tuple(others), math.nan, tuple(None for _ in others))
    stamp, positions = past[-1]
    if view.handling != "predicted":
        return SentFrame(tuple(others), stamp, tuple(positions[j] for j in others))
    horizon = view.horizon_s
    if horizon is None:
        measured = None if clock is None else one_way_ms(clock.recent_delays())
        horizon = 0.0 if measured is None else measured / 1000.0
    history = np.array([x for _, x in past[-FIT_SAMPLES:]], dtype=np.float64)
    ahead = dead_reckon(history, CONTROL_PERIOD, horizon, PLAYING_RANGE)
    return SentFrame(tuple(others), stamp, tuple(float(ahead[j]) for j in others))

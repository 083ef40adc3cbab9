"""Each page's frame of a sample: its own position, and its partners' as the condition shows them.

A page's own position is the one just recorded. Its partners' are those recorded ``delay``
samples earlier (none before that: not drawn), or, when the condition jitters that delay, the
newest sample delivered to the page as over a network (`JitteredLink`), none while occluded,
and drawn as the condition's view says (`mirror_avatar.lab.design.partner_view.PartnerView`,
METHODS section 19):

- ``as_arrives``: the positions, drawn as they arrive;
- ``equalised``: the positions and ``due``, the page time at which every page draws them:
  their sample's time plus the declared lag, or the slowest connected page's one-way delay
  (half the 95th percentile of the round trips of its clock's window:
  `mirror_avatar.realtime.partner_view.LAG_QUANTILE`), on the page's clock
  (`mirror_avatar.realtime.partner_view.due_page_ms`); a page whose clock is not known yet
  draws them as they arrive;
- ``predicted``: each partner extrapolated (`mirror_avatar.realtime.partner_view.dead_reckon`)
  to where the recording shows it the declared horizon, or the page's own one-way delay (half
  its median round trip; none before its clock is known), after the sample sent
  (`mirror_avatar.realtime.partner_view.recorded_read_s`), fitted on the partner's samples as
  they were read: a page's pointer samples at their read times on the server's clock, those
  that arrived by the sample sent (the ticks' samples of a partner without them: an avatar, a
  device, a page before its clock is known).

The recording keeps the true positions; what each page was sent is remembered for the view
file (`mirror_avatar.lab.running.views.ViewLog`).
"""

from __future__ import annotations

import collections
import math
from collections.abc import Iterable
from typing import NamedTuple

import numpy as np

from mirror_avatar.common.seeds import spawn_seeds
from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.files.trials import PLAYING_RANGE
from mirror_avatar.lab.design.partner_view import PartnerView
from mirror_avatar.lab.running.participant import Participant
from mirror_avatar.lab.running.trial import LabTrial
from mirror_avatar.lab.running.views import SentFrame
from mirror_avatar.realtime.inputs import BrowserInput, PointerSample
from mirror_avatar.realtime.page_clock import PageClock
from mirror_avatar.realtime.partner_view import (
    JITTER_SPAN,
    LAG_QUANTILE,
    Array,
    dead_reckon,
    due_page_ms,
    jitter_draw,
    jittered_delay_s,
    one_way_ms,
    recorded_read_s,
)
from mirror_avatar.remote.network import due_time

AS_ARRIVES = PartnerView()
"""The partners drawn as they arrive."""

DUE_TOLERANCE_S = 1e-9
"""A sample due within this of a tick's time (s) is due at it (its time and delay summed in
floating point)."""

FIT_SPAN_S = 0.3
"""Time (s) back from the sample sent whose arrivals a prediction looks through for the samples
it fits (**choice**: the samples read within
`mirror_avatar.realtime.partner_view.FIT_WINDOW_S` arrive spread by the uplink's jitter and
held behind late ones, TCP's order; 0.3 s covers 0.09 s and a hold of over 0.2 s)."""

FIT_TICKS = math.ceil(FIT_SPAN_S / CONTROL_PERIOD)
"""Samples back whose arrivals a prediction looks through (`FIT_SPAN_S`)."""


class Taken(NamedTuple):
    """A sample as the partners' frames need it.

    Its time (``stamp``: s, the server's clock), every player's position (``positions``:
    units) and the pointer samples received by then since the sample before (``reads``: by
    player index, oldest first, those with a server time).
    """

    stamp: float
    positions: list[float]
    reads: dict[int, list[PointerSample]]


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

    Remembers the samples a delay, its jitter and a prediction need (`Taken`): the last
    ``delay + FIT_TICKS`` and the jitter's `JITTER_SPAN` SDs, from the trial's first sample;
    with a jitter, each page's `JitteredLink`.
    """

    def __init__(self) -> None:
        self._history: collections.deque[Taken] = collections.deque(maxlen=1)
        self._links: dict[int, JitteredLink] = {}

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
            How many samples late the partners are drawn (jittered as ``view`` says).
        hidden
            Whether the partners are hidden at this sample.
        view
            How the pages draw them.
        """
        span = math.ceil(JITTER_SPAN * view.jitter_s / CONTROL_PERIOD)
        if trial.k == 1 or self._history.maxlen != delay + span + FIT_TICKS:
            self._history = collections.deque(maxlen=delay + span + FIT_TICKS)
            self._links = {}
        positions = trial.positions()
        self._history.append(Taken(trial.tick_log.last_stamp, positions, _reads(trial)))
        lag_ms = None
        if view.handling == "equalised":
            lag_ms = (
                slowest_one_way_ms(playing.values()) if view.lag_s is None else view.lag_s * 1000.0
            )
        k = trial.k - 1
        history = [] if hidden else list(self._history)
        for participant in playing.values():
            age = self._age(trial, participant.index, delay, view)
            kept = 0 if age is None else max(0, len(self._history) - age)  # those `age` old
            past = history[:kept]
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

    def _age(self, trial: LabTrial, index: int, delay: int, view: PartnerView) -> int | None:
        """Return how many samples old person ``index``'s partners are drawn now (None: none).

        With a jitter, the sample just taken is sent down the person's `JitteredLink` (seeded
        by the trial's seed and the person's index), its delay drawn.
        """
        if not view.jitter_s:
            return delay
        link = self._links.get(index)
        if link is None:
            seed = spawn_seeds([trial.seed, index], 1)[0]
            link = self._links[index] = JitteredLink(np.random.default_rng(seed))
        jitter = jitter_draw(link.rng, view.jitter_distribution, view.jitter_s)
        k = trial.k - 1
        shown = link.deliver(k, jittered_delay_s(delay * CONTROL_PERIOD, jitter, view.jitter_s))
        return None if shown is None else k - shown


class JitteredLink:
    """A partner's samples delivered to one page as over a network: in order, each delayed.

    Sample k, taken at ``k T``, is due its delay later but never before the sample before it
    (TCP's order: the emulated internet's rule, `mirror_avatar.remote.network.due_time`); at
    each sample the page is sent the newest sample due by then.

    Parameters
    ----------
    rng
        Draws the person's jitter.
    """

    def __init__(self, rng: np.random.Generator) -> None:
        self.rng = rng
        self._due: collections.deque[tuple[int, float]] = collections.deque()
        self._last = -math.inf
        self._shown: int | None = None

    def deliver(self, k: int, delay_s: float) -> int | None:
        """Send sample k delayed ``delay_s`` (s); return the newest sample due at ``k T``."""
        self._last, _ = due_time(k * CONTROL_PERIOD, delay_s * 1000.0, self._last, ())
        self._due.append((k, self._last))
        now = k * CONTROL_PERIOD + DUE_TOLERANCE_S
        while self._due and self._due[0][1] <= now:
            self._shown = self._due.popleft()[0]
        return self._shown


def _reads(trial: LabTrial) -> dict[int, list[PointerSample]]:
    """Return the pointer samples received at the trial's latest tick with a server time."""
    index = {slot.label: k for k, slot in enumerate(trial.plan.slots)}
    return {
        index[label]: [s for s in samples if not math.isnan(s.server_s)]
        for label, samples in trial.pointer_log.received.items()
    }


def _partners(
    past: list[Taken],
    others: list[int],
    view: PartnerView,
    clock: PageClock | None,
) -> SentFrame:
    """Return what a page is sent of its partners ``others`` from the samples ``past``."""
    if not past:
        return SentFrame(tuple(others), math.nan, tuple(None for _ in others))
    stamp, positions, _ = past[-1]
    if view.handling != "predicted":
        return SentFrame(tuple(others), stamp, tuple(positions[j] for j in others))
    horizon = view.horizon_s
    if horizon is None:
        measured = None if clock is None else one_way_ms(clock.recent_delays())
        horizon = 0.0 if measured is None else measured / 1000.0
    ahead = []
    for j in others:
        read, x, arrived = _as_read(past[-FIT_TICKS:], j)
        to_s = recorded_read_s(stamp + horizon, read, arrived)
        ahead.append(dead_reckon(read, x, to_s, PLAYING_RANGE))
    return SentFrame(tuple(others), stamp, tuple(ahead))


def _as_read(recent: list[Taken], j: int) -> tuple[Array, Array, Array]:
    """Return player j's samples known at the newest of ``recent``, as they were read.

    Their read times (s), positions (units) and arrivals (s; all the server's clock): its
    pointer samples that arrived by the newest's time, or else the samples' own (read and
    arrived at their time).
    """
    stamp = recent[-1].stamp
    pointer = [s for taken in recent for s in taken.reads.get(j, ()) if s.received_s <= stamp]
    if pointer:
        read, x, arrived = zip(*((s.server_s, s.x, s.received_s) for s in pointer), strict=True)
        return np.array(read), np.array(x), np.array(arrived)
    times = np.array([taken.stamp for taken in recent])
    return times, np.array([taken.positions[j] for taken in recent]), times

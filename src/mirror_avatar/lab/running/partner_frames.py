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

from mirror_avatar.common.seeds import spawn_seeds
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
    JITTER_SPAN,
    LAG_QUANTILE,
    dead_reckon,
    due_page_ms,
    jitter_draw,
    jittered_delay_s,
    one_way_ms,
)
from mirror_avatar.remote.network import due_time

AS_ARRIVES = PartnerView()
"""The partners drawn as they arrive."""

DUE_TOLERANCE_S = 1e-9
"""A sample due within this of a tick's time (s) is due at it (its time and delay summed in
floating point)."""


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

    Remembers the samples a delay, its jitter and a prediction need: ``(time, positions)`` of
    the last ``delay + FIT_SAMPLES`` and the jitter's `JITTER_SPAN` SDs, from the trial's first
    sample; with a jitter, each page's `JitteredLink`.
    """

    def __init__(self) -> None:
        self._history: collections.deque[tuple[float, list[float]]] = collections.deque(maxlen=1)
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
        if trial.k == 1 or self._history.maxlen != delay + span + FIT_SAMPLES:
            self._history = collections.deque(maxlen=delay + span + FIT_SAMPLES)
            self._links = {}
        positions = trial.positions()
        self._history.append((trial.tick_log.last_stamp, positions))
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

"""Where a person's position comes from: a browser page or a device, sampled by the server's clock.

An `InputSource` holds the latest sample a device delivered (`Sample`: position in units, a
sequence number that grows with every new sample, and when it arrived). The server's clock reads
it once per control period through a `HumanPlayer`, which never invents a position: when no new
sample has arrived since the previous tick it holds the last one and counts the tick as held,
and before the first sample it holds the centre of the playing range (also counted).

Liveness is judged from what a source actually delivers, not from a connection's state: an
input is *lost* at a tick when its newest sample arrived more than `LIVENESS_TIMEOUT` seconds
earlier (or, before its first sample, when the trial started that long ago), and *live* again
as soon as a new sample arrives. A page that freezes or is closed, a network that stalls, an LSL
stream that vanishes or stops sending: all look the same, and all are seen.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.players.base import ExternalPlayer
from mirror_avatar.realtime.interruptions import Interruptions
from mirror_avatar.realtime.page_clock import PageClock

LIVENESS_TIMEOUT = 1.0
"""Seconds without a new sample after which an input is judged lost (**choice**: a page sends
one position per animation frame, 60 a second; a hand tracker 100 or more; a second is over
30 control periods, far beyond a network's hiccup, short enough to act on within a trial)."""

STALL_GAP = 0.5
"""Seconds without a page's samples recorded as a stall (**choice**: a page sends at least one
batch per animation frame, 60 a second; half a second is eight times an 80 +- 25 ms network's
jitter of three SDs, and far beyond a late frame)."""


@dataclass(frozen=True)
class Sample:
    """One position delivered by an input device.

    Attributes
    ----------
    x
        Position (units, within the playing range).
    seq
        Sequence number, larger for every newer sample of the same source.
    received
        When the server received it (`time.monotonic`, s).
    """

    x: float
    seq: int
    received: float


class InputSource(Protocol):
    """A person's input device as the server's clock sees it."""

    def latest(self) -> Sample | None:
        """Return the newest sample delivered, or None before the first."""
        ...


@dataclass(frozen=True)
class PointerSample:
    """One pointer sample as its page read it and the server received it.

    Attributes
    ----------
    seq
        Number of the batch that carried it (as `Sample.seq`).
    page_ms
        When the page read it (ms, its own clock).
    server_s
        The same time on the server's clock (s; NaN before the page's first clock exchange).
    received_s
        When its batch reached the server (s, the server's clock).
    x
        Position (units).
    """

    seq: int
    page_ms: float
    server_s: float
    received_s: float
    x: float


@dataclass(frozen=True)
class Batch:
    """A page's message of samples, as the server received it.

    When it reached the server (``received_s``: s, the server's clock), when the page sent it
    (``sent_ms``: ms, its clock; one animation frame) and how many samples it held (``n``).
    """

    received_s: float
    sent_ms: float
    n: int


class BrowserInput:
    """The pointer samples a participant's page sent and the page's clock (thread-safe).

    A page numbers its batches from 0 on each connection; `reconnected` makes a new
    connection's numbers continue after the last sample's, so ``seq`` keeps growing.

    Attributes
    ----------
    clock
        The page's clock on the server's (`mirror_avatar.realtime.page_clock.PageClock`).
    batches
        Every batch of samples received (`Batch`).
    stalls
        Each gap longer than `STALL_GAP` between two batches: its start (s, the server's
        clock) and length (s).
    interruptions
        The page's tab hidden and its window out of focus
        (`mirror_avatar.realtime.interruptions.Interruptions`).
    """

    def __init__(self) -> None:
        self._latest: Sample | None = None
        self._base = 0
        self._lock = threading.Lock()
        self.clock = PageClock()
        self.batches: list[Batch] = []
        self.stalls: list[tuple[float, float]] = []
        self.interruptions = Interruptions()
        self._unread: list[PointerSample] = []

    def reconnected(self) -> None:
        """Start numbering the next connection's positions after the newest sample."""
        with self._lock:
            self._base = 0 if self._latest is None else self._latest.seq + 1
            self.clock.forget()

    def put_batch(
        self, seq: int, sent_ms: float, samples: list[tuple[float, float]], received_s: float
    ) -> None:
        """Store batch ``seq``: its samples (page time in ms, position in units), oldest first.

        Each sample's time is mapped onto the server's clock with the page's current offset;
        the newest becomes the position the server's clock reads (`put`).
        """
        with self._lock:
            if self.batches and received_s - self.batches[-1].received_s > STALL_GAP:
                start = self.batches[-1].received_s
                self.stalls.append((start, received_s - start))
            self.batches.append(Batch(received_s, sent_ms, len(samples)))
            self._unread += [
                PointerSample(seq + self._base, t, self.clock.to_server(t), received_s, x)
                for t, x in samples
            ]
        self.put(samples[-1][1], seq)

    def unread(self) -> list[PointerSample]:
        """Return the samples received since the previous call, oldest first."""
        with self._lock:
            samples, self._unread = self._unread, []
        return samples

    def rates(self, start_s: float, end_s: float) -> dict[str, object]:
        """Summarise the page between server times ``start_s`` and ``end_s`` (s).

        Returns
        -------
        dict
            ``sample_rate_hz`` (samples received per second), ``frame_rate_hz`` (the page's
            animation frames, one batch each, per second; None when the span is empty) and
            ``stalls`` (``{"start_s", "length_s"}`` of those that began within it).
        """
        span = end_s - start_s
        with self._lock:
            during = [b for b in self.batches if start_s <= b.received_s <= end_s]
            stalls = [(s, n) for s, n in self.stalls if start_s <= s <= end_s]
        frames = len({b.sent_ms for b in during})
        return {
            "sample_rate_hz": sum(b.n for b in during) / span if span > 0 else None,
            "frame_rate_hz": frames / span if span > 0 else None,
            "stalls": [{"start_s": s, "length_s": n} for s, n in stalls],
        }

    def put(self, x: float, seq: int) -> None:
        """Store a position (units) numbered ``seq``; an older or repeated ``seq`` is ignored."""
        with self._lock:
            seq += self._base
            if self._latest is None or seq > self._latest.seq:
                self._latest = Sample(x, seq, time.monotonic())

    def latest(self) -> Sample | None:
        """Return the newest position received, or None before the first."""
        with self._lock:
            return self._latest


@dataclass(frozen=True)
class TickInput:
    """What a `HumanPlayer` used at one tick.

    Attributes
    ----------
    seq
        The sample's sequence number (-1 before any).
    age
        Its age when read (s; NaN before any).
    held
        Whether no new sample had arrived since the previous tick.
    alive
        Whether the input delivered within `LIVENESS_TIMEOUT` (see the module docstring).
    """

    seq: int
    age: float
    held: bool
    alive: bool = True


class HumanPlayer(ExternalPlayer):
    """A person on the server's clock: the newest sample of its `InputSource` at each tick.

    Parameters
    ----------
    source
        The person's input device.
    label
        The person's name in the session.
    period
        Control period T (s), for the finite-difference velocity ``(x_k - x_{k-1}) / T``.
    timeout
        Seconds without a new sample after which the input is judged lost.
    clock
        Monotonic clock (s), the one `Sample.received` is stamped with.

    Attributes
    ----------
    held, lost
        Ticks of the trial at which the position was held, and at which the input was lost.
    last_input
        What the latest tick used (`TickInput`).
    """

    def __init__(
        self,
        source: InputSource,
        label: str,
        period: float = CONTROL_PERIOD,
        timeout: float = LIVENESS_TIMEOUT,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.source = source
        self.label = label
        self.period = period
        self.timeout = timeout
        self.clock = clock
        self.held = self.lost = 0
        self.last_input = TickInput(-1, float("nan"), True)
        self._previous: float | None = None
        self._started = clock()

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        """Start a trial: forget the previous sample and the held and lost counts."""
        self._previous = None
        self.held = self.lost = 0
        self.last_input = TickInput(-1, float("nan"), True)
        self._started = self.clock()
        sample = self.source.latest()
        return (0.0 if sample is None else sample.x), 0.0

    def current_state(self) -> tuple[float, float]:
        """Read the newest sample: its position (units) and the finite-difference velocity."""
        sample = self.source.latest()
        previous_seq = self.last_input.seq
        now = self.clock()
        if sample is None:
            alive = now - self._started <= self.timeout
            x, tick = 0.0, TickInput(-1, float("nan"), True, alive)
        else:
            age = now - sample.received
            heard = max(sample.received, self._started)
            alive = now - heard <= self.timeout
            x, tick = sample.x, TickInput(sample.seq, age, sample.seq == previous_seq, alive)
        self.held += int(tick.held)
        self.lost += int(not tick.alive)
        self.last_input = tick
        before = x if self._previous is None else self._previous
        self._previous = x
        return x, (x - before) / self.period

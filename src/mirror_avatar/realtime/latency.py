"""Round trips between the server and a page, every one of them measured.

The server pings a page at a steady interval; `Pings` remembers when each ping left (up to
`MAX_OUTSTANDING` unanswered ones), so every answer is measured, however late: a page that reads
slowly shows round trips longer than the ping interval, and a page that stops answering shows the
age of its oldest unanswered ping (`Pings.waiting`). `RoundTrips` keeps the measures for
summaries.
"""

from __future__ import annotations

import collections
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

MAX_OUTSTANDING = 1024
"""Most unanswered pings remembered (at 2 a second: over 8 minutes)."""

RECENT = 100
"""Round trips kept for the console's live numbers."""


@dataclass
class RoundTrips:
    """Round-trip times (ms) of a trial or a connection."""

    samples: list[float] = field(default_factory=list)

    def add(self, rtt_ms: float) -> None:
        """Record one round trip (ms)."""
        self.samples.append(rtt_ms)

    def summary(self) -> dict[str, float | int | None]:
        """Count, mean, median, 95th percentile and maximum (ms); None when there are none."""
        return summarise(self.samples)


def summarise(values: Sequence[float]) -> dict[str, float | int | None]:
    """Return the count, mean, median, 95th percentile and maximum of ``values`` (None if none)."""
    if not len(values):
        return {"n": 0, "mean": None, "median": None, "p95": None, "max": None}
    array = np.asarray(values, dtype=np.float64)
    return {
        "n": int(array.size),
        "mean": float(array.mean()),
        "median": float(np.median(array)),
        "p95": float(np.percentile(array, 95)),
        "max": float(array.max()),
    }


class Pings:
    """The pings sent to one page and the round trips of their answers.

    Parameters
    ----------
    clock
        Monotonic clock (s).

    Attributes
    ----------
    recent
        The last `RECENT` round trips (ms).
    answered, unanswered
        Pings answered, and pings forgotten unanswered (beyond `MAX_OUTSTANDING`).
    """

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self.clock = clock
        self._sent: collections.OrderedDict[int, float] = collections.OrderedDict()
        self._next = 0
        self.recent: collections.deque[float] = collections.deque(maxlen=RECENT)
        self.answered = self.unanswered = 0

    def send(self) -> int:
        """Register a new ping and return its id."""
        self._next += 1
        self._sent[self._next] = self.clock()
        if len(self._sent) > MAX_OUTSTANDING:
            self._sent.popitem(last=False)
            self.unanswered += 1
        return self._next

    def answer(self, ping_id: int) -> float | None:
        """Measure the round trip (ms) of ping ``ping_id``; None for an unknown or repeated id."""
        sent = self._sent.pop(ping_id, None)
        if sent is None:
            return None
        rtt = (self.clock() - sent) * 1000.0
        self.recent.append(rtt)
        self.answered += 1
        return rtt

    def waiting(self) -> float | None:
        """Age (ms) of the oldest unanswered ping, or None when every ping was answered."""
        if not self._sent:
            return None
        return (self.clock() - next(iter(self._sent.values()))) * 1000.0

"""A page's clock on the server's: NTP-style exchanges, the offset and its uncertainty.

A page stamps a request with its own time ``t0`` (ms, ``performance.timeOrigin +
performance.now()``); the server stamps its receipt ``t1`` and its answer ``t2`` (ms, the
session's clock, the one ``clock_s`` of a trial's inputs file is on); the page stamps the
answer's arrival ``t3`` and reports it. One exchange gives (RFC 5905, section 8)::

    offset = ((t1 - t0) + (t2 - t3)) / 2      server time = page time + offset
    delay  = (t3 - t0) - (t2 - t1)            the round trip, the server's own time out

and the offset is wrong by at most half the delay (the legs' difference halved), the textbook
bound. `PageClock.estimate` takes the exchanges of the last `WINDOW`, keeps the `KEPT` share
with the smallest delays (NTP's minimum-delay filter: queueing only ever adds delay, so the
fastest exchanges are the least skewed) and averages their offsets (against a symmetric jitter
the legs' difference does not shrink with the delay: only averaging narrows it). Its uncertainty
is half the smallest delay of the window. METHODS section 18.
"""

from __future__ import annotations

import collections
import math
from dataclasses import dataclass

import numpy as np

from mirror_avatar.realtime.latency import summarise

WINDOW = 600
"""Exchanges an estimate is made from: at 10 a second, the last minute (**choice**: two
computers' clocks drift apart by tens of ppm, under 1.5 ms over half a minute)."""

KEPT = 0.25
"""Share of a window's exchanges, those of smallest delay, whose offsets are averaged
(**choice**: a full window's 150 average a symmetric jitter's 17.7 ms down to 1.4 ms, and
leave out the exchanges a busy machine queued longest)."""

MAX_PENDING = 256
"""Exchanges awaiting the page's report remembered (older ones are forgotten)."""


@dataclass(frozen=True)
class Exchange:
    """One NTP-style exchange's four times (ms).

    Page send ``t0``, server receipt ``t1``, server send ``t2``, page receipt ``t3``; ``t0`` and
    ``t3`` on the page's clock, ``t1`` and ``t2`` on the server's.
    """

    t0: float
    t1: float
    t2: float
    t3: float

    @property
    def offset(self) -> float:
        """Server time minus page time (ms), as this exchange measures it."""
        return ((self.t1 - self.t0) + (self.t2 - self.t3)) / 2.0

    @property
    def delay(self) -> float:
        """Round trip (ms), the server's time between receipt and answer left out."""
        return (self.t3 - self.t0) - (self.t2 - self.t1)


@dataclass(frozen=True)
class Estimate:
    """The offset of a page's clock at server time ``at_s`` (s).

    ``offset_ms``: server time minus page time (ms); ``uncertainty_ms``: half the smallest round
    trip it was made from (ms).
    """

    at_s: float
    offset_ms: float
    uncertainty_ms: float


def estimate(exchanges: list[Exchange], kept: float = KEPT) -> tuple[float, float]:
    """Return the offset and uncertainty (ms) of ``exchanges`` (see the module docstring)."""
    ordered = sorted(exchanges, key=lambda e: e.delay)
    best = ordered[: max(1, math.ceil(kept * len(ordered)))]
    return float(np.mean([e.offset for e in best])), ordered[0].delay / 2.0


class PageClock:
    """One page's exchanges, its clock's estimates and how its time maps onto the server's.

    Attributes
    ----------
    exchanges
        Every exchange completed, in order.
    estimates
        The estimate after each exchange (`Estimate`).
    """

    def __init__(self, window: int = WINDOW) -> None:
        self.window = window
        self.exchanges: list[Exchange] = []
        self.estimates: list[Estimate] = []
        self._recent: collections.deque[Exchange] = collections.deque(maxlen=window)
        self._pending: collections.OrderedDict[int, tuple[float, float, float]] = (
            collections.OrderedDict()
        )

    def answer(self, exchange_id: int, t0: float, t1: float, t2: float) -> None:
        """Remember the server's times (ms) of request ``exchange_id`` until the page reports."""
        self._pending[exchange_id] = (t0, t1, t2)
        if len(self._pending) > MAX_PENDING:
            self._pending.popitem(last=False)

    def forget(self) -> None:
        """Forget the exchanges awaiting a report (a new connection numbers its own)."""
        self._pending.clear()

    def complete(self, exchange_id: int, t3: float) -> Exchange | None:
        """Complete exchange ``exchange_id`` with the page's receipt ``t3`` (ms).

        Returns None for an unknown id or an impossible exchange (a negative delay).
        """
        times = self._pending.pop(exchange_id, None)
        if times is None:
            return None
        exchange = Exchange(*times, t3)
        if exchange.delay < 0.0:
            return None
        self.exchanges.append(exchange)
        self._recent.append(exchange)
        offset, uncertainty = estimate(list(self._recent))
        self.estimates.append(Estimate(exchange.t2 / 1000.0, offset, uncertainty))
        return exchange

    @property
    def offset_ms(self) -> float:
        """The latest estimate's offset, server time minus page time (ms); NaN before any."""
        return self.estimates[-1].offset_ms if self.estimates else math.nan

    def recent_delays(self) -> list[float]:
        """Return the round trips (ms) of the exchanges the latest estimate was made from."""
        return [exchange.delay for exchange in self._recent]

    def to_server(self, page_ms: float) -> float:
        """Map a page time (ms) onto the server's clock (s); NaN before the first exchange."""
        if not self.estimates:
            return math.nan
        return (page_ms + self.estimates[-1].offset_ms) / 1000.0

    def summary(self, start_s: float, end_s: float) -> dict[str, object]:
        """Summarise the exchanges and estimates between server times ``start_s`` and ``end_s`` (s).

        Returns
        -------
        dict
            ``exchanges``, ``rtt_ms`` (`mirror_avatar.realtime.latency.summarise`),
            ``offset_ms`` and ``uncertainty_ms`` (each: first, median, min and max; None if
            none).
        """
        during = [e for e in self.estimates if start_s <= e.at_s <= end_s]
        delays = [e.delay for e in self.exchanges if start_s <= e.t2 / 1000.0 <= end_s]
        return {
            "exchanges": len(delays),
            "rtt_ms": summarise(delays),
            "offset_ms": _spread([e.offset_ms for e in during]),
            "uncertainty_ms": _spread([e.uncertainty_ms for e in during]),
        }


def _spread(values: list[float]) -> dict[str, float] | None:
    if not values:
        return None
    array = np.asarray(values)
    return {
        "first": float(array[0]),
        "median": float(np.median(array)),
        "min": float(array.min()),
        "max": float(array.max()),
    }

"""Rate limits: a token bucket per client, connection or address."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field


@dataclass
class TokenBucket:
    """A rate limit: ``rate`` events per second sustained, up to ``burst`` at once.

    Parameters
    ----------
    rate
        Tokens added per second.
    burst
        Most tokens held (and the number available at first).
    clock
        Monotonic time source (s).
    """

    rate: float
    burst: float
    clock: Callable[[], float] = time.monotonic
    tokens: float = field(init=False)
    updated: float = field(init=False)

    def __post_init__(self) -> None:
        self.tokens = self.burst
        self.updated = self.clock()

    def take(self) -> float:
        """Take one token: 0.0 when allowed, else the seconds until one is available."""
        now = self.clock()
        self.tokens = min(self.burst, self.tokens + (now - self.updated) * self.rate)
        self.updated = now
        if self.tokens >= 1.0:
            self.tokens -= 1.0
            return 0.0
        return (1.0 - self.tokens) / self.rate


MAX_TRACKED = 10_000
"""Most addresses whose rates are tracked at once (beyond that the table starts afresh)."""


def bucket_for(
    buckets: dict[str, TokenBucket],
    address: str,
    rate: float,
    burst: float,
    clock: Callable[[], float] = time.monotonic,
) -> TokenBucket:
    """Return ``address``'s bucket in ``buckets``, made on first use (at most `MAX_TRACKED`)."""
    if address not in buckets:
        if len(buckets) > MAX_TRACKED:
            buckets.clear()
        buckets[address] = TokenBucket(rate, burst, clock)
    return buckets[address]

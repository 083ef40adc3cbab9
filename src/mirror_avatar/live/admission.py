"""Who may connect to the live server, how many at once, and how often.

Three guards, each configurable through `mirror_avatar.live.server.LiveSettings`:

- `host_allowed`: without an access token the server answers only requests addressed to a
  loopback name or address (or a name the researcher allows), so a page of another site whose
  name resolves to 127.0.0.1 (DNS rebinding) cannot reach it.
- `Admission`: at most ``max_sessions`` connections, at most ``max_per_address`` from one client
  address. When a newcomer finds no room, the connection that has been idle longest - no trial
  running, connected for at least ``evict_after`` seconds - is evicted to make room (its page
  reconnects when its participant presses Start), so a connection that never plays cannot hold
  a slot a participant needs; a connection with a running trial is never evicted.
- `TokenBucket`: rates - new connections per address, trial starts per address and per
  connection, and messages per connection - each a sustained rate with a burst.
"""

from __future__ import annotations

import ipaddress
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

LOOPBACK_NAMES = frozenset({"localhost"})
"""Host names that always mean this machine (addresses are recognised as loopback by value)."""


def host_name(host_header: str | None) -> str:
    """Return the name or address of a ``Host`` header without its port or IPv6 brackets."""
    host = (host_header or "").strip().lower()
    if host.startswith("["):
        return host[1:].split("]", 1)[0]
    return host.rsplit(":", 1)[0] if host.count(":") == 1 else host


def is_loopback(host: str) -> bool:
    """Whether ``host`` (a name or an address) only reaches this machine."""
    if host in LOOPBACK_NAMES or host.endswith(".localhost"):
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def host_allowed(host_header: str | None, allowed: frozenset[str]) -> bool:
    """Whether a request addressed to ``host_header`` may be answered without a token.

    Loopback names and addresses always may; other names only when listed in ``allowed``.
    """
    host = host_name(host_header)
    return is_loopback(host) or host in allowed


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


class Client(Protocol):
    """What `Admission` needs to know of a connection."""

    address: str
    opened: float
    last_active: float

    @property
    def playing(self) -> bool:
        """Whether a trial is running (such a connection is never evicted)."""
        ...

    def evict(self) -> None:
        """Close the connection to make room for another."""
        ...


@dataclass
class Admission:
    """The live server's connections, with per-address limits and eviction of idle ones.

    Parameters
    ----------
    max_sessions
        Most connections at once.
    max_per_address
        Most connections from one client address.
    evict_after
        Seconds a connection without a trial must have been open before it may be evicted.
    connect_rate, connect_burst
        New connections per second (sustained, burst) from one address.
    start_rate, start_burst
        Trial starts per second (sustained, burst) from one address.
    clock
        Monotonic time source (s).
    """

    max_sessions: int
    max_per_address: int
    evict_after: float
    connect_rate: float
    connect_burst: float
    start_rate: float
    start_burst: float
    clock: Callable[[], float] = time.monotonic
    clients: list[Client] = field(default_factory=list)
    _connects: dict[str, TokenBucket] = field(default_factory=dict)
    _starts: dict[str, TokenBucket] = field(default_factory=dict)

    def admit(self, client: Client) -> str | None:
        """Register ``client``, evicting an idle connection if need be; or say why not."""
        bucket = self._bucket(self._connects, client.address, self.connect_rate,
                              self.connect_burst)  # fmt: skip
        if bucket.take() > 0.0:
            return "too many connections from this address: wait a moment"
        same = [c for c in self.clients if c.address == client.address]
        if len(same) >= self.max_per_address and not self._evict(same):
            return "too many connections from this address"
        if len(self.clients) >= self.max_sessions and not self._evict(self.clients):
            return "server busy: too many players"
        self.clients.append(client)
        return None

    def release(self, client: Client) -> None:
        """Forget ``client`` (its connection ended)."""
        if client in self.clients:
            self.clients.remove(client)

    def start_wait(self, address: str) -> float:
        """Take a trial start for ``address``: 0.0 when allowed, else seconds to wait."""
        return self._bucket(self._starts, address, self.start_rate, self.start_burst).take()

    def _evict(self, candidates: list[Client]) -> bool:
        now = self.clock()
        idle = [c for c in candidates if not c.playing and now - c.opened >= self.evict_after]
        if not idle:
            return False
        victim = min(idle, key=lambda c: c.last_active)
        self.release(victim)
        victim.evict()
        return True

    def _bucket(
        self, buckets: dict[str, TokenBucket], address: str, rate: float, burst: float
    ) -> TokenBucket:
        if address not in buckets:
            if len(buckets) > 10_000:
                buckets.clear()
            buckets[address] = TokenBucket(rate, burst, self.clock)
        return buckets[address]

"""Who may connect to the live server, how many at once, and how often.

Two guards, each configurable through `mirror_avatar.live.server.LiveSettings` (the host,
token and origin checks are the shared gates of `mirror_avatar.realtime.gates`):

- `Admission`: at most ``max_sessions`` connections, at most ``max_per_address`` from one client
  address. When a newcomer finds no room, the connection that has been idle longest - no trial
  running, connected for at least ``evict_after`` seconds - is evicted to make room (its page
  reconnects when its participant presses Start), so a connection that never plays cannot hold
  a slot a participant needs; a connection with a running trial is never evicted.
- `mirror_avatar.realtime.rates.TokenBucket`: rates - new connections per address, trial
  starts per address and per connection, and messages per connection - each a sustained rate
  with a burst.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

from mirror_avatar.realtime.rates import TokenBucket, bucket_for


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
        bucket = bucket_for(self._connects, client.address, self.connect_rate,
                            self.connect_burst, self.clock)  # fmt: skip
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
        return bucket_for(
            self._starts, address, self.start_rate, self.start_burst, self.clock
        ).take()

    def _evict(self, candidates: list[Client]) -> bool:
        now = self.clock()
        idle = [c for c in candidates if not c.playing and now - c.opened >= self.evict_after]
        if not idle:
            return False
        victim = min(idle, key=lambda c: c.last_active)
        self.release(victim)
        victim.evict()
        return True

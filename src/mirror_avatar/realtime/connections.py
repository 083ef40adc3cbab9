"""The connections a server holds: caps per client address and in total, and their log.

`Connections` admits each new connection before anything of it is read, or refuses it: an
address opening more than `ConnectionSettings.connection_rate` connections per second, or
holding `ConnectionSettings.max_per_address`, gets no more, and when the
server holds `ConnectionSettings.max_connections` a newcomer takes the place of the oldest
connection waiting for its first request, else of the oldest kept alive between two requests,
else of the oldest whose request's body is still arriving (`Holder.spare`), or is refused when
there is none. A request being answered and a WebSocket are never closed to make room: a
participant's page, once joined, keeps its connection, and a flood of connections, from however
many addresses, cannot keep a newcomer (the researcher's console, a page) out. Refusals and the
connections closed for a late request are logged once per address per
`ConnectionSettings.log_interval` (`QuietLog`), so a flood does not flood the log.
"""

from __future__ import annotations

import collections
import logging
import resource
import time
from collections.abc import Callable
from typing import Protocol

from mirror_avatar.realtime.rates import MAX_TRACKED, TokenBucket, bucket_for
from mirror_avatar.realtime.settings import ConnectionSettings

LOG = logging.getLogger("uvicorn.error")
"""The servers' log (uvicorn's, which the real-time servers print)."""


MADE_ROOM = "connections closed to make room, the server is full"
"""The log's phrase for connections closed by `Connections` to admit another."""


class Holder(Protocol):
    """What `Connections` needs of a connection: its address, its state, how to close it."""

    address: str

    @property
    def spare(self) -> int | None:
        """In what turn it may be closed to make room, or ``None`` when it must not be.

        0: it waits for its first request; 1: it is kept alive between two requests; 2: its
        request's body is still arriving; ``None``: a request being answered, a WebSocket.
        """
        ...

    def close_now(self) -> None:
        """Close the connection at once, discarding what it has not sent."""
        ...


def descriptor_share() -> int:
    """Half this process's soft limit of open file descriptors (``ulimit -n``)."""
    soft = resource.getrlimit(resource.RLIMIT_NOFILE)[0]
    return soft // 2 if soft != resource.RLIM_INFINITY else 2**31


class QuietLog:
    """Log lines about one address at most once per ``interval`` seconds, counting the others.

    The first event of a kind from an address is logged at once; later ones are counted and
    logged, with their number, with the first one after the interval has passed.
    """

    def __init__(self, interval: float, clock: Callable[[], float] = time.monotonic) -> None:
        self.interval = interval
        self.clock = clock
        self.counts: collections.Counter[tuple[str, str]] = collections.Counter()
        self.logged: dict[tuple[str, str], float] = {}

    def event(self, address: str, what: str) -> None:
        """Count one event ``what`` (a phrase) of ``address``; log it if its interval passed."""
        key = (address, what)
        if len(self.logged) > MAX_TRACKED:
            self.logged.clear()
            self.counts.clear()
        self.counts[key] += 1
        now = self.clock()
        if now - self.logged.get(key, -self.interval) >= self.interval:
            LOG.warning("%s: %s: %d (one line per address per %g s at most)", address, what,
                        self.counts[key], self.interval)  # fmt: skip
            self.logged[key] = now
            del self.counts[key]


class Connections:
    """The connections a server holds, in the order they came (see the module docstring).

    Parameters
    ----------
    settings
        The caps and the log's interval.
    """

    def __init__(self, settings: ConnectionSettings) -> None:
        self.max_per_address = settings.max_per_address
        self.max_connections = min(settings.max_connections, descriptor_share())
        self.log = QuietLog(settings.log_interval)
        self.held: dict[object, Holder] = {}
        self.per_address: collections.Counter[str] = collections.Counter()
        self.rate = settings.connection_rate
        self.rates: dict[str, TokenBucket] = {}

    def admit(self, key: object, holder: Holder) -> bool:
        """Hold ``holder`` under ``key`` (its transport) if there is room; whether it is held."""
        bucket = bucket_for(self.rates, holder.address, self.rate, 2.0 * self.max_per_address)
        if bucket.take() > 0.0:
            self.log.event(holder.address, "connections refused, opened too fast")
            return False
        if self.per_address[holder.address] >= self.max_per_address:
            self.log.event(holder.address, "connections refused, too many from this address")
            return False
        if len(self.held) >= self.max_connections and not self._make_room():
            self.log.event(holder.address, "connections refused, the server is full")
            return False
        self.held[key] = holder
        self.per_address[holder.address] += 1
        return True

    def release(self, key: object) -> None:
        """Forget the connection held under ``key`` (closed)."""
        holder = self.held.pop(key, None)
        if holder is not None:
            self.per_address[holder.address] -= 1
            if not self.per_address[holder.address]:
                del self.per_address[holder.address]

    def _make_room(self) -> bool:
        """Close the connection spared least (`Holder.spare`), the oldest of those; whether any."""
        turns = [(turn, n, key) for n, (key, holder) in enumerate(self.held.items())
                 if (turn := holder.spare) is not None]  # fmt: skip
        if not turns:
            return False
        key = min(turns)[2]
        holder = self.held[key]
        self.release(key)
        holder.close_now()
        self.log.event(holder.address, MADE_ROOM)
        return True

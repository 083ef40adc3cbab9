"""What both real-time servers let a page do, and how slow an avatar may be."""

from __future__ import annotations

from dataclasses import dataclass

from mirror_avatar.realtime.clock import MAX_STEP


@dataclass(frozen=True, kw_only=True)
class PageSettings:
    """Settings every real-time server shares (keyword arguments of its own settings).

    Parameters
    ----------
    countdown
        Seconds of countdown before a trial starts.
    max_tick
        Seconds one step of the avatars may take before the trial is ended.
    send_timeout
        Seconds a message may wait for a page that does not read before the page is dropped.
    max_message_rate
        Messages per second a page may send (sustained; bursts of a second's worth).
    max_rejected
        Bad messages tolerated on one connection before it is closed.
    """

    countdown: int = 3
    max_tick: float = MAX_STEP
    send_timeout: float = 2.0
    max_message_rate: float = 250.0
    max_rejected: int = 100


@dataclass(frozen=True, kw_only=True)
class ConnectionSettings:
    """How long a request may take to arrive, and how many connections a server holds.

    Both real-time servers (`mirror_avatar.realtime.transport.make_server`) apply them to every
    connection before any request reaches the application (`mirror_avatar.realtime.protocols`,
    `mirror_avatar.realtime.connections`).

    Parameters
    ----------
    header_timeout
        Seconds from a connection's opening (or, on a kept-alive connection, from the first
        byte of its next request) to the end of the request's headers; then it is closed
        (**choice**: hyper's and Go's servers time the headers the same way).
    body_timeout
        Seconds from the end of a request's headers to the end of its body; then it is closed.
    max_per_address
        Connections one client address may hold open at once (HTTP requests and WebSockets);
        one more is closed at once.
    connection_rate
        New connections per second one client address may open (sustained; bursts of twice
        ``max_per_address``); one more is closed at once, before anything of it is read, which
        costs the server far less than refusing its request once read (the gates' rates).
    max_connections
        Connections the server holds open at once, at most half its limit of open file
        descriptors (``ulimit -n``: the other half is left for its files). A newcomer beyond it
        takes the place of the oldest connection waiting for its first request (else for its
        next one, else for the rest of its request's body), or is closed at once when there is
        none.
    log_interval
        Seconds between two log lines about one address's refused or timed-out connections
        (the first is logged at once, the next ones counted).
    """

    header_timeout: float = 10.0
    body_timeout: float = 20.0
    max_per_address: int = 32
    connection_rate: float = 50.0
    max_connections: int = 1000
    log_interval: float = 10.0

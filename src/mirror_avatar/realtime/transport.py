"""The servers' sockets: listening, aborting a connection that stopped reading, quiet logs.

Both real-time servers run under uvicorn (`make_server`) on a socket bound before the server
starts (`listening_socket`), with protocols that time each request's arrival and cap the
connections per client address and in total (`mirror_avatar.realtime.protocols`). Its event
loop accepts at most `ACCEPT_BATCH` connections at a time and the objects that exist once it
serves are left out of garbage collection (`RealtimeServer`), so that neither a flood of
connections nor a collection holds it for long. A connection whose client stopped reading is
aborted (`abort_transport`), not closed gracefully, so its socket cannot linger; the transport
is reached through the server's own ASGI ``send`` callable, which the gates keep in the scope
under `SERVER_SEND` (`mirror_avatar.realtime.gates`). The access log leaves secrets out
(`RedactSecrets`): tokens in query strings and the keys of join links.
"""

from __future__ import annotations

import asyncio
import gc
import logging
import re
import secrets
import socket

import uvicorn
from starlette.types import ASGIApp
from starlette.websockets import WebSocket

from mirror_avatar.realtime.protocols import GuardedConfig
from mirror_avatar.realtime.settings import ConnectionSettings
from mirror_avatar.realtime.tls import TlsFiles

MAX_FRAME_BYTES = 16 * 1024
"""Largest WebSocket frame the servers read at all (bytes); larger ones close the connection."""

SERVER_SEND = "mirror_avatar.server_send"
"""Scope key of the ASGI server's own ``send`` callable (see `abort_transport`)."""


def abort_transport(websocket: WebSocket, delay: float = 0.0) -> None:
    """Close a connection's socket at once, or after ``delay`` seconds, discarding the rest.

    A graceful close would wait for a client that stopped reading to take the queued data, so
    its socket would stay open. The transport is reached through the server's own ASGI ``send``
    callable, which the gates keep in the scope (uvicorn's is a method of its protocol
    object); under a server that does not expose it the connection is left to its own close.
    """
    transport = _transport(websocket)
    if transport is not None:
        asyncio.get_running_loop().call_later(delay, transport.abort)


def stop_reading(websocket: WebSocket) -> None:
    """Read nothing more from a connection's socket (a flooding client's data stays unread)."""
    transport = _transport(websocket)
    if transport is not None:
        transport.pause_reading()


def _transport(websocket: WebSocket) -> asyncio.Transport | None:
    """Return the socket transport under ``websocket``, if the server exposes it (the gates)."""
    protocol = getattr(websocket.scope.get(SERVER_SEND), "__self__", None)
    transport = getattr(protocol, "transport", None)
    return transport if isinstance(transport, asyncio.Transport) else None


def make_token() -> str:
    """Generate a fresh random access token (URL-safe, 128 bits)."""
    return secrets.token_urlsafe(16)


LISTEN_BACKLOG = 2048
"""Connections the kernel queues for the server before it accepts them (uvicorn's default)."""

ACCEPT_BATCH = 4
"""Most connections the event loop accepts in one turn (**choice**). asyncio accepts up to the
listen backlog's number of waiting connections in one turn of the loop, and the next turns
handshake all of them before anything else waiting runs: under a flood of connections, with
thousands queued, a turn lasted long enough for the trials' clocks to fall behind. With a small
batch each turn stays short, so the clocks' timers, the pages' frames and their positions wait
for a few handshakes at most; the rest of a flood waits in the kernel's queue."""

RECEIVE_BUFFER_BYTES = 8192
"""Kernel receive buffer of each connection (bytes; Linux doubles it; **choice**). One read
of a client's data is parsed whole before the event loop moves on, so the buffer bounds the
frames a flooding client can make the server parse at once (a few hundred), while a browser
sends a few kilobytes per second."""


def listening_socket(host: str, port: int) -> socket.socket:
    """Bind the server's socket and listen (IPv4 or IPv6 by ``host``; port 0: any free port).

    The socket listens before the server runs, so a client that connects as soon as the address
    is printed waits in the kernel's queue (`LISTEN_BACKLOG` connections) instead of being
    refused.
    Accepted connections inherit its `RECEIVE_BUFFER_BYTES` receive buffer, and its protocol
    (TCP by name), from which asyncio turns Nagle's algorithm off on each (``TCP_NODELAY``): a
    small message is sent at once instead of waiting for the client's acknowledgement of the
    previous one.
    """
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM, socket.IPPROTO_TCP)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER_BYTES)
    try:
        sock.bind((host, port))
        sock.listen(LISTEN_BACKLOG)
    except OSError:
        sock.close()
        raise
    return sock


def make_server(
    app: ASGIApp,
    host: str,
    port: int,
    log_level: str = "warning",
    guard: ConnectionSettings | None = None,
    tls: TlsFiles | None = None,
) -> uvicorn.Server:
    """Configure a uvicorn server for ``app`` (sans-I/O WebSockets, `MAX_FRAME_BYTES` frames).

    Its connections are guarded by ``guard`` (request deadlines, caps: `GuardedConfig`;
    default: `ConnectionSettings`'s defaults); with ``tls`` it serves HTTPS and secure
    WebSockets with that certificate (its files checked by the caller: `TlsFiles.check`); its
    logs leave secrets out (`keep_secrets_out_of_logs`).
    """
    config = GuardedConfig(
        app,
        guard or ConnectionSettings(),
        host=host,
        port=port,
        ws_max_size=MAX_FRAME_BYTES,
        log_level=log_level,
        lifespan="off",
        backlog=ACCEPT_BATCH,
        **({} if tls is None else tls.uvicorn_options()),
    )
    keep_secrets_out_of_logs()
    return RealtimeServer(config)


class RealtimeServer(uvicorn.Server):
    """A uvicorn server whose event loop is never held long by accepting or collecting.

    - It accepts `ACCEPT_BATCH` connections at a time. asyncio takes one number, the server's
      ``backlog``, both for the kernel's queue (``listen``) and for the connections accepted in
      one turn of the loop; the server is configured with `ACCEPT_BATCH`, and once it listens
      its sockets are set back to queue `LISTEN_BACKLOG` connections.
    - Before it serves, the objects that exist (the modules imported: hundreds of thousands) are
      frozen out of garbage collection (`gc.freeze`, **choice**): a full collection would
      otherwise walk them all, holding every thread (the trials' clocks among them) while it
      runs, which a flood of connections, with all the objects it makes, triggers often.
    """

    async def startup(self, sockets: list[socket.socket] | None = None) -> None:
        """Freeze the heap, start serving, let the kernel queue `LISTEN_BACKLOG` connections.

        The heap is frozen before the base class marks the server ``started``, so whoever
        waits for that flag finds it frozen.
        """
        gc.collect()
        gc.freeze()
        await super().startup(sockets)
        for server in self.servers:
            for listener in server.sockets:  # the kernel's socket through a duplicate handle
                with socket.fromfd(listener.fileno(), listener.family, listener.type) as sock:
                    sock.listen(LISTEN_BACKLOG)


SECRETS = re.compile(r"(token=|/join/)[^&\s\"/?]+")
"""Where secrets stand in a request line: a token query parameter, a join link's key."""


class RedactSecrets(logging.Filter):
    """A logging filter replacing tokens and join keys in log records by ``***``."""

    def filter(self, record: logging.LogRecord) -> bool:
        """Redact the record's arguments (uvicorn's access log puts the path there)."""
        if isinstance(record.args, tuple):
            record.args = tuple(
                SECRETS.sub(r"\1***", arg) if isinstance(arg, str) else arg for arg in record.args
            )
        record.msg = SECRETS.sub(r"\1***", str(record.msg))
        return True


def keep_secrets_out_of_logs() -> None:
    """Install `RedactSecrets` on uvicorn's logs (HTTP requests and WebSocket handshakes)."""
    for name in ("uvicorn.access", "uvicorn.error"):
        log = logging.getLogger(name)
        if not any(isinstance(f, RedactSecrets) for f in log.filters):
            log.addFilter(RedactSecrets())

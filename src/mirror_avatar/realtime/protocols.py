"""uvicorn's HTTP and WebSocket protocols with a deadline for each request and a cap on connections.

uvicorn times only the idle time between two requests of a kept-alive connection; a client
that sends part of a request, or trickles it a byte at a time, holds its connection (and a file
descriptor) for ever. `GuardedHttp` closes a connection whose request's headers have not
arrived within `ConnectionSettings.header_timeout` of its opening (or of the first byte of a
kept-alive connection's next request), or whose body has not within
`ConnectionSettings.body_timeout` of its headers: absolute deadlines, so trickling does not
extend them. It asks `mirror_avatar.realtime.connections.Connections` to admit each connection
before reading anything of it, and closes it at once when refused. A connection upgraded to a
WebSocket is handed to `GuardedWebSocket`, which keeps it counted until it closes.

Both are set on the server by `GuardedConfig` (uvicorn takes protocol classes as its ``http``
and ``ws`` settings); `mirror_avatar.realtime.transport.make_server` uses it.
"""

from __future__ import annotations

import asyncio
from typing import Any

import h11
import uvicorn
from starlette.types import ASGIApp
from uvicorn.protocols.http.h11_impl import H11Protocol
from uvicorn.protocols.utils import get_remote_addr
from uvicorn.protocols.websockets.websockets_sansio_impl import WebSocketsSansIOProtocol
from uvicorn.server import ServerState

from mirror_avatar.realtime.connections import Connections
from mirror_avatar.realtime.settings import ConnectionSettings


class GuardedConfig(uvicorn.Config):
    """A uvicorn configuration serving with `GuardedHttp` and `GuardedWebSocket`.

    Parameters
    ----------
    app
        The application.
    guard
        The deadlines and caps.
    **options
        uvicorn's other settings (`uvicorn.Config`).
    """

    def __init__(self, app: ASGIApp, guard: ConnectionSettings, **options: Any) -> None:
        super().__init__(app, http=GuardedHttp, ws=GuardedWebSocket, **options)
        self.guard = guard
        self.connections = Connections(guard)


def _guarded(config: uvicorn.Config) -> GuardedConfig:
    if not isinstance(config, GuardedConfig):
        raise TypeError("the guarded protocols need a GuardedConfig")
    return config


def _address(transport: asyncio.BaseTransport) -> str:
    """Return the client address of a connection ('' when it has none: a Unix socket)."""
    remote = get_remote_addr(transport)  # type: ignore[arg-type]
    return remote[0] if remote else ""


class GuardedHttp(H11Protocol):
    """uvicorn's h11 protocol, admitted by `Connections`, each request's arrival timed."""

    def __init__(
        self,
        config: uvicorn.Config,
        server_state: ServerState,
        app_state: dict[str, Any],
        _loop: asyncio.AbstractEventLoop | None = None,
    ) -> None:
        super().__init__(config, server_state, app_state, _loop)
        self.guard = _guarded(config)
        self.address = ""
        self.admitted = False
        self.upgraded = False
        self.phase = ""  # what is awaited against a deadline: "headers", "body" or nothing
        self.deadline: asyncio.TimerHandle | None = None

    @property
    def spare(self) -> int | None:
        """In what turn it may be closed to make room (`Connections`), or ``None``."""
        if self.upgraded:
            return None
        if self.conn.their_state is h11.IDLE:
            return 0 if self.cycle is None else 1
        return 2 if self.conn.their_state is h11.SEND_BODY else None

    def close_now(self) -> None:
        """Close the connection at once."""
        self.transport.abort()

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        """Admit the connection and await its request's headers, or close it at once."""
        self.address = _address(transport)
        self.admitted = self.guard.connections.admit(transport, self)
        if not self.admitted:
            transport.abort()
            return
        super().connection_made(transport)
        self._watch()

    def connection_lost(self, exc: Exception | None) -> None:
        """Forget a closed connection (one refused was never held)."""
        if self.admitted:
            self._set_deadline("")
            self.guard.connections.release(self.transport)
            super().connection_lost(exc)

    def data_received(self, data: bytes) -> None:
        """Parse what arrived, then time what is still awaited."""
        super().data_received(data)
        self._watch()

    def handle_websocket_upgrade(self, event: h11.Request) -> None:
        """Hand the connection to the WebSocket protocol (no deadline: the request arrived)."""
        self.upgraded = True
        self._set_deadline("")
        super().handle_websocket_upgrade(event)

    def _watch(self) -> None:
        """Set the deadline of what the connection awaits: a request's headers, or its body.

        A kept-alive connection between requests is left to uvicorn's keep-alive timeout
        until a byte of its next request arrives.
        """
        if self.upgraded or self.transport.is_closing():
            self._set_deadline("")
        elif self.conn.their_state is h11.IDLE:
            self._set_deadline("headers")
        elif self.conn.their_state is h11.SEND_BODY:
            self._set_deadline("body")
        else:
            self._set_deadline("")

    def _set_deadline(self, phase: str) -> None:
        """Start the deadline of ``phase`` unless it runs already; none for ''."""
        if phase == self.phase:
            return
        if self.deadline is not None:
            self.deadline.cancel()
            self.deadline = None
        self.phase = phase
        if phase:
            seconds = self._timeout(phase)
            self.deadline = self.loop.call_later(seconds, self._time_out)

    def _timeout(self, phase: str) -> float:
        guard = self.guard.guard
        return guard.header_timeout if phase == "headers" else guard.body_timeout

    def _time_out(self) -> None:
        """Close a connection whose request's headers or body came too late."""
        self.deadline = None
        late = f"requests closed, their {self.phase} not complete within "
        self.guard.connections.log.event(self.address, f"{late}{self._timeout(self.phase):g} s")
        self.transport.abort()


class GuardedWebSocket(WebSocketsSansIOProtocol):
    """uvicorn's WebSocket protocol, its connection counted by `Connections` until it closes."""

    def connection_lost(self, exc: Exception | None) -> None:
        """Close as uvicorn does, then forget the connection."""
        super().connection_lost(exc)
        _guarded(self.config).connections.release(self.transport)

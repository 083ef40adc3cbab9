"""The live server: one page, one WebSocket per browser tab, one avatar per trial.

`create_app` builds the ASGI application (starlette): ``/`` serves the page, ``/static/`` its
script and style, and ``/ws`` the game's WebSocket (messages in `mirror_avatar.live.protocol`).
Each connection plays at most one trial at a time (`mirror_avatar.live.session.LiveTrial`): a
task ticks it every control period on absolute deadlines, while the receive loop stores the
pointer's latest position and answers each one at once with the avatar's position.

Robustness: a malformed, oversized or out-of-range message is answered with an ``error`` and
ignored, as are messages beyond ``max_message_rate`` (a connection sending more than
``max_rejected`` of them is closed with code 1008, and nothing more it sends is read: its
socket is aborted ``send_timeout`` seconds later); connections are admitted by
`mirror_avatar.live.admission.Admission` (global and per-address limits, idle connections
evicted for newcomers, close code 1013 when there is no room) and trial starts are rate-limited
per connection and per address; a connection without a trial that sends nothing for
``idle_timeout`` seconds is closed (code 4000); a trial whose browser stops sending for
``stale_timeout`` seconds is saved as incomplete and its connection closed (code 4408); a client
that stops reading, so that a message cannot be delivered within ``send_timeout``, is dropped; a
dropped connection saves its trial as incomplete. Each tick of a trial runs in a worker thread
(the compiled steps release the GIL), so a slow avatar delays only its own trial, which is ended
when a tick takes longer than ``max_tick``. No connection's failure touches another's files.

Access: when the settings hold a token, every HTTP request and WebSocket handshake must carry it,
as the ``token`` query parameter or the cookie the page sets; ``serve`` generates one whenever
the server binds to a non-loopback address. Without a token, only requests addressed to a
loopback name or address, or to a name in ``allowed_hosts``, are answered (DNS rebinding).
WebSocket handshakes from another origin are refused.
"""

from __future__ import annotations

import asyncio
import contextlib
import hmac
import json
import logging
import secrets
import socket
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import uvicorn
from starlette.applications import Starlette
from starlette.requests import HTTPConnection, Request
from starlette.responses import FileResponse, PlainTextResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.types import ASGIApp, Receive, Scope, Send
from starlette.websockets import WebSocket, WebSocketClose, WebSocketDisconnect

from mirror_avatar.atomic import json_safe
from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.errors import InputError
from mirror_avatar.experiments.cyber_player import BASELINE_SESSIONS, VALIDATION_SESSIONS
from mirror_avatar.experiments.personal_avatar import DEFAULT_SESSIONS
from mirror_avatar.live.admission import Admission, TokenBucket, host_allowed
from mirror_avatar.live.avatar_build import build_avatar, describe_avatar
from mirror_avatar.live.protocol import (
    DURATION_RANGE,
    MODES,
    BuildRequest,
    Message,
    PositionUpdate,
    ProtocolError,
    StartRequest,
    StopRequest,
    parse_message,
)
from mirror_avatar.live.session import (
    AvatarFactory,
    LiveTrial,
    make_avatar_factory,
    start_trial,
)

logger = logging.getLogger(__name__)
STATIC = Path(__file__).parent / "static"
TOKEN_COOKIE = "mirror_avatar_token"
MAX_FRAME_BYTES = 16 * 1024
"""Largest WebSocket frame the server reads at all (bytes); larger ones close the connection."""

CLOSE_BUSY, CLOSE_POLICY, CLOSE_STALE, CLOSE_IDLE = 1013, 1008, 4408, 4000
SERVER_SEND = "mirror_avatar.server_send"
"""Scope key of the ASGI server's own ``send`` callable (see `abort_transport`)."""


BUILD_SESSIONS = (DEFAULT_SESSIONS, VALIDATION_SESSIONS, BASELINE_SESSIONS)
"""A built avatar's training, validation and baseline sessions: `avatar create`'s defaults."""


@dataclass(frozen=True)
class LiveSettings:
    """How the live server runs.

    Parameters
    ----------
    out_dir
        Root directory of the recordings.
    avatar_spec
        The avatar's spec, recorded in every sidecar.
    token
        Access token required on every connection, or None for none.
    allowed_hosts
        Host names, besides loopback ones, that requests may be addressed to when there is no
        token.
    max_sessions
        Most simultaneous WebSocket connections.
    max_per_address
        Most simultaneous connections from one client address.
    evict_after
        Seconds a connection without a trial is protected from eviction by a newcomer.
    stale_timeout
        Seconds without a position message after which a running trial is ended (incomplete).
    idle_timeout
        Seconds without any message after which a connection without a trial is closed.
    send_timeout
        Seconds a message may wait for a client that does not read before it is dropped.
    max_tick
        Seconds one tick of a trial may take before the trial is ended (a too slow avatar).
    countdown
        Seconds of countdown before a trial starts.
    max_rejected
        Bad messages tolerated on one connection before it is closed.
    max_message_rate
        Messages per second one connection may send (sustained; bursts of a second's worth).
    connects_per_second, starts_per_second
        New connections and trial starts per second from one address (sustained; bursts of
        `ADDRESS_BURST`); each connection may also start a trial at most every
        ``1 / starts_per_second`` seconds after a burst of two.
    period
        Control period T (s).
    build_sessions
        A participant's avatar built from the page: training sessions per role, validation
        sessions per partner and baseline sessions (`mirror_avatar.live.avatar_build`).
    """

    out_dir: Path
    avatar_spec: str | None = None
    token: str | None = None
    allowed_hosts: frozenset[str] = frozenset()
    max_sessions: int = 8
    max_per_address: int = 4
    evict_after: float = 3.0
    stale_timeout: float = 2.0
    idle_timeout: float = 60.0
    send_timeout: float = 2.0
    max_tick: float = 0.5
    countdown: int = 3
    max_rejected: int = 100
    max_message_rate: float = 250.0
    connects_per_second: float = 2.0
    starts_per_second: float = 0.5
    period: float = CONTROL_PERIOD
    build_sessions: tuple[int, int, int] = (
        DEFAULT_SESSIONS,
        VALIDATION_SESSIONS,
        BASELINE_SESSIONS,
    )


ADDRESS_BURST = 10
"""Connections and trial starts one address may make at once before its rate applies."""


def create_app(settings: LiveSettings, avatar_factory: AvatarFactory | None) -> ASGIApp:
    """Build the live server's ASGI application.

    Parameters
    ----------
    settings
        See `LiveSettings`.
    avatar_factory
        Builds the avatar of each trial (`mirror_avatar.live.session.make_avatar_factory`);
        None allows solo trials only.
    """
    admission = Admission(
        settings.max_sessions,
        settings.max_per_address,
        settings.evict_after,
        settings.connects_per_second,
        ADDRESS_BURST,
        settings.starts_per_second,
        ADDRESS_BURST,
    )

    async def index(request: Request) -> Response:
        response = FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-store"})
        if settings.token is not None:
            response.set_cookie(TOKEN_COOKIE, settings.token, httponly=True, samesite="strict")
        return response

    async def game_socket(websocket: WebSocket) -> None:
        await websocket.accept()
        connection = Connection(websocket, settings, avatar_factory, admission)
        refused = admission.admit(connection)
        if refused is not None:
            await connection.send({"type": "error", "message": refused})
            await connection.close(CLOSE_BUSY, refused, read_more=False)
            return
        try:
            await connection.run()
        finally:
            admission.release(connection)

    app = Starlette(
        routes=[
            Route("/", index),
            WebSocketRoute("/ws", game_socket),
            Mount("/static", StaticFiles(directory=STATIC), name="static"),
        ]
    )
    return AccessGate(app, settings.token, settings.allowed_hosts)


class AccessGate:
    """ASGI middleware: check the access token, the host and the WebSocket origin.

    Parameters
    ----------
    app
        The application behind the gate.
    token
        The token every HTTP request and WebSocket handshake must carry, or None.
    allowed_hosts
        Without a token, the host names besides loopback ones requests may be addressed to.
    """

    def __init__(
        self, app: ASGIApp, token: str | None, allowed_hosts: frozenset[str] = frozenset()
    ) -> None:
        self.app = app
        self.token = token
        self.allowed_hosts = allowed_hosts

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        """Pass allowed connections through; refuse the others (HTTP 403 or WebSocket close)."""
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        connection = HTTPConnection(scope)
        problem = self._problem(connection)
        if problem is None:
            scope[SERVER_SEND] = send
            await self.app(scope, receive, send)
        elif scope["type"] == "http":
            await PlainTextResponse(problem, status_code=403)(scope, receive, send)
        else:
            await WebSocketClose(CLOSE_POLICY, problem)(scope, receive, send)

    def _problem(self, connection: HTTPConnection) -> str | None:
        if self.token is not None:
            given = connection.query_params.get("token") or connection.cookies.get(TOKEN_COOKIE)
            if given is None or not hmac.compare_digest(given.encode(), self.token.encode()):
                return "missing or wrong access token"
        elif not host_allowed(connection.headers.get("host"), self.allowed_hosts):
            return "this server answers only requests addressed to this machine (see --allow-host)"
        origin = connection.headers.get("origin")
        if (
            connection.scope["type"] == "websocket"
            and origin is not None
            and urlsplit(origin).netloc != connection.headers.get("host")
        ):
            return "cross-origin WebSocket refused"
        return None


class Connection:
    """One browser tab's WebSocket: its messages, its running trial and that trial's ticker.

    Attributes
    ----------
    address
        The client's address (host of the peer).
    opened, last_active
        When it connected and when it last sent a message (monotonic seconds).
    """

    def __init__(
        self,
        websocket: WebSocket,
        settings: LiveSettings,
        avatar_factory: AvatarFactory | None,
        admission: Admission,
    ) -> None:
        self.websocket = websocket
        self.settings = settings
        self.avatar_factory = avatar_factory
        self.avatar_spec = settings.avatar_spec
        self.building = False
        self.admission = admission
        self.address = websocket.client.host if websocket.client else ""
        self.opened = self.last_active = time.monotonic()
        self.trial: LiveTrial | None = None
        self.ticker: asyncio.Task[None] | None = None
        self.receiver: asyncio.Task[None] | None = None
        self.dropped = False
        self.rejected = 0
        self.messages = TokenBucket(settings.max_message_rate, settings.max_message_rate)
        self.starts = TokenBucket(settings.starts_per_second, 2)

    @property
    def playing(self) -> bool:
        """Whether a trial is running, or an avatar is being built, on this connection."""
        return self.trial is not None or self.building

    async def run(self) -> None:
        """Serve the connection until it closes; a trial still running is saved as incomplete."""
        modes = MODES if self.avatar_factory is not None else ("solo",)
        await self.send(
            {
                "type": "ready",
                "modes": list(modes),
                "avatar": self.settings.avatar_spec,
                "period": self.settings.period,
                "duration_range": list(DURATION_RANGE),
            }
        )
        self.receiver = asyncio.create_task(self._receive_loop())
        try:
            with contextlib.suppress(asyncio.CancelledError):
                await self.receiver
        finally:
            if self.ticker is not None:
                self.ticker.cancel()
            self.end_trial(False, "connection closed")

    def evict(self) -> None:
        """Close this idle connection to make room for a newcomer (close code 4000)."""
        asyncio.get_running_loop().create_task(
            self.close(CLOSE_IDLE, "closed while idle to make room: press Start to reconnect")
        )
        self.drop()

    def drop(self) -> None:
        """Stop serving this connection (its trial, if any, is saved as incomplete).

        The receive loop is cancelled and also checks `dropped`, because a cancellation that
        arrives while a message is ready can be absorbed by `asyncio.wait_for`.
        """
        self.dropped = True
        if self.receiver is not None:
            self.receiver.cancel()

    async def _receive_loop(self) -> None:
        while not self.dropped:
            timeout = None if self.playing else self.settings.idle_timeout
            try:
                message = await asyncio.wait_for(self.websocket.receive(), timeout)
            except TimeoutError:
                await self.close(CLOSE_IDLE, "idle for too long: press Start to reconnect")
                return
            if message["type"] == "websocket.disconnect":
                return
            self.last_active = time.monotonic()
            if self.messages.take() > 0.0:
                problem = f"too many messages: at most {self.settings.max_message_rate:g} per s"
                if not await self.reject(problem):
                    return
                continue
            try:
                request = parse_message(message.get("text", message.get("bytes")))
            except ProtocolError as error:
                if not await self.reject(str(error)):
                    return
                continue
            await self.handle(request)

    async def handle(self, request: Message) -> None:
        """Act on one valid message."""
        trial = self.trial
        if isinstance(request, BuildRequest):
            await self.build(request)
            return
        if isinstance(request, PositionUpdate):
            if trial is not None:
                trial.update_person(request.x, request.rtt_ms)
            await self.send(
                {
                    "type": "avatar",
                    "seq": request.seq,
                    "x": None if trial is None else trial.avatar_x,
                    "progress": 0.0 if trial is None else trial.progress,
                }
            )
        elif isinstance(request, StopRequest):
            if self.ticker is not None:
                self.ticker.cancel()
            summary = self.end_trial(False, "stopped by the participant")
            if summary is not None:
                await self.send({"type": "done", "summary": summary})
        elif trial is not None:
            await self.reject("a trial is already running")
        else:
            await self.start(request)

    async def start(self, request: StartRequest) -> None:
        """Build the trial (in a worker thread: loading an avatar may take a while) and tick it.

        Refused when the mode needs an avatar the server lacks, or when this connection or its
        address started too many trials lately.
        """
        if request.mode != "solo" and self.avatar_factory is None:
            await self.reject(f"mode {request.mode} needs an avatar; this server has none")
            return
        wait = max(self.starts.take(), self.admission.start_wait(self.address))
        if wait > 0.0:
            await self.reject(f"too many trials started: wait {wait:.1f} s")
            return
        try:
            self.trial = await asyncio.to_thread(
                start_trial,
                self.settings.out_dir,
                request,
                self.avatar_factory,
                self.avatar_spec,
                self.settings.period,
            )
        except (InputError, OSError) as error:
            await self.send({"type": "error", "message": f"cannot start the trial: {error}"})
            return
        self.ticker = asyncio.create_task(self._tick(self.trial))

    async def _tick(self, trial: LiveTrial) -> None:
        try:
            await self._run_trial(trial)
        except Exception as error:  # a failing avatar must not lose the recording
            logger.exception("trial failed")
            if self.trial is not trial:
                return
            self.end_trial(False, f"server error: {type(error).__name__}")
            await self.send({"type": "error", "message": "server error: trial saved as incomplete"})

    async def _run_trial(self, trial: LiveTrial) -> None:
        for remaining in range(self.settings.countdown, 0, -1):
            await self.send({"type": "countdown", "remaining": remaining})
            await asyncio.sleep(1.0)
        await self.send({"type": "go", "avatar": trial.avatar_x, "duration": trial.duration})
        loop = asyncio.get_running_loop()
        start = loop.time()
        while not trial.finished and self.trial is trial:
            delay = start + trial.k * trial.period - loop.time()
            if delay > 0:
                await asyncio.sleep(delay)
            if self.trial is not trial:
                return
            if time.monotonic() - trial.last_heard > self.settings.stale_timeout:
                self.end_trial(False, "the browser stopped sending")
                await self.close(CLOSE_STALE, "no position received: trial saved as incomplete")
                return
            began = loop.time()
            await asyncio.to_thread(trial.tick, max(0.0, -delay))
            if loop.time() - began > self.settings.max_tick and self.trial is trial:
                summary = self.end_trial(False, "the avatar is too slow for real time")
                await self.send({"type": "done", "summary": summary})
                return
        if self.trial is trial:
            await self.send({"type": "done", "summary": self.end_trial(True, "completed")})

    async def build(self, request: BuildRequest) -> None:
        """Build the participant's avatar in a worker thread, reporting each stage.

        Then this connection's trials play with it.
        """
        if self.playing:
            await self.reject("a trial or an avatar build is running")
            return
        self.building = True
        loop = asyncio.get_running_loop()

        def report(stage: str) -> None:
            message = {"type": "building", "stage": stage}
            asyncio.run_coroutine_threadsafe(self.send(message), loop)

        folder = self.settings.out_dir / request.participant
        try:
            path = await asyncio.to_thread(
                build_avatar, folder, request.participant, self.settings.build_sessions, report
            )
        except (InputError, OSError) as error:
            await self.send({"type": "error", "message": f"cannot build the avatar: {error}"})
            return
        finally:
            self.building = False
        self.avatar_factory = make_avatar_factory(str(path))
        self.avatar_spec = str(path)
        built = {"type": "built", "avatar": path.name, "modes": list(MODES)}
        await self.send(built | describe_avatar(path))

    def end_trial(self, complete: bool, reason: str) -> dict[str, Any] | None:
        """Finish and save the running trial, if any, and return its sidecar."""
        trial, self.trial = self.trial, None
        return None if trial is None else trial.finish(complete, reason)

    async def reject(self, problem: str) -> bool:
        """Answer a bad message with an error; return False once the connection was closed."""
        self.rejected += 1
        if self.trial is not None:
            self.trial.rejected_messages += 1
        if self.rejected > self.settings.max_rejected:
            await self.close(CLOSE_POLICY, "too many bad messages", read_more=False)
            return False
        await self.send({"type": "error", "message": problem})
        return True

    async def send(self, message: dict[str, Any]) -> None:
        """Send a message as strict JSON (NaN as null); a connection already gone is no error.

        A client that does not take the message within ``send_timeout`` is dropped.
        """
        text = json.dumps(json_safe(message), allow_nan=False)
        try:
            await asyncio.wait_for(self.websocket.send_text(text), self.settings.send_timeout)
        except TimeoutError:
            logger.warning("dropping %s: it stopped reading", self.address)
            abort_transport(self.websocket)
            self.drop()
        except (WebSocketDisconnect, RuntimeError, OSError):
            return

    async def close(self, code: int, reason: str, read_more: bool = True) -> None:
        """Close the connection with ``code`` unless it is closed or stopped reading.

        With ``read_more`` False (a refused or flooding client) nothing more it sends is read -
        the server would otherwise parse whatever it sends while waiting for its close reply -
        and its socket is aborted ``send_timeout`` seconds later.
        """
        with contextlib.suppress(RuntimeError, OSError, TimeoutError):
            await asyncio.wait_for(self.websocket.close(code, reason), self.settings.send_timeout)
        if not read_more:  # after the close: the server resumes reading when it sends one
            stop_reading(self.websocket)
            abort_transport(self.websocket, self.settings.send_timeout)


def abort_transport(websocket: WebSocket, delay: float = 0.0) -> None:
    """Close a connection's socket at once, or after ``delay`` seconds, discarding the rest.

    A graceful close would wait for a client that stopped reading to take the queued data, so
    its socket would stay open. The transport is reached through the server's own ASGI ``send``
    callable, which `AccessGate` keeps in the scope (uvicorn's is a method of its protocol
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
    """Return the socket transport under ``websocket``, if the server exposes it (`AccessGate`)."""
    protocol = getattr(websocket.scope.get(SERVER_SEND), "__self__", None)
    transport = getattr(protocol, "transport", None)
    return transport if isinstance(transport, asyncio.Transport) else None


def make_token() -> str:
    """Generate a fresh random access token (URL-safe, 128 bits)."""
    return secrets.token_urlsafe(16)


LISTEN_BACKLOG = 2048
"""Connections the kernel queues for the server before it accepts them (uvicorn's default)."""

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
    sock.bind((host, port))
    sock.listen(LISTEN_BACKLOG)
    return sock


def make_server(app: ASGIApp, host: str, port: int, log_level: str = "warning") -> uvicorn.Server:
    """Configure a uvicorn server for ``app`` (sans-I/O WebSockets, `MAX_FRAME_BYTES` frames)."""
    config = uvicorn.Config(
        app,
        host=host,
        port=port,
        ws="websockets-sansio",
        ws_max_size=MAX_FRAME_BYTES,
        log_level=log_level,
        lifespan="off",
        backlog=LISTEN_BACKLOG,
    )
    return uvicorn.Server(config)

"""The live server: one page, one WebSocket per browser tab, one avatar per trial.

`create_app` builds the ASGI application (starlette): ``/`` serves the page, ``/static/`` its
script and style, and ``/ws`` the game's WebSocket (messages in `mirror_avatar.live.protocol`).
Each connection plays at most one trial at a time (`mirror_avatar.live.session.LiveTrial`): a
task ticks it every control period on absolute deadlines, while the receive loop stores the
pointer's latest position and answers each one at once with the avatar's position.

Robustness: a malformed, oversized or out-of-range message is answered with an ``error`` and
ignored (a connection sending more than ``max_rejected`` of them is closed); connections beyond
``max_sessions`` are refused with close code 1013; a trial whose browser stops sending for
``stale_timeout`` seconds is saved as incomplete and its connection closed (code 4408); a dropped
connection saves its trial as incomplete. No connection's failure touches another's files.

Access: when the settings hold a token, every HTTP request and WebSocket handshake must carry it,
as the ``token`` query parameter or the cookie the page sets; ``serve`` generates one whenever
the server binds to a non-loopback address. WebSocket handshakes from another origin are refused.
"""

from __future__ import annotations

import asyncio
import contextlib
import hmac
import ipaddress
import json
import logging
import secrets
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
from mirror_avatar.live.protocol import (
    DURATION_RANGE,
    MODES,
    PositionUpdate,
    ProtocolError,
    StartRequest,
    StopRequest,
    parse_message,
)
from mirror_avatar.live.session import AvatarFactory, LiveTrial, start_trial

logger = logging.getLogger(__name__)
STATIC = Path(__file__).parent / "static"
TOKEN_COOKIE = "mirror_avatar_token"
MAX_FRAME_BYTES = 16 * 1024
"""Largest WebSocket frame the server reads at all (bytes); larger ones close the connection."""

CLOSE_BUSY, CLOSE_POLICY, CLOSE_STALE = 1013, 1008, 4408


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
    max_sessions
        Most simultaneous WebSocket connections.
    stale_timeout
        Seconds without a position message after which a running trial is ended (incomplete).
    idle_timeout
        Seconds without any message after which an idle connection is closed.
    countdown
        Seconds of countdown before a trial starts.
    max_rejected
        Bad messages tolerated on one connection before it is closed.
    period
        Control period T (s).
    """

    out_dir: Path
    avatar_spec: str | None = None
    token: str | None = None
    max_sessions: int = 4
    stale_timeout: float = 2.0
    idle_timeout: float = 1800.0
    countdown: int = 3
    max_rejected: int = 100
    period: float = CONTROL_PERIOD


def is_loopback(host: str) -> bool:
    """Whether ``host`` (an address or ``localhost``) only accepts connections from this machine."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


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
    state = {"active": 0}

    async def index(request: Request) -> Response:
        response = FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-store"})
        if settings.token is not None:
            response.set_cookie(TOKEN_COOKIE, settings.token, httponly=True, samesite="strict")
        return response

    async def socket(websocket: WebSocket) -> None:
        await websocket.accept()
        if state["active"] >= settings.max_sessions:
            await websocket.send_json({"type": "error", "message": "server busy: too many players"})
            await websocket.close(CLOSE_BUSY)
            return
        state["active"] += 1
        try:
            await Connection(websocket, settings, avatar_factory).run()
        finally:
            state["active"] -= 1

    app = Starlette(
        routes=[
            Route("/", index),
            WebSocketRoute("/ws", socket),
            Mount("/static", StaticFiles(directory=STATIC), name="static"),
        ]
    )
    return AccessGate(app, settings.token)


class AccessGate:
    """ASGI middleware: check the access token and the WebSocket origin on every connection.

    Parameters
    ----------
    app
        The application behind the gate.
    token
        The token every HTTP request and WebSocket handshake must carry, or None.
    """

    def __init__(self, app: ASGIApp, token: str | None) -> None:
        self.app = app
        self.token = token

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        """Pass allowed connections through; refuse the others (HTTP 403 or WebSocket close)."""
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        connection = HTTPConnection(scope)
        problem = self._problem(connection)
        if problem is None:
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
        origin = connection.headers.get("origin")
        if (
            connection.scope["type"] == "websocket"
            and origin is not None
            and urlsplit(origin).netloc != connection.headers.get("host")
        ):
            return "cross-origin WebSocket refused"
        return None


class Connection:
    """One browser tab's WebSocket: its messages, its running trial and that trial's ticker."""

    def __init__(
        self, websocket: WebSocket, settings: LiveSettings, avatar_factory: AvatarFactory | None
    ) -> None:
        self.websocket = websocket
        self.settings = settings
        self.avatar_factory = avatar_factory
        self.trial: LiveTrial | None = None
        self.ticker: asyncio.Task[None] | None = None
        self.rejected = 0

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
        try:
            await self._receive_loop()
        finally:
            if self.ticker is not None:
                self.ticker.cancel()
            self.end_trial(False, "connection closed")

    async def _receive_loop(self) -> None:
        while True:
            try:
                message = await asyncio.wait_for(
                    self.websocket.receive(), self.settings.idle_timeout
                )
            except TimeoutError:
                await self.close(CLOSE_STALE, "idle for too long")
                return
            if message["type"] == "websocket.disconnect":
                return
            try:
                request = parse_message(message.get("text", message.get("bytes")))
            except ProtocolError as error:
                if not await self.reject(str(error)):
                    return
                continue
            await self.handle(request)

    async def handle(self, request: PositionUpdate | StartRequest | StopRequest) -> None:
        """Act on one valid message."""
        trial = self.trial
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
        """Build the trial (in a worker thread: loading an avatar may take a while) and tick it."""
        if request.mode != "solo" and self.avatar_factory is None:
            await self.reject(f"mode {request.mode} needs an avatar; this server has none")
            return
        try:
            self.trial = await asyncio.to_thread(
                start_trial,
                self.settings.out_dir,
                request,
                self.avatar_factory,
                self.settings.avatar_spec,
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
            trial.tick(max(0.0, -delay))
        if self.trial is trial:
            await self.send({"type": "done", "summary": self.end_trial(True, "completed")})

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
            await self.close(CLOSE_POLICY, "too many bad messages")
            return False
        await self.send({"type": "error", "message": problem})
        return True

    async def send(self, message: dict[str, Any]) -> None:
        """Send a message as strict JSON (NaN as null); a connection already gone is no error."""
        text = json.dumps(json_safe(message), allow_nan=False)
        with contextlib.suppress(WebSocketDisconnect, RuntimeError, OSError):
            await self.websocket.send_text(text)

    async def close(self, code: int, reason: str) -> None:
        """Close the connection with ``code`` unless it is already closed."""
        with contextlib.suppress(RuntimeError, OSError):
            await self.websocket.close(code, reason)


def make_token() -> str:
    """Generate a fresh random access token (URL-safe, 128 bits)."""
    return secrets.token_urlsafe(16)


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
    )
    return uvicorn.Server(config)

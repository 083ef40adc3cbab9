"""The live server: one page, one WebSocket per browser tab, one avatar per trial.

`create_app` builds the ASGI application (starlette): ``/`` serves the page, ``/static/`` its
script and style, and ``/ws`` the game's WebSocket (messages in `mirror_avatar.live.messages`).
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
import logging
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from starlette.applications import Starlette
from starlette.middleware import Middleware
from starlette.requests import Request
from starlette.responses import FileResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.types import ASGIApp
from starlette.websockets import WebSocket

from mirror_avatar.common.errors import InputError
from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.experiments.cyber_player import BASELINE_SESSIONS, VALIDATION_SESSIONS
from mirror_avatar.experiments.personal_avatar import DEFAULT_SESSIONS
from mirror_avatar.live.admission import Admission
from mirror_avatar.live.avatar_build import (
    build_avatar,
    build_readiness,
    describe_avatar,
    solo_trial_files,
)
from mirror_avatar.live.messages import (
    DURATION_RANGE,
    MODES,
    BuildRequest,
    Message,
    PositionUpdate,
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
from mirror_avatar.realtime.clock import MAX_LATENESS, ClockLimits, run_on_clock
from mirror_avatar.realtime.gates import HostGate, OriginGate, TokenGate
from mirror_avatar.realtime.inbox import Inbox
from mirror_avatar.realtime.outbox import Outbox, Peer
from mirror_avatar.realtime.rates import TokenBucket
from mirror_avatar.realtime.settings import PageSettings

logger = logging.getLogger(__name__)
STATIC = Path(__file__).parent / "static"
TOKEN_COOKIE = "mirror_avatar_token"
CLOSE_BUSY, CLOSE_POLICY, CLOSE_STALE, CLOSE_IDLE = 1013, 1008, 4408, 4000


BUILD_SESSIONS = (DEFAULT_SESSIONS, VALIDATION_SESSIONS, BASELINE_SESSIONS)
"""A built avatar's training, validation and baseline sessions: `avatar create`'s defaults."""


@dataclass(frozen=True, kw_only=True)
class LiveSettings(PageSettings):
    """How the live server runs (and the `mirror_avatar.realtime.settings.PageSettings`).

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
    max_lateness
        Seconds a tick may come after its deadline before the trial is ended (the clock
        cannot be kept; `mirror_avatar.realtime.clock.MAX_LATENESS`).
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
    max_lateness: float = MAX_LATENESS
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
            connection.send({"type": "error", "message": refused})
            connection.outbox.end(CLOSE_BUSY, refused, read_more=False)
            await connection.close_outbox()
            return
        try:
            await connection.run()
        finally:
            admission.release(connection)

    if settings.token is not None:
        gates = [Middleware(TokenGate, token=settings.token, cookie=TOKEN_COOKIE)]
    else:
        gates = [Middleware(HostGate, allowed=settings.allowed_hosts)]
    return Starlette(
        routes=[
            Route("/", index),
            WebSocketRoute("/ws", game_socket),
            Mount("/static", StaticFiles(directory=STATIC), name="static"),
        ],
        middleware=[*gates, Middleware(OriginGate)],
    )


class Connection:
    """One browser tab's WebSocket: its messages, its running trial and that trial's clock.

    Everything it sends goes through its `mirror_avatar.realtime.outbox.Outbox`: control
    messages in order, the avatar's answers to positions as frames (only the newest undelivered
    one is kept), so a tab that reads slowly delays nothing.

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
        self.inbox = Inbox(
            websocket,
            parse_message,
            settings.max_message_rate,
            settings.max_rejected,
            self._answer_problem,
            self._send_away,
        )
        self.starts = TokenBucket(settings.starts_per_second, 2)
        peer = Peer(websocket, settings.send_timeout, self.address, self.drop)
        self.outbox = Outbox(peer)
        self.limits = ClockLimits(
            settings.max_tick, settings.max_lateness, "the avatar is too slow for real time"
        )

    @property
    def playing(self) -> bool:
        """Whether a trial is running, or an avatar is being built, on this connection."""
        return self.trial is not None or self.building

    async def run(self) -> None:
        """Serve the connection until it closes; a trial still running is saved as incomplete."""
        modes = MODES if self.avatar_factory is not None else ("solo",)
        self.send(
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
            await self.end_trial(False, "connection closed")
            await self.close_outbox()

    def evict(self) -> None:
        """Close this idle connection to make room for a newcomer (close code 4000)."""
        self.outbox.end(CLOSE_IDLE, "closed while idle to make room: press Start to reconnect")
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
        messages = self.inbox.messages(
            lambda: None if self.playing else self.settings.idle_timeout, lambda: self.dropped
        )
        try:
            async for request in messages:
                self.last_active = time.monotonic()
                await self.handle(request)
        except TimeoutError:
            self.outbox.end(CLOSE_IDLE, "idle for too long: press Start to reconnect")

    async def handle(self, request: Message) -> None:
        """Act on one valid message."""
        trial = self.trial
        if isinstance(request, BuildRequest):
            await self.build(request)
            return
        if isinstance(request, PositionUpdate):
            if trial is not None:
                trial.update_person(request.x, request.rtt_ms, request.seq)
            self.outbox.put_frame(
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
            summary = await self.end_trial(False, "stopped by the participant")
            if summary is not None:
                await self.send_done(summary)
        elif trial is not None:
            self.reject("a trial is already running")
        else:
            await self.start(request)

    async def start(self, request: StartRequest) -> None:
        """Build the trial (in a worker thread: loading an avatar may take a while) and tick it.

        Refused when the mode needs an avatar the server lacks, or when this connection or its
        address started too many trials lately.
        """
        if request.mode != "solo" and self.avatar_factory is None:
            self.reject(f"mode {request.mode} needs an avatar; this server has none")
            return
        wait = max(self.starts.take(), self.admission.start_wait(self.address))
        if wait > 0.0:
            self.reject(f"too many trials started: wait {wait:.1f} s")
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
            self.send({"type": "error", "message": f"cannot start the trial: {error}"})
            return
        self.ticker = asyncio.create_task(self._tick(self.trial))

    async def _tick(self, trial: LiveTrial) -> None:
        try:
            await self._run_trial(trial)
        except Exception as error:  # a failing avatar must not lose the recording
            logger.exception("trial failed")
            if self.trial is not trial:
                return
            await self.end_trial(False, f"server error: {type(error).__name__}")
            self.send({"type": "error", "message": "server error: trial saved as incomplete"})

    async def _run_trial(self, trial: LiveTrial) -> None:
        for remaining in range(self.settings.countdown, 0, -1):
            self.send({"type": "countdown", "remaining": remaining})
            await asyncio.sleep(1.0)
        self.send({"type": "go", "avatar": trial.avatar_x, "duration": trial.duration})
        stale = "the browser stopped sending"

        def stop_reason() -> str | None:
            if self.trial is not trial:
                return "replaced"
            if time.monotonic() - trial.last_heard > self.settings.stale_timeout:
                return stale
            return None

        complete, reason = await run_on_clock(trial, self.limits, stop_reason)
        if self.trial is not trial:
            return
        summary = await self.end_trial(complete, reason)
        if reason == stale:
            self.outbox.end(CLOSE_STALE, "no position received: trial saved as incomplete")
            self.drop()
        elif summary is not None:
            await self.send_done(summary)

    async def build(self, request: BuildRequest) -> None:
        """Build the participant's avatar in a worker thread, reporting each stage.

        Then this connection's trials play with it.
        """
        if self.playing:
            self.reject("a trial or an avatar build is running")
            return
        self.building = True
        loop = asyncio.get_running_loop()

        def report(stage: str) -> None:
            loop.call_soon_threadsafe(self.send, {"type": "building", "stage": stage})

        folder = self.settings.out_dir / request.participant
        try:
            path = await asyncio.to_thread(
                build_avatar, folder, request.participant, self.settings.build_sessions, report
            )
            described = await asyncio.to_thread(describe_avatar, path)
        except (InputError, OSError) as error:
            self.send({"type": "error", "message": f"cannot build the avatar: {error}"})
            return
        finally:
            self.building = False
        self.avatar_factory = make_avatar_factory(str(path))
        self.avatar_spec = str(path)
        built = {"type": "built", "avatar": path.name, "modes": list(MODES)}
        self.send(built | described)

    async def end_trial(self, complete: bool, reason: str) -> dict[str, Any] | None:
        """Finish and save the running trial, if any, and return its sidecar.

        The metrics are computed in a worker thread: a long trial's end stalls no one else.
        """
        trial, self.trial = self.trial, None
        if trial is None:
            return None
        return await asyncio.to_thread(trial.finish, complete, reason)

    async def send_done(self, summary: dict[str, Any]) -> None:
        """Tell the page its trial is saved, with what the participant's solo trials now allow.

        The readiness to build an avatar (`build_readiness`) is counted from the files in a
        worker thread.
        """
        participant = str(summary["participant"])
        folder = self.settings.out_dir / participant
        count = len(await asyncio.to_thread(solo_trial_files, folder, participant))
        self.send({"type": "done", "summary": summary, "build": build_readiness(count)})

    def reject(self, problem: str) -> bool:
        """Answer a bad message with an error; return False once the connection is closing."""
        return self.inbox.reject(problem)

    def _answer_problem(self, problem: str) -> None:
        if self.trial is not None:
            self.trial.rejected_messages += 1
        self.send({"type": "error", "message": problem})

    def _send_away(self) -> None:
        self.outbox.end(CLOSE_POLICY, "too many bad messages", read_more=False)
        self.dropped = True

    def send(self, message: dict[str, Any]) -> None:
        """Queue a control message (strict JSON, NaN as null) in the connection's outbox."""
        self.outbox.put(message)

    async def close_outbox(self) -> None:
        """Let the outbox send what it holds and close the connection, or stop it at once.

        An outbox told to end (`Outbox.end`) closes the connection itself once its messages are
        sent (within the send timeout per message); otherwise the connection is gone already.
        """
        if self.outbox.ending:
            await self.outbox.ended()
        else:
            self.outbox.close()

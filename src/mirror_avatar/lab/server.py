"""The lab server: the researcher's console, its HTTP/JSON API and the participants' pages.

Routes (`create_lab_app`):

- ``GET /console``: the researcher's console (a page using the API below).
- ``GET /api/sessions``: every session's status (and the protocol's title, seed and people
  when one is loaded); ``POST /api/sessions`` with a plan
  (`mirror_avatar.lab.plan.parse_plan`) builds its avatars (a bad spec is refused here, 400),
  creates the session and answers its status and its join links; with a protocol loaded,
  ``POST /api/sessions`` with ``{"participant": p}`` creates (or resumes) participant p's run
  of it (`mirror_avatar.lab.study.StudySession`), or answers the run as it is while it is
  open (200: a reloaded console shows it again).
- ``POST /api/protocol`` with ``{"name": file name, "text": TOML}``: loads a protocol from the
  console (`mirror_avatar.lab.protocol_store.store_protocol`: validated, kept as
  ``OUT/protocols/<name>.toml``, used from then on); refused while a participant's run of the
  current protocol is playing (409).
- ``GET /api/sessions/{id}``: a session's status (`mirror_avatar.lab.runner.LabSession.status`)
  with its join links; ``GET /api/sessions/{id}/live``: the last 10 s of positions and ρ_g.
- ``POST /api/sessions/{id}/start`` (body ``{"force": true}`` starts without everyone),
  ``/stop`` and ``/abort``; ``POST /api/sessions/{id}/export`` (body ``{"folder": name}``,
  optional) exports the session's trials as BIDS (`mirror_avatar.lab.bids.export_bids`) into
  ``OUT/bids`` or ``OUT/<name>`` between trials, answering the folder and its file count.
- ``GET /api/sessions/{id}/files/{name}``: a file of the session (plan, trials' recordings;
  refused, 403, for a run of a double-blind protocol, whose statuses are blinded too:
  `mirror_avatar.lab.blinding`);
  ``GET /api/sessions/{id}/qr/{label}.svg``: the QR code of a person's join link.
- ``GET /join/{key}``: a participant's page; ``/ws/join/{key}``: its WebSocket
  (`mirror_avatar.lab.messages`).

Access: ``/console`` and ``/api`` need the researcher's token always, even on loopback: as the
``token`` query parameter (the console's URL), the cookie the console sets, or an
``Authorization: Bearer`` header (scripts). POSTs must be JSON (a cross-site form cannot send
one). A join link holds the secret key of one person's slot in one session: it shows that
session only, moves that person's point only, and expires when the session ends. WebSocket
handshakes from another origin are refused. Rates are limited per client address (API
requests, connections; the researcher's token-carrying requests have a budget of their own, so a
flood from their address does not slow them) and per connection (messages). Clients never name
a path: files are written by the server into ``OUT/<session id>/`` under names it makes, and
served only from the session's own folder by the names it lists, through the checked reader.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import io
import logging
import mimetypes
import os
import re
import time
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import IO, Any

from starlette.applications import Starlette
from starlette.middleware import Middleware
from starlette.requests import Request
from starlette.responses import (
    FileResponse,
    JSONResponse,
    PlainTextResponse,
    RedirectResponse,
    Response,
    StreamingResponse,
)
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.types import ASGIApp
from starlette.websockets import WebSocket, WebSocketDisconnect

from mirror_avatar.atomic import json_safe
from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.errors import InputError
from mirror_avatar.lab.blinding import console_status, hidden_of, unjoined
from mirror_avatar.lab.files import is_session_folder
from mirror_avatar.lab.messages import Answer, Pong, parse_participant_message
from mirror_avatar.lab.plan import LslDevice, SessionPlan, parse_plan
from mirror_avatar.lab.protocol import MAX_PROTOCOL_BYTES, Protocol
from mirror_avatar.lab.protocol_store import PROTOCOLS_FOLDER, store_protocol
from mirror_avatar.lab.runner import LabSession, Outlet, Participant
from mirror_avatar.lab.study import StudySession, study_folder
from mirror_avatar.lab.trial import build_avatars
from mirror_avatar.players.base import Player
from mirror_avatar.realtime.gates import JsonGate, OriginGate, RateGate, TokenGate
from mirror_avatar.realtime.inbox import Inbox
from mirror_avatar.realtime.inputs import BrowserInput, InputSource
from mirror_avatar.realtime.latency import Pings
from mirror_avatar.realtime.messages import PositionUpdate
from mirror_avatar.realtime.outbox import Outbox, Peer
from mirror_avatar.realtime.settings import PageSettings
from mirror_avatar.realtime.trial import Clock
from mirror_avatar.trial_io import MAX_FILE_BYTES
from mirror_avatar.user_files import open_regular, parse_json

STATIC = Path(__file__).parent / "static"
"""The console's and the participants' pages."""

TOKEN_COOKIE = "mirror_avatar_lab_token"
"""The cookie holding the researcher's token once the console's link was opened."""

logger = logging.getLogger(__name__)
CLOSE_POLICY, CLOSE_REPLACED, CLOSE_UNKNOWN = 1008, 4002, 4004
FILE_NAME = re.compile(
    r"plan\.json|study\.json|trial-\d{2,3}_(session\.csv|session\.json|inputs\.csv|answers\.json)"
)
"""Names of the files a session's folder may serve."""

MAX_PARTICIPANT = 999
"""Largest participant number of a protocol."""

MAX_BODY_BYTES = 64 * 1024
"""Largest API request body (bytes)."""

MAX_PROTOCOL_BODY_BYTES = 2 * MAX_PROTOCOL_BYTES + 1024
"""Largest body of ``POST /api/protocol`` (bytes): a protocol's largest text, escaped as JSON."""

EXPORT_FOLDER = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]{0,63}")
"""Name of a folder of OUT the console may export into (one path part, no dots)."""

PLAYING = ("countdown", "running", "pause")
"""States in which a session's trials are being played (no export then)."""


@dataclass(frozen=True, kw_only=True)
class LabSettings(PageSettings):
    """How the lab server runs (and the `mirror_avatar.realtime.settings.PageSettings`).

    Parameters
    ----------
    out_dir
        Where sessions are recorded (one folder each).
    token
        The researcher's token.
    max_sessions
        Most sessions that have not ended at once.
    ping_interval
        Seconds between the round-trip pings sent to each page.
    requests_per_second
        API requests and WebSocket connections per second from one address (bursts of 4 s).
    lsl
        Whether sessions publish an LSL outlet and take LSL input devices (needs pylsl).
    protocol
        The study protocol whose participants' sessions the console creates
        (`mirror_avatar.lab.study.StudySession`) until the console loads another, or None.
    """

    out_dir: Path
    token: str
    max_sessions: int = 16
    ping_interval: float = 0.5
    requests_per_second: float = 40.0
    lsl: bool = False
    protocol: Protocol | None = None


KEEP_ENDED = 8
"""Ended sessions kept in memory for the console (the oldest beyond are forgotten; their
files stay)."""


@dataclass
class Lab:
    """The server's sessions and the keys of their join links.

    A session that ends loses its join keys at once (its links stop); of the ended sessions
    only the `KEEP_ENDED` most recent stay listed, so memory and the console's answers do not
    grow with the sessions a server has run. ``protocol`` is the protocol whose participants'
    runs are created: the settings' at first, then the last one loaded from the console.
    ``opening`` names the sessions whose folders are being made or read in a worker thread.
    """

    settings: LabSettings
    sessions: dict[str, LabSession] = field(default_factory=dict)
    keys: dict[str, tuple[LabSession, Participant]] = field(default_factory=dict)
    created: int = 0
    protocol: Protocol | None = field(init=False)
    opening: set[str] = field(default_factory=set)

    def __post_init__(self) -> None:
        self.protocol = self.settings.protocol

    async def create(self, plan: SessionPlan, avatars: dict[int, Player]) -> LabSession:
        """Create a session of ``plan`` with its avatars, built (`build_avatars`).

        Its folder and ``plan.json`` are written in a worker thread.
        """
        self.forget_ended()
        active = [s for s in self.sessions.values() if not s.ended]
        if len(active) + len(self.opening) >= self.settings.max_sessions:
            raise InputError("plan", f"{len(active)} sessions are open: end one first")
        self.created += 1
        stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%S")
        session_id = f"{stamp}-{self.created:03d}"
        outlet, open_device, clock = lsl_hooks(self.settings.lsl, session_id, plan)
        self.opening.add(session_id)
        try:
            session = await asyncio.to_thread(
                LabSession,
                session_id,
                plan,
                self.settings.out_dir / session_id,
                clock,
                self.settings.countdown,
                self.settings.max_tick,
                outlet,
                open_device,
            )
        finally:
            self.opening.discard(session_id)
        session.avatars = avatars
        self._add(session)
        return session

    async def create_study(self, participant: int) -> LabSession:
        """Create (or resume from its folder) participant ``participant``'s run of the protocol.

        The folder is made, or its ``study.json`` read and its trials listed, in a worker
        thread (`mirror_avatar.lab.study.read_schedule`: the checked reader), so that a bad
        folder delays no one's clock. With LSL, the session stamps its samples on the LSL
        clock and publishes one outlet for the participant's whole run (`study_outlet`).
        """
        protocol = self.protocol
        assert protocol is not None
        self.forget_ended()
        name = study_folder(protocol, participant)
        open_ = name in self.sessions and not self.sessions[name].ended
        if open_ or name in self.opening:
            raise InputError("participant", f"participant {participant}'s session is open")
        self.opening.add(name)
        try:
            session = await asyncio.to_thread(
                StudySession,
                protocol,
                participant,
                self.settings.out_dir / name,
                lsl_clock() if self.settings.lsl else time.monotonic,
                self.settings.countdown,
                self.settings.max_tick,
            )
        finally:
            self.opening.discard(name)
        if self.settings.lsl:
            session.outlet = study_outlet(session)
        self.sessions.pop(name, None)
        self._add(session)
        return session

    def open_study(self, participant: int) -> LabSession | None:
        """Return participant ``participant``'s run of the protocol while it is open, or None."""
        assert self.protocol is not None
        self.forget_ended()
        session = self.sessions.get(study_folder(self.protocol, participant))
        return None if session is None or session.ended else session

    def _add(self, session: LabSession) -> None:
        self.sessions[session.id] = session
        for participant in session.everyone():
            self.keys[participant.key] = (session, participant)

    def find(self, key: str) -> tuple[LabSession, Participant] | None:
        """Return the session and slot of a join key, while the session lasts."""
        self.forget_ended()
        return self.keys.get(key)

    def forget_ended(self) -> None:
        """Drop the keys of ended sessions, and the ended sessions beyond `KEEP_ENDED`."""
        for key, (session, _) in list(self.keys.items()):
            if session.ended:
                del self.keys[key]
        ended = [sid for sid, session in self.sessions.items() if session.ended]
        for sid in ended[: max(0, len(ended) - KEEP_ENDED)]:
            del self.sessions[sid]


def lsl_hooks(
    enabled: bool, session_id: str, plan: SessionPlan
) -> tuple[Outlet | None, Callable[[LslDevice], InputSource] | None, Clock]:
    """Return a session's LSL outlet, LSL device opener and clock (without LSL: monotonic)."""
    if not enabled:
        return None, None, time.monotonic
    from mirror_avatar.lab.lsl import LslInput, SessionOutlet

    outlet = SessionOutlet(
        f"mirror-avatar {session_id}",
        f"mirror-avatar-{session_id}",
        [slot.label for slot in plan.slots],
        list(plan.roles),
        [slot.kind for slot in plan.slots],
        CONTROL_PERIOD,
    )

    def open_device(device: LslDevice) -> InputSource:
        return LslInput(
            device.stream, device.channel, device.scale, device.offset,
            source_id=device.source_id,
        )  # fmt: skip

    return outlet, open_device, lsl_clock()


def lsl_clock() -> Clock:
    """Return the LSL clock (`pylsl.local_clock`, s)."""
    import pylsl

    return pylsl.local_clock


def study_outlet(session: StudySession) -> Outlet:
    """Return the LSL outlet of a participant's run of a protocol.

    **Choice**: one outlet for the whole run (a recorder resolves it once), with a channel per
    player label of the run (`mirror_avatar.lab.study.StudySession.channels`; NaN while that
    player is not in the condition), named and identified by the run's folder
    (``mirror-avatar <protocol>-p003``, so a resumed run publishes under the same source id),
    and markers naming each condition and its line-up as it begins, each trial's start and
    end and each perturbation.
    """
    from mirror_avatar.lab.lsl import SessionOutlet

    labels, roles, kinds = session.channels()
    return SessionOutlet(
        f"mirror-avatar {session.id}",
        f"mirror-avatar-{session.id}",
        labels,
        roles,
        kinds,
        CONTROL_PERIOD,
    )


def create_lab_app(settings: LabSettings) -> ASGIApp:
    """Build the lab server's ASGI application (see the module docstring)."""
    lab = Lab(settings)
    api = LabApi(lab)
    rate = settings.requests_per_second
    researcher = "the console needs the researcher's token (printed by mirror-avatar lab)"
    app = Starlette(
        routes=[
            Route("/", index_page),
            Route("/console", console_page),
            Route("/join/{key}", functools.partial(join_page, lab)),
            Route("/api/sessions", api.sessions, methods=["GET", "POST"]),
            Route("/api/protocol", api.protocol, methods=["POST"]),
            Route("/api/sessions/{sid}", api.session),
            Route("/api/sessions/{sid}/live", api.live),
            Route("/api/sessions/{sid}/{action:str}", api.command, methods=["POST"]),
            Route("/api/sessions/{sid}/files/{name}", api.file),
            Route("/api/sessions/{sid}/qr/{label}.svg", api.qr),
            WebSocketRoute("/ws/join/{key}", functools.partial(join_socket, lab)),
            Mount("/static", StaticFiles(directory=STATIC), name="static"),
        ],
        exception_handlers={ApiError: api_error},
        middleware=[
            Middleware(
                RateGate,
                rate=rate,
                burst=4 * rate,
                paths=("/api", "/ws"),
                token=settings.token,
                cookie=TOKEN_COOKIE,
            ),
            Middleware(
                TokenGate,
                token=settings.token,
                cookie=TOKEN_COOKIE,
                paths=("/api", "/console"),
                problem=researcher,
            ),
            Middleware(OriginGate),
            Middleware(JsonGate),
        ],
    )
    app.state.lab = lab
    return app


async def index_page(request: Request) -> Response:
    """Where to go: the console's link or a join link."""
    return PlainTextResponse("mirror-avatar lab: open the console link it printed, or a join link.")


async def console_page(request: Request) -> Response:
    """Serve the console; the token in its URL goes into a cookie and out of the URL.

    The gate checked the token: a wrong one never reaches here, so it cannot replace the
    researcher's cookie.
    """
    if "token" in request.query_params:
        token = request.query_params["token"]
        response: Response = RedirectResponse("/console", status_code=303)
        response.set_cookie(TOKEN_COOKIE, token, httponly=True, samesite="strict")
        return response
    return FileResponse(STATIC / "console.html", headers={"Cache-Control": "no-store"})


async def join_page(lab: Lab, request: Request) -> Response:
    """Serve a participant's page while its link is valid."""
    if lab.find(request.path_params["key"]) is None:
        return PlainTextResponse("this link is not valid or its session has ended", 404)
    return FileResponse(STATIC / "participant.html", headers={"Cache-Control": "no-store"})


class LabApi:
    """The researcher's HTTP/JSON API (every answer is JSON; errors ``{"error": text}``)."""

    def __init__(self, lab: Lab) -> None:
        self.lab = lab
        self.loading = asyncio.Lock()

    def _session(self, request: Request) -> LabSession:
        self.lab.forget_ended()
        session = self.lab.sessions.get(request.path_params["sid"])
        if session is None:
            raise ApiError(404, "no such session")
        return session

    async def sessions(self, request: Request) -> Response:
        """List the sessions, or create one from the plan in the body."""
        if request.method == "GET":
            self.lab.forget_ended()
            listing: dict[str, Any] = {
                "sessions": [self._status(s, request) for s in self.lab.sessions.values()]
            }
            if self.lab.protocol is not None:
                listing["protocol"] = protocol_summary(self.lab.protocol)
            return _json(listing)
        try:
            data = await _body(request)
            if isinstance(data, dict) and "participant" in data:
                participant = self._participant(data["participant"])
                running = self.lab.open_study(participant)
                if running is not None:
                    return _json(self._status(running, request))
                session = await self.lab.create_study(participant)
            else:
                plan = parse_plan(data)
                avatars = await asyncio.to_thread(build_avatars, plan)
                session = await self.lab.create(plan, avatars)
        except InputError as error:
            raise ApiError(400, str(error)) from None
        except OSError as error:
            raise unwritable(error) from None
        return _json(self._status(session, request), 201)

    def _participant(self, participant: object) -> int:
        """Check a participant's number for a run of the server's protocol."""
        if self.lab.protocol is None:
            raise InputError(
                "participant", "no protocol loaded (load one on the console, or use --protocol)"
            )
        if not isinstance(participant, int) or isinstance(participant, bool) or participant < 0:
            raise InputError("participant", "must be the participant's number, 0 or more")
        if participant > MAX_PARTICIPANT:
            raise InputError("participant", f"must be at most {MAX_PARTICIPANT}")
        return participant

    async def protocol(self, request: Request) -> Response:
        """Load the protocol in the body (``name``, ``text``) and use it from then on.

        Answers the protocol's title, seed, people and kept copy; refused while a participant's
        run of the current protocol is playing (409).
        """
        data = await _body(request, limit=MAX_PROTOCOL_BODY_BYTES)
        if not isinstance(data, dict) or not all(
            isinstance(data.get(key), str) for key in ("name", "text")
        ):
            raise ApiError(400, 'the body must be {"name": the file\'s name, "text": its TOML}')
        async with self.loading:
            current = None if self.lab.protocol is None else self.lab.protocol.source
            playing = [
                s.id
                for s in self.lab.sessions.values()
                if isinstance(s, StudySession)
                and s.protocol.source == current
                and s.state in PLAYING
            ]
            if playing:
                problem = f"{playing[0]} is playing: load a protocol when no trial runs"
                return _json({"error": problem}, 409)
            try:
                protocol = await asyncio.to_thread(
                    store_protocol, self.lab.settings.out_dir, data["name"], data["text"]
                )
            except InputError as error:
                raise ApiError(400, str(error)) from None
            except OSError as error:
                raise unwritable(error) from None
            self.lab.protocol = protocol
        logger.info("protocol %s loaded from the console", protocol.source)
        return _json({"protocol": protocol_summary(protocol)})

    async def session(self, request: Request) -> Response:
        """One session's status and join links."""
        return _json(self._status(self._session(request), request))

    async def live(self, request: Request) -> Response:
        """Answer the running trial's last 10 s of positions and group synchronisation."""
        session = self._session(request)
        trial = session.trial
        if trial is None:
            return _json({"state": session.state, "trial": None})
        data = await asyncio.to_thread(trial.recent, 10.0)
        return _json({"state": session.state, "trial": trial.n, "progress": trial.progress} | data)

    async def command(self, request: Request) -> Response:
        """Start, stop or abort a session."""
        action = request.path_params["action"]
        session = self._session(request)
        data = await _body(request, allow_empty=True)
        if action == "start":
            force = bool(isinstance(data, dict) and data.get("force"))
            problem = unjoined(session) if hidden_of(session) and not force else None
            problem = problem or session.start(force=force)
            if problem is not None:
                return _json({"error": problem}, 409)
        elif action == "stop":
            await session.stop()
        elif action == "abort":
            await session.abort()
        elif action == "export":
            return await self._export(session, data)
        else:
            return _json({"error": f"unknown action {action!r}: start, stop, abort or export"}, 404)
        return _json(self._status(session, request))

    async def _export(self, session: LabSession, data: Any) -> Response:
        """Export the session as BIDS into ``OUT/bids`` or ``OUT/<folder>`` (not while playing).

        Answers the dataset's folder, its number of files and the motion files written.
        """
        from mirror_avatar.lab.bids import export_bids

        folder = data.get("folder", "bids") if isinstance(data, dict) else "bids"
        if not isinstance(folder, str) or not EXPORT_FOLDER.fullmatch(folder):
            raise ApiError(400, "folder: a name of letters, digits, - and _ (at most 64)")
        target = self.lab.settings.out_dir / folder
        if folder == PROTOCOLS_FOLDER:
            raise ApiError(400, f"folder: {folder} holds the loaded protocols, not a BIDS dataset")
        if folder in self.lab.sessions or await asyncio.to_thread(is_session_folder, target):
            raise ApiError(400, f"folder: {folder} is a session's folder, not a BIDS dataset")
        if session.state in PLAYING:
            problem = f"the session is playing ({session.state}): export when it waits or has ended"
            return _json({"error": problem}, 409)

        def export() -> tuple[int, int]:  # off the event loop: the trials' clocks run on it
            written = export_bids(session.directory, target)
            return len(written), sum(1 for path in target.rglob("*") if path.is_file())

        try:
            motion_files, files = await asyncio.to_thread(export)
        except InputError as error:
            raise ApiError(400, str(error)) from None
        except OSError as error:
            raise unwritable(error) from None
        session.log(f"exported {motion_files} motion files to {target}")
        return _json({"folder": str(target), "files": files, "motion_files": motion_files})

    async def file(self, request: Request) -> Response:
        """Serve a file of the session's folder, by one of the names the session lists.

        Opened in a worker thread by the checked reader (`mirror_avatar.user_files.
        open_regular`: a regular file of at most `MAX_FILE_BYTES`) and sent in chunks read in
        worker threads.
        """
        name = request.path_params["name"]
        session = self._session(request)
        if hidden_of(session):
            problem = "the protocol is double blind: a run's files are hidden until its export"
            return _json({"error": problem}, 403)
        path = session.directory / name
        if not FILE_NAME.fullmatch(name):
            return _json({"error": "no such file in this session"}, 404)
        try:
            handle = await asyncio.to_thread(open_regular, path, MAX_FILE_BYTES)
        except InputError:
            return _json({"error": "no such file in this session"}, 404)
        size = os.fstat(handle.fileno()).st_size
        return StreamingResponse(
            file_chunks(handle),
            media_type=mimetypes.guess_type(name)[0] or "application/octet-stream",
            headers={"Cache-Control": "no-store", "Content-Length": str(size)},
        )

    async def qr(self, request: Request) -> Response:
        """Serve the QR code (SVG) of a person's join link."""
        import segno

        links = join_links(self._session(request), request)
        label = request.path_params["label"]
        if label not in links:
            return _json({"error": "no such person in this session"}, 404)
        svg = io.BytesIO()
        segno.make(links[label], error="m").save(svg, kind="svg", scale=4, border=2)
        return Response(
            svg.getvalue(), media_type="image/svg+xml", headers={"Cache-Control": "no-store"}
        )

    def _status(self, session: LabSession, request: Request) -> dict[str, Any]:
        """Return a session's status and links, blinded for a double-blind protocol's run."""
        links = {} if session.ended else join_links(session, request)
        return console_status(session, session.status() | {"links": links})


def protocol_summary(protocol: Protocol) -> dict[str, Any]:
    """Return the protocol as the console shows it: title, seed, people, blind, file, warnings."""
    return {
        "title": protocol.title,
        "seed": protocol.seed,
        "people": protocol.people,
        "blind": protocol.blind,
        "file": protocol.source,
        "warnings": list(protocol.warnings),
    }


def join_links(session: LabSession, request: Request) -> dict[str, str]:
    """Each person's join link, on the address the researcher reached the server by."""
    base = str(request.base_url).rstrip("/")
    return {p.label: f"{base}/join/{p.key}" for p in session.everyone()}


class ApiError(Exception):
    """An API request that cannot be served: answered as ``{"error": message}`` with ``status``."""

    def __init__(self, status: int, message: str) -> None:
        super().__init__(message)
        self.status = status


def unwritable(error: OSError) -> ApiError:
    """Say in one line which file the server could not write (a full disk, a file-size limit)."""
    line = str(InputError(error.filename, error.strerror or type(error).__name__))
    logger.warning("cannot write: %s", line)
    return ApiError(500, line)


async def api_error(request: Request, error: Exception) -> Response:
    """Answer an `ApiError` as JSON."""
    assert isinstance(error, ApiError)
    return _json({"error": str(error)}, error.status)


async def _body(request: Request, allow_empty: bool = False, limit: int = MAX_BODY_BYTES) -> Any:
    """Read a request's JSON body: at most ``limit`` bytes, parsed by the bounded parser.

    Raises
    ------
    ApiError
        400: over the limit, or not JSON (`mirror_avatar.user_files.parse_json`: not UTF-8,
        nested too deeply, NaN or a number beyond float64's range).
    """
    raw = bytearray()
    async for chunk in request.stream():  # read no further than the limit
        raw += chunk
        if len(raw) > limit:
            raise ApiError(400, f"request body over {limit} bytes")
    if not raw and allow_empty:
        return {}
    try:
        return await asyncio.to_thread(parse_json, bytes(raw), None, "the request body")
    except InputError as error:
        raise ApiError(400, str(error)) from None


async def file_chunks(handle: IO[bytes], size: int = 2**16) -> AsyncIterator[bytes]:
    """Yield an open file's bytes in chunks of ``size`` read in worker threads, then close it."""
    try:
        while chunk := await asyncio.to_thread(handle.read, size):
            yield chunk
    finally:
        handle.close()


def _json(data: dict[str, Any], status: int = 200) -> JSONResponse:
    return JSONResponse(json_safe(data), status_code=status, headers={"Cache-Control": "no-store"})


async def join_socket(lab: Lab, websocket: WebSocket) -> None:
    """Serve a participant's page: its position in, the frames of the players it sees out."""
    found = lab.find(websocket.path_params["key"])
    if found is None:
        await websocket.close(CLOSE_UNKNOWN, "this link is not valid or its session has ended")
        return
    session, participant = found
    await websocket.accept()
    previous = participant.connection
    if isinstance(previous, WebSocket):  # it may be gone already, or closing for another page
        with contextlib.suppress(RuntimeError, OSError, WebSocketDisconnect):
            await previous.close(CLOSE_REPLACED, "this link was opened on another page")
    page = ParticipantPage(lab.settings, session, participant, websocket)
    await page.run()


class ParticipantPage:
    """One participant page's connection: receive positions and pongs, ping, send frames."""

    def __init__(
        self,
        settings: LabSettings,
        session: LabSession,
        participant: Participant,
        websocket: WebSocket,
    ) -> None:
        self.settings = settings
        self.session = session
        self.participant = participant
        self.websocket = websocket
        self.pings = Pings()
        self.outbox = Outbox(Peer(websocket, settings.send_timeout, participant.label))
        self.inbox = Inbox(
            websocket,
            parse_participant_message,
            settings.max_message_rate,
            settings.max_rejected,
            lambda problem: self.outbox.put({"type": "error", "message": problem}),
            lambda: self.outbox.end(CLOSE_POLICY, "too many bad messages"),
        )

    async def run(self) -> None:
        """Serve the page until it closes or the session ends."""
        self.participant.pings = self.pings
        self.session.attach(self.participant, self.outbox, self.websocket)
        pinger = asyncio.get_running_loop().create_task(self._ping())
        try:
            await self._receive()
        finally:
            pinger.cancel()
            if self.outbox.ending:
                await self.outbox.ended()
            self.session.detach(self.participant, self.outbox)
            self.outbox.close()  # also when a newer page of the slot replaced this one

    async def _ping(self) -> None:
        while True:
            self.outbox.put({"type": "ping", "id": self.pings.send()})
            await asyncio.sleep(self.settings.ping_interval)

    async def _receive(self) -> None:
        async for message in self.inbox.messages():
            self._handle(message)

    def _handle(self, message: PositionUpdate | Pong | Answer) -> None:
        participant = self.participant
        participant.last_heard = time.monotonic()
        if isinstance(message, Answer):
            problem = self.session.answer(participant, message)
            if problem is not None:
                self.outbox.put({"type": "error", "message": problem})
        elif isinstance(message, Pong):
            self.pings.answer(message.id)
            participant.late_frames = message.late_frames
        elif isinstance(participant.source, BrowserInput):
            participant.source.put(message.x, message.seq)

"""The researcher's HTTP/JSON API of the lab server (routes: `mirror_avatar.lab.running.server`).

Every answer is JSON, errors ``{"error": text}``; request bodies are read up to a bound and
parsed by the bounded parser (`mirror_avatar.files.user_files.parse_json`); files are served only
from a session's own folder, by the names it lists, through the checked reader.
"""

from __future__ import annotations

import asyncio
import io
import logging
import mimetypes
import os
import re
from collections.abc import AsyncIterator
from typing import IO, Any

from starlette.requests import ClientDisconnect, Request
from starlette.responses import JSONResponse, Response, StreamingResponse

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.atomic import json_safe
from mirror_avatar.files.trial_io import MAX_FILE_BYTES
from mirror_avatar.files.user_files import open_regular, parse_json
from mirror_avatar.lab.design.plan import parse_plan
from mirror_avatar.lab.design.protocol import MAX_PROTOCOL_BYTES, Protocol
from mirror_avatar.lab.design.protocol_store import PROTOCOLS_FOLDER, store_protocol
from mirror_avatar.lab.files import is_session_folder
from mirror_avatar.lab.running.blinding import console_status, hidden_of, unjoined
from mirror_avatar.lab.running.public import base_address
from mirror_avatar.lab.running.runner import LabSession
from mirror_avatar.lab.running.screening import still_screened
from mirror_avatar.lab.running.sessions import Lab
from mirror_avatar.lab.running.study import ParticipantRun
from mirror_avatar.lab.running.trial import build_avatars

logger = logging.getLogger(__name__)

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

DEFAULT_REFUSAL = "You cannot take part in this study."
"""What a screened-out person is told when the researcher gives no reason."""

MAX_REASON_CHARS = 200
"""Longest reason a screened-out person is told (characters)."""

PLAYING = ("countdown", "running", "pause")
"""States in which a session's trials are being played (no export then)."""


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
            return json_answer(listing)
        try:
            data = await read_body(request)
            if isinstance(data, dict) and "participant" in data:
                participant = self._participant(data["participant"])
                running = self.lab.open_study(participant)
                if running is not None:
                    return json_answer(self._status(running, request))
                session = await self.lab.create_study(participant)
            else:
                plan = parse_plan(data)
                avatars = await asyncio.to_thread(build_avatars, plan)
                session = await self.lab.create(plan, avatars)
        except InputError as error:
            raise ApiError(400, str(error)) from None
        except OSError as error:
            raise unwritable(error) from None
        return json_answer(self._status(session, request), 201)

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
        data = await read_body(request, limit=MAX_PROTOCOL_BODY_BYTES)
        if not isinstance(data, dict) or not all(
            isinstance(data.get(key), str) for key in ("name", "text")
        ):
            raise ApiError(400, 'the body must be {"name": the file\'s name, "text": its TOML}')
        async with self.loading:
            current = None if self.lab.protocol is None else self.lab.protocol.source
            playing = [
                s.id
                for s in self.lab.sessions.values()
                if isinstance(s.schedule, ParticipantRun)
                and s.schedule.protocol.source == current
                and s.state in PLAYING
            ]
            if playing:
                problem = f"{playing[0]} is playing: load a protocol when no trial runs"
                return json_answer({"error": problem}, 409)
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
        return json_answer({"protocol": protocol_summary(protocol)})

    async def session(self, request: Request) -> Response:
        """One session's status and join links."""
        return json_answer(self._status(self._session(request), request))

    async def live(self, request: Request) -> Response:
        """Answer the running trial's last 10 s of positions and group synchronisation."""
        session = self._session(request)
        trial = session.trial
        if trial is None:
            return json_answer({"state": session.state, "trial": None})
        data = await asyncio.to_thread(trial.recent, 10.0)
        return json_answer(
            {"state": session.state, "trial": trial.n, "progress": trial.progress} | data
        )

    async def command(self, request: Request) -> Response:
        """Start, stop or abort a session."""
        action = request.path_params["action"]
        session = self._session(request)
        data = await read_body(request, allow_empty=True)
        if action == "start":
            force = bool(isinstance(data, dict) and data.get("force"))
            problem = None if force else not_ready(session)
            problem = problem or session.start(force=force)
            if problem is not None:
                return json_answer({"error": problem}, 409)
        elif action == "stop":
            await session.stop()
        elif action == "abort":
            await session.abort()
        elif action == "export":
            return await self._export(session, data)
        elif action == "refuse":
            self._refuse(session, data)
        else:
            problem = f"unknown action {action!r}: start, stop, abort, export or refuse"
            return json_answer({"error": problem}, 404)
        return json_answer(self._status(session, request))

    def _refuse(self, session: LabSession, data: Any) -> None:
        """Screen out the person labelled ``data["person"]``, telling them ``data["reason"]``.

        `mirror_avatar.lab.running.sessions.Lab.refuse`: their page shows the reason and the
        protocol's refusal code or link.
        """
        body = data if isinstance(data, dict) else {}
        people = {p.label: p for p in session.everyone()}
        reason = body.get("reason", DEFAULT_REFUSAL)
        if body.get("person") not in people:
            raise ApiError(400, f"person: one of {', '.join(people)}")
        if not isinstance(reason, str) or not 0 < len(reason) <= MAX_REASON_CHARS:
            raise ApiError(400, f"reason: one line of 1 to {MAX_REASON_CHARS} characters")
        self.lab.refuse(people[body["person"]].key, " ".join(reason.split()))

    async def _export(self, session: LabSession, data: Any) -> Response:
        """Export the session as BIDS into ``OUT/bids`` or ``OUT/<folder>`` (not while playing).

        Answers the dataset's folder, its number of files and the motion files written.
        """
        from mirror_avatar.lab.export.bids import export_bids

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
            return json_answer({"error": problem}, 409)

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
        return json_answer({"folder": str(target), "files": files, "motion_files": motion_files})

    async def file(self, request: Request) -> Response:
        """Serve a file of the session's folder, by one of the names the session lists.

        Opened in a worker thread by the checked reader (`mirror_avatar.files.user_files.
        open_regular`: a regular file of at most `MAX_FILE_BYTES`) and sent in chunks read in
        worker threads.
        """
        name = request.path_params["name"]
        session = self._session(request)
        if hidden_of(session):
            problem = "the protocol is double blind: a run's files are hidden until its export"
            return json_answer({"error": problem}, 403)
        path = session.directory / name
        if not FILE_NAME.fullmatch(name):
            return json_answer({"error": "no such file in this session"}, 404)
        try:
            handle = await asyncio.to_thread(open_regular, path, MAX_FILE_BYTES)
        except InputError:
            return json_answer({"error": "no such file in this session"}, 404)
        size = os.fstat(handle.fileno()).st_size
        return StreamingResponse(
            file_chunks(handle),
            media_type=mimetypes.guess_type(name)[0] or "application/octet-stream",
            headers={"Cache-Control": "no-store", "Content-Length": str(size)},
        )

    async def qr(self, request: Request) -> Response:
        """Serve the QR code (SVG) of a person's join link."""
        import segno

        links = join_links(self._session(request), self._base(request))
        label = request.path_params["label"]
        if label not in links:
            return json_answer({"error": "no such person in this session"}, 404)
        svg = io.BytesIO()
        segno.make(links[label], error="m").save(svg, kind="svg", scale=4, border=2)
        return Response(
            svg.getvalue(), media_type="image/svg+xml", headers={"Cache-Control": "no-store"}
        )

    def _base(self, request: Request) -> str:
        """Return the address join links are built on (`mirror_avatar.lab.running.public`)."""
        return base_address(self.lab.settings.public_url, request)

    def _status(self, session: LabSession, request: Request) -> dict[str, Any]:
        """Return a session's status and links, blinded for a double-blind protocol's run."""
        links = {} if session.ended else join_links(session, self._base(request))
        return console_status(session, session.status() | {"links": links})


def not_ready(session: LabSession) -> str | None:
    """Say why a session should not start yet unless forced, or None.

    A double-blind run's pages not all joined (`unjoined`), or a person's entry still being
    screened (`mirror_avatar.lab.running.screening.still_screened`).
    """
    return (unjoined(session) if hidden_of(session) else None) or still_screened(session)


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


def join_links(session: LabSession, base: str) -> dict[str, str]:
    """Each person's join link, on the address ``base`` (``https://NAME[:PORT]``)."""
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
    return json_answer({"error": str(error)}, error.status)


async def read_body(
    request: Request, allow_empty: bool = False, limit: int = MAX_BODY_BYTES
) -> Any:
    """Read a request's JSON body: at most ``limit`` bytes, parsed by the bounded parser.

    Raises
    ------
    ApiError
        400: over the limit, or not JSON (`mirror_avatar.files.user_files.parse_json`: not UTF-8,
        nested too deeply, NaN or a number beyond float64's range), or the connection closed
        before the body's end (its client left, or the server closed it: its body came too
        slowly); the answer then goes nowhere, and nothing is logged as an error.
    """
    raw = bytearray()
    try:
        async for chunk in request.stream():  # read no further than the limit
            raw += chunk
            if len(raw) > limit:
                raise ApiError(400, f"request body over {limit} bytes")
    except ClientDisconnect:
        raise ApiError(400, "the connection closed before the request's body ended") from None
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


def json_answer(data: dict[str, Any], status: int = 200) -> JSONResponse:
    """Answer ``data`` as JSON (never cached)."""
    return JSONResponse(json_safe(data), status_code=status, headers={"Cache-Control": "no-store"})

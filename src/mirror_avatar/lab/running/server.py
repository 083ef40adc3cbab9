"""The lab server: the researcher's console, its HTTP/JSON API and the participants' pages.

Routes (`create_lab_app`):

- ``GET /console``: the researcher's console (a page using the API below).
- ``GET /api/sessions``: every session's status (and the protocol's title, seed and people
  when one is loaded); ``POST /api/sessions`` with a plan
  (`mirror_avatar.lab.design.plan.parse_plan`) builds its avatars (a bad spec is refused here, 400),
  creates the session and answers its status and its join links; with a protocol loaded,
  ``POST /api/sessions`` with ``{"participant": p}`` creates (or resumes) participant p's run
  of it (`mirror_avatar.lab.running.study.ParticipantRun`), or answers the run as it is while it is
  open (200: a reloaded console shows it again).
- ``POST /api/protocol`` with ``{"name": file name, "text": TOML}``: loads a protocol from the
  console (`mirror_avatar.lab.design.protocol_store.store_protocol`: validated, kept as
  ``OUT/protocols/<name>.toml``, used from then on); refused while a participant's run of the
  current protocol is playing (409).
- ``GET /api/sessions/{id}``: a session's status
(`mirror_avatar.lab.running.runner.LabSession.status`)
  with its join links; ``GET /api/sessions/{id}/live``: the last 10 s of positions and ρ_g.
- ``POST /api/sessions/{id}/start`` (body ``{"force": true}`` starts without everyone),
  ``/stop`` and ``/abort``; ``/refuse`` (body ``{"person": label, "reason": text}``) screens a
  person out (`mirror_avatar.lab.running.sessions.Lab.refuse`);
  ``POST /api/sessions/{id}/export`` (body ``{"folder": name}``, optional) exports the
  session's trials as BIDS (`mirror_avatar.lab.export.bids.export_bids`) into ``OUT/bids`` or
  ``OUT/<name>`` between trials, answering the folder and its file count.
- ``GET /api/sessions/{id}/files/{name}``: a file of the session (plan, trials' recordings;
  refused, 403, for a run of a double-blind protocol, whose statuses are blinded too:
  `mirror_avatar.lab.running.blinding`);
  ``GET /api/sessions/{id}/qr/{label}.svg``: the QR code of a person's join link (join links are
  built on the server's public address when it has one: `mirror_avatar.lab.running.public`).
- ``GET /join/{key}``: a participant's page (its panel identifiers, in a protocol's run, taken
  from the query: `join_page`); ``GET /join/{key}/intro`` and ``POST /join/{key}/consent``: the
  pages before the game and the consent answer (`mirror_avatar.lab.running.consent`);
  ``/ws/join/{key}``: its WebSocket (`mirror_avatar.lab.running.messages`).

Access: ``/console`` and ``/api`` need the researcher's token always, even on loopback: as the
``token`` query parameter (the console's URL), the cookie the console sets, or an
``Authorization: Bearer`` header (scripts). POSTs must be JSON (a cross-site form cannot send
one). A join link holds the secret key of one person's slot in one session: it shows that
session only, moves that person's point only, and expires when the session ends. WebSocket
handshakes from another origin than the server's (or its public address's) are refused. Rates
are limited per client address (API requests, connections; the researcher's token-carrying
requests have a budget of their own, so a flood from their address does not slow them) and per
connection (messages). Clients never name
a path: files are written by the server into ``OUT/<session id>/`` under names it makes, and
served only from the session's own folder by the names it lists, through the checked reader.

The session registry and the settings are in `mirror_avatar.lab.running.sessions`, the API's
handlers in `mirror_avatar.lab.running.api`, a participant page's WebSocket in
`mirror_avatar.lab.running.participant_page`.
"""

from __future__ import annotations

import functools
from pathlib import Path
from urllib.parse import urlsplit

from starlette.applications import Starlette
from starlette.middleware import Middleware
from starlette.requests import Request
from starlette.responses import FileResponse, PlainTextResponse, RedirectResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.types import ASGIApp

from mirror_avatar.lab.design.online import panel_values
from mirror_avatar.lab.running.api import ApiError, LabApi, api_error
from mirror_avatar.lab.running.consent import consent, intro
from mirror_avatar.lab.running.participant_page import join_socket
from mirror_avatar.lab.running.public import is_secure
from mirror_avatar.lab.running.sessions import Lab, LabSettings
from mirror_avatar.lab.running.study import ParticipantRun
from mirror_avatar.realtime.gates import JsonGate, OriginGate, RateGate, TokenGate

STATIC = Path(__file__).parents[1] / "static"
"""The console's and the participants' pages."""

TOKEN_COOKIE = "mirror_avatar_lab_token"
"""The cookie holding the researcher's token once the console's link was opened."""


def create_lab_app(settings: LabSettings) -> ASGIApp:
    """Build the lab server's ASGI application (see the module docstring)."""
    lab = Lab(settings)
    api = LabApi(lab)
    rate = settings.requests_per_second
    researcher = "the console needs the researcher's token (printed by mirror-avatar lab)"
    app = Starlette(
        routes=[
            Route("/", index_page),
            Route("/console", functools.partial(console_page, settings.public_url)),
            Route("/join/{key}", functools.partial(join_page, lab)),
            Route("/join/{key}/intro", functools.partial(intro, lab)),
            Route("/join/{key}/consent", functools.partial(consent, lab), methods=["POST"]),
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
                paths=("/api", "/ws", "/join"),
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
            Middleware(OriginGate, also=public_hosts(settings.public_url)),
            Middleware(JsonGate),
        ],
    )
    app.state.lab = lab
    return app


async def index_page(request: Request) -> Response:
    """Where to go: the console's link or a join link."""
    return PlainTextResponse("mirror-avatar lab: open the console link it printed, or a join link.")


def public_hosts(public_url: str | None) -> frozenset[str]:
    """Return the host (``name[:port]``) of the public address, whose pages may connect."""
    return frozenset() if public_url is None else frozenset({urlsplit(public_url).netloc})


async def console_page(public_url: str | None, request: Request) -> Response:
    """Serve the console; the token in its URL goes into a cookie and out of the URL.

    The gate checked the token: a wrong one never reaches here, so it cannot replace the
    researcher's cookie. Over TLS (`mirror_avatar.lab.running.public.is_secure`) the cookie is
    marked secure: the browser never sends it over plain HTTP.
    """
    if "token" in request.query_params:
        token = request.query_params["token"]
        response: Response = RedirectResponse("/console", status_code=303)
        secure = is_secure(public_url, request)
        response.set_cookie(TOKEN_COOKIE, token, httponly=True, samesite="strict", secure=secure)
        return response
    return FileResponse(STATIC / "console.html", headers={"Cache-Control": "no-store"})


async def join_page(lab: Lab, request: Request) -> Response:
    """Serve a participant's page while its link is valid, recording its panel identifiers.

    In a participant's run of a protocol with ``panel_ids`` (`mirror_avatar.lab.design.online`),
    the identifiers the link's query gives are kept for its person (a link opened again without
    them keeps those given before); a value that is not a safe identifier is refused (400).
    """
    found = lab.find(request.path_params["key"])
    if found is None:
        return PlainTextResponse("this link is not valid or its session has ended", 404)
    session, participant = found
    if isinstance(session.schedule, ParticipantRun):
        names = session.schedule.protocol.online.panel_ids
        values = panel_values(names, request.query_params)
        if isinstance(values, str):
            return PlainTextResponse(values, 400)
        participant.panel |= values
    return FileResponse(STATIC / "participant.html", headers={"Cache-Control": "no-store"})

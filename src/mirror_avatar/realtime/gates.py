"""Gates: ASGI middleware that refuses a request or a WebSocket handshake for one reason each.

Both servers stack the gates they need as Starlette middleware, outermost first, for instance::

    Starlette(routes, middleware=[
        Middleware(RateGate, rate=40.0, burst=160.0, paths=("/api", "/ws")),
        Middleware(TokenGate, token=token, cookie="name", paths=("/api", "/console")),
        Middleware(OriginGate),
    ])

Each gate answers one question about a request (`Gate.problem`); the first gate with a problem
refuses it - an HTTP status with a one-line text, or a WebSocket close with code 1008 - and the
application behind never sees it. A request every gate passes reaches the application with the
server's own ``send`` callable kept in its scope (`mirror_avatar.realtime.transport.SERVER_SEND`).

- `HostGate`: only requests addressed to a loopback name or address, or a name the researcher
  allows, so a page of another site whose name resolves to 127.0.0.1 (DNS rebinding) cannot
  reach a server that has no token.
- `TokenGate`: the access token, as a ``token`` query parameter, a cookie or an
  ``Authorization: Bearer`` header, compared in constant time.
- `OriginGate`: WebSocket handshakes only from pages of the server's own origin.
- `RateGate`: requests per second from one client address (the token's holder has a budget of
  their own).
- `JsonGate`: POST bodies must be declared JSON (a cross-site form cannot send one).
"""

from __future__ import annotations

import hmac
import ipaddress
from collections.abc import Sequence
from urllib.parse import urlsplit

from starlette.requests import HTTPConnection
from starlette.responses import PlainTextResponse
from starlette.types import ASGIApp, Receive, Scope, Send
from starlette.websockets import WebSocketClose

from mirror_avatar.realtime.rates import TokenBucket, bucket_for
from mirror_avatar.realtime.transport import SERVER_SEND

CLOSE_POLICY = 1008
"""WebSocket close code of a refused handshake (policy violation)."""

EVERYWHERE: tuple[str, ...] = ("/",)
"""The path prefixes of a gate guarding every request."""


class Refusal(Exception):
    """Why a gate refuses a request: the text and the HTTP status."""

    def __init__(self, text: str, status: int = 403) -> None:
        super().__init__(text)
        self.text = text
        self.status = status


class Gate:
    """ASGI middleware passing the requests `problem` finds nothing wrong with.

    Parameters
    ----------
    app
        The application (or the next gate) behind this one.
    paths
        Path prefixes the gate guards (the others pass).
    """

    def __init__(self, app: ASGIApp, paths: Sequence[str] = EVERYWHERE) -> None:
        self.app = app
        self.paths = tuple(paths)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        """Pass allowed requests through; refuse the others (HTTP status or WebSocket close)."""
        if scope["type"] in ("http", "websocket"):
            connection = HTTPConnection(scope)
            try:
                if connection.url.path.startswith(self.paths):
                    self.check(connection)
            except Refusal as refusal:
                if scope["type"] == "http":
                    response = PlainTextResponse(refusal.text, status_code=refusal.status)
                    await response(scope, receive, send)
                else:
                    await WebSocketClose(CLOSE_POLICY, refusal.text)(scope, receive, send)
                return
            scope.setdefault(SERVER_SEND, send)
        await self.app(scope, receive, send)

    def check(self, connection: HTTPConnection) -> None:
        """Raise `Refusal` when the request must not pass."""
        raise NotImplementedError


LOOPBACK_NAMES = frozenset({"localhost"})
"""Host names that always mean this machine (addresses are recognised as loopback by value)."""


def host_name(host_header: str | None) -> str:
    """Return the name or address of a ``Host`` header without its port or IPv6 brackets."""
    host = (host_header or "").strip().lower()
    if host.startswith("["):
        return host[1:].split("]", 1)[0]
    return host.rsplit(":", 1)[0] if host.count(":") == 1 else host


def is_loopback(host: str) -> bool:
    """Whether ``host`` (a name or an address) only reaches this machine."""
    if host in LOOPBACK_NAMES or host.endswith(".localhost"):
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def host_allowed(host_header: str | None, allowed: frozenset[str]) -> bool:
    """Whether a request addressed to ``host_header`` may be answered without a token.

    Loopback names and addresses always may; other names only when listed in ``allowed``.
    """
    host = host_name(host_header)
    return is_loopback(host) or host in allowed


class HostGate(Gate):
    """Refuse requests addressed to a host that is neither loopback nor in ``allowed``."""

    def __init__(self, app: ASGIApp, allowed: frozenset[str] = frozenset()) -> None:
        super().__init__(app)
        self.allowed = allowed

    def check(self, connection: HTTPConnection) -> None:
        """Refuse a request addressed to another host (403)."""
        if not host_allowed(connection.headers.get("host"), self.allowed):
            raise Refusal(
                "this server answers only requests addressed to this machine (see --allow-host)"
            )


def given_token(connection: HTTPConnection, cookie: str, query: bool = True) -> str | None:
    """Return the token a request carries: bearer header, else query parameter, else cookie."""
    header = connection.headers.get("authorization", "")
    if header.startswith("Bearer "):
        return header.removeprefix("Bearer ").strip()
    if query and "token" in connection.query_params:
        return connection.query_params["token"]
    return connection.cookies.get(cookie)


def token_matches(given: str | None, token: str) -> bool:
    """Whether ``given`` is ``token`` (compared in constant time)."""
    return given is not None and hmac.compare_digest(given.encode(), token.encode())


class TokenGate(Gate):
    """Refuse requests that do not carry the access token.

    Parameters
    ----------
    app, paths
        As in `Gate`.
    token
        The token.
    cookie
        The cookie that may carry it.
    problem
        The refusal's text.
    """

    def __init__(
        self,
        app: ASGIApp,
        token: str,
        cookie: str,
        paths: Sequence[str] = EVERYWHERE,
        problem: str = "missing or wrong access token",
    ) -> None:
        super().__init__(app, paths)
        self.token = token
        self.cookie = cookie
        self.problem = problem

    def check(self, connection: HTTPConnection) -> None:
        """Refuse a request without the right token (403)."""
        if not token_matches(given_token(connection, self.cookie), self.token):
            raise Refusal(self.problem)


class OriginGate(Gate):
    """Refuse WebSocket handshakes sent by a page of another origin than the server's.

    Parameters
    ----------
    app
        As in `Gate`.
    also
        Further hosts (``name[:port]``) whose pages may connect: the server's public address
        behind a reverse proxy that does not pass the ``Host`` header on.
    """

    def __init__(self, app: ASGIApp, also: frozenset[str] = frozenset()) -> None:
        super().__init__(app)
        self.also = also

    def check(self, connection: HTTPConnection) -> None:
        """Refuse a cross-origin WebSocket handshake (close 1008)."""
        origin = connection.headers.get("origin")
        if (
            connection.scope["type"] == "websocket"
            and origin is not None
            and urlsplit(origin).netloc not in {connection.headers.get("host"), *self.also}
        ):
            raise Refusal("cross-origin WebSocket refused")


class RateGate(Gate):
    """Refuse requests beyond ``rate`` per second (bursts of ``burst``) from one address.

    With a ``token``, requests carrying it (`given_token`) draw on a budget of their own,
    the same rate and burst, not on their address's: a flood of anonymous connections from
    the researcher's address (or a proxy's) leaves the researcher's API calls their rate.
    """

    def __init__(
        self,
        app: ASGIApp,
        rate: float,
        burst: float,
        paths: Sequence[str] = EVERYWHERE,
        token: str | None = None,
        cookie: str = "",
    ) -> None:
        super().__init__(app, paths)
        self.rate = rate
        self.burst = burst
        self.token = token
        self.cookie = cookie
        self.buckets: dict[str, TokenBucket] = {}
        self.holder = TokenBucket(rate, burst)

    def check(self, connection: HTTPConnection) -> None:
        """Take one request from its budget; refuse it when exhausted (429)."""
        if self.token is not None and token_matches(
            given_token(connection, self.cookie), self.token
        ):
            bucket = self.holder
        else:
            address = connection.client.host if connection.client else ""
            bucket = bucket_for(self.buckets, address, self.rate, self.burst)
        if bucket.take() > 0.0:
            raise Refusal("too many requests: slow down", 429)


class JsonGate(Gate):
    """Refuse POST requests whose body is not declared JSON."""

    def check(self, connection: HTTPConnection) -> None:
        """Refuse a POST without ``Content-Type: application/json`` (415)."""
        if connection.scope["type"] == "http" and connection.scope["method"] == "POST":
            kind = connection.headers.get("content-type", "")
            if not kind.startswith("application/json"):
                raise Refusal("API requests must be JSON (Content-Type: application/json)", 415)

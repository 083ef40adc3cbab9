"""Slow and flooding clients of a real lab server over real sockets on loopback.

Half-sent requests, trickled bodies and one address's crowd of connections are closed
(`mirror_avatar.realtime.protocols`, `mirror_avatar.realtime.connections`), while another
address, the researcher's API and a joined participant's page keep being served. Every wait has
a generous deadline; nothing is timed.
"""

from __future__ import annotations

import contextlib
import logging
import socket
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest
from websockets.sync.client import connect

from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.realtime.settings import ConnectionSettings
from mirror_avatar.testing import ServerThread
from waiting import wait_for

TOKEN = "researcher-token"
BEARER = {"Authorization": f"Bearer {TOKEN}"}
HALF_SENT = b"GET /api/sessions HTTP/1.1\r\nHost: 127.0.0.1\r\n"
"""A request whose headers never end."""
SLOW_BODY = (
    b"POST /api/sessions HTTP/1.1\r\nHost: 127.0.0.1\r\nAuthorization: Bearer "
    + TOKEN.encode()
    + b"\r\nContent-Type: application/json\r\nContent-Length: 1000\r\n\r\n{"
)
"""A request whose body never ends."""
CAP = 4
"""Connections per address in these tests."""
CLOSED_WITHIN = 30.0
"""Seconds a connection the server must close is given (generous: the machine is busy)."""


def serve(tmp_path: Path, **guard: float) -> ServerThread:
    settings = LabSettings(out_dir=tmp_path, token=TOKEN, countdown=1)
    limits = {"header_timeout": 60.0, "body_timeout": 60.0, "max_per_address": CAP} | guard
    return ServerThread(create_lab_app(settings), guard=ConnectionSettings(**limits))  # type: ignore[arg-type]


@contextlib.contextmanager
def heard() -> Iterator[list[str]]:
    """The server log's warnings from now on (once the server has configured its logs)."""
    lines: list[str] = []
    handler = logging.Handler(logging.WARNING)
    handler.emit = lambda record: lines.append(record.getMessage())  # type: ignore[method-assign]
    log = logging.getLogger("uvicorn.error")
    log.addHandler(handler)
    yield lines
    log.removeHandler(handler)


def open_from(server: ServerThread, source: str, data: bytes = HALF_SENT) -> socket.socket:
    """Connect from loopback address ``source`` and send ``data``."""
    sock = socket.create_connection((server.host, server.port), source_address=(source, 0))
    sock.sendall(data)
    return sock


def closed(sock: socket.socket, trickle: float = 0.0) -> bool:
    """Wait until the server closes ``sock`` (within `CLOSED_WITHIN`); whether it did.

    With ``trickle`` (s), a byte more is sent that often meanwhile (slowloris).
    """
    sock.settimeout(trickle or CLOSED_WITHIN)
    rounds = int(CLOSED_WITHIN / trickle) if trickle else 1
    for _ in range(rounds):
        try:
            while data := sock.recv(4096):
                assert b"200 OK" not in data
            return True
        except ConnectionResetError:
            return True
        except TimeoutError:
            with contextlib.suppress(OSError):
                sock.send(b"a")
    return False


def still_open(sock: socket.socket) -> bool:
    """Whether the server has neither closed ``sock`` nor sent anything on it."""
    try:
        sock.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT)
    except BlockingIOError:
        return True
    except OSError:
        return False
    return False


def answered(server: ServerThread, source: str = "127.0.0.1", path: str = "/api/sessions") -> int:
    """The status of a GET of ``path`` with the token, on a new connection from ``source``."""
    transport = httpx.HTTPTransport(local_address=source)
    with httpx.Client(transport=transport, headers=BEARER, timeout=CLOSED_WITHIN) as client:
        return client.get(f"{server.url}{path}").status_code


def test_a_half_sent_request_is_closed_after_the_header_timeout(tmp_path):
    with serve(tmp_path, header_timeout=1.0) as server, heard() as warnings:
        quiet = open_from(server, "127.0.0.2")
        trickling = open_from(server, "127.0.0.3")
        with quiet, trickling:
            assert closed(quiet)
            assert closed(trickling, trickle=0.1)
        assert answered(server) == 200
    late = [line for line in warnings if "headers not complete within 1 s" in line]
    assert {line.split(":")[0] for line in late} == {"127.0.0.2", "127.0.0.3"}


def test_a_slow_body_is_closed_after_the_body_timeout(tmp_path):
    with serve(tmp_path, body_timeout=1.0) as server, heard() as warnings:
        with open_from(server, "127.0.0.2", SLOW_BODY) as slow:
            assert closed(slow, trickle=0.1)
        assert answered(server) == 200
    assert any("body not complete within 1 s" in line for line in warnings)
    assert not any("Exception" in line for line in warnings)


def test_the_per_address_cap_refuses_one_more_while_another_address_is_served(tmp_path):
    with serve(tmp_path) as server, heard() as warnings, contextlib.ExitStack() as stack:
        held = [stack.enter_context(open_from(server, "127.0.0.2")) for _ in range(CAP)]
        extra = [stack.enter_context(open_from(server, "127.0.0.2")) for _ in range(3)]
        assert all(closed(sock) for sock in extra)
        assert all(still_open(sock) for sock in held)
        assert answered(server, "127.0.0.3") == 200
        held.pop().close()  # room for one more
        wait_for(lambda: answered(server, "127.0.0.2") == 200, what="a place freed")
    refusals = [line for line in warnings if "too many from this address" in line]
    assert refusals == ["127.0.0.2: connections refused, too many from this address: 1 (one "
                        "line per address per 10 s at most)"]  # fmt: skip


def test_an_address_opening_connections_too_fast_is_refused_while_another_is_served(tmp_path):
    with serve(tmp_path, connection_rate=0.01) as server, heard() as warnings:  # burst 2 * CAP
        assert [answered(server, "127.0.0.2", "/") for _ in range(2 * CAP)] == [200] * 2 * CAP
        with open_from(server, "127.0.0.2", b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n") as late:
            assert closed(late)
        assert answered(server, "127.0.0.3", "/") == 200
    assert any("127.0.0.2: connections refused, opened too fast" in line for line in warnings)


@pytest.mark.parametrize("held", [HALF_SENT, SLOW_BODY], ids=["half-sent", "slow body"])
def test_the_researcher_and_a_joined_page_are_served_while_the_server_is_full(tmp_path, held):
    full = serve(tmp_path, max_connections=2 * CAP + 1)
    with full as server, heard() as warnings, contextlib.ExitStack() as stack:
        people = [{"label": "P1", "kind": "human"}, {"label": "P2", "kind": "human"}]
        plan = {"condition": "joint", "duration": 30.0, "players": people}
        created = httpx.post(f"{server.url}/api/sessions", json=plan, headers=BEARER).json()
        link = created["links"]["P1"].replace("http://", "ws://").replace("/join/", "/ws/join/")
        page = stack.enter_context(connect(link, proxy=None, open_timeout=CLOSED_WITHIN))
        assert '"welcome"' in str(page.recv(timeout=CLOSED_WITHIN))
        for source in ("127.0.0.2", "127.0.0.3"):  # together with the page: full
            for _ in range(CAP):
                stack.enter_context(open_from(server, source, held))
        for _ in range(3):
            assert answered(server) == 200
        status = httpx.get(f"{server.url}/api/sessions/{created['id']}", headers=BEARER).json()
        assert [slot.get("connected") for slot in status["slots"]] == [True, False]
    assert any("closed to make room" in line for line in warnings)

"""The lab server with its own certificate and a public address, over real sockets: the console's
cookie is secure, join links and QR codes use the public address, a page's secure WebSocket
from it is welcomed; bad certificate, key or address options are one line each, exit code 2."""

from __future__ import annotations

import asyncio
import json
import ssl
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest
import websockets
from test_lab_server import BEARER, DYAD, TOKEN
from tls_servers import free_port, new_key, self_signed, write_key

from mirror_avatar.cli import main
from mirror_avatar.lab.running.server import TOKEN_COOKIE, LabSettings, create_lab_app
from mirror_avatar.realtime.tls import TlsFiles
from mirror_avatar.testing import ServerThread


@pytest.fixture
def certified(tmp_path: Path) -> TlsFiles:
    return TlsFiles(*self_signed(tmp_path))


@pytest.fixture
def lab(tmp_path: Path, certified: TlsFiles) -> Iterator[ServerThread]:
    """A lab server over HTTPS on 127.0.0.1 whose public address is https://localhost:PORT."""
    port = free_port()
    settings = LabSettings(
        out_dir=tmp_path / "out", token=TOKEN, public_url=f"https://localhost:{port}"
    )
    with ServerThread(create_lab_app(settings), tls=certified, port=port) as running:
        yield running


def test_links_cookie_and_a_secure_websocket_over_the_servers_certificate(lab, certified):
    trusted = ssl.create_default_context(cafile=certified.certfile)
    public = f"https://localhost:{lab.port}"
    with httpx.Client(base_url=lab.url, verify=trusted) as client:
        opened = client.get(f"/console?token={TOKEN}", follow_redirects=False)
        assert opened.status_code == 303
        cookie = opened.headers["set-cookie"]
        assert cookie.startswith(f"{TOKEN_COOKIE}=") and "secure" in cookie.lower()
        created = client.post("/api/sessions", json=DYAD, headers=BEARER)
        assert created.status_code == 201, created.text
        links = created.json()["links"]
        assert set(links) == {"P1", "P2"}
        assert all(link.startswith(f"{public}/join/") for link in links.values())
        qr = client.get(f"/api/sessions/{created.json()['id']}/qr/P1.svg", headers=BEARER)
        assert qr.status_code == 200 and qr.content.startswith(b"<?xml")
    with httpx.Client(verify=trusted) as browser:  # the participant, at the public address
        assert browser.get(links["P1"]).status_code == 200
    socket_url = links["P1"].replace("https://", "wss://").replace("/join/", "/ws/join/")

    async def welcome(origin: str) -> dict[str, object]:
        async with websockets.connect(socket_url, ssl=trusted, origin=origin) as page:  # type: ignore[arg-type]
            while (message := json.loads(await page.recv()))["type"] != "welcome":
                pass
            return message

    assert asyncio.run(welcome(public))["label"] == "P1"
    with pytest.raises(websockets.InvalidStatus):  # a page of another site
        asyncio.run(welcome("https://elsewhere.example.org"))


def test_plain_http_to_the_tls_port_gets_no_page(lab):
    with pytest.raises(httpx.HTTPError):
        httpx.get(lab.url.replace("https://", "http://") + "/", timeout=5)


def bad_options(folder: Path) -> list[tuple[list[str], str, str]]:
    """Bad certificate options, each with the file and the option its error line names."""
    cert, key = self_signed(folder)
    other = folder / "other.key"
    write_key(new_key(), other)
    junk = folder / "junk.pem"
    junk.write_text("not a certificate\n")
    missing = folder / "missing.key"
    return [
        (["--certfile", str(cert), "--keyfile", str(missing)], str(missing), "--keyfile"),
        (["--certfile", str(folder / "no.crt"), "--keyfile", str(key)], "no.crt", "--certfile"),
        (["--certfile", str(junk), "--keyfile", str(key)], str(junk), "--certfile"),
        (["--certfile", str(cert), "--keyfile", str(junk)], str(junk), "--keyfile"),
        (["--certfile", str(cert), "--keyfile", str(other)], str(other), "--keyfile"),
        (["--certfile", str(cert)], "--certfile", "--keyfile"),
        (["--public-url", "ftp://study.example.org"], "ftp://", "--public-url"),
        (["--public-url", "study.example.org"], "study.example.org", "--public-url"),
        (["--public-url", "https://study.example.org/lab?x=1"], "/lab", "--public-url"),
    ]


def test_bad_certificate_and_address_options_are_one_line(tmp_path, capsys):
    for options, named, option in bad_options(tmp_path):
        code = main(["lab", "--port", "0", "--out", str(tmp_path / "out"), *options])
        err = capsys.readouterr().err
        assert code == 2, (options, err)
        assert err.count("\n") == 1 and "Traceback" not in err, err
        assert named in err and option in err, (options, err)

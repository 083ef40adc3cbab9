"""Access to the lab server: a wrong token cannot replace the researcher's cookie, secrets stay
out of the server's log, and ended sessions leave memory (their links stop, their files stay)."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import httpx
import pytest
from test_lab_server import BEARER, DYAD, TOKEN, command, create, socket_url
from websockets.sync.client import connect

from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.lab.running.sessions import KEEP_ENDED
from mirror_avatar.testing import ServerThread
from waiting import wait_for


def test_a_link_with_a_wrong_token_leaves_the_researchers_cookie_alone(tmp_path):
    app = create_lab_app(LabSettings(out_dir=tmp_path, token=TOKEN))
    with ServerThread(app) as lab, httpx.Client(base_url=lab.url) as browser:
        entered = browser.get(f"/console?token={TOKEN}", follow_redirects=True)
        assert entered.status_code == 200 and "New session" in entered.text
        lured = browser.get("/console?token=anything")
        assert lured.status_code == 403 and "set-cookie" not in lured.headers
        assert browser.get("/api/sessions").status_code == 200  # still the researcher


def test_tokens_and_join_keys_stay_out_of_the_log(tmp_path):
    log = tmp_path / "server.log"
    with log.open("w") as output:
        server = subprocess.Popen(
            [Path(sys.executable).parent / "mirror-avatar", "lab", "--port", "0",
             "--out", str(tmp_path / "out"), "--no-lsl"],
            stdout=output, stderr=subprocess.STDOUT, text=True,
            env=os.environ | {"PYTHONUNBUFFERED": "1"},
        )  # fmt: skip
    try:

        def console_link() -> re.Match[str] | None:
            assert server.poll() is None, log.read_text()
            return re.search(r"console: (http://[^/]+)/console\?token=(\S+)", log.read_text())

        url, token = wait_for(console_link, 60.0, "the console's link", interval=0.1).groups()
        headers = {"Authorization": f"Bearer {token}"}
        with httpx.Client(base_url=url) as browser:
            assert browser.get(f"/console?token={token}").status_code == 303
            created = browser.post("/api/sessions", json=DYAD, headers=headers).json()
            link = created["links"]["P1"]
            assert browser.get(link).status_code == 200
        with connect(socket_url(link)) as page:
            assert '"welcome"' in page.recv(5)
    finally:
        server.send_signal(signal.SIGINT)
        server.wait(20)
    text = log.read_text()
    key = link.rsplit("/", 1)[1]
    access = [line for line in text.splitlines() if "GET " in line or "WebSocket" in line]
    assert len(access) == 3, text
    assert not [line for line in access if token in line or key in line], text
    assert any("/join/***" in line for line in access) and any(
        "token=***" in line for line in access
    )


def test_ended_sessions_leave_memory_their_links_stop_and_their_files_stay(tmp_path):
    with ServerThread(create_lab_app(LabSettings(out_dir=tmp_path, token=TOKEN))) as lab:
        ended = []
        for _ in range(KEEP_ENDED + 3):
            created = create(lab, DYAD)
            assert command(lab, created["id"], "abort").status_code == 200
            ended.append(created)
        listed = httpx.get(f"{lab.url}/api/sessions", headers=BEARER).json()["sessions"]
        assert [s["id"] for s in listed] == [s["id"] for s in ended[-KEEP_ENDED:]]
        assert all(s["links"] == {} for s in listed)
        first = ended[0]
        missing = httpx.get(f"{lab.url}/api/sessions/{first['id']}", headers=BEARER)
        assert missing.status_code == 404
        for created in (first, ended[-1]):
            assert httpx.get(created["links"]["P1"]).status_code == 404
        assert (tmp_path / first["id"] / "plan.json").is_file()
        again = create(lab, DYAD)  # a new session gets a new folder, never an old one's
        assert again["id"] not in {s["id"] for s in ended}


@pytest.mark.parametrize(("options", "said"), [([], "LSL off"), (["--lsl"], "LSL on")])
def test_lsl_streams_are_published_only_when_asked(tmp_path, options, said):
    """An LSL outlet is discoverable on the whole network: a lab on loopback publishes none."""
    if options:
        pytest.importorskip("pylsl")
    server = subprocess.Popen(
        [sys.executable, "-c", "from mirror_avatar.console import run; run()", "lab",
         "--port", "0", "--out", str(tmp_path / "out"), *options],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
    )  # fmt: skip
    try:
        first = server.stdout.readline()  # type: ignore[union-attr]
        lines = [server.stdout.readline() for _ in range(2)]  # type: ignore[union-attr]
        console = lines[-1].split()[1]
        # stopped once it serves: its Ctrl+C handling is then uvicorn's
        wait_for(lambda: _answers(console), 60.0, "the lab serving")
    finally:
        server.send_signal(signal.SIGINT)
        server.communicate(timeout=20)
    assert first.startswith("mirror-avatar lab: recording to") and first.endswith(f"; {said}\n")
    assert lines[0].startswith("researcher's token: ") and lines[1].startswith("console: ")


def _answers(url: str) -> bool:
    """Whether a server answers at ``url``."""
    try:
        return httpx.get(url, timeout=2.0).status_code < 500
    except httpx.TransportError:
        return False

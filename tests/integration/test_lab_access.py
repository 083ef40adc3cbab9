"""Access to the lab server: a wrong token cannot replace the researcher's cookie, secrets stay
out of the server's log, and ended sessions leave memory (their links stop, their files stay)."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import httpx
from test_lab_server import BEARER, DYAD, TOKEN, command, create, socket_url
from websockets.sync.client import connect

from mirror_avatar.lab.server import KEEP_ENDED, LabSettings, create_lab_app
from mirror_avatar.testing import ServerThread


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
        url = token = None
        deadline = time.monotonic() + 60.0
        while not (url and token):
            assert server.poll() is None and time.monotonic() < deadline, log.read_text()
            time.sleep(0.1)
            if found := re.search(r"console: (http://[^/]+)/console\?token=(\S+)", log.read_text()):
                url, token = found.groups()
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

"""A study served to a recruitment panel over HTTPS, in real browsers: the server shows a
certificate the test made, the console hands out links at the public address, two participants'
pages open them with their panel identifiers, read the instructions and agree to the consent
page, play the trial and are shown the completion code and the link back; the console exports the
run with the identifiers and the completion code each was shown; a participant who does not
agree is shown the refusal code."""

from __future__ import annotations

import csv
import json
import ssl
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from test_lab_browser import TrustingBrowser, screenshot, shown_links
from test_lab_online import COMPLETE, ONLINE
from tls_servers import free_port, self_signed

from mirror_avatar.lab.design.protocol import load_protocol
from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.realtime.tls import TlsFiles
from mirror_avatar.testing import ServerThread

pytestmark = pytest.mark.browser

TOKEN = "online-browser-token"
BEARER = {"Authorization": f"Bearer {TOKEN}"}
PROTOCOL = f"""
title = "mirror game online"
seed = 5
{ONLINE}
[[blocks]]
[[blocks.conditions]]
name = "together"
game = "joint"
players = [{{ label = "P1", kind = "person" }}, {{ label = "P2", kind = "person" }}]
trials = 1
duration = 3
"""
CONSENT = """This study is run by the Mirror Lab. Your pointer's movements are recorded with your \
panel identifier; nothing else about you is.
Taking part is voluntary: you may stop at any time by closing this page.
Do you agree to take part?"""
PANEL = {
    "P1": "PROLIFIC_PID=5f1a2b3c4d5e6f7a8b9c0d1e&STUDY_ID=64aa01&SESSION_ID=s-01",
    "P2": "PROLIFIC_PID=60b2c3d4e5f6a7b8c9d0e1f2&STUDY_ID=64aa01&SESSION_ID=s-02",
}


@pytest.fixture
def served(tmp_path: Path) -> Iterator[tuple[ServerThread, TlsFiles, str]]:
    """The lab over HTTPS on 127.0.0.1, its public address https://localhost:PORT."""
    (tmp_path / "study.toml").write_text(PROTOCOL)
    (tmp_path / "consent.txt").write_text(CONSENT)
    port = free_port()
    public = f"https://localhost:{port}"
    settings = LabSettings(
        out_dir=tmp_path / "out",
        token=TOKEN,
        countdown=1,
        protocol=load_protocol(tmp_path / "study.toml"),
        public_url=public,
    )
    tls = TlsFiles(*self_signed(tmp_path))
    with ServerThread(create_lab_app(settings), tls=tls, port=port) as server:
        yield server, tls, public


def create_run(console: Any, participant: int) -> dict[str, str]:
    """Create a participant's run on the console; return its people's join links."""
    console.fill("#participant", str(participant))
    console.click("#create-participant")
    console.wait_for_function(
        f"document.getElementById('session-id').textContent === 'study-p{participant:03d}'"
    )
    return shown_links(console)


def open_intro(browser: Any, link: str) -> Any:
    page = browser.new_context(viewport={"width": 900, "height": 700}).new_page()
    page.goto(link)
    page.wait_for_selector("#intro:not([hidden]) #consent")
    return page


def test_panel_participants_consent_play_and_get_the_completion_code_over_https(
    chromium, served, tmp_path
):
    server, tls, public = served
    trusting = TrustingBrowser(chromium)
    console = trusting.new_context(viewport={"width": 1280, "height": 1000}).new_page()
    console.goto(f"{server.url}/console?token={TOKEN}")
    console.wait_for_selector("#study:not([hidden])")
    links = create_run(console, 0)
    assert all(link.startswith(f"{public}/join/") for link in links.values()), links
    pages = {label: open_intro(trusting, f"{link}?{PANEL[label]}") for label, link in links.items()}
    intro = pages["P1"].locator("#intro").inner_text()
    assert "Follow your partner as closely as you can" in intro
    assert "Do you agree to take part?" in intro
    screenshot(pages["P1"], "lab-online-consent")
    assert not console.locator("#slots td.state.connected").count()  # no one joined before agreeing
    for page in pages.values():
        page.click("#agree")
        page.wait_for_function("window.mirrorLab && window.mirrorLab.welcome !== null")
    console.wait_for_function("document.querySelectorAll('#slots td.state.connected').length === 2")
    console.click("#start")
    for page in pages.values():
        page.wait_for_selector("#ending:not([hidden]) #ending-code", timeout=60_000)
    end = pages["P2"]
    assert end.locator("#ending-code").inner_text() == "C1A2B3C4"
    assert end.locator("#ending-link").get_attribute("href") == COMPLETE
    screenshot(end, "lab-online-end")
    console.click("#export")
    console.wait_for_function(
        "document.getElementById('export-result').textContent.startsWith('exported')"
    )
    out = tmp_path / "out"
    sidecar = json.loads((out / "study-p000" / "trial-01_session.json").read_text())["metadata"]
    assert sidecar["complete"]
    assert sidecar["lab"]["panel"]["P2"] == {
        "PROLIFIC_PID": "60b2c3d4e5f6a7b8c9d0e1f2",
        "STUDY_ID": "64aa01",
        "SESSION_ID": "s-02",
    }
    assert set(sidecar["lab"]["consented"]) == {"P1", "P2"}
    with (out / "bids" / "participants.tsv").open(encoding="utf-8") as table:
        rows = {row["label"]: row for row in csv.DictReader(table, delimiter="\t")}
    assert rows["P1"]["PROLIFIC_PID"] == "5f1a2b3c4d5e6f7a8b9c0d1e"
    assert rows["P2"]["SESSION_ID"] == "s-02"
    assert rows["P1"]["completion_code"] == rows["P2"]["completion_code"] == "C1A2B3C4"

    declining = open_intro(trusting, f"{create_run(console, 1)['P1']}?{PANEL['P1']}")
    declining.click("#decline")
    declining.wait_for_selector("#ending:not([hidden]) #ending-code")
    assert declining.locator("#ending-code").inner_text() == "NOFIT123"
    assert "You chose not to take part" in declining.locator("#message").inner_text()
    screenshot(declining, "lab-online-declined")
    trusted = ssl.create_default_context(cafile=tls.certfile)
    status = httpx.get(f"{server.url}/api/sessions/study-p001", headers=BEARER, verify=trusted)
    assert any("P1 did not agree" in event for event in status.json()["events"])
    for page in (console, declining, *pages.values()):  # the browser closes its TLS connections
        page.context.close()

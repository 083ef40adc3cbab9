"""The console loading a study protocol in a real browser: a file chosen in its file input,
a bad one refused with its one line, a good one shown and a participant's run created."""

from __future__ import annotations

import json

import pytest
from browsers import SCREENSHOTS
from test_lab_study import PROTOCOL

from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.testing import ServerThread

pytestmark = pytest.mark.browser

TOKEN = "protocol-load-token"
SCREENSHOT = "lab-protocol-loaded-console.png"
REFUSED = "lab-protocol-refused-panel.png"


def test_the_console_loads_a_protocol_file_and_creates_a_participants_run(chromium, tmp_path):
    bad = tmp_path / "pilot.toml"
    bad.write_text(PROTOCOL.replace("trials = 2", "trials = 0"))
    good = tmp_path / "pilot study.toml"
    good.write_text(PROTOCOL)
    out = tmp_path / "out"
    settings = LabSettings(out_dir=out, token=TOKEN, countdown=1)
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    for name in (SCREENSHOT, REFUSED):
        (SCREENSHOTS / name).unlink(missing_ok=True)
    with ServerThread(create_lab_app(settings)) as lab:
        console = chromium.new_context(viewport={"width": 1280, "height": 900}).new_page()
        console.goto(f"{lab.url}/console?token={TOKEN}")
        console.wait_for_selector("#study #load-protocol")
        assert console.locator("#study-title").inner_text() == "none loaded"
        assert console.locator("#study-run").is_hidden()

        console.set_input_files("#protocol-file", str(bad))
        console.click("#load-protocol")
        console.wait_for_function("document.getElementById('protocol-error').textContent !== ''")
        refusal = console.locator("#protocol-error").inner_text()
        assert refusal.startswith("pilot.toml: blocks[0].conditions[1].trials: ")
        assert "\n" not in refusal
        assert console.locator("#study-run").is_hidden()
        console.locator("#study").screenshot(path=str(SCREENSHOTS / REFUSED))

        console.set_input_files("#protocol-file", str(good))
        console.click("#load-protocol")
        console.wait_for_selector("#study-run:not([hidden])")
        title = console.locator("#study-title").inner_text()
        assert title == '"test study" · seed 7 · people P1, P2'
        copy = out / "protocols" / "pilot-study.toml"
        assert console.locator("#protocol-result").inner_text() == f"loaded; kept as {copy}"
        assert console.locator("#protocol-error").inner_text() == ""
        assert copy.read_text() == PROTOCOL

        console.fill("#participant", "1")
        console.click("#create-participant")
        console.locator('a.join[data-label="P1"]').wait_for()
        sid = console.locator("#session-id").inner_text()
        assert sid == "pilot-study-p001"
        study = json.loads((out / sid / "study.json").read_text())
        assert study["protocol"]["source"] == str(copy) and study["participant"] == 1
        console.wait_for_function(
            "document.getElementById('session-summary').textContent.startsWith('participant 1')"
        )
        console.screenshot(path=str(SCREENSHOTS / SCREENSHOT), full_page=True)

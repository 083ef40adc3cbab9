"""A study protocol's questions in real browsers: two participants' pages answer after the
trial, one by mouse on a desktop page and one by touch on a phone-sized page."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from browsers import SCREENSHOTS

from mirror_avatar.lab.design.protocol import load_protocol
from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.testing import ServerThread
from waiting import wait_for

pytestmark = pytest.mark.browser

TOKEN = "study-browser-token"
BEARER = {"Authorization": f"Bearer {TOKEN}"}
PROTOCOL = """
title = "questions in the browser"
seed = 3

[questions.partner]
text = "Was your partner a person or a computer?"
kind = "choice"
options = ["a person", "a computer"]

[questions.confidence]
text = "How confident are you?"
kind = "likert"
points = 7
anchors = ["guessing", "certain"]

[questions.remarks]
text = "Anything you noticed?"
kind = "text"
max_chars = 60

[[blocks]]
name = "only"
after_block = ["remarks"]

[[blocks.conditions]]
name = "together"
game = "joint"
players = [{ label = "P1", kind = "person" }, { label = "P2", kind = "person" }]
trials = 1
duration = 2
after_trial = ["partner", "confidence"]
"""


@pytest.fixture
def lab(tmp_path: Path) -> Iterator[ServerThread]:
    path = tmp_path / "study.toml"
    path.write_text(PROTOCOL)
    settings = LabSettings(
        out_dir=tmp_path / "out", token=TOKEN, countdown=1, protocol=load_protocol(path)
    )
    with ServerThread(create_lab_app(settings)) as running:
        yield running


def join(context: Any, link: str) -> Any:
    page = context.new_page()
    page.goto(link)
    page.wait_for_function("window.mirrorLab && window.mirrorLab.welcome !== null")
    return page


def button(question: str, value: str) -> str:
    return f'fieldset[data-question="{question}"] button[data-value="{value}"]'


@pytest.mark.long
def test_two_pages_answer_by_mouse_and_by_touch(chromium, lab, tmp_path):
    console = chromium.new_context(viewport={"width": 1280, "height": 900}).new_page()
    console.goto(f"{lab.url}/console?token={TOKEN}")
    console.wait_for_selector("#study:not([hidden])")
    assert "people P1, P2" in console.locator("#study-title").inner_text()
    console.fill("#participant", "0")
    console.click("#create-participant")
    console.wait_for_selector("a.join")
    sid = console.locator("#session-id").inner_text()
    assert sid == "study-p000"
    links = httpx.get(f"{lab.url}/api/sessions/{sid}", headers=BEARER).json()["links"]
    desk = join(chromium.new_context(viewport={"width": 900, "height": 600}), links["P1"])
    phone_context = chromium.new_context(
        viewport={"width": 390, "height": 780}, has_touch=True, is_mobile=True
    )
    phone = join(phone_context, links["P2"])
    partner = [v["label"] for v in phone.evaluate("window.mirrorLab.welcome.visible")][1:]
    assert partner == ["your partner"]
    start = httpx.post(f"{lab.url}/api/sessions/{sid}/start", json={}, headers=BEARER)
    assert start.status_code == 200, start.text
    for page in (desk, phone):
        page.wait_for_selector("#questions fieldset", timeout=30_000)
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    phone.screenshot(path=SCREENSHOTS / "lab-study-question-phone.png", full_page=True)
    console.wait_for_function(  # the console polls: wait for the status that lists the questions
        "document.getElementById('session-summary').textContent.includes('P1 to answer')"
    )
    summary = console.locator("#session-summary").inner_text()
    assert "block 1 of 1, condition 'together', trial 1 of 1" in summary
    assert "P1 to answer: confidence, partner, remarks" in summary
    assert "P2 to answer: confidence, partner, remarks" in summary
    console.screenshot(path=SCREENSHOTS / "lab-study-console.png", full_page=True)

    desk.click(button("partner", "a computer"))
    desk.click(button("confidence", "6"))
    desk.fill('fieldset[data-question="remarks"] textarea', "it followed me")
    desk.click('fieldset[data-question="remarks"] button')
    phone.tap(button("partner", "a person"))
    phone.tap(button("confidence", "3"))
    phone.fill('fieldset[data-question="remarks"] textarea', "felt human")
    phone.screenshot(path=SCREENSHOTS / "lab-study-question-phone-answered.png", full_page=True)
    phone.tap('fieldset[data-question="remarks"] button')

    def finished() -> bool:
        answer = httpx.get(f"{lab.url}/api/sessions/{sid}", headers=BEARER).json()
        return answer["state"] == "finished"

    desk.wait_for_function("document.getElementById('questions').hidden")
    phone.wait_for_function("document.getElementById('questions').hidden")
    wait_for(finished, what="the run to finish")
    saved = json.loads((tmp_path / "out" / sid / "trial-01_answers.json").read_text())
    values = {
        label: {q: a["value"] for q, a in answers.items()}
        for label, answers in saved["answers"].items()
    }
    assert values == {
        "P1": {"partner": "a computer", "confidence": 6, "remarks": "it followed me"},
        "P2": {"partner": "a person", "confidence": 3, "remarks": "felt human"},
    }
    assert (saved["after_trial"], saved["after_block"]) == (["partner", "confidence"], ["remarks"])
    for context in (desk.context, phone_context, console.context):
        context.close()


OCCLUDED = """
title = "hidden partner"
seed = 2

[[blocks]]
name = "only"

[[blocks.conditions]]
name = "hidden"
game = "joint"
players = [
  { label = "P1", kind = "person" },
  { label = "A1", kind = "avatar", spec = "bundled:slow" },
]
trials = 1
duration = 7
occlude = [[2.0, 4.5]]
"""

PARTNER_PIXELS = """async () => {
  // The page draws on its animation frames what its last message said: the pixels are read
  // two frames after the state, and the state again, so that a sample taken as the occlusion
  // begins or ends (a frame not drawn yet), or as the session ends (the line alone is drawn
  // from then on), is seen to straddle it.
  const state = () => {
    if (document.getElementById("message").textContent.includes("session has ended")) {
      return "over";
    }
    const x = window.mirrorLab.others.get(1);
    return x === null ? "hidden" : typeof x === "number" ? "shown" : "none";
  };
  const frame = () => new Promise((resolve) => requestAnimationFrame(resolve));
  const before = state();
  await frame();
  await frame();
  const canvas = document.getElementById("field");
  const data = canvas.getContext("2d").getImageData(0, 0, canvas.width, canvas.height).data;
  let n = 0;  // the partner's colour, #d62728 (player 1)
  for (let i = 0; i < data.length; i += 4) {
    const near = (value, target) => Math.abs(value - target) < 25;
    if (near(data[i], 214) && near(data[i + 1], 39) && near(data[i + 2], 40)) n += 1;
  }
  return [n, before, state()];
}"""


def test_an_occluded_partner_is_absent_from_the_page_pixels(chromium, tmp_path):
    path = tmp_path / "hidden.toml"
    path.write_text(OCCLUDED)
    settings = LabSettings(
        out_dir=tmp_path / "out", token=TOKEN, countdown=1, protocol=load_protocol(path)
    )
    with ServerThread(create_lab_app(settings)) as lab:
        created = httpx.post(f"{lab.url}/api/sessions", json={"participant": 0}, headers=BEARER)
        sid, links = created.json()["id"], created.json()["links"]
        page = join(chromium.new_context(viewport={"width": 900, "height": 500}), links["P1"])
        httpx.post(f"{lab.url}/api/sessions/{sid}/start", json={}, headers=BEARER)
        samples: list[tuple[int, str, str]] = []
        page.wait_for_function("window.mirrorLab.others.size === 1", timeout=30_000)
        while httpx.get(f"{lab.url}/api/sessions/{sid}", headers=BEARER).json()["state"] in (
            "countdown",
            "running",
        ):
            samples.append(tuple(page.evaluate(PARTNER_PIXELS)))
            if samples[-1][1] == "hidden" and not (SCREENSHOTS / "lab-study-occluded.png").exists():
                SCREENSHOTS.mkdir(parents=True, exist_ok=True)
                page.screenshot(path=SCREENSHOTS / "lab-study-occluded.png")
            page.wait_for_timeout(50)
        page.context.close()
    hidden = [n for n, before, after in samples if before == after == "hidden"]
    shown = [n for n, before, after in samples if before == after == "shown"]
    assert len(hidden) >= 3 and len(shown) >= 3
    assert max(hidden) == 0  # occluded: not one pixel of the partner's colour
    assert min(shown) > 50, samples  # otherwise the partner's disc is drawn

"""A whole study protocol in real browsers: the console (as a researcher uses it) and two
participants' pages, one answering by mouse on a desktop and one by touch on a phone, through
3 conditions x 2 trials in a counterbalanced order with an avatar; and a partner's visual delay
read back from a page's pixels."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from browsers import SCREENSHOTS
from test_lab_study_browser import button, join

from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.lab.design.order import condition_order
from mirror_avatar.lab.design.protocol import load_protocol
from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.testing import ServerThread

pytestmark = pytest.mark.browser

TOKEN = "study-protocol-token"
PARTICIPANT = 1
CONSOLE = "lab-study-protocol-console.png"
PHONE_QUESTION = "lab-study-protocol-question-phone.png"
PHONE_END = "lab-study-protocol-end-phone.png"
PHONE_WAITING = "lab-study-protocol-waiting-phone.png"
PROTOCOL = """
title = "three conditions"
seed = 11

[questions.partner]
text = "Was your partner a person or a computer?"
kind = "choice"
options = ["a person", "a computer"]

[questions.confidence]
text = "How confident are you?"
kind = "likert"
points = 5
anchors = ["guessing", "certain"]

[[blocks]]
name = "main"
order = "latin"

[[blocks.conditions]]
name = "together"
game = "joint"
players = [{ label = "P1", kind = "person" }, { label = "P2", kind = "person" }]
trials = 2
duration = 2
pause = 0
after_trial = ["partner"]

[[blocks.conditions]]
name = "lead"
game = "leader_follower"
players = [
  { label = "P1", kind = "person" },
  { label = "P2", kind = "person-or-avatar", spec = "bundled:slow" },
]
leaders = ["P1"]
trials = 2
duration = 2
pause = 0
after_trial = ["partner", "confidence"]

[[blocks.conditions]]
name = "trio"
game = "group"
players = [
  { label = "P1", kind = "person" },
  { label = "P2", kind = "person" },
  { label = "A1", kind = "avatar", spec = "bundled:slow" },
]
trials = 2
duration = 2
pause = 0
after_trial = ["confidence"]
"""

TASKS = {  # what each role is asked to do, as the participant's page words it
    "joint": "Move together with your partner: neither of you leads.",
    "leader": "You lead: move freely, your partner follows you.",
    "follower": "Follow your partner as closely as you can.",
    "group": "Move in step with the others.",
}


POINTER_TYPES = """
window.pointerTypes = new Set();  // how the page was pressed: mouse, touch or pen
addEventListener("pointerdown", (event) => window.pointerTypes.add(event.pointerType), true);
"""


def create_run(
    chromium: Any, url: str, token: str, out: Path, participant: int
) -> tuple[Any, dict[str, str], str, dict[str, Any]]:
    """Create a participant's run from the console; return the console page, the people's join
    links, the run's session id and its ``study.json``."""
    console = chromium.new_context(viewport={"width": 1280, "height": 900}).new_page()
    console.goto(f"{url}/console?token={token}")
    console.wait_for_selector("#study:not([hidden])")
    console.fill("#participant", str(participant))
    console.click("#create-participant")
    links = {}
    for label in ("P1", "P2"):
        link = console.locator(f'a.join[data-label="{label}"]')
        link.wait_for()
        links[label] = link.get_attribute("href")
    sid = console.locator("#session-id").inner_text()
    return console, links, sid, json.loads((out / sid / "study.json").read_text())


def role(plan: dict[str, Any], label: str) -> str:
    """The role of a player in a recorded plan (its game and leaders)."""
    labels = [slot["label"] for slot in plan["slots"]]
    if plan["condition"] == "leader_follower":
        return "leader" if labels.index(label) in plan["leaders"] else "follower"
    return "joint" if plan["condition"] == "joint" else "group"


def expected_tasks(study: dict[str, Any], label: str) -> list[tuple[int, str]]:
    """(trial, task words) a person should see, from the order ``study.json`` records."""
    return [
        (n, TASKS[role(condition["plan"], label)])
        for condition in study["order"]
        if condition["players"][label] == "human"
        for n in condition["trials"]
    ]


def move_until(pages: list[Any], done: str) -> None:
    """Sweep each page's pointer to and fro over its field until ``done`` holds on every page."""
    boxes = [page.locator("#field").bounding_box() for page in pages]
    for i in range(300):
        if all(page.evaluate(done) for page in pages):
            return
        for k, (page, box) in enumerate(zip(pages, boxes, strict=True)):
            phase = np.sin(2 * np.pi * i / (40 + 13 * k))
            page.mouse.move(
                box["x"] + box["width"] * (0.5 + 0.3 * phase), box["y"] + box["height"] / 2
            )
        pages[0].wait_for_timeout(30)


def answer(page: Any, n: int, touch: bool) -> dict[str, Any]:
    """Answer the open questions of trial n by click (or tap); return the answers given."""
    page.wait_for_selector("#questions:not([hidden]) fieldset", timeout=30_000)
    asked = page.eval_on_selector_all(
        "#questions fieldset", "sets => sets.map(s => s.dataset.question)"
    )
    given: dict[str, Any] = {}
    for question in asked:
        if question == "partner":
            given[question] = ["a person", "a computer"][(n + touch) % 2]
        else:
            given[question] = 1 + (n + 2 * touch) % 5
        target = button(question, str(given[question]))
        page.tap(target) if touch else page.click(target)
    page.wait_for_function("document.getElementById('questions').hidden")
    return given


@pytest.mark.long
def test_three_pages_run_a_counterbalanced_protocol_with_an_avatar(chromium, tmp_path):
    path = tmp_path / "study.toml"
    path.write_text(PROTOCOL)
    protocol = load_protocol(path)
    out = tmp_path / "out"
    settings = LabSettings(out_dir=out, token=TOKEN, countdown=1, protocol=protocol)
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    for name in (CONSOLE, PHONE_QUESTION, PHONE_END, PHONE_WAITING):
        (SCREENSHOTS / name).unlink(missing_ok=True)
    with ServerThread(create_lab_app(settings)) as lab:
        console, links, sid, study = create_run(chromium, lab.url, TOKEN, out, PARTICIPANT)
        desk_context = chromium.new_context(viewport={"width": 900, "height": 600})
        phone_context = chromium.new_context(
            viewport={"width": 390, "height": 780}, has_touch=True, is_mobile=True
        )
        for context in (desk_context, phone_context):
            context.add_init_script(POINTER_TYPES)
        desk, phone = join(desk_context, links["P1"]), join(phone_context, links["P2"])
        pages = {"P1": (desk, False), "P2": (phone, True)}
        for label in pages:
            console.wait_for_selector(f'tr[data-label="{label}"] td.state.connected')
        console.click("#start")

        seen: dict[str, list[tuple[int, str]]] = {"P1": [], "P2": []}
        given: dict[int, dict[str, dict[str, Any]]] = {}
        texts: list[str] = []
        total = sum(len(condition["trials"]) for condition in study["order"])
        for n in range(1, total + 1):
            playing = {
                label: page
                for label, page in pages.items()
                if any(n in c["trials"] and c["players"][label] == "human" for c in study["order"])
            }
            for label, (page, _) in playing.items():
                page.wait_for_function(
                    f"document.getElementById('trial').textContent === 'Trial {n} of {total}'",
                    timeout=30_000,
                )
                seen[label].append((n, page.locator("#task").inner_text()))
                texts.append(page.locator("body").inner_text())
            move_until(
                [page for page, _ in playing.values()],
                "!document.getElementById('questions').hidden",
            )
            if n >= 2 and "P2" in playing and not (SCREENSHOTS / PHONE_QUESTION).exists():
                console.wait_for_function(
                    "document.getElementById('session-summary').textContent.includes('to answer')"
                )
                condition = next(c for c in study["order"] if n in c["trials"])
                within = condition["trials"].index(n) + 1
                summary = console.locator("#session-summary").inner_text()
                assert f"condition '{condition['condition']}', trial {within} of 2" in summary
                console.screenshot(path=SCREENSHOTS / CONSOLE, full_page=True)
                phone.wait_for_selector("#questions:not([hidden]) fieldset", timeout=30_000)
                phone.screenshot(path=SCREENSHOTS / PHONE_QUESTION)
            if "P2" not in playing:  # P2's partner is an avatar: P2 waits, and is told so
                phone.wait_for_function(
                    "document.getElementById('message').textContent.includes('Not your turn')"
                )
                if not (SCREENSHOTS / PHONE_WAITING).exists():
                    phone.screenshot(path=SCREENSHOTS / PHONE_WAITING)
            given[n] = {}
            for label, (page, touch) in playing.items():
                given[n][label] = answer(page, n, touch)
                texts.append(page.locator("body").inner_text())
        for page, _ in pages.values():
            page.wait_for_function(
                "document.getElementById('message').textContent.includes('session has ended')"
            )
            texts.append(page.locator("body").inner_text())
        phone.screenshot(path=SCREENSHOTS / PHONE_END)
        pressed = {
            label: set(page.evaluate("[...window.pointerTypes]"))
            for label, (page, _) in pages.items()
        }
        desk.screenshot(path=SCREENSHOTS / "lab-study-protocol-end.png")
        console.wait_for_function("document.getElementById('state').textContent === 'finished'")
        for page in [console, desk, phone]:
            page.context.close()

    # counterbalanced: the recorded order is the participant's row of the Latin square
    names = [c.name for c in protocol.blocks[0].conditions]
    row = condition_order("latin", 3, PARTICIPANT, protocol.seed, 0)
    assert [c["condition"] for c in study["order"]] == [names[i] for i in row]
    assert json.loads((out / sid / "study.json").read_text()) == study
    # each person saw their conditions' tasks in the recorded order
    for label in pages:
        assert seen[label] == expected_tasks(study, label)
    assert len(seen["P1"]) == total  # P1 plays every trial; P2 waits if the draw gave an avatar
    assert pressed == {"P1": {"mouse"}, "P2": {"touch"}}  # answered by mouse, and by touch
    # blinded: no page ever showed a kind, a label of an avatar or its spec
    for text in texts:
        words = set(text.lower().replace(".", " ").replace(":", " ").split())
        assert not {"avatar", "a1", "bundled", "human"} & words
    # the files hold the answers and the true kinds of the partners
    for condition in study["order"]:
        for n in condition["trials"]:
            trial = load_session(out / sid / f"trial-{n:02d}_session.csv")
            meta = trial.metadata["lab"]
            assert meta["protocol_condition"] == condition["condition"]
            assert meta["partners"] == condition["players"]
            assert trial.metadata["complete"]
            saved = json.loads((out / sid / f"trial-{n:02d}_answers.json").read_text())
            values = {
                label: {q: a["value"] for q, a in answers.items()}
                for label, answers in saved["answers"].items()
            }
            assert values == given[n]
    kinds = {c["condition"]: c["players"] for c in study["order"]}
    assert kinds["trio"] == {"P1": "human", "P2": "human", "A1": "avatar"}
    drawn = protocol.schedule(PARTICIPANT)
    lead = next(step for step in drawn if step.name == "lead")
    assert kinds["lead"]["P2"] == ("human" if lead.persons["P2"] else "avatar")


DELAYED = """
title = "a late partner"
seed = 5

[[blocks]]
name = "only"

[[blocks.conditions]]
name = "late"
game = "joint"
players = [
  { label = "P1", kind = "person" },
  { label = "A1", kind = "avatar", spec = "bundled:slow" },
]
trials = 1
duration = 3
delay = 0.3
"""

FRAMES_SEEN = """
(() => {  // note the tick k of the last frame the page received
  const Native = window.WebSocket;
  window.WebSocket = class extends Native {
    constructor(...args) {
      super(...args);
      this.addEventListener("message", (event) => {
        const message = JSON.parse(event.data);
        if (message.type === "frame") window.lastFrameK = message.k;
      });
    }
  };
})();
"""

WATCH_PARTNER = """() => {
  // After each of the page's own draws (requestAnimationFrame callbacks run in the order they
  // were asked for), find the partner's disc in the canvas pixels: the lowest band of rows
  // holding the partner's colour (its label is written above it), their mean column its centre.
  window.drawn = [];
  const canvas = document.getElementById("field");
  const ctx = canvas.getContext("2d");
  const hex = window.mirrorLab.welcome.visible[1].colour;
  const rgb = [1, 3, 5].map((i) => parseInt(hex.slice(i, i + 2), 16));
  const look = () => {
    const { width, height } = canvas;
    const data = ctx.getImageData(0, 0, width, height).data;
    let count = 0, sum = 0;
    for (let y = height - 1; y >= 0; y -= 1) {
      let inRow = 0;
      for (let x = 0; x < width; x += 1) {
        const i = 4 * (y * width + x);
        if (data[i + 3] > 128 && rgb.every((c, j) => Math.abs(data[i + j] - c) < 25)) {
          inRow += 1;
          sum += x;
        }
      }
      count += inRow;
      if (count > 0 && inRow === 0) break;
    }
    if (window.lastFrameK !== undefined) {
      window.drawn.push([window.lastFrameK, count ? sum / count : null]);
    }
    requestAnimationFrame(look);
  };
  requestAnimationFrame(look);
}"""


def best_lag(drawn: np.ndarray, recorded: np.ndarray, lags: range) -> tuple[int, float, float]:
    """The lag (samples) at which the drawn centres (pixels) best fit the recorded positions.

    ``drawn`` holds rows (tick k, centre in pixels); for each lag L the pixels are fitted by a
    straight line of the positions recorded at k - L (the page's scale and offset need not be
    known). Returns the best lag, its RMS residual (pixels) and its scale (pixels per unit).
    """
    fits = []
    for lag in lags:
        rows = drawn[drawn[:, 0] >= lag]
        x = recorded[rows[:, 0].astype(int) - lag]
        scale, offset = np.polyfit(x, rows[:, 1], 1)
        residual = float(np.sqrt(np.mean((rows[:, 1] - scale * x - offset) ** 2)))
        fits.append((residual, lag, float(scale)))
    residual, lag, scale = min(fits)
    return lag, residual, scale


def test_a_delayed_partner_is_drawn_300_ms_late_on_the_page(chromium, tmp_path):
    path = tmp_path / "late.toml"
    path.write_text(DELAYED)
    out = tmp_path / "out"
    settings = LabSettings(out_dir=out, token=TOKEN, countdown=1, protocol=load_protocol(path))
    with ServerThread(create_lab_app(settings)) as lab:
        console = chromium.new_context(viewport={"width": 1280, "height": 900}).new_page()
        console.goto(f"{lab.url}/console?token={TOKEN}")
        console.click("#create-participant")
        link = console.locator('a.join[data-label="P1"]')
        link.wait_for()
        context = chromium.new_context(viewport={"width": 900, "height": 500})
        context.add_init_script(FRAMES_SEEN)
        page = join(context, link.get_attribute("href"))
        page.evaluate(WATCH_PARTNER)
        console.wait_for_selector('tr[data-label="P1"] td.state.connected')
        console.click("#start")
        page.wait_for_function("window.drawn.length > 0", timeout=30_000)
        move_until([page], "document.getElementById('message').textContent.includes('ended')")
        drawn = np.array(
            [(k, x) for k, x in page.evaluate("window.drawn") if x is not None], dtype=float
        )
        width = page.evaluate("document.getElementById('field').width")
        sid = console.locator("#session-id").inner_text()
        for each in (console, page):
            each.context.close()
    trial = load_session(out / sid / "trial-01_session.csv")
    assert trial.metadata["lab"]["partner_delay_s"] == pytest.approx(0.3)
    partner = trial.positions[1]
    assert len(drawn) > 60 and np.ptp(partner[drawn[:, 0].astype(int)]) > 0.05  # it moved
    lag, residual, scale = best_lag(drawn, partner, range(0, 31))
    assert abs(lag * CONTROL_PERIOD - 0.3) <= CONTROL_PERIOD + 1e-9
    assert residual < 0.5  # the disc is drawn where the recorded position puts it
    assert scale == pytest.approx(0.9 * width, rel=0.01)  # one unit is 90 % of the field

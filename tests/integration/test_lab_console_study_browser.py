"""The researcher's console through a participant's run in Chromium: a reload keeps the run shown
and "Create (or resume)" shows it again, the trial list names each trial's condition, partners
and answers, and a finished run waits for nobody."""

from __future__ import annotations

import re
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

TOKEN = "console-study-token"
BEARER = {"Authorization": f"Bearer {TOKEN}"}
PROTOCOL = """
title = "the console's trial list"
seed = 11

[questions.partner]
text = "Was your partner a person or a computer?"
kind = "choice"
options = ["a person", "a computer"]

[questions.confidence]
text = "How confident are you?"
kind = "likert"
points = 7

[[blocks]]
name = "partners"
order = "latin"

[[blocks.conditions]]
name = "together"
game = "joint"
players = [
  { label = "P1", kind = "person" },
  { label = "P2", kind = "person-or-avatar", spec = "bundled:slow" },
]
duration = 2
after_trial = ["partner", "confidence"]

[[blocks.conditions]]
name = "follow"
game = "leader_follower"
players = [
  { label = "P1", kind = "person" },
  { label = "A1", kind = "avatar", spec = "bundled:slow" },
]
leaders = ["A1"]
duration = 2
after_trial = ["partner", "confidence"]
"""
ANSWERS = {"P1": ("a computer", "6"), "P2": ("a person", "3")}
"""Each person's answer to the partner question and their confidence."""


BLIND = PROTOCOL.replace("seed = 11\n", 'seed = 11\nblind = "double"\n').replace(
    'kind = "person-or-avatar", spec = "bundled:slow"',
    'kind = "person-or-avatar", spec = "bundled:fast"',
)
"""The same protocol, double blind, its hidden avatar's spec told apart from the other's."""


def serve(tmp_path: Path, text: str) -> ServerThread:
    path = tmp_path / "console.toml"
    path.write_text(text)
    settings = LabSettings(
        out_dir=tmp_path / "out", token=TOKEN, countdown=1, protocol=load_protocol(path)
    )
    return ServerThread(create_lab_app(settings))


@pytest.fixture
def lab(tmp_path: Path) -> Iterator[ServerThread]:
    with serve(tmp_path, PROTOCOL) as running:
        yield running


def join(context: Any, link: str) -> Any:
    page = context.new_page()
    page.goto(link)
    page.wait_for_function("window.mirrorLab && window.mirrorLab.welcome !== null")
    return page


def answer_if_asked(page: Any, label: str) -> None:
    """Click the page's answers when its questions are open."""
    if page.locator("#questions").is_hidden():
        return
    choice, point = ANSWERS[label]
    for question, value in (("partner", choice), ("confidence", point)):
        chosen = page.locator(f'fieldset[data-question="{question}"] button[data-value="{value}"]')
        if chosen.count():
            chosen.click()


def play_to_the_end(chromium: Any, lab: ServerThread, console: Any, sid: str) -> dict[str, Any]:
    """Join both people's pages, start the run from the console and answer until it finishes."""
    links = httpx.get(f"{lab.url}/api/sessions/{sid}", headers=BEARER).json()["links"]
    pages = {label: join(chromium.new_context(), links[label]) for label in ("P1", "P2")}
    console.wait_for_function("!document.getElementById('start').disabled")
    console.click("#start")

    def finished() -> bool:
        if console.locator("#state").inner_text() == "finished":
            return True
        for label, page in reversed(pages.items()):  # the later slot answers first
            answer_if_asked(page, label)
        return False

    wait_for(finished, 120.0, f"the run {sid} to finish on the console", interval=0.1)
    console.wait_for_function("document.querySelectorAll('#trial-list tbody tr').length === 2")
    return pages


@pytest.mark.long
def test_the_console_lists_each_trials_condition_partners_and_answers(chromium, lab, tmp_path):
    console = chromium.new_context(viewport={"width": 1280, "height": 1000}).new_page()
    console.goto(f"{lab.url}/console?token={TOKEN}")
    console.wait_for_selector("#study-run:not([hidden])")
    console.click("#create-participant")
    console.wait_for_selector("a.join")
    sid = console.locator("#session-id").inner_text()
    console.reload()  # the run stays shown, and creating it again shows it without an error
    console.wait_for_selector("a.join")
    assert console.locator("#session-id").inner_text() == sid
    console.click("#create-participant")
    console.wait_for_timeout(600)
    assert console.locator("#study-error").inner_text() == ""
    assert console.locator("#session-id").inner_text() == sid

    pages = play_to_the_end(chromium, lab, console, sid)

    assert console.locator("#session-error").inner_text() == ""
    summary = console.locator("#session-summary").inner_text()
    assert "finished: all 2 trials played" in summary and "waiting" not in summary
    status = httpx.get(f"{lab.url}/api/sessions/{sid}", headers=BEARER).json()
    rows = console.locator("#trial-list tbody tr")
    for i, trial in enumerate(status["trials"]):
        cells = rows.nth(i).locator("td")
        assert cells.nth(1).inner_text() == f"{trial['condition']} (partners)"
        kinds = {"human": "person", "avatar": "avatar"}
        partners = [f"{label} {kinds[kind]}" for label, kind in trial["partners"].items()]
        assert cells.nth(2).inner_text().splitlines() == partners
        answered = [
            f"{label}: partner {ANSWERS[label][0]}, confidence {ANSWERS[label][1]}"
            for label, kind in trial["partners"].items()
            if kind == "human"
        ]
        assert cells.nth(3).inner_text().splitlines() == answered
    assert {trial["condition"] for trial in status["trials"]} == {"together", "follow"}
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    shot = SCREENSHOTS / "lab-console-study-trials.png"
    console.locator("#session").screenshot(path=shot)
    for page in [console, *pages.values()]:
        page.context.close()


def test_a_run_created_while_a_listing_is_on_its_way_stays_shown(chromium, lab):
    """The console asked for the sessions before the run was created and got the answer after:
    the run it shows is not taken for one the server forgot (it was hidden, its hash cleared)."""
    console = chromium.new_context(viewport={"width": 1280, "height": 1000}).new_page()
    held: list[tuple[Any, Any]] = []
    holding = {"on": False}

    def hold_listings(route: Any) -> None:
        if route.request.method == "GET" and holding["on"]:
            held.append((route, route.fetch()))  # answered now, delivered later
        else:
            route.continue_()

    console.route(re.compile(r".*/api/sessions$"), hold_listings)
    console.goto(f"{lab.url}/console?token={TOKEN}")
    console.wait_for_selector("#study-run:not([hidden])")
    holding["on"] = True
    wait_for(lambda: console.wait_for_timeout(50) or held, 30.0, "a listing to be held")
    console.fill("#participant", "0")
    console.click("#create-participant")
    console.wait_for_function("location.hash === '#console-p000'")
    holding["on"] = False
    for route, answer in held:
        route.fulfill(response=answer)
    console.wait_for_function(
        "document.getElementById('sessions-list').textContent.includes('console-p000')"
    )
    assert console.evaluate("location.hash") == "#console-p000"
    assert console.locator("#session").is_visible()
    console.context.close()


@pytest.mark.long
def test_a_double_blind_console_never_shows_the_hidden_kind(chromium, tmp_path):
    with serve(tmp_path, BLIND) as lab:
        console = chromium.new_context(viewport={"width": 1280, "height": 1000}).new_page()
        console.goto(f"{lab.url}/console?token={TOKEN}")
        console.wait_for_selector("#study-run:not([hidden])")
        assert "double blind" in console.locator("#study-title").inner_text()
        texts = []
        protocol = load_protocol(tmp_path / "console.toml")
        draws = {
            p: next(s.persons["P2"] for s in protocol.schedule(p) if s.persons) for p in range(4)
        }
        chosen = [
            next(p for p, person in draws.items() if person is kind) for kind in (True, False)
        ]
        for participant in chosen:  # one meets the person in 'together', the other the avatar
            console.fill("#participant", str(participant))
            console.click("#create-participant")
            console.wait_for_function(
                f"location.hash === '#console-p{participant:03d}' || "
                "document.getElementById('study-error').textContent !== ''"
            )
            assert console.locator("#study-error").inner_text() == ""
            console.wait_for_selector("a.join")
            sid = console.locator("#session-id").inner_text()
            pages = play_to_the_end(chromium, lab, console, sid)
            texts.append(console.locator("body").inner_text())
            rows = console.locator("#trial-list tbody tr")
            partners = [rows.nth(i).locator("td").nth(2).inner_text() for i in range(2)]
            answers = [rows.nth(i).locator("td").nth(3).inner_text() for i in range(2)]
            assert sorted(partners) == ["P1 person\nA1 avatar", "P1 person\nP2 hidden until export"]
            assert answers == ["P1: partner a computer, confidence 6"] * 2
            slots = console.locator("#slots tbody").inner_text()
            assert "person or avatar: hidden until export" in slots
            summary = console.locator("#session-summary").inner_text()
            assert re.search(r"pages: P1 (not )?connected, P2 (not )?connected · double", summary)
            for page in pages.values():
                page.context.close()
            study = (tmp_path / "out" / sid / "study.json").read_text()
            truth = "human" if draws[participant] else "avatar"
            assert f'"P2": "{truth}"' in study  # the files on disk keep the truth
        for text in texts:
            assert "bundled:fast" not in text
            assert "P2 person" not in text and "P2 avatar" not in text and "P2:" not in text
        console.context.close()

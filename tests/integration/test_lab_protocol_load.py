"""A study protocol loaded from the console through the real lab server: validated with one line
per mistake, kept under OUT/protocols, refused while a participant plays, run from then on and
resumed by a server restarted with the kept copy."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from test_lab_server import BEARER, TOKEN
from test_lab_study import PROTOCOL, create_participant

from mirror_avatar.lab.protocol import MAX_PROTOCOL_BYTES, load_protocol
from mirror_avatar.lab.protocol_store import SEED_LINE
from mirror_avatar.lab.server import LabSettings, create_lab_app
from mirror_avatar.testing import ServerThread

SHAPE = 'the body must be {"name": the file\'s name, "text": its TOML}'
UNSEEDED = PROTOCOL.replace("seed = 7\n", "")

PEOPLE_ONLY = """
title = "two people"
seed = 3

[[blocks]]
name = "main"

[[blocks.conditions]]
name = "together"
game = "joint"
players = [{ label = "P1", kind = "person" }, { label = "P2", kind = "person" }]
trials = 1
duration = 600
"""


@pytest.fixture
def out(tmp_path: Path) -> Path:
    return tmp_path / "out"


@pytest.fixture
def lab(out: Path) -> Iterator[ServerThread]:
    settings = LabSettings(out_dir=out, token=TOKEN, countdown=1)
    with ServerThread(create_lab_app(settings)) as running:
        yield running


def load(url: str, name: str, text: str) -> httpx.Response:
    return httpx.post(f"{url}/api/protocol", json={"name": name, "text": text}, headers=BEARER)


def listing(url: str) -> dict[str, Any]:
    answer = httpx.get(f"{url}/api/sessions", headers=BEARER)
    assert answer.status_code == 200
    return answer.json()


def test_a_protocol_loaded_from_the_console_is_kept_and_run(lab, out):
    assert "protocol" not in listing(lab.url)
    none = httpx.post(f"{lab.url}/api/sessions", json={"participant": 0}, headers=BEARER)
    assert none.status_code == 400
    assert none.json()["error"] == (
        "participant: no protocol loaded (load one on the console, or use --protocol)"
    )
    loaded = load(lab.url, "My study.toml", UNSEEDED)
    assert loaded.status_code == 200, loaded.text
    summary = loaded.json()["protocol"]
    copy = out / "protocols" / "My-study.toml"
    assert summary["title"] == "test study" and summary["people"] == ["P1", "P2"]
    assert summary["file"] == str(copy)
    assert listing(lab.url)["protocol"] == summary
    # the seed drawn for a protocol without one is written into the copy, the text kept as sent
    assert copy.read_text() == SEED_LINE.format(seed=summary["seed"]) + UNSEEDED
    assert load_protocol(copy).seed == summary["seed"]
    created = create_participant(lab.url, 2, BEARER)
    assert created["id"] == "My-study-p002" and set(created["links"]) == {"P1", "P2"}
    study = json.loads((out / "My-study-p002" / "study.json").read_text())
    assert study["seed"] == summary["seed"]
    assert study["protocol"] == {"source": str(copy), "title": "test study"}
    again = load(lab.url, "My study.toml", UNSEEDED)  # the same text again: the copy, its seed
    assert again.status_code == 200 and again.json()["protocol"] == summary
    other = load(lab.url, "My study.toml", PROTOCOL)
    assert other.status_code == 400
    assert other.json()["error"] == (
        f"My study.toml: {copy} holds another protocol of that name "
        "(rename the file, or load that one)"
    )
    assert copy.read_text() == SEED_LINE.format(seed=summary["seed"]) + UNSEEDED
    assert listing(lab.url)["protocol"] == summary


def test_a_server_restarted_with_the_kept_copy_resumes_the_participants_folders(lab, out):
    loaded = load(lab.url, "study.toml", UNSEEDED)
    assert loaded.status_code == 200, loaded.text
    first = create_participant(lab.url, 0, BEARER)
    httpx.post(f"{lab.url}/api/sessions/{first['id']}/abort", headers=BEARER, json={})
    copy = Path(loaded.json()["protocol"]["file"])
    settings = LabSettings(out_dir=out, token=TOKEN, countdown=1, protocol=load_protocol(copy))
    with ServerThread(create_lab_app(settings)) as restarted:
        resumed = create_participant(restarted.url, 0, BEARER)
    assert resumed["id"] == first["id"] == "study-p000"
    assert any("resumed at trial 1 of 3" in event for event in resumed["events"])


def test_bad_protocols_are_refused_with_one_line(lab, out):
    for name, text, problem in (
        ("duet.toml", PROTOCOL.replace('game = "joint"', 'game = "duet"'),
         "duet.toml: blocks[0].conditions[1].game: 'duet' is not a game "
         "(one of solo, leader_follower, joint, group)"),
        ("C:\\studies\\broken.toml", "title = \n[[blocks]]\n", None),
        ("big.toml", "#" * (MAX_PROTOCOL_BYTES + 1),
         f"big.toml: the protocol is over {MAX_PROTOCOL_BYTES} bytes (shorten it)"),
        ("###.toml", PROTOCOL,
         "###.toml: the file name has no letters or digits (rename it, e.g. study.toml)"),
    ):  # fmt: skip
        answer = load(lab.url, name, text)
        assert answer.status_code == 400, answer.text
        error = answer.json()["error"]
        assert "\n" not in error
        if problem is None:
            assert error.startswith("broken.toml: not valid TOML: ") and "line 1" in error
        else:
            assert error == problem
    for body in ({"name": "study.toml"}, {"name": 1, "text": PROTOCOL}, ["study.toml"]):
        answer = httpx.post(f"{lab.url}/api/protocol", json=body, headers=BEARER)
        assert answer.status_code == 400
        assert answer.json()["error"] == SHAPE
    unauthorised = httpx.post(f"{lab.url}/api/protocol", json={"name": "a", "text": PROTOCOL})
    assert unauthorised.status_code in (401, 403)
    assert "protocol" not in listing(lab.url)
    assert not (out / "protocols").exists()


def test_loading_is_refused_while_a_participant_plays(lab, out):
    assert load(lab.url, "people.toml", PEOPLE_ONLY).status_code == 200
    sid = create_participant(lab.url, 0, BEARER)["id"]
    assert load(lab.url, "people.toml", PEOPLE_ONLY).status_code == 200  # the same, reloaded
    start = f"{lab.url}/api/sessions/{sid}/start"
    started = httpx.post(start, json={"force": True}, headers=BEARER)
    assert started.status_code == 200, started.text
    refused = load(lab.url, "study.toml", PROTOCOL)
    assert refused.status_code == 409
    assert refused.json()["error"] == f"{sid} is playing: load a protocol when no trial runs"
    assert listing(lab.url)["protocol"]["title"] == "two people"
    httpx.post(f"{lab.url}/api/sessions/{sid}/abort", json={}, headers=BEARER)
    loaded = load(lab.url, "study.toml", PROTOCOL)
    assert loaded.status_code == 200, loaded.text
    assert loaded.json()["protocol"]["title"] == "test study"
    assert create_participant(lab.url, 0, BEARER)["id"] == "study-p000"
    assert sorted(p.name for p in (out / "protocols").iterdir()) == ["people.toml", "study.toml"]


def test_a_protocol_too_long_for_a_participant_loads_with_its_warning_shown(lab, out):
    answer = load(lab.url, "marathon.toml", PEOPLE_ONLY.replace("trials = 1", "trials = 30"))
    assert answer.status_code == 200, answer.text
    warnings = answer.json()["protocol"]["warnings"]
    assert len(warnings) == 1 and "h" in warnings[0], warnings
    assert listing(lab.url)["protocol"]["warnings"] == warnings

"""A double-blind protocol through the real lab server: the console's API never tells whether a
person or the avatar fills a person-or-avatar slot, the files on disk do, and the export too."""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from test_lab_server import BEARER, TOKEN, status
from test_lab_study import (
    PROTOCOL,
    AnsweringPage,
    create_participant,
    person_plays_together,
    play_to_the_end,
)

from mirror_avatar.lab.design.protocol import load_protocol
from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.testing import ServerThread

HIDDEN_SPEC = "bundled:fast"
"""The hidden slot's avatar spec (the other avatar's is bundled:slow): never in an answer."""

BLIND = PROTOCOL.replace("seed = 7\n", 'seed = 7\nblind = "double"\n').replace(
    '{ label = "P2", kind = "person-or-avatar", spec = "bundled:slow" }',
    f'{{ label = "P2", kind = "person-or-avatar", spec = "{HIDDEN_SPEC}" }}',
)


@pytest.fixture
def protocol_file(tmp_path: Path) -> Path:
    path = tmp_path / "blind.toml"
    path.write_text(BLIND)
    return path


@pytest.fixture
def lab(tmp_path: Path, protocol_file: Path) -> Iterator[ServerThread]:
    protocol = load_protocol(protocol_file)
    assert protocol.blind == "double"
    settings = LabSettings(out_dir=tmp_path / "out", token=TOKEN, countdown=1, protocol=protocol)
    with ServerThread(create_lab_app(settings)) as running:
        yield running


class Console:
    """Polls every answer the console reads while a run plays, keeping their texts."""

    def __init__(self, url: str, sid: str) -> None:
        self.paths = [
            f"{url}/api/sessions/{sid}",
            f"{url}/api/sessions",
            f"{url}/api/sessions/{sid}/live",
        ]
        self.texts: list[str] = []
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._poll)

    def _poll(self) -> None:
        while not self.done.wait(0.1):
            self.texts += [httpx.get(path, headers=BEARER).text for path in self.paths]

    def __enter__(self) -> Console:
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.done.set()
        self.thread.join(timeout=10)


def assert_blinded(run: dict[str, Any]) -> None:
    """Nothing in a run's status tells P2's kind."""
    for slot in run["slots"]:
        if slot["label"] == "P2":
            assert set(slot) == {"index", "label", "role", "colour", "kind"}
            assert slot["kind"] == "hidden"
    assert all(s["kind"] == "hidden" for s in run["plan"]["slots"] if s["label"] == "P2")
    for trial in run["trials"]:
        assert trial["partners"].get("P2", "hidden") == "hidden"
        assert all("P2" not in trial[key] for key in ("answers", "held", "lost", "dropped"))
        assert trial["files"] == []
    assert "P2" not in run["study"]["waiting"] and "P2" not in run["study"]["unanswered"]
    assert not any("P2" in event for event in run["events"])
    assert set(run["study"]["pages"]) == {"P1", "P2"}


@pytest.mark.long
def test_a_double_blind_run_hides_the_partner_kinds_until_export(lab, tmp_path, protocol_file):
    draws = {p: person_plays_together(protocol_file, p) for p in range(4)}
    meets_person = next(p for p, person in draws.items() if person)
    meets_avatar = next(p for p, person in draws.items() if not person)
    for participant in (meets_person, meets_avatar):
        created = create_participant(lab.url, participant, BEARER)
        sid = created["id"]
        assert_blinded(created)
        start = httpx.post(f"{lab.url}/api/sessions/{sid}/start", json={}, headers=BEARER)
        assert start.status_code == 409  # every person's page, not only those playing now
        assert start.json()["error"] == "not joined yet: P1, P2 (start anyway with force)"
        pages = [
            AnsweringPage(created["links"]["P1"]),
            AnsweringPage(created["links"]["P2"], phase=-0.4),
        ]
        with Console(lab.url, sid) as console:
            play_to_the_end(lab, sid, pages, force=True)
        # read while a trial ran (how many reads fit in the run depends on the machine's load)
        assert any('"state":"running"' in text for text in console.texts)
        for text in console.texts:
            assert HIDDEN_SPEC not in text
            answer = json.loads(text)
            for run in answer.get("sessions", [answer] if "slots" in answer else []):
                if run["id"] == sid:
                    assert_blinded(run)
        final = status(lab, sid)
        assert_blinded(final)
        assert {t["condition"] for t in final["trials"]} == {"follow", "together"}
        for name in ("study.json", "trial-01_session.json", "trial-01_answers.json"):
            served = httpx.get(f"{lab.url}/api/sessions/{sid}/files/{name}", headers=BEARER)
            assert served.status_code == 403
            assert served.json()["error"] == (
                "the protocol is double blind: a run's files are hidden until its export"
            )

        kind = "human" if draws[participant] else "avatar"  # the files on disk keep the truth
        folder = tmp_path / "out" / sid
        study = json.loads((folder / "study.json").read_text())
        together = next(c for c in study["order"] if c["condition"] == "together")
        assert together["players"]["P2"] == kind
        exported = httpx.post(
            f"{lab.url}/api/sessions/{sid}/export", json={"folder": "bids"}, headers=BEARER
        )
        assert exported.status_code == 200, exported.text
        subject = f"sub-p{participant:03d}P1"
        motions = sorted((tmp_path / "out" / "bids" / subject / "motion").glob("*_motion.json"))
        kinds = set()
        for path in motions:
            game = json.loads(path.read_text())["MirrorGame"]
            kinds |= {slot["kind"] for slot in game["lab"]["slots"] if slot["label"] == "P2"}
        assert kinds == {kind}  # the export restores it

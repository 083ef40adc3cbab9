"""A protocol served to a recruitment panel, through the real lab server: the panel identifiers
of a join link recorded in each trial's sidecar and the BIDS participants table, the completion
code and link on the welcome the end page shows, and a person screened out with the refusal
code, on their page and each time they open their link again."""

from __future__ import annotations

import asyncio
import contextlib
import csv
import json
from collections.abc import Iterator
from pathlib import Path

import httpx
import pandas as pd
import pytest
import websockets
from test_cli_lab import bids_validated
from test_lab_pilot import run_command
from test_lab_server import BEARER, TOKEN, Page, status, welcomed
from test_lab_study import create_participant, play_to_the_end

from mirror_avatar.cli import main
from mirror_avatar.lab.design.protocol import load_protocol
from mirror_avatar.lab.running.participant_page import CLOSE_CONSENT
from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.lab.running.sessions import CLOSE_REFUSED
from mirror_avatar.testing import ServerThread

COMPLETE = "https://app.prolific.com/submissions/complete?cc=C1A2B3C4"
ONLINE = f"""
[online]
panel_ids = ["PROLIFIC_PID", "STUDY_ID", "SESSION_ID"]
completion_code = "C1A2B3C4"
completion_url = "{COMPLETE}"
refusal_code = "NOFIT123"
instructions = '''Move your point with the mouse.
Follow your partner as closely as you can.'''
consent_file = "consent.txt"
"""
"""The ``[online]`` table of the tests' protocols (the consent text in a file beside them)."""


def solo_protocol(title: str, seed: int, online: str, duration: float) -> str:
    """A protocol of one solo trial of ``duration`` seconds with the ``[online]`` table given."""
    return f"""
title = "{title}"
seed = {seed}
{online}
[[blocks]]
[[blocks.conditions]]
name = "alone"
game = "solo"
players = [{{ label = "P1", kind = "person" }}]
trials = 1
duration = {duration:g}
"""


PROTOCOL = solo_protocol("online study", 3, ONLINE, 2)


INSTRUCTIONS = "Move your point with the mouse.\nFollow your partner as closely as you can."
CONSENT = "You will play a movement game for 2 minutes.\nYour movements are recorded.\n"


def agree(link: str, agreed: bool = True) -> dict[str, object]:
    """Answer the link's consent page as its participant."""
    answer = httpx.post(f"{link}/consent", json={"agree": agreed})
    assert answer.status_code == 200, answer.text
    return answer.json()


async def opened(link: str) -> tuple[list[dict[str, object]], int | None]:
    """Open a join link's WebSocket: the messages received until it closes, and its close code."""
    received = []
    socket_url = link.replace("http://", "ws://").replace("/join/", "/ws/join/")
    async with websockets.connect(socket_url) as page:
        with contextlib.suppress(websockets.ConnectionClosed):
            async for text in page:
                received.append(json.loads(text))
        return received, page.close_code


@pytest.fixture
def lab(tmp_path: Path) -> Iterator[ServerThread]:
    path = tmp_path / "online.toml"
    path.write_text(PROTOCOL)
    (tmp_path / "consent.txt").write_text(CONSENT)
    settings = LabSettings(
        out_dir=tmp_path / "out", token=TOKEN, countdown=1, protocol=load_protocol(path)
    )
    with ServerThread(create_lab_app(settings)) as running:
        yield running


def test_panel_identifiers_are_recorded_and_the_end_gives_the_completion_code(lab, tmp_path):
    created = create_participant(lab.url, 0, BEARER)
    link = created["links"]["P1"]
    unsafe = httpx.get(f"{link}?PROLIFIC_PID=../../etc/passwd")
    assert unsafe.status_code == 400 and "PROLIFIC_PID must be" in unsafe.text
    query = "PROLIFIC_PID=5f1a2b3c4d5e6f7a8b9c0d1e&STUDY_ID=s-42&other=ignored"
    assert httpx.get(f"{link}?{query}").status_code == 200
    assert httpx.get(link).status_code == 200  # opened again without them: they are kept
    assert agree(link) == {"consented": True}
    page = Page(link)
    play_to_the_end(lab, created["id"], [page])
    (welcome,) = page.of_type("welcome")[:1]
    assert welcome["completion"] == {"code": "C1A2B3C4", "url": COMPLETE}
    folder = tmp_path / "out" / created["id"]
    sidecar = json.loads((folder / "trial-01_session.json").read_text())
    panel = {"P1": {"PROLIFIC_PID": "5f1a2b3c4d5e6f7a8b9c0d1e", "STUDY_ID": "s-42"}}
    assert sidecar["metadata"]["lab"]["panel"] == panel
    (answer,) = json.loads((folder / "consent-P1.json").read_text())["answers"]
    assert answer["agree"] and sidecar["metadata"]["lab"]["consented"] == {"P1": answer["utc"]}
    bids = tmp_path / "bids"
    assert main(["lab", "export", str(folder), "--out", str(bids)]) == 0
    with (bids / "participants.tsv").open(encoding="utf-8") as table:
        (row,) = csv.DictReader(table, delimiter="\t")
    assert row["PROLIFIC_PID"] == "5f1a2b3c4d5e6f7a8b9c0d1e" and row["STUDY_ID"] == "s-42"
    assert row["completion_code"] == "C1A2B3C4"
    described = json.loads((bids / "participants.json").read_text())
    assert "recruitment panel" in described["PROLIFIC_PID"]["Description"]
    assert "end page showed" in described["completion_code"]["Description"]
    ended = json.loads((bids / "sourcedata" / created["id"] / "ended.json").read_text())
    assert ended["shown"] == ["P1"] and ended["completion"]["code"] == "C1A2B3C4"
    bids_validated(bids)
    for source in (folder, bids):  # the run folder and its export give the table the same cells
        out = tmp_path / f"table-{source.name}"
        assert main(["study", "table", str(source), "--out", str(out), "--surrogates", "0"]) == 0
        (cells,) = pd.read_csv(out / "study.csv", dtype=str).itertuples()
        assert cells.panel_PROLIFIC_PID == "5f1a2b3c4d5e6f7a8b9c0d1e"
        assert cells.panel_STUDY_ID == "s-42" and cells.completion_code == "C1A2B3C4"


def test_a_person_screened_out_sees_the_refusal_code_now_and_on_return(lab):
    created = create_participant(lab.url, 1, BEARER)
    sid, link = created["id"], created["links"]["P1"]
    agree(link)
    page = Page(link)

    async def refused_while_connected() -> None:
        playing = asyncio.create_task(page.play(30.0))
        await welcomed([page])
        answer = await asyncio.to_thread(
            httpx.post,
            f"{lab.url}/api/sessions/{sid}/refuse",
            json={"person": "P1", "reason": "Your connection is too slow for this study."},
            headers=BEARER,
        )
        assert answer.status_code == 200, answer.text
        await playing

    asyncio.run(refused_while_connected())
    (refusal,) = page.of_type("refused")
    assert refusal == {
        "type": "refused",
        "message": "Your connection is too slow for this study.",
        "code": "NOFIT123",
        "url": None,
    }
    assert page.closed is not None and page.closed.rcvd.code == CLOSE_REFUSED
    assert any("P1 screened out" in event for event in status(lab, sid)["events"])

    assert asyncio.run(opened(link)) == ([refusal], CLOSE_REFUSED)
    unknown = httpx.post(
        f"{lab.url}/api/sessions/{sid}/refuse", json={"person": "P9"}, headers=BEARER
    )
    assert unknown.status_code == 400 and "person: one of P1" in unknown.text


def test_the_pages_before_the_game_and_a_participant_who_does_not_agree(lab, tmp_path):
    created = create_participant(lab.url, 2, BEARER)
    sid, link = created["id"], created["links"]["P1"]
    intro = httpx.get(f"{link}/intro").json()
    assert intro == {
        "instructions": INSTRUCTIONS,
        "consent": CONSENT.strip(),
        "consented": False,
        "refused": None,
    }
    assert asyncio.run(opened(link)) == ([], CLOSE_CONSENT)  # no game before the answer
    bad = httpx.post(f"{link}/consent", json={"agree": "yes"})
    assert bad.status_code == 400 and "agree" in bad.text
    refusal = {
        "type": "refused",
        "message": "You chose not to take part. Thank you for your time.",
        "code": "NOFIT123",
        "url": None,
    }
    assert agree(link, False) == {"refused": refusal}
    assert agree(link, True) == {"refused": refusal}  # the first answer counts
    assert httpx.get(f"{link}/intro").json()["refused"] == refusal
    assert asyncio.run(opened(link)) == ([refusal], CLOSE_REFUSED)
    folder = tmp_path / "out" / sid
    (answer,) = json.loads((folder / "consent-P1.json").read_text())["answers"]
    assert answer["agree"] is False
    events = status(lab, sid)["events"]
    assert any("P1 did not agree to take part" in event for event in events)
    assert status(lab, sid)["state"] == "waiting" and not (folder / "trial-01_session.csv").exists()


@pytest.mark.long
def test_a_pilot_s_stand_ins_agree_to_the_consent_page_as_participants_do(tmp_path):
    protocol = tmp_path / "online.toml"
    protocol.write_text(PROTOCOL)
    (tmp_path / "consent.txt").write_text(CONSENT)
    out = tmp_path / "out"
    result = run_command(
        "lab", "pilot", "--protocol", str(protocol), "--participants", "1",
        "--stand-in", "P1=bundled:slow", "--out", str(out),
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert "participant 0: finished" in result.stdout
    (answer,) = json.loads((out / "online-p000" / "consent-P1.json").read_text())["answers"]
    assert answer["agree"] is True

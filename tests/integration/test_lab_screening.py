"""Screening declared in the protocol, through the real lab server: a page whose round trips at
entry are above the bound refused with both numbers, the refusal in its file and the log; a tab
hidden during a trial recorded in the sidecar and the person told on return, or refused; no run
started until every connected page's entry is judged."""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import json
import math
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pandas as pd
import pytest
import websockets
from test_lab_online import opened, solo_protocol
from test_lab_server import BEARER, TOKEN, Page, command, socket_url, status
from test_lab_study import create_participant, play_to_the_end

from mirror_avatar.cli import main
from mirror_avatar.lab.design.protocol import load_protocol
from mirror_avatar.lab.running.screening import BACK_NOTICE, ENTRY_EXCHANGES, HIDDEN_REFUSAL
from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.lab.running.sessions import CLOSE_REFUSED
from mirror_avatar.testing import ServerThread
from waiting import wait_for


def protocol(hidden_tab: str) -> str:
    """A one-trial protocol screening at 150 ms and treating a hidden tab as ``hidden_tab``."""
    online = f"""[online]
refusal_code = "NOFIT123"
screen_round_trip_p95_ms = 150
screen_hidden_tab = "{hidden_tab}"
"""
    return solo_protocol("screened study", 5, online, 3)


def serve(tmp_path: Path, hidden_tab: str) -> ServerThread:
    return serve_protocol(tmp_path / f"screened-{hidden_tab}.toml", protocol(hidden_tab))


def serve_protocol(path: Path, text: str) -> ServerThread:
    """A lab server of the protocol ``text``, written to ``path``, its runs in ``out`` beside."""
    path.write_text(text)
    settings = LabSettings(
        out_dir=path.parent / "out", token=TOKEN, countdown=1, protocol=load_protocol(path)
    )
    return ServerThread(create_lab_app(settings))


@pytest.fixture
def lab(tmp_path: Path) -> Iterator[ServerThread]:
    with serve(tmp_path, "record") as running:
        yield running


async def exchanged(link: str, delay_ms: float, stay: bool) -> list[dict[str, Any]]:
    """Make the page's `ENTRY_EXCHANGES` clock exchanges, 20 ms apart as ``clock.js`` does, as
    a page whose answers arrive ``delay_ms`` after its requests leave (its own clock says so).

    Then read until the socket closes (``stay``), or leave half a second after the last report.
    """
    received: list[dict[str, Any]] = []
    async with asyncio.timeout(60), websockets.connect(socket_url(link)) as page:

        async def request() -> None:
            for n in range(1, ENTRY_EXCHANGES + 1):
                await page.send(json.dumps({"type": "clock", "id": n, "t0": 1000.0 * n}))
                await asyncio.sleep(0.02)

        requests = asyncio.create_task(request())
        answered = 0
        with contextlib.suppress(websockets.ConnectionClosed):
            async for text in page:
                message = json.loads(text)
                received.append(message)
                if message["type"] == "clock":
                    t3 = message["t0"] + delay_ms
                    await page.send(json.dumps({"type": "clocked", "id": message["id"], "t3": t3}))
                    answered += 1
                if answered == ENTRY_EXCHANGES and not stay:
                    await asyncio.sleep(0.5)
                    break
        await requests
    return received


def test_a_page_at_300_ms_is_refused_at_entry_with_both_numbers(lab, tmp_path):
    created = create_participant(lab.url, 0, BEARER)
    sid, link = created["id"], created["links"]["P1"]
    received = asyncio.run(exchanged(link, 300.0, stay=True))
    (refused,) = [m for m in received if m["type"] == "refused"]
    # the round trip the server measures is the page's 300 ms less the server's own time to
    # answer: a few ms idle, tens of ms on a loaded machine
    assert refused["message"].startswith("Your connection's round trip (p95 ")
    p95 = int(refused["message"].split("p95 ")[1].split(" ms")[0])
    assert 250 <= p95 <= 300
    assert refused["message"].endswith(" ms) is above the study's 150 ms.")
    assert refused["code"] == "NOFIT123"
    record = json.loads((tmp_path / "out" / sid / "refusal-P1.json").read_text())
    assert record["reason"] == refused["message"]
    assert record["bounds"]["round_trip_p95_ms"] == 150
    assert len(record["rtt_ms"]) == 100 and round(record["rtt_p95_ms"]) == p95
    assert any("P1 screened out: Your connection's" in e for e in status(lab, sid)["events"])
    assert asyncio.run(opened(link)) == ([refused], CLOSE_REFUSED)
    admitted = create_participant(lab.url, 1, BEARER)
    play_to_the_end(lab, admitted["id"], [ClockedPage(admitted["links"]["P1"])], judged=True)
    table = tmp_path / "table"
    assert main(["study", "table", str(tmp_path / "out"), "--out", str(table)]) == 0
    rows = pd.read_csv(table / "study.csv").set_index("participant")
    assert rows.loc["p000", "refusals"] == 1 and rows.loc["p000", "refusal"] == refused["message"]
    assert pd.isna(rows.loc["p000", "trial"]) and rows.loc["p001", "refusals"] == 0
    assert pd.isna(rows.loc["p001", "refusal"]) and rows.loc["p001", "trial"] == 1
    assert main(["study", "report", str(table), "--out", str(tmp_path / "report")]) == 0
    notes = json.loads((tmp_path / "report" / "results.json").read_text())["notes"]
    assert "1 rows of persons screened out before their first trial left out" in notes


def test_a_page_within_the_bound_is_admitted_and_not_judged_again(lab):
    created = create_participant(lab.url, 1, BEARER)
    sid, link = created["id"], created["links"]["P1"]

    for _ in range(2):
        received = asyncio.run(exchanged(link, 40.0, stay=False))
        assert not [m for m in received if m["type"] == "refused"]
    admitted = [e for e in status(lab, sid)["events"] if "admitted" in e]
    assert len(admitted) == 1 and "P1 admitted: round trip p95 " in admitted[0]


def test_a_run_does_not_start_until_every_page_s_entry_is_judged(lab):
    created = create_participant(lab.url, 3, BEARER)
    sid, link = created["id"], created["links"]["P1"]

    async def scenario() -> tuple[httpx.Response, httpx.Response]:
        async with websockets.connect(socket_url(link)) as page:
            await page.recv()  # welcome: connected, no clock exchanged yet
            early = await asyncio.to_thread(command, lab, sid, "start")
            await judged_entry(page)
            await asyncio.to_thread(
                wait_for, lambda: status(lab, sid)["slots"][0]["entry_rtt_p95_ms"] is not None,
                30.0, "the entry judged",
            )  # fmt: skip
            return early, await asyncio.to_thread(command, lab, sid, "start")

    early, started = asyncio.run(scenario())
    assert early.status_code == 409
    assert early.json()["error"] == (
        f"still being screened: P1 (their page's first {ENTRY_EXCHANGES} round trips, about 2 s "
        "after joining; start anyway with force)"
    )
    assert started.status_code == 200, started.text


async def judged_entry(page: Any) -> None:
    """Make a page's `ENTRY_EXCHANGES` clock exchanges on its socket ``page``, one at a time."""
    for n in range(1, ENTRY_EXCHANGES + 1):
        await page.send(clock_request(n))
        while (message := json.loads(await page.recv()))["type"] != "clock":
            pass
        await page.send(clock_report(message))


def clock_request(n: int) -> str:
    """A page's request ``n`` for the server's time, on its own clock (ms) as ``clock.js``'s."""
    return json.dumps({"type": "clock", "id": n, "t0": time.time() * 1000.0})


def clock_report(answer: dict[str, Any]) -> str:
    """A page's report of when the server's ``answer`` arrived, on its own clock (ms)."""
    return json.dumps({"type": "clocked", "id": answer["id"], "t3": time.time() * 1000.0})


class ClockedPage(Page):
    """A page that makes its entry's clock exchanges as it connects, 20 ms apart, then plays."""

    async def _send(self, socket: Any) -> None:
        for n in range(1, ENTRY_EXCHANGES + 1):
            await socket.send(clock_request(n))
            await asyncio.sleep(0.02)
        await super()._send(socket)

    async def on_message(self, socket: Any, message: dict[str, Any]) -> None:
        await super().on_message(socket, message)
        if message["type"] == "clock":
            await socket.send(clock_report(message))


SIZED = """[online]
refusal_code = "NOFIT123"
screen_frame_rate_hz = 30
screen_window_width_px = 800
"""


async def entered(link: str, frames_hz: float, width: int) -> list[dict[str, Any]]:
    """Join as a page whose window is ``width`` x 600 px and which draws ``frames_hz`` frames a
    second (one pointer batch each), making its entry's clock exchanges 20 ms apart; read until
    the socket closes or half a second after the last exchange's report."""
    received: list[dict[str, Any]] = []
    async with asyncio.timeout(60), websockets.connect(socket_url(link)) as page:
        await page.send(json.dumps({"type": "window", "width": width, "height": 600}))

        async def frames() -> None:
            for seq in itertools.count():
                sent = time.time() * 1000.0
                batch = {"type": "pointer", "seq": seq, "sent": sent, "ago": [0.0], "x": [0.0]}
                await page.send(json.dumps(batch))
                await asyncio.sleep(1.0 / frames_hz)

        async def requests() -> None:
            for n in range(1, ENTRY_EXCHANGES + 1):
                await page.send(clock_request(n))
                await asyncio.sleep(0.02)

        tasks = [asyncio.create_task(frames()), asyncio.create_task(requests())]
        answered, deadline = 0, math.inf
        with contextlib.suppress(websockets.ConnectionClosed, TimeoutError):
            while True:
                async with asyncio.timeout(max(0.0, deadline - time.monotonic())):
                    message = json.loads(await page.recv())
                received.append(message)
                if message["type"] == "clock":
                    await page.send(clock_report(message))
                    answered += 1
                    if answered == ENTRY_EXCHANGES:
                        deadline = time.monotonic() + 0.5
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
    return received


def test_a_page_drawing_too_few_frames_or_too_narrow_is_refused_at_entry(tmp_path):
    with serve_protocol(tmp_path / "sized.toml", solo_protocol("sized study", 5, SIZED, 3)) as lab:
        pages = {n: create_participant(lab.url, n, BEARER) for n in range(3)}
        slow = asyncio.run(entered(pages[0]["links"]["P1"], 10.0, 1280))
        narrow = asyncio.run(entered(pages[1]["links"]["P1"], 60.0, 640))
        fine = asyncio.run(entered(pages[2]["links"]["P1"], 60.0, 1280))
        events = status(lab, pages[2]["id"])["events"]
    (refused,) = [m for m in slow if m["type"] == "refused"]
    rate = float(refused["message"].split("drew ")[1].split(" frames")[0])
    assert 5.0 <= rate <= 11.0, refused  # 10 batches a second, fewer when the machine is busy
    assert refused["message"].endswith(" frames a second, fewer than the study's 30.")
    (refused,) = [m for m in narrow if m["type"] == "refused"]
    assert refused["message"] == "Your window is 640 px wide, narrower than the study's 800 px."
    record = json.loads((tmp_path / "out" / pages[1]["id"] / "refusal-P1.json").read_text())
    assert record["window_px"] == [640, 600] and record["bounds"]["window_width_px"] == 800
    assert not [m for m in fine if m["type"] == "refused"]
    (admitted,) = [e for e in events if "admitted" in e]
    assert "frames/s, window 1280x600 px" in admitted


class HidingPage(Page):
    """A page whose tab is hidden for ``hidden_s`` seconds once the trial starts.

    It exchanges no clocks, so its entry is never judged (its run is started by force) and its
    events are timed on their receipt.
    """

    hidden_s = 0.6

    async def on_message(self, socket: Any, message: dict[str, Any]) -> None:
        await super().on_message(socket, message)
        if message["type"] == "go":
            asyncio.get_running_loop().create_task(self._hide(socket))

    async def _hide(self, socket: Any) -> None:
        await socket.send(focus("hidden"))
        await asyncio.sleep(self.hidden_s)
        await socket.send(focus("visible"))


def focus(event: str) -> str:
    """A page's report of its tab hidden or shown, on its own clock (ms)."""
    return json.dumps({"type": "focus", "event": event, "t": time.time() * 1000.0})


class ClockedHidingPage(ClockedPage, HidingPage):
    """A `HidingPage` that makes its entry's clock exchanges, so its entry is judged and its
    events timed by its own clock."""


def test_a_tab_hidden_during_a_trial_is_recorded_and_the_person_told(lab, tmp_path):
    created = create_participant(lab.url, 2, BEARER)
    sid, link = created["id"], created["links"]["P1"]
    page = ClockedHidingPage(link)
    play_to_the_end(lab, sid, [page], judged=True)
    assert page.of_type("notice") == [{"type": "notice", "message": BACK_NOTICE}]
    sidecar = json.loads((tmp_path / "out" / sid / "trial-01_session.json").read_text())
    (hidden,) = sidecar["metadata"]["pages"]["P1"]["interruptions"]
    # timed by the page's clock, mapped onto the server's by its exchanges
    assert hidden["kind"] == "hidden" and 0.5 <= hidden["end_s"] - hidden["start_s"] <= 3.0
    events = status(lab, sid)["events"]
    assert any("P1: hidden during trial 1" in e for e in events)
    assert any("P1: back after" in e for e in events)


def test_a_tab_hidden_during_a_trial_refuses_the_person_when_the_protocol_says_so(tmp_path):
    with serve(tmp_path, "refuse") as lab:
        created = create_participant(lab.url, 0, BEARER)
        sid, link = created["id"], created["links"]["P1"]
        page = HidingPage(link)
        play_to_the_end(lab, sid, [page], force=True)
    (refused,) = page.of_type("refused")
    assert refused["message"] == HIDDEN_REFUSAL and refused["code"] == "NOFIT123"
    assert page.closed is not None and page.closed.rcvd.code == CLOSE_REFUSED
    record = json.loads((tmp_path / "out" / sid / "refusal-P1.json").read_text())
    assert record["reason"] == HIDDEN_REFUSAL and record["trial"] == 1

"""Screening during play, through the real lab server: a page whose frame rate drops mid-trial
recorded in the sidecar with its reason, logged, told in one line and counted in the study
table, or refused when the protocol says so; a page that keeps its rate not flagged."""

from __future__ import annotations

import asyncio
import itertools
import json
import math
import time
from pathlib import Path
from typing import Any

import pandas as pd
import pytest
from test_lab_online import solo_protocol
from test_lab_screening import ClockedPage, clock_request, serve_protocol
from test_lab_server import BEARER, status
from test_lab_study import create_participant, play_to_the_end

from mirror_avatar.cli import main
from mirror_avatar.lab.running.screening import ENTRY_EXCHANGES
from mirror_avatar.lab.running.sessions import CLOSE_REFUSED
from mirror_avatar.testing import ServerThread

pytestmark = pytest.mark.realtime

BOUND_HZ = 20
"""The protocol's fewest frames a second (a page draws 60, or 4 once slowed)."""


def protocol(during_play: str) -> str:
    """A protocol of two 5 s trials holding its frame-rate bound during play as ``during_play``."""
    online = f"""[online]
refusal_code = "NOFIT123"
screen_frame_rate_hz = {BOUND_HZ}
screen_during_play = "{during_play}"
"""
    return solo_protocol("screened in play", 5, online, 5).replace("trials = 1", "trials = 2")


def serve(tmp_path: Path, during_play: str) -> ServerThread:
    return serve_protocol(tmp_path / f"in-play-{during_play}.toml", protocol(during_play))


class FramedPage(ClockedPage):
    """A page drawing 60 frames a second, one pointer batch each, as ``clock.js`` sends them;
    with ``slowed_hz`` it draws that many a second from one second into the first trial on."""

    def __init__(self, link: str, slowed_hz: float | None = None) -> None:
        super().__init__(link)
        self.slowed_hz = slowed_hz
        self.go_at = math.inf

    async def on_message(self, socket: Any, message: dict[str, Any]) -> None:
        await super().on_message(socket, message)
        if message["type"] == "go":
            self.go_at = min(self.go_at, time.monotonic())

    async def _send(self, socket: Any) -> None:
        await socket.send(json.dumps({"type": "window", "width": 1280, "height": 720}))
        await asyncio.gather(self._exchange(socket), self._frames(socket))

    async def _exchange(self, socket: Any) -> None:
        for n in range(1, ENTRY_EXCHANGES + 1):
            await socket.send(clock_request(n))
            await asyncio.sleep(0.02)

    async def _frames(self, socket: Any) -> None:
        seq, began = 0, time.monotonic()
        while True:
            x = self.x(time.monotonic() - began)
            batch = {"type": "pointer", "seq": seq, "sent": time.time() * 1000.0, "ago": [0.0],
                     "x": [x]}  # fmt: skip
            await socket.send(json.dumps(batch))
            seq += 1
            slowed = time.monotonic() > self.go_at + 1.0
            rate = self.slowed_hz if slowed and self.slowed_hz is not None else 60.0
            await asyncio.sleep(1.0 / rate)


def sidecar_page(run: Path, n: int) -> dict[str, Any]:
    """The record of P1's page in trial ``n``'s sidecar in the run folder ``run``."""
    sidecar = json.loads((run / f"trial-{n:02d}_session.json").read_text())
    return dict(sidecar["metadata"]["pages"]["P1"])


def test_a_page_whose_frame_rate_drops_mid_trial_is_recorded_and_told(tmp_path):
    with serve(tmp_path, "record") as lab:
        runs = [create_participant(lab.url, n, BEARER) for n in range(2)]
        steady = FramedPage(runs[0]["links"]["P1"])
        play_to_the_end(lab, runs[0]["id"], [steady], judged=True)
        slowed = FramedPage(runs[1]["links"]["P1"], slowed_hz=4.0)
        play_to_the_end(lab, runs[1]["id"], [slowed], judged=True)
        events = status(lab, runs[1]["id"])["events"]
        assert not [e for e in status(lab, runs[0]["id"])["events"] if "bounds" in e]
    assert steady.of_type("notice") == []
    # told in the trial it slowed in, and again in the next, still slow (the page clears the
    # line as a trial starts)
    told = [notice["message"] for notice in slowed.of_type("notice")]
    assert len(told) == 2, told
    for n, said in enumerate(told, 1):
        assert said.startswith("Your browser drew ")
        assert said.endswith(f" frames a second, fewer than the study's {BOUND_HZ}.")
        # flagged once the last 2 s hold fewer than 40 frames: under 20 a second
        assert float(said.split("drew ")[1].split(" frames")[0]) < BOUND_HZ
        assert any(f"P1: below bounds during trial {n}: {said}" in e for e in events)
    out = tmp_path / "out"
    pages = [sidecar_page(out / runs[1]["id"], n) for n in (1, 2)]
    # one interruption, from the first trial on: still open at the end of each
    for page in pages:
        (below,) = page["interruptions"]
        assert below["kind"] == "below_bounds" and below["reason"] == told[0] and below["open"]
    assert "interruptions" not in sidecar_page(out / runs[0]["id"], 1)
    table = tmp_path / "table"
    assert main(["study", "table", str(out), "--out", str(table)]) == 0
    rows = pd.read_csv(table / "study.csv")
    counted = rows.groupby("participant")["page_below_bounds"].sum()
    assert counted.to_dict() == {"p000": 0, "p001": 2}
    first, second = rows[rows["participant"] == "p001"].sort_values("trial")["page_below_bounds_s"]
    # from the drop's judgement to the end of trial 1, then the whole of trial 2 (5 s)
    assert 0.0 < first < second and second == pytest.approx(5.0, abs=0.5)


def test_a_page_whose_frame_rate_drops_mid_trial_is_refused_when_the_protocol_says_so(tmp_path):
    with serve(tmp_path, "refuse") as lab:
        created = create_participant(lab.url, 0, BEARER)
        sid = created["id"]
        slowed = FramedPage(created["links"]["P1"], slowed_hz=4.0)
        play_to_the_end(lab, sid, [slowed], judged=True)
    (refused,) = slowed.of_type("refused")
    assert refused["message"].endswith(f" frames a second, fewer than the study's {BOUND_HZ}.")
    assert refused["code"] == "NOFIT123"
    assert slowed.closed is not None and slowed.closed.rcvd.code == CLOSE_REFUSED
    record = json.loads((tmp_path / "out" / sid / "refusal-P1.json").read_text())
    assert record["reason"] == refused["message"] and record["trial"] == 1
    assert record["frame_rate_hz"] < BOUND_HZ and record["bounds"]["frame_rate_hz"] == BOUND_HZ


LAG_MS = 300.0
"""How late a lagging page's clock reports arrive (ms) from one second into the first trial on."""

ROUND_TRIP_BOUND_MS = 150


class LaggingPage(FramedPage):
    """A page drawing 60 frames a second and exchanging clocks as ``clock.js`` does (its entry's
    exchanges 20 ms apart, then one every 100 ms); with ``lagging`` its reports say the server's
    answers arrived `LAG_MS` later from one second into the first trial on."""

    def __init__(self, link: str, lagging: bool) -> None:
        super().__init__(link)
        self.lagging = lagging

    async def on_message(self, socket: Any, message: dict[str, Any]) -> None:
        late = self.lagging and time.monotonic() > self.go_at + 1.0
        if message["type"] == "clock" and late:
            report = {"type": "clocked", "id": message["id"], "t3": time.time() * 1000.0 + LAG_MS}
            await socket.send(json.dumps(report))
            return
        await super().on_message(socket, message)

    async def _exchange(self, socket: Any) -> None:
        for n in itertools.count(1):
            await socket.send(clock_request(n))
            await asyncio.sleep(0.02 if n < ENTRY_EXCHANGES else 0.1)


def test_a_page_whose_round_trip_grows_mid_trial_is_recorded_and_told(tmp_path):
    online = f"""[online]
screen_round_trip_p95_ms = {ROUND_TRIP_BOUND_MS}
screen_during_play = "record"
"""
    text = solo_protocol("round trip in play", 5, online, 5).replace("trials = 1", "trials = 2")
    with serve_protocol(tmp_path / "round-trip.toml", text) as lab:
        runs = [create_participant(lab.url, n, BEARER) for n in range(2)]
        steady = LaggingPage(runs[0]["links"]["P1"], lagging=False)
        play_to_the_end(lab, runs[0]["id"], [steady], judged=True)
        lagging = LaggingPage(runs[1]["links"]["P1"], lagging=True)
        play_to_the_end(lab, runs[1]["id"], [lagging], judged=True)
        events = status(lab, runs[1]["id"])["events"]
    assert steady.of_type("notice") == []
    told = [notice["message"] for notice in lagging.of_type("notice")]
    assert len(told) == 2, told
    for n, said in enumerate(told, 1):
        assert said.startswith("Your connection's round trip (p95 ")
        assert said.endswith(f" ms) is above the study's {ROUND_TRIP_BOUND_MS} ms.")
        assert ROUND_TRIP_BOUND_MS < int(said.split("p95 ")[1].split(" ms")[0]) <= 2 * LAG_MS
        assert any(f"P1: below bounds during trial {n}: {said}" in e for e in events)
    out = tmp_path / "out"
    (below,) = sidecar_page(out / runs[1]["id"], 1)["interruptions"]
    assert below["kind"] == "below_bounds" and below["reason"] == told[0]
    assert "interruptions" not in sidecar_page(out / runs[0]["id"], 1)
    table = tmp_path / "table"
    assert main(["study", "table", str(out), "--out", str(table)]) == 0
    counted = pd.read_csv(table / "study.csv").groupby("participant")["page_below_bounds"].sum()
    assert counted.to_dict() == {"p000": 0, "p001": 2}

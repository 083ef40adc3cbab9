"""Recordings that say what really happened, through the real servers: each sample's true time
and lateness, a trial ended when its clock cannot be kept, a too slow avatar refused when the
session is created, and inputs that stop delivering (a frozen page, a page that answers late)."""

from __future__ import annotations

import asyncio
import csv
import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
from test_lab_server import BEARER, DYAD, TOKEN, Page, command, create, status, stopped
from websockets.sync.client import connect

from mirror_avatar.deep.player import MAX_LAYERS, MAX_UNITS, DeepCyberPlayer
from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.lab.design.plan import MAX_PLAYERS
from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.live.server import LiveSettings, create_app
from mirror_avatar.players import Player
from mirror_avatar.realtime.clock import time_players
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.specs import load_player
from mirror_avatar.testing import ServerThread
from waiting import wait_for


def read_rows(path: Path) -> list[dict[str, str]]:
    with path.open() as file:
        return list(csv.DictReader(file))


class Laggard(Player):
    """An avatar three control periods slow per step (it sleeps, as a slow model would)."""

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        return 0.0, 0.0

    def step(self, observation: Any) -> tuple[float, float]:
        time.sleep(3 * self.period)
        return 0.0, 0.0


def play_live(url: str, mode: str, duration: float) -> dict[str, Any]:
    """A scripted browser: start a trial, send the pointer at 60 Hz until the trial is done."""
    with connect(url.replace("http://", "ws://") + "/ws") as ws:
        assert json.loads(ws.recv(10))["type"] == "ready"
        start = {"type": "start", "mode": mode, "participant": "P01", "duration": duration}
        ws.send(json.dumps(start))
        seq = 0
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline:
            seq += 1
            ws.send(json.dumps({"type": "position", "seq": seq, "x": 0.1}))
            try:
                while True:
                    message = json.loads(ws.recv(1 / 60))
                    if message["type"] == "done":
                        return dict(message["summary"])
            except TimeoutError:
                pass
    raise AssertionError("the trial never ended")


def test_a_live_trial_that_cannot_keep_its_clock_is_ended_with_its_true_lateness(tmp_path):
    settings = LiveSettings(out_dir=tmp_path, avatar_spec="laggard", countdown=0)
    with ServerThread(create_app(settings, lambda mode: Laggard())) as server:
        summary = play_live(server.url, "avatar_follows", 30.0)
    assert not summary["complete"]
    assert summary["end_reason"].startswith("the clock could not be kept: sample ")
    (inputs,) = (tmp_path / "P01").glob("*_inputs.csv")
    rows = read_rows(inputs)
    assert len(rows) == summary["n_samples"]
    clock = np.array([float(row["clock_s"]) for row in rows])
    late = np.array([float(row["late_ms"]) for row in rows])
    step = np.array([float(row["step_ms"]) for row in rows])
    times = np.array([float(row["time"]) for row in rows])
    assert np.all(np.diff(clock) >= 3 * settings.period)  # taken one slow step apart, recorded
    assert np.all(step[:-1] >= 3 * settings.period * 1000.0)
    assert late[-1] > 1000.0 and late[-1] > late[len(late) // 2] > late[1]
    # the engine's clock says less time passed than the wall clock, by the ticks' growing
    # lateness (each sample stamped in the clock's thread, a hand-off after its tick was called)
    behind = (clock[-1] - clock[0]) - (times[-1] - times[0])
    assert behind == pytest.approx((late[-1] - late[0]) / 1000.0, abs=0.1)
    recorded = summary["tick_lateness_ms"]
    assert recorded["n"] == len(rows) and recorded["max"] == pytest.approx(late.max(), abs=1e-3)
    sidecar_path = inputs.with_name(inputs.name.replace("_inputs.csv", "_session.json"))
    sidecar = json.loads(sidecar_path.read_text())
    assert sidecar["metadata"]["complete"] is False
    assert sidecar["metadata"]["tick_lateness_ms"]["over_period"] > 0


def slow_network(path: Path) -> str:
    """A legal but slow DQN avatar file: the largest network a file may declare."""
    player = DeepCyberPlayer(hidden=(MAX_UNITS,) * MAX_LAYERS)
    player.initialise_policy(0)
    return str(player.save(path))


@pytest.mark.long
def test_a_lab_session_whose_avatars_cannot_step_in_time_is_refused_at_creation(tmp_path):
    """As many of the largest legal DQN avatars as need, on this machine, three times the control
    period per step (measured here first): the plan is refused when the session is created."""
    spec = slow_network(tmp_path / "slow.npz")
    (one,) = time_players([load_player(spec, "group")], steps=5)
    n = min(MAX_PLAYERS - 1, max(2, math.ceil(3 * CONTROL_PERIOD / one)))
    avatars = [{"label": f"A{k}", "kind": "avatar", "spec": spec} for k in range(n)]
    plan = {
        "condition": "group",
        "duration": 10.0,
        "players": [{"label": "P1", "kind": "human"}, *avatars],
    }
    settings = LabSettings(out_dir=tmp_path / "out", token=TOKEN)
    with ServerThread(create_lab_app(settings)) as lab:
        refused = httpx.post(f"{lab.url}/api/sessions", json=plan, headers=BEARER, timeout=300)
        assert refused.status_code == 400, refused.text
        error = refused.json()["error"]
        assert error.startswith("players[") and "ms per step on this machine" in error
        assert "over the control period of 30 ms" in error
        assert httpx.get(f"{lab.url}/api/sessions", headers=BEARER).json() == {"sessions": []}


@pytest.fixture
def lab(tmp_path: Path) -> Any:
    settings = LabSettings(out_dir=tmp_path, token=TOKEN, countdown=1)
    with ServerThread(create_lab_app(settings)) as running:
        yield running


FROZEN_PAGE = """
import json, sys, time
from websockets.sync.client import connect
with connect(sys.argv[1]) as ws:
    seq = 0
    while True:
        ws.send(json.dumps({"type": "position", "seq": seq, "x": 0.2}))
        seq += 1
        try:
            while True:
                message = json.loads(ws.recv(1 / 60))
                if message["type"] == "ping":
                    ws.send(json.dumps({"type": "pong", "id": message["id"]}))
        except TimeoutError:
            pass
"""


def test_a_frozen_page_is_seen_lost_recorded_and_stops_the_trial(lab, tmp_path):
    """A participant's browser process is stopped (SIGSTOP): its connection stays open, but its
    input stops; the trial records it and, as the plan says, stops."""
    created = create(lab, DYAD | {"duration": 30.0, "on_drop": "stop"})
    sid = created["id"]
    steady = Page(created["links"]["P1"])
    url = created["links"]["P2"].replace("http://", "ws://").replace("/join/", "/ws/join/")
    frozen = subprocess.Popen([sys.executable, "-c", FROZEN_PAGE, url])
    try:

        async def scenario() -> None:
            playing = asyncio.create_task(steady.play(40.0))
            await asyncio.to_thread(
                wait_for, lambda: all(s["connected"] for s in status(lab, sid)["slots"])
            )
            await asyncio.to_thread(lambda: command(lab, sid, "start").raise_for_status())
            await asyncio.to_thread(
                wait_for, lambda: steady.of_type("frame") and steady.of_type("frame")[-1]["k"] > 60
            )
            os.kill(frozen.pid, signal.SIGSTOP)
            await asyncio.to_thread(wait_for, lambda: steady.of_type("end"), 30.0)
            await stopped([playing])

        asyncio.run(scenario())
        now = status(lab, sid)
    finally:
        os.kill(frozen.pid, signal.SIGKILL)
        frozen.wait(10)
    (end,) = steady.of_type("end")
    assert end["reason"] == "P2's input was lost"
    trial = now["trials"][0]
    assert not trial["complete"] and trial["lost"]["P2"] > 0
    assert any("P2: input lost at sample" in event for event in now["events"])
    record = json.loads((tmp_path / sid / "trial-01_session.json").read_text())["metadata"]
    (lost,) = [e for e in record["input_events"] if e["event"] == "lost"]
    assert lost["label"] == "P2" and lost["seq"] >= 0
    rows = read_rows(tmp_path / sid / "trial-01_inputs.csv")
    alive = [int(row["alive_P2"]) for row in rows]
    assert alive[lost["sample"]] == 0 and all(alive[: lost["sample"]])
    assert all(int(row["alive_P1"]) for row in rows)
    ages = [float(row["age_ms_P2"]) for row in rows[lost["sample"] :]]
    assert ages[0] > 1000.0 and all(np.diff(ages) > 0)
    session = load_session(tmp_path / sid / "trial-01_session.csv")
    assert session.n_samples == len(rows) == record["tick_lateness_ms"]["n"]


class LatePage(Page):
    """A page that answers each ping 1.5 s late (three ping intervals)."""

    async def play(self, seconds: float) -> None:
        import websockets

        async with websockets.connect(self.url) as socket:
            answers: list[asyncio.Task[None]] = []

            async def answer(ping_id: int) -> None:
                await asyncio.sleep(1.5)
                await socket.send(json.dumps({"type": "pong", "id": ping_id}))

            try:
                async with asyncio.timeout(seconds):
                    async for text in socket:
                        message = json.loads(text)
                        self.messages.append(message)
                        if message["type"] == "ping":
                            answers.append(asyncio.create_task(answer(message["id"])))
            except TimeoutError:
                pass
            finally:
                await stopped(answers)


def test_every_ping_is_measured_so_a_late_page_shows_its_true_round_trip(lab):
    created = create(lab, DYAD)
    sid = created["id"]
    page = LatePage(created["links"]["P1"])

    async def scenario() -> dict[str, Any]:
        playing = asyncio.create_task(page.play(6.0))
        await asyncio.sleep(5.0)
        slot = await asyncio.to_thread(lambda: status(lab, sid)["slots"][0])
        await playing
        return slot

    slot = asyncio.run(scenario())
    assert slot["rtt_median_ms"] >= 1500.0 and slot["rtt_p95_ms"] >= 1500.0
    assert slot["rtt_waiting_ms"] >= 1500.0 * 0.5

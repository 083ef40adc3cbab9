"""A good participant beside a slow avatar in another session: measure whether its clock slips.

Live (``play``): a good participant plays ``bundled:slow`` in avatar-follows mode, sending
positions at 60 Hz; its input-to-frame time (a position to the server's answer carrying the
avatar) and the longest gap between answers are measured before, during and after another
connection plays an avatar three control periods slow per step (a sleeping Python player, as a
too large model would be), which the server ends when its clock falls a second behind.

Lab: a dyad of two pages plays a trial while the researcher creates a session whose plan holds
five of the largest legal DQN avatars (8 hidden layers of 1024 units); the server times them
and refuses the plan. The good session's frame gaps are measured before, during and after.
"""

from __future__ import annotations

import asyncio
import json
import math
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import websockets

from mirror_avatar.deep.player import MAX_LAYERS, MAX_UNITS, DeepCyberPlayer
from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.live.server import LiveSettings, create_app
from mirror_avatar.live.session import make_avatar_factory
from mirror_avatar.players import Player
from mirror_avatar.testing import ServerThread

TOKEN = "bench"
BEARER = {"Authorization": f"Bearer {TOKEN}"}


class Laggard(Player):
    """An avatar three control periods slow per step."""

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        """Start at rest."""
        return 0.0, 0.0

    def step(self, observation: Any) -> tuple[float, float]:
        """Take three control periods, then stay at rest."""
        time.sleep(3 * self.period)
        return 0.0, 0.0


async def paced_player(url: str, mode: str, seconds: float, log: dict[str, Any]) -> None:
    """Start a trial and send the pointer at 60 Hz for ``seconds`` or until it is done."""
    sent: dict[int, float] = {}
    answered: dict[int, float] = {}
    log |= {"sent": sent, "answered": answered}
    async with websockets.connect(url) as ws:
        await ws.recv()
        start = {"type": "start", "mode": mode, "participant": "B1", "duration": seconds + 2}
        await ws.send(json.dumps(start))

        async def read() -> None:
            async for text in ws:
                message = json.loads(text)
                if message["type"] == "avatar":
                    answered[message["seq"]] = time.monotonic()
                elif message["type"] == "done":
                    log["done"] = (time.monotonic(), message["summary"]["end_reason"])
                    return

        reader = asyncio.create_task(read())
        seq, began = 0, time.monotonic()
        while time.monotonic() - began < seconds and not reader.done():
            seq += 1
            sent[seq] = time.monotonic()
            await ws.send(
                json.dumps({"type": "position", "seq": seq, "x": 0.2 * math.sin(seq / 20)})
            )
            await asyncio.sleep(1 / 60)
        reader.cancel()


def window_rows(case: str, times: np.ndarray, latency: np.ndarray | None, windows: list) -> list:
    rows = []
    for name, low, high in windows:
        inside = times[(times >= low) & (times < high)]
        gap = float(np.diff(inside).max() * 1000.0) if inside.size > 1 else math.nan
        note = f"{inside.size} answers; longest gap {gap:.1f} ms"
        if latency is not None:
            chosen = latency[(latency[:, 0] >= low) & (latency[:, 0] < high), 1] * 1000.0
            rows.append({"name": f"{case} input-to-frame p50, {name}", "value": float(
                np.median(chosen)), "unit": "ms", "note": note})  # fmt: skip
            rows.append({"name": f"{case} input-to-frame p95, {name}", "value": float(
                np.percentile(chosen, 95)), "unit": "ms", "note": note})  # fmt: skip
        rows.append({"name": f"{case} longest gap, {name}", "value": gap, "unit": "ms",
                     "note": note})  # fmt: skip
    return rows


def live_rows(seconds: float) -> list[dict]:
    good = make_avatar_factory("bundled:slow")

    def factory(mode: str) -> Player:
        return Laggard() if mode == "avatar_leads" else good(mode)

    with tempfile.TemporaryDirectory() as folder:
        settings = LiveSettings(out_dir=Path(folder), avatar_spec="bench", countdown=0)
        with ServerThread(create_app(settings, factory)) as server:
            url = server.url.replace("http://", "ws://") + "/ws"
            good_log: dict[str, Any] = {}
            slow_log: dict[str, Any] = {}

            async def scenario() -> float:
                playing = asyncio.create_task(
                    paced_player(url, "avatar_follows", seconds, good_log)
                )
                await asyncio.sleep(seconds / 3)
                slow_start = time.monotonic()
                await paced_player(url, "avatar_leads", seconds, slow_log)
                await playing
                return slow_start

            slow_start = asyncio.run(scenario())
    sent, answered = good_log["sent"], good_log["answered"]
    latency = np.array([(sent[s], answered[s] - sent[s]) for s in sent if s in answered])
    slow_end, reason = slow_log["done"]
    t0, t1 = latency[0, 0], latency[-1, 0]
    windows = [("before", t0 + 0.5, slow_start), ("during", slow_start, slow_end),
               ("after", slow_end, t1)]  # fmt: skip
    rows = window_rows("live", np.sort(np.array(list(answered.values()))), latency, windows)
    rows.append({"name": "live slow session ended after", "value": slow_end - slow_start,
                 "unit": "s", "note": reason})  # fmt: skip
    return rows


async def lab_page(url: str, seconds: float, frames: list[float]) -> None:
    """Play a participant's page: answer pings, send the pointer at 60 Hz, stamp each frame."""
    async with websockets.connect(url) as ws:

        async def send() -> None:
            seq = 0
            while True:
                await ws.send(json.dumps({"type": "position", "seq": seq, "x": 0.1}))
                seq += 1
                await asyncio.sleep(1 / 60)

        sender = asyncio.create_task(send())
        try:
            async with asyncio.timeout(seconds):
                async for text in ws:
                    message = json.loads(text)
                    if message["type"] == "frame":
                        frames.append(time.monotonic())
                    elif message["type"] == "ping":
                        await ws.send(json.dumps({"type": "pong", "id": message["id"]}))
        except (TimeoutError, websockets.ConnectionClosed):
            pass
        finally:
            sender.cancel()


def lab_rows(seconds: float) -> list[dict]:
    with tempfile.TemporaryDirectory() as folder:
        big = DeepCyberPlayer(hidden=(MAX_UNITS,) * MAX_LAYERS)
        big.initialise_policy(0)
        spec = str(big.save(Path(folder) / "big.npz"))
        settings = LabSettings(out_dir=Path(folder) / "out", token=TOKEN, countdown=1)
        with ServerThread(create_lab_app(settings)) as lab:
            people = [{"label": label, "kind": "human"} for label in ("P1", "P2")]
            dyad = {"condition": "joint", "duration": seconds, "players": people}
            created = httpx.post(f"{lab.url}/api/sessions", json=dyad, headers=BEARER).json()
            links = [link.replace("http://", "ws://").replace("/join/", "/ws/join/")
                     for link in created["links"].values()]  # fmt: skip
            frames: list[float] = []
            avatars = [{"label": f"A{k}", "kind": "avatar", "spec": spec} for k in range(5)]
            slow = {"condition": "group", "duration": 10.0, "players": [people[0], *avatars]}
            marks: dict[str, Any] = {}

            async def scenario() -> None:
                pages = [asyncio.create_task(lab_page(url, seconds + 4, f))
                         for url, f in zip(links, (frames, []), strict=True)]  # fmt: skip
                await asyncio.sleep(0.5)
                url = f"{lab.url}/api/sessions/{created['id']}/start"
                await asyncio.to_thread(httpx.post, url, json={}, headers=BEARER)
                await asyncio.sleep(seconds / 3)
                marks["from"] = time.monotonic()
                answer = await asyncio.to_thread(
                    httpx.post, f"{lab.url}/api/sessions", json=slow, headers=BEARER, timeout=300
                )
                marks["to"], marks["answer"] = time.monotonic(), answer.json().get("error")
                await asyncio.gather(*pages)

            asyncio.run(scenario())
    times = np.array(frames)
    windows = [("before", times[0] + 0.5, marks["from"]), ("during", marks["from"], marks["to"]),
               ("after", marks["to"], times[-1])]  # fmt: skip
    rows = window_rows("lab", times, None, windows)
    rows.append({"name": "lab slow plan refused after", "value": marks["to"] - marks["from"],
                 "unit": "s", "note": str(marks["answer"])})  # fmt: skip
    return rows


def run(quick: bool) -> list[dict]:
    print("  live: a slow avatar beside a good participant ...", file=sys.stderr, flush=True)
    rows = live_rows(9.0 if quick else 15.0)
    print("  lab: a slow plan refused beside a running trial ...", file=sys.stderr, flush=True)
    return rows + lab_rows(12.0 if quick else 20.0)


if __name__ == "__main__":
    for row in run(quick="--quick" in sys.argv):
        print(row)

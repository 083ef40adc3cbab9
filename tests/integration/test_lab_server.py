"""The lab server over real sockets: the researcher's API, participants' pages as WebSocket
clients, one clock for all, drops, expiry, and a server killed mid-trial."""

from __future__ import annotations

import asyncio
import contextlib
import gc
import json
import logging
import math
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import httpx
import numpy as np
import pytest
import websockets

from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.lab.design.avatars import MAX_RECORDING_SPEC_BYTES
from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.testing import ServerThread, raw_websocket
from waiting import wait_for

TOKEN = "researcher-token"
BEARER = {"Authorization": f"Bearer {TOKEN}"}
DYAD = {
    "condition": "leader_follower",
    "leaders": [0],
    "duration": 3.0,
    "players": [{"label": "P1", "kind": "human"}, {"label": "P2", "kind": "human"}],
}
RING = {
    "condition": "group",
    "graph": "ring",
    "duration": 3.0,
    "players": [
        {"label": "P1", "kind": "human"},
        {"label": "A1", "kind": "avatar", "spec": "bundled:slow"},
        {"label": "P2", "kind": "human"},
        {"label": "A2", "kind": "avatar", "spec": "bundled:fast"},
    ],
}


@pytest.fixture
def lab(tmp_path: Path) -> Iterator[ServerThread]:
    settings = LabSettings(out_dir=tmp_path, token=TOKEN, countdown=1)
    with ServerThread(create_lab_app(settings)) as running:
        yield running


def create(lab: ServerThread, plan: dict[str, Any]) -> dict[str, Any]:
    response = httpx.post(f"{lab.url}/api/sessions", json=plan, headers=BEARER)
    assert response.status_code == 201, response.text
    return response.json()


def status(lab: ServerThread, sid: str) -> dict[str, Any]:
    return httpx.get(f"{lab.url}/api/sessions/{sid}", headers=BEARER).json()


def command(lab: ServerThread, sid: str, action: str, body: Any = None) -> httpx.Response:
    return httpx.post(f"{lab.url}/api/sessions/{sid}/{action}", json=body or {}, headers=BEARER)


def socket_url(link: str) -> str:
    return link.replace("http://", "ws://").replace("/join/", "/ws/join/")


class Page:
    """A participant's page as a WebSocket client: sends a position at 60 Hz, answers pings,
    keeps every message."""

    def __init__(self, link: str, phase: float = 0.0) -> None:
        self.url = socket_url(link)
        self.phase = phase
        self.messages: list[dict[str, Any]] = []
        self.sent: list[tuple[int, float]] = []
        self.closed: websockets.ConnectionClosed | None = None

    def x(self, t: float) -> float:
        return round(0.3 * math.sin(2 * math.pi * 0.5 * t + self.phase), 6)

    async def play(self, seconds: float) -> None:
        async with websockets.connect(self.url) as socket:
            sender = asyncio.create_task(self._send(socket))
            try:
                async with asyncio.timeout(seconds):
                    async for text in socket:
                        message = json.loads(text)
                        self.messages.append(message)
                        await self.on_message(socket, message)
            except websockets.ConnectionClosed as closed:
                self.closed = closed
            except TimeoutError:
                pass
            finally:
                await stopped([sender])

    async def on_message(self, socket: Any, message: dict[str, Any]) -> None:
        """Answer a ping (pages that do more extend this)."""
        if message["type"] == "ping":
            await socket.send(json.dumps({"type": "pong", "id": message["id"]}))

    async def _send(self, socket: Any) -> None:
        began, seq = time.monotonic(), 0
        while True:
            x = self.x(time.monotonic() - began)
            await socket.send(json.dumps({"type": "position", "seq": seq, "x": x}))
            self.sent.append((seq, x))
            seq += 1
            await asyncio.sleep(1 / 60)

    def of_type(self, kind: str) -> list[dict[str, Any]]:
        return [m for m in self.messages if m["type"] == kind]


async def welcomed(pages: list[Page]) -> None:
    """Wait until the server has welcomed every page: each has joined its slot."""
    await asyncio.to_thread(
        wait_for, lambda: all(page.of_type("welcome") for page in pages), 60.0, "every welcome"
    )


async def stopped(tasks: list[asyncio.Task[None]]) -> None:
    """Cancel ``tasks`` and wait until each has ended (a page closes its socket as it ends).

    A task cancelled and left running would be cancelled a second time by `asyncio.run` as it
    returns, interrupting the page's closing handshake and leaving its socket unclosed.
    """
    for task in tasks:
        task.cancel()
    await asyncio.gather(*tasks, return_exceptions=True)


async def play_all(pages: list[Page], seconds: float, start: Any) -> None:
    tasks = [asyncio.create_task(page.play(seconds)) for page in pages]
    await welcomed(pages)
    await asyncio.to_thread(start)
    await asyncio.gather(*tasks)


def test_the_console_and_the_api_need_the_researchers_token(lab):
    assert httpx.get(f"{lab.url}/console").status_code == 403
    assert httpx.get(f"{lab.url}/api/sessions").status_code == 403
    wrong = {"Authorization": "Bearer nope"}
    assert httpx.get(f"{lab.url}/api/sessions", headers=wrong).status_code == 403
    with httpx.Client(base_url=lab.url) as browser:
        entered = browser.get(f"/console?token={TOKEN}", follow_redirects=True)
        assert entered.status_code == 200 and "New session" in entered.text
        assert entered.url.path == "/console" and "token" not in str(entered.url)
        assert browser.get("/api/sessions").json() == {"sessions": []}
        form = browser.post("/api/sessions", content=json.dumps(DYAD))  # not JSON: a form post
        assert form.status_code == 415


def test_a_session_gives_one_link_per_person_that_cannot_control_it(lab):
    created = create(lab, RING)
    assert set(created["links"]) == {"P1", "P2"} and created["state"] == "waiting"
    link = created["links"]["P1"]
    assert httpx.get(link).status_code == 200
    assert httpx.get(f"{lab.url}/join/not-a-key").status_code == 404
    qr = httpx.get(f"{lab.url}/api/sessions/{created['id']}/qr/P1.svg", headers=BEARER)
    assert qr.headers["content-type"].startswith("image/svg") and b"<svg" in qr.content

    async def misbehave() -> list[dict[str, Any]]:
        async with websockets.connect(socket_url(link)) as socket:
            for text in ('{"type": "start"}', '{"type": "abort"}', "x" * 600, '{"type": "stop"}'):
                await socket.send(text)
            replies = []
            while len([r for r in replies if r["type"] == "error"]) < 4:
                replies.append(json.loads(await socket.recv()))
            return replies

    replies = asyncio.run(misbehave())
    welcome = replies[0]
    assert welcome["type"] == "welcome" and welcome["label"] == "P1"
    assert [v["label"] for v in welcome["visible"]] == ["P1", "A1", "A2"]  # its ring neighbours
    assert status(lab, created["id"])["state"] == "waiting"


def test_files_are_served_by_their_listed_names_only(lab):
    sid = create(lab, DYAD)["id"]
    base = f"{lab.url}/api/sessions/{sid}/files"
    assert httpx.get(f"{base}/plan.json", headers=BEARER).json()["plan"]["condition"] == (
        "leader_follower"
    )
    for name in ("..%2F..%2Fetc%2Fpasswd", "%2Fetc%2Fpasswd", "trial-01_session.csv"):
        assert httpx.get(f"{base}/{name}", headers=BEARER).status_code == 404


def test_a_dyad_of_two_people_plays_on_one_clock(lab, tmp_path):
    created = create(lab, DYAD | {"trials": 2, "pause": 0.5})
    sid = created["id"]
    assert command(lab, sid, "start").status_code == 409  # nobody has joined
    pages = [Page(created["links"]["P1"]), Page(created["links"]["P2"], phase=-0.5)]
    asyncio.run(play_all(pages, 12.0, lambda: command(lab, sid, "start").raise_for_status()))
    final = status(lab, sid)
    assert final["state"] == "finished" and final["links"] == {}
    assert [t["complete"] for t in final["trials"]] == [True, True]
    assert 0.5 < final["trials"][0]["metrics"]["phase_locking"] <= 1
    for page in pages:
        ends = page.of_type("end")
        assert [e["trial"] for e in ends] == [1, 2] and "phase_locking" in ends[0]["metrics"]
        assert page.closed is not None and page.closed.rcvd.code == 4001
    for n in (1, 2):
        session = load_session(tmp_path / sid / f"trial-0{n}_session.csv")
        assert session.n_samples == 101 and session.roles == ("leader", "follower")
        assert session.metadata["complete"] and session.metadata["lab"]["trial"] == n
        sent = {x for page in pages[:1] for _, x in page.sent}
        assert set(np.round(session.positions[0, 5:], 6)) <= sent
    row = next(s for s in final["slots"] if s["label"] == "P1")
    frames = pages[0].of_type("frame")
    assert len(frames) + row["frames_dropped"] == 2 * 101  # each frame received or counted
    for n, received in enumerate(frames_of_each_trial(frames), start=1):
        samples = [f["k"] for f in received]
        assert samples == sorted(set(samples)) and samples[-1] == 100
        lost = sorted(set(range(101)) - set(samples))
        caught_up = clock_caught_up(tmp_path / sid / f"trial-0{n}_inputs.csv")
        assert all(caught_up[k] for k in lost), f"trial {n}: frames {lost} lost on time"
        session = load_session(tmp_path / sid / f"trial-0{n}_session.csv")
        x = [f["x"] for f in received]
        np.testing.assert_array_equal(x, session.positions[:, samples].T)
    assert row["rtt_median_ms"] is not None and row["rtt_median_ms"] < 100


def frames_of_each_trial(frames: list[dict[str, Any]]) -> list[list[dict[str, Any]]]:
    """Split a page's frames into trials (each trial's samples start again at 0)."""
    trials: list[list[dict[str, Any]]] = []
    for frame in frames:
        if not trials or frame["k"] <= trials[-1][-1]["k"]:
            trials.append([])
        trials[-1].append(frame)
    return trials


def clock_caught_up(inputs: Path) -> np.ndarray:
    """For each sample k, whether the clock was catching up when sample k + 1 was taken.

    Per the trial's own record of its clock (``clock_s``), sample k + 1 came less than T/2
    after sample k: the clock had fallen behind, so frame k could be superseded before it was
    sent (a page sees the newest frame, not a backlog). A frame missing where the clock kept
    its period was lost.
    """
    clock = np.loadtxt(inputs, delimiter=",", skiprows=1, usecols=1, ndmin=1)
    return np.append(np.diff(clock) < CONTROL_PERIOD / 2, False)


def test_a_link_opened_by_many_clients_at_once_replaces_pages_without_errors(lab, caplog):
    link = create(lab, DYAD)["links"]["P1"]
    path = urlsplit(socket_url(link)).path
    with contextlib.ExitStack() as opened:  # 30 pages, none of which answers a close
        sockets = [opened.enter_context(raw_websocket(lab.port, path=path)) for _ in range(30)]
        for sock in sockets:
            sock.settimeout(60.0)
        assert all(sock.recv(1) != b"" for sock in sockets)  # every one accepted
    newest = Page(link)
    asyncio.run(newest.play(2.0))
    assert newest.of_type("welcome")
    gc.collect()  # an outbox task left pending would be reported as destroyed now
    errors = [r.getMessage() for r in caplog.records if r.levelno >= logging.ERROR]
    assert errors == []


class Follower(Page):
    """A participant's page that copies the avatar it sees ``delay`` samples late."""

    def __init__(self, link: str, delay: int) -> None:
        super().__init__(link)
        self.delay = delay
        self.seen: list[float] = []  # the avatar's position in each frame received
        self._read = 0

    def x(self, t: float) -> float:
        for message in self.messages[self._read :]:
            if message["type"] == "frame":
                self.seen.append(message["x"][1])
        self._read = len(self.messages)
        return self.seen[-1 - self.delay] if len(self.seen) > self.delay else 0.0


def test_an_avatar_leads_a_following_participant_and_the_measures_name_it(lab, tmp_path):
    plan = {
        "condition": "leader_follower",
        "leaders": [0],
        "duration": 15.0,
        "players": [
            {"label": "A1", "kind": "avatar", "spec": "bundled:slow"},
            {"label": "P1", "kind": "human"},
        ],
    }
    created = create(lab, plan)
    sid = created["id"]
    follower = Follower(created["links"]["P1"], delay=10)  # 10 frames: 0.3 s behind
    asyncio.run(play_all([follower], 22.0, lambda: command(lab, sid, "start").raise_for_status()))
    (trial,) = status(lab, sid)["trials"]
    measures = trial["measures"]
    assert trial["complete"] and measures["leader"] == 0  # the avatar, A1
    assert 0.25 <= measures["leader_lag_s"] <= 0.6  # 0.3 s copied, plus the network
    assert 0.0 <= measures["co_confidence_rate"] <= 1.0
    assert measures["leader_share_p_value"] == pytest.approx(1 / 20)  # beat all 19 surrogates
    listed = ("jitter_index_player_1", "transfer_entropy_1_to_0", "co_confidence_rate_p_value")
    assert set(listed) <= set(measures)
    sidecar = json.loads((tmp_path / sid / "trial-01_session.json").read_text())["metadata"]
    assert sidecar["measures"]["leader"] == 0 and sidecar["measures"]["surrogates"]["n"] == 19
    assert sidecar["measures"]["co_confidence_rate"] == measures["co_confidence_rate"]
    (end,) = follower.of_type("end")
    assert end["metrics"]["led_by"] == "partner" and "co_confidence_rate" in end["metrics"]


def test_a_dropped_participant_is_marked_and_the_trial_goes_on(lab, tmp_path):
    created = create(lab, RING | {"duration": 4.0})
    sid = created["id"]
    stay, leave = Page(created["links"]["P1"]), Page(created["links"]["P2"])

    async def scenario() -> None:
        staying = asyncio.create_task(stay.play(9.0))
        leaving = asyncio.create_task(leave.play(3.5))  # leaves about 2 s into the trial
        await welcomed([stay, leave])
        await asyncio.to_thread(lambda: command(lab, sid, "start").raise_for_status())
        await asyncio.gather(staying, leaving)

    asyncio.run(scenario())
    trial = status(lab, sid)["trials"][0]
    assert trial["complete"] and 20 < trial["dropped"]["P2"] < 120
    session = load_session(tmp_path / sid / "trial-01_session.csv")
    assert session.metadata["dropped"] == trial["dropped"] and session.n_samples == 134
    dropped = trial["dropped"]["P2"]
    assert np.all(session.positions[2, dropped + 5 :] == session.positions[2, -1])  # held
    assert trial["held"]["P2"] >= 134 - dropped - 5


def test_on_drop_stop_ends_the_trial(lab, tmp_path):
    created = create(lab, RING | {"duration": 10.0, "on_drop": "stop"})
    sid = created["id"]
    pages = [Page(created["links"]["P1"]), Page(created["links"]["P2"])]

    async def scenario() -> None:
        tasks = [asyncio.create_task(pages[0].play(6.0)), asyncio.create_task(pages[1].play(3.0))]
        await welcomed(pages)
        await asyncio.to_thread(lambda: command(lab, sid, "start").raise_for_status())
        await asyncio.gather(*tasks)

    asyncio.run(scenario())
    trial = status(lab, sid)["trials"][0]
    assert not trial["complete"] and trial["end_reason"] == "P2 dropped"
    assert load_session(tmp_path / sid / "trial-01_session.csv").metadata["complete"] is False


def test_abort_saves_the_trial_and_expires_the_links(lab, tmp_path):
    created = create(lab, RING | {"duration": 30.0})
    sid = created["id"]
    pages = [Page(created["links"]["P1"]), Page(created["links"]["P2"])]

    def start_then_abort() -> None:
        command(lab, sid, "start").raise_for_status()
        wait_for(lambda: status(lab, sid)["state"] == "running")
        time.sleep(1.0)
        command(lab, sid, "abort").raise_for_status()

    asyncio.run(play_all(pages, 8.0, start_then_abort))
    final = status(lab, sid)
    assert final["state"] == "aborted" and final["trials"][0]["end_reason"] == "session aborted"
    plays = {row["label"]: row.get("plays") for row in final["slots"]}
    assert plays == {"P1": None, "A1": "virtual trainer (bundled:slow)", "P2": None,
                     "A2": "virtual trainer (bundled:fast)"}  # fmt: skip
    assert all(page.closed is not None and page.closed.rcvd.code == 4001 for page in pages)
    assert httpx.get(created["links"]["P1"]).status_code == 404
    assert command(lab, sid, "start").status_code == 409
    assert load_session(tmp_path / sid / "trial-01_session.csv").n_samples > 20


def test_api_requests_are_rate_limited(tmp_path):
    settings = LabSettings(out_dir=tmp_path, token=TOKEN, requests_per_second=5.0)
    with ServerThread(create_lab_app(settings)) as lab, httpx.Client(headers=BEARER) as client:
        codes = [client.get(f"{lab.url}/api/sessions").status_code for _ in range(40)]
        assert codes[0] == 200 and codes[-1] == 429
        assert client.get(f"{lab.url}/api/sessions").text.startswith("too many requests")


@pytest.mark.long
def test_killing_the_server_leaves_every_sample_on_disk(tmp_path):
    server = subprocess.Popen(
        [
            Path(sys.executable).parent / "mirror-avatar",
            "lab",
            "--port",
            "0",
            "--out",
            str(tmp_path),
            "--no-lsl",
        ],  # fmt: skip
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        start_new_session=True,
    )
    try:
        url = token = None
        for line in server.stdout:  # type: ignore[union-attr]
            if found := re.search(r"console: (http://[^/]+)/console\?token=(\S+)", line):
                url, token = found.groups()
                break
        assert url and token
        headers = {"Authorization": f"Bearer {token}"}
        plan = RING | {"duration": 60.0}
        created = httpx.post(f"{url}/api/sessions", json=plan, headers=headers).json()
        page = Page(created["links"]["P1"])
        other = Page(created["links"]["P2"])

        def start() -> None:
            httpx.post(f"{url}/api/sessions/{created['id']}/start", json={}, headers=headers)

        async def scenario() -> None:
            tasks = [asyncio.create_task(p.play(30.0)) for p in (page, other)]
            await welcomed([page, other])
            await asyncio.to_thread(start)
            await asyncio.to_thread(wait_for, lambda: len(page.of_type("frame")) >= 100)
            os.killpg(server.pid, signal.SIGKILL)
            await asyncio.gather(*tasks)

        asyncio.run(scenario())
        last_frame = page.of_type("frame")[-1]["k"]
        session = load_session(tmp_path / created["id"] / "trial-01_session.csv")
        assert session.n_samples >= last_frame + 1
        assert session.metadata["complete"] is False
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(server.pid, signal.SIGKILL)
        server.wait(10)
        server.stdout.close()  # type: ignore[union-attr]


def test_hidden_metrics_and_a_participant_who_rejoins(lab, tmp_path):
    created = create(lab, DYAD | {"duration": 5.0, "show_metrics": False})
    sid = created["id"]
    steady = Page(created["links"]["P1"])
    first, again = Page(created["links"]["P2"]), Page(created["links"]["P2"], phase=1.0)

    async def scenario() -> None:
        staying = asyncio.create_task(steady.play(10.0))
        leaving = asyncio.create_task(first.play(2.5))
        await welcomed([steady, first])
        await asyncio.to_thread(lambda: command(lab, sid, "start").raise_for_status())
        await leaving
        await asyncio.to_thread(wait_for, lambda: not status(lab, sid)["slots"][1]["connected"])
        await again.play(7.0)
        await staying

    asyncio.run(scenario())
    trial = status(lab, sid)["trials"][0]
    assert trial["complete"] and "P2" in trial["dropped"]
    (end,) = again.of_type("end")
    assert "metrics" not in end and again.of_type("frame")
    session = load_session(tmp_path / sid / "trial-01_session.csv")
    rejoined = again.sent[0][1]
    later = session.positions[1, trial["dropped"]["P2"] + 40 :]
    assert rejoined in set(np.round(later, 6)) or np.ptp(later) > 0.1  # moving again


def test_api_errors_are_one_json_line(lab):
    bad_plan = httpx.post(f"{lab.url}/api/sessions", json={"condition": "x"}, headers=BEARER)
    assert bad_plan.status_code == 400 and bad_plan.json()["error"].startswith("plan:")
    not_json = httpx.post(
        f"{lab.url}/api/sessions",
        content=b"{nope",
        headers=BEARER | {"Content-Type": "application/json"},
    )
    assert not_json.status_code == 400 and "not valid JSON" in not_json.json()["error"]
    typo = RING | {"players": [*RING["players"][:3], {**RING["players"][3], "spec": "bundled:slw"}]}
    refused = httpx.post(f"{lab.url}/api/sessions", json=typo, headers=BEARER)
    assert refused.status_code == 400 and "unknown bundled style" in refused.json()["error"]
    assert httpx.get(f"{lab.url}/api/sessions", headers=BEARER).json() == {"sessions": []}
    missing = httpx.get(f"{lab.url}/api/sessions/nope/live", headers=BEARER)
    assert missing.status_code == 404 and missing.json() == {"error": "no such session"}
    sid = create(lab, DYAD)["id"]
    unknown = command(lab, sid, "dance")
    assert unknown.status_code == 404
    assert "start, stop, abort, export or refuse" in unknown.json()["error"]


def test_a_huge_recording_as_an_avatar_is_refused_before_it_is_read(lab, tmp_path):
    huge = tmp_path / "huge.csv"
    with huge.open("wb") as file:  # a sparse file: its size is what is checked, nothing is read
        file.truncate(MAX_RECORDING_SPEC_BYTES + 1)
    for spec in (str(huge), f"vt:{huge}"):
        players = [*RING["players"][:3], {**RING["players"][3], "spec": spec}]
        refused = httpx.post(
            f"{lab.url}/api/sessions", json=RING | {"players": players}, headers=BEARER
        )
        error = refused.json()["error"]
        assert refused.status_code == 400 and "huge.csv" in error and "limit" in error, error
    assert httpx.get(f"{lab.url}/api/sessions", headers=BEARER).json() == {"sessions": []}

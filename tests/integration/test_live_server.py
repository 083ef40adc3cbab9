"""The live server over real sockets: a uvicorn server in a thread and `websockets` clients."""

from __future__ import annotations

import gc
import json
import math
import os
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
from websockets.exceptions import ConnectionClosed, InvalidStatus
from websockets.sync.client import ClientConnection, connect

from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.files.trials import make_trial
from mirror_avatar.live.server import LiveSettings, create_app
from mirror_avatar.live.session import AvatarFactory, make_avatar_factory
from mirror_avatar.players import Player
from mirror_avatar.realtime.transport import ACCEPT_BATCH, RECEIVE_BUFFER_BYTES, listening_socket
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.testing import ServerThread, raw_websocket, text_frame
from waiting import wait_for

FRAME = 1 / 60


def sway(t: float) -> float:
    """The test's pointer trajectory (units): a 0.5 Hz sine of amplitude 0.3."""
    return 0.3 * math.sin(2 * math.pi * 0.5 * t)


class Browser:
    """A scripted browser: sends the pointer once per frame and reads every reply."""

    def __init__(self, ws: ClientConnection) -> None:
        self.ws = ws
        self.seq = 0
        self.messages: list[dict[str, Any]] = []
        self.sent: list[float] = []  # when each position went out (monotonic s)
        self.replies: list[tuple[float, float]] = []  # (monotonic s, the trial's progress)
        self.ready = self.receive()

    def receive(self, timeout: float = 5.0) -> dict[str, Any]:
        message = json.loads(self.ws.recv(timeout))
        self.messages.append(message)
        return message

    def send(self, message: dict[str, Any] | str) -> None:
        self.ws.send(message if isinstance(message, str) else json.dumps(message))

    def start(self, mode: str, duration: float, **extra: Any) -> None:
        self.send({"type": "start", "mode": mode, "participant": "P07", "duration": duration})
        self.messages.clear()

    def position(self, x: float) -> dict[str, Any]:
        """Send one position and return the server's answer to it."""
        self.seq += 1
        self.sent.append(time.monotonic())
        self.send({"type": "position", "seq": self.seq, "x": x, "rtt": 1.0})
        while True:
            message = self.receive()
            if message["type"] == "avatar":
                self.replies.append((time.monotonic(), message["progress"]))
            if message["type"] in ("avatar", "error"):
                return message

    def play(
        self, trajectory: Callable[[float], float], until: float = math.inf
    ) -> dict[str, Any] | None:
        """Move along ``trajectory`` (time since go, s) until done or ``until`` s; return done."""
        began = None
        deadline = time.monotonic() + 30.0
        while True:
            assert time.monotonic() < deadline, "the trial never ended"
            t = 0.0 if began is None else time.monotonic() - began
            if t > until:
                return None
            self.position(trajectory(t))
            for message in self.messages:
                if message["type"] == "go" and began is None:
                    began = time.monotonic()
                if message["type"] == "done":
                    return message["summary"]
            self.messages.clear()
            time.sleep(FRAME)


class Replay(Player):
    """A player replaying a fixed sine, ignoring its partner (stands in for the engine in the
    robustness tests, which are about the server, not the avatar)."""

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        self.k = 0
        return 0.0, 0.0

    def step(self, observation: Any) -> tuple[float, float]:
        self.k += 1
        return 0.2 * math.sin(self.k * self.period), 0.2 * math.cos(self.k * self.period)


def replay_factory(mode: str) -> Replay:
    return Replay()


class Live:
    """Live servers on free ports and browsers connected to them, all closed by the test's end."""

    def __init__(self, stack: ExitStack, out_dir: Path) -> None:
        self.stack = stack
        self.out_dir = out_dir

    def serve(self, factory: AvatarFactory | None = replay_factory, **options: Any) -> ServerThread:
        settings = LiveSettings(out_dir=self.out_dir, avatar_spec="test", countdown=0, **options)
        return self.stack.enter_context(ServerThread(create_app(settings, factory)))

    def open(self, server: ServerThread, query: str = "", **options: Any) -> Browser:
        url = server.url.replace("http", "ws") + "/ws" + query
        return Browser(self.stack.enter_context(connect(url, proxy=None, **options)))


@pytest.fixture
def live(tmp_path: Path) -> Iterator[Live]:
    with ExitStack() as stack:
        yield Live(stack, tmp_path / "recordings")


def read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    lines = path.read_text().splitlines()
    return lines[0].split(","), np.loadtxt(lines[1:], delimiter=",", ndmin=2)


def sidecars(tmp_path: Path) -> list[dict[str, Any]]:
    """The live metadata of each trial's session sidecar, with the number of samples."""
    paths = sorted((tmp_path / "recordings" / "P07").glob("*_session.json"))
    records = [json.loads(path.read_text()) for path in paths]
    return [record["metadata"] | {"n_samples": record.get("n_samples")} for record in records]


def observed_tolerance(player: Browser, n_ticks: int) -> float:
    """How far (units) a recorded sample may be from `sway` at its time, from this run's clocks.

    The server keeps the last position sent, at most the longest gap between two sends old;
    and its ticks are late by an amount the lag search removes only where it is constant: its
    spread is read from the replies (ticks done, from their progress, against the client's
    clock; over-estimated by up to one tick). Both times the sway's top speed.
    """
    speed = 0.3 * 2 * math.pi * 0.5
    replies = np.array([(t, p) for t, p in player.replies if 0.0 < p < 1.0])
    late = replies[:, 0] - replies[:, 1] * n_ticks * CONTROL_PERIOD
    return speed * (float(np.diff(player.sent).max()) + float(np.ptp(late)))


def test_solo_trial_is_recorded_as_a_trial_csv(live, tmp_path):
    player = live.open(live.serve())
    assert player.ready["modes"] == ["solo", "avatar_leads", "avatar_follows", "joint"]
    player.start("solo", 1.5)
    summary = player.play(sway)
    assert summary is not None and summary["complete"] and summary["avatar"] is None
    directory = tmp_path / "recordings" / "P07"
    header, data = read_csv(directory / summary["files"]["person"])
    assert header == ["time", "position"]
    solo = load_session(directory / summary["files"]["session"])
    np.testing.assert_array_equal(solo.positions[0], data[:, 1])
    assert solo.n_players == 1 and solo.roles == ("solo",)
    assert data.shape == (round(1.5 / CONTROL_PERIOD) + 1, 2)
    np.testing.assert_allclose(np.diff(data[:, 0]), CONTROL_PERIOD, atol=1e-4)
    # the recorded trace is the sent one, up to the delay between client and server clocks
    lags = np.arange(0.0, 0.2, 0.005)
    errors = [np.abs(data[:, 1] - [sway(t - lag) for t in data[:, 0]]).max() for lag in lags]
    assert min(errors) < observed_tolerance(player, data.shape[0])
    trial = make_trial(data[:, 0], data[:, 1])
    assert trial.rate == pytest.approx(1 / CONTROL_PERIOD)
    # one round trip per position the server received while the trial ran (as many as the
    # client managed to send: fewer on a busy machine)
    during = sum(0.0 < progress < 1.0 for _, progress in player.replies)
    assert during > 0 and abs(summary["round_trip_ms"]["n"] - during) <= 1
    assert summary["seed"] >= 0
    assert summary["metrics"]["person_speed"] == pytest.approx(0.6, rel=0.15)


def test_avatar_modes_write_a_session_with_both_players(live, tmp_path):
    player = live.open(live.serve())
    player.start("avatar_leads", 1.0)
    summary = player.play(sway)
    assert summary["complete"], summary.get("end_reason")
    assert summary["avatar_role"] == "leader"
    session = load_session(tmp_path / "recordings" / "P07" / summary["files"]["session"])
    assert session.labels == ("person P07", "avatar") and session.roles == ("follower", "leader")
    expected = [0.2 * math.sin(k * CONTROL_PERIOD) for k in range(session.n_samples)]
    np.testing.assert_allclose(session.positions[1], expected, atol=1e-15)
    for key in ("rmse", "phase_locking", "mean_relative_phase", "emd_players"):
        assert math.isfinite(summary["metrics"][key])


def test_dropped_connection_leaves_an_incomplete_trial_and_server_keeps_serving(live, tmp_path):
    server = live.serve()
    player = live.open(server)
    player.start("avatar_follows", 30.0)
    assert player.play(sway, until=1.0) is None
    player.ws.close()
    wait_for(lambda: "ended_utc" in sidecars(tmp_path)[0])
    record = sidecars(tmp_path)[0]
    assert not record["complete"] and record["end_reason"] == "connection closed"
    session = load_session(tmp_path / "recordings" / "P07" / record["files"]["session"])
    assert 20 < session.n_samples < 60 and record["n_samples"] == session.n_samples
    again = live.open(server)
    again.start("solo", 1.0)
    assert again.play(sway)["complete"]


def test_stop_ends_the_trial_early_and_another_can_start(live, tmp_path):
    player = live.open(live.serve())
    player.start("solo", 30.0)
    player.play(sway, until=0.5)
    player.send({"type": "stop"})
    while (message := player.receive())["type"] != "done":
        pass
    summary = message["summary"]
    assert not summary["complete"] and summary["end_reason"] == "stopped by the participant"
    player.start("solo", 1.0)
    assert player.play(sway)["complete"]
    assert len(sidecars(tmp_path)) == 2


def test_a_client_that_stops_sending_is_timed_out(live, tmp_path):
    player = live.open(live.serve(stale_timeout=0.3))
    player.start("solo", 30.0)
    player.play(sway, until=0.6)
    time.sleep(0.8)
    with pytest.raises(ConnectionClosed) as closed:
        while True:
            player.receive()
    assert closed.value.rcvd.code == 4408
    (record,) = sidecars(tmp_path)
    assert not record["complete"] and record["end_reason"] == "the browser stopped sending"


def test_idle_connections_are_closed_and_free_their_place(live):
    server = live.serve(idle_timeout=0.3, max_sessions=1)
    idle = live.open(server)
    with pytest.raises(ConnectionClosed) as closed:
        idle.receive()
    assert closed.value.rcvd.code == 4000 and "press Start" in closed.value.rcvd.reason
    assert live.open(server).ready["type"] == "ready"


def answer(browser: Browser) -> dict[str, Any]:
    """The next message that answers one the browser sent (not the trial's own go)."""
    while (message := browser.receive())["type"] == "go":
        pass
    return message


def test_bad_messages_are_answered_and_ignored(live, tmp_path):
    server = live.serve()
    player, other = live.open(server), live.open(server)
    player.start("solo", 3.0)
    other.start("avatar_follows", 1.0)
    player.position(0.1)
    position = '{"type": "position", "seq": 1, "x": %s}'
    bad = ["not json", "[1, 2]", '{"type": "jump"}', "x" * 600]
    bad += [position % x for x in ("0.7", "NaN", '"0.1"', "1" + "0" * 400)]
    for message in bad:
        player.send(message)
        assert answer(player)["type"] == "error"
    player.ws.send(b"\x00\x01")
    assert "text" in answer(player)["message"]
    player.send({"type": "start", "mode": "solo", "participant": "../etc", "duration": 1})
    assert "participant" in player.receive()["message"]
    assert player.play(lambda t: -0.2)["complete"]
    assert other.play(sway)["complete"]
    records = {record["mode"]: record for record in sidecars(tmp_path)}
    assert records["solo"]["rejected_messages"] == 10
    _, data = read_csv(tmp_path / "recordings" / "P07" / records["solo"]["files"]["person"])
    assert np.abs(data[:, 1]).max() <= 0.2 + 1e-9


def test_oversized_frames_close_only_their_connection(live):
    server = live.serve()
    player, other = live.open(server), live.open(server)
    player.send("x" * 100_000)
    with pytest.raises(ConnectionClosed) as closed:
        player.receive()
    assert closed.value.rcvd.code == 1009
    other.start("solo", 1.0)
    assert other.play(sway)["complete"]


def test_too_many_sessions_are_refused(live):
    server = live.serve(max_sessions=2)
    first, second = live.open(server), live.open(server)
    third = live.open(server)
    assert third.ready["type"] == "error" and "busy" in third.ready["message"]
    with pytest.raises(ConnectionClosed) as closed:
        third.receive()
    assert closed.value.rcvd.code == 1013
    first.start("solo", 1.0)
    assert first.play(sway)["complete"]
    assert second.position(0.0)["type"] == "avatar"


def test_token_is_required_on_every_connection(live):
    server = live.serve(token="s3cret")
    web = live.stack.enter_context(httpx.Client(trust_env=False))
    assert web.get(server.url + "/").status_code == 403
    assert web.get(server.url + "/static/game.js").status_code == 403
    assert web.get(server.url + "/?token=wrong").status_code == 403
    with httpx.Client(trust_env=False) as browser:
        page = browser.get(server.url + "/?token=s3cret")
        assert page.status_code == 200 and "Mirror game" in page.text
        assert browser.get(server.url + "/static/game.js").status_code == 200  # by cookie
    with pytest.raises(InvalidStatus) as refused:
        live.open(server)
    assert refused.value.response.status_code == 403
    assert live.open(server, "?token=s3cret").ready["type"] == "ready"


def test_cross_origin_websockets_are_refused(live):
    server = live.serve()
    with pytest.raises(InvalidStatus):
        live.open(server, origin="http://evil.example")
    assert live.open(server, origin=server.url).ready["type"] == "ready"


def test_server_without_avatar_offers_solo_only(live):
    player = live.open(live.serve(factory=None))
    assert player.ready["modes"] == ["solo"]
    player.start("joint", 1.0)
    assert "needs an avatar" in player.receive()["message"]


def test_default_avatar_is_the_engine_virtual_trainer(live, tmp_path):
    player = live.open(live.serve(factory=make_avatar_factory()))
    player.start("avatar_follows", 2.0)
    summary = player.play(sway)
    assert summary["complete"], summary.get("end_reason")
    session = load_session(tmp_path / "recordings" / "P07" / summary["files"]["session"])
    assert np.ptp(session.positions[1]) > 0.1


def run_play(*args: str, out_dir: Path) -> subprocess.Popen[str]:
    command = Path(sys.executable).parent / "mirror-avatar"
    environment = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen(
        [str(command), "play", "--out", str(out_dir), *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=environment,
    )


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def test_play_command_requires_a_token_off_loopback(tmp_path):
    port = free_port()
    process = run_play("--host", "0.0.0.0", "--port", str(port), out_dir=tmp_path)
    try:
        lines = []
        while not (lines and lines[-1].startswith("open ")):
            line = process.stdout.readline()
            assert line, f"play exited early: {process.stderr.read()}"
            lines.append(line.strip())
        token = next(line.split()[2] for line in lines if line.startswith("access token"))
        assert f"?token={token}" in lines[-1]
        url = f"http://127.0.0.1:{port}/"
        with httpx.Client(trust_env=False) as web:
            deadline = time.monotonic() + 20
            while True:
                try:
                    refused = web.get(url)
                    break
                except httpx.ConnectError:
                    assert time.monotonic() < deadline
                    time.sleep(0.1)
            assert refused.status_code == 403
            assert web.get(url, params={"token": token}).status_code == 200
    finally:
        process.terminate()
        process.communicate(timeout=10)


def test_play_command_rejects_a_bad_avatar_in_one_line(tmp_path):
    process = run_play("--avatar", "no-such-avatar:xyz", "--port", "0", out_dir=tmp_path)
    out, err = process.communicate(timeout=60)
    assert process.returncode == 2
    assert len(err.strip().splitlines()) == 1 and err.startswith("mirror-avatar: error:")


def test_requests_for_other_host_names_are_refused_without_a_token(live):
    """DNS rebinding: a page of another site whose name resolves to 127.0.0.1 gets nothing."""
    server = live.serve()
    port = server.url.rsplit(":", 1)[1]
    web = live.stack.enter_context(httpx.Client(trust_env=False))
    assert web.get(server.url + "/").status_code == 200
    for host in (f"localhost:{port}", f"[::1]:{port}", f"127.0.0.1:{port}"):
        assert web.get(server.url + "/", headers={"Host": host}).status_code == 200
    forged = {"Host": f"attacker.example:{port}"}
    refused = web.get(server.url + "/", headers=forged)
    assert refused.status_code == 403 and "--allow-host" in refused.text
    rebound = socket.create_connection(("127.0.0.1", int(port)))
    with pytest.raises(InvalidStatus) as handshake:
        connect(f"ws://attacker.example:{port}/ws", sock=rebound, proxy=None,
                origin=f"http://attacker.example:{port}")  # fmt: skip
    assert handshake.value.response.status_code == 403
    named = live.serve(allowed_hosts=frozenset({"labpc.local"}))
    assert web.get(named.url + "/", headers={"Host": f"labpc.local:{port}"}).status_code == 200
    with_token = live.serve(token="t0ken")
    assert web.get(with_token.url + "/?token=t0ken", headers=forged).status_code == 200


def test_idle_connections_make_room_for_a_newcomer_but_players_keep_theirs(live):
    """Connections that never play are evicted for newcomers; one with a trial never is."""
    server = live.serve(max_sessions=2, evict_after=0.2)
    player, idle = live.open(server), live.open(server)
    player.start("solo", 3.0)
    time.sleep(0.3)
    newcomer = live.open(server)
    assert newcomer.ready["type"] == "ready"
    with pytest.raises(ConnectionClosed) as closed:
        idle.receive()
    assert closed.value.rcvd.code == 4000
    late = live.open(server)
    assert late.ready["type"] == "error" and "busy" in late.ready["message"]
    assert player.play(sway)["complete"]


def test_one_address_cannot_take_every_place(live):
    server = live.serve(max_sessions=3, max_per_address=2, evict_after=60.0)
    live.open(server), live.open(server)
    third = live.open(server)
    assert third.ready["type"] == "error" and "this address" in third.ready["message"]


def test_connection_churn_from_one_address_is_slowed(live):
    server = live.serve(connects_per_second=0.5)
    answers = [live.open(server).ready for _ in range(12)]
    refused = [a for a in answers if a["type"] == "error" and "wait" in a["message"]]
    assert len(refused) >= 2  # a burst of 10 then one every 2 s


def test_trial_start_churn_is_rate_limited(live, tmp_path):
    """Start/stop as fast as possible: a few trials, then refusals; the files stay few."""
    server = live.serve(starts_per_second=0.5)
    churner = live.open(server)
    refusals = 0
    for _ in range(40):
        churner.start("solo", 5.0)
        churner.send({"type": "stop"})  # answered by done, or by nothing after a refusal
        while (message := churner.receive())["type"] not in ("done", "error"):
            pass
        refusals += message["type"] == "error" and "too many trials" in message["message"]
    assert refusals >= 30
    assert len(list((tmp_path / "recordings").rglob("*"))) < 3 * 10 + 2


def test_a_message_flood_closes_only_the_flooding_connection(live):
    server = live.serve(max_message_rate=100.0)
    flooder, player = live.open(server), live.open(server)
    player.start("solo", 1.0)
    message = json.dumps({"type": "position", "seq": 1, "x": 0.0})
    with pytest.raises(ConnectionClosed) as closed:
        for _ in range(5000):
            flooder.ws.send(message)
        while True:
            flooder.receive()
    assert closed.value.rcvd is not None and closed.value.rcvd.code == 1008
    assert player.play(sway)["complete"]


def deaf_client(port: int) -> socket.socket:
    """A WebSocket client that never reads: a raw socket with a small receive window."""
    sock = raw_websocket(port, receive_buffer=4096)
    response = b""
    while b"\r\n\r\n" not in response:
        response += sock.recv(1)
    assert b" 101 " in response.split(b"\r\n")[0]
    return sock


@pytest.mark.long
def test_a_client_that_stops_reading_is_dropped(live):
    """Its replies cannot be delivered: the server resets it and its place is free again."""
    server = live.serve(max_sessions=1, max_message_rate=1e6, send_timeout=0.5)
    deaf = deaf_client(int(server.url.rsplit(":", 1)[1]))
    live.stack.callback(deaf.close)
    deaf.settimeout(10.0)
    frame = text_frame(json.dumps({"type": "position", "seq": 1, "x": 0.0}))
    with pytest.raises(ConnectionResetError):
        for _ in range(10_000_000):
            deaf.sendall(frame)
    assert live.open(server).ready["type"] == "ready"


def test_a_flooding_client_is_read_no_more_and_reset(live):
    """Over the message rate and deaf to the close: the server stops reading it (its sends
    stall within a few buffers' worth) and resets it after the send timeout."""
    server = live.serve(max_message_rate=50.0, max_rejected=20, send_timeout=0.5)
    flooder = deaf_client(int(server.url.rsplit(":", 1)[1]))
    live.stack.callback(flooder.close)
    flooder.settimeout(10.0)
    frame = text_frame(json.dumps({"type": "position", "seq": 1, "x": 0.0}))
    sent, began = 0, time.monotonic()
    with pytest.raises(ConnectionResetError):
        while True:
            flooder.sendall(frame)
            sent += 1
    assert time.monotonic() - began < 5.0
    assert sent * len(frame) < 16 * 2**20, "the server kept reading the flood"
    assert live.open(server).ready["type"] == "ready"


def test_the_server_socket_bounds_what_one_read_takes():
    sock = listening_socket("127.0.0.1", 0)
    try:
        assert sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF) <= 4 * RECEIVE_BUFFER_BYTES
    finally:
        sock.close()


def test_the_server_socket_queues_a_client_that_connects_before_the_server_runs():
    sock = listening_socket("127.0.0.1", 0)
    try:
        client = socket.create_connection(sock.getsockname(), timeout=5.0)
        client.close()
    finally:
        sock.close()


def test_a_burst_of_connections_is_accepted_in_batches_and_every_one_answered(live):
    server = live.serve()
    assert gc.get_freeze_count() > 0  # the heap of imports is left out of collections
    clients = [socket.create_connection((server.host, server.port), timeout=30.0)
               for _ in range(4 * ACCEPT_BATCH)]  # fmt: skip
    try:
        for client in clients:
            client.sendall(b"GET /nowhere HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        assert all(client.recv(9) == b"HTTP/1.1 " for client in clients)
    finally:
        for client in clients:
            client.close()


class Sleepy(Replay):
    """An avatar whose steps take a second each (sleeping, as a slow compiled step would)."""

    def step(self, observation: Any) -> tuple[float, float]:
        time.sleep(1.0)
        return super().step(observation)


def test_a_too_slow_avatar_ends_its_trial_and_stalls_no_one_else(live):
    server = live.serve(factory=lambda mode: Sleepy())
    slow, other = live.open(server), live.open(server)
    slow.start("avatar_follows", 5.0)
    slow.position(0.0)
    began = time.monotonic()
    answers = [other.position(0.0) for _ in range(20)]
    assert all(a["type"] == "avatar" for a in answers)
    assert time.monotonic() - began < 0.9  # answered while the slow avatar's tick runs
    summary = slow.play(sway)
    assert not summary["complete"]
    assert summary["end_reason"] == "the avatar is too slow for real time"


def test_participant_ids_may_not_start_with_a_dash(live):
    server = live.serve()
    player = live.open(server)
    player.send({"type": "start", "mode": "solo", "participant": "-rf", "duration": 1})
    assert "starting with a letter or digit" in player.receive()["message"]

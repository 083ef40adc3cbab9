"""The emulated internet between a client and a real TCP echo server on loopback.

Every test reads the proxy's truth log and checks it against the declared network and against
what the client itself saw (its own stamps on the monotonic clock, the bytes echoed back).
"""

from __future__ import annotations

import signal
import socket
import socketserver
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from mirror_avatar.cli import main
from mirror_avatar.remote.network import parse_network
from mirror_avatar.remote.proxy import ProxyThread
from mirror_avatar.remote.truth import COLUMNS, fingerprint
from waiting import wait_for


class Echo(socketserver.BaseRequestHandler):
    def handle(self) -> None:
        while data := self.request.recv(65_536):
            self.request.sendall(data)


@pytest.fixture
def echo() -> Iterator[tuple[str, int]]:
    server = socketserver.ThreadingTCPServer(("127.0.0.1", 0), Echo)
    server.daemon_threads = True
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield server.server_address[:2]
    server.shutdown()
    server.server_close()


def exchange(port: int, messages: list[bytes], every_s: float) -> tuple[bytes, list[float]]:
    """Send ``messages`` one every ``every_s`` s while reading the echo; return the bytes
    echoed and when each read returned (`time.monotonic`)."""
    expected = sum(len(m) for m in messages)
    received: list[bytes] = []
    stamps: list[float] = []
    with socket.create_connection(("127.0.0.1", port)) as client:
        client.settimeout(30.0)

        def read() -> None:
            while sum(len(r) for r in received) < expected:
                data = client.recv(65_536)
                if not data:
                    return
                stamps.append(time.monotonic())
                received.append(data)

        reader = threading.Thread(target=read)
        reader.start()
        began = time.monotonic()
        for n, message in enumerate(messages):
            time.sleep(max(0.0, began + n * every_s - time.monotonic()))
            client.sendall(message)
        reader.join(60.0)
    return b"".join(received), stamps


def truth(path: Path) -> pd.DataFrame:
    table = pd.read_csv(path, keep_default_na=False)
    assert tuple(table.columns) == COLUMNS
    return table


def test_delays_follow_the_declared_model_and_order_is_kept(echo, tmp_path):
    network = parse_network("up=80+-25,down=40+-10")
    log = tmp_path / "truth.csv"
    messages = [b"%05d;" % n for n in range(200)]
    with ProxyThread(network, echo, log, 11) as proxy:
        port = proxy.proxy.port
        sent_at = time.monotonic()
        echoed, stamps = exchange(port, messages, 0.02)
    assert echoed == b"".join(messages)  # every byte, in order, both ways
    table = truth(log)
    data = table[table.bytes > 0]
    for direction, (mean, sd) in {"up": (80.0, 25.0), "down": (40.0, 10.0)}.items():
        drawn = data[data.direction == direction].delay_ms.to_numpy()
        assert len(drawn) >= 50, direction  # chunks as the sockets gave them (some coalesced)
        # the draws are the declared normal, truncated at 0 (4 standard errors; SD within 20 %)
        assert abs(drawn.mean() - mean) < 4 * sd / np.sqrt(len(drawn)), direction
        assert drawn.std(ddof=1) == pytest.approx(sd, rel=0.2), direction
        model = stats.truncnorm(-mean / sd, np.inf, loc=mean, scale=sd)
        assert stats.kstest(drawn, model.cdf).pvalue > 0.001, direction
    for _, lane in table.groupby(["connection", "direction"]):
        assert lane.chunk.tolist() == list(range(len(lane)))
        assert np.all(np.diff(lane.due_s) >= 0) and np.all(np.diff(lane.delivered_s) >= 0)
        own = lane.received_s + lane.delay_ms / 1000
        assert np.all(lane.due_s >= own - 1e-6)  # never before its own delay
        assert np.all(lane.delivered_s >= lane.due_s - 1e-6)  # never before it is due
        assert set(lane.cause) <= {"delay", "order"}
        own_time = (lane.cause == "delay").to_numpy()
        assert np.allclose(lane.due_s[own_time], own[own_time], atol=1e-6)
        behind = lane.due_s.to_numpy()[~own_time] == lane.due_s.shift().to_numpy()[~own_time]
        assert behind.all()  # the others are due with the chunk before them
    # the log's times are the client's own clock: its first message left before the proxy got
    # it, and its echo came back after the proxy delivered it
    up0, down0 = (data[data.direction == d].iloc[0] for d in ("up", "down"))
    assert sent_at <= up0.received_s < up0.delivered_s <= down0.received_s
    assert down0.received_s < down0.delivered_s <= stamps[0]


def test_a_stall_holds_everything_then_releases_it_in_order(echo, tmp_path):
    network = parse_network("5,stall=0.8:0.7")
    log = tmp_path / "truth.csv"
    messages = [b"%04d;" % n for n in range(100)]
    with ProxyThread(network, echo, log, 2) as proxy:
        started = proxy.proxy.started_s
        echoed, _ = exchange(proxy.proxy.port, messages, 0.02)
    assert echoed == b"".join(messages)
    table = truth(log)
    delivered = table.delivered_s - started
    assert not np.any((delivered > 0.8) & (delivered < 1.5))  # nothing got through the stall
    held = table[table.cause == "stall"]
    assert len(held) >= 10 and np.all(held.delivered_s - started >= 1.5)
    during = (table.received_s - started > 0.8) & (table.received_s - started < 1.49)
    assert set(table[during & (table.direction == "up")].cause) == {"stall"}


def test_connections_are_numbered_and_join_keys_never_written(echo, tmp_path):
    log = tmp_path / "truth.csv"
    with ProxyThread(parse_network("none"), echo, log, 0) as proxy:
        for path in ("/ws/join/s3cr3t-key", "/console?token=t0ken"):
            request = f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n".encode()
            assert exchange(proxy.proxy.port, [request], 0.0)[0] == request
        wait_for(lambda: (truth(log).bytes == 0).sum() == 4)  # each stream's end, both ways
    table = truth(log)
    firsts = table[(table.direction == "up") & (table.chunk == 0)].set_index("connection")
    assert firsts.request.to_dict() == {
        1: f"GET /ws/join/{fingerprint('s3cr3t-key')} HTTP/1.1",
        2: f"GET /console?token={fingerprint('t0ken')} HTTP/1.1",
    }
    text = log.read_text()
    assert "s3cr3t" not in text and "t0ken" not in text
    ends = table[table.bytes == 0]
    assert sorted(zip(ends.connection, ends.direction, strict=True)) == [
        (1, "down"), (1, "up"), (2, "down"), (2, "up")
    ]  # fmt: skip
    assert log.with_suffix(".json").exists()


def test_a_page_whose_server_is_gone_is_closed(tmp_path):
    with socket.socket() as unused:
        unused.bind(("127.0.0.1", 0))
        gone = unused.getsockname()[:2]
    with (
        ProxyThread(parse_network("10"), gone, tmp_path / "truth.csv", 0) as proxy,
        socket.create_connection(("127.0.0.1", proxy.proxy.port)) as client,
    ):
        client.settimeout(30.0)
        assert client.recv(10) == b""


@pytest.mark.parametrize(
    ("arguments", "says"),
    [
        (["--to", "http://10.1.2.3:8766", "--network", "80"], "--to: 'http://10.1.2.3:8766': the"),
        (["--to", "127.0.0.1", "--network", "80"], "give the lab's address"),
        (["--to", "http://127.0.0.1:8766", "--network", "80+-"], "--network: '80+-' is not"),
        (["--to", "http://127.0.0.1:8766", "--network", "80", "--log", "t.txt"], "end in .csv"),
    ],
)
def test_lab_proxy_refuses_bad_input_in_one_line(arguments, says, capsys):
    assert main(["lab", "proxy", *arguments]) == 2
    error = capsys.readouterr().err.strip()
    assert says in error and "\n" not in error


@pytest.mark.long
def test_lab_proxy_prints_the_address_and_logs_until_interrupted(echo, tmp_path):
    log = tmp_path / "net.csv"
    command = [
        sys.executable, "-c", "from mirror_avatar.console import run; run()", "lab", "proxy",
        "--to", f"http://{echo[0]}:{echo[1]}", "--network", "30+-5", "--log", str(log),
        "--seed", "9",
    ]  # fmt: skip
    with subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    ) as run:
        assert run.stdout is not None
        assert run.stdout.readline().startswith("mirror-avatar lab proxy: network 30+-5, seed 9")
        address = run.stdout.readline().split()[4]
        port = int(address.rsplit(":", 1)[1])
        assert exchange(port, [b"ping"], 0.0)[0] == b"ping"
        wait_for(lambda: len(truth(log)) == 4, timeout=30.0)  # data and end, both ways
        run.send_signal(signal.SIGINT)
        _, error = run.communicate(timeout=30)
    assert run.returncode == 130 and error.strip() == "mirror-avatar: aborted (SIGINT)"
    assert truth(log).delay_ms.between(15, 45).all()

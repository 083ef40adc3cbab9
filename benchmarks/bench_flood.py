"""The live server under a flood from one client: a well-behaved player's round trip and slot.

The server is the real command, ``mirror-avatar play`` with its default limits, in its own
process. A well-behaved player connects from 127.0.0.1 and plays an avatar-follows trial,
sending positions at 60 Hz like a browser; its round trip (a position message to the server's
acknowledgement) is measured first with nothing else connected (the idle baseline), then during
each flood, sent from another loopback address (127.0.0.2) by separate processes:

- ``unpaced``: a trial started, then position messages as fast as the socket takes them;
- ``deaf``: a raw client that starts a trial and sends, but never reads what it is sent;
- ``churn``: trials started and stopped as fast as the server answers;
- ``crowd``: 50 connections held open and reopened whenever the server closes one;
- ``all``: the four at once.

Flooders run at the lowest CPU priority (``nice 19``): they stand for clients on other
machines, whose own CPU cost is not the server's; what they send still reaches the server in
full. Each flood also times how long a newcomer from 127.0.0.1 waits for its slot (connection
to the server's ``ready``) and counts the files the server wrote. Ratios are against the idle
baseline measured in the same run.
"""

from __future__ import annotations

import json
import multiprocessing as mp
import os
import resource
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from websockets.exceptions import ConnectionClosed, InvalidStatus
from websockets.sync.client import ClientConnection, connect

from mirror_avatar.testing import raw_websocket, text_frame

FLOOD_ADDRESS = "127.0.0.2"
CROWD = 50
START = {"type": "start", "mode": "avatar_follows", "participant": "P01", "duration": 120}


def free_port() -> int:
    """Return a TCP port free on loopback now."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def start_server(out: Path, port: int) -> subprocess.Popen[bytes]:
    """Run ``mirror-avatar play`` on ``port`` and wait until it accepts connections."""
    command = [sys.executable, "-c", "from mirror_avatar.console import run; run()", "play",
               "--port", str(port), "--out", str(out)]  # fmt: skip
    server = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1).close()
            return server
        except OSError:
            time.sleep(0.2)
    server.kill()
    raise RuntimeError("the server did not start")


def open_player(url: str, source: str = "127.0.0.1") -> ClientConnection:
    """Connect from ``source`` and wait for the server's ``ready`` message."""
    ws = connect(url, proxy=None, source_address=(source, 0), open_timeout=30)
    ws.recv(timeout=30)
    return ws


def play_trial(url: str, n: int) -> np.ndarray:
    """Round trips (s) of ``n`` positions sent at 60 Hz during an avatar-follows trial.

    Positions are sent from the start, through the countdown, as a browser does; the round
    trips are those after the server's ``go``.
    """
    times, seq, playing = [], 0, False
    with open_player(url) as ws:
        ws.send(json.dumps(START))
        while len(times) < n:
            seq += 1
            sent = time.perf_counter()
            ws.send(json.dumps({"type": "position", "seq": seq, "x": 0.1, "rtt": None}))
            while (reply := json.loads(ws.recv(timeout=30))).get("seq") != seq:
                playing = playing or reply["type"] == "go"
            if playing:
                times.append(time.perf_counter() - sent)
            time.sleep(max(0.0, 1 / 60 - (time.perf_counter() - sent)))
        ws.send(json.dumps({"type": "stop"}))
    return np.asarray(times)


def slot_waits(url: str, count: int) -> list[float]:
    """Seconds a newcomer waits for ``ready``, ``count`` times (inf: refused)."""
    waits = []
    for _ in range(count):
        began = time.perf_counter()
        try:
            open_player(url).close()
            waits.append(time.perf_counter() - began)
        except (ConnectionClosed, InvalidStatus, OSError, TimeoutError):
            waits.append(float("inf"))
        time.sleep(0.5)
    return waits


def flood_unpaced(url: str, port: int) -> None:
    """Start a trial, then send positions unpaced."""
    with open_player(url, FLOOD_ADDRESS) as ws:
        ws.send(json.dumps(START))
        _send_forever(ws.send, json.dumps({"type": "position", "seq": 1, "x": 0.0}))


def flood_deaf(url: str, port: int) -> None:
    """Start a trial from a raw client and send positions, never reading."""
    sock = raw_websocket(port, FLOOD_ADDRESS, receive_buffer=4096)
    sock.sendall(text_frame(json.dumps(START)))
    sock.settimeout(10)
    _send_forever(sock.sendall, text_frame(json.dumps({"type": "position", "seq": 1, "x": 0.0})))


def flood_churn(url: str, port: int) -> None:
    """Start and stop trials as fast as the server answers."""
    with open_player(url, FLOOD_ADDRESS) as ws:
        while True:
            ws.send(json.dumps(START))
            ws.send(json.dumps({"type": "stop"}))
            ws.recv(timeout=10)
            _report(2)


def flood_crowd(url: str, port: int) -> None:
    """Hold `CROWD` connections open, reopening each one the server closes."""
    held: list[socket.socket] = []
    while True:
        held = [sock for sock in held if _still_open(sock)]
        while len(held) < CROWD:
            sock = raw_websocket(port, FLOOD_ADDRESS)
            sock.setblocking(False)
            held.append(sock)
            _report(1)
        time.sleep(0.05)


FLOODERS: dict[str, Callable[[str, int], None]] = {
    "unpaced": flood_unpaced,
    "deaf": flood_deaf,
    "churn": flood_churn,
    "crowd": flood_crowd,
}


def _still_open(sock: socket.socket) -> bool:
    """Drain what ``sock`` received; False (and closed) once the server closed it."""
    try:
        while data := sock.recv(65536):
            del data
        sock.close()
        return False
    except BlockingIOError:
        return True
    except OSError:
        sock.close()
        return False


def _send_forever(send: Callable[[Any], Any], message: Any) -> None:
    """Send ``message`` as fast as ``send`` takes it, counting every thousand."""
    sent = 0
    while True:
        send(message)
        sent += 1
        if sent % 1000 == 0:
            _report(1000)


_counter: Any = None


def _report(actions: int) -> None:
    with _counter.get_lock():
        _counter.value += actions


def _flooder(name: str, url: str, port: int, counter: Any) -> None:
    """Run one flood forever at the lowest priority, starting over whenever it is cut off."""
    global _counter
    _counter = counter
    os.nice(19)
    while True:
        try:
            FLOODERS[name](url, port)
        except (ConnectionClosed, InvalidStatus, OSError, TimeoutError):
            time.sleep(0.01)


def measure(url: str, port: int, out: Path, flood: list[str], n: int) -> dict[str, Any]:
    """Round trips and slot waits while the ``flood`` processes run."""
    counter = mp.Value("q", 0)
    processes = [mp.Process(target=_flooder, args=(name, url, port, counter), daemon=True)
                 for name in flood]  # fmt: skip
    files_before = sum(1 for _ in out.rglob("*"))
    for process in processes:
        process.start()
    try:
        time.sleep(2.0 if flood else 0.0)
        rtt = play_trial(url, n)
        waits = slot_waits(url, 5)
    finally:
        for process in processes:
            process.kill()
            process.join()
    return {
        "rtt": rtt,
        "waits": waits,
        "actions": counter.value,
        "files": sum(1 for _ in out.rglob("*")) - files_before,
    }


def run(quick: bool) -> list[dict]:
    n = 240 if quick else 1800
    scenarios = {"idle": [], **{name: [name] for name in FLOODERS}, "all": list(FLOODERS)}
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        out, port = Path(folder) / "recordings", free_port()
        server = start_server(out, port)
        url = f"ws://127.0.0.1:{port}/ws"
        try:
            results = {}
            for name, flood in scenarios.items():
                print(f"  flood {name} ...", file=sys.stderr, flush=True)
                results[name] = measure(url, port, out, flood, n)
        finally:
            server.terminate()
            server.wait(30)
    idle = results["idle"]["rtt"]
    for name, result in results.items():
        rows += _rows(name, result, idle, n)
    return rows


def _rows(name: str, result: dict[str, Any], idle: np.ndarray, n: int) -> list[dict]:
    """Describe one scenario: median and 95th percentile round trips, and its slot waits."""
    waits = result["waits"]
    note = (
        f"{n} positions at 60 Hz; flood: {result['actions']:,} messages/connections; "
        f"{result['files']} files written; newcomer waits "
        + ", ".join("refused" if w == float("inf") else f"{w * 1e3:.0f} ms" for w in waits)
    )
    rows = []
    for label, q in (("median", 50), ("95th percentile", 95)):
        value = float(np.percentile(result["rtt"], q)) * 1e3
        base = float(np.percentile(idle, q)) * 1e3
        rows.append(
            {
                "name": f"round trip under flood '{name}', {label}",
                "value": round(value, 3),
                "unit": "ms",
                "baseline": f"idle {base:.3f} ms",
                "ratio": round(value / base, 2),
                "peak_memory_mb": round(_peak_mb(), 1),
                "note": note if q == 95 else f"slowest newcomer {max(waits):.2f} s",
            }
        )
    return rows


def _peak_mb() -> float:
    """Peak resident memory of the children so far (MB): the server and the flooders."""
    return resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024

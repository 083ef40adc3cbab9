"""Clients of a real lab server for the benchmarks: the server process and participants' pages.

`start_lab` runs the real command, ``mirror-avatar lab``, in its own process (`stop_process`
reads its peak resident memory before ending it). `page_client` plays a participant's page over
a WebSocket as a browser does: a position at `SEND_RATE` on absolute deadlines, each unique to
its client and sequence number, pongs for the server's pings, every frame stamped on arrival
(`PageLog`). `input_to_frame` matches the positions to the frames of the samples that used
them, through the trial's ``inputs.csv``.
"""

from __future__ import annotations

import asyncio
import collections
import functools
import json
import math
import os
import queue
import resource
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import httpx
import numpy as np
from websockets.asyncio.client import ClientConnection, connect
from websockets.exceptions import ConnectionClosed

from mirror_avatar.testing import raw_websocket

SEND_RATE = 60.0
"""Positions a page sends per second (a browser's animation frames)."""

CROWD = 50
"""Connections one flooding process holds open at once."""

CONNECT_TIMEOUT = 0.2
"""Seconds a flooding process waits for a connection (the server's queue may be full)."""


def socket_url(link: str) -> str:
    """Return the WebSocket URL of a participant's join link."""
    return link.replace("http://", "ws://").replace("/join/", "/ws/join/")


def start_process(
    command: list[str], log: Path, marker: str, files: int | None = None
) -> tuple[subprocess.Popen, str]:
    """Start ``command`` and return it with the first stdout line starting with ``marker``.

    Its stdout keeps being drained (into ``log``, with its stderr) so that it never blocks.
    ``files`` sets its limit of open file descriptors (``ulimit -n``; default: this process's).
    """
    limit = None if files is None else functools.partial(_limit_files, files)
    with log.open("ab") as errors:
        process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=errors, text=True,
                                   env={**os.environ, "PYTHONUNBUFFERED": "1"},
                                   preexec_fn=limit)  # fmt: skip
    lines: queue.Queue[str] = queue.Queue()
    threading.Thread(target=_drain, args=(process, lines, log), daemon=True).start()
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        try:
            line = lines.get(timeout=1)
        except queue.Empty:
            continue
        if line.startswith(marker):
            return process, line
        if not line:
            break
    process.kill()
    raise RuntimeError(f"{command[:4]} did not start: see {log.read_text()[-2000:]}")


def _limit_files(files: int) -> None:
    """Set this process's soft limit of open file descriptors (in a child, before its exec)."""
    resource.setrlimit(
        resource.RLIMIT_NOFILE, (files, resource.getrlimit(resource.RLIMIT_NOFILE)[1])
    )


def _drain(process: subprocess.Popen, lines: queue.Queue[str], log: Path) -> None:
    """Pass ``process``'s stdout lines on, and append them to ``log``; an empty line at EOF."""
    assert process.stdout is not None
    with log.open("a") as copy:
        for line in process.stdout:
            copy.write(line)
            lines.put(line)
    lines.put("")


def stop_process(process: subprocess.Popen) -> float:
    """Return the peak resident memory (MB) of ``process``, then terminate it."""
    peak = 0.0
    try:
        for line in Path(f"/proc/{process.pid}/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                peak = int(line.split()[1]) / 1024
    except OSError:
        pass
    process.terminate()
    try:
        process.wait(30)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()
    return peak


def start_lab(out: Path, log: Path, files: int | None = None) -> tuple[subprocess.Popen, str, str]:
    """Run ``mirror-avatar lab --port 0``; return it, its base URL and the researcher's token.

    ``files``: its limit of open file descriptors (as `start_process`).
    """
    command = [sys.executable, "-c", "from mirror_avatar.console import run; run()", "lab",
               "--port", "0", "--out", str(out), "--no-lsl"]  # fmt: skip
    process, line = start_process(command, log, "console: ", files)
    url = line.split()[1]
    base, token = url.split("/console?token=")
    return process, base, token


def position(seq: int, phase: float) -> str:
    """Return position message ``seq``: a 0.5 Hz sine, unique to the client and ``seq``."""
    x = 0.3 * math.sin(math.pi * seq / SEND_RATE + phase) + 1e-9 * seq
    return json.dumps({"type": "position", "seq": seq, "x": x})


async def send_positions(ws: ClientConnection, phase: float, sent: dict[int, float]) -> None:
    """Send positions at `SEND_RATE` on absolute deadlines, noting when each one left."""
    start, seq = time.monotonic(), 0
    while True:
        await asyncio.sleep(max(0.0, start + seq / SEND_RATE - time.monotonic()))
        sent[seq] = time.monotonic()
        await ws.send(position(seq, phase))
        seq += 1


class PageLog:
    """What one participant's client saw: positions sent, frames received (sample, time)."""

    def __init__(self, label: str) -> None:
        self.label = label
        self.sent: dict[int, float] = {}
        self.frames: list[tuple[int, float]] = []
        self.own_null = 0


async def page_client(url: str, log: PageLog, phase: float) -> None:
    """Join by ``url``, send positions at 60 Hz, answer pings, note frames until the end."""
    async with connect(url, proxy=None, open_timeout=30) as ws:
        sender = asyncio.create_task(send_positions(ws, phase, log.sent))
        try:
            async for text in ws:
                message = json.loads(text)
                kind = message["type"]
                if kind == "ping":
                    await ws.send(json.dumps({"type": "pong", "id": message["id"],
                                              "late_frames": 0}))  # fmt: skip
                elif kind == "frame":
                    log.frames.append((message["k"], time.monotonic()))
                    log.own_null += message["x"][0] is None
                elif kind == "end":
                    sender.cancel()
        except ConnectionClosed:
            pass
        finally:
            sender.cancel()


async def wait_joined(api: httpx.AsyncClient, sid: str) -> None:
    """Wait until every person's page has joined the session."""
    for _ in range(300):
        status = (await api.get(f"/api/sessions/{sid}")).json()
        if all(slot.get("connected", True) for slot in status["slots"]):
            return
        await asyncio.sleep(0.1)
    raise RuntimeError("the clients did not join")


def input_to_frame(log: PageLog, inputs: list[dict[str, str]]) -> np.ndarray:
    """When each sampled position was sent, and the seconds until its sample's frame arrived.

    A position is sampled at the first sample whose ``seq_<label>`` names it; its frame is the
    first frame received for that sample or a later one (a superseded frame is never sent).

    Returns
    -------
    numpy.ndarray
        Shape (n, 2): the sending time (`time.monotonic`, s) and the latency (s) of each.
    """
    first: dict[int, int] = {}
    for k, row in enumerate(inputs):
        first.setdefault(int(row[f"seq_{log.label}"]), k)
    arrivals = sorted(log.frames)
    samples = [k for k, _ in arrivals]
    pairs = []
    for seq, k in first.items():
        i = int(np.searchsorted(samples, k))
        if seq in log.sent and i < len(arrivals):
            pairs.append((log.sent[seq], arrivals[i][1] - log.sent[seq]))
    return np.asarray(pairs, dtype=float).reshape(-1, 2)


def flood(port: int, sources: list[str], seconds: float, paths: list[str]) -> int:
    """Open WebSockets to ``paths`` from ``sources`` in turn for ``seconds``, as fast as they open.

    At most `CROWD` stay open (unread); each one beyond closes the oldest. Returns how many
    handshakes were sent (the server's rate gate refuses most of a flood's). A connection that
    cannot be made (the server's queue is full) is given up after the default socket timeout.
    """
    held: collections.deque[socket.socket] = collections.deque()
    opened, end = 0, time.monotonic() + seconds
    while time.monotonic() < end:
        for path in paths:
            try:
                held.append(raw_websocket(port, sources[opened % len(sources)], path=path))
                opened += 1
            except OSError:
                time.sleep(0.001)
        while len(held) > CROWD:
            held.popleft().close()
    for sock in held:
        sock.close()
    return opened


PARTIAL_REQUESTS = (
    b"GET /api/sessions HTTP/1.1\r\nHost: 127.0.0.1\r\nX-",
    b"GET /join/",
    b"POST /api/sessions HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
    b"Content-Length: 100000\r\n\r\n{",
)
"""Requests a half-open client starts and never finishes: headers, request line, body."""


def hold(port: int, sources: list[str], seconds: float, most: int) -> tuple[int, int]:
    """Hold up to ``most`` half-sent requests (`PARTIAL_REQUESTS`) from ``sources`` in turn.

    Every second, each held request is sent one more byte (slowloris); a connection the server
    closed is replaced. Returns how many connections were opened and how many the server closed.
    """
    held: list[socket.socket] = []
    opened = closed = 0
    end, trickle = time.monotonic() + seconds, time.monotonic() + 1.0
    while time.monotonic() < end:
        if len(held) < most:
            try:
                sock = socket.create_connection(
                    ("127.0.0.1", port), source_address=(sources[opened % len(sources)], 0)
                )
                sock.sendall(PARTIAL_REQUESTS[opened % len(PARTIAL_REQUESTS)])
                sock.setblocking(False)  # `_still_open` must not wait on it
                held.append(sock)
                opened += 1
            except OSError:
                time.sleep(0.001)
        else:
            time.sleep(0.01)
        if time.monotonic() >= trickle:
            trickle += 1.0
            alive = [sock for sock in held if _still_open(sock)]
            closed += len(held) - len(alive)
            held = alive
    for sock in held:
        sock.close()
    return opened, closed


def _still_open(sock: socket.socket) -> bool:
    """Send one more byte of a half-sent request; whether the server still holds it open."""
    try:
        if sock.recv(1, socket.MSG_PEEK) == b"":
            raise ConnectionResetError
    except BlockingIOError:
        pass
    except OSError:
        sock.close()
        return False
    try:
        sock.send(b"a")
    except BlockingIOError:
        pass
    except OSError:
        sock.close()
        return False
    return True


def main(argv: list[str]) -> None:
    """Run a client in a process of its own (the hostile clients of ``bench_hostile``).

    ``page URL``: play a participant's page until its connection closes.
    ``flood PORT SOURCES SECONDS PATH...``: `flood` (SOURCES comma-separated); print ``ready``
    before it begins and the count at the end (the caller runs it at the lowest priority,
    ``nice 19``).
    ``hold PORT SOURCES SECONDS MOST``: `hold`; print ``ready``, then its two counts.
    """
    if argv[0] == "page":
        asyncio.run(page_client(argv[1], PageLog("page"), 0.0))
    elif argv[0] == "flood":
        socket.setdefaulttimeout(CONNECT_TIMEOUT)
        print("ready", flush=True)
        print(flood(int(argv[1]), argv[2].split(","), float(argv[3]), argv[4:]), flush=True)
    elif argv[0] == "hold":
        socket.setdefaulttimeout(CONNECT_TIMEOUT)
        print("ready", flush=True)
        opened, closed = hold(int(argv[1]), argv[2].split(","), float(argv[3]), int(argv[4]))
        print(opened, closed, flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])

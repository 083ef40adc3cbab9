"""A good participant of a lab session beside hostile clients: its frames' latency and gaps.

The server is the real command, ``mirror-avatar lab``, in its own process on loopback. A good
participant's page (`probe_clients.page_client`, in this process) plays a group session with
a ``bundled:slow`` avatar and a second person's slot, sending its pointer at 60 Hz. For each
position it measures the input-to-frame time (from sending it to receiving the frame of the
first sample that used it, matched through the trial's ``inputs.csv``) and, from the frames'
arrival times, the gaps between frames (the control period T = 30 ms when all is well).

Hostile clients come one after another during the same trial; for each, the good page's
input-to-frame p50 and p95 and its longest frame gap are reported in three windows: before
(`WINDOW` s), during, and after (`WINDOW` s):

- ``connection flood``: four processes (``nice 19``, from 127.0.0.2-5) open WebSockets as
  fast as they open, to an unknown join key and to a real one of another session, holding 50
  each unread and closing the oldest; meanwhile a newcomer joins that session by its other
  link every half second, and how long it waits for its welcome is noted;
- ``40-address flood``: the same from 40 addresses (127.0.2.1-40, ten per process);
- ``half-open requests``: four processes (normal priority) from 140 addresses (127.0.1.1-140)
  open connections and send part of a request (a request line, headers without their end, or
  a JSON body shorter than its declared length), a byte more each second, up to `HALF_OPEN`
  at once, replacing those the server closes; the server runs at ``ulimit -n 1024``
  (`SERVER_FILES`) throughout;
- ``slow reader``: a page that never reads its socket (4 KB receive buffer) takes the second
  person's slot of the good participant's own session;
- ``frozen page``: the page of another running session, a process of its own, is stopped
  (SIGSTOP) mid-trial and continued (SIGCONT) at the end of the window;
- ``FIFO specs``: seven session-create requests at once whose avatar specs are FIFOs
  (``os.mkfifo``, named ``.npz``), repeated for the window;
- ``huge spec``: session-create requests whose avatar spec is a 1 GiB file (a sparse file made
  with ``truncate``: its size is real, its blocks are not), as ``.npz`` and ``.csv`` in turn;
- ``slow avatar``: session-create requests whose plan holds eight of the largest legal DQN
  avatars (8 hidden layers of 1024 units), timed by the server and refused as too slow;
- ``FIFO resume``, ``huge resume``, ``nested resume``: requests resuming a participant's run
  of the protocol loaded from the console (`RESUME_PROTOCOL`) whose folder's ``study.json`` is
  a FIFO, a 600 MB file (its JSON padded with real spaces), or JSON nested 200 000 deep.

The researcher's API is asked every `API_INTERVAL` s on a new connection throughout
(`ApiProbe`); each window reports its median and longest answer. The baseline of each case is
its own "before" window. The server's peak resident memory, the
machine's load average and, per window, how long the server's main thread waited for a CPU
(`CpuWaits`: time it could not run at all) are reported too.
"""

from __future__ import annotations

import asyncio
import collections
import csv
import functools
import io
import math
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import httpx
import numpy as np
from websockets.asyncio.client import connect
from websockets.exceptions import WebSocketException

from mirror_avatar.deep.player import MAX_LAYERS, MAX_UNITS, DeepCyberPlayer
from mirror_avatar.lab.files import STUDY_FILE
from mirror_avatar.testing import raw_websocket

sys.path.insert(0, str(Path(__file__).parent))
from probe_clients import (  # noqa: E402
    PageLog,
    input_to_frame,
    page_client,
    socket_url,
    start_lab,
    stop_process,
    wait_joined,
)

CLIENTS = Path(__file__).parent / "probe_clients.py"
GAP_BOUND_MS = 100.0
"""Longest frame gap the good participant may see (ms)."""

WINDOW = 3.0
"""Seconds of the "before" and "after" windows (quick runs; full runs double them)."""

FIFOS = 7
"""FIFO specs asked for at once."""

FLOOD_ADDRESSES = ("127.0.0.2", "127.0.0.3", "127.0.0.4", "127.0.0.5")
"""Loopback addresses of the flooding processes (the server limits rates per address)."""

WIDE_FLOOD_ADDRESSES = tuple(f"127.0.2.{k}" for k in range(1, 41))
"""The 40 loopback addresses of the wide connection flood (shared by `FLOOD_PROCESSES`)."""

HALF_OPEN_ADDRESSES = tuple(f"127.0.1.{k}" for k in range(1, 141))
"""The 140 loopback addresses of the half-open requests (shared by `FLOOD_PROCESSES`)."""

HALF_OPEN = 18_000
"""Half-sent requests the half-open case tries to hold at once (all its processes)."""

FLOOD_PROCESSES = 4
"""Processes sending the wide flood, and those holding the half-open requests."""

SERVER_FILES = 1024
"""The lab server's limit of open file descriptors (``ulimit -n``: a common default)."""

API_INTERVAL = 0.25
"""Seconds between the researcher's probing API requests (each on a new connection)."""

API_TIMEOUT = 5.0
"""Seconds a probing API request is given before it counts as unanswered."""

BIG_AVATARS = 8
"""The largest legal DQN avatars in the too slow plan."""

CPU_WAIT_INTERVAL = 0.05
"""Seconds between samples of the server's wait for a CPU."""

BATCH_INTERVAL = 0.5
"""Seconds between the batches of session-create requests of a hostile case."""

AVATAR = "bundled:slow"
"""The avatar of the good session and of the frozen page's session."""

RESUME_PROTOCOL = """title = "resume"
seed = 1

[[blocks]]
name = "main"

[[blocks.conditions]]
name = "together"
game = "joint"
players = [{ label = "P1", kind = "person" }, { label = "P2", kind = "person" }]
trials = 1
duration = 10
"""
"""The protocol loaded from the console (as ``resume.toml``) whose participants' runs resume."""

RESUMES = {"FIFO resume": 1, "huge resume": 2, "nested resume": 3}
"""The participant whose folder each resume case holds."""

PADDED_BYTES = 600 * 2**20
"""Size of the whitespace-padded ``study.json`` (bytes)."""

NESTED = 200_000
"""Depth of the nested ``study.json``."""


def lowest() -> None:
    """Run at the lowest CPU priority (a flooding process: another machine's clients)."""
    os.nice(19)


def person(label: str) -> dict[str, str]:
    return {"label": label, "kind": "human"}


def avatar(label: str, spec: str) -> dict[str, str]:
    return {"label": label, "kind": "avatar", "spec": spec}


@dataclass
class Mark:
    """One hostile client's window: its case, when it was called, began and ended, what it did.

    A client that must start first (processes) begins after it was called; the "before"
    window ends when it was called, the "during" window starts when it began.
    """

    case: str
    called: float
    began: float
    ended: float
    note: str


class Hostiles:
    """The hostile clients, each run for ``seconds`` against the lab server at ``base``.

    Each returns a note saying what it did and how the server answered.
    """

    def __init__(self, api: httpx.AsyncClient, base: str, folder: Path, out: Path) -> None:
        self.api = api
        self.out = out
        self.port = int(urlsplit(base).port or 80)
        self.reader_path = ""  # the good session's second person's socket path
        self.flood_target = ""  # a real join key's socket path, of a session never started
        self.newcomer = ""  # the other join link of that session (a page's URL)
        self.frozen: subprocess.Popen[bytes] | None = None
        self.fifos = [folder / f"fifo-{k}.npz" for k in range(FIFOS)]
        self.huge = [folder / "huge.npz", folder / "huge.csv"]
        self.big = folder / "big.npz"
        self.began: float | None = None  # when a hostile client that needs to start began

    def prepare(self) -> None:
        """Make the FIFOs, the sparse 1 GiB files and the largest legal DQN avatar."""
        for fifo in self.fifos:
            os.mkfifo(fifo)
        for path in self.huge:
            with path.open("wb") as file:
                file.truncate(2**30)
        big = DeepCyberPlayer(hidden=(MAX_UNITS,) * MAX_LAYERS)
        big.initialise_policy(0)
        big.save(self.big)
        folders = {case: self.out / f"resume-p{n:03d}" for case, n in RESUMES.items()}
        schedules = {case: folder / STUDY_FILE for case, folder in folders.items()}
        for schedule in schedules.values():
            schedule.parent.mkdir(parents=True)
        os.mkfifo(schedules["FIFO resume"])
        with schedules["huge resume"].open("wb") as file:
            file.write(b'{"seed": 1, "participant": 2}')
            spaces = b" " * 2**24
            for _ in range(PADDED_BYTES // len(spaces)):
                file.write(spaces)
        schedules["nested resume"].write_text("[" * NESTED + "]" * NESTED)

    async def connection_flood(self, seconds: float) -> str:
        """Flood the server with connections from `FLOOD_ADDRESSES` (a process each)."""
        return await self._flood(seconds, [[source] for source in FLOOD_ADDRESSES])

    async def wide_flood(self, seconds: float) -> str:
        """Flood the server with connections from the 40 `WIDE_FLOOD_ADDRESSES`."""
        return await self._flood(seconds, _shares(WIDE_FLOOD_ADDRESSES))

    async def _flood(self, seconds: float, sources: list[list[str]]) -> str:
        """Flood from ``sources`` (a process each), a newcomer joining every half second."""
        paths = [self.flood_target, "/ws/join/not-a-key"]
        floods = await self._processes("flood", seconds, sources, paths)
        waits = []
        while time.monotonic() < self.began + seconds - 1.0:
            await asyncio.sleep(0.5)
            waits.append(await self._join_wait())
        counts = [int((await flood.communicate())[0] or 0) for flood in floods]
        joins = ", ".join("refused" if math.isinf(wait) else f"{wait * 1e3:.0f}" for wait in waits)
        return (
            f"{sum(counts):,} handshakes from {len(floods)} processes and "
            f"{sum(map(len, sources))} addresses; a newcomer joining another session meanwhile "
            f"waited {joins} ms for its welcome"
        )

    async def half_open(self, seconds: float) -> str:
        """Hold up to `HALF_OPEN` half-sent requests from the 140 `HALF_OPEN_ADDRESSES`.

        The holding processes run at normal priority: they mostly sleep, and at the lowest
        one a busy machine left them too little time to open their connections.
        """
        sources = _shares(HALF_OPEN_ADDRESSES)
        most = [str(HALF_OPEN // len(sources))]
        holders = await self._processes("hold", seconds, sources, most, priority=None)
        answers = [(await holder.communicate())[0].split() for holder in holders]
        opened, closed = (sum(int(answer[k]) for answer in answers) for k in (0, 1))
        return (
            f"{opened:,} half-sent requests (headers, request line, body; a byte more each "
            f"second) from {len(HALF_OPEN_ADDRESSES)} addresses, {closed:,} closed by the server"
        )

    async def _processes(
        self,
        kind: str,
        seconds: float,
        sources: list[list[str]],
        rest: list[str],
        priority: Callable[[], None] | None = lowest,
    ) -> list[asyncio.subprocess.Process]:
        """Start a `probe_clients` process of ``kind`` per list of sources; note when all began.

        ``priority`` is run in each before it starts (default `lowest`).
        """
        processes = []
        for share in sources:
            command = [str(CLIENTS), kind, str(self.port), ",".join(share), str(seconds), *rest]
            processes.append(
                await asyncio.create_subprocess_exec(
                    sys.executable, *command, stdout=asyncio.subprocess.PIPE, preexec_fn=priority
                )
            )
        for process in processes:
            assert process.stdout is not None
            await process.stdout.readline()  # its imports done: it begins
        self.began = time.monotonic()
        return processes

    async def _join_wait(self) -> float:
        """Seconds from opening the newcomer's join link to its first message (the welcome).

        ``inf`` when its connection was closed or refused before.
        """
        began = time.monotonic()
        try:
            async with connect(self.newcomer, proxy=None, open_timeout=30) as ws:
                await ws.recv()
        except (OSError, WebSocketException):
            return math.inf
        return time.monotonic() - began

    async def slow_reader(self, seconds: float) -> str:
        """Join the good session's second slot and never read."""
        sock = await asyncio.to_thread(
            raw_websocket, self.port, "127.0.0.1", 4096, self.reader_path
        )
        try:
            await asyncio.sleep(seconds)
        finally:
            sock.close()
        return "joined the good session's second slot, 4 KB receive buffer, never read"

    async def frozen_page(self, seconds: float) -> str:
        """Stop another session's page process, then continue it."""
        assert self.frozen is not None
        os.kill(self.frozen.pid, signal.SIGSTOP)
        try:
            await asyncio.sleep(seconds)
        finally:
            os.kill(self.frozen.pid, signal.SIGCONT)
        return "another session's page process stopped (SIGSTOP), then continued"

    async def fifo_specs(self, seconds: float) -> str:
        """Ask for sessions whose avatar specs are FIFOs, `FIFOS` at once."""
        plans = [self._plan([avatar("A1", str(fifo))]) for fifo in self.fifos]
        return await self._refused(seconds, lambda: [self._create(plan) for plan in plans])

    async def huge_spec(self, seconds: float) -> str:
        """Ask for sessions whose avatar spec is a 1 GiB file."""
        plans = [self._plan([avatar("A1", str(path))]) for path in self.huge]
        return await self._refused(seconds, lambda: [self._create(plan) for plan in plans])

    async def slow_avatar(self, seconds: float) -> str:
        """Ask for a session of `BIG_AVATARS` of the largest legal DQN avatars."""
        big = [avatar(f"A{k}", str(self.big)) for k in range(BIG_AVATARS)]
        plan = self._plan(big, condition="group")
        return await self._refused(seconds, lambda: [self._create(plan)])

    async def resume(self, case: str, seconds: float) -> str:
        """Ask to resume the run of the participant whose ``study.json`` is ``case``'s."""
        body = {"participant": RESUMES[case]}

        async def ask() -> tuple[int, str]:
            answer = await self.api.post("/api/sessions", json=body)
            return answer.status_code, str(answer.json().get("error", answer.text))

        return await self._refused(seconds, lambda: [ask()])

    def _plan(self, avatars: list[dict[str, str]], condition: str = "joint") -> dict[str, Any]:
        return {"condition": condition, "duration": 10.0, "players": [person("P1"), *avatars]}

    async def _create(self, plan: dict[str, Any]) -> tuple[int, str]:
        answer = await self.api.post("/api/sessions", json=plan)
        try:
            return answer.status_code, str(answer.json().get("error", ""))
        except ValueError:
            return answer.status_code, answer.text

    async def _refused(
        self, seconds: float, requests: Callable[[], list[Awaitable[tuple[int, str]]]]
    ) -> str:
        """Send the requests at once, again every `BATCH_INTERVAL` s until ``seconds`` passed.

        A batch not answered within the interval is followed at once by the next. Returns a
        description of the answers.
        """
        answers: list[tuple[int, str]] = []
        slowest, end = 0.0, time.monotonic() + seconds
        while (began := time.monotonic()) < end:
            answers += await asyncio.gather(*requests())
            slowest = max(slowest, time.monotonic() - began)
            await asyncio.sleep(max(0.0, began + BATCH_INTERVAL - time.monotonic()))
        codes = sorted({code for code, _ in answers})
        return (
            f"{len(answers)} requests, answered {codes} in at most {slowest * 1e3:.0f} ms: "
            f"{answers[-1][1]}"
        )


def _shares(addresses: tuple[str, ...]) -> list[list[str]]:
    """Split ``addresses`` between `FLOOD_PROCESSES` processes."""
    return [list(addresses[k::FLOOD_PROCESSES]) for k in range(FLOOD_PROCESSES)]


class ApiProbe:
    """The researcher's API, asked every `API_INTERVAL` s on a new connection: answer times.

    Each request (``GET /api/sessions`` with the token) opens a connection of its own, as a
    console reloaded or a script would, so that a server refusing or not accepting connections
    shows. `samples` holds (sending time, seconds to the answer or ``inf`` when none came
    within `API_TIMEOUT` s or the connection failed).
    """

    def __init__(self, base: str, token: str) -> None:
        self.samples: list[tuple[float, float]] = []
        self.client = httpx.AsyncClient(
            base_url=base,
            headers={"Authorization": f"Bearer {token}"},
            timeout=API_TIMEOUT,
            limits=httpx.Limits(max_keepalive_connections=0),
        )

    async def run(self) -> None:
        """Ask until cancelled."""
        async with self.client:
            while True:
                began = time.monotonic()
                try:
                    (await self.client.get("/api/sessions")).raise_for_status()
                    self.samples.append((began, time.monotonic() - began))
                except httpx.HTTPError:
                    self.samples.append((began, float("inf")))
                await asyncio.sleep(max(0.0, began + API_INTERVAL - time.monotonic()))

    def within(self, low: float, high: float) -> tuple[float, float, int]:
        """Median and longest answer (ms) of the requests sent in [low, high), and their count."""
        times = np.array([t for began, t in self.samples if low <= began < high]) * 1e3
        if times.size == 0:
            return float("nan"), float("nan"), 0
        return float(np.median(times)), float(times.max()), int(times.size)


class CpuWaits:
    """Samples of how long a process's main thread has waited for a CPU (Linux ``schedstat``).

    A thread that is ready to run but finds every core busy waits on the kernel's run queue;
    ``/proc/PID/task/PID/schedstat`` counts that time. Sampled every `CPU_WAIT_INTERVAL` s in a
    thread of this process, so that a window's frame gaps can be set beside the time the
    server could not run at all, whatever it was doing.
    """

    def __init__(self, pid: int) -> None:
        self.path = Path(f"/proc/{pid}/task/{pid}/schedstat")
        self.samples: list[tuple[float, float]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)
        self._thread.start()

    def _sample(self) -> None:
        while not self._stop.wait(CPU_WAIT_INTERVAL):
            try:
                waited = int(self.path.read_text().split()[1]) / 1e6
            except (OSError, IndexError, ValueError):
                return
            self.samples.append((time.monotonic(), waited))

    def stop(self) -> None:
        """Stop sampling."""
        self._stop.set()
        self._thread.join()

    def within(self, low: float, high: float) -> float:
        """Milliseconds the main thread waited for a CPU between ``low`` and ``high``."""
        times = np.array([t for t, _ in self.samples])
        waits = np.array([w for _, w in self.samples])
        if times.size < 2:
            return float("nan")
        return float(np.interp(high, times, waits) - np.interp(low, times, waits))


async def create(api: httpx.AsyncClient, plan: dict[str, Any]) -> dict[str, Any]:
    answer = await api.post("/api/sessions", json=plan)
    answer.raise_for_status()
    return dict(answer.json())


async def scenario(
    base: str, token: str, folder: Path, window: float, only: list[str]
) -> dict[str, Any]:
    """Play the good session through every hostile case; return its log, marks and inputs.

    The researcher's API is probed throughout (`ApiProbe`).
    """
    headers = {"Authorization": f"Bearer {token}"}
    probe = ApiProbe(base, token)
    async with httpx.AsyncClient(base_url=base, headers=headers, timeout=300) as api:
        hostiles = Hostiles(api, base, folder, folder / "lab")
        await asyncio.to_thread(hostiles.prepare)
        body = {"name": "resume.toml", "text": RESUME_PROTOCOL}
        (await api.post("/api/protocol", json=body)).raise_for_status()
        cases: list[tuple[str, Callable[[float], Awaitable[str]]]] = [
            ("connection flood", hostiles.connection_flood),
            ("40-address flood", hostiles.wide_flood),
            ("half-open requests", hostiles.half_open),
            ("slow reader", hostiles.slow_reader),
            ("frozen page", hostiles.frozen_page),
            ("FIFO specs", hostiles.fifo_specs),
            ("huge spec", hostiles.huge_spec),
            ("slow avatar", hostiles.slow_avatar),
            *((case, functools.partial(hostiles.resume, case)) for case in RESUMES),
        ]
        cases = [(case, hostile) for case, hostile in cases if not only or case in only]
        duration = len(cases) * (4 * window + 60.0) + 30.0  # the researcher stops it
        people = [person("G1"), person("S1"), avatar("A1", AVATAR)]
        good = await create(api, {"condition": "group", "graph": "complete", "seed": 1,
                                  "duration": duration, "players": people})  # fmt: skip
        frozen = await create(api, {"condition": "joint", "duration": duration,
                                    "players": [person("F1"), avatar("A1", AVATAR)]})  # fmt: skip
        target = await create(api, {"condition": "joint", "duration": duration,
                                    "players": [person("T1"), person("T2")]})  # fmt: skip
        hostiles.reader_path = urlsplit(socket_url(good["links"]["S1"])).path
        hostiles.flood_target = urlsplit(socket_url(target["links"]["T1"])).path
        hostiles.newcomer = socket_url(target["links"]["T2"])
        log = PageLog("G1")
        page = asyncio.create_task(page_client(socket_url(good["links"]["G1"]), log, 0.0))
        probing = asyncio.create_task(probe.run())
        hostiles.frozen = subprocess.Popen(
            [sys.executable, str(CLIENTS), "page", socket_url(frozen["links"]["F1"])]
        )
        try:
            await wait_joined(api, frozen["id"])
            (await api.post(f"/api/sessions/{frozen['id']}/start", json={})).raise_for_status()
            (await api.post(f"/api/sessions/{good['id']}/start", json={"force": True})
             ).raise_for_status()  # fmt: skip
            while len(log.frames) < 30:
                await asyncio.sleep(0.1)
            marks = []
            for case, hostile in cases:
                print(f"  {case} ...", file=sys.stderr, flush=True)
                await asyncio.sleep(window)
                called, hostiles.began = time.monotonic(), None
                note = await hostile(2 * window if case == "slow reader" else window)
                began = hostiles.began or called
                marks.append(Mark(case, called, began, time.monotonic(), note))
                await asyncio.sleep(window)
            (await api.post(f"/api/sessions/{good['id']}/stop", json={})).raise_for_status()
            await asyncio.wait([page], timeout=10)
        finally:
            page.cancel()
            probing.cancel()
            hostiles.frozen.kill()
            hostiles.frozen.wait()
        trial = (await api.get(f"/api/sessions/{good['id']}")).json()["trials"][0]
        inputs = await api.get(f"/api/sessions/{good['id']}/files/{trial['files'][2]}")
        inputs.raise_for_status()
    rows = list(csv.DictReader(io.StringIO(inputs.text)))
    return {"log": log, "marks": marks, "inputs": rows, "trial": trial, "api": probe}


def measure(quick: bool, only: list[str]) -> dict[str, Any]:
    """Run the server and the scenario; return what was measured, the server's peak memory."""
    window = WINDOW if quick else 2 * WINDOW
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory() as folder:
        log = Path(folder) / "server.log"
        lab, base, token = start_lab(Path(folder) / "lab", log, SERVER_FILES)
        waits = CpuWaits(lab.pid)
        try:
            result = asyncio.run(scenario(base, token, Path(folder), window, only))
        finally:
            waits.stop()
            peak = stop_process(lab)
        lines = log.read_text().splitlines()
        warnings = [line for line in lines if line.startswith("WARNING")]
        errors = [line for line in lines if line.startswith("ERROR") or "destroyed" in line
                  or "Too many open files" in line]  # fmt: skip
    return result | {
        "window": window,
        "peak_mb": peak,
        "cpu_waits": waits,
        "load": (load_before, os.getloadavg()),
        "warnings": warnings,
        "log_lines": len(lines),
        "errors": errors,
    }


def window_stats(
    latency: np.ndarray, arrivals: np.ndarray, low: float, high: float
) -> dict[str, float]:
    """Summarise a window [low, high) of the good participant's record.

    Returns the number of positions sent in it, their input-to-frame p50 and p95 (ms), and the
    longest gap (ms) between two frames, the later one arriving in it, with the arrival times
    (s) of its two frames.
    """
    chosen = latency[(latency[:, 0] >= low) & (latency[:, 0] < high), 1] * 1e3
    ends = (arrivals[1:] >= low) & (arrivals[1:] < high)
    gaps = np.diff(arrivals)[ends] * 1e3
    nan = float("nan")
    ended = np.flatnonzero(ends) + 1  # indices of the frames ending the window's gaps
    longest = int(ended[np.argmax(gaps)]) if gaps.size else 0
    return {
        "n": int(chosen.size),
        "p50": float(np.median(chosen)) if chosen.size else nan,
        "p95": float(np.percentile(chosen, 95)) if chosen.size else nan,
        "gap": float(gaps.max()) if gaps.size else nan,
        "gap_from": float(arrivals[longest - 1]) if gaps.size else nan,
        "gap_to": float(arrivals[longest]) if gaps.size else nan,
    }


def table(result: dict[str, Any]) -> tuple[str, dict[str, dict[str, dict[str, float]]]]:
    """Make the Markdown table and return it with its numbers.

    Columns: case, window, n inputs, input-to-frame p50 and p95, longest frame gap, the
    researcher's API answer times (median and longest, `ApiProbe`; ``inf``: unanswered), and
    the time the server's main thread waited for a CPU (`CpuWaits`) during that gap and during
    the whole window.
    """
    log: PageLog = result["log"]
    latency = input_to_frame(log, result["inputs"])
    arrivals = np.array(sorted(t for _, t in log.frames))
    window = result["window"]
    lines = ["| case | window | n inputs | p50 ms | p95 ms | longest gap ms | "
             "API median / longest ms (n) | server's CPU wait in it, ms | in the window, ms |",
             "|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    stats: dict[str, dict[str, dict[str, float]]] = {}
    for mark in result["marks"]:
        spans = {"before": (mark.called - window, mark.called), "during": (mark.began, mark.ended),
                 "after": (mark.ended, mark.ended + window)}  # fmt: skip
        stats[mark.case] = {}
        for name, (low, high) in spans.items():
            s = window_stats(latency, arrivals, low, high)
            s["wait"] = result["cpu_waits"].within(low, high)
            s["gap_wait"] = result["cpu_waits"].within(s["gap_from"], s["gap_to"])
            s["api"], s["api_max"], asked = result["api"].within(low, high)
            stats[mark.case][name] = s
            lines.append(f"| {mark.case} | {name} ({high - low:.1f} s) | {s['n']} | "
                         f"{s['p50']:.1f} | {s['p95']:.1f} | {s['gap']:.1f} | "
                         f"{s['api']:.0f} / {s['api_max']:.0f} ({asked}) | "
                         f"{s['gap_wait']:.0f} | {s['wait']:.0f} |")  # fmt: skip
    return "\n".join(lines), stats


def report(result: dict[str, Any]) -> tuple[str, list[dict]]:
    """Return the printed table with its context, and the rows for ``run.py``."""
    text, stats = table(result)
    (b1, b5, b15), (a1, a5, a15) = result["load"]
    trial = result["trial"]
    longest = max(s["gap"] for case in stats.values() for s in case.values())
    peak = round(result["peak_mb"], 1)
    context = (
        f"Load average {b1:.2f}/{b5:.2f}/{b15:.2f} before, {a1:.2f}/{a5:.2f}/{a15:.2f} after; "
        f"server peak resident memory {peak} MB; the good trial ended: {trial['end_reason']} "
        f"({trial['n_samples']} samples, held {trial['held']}); longest gap of all windows "
        f"{longest:.1f} ms (bound {GAP_BOUND_MS:g} ms); server log: "
        f"{result['log_lines']} lines, {len(result['warnings'])} warnings, "
        f"{len(result['errors'])} errors (or out of descriptors)."
    )
    notes = "\n".join(f"- {mark.case}: {mark.note}" for mark in result["marks"])
    kinds = collections.Counter(re.sub(r"[\d.]+", "N", line) for line in result["warnings"])
    notes += "".join(f"\n- server log, {n} times: {kind}" for kind, n in kinds.most_common(8))
    rows = []
    for case, windows in stats.items():
        before, during, after = windows["before"], windows["during"], windows["after"]
        rows.append({
            "name": f"{case}: longest frame gap during",
            "value": round(during["gap"], 1),
            "unit": "ms",
            "baseline": f"before {before['gap']:.1f} ms",
            "ratio": round(during["gap"] / before["gap"], 2),
            "peak_memory_mb": peak,
            "note": f"input-to-frame p50/p95 before {before['p50']:.1f}/{before['p95']:.1f}, "
                    f"during {during['p50']:.1f}/{during['p95']:.1f}, after "
                    f"{after['p50']:.1f}/{after['p95']:.1f} ms; gap after {after['gap']:.1f} ms; "
                    f"researcher's API longest answer before/during/after {before['api_max']:.0f}/"
                    f"{during['api_max']:.0f}/{after['api_max']:.0f} ms",
        })  # fmt: skip
    rows.append({"name": "longest frame gap, all windows", "value": round(longest, 1),
                 "unit": "ms", "baseline": f"bound {GAP_BOUND_MS:g} ms",
                 "ratio": round(longest / GAP_BOUND_MS, 2), "peak_memory_mb": peak,
                 "note": context})  # fmt: skip
    return f"{text}\n\n{context}\n\n{notes}", rows


def run(quick: bool, only: list[str] | None = None) -> list[dict]:
    """Measure every case (or those named in ``only``); print the table, return the rows."""
    text, rows = report(measure(quick, only or []))
    print(text, file=sys.stderr, flush=True)
    return rows


if __name__ == "__main__":
    named = [arg for arg in sys.argv[1:] if arg != "--quick"]
    for row in run(quick="--quick" in sys.argv, only=named):
        print(row)

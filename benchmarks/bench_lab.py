"""Lab sessions: the server clock's tick cost, and round trips with four participants' pages.

- Tick cost (in process): a `LabTrial` of N = 2, 4 and 10 players, half people (fed through
  `BrowserInput.put` with a moving position before every tick) and half ``bundled:slow``
  avatars, in a ``joint`` pair (N = 2) or a ``group`` on a ring, recording into a temporary
  folder; every `LabTrial.tick` of a 60 s trial is timed. The baseline is the bare engine step
  of the same players without recording (`Engine` with no sinks), so the ratio is what
  recording (two flushed CSV lines per tick) costs; the fraction of the control period T a tick
  uses is in the note. Building the frames for all people once per tick (JSON encoded as the
  runner does) is timed too. Peak memory is traced (`tracemalloc`) in a separate untimed pass.
- Round trips: the real command, ``mirror-avatar lab``, in its own process; a session of four
  people (P1..P4) and two avatars in a complete group is created through the HTTP/JSON API and
  four WebSocket clients, in one asyncio loop of this process, join it by their links, send a
  position at 60 Hz like a browser and answer each ``ping``. Measured: the server's own ping
  round trips (the session's status at the end of the trial), and the input-to-frame latency:
  from sending a position to receiving the frame of the first sample that used it (found in
  the trial's ``inputs.csv``, which records the position's sequence number per sample). This
  includes the wait for the tick that samples it: a position is sampled only while it is the
  newest, so sampled positions wait at most one send interval (1/60 s, not T), about half of
  one on average; the server's own record of that wait (``age_ms``) is in the note. The
  baseline is a bare ``websockets`` echo server in its own process, four clients sending at
  60 Hz for as long, in the same run. Peak memory is the server process's peak resident size.
"""

from __future__ import annotations

import asyncio
import csv
import io
import json
import math
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path
from typing import Any

import httpx
import numpy as np
from websockets.asyncio.client import connect

from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.engine.loop import Engine, count_samples
from mirror_avatar.lab.design.plan import SessionPlan, parse_plan
from mirror_avatar.lab.running.trial import LabTrial, build_avatars
from mirror_avatar.players.base import Player
from mirror_avatar.realtime.inputs import BrowserInput, HumanPlayer
from mirror_avatar.realtime.outbox import encode_message

sys.path.insert(0, str(Path(__file__).parent))
from probe_clients import (  # noqa: E402
    SEND_RATE,
    PageLog,
    input_to_frame,
    page_client,
    send_positions,
    socket_url,
    start_lab,
    start_process,
    stop_process,
    wait_joined,
)

AVATAR = "bundled:slow"
SIZES = (2, 4, 10)
CLIENTS = 4
PERIOD_NOTE = f"control period {CONTROL_PERIOD * 1e3:g} ms"
ECHO_SERVER = """
import asyncio
from websockets.asyncio.server import serve

async def echo(ws):
    async for message in ws:
        await ws.send(message)

async def main():
    async with serve(echo, "127.0.0.1", 0) as server:
        print("port", server.sockets[0].getsockname()[1], flush=True)
        await asyncio.Future()

asyncio.run(main())
"""


def tick_plan(n_players: int, duration: float) -> SessionPlan:
    """People and ``bundled:slow`` avatars alternating: a joint pair, or a group on a ring."""
    slots = [
        {"label": f"P{k + 1}", "kind": "human"}
        if k % 2 == 0
        else {"label": f"A{k + 1}", "kind": "avatar", "spec": AVATAR}
        for k in range(n_players)
    ]
    condition = "joint" if n_players == 2 else "group"
    return parse_plan(
        {"condition": condition, "graph": "ring", "players": slots, "duration": duration, "seed": 1}
    )


def feed(inputs: dict[int, BrowserInput], k: int) -> None:
    """Give every person a new position for sample k (a 0.5 Hz sine, phase by player)."""
    for j, source in inputs.items():
        source.put(0.3 * math.sin(math.pi * k * CONTROL_PERIOD + j), k)


def frames(plan: SessionPlan, trial: LabTrial) -> list[str]:
    """Encode one tick's frame for every person, as `LabSession._send_frames` builds them."""
    positions, progress = trial.positions(), trial.progress
    texts = []
    for k in plan.humans:
        visible = [k, *plan.neighbours(k)]
        message = {"type": "frame", "k": trial.k - 1, "x": [positions[j] for j in visible],
                   "progress": progress}  # fmt: skip
        texts.append(encode_message(message))
    return texts


def new_trial(
    plan: SessionPlan, folder: Path, avatars: dict[int, Player]
) -> tuple[LabTrial, dict[int, BrowserInput]]:
    """Return trial 1 of ``plan``, recording into ``folder``, and its people's inputs."""
    inputs = {k: BrowserInput() for k in plan.humans}
    lab = {"session_id": "bench", "condition": plan.condition}
    return LabTrial(plan, 1, folder, inputs, avatars, time.monotonic, lab), inputs


def time_ticks(plan: SessionPlan, avatars: dict[int, Player]) -> tuple[np.ndarray, np.ndarray]:
    """Seconds of every `LabTrial.tick` of one trial, and of building each tick's frames."""
    ticks, encoding = [], []
    with tempfile.TemporaryDirectory() as folder:
        trial, inputs = new_trial(plan, Path(folder), avatars)
        while not trial.finished:
            feed(inputs, trial.k)
            began = time.perf_counter()
            trial.tick()
            ticks.append(time.perf_counter() - began)
            began = time.perf_counter()
            frames(plan, trial)
            encoding.append(time.perf_counter() - began)
        trial.finish(True, "completed")
    return np.asarray(ticks), np.asarray(encoding)


def time_engine(plan: SessionPlan, avatars: dict[int, Player]) -> np.ndarray:
    """Seconds of every bare `Engine.step` of the same players, recording nothing."""
    inputs = {k: BrowserInput() for k in plan.humans}
    players = [
        HumanPlayer(inputs[k], slot.label) if slot.kind == "human" else avatars[k]
        for k, slot in enumerate(plan.slots)
    ]
    engine = Engine(players, plan.graph, plan.roles, [slot.label for slot in plan.slots])
    n_samples = count_samples(plan.duration, CONTROL_PERIOD)
    engine.reset(1, n_samples)
    steps = []
    for k in range(n_samples - 1):
        feed(inputs, k)
        began = time.perf_counter()
        engine.step()
        steps.append(time.perf_counter() - began)
    return np.asarray(steps)


def traced_peak_mb(plan: SessionPlan) -> float:
    """Peak traced memory (MB) of building the avatars and playing one recorded trial."""
    tracemalloc.start()
    avatars = build_avatars(plan)
    with tempfile.TemporaryDirectory() as folder:
        trial, inputs = new_trial(plan, Path(folder), avatars)
        while not trial.finished:
            feed(inputs, trial.k)
            trial.tick()
            frames(plan, trial)
        trial.finish(True, "completed")
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak / 2**20


def tick_rows(n_players: int, duration: float) -> list[dict]:
    """Median and 95th percentile tick, and the frames' cost, for ``n_players`` players."""
    plan = tick_plan(n_players, duration)
    avatars = build_avatars(plan)
    engine = time_engine(plan, avatars)
    ticks, encoding = time_ticks(plan, avatars)
    peak = round(traced_peak_mb(plan), 1)
    people = len(plan.humans)
    setting = (
        f"{_count(people, 'person', 'people')} + "
        f"{_count(n_players - people, f'{AVATAR} avatar', f'{AVATAR} avatars')}, {plan.condition}"
        + (" on a ring" if plan.condition == "group" else "")
        + f"; {ticks.size} ticks of a {duration:g} s trial"
    )
    rows = []
    for label, q in (("median", 50), ("95th percentile", 95)):
        value, base = np.percentile(ticks, q), np.percentile(engine, q)
        rows.append(
            {
                "name": f"tick, {n_players} players, {label}",
                "value": round(value * 1e3, 4),
                "unit": "ms",
                "baseline": f"bare engine step {base * 1e3:.4f} ms",
                "ratio": round(value / base, 2),
                "peak_memory_mb": peak,
                "note": f"{setting}; {value / CONTROL_PERIOD:.2%} of the {PERIOD_NOTE}",
            }
        )
    value = np.median(encoding)
    rows.append(
        {
            "name": f"frames for all people, {n_players} players, median",
            "value": round(value * 1e3, 4),
            "unit": "ms/tick",
            "baseline": PERIOD_NOTE,
            "ratio": round(value / CONTROL_PERIOD, 5),
            "peak_memory_mb": peak,
            "note": f"{_count(people, 'frame', 'frames')} JSON-encoded per tick (p95 "
            f"{np.percentile(encoding, 95) * 1e3:.4f} ms)",
        }
    )
    return rows


def _count(n: int, one: str, many: str) -> str:
    return f"{n} {one if n == 1 else many}"


def start_echo(log: Path) -> tuple[subprocess.Popen, int]:
    """Run a bare ``websockets`` echo server; return it and its port."""
    process, line = start_process([sys.executable, "-c", ECHO_SERVER], log, "port ")
    return process, int(line.split()[1])


async def echo_client(url: str, duration: float, phase: float) -> list[float]:
    """Round trips (s) of positions sent at 60 Hz to the echo server for ``duration`` s."""
    sent: dict[int, float] = {}
    times = []
    async with connect(url, proxy=None) as ws:
        sender = asyncio.create_task(send_positions(ws, phase, sent))
        end = time.monotonic() + duration
        while (left := end - time.monotonic()) > 0:
            try:
                message = await asyncio.wait_for(ws.recv(), left)
            except TimeoutError:
                break
            times.append(time.monotonic() - sent[json.loads(message)["seq"]])
        sender.cancel()
    return times


async def echo_round_trips(port: int, duration: float) -> np.ndarray:
    """Round trips (s) of `CLIENTS` clients of the echo server at once."""
    url = f"ws://127.0.0.1:{port}"
    results = await asyncio.gather(*(echo_client(url, duration, i) for i in range(CLIENTS)))
    return np.concatenate([np.asarray(r) for r in results])


def session_plan(duration: float) -> dict[str, Any]:
    """Four people P1..P4 and two avatars in a complete group, one trial."""
    people = [{"label": f"P{k}", "kind": "human"} for k in range(1, CLIENTS + 1)]
    avatars = [{"label": f"A{k}", "kind": "avatar", "spec": AVATAR} for k in (1, 2)]
    return {"condition": "group", "graph": "complete", "players": people + avatars,
            "duration": duration, "trials": 1, "seed": 1}  # fmt: skip


async def lab_session(base: str, token: str, duration: float) -> tuple[dict, list[PageLog], str]:
    """Play one session; return its final status, the clients' logs and its inputs file."""
    headers = {"Authorization": f"Bearer {token}"}
    async with httpx.AsyncClient(base_url=base, headers=headers, timeout=30) as api:
        created = await api.post("/api/sessions", json=session_plan(duration))
        created.raise_for_status()
        status = created.json()
        logs = [PageLog(label) for label in status["links"]]
        urls = [socket_url(link) for link in status["links"].values()]
        clients = [asyncio.create_task(page_client(url, log, i))
                   for i, (url, log) in enumerate(zip(urls, logs, strict=True))]  # fmt: skip
        sid = status["id"]
        await wait_joined(api, sid)
        (await api.post(f"/api/sessions/{sid}/start", json={})).raise_for_status()
        await asyncio.wait_for(asyncio.gather(*clients), duration + 60)
        status = (await api.get(f"/api/sessions/{sid}")).json()
        name = status["trials"][0]["files"][2]
        inputs = await api.get(f"/api/sessions/{sid}/files/{name}")
        inputs.raise_for_status()
    return status, logs, inputs.text


def sampled_ages(inputs: list[dict[str, str]], labels: list[str]) -> np.ndarray:
    """Ages (ms) of the new positions the trial sampled, as the server recorded them."""
    ages = [
        float(row[f"age_ms_{label}"])
        for row in inputs
        for label in labels
        if row[f"held_{label}"] == "0" and row[f"age_ms_{label}"]
    ]
    return np.asarray(ages)


def round_trips(duration: float) -> dict[str, Any]:
    """Run the echo baseline, then the lab session; return what both measured."""
    with tempfile.TemporaryDirectory() as folder:
        log = Path(folder) / "servers.log"
        echo, port = start_echo(log)
        try:
            echo_times = asyncio.run(echo_round_trips(port, duration))
        finally:
            echo_peak = stop_process(echo)
        lab, base, token = start_lab(Path(folder) / "lab", log)
        try:
            status, logs, inputs = asyncio.run(lab_session(base, token, duration))
        finally:
            lab_peak = stop_process(lab)
        warnings = [line for line in log.read_text().splitlines() if "WARNING" in line]
    rows = list(csv.DictReader(io.StringIO(inputs)))
    return {
        "echo": echo_times,
        "echo_peak": echo_peak,
        "lab_peak": lab_peak,
        "status": status,
        "logs": logs,
        "latency": np.concatenate([input_to_frame(page, rows)[:, 1] for page in logs]),
        "ages": sampled_ages(rows, [page.label for page in logs]),
        "warnings": warnings,
    }


def round_trip_rows(duration: float) -> list[dict]:
    """Echo, ping and input-to-frame rows, and the trial's held samples and dropped frames."""
    result = round_trips(duration)
    echo, status, logs = result["echo"], result["status"], result["logs"]
    people = [slot for slot in status["slots"] if slot["kind"] == "human"]
    setting = f"{CLIENTS} clients at {SEND_RATE:g} Hz for {duration:g} s"
    rows = []
    for label, q in (("median", 50), ("95th percentile", 95)):
        base = float(np.percentile(echo, q)) * 1e3
        note = f"bare websockets echo server; {echo.size} messages, {setting}"
        rows.append(_row(f"echo round trip, {label}", base, None, result["echo_peak"], note))
    for label, q, key in (("median", 50, "rtt_median_ms"), ("95th percentile", 95, "rtt_p95_ms")):
        value = float(np.mean([slot[key] for slot in people]))
        base = float(np.percentile(echo, q)) * 1e3
        note = (
            f"the server's ping round trips, mean of the {CLIENTS} slots' {key} "
            f"({', '.join(f'{slot[key]:.2f}' for slot in people)} ms)"
        )
        rows.append(_row(f"lab ping round trip, {label}", value, base, result["lab_peak"], note))
    latency = result["latency"]
    nulls = sum(page.own_null for page in logs)
    received = sum(len(page.frames) for page in logs)
    for label, q in (("median", 50), ("95th percentile", 95)):
        value = float(np.percentile(latency, q)) * 1e3
        base = float(np.percentile(echo, q)) * 1e3
        note = (
            f"{latency.size} sampled positions, matched through the trial's inputs.csv; "
            f"includes their wait for the tick (the server records a median age of "
            f"{np.median(result['ages']):.2f} ms, p95 {np.percentile(result['ages'], 95):.2f} ms "
            f"at sampling; send interval {1e3 / SEND_RATE:.1f} ms, T/2 = "
            f"{CONTROL_PERIOD * 500:g} ms); {nulls} of {received} frames carried null as the "
            "client's own position"
        )
        rows.append(_row(f"lab input-to-frame latency, {label}", value, base,
                         result["lab_peak"], note))  # fmt: skip
    rows += _quality_rows(status, logs, result)
    return rows


def _row(name: str, value: float, base: float | None, peak: float, note: str) -> dict:
    return {
        "name": name,
        "value": round(value, 3),
        "unit": "ms",
        "baseline": "" if base is None else f"echo {base:.3f} ms",
        "ratio": "" if base is None else round(value / base, 2),
        "peak_memory_mb": round(peak, 1),
        "note": note,
    }


def _quality_rows(status: dict, logs: list[PageLog], result: dict[str, Any]) -> list[dict]:
    """Held samples (from the trial's summary) and frames dropped (from the slots' status)."""
    trial = status["trials"][0]
    n_samples = trial["n_samples"]
    held = trial["held"]
    people = [slot for slot in status["slots"] if slot["kind"] == "human"]
    dropped = {slot["label"]: slot["frames_dropped"] for slot in people}
    received = {page.label: len(page.frames) for page in logs}
    outcome = f"trial {'complete' if trial['complete'] else 'incomplete'}: {trial['end_reason']}"
    warnings = f"; {len(result['warnings'])} server warnings" if result["warnings"] else ""
    return [
        {
            "name": "lab held samples (all people)",
            "value": sum(held.values()),
            "unit": "samples",
            "baseline": f"{n_samples} samples x {len(held)} people",
            "ratio": round(sum(held.values()) / (n_samples * len(held)), 4),
            "peak_memory_mb": round(result["lab_peak"], 1),
            "note": f"{outcome}; per person {held}; connections dropped: {trial['dropped']}",
        },
        {
            "name": "lab frames dropped (all people)",
            "value": sum(dropped.values()),
            "unit": "frames",
            "baseline": f"{sum(received.values())} received",
            "ratio": round(sum(dropped.values()) / max(1, sum(received.values())), 4),
            "peak_memory_mb": round(result["lab_peak"], 1),
            "note": f"superseded frames per person {dropped}; frames received {received}"
            + warnings,
        },
    ]


def run(quick: bool) -> list[dict]:
    duration = 10.0 if quick else 60.0
    rows = []
    for n_players in SIZES:
        print(f"  tick cost, {n_players} players ...", file=sys.stderr, flush=True)
        rows += tick_rows(n_players, duration)
    print("  round trips ...", file=sys.stderr, flush=True)
    rows += round_trip_rows(8.0 if quick else 30.0)
    return rows


if __name__ == "__main__":
    for row in run(quick="--quick" in sys.argv):
        print(row)

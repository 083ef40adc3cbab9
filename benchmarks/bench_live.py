"""Live play: the avatar's step cost, the per-sample recording cost and the loopback round trip.

- Avatar step: `Player.step` of the default avatar (the engine's virtual trainer, in each role)
  against a 0.5 Hz sine partner; ratio = cost / control period (the fraction of the 30 ms
  budget a step uses).
- Recording: one `TrialRecorder.append` (a CSV line written and flushed to each file); ratio
  against the control period too.
- Round trip: a position message to the live server and its avatar answer over a real loopback
  WebSocket during a running avatar-follows trial, sent at 60 Hz like a browser; baseline = a bare
  `websockets` echo server measured in the same run.
"""

from __future__ import annotations

import json
import math
import resource
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
from websockets.sync.client import connect
from websockets.sync.server import serve

from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.live.server import LiveSettings, create_app
from mirror_avatar.live.session import (
    DEFAULT_AVATAR,
    AvatarFactory,
    PersonTrialWriter,
    make_avatar_factory,
)
from mirror_avatar.players import Observation
from mirror_avatar.sessions.graphs import complete_graph
from mirror_avatar.sessions.writer import SessionWriter
from mirror_avatar.testing import ServerThread


def peak_memory_mb() -> float:
    """Peak resident memory of this process so far (MB; Linux reports kB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def time_steps(factory: AvatarFactory, mode: str, n: int) -> float:
    """Mean seconds per avatar step in ``mode``."""
    player = factory(mode)
    player.reset(1)
    partner = [0.3 * math.sin(math.pi * k * CONTROL_PERIOD) for k in range(n + 2)]
    seen = [
        Observation.of_partner(
            k, partner[k + 1], (partner[k + 1] - partner[k]) / CONTROL_PERIOD, partner[k]
        )  # fmt: skip
        for k in range(n + 1)
    ]
    for observation in seen[:20]:  # compile and warm up
        player.step(observation)
    start = time.perf_counter()
    for observation in seen[1:]:
        player.step(observation)
    return (time.perf_counter() - start) / n


def time_recording(n: int) -> float:
    """Mean seconds per recorded sample (the session and trial CSV lines written and flushed)."""
    with tempfile.TemporaryDirectory() as folder:
        labels, roles = ("person", "avatar"), ("leader", "follower")
        session = SessionWriter(Path(folder) / "bench_session.csv", labels, roles,
                                complete_graph(2), CONTROL_PERIOD, {})  # fmt: skip
        person = PersonTrialWriter(Path(folder) / "bench.csv")
        rows = [np.array([k * CONTROL_PERIOD, 0.1, 0.2, np.nan, np.nan, -0.1, -0.2, 3.0, 0.5])
                for k in range(n)]  # fmt: skip
        start = time.perf_counter()
        for row in rows:
            session.append(row)
            person(row)
        elapsed = time.perf_counter() - start
        session.close(True)
        person.close()
    return elapsed / n


def round_trips(url: str, n: int, start: dict | None) -> np.ndarray:
    """Round-trip times (s) of ``n`` position messages sent at 60 Hz."""
    times = []
    with connect(url, proxy=None) as ws:
        if start is not None:
            ws.recv()  # ready
            ws.send(json.dumps(start))
        for seq in range(n):
            sent = time.perf_counter()
            ws.send(json.dumps({"type": "position", "seq": seq, "x": 0.1, "rtt": None}))
            while True:
                reply = json.loads(ws.recv())
                if reply.get("seq") == seq:
                    break
            times.append(time.perf_counter() - sent)
            time.sleep(max(0.0, 1 / 60 - (time.perf_counter() - sent)))
    return np.asarray(times)


def echo_round_trips(n: int) -> np.ndarray:
    """Round trips to a bare `websockets` echo server on loopback (s)."""

    def echo(ws) -> None:  # noqa: ANN001 - a websockets ServerConnection
        for message in ws:
            ws.send(json.dumps({"seq": json.loads(message)["seq"]}))

    with serve(echo, "127.0.0.1", 0) as server:
        thread = threading.Thread(target=server.serve_forever, daemon=True)
        thread.start()
        port = server.socket.getsockname()[1]
        try:
            return round_trips(f"ws://127.0.0.1:{port}", n, None)
        finally:
            server.shutdown()
            thread.join()


def live_round_trips(n: int, factory: AvatarFactory | None) -> np.ndarray:
    """Round trips to the live server during a trial (s): avatar-follows with ``factory``."""
    start = {
        "type": "start",
        "mode": "solo" if factory is None else "avatar_follows",
        "participant": "bench",
        "duration": n / 60 + 5,
    }
    with tempfile.TemporaryDirectory() as folder:
        settings = LiveSettings(out_dir=Path(folder), avatar_spec=DEFAULT_AVATAR, countdown=0)
        with ServerThread(create_app(settings, factory)) as server:
            return round_trips(server.url.replace("http", "ws") + "/ws", n, start)


def default_factory() -> AvatarFactory | None:
    """Return the engine's default avatar factory, or None while the engine is missing."""
    try:
        return make_avatar_factory()
    except ImportError:
        return None


def run(quick: bool) -> list[dict]:
    n_steps = 500 if quick else 5000
    factory = default_factory()
    rows = []
    for mode in ("avatar_follows", "avatar_leads", "joint"):
        row = {"name": f"avatar step ({mode}, {DEFAULT_AVATAR})", "unit": "us/step"}
        if factory is None:
            rows.append({**row, "value": "", "note": "not measured: engine players missing"})
            continue
        cost = time_steps(factory, mode, n_steps)
        rows.append(
            {
                **row,
                "value": round(cost * 1e6, 1),
                "baseline": f"control period {CONTROL_PERIOD * 1e3:g} ms",
                "ratio": round(cost / CONTROL_PERIOD, 5),
                "peak_memory_mb": round(peak_memory_mb(), 1),
                "note": f"mean of {n_steps} steps against a sine partner",
            }
        )
    cost = time_recording(n_steps)
    rows.append(
        {
            "name": "record one sample (2 CSV lines, flushed)",
            "value": round(cost * 1e6, 1),
            "unit": "us/sample",
            "baseline": f"control period {CONTROL_PERIOD * 1e3:g} ms",
            "ratio": round(cost / CONTROL_PERIOD, 5),
            "peak_memory_mb": round(peak_memory_mb(), 1),
            "note": f"mean of {n_steps} samples",
        }
    )
    n_messages = 120 if quick else 1200
    echo = echo_round_trips(n_messages)
    live = live_round_trips(n_messages, factory)
    during = (
        "a solo trial (engine players missing)" if factory is None else "an avatar-follows trial"
    )
    for label, percentile in (("median", 50), ("95th percentile", 95)):
        value = float(np.percentile(live, percentile)) * 1e3
        base = float(np.percentile(echo, percentile)) * 1e3
        rows.append(
            {
                "name": f"loopback round trip, {label}",
                "value": round(value, 3),
                "unit": "ms",
                "baseline": f"bare websockets echo {base:.3f} ms",
                "ratio": round(value / base, 2),
                "peak_memory_mb": round(peak_memory_mb(), 1),
                "note": f"{n_messages} messages at 60 Hz during {during}",
            }
        )
    return rows

"""Lab sessions and the Lab Streaming Layer over loopback, with real pylsl streams.

A sine published through a pylsl outlet plays a participant (their device), and the session's
own outlet is read back with a pylsl inlet, sample by sample.
"""

from __future__ import annotations

import asyncio
import csv
import threading
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

import httpx
import numpy as np
import pytest
from test_lab_server import BEARER, TOKEN, Page, status, welcomed

from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.testing import ServerThread
from waiting import wait_for

pytestmark = pytest.mark.realtime

pylsl = pytest.importorskip("pylsl")

AMPLITUDE_MM, FREQUENCY_HZ, PHASE, RATE_HZ = 150.0, 0.5, 0.7, 250.0
MM_PER_UNIT = 600.0


@pytest.fixture
def lab(tmp_path: Path) -> Iterator[ServerThread]:
    # A tick of this busy test process may take long; ending the trial for it is not tested here.
    settings = LabSettings(out_dir=tmp_path, token=TOKEN, countdown=1, lsl=True, max_tick=10.0)
    with ServerThread(create_lab_app(settings)) as running:
        yield running


def sine_mm(t: np.ndarray | float) -> np.ndarray | float:
    """The tracker's position (mm) at LSL time ``t`` (s)."""
    return AMPLITUDE_MM * np.sin(2 * np.pi * FREQUENCY_HZ * t + PHASE)


def publish_sine(name: str, stop: threading.Event, sent: list[tuple[float, float]]) -> None:
    """A hand tracker: the sine in millimetres, two channels, at 250 Hz, LSL-time-stamped;
    appends each sample's (LSL time, mm) to ``sent`` before pushing it."""
    info = pylsl.StreamInfo(name, "Position", 2, RATE_HZ, pylsl.cf_double64, name)
    outlet = pylsl.StreamOutlet(info)
    began = time.monotonic()
    n = 0
    while not stop.is_set():
        now = pylsl.local_clock()
        sent.append((now, float(sine_mm(now))))
        outlet.push_sample([0.0, sent[-1][1]], now)
        n += 1
        time.sleep(max(0.0, began + n / RATE_HZ - time.monotonic()))


def fit_sine(t: np.ndarray, x: np.ndarray) -> tuple[float, float]:
    """Least-squares amplitude and phase (rad) of a sine of `FREQUENCY_HZ` through (t, x)."""
    w = 2 * np.pi * FREQUENCY_HZ * t
    design = np.column_stack([np.sin(w), np.cos(w), np.ones_like(t)])
    (a, b, _), *_ = np.linalg.lstsq(design, x, rcond=None)
    return float(np.hypot(a, b)), float(np.arctan2(b, a))


def test_an_lsl_stream_plays_a_participant(lab, tmp_path):
    name = f"tracker-{uuid.uuid4().hex[:8]}"
    stop = threading.Event()
    sent: list[tuple[float, float]] = []
    tracker = threading.Thread(target=publish_sine, args=(name, stop, sent), daemon=True)
    tracker.start()
    try:
        lsl_person = {"stream": name, "channel": 1, "scale": 1 / MM_PER_UNIT}
        plan = {
            "condition": "joint",
            "duration": 4.0,
            "players": [
                {"label": "H1", "kind": "human", "device": "lsl", "lsl": lsl_person},
                {"label": "A1", "kind": "avatar", "spec": "bundled:slow"},
            ],
        }
        created = httpx.post(f"{lab.url}/api/sessions", json=plan, headers=BEARER).json()
        assert created["links"] == {"H1": created["links"]["H1"]}  # it may watch the game
        sid = created["id"]
        started = httpx.post(f"{lab.url}/api/sessions/{sid}/start", json={}, headers=BEARER)
        assert started.status_code == 200, started.text
        wait_for(lambda: status(lab, sid)["state"] == "finished", 30)
    finally:
        stop.set()
        tracker.join(5)
    session = load_session(tmp_path / sid / "trial-01_session.csv")
    with (tmp_path / sid / "trial-01_inputs.csv").open() as file:
        rows = list(csv.DictReader(file))
    clock = np.array([float(row["clock_s"]) for row in rows])
    x = session.positions[0]
    # The tracker is a Python thread of this busy test process: under load it misses some of
    # the 30 ms ticks (held, the last sample kept), as many as the load makes; the inputs log
    # counts them as the session does.
    held = [row["held_H1"] for row in rows]
    assert session.n_samples == 134 and session.metadata["held"]["H1"] == held.count("1")
    # How late a tick's sample is depends on how late the busy test process published and
    # pulled it: not asserted. What holds on any clock: every position recorded is a sample the
    # tracker published before the tick, and at the times those samples were taken the
    # positions are the tracker's sine in units, of its amplitude and phase.
    stamps, published = (np.array(column) for column in zip(*sent, strict=True))
    taken = []  # the LSL time stamp of the sample each tick recorded
    for tick_clock, position in zip(clock, x, strict=True):
        (same,) = np.nonzero(
            (stamps <= tick_clock) & (np.abs(published / MM_PER_UNIT - position) < 1e-12)
        )
        assert same.size, (tick_clock, position)
        taken.append(stamps[same[-1]])
    amplitude, phase = fit_sine(np.asarray(taken), x)
    assert amplitude == pytest.approx(AMPLITUDE_MM / MM_PER_UNIT, rel=0.01)
    assert abs(np.angle(np.exp(1j * (phase - PHASE)))) < 0.01 * 2 * np.pi


def test_the_sessions_outlet_carries_every_sample_of_every_player(lab, tmp_path):
    plan = {
        "condition": "group",
        "graph": "ring",
        "duration": 3.0,
        "players": [
            {"label": "P1", "kind": "human"},
            {"label": "A1", "kind": "avatar", "spec": "bundled:slow"},
            {"label": "A2", "kind": "avatar", "spec": "bundled:fast"},
        ],
    }
    created = httpx.post(f"{lab.url}/api/sessions", json=plan, headers=BEARER).json()
    sid = created["id"]
    (info,) = pylsl.resolve_byprop("source_id", f"mirror-avatar-{sid}", timeout=5)
    inlet = pylsl.StreamInlet(info, max_buflen=60)
    inlet.open_stream(timeout=5)
    correction = inlet.time_correction(timeout=5)  # it would wait forever once the stream ends
    (marker_info,) = pylsl.resolve_byprop("source_id", f"mirror-avatar-{sid}-markers", timeout=5)
    markers = pylsl.StreamInlet(marker_info)
    markers.open_stream(timeout=5)
    assert markers.info().type() == "Markers"
    described = inlet.info()
    assert described.channel_count() == 3
    assert described.nominal_srate() == pytest.approx(1 / 0.03)
    channels = described.desc().child("channels").child("channel")
    labels = []
    while not channels.empty():
        labels.append((channels.child_value("label"), channels.child_value("kind")))
        channels = channels.next_sibling()
    assert labels == [("P1", "human"), ("A1", "avatar"), ("A2", "avatar")]

    def start() -> None:
        httpx.post(f"{lab.url}/api/sessions/{sid}/start", json={}, headers=BEARER)

    page = Page(created["links"]["P1"])

    async def play() -> None:
        task = asyncio.create_task(page.play(8.0))
        await welcomed([page])
        await asyncio.to_thread(start)
        await task

    asyncio.run(play())
    samples, stamps = [], []
    while True:
        chunk, times = inlet.pull_chunk(timeout=1.0)
        if not chunk:
            break
        samples += chunk
        stamps += times
    session = load_session(tmp_path / sid / "trial-01_session.csv")
    np.testing.assert_array_equal(np.asarray(samples).T, session.positions)
    with (tmp_path / sid / "trial-01_inputs.csv").open() as file:
        clock = [float(row["clock_s"]) for row in csv.DictReader(file)]
    np.testing.assert_allclose(np.asarray(stamps) + correction, clock, atol=1e-3)
    events, times = markers.pull_chunk(timeout=1.0)
    assert [event for (event,) in events] == ["trial 1 start", "trial 1 end: completed"]
    np.testing.assert_allclose(np.asarray(times) + correction, [clock[0], clock[-1]], atol=1e-3)

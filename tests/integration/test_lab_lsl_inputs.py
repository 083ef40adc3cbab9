"""LSL inputs that fail in a lab session, over real LSL on loopback: a stream that vanishes is
seen lost and recorded, two streams of one name are refused (or chosen by source id), and the
stream's source id, host and sample counts are recorded."""

from __future__ import annotations

import csv
import json
import threading
import time
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from test_lab_server import BEARER, TOKEN, status

from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.testing import ServerThread
from waiting import wait_for

pytestmark = pytest.mark.realtime

pylsl = pytest.importorskip("pylsl")


@pytest.fixture
def lab(tmp_path: Path) -> Iterator[ServerThread]:
    settings = LabSettings(out_dir=tmp_path, token=TOKEN, countdown=1, lsl=True)
    with ServerThread(create_lab_app(settings)) as running:
        yield running


class Slider:
    """A one-channel LSL stream at 100 Hz sending 0.1 (and a few values out of range)."""

    def __init__(self, name: str, source_id: str = "") -> None:
        self.info = pylsl.StreamInfo(name, "Position", 1, 100.0, pylsl.cf_double64, source_id)
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        outlet = pylsl.StreamOutlet(self.info)
        n = 0
        while not self.stop.is_set():
            outlet.push_sample([5.0 if n % 50 == 0 else 0.1])
            n += 1
            time.sleep(0.01)
        del outlet  # the stream vanishes from the network

    def vanish(self) -> None:
        self.stop.set()
        self.thread.join(5)


def plan_of(name: str, duration: float, **lsl: Any) -> dict[str, Any]:
    return {
        "condition": "joint",
        "duration": duration,
        "players": [
            {"label": "H1", "kind": "human", "device": "lsl", "lsl": {"stream": name} | lsl},
            {"label": "A1", "kind": "avatar", "spec": "bundled:slow"},
        ],
    }


def start(lab: ServerThread, plan: dict[str, Any]) -> str:
    created = httpx.post(f"{lab.url}/api/sessions", json=plan, headers=BEARER)
    assert created.status_code == 201, created.text
    sid = str(created.json()["id"])
    started = httpx.post(f"{lab.url}/api/sessions/{sid}/start", json={}, headers=BEARER)
    assert started.status_code == 200, started.text
    return sid


def test_a_stream_that_vanishes_is_seen_lost_and_recorded(lab, tmp_path):
    name = f"slider-{uuid.uuid4().hex[:8]}"
    slider = Slider(name)  # no source id: once gone, liblsl cannot recover it
    try:
        sid = start(lab, plan_of(name, 6.0))
        wait_for(lambda: (status(lab, sid)["trial"] or {}).get("progress", 0) > 0.3, 30)
    finally:
        slider.vanish()
    wait_for(lambda: status(lab, sid)["state"] == "finished", 30)
    now = status(lab, sid)
    assert any("H1: input lost at sample" in event for event in now["events"])
    trial = now["trials"][0]
    assert trial["complete"] and trial["lost"]["H1"] > 0  # on_drop "continue": it went on
    record = json.loads((tmp_path / sid / "trial-01_session.json").read_text())["metadata"]
    (lost,) = record["input_events"]
    assert (lost["label"], lost["event"]) == ("H1", "lost") and lost["seq"] > 0
    with (tmp_path / sid / "trial-01_inputs.csv").open() as file:
        alive = [int(row["alive_H1"]) for row in csv.DictReader(file)]
    assert all(alive[: lost["sample"]]) and not any(alive[lost["sample"] :])
    assert record["lost"]["H1"] == len(alive) - lost["sample"]
    device = record["lab"]["slots"][0]["input"]
    assert device["stream"] == name and device["source_id"] == ""
    assert device["hostname"] and device["received"] > 100
    assert device["clipped"] == pytest.approx(device["received"] / 50, abs=2)
    assert device["invalid"] == 0


def test_two_streams_of_one_name_are_refused_unless_a_source_id_chooses(lab, tmp_path):
    name = f"slider-{uuid.uuid4().hex[:8]}"
    first, second = Slider(name, f"{name}-a"), Slider(name, f"{name}-b")
    try:
        refused = start(lab, plan_of(name, 2.0))
        wait_for(lambda: status(lab, refused)["error"] is not None, 30)
        error = status(lab, refused)["error"]
        assert "2 streams have this name" in error and "give the plan's lsl.source_id" in error
        assert f"{name}-a" in error and f"{name}-b" in error
        assert status(lab, refused)["state"] == "waiting"
        chosen = start(lab, plan_of(name, 2.0, source_id=f"{name}-b"))
        wait_for(lambda: status(lab, chosen)["state"] == "finished", 30)
    finally:
        first.vanish()
        second.vanish()
    record = json.loads((tmp_path / chosen / "trial-01_session.json").read_text())["metadata"]
    assert record["lab"]["slots"][0]["input"]["source_id"] == f"{name}-b"

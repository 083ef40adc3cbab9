"""The real-time core's pieces on their own: input liveness, every ping's round trip, secrets
kept out of logs, write failures named, avatars timed, lateness recorded per sample."""

from __future__ import annotations

import csv
import errno
import logging
import time

import pytest

from mirror_avatar.lab.design.plan import parse_plan
from mirror_avatar.lab.running.trial import LabTrial
from mirror_avatar.players import Player
from mirror_avatar.realtime.clock import time_players
from mirror_avatar.realtime.inputs import HumanPlayer, Sample
from mirror_avatar.realtime.latency import MAX_OUTSTANDING, Pings
from mirror_avatar.realtime.transport import RedactSecrets
from mirror_avatar.realtime.trial import DISK_FULL, lateness_summary, write_failure


class Clock:
    """A clock the test moves by hand (s)."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


class Device:
    """An input device whose samples the test delivers."""

    def __init__(self) -> None:
        self.sample: Sample | None = None

    def latest(self) -> Sample | None:
        return self.sample


def test_an_input_is_lost_when_it_stops_delivering_and_live_when_it_resumes():
    clock, device = Clock(), Device()
    person = HumanPlayer(device, "P1", timeout=1.0, clock=clock)
    person.reset()
    seen = []
    for now, delivered in [(100.5, None), (101.2, None), (101.3, 0.1), (102.2, None),
                           (102.4, None), (102.5, 0.2)]:  # fmt: skip
        clock.now = now
        if delivered is not None:
            seq = 0 if device.sample is None else device.sample.seq + 1
            device.sample = Sample(delivered, seq, now)
        person.current_state()
        seen.append((person.last_input.alive, person.last_input.held))
    assert seen == [(True, True), (False, True), (True, False), (True, True), (False, True),
                    (True, False)]  # fmt: skip
    assert (person.lost, person.held) == (2, 4)


def test_every_ping_is_measured_however_late():
    clock = Clock()
    pings = Pings(clock)
    first, second, third = pings.send(), pings.send(), pings.send()
    clock.now += 2.5
    assert pings.answer(second) == pytest.approx(2500.0)
    assert pings.answer(second) is None and pings.answer(99) is None
    assert pings.waiting() == pytest.approx(2500.0)  # the first is still unanswered
    assert pings.answer(first) == pytest.approx(2500.0) and pings.answer(third) is not None
    assert pings.waiting() is None and pings.answered == 3
    for _ in range(MAX_OUTSTANDING + 5):
        pings.send()
    assert pings.unanswered == 5


def test_tokens_and_join_keys_are_redacted_from_log_records():
    record = logging.LogRecord(
        "uvicorn.access", logging.INFO, "", 0, '%s - "%s %s HTTP/%s" %d', (
            "127.0.0.1:5", "GET", "/console?token=s3cret&x=1", "1.1", 303), None,
    )  # fmt: skip
    socket = logging.LogRecord(
        "uvicorn.error", logging.INFO, "", 0, '%s - "WebSocket %s" [accepted]',
        ("127.0.0.1:6", "/ws/join/K3y-_abc"), None,
    )  # fmt: skip
    for item in (record, socket):
        RedactSecrets().filter(item)
    assert record.getMessage() == '127.0.0.1:5 - "GET /console?token=***&x=1 HTTP/1.1" 303'
    assert socket.getMessage() == '127.0.0.1:6 - "WebSocket /ws/join/***" [accepted]'


def test_write_failures_are_named_with_their_file():
    full = write_failure(OSError(errno.ENOSPC, "No space left on device", "/out/t_session.csv"))
    assert full == f"{DISK_FULL}: cannot write /out/t_session.csv (No space left on device)"
    limited = write_failure(OSError(errno.EFBIG, "File too large", "/out/t_inputs.csv"))
    assert limited == f"{DISK_FULL}: cannot write /out/t_inputs.csv (File too large)"
    assert write_failure(OSError(errno.EIO, "Input/output error")) == (
        "cannot write the recording: Input/output error"
    )


class Sleeper(Player):
    """Sleeps 20 ms per step."""

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        return 0.0, 0.0

    def step(self, observation: object) -> tuple[float, float]:
        time.sleep(0.02)
        return 0.0, 0.0


def test_an_avatar_is_timed_by_its_own_steps():
    (median,) = time_players([Sleeper()], steps=3)
    assert median >= 0.02


def test_each_sample_records_its_ticks_lateness(tmp_path):
    from mirror_avatar.realtime.inputs import BrowserInput

    plan = parse_plan({"condition": "solo", "duration": 1.0, "players": [
        {"label": "P1", "kind": "human"}]})  # fmt: skip
    source = BrowserInput()
    trial = LabTrial(
        plan,
        1,
        tmp_path,
        {0: source},
        {},
        time.monotonic,
        {"session_id": "solo", "condition": "solo"},
    )
    late = [0.0, 0.25, 0.0125, 0.0]
    for k, lateness in enumerate(late):
        source.put(0.01 * k, k)
        trial.tick(lateness)
    summary = trial.finish(False, "stopped")
    with trial.inputs_path.open() as file:
        rows = list(csv.DictReader(file))
    assert [float(row["late_ms"]) for row in rows] == [0.0, 250.0, 12.5, 0.0]
    assert all(float(row["step_ms"]) >= 0.0 for row in rows)
    assert [int(row["alive_P1"]) for row in rows] == [1] * 4
    assert summary["tick_lateness_ms"] == lateness_summary(late, trial.period)
    assert summary["tick_lateness_ms"]["over_period"] == 1
    assert summary["tick_lateness_ms"]["max"] == pytest.approx(250.0)

"""LSL over loopback: the session's outlet read back by an inlet, LSL streams as input devices."""

from __future__ import annotations

import json
import math
import sys
import threading
import time
import uuid
import xml.etree.ElementTree as ET
from collections.abc import Iterator

import numpy as np
import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.lab.running.lsl import UNIT, LslInput, SessionOutlet
from mirror_avatar.realtime.inputs import HumanPlayer
from waiting import wait_for

pylsl = pytest.importorskip("pylsl")

T = CONTROL_PERIOD
LABELS = ("P01", "P02", "avatar")
ROLES = ("leader", "follower", "follower")
KINDS = ("human", "human", "avatar")
RATE = 250.0
AMPLITUDE_MM = 150.0
FREQUENCY = 0.5
MM_PER_UNIT = 600.0


def unique(prefix: str) -> str:
    return f"test-{prefix}-{uuid.uuid4().hex}"


def engine_rows(n_rows: int, n_players: int, rng: np.random.Generator) -> np.ndarray:
    rows = np.empty((n_rows, 1 + 4 * n_players))
    rows[:, 0] = np.arange(n_rows) * T
    rows[:, 1:] = rng.uniform(-0.5, 0.5, (n_rows, 4 * n_players))
    return rows


def connected_inlet(name: str):
    found = pylsl.resolve_byprop("name", name, timeout=5)
    assert len(found) == 1
    inlet = pylsl.StreamInlet(found[0])
    inlet.info(5)
    inlet.open_stream(5)
    return inlet


def pull_all(inlet, n: int, timeout: float = 5.0) -> tuple[np.ndarray, np.ndarray]:
    samples: list[list[float]] = []
    stamps: list[float] = []
    deadline = time.monotonic() + timeout
    while len(stamps) < n and time.monotonic() < deadline:
        chunk, chunk_stamps = inlet.pull_chunk(timeout=0.1, max_samples=n - len(stamps))
        samples.extend(chunk)
        stamps.extend(chunk_stamps)
    return np.asarray(samples, dtype=np.float64), np.asarray(stamps)


def session_outlet(name: str) -> SessionOutlet:
    return SessionOutlet(name, f"{name}-source", LABELS, ROLES, KINDS, T)


def raw_outlet(name: str, channels: int, rate: float, fmt: int | None = None):
    fmt = pylsl.cf_double64 if fmt is None else fmt
    return pylsl.StreamOutlet(pylsl.StreamInfo(name, "Mocap", channels, rate, fmt, name))


# SessionOutlet


def test_outlet_describes_players_channels_and_rate() -> None:
    name = unique("outlet")
    with session_outlet(name):
        inlet = connected_inlet(name)
        info = inlet.info(5)
        assert info.type() == "Position"
        assert info.channel_count() == 3
        assert info.channel_format() == pylsl.cf_double64
        assert info.source_id() == f"{name}-source"
        assert info.nominal_srate() == pytest.approx(1 / T, rel=1e-9)
        desc = ET.fromstring(info.as_xml()).find("desc")
        inlet.close_stream()
        del inlet
    assert desc is not None
    channels = [
        tuple(channel.findtext(key) for key in ("label", "role", "kind", "unit", "type"))
        for channel in desc.findall("channels/channel")
    ]
    expected = [(*player, UNIT, "Position") for player in zip(LABELS, ROLES, KINDS, strict=True)]
    assert channels == expected
    assert desc.findtext("acquisition/manufacturer") == "mirror-avatar"
    assert desc.findtext("acquisition/model") == "mirror game"
    assert float(desc.findtext("session/period_s", "nan")) == T


def test_outlet_delivers_every_row_positions_exactly_in_order(rng: np.random.Generator) -> None:
    name = unique("outlet")
    rows = engine_rows(200, 3, rng)
    with session_outlet(name) as outlet:
        inlet = connected_inlet(name)
        assert outlet.wait_for_consumers(5)
        before = pylsl.local_clock()
        for row in rows:
            outlet.push(row)
        after = pylsl.local_clock()
        samples, stamps = pull_all(inlet, len(rows))
        del inlet
    assert samples.shape == (200, 3)
    assert np.array_equal(samples, rows[:, 1::4])
    assert np.all(np.diff(stamps) > 0)
    assert before <= stamps[0] and stamps[-1] <= after


def test_outlet_keeps_given_timestamps_and_checks_shapes() -> None:
    name = unique("outlet")
    with session_outlet(name) as outlet:
        inlet = connected_inlet(name)
        outlet.push_positions([0.1, -0.2, 0.3], timestamp=1234.5)
        samples, stamps = pull_all(inlet, 1)
        del inlet
        with pytest.raises(ValueError, match="3 positions"):
            outlet.push_positions([0.1, 0.2])
        with pytest.raises(ValueError, match="shape"):
            outlet.push(np.zeros(12))
    assert samples.tolist() == [[0.1, -0.2, 0.3]]
    assert stamps.tolist() == [1234.5]


def test_closed_outlet_is_withdrawn() -> None:
    name = unique("outlet")
    outlet = session_outlet(name)
    assert pylsl.resolve_byprop("name", name, timeout=5)
    outlet.close()
    outlet.close()
    assert pylsl.resolve_byprop("name", name, timeout=0.3) == []
    with pytest.raises(RuntimeError, match="closed"):
        outlet.push_positions([0.0, 0.0, 0.0])


@pytest.mark.parametrize(
    ("labels", "kinds", "period", "problem"),
    [
        (LABELS, ("human", "human", "robot"), T, "unknown player kind 'robot'"),
        (LABELS[:2], KINDS, T, "as many labels"),
        ((), (), T, "as many labels"),
        (LABELS, KINDS, 0.0, "period must be positive"),
    ],
)
def test_outlet_rejects_bad_players(labels, kinds, period, problem) -> None:
    roles = ROLES[: len(kinds)]
    with pytest.raises(InputError, match=problem):
        SessionOutlet(unique("bad"), "bad", labels, roles, kinds, period)


# LslInput


@pytest.fixture
def hand() -> Iterator[tuple[str, object]]:
    """A 3-channel tracker outlet at 250 Hz; channel 1 will carry the hand (mm)."""
    name = unique("hand")
    outlet = raw_outlet(name, 3, RATE)
    yield name, outlet
    del outlet


def send_sine(outlet, t0: float, duration: float, sent: list[int]) -> None:
    """Push [far off, 150 mm sine at 0.5 Hz, far off] at 250 Hz, stamped with the LSL clock."""
    k = 0
    while (now := pylsl.local_clock()) - t0 < duration:
        value = AMPLITUDE_MM * math.sin(2 * math.pi * FREQUENCY * (now - t0))
        outlet.push_sample([1e6, value, -1e6], now)
        k += 1
        time.sleep(max(0.0, t0 + k / RATE - pylsl.local_clock()))
    sent.append(k)


def sample_ticks(device: LslInput, sender: threading.Thread) -> np.ndarray:
    """Read the device every control period while the sender runs, as the session's clock does.

    Returns rows (tick LSL time, x, seq, last_timestamp, time_correction), keeping only ticks whose
    reads were not interleaved with a new sample: the sample read before the tick's time is taken
    is the one read after it.
    """
    ticks = []
    next_tick = time.monotonic()
    while sender.is_alive():
        next_tick += T
        time.sleep(max(0.0, next_tick - time.monotonic()))
        before = device.latest()
        tick = pylsl.local_clock()
        first = device.latest()
        stamp, correction = device.last_timestamp, device.time_correction
        if first is not None and first is before and device.latest() is first:
            ticks.append((tick, first.x, first.seq, stamp, correction))
    return np.asarray(ticks)


def test_input_follows_a_tracker_sine_in_units(hand) -> None:
    name, outlet = hand
    sent: list[int] = []
    with LslInput(name, channel=1, scale=1 / MM_PER_UNIT, timeout=5) as device:
        assert device.latest() is None
        t0 = pylsl.local_clock()
        sender = threading.Thread(target=send_sine, args=(outlet, t0, 3.0, sent))
        sender.start()
        ticks = sample_ticks(device, sender)
        sender.join()
        wait_for(lambda: device.n_received == sent[0])
        newest = device.latest()
        assert newest is not None and newest.seq == sent[0]
        assert HumanPlayer(device, "P01").current_state()[0] == newest.x
        assert device.clipped == 0
        assert device.error is None
    tick, x, seq, stamp, correction = ticks.T
    amplitude = AMPLITUDE_MM / MM_PER_UNIT
    omega = 2 * math.pi * FREQUENCY
    assert len(ticks) > 80
    assert np.all(np.abs(correction) < 1e-3)
    sender_time = stamp - correction - t0
    assert np.max(np.abs(x - amplitude * np.sin(omega * sender_time))) < 1e-6
    assert np.all(np.diff(seq) >= 0) and seq[-1] > seq[0]
    # How late a tick's sample is depends on how late this busy test process published and
    # pulled it: not asserted. Every sample a tick read was published before the tick, and its
    # value (above) is the tracker's sine in units at the time it was taken.
    assert np.all(stamp - correction <= tick)


def test_input_clips_to_the_playing_range_and_skips_invalid_values() -> None:
    name = unique("slider")
    outlet = raw_outlet(name, 1, pylsl.IRREGULAR_RATE)
    values = [0.0, 0.05, 0.1, 0.2, -1.0, math.nan]
    with LslInput(name, offset=0.42, timeout=5) as device:
        for value in values:
            outlet.push_sample([value])
        wait_for(lambda: device.n_received == len(values))
        latest = device.latest()
        description = device.describe()
    del outlet
    assert latest is not None
    assert (latest.x, latest.seq) == (-0.5, 5)
    assert (device.clipped, device.invalid) == (3, 1)
    assert description == {
        "stream": name,
        "type": "Mocap",
        "source_id": name,
        "hostname": description["hostname"],
        "channel": 0,
        "channel_count": 1,
        "nominal_rate": 0.0,
        "scale": 1.0,
        "offset": 0.42,
        "received": 6,
        "invalid": 1,
        "clipped": 3,
    }
    json.dumps(description)


def test_closed_input_stops_its_thread_and_keeps_the_last_sample() -> None:
    name = unique("slider")
    outlet = raw_outlet(name, 1, pylsl.IRREGULAR_RATE)
    device = LslInput(name, timeout=5)
    outlet.push_sample([0.125])
    wait_for(lambda: device.n_received == 1)
    device.close()
    device.close()
    del outlet
    assert f"lsl {name}" not in {thread.name for thread in threading.enumerate()}
    latest = device.latest()
    assert latest is not None and latest.x == 0.125


def test_input_reports_a_stream_lost_for_good() -> None:
    name = unique("no-source-id")
    outlet = pylsl.StreamOutlet(pylsl.StreamInfo(name, "Mocap", 1, RATE, pylsl.cf_double64, ""))
    with LslInput(name, timeout=5) as device:
        outlet.push_sample([0.25])
        wait_for(lambda: device.n_received == 1)
        del outlet
        wait_for(lambda: device.error is not None)
        assert "lost" in (device.error or "")
        latest = device.latest()
    assert latest is not None and latest.x == 0.25


def test_unknown_stream_is_an_input_error() -> None:
    name = unique("absent")
    start = time.monotonic()
    with pytest.raises(InputError, match="no stream of that name") as caught:
        LslInput(name, timeout=0.3)
    assert time.monotonic() - start < 3.0
    assert name in str(caught.value)


def test_channel_outside_the_stream_is_an_input_error() -> None:
    name = unique("pair")
    outlet = raw_outlet(name, 2, RATE)
    with pytest.raises(InputError, match=r"has 2 channel\(s\) \(0\.\.1\), not channel 2"):
        LslInput(name, channel=2, timeout=5)
    del outlet


def test_text_stream_is_an_input_error() -> None:
    name = unique("markers")
    outlet = raw_outlet(name, 1, pylsl.IRREGULAR_RATE, pylsl.cf_string)
    with pytest.raises(InputError, match="not numbers"):
        LslInput(name, timeout=5)
    del outlet


def test_zero_scale_is_an_input_error() -> None:
    with pytest.raises(InputError, match="scale"):
        LslInput(unique("any"), scale=0.0)


def test_missing_pylsl_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "pylsl", None)
    message = "pylsl is not installed: pip install 'mirror-avatar[lsl]'"
    with pytest.raises(InputError) as outlet_error:
        SessionOutlet("s", "s", LABELS, ROLES, KINDS, T)
    with pytest.raises(InputError) as input_error:
        LslInput("hand")
    for error in (outlet_error.value, input_error.value):
        assert error.problem == message
        assert "\n" not in str(error) and str(error).endswith(message)

"""A page's clock on the server's: NTP-style exchanges against synthetic ones of known offset."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mirror_avatar.lab.running.messages import PointerBatch, parse_participant_message
from mirror_avatar.realtime.messages import ProtocolError
from mirror_avatar.realtime.page_clock import Exchange, PageClock, estimate

OFFSET = 1234.5
"""Server time minus page time (ms) of the synthetic exchanges."""


def exchange(t0: float, up: float, down: float, held: float = 0.3) -> Exchange:
    """An exchange sent at page time ``t0`` whose legs took ``up`` and ``down`` ms and which
    the server held ``held`` ms."""
    t1 = t0 + OFFSET + up
    return Exchange(t0, t1, t1 + held, t1 + held - OFFSET + down)


def test_symmetric_legs_give_the_offset_and_the_round_trip():
    e = exchange(1000.0, 80.0, 80.0)
    assert e.offset == pytest.approx(OFFSET)
    assert e.delay == pytest.approx(160.0)


@pytest.mark.parametrize(("up", "down"), [(20.0, 140.0), (140.0, 20.0), (0.0, 90.0), (55, 105)])
def test_asymmetric_legs_err_by_half_their_difference_within_half_the_round_trip(up, down):
    e = exchange(0.0, up, down)
    assert e.offset - OFFSET == pytest.approx((up - down) / 2)
    assert abs(e.offset - OFFSET) <= e.delay / 2


def test_the_minimum_delay_exchanges_are_kept_against_queueing():
    """Legs of 40 ms plus a queue's exponential wait (mean 60 ms) each way: single exchanges
    err by tens of ms, the least delayed tenth's mean by a few."""
    rng = np.random.default_rng(7)
    waits = rng.exponential(60.0, size=(200, 2))
    exchanges = [exchange(100.0 * i, 40 + up, 40 + down) for i, (up, down) in enumerate(waits)]
    errors = np.array([e.offset - OFFSET for e in exchanges])
    offset, uncertainty = estimate(exchanges, kept=0.1)
    assert np.abs(errors).max() > 100.0
    assert abs(offset - OFFSET) < 5.0
    assert abs(offset - OFFSET) <= uncertainty
    assert uncertainty == pytest.approx(min(e.delay for e in exchanges) / 2)


def test_a_window_of_normal_legs_averages_to_the_offset():
    """80 +- 25 ms each way (the browser test's network): one exchange errs with an SD of
    25 / sqrt(2) = 17.7 ms; the kept quarter of 200 averages it to about 2.5 ms."""
    rng = np.random.default_rng(3)
    legs = rng.normal(80.0, 25.0, size=(200, 2)).clip(0.0)
    clock = PageClock()
    for i, (up, down) in enumerate(legs):
        e = exchange(100.0 * i, up, down)
        clock.answer(i, e.t0, e.t1, e.t2)
        assert clock.complete(i, e.t3) == e
    assert clock.estimates[-1].offset_ms == pytest.approx(OFFSET, abs=6.0)
    assert clock.to_server(5000.0) == pytest.approx((5000.0 + OFFSET) / 1000.0, abs=0.006)


def test_a_clock_maps_nothing_before_its_first_exchange_and_refuses_unknown_reports():
    clock = PageClock()
    assert math.isnan(clock.to_server(1.0))
    assert clock.complete(1, 10.0) is None
    clock.answer(1, 100.0, 50.0, 51.0)
    assert clock.complete(1, 99.0) is None  # answered before it was asked: a negative delay
    assert clock.complete(1, 300.0) is None  # reported once only


def test_a_summary_holds_the_exchanges_of_its_span():
    clock = PageClock(window=4)
    for i, up in enumerate([80.0, 60.0, 100.0, 70.0, 90.0]):
        e = exchange(1000.0 * i, up, 80.0)
        clock.answer(i, e.t0, e.t1, e.t2)
        clock.complete(i, e.t3)
    spans = [e.t2 / 1000.0 for e in clock.exchanges]
    summary = clock.summary(spans[1], spans[3])
    assert summary["exchanges"] == 3
    assert summary["rtt_ms"]["max"] == pytest.approx(180.3 - 0.3)
    assert summary["offset_ms"]["first"] == pytest.approx(OFFSET - 10.0)
    assert clock.summary(-1.0, -0.5)["offset_ms"] is None


def test_a_pointer_batch_holds_its_samples_on_the_page_clock():
    text = '{"type": "pointer", "seq": 3, "sent": 1000.5, "ago": [16.5, 0], "x": [0.1, -0.2]}'
    samples = [(984.0, 0.1), (1000.5, -0.2)]
    assert parse_participant_message(text) == PointerBatch(3, 1000.5, samples)


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        ('{"type": "pointer", "seq": 0, "sent": 1, "ago": [1], "x": []}', "same length"),
        ('{"type": "pointer", "seq": 0, "sent": 1, "ago": [], "x": []}', "1 to 20"),
        ('{"type": "pointer", "seq": 0, "sent": 1, "ago": [-1], "x": [0]}', "outside"),
        ('{"type": "pointer", "seq": 0, "sent": 1, "ago": [0], "x": [2]}', "playing range"),
        ('{"type": "clock", "id": 1}', "'t0' must be a number"),
        ('{"type": "clocked", "id": -1, "t3": 5}', "clocked: 'id'"),
    ],
)
def test_bad_clock_and_pointer_messages_say_what_is_wrong(text, problem):
    with pytest.raises(ProtocolError, match=problem):
        parse_participant_message(text)

"""A virtual participant's page: the frames it draws and reports, and the pointer it sends, read
back by the server's own message parser."""

from __future__ import annotations

import json

import pytest

from mirror_avatar.lab.running.messages import PointerBatch, Shown, parse_participant_message
from mirror_avatar.lab.running.pilot import StandIn
from mirror_avatar.lab.running.stand_in_page import (
    ANIMATION_PERIOD_MS,
    SHOWN_BATCH,
    PageDisplay,
    next_frame_ms,
    pointer_batches,
)


def frame(k: int, *partners: float | None, due: float | None = None) -> dict[str, object]:
    message: dict[str, object] = {"type": "frame", "k": k, "x": [0.0, *partners]}
    if due is not None:
        message["due"] = due
    return message


def reported(display: PageDisplay) -> list[tuple[int, float]]:
    """The draws of the display's reports, as the server reads them."""
    draws = []
    for text in display.reports():
        shown = parse_participant_message(text)
        assert isinstance(shown, Shown)
        draws += list(zip(shown.k, shown.t_ms, strict=True))
    return draws


def test_a_page_draws_the_newest_frame_arrived_and_never_one_superseded():
    display = PageDisplay()
    display.draw(0.0)
    assert display.partners == {}
    display.receive(frame(0, 0.1))
    display.receive(frame(1, 0.2))
    display.draw(16.7)
    assert display.partners == {0: 0.2}
    display.draw(33.3)  # nothing new: the partner stays drawn, no new draw reported
    for k in range(2, 2 + SHOWN_BATCH - 1):
        display.receive(frame(k, 0.01 * k))
        display.draw(20.0 * k)
    assert reported(display) == [(1, 16.7)] + [(k, 20.0 * k) for k in range(2, SHOWN_BATCH + 1)]
    assert reported(display) == []


def test_an_equalised_frame_is_held_until_its_due_time():
    display = PageDisplay()
    display.receive(frame(0, 0.1, due=100.0))
    display.receive(frame(1, 0.2, due=130.0))
    display.draw(99.9)
    assert display.partners == {}
    display.draw(100.0)
    assert display.partners == {0: 0.1}
    display.draw(129.0)
    assert display.partners == {0: 0.1}
    display.draw(140.04)
    assert display.partners == {0: 0.2}
    for t in range(200, 200 + 10 * (SHOWN_BATCH - 2), 10):
        display.receive(frame(t, 0.3, due=float(t)))
        display.draw(float(t))
    assert reported(display)[:2] == [(0, 100.0), (1, 140.0)]


def test_a_hidden_partner_is_not_drawn_nor_reported_and_a_countdown_forgets_all():
    display = PageDisplay()
    display.receive(frame(0, 0.1, 0.2))
    display.draw(1.0)
    assert display.partners == {0: 0.1, 1: 0.2}
    display.receive(frame(1, None, 0.3))
    display.draw(2.0)
    assert display.partners == {1: 0.3}
    display.receive(frame(2, None, None))
    display.draw(3.0)
    assert display.partners == {}
    display.receive(frame(3, 0.4, None))
    display.clear()
    display.draw(4.0)
    assert display.partners == {}
    for k in range(4, 4 + SHOWN_BATCH):
        display.receive(frame(k, 0.5))
        display.draw(float(k))
    assert [k for k, _ in reported(display)] == list(range(4, 4 + SHOWN_BATCH))


@pytest.mark.parametrize(
    ("now", "expected"),
    [(0.0, 1), (ANIMATION_PERIOD_MS - 1e-6, 1), (ANIMATION_PERIOD_MS + 1e-6, 2), (100.0, 7)],
)
def test_the_next_animation_frame_is_the_first_after_now_on_the_60_hz_grid(now, expected):
    assert next_frame_ms(1000.0, 1000.0 + now) == pytest.approx(1000.0 + expected * 1000.0 / 60.0)


def test_pointer_batches_split_at_the_server_s_bound_and_keep_each_read_time():
    samples = [(1000.0 + 10.0 * n, 0.001 * n) for n in range(25)]
    messages = pointer_batches(samples, 1250.0, 7)
    batches = [parse_participant_message(json.dumps(m)) for m in messages]
    assert all(isinstance(b, PointerBatch) for b in batches)
    assert [b.seq for b in batches] == [7, 8]  # type: ignore[union-attr]
    read = [value for b in batches for s in b.samples for value in s]  # type: ignore[union-attr]
    assert read == pytest.approx([value for s in samples for value in s])


def test_a_stand_in_steps_every_control_period_of_its_clock_on_the_partners_drawn():
    stand_in = StandIn("P2", "kuramoto", seed=1)
    stand_in.welcome({"role": "follower"})
    stand_in.countdown()
    stand_in.start(1, 0.0)
    stand_in.display.receive(frame(0, 0.25))
    sent = [parse_participant_message(m) for m in stand_in.animate(100.0)]
    (batch,) = sent
    assert isinstance(batch, PointerBatch)
    assert [t for t, _ in batch.samples] == pytest.approx([30.0, 60.0, 90.0])
    assert stand_in.display.partners == {0: 0.25}
    (held,) = [parse_participant_message(m) for m in stand_in.animate(110.0)]
    assert isinstance(held, PointerBatch) and held.seq == batch.seq + 1
    assert held.samples == [(pytest.approx(110.0), batch.samples[-1][1])]
    stand_in.stop()
    (still,) = [parse_participant_message(m) for m in stand_in.animate(500.0)]
    assert isinstance(still, PointerBatch)
    assert still.samples == [(pytest.approx(500.0), batch.samples[-1][1])]

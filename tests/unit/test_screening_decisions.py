"""Screening decisions: a page's round trips, frame rate and window at entry against the
protocol's bounds, its frame rate during play over a sliding window, a page's interruptions
paired and cut to a trial, recorded in the sidecar and counted in the table."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.trial_record import PageRecord, SlotRecord, TrialRecord, trial_record
from mirror_avatar.lab.design.checker import Checker
from mirror_avatar.lab.design.online import Screening, parse_online
from mirror_avatar.lab.running.messages import (
    FocusChange,
    WindowSize,
    parse_participant_message,
)
from mirror_avatar.lab.running.play_screening import PLAY_WINDOW_S, FrameWindow
from mirror_avatar.lab.running.screening import Entry, entry_refusal, round_trip_p95
from mirror_avatar.realtime.interruptions import Interruptions
from mirror_avatar.realtime.messages import ProtocolError


def test_the_95th_percentile_interpolates_between_the_ranks_around_it():
    # 100 round trips, ranks 0-94 at 100 ms and 95-99 at 400 ms: the 95th percentile lies at
    # rank 0.95 * 99 = 94.05, a twentieth of the way from 100 ms to 400 ms (115 ms)
    delays = [100.0] * 95 + [400.0] * 5
    assert round_trip_p95(delays) == pytest.approx(115.0)
    assert entry_refusal(Entry(delays), Screening(150.0)) is None
    assert entry_refusal(Entry(delays), Screening(114.0)) == (
        "Your connection's round trip (p95 115 ms) is above the study's 114 ms."
    )


def test_a_page_at_300_ms_is_refused_at_150_and_one_at_the_bound_is_admitted():
    assert entry_refusal(Entry([312.0] * 100), Screening(150.0)) == (
        "Your connection's round trip (p95 312 ms) is above the study's 150 ms."
    )
    assert entry_refusal(Entry([150.0] * 100), Screening(150.0)) is None


SIZED = Screening(frame_rate_hz=30.0, window_width_px=800, window_height_px=400)
"""A protocol screening frame rate and window, not round trips."""


def test_a_slow_page_or_a_small_window_is_refused_with_each_number_and_bound():
    fine = Entry([400.0] * 100, 59.6, (1280, 720))
    assert entry_refusal(fine, SIZED) is None  # round trips not screened here
    assert entry_refusal(Entry([20.0] * 100, 29.9, (800, 400)), SIZED) == (
        "Your browser drew 29.9 frames a second, fewer than the study's 30."
    )
    assert entry_refusal(Entry([20.0] * 100, 60.0, (640, 360)), SIZED) == (
        "Your window is 640 px wide, narrower than the study's 800 px. "
        "Your window is 360 px high, lower than the study's 400 px."
    )


def test_a_page_that_drew_nothing_or_never_said_its_window_is_refused():
    assert entry_refusal(Entry([20.0] * 100), SIZED) == (
        "Your browser drew 0 frames a second, fewer than the study's 30. "
        "Your window is 0 px wide, narrower than the study's 800 px. "
        "Your window is 0 px high, lower than the study's 400 px."
    )


def test_an_entry_is_recorded_with_what_it_measured():
    measured = Entry([100.0] * 95 + [400.0] * 5, 60.0, (1280, 720)).measured()
    assert measured["rtt_p95_ms"] == pytest.approx(115.0) and len(measured["rtt_ms"]) == 100
    assert measured["frame_rate_hz"] == 60.0 and measured["window_px"] == [1280, 720]


def test_the_protocol_declares_its_screening_and_defaults_to_none():
    check, here = Checker("study.toml"), Path(".")
    assert parse_online(check, {}, here).screening == Screening(None, "record")
    assert not Screening().at_entry
    declared = {"screen_round_trip_p95_ms": 150, "screen_hidden_tab": "refuse"}
    assert parse_online(check, declared, here).screening == Screening(150, "refuse")
    sized = {"screen_frame_rate_hz": 30, "screen_window_width_px": 800,
             "screen_window_height_px": 400}  # fmt: skip
    assert parse_online(check, sized, here).screening == SIZED and SIZED.at_entry


@pytest.mark.parametrize(
    ("key", "value", "said"),
    [("screen_frame_rate_hz", 0, "a number in [1, 1000] Hz"),
     ("screen_window_width_px", 800.5, "a whole number in [100, 100000] px")],
)  # fmt: skip
def test_a_bad_screening_bound_is_refused_naming_the_key(key: str, value: float, said: str):
    with pytest.raises(InputError, match=rf"study.toml: online.{key}: .*{re.escape(said)}"):
        parse_online(Checker("study.toml"), {key: value}, Path("."))


def test_a_page_says_its_window_in_css_pixels():
    message = '{"type": "window", "width": 1280, "height": 720}'
    assert parse_participant_message(message) == WindowSize(1280, 720)
    for bad in ('{"type": "window", "width": 0, "height": 720}',
                '{"type": "window", "width": 1280.5, "height": 720}',
                '{"type": "window", "width": 1280, "height": 100001}'):  # fmt: skip
        with pytest.raises(ProtocolError, match="window: "):
            parse_participant_message(bad)


def test_a_page_reports_its_focus_changes_with_its_own_time():
    message = '{"type": "focus", "event": "hidden", "t": 1700000000123.5}'
    assert parse_participant_message(message) == FocusChange("hidden", 1700000000123.5)
    with pytest.raises(ProtocolError, match="focus: 'event' must be one of hidden, blur"):
        parse_participant_message('{"type": "focus", "event": "minimised", "t": 1}')
    with pytest.raises(ProtocolError):
        parse_participant_message('{"type": "focus", "event": "blur"}')


def test_interruptions_pair_each_start_with_its_end_and_are_cut_to_the_trial():
    spans = Interruptions()
    assert spans.event("visible", 1.0) is None  # an end without a start
    assert spans.event("hidden", 2.0) is None
    assert spans.event("blur", 2.1) is None
    assert spans.event("hidden", 2.5) is None  # the page's state repeated: the first start kept
    assert spans.event("visible", 4.0) == ("hidden", 2.0, 4.0)
    assert spans.event("focus", 4.2) == ("blur", 2.1, 4.2)
    assert spans.event("hidden", 9.0) is None  # still hidden when the trial ends
    assert spans.between(3.0, 10.0) == [
        {"kind": "hidden", "start_s": 3.0, "end_s": 4.0},
        {"kind": "blur", "start_s": 3.0, "end_s": 4.2},
        {"kind": "hidden", "start_s": 9.0, "end_s": 10.0, "open": True},
    ]
    assert spans.between(5.0, 8.0) == []


def test_the_table_counts_each_kind_of_interruption_and_its_length():
    interruptions = (
        {"kind": "hidden", "start_s": 3.0, "end_s": 4.5},
        {"kind": "blur", "start_s": 3.0, "end_s": 4.75},
        {"kind": "hidden", "start_s": 9.0, "end_s": 10.0, "open": True},
    )
    page = PageRecord(0, {}, None, None, None, None, (), interruptions)
    cells = page.cells()
    assert (cells["page_hidden"], cells["page_hidden_s"]) == (2, 2.5)
    assert (cells["page_blur"], cells["page_blur_s"]) == (1, 1.75)
    assert page.to_json()["interruptions"] == list(interruptions)
    record = TrialRecord("s", 1, "solo", (SlotRecord("P1", "human", "solo"),), pages={"P1": page})
    assert trial_record(json.loads(json.dumps(record.metadata_json()))) == record


def test_the_frame_rate_during_play_is_counted_over_the_last_two_seconds():
    window = FrameWindow(PLAY_WINDOW_S)
    for sent_ms in range(0, 1981, 20):  # 50 Hz from 0 to 1980 ms: not yet a whole window
        window.add(float(sent_ms))
    assert window.rate_hz() is None
    window.add(2000.0)  # (0, 2000] holds the frames at 20, 40, ..., 2000 ms: 100 in 2 s
    assert window.rate_hz() == pytest.approx(50.0)
    window.add(2000.0)  # a second batch of the same frame
    assert window.rate_hz() == pytest.approx(50.0)
    for sent_ms in range(2100, 3001, 100):  # then 10 Hz: 2100, 2200, ..., 3000 ms
        window.add(float(sent_ms))
    # (1000, 3000] holds 50 frames at 50 Hz (1020 to 2000 ms) and 10 at 10 Hz: 60 in 2 s
    assert window.rate_hz() == pytest.approx(30.0)
    window.clear()
    window.add(5000.0)
    assert window.rate_hz() is None


def test_a_page_below_its_bounds_is_an_interruption_with_its_reason():
    spans = Interruptions()
    reason = "Your browser drew 12 frames a second, fewer than the study's 30."
    assert spans.begin("below_bounds", 2.0, reason)
    assert not spans.begin("below_bounds", 2.5, "another")  # already below: the first kept
    assert spans.between(1.0, 3.0) == [
        {"kind": "below_bounds", "start_s": 2.0, "end_s": 3.0, "reason": reason, "open": True}
    ]
    assert spans.end("below_bounds", 4.0) == ("below_bounds", 2.0, 4.0)
    assert spans.end("below_bounds", 5.0) is None
    (span,) = spans.between(1.0, 6.0)
    page = PageRecord(0, {}, None, None, None, None, (), (span,))
    assert (page.cells()["page_below_bounds"], page.cells()["page_below_bounds_s"]) == (1, 2.0)
    record = TrialRecord("s", 1, "solo", (SlotRecord("P1", "human", "solo"),), pages={"P1": page})
    assert trial_record(json.loads(json.dumps(record.metadata_json()))) == record


def test_the_protocol_holds_its_bounds_during_play_only_when_asked():
    check, here = Checker("study.toml"), Path(".")
    sized = {"screen_frame_rate_hz": 30}
    assert parse_online(check, sized, here).screening.during_play == "off"
    assert not parse_online(check, sized, here).screening.in_play
    played = parse_online(check, sized | {"screen_during_play": "record"}, here).screening
    assert played.in_play and played.during_play == "record"
    timed = {"screen_round_trip_p95_ms": 150, "screen_during_play": "refuse"}
    assert parse_online(check, timed, here).screening.in_play
    with pytest.raises(InputError, match=r"online.screen_during_play: 'refuse' has no bound"):
        parse_online(check, {"screen_during_play": "refuse"}, here)

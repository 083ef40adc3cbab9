"""Screening decisions: a page's round trips, frame rate and window at entry against the
protocol's bounds, a page's interruptions paired and cut to a trial, recorded in the sidecar and
counted in the table."""

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

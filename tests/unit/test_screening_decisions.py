"""Screening decisions: a page's round trips at entry against the protocol's bound, a page's
interruptions paired and cut to a trial, recorded in the sidecar and counted in the table."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mirror_avatar.files.trial_record import PageRecord, SlotRecord, TrialRecord, trial_record
from mirror_avatar.lab.design.checker import Checker
from mirror_avatar.lab.design.online import Screening, parse_online
from mirror_avatar.lab.running.messages import FocusChange, parse_participant_message
from mirror_avatar.lab.running.screening import entry_refusal, round_trip_p95
from mirror_avatar.realtime.interruptions import Interruptions
from mirror_avatar.realtime.messages import ProtocolError


def test_the_95th_percentile_interpolates_between_the_ranks_around_it():
    # 100 round trips, ranks 0-94 at 100 ms and 95-99 at 400 ms: the 95th percentile lies at
    # rank 0.95 * 99 = 94.05, a twentieth of the way from 100 ms to 400 ms (115 ms)
    delays = [100.0] * 95 + [400.0] * 5
    assert round_trip_p95(delays) == pytest.approx(115.0)
    assert entry_refusal(delays, 150.0) is None
    assert entry_refusal(delays, 114.0) == (
        "Your connection's round trip (p95 115 ms) is above the study's 114 ms."
    )


def test_a_page_at_300_ms_is_refused_at_150_and_one_at_the_bound_is_admitted():
    assert entry_refusal([312.0] * 100, 150.0) == (
        "Your connection's round trip (p95 312 ms) is above the study's 150 ms."
    )
    assert entry_refusal([150.0] * 100, 150.0) is None


def test_the_protocol_declares_its_screening_and_defaults_to_none():
    check, here = Checker("study.toml"), Path(".")
    assert parse_online(check, {}, here).screening == Screening(None, "record")
    declared = {"screen_round_trip_p95_ms": 150, "screen_hidden_tab": "refuse"}
    assert parse_online(check, declared, here).screening == Screening(150, "refuse")


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

"""Parsing the browser's messages: valid ones become typed requests, anything else one error."""

from __future__ import annotations

import contextlib
import json

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mirror_avatar.live.messages import (
    PositionUpdate,
    ProtocolError,
    StartRequest,
    StopRequest,
    parse_message,
)
from mirror_avatar.realtime.messages import MAX_MESSAGE_BYTES


def test_valid_messages_are_parsed():
    assert parse_message('{"type": "position", "seq": 3, "x": -0.25, "rtt": 1.5}') == (
        PositionUpdate(seq=3, x=-0.25, rtt_ms=1.5)
    )
    assert parse_message('{"type": "position", "seq": 0, "x": 0.5, "rtt": null}').rtt_ms is None
    start = parse_message(
        json.dumps(
            {"type": "start", "mode": "joint", "participant": "P-1_a", "duration": 60, "seed": 7}
        )
    )
    assert start == StartRequest(mode="joint", participant="P-1_a", duration=60.0, seed=7)
    assert parse_message('{"type": "stop"}') == StopRequest()


@pytest.mark.parametrize(
    ("message", "problem"),
    [
        (b'{"type": "stop"}', "only text"),
        (None, "only text"),
        ("{", "not valid JSON"),
        ("[]", "not a JSON object"),
        ('{"type": "teleport"}', "unknown message type"),
        ('{"seq": 1, "x": 0}', "unknown message type"),
        ('{"type": "position", "x": 0.1}', "'seq'"),
        ('{"type": "position", "seq": -1, "x": 0.1}', "'seq'"),
        ('{"type": "position", "seq": true, "x": 0.1}', "'seq'"),
        ('{"type": "position", "seq": 1.5, "x": 0.1}', "'seq'"),
        ('{"type": "position", "seq": 1}', "'x' must be a number"),
        ('{"type": "position", "seq": 1, "x": "0.1"}', "'x' must be a number"),
        ('{"type": "position", "seq": 1, "x": true}', "'x' must be a number"),
        ('{"type": "position", "seq": 1, "x": NaN}', "finite"),
        ('{"type": "position", "seq": 1, "x": Infinity}', "finite"),
        ('{"type": "position", "seq": 1, "x": 0.5001}', "outside the playing range"),
        ('{"type": "position", "seq": 1, "x": -3}', "outside the playing range"),
        ('{"type": "position", "seq": 1, "x": 1' + "0" * 400 + "}", "too large"),
        ('{"type": "position", "seq": 1, "x": 0, "rtt": -1}', "rtt"),
        ('{"type": "position", "seq": 1, "x": 0, "rtt": 1e9}', "rtt"),
        ('{"type": "start", "mode": "duel", "participant": "a", "duration": 5}', "mode"),
        ('{"type": "start", "mode": "solo", "participant": "../x", "duration": 5}', "participant"),
        ('{"type": "start", "mode": "solo", "participant": "", "duration": 5}', "participant"),
        ('{"type": "start", "mode": "solo", "participant": 7, "duration": 5}', "participant"),
        ('{"type": "start", "mode": "solo", "participant": "a", "duration": 0.5}', "duration"),
        ('{"type": "start", "mode": "solo", "participant": "a", "duration": 1e4}', "duration"),
        ('{"type": "start", "mode": "solo", "participant": "a"}', "'duration'"),
        (
            '{"type": "start", "mode": "solo", "participant": "a", "duration": 5, "seed": -2}',
            "seed",
        ),
        (
            '{"type": "start", "mode": "solo", "participant": "a", "duration": 5, "seed": "1"}',
            "seed",
        ),
        ('{"type": "stop", "pad": "' + "x" * MAX_MESSAGE_BYTES + '"}', "longer than"),
    ],
)
def test_bad_messages_raise_one_protocol_error(message, problem):
    with pytest.raises(ProtocolError, match=problem) as error:
        parse_message(message)
    assert "\n" not in str(error.value)


def test_size_limit_counts_bytes_not_characters():
    short = '{"type": "stop", "p": "' + "é" * 200 + '"}'
    long = '{"type": "stop", "p": "' + "é" * 250 + '"}'  # 275 characters, 525 bytes
    assert len(long) < MAX_MESSAGE_BYTES < len(long.encode())
    assert parse_message(short) == StopRequest()
    with pytest.raises(ProtocolError, match="longer than"):
        parse_message(long)


@given(st.one_of(st.text(max_size=600), st.binary(max_size=64), st.none()))
def test_arbitrary_input_never_raises_anything_else(message):
    with contextlib.suppress(ProtocolError):
        parse_message(message)


@given(
    st.recursive(
        st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=8),
        lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=6), inner),
        max_leaves=8,
    ),
    st.sampled_from(["position", "start", "stop", "other"]),
)
def test_arbitrary_json_objects_are_parsed_or_refused(value, kind):
    fields = value if isinstance(value, dict) else {"x": value, "seq": value}
    message = json.dumps({**fields, "type": kind})
    try:
        parsed = parse_message(message)
    except ProtocolError:
        return
    if isinstance(parsed, PositionUpdate):
        assert -0.5 <= parsed.x <= 0.5 and parsed.seq >= 0

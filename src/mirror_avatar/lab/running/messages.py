"""Messages between a participant's page and the lab server, and their validation.

The page sends JSON text messages (at most `mirror_avatar.realtime.messages.MAX_MESSAGE_BYTES`):

- ``{"type": "position", "seq": n, "x": x}``: the pointer's latest position (units), numbered
  ``n`` from 0 on each connection, sent once per animation frame while a trial runs;
- ``{"type": "pong", "id": i, "late_frames": f}``: the answer to the server's ``ping`` ``i``
  (the server measures the round trip), with the number of animation frames the page drew
  late so far (more than twice the display's frame interval);
- ``{"type": "answer", "trial": n, "question": id, "value": v}``: the participant's answer to
  a question asked after trial ``n`` (a study protocol's ``questions`` message).

The server sends ``welcome`` (the participant's slot, the players it sees and their colours),
``ping``, ``countdown``, ``go``, ``frame`` (once per tick: the sample ``k``, the visible
players' positions and the trial's progress), ``end`` (the trial's metrics when the researcher
shows them), ``state`` (waiting, paused, ended) and ``error``. A participant cannot control
the session: no message it sends does more than move its own point.
"""

from __future__ import annotations

from dataclasses import dataclass

from mirror_avatar.realtime.messages import (
    PositionUpdate,
    ProtocolError,
    parse_json_object,
    parse_position,
)

MAX_COUNT = 2**31
"""Largest ping id or late-frame count accepted."""


@dataclass(frozen=True)
class Pong:
    """The page's answer to ping ``id``, with its count of late animation frames."""

    id: int
    late_frames: int


@dataclass(frozen=True)
class Answer:
    """The participant's answer ``value`` (text or integer) to ``question`` after ``trial``."""

    trial: int
    question: str
    value: str | int


ParticipantMessage = PositionUpdate | Pong | Answer


def parse_participant_message(text: str | bytes | None) -> ParticipantMessage:
    """Parse and validate one message from a participant's page.

    Raises
    ------
    ProtocolError
        Binary, oversized, not a JSON object, an unknown type, or a bad field.
    """
    data = parse_json_object(text)
    kind = data.get("type")
    if kind == "position":
        return parse_position(data)
    if kind == "pong":
        return Pong(_count(data, "id"), _count(data, "late_frames"))
    if kind == "answer":
        question, value = data.get("question"), data.get("value")
        if not isinstance(question, str) or not isinstance(value, str | int) or value is True:
            raise ProtocolError("answer: 'question' must be text, 'value' text or an integer")
        return Answer(_count(data, "trial"), question, value)
    raise ProtocolError(f"unknown message type {kind!r}")


def _count(data: dict[str, object], key: str) -> int:
    value = data.get(key, 0)
    if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value < MAX_COUNT:
        raise ProtocolError(f"pong: {key!r} must be a non-negative integer")
    return value

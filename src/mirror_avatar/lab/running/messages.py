"""Messages between a participant's page and the lab server, and their validation.

The page sends JSON text messages (at most `mirror_avatar.realtime.messages.MAX_MESSAGE_BYTES`):

- ``{"type": "position", "seq": n, "x": x}``: the pointer's latest position (units), numbered
  ``n`` from 0 on each connection, sent once per animation frame while a trial runs; the page
  that steps an avatar (`mirror_avatar.lab.running.page_avatar`) adds, once per tick,
  ``"avatar": {"tick": j, "x": a, "v": w}``: the avatar's position (units) and velocity
  (units/s) at tick j, stepped from the person's position ``x`` (`AvatarPosition`);
- ``{"type": "pong", "id": i, "late_frames": f}``: the answer to the server's ``ping`` ``i``
  (the server measures the round trip), with the number of animation frames the page drew
  late so far (more than twice the display's frame interval);
- ``{"type": "answer", "trial": n, "question": id, "value": v}``: the participant's answer to
  a question asked after trial ``n`` (a study protocol's ``questions`` message).

The server sends ``welcome`` (the participant's slot, the players it sees and their colours),
``ping``, ``countdown``, ``avatar`` (the player index and message of the avatar the page
steps, `mirror_avatar.browser.browser_arrays`), ``go``, ``frame`` (once per tick: the sample
``k``, the visible players' positions and the trial's progress), ``end`` (the trial's metrics
when the researcher shows them), ``state`` (waiting, paused, ended) and ``error``. A participant
cannot control the session: no message it sends does more than move its own point (and the
avatar its page steps).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from mirror_avatar.files.trials import PLAYING_RANGE
from mirror_avatar.files.user_files import is_int
from mirror_avatar.lab.running.page_avatar import PageStep
from mirror_avatar.realtime.messages import (
    PositionUpdate,
    ProtocolError,
    number_field,
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


@dataclass(frozen=True)
class AvatarPosition:
    """The person's position and the avatar's state at a tick, stepped from that position."""

    position: PositionUpdate
    step: PageStep


ParticipantMessage = PositionUpdate | AvatarPosition | Pong | Answer


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
        position = parse_position(data)
        return position if "avatar" not in data else _avatar(data["avatar"], position)
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


def _avatar(value: object, position: PositionUpdate) -> AvatarPosition:
    """Read a position's ``avatar``: a tick, a position in the playing range, a finite velocity."""
    if not isinstance(value, dict):
        raise ProtocolError("position: 'avatar' must be an object {tick, x, v}")
    tick = value.get("tick")
    if not is_int(tick) or not 0 <= tick < MAX_COUNT:
        raise ProtocolError("avatar: 'tick' must be a non-negative integer")
    x, v = number_field(value, "x", "avatar"), number_field(value, "v", "avatar")
    low, high = PLAYING_RANGE
    if not low <= x <= high:
        raise ProtocolError(f"avatar: x = {x:g} is outside the playing range [{low}, {high}]")
    seen = position.x if tick > 0 else math.nan
    return AvatarPosition(position, PageStep(tick, x, v, seen))

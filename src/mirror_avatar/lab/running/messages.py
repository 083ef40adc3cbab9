"""Messages between a participant's page and the lab server, and their validation.

The page sends JSON text messages (at most `mirror_avatar.realtime.messages.MAX_MESSAGE_BYTES`):

- ``{"type": "pointer", "seq": n, "sent": s, "ago": [a, ...], "x": [x, ...]}``: the pointer's
  samples (units) read since the previous batch, at the device's rate (coalesced pointer
  events), oldest first, each read ``a`` ms before the batch was sent at ``s`` (ms, the page's
  clock: ``performance.timeOrigin + performance.now()``); numbered ``n`` from 0 on each
  connection, at least one per animation frame (the current position when the pointer did not
  move);
- ``{"type": "position", "seq": n, "x": x}``: a position without its time, numbered with the
  ``pointer`` batches; the page that steps an avatar (`mirror_avatar.lab.running.page_avatar`)
  sends one per tick, with
  ``"avatar": {"tick": j, "x": a, "v": w}``: the avatar's position (units) and velocity
  (units/s) at tick j, stepped from the person's position ``x`` (`AvatarPosition`);
- ``{"type": "clock", "id": i, "t0": t}``: an NTP-style request sent at ``t`` (ms, the page's
  clock), which the server answers at once with ``t0`` and its own receipt and send times
  ``t1`` and ``t2`` (ms, its clock); ``{"type": "clocked", "id": i, "t3": t}``: when the answer
  arrived (ms, the page's clock) (`mirror_avatar.realtime.page_clock`);
- ``{"type": "pong", "id": i, "late_frames": f}``: the answer to the server's ``ping`` ``i``
  (the server measures the round trip), with the number of animation frames the page drew
  late so far (more than twice the display's frame interval);
- ``{"type": "focus", "event": e, "t": t}``: the page's tab was hidden or shown again
  (``e``: ``hidden``, ``visible``) or its window lost or regained the focus (``blur``,
  ``focus``) at ``t`` (ms, the page's clock) (`mirror_avatar.realtime.interruptions`);
- ``{"type": "window", "width": w, "height": h}``: the page's window (its viewport, CSS
  pixels) as it connects and after each resize (`WindowSize`; screened at entry:
  `mirror_avatar.lab.running.screening`);
- ``{"type": "answer", "trial": n, "question": id, "value": v}``: the participant's answer to
  a question asked after trial ``n`` (a study protocol's ``questions`` message);
- ``{"type": "shown", "k": [k, ...], "t": [t, ...]}``: the frames the page drew (each frame's
  sample ``k``) and when (``t``: the animation frame's time, ms, the page's clock), at most
  `MAX_BATCH` (`mirror_avatar.lab.running.views`).

The server sends ``welcome`` (the participant's slot, the players it sees and their colours),
``ping``, ``countdown``, ``avatar`` (the player index and message of the avatar the page
steps, `mirror_avatar.browser.browser_arrays`), ``go``, ``frame`` (once per tick: the sample
``k``, the visible players' positions, the trial's progress and, for an equalised view, the
page time ``due`` at which to draw it: `mirror_avatar.lab.running.partner_frames`), ``end``
(the trial's metrics when the researcher shows them), ``state`` (waiting, paused, ended),
``notice`` (one line to show the participant: `mirror_avatar.lab.running.screening`),
``refused`` and ``error``. A
participant cannot control the session: no message it sends does more than move its own point
(and the avatar its page steps).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from mirror_avatar.files.trials import PLAYING_RANGE
from mirror_avatar.files.user_files import is_int
from mirror_avatar.lab.running.page_avatar import PageStep
from mirror_avatar.realtime.interruptions import EVENTS
from mirror_avatar.realtime.messages import (
    PositionUpdate,
    ProtocolError,
    number_field,
    parse_json_object,
    parse_position,
)

MAX_COUNT = 2**31
"""Largest ping id or late-frame count accepted."""

MAX_BATCH = 20
"""Most samples in one ``pointer`` message (a 1000 Hz mouse at 60 frames a second sends 17)."""

MAX_AGO_MS = 10_000.0
"""Longest a sample may have been read before its batch was sent (ms)."""


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


@dataclass(frozen=True)
class PointerBatch:
    """Pointer samples: batch ``seq`` sent at ``sent_ms`` (ms, the page's clock).

    Its ``samples`` are (page time in ms, position in units), oldest first.
    """

    seq: int
    sent_ms: float
    samples: list[tuple[float, float]]


@dataclass(frozen=True)
class ClockRequest:
    """NTP-style request ``id`` sent at ``t0`` (ms, the page's clock)."""

    id: int
    t0: float


@dataclass(frozen=True)
class ClockReport:
    """The page's receipt ``t3`` (ms, its clock) of the answer to request ``id``."""

    id: int
    t3: float


@dataclass(frozen=True)
class FocusChange:
    """The page's tab hidden or shown, or its window blurred or focused (``event``), at ``t_ms``.

    ``t_ms``: ms, the page's clock; ``event``: one of
    `mirror_avatar.realtime.interruptions.EVENTS`.
    """

    event: str
    t_ms: float


@dataclass(frozen=True)
class WindowSize:
    """The page's viewport: ``width`` and ``height`` in CSS pixels."""

    width: int
    height: int


MAX_WINDOW_PX = 100_000
"""Largest window side a page may report (CSS pixels)."""


@dataclass(frozen=True)
class Shown:
    """Frames the page drew: each frame's sample ``k`` and its draw's time ``t_ms`` (ms, page)."""

    k: list[int]
    t_ms: list[float]


ParticipantMessage = (
    PositionUpdate
    | AvatarPosition
    | Pong
    | Answer
    | PointerBatch
    | ClockRequest
    | ClockReport
    | FocusChange
    | WindowSize
    | Shown
)


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
    if kind == "pointer":
        return _pointer(data)
    if kind == "clock":
        return ClockRequest(_count(data, "id"), number_field(data, "t0", "clock"))
    if kind == "clocked":
        return ClockReport(_count(data, "id"), number_field(data, "t3", "clocked"))
    if kind == "focus":
        event = data.get("event")
        if event not in EVENTS:
            raise ProtocolError(f"focus: 'event' must be one of {', '.join(EVENTS)}")
        return FocusChange(str(event), number_field(data, "t", "focus"))
    if kind == "shown":
        return _shown(data)
    if kind == "window":
        width, height = _count(data, "width"), _count(data, "height")
        if not (0 < width <= MAX_WINDOW_PX and 0 < height <= MAX_WINDOW_PX):
            raise ProtocolError(f"window: 'width' and 'height' must be 1 to {MAX_WINDOW_PX} px")
        return WindowSize(width, height)
    if kind == "pong":
        return Pong(_count(data, "id"), _count(data, "late_frames"))
    if kind == "answer":
        question, value = data.get("question"), data.get("value")
        if not isinstance(question, str) or not isinstance(value, str | int) or value is True:
            raise ProtocolError("answer: 'question' must be text, 'value' text or an integer")
        return Answer(_count(data, "trial"), question, value)
    raise ProtocolError(f"unknown message type {kind!r}")


def _pointer(data: dict[str, object]) -> PointerBatch:
    """Validate a ``pointer`` message: as many ages as positions, 1 to `MAX_BATCH`."""
    ago, xs = data.get("ago"), data.get("x")
    if not isinstance(ago, list) or not isinstance(xs, list) or len(ago) != len(xs):
        raise ProtocolError("pointer: 'ago' and 'x' must be lists of the same length")
    if not 1 <= len(xs) <= MAX_BATCH:
        raise ProtocolError(f"pointer: 1 to {MAX_BATCH} samples per message")
    sent = number_field(data, "sent", "pointer")
    samples = []
    for a, x in zip(ago, xs, strict=True):
        position = parse_position({"seq": 0, "x": x}).x
        age = number_field({"ago": a}, "ago", "pointer")
        if not 0.0 <= age <= MAX_AGO_MS:
            raise ProtocolError(f"pointer: ago = {age:g} ms is outside [0, {MAX_AGO_MS:g}]")
        samples.append((sent - age, position))
    return PointerBatch(_count(data, "seq"), sent, samples)


def _shown(data: dict[str, object]) -> Shown:
    """Validate a ``shown`` message: as many times as samples, 1 to `MAX_BATCH`."""
    ks, ts = data.get("k"), data.get("t")
    if not isinstance(ks, list) or not isinstance(ts, list) or len(ks) != len(ts):
        raise ProtocolError("shown: 'k' and 't' must be lists of the same length")
    if not 1 <= len(ks) <= MAX_BATCH:
        raise ProtocolError(f"shown: 1 to {MAX_BATCH} frames per message")
    samples = [_count({"type": "shown", "k": k}, "k") for k in ks]
    return Shown(samples, [number_field({"t": t}, "t", "shown") for t in ts])


def _count(data: dict[str, object], key: str) -> int:
    value = data.get(key, 0)
    if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value < MAX_COUNT:
        raise ProtocolError(f"{data.get('type')}: {key!r} must be a non-negative integer")
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

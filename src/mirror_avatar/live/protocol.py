"""Messages between the browser and the live server, and their validation.

The browser sends JSON text messages, one object each, with a ``type`` field:

- ``{"type": "start", "mode": M, "participant": P, "duration": D}`` asks for a trial of ``D``
  seconds in mode ``M`` (one of `MODES`) for participant ``P``; an optional integer ``seed``
  fixes the avatar's randomness (otherwise the server draws one and records it).
- ``{"type": "position", "seq": n, "x": x, "rtt": r}`` is the pointer's latest position ``x``
  (units, within the playing range) sent once per animation frame, numbered ``n``; ``r`` is the
  last round trip the browser measured (ms), or ``null`` before the first.
- ``{"type": "stop"}`` ends the running trial early (it is saved, marked incomplete).
- ``{"type": "build", "participant": P}`` builds P's personal avatar from their recorded solo
  trials (`mirror_avatar.live.avatar_build`); it then plays this connection's trials.

The server replies with ``ready``, ``countdown``, ``go``, ``avatar`` (one per ``position``:
``{"type": "avatar", "seq": n, "x": avatar position, "progress": fraction of the trial}``),
``done`` (metrics and file names), ``building`` (a build's stage), ``built`` (the avatar's file
and the modes it plays) and ``error`` messages. Anything malformed raises
`ProtocolError`, whose message is sent back to the browser as an ``error``.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from typing import Any

from mirror_avatar.trials import PLAYING_RANGE

MODES = ("solo", "avatar_leads", "avatar_follows", "joint")
"""Trial modes: the person alone, the avatar leading, the avatar following, joint improvisation."""

MAX_MESSAGE_BYTES = 512
"""Longest message accepted (bytes); a position update is about 60."""

DURATION_RANGE = (1.0, 600.0)
"""Shortest and longest trial a browser may ask for (s)."""

MAX_RTT_MS = 60_000.0
"""Largest round trip (ms) accepted from a browser's report."""

PARTICIPANT_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]{0,31}")
"""Participant ids: they become file and folder names, so only letters, digits, ``_`` and ``-``,
starting with a letter or digit (a leading ``-`` reads as an option to shell commands)."""


class ProtocolError(ValueError):
    """A message from the browser that cannot be used; the text says why in one line."""


@dataclass(frozen=True)
class StartRequest:
    """A request to start a trial."""

    mode: str
    participant: str
    duration: float
    seed: int | None = None


@dataclass(frozen=True)
class PositionUpdate:
    """The pointer's latest position (units) and the browser's last round trip (ms)."""

    seq: int
    x: float
    rtt_ms: float | None = None


@dataclass(frozen=True)
class StopRequest:
    """A request to end the running trial now."""


@dataclass(frozen=True)
class BuildRequest:
    """A request to build a participant's avatar from their recorded solo trials."""

    participant: str


Message = StartRequest | PositionUpdate | StopRequest | BuildRequest


def parse_message(text: str | bytes | None) -> Message:
    """Parse and validate one message from the browser.

    Parameters
    ----------
    text
        The WebSocket frame's text (binary frames are refused).

    Returns
    -------
    StartRequest or PositionUpdate or StopRequest or BuildRequest

    Raises
    ------
    ProtocolError
        If the frame is binary, longer than `MAX_MESSAGE_BYTES`, not a JSON object, of an
        unknown type, or has a missing, mistyped or out-of-range field.
    """
    data = parse_json_object(text)
    kind = data.get("type")
    if kind == "position":
        return parse_position(data)
    if kind == "start":
        return _parse_start(data)
    if kind == "stop":
        return StopRequest()
    if kind == "build":
        return BuildRequest(participant=_participant(data, "build"))
    raise ProtocolError(f"unknown message type {kind!r}")


def parse_json_object(text: str | bytes | None) -> dict[str, Any]:
    """Decode one text frame holding a JSON object of at most `MAX_MESSAGE_BYTES` bytes.

    Raises
    ------
    ProtocolError
        If the frame is binary, too long, not JSON or not an object.
    """
    if not isinstance(text, str):
        raise ProtocolError("only text messages are accepted")
    if len(text.encode()) > MAX_MESSAGE_BYTES:
        raise ProtocolError(f"message longer than {MAX_MESSAGE_BYTES} bytes")
    try:
        data = json.loads(text)
    except ValueError:
        raise ProtocolError("message is not valid JSON") from None
    if not isinstance(data, dict):
        raise ProtocolError("message is not a JSON object")
    return data


def parse_position(data: dict[str, Any]) -> PositionUpdate:
    """Validate a ``position`` message's fields (``seq``, ``x``, optional ``rtt``)."""
    seq = data.get("seq")
    if not isinstance(seq, int) or isinstance(seq, bool) or seq < 0:
        raise ProtocolError("position: 'seq' must be a non-negative integer")
    x = _number(data, "x", "position")
    low, high = PLAYING_RANGE
    if not low <= x <= high:
        raise ProtocolError(f"position: x = {x:g} is outside the playing range [{low}, {high}]")
    rtt = data.get("rtt")
    if rtt is not None:
        rtt = _number(data, "rtt", "position")
        if not 0.0 <= rtt <= MAX_RTT_MS:
            raise ProtocolError(f"position: rtt = {rtt:g} ms is outside [0, {MAX_RTT_MS:g}]")
    return PositionUpdate(seq=seq, x=x, rtt_ms=rtt)


def _parse_start(data: dict[str, Any]) -> StartRequest:
    mode = data.get("mode")
    if mode not in MODES:
        raise ProtocolError(f"start: mode must be one of {', '.join(MODES)}")
    participant = _participant(data, "start")
    duration = _number(data, "duration", "start")
    low, high = DURATION_RANGE
    if not low <= duration <= high:
        raise ProtocolError(f"start: duration must be between {low:g} and {high:g} s")
    seed = data.get("seed")
    if seed is not None and (not _is_int(seed) or not 0 <= seed < 2**63):
        raise ProtocolError("start: seed must be a non-negative integer")
    return StartRequest(mode=mode, participant=participant, duration=duration, seed=seed)


def _participant(data: dict[str, Any], kind: str) -> str:
    participant = data.get("participant")
    if not isinstance(participant, str) or not PARTICIPANT_PATTERN.fullmatch(participant):
        raise ProtocolError(
            f"{kind}: participant id must be 1-32 letters, digits, '_' or '-', starting with a "
            "letter or digit"
        )
    return participant


def _is_int(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _number(data: dict[str, Any], key: str, kind: str) -> float:
    value = data.get(key)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ProtocolError(f"{kind}: {key!r} must be a number")
    try:
        value = float(value)
    except OverflowError:
        raise ProtocolError(f"{kind}: {key!r} is too large") from None
    if not math.isfinite(value):
        raise ProtocolError(f"{kind}: {key!r} must be finite")
    return value

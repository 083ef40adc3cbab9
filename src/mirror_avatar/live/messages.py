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
``done`` (metrics and file names, and under ``build`` what the participant's solo trials now
allow: `mirror_avatar.live.avatar_build.build_readiness`), ``building`` (a build's stage),
``built`` (the avatar's file and the modes it plays) and ``error`` messages. Anything malformed
raises `ProtocolError`, whose message is sent back to the browser as an ``error``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from mirror_avatar.files.user_files import is_int
from mirror_avatar.realtime.messages import (
    PARTICIPANT_PATTERN,
    PositionUpdate,
    ProtocolError,
    number_field,
    parse_json_object,
    parse_position,
)

MODES = ("solo", "avatar_leads", "avatar_follows", "joint")
"""Trial modes: the person alone, the avatar leading, the avatar following, joint improvisation."""

DURATION_RANGE = (1.0, 600.0)
"""Shortest and longest trial a browser may ask for (s)."""


@dataclass(frozen=True)
class StartRequest:
    """A request to start a trial."""

    mode: str
    participant: str
    duration: float
    seed: int | None = None


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


def _parse_start(data: dict[str, Any]) -> StartRequest:
    mode = data.get("mode")
    if mode not in MODES:
        raise ProtocolError(f"start: mode must be one of {', '.join(MODES)}")
    participant = _participant(data, "start")
    duration = number_field(data, "duration", "start")
    low, high = DURATION_RANGE
    if not low <= duration <= high:
        raise ProtocolError(f"start: duration must be between {low:g} and {high:g} s")
    seed = data.get("seed")
    if seed is not None and (not is_int(seed) or not 0 <= seed < 2**63):
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

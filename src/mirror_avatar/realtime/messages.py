"""What every page sends the real-time servers: one JSON object per text frame, validated.

Both servers read a page's pointer as ``{"type": "position", "seq": n, "x": x}`` (units, within
the playing range, numbered ``n`` from 0 on each connection; the live page adds ``"rtt": r``, its
last measured round trip in ms). Anything malformed raises `ProtocolError`, whose one-line
message is sent back to the page as an ``error``.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from typing import Any

from mirror_avatar.files.trials import PLAYING_RANGE
from mirror_avatar.files.user_files import is_int

MAX_MESSAGE_BYTES = 512
"""Longest message accepted (bytes); a position update is about 60."""

MAX_RTT_MS = 60_000.0
"""Largest round trip (ms) accepted from a browser's report."""

PARTICIPANT_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]{0,31}")
"""Participant ids: they become file and folder names, so only letters, digits, ``_`` and ``-``,
starting with a letter or digit (a leading ``-`` reads as an option to shell commands)."""


class ProtocolError(ValueError):
    """A message from a page that cannot be used; the text says why in one line."""


@dataclass(frozen=True)
class PositionUpdate:
    """The pointer's latest position (units) and the browser's last round trip (ms)."""

    seq: int
    x: float
    rtt_ms: float | None = None


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
    if not is_int(seq) or seq < 0:
        raise ProtocolError("position: 'seq' must be a non-negative integer")
    x = number_field(data, "x", "position")
    low, high = PLAYING_RANGE
    if not low <= x <= high:
        raise ProtocolError(f"position: x = {x:g} is outside the playing range [{low}, {high}]")
    rtt = data.get("rtt")
    if rtt is not None:
        rtt = number_field(data, "rtt", "position")
        if not 0.0 <= rtt <= MAX_RTT_MS:
            raise ProtocolError(f"position: rtt = {rtt:g} ms is outside [0, {MAX_RTT_MS:g}]")
    return PositionUpdate(seq=seq, x=x, rtt_ms=rtt)


def number_field(data: dict[str, Any], key: str, kind: str) -> float:
    """Return ``data[key]`` as a finite float, or raise `ProtocolError` naming ``kind.key``."""
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

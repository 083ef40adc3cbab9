"""The proxy's truth: a row per chunk it carried, written as it is delivered.

Times are on the monotonic clock (`time.monotonic_ns`, written in seconds with 9 decimals), the
clock the lab server stamps its samples with (``clock_s`` of a trial's inputs file, on the same
machine), so the two compare with no conversion. The file's JSON companion (`write_companion`)
holds the network, the seed, the target, the proxy's address and its start, and one anchor to
the wall clock taken at the start (`time.time_ns` beside `time.monotonic_ns`).

Columns (`COLUMNS`): ``connection`` (numbered from 1 as accepted), ``direction`` (``up``:
page->server, ``down``: server->page), ``chunk`` (from 0 per connection and direction),
``bytes`` (0: the end of the stream), ``received_s``, ``delay_ms`` (drawn), ``due_s``,
``delivered_s`` (when the proxy handed it to the socket), ``cause`` (`mirror_avatar.remote.network.
due_time`: ``delay``, ``order`` or ``stall``) and ``request`` (the first up chunk's HTTP request
line, a join link's key or token replaced by ``sha256:`` and its digest's first 12 hex digits,
so a test that knows the link finds its page and the file holds no secret).
"""

from __future__ import annotations

import csv
import hashlib
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from mirror_avatar.realtime.transport import SECRETS

COLUMNS = (
    "connection", "direction", "chunk", "bytes", "received_s", "delay_ms", "due_s",
    "delivered_s", "cause", "request",
)  # fmt: skip
"""The truth log's columns."""

REQUEST_LINE = re.compile(rb"([A-Z]{3,7} \S{1,2048} HTTP/\d(?:\.\d)?)\r\n")
"""An HTTP request line at the start of a connection."""


@dataclass(frozen=True)
class Chunk:
    """One chunk as the proxy carried it (times in s on the monotonic clock)."""

    connection: int
    direction: str
    chunk: int
    size: int
    received_s: float
    delay_ms: float
    due_s: float
    delivered_s: float
    cause: str
    request: str = ""


def fingerprint(secret: str) -> str:
    """Return how the log names a secret: ``sha256:`` and its digest's first 12 hex digits."""
    return "sha256:" + hashlib.sha256(secret.encode()).hexdigest()[:12]


def request_line(data: bytes) -> str:
    """Return the HTTP request line ``data`` starts with, its secrets fingerprinted ("" if none)."""
    found = REQUEST_LINE.match(data)
    if found is None:
        return ""
    line = found.group(1).decode("ascii", errors="replace")
    return SECRETS.sub(lambda m: m.group(1) + fingerprint(m.group(0)[len(m.group(1)) :]), line)


class TruthLog:
    """The truth log's CSV, a row written and flushed per chunk delivered."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._file: IO[str] = path.open("w", encoding="utf-8", newline="")
        self._writer = csv.writer(self._file)
        self._writer.writerow(COLUMNS)
        self._file.flush()

    def write(self, chunk: Chunk) -> None:
        """Write one chunk's row."""
        self._writer.writerow(
            [
                chunk.connection, chunk.direction, chunk.chunk, chunk.size,
                f"{chunk.received_s:.9f}", f"{chunk.delay_ms:.3f}", f"{chunk.due_s:.9f}",
                f"{chunk.delivered_s:.9f}", chunk.cause, chunk.request,
            ]
        )  # fmt: skip
        self._file.flush()

    def close(self) -> None:
        """Close the file."""
        self._file.close()


def companion(path: Path) -> Path:
    """Return the truth log's JSON companion: the same name ending in ``.json``."""
    return path.with_suffix(".json")


def write_companion(path: Path, facts: dict[str, Any]) -> None:
    """Write the truth log's JSON companion (the network, seed, clock and anchor)."""
    companion(path).write_text(json.dumps(facts, indent=2) + "\n", encoding="utf-8")

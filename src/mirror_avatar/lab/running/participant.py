"""A person's slot in a lab session: its join link, input device, page connection and its quality.

Player k's colour (`COLOURS`) is the same on every page and on the console.
"""

from __future__ import annotations

import secrets
import time
from typing import Any

import numpy as np

from mirror_avatar.realtime.inputs import BrowserInput, InputSource
from mirror_avatar.realtime.latency import Pings
from mirror_avatar.realtime.outbox import Outbox

COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#8c564b",
           "#e377c2", "#7f7f7f", "#bcbd22", "#393b79", "#637939", "#8c6d31", "#843c39",
           "#7b4173", "#3182bd")  # fmt: skip
"""Player k's colour on every page (the console's plots included)."""


class Participant:
    """A person's slot: its link key, its input device and its page's connection, if any.

    Attributes
    ----------
    index, label, key
        Player index, label and the secret of the slot's join link.
    visible
        The players its page shows: itself, then those it observes (the graph), by index.
    source
        The input device (`BrowserInput` for the pointer; an LSL input once opened).
    outbox
        The connected page's `Outbox`, or None when no page is connected.
    connection
        The connected page's transport (the server's WebSocket), which a page opening the same
        link replaces; the runner only holds it.
    joined
        Whether a page (or the LSL device) has ever joined.
    pings
        The current page's pings and their round trips
        (`mirror_avatar.realtime.latency.Pings`), or None before a page joined.
    late_frames, frames_dropped
        Animation frames the page drew late (its own count) and frames superseded before they
        could be sent, over the page's earlier connections.
    last_heard
        When the page last sent a message (`time.monotonic`, s), or None.
    panel
        The person's identifiers on their recruitment panel, from their join link's query
        (`mirror_avatar.lab.design.online.panel_values`), by name.
    consented
        When the person agreed to take part (UTC, ISO 8601) on the protocol's consent page
        (`mirror_avatar.lab.running.consent`), or None.
    refused
        Why the person was screened out (`mirror_avatar.lab.running.sessions.Lab.refuse`), one
        line their page shows, or None: a refused person's link shows only that.
    entry_rtt_p95_ms
        The 95th percentile (ms) of their first page's round trips at entry, once judged
        (`mirror_avatar.lab.running.screening`), or None.
    """

    def __init__(self, index: int, label: str, device: str, visible: list[int]) -> None:
        self.index = index
        self.label = label
        self.device = device
        self.visible = visible
        self.key = secrets.token_urlsafe(16)
        self.source: InputSource | None = BrowserInput() if device == "pointer" else None
        self.outbox: Outbox | None = None
        self.connection: object | None = None
        self.joined = False
        self.pings: Pings | None = None
        self.late_frames = 0
        self.frames_dropped = 0
        self.last_heard: float | None = None
        self.panel: dict[str, str] = {}
        self.consented: str | None = None
        self.refused: str | None = None
        self.entry_rtt_p95_ms: float | None = None

    @property
    def connected(self) -> bool:
        """Whether a page is connected (an LSL device counts once its stream is open)."""
        return self.outbox is not None or (self.device == "lsl" and self.source is not None)

    def quality(self) -> dict[str, Any]:
        """Return the page's round trips, frames dropped and late, and when it was last heard.

        Round trips in ms: median, 95th percentile and the oldest unanswered ping's age.
        """
        pings = self.pings
        values = np.asarray([] if pings is None else pings.recent)
        dropped = self.frames_dropped + (0 if self.outbox is None else self.outbox.superseded)
        return {
            "rtt_median_ms": float(np.median(values)) if values.size else None,
            "rtt_p95_ms": float(np.percentile(values, 95)) if values.size else None,
            "rtt_waiting_ms": None if pings is None else pings.waiting(),
            "frames_dropped": dropped,
            "late_frames": self.late_frames,
            "last_heard_s": None if self.last_heard is None else time.monotonic() - self.last_heard,
        }

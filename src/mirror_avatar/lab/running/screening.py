"""Screening a participant as the protocol declares it: round trips at entry, a hidden tab.

As docs/METHODS.md, section 9 (*Screening*), describes. A protocol's ``[online]`` table
(`mirror_avatar.lab.design.online.Screening`) may bound what a page shows over its first
`ENTRY_EXCHANGES` clock exchanges (the burst the page sends as it connects, ``clock.js``): the
95th percentile of their round trips, the page's animation frames a second meanwhile, and its
window's size (`Entry`): a page outside a bound is refused (`entry_refusal`, one line naming
each number and its bound; the frame rate and window bounds may hold during play too:
`mirror_avatar.lab.running.play_screening`). Until
every connected person's entry is judged, the run does not start unless forced
(`still_screened`): a person refused during a trial would leave it half played. A tab
hidden or a window out of focus during a trial is recorded in the trial's sidecar
(`mirror_avatar.realtime.interruptions`) and the person told `BACK_NOTICE` when they come back;
with ``screen_hidden_tab = "refuse"`` a tab hidden during a trial refuses the person instead
(`HIDDEN_REFUSAL`; a window out of focus alone never does: a click on the browser's own bar
takes the focus). Every refusal is written to ``refusal-<label>.json`` in the run's folder
(`record_refusal`) and the session's log, read back by
`mirror_avatar.lab.export.run_outcomes`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from mirror_avatar.files.atomic import write_atomic_json
from mirror_avatar.lab.design.online import Online, Screening
from mirror_avatar.lab.files import refusal_file
from mirror_avatar.lab.running.runner import LabSession
from mirror_avatar.lab.running.study import ParticipantRun

ENTRY_EXCHANGES = 100
"""Clock exchanges a page's entry is judged on: the burst it sends as it connects
(``BURST`` in ``clock.js``)."""

BACK_NOTICE = "The study needs this tab visible during trials."
"""What a person is told when their tab or window comes back during, or after, a trial."""

HIDDEN_REFUSAL = "Your tab was hidden during a trial; the study needs it visible throughout."
"""Why a person is refused whose tab was hidden during a trial (``screen_hidden_tab =
"refuse"``)."""


def online_of(session: LabSession) -> Online:
    """Return the ``[online]`` table of a participant's run (empty for a plan's session)."""
    schedule = session.schedule
    return schedule.protocol.online if isinstance(schedule, ParticipantRun) else Online()


def still_screened(session: LabSession) -> str | None:
    """Say whose entry is still being judged, or None when no connected person's is.

    A person is judged on their page's first `ENTRY_EXCHANGES` clock exchanges (about 2 s after
    it connects) when the protocol bounds their entry; one refused is no longer connected.
    """
    if not online_of(session).screening.at_entry:
        return None
    judged = [
        person.label
        for person in session.everyone()
        if person.connected and person.device == "pointer" and person.entry_rtt_p95_ms is None
    ]
    if not judged:
        return None
    return (
        f"still being screened: {', '.join(judged)} (their page's first {ENTRY_EXCHANGES} round "
        "trips, about 2 s after joining; start anyway with force)"
    )


def round_trip_p95(delays_ms: Sequence[float]) -> float:
    """Return the 95th percentile (ms) of round trips ``delays_ms`` (ms; linear interpolation)."""
    return float(np.percentile(np.asarray(delays_ms, dtype=float), 95))


@dataclass(frozen=True)
class Entry:
    """What a page showed over its first `ENTRY_EXCHANGES` clock exchanges.

    Attributes
    ----------
    delays_ms
        Their round trips (ms).
    frame_rate_hz
        The page's animation frames a second meanwhile (one pointer batch each), or None when
        the span was empty.
    window_px
        The page's window (width, height; CSS pixels) as it last reported it, or None.
    """

    delays_ms: Sequence[float]
    frame_rate_hz: float | None = None
    window_px: tuple[int, int] | None = None

    def measured(self) -> dict[str, Any]:
        """Return what a refusal's file records of the entry."""
        return {
            "rtt_p95_ms": round_trip_p95(self.delays_ms),
            "rtt_ms": [round(delay, 3) for delay in self.delays_ms],
            "frame_rate_hz": self.frame_rate_hz,
            "window_px": None if self.window_px is None else list(self.window_px),
        }


def entry_refusal(entry: Entry, screening: Screening) -> str | None:
    """Return why a page is refused at entry, one sentence per bound it misses, or None.

    The bounds are the protocol's (`Screening`): a round trip's 95th percentile above
    ``round_trip_p95_ms``, and those of `bound_misses` (none measured counts as 0 frames a
    second: a hidden tab draws none).
    """
    reasons = round_trip_misses(entry.delays_ms, screening)
    reasons += bound_misses(entry.frame_rate_hz or 0.0, entry.window_px, screening)
    return " ".join(reasons) or None


def round_trip_misses(delays_ms: Sequence[float], screening: Screening) -> list[str]:
    """Return the sentence of a page whose round trips ``delays_ms`` (ms) miss the bound, or [].

    Missed when their 95th percentile (`round_trip_p95`) is above ``round_trip_p95_ms``.
    """
    bound = screening.round_trip_p95_ms
    if bound is None or not len(delays_ms):
        return []
    p95 = round_trip_p95(delays_ms)
    if p95 <= bound:
        return []
    return [f"Your connection's round trip (p95 {p95:.0f} ms) is above the study's {bound:g} ms."]


def bound_misses(
    frame_rate_hz: float, window_px: tuple[int, int] | None, screening: Screening
) -> list[str]:
    """Return one sentence per frame or window bound of ``screening`` a page misses.

    Fewer animation frames a second (``frame_rate_hz``, Hz) than ``frame_rate_hz``; a window
    (``window_px``: width, height; CSS pixels) narrower or lower than ``window_width_px`` or
    ``window_height_px`` (a page that never said its window misses both).
    """
    reasons = []
    fewest = screening.frame_rate_hz
    if fewest is not None and frame_rate_hz < fewest:
        reasons.append(f"Your browser drew {frame_rate_hz:.3g} frames a second, fewer than the "
                       f"study's {fewest:g}.")  # fmt: skip
    width, height = window_px or (0, 0)
    if screening.window_width_px is not None and width < screening.window_width_px:
        reasons.append(f"Your window is {width} px wide, narrower than the study's "
                       f"{screening.window_width_px} px.")  # fmt: skip
    if screening.window_height_px is not None and height < screening.window_height_px:
        reasons.append(f"Your window is {height} px high, lower than the study's "
                       f"{screening.window_height_px} px.")  # fmt: skip
    return reasons


def record_refusal(directory: Path, label: str, reason: str, measured: dict[str, Any]) -> None:
    """Write the person's refusal (why, when in UTC, what was measured) to their file (blocking)."""
    record = {"label": label, "reason": reason, "utc": datetime.now(UTC).isoformat()}
    write_atomic_json(refusal_file(directory, label), record | measured)

"""Screening a participant as the protocol declares it: round trips at entry, a hidden tab.

As docs/METHODS.md, section 9 (*Screening*), describes. A protocol's ``[online]`` table
(`mirror_avatar.lab.design.online.Screening`) may bound the 95th percentile of a page's round
trips over its first `ENTRY_EXCHANGES` clock exchanges (the burst the page sends as it connects,
``clock.js``): a page above it is refused (`entry_refusal`, one line naming both numbers). Until
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
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from mirror_avatar.files.atomic import write_atomic_json
from mirror_avatar.lab.design.online import Online
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

    A person is judged on their page's first `ENTRY_EXCHANGES` round trips (about 2 s after it
    connects) when the protocol bounds them; one refused is no longer connected.
    """
    if online_of(session).screening.round_trip_p95_ms is None:
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


def entry_refusal(delays_ms: Sequence[float], bound_ms: float) -> str | None:
    """Return why a page is refused at entry, or None when it is admitted.

    Parameters
    ----------
    delays_ms
        The round trips (ms) of the page's first clock exchanges.
    bound_ms
        The protocol's ``screen_round_trip_p95_ms`` (ms): a 95th percentile above it refuses.
    """
    p95 = round_trip_p95(delays_ms)
    if p95 <= bound_ms:
        return None
    return f"Your connection's round trip (p95 {p95:.0f} ms) is above the study's {bound_ms:g} ms."


def record_refusal(directory: Path, label: str, reason: str, measured: dict[str, Any]) -> None:
    """Write the person's refusal (why, when in UTC, what was measured) to their file (blocking)."""
    record = {"label": label, "reason": reason, "utc": datetime.now(UTC).isoformat()}
    write_atomic_json(refusal_file(directory, label), record | measured)

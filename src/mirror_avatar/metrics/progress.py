"""A participant's progress over their sessions: their own motion drifting, their coordination.

METHODS section 10: in a curriculum, a patient's own IMS should move and their coordination
should hold or improve from session to session. `order_by_start` puts sessions in the order
they were played, by the start time each recorded; `progress_table` follows one player (by
index, player 0 by default: the person in a live trial) through sessions in that order: the EMD
of their velocity IMS to their first session's, to their partner's in the same session, and the
session's CV and RMS (`mirror_avatar.metrics.summary.session_metrics`).
"""

from __future__ import annotations

from collections.abc import Sequence
from datetime import UTC, datetime
from typing import Any, TypeVar

import pandas as pd

from mirror_avatar.files.trial_record import lab_trial_record
from mirror_avatar.metrics.summary import session_metrics
from mirror_avatar.sessions.session import Session
from mirror_avatar.signatures.signature import compute_emd, compute_ims

START_KEYS = ("started_utc", "created_utc")
"""Metadata keys of a session's start time (ISO 8601), in order of preference: a live or lab
trial's ``started_utc`` (when its clock started), else the ``created_utc`` of its file;
then a lab trial's record's creation time, with the trial number after it."""

Item = TypeVar("Item")


def recorded_start(session: Session) -> tuple[datetime, int] | None:
    """Return when ``session`` was played, as it recorded it: (start time, lab trial number).

    The trial number (0 when there is none) orders the trials of one lab session, which a lab
    export stamps with the session's creation time. None when no readable time is recorded.
    """
    metadata = session.metadata
    record = lab_trial_record(metadata)
    stamps = [metadata.get(key) for key in START_KEYS]
    if record is not None:
        stamps += [record.created_utc]
    number = 0 if record is None else record.trial
    for stamp in stamps:
        if isinstance(stamp, str):
            try:
                moment = datetime.fromisoformat(stamp)
            except ValueError:
                continue
            return (moment if moment.tzinfo else moment.replace(tzinfo=UTC)), number
    return None


def order_by_start(
    sessions: Sequence[tuple[Item, Session]],
) -> tuple[list[tuple[Item, Session]], list[Item]]:
    """Order sessions by their recorded start (`recorded_start`), earliest first.

    Returns
    -------
    ordered : list
        The sessions by start time (ties in the order given) when every session recorded one;
        otherwise in the order given.
    untimed : list
        The names of the sessions without a recorded start time (empty when ordered by time).
    """
    starts = [recorded_start(session) for _, session in sessions]
    untimed = [name for (name, _), start in zip(sessions, starts, strict=True) if start is None]
    if untimed:
        return list(sessions), untimed
    timed = [start for start in starts if start is not None]
    order = sorted(range(len(sessions)), key=timed.__getitem__)
    return [sessions[k] for k in order], []


def progress_table(
    sessions: Sequence[tuple[str, Session]], trim: float, player: int = 0,
    metrics: Sequence[dict[str, Any]] | None = None,
) -> pd.DataFrame:  # fmt: skip
    """One row per session, in order: drift of the player's IMS, and coordination.

    Parameters
    ----------
    sessions
        (name, session) pairs in the order the participant played them; at least one.
    trim
        Seconds left out at the start of each session.
    player
        The participant's index in every session.
    metrics
        Each session's `session_metrics` after the trim, when they are computed already.

    Returns
    -------
    pandas.DataFrame
        Indexed by session number (from 1): ``session`` (name), ``EMD to first session``,
        ``EMD to partner`` (player 1, or 0 when following player 1), ``CV`` and ``RMS``
        (units).
    """
    rows, first = [], None
    for number, (name, session) in enumerate(sessions, start=1):
        trimmed = session.trimmed(trim)
        ims = compute_ims(trimmed.velocities[player])
        first = ims if first is None else first
        found = session_metrics(trimmed) if metrics is None else metrics[number - 1]
        rows.append(
            {
                "number": number,
                "session": name,
                "EMD to first session": compute_emd(ims, first),
                "EMD to partner": found.get("emd_players", float("nan")),
                "CV": found.get("phase_locking", float("nan")),
                "RMS": found.get("rmse", float("nan")),
            }
        )
    return pd.DataFrame(rows).set_index("number")

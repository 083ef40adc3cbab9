"""A participant's progress over their sessions: their own motion drifting, their coordination.

METHODS section 10: in a curriculum, a patient's own IMS should move and their coordination
should hold or improve from session to session. `progress_table` follows one player (by index,
player 0 by default: the person in a live trial) through sessions in the order given: the EMD of
their velocity IMS to their first session's, to their partner's in the same session, and the
session's CV and RMS (`mirror_avatar.metrics.summary.session_metrics`).
"""

from __future__ import annotations

from collections.abc import Sequence

import pandas as pd

from mirror_avatar.metrics.summary import session_metrics
from mirror_avatar.session import Session
from mirror_avatar.signature import compute_emd, compute_ims


def progress_table(
    sessions: Sequence[tuple[str, Session]], trim: float, player: int = 0
) -> pd.DataFrame:
    """One row per session, in order: drift of the player's IMS, and coordination.

    Parameters
    ----------
    sessions
        (name, session) pairs in the order the participant played them; at least one.
    trim
        Seconds left out at the start of each session.
    player
        The participant's index in every session.

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
        metrics = session_metrics(session, trim=trim)
        rows.append(
            {
                "number": number,
                "session": name,
                "EMD to first session": compute_emd(ims, first),
                "EMD to partner": metrics.get("emd_players", float("nan")),
                "CV": metrics.get("phase_locking", float("nan")),
                "RMS": metrics.get("rmse", float("nan")),
            }
        )
    return pd.DataFrame(rows).set_index("number")

"""What each page was sent of its partners and when it drew it: ``trial-NN_view.csv``.

Every frame the server sends a page (`frame`) carries the sample ``k`` it was sent at, the
positions the page draws (its own, then its partners' as the condition shows them: delayed,
hidden, predicted) and, for an equalised view, ``due``: the page time (ms) at which to draw it
(`mirror_avatar.realtime.partner_view.due_page_ms`). The page reports, in ``shown`` messages,
the frames it drew and the time of the animation frame that drew each (ms, its clock); the
server maps that time onto its clock (`mirror_avatar.realtime.page_clock.PageClock.to_server`)
and `ViewLog` writes one row per partner drawn (`VIEW_COLUMNS`): the page's label, the
partner's, the frame's sample ``k``, the time of the partner's sample drawn (``sample_s``, the
server's clock: earlier than sample k's with a delay), the page time and server time of the
draw (``page_ms``, ``shown_s``) and the position drawn (``x``, units). `ViewLog.summary` judges
the draws against the recording (METHODS section 19).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mirror_avatar.files.atomic import LineFile
from mirror_avatar.realtime.partner_view import (
    displayed_delays_ms,
    displayed_errors,
    view_summary,
)
from mirror_avatar.realtime.trial import Array

VIEW_COLUMNS = ("label", "partner", "k", "sample_s", "page_ms", "shown_s", "x")
"""Columns of a trial's view file (`ViewLog`)."""

KEPT_FRAMES = 400
"""Frames sent to a page remembered until it reports drawing them (12 s at 30 ms: far beyond
any lag a condition allows)."""


@dataclass(frozen=True)
class SentFrame:
    """What a page was sent of its partners at one sample.

    ``partners``: their player indices; ``sample_s``: the time of the samples shown (s, the
    server's clock); ``x``: the positions the page draws (units; None: hidden).
    """

    partners: tuple[int, ...]
    sample_s: float
    x: tuple[float | None, ...]


@dataclass(frozen=True)
class Draw:
    """One partner drawn: its index, its sample's time, the draw's times, the position."""

    partner: int
    k: int
    sample_s: float
    page_ms: float
    shown_s: float
    x: float


class ViewLog:
    """Engine sink writing ``trial-NN_view.csv``: the partners each page drew, at each tick.

    Parameters
    ----------
    path
        The file; it must not exist yet.
    labels
        Every player's label, in player order.
    """

    def __init__(self, path: Path, labels: Sequence[str]) -> None:
        self.path = path
        self.labels = list(labels)
        self._file = LineFile(path, ",".join(VIEW_COLUMNS))
        self._lock = threading.Lock()
        self._sent: dict[str, dict[int, SentFrame]] = {}
        self._unwritten: list[tuple[str, Draw]] = []
        self._closed = False
        self.draws: dict[str, list[Draw]] = {}

    def sent(self, label: str, k: int, frame: SentFrame) -> None:
        """Remember what ``label``'s page was sent at sample ``k``."""
        with self._lock:
            frames = self._sent.setdefault(label, {})
            frames[k] = frame
            frames.pop(k - KEPT_FRAMES, None)

    def shown(self, label: str, drawn: Sequence[tuple[int, float, float]]) -> None:
        """Take the frames ``label``'s page drew: (sample k, page ms, server s) each.

        A frame not sent in this trial (or forgotten), drawn before the page's clock was known
        (NaN server time), or reported after the file was closed is left out; each drawn
        partner is kept once.
        """
        with self._lock:
            if self._closed:
                return
            frames = self._sent.get(label, {})
            for k, page_ms, shown_s in drawn:
                frame = frames.pop(k, None)
                if frame is None or math.isnan(shown_s):
                    continue
                for partner, x in zip(frame.partners, frame.x, strict=True):
                    if x is not None:
                        draw = Draw(partner, k, frame.sample_s, page_ms, shown_s, x)
                        self._unwritten.append((label, draw))
                        self.draws.setdefault(label, []).append(draw)

    def __call__(self, row: Array) -> None:
        """Write the draws reported since the previous tick."""
        self._write_unwritten()

    def _write_unwritten(self) -> None:
        with self._lock:
            rows, self._unwritten = self._unwritten, []
        for label, d in rows:
            times = f"{d.sample_s:.6f},{d.page_ms:.3f},{d.shown_s:.6f}"
            self._file.write(f"{label},{self.labels[d.partner]},{d.k},{times},{d.x!r}")

    def close(self) -> None:
        """Write the draws reported since the last tick, then close the file.

        Reports arriving later are left out, so the file and `summary` hold the same draws.
        """
        with self._lock:
            self._closed = True
        self._write_unwritten()
        self._file.close()

    def summary(self, label: str, times_s: Array, positions: Array) -> dict[str, Any] | None:
        """Summarise ``label``'s page's draws against the recording (None: none, or no samples).

        Parameters
        ----------
        label
            The page's person.
        times_s
            Each recorded sample's time (s, the server's clock), shape (n_samples,).
        positions
            The recorded positions (units), shape (n_players, n_samples).

        Returns
        -------
        dict
            `mirror_avatar.realtime.partner_view.view_summary` over every partner drawn.
        """
        with self._lock:
            draws = list(self.draws.get(label, ()))
        if not draws:
            return None
        n = min(times_s.size, positions.shape[1])
        if n == 0:
            return None
        delays = displayed_delays_ms(
            np.array([d.shown_s for d in draws]), np.array([d.sample_s for d in draws])
        )
        errors = np.concatenate(
            [
                displayed_errors(
                    np.array([d.shown_s for d in mine]),
                    np.array([d.x for d in mine]),
                    times_s[:n],
                    positions[partner, :n],
                )
                for partner in sorted({d.partner for d in draws})
                if (mine := [d for d in draws if d.partner == partner])
            ]
        )
        return view_summary(delays, errors)

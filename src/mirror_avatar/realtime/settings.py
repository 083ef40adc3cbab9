"""What both real-time servers let a page do, and how slow an avatar may be."""

from __future__ import annotations

from dataclasses import dataclass

from mirror_avatar.realtime.clock import MAX_STEP


@dataclass(frozen=True, kw_only=True)
class PageSettings:
    """Settings every real-time server shares (keyword arguments of its own settings).

    Parameters
    ----------
    countdown
        Seconds of countdown before a trial starts.
    max_tick
        Seconds one step of the avatars may take before the trial is ended.
    send_timeout
        Seconds a message may wait for a page that does not read before the page is dropped.
    max_message_rate
        Messages per second a page may send (sustained; bursts of a second's worth).
    max_rejected
        Bad messages tolerated on one connection before it is closed.
    """

    countdown: int = 3
    max_tick: float = MAX_STEP
    send_timeout: float = 2.0
    max_message_rate: float = 250.0
    max_rejected: int = 100

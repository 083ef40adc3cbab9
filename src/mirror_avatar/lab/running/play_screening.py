"""Screening a page during play: its round trips and frame rate over sliding windows, its window.

As docs/METHODS.md, section 9 (*Screening during play*), describes. With ``screen_during_play``
(``"record"`` or ``"refuse"``) the protocol's round-trip, frame rate and window bounds
(`mirror_avatar.lab.design.online.Screening`) hold during each trial too. A page's animation
frames (one pointer batch each, distinct by their send time on the page's own clock) are
counted over the last `PLAY_WINDOW_S` seconds (`FrameWindow`), its last `PLAY_EXCHANGES` clock
exchanges kept, and at each frame their round trips' 95th percentile, the frame rate and the
window the page last said are judged against the bounds
(`mirror_avatar.lab.running.screening.round_trip_misses`, `bound_misses`). A page that misses
one during a trial
starts a ``below_bounds`` interruption (`mirror_avatar.realtime.interruptions`: recorded in the
trial's sidecar with its reason and counted in the study table), is logged and told the reason
in one line (again in each later trial while still below them: the page clears the line as
a trial starts), and with ``"refuse"`` is refused; the interruption ends at the first frame
whose window meets the bounds again, during a trial or after it. A hidden tab draws no
frames, and is an interruption of its own: it ends a ``below_bounds`` one and empties the
window, which is judged again once it spans `PLAY_WINDOW_S` of frames drawn since.
"""

from __future__ import annotations

import math
from collections import deque

from mirror_avatar.files.trial_record import BELOW_BOUNDS
from mirror_avatar.lab.running.participant import Participant
from mirror_avatar.lab.running.runner import LabSession
from mirror_avatar.lab.running.screening import bound_misses, online_of, round_trip_misses
from mirror_avatar.lab.running.sessions import Lab
from mirror_avatar.realtime.inputs import BrowserInput
from mirror_avatar.realtime.outbox import Outbox

PLAY_WINDOW_S = 2.0
"""Length (s, the page's clock) of the window a page's frame rate is judged over during play
(**choice**: the span of the entry's clock exchanges; a collection's pause of 100 ms loses 5 %
of a 60 Hz page's 120 frames, while a page slowed for good is seen within 2 s)."""

PLAY_EXCHANGES = 50
"""Clock exchanges whose round trips are judged during play (**choice**: 5 s of ``clock.js``'s
one exchange every 100 ms; half the entry's 100, so a link slowed for good is seen within about
half a second, when 3 of the 50 exceed the bound, and a single late exchange is not)."""


class FrameWindow:
    """A page's animation frames over its last ``length_s`` seconds, on its own clock.

    Parameters
    ----------
    length_s
        The window's length (s).

    Attributes
    ----------
    frames
        The send times (ms, the page's clock) of the frames in the window, oldest first, after
        the newest one at or before its start (kept to know the window is spanned).
    """

    def __init__(self, length_s: float = PLAY_WINDOW_S) -> None:
        self.length_ms = 1000.0 * length_s
        self.frames: deque[float] = deque()

    def add(self, sent_ms: float) -> None:
        """Add a frame sent at ``sent_ms`` (ms); a time not after the newest is the same frame."""
        if self.frames and sent_ms <= self.frames[-1]:
            return
        self.frames.append(sent_ms)
        start = sent_ms - self.length_ms
        while len(self.frames) > 1 and self.frames[1] <= start:
            self.frames.popleft()

    def rate_hz(self) -> float | None:
        """Return the frames a second (Hz) in the window ending at the newest frame, or None.

        The window is ``(newest - length, newest]``; None until a frame at or before its start
        shows that the page has been drawing for a whole window.
        """
        if not self.frames or self.frames[0] > self.frames[-1] - self.length_ms:
            return None
        return (len(self.frames) - 1) / (self.length_ms / 1000.0)

    def clear(self) -> None:
        """Forget every frame."""
        self.frames.clear()


class PlayScreen:
    """One page's screening during play (see the module docstring).

    Parameters
    ----------
    lab
        The server's sessions (to refuse the person).
    session
        The person's session.
    participant
        The page's person.
    outbox
        The page's messages out (to tell the person).

    Attributes
    ----------
    window
        The page's frames over the last `PLAY_WINDOW_S` seconds (`FrameWindow`).
    round_trips
        The round trips (ms) of the page's last `PLAY_EXCHANGES` clock exchanges.
    told_in
        The trial whose person this page told of being below the bounds, until back within
        them (None).
    """

    def __init__(
        self, lab: Lab, session: LabSession, participant: Participant, outbox: Outbox
    ) -> None:
        self.lab = lab
        self.session = session
        self.participant = participant
        self.outbox = outbox
        self.screening = online_of(session).screening
        self.window = FrameWindow()
        self.round_trips: deque[float] = deque(maxlen=PLAY_EXCHANGES)
        self.told_in: int | None = None

    def exchange(self, delay_ms: float) -> None:
        """Keep the round trip (ms) of the page's newest clock exchange."""
        self.round_trips.append(delay_ms)

    def frame(
        self,
        source: BrowserInput,
        sent_ms: float,
        received_s: float,
        window_px: tuple[int, int] | None,
    ) -> None:
        """Judge the page at its frame sent at ``sent_ms`` (ms, its clock).

        ``received_s`` is when it arrived (s, the server's clock: the frame's time before the
        page's first clock exchange), ``window_px`` the page's window as it last said it (width,
        height; CSS pixels).
        """
        if not self.screening.in_play:
            return
        self.window.add(sent_ms)
        rate = self.window.rate_hz()
        if rate is None:
            return
        at_s = source.clock.to_server(sent_ms)
        at_s = received_s if math.isnan(at_s) else at_s
        reasons = round_trip_misses(self._judged_round_trips(), self.screening)
        reason = " ".join(reasons + bound_misses(rate, window_px, self.screening)) or None
        label, trial = self.participant.label, self.session.playing_in(self.participant)
        if reason is None:
            self.told_in = None
            ended = source.interruptions.end(BELOW_BOUNDS, at_s)
            if ended is not None:
                self.session.log(f"{label}: within bounds again after {at_s - ended[1]:.1f} s")
        elif trial is not None and self.told_in != trial.n:
            self.told_in = trial.n
            source.interruptions.begin(BELOW_BOUNDS, at_s, reason)
            self.session.log(f"{label}: below bounds during trial {trial.n}: {reason}")
            self.outbox.put({"type": "notice", "message": reason})
            if self.screening.during_play == "refuse":
                window = None if window_px is None else list(window_px)
                measured = {"trial": trial.n, "rtt_ms": list(self.round_trips),
                            "frame_rate_hz": rate, "window_px": window,
                            "bounds": self._bounds()}  # fmt: skip
                self.lab.refuse(self.participant.key, reason, measured)

    def hidden(self, source: BrowserInput, at_s: float) -> None:
        """End any ``below_bounds`` interruption as the tab hides at ``at_s`` (s); clear the window.

        The hidden tab is an interruption of its own, and draws no frames.
        """
        source.interruptions.end(BELOW_BOUNDS, at_s)
        self.window.clear()
        self.told_in = None

    def _judged_round_trips(self) -> list[float]:
        """Return the round trips (ms) to judge: the last `PLAY_EXCHANGES`, or none until then."""
        return list(self.round_trips) if len(self.round_trips) == PLAY_EXCHANGES else []

    def _bounds(self) -> dict[str, float | int | None]:
        """Return the bounds held during play, as a refusal's file records them."""
        screening = self.screening
        return {"round_trip_p95_ms": screening.round_trip_p95_ms,
                "frame_rate_hz": screening.frame_rate_hz,
                "window_width_px": screening.window_width_px,
                "window_height_px": screening.window_height_px}  # fmt: skip

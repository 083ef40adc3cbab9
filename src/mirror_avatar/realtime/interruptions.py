"""A page's interruptions: its tab hidden or its window out of focus, on the server's clock.

A participant's page reports each ``visibilitychange`` (``hidden``, ``visible``) and each window
``blur`` and ``focus`` with its own time; the server maps that time onto its clock
(`mirror_avatar.realtime.page_clock.PageClock.to_server`) and `Interruptions` pairs each start
with its end: a ``hidden`` interruption from ``hidden`` to ``visible``, a ``blur`` one from
``blur`` to ``focus``. The server adds its own kind, ``below_bounds`` (the page's frame rate or
window below the protocol's bounds during play: `mirror_avatar.lab.running.play_screening`),
with the reason it gives. METHODS section 9 (*Screening*).
"""

from __future__ import annotations

import threading

from mirror_avatar.files.trial_record import PAGE_INTERRUPTIONS

KINDS = dict(zip(PAGE_INTERRUPTIONS, ("visible", "focus"), strict=True))
"""Each kind of interruption a page reports, by the event that starts it, and the event that
ends it."""

EVENTS = (*KINDS, *KINDS.values())
"""The events a page reports."""

MAX_KEPT = 10_000
"""Most interruptions a page's record keeps (the oldest beyond are forgotten)."""


class Interruptions:
    """One page's interruptions (thread-safe: the event loop adds, a trial's thread reads).

    Attributes
    ----------
    spans
        Each ended interruption: its kind, start and end (s, the server's clock) and reason
        (None for those the page reports), in order.
    open
        The start (s) and reason of each interruption not yet ended, by kind.
    """

    def __init__(self) -> None:
        self.spans: list[tuple[str, float, float, str | None]] = []
        self.open: dict[str, tuple[float, str | None]] = {}
        self._lock = threading.Lock()

    def event(self, name: str, at_s: float) -> tuple[str, float, float] | None:
        """Add the page's event ``name`` (one of `EVENTS`) at server time ``at_s`` (s).

        Returns the interruption it ends (kind, start, end), or None: it starts one, or repeats
        the page's state (a second ``hidden``: the first start kept; an end without a start).
        """
        if name in KINDS:
            self.begin(name, at_s)
            return None
        return self.end(next(kind for kind, end in KINDS.items() if end == name), at_s)

    def begin(self, kind: str, at_s: float, reason: str | None = None) -> bool:
        """Start an interruption of ``kind`` at server time ``at_s`` (s), for ``reason``.

        Returns whether it started one (False: one of that kind is open; its start is kept).
        """
        with self._lock:
            if kind in self.open:
                return False
            self.open[kind] = (at_s, reason)
            return True

    def end(self, kind: str, at_s: float) -> tuple[str, float, float] | None:
        """End the open interruption of ``kind`` at server time ``at_s`` (s).

        Returns it (kind, start, end), or None when none of that kind is open.
        """
        with self._lock:
            start, reason = self.open.pop(kind, (None, None))
            if start is None:
                return None
            span = (kind, start, max(start, at_s), reason)
            self.spans.append(span)
            del self.spans[:-MAX_KEPT]
            return span[:3]

    def between(self, start_s: float, end_s: float) -> list[dict[str, object]]:
        """Return the interruptions overlapping server times ``start_s`` to ``end_s`` (s).

        Each is ``{"kind", "start_s", "end_s"}`` cut to that span, with its ``"reason"`` when it
        has one; one still open ends at ``end_s``, with ``"open": True``.
        """
        with self._lock:
            spans = [(kind, a, b, why, False) for kind, a, b, why in self.spans]
            spans += [(kind, a, end_s, why, True) for kind, (a, why) in self.open.items()]
        found = []
        for kind, a, b, why, still in sorted(spans, key=lambda span: span[1]):
            if a <= end_s and b >= start_s:
                span = {"kind": kind, "start_s": max(a, start_s), "end_s": min(b, end_s)}
                span |= {"reason": why} if why is not None else {}
                found.append(span | ({"open": True} if still else {}))
        return found

"""An emulated internet as declared: one-way delays per direction, and stalls (METHODS 17).

A network spec is one string, parsed here and nowhere else (`parse_network`)::

    80+-25                  both directions: 80 ms mean one-way delay, 25 ms SD
    up=120+-40,down=40+-15  page->server and server->page apart
    120+-40,stall=5:1       and a stall 5 s after the proxy starts, for 1 s
    none                    no delay (the proxy still logs the truth)

A chunk's delay is drawn from a normal distribution truncated at 0 (`Delay.draw`); its delivery
is due that long after it was received, but no earlier than the chunk before it in its
connection and direction (TCP's order), and a chunk due during a stall is held to its end, as
are those behind it (`due_time`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from mirror_avatar.common.errors import InputError
from mirror_avatar.common.seeds import spawn_seeds

MAX_DELAY_MS = 10_000.0
"""Largest mean or SD of a one-way delay (ms)."""

MAX_STALL_S = 600.0
"""Longest stall, and latest start of one (s)."""

EXAMPLE = "give a delay in ms such as 80+-25, up=120+-40,down=40+-15, or 120+-40,stall=5:1"
"""What a refused spec's line suggests."""

DIRECTIONS = ("up", "down")
"""A connection's two directions: page->server (``up``) and server->page (``down``)."""

_NUMBER = r"(\d+(?:\.\d*)?|\.\d+)"
_DELAY = re.compile(rf"{_NUMBER}(?:(?:\+-|±){_NUMBER})?")
_STALL = re.compile(rf"{_NUMBER}:{_NUMBER}")


@dataclass(frozen=True)
class Delay:
    """One direction's one-way delay (ms).

    Normal with mean ``mean_ms`` and SD ``sd_ms``, truncated at 0 (a draw below 0 is drawn
    again).
    """

    mean_ms: float
    sd_ms: float = 0.0

    def draw(self, rng: np.random.Generator) -> float:
        """Return one chunk's delay (ms)."""
        if self.sd_ms == 0.0:
            return self.mean_ms
        while (value := float(rng.normal(self.mean_ms, self.sd_ms))) < 0.0:
            pass
        return value

    def __str__(self) -> str:
        return f"{self.mean_ms:g}" + (f"+-{self.sd_ms:g}" if self.sd_ms else "")


@dataclass(frozen=True)
class Stall:
    """A stall: everything due in it is held, then released at its end.

    It lasts from ``start_s`` to ``start_s + duration_s`` (s after the proxy started).
    """

    start_s: float
    duration_s: float

    @property
    def end_s(self) -> float:
        """When the stall ends (s after the proxy started)."""
        return self.start_s + self.duration_s

    def __str__(self) -> str:
        return f"stall={self.start_s:g}:{self.duration_s:g}"


@dataclass(frozen=True)
class Network:
    """An emulated internet: each direction's delay and the stalls, in order of start."""

    up: Delay
    down: Delay
    stalls: tuple[Stall, ...] = ()

    def delay(self, direction: str) -> Delay:
        """Return the delay of ``direction`` (``up`` or ``down``)."""
        return self.up if direction == "up" else self.down

    def __str__(self) -> str:
        delays = [str(self.up)] if self.up == self.down else [f"up={self.up}", f"down={self.down}"]
        return ",".join(delays + [str(stall) for stall in self.stalls])


def due_time(
    received_s: float, delay_ms: float, previous_s: float, stalls: tuple[Stall, ...]
) -> tuple[float, str]:
    """Return when a chunk is delivered and why then (s after the proxy started).

    Parameters
    ----------
    received_s
        When the proxy received the chunk (s after it started).
    delay_ms
        The chunk's drawn one-way delay (ms).
    previous_s
        When the chunk before it in its connection and direction is delivered (s; ``-inf``
        for the first).
    stalls
        The network's stalls, in order of start, none overlapping.

    Returns
    -------
    tuple of (float, str)
        The delivery time, and why then: ``delay`` (its own delay), ``stall`` (held to a
        stall's end, itself or behind a chunk that is) or ``order`` (behind the chunk before
        it, due later).
    """
    own = received_s + delay_ms / 1000.0
    due = max(own, previous_s)
    for stall in stalls:
        if stall.start_s <= due < stall.end_s:
            due = stall.end_s
    if due == own:
        return due, "delay"
    return due, "stall" if any(due == stall.end_s for stall in stalls) else "order"


def parse_network(text: str, option: str = "--network") -> Network:
    """Read a network spec (see the module's docstring).

    Raises
    ------
    InputError
        One line naming ``option``, the part refused and an example.
    """
    spec = text.strip()
    if spec.lower() in ("none", "0"):
        return Network(Delay(0.0), Delay(0.0))
    delays: dict[str, Delay] = {}
    stalls: list[Stall] = []
    for part in (p.strip() for p in spec.split(",")):
        key, sep, value = part.rpartition("=")
        if key == "stall":
            stalls.append(_stall(value, option))
        elif key in ("", *DIRECTIONS) and (key or not sep):
            for direction in [key] if key else DIRECTIONS:
                if direction in delays:
                    raise InputError(option, f"{text!r}: {direction} delay given twice; {EXAMPLE}")
                delays[direction] = _delay(value, option)
        else:
            raise InputError(option, f"{text!r}: {part!r} is not a delay or stall; {EXAMPLE}")
    missing = [d for d in DIRECTIONS if d not in delays]
    if missing:
        raise InputError(option, f"{text!r}: no {missing[0]} delay; {EXAMPLE}")
    return Network(delays["up"], delays["down"], _merged(stalls))


def _delay(text: str, option: str) -> Delay:
    found = _DELAY.fullmatch(text)
    if found is None:
        raise InputError(option, f"{text!r} is not a delay: {EXAMPLE}")
    mean, sd = float(found.group(1)), float(found.group(2) or 0.0)
    if max(mean, sd) > MAX_DELAY_MS:
        raise InputError(option, f"{text!r}: delays are up to {MAX_DELAY_MS:g} ms; {EXAMPLE}")
    return Delay(mean, sd)


def _stall(text: str, option: str) -> Stall:
    found = _STALL.fullmatch(text)
    if found is None:
        raise InputError(
            option, f"stall={text!r} is not START:SECONDS (such as stall=5:1, s after the start)"
        )
    start, duration = float(found.group(1)), float(found.group(2))
    if duration <= 0.0 or max(start, duration) > MAX_STALL_S:
        raise InputError(
            option,
            f"stall={text}: give a start and a duration from 0 to {MAX_STALL_S:g} s, "
            "the duration above 0 (such as stall=5:1)",
        )
    return Stall(start, duration)


def _merged(stalls: list[Stall]) -> tuple[Stall, ...]:
    """Return the stalls in order of start, those that overlap or touch made one."""
    merged: list[Stall] = []
    for stall in sorted(stalls, key=lambda s: s.start_s):
        if merged and stall.start_s <= merged[-1].end_s:
            last = merged.pop()
            stall = Stall(last.start_s, max(last.end_s, stall.end_s) - last.start_s)
        merged.append(stall)
    return tuple(merged)


def lane_rng(seed: int, connection: int, direction: str) -> np.random.Generator:
    """Return the generator of one connection's one direction.

    Its delays depend on the seed, the connection's number and the direction only, however the
    connections interleave.
    """
    lanes = spawn_seeds([seed, connection], len(DIRECTIONS))
    return np.random.default_rng(int(lanes[DIRECTIONS.index(direction)]))

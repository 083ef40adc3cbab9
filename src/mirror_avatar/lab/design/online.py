"""A protocol's ``[online]`` table: a study served to a recruitment panel's participants.

As docs/METHODS.md, section 9 (*Served on the internet*), describes.

A panel (Prolific, for instance) opens each participant's link with identifiers as query
parameters (``/join/KEY?PROLIFIC_PID=...&STUDY_ID=...``): the protocol names those to record
(``panel_ids``), and each value is checked (`panel_values`: at most `MAX_PANEL_VALUE_CHARS`
letters, digits, ``_`` and ``-``; recorded as text, never used as a path). At the end the
participant's page shows the completion code, or a link back to the panel carrying it; a
participant screened out is shown the refusal code or link instead
(`mirror_avatar.lab.running.sessions.Lab.refuse`).

Before the game the page shows the instructions and the consent text, each written in the
protocol or in a text file beside it (a name, never a path: `_page_text`); a participant who does
not agree is not played and is shown the refusal (`mirror_avatar.lab.running.consent`).

The protocol may screen its participants (`Screening`, applied by
`mirror_avatar.lab.running.screening`): on the round trips of a page's first clock exchanges,
its frame rate and its window size as it connects and, with ``screen_during_play``, during each
trial, and on a tab hidden during a trial.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from mirror_avatar.common.errors import InputError
from mirror_avatar.common.text import first_control
from mirror_avatar.files.user_files import read_text
from mirror_avatar.lab.design.checker import Checker
from mirror_avatar.lab.design.protocol_keys import (
    MAX_PAGE_CHARS,
    MAX_PANEL_IDS,
    ONLINE_SETTINGS,
    by_key,
    keys_of,
)

PANEL_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,31}")
"""A panel identifier's name: a query parameter's name (``PROLIFIC_PID``)."""

MAX_PANEL_VALUE_CHARS = 64
"""Longest value of a panel identifier (characters; Prolific's are 24)."""

PANEL_VALUE = re.compile(rf"[A-Za-z0-9_-]{{1,{MAX_PANEL_VALUE_CHARS}}}")
"""A panel identifier's value: letters, digits, ``_`` and ``-`` only."""

CODE = re.compile(r"[A-Za-z0-9_-]{1,64}")
"""A completion or refusal code."""

MAX_URL_CHARS = 500
"""Longest completion or refusal link (characters)."""

FILE_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}")
"""The name of a page's text file beside the protocol (no folder, no leading dot)."""

SCREENING = by_key(ONLINE_SETTINGS)
"""The ``[online]`` table's settings by key (its screening keys are read from them)."""

MAX_PAGE_BYTES = 4 * MAX_PAGE_CHARS
"""Largest page text file read (bytes: UTF-8 takes up to 4 a character)."""


@dataclass(frozen=True)
class Ending:
    """What a participant's page shows at the end: a code to copy, a link back, or both."""

    code: str | None = None
    url: str | None = None

    def to_json(self) -> dict[str, str | None]:
        """Return the ending as the page receives it."""
        return {"code": self.code, "url": self.url}

    def __bool__(self) -> bool:
        """Whether it gives the participant anything."""
        return self.code is not None or self.url is not None


@dataclass(frozen=True)
class Screening:
    """Who a protocol screens out (`mirror_avatar.lab.running.screening`).

    Attributes
    ----------
    round_trip_p95_ms
        The bound (ms) on the 95th percentile of a page's round trips at connect, or None.
    hidden_tab
        ``"record"`` (a tab hidden during a trial is recorded and the person told) or
        ``"refuse"`` (the person is refused).
    frame_rate_hz
        The fewest animation frames a second (Hz) a page may draw at connect, or None.
    window_width_px, window_height_px
        The smallest window (CSS pixels) a page may have at connect, or None.
    during_play
        ``"off"``, or what a page outside the round-trip, frame rate and window bounds during a
        trial does: ``"record"`` (recorded and the person told) or ``"refuse"`` (the person is
        refused).
    """

    round_trip_p95_ms: float | None = None
    hidden_tab: str = "record"
    frame_rate_hz: float | None = None
    window_width_px: int | None = None
    window_height_px: int | None = None
    during_play: str = "off"

    @property
    def at_entry(self) -> bool:
        """Whether a page is judged as it connects (any bound of its entry declared)."""
        bounds = (self.round_trip_p95_ms, self.frame_rate_hz, self.window_width_px,
                  self.window_height_px)  # fmt: skip
        return any(bound is not None for bound in bounds)

    @property
    def in_play(self) -> bool:
        """Whether a page is judged during trials (``during_play`` and a bound of its entry)."""
        return self.during_play != "off" and self.at_entry


@dataclass(frozen=True)
class Online:
    """A protocol's ``[online]`` table (see the module docstring).

    Attributes
    ----------
    panel_ids
        The query parameters of a join link recorded for its participant.
    completion
        Shown on the page when the participant's run has ended.
    refusal
        Shown to a participant screened out.
    instructions, consent
        The texts of the pages shown before the game (None: no such page).
    screening
        Who is screened out (`Screening`).
    """

    panel_ids: tuple[str, ...] = ()
    completion: Ending = Ending()
    refusal: Ending = Ending()
    instructions: str | None = None
    consent: str | None = None
    screening: Screening = Screening()


def parse_online(check: Checker, value: object, folder: Path) -> Online:
    """Read the ``[online]`` table (its keys: `mirror_avatar.lab.design.protocol_keys`).

    ``folder`` holds the protocol file, and the pages' text files it names.
    """
    data = check.table(value, "online")
    check.keys(data, "online", keys_of(ONLINE_SETTINGS))
    names = data.get("panel_ids", [])
    fix = 'e.g. ["PROLIFIC_PID", "STUDY_ID", "SESSION_ID"]'
    if not isinstance(names, list) or len(names) > MAX_PANEL_IDS:
        raise check.error("online.panel_ids", f"must be a list of at most {MAX_PANEL_IDS}", fix)
    for i, name in enumerate(names):
        if not isinstance(name, str) or not PANEL_NAME.fullmatch(name) or names.index(name) < i:
            raise check.error(
                f"online.panel_ids[{i}]",
                f"{name!r} is not a new query parameter name (1-32 letters, digits and _)",
                fix,
            )
    return Online(
        tuple(names),
        _ending(check, data, "completion"),
        _ending(check, data, "refusal"),
        _page_text(check, data, "instructions", folder),
        _page_text(check, data, "consent", folder),
        _screening(check, data),
    )


def _screening(check: Checker, data: dict[str, Any]) -> Screening:
    """Read the ``screen_`` keys; ``screen_during_play`` needs a bound of the entry's."""
    keys = ("round_trip_p95_ms", "hidden_tab", "frame_rate_hz", "window_width_px",
            "window_height_px", "during_play")  # fmt: skip
    screening = Screening(*(check.setting(data, "online", SCREENING[f"screen_{k}"]) for k in keys))
    if screening.during_play != "off" and not screening.in_play:
        raise check.error(
            "online.screen_during_play",
            f"{screening.during_play!r} has no bound to hold during play",
            "declare screen_frame_rate_hz, screen_window_width_px or screen_window_height_px",
        )
    return screening


def _page_text(check: Checker, data: dict[str, Any], page: str, folder: Path) -> str | None:
    """Read a page's text: ``<page>`` in the protocol, or ``<page>_file`` beside it.

    The file is named, not pathed: a name of letters, digits, ``.``, ``_`` and ``-`` in the
    protocol's folder, read by the checked reader (a regular UTF-8 file of at most
    `MAX_PAGE_BYTES`). Line breaks are kept; other control characters are refused.
    """
    where, text = f"online.{page}", data.get(page)
    if f"{page}_file" in data:
        if text is not None:
            raise check.error(where, f"{page} and {page}_file both give the page", "keep one")
        where, name = f"online.{page}_file", data[f"{page}_file"]
        if not isinstance(name, str) or not FILE_NAME.fullmatch(name):
            raise check.error(where, f"{name!r} is not a file name", f'e.g. "{page}.txt"')
        try:
            text = read_text(folder / name, MAX_PAGE_BYTES)
        except InputError as error:
            raise check.error(where, str(error), "put the file beside the protocol") from None
    if text is None:
        return None
    if not isinstance(text, str) or not (text.strip() and len(text) <= MAX_PAGE_CHARS):
        raise check.error(where, f"must be text of 1 to {MAX_PAGE_CHARS} characters", "shorten it")
    control = first_control(text.replace("\n", "").replace("\r", ""))
    if control is not None:
        raise check.error(where, f"holds the control character {control!r}", "remove it")
    return text.strip()


def _ending(check: Checker, data: dict[str, Any], which: str) -> Ending:
    """Read ``<which>_code`` and ``<which>_url``."""
    code, url = data.get(f"{which}_code"), data.get(f"{which}_url")
    if code is not None and not (isinstance(code, str) and CODE.fullmatch(code)):
        raise check.error(
            f"online.{which}_code", "must be 1-64 letters, digits, _ or -", 'e.g. "C1A2B3C4"'
        )
    if url is not None:
        parts = urlsplit(url) if isinstance(url, str) and len(url) <= MAX_URL_CHARS else None
        if parts is None or parts.scheme != "https" or not parts.hostname:
            raise check.error(
                f"online.{which}_url",
                f"must be an https link of at most {MAX_URL_CHARS} characters",
                'e.g. "https://app.prolific.com/submissions/complete?cc=C1A2B3C4"',
            )
        check.text(url, f"online.{which}_url")
    return Ending(code, url)


def panel_values(names: tuple[str, ...], query: Mapping[str, str]) -> dict[str, str] | str:
    """Return a join link's panel identifiers, or why they are refused.

    Parameters
    ----------
    names
        The protocol's ``panel_ids``; other query parameters are ignored.
    query
        The link's query parameters.

    Returns
    -------
    dict or str
        The values given, by name (an identifier left out is absent), or one line naming the
        identifier whose value is not 1 to `MAX_PANEL_VALUE_CHARS` letters, digits, ``_`` or
        ``-``.
    """
    values = {name: query[name] for name in names if name in query}
    for name, value in values.items():
        if not PANEL_VALUE.fullmatch(value):
            return (
                f"{name} must be 1 to {MAX_PANEL_VALUE_CHARS} letters, digits, _ or -: "
                "open the link the panel gave"
            )
    return values

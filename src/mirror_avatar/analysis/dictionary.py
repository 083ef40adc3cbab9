"""The study table's data dictionary: every column's description, units, levels and role.

Each column of `mirror_avatar.analysis.table` is described BIDS-style (``Description``,
``Units`` where it has units, ``Levels`` for a categorical one) plus ``Role``: ``identifier``
(who and which trial), ``design`` (what the protocol set: the factors), ``measure`` (computed
from the recording), ``p_value`` (a measure's p-value against its surrogates), ``answer``
(what the person answered) or ``quality`` (how the trial was recorded: whether it ran to its
end), so a report finds its measures, factors and the trials to leave out by role.
"""

from __future__ import annotations

import re
from typing import Any

from mirror_avatar.metrics import registry

ROLES = ("identifier", "design", "quality", "measure", "p_value", "answer")
"""What a column is, as the dictionary's ``Role`` says."""

DESIGN_COLUMNS: dict[str, dict[str, Any]] = {
    "participant": {"Description": "The study participant (pNNN: their number in the "
                    "counterbalancing), or the session id of a plain lab session",
                    "Role": "identifier"},
    "session": {"Description": "The lab session the trial was recorded in", "Role": "identifier"},
    "person": {"Description": "The player's label in the protocol (P1, A1...)",
               "Role": "identifier"},
    "player_kind": {"Description": "Who played in this slot",
                    "Levels": {"person": "a person at a page or device",
                               "avatar": "a computer player",
                               "recording": "a person's recorded trial replayed"},
                    "Role": "design"},
    "block": {"Description": "The block's position in the participant's run (1-based)",
              "Role": "design"},
    "condition": {"Description": "The study protocol's condition (a plain lab session: the "
                  "game, solo, leader_follower, joint or group)", "Role": "design"},
    "trial": {"Description": "The trial's number in the participant's run (1-based)",
              "Role": "identifier"},
    "position": {"Description": "The condition's position in the participant's order "
                 "(1-based)", "Role": "design"},
    "partners": {"Description": "The labels of every other player of the trial, joined by +",
                 "Role": "design"},
    "partner_kind": {"Description": "The true kind of the player's partners",
                     "Levels": {"person": "every partner a person",
                                "avatar": "every partner a computer player",
                                "recording": "every partner a person's recorded trial replayed",
                                "mixed": "partners of several kinds",
                                "none": "no partner (a solo trial)"},
                     "Role": "design"},
    "delay_s": {"Description": "Visual delay of the partners on the persons' pages",
                "Units": "s", "Role": "design"},
    "partner_view": {"Description": "How the pages drew the partners when the people's links "
                     "differed (METHODS section 19)",
                     "Levels": {"as_arrives": "as each frame arrived",
                                "equalised": "each sample drawn the same lag after it was taken "
                                             "on every page (local lag)",
                                "predicted": "extrapolated from the partner's last samples "
                                             "(dead reckoning)"},
                     "Role": "design"},
    "occluded": {"Description": "Whether the partners were hidden during part of the trial",
                 "Role": "design"},
    "perturbations": {"Description": "Changes of an avatar during the trial",
                      "Role": "design"},
    "complete": {"Description": "Whether the trial ran to its end (false: it stopped early - "
                 "aborted, ended by a drop or a crash - and its measures, if any, are of what "
                 "was recorded; study report leaves it out)", "Role": "quality"},
}  # fmt: skip
"""The identifier, design and quality columns, in table order."""

PAGE_COLUMNS: dict[str, dict[str, Any]] = {
    "page_rtt_median_ms": {"Description": "Median round trip of the person's page to the "
                           "server during the trial (NTP-style exchanges, METHODS section 18)",
                           "Units": "ms", "Role": "quality"},
    "page_rtt_p95_ms": {"Description": "95th percentile of the page's round trips",
                        "Units": "ms", "Role": "quality"},
    "page_rtt_max_ms": {"Description": "Longest round trip of the page", "Units": "ms",
                        "Role": "quality"},
    "page_offset_ms": {"Description": "Median offset of the page's clock during the trial "
                       "(server time minus page time)", "Units": "ms", "Role": "quality"},
    "page_uncertainty_ms": {"Description": "Median uncertainty of the page clock's offset "
                            "(half the smallest round trip of its window)", "Units": "ms",
                            "Role": "quality"},
    "page_sample_rate_hz": {"Description": "Pointer samples the page sent per second (its "
                            "device's rate)", "Units": "Hz", "Role": "quality"},
    "page_frame_rate_hz": {"Description": "Animation frames the page drew per second",
                           "Units": "Hz", "Role": "quality"},
    "page_stalls": {"Description": "Gaps of over half a second in the page's samples",
                    "Role": "quality"},
    "page_stalled_s": {"Description": "The page's stalls' total length", "Units": "s",
                       "Role": "quality"},
    "page_hidden": {"Description": "Times the page's tab was hidden during the trial "
                    "(METHODS section 9)", "Role": "quality"},
    "page_hidden_s": {"Description": "How long the page's tab was hidden during the trial",
                      "Units": "s", "Role": "quality"},
    "page_blur": {"Description": "Times the page's window lost the focus during the trial",
                  "Role": "quality"},
    "page_blur_s": {"Description": "How long the page's window was out of focus during the "
                    "trial", "Units": "s", "Role": "quality"},
    "page_below_bounds": {"Description": "Times the page's frame rate (over its last 2 s) or "
                          "window fell below the protocol's bounds during the trial "
                          "(screen_during_play, METHODS section 9)", "Role": "quality"},
    "page_below_bounds_s": {"Description": "How long the page was below the protocol's bounds "
                            "during the trial", "Units": "s", "Role": "quality"},
    "page_view_delay_ms": {"Description": "Mean delay from a partner's sample to the page "
                           "drawing it, on the server's clock (METHODS section 19)", "Units": "ms",
                           "Role": "quality"},
    "page_view_delay_p95_ms": {"Description": "95th percentile of the delay from a partner's "
                               "sample to the page drawing it", "Units": "ms", "Role": "quality"},
    "page_view_error_rms": {"Description": "RMS of the partner's drawn position minus its "
                            "recorded position at the time of drawing",
                            "Units": "playing range units", "Role": "quality"},
}  # fmt: skip
"""The quality columns of a person's page (`mirror_avatar.files.trial_record.PageRecord.cells`),
in table order; empty on the rows of avatars, devices and trials recorded before them."""

RUN_COLUMNS: dict[str, dict[str, Any]] = {
    "completion_code": {"Description": "The completion code the person's end page showed when "
                        "their run ended (the link back when the protocol gives only a link; "
                        "empty: not shown)", "Role": "quality"},
    "refusals": {"Description": "Times the person was screened out in the participant's run "
                 "(METHODS section 9; a person screened out stays out: 0 or 1)",
                 "Role": "quality"},
    "refusal": {"Description": "Why the person was screened out, as their page said it "
                "(empty: not screened out)", "Role": "quality"},
}  # fmt: skip
"""The columns of a run's outcomes (`mirror_avatar.analysis.outcomes`), on each of its persons'
rows; a person screened out before their first trial has one row of their own, its trial empty."""

PANEL_PREFIX = "panel_"
"""What a panel identifier's column is named after: ``panel_PROLIFIC_PID``."""


def panel_info(column: str) -> dict[str, Any]:
    """Describe a panel identifier's column (``panel_<name>``)."""
    name = column.removeprefix(PANEL_PREFIX)
    return {"Description": f"The person's {name} on their recruitment panel, from their join "
            "link's query (empty: the link had none)", "Role": "identifier"}  # fmt: skip


MEASURE_COLUMNS = registry.TABLE_COLUMNS
"""The measure columns of the study table, in order (`mirror_avatar.metrics.registry`)."""

PER_PLAYER = registry.OWN_COLUMNS
"""The columns of a measure with one value per player: the player's own, on its row."""


def _registry_key(column: str) -> str:
    return f"{column}_player_0" if column in PER_PLAYER else column


def _described(column: str) -> tuple[str, str]:
    key = _registry_key(column)
    unit = registry.measure(key).unit
    return registry.description(key), registry.UNIT_NAMES.get(unit, unit)


MEASURES: dict[str, tuple[str, str]] = {column: _described(column) for column in MEASURE_COLUMNS}
"""Every measure column: description and units, from `mirror_avatar.metrics.registry`."""


def column_label(column: str) -> str:
    """Name a column in words: a measure's registry label, any other column by its name.

    A player's own measure is named without the player's number: ``jitter index (2-3 Hz share)``.
    """
    if column not in MEASURES:
        return column
    label = registry.label(_registry_key(column))
    return re.sub(r" (of )?player 0", "", label) if column in PER_PLAYER else label


def is_angle(column: str) -> bool:
    """Whether a column is a measure whose values are angles (`registry.Measure.angle`)."""
    return column in MEASURES and registry.measure(_registry_key(column)).angle


def p_value_column(measure: str) -> str:
    """Return the column of a tested measure's p-value against surrogates."""
    return registry.p_value_key(measure) if registry.find(measure) else f"{measure}_p_value"


def _tested(column: str) -> str:
    """Return the measure column a p-value column belongs to (the column itself otherwise)."""
    return registry.tested_of(column) or column.removesuffix("_p_value")


def measure_info(column: str) -> dict[str, Any]:
    """Describe a measure column (a measure or a measure's p-value)."""
    tested = _tested(column)
    if column != tested:
        text = MEASURES[tested][0]
        return {"Description": f"p-value against surrogates of: {text}", "Role": "p_value"}
    text, units = MEASURES[column]
    return {"Description": text} | ({"Units": units} if units else {}) | {"Role": "measure"}


GUESS_COLUMNS: dict[str, dict[str, Any]] = {
    "guess_kind": {"Description": "What the person said their partner was, from their answer "
                   "to the person-or-computer question",
                   "Levels": {"person": "a person", "avatar": "a computer"}, "Role": "answer"},
    "guess_correct": {"Description": "Whether guess_kind names whose motion the partners "
                      "showed (partner_kind; a recording is a person's)", "Role": "answer"},
    "guess_confidence": {"Description": "The Likert point of the confidence question asked "
                         "with the guess (empty when none was asked)", "Role": "answer"},
}  # fmt: skip
"""The columns of the person-or-computer question."""

CSV_TEXT = (
    " In study.csv a text cell that starts with =, +, -, @, a tab, a carriage return or ' has a "
    "' put before it, so that a spreadsheet shows it as text and never runs it as a formula; "
    "study.parquet holds the text as given."
)
"""What a text column's description adds: how `mirror_avatar.files.atomic.csv_text` writes it."""

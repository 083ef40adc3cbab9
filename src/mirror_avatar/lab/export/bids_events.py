"""The events of an exported lab trial: the trial, its condition and every manipulation.

One ``_events.tsv`` per recording (BIDS 1.9.0, task events), all with the columns
`EVENT_COLUMNS`, described once for the dataset in ``task-mirrorgame_events.json``
(`EVENT_COLUMN_INFO`). Onsets and durations are in seconds from the recording's first sample;
``sample`` is the index (0-based) of the first sample at or after the onset. The rows, in
order of onset (the trial first):

- ``trial``: the whole trial as recorded, with its number, block and condition (the protocol's
  condition name in a study, else the lab condition);
- ``delay``: the visual delay of the partners on the pages (``delay_s``), for the whole trial;
- ``occlusion``: each interval during which the partners were hidden, clipped to the recording;
- ``input_lost`` / ``input_live``: a person's input stopped delivering / delivered again
  (``player``), from the record's input events;
- ``dropped``: a person's connection dropped (``player``), from the record's drops;
- ``perturbation``: a change of an avatar mid-trial (``player``, ``change``), from the
  record's perturbations.

Everything is read from the trial's record (`mirror_avatar.files.trial_record.TrialRecord`).
"""

from __future__ import annotations

import math
from typing import Any

from mirror_avatar.files.bids.names import MISSING
from mirror_avatar.files.trial_record import TrialRecord

EVENT_COLUMNS = (
    "onset", "duration", "trial_type", "sample", "trial", "block", "condition", "player",
    "delay_s", "change",
)  # fmt: skip
"""Columns of a recording's ``_events.tsv``."""

EVENT_COLUMN_INFO: dict[str, Any] = {
    "onset": {"Description": "Onset from the recording's first sample", "Units": "s"},
    "duration": {"Description": "Duration of the event (0: an instant)", "Units": "s"},
    "trial_type": {
        "Description": "What happened",
        "Levels": {
            "trial": "The trial, from its first recorded sample to its last",
            "delay": "The partners were drawn delay_s late on the participants' pages for the "
            "whole trial (the recording holds their true positions)",
            "occlusion": "The partners were hidden on the participants' pages",
            "input_lost": "The input of participant `player` stopped delivering samples; "
            "their last position is held",
            "input_live": "The input of participant `player` delivered samples again",
            "dropped": "The connection of participant `player` dropped; their position is "
            "held from here on",
            "perturbation": "The avatar `player` was changed mid-trial as `change` says",
        },
    },
    "sample": {"Description": "Index of the first motion sample at or after the onset (0-based)"},
    "trial": {"Description": "Number of the trial in its session (the run's index)"},
    "block": {"Description": "Block of the study protocol the trial belongs to (n/a: no study)"},
    "condition": {
        "Description": "Condition of the trial: the study protocol's condition name, else the "
        "lab condition (solo, leader_follower, joint or group)"
    },
    "player": {"Description": "Label of the player the event concerns (n/a: every player)"},
    "delay_s": {"Description": "Visual delay of the partners on the pages", "Units": "s"},
    "change": {"Description": "What a perturbation changed in the avatar, as recorded"},
}
"""The events' columns, described once for the dataset (``task-mirrorgame_events.json``)."""


def trial_events(record: TrialRecord, n_samples: int, period: float) -> list[dict[str, str]]:
    """List the events of a lab trial (see the module docstring) as ``_events.tsv`` rows.

    Parameters
    ----------
    record
        The trial's record (`mirror_avatar.files.trial_record.TrialRecord`): its study's delay and
        occlusions, its input events, drops and perturbations.
    n_samples
        Samples recorded.
    period
        The control period (s).

    Returns
    -------
    list of dict
        One row per event (every column -> its cell, ``n/a`` when it does not apply), the
        trial first, then by onset.
    """
    length = n_samples * period
    common = {
        "trial": str(record.trial),
        "block": _cell(record.block),
        "condition": _cell(record.named_condition),
    }
    rows = [_row(0.0, length, "trial", period)]
    study = record.study
    if study is not None and study.delay_s > 0:
        rows.append(_row(0.0, length, "delay", period) | {"delay_s": repr(float(study.delay_s))})
    for start, end in () if study is None else study.occluded_s:
        if 0 <= start < end and start < length:
            rows.append(_row(start, min(end, length) - start, "occlusion", period))
    for event in record.input_events:
        if event.event in ("lost", "live"):
            row = _row(event.sample * period, 0.0, f"input_{event.event}", period)
            rows.append(row | {"player": _cell(event.label)})
    for who, sample in record.dropped.items():
        rows.append(_row(sample * period, 0.0, "dropped", period) | {"player": who})
    for change in record.perturbations:
        rows.append(_row(change.time_s, 0.0, "perturbation", period)
                    | {"player": _cell(change.player), "change": _cell(change.change)})  # fmt: skip
    first, rest = rows[0], rows[1:]
    rest.sort(key=lambda row: float(row["onset"]))
    empty = dict.fromkeys(EVENT_COLUMNS, MISSING)
    return [empty | common | row for row in (first, *rest)]


def _row(onset: float, duration: float, kind: str, period: float) -> dict[str, str]:
    """Return an event's onset, duration (s), type and first sample."""
    sample = max(0, math.ceil(round(onset / period, 9)))
    return {"onset": repr(float(onset)), "duration": repr(float(duration)),
            "trial_type": kind, "sample": str(sample)}  # fmt: skip


def _cell(value: object) -> str:
    """Write a value as a TSV cell: text as is, numbers as written, nothing as ``n/a``."""
    return MISSING if value is None or value == "" else str(value)

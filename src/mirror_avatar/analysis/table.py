"""The study table: one row per trial and player, with the design, the measures and the answers.

`study_table` turns a study's trials (`mirror_avatar.analysis.trials.read_study_trials`) into
one long `pandas.DataFrame` (columns in `mirror_avatar.analysis.dictionary`): who played
(``participant``, ``session``, ``person``, ``player_kind``: `slot_kind`), where the trial
stands in the participant's run (``block`` and ``position``: 1-based order of the block and of
the condition in the run, counted from the trials as played; ``trial``), what the protocol set
(``condition``, ``partners``, ``partner_kind``, ``delay_s``, ``partner_view``, ``occluded``,
``perturbations``), whether the trial ran to its end (``complete``, its record's: an aborted
trial's rows are kept, saying so), a person's panel identifiers (``panel_<name>``) and their
run's outcomes (the completion code shown, refusals:
`mirror_avatar.analysis.dictionary.RUN_COLUMNS`), the measures of the player's trial
(`mirror_avatar.metrics.session_metrics` and `mirror_avatar.metrics.measures.session_measures`,
measured as ``evaluate`` and the lab measure
a trial: `mirror_avatar.metrics.measuring.measure_trial`, with ``surrogates`` circular-shift
surrogates seeded by the trial's own seed: a pair's measures on both players' rows, a player's
own - jitter index, influence, a group member's measures against its neighbours - on its row),
then each answer (``answer_<question id>``) and, for a person-or-computer question, the guess
(`mirror_avatar.lab.design.guesses`).
`write_study_table` writes ``study.csv``, ``study.parquet`` and the dictionary ``study.json``.
"""

from __future__ import annotations

import io
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from mirror_avatar.analysis.dictionary import (
    CSV_TEXT,
    DESIGN_COLUMNS,
    GUESS_COLUMNS,
    MEASURES,
    PAGE_COLUMNS,
    PANEL_PREFIX,
    PER_PLAYER,
    RUN_COLUMNS,
    measure_info,
    p_value_column,
    panel_info,
)
from mirror_avatar.analysis.outcomes import RunKey
from mirror_avatar.analysis.trials import StudyTrial
from mirror_avatar.files.atomic import (
    csv_text,
    json_text,
    write_atomic_files,
)
from mirror_avatar.files.trial_record import SlotRecord, partner_kind
from mirror_avatar.lab.design.guesses import MOTION_OF, guess, motion_kind
from mirror_avatar.lab.export.run_outcomes import RunOutcomes
from mirror_avatar.metrics import TRIM, registry
from mirror_avatar.metrics.measuring import TRIAL_SURROGATES, measure_trial

TABLE_FILES = ("study.csv", "study.parquet", "study.json")
"""The files `write_study_table` writes."""

SURROGATES = TRIAL_SURROGATES
"""Surrogates per trial by default: the lab's own (p-values down to 0.05)."""

MAX_LEVELS = 20
"""Most distinct values a text column may have to be listed as ``Levels`` (**choice**)."""

_PER_PLAYER = tuple(f"{column}_player_" for column in PER_PLAYER)


def study_table(
    trials: Sequence[StudyTrial],
    trim: float = TRIM,
    surrogates: int = SURROGATES,
    outcomes: Mapping[RunKey, RunOutcomes] | None = None,
) -> pd.DataFrame:
    """Make the study table of ``trials`` (module docstring); rows by participant, trial, player.

    ``outcomes`` are the runs' (`mirror_avatar.analysis.outcomes.read_study_outcomes`): their
    `RUN_COLUMNS` on each person's rows, and a row for each person screened out before their
    first trial.
    """
    outcomes = outcomes or {}
    rows = [
        row
        for trial in trials
        for row in trial_rows(trial, trial_measures(trial, trim, surrogates) or {}, outcomes)
    ]
    return table_of_rows(rows, outcomes)


def table_of_rows(
    rows: list[dict[str, Any]], outcomes: Mapping[RunKey, RunOutcomes]
) -> pd.DataFrame:
    """Make the study table of its trials' rows (`trial_rows`, in trial order).

    The runs' ``outcomes`` add a row for each person screened out before their first trial.
    """
    rows += _refused_before_playing(rows, outcomes)
    return _ordered(pd.DataFrame(rows))


def trial_rows(
    trial: StudyTrial, measures: dict[str, Any], outcomes: Mapping[RunKey, RunOutcomes]
) -> list[dict[str, Any]]:
    """Return a trial's rows, one per player, given its ``measures`` (`trial_measures`)."""
    run = outcomes.get((trial.participant, trial.record.session_id))
    rows = []
    for k, slot in enumerate(trial.record.slots):
        row = _design(trial, slot) | {"block": trial.block, "position": trial.position}
        row |= _panel(trial, slot) | _run(run, slot.label, outcomes)
        row |= _page(trial, slot)
        row |= _player_measures(measures, k, trial)
        row |= _answers(trial, slot)
        rows.append(row)
    return rows


def _panel(trial: StudyTrial, slot: SlotRecord) -> dict[str, str]:
    """Return the person's panel identifiers (``panel_<name>``), as their join link gave them."""
    study = trial.record.study
    ids = {} if study is None else study.panel.get(slot.label, {})
    return {f"{PANEL_PREFIX}{name}": value for name, value in ids.items()}


def _run(
    run: RunOutcomes | None, label: str, outcomes: Mapping[RunKey, RunOutcomes]
) -> dict[str, Any]:
    """Return a person's `RUN_COLUMNS`: the completion shown, the refusals and why."""
    row: dict[str, Any] = {}
    if any(o.completion for o in outcomes.values()):
        row["completion_code"] = None if run is None else run.completion.get(label)
    if any(o.refusals for o in outcomes.values()):
        reason = None if run is None else run.refusals.get(label)
        row |= {"refusals": int(reason is not None), "refusal": reason}
    return row


def _refused_before_playing(
    rows: list[dict[str, Any]], outcomes: Mapping[RunKey, RunOutcomes]
) -> list[dict[str, Any]]:
    """Return a row for each person refused in a run who has no row: they played no trial."""
    played = {(row["participant"], row["session"], row["person"]) for row in rows}
    return [
        {"participant": participant, "session": session, "person": label,
         "player_kind": "person", "complete": False}
        | _run(run, label, outcomes)
        for (participant, session), run in outcomes.items()
        for label in run.refusals
        if (participant, session, label) not in played
    ]  # fmt: skip


def trial_measures(trial: StudyTrial, trim: float, surrogates: int) -> dict[str, Any] | None:
    """Compute a trial's metrics and measures (`mirror_avatar.metrics.measuring.measure_trial`).

    A trial with fewer than `mirror_avatar.files.trials.MIN_SAMPLES` samples after the trim (a run
    stopped at once) has none (None): its rows keep their design and answers.
    """
    measured = measure_trial(trial.session, surrogates, trim)
    return None if measured is None else measured.metrics | measured.measures.values


def slot_kind(slot: SlotRecord) -> str:
    """Name a slot's kind: ``person``, ``avatar`` or ``recording`` (`motion_kind`)."""
    return motion_kind(slot.kind, slot.spec)


def _design(trial: StudyTrial, slot: SlotRecord) -> dict[str, Any]:
    record, study = trial.record, trial.record.study
    partners = record.partners_of(slot.label)
    return {
        "participant": trial.participant,
        "session": record.session_id,
        "person": slot.label,
        "player_kind": slot_kind(slot),
        "condition": record.condition if study is None else study.condition,
        "trial": record.trial,
        "partners": "+".join(p.label for p in partners),
        "partner_kind": partner_kind(slot_kind(p) for p in partners),
        "delay_s": 0.0 if study is None else float(study.delay_s),
        "partner_view": "as_arrives"
        if study is None or study.partner_view is None
        else study.partner_view["handling"],
        "occluded": study is not None and bool(study.occluded_s),
        "perturbations": len(record.perturbations),
        "complete": record.complete,
    }


def _page(trial: StudyTrial, slot: SlotRecord) -> dict[str, Any]:
    """Return the quality columns of the person's page (`PAGE_COLUMNS`), none without one."""
    page = trial.record.pages.get(slot.label)
    return {} if page is None else page.cells()


def _player_measures(measures: dict[str, Any], k: int, trial: StudyTrial) -> dict[str, Any]:
    """Select player k's measures: the pair's or group's, its own, its p-values."""
    labels = [slot.label for slot in trial.record.slots]
    row: dict[str, Any] = {}
    for key, value in measures.items():
        own = next((prefix for prefix in _PER_PLAYER if key.startswith(prefix)), None)
        if own is not None:
            if key == f"{own}{k}" and value is not None:
                row[own.removesuffix("_").removesuffix("_player")] = value
        elif key == "leader":
            row[key] = labels[value] if isinstance(value, int) else str(value)
        elif _known(key) and isinstance(value, int | float) and not _pairwise(key, len(labels)):
            row[key] = value
    group = measures.get("players")
    if isinstance(group, list):
        row |= {key: group[k][key] for key in registry.GROUP_PLAYER if key in group[k]}
    return row


def _pairwise(key: str, n_players: int) -> bool:
    """Whether ``key`` is a pair's measure in a group (``influence`` averages a player's)."""
    return n_players > 2 and key.startswith("transfer_entropy_")


_KNOWN = frozenset(MEASURES) | {p_value_column(m) for m in MEASURES}


def _known(key: str) -> bool:
    return key in _KNOWN


def _answers(trial: StudyTrial, slot: SlotRecord) -> dict[str, Any]:
    """Return a person's answers after the trial, and their person-or-computer guess."""
    given = () if trial.answers is None else trial.answers.of(slot.label)
    row: dict[str, Any] = {f"answer_{a.question}": _answer(a.value, a.kind) for a in given}
    found = guess(given)
    if found is not None:
        partners = _design(trial, slot)["partner_kind"]
        kind, confidence = found
        row |= {
            "guess_kind": kind,
            "guess_correct": None
            if kind is None or partners not in MOTION_OF
            else kind == MOTION_OF[partners],
            "guess_confidence": confidence,
        }
    return row


def _answer(value: object, kind: str) -> object:
    """Return an answer as a cell: a Likert point as a float, text as text, nothing as None."""
    if value is None or value == "":
        return None
    if kind == "likert" and isinstance(value, int | float) and not isinstance(value, bool):
        return float(value)
    return value if isinstance(value, str) else str(value)


def _ordered(table: pd.DataFrame) -> pd.DataFrame:
    """Order the columns (design, measures, answers) and rows, and type them."""
    design = list(DESIGN_COLUMNS)
    tested = (c for m in MEASURES for c in (m, p_value_column(m)) if c in table.columns)
    measured = list(dict.fromkeys(tested))  # time_lag and its peak share one p-value
    answers = sorted(c for c in table.columns if c.startswith("answer_"))
    guesses = [c for c in GUESS_COLUMNS if c in table.columns]
    pages = [c for c in PAGE_COLUMNS if c in table.columns]
    if table.empty:
        return pd.DataFrame(columns=design)
    panels = sorted(c for c in table.columns if c.startswith(PANEL_PREFIX))
    runs = [c for c in RUN_COLUMNS if c in table.columns]
    table = table.reindex(columns=design + panels + runs + pages + measured + answers + guesses)
    table = table.sort_values(["participant", "session", "trial"], kind="stable")
    types = {"block": "int64", "trial": "int64", "position": "int64", "perturbations": "int64",
             "delay_s": "float64", "occluded": "bool", "complete": "bool"}  # fmt: skip
    if "refusals" in table:
        types["refusals"] = "int64"
    table = table.astype(types | _nullable(table, types))
    for column in [*pages, *measured, "guess_confidence"]:
        if column in table and column != "leader":
            table[column] = pd.to_numeric(table[column], errors="coerce").astype("float64")
    for column in [c for c in answers if table[c].map(_is_number).all()]:
        table[column] = table[column].astype("float64")
    if "guess_correct" in table:
        table["guess_correct"] = table["guess_correct"].astype("boolean")
    return table.reset_index(drop=True)


def _nullable(table: pd.DataFrame, types: dict[str, str]) -> dict[str, str]:
    """Return the nullable types of the columns with empty cells (a refused person's row)."""
    nullable = {"int64": "Int64", "bool": "boolean"}
    return {
        c: nullable[kind] for c, kind in types.items() if kind in nullable and table[c].isna().any()
    }


def _is_number(value: object) -> bool:
    """Whether an answer cell is a number or empty (a Likert point, or none given)."""
    return value is None or isinstance(value, float)


def table_dictionary(table: pd.DataFrame, questions: dict[str, str]) -> dict[str, Any]:
    """Describe every column of ``table`` (`mirror_avatar.analysis.dictionary`).

    ``questions`` gives each question's text by id, for its answer column.
    """
    info: dict[str, Any] = {}
    for column in table.columns:
        if column in DESIGN_COLUMNS:
            info[column] = dict(DESIGN_COLUMNS[column])
        elif column in GUESS_COLUMNS:
            info[column] = dict(GUESS_COLUMNS[column])
        elif column in PAGE_COLUMNS:
            info[column] = dict(PAGE_COLUMNS[column])
        elif column in RUN_COLUMNS:
            info[column] = dict(RUN_COLUMNS[column])
        elif column.startswith(PANEL_PREFIX):
            info[column] = panel_info(column)
        elif column.startswith("answer_"):
            qid = column.removeprefix("answer_")
            info[column] = {"Description": f"The answer to {qid}: {questions.get(qid, qid)}",
                            "Role": "answer"}  # fmt: skip
        else:
            info[column] = measure_info(column)
        if any(isinstance(value, str) for value in table[column]):
            info[column]["Description"] += CSV_TEXT
        text = pd.api.types.is_object_dtype(table[column]) or pd.api.types.is_string_dtype(
            table[column]
        )
        if text and "Levels" not in info[column]:
            values = sorted({str(v) for v in table[column].dropna()})
            categorical = column in ("condition", "leader") or column.startswith("answer_")
            if categorical and 0 < len(values) <= MAX_LEVELS:
                info[column]["Levels"] = {value: value for value in values}
    return info


def question_texts(trials: Sequence[StudyTrial]) -> dict[str, str]:
    """Return each question's text by id, as the trials' answers record it."""
    return {a.question: a.text for t in trials if t.answers for a in t.answers.answers}


def write_study_table(table: pd.DataFrame, dictionary: dict[str, Any], out_dir: Path) -> None:
    """Write ``study.csv`` (empty cells: NA), ``study.parquet`` and ``study.json`` together.

    All three or none (`mirror_avatar.files.atomic.write_atomic_files`): a failure leaves each file
    as it was, so no table is left without its dictionary.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    contents = (csv_text(table, index=False, na_rep="NA"), _parquet(table), json_text(dictionary))
    write_atomic_files(out_dir, dict(zip(TABLE_FILES, contents, strict=True)))


def _parquet(table: pd.DataFrame) -> bytes:
    buffer = io.BytesIO()
    table.to_parquet(buffer, index=False)
    return buffer.getvalue()

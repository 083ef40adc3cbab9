"""Acquisition times and answers of a lab trial as the BIDS export writes them."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from mirror_avatar.files.bids.tables import read_tsv, tsv_rows
from mirror_avatar.files.bids.writing import tsv_table
from mirror_avatar.files.trial_record import SlotRecord, TrialRecord, trial_record
from mirror_avatar.lab.export.bids_study import acq_time, answer_rows, read_answers


def record(**stamps: str | None) -> TrialRecord:
    """A one-person solo trial's record with the given time stamps (``lab_created_utc`` is
    the early recordings' creation time inside the ``lab`` object)."""
    lab: dict[str, Any] = {"session_id": "s", "condition": "solo", "trial": 1,
                           "slots": [{"label": "P1", "kind": "human", "role": "solo"}]}  # fmt: skip
    if "lab_created_utc" in stamps:
        lab["created_utc"] = stamps.pop("lab_created_utc")
    return trial_record({"lab": lab} | stamps)


def test_acq_time_is_the_first_samples_time_in_utc_as_bids_writes_it() -> None:
    stamps = {
        "started_utc": "2026-11-25T23:30:00.250000+01:00",
        "created_utc": "2026-11-25T22:29:59.000000+00:00",
        "lab_created_utc": "2020-01-01T00:00:00+00:00",
    }
    assert acq_time(record(**stamps)) == "2026-11-25T22:30:00.250000Z"
    assert acq_time(record(**stamps | {"started_utc": None})) == "2026-11-25T22:29:59.000000Z"
    assert acq_time(record(lab_created_utc="2025-03-01T10:00:00")) == (
        "2025-03-01T10:00:00.000000Z"
    )
    assert acq_time(record(created_utc="yesterday")) == "n/a"


def test_answers_without_the_questions_text_keep_their_values_and_order(tmp_path: Path) -> None:
    answers = {
        "trial": 3, "block": "b", "condition": "c", "after_trial": ["who", "sure"],
        "after_block": ["notes"],
        "answers": {
            "P1": {
                "notes": {"value": "tab\there\nand a line", "utc": "u3"},
                "sure": {"value": 6, "utc": "u2"},
                "who": {"value": "a person", "utc": "u1"},
            },
            "P2": {},
        },
    }  # fmt: skip
    (tmp_path / "trial-03_answers.json").write_text(json.dumps(answers))
    answers = read_answers(tmp_path / "trial-03_session.csv")
    assert read_answers(tmp_path / "trial-04_session.csv") is None
    slots = [SlotRecord("P1", "human", "group"), SlotRecord("A1", "avatar", "group"),
             SlotRecord("P2", "human", "group")]  # fmt: skip
    rows = answer_rows(answers, "P1", slots)
    assert [(r["question"], r["text"], r["kind"], r["answer"], r["after"], r["answered_utc"])
            for r in rows] == [
        ("who", "n/a", "n/a", "a person", "trial", "u1"),
        ("sure", "n/a", "n/a", "6", "trial", "u2"),
        ("notes", "n/a", "n/a", "tab\there\nand a line", "block", "u3"),
    ]  # fmt: skip
    assert {(r["partners"], r["partner_kind"]) for r in rows} == {("A1+P2", "mixed")}
    assert answer_rows(answers, "P2", slots) == [] and answer_rows(answers, "P3", slots) == []
    alone = answer_rows(answers, "P1", slots[:1])
    assert {(r["partners"], r["partner_kind"]) for r in alone} == {("n/a", "none")}


def test_a_tsv_cell_reads_back_as_the_text_written(tmp_path: Path) -> None:
    texts = ["a\tb", "two\r\nlines\n", "C:\\new\\table", '"quoted" ', "  ", "\\t typed", "é\x1b[0m"]
    path = tmp_path / "t.tsv"
    path.write_text(
        tsv_table(["key", "text"], [{"key": str(i), "text": t} for i, t in enumerate(texts)])
    )
    assert len(path.read_text().splitlines()) == len(texts) + 1
    header, rows = tsv_rows(path)
    assert header == ["key", "text"]
    assert [row["text"] for row in rows] == texts
    assert read_tsv(path, "key")[1]["2"]["text"] == "C:\\new\\table"

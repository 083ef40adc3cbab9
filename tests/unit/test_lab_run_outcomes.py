"""A study run's end and refusals read back (`mirror_avatar.lab.export.run_outcomes`): what the
runner and the screening write, a link-only completion, and damaged files refused naming them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.lab.export.run_outcomes import RunOutcomes, read_outcomes, write_ended
from mirror_avatar.lab.running.screening import record_refusal

LINK = "https://app.prolific.com/submissions/complete?cc=C1A2B3C4"


def test_the_end_and_the_refusals_read_back_as_written(tmp_path):
    assert read_outcomes(tmp_path) == RunOutcomes()
    write_ended(tmp_path, {"code": "C1A2B3C4", "url": LINK}, ["P1", "P3"])
    record_refusal(tmp_path, "P2", "Your tab was hidden.", {"trial": 2})
    assert read_outcomes(tmp_path) == RunOutcomes(
        completion={"P1": "C1A2B3C4", "P3": "C1A2B3C4"}, refusals={"P2": "Your tab was hidden."}
    )


def test_a_link_only_completion_is_the_link_and_none_is_nothing(tmp_path):
    write_ended(tmp_path, {"code": None, "url": LINK}, ["P1"])
    assert read_outcomes(tmp_path).completion == {"P1": LINK}
    write_ended(tmp_path, None, ["P1"])
    assert read_outcomes(tmp_path).completion == {}


@pytest.mark.parametrize(
    ("name", "text", "problem"),
    [
        ("ended.json", "[1, 2]", "not a JSON object"),
        ("ended.json", '{"completion": null, "shown": "P1"}', "shown is not a list"),
        ("refusal-P1.json", '{"label": "P1"}', "no label or no reason"),
        ("refusal-P1.json", "{not json", "refusal-P1.json"),
    ],
)
def test_a_damaged_file_is_refused_naming_it(tmp_path: Path, name, text, problem):
    (tmp_path / name).write_text(text)
    with pytest.raises(InputError, match=problem) as refused:
        read_outcomes(tmp_path)
    assert name in str(refused.value)


def test_what_the_runner_writes_is_one_json_object(tmp_path):
    write_ended(tmp_path, None, [])
    ended = json.loads((tmp_path / "ended.json").read_text())
    assert set(ended) == {"ended_utc", "completion", "shown"} and ended["shown"] == []

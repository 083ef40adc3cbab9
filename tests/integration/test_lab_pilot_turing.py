"""The Turing template piloted through the lab server to its report (issue 47, item 6).

Two virtual participants follow, blinded, either a person's recorded trial replayed or that
person's avatar (`examples/protocols/turing.toml`, trials shortened) and answer "person or
computer?" with a detection rate of 1 (``--answer partner=detect:1``: the stand-ins' truth, from
the protocol's schedule, must agree with the table's, from the recorded slots); `study table`
must call a recording a person's motion and `study report` score every answer against chance
with that truth.
"""

from __future__ import annotations

import json

import pandas as pd
import pytest
from scipy import stats
from test_lab_pilot import ROOT, rehearsal, run_command

TEMPLATE = ROOT / "examples" / "protocols" / "turing.toml"
PARTNERS = {"recording-1": "recording", "recording-2": "recording",
            "avatar-1": "avatar", "avatar-2": "avatar"}  # fmt: skip
"""Each condition's partner as the study table names it."""

RIGHT = {"recording": "person", "avatar": "avatar"}
"""The right guess about each partner: a recording replayed is a person's motion."""


@pytest.fixture(scope="module")
def reported(tmp_path_factory: pytest.TempPathFactory) -> tuple[pd.DataFrame, dict, str]:
    folder = tmp_path_factory.mktemp("turing")
    out, results, report = folder / "out", folder / "results", folder / "report"
    # The answers' scores need neither surrogates nor many bootstrap resamples.
    for arguments in (
        ("lab", "pilot", "--protocol", str(rehearsal(TEMPLATE, folder)), "--participants", "2",
         "--seed", "11", "--answer", "partner=detect:1", "--out", str(out)),
        ("study", "table", str(out), "--surrogates", "0", "--out", str(results)),
        ("study", "report", str(results), "--resamples", "100", "--out", str(report)),
    ):  # fmt: skip
        result = run_command(*arguments)
        assert result.returncode == 0, result.stderr
    table = pd.read_csv(results / "study.csv")
    scores = json.loads((report / "results.json").read_text(encoding="utf-8"))
    return table, scores["identification"], (report / "report.html").read_text(encoding="utf-8")


@pytest.mark.long
def test_the_table_names_the_recording_a_person_s_motion(reported):
    table, _, _ = reported
    people = table[table["player_kind"] == "person"]
    assert len(people) == 2 * len(PARTNERS)
    assert dict(zip(people["condition"], people["partner_kind"], strict=True)) == PARTNERS
    partners = table[table["person"] == "A1"]
    assert dict(zip(partners["condition"], partners["player_kind"], strict=True)) == PARTNERS
    assert people["guess_kind"].isin(["person", "avatar"]).all()
    right = people["guess_kind"] == people["partner_kind"].map(RIGHT)
    assert people["guess_correct"].astype(bool).tolist() == right.tolist()
    assert right.all()  # detect:1 names the true kind every time
    assert people["guess_confidence"].between(1, 7).all()


@pytest.mark.long
def test_the_report_scores_every_answer_against_chance(reported):
    table, found, html = reported
    people = table[table["player_kind"] == "person"]
    correct = int(people["guess_correct"].astype(bool).sum())
    assert (found["answers"], found["correct"], found["left_out"]) == (8, correct, 0)
    assert found["rate"] == pytest.approx(correct / 8)
    assert found["binomial_p"] == pytest.approx(stats.binomtest(correct, 8, 0.5).pvalue)
    detection = found["detection"]
    assert detection["hits"] + detection["misses"] == 4  # the recordings: persons
    assert detection["false_alarms"] + detection["correct_rejections"] == 4
    said_person = people["guess_kind"] == "person"
    recorded = people["partner_kind"] == "recording"
    assert detection["hits"] == int((said_person & recorded).sum())
    kinds = {row["condition"]: row["partners"] for row in found["per_condition"]}
    assert kinds == PARTNERS
    assert "Identification: person or avatar?" in html
    assert f"{correct} of 8 answers right" in html

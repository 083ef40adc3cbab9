"""A study's results in words, and its figures: what each line says in each case."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from matplotlib.lines import Line2D
from study_tables import CONDITIONS, dictionary, make_study_rows, scripted_answers
from study_tables import write_study_table as write_table

from mirror_avatar.analysis.identification import identify
from mirror_avatar.analysis.random_effects import INTERCEPT, SLOPES
from mirror_avatar.analysis.statistics import Contrast, condition_summaries, participant_means
from mirror_avatar.analysis.study_figures import plot_identification, plot_participants
from mirror_avatar.analysis.study_file import read_study_table
from mirror_avatar.analysis.study_report import analyse_study, write_study_report
from mirror_avatar.analysis.study_text import (
    comparison_sentence,
    format_p,
    methods_paragraph,
    verdict,
)

CONTRAST = Contrast(
    measure="rms", condition="delay 0.5 s", reference="no delay", difference=0.07,
    ci_low=0.03, ci_high=0.11, p=0.003, p_holm=0.003, standardised=1.1, participants=12,
    reference_mean=0.12, condition_mean=0.19, d_z=1.4, t=4.0, t_p=0.002, wilcoxon_p=0.004,
    q=0.006,
)  # fmt: skip


def test_a_change_and_no_change_in_words() -> None:
    """Exploratory lines name the measure by its label and judge it by its q-value."""
    assert comparison_sentence(CONTRAST, "RMS", "units") == (
        "Delay 0.5 s raised RMS from 0.12 (no delay) to 0.19 units "
        "(exploratory: q = 0.006, p = 0.003, d_z = 1.4, n = 12)."
    )
    lowered = replace(CONTRAST, difference=-0.07, reference_mean=0.19, condition_mean=0.12)
    assert comparison_sentence(lowered, "RMS", "1").startswith(
        "Delay 0.5 s lowered RMS from 0.19 (no delay) to 0.12 (exploratory: q = 0.006"
    )
    unchanged = replace(CONTRAST, p=0.02, q=0.4)
    assert comparison_sentence(unchanged, "RMS", "units") == (
        "Delay 0.5 s did not change RMS detectably from no delay: 0.12 and 0.19 units "
        "(exploratory: q = 0.400, p = 0.020, d_z = 1.4, n = 12)."
    )


def test_p_values_in_words() -> None:
    assert [format_p(p) for p in (0.0004, 0.0031, 0.5, float("nan"))] == [
        "p < 0.001", "p = 0.003", "p = 0.500", "p = n/a",
    ]  # fmt: skip


def test_verdict_says_above_below_or_at_chance() -> None:
    """Over the persons' rates (scripted_answers: answer i is person i mod 3's), by hand: below,
    rates 2/14, 1/13, 1/13, t = -18.4 on 2 df; six of ten, rates 2/4, 2/3, 2/3, t = 2.0."""
    truth = ["person"] * 20 + ["avatar"] * 20
    wrong = ["avatar"] * 18 + ["person"] * 2 + ["person"] * 18 + ["avatar"] * 2
    below = identify(scripted_answers(truth, wrong, [np.nan] * 40))
    assert below is not None
    assert verdict([CONTRAST], below, labels={"rms": "RMS"}) == (
        "No hypothesis declared: every comparison is exploratory. Exploratory: 1 of 1 "
        "comparisons changed a measure (q < 0.05, Benjamini-Hochberg): delay 0.5 s on RMS. "
        "Partners identified below chance: 10% right (t-test over 3 persons, p = 0.003)."
    )
    guesses = ["person"] * 6 + ["avatar"] * 4
    six_of_ten = identify(scripted_answers(["person"] * 10, guesses, [0.5] * 10))
    assert six_of_ten is not None
    assert verdict([], six_of_ten) == (
        "No hypothesis declared: every comparison is exploratory. No conditions to compare. "
        "Partners identified at chance: 61% right (t-test over 3 persons, p = 0.184)."
    )
    one_person = identify(scripted_answers(["person"] * 10, guesses, [0.5] * 10).assign(
        participant="p000"
    ))  # fmt: skip
    assert one_person is not None
    assert verdict([], one_person).endswith(
        "Partners identified at chance: 60% right (exact binomial over 10 answers, p = 0.754)."
    )


def test_contrasts_of_a_fit_that_did_not_converge_are_left_out_of_the_verdict_and_named() -> None:
    other = replace(CONTRAST, measure="phase_locking", q=0.5)
    assert verdict([CONTRAST, other], None, labels={"rms": "RMS"}, unconverged=["rms"]) == (
        "No hypothesis declared: every comparison is exploratory. Exploratory: none of 1 "
        "comparisons changed a measure (q < 0.05 in none). Not counted, their fit did not "
        "converge: RMS."
    )


def test_identification_without_avatars_says_why_there_is_no_d_prime(tmp_path: Path) -> None:
    rows = scripted_answers(["person"] * 10, ["person"] * 7 + ["avatar"] * 3, [np.nan] * 10)
    table = read_study_table(write_table(rows, tmp_path))
    analysis = analyse_study(table, resamples=999)
    page = write_study_report(analysis, tmp_path / "out").read_text()
    assert "d&#39; and c need answers about both kinds of partner" in page


@pytest.mark.long
def test_measures_without_numbers_or_values_are_said_not_averaged(tmp_path: Path) -> None:
    rows = make_study_rows(0).assign(
        cv=np.nan, leader=lambda r: np.where(r["trial"] > 2, "0", "none")
    )
    described = dictionary(rows) | {"cv": {"Role": "measure"}, "leader": {"Role": "measure"}}
    write_table(rows, tmp_path)
    (tmp_path / "study.json").write_text(json.dumps(described))
    table = read_study_table(tmp_path)
    assert table.measures == ["rms", "phase_locking", "cv"]
    assert table.skipped_measures == ["leader"]
    analysis = analyse_study(table, resamples=999)
    assert "not numbers, so not averaged: leader" in analysis.notes
    assert [m.measure for m in analysis.models] == ["rms", "phase_locking"]
    cv = analysis.summaries[analysis.summaries["measure"] == "cv"]
    assert list(cv["participants"]) == [0, 0] and cv["mean"].isna().all()
    write_study_report(analysis, tmp_path / "out")


def test_participant_figure_joins_each_participants_conditions() -> None:
    rows = make_study_rows(0, effects={"rms": 0.05})
    rows = rows[rows["player_kind"] == "person"]
    means = participant_means(rows, "rms", CONDITIONS)
    summary = condition_summaries(rows, ["rms"], CONDITIONS, seed=0, resamples=999)
    figure = plot_participants(means, summary, "rms (units)")
    lines = [line for line in figure.axes[0].get_lines() if len(line.get_xdata()) == 2]
    joined = [line for line in lines if line.get_color() == "0.6"]
    assert len(joined) == 12
    for line, (_, values) in zip(joined, means.iterrows(), strict=True):
        assert np.allclose(line.get_ydata(), values.to_numpy())
    assert figure.axes[0].get_ylabel() == "rms (units)"


def test_identification_figure_has_a_line_per_person() -> None:
    truth = ["person", "avatar"] * 24
    guesses = ["person", "avatar"] * 18 + ["avatar", "person"] * 6
    found = identify(scripted_answers(truth, guesses, list(np.linspace(0, 1, 48))))
    assert found is not None
    figure = plot_identification(scripted_answers(truth, guesses, [0.5] * 48), found)
    rates, confidence = figure.axes
    participant_lines = [
        line for line in rates.get_lines() if isinstance(line, Line2D) and line.get_color() == "0.6"
    ]
    assert len(participant_lines) == found.persons == 3
    assert confidence.get_ylabel() == "confidence"
    hit, alarm = found.per_person.iloc[0][["hit_rate", "false_alarm_rate"]]
    assert participant_lines[0].get_ydata() == pytest.approx([hit, alarm])
    assert isinstance(found.per_person, pd.DataFrame)


def test_an_untested_comparison_says_so() -> None:
    nan = float("nan")
    untested = replace(CONTRAST, difference=nan, p=nan, p_holm=nan, d_z=nan, q=nan)
    assert comparison_sentence(untested, "rms", "units") == (
        "Delay 0.5 s against no delay: rms 0.12 and 0.19 units, not tested (see the notes below)."
    )


@pytest.mark.parametrize(
    ("incomplete", "said"),
    [(None, "12 trials (the persons' rows of the study table; avatars' rows left out; the table "
            "does not say which trials ran to their end, so all were kept)"),
     (0, "12 complete trials (the persons' rows of the study table; avatars' rows left out; "
         "every trial ran to its end)"),
     (3, "12 complete trials (the persons' rows of the study table; avatars' rows and 3 rows of "
         "incomplete trials, stopped before their end, left out)")],
)  # fmt: skip
def test_the_methods_count_complete_trials_and_say_what_was_left_out(
    incomplete: int | None, said: str
) -> None:
    versions = dict.fromkeys(("mirror-avatar", "python", "numpy", "pandas", "scipy",
                              "statsmodels"), "1")  # fmt: skip
    parameters = {"versions": versions, "participants": 3, "rows": 12,
                  "incomplete_rows": incomplete, "confidence": 0.95, "bootstrap_resamples": 99,
                  "seed": 0, "reference": "a"}  # fmt: skip
    assert f"from 3 participants' {said}. Each" in methods_paragraph(parameters)


def test_the_methods_say_each_measures_random_effects_by_its_label() -> None:
    versions = dict.fromkeys(("mirror-avatar", "python", "numpy", "pandas", "scipy",
                              "statsmodels"), "1")  # fmt: skip
    fitted = {"RMSE": SLOPES, "CV (phase locking, 0-1)": SLOPES, "Lag": INTERCEPT}
    parameters = {"versions": versions, "participants": 3, "rows": 12, "incomplete_rows": 0,
                  "confidence": 0.95, "bootstrap_resamples": 99, "seed": 0, "reference": "a",
                  "random_effects": fitted}  # fmt: skip
    said = methods_paragraph(parameters)
    assert (f"(fitted: {SLOPES} for RMSE and CV (phase locking, 0-1); {INTERCEPT} for Lag)"
            in said)  # fmt: skip
    assert "Satterthwaite's degrees of freedom" in said

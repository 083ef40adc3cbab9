"""``study report``: a study table read back, analysed, and written as HTML, JSON and CSV.

Synthetic tables with known truth, written as ``study table`` writes them (study.csv and its
data dictionary study.json); the command run through click's runner on the command object.
"""

from __future__ import annotations

import csv
import json
import re
import subprocess
import sys
from dataclasses import replace
from html import escape as html_escape
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner
from study_tables import CONDITIONS, make_study_rows, with_answers, write_study_table
from test_analysis_hypothesis import protocol_text

from mirror_avatar.analysis.hypothesis import ANGLE_TEST
from mirror_avatar.analysis.statistics import participant_means
from mirror_avatar.analysis.study_file import read_study_table
from mirror_avatar.analysis.study_report import (
    STUDY_REPORT_FILES,
    analyse_study,
    write_study_report,
)
from mirror_avatar.analysis.study_text import methods_paragraph
from mirror_avatar.analysis.table import table_dictionary
from mirror_avatar.analysis.table import write_study_table as write_table_files
from mirror_avatar.cli.study_report import report
from mirror_avatar.common.errors import InputError
from mirror_avatar.lab.design.protocol import Analysis, protocol_from_text

NO_DELAY, DELAY = CONDITIONS
EFFECTS = {"rms": 0.05, "phase_locking": -0.1}


@pytest.fixture
def table_dir(tmp_path: Path) -> Path:
    rows = with_answers(make_study_rows(0, effects=EFFECTS), seed=1)
    return write_study_table(rows, tmp_path / "table")


def test_read_a_folder_or_its_csv_with_the_dictionary(table_dir: Path) -> None:
    for path in (table_dir, table_dir / "study.csv"):
        table = read_study_table(path)
        assert table.source == table_dir / "study.csv"
        assert table.measures == ["rms", "phase_locking"]
        assert table.units("rms") == "units"
        assert table.conditions() == list(CONDITIONS)


def test_read_keeps_identifiers_as_text_and_reads_parquet(tmp_path: Path) -> None:
    rows = make_study_rows(0).assign(participant=lambda r: r["participant"].str[1:])  # "000"
    folder = write_study_table(rows, tmp_path / "csv")
    assert read_study_table(folder).rows["participant"].iloc[0] == "000"
    (tmp_path / "pq").mkdir()
    rows.to_parquet(tmp_path / "pq" / "study.parquet")
    parquet = read_study_table(tmp_path / "pq")
    assert parquet.source.name == "study.parquet"
    assert parquet.measures == ["rms", "phase_locking"]


def test_without_a_dictionary_measures_are_the_numeric_non_design_columns(tmp_path: Path) -> None:
    rows = with_answers(make_study_rows(0), seed=1)
    table = read_study_table(write_study_table(rows, tmp_path, with_dictionary=False))
    assert table.measures == ["rms", "phase_locking"]
    assert table.units("rms") == ""


def test_without_a_dictionary_a_numeric_session_id_is_no_measure(tmp_path: Path) -> None:
    """Every identifier and design column of the study table's dictionary is never a measure."""
    rows = make_study_rows(0).assign(session=7)
    table = read_study_table(write_study_table(rows, tmp_path, with_dictionary=False))
    assert table.measures == ["rms", "phase_locking"]


def bad_table(folder: Path, case: str) -> Path:
    """Write the bad table ``case`` in ``folder`` and return the path to give the reader."""
    if case == "empty folder":
        return folder
    if case == "missing":
        return folder / "missing.csv"
    if case == "not a table":
        (folder / "t.txt").write_text("x")
        return folder / "t.txt"
    drop = {"no position": ["position"], "no measure": ["rms", "phase_locking"]}.get(case, [])
    rows = make_study_rows(0).drop(columns=drop)
    if case == "no condition":
        rows["condition"] = np.nan
    write_study_table(rows, folder)
    if case == "bad dictionary":
        (folder / "study.json").write_text("{not json")
    if case == "deep dictionary":
        (folder / "study.json").write_text('{"a": ' * 5000 + "1" + "}" * 5000)
    return folder / "study.csv"


@pytest.mark.parametrize(
    ("case", "problem"),
    [
        ("empty folder", "no study.csv or study.parquet in it"),
        ("missing", "no such file or folder"),
        ("not a table", "is not a .csv or .parquet"),
        ("no position", "no position column"),
        ("no measure", "no measure column"),
        ("no condition", "no row has a condition"),
        ("bad dictionary", "study.json: is not valid JSON"),
        ("deep dictionary", "study.json: is JSON nested deeper than the limit of 32 levels"),
    ],
)
def test_bad_tables_are_refused_in_one_line(tmp_path: Path, case: str, problem: str) -> None:
    with pytest.raises(InputError, match=re.escape(problem)) as error:
        read_study_table(bad_table(tmp_path, case))
    assert "\n" not in str(error.value)


def test_analysis_leaves_out_the_avatars_rows_and_finds_the_effects(table_dir: Path) -> None:
    analysis = analyse_study(read_study_table(table_dir), seed=3, resamples=999)
    assert set(analysis.rows["player_kind"]) == {"person"}
    assert any("avatars left out" in note for note in analysis.notes)
    assert analysis.reference == NO_DELAY
    means = participant_means(analysis.rows, "rms", CONDITIONS)
    summary = analysis.summaries.set_index(["measure", "condition"])
    assert summary.loc[("rms", DELAY), "mean"] == pytest.approx(means[DELAY].mean())
    assert summary["mean"].max() < 1.0  # no avatar value (100) in any mean
    rms, locking = analysis.sentences()
    assert rms.startswith(f"Delay 0.5 s raised rms from {means[NO_DELAY].mean():.3g} (no delay)")
    assert locking.startswith("Delay 0.5 s lowered CV (phase locking, 0-1) from")
    assert "Exploratory: 2 of 2 comparisons changed a measure" in analysis.verdict()
    assert "Partners identified above chance" in analysis.verdict()


def test_identical_conditions_are_said_not_to_differ(tmp_path: Path) -> None:
    rows = make_study_rows(3)  # no effect; p >= 0.05 for both measures with this seed
    analysis = analyse_study(read_study_table(write_study_table(rows, tmp_path)), resamples=999)
    assert all(c.p >= 0.05 for c in analysis.contrasts)
    assert all("did not change" in line for line in analysis.sentences())
    assert analysis.verdict() == (
        "No hypothesis declared: every comparison is exploratory. "
        "Exploratory: none of 2 comparisons changed a measure (q < 0.05 in none)."
    )
    assert analysis.identification is None


def test_few_participants_are_warned_of_and_the_df_are_shown(tmp_path: Path) -> None:
    """Five participants: the notes warn; twelve: they do not. The df reach the contrasts.csv."""
    few = make_study_rows(0, participants=5, effects=EFFECTS)
    analysis = analyse_study(read_study_table(write_study_table(few, tmp_path / "few")),
                             resamples=999)  # fmt: skip
    (warning,) = [note for note in analysis.notes if note.startswith("only 5 participants")]
    assert "fewer than 6" in warning
    html = write_study_report(analysis, tmp_path / "out")
    contrasts = pd.read_csv(html.parent / "contrasts.csv")
    assert list(contrasts["df"]) == pytest.approx([c.df for c in analysis.contrasts])
    assert "Satterthwaite" in html.read_text()
    assert analysis.parameters["random_effects"] == {
        analysis.table.label(m.measure): m.random_effects for m in analysis.models
    }
    many = analyse_study(read_study_table(write_study_table(make_study_rows(0), tmp_path / "all")),
                         resamples=999)  # fmt: skip
    assert not any("participants (fewer than" in note for note in many.notes)


def test_another_reference_and_an_unknown_one(table_dir: Path) -> None:
    table = read_study_table(table_dir)
    analysis = analyse_study(table, reference=DELAY, resamples=999)
    (contrast, _) = analysis.contrasts
    assert (contrast.condition, contrast.reference) == (NO_DELAY, DELAY)
    assert contrast.difference < 0
    with pytest.raises(InputError, match=r"--reference: no condition 'fast'"):
        analyse_study(table, reference="fast")


def test_one_condition_has_means_and_no_comparison(tmp_path: Path) -> None:
    rows = make_study_rows(0)
    rows = rows.assign(condition=rows["condition"].where(rows["condition"] == NO_DELAY))
    analysis = analyse_study(read_study_table(write_study_table(rows, tmp_path)), resamples=999)
    assert analysis.models == [] and len(analysis.summaries) == 2
    assert analysis.verdict().endswith("No conditions to compare.")
    write_study_report(analysis, tmp_path / "out")


def test_report_leads_with_its_verdict_and_results_hold_every_number(
    table_dir: Path, tmp_path: Path
) -> None:
    analysis = analyse_study(read_study_table(table_dir), seed=11, resamples=999)
    html = write_study_report(analysis, tmp_path / "out")
    assert sorted(p.name for p in html.parent.iterdir()) == sorted(STUDY_REPORT_FILES)
    page = html.read_text()
    lead = page.index('<p class="lead">')
    assert page.index("</h1>") < lead < page.index("<section")
    assert html_escape(analysis.verdict()) in page[lead : lead + 400]
    assert page.count("<img ") == 3  # rms, phase locking, identification
    assert "random seed 11" in page and "999 resamples" in page
    results = json.loads((html.parent / "results.json").read_text())
    assert results["parameters"]["seed"] == 11
    assert results["parameters"]["versions"]["statsmodels"]
    (model, _) = results["models"]
    assert model["contrasts"][0]["p"] == pytest.approx(analysis.contrasts[0].p)
    found = analysis.identification
    assert found is not None
    assert results["identification"]["detection"]["d_prime"] == pytest.approx(
        found.detection.d_prime
    )
    assert len(results["identification"]["per_person"]) == 12
    contrasts = pd.read_csv(html.parent / "contrasts.csv")
    assert list(contrasts["measure"]) == ["rms", "phase_locking"]
    # The partners alternate between persons and avatars: kind and condition x kind are tested.
    assert model["fixed_effects"] == (
        "measure ~ condition + position + partner kind + condition x partner kind"
    )
    assert [f["term"] for f in model["factors"]] == ["partner kind", "condition x partner kind"]
    assert "Partner kind: rms was" in page and "Condition x partner kind: delay 0.5 s" in page
    stuck = replace(analysis, models=[replace(analysis.models[0], converged=False),
                                      analysis.models[1]])  # fmt: skip
    assert "of 1 comparisons" in stuck.verdict()
    assert "Not counted, their fit did not converge: rms." in stuck.verdict()
    methods = results["methods"]
    assert (
        "(fitted: measure ~ condition + position + partner kind + condition x partner kind "
        "for rms and CV (phase locking, 0-1))" in methods
    )
    conditions = pd.read_csv(html.parent / "conditions.csv")
    assert np.all(conditions["ci_low"] < conditions["ci_high"])


def test_the_command_writes_the_report(table_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "report"
    result = CliRunner().invoke(
        report, [str(table_dir), "--out", str(out), "--seed", "5", "--resamples", "500"]
    )
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert lines[0].startswith("No hypothesis declared: every comparison is exploratory.")
    assert lines[1].strip().startswith("Delay 0.5 s raised rms")
    assert lines[-1] == f"wrote {(out / 'report.html').resolve()}"
    results = json.loads((out / "results.json").read_text())
    assert results["parameters"]["seed"] == 5
    assert results["parameters"]["bootstrap_resamples"] == 500


def test_the_command_refuses_bad_input_before_any_work(table_dir: Path, tmp_path: Path) -> None:
    runner = CliRunner()
    missing = runner.invoke(report, [str(tmp_path / "nothing"), "--out", str(tmp_path / "o")])
    assert isinstance(missing.exception, InputError)
    assert "no such file or folder" in str(missing.exception)
    blocked = tmp_path / "blocked"
    (blocked / "results.json").mkdir(parents=True)
    refused = runner.invoke(report, [str(table_dir), "--out", str(blocked)])
    assert isinstance(refused.exception, InputError)
    assert "results.json" in str(refused.exception)
    reference = runner.invoke(report, [str(table_dir), "--out", str(tmp_path / "o"),
                                       "--reference", "nope"])  # fmt: skip
    assert isinstance(reference.exception, InputError)
    assert not (tmp_path / "o").exists()


def test_two_persons_of_a_participant_count_once_and_answer_each(tmp_path: Path) -> None:
    """A two-person protocol: P1 and P2 of one participant share the pair's measures; the
    participant is the unit of the statistics, and each person's answers are scored apart."""
    one = make_study_rows(2, effects=EFFECTS)
    one = with_answers(one[one["player_kind"] == "person"], seed=4)
    two = pd.concat([one, one.assign(person="P2", partners="P1")], ignore_index=True)
    two = with_answers(two, seed=4)
    alone = analyse_study(read_study_table(write_study_table(one, tmp_path / "one")))
    pair = analyse_study(read_study_table(write_study_table(two, tmp_path / "two")))
    assert pair.parameters["participants"] == 12
    pd.testing.assert_frame_equal(pair.summaries, alone.summaries)
    assert [c.p for c in pair.contrasts] == pytest.approx(
        [c.p for c in alone.contrasts], rel=1e-6, abs=0
    )
    assert pair.identification is not None
    assert pair.identification.persons == 24
    assert "p000/P2" in pair.identification.per_person.index


@pytest.mark.long
@pytest.mark.parametrize("with_dictionary", [True, False])
def test_ratings_are_compared_like_measures(tmp_path: Path, with_dictionary: bool) -> None:
    """A numeric answer (a 1-7 rating, one point lower with the delay) is an outcome; the
    person-or-avatar answer (text) is not."""
    rows = with_answers(make_study_rows(0), seed=1)
    rng = np.random.default_rng(2)
    delayed = (rows["condition"] == DELAY).to_numpy()
    rating = np.clip(np.round(5.0 - delayed + rng.normal(0, 0.7, len(rows))), 1, 7)
    rows = rows.assign(answer_enjoy=np.where(rows["player_kind"] == "person", rating, np.nan))
    table = read_study_table(write_study_table(rows, tmp_path, with_dictionary=with_dictionary))
    assert table.rated_answers == ["answer_enjoy"]
    assert table.outcomes == ["rms", "phase_locking", "answer_enjoy"]
    analysis = analyse_study(table, resamples=999)
    (enjoy,) = [c for c in analysis.contrasts if c.measure == "answer_enjoy"]
    assert enjoy.p < 0.05 and enjoy.difference == pytest.approx(-1.0, abs=0.3)
    assert analysis.sentences()[-1].startswith("Delay 0.5 s lowered answer_enjoy from")


FORMULAS = ("=cmd|' /C calc'!A0", "+1+1", "-2+3", "@SUM(A1)", "\tx", "\rx", "'quoted", "a\rb")


def test_text_cells_never_open_as_formulas_and_read_back_as_given(tmp_path: Path) -> None:
    """OWASP's rule on every CSV the study writes: a text cell that a spreadsheet would run (or
    one starting with the quote itself) gets a quote before it; numbers, negative ones too, are
    written as they are; a carriage return stays inside its cell; the Parquet and the report
    read back the text as given."""
    rows = make_study_rows(0, conditions=(FORMULAS[0], "plain")).rename(columns={"rms": "rmse"})
    rows["rmse"] = -rows["rmse"]
    rows["answer_why"] = [FORMULAS[i % len(FORMULAS)] for i in range(len(rows))]
    out = tmp_path / "table"
    write_table_files(rows, table_dictionary(rows, {"why": "Why?"}), out)
    with (out / "study.csv").open(newline="", encoding="utf-8") as file:
        header, *cells = list(csv.reader(file))
    texts = [cell for row in cells for name, cell in zip(header, row, strict=True)
             if name in ("condition", "answer_why")]  # fmt: skip
    assert not [cell for cell in texts if cell.startswith(("=", "+", "-", "@", "\t", "\r"))]
    assert "'" + FORMULAS[0] in texts and "''quoted" in texts
    negative = [float(row[header.index("rmse")]) for row in cells]
    assert negative == pytest.approx(rows["rmse"].tolist(), rel=1e-12)
    pd.testing.assert_series_equal(pd.read_parquet(out / "study.parquet")["answer_why"],
                                   rows["answer_why"], check_dtype=False)  # fmt: skip
    table = read_study_table(out)
    assert table.conditions() == [FORMULAS[0], "plain"]
    assert table.rows["answer_why"].tolist() == rows["answer_why"].tolist()
    assert "a spreadsheet shows it as text" in json.loads((out / "study.json").read_text())[
        "answer_why"]["Description"]  # fmt: skip
    html = write_study_report(analyse_study(table, resamples=200), tmp_path / "report")
    for name in ("conditions.csv", "contrasts.csv"):
        text = (html.parent / name).read_text(encoding="utf-8")
        assert "'" + FORMULAS[0] in text and "\n" + FORMULAS[0] not in text
        assert "," + FORMULAS[0] not in text


LIMITED = """
import json, resource, sys
from pathlib import Path
import pandas as pd
limit = int(sys.argv[1])
if sys.argv[2] == "table":
    from mirror_avatar.analysis.table import table_dictionary, write_study_table
    rows = pd.read_parquet(sys.argv[3])
    dictionary = table_dictionary(rows, {"why": "Why? " * 20_000})
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    write_study_table(rows, dictionary, Path(sys.argv[4]))
else:
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    from mirror_avatar.console import run
    sys.argv[1:3] = []
    run()
"""
"""Child: the study table's writer or the command line under a file-size limit of ``argv[1]``
bytes (a write beyond it fails with EFBIG: Python ignores SIGXFSZ)."""


def limited(limit: int, *arguments: str | Path) -> subprocess.CompletedProcess[str]:
    """Run `LIMITED` with ``arguments`` in a fresh interpreter."""
    command = [sys.executable, "-c", LIMITED, str(limit), *map(str, arguments)]
    return subprocess.run(command, capture_output=True, text=True, check=False, timeout=300)


def contents(folder: Path) -> dict[str, bytes]:
    return {path.name: path.read_bytes() for path in sorted(folder.iterdir())}


@pytest.mark.long
def test_a_table_without_room_for_its_dictionary_writes_no_file(tmp_path: Path) -> None:
    """Under a file-size limit that study.csv and study.parquet fit in and the dictionary does
    not, no file is written, and a table written before stays whole."""
    rows = make_study_rows(0).rename(columns={"rms": "rmse"}).assign(answer_why="because")
    rows.to_parquet(tmp_path / "rows.parquet")
    fresh, kept = tmp_path / "fresh", tmp_path / "kept"
    write_table_files(rows.iloc[:4], table_dictionary(rows.iloc[:4], {}), kept)
    before = contents(kept)
    for out in (fresh, kept):
        done = limited(60_000, "table", tmp_path / "rows.parquet", out)
        assert done.returncode == 1, done.stderr
        assert f"File too large: '{out / 'study.json'}'" in done.stderr
    assert contents(fresh) == {}
    assert contents(kept) == before


@pytest.mark.long
def test_a_report_without_room_for_its_page_writes_no_file(table_dir: Path, tmp_path: Path) -> None:
    """Under a file-size limit that results.json and the CSVs fit in and report.html does not,
    the command fails in one line naming the page, and a report written before stays whole."""
    out = tmp_path / "report"
    assert CliRunner().invoke(report, [str(table_dir), "--out", str(out), "--resamples", "200"],
                              catch_exceptions=False).exit_code == 0  # fmt: skip
    before = contents(out)
    for folder in (tmp_path / "fresh", out):
        command = ["study", "report", table_dir, "--out", folder, "--seed", "3"]
        done = limited(100_000, "report", *command, "--resamples", "200")
        assert done.returncode == 2, done.stderr
        assert done.stderr.splitlines() == [
            f"mirror-avatar: error: {folder / 'report.html'}: File too large"
        ]
    assert contents(tmp_path / "fresh") == {}
    assert contents(out) == before


@pytest.mark.long
def test_values_that_are_not_finite_are_left_out_and_counted(tmp_path: Path) -> None:
    """An infinite value (a measure divided by a zero spread) would make its condition's mean
    infinite beside a finite interval, with numpy's warnings on stderr (errors here): it is left
    out of every statistic, and a note says how many and why."""
    rows = make_study_rows(0, effects=EFFECTS)
    persons = rows.index[rows["player_kind"] == "person"]
    rows.loc[persons[:3], "rms"] = [np.inf, -np.inf, np.inf]
    finite = make_study_rows(0, effects=EFFECTS)
    finite.loc[persons[:3], "rms"] = np.nan
    analysis = analyse_study(
        read_study_table(write_study_table(rows, tmp_path / "inf")), resamples=200
    )
    expected = analyse_study(
        read_study_table(write_study_table(finite, tmp_path / "nan")), resamples=200
    )
    pd.testing.assert_frame_equal(analysis.summaries, expected.summaries)
    assert np.isfinite(analysis.summaries[["mean", "ci_low", "ci_high", "sd"]].to_numpy()).all()
    assert "rms: 3 of 96 values left out, not finite (infinite)" in analysis.notes


def test_an_angle_measure_is_averaged_and_compared_on_the_circle(tmp_path: Path) -> None:
    """Mean relative phase near pi, 0.5 rad later with the delay (wrapping past pi): the report
    gives circular means near pi and a difference near 0.5, where arithmetic gives neither."""
    rows = make_study_rows(6).drop(columns=["rms", "phase_locking"])
    rng = np.random.default_rng(6)
    own = {p: np.pi + rng.normal(0, 0.3) for p in rows["participant"].unique()}
    phase = [own[p] + 0.5 * (c == DELAY) + rng.vonmises(0.0, 8.0)
             for p, c in zip(rows["participant"], rows["condition"], strict=True)]  # fmt: skip
    rows["mean_relative_phase"] = np.angle(np.exp(1j * np.array(phase)))
    analysis = analyse_study(read_study_table(write_study_table(rows, tmp_path / "t", False)))
    summaries = analysis.summaries.set_index("condition")
    assert abs(summaries.loc[NO_DELAY, "mean"]) > 2.8
    assert summaries.loc[NO_DELAY, "resultant_length"] > 0.8
    assert summaries.loc[NO_DELAY, "rayleigh_p"] < 0.001
    (contrast,) = analysis.contrasts
    assert contrast.difference == pytest.approx(0.5, abs=0.15) and contrast.p < 0.01
    (model,) = analysis.models
    assert model.fixed_effects.startswith("circular: sign-flip randomisation test")
    methods = methods_paragraph(analysis.parameters)
    assert "circular: sign-flip randomisation test" in methods
    assert "Mean relative phase (player 0 - player 1), angles, were averaged as unit vectors" in (
        methods
    )
    html = write_study_report(analysis, tmp_path / "out")
    conditions = pd.read_csv(html.parent / "conditions.csv")
    assert conditions["resultant_length"].notna().all()
    declared = Analysis(("mean_relative_phase",), "higher", DELAY, NO_DELAY, 0.1, 0.05)
    protocol = replace(protocol_from_text(protocol_text(""), "delay.toml"), analysis=declared)
    confirmed = analyse_study(read_study_table(tmp_path / "t"), protocol=protocol)
    # the confirmatory test on the circle too: the phases sit at +-pi, where a linear mean fails
    (test,) = confirmed.confirmatory
    assert test.test == ANGLE_TEST and test.estimate == pytest.approx(0.5, abs=0.15)
    assert abs(test.reference_mean) > 2.8 and test.p < 0.01 and test.supported
    assert np.isnan(test.t) and np.isnan(test.ci_low)
    (sentence,) = confirmed.hypothesis_sentences()
    assert "(one-sided sign-flip test of the participants' differences of circular means p" in (
        sentence
    )
    assert "CI" not in sentence
    assert ANGLE_TEST in confirmed.parameters["confirmatory_model"]

"""A protocol's declared hypothesis: the confirmatory test first, every other comparison with q.

Benjamini-Hochberg checked against statsmodels; the confirmatory test's power and false
positive rate on synthetic studies with known truth (`study_tables`); the report and the
command led by the hypothesis, with the protocol's conditions in its order.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from statsmodels.stats.multitest import multipletests
from study_tables import CONDITIONS, make_study_rows, write_study_table

from mirror_avatar.analysis.hypothesis import confirm
from mirror_avatar.analysis.multiple_tests import benjamini_hochberg, holm
from mirror_avatar.analysis.study_file import read_study_table
from mirror_avatar.analysis.study_report import analyse_study, write_study_report
from mirror_avatar.analysis.study_text import confirmatory_sentence
from mirror_avatar.cli.study_report import report
from mirror_avatar.common.errors import InputError
from mirror_avatar.lab.design.protocol import Analysis, Protocol, protocol_from_text

NO_DELAY, DELAY = CONDITIONS
CONDITION = """
[[blocks.conditions]]
name = "{name}"
game = "leader_follower"
players = [
  {{ label = "P1", kind = "person" }},
  {{ label = "A1", kind = "avatar", spec = "bundled:slow" }},
]
leaders = ["A1"]
duration = 10
"""
ANALYSIS = """
[analysis]
primary = "phase_locking"
direction = "lower"
contrast = ["delay 0.5 s", "no delay"]
smallest_effect = 0.05
"""


def protocol_text(analysis: str = ANALYSIS) -> str:
    """A protocol of the synthetic study, its conditions in the other order than the table's."""
    conditions = "".join(CONDITION.format(name=name) for name in (DELAY, NO_DELAY))
    return f'seed = 1\n[[blocks]]\norder = "latin"\n{conditions}{analysis}'


@pytest.fixture(scope="module")
def protocol() -> Protocol:
    return protocol_from_text(protocol_text(), "delay.toml")


ADJUSTMENTS = [(benjamini_hochberg, "fdr_bh"), (holm, "holm")]


@pytest.mark.parametrize(("adjust", "method"), ADJUSTMENTS)
@pytest.mark.parametrize("size", [1, 2, 7, 50, 400])
def test_adjusted_p_values_equal_statsmodels(adjust, method: str, size: int) -> None:
    rng = np.random.default_rng(size)
    p = np.concatenate([rng.uniform(0, 1, size), rng.uniform(0, 0.01, size // 3)])
    p[: size // 4] = p[0]  # ties
    expected = multipletests(p, method=method)[1]
    np.testing.assert_allclose(adjust(p), expected, rtol=1e-12, atol=0)


@pytest.mark.parametrize(("adjust", "method"), ADJUSTMENTS)
def test_adjusted_p_values_leave_untested_out(adjust, method: str) -> None:
    p = np.array([0.01, np.nan, 0.04, 0.03, np.nan])
    expected = multipletests([0.01, 0.04, 0.03], method=method)[1]
    found = adjust(p)
    np.testing.assert_allclose(found[[0, 2, 3]], expected)
    assert np.isnan(found[[1, 4]]).all()
    assert np.isnan(adjust([np.nan])).all()


def declared(direction: str = "lower", smallest: float = 0.0) -> Analysis:
    return Analysis(("phase_locking",), direction, DELAY, NO_DELAY, smallest, 0.05)


def persons(seed: int, effect: float, participants: int = 12):
    rows = make_study_rows(seed, participants=participants, effects={"phase_locking": effect})
    return rows[rows["player_kind"] == "person"]


def test_a_true_effect_is_found_in_at_least_18_of_20_seeds() -> None:
    """Phase locking 0.03 lower with the delay (d_z about 1.4 with 12 participants)."""
    found = [confirm(persons(seed, -0.03), declared())[0].supported for seed in range(20)]
    assert sum(found) >= 18


@pytest.mark.long
def test_with_no_effect_the_false_positive_rate_is_at_most_a_tenth() -> None:
    tests = [confirm(persons(seed, 0.0), declared())[0] for seed in range(100)]
    assert sum(t.significant for t in tests) <= 10
    assert sum(t.significant for t in tests) >= 1  # a test that never rejects is no test


def test_one_sided_as_declared_and_its_interval_agrees() -> None:
    rows = persons(0, -0.03)
    lower, higher, either = (
        confirm(rows, declared(d))[0] for d in ("lower", "higher", "two-sided")
    )
    assert lower.estimate < 0 and lower.p < 0.05 and higher.p > 0.95
    assert lower.p == pytest.approx(either.p / 2)
    assert (lower.confidence, either.confidence) == (0.9, 0.95)
    assert lower.ci_high < 0  # the bound on the hypothesis's side excludes 0
    assert lower.ci_low < lower.estimate < lower.ci_high
    assert not higher.supported and lower.supported and either.supported


def test_an_effect_under_the_smallest_of_interest_is_not_supported() -> None:
    small = confirm(persons(0, -0.03), declared(smallest=0.1))[0]
    assert small.significant and not small.exceeds_smallest and not small.supported


def test_several_primary_measures_are_holm_corrected() -> None:
    rows = make_study_rows(1, effects={"phase_locking": -0.03, "rms": 0.02})
    rows = rows[rows["player_kind"] == "person"]
    both = replace(declared("two-sided"), primary=("phase_locking", "rms"))
    tests = confirm(rows, both)
    expected = multipletests([t.p for t in tests], method="holm")[1]
    assert [t.p_holm for t in tests] == pytest.approx(list(expected))


@pytest.mark.long
def test_the_report_leads_with_the_hypothesis(protocol: Protocol, tmp_path: Path) -> None:
    rows = make_study_rows(0, effects={"phase_locking": -0.1, "rms": 0.05})
    table = read_study_table(write_study_table(rows, tmp_path / "table"))
    analysis = analyse_study(table, resamples=999, protocol=protocol)
    assert analysis.reference == NO_DELAY
    assert analysis.conditions == [DELAY, NO_DELAY]  # the protocol's order
    (test,) = analysis.confirmatory or []
    assert test.supported
    assert analysis.verdict().startswith(
        "Hypothesis (delay 0.5 s against no delay): CV (phase locking, 0-1) supported. "
        "Exploratory: 1 of 1 comparisons changed a measure"
    )
    (sentence,) = analysis.hypothesis_sentences()
    assert sentence.startswith(
        "Hypothesis (CV (phase locking, 0-1) lower in delay 0.5 s than in no delay): CV (phase "
        "locking, 0-1) 0.82 (no delay) and "
    )
    assert "one-sided paired t-test p < 0.001, n = 12" in sentence
    assert sentence.endswith("the hypothesis is supported.")
    html = write_study_report(analysis, tmp_path / "out")
    page = html.read_text()
    assert page.index("Confirmatory test") < page.index("Exploratory comparisons")
    results = json.loads((html.parent / "results.json").read_text())
    assert results["confirmatory"][0]["supported"] is True
    assert results["parameters"]["hypothesis"]["primary"] == ["phase_locking"]
    (rms, locking) = [c for model in results["models"] for c in model["contrasts"]]
    assert (rms["exploratory"], locking["exploratory"]) == (True, False)
    assert rms["q"] == pytest.approx(rms["p"])  # the only exploratory comparison
    assert locking["q"] is None  # NaN: not exploratory


def test_without_a_hypothesis_the_reference_is_the_protocols_first(tmp_path: Path) -> None:
    plain = protocol_from_text(protocol_text(analysis=""), "plain.toml")
    table = read_study_table(write_study_table(make_study_rows(0), tmp_path))
    analysis = analyse_study(table, resamples=999, protocol=plain)
    assert analysis.reference == DELAY and analysis.confirmatory is None
    assert analysis.verdict().startswith("No hypothesis declared")
    assert [c.q for c in analysis.contrasts] == pytest.approx(
        list(benjamini_hochberg([c.p for c in analysis.contrasts]))
    )


def test_a_hypothesis_the_table_cannot_test_is_refused(tmp_path: Path) -> None:
    other = protocol_from_text(protocol_text(ANALYSIS.replace("phase_locking", "rmse")), "o.toml")
    table = read_study_table(write_study_table(make_study_rows(0), tmp_path))
    with pytest.raises(InputError, match=r"o\.toml: analysis\.primary: no measure rmse in "):
        analyse_study(table, protocol=other)
    rows = make_study_rows(0, conditions=(NO_DELAY, "fast"))
    table = read_study_table(write_study_table(rows, tmp_path / "fast"))
    with pytest.raises(InputError, match=r"o\.toml: analysis: no condition 'delay 0.5 s' in "):
        analyse_study(table, protocol=other)


def test_the_command_takes_the_protocol(tmp_path: Path) -> None:
    folder = write_study_table(make_study_rows(0, effects={"phase_locking": -0.1}), tmp_path / "t")
    (tmp_path / "delay.toml").write_text(protocol_text())
    out = tmp_path / "report"
    result = CliRunner().invoke(report, [str(folder), "--out", str(out), "--resamples", "200",
                                         "--protocol", str(tmp_path / "delay.toml")])  # fmt: skip
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert lines[0].startswith("Hypothesis (delay 0.5 s against no delay): CV")
    assert lines[1].strip().startswith("Hypothesis (CV (phase locking, 0-1) lower in delay")


def test_each_outcome_in_words() -> None:
    """Supported, significant but under the smallest effect, not significant, not tested."""
    rows = persons(0, -0.03)
    said = {
        name: confirmatory_sentence(confirm(data, analysis)[0], "CV", "")
        for name, data, analysis in (
            ("supported", rows, declared()),
            ("small", rows, declared(smallest=0.1)),
            ("wrong way", rows, declared("higher")),
            ("one participant", persons(0, -0.03, participants=1), declared()),
        )
    }
    assert said["supported"].endswith("at least the smallest effect of interest, 0: the "
                                      "hypothesis is supported.")  # fmt: skip
    assert said["small"].endswith("significant at alpha = 0.05 but under the smallest effect of "
                                  "interest, 0.1: not supported.")  # fmt: skip
    assert said["wrong way"].startswith("Hypothesis (CV higher in delay 0.5 s than in no delay)")
    assert said["wrong way"].endswith("not significant at alpha = 0.05: the hypothesis is not "
                                      "supported.")  # fmt: skip
    assert said["one participant"] == (
        "Hypothesis (CV lower in delay 0.5 s than in no delay): not tested (n = 1 with a mean in "
        "both conditions; two or more whose differences differ are needed)."
    )

"""The identification test's power by simulation: against exact and normal theory, and the command.

With no spread between persons every person is right with one probability p, and a study's
power is computed independently two ways: exactly, by summing the multinomial probability of
every multiset of the persons' counts whose test rejects on the planned side (few answers), and
by the noncentral t of the persons' rates, whose SD is sqrt(p (1 - p) / T) (many answers). With
20000 simulated studies the binomial Monte Carlo standard error is at most 0.0035, so 0.03 is
more than 8 standard errors.
"""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import integrate, special, stats
from study_tables import make_study_rows, with_answers, write_study_table
from test_analysis_hypothesis import ANALYSIS, CONDITION

from mirror_avatar.analysis.identification import CHANCE, chance_tests, identify
from mirror_avatar.analysis.identification_power import (
    RateSpread,
    answers_per_person,
    fit_rates,
    log_likelihood,
    pilot_rates,
    simulate_identification,
)
from mirror_avatar.analysis.study_file import read_study_table
from mirror_avatar.analysis.study_text import ALPHA
from mirror_avatar.cli import main
from mirror_avatar.common.errors import InputError
from mirror_avatar.lab.design.protocol import load_protocol, protocol_from_text

NO_SPREAD = RateSpread(logit_mean=0.0, logit_sd=0.0, persons=10, answers=100, pilot_rate=0.5)
QUESTION = """
[questions.partner]
text = "Was your partner a person or a computer?"
kind = "choice"
options = ["a person", "a computer"]
"""


def exact_power(persons: int, answers: int, rate: float) -> float:
    """Sum the probability of every multiset of the persons' counts the test rejects above 0.5."""
    pmf = stats.binom.pmf(np.arange(answers + 1), answers, rate)
    sets = np.array(list(itertools.combinations_with_replacement(range(answers + 1), persons)))
    found, p = chance_tests(sets, np.full(sets.shape, answers))
    rejected = (p < ALPHA) & (found > CHANCE)
    orders = np.array([math.factorial(persons) / np.prod([math.factorial(m) for m in
                       np.bincount(row, minlength=answers + 1)]) for row in sets])  # fmt: skip
    probability = orders * np.prod(pmf[sets], axis=1)
    assert probability.sum() == pytest.approx(1.0, abs=1e-9)
    return float(probability[rejected].sum())


def test_power_without_spread_equals_the_exact_power() -> None:
    for n in (4, 6, 8):
        found = simulate_identification(NO_SPREAD, n, 6, 20_000, seed=1, rate=0.7)
        assert found.power == pytest.approx(exact_power(n, 6, 0.7), abs=0.03), n
        assert found.standard_error < 0.0036


def test_power_without_spread_equals_the_noncentral_t_power_of_the_rates() -> None:
    rate, answers = 0.55, 40
    d = (rate - CHANCE) / math.sqrt(rate * (1 - rate) / answers)
    for n in (6, 12, 24):
        found = simulate_identification(NO_SPREAD, n, answers, 20_000, seed=2, rate=rate)
        critical = stats.t.ppf(1 - ALPHA / 2, n - 1)
        expected = stats.nct.sf(critical, n - 1, d * math.sqrt(n))
        assert found.power == pytest.approx(expected, abs=0.03), n


def test_at_chance_the_test_rejects_at_most_at_alpha() -> None:
    for n in (5, 12):
        found = simulate_identification(NO_SPREAD, n, 10, 20_000, seed=3, rate=0.5)
        assert found.rejections == (found.all_rejections,)
        assert found.power <= ALPHA + 3 * math.sqrt(ALPHA * (1 - ALPHA) / 20_000), n


def test_power_grows_with_persons_and_falls_with_their_spread() -> None:
    spread = RateSpread(0.0, 1.0, persons=10, answers=100, pilot_rate=0.5)
    powers = [simulate_identification(spread, n, 8, 2000, 4, 0.65).power for n in (4, 8, 16, 32)]
    assert powers == sorted(powers)
    assert powers[0] < 0.3 < 0.8 < powers[-1]
    flat = simulate_identification(NO_SPREAD, 8, 8, 2000, 4, 0.65).power
    assert flat > powers[1] + 0.05


def test_the_planned_rate_is_the_persons_mean_rate() -> None:
    spread = RateSpread(0.0, 1.5, persons=10, answers=100, pilot_rate=0.5)
    logit_mean = spread.planned(0.7)
    expected, _ = integrate.quad(
        lambda z: special.expit(logit_mean + 1.5 * z) * stats.norm.pdf(z), -np.inf, np.inf
    )
    assert expected == pytest.approx(0.7, abs=1e-9)


@pytest.mark.parametrize("logit_sd", [1.3, 5.0, 10.0])
def test_the_likelihood_equals_its_integral(logit_sd: float) -> None:
    # persons all right or all wrong: with a large sigma, a steep step in z
    correct, answers = np.array([3, 7, 10, 0, 40, 3]), np.array([10, 10, 12, 5, 40, 10])

    def person(k: int, total: int) -> float:
        found, _ = integrate.quad(
            lambda z: stats.binom.pmf(k, total, special.expit(0.4 + logit_sd * z))
            * stats.norm.pdf(z), -np.inf, np.inf, epsabs=1e-15, epsrel=1e-12, limit=400,
        )  # fmt: skip
        return math.log(found)

    expected = sum(person(k, t) for k, t in zip(correct, answers, strict=True))
    assert log_likelihood(correct, answers, 0.4, logit_sd) == pytest.approx(expected, rel=1e-10)


@pytest.mark.parametrize(("logit_mean", "logit_sd"), [(0.8, 0.7), (0.85, 0.0), (-0.3, 1.2)])
def test_the_fit_finds_a_large_pilots_rates(logit_mean: float, logit_sd: float) -> None:
    rng = np.random.default_rng(5)
    truth = special.expit(logit_mean + logit_sd * rng.standard_normal(600))
    answers = np.full(600, 20)
    found_mean, found_sd = fit_rates(rng.binomial(answers, truth), answers)
    assert found_mean == pytest.approx(logit_mean, abs=0.1)
    assert found_sd == pytest.approx(logit_sd, abs=0.2)


def test_the_simulated_test_is_the_reports() -> None:
    rng = np.random.default_rng(6)
    for persons, spread in [(5, 0.0), (5, 1.0), (1, 0.0), (3, 9.0)]:
        rows = _answers(rng, persons, special.expit(0.5 + spread * rng.standard_normal(persons)))
        found = identify(rows)
        assert found is not None
        counts = rows.groupby("participant")["guess_correct"].agg(["sum", "size"])
        rate, p = chance_tests(counts["sum"].to_numpy()[None, :], counts["size"].to_numpy()[None])
        assert (rate[0], p[0]) == pytest.approx(found.chance_test, rel=1e-12)


def test_every_rate_the_same_is_tested_by_the_pooled_binomial() -> None:
    rate, p = chance_tests(np.array([[8, 8, 8]]), np.array([[10, 10, 10]]))
    assert rate[0] == 0.8
    assert p[0] == pytest.approx(stats.binomtest(24, 30, 0.5).pvalue)


def _answers(rng: np.random.Generator, persons: int, rates: np.ndarray) -> pd.DataFrame:
    """A person's 12 answers each, about partners alternately persons and avatars."""
    truth = np.tile(["person", "avatar"], 6)
    rows = []
    for i in range(persons):
        right = rng.random(12) < rates[i]
        guess = np.where(right, truth, np.where(truth == "person", "avatar", "person"))
        rows.append(pd.DataFrame({"participant": f"p{i}", "person": "P1", "condition": "c",
                                  "partner_kind": truth, "guess_kind": guess,
                                  "guess_correct": right}))  # fmt: skip
    return pd.concat(rows, ignore_index=True)


def protocol_text(trials: int = 4, asked: bool = True, analysis: str = "") -> str:
    after = '\nafter_trial = ["partner"]\n' if asked else "\n"
    conditions = "".join(CONDITION.format(name=name) + f"trials = {trials}{after}"
                         for name in ("no delay", "delay 0.5 s"))  # fmt: skip
    return f'seed = 1\n{QUESTION}\n[[blocks]]\norder = "latin"\n{conditions}{analysis}'


def test_answers_per_person_are_the_protocols_trials_asked_about() -> None:
    assert answers_per_person(protocol_from_text(protocol_text(3), "t.toml")) == 6
    assert answers_per_person(load_protocol(Path("examples/protocols/turing.toml"))) == 4
    with pytest.raises(InputError, match='t.toml: asks "person or computer'):
        answers_per_person(protocol_from_text(protocol_text(3, asked=False), "t.toml"))


@pytest.fixture(scope="module")
def pilot(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("pilot")
    rows = with_answers(make_study_rows(seed=2, participants=12), seed=2, right=0.75)
    table = write_study_table(rows, folder / "table")
    protocol = folder / "turing.toml"
    protocol.write_text(protocol_text())
    return table, protocol


def test_a_pilots_rates_are_fitted(pilot: tuple[Path, Path]) -> None:
    spread = pilot_rates(read_study_table(pilot[0]))
    assert (spread.persons, spread.answers) == (12, 96)
    assert spread.pilot_rate == pytest.approx(0.75, abs=0.08)
    assert spread.mean_rate == pytest.approx(spread.pilot_rate, abs=0.03)


def test_a_pilot_of_one_person_is_refused(tmp_path: Path) -> None:
    rows = with_answers(make_study_rows(seed=2, participants=1), seed=2)
    table = read_study_table(write_study_table(rows, tmp_path / "one"))
    with pytest.raises(InputError, match="1 person\\(s\\) answered"):
        pilot_rates(table)


def test_study_power_of_the_identification_test(pilot: tuple[Path, Path], tmp_path: Path) -> None:
    table, protocol = pilot
    arguments = ["study", "power", str(table), "--protocol", str(protocol), "--test",
                 "identification", "--participants", "4,8,16", "--simulations", "400",
                 "--rate", "0.6", "--out", str(tmp_path)]  # fmt: skip
    assert main(arguments) == 0
    found = pd.read_csv(tmp_path / "power.csv")
    assert found["participants"].tolist() == [4, 8, 16]
    assert (found["power"] <= found["power_either_side"]).all()
    written = json.loads((tmp_path / "power.json").read_text())
    assert written["hypothesis"]["test"] == "identification"
    assert (written["rate"], written["answers_per_person"]) == (0.6, 8)
    assert written["pilot"]["persons"] == 12
    assert (tmp_path / "power.png").read_bytes().startswith(b"\x89PNG")
    more = tmp_path / "more"
    assert main([*arguments[:-1], str(more), "--trials", "40"]) == 0
    assert json.loads((more / "power.json").read_text())["answers_per_person"] == 40
    assert (pd.read_csv(more / "power.csv")["power"] >= found["power"] - 0.1).all()
    declared = tmp_path / "declared.toml"
    declared.write_text(protocol_text(analysis=ANALYSIS))
    plan = ["study", "plan", "--protocol", str(declared), "--power", str(tmp_path), "--out",
            str(tmp_path / "plan")]  # fmt: skip
    assert main(plan) == 2


@pytest.mark.parametrize(
    ("options", "problem"),
    [
        (["--test", "identification", "--effect", "0.1"], "--effect"),
        (["--rate", "0.6"], "--rate"),
        (["--test", "identification", "--rate", "1"], "--rate"),
    ],
)
def test_study_power_refuses_options_of_the_other_test(
    pilot: tuple[Path, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    options: list[str],
    problem: str,
) -> None:
    table, protocol = pilot
    arguments = ["study", "power", str(table), "--protocol", str(protocol),
                 "--out", str(tmp_path / "o")]  # fmt: skip
    assert main(arguments + options) == 2
    error = capsys.readouterr().err.strip()
    assert problem in error and "\n" not in error
    assert not (tmp_path / "o" / "power.csv").exists()


@pytest.mark.slow
def test_power_equals_a_slow_simulation_of_whole_studies_scored_by_the_report() -> None:
    # persons right with probability expit(0.85 + 1.0 z) (mean rate 0.67), 12 answers each, 8
    # persons a study: 400 studies as answer rows, each scored by the report's `identify`
    rng = np.random.default_rng(8)
    said = 0
    for _ in range(400):
        found = identify(_answers(rng, 8, special.expit(0.85 + rng.standard_normal(8))))
        assert found is not None
        rate, p = found.chance_test
        said += p < ALPHA and rate > CHANCE
    fast = simulate_identification(RateSpread(0.85, 1.0, 8, 96, 0.67), 8, 12, 20_000, seed=9)
    # the slow share's Monte Carlo SE is at most 0.025
    assert fast.power == pytest.approx(said / 400, abs=0.06)
    pilot = identify(_answers(rng, 300, special.expit(0.85 + rng.standard_normal(300))))
    assert pilot is not None
    counts = pilot.per_person[["correct", "answers"]].to_numpy(np.int64)
    logit_mean, logit_sd = fit_rates(counts[:, 0], counts[:, 1])
    assert (logit_mean, logit_sd) == pytest.approx((0.85, 1.0), abs=0.15)

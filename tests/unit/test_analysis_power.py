"""The declared test's power by simulation: against theory, against `confirm`, and the command.

The simulated power of a paired comparison with a known standardised effect d is checked
against the noncentral-t power (statsmodels' `TTestPower`) at three numbers of participants,
one-sided and two-sided: with 20000 simulated studies the binomial Monte Carlo standard error is
at most 0.5 / sqrt(20000) = 0.0035, so 0.03 is more than 8 standard errors.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from statsmodels.stats.power import TTestPower
from study_tables import CONDITIONS, TRIAL_SD, make_study_rows, write_study_table
from test_analysis_hypothesis import ANALYSIS, protocol_text

from mirror_avatar.analysis.hypothesis import confirm
from mirror_avatar.analysis.power import (
    CHUNK_VALUES,
    PowerPoint,
    Spread,
    pilot_spread,
    rejections,
    simulate_differences,
    simulate_power,
    smallest_participants,
)
from mirror_avatar.analysis.study_file import read_study_table
from mirror_avatar.cli import main
from mirror_avatar.common.errors import InputError
from mirror_avatar.lab.design.protocol import Analysis

NO_DELAY, DELAY = CONDITIONS
UNIT_SPREAD = Spread(("rms",), np.array([[1.0]]), 10, np.zeros(1), np.array([[0.0]]), 0.5)
STATSMODELS = {"higher": "larger", "lower": "smaller", "two-sided": "two-sided"}


def hypothesis(
    direction: str, effect: float = 0.5, primary: tuple[str, ...] = ("rms",)
) -> Analysis:
    return Analysis(primary=primary, direction=direction, condition=DELAY, reference=NO_DELAY,
                    smallest_effect=effect)  # fmt: skip


@pytest.mark.parametrize("direction", ["higher", "lower", "two-sided"])
def test_simulated_power_equals_the_noncentral_t_power(direction: str) -> None:
    analysis = hypothesis(direction)
    signed = -0.5 if direction == "lower" else 0.5
    for n in (8, 16, 30):
        found = simulate_power(UNIT_SPREAD, analysis, n, 20_000, seed=1)
        expected = TTestPower().power(effect_size=signed, nobs=n, alpha=0.05,
                                      alternative=STATSMODELS[direction])  # fmt: skip
        assert found.power == pytest.approx(expected, abs=0.03)
        low, high = found.interval
        assert low < found.power < high
        assert found.standard_error < 0.0036


def test_studies_drawn_in_chunks_keep_the_noncentral_t_power() -> None:
    # 5000 studies of 1000 participants: three chunks of CHUNK_VALUES, Monte Carlo SE 0.0055
    assert 2 * CHUNK_VALUES < 5000 * 1000
    found = simulate_power(UNIT_SPREAD, hypothesis("higher", 0.08), 1000, 5000, seed=1)
    assert found.simulations == 5000
    expected = TTestPower().power(effect_size=0.08, nobs=1000, alpha=0.05, alternative="larger")
    assert found.power == pytest.approx(expected, abs=0.03)


def test_power_grows_with_participants() -> None:
    powers = [simulate_power(UNIT_SPREAD, hypothesis("higher"), n, 2000, 3).power
              for n in (4, 8, 16, 32)]  # fmt: skip
    assert powers == sorted(powers)
    assert powers[0] < 0.3 < 0.8 < powers[-1]


def test_no_effect_rejects_at_alpha() -> None:
    found = simulate_power(UNIT_SPREAD, hypothesis("two-sided"), 12, 20_000, 2, effect=0.0)
    assert found.power == pytest.approx(0.05, abs=0.01)


def test_the_simulated_test_is_the_reports_confirm() -> None:
    analysis = hypothesis("lower", 0.02, ("rms", "phase_locking"))
    covariance = np.array([[1e-3, 4e-4], [4e-4, 2e-3]])
    differences = simulate_differences(covariance, 0.02, "lower", 9, 40, np.random.default_rng(5))
    rejected = rejections(differences, analysis)
    for study, expected in zip(differences, rejected, strict=True):
        found = [test.significant for test in confirm(study_rows(study, analysis), analysis)]
        assert found == list(expected)
    assert 0 < rejected.sum() < rejected.size


def study_rows(differences: np.ndarray, analysis: Analysis) -> pd.DataFrame:
    """The rows of a study whose participants' differences are ``differences`` (m, n)."""
    n = differences.shape[1]
    participants = np.tile([f"p{i}" for i in range(n)], 2)
    conditions = np.repeat([analysis.reference, analysis.condition], n)
    values = {m: np.concatenate([np.zeros(n), d]) for m, d in zip(analysis.primary, differences,
                                                                 strict=True)}  # fmt: skip
    return pd.DataFrame({"participant": participants, "condition": conditions} | values)


def points(powers: dict[int, float]) -> list[PowerPoint]:
    return [PowerPoint(n, 100, (round(100 * p),), round(100 * p)) for n, p in powers.items()]


def test_smallest_number_reaching_the_target() -> None:
    assert smallest_participants(points({6: 0.5, 8: 0.79, 12: 0.8, 16: 0.95}), 0.8) == 12
    assert smallest_participants(points({16: 0.95, 6: 0.85, 8: 0.7, 12: 0.9}), 0.8) == 12
    assert smallest_participants(points({6: 0.5, 8: 0.6}), 0.8) is None


def test_pilot_spread_is_the_sd_of_the_participants_differences(tmp_path: Path) -> None:
    rows = make_study_rows(seed=4, participants=10, effects={"rms": 0.03})
    table = read_study_table(write_study_table(rows, tmp_path / "pilot"))
    spread = pilot_spread(table, hypothesis("higher", 0.02, ("rms", "phase_locking")), "p.toml")
    persons = rows[rows["player_kind"] == "person"]
    means = persons.groupby(["participant", "condition"])["rms"].mean().unstack()
    differences = means[DELAY] - means[NO_DELAY]
    assert spread.participants == 10
    assert spread.sd[0] == pytest.approx(differences.std(ddof=1), rel=1e-12)
    assert spread.pilot_differences[0] == pytest.approx(differences.mean(), rel=1e-12)
    assert spread.covariance.shape == (2, 2)


def test_trial_noise_is_estimated_and_planned(tmp_path: Path) -> None:
    rows = make_study_rows(seed=6, participants=40, trials=4)
    table = read_study_table(write_study_table(rows, tmp_path / "pilot"))
    analysis = hypothesis("higher", 0.01)
    spread = pilot_spread(table, analysis, "p.toml")
    assert spread.trial_factor == pytest.approx(0.5)
    assert np.sqrt(spread.trial_covariance[0, 0]) == pytest.approx(TRIAL_SD["rms"], rel=0.1)
    # the synthetic participants differ by trial noise alone: their own spread is clipped to 0
    noise = spread.trial_factor * spread.trial_covariance[0, 0]
    pilot = spread.covariance[0, 0]
    assert spread.with_trials(4)[0, 0] == pytest.approx(max(pilot, noise), rel=1e-9)
    assert spread.with_trials(16)[0, 0] < spread.covariance[0, 0]
    few, many = (simulate_power(spread, analysis, 12, 2000, 1, trials=k).power for k in (1, 16))
    assert few < many


def test_pilot_without_a_condition_of_the_contrast_is_refused(tmp_path: Path) -> None:
    rows = make_study_rows(seed=1, conditions=(NO_DELAY, "delay 1 s"))
    table = read_study_table(write_study_table(rows, tmp_path / "pilot"))
    with pytest.raises(InputError, match="p.toml: analysis: no condition 'delay 0.5 s'"):
        pilot_spread(table, hypothesis("higher"), "p.toml")


def test_pilot_without_the_primary_measure_is_refused(tmp_path: Path) -> None:
    table = read_study_table(write_study_table(make_study_rows(seed=1), tmp_path / "pilot"))
    with pytest.raises(InputError, match="p.toml: analysis.primary: no measure rmse"):
        pilot_spread(table, hypothesis("higher", primary=("rmse",)), "p.toml")


@pytest.fixture(scope="module")
def pilot(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("pilot")
    table = write_study_table(make_study_rows(seed=2, participants=6), folder / "table")
    protocol = folder / "delay.toml"
    protocol.write_text(protocol_text())
    return table, protocol


def test_study_power_writes_its_files(pilot: tuple[Path, Path], tmp_path: Path) -> None:
    table, protocol = pilot
    arguments = ["study", "power", str(table), "--protocol", str(protocol),
                 "--participants", "4,8,16", "--simulations", "400", "--seed", "7",
                 "--out", str(tmp_path)]  # fmt: skip
    assert main(arguments) == 0
    found = pd.read_csv(tmp_path / "power.csv")
    assert found["participants"].tolist() == [4, 8, 16]
    assert (found["ci_low"] <= found["power"]).all() and (found["power"] <= found["ci_high"]).all()
    written = json.loads((tmp_path / "power.json").read_text())
    assert written["seed"] == 7 and written["simulations"] == 400
    assert written["trials_per_condition"] is None
    assert written["effect"] == 0.05 and written["hypothesis"]["direction"] == "lower"
    assert len(written["table_sha256"]) == 64
    assert (tmp_path / "power.png").read_bytes().startswith(b"\x89PNG")
    again = tmp_path / "again"
    assert main([*arguments[:-1], str(again)]) == 0
    assert (again / "power.csv").read_text() == (tmp_path / "power.csv").read_text()
    planned = tmp_path / "planned"
    assert main([*arguments[:-1], str(planned), "--trials", "16"]) == 0
    assert json.loads((planned / "power.json").read_text())["trials_per_condition"] == 16


@pytest.mark.parametrize(
    ("analysis", "options", "problem"),
    [
        (ANALYSIS, ["--participants", "4,x"], "--participants"),
        (ANALYSIS, ["--participants", "1,8"], "--participants"),
        (ANALYSIS, ["--effect", "-1"], "--effect"),
        (ANALYSIS, ["--trials", "0"], "--trials"),
        ("", [], "no [analysis]"),
        (ANALYSIS.replace("phase_locking", "rmse"), [], "no measure rmse"),
        (ANALYSIS.replace("no delay", "fast"), [], "'fast' is not a condition"),
    ],
)
def test_study_power_refuses_bad_input(
    pilot: tuple[Path, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    analysis: str,
    options: list[str],
    problem: str,
) -> None:
    table, _ = pilot
    protocol = tmp_path / "edited.toml"
    protocol.write_text(protocol_text(analysis))
    arguments = [
        "study",
        "power",
        str(table),
        "--protocol",
        str(protocol),
        "--out",
        str(tmp_path / "o"),
    ]
    assert main(arguments + options) == 2
    error = capsys.readouterr().err.strip()
    assert problem in error and "\n" not in error
    assert not (tmp_path / "o" / "power.csv").exists()


ANGLE_SPREAD = Spread(("mean_relative_phase",), np.array([[0.04]]), 10, np.zeros(1),
                      np.array([[0.0]]), 0.5, angles=(True,))  # fmt: skip
"""Participants' differences of direction with SD 0.2 rad: concentrated, far from wrapping."""


@pytest.mark.parametrize("direction", ["higher", "two-sided"])
def test_an_angles_power_is_the_sign_flip_tests_near_the_noncentral_t_power(
    direction: str,
) -> None:
    # Differences of SD 0.2 rad barely wrap and sin d is nearly d: the sign-flip test, a
    # permutation version of the t-test, has nearly its power (n = 30 draws its flips)
    analysis = hypothesis(direction, 0.1, ("mean_relative_phase",))
    for n in (10, 16, 30):
        found = simulate_power(ANGLE_SPREAD, analysis, n, 4000, seed=2)
        expected = TTestPower().power(effect_size=0.5, nobs=n, alpha=0.05,
                                      alternative=STATSMODELS[direction])  # fmt: skip
        assert found.power == pytest.approx(expected, abs=0.04), n


def test_an_angle_simulated_is_tested_as_the_reports_confirm_tests_it() -> None:
    analysis = hypothesis("higher", 0.3, ("mean_relative_phase",))
    differences = simulate_differences(np.array([[0.25]]), 0.3, "higher", 7, 30,
                                       np.random.default_rng(3))  # fmt: skip
    rejected = rejections(differences, analysis, np.array([True]))
    for study, expected in zip(differences, rejected, strict=True):
        rows = study_rows(study, analysis)
        rows["mean_relative_phase"] = np.angle(np.exp(1j * (rows["mean_relative_phase"] + 3.0)))
        found = [test.significant for test in confirm(rows, analysis)]
        assert found == list(expected)
    assert 0 < rejected.sum() < rejected.size


def test_a_pilots_angles_near_pi_give_the_spread_they_give_near_0(tmp_path: Path) -> None:
    rows = make_study_rows(seed=7, participants=10)
    rng = np.random.default_rng(7)
    phase = 0.3 * rng.standard_normal(len(rows)) + 0.2 * (rows["condition"] == DELAY)
    spreads = []
    for centre in (0.0, np.pi):
        rows["mean_relative_phase"] = np.angle(np.exp(1j * (phase + centre)))
        table = read_study_table(write_study_table(rows, tmp_path / f"at{centre:.0f}", False))
        analysis = hypothesis("higher", 0.1, ("mean_relative_phase",))
        spreads.append(pilot_spread(table, analysis, "p.toml"))
    near_zero, near_pi = spreads
    assert near_pi.angles == (True,)
    assert near_pi.covariance[0, 0] == pytest.approx(near_zero.covariance[0, 0], rel=1e-9)
    assert near_pi.trial_covariance[0, 0] == pytest.approx(
        near_zero.trial_covariance[0, 0], rel=1e-9
    )
    assert near_pi.pilot_differences[0] == pytest.approx(near_zero.pilot_differences[0], abs=1e-9)
    assert 0.1 < near_pi.pilot_differences[0] < 0.3


@pytest.mark.long
def test_power_from_a_pilot_equals_a_slow_simulation_of_whole_trial_level_studies(
    tmp_path: Path,
) -> None:
    """Trial-level studies (a random intercept and a random slope for condition per
    participant, trial noise; `make_study_rows`) simulated one by one and tested by `confirm`,
    against `simulate_power` from a large pilot's spread with two trials, planned at four.

    Truth: RMS effect 0.015, participants' own effects SD 0.02, trial SD `TRIAL_SD`; 600 slow
    studies (Monte Carlo SE at most 0.021), tolerance 0.065 (about 3 SE).
    """
    effect, slope_sd, n, trials = 0.015, 0.02, 10, 4
    analysis = hypothesis("higher", effect)
    pilot_rows = make_study_rows(seed=99, participants=300, trials=2, effects={"rms": effect},
                                 slope_sd={"rms": slope_sd})  # fmt: skip
    spread = pilot_spread(read_study_table(write_study_table(pilot_rows, tmp_path / "pilot")),
                          analysis, "p.toml")  # fmt: skip
    planned = spread.with_trials(trials)[0, 0]
    true_variance = slope_sd**2 + 2 * TRIAL_SD["rms"] ** 2 / trials
    assert planned == pytest.approx(true_variance, rel=0.2)
    fast = simulate_power(spread, analysis, n, 20_000, seed=4, trials=trials).power
    slow = np.mean([
        confirm(make_study_rows(seed=1000 + s, participants=n, trials=trials,
                                effects={"rms": effect}, slope_sd={"rms": slope_sd}),
                analysis)[0].significant
        for s in range(600)
    ])  # fmt: skip
    assert fast == pytest.approx(slow, abs=0.065)
    theory = TTestPower().power(effect_size=effect / np.sqrt(true_variance), nobs=n, alpha=0.05,
                                alternative="larger")  # fmt: skip
    assert slow == pytest.approx(theory, abs=0.065)

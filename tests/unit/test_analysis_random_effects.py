"""Random slopes for condition where the data support them, on simulated studies of known truth.

Studies of 12 participants in two counterbalanced conditions, 6 trials each (`make_study_rows`),
RMS with a trial SD of 0.02: with each participant's own effect drawn with an SD of 0.03 (a true
slope variance) the slopes are kept in every seed and the condition is tested on about n - 2 =
10 df (participants, less the condition and position effects: the crossover's); with none, the
random intercept is kept in most seeds, the report says why, and the condition is tested against
the trials' noise on N - n - 2 = 130 df. With participants' own effects around none, the
slopes find a difference at p < 0.05 in at most 1 of 10 seeds; the random intercept alone, in 3
of these 10.

Partners: each participant meets avatars A1 to A4 in turn (trial k of participant i with
A((i + k) mod 4 + 1)), each avatar adding its own level to RMS. With avatars' levels of SD 0.03
the partners are a crossed random factor in every seed, the condition effect still found near
its truth; with none, they are left out in most seeds and the notes say why; two avatars are
too few.
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest
from statsmodels.regression.mixed_linear_model import MixedLM
from statsmodels.tools.sm_exceptions import ConvergenceWarning
from study_tables import CONDITIONS, make_study_rows

from mirror_avatar.analysis.random_effects import CROSSED, INTERCEPT, SLOPES, unsupported
from mirror_avatar.analysis.small_sample import satterthwaite_tests
from mirror_avatar.analysis.statistics import MeasureModel, fit_contrasts, trial_values

NO_DELAY, DELAY = CONDITIONS
SEEDS = range(10)


def persons(seed: int, effect: float, slope_sd: float | None, **design: int) -> pd.DataFrame:
    slopes = None if slope_sd is None else {"rms": slope_sd}
    rows = make_study_rows(seed, trials=design.pop("trials", 6), effects={"rms": effect},
                           slope_sd=slopes, **design)  # fmt: skip
    return rows[rows["player_kind"] == "person"]


def model(seed: int, effect: float, slope_sd: float | None, **design: int) -> MeasureModel:
    found = fit_contrasts(persons(seed, effect, slope_sd, **design), "rms", CONDITIONS, NO_DELAY)
    assert found is not None
    return found


def intercept_only_p(seed: int) -> float:
    """The condition's p in the random intercept model, fitted whatever the data support."""
    trials = trial_values(persons(seed, 0.0, 0.03), "rms")
    design = pd.DataFrame({"Intercept": 1.0, "delay": (trials["condition"] == DELAY) * 1.0,
                           "position": trials["position"] * 1.0})  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        result = MixedLM(trials["rms"], design, groups=trials["participant"]).fit(reml=True)
    return satterthwaite_tests(result, [[0.0, 1.0, 0.0]])[0].p


def test_participants_own_effects_get_slopes_and_the_participants_df() -> None:
    models = [model(seed, 0.03, 0.03) for seed in SEEDS]
    assert all(m.random_effects == SLOPES and m.notes == [] for m in models)
    contrasts = [m.contrasts[0] for m in models]
    assert all(9.0 < c.df < 12.0 for c in contrasts)
    assert np.mean([c.difference for c in contrasts]) == pytest.approx(0.03, abs=0.01)
    assert sum(c.ci_low < 0.03 < c.ci_high for c in contrasts) >= 8


@pytest.mark.long
def test_varying_effects_around_none_are_rarely_found() -> None:
    """The slopes keep the false positives near alpha, where a random intercept does not."""
    p = [model(seed, 0.0, 0.03).contrasts[0].p for seed in SEEDS]
    assert sum(value >= 0.05 for value in p) >= 9, p
    assert sum(intercept_only_p(seed) < 0.05 for seed in SEEDS) >= 3


@pytest.mark.long
def test_without_participants_own_effects_the_intercept_is_kept_and_said() -> None:
    models = [model(seed, 0.03, None) for seed in SEEDS]
    kept = [m for m in models if m.random_effects == INTERCEPT]
    assert len(kept) >= 8
    for m in kept:
        assert any(n.startswith("no random slopes for condition: ") for n in m.notes), m.notes
        assert m.contrasts[0].df == pytest.approx(12 * 2 * 6 - 12 - 2, abs=0.5)
        assert m.contrasts[0].p < 0.001


def test_what_the_data_cannot_estimate_is_said() -> None:
    two = model(0, 0.03, 0.03, participants=2)
    assert two.random_effects == INTERCEPT
    assert any("2 participants with every condition, fewer than the 3" in n for n in two.notes)
    once = model(0, 0.03, 0.03, trials=1)
    assert once.random_effects == INTERCEPT
    assert any("one trial per participant and condition" in n for n in once.notes)


def test_unsupported_counts_participants_with_every_condition() -> None:
    participants = pd.Series(["a", "a", "b", "b", "c", "c", "c"])
    conditions = pd.Series(["x", "y", "x", "y", "x", "y", "y"])
    assert unsupported(participants, conditions) is None
    assert unsupported(participants[:-3], conditions[:-3]) is not None  # a and b only
    assert "one trial" in str(unsupported(participants[:-1], conditions[:-1]))


def with_partners(rows: pd.DataFrame, seed: int, partner_sd: float, count: int) -> pd.DataFrame:
    """The rows with avatars A1..A``count`` met in turn, each adding its level to RMS."""
    turn = (rows["participant"].str[1:].astype(int) + rows["trial"]) % count
    level = np.random.default_rng(100 + seed).normal(0.0, partner_sd, count)
    return rows.assign(partners="A" + (turn + 1).astype(str),
                       rms=rows["rms"] + level[turn.to_numpy()])  # fmt: skip


def partner_model(
    seed: int, partner_sd: float, count: int = 4, slope_sd: float | None = None
) -> MeasureModel:
    rows = with_partners(persons(seed, 0.03, slope_sd), seed, partner_sd, count)
    found = fit_contrasts(rows, "rms", CONDITIONS, NO_DELAY)
    assert found is not None
    return found


def test_avatars_levels_make_partner_identity_a_crossed_factor() -> None:
    models = [partner_model(seed, 0.03) for seed in range(5)]
    assert all(m.random_effects == f"{INTERCEPT}, and {CROSSED}" for m in models)
    assert all(m.notes == [] and m.partner_variance > 0 for m in models)
    contrasts = [m.contrasts[0] for m in models]
    assert np.mean([c.difference for c in contrasts]) == pytest.approx(0.03, abs=0.005)
    # the residual's N - n - 2 = 130 df, less the partners' 3
    assert all(c.df == pytest.approx(127.0, abs=0.5) and c.p < 0.001 for c in contrasts)


def test_partners_without_their_own_levels_are_left_out_and_said() -> None:
    models = [partner_model(seed, 0.0) for seed in range(5)]
    left = [m for m in models if CROSSED not in m.random_effects]
    assert len(left) >= 4
    for m in left:
        assert any(n.startswith("no random effect of partner identity: ") for n in m.notes)
        assert np.isnan(m.partner_variance)
    two = partner_model(0, 0.03, count=2)
    assert CROSSED not in two.random_effects
    assert any("2 partners met by two participants or more, fewer than 3" in n for n in two.notes)


def test_slopes_and_partners_together() -> None:
    """Participants' own effects and avatars' levels: slopes (uncorrelated) and partners."""
    both = partner_model(0, 0.03, slope_sd=0.03)
    assert both.random_effects == (f"{SLOPES.replace('correlated', 'uncorrelated')}, and "
                                   f"{CROSSED}")  # fmt: skip
    (contrast,) = both.contrasts
    assert contrast.df == pytest.approx(10.0, abs=1.0)
    assert contrast.ci_low < 0.03 < contrast.ci_high

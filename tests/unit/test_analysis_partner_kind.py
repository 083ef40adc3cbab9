"""The partner's kind and condition x kind as fixed effects of a measure's mixed model.

Checked against ordinary least squares with a dummy per participant (statsmodels), which a
balanced design with a random intercept equals for effects within participants (as for the
conditions, docs/METHODS.md section 15.3), against the cell means computed by hand, and on
simulated studies with and without a known effect of the partner's kind. Where each participant
has their own kind effect, random slopes for the kind are chosen and the kind is then tested as
the paired t-test of the participants' differences between the kinds (scipy), which a balanced
design with such slopes equals.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import statsmodels.formula.api as smf
from scipy import stats
from study_tables import CONDITIONS, make_study_rows

from mirror_avatar.analysis.partner_kind import INTERACTION_TERM, KIND_TERM
from mirror_avatar.analysis.random_effects import INTERCEPT, KIND_SLOPES
from mirror_avatar.analysis.statistics import fit_contrasts

NO_DELAY, DELAY = CONDITIONS


def kinds_study(seed: int, kind_effect: float = 0.0, interaction: float = 0.0) -> pd.DataFrame:
    """The persons' rows, the partner a person in even trials and an avatar in odd ones.

    RMS is ``kind_effect`` higher with an avatar, and the delay's effect ``interaction`` higher
    with an avatar than with a person.
    """
    rows = make_study_rows(seed, trials=4)
    rows = rows[rows["player_kind"] == "person"].copy()
    avatar = (rows["trial"] % 2 == 1).to_numpy()
    rows["partner_kind"] = np.where(avatar, "avatar", "person")
    rows["rms"] += avatar * (kind_effect + interaction * (rows["condition"] == DELAY))
    return rows


def own_kinds_study(seed: int, kind_effect: float, kind_sd: float) -> pd.DataFrame:
    """`kinds_study` with each participant's own kind effect, drawn with SD ``kind_sd``."""
    rows = kinds_study(seed, kind_effect=kind_effect)
    rng = np.random.default_rng(1000 + seed)
    own = {p: rng.normal(0.0, kind_sd) for p in rows["participant"].unique()}
    rows["rms"] += (rows["partner_kind"] == "avatar") * rows["participant"].map(own)
    return rows


def test_participants_own_kind_effects_get_slopes_and_the_paired_t_test() -> None:
    for seed in range(4):
        rows = own_kinds_study(seed, 0.03, 0.03)
        model = fit_contrasts(rows, "rms", CONDITIONS, NO_DELAY)
        assert model is not None and model.random_effects == KIND_SLOPES, model.notes
        kind = model.factors[0]
        means = rows.groupby(["participant", "partner_kind"])["rms"].mean().unstack()
        differences = means["avatar"] - means["person"]
        paired = stats.ttest_1samp(differences, 0.0)
        assert kind.estimate == pytest.approx(differences.mean(), rel=1e-4)
        assert kind.df == pytest.approx(len(differences) - 1, abs=0.1)
        assert kind.p == pytest.approx(paired.pvalue, rel=1e-3)


def test_without_own_kind_effects_no_kind_slopes_and_said() -> None:
    for seed in range(4):
        model = fit_contrasts(own_kinds_study(seed, 0.03, 0.0), "rms", CONDITIONS, NO_DELAY)
        assert model is not None and "partner kind" not in model.random_effects
        assert any(n.startswith("no random slopes for partner kind: ") for n in model.notes)


@pytest.mark.long
def test_own_kind_effects_around_none_are_rarely_found() -> None:
    """With kind slopes, p < 0.05 in at most 2 of 10 seeds of own effects around none."""
    p = [fit_contrasts(own_kinds_study(seed, 0.0, 0.03), "rms", CONDITIONS,
                       NO_DELAY).factors[0].p for seed in range(10)]  # fmt: skip
    assert sum(value < 0.05 for value in p) <= 2, p


def test_balanced_kinds_equal_least_squares_with_a_dummy_per_participant() -> None:
    rows = kinds_study(0, kind_effect=0.03, interaction=0.02)
    model = fit_contrasts(rows, "rms", CONDITIONS, NO_DELAY)
    assert model is not None and model.random_effects == INTERCEPT
    assert model.fixed_effects == (
        "measure ~ condition + position + partner kind + condition x partner kind"
    )
    ols = smf.ols(
        "rms ~ C(participant) + C(condition, Sum) * C(partner_kind, Sum) + position", rows
    ).fit()
    condition, kind = "C(condition, Sum)[S.delay 0.5 s]", "C(partner_kind, Sum)[S.avatar]"
    (contrast,) = model.contrasts
    kind_test, interaction_test = model.factors
    assert (kind_test.term, kind_test.condition, kind_test.kind, kind_test.reference_kind) == (
        KIND_TERM, "", "avatar", "person"
    )  # fmt: skip
    assert (interaction_test.term, interaction_test.condition) == (INTERACTION_TERM, DELAY)
    # Sum coding's +-1 codes: a difference is twice its coefficient, the interaction four times.
    for found, name, scale in [(contrast.difference, condition, 2), (kind_test.estimate, kind, 2),
                               (interaction_test.estimate, f"{condition}:{kind}", 4)]:  # fmt: skip
        assert found == pytest.approx(scale * ols.params[name], rel=1e-4)
    for found, name in [(contrast.p, condition), (kind_test.p, kind),
                        (interaction_test.p, f"{condition}:{kind}")]:  # fmt: skip
        assert found == pytest.approx(ols.pvalues[name], rel=1e-3, abs=1e-12)
    assert kind_test.df == pytest.approx(ols.df_resid, abs=0.01)
    cells = rows.groupby(["condition", "partner_kind"])["rms"].mean()
    by_hand = (cells[DELAY, "avatar"] - cells[DELAY, "person"]) - (
        cells[NO_DELAY, "avatar"] - cells[NO_DELAY, "person"]
    )
    assert interaction_test.estimate == pytest.approx(by_hand, rel=1e-4)
    kinds = rows.groupby("partner_kind")["rms"].mean()
    assert kind_test.estimate == pytest.approx(kinds["avatar"] - kinds["person"], rel=1e-4)


@pytest.mark.long
def test_a_kind_effect_is_found_in_every_seed_and_none_seldom() -> None:
    """Avatar 0.03 higher (1.5 trial SDs): found with its sign in 10 of 10 seeds; none: p >=
    0.05 for the kind in at least 8 of 10 seeds, and for condition x kind likewise."""
    found, false_kind, false_interaction = 0, 0, 0
    for seed in range(10):
        with_effect = fit_contrasts(kinds_study(seed, kind_effect=0.03), "rms", CONDITIONS,
                                    NO_DELAY)  # fmt: skip
        none = fit_contrasts(kinds_study(100 + seed), "rms", CONDITIONS, NO_DELAY)
        assert with_effect is not None and none is not None
        kind = with_effect.factors[0]
        found += kind.p < 0.05 and kind.estimate > 0
        false_kind += none.factors[0].p < 0.05
        false_interaction += none.factors[1].p < 0.05
    assert found == 10
    assert false_kind <= 2 and false_interaction <= 2


def test_a_kind_met_in_one_condition_only_has_no_interaction_and_says_so() -> None:
    rows = kinds_study(1, kind_effect=0.03)
    rows.loc[rows["condition"] == DELAY, "partner_kind"] = "avatar"
    model = fit_contrasts(rows, "rms", CONDITIONS, NO_DELAY)
    assert model is not None
    assert [f.term for f in model.factors] == [KIND_TERM]
    assert any(INTERACTION_TERM in note and "not tested" in note for note in model.notes)
    assert model.fixed_effects == "measure ~ condition + position + partner kind"


def test_a_condition_that_fixes_the_kind_leaves_the_kind_to_the_contrast() -> None:
    rows = kinds_study(2)
    rows["partner_kind"] = np.where(rows["condition"] == DELAY, "avatar", "person")
    model = fit_contrasts(rows, "rms", CONDITIONS, NO_DELAY)
    assert model is not None and model.factors == []
    assert any("condition fixes the partner's kind" in note for note in model.notes)
    assert model.fixed_effects == "measure ~ condition + position"


def test_one_kind_adds_nothing() -> None:
    rows = kinds_study(3).assign(partner_kind="avatar")
    model = fit_contrasts(rows, "rms", CONDITIONS, NO_DELAY)
    assert model is not None and model.factors == [] and model.converged
    assert not any("partner kind" in note for note in model.notes)

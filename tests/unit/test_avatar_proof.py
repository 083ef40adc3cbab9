"""The avatar's proof against the person: held-out trials, EMDs and the replayed partner's sign."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.stats import wasserstein_distance

from mirror_avatar.errors import InputError
from mirror_avatar.experiments.avatar_proof import (
    count_held_out,
    dyad_numbers,
    find_person,
    prove_held_out,
    split_held_out,
)
from mirror_avatar.session import Session
from mirror_avatar.signature import DEFAULT_BINS, compute_ims
from mirror_avatar.trials import compute_velocity, make_trial


def scipy_emd(a: np.ndarray, b: np.ndarray) -> float:
    """EMD of two velocity series' IMS by scipy, normalised by the bin range."""
    centres = DEFAULT_BINS.centres
    weights = compute_ims(a), compute_ims(b)
    return wasserstein_distance(centres, centres, *weights) / (centres[-1] - centres[0])


def sine_trial(frequency: float, label: str, seconds: float = 30.0):
    t = np.arange(0.0, seconds, 0.01)
    return make_trial(t, 0.3 * np.sin(2 * np.pi * frequency * t), label=label)


@pytest.mark.parametrize(("n", "held"), [(1, 0), (2, 0), (3, 1), (4, 1), (7, 1), (8, 2), (12, 3)])
def test_one_trial_in_four_is_held_out_from_three(n: int, held: int) -> None:
    assert count_held_out(n) == held


def test_held_out_trials_spread_over_the_recording_order() -> None:
    trials = [sine_trial(0.5, f"t{k}", 2.0) for k in range(8)]
    fitted, held = split_held_out(trials, 2)
    assert [t.label for t in held] == ["t2", "t5"] and len(fitted) == 6
    assert [t.label for t in split_held_out(trials[:3], 1)[1]] == ["t1"]
    with pytest.raises(InputError, match="keep at least one to fit"):
        split_held_out(trials[:3], 3)


def test_held_out_emds_match_scipy_and_judge_the_leader() -> None:
    trials = [sine_trial(f, f"t{k}") for k, f in enumerate((0.40, 0.45, 0.50, 0.42))]
    fitted, held = split_held_out(trials, 1)
    velocities = [compute_velocity(t.positions, 100.0) for t in trials]
    like = [compute_velocity(sine_trial(0.44, "a").positions, 100.0)]
    unlike = [compute_velocity(sine_trial(1.5, "b").positions, 100.0)]
    proof = prove_held_out(fitted, held, {"played as follower": unlike, "played as leader": like})
    ordered = [velocities[k] for k in (0, 1, 3, 2)]  # fitted first, then the held-out t2
    own = [scipy_emd(a, b) for a, b in itertools.combinations(ordered, 2)]
    np.testing.assert_allclose(proof.own, own, atol=1e-12)
    np.testing.assert_allclose(proof.played, [scipy_emd(velocities[2], like[0])], atol=1e-12)
    assert proof.to_avatar["played as follower"][0] > proof.own.max()
    assert proof.moves_like and proof.verdict().startswith("moves like the person")
    lo, hi = np.percentile(own, [5, 95])
    assert f"within the person's own {lo:.4f}-{hi:.4f}" in proof.verdict()
    swapped = prove_held_out(fitted, held, {"played as leader": unlike})
    assert not swapped.moves_like and swapped.verdict().startswith("moves unlike the person")


@pytest.mark.parametrize("partner", [0, 1])
def test_the_partner_ahead_is_a_positive_lag_whichever_its_place(partner: int) -> None:
    t = np.arange(0.0, 30.0, 0.01)
    ahead, behind = 0.3 * np.sin(2 * np.pi * 0.5 * t), 0.3 * np.sin(2 * np.pi * 0.5 * (t - 0.2))
    positions = np.array([ahead, behind] if partner == 0 else [behind, ahead])
    velocities = np.gradient(positions, t, axis=1)
    nan = np.full_like(positions, np.nan)
    session = Session(t, positions, velocities, nan, nan, labels=("A", "B"))
    numbers = dyad_numbers(session, partner)
    assert numbers["lag"] == pytest.approx(0.2, abs=0.011)
    assert numbers["cv"] > 0.99 and numbers["rms"] > 0
    assert find_person("s", session, "B" if partner == 0 else "A").person == 1 - partner
    with pytest.raises(InputError, match="no single player labelled 'C'"):
        find_person("s", session, "C")

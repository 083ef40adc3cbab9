"""The avatar checked against held-out trials in every role: folds, EMDs, the flag (issue 38.3)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.stats import wasserstein_distance

from mirror_avatar.common.errors import InputError
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.experiments.avatar_holdout import (
    Fold,
    RoleMotion,
    make_folds,
    prove_held_out,
    split_held_out,
)
from mirror_avatar.experiments.avatar_proof import Proof
from mirror_avatar.files.trials import make_trial
from mirror_avatar.signatures.likeness import trial_velocity
from mirror_avatar.signatures.signature import DEFAULT_BINS, compute_ims

RATE = 1 / 0.03  # the avatar's control rate


def scipy_emd(a: np.ndarray, b: np.ndarray) -> float:
    """EMD of two velocity series' IMS by scipy, normalised by the bin range."""
    centres = DEFAULT_BINS.centres
    weights = compute_ims(a), compute_ims(b)
    return wasserstein_distance(centres, centres, *weights) / (centres[-1] - centres[0])


@pytest.mark.parametrize(
    ("n", "folds"),
    [
        (2, []),
        (3, [[0], [1], [2]]),
        (5, [[0], [1], [2], [3], [4]]),
        (7, [[0, 5], [1, 6], [2], [3], [4]]),
        (12, [[0, 5, 10], [1, 6, 11], [2, 7], [3, 8], [4, 9]]),
    ],
)
def test_every_trial_is_held_out_once_leave_one_out_up_to_five(n: int, folds) -> None:
    assert make_folds(n) == folds


def test_one_split_spreads_the_held_out_trials_over_the_recording_order() -> None:
    t = np.arange(0.0, 2.0, 0.01)
    trials = [make_trial(t, np.sin(t), label=f"t{k}") for k in range(8)]
    fitted, held = split_held_out(trials, 2)
    assert [t.label for t in held] == ["t2", "t5"] and len(fitted) == 6
    with pytest.raises(InputError, match="keep at least one to fit"):
        split_held_out(trials[:3], 3)


@pytest.fixture(scope="module")
def slow_person() -> list:
    """Five real trials of the bundled slow style: the person."""
    return [t for t in load_zhai2017() if t.label.startswith("slow")][:5]


def folds_with(person: list, velocities: dict[str, list]) -> list[Fold]:
    """Leave-one-out folds whose avatar moves, in each role, with the given velocities."""
    return [
        Fold([trial], {role: RoleMotion(v, v) for role, v in velocities.items()})
        for trial in person
    ]


@pytest.mark.long
def test_a_follower_four_times_further_than_its_person_is_flagged(slow_person: list) -> None:
    """Leader and group member move as other trials of the slow style; the follower, wrong on
    purpose, as those trials 1.4 times faster: its median EMD to the person's trials is 4.4 x
    their own trial-to-trial median."""
    trials = {t.label: t for t in load_zhai2017()}
    others = [trial_velocity(trials[f"slow-{k}"], RATE) for k in (6, 7, 8)]
    motion = {"follower": [1.4 * v for v in others], "leader": others, "group member": others}
    proof = prove_held_out(slow_person, folds_with(slow_person, motion), RATE, seed=1)
    person_v = [t.resampled().velocity() for t in slow_person]
    own = [scipy_emd(a, b) for a, b in itertools.combinations(person_v, 2)]
    np.testing.assert_allclose(proof.own, own, atol=1e-12)
    expected = [scipy_emd(person_v[k], v) for k in range(5) for v in motion["follower"]]
    np.testing.assert_allclose(proof.to_avatar["follower"], expected, atol=1e-12)
    hi = np.percentile(own, 95)
    assert np.median(expected) > hi and proof.flagged("follower")
    assert proof.ratio("follower") == pytest.approx(np.median(expected) / np.median(own))
    assert 4.0 < proof.ratio("follower") < 5.0
    assert not proof.flagged("leader") and not proof.flagged("group member")
    sentence = proof.role_verdict("follower")
    assert sentence.startswith("As follower, FLAGGED: the avatar is further from the person")
    assert f"above their 95th percentile {hi:.4f}" in sentence
    assert proof.role_verdict("leader").startswith("As leader, the avatar moves like the person")
    assert proof.verdict() == (
        "moves like the person as leader and group member, but is FLAGGED as follower "
        f"({proof.ratio('follower'):.1f} x the person's own EMD): median EMD to held-out trials "
        f"above the person's own 95th percentile {hi:.4f} (leave-one-out over 5 trials); the "
        "person's virtual trainer is as far as follower (no human reference)"
    )
    assert "No human reference exists for the follower" in sentence
    assert sentence.endswith(
        "record the person in this role (--with-partner) for a human reference."
    )
    assert "No human reference" not in proof.role_verdict("leader")
    table = Proof(proof, None).tables()
    emd = next(t for caption, t in table.items() if caption.startswith("Velocity IMS EMD"))
    assert emd.loc["the avatar as follower", "verdict"].startswith("FLAGGED")
    assert emd.loc["the avatar as leader", "verdict"] == "within the person's own range"
    assert "95th percentile" in emd.columns and not any("P5" in c for c in emd.columns)
    likeness = next(t for caption, t in table.items() if caption.startswith("Human-likeness"))
    assert list(likeness.index.get_level_values(0).unique()) == list(motion)
    assert "p-value (permutations by trial)" in likeness.columns


@pytest.mark.long
def test_a_flagged_role_ends_with_the_next_step_a_person_can_take(slow_person: list) -> None:
    """A leader and a follower 1.4 x faster than the person, their virtual trainer not: the
    leader asks for more solo trials, the follower (further than the trainer) for training."""
    trials = {t.label: t for t in load_zhai2017()}
    others = [trial_velocity(trials[f"slow-{k}"], RATE) for k in (6, 7, 8)]
    fast = [1.4 * v for v in others]
    motion = {"follower": RoleMotion(fast, others), "leader": RoleMotion(fast, others)}
    folds = [Fold([trial], dict(motion)) for trial in slow_person]
    proof = prove_held_out(slow_person, folds, RATE, seed=1)
    assert proof.flagged("leader") and proof.flagged("follower")
    assert proof.role_verdict("leader").endswith(
        "Next: record more or longer solo trials (five of a minute or more) and create the "
        "avatar again."
    )
    assert not proof.as_far_as_trainer("follower")
    assert "train longer (--sessions above the default)" in proof.role_verdict("follower")
    assert proof.verdict().endswith("; next: train longer (--sessions)")

"""The avatar's held-out check carries the human-likeness battery in every role (issue 38.2)."""

from __future__ import annotations

import pytest

from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.experiments.avatar_holdout import Fold, RoleMotion, prove_held_out
from mirror_avatar.experiments.avatar_proof import Proof
from mirror_avatar.signatures.likeness import trial_velocity

RATE = 1 / 0.03  # the avatar's control rate


@pytest.mark.long
def test_an_avatar_moving_as_another_style_is_distinguishable() -> None:
    trials = {t.label: t for t in load_zhai2017()}
    person = [trials[f"fast-{k}"] for k in (1, 2, 3, 4)]
    slow = [trial_velocity(trials[f"slow-{k}"], RATE) for k in range(1, 7)]
    fast = [trial_velocity(trials[f"fast-{k}"], RATE) for k in (5, 6, 7, 9)]
    motion = {"leader": RoleMotion(slow, slow), "follower": RoleMotion(fast, fast)}
    folds = [Fold(person[:2], motion), Fold(person[2:], motion)]
    proof = prove_held_out(person, folds, RATE, seed=4)
    leader, follower = proof.likeness["leader"], proof.likeness["follower"]
    assert leader.seed == 4
    assert leader.classifier is not None and leader.classifier.auc > 0.9
    assert leader.distinguishable
    assert leader.distances[0].ratio > 2  # the IMS EMD to the held-out trials, x the person's
    assert follower.distances[0].ratio < 1.5
    assert proof.to_json_dict()["likeness"]["leader"]["verdict"] == leader.verdict()
    assert proof.scheme() == "2 folds over 4 trials"
    assert "2 more avatars, each built the same way without a fold" in proof.explain_scheme()
    tables = Proof(proof, None).tables()
    caption = next(c for c in tables if c.startswith("Human-likeness of the avatar in each role"))
    assert list(tables[caption].loc["leader"].index) == [
        "velocity IMS EMD",
        "amplitude (units)",
        "spectrum (Hz)",
        "classifier AUC (0.5 = chance)",
    ]

"""The avatar's held-out check carries the human-likeness battery (issue 38.2)."""

from __future__ import annotations

from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.experiments.avatar_proof import Proof, prove_held_out
from mirror_avatar.likeness import trial_velocity

RATE = 1 / 0.03  # the avatar's control rate


def test_an_avatar_moving_as_another_style_is_distinguishable() -> None:
    trials = {t.label: t for t in load_zhai2017()}
    fitted = [trials[f"fast-{k}"] for k in (1, 2, 3)]
    held_out = [trials["fast-4"], trials["fast-8"]]
    motion = {
        "played as leader": [trial_velocity(trials[f"slow-{k}"], RATE) for k in range(1, 7)],
        "played as follower": [trial_velocity(trials[f"fast-{k}"], RATE) for k in (5, 6, 7, 9)],
    }
    proof = prove_held_out(fitted, held_out, motion, RATE, seed=4)
    leader, follower = proof.likeness["played as leader"], proof.likeness["played as follower"]
    assert leader.seed == 4
    assert leader.classifier.auc > 0.9 and leader.distinguishable
    assert leader.distances[0].ratio > 2  # the IMS EMD to the held-out trials, x the person's
    assert follower.distances[0].ratio < 1.5
    assert proof.to_json_dict()["likeness"]["played as leader"]["verdict"] == leader.verdict()
    tables = Proof(proof, None, held_out).tables()
    caption = "Human-likeness of the avatar played as leader, against the held-out trials"
    assert list(tables[caption].index) == [
        "velocity IMS EMD",
        "amplitude (units)",
        "spectrum (Hz)",
        "classifier AUC (0.5 = chance)",
    ]

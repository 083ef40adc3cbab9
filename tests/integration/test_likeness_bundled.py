"""The classifier two-sample test on the bundled people (issue 38's must-show).

Held-out trials of one style against each other are indistinguishable (AUC near 0.5, p > 0.05);
fast against slow trials are told apart (AUC near 1).
"""

from __future__ import annotations

import pytest

from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.signatures.likeness import compare_motion, trial_velocity


@pytest.fixture(scope="module")
def styles() -> dict[str, list]:
    by_style: dict[str, list] = {}
    for trial in load_zhai2017():
        by_style.setdefault(trial.group, []).append(trial_velocity(trial))
    return by_style


@pytest.mark.long
@pytest.mark.parametrize("style", ["fast", "slow"])
def test_trials_of_one_style_are_indistinguishable(styles: dict[str, list], style: str) -> None:
    trials = styles[style]
    likeness = compare_motion(trials[::2], trials[1::2], seed=0)
    assert likeness.classifier.test.p_value > 0.05
    assert abs(likeness.classifier.auc - 0.5) < 0.25
    assert abs(likeness.classifier.test.null.mean() - 0.5) < 0.05
    assert not likeness.distinguishable
    assert likeness.verdict().startswith("indistinguishable at this data size")


@pytest.mark.long
def test_fast_and_slow_are_told_apart(styles: dict[str, list]) -> None:
    likeness = compare_motion(styles["fast"], styles["slow"], seed=0)
    assert likeness.classifier.auc > 0.95
    assert likeness.classifier.test.p_value < 0.01
    assert all(d.distinguishable for d in likeness.distances)
    assert likeness.verdict().startswith("distinguishable: classifier AUC 1.00")

"""Each trial put with its nearest person, against shuffled labels (issue 39.3, the signature's
verdict): hand-computed cases, a slow reference, and the bundled styles."""

from __future__ import annotations

import numpy as np
import pytest

from mirror_avatar.signatures.identification import identify_people
from mirror_avatar.signatures.signature import analyse_signatures


def slow_nearest(emd: np.ndarray, people: list[str]) -> list[str]:
    """The nearest person of each trial, by loops: mean distance to the person's other trials."""
    names = list(dict.fromkeys(people))
    nearest = []
    for i in range(len(people)):
        means = {}
        for name in names:
            others = [j for j, p in enumerate(people) if p == name and j != i]
            means[name] = np.mean([emd[i, j] for j in others]) if others else np.inf
        nearest.append(min(names, key=lambda name: means[name]))
    return nearest


def symmetric(upper: dict[tuple[int, int], float], m: int) -> np.ndarray:
    emd = np.zeros((m, m))
    for (i, j), value in upper.items():
        emd[i, j] = emd[j, i] = value
    return emd


def test_two_people_by_hand() -> None:
    """a0, a1 close (0.01), b0, b1 close (0.02), a-b far apart except a1-b0 (0.012): a1's mean
    to b is (0.012 + 0.09) / 2 = 0.051 > 0.01, so all four are put with their own person."""
    emd = symmetric({(0, 1): 0.01, (2, 3): 0.02, (0, 2): 0.08, (0, 3): 0.09, (1, 2): 0.012,
                     (1, 3): 0.09}, 4)  # fmt: skip
    result = identify_people(emd, ["a", "a", "b", "b"], shuffles=99)
    assert result is not None
    assert result.predicted == ["a", "a", "b", "b"] and result.rate == 1.0
    # shuffles fall on the 3 ways to pair 4 trials alike: the true pairs score 1; {a0 b0, a1 b1}
    # scores 0 (each trial nearer the other pair); {a0 b1, a1 b0} 0.5 (a1 and b0, 0.012 apart,
    # are right): chance (1 + 0 + 0.5) / 3
    assert result.chance == pytest.approx(0.5, abs=0.1)


def test_a_trial_nearer_another_person_is_put_with_them() -> None:
    """b1 is 0.01 from a's two trials and 0.05 from b0: it goes to a; b0 (0.08 from a) stays."""
    emd = symmetric({(0, 1): 0.01, (0, 2): 0.08, (1, 2): 0.08, (0, 3): 0.01, (1, 3): 0.01,
                     (2, 3): 0.05}, 4)  # fmt: skip
    result = identify_people(emd, ["a", "a", "b", "b"], shuffles=9)
    assert result is not None
    assert result.predicted == ["a", "a", "b", "a"] and result.rate == 0.75


def test_matches_the_slow_reference_and_skips_lone_trials(rng: np.random.Generator) -> None:
    points = rng.normal(size=(23, 3))
    emd = np.linalg.norm(points[:, None] - points[None], axis=2)
    people = [f"p{k % 6}" for k in range(22)] + ["alone"]
    result = identify_people(emd, people, shuffles=50)
    assert result is not None
    expected = slow_nearest(emd, people)[:22]
    assert result.predicted == expected and result.truth == people[:22]
    assert result.rate == pytest.approx(np.mean(np.array(expected) == np.array(people[:22])))
    assert "alone" in result.people and len(result.null) == 50


def test_no_identification_without_two_people_or_a_repeated_person() -> None:
    emd = symmetric({(0, 1): 0.1, (0, 2): 0.1, (1, 2): 0.1}, 3)
    assert identify_people(emd, ["a", "a", "a"]) is None
    assert identify_people(emd, ["a", "b", "c"]) is None


def test_bundled_styles_are_told_apart_and_shuffled_ones_are_not(zhai_trials) -> None:
    analysis = analyse_signatures(zhai_trials)
    result = identify_people(analysis.emd, analysis.groups, seed=1)
    assert result is not None and result.told_apart
    assert result.rate == 1.0 and result.p_value == pytest.approx(1 / 1000)
    assert 0.4 < result.chance < 0.65
    assert result.verdict().startswith("The 2 people are told apart: 18 of 18 trials (100%)")
    assert "p <= 0.001" in result.verdict()
    mixed = list(np.random.default_rng(3).permutation(analysis.groups))
    shuffled = identify_people(analysis.emd, mixed, seed=1)
    assert shuffled is not None and not shuffled.told_apart
    assert "not told apart at this data size" in shuffled.verdict()

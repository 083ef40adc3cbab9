"""Transfer entropy: pyinform against a slow hand-written plug-in estimator, and its direction."""

from __future__ import annotations

import numpy as np
import pyinform
import pytest

from mirror_avatar.metrics.transfer_entropy import discretise, phases, transfer_entropy
from mirror_avatar.testing import plug_in_transfer_entropy as plug_in_te
from mirror_avatar.testing import swapped_roles

RATE = 50.0


@pytest.mark.parametrize("k", [1, 2, 3])
def test_pyinform_matches_the_plug_in_estimator(rng, k):
    source = rng.integers(0, 3, size=(3, 60))
    target = np.roll(source, 1, axis=1) ^ (rng.random((3, 60)) < 0.3)
    assert pyinform.transfer_entropy(source, target, k=k) == pytest.approx(
        plug_in_te(source, target, k), abs=1e-10
    )


def test_a_hand_computed_case():
    """Target copies the source one step later: TE = H(y_{t+1} | y_t) of a fair coin = 1 bit."""
    source = np.array([0, 1, 1, 0, 1, 0, 0, 1, 1, 1, 0, 0, 0, 1, 0, 1, 1])
    target = np.concatenate(([0], source[:-1]))
    assert plug_in_te(source, target, 1) == pytest.approx(
        pyinform.transfer_entropy(source, target, 1)
    )
    assert plug_in_te(np.zeros(8, int), np.arange(8) % 2, 1) == 0.0


def test_the_estimator_on_velocities_is_pyinform_on_the_binned_phases(rng):
    v0, v1 = rng.normal(size=1000), rng.normal(size=1000)
    expected = plug_in_te(phases(discretise(v0, 3), 5), phases(discretise(v1, 3), 5), 2)
    assert transfer_entropy(v0, v1, 50.0, history=2, bins=3, step=0.1) == pytest.approx(
        expected, abs=1e-10
    )


def test_bins_are_equiprobable(rng):
    states = discretise(rng.normal(size=1000), 4)
    np.testing.assert_array_equal(np.bincount(states), [250, 250, 250, 250])


def test_transfer_entropy_is_larger_from_leader_to_follower(rng):
    n = 3000
    x0, x1 = swapped_roles(rng, n, 10, RATE)
    v0, v1 = np.gradient(x0) * RATE, np.gradient(x1) * RATE
    first, second = slice(0, n // 2), slice(n // 2, n)
    assert transfer_entropy(v0[first], v1[first], RATE) > 2 * transfer_entropy(
        v1[first], v0[first], RATE
    )
    assert transfer_entropy(v1[second], v0[second], RATE) > 2 * transfer_entropy(
        v0[second], v1[second], RATE
    )

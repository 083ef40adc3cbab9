"""Motion between two people: the two methods of a curriculum stage against independent truth."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import wasserstein_distance

from mirror_avatar.common.errors import InputError
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.training.curriculum import QUANTILE_SECONDS, QUANTILE_SEED, StageMotion


@pytest.fixture(scope="module")
def people(zhai_trials_100hz: list) -> tuple[IMSGenerator, IMSGenerator]:
    """A slow patient and a fast target."""
    slow = IMSGenerator(n_symbols=32, random_state=0).fit(zhai_trials_100hz[9:13])
    fast = IMSGenerator(n_symbols=32, random_state=0).fit(zhai_trials_100hz[:4])
    return slow, fast


def test_displacement_at_zero_is_the_patient(people) -> None:
    patient, target = people
    stage = StageMotion(patient, target, 0.0, "displacement")
    np.testing.assert_allclose(stage.sample_velocity(3000, 5), patient.sample_velocity(3000, 5))


@pytest.mark.parametrize("weight", [0.25, 0.5, 0.75, 1.0])
def test_displacement_moves_linearly_in_wasserstein_distance(people, weight) -> None:
    """1-D Wasserstein distance is linear along displacement interpolation (scipy as oracle):
    W(patient, stage_w) = w W(patient, target) and W(stage_w, target) = (1 - w) W. The people
    are the draws the quantile functions were estimated from (seed 0, 600 s)."""
    patient, target = people
    n = int(QUANTILE_SECONDS * patient.rate)
    p, t = patient.sample_velocity(n, QUANTILE_SEED), target.sample_velocity(n, QUANTILE_SEED)
    stage = StageMotion(patient, target, weight, "displacement").sample_velocity(n, QUANTILE_SEED)
    total = wasserstein_distance(p, t)
    assert wasserstein_distance(p, stage) == pytest.approx(weight * total, rel=0.01)
    assert wasserstein_distance(stage, t) == pytest.approx((1 - weight) * total, abs=0.01 * total)


def test_a_mixture_draws_whole_blocks_from_either_person(people) -> None:
    patient, target = people
    for weight, person in ((0.0, patient), (1.0, target)):
        stage = StageMotion(patient, target, weight, "mixture").sample_velocity(100, 3)
        rng = np.random.default_rng(3)
        rng.random()  # the draw that chose the block's person
        assert np.array_equal(stage, person.sample_velocity(500, rng)[:100])


@pytest.mark.parametrize(
    ("weight", "method", "message"),
    [(1.5, "mixture", "outside"), (0.5, "blend", "not one of")],
)
def test_bad_stages_are_refused(people, weight, method, message) -> None:
    with pytest.raises(InputError, match=message):
        StageMotion(*people, weight, method)

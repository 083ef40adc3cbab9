"""Seeds spawned in compiled code against `numpy.random.SeedSequence` itself."""

from __future__ import annotations

import numpy as np
import pytest

from mirror_avatar.common.seeds import spawn_seeds

SEEDS = [0, 1, 7, 2**32 - 1, 2**32, 2**63 + 11, 2**64 - 1, 2**96 + 5, 2**128 - 1, 2**160 + 3]


def numpy_spawn(seed: int | list[int], n: int, bits: int) -> np.ndarray:
    dtype = np.uint32 if bits == 32 else np.uint64
    children = np.random.SeedSequence(seed).spawn(n)
    return np.array([c.generate_state(1, dtype)[0] for c in children], dtype=np.uint64)


@pytest.mark.parametrize("bits", [32, 64])
@pytest.mark.parametrize("seed", SEEDS)
def test_spawned_seeds_equal_numpys(seed: int, bits: int) -> None:
    np.testing.assert_array_equal(spawn_seeds(seed, 9, bits), numpy_spawn(seed, 9, bits))


def test_random_seeds_and_numpy_integers_equal_numpys() -> None:
    for seed in np.random.default_rng(0).integers(0, 2**63, 50, dtype=np.int64):
        np.testing.assert_array_equal(spawn_seeds(seed, 3), numpy_spawn(int(seed), 3, 32))
        np.testing.assert_array_equal(
            spawn_seeds(np.uint64(seed), 3, 64), numpy_spawn(int(seed), 3, 64)
        )


def test_child_seeds_do_not_depend_on_how_many_are_spawned() -> None:
    np.testing.assert_array_equal(spawn_seeds(5, 1000, 64)[:10], spawn_seeds(5, 10, 64))


def test_sequence_seeds_still_go_through_numpy() -> None:
    np.testing.assert_array_equal(spawn_seeds([3, 4], 5), numpy_spawn([3, 4], 5, 32))

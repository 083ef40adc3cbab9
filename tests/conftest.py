"""Shared fixtures (a seeded random generator, the bundled real trials) and the kernels' warm-up."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import settings

from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.files.trials import Trial
from mirror_avatar.warm_up import warm_up

# Property tests without a time limit per example (a busy machine is not a failure), with examples
# drawn from each test's name (every run tries the same ones) and no example database between runs.
settings.register_profile("any_machine", deadline=None, derandomize=True, database=None)
settings.load_profile("any_machine")


def pytest_configure(config: pytest.Config) -> None:
    """Compile the kernels (`mirror_avatar.warm_up`) in this process before any worker starts.

    numba's on-disk cache is not safe against several processes writing it at once (numba
    issue 4807: a process can load one process's index with another's code and crash). With
    ``-n``, the test workers and the command-line tests' child processes would otherwise all
    compile the same kernels on a fresh checkout and write them side by side; compiled here
    first (or already by ``make``'s install), they only read the cache.
    """
    if hasattr(config, "workerinput"):  # a worker of pytest-xdist: the controller compiled
        return
    warm_up()


SLOW_TIMEOUT = 1800
"""Deadline (s) of a test marked slow (minutes of work; the others have pyproject's)."""


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Give each test marked slow, unless it sets its own, the longer `SLOW_TIMEOUT`."""
    for item in items:
        if item.get_closest_marker("slow") and not item.get_closest_marker("timeout"):
            item.add_marker(pytest.mark.timeout(SLOW_TIMEOUT))


@pytest.fixture
def rng() -> np.random.Generator:
    """A random generator with a fixed seed, new for each test."""
    return np.random.default_rng(20181010)


@pytest.fixture(scope="session")
def zhai_trials() -> list[Trial]:
    """The 18 bundled real solo trials at their native rate."""
    return load_zhai2017()


@pytest.fixture(scope="session")
def zhai_trials_100hz(zhai_trials: list[Trial]) -> list[Trial]:
    """The bundled trials resampled to 100 Hz."""
    return [trial.resampled(100.0) for trial in zhai_trials]

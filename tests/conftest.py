"""Shared fixtures (a seeded random generator, the bundled real trials) and the kernels' warm-up."""

from __future__ import annotations

import numpy as np
import pytest

from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.dynamics import FOLLOWER, LEADER
from mirror_avatar.engine.batch import run_sessions
from mirror_avatar.engine.loop import play
from mirror_avatar.generator import IMSGenerator
from mirror_avatar.players import VirtualTrainer
from mirror_avatar.training.imitation import train_cyber_player, train_group_cyber_player
from mirror_avatar.trials import Trial


def pytest_configure(config: pytest.Config) -> None:
    """Compile the main kernels in this process before any test worker starts.

    numba's on-disk cache is not safe against several processes writing it at once (numba
    issue 4807: a process can load one process's index with another's code and crash). With
    ``-n``, the test workers and the command-line tests' child processes would otherwise all
    compile the same kernels on a fresh checkout and write them side by side; compiled here
    first, they only read the cache.
    """
    if hasattr(config, "workerinput"):  # a worker of pytest-xdist: the controller compiled
        return
    trials = [t.resampled(100.0) for t in load_zhai2017()[:2]]
    motion = IMSGenerator(n_symbols=8, random_state=0).fit(trials)
    pair = [VirtualTrainer(LEADER, motion), VirtualTrainer(FOLLOWER, motion)]
    play(pair, duration=1.0, seed=0)
    for _ in run_sessions([pair], 2, duration=1.0, n_jobs=1, progress=False):
        pass
    for agent in ("tabular", "dqn"):
        train_cyber_player(motion, [motion], n_sessions=2, duration=1.0, n_jobs=1, agent=agent)
        train_group_cyber_player(
            motion, [motion] * 2, n_sessions=2, duration=1.0, n_jobs=1, agent=agent
        )


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

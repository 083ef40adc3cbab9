"""Shared fixtures: a seeded random generator and the bundled real trials."""

from __future__ import annotations

import numpy as np
import pytest

from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.trials import Trial


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

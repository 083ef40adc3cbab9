"""Surrogates in bounded memory: each is drawn, measured and dropped in turn.

Peak memory (tracemalloc, which counts NumPy's arrays) of a session's measures with 10 and with
100 circular-shift surrogates: the second may not grow by more than a few surrogates' worth, as
it did when every surrogate session was held at once.
"""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from mirror_avatar.common.constraints import ConstraintError
from mirror_avatar.metrics.measures import MAX_SURROGATES, MeasureOptions, session_measures
from mirror_avatar.sessions.session import Session
from mirror_avatar.testing import smooth_motion

RATE = 50.0
N_SAMPLES = 6000


def pair(rng: np.random.Generator) -> Session:
    s = smooth_motion(rng, N_SAMPLES + 10, RATE)
    x = np.array([s[10:], s[:-10]])
    v = np.gradient(x, 1 / RATE, axis=1)
    nan = np.full_like(x, np.nan)
    return Session(np.arange(N_SAMPLES) / RATE, x, v, nan, nan)


def peak_bytes(session: Session, n_surrogates: int) -> int:
    options = MeasureOptions(n_surrogates=n_surrogates)
    tracemalloc.start()
    try:
        found = session_measures(session, options=options)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert found.values["surrogates"]["n"] == n_surrogates
    return peak


@pytest.mark.long
def test_the_memory_of_surrogates_does_not_grow_with_their_number(rng):
    session = pair(rng)
    one_surrogate = 2 * session.positions.nbytes  # its positions and velocities
    few, many = peak_bytes(session, 10), peak_bytes(session, 100)
    assert many - few < 5 * one_surrogate, (few, many, one_surrogate)


def test_more_surrogates_than_the_bound_are_refused():
    MeasureOptions(n_surrogates=MAX_SURROGATES)
    with pytest.raises(ConstraintError, match=r"n_surrogates: 1000000000 is not allowed"):
        MeasureOptions(n_surrogates=10**9)

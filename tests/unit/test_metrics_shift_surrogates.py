"""A pair's circular-shift surrogates measured together equal each one measured in turn.

`mirror_avatar.metrics.measures.session_measures` measures a pair's shift surrogates a chunk at a
time; the reference is the one-at-a-time path it replaced and still takes for groups and
pseudo-pairs: each surrogate session drawn (`shifted`) and measured alone
(`coordination_statistics`). The study table's p-values are checked against it too, and the
direct cross-correlation against scipy's.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import signal
from test_study_table_plain import record_session

from mirror_avatar.analysis.table import study_table, table_of_rows, trial_rows
from mirror_avatar.analysis.trials import StudyTrial, read_study_trials
from mirror_avatar.metrics.coordination import compute_cross_correlation_peak
from mirror_avatar.metrics.measures import (
    SHIFT_SAMPLES,
    MeasureOptions,
    coordination_statistics,
    session_measures,
)
from mirror_avatar.metrics.measuring import TRIAL_SURROGATES, measure_trial, surrogate_seed
from mirror_avatar.metrics.quantities import Quantities
from mirror_avatar.metrics.registry import measures_tested, p_value_key
from mirror_avatar.metrics.surrogates import p_value, shift_offsets, shifted
from mirror_avatar.sessions.session import Session
from mirror_avatar.testing import smooth_motion

RATE = 25.0


def pair(rng: np.random.Generator, n: int, delay: int = 10) -> Session:
    """Player 1 repeats player 0's smooth motion ``delay`` samples later, with a little noise."""
    s = smooth_motion(rng, n + delay, RATE)
    x = np.array([s[delay:], s[:-delay] + 0.05 * smooth_motion(rng, n, RATE, cutoff=3.0)])
    v = np.gradient(x, 1 / RATE, axis=1)
    nan = np.full_like(x, np.nan)
    return Session(np.arange(n) / RATE, x, v, nan, nan)


def one_at_a_time(session: Session, options: MeasureOptions) -> dict[str, np.ndarray]:
    """The reference: each surrogate drawn as `session_measures` draws it, measured alone."""
    q = Quantities.of(session)
    rng = np.random.default_rng(options.seed)
    shift = round(options.min_shift * q.rate)
    offsets = shift_offsets(session.n_samples, 2, options.n_surrogates, shift, rng)
    draws = [
        coordination_statistics(shifted(q.positions, k), shifted(q.velocities, k), q.rate, options)
        for k in offsets
    ]
    return {name: np.array([d[name] for d in draws]) for name in measures_tested(2)}


@pytest.mark.parametrize(
    ("n", "options"),
    [
        (500, MeasureOptions(n_surrogates=19, seed=3)),
        (500, MeasureOptions(n_surrogates=7, seed=4, lead_signal="position", lead_window=3.0)),
        (120, MeasureOptions(n_surrogates=9, seed=5, min_shift=1.0)),  # no leadership window
        (3 * SHIFT_SAMPLES // 25, MeasureOptions(n_surrogates=25, seed=6)),  # chunks of 8
    ],
)
def test_shift_surrogates_measured_together_equal_each_measured_alone(rng, n, options):
    session = pair(rng, n)
    found = session_measures(session, options=options)
    reference = one_at_a_time(session, options)
    assert found.null.keys() == reference.keys()
    for name, null in reference.items():
        assert found.null[name].shape == (options.n_surrogates,)
        np.testing.assert_allclose(found.null[name], null, rtol=1e-12, atol=1e-12, err_msg=name)
    if n == 120:
        assert np.isnan(found.null["leadership_strength"]).all()


def test_the_cross_correlation_peak_is_scipys_within_the_lags(rng):
    """Against `scipy.signal.correlate` of the whole series, restricted to +-max_lag."""
    a, b = smooth_motion(rng, 300, RATE), smooth_motion(rng, 300, RATE) + 2.0
    for max_lag in (0.0, 0.5, 1.5, 100.0):
        ca, cb = a - a.mean(), b - b.mean()
        corr = signal.correlate(cb, ca) / np.sqrt(np.sum(ca**2) * np.sum(cb**2))
        lags = signal.correlation_lags(cb.size, ca.size)
        keep = np.abs(lags) <= round(max_lag * RATE)
        best = np.argmax(corr[keep])
        lag, value = compute_cross_correlation_peak(a, b, RATE, max_lag)
        assert lag == lags[keep][best] / RATE
        assert value == pytest.approx(corr[keep][best], rel=1e-12)


DYAD = {
    "condition": "joint", "duration": 8.0, "trials": 3, "seed": 7,
    "players": [{"label": "P1", "kind": "human"}, {"label": "P2", "kind": "human"}],
}  # fmt: skip


@pytest.fixture(scope="module")
def dyad_session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Three 8 s trials of two people, recorded as the lab records them."""
    return record_session(tmp_path_factory.mktemp("lab") / "20261130T010203-001", DYAD, 3)


def reference_measures(trial: StudyTrial) -> dict[str, object]:
    """A trial's measures with each p-value from its surrogates measured one at a time."""
    measured = measure_trial(trial.session, TRIAL_SURROGATES)
    assert measured is not None
    values = measured.measures.values
    options = MeasureOptions(n_surrogates=TRIAL_SURROGATES, seed=surrogate_seed(trial.session, -1))
    nulls = one_at_a_time(measured.session, options)
    p_values = {
        p_value_key(name): p_value(values[name], nulls[name], greater)
        for name, greater in measures_tested(2).items()
    }
    return measured.metrics | values | p_values


def test_the_study_tables_p_values_are_those_of_surrogates_measured_alone(dyad_session):
    """The table's numbers within 1e-9 (relative) of the reference's, its text the same."""
    trials = read_study_trials([dyad_session])
    table = study_table(trials)
    reference = table_of_rows(
        [row for t in trials for row in trial_rows(t, reference_measures(t), {})], {}
    )
    assert list(table.columns) == list(reference.columns)
    assert any(c.endswith("_p_value") for c in table.columns)
    for column in table.columns:
        if pd.api.types.is_float_dtype(table[column]):
            np.testing.assert_allclose(
                table[column], reference[column], rtol=1e-9, atol=0, err_msg=column
            )
        else:
            pd.testing.assert_series_equal(table[column], reference[column])

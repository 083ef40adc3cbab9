"""Tests of the coordination metrics against constructed signals with known answers."""

import numpy as np
import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.metrics import (
    compute_cross_correlation_peak,
    compute_mean_relative_phase,
    compute_phase,
    compute_phase_locking,
    compute_relative_phase,
    compute_rmse,
    compute_time_lag,
    paired_ttest,
    session_metrics,
)
from mirror_avatar.sessions.session import Session
from mirror_avatar.signatures.signature import DEFAULT_BINS

RATE = 100.0
T = np.arange(0, 30, 1 / RATE)


def test_rmse_constant_offset():
    x = np.sin(T)
    assert compute_rmse(x + 0.3, x) == pytest.approx(0.3)


def test_hilbert_phase_of_a_sine_shift():
    shift = 0.7
    x1 = np.sin(2 * np.pi * 0.5 * T + shift)
    x2 = np.sin(2 * np.pi * 0.5 * T)
    dphi = compute_relative_phase(x1, x2)[200:-200]
    assert compute_mean_relative_phase(dphi) == pytest.approx(shift, abs=1e-2)
    assert compute_phase_locking(dphi) == pytest.approx(1.0, abs=1e-3)


def modulated(phase: np.ndarray, depth: float = 0.8) -> np.ndarray:
    """An oscillation whose protophase is ``phase + depth sin(phase)``: not uniform in time."""
    return np.cos(phase + depth * np.sin(phase))


def test_kralemann_recovers_the_true_phase_from_a_non_uniform_protophase():
    """Kralemann et al. 2008: the true phase grows uniformly; the Hilbert protophase does not."""
    true_phase = 2 * np.pi * 0.5 * T
    x = modulated(true_phase)
    inner = slice(300, -300)
    protophase = compute_phase(x)[inner] - true_phase[inner]
    phase = compute_phase(x, method="kralemann")[inner] - true_phase[inner]
    assert np.std(protophase) > 0.2
    assert np.std(phase) < 1e-4
    shift = 0.9
    both = [modulated(true_phase + shift), x]
    hilbert = compute_relative_phase(*both)[inner]
    kralemann = compute_relative_phase(*both, method="kralemann")[inner]
    assert compute_phase_locking(hilbert) < 0.98
    assert compute_phase_locking(kralemann) > 0.9999
    assert compute_mean_relative_phase(kralemann) == pytest.approx(shift, abs=1e-6)


def test_uniform_phases_cv_near_zero(rng):
    assert compute_phase_locking(rng.uniform(-np.pi, np.pi, 20000)) < 0.03


def test_cross_correlation_peak_of_a_scaled_delayed_copy():
    x1 = np.sin(2 * np.pi * 0.3 * T) + 0.5 * np.sin(2 * np.pi * 0.77 * T)
    lag, peak = compute_cross_correlation_peak(x1, 3.0 * np.roll(x1, 10) + 1.0, RATE)
    assert lag == pytest.approx(0.1) and peak == pytest.approx(1.0, abs=0.02)
    _, opposite = compute_cross_correlation_peak(x1, -x1, RATE, max_lag=0.0)
    assert opposite == pytest.approx(-1.0)


def test_time_lag_sign():
    x1 = np.sin(2 * np.pi * 0.3 * T) + 0.5 * np.sin(2 * np.pi * 0.77 * T)
    delay = 25  # samples: x2 follows x1 by 0.25 s
    x2 = np.roll(x1, delay)
    assert compute_time_lag(x1, x2, RATE) == pytest.approx(0.25)
    assert compute_time_lag(x2, x1, RATE) == pytest.approx(-0.25)
    assert compute_mean_relative_phase(compute_relative_phase(x1, x2)) > 0


def test_paired_ttest_by_hand():
    a = np.array([1.0, 2.0, 3.0, 4.0, 6.0])
    b = np.array([1.5, 1.0, 2.0, 3.0, 4.0])
    d = a - b
    t = d.mean() / (d.std(ddof=1) / np.sqrt(d.size))
    res = paired_ttest(a, b)
    assert res.t == pytest.approx(t) and res.df == 4
    assert str(res).startswith("t(4) = ")


def test_bad_input():
    with pytest.raises(InputError):
        compute_rmse([1.0, 2.0], [1.0])
    with pytest.raises(InputError):
        compute_relative_phase(T, T, method="nope")


def test_session_metrics_on_two_sinusoids():
    x = np.stack([np.sin(2 * np.pi * 0.5 * T + 0.4), np.sin(2 * np.pi * 0.5 * T)])
    v = np.gradient(x, 1 / RATE, axis=1)
    references = np.stack([v[0], np.full(T.size, np.nan)])
    session = Session(T, x, v, np.full_like(x, np.nan), references)
    m = session_metrics(session, trim=2.0)
    assert m["phase_locking"] == pytest.approx(1.0, abs=1e-3)
    assert m["mean_relative_phase"] == pytest.approx(0.4, abs=2e-2)
    assert m["time_lag"] == pytest.approx(0.4 / (2 * np.pi * 0.5), abs=0.011)
    assert m["emd_players"] == pytest.approx(0.0, abs=1e-2)
    assert m["emd_reference_0"] == pytest.approx(0.0, abs=1e-12)
    assert m["emd_reference_1"] is None


def test_session_emd_to_reference_is_the_shift_of_the_velocities():
    x = np.stack([0.3 * np.sin(2 * np.pi * 0.5 * T), 0.3 * np.sin(2 * np.pi * 0.5 * T + 1.0)])
    v = np.gradient(x, 1 / RATE, axis=1)
    shift = 0.25
    references = v + shift
    references[:, -1] = np.nan
    session = Session(T, x, v, np.full_like(x, np.nan), references)
    m = session_metrics(session)
    bins = DEFAULT_BINS
    expected = shift / (bins.hi - bins.lo)
    for key in ("emd_reference_0", "emd_reference_1"):
        assert m[key] == pytest.approx(expected, abs=bins.width / (bins.hi - bins.lo))


def test_a_player_that_does_not_move_has_no_phase():
    x = np.stack([np.sin(2 * np.pi * 0.5 * T), np.zeros(T.size)])
    v = np.gradient(x, 1 / RATE, axis=1)
    nan = np.full_like(x, np.nan)
    m = session_metrics(Session(T, x, v, nan, nan))
    assert np.isnan(m["phase_locking"]) and np.isnan(m["time_lag"])
    assert m["rmse"] == pytest.approx(np.sqrt(0.5), rel=1e-3)


def test_a_solo_session_has_its_reference_distance_only():
    x = 0.3 * np.sin(2 * np.pi * 0.5 * T)[None]
    v = np.gradient(x, 1 / RATE, axis=1)
    assert session_metrics(Session(T, x, v, np.full_like(x, np.nan), v)) == {
        "emd_reference_0": pytest.approx(0.0, abs=1e-12)
    }

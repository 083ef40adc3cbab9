import numpy as np
import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.trials import compute_velocity, finite_difference, make_trial, resample


def test_finite_difference_is_exact_on_a_cubic():
    t = np.linspace(-1.0, 2.0, 31)
    x = 2 * t**3 - t**2 + 0.5 * t - 3
    exact = 6 * t**2 - 2 * t + 0.5
    np.testing.assert_allclose(finite_difference(x, t[1] - t[0]), exact, atol=1e-10)


def test_finite_difference_is_exact_on_a_quartic_at_the_ends():
    t = np.linspace(0.0, 1.0, 11)
    np.testing.assert_allclose(finite_difference(t**4, t[1] - t[0]), 4 * t**3, atol=1e-10)


def test_velocity_of_a_sinusoid(rng):
    rate = 100.0
    t = np.arange(0, 20, 1 / rate)
    x = 0.3 * np.sin(2 * np.pi * 0.8 * t)
    v = compute_velocity(x, rate)
    exact = 0.3 * 2 * np.pi * 0.8 * np.cos(2 * np.pi * 0.8 * t)
    np.testing.assert_allclose(v[50:-50], exact[50:-50], atol=2e-3)


def test_resample_irregular_onto_uniform_grid(rng):
    t = np.cumsum(rng.uniform(0.03, 0.18, size=400))
    trial = make_trial(t, 0.4 * np.sin(t), label="jitter")
    uniform = resample(trial, 100.0)
    assert uniform.is_uniform
    assert uniform.rate == pytest.approx(100.0)
    np.testing.assert_allclose(uniform.positions, 0.4 * np.sin(uniform.times), atol=2e-3)


def test_flat_runs_are_valid():
    x = np.r_[np.linspace(0, 0.2, 30), np.full(40, 0.2), np.linspace(0.2, -0.1, 30)]
    trial = make_trial(np.arange(100) / 10, x)
    assert trial.n_samples == 100


@pytest.mark.parametrize(
    ("times", "positions", "problem"),
    [
        (np.arange(10) / 10, np.zeros(10), "only 10 samples"),
        (np.arange(50) / 10, np.r_[np.zeros(49), np.nan], "NaN"),
        (np.r_[np.arange(25), np.arange(25)] / 10, np.zeros(50), "does not increase"),
        (np.arange(50) * 1000.0, np.zeros(50), "sampling rate"),
        (np.arange(50) / 10, np.full(50, 250.0), "normalised"),
    ],
)
def test_bad_samples_raise_one_line_naming_the_source(times, positions, problem):
    with pytest.raises(InputError, match=problem) as caught:
        make_trial(times, positions, source="trial.csv")
    assert str(caught.value).startswith("trial.csv: ")
    assert "\n" not in str(caught.value)

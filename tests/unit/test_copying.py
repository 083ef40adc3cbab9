"""The data-copying test (Meehan, Chaudhuri & Dasgupta 2020) on motion of known origin."""

from __future__ import annotations

import json

import numpy as np
import pytest
import scipy.signal
import scipy.stats

from mirror_avatar.common.errors import InputError
from mirror_avatar.signatures.copying import (
    THRESHOLD,
    copying_test,
    mann_whitney_z,
    motion_windows,
)

RATE = 100.0
TRIALS = 4  # of each set: 4 x 59 = 236 held-out and generated windows, 5 cells


def _velocity(
    rng: np.random.Generator, cutoff: float = 1.0, rms: float = 0.5, seconds: float = 60.0
) -> np.ndarray:
    """Velocity (units/s): Gaussian noise low-passed at ``cutoff`` Hz, scaled to ``rms``."""
    n = round(seconds * RATE)
    sos = scipy.signal.butter(4, cutoff, fs=RATE, output="sos")
    velocity = scipy.signal.sosfiltfilt(sos, rng.normal(size=n + 400))[200:-200]
    return velocity * rms / velocity.std()


def _sets(rng: np.random.Generator) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Training and held-out trials: independent draws of one process."""
    return [_velocity(rng) for _ in range(TRIALS)], [_velocity(rng) for _ in range(TRIALS)]


def test_windows_of_a_minute() -> None:
    t = np.arange(round(60 * RATE)) / RATE
    velocity = np.sin(2 * np.pi * 0.5 * t) + np.sin(2 * np.pi * 7.0 * t)
    windows = motion_windows(velocity, RATE)
    assert windows.shape == (59, 20)
    # the 7 Hz part is filtered out before decimation; the 0.5 Hz part is kept, sampled at
    # 10 Hz from the first sample, each window a second after the one before
    window_t = 1.0 * np.arange(59)[:, None] + 0.1 * np.arange(20)[None, :]
    middle = slice(5, 54)  # away from the filter's edges
    expected = np.sin(2 * np.pi * 0.5 * window_t)
    assert np.abs(windows[middle] - expected[middle]).max() < 0.02
    assert motion_windows(velocity[:150], RATE).shape == (0, 20)
    assert motion_windows(velocity, RATE, hop=0.1).shape == (581, 20)


def test_copied_training_windows_are_data_copying(rng: np.random.Generator) -> None:
    training, held_out = _sets(rng)
    generated = [v + rng.normal(0.0, 0.01, v.size) for v in training]
    result = copying_test(training, held_out, generated, seed=1)
    # every cell at its most negative: all generated distances below all held-out ones
    assert result.c_t < -7.0
    assert result.copying
    assert result.distance_ratio < 0.1
    assert result.verdict().startswith("data-copying: C_T = -")


def test_copy_shifted_off_the_hop_is_still_found(rng: np.random.Generator) -> None:
    # a copy starting 0.35 s into each training trial: its windows fall between the 1 s hops,
    # and only the training windows taken every 0.1 s sit near them
    training, held_out = _sets(rng)
    generated = [np.roll(v, 35) + rng.normal(0.0, 0.01, v.size) for v in training]
    result = copying_test(training, held_out, generated, seed=1)
    assert result.c_t < -5.0
    assert result.copying


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_fresh_draws_of_the_process_are_not_copying(seed: int) -> None:
    rng = np.random.default_rng(seed)
    training, held_out = _sets(rng)
    generated = [_velocity(rng) for _ in range(TRIALS)]
    result = copying_test(training, held_out, generated, seed=seed)
    # over 60 seeds C_T had SD 0.45 and |C_T| at most 1.1 (the cells' weighted mean of
    # about-standard-normal Z scores is narrower than N(0, 1))
    assert abs(result.c_t) < 1.5
    assert not result.copying
    assert result.cells_used == result.n_cells == 5
    assert 0.8 < result.distance_ratio < 1.25


def test_a_different_process_sits_farther_than_fresh_motion(rng: np.random.Generator) -> None:
    training, held_out = _sets(rng)
    generated = [_velocity(rng, cutoff=2.0) for _ in range(TRIALS)]  # faster motion
    result = copying_test(training, held_out, generated)
    assert result.c_t > 3.0
    assert not result.copying
    assert result.distance_ratio > 1.5
    assert result.verdict().startswith("no data-copying: C_T = ")
    assert "no closer to the training trials" in result.verdict()


def test_z_matches_scipy_mann_whitney(rng: np.random.Generator) -> None:
    generated = rng.normal(0.0, 1.0, 37).round(1)  # rounded: ties
    held_out = rng.normal(0.3, 1.0, 52).round(1)
    test = scipy.stats.mannwhitneyu(
        generated, held_out, alternative="less", method="asymptotic", use_continuity=False
    )
    assert mann_whitney_z(generated, held_out) == pytest.approx(scipy.stats.norm.ppf(test.pvalue))


def test_one_cell_is_scipys_mann_whitney_on_brute_force_distances(
    rng: np.random.Generator,
) -> None:
    training, held_out = _sets(rng)
    generated = [_velocity(rng) for _ in range(TRIALS)]
    result = copying_test(training, held_out, generated, n_cells=1)
    train = np.concatenate([motion_windows(v, RATE, hop=0.1) for v in training])

    def nearest(signals: list[np.ndarray]) -> np.ndarray:
        windows = np.concatenate([motion_windows(v, RATE) for v in signals])
        return np.sqrt(((windows[:, None, :] - train[None, :, :]) ** 2).mean(axis=2)).min(axis=1)

    ours, fresh = nearest(generated), nearest(held_out)
    test = scipy.stats.mannwhitneyu(
        ours, fresh, alternative="less", method="asymptotic", use_continuity=False
    )
    z = scipy.stats.norm.ppf(test.pvalue)
    assert result.cell_z[0] == pytest.approx(z)
    assert result.c_t == pytest.approx(z)
    assert result.median_generated_distance == pytest.approx(np.median(ours))
    assert result.median_held_out_distance == pytest.approx(np.median(fresh))
    assert result.n_windows == (train.shape[0], 236, 236)


def test_verdict_and_json(rng: np.random.Generator) -> None:
    training, held_out = _sets(rng)
    generated = [_velocity(rng) for _ in range(TRIALS)]
    result = copying_test(training, held_out, generated, seed=3)
    line = result.verdict()
    assert line.startswith("no data-copying: C_T = ")
    assert f"median distance {result.distance_ratio:.2f} x)" in line
    assert "\n" not in line
    record = json.loads(json.dumps(result.to_json_dict(), allow_nan=False))
    assert set(record) == {
        "c_t",
        "copying",
        "threshold",
        "tau",
        "n_cells",
        "cells_used",
        "cell_z",
        "cell_held_out_mass",
        "cell_generated_mass",
        "cell_used",
        "median_held_out_distance",
        "median_generated_distance",
        "distance_ratio",
        "n_windows",
        "seed",
        "verdict",
    }
    assert record["c_t"] == pytest.approx(result.c_t)
    assert record["threshold"] == THRESHOLD
    assert record["tau"] == pytest.approx(20 / 236)
    assert record["copying"] is False
    assert record["verdict"] == line
    assert sum(record["cell_held_out_mass"]) == pytest.approx(1.0)
    assert record["n_windows"]["generated"] == 236
    assert record["seed"] == 3


def test_too_few_windows_is_an_input_error(rng: np.random.Generator) -> None:
    training, held_out = _sets(rng)
    with pytest.raises(InputError, match="fewer than the 20"):
        copying_test(training, held_out, [_velocity(rng, seconds=10.0)])
    with pytest.raises(InputError, match="no cell"):
        copying_test(training, held_out, [_velocity(rng, seconds=30.0)], n_cells=10)

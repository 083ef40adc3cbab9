"""Tests of the compiled Q-network against finite differences, NumPy and Adam's definition."""

import math

import numpy as np
import pytest

from mirror_avatar.deep.network import (
    HUBER_DELTA,
    adam_step,
    batch_q_values,
    count_parameters,
    greedy_action,
    initial_parameters,
    loss_gradient,
    q_values,
)

SIZES = np.array([7, 100, 50, 50, 9])


def numpy_values(params: np.ndarray, sizes: np.ndarray, inputs: np.ndarray) -> np.ndarray:
    """A plain NumPy forward pass over the same flat layout (weights row major, then biases)."""
    activation, start = inputs, 0
    for layer, (fan_in, fan_out) in enumerate(zip(sizes[:-1], sizes[1:], strict=True)):
        weights = params[start : start + fan_in * fan_out].reshape(fan_out, fan_in)
        biases = params[start + fan_in * fan_out : start + (fan_in + 1) * fan_out]
        start += (fan_in + 1) * fan_out
        activation = activation @ weights.T + biases
        if layer < len(sizes) - 2:
            activation = np.maximum(activation, 0.0)
    return activation


def huber(errors: np.ndarray) -> float:
    small = np.abs(errors) <= HUBER_DELTA
    quadratic = 0.5 * errors**2
    linear = HUBER_DELTA * (np.abs(errors) - 0.5 * HUBER_DELTA)
    return float(np.mean(np.where(small, quadratic, linear)))


@pytest.fixture
def batch(rng):
    params = initial_parameters(SIZES, rng)
    inputs = rng.normal(size=(32, SIZES[0]))
    actions = rng.integers(0, SIZES[-1], 32)
    targets = rng.normal(scale=2.0, size=32)  # errors on both sides of the Huber threshold
    return params, inputs, actions, targets


def test_parameter_count_and_initial_scale(rng) -> None:
    params = initial_parameters(SIZES, rng)
    assert params.size == count_parameters(SIZES) == 7 * 100 + 100 + 100 * 50 + 50 + 2550 + 459
    first = params[:700]
    assert np.all(np.abs(first) <= math.sqrt(6 / 7)) and first.std() > 0.4
    assert np.all(params[700:800] == 0.0)


def test_values_match_numpy(batch) -> None:
    params, inputs, _, _ = batch
    expected = numpy_values(params, SIZES, inputs)
    np.testing.assert_allclose(batch_q_values(params, SIZES, inputs), expected, rtol=1e-12)
    for row in range(4):
        np.testing.assert_allclose(q_values(params, SIZES, inputs[row]), expected[row], rtol=1e-12)
        assert greedy_action(params, SIZES, inputs[row]) == int(np.argmax(expected[row]))


def test_loss_is_the_mean_huber_loss(batch) -> None:
    params, inputs, actions, targets = batch
    chosen = numpy_values(params, SIZES, inputs)[np.arange(32), actions]
    gradient = np.empty_like(params)
    loss = loss_gradient(params, SIZES, inputs, actions, targets, gradient)
    assert np.abs(chosen - targets).max() > HUBER_DELTA > np.abs(chosen - targets).min()
    assert loss == pytest.approx(huber(chosen - targets), rel=1e-12)


def test_gradient_matches_central_differences(batch, rng) -> None:
    params, inputs, actions, targets = batch
    gradient = np.empty_like(params)
    loss_gradient(params, SIZES, inputs, actions, targets, gradient)
    scratch = np.empty_like(params)
    every_layer = [0, 699, 700, 799, 800, 5799, 5849, 8400, 8449, params.size - 1]
    picks = np.concatenate([every_layer, rng.choice(params.size, 60, replace=False)])
    for i in picks:
        step = 1e-6
        up, down = params.copy(), params.copy()
        up[i] += step
        down[i] -= step
        numeric = (
            loss_gradient(up, SIZES, inputs, actions, targets, scratch)
            - loss_gradient(down, SIZES, inputs, actions, targets, scratch)
        ) / (2 * step)
        assert gradient[i] == pytest.approx(numeric, abs=1e-8), i


def test_adam_follows_its_definition(rng) -> None:
    params = rng.normal(size=20)
    first, second = np.zeros(20), np.zeros(20)
    expected, m, v = params.copy(), np.zeros(20), np.zeros(20)
    for step in range(1, 6):
        gradient = rng.normal(size=20)
        adam_step(params, gradient, first, second, step, 0.01)
        m = 0.9 * m + 0.1 * gradient
        v = 0.999 * v + 0.001 * gradient**2
        expected -= 0.01 * (m / (1 - 0.9**step)) / (np.sqrt(v / (1 - 0.999**step)) + 1e-8)
        np.testing.assert_allclose(params, expected, rtol=1e-6, atol=1e-12)


def test_adam_fits_a_regression(rng) -> None:
    """Gradient steps on the loss drive Q(s, a) towards a fixed function of s (a sanity check)."""
    sizes = np.array([2, 16, 3])
    params = initial_parameters(sizes, rng)
    inputs = rng.uniform(-1, 1, (256, 2))
    actions = rng.integers(0, 3, 256)
    targets = np.sin(2 * inputs[:, 0]) + actions * inputs[:, 1]
    gradient, first, second = np.empty_like(params), np.zeros_like(params), np.zeros_like(params)
    start = loss_gradient(params, sizes, inputs, actions, targets, gradient)
    for step in range(1, 3001):
        loss_gradient(params, sizes, inputs, actions, targets, gradient)
        adam_step(params, gradient, first, second, step, 0.01)
    end = loss_gradient(params, sizes, inputs, actions, targets, gradient)
    assert end < 0.02 * start

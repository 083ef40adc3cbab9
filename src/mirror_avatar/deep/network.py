"""A small fully connected Q-network in compiled code: forward pass, Huber-loss gradient, Adam.

The network maps a feature vector to one value per action through ReLU hidden layers and a
linear output layer (METHODS section 8: hidden layers 100-50-50). All its parameters live in
one flat float64 vector, layer after layer, each layer's weights ``W`` (fan_out x fan_in, row
major) followed by its biases (fan_out,); ``sizes`` lists the widths from the input to the
output, for example ``[7, 100, 50, 50, 9]``. A flat vector is what the compiled session loop,
the replay learner and the model file all hold, so a network is two arrays and nothing else.

The minibatch loss is the mean Huber loss (threshold `HUBER_DELTA`) between the values of the
actions taken and their targets, as in DQN (Mnih et al. 2015); `loss_gradient` returns its exact
gradient (checked against finite differences and a NumPy reference in the tests) and
`adam_step` applies Adam (Kingma & Ba 2015) in place.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

Array = NDArray[np.float64]
Ints = NDArray[np.int64]

HUBER_DELTA = 1.0
"""Where the Huber loss turns from quadratic to linear (in units of the scaled Q values)."""

ADAM_BETAS = (0.9, 0.999)
ADAM_EPSILON = 1e-8


def count_parameters(sizes: Ints) -> int:
    """Count the weights and biases of a network of layer widths ``sizes``."""
    return int(sum((int(a) + 1) * int(b) for a, b in zip(sizes[:-1], sizes[1:], strict=True)))


def initial_parameters(sizes: Ints, rng: np.random.Generator) -> Array:
    """Draw a network's parameters: He-uniform weights for ReLU layers, zero biases (seeded).

    Each weight of a layer with fan-in a is uniform in ``±sqrt(6 / a)``.
    """
    parts = []
    for fan_in, fan_out in zip(sizes[:-1], sizes[1:], strict=True):
        bound = math.sqrt(6.0 / fan_in)
        parts += [rng.uniform(-bound, bound, int(fan_in) * int(fan_out)), np.zeros(int(fan_out))]
    return np.concatenate(parts)


@njit(cache=True, nogil=True)
def _layer(params: Array, sizes: Ints, layer: int) -> tuple[Array, Array, int]:
    """Return layer ``layer``'s weights (fan_out, fan_in), biases and their offset in ``params``."""
    start = 0
    for j in range(layer):
        start += (sizes[j] + 1) * sizes[j + 1]
    fan_in, fan_out = sizes[layer], sizes[layer + 1]
    weights = params[start : start + fan_in * fan_out].reshape((fan_out, fan_in))
    biases = params[start + fan_in * fan_out : start + (fan_in + 1) * fan_out]
    return weights, biases, start


@njit(cache=True, nogil=True)
def q_values(params: Array, sizes: Ints, features: Array) -> Array:
    """Return the action values of one feature vector, shape (sizes[-1],)."""
    activation = features.copy()
    last = sizes.size - 2
    for layer in range(last + 1):
        weights, biases, _ = _layer(params, sizes, layer)
        out = biases.copy()
        for o in range(weights.shape[0]):
            total = out[o]
            for i in range(weights.shape[1]):
                total += weights[o, i] * activation[i]
            out[o] = total if layer == last or total > 0.0 else 0.0
        activation = out
    return activation


@njit(cache=True, nogil=True)
def greedy_action(params: Array, sizes: Ints, features: Array) -> int:
    """Index of the action of highest value (the first of equals)."""
    return int(np.argmax(q_values(params, sizes, features)))


@njit(cache=True, nogil=True)
def _activations(params: Array, sizes: Ints, inputs: Array, buffer: Array) -> None:
    """Forward a batch (B, sizes[0]), writing every layer's output into ``buffer`` in turn.

    ``buffer`` holds B x (sizes[1] + ... + sizes[-1]) values: layer l's (B, sizes[l + 1])
    block follows layer l - 1's.
    """
    batch = inputs.shape[0]
    previous = inputs
    offset = 0
    last = sizes.size - 2
    for layer in range(last + 1):
        weights, biases, _ = _layer(params, sizes, layer)
        width = sizes[layer + 1]
        out = buffer[offset : offset + batch * width].reshape((batch, width))
        out[:, :] = np.dot(previous, weights.T)
        for b in range(batch):
            for o in range(width):
                value = out[b, o] + biases[o]
                out[b, o] = value if layer == last or value > 0.0 else 0.0
        previous = out
        offset += batch * width


@njit(cache=True, nogil=True)
def batch_q_values(params: Array, sizes: Ints, inputs: Array) -> Array:
    """Return the action values of feature vectors (B, sizes[0]), shape (B, sizes[-1])."""
    batch = inputs.shape[0]
    buffer = np.empty(batch * int(np.sum(sizes[1:])))
    _activations(params, sizes, inputs, buffer)
    width = sizes[-1]
    return buffer[buffer.size - batch * width :].reshape((batch, width)).copy()


@njit(cache=True, nogil=True)
def loss_gradient(
    params: Array, sizes: Ints, inputs: Array, actions: Ints, targets: Array, gradient: Array
) -> float:
    """Return the mean Huber loss of ``Q(inputs)[actions]`` against ``targets``; fill ``gradient``.

    Parameters
    ----------
    params, sizes
        The network.
    inputs
        Feature vectors, shape (B, sizes[0]).
    actions
        The action taken in each, shape (B,).
    targets
        Their target values, shape (B,).
    gradient
        Receives d loss / d params, shape like ``params``.

    Returns
    -------
    float
        The loss.
    """
    batch = inputs.shape[0]
    n_layers = sizes.size - 1
    buffer = np.empty(batch * int(np.sum(sizes[1:])))
    _activations(params, sizes, inputs, buffer)
    end = buffer.size
    width = sizes[-1]
    delta = np.zeros((batch, width))
    output = buffer[end - batch * width :].reshape((batch, width))
    loss = 0.0
    for b in range(batch):
        error = output[b, actions[b]] - targets[b]
        if abs(error) <= HUBER_DELTA:
            loss += 0.5 * error * error
            delta[b, actions[b]] = error / batch
        else:
            loss += HUBER_DELTA * (abs(error) - 0.5 * HUBER_DELTA)
            delta[b, actions[b]] = math.copysign(HUBER_DELTA, error) / batch
    end -= batch * width
    for layer in range(n_layers - 1, -1, -1):
        weights, _, start = _layer(params, sizes, layer)
        fan_in, fan_out = sizes[layer], sizes[layer + 1]
        below = buffer[end - batch * fan_in : end].reshape((batch, fan_in)) if layer else inputs
        gradient[start : start + fan_in * fan_out] = np.dot(delta.T, below).ravel()
        gradient[start + fan_in * fan_out : start + (fan_in + 1) * fan_out] = delta.sum(axis=0)
        if layer > 0:
            delta = np.dot(delta, weights)
            for b in range(batch):
                for i in range(fan_in):
                    if below[b, i] <= 0.0:
                        delta[b, i] = 0.0
            end -= batch * fan_in
    return loss / batch


@njit(cache=True, nogil=True)
def adam_step(
    params: Array, gradient: Array, first: Array, second: Array, step: int, learning_rate: float
) -> None:
    """One Adam update of ``params`` in place; ``first``/``second`` are its moment estimates.

    ``step`` counts updates from 1 (for the bias corrections).
    """
    beta1, beta2 = ADAM_BETAS
    scale = learning_rate * math.sqrt(1.0 - beta2**step) / (1.0 - beta1**step)
    for i in range(params.size):
        g = gradient[i]
        first[i] = beta1 * first[i] + (1.0 - beta1) * g
        second[i] = beta2 * second[i] + (1.0 - beta2) * g * g
        params[i] -= scale * first[i] / (math.sqrt(second[i]) + ADAM_EPSILON)

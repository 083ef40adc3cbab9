"""A Kuramoto phase oscillator as a player, for groups.

The model of Kuramoto (1975), as avatars in CHRONOS and SHARESPACE are driven.

The player is a phase theta (rad) with natural frequency omega; its position is the phase's
projection ``x = A cos(theta)`` (units) and its velocity ``x' = -A theta' sin(theta)``. Each of
its m neighbours has a phase estimated from its position and velocity at t_k as if it were a
harmonic oscillator at the player's own frequency, ``phi_j = atan2(-x'_j / omega, x_j)``
(**choice**: the players of the mirror game share positions, not phases), held over the
control period::

    theta' = omega + K / m sum_j sin(phi_j - theta)

(``theta' = omega`` alone), integrated with RK4 (`rk4_held`). The positions stay within
[-A, A], inside the playing range for A <= 0.5.

Parameters (**choices**: the sources give the model, not values for the mirror game):
omega = pi rad/s (0.5 Hz), K = 2 rad/s, A = 0.3 units, theta(0) = 0.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from numba import njit

from mirror_avatar.players.base import Observation
from mirror_avatar.players.dynamical import (
    RATES_SIGNATURE,
    Array,
    ModelPartner,
    Parameter,
    rk4_held,
)

N_SUBSTEPS = 4
"""RK4 steps per control period."""

PARAMETERS: Mapping[str, Parameter] = {
    "omega": Parameter(math.pi, 0.01, 100.0, "natural frequency omega (rad/s)"),
    "coupling": Parameter(2.0, -1000.0, 1000.0, "coupling strength K (rad/s)"),
    "amplitude": Parameter(0.3, 0.0, 0.5, "amplitude A (units)"),
    "phase": Parameter(0.0, -math.pi, math.pi, "initial phase theta(0) (rad)"),
}
"""The oscillator (see the module docstring)."""


@njit(RATES_SIGNATURE, cache=True, nogil=True)
def kuramoto_rates(t: float, y: Array, params: Array, inputs: Array, out: Array) -> None:
    """Rate of ``(theta,)``; params ``(omega, K)``, inputs the neighbours' phases, shape (m,)."""
    pull = 0.0
    for j in range(inputs.size):
        pull += math.sin(inputs[j] - y[0])
    out[0] = params[0] + (params[1] * pull / inputs.size if inputs.size > 0 else 0.0)


@njit(cache=True, nogil=True)
def neighbour_phases(positions: Array, velocities: Array, omega: float) -> Array:
    """Phases (rad) of neighbours at positions (units) and velocities (units/s), shape (m,)."""
    phases = np.empty(positions.size)
    for j in range(positions.size):
        phases[j] = math.atan2(-velocities[j] / omega, positions[j])
    return phases


def kuramoto_step(
    y: Array, params: Array, positions: Array, velocities: Array, period: float
) -> tuple[float, float]:
    """Advance ``(theta,)`` over one period in place; return the position and velocity.

    params are ``(omega, K, A)``.
    """
    phases = neighbour_phases(positions, velocities, params[0])
    rk4_held(kuramoto_rates, y, params, phases, 0.0, period, N_SUBSTEPS)
    rate = np.empty(1)
    kuramoto_rates(period, y, params, phases, rate)
    amplitude = params[2]
    return amplitude * math.cos(y[0]), -amplitude * rate[0] * math.sin(y[0])


class KuramotoPlayer(ModelPartner):
    """A Kuramoto phase oscillator player (see the module docstring)."""

    PARAMETERS = PARAMETERS
    FIXED_IN_TRIAL = ("phase", "amplitude")
    TRIAL_STATE = ("state",)
    NAME = "Kuramoto oscillator"

    def kernel_parameters(self) -> Array:
        """Return the natural frequency, coupling and amplitude, as the kernel reads them."""
        return self.parameter_array(("omega", "coupling", "amplitude"))

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        """Start at the initial phase, moving at the natural frequency (``seed`` unused)."""
        o = self.options
        self.state = np.array([o["phase"]])
        theta, amplitude = o["phase"], o["amplitude"]
        return amplitude * math.cos(theta), -amplitude * o["omega"] * math.sin(theta)

    def step(self, observation: Observation) -> tuple[float, float]:
        """Estimate the neighbours' phases at t_k and advance one period."""
        x, v = kuramoto_step(
            self.state, self.params, observation.positions, observation.velocities, self.period
        )
        self.state[0] = math.remainder(float(self.state[0]), 2.0 * math.pi)
        return x, v

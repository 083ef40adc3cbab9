"""The reactive-predictive controller of Noy, Dekel & Alon (2011) as Zhai et al. (2017) write it.

Zhai et al. (2017, section 6.3.1) write the controller they compare as (x the player's position,
units)::

    x''   = sum_i A_i omega_i cos(omega_i t) + f          predictive and reactive units
    f'    = k (r_v - x')                                    reactive unit: integral feedback
    A_i'  = lambda (r_v - sum_j A_j sin(omega_j t)) sin(omega_i t)

with r_v the partner's (estimated) velocity sampled at t_k and held over the control period, t
the time since the start of the trial and A_i(0) = 0. The predictor sum_i A_i sin(omega_i t) is
fitted online to the partner's velocity; the reactive unit compares the player's velocity with
the partner's, as Noy et al.'s Fig. 4 describes ("integral feedback that compares v1 with v2").
Nothing pulls the positions together: the player tracks its partner's velocity, its velocity
error swings at sqrt(k) rad/s (the follower's jitter Noy et al. describe) and its position keeps
whatever offset it has.

Parameters (Zhai et al. 2017, "as suggested in" Noy et al. 2011): k = 30, lambda = 0.01,
omega_i = 0.025, 0.05, 0.075, 0.1, 0.125, A_i(0) = 0. **Choice**: the sources give the
frequencies without a unit; they are read in rad/s with t in seconds, as Zhai et al. simulate
(``omega_low``, ``omega_high`` set other values). **Departures**: integrated with RK4
(`rk4_held`) rather than Euler, the partner's velocity is the one observed, the player starts at
rest at 0; at a wall the position is clipped and an outward velocity stopped.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from numba import njit

from mirror_avatar.files.trials import PLAYING_RANGE
from mirror_avatar.players.base import Observation, partner_state
from mirror_avatar.players.dynamical import (
    RATES_SIGNATURE,
    Array,
    ModelPartner,
    Parameter,
    rk4_held,
)

N_FREQUENCIES = 5
"""Sinusoids of the predictor (Noy et al. 2011)."""

N_SUBSTEPS = 8
"""RK4 steps per control period (the fastest rate, sqrt(k) = 5.5 rad/s, times a step 3.75 ms)."""

PARAMETERS: Mapping[str, Parameter] = {
    "k": Parameter(30.0, 0.0, 1e4, "reactive (integral) gain (1/s²)"),
    "lam": Parameter(0.01, 0.0, 1e3, "predictor learning rate lambda (1/s)"),
    "omega_low": Parameter(0.025, 0.0, 100.0, "lowest predictor frequency (rad/s)"),
    "omega_high": Parameter(0.125, 0.0, 100.0, "highest predictor frequency (rad/s)"),
}
"""The parameters of Zhai et al.'s implementation (five frequencies evenly spaced)."""


@njit(RATES_SIGNATURE, cache=True, nogil=True)
def rpc_rates(t: float, y: Array, params: Array, inputs: Array, out: Array) -> None:
    """Rates of the state ``(x, x', f, A_1..A_5)``; params ``(k, lambda, omega_1..5)``."""
    prediction = 0.0
    drive = 0.0
    for i in range(N_FREQUENCIES):
        omega = params[2 + i]
        prediction += y[3 + i] * math.sin(omega * t)
        drive += y[3 + i] * omega * math.cos(omega * t)
    error = inputs[1] - prediction
    out[0] = y[1]
    out[1] = drive + y[2]
    out[2] = params[0] * (inputs[1] - y[1])
    for i in range(N_FREQUENCIES):
        out[3 + i] = params[1] * error * math.sin(params[2 + i] * t)


def rpc_step(y: Array, params: Array, inputs: Array, t: float, period: float) -> None:
    """Advance the state over one period in place and stop it at a wall."""
    rk4_held(rpc_rates, y, params, inputs, t, period, N_SUBSTEPS)
    low, high = PLAYING_RANGE
    if y[0] >= high or y[0] <= low:
        y[0] = min(max(y[0], low), high)
        if (y[0] == high and y[1] > 0.0) or (y[0] == low and y[1] < 0.0):
            y[1] = 0.0


class ReactivePredictivePlayer(ModelPartner):
    """The reactive-predictive controller (see the module docstring)."""

    PARAMETERS = PARAMETERS
    ORDERED = (("omega_low", "omega_high"),)
    TRIAL_STATE = ("state", "_k")
    NAME = "reactive-predictive (Noy et al. 2011)"

    def kernel_parameters(self) -> Array:
        """Return the gain k, the learning rate lambda and the predictor's frequencies."""
        o = self.options
        omegas = np.linspace(o["omega_low"], o["omega_high"], N_FREQUENCIES)
        return np.concatenate([[o["k"], o["lam"]], omegas])

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        """Start at rest at 0 with an empty predictor (``seed`` changes nothing)."""
        self.state = np.zeros(3 + N_FREQUENCIES)
        self._k = 0
        return 0.0, 0.0

    def step(self, observation: Observation) -> tuple[float, float]:
        """Sample the partner's velocity at t_k and advance one period."""
        x, v = float(self.state[0]), float(self.state[1])
        r_p, r_v, _ = partner_state(
            observation.positions, observation.velocities, observation.previous_positions, x, v
        )
        inputs = np.array([r_p, r_v])
        rpc_step(self.state, self.params, inputs, self._k * self.period, self.period)
        self._k += 1
        return float(self.state[0]), float(self.state[1])

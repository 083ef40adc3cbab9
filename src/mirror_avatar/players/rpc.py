"""The reactive-predictive controller of Noy, Dekel & Alon (2011), as Zhai et al. (2017) compare it.

A reactive unit (integral feedback of the position error) and a predictive unit (a sum of five
sinusoids fitted online to the partner's velocity) drive the player's position x (units)::

    P(t)  = sum_i A_i sin(omega_i t) + B_i cos(omega_i t)     predicted partner velocity
    x'    = w + P(t)
    w'    = k (r_p - x)                                        reactive unit
    A_i'  = lambda (r_v - P(t)) sin(omega_i t)                 least-mean-squares fit
    B_i'  = lambda (r_v - P(t)) cos(omega_i t)

with r_p and r_v the partner's position and velocity sampled at t_k and held over the control
period, t the time since the start of the trial, all amplitudes zero at the start. The
player's velocity is ``w + P``. Pure integral feedback makes the player oscillate around its
partner at sqrt(k) rad/s until the predictor has learnt the partner's motion: the jitter of a
follower that the paper describes.

Parameters (Zhai et al. 2017, after Noy et al. 2011): k = 30 (1/s²), lambda = 0.01 (1/s), five
frequencies evenly spaced from 0.025 to 0.125. **Choice**: Noy et al.'s frequencies are per
sample of their 50 Hz recordings, so here they are 1.25 to 6.25 rad/s (0.2 to 1 Hz); k and
lambda are read per second. **Departure**: the source's exact equations were not available to
us; this is the structure its Fig. 4 describes (integral feedback plus a sinusoidal
predictor), integrated with RK4 (`rk4_held`). At a wall the position is clipped and the reactive
velocity set so the player stops.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from numba import njit

from mirror_avatar.players.base import Observation, partner_state
from mirror_avatar.players.dynamical import Array, ModelPartner, Parameter, rk4_held
from mirror_avatar.trials import PLAYING_RANGE

N_FREQUENCIES = 5
"""Sinusoids of the predictor (Noy et al. 2011)."""

N_SUBSTEPS = 8
"""RK4 steps per control period (the fastest rate, sqrt(k) = 5.5 rad/s, times a step 3.75 ms)."""

PARAMETERS: Mapping[str, Parameter] = {
    "k": Parameter(30.0, 0.0, 1e4, "reactive (integral) gain (1/s²)"),
    "lam": Parameter(0.01, 0.0, 1e3, "predictor learning rate lambda (1/s)"),
    "omega_low": Parameter(1.25, 0.0, 100.0, "lowest predictor frequency (rad/s)"),
    "omega_high": Parameter(6.25, 0.0, 100.0, "highest predictor frequency (rad/s)"),
}
"""The parameters of Zhai et al.'s implementation (see the module docstring for the units)."""


@njit(cache=True, nogil=True)
def rpc_rates(t: float, y: Array, params: Array, inputs: Array, out: Array) -> None:
    """Rates of the state ``(x, w, A_1..A_5, B_1..B_5)``; params ``(k, lambda, omega_1..5)``."""
    n = N_FREQUENCIES
    prediction = 0.0
    for i in range(n):
        prediction += y[2 + i] * math.sin(params[2 + i] * t) + y[2 + n + i] * math.cos(
            params[2 + i] * t
        )
    error = inputs[1] - prediction
    out[0] = y[1] + prediction
    out[1] = params[0] * (inputs[0] - y[0])
    for i in range(n):
        out[2 + i] = params[1] * error * math.sin(params[2 + i] * t)
        out[2 + n + i] = params[1] * error * math.cos(params[2 + i] * t)


def rpc_step(y: Array, params: Array, inputs: Array, t: float, period: float) -> float:
    """Advance the state over one period in place, stop it at a wall; return the velocity."""
    rk4_held(rpc_rates, y, params, inputs, t, period, N_SUBSTEPS)
    rates = np.empty_like(y)
    rpc_rates(t + period, y, params, inputs, rates)
    velocity = rates[0]
    low, high = PLAYING_RANGE
    if y[0] > high or y[0] < low:
        y[0] = min(max(y[0], low), high)
        if (y[0] == high and velocity > 0.0) or (y[0] == low and velocity < 0.0):
            y[1] -= velocity
            velocity = 0.0
    return velocity


class ReactivePredictivePlayer(ModelPartner):
    """The reactive-predictive controller (see the module docstring).

    Parameters
    ----------
    options
        Values of `PARAMETERS` by name; the others take the published values.
    label
        Its name in sessions.
    """

    PARAMETERS = PARAMETERS

    def __init__(self, options: Mapping[str, float] | None = None, label: str = "") -> None:
        super().__init__(options, label or "reactive-predictive (Noy et al. 2011)")
        o = self.options
        omegas = np.linspace(o["omega_low"], o["omega_high"], N_FREQUENCIES)
        self.params = np.concatenate([[o["k"], o["lam"]], omegas])

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        """Start at rest at 0 with an empty predictor (``seed`` changes nothing)."""
        self.state = np.zeros(2 + 2 * N_FREQUENCIES)
        self._k = 0
        return 0.0, 0.0

    def step(self, observation: Observation) -> tuple[float, float]:
        """Sample the partner at t_k and advance one period."""
        x = float(self.state[0])
        r_p, r_v, _ = partner_state(
            observation.positions, observation.velocities, observation.previous_positions, x, 0.0
        )
        inputs = np.array([r_p, r_v])
        velocity = rpc_step(self.state, self.params, inputs, self._k * self.period, self.period)
        self._k += 1
        return float(self.state[0]), float(velocity)

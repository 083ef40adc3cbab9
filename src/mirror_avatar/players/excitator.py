"""The Jirsa-Kelso excitator (Jirsa & Kelso 2005) as a partner coupled to the player it follows.

The excitator is a two-dimensional FitzHugh-Nagumo-like system whose fast variable u is the
movement; the player's position is ``s u`` (units) with s a scale mapping u's range (about
[-2, 2]) onto the playing range. Coupled to its partner's position r_p (sampled at t_k and
held over the control period)::

    u' = tau (u - u³/3 + w) + c (r_p / s - u)
    w' = -(u - a + b w) / tau

integrated with RK4 (`rk4_held`). With |a| > 1 the excitator is excitable (a stable rest
state that a push sends round one excursion: a discrete movement); with |a| < 1 it oscillates
(rhythmic movement). The player's velocity is ``s u'``.

Parameters: a = 1.05, b = 0 and tau = 1 (the excitable regime of the source's discrete
movements); **choices** (the source couples excitators to stimuli, not to a person's position):
the coupling c = 10 (1/s), time in seconds and the scale s = 0.25 units. With b = 0 the
recovery variable integrates a - u, so the follower's mean position is held at s a (0.26 units)
whatever its partner does; a positive b lets it follow a partner centred elsewhere. The player
starts at rest on u's rest state; at a wall the position is clipped and an outward velocity set to
zero (u held at the wall).
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

N_SUBSTEPS = 8
"""RK4 steps per control period."""

PARAMETERS: Mapping[str, Parameter] = {
    "a": Parameter(1.05, -10.0, 10.0, "threshold a"),
    "b": Parameter(0.0, -10.0, 10.0, "recovery b"),
    "tau": Parameter(1.0, 0.01, 100.0, "time-scale separation tau"),
    "c": Parameter(10.0, 0.0, 1e4, "coupling to the partner's position c (1/s)"),
    "scale": Parameter(0.25, 0.01, 1.0, "position per unit of u, s (units)"),
}
"""The excitator and its coupling (see the module docstring)."""


@njit(RATES_SIGNATURE, cache=True, nogil=True)
def excitator_rates(t: float, y: Array, params: Array, inputs: Array, out: Array) -> None:
    """Rates of ``(u, w)``; params ``(a, b, tau, c, s)``, inputs ``(r_p,)``."""
    u, w = y[0], y[1]
    a, b, tau, c, s = params[0], params[1], params[2], params[3], params[4]
    out[0] = tau * (u - u * u * u / 3.0 + w) + c * (inputs[0] / s - u)
    out[1] = -(u - a + b * w) / tau


def excitator_step(y: Array, params: Array, inputs: Array, period: float) -> float:
    """Advance ``(u, w)`` over one period in place, stop at a wall; return the velocity."""
    rk4_held(excitator_rates, y, params, inputs, 0.0, period, N_SUBSTEPS)
    rates = np.empty_like(y)
    excitator_rates(period, y, params, inputs, rates)
    s = params[4]
    velocity = s * rates[0]
    low, high = PLAYING_RANGE
    if s * y[0] > high:
        y[0] = high / s
        velocity = min(velocity, 0.0)
    elif s * y[0] < low:
        y[0] = low / s
        velocity = max(velocity, 0.0)
    return velocity


def rest_state(a: float, b: float) -> tuple[float, float]:
    """Return the uncoupled excitator's rest state (u, w) nearest u = a.

    Solves ``u - u³/3 + w = 0`` and ``u - a + b w = 0`` by Newton's method from u = a.
    """
    u = a
    for _ in range(100):
        w = -(u - u**3 / 3.0)
        residual = u - a + b * w
        slope = 1.0 - b * (1.0 - u * u)
        if slope == 0.0 or abs(residual) < 1e-15:
            break
        u -= residual / slope
    return u, -(u - u**3 / 3.0)


class ExcitatorPartner(ModelPartner):
    """A Jirsa-Kelso excitator partner (see the module docstring)."""

    PARAMETERS = PARAMETERS
    FIXED_IN_TRIAL = ("scale",)
    TRIAL_STATE = ("state",)
    NAME = "excitator (Jirsa & Kelso 2005)"

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        """Start at rest on the rest state, clipped to the range (``seed`` changes nothing)."""
        o = self.options
        u, w = rest_state(o["a"], o["b"])
        s = o["scale"]
        if not math.isfinite(u):
            u, w = 0.0, 0.0
        low, high = PLAYING_RANGE
        u = min(max(u, low / s), high / s)
        self.state = np.array([u, w])
        return s * u, 0.0

    def step(self, observation: Observation) -> tuple[float, float]:
        """Sample the partner at t_k and advance one period."""
        s = self.options["scale"]
        x = s * float(self.state[0])
        r_p, _, _ = partner_state(
            observation.positions, observation.velocities, observation.previous_positions, x, 0.0
        )
        velocity = excitator_step(self.state, self.params, np.array([r_p]), self.period)
        return s * float(self.state[0]), float(velocity)

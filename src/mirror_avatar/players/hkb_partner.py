"""A coupled HKB oscillator partner (Haken, Kelso & Bunz 1985; Kelso et al. 1990).

The player is a self-sustained hybrid (Rayleigh-van der Pol) oscillator coupled to its partner
by the HKB coupling function::

    x'' = -(alpha x² + beta x'² - gamma) x' - omega² x + (x' - r_v) [a + b (x - r_p)²]

with r_p and r_v the partner's position and velocity sampled at t_k and held over the control
period, integrated with RK4 (`rk4_held`). With gamma > 0 it oscillates on its own, on a limit
cycle of amplitude about ``sqrt(4 gamma / (alpha + 3 beta omega²))``; negative a and b pull its
velocity towards its partner's, the more so the further apart they are (in-phase attraction).

Parameters (**choices**: the sources give the form and the signs, not values for the mirror
game's units): alpha = beta = gamma = 1 and omega = pi rad/s, a limit cycle of about 0.36
units at 0.5 Hz, a hand's pace; a = -1 (1/s) and b = -10 (1/(s units²)). The player starts
at rest at `START` (off the unstable rest point 0, so it oscillates alone too); at a wall the
position is clipped and an outward velocity set to zero.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from numba import njit

from mirror_avatar.dynamics import clip_to_range
from mirror_avatar.players.base import Observation, partner_state
from mirror_avatar.players.dynamical import (
    RATES_SIGNATURE,
    Array,
    ModelPartner,
    Parameter,
    rk4_held,
)

N_SUBSTEPS = 16
"""RK4 steps per control period."""

START = 0.1
"""Initial position (units), at rest (**choice**)."""

PARAMETERS: Mapping[str, Parameter] = {
    "alpha": Parameter(1.0, 0.0, 1000.0, "van der Pol damping alpha (1/(s units²))"),
    "beta": Parameter(1.0, 0.0, 1000.0, "Rayleigh damping beta (s/units²)"),
    "gamma": Parameter(1.0, -100.0, 100.0, "linear (negative) damping gamma (1/s)"),
    "omega": Parameter(math.pi, 0.0, 100.0, "natural frequency omega (rad/s)"),
    "a": Parameter(-1.0, -1000.0, 1000.0, "coupling a (1/s)"),
    "b": Parameter(-10.0, -1000.0, 1000.0, "coupling b (1/(s units²))"),
}
"""The oscillator and its coupling (see the module docstring)."""


@njit(RATES_SIGNATURE, cache=True, nogil=True)
def hkb_partner_rates(t: float, y: Array, params: Array, inputs: Array, out: Array) -> None:
    """Rates of ``(x, x')``; params ``(alpha, beta, gamma, omega, a, b)``, inputs ``(r_p, r_v)``."""
    x, v = y[0], y[1]
    alpha, beta, gamma, omega, a, b = (
        params[0],
        params[1],
        params[2],
        params[3],
        params[4],
        params[5],
    )
    d = x - inputs[0]
    out[0] = v
    out[1] = (
        -(alpha * x * x + beta * v * v - gamma) * v
        - omega * omega * x
        + (v - inputs[1]) * (a + b * d * d)
    )


def hkb_partner_step(y: Array, params: Array, inputs: Array, period: float) -> None:
    """Advance ``(x, x')`` over one period in place and stop it at a wall."""
    rk4_held(hkb_partner_rates, y, params, inputs, 0.0, period, N_SUBSTEPS)
    y[0], y[1] = clip_to_range(y[0], y[1])


class HKBPartner(ModelPartner):
    """A coupled HKB oscillator partner (see the module docstring)."""

    PARAMETERS = PARAMETERS
    TRIAL_STATE = ("state",)
    NAME = "HKB oscillator (Haken, Kelso & Bunz 1985)"

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        """Start at rest at `START` (``seed`` changes nothing)."""
        self.state = np.array([START, 0.0])
        return START, 0.0

    def step(self, observation: Observation) -> tuple[float, float]:
        """Sample the partner at t_k and advance one period."""
        x, v = float(self.state[0]), float(self.state[1])
        r_p, r_v, _ = partner_state(
            observation.positions, observation.velocities, observation.previous_positions, x, v
        )
        hkb_partner_step(self.state, self.params, np.array([r_p, r_v]), self.period)
        return float(self.state[0]), float(self.state[1])

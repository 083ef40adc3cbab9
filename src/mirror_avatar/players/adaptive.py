"""The adaptive-control virtual player of Zhai et al. (2017, section 4).

An HKB end effector whose coupling gains adapt to the partner it follows.

The end effector is the HKB oscillator of `mirror_avatar.dynamics`::

    x'' = -(alpha x² + beta x'² - gamma) x' - omega² x + u

driven by the control (e = x - r_p, e_v = x' - r_v_hat, r_p the partner's position and r_v_hat
its estimated velocity)::

    u_I = C_p exp(-delta e_v²) e
    u   = [a + b e²] e_v - u_I

with the gains adapting as::

    a' = -exp(-2a) [e e_v + eta_a e²] - eta_a
    b' = e_v exp(-2b) [omega² x + (alpha x² + beta x'² - gamma) x' - eta_a e_v - u_I] - eta_a

How it runs (follows the public MirrorGame code, ``Adaptive Control/simulation/simulationHC.m``):
the controller is a sampled-data one. At each controller sample it reads the partner's position,
estimates the partner's velocity by the backward difference over the last sampling interval (the
paper's eq. (3); zero at the first sample), advances a and b by one explicit Euler step of the
sampling interval, clips each to [-bound, bound] (the code's ``coupMax`` 5), and computes u, held
until the next sample while the HKB is integrated (RK4, `mirror_avatar.dynamics.advance_hkb`);
at the first sample u uses a(0), b(0). The code's loop does all this on every pass, its step the
pass's wall-clock time capped at 0.1 s (the paper's "T = 0.1 s"), so by default the controller
samples every control period (`mirror_avatar.dynamics.CONTROL_PERIOD`). The b law's ``u`` is
u_I, as the public code passes it (**choice**: the paper writes u).
In the leader role, u_I takes the leader's gains (``leader_cp``, ``leader_delta``; the public
code's ``CpL``, ``deltaL``, which it names without values: their defaults here equal the
follower's, **choice**).

**Departures**: the public code integrates the HKB by one explicit Euler step per pass, RK4 here
(``euler=True`` takes the code's step, whose damping step shrinks the speed only while
beta x'² T < 2, below 1.8 units/s at T = 0.03 s); a longer sampling time is rounded to a whole
number of control periods; the player starts at rest at 0, not at the partner's position, and
stops at the walls. In a group it follows its neighbours' mean (METHODS section 8).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from numba import njit

from mirror_avatar.dynamics import (
    CONTROL_PERIOD,
    DAMPING_STIFFNESS,
    MAX_RK4_SUBSTEPS,
    advance_hkb,
    clip_to_range,
    hkb_acceleration,
)
from mirror_avatar.players.base import Observation, partner_state
from mirror_avatar.players.dynamical import ModelPartner, Parameter

PARAMETERS: Mapping[str, Parameter] = {
    "alpha": Parameter(10.0, 0.0, 1000.0, "HKB alpha (1/(s units²))"),
    "beta": Parameter(20.0, 0.0, 1000.0, "HKB beta (s/units²)"),
    "gamma": Parameter(-1.0, -100.0, 100.0, "HKB gamma (1/s)"),
    "omega": Parameter(0.1, 0.0, 100.0, "HKB omega (rad/s)"),
    "a0": Parameter(-5.0, -50.0, 50.0, "initial gain a(0)"),
    "b0": Parameter(-5.0, -50.0, 50.0, "initial gain b(0)"),
    "cp": Parameter(40.0, 0.0, 1e4, "position gain C_p (1/s²)"),
    "delta": Parameter(0.25, 0.0, 1e3, "velocity width delta (s²/units²)"),
    "leader_cp": Parameter(40.0, 0.0, 1e4, "C_p in the leader role (1/s²)"),
    "leader_delta": Parameter(0.25, 0.0, 1e3, "delta in the leader role (s²/units²)"),
    "eta": Parameter(30.0, 0.0, 1e4, "adaptation rate eta_a"),
    "bound": Parameter(5.0, 0.01, 50.0, "bound on |a| and |b| (the code's coupMax)"),
    "sampling": Parameter(
        CONTROL_PERIOD, 0.0, 1.0, "controller sampling time (s), in whole periods"
    ),
}
"""The published parameters: the HKB's, C_p, delta and eta_a from the public code's
``parameters/parametersHC.m``, a(0) and b(0) from ``parameters/simulationParameters.m``, the bound
from ``simulation/simulationHC.m`` (``coupMax``), sampling every pass of its loop (one control
period here)."""

MIN_SUBSTEPS = 16
"""Fewest RK4 steps per control period (the HKB under the held control to about 1e-9)."""

LEADER_ROLES = ("leader", "group_leader")
"""Roles in which the player takes the leader's gains."""


@njit(cache=True, nogil=True)
def adaptive_gains(
    a: float,
    b: float,
    x: float,
    v: float,
    r_p: float,
    r_v: float,
    cp: float,
    delta: float,
    eta: float,
    alpha: float,
    beta: float,
    gamma: float,
    omega: float,
    dt: float,
    bound: float,
) -> tuple[float, float, float]:
    """Advance the gains by one Euler step of ``dt`` (s), clip them; return a, b and u_I.

    Parameters
    ----------
    a, b
        The gains before the step.
    x, v
        The player's position (units) and velocity (units/s) at the sample.
    r_p, r_v
        The partner's position and estimated velocity at the sample.
    cp, delta, eta, alpha, beta, gamma, omega
        The controller's and the end effector's parameters.
    dt
        The sampling interval (s); 0 leaves the gains as they are (the first sample).
    bound
        The gains are clipped to [-bound, bound].
    """
    e, ev = x - r_p, v - r_v
    u_i = cp * math.exp(-delta * ev * ev) * e
    if dt > 0.0:
        rate_a = -math.exp(-2.0 * a) * (e * ev + eta * e * e) - eta
        damping = (alpha * x * x + beta * v * v - gamma) * v
        rate_b = ev * math.exp(-2.0 * b) * (omega * omega * x + damping - eta * ev - u_i) - eta
        a = a + dt * rate_a
        b = b + dt * rate_b
    return min(max(a, -bound), bound), min(max(b, -bound), bound), u_i


@njit(cache=True, nogil=True)
def count_hkb_substeps(
    x: float,
    v: float,
    u: float,
    alpha: float,
    beta: float,
    gamma: float,
    omega: float,
    period: float,
) -> int:
    """RK4 steps for one period of the HKB: at least `MIN_SUBSTEPS`, more when it is stiff.

    The damping rate ``alpha x² + 3 beta x'² + |gamma|`` (1/s), taken at the velocity the held
    control and the spring force ``omega² x`` could reach over the period, times the step stays
    below `DAMPING_STIFFNESS`. (Without the spring force a stiff spring, omega = 100 rad/s with
    beta = 1000, sent the velocity beyond the estimate within a period and RK4 to infinity.)
    """
    fastest = abs(v) + (abs(u) + omega * omega * abs(x)) * period
    rate = alpha * x * x + 3.0 * beta * fastest * fastest + abs(gamma)
    wanted = math.ceil(period * rate / DAMPING_STIFFNESS)
    return int(min(max(wanted, MIN_SUBSTEPS), MAX_RK4_SUBSTEPS))


class AdaptivePlayer(ModelPartner):
    """The adaptive-control virtual player (see the module docstring).

    Parameters
    ----------
    options
        Values of `PARAMETERS` by name; the others take the published values.
    role
        The role it plays: in `LEADER_ROLES` its position gain and width are the leader's.
    label
        Its name in sessions.
    euler
        Advance the HKB by one explicit Euler step per control period, as the public code does,
        instead of RK4 (for checking the player against that code).
    """

    PARAMETERS = PARAMETERS
    FIXED_IN_TRIAL = ("a0", "b0")
    TRIAL_STATE = ("_x", "_v", "gains", "_k", "_u", "_sampled", "last_control")

    def __init__(
        self,
        options: Mapping[str, float] | None = None,
        role: str = "follower",
        label: str = "",
        *,
        euler: bool = False,
    ) -> None:
        super().__init__(options, label or "adaptive control (Zhai et al. 2017)")
        self.role = role
        self.euler = euler
        o = self.options
        self.hold = max(1, round(o["sampling"] / self.period))
        leads = role in LEADER_ROLES
        self.cp = o["leader_cp"] if leads else o["cp"]
        self.delta = o["leader_delta"] if leads else o["delta"]

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        """Start at rest at 0 with the gains a(0), b(0) (``seed`` changes nothing)."""
        o = self.options
        self._x, self._v = 0.0, 0.0
        self.gains = (o["a0"], o["b0"])
        self._k = 0
        self._u = 0.0
        self._sampled = math.nan
        self.last_control = self.last_reference = math.nan
        return self._x, self._v

    def step(self, observation: Observation) -> tuple[float, float]:
        """Sample the partner when the controller samples, then advance one period."""
        o = self.options
        if self._k % self.hold == 0:
            r_p, _, _ = partner_state(
                observation.positions,
                observation.velocities,
                observation.previous_positions,
                self._x,
                self._v,
            )
            first = math.isnan(self._sampled)
            interval = self.hold * self.period
            r_v = 0.0 if first else (r_p - self._sampled) / interval
            a, b, u_i = adaptive_gains(
                self.gains[0],
                self.gains[1],
                self._x,
                self._v,
                r_p,
                r_v,
                self.cp,
                self.delta,
                o["eta"],
                o["alpha"],
                o["beta"],
                o["gamma"],
                o["omega"],
                0.0 if first else interval,
                o["bound"],
            )
            self.gains = (a, b)
            e = self._x - r_p
            self._u = (a + b * e * e) * (self._v - r_v) - u_i
            self._sampled = r_p
        self._x, self._v = self._advance()
        self.last_control = self._u
        self._k += 1
        return self._x, self._v

    def _advance(self) -> tuple[float, float]:
        """Integrate the HKB over one control period under the held control."""
        o = self.options
        x, v, u = self._x, self._v, self._u
        hkb = (o["alpha"], o["beta"], o["gamma"], o["omega"])
        if self.euler:
            return clip_to_range(
                x + self.period * v, v + self.period * hkb_acceleration(x, v, u, *hkb)
            )
        n = count_hkb_substeps(x, v, u, *hkb, self.period)
        return advance_hkb(x, v, u, *hkb, self.period, n)

"""The virtual trainer's end effector: an HKB oscillator driven by a per-interval optimal control.

End-effector dynamics (METHODS section 5), with control input ``u`` (units/s²)::

    x'' = -(alpha x² + beta x'² - gamma) x' - omega² x + u

On each control interval [t_k, t_k + T] the controller minimises::

    J = theta_p/2 (x(T) - r_p)² + 1/2 ∫ [theta_s (x' - r_s)² + theta_v (x' - r_v)² + eta u²] dτ

with ``r_p`` the partner's predicted position at the end of the interval, ``r_s`` the reference
velocity from the IMS generator and ``r_v`` the partner's estimated velocity (joint improvisation
only), all held constant over the interval, and ``theta_s = 1 - theta_p - theta_v``.

How it is solved (follows METHODS section 5; departs from the original implementation, which
called MATLAB's bvp4c at every step): Pontryagin's principle gives the nonlinear two-point boundary
value problem of the section, solved here **exactly up to integration error** by shooting on the
two initial costates. The state-costate system and its sensitivities with respect to the initial
costates are integrated with fixed-step RK4 (at least `N_SUBSTEPS` steps per interval, more when
the interval is stiff, see `count_substeps`), and Newton's method on the two terminal conditions
converges in two or three iterations from the exact solution of the problem with frozen damping
(the problem is nearly linear over 0.03 s). The published closed-form quadratic-in-time
approximation is **not** used: it gets velocity and control wrong by tens of percent. After the
interval, the position is clipped to the playing range [-0.5, 0.5] and an outward velocity at the
wall is set to zero (a hand stopped at the edge of the range).

The cyber player's end effector is the same oscillator with a control chosen from a finite set and
held over the period (`integrate_hkb`, METHODS section 7).

Everything numerical is compiled with numba. Compiled functions read the parameters by name from a
record of `PARAMS_DTYPE` (`HKBParams.record`), so `optimal_control_step` and `integrate_hkb` are the
single steps used by every player, in the Python step loop and in the compiled batch loop alike.
The parameters, both steps and the solver's pieces stay in one module: they are read together.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from mirror_avatar.errors import InputError
from mirror_avatar.model_files import check_real
from mirror_avatar.trials import PLAYING_RANGE

CONTROL_PERIOD = 0.03
"""The control period T of the paper (s): players are advanced every T."""

N_SUBSTEPS = 4
"""Fewest RK4 steps per control interval in the shooting solve."""

STEP_STIFFNESS = 0.5
"""Largest RK4 step times the interval's fastest rate: more substeps are taken when needed."""

MAX_RK4_SUBSTEPS = 4096
"""Most RK4 steps per control period (**choice**), whatever the state and parameters: it bounds
the cost of one step. Within the playing range at the paper's parameters, `count_substeps` asks
for at most a few hundred (a partner crossing the whole range in one period)."""

MAX_NEWTON = 8
"""Most Newton iterations on the initial costates per control interval."""

NEWTON_TOLERANCE = 1e-3
"""Newton stops when the control at t_k and the end velocity change by less than this fraction
(the end state, extrapolated to first order in the last update, is then accurate to about its
square)."""

PARAMS_DTYPE = np.dtype(
    [
        ("alpha", np.float64),
        ("beta", np.float64),
        ("gamma", np.float64),
        ("omega", np.float64),
        ("eta", np.float64),
        ("theta_p", np.float64),
        ("theta_v", np.float64),
        ("period", np.float64),
    ]
)
"""The fields of `HKBParams` as compiled code reads them (a numpy record, by name)."""

PARAMETER_RANGES: dict[str, tuple[float, float]] = {
    "omega": (0.0, 100.0),
    "theta_p": (0.0, 1.0),
    "theta_v": (0.0, 1.0),
    "alpha": (0.0, 1000.0),
    "beta": (0.0, 1000.0),
    "gamma": (-1000.0, 1000.0),
    "eta": (1e-8, 1e4),
    "period": (1e-3, 1.0),
}
"""The range, inclusive, of each `HKBParams` field; anything else (NaN, inf, a string) is refused.

The weights theta_p and theta_v lie in [0, 1] by definition; the other bounds are a **choice**:
generous physical bounds around the paper's values (omega 0.1-0.8 rad/s, alpha 1, beta 2,
gamma -1, eta 1e-4, period 0.03 s). omega up to 100 rad/s (16 Hz, beyond any hand); non-negative
nonlinear damping alpha, beta up to 1000; |gamma| up to 1000 (1/s); eta from 1e-8, which keeps the
costate-control rate sqrt((1 - theta_p) / eta) and so `count_substeps` bounded (at most 2e4 RK4
steps per period from that rate); period from 1 ms to 1 s."""

_LOW, _HIGH = PLAYING_RANGE
Record = Any
"""A numpy record of `PARAMS_DTYPE` (numba's Record type in compiled code)."""


@dataclass(frozen=True)
class HKBParams:
    """Parameters of one virtual trainer's end effector and cost.

    Parameters
    ----------
    omega
        Natural frequency (rad/s).
    theta_p
        Weight of the terminal position error to the partner's predicted position.
    theta_v
        Weight of the velocity error to the partner's estimated velocity (joint improvisation;
        0 in leader and follower roles).
    alpha, beta, gamma
        HKB nonlinear damping coefficients (paper: 1, 2, -1; with gamma < 0 there is no limit
        cycle and all motion comes from the control).
    eta
        Weight of the control effort (paper: 1e-4).
    period
        Control period T (s).

    Raises
    ------
    InputError
        A field outside its `PARAMETER_RANGES`, or theta_p + theta_v above 1.
    """

    omega: float
    theta_p: float
    theta_v: float = 0.0
    alpha: float = 1.0
    beta: float = 2.0
    gamma: float = -1.0
    eta: float = 1e-4
    period: float = CONTROL_PERIOD

    def __post_init__(self) -> None:
        for name, (low, high) in PARAMETER_RANGES.items():
            check_real("HKBParams", name, getattr(self, name), low, high)
        if self.theta_s < 0.0:
            raise InputError("HKBParams", "theta_p + theta_v must not exceed 1")

    @property
    def theta_s(self) -> float:
        """Weight of the velocity error to the reference signature, 1 - theta_p - theta_v."""
        return 1.0 - self.theta_p - self.theta_v

    def record(self) -> NDArray[np.void]:
        """Return the parameters as a one-element array of `PARAMS_DTYPE`, shape (1,).

        Compiled functions take its element (``record()[0]``) and read the fields by name.
        """
        return records([self])

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable parameters."""
        return asdict(self)

    def with_(self, **changes: float) -> HKBParams:
        """Return a copy with some parameters overridden."""
        return replace(self, **changes)


LEADER = HKBParams(omega=0.8, theta_p=0.1)
"""The paper's leader: weak pull to the partner, strong pull to its own signature."""

FOLLOWER = HKBParams(omega=0.1, theta_p=0.9)
"""The paper's follower: strong pull to the partner's predicted position."""

JOINT = HKBParams(omega=0.45, theta_p=0.5, theta_v=0.2)
"""Joint improvisation (**choice**: the paper gives no numbers). Between leader and follower in
position weight and frequency, with a velocity term towards the partner's (theta_s = 0.3)."""


def records(params: Sequence[HKBParams | None]) -> NDArray[np.void]:
    """Stack parameters into an array of `PARAMS_DTYPE`, shape (len(params),).

    None (a player without an HKB end effector) gives a record of zeros.
    """
    table = np.zeros(len(params), dtype=PARAMS_DTYPE)
    for i, p in enumerate(params):
        if p is not None:
            table[i] = tuple(getattr(p, name) for name in PARAMS_DTYPE.names or ())
    return table


GROUP = HKBParams(omega=0.75, theta_p=0.85, theta_v=0.05)
"""A member of a group improvising together (METHODS section 8; the group's later code uses
theta_p 0.75-0.85, theta_s 0.1-0.2, theta_v 0.05, omega 0.5-1): the strongest coupling of that
range, theta_s = 0.1 (**choice**: with the bundled styles' fast references, weaker coupling keeps
a group of four on a complete graph below a group synchronisation of 0.8), omega in the middle."""

GROUP_LEADER = HKBParams(omega=0.75, theta_p=0.2)
"""A group's leader (METHODS section 8: theta_p 0.2, theta_s 0.8)."""

ROLES = ("leader", "follower", "joint", "group", "group_leader")
_PRESETS = {
    "leader": LEADER,
    "follower": FOLLOWER,
    "joint": JOINT,
    "group": GROUP,
    "group_leader": GROUP_LEADER,
}


def preset(role: str) -> HKBParams:
    """Return the parameters of a role preset, one of `ROLES`."""
    try:
        return _PRESETS[role]
    except KeyError:
        raise InputError("role", f"unknown role {role!r}; expected one of {ROLES}") from None


@njit(cache=True)
def hkb_acceleration(
    x: float, v: float, u: float, alpha: float, beta: float, gamma: float, omega: float
) -> float:
    """HKB acceleration ``-(alpha x² + beta v² - gamma) v - omega² x + u`` (units/s²)."""
    return -(alpha * x * x + beta * v * v - gamma) * v - omega * omega * x + u


@njit(cache=True)
def _derivatives(
    w: NDArray[np.float64],
    p: Record,
    theta_p: float,
    theta_v: float,
    reference_velocity: float,
    partner_velocity: float,
    frozen: float,
    size: int,
    dw: NDArray[np.float64],
) -> None:
    """Right-hand side of the state-costate system and of its costate sensitivities.

    ``w = [x, y, l1, l2, s]`` with ``s[i, j] = w[4 + 2 i + j]`` = d z_i / d(l1(0), l2(0))_j.
    Writes the derivative of the first ``size`` entries of ``w`` (4: state and costates only,
    12: with the sensitivities) into ``dw``, shape (12,). With ``frozen`` >= 0 (a damping
    coefficient, 1/s) the HKB damping ``alpha x² + beta y² - gamma`` is frozen at that value,
    which makes the system linear; with ``frozen`` < 0 it is the full nonlinear system.
    ``theta_p`` and ``theta_v`` are the partner weights in use (see `partner_weights`).
    """
    alpha, beta, gamma, omega, eta = p.alpha, p.beta, p.gamma, p.omega, p.eta
    theta_s = 1.0 - theta_p - theta_v
    x, y, l1, l2 = w[0], w[1], w[2], w[3]
    w2 = omega * omega
    if frozen >= 0.0:
        alpha = beta = 0.0
        gamma = -frozen
    damping = alpha * x * x + 3.0 * beta * y * y - gamma
    coupling = 2.0 * alpha * x * y + w2
    dw[0] = y
    dw[1] = hkb_acceleration(x, y, -l2 / eta, alpha, beta, gamma, omega)
    dw[2] = l2 * coupling
    dw[3] = (
        l2 * damping - l1 - theta_s * (y - reference_velocity) - theta_v * (y - partner_velocity)
    )
    for j in range(2 if size == 12 else 0):
        sx, sy, s1, s2 = w[4 + j], w[6 + j], w[8 + j], w[10 + j]
        dw[4 + j] = sy
        dw[6 + j] = -coupling * sx - damping * sy - s2 / eta
        dw[8 + j] = 2.0 * alpha * l2 * (y * sx + x * sy) + coupling * s2
        dw[10 + j] = (
            2.0 * alpha * l2 * x * sx
            + (6.0 * beta * l2 * y - theta_s - theta_v) * sy
            - s1
            + damping * s2
        )


@njit(cache=True)
def _shoot(
    x: float,
    y: float,
    l1: float,
    l2: float,
    p: Record,
    theta_p: float,
    theta_v: float,
    reference_velocity: float,
    partner_velocity: float,
    frozen: float,
    n_substeps: int,
    size: int,
    work: NDArray[np.float64],
) -> None:
    """Integrate state and costates (``size`` 4), and sensitivities (12), with RK4, in place.

    ``work`` (4, 12): row 0 receives the solution at the end of the interval (layout of
    `_derivatives`), rows 1-3 are scratch.
    """
    h = p.period / n_substeps
    state, stage, k, acc = work[0], work[1], work[2], work[3]
    state[:] = 0.0
    state[0], state[1], state[2], state[3] = x, y, l1, l2
    state[8] = 1.0
    state[11] = 1.0
    for _ in range(n_substeps):
        for i in range(size):
            acc[i] = 0.0
            stage[i] = state[i]
        for stage_index in range(4):
            _derivatives(
                stage, p, theta_p, theta_v, reference_velocity, partner_velocity, frozen, size, k
            )
            weight = 1.0 if stage_index == 0 or stage_index == 3 else 2.0
            step = h if stage_index == 2 else 0.5 * h
            for i in range(size):
                acc[i] += weight * k[i]
                stage[i] = state[i] + step * k[i]
        for i in range(size):
            state[i] += h / 6.0 * acc[i]


@njit(cache=True)
def count_substeps(
    x: float,
    y: float,
    reference_velocity: float,
    partner_velocity: float,
    p: Record,
    theta_p: float,
    theta_v: float,
    n_min: int,
) -> int:
    """RK4 steps for one interval: at least ``n_min``, and enough that step x rate <= 0.5.

    At most `MAX_RK4_SUBSTEPS`, so that no state (a hostile partner's jumps included) and no
    parameters within `PARAMETER_RANGES` make one step arbitrarily slow.

    The fastest rates (1/s) of the state-costate system are the costate-control coupling
    ``sqrt((theta_s + theta_v) / eta)`` (about 95/s for the leader) and the HKB damping
    ``alpha x² + 3 beta y² - gamma``, bounded with the largest of the current, reference and
    partner speeds (at 9 units/s the damping is about 490/s, and RK4 with the minimum steps
    would be unstable); `STEP_STIFFNESS` keeps RK4 accurate to well under 1 % at both.
    """
    speed = max(abs(y), abs(reference_velocity), abs(partner_velocity) if theta_v > 0.0 else 0.0)
    damping = p.alpha * x * x + 3.0 * p.beta * speed * speed - p.gamma
    coupling = np.sqrt((1.0 - theta_p) / p.eta)
    rate = max(damping, coupling)
    return min(MAX_RK4_SUBSTEPS, max(n_min, int(np.ceil(rate * p.period / STEP_STIFFNESS))))


@njit(cache=True)
def solve_interval(
    x: float,
    y: float,
    partner_prediction: float,
    reference_velocity: float,
    partner_velocity: float,
    p: Record,
    coupled: bool,
    n_substeps: int,
    max_newton: int,
    tolerance: float,
) -> tuple[float, float, float, float, bool]:
    """Solve one interval's optimal-control problem without clipping.

    The initial guess is the exact solution of the problem with the HKB damping frozen at its
    mean along a velocity ramp from ``y`` to ``r_s`` (linear, so one Newton step solves it); then
    Newton iterations on the full nonlinear problem: the first with sensitivities, the next
    as chord iterations (shooting state and costates only, with the last Jacobian and end-state
    sensitivities) while each shrinks the update at least fourfold, until the control at t_k
    changes by less than ``tolerance`` (relative) and the last update moves the end velocity by
    less than ``tolerance`` (relative, floor 1 unit/s). If it has not converged after
    ``max_newton`` iterations or the shooting overflows (speeds of several units/s, where the
    HKB damping ``3 beta y²`` makes forward shooting ill-conditioned), the frozen-damping
    solution is returned instead.

    Parameters
    ----------
    x, y
        Position (units) and velocity (units/s) at t_k.
    partner_prediction
        Predicted partner position at t_k + T (units).
    reference_velocity
        Reference velocity r_s (units/s).
    partner_velocity
        Estimated partner velocity r_v (units/s), used when theta_v > 0.
    p
        The parameters, a record of `PARAMS_DTYPE` (`HKBParams.record`).
    coupled
        False for a player alone: the partner terms are dropped (see `partner_weights`).
    n_substeps, max_newton
        Fewest RK4 steps per interval (`count_substeps` adds more where the interval is stiff)
        and the most chord-Newton iterations on the nonlinear problem.
    tolerance
        Convergence threshold (`NEWTON_TOLERANCE` in `optimal_control_step`).

    Returns
    -------
    tuple
        ``(x(T), y(T), lambda1(0), lambda2(0), converged)``; the optimal control at t_k is
        ``-lambda2(0) / eta``; ``converged`` is False when the frozen-damping fallback is used.
    """
    work = np.empty((4, 12))
    state = work[0]
    theta_p, theta_v = partner_weights(p, coupled)
    n_substeps = count_substeps(
        x, y, reference_velocity, partner_velocity, p, theta_p, theta_v, n_substeps
    )
    mean_square = (y * y + y * reference_velocity + reference_velocity * reference_velocity) / 3.0
    frozen = max(p.alpha * x * x + p.beta * mean_square - p.gamma, 0.0)
    l1, l2 = 0.0, 0.0
    fallback = (x, y, 0.0, 0.0)
    j11 = j12 = j21 = j22 = det = sx1 = sx2 = sy1 = sy2 = 0.0
    size, previous = 12, np.inf
    for iteration in range(max_newton + 1):
        damping = frozen if iteration == 0 else -1.0
        _shoot(
            x,
            y,
            l1,
            l2,
            p,
            theta_p,
            theta_v,
            reference_velocity,
            partner_velocity,
            damping,
            n_substeps,
            size,
            work,
        )
        if size == 12:
            # Jacobian of the terminal residual in (l1(0), l2(0)), and end-state sensitivities.
            j11 = state[8] - theta_p * state[4]
            j12 = state[9] - theta_p * state[5]
            j21, j22 = state[10], state[11]
            det = j11 * j22 - j12 * j21
            sx1, sx2, sy1, sy2 = state[4], state[5], state[6], state[7]
        r1 = state[2] - theta_p * (state[0] - partner_prediction)
        r2 = state[3]
        d1 = -(j22 * r1 - j12 * r2) / det
        d2 = -(j11 * r2 - j21 * r1) / det
        l1 += d1
        l2 += d2
        size = 12 if iteration == 0 or abs(d2) > 0.25 * previous else 4
        previous = abs(d2)
        # End state to first order in the update (exact once the iteration has converged).
        x_end = state[0] + sx1 * d1 + sx2 * d2
        y_end = state[1] + sy1 * d1 + sy2 * d2
        if not (np.isfinite(x_end) and np.isfinite(y_end) and np.isfinite(l2)):
            break
        if iteration == 0:
            fallback = (x_end, y_end, l1, l2)
        elif abs(d2) <= tolerance * (abs(l2) + p.eta) and abs(y_end - state[1]) <= tolerance * (
            abs(y_end) + 1.0
        ):
            return x_end, y_end, l1, l2, True
    return fallback[0], fallback[1], fallback[2], fallback[3], False


@njit(cache=True)
def clip_to_range(x: float, v: float) -> tuple[float, float]:
    """Clip a position to [-0.5, 0.5]; at a wall, drop the velocity pushing further out."""
    if x > _HIGH:
        return _HIGH, min(v, 0.0)
    if x < _LOW:
        return _LOW, max(v, 0.0)
    return x, v


@njit(cache=True)
def optimal_control_step(
    x: float,
    y: float,
    partner_prediction: float,
    reference_velocity: float,
    partner_velocity: float,
    p: Record,
    coupled: bool = True,
) -> tuple[float, float, float]:
    """Advance the virtual trainer by one control period under its optimal control.

    Parameters are those of `solve_interval`; ``coupled`` is False for a player with no partner.

    Returns
    -------
    tuple of float
        Position (units, clipped to [-0.5, 0.5]) and velocity (units/s) at t_k + T, and the
        optimal control at t_k (units/s²).
    """
    x_next, y_next, _, l2, _ = solve_interval(
        x,
        y,
        partner_prediction,
        reference_velocity,
        partner_velocity,
        p,
        coupled,
        N_SUBSTEPS,
        MAX_NEWTON,
        NEWTON_TOLERANCE,
    )
    x_next, y_next = clip_to_range(x_next, y_next)
    return x_next, y_next, -l2 / p.eta


@njit(cache=True)
def partner_weights(p: Record, coupled: bool) -> tuple[float, float]:
    """Return the weights ``(theta_p, theta_v)`` of the partner terms in use.

    A player coupled to others uses its own; a player alone (no neighbour, METHODS section 8
    with an empty neighbourhood) has no partner to track, so both are 0 and the whole weight
    ``theta_s = 1`` goes to its reference velocity (**choice**: the methods do not say).
    """
    if coupled:
        return p.theta_p, p.theta_v
    return 0.0, 0.0


@njit(cache=True)
def integrate_hkb(x: float, v: float, u: float, p: Record, n_substeps: int) -> tuple[float, float]:
    """Advance the HKB end effector by one control period with u held constant (RK4).

    Parameters
    ----------
    x, v
        Position (units) and velocity (units/s) at the start of the period.
    u
        Acceleration input (units/s²), held over the period.
    p
        The end effector, a record of `PARAMS_DTYPE` (alpha, beta, gamma, omega and period are
        read).
    n_substeps
        Number of RK4 steps of length ``p.period / n_substeps``.

    Returns
    -------
    tuple of float
        Position and velocity at the end of the period; the position is clipped to [-0.5, 0.5]
        and an outward velocity at the boundary is set to zero.
    """
    return advance_hkb(x, v, u, p.alpha, p.beta, p.gamma, p.omega, p.period, n_substeps)


@njit(cache=True)
def advance_hkb(
    x: float,
    v: float,
    u: float,
    alpha: float,
    beta: float,
    gamma: float,
    omega: float,
    period: float,
    n_substeps: int,
) -> tuple[float, float]:
    """`integrate_hkb` with the parameters as numbers, for loops that hold them in registers."""
    h = period / n_substeps
    for _ in range(n_substeps):
        a1 = hkb_acceleration(x, v, u, alpha, beta, gamma, omega)
        x2, v2 = x + 0.5 * h * v, v + 0.5 * h * a1
        a2 = hkb_acceleration(x2, v2, u, alpha, beta, gamma, omega)
        x3, v3 = x + 0.5 * h * v2, v + 0.5 * h * a2
        a3 = hkb_acceleration(x3, v3, u, alpha, beta, gamma, omega)
        x4, v4 = x + h * v3, v + h * a3
        a4 = hkb_acceleration(x4, v4, u, alpha, beta, gamma, omega)
        x += h / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4)
        v += h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
    return clip_to_range(x, v)

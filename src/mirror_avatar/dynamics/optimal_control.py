"""The optimal control of one interval: Pontryagin's two-point problem solved by shooting.

The state and costates are integrated with fixed-step RK4 (`_shoot`, with sensitivities
`_shoot_with_sensitivities`); Newton's method on the two initial costates (`_newton`) refines
a first guess; the frozen-damping linear problem is tabulated once per parameter set
(`_tabulate_linear`). The method is in the package's docstring (`mirror_avatar.dynamics`).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from mirror_avatar.dynamics.hkb import Record, hkb_acceleration

N_SUBSTEPS = 4
"""Fewest RK4 steps per control interval in the shooting solve."""

STEP_STIFFNESS = 0.5
"""Largest RK4 step times the costate-control coupling rate: more substeps when needed."""

DAMPING_STIFFNESS = 0.4
"""Largest RK4 step times the HKB damping rate (at fast hand speeds the problem's stiffest)."""

MAX_RK4_SUBSTEPS = 4096
"""Most RK4 steps per control period (**choice**), whatever the state and parameters: it bounds
the cost of one step. Within the playing range at the paper's parameters, `count_substeps` asks
for at most a few hundred (a partner crossing the whole range in one period)."""

MAX_NEWTON = 8
"""Most chord iterations on the initial costates per control interval; a continuation stage
allows three times as many Newton iterations, halved steps included."""

NEWTON_TOLERANCE = 1e-3
"""Newton stops when the control at t_k and the end velocity change by less than this fraction
(the end state, extrapolated to first order in the last update, is then accurate to about its
square)."""

CONTINUATION_STAGES = 4
"""Steps of the continuation from the linear to the full problem when Newton alone fails."""

MIN_STEP_SCALE = 1.0 / 1024.0
"""Smallest fraction of a Newton step tried when the full step overshoots (backtracking)."""

LINEAR_GRID = 257
"""Frozen damping values at which the linear problem's solution map is tabulated."""

LINEAR_MAX_DAMPING = 64.0
"""Largest tabulated frozen damping (1/s): a hand at about 5.6 units/s with the paper's beta;
beyond it the frozen problem is integrated at each step."""

LINEAR_SUBSTEPS = 64
"""RK4 steps per interval when tabulating the linear problem (its solution to about 1e-12)."""

LINEAR_COLUMNS = 20
"""Numbers per tabulated map: the end state-costate (x, y, l1, l2) for unit initial x, y, l1, l2
(4 x 4) and for a unit forcing (4)."""


@njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"})
def _costate_rates(
    x: float,
    y: float,
    l1: float,
    l2: float,
    alpha: float,
    beta: float,
    gamma: float,
    omega: float,
    eta: float,
    tracking: float,
    forcing: float,
) -> tuple[float, float, float, float, float, float]:
    """Rates of the state-costate system, and the two coefficients its sensitivities share.

    ``tracking = theta_s + theta_v`` and ``forcing = theta_s r_s + theta_v r_v`` (the velocity
    terms of the cost). Returns ``(x', y', l1', l2', coupling, damping)`` with ``coupling =
    2 alpha x y + omega²`` and ``damping = alpha x² + 3 beta y² - gamma``, the derivatives of
    the HKB acceleration with respect to -x and -y.
    """
    coupling = 2.0 * alpha * x * y + omega * omega
    damping = alpha * x * x + 3.0 * beta * y * y - gamma
    return (
        y,
        hkb_acceleration(x, y, -l2 / eta, alpha, beta, gamma, omega),
        l2 * coupling,
        l2 * damping - l1 - tracking * y + forcing,
        coupling,
        damping,
    )


@njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"})
def _shoot(
    n_lanes: int,
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    l1: NDArray[np.float64],
    l2: NDArray[np.float64],
    alpha: NDArray[np.float64],
    beta: NDArray[np.float64],
    gamma: NDArray[np.float64],
    omega: NDArray[np.float64],
    eta: NDArray[np.float64],
    tracking: NDArray[np.float64],
    forcing: NDArray[np.float64],
    h: NDArray[np.float64],
    n_substeps: NDArray[np.int64],
) -> None:
    """Integrate the state and costates of ``n_lanes`` problems over one interval, in place.

    Problem ``j`` (lane ``j``: the first ``n_lanes`` entries of every array, shape (L,)) starts
    from ``(x, y, l1, l2)[j]`` and takes ``n_substeps[j]`` RK4 steps of ``h[j]`` seconds; the
    other arguments are those of `_costate_rates`, one per lane. The lanes advance in lockstep
    (a lane that has taken its steps keeps its end value, and the loop stops at the last lanes
    once they are done), so the compiler vectorises the lane loop; each lane's arithmetic is
    that of a problem integrated alone.
    """
    n_max = 0
    for j in range(n_lanes):
        n_max = max(n_max, n_substeps[j])
    for step in range(n_max):
        while n_lanes > 0 and n_substeps[n_lanes - 1] <= step:
            n_lanes -= 1  # the last lanes are done
        for j in range(n_lanes):
            x0, y0, m0, k0, hj = x[j], y[j], l1[j], l2[j], h[j]
            a, b, g, w = alpha[j], beta[j], gamma[j], omega[j]
            e, t, f = eta[j], tracking[j], forcing[j]
            a0, a1, a2, a3, _, _ = _costate_rates(x0, y0, m0, k0, a, b, g, w, e, t, f)
            b0, b1, b2, b3, _, _ = _costate_rates(
                x0 + 0.5 * hj * a0, y0 + 0.5 * hj * a1, m0 + 0.5 * hj * a2, k0 + 0.5 * hj * a3,
                a, b, g, w, e, t, f,
            )  # fmt: skip
            c0, c1, c2, c3, _, _ = _costate_rates(
                x0 + 0.5 * hj * b0, y0 + 0.5 * hj * b1, m0 + 0.5 * hj * b2, k0 + 0.5 * hj * b3,
                a, b, g, w, e, t, f,
            )  # fmt: skip
            d0, d1, d2, d3, _, _ = _costate_rates(
                x0 + hj * c0, y0 + hj * c1, m0 + hj * c2, k0 + hj * c3, a, b, g, w, e, t, f
            )
            going = step < n_substeps[j]
            x[j] = x0 + hj / 6.0 * (a0 + 2.0 * b0 + 2.0 * c0 + d0) if going else x0
            y[j] = y0 + hj / 6.0 * (a1 + 2.0 * b1 + 2.0 * c1 + d1) if going else y0
            l1[j] = m0 + hj / 6.0 * (a2 + 2.0 * b2 + 2.0 * c2 + d2) if going else m0
            l2[j] = k0 + hj / 6.0 * (a3 + 2.0 * b3 + 2.0 * c3 + d3) if going else k0


Twelve = tuple[float, float, float, float, float, float, float, float, float, float, float, float]
"""``[x, y, l1, l2, s]``: the state, costates and sensitivities of `_sensitivity_rates`."""
_ZEROS: Twelve = (0.0,) * 12


@njit(cache=True, nogil=True, fastmath={"contract"}, inline="always")
def _sensitivity_rates(
    z: Twelve,
    alpha: float,
    beta: float,
    gamma: float,
    omega: float,
    eta: float,
    tracking: float,
    forcing: float,
) -> Twelve:
    """Rates of ``z = [x, y, l1, l2, s]``, ``s`` the sensitivities, in the same layout.

    ``z[4 + 4 j : 8 + 4 j]`` = d(x, y, l1, l2) / d(initial costate j), j = 0 (l1) and 1 (l2).
    Tuples rather than arrays: the RK4 steps of `_shoot_with_sensitivities` keep them in
    registers.
    """
    x, y, l1, l2 = z[0], z[1], z[2], z[3]
    r0, r1, r2, r3, coupling, damping = _costate_rates(
        x, y, l1, l2, alpha, beta, gamma, omega, eta, tracking, forcing
    )
    a, b = 2.0 * alpha * l2, 6.0 * beta * l2 * y - tracking
    return (
        r0, r1, r2, r3,
        z[5], -coupling * z[4] - damping * z[5] - z[7] / eta,
        a * (y * z[4] + x * z[5]) + coupling * z[7],
        a * x * z[4] + b * z[5] - z[6] + damping * z[7],
        z[9], -coupling * z[8] - damping * z[9] - z[11] / eta,
        a * (y * z[8] + x * z[9]) + coupling * z[11],
        a * x * z[8] + b * z[9] - z[10] + damping * z[11],
    )  # fmt: skip


@njit(cache=True, nogil=True, fastmath={"contract"}, inline="always")
def _step_to(z: Twelve, h: float, rate: Twelve) -> Twelve:
    """Return ``z + h rate``, element by element."""
    return (
        z[0] + h * rate[0], z[1] + h * rate[1], z[2] + h * rate[2], z[3] + h * rate[3],
        z[4] + h * rate[4], z[5] + h * rate[5], z[6] + h * rate[6], z[7] + h * rate[7],
        z[8] + h * rate[8], z[9] + h * rate[9], z[10] + h * rate[10], z[11] + h * rate[11],
    )  # fmt: skip


@njit(cache=True, nogil=True, fastmath={"contract"})
def _shoot_with_sensitivities(
    x: float,
    y: float,
    l1: float,
    l2: float,
    alpha: float,
    beta: float,
    gamma: float,
    omega: float,
    eta: float,
    tracking: float,
    forcing: float,
    period: float,
    n_substeps: int,
    z: NDArray[np.float64],
) -> None:
    """`_shoot` with the sensitivities to the initial costates, into ``z`` (12,) in place.

    ``z`` receives the layout of `_sensitivity_rates` at the end of the interval. Each RK4
    step sums its stages' rates as ``((k1 + 2 k2) + 2 k3) + k4`` from zero.
    """
    h = period / n_substeps
    state = (x, y, l1, l2, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0)
    for _ in range(n_substeps):
        k1 = _sensitivity_rates(state, alpha, beta, gamma, omega, eta, tracking, forcing)
        total = _step_to(_ZEROS, 1.0, k1)
        k2 = _sensitivity_rates(
            _step_to(state, 0.5 * h, k1), alpha, beta, gamma, omega, eta, tracking, forcing
        )
        total = _step_to(total, 2.0, k2)
        k3 = _sensitivity_rates(
            _step_to(state, 0.5 * h, k2), alpha, beta, gamma, omega, eta, tracking, forcing
        )
        total = _step_to(total, 2.0, k3)
        k4 = _sensitivity_rates(
            _step_to(state, h, k3), alpha, beta, gamma, omega, eta, tracking, forcing
        )
        total = _step_to(total, 1.0, k4)
        state = _step_to(state, h / 6.0, total)
    for i in range(12):
        z[i] = state[i]


@njit(cache=True, nogil=True)
def _tabulate_linear(
    omega: float, eta: float, tracking: float, period: float, out: NDArray[np.float64]
) -> None:
    """Fill ``out`` (`LINEAR_GRID`, `LINEAR_COLUMNS`) with the frozen-damping solution maps.

    With the damping frozen at ``c`` the state-costate system is linear with constant
    coefficients, so its end value is ``M(c) [x, y, l1, l2](0) + g(c) forcing``; row ``i`` holds
    ``M`` column by column, then ``g``, at ``c = i LINEAR_MAX_DAMPING / (LINEAR_GRID - 1)``.
    """
    lanes = np.zeros((4, 5))
    ones = np.ones(5)
    zeros = np.zeros(5)
    forcing = np.zeros(5)
    forcing[4] = 1.0
    steps = np.full(5, LINEAR_SUBSTEPS)
    h = np.full(5, period / LINEAR_SUBSTEPS)
    for i in range(LINEAR_GRID):
        lanes[:, :] = 0.0
        for column in range(4):
            lanes[column, column] = 1.0
        gamma = -LINEAR_MAX_DAMPING * i / (LINEAR_GRID - 1) * ones
        _shoot(
            5, lanes[0], lanes[1], lanes[2], lanes[3], zeros, zeros, gamma, omega * ones,
            eta * ones, tracking * ones, forcing, h, steps,
        )  # fmt: skip
        for column in range(5):
            for r in range(4):
                out[i, 4 * column + r] = lanes[r, column]


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
    """RK4 steps for one interval: at least ``n_min``, and enough for the interval's rates.

    At most `MAX_RK4_SUBSTEPS`, so that no state (a hostile partner's jumps included) and no
    parameters within `PARAMETER_RANGES` make one step arbitrarily slow.

    The fastest rates (1/s) of the state-costate system are the costate-control coupling
    ``sqrt((theta_s + theta_v) / eta)`` (about 95/s for the leader) and the HKB damping
    ``alpha x² + 3 beta y² - gamma``, bounded with the largest of the current, reference and
    partner speeds (at 9 units/s the damping is about 490/s, and RK4 with the minimum steps
    would be unstable). A step times the coupling rate stays within `STEP_STIFFNESS`, times the
    damping within `DAMPING_STIFFNESS` (the tests check the resulting accuracy against a tight
    solution of the problem).
    """
    speed = max(abs(y), abs(reference_velocity), abs(partner_velocity) if theta_v > 0.0 else 0.0)
    damping = p.alpha * x * x + 3.0 * p.beta * speed * speed - p.gamma
    coupling = coupling_rate(p, theta_p)
    steps = max(damping / DAMPING_STIFFNESS, coupling / STEP_STIFFNESS) * p.period
    return min(MAX_RK4_SUBSTEPS, max(n_min, int(np.ceil(steps))))


@njit(cache=True, inline="always")
def coupling_rate(p: Record, theta_p: float) -> float:
    """Return the costate-control coupling rate ``sqrt((1 - theta_p) / eta)`` (1/s)."""
    return np.sqrt((1.0 - theta_p) / p.eta)


@njit(cache=True, nogil=True, inline="always")
def _jacobian(z: NDArray[np.float64], theta_p: float) -> tuple[float, float, float, float]:
    """`_residual_jacobian` from the sensitivities in ``z`` (layout of `_sensitivity_rates`)."""
    return _residual_jacobian(z[4], z[6], z[7], z[8], z[10], z[11], theta_p)


@njit(cache=True, nogil=True, inline="always")
def _residual_jacobian(
    x_l1: float, l1_l1: float, l2_l1: float, x_l2: float, l1_l2: float, l2_l2: float, theta_p: float
) -> tuple[float, float, float, float]:
    """Return ``(j11, j12, j21, j22)``, the Jacobian of the terminal residual.

    The residual is ``(l1(T) - theta_p (x(T) - r_p), l2(T))``; ``a_b`` is the derivative of
    ``a(T)`` in the initial costate ``b(0)``.
    """
    return l1_l1 - theta_p * x_l1, l1_l2 - theta_p * x_l2, l2_l1, l2_l2


@njit(cache=True, nogil=True, inline="always")
def _costate_update(
    j11: float, j12: float, j21: float, j22: float, r1: float, r2: float
) -> tuple[float, float]:
    """Return the costate update that solves the terminal residual ``(r1, r2)`` to first order."""
    det = j11 * j22 - j12 * j21
    return -(j22 * r1 - j12 * r2) / det, -(j11 * r2 - j21 * r1) / det


@njit(cache=True, nogil=True, inline="always")
def _newton_update(
    z: NDArray[np.float64], theta_p: float, r1: float, r2: float
) -> tuple[float, float]:
    """`_costate_update` with the Jacobian from the sensitivities in ``z`` (`_jacobian`)."""
    j11, j12, j21, j22 = _jacobian(z, theta_p)
    return _costate_update(j11, j12, j21, j22, r1, r2)


@njit(cache=True, nogil=True, inline="always")
def _converged(
    d2: float, l2: float, eta: float, y_end: float, y_shot: float, tolerance: float
) -> bool:
    """Check whether Newton has converged.

    True when the control changed by less than ``tolerance`` (relative) and the last update
    moved the end velocity (from the shot's ``y_shot``) by less than ``tolerance`` (relative,
    floor 1 unit/s).
    """
    return abs(d2) <= tolerance * (abs(l2) + eta) and abs(y_end - y_shot) <= tolerance * (
        abs(y_end) + 1.0
    )


@njit(cache=True, nogil=True)
def _newton(
    x: float,
    y: float,
    partner_prediction: float,
    l1: float,
    l2: float,
    alpha: float,
    beta: float,
    p: Record,
    theta_p: float,
    tracking: float,
    forcing: float,
    n: int,
    tolerance: float,
    z: NDArray[np.float64],
) -> tuple[bool, float, float, float, float]:
    """Full Newton on the initial costates from ``(l1, l2)``, halving steps that overshoot.

    Every iteration integrates the sensitivities (`_shoot_with_sensitivities`, scratch ``z``);
    a step that makes the terminal residual larger or the shooting overflow is halved (down to
    `MIN_STEP_SCALE`). ``alpha`` and ``beta`` are the nonlinear damping coefficients in use
    (`_continuation` scales them). Returns ``(converged, l1, l2, x(T), y(T))``, the end state
    extrapolated to first order in the last update.
    """
    gamma, omega, eta, period = p.gamma, p.omega, p.eta, p.period
    residual, scale, d1, d2 = np.inf, 1.0, 0.0, 0.0
    for _ in range(3 * MAX_NEWTON):
        _shoot_with_sensitivities(
            x, y, l1, l2, alpha, beta, gamma, omega, eta, tracking, forcing, period, n, z
        )
        r1 = z[2] - theta_p * (z[0] - partner_prediction)
        r2 = z[3]
        size = abs(r1) + abs(r2)
        if not size <= residual:  # larger, or not a number
            if scale <= MIN_STEP_SCALE:
                break
            scale *= 0.5
            l1 -= scale * d1
            l2 -= scale * d2
            continue
        d1, d2 = _newton_update(z, theta_p, r1, r2)
        l1 += d1
        l2 += d2
        scale, residual = 1.0, size
        y_end = z[1] + z[5] * d1 + z[9] * d2
        if _converged(d2, l2, eta, y_end, z[1], tolerance):
            return True, l1, l2, z[0] + z[4] * d1 + z[8] * d2, y_end
    return False, l1, l2, np.nan, np.nan

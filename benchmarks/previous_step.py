"""The optimal-control step as it was before the tabulated linear start (the speed baseline).

`previous_solve_interval` is the solver of mirror-avatar 0.x up to this change, kept here, not in
the package, so that `bench_step` measures the new step against it in the same run: Newton
shooting from the frozen-damping solution integrated at every step (RK4 on the state, costates
and sensitivities in arrays), then chord iterations. It reads only the scalar fields of a
parameter record, as before.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from mirror_avatar.dynamics import (
    Record,
    count_substeps,
    hkb_acceleration,
    partner_weights,
)


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
def previous_solve_interval(
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

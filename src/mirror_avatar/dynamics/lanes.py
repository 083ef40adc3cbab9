"""Many optimal-control problems solved together, in lockstep (`solve_intervals`).

The plain shots of all problems of a period are integrated by one loop over the problems that
the compiler vectorises, while each problem's iterations stop on its own test, so every problem
gets the result it gets alone; one problem is the case of one (`solve_interval`). A problem's
numbers live in one column of the lane array, in the rows named here; its first guess is the
frozen-damping solution read from the tabulated maps (`_frozen_guess`).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from mirror_avatar.dynamics.hkb import Record, clip_to_range, partner_weights
from mirror_avatar.dynamics.optimal_control import (
    CONTINUATION_STAGES,
    LINEAR_GRID,
    LINEAR_MAX_DAMPING,
    MAX_NEWTON,
    N_SUBSTEPS,
    NEWTON_TOLERANCE,
    _converged,
    _costate_update,
    _newton,
    _residual_jacobian,
    _shoot,
    _shoot_with_sensitivities,
    count_substeps,
)

X, Y, L1, L2 = 0, 1, 2, 3
END = 4
"""Rows END .. END + 3: the last shot's end state-costate (x, y, l1, l2), then the update's
extrapolated end state (x, y) once a lane is solved."""
ALPHA, BETA, GAMMA, OMEGA, ETA, TRACKING, FORCING, STEP = range(8, 16)
"""Rows of the per-lane arguments of `_shoot`, in its order (STEP: the RK4 step, s)."""
PREDICTION, THETA_P, PREVIOUS, RESIDUAL = 16, 17, 18, 19
SENSITIVITY = 20
"""Rows SENSITIVITY .. SENSITIVITY + 3: d x(T) / d l1(0), d y(T) / d l1(0), d x(T) / d l2(0),
d y(T) / d l2(0) (the end state's first-order response to the costate update)."""
JACOBIAN = 24
"""Rows JACOBIAN .. JACOBIAN + 3: j11, j12, j21, j22 of the terminal residual in the initial
costates (`_jacobian`)."""
FALLBACK = 28
"""Rows FALLBACK .. FALLBACK + 3: the frozen-damping solution (x(T), y(T), l1(0), l2(0))."""
FROZEN = 32
"""Row of the damping (1/s) frozen in the initial guess's linear problem."""
LANE_ROWS = 33
"""Rows of the lane array of `solve_intervals`, shape (LANE_ROWS, L): one column per problem,
the rows named by the constants above (X, Y, L1, L2: the start state and current costates)."""

ITERATING, SOLVED, CONTINUING = 0, 1, 2
"""A lane's status in `solve_intervals`: in the chord iterations, solved, or left to the
continuation."""

PROBLEM_COLUMNS = 5
"""Numbers per problem in `solve_intervals`: position and velocity at t_k, the partner's
predicted position, the reference velocity and the partner's velocity."""


@njit(cache=True, nogil=True, inline="always")
def _frozen_guess(
    lanes: NDArray[np.float64],
    j: int,
    p: Record,
    table: int,
    n_substeps: int,
    z: NDArray[np.float64],
) -> None:
    """Solve lane ``j``'s frozen-damping problem from costates (0, 0) into its shot rows.

    The damping is frozen at the lane's `FROZEN` row; the solution's end state-costate and
    sensitivities are stored as `_keep_shot` stores a shot. They are interpolated (linearly in
    the damping) from the record's table ``p.linear[table]`` within `LINEAR_MAX_DAMPING`, and
    integrated (`_shoot_with_sensitivities`, ``z`` scratch) beyond it.
    """
    x, y, frozen = lanes[X, j], lanes[Y, j], lanes[FROZEN, j]
    tracking, forcing, theta_p = lanes[TRACKING, j], lanes[FORCING, j], lanes[THETA_P, j]
    where = frozen / LINEAR_MAX_DAMPING * (LINEAR_GRID - 1)
    if where >= LINEAR_GRID - 1:
        _shoot_with_sensitivities(
            x, y, 0.0, 0.0, 0.0, 0.0, -frozen, p.omega, p.eta, tracking, forcing, p.period,
            n_substeps, z,
        )  # fmt: skip
        _keep_shot(z, theta_p, lanes, j)
        return
    i = int(where)
    w = where - i
    low, high = p.linear[table, i], p.linear[table, i + 1]
    for r in range(4):
        free = x * _lerp(low, high, r, w)
        free += y * _lerp(low, high, 4 + r, w)
        free += forcing * _lerp(low, high, 16 + r, w)
        lanes[END + r, j] = free
    _keep_sensitivities(
        _lerp(low, high, 8, w), _lerp(low, high, 9, w), _lerp(low, high, 10, w),
        _lerp(low, high, 11, w), _lerp(low, high, 12, w), _lerp(low, high, 13, w),
        _lerp(low, high, 14, w), _lerp(low, high, 15, w), theta_p, lanes, j,
    )  # fmt: skip


@njit(cache=True, nogil=True, inline="always")
def _lerp(low: NDArray[np.float64], high: NDArray[np.float64], column: int, w: float) -> float:
    """Interpolate a column of two table rows: weight ``w`` on ``high``."""
    return low[column] * (1.0 - w) + high[column] * w


@njit(cache=True, nogil=True)
def solve_intervals(
    problems: NDArray[np.float64],
    coupled: NDArray[np.bool_],
    params: NDArray[np.void],
    which: NDArray[np.int64],
    n_min: int,
    max_newton: int,
    tolerance: float,
    out: NDArray[np.float64],
) -> None:
    """Solve many intervals' optimal-control problems without clipping, in lockstep.

    Shooting on the two initial costates, Newton's method on the two terminal conditions:

    1. The initial guess is the exact solution of the problem with the HKB damping frozen at
       its mean along a velocity ramp from ``y`` to ``r_s`` (a linear problem, tabulated per
       parameter set in the record's ``linear`` field, `_frozen_guess`); its Jacobian (the
       sensitivities of the end state-costate to the initial costates) starts the iterations.
    2. Chord iterations: each shoots the full nonlinear state and costates (`_shoot`, 4
       numbers) and updates the costates with the last Jacobian; when an update fails to
       shrink at least twofold, the next iteration also integrates the sensitivities
       (`_shoot_with_sensitivities`), a full Newton step. It stops when the control at t_k
       changes by less than ``tolerance`` (relative) and the last update moves the end
       velocity by less than ``tolerance`` (relative, floor 1 unit/s); the end state is
       extrapolated to first order in that last update.
    3. At fast hand speeds the damping ``3 beta y²`` makes the problem strongly nonlinear and
       forward shooting sensitive: when the first nonlinear residual exceeds the frozen
       problem's residual at costates (0, 0), the shooting overflows, or the chord iterations
       have not converged after ``max_newton`` iterations, the problem is solved by
       continuation instead: full Newton (`_newton`, with step halving) on the problem with
       the nonlinear damping coefficients scaled by 0, 1/4, ..., 1, each from the last.

    If the continuation fails too, the frozen-damping solution is returned, flagged as not
    converged.

    The problems are independent: the plain shots of every problem still iterating are taken
    together by one call of `_shoot` (vectorised across them), the rest problem by problem. A
    problem's result does not depend on the others solved with it.

    Parameters
    ----------
    problems
        One row per problem, shape (L, `PROBLEM_COLUMNS`): position (units) and velocity
        (units/s) at t_k, the partner's predicted position at t_k + T (units), the reference
        velocity r_s (units/s) and the partner's estimated velocity r_v (units/s, used when
        theta_v > 0).
    coupled
        False for a player alone: the partner terms are dropped (see `partner_weights`),
        shape (L,).
    params, which
        The parameter sets, records of `PARAMS_DTYPE` (`records`), shape (P,), and each
        problem's row in them, shape (L,).
    n_min, max_newton
        Fewest RK4 steps per interval (`count_substeps` adds more where the interval is stiff)
        and the most chord iterations before the continuation takes over.
    tolerance
        Convergence threshold (`NEWTON_TOLERANCE` in `optimal_control_steps`).
    out
        Receives, shape (L, 5): ``x(T), y(T), lambda1(0), lambda2(0)`` and 1.0 where
        converged, 0.0 where the frozen-damping fallback is used. The optimal control at t_k is
        ``-lambda2(0) / eta``.
    """
    n_lanes = problems.shape[0]
    lanes = np.empty((LANE_ROWS, n_lanes))
    steps = np.empty(n_lanes, np.int64)
    index = np.arange(n_lanes)
    refresh = np.zeros(n_lanes, np.bool_)
    status = np.empty(n_lanes, np.int64)
    z = np.empty(12)
    _start_lanes(problems, coupled, params, which, n_min, lanes, steps, z)
    active = n_lanes
    for iteration in range(max_newton + 1):
        if iteration > 0:
            _shoot_lanes(lanes, steps, refresh, params, which, index, active, z)
        _chord_updates(lanes, refresh, status, active, iteration, tolerance)
        active = _retire(
            lanes, steps, index, refresh, status, active, problems, params, which, tolerance,
            z, out,
        )  # fmt: skip
        if active == 0:
            return
    status[:active] = CONTINUING
    _retire(
        lanes, steps, index, refresh, status, active, problems, params, which, tolerance, z, out
    )


@njit(cache=True, nogil=True)
def _start_lanes(
    problems: NDArray[np.float64],
    coupled: NDArray[np.bool_],
    params: NDArray[np.void],
    which: NDArray[np.int64],
    n_min: int,
    lanes: NDArray[np.float64],
    steps: NDArray[np.int64],
    z: NDArray[np.float64],
) -> None:
    """Fill the problems' lanes (one column of the lane array each) and their RK4 steps.

    The costates start at 0 with the frozen-damping solution's end state and sensitivities
    (`_frozen_guess`, ``z`` scratch). The problems' coefficients are computed in a first pass
    over them all and the guesses, read from the tables, in a second: two short loops, whose
    independent iterations the processor overlaps, run faster than one long one.
    """
    for j in range(problems.shape[0]):
        steps[j] = _lane_coefficients(problems[j], coupled[j], params[which[j]], n_min, lanes, j)
    for j in range(problems.shape[0]):
        _frozen_guess(lanes, j, params[which[j]], 0 if coupled[j] else 1, steps[j], z)


@njit(cache=True, nogil=True, inline="always")
def _lane_coefficients(
    problem: NDArray[np.float64],
    coupled: bool,
    p: Record,
    n_min: int,
    lanes: NDArray[np.float64],
    j: int,
) -> int:
    """Fill lane ``j`` but for its shot rows; return its RK4 steps (`count_substeps`).

    The damping frozen for the initial guess (row `FROZEN`) is the HKB damping's mean along a
    velocity ramp from ``y`` to ``r_s``.
    """
    x, y, prediction, reference_velocity, partner_velocity = (
        problem[0], problem[1], problem[2], problem[3], problem[4]
    )  # fmt: skip
    theta_p, theta_v = partner_weights(p, coupled)
    tracking = 1.0 - theta_p
    forcing = (tracking - theta_v) * reference_velocity + theta_v * partner_velocity
    n = count_substeps(x, y, reference_velocity, partner_velocity, p, theta_p, theta_v, n_min)
    mean_square = (y * y + y * reference_velocity + reference_velocity * reference_velocity) / 3.0
    lanes[FROZEN, j] = max(p.alpha * x * x + p.beta * mean_square - p.gamma, 0.0)
    lanes[X, j], lanes[Y, j], lanes[L1, j], lanes[L2, j] = x, y, 0.0, 0.0
    lanes[ALPHA, j], lanes[BETA, j], lanes[GAMMA, j], lanes[OMEGA, j] = (
        p.alpha, p.beta, p.gamma, p.omega
    )  # fmt: skip
    lanes[ETA, j], lanes[TRACKING, j], lanes[FORCING, j] = p.eta, tracking, forcing
    lanes[STEP, j], lanes[PREDICTION, j], lanes[THETA_P, j] = p.period / n, prediction, theta_p
    lanes[PREVIOUS, j] = lanes[RESIDUAL, j] = np.inf
    lanes[FALLBACK, j], lanes[FALLBACK + 1, j] = x, y
    lanes[FALLBACK + 2, j], lanes[FALLBACK + 3, j] = 0.0, 0.0
    return n


@njit(cache=True, nogil=True, inline="always")
def _keep_shot(z: NDArray[np.float64], theta_p: float, lanes: NDArray[np.float64], j: int) -> None:
    """Store a shot with sensitivities ``z`` (layout of `_sensitivity_rates`) in lane ``j``."""
    lanes[END, j], lanes[END + 1, j], lanes[END + 2, j], lanes[END + 3, j] = z[0], z[1], z[2], z[3]
    _keep_sensitivities(z[4], z[5], z[6], z[7], z[8], z[9], z[10], z[11], theta_p, lanes, j)


@njit(cache=True, nogil=True, inline="always")
def _keep_sensitivities(
    x_l1: float,
    y_l1: float,
    l1_l1: float,
    l2_l1: float,
    x_l2: float,
    y_l2: float,
    l1_l2: float,
    l2_l2: float,
    theta_p: float,
    lanes: NDArray[np.float64],
    j: int,
) -> None:
    """Store the end state-costate's sensitivities in lane ``j``.

    ``a_b`` is the derivative of ``a(T)`` in the initial costate ``b(0)``. The lane keeps those
    of the end state, which the updates extrapolate with, and the Jacobian of the terminal
    residual (`_residual_jacobian`).
    """
    s, jac = SENSITIVITY, JACOBIAN
    lanes[s, j], lanes[s + 1, j], lanes[s + 2, j], lanes[s + 3, j] = x_l1, y_l1, x_l2, y_l2
    lanes[jac, j], lanes[jac + 1, j], lanes[jac + 2, j], lanes[jac + 3, j] = _residual_jacobian(
        x_l1, l1_l1, l2_l1, x_l2, l1_l2, l2_l2, theta_p
    )


@njit(cache=True, nogil=True)
def _shoot_lanes(
    lanes: NDArray[np.float64],
    steps: NDArray[np.int64],
    refresh: NDArray[np.bool_],
    params: NDArray[np.void],
    which: NDArray[np.int64],
    index: NDArray[np.int64],
    active: int,
    z: NDArray[np.float64],
) -> None:
    """Shoot the first ``active`` lanes from their costates, into their END rows.

    All are shot together (`_shoot`); those due a Newton step are then shot again one by one
    with their sensitivities (`_shoot_with_sensitivities`, ``z`` scratch).
    """
    for row in range(4):
        lanes[END + row, :active] = lanes[X + row, :active]
    _shoot(
        active, lanes[END], lanes[END + 1], lanes[END + 2], lanes[END + 3], lanes[ALPHA],
        lanes[BETA], lanes[GAMMA], lanes[OMEGA], lanes[ETA], lanes[TRACKING], lanes[FORCING],
        lanes[STEP], steps,
    )  # fmt: skip
    for j in range(active):
        if refresh[j]:
            lane, p = lanes[:, j], params[which[index[j]]]
            _shoot_with_sensitivities(
                lane[X], lane[Y], lane[L1], lane[L2], p.alpha, p.beta, p.gamma, p.omega, p.eta,
                lane[TRACKING], lane[FORCING], p.period, steps[j], z,
            )  # fmt: skip
            _keep_shot(z, lane[THETA_P], lanes, j)


@njit(cache=True, nogil=True, error_model="numpy")
def _chord_updates(
    lanes: NDArray[np.float64],
    refresh: NDArray[np.bool_],
    status: NDArray[np.int64],
    active: int,
    iteration: int,
    tolerance: float,
) -> None:
    """Update the first ``active`` lanes' costates from their last shots (chord or Newton steps).

    Sets each one's status: `SOLVED` once converged (its END rows then hold the extrapolated
    end state), `CONTINUING` when the first nonlinear residual exceeds the frozen problem's
    or the shooting overflows; and whether its next shot integrates sensitivities.
    """
    s, jac = SENSITIVITY, JACOBIAN
    for j in range(active):
        theta_p, x_shot, y_shot = lanes[THETA_P, j], lanes[END, j], lanes[END + 1, j]
        r1 = lanes[END + 2, j] - theta_p * (x_shot - lanes[PREDICTION, j])
        r2 = lanes[END + 3, j]
        j11, j12, j21, j22 = lanes[jac, j], lanes[jac + 1, j], lanes[jac + 2, j], lanes[jac + 3, j]
        d1, d2 = _costate_update(j11, j12, j21, j22, r1, r2)
        l1, l2 = lanes[L1, j] + d1, lanes[L2, j] + d2
        # End state to first order in the update (exact once the iteration has converged).
        x_end = x_shot + lanes[s, j] * d1 + lanes[s + 2, j] * d2
        y_end = y_shot + lanes[s + 1, j] * d1 + lanes[s + 3, j] * d2
        size = abs(r1) + abs(r2)
        finite = np.isfinite(x_end) and np.isfinite(y_end) and np.isfinite(l2)
        diverging = iteration == 1 and not size <= lanes[RESIDUAL, j]
        done = iteration > 0 and _converged(d2, l2, lanes[ETA, j], y_end, y_shot, tolerance)
        status[j] = CONTINUING if diverging or not finite else (SOLVED if done else ITERATING)
        if iteration == 0 and finite:
            lanes[FALLBACK, j], lanes[FALLBACK + 1, j] = x_end, y_end
            lanes[FALLBACK + 2, j], lanes[FALLBACK + 3, j] = l1, l2
        lanes[L1, j], lanes[L2, j], lanes[END, j], lanes[END + 1, j] = l1, l2, x_end, y_end
        refresh[j] = iteration > 0 and abs(d2) > 0.5 * lanes[PREVIOUS, j]
        lanes[PREVIOUS, j], lanes[RESIDUAL, j] = abs(d2), size


@njit(cache=True, nogil=True)
def _retire(
    lanes: NDArray[np.float64],
    steps: NDArray[np.int64],
    index: NDArray[np.int64],
    refresh: NDArray[np.bool_],
    status: NDArray[np.int64],
    active: int,
    problems: NDArray[np.float64],
    params: NDArray[np.void],
    which: NDArray[np.int64],
    tolerance: float,
    z: NDArray[np.float64],
    out: NDArray[np.float64],
) -> int:
    """Write out the first ``active`` lanes that are solved or left to the continuation.

    A solved lane's result goes to its row of ``out``; a lane left to the continuation is
    solved by it (`_continuation`) now. The last active lane moves into each one's place (a
    written-out lane is not read again); returns the number of lanes still iterating (the first
    ones).
    """
    j = 0
    while j < active:
        if status[j] == ITERATING:
            j += 1
            continue
        row = index[j]
        if status[j] == SOLVED:
            out[row, 0], out[row, 1] = lanes[END, j], lanes[END + 1, j]
            out[row, 2], out[row, 3], out[row, 4] = lanes[L1, j], lanes[L2, j], 1.0
        else:
            p = params[which[row]]
            _continuation(problems[row], p, lanes[:, j], steps[j], z, tolerance, out[row])
        active -= 1
        for r in range(LANE_ROWS):
            lanes[r, j] = lanes[r, active]
        steps[j], index[j] = steps[active], index[active]
        refresh[j], status[j] = refresh[active], status[active]
    return active


@njit(cache=True, nogil=True)
def _continuation(
    problem: NDArray[np.float64],
    p: Record,
    lane: NDArray[np.float64],
    n_substeps: int,
    z: NDArray[np.float64],
    tolerance: float,
    out: NDArray[np.float64],
) -> None:
    """Solve a lane's problem by continuation in the nonlinear damping, into ``out``.

    Falls back to the lane's frozen-damping solution (flagged 0.0) if a stage fails to
    converge; ``z`` is scratch.
    """
    x, y, partner_prediction = problem[0], problem[1], problem[2]
    theta_p, tracking, forcing = lane[THETA_P], lane[TRACKING], lane[FORCING]
    l1 = l2 = x_end = y_end = 0.0
    for stage in range(CONTINUATION_STAGES + 1):
        share = stage / CONTINUATION_STAGES
        converged, l1, l2, x_end, y_end = _newton(
            x, y, partner_prediction, l1, l2, p.alpha * share, p.beta * share, p, theta_p,
            tracking, forcing, n_substeps, tolerance, z,
        )  # fmt: skip
        if not converged:
            out[:4] = lane[FALLBACK : FALLBACK + 4]
            out[4] = 0.0
            return
    out[0], out[1], out[2], out[3], out[4] = x_end, y_end, l1, l2, 1.0


@njit(cache=True, nogil=True)
def solve_interval(
    x: float,
    y: float,
    partner_prediction: float,
    reference_velocity: float,
    partner_velocity: float,
    params: NDArray[np.void],
    coupled: bool,
    n_substeps: int,
    max_newton: int,
    tolerance: float,
) -> tuple[float, float, float, float, bool]:
    """`solve_intervals` of one problem; ``params`` holds its parameters' record, shape (1,).

    Returns ``(x(T), y(T), lambda1(0), lambda2(0), converged)``.
    """
    problems = np.array([[x, y, partner_prediction, reference_velocity, partner_velocity]])
    out = np.empty((1, 5))
    first = np.zeros(1, np.int64)
    solve_intervals(
        problems, np.array([coupled]), params, first, n_substeps, max_newton, tolerance, out
    )
    return out[0, 0], out[0, 1], out[0, 2], out[0, 3], out[0, 4] != 0.0


@njit(cache=True, nogil=True)
def optimal_control_steps(
    problems: NDArray[np.float64],
    coupled: NDArray[np.bool_],
    params: NDArray[np.void],
    which: NDArray[np.int64],
    out: NDArray[np.float64],
) -> None:
    """Advance virtual trainers by one control period under their optimal controls.

    Parameters are those of `solve_intervals`: one problem per row of ``problems`` (L, 5).
    ``out`` (L, 3) receives each one's position (units, clipped to [-0.5, 0.5]) and velocity
    (units/s) at t_k + T, and its optimal control at t_k (units/s²).
    """
    n_lanes = problems.shape[0]
    solved = np.empty((n_lanes, 5))
    solve_intervals(
        problems, coupled, params, which, N_SUBSTEPS, MAX_NEWTON, NEWTON_TOLERANCE, solved
    )
    for j in range(n_lanes):
        out[j, 0], out[j, 1] = clip_to_range(solved[j, 0], solved[j, 1])
        out[j, 2] = -solved[j, 3] / params[which[j]].eta

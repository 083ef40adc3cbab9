"""Tests of the HKB end effector: the optimal-control step against a tight nonlinear BVP
solution, and the RK4 step of the cyber player against scipy's ODE solver."""

from functools import cache

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from mirror_avatar.common.errors import InputError
from mirror_avatar.dynamics import (
    FOLLOWER,
    FORCING,
    FROZEN,
    HKB_FIELDS,
    JOINT,
    LANE_ROWS,
    LEADER,
    MAX_NEWTON,
    N_SUBSTEPS,
    NEWTON_TOLERANCE,
    PARAMS_DTYPE,
    THETA_P,
    TRACKING,
    HKBParams,
    X,
    Y,
    clip_to_range,
    hkb_acceleration,
    integrate_hkb,
    optimal_control_steps,
    preset,
    records,
    solve_interval,
    solve_intervals,
)
from mirror_avatar.dynamics.lanes import _frozen_guess, _keep_shot
from mirror_avatar.dynamics.optimal_control import _shoot_with_sensitivities
from mirror_avatar.engine.loop import play
from mirror_avatar.players import VirtualTrainer
from mirror_avatar.testing import solve_step_bvp


def solve_reference(params: HKBParams, x0, y0, rp, rs, rv) -> tuple[float, float, float]:
    """The nonlinear two-point BVP of METHODS section 5 solved by scipy at tolerance 1e-8."""
    return solve_step_bvp(params, x0, y0, rp, rs, rv)


def step(params: HKBParams, x0, y0, rp, rs, rv, coupled=True) -> tuple[float, float, float]:
    out = np.empty((1, 3))
    problem = np.array([[x0, y0, rp, rs, rv]])
    optimal_control_steps(problem, np.array([coupled]), params.record(), np.zeros(1, int), out)
    return out[0, 0], out[0, 1], out[0, 2]


@cache
def grid() -> list[tuple[str, float, float, float, float, float]]:
    """Starting states, partner predictions and references, for every role."""
    rng = np.random.default_rng(2024)
    cases = []
    for role in ("leader", "follower", "joint"):
        for _ in range(25):
            x0 = rng.uniform(-0.45, 0.45)
            rp = float(np.clip(x0 + rng.uniform(-0.1, 0.1), -0.5, 0.5))
            cases.append((role, x0, rng.uniform(-2, 2), rp, rng.uniform(-2, 2), rng.uniform(-2, 2)))
    return cases


def relative_error(value: float, truth: float, floor: float = 0.05) -> float:
    """Error relative to the true value, with a floor of 0.05 units/s (velocities near zero)."""
    return abs(value - truth) / max(abs(truth), floor)


def solve(params: HKBParams, x0, y0, rp, rs, rv, coupled=True):
    """The step's solver, unclipped: ``(x(T), y(T), u(0), converged)``."""
    x, y, _, l2, converged = solve_interval(
        x0, y0, rp, rs, rv, params.record(), coupled, N_SUBSTEPS, MAX_NEWTON, NEWTON_TOLERANCE
    )
    return x, y, -l2 / params.eta, converged


def assert_tight(params: HKBParams, x0, y0, rp, rs, rv) -> None:
    """End position within 1e-5 units, end velocity within 1 %, control within 0.1 %."""
    x_true, y_true, u_true = solve_reference(params, x0, y0, rp, rs, rv)
    x_end, y_end, u0, converged = solve(params, x0, y0, rp, rs, rv)
    assert converged
    assert abs(x_end - x_true) < 1e-5
    assert relative_error(y_end, y_true) < 0.01
    assert relative_error(u0, u_true, floor=1.0) < 0.001


@pytest.mark.parametrize("case", range(75))
def test_step_matches_tight_bvp_solution(case: int) -> None:
    role, x0, y0, rp, rs, rv = grid()[case]
    assert_tight(preset(role), x0, y0, rp, rs, rv)
    x_true, y_true, _ = solve_reference(preset(role), x0, y0, rp, rs, rv)
    x_end, y_end, _ = step(preset(role), x0, y0, rp, rs, rv)
    assert (x_end, y_end) == pytest.approx(clip_to_range(x_true, y_true), abs=1e-3)


def test_problems_solved_together_are_each_solved_as_alone() -> None:
    """Lockstep solving (vectorised shots, lanes finishing at different iterations, Newton
    refreshes, continuations at fast speeds) gives every problem its result alone, bit for bit."""
    cases = list(grid()) + [("leader", 0.0, y0, 0.0, rs, 0.0) for y0, rs in FAST_STATES]
    problems = np.array([case[1:] for case in cases])
    params = records([preset(case[0]) for case in cases])
    coupled = np.arange(len(cases)) % 4 != 3
    together = np.empty((len(cases), 5))
    which = np.arange(len(cases))
    solve_intervals(
        problems, coupled, params, which, N_SUBSTEPS, MAX_NEWTON, NEWTON_TOLERANCE, together
    )
    for j, case in enumerate(cases):
        alone = solve_interval(
            *case[1:], params[j : j + 1], coupled[j], N_SUBSTEPS, MAX_NEWTON, NEWTON_TOLERANCE
        )
        assert tuple(together[j]) == (*alone[:4], float(alone[4]))


def quadratic_in_time_step(params: HKBParams, x0, y0, rp, rs) -> tuple[float, float]:
    """The closed-form shortcut: constant acceleration a (x quadratic in time) minimising J.

    With x(t) = x0 + y0 t + a t²/2 and u = a, J is quadratic in a; its minimiser is closed form.
    """
    T, tp, ts, eta = params.period, params.theta_p, params.theta_s, params.eta
    # J(a) = tp/2 (e + a T²/2)² + 1/2 ∫ ts (d + a t)² + eta a² dt, e = x0 + y0 T - rp, d = y0 - rs
    e, d = x0 + y0 * T - rp, y0 - rs
    curvature = tp * T**4 / 4 + ts * T**3 / 3 + eta * T
    slope = tp * e * T**2 / 2 + ts * d * T**2 / 2
    a = -slope / curvature
    return x0 + y0 * T + a * T**2 / 2, y0 + a * T


def test_closed_form_shortcut_is_not_what_runs() -> None:
    shortcut, compiled = [], []
    for role, x0, y0, rp, rs, rv in grid():
        if role == "joint":
            continue
        params = preset(role)
        x_true, y_true, u_true = solve_reference(params, x0, y0, rp, rs, rv)
        if abs(x_true) >= 0.5:
            continue
        _, y_short = quadratic_in_time_step(params, x0, y0, rp, rs)
        _, y_step, u_step = step(params, x0, y0, rp, rs, rv)
        u_short = (y_short - y0) / params.period
        shortcut.append((relative_error(y_short, y_true), relative_error(u_short, u_true, 1.0)))
        compiled.append((relative_error(y_step, y_true), relative_error(u_step, u_true, 1.0)))
    velocity_short, control_short = np.median(shortcut, axis=0)
    assert velocity_short > 0.1 and control_short > 0.3
    assert np.max(compiled) < 0.01


def test_velocity_tracks_reference_within_a_few_periods() -> None:
    x, y = 0.0, 0.0
    for _ in range(20):
        x, y, _ = step(LEADER, x, y, x, 0.8, 0.0)
    assert y == pytest.approx(0.8, rel=0.1)


def test_follower_converges_to_a_still_partner() -> None:
    x, y = -0.3, 0.0
    for _ in range(200):
        x, y, _ = step(FOLLOWER, x, y, 0.2, 0.0, 0.0)
    assert x == pytest.approx(0.2, abs=0.01)


@pytest.mark.parametrize("case", range(0, 75, 5))
def test_a_player_alone_solves_the_problem_without_partner_terms(case: int) -> None:
    """Uncoupled, the step is the tight solution with theta_p = theta_v = 0 (theta_s = 1)."""
    role, x0, y0, rp, rs, rv = grid()[case]
    alone = preset(role).with_(theta_p=0.0, theta_v=0.0)
    x_true, y_true, u_true = solve_reference(alone, x0, y0, rp, rs, rv)
    x_true, y_true = clip_to_range(x_true, y_true)
    x_end, y_end, u0 = step(preset(role), x0, y0, rp + 0.3, rs, rv + 1.0, coupled=False)
    assert abs(x_end - x_true) < 1e-3
    assert relative_error(y_end, y_true) < 0.05
    assert relative_error(u0, u_true, floor=1.0) < 0.05


def test_position_is_clipped_at_the_wall() -> None:
    x, y, _ = step(LEADER, 0.49, 2.0, 0.6, 2.0, 0.0)
    assert x == 0.5 and y == 0.0


def test_parameters_reach_compiled_code_by_name() -> None:
    table = records([LEADER, None, FOLLOWER])
    assert table.dtype == PARAMS_DTYPE and table.shape == (3,)
    assert table[0]["omega"] == LEADER.omega and table[2]["theta_p"] == FOLLOWER.theta_p
    assert all(table[1][name] == 0.0 for name in HKB_FIELDS) and not table[1]["linear"].any()
    assert LEADER.record()[0]["period"] == LEADER.period


def test_acceleration_formula() -> None:
    assert hkb_acceleration(0.5, 2.0, 1.0, 1.0, 2.0, -1.0, 0.8) == pytest.approx(
        -(0.25 + 8.0 + 1.0) * 2.0 - 0.64 * 0.5 + 1.0
    )


def test_presets_and_overrides() -> None:
    assert (LEADER.theta_p, LEADER.omega, FOLLOWER.theta_p, FOLLOWER.omega) == (0.1, 0.8, 0.9, 0.1)
    assert JOINT.theta_v > 0 and JOINT.theta_s == pytest.approx(1 - JOINT.theta_p - JOINT.theta_v)
    assert LEADER.with_(omega=1.0).omega == 1.0
    assert preset("follower") is FOLLOWER
    with pytest.raises(InputError, match="unknown role"):
        preset("coach")
    with pytest.raises(InputError, match="exceed 1"):
        HKBParams(omega=1.0, theta_p=0.8, theta_v=0.5)


FAST_STATES = [(3.0, 3.0), (4.0, 5.0), (2.0, 6.0), (5.0, 0.0), (-3.0, -4.0), (1.91, 4.48)]
"""Start velocities and references (units/s) where the problem is strongly nonlinear."""


@pytest.mark.parametrize("role", ["leader", "follower", "joint"])
@pytest.mark.parametrize(("y0", "rs"), FAST_STATES)
def test_fast_steps_converge_to_the_tight_solution(role: str, y0: float, rs: float) -> None:
    """Above about 3 units/s the damping 3 beta y² makes the problem strongly nonlinear: the
    chord iterations give way to the continuation, which still meets the tight tolerances."""
    assert_tight(preset(role), 0.0, y0, 0.0, rs, 0.0)


@pytest.mark.parametrize("coupled", [True, False])
@pytest.mark.parametrize("damping", [0.0, 3.3, 17.1, 63.9, 80.0])
def test_tabulated_linear_problem_matches_its_integration(coupled: bool, damping: float) -> None:
    """The frozen-damping guess from the table equals the same problem integrated finely."""
    p = JOINT.record()[0]
    theta_p = JOINT.theta_p if coupled else 0.0
    theta_v = JOINT.theta_v if coupled else 0.0
    tracking, forcing = 1.0 - theta_p, (1.0 - theta_p - theta_v) * 1.3 + theta_v * -0.4
    lanes, z = np.zeros((LANE_ROWS, 2)), np.empty(12)
    for row, value in [(X, 0.2), (Y, 0.7), (FROZEN, damping), (TRACKING, tracking)]:
        lanes[row] = value
    lanes[FORCING], lanes[THETA_P] = forcing, theta_p
    _frozen_guess(lanes, 0, p, 0 if coupled else 1, 64, z)
    _shoot_with_sensitivities(
        0.2, 0.7, 0.0, 0.0, 0.0, 0.0, -damping, JOINT.omega, JOINT.eta, tracking, forcing,
        JOINT.period, 64,
        z,
    )  # fmt: skip
    _keep_shot(z, theta_p, lanes, 1)
    np.testing.assert_allclose(lanes[:, 0], lanes[:, 1], rtol=1e-4, atol=1e-9)


def test_sessions_on_recorded_references_never_run_away(zhai_trials_100hz) -> None:
    """Leader and follower on the recorded velocities of the bundled trials (up to ~9 units/s).

    Speeds stay within the references' range: a wrongly accepted shooting solution once drove a
    trainer to hundreds of units/s here.
    """
    for first in range(0, 18, 3):
        trials = (zhai_trials_100hz[first], zhai_trials_100hz[first + 1])
        players = [VirtualTrainer(LEADER, trials[0]), VirtualTrainer(FOLLOWER, trials[1])]
        session = play(players, duration=min(t.duration for t in trials), seed=first)
        fastest = np.abs(session.velocities).max()
        assert np.isfinite(fastest)
        assert fastest <= np.abs(session.references[:, :-1]).max() + 0.5


HKB_CASES = [(0.1, 0.2, 2.0), (-0.3, -0.5, -4.0), (0.0, 1.0, 0.5)]


@pytest.mark.parametrize(("x0", "v0", "u"), HKB_CASES)
def test_integrate_hkb_matches_solve_ivp(x0, v0, u):
    p = FOLLOWER

    def rhs(_t, y):
        x, v = y
        return [v, hkb_acceleration(x, v, u, p.alpha, p.beta, p.gamma, p.omega)]

    exact = solve_ivp(rhs, (0.0, p.period), [x0, v0], rtol=1e-12, atol=1e-14).y[:, -1]
    x, v = integrate_hkb(x0, v0, u, p.record()[0], 3)
    np.testing.assert_allclose([x, v], exact, rtol=0, atol=1e-8)


def test_integrate_hkb_stops_at_the_edge_of_the_range():
    p = FOLLOWER.record()[0]
    assert integrate_hkb(0.499, 1.0, 4.0, p, 3) == (0.5, 0.0)
    assert integrate_hkb(-0.499, -1.0, -4.0, p, 3) == (-0.5, 0.0)

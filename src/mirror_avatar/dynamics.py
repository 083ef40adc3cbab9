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
two initial costates (`solve_intervals`). The state and costates are integrated with fixed-step
RK4 (at least `N_SUBSTEPS` steps per interval, more when the interval is stiff, see
`count_substeps`). Newton's method on the two terminal conditions starts from the exact solution
of the problem with frozen damping, a linear problem whose solution map is tabulated once per
parameter set (the record's ``linear`` field), and continues with chord iterations (the
problem is nearly linear over 0.03 s); at fast hand speeds, where it is not, a continuation
from the linear to the full problem takes over. The published closed-form quadratic-in-time
approximation is **not** used: it gets velocity and control wrong by tens of percent. After the
interval, the position is clipped to the playing range [-0.5, 0.5] and an outward velocity at the
wall is set to zero (a hand stopped at the edge of the range).

The problems of many virtual trainers (all those of a batch chunk's sessions in one period) are
solved together, in lockstep: their plain shots are integrated by one loop over the problems that
the compiler vectorises, while each problem's iterations stop on its own test, so every problem
gets the result it gets alone, bit for bit; one problem is the case of one.

The cyber player's end effector is the same oscillator with a control chosen from a finite set and
held over the period (`integrate_hkb`, METHODS section 7).

Everything numerical is compiled with numba. Compiled functions read the parameters by name from a
record of `PARAMS_DTYPE` (`HKBParams.record`), so `optimal_control_steps` and `integrate_hkb` are
the single steps used by every player, in the Python step loop and in the compiled batch loop
alike.
The parameters, both steps and the solver's pieces stay in one module: they are read together.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass, replace
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
        ("linear", np.float64, (2, LINEAR_GRID, LINEAR_COLUMNS)),
    ]
)
"""The fields of `HKBParams` as compiled code reads them (a numpy record, by name), and the
tabulated frozen-damping solution maps of its optimal-control problem (``linear``: coupled,
then alone; `_tabulate_linear`)."""

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
        """JSON-serialisable parameters, in the order of the fields (an instance holds no more)."""
        return dict(vars(self))

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
            for name in HKB_FIELDS:
                table[i][name] = getattr(p, name)
            table[i]["linear"] = linear_tables(p)
    return table


HKB_FIELDS = ("alpha", "beta", "gamma", "omega", "eta", "theta_p", "theta_v", "period")
"""The fields of `PARAMS_DTYPE` that are `HKBParams` fields."""


@functools.cache
def linear_tables(p: HKBParams) -> NDArray[np.float64]:
    """Tabulate the frozen-damping solution maps of ``p``'s problem, coupled and alone.

    See `_tabulate_linear`.

    Returns
    -------
    ndarray
        Shape (2, `LINEAR_GRID`, `LINEAR_COLUMNS`); computed once per parameter set.
    """
    tables = np.empty((2, LINEAR_GRID, LINEAR_COLUMNS))
    for index, tracking in enumerate((1.0 - p.theta_p, 1.0)):
        _tabulate_linear(p.omega, p.eta, tracking, p.period, tables[index])
    tables.flags.writeable = False
    return tables


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


@njit(cache=True, fastmath={"contract"})
def hkb_acceleration(
    x: float, v: float, u: float, alpha: float, beta: float, gamma: float, omega: float
) -> float:
    """HKB acceleration ``-(alpha x² + beta v² - gamma) v - omega² x + u`` (units/s²)."""
    return -(alpha * x * x + beta * v * v - gamma) * v - omega * omega * x + u


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


@njit(cache=True)
def clip_to_range(x: float, v: float) -> tuple[float, float]:
    """Clip a position to [-0.5, 0.5]; at a wall, drop the velocity pushing further out."""
    if x > _HIGH:
        return _HIGH, min(v, 0.0)
    if x < _LOW:
        return _LOW, max(v, 0.0)
    return x, v


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


@njit(cache=True, fastmath={"contract"})
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

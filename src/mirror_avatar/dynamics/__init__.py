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

The package, one idea per module, from the bottom: `hkb` (the oscillator, the cyber player's RK4
step, the playing range), `optimal_control` (one interval's shooting and Newton iterations, the
tabulated linear problem), `lanes` (many problems in lockstep, `solve_intervals`, and the
virtual trainer's step `optimal_control_steps`), `parameters` (`HKBParams`, its ranges, record
and role presets). Everything is importable from ``mirror_avatar.dynamics``.
"""

from mirror_avatar.dynamics.hkb import (
    Record,
    advance_hkb,
    clip_to_range,
    hkb_acceleration,
    integrate_hkb,
    partner_weights,
)
from mirror_avatar.dynamics.lanes import (
    ALPHA,
    BETA,
    CONTINUING,
    END,
    ETA,
    FALLBACK,
    FORCING,
    FROZEN,
    GAMMA,
    ITERATING,
    JACOBIAN,
    L1,
    L2,
    LANE_ROWS,
    OMEGA,
    PREDICTION,
    PREVIOUS,
    PROBLEM_COLUMNS,
    RESIDUAL,
    SENSITIVITY,
    SOLVED,
    STEP,
    THETA_P,
    TRACKING,
    X,
    Y,
    optimal_control_steps,
    solve_interval,
    solve_intervals,
)
from mirror_avatar.dynamics.optimal_control import (
    CONTINUATION_STAGES,
    DAMPING_STIFFNESS,
    LINEAR_COLUMNS,
    LINEAR_GRID,
    LINEAR_MAX_DAMPING,
    LINEAR_SUBSTEPS,
    MAX_NEWTON,
    MAX_RK4_SUBSTEPS,
    MIN_STEP_SCALE,
    N_SUBSTEPS,
    NEWTON_TOLERANCE,
    STEP_STIFFNESS,
    Twelve,
    count_substeps,
    coupling_rate,
)
from mirror_avatar.dynamics.parameters import (
    CONTROL_PERIOD,
    FOLLOWER,
    GROUP,
    GROUP_LEADER,
    HKB_FIELDS,
    JOINT,
    LEADER,
    PARAMETER_RANGES,
    PARAMS_DTYPE,
    ROLES,
    HKBParams,
    linear_tables,
    preset,
    records,
)

__all__ = [
    "ALPHA",
    "BETA",
    "CONTINUATION_STAGES",
    "CONTINUING",
    "CONTROL_PERIOD",
    "DAMPING_STIFFNESS",
    "END",
    "ETA",
    "FALLBACK",
    "FOLLOWER",
    "FORCING",
    "FROZEN",
    "GAMMA",
    "GROUP",
    "GROUP_LEADER",
    "HKBParams",
    "HKB_FIELDS",
    "ITERATING",
    "JACOBIAN",
    "JOINT",
    "L1",
    "L2",
    "LANE_ROWS",
    "LEADER",
    "LINEAR_COLUMNS",
    "LINEAR_GRID",
    "LINEAR_MAX_DAMPING",
    "LINEAR_SUBSTEPS",
    "MAX_NEWTON",
    "MAX_RK4_SUBSTEPS",
    "MIN_STEP_SCALE",
    "NEWTON_TOLERANCE",
    "N_SUBSTEPS",
    "OMEGA",
    "PARAMETER_RANGES",
    "PARAMS_DTYPE",
    "PREDICTION",
    "PREVIOUS",
    "PROBLEM_COLUMNS",
    "RESIDUAL",
    "ROLES",
    "Record",
    "SENSITIVITY",
    "SOLVED",
    "STEP",
    "STEP_STIFFNESS",
    "THETA_P",
    "TRACKING",
    "Twelve",
    "X",
    "Y",
    "advance_hkb",
    "clip_to_range",
    "count_substeps",
    "coupling_rate",
    "hkb_acceleration",
    "integrate_hkb",
    "linear_tables",
    "optimal_control_steps",
    "partner_weights",
    "preset",
    "records",
    "solve_interval",
    "solve_intervals",
]

"""The parameters of an HKB end effector and its cost: their ranges, record and role presets.

`HKBParams` is read by compiled code by name, as a record of `PARAMS_DTYPE`, which also carries
the tabulated frozen-damping solution maps of its optimal-control problem (`linear_tables`).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.dynamics.optimal_control import (
    LINEAR_COLUMNS,
    LINEAR_GRID,
    _tabulate_linear,
)
from mirror_avatar.files.model_files import check_real

CONTROL_PERIOD = 0.03
"""The control period T of the paper (s): players are advanced every T."""


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

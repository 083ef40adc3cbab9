"""The HKB oscillator of every end effector, and the RK4 step of a control held over a period.

``x'' = -(alpha x² + beta x'² - gamma) x' - omega² x + u`` (METHODS section 5); `integrate_hkb`
is the cyber player's end effector (METHODS section 7): a control chosen from a finite set and
held over the period. Positions stay within the playing range (`clip_to_range`).
"""

from __future__ import annotations

from typing import Any

from numba import njit

from mirror_avatar.files.trials import PLAYING_RANGE

_LOW, _HIGH = PLAYING_RANGE
Record = Any
"""A numpy record of `mirror_avatar.dynamics.PARAMS_DTYPE` (numba's Record type in compiled
code)."""


@njit(cache=True, fastmath={"contract"})
def hkb_acceleration(
    x: float, v: float, u: float, alpha: float, beta: float, gamma: float, omega: float
) -> float:
    """HKB acceleration ``-(alpha x² + beta v² - gamma) v - omega² x + u`` (units/s²)."""
    return -(alpha * x * x + beta * v * v - gamma) * v - omega * omega * x + u


@njit(cache=True)
def clip_to_range(x: float, v: float) -> tuple[float, float]:
    """Clip a position to [-0.5, 0.5]; at a wall, drop the velocity pushing further out."""
    if x > _HIGH:
        return _HIGH, min(v, 0.0)
    if x < _LOW:
        return _LOW, max(v, 0.0)
    return x, v


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

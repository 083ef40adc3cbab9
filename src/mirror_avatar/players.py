"""The player step protocol shared by every kind of player.

Virtual trainer, recorded trial, cyber player and live human are all advanced one control period
at a time by the same two calls.

Seeding rules (as in Gymnasium's ``reset(seed=...)``): ``reset(seed=s)`` with an integer makes
everything the player does afterwards a deterministic function of ``s`` and of the partner's
observations; ``reset(seed=None)`` draws fresh entropy. A player never touches global random state.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

CONTROL_PERIOD = 0.03
"""The control period T of the paper (s): players are advanced every T."""


@runtime_checkable
class Player(Protocol):
    """A mirror-game player.

    Attributes
    ----------
    period
        Control period (s) at which `step` is called.
    """

    period: float

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        """Start a new trial and return the initial (position, velocity) (units, units/s)."""
        ...

    def step(self, partner_position: float, partner_velocity: float) -> tuple[float, float]:
        """Observe the partner at the current time and advance one period.

        Parameters
        ----------
        partner_position, partner_velocity
            The partner's position (units) and velocity (units/s) now, at time t_k.

        Returns
        -------
        tuple of float
            Own (position, velocity) at t_k + period; position within [-0.5, 0.5].
        """
        ...

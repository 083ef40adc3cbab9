"""The avatar's proof against the person: the replayed partner's sign and the person found."""

from __future__ import annotations

import numpy as np
import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.experiments.avatar_proof import dyad_numbers, find_person
from mirror_avatar.sessions.session import Session


@pytest.mark.parametrize("partner", [0, 1])
def test_the_partner_ahead_is_a_positive_lag_whichever_its_place(partner: int) -> None:
    t = np.arange(0.0, 30.0, 0.01)
    ahead, behind = 0.3 * np.sin(2 * np.pi * 0.5 * t), 0.3 * np.sin(2 * np.pi * 0.5 * (t - 0.2))
    positions = np.array([ahead, behind] if partner == 0 else [behind, ahead])
    velocities = np.gradient(positions, t, axis=1)
    nan = np.full_like(positions, np.nan)
    session = Session(t, positions, velocities, nan, nan, labels=("A", "B"))
    numbers = dyad_numbers(session, partner)
    assert numbers["lag"] == pytest.approx(0.2, abs=0.011)
    assert numbers["cv"] > 0.99 and numbers["rms"] > 0
    assert find_person("s", session, "B" if partner == 0 else "A").person == 1 - partner
    with pytest.raises(InputError, match="no single player labelled 'C'"):
        find_person("s", session, "C")

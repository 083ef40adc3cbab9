"""An avatar's players stepped in Chromium equal the Python players (METHODS section 16).

Each kind the page steps (``lab/static/avatars.js``) is built in a real Chromium from the
message `mirror_avatar.browser.browser_arrays` makes of the player (the learned ones read back
from a personal avatar's file), stepped for 2000 control periods (60 s) against the motion of
recorded people, and compared with the same player stepped in Python from the same seed.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mirror_avatar.browser import browser_arrays
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.files.trials import Trial
from mirror_avatar.players import Player, RecordedPlayer
from mirror_avatar.specs import bundled_generator
from mirror_avatar.testing import (
    ServerThread,
    partner_motion,
    static_app,
    step_in_page,
    step_in_python,
)
from mirror_avatar.training.avatar import Avatar, load_avatar
from mirror_avatar.training.imitation import make_cyber_player, make_group_cyber_player

pytestmark = pytest.mark.browser

N_STEPS = 2000
"""Control periods stepped: 60 s, a bundled trial's length."""

TOLERANCE = 1e-9
"""Largest |browser - Python| position or velocity allowed (units, units/s)."""

SEED = 7


@pytest.fixture(scope="module")
def trials() -> list[Trial]:
    return load_zhai2017()


@pytest.fixture(scope="module")
def page(chromium: Any) -> Iterator[Any]:
    with ServerThread(static_app()) as server:
        page = chromium.new_page()
        page.goto(f"{server.url}/")
        yield page
        page.close()


def seeded_avatar(agent: str, folder: Path) -> Avatar:
    """A personal avatar of untrained, seeded policies, written to its file and read back."""
    generator = bundled_generator("slow")
    players = {}
    for seed, role in enumerate(("follower", "leader")):
        players[role] = make_cyber_player(role, generator, agent=agent)  # type: ignore[arg-type]
        players[role].initialise_policy(seed)
        players[role].training_ = {"role": role}
    path = Avatar("P01", generator, players).save(folder / f"{agent}.npz")
    return load_avatar(path)


@pytest.fixture(scope="module", params=["tabular", "dqn"])
def avatar(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Avatar:
    return seeded_avatar(request.param, tmp_path_factory.mktemp("avatar"))


def compare(page: Any, player: Player, neighbours: list[Trial]) -> None:
    """Step ``player`` in the page and in Python; assert they agree within `TOLERANCE`."""
    positions, velocities = partner_motion(neighbours, N_STEPS)
    message = browser_arrays(player, SEED, N_STEPS)
    in_page, _, _ = step_in_page(page, message, positions, velocities)
    in_python = step_in_python(player, SEED, positions, velocities)
    assert in_page.shape == in_python.shape == (N_STEPS + 1, 2)
    assert np.max(np.abs(in_page - in_python)) <= TOLERANCE
    assert np.ptp(in_python[:, 0]) > 0.1  # it moved


def test_a_recording_replays_the_same_in_the_page(page: Any, trials: list[Trial]) -> None:
    compare(page, RecordedPlayer(trials[4]), trials[10:11])


@pytest.mark.parametrize("role", ["follower", "leader"])
def test_an_avatar_s_policy_steps_the_same_in_the_page(
    page: Any, trials: list[Trial], avatar: Avatar, role: str
) -> None:
    compare(page, avatar.player(role), trials[10:11])


@pytest.mark.parametrize("agent", ["tabular", "dqn"])
def test_a_group_member_steps_the_same_in_the_page(
    page: Any, trials: list[Trial], agent: str
) -> None:
    player = make_group_cyber_player(bundled_generator("slow"), agent=agent)  # type: ignore[arg-type]
    player.initialise_policy(3)
    compare(page, player, [trials[1], trials[10], trials[12]])


def test_the_page_refuses_a_message_of_another_kind(page: Any, trials: list[Trial]) -> None:
    message = browser_arrays(RecordedPlayer(trials[4]), SEED, N_STEPS) | {"kind": "trainer"}
    positions, velocities = partner_motion(trials[10:11], 2)
    with pytest.raises(Exception, match="cannot step a trainer player"):
        step_in_page(page, message, positions, velocities)

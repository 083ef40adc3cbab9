"""Player kinds register themselves: a new kind runs in the compiled loop without an engine edit."""

from typing import NamedTuple

import numpy as np
import pytest
from numba import njit

from mirror_avatar.dynamics import FOLLOWER
from mirror_avatar.engine.compiled import run_plans
from mirror_avatar.engine.dispatch import loop_source
from mirror_avatar.engine.loop import play
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.players import RecordedPlayer, VirtualTrainer
from mirror_avatar.players.base import PlayerPlan
from mirror_avatar.players.kinds import PlayerKind, player_kind, register_kind


class Holds(NamedTuple):
    """Where each still player holds, shape (K,)."""

    positions: np.ndarray


def pack_holds(plans, players) -> Holds:
    return Holds(np.array([plan.start[0] for plan in plans]))


@njit(cache=True)
def hold_still(positions, slot, k, x, v, neighbours, velocities, previous, reference):
    return positions[slot], 0.0, np.nan


STILL = register_kind(PlayerKind("still", Holds, pack_holds, hold_still))


def test_a_registered_kind_plays_as_its_python_twin(zhai_trials_100hz) -> None:
    motion = IMSGenerator(n_symbols=8, random_state=0).fit(zhai_trials_100hz[:2])
    trainer = VirtualTrainer(FOLLOWER, motion)
    n = 120
    # The same still player as a recording of a constant position.
    twin = RecordedPlayer.on_grid(np.full(n, 0.2), np.zeros(n), trainer.period)
    played = play([twin, trainer], duration=(n - 1) * trainer.period, seed=4)
    trainer_seed = played.metadata["player_seeds"][1]
    plans = [PlayerPlan(STILL.name, (0.2, 0.0)), trainer.plan(trainer_seed, n - 1)]
    out = run_plans(plans, np.array([[0, 1], [1, 0]], dtype=np.int8), n)
    assert out.shape == (4, 2, n)
    np.testing.assert_array_equal(out[0, 0], np.full(n, 0.2))
    for channel, name in enumerate(("positions", "velocities", "controls", "references")):
        np.testing.assert_array_equal(out[channel, 1], getattr(played, name)[1])


def test_the_loop_is_written_from_the_registry() -> None:
    source = loop_source([STILL, player_kind("virtual_trainer")])
    assert "hold_still as step_0" in source
    assert "pose_trainer as step_1" in source and "solve_trainers as solve_1" in source
    assert "kinds[i] == 0" in source and "kinds[i] == 1" in source


def test_a_kind_name_is_taken_once() -> None:
    with pytest.raises(ValueError, match="identifier"):
        PlayerKind("two words", Holds, pack_holds, hold_still)
    with pytest.raises(ValueError, match="already registered"):
        register_kind(PlayerKind("virtual_trainer", Holds, pack_holds, hold_still))
    with pytest.raises(ValueError, match="no player kind"):
        player_kind("unknown")

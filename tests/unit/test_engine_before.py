"""Two-player sessions are bit-identical to those of the engine before the N-player engine.

`tests/fixtures/engine_before/` holds sessions, the generators they used and the training
results recorded with commit c9581d4 (see its ``make.py``); here the current engine replays them.
"""

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.dynamics import FOLLOWER, JOINT, LEADER
from mirror_avatar.engine.batch import play_compiled, run_sessions
from mirror_avatar.engine.loop import play
from mirror_avatar.generator import IMSGenerator
from mirror_avatar.learning.imitation import train_cyber_player
from mirror_avatar.players import RecordedPlayer, VirtualTrainer
from mirror_avatar.session import Session

FIXTURES = Path(__file__).parents[1] / "fixtures" / "engine_before"
CHANNELS = ("positions", "velocities", "controls", "references")
DURATION = 10.0


@pytest.fixture(scope="module")
def generators() -> tuple[IMSGenerator, IMSGenerator]:
    return IMSGenerator.load(FIXTURES / "fast32.npz"), IMSGenerator.load(FIXTURES / "slow32.npz")


@pytest.fixture(scope="module")
def trials() -> list:
    return [t.resampled(100.0) for t in load_zhai2017()]


def assert_recorded(name: str, session: Session, channels=CHANNELS) -> None:
    with np.load(FIXTURES / f"{name}.npz") as recorded:
        for channel in channels:
            np.testing.assert_array_equal(getattr(session, channel), recorded[channel])
        np.testing.assert_array_equal(session.times, recorded["times"])


def lineups(generators, trials) -> dict[str, tuple[list, int]]:
    fast, slow = generators
    return {
        "vt_leader_vt_follower": (
            [VirtualTrainer(LEADER, slow), VirtualTrainer(FOLLOWER, fast)],
            7,
        ),
        "recorded_vt_follower": ([RecordedPlayer(trials[4]), VirtualTrainer(FOLLOWER, slow)], 3),
        "joint_trial_reference": (
            [VirtualTrainer(JOINT, trials[13]), VirtualTrainer(JOINT, fast)],
            5,
        ),
    }


@pytest.mark.parametrize(
    "name", ["vt_leader_vt_follower", "recorded_vt_follower", "joint_trial_reference"]
)
def test_sessions_are_bit_identical_in_both_loops(generators, trials, name) -> None:
    players, seed = lineups(generators, trials)[name]
    assert_recorded(name, play(players, DURATION, seed))
    assert_recorded(name, play_compiled(players, 334, seed))


def test_batch_run_is_bit_identical(generators, trials) -> None:
    fast, slow = generators
    pairs = [
        (VirtualTrainer(LEADER, fast), VirtualTrainer(FOLLOWER, slow)),
        (VirtualTrainer(LEADER, trials[4]), VirtualTrainer(FOLLOWER, fast)),
    ]
    chunks = list(run_sessions(pairs, 4, duration=5.0, seed=11, n_jobs=1, chunk_size=3))
    sessions = [s for chunk in chunks for s in chunk]
    with np.load(FIXTURES / "batch.npz") as recorded:
        for channel in CHANNELS:
            stacked = np.stack([getattr(s, channel) for s in sessions])
            np.testing.assert_array_equal(stacked, recorded[channel])
        assert [s.metadata["seed"] for s in sessions] == recorded["seeds"].tolist()


@pytest.mark.parametrize(("role", "partner_params"), [("follower", LEADER), ("leader", FOLLOWER)])
def test_training_and_cyber_sessions_are_bit_identical(generators, role, partner_params) -> None:
    """The same Q-table and learning curve; the same closed-loop session.

    The cyber player now reports its controls (they were NaN before): only they differ.
    """
    fast, slow = generators
    expected = json.loads((FIXTURES / "training.json").read_text())[role]
    player, curve = train_cyber_player(
        slow, [fast, slow], role=role, n_sessions=40, seed=0, duration=DURATION, n_jobs=1
    )
    assert hashlib.sha256(player.q_table_.tobytes()).hexdigest() == expected["q_table_sha256"]
    assert curve.rms == expected["learning_curve_rms"]
    partner = VirtualTrainer(partner_params, fast)
    players = [partner, player] if role == "follower" else [player, partner]
    cyber = players.index(player)
    for session in (play(players, DURATION, 9), play_compiled(players, 334, 9)):
        assert_recorded(f"cyber_{role}", session, ("positions", "velocities", "references"))
        with np.load(FIXTURES / f"cyber_{role}.npz") as recorded:
            np.testing.assert_array_equal(
                session.controls[1 - cyber], recorded["controls"][1 - cyber]
            )
        assert np.all(np.isfinite(session.controls[cyber, :-1]))
        assert set(np.unique(session.controls[cyber, :-1])) <= set(player.actions_)

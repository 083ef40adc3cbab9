"""Tests of DQN training: schedule, replay, seeding, learning, checkpoints and the CLI."""

import itertools
import re

import numpy as np
import pytest

from mirror_avatar.cli import main
from mirror_avatar.common.errors import InputError
from mirror_avatar.deep.player import DeepCyberPlayer, load_deep_cyber_player
from mirror_avatar.deep.training import (
    DQNLearner,
    GeometricEpsilon,
    ReplayBuffer,
)
from mirror_avatar.specs import bundled_generator
from mirror_avatar.testing import make_follower_sessions
from mirror_avatar.training.imitation import score_avatar, train_group_cyber_player

ACTIONS = tuple(4.0 * a for a in (-4.0, -2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0, 4.0))


@pytest.fixture(scope="module")
def sessions(zhai_trials) -> tuple[list, list]:
    """Real slow trials, each led by itself and followed 0.3 s later: training and held out."""
    slow = [t for t in zhai_trials if t.group == "slow"]
    return make_follower_sessions(slow[:6]), make_follower_sessions(slow[6:])


def train(sessions, n_sessions, seed=0, **options) -> tuple[DeepCyberPlayer, DQNLearner]:
    player = DeepCyberPlayer(actions=ACTIONS, hidden=(32, 32))
    learner = DQNLearner(player, random_state=seed, progress=False, **options)
    learner.fit(itertools.islice(itertools.cycle(sessions), n_sessions))
    return player, learner


def test_geometric_epsilon_is_the_published_schedule() -> None:
    schedule = GeometricEpsilon()
    assert [schedule(i) for i in (0, 1, 2)] == [1.0, 0.9, pytest.approx(0.81)]
    assert schedule(21) == pytest.approx(0.9**21) and schedule(22) == 0.1 == schedule(1000)
    with pytest.raises(InputError):
        GeometricEpsilon(factor=1.0)


def test_the_replay_buffer_is_a_ring(sessions) -> None:
    _, learner = train(sessions[0][:1], 2, buffer_size=1500, learning_starts=1000, train_every=8)
    replay = learner.replay_
    steps = sessions[0][0].n_samples - 1
    assert replay.counters[0] == 2 * steps and replay.size == 1500
    assert replay.counters[1] == (2 * steps - 1000) // 8 + 1
    assert set(np.unique(replay.actions)) <= set(range(9))
    empty = ReplayBuffer.empty(4, 3)
    assert empty.size == 0 and empty.inputs.shape == (4, 3)


def test_the_same_seed_gives_the_same_weights(sessions) -> None:
    a, _ = train(sessions[0], 3, seed=7, train_every=4)
    b, _ = train(sessions[0], 3, seed=7, train_every=4)
    c, _ = train(sessions[0], 3, seed=8, train_every=4)
    np.testing.assert_array_equal(a.weights_, b.weights_)
    assert not np.array_equal(a.weights_, c.weights_)
    assert a.training_["seed"] == 7 and a.training_["agent"] == "dqn"


def test_training_learns_to_imitate_the_target(sessions) -> None:
    player, learner = train(sessions[0], 30, train_every=2, block_size=5)
    untrained = DeepCyberPlayer(actions=ACTIONS, hidden=(32, 32))
    untrained.initialise_policy(0)
    held_out = sessions[1]
    trained_rms = score_avatar(player, held_out)[1].mean()
    assert trained_rms < 0.25 * score_avatar(untrained, held_out)[1].mean()
    assert trained_rms < 0.05
    curve = learner.learning_curve_
    assert curve.sessions == [5, 10, 15, 20, 25, 30]
    assert curve.rms[-1] < 0.5 * curve.rms[0]
    again = score_avatar(player, held_out)[1]  # scoring learns nothing: the same play again
    assert again.mean() == trained_rms


def test_checkpoints_hold_the_network_and_resume_counting(sessions, tmp_path) -> None:
    path = tmp_path / "deep.npz"
    player, learner = train(sessions[0], 4, train_every=8, checkpoint_every=2, checkpoint_path=path)
    saved = load_deep_cyber_player(path)
    np.testing.assert_array_equal(saved.weights_, player.weights_)
    assert saved.training_["n_sessions"] == 4
    resumed = DQNLearner(saved, random_state=1, progress=False).fit([])
    assert resumed.n_sessions_ == 4 and resumed.epsilon_ == 1.0
    np.testing.assert_array_equal(saved.weights_, player.weights_)


@pytest.mark.parametrize(
    ("option", "value", "fragment"),
    [
        ("discount", 1.0, "discount: must be in [0, 1)"),
        ("batch_size", 0, "batch_size: must be at least 1"),
        ("learning_starts", 10, "learning_starts: must lie between batch_size and buffer_size"),
        ("reward_scale", -1.0, "reward_scale: must be positive"),
    ],
)
def test_bad_options_are_refused_in_one_line(option, value, fragment) -> None:
    with pytest.raises(InputError, match=re.escape(fragment)):
        DQNLearner(DeepCyberPlayer(), **{option: value}).fit([])


def test_a_group_member_learns_on_random_graphs() -> None:
    slow, fast = bundled_generator("slow"), bundled_generator("fast")
    player, curve = train_group_cyber_player(
        slow, [fast, slow, fast], n_sessions=6, duration=15.0, agent="dqn", progress=False
    )
    assert isinstance(player, DeepCyberPlayer) and player.n_slots == 3
    assert player.training_["role"] == "group" and player.training_["agent"] == "dqn"
    assert curve.rms[-1] < curve.rms[0]


def test_the_cli_trains_a_dqn_follower(tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    out = tmp_path / "dqn.npz"
    arguments = ["train", "--target", "bundled:slow", "--partners", "bundled:fast", "--agent",
                 "dqn", "--sessions", "3", "--duration", "10", "--jobs", "1",
                 "--out", str(out)]  # fmt: skip
    assert main(arguments) == 0
    assert "trained a dqn follower on 3 sessions" in capsys.readouterr().out
    player = load_deep_cyber_player(out)
    assert player.training_["n_sessions"] == 3 and player.training_["role"] == "follower"
    assert (tmp_path / "dqn.learning_curve.csv").exists()
    assert main([*arguments[:-6], "--agent", "deep", *arguments[-6:]]) == 2

from __future__ import annotations

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from mirror_avatar.common.errors import InputError
from mirror_avatar.deep.features import encode
from mirror_avatar.deep.network import greedy_action
from mirror_avatar.deep.player import DeepCyberPlayer
from mirror_avatar.dynamics import FOLLOWER, integrate_hkb
from mirror_avatar.engine.batch import play_compiled
from mirror_avatar.learning.agent import DEFAULT_ACTIONS, CyberPlayer
from mirror_avatar.learning.kernels import compute_reward
from mirror_avatar.rl.env import MirrorGameEnv
from mirror_avatar.sessions.graphs import random_connected_graph, star_graph
from mirror_avatar.sessions.session import Session
from mirror_avatar.specs import load_player
from mirror_avatar.training.imitation import score_avatar


def sine_sessions(k: int = 3, n: int = 50, lag: int = 5) -> list[Session]:
    """k dyads: partner a 0.2 Hz sine of varying amplitude, target the same, lagged."""
    t = np.arange(n + lag) * 0.03
    sessions = []
    for amplitude in np.linspace(0.2, 0.4, k):
        x = amplitude * np.sin(2 * np.pi * 0.2 * t)
        v = amplitude * 2 * np.pi * 0.2 * np.cos(2 * np.pi * 0.2 * t)
        nan = np.full((2, n), np.nan)
        sessions.append(
            Session(t[:n], np.stack([x[lag:], x[:-lag]]), np.stack([v[lag:], v[:-lag]]), nan, nan)
        )
    return sessions


@pytest.mark.parametrize("observation", ["continuous", "discrete"])
def test_env_passes_gymnasium_check_env(observation):
    env = MirrorGameEnv(sine_sessions(), observation=observation)
    check_env(env, skip_render_check=True)


def test_episode_is_one_session_with_the_cyber_player_reward():
    (session,) = sine_sessions(k=1, n=40)
    env = MirrorGameEnv([session])
    obs, info = env.reset(seed=0)
    (px, tx), (pv, tv) = session.positions, session.velocities
    np.testing.assert_allclose(obs, [tx[0], tv[0], px[0], pv[0]], rtol=1e-6)
    x, v = tx[0], tv[0]
    for k in range(1, 40):
        action = k % 9
        obs, reward, terminated, truncated, info = env.step(action)
        x, v = integrate_hkb(x, v, DEFAULT_ACTIONS[action], FOLLOWER.record()[0], 3)
        assert reward == compute_reward(x, v, tx[k], tv[k], DEFAULT_ACTIONS[action], 1e-4)
        np.testing.assert_allclose(obs, [x, v, px[k], pv[k]], rtol=1e-6)
        assert info["target"] == (tx[k], tv[k])
        assert not terminated and truncated == (k == 39)


def test_in_a_group_the_agent_sees_the_mean_of_the_targets_neighbours():
    (dyad,) = sine_sessions(k=1, n=30)
    x = np.vstack([dyad.positions, -dyad.positions[:1]])
    v = np.vstack([dyad.velocities, -dyad.velocities[:1]])
    nan = np.full_like(x, np.nan)
    group = Session(dyad.times, x, v, nan, nan, graph=star_graph(3, centre=1))
    env = MirrorGameEnv([group], target=1)
    obs, _ = env.reset(seed=0)
    np.testing.assert_allclose(obs[2:], [0.0, 0.0], atol=1e-7)
    leaf = MirrorGameEnv([group], target=2)
    obs, _ = leaf.reset(seed=0)
    np.testing.assert_allclose(obs, [x[2, 0], v[2, 0], x[1, 0], v[1, 0]], rtol=1e-6)


def test_seeded_resets_pick_the_same_sessions():
    env = MirrorGameEnv(sine_sessions(k=5))
    first = [env.reset(seed=s)[0][2:] for s in range(10)]
    again = [env.reset(seed=s)[0][2:] for s in range(10)]
    np.testing.assert_array_equal(first, again)
    assert len({tuple(o) for o in first}) > 1


def test_callable_and_iterator_sources():
    def make(rng: np.random.Generator) -> Session:
        (session,) = sine_sessions(k=1)
        session.positions[0] += rng.uniform(-0.05, 0.05)
        return session

    env = MirrorGameEnv(make)
    a, b = env.reset(seed=4)[0], env.reset(seed=4)[0]
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, env.reset(seed=5)[0])
    check_env(MirrorGameEnv(make), skip_render_check=True)

    env = MirrorGameEnv(iter(sine_sessions(k=2)))
    env.reset()
    env.reset()
    with pytest.raises(StopIteration):
        env.reset()


def test_discrete_observation_is_the_q_table_cell():
    player = CyberPlayer()
    (session,) = sine_sessions(k=1)
    env = MirrorGameEnv([session], player=player, observation="discrete")
    obs, _ = env.reset(seed=0)
    (px, tx), (pv, tv) = session.positions, session.velocities
    assert obs == player.discretisation_.index(tx[0], tv[0], px[0], pv[0])
    assert env.observation_space.n == player.discretisation_.n_states


def test_bad_arguments_are_input_errors():
    with pytest.raises(InputError, match="observation"):
        MirrorGameEnv(sine_sessions(), observation="pixels")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="sessions"):
        MirrorGameEnv([])
    env = MirrorGameEnv(lambda rng: sine_sessions(k=2))  # type: ignore[arg-type, return-value]
    with pytest.raises(InputError, match="expected a Session"):
        env.reset(seed=0)


def test_greedy_policy_through_the_env_scores_as_the_compiled_session():
    player = CyberPlayer()
    player.initialise_q(2, 1.0)
    sessions = sine_sessions(k=1, n=200)
    env = MirrorGameEnv(sessions, player=player, observation="discrete")
    obs, _ = env.reset(seed=0)
    rewards, truncated = [], False
    while not truncated:
        obs, reward, _, truncated, _ = env.step(int(np.argmax(player.q_table_[obs])))
        rewards.append(reward)
    mean_reward, _ = score_avatar(player, sessions)
    assert len(rewards) == 199
    assert np.mean(rewards) == pytest.approx(mean_reward[0], rel=1e-12)


@pytest.fixture(scope="module")
def group_sessions() -> list[Session]:
    """Virtual-trainer groups of four on a new random connected graph each."""
    group = [load_player(spec, "group") for spec in ("bundled:fast", "bundled:slow") * 2]
    return [play_compiled(group, 100, seed, random_connected_graph) for seed in range(4)]


def test_dynamic_observations_pass_check_env_on_random_graphs(group_sessions):
    check_env(
        MirrorGameEnv(group_sessions, observation="dynamic", target=3), skip_render_check=True
    )


def test_dynamic_observations_are_the_deep_players_input(group_sessions):
    player = DeepCyberPlayer(n_slots=3)
    player.initialise_policy(0)
    env = MirrorGameEnv(group_sessions, player, observation="dynamic", target=3)
    obs, _ = env.reset(seed=1)
    session = env._session
    neighbours = np.flatnonzero(session.graph[3])
    for k in range(1, 30):
        x, v = env._agent.state
        expected = np.empty(13)
        encode(
            x,
            v,
            0.0,
            session.positions[neighbours, k - 1],
            session.velocities[neighbours, k - 1],
            3,
            False,
            expected,
        )
        np.testing.assert_array_equal(obs, expected.astype(np.float32))
        obs, *_ = env.step(greedy_action(player.weights_, player.sizes_, obs.astype(np.float64)))
    with pytest.raises(InputError, match="'discrete' \\(for a tabular player\\)"):
        MirrorGameEnv(group_sessions, player, observation="discrete")

from __future__ import annotations

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from mirror_avatar.env import MirrorGameEnv
from mirror_avatar.errors import InputError
from mirror_avatar.learning import DEFAULT_ACTIONS, CyberPlayer, compute_reward, integrate_hkb


def sine_chunk(k: int = 3, n: int = 50, lag: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """k sessions (k, 2, n): partner a 0.2 Hz sine of varying amplitude, target the same, lagged."""
    t = np.arange(n + lag) * 0.03
    amplitudes = np.linspace(0.2, 0.4, k)[:, None]
    x = amplitudes * np.sin(2 * np.pi * 0.2 * t)
    v = amplitudes * 2 * np.pi * 0.2 * np.cos(2 * np.pi * 0.2 * t)
    return np.stack([x[:, lag:], x[:, :-lag]], axis=1), np.stack([v[:, lag:], v[:, :-lag]], axis=1)


@pytest.mark.parametrize("observation", ["continuous", "discrete"])
def test_env_passes_gymnasium_check_env(observation):
    env = MirrorGameEnv(sine_chunk(), observation=observation)
    check_env(env, skip_render_check=True)


def test_episode_is_one_session_with_the_cyber_player_reward():
    positions, velocities = sine_chunk(k=1, n=40)
    env = MirrorGameEnv((positions[0], velocities[0]))
    obs, info = env.reset(seed=0)
    (px, tx), (pv, tv) = positions[0], velocities[0]
    np.testing.assert_allclose(obs, [tx[0], tv[0], px[0], pv[0]], rtol=1e-6)
    x, v = tx[0], tv[0]
    hkb = np.array([1.0, 2.0, -1.0, 0.1])
    for k in range(1, 40):
        action = k % 9
        obs, reward, terminated, truncated, info = env.step(action)
        x, v = integrate_hkb(x, v, DEFAULT_ACTIONS[action], hkb, 0.03, 3)
        assert reward == compute_reward(x, v, tx[k], tv[k], DEFAULT_ACTIONS[action], 1e-4)
        np.testing.assert_allclose(obs, [x, v, px[k], pv[k]], rtol=1e-6)
        assert info["target"] == (tx[k], tv[k])
        assert not terminated and truncated == (k == 39)


def test_seeded_resets_pick_the_same_sessions():
    env = MirrorGameEnv(sine_chunk(k=5))
    first = [env.reset(seed=s)[0][2:] for s in range(10)]
    again = [env.reset(seed=s)[0][2:] for s in range(10)]
    np.testing.assert_array_equal(first, again)
    assert len({tuple(o) for o in first}) > 1


def test_callable_and_iterator_sources():
    def make(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        positions, velocities = sine_chunk(k=1)
        shift = rng.uniform(-0.05, 0.05)
        return positions[0] + shift, velocities[0]

    env = MirrorGameEnv(make)
    a, b = env.reset(seed=4)[0], env.reset(seed=4)[0]
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, env.reset(seed=5)[0])
    check_env(MirrorGameEnv(make), skip_render_check=True)

    chunks = iter([sine_chunk(k=1), sine_chunk(k=1)])
    env = MirrorGameEnv(chunks)
    env.reset()
    env.reset()
    with pytest.raises(StopIteration):
        env.reset()


def test_discrete_observation_is_the_q_table_cell():
    player = CyberPlayer()
    env = MirrorGameEnv(sine_chunk(k=1), player=player, observation="discrete")
    obs, _ = env.reset(seed=0)
    positions, velocities = sine_chunk(k=1)
    (px, tx), (pv, tv) = positions[0], velocities[0]
    assert obs == player.discretisation_.index(tx[0], tv[0], px[0], pv[0])
    assert env.observation_space.n == player.discretisation_.n_states


def test_bad_arguments_are_input_errors():
    with pytest.raises(InputError, match="observation"):
        MirrorGameEnv(sine_chunk(), observation="pixels")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="sessions"):
        MirrorGameEnv((np.zeros(5), np.zeros(5)))
    env = MirrorGameEnv(lambda rng: sine_chunk(k=2))
    with pytest.raises(InputError, match="one session"):
        env.reset(seed=0)


def test_greedy_policy_through_the_env_scores_as_the_compiled_session():
    player = CyberPlayer()
    player.initialise_q(2, 1.0)
    chunk = sine_chunk(k=1, n=200)
    env = MirrorGameEnv(chunk, player=player, observation="discrete")
    obs, _ = env.reset(seed=0)
    rewards, truncated = [], False
    while not truncated:
        obs, reward, _, truncated, _ = env.step(int(np.argmax(player.q_table_[obs])))
        rewards.append(reward)
    mean_reward, _ = player.evaluate([chunk])
    assert len(rewards) == 199
    assert np.mean(rewards) == pytest.approx(mean_reward[0], rel=1e-12)

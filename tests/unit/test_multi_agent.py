"""The PettingZoo parallel environment: several learning agents in one group on one clock."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pettingzoo")
from pettingzoo.test import parallel_api_test, parallel_seed_test  # noqa: E402

from mirror_avatar.common.errors import InputError  # noqa: E402
from mirror_avatar.dynamics import GROUP  # noqa: E402
from mirror_avatar.engine.loop import Engine  # noqa: E402
from mirror_avatar.learning.agent import CyberPlayer  # noqa: E402
from mirror_avatar.learning.kernels import compute_reward  # noqa: E402
from mirror_avatar.players import VirtualTrainer  # noqa: E402
from mirror_avatar.rl.env import ActionPlayer  # noqa: E402
from mirror_avatar.rl.multi_agent import MirrorGroupEnv  # noqa: E402
from mirror_avatar.sessions.graphs import ring_graph  # noqa: E402
from mirror_avatar.specs import bundled_generator  # noqa: E402


def partners(n: int = 2) -> list[VirtualTrainer]:
    styles = ("slow", "fast")
    return [VirtualTrainer(GROUP, bundled_generator(styles[k % 2])) for k in range(n)]


def make_env(**kwargs) -> MirrorGroupEnv:
    return MirrorGroupEnv(n_agents=2, partners=partners(), duration=3.0, **kwargs)


def test_passes_pettingzoo_api_and_seed_tests():
    parallel_api_test(make_env(), num_cycles=200)
    parallel_seed_test(make_env)


def play_episode(env: MirrorGroupEnv, seed: int, policy) -> tuple[list, list]:
    observations, _ = env.reset(seed=seed)
    seen, rewards = [observations], []
    while env.agents:
        actions = {name: policy(name, observations[name]) for name in env.agents}
        observations, reward, _, _, _ = env.step(actions)
        seen.append(observations)
        rewards.append(reward)
    return seen, rewards


def follow(name: str, observation: np.ndarray) -> int:
    """Accelerate towards the neighbours: index 1 or 2 of the actions by the sign of the gap."""
    x, v, xn, vn = observation
    return 4 if (xn - x) + 0.2 * (vn - v) > 0 else 3


def test_same_seed_same_actions_same_episode():
    first = play_episode(make_env(), 5, follow)
    again = play_episode(make_env(), 5, follow)
    assert len(first[1]) == round(3.0 / 0.03)
    for a, b in zip(first[0], again[0], strict=True):
        assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    assert first[1] == again[1]


def test_rewards_and_observations_follow_the_engine():
    """The episode is the engine's session of the agents' players and the partners on the ring;
    each reward is the cyber player's reward against the mean of the agent's neighbours."""
    env = MirrorGroupEnv(n_agents=2, partners=partners(), graph=ring_graph(4), duration=3.0)
    observations, rewards = play_episode(env, 11, follow)
    session = env.session()
    assert session.n_players == 4 and session.n_samples == 101
    np.testing.assert_array_equal(session.graph, ring_graph(4))
    actions = CyberPlayer().actions_
    for k in (10, 50, 99):
        for i, name in enumerate(("agent_0", "agent_1")):
            neighbours = np.flatnonzero(session.graph[i])
            xn = session.positions[neighbours, k + 1].mean()
            vn = session.velocities[neighbours, k + 1].mean()
            x, v = session.positions[i, k + 1], session.velocities[i, k + 1]
            u = session.controls[i, k]
            assert u in actions
            expected = compute_reward(x, v, xn, vn, u, CyberPlayer().params.eta)
            assert rewards[k][name] == pytest.approx(expected)
            np.testing.assert_allclose(observations[k + 1][name], [x, v, xn, vn], rtol=1e-6)
    replay_partners = partners()
    avatars = [ActionPlayer(CyberPlayer()) for _ in range(2)]
    for avatar, i in zip(avatars, (0, 1), strict=True):
        avatar.start = (float(session.positions[i, 0]), 0.0)
    engine = Engine([*avatars, *replay_partners], ring_graph(4))
    engine.reset(session.metadata["seed"], session.n_samples)
    for k in range(session.n_samples - 1):
        for avatar, i in zip(avatars, (0, 1), strict=True):
            avatar.action = int(np.flatnonzero(actions == session.controls[i, k])[0])
        engine.step()
    replay = engine.finish()
    np.testing.assert_array_equal(replay.positions, session.positions)


def test_agents_following_their_neighbours_earn_more_than_agents_at_rest():
    def rest(name: str, observation: np.ndarray) -> int:
        return 0

    totals = {}
    for name, policy in (("follow", follow), ("rest", rest)):
        _, rewards = play_episode(make_env(graph=ring_graph(4)), 3, policy)
        totals[name] = sum(r["agent_0"] + r["agent_1"] for r in rewards)
    assert totals["follow"] > totals["rest"]


def test_bad_groups_are_input_errors():
    with pytest.raises(InputError, match="at least one agent"):
        MirrorGroupEnv(n_agents=0, partners=partners())
    with pytest.raises(InputError, match="two players"):
        MirrorGroupEnv(n_agents=1)

"""Tests of the compiled Q-learning kernels: reward, exploration, update, one learning session."""

import numpy as np
import pytest

from mirror_avatar.learning.agent import CyberPlayer
from mirror_avatar.learning.discretisation import make_default_discretisation
from mirror_avatar.learning.kernels import (
    choose_action,
    compute_reward,
    draw_exploration,
    learn_session,
    mean_track,
    update_q,
)
from mirror_avatar.players.base import neighbour_mean
from mirror_avatar.testing import make_follower_sessions, python_learn_session


def test_compute_reward_formula():
    r = compute_reward(0.3, 1.0, 0.1, 0.5, 2.0, 1e-4)
    assert r == pytest.approx(-(0.2**2) - 0.1 * 0.5**2 - 1e-4 * 4.0, abs=1e-15)
    assert compute_reward(0.2, -0.1, 0.2, -0.1, 0.0, 1e-4) == 0.0


def chain(s: int, a: int, n: int) -> tuple[int, float]:
    """Deterministic chain: action 1 moves right, 0 left; moving right at the end pays 1."""
    if a == 1:
        return min(s + 1, n - 1), 1.0 if s == n - 1 else 0.0
    return max(s - 1, 0), 0.0


def test_q_learning_converges_to_value_iteration_on_a_chain(rng):
    n, discount = 5, 0.9
    q_star = np.zeros((n, 2))
    for _ in range(2000):
        q_star = np.array(
            [
                [r + discount * q_star[s2].max() for s2, r in (chain(s, a, n) for a in (0, 1))]
                for s in range(n)
            ]
        )
    q = -1e-3 * rng.random((n, 2))
    s = 0
    for draw, random_action in zip(*draw_exploration(rng, 20_000, 2), strict=True):
        a = choose_action(q, s, 1.0, draw, random_action)  # explore: Q-learning is off-policy
        s_next, r = chain(s, a, n)
        update_q(q, s, a, r, s_next, 0.5, discount)
        s = s_next
    np.testing.assert_allclose(q, q_star, atol=1e-6)
    assert np.all(q.argmax(axis=1) == 1)
    assert q_star[n - 1, 1] == pytest.approx(1 / (1 - discount))


def test_choose_action_is_greedy_without_exploration(rng):
    q = rng.random((3, 9))
    assert all(choose_action(q, s, 0.0, 0.0, 4) == q[s].argmax() for s in range(3))
    assert choose_action(q, 0, 0.3, 0.29, 4) == 4
    assert choose_action(q, 0, 0.3, 0.3, 4) == q[0].argmax()


def test_exploration_draws_are_uniform(rng):
    draws, random_actions = draw_exploration(rng, 20_000, 9)
    assert draws.shape == random_actions.shape == (20_000,)
    assert draws.min() >= 0.0 and draws.max() < 1.0
    assert abs(draws.mean() - 0.5) < 0.01
    np.testing.assert_allclose(np.bincount(random_actions, minlength=9) / 20_000, 1 / 9, atol=0.01)


def test_mean_track_is_what_players_see(rng):
    tracks = rng.normal(size=(3, 40))
    expected = [neighbour_mean(np.ascontiguousarray(tracks[:, k])) for k in range(40)]
    np.testing.assert_array_equal(mean_track(tracks), expected)
    np.testing.assert_allclose(mean_track(tracks), tracks.mean(axis=0), rtol=1e-14)
    np.testing.assert_array_equal(mean_track(tracks[:1]), tracks[0])


@pytest.mark.parametrize("features", ["absolute", "relative", "reference"])
def test_learn_session_matches_the_python_reference(zhai_trials, features):
    session = make_follower_sessions([t for t in zhai_trials if t.group == "slow"][:1])[0]
    px, tx = session.positions[:, :400]
    pv, tv = session.velocities[:, :400]
    tr = tv + 0.1 * np.sin(np.arange(tv.size) / 7.0)
    player = CyberPlayer(make_default_discretisation(features))
    player.initialise_q(3, 1e-2)
    reference = CyberPlayer(make_default_discretisation(features))
    initial = player.q_table_.copy()
    reference.q_table_ = initial.copy()
    policy = player.policy_
    disc = policy.discretisation
    draws = draw_exploration(np.random.default_rng(5), tx.size - 1, policy.actions.size)
    fast = learn_session(
        policy.q_table, px, pv, tx, tv, tr, disc.mode, disc.flat_edges, disc.offsets,
        policy.actions, player.params.record()[0], policy.n_substeps, 0.2, 0.95, 0.3, *draws,
    )  # fmt: skip
    slow = python_learn_session(reference, px, pv, tx, tv, tr, 0.2, 0.95, 0.3, *draws)
    np.testing.assert_allclose(fast, slow, rtol=1e-12)
    np.testing.assert_allclose(player.q_table_, reference.q_table_, rtol=0, atol=1e-14)
    assert np.sum(player.q_table_ != initial) > 100

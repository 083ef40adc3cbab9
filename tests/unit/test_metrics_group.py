"""Group synchronisation (cluster phase) against multiSyncPy and constructed cases."""

import numpy as np
import pytest
from multiSyncPy.synchrony_metrics import rho

from mirror_avatar.common.errors import InputError
from mirror_avatar.metrics import compute_cluster_phase, compute_phase, session_metrics
from mirror_avatar.sessions.graphs import path_graph
from mirror_avatar.sessions.session import Session

RATE = 100.0
T = np.arange(0, 40, 1 / RATE)


@pytest.mark.parametrize("n_players", [3, 4, 6, 10])
def test_equals_multisyncpy_on_the_same_phases(rng, n_players):
    drift = np.cumsum(rng.normal(0, 0.05, (n_players, T.size)), axis=1)
    phases = 2 * np.pi * 0.4 * T + rng.uniform(0, 2 * np.pi, (n_players, 1)) + drift
    ours = compute_cluster_phase(phases)
    group_series, group_mean = rho(phases)
    np.testing.assert_allclose(ours.group, group_series, rtol=0, atol=1e-9)
    assert ours.group.mean() == pytest.approx(group_mean, abs=1e-9)


def test_equals_multisyncpy_on_phases_of_positions(rng):
    x = np.array([0.3 * np.sin(2 * np.pi * f * T + p) for f, p in rng.uniform(0.2, 0.5, (5, 2))])
    phases = np.array([compute_phase(row) for row in x])
    np.testing.assert_allclose(compute_cluster_phase(phases).group, rho(phases)[0], atol=1e-9)


def test_identical_phases_are_perfectly_synchronised():
    phases = np.tile(2 * np.pi * 0.5 * T, (4, 1))
    cluster = compute_cluster_phase(phases)
    for values in (cluster.group, cluster.individual, cluster.kuramoto):
        np.testing.assert_allclose(values, 1.0, atol=1e-12)
    np.testing.assert_allclose(cluster.mean_relative_phases, 0.0, atol=1e-12)


def test_a_player_in_anti_phase():
    """A constant offset is still synchronisation; it shows in the relative phase and in r."""
    phases = np.tile(2 * np.pi * 0.5 * T, (4, 1))
    phases[3] += np.pi
    cluster = compute_cluster_phase(phases)
    np.testing.assert_allclose(cluster.group, 1.0, atol=1e-12)
    np.testing.assert_allclose(cluster.individual, 1.0, atol=1e-12)
    np.testing.assert_allclose(cluster.kuramoto, 0.5, atol=1e-12)
    offset = np.angle(
        np.exp(1j * (cluster.mean_relative_phases[3] - cluster.mean_relative_phases[0]))
    )
    assert abs(offset) == pytest.approx(np.pi, abs=1e-9)


@pytest.mark.parametrize("n_players", [4, 9, 16])
def test_independent_random_phases_give_about_one_over_root_n(rng, n_players):
    phases = rng.uniform(-np.pi, np.pi, (n_players, 50_000))
    cluster = compute_cluster_phase(phases)
    expected = np.sqrt(np.pi) / 2 / np.sqrt(n_players)  # mean length of a random walk of N steps
    assert cluster.group.mean() == pytest.approx(expected, rel=0.08)
    # each player is 1/N of the cluster phase, so even it is only as close to it as chance allows
    np.testing.assert_allclose(cluster.individual, expected, rtol=0.08)


def test_bad_phases():
    with pytest.raises(InputError, match="N >= 2"):
        compute_cluster_phase(np.zeros((1, 10)))
    with pytest.raises(InputError, match="NaN"):
        compute_cluster_phase(np.full((3, 10), np.nan))


def group_session(offsets, noise=0.0, graph=None, seed=0) -> Session:
    rng = np.random.default_rng(seed)
    x = np.array([0.3 * np.sin(2 * np.pi * 0.5 * T - o) for o in offsets])
    x += noise * rng.normal(size=x.shape)
    v = np.gradient(x, 1 / RATE, axis=1)
    nan = np.full_like(x, np.nan)
    return Session(T, x, v, nan, nan, graph=graph)


def test_session_metrics_of_a_group():
    session = group_session([0.0, 0.1, 0.2, 0.3], graph=path_graph(4))
    m = session_metrics(session, trim=2.0)
    assert m["group_synchronisation"] == pytest.approx(1.0, abs=1e-3)
    assert m["kuramoto_order"] > 0.98
    players = m["players"]
    assert [p["neighbours"] for p in players] == [[1], [0, 2], [1, 3], [2]]
    assert players[0]["time_lag"] == pytest.approx(0.1 / np.pi, abs=0.011)  # 0 is ahead of 1
    assert players[1]["time_lag"] == pytest.approx(0.0, abs=0.011)
    assert all(p["phase_locking"] > 0.99 and p["max_cross_correlation"] > 0.99 for p in players)
    assert m["mean_rmse"] == pytest.approx(np.mean([p["rmse"] for p in players]))
    assert set(m) >= {f"emd_reference_{i}" for i in range(4)}


def test_noise_lowers_group_synchronisation():
    clean = session_metrics(group_session([0.0, 0.5, 1.0]), trim=2.0)
    noisy = session_metrics(group_session([0.0, 0.5, 1.0], noise=0.3), trim=2.0)
    assert noisy["group_synchronisation"] < clean["group_synchronisation"] - 0.1

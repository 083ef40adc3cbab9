from __future__ import annotations

import csv
import io
import itertools
import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from mirror_avatar import players
from mirror_avatar.errors import InputError
from mirror_avatar.learning import (
    DEFAULT_ACTIONS,
    CyberPlayer,
    Discretisation,
    ExponentialEpsilon,
    QLearner,
    choose_action,
    compute_reward,
    integrate_hkb,
    iter_sessions,
    load_cyber_player,
    make_default_discretisation,
    make_follower_sessions,
    run_q_session,
    update_q,
)
from mirror_avatar.players import CONTROL_PERIOD, Player
from mirror_avatar.trials import Trial, make_trial

HKB = np.array([1.0, 2.0, -1.0, 0.1])


@pytest.fixture(scope="module")
def slow_chunks(zhai_trials: list[Trial]) -> tuple[tuple, tuple]:
    slow = [t for t in zhai_trials if t.group == "slow"]
    return make_follower_sessions(slow[:7]), make_follower_sessions(slow[7:])


def repeat(chunk: tuple[np.ndarray, np.ndarray], n_sessions: int):
    positions, velocities = chunk
    for i in range(n_sessions):
        j = i % positions.shape[0]
        yield positions[j], velocities[j]


def trained_player(chunk, features="relative", n_sessions=2000, seed=0) -> CyberPlayer:
    player = CyberPlayer(make_default_discretisation(features))
    QLearner(random_state=seed, progress=False, block_size=100).train(
        player, repeat(chunk, n_sessions)
    )
    return player


# --- dynamics and reward -----------------------------------------------------------------------


@pytest.mark.parametrize(("x0", "v0", "u"), [(0.1, 0.2, 2.0), (-0.3, -0.5, -4.0), (0.0, 1.0, 0.5)])
def test_integrate_hkb_matches_solve_ivp(x0, v0, u):
    alpha, beta, gamma, omega = HKB

    def rhs(_t, y):
        x, v = y
        return [v, -(alpha * x**2 + beta * v**2 - gamma) * v - omega**2 * x + u]

    exact = solve_ivp(rhs, (0.0, CONTROL_PERIOD), [x0, v0], rtol=1e-12, atol=1e-14).y[:, -1]
    x, v = integrate_hkb(x0, v0, u, HKB, CONTROL_PERIOD, 3)
    np.testing.assert_allclose([x, v], exact, rtol=0, atol=1e-8)


def test_integrate_hkb_stops_at_the_edge_of_the_range():
    x, v = integrate_hkb(0.499, 1.0, 4.0, HKB, CONTROL_PERIOD, 3)
    assert (x, v) == (0.5, 0.0)
    x, v = integrate_hkb(-0.499, -1.0, -4.0, HKB, CONTROL_PERIOD, 3)
    assert (x, v) == (-0.5, 0.0)


def test_compute_reward_formula():
    r = compute_reward(0.3, 1.0, 0.1, 0.5, 2.0, 1e-4)
    assert r == pytest.approx(-(0.2**2) - 0.1 * 0.5**2 - 1e-4 * 4.0, abs=1e-15)
    assert compute_reward(0.2, -0.1, 0.2, -0.1, 0.0, 1e-4) == 0.0


def test_exponential_epsilon_decreases_strictly():
    schedule = ExponentialEpsilon(start=0.6, end=0.02, half_life=10.0)
    values = np.array([schedule(i) for i in range(500)])
    assert values[0] == pytest.approx(0.6)
    assert schedule(10) == pytest.approx(0.02 + 0.58 / 2)
    assert np.all(np.diff(values) < 0) and values[-1] > 0.02


# --- discretisation ----------------------------------------------------------------------------


def test_discretisation_index_matches_digitize(rng):
    disc = make_default_discretisation("relative")
    for x, v, xp, vp in rng.uniform(-1, 1, (200, 4)):
        bins = [
            np.digitize(f, e) for f, e in zip((x - xp, v - vp, xp, vp), disc.edges, strict=True)
        ]
        assert disc.index(x, v, xp, vp) == np.ravel_multi_index(bins, disc.shape)
    absolute = Discretisation.uniform("absolute", [(-0.5, 0.5)] * 4, [4, 3, 2, 1])
    assert absolute.shape == (4, 3, 2, 1) and absolute.n_states == 24
    assert absolute.index(-0.3, 0.0, 0.3, 9.0) == np.ravel_multi_index((0, 1, 1, 0), (4, 3, 2, 1))


def test_discretisation_rejects_bad_edges():
    with pytest.raises(InputError, match="increasing"):
        Discretisation("absolute", ([0.0, 0.0], [], [], []))
    with pytest.raises(InputError, match="4 arrays"):
        Discretisation("absolute", ([0.0],))
    with pytest.raises(InputError, match="features"):
        Discretisation("polar", ([], [], [], []))  # type: ignore[arg-type]


# --- Q-learning core ---------------------------------------------------------------------------


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
    for _ in range(20_000):
        a = choose_action(q, s, 1.0, rng)  # explore uniformly: Q-learning is off-policy
        s_next, r = chain(s, a, n)
        update_q(q, s, a, r, s_next, 0.5, discount)
        s = s_next
    np.testing.assert_allclose(q, q_star, atol=1e-6)
    assert np.all(q.argmax(axis=1) == 1)
    assert q_star[n - 1, 1] == pytest.approx(1 / (1 - discount))


def test_choose_action_is_greedy_without_exploration(rng):
    q = rng.random((3, 9))
    assert all(choose_action(q, s, 0.0, rng) == q[s].argmax() for s in range(3))
    picks = [choose_action(q, 0, 1.0, rng) for _ in range(2000)]
    assert set(picks) == set(range(9))


def reference_session(q, px, pv, tx, tv, tr, player, lr, discount, eps, rng):
    """Straightforward Python Q-learning over one session, for comparison with the compiled one."""
    disc, actions = player.discretisation_, np.asarray(DEFAULT_ACTIONS)
    alpha, beta, gamma, omega = HKB
    h = CONTROL_PERIOD / 3

    def acc(x, v, u):
        return -(alpha * x * x + beta * v * v - gamma) * v - omega * omega * x + u

    def cell(x, v, k):
        if disc.features == "reference":
            features = (x - px[k], v - tr[k], x, tr[k])
        else:
            features = (x - px[k], v - pv[k], px[k], pv[k])
        bins = [
            int(np.searchsorted(e, f, side="right"))
            for f, e in zip(features, disc.edges, strict=True)
        ]
        return int(np.ravel_multi_index(bins, disc.shape))

    x, v = tx[0], tv[0]
    total = squares = 0.0
    for k in range(px.size - 1):
        s = cell(x, v, k)
        a = int(rng.integers(0, 9)) if rng.random() < eps else int(np.argmax(q[s]))
        u = actions[a]
        for _ in range(3):
            k1x, k1v = v, acc(x, v, u)
            k2x, k2v = v + h / 2 * k1v, acc(x + h / 2 * k1x, v + h / 2 * k1v, u)
            k3x, k3v = v + h / 2 * k2v, acc(x + h / 2 * k2x, v + h / 2 * k2v, u)
            k4x, k4v = v + h * k3v, acc(x + h * k3x, v + h * k3v, u)
            x, v = (
                x + h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x),
                v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v),
            )
        if abs(x) > 0.5:
            x, v = math.copysign(0.5, x), (min(v, 0.0) if x > 0 else max(v, 0.0))
        r = -((x - tx[k + 1]) ** 2) - 0.1 * (v - tv[k + 1]) ** 2 - 1e-4 * u * u
        q[s, a] += lr * (r + discount * q[cell(x, v, k + 1)].max() - q[s, a])
        total += r
        squares += (x - tx[k + 1]) ** 2
    return total, math.sqrt(squares / (px.size - 1))


@pytest.mark.parametrize("features", ["relative", "reference"])
def test_run_q_session_matches_python_reference(slow_chunks, features):
    positions, velocities = slow_chunks[0]
    px, tx = positions[0, :, :400]
    pv, tv = velocities[0, :, :400]
    tr = tv + 0.1 * np.sin(np.arange(tv.size) / 7.0)
    player = CyberPlayer(make_default_discretisation(features))
    player.initialise_q(3, 1e-2)
    q_reference = player.q_table_.copy()
    fast = run_q_session(
        player.q_table_,
        px,
        pv,
        tx,
        tv,
        tr,
        *player.session_arguments(),
        0.2,
        0.95,
        0.3,
        np.random.default_rng(5),
    )
    slow = reference_session(
        q_reference, px, pv, tx, tv, tr, player, 0.2, 0.95, 0.3, np.random.default_rng(5)
    )
    np.testing.assert_allclose(fast, slow, rtol=1e-12)
    np.testing.assert_allclose(player.q_table_, q_reference, rtol=0, atol=1e-14)


def test_greedy_evaluation_leaves_q_unchanged(slow_chunks):
    player = CyberPlayer()
    player.initialise_q(0, 1e-3)
    before = player.q_table_.copy()
    rewards, rms = player.evaluate([slow_chunks[1]])
    assert np.array_equal(before, player.q_table_)
    assert rewards.shape == rms.shape == (2,) and np.all(rewards < 0) and np.all(rms > 0)


# --- training ----------------------------------------------------------------------------------


def test_same_seed_gives_identical_q_table(slow_chunks):
    a = trained_player(slow_chunks[0], n_sessions=20, seed=7)
    b = trained_player(slow_chunks[0], n_sessions=20, seed=7)
    c = trained_player(slow_chunks[0], n_sessions=20, seed=8)
    assert np.array_equal(a.q_table_, b.q_table_)
    assert not np.array_equal(a.q_table_, c.q_table_)
    assert a.training_["seed"] == 7 and a.training_["n_sessions"] == 20


def test_learning_beats_random_and_copy_baselines_on_a_real_follower_task(slow_chunks):
    """Partner = a real slow trial, target = that trial 0.3 s late; test on held-out trials."""
    train, test = slow_chunks
    copy_rms = np.sqrt(np.mean((test[0][:, 0] - test[0][:, 1]) ** 2, axis=1))
    untrained = CyberPlayer()
    untrained.initialise_q(1, 1e-3)
    relative = trained_player(train, "relative")
    absolute = trained_player(train, "absolute")
    rms = {
        name: p.evaluate([test])[1].mean()
        for name, p in [("untrained", untrained), ("relative", relative), ("absolute", absolute)]
    }
    assert rms["relative"] < 0.7 * copy_rms.mean()
    assert rms["absolute"] < copy_rms.mean()
    assert rms["relative"] < rms["absolute"] < 0.3 * rms["untrained"]


def test_learning_curve_improves_and_saves(slow_chunks, tmp_path):
    learner = QLearner(random_state=0, progress=False, block_size=25)
    learner.train(CyberPlayer(), repeat(slow_chunks[0], 110))
    curve = learner.learning_curve_
    assert curve.sessions == [25, 50, 75, 100, 110]
    assert curve.rms[-1] < 0.6 * curve.rms[0]
    assert np.all(np.diff(curve.epsilon) < 0)
    with open(curve.save(tmp_path / "curve.csv")) as file:
        rows = list(csv.DictReader(file))
    assert [int(r["sessions"]) for r in rows] == curve.sessions
    np.testing.assert_allclose([float(r["rms"]) for r in rows], curve.rms)
    data = json.loads(curve.save(tmp_path / "curve.json").read_text())
    assert [row["mean_reward"] for row in data] == curve.mean_reward


def test_training_streams_lazily_and_continues(slow_chunks):
    consumed = []

    def stream():
        for i, chunk in enumerate(repeat(slow_chunks[0], 6)):
            consumed.append(i)
            yield chunk

    learner = QLearner(random_state=0, progress=False, block_size=4)
    player = CyberPlayer()
    sessions = stream()
    learner.train(player, itertools.islice(sessions, 3))
    assert consumed == [0, 1, 2] and learner.n_sessions_ == 3
    first = player.q_table_.copy()
    learner.train(player, sessions)
    assert consumed == list(range(6)) and learner.n_sessions_ == 6
    assert player.training_["n_sessions"] == 6 and learner.learning_curve_.sessions == [3, 6]
    assert not np.array_equal(first, player.q_table_)


def test_checkpoints_are_loadable(slow_chunks, tmp_path):
    path = tmp_path / "ckpt.npz"
    learner = QLearner(random_state=0, progress=False, checkpoint_every=3, checkpoint_path=path)
    player = CyberPlayer()
    learner.train(player, repeat(slow_chunks[0], 4))
    loaded = load_cyber_player(path)
    assert loaded.training_["n_sessions"] == 4
    np.testing.assert_array_equal(loaded.q_table_, player.q_table_)


@pytest.mark.parametrize(
    "chunk",
    [
        (np.zeros((3, 10)), np.zeros((3, 10))),
        (np.zeros((1, 2, 10)), np.zeros((1, 2, 9))),
        (np.full((2, 10), np.nan), np.zeros((2, 10))),
        "not a chunk",
    ],
)
def test_iter_sessions_rejects_bad_chunks(chunk):
    with pytest.raises(InputError, match="sessions"):
        list(iter_sessions([chunk]))


def test_iter_sessions_accepts_mappings_objects_and_pairs():
    positions, velocities = np.arange(40.0).reshape(2, 2, 10), np.ones((2, 2, 10))

    class Chunk:
        def __init__(self) -> None:
            self.positions, self.velocities = positions, velocities

    forms = [
        {"positions": positions, "velocities": velocities},
        Chunk(),
        (positions[0], velocities[0]),
    ]
    sessions = list(iter_sessions(forms))
    assert len(sessions) == 5
    np.testing.assert_array_equal(sessions[1][2], positions[1, 1])


def test_bad_hyper_parameters_are_input_errors():
    with pytest.raises(InputError, match="discount"):
        QLearner(discount=1.0).train(CyberPlayer(), [])
    with pytest.raises(InputError, match="checkpoint_path"):
        QLearner(checkpoint_every=5).train(CyberPlayer(), [])


# --- the player protocol -----------------------------------------------------------------------


def test_cyber_player_follows_the_player_protocol(slow_chunks):
    player = trained_player(slow_chunks[0], n_sessions=30)
    assert isinstance(player, Player) and player.period == CONTROL_PERIOD
    assert player.reset(seed=1) == (0.0, 0.0)
    (px, _), (pv, _) = slow_chunks[1][0][0], slow_chunks[1][1][0]
    path = [player.step(x, v) for x, v in zip(px, pv, strict=True)]
    assert np.all(np.abs(np.array(path)[:, 0]) <= 0.5)
    player.reset(seed=2)
    assert [player.step(x, v) for x, v in zip(px, pv, strict=True)] == path
    x, v = player.reset()
    decided = player.decide(x, v, px[0], pv[0])
    assert player.step(px[0], pv[0]) == integrate_hkb(
        x, v, DEFAULT_ACTIONS[decided], HKB, CONTROL_PERIOD, 3
    )


def test_untrained_player_cannot_play():
    with pytest.raises(InputError, match="Q-table"):
        CyberPlayer().reset()


# --- persistence -------------------------------------------------------------------------------


@pytest.fixture
def saved(slow_chunks, tmp_path) -> tuple[CyberPlayer, Path]:
    player = trained_player(slow_chunks[0], "absolute", n_sessions=10, seed=5)
    return player, player.save(tmp_path / "player.npz")


def test_save_load_round_trip(saved, slow_chunks):
    player, path = saved
    loaded = load_cyber_player(path)
    np.testing.assert_array_equal(loaded.q_table_, player.q_table_)
    assert loaded.parameters() == player.parameters()
    assert loaded.discretisation_.features == "absolute"
    for a, b in zip(loaded.discretisation_.edges, player.discretisation_.edges, strict=True):
        np.testing.assert_array_equal(a, b)
    assert loaded.training_ == player.training_
    np.testing.assert_array_equal(
        loaded.evaluate([slow_chunks[1]])[1], player.evaluate([slow_chunks[1]])[1]
    )
    with np.load(path, allow_pickle=False) as archive:
        metadata = json.loads(str(archive["metadata"]))
    assert metadata["format"] == "mirror-avatar/cyber-player" and metadata["seed"] == 5
    assert not list(path.parent.glob("*.tmp"))


def rewrite(path: Path, **changes) -> None:
    with np.load(path, allow_pickle=False) as archive:
        arrays = {key: archive[key] for key in archive.files}
    arrays.update(changes)
    with open(path, "wb") as file:
        np.savez(file, **{k: v for k, v in arrays.items() if v is not None})


def edit_metadata(path: Path, **changes) -> None:
    with np.load(path, allow_pickle=False) as archive:
        metadata = json.loads(str(archive["metadata"]))
    metadata.update(changes)
    rewrite(path, metadata=np.array(json.dumps(metadata)))


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        (lambda p: p.unlink(), "no such file"),
        (lambda p: p.write_bytes(b"garbage, not a zip"), "not a readable"),
        (lambda p: p.write_bytes(p.read_bytes()[: p.stat().st_size // 2]), "not a readable"),
        (lambda p: np.savez(p, weights=np.ones(3)), "no metadata"),
        (lambda p: p.write_bytes(npy_bytes(np.ones(3))), "not a zip archive"),
        (lambda p: rewrite(p, q_table=np.zeros((5, 9))), "does not match"),
        (lambda p: rewrite(p, actions=np.ones(4)), "does not match"),
        (lambda p: rewrite(p, edge_counts=np.array([1, 2, 3])), "edge counts"),
        (lambda p: rewrite(p, metadata=np.array("{not json")), "JSON"),
        (lambda p: rewrite(p, q_table=np.array([[object()]], dtype=object)), "not a readable"),
        (lambda p: edit_metadata(p, format="someone-else/model"), "not a mirror-avatar"),
        (lambda p: edit_metadata(p, version=99), "version"),
        (lambda p: edit_metadata(p, parameters={"speed": 1}), "invalid model"),
    ],
)
def test_load_rejects_bad_files(saved, damage, message):
    _, path = saved
    damage(path)
    with pytest.raises(InputError, match=message) as error:
        load_cyber_player(path)
    assert str(error.value).startswith(str(path)) and "\n" not in str(error.value)


def test_load_rejects_non_finite_q(saved):
    player, path = saved
    q = player.q_table_.copy()
    q[0, 0] = np.nan
    rewrite(path, q_table=q)
    with pytest.raises(InputError, match="finite"):
        CyberPlayer.load(path)


def npy_bytes(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, array)
    return buffer.getvalue()


def test_epsilon_must_not_increase(slow_chunks):
    learner = QLearner(epsilon=lambda i: 0.1 + 0.01 * i, progress=False)
    with pytest.raises(InputError, match="never increase"):
        learner.train(CyberPlayer(), repeat(slow_chunks[0], 3))
    with pytest.raises(InputError, match="half_life"):
        ExponentialEpsilon(start=0.1, end=0.2)


def test_chunk_period_must_match_the_player():
    positions, velocities = np.zeros((1, 2, 10)), np.zeros((1, 2, 10))
    chunk = {"positions": positions, "velocities": velocities, "period": 0.01}
    with pytest.raises(InputError, match="sampled every 0.01 s"):
        list(iter_sessions([chunk], CONTROL_PERIOD))
    assert len(list(iter_sessions([dict(chunk, period=CONTROL_PERIOD)], CONTROL_PERIOD))) == 1
    with pytest.raises(InputError, match="must hold positions and velocities"):
        list(iter_sessions([{"positions": positions}]))
    with pytest.raises(InputError, match="numeric"):
        list(iter_sessions([(positions, "fast")]))


def test_bad_dynamics_are_input_errors():
    with pytest.raises(InputError, match="n_substeps"):
        CyberPlayer(n_substeps=0).session_arguments()
    with pytest.raises(InputError, match="actions"):
        CyberPlayer(actions=[]).session_arguments()


def test_check_player_conformance(slow_chunks):
    players.check_player(lambda: trained_player(slow_chunks[0], n_sessions=5))


def test_make_follower_sessions_delays_the_partner(zhai_trials):
    positions, velocities = make_follower_sessions(zhai_trials[:3], lag=0.3)
    assert positions.shape == velocities.shape and positions.shape[:2] == (3, 2)
    np.testing.assert_array_equal(positions[:, 1, 10:], positions[:, 0, :-10])
    uniform = zhai_trials[0].resampled(1 / CONTROL_PERIOD)
    np.testing.assert_array_equal(positions[0, 0], uniform.positions[10 : 10 + positions.shape[2]])
    with pytest.raises(InputError, match="no trials"):
        make_follower_sessions([])
    t = np.arange(100) * 0.03
    positions, _ = make_follower_sessions([make_trial(t, 0.1 * np.sin(t))], lag=0.001)
    np.testing.assert_array_equal(positions[0, 1, 1:], positions[0, 0, :-1])


def test_training_resumes_from_a_checkpoint(slow_chunks, tmp_path):
    path = tmp_path / "ckpt.npz"
    QLearner(random_state=0, progress=False, checkpoint_path=path).train(
        CyberPlayer(), repeat(slow_chunks[0], 4)
    )
    resumed = load_cyber_player(path)
    saved_q = resumed.q_table_.copy()
    learner = QLearner(random_state=1, progress=False).train(resumed, [])
    np.testing.assert_array_equal(resumed.q_table_, saved_q)
    learner.train(resumed, repeat(slow_chunks[0], 2))
    assert learner.n_sessions_ == 6 and resumed.training_["n_sessions"] == 6
    assert learner.epsilon_ == pytest.approx(ExponentialEpsilon()(5))

"""Tests of training: the QLearner estimator on streamed sessions, its schedule and curve."""

import csv
import itertools
import json

import numpy as np
import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.engine.batch import play_compiled
from mirror_avatar.engine.loop import count_samples, play
from mirror_avatar.files.trials import make_trial
from mirror_avatar.learning.agent import CyberPlayer, load_cyber_player
from mirror_avatar.learning.discretisation import make_default_discretisation
from mirror_avatar.learning.training import (
    ExponentialEpsilon,
    ImitationTask,
    QLearner,
)
from mirror_avatar.metrics import session_metrics
from mirror_avatar.players import RecordedPlayer
from mirror_avatar.sessions.graphs import star_graph
from mirror_avatar.sessions.session import Session
from mirror_avatar.signatures.signature import compute_emd, compute_ims
from mirror_avatar.testing import make_follower_sessions
from mirror_avatar.training.imitation import score_avatar


@pytest.fixture(scope="module")
def slow_sessions(zhai_trials) -> tuple[list, list]:
    slow = [t for t in zhai_trials if t.group == "slow"]
    return make_follower_sessions(slow[:7]), make_follower_sessions(slow[7:])


def repeat(sessions: list, n_sessions: int):
    return (sessions[i % len(sessions)] for i in range(n_sessions))


def trained_player(sessions, features="relative", n_sessions=2000, seed=0) -> CyberPlayer:
    player = CyberPlayer(make_default_discretisation(features))
    QLearner(player, random_state=seed, progress=False, block_size=100).fit(
        repeat(sessions, n_sessions)
    )
    return player


def test_exponential_epsilon_decreases_strictly():
    schedule = ExponentialEpsilon(start=0.6, end=0.02, half_life=10.0)
    values = np.array([schedule(i) for i in range(500)])
    assert values[0] == pytest.approx(0.6)
    assert schedule(10) == pytest.approx(0.02 + 0.58 / 2)
    assert np.all(np.diff(values) < 0) and values[-1] > 0.02


def test_same_seed_gives_identical_q_table(slow_sessions):
    a = trained_player(slow_sessions[0], n_sessions=20, seed=7)
    b = trained_player(slow_sessions[0], n_sessions=20, seed=7)
    c = trained_player(slow_sessions[0], n_sessions=20, seed=8)
    assert np.array_equal(a.q_table_, b.q_table_)
    assert not np.array_equal(a.q_table_, c.q_table_)
    assert a.training_["seed"] == 7 and a.training_["n_sessions"] == 20


def test_learning_beats_random_and_copy_baselines_on_a_real_follower_task(slow_sessions):
    """Partner = a real slow trial, target = that trial 0.3 s late; test on held-out trials."""
    train, test = slow_sessions
    copy_rms = np.mean([np.sqrt(np.mean((s.positions[0] - s.positions[1]) ** 2)) for s in test])
    untrained = CyberPlayer()
    untrained.initialise_q(1, 1e-3)
    relative = trained_player(train, "relative")
    absolute = trained_player(train, "absolute")
    rms = {
        name: score_avatar(p, test)[1].mean()
        for name, p in [("untrained", untrained), ("relative", relative), ("absolute", absolute)]
    }
    assert rms["relative"] < 0.7 * copy_rms
    assert rms["absolute"] < copy_rms
    assert rms["relative"] < rms["absolute"] < 0.3 * rms["untrained"]


def test_greedy_scoring_leaves_q_unchanged(slow_sessions):
    player = CyberPlayer()
    player.initialise_q(0, 1e-3)
    before = player.q_table_.copy()
    rewards, rms = score_avatar(player, slow_sessions[1])
    assert np.array_equal(before, player.q_table_)
    assert rewards.shape == rms.shape == (2,) and np.all(rewards < 0) and np.all(rms > 0)


def test_learning_curve_improves_and_saves(slow_sessions, tmp_path):
    learner = QLearner(CyberPlayer(), random_state=0, progress=False, block_size=25)
    learner.fit(repeat(slow_sessions[0], 110))
    curve = learner.learning_curve_
    assert curve.sessions == [25, 50, 75, 100, 110]
    assert curve.rms[-2] < 0.6 * curve.rms[0]  # the last whole block against the first
    assert np.all(np.diff(curve.epsilon) < 0)
    with open(curve.save(tmp_path / "curve.csv")) as file:
        rows = list(csv.DictReader(file))
    assert [int(r["sessions"]) for r in rows] == curve.sessions
    np.testing.assert_allclose([float(r["rms"]) for r in rows], curve.rms)
    data = json.loads(curve.save(tmp_path / "curve.json").read_text())
    assert [row["mean_reward"] for row in data] == curve.mean_reward


def test_partial_fit_streams_lazily_and_continues_where_fit_stopped(slow_sessions):
    consumed = []

    def stream():
        for i, session in enumerate(repeat(slow_sessions[0], 6)):
            consumed.append(i)
            yield session

    player = CyberPlayer()
    learner = QLearner(player, random_state=0, progress=False, block_size=4)
    sessions = stream()
    learner.fit(itertools.islice(sessions, 3))
    assert consumed == [0, 1, 2] and learner.n_sessions_ == 3
    first = player.q_table_.copy()
    learner.partial_fit(sessions)
    assert consumed == list(range(6)) and learner.n_sessions_ == 6
    assert player.training_["n_sessions"] == 6 and learner.learning_curve_.sessions == [3, 6]
    assert not np.array_equal(first, player.q_table_)
    whole = CyberPlayer()
    QLearner(whole, random_state=0, progress=False, block_size=4).fit(repeat(slow_sessions[0], 6))
    np.testing.assert_array_equal(whole.q_table_, player.q_table_)


def test_checkpoints_are_loadable(slow_sessions, tmp_path):
    path = tmp_path / "ckpt.npz"
    player = CyberPlayer()
    learner = QLearner(player, random_state=0, progress=False, checkpoint_every=3,
                       checkpoint_path=path)  # fmt: skip
    learner.fit(repeat(slow_sessions[0], 4))
    loaded = load_cyber_player(path)
    assert loaded.training_["n_sessions"] == 4
    np.testing.assert_array_equal(loaded.q_table_, player.q_table_)


def test_training_resumes_from_a_checkpoint(slow_sessions, tmp_path):
    path = tmp_path / "ckpt.npz"
    QLearner(CyberPlayer(), random_state=0, progress=False, checkpoint_path=path).fit(
        repeat(slow_sessions[0], 4)
    )
    resumed = load_cyber_player(path)
    saved_q = resumed.q_table_.copy()
    learner = QLearner(resumed, random_state=1, progress=False).fit([])
    np.testing.assert_array_equal(resumed.q_table_, saved_q)
    learner.partial_fit(repeat(slow_sessions[0], 2))
    assert learner.n_sessions_ == 6 and resumed.training_["n_sessions"] == 6
    assert learner.epsilon_ == pytest.approx(ExponentialEpsilon()(5))


def test_the_target_is_seen_through_its_neighbours_mean(slow_sessions):
    """In a star, the centre's partner is the mean of the others; a leaf's is the centre."""
    base = slow_sessions[0][0]
    x = np.vstack([base.positions, base.positions[:1] + 0.1])
    v = np.vstack([base.velocities, base.velocities[:1]])
    nan = np.full_like(x, np.nan)
    group = Session(base.times, x, v, nan, nan, graph=star_graph(3, centre=1))
    centre = ImitationTask.from_session(group, 1, base.period)
    np.testing.assert_allclose(centre.partner_x, (x[0] + x[2]) / 2, rtol=1e-14)
    leaf = ImitationTask.from_session(group, 2, base.period)
    np.testing.assert_array_equal(leaf.partner_x, x[1])


def test_bad_hyper_parameters_and_sessions_are_input_errors(slow_sessions):
    with pytest.raises(InputError, match="discount"):
        QLearner(CyberPlayer(), discount=1.0).fit([])
    with pytest.raises(InputError, match="checkpoint_path"):
        QLearner(CyberPlayer(), checkpoint_every=5).fit([])
    session = slow_sessions[0][0]
    with pytest.raises(InputError, match="sampled every"):
        ImitationTask.from_session(session, 1, 0.01)
    with pytest.raises(InputError, match="no player 2"):
        ImitationTask.from_session(session, 2, session.period)
    lonely = Session(session.times, session.positions, session.velocities, session.controls,
                     session.references, graph=np.zeros((2, 2)))  # fmt: skip
    with pytest.raises(InputError, match="observes no one"):
        ImitationTask.from_session(lonely, 1, session.period)
    leader = CyberPlayer(make_default_discretisation("reference"))
    leader.initialise_q(0, 1.0)
    with pytest.raises(InputError, match="reference velocities"):
        score_avatar(leader, [session])


def test_epsilon_must_not_increase(slow_sessions):
    learner = QLearner(CyberPlayer(), epsilon=lambda i: 0.1 + 0.01 * i, progress=False)
    with pytest.raises(InputError, match="never increase"):
        learner.fit(repeat(slow_sessions[0], 3))
    with pytest.raises(InputError, match="half_life"):
        ExponentialEpsilon(start=0.1, end=0.2)


def test_the_target_signature_is_learned_saved_and_scored(slow_sessions, tmp_path):
    """The player keeps its target's velocity counts; its sessions score its IMS against them."""
    sessions = slow_sessions[0]
    player = CyberPlayer()
    QLearner(player, random_state=0, progress=False).fit(repeat(sessions, 9))
    targets = [sessions[i % len(sessions)].velocities[1] for i in range(9)]
    np.testing.assert_array_equal(player.target_ims(), compute_ims(np.concatenate(targets)))
    assert CyberPlayer().target_ims() is None and "target_ims" not in CyberPlayer().describe()
    loaded = load_cyber_player(player.save(tmp_path / "p.npz"))
    np.testing.assert_array_equal(loaded.target_counts_, player.target_counts_)
    partner = RecordedPlayer(make_trial(sessions[0].times, sessions[0].positions[0]))
    lineup = [partner, loaded]
    n_samples = count_samples(6.0, loaded.period)
    for session in (play(lineup, 6.0, 1), play_compiled(lineup, n_samples, 1)):
        own = compute_ims(session.trimmed(1.0).velocities[1])
        metrics = session_metrics(session, trim=1.0)
        assert metrics["emd_target_1"] == pytest.approx(compute_emd(own, player.target_ims()))
        assert "emd_target_0" not in metrics


@pytest.mark.parametrize(
    ("counts", "problem"),
    [
        (np.ones(5), "target_counts has shape"),
        (-np.ones(200), r"holds -1\.0; its values must be finite and within 0\.\."),
    ],
)
def test_bad_target_counts_in_a_file_are_refused(slow_sessions, tmp_path, counts, problem):
    player = CyberPlayer()
    QLearner(player, random_state=0, progress=False).fit(slow_sessions[0][:1])
    player.target_counts_ = counts
    path = player.save(tmp_path / "bad.npz")
    with pytest.raises(InputError, match=problem):
        load_cyber_player(path)

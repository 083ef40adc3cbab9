"""The paper's training set-up: virtual trainers VT1..VT6 and the streamed training driver."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar import dynamics
from mirror_avatar.common.errors import InputError
from mirror_avatar.engine.batch import run_sessions
from mirror_avatar.engine.loop import play
from mirror_avatar.files.model_files import read_archive, save_model
from mirror_avatar.files.trials import Trial
from mirror_avatar.learning.agent import DEFAULT_ACTIONS, load_cyber_player
from mirror_avatar.learning.discretisation import make_default_discretisation
from mirror_avatar.learning.training import (
    ImitationTask,
    play_task,
    policy_arguments,
)
from mirror_avatar.players import check_player
from mirror_avatar.training.cast import (
    SEEN_PARTNERS,
    TARGET,
    UNSEEN_PARTNER,
    VirtualTrainerSpec,
    make_virtual_trainers,
)
from mirror_avatar.training.imitation import (
    derive_seeds,
    learning_curve_path,
    make_cyber_player,
    make_pairs,
    make_role_discretisation,
    score_avatar,
    train_cyber_player,
)


@pytest.fixture(scope="module")
def trainers(zhai_trials: list[Trial]) -> list[VirtualTrainerSpec]:
    return make_virtual_trainers(zhai_trials, n_symbols=64)


def test_six_disjoint_trainers_three_trials_each(trainers: list[VirtualTrainerSpec]) -> None:
    assert [t.label for t in trainers] == [f"VT{i}" for i in range(1, 7)]
    assert trainers[0].trial_labels == ("fast-1", "fast-2", "fast-3")
    assert trainers[TARGET].trial_labels == ("slow-4", "slow-5", "slow-6")
    assert trainers[UNSEEN_PARTNER].trial_labels == ("slow-7", "slow-8", "slow-9")
    used = [label for t in trainers for label in t.trial_labels]
    assert len(used) == len(set(used)) == 18
    assert TARGET not in SEEN_PARTNERS and UNSEEN_PARTNER not in SEEN_PARTNERS


def test_trainer_generators_keep_their_style(trainers: list[VirtualTrainerSpec]) -> None:
    """Each generator's velocities are as fast as its own trials: fast VTs faster than slow."""
    spread = [np.std(t.generator.sample_velocity(6000, 0)) for t in trainers]
    assert min(spread[:3]) > max(spread[3:])


def test_make_virtual_trainers_rejects_bad_counts(zhai_trials: list[Trial]) -> None:
    with pytest.raises(InputError, match="multiple of 2 groups"):
        make_virtual_trainers(zhai_trials, n=5)
    with pytest.raises(InputError, match="group 'fast'"):
        make_virtual_trainers(zhai_trials[:2] + zhai_trials[9:], n=6)


def test_pairs_put_the_partner_first_in_the_other_role(
    trainers: list[VirtualTrainerSpec],
) -> None:
    partners = [trainers[i].generator for i in SEEN_PARTNERS]
    follower = make_pairs(trainers[TARGET].generator, partners, "follower")
    assert len(follower) == 4
    assert all(p.params == dynamics.LEADER and t.params == dynamics.FOLLOWER for p, t in follower)
    assert all(t.reference is trainers[TARGET].generator for _, t in follower)
    leader = make_pairs(trainers[TARGET].generator, partners, "leader")
    assert all(p.params == dynamics.FOLLOWER and t.params == dynamics.LEADER for p, t in leader)
    with pytest.raises(InputError, match="role"):
        make_pairs(trainers[TARGET].generator, partners, "joint")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="partner"):
        make_pairs(trainers[TARGET].generator, [], "follower")


def test_cyber_player_takes_the_role_dynamics() -> None:
    follower, leader = make_cyber_player("follower"), make_cyber_player("leader")
    assert follower.params == dynamics.FOLLOWER and leader.params == dynamics.LEADER
    assert (follower.params.alpha, follower.params.beta, follower.params.gamma) == (1.0, 2.0, -1.0)
    np.testing.assert_allclose(follower.actions_, 4.0 * np.array(DEFAULT_ACTIONS))


def test_role_discretisations() -> None:
    """The leader uses reference features; the follower's own bins are finer, symmetric about 0."""
    default = make_default_discretisation("relative")
    leader, follower = make_role_discretisation("leader"), make_role_discretisation("follower")
    assert make_cyber_player("leader").discretisation_.shape == leader.shape == (10, 10, 8, 12)
    assert make_cyber_player("follower").discretisation_.shape == follower.shape == (18, 14, 6, 7)
    assert leader.features == "reference" and follower.features == "relative"
    # the leader's cell follows its own reference velocity, not the partner's velocity
    assert leader.index(0.0, 0.2, 0.0, 0.0, 0.2) != leader.index(0.0, 0.2, 0.0, 0.0, -0.2)
    assert leader.index(0.0, 0.2, 0.0, 0.5, 0.2) == leader.index(0.0, 0.2, 0.0, -0.5, 0.2)
    for own in follower.edges[:2]:
        np.testing.assert_array_equal(own, -own[::-1])
        assert own[own.size // 2] == 0.0
    for d in (2, 3):
        np.testing.assert_array_equal(follower.edges[d], default.edges[d])
    assert follower.index(0.055, 0.0, 0.0, 0.3) != follower.index(0.08, 0.0, 0.0, 0.3)
    assert default.index(0.055, 0.0, 0.0, 0.3) == default.index(0.08, 0.0, 0.0, 0.3)
    with pytest.raises(InputError, match="role"):
        make_role_discretisation("joint")  # type: ignore[arg-type]


def test_seeds_are_derived_independently() -> None:
    assert derive_seeds(0) == derive_seeds(0)
    assert len(set(derive_seeds(0))) == 2 and derive_seeds(0) != derive_seeds(1)


def _train(trainers: list[VirtualTrainerSpec], seed: int, **kwargs: object) -> tuple:
    return train_cyber_player(
        trainers[TARGET].generator,
        [trainers[i].generator for i in SEEN_PARTNERS],
        n_sessions=6,
        seed=seed,
        duration=5.0,
        n_jobs=1,
        chunk_size=4,
        progress=False,
        **kwargs,  # type: ignore[arg-type]
    )


def test_training_is_reproducible_from_the_seed(trainers: list[VirtualTrainerSpec]) -> None:
    first, curve = _train(trainers, seed=3)
    again, _ = _train(trainers, seed=3)
    other, _ = _train(trainers, seed=4)
    np.testing.assert_array_equal(first.q_table_, again.q_table_)
    assert not np.array_equal(first.q_table_, other.q_table_)
    assert first.training_["run_seed"] == 3 and first.training_["n_sessions"] == 6
    assert curve.sessions[-1] == 6


def test_training_learns_from_exactly_the_batch_sessions(
    trainers: list[VirtualTrainerSpec],
) -> None:
    """The driver's curve equals Q-learning on the batch engine's sessions, replayed by hand."""
    player, curve = _train(trainers, seed=5)
    pairs = make_pairs(trainers[TARGET].generator, [trainers[i].generator for i in SEEN_PARTNERS],
                       "follower")  # fmt: skip
    session_seed, learner_seed = derive_seeds(5)
    (chunk,) = run_sessions(pairs, 6, duration=5.0, seed=session_seed, n_jobs=1)
    replay = make_cyber_player("follower")
    sequence = np.random.SeedSequence(learner_seed)
    q_seed, explore_seed = sequence.spawn(2)
    replay.initialise_q(np.random.default_rng(q_seed), 1e-3)
    rng = np.random.default_rng(explore_seed)
    scores = []
    for i, session in enumerate(chunk):
        task = ImitationTask.from_session(session, 1, session.period)
        epsilon = 0.01 + 0.49 * 0.5 ** (i / 1.0)
        scores.append(play_task(policy_arguments(replay), task, 0.1, 0.95, epsilon, rng))
    np.testing.assert_allclose(replay.q_table_, player.q_table_)
    assert curve.rms == pytest.approx([s[1] for s in scores])


def test_leader_plays_from_its_own_reference(
    trainers: list[VirtualTrainerSpec], tmp_path: Path
) -> None:
    """A reference-feature leader draws its reference from VT5's generator at each reset, passes
    the step protocol as a stochastic player and plays the same from its saved file alone."""
    leader, _ = _train(trainers, seed=2, role="leader")
    assert leader.reference is trainers[TARGET].generator and leader.stochastic
    check_player(lambda: leader)
    path = leader.save(tmp_path / "leader.npz")
    loaded = load_cyber_player(path)
    np.testing.assert_array_equal(loaded.q_table_, leader.q_table_)
    partner = trainers[0].player("follower")
    a, b = (play([p, partner], 3.0, seed=4) for p in (leader, loaded))
    np.testing.assert_array_equal(a.positions, b.positions)
    assert np.all(np.isfinite(a.references[0, :-1]))  # the leader's own reference is recorded
    np.testing.assert_array_equal(a.references, b.references)
    arrays, metadata = read_archive(path)
    kept = {k: v for k, v in arrays.items() if not k.startswith("reference_")}
    del metadata["reference"]
    broken = tmp_path / "broken.npz"
    save_model(broken, metadata.pop("format"), metadata.pop("version"), kept, metadata)
    with pytest.raises(InputError, match="broken.npz: reference features but no reference"):
        load_cyber_player(broken)


def test_a_saved_leader_needs_a_generator_target(
    trainers: list[VirtualTrainerSpec], zhai_trials: list[Trial], tmp_path: Path
) -> None:
    with pytest.raises(InputError, match="target: a leader or a deep player saved to a file needs"):
        train_cyber_player(
            zhai_trials[12], [trainers[0].generator], "leader", checkpoint=tmp_path / "p.npz"
        )
    assert not (tmp_path / "p.npz").exists()


def test_reference_features_need_reference_velocities(trainers: list[VirtualTrainerSpec]) -> None:
    leader = make_cyber_player("leader")
    leader.initialise_q(0, 1e-3)
    with pytest.raises(InputError, match="reference generator"):
        leader.reset(seed=0)
    pairs = make_pairs(trainers[TARGET].generator, [trainers[0].generator], "leader")
    (session,) = next(run_sessions(pairs, 1, duration=2.0, n_jobs=1))
    session.references[:] = np.nan
    with pytest.raises(InputError, match="reference velocities"):
        score_avatar(leader, [session])
    (session,) = next(run_sessions(pairs, 1, duration=2.0, n_jobs=1))
    assert score_avatar(leader, [session])[1].shape == (1,)


def test_checkpoint_and_learning_curve_files(
    trainers: list[VirtualTrainerSpec], tmp_path: Path
) -> None:
    policy = tmp_path / "policy.npz"
    player, curve = _train(trainers, seed=1, checkpoint=policy, checkpoint_every=3)
    loaded = load_cyber_player(policy)
    np.testing.assert_array_equal(loaded.q_table_, player.q_table_)
    assert loaded.training_["role"] == "follower"
    assert loaded.params.omega == dynamics.FOLLOWER.omega
    path = curve.save(learning_curve_path(policy))
    assert path == tmp_path / "policy.learning_curve.csv"
    lines = path.read_text().splitlines()
    assert lines[0] == "sessions,mean_reward,rms,epsilon" and len(lines) == 7


@pytest.mark.slow
def test_learning_happens_and_beats_the_baselines(trainers: list[VirtualTrainerSpec]) -> None:
    """Follower training on VT sessions: the curve improves and the trained player imitates VT5
    on held-out sessions better than an untrained player and than copying the partner."""
    player, curve = train_cyber_player(
        trainers[TARGET].generator,
        [trainers[i].generator for i in SEEN_PARTNERS],
        n_sessions=3000,
        seed=0,
        progress=False,
    )
    assert np.mean(curve.rms[-10:]) < 0.6 * np.mean(curve.rms[:5])
    partners = [trainers[i].generator for i in (*SEEN_PARTNERS, UNSEEN_PARTNER)]
    pairs = make_pairs(trainers[TARGET].generator, partners, "follower")
    sessions = [s for chunk in run_sessions(pairs, 30, seed=99, n_jobs=2) for s in chunk]
    untrained = make_cyber_player("follower")
    untrained.initialise_q(0, 1e-3)
    trained_rms = score_avatar(player, sessions)[1].mean()
    positions = np.stack([s.positions for s in sessions])
    copy_rms = np.sqrt(((positions[:, 0, 1:] - positions[:, 1, 1:]) ** 2).mean(axis=1)).mean()
    assert trained_rms < 0.5 * score_avatar(untrained, sessions)[1].mean()
    assert trained_rms < copy_rms
    assert math.isfinite(trained_rms)

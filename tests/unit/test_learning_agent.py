"""Tests of the cyber player: its cells, the player protocol, and its model file."""

import io
import json
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.dynamics import CONTROL_PERIOD, FOLLOWER, LEADER, integrate_hkb
from mirror_avatar.learning.agent import DEFAULT_ACTIONS, CyberPlayer, load_cyber_player
from mirror_avatar.learning.discretisation import Discretisation, make_default_discretisation
from mirror_avatar.learning.training import QLearner
from mirror_avatar.players import Observation, Player, check_player
from mirror_avatar.testing import make_follower_sessions
from mirror_avatar.training.imitation import score_avatar


@pytest.fixture(scope="module")
def slow_sessions(zhai_trials) -> tuple[list, list]:
    slow = [t for t in zhai_trials if t.group == "slow"]
    return make_follower_sessions(slow[:7]), make_follower_sessions(slow[7:])


def trained_player(sessions, features="relative", n_sessions=30, seed=0) -> CyberPlayer:
    player = CyberPlayer(make_default_discretisation(features))
    stream = (sessions[i % len(sessions)] for i in range(n_sessions))
    QLearner(player, random_state=seed, progress=False).fit(stream)
    return player


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
    reference = make_default_discretisation("reference")
    x, v, xp, r = 0.1, 0.4, -0.05, 0.3
    bins = [np.digitize(f, e) for f, e in zip((x - xp, v - r, x, r), reference.edges, strict=True)]
    assert reference.index(x, v, xp, 9.0, r) == np.ravel_multi_index(bins, reference.shape)


def test_discretisation_index_on_the_edges_and_beyond():
    """A value on an edge lies above it, infinities in the end bins, as numpy.digitize says."""
    disc = make_default_discretisation("absolute")
    for d, edges in enumerate(disc.edges):
        for value in [*edges, -np.inf, np.inf, edges[0] - 1e-12, edges[-1] + 1e-12]:
            state = [0.0] * 4
            state[d] = value
            bins = [np.digitize(f, e) for f, e in zip(state, disc.edges, strict=True)]
            assert disc.index(*state) == np.ravel_multi_index(bins, disc.shape)


def test_discretisation_rejects_bad_edges():
    with pytest.raises(InputError, match="increasing"):
        Discretisation("absolute", ([0.0, 0.0], [], [], []))
    with pytest.raises(InputError, match="4 arrays"):
        Discretisation("absolute", ([0.0],))
    with pytest.raises(InputError, match="features"):
        Discretisation("polar", ([], [], [], []))  # type: ignore[arg-type]


# --- the player protocol -----------------------------------------------------------------------


def test_cyber_player_follows_the_player_protocol(slow_sessions):
    player = trained_player(slow_sessions[0])
    assert isinstance(player, Player) and player.period == CONTROL_PERIOD
    assert player.reset(seed=1) == (0.0, 0.0)
    partner_x, partner_v = slow_sessions[1][0].positions[0], slow_sessions[1][0].velocities[0]
    seen = [
        Observation.of_partner(k, x, v, x)
        for k, (x, v) in enumerate(zip(partner_x, partner_v, strict=False))
    ]
    path = [player.step(o) for o in seen]
    assert np.all(np.abs(np.array(path)[:, 0]) <= 0.5)
    player.reset(seed=2)
    assert [player.step(o) for o in seen] == path


def test_the_step_applies_the_greedy_action_and_reports_it(slow_sessions):
    player = trained_player(slow_sessions[0])
    x, v = player.reset()
    seen = Observation.of_partner(0, 0.2, -0.3, 0.2)
    best = int(np.argmax(player.q_table_[player.discretisation_.index(x, v, 0.2, -0.3)]))
    assert player.step(seen) == integrate_hkb(x, v, DEFAULT_ACTIONS[best], FOLLOWER.record()[0], 3)
    assert player.last_control == DEFAULT_ACTIONS[best]


def test_check_player_conformance(slow_sessions):
    check_player(lambda: trained_player(slow_sessions[0], n_sessions=5))


def test_untrained_player_cannot_play():
    with pytest.raises(InputError, match="Q-table"):
        CyberPlayer().reset()


def test_bad_dynamics_are_input_errors():
    with pytest.raises(InputError, match="n_substeps"):
        player = CyberPlayer(n_substeps=0)
        player.initialise_q(0, 1.0)
        player.reset()
    with pytest.raises(InputError, match="actions"):
        CyberPlayer(actions=[]).initialise_q(0, 1.0)


# --- persistence -------------------------------------------------------------------------------


@pytest.fixture
def saved(slow_sessions, tmp_path) -> tuple[CyberPlayer, Path]:
    player = trained_player(slow_sessions[0], "absolute", n_sessions=10, seed=5)
    return player, player.save(tmp_path / "player.npz")


def test_save_load_round_trip(saved, slow_sessions):
    player, path = saved
    loaded = load_cyber_player(path)
    np.testing.assert_array_equal(loaded.q_table_, player.q_table_)
    assert loaded.parameters() == player.parameters()
    assert loaded.discretisation_.features == "absolute"
    for a, b in zip(loaded.discretisation_.edges, player.discretisation_.edges, strict=True):
        np.testing.assert_array_equal(a, b)
    assert loaded.training_ == player.training_
    np.testing.assert_array_equal(
        score_avatar(loaded, slow_sessions[1])[1], score_avatar(player, slow_sessions[1])[1]
    )
    with np.load(path, allow_pickle=False) as archive:
        metadata = json.loads(str(archive["metadata"]))
    assert metadata["format"] == "mirror-avatar/cyber-player" and metadata["seed"] == 5
    assert not list(path.parent.glob("*.tmp"))


def test_files_without_cost_weights_still_load(saved):
    """Version-1 files name the end effector only (alpha..period, substeps, start)."""
    _, path = saved
    edit_metadata(path, parameters={"alpha": 1.0, "beta": 2.0, "gamma": -1.0, "omega": 0.8,
                                    "eta": 1e-4, "period": 0.03, "n_substeps": 3,
                                    "initial_position": 0.1})  # fmt: skip
    loaded = load_cyber_player(path)
    assert loaded.params.omega == LEADER.omega and loaded.initial_position == 0.1


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


def npy_bytes(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, array)
    return buffer.getvalue()


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
        (lambda p: rewrite(p, edge_counts=np.array([1, 2, 3])), "edge_counts has shape"),
        (lambda p: rewrite(p, metadata=np.array("{not json")), "JSON"),
        (lambda p: rewrite(p, q_table=np.array([[object()]], dtype=object)), "dtype object"),
        (lambda p: edit_metadata(p, format="someone-else/model"), "not a mirror-avatar"),
        (lambda p: edit_metadata(p, version=99), "version"),
        (lambda p: edit_metadata(p, parameters={"speed": 1}), "unknown parameter 'speed'"),
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

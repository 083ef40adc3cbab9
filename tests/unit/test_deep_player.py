"""Tests of the deep cyber player: its input, the player protocol, both loops, its model file."""

import itertools

import numpy as np
import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.deep.features import (
    RELATIVE_POSITION_SCALE,
    RELATIVE_VELOCITY_SCALE,
    count_features,
    encode,
)
from mirror_avatar.deep.network import q_values
from mirror_avatar.deep.player import DeepCyberPlayer, load_deep_cyber_player
from mirror_avatar.dynamics import FOLLOWER, integrate_hkb
from mirror_avatar.engine.batch import play_compiled
from mirror_avatar.engine.loop import play
from mirror_avatar.learning.agent import CyberPlayer
from mirror_avatar.players import Observation, check_player
from mirror_avatar.sessions.graphs import ring_graph
from mirror_avatar.signatures.signature import DEFAULT_BINS
from mirror_avatar.specs import bundled_generator, load_player

SCALED_ACTIONS = tuple(4.0 * a for a in (-4.0, -2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0, 4.0))


def deep_player(seed: int = 3, **options) -> DeepCyberPlayer:
    player = DeepCyberPlayer(actions=SCALED_ACTIONS, **options)
    player.initialise_policy(seed)
    return player


def features(x, v, positions, velocities, n_slots, reference=0.0, use_reference=False):
    out = np.full(count_features(n_slots, use_reference), np.nan)
    encode(x, v, reference, np.array(positions), np.array(velocities), n_slots, use_reference, out)
    return out


def test_a_dyad_sees_its_state_and_its_partner_relative_to_itself() -> None:
    got = features(0.1, 0.2, [0.3], [-0.4], n_slots=0)
    rx, rv = RELATIVE_POSITION_SCALE, RELATIVE_VELOCITY_SCALE
    np.testing.assert_allclose(got, [0.2, 0.2, 0.2 * rx, -0.6 * rv])
    with_reference = features(0.1, 0.2, [0.3], [-0.4], 0, reference=0.7, use_reference=True)
    np.testing.assert_allclose(with_reference, [0.2, 0.2, 0.7, 0.2 * rx, -0.6 * rv])


def test_neighbour_slots_ignore_numbering_and_pad_with_own_state() -> None:
    positions, velocities = [0.3, -0.2, 0.05], [0.1, 0.5, -0.3]
    reference = features(0.0, 0.1, positions, velocities, n_slots=4)
    for order in itertools.permutations(range(3)):
        shuffled = features(
            0.0, 0.1, [positions[i] for i in order], [velocities[i] for i in order], n_slots=4
        )
        np.testing.assert_allclose(shuffled, reference, rtol=0, atol=1e-15)
    slots = reference[4:].reshape(4, 3)
    np.testing.assert_allclose(slots[:, 0] / RELATIVE_POSITION_SCALE, [-0.2, 0.05, 0.3, 0.0])
    np.testing.assert_array_equal(slots[:, 2], [1.0, 1.0, 1.0, 0.0])
    assert np.all(slots[3] == 0.0)  # the empty slot holds the avatar's own state (relative: 0)
    alone = features(0.2, -0.1, [], [], n_slots=2)
    np.testing.assert_array_equal(alone, [0.4, -0.1, 0, 0, 0, 0, 0, 0, 0, 0])


def test_more_neighbours_than_slots_keep_the_nearest_and_the_mean_of_all() -> None:
    got = features(0.0, 0.0, [0.4, -0.1, 0.02, -0.3], [0.0, 0.0, 0.0, 0.0], n_slots=2)
    assert got[2] == pytest.approx(0.005 * RELATIVE_POSITION_SCALE)
    np.testing.assert_allclose(got[4:].reshape(2, 3)[:, 0] / RELATIVE_POSITION_SCALE, [-0.1, 0.02])


@pytest.mark.parametrize("n_slots", [0, 3])
def test_the_deep_player_honours_the_protocol(n_slots) -> None:
    check_player(lambda: deep_player(n_slots=n_slots))
    generator = bundled_generator("slow")
    check_player(lambda: deep_player(use_reference=True, reference=generator))


def test_a_step_takes_the_network_s_best_action() -> None:
    player = deep_player(n_slots=2)
    x, v = player.reset(seed=0)
    seen = Observation(0, np.array([0.2, -0.1]), np.array([0.3, 0.0]), np.array([0.2, -0.1]))
    values = q_values(player.weights_, player.sizes_, features(x, v, [0.2, -0.1], [0.3, 0.0], 2))
    best = SCALED_ACTIONS[int(np.argmax(values))]
    assert player.step(seen) == integrate_hkb(x, v, best, FOLLOWER.record()[0], 3)
    assert player.last_control == best


def test_compiled_and_python_loops_agree_bit_for_bit_in_a_mixed_group() -> None:
    tabular = CyberPlayer(actions=SCALED_ACTIONS, label="tabular")
    tabular.initialise_q(1, 1.0)
    group = [
        load_player("bundled:fast", "group"),
        deep_player(n_slots=3, label="deep"),
        tabular,
        deep_player(seed=4, use_reference=True, reference=bundled_generator("slow")),
    ]
    looped = play(group, 10.0, seed=5, graph=ring_graph(4))
    compiled = play_compiled(group, looped.n_samples, 5, ring_graph(4))
    for channel in ("positions", "velocities", "controls", "references"):
        np.testing.assert_array_equal(getattr(compiled, channel), getattr(looped, channel))
    assert np.ptp(looped.positions[1]) > 0.01 and np.ptp(looped.positions[3]) > 0.01


def test_a_saved_player_plays_the_same_from_its_file(tmp_path) -> None:
    leader = deep_player(use_reference=True, reference=bundled_generator("slow"))
    leader.training_ = {"role": "leader", "n_sessions": 3, "seed": 9}
    leader.target_counts_ = np.arange(float(DEFAULT_BINS.n))
    path = leader.save(tmp_path / "leader.npz")
    loaded = load_deep_cyber_player(path)
    np.testing.assert_array_equal(loaded.weights_, leader.weights_)
    assert loaded.describe() == leader.describe()
    partner = load_player("bundled:fast", "follower")
    a = play([partner, leader], 5.0, seed=2)
    b = play([partner, load_player(str(path), "leader")], 5.0, seed=2)
    np.testing.assert_array_equal(a.positions, b.positions)
    with pytest.raises(InputError, match="trained as leader cannot play follower"):
        load_player(str(path), "follower")


def test_an_untrained_player_says_so() -> None:
    with pytest.raises(InputError, match="has no network"):
        DeepCyberPlayer().reset(0)
    with pytest.raises(InputError, match="needs a reference generator"):
        deep_player(use_reference=True).reset(0)

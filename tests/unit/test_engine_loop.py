"""Tests of the engine: N players on a graph through the Python step loop and the compiled loop."""

import math

import numpy as np
import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.dynamics import FOLLOWER, JOINT, LEADER
from mirror_avatar.engine.batch import play_compiled
from mirror_avatar.engine.loop import Engine, play
from mirror_avatar.learning.agent import CyberPlayer
from mirror_avatar.learning.discretisation import make_default_discretisation
from mirror_avatar.metrics import compute_phase_locking, compute_relative_phase
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.players import ExternalPlayer, RecordedPlayer, VirtualTrainer
from mirror_avatar.sessions.graphs import path_graph, random_connected_graph, ring_graph, star_graph
from mirror_avatar.sessions.session import Session

CHANNELS = ("positions", "velocities", "controls", "references")


@pytest.fixture(scope="module")
def generator(zhai_trials_100hz: list) -> IMSGenerator:
    return IMSGenerator(n_symbols=32, random_state=0).fit(zhai_trials_100hz[9:12])


@pytest.fixture(scope="module")
def session(generator: IMSGenerator) -> Session:
    return play([VirtualTrainer(LEADER, generator), VirtualTrainer(FOLLOWER, generator)], 20.0, 7)


@pytest.fixture(scope="module")
def cyber(generator: IMSGenerator) -> CyberPlayer:
    player = CyberPlayer(make_default_discretisation("reference"), reference=generator)
    player.initialise_q(np.random.default_rng(3), 1.0)
    return player


def test_session_shapes_and_records(session: Session) -> None:
    assert session.times.size == 668 and session.positions.shape == (2, 668)
    assert session.period == pytest.approx(0.03)
    assert np.all(np.isfinite(session.controls[:, :-1])) and np.all(
        np.isnan(session.controls[:, -1])
    )
    assert np.all(np.abs(session.positions) <= 0.5)
    assert session.metadata["seed"] == 7 and len(session.metadata["player_seeds"]) == 2
    assert session.metadata["players"][0]["params"]["theta_p"] == 0.1
    np.testing.assert_array_equal(session.graph, [[0, 1], [1, 0]])


def test_same_seed_same_session(generator: IMSGenerator, session: Session) -> None:
    players = [VirtualTrainer(LEADER, generator), VirtualTrainer(FOLLOWER, generator)]
    np.testing.assert_array_equal(play(players, 20.0, 7).positions, session.positions)
    assert not np.array_equal(play(players, 20.0, 8).positions, session.positions)


def test_follower_lags_the_leader(session: Session) -> None:
    phase = compute_relative_phase(session.positions[0], session.positions[1])
    assert np.angle(np.mean(np.exp(1j * phase))) > 0
    assert compute_phase_locking(phase) > 0.8


def test_velocities_are_consistent_with_positions(session: Session) -> None:
    inner = session.positions[:, 1:-1]
    numeric = (session.positions[:, 2:] - session.positions[:, :-2]) / (2 * session.period)
    moving = np.abs(inner) < 0.49
    assert np.median(np.abs(numeric - session.velocities[:, 1:-1])[moving]) < 0.05


def test_recorded_player_has_no_control(zhai_trials_100hz, generator) -> None:
    players = [RecordedPlayer(zhai_trials_100hz[0]), VirtualTrainer(FOLLOWER, generator)]
    recorded = play(players, 3.0)
    assert np.all(np.isnan(recorded.controls[0])) and np.all(np.isnan(recorded.references[0]))
    assert isinstance(recorded.metadata["seed"], int)


def lineup(n: int, generator, trials, cyber) -> list:
    """n players of every kind: virtual trainers of three roles, a recording, a cyber player."""
    kinds = [
        lambda: VirtualTrainer(JOINT, generator),
        lambda: VirtualTrainer(LEADER, trials[2]),
        lambda: RecordedPlayer(trials[5]),
        lambda: cyber,
        lambda: VirtualTrainer(FOLLOWER, generator),
    ]
    return [kinds[i % len(kinds)]() for i in range(n)]


@pytest.mark.parametrize(
    ("n", "graph"),
    [
        (1, None),
        (2, None),
        (3, None),
        (3, path_graph(3)),
        (6, ring_graph(6)),
        (6, star_graph(6, centre=2)),
    ],
)
def test_any_number_of_players_play_the_same_in_both_loops(
    n, graph, generator, zhai_trials_100hz, cyber
) -> None:
    players = lineup(n, generator, zhai_trials_100hz, cyber)
    looped = play(players, 6.0, seed=21, graph=graph)
    compiled = play_compiled(players, looped.n_samples, 21, graph)
    assert looped.positions.shape == (n, 201)
    for channel in CHANNELS:
        np.testing.assert_array_equal(getattr(compiled, channel), getattr(looped, channel))
    np.testing.assert_array_equal(compiled.graph, looped.graph)
    assert np.all(np.abs(looped.positions) <= 0.5) and np.all(np.isfinite(looped.velocities))


def test_who_observes_whom_matters(generator) -> None:
    """On a path the ends only see the middle: cutting a link changes what the players do."""
    players = [VirtualTrainer(FOLLOWER, generator) for _ in range(3)]
    complete = play(players, 5.0, seed=4)
    path = play(players, 5.0, seed=4, graph=path_graph(3))
    np.testing.assert_array_equal(complete.references, path.references)
    assert not np.array_equal(complete.positions, path.positions)


def test_a_virtual_trainer_alone_tracks_its_reference(generator) -> None:
    solo = play([VirtualTrainer(FOLLOWER, generator)], 20.0, seed=1)
    assert solo.roles == ("solo",) and solo.graph.shape == (1, 1)
    velocity, reference = solo.velocities[0, 1:], solo.references[0, :-1]
    inside = np.abs(solo.positions[0, 1:]) < 0.45
    assert np.corrcoef(velocity[inside], reference[inside])[0, 1] > 0.95


def test_a_drawn_graph_is_new_for_each_seed_and_replayed_by_it(generator) -> None:
    players = [VirtualTrainer(JOINT, generator) for _ in range(5)]
    graphs = [play(players, 1.0, seed=s, graph=random_connected_graph).graph for s in range(6)]
    assert len({g.tobytes() for g in graphs}) > 1
    again = play(players, 1.0, seed=3, graph=random_connected_graph)
    np.testing.assert_array_equal(again.graph, graphs[3])
    compiled = play_compiled(players, again.n_samples, 3, random_connected_graph)
    np.testing.assert_array_equal(compiled.positions, again.positions)


class Pointer(ExternalPlayer):
    """A person whose positions come from a script, read once per sample."""

    def __init__(self, path: list[float]) -> None:
        self.path = path

    def reset(self, seed=None):
        self.k = 0
        return self.path[0], 0.0

    def current_state(self):
        x = self.path[self.k]
        self.k += 1
        return x, 1.0


def test_external_players_are_read_not_stepped_and_sinks_see_every_sample(generator) -> None:
    path = [0.1 * math.sin(k / 3) for k in range(30)]
    rows = []
    engine = Engine([Pointer(path), VirtualTrainer(FOLLOWER, generator)], sinks=[rows.append])
    engine.reset(seed=2, n_samples=30)
    for _ in range(29):
        engine.step()
    session = engine.finish()
    np.testing.assert_array_equal(session.positions[0], path)
    np.testing.assert_array_equal(session.velocities[0], 1.0)
    np.testing.assert_array_equal(np.array(rows), session.table())
    follower = play([RecordedPlayer.on_grid(np.array(path), np.ones(30), 0.03), engine.players[1]],
                    0.87, seed=2)  # fmt: skip
    np.testing.assert_array_equal(follower.positions[1], session.positions[1])


def test_bad_lineups_are_refused(generator) -> None:
    with pytest.raises(InputError, match="periods differ"):
        play(
            [
                VirtualTrainer(LEADER.with_(period=0.02), generator),
                VirtualTrainer(FOLLOWER, generator),
            ]
        )
    with pytest.raises(InputError, match="at least one player"):
        play([])
    with pytest.raises(InputError, match="square"):
        play([VirtualTrainer(FOLLOWER, generator)] * 2, graph=np.ones(3))
    with pytest.raises(InputError, match="exceed one control period"):
        play([VirtualTrainer(FOLLOWER, generator)], duration=0.01)

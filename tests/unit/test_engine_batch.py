"""Tests of the batch engine: identical to one-at-a-time play, however the sessions are run."""

import threading

import numpy as np
import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.common.seeds import spawn_seeds
from mirror_avatar.dynamics import FOLLOWER, JOINT, LEADER
from mirror_avatar.engine.batch import run_sessions
from mirror_avatar.engine.loop import play
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.players import ExternalPlayer, RecordedPlayer, VirtualTrainer
from mirror_avatar.sessions.graphs import random_connected_graph
from waiting import wait_for

CHANNELS = ("positions", "velocities", "controls", "references")


@pytest.fixture(scope="module")
def generators(zhai_trials_100hz: list) -> tuple[IMSGenerator, IMSGenerator]:
    fast = IMSGenerator(n_symbols=32, random_state=0).fit(zhai_trials_100hz[0:3])
    slow = IMSGenerator(n_symbols=32, random_state=0).fit(zhai_trials_100hz[9:12])
    return fast, slow


@pytest.fixture(scope="module")
def pairs(generators, zhai_trials_100hz: list) -> list:
    fast, slow = generators
    return [
        (VirtualTrainer(LEADER, fast), VirtualTrainer(FOLLOWER, slow)),
        (VirtualTrainer(LEADER, slow), VirtualTrainer(FOLLOWER, slow)),
        (RecordedPlayer(zhai_trials_100hz[5]), VirtualTrainer(FOLLOWER, fast)),
    ]


def collect(chunks) -> list:
    return [session for chunk in chunks for session in chunk]


def test_batch_sessions_equal_played_sessions(pairs) -> None:
    sessions = collect(run_sessions(pairs, 6, duration=5.0, seed=11, n_jobs=1, chunk_size=4))
    seeds = spawn_seeds(11, 6, bits=64)
    assert [s.metadata["seed"] for s in sessions] == seeds.tolist()
    assert [s.metadata["lineup"] for s in sessions] == [0, 1, 2, 0, 1, 2]
    for i, session in enumerate(sessions):
        assert session.positions.shape == (2, 168)
        played = play(pairs[i % 3], duration=5.0, seed=int(seeds[i]))
        for channel in CHANNELS:
            np.testing.assert_array_equal(getattr(session, channel), getattr(played, channel))


def test_chunking_and_threads_do_not_change_results(pairs) -> None:
    inline = collect(run_sessions(pairs, 7, duration=4.0, seed=2, n_jobs=1, chunk_size=7))
    threads = collect(run_sessions(pairs, 7, duration=4.0, seed=2, n_jobs=2, chunk_size=2))
    for a, b in zip(inline, threads, strict=True):
        for channel in CHANNELS:
            np.testing.assert_array_equal(getattr(a, channel), getattr(b, channel))


def test_a_run_stopped_early_leaves_no_worker_thread_behind(pairs) -> None:
    chunks = run_sessions(pairs, 200, duration=4.0, n_jobs=2, chunk_size=2)
    assert len(next(chunks)) == 2
    chunks.close()
    names = lambda: [thread.name for thread in threading.enumerate()]  # noqa: E731
    wait_for(lambda: not any(n.startswith("mirror-avatar-batch") for n in names()), 30.0)


def test_chunks_stream_in_order(pairs) -> None:
    chunks = run_sessions(pairs, 5, duration=2.0, n_jobs=1, chunk_size=2)
    assert [[s.metadata["session"] for s in chunk] for chunk in chunks] == [[0, 1], [2, 3], [4]]


def test_groups_on_new_random_graphs(generators) -> None:
    fast, slow = generators
    group = [VirtualTrainer(JOINT, g) for g in (fast, slow, fast, slow)]
    sessions = collect(
        run_sessions([group], 4, 3.0, seed=5, n_jobs=1, graph=random_connected_graph)
    )
    assert all(s.n_players == 4 for s in sessions)
    assert len({s.graph.tobytes() for s in sessions}) > 1
    again = play(group, 3.0, seed=sessions[2].metadata["seed"], graph=random_connected_graph)
    np.testing.assert_array_equal(again.graph, sessions[2].graph)
    np.testing.assert_array_equal(again.positions, sessions[2].positions)


class Person(ExternalPlayer):
    def reset(self, seed=None):
        return 0.0, 0.0

    def current_state(self):
        return 0.0, 0.0


def test_bad_runs_are_refused(pairs) -> None:
    with pytest.raises(InputError, match="cannot run Person"):
        next(run_sessions([(Person(), pairs[0][1])], 1))
    with pytest.raises(InputError, match="no players"):
        next(run_sessions([], 1))
